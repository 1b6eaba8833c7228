"""The command line: output, exit codes, and one clear line for every user mistake."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

import lsys3d
from lsys3d.cli import main


def run(*args, **kw):
    return subprocess.run([sys.executable, "-m", "lsys3d", *args], capture_output=True, text=True, **kw)


def test_derive_prints_the_canonical_string(capsys):
    assert main(["derive", "koch", "-n", "1"]) == 0
    assert capsys.readouterr().out == "F-F++F-F\n"


def test_derive_with_seed(capsys):
    main(["derive", "koch-stochastic", "-n", "3", "--seed", "4"])
    a = capsys.readouterr().out
    main(["derive", "koch-stochastic", "-n", "3", "--seed", "4"])
    assert capsys.readouterr().out == a


def test_presets_lists_one_line_each(capsys):
    assert main(["presets"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert any(line.startswith("koch ") for line in lines)
    assert all(len(line.split(None, 1)) == 2 for line in lines)


def test_python_dash_m_and_entry_point_agree():
    out = run("derive", "dog", "-n", "1")
    assert out.returncode == 0 and out.stdout == "GOD\n"


@pytest.mark.parametrize(
    ("text", "fragment"),
    [
        ('axiom = "F"\nrules = ["F -> F[+F"]\n', ":2:17: unbalanced '['"),
        ('axiom = "A(0)"\nrules = ["A(x) -> A(1/x)"]\n', "division by zero"),
        ("axiom = \n", ":1:9: TOML syntax error"),
    ],
)
def test_grammar_errors_are_one_line_without_traceback(tmp_path, text, fragment):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    out = run("derive", str(path))
    assert out.returncode == 1
    assert out.stdout == ""
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and fragment in lines[0] and lines[0].startswith(f"lsys3d: error: {path}")
    assert "Traceback" not in out.stderr


def test_missing_preset_and_limit_errors():
    out = run("derive", "nope")
    assert out.returncode == 1 and "no bundled preset named 'nope'" in out.stderr
    out = run("derive", "algae", "-n", "60")
    assert out.returncode == 1 and "--max-modules" in out.stderr and "Traceback" not in out.stderr


def test_usage_errors_exit_2():
    assert run("derive").returncode == 2
    assert run("frobnicate").returncode == 2
    assert run("derive", "koch", "-n", "x").returncode == 2


def test_stats_json_and_table(capsys):

    assert main(["stats", "abop-1.24a", "--json"]) == 0
    stats = json.loads(capsys.readouterr().out)
    for key in ("modules", "segments", "chains", "branches", "leaves", "bbox_min", "bbox_max", "total_length"):
        assert key in stats
    assert stats["segments"] == str(lsys3d.derive(lsys3d.load_preset("abop-1.24a"))).count("F")
    assert list(stats) == sorted(stats)
    assert main(["stats", "abop-1.24a"]) == 0
    table = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in table] == sorted(stats)
