"""The examples in README.md and docs/ run, so they cannot rot."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import lsys3d

ROOT = Path(__file__).resolve().parent.parent
DOCS = sorted([ROOT / "README.md", *(ROOT / "docs").glob("*.md"), *(ROOT / "docs" / "dialects").glob("*.md")])


def blocks(lang: str):
    for path in DOCS:
        text = path.read_text(encoding="utf-8")
        for k, m in enumerate(re.finditer(rf"```{lang}\n(.*?)```", text, re.DOTALL)):
            yield pytest.param(m.group(1), id=f"{path.name}-{lang}-{k}")


@pytest.mark.parametrize(
    "path", [p for p in DOCS if "```python" in p.read_text(encoding="utf-8")], ids=lambda p: p.name
)
def test_python_examples_run(path, tmp_path, monkeypatch):
    """A page's ``python`` blocks run in order, in one namespace, as a reader would type them."""
    monkeypatch.chdir(tmp_path)
    namespace = {"__name__": "__doc_example__"}
    text = path.read_text(encoding="utf-8")
    for m in re.finditer(r"```python\n(.*?)```", text, re.DOTALL):
        line = text.count("\n", 0, m.start()) + 2
        exec(compile("\n" * (line - 1) + m.group(1), str(path), "exec"), namespace)


@pytest.mark.parametrize("text", [b for b in blocks("toml") if "axiom" in b.values[0]])
def test_toml_examples_parse(text):
    g = lsys3d.Grammar.from_text(text)
    assert len(lsys3d.derive(g)) > 0


def test_architecture_names_what_exists():
    """docs/architecture.md names modules, functions and classes: each must exist, so the map cannot rot."""
    import importlib

    text = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    paths = set(re.findall(r"`((?:lsys3d|tests|benchmarks|assets)/[\w/.]+)`", text))
    assert len(paths) >= 20
    for path in sorted(paths):
        assert (ROOT / path.rstrip("/")).exists(), f"docs/architecture.md names {path}, which does not exist"
    # every options class of the table lives in the module the table names
    for cls, module in re.findall(r"^\| `(\w+Options|Limits)` \| `lsys3d/([\w/]+)\.py` \|", text, re.MULTILINE):
        name = "lsys3d." + module.replace("/", ".").removesuffix(".__init__")
        assert hasattr(importlib.import_module(name), cls), f"{cls} is not in {name}"
    # every stage function of the stage table is in its module
    for module, function in re.findall(r"^\| \w+ \| `lsys3d/([\w/]+)\.py` \| `([\w.]+)", text, re.MULTILINE):
        obj = importlib.import_module("lsys3d." + module.replace("/", ".").removesuffix(".__init__"))
        for part in function.split("."):
            obj = getattr(obj, part.split("(")[0])
    # every module of the package appears on the page
    modules = {p.relative_to(ROOT).as_posix() for p in (ROOT / "lsys3d").rglob("*.py") if p.name != "__init__.py"}
    missing = sorted(m for m in modules if m not in text and m.split("/")[-1] not in ("__main__.py",))
    assert not missing, f"docs/architecture.md does not mention {missing}"


@pytest.mark.parametrize("text", [b for b in blocks("toml") if "[[jobs]]" in b.values[0]])
def test_jobs_file_examples_parse(text, tmp_path):
    """A jobs file in the docs reads (the grammar files it names exist beside it, as one would have them)."""
    from lsys3d.library.jobs import read_jobs

    for name in re.findall(r'"([\w/]+\.toml)"', text):
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text('axiom = "F"\nrules = ["F -> F[+F]F"]\n')
    path = tmp_path / "jobs.toml"
    path.write_text(text)
    assert read_jobs(path)


@pytest.mark.parametrize("path", sorted((ROOT / "docs" / "looks").glob("*.toml")), ids=lambda p: p.name)
def test_looks_grammars_grow(path, tmp_path):
    """The example grammars of docs/looks.md grow with the textures and models beside them, and export."""
    tree = lsys3d.generate(path, iterations=3)
    assert tree.materials and tree.bark.is_watertight
    lsys3d.export(tree, tmp_path / "look.glb")
    lsys3d.export(tree, tmp_path / "look.usdz")


@pytest.mark.parametrize("name", ["abop", "lpy", "cpfg", "lparser", "houdini"])
def test_each_dialect_has_a_page_with_its_generated_table(name):
    from lsys3d.lsystem.dialects import table_markdown

    text = (ROOT / "docs" / "dialects" / f"{name}.md").read_text(encoding="utf-8")
    assert table_markdown(name) in text
    for section in ("## What is read", "## The symbols", "## What is refused", "## A worked example"):
        assert section in text, section
