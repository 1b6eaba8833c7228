"""Regenerate docs/gallery.md and its pictures in docs/gallery/: one per bundled preset.

Run it with ``make gallery``, or::

    LSYS3D_BLENDER=.venv-bpy/bin/python .venv/bin/python docs/make_gallery.py [PRESET ...]

Flat presets (the 2D curves and plants) become SVG line drawings of their
skeleton (:mod:`lsys3d.exchange.svg`); 3D ones are rendered by Blender
(:func:`lsys3d.preview`) as small PNGs; symbol-only grammars, which draw
nothing, show their derived strings.  Naming presets renders only those
pictures; the page is always rewritten whole.
"""

from __future__ import annotations

import argparse
import re
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

import lsys3d
from lsys3d.lsystem.presets import describe, preset_text
from lsys3d.render.preview import PreviewOptions, preview

DOCS = Path(__file__).resolve().parent
PICTURES = DOCS / "gallery"
PAGE = DOCS / "gallery.md"
PIXELS = 360  # small pictures keep the repository small
THUMBNAIL = 120  # the overview at the top of the page
SAMPLES = 16
VIEWS = {"hilbert3d": "iso", "bush": "iso"}  # the others from the front
DERIVED_SHOWN = 200  # characters of a derived string shown for symbol-only grammars


def is_flat(skeleton) -> bool:
    """Whether everything the turtle drew lies in one coordinate plane (and no leaf model stands out of it)."""
    points = [skeleton.start, skeleton.end, skeleton.polygon_points]
    if len(skeleton.leaf_position):
        return False
    pts = np.concatenate(points)
    extent = np.ptp(pts, axis=0)
    return bool(extent.min() <= 1e-9 * extent.max())


def picture(name: str, render: bool) -> tuple[str | None, str]:
    """Make the picture of one preset (when ``render``); its file name (None: draws nothing) and a caption."""
    grammar = lsys3d.load_preset(name)
    modules = lsys3d.derive(grammar)
    skeleton = lsys3d.interpret(modules, grammar, seed=grammar.seed)
    if len(skeleton) == 0 and skeleton.n_leaves == 0:
        return None, f"{len(modules):,} modules after {grammar.iterations} iterations; it draws nothing"
    counts = f"{len(skeleton):,} segments, {skeleton.n_leaves:,} leaves after {grammar.iterations} iterations"
    if is_flat(skeleton):
        target = PICTURES / f"{name}.svg"
        if render:
            lsys3d.export(lsys3d.generate(grammar, union=False), target)
        return target.name, f"{counts}; the skeleton drawn as SVG"
    view = VIEWS.get(name, "front")
    target = PICTURES / f"{name}.png"
    if render:
        tree = lsys3d.generate(grammar)
        preview(tree, target, PreviewOptions(size=(PIXELS, PIXELS), view=view, samples=SAMPLES, quality="final"))
    return target.name, f"{counts}; rendered by Blender (Cycles), {view} view"


def slug(title: str) -> str:
    """The anchor GitHub gives a heading."""
    return re.sub(r"[^\w\- ]", "", title.lower()).replace(" ", "-")


def img(image: str, name: str, pixels: int) -> str:
    """An ``<img>`` sized by its longer side (an SVG's aspect is in its width and height attributes)."""
    side = "width"
    if image.endswith(".svg"):
        root = ET.parse(PICTURES / image).getroot()
        if float(root.get("height")) > float(root.get("width")):
            side = "height"
    return f'<img src="gallery/{image}" alt="{name}" {side}="{pixels}">'


def page(entries: list[tuple[str, str | None, str]]) -> str:
    lines = [
        "# Gallery",
        "",
        "Every bundled preset at its own iteration count and seed: the 3D plants rendered by Blender with",
        "`lsys3d preview` (360x360, 16 samples, denoised), the flat curves and plants as the SVG line drawing",
        "that `lsys3d generate NAME -o NAME.svg` writes. Below each picture, the grammar (`lsys3d/assets/presets/`).",
        "",
        "Regenerate the pictures and this page with `make gallery` (it runs `docs/make_gallery.py`).",
        "",
        "<p>",
        *(
            f'<a href="#{slug(name)}"><img src="gallery/{image}" alt="{name}" height="{THUMBNAIL}"></a>'
            for name, image, _ in entries
            if image
        ),
        "</p>",
        "",
    ]
    for name, image, caption in entries:
        lines += [f"## {name}", "", describe(name), ""]
        if image:
            lines += [img(image, name, PIXELS), ""]
        lines += [f"*{caption}.*", ""]
        lines += ["```toml", preset_text(name).rstrip("\n"), "```", ""]
        if image is None:
            grammar = lsys3d.load_preset(name)
            derived = str(lsys3d.derive(grammar))
            shown = derived if len(derived) <= DERIVED_SHOWN else derived[:DERIVED_SHOWN] + " ..."
            lines += ["Derived:", "", "```text", shown, "```", ""]
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("presets", nargs="*", help="render only these (default: all)")
    args = parser.parse_args(argv)
    names = lsys3d.list_presets()
    unknown = sorted(set(args.presets) - set(names))
    if unknown:
        parser.error(f"unknown presets: {', '.join(unknown)}")
    PICTURES.mkdir(exist_ok=True)
    entries = []
    for name in names:
        render = not args.presets or name in args.presets
        t0 = time.perf_counter()
        image, caption = picture(name, render)
        if render:
            print(f"{name:<16} {image or '-':<22} {time.perf_counter() - t0:5.1f} s", file=sys.stderr)
        entries.append((name, image, caption))
    PAGE.write_text(page(entries), encoding="utf-8")
    total = sum(p.stat().st_size for p in PICTURES.iterdir())
    print(f"wrote {PAGE.relative_to(DOCS.parent)} and {PICTURES.relative_to(DOCS.parent)}/ ({total / 1024:.0f} KiB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
