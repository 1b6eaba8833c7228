"""Regression-test generated assets against golden files, from pytest or any test runner.

::

    from pathlib import Path

    import lsys3d
    from lsys3d.testing import assert_matches_golden

    GOLDEN = Path(__file__).parent / "golden"

    def test_oak_counts():
        tree = lsys3d.generate("assets/oak.toml", iterations=5, seed=7)
        assert_matches_golden(tree, GOLDEN / "oak.json")

The first run (or a run after a deliberate change) records the file:
``pytest --lsys3d-update-golden`` (this module is a pytest plugin, loaded
automatically once lsys3d is installed), or ``LSYS3D_UPDATE_GOLDEN=1`` in the
environment.  The same files work with ``lsys3d check tests/golden/*.json``.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["assert_matches_golden", "update_requested"]

_UPDATE_OPTION = "--lsys3d-update-golden"
_update_from_pytest = False


def update_requested() -> bool:
    """Whether golden files should be rewritten: pytest's ``--lsys3d-update-golden`` or ``LSYS3D_UPDATE_GOLDEN=1``."""
    return _update_from_pytest or os.environ.get("LSYS3D_UPDATE_GOLDEN", "").lower() in ("1", "true", "yes")


def assert_matches_golden(tree, path: str | os.PathLike, *, update: bool | None = None, rtol: float | None = None):
    """Assert that a generated tree's report matches a golden file.

    Parameters
    ----------
    tree : Tree
        From :func:`lsys3d.generate`.
    path : path-like
        The golden file (JSON, see :mod:`lsys3d.golden.golden`).
    update : bool, optional
        Write the file instead of failing when it is missing or differs;
        defaults to :func:`update_requested`.
    rtol : float, optional
        Relative tolerance of floating values (default :data:`lsys3d.golden.golden.RTOL`).

    Raises
    ------
    AssertionError
        The file is missing, was recorded for another recipe (grammar,
        iterations, seed or options), or a count or measure differs; the
        message holds the table of differences and how to update.
    """
    from .golden.golden import RTOL, compare, format_differences, read_golden, recipe_for, write_golden
    from .stats import report

    path = Path(path)
    update = update_requested() if update is None else update
    recipe = recipe_for(tree, golden_path=path)
    actual = report(tree.modules, tree.skeleton, tree)
    how = f"rerun with pytest {_UPDATE_OPTION} (or LSYS3D_UPDATE_GOLDEN=1) to record it"
    if not path.exists():
        if update:
            path.parent.mkdir(parents=True, exist_ok=True)
            write_golden(path, recipe, actual)
            return
        raise AssertionError(f"{path}: no golden file yet; {how}")
    recorded_recipe, recorded = read_golden(path)
    if _identity(recorded_recipe) != _identity(recipe):
        if update:
            write_golden(path, recipe, actual)
            return
        raise AssertionError(
            f"{path}: recorded for {recorded_recipe.describe()}, but this tree is {recipe.describe()}; {how}"
        )
    differences, warnings = compare(recorded, actual, RTOL if rtol is None else rtol)
    failed = [d for d in differences if d.failed]
    if update and (differences or recorded != actual):
        write_golden(path, recipe, actual)
        return
    if failed:
        notes = "".join(f"\n  warning: {w}" for w in warnings)
        raise AssertionError(
            f"{path}: {len(failed)} of the counts differ from the golden file ({how}){notes}\n"
            + format_differences(differences)
        )


def _identity(recipe) -> tuple:
    """What names the asset (the grammar's hash aside: a changed grammar shows as changed counts)."""
    return recipe.preset, recipe.file, recipe.text, recipe.iterations, recipe.seed, recipe.mesh, recipe.options


# ---------------------------------------------------------------- pytest plugin (entry point "pytest11")


def pytest_addoption(parser):
    parser.getgroup("lsys3d").addoption(
        _UPDATE_OPTION,
        action="store_true",
        default=False,
        help="lsys3d: record or rewrite golden files instead of failing on differences",
    )


def pytest_configure(config):
    global _update_from_pytest
    _update_from_pytest = bool(config.getoption(_UPDATE_OPTION, default=False))
