"""The watch over numba's compilation of lsys3d's kernels (what the CLI shows on a first run)."""

from __future__ import annotations

import ast
import functools
import importlib
import json
import os
import pkgutil
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import first_run
import numba
import numpy as np
import pytest
from shared import shared

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


def test_only_stops_at_a_kernel_of_another_module():
    mine, other = _kernel("lsys3d.for_the_test.mine"), _kernel("lsys3d.for_the_test_other")
    with compiling.only(("lsys3d.for_the_test.mine",)):
        assert mine(2) == 4
        with pytest.raises(compiling.ForeignKernel, match="for_the_test_other"):
            other(2)
    assert other(2) == 4  # outside: compiled as ever


class _FakeHelper:
    """Stands in for a helper process: records when it is waited for."""

    def __init__(self, own, log):
        self.own, self.log = own, log

    def covers(self, dispatcher) -> bool:
        return dispatcher.py_func.__module__.startswith(self.own)

    def wait(self) -> None:
        self.log.append("waited")

    def idle(self) -> None:
        pass


def test_the_main_process_waits_for_the_helper_before_compiling_one_of_its_kernels(monkeypatch):
    log = []
    helper = _FakeHelper(("lsys3d.for_the_test.helped",), log)
    monkeypatch.setattr(compiling, "_helpers", [helper])
    gate = compiling._Gate()
    helped, other = _kernel("lsys3d.for_the_test.helped"), _kernel("lsys3d.for_the_test.main")
    with compiling.watch(lambda done, total, name: log.append(name)):
        compiling.event.register("numba:compile", gate)
        try:
            other(1)
            assert log == ["_kernel.<locals>.double"]  # not the helper's: no wait
            helped(1)
        finally:
            compiling.event.unregister("numba:compile", gate)
    assert log[1:] == ["waited", "_kernel.<locals>.double"] or log[1:] == ["_kernel.<locals>.double", "waited"]
    compiling.wait("lsys3d.for_the_test.helped.x")  # and before calling into its modules
    assert log[-1] == "waited"
    compiling.wait("lsys3d.elsewhere")
    assert log.count("waited") == 2


def test_no_helper_starts_when_the_kernels_are_cached(monkeypatch):
    from lsys3d.mesh import precompile

    precompile.run()  # the cleanup's kernels loaded (or compiled) in this process
    monkeypatch.setattr(compiling.subprocess, "Popen", _no_process)
    with compiling.ahead(precompile.__name__, precompile.OWN, precompile.ENTRIES) as helper:
        assert helper is None


def test_a_failing_helper_is_waited_for_and_leaves_the_compiling_to_the_main_process():
    kernel = _kernel("lsys3d.for_the_test.failing")
    with compiling.ahead("lsys3d.for_the_test_no_such_module", ("lsys3d.for_the_test.failing",), [kernel]) as helper:
        assert helper is not None and compiling._helpers == [helper]
        assert kernel(3) == 6  # waits for the helper first (the gate), then compiles it here
        assert helper.returncode not in (None, 0)
    assert compiling._helpers == []


def _spares(log):
    """Two spare groups whose compiling is only recorded in ``log``."""
    return [compiling.Spare((f"lsys3d.for_the_test.spare{i}",), lambda i=i: log.append(f"spare {i}")) for i in (0, 1)]


def test_the_first_to_claim_a_spare_group_is_the_only_one(tmp_path):
    path = str(tmp_path / "0")
    assert compiling._claim(path)
    assert not compiling._claim(path)  # (the other process, later)
    assert not compiling._claim(str(tmp_path / "gone" / "0"))  # no folder: not claimed
    assert not compiling._claim(None)


@pytest.mark.parametrize("claimed", [(), ("0",), ("1",), ("0", "1")])
def test_a_helper_compiles_the_spare_groups_after_its_own_that_the_main_process_has_not_claimed(
    tmp_path, monkeypatch, claimed
):
    for name in claimed:
        (tmp_path / name).touch()
    monkeypatch.setenv(compiling._CLAIMS, str(tmp_path))
    log = []
    compiling.help_ahead(("lsys3d.for_the_test.own",), lambda: log.append("own"), _spares(log))
    assert log == ["own"] + [f"spare {i}" for i in "01" if i not in claimed]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["0", "1"]


def _sleeping(seconds):
    """A stand-in for subprocess.Popen that starts a process sleeping ``seconds`` instead (a helper at work)."""
    popen = subprocess.Popen

    def start(args, **kw):
        return popen([sys.executable, "-c", f"import time; time.sleep({seconds})"], **kw)

    return start


