"""Census of grammar files: segments drawn and the share shorter than their width.

    python benchmarks/dense_census.py FILE... [--min-segments 20000] [--more 1] [--seconds 60]

For each file as it is (its own iterations): the number of segments the turtle
draws and the share of them whose length is below their width (the larger of
``width_start`` and ``width_end``), the mark of a dense grammar whose union is
hard (issue 34).  Files that fail to read or draw are listed with their error.
"""

from __future__ import annotations

import argparse
import logging
import signal
import sys
from pathlib import Path

import numpy as np


def census(path: Path, more: int = 0) -> tuple[int, float, float]:
    """Segments drawn by ``path`` (``more`` generations past its own), the share shorter than wide, median l/w."""
    import lsys3d
    from lsys3d.pipeline import draw

    g = lsys3d.load(path)
    _, sk = draw(g, g.iterations + more, g.seed)
    if len(sk) == 0:
        return 0, 0.0, 0.0
    length = np.linalg.norm(sk.end - sk.start, axis=1)
    width = np.maximum(sk.width_start, sk.width_end)
    return len(sk), float(np.mean(length < width)), float(np.median(length / np.maximum(width, 1e-300)))


def _timeout(signum, frame):
    raise TimeoutError("over the time limit")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="+", type=Path)
    ap.add_argument("--min-segments", type=int, default=0, help="list only files drawing at least this many")
    ap.add_argument("--seconds", type=int, default=60, help="time limit per file")
    ap.add_argument("--more", type=int, default=0, help="derive this many generations past the file's own")
    args = ap.parse_args(argv)
    logging.disable(logging.WARNING)
    signal.signal(signal.SIGALRM, _timeout)
    print(f"{'file':<60} {'segments':>9} {'short':>7} {'median l/w':>10}")
    for f in args.files:
        signal.alarm(args.seconds)
        try:
            n, short, ratio = census(f, args.more)
        except Exception as exc:  # a census lists every failure and goes on
            print(f"{f!s:<60} {type(exc).__name__}: {str(exc)[:60]}", file=sys.stderr)
            continue
        finally:
            signal.alarm(0)
        if n >= args.min_segments:
            print(f"{f!s:<60} {n:>9,} {short:>7.1%} {ratio:>10.3f}", flush=True)


if __name__ == "__main__":
    main()
