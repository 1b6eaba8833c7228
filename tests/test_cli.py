"""The command line: output, exit codes, and one clear line for every user mistake."""

from __future__ import annotations

import json
import logging
import subprocess
import sys

import pytest

import lsys3d
from lsys3d.cli import build_parser, main
from lsys3d.lsystem.grammar import GROUPS


def run(*args, **kw):
    return subprocess.run([sys.executable, "-m", "lsys3d", *args], capture_output=True, text=True, **kw)


@pytest.fixture
def command(capsys, caplog):
    """``command(*args)``: the command line's ``main`` run in this process, as ``(code, stdout, stderr)``.

    For the tests of what a mistake prints: the program (``python -m lsys3d``, the console script) is
    ``main`` and an exit with its code (tests/test_cli.py's subprocess tests run it whole), and a child
    process per mistake costs an interpreter and lsys3d's imports each.  ``stderr`` is what the program's
    stderr would hold: what ``main`` wrote to it (its error line, argparse's usage) and, after it, each
    warning or error it logged, as the program's ``lsys3d: message`` lines (under pytest the log goes to
    pytest's capture, not to stderr), so a stray warning still shows as a second line.  ``code`` is
    ``main``'s return value, or its ``SystemExit`` code (argparse's usage errors).
    """

    def call(*args: str) -> tuple[int, str, str]:
        capsys.readouterr()
        caplog.clear()
        try:
            code = main(list(args))
        except SystemExit as exc:
            code = exc.code
        out, err = capsys.readouterr()
        logged = [f"lsys3d: {r.getMessage()}\n" for r in caplog.records if r.levelno >= logging.WARNING]
        return code, out, err + "".join(logged)

    return call


def test_derive_prints_the_canonical_string(capsys):
    assert main(["derive", "koch", "-n", "1"]) == 0
    assert capsys.readouterr().out == "F-F++F-F\n"


def test_derive_interpretation_prints_the_string_the_turtle_reads(tmp_path, capsys):
    path = tmp_path / "h.toml"
    path.write_text('axiom = "A"\niterations = 2\nrules = ["A -> AB"]\nhomomorphism = ["B -> F+"]\n')
    assert main(["derive", str(path)]) == 0
    assert capsys.readouterr().out == "ABB\n"
    assert main(["derive", str(path), "--interpretation"]) == 0
    assert capsys.readouterr().out == "AF+F+\n"
    assert main(["derive", str(path), "--interpretation", "-n", "1"]) == 0
    assert capsys.readouterr().out == "AF+\n"