def _ahead(log, spares=None):
    return compiling.ahead(
        "lsys3d.for_the_test_helper",
        ("lsys3d.for_the_test.own",),
        [_kernel("x")],
        _spares(log) if spares is None else spares,
        lambda: log.append("main only"),
    )


def test_the_main_process_compiles_the_spare_groups_while_it_waits_for_a_working_helper(monkeypatch):
    monkeypatch.setattr(compiling.subprocess, "Popen", _sleeping(1))
    log = []
    with _ahead(log) as helper:
        compiling.wait("lsys3d.elsewhere")  # not the helper's modules: no idling
        assert log == []
        assert compiling._claim(os.path.join(helper._claims, "0"))  # as the helper would, done with its own
        compiling.wait("lsys3d.for_the_test.own.x")
        assert log == ["main only", "spare 1"]  # then the group the helper had not claimed
        compiling.wait("lsys3d.for_the_test.own.x")  # once
    assert log == ["main only", "spare 1"]


def test_the_main_process_waits_for_the_helper_before_compiling_a_spare_kernel_the_helper_claimed(monkeypatch):
    monkeypatch.setattr(compiling.subprocess, "Popen", _sleeping(1))
    log = []
    spare0, spare1 = _kernel("lsys3d.for_the_test.spare0"), _kernel("lsys3d.for_the_test.spare1")
    with _ahead(log) as helper:
        assert compiling._claim(os.path.join(helper._claims, "1"))  # as the helper would
        assert spare0(2) == 4  # not claimed: this process claims it and compiles it at once
        assert helper.returncode is None and helper.spare_is_mine(0)
        assert spare1(2) == 4  # the gate waited for the helper first
        assert helper.returncode == 0
        compiling.wait("lsys3d.for_the_test.own.x")
    assert log == []  # no idling: the helper had ended


_DEFAULT_TREE = """
import json, sys
import lsys3d
from lsys3d import compiling, firstrun
from lsys3d.mesh import precompile

def own_signatures():
    own = [
        k
        for k in compiling.kernels()
        if k.py_func.__module__.startswith(precompile.OWN) and not any(s.covers(k) for s in firstrun.SPARES)
    ]
    return {f"{k.py_func.__module__}.{k.py_func.__qualname__}": len(k.signatures) for k in own if k.signatures}

with compiling.only(precompile.OWN, but=tuple(name for spare in firstrun.SPARES for name in spare.names)):
    precompile.run()  # as in the helper
helped = own_signatures()
lsys3d.export(lsys3d.generate(lsys3d.load(lsys3d.DEFAULT_PRESET)), sys.argv[1])
spares = {}
for table in (firstrun.SIGNATURES, firstrun.MAIN_ONLY):
    for k, declared in table.items():
        spares[k.py_func.__qualname__] = [sorted(map(str, k.signatures)), sorted(str(tuple(s)) for s in declared)]
entries = sorted(f"{k.py_func.__module__}.{k.py_func.__qualname__}" for k in precompile.ENTRIES)
print(json.dumps({"helped": helped, "after": own_signatures(), "entries": entries, "spares": spares}))
"""


@functools.cache
def _default_tree() -> dict:
    """What the default tree asks of the helper's kernels and of the spare ones, from a process of its own with the
    suite's (warm) cache: ``helped``, the signatures of the helper's own kernels after it ran alone (the number of
    each kernel's); ``after``, the same after the default tree was grown and written; ``entries``, precompile's
    ENTRIES; ``spares``, each spare (and main-only) kernel's signatures called and declared.  One process for the
    two tests below (once in the run: tests/shared.py)."""

    def run() -> dict:
        with tempfile.TemporaryDirectory(prefix="lsys3d-default-tree-") as scratch:
            command = [sys.executable, "-c", _DEFAULT_TREE, os.path.join(scratch, "tree.glb")]
            out = subprocess.run(command, capture_output=True, text=True, check=True)
        return json.loads(out.stdout.splitlines()[-1])

    return shared("compiling-default-tree", run)


