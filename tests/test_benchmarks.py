"""Every benchmark still runs: each in a process of its own, on inputs small enough for the suite.

The benchmarks are not run by anything else, and one had stopped running for
several stops (``bench_memory.py``: options and provenance it read had gone)
before anyone noticed.  This only checks that each one runs to the end and
prints its table: no timing is asserted (the numbers of a smoke run mean
nothing).

Each runs as ``python benchmarks/SCRIPT ARGS`` would (``__main__``, its folder first on ``sys.path``, its own
``sys.argv``), in a process forked for it from a server process that has imported the third-party libraries
the benchmarks share (numpy, numba, trimesh, manifold3d, usd-core: :data:`PRELOADED`) once per test
process, instead of a new interpreter importing them again for each of the 18 (about a CPU second each).
lsys3d itself is imported by each benchmark, as when run on its own (``profile_memory.py`` wraps its
functions before the pipeline imports them).
"""

from __future__ import annotations

import multiprocessing
from pathlib import Path

import pytest
from forked import run_script

BENCHMARKS = Path(__file__).resolve().parent.parent / "benchmarks"

SMOKE = {
    "bench_attributes.py": ["--preset", "koch", "--repeat", "1"],
    "blob_presets.py": ["--only", "koch", "--repeats", "1"],
    "bench_blender_regrow.py": ["--iterations", "3", "--repeat", "1"],  # in .venv-bpy's Python (skips without)
    "bench_botany.py": ["--quick", "--presets", "grass", "foxglove", "--check"],
    "bench_batch.py": ["--seeds", "1", "--skip-dask", "--quick"],  # the Dask cluster itself: test_batch.py
    "bench_derive.py": ["--quick"],
    "bench_environment.py": ["--iterations", "20", "--repeat", "1"],
    "bench_edit.py": ["--preset", "koch", "--edits", "1"],
    "bench_export.py": ["--quick"],
    # every setting (growth, birth attribute, rig, wind) on 125 segments instead of the preset's own 3,125
    "bench_growth.py": ["--preset", "abop-1.24a", "--iterations", "3", "--repeat", "1", "--seconds", "1"],
    "bench_memory.py": ["--cases", "tree3d:3", "tree3d:3:no-union"],
    "bench_mesh.py": ["--sizes", "200", "--repeat", "1", "--naive-cap", "200"],
    "bench_quality.py": ["--presets", "koch", "--repeat", "1"],
    "bench_readers.py": ["--quick"],
    "bench_turtle.py": ["-n", "4", "--repeat", "1"],
    "bench_union_scale.py": ["--plant", "3", "--no-fern", "--compare", "0", "--no-naive"],
    "compile_profile.py": ["--top", "5", "--", "generate", "koch", "-o", "koch.glb"],  # warm: nothing compiled
    "dense_census.py": [str(BENCHMARKS.parent / "tests/corpus/lpy/real/abop_chap1_lsystem1.4.lpy")],
    "preset_bytes.py": ["out", "--only", "snowflake", "algae"],  # one written, one skipped (draws nothing)
    "profile_memory.py": ["koch", "-n", "2"],
}


def test_every_benchmark_has_a_smoke_run():
    scripts = {p.name for p in BENCHMARKS.glob("*.py")} - {"timing.py"}  # timing.py: their shared helpers
    assert scripts == set(SMOKE)


#: What the server process imports before it forks a process for each benchmark: the libraries every
#: benchmark's lsys3d loads, none of lsys3d's own modules.
PRELOADED = ["numpy", "numba", "trimesh", "manifold3d", "pxr.Usd", "pxr.UsdGeom", "forked"]


@pytest.fixture(scope="module")
def forks():
    """A multiprocessing context whose processes fork from a server that preloaded :data:`PRELOADED`."""
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(PRELOADED)
    yield context
    # the server stopped and waited for by this process (multiprocessing's own call for that, which its tests
    # use): no server left running, and its time and its children's counted as this process's children's
    from multiprocessing import forkserver

    forkserver._forkserver._stop()


@pytest.mark.parametrize("script", sorted(SMOKE))
def test_the_benchmark_runs(script, tmp_path, forks):
    out, err = tmp_path / "stdout.txt", tmp_path / "stderr.txt"
    work = tmp_path / "work"  # anything a benchmark leaves behind stays out of the checkout
    work.mkdir()
    process = forks.Process(
        target=run_script, args=(str(BENCHMARKS / script), SMOKE[script], str(work), str(out), str(err))
    )
    process.start()
    process.join(timeout=600)
    if process.exitcode is None:
        process.kill()
        process.join()
    stdout, stderr = out.read_text(errors="replace"), err.read_text(errors="replace")
    assert process.exitcode == 0, f"{script} failed ({process.exitcode}):\n{stdout[-2000:]}\n{stderr[-4000:]}"
    assert stdout.strip(), f"{script} printed nothing"
