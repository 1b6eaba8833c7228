"""Botanical form of grown skeletons: pipe model, taper, flare, curvature, leaves, seeds; a row per species.

    python benchmarks/bench_botany.py [--presets oak pine ...] [--grammars docs/form/x.toml ...] [--check] [--quick]

For each grammar (default: every preset of the group ``species``; ``--presets``
and ``--grammars`` name others, e.g. tree3d and ``docs/form/*.toml``) prints,
from the skeleton the form stage hands the sweep (:func:`lsys3d.pipeline.draw`),
the measures of :mod:`lsys3d.turtle.botany` (their one home, which the tests use too):

* ``forks``: segments with two children or more;
* ``area med`` / ``in 0.8-1.25``: the median over forks of the sum of the
  children's ``d**2`` where they leave the parent over the parent's ``d**2`` at
  its end (1: the pipe model with exponent 2), and the share of forks within
  0.8-1.25.  A lateral's branch collar is measured at its end, where it has
  faded into the branch's own width; ``raw med`` is the median at the
  children's very start, collar included (it is higher by ``branch_collar**2``);
* ``child/parent``: the largest child-start over parent-end width (collars included);
* ``growth``: the largest width ratio toward the tip along a chain (inside a
  segment and across its joints; at most 1: never grows);
* ``base d``: the trunk's diameter at the ground, metres;
* ``flare``: the trunk's diameter at the ground over its diameter at 10% of the
  plant's height;
* ``straight5``: chains of five segments or more whose headings all lie within
  0.5 degrees of each other;
* ``sky%``: blades whose normal lies within 60 degrees of the sky (+Y), as the
  leaf stage places them (``[leaves]``: clusters, light, cards; :func:`lsys3d.look.leaf_form.arrange`);
* ``seeds``: distinct skeletons among seeds 0-4;
* ``goals``: PASS or FAIL per goal of :data:`lsys3d.turtle.botany.GOALS`
  (pipe, child, growth, flare on trees, curved and leaves on broadleaves, seeds), ``-``
  where a goal does not apply.

``--check`` exits with status 1 when a goal fails.  ``--with-form`` adds a row
per preset grown with the ``[form]`` table of ``docs/form/tree3d-form.toml``
given as options (``name+form``).  ``--quick``: two iterations fewer (and not
below 2) and no timing, for the test suite's smoke run.  ``--times`` adds the
form stage's time (best of 3) and its ratio to the turtle's.
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

import lsys3d
from lsys3d.look.leaf_form import arrange
from lsys3d.look.leaves import LeafOptions
from lsys3d.lsystem.grammar import Grammar
from lsys3d.lsystem.presets import preset_info
from lsys3d.pipeline import GenerateOptions, draw
from lsys3d.turtle.botany import GOALS, measure, verdicts
from lsys3d.turtle.form import FormOptions

DOCS = Path(__file__).resolve().parent.parent / "docs" / "form"
DEMO = DOCS / "tree3d-form.toml"


def timed(grammar: Grammar, n: int, options: GenerateOptions) -> tuple[float, float]:
    """Best of 3 of the turtle's and the form stage's seconds."""
    best = {"interpret": float("inf"), "form": float("inf")}
    for _ in range(3):
        seen = {}

        def progress(stage, event, seconds, seen=seen):
            if event == "done":
                seen[stage] = seconds

        draw(grammar, n, grammar.seed, options, progress=progress)
        for k in best:
            best[k] = min(best[k], seen.get(k, 0.0))
    return best["interpret"], best["form"]


def species() -> list[str]:
    """The presets of the group ``species``."""
    return [n for n in lsys3d.list_presets() if preset_info(n).group == "species"]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--presets", nargs="*", default=None, help="presets (default: every species)")
    ap.add_argument("--grammars", nargs="*", default=[], help="grammar files, e.g. docs/form/*.toml")
    ap.add_argument("--with-form", action="store_true", help="also each preset with the demo's [form] as options")
    ap.add_argument("--check", action="store_true", help="exit with status 1 when a goal fails")
    ap.add_argument("--times", action="store_true", help="also time the form stage (best of 3)")
    ap.add_argument("--quick", action="store_true", help="two iterations fewer: a smoke run")
    args = ap.parse_args(argv)
    logging.getLogger("lsys3d").setLevel(logging.WARNING)
    grammars: list[tuple[str, Grammar, GenerateOptions]] = []
    names = species() if args.presets is None else args.presets
    plain = GenerateOptions()
    formed = GenerateOptions.from_flat(**Grammar.from_file(DEMO).form) if args.with_form else plain
    for name in dict.fromkeys(names):
        grammars.append((name, lsys3d.load_preset(name), plain))
        if args.with_form:
            grammars.append((name + "+form", lsys3d.load_preset(name), formed))
    grammars += [(Path(p).stem, Grammar.from_file(p), plain) for p in args.grammars]
    goals = list(GOALS)
    print(
        f"{'grammar':>16} {'iter':>4} {'segments':>8} {'forks':>6} {'area med':>8} {'raw med':>7} "
        f"{'in 0.8-1.25':>11} {'child/parent':>12} {'growth':>7} {'base d':>6} {'flare':>6} {'straight5':>9} "
        f"{'sky%':>6} {'seeds':>5} "
        + " ".join(f"{g:>6}" for g in goals)
        + (" form ms form/interp" if args.times else "")
    )
    failed = []
    for name, g, options in grammars:
        n = max(2, g.iterations - 2) if args.quick else g.iterations
        _, sk = draw(g, n, g.seed, options)
        collar = FormOptions.from_grammar(g, options.form).branch_collar
        blades = arrange(sk, LeafOptions.from_grammar(g, options.leaves), g.seed)
        m = measure(sk, [draw(g, n, seed, options)[1] for seed in range(5)], collar, blades)
        verdict = verdicts(name, m)
        marks = " ".join(f"{'-' if v is None else 'PASS' if v else 'FAIL':>6}" for v in verdict.values())
        failed += [f"{name}: {goal}" for goal, v in verdict.items() if v is False]
        timing = ""
        if args.times:
            t_interp, t_form = timed(g, n, options)
            timing = f" {1e3 * t_form:>7.1f} {t_form / t_interp:>11.1f}" if t_form else f" {'-':>7} {'-':>11}"
        print(
            f"{name:>16} {n:>4} {m.segments:>8,} {m.forks:>6,} {m.area_median:>8.3f} {m.raw_area_median:>7.3f} "
            f"{m.within:>10.1f}% {m.child_parent:>12.3f} {m.growth:>7.3f} {m.trunk_base_diameter:>6.3f} "
            f"{m.flare:>6.2f} {m.straight5:>9,} {m.sky:>6.1f} {m.seeds:>5} {marks}{timing}",
            flush=True,
        )
    if failed:
        print("failed goals: " + "; ".join(failed))
    return 1 if args.check and failed else 0


if __name__ == "__main__":
    sys.exit(main())
