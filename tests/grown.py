"""Each bundled preset grown once per test run, shared by the test modules (and the xdist workers) that look at
it (:func:`shared.shared`)."""

from __future__ import annotations

import functools

from shared import shared

import lsys3d
from lsys3d.lsystem.presets import preset_info
from lsys3d.pipeline import generate


@functools.cache
def grown(name: str):
    """The preset's tree at its own iterations and seed (grown on first use in the run, then shared)."""
    return shared(f"grown-{name}", lambda: generate(name))


def species() -> list[str]:
    """The bundled presets of the group ``species``, sorted."""
    return list(_species())


@functools.cache
def _species() -> tuple[str, ...]:
    # (read once per process: the parametrize lists of three test modules ask while pytest collects, and each
    # preset's group means loading the whole preset)
    return tuple(name for name in lsys3d.list_presets() if preset_info(name).group == "species")
