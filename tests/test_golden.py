"""Golden files: every preset's counts pinned in tests/golden, the check command, the pytest helper, determinism."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from grown import grown

import lsys3d
from lsys3d.cli import main
from lsys3d.errors import GoldenError
from lsys3d.golden.golden import Recipe, check, compare, format_differences, read_golden, recipe_for, write_golden
from lsys3d.lsystem.derive import derive
from lsys3d.stats import report
from lsys3d.testing import assert_matches_golden
from lsys3d.turtle import interpret

GOLDEN = Path(__file__).parent / "golden"
PRESETS = lsys3d.list_presets()


def test_every_preset_has_a_golden_file():
    assert sorted(p.stem for p in GOLDEN.glob("*.json")) == PRESETS


@pytest.mark.parametrize("name", PRESETS)
def test_preset_matches_its_golden_file(name):
    """Any change to derivation, turtle, sweep or union shows here as a reviewed count change.

    After a deliberate change: ``pytest tests/test_golden.py --lsys3d-update-golden`` (or
    ``lsys3d check --update tests/golden/*.json``), and review the diff of tests/golden.
    """
    path = GOLDEN / f"{name}.json"
    recipe, _ = read_golden(path)
    grammar = lsys3d.load_preset(name)
    assert (recipe.preset, recipe.iterations, recipe.seed) == (name, grammar.iterations, grammar.seed)
    if recipe.mesh:
        assert_matches_golden(grown(name), path)
    else:  # symbol-only grammars: nothing to mesh, the derivation and the turtle's counts are pinned
        modules = derive(grammar)
        actual = report(modules, interpret(modules, grammar, seed=grammar.seed))
        assert_same(path, actual)


def assert_same(path: Path, actual: dict):
    _, recorded = read_golden(path)
    differences, _ = compare(recorded, actual)
    assert not [d for d in differences if d.failed], f"{path}\n{format_differences(differences)}"


def test_report_is_stable_and_sorted():
    tree = lsys3d.generate("koch", iterations=2)
    r = report(tree.modules, tree.skeleton, tree)
    assert list(r) == ["bark", "bbox", "derive", "interpret", "leaves", "quality", "sweep", "versions"]
    for section in r.values():
        assert list(section) == sorted(section)
    assert set(r["versions"]) >= {"lsys3d", "numpy", "manifold3d"}
    assert r["derive"]["modules"] == len(tree.modules) == 36
    assert r["interpret"]["segments"] == str(tree.modules).count("F") == 16
    assert r["sweep"]["faces"] == tree.counts.tube_faces
    assert r["bark"]["faces"] == len(tree.bark.faces) and r["bark"]["vertices"] == len(tree.bark.vertices)
    # floats are rounded to 9 significant digits, so the same numbers print the same everywhere
    assert r["bark"]["volume"] == float(f"{tree.bark.volume:.9g}")
    assert r == report(tree.modules, tree.skeleton, tree)


def test_compare_rules():
    old = {
        "derive": {"modules": 10},
        "bark": {"faces": 1000, "volume": 2.0, "unioned": True, "watertight": True},
        "interpret": {"bbox_min": [0.0, 0.0, 0.0], "bbox_max": [1.0, 4.0, 1.0]},
        "versions": {"manifold3d": "3.5.4", "numpy": "2.4.6"},
    }

    def changed(**sections):
        new = json.loads(json.dumps(old))
        for key, value in sections.items():
            section, name = key.split("__")
            new[section][name] = value
        return compare(old, new)

    assert compare(old, old) == ([], [])
    diffs, _ = changed(derive__modules=11)
    assert [(d.key, d.failed) for d in diffs] == [("derive.modules", True)]
    diffs, _ = changed(bark__volume=2.0 * (1 + 1e-7))
    assert [(d.key, d.failed) for d in diffs] == [("bark.volume", False)]
    diffs, _ = changed(bark__volume=2.001)
    assert diffs[0].failed
    diffs, _ = changed(bark__watertight=False)
    assert diffs[0].failed and diffs[0].change() == "changed"
    # union counts: exact with the recorded manifold3d, within 2% (and a warning) with another
    diffs, warnings = changed(bark__faces=1010)
    assert diffs[0].failed and warnings == []
    diffs, warnings = changed(bark__faces=1010, versions__manifold3d="3.6.0")
    assert not diffs[0].failed and "manifold3d 3.5.4 recorded" in warnings[0]
    diffs, _ = changed(bark__faces=1030, versions__manifold3d="3.6.0")
    assert diffs[0].failed
    # other versions are not compared
    assert changed(versions__numpy="3.0.0") == ([], [])
    # a key the golden file lacks is listed, one the new report lacks fails
    new = json.loads(json.dumps(old))
    new["derive"]["branches"] = 3
    del new["bark"]["faces"]
    diffs, _ = compare(old, new)
    assert [(d.key, d.failed) for d in diffs] == [("bark.faces", True), ("derive.branches", False)]
    assert "bark.faces" in format_differences(diffs) and "missing from the new report" in format_differences(diffs)


def _golden(tmp_path: Path, name="koch", n=2, **options) -> Path:
    tree = lsys3d.generate(name, iterations=n, **options)
    path = tmp_path / f"{name}.json"
    write_golden(path, recipe_for(tree, golden_path=path), report(tree.modules, tree.skeleton, tree))
    return path


def _edit(path: Path, fn):
    data = json.loads(path.read_text())
    fn(data)
    path.write_text(json.dumps(data))


def test_check_passes_fails_and_updates(tmp_path, capsys):
    path = _golden(tmp_path, sides=5)
    assert read_golden(path)[0].options == {"sweep": {"sides": 5}}
    assert check(path).ok
    assert main(["check", str(path)]) == 0
    assert capsys.readouterr().out.startswith(f"ok      {path} (koch n=2 seed=0")

    def tamper(data):
        data["report"]["bark"]["faces"] += 6
        data["report"]["derive"]["modules"] -= 1

    _edit(path, tamper)
    before = path.read_text()
    assert main(["check", str(path)]) == 1
    out = capsys.readouterr().out
    assert f"FAILED  {path}" in out and "2 differences" in out
    assert "bark.faces" in out and "-6 (" in out and "derive.modules" in out and "+1 (" in out
    assert path.read_text() == before  # a plain check never writes
    assert main(["check", "--update", str(path)]) == 0
    out = capsys.readouterr().out
    assert f"updated {path}" in out and "bark.faces, derive.modules" in out
    assert check(path).ok and read_golden(path)[0].options == {"sweep": {"sides": 5}}


def test_check_reports_bad_files_and_goes_on(tmp_path, capsys):
    good = _golden(tmp_path)
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    assert main(["check", str(bad), str(tmp_path / "missing.json"), str(good)]) == 1
    captured = capsys.readouterr()
    assert "not a golden file" in captured.err and "no such golden file" in captured.err
    assert "Traceback" not in captured.err and f"ok      {good}" in captured.out
    _edit(good, lambda d: d["recipe"].update(options={"sweep": {"sidez": 3}}))
    with pytest.raises(GoldenError, match="unknown option 'sidez'"):
        check(good)
    _edit(good, lambda d: d["recipe"].update(options={}, file="x.toml"))
    with pytest.raises(GoldenError, match="exactly one of"):
        check(good)


def test_stats_writes_a_golden_file_for_a_grammar_file(tmp_path, capsys, monkeypatch):
    grammar = tmp_path / "plants" / "twig.toml"
    grammar.parent.mkdir()
    grammar.write_text('axiom = "F"\nangle = 30\niterations = 2\nrules = ["F -> F[+F]F"]\n')
    golden = tmp_path / "golden" / "twig.json"
    golden.parent.mkdir()
    monkeypatch.chdir(tmp_path)
    assert main(["stats", "plants/twig.toml", "--mesh", "--sides", "4", "--golden", str(golden), "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    recipe, recorded = read_golden(golden)
    assert recorded == printed
    assert recipe == Recipe(
        iterations=2,
        seed=0,
        file="../plants/twig.toml",
        options={"sweep": {"sides": 4}},
        grammar_sha256=hashlib.sha256(grammar.read_bytes()).hexdigest(),
    )
    monkeypatch.chdir(grammar.parent)  # the file is found from the golden file's folder, not the working one
    assert check(golden).ok
    grammar.write_text('axiom = "F"\nangle = 30\niterations = 2\nrules = ["F -> F[+F][-F]F"]\n')
    result = check(golden)
    assert not result.ok and "the grammar's text changed" in result.warnings[0]
    assert {d.key for d in result.differences if d.failed} >= {"derive.modules", "interpret.segments"}


def test_stats_refuses_an_unwritable_golden_file_before_working(tmp_path, capsys, monkeypatch):
    import lsys3d.pipeline

    monkeypatch.setattr(lsys3d.pipeline, "generate", lambda *a, **k: pytest.fail("grew before checking the target"))
    assert main(["stats", "koch", "--mesh", "--golden", str(tmp_path / "missing" / "k.json")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "does not exist" in err


def test_stats_table_has_dotted_keys(capsys):
    assert main(["stats", "koch", "-n", "1"]) == 0
    lines = capsys.readouterr().out.splitlines()
    keys = [line.split()[0] for line in lines]
    assert "derive.modules" in keys and "interpret.segments" in keys and "versions.manifold3d" in keys
    assert keys == sorted(keys)


def test_assert_matches_golden_records_compares_and_explains(tmp_path):
    tree = lsys3d.generate("koch", iterations=1)
    path = tmp_path / "k.json"
    with pytest.raises(AssertionError, match=r"no golden file yet.*--lsys3d-update-golden"):
        assert_matches_golden(tree, path)
    assert_matches_golden(tree, path, update=True)
    assert_matches_golden(tree, path)
    with pytest.raises(AssertionError, match="recorded for koch n=1 seed=0, but this tree is koch n=2"):
        assert_matches_golden(lsys3d.generate("koch", iterations=2), path)
    _edit(path, lambda d: d["report"]["sweep"].update(faces=1))
    with pytest.raises(AssertionError, match=r"1 of the counts differ[\s\S]*sweep\.faces"):
        assert_matches_golden(tree, path)


EXAMPLE_TEST = """
from pathlib import Path

import lsys3d
from lsys3d.testing import assert_matches_golden


def test_koch_counts():
    tree = lsys3d.generate("koch", iterations=2, seed=7)
    assert_matches_golden(tree, Path(__file__).parent / "golden" / "koch.json")
"""


def _pytest(folder: Path, *args):
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTEST", "LSYS3D"))}
    return subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "--rootdir", str(folder), *args, str(folder)],
        capture_output=True,
        text=True,
        cwd=folder,
        env=env,
        timeout=600,
    )


def test_pytest_plugin_option_records_golden_files(tmp_path):
    """The example a user copies: fails without a golden file, records it with the plugin's option."""
    (tmp_path / "test_trees.py").write_text(textwrap.dedent(EXAMPLE_TEST))
    first = _pytest(tmp_path)
    assert first.returncode == 1 and "no golden file yet" in first.stdout
    second = _pytest(tmp_path, "--lsys3d-update-golden")
    assert second.returncode == 0, second.stdout + second.stderr
    assert read_golden(tmp_path / "golden" / "koch.json")[0].seed == 7
    third = _pytest(tmp_path)
    assert third.returncode == 0, third.stdout + third.stderr


# ---------------------------------------------------------------- determinism across processes

GROW_AND_HASH = """
import hashlib, json, sys
from pathlib import Path
import lsys3d
from lsys3d.stats import report
folder = Path(sys.argv[1])
for name in sys.argv[2:-1]:  # grammars grown first in this process, to show they leave no trace
    lsys3d.generate(str(folder / f"{name}.toml"), iterations=3)
tree = lsys3d.generate(str(folder / f"{sys.argv[-1]}.toml"))
out = {}
for suffix in (".glb", ".usda", ".usdc"):
    path = lsys3d.export(tree, folder / f"out{suffix}")
    out[suffix] = hashlib.sha256(path.read_bytes()).hexdigest()
r = report(tree.modules, tree.skeleton, tree)
print(json.dumps({"files": out, "report": r}, sort_keys=True))
"""


def _grow_in_process(folder: Path, hash_seed: str, *names: str) -> dict:
    env = {**os.environ, "PYTHONHASHSEED": hash_seed}
    done = subprocess.run(
        [sys.executable, "-c", GROW_AND_HASH, str(folder), *names],
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def test_same_counts_and_bytes_in_separate_processes(tmp_path):
    """Same grammar and seed: identical counts and exported bytes, whatever the hash seed, and
    whatever other grammars (one of them edited in between) the process grew before."""
    import lsys3d.lsystem.presets

    for name in ("tree3d", "bush", "koch-stochastic"):
        (tmp_path / f"{name}.toml").write_text(lsys3d.lsystem.presets.preset_text(name))
    first = _grow_in_process(tmp_path, "1", "tree3d")
    bush = tmp_path / "bush.toml"
    bush.write_text(bush.read_text().replace("iterations = 7", "iterations = 3").replace("angle = 22.5", "angle = 30"))
    second = _grow_in_process(tmp_path, "4242", "bush", "koch-stochastic", "tree3d")
    assert second["files"] == first["files"]
    assert second["report"] == first["report"]
    # and the same counts as the golden file recorded in another session
    golden = json.loads((GOLDEN / "tree3d.json").read_text())["report"]
    differences, _ = compare(golden, first["report"])
    assert not [d for d in differences if d.failed], format_differences(differences)


def test_golden_files_do_not_depend_on_where_they_are(tmp_path):
    """Copying a golden file elsewhere keeps it valid (presets are named, not located)."""
    shutil.copy(GOLDEN / "koch.json", tmp_path / "koch.json")
    assert check(tmp_path / "koch.json").ok


def test_a_recipe_without_mesh_keeps_the_turtle_settings(tmp_path, capsys):
    """stats --turtle ... --golden (no --mesh) regrows with the same turtle overrides and limits."""
    golden = tmp_path / "k.json"
    args = ["stats", "koch", "-n", "2", "--turtle", "length_jitter=0.3", "--golden", str(golden), "--json"]
    assert main(args) == 0
    printed = json.loads(capsys.readouterr().out)
    recipe, recorded = read_golden(golden)
    assert recipe.options == {"turtle": {"length_jitter": 0.3}} and not recipe.mesh
    assert recorded == printed and printed["interpret"]["total_length"] != 16.0  # the jitter changed the lengths
    assert check(golden).ok
