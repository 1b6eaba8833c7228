"""Botanical form of grown skeletons: pipe model, taper, flare, curvature, leaves, seeds; a report per grammar.

    python benchmarks/bench_botany.py [--presets tree3d ...] [--grammars docs/form/x.toml ...] [--quick]

For each grammar (default: every preset whose grammar has a ``[form]`` table,
tree3d, and the example grammars of ``docs/form/``) prints, from the skeleton
the form stage hands the sweep (:func:`lsys3d.pipeline.draw`):

* ``forks``: segments with two children or more;
* ``area med`` / ``in 0.8-1.25``: the median over forks of the sum of the
  children's ``d**2`` at their start over the parent's ``d**2`` at its end
  (1: the pipe model with exponent 2; a collar raises it by ``collar**2``),
  and the share of forks within 0.8-1.25;
* ``child/parent``: the largest child-start over parent-end width;
* ``growth``: the largest width ratio toward the tip along a chain (inside a
  segment and across its joints; at most 1: never grows);
* ``flare``: the trunk's diameter at the ground over its diameter at 10% of the
  plant's height;
* ``straight5``: chains of five segments or more whose headings all lie within
  0.5 degrees of each other;
* ``sky%``: leaves whose blade normal (a leaf instance's up vector, a leaf
  polygon's Newell normal) lies within 60 degrees of the sky (+Y);
* ``seeds``: distinct skeletons among seeds 0-4;
* ``form ms`` and ``form/interp``: the form stage's time (best of 3), and over the turtle's.

``--with-form`` adds a row per preset grown with the ``[form]`` table of
``docs/form/tree3d-form.toml`` given as options (``name+form``): the same
plant before and after.  ``--quick``: two iterations fewer (and not below 2),
for the test suite's smoke run.
"""

from __future__ import annotations

import argparse
import hashlib
import logging
from pathlib import Path

import numpy as np

import lsys3d
from lsys3d.grammar import Grammar
from lsys3d.pipeline import GenerateOptions, draw
from lsys3d.skeleton import Skeleton

DOCS = Path(__file__).resolve().parent.parent / "docs" / "form"
DEMO = DOCS / "tree3d-form.toml"


def fork_ratios(sk: Skeleton) -> tuple[int, np.ndarray, float]:
    """Number of forks, each fork's children/parent area ratio, and the largest child-start / parent-end width."""
    child = np.flatnonzero(sk.parent >= 0)
    parent = sk.parent[child]
    counts = np.bincount(parent, minlength=len(sk))
    fork = counts >= 2
    area = np.bincount(parent, weights=sk.width_start[child] ** 2, minlength=len(sk))
    ratios = area[fork] / np.maximum(sk.width_end[fork] ** 2, 1e-300)
    widest = float((sk.width_start[child] / np.maximum(sk.width_end[parent], 1e-300)).max()) if len(child) else 0.0
    return int(fork.sum()), ratios, widest


def chain_growth(sk: Skeleton) -> float:
    """The largest width ratio toward the tip along any chain: inside segments and across their joints."""
    inside = sk.width_end / np.maximum(sk.width_start, 1e-300)
    ch = sk.chains
    seg = ch.segments
    same = ch.chain_of[seg[1:]] == ch.chain_of[seg[:-1]]
    joint = sk.width_start[seg[1:]][same] / np.maximum(sk.width_end[seg[:-1]][same], 1e-300)
    return float(max(inside.max(initial=0.0), joint.max(initial=0.0)))


def trunk_flare(sk: Skeleton) -> float:
    """Trunk diameter at the ground over its diameter at 10% of the plant's height (nan without a trunk there)."""
    trunk = np.flatnonzero(sk.order == 0)
    if not len(trunk):
        return float("nan")
    low, high = sk.bounds()[:, 1]
    base = trunk[np.argmin(sk.start[trunk, 1])]
    y = low + 0.1 * (high - low)
    y0, y1 = sk.start[trunk, 1], sk.end[trunk, 1]
    spans = np.flatnonzero((np.minimum(y0, y1) <= y) & (np.maximum(y0, y1) >= y) & (y1 != y0))
    if not len(spans):
        return float("nan")
    s = trunk[spans[0]]
    t = (y - sk.start[s, 1]) / (sk.end[s, 1] - sk.start[s, 1])
    at = sk.width_start[s] + t * (sk.width_end[s] - sk.width_start[s])
    return float(sk.width_start[base] / at)


