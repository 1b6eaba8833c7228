"""SVG line drawings: valid XML, every segment drawn where the skeleton has it, fitted, deterministic."""

from __future__ import annotations

import subprocess
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from skeletons import make_skeleton

import lsys3d
from lsys3d.errors import ExportError
from lsys3d.exchange import SUPPORTED_SUFFIXES, ExportOptions, export
from lsys3d.exchange.svg import DISPLAY_PIXELS, MARGIN, drawing_plane, svg_text
from lsys3d.tree import Tree

NS = "{http://www.w3.org/2000/svg}"
FLAT = [("koch", 3), ("snowflake", 2), ("dragon", 6), ("plant", 3), ("abop-1.24d", 3), ("koch-stochastic", 3)]


def grow(name, n):
    return lsys3d.generate(name, iterations=n, union=False)


def parse(text: str):
    root = ET.fromstring(text.encode("utf-8"))
    assert root.tag == f"{NS}svg"
    return root


def numbers(text: str) -> np.ndarray:
    return np.array([float(v) for v in text.replace(",", " ").split()])


def polylines(root) -> list[tuple[float, np.ndarray]]:
    """(stroke width, points (m, 2)) of every polyline."""
    out = []
    for line in root.iter(f"{NS}polyline"):
        out.append((float(line.get("stroke-width")), numbers(line.get("points")).reshape(-1, 2)))
    return out


def drawn_segments(root) -> np.ndarray:
    """Every drawn segment as (x0, y0, x1, y1), in SVG coordinates."""
    pairs = [np.hstack([pts[:-1], pts[1:]]) for _, pts in polylines(root)]
    return np.vstack(pairs) if pairs else np.zeros((0, 4))


def sort_rows(a: np.ndarray) -> np.ndarray:
    return a[np.lexsort(a.T[::-1])]


@pytest.mark.parametrize("name, n", FLAT, ids=[f[0] for f in FLAT])
def test_flat_drawing_is_the_skeleton_in_xy(name, n):
    tree = grow(name, n)
    sk = tree.skeleton
    root = parse(svg_text(tree))
    segments = drawn_segments(root)
    assert len(segments) == len(sk)  # one drawn segment per skeleton segment
    # the same segments chain by chain, in the XY plane with y flipped, to the written precision
    order = sk.chains.segments
    expected = np.hstack([sk.start[order, :2], sk.end[order, :2]]) * [1, -1, 1, -1]
    size = np.ptp(np.vstack([sk.start, sk.end]), axis=0).max()
    np.testing.assert_allclose(segments, expected, atol=1e-4 * size)

    # the viewBox is the drawing's box plus the margin and half the widest stroke, and holds every point
    x0, y0, w, h = numbers(root.get("viewBox"))
    pts = segments.reshape(-1, 2)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    margin = 0.03 * size + 0.5 * max(sk.width_start.max(), sk.width_end.max())
    np.testing.assert_allclose([x0, y0, w, h], [*(lo - margin), *(hi - lo + 2 * margin)], atol=2e-4 * size)
    width, height = float(root.get("width")), float(root.get("height"))
    assert max(width, height) == DISPLAY_PIXELS
    assert width / height == pytest.approx(w / h, rel=2e-3)
    # strokes as wide as the branches
    assert all(s == pytest.approx(sk.width_start[0], rel=1e-6) for s, _ in polylines(root))
    assert root.find(f"{NS}title").text == name


def test_one_polyline_per_chain_when_widths_are_equal():
    tree = grow("koch", 3)
    assert len(polylines(parse(svg_text(tree)))) == len(tree.skeleton.chains) == 1


def test_same_bytes_every_time(tmp_path):
    a = export(grow("abop-1.24d", 3), tmp_path / "a.svg").read_bytes()
    b = export(grow("abop-1.24d", 3), tmp_path / "b.svg").read_bytes()
    assert a == b
    assert b"-0," not in a and b"-0 " not in a and b'-0"' not in a  # no negative zeros
    assert ".svg" in SUPPORTED_SUFFIXES


