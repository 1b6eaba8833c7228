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

import logging
import os
from pathlib import Path

try:
    from pluggy import HookimplMarker  # pytest's hook marker (pytest.hookimpl) without importing pytest

    _hookimpl = HookimplMarker("pytest")
except ImportError:  # no pytest here: the plugin's hooks are never called

    def _hookimpl(**_):
        return lambda fn: fn


__all__ = ["GoldenMismatch", "assert_matches_golden", "update_requested"]

log = logging.getLogger("lsys3d")

_UPDATE_OPTION = "--lsys3d-update-golden"
_update_from_pytest = False
_updates: list[tuple[Path, str]] = []
"""What the updates since the pytest plugin last looked changed: each golden file and one text for it."""
_reported: list[str] = []
"""The updates of the whole pytest run (the controlling process's, under pytest-xdist), for its summary."""

TABLE_ROWS = 16
"""Most rows of the table of differences in a failure's message (the failed keys first)."""


class GoldenMismatch(AssertionError):
    """A tree does not match its golden file (an ``AssertionError``: any test runner reports it as a failure).

    Its message is the whole report, the table of differences first; the pytest plugin shows it alone, without
    the traceback through this module.
    """


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
        The golden file (JSON, see :mod:`lsys3d.golden.golden`); its folder is created when recorded.
    update : bool, optional
        Write the file instead of failing when it is missing or differs;
        defaults to :func:`update_requested`.  What an update changed is
        logged (``updated golden/oak.json: bark.faces: 37,770 -> 37,820 ...``)
        and listed at the end of a pytest run.
    rtol : float, optional
        Relative tolerance of floating values (default :data:`lsys3d.golden.golden.RTOL`).

    Raises
    ------
    GoldenMismatch
        An ``AssertionError``: the file is missing, was recorded for another
        recipe (grammar, iterations, seed or options), or a count or measure
        differs.  The message starts with what differs, counts and values
        apart (``2 counts differ, 1 value (bark.area) differs beyond
        tolerance``), then the table of differences (at most
        :data:`TABLE_ROWS` rows, the failed first) and how to update.
    """
    __tracebackhide__ = True  # pytest: the failure is the test's line, not this helper's source
    from .golden.golden import (
        RTOL,
        compare,
        format_changes,
        format_differences,
        read_golden,
        recipe_for,
        summarize,
        write_golden,
    )
    from .stats import report

    path = Path(path)
    update = update_requested() if update is None else update
    recipe = recipe_for(tree, golden_path=path)
    actual = report(tree.modules, tree.skeleton, tree)
    how = f"to record the new counts: pytest {_UPDATE_OPTION} (or LSYS3D_UPDATE_GOLDEN=1)"
    if not path.exists():
        if update:
            write_golden(path, recipe, actual)
            _updated(path, f"recorded (a new golden file for {recipe.describe()})")
            return
        raise GoldenMismatch(f"{path}: no golden file yet; {how}")
    recorded_recipe, recorded = read_golden(path)
    if _identity(recorded_recipe) != _identity(recipe):
        if update:
            write_golden(path, recipe, actual)
            _updated(path, f"recorded anew for {recipe.describe()} (was {recorded_recipe.describe()})")
            return
        raise GoldenMismatch(
            f"{path}: recorded for {recorded_recipe.describe()}, but this tree is {recipe.describe()}; {how}"
        )
    differences, warnings = compare(recorded, actual, RTOL if rtol is None else rtol)
    if update and (differences or recorded != actual):
        write_golden(path, recipe, actual)
        n = len(differences)
        _updated(path, f"{n} key{'s' if n > 1 else ''}\n{format_changes(differences)}" if n else "only the versions")
        return
    if any(d.failed for d in differences):
        notes = "".join(f"\n  warning: {w}" for w in warnings)
        raise GoldenMismatch(
            f"{path}: {summarize(differences)}\n{format_differences(differences, TABLE_ROWS)}{notes}\n{how}"
        )


def _updated(path: Path, what: str) -> None:
    text = f"updated {path}: {what}"
    _updates.append((path, text))
    log.warning("%s", text)


def _identity(recipe) -> tuple:
    """What names the asset (the grammar's hash aside: a changed grammar shows as changed counts)."""
    return recipe.preset, recipe.file, recipe.text, recipe.iterations, recipe.seed, recipe.mesh, recipe.options


# ---------------------------------------------------------------- pytest plugin (entry point "pytest11")
_UPDATES_KEY = "lsys3d_golden_updates"


class _Failure:
    """A golden mismatch as pytest shows it: the test's line and the message, no traceback (``--tb=long`` or
    ``native`` still show it); ``reprcrash`` gives the short summary's line."""

    def __init__(self, where: str, message: str):
        self.text = f"{where}: {message}" if where else message
        self.reprcrash = self
        self.message = message

    def toterminal(self, tw) -> None:
        for line in self.text.splitlines():
            tw.line(line)

    def __str__(self) -> str:
        return self.text


def _test_line(item, excinfo) -> str:
    """``path:line`` of the test's own call: the innermost frame in the test's file."""
    fspath = str(getattr(item, "path", ""))
    for entry in reversed(excinfo.traceback):
        if str(entry.path) == fspath:
            return f"{os.path.relpath(fspath, item.config.rootpath)}:{entry.lineno + 1}"
    return ""


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
    _reported.clear()


@_hookimpl(wrapper=True)
def pytest_runtest_makereport(item, call):
    report = yield
    if _updates:
        # the project's golden files: those a test records in a temporary folder (pytest's tmp_path, anything
        # outside the rootdir) stay in the test's log, not in the run's summary
        factory = getattr(item.config, "_tmp_path_factory", None)
        temporary = factory.getbasetemp() if factory is not None else None
        listed = [
            text
            for path, text in _updates
            if _inside(path, item.config.rootpath) and not (temporary is not None and _inside(path, temporary))
        ]
        if listed:
            report.user_properties.append((_UPDATES_KEY, listed))
        _updates.clear()
    excinfo = call.excinfo
    if (
        excinfo is not None
        and excinfo.errisinstance(GoldenMismatch)
        and item.config.getoption("tbstyle", "auto") in ("auto", "short")
    ):
        report.longrepr = _Failure(_test_line(item, excinfo), str(excinfo.value))
    return report


def _inside(path: Path, root: Path) -> bool:
    """Whether ``path`` lies in the folder ``root`` (both resolved: a symlinked temporary folder is not)."""
    return Path(path).resolve().is_relative_to(Path(root).resolve())


def pytest_runtest_logreport(report):
    for key, texts in getattr(report, "user_properties", ()):
        if key == _UPDATES_KEY:
            _reported.extend(texts)


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    if _reported:
        terminalreporter.section("lsys3d golden files updated")
        for text in _reported:
            for line in text.splitlines():
                terminalreporter.line(line)
