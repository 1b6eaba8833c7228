"""Golden files: every preset's counts pinned in tests/golden, the check command, the pytest helper, determinism."""

from __future__ import annotations

import hashlib
import json
import os
import re
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
from lsys3d.testing import TABLE_ROWS, assert_matches_golden
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
    assert f"FAILED  {path}" in out and "): 2 counts differ\n" in out
    assert "bark.faces" in out and "-6 (" in out and "derive.modules" in out and "+1 (" in out
    assert path.read_text() == before  # a plain check never writes
    assert main(["check", "--update", str(path)]) == 0
    out = capsys.readouterr().out
    assert f"updated {path}" in out and "2 keys changed" in out
    assert "  bark.faces: " in out and "  derive.modules: " in out
    assert check(path).ok and read_golden(path)[0].options == {"sweep": {"sides": 5}}


def test_check_reports_bad_files_and_goes_on(tmp_path, capsys):
    good = _golden(tmp_path)
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    assert main(["check", str(bad), str(tmp_path / "missing.json"), str(good)]) == 1
    captured = capsys.readouterr()
    assert "not a golden file" in captured.err and f"MISSING {tmp_path / 'missing.json'}" in captured.out
    assert "Traceback" not in captured.err and f"ok      {good}" in captured.out
    assert captured.out.splitlines()[-1] == "3 golden files: 1 missing, 1 could not be checked"
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

    monkeypatch.setattr(lsys3d.pipeline, "grow", lambda *a, **k: pytest.fail("grew before checking the target"))
    (tmp_path / "a_file").write_text("")
    assert main(["stats", "koch", "--mesh", "--golden", str(tmp_path / "a_file" / "k.json")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cannot create folder" in err and str(tmp_path / "a_file") in err


def test_stats_creates_the_folder_of_a_golden_file(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["stats", "koch", "-n", "1", "--golden", "golden/new/koch.json"]) == 0
    capsys.readouterr()
    assert read_golden(tmp_path / "golden" / "new" / "koch.json")[0].iterations == 1
    assert main(["check", "golden/new/koch.json"]) == 0


def test_check_says_missing_and_update_records_a_presets_file(tmp_path, capsys):
    koch, other = tmp_path / "golden" / "koch.json", tmp_path / "golden" / "mine.json"
    assert main(["check", str(koch)]) == 1
    out = capsys.readouterr().out
    assert out.startswith(f"MISSING {koch}: no such golden file") and "check --update' records a file" in out
    assert out.splitlines()[-1] == "1 golden file: 1 missing" and "differ" not in out
    assert main(["check", "--update", str(koch), str(other)]) == 1
    out = capsys.readouterr().out
    grammar = lsys3d.load_preset("koch")
    assert f"recorded {koch} (koch n={grammar.iterations} seed={grammar.seed}): it was missing" in out
    assert f"MISSING {other}: no such golden file; its name is no bundled preset's" in out
    assert "records the new counts" not in out  # --update was given: no advice to give it
    recipe, _ = read_golden(koch)
    assert (recipe.preset, recipe.iterations, recipe.mesh) == ("koch", grammar.iterations, True)
    assert main(["check", str(koch)]) == 0
    capsys.readouterr()
    result = check(tmp_path / "algae.json", update=True)  # a symbol-only preset: recorded without the mesh
    assert result.created and result.ok and not read_golden(tmp_path / "algae.json")[0].mesh


def test_check_names_counts_and_values_apart_and_update_lists_changes(tmp_path, capsys):
    path = _golden(tmp_path)

    def tamper(data):
        data["report"]["bark"]["faces"] += 6
        data["report"]["derive"]["modules"] -= 1
        data["report"]["bark"]["area"] *= 1.01
        data["report"]["bbox"]["max"][0] += 0.5

    _edit(path, tamper)
    assert main(["check", str(path)]) == 1
    out = capsys.readouterr().out
    assert "2 counts differ, 2 values (bark.area, bbox.max) differ beyond tolerance" in out.splitlines()[0]
    assert main(["check", "--update", str(path)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].endswith("4 keys changed")
    faces = next(line for line in out if line.startswith("  bark.faces:"))
    _, recorded = read_golden(path)
    assert faces.startswith(f"  bark.faces: {recorded['bark']['faces'] + 6:,} -> {recorded['bark']['faces']:,}  -6 (")


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
    with pytest.raises(AssertionError, match=r"k.json: 1 count differs\n  key .*\n  sweep\.faces "):
        assert_matches_golden(tree, path)


EXAMPLE_TEST = """
from pathlib import Path

import lsys3d
from lsys3d.testing import assert_matches_golden


def test_koch_counts():
    tree = lsys3d.generate("koch", iterations=2, seed=7)
    assert_matches_golden(tree, Path(__file__).parent / "golden" / "koch.json")
"""


#: The inner pytest runs' options: no cache folder, and none of the test environment's plugins that lsys3d's has
#: nothing to do with (hypothesis, anyio, xdist: their imports were a third of each run's 3.4 CPU s).
INNER = ("-p", "no:cacheprovider", "-p", "no:hypothesispytest", "-p", "no:anyio", "-p", "no:xdist")


def _pytest(folder: Path, *args):
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTEST", "LSYS3D"))}
    return subprocess.run(
        [sys.executable, "-m", "pytest", "-q", *INNER, "--rootdir", str(folder), *args, str(folder)],
        capture_output=True,
        text=True,
        cwd=folder,
        env=env,
        timeout=600,
    )


RECORDED_IN_A_TEMPORARY_FOLDER = """

def test_records_in_a_temporary_folder(tmp_path):
    tree = lsys3d.generate("koch", iterations=1, seed=7)
    assert_matches_golden(tree, tmp_path / "elsewhere.json")
    assert (tmp_path / "elsewhere.json").exists()
"""


@pytest.mark.slow  # five pytest runs in subprocesses
def test_pytest_plugin_option_records_golden_files_and_lists_what_it_changed(tmp_path):
    """The example a user copies: fails without a golden file (``--tb=long`` still shows the whole traceback,
    for whoever asks), records it with the plugin's option and lists it, then passes; an update lists what it
    changed, and nothing when nothing changed.

    One user's session, run after run on the same folder (five inner pytest runs, each ~1.3 CPU s: it was
    three tests of three runs each, two of which recorded the same file first)."""
    (tmp_path / "test_trees.py").write_text(textwrap.dedent(EXAMPLE_TEST + RECORDED_IN_A_TEMPORARY_FOLDER))
    path = tmp_path / "golden" / "koch.json"

    def run(*args):  # the inner runs' tmp_path inside the project's folder, as pytester puts it
        return _pytest(tmp_path, "--basetemp", str(tmp_path / "basetemp"), *args)

    first = run("--tb=long", "-k", "test_koch_counts")
    assert first.returncode == 1 and "no golden file yet" in first.stdout, first.stdout + first.stderr
    assert "def test_koch_counts" in first.stdout  # --tb=long: the traceback through the test's own source
    recorded = run("--lsys3d-update-golden")
    assert recorded.returncode == 0 and "2 passed" in recorded.stdout, recorded.stdout + recorded.stderr
    pytest.LineMatcher(recorded.stdout.splitlines()).fnmatch_lines(
        ["*= lsys3d golden files updated =*", f"updated {path}: recorded (a new golden file*"]
    )
    # the summary lists the project's golden files: one a test records in a temporary folder is not among them
    assert "elsewhere.json" not in recorded.stdout
    assert read_golden(path)[0].seed == 7
    third = run("-k", "test_koch_counts")
    assert third.returncode == 0, third.stdout + third.stderr
    _, counts = read_golden(path)
    _edit(path, lambda d: d["report"]["bark"].update(faces=d["report"]["bark"]["faces"] + 6))
    again = run("--lsys3d-update-golden")
    assert again.returncode == 0 and "2 passed" in again.stdout, again.stdout + again.stderr
    faces = counts["bark"]["faces"]
    pytest.LineMatcher(again.stdout.splitlines()).fnmatch_lines(
        [f"updated {path}: 1 key", f"  bark.faces: {faces + 6:,} -> {faces:,}  -6 (*%)"]
    )
    assert read_golden(path)[1] == counts
    quiet = run("--lsys3d-update-golden")
    assert quiet.returncode == 0, quiet.stdout + quiet.stderr
    # nothing changed in the project's golden files (the temporary one was recorded again), nothing listed
    assert "lsys3d golden files updated" not in quiet.stdout


def _tamper_everything(path: Path) -> int:
    """Every count and value of a golden file's report changed; returns how many keys changed."""

    def bump(value):
        if isinstance(value, bool):
            return not value
        if isinstance(value, (int, float)):
            return value * 2 + 1
        if isinstance(value, list):
            return [bump(v) for v in value]
        return value

    data = json.loads(path.read_text())
    for section, values in data["report"].items():
        if section != "versions":
            data["report"][section] = {key: bump(value) for key, value in values.items()}
    path.write_text(json.dumps(data))
    return sum(len(v) for k, v in data["report"].items() if k != "versions")


def _failure_section(lines: list[str]) -> list[str]:
    """The lines pytest prints for the one failure: from its ``___ test_name ___`` header to the summary."""
    start = next(i for i, line in enumerate(lines) if line.startswith("_") and "test_koch_counts" in line)
    end = next(i for i, line in enumerate(lines) if i > start and line.startswith("="))
    return lines[start:end]


@pytest.mark.slow  # a pytest run in a subprocess
def test_a_golden_failure_in_pytest_is_short_and_reads_like_an_assertion(tmp_path):
    """The table first, no traceback through lsys3d's source nor a repr of the tree, at most 25 lines.  The golden
    file is recorded here, as the example's test would record it (the inner run of the test above records it);
    not under pytester's fixture, which would take the modules this generate imports out of sys.modules again
    (numba's, whose registrations then fail when they are imported a second time)."""
    (tmp_path / "test_trees.py").write_text(EXAMPLE_TEST.strip() + "\n")  # as pytester's makepyfile wrote it
    golden = tmp_path / "golden" / "koch.json"
    assert_matches_golden(lsys3d.generate("koch", iterations=2, seed=7), golden, update=True)
    changed = _tamper_everything(golden)
    result = _pytest(tmp_path, "--basetemp", str(tmp_path / "basetemp"))
    assert result.returncode == 1 and "1 failed" in result.stdout, result.stdout + result.stderr
    outlines = result.stdout.splitlines()
    section = _failure_section(outlines)
    assert len(section) <= 25, "\n".join(section)
    first = section[1]
    line = 1 + EXAMPLE_TEST.strip().splitlines().index(
        '    assert_matches_golden(tree, Path(__file__).parent / "golden" / "koch.json")'
    )
    assert first.startswith(f"test_trees.py:{line}: ") and "golden/koch.json: " in first  # the test's own line
    assert re.search(r"\d+ counts differ, \d+ values \(bark\.area, [^)]*\) differ beyond tolerance", first), first
    assert section[2].split() == ["key", "golden", "now", "change"]
    assert f"and {changed - TABLE_ROWS} more ({changed - TABLE_ROWS} of them failed)" in "\n".join(section)
    assert section[-1] == "to record the new counts: pytest --lsys3d-update-golden (or LSYS3D_UPDATE_GOLDEN=1)"
    text = result.stdout
    assert "def test_koch_counts" not in text and "assert_matches_golden(" not in text and "Tree(" not in text
    assert "testing.py" not in text and "Traceback" not in text
    summary = next(line for line in outlines if line.startswith("FAILED test_trees.py::test_koch_counts"))
    assert summary.startswith("FAILED test_trees.py::test_koch_counts - /")  # with the message's start


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


@pytest.mark.slow  # two processes grow and export five grammars
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


def test_docs_golden_counts_are_the_golden_files():
    """docs/golden.md and the README quote tree3d's counts: those pinned in tests/golden/tree3d.json."""
    repo = Path(__file__).parent.parent
    recorded = read_golden(GOLDEN / "tree3d.json")[1]
    quoted = re.search(r"\(bark\.faces  (\d+)\)", (repo / "docs" / "golden.md").read_text())
    assert quoted and int(quoted.group(1)) == recorded["bark"]["faces"]
    readme = " ".join((repo / "README.md").read_text().split())
    quoted = re.search(r"tree3d's ([\d,]+) bark triangles hold (\d+) slivers .* and (\d+) of aspect over 100", readme)
    quality = recorded["quality"]
    assert quoted, "the README's sentence on tree3d's triangles changed"
    assert [int(g.replace(",", "")) for g in quoted.groups()] == [
        quality["triangles"],
        quality["slivers"],
        quality["over_100"],
    ]
