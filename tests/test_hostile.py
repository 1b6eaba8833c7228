"""Hostile and broken input: clear errors, bounded resources, nothing lost (issue 7).

* No code execution: payloads in every place a grammar holds text are refused, and a canary file that the
  payload would create never appears.
* A table of bad inputs, each through the public API or the CLI, with its error class and message.
* Every resource limit refuses with its size and how to raise it, and can be raised.
* Fuzzing: random rule strings and grammars run through parse, derive, interpret, sweep and union; the only
  outcomes are a result that keeps its invariants or an ``LSystemError``.  Plain ``pytest`` runs the fixed,
  CI-sized examples of the default profile (a few seconds); ``HYPOTHESIS_PROFILE=fuzz pytest
  tests/test_hostile.py -k random`` (or ``--hypothesis-profile=fuzz``) runs 2000 random ones per test (about
  two minutes).
* Nothing lost: a failed or interrupted export keeps the old file and leaves no temporary file.

Round 2 (issue 18), at the end of the file: bombs inside every documented limit run in a subprocess whose
address space is capped (RLIMIT_AS), so a regression fails instead of swapping; more bad inputs whose only
acceptable outcome is one line; every output format written under RLIMIT_FSIZE and onto a full tmpfs (where
mounting is allowed), and interrupted by SIGTERM and SIGHUP; the option classes' cases wait for issue 13.
"""

from __future__ import annotations

import dataclasses
import errno
import importlib
import json
import os
import re
import signal
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from grown import grown
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from invariants import balanced
from skeletons import make_skeleton

import lsys3d
from lsys3d import (
    DerivationError,
    ExportError,
    GeometryError,
    Grammar,
    GrammarError,
    InterpretError,
    LimitError,
    LSystemError,
    ModuleString,
    OptionsError,
    TurtleOptions,
)
from lsys3d.cli import build_parser, main
from lsys3d.errors import GoldenError
from lsys3d.exchange import atomic
from lsys3d.golden import golden
from lsys3d.mesh.sweep import DEFAULT_MAX_TRIANGLES, sweep
from lsys3d.mesh.union.union import union
from lsys3d.pipeline import GenerateOptions, draw
from lsys3d.turtle import DEFAULT_MAX_SEGMENTS, interpret

derive_module = importlib.import_module("lsys3d.lsystem.derive")  # lsys3d.derive is the function


# ---------------------------------------------------------------- no code execution
def payloads(canary: Path) -> list[str]:
    """Python that would create ``canary`` (or reach for the interpreter) if anything evaluated it."""
    c = str(canary)
    return [
        f"__import__('os').system('touch {c}')",
        f"open('{c}', 'w').write('x')",
        f"eval(\"open('{c}', 'w')\")",
        "exec('import os')",
        "().__class__.__bases__[0].__subclasses__()",
        "sqrt.__globals__",
        f"(lambda: open('{c}', 'w'))()",
        f"[open('{c}', 'w') for _ in (1,)]",
        f"{{k: open('{c}', 'w') for k in 'a'}}",
        f"1 if open('{c}', 'w') else 0",
        "(x := 1)",
        f'f\'{{open("{c}", "w")}}\'',
        f"getattr(__builtins__, 'open')('{c}', 'w')",
        "x[0]",
        "x; 1",
        "(" * 200 + "1" + ")" * 200,  # deeply nested
        "x+" * 200 + "1",  # a chain of operators as tall as the nesting limit allows three times
        "1+" * 3000 + "1",  # very long
    ]


def toml_string(text: str) -> str:
    return json.dumps(text)  # JSON string escapes are TOML basic-string escapes


# Where a grammar holds text that could be taken for code; each gives the TOML file and the Python fields.
PLACES = {
    "successor parameter": lambda p: {"axiom": "F(1)", "rules": [f"F(x) -> F({p})"]},
    "condition": lambda p: {"axiom": "F(1)", "rules": [f"F(x) : {p} -> F(x)"]},
    "weight": lambda p: {"axiom": "F(1)", "rules": [f"F(x) -> F(x) : {p}", "F(x) -> F(x) : 1"]},
    "predecessor parameter": lambda p: {"axiom": "F", "rules": [f"F({p}) -> F"]},
    "axiom parameter": lambda p: {"axiom": f"F({p})"},
    "define value": lambda p: {"axiom": "F", "defines": {"R": p}},
    "define name": lambda p: {"axiom": "F", "defines": {p: 1}},
}


def as_toml(fields: dict) -> str:
    lines = [f"axiom = {toml_string(fields['axiom'])}"]
    if "rules" in fields:
        lines.append("rules = [" + ", ".join(toml_string(r) for r in fields["rules"]) + "]")
    if "defines" in fields:
        lines.append("[defines]")
        lines += [
            f"{toml_string(k)} = {v if isinstance(v, int) else toml_string(v)}" for k, v in fields["defines"].items()
        ]
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("place", sorted(PLACES))
def test_payloads_in_rules_axiom_and_defines_are_refused(tmp_path, place):
    canary = tmp_path / "canary"
    for payload in payloads(canary):
        fields = PLACES[place](payload)
        with pytest.raises(GrammarError) as info:
            Grammar(**fields)
        assert "\n" not in str(info.value)
        path = tmp_path / "hostile.toml"
        path.write_text(as_toml(fields), encoding="utf-8")
        with pytest.raises(GrammarError) as info:
            Grammar.from_file(path)
        assert str(info.value).startswith(f"{path}:")
    assert not canary.exists()


@pytest.mark.parametrize(
    ("template", "fragment"),
    [
        ("[turtle]\nstep = {value}\n", "step: must be a"),
        ("[turtle]\ntropism = [{value}, 0, 0]\n", "tropism: must be a list of 3 numbers"),
        ("[turtle]\n{key} = 1\n", "unknown key"),
    ],
)
def test_payloads_in_the_turtle_table_are_refused(tmp_path, template, fragment):
    canary = tmp_path / "canary"
    for payload in payloads(canary):
        text = 'axiom = "F"\n' + template.format(value=toml_string(payload), key=toml_string(payload))
        grammar = Grammar.from_text(text, source="plant.toml")
        with pytest.raises(GrammarError, match=fragment) as info:
            interpret(grammar.axiom_modules, grammar)
        assert re.match(r"plant\.toml:[23]:1: \[turtle\] ", str(info.value)), str(info.value)
    assert not canary.exists()


def test_payloads_as_toml_keys_are_refused_and_names_stay_plain_text(tmp_path):
    canary = tmp_path / "canary"
    for payload in payloads(canary):
        with pytest.raises(GrammarError, match="unknown key"):
            Grammar.from_text(f'axiom = "F"\n{toml_string(payload)} = 1\n')
        # a name or description is text to show, never evaluated: kept verbatim
        g = Grammar.from_text(f'axiom = "F"\nname = {toml_string(payload)}\ndescription = {toml_string(payload)}\n')
        assert g.name == g.description == payload
    assert not canary.exists()


def test_the_parser_has_no_door_to_python():
    import lsys3d.lsystem.expr as expr

    source = Path(expr.__file__).read_text()
    assert not re.search(r"(?<![\w.])(eval|exec|compile|getattr|__import__)\(|importlib", source)


# ---------------------------------------------------------------- the table of bad inputs
class Context:
    def __init__(self, tmp_path: Path, monkeypatch, capsys):
        self.tmp = tmp_path
        self.monkeypatch = monkeypatch
        self.capsys = capsys

    def file(self, text: str | bytes, name: str = "plant.toml") -> Path:
        path = self.tmp / name
        if isinstance(text, bytes):
            path.write_bytes(text)
        else:
            path.write_text(text, encoding="utf-8")
        return path


def check_message(message: str, fragment: str):
    assert fragment in message, message
    assert "\n" not in message
    where, sep, what = message.partition(": ")
    assert sep and where.strip() and what.strip(), f"not 'where: what': {message!r}"


def grow(text: str | bytes, iterations: int | None = None):
    """A grammar file through the public API: read, derive, interpret, sweep (the tube soup, no union)."""

    def run(ctx: Context, error, fragment):
        path = ctx.file(text)
        with pytest.raises(error) as info:
            lsys3d.generate(path, iterations, union=False)
        assert type(info.value) is error, repr(info.value)
        check_message(str(info.value), fragment)
        if error is GrammarError:
            assert str(info.value).startswith(f"{path}:")

    return run


def api(fn):
    """A call into the public API, given the test context."""

    def run(ctx: Context, error, fragment):
        with pytest.raises(error) as info:
            fn(ctx)
        assert type(info.value) is error, repr(info.value)
        check_message(str(info.value), fragment)

    return run


def cli(*argv: str, setup=None):
    """The command line: the command raises ``error``; main() exits 1 with one line on stderr."""

    def run(ctx: Context, error, fragment):
        if setup:
            setup(ctx)
        args = [a.format(tmp=ctx.tmp) for a in argv]
        parsed = build_parser().parse_args(args)
        with pytest.raises(error) as info:
            parsed.func(parsed)
        assert type(info.value) is error, repr(info.value)
        check_message(str(info.value), fragment)
        ctx.capsys.readouterr()
        assert main(args) == 1
        out = ctx.capsys.readouterr()
        lines = out.err.splitlines()
        assert len(lines) == 1 and lines[0].startswith("lsys3d: error: ") and fragment in lines[0], out.err
        assert "Traceback" not in out.err and "\x1b" not in out.err  # escape sequences are printed escaped

    return run


def from_symbols(text: str):
    return lambda ctx: interpret(ModuleString.from_symbols(text), TurtleOptions())


def with_params(symbols: str, arity: list[int], params: list[float]) -> ModuleString:
    return ModuleString(
        np.array([ord(c) for c in symbols], np.uint8), np.array(arity, np.uint8), np.array(params, np.float64)
    )


def nan_skeleton(ctx):
    sk = make_skeleton([[0, 0, 0], [0, 1, 0]], [[0, 1, 0], [0, np.nan, 0]], 0.1)
    sweep(sk)


def big_file(ctx):
    ctx.monkeypatch.setattr(lsys3d.lsystem.grammar, "MAX_GRAMMAR_BYTES", 64)
    lsys3d.Grammar.from_file(ctx.file('axiom = "F"\n' + "# padding\n" * 10))


def turtle_nan(ctx):
    interpret(with_params("F+F", [0, 1, 0], [np.nan]), TurtleOptions())


def start_nan(ctx):
    lsys3d.derive(Grammar(axiom="A(1)", rules=["A(x) -> A(x + 1)"]), 1, start=with_params("A", [1], [np.nan]))


def many_symbols(ctx):
    Grammar(axiom="".join(map(chr, range(0x400, 0x481))))  # 129 distinct non-ASCII symbols


def a_file(ctx):
    ctx.file("not a folder", "f")


def old(ctx):
    ctx.file("good old asset", "t.glb")


def a_folder(ctx):
    (ctx.tmp / "d.glb").mkdir()


def bad_export_options(ctx):
    export_koch(ctx, ctx.tmp / "t.usda", lsys3d.ExportOptions(units="km"))


def locked_folder(ctx) -> Path:
    """A folder this process cannot create files in (root ignores permissions, not sysfs)."""
    if os.geteuid() == 0:
        return Path("/sys")
    folder = ctx.tmp / "locked"
    folder.mkdir()
    folder.chmod(0o500)
    return folder


