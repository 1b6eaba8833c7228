"""Turtle throughput: the numba interpreter against a plain Python loop, same process.

Run with ``python benchmarks/bench_turtle.py [-n 9]``.  Figure 1.24f derived
9 times is about 1.6 million modules.  The JIT compile (or cache load) of the
kernel is measured on a warm-up call and excluded from the rates.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
from timing import best_of

from lsys3d import derive, load_preset
from lsys3d.turtle import TurtleOptions, interpret


def python_turtle(text: str, angle_deg: float, heading_deg: float = 90.0, step: float = 1.0):
    """A straightforward per-module turtle: F f + - & ^ \\ / | [ ], frames as Python floats."""
    a = math.radians(angle_deg)
    ca, sa = math.cos(a), math.sin(a)
    h0 = math.radians(heading_deg)
    pos = (0.0, 0.0, 0.0)
    hx, hy, hz = math.cos(h0), math.sin(h0), 0.0
    lx, ly, lz = -hy, hx, 0.0
    ux, uy, uz = 0.0, 0.0, 1.0
    last = -1
    stack = []
    starts, ends, parents = [], [], []
    for ch in text:
        if ch == "F" or ch == "f":
            end = (pos[0] + hx * step, pos[1] + hy * step, pos[2] + hz * step)
            if ch == "F":
                starts.append(pos)
                ends.append(end)
                parents.append(last)
                last = len(starts) - 1
            else:
                last = -1
            pos = end
        elif ch == "+" or ch == "-":
            s = sa if ch == "+" else -sa
            hx, hy, hz, lx, ly, lz = (
                hx * ca + lx * s,
                hy * ca + ly * s,
                hz * ca + lz * s,
                lx * ca - hx * s,
                ly * ca - hy * s,
                lz * ca - hz * s,
            )
        elif ch == "&" or ch == "^":
            s = sa if ch == "^" else -sa
            hx, hy, hz, ux, uy, uz = (
                hx * ca + ux * s,
                hy * ca + uy * s,
                hz * ca + uz * s,
                ux * ca - hx * s,
                uy * ca - hy * s,
                uz * ca - hz * s,
            )
        elif ch == "/" or ch == "\\":
            s = sa if ch == "/" else -sa
            lx, ly, lz, ux, uy, uz = (
                lx * ca + ux * s,
                ly * ca + uy * s,
                lz * ca + uz * s,
                ux * ca - lx * s,
                uy * ca - ly * s,
                uz * ca - lz * s,
            )
        elif ch == "|":
            hx, hy, hz, lx, ly, lz = -hx, -hy, -hz, -lx, -ly, -lz
        elif ch == "[":
            stack.append((pos, hx, hy, hz, lx, ly, lz, ux, uy, uz, last))
        elif ch == "]":
            pos, hx, hy, hz, lx, ly, lz, ux, uy, uz, last = stack.pop()
    return np.array(starts), np.array(ends), np.array(parents)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-n", "--iterations", type=int, default=9, help="generations of abop-1.24f (default 9)")
    parser.add_argument("--repeat", type=int, default=3, help="timed runs of the numba turtle (best is kept)")
    args = parser.parse_args(argv)

    grammar = load_preset("abop-1.24f")
    options = TurtleOptions.from_grammar(grammar)

    t0 = time.perf_counter()
    interpret(derive(grammar, 1), options)  # compile, or load the cached machine code
    warmup = time.perf_counter() - t0

    modules = derive(grammar, args.iterations)
    m = len(modules)
    text = modules.symbol_text()
    print(f"abop-1.24f n={args.iterations}: {m:,} modules, {modules.count('F'):,} segments")
    print(f"warm-up (JIT compile or cache load): {warmup:.3f} s")

    t_numba, skeleton = best_of(lambda: interpret(modules, options), args.repeat)
    t_python, (starts, ends, parents) = best_of(lambda: python_turtle(text, grammar.angle), 2)

    # same drawing from both: a check that the baseline is a fair one
    assert len(starts) == len(skeleton)
    np.testing.assert_allclose(ends, skeleton.end, atol=1e-6)
    np.testing.assert_array_equal(parents, skeleton.parent)

    rate_numba, rate_python = m / t_numba, m / t_python
    print(f"numba turtle : {t_numba:8.3f} s  {rate_numba / 1e6:8.2f} M modules/s")
    print(f"python loop  : {t_python:8.3f} s  {rate_python / 1e6:8.2f} M modules/s")
    print(f"ratio        : {rate_numba / rate_python:8.1f}x (target >= 10x)")


if __name__ == "__main__":
    main()
