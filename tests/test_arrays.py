"""lsys3d.arrays' compiled helpers, against numpy."""

from __future__ import annotations

import numpy as np
import pytest

from lsys3d.arrays import sort_between


@pytest.mark.parametrize("dtype", [np.int32, np.int64])
def test_sort_between_sorts_the_slice_as_numpy_does_and_nothing_else(dtype):
    rng = np.random.default_rng(7)
    for n in (0, 1, 2, 3, 17, 100, 1000):
        a = rng.integers(-50, 50, n + 10).astype(dtype)
        lo, hi = 4, 4 + n
        want = a.copy()
        want[lo:hi] = np.sort(a[lo:hi])
        sort_between(a, lo, hi)
        assert a.dtype == dtype and a.tolist() == want.tolist()