def export_koch(ctx, target: Path, options=None):
    lsys3d.export(lsys3d.generate("koch", 1, union=False), target, options)


def disk_full(ctx):
    target = ctx.file("good old asset", "tree.glb")

    def write(f, chunks):
        f.write(b"half an asset")
        raise OSError(errno.ENOSPC, "No space left on device")

    ctx.monkeypatch.setattr(atomic, "_write_chunks", write)
    try:
        export_koch(ctx, target)
    finally:  # the old file is untouched and no temporary file remains
        assert target.read_text() == "good old asset"
        assert [p.name for p in ctx.tmp.iterdir()] == ["tree.glb"]


A = 'axiom = "A(1)"\n'
F = 'axiom = "F"\n'
DEEP = "(" * 65 + "x" + ")" * 65

CASES = [
    # (id, run, error class, message fragment)
    # -- TOML and the file
    ("toml-syntax", grow('axiom = "F\nrules = []\n'), GrammarError, "TOML syntax error"),
    ("toml-missing-axiom", grow('rules = ["F -> FF"]\n'), GrammarError, "missing 'axiom'"),
    ("toml-unknown-key", grow(F + "rulez = []\n"), GrammarError, "unknown key 'rulez'"),
    ("toml-rules-not-list", grow(F + 'rules = "F -> FF"\n'), GrammarError, "'rules' must be a list"),
    ("toml-defines-not-table", grow(F + "defines = 3\n"), GrammarError, "'defines' must be a table"),
    ("toml-ignore-not-string", grow(F + 'ignore = ["+", 1]\n'), GrammarError, "'ignore' must be a string"),
    ("toml-iterations-string", grow(F + 'iterations = "many"\n'), GrammarError, "'iterations' must be a whole"),
    ("toml-angle-infinite", grow(F + "angle = inf\n"), GrammarError, "'angle' must be a number"),
    ("file-not-utf8", grow(b'axiom = "\xff"\n'), GrammarError, "not UTF-8"),
    ("file-too-large", api(big_file), GrammarError, "more than 64 (lsys3d.lsystem.grammar.MAX_GRAMMAR_BYTES)"),
    ("file-missing", cli("derive", "{tmp}/nope.toml"), GrammarError, "no such grammar file"),
    ("preset-unknown", cli("derive", "no-such-preset"), GrammarError, "no bundled preset named"),
    # -- rule syntax
    ("rule-no-arrow", grow(F + 'rules = ["F F"]\n'), GrammarError, "expected '->'"),
    ("rule-no-predecessor", grow(F + 'rules = ["-> F"]\n'), GrammarError, "missing predecessor"),
    ("rule-two-predecessors", grow(F + 'rules = ["A B -> F"]\n'), GrammarError, "must be one module"),
    ("rule-unclosed-paren", grow(F + 'rules = ["A(x -> F"]\n'), GrammarError, "unclosed '('"),
    ("rule-formal-twice", grow(F + 'rules = ["A(x, x) -> F"]\n'), GrammarError, "used twice"),
    ("rule-chained-comparison", grow(A + 'rules = ["A(x) : 1 < x < 3 -> F"]\n'), GrammarError, "cannot be chained"),
    ("rule-empty-condition", grow(A + 'rules = ["A(x) : -> F"]\n'), GrammarError, "empty condition"),
    # -- brackets and polygons
    ("successor-open-bracket", grow(F + 'rules = ["F -> F[+F"]\n'), GrammarError, "unbalanced '['"),
    ("axiom-pop-without-push", grow('axiom = "F]F"\n'), GrammarError, "unbalanced ']' in axiom"),
    ("turtle-pop-empty-stack", api(from_symbols("F[]]F")), InterpretError, "nothing to pop"),
    ("polygon-never-closed", grow('axiom = "F{.f.f"\n'), InterpretError, "polygon never closed"),
    ("polygon-closed-twice", grow('axiom = "F{.f.}}"\n'), InterpretError, "no polygon is open"),
    ("polygon-nested-too-deep", grow(f'axiom = "{"{" * 1001}{"}" * 1001}"\n'), InterpretError, "polygons open at once"),
    # -- L-Py's nF and @Tp, Lparser's carried arguments
    ("lpy-nF-too-many-steps", grow('dialect = "lpy"\naxiom = "nF(1e300, 1e-300)"\n'), LimitError, "segments"),
    ("lpy-nF-many-huge", grow(f'dialect = "lpy"\naxiom = "{"nF(1e300, 1e-300)" * 2000}"\n'), LimitError, "segments"),
    ("lpy-nF-no-step", grow('dialect = "lpy"\naxiom = "F nF(1, 0)"\n'), InterpretError, "nF(length, dlength"),
    ("lpy-nF-radius-too-wide", grow('dialect = "lpy"\naxiom = "nF(1, 0.5, 1e300)"\n'), InterpretError, "width must be"),
    ("lpy-Tp-two-coordinates", grow('dialect = "lpy"\naxiom = "@Tp(1, 0) F"\n'), InterpretError, "@Tp(x, y, z)"),
    (
        "lparser-carried-argument-unclosed",
        api(lambda ctx: lsys3d.Grammar.from_file(ctx.file("1\n30\n10\nA(1)\nA=F(\n@\n", "plant.ls"))),
        GrammarError,
        "plant.ls:5:",
    ),
    # -- unknown names, wrong arity
    ("unknown-name", grow(A + 'rules = ["A(x) -> A(y)"]\n'), GrammarError, "unknown name 'y'"),
    ("unknown-function", grow(A + 'rules = ["A(x) -> A(foo(x))"]\n'), GrammarError, "unknown function 'foo'"),
    ("unknown-turtle-key", grow(F + "[turtle]\ncolour = 3\n"), GrammarError, "unknown key 'colour'"),
    ("arity-axiom", grow('axiom = "A(1,2)"\nrules = ["A(x) -> F"]\n'), GrammarError, "wrong arity"),
    ("arity-function", grow(A + 'rules = ["A(x) -> A(sqrt(x, 2))"]\n'), GrammarError, "takes 1 argument"),
    ("arity-turtle-command", grow('axiom = "+(1,2)F"\n'), InterpretError, "takes at most 1 argument"),
    # -- weights
    ("weight-zero", grow(F + 'rules = ["F -> FF : 0", "F -> F"]\n'), GrammarError, "weight must be positive"),
    ("weight-negative", grow(F + 'rules = ["F -> FF : -2"]\n'), GrammarError, "weight must be positive"),
    ("weight-unknown-name", grow(F + 'rules = ["F -> FF : w"]\n'), GrammarError, "bad weight: unknown name 'w'"),
    ("weight-infinite", grow(F + 'rules = ["F -> FF : 1e400"]\n'), GrammarError, "bad weight: result is not a"),
    ("weight-missing", grow(F + 'rules = ["F -> FF : "]\n'), GrammarError, "empty weight"),
    # -- numbers: division by zero, overflow, NaN
    ("div0-derive", grow(A + 'rules = ["A(x) -> A(x - 1)F(1 / x)"]\n', 3), DerivationError, "division by zero"),
    ("div0-condition", grow('axiom = "A(0)"\nrules = ["A(x) : 1 / x > 1 -> F"]\n'), DerivationError, "condition"),
    ("div0-axiom", grow('axiom = "F(1/0)"\n'), GrammarError, "division by zero"),
    ("div0-define", grow(F + 'defines = { R = "1 / 0" }\n'), GrammarError, "define 'R': division by zero"),
    ("overflow-parameter", grow(A + 'rules = ["A(x) -> A(x * 1e300)"]\n', 3), DerivationError, "A(1e+300) (#0)"),
    ("nan-parameter", grow('axiom = "A(1e308)"\nrules = ["A(x) -> A(x*10 - x*10)"]\n'), DerivationError, "NaN"),
    ("overflow-exp", grow('axiom = "A(1000)"\nrules = ["A(x) -> A(exp(x))"]\n'), DerivationError, "exp(x)"),
    ("domain-sqrt", grow('axiom = "A(-1)"\nrules = ["A(x) -> A(sqrt(x))"]\n'), DerivationError, "square root"),
    ("turtle-position-overflow", grow('axiom = "F(1e308)F(1e308)"\n'), InterpretError, "left the drawable range"),
    ("turtle-step-overflow", grow('axiom = "\\"(1e300)\\"(1e300)F"\n'), InterpretError, "step length"),
    ("turtle-nan-parameter", api(turtle_nan), InterpretError, "not a finite number"),
    ("start-nan-parameter", api(start_nan), DerivationError, "start string: module A(nan)"),
    # -- the axiom
    ("axiom-empty", grow('axiom = ""\n'), GrammarError, "the axiom is empty"),
    ("axiom-blank", api(lambda c: Grammar(axiom=" \t ")), GrammarError, "the axiom is empty"),
    # -- degenerate geometry
    ("zero-length-segments", grow('axiom = "F(0)F(0)"\n'), GeometryError, "shorter than min_length"),
    ("negative-width", grow('axiom = "!(-1)F"\n'), InterpretError, "the width must be"),
    ("nan-coordinates", api(nan_skeleton), GeometryError, "segment 1 (module 1)"),
    ("draws-nothing", cli("generate", "algae", "-o", "{tmp}/a.glb"), GeometryError, "nothing to mesh"),
    # -- limits
    ("limit-modules", grow('axiom = "A"\nrules = ["A -> AA"]\n', 40), LimitError, "1,099,511,627,776 modules"),
    ("limit-modules-parametric", grow(A + 'rules = ["A(x) -> A(x)F(x + 1)A(x)"]\n', 40), LimitError, "--max-modules"),
    ("limit-segments", cli("stats", "koch", "-n", "3", "--max-segments", "10"), LimitError, "up to 64 segments"),
    ("limit-triangles", cli("stats", "koch", "--mesh", "--max-triangles", "1000"), LimitError, "11,440 tube triangles"),
    ("limit-iterations", grow(F + "iterations = 1_000_000_000\n"), LimitError, "MAX_ITERATIONS"),
    ("limit-depth", grow(A + f'rules = ["A(x) -> A({DEEP})"]\n'), GrammarError, "nested deeper than 64"),
    ("limit-length", grow(A + 'rules = ["A(x) -> A(' + "x+" * 2100 + 'x)"]\n'), GrammarError, "longer than 4096"),
    ("limit-parameters", grow('axiom = "A(' + ",".join(["1"] * 33) + ')"\n'), GrammarError, "more than 32"),
    ("limit-symbols", api(many_symbols), GrammarError, "128 distinct"),
    # -- output
    ("output-unknown-suffix", cli("generate", "koch", "-o", "{tmp}/tree.fbx"), ExportError, "unknown suffix '.fbx'"),
    ("output-no-suffix", cli("generate", "koch", "-o", "{tmp}/tree"), ExportError, "no suffix"),
    ("output-missing-folder", cli("generate", "koch", "-o", "{tmp}/missing/t.glb"), ExportError, "does not exist"),
    ("output-folder-is-file", cli("generate", "-o", "{tmp}/f/t.glb", setup=a_file), ExportError, "not a folder"),
    ("output-is-folder", cli("generate", "-o", "{tmp}/d.glb", setup=a_folder), ExportError, "d.glb: is a folder"),
    ("output-unwritable", api(lambda c: export_koch(c, locked_folder(c) / "tree.glb")), ExportError, "is not writable"),
    ("output-no-clobber", cli("generate", "--no-clobber", "-o", "{tmp}/t.glb", setup=old), ExportError, "file exists"),
    ("output-disk-full", api(disk_full), ExportError, "tree.glb: no space left on device"),
    ("output-bad-options", api(bad_export_options), OptionsError, "ExportOptions.units: must be one of"),
]  # fmt: skip


