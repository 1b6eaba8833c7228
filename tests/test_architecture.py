"""The package's shape, read from the source with ``ast`` (nothing is imported).

- A module imports only its own stage, earlier stages and the shared modules (``docs/architecture.md``).
- No import cycle among lsys3d's modules at module level.
- Few imports inside functions: lazy loading belongs in the entry points (the package root's ``__getattr__``,
  the command line), not scattered through the stages to dodge cycles.
- No module longer than ``MAX_LINES``, but for the known exceptions listed once below.
"""

from __future__ import annotations

import ast
import functools
import subprocess
import sys
from pathlib import Path

import pytest
from shared import shared

PACKAGE = Path(__file__).resolve().parents[1] / "lsys3d"

# The pipeline's order, one entry per stage: a package (every module under it), or a set of top-level modules.
# A module may import modules of its own stage and of earlier ones, never of a later one.
STAGES = (
    "lsys3d.lsystem",
    "lsys3d.turtle",
    "lsys3d.mesh",
    "lsys3d.look",
    {"lsys3d.tree", "lsys3d.pipeline", "lsys3d.stats"},  # the assembly: the stages run in order into a Tree
    "lsys3d.exchange",
    "lsys3d.render",
    "lsys3d.golden",
    "lsys3d.library",
    "lsys3d.edit",  # the editor: a server over the whole pipeline and its writers
    "lsys3d.blender",  # the Blender add-on: a plant grown into Blender's data (imports bpy; runs inside Blender)
    # the entry points (testing: the pytest plugin; firstrun: a first run's helper process, python -m)
    {"lsys3d", "lsys3d.cli", "lsys3d.__main__", "lsys3d.testing", "lsys3d.firstrun"},
)

# Importable by every stage; a shared module imports only shared modules.
SHARED = {
    "lsys3d.errors",
    "lsys3d.arrays",
    "lsys3d.options",
    "lsys3d.streams",
    "lsys3d.version",
    "lsys3d.provenance",
    "lsys3d.external",
    "lsys3d.images",
    "lsys3d.noise",
    "lsys3d.compiling",
    "lsys3d.cachelock",
    # The turtle's command table (symbol, name, kind, arguments): the vocabulary the dialects (lsystem) declare
    # their own rows of. It imports nothing of lsys3d.
    "lsys3d.turtle.commands",
}

# Where lazy loading belongs: the entry points may import inside functions as much as they like.
ENTRY_POINTS = {"lsys3d", "lsys3d.cli"}
MAX_FUNCTION_IMPORTS = 10

MAX_LINES = 1200
# Longer than MAX_LINES: none.  Do not add to this list: split the module instead (by step, one operation a file).
TOO_LONG: set[str] = set()


def _modules() -> dict[str, Path]:
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


MODULES = _modules()


