"""The watch over numba's compilation of lsys3d's kernels (what the CLI shows on a first run)."""

from __future__ import annotations

import numba
import numpy as np

from lsys3d import compiling


def _kernel(module: str):
    """A fresh, uncached kernel that claims to live in ``module``."""

    def double(x):
        return 2 * x

    double.__module__ = module
    return numba.njit(double)


def test_watch_reports_each_of_lsys3ds_kernels_once():
    ours, theirs = _kernel("lsys3d.for_the_test"), _kernel("elsewhere")
    reports = []
    with compiling.watch(lambda done, total, name: reports.append((done, total, name))):
        assert ours(2) == 4 and ours(2.5) == 5.0  # two signatures, one kernel
        assert theirs(3) == 6
    assert [(done, name) for done, _, name in reports] == [(1, "_kernel.<locals>.double")]
    assert all(total >= done for done, total, _ in reports)
    ours(np.int32(1))  # after the watch: nothing reported
    assert len(reports) == 1


def test_a_kernel_with_code_counts_as_cached():
    kernel = _kernel("lsys3d.for_the_test")
    assert not compiling.is_cached(kernel)
    kernel(1)
    assert compiling.is_cached(kernel)


def test_the_loaded_modules_kernels_are_found():
    from lsys3d.turtle import kernel

    found = compiling.kernels()
    assert kernel.run in found and len(found) == len({id(k) for k in found})