def test_the_table_is_large_and_covers_every_error_class():
    assert len(CASES) >= 40
    assert len({case[0] for case in CASES}) == len(CASES)
    classes = {case[2] for case in CASES}
    assert classes >= {GrammarError, DerivationError, LimitError, InterpretError, GeometryError, ExportError}


@pytest.mark.parametrize(("run", "error", "fragment"), [pytest.param(*c[1:], id=c[0]) for c in CASES])
def test_bad_input(tmp_path, monkeypatch, capsys, run, error, fragment):
    run(Context(tmp_path, monkeypatch, capsys), error, fragment)


@pytest.mark.parametrize(
    "argv",
    [
        ["generate", "--sides", "2"],
        ["stats", "koch", "--max-segments", "0"],
        ["stats", "koch", "--max-triangles", "lots"],
        ["derive", "koch", "-n", "-1"],
        ["derive", "koch", "--max-modules", "0"],
        ["derive"],
        ["grow"],
    ],
)
def test_usage_errors_exit_2_with_one_line(capsys, argv):
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
    out = capsys.readouterr()
    lines = out.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("lsys3d: error: ") and "--help" in lines[0], out.err
    assert out.out == ""


def test_error_messages_quoting_multiline_rules_stay_one_line(tmp_path, capsys):
    path = tmp_path / "plant.toml"
    path.write_text('axiom = "A(0)"\nrules = ["""A(x) ->\nA(1 / x)"""]\n')
    assert main(["derive", str(path)]) == 1
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1 and "division by zero" in lines[0] and "A(x) -> A(1 / x)" in lines[0]


def test_zero_width_is_clamped_to_a_thin_closed_tube():
    tree = lsys3d.generate(Grammar(axiom="!(0)F"), sides=4)
    assert tree.bark.is_watertight and tree.bark.volume > 0


def test_overflow_names_the_rule_parameter_and_module():
    # the second rule's second parameter overflows at generation 2; the first rule is innocent
    g = Grammar(axiom="A(1)B(1,1)", rules=["A(x) -> A(x * 2)", "B(x, y) -> B(x + 1, y * 1e200)"])
    with pytest.raises(DerivationError) as info:
        lsys3d.derive(g, 3)
    message = str(info.value)
    assert message.startswith("rules[1]:1:1: rule 'B(x, y) -> B(x + 1, y * 1e200)': ")
    assert "parameter 'y * 1e200' of B for module B(2,1e+200) (#1) while deriving generation 2" in message


# ---------------------------------------------------------------- limits: defaults, and each one can be raised
def test_defaults_leave_every_preset_a_hundredfold_headroom():
    """How the defaults were chosen: at least 100x what the largest bundled plant needs at its own iterations,
    grown as it is grown; the scene presets (a hedge, a wall of ivy: many plants) at least 30x."""
    assert GenerateOptions().limits.max_segments == DEFAULT_MAX_SEGMENTS
    assert GenerateOptions().limits.max_triangles == DEFAULT_MAX_TRIANGLES
    most = {group: {"modules": 0, "segments": 0, "triangles": 0} for group in ("plant", "scene")}
    for name in lsys3d.list_presets():
        g = lsys3d.load_preset(name)
        try:  # the tree the preset tests grow once per run (tests/grown.py): its modules and skeleton are draw's
            tree = grown(name)
            modules, skeleton = tree.modules, tree.skeleton
        except GeometryError:  # the string demonstrations (algae, dog) draw nothing that generate could mesh
            modules, skeleton = draw(g, g.iterations, g.seed)
        tubes = sweep(skeleton)
        m = most["scene" if g.group == "scene" else "plant"]
        m["modules"] = max(m["modules"], len(modules) + derive_module.PARAMETER_COST * len(modules.params))
        m["segments"] = max(m["segments"], len(skeleton))
        m["triangles"] = max(m["triangles"], len(tubes.faces))
    for group, factor in (("plant", 100), ("scene", 30)):
        m = most[group]
        assert m["modules"] * factor <= lsys3d.DEFAULT_MAX_MODULES, group
        assert m["segments"] * factor <= DEFAULT_MAX_SEGMENTS, group
        assert m["triangles"] * factor <= DEFAULT_MAX_TRIANGLES, group


def test_each_limit_can_be_raised(monkeypatch):
    koch = lsys3d.load_preset("koch")
    modules = lsys3d.derive(koch, 2)
    skeleton = interpret(modules, koch)
    n = len(skeleton)
    assert n == str(modules).count("F") > 1
    with pytest.raises(LimitError, match=f"up to {n} segments, more than the limit of {n - 1}"):
        interpret(modules, koch, max_segments=n - 1)
    assert len(interpret(modules, koch, max_segments=n)) == n
    tubes = sweep(skeleton)
    with pytest.raises(LimitError, match=f"{len(tubes.faces):,} tube triangles"):
        sweep(skeleton, max_triangles=len(tubes.faces) - 1)
    assert len(sweep(skeleton, max_triangles=len(tubes.faces)).faces) == len(tubes.faces)
    with pytest.raises(LimitError, match="segments"):
        lsys3d.generate(koch, 2, union=False, max_segments=10)
    with pytest.raises(LimitError, match="tube triangles"):
        lsys3d.generate(koch, 2, union=False, max_triangles=10)

    deep = "(" * 80 + "1" + ")" * 80
    with pytest.raises(GrammarError, match="nested deeper than 64"):
        Grammar(axiom=f"A({deep})")
    monkeypatch.setattr(lsys3d.lsystem.expr, "MAX_DEPTH", 100)
    assert str(Grammar(axiom=f"A({deep})").axiom_modules) == "A(1)"

    chain = "+".join(["1"] * 300)
    with pytest.raises(GrammarError, match="nested deeper than 100"):
        Grammar(axiom=f"A({chain})")
    monkeypatch.setattr(lsys3d.lsystem.expr, "MAX_DEPTH", 300)
    assert str(Grammar(axiom=f"A({chain})").axiom_modules) == "A(300)"

    spaced = "1" + " " * 4100
    with pytest.raises(GrammarError, match="longer than 4096"):
        Grammar(axiom=f"A({spaced})")
    monkeypatch.setattr(lsys3d.lsystem.expr, "MAX_LENGTH", 5000)
    assert str(Grammar(axiom=f"A({spaced})").axiom_modules) == "A(1)"

    many = ",".join(["1"] * 40)
    monkeypatch.setattr(lsys3d.lsystem.rules, "MAX_PARAMETERS", 40)  # the rules read it where they are parsed
    assert len(Grammar(axiom=f"A({many})").axiom_modules.params) == 40

    still = Grammar(axiom="A", rules=["A -> B", "B -> A"])
    with pytest.raises(LimitError, match="MAX_ITERATIONS"):
        lsys3d.derive(still, 20_001)
    monkeypatch.setattr(derive_module, "MAX_ITERATIONS", 20_001)
    assert str(lsys3d.derive(still, 20_001)) == "B"


def test_raising_the_depth_beyond_pythons_stack_is_still_an_error(monkeypatch):
    monkeypatch.setattr(lsys3d.lsystem.expr, "MAX_DEPTH", 10**6)
    with pytest.raises(GrammarError, match="nested too deeply for Python's stack"):
        Grammar(axiom="A(" + "(" * 2000 + "1" + ")" * 2000 + ")")
    monkeypatch.setattr(lsys3d.lsystem.expr, "MAX_LENGTH", 10**5)
    g = Grammar(axiom="A(1)", rules=["A(x) -> A(" + "x+" * 5000 + "1)"])  # parsed without recursion
    with pytest.raises(DerivationError, match="nested too deeply for Python's stack"):
        lsys3d.derive(g, 1)


def test_a_device_is_refused_before_it_is_read():
    if not Path("/dev/zero").exists():
        pytest.skip("no /dev/zero on this system")
    with pytest.raises(GrammarError, match="not a regular file"):
        Grammar.from_file("/dev/zero")


# ---------------------------------------------------------------- fuzzing
FUZZ = settings(deadline=None, suppress_health_check=[HealthCheck.too_slow])  # example counts from the profile
LIMITS = {"max_modules": 2_000}

RULE_ALPHABET = st.sampled_from(
    [*"AFBf+-&^/\\|$[]{}.!'\"~()<>:,=*", " ", "->", "x", "y", "1", "0.5", "2", "/", " x ", "(x)", "(x, y)", "^"]
)
PIECE = st.lists(RULE_ALPHABET, max_size=7).map("".join)
# mostly "left -> right", so that the random pieces reach every part of the rule parser (and beyond)
RULE_TEXT = st.tuples(PIECE, st.sampled_from(["->", " -> ", "=", " : ", ""]), PIECE).map("".join)


def run_pipeline(grammar: Grammar, iterations: int, union_too: bool = True):
    """Every stage with small limits; checks each result's invariants. LSystemError is the only other outcome."""
    try:
        modules = lsys3d.derive(grammar, iterations, **LIMITS)
        assert balanced(modules.symbol_text())
        assert np.isfinite(modules.params).all()
        skeleton = interpret(modules, grammar, max_segments=300)
        skeleton.validate()
        tubes = sweep(skeleton, lsys3d.SweepOptions(sides=4), max_triangles=20_000)
        assert np.isfinite(tubes.points).all()
        if union_too and 0 < len(tubes) <= 25:
            mesh = union(tubes)
            assert mesh.is_watertight and mesh.is_winding_consistent
            assert 0 < mesh.volume <= tubes.volumes().sum() * (1 + 1e-5)
    except LSystemError as exc:
        message = str(exc)
        assert message and "\n" not in message and "Traceback" not in message


@FUZZ
@given(RULE_TEXT, PIECE)
def test_random_rule_strings(rule, axiom):
    try:
        grammar = Grammar(axiom=axiom or "F", rules=[rule], angle=30)
    except GrammarError as exc:
        assert str(exc).startswith(("rules[0]:", "axiom:", "<grammar>")), str(exc)
        return
    run_pipeline(grammar, 2, union_too=False)


NUMBERS = st.sampled_from(["0", "1", "2", "0.5", "1e308", "-1", "3.7", "1e-300"])


def expressions(names: list[str]):
    leaves = st.one_of(NUMBERS, st.sampled_from(names)) if names else NUMBERS
    return st.recursive(
        leaves,
        lambda inner: st.one_of(
            st.tuples(inner, st.sampled_from(["+", "-", "*", "/", "^", "<", "==", "and"]), inner).map(
                lambda t: f"({t[0]} {t[1]} {t[2]})"
            ),
            st.tuples(st.sampled_from(["sqrt", "log", "exp", "sin", "abs", "-"]), inner).map(
                lambda t: f"{t[0]}({t[1]})"
            ),
        ),
        max_leaves=4,
    )


