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


@pytest.mark.parametrize("code", list(blocks("python")))
def test_python_examples_run(code, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    exec(compile(code, "<doc example>", "exec"), {"__name__": "__doc_example__"})


@pytest.mark.parametrize("text", [b for b in blocks("toml") if "axiom" in b.values[0]])
def test_toml_examples_parse(text):
    g = lsys3d.Grammar.from_text(text)
    assert len(lsys3d.derive(g)) > 0
