"""The native readers against lsys3d's TOML path, measured in the same run.

    python benchmarks/bench_readers.py [--quick]

Reading: the same grammar written as TOML, as an L-Py file (one-line rules, and rule bodies with ifs),
as a cpfg file and (single-character symbols) as an Lparser file, at several sizes; the ratio is the
reader's time over TOML's, so 1.0x is "as fast as TOML" and a reader that grew worse than linearly
would show a ratio that climbs with the size.

Deriving: the corpus's largest models derived from the native file and from the same rules in TOML;
the strings are checked equal and the ratio should stay near 1.0x (the dialects change the notation,
not the engine).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from timing import best_of

import lsys3d

CORPUS = Path(__file__).resolve().parent.parent / "tests" / "corpus"


def toml_text(axiom: str, rules: list[str], **keys) -> str:
    lines = [f"axiom = {json.dumps(axiom)}"] + [f"{k} = {json.dumps(v)}" for k, v in keys.items()]
    return "\n".join(lines) + "\nrules = [\n" + "".join(f"  {json.dumps(r)},\n" for r in rules) + "]\n"


def pairs(n: int) -> dict[str, tuple[str, str, str]]:
    """For each reader: (native text, its source name, the same grammar in TOML), with ``n`` rules."""
    names = [f"A{i}" for i in range(n + 1)]
    one_line = [f"A{i}(x) --> F(x)[+A{i + 1}(x + 1)]A{i}(x + 1)" for i in range(n)]
    lpy = f"module {', '.join(names)}\nAxiom: A0(0)\nproduction:\n" + "\n".join(one_line) + "\nendlsystem\n"
    lpy_toml = toml_text("A0(0)", [r.replace("-->", "->") for r in one_line], modules=names, dialect="lpy")
    bodies = "".join(
        f"A{i}(x) :\n    y = x + 1\n    if x < {i + 2}:\n        produce F(x)[+A{i + 1}(y)]A{i}(y)\n" for i in range(n)
    )
    lpy_bodies = f"module {', '.join(names)}\nAxiom: A0(0)\nproduction:\n{bodies}endlsystem\n"
    bodies_toml = toml_text(
        "A0(0)",
        [f"A{i}(x) : {{y = x + 1}} (x < {i + 2}) -> F(x)[+A{i + 1}(y)]A{i}(y)" for i in range(n)],
        modules=names,
        dialect="lpy",
    )
    conditional = [f"A(x) : x < {i + 2} --> F(x)[+A(x + 1)]A(x + 1)" for i in range(n)]
    cpfg = "#define N 1\nLsystem: 1\nderivation length: N\naxiom: A(0)\n" + "\n".join(conditional) + "\nendlsystem\n"
    cpfg_toml = toml_text("A(0)", [r.replace("-->", "->") for r in conditional], dialect="cpfg")
    return {
        "lpy": (lpy, "big.lpy", lpy_toml),
        "lpy bodies": (lpy_bodies, "big.lpy", bodies_toml),
        "cpfg": (cpfg, "big.l", cpfg_toml),
    }


def lparser_pair() -> tuple[str, str]:
    """Single-character rules (Lparser has one rule per symbol): as Lparser writes them, and as TOML."""
    symbols = [chr(c) for c in range(ord("A"), ord("Z") + 1) if chr(c) not in "FZ"]
    rules = [f"{s}=F[+{symbols[(k + 1) % len(symbols)]}]{s}" for k, s in enumerate(symbols)]
    ls = "3\n25\n20\nA\n" + "\n".join(rules) + "\n@\n"
    return ls, toml_text("A", rules, dialect="lparser", iterations=3, angle=25)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller sizes")
    args = parser.parse_args()

    print("Reading: n rules, each notation against the same grammar in TOML (ratio: native / TOML)")
    print(f"{'rules':>6} {'lpy':>14} {'lpy bodies':>14} {'cpfg':>14}")
    for n in (25, 50, 100) if args.quick else (30, 60, 120):
        cells = []
        for native, source, toml in pairs(n).values():
            t_native = t_toml = float("inf")
            for _ in range(3):  # alternated, so that neither gets a warmer machine
                t, _ = best_of(lambda native=native, source=source: lsys3d.Grammar.from_text(native, source=source), 1)
                t_native = min(t_native, t)
                t, _ = best_of(lambda toml=toml: lsys3d.Grammar.from_text(toml, source="big.toml"), 1)
                t_toml = min(t_toml, t)
            cells.append(f"{t_native * 1e3:6.1f}ms {t_native / t_toml:4.2f}x")
        print(f"{n:>6} " + " ".join(f"{c:>14}" for c in cells))
    ls, toml = lparser_pair()
    t_ls, _ = best_of(lambda: lsys3d.Grammar.from_text(ls, source="big.ls"), repeat=5)
    t_toml, _ = best_of(lambda: lsys3d.Grammar.from_text(toml, source="big.toml"), repeat=5)
    print(f"Lparser, 24 rules: {t_ls * 1e3:.2f} ms, {t_ls / t_toml:.2f}x the same rules in TOML")

    print()
    print("Deriving the corpus's largest models: native file against the same rules in TOML")
    print(f"{'model':<28} {'n':>3} {'modules':>10} {'native s':>9} {'toml s':>8} {'ratio':>7}")
    cases = [
        ("cpfg/plant_1_24d.l", 9 if args.quick else 10),
        ("cpfg/monopodial.l", 14 if args.quick else 16),
        ("cpfg/signal_131a.l", 30),
        ("lpy/binary_tree.lpy", 14 if args.quick else 16),
        ("lparser/fractal_e.ls", 9 if args.quick else 10),
    ]
    for name, n in cases:
        native = lsys3d.Grammar.from_file(CORPUS / name)
        same = lsys3d.Grammar(
            axiom=native.axiom,
            rules=[p.text for p in native.productions],
            defines=native.defines,
            ignore=native.ignore,
            dialect=native.dialect,
            modules=native.modules,
        )
        t_native = t_toml = float("inf")
        for _ in range(3):  # alternated, so that neither gets a warmer machine
            t, a = best_of(lambda g=native, n=n: lsys3d.derive(g, n, max_modules=10**9), repeat=1)
            t_native = min(t_native, t)
            t, b = best_of(lambda g=same, n=n: lsys3d.derive(g, n, max_modules=10**9), repeat=1)
            t_toml = min(t_toml, t)
        assert str(a) == str(b) if len(a) < 10**6 else len(a) == len(b)
        print(f"{name:<28} {n:>3} {len(a):>10,} {t_native:>9.3f} {t_toml:>8.3f} {t_native / t_toml:>6.2f}x")


if __name__ == "__main__":
    main()