def _type_checking(node: ast.AST) -> bool:
    test = getattr(node, "test", None)
    return isinstance(node, ast.If) and (
        (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING")
        or (isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")
    )


def _is_import_module(func: ast.expr) -> bool:
    return (isinstance(func, ast.Attribute) and func.attr == "import_module") or (
        isinstance(func, ast.Name) and func.id == "import_module"
    )


def _targets(module: str, node: ast.Import | ast.ImportFrom) -> list[str]:
    """The lsys3d modules an import statement in ``module`` loads (a name imported from a package may be one)."""
    if isinstance(node, ast.Import):
        return [a.name for a in node.names if a.name.split(".")[0] == "lsys3d"]
    if node.level:
        base = module.split(".")
        if MODULES[module].name != "__init__.py":
            base = base[:-1]
        base = base[: len(base) - node.level + 1]
        full = ".".join(base + ([node.module] if node.module else []))
    else:
        full = node.module or ""
    if full.split(".")[0] != "lsys3d":
        return []
    out = []
    for alias in node.names:
        sub = f"{full}.{alias.name}"
        out.append(sub if sub in MODULES else full)
    return out


def _imports(module: str) -> tuple[list[tuple[str, int]], list[tuple[str, int]]]:
    """``(module level, inside functions)``: the lsys3d modules ``module`` imports, with line numbers
    (inside functions, one entry per statement; a call of ``importlib.import_module`` counts as one).

    Imports under ``if TYPE_CHECKING:`` are left out: they never run.
    """
    text = MODULES[module].read_text(encoding="utf-8")
    tree = ast.parse(text)
    # an import is a statement: only a call of import_module hides in an expression (most of a module's nodes)
    statements_only = "import_module" not in text
    top: list[tuple[str, int]] = []
    late: list[tuple[str, int]] = []

    def walk(node: ast.AST, in_function: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if _type_checking(child) or (statements_only and isinstance(child, ast.expr)):
                continue
            inside = in_function or isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda)
            if isinstance(child, ast.Import | ast.ImportFrom):
                targets = _targets(module, child)
                if inside and targets:  # one statement, one late import
                    late.append((", ".join(sorted(set(targets))), child.lineno))
                elif not inside:
                    top.extend((t, child.lineno) for t in targets)
            elif isinstance(child, ast.Call) and _is_import_module(child.func):  # a late import by name
                late.append(("importlib.import_module", child.lineno))
            walk(child, inside)

    walk(tree, False)
    return top, late


@functools.cache
def _all_imports() -> dict[str, tuple[list[tuple[str, int]], list[tuple[str, int]]]]:
    """:func:`_imports` of every module, read when a test first asks (not while pytest collects the suite, in
    every worker), once in the run (tests/shared.py)."""
    return shared("architecture-imports", lambda: {m: _imports(m) for m in MODULES})


def _existing(name: str) -> str:
    """The module a dotted name loads: itself, or the package it is an attribute of."""
    while name not in MODULES:
        name = name.rsplit(".", 1)[0]
    return name


def _stage(module: str) -> int | None:
    """The index of ``module``'s stage in STAGES; -1 for a shared module; None if it has none."""
    if module in SHARED:
        return -1
    for i, stage in enumerate(STAGES):
        if isinstance(stage, str) and (module == stage or module.startswith(stage + ".")):
            return i
        if isinstance(stage, set) and module in stage:
            return i
    return None


def _name(index: int) -> str:
    stage = STAGES[index]
    return stage if isinstance(stage, str) else "/".join(sorted(stage))


def test_every_module_has_a_stage():
    assert [m for m in MODULES if _stage(m) is None] == [], "add the module to STAGES or SHARED"


@pytest.mark.parametrize("module", sorted(MODULES))
def test_no_module_imports_a_later_stage(module):
    mine = _stage(module)
    wrong = []
    for target, line in _all_imports()[module][0]:
        target = _existing(target)
        theirs = _stage(target)
        if mine == -1 and theirs != -1:
            wrong.append(f"line {line}: {target} (a shared module imports only shared modules)")
        elif theirs is not None and mine is not None and theirs > mine:
            wrong.append(f"line {line}: {target} ({_name(theirs)} comes after {_name(mine)})")
    assert wrong == [], f"{module} imports a later stage: " + "; ".join(wrong)


def _graph() -> dict[str, set[str]]:
    """Module-level import edges.  Importing ``a.b.c`` first runs the packages ``a`` and ``a.b``: an import
    depends on those packages too, unless they already enclose the importer (then they are running already)."""
    graph: dict[str, set[str]] = {m: set() for m in MODULES}
    for module, (top, _) in _all_imports().items():
        enclosing = {module.rsplit(".", k)[0] for k in range(module.count(".") + 1)}
        for target, _line in top:
            target = _existing(target)
            parts = target.split(".")
            for k in range(1, len(parts) + 1):
                step = ".".join(parts[:k])
                if step in MODULES and step not in enclosing and step != module:
                    graph[module].add(step)
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan, iteratively)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    found = []
    counter = 0
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            advanced = False
            for child in children:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                    advanced = True
                    break
                if child in on_stack:
                    low[node] = min(low[node], index[child])
            if advanced:
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return found


def test_the_cycle_finder_finds_a_cycle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_cycle():
    assert _cycles(_graph()) == []


def test_few_imports_inside_functions():
    late = [
        f"{MODULES[m].relative_to(PACKAGE.parent)}:{line} {target}"
        for m, (_, inside) in sorted(_all_imports().items())
        if m not in ENTRY_POINTS
        for target, line in inside
    ]
    assert len(late) <= MAX_FUNCTION_IMPORTS, "imports of lsys3d modules inside functions:\n" + "\n".join(late)


def test_the_import_reader_sees_late_imports():
    top, inside = _all_imports()["lsys3d.cli"]
    assert any(t.startswith("lsys3d.") for t, _ in top)
    assert any(t.startswith("lsys3d.") for t, _ in inside)  # the subcommands' modules, loaded when they run


def test_no_module_is_too_long():
    lengths = {
        str(p.relative_to(PACKAGE.parent)): len(p.read_text(encoding="utf-8").splitlines()) for p in MODULES.values()
    }
    long = {path: n for path, n in lengths.items() if n > MAX_LINES}
    assert set(long) - TOO_LONG == set(), f"modules over {MAX_LINES} lines: {long}"
    assert TOO_LONG - set(long) == set(), "split already: remove it from TOO_LONG"


HEAVY = ("numpy", "numba", "pxr", "dask", "distributed", "trimesh", "manifold3d", "starlette", "uvicorn")


@pytest.mark.parametrize(
    "code",
    [
        "import lsys3d",
        "from lsys3d.cli import main\ntry:\n    main(['--help'])\nexcept SystemExit:\n    pass",
    ],
    ids=["import lsys3d", "lsys3d --help"],
)
def test_the_entry_points_load_no_heavy_module(code):
    """The package root and the command line import a stage's modules when it is used, not before."""
    check = f"{code}\nimport sys\nprint('loaded:', *(m for m in {HEAVY!r} if m in sys.modules))"
    done = subprocess.run([sys.executable, "-c", check], capture_output=True, text=True, cwd=PACKAGE.parent)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines()[-1] == "loaded:", done.stdout


def test_a_public_name_loads_its_module():
    done = subprocess.run(
        [sys.executable, "-c", "import lsys3d, sys; lsys3d.Grammar; print('lsys3d.lsystem.grammar' in sys.modules)"],
        capture_output=True,
        text=True,
        cwd=PACKAGE.parent,
    )
    assert done.stdout.strip() == "True", done.stderr
