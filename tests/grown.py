"""Each bundled preset grown once per test session, shared by the test modules that look at it."""

from __future__ import annotations

import functools

from lsys3d.pipeline import generate


@functools.cache
def grown(name: str):
    """The preset's tree at its own iterations and seed (grown on first use, then cached)."""
    return generate(name)