def test_a_3d_tree_stands_up_with_its_leaves():
    tree = grow("tree3d", 3)
    sk = tree.skeleton
    root = parse(svg_text(tree))
    segments = drawn_segments(root)
    assert len(segments) == len(sk)
    # projected on XY (Y up): the trunk's base is the lowest point on the page (largest SVG y)
    base = sk.start[0]
    assert segments[:, [1, 3]].max() == pytest.approx(-base[1], abs=1e-3)
    # tapering branches: several widths, the trunk's the widest
    widths = [s for s, _ in polylines(root)]
    assert len(set(widths)) > 1 and widths[0] == max(widths)
    leaves = list(root.iter(f"{NS}path"))
    assert len(leaves) == len(tree.leaves.transforms) > 0
    assert all(p.get("d").startswith("M") and p.get("d").endswith("Z") for p in leaves)


def test_polygon_leaves_are_filled_polygons():
    tree = grow("bush", 2)
    root = parse(svg_text(tree))
    polygons = list(root.iter(f"{NS}polygon"))
    assert len(polygons) == tree.skeleton.n_polygons > 0
    group = next(g for g in root.iter(f"{NS}g") if g.find(f"{NS}polygon") is not None)
    assert group.get("fill") == "#76b359"  # the leaf material's linear (0.18, 0.45, 0.10) in sRGB


def test_hairline_strokes_are_one_pixel():
    root = parse(svg_text(grow("tree3d", 3), ExportOptions(hairline=True)))
    _, _, w, h = numbers(root.get("viewBox"))
    widths = {s for s, _ in polylines(root)}
    assert len(widths) == 1
    # one pixel at the drawing's natural size: the viewBox is the drawing (size) with a margin of
    # MARGIN * size + half a stroke on each side, so max(w, h) = (1 + 2 MARGIN) size + hairline
    hairline = max(w, h) / ((1 + 2 * MARGIN) * DISPLAY_PIXELS + 1)
    assert widths.pop() == pytest.approx(hairline, rel=2e-3)


def test_drawing_plane_rules():
    x, y, z = np.eye(3)

    def plane(points):
        right, up = drawing_plane(np.array(points, float))
        return right.tolist(), up.tolist()

    assert plane([[0, 0, 0], [3, 1, 0]]) == (x.tolist(), y.tolist())  # flat in z
    assert plane([[0, 0, 0], [0, 1, 3]]) == ((-z).tolist(), y.tolist())  # flat in x: seen from +x
    assert plane([[0, 0, 0], [3, 0, 1]]) == (x.tolist(), (-z).tolist())  # flat in y: seen from above
    assert plane([[0, 0, 0], [1, 2, 3]]) == ((-z).tolist(), y.tolist())  # 3D, deeper than wide: y stays up
    assert plane([[0, 0, 0], [3, 2, 1]]) == (x.tolist(), y.tolist())


def test_a_drawing_in_the_yz_plane_is_seen_from_the_side():
    sk = make_skeleton([[0, 0, 0], [0, 1, 0]], [[0, 1, 0], [0, 1, 2]], 0.1)
    tree = Tree(bark=grow("koch", 1).bark, skeleton=sk)
    root = parse(svg_text(tree))
    np.testing.assert_allclose(sort_rows(drawn_segments(root)), sort_rows(np.array([[0, 0, 0, -1], [0, -1, -2, -1]])))


def test_nothing_to_draw_is_an_error(tmp_path):
    empty = make_skeleton(np.zeros((0, 3)), np.zeros((0, 3)), 0.1)
    tree = Tree(bark=grow("koch", 1).bark, skeleton=empty)
    with pytest.raises(ExportError, match=r"empty\.svg: nothing to draw"):
        export(tree, tmp_path / "empty.svg")
    assert list(tmp_path.iterdir()) == []


def test_cli_generate_koch_svg(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "lsys3d", "generate", "koch", "-o", "koch.svg"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("wrote koch.svg: 256 segments, 0 leaves")
    root = parse((tmp_path / "koch.svg").read_text(encoding="utf-8"))
    assert len(drawn_segments(root)) == 256
    assert sorted(p.name for p in tmp_path.iterdir()) == ["koch.svg"]


def test_centimetres_scale_the_drawing_and_the_up_axis_does_not_turn_it():
    tree = grow("koch", 2)
    metres = numbers(parse(svg_text(tree)).get("viewBox"))
    cm = numbers(parse(svg_text(tree, ExportOptions(units="cm", up_axis="Z"))).get("viewBox"))
    np.testing.assert_allclose(cm, metres * 100, rtol=1e-3)
