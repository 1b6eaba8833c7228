"""Batches: files and manifest, resume, failures among good jobs, killed workers, interrupts, shards, Dask."""

from __future__ import annotations

import contextlib
import json
import logging
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import validators
from batches import IDS, copy_of_library, small_library, write_project

import lsys3d
from lsys3d.errors import BatchError
from lsys3d.exchange.library import read_library
from lsys3d.golden.golden import Recipe, compare, grow
from lsys3d.library.batch import MANIFEST, batch, plan, read_manifests
from lsys3d.library.jobs import read_jobs

LINE_KEYS = {"counts", "crown_radius", "export", "files", "id", "lsys3d_manifest", "recipe", "run", "status"}
RUN_KEYS = {"attempts", "finished", "peak_memory", "predicted_memory", "seconds", "worker"}


def manifest_lines(outdir: Path) -> list[dict]:
    lines = []
    for path in sorted(outdir.glob("manifest*.jsonl")):
        lines += [json.loads(raw) for raw in path.read_text().splitlines() if raw.strip()]
    return lines


def temporaries(folder: Path) -> list[Path]:
    return [p for p in folder.rglob("*") if re.fullmatch(r"\..+\.[0-9a-f]{8}\.tmp\.\w+", p.name)]


def sha256(path: Path) -> str:
    import hashlib

    return hashlib.sha256(path.read_bytes()).hexdigest()


def without_run(line: dict) -> dict:
    return {k: v for k, v in line.items() if k != "run"}


def kill(pid: int) -> None:
    with contextlib.suppress(ProcessLookupError):
        os.kill(pid, signal.SIGKILL)


# ---------------------------------------------------------------- one batch, looked at closely


def test_batch_writes_every_file_a_manifest_line_each_and_the_library():
    folder, result = small_library()
    out = folder / "out"
    assert result.done == IDS and result.skipped == [] and result.failed == []
    lines = manifest_lines(out)
    assert [line["id"] for line in sorted(lines, key=lambda x: IDS.index(x["id"]))] == IDS
    for line in lines:
        assert set(line) == LINE_KEYS and set(line["run"]) == RUN_KEYS, line
        assert line["status"] == "done" and line["run"]["attempts"] == 1
        assert line["run"]["peak_memory"] > 0 and line["run"]["predicted_memory"] > 0
        assert [f["path"].rsplit(".", 1)[1] for f in line["files"]] == ["glb", "usdc"]
        for entry in line["files"]:
            path = out / entry["path"]
            assert path.stat().st_size == entry["bytes"] and sha256(path) == entry["sha256"]
        assert line["crown_radius"] > 0
    assert temporaries(folder) == []
    # seeds differ: natural variation makes every tree3d its own
    assert len({line["files"][0]["sha256"] for line in lines}) == len(IDS)


def test_a_manifest_recipe_regrows_its_counts_and_bytes(tmp_path):
    folder, _ = small_library()
    out = folder / "out"
    lines = read_manifests(out)
    for job_id in ("tree3d_s2", "fern_s1"):
        line = lines[job_id]
        recipe = Recipe(**line["recipe"])
        assert recipe.seed == int(job_id.rsplit("_s", 1)[1]) and recipe.options["sweep"] == {"sides": 4}
        regrown = grow(recipe, out)  # what `lsys3d check` does with a golden file's recipe
        differences, _ = compare(line["counts"], regrown)
        assert differences == []
    assert lines["fern_s1"]["recipe"]["file"] == "../grammars/fern.toml"
    # the same bytes from this process as from the workers
    tree = lsys3d.generate("tree3d", 3, 1, options=read_jobs(folder / "jobs.toml")[1].options)
    written = lsys3d.export(tree, tmp_path / "tree3d_s1.glb")
    assert sha256(written) == lines["tree3d_s1"]["files"][0]["sha256"]


