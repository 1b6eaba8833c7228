"""Derivation speed against plain-Python rewriters measured in the same run.

    python benchmarks/bench_derive.py [--quick]

Prints modules per second for lsys3d and for two baselines:

* D0L (ABOP figure 1.24f, 9 to 11 generations): ``str.translate`` with a
  table of successors, the fastest pure-string rewriter in Python.
* Parametric (ABOP figure 2.6 monopodial tree): a per-module Python rewriter
  with the rules written as Python lambdas (no parsing cost at all).
* Context (``B < A -> AA`` with ``A`` in the ignore set, the string ``B[AAA...]``):
  the textbook per-module walk of ABOP section 1.8, whose walks here cross the
  whole branch (quadratic), against lsys3d's skip tables (linear).
"""

from __future__ import annotations

import argparse

from timing import best_of

import lsys3d


def translate_rewriter(axiom: str, rules: dict[str, str], n: int) -> str:
    table = str.maketrans(rules)
    s = axiom
    for _ in range(n):
        s = s.translate(table)
    return s


def monopodial_python(n: int):
    r1, r2, a0, a2, d, wr = 0.9, 0.6, 45.0, 45.0, 137.5, 0.707
    rules = {
        "A": lambda l, w: [
            ("!", (w,)),
            ("F", (l,)),
            ("[", ()),
            ("&", (a0,)),
            ("B", (l * r2, w * wr)),
            ("]", ()),
            ("/", (d,)),
            ("A", (l * r1, w * wr)),
        ],
        "B": lambda l, w: [
            ("!", (w,)),
            ("F", (l,)),
            ("[", ()),
            ("-", (a2,)),
            ("$", ()),
            ("C", (l * r2, w * wr)),
            ("]", ()),
            ("C", (l * r1, w * wr)),
        ],
        "C": lambda l, w: [
            ("!", (w,)),
            ("F", (l,)),
            ("[", ()),
            ("+", (a2,)),
            ("$", ()),
            ("B", (l * r2, w * wr)),
            ("]", ()),
            ("B", (l * r1, w * wr)),
        ],
    }
    s = [("A", (1.0, 0.15))]
    for _ in range(n):
        out = []
        for sym, args in s:
            rule = rules.get(sym)
            if rule is None:
                out.append((sym, args))
            else:
                out.extend(rule(*args))
        s = out
    return s


def context_textbook(axiom: str, n: int) -> str:
    """``B < A -> AA``, ``A`` ignored: each module walks left over ignored symbols and brackets to find B."""
    s = axiom
    for _ in range(n):
        out = []
        for i, c in enumerate(s):
            j = i - 1
            while j >= 0 and s[j] in "A[":  # A is ignored, '[' steps out to the parent
                j -= 1
            out.append("AA" if c == "A" and j >= 0 and s[j] == "B" else c)
        s = "".join(out)
    return s


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller sizes (the large context string at 18, not 24)")
    args = parser.parse_args()

    print("D0L: ABOP figure 1.24f (X -> F-[[X]+X]+F[+FX]-X, F -> FF)")
    print(f"{'n':>3} {'modules':>12} {'lsys3d Mmod/s':>14} {'translate Mmod/s':>17} {'ratio':>7}")
    g = lsys3d.load_preset("abop-1.24f")
    rules = {p.predecessor.symbol: "".join(m.symbol for m in p.successor) for p in g.productions}
    for n in (7, 8, 9) if args.quick else (9, 10, 11):
        t_ours, ours = best_of(lambda n=n: lsys3d.derive(g, n, max_modules=10**9))
        t_base, base = best_of(lambda n=n: translate_rewriter(g.axiom, rules, n))
        assert ours.symbol_text() == base
        m = len(ours)
        print(f"{n:>3} {m:>12,} {m / t_ours / 1e6:>14.1f} {m / t_base / 1e6:>17.1f} {t_base / t_ours:>6.1f}x")

    print()
    print("Parametric: ABOP figure 2.6 monopodial tree")
    print(f"{'n':>3} {'modules':>12} {'lsys3d Mmod/s':>14} {'python Mmod/s':>14} {'ratio':>7}")
    g = lsys3d.load_preset("monopodial")
    for n in (12, 14) if args.quick else (14, 16, 18):
        t_ours, ours = best_of(lambda n=n: lsys3d.derive(g, n, max_modules=10**9), repeat=2)
        t_base, base = best_of(lambda n=n: monopodial_python(n), repeat=1)
        assert len(ours) == len(base)
        m = len(ours)
        print(f"{n:>3} {m:>12,} {m / t_ours / 1e6:>14.2f} {m / t_base / 1e6:>14.2f} {t_base / t_ours:>6.1f}x")

    print()
    print("Context: B < A -> AA with A ignored (every walk crosses the branch)")
    print(f"{'n':>3} {'modules':>12} {'lsys3d Mmod/s':>14} {'textbook Mmod/s':>16} {'ratio':>7}")
    g = lsys3d.Grammar(axiom="B[A]", rules=["B < A -> AA", "A -> A"], ignore="A")
    for n in (9, 11) if args.quick else (10, 12, 13):
        t_ours, ours = best_of(lambda n=n: lsys3d.derive(g, n), repeat=2)
        t_base, base = best_of(lambda n=n: context_textbook(g.axiom, n), repeat=1)
        assert str(ours) == base
        m = len(ours)
        print(f"{n:>3} {m:>12,} {m / t_ours / 1e6:>14.2f} {m / t_base / 1e6:>16.3f} {t_base / t_ours:>6.0f}x")
    big_n = 18 if args.quick else 24  # 24: 16.8 million modules, most of a quick run's time (its memory)
    t_big, big = best_of(lambda: lsys3d.derive(g, big_n), repeat=1)
    print(f"{big_n:>3} {len(big):>12,} {len(big) / t_big / 1e6:>14.2f} {'(textbook: hours)':>16}")


if __name__ == "__main__":
    main()