def straight_chains(sk: Skeleton, min_segments: int = 5, degrees: float = 0.5) -> int:
    """Chains of at least ``min_segments`` segments whose headings all lie within ``degrees`` of the first one."""
    ch = sk.chains
    long = np.flatnonzero(ch.lengths() >= min_segments)
    if not len(long):
        return 0
    seg = ch.segments
    first = np.repeat(seg[ch.offsets[long]], ch.lengths()[long])
    members = np.concatenate([seg[ch.offsets[c] : ch.offsets[c + 1]] for c in long])
    cos = np.einsum("ij,ij->i", sk.heading[members], sk.heading[first])
    bent = cos < np.cos(np.radians(degrees))
    which = np.repeat(np.arange(len(long)), ch.lengths()[long])
    return int(len(long) - np.unique(which[bent]).size)


def sky_share(sk: Skeleton, degrees: float = 60.0) -> float:
    """Percent of leaves whose blade normal is within ``degrees`` of +Y (nan without leaves)."""
    normals = [sk.leaf_up]
    if sk.n_polygons:
        pts, off = sk.polygon_points, sk.polygon_offsets
        poly = np.repeat(np.arange(sk.n_polygons), np.diff(off))
        nxt = np.arange(len(pts)) + 1
        nxt[off[1:] - 1] = off[:-1]
        newell = np.zeros((sk.n_polygons, 3))
        np.add.at(newell, poly, np.cross(pts, pts[nxt]))
        normals.append(newell / np.maximum(np.linalg.norm(newell, axis=1, keepdims=True), 1e-300))
    n = np.concatenate(normals)
    if not len(n):
        return float("nan")
    return float(100.0 * np.mean(n[:, 1] >= np.cos(np.radians(degrees))))


def digest(sk: Skeleton) -> str:
    h = hashlib.sha256()
    for a in (sk.start, sk.end, sk.width_start, sk.width_end, sk.leaf_position):
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


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


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--presets", nargs="*", default=None, help="presets (default: those with [form], and tree3d)")
    ap.add_argument("--grammars", nargs="*", default=None, help="grammar files (default: docs/form/*.toml)")
    ap.add_argument("--with-form", action="store_true", help="also each preset with the demo's [form] as options")
    ap.add_argument("--quick", action="store_true", help="two iterations fewer: a smoke run")
    args = ap.parse_args(argv)
    logging.getLogger("lsys3d").setLevel(logging.WARNING)
    grammars: list[tuple[str, Grammar, GenerateOptions]] = []
    names = args.presets
    if names is None:
        names = [n for n in lsys3d.list_presets() if lsys3d.load_preset(n).form] + ["tree3d"]
    plain, formed = GenerateOptions(), GenerateOptions.from_flat(**Grammar.from_file(DEMO).form)
    for name in dict.fromkeys(names):
        grammars.append((name, lsys3d.load_preset(name), plain))
        if args.with_form:
            grammars.append((name + "+form", lsys3d.load_preset(name), formed))
    files = args.grammars if args.grammars is not None else sorted(str(p) for p in DOCS.glob("*.toml"))
    grammars += [(Path(p).stem, Grammar.from_file(p), plain) for p in files]
    print(
        f"{'grammar':>16} {'iter':>4} {'segments':>8} {'forks':>6} {'area med':>8} {'in 0.8-1.25':>11} "
        f"{'child/parent':>12} {'growth':>7} {'flare':>6} {'straight5':>9} {'sky%':>6} {'seeds':>5} "
        f"{'form ms':>7} {'form/interp':>11}"
    )
    for name, g, options in grammars:
        n = max(2, g.iterations - 2) if args.quick else g.iterations
        _, sk = draw(g, n, g.seed, options)
        forks, ratios, widest = fork_ratios(sk)
        within = 100.0 * np.mean((ratios >= 0.8) & (ratios <= 1.25)) if len(ratios) else float("nan")
        median = float(np.median(ratios)) if len(ratios) else float("nan")
        seeds = len({digest(draw(g, n, seed, options)[1]) for seed in range(5)})
        t_interp, t_form = timed(g, n, options)
        ratio = f"{t_form / t_interp:.1f}" if t_form else "-"
        ms = f"{1e3 * t_form:.1f}" if t_form else "-"
        print(
            f"{name:>16} {n:>4} {len(sk):>8,} {forks:>6,} {median:>8.3f} {within:>10.1f}% "
            f"{widest:>12.3f} {chain_growth(sk):>7.3f} {trunk_flare(sk):>6.2f} {straight_chains(sk):>9,} "
            f"{sky_share(sk):>6.1f} {seeds:>5} {ms:>7} {ratio:>11}",
            flush=True,
        )


if __name__ == "__main__":
    main()