# weighted: drawing and branching often, a lone bracket or polygon brace (refused or an InterpretError) rarely
MODULES = [*"FFFFAABB++--&/!f~X", "branch", "branch", "branch", "lone", "{.f.+f.}"]


@st.composite
def successors(draw, names: list[str], depth: int = 0):
    out = []
    for _ in range(draw(st.integers(0, 6))):
        kind = draw(st.sampled_from(MODULES))
        if kind == "branch":
            out.append("[" + (draw(successors(names, depth + 1)) if depth < 2 else "F") + "]")
        elif kind == "lone":
            out.append(draw(st.sampled_from("[]{}")))
        elif kind in "AB" or (kind in "+-&/!~" and draw(st.booleans())):
            out.append(f"{kind}({draw(expressions(names))})")
        else:
            out.append(kind)
    return "".join(out)


@st.composite
def grammar_fields(draw):
    rules = []
    for _ in range(draw(st.integers(1, 3))):
        pred = draw(st.sampled_from(["A(x)", "A(x)", "B(x)", "F", "F", "X"]))
        names = ["x"] if "(" in pred else []
        rule = f"{pred}"
        if names and draw(st.booleans()):
            rule += f" : {draw(expressions(names))}"
        rule += f" -> {'F' if pred == 'F' else ''}{draw(successors(names))}"  # F grows
        if draw(st.booleans()):
            rule += f" : {draw(st.sampled_from(['1', '2', '0.5', '3', '1.5', '4', '0.25', '0']))}"
        rules.append(rule)
    axiom = draw(st.sampled_from(["A(1)", "F", "FA(1)", "X", "A(1)B(2)", "F[+A(0.5)]X", "{.f.+f.}A(1)"]))
    return {"axiom": axiom, "rules": rules, "angle": draw(st.sampled_from([25.0, 90.0]))}


@FUZZ
@given(grammar_fields(), st.integers(0, 4))
def test_random_grammars_through_every_stage(fields, iterations):
    try:
        grammar = Grammar(**fields)
    except GrammarError as exc:  # a weight of 0, an unbalanced bracket...: refused with a position
        assert re.match(r"(rules\[\d\]|axiom):1:\d+: ", str(exc)), str(exc)
        return
    run_pipeline(grammar, iterations)


# ---------------------------------------------------------------- nothing lost
def test_ctrl_c_during_export_keeps_the_old_file_and_exits_130(tmp_path, monkeypatch, capsys):
    target = tmp_path / "tree.glb"
    target.write_bytes(b"good old asset")

    def interrupted(f, chunks):
        f.write(b"half an asset")
        raise KeyboardInterrupt

    monkeypatch.setattr(atomic, "_write_chunks", interrupted)
    assert main(["generate", "koch", "-n", "1", "-o", str(target)]) == 130
    assert capsys.readouterr().err == "lsys3d: interrupted\n"
    assert target.read_bytes() == b"good old asset"
    assert [p.name for p in tmp_path.iterdir()] == ["tree.glb"]


def test_full_disk_through_the_cli_keeps_the_old_files(tmp_path, monkeypatch, capsys):
    target = tmp_path / "tree.gltf"
    old = {target: b"good old asset", target.with_suffix(".bin"): b"good old buffer"}
    for path, data in old.items():
        path.write_bytes(data)

    def full(f, chunks):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(atomic, "_write_chunks", full)
    assert main(["generate", "koch", "-n", "1", "-o", str(target)]) == 1
    assert capsys.readouterr().err == f"lsys3d: error: {target}: no space left on device\n"
    assert {p: p.read_bytes() for p in tmp_path.iterdir()} == old


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
def deliverable_signals() -> None:
    """In a child before it runs Python: SIGINT and SIGHUP back to their defaults.

    A shell's background job starts with SIGINT ignored (and ``nohup`` ignores SIGHUP); lsys3d keeps an ignored
    signal ignored, as it should, so a test of what it does when the signal arrives must not inherit that."""
    for signum in (signal.SIGINT, signal.SIGHUP):
        signal.signal(signum, signal.SIG_DFL)


def test_a_real_sigint_exits_130_and_keeps_the_old_file(tmp_path):
    target = tmp_path / "tree.glb"
    target.write_bytes(b"good old asset")
    proc = subprocess.Popen(
        [sys.executable, "-m", "lsys3d", "-v", "generate", "tree3d", "-n", "7", "-o", str(target)],
        stderr=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
        preexec_fn=deliverable_signals,
    )
    seen = []
    for line in proc.stderr:  # -v logs each stage once it is done; interrupt the sweep or the union
        seen.append(line)
        if line.startswith("lsys3d: interpret"):
            proc.send_signal(signal.SIGINT)
            break
    rest = proc.stderr.read()
    assert proc.wait(timeout=120) == 130, "".join(seen) + rest
    assert rest.splitlines()[-1] == "lsys3d: interrupted"
    assert "Traceback" not in rest
    assert target.read_bytes() == b"good old asset"
    assert [p.name for p in tmp_path.iterdir()] == ["tree.glb"]


# ================================================================ round 2 (issue 18)
# Bombs inside every documented limit, tracebacks, and nothing lost on a full disk or a SIGTERM.
BIG_INT = "1" + "0" * 400  # a TOML integer far beyond float range
X32 = ",".join(f"x{i}" for i in range(32))  # 32 formal parameters
DERIVE_CAP = 3 << 29  # 1.5 GiB of address space: derivation and printing (a bare `lsys3d derive` maps ~0.4 GiB)
MESH_CAP = 3 << 30  # 3 GiB for commands that load USD and build meshes (USD alone maps ~0.9 GiB)


def run_lsys3d(
    argv, cwd: Path, *, cap: int = DERIVE_CAP, fsize: int | None = None, timeout: float = 60, env=None, script=None
):
    """``python -m lsys3d argv`` in a subprocess whose address space is capped (RLIMIT_AS), and optionally its
    file size (RLIMIT_FSIZE: a write past it fails with EFBIG; Python ignores SIGXFSZ); with ``script``, that
    Python text runs with ``argv`` instead of ``-m lsys3d`` (several commands in one process, the same limits)."""
    import resource

    def limits():
        resource.setrlimit(resource.RLIMIT_AS, (cap, cap))
        if fsize is not None:
            resource.setrlimit(resource.RLIMIT_FSIZE, (fsize, fsize))

    return subprocess.run(
        [sys.executable, *(["-c", script] if script else ["-m", "lsys3d"]), *argv],
        cwd=cwd,
        preexec_fn=limits,
        capture_output=True,
        text=True,
        timeout=timeout,
        env=env,
    )


def one_error_line(proc: subprocess.CompletedProcess, fragment: str) -> str:
    lines = proc.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("lsys3d: error: ") and fragment in lines[0], proc.stderr
    return lines[0]


def leftovers(folder: Path) -> list[str]:
    """Temporary files of any writer left in ``folder``: ours (.<name>.<hex>.tmp.*), USD's (.<name>...tmp.XXXXXX)."""
    return sorted(p.name for p in folder.iterdir() if ".tmp" in p.name or p.name.startswith("lsys3d-"))


def rules_toml(axiom: str, rules: list[str], iterations: int, extra: str = "") -> str:
    body = ",\n".join(f"  {toml_string(r)}" for r in rules)
    return f"axiom = {toml_string(axiom)}\niterations = {iterations}\nrules = [\n{body}\n]\n{extra}"


BOMBS = [
    # D0L: B is never reached from the axiom; it used to be expanded anyway (23 GB at 40 steps)
    ("unreachable", rules_toml("A", ["A -> A", "B -> BB"], 40), ["derive"], 0, lambda out: out == "A\n"),
    # grows to 131,072 modules, then stops changing: that string is the rest of the generations (every
    # generation was kept: 22.9 GB); tests/test_derive.py checks that one generation is alive at a time
    (
        "fixed-point",
        rules_toml("A(0)", ["A(x) : x < 17 -> A(x + 1)A(x + 1)"], 10_000),
        ["stats", "--json"],
        0,
        lambda out: json.loads(out)["derive"]["modules"] == 2**17,
    ),
    # parameters count: 32-parameter modules at a third of the module limit took 11 GB
    (
        "parameters",
        rules_toml("A(" + ",".join(["1"] * 32) + ")", [f"A({X32}) -> A({X32})A({X32})"], 24),
        ["derive"],
        1,
        lambda out: out == "",
    ),
    # ... also where the length depends on the values (a condition): checked before each generation is allocated
    (
        "parameters-conditional",
        rules_toml("A(" + ",".join(["1"] * 32) + ")", [f"A({X32}) : x0 > 0 -> A({X32})A({X32})"], 24),
        # refused at generation 17, before it is allocated (at 22 by default: 1.8 GB, 10 s; at 19 with 5,000,000)
        ["derive", "--max-modules", "1000000"],
        1,
        lambda out: out == "",
    ),
    # ABOP-style context with the predecessor in the ignore set, and ']' as right context: quadratic before
    (
        "context-ignored-predecessor",
        rules_toml("B[A]", ["B < A -> AA", "A -> A"], 17, 'ignore = "A"\n'),
        ["stats", "--json"],
        0,
        lambda out: json.loads(out)["derive"]["modules"] == 2**17 + 3,
    ),
    (
        "context-branch-end",
        rules_toml("[A]", ["A > ] -> AA"], 17),
        ["stats", "--json"],
        0,
        lambda out: json.loads(out)["derive"]["modules"] == 2**17 + 2,
    ),
]


@pytest.mark.skipif(sys.platform != "linux", reason="RLIMIT_AS")
@pytest.mark.parametrize(("text", "argv", "status", "check"), [pytest.param(*b[1:], id=b[0]) for b in BOMBS])
def test_bombs_inside_the_limits_end_within_memory_and_time(tmp_path, text, argv, status, check):
    (tmp_path / "bomb.toml").write_text(text)
    proc = run_lsys3d([*argv, "bomb.toml"], tmp_path, cap=MESH_CAP)  # the goal is 4 GB
    assert proc.returncode == status, proc.stderr[-2000:]
    assert check(proc.stdout), proc.stdout[:200]
    if status:
        one_error_line(proc, "parameters (each counts as 0.4 of a module)")
    else:  # nothing but the grammar's warnings (a symbol with no rule and no meaning)
        assert all(line.startswith("lsys3d: warning: ") for line in proc.stderr.splitlines()), proc.stderr


