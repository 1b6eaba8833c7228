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
"""

from __future__ import annotations

import errno
import importlib
import json
import os
import re
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
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
    TurtleOptions,
)
from lsys3d.cli import build_parser, main
from lsys3d.exchange import atomic
from lsys3d.pipeline import GenerateOptions
from lsys3d.sweep import DEFAULT_MAX_TRIANGLES, sweep
from lsys3d.turtle import DEFAULT_MAX_SEGMENTS, interpret
from lsys3d.union import union

derive_module = importlib.import_module("lsys3d.derive")  # lsys3d.derive is the function


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
        ("[turtle]\nstep = {value}\n", "'step' must be a finite number"),
        ("[turtle]\ntropism = [{value}, 0, 0]\n", "'tropism' must be a list of three numbers"),
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
    import lsys3d.expr as expr

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
        assert "Traceback" not in out.err

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
    ctx.monkeypatch.setattr(lsys3d.grammar, "MAX_GRAMMAR_BYTES", 64)
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
    ("file-too-large", api(big_file), GrammarError, "larger than 64 (lsys3d.grammar.MAX_GRAMMAR_BYTES)"),
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
    ("polygon-nested", grow('axiom = "{.f{.f}}"\n'), InterpretError, "already open"),
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
    ("limit-triangles", cli("stats", "koch", "--mesh", "--max-triangles", "1000"), LimitError, "4,944 tube triangles"),
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
    ("output-bad-options", api(bad_export_options), ExportError, "units must be one of"),
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
    """How the defaults were chosen: at least 100x what the largest bundled preset needs at its own iterations."""
    assert GenerateOptions().max_segments == DEFAULT_MAX_SEGMENTS
    assert GenerateOptions().max_tube_triangles == DEFAULT_MAX_TRIANGLES
    most = {"modules": 0, "segments": 0, "triangles": 0}
    for name in lsys3d.list_presets():
        g = lsys3d.load_preset(name)
        modules = lsys3d.derive(g)
        skeleton = interpret(modules, g)
        tubes = sweep(skeleton)
        most = {
            "modules": max(most["modules"], len(modules)),
            "segments": max(most["segments"], len(skeleton)),
            "triangles": max(most["triangles"], len(tubes.faces)),
        }
    assert most["modules"] * 100 <= lsys3d.DEFAULT_MAX_MODULES
    assert most["segments"] * 100 <= DEFAULT_MAX_SEGMENTS
    assert most["triangles"] * 100 <= DEFAULT_MAX_TRIANGLES


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
        lsys3d.generate(koch, 2, union=False, max_tube_triangles=10)

    deep = "(" * 80 + "1" + ")" * 80
    with pytest.raises(GrammarError, match="nested deeper than 64"):
        Grammar(axiom=f"A({deep})")
    monkeypatch.setattr(lsys3d.expr, "MAX_DEPTH", 100)
    assert str(Grammar(axiom=f"A({deep})").axiom_modules) == "A(1)"

    chain = "+".join(["1"] * 300)
    with pytest.raises(GrammarError, match="nested deeper than 100"):
        Grammar(axiom=f"A({chain})")
    monkeypatch.setattr(lsys3d.expr, "MAX_DEPTH", 300)
    assert str(Grammar(axiom=f"A({chain})").axiom_modules) == "A(300)"

    spaced = "1" + " " * 4100
    with pytest.raises(GrammarError, match="longer than 4096"):
        Grammar(axiom=f"A({spaced})")
    monkeypatch.setattr(lsys3d.expr, "MAX_LENGTH", 5000)
    assert str(Grammar(axiom=f"A({spaced})").axiom_modules) == "A(1)"

    many = ",".join(["1"] * 40)
    monkeypatch.setattr(lsys3d.grammar, "MAX_PARAMETERS", 40)
    assert len(Grammar(axiom=f"A({many})").axiom_modules.params) == 40

    still = Grammar(axiom="A", rules=["A -> B", "B -> A"])
    with pytest.raises(LimitError, match="MAX_ITERATIONS"):
        lsys3d.derive(still, 20_001)
    monkeypatch.setattr(derive_module, "MAX_ITERATIONS", 20_001)
    assert str(lsys3d.derive(still, 20_001)) == "B"


def test_raising_the_depth_beyond_pythons_stack_is_still_an_error(monkeypatch):
    monkeypatch.setattr(lsys3d.expr, "MAX_DEPTH", 10**6)
    with pytest.raises(GrammarError, match="nested too deeply for Python's stack"):
        Grammar(axiom="A(" + "(" * 2000 + "1" + ")" * 2000 + ")")
    monkeypatch.setattr(lsys3d.expr, "MAX_LENGTH", 10**5)
    g = Grammar(axiom="A(1)", rules=["A(x) -> A(" + "x+" * 5000 + "1)"])  # parsed without recursion
    with pytest.raises(DerivationError, match="nested too deeply for Python's stack"):
        lsys3d.derive(g, 1)


def test_a_device_is_read_no_further_than_the_size_limit():
    if not Path("/dev/zero").exists():
        pytest.skip("no /dev/zero on this system")
    with pytest.raises(GrammarError, match="larger than"):
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
def test_a_real_sigint_exits_130_and_keeps_the_old_file(tmp_path):
    target = tmp_path / "tree.glb"
    target.write_bytes(b"good old asset")
    proc = subprocess.Popen(
        [sys.executable, "-m", "lsys3d", "-v", "generate", "tree3d", "-n", "7", "-o", str(target)],
        stderr=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
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
