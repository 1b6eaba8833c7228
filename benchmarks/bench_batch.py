"""A library of 200 jobs (4 presets x 50 seeds) three ways, and a forest of 10,000 instances, all in one run.

    python benchmarks/bench_batch.py [--seeds 50] [--skip-dask] [--quick]

1. Baseline: every job in this one process, one after the other (``run_job`` in a loop).
2. ``lsys3d batch`` with the local runner: one worker process per core.  Ratio of
   throughputs against the baseline (the goal: at least 90% of the core count).
3. The same jobs on a Dask cluster this script starts on 127.0.0.1 (``dask scheduler``
   and one ``dask worker`` process per core, one thread each); the files must be
   byte-identical to the local runner's and the manifest lines equal but for ``run``
   (times, memory, worker names).
4. ``lsys3d forest``: 10,000 instances of 20 of the assets (5 of each species), as
   ``.usdc`` and as ``.glb``: seconds (beyond the assets, which exist) and bytes.

The presets run at fewer generations than their own (tree3d 5, bush 5, monopodial 9,
ternary 5: about half a second each), with natural variation so every seed differs, so
that the three runs take minutes, not an hour.  ``--quick`` (the test suite's smoke run) grows them at
:data:`QUICK` generations instead: every step still runs, on jobs of a few hundredths of a second.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from lsys3d.exchange.library import read_library, write_library
from lsys3d.library.batch import batch, plan, read_manifests, run_job
from lsys3d.library.forest import ForestOptions, forest
from lsys3d.library.runners import cpu_count

PRESETS = {"tree3d": 5, "bush": 5, "monopodial": 9, "ternary": 5}
QUICK = {"tree3d": 3, "bush": 3, "monopodial": 6, "ternary": 3}


def jobs_text(seeds: int, presets: dict[str, int] = PRESETS) -> str:
    text = '[defaults]\nformats = ["glb", "usdc"]\n'
    for name, n in presets.items():
        text += (
            f'\n[[jobs]]\ngrammar = "{name}"\nseeds = "0-{seeds - 1}"\n'
            f"options = {{ iterations = {n}, sides = 6, turtle = {{ angle_jitter = 8, length_jitter = 0.1 }} }}\n"
        )
    return text


def children_cpu() -> float:
    """CPU seconds of the child processes that ended (workers, and their own children)."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def start_dask(folder: Path, workers: int) -> tuple[str, list[subprocess.Popen]]:
    dask = Path(sys.executable).with_name("dask")
    info = folder / "scheduler.json"
    common = ["--no-dashboard"]
    procs = [
        subprocess.Popen(
            [str(dask), "scheduler", "--host", "127.0.0.1", "--port", "0", "--scheduler-file", str(info), *common],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
    ]
    deadline = time.monotonic() + 60
    while not info.exists() and time.monotonic() < deadline:
        time.sleep(0.1)
    address = json.loads(info.read_text())["address"]
    for _ in range(workers):
        procs.append(
            subprocess.Popen(
                [
                    str(dask),
                    "worker",
                    address,
                    "--nthreads",
                    "1",
                    "--host",
                    "127.0.0.1",
                    "--resources",
                    "memory=4e9",
                    *common,
                ],
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
        )
    from distributed import Client

    with Client(address) as client:
        client.wait_for_workers(workers, timeout=120)
    return address, procs


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--seeds", type=int, default=50)
    parser.add_argument("--skip-dask", action="store_true")
    parser.add_argument("--quick", action="store_true", help="the presets at fewer generations (QUICK)")
    args = parser.parse_args()
    cores = cpu_count()
    print(f"{len(PRESETS)} presets x {args.seeds} seeds, {cores} cores, load average {os.getloadavg()[0]:.1f}")
    print("  (the load average counts other users' work too: wall-clock ratios need an idle machine)")
    with tempfile.TemporaryDirectory(prefix="bench-batch-") as tmp:
        tmp = Path(tmp)
        jobs_file = tmp / "jobs.toml"
        jobs_file.write_text(jobs_text(args.seeds, QUICK if args.quick else PRESETS))

        # 1. one process
        the = plan(jobs_file, tmp / "one")
        for name in PRESETS:
            (tmp / "one" / name).mkdir(parents=True)
        run_job(the.jobs[0], tmp / "warm")  # imports and numba's cache, as a worker does before its first job
        t0, c0 = time.perf_counter(), time.process_time()
        for job in the.jobs:
            line = run_job(job, tmp / "one")
            assert line["status"] == "done", line
        one, cpu = time.perf_counter() - t0, time.process_time() - c0
        n = len(the.jobs)
        print(f"  one process            {one:7.1f} s  {n / one:5.2f} jobs/s   (baseline; {cpu / n:.3f} CPU s/job)")

        # 2. the local runner
        t0, c0 = time.perf_counter(), children_cpu()
        local = batch(jobs_file, tmp / "local", library=False)
        seconds, workers_cpu = time.perf_counter() - t0, children_cpu() - c0
        assert not local.failed, local.errors
        print(
            f"  local runner, {cores} procs  {seconds:7.1f} s  {n / seconds:5.2f} jobs/s   {one / seconds:4.2f}x "
            f"the baseline ({one / seconds / cores:.0%} of {cores}x; worker start-up included; "
            f"{workers_cpu / n:.3f} CPU s/job in the workers)"
        )

        # 3. Dask on 127.0.0.1
        if not args.skip_dask:
            c0 = children_cpu()
            address, procs = start_dask(tmp, cores)
            try:
                t0 = time.perf_counter()
                result = batch(jobs_file, tmp / "dask", scheduler=address, library=False)
                seconds = time.perf_counter() - t0
            finally:
                for p in procs[::-1]:
                    p.terminate()
                for p in procs:
                    p.wait(timeout=60)
            dask_cpu = children_cpu() - c0
            assert not result.failed, result.errors
            a, b = read_manifests(tmp / "local"), read_manifests(tmp / "dask")
            same_lines = all({**a[i], "run": None} == {**b[i], "run": None} for i in a) and a.keys() == b.keys()
            files = [f["path"] for line in a.values() for f in line["files"]]
            same_files = all((tmp / "local" / f).read_bytes() == (tmp / "dask" / f).read_bytes() for f in files)
            print(
                f"  Dask, {cores} workers       {seconds:7.1f} s  {n / seconds:5.2f} jobs/s   {one / seconds:4.2f}x "
                f"the baseline ({dask_cpu / n:.3f} CPU s/job in the scheduler and workers); {len(files)} files "
                f"byte-identical: {same_files}, manifest lines equal but for run: {same_lines}"
            )

        # 4. a forest of 10,000 instances of 20 assets
        lines = read_manifests(tmp / "local")
        full = batch(jobs_file, tmp / "local")  # skips every job, writes library.usda
        library = read_library(full.library)
        chosen = [v for v in library.variants if v.seed < 5]
        small = write_library(tmp / "local" / "library20.usda", chosen, library.options)
        assets = sum(f["bytes"] for v in chosen for f in lines[v.name]["files"] if f["path"].endswith(".usdc"))
        options = ForestOptions(area=(1500, 1500), count=10_000, seed=1)
        forest(small, tmp / "warm.usdc", ForestOptions(count=10))  # numba's cache, USD's plugins
        for suffix in (".usdc", ".glb"):
            t0 = time.perf_counter()
            path = forest(small, tmp / f"forest{suffix}", options)
            seconds = time.perf_counter() - t0
            size = path.stat().st_size
            what = f"the assets' .usdc: {assets:,} bytes" if suffix == ".usdc" else "holds each asset once"
            print(
                f"  forest{suffix:<6} 10,000 instances of {len(chosen)} assets: {seconds:5.2f} s, {size:,} bytes "
                f"({size / 10_000:.0f} bytes/instance; {what})"
            )


if __name__ == "__main__":
    main()