@pytest.mark.skipif(sys.platform != "linux", reason="RLIMIT_AS")
def test_derive_prints_a_long_string_without_holding_its_text(tmp_path):
    """1,048,576 four-parameter modules (12 MB of text, 4.2M numbers) through a pipe: the text is streamed, each
    distinct number formatted once (str() held every number as a Python float and a string: 8.1 GB at 16.8M, so
    some 2 GB at these 4.2M, still beyond the 1.5 GiB the process may map; 20 generations instead of 22 print a
    quarter of the text, 1.4 CPU s instead of 3.4)."""
    (tmp_path / "long.toml").write_text(rules_toml("A(1,2,3,4)", ["A(a,b,c,d) -> A(a+1,b,c,d)A(a,b+0.5,c,d)"], 20))
    import resource

    def cap():
        resource.setrlimit(resource.RLIMIT_AS, (DERIVE_CAP, DERIVE_CAP))

    proc = subprocess.Popen(
        [sys.executable, "-m", "lsys3d", "derive", "long.toml"],
        cwd=tmp_path,
        preexec_fn=cap,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    size, head, tail = 0, b"", b""
    while chunk := proc.stdout.read(1 << 20):
        head = head or chunk[:40]
        tail = (tail + chunk)[-40:]
        size += len(chunk)
    assert proc.wait(timeout=120) == 0, proc.stderr.read().decode()[-2000:]
    assert head.startswith(b"A(21,2,3,4)A(20,2.5,3,4)") and tail.endswith(b"A(1,12,3,4)\n")
    assert size > 12_000_000


@pytest.mark.skipif(sys.platform != "linux", reason="RLIMIT_AS")
def test_grammar_parsing_is_linear_in_the_number_of_rules(tmp_path):
    """10,000 short rules parse within the time and memory goals (the quadratic parser took > 120 s and 15 GB at
    20,000 rules: a quarter of that at 10,000, some 3.7 GB, is still beyond the 1.5 GiB the process may map; the
    linear one takes 2 CPU s instead of 3.4 at 20,000); an error in the first of 4,000 identical rules is reported
    at once (it waited for the whole file: 119 s)."""
    many = [f"{'ABCDEFGHIJKLMNOPQRSTUVWXYZ'[i % 26]}(x) : x > {i} -> {'ABCDEFGH'[i % 8]}(x + 1)" for i in range(10_000)]
    (tmp_path / "many.toml").write_text(rules_toml("A(1)", many, 1))
    proc = run_lsys3d(["derive", "many.toml"], tmp_path)
    assert proc.returncode == 0 and proc.stdout == "A(2)\n", proc.stderr[-2000:]  # the first rule for A applies
    (tmp_path / "same.toml").write_text(rules_toml("F", ["F -> F("] + ["F -> FF"] * 4000, 1))
    proc = run_lsys3d(["derive", "same.toml"], tmp_path)
    assert proc.returncode == 1
    one_error_line(proc, "same.toml:4:10: unclosed '(' after 'F'")


# ``lsys3d derive FILE`` for each file in turn in one process (the suite pays Python's start-up once), run by
# run_lsys3d (its memory cap); prints each file's exit status and output as JSON.
DERIVE_EACH = """
import contextlib, io, json, sys
from lsys3d.cli import main

results = {}
for name in sys.argv[1:]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["derive", name])
    results[name] = [code, out.getvalue()[:100], err.getvalue()[-2000:]]
print(json.dumps(results))
"""


@pytest.mark.slow  # reads large files in a subprocess
@pytest.mark.skipif(sys.platform != "linux", reason="RLIMIT_AS")
def test_native_readers_are_linear_in_the_size_of_the_file(tmp_path):
    """10,000 rules as L-Py one-liners and as cpfg productions, 8,000 L-Py rule bodies with ifs and a 600 KB
    Lparser axiom read and derive within the time and memory goals (a reader that walked the file once per
    rule would take minutes)."""
    letters = "ABCDEFGHIJKLMNOPQRSTUVWXYZ"
    one_line = "".join(f"{letters[i % 26]}(x) --> {'ABCDEFGH'[i % 8]}(x + 1)\n" for i in range(10_000))
    (tmp_path / "many.lpy").write_text(f"Axiom: A(1)\nproduction:\n{one_line}endlsystem\n")
    bodies = "".join(f"{letters[i % 26]}(x) :\n  y = x + 1\n  if x > {i}:\n    produce B(y)\n" for i in range(8_000))
    (tmp_path / "bodies.lpy").write_text(f"Axiom: A(1)\nproduction:\n{bodies}endlsystem\n")
    cpfg = "".join(f"{letters[i % 26]}(x) : x > {i} --> {'ABCDEFGH'[i % 8]}(x + 1)\n" for i in range(10_000))
    (tmp_path / "many.l").write_text(f"Lsystem: 1\naxiom: A(1)\n{cpfg}endlsystem\n")
    (tmp_path / "long.ls").write_text("1\n30\n10\n" + "F+" * 300_000 + "\n@\n")
    # the first rule for A applies (in L-Py and cpfg, rules without weights are no stochastic alternatives)
    expected = {"many.lpy": "A(2)", "bodies.lpy": "B(2)", "many.l": "A(2)", "long.ls": None}
    proc = run_lsys3d(list(expected), tmp_path, script=DERIVE_EACH, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    results = json.loads(proc.stdout)
    assert list(results) == list(expected)
    for name, (code, out, err) in results.items():
        assert code == 0, (name, err)
        assert expected[name] is None or out == expected[name] + "\n", (name, out)


def test_many_identical_stochastic_rules_pick_in_linear_time():
    """4,000 equal alternatives of one pool: each module's choice is found by one sort, not a pass per rule."""
    g = Grammar(axiom="F" * 20_000, rules=[f"F -> {c}" for c in "ABCD"] * 1000)
    counts = {c: str(lsys3d.derive(g, 1, seed=3)).count(c) for c in "ABCD"}
    assert sum(counts.values()) == 20_000 and min(counts.values()) > 4000


def test_equal_weights_whose_sum_overflows_are_still_equal():
    g = Grammar(axiom="F" * 4000, rules=["F -> A : 1e308", "F -> B : 1e308"])
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no RuntimeWarning either
        text = str(lsys3d.derive(g, 1, seed=5))
    assert abs(text.count("A") / 4000 - 0.5) < 0.05


def test_iter_text_is_the_canonical_text_in_pieces():
    g = Grammar(axiom="A(0.5, -0, 1e-9)[+F(2)]B", rules=["A(x, y, z) -> A(x * 2, y, z)F(1 / 7)A(x, -y, z)"])
    s = lsys3d.derive(g, 5)
    for chunk in (1, 3, 7, 1 << 16):
        pieces = list(s.iter_text(chunk))
        assert "".join(pieces) == str(s) and len(pieces) == -(-len(s) // chunk)
    assert str(lsys3d.derive(g, 1)) == "A(1,0,0)F(0.142857)A(0.5,0,0)[+F(2)]B"


# ---------------------------------------------------------------- round 2: one line, never a traceback
def symlink_loop(ctx):
    os.symlink("loop.toml", ctx.tmp / "loop.toml")


def looping_folder(ctx):
    os.symlink("loopdir", ctx.tmp / "loopdir")


def deep_golden(ctx):
    ctx.file('{"a":' * 3000 + "1" + "}" * 3000, "deep.json")
    golden.check(ctx.tmp / "deep.json")


def huge_float32_leaves(ctx):
    tree = lsys3d.generate(Grammar(axiom="F~(0.5)"), union=False)
    tree = dataclasses.replace(
        tree, leaves=dataclasses.replace(tree.leaves, transforms=tree.leaves.transforms * 1e39)
    )  # scale 5e38: past float32
    lsys3d.export(tree, ctx.tmp / "t.glb", lsys3d.ExportOptions(instance_leaves=True))


def huge_svg_widths(ctx):
    tree = lsys3d.generate(Grammar(axiom="F"), union=False)
    sk = tree.skeleton
    wide = dataclasses.replace(sk, width_start=sk.width_start * 1e308, width_end=sk.width_end * 1e308)
    lsys3d.export(dataclasses.replace(tree, skeleton=wide), ctx.tmp / "t.svg")


def steps_file(ctx):
    ctx.file('axiom = "F(1e200)+F(1e200)"\n', "huge.toml")


ROUND_2 = [
    # -- TOML: numbers beyond float range, nesting
    ("toml-angle-beyond-float", grow(F + f"angle = {BIG_INT}\n"), GrammarError, "'angle' must be a number"),
    ("toml-define-beyond-float", grow(F + f"[defines]\nR = {BIG_INT}\n"), GrammarError, "define 'R' must be a finite"),
    ("toml-nested-deeply", grow(F + "x = " + "[" * 3000 + "]" * 3000 + "\n"), GrammarError, "nested too deeply"),
    ("toml-key-escape-sequence", grow(F + '"\\u001b[2J" = 1\n'), GrammarError, "unknown key '\\x1b[2J'"),
    # -- grammar paths
    ("path-too-long", cli("derive", "{tmp}/" + "x" * 300 + ".toml"), GrammarError, "file name too long"),
    ("path-symlink-loop", cli("derive", "{tmp}/loop.toml", setup=symlink_loop), GrammarError, "symbolic links"),
    ("path-folder", cli("derive", "{tmp}"), GrammarError, "the grammar file is a folder"),
    ("preset-escape-sequence", cli("derive", "\x1b]0;owned\x07tree"), GrammarError, "'\\x1b]0;owned\\x07tree'"),
    # -- sizes the mesh stages cannot compute with: the turtle names the module and the setting
    ("turtle-step-huge", cli("generate", "{tmp}/huge.toml", "-o", "{tmp}/t.glb", setup=steps_file), InterpretError,
     "module 0 'F(1e+200)' (forward): the turtle's position left the drawable range"),
    ("turtle-width-huge", grow('axiom = "!(1e300)F"\n'), InterpretError, "width must be a number from 0 to 1e+09"),
    ("turtle-leaf-huge", grow('axiom = "F~(1e300)"\n'), InterpretError, "leaf size must be a number from 0 to 1e+09"),
    ("export-leaf-beyond-float32", api(huge_float32_leaves), ExportError, "beyond the 32-bit float range"),
    ("export-svg-width-overflow", api(huge_svg_widths), ExportError, "extent (with the branch widths) holds a value"),
    # -- output paths
    ("output-name-too-long", cli("generate", "koch", "-o", "{tmp}/" + "t" * 300 + ".glb"), ExportError,
     "file name too long"),
    ("output-folder-loop", cli("generate", "koch", "-o", "{tmp}/loopdir/t.glb", setup=looping_folder), ExportError,
     "too many levels of symbolic links"),
    # -- golden files
    ("golden-nested-deeply", api(deep_golden), GoldenError, "nested too deeply"),
]  # fmt: skip


@pytest.mark.parametrize(("run", "error", "fragment"), [pytest.param(*c[1:], id=c[0]) for c in ROUND_2])
def test_bad_input_round_2(tmp_path, monkeypatch, capsys, run, error, fragment):
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # numpy's warnings would be lines of their own
        run(Context(tmp_path, monkeypatch, capsys), error, fragment)


@pytest.mark.parametrize(
    "argv",
    [["check", "x.json", "--rtol", "-1"], ["check", "x.json", "--rtol", "nan"], ["check", "x.json", "--rtol", "inf"]],
)
def test_bad_tolerances_are_usage_errors(capsys, argv):
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
    assert "--rtol: must be a finite number >= 0" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("field", "value", "fragment"),
    [
        ("iterations", -1, "'iterations' must be a whole number >= 0, not -1"),
        ("iterations", "3", "'iterations' must be a whole number >= 0"),
        ("iterations", True, "'iterations' must be a whole number >= 0, not true"),
        ("iterations", float("nan"), "'iterations' must be a whole number >= 0, not NaN"),
        ("seed", 1.5, "'seed' must be a whole number >= 0"),
        ("mesh", "yes", "'mesh' must be true or false"),
        ("preset", 7, "'preset' must be a preset's name"),
        ("preset", "tree3d\x00", "'preset' must be a preset's name"),
        ("preset", "../../etc/passwd", "no bundled preset named '../../etc/passwd'"),
        ("file", "plant\x00.toml", "'file' must be a file name"),
        ("text", 5, "'text' must be the grammar's text"),
        ("iterations", 10**400, "more than the limit of 10,000"),
        ("options", [], "'options' must be a table of options"),
        ("options", {"sweep": {"sides": 2}}, "recipe options: SweepOptions.sides"),
        ("options", {"colour": 1}, "recipe options: unknown option 'colour'"),
        ("grammar_sha256", 5, "'grammar_sha256' must be a text"),
    ],
)
def test_golden_recipe_fields_are_checked(tmp_path, capsys, field, value, fragment):
    recipe = {"iterations": 1, "seed": 0, "mesh": False, field: value}
    if field not in ("file", "text"):
        recipe.setdefault("preset", "koch")
    path = tmp_path / "g.json"
    path.write_text(json.dumps({"lsys3d_golden": 1, "recipe": recipe, "report": {}}))
    with pytest.raises(GoldenError, match=re.escape(fragment)):
        golden.check(path)
    assert main(["check", str(path)]) == 1
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith(f"lsys3d: error: {path}: ") and "Traceback" not in err[0]


def test_a_name_with_control_characters_makes_well_formed_svg(tmp_path):
    import xml.dom.minidom

    tree = lsys3d.generate(Grammar(axiom="F[+F]F", name="plant\x01\x1b[2J\x7f"), union=False)
    path = lsys3d.export(tree, tmp_path / "t.svg")
    document = xml.dom.minidom.parse(str(path))
    assert document.getElementsByTagName("title")[0].firstChild.data == "plant\\x01\\x1b[2J\\x7f"


def test_lone_surrogates_are_refused_where_they_enter():
    with pytest.raises(GrammarError, match=r"'name' is not valid Unicode text \(a lone surrogate at character 3\)"):
        Grammar(axiom="F", name="ab\udcff")


def test_a_long_file_name_gets_a_shorter_temporary_name(tmp_path):
    """A 251-byte name is valid; its temporary name (16 bytes longer) would not be, so its stem is cut."""
    for suffix in (".glb", ".usdc", ".usdz"):
        target = tmp_path / ("t" * (251 - len(suffix)) + suffix)
        assert lsys3d.export(lsys3d.generate("koch", 1, union=False), target) == target
    assert leftovers(tmp_path) == [] and len(list(tmp_path.iterdir())) == 3


def test_echoed_paths_are_escaped(tmp_path, capsys):
    """A file name with an escape sequence (or undecodable bytes) is printed escaped, never raw."""
    name = tmp_path / "tree\x1b[2J\udcff.glb"
    assert main(["generate", "koch", "-n", "1", "-o", str(name)]) == 0
    out = capsys.readouterr().out
    assert "\x1b" not in out and "tree\\x1b[2J\\udcff.glb" in out


# ---------------------------------------------------------------- round 2: the options checker (issue 13)


@pytest.mark.parametrize(
    "table", [f"step = {BIG_INT}", f"width = {BIG_INT}", f"tropism = [{BIG_INT}, 0, 0]", f"angle_jitter = {BIG_INT}"]
)
def test_turtle_table_integers_beyond_float_range(tmp_path, capsys, table):
    path = tmp_path / "plant.toml"
    path.write_text(f'axiom = "F"\n[turtle]\n{table}\n')
    with pytest.raises(LSystemError) as info:
        lsys3d.generate(path, union=False)
    check_message(str(info.value), "[turtle]")
    assert main(["generate", str(path), "--no-union", "-o", str(tmp_path / "t.glb")]) == 1
    assert len(capsys.readouterr().err.splitlines()) == 1


@pytest.mark.parametrize("argv", [["--turtle", f"step={BIG_INT}"], ["--sides", BIG_INT]])
def test_option_flags_beyond_float_range(tmp_path, capsys, argv):
    with pytest.raises(SystemExit) as info:  # usage errors, or ...
        code = main(["generate", "koch", "-n", "1", "--no-union", "-o", str(tmp_path / "t.glb"), *argv])
        raise SystemExit(code)  # ... errors of the options checker
    assert info.value.code in (1, 2)
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("lsys3d: error: ")


@pytest.mark.parametrize(
    "build",
    [
        lambda: lsys3d.TurtleOptions(step=int(BIG_INT)),
        lambda: lsys3d.SweepOptions(sides=int(BIG_INT)),
        lambda: lsys3d.SweepOptions(bark_octaves=10**9),  # a time bomb: 1e9 octaves of noise per vertex
        lambda: lsys3d.generate("koch", 1, union=False, options=GenerateOptions(turtle={"step": int(BIG_INT)})),
    ],
)
def test_option_classes_raise_lsys3d_errors(build):
    with pytest.raises(LSystemError) as info:
        build()
    check_message(str(info.value), "")


@pytest.mark.parametrize("table", ["step = 1e400", "tropism = [1e400, 0, 0]"])
def test_turtle_table_infinities_are_one_line(tmp_path, capsys, table):
    """Floats that overflow to inf: one line from a grammar (exit 1), a usage error from a flag (exit 2)."""
    path = tmp_path / "plant.toml"
    path.write_text(f'axiom = "F"\n[turtle]\n{table}\n')
    assert main(["generate", str(path), "--no-union", "-o", str(tmp_path / "t.glb")]) == 1
    with pytest.raises(SystemExit) as info:
        main(["generate", "koch", "-n", "1", "--turtle", "step=1e400", "-o", str(tmp_path / "t.glb")])
    assert info.value.code == 2
    assert all(line.startswith("lsys3d: error: ") for line in capsys.readouterr().err.splitlines())


# ---------------------------------------------------------------- round 2: full disk, every format
OUTPUTS = [".glb", ".gltf", ".usda", ".usdc", ".usd", ".usdz", ".obj", ".ply", ".stl", ".svg"]

# One process writes every format in turn (each a whole `lsys3d generate`), so the suite pays Python's and
# USD's start-up once.  argv: what to do ("fsize BYTES", "signal NAME" or "plain -"), the folder, the suffixes.
EVERY_FORMAT = """
import contextlib, io, json, os, resource, signal, sys
from lsys3d.cli import main
from lsys3d.exchange import atomic, usd

kind, value, folder, *suffixes = sys.argv[1:]
if kind == "fsize":  # a write past it fails with EFBIG (Python ignores SIGXFSZ)
    resource.setrlimit(resource.RLIMIT_FSIZE, (int(value), int(value)))
elif kind == "signal":  # the signal arrives while the writer has a temporary file open
    def during(fn):
        def wrapped(*args, **kw):
            result = fn(*args, **kw)
            os.kill(os.getpid(), getattr(signal, value))
            return result
        return wrapped
    atomic._write_chunks = during(atomic._write_chunks)  # every writer but USD's crate
    usd._whole_crate = during(usd._whole_crate)  # right after USD wrote a crate (.usdc/.usd, inside a .usdz)
results = {}
for suffix in suffixes:
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        code = main(["generate", "tree3d", "-n", "4", "--no-union", "-o", os.path.join(folder, "tree" + suffix)])
    results[suffix] = [code, err.getvalue()]
print(json.dumps(results))
"""


def every_format(kind: str, value, folder: Path, suffixes=OUTPUTS) -> dict[str, tuple[int, str, dict]]:
    """Write each format over old files in ``folder`` under a file-size limit or a signal; returns, per suffix,
    the exit status, stderr and the old files' contents afterwards (which must be the old contents)."""
    olds = {}
    for suffix in suffixes:
        olds[suffix] = {folder / f"tree{suffix}": f"good old {suffix}".encode()}
        if suffix == ".gltf":
            olds[suffix][folder / "tree.bin"] = b"good old buffer"
    scratch = folder.parent / "tmpdir"
    scratch.mkdir(exist_ok=True)
    env = {**os.environ, "TMPDIR": str(scratch)}
    results = {}
    for suffix in suffixes:  # one at a time: the .gltf's tree.bin is not the .glb's
        for path, data in olds[suffix].items():
            path.write_bytes(data)
    proc = subprocess.run(
        [sys.executable, "-c", EVERY_FORMAT, kind, str(value), str(folder), *suffixes],
        cwd=folder.parent,
        capture_output=True,
        text=True,
        timeout=300,
        env=env,
        preexec_fn=deliverable_signals,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    for suffix, (code, err) in json.loads(proc.stdout.splitlines()[-1]).items():
        results[suffix] = (code, err, {p: p.read_bytes() for p in olds[suffix]} == olds[suffix])
    assert leftovers(folder) == [] and list(scratch.iterdir()) == []  # ours, USD's, the temp directory's
    return results


@pytest.mark.skipif(sys.platform != "linux", reason="RLIMIT_FSIZE")
def test_file_size_limit_keeps_the_old_file_for_every_format(tmp_path):
    """``ulimit -f``: every writer fails with 'file too large' (USD's said 'crate file corrupt'; .usdz exited 0
    with a truncated package), keeps the old file, and leaves no temporary file, there or in TMPDIR."""
    folder = tmp_path / "out"
    folder.mkdir()
    results = every_format("fsize", 20_000, folder)  # each format writes more (the smallest, .svg, 33 KB)
    for suffix, (code, err, kept) in results.items():
        assert (code, kept) == (1, True), (suffix, err)
        assert (
            err == f"lsys3d: error: {folder / ('tree.bin' if suffix == '.gltf' else 'tree' + suffix)}: file too large\n"
        )


@pytest.fixture
def small_tmpfs(tmp_path):
    """A 64 KiB tmpfs, where mounting is allowed (root on Linux); skipped elsewhere."""
    folder = tmp_path / "small"
    folder.mkdir()
    if sys.platform != "linux" or os.geteuid() != 0:
        pytest.skip("mounting a tmpfs needs root on Linux")
    proc = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(folder)], capture_output=True)
    if proc.returncode:
        pytest.skip(f"cannot mount a tmpfs: {proc.stderr.decode().strip()}")
    try:
        yield folder
    finally:
        subprocess.run(["umount", str(folder)], check=True)


def test_full_file_system_keeps_the_old_file_for_every_format(small_tmpfs):
    """A full disk: 'no space left on device' for every format (the old files take 44 of the 64 KiB, every
    output is larger than the 20 KiB left), the old files kept, nothing left behind."""
    for suffix, (code, err, kept) in every_format("plain", "-", small_tmpfs).items():
        assert (code, kept) == (1, True), (suffix, err)
        assert err.endswith(": no space left on device\n") and len(err.splitlines()) == 1, (suffix, err)


# ---------------------------------------------------------------- round 2: SIGTERM and SIGHUP
@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
@pytest.mark.parametrize("signame", ["SIGTERM", "SIGHUP"])
def test_sigterm_during_export_keeps_the_old_file_and_leaves_nothing(tmp_path, signame):
    folder = tmp_path / "out"
    folder.mkdir()
    suffixes = OUTPUTS if signame == "SIGTERM" else [".glb", ".usdc", ".usdz"]
    for suffix, (code, err, kept) in every_format("signal", signame, folder, suffixes).items():
        assert (code, kept) == (128 + getattr(signal, signame), True), (suffix, err)
        assert err == f"lsys3d: interrupted ({signame})\n", suffix


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
def test_a_real_sigterm_exits_143_and_keeps_the_old_file(tmp_path):
    target = tmp_path / "tree.usdz"
    target.write_bytes(b"good old asset")
    scratch = tmp_path / "tmpdir"
    scratch.mkdir()
    proc = subprocess.Popen(
        [sys.executable, "-m", "lsys3d", "-v", "generate", "tree3d", "-n", "7", "-o", str(target)],
        stderr=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
        env={**os.environ, "TMPDIR": str(scratch)},
        preexec_fn=deliverable_signals,
    )
    seen = []
    for line in proc.stderr:  # -v logs each stage once it is done; terminate the sweep or the union
        seen.append(line)
        if line.startswith("lsys3d: interpret"):
            proc.send_signal(signal.SIGTERM)
            break
    rest = proc.stderr.read()
    assert proc.wait(timeout=120) == 143, "".join(seen) + rest
    assert rest.splitlines()[-1] == "lsys3d: interrupted (SIGTERM)" and "Traceback" not in rest
    assert target.read_bytes() == b"good old asset"
    assert leftovers(tmp_path) == [] and list(scratch.iterdir()) == []


def test_an_ignored_sighup_stays_ignored():
    from lsys3d.cli import _signals_interrupt

    previous = signal.signal(signal.SIGHUP, signal.SIG_IGN)
    try:
        with _signals_interrupt():
            assert signal.getsignal(signal.SIGHUP) is signal.SIG_IGN
            assert signal.getsignal(signal.SIGTERM) not in (signal.SIG_DFL, signal.SIG_IGN)
        assert signal.getsignal(signal.SIGTERM) is not None
    finally:
        signal.signal(signal.SIGHUP, previous)


# ================================================================ round 3 (issue 38)
# The new doors: native readers, models, batch manifests, forests, the rig/wind flags.  Root causes: one reader
# for every file (lsys3d.external: regular files only, opened without blocking, bounded, depth-bounded JSON), one
# rule for paths a file names (resolved, inside the folder the user named), the manifest as lsys3d's own record.
def finishes(fn, seconds: float = 30.0):
    """``fn()``'s result or exception, failing (not hanging) when it has not returned within ``seconds``."""
    import threading

    box: dict = {}

    def run():
        try:
            box["value"] = fn()
        except BaseException as exc:  # handed to the test
            box["error"] = exc

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(seconds)
    assert not thread.is_alive(), f"still running after {seconds} s"
    if "error" in box:
        raise box["error"]
    return box["value"]


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="FIFOs")
def test_the_one_reader_refuses_special_files_without_blocking(tmp_path):
    from lsys3d.external import FileRefused, open_regular, read_file

    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    for path, fragment in [
        (fifo, "not a regular file"),
        ("/dev/zero", "not a regular file"),
        (tmp_path, "is a folder"),
        (tmp_path / "none", "no such thing file"),
    ]:
        with pytest.raises(FileRefused, match=fragment):
            finishes(lambda p=path: read_file(p, 100, "thing", "LIMIT"))
    (tmp_path / "big").write_bytes(b"x" * 101)
    with pytest.raises(FileRefused, match=r"101 bytes, more than 100 \(LIMIT\)"):
        read_file(tmp_path / "big", 100, "thing", "LIMIT")
    (tmp_path / "link").symlink_to(tmp_path / "big")
    with pytest.raises(FileRefused, match="is a symlink"):
        open_regular(tmp_path / "link", 1000, "thing", "LIMIT", follow=False)
    assert read_file(tmp_path / "link", 1000, "thing", "LIMIT") == b"x" * 101


