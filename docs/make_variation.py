"""Regenerate the pictures of natural variation and procedural bark in docs/variation/.

Run it with Blender's Python available to :func:`lsys3d.preview`::

    LSYS3D_BLENDER=.venv-bpy/bin/python .venv/bin/python docs/make_variation.py [NAME ...]

Every picture is the default tree (``tree3d``, seed 7) with one control turned
on, except the bark close-ups, which show a forked stem.  docs/turtle.md and
docs/mesh.md show them.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import lsys3d
from lsys3d.mesh.sweep import SweepOptions
from lsys3d.pipeline import GenerateOptions
from lsys3d.render.preview import PreviewOptions, preview

PICTURES = Path(__file__).resolve().parent / "variation"
PIXELS = 320  # small pictures keep the repository small
SEED = 7

FORK = lsys3d.Grammar(
    name="fork",
    axiom="!(0.5)F(1.2)[&(35)!(0.3)F(1.4)][/(180)&(30)!(0.25)F(1.2)]!(0.35)F(1.4)",
    seed=SEED,
)
BARK = SweepOptions(sides=64, bark_displacement=0.5, bark_frequency=5.0, bark_octaves=4)

# name: (grammar, generate options, caption)
PICTURES_MADE = {
    "plain": ("tree3d", GenerateOptions(), "tree3d, seed 7: no variation"),
    "angle": ("tree3d", GenerateOptions(turtle={"angle_jitter": 12.0}), "angle_jitter = 12"),
    "length": ("tree3d", GenerateOptions(turtle={"length_jitter": 0.35}), "length_jitter = 0.35"),
    "width": ("tree3d", GenerateOptions(turtle={"width_jitter": 0.6}), "width_jitter = 0.6"),
    "roll": ("tree3d", GenerateOptions(turtle={"branch_roll": 180.0}), "branch_roll = 180"),
    "drop": ("tree3d", GenerateOptions(turtle={"branch_drop": 0.12}), "branch_drop = 0.12"),
    "normal": (
        "tree3d",
        GenerateOptions(turtle={"angle_jitter": 12.0, "jitter_distribution": "normal"}),
        'angle_jitter = 12, jitter_distribution = "normal"',
    ),
    "fork_plain": (FORK, GenerateOptions(sweep=SweepOptions(sides=64)), "a fork, smooth tubes"),
    "fork_bark": (FORK, GenerateOptions(sweep=BARK), "bark_displacement = 0.5 (bark_frequency 5, bark_octaves 4)"),
    "fork_color": (
        FORK,
        GenerateOptions(sweep=BARK).with_flat(bark_color_variation=1.0, bark_color_frequency=8.0),
        "and bark_color_variation = 1 (bark_color_frequency 8)",
    ),
}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="*", help=f"pictures to render (default all: {', '.join(PICTURES_MADE)})")
    args = parser.parse_args(argv)
    PICTURES.mkdir(exist_ok=True)
    for name in args.names or PICTURES_MADE:
        grammar, options, caption = PICTURES_MADE[name]
        t0 = time.perf_counter()
        tree = lsys3d.generate(grammar, seed=SEED, options=options)
        view = "iso" if isinstance(grammar, lsys3d.Grammar) else "front"
        preview(tree, PICTURES / f"{name}.png", PreviewOptions(size=(PIXELS, PIXELS), view=view, quality="final"))
        print(f"{name}.png: {caption} ({time.perf_counter() - t0:.1f} s)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