_SPARE_ALONE = """
import json, shutil, sys
from pathlib import Path
from lsys3d import compiling, firstrun
from lsys3d.mesh import precompile

# the helper's own kernels' cache files, copied from the suite's cache into this process's empty one
sources = json.loads(sys.argv[1])
for k in compiling.kernels():
    name = f"{k.py_func.__module__}.{k.py_func.__qualname__}"
    if name in sources:
        Path(k._cache._cache_path).mkdir(parents=True, exist_ok=True)
        base = k._cache._cache_file._index_name[: -len(".nbi")]
        for path in Path(sources[name]).glob(f"{base}.*"):
            shutil.copyfile(path, Path(k._cache._cache_path) / path.name)
with compiling.only(precompile.OWN, but=tuple(name for spare in firstrun.SPARES for name in spare.names)):
    precompile.run()  # the helper's own kernels first, as in the helper (loaded: copied above)
for spare in firstrun.SPARES:
    with compiling.only(spare.names):  # as in the helper
        spare.compile()
print("ok")
"""


def _helpers_own_cache() -> dict[str, str]:
    """The helper's own kernels (precompile.OWN's, but the spare groups') and the folder of each one's files in
    this process's cache (the suite's)."""
    from lsys3d import firstrun
    from lsys3d.mesh import precompile

    return {
        f"{k.py_func.__module__}.{k.py_func.__qualname__}": k._cache._cache_path
        for k in compiling.kernels()
        if k.py_func.__module__.startswith(precompile.OWN) and not any(s.covers(k) for s in firstrun.SPARES)
    }


def test_the_spare_kernels_are_compiled_for_the_signatures_the_default_tree_asks_for(tmp_path):
    """The default tree calls the spare kernels with the signatures firstrun declares, no other, and SIGNATURES
    holds the kernels of SPARES; compiled after the helper's own kernels in a cache that holds nothing else (but
    numba's), each spare group compiles nothing outside its names, as the helper needs.

    The helper's own kernels are not compiled again for it (13 CPU s in a cache of its own): their files are
    copied from the suite's cache into an empty one (every kernel of precompile.OWN's modules but the spare
    groups', each with the signatures the suite compiled: the helper's, and any a test asked for besides), so a
    spare group that calls any other lsys3d kernel (or a spare kernel of another group) compiles it, which
    ``only`` stops.  A spare group that would need one of the helper's own kernels for a signature the helper
    does not compile is the first-run test's to see: its main process would compile that kernel (never one of
    the helper's, that test asserts)."""
    for name, (called, declared) in _default_tree()["spares"].items():
        assert called == declared, name
    from lsys3d import firstrun

    for kernel in firstrun.SIGNATURES:
        assert [spare for spare in firstrun.SPARES if spare.covers(kernel)], kernel
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    command = [sys.executable, "-c", _SPARE_ALONE, json.dumps(_helpers_own_cache())]
    out = subprocess.run(command, capture_output=True, text=True, env=env)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr[-2000:]


def _no_process(*args, **kw):
    raise AssertionError("a warm run started a helper process")


def test_the_helper_compiles_the_signatures_the_default_trees_cleanup_asks_for():
    """What the helper compiles is what the cleanup of the default tree calls, type for type (but the spare
    groups'): the tree asks for no signature of the cleanup's kernels that the helper did not make, and ENTRIES
    are the kernels the helper calls from Python (the ones the main process checks the cache for)."""
    tree = _default_tree()
    assert tree["after"] == tree["helped"]
    assert sorted(tree["helped"]) == tree["entries"]


@pytest.mark.slow
def test_a_first_run_shows_its_compiling_compiles_the_cleanup_in_a_helper_and_writes_the_same_bytes(tmp_path):
    """From an empty kernel cache, ``lsys3d generate`` (the default tree) shows "compiling lsys3d's kernels
    (first run only)" with its count on a terminal, starts the helper, compiles none of the cleanup's kernels
    itself (so never one the helper compiles), and writes the bytes a warm run does.

    The run looked at is the session's own when the suite started from an empty cache (a fresh clone, CI:
    ``pytest_sessionstart`` ran it, tests/first_run.py, and its kernels are the suite's); when the cache was
    warm, this test does the same run itself, in a temporary cache (compiling every kernel of the default
    tree, a minute of CPU)."""
    from lsys3d import firstrun
    from lsys3d.mesh import precompile

    record = first_run.session_record()
    if record is None or record.get("loaded"):  # a warm (or partly warm) cache at the session's start
        record = first_run.run(tmp_path / "cold", cache=tmp_path / "cache")
    assert record["returncode"] == 0 and record["code"] == 0, record["stderr"][-3000:]
    assert record["loaded"] == []  # nothing came from a cache but the helper's kernels
    assert record["compiled"] and record["helped"]
    assert not [
        m
        for m in record["compiled"]
        if m.startswith(precompile.OWN) and not any(m.startswith(spare.names) for spare in firstrun.SPARES)
    ]
    shown = re.findall(r"compiling lsys3d's kernels \(first run only\): (\d+) of up to (\d+)", record["stderr"])
    assert shown and all(0 < int(done) <= int(total) for done, total in shown)
    assert [int(done) for done, _ in shown] == sorted(int(done) for done, _ in shown)
    assert record["stdout"].startswith("wrote ")
    warm = tmp_path / "warm.glb"
    subprocess.run([sys.executable, "-m", "lsys3d", "generate", "-q", "-o", str(warm)], check=True)
    assert Path(record["output"]).read_bytes() == warm.read_bytes()