def test_the_library_holds_every_asset_as_payloads_and_passes_usd_validators():
    folder, result = small_library()
    library = read_library(folder / "out")
    assert result.library == folder / "out" / "library.usda" and result.library_variants == len(IDS)
    assert [v.name for v in library.variants] == sorted(IDS)
    assert all(v.usd.startswith("./") and v.glb and v.crown_radius > 0 for v in library.variants)
    assert validators.usd_problems(result.library) == []
    from pxr import Usd

    stage = Usd.Stage.Open(str(result.library), Usd.Stage.LoadNone)  # opens without loading a mesh
    prim = stage.GetDefaultPrim()
    species = prim.GetVariantSets().GetVariantSet("species")
    assert species.GetVariantNames() == ["fern", "tree3d"]
    species.SetVariantSelection("tree3d")
    seeds = prim.GetVariantSets().GetVariantSet("seed")
    assert seeds.GetVariantNames() == ["seed_0", "seed_1", "seed_2"]
    assert prim.HasAuthoredPayloads()


# ---------------------------------------------------------------- resume


def test_a_second_run_skips_everything():
    folder, _ = small_library()
    before = (folder / "out" / MANIFEST).read_bytes()
    again = batch(folder / "jobs.toml", folder / "out", workers=2)
    assert again.done == [] and again.skipped == IDS and again.failed == []
    assert (folder / "out" / MANIFEST).read_bytes() == before  # nothing run, nothing recorded


def test_resume_regrows_exactly_what_changed(tmp_path):
    project = copy_of_library(tmp_path)
    out = project / "out"
    (out / "tree3d" / "tree3d_s1.glb").write_bytes(b"not the file the manifest hashed")
    (out / "tree3d" / "tree3d_s2.usdc").unlink()
    fern = project / "grammars" / "fern.toml"
    fern.write_text(fern.read_text().replace("angle = 25", "angle = 27"))
    the = plan(project / "jobs.toml", out)
    assert [job.id for job in the.to_run] == ["tree3d_s1", "tree3d_s2", "fern_s1", "fern_s2"]
    result = batch(the, out, workers=1)  # one worker process: what runs is the point, not where
    assert result.done == ["tree3d_s1", "tree3d_s2", "fern_s1", "fern_s2"] and result.skipped == ["tree3d_s0"]
    lines = read_manifests(out)
    assert sha256(out / "tree3d" / "tree3d_s1.glb") == lines["tree3d_s1"]["files"][0]["sha256"]
    # a new option changes the recipe of the entry's jobs only
    jobs = project / "jobs.toml"
    jobs.write_text(jobs.read_text().replace("seeds = [1, 2]", "seeds = [1, 2]\noptions = { sides = 5 }"))
    assert [job.id for job in plan(jobs, out).to_run] == ["fern_s1", "fern_s2"]


def test_a_line_cut_short_is_skipped_and_the_next_starts_on_its_own(tmp_path):
    project = copy_of_library(tmp_path)
    out = project / "out"
    with open(out / MANIFEST, "ab") as f:
        f.write(b'{"id": "tree3d_s0", "status": "do')  # a crash in the middle of a write
    (out / "tree3d" / "tree3d_s0.glb").unlink()
    result = batch(project / "jobs.toml", out, workers=1)
    assert result.done == ["tree3d_s0"]
    last = (out / MANIFEST).read_text().splitlines()[-1]
    assert json.loads(last)["id"] == "tree3d_s0"  # it started on a line of its own
    assert read_manifests(out)["tree3d_s0"]["status"] == "done"


# ---------------------------------------------------------------- failures


FAILING = """\
[defaults]
formats = ["glb"]

[[jobs]]
grammar = "abop-1.24a"
seeds = "0-1"
options = { iterations = 1, sides = 4, angle_jitter = 5 }   # seeds that matter: no SeedWarning line

[[jobs]]
grammar = "grammars/broken.toml"

[[jobs]]
grammar = "abop-1.24b"
options = { max-segments = 3 }

[[jobs]]
grammar = "algae"
"""