def test_json_nesting_is_checked_before_parsing():
    from lsys3d.external import MAX_JSON_DEPTH, json_depth, load_json

    assert json_depth('{"a": "[[[[", "b": ["\\"]]", [1]]}') == 3
    assert json_depth('["\\\\", [[]]]') == 3  # an escaped backslash ends before the quote that closes the string
    assert load_json("[" * MAX_JSON_DEPTH + "]" * MAX_JSON_DEPTH) == eval("[" * MAX_JSON_DEPTH + "]" * MAX_JSON_DEPTH)
    with pytest.raises(ValueError, match="nested 100000 deep"):
        load_json("[" * 100_000 + "]" * 100_000)


def test_the_path_rule_follows_symlinks_and_stays_inside(tmp_path):
    from lsys3d.external import FileRefused, inside

    (tmp_path / "lib").mkdir()
    (tmp_path / "outside.usdc").write_text("x")
    (tmp_path / "lib" / "in.usdc").symlink_to(tmp_path / "outside.usdc")
    (tmp_path / "lib" / "loop").symlink_to(tmp_path / "lib" / "loop")
    assert inside(tmp_path / "lib", "a/b.usdc", "asset") == (tmp_path / "lib" / "a" / "b.usdc").resolve()
    for name in ("in.usdc", "../outside.usdc", str(tmp_path / "outside.usdc"), "a/../../outside.usdc"):
        with pytest.raises(FileRefused, match="the asset is outside the folder"):
            inside(tmp_path / "lib", name, "asset")
    with pytest.raises(FileRefused):
        inside(tmp_path / "lib", "loop", "asset")


