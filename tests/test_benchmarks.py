"""Every benchmark still runs: each in a process of its own, on inputs small enough for the suite.

The benchmarks are not run by anything else, and one had stopped running for
several stops (``bench_memory.py``: options and provenance it read had gone)
before anyone noticed.  This only checks that each one runs to the end and
prints its table: no timing is asserted (the numbers of a smoke run mean
nothing).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parent.parent / "benchmarks"

SMOKE = {
    "bench_attributes.py": ["--preset", "koch", "--repeat", "1"],
    "blob_presets.py": ["--only", "koch", "--repeats", "1"],
    "bench_blender_regrow.py": ["--iterations", "3", "--repeat", "1"],  # in .venv-bpy's Python (skips without)
    "bench_botany.py": ["--quick", "--presets", "grass", "foxglove", "--check"],
    "bench_batch.py": ["--seeds", "1", "--skip-dask"],  # the Dask cluster itself: test_batch.py
    "bench_derive.py": ["--quick"],
    "bench_environment.py": ["--iterations", "20", "--repeat", "1"],
    "bench_edit.py": ["--preset", "koch", "--edits", "1"],
    "bench_export.py": ["--quick"],
    "bench_growth.py": ["--preset", "abop-1.24a", "--repeat", "1", "--seconds", "1"],
    "bench_memory.py": ["--cases", "tree3d:3", "tree3d:3:no-union"],
    "bench_mesh.py": ["--sizes", "200", "--repeat", "1", "--naive-cap", "200"],
    "bench_quality.py": ["--presets", "koch", "--repeat", "1"],
    "bench_readers.py": ["--quick"],
    "bench_turtle.py": ["-n", "4", "--repeat", "1"],
    "bench_union_scale.py": ["--plant", "3", "--no-fern", "--compare", "0", "--no-naive"],
    "compile_profile.py": ["--top", "5", "--", "generate", "koch", "-o", "koch.glb"],  # warm: nothing compiled
    "dense_census.py": [str(BENCHMARKS.parent / "tests/corpus/lpy/real/abop_chap1_lsystem1.4.lpy")],
    "profile_memory.py": ["koch", "-n", "2"],
}


def test_every_benchmark_has_a_smoke_run():
    scripts = {p.name for p in BENCHMARKS.glob("*.py")} - {"timing.py"}  # timing.py: their shared helpers
    assert scripts == set(SMOKE)


@pytest.mark.parametrize("script", sorted(SMOKE))
def test_the_benchmark_runs(script, tmp_path):
    done = subprocess.run(
        [sys.executable, str(BENCHMARKS / script), *SMOKE[script]],
        cwd=tmp_path,  # anything a benchmark leaves behind stays out of the checkout
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, f"{script} failed:\n{done.stdout[-2000:]}\n{done.stderr[-4000:]}"
    assert done.stdout.strip(), f"{script} printed nothing"
