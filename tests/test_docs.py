"""The examples in README.md and docs/ run, so they cannot rot."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import lsys3d

ROOT = Path(__file__).resolve().parent.parent
DOCS = sorted([ROOT / "README.md", *(ROOT / "docs").glob("*.md")])


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


@pytest.mark.parametrize("text", [b for b in blocks("toml") if "[[jobs]]" in b.values[0]])
def test_jobs_file_examples_parse(text, tmp_path):
    """A jobs file in the docs reads (the grammar files it names exist beside it, as one would have them)."""
    from lsys3d.jobs import read_jobs

    for name in re.findall(r'"([\w/]+\.toml)"', text):
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text('axiom = "F"\nrules = ["F -> F[+F]F"]\n')
    path = tmp_path / "jobs.toml"
    path.write_text(text)
    assert read_jobs(path)