CPFG = 'Lsystem: 1\n#include "{name}"\nderivation length: 2\naxiom: F\nF --> FF\nendlsystem\n'


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="FIFOs")
def test_cpfg_includes_stay_in_the_grammars_folder_and_never_block(tmp_path):
    folder, outside = tmp_path / "grammar", tmp_path / "elsewhere"
    folder.mkdir()
    outside.mkdir()
    (outside / "secret.l").write_text("the secret first line\n")
    (folder / "inc.l").symlink_to(outside / "secret.l")
    os.mkfifo(folder / "fifo.l")
    (folder / "ok.l").write_text("#define N 2\n")
    for name, fragment in [("inc.l", "outside the folder"), ("fifo.l", "not a regular file")]:
        (folder / "plant.l").write_text(CPFG.format(name=name))
        with pytest.raises(GrammarError, match=fragment) as info:
            finishes(lambda: Grammar.from_file(folder / "plant.l"))
        assert str(info.value).startswith(f"{folder / 'plant.l'}:2:1: #include '{name}'")
        assert "secret" not in str(info.value)
    (folder / "plant.l").write_text(CPFG.format(name="ok.l"))
    assert Grammar.from_file(folder / "plant.l").iterations == 2


def test_a_utf8_bom_is_accepted_in_every_grammar_file(tmp_path):
    bom = "\ufeff"
    files = {
        "bom.toml": 'axiom = "F"\nrules = ["F -> FF"]\n',
        "bom.lpy": "Axiom: F\nderivation length: 2\nproduction:\nF --> FF\nendlsystem\n",
        "bom.l": "Lsystem: 1\nderivation length: 2\naxiom: F\nF --> FF\nendlsystem\n",
    }
    for name, text in files.items():
        (tmp_path / name).write_text(bom + text, encoding="utf-8")
        grammar = Grammar.from_file(tmp_path / name)
        assert grammar.axiom == "F" and len(grammar.rules) == 1, name


@pytest.mark.parametrize(
    ("name", "text", "where"),
    [
        ("nul.toml", 'axiom = "F"\nrules = ["F -> F\\u0000F"]\n', "nul.toml:2:17:"),
        ("nul.l", "Lsystem: 1\nderivation length: 1\naxiom: F\nF --> F\0F\nendlsystem\n", "nul.l:4:8:"),
    ],
)
def test_a_nul_inside_a_rule_is_refused_where_it_stands(tmp_path, name, text, where):
    (tmp_path / name).write_text(text)
    with pytest.raises(GrammarError, match="holds a NUL character") as info:
        Grammar.from_file(tmp_path / name)
    assert str(info.value).startswith(f"{tmp_path / where}")
    with pytest.raises(GrammarError, match="holds a NUL character"):
        Grammar(axiom="F\0")


def lpy_ifs(blocks: int, produce: str) -> str:
    body = "".join(f"    if x > {i}:\n        y = {i}\n    else:\n        y = {i + 1}\n" for i in range(blocks))
    return f"Axiom: A(1)\nderivation length: 2\nproduction:\nA(x):\n{body}{produce}endlsystem\n"


@pytest.mark.parametrize(
    ("produce", "fragment"),
    [
        ("    produce A(y)\n", "more than 256 ways through the rule's 'if's"),  # every way produces
        ("    nproduce A(y)\n", "more than 256 ways"),
        ("", "MAX_WALK"),  # no way produces: the work is bounded, not only the rules made
    ],
)
def test_lpy_if_else_chains_are_bounded_in_work(produce, fragment):
    """20 blocks one after the other: 2**20 ways (16 took over 120 s, 20 took 5.8 GB); refused in a moment."""
    with pytest.raises(GrammarError, match=fragment) as info:
        finishes(lambda: Grammar.from_text(lpy_ifs(20, produce), source="ifs.lpy"))
    assert str(info.value).startswith("ifs.lpy:4:1: ")
    assert len(Grammar.from_text(lpy_ifs(7, "    produce A(y)\n"), source="ifs.lpy").rules) == 128


def instanced_glb(path: Path, nodes: int, subdivisions: int = 3) -> int:
    """A .glb whose ``nodes`` nodes all place one icosphere; its triangles."""
    import struct

    import trimesh

    mesh = trimesh.creation.icosphere(subdivisions=subdivisions)
    glb = trimesh.Scene(mesh).export(file_type="glb")
    (length,) = struct.unpack_from("<I", glb, 12)
    doc = json.loads(glb[20 : 20 + length])
    doc["nodes"] = [{"mesh": 0, "translation": [i * 0.01, 0, 0]} for i in range(nodes)]
    doc["scenes"] = [{"nodes": list(range(nodes))}]
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    binary = glb[20 + length :]
    head = b"glTF" + struct.pack("<II", 2, 20 + len(text) + len(binary)) + struct.pack("<I4s", len(text), b"JSON")
    path.write_bytes(head + text + binary)
    return len(mesh.faces)


def test_a_model_whose_nodes_instance_one_mesh_is_counted_before_flattening(tmp_path):
    """20,000 nodes placing one 1,280-triangle mesh (a 1 MB file): flattened it took 7.7 GB and 105 s."""
    from lsys3d.errors import AssetError
    from lsys3d.look.surfaces import load_model

    triangles = instanced_glb(tmp_path / "bomb.glb", 20_000)
    assert (tmp_path / "bomb.glb").stat().st_size < 2 << 20
    with pytest.raises(AssetError, match=f"the model has {20_000 * triangles:,} triangles, more than 200,000"):
        finishes(lambda: load_model(tmp_path / "bomb.glb"))
    instanced_glb(tmp_path / "few.glb", 10, subdivisions=1)
    assert len(load_model(tmp_path / "few.glb").faces) == 10 * 80  # each placement counted, and made