def _kernel_decorated(fn: ast.FunctionDef) -> str | None:
    """``"inner"`` or ``"kernel"`` for a function compiled by numba (lsys3d.compiling's decorators, or the
    remesh package's names for them), None for a plain function."""
    for decorator in fn.decorator_list:
        text = ast.unparse(decorator)
        if text.startswith(("inner(", "_leaf_inner", "_inline_inner")):
            return "inner"
        if text.startswith(("kernel(", "_leaf", "_inline", "numba.njit", "njit")):
            return "kernel"
    return None


def _python_names(tree: ast.AST) -> set[str]:
    """The names that code outside kernels mentions (as a name or an attribute): what Python may call."""
    names: set[str] = set()

    def visit(node: ast.AST, in_kernel: bool) -> None:
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            in_kernel = in_kernel or _kernel_decorated(node) is not None
        elif not in_kernel and isinstance(node, ast.Name):
            names.add(node.id)
        elif not in_kernel and isinstance(node, ast.Attribute):
            names.add(node.attr)
        for child in ast.iter_child_nodes(node):
            visit(child, in_kernel)

    visit(tree, False)
    return names


def test_no_python_code_names_a_kernel_compiled_for_kernels_only():
    """An ``inner`` kernel has no CPython wrapper: the package, its tests, benchmarks and tools call it only from
    other kernels (a name shared with a plain function counts too: rename one of them)."""
    root = Path(compiling.__file__).parent.parent
    sources = [p for d in ("lsys3d", "tests", "benchmarks", "tools") for p in (root / d).rglob("*.py")]
    texts = {p: p.read_text(encoding="utf-8") for p in sources}
    # (only the files whose text could hold what is looked for are parsed: every decorator of an inner kernel has
    # "inner" in its name, and a file that does not hold a kernel's name as a word cannot name it)
    inner = {
        node.name: p.relative_to(root)
        for p, text in texts.items()
        if "inner" in text
        for node in ast.walk(ast.parse(text))
        if isinstance(node, ast.FunctionDef) and _kernel_decorated(node) == "inner"
    }
    assert len(inner) > 50
    word = re.compile(r"\b(?:" + "|".join(map(re.escape, sorted(inner))) + r")\b")
    named = set().union(*(_python_names(ast.parse(text)) for text in texts.values() if word.search(text)))
    assert {name: str(path) for name, path in inner.items() if name in named} == {}


def test_a_kernel_compiled_for_kernels_only_raises_when_python_calls_it():
    from lsys3d.mesh.remesh import halfedge

    name = "_nxt"  # (by its name: the test above finds no Python code naming an inner kernel)
    nxt = getattr(halfedge, name)
    assert isinstance(nxt, compiling.InnerKernel)
    with pytest.raises(TypeError, match=r"halfedge\._nxt: compiled for other kernels only"):
        nxt(4)


def test_every_kernel_is_compiled_without_the_wrappers_it_does_not_need():
    """Every kernel of the package comes from :func:`compiling.kernel` or :func:`compiling.inner`: no C-function
    wrapper, and no CPython wrapper for the kernels only kernels call."""
    import lsys3d

    root = Path(lsys3d.__file__).parent
    for info in pkgutil.walk_packages([str(root)], "lsys3d."):
        if not info.name.startswith(("lsys3d.blender", "lsys3d.edit")) and not info.name.endswith("__main__"):
            importlib.import_module(info.name)
    found = compiling.kernels()
    assert len(found) > 150
    assert [k.py_func.__qualname__ for k in found if not k.targetoptions.get("no_cfunc_wrapper")] == []
    inner = [k for k in found if isinstance(k, compiling.InnerKernel)]
    assert inner and all(k.targetoptions.get("no_cpython_wrapper") for k in inner)