@pytest.mark.parametrize("command", ["generate", "preview", "derive", "stats"])
def test_grammar_help_names_every_suffix_read(command, capsys):
    """The suffixes come from the dialect table: every one the readers take is named in the help."""
    from lsys3d.lsystem.dialects import GRAMMAR_SUFFIXES, SUFFIXES

    with pytest.raises(SystemExit):
        main([command, "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert set(SUFFIXES) <= set(GRAMMAR_SUFFIXES) and ".toml" in GRAMMAR_SUFFIXES
    assert f"a grammar file ({', '.join(GRAMMAR_SUFFIXES)}) or the name of a bundled preset" in text


def test_derive_with_seed(capsys):
    main(["derive", "koch-stochastic", "-n", "3", "--seed", "4"])
    a = capsys.readouterr().out
    main(["derive", "koch-stochastic", "-n", "3", "--seed", "4"])
    assert capsys.readouterr().out == a


def test_presets_lists_one_line_each(capsys):
    assert main(["presets"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert any(line.startswith("  koch ") for line in lines)
    # a header per group, then one indented line per preset: its name and description
    assert all(len(line.split(None, 1)) == 2 for line in lines if line.startswith("  "))
    assert sum(not line.startswith("  ") for line in lines) == len(GROUPS)


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
def test_grammar_errors_are_one_line_without_traceback(tmp_path, text, fragment, command):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    code, stdout, stderr = command("derive", str(path))  # a traceback would be this test's exception
    assert code == 1
    assert stdout == ""
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and fragment in lines[0] and lines[0].startswith(f"lsys3d: error: {path}")


def test_missing_preset_and_limit_errors(command):
    code, _, stderr = command("derive", "nope")
    assert code == 1 and "no bundled preset named 'nope'" in stderr
    code, _, stderr = command("derive", "algae", "-n", "60")
    assert code == 1 and "--max-modules" in stderr and len(stderr.splitlines()) == 1


def test_usage_errors_exit_2(command):
    assert run("derive").returncode == 2  # the program's own exit status
    assert command("frobnicate")[0] == 2
    assert command("derive", "koch", "-n", "x")[0] == 2


def test_stats_json_and_table(capsys):
    assert main(["stats", "abop-1.24a", "--json"]) == 0
    stats = json.loads(capsys.readouterr().out)
    assert list(stats) == ["derive", "interpret", "versions"]  # no mesh sections without --mesh
    assert set(stats["derive"]) == {"modules", "branches"}
    for key in ("segments", "chains", "leaves", "bbox_min", "bbox_max", "total_length"):
        assert key in stats["interpret"]
    assert stats["interpret"]["segments"] == str(lsys3d.derive(lsys3d.load_preset("abop-1.24a"))).count("F")
    assert main(["stats", "abop-1.24a"]) == 0
    table = capsys.readouterr().out.splitlines()
    keys = [line.split()[0] for line in table]
    assert keys == sorted(keys) and "interpret.segments" in keys and "versions.numpy" in keys


def test_generate_without_arguments_writes_tree_glb(tmp_path):
    out = run("generate", cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    glb = tmp_path / "tree.glb"
    assert glb.read_bytes()[:4] == b"glTF"
    assert out.stdout.startswith("wrote tree.glb: ") and "leaves" in out.stdout
    assert out.stderr == ""  # piped: no progress lines
    assert [p.name for p in tmp_path.iterdir()] == ["tree.glb"]  # no temporary files left


def test_generate_options_reach_the_file(tmp_path, capsys):
    path = tmp_path / "k.usda"
    args = ["generate", "koch", "-n", "1", "--sides", "5", "--no-union", "--units", "cm", "--up-axis", "Z"]
    assert main([*args, "--skeleton-curves", "-o", str(path)]) == 0
    text = path.read_text()
    assert "metersPerUnit = 0.01" in text and 'upAxis = "Z"' in text and "BasisCurves" in text
    # koch n=1: 4 segments in one chain, one tube of 5 sides (tube soup, no union)
    from pxr import Usd

    stage = Usd.Stage.Open(str(path))
    stats = json.loads(stage.GetDefaultPrim().GetCustomDataByKey("lsys3d")["provenance"])
    assert stats["options"]["union"]["enabled"] is False and stats["options"]["sweep"]["sides"] == 5
    assert stage.GetDefaultPrim().GetName() == "koch" and Usd.ModelAPI(stage.GetDefaultPrim()).GetAssetName() == "koch"
    assert main(["-q", "generate", "koch", "-n", "1", "-o", str(tmp_path / "q.glb")]) == 0
    assert capsys.readouterr().out.count("wrote") == 1  # -q printed nothing


def test_generate_refuses_before_working(tmp_path, command):
    code, _, stderr = command("generate", "-o", str(tmp_path / "tree.fbx"))
    assert code == 1 and "unknown suffix '.fbx'" in stderr and len(stderr.splitlines()) == 1
    code, _, stderr = command("generate", "-o", str(tmp_path / "missing" / "tree.glb"))
    assert code == 1 and "does not exist" in stderr
    (tmp_path / "old.glb").write_bytes(b"precious")
    code, _, stderr = command("generate", "koch", "-n", "1", "--no-clobber", "-o", str(tmp_path / "old.glb"))
    assert code == 1 and "file exists" in stderr
    assert (tmp_path / "old.glb").read_bytes() == b"precious"
    code, _, stderr = command("generate", "algae", "-o", str(tmp_path / "a.glb"))
    assert code == 1 and "nothing to mesh" in stderr and len(stderr.splitlines()) == 1
    assert not (tmp_path / "a.glb").exists()


def test_generate_verbose_times_each_stage(tmp_path):
    out = run("-v", "generate", "koch", "-n", "2", "-o", str(tmp_path / "k.glb"))
    assert out.returncode == 0
    for stage in ("derive", "interpret", "sweep", "union", "leaves", "export"):
        assert f"lsys3d: {stage}" in out.stderr


def test_stats_mesh(capsys):
    assert main(["stats", "abop-1.24a", "-n", "2", "--mesh", "--json"]) == 0
    stats = json.loads(capsys.readouterr().out)
    assert list(stats) == ["bark", "bbox", "derive", "interpret", "leaves", "quality", "sweep", "versions"]
    bark = stats["bark"]
    assert bark["watertight"] and bark["components"] == 1 and bark["volume"] > 0 and bark["unioned"]
    assert stats["sweep"]["vertices"] > 0 and stats["interpret"]["segments"] == 25
    assert main(["stats", "abop-1.24a", "-n", "2", "--mesh", "--no-union", "--json"]) == 0
    soup = json.loads(capsys.readouterr().out)
    assert soup["bark"]["faces"] == soup["sweep"]["faces"] == stats["sweep"]["faces"]
    assert not soup["bark"]["unioned"]


def test_quiet_and_verbose_after_the_subcommand(tmp_path, capsys):
    assert main(["generate", "koch", "-n", "1", "-q", "-o", str(tmp_path / "k.glb")]) == 0
    assert capsys.readouterr().out == ""
    # after the subcommand, --verbose is the flag -v sets before it: main reads that one flag for the log's level
    # (test_generate_verbose_times_each_stage's process shows that log, where pytest's handlers do not stand in
    # the way of logging.basicConfig)
    parser = build_parser("generate")
    assert parser.parse_args(["generate", "koch", "--verbose"]).verbose
    assert parser.parse_args(["-v", "generate", "koch"]).verbose
    assert not parser.parse_args(["generate", "koch"]).verbose


def test_union_settings_from_the_command_line(tmp_path, capsys, command):
    assert main(["generate", "tree3d", "-n", "3", "--workers", "1", "-o", str(tmp_path / "t.glb")]) == 0
    assert main(["generate", "tree3d", "-n", "3", "--max-union-pairs", "5", "-o", str(tmp_path / "u.glb")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("lsys3d: error: union: more than 5 pairs of tube pieces may touch")
    assert not (tmp_path / "u.glb").exists()
    code, _, stderr = command("generate", "tree3d", "--workers", "-1")
    assert code == 2 and "--workers" in stderr


def test_the_union_shows_a_percentage_on_a_terminal(capsys):
    from lsys3d.cli import _Progress

    shown = _Progress(True)
    shown("union", "start", 0.0)
    shown("union", "progress", 0.25)
    shown("union", "done", 3.0)
    err = capsys.readouterr().err
    assert "lsys3d: union 25%" in err and "lsys3d: union 3.00 s" in err
    _Progress(False)("union", "progress", 0.5)
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("given", [None, "1"])
def test_small_pages_for_the_command_line_unless_told(monkeypatch, capsys, given):
    """The command line keeps numpy out of transparent huge pages (and tells its workers so), unless the
    environment says otherwise; numpy's own setting is restored after the test."""
    import os

    import numpy as np

    setting = getattr(getattr(np, "_core", None), "multiarray", None)
    if not hasattr(setting, "_set_madvise_hugepage"):
        pytest.skip("this numpy has no huge page setting")
    if given is None:
        monkeypatch.delenv("NUMPY_MADVISE_HUGEPAGE", raising=False)
    else:
        monkeypatch.setenv("NUMPY_MADVISE_HUGEPAGE", given)
    before = setting._set_madvise_hugepage(True)
    try:
        assert main(["presets"]) == 0
        assert setting._set_madvise_hugepage(True) is (given is not None)  # returns the setting it replaces
    finally:
        setting._set_madvise_hugepage(before)
    assert os.environ["NUMPY_MADVISE_HUGEPAGE"] == ("0" if given is None else given)


def test_the_program_ends_at_once_with_its_code_its_output_flushed_and_exit_handlers_run(tmp_path):
    """``lsys3d`` (cli.run) skips Python's teardown: what it printed, its exit code and its atexit handlers
    are all there, through a pipe (buffered) as on a terminal."""
    from lsys3d import cli

    marker = tmp_path / "atexit"
    code = (
        "import atexit, sys\n"
        f"atexit.register(lambda: open({str(marker)!r}, 'w').write('ran'))\n"
        "from lsys3d import cli\n"
        "sys.argv = ['lsys3d', *sys.argv[1:]]\n"
        "cli.run()\n"
        "print('not reached')\n"
    )
    done = subprocess.run([sys.executable, "-c", code, "derive", "koch", "-n", "1"], capture_output=True, text=True)
    assert (done.returncode, done.stdout, done.stderr) == (0, "F-F++F-F\n", "")
    assert marker.read_text() == "ran"
    failed = subprocess.run([sys.executable, "-c", code, "derive", "no-such-preset"], capture_output=True, text=True)
    assert failed.returncode == cli.EXIT_USER_ERROR and failed.stdout == ""
    assert failed.stderr.startswith("lsys3d: error:")


def test_the_program_ends_as_python_does_while_another_thread_runs(monkeypatch):
    """A thread of the command still running (not a daemon): Python's own exit, which waits for it."""
    import threading

    from lsys3d import cli

    release = threading.Event()
    worker = threading.Thread(target=release.wait)
    worker.start()
    try:
        monkeypatch.setattr(cli, "main", lambda: 3)
        monkeypatch.setattr(cli.os, "_exit", lambda code: pytest.fail("os._exit with a thread running"))
        with pytest.raises(SystemExit) as stop:
            cli.run()
        assert stop.value.code == 3
    finally:
        release.set()
        worker.join()