def test_wind_keys_are_predicted_before_allocating(monkeypatch):
    """At the documented maxima (60 s at 120 fps on a rig of 17,693 joints: 127 million keys) the animation took
    5.2 GB before running out of memory; the keys are counted first and refused (MAX_WIND_KEYS: 16 million)."""
    wind = importlib.import_module("lsys3d.look.wind")

    tree = lsys3d.generate("abop-1.24a", iterations=2, rig=True, wind_animation=2, wind_fps=12)
    keys = len(tree.animation) * len(tree.rig)
    monkeypatch.setattr(wind, "MAX_WIND_KEYS", keys - 1)
    with pytest.raises(LimitError, match=rf"25 keyframes for {len(tree.rig)} joints would be {keys} joint keys"):
        lsys3d.generate("abop-1.24a", iterations=2, rig=True, wind_animation=2, wind_fps=12)


def test_forest_ranges_fit_in_memory_or_are_refused():
    from lsys3d.library.forest import MAX_INSTANCES, ForestOptions

    assert MAX_INSTANCES == 1_000_000  # about 800 bytes an instance measured: 0.93 GB and 38 s at the most
    with pytest.raises(OptionsError, match="count"):
        ForestOptions(count=MAX_INSTANCES + 1)
    with pytest.raises(OptionsError, match="seed"):
        ForestOptions(seed=2**64)
    assert ForestOptions(seed=2**64 - 1).seed == 2**64 - 1


def test_a_huge_forest_seed_is_one_line(tmp_path, capsys):
    with pytest.raises(SystemExit) as info:  # a usage error, as every flag out of its range
        main(["forest", str(tmp_path), "--seed", "9" * 30])
    assert info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "seed" in err[0], err


def test_a_library_naming_files_outside_it_is_refused(tmp_path):
    from lsys3d.exchange.common import ExportOptions
    from lsys3d.exchange.library import LibraryVariant, read_library, write_library
    from lsys3d.library.forest import forest

    (tmp_path / "lib").mkdir()
    (tmp_path / "secret").mkdir()
    (tmp_path / "secret" / "tree.usdc").write_text("#usda 1.0\n")
    (tmp_path / "lib" / "tree").mkdir()
    (tmp_path / "lib" / "tree" / "linked.usdc").symlink_to(tmp_path / "secret" / "tree.usdc")
    for usd, glb in [
        (str(tmp_path / "secret" / "tree.usdc"), None),
        ("../secret/tree.usdc", None),
        ("tree/linked.usdc", None),
        ("tree/t.usdc", str(tmp_path / "secret" / "tree.glb")),
    ]:
        variant = LibraryVariant("tree", 0, usd, glb, 1.0, (-1, 0, -1), (1, 2, 1))
        write_library(tmp_path / "lib" / "library.usda", [variant], ExportOptions())
        with pytest.raises(lsys3d.ForestError, match="is outside the folder"):
            read_library(tmp_path / "lib")
        for suffix in (".usdc", ".glb"):
            with pytest.raises(lsys3d.ForestError, match="is outside the folder"):
                forest(tmp_path / "lib", tmp_path / f"forest{suffix}")
            assert not (tmp_path / f"forest{suffix}").exists()


def small_jobs(folder: Path, name: str = "koch", formats: str = '["svg"]') -> Path:
    path = folder / "jobs.toml"
    path.write_text(f'[[jobs]]\ngrammar = "koch"\nname = "{name}"\nseeds = "0"\nformats = {formats}\n')
    return path


def done_line(the, job, files: list[dict]) -> str:
    from lsys3d.library.batch import MANIFEST_FORMAT, _export_key

    line = {
        "export": _export_key(job),
        "files": files,
        "id": job.id,
        "lsys3d_manifest": MANIFEST_FORMAT,
        "recipe": the.recipes[job.id],
        "run": {"finished": "2026-01-01T00:00:00.000000Z"},
        "status": "done",
    }
    return json.dumps(line) + "\n"


def test_a_manifest_line_naming_a_file_outside_outdir_never_counts_the_job_done(tmp_path):
    from lsys3d.library.batch import plan
    from lsys3d.library.worker import sha256_of

    jobs, outdir = small_jobs(tmp_path), tmp_path / "out"
    (outdir / "koch").mkdir(parents=True)
    the = plan(jobs, outdir)
    job = the.jobs[0]
    mine = outdir / job.paths[0]
    mine.write_text("<svg/>")
    elsewhere = tmp_path / "koch_s0.svg"
    elsewhere.write_text("<svg/>")
    entry = {"bytes": 6, "sha256": sha256_of(mine)}
    (outdir / "manifest.jsonl").write_text(done_line(the, job, [{**entry, "path": job.paths[0]}]))
    assert plan(jobs, outdir).skipped == [job.id]  # the line as lsys3d writes it: done
    mine.unlink()
    (outdir / "koch" / "koch_s0.svg").symlink_to(elsewhere)  # the right name, but a symlink out of OUTDIR
    for files in (
        [{**entry, "path": str(elsewhere)}],
        [{**entry, "path": "../koch_s0.svg"}],
        [{**entry, "path": job.paths[0]}],
    ):
        (outdir / "manifest.jsonl").write_text(done_line(the, job, files))
        assert plan(jobs, outdir).skipped == [], files


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="FIFOs")
def test_the_manifest_is_a_regular_file_of_outdir_never_a_symlink_pipe_or_device(tmp_path, capsys):
    jobs, outdir = small_jobs(tmp_path), tmp_path / "out"
    outdir.mkdir()
    target = tmp_path / "elsewhere.jsonl"
    target.write_text("")
    manifest = outdir / "manifest.jsonl"
    for make, fragment in [
        (lambda: manifest.symlink_to(target), "the manifest is a symlink"),
        (lambda: manifest.symlink_to("/dev/zero"), "the manifest is a symlink"),
        (lambda: os.mkfifo(manifest), "the manifest is not a regular file"),
    ]:
        make()
        assert finishes(lambda: main(["batch", str(jobs), "-o", str(outdir), "-q"])) == 1
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith(f"lsys3d: error: {manifest}: ") and fragment in err[0], err
        manifest.unlink()
    assert target.read_text() == ""  # nothing appended through the link
    assert not (outdir / "koch" / "koch_s0.svg").exists()


def test_the_manifest_writer_refuses_a_symlink_made_after_the_plan(tmp_path):
    from lsys3d.library.batch import _ManifestWriter

    target = tmp_path / "elsewhere.jsonl"
    target.write_text("")
    (tmp_path / "manifest.jsonl").symlink_to(target)
    with pytest.raises(lsys3d.BatchError, match="the manifest is a symlink"):
        _ManifestWriter(tmp_path / "manifest.jsonl")
    assert target.read_text() == ""


def test_bad_manifest_lines_are_skipped_with_a_warning(tmp_path, caplog):
    from lsys3d.library.batch import MAX_MANIFEST_LINE, read_manifests

    good = json.dumps({"id": "a_s0", "lsys3d_manifest": 1, "status": "failed"})
    lines = [
        "[" * 200_000 + "]" * 200_000,
        '{"id": ' + "[" * 100 + "]" * 100 + "}",
        "x" * (MAX_MANIFEST_LINE + 10),
        good,
    ]
    (tmp_path / "manifest.jsonl").write_text("\n".join(lines) + "\n")
    with caplog.at_level("WARNING", logger="lsys3d"):
        assert list(read_manifests(tmp_path)) == ["a_s0"]
    assert [r.getMessage().split(":")[-1] for r in caplog.records] == [" not a manifest line, skipped"] * 3


def test_jobs_turtle_option_as_a_list_of_key_value(tmp_path):
    from lsys3d.library.jobs import read_jobs

    path = tmp_path / "jobs.toml"
    path.write_text(
        '[[jobs]]\ngrammar = "koch"\nformats = ["svg"]\noptions = { turtle = ["width_jitter=0.2", "step = 2"] }\n'
    )
    (job,) = read_jobs(path)
    assert dict(job.options.turtle) == {"step": 2, "width_jitter": 0.2}
    for bad, fragment in [('["nope=1"]', "expected KEY=VALUE"), ("[3]", "expected KEY=VALUE"), ("3", "a table")]:
        path.write_text(f'[[jobs]]\ngrammar = "koch"\nformats = ["svg"]\noptions = {{ turtle = {bad} }}\n')
        with pytest.raises(lsys3d.BatchError, match=fragment) as info:
            read_jobs(path)
        assert str(info.value).startswith(f"{path}:4:")


def test_a_job_failing_on_a_later_format_leaves_none_of_its_files(tmp_path):
    from lsys3d.library.jobs import read_jobs
    from lsys3d.library.worker import run_job

    (job,) = read_jobs(small_jobs(tmp_path, formats='["svg", "obj"]'))
    (tmp_path / "koch").mkdir()
    (tmp_path / "koch" / "koch_s0.obj").mkdir()  # the second format cannot be written
    line = run_job(job, tmp_path)
    assert line["status"] == "failed" and "koch_s0.obj: is a folder" in line["error"]
    assert sorted(p.name for p in (tmp_path / "koch").iterdir()) == ["koch_s0.obj"]


@pytest.mark.parametrize("name", ["manifest.jsonl", "manifest-1-of-2.jsonl", "library.usda"])
def test_a_job_named_like_the_batchs_own_files_is_refused_naming_that_path(tmp_path, capsys, name):
    jobs, outdir = small_jobs(tmp_path, name=name), tmp_path / "out"
    assert main(["batch", str(jobs), "-o", str(outdir), "-q"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"lsys3d: error: {outdir / name}: the job name"), err
    assert not outdir.exists()


def test_rig_with_a_format_that_holds_no_joints_is_refused(tmp_path, capsys):
    for suffix in (".stl", ".obj", ".ply", ".svg"):
        assert main(["generate", "koch", "-n", "1", "--rig", "-o", str(tmp_path / f"k{suffix}")]) == 1
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and f"--rig: a {suffix} file holds no joints" in err[0], err
        assert not (tmp_path / f"k{suffix}").exists()


@pytest.mark.skipif(importlib.util.find_spec("distributed") is None, reason="needs Dask")
@pytest.mark.parametrize("address", ["foo://host:1", "inproc://x"])
def test_a_scheduler_address_that_cannot_work_exits_with_one_line(tmp_path, address):
    """The Client's constructor failed and left a half-made client whose __del__ waited forever at exit."""
    small_jobs(tmp_path)
    proc = run_lsys3d(["batch", "jobs.toml", "-o", "out", "--scheduler", address], tmp_path, cap=MESH_CAP, timeout=60)
    assert proc.returncode == 1
    one_error_line(proc, "cannot reach the Dask scheduler")


def test_a_batch_of_one_failing_job_prints_its_failure_once(tmp_path, capsys):
    (tmp_path / "broken.toml").write_text('axiom = "F"\nrules = ["F -> F("]\n')
    jobs = tmp_path / "jobs.toml"
    jobs.write_text('[[jobs]]\ngrammar = "broken.toml"\nseeds = "0"\nformats = ["svg"]\n')
    assert main(["batch", str(jobs), "-o", str(tmp_path / "out"), "-q"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"lsys3d: error: broken_s0 failed: {tmp_path / 'broken.toml'}:2:17: unclosed '(' after 'F'"], err