def test_failing_jobs_do_not_stop_the_others(tmp_path):
    write_project(tmp_path, FAILING)
    (tmp_path / "grammars" / "broken.toml").write_text('axiom = "F"\nrules = ["F -> F[+F"]\n')
    command = [sys.executable, "-m", "lsys3d", "batch", str(tmp_path / "jobs.toml"), "-o", str(tmp_path / "out")]
    out = subprocess.run(  # one worker process: the failures among good jobs are the point, not where they run
        [*command, "--workers", "1"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert out.returncode == 1, out.stderr
    assert "5 jobs: 2 done, 0 skipped, 3 failed" in out.stdout
    errors = out.stderr.strip().splitlines()
    assert errors[-1] == "lsys3d: error: 3 of 5 jobs failed: broken_s0, abop-1.24b_s0, algae_s0"
    assert len(errors) == 4 and "\x1b" not in out.stderr  # one line per failure; no progress bar when piped
    lines = read_manifests(tmp_path / "out")
    assert lines["abop-1.24a_s0"]["status"] == lines["abop-1.24a_s1"]["status"] == "done"
    assert "broken.toml:2:" in lines["broken_s0"]["error"] and "unbalanced" in lines["broken_s0"]["error"]
    assert lines["broken_s0"]["recipe"] is None
    assert "more than the limit of 3" in lines["abop-1.24b_s0"]["error"]
    assert "nothing to mesh" in lines["algae_s0"]["error"]
    assert all("\n" not in line.get("error", "") for line in lines.values())
    assert not (tmp_path / "out" / "library.usda").exists()  # no job writes USD


def test_a_killed_worker_is_replaced_and_its_job_retried(tmp_path):
    jobs = write_project(
        tmp_path,
        # every tree3d attempt starts in a fresh worker (the first two, and each replacement), which loads the
        # kernels before it grows (half a second or more): the kill a tenth of a second after the start lands in
        # the job, and the retried job runs whole (at 5 generations: a quarter of a second more)
        '[[jobs]]\ngrammar = "tree3d"\nseeds = "0-1"\nformats = ["glb", "usdc"]\n'
        "options = { sides = 4, iterations = 5 }\n"
        '[[jobs]]\ngrammar = "abop-1.24a"\nseeds = "0-2"\nformats = ["glb"]\noptions = { iterations = 1 }\n',
    )
    starts: dict[str, int] = {}

    def progress(event):
        if event.kind != "start":
            return
        starts[event.job_id] = starts.get(event.job_id, 0) + 1
        pid = int(event.worker.rsplit(":", 1)[1])
        # tree3d_s0's worker is killed once, in the job; tree3d_s1's every time it starts
        if event.job_id == "tree3d_s1" or (event.job_id == "tree3d_s0" and starts[event.job_id] == 1):
            threading.Timer(0.1, kill, (pid,)).start()

    result = batch(jobs, tmp_path / "out", workers=2, progress=progress)
    assert result.failed == ["tree3d_s1"]
    assert re.fullmatch(r"its worker was killed by SIGKILL \(out of memory\?\), 3 times", result.errors["tree3d_s1"])
    assert result.done == ["tree3d_s0", "abop-1.24a_s0", "abop-1.24a_s1", "abop-1.24a_s2"]
    lines = read_manifests(tmp_path / "out")
    assert lines["tree3d_s0"]["run"]["attempts"] == 2 and lines["tree3d_s1"]["run"]["attempts"] == 3
    for entry in lines["tree3d_s0"]["files"]:  # the retried job's files are whole
        assert sha256(tmp_path / "out" / entry["path"]) == entry["sha256"]
    assert validators.usd_problems(tmp_path / "out" / "tree3d" / "tree3d_s0.usdc") == []
    assert temporaries(tmp_path) == []  # the killed attempts' temporary files are gone


def test_a_memory_budget_runs_jobs_one_at_a_time(tmp_path):
    jobs = write_project(
        tmp_path, '[[jobs]]\ngrammar = "abop-1.24a"\nseeds = "0-3"\nformats = ["glb"]\noptions = { iterations = 1 }\n'
    )
    in_flight, most = set(), 0

    def progress(event):
        nonlocal most
        if event.kind == "start":
            in_flight.add(event.job_id)
            most = max(most, len(in_flight))
        else:
            in_flight.discard(event.job_id)

    result = batch(jobs, tmp_path / "out", workers=2, memory=1, progress=progress)
    assert result.done == [f"abop-1.24a_s{s}" for s in range(4)]
    assert most == 1


def test_the_temporary_files_of_killed_writers_are_removed_usds_own_too(tmp_path):
    """A worker killed while writing leaves the writer's temporary file, or, while USD writes, USD's own: made
    from ours with the suffix replaced by six random characters (seen: ``.tree3d_s0.695320be.tmp.NH17bU``)."""
    from lsys3d.library.batch import remove_temporaries

    jobs = plan(write_project(tmp_path, '[[jobs]]\ngrammar = "koch"\nseeds = 0\nformats = ["glb", "usdc"]\n'), tmp_path)
    target = tmp_path / jobs.jobs[0].paths[0]
    folder, stem = target.parent, target.stem
    folder.mkdir(parents=True)
    left = [f".{stem}.695320be.tmp.glb", f".{stem}.695320be.tmp.usdc", f".{stem}.695320be.tmp.NH17bU"]
    kept = [".other.695320be.tmp.NH17bU", f".{stem}.695320be.tmp.NH17b", "notes.txt"]
    for name in left + kept:
        (folder / name).write_text("x")
    assert remove_temporaries(jobs.jobs, tmp_path) == 3
    assert sorted(p.name for p in folder.iterdir()) == sorted(kept)


@pytest.mark.slow  # two batches in a subprocess
def test_sigterm_stops_the_batch_and_the_same_command_resumes(tmp_path):
    jobs = write_project(
        tmp_path,
        '[[jobs]]\ngrammar = "tree3d"\nseeds = "0-3"\nformats = ["glb", "usdc"]\n'
        "options = { iterations = 5, sides = 4 }\n",
    )
    out = tmp_path / "out"
    command = [sys.executable, "-m", "lsys3d", "batch", str(jobs), "-o", str(out), "--workers", "2"]
    proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline and proc.poll() is None:
        if (out / MANIFEST).exists() and (out / MANIFEST).read_text().count("\n") >= 1:
            break
        time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stderr
    assert "interrupted" in stderr and "Traceback" not in stderr
    assert temporaries(tmp_path) == []
    done = {k for k, line in read_manifests(out).items() if line["status"] == "done"}
    assert 1 <= len(done) < 4
    result = batch(jobs, out, workers=1)  # (one worker process: the resume is the point)
    assert set(result.skipped) == done and len(result.done) == 4 - len(done) and result.failed == []


def test_a_stop_signal_wrapped_by_a_compiled_call_stops_the_worker(tmp_path, monkeypatch):
    """SIGTERM's SystemExit raised inside a numba call comes out as a SystemError: the batch is stopping,
    the job has not failed (no traceback in the log, no failed line)."""
    from lsys3d import pipeline
    from lsys3d.library.batch import run_job

    def interrupted(*args, **kw):
        try:
            raise SystemExit(143)
        except SystemExit as exc:
            raise SystemError("returned a result with an exception set") from exc

    monkeypatch.setattr(pipeline, "grow", interrupted)  # what a worker calls
    job = plan(write_project(tmp_path), tmp_path / "out").jobs[0]
    with pytest.raises(SystemExit) as stop:
        run_job(job, tmp_path / "out")
    assert stop.value.code == 143

    def broken(*args, **kw):
        raise SystemError("a bug of ours")

    monkeypatch.setattr(pipeline, "grow", broken)
    line = run_job(job, tmp_path / "out")
    assert line["status"] == "failed" and "internal error: SystemError" in line["error"]


# ---------------------------------------------------------------- shards


def test_shards_split_the_jobs_and_a_last_run_writes_the_whole_library(tmp_path):
    project = write_project(tmp_path)
    out = tmp_path / "out"
    first = batch(project, out, shard_of=(1, 2), workers=1)
    second = batch(project, out, shard_of=(2, 2), workers=1)
    assert sorted(first.done + second.done) == sorted(IDS) and not set(first.done) & set(second.done)
    assert first.done == IDS[0::2] and second.done == IDS[1::2]
    assert sorted(p.name for p in out.glob("manifest*.jsonl")) == ["manifest-1-of-2.jsonl", "manifest-2-of-2.jsonl"]
    final = batch(project, out, workers=1)
    assert final.skipped == IDS and final.done == []
    assert len(read_library(out).variants) == len(IDS)


# ---------------------------------------------------------------- the command


def run(*args, **kw):
    return subprocess.run([sys.executable, "-m", "lsys3d", *args], capture_output=True, text=True, timeout=300, **kw)


def test_command_errors_are_one_line(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('[[jobs]]\ngrammar = "kosh"\nformats = ["glb"]\n')
    out = run("batch", str(bad), "-o", str(tmp_path / "out"))
    assert out.returncode == 1 and out.stderr.startswith(f"lsys3d: error: {bad}:2:11: grammar: no bundled preset")
    assert len(out.stderr.strip().splitlines()) == 1 and not (tmp_path / "out").exists()
    from lsys3d.cli import main

    for flags in (["--shard", "0/2"], ["--memory", "lots"], ["--workers", "0"]):
        with pytest.raises(SystemExit) as info:
            main(["batch", str(bad), "-o", str(tmp_path / "out"), *flags])
        assert info.value.code == 2


def test_dry_run_lists_the_plan(capsys):
    from lsys3d.cli import main

    folder, _ = small_library()
    assert main(["batch", str(folder / "jobs.toml"), "-o", str(folder / "out"), "--dry-run"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("tree3d_s0  tree3d/tree3d_s0.glb tree3d/tree3d_s0.usdc  done, skip")
    assert lines[-1] == "5 jobs: 0 to run, 5 done"


def test_dry_run_predicts_sizes(tmp_path, capsys):
    from lsys3d.cli import main

    project = write_project(tmp_path)
    assert main(["batch", str(project), "-o", str(tmp_path / "out"), "--dry-run", "--shard", "2/2"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("tree3d_s1  tree3d/tree3d_s1.glb tree3d/tree3d_s1.usdc  run  ")
    assert re.search(r"run  [\d,]+ modules, [\d,]+ segments, ~[\d,]+ tube triangles, ~[\d,]+ MB$", lines[0])
    assert lines[-1] == "2 jobs: 2 to run, 0 done" and not (tmp_path / "out").exists()


def test_an_output_folder_that_cannot_be_made(tmp_path):
    project = write_project(tmp_path)
    (tmp_path / "file").write_text("")
    with pytest.raises(BatchError, match="cannot make the output folder"):
        batch(project, tmp_path / "file" / "out")


# ---------------------------------------------------------------- Dask


@pytest.fixture(scope="module")
def cluster():
    from distributed import LocalCluster

    with LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=None,
        resources={"memory": 8e9},
    ) as c:
        yield c


def test_dask_makes_the_same_files_and_lines_and_carries_the_prediction(cluster, tmp_path):
    from distributed.diagnostics.plugin import SchedulerPlugin

    class Restrictions(SchedulerPlugin):
        def __init__(self, scheduler):
            self.scheduler, self.seen = scheduler, {}

        def transition(self, key, start, finish, *args, **kwargs):
            task = self.scheduler.tasks.get(key)
            if finish == "processing" and task is not None:
                self.seen[str(key)] = dict(task.resource_restrictions or {})

    plugin = Restrictions(cluster.scheduler)
    cluster.scheduler.add_plugin(plugin, name="lsys3d-test-restrictions")
    folder, _ = small_library()
    out = folder / "out-dask"  # beside the local run's folder: the recipes' relative grammar paths are the same
    try:
        result = batch(folder / "jobs.toml", out, scheduler=cluster.scheduler_address)
        assert result.done == IDS and result.failed == []
        local, dask = read_manifests(folder / "out"), read_manifests(out)
        for job_id in IDS:
            assert without_run(dask[job_id]) == without_run(local[job_id])
            for entry in dask[job_id]["files"]:
                assert (out / entry["path"]).read_bytes() == (folder / "out" / entry["path"]).read_bytes()
        predicted = {job_id: dask[job_id]["run"]["predicted_memory"] for job_id in IDS}
        seen = {re.fullmatch(r"lsys3d-(.+)-[0-9a-f]{8}", k).group(1): v for k, v in plugin.seen.items()}
        assert seen == {job_id: {"memory": predicted[job_id]} for job_id in IDS}
    finally:
        cluster.scheduler.remove_plugin(name="lsys3d-test-restrictions")
        import shutil

        shutil.rmtree(out, ignore_errors=True)


def test_dask_retries_a_job_whose_worker_was_killed(cluster, tmp_path, caplog):
    """A real worker process of a LocalCluster killed in the middle of a job: the scheduler runs the job
    again, the manifest counts 2 attempts (the others 1), and one warning line names the job."""
    from distributed import Client

    jobs = write_project(
        tmp_path,
        # iterations 6: the job takes over half a second (0.58 CPU s warm; 2.2 at 7), so that the kill a tenth of
        # a second after it is seen running lands in it
        '[[jobs]]\ngrammar = "tree3d"\nseeds = 0\nformats = ["usdc"]\noptions = { sides = 4, iterations = 6 }\n'
        '[[jobs]]\ngrammar = "abop-1.24a"\nseeds = "0-1"\nformats = ["glb"]\noptions = { iterations = 1 }\n',
    )
    killed: list[str] = []

    def executing(dask_worker):
        return [str(task.key) for task in dask_worker.state.executing]

    def killer():
        with Client(cluster.scheduler_address, set_as_default=False) as client:
            deadline = time.monotonic() + 240
            while time.monotonic() < deadline and not killed:
                try:
                    running = client.run(executing)
                    pids = client.run(os.getpid)
                except Exception:  # a worker coming back
                    continue
                for address, keys in running.items():
                    if any("-tree3d_s0-" in k for k in keys):
                        time.sleep(0.1)
                        kill(pids[address])
                        killed.append(address)
                        return
                time.sleep(0.05)

    thread = threading.Thread(target=killer)
    thread.start()
    try:
        with caplog.at_level(logging.WARNING, logger="lsys3d"):
            result = batch(jobs, tmp_path / "out", scheduler=cluster.scheduler_address)
    finally:
        thread.join()
    assert killed and result.failed == [] and result.done == ["tree3d_s0", "abop-1.24a_s0", "abop-1.24a_s1"]
    lines = read_manifests(tmp_path / "out")
    assert {job_id: lines[job_id]["run"]["attempts"] for job_id in lines} == {
        "tree3d_s0": 2,
        "abop-1.24a_s0": 1,
        "abop-1.24a_s1": 1,
    }
    lost = [r.getMessage() for r in caplog.records if r.name == "lsys3d" and "died" in r.getMessage()]
    assert lost == ["tree3d_s0: its Dask worker died running it; the scheduler started it again"]
    line = lines["tree3d_s0"]
    path = tmp_path / "out" / line["files"][0]["path"]
    assert sha256(path) == line["files"][0]["sha256"]
    assert validators.usd_problems(path) == []
    assert temporaries(tmp_path) == []


def test_an_unreachable_scheduler_is_one_error(tmp_path, monkeypatch):
    import lsys3d.library.runners

    monkeypatch.setattr(lsys3d.library.runners, "CONNECT_TIMEOUT", "1s")
    project = write_project(tmp_path)
    with pytest.raises(BatchError, match="cannot reach the Dask scheduler"):
        batch(project, tmp_path / "out", scheduler="tcp://127.0.0.1:9")


def test_a_batch_of_seeds_that_change_nothing_warns_once(tmp_path):
    """seeds = "0-2" of a grammar nothing random shapes: three copies of one plant, and one SeedWarning saying
    so (the rule of generate and the CLI's --variants); with a jitter, none: one batch holding both entries
    warns once, for the entry without the jitter."""
    import warnings

    from lsys3d.errors import SeedWarning

    entry = '[[jobs]]\ngrammar = "abop-1.24a"\nseeds = "%s"\nformats = ["glb"]\noptions = { iterations = 1%s }\n'
    jobs = write_project(tmp_path, entry % ("0-2", "") + entry % ("3-5", ", angle_jitter = 5"))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = batch(jobs, tmp_path / "out", workers=1, library=False)
    assert result.ok and len(result.done) == 6
    seeds = [str(w.message) for w in caught if issubclass(w.category, SeedWarning)]
    assert len(seeds) == 1, seeds
    assert "abop-1.24a grows the same plant from every seed" in seeds[0] and "3 variants" in seeds[0]
    lines = read_manifests(tmp_path / "out")
    counts = [lines[f"abop-1.24a_s{seed}"]["counts"] for seed in range(3)]
    assert counts[0] == counts[1] == counts[2]  # what it warns of


def test_a_worker_stop_that_lands_in_a_finalizer_is_put_off_until_after_it():
    """SIGTERM inside ``__del__`` (Python would print and swallow the SystemExit) stops the worker 10 ms later."""
    from lsys3d.library import runners

    class Closing:
        def __del__(self):
            runners._stop(signal.SIGTERM, sys._getframe())  # as if the signal arrived here
            seen.append("finalizer ran to its end")

    seen: list[str] = []
    previous = signal.getsignal(signal.SIGALRM)
    try:
        Closing()  # dropped at once: its __del__ runs
        assert seen == ["finalizer ran to its end"]
        with pytest.raises(SystemExit) as stopped:
            time.sleep(5)
        assert stopped.value.code == 128 + signal.SIGTERM
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
