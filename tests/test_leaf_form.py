"""Leaf form: blade shapes, petioles, sizes in metres, clusters, blades toward the light, cards, [leaves]."""

from __future__ import annotations

import numpy as np
import pytest
import validators

import lsys3d
from lsys3d.errors import GrammarError, LimitError, OptionsError
from lsys3d.look.leaf_form import PETIOLE_HALF_WIDTH, SHAPES, arrange, blade, droop, spray_card, toward_light
from lsys3d.look.leaves import LeafOptions, default_leaf, leaves
from lsys3d.pipeline import draw
from lsys3d.turtle.skeleton import Skeleton


@pytest.fixture(scope="module")
def tree3d_skeleton() -> Skeleton:
    grammar = lsys3d.load_preset("tree3d")
    return draw(grammar, grammar.iterations, grammar.seed)[1]


def one_twig(leaf_heading=(0.0, 1.0, 0.0), leaf_left=(1.0, 0.0, 0.0)) -> Skeleton:
    """Two segments up the y axis (0 -> 1 -> 2) with a leaf at the top of the second."""
    h, lf = np.array(leaf_heading, float), np.array(leaf_left, float)
    return Skeleton.from_segments(
        [[0, 0, 0], [0, 1, 0]],
        [[0, 1, 0], [0, 2, 0]],
        0.05,
        leaf_position=[[0, 2, 0]],
        leaf_heading=[h],
        leaf_left=[lf],
        leaf_up=[np.cross(h, lf)],
        leaf_size=[0.5],
        leaf_material=np.array([3], np.int32),
        leaf_segment=np.array([1], np.int64),
    )


def sky_share(up: np.ndarray, degrees: float = 60.0) -> float:
    """Share of the blades whose front faces within ``degrees`` of straight up."""
    return float(np.mean(up[:, 1] > np.cos(np.radians(degrees))))


# ---------------------------------------------------------------- shapes


def is_flat_disc(m) -> None:
    """A flat triangulated sheet in the x-z plane facing +y: one disc (V - E + F = 1), no fold, uv in [0, 1]."""
    assert np.all(m.vertices[:, 1] == 0)
    tri = m.vertices[m.faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    assert (cross[:, 1] > 1e-9).all()  # every triangle faces +y and has an area: no fold, no sliver of nothing
    np.testing.assert_allclose(m.normals, np.broadcast_to([0, 1, 0], m.normals.shape))
    edges = np.sort(m.faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    unique_edges, uses = np.unique(edges, axis=0, return_counts=True)
    assert uses.max() <= 2  # a 2-manifold with boundary
    assert len(np.unique(m.faces)) - len(unique_edges) + len(m.faces) == 1  # one disc
    assert m.uv.min() >= 0 and m.uv.max() <= 1


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("points", [1, 7])
def test_each_shape_is_a_flat_disc_with_uv_over_its_box(shape, points):
    m = blade(shape, points)
    is_flat_disc(m)
    assert m.vertices[:, 2].max() == pytest.approx(1.0)  # length 1 along +z, from the attachment point
    assert np.abs(m.vertices).min(axis=0)[2] == pytest.approx(0.0, abs=1e-12)  # the origin is on the blade
    uv = m.uv.reshape(-1, 2)
    np.testing.assert_allclose([uv.min(axis=0), uv.max(axis=0)], [[0, 0], [1, 1]], atol=1e-6)  # the box fills it
    # uv follow the box: u with x, v with z
    corners = m.vertices[m.faces].reshape(-1, 3)
    lo, hi = corners[:, [0, 2]].min(axis=0), corners[:, [0, 2]].max(axis=0)
    np.testing.assert_allclose(uv, (corners[:, [0, 2]] - lo) / (hi - lo), atol=1e-6)


def test_shapes_differ_in_outline():
    widths = {s: float(np.ptp(blade(s).vertices[:, 0])) for s in SHAPES}
    assert widths["needle"] < widths["blade"] < widths["lanceolate"] < widths["default"] < widths["ovate"]
    assert widths["palmate"] > 1.0  # a maple is wider than long
    lobed = blade("lobed")
    # the lobes: the outline goes in and out at least three times a side
    rows = lobed.vertices[lobed.vertices[:, 0] > 0]
    half = rows[np.argsort(rows[:, 2]), 0]
    assert (np.diff(np.sign(np.diff(half))) != 0).sum() >= 5
    assert blade("palmate").vertices[:, 2].min() < 0  # a maple's lower lobes hang below the petiole's notch


def test_default_shape_is_the_original_leaf():
    """The built-in leaf (``default_leaf``, which is ``blade("default")``) keeps its outline: rows of
    half-width ``0.25 sin(pi z)^0.8 / max`` between a base at 0 and a tip at 1, four triangles a row."""
    for points in (1, 7):
        m = default_leaf(points)
        z = np.linspace(0.0, 1.0, points + 2)[1:-1]
        half = np.sin(np.pi * z) ** 0.8
        half *= 0.25 / half.max()
        np.testing.assert_allclose(m.vertices[1:-1:3], np.stack([-half, 0 * z, z], axis=1))
        np.testing.assert_allclose(m.vertices[3:-1:3], np.stack([half, 0 * z, z], axis=1))
        np.testing.assert_array_equal(m.vertices[[0, -1]], [[0, 0, 0], [0, 0, 1]])
        assert len(m.faces) == 4 * points and np.all(m.face_normals[:, 1] > 0)
        np.testing.assert_allclose(m.uv.reshape(-1, 2)[:, 0], m.vertices[m.faces].reshape(-1, 3)[:, 0] / 0.5 + 0.5)


@pytest.mark.parametrize("shape", ["default", "palmate", "needle"])
def test_petiole_is_a_narrow_strip_and_the_blade_sits_on_it(shape):
    bare = blade(shape, 5)
    m = blade(shape, 5, petiole=0.3)
    assert len(m.faces) == len(bare.faces) + 2
    stalk = m.vertices[-4:]
    np.testing.assert_allclose(np.abs(stalk[:, 0]), PETIOLE_HALF_WIDTH)
    np.testing.assert_allclose(sorted(stalk[:, 2]), [0, 0, 0.3, 0.3])
    # the blade, moved up by the stalk
    np.testing.assert_allclose(m.vertices[:-4], bare.vertices + np.array([0, 0, 0.3]))
    assert m.uv.min() >= 0 and m.uv.max() <= 1
    stalk_faces = m.faces[-2:]
    assert (stalk_faces >= len(m.vertices) - 4).all()
    tri = m.vertices[m.faces]
    assert (np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])[:, 1] > 0).all()


def test_petiole_through_the_leaves_stage():
    sk = one_twig()
    out = leaves(sk, options=LeafOptions(petiole_length=0.25, leaf_size=0.1))
    assert out.model.bounds[1, 2] == pytest.approx(1.25)
    # the stalk starts at the leaf's place, the blade 2.5 cm further along the leaf's heading
    placed = out.merged.vertices
    assert placed[:, 1].min() == pytest.approx(2.0) and placed[:, 1].max() == pytest.approx(2.125)


@pytest.mark.parametrize("crossed", [False, True])
def test_spray_card(crossed):
    m = spray_card(0.3, crossed)
    assert len(m.faces) == (4 if crossed else 2)
    assert m.uv.min() == 0 and m.uv.max() == 1
    tri = m.vertices[m.faces]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    np.testing.assert_allclose(normals / np.linalg.norm(normals, axis=1)[:, None], m.normals[:, 0], atol=1e-6)


# ---------------------------------------------------------------- sizes and clusters


def test_leaf_size_in_metres_and_its_variation(tree3d_skeleton):
    sk = tree3d_skeleton
    assert np.all(sk.leaf_size == 0.5)  # the preset's step: 3-4 times a real leaf on an 11 m tree
    same = arrange(sk, LeafOptions(leaf_size=0.12))
    np.testing.assert_array_equal(same.leaf_size, 0.12)
    np.testing.assert_array_equal(same.leaf_position, sk.leaf_position)  # only the size changed
    varied = arrange(sk, LeafOptions(leaf_size=0.12, leaf_size_variation=0.25), seed=4)
    assert varied.leaf_size.min() >= 0.12 * 0.75 and varied.leaf_size.max() <= 0.12 * 1.25
    assert np.ptp(varied.leaf_size) > 0.05 and abs(varied.leaf_size.mean() - 0.12) < 0.005
    out = leaves(sk, options=LeafOptions(leaf_size=0.12, leaf_size_variation=0.25), seed=4)
    # the transforms scale the unit-long blade to each leaf's length: the baked blades are that long
    np.testing.assert_allclose(np.linalg.norm(out.transforms[:, :3, 2], axis=1), varied.leaf_size)


def test_clusters_grow_along_the_end_of_the_twig():
    sk = one_twig()
    out = arrange(sk, LeafOptions(leaves_per_cluster=5, cluster_length=0.4, leaf_size=0.1), seed=1)
    assert len(out.leaf_position) == 5
    np.testing.assert_allclose(out.leaf_position[:, [0, 2]], 0, atol=1e-12)  # on the twig
    np.testing.assert_allclose(out.leaf_position[:, 1], [2.0, 1.9, 1.8, 1.7, 1.6])  # the tip, then back along it
    assert out.leaf_material.tolist() == [3] * 5 and out.leaf_segment.tolist() == [1] * 5
    np.testing.assert_array_equal(out.leaf_heading[0], sk.leaf_heading[0])  # the tip's leaf keeps its frame
    # the others fan cluster_spread (45 +- 15%) off the twig, all around it
    angle = np.degrees(np.arccos(out.leaf_heading[1:, 1]))
    assert (angle > 45 * 0.84).all() and (angle < 45 * 1.16).all()
    azimuth = np.arctan2(out.leaf_heading[1:, 2], out.leaf_heading[1:, 0])
    assert np.ptp(np.unwrap(np.sort(azimuth))) > np.pi
    for name in ("leaf_heading", "leaf_left", "leaf_up"):
        np.testing.assert_allclose(np.linalg.norm(getattr(out, name), axis=1), 1.0)
    np.testing.assert_allclose(np.cross(out.leaf_heading, out.leaf_left), out.leaf_up, atol=1e-12)


def test_a_cluster_longer_than_its_segment_follows_the_parents():
    sk = one_twig()
    out = arrange(sk, LeafOptions(leaves_per_cluster=3, cluster_length=1.5), seed=0)
    np.testing.assert_allclose(out.leaf_position[:, 1], [2.0, 1.25, 0.5])
    out = arrange(sk, LeafOptions(leaves_per_cluster=3, cluster_length=5.0), seed=0)
    assert out.leaf_position[:, 1].min() == 0.0  # no further back than the plant's base


@pytest.mark.parametrize("phyllotaxis", ["alternate", "opposite"])
def test_phyllotaxis(phyllotaxis):
    sk = one_twig()
    out = arrange(sk, LeafOptions(leaves_per_cluster=5, cluster_phyllotaxis=phyllotaxis, leaf_size=0.1), seed=2)
    y = out.leaf_position[:, 1].round(9)
    radial = out.leaf_heading[1:, [0, 2]]
    if phyllotaxis == "opposite":
        assert len(set(y[1:])) == 2  # two pairs, each at one node
        assert np.dot(radial[0], radial[1]) < -0.9 * np.linalg.norm(radial[0]) * np.linalg.norm(radial[1])
    else:
        assert len(set(y)) == 5
        assert np.dot(radial[0], radial[1]) < 0  # half a turn (and a little jitter) apart


def test_cluster_counts_on_tree3d(tree3d_skeleton):
    sk = tree3d_skeleton
    k = len(sk.leaf_position)
    out = leaves(sk, options=LeafOptions(leaves_per_cluster=6, leaf_size=0.1, leaf_points=2), seed=0)
    assert len(out.transforms) == 6 * k and len(out.merged.faces) == 6 * k * 8
    assert out.instance_material.tolist() == np.repeat(sk.leaf_material, 6).tolist()
    with pytest.raises(LimitError, match="leaves: 4,374 leaves of 8 triangles"):
        leaves(sk, options=LeafOptions(leaves_per_cluster=6, leaf_points=2), max_triangles=30_000)


def test_same_seed_same_leaves_other_seed_other_leaves(tree3d_skeleton):
    options = LeafOptions(leaves_per_cluster=4, leaf_size=0.1, leaf_size_variation=0.2, leaf_light=0.5)
    a, b = arrange(tree3d_skeleton, options, seed=7), arrange(tree3d_skeleton, options, seed=7)
    c = arrange(tree3d_skeleton, options, seed=8)
    for name in ("leaf_position", "leaf_heading", "leaf_left", "leaf_up", "leaf_size"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert not np.array_equal(a.leaf_size, c.leaf_size) and not np.array_equal(a.leaf_heading, c.leaf_heading)


def test_neutral_options_leave_the_skeleton_as_it_is(tree3d_skeleton):
    assert arrange(tree3d_skeleton, LeafOptions(cluster_spread=10, cluster_length=1.0, light=(1, 0, 0))) is (
        tree3d_skeleton
    )
    assert leaves(tree3d_skeleton).instance_material is None


# ---------------------------------------------------------------- light and droop


def test_toward_light_turns_the_front_by_the_fraction_and_keeps_the_heading_close():
    rng = np.random.default_rng(0)
    h = rng.normal(size=(200, 3))
    h /= np.linalg.norm(h, axis=1)[:, None]
    lf = np.cross(h, rng.normal(size=(200, 3)))
    lf /= np.linalg.norm(lf, axis=1)[:, None]
    up = np.cross(h, lf)
    light = np.array([0.0, 1.0, 0.0])
    before = np.arccos(np.clip(up @ light, -1, 1))
    for fraction in (0.3, 0.8, 1.0):
        h2, l2, u2 = toward_light(h, lf, up, light, fraction)
        after = np.arccos(np.clip(u2 @ light, -1, 1))
        np.testing.assert_allclose(after, (1 - fraction) * before, atol=1e-7)
        np.testing.assert_allclose(np.cross(h2, l2), u2, atol=1e-12)
        # the new heading is the old one's projection across the new up: no frame with that up has a closer one
        projection = h - (h * u2).sum(axis=1)[:, None] * u2
        projection /= np.linalg.norm(projection, axis=1)[:, None]
        np.testing.assert_allclose(h2, projection, atol=1e-9)


def test_droop_hangs_the_tip_and_no_further_than_down():
    h = np.array([[1.0, 0.0, 0.0], [0.0, -0.9, 0.43588989]])
    h /= np.linalg.norm(h, axis=1)[:, None]
    lf = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
    up = np.cross(h, lf)
    h2, l2, u2 = droop(h, lf, up, 30)
    assert np.degrees(np.arcsin(-h2[0, 1])) == pytest.approx(30)  # a level blade: its tip 30 degrees down
    np.testing.assert_allclose(h2[1], [0, -1, 0], atol=1e-9)  # 26 degrees from down: ends pointing down
    np.testing.assert_allclose(np.cross(h2, l2), u2, atol=1e-12)


def test_seventy_percent_face_the_sky_on_tree3d():
    """With leaf_light 0.8, at least 70% of tree3d's blades face within 60 degrees of the sky (14% without)."""
    kw = {"union": False, "leaf_size": 0.12, "leaves_per_cluster": 4, "leaf_droop": 15}
    plain = lsys3d.generate("tree3d", **kw)
    lit = lsys3d.generate("tree3d", leaf_light=0.8, **kw)
    up_plain = plain.leaves.transforms[:, :3, 1]
    up_lit = lit.leaves.transforms[:, :3, 1]
    assert len(up_lit) == 4 * 729
    assert sky_share(up_plain / np.linalg.norm(up_plain, axis=1)[:, None]) < 0.3
    assert sky_share(up_lit / np.linalg.norm(up_lit, axis=1)[:, None]) >= 0.7
    # the exported faces agree: the baked blades' normals
    normals = lit.leaves.merged.normals[:, 0]
    assert np.mean(normals[:, 1] > 0.5) >= 0.7


# ---------------------------------------------------------------- cards


@pytest.mark.parametrize("card", ["spray", "cross"])
def test_cards_one_per_cluster(tree3d_skeleton, card):
    sk = tree3d_skeleton
    options = LeafOptions(leaf_card=card, leaves_per_cluster=8, leaf_size=0.1, cluster_length=0.2)
    out = leaves(sk, options=options, seed=0)
    k = len(sk.leaf_position)
    assert len(out.transforms) == k and len(out.merged.faces) == k * (2 if card == "spray" else 4)
    assert out.merged.uv.min() >= 0 and out.merged.uv.max() <= 1
    # each card reaches from cluster_length back along the twig to past the tips of the top leaves
    lengths = np.linalg.norm(out.transforms[:, :3, 2], axis=1)
    np.testing.assert_allclose(lengths, 0.2 + 0.1 * np.cos(np.radians(45)))
    np.testing.assert_allclose(np.linalg.norm(out.transforms[:, :3, 3] - sk.leaf_position, axis=1), 0.2, atol=1e-9)


def test_twig_cards_take_each_leafs_place(tree3d_skeleton):
    """leaf_card = "twigs": a square card where each clustered leaf would be, card_length leaves long."""
    sk = tree3d_skeleton
    base = dict(leaves_per_cluster=5, leaf_size=0.1, cluster_length=0.2, leaf_light=0.5)
    single = leaves(sk, options=LeafOptions(**base), seed=0)
    twigs = leaves(sk, options=LeafOptions(**base, leaf_card="twigs", card_length=3.0), seed=0)
    k = len(sk.leaf_position)
    assert len(twigs.transforms) == 5 * k and len(twigs.merged.faces) == 2 * 5 * k
    np.testing.assert_allclose(twigs.transforms[:, :3, 3], single.transforms[:, :3, 3])
    np.testing.assert_allclose(twigs.transforms[:, :3, :3], 3.0 * single.transforms[:, :3, :3])
    np.testing.assert_allclose(twigs.model.bounds, [[-0.5, 0, 0], [0.5, 0, 1]])  # square: the picture's shape
    aspect = leaves(sk, options=LeafOptions(**base, leaf_card="spray", card_aspect=0.7), seed=0).model
    np.testing.assert_allclose(aspect.bounds[:, 0], [-0.35, 0.35])


def test_leaf_outward_leans_the_light_away_from_the_crowns_axis(tree3d_skeleton):
    sk = tree3d_skeleton
    options = LeafOptions(leaves_per_cluster=3, leaf_size=0.1, leaf_light=1.0, leaf_outward=0.5, leaf_card="twigs")
    out = leaves(sk, options=options, seed=0)
    up = out.transforms[:, :3, 1] / np.linalg.norm(out.transforms[:, :3, 1], axis=1)[:, None]
    # every card faces 45 degrees above the horizon, away from the vertical line through the leaves' middle
    np.testing.assert_allclose(up[:, 1], np.sqrt(0.5), atol=1e-9)
    away = out.transforms[:, [0, 2], 3] - sk.leaf_position[:, [0, 2]].mean(axis=0)
    assert np.all(np.einsum("ij,ij->i", up[:, [0, 2]], away) > 0)
    assert sky_share(up) == 1.0
    # without it the same cards face straight up
    flat = leaves(sk, options=options.replace(leaf_outward=0.0), seed=0).transforms[:, :3, 1]
    np.testing.assert_allclose(flat[:, 1] / np.linalg.norm(flat, axis=1), 1.0)


# ---------------------------------------------------------------- options and the grammar's [leaves]


@pytest.mark.parametrize(
    "kw, message",
    [
        ({"leaf_light": 1.5}, r"LeafOptions.leaf_light: must be in \[0, 1\], not 1.5"),
        ({"leaves_per_cluster": 0}, r"LeafOptions.leaves_per_cluster: must be in \[1, 64\], not 0"),
        ({"leaf_shape": "fern"}, r"LeafOptions.leaf_shape: must be one of 'default'"),
        ({"leaf_card": "billboard"}, r"LeafOptions.leaf_card: must be one of 'none', 'spray', 'cross', 'twigs'"),
        ({"card_length": 0}, r"LeafOptions.card_length: must be in \[0.1, 100\], not 0"),
        ({"leaf_outward": 1.5}, r"LeafOptions.leaf_outward: must be in \[0, 1\], not 1.5"),
        ({"light": (0, 0, 0)}, r"LeafOptions.light: must be a direction"),
        ({"light": (0, 1)}, r"LeafOptions.light: must be a list of 3 numbers"),
        ({"leaf_droop": 91}, r"LeafOptions.leaf_droop: must be in \[0, 90\]"),
        ({"leaf_size": -0.1}, r"LeafOptions.leaf_size: must be in \[0, 1e\+09\], not -0.1"),
        ({"leaf_size_variation": 1.0}, r"LeafOptions.leaf_size_variation: must be in \[0, 0.9\]"),
        ({"petiole_length": float("nan")}, r"LeafOptions.petiole_length: must be a finite number"),
    ],
)
def test_options_out_of_range(kw, message):
    with pytest.raises(OptionsError, match=message):
        LeafOptions(**kw)
    with pytest.raises(OptionsError, match=message):
        lsys3d.generate("tree3d", iterations=1, union=False, **kw)


LEAFY = """\
name = "leafy"
axiom = "F(1)[+F(0.5)~][-F(0.5)~]F(0.5)~"
angle = 40

[turtle]
leaf = "~"

[leaves]
leaf_size = 0.1
leaves_per_cluster = 3
leaf_shape = "ovate"
"""


def test_leaves_table_sets_the_options():
    g = lsys3d.Grammar.from_text(LEAFY + "light = [0, 1, 0.2]\n", "leafy.toml")
    assert dict(g.leaves)["leaf_shape"] == "ovate" and dict(g.leaves)["light"] == [0, 1, 0.2]
    tree = lsys3d.generate(g, union=False)
    assert len(tree.leaves.transforms) == 9
    np.testing.assert_allclose(np.linalg.norm(tree.leaves.transforms[:, :3, 2], axis=1), 0.1)
    assert len(tree.leaves.model.faces) == 28 and np.ptp(tree.leaves.model.vertices[:, 0]) == pytest.approx(0.6)
    # an option given to generate wins over the table; the others stay the table's
    tree = lsys3d.generate(g, union=False, leaves_per_cluster=2)
    assert len(tree.leaves.transforms) == 6
    assert tree.provenance.options["leaves"] == {"leaf_points": 7, "leaves_per_cluster": 2}
    assert "[leaves]" in tree.provenance.grammar_text  # the table travels with the grammar
    # a grammar built in Python renders its table for the provenance, and reads back the same
    built = lsys3d.Grammar(axiom="F~", leaves={"leaf_size": 0.2, "light": [1, 1, 0]})
    text = lsys3d.generate(built, union=False).provenance.grammar_text
    assert dict(lsys3d.Grammar.from_text(text).leaves) == {"leaf_size": 0.2, "light": [1, 1, 0]}


@pytest.mark.parametrize(
    "line, message",
    [
        (
            "leaf_sise = 0.1",
            r"leafy.toml:12:1: \[leaves\] unknown key 'leaf_sise' \(known keys: card_aspect, card_length",
        ),
        ("  leaf_light = 2", r"leafy.toml:12:3: \[leaves\] leaf_light: must be in \[0, 1\], not 2"),
        ('leaf_card = "fern"', r"leafy.toml:12:1: \[leaves\] leaf_card: must be one of 'none', 'spray', 'cross'"),
        ("light = [0, 0, 0]", r"leafy.toml:12:1: \[leaves\] LeafOptions.light: must be a direction"),
    ],
)
def test_bad_leaves_table_is_a_grammar_error_at_its_line(line, message):
    text = LEAFY + line + "\n"
    with pytest.raises(GrammarError, match=message):
        lsys3d.generate(lsys3d.Grammar.from_text(text, "leafy.toml"), union=False)


def test_leaves_must_be_a_table():
    with pytest.raises(GrammarError, match=r"leafy.toml:2:1: 'leaves' must be a table"):
        lsys3d.Grammar.from_text('axiom = "F"\nleaves = 3\n', "leafy.toml")


def test_defaults_are_not_recorded_so_old_files_keep_their_bytes():
    assert LeafOptions().plain() == {"leaf_points": 7}
    o = LeafOptions(leaf_size=0.1, light=(0.0, 1.0, 1.0), leaf_card="spray")
    assert o.plain() == {"leaf_card": "spray", "leaf_points": 7, "leaf_size": 0.1, "light": [0.0, 1.0, 1.0]}
    assert LeafOptions.from_plain(o.plain()) == o


# ---------------------------------------------------------------- levels of detail and export


def test_levels_of_detail_with_clusters():
    tree = lsys3d.generate(
        "tree3d", iterations=4, union=False, lod=(0, 1, 2, 3), leaf_size=0.1, leaves_per_cluster=4, leaf_light=0.7
    )
    leaf_counts = [len(lod.leaves.transforms) for lod in tree.lods[:3]]
    assert leaf_counts[0] == 4 * len(tree.skeleton.leaf_position) and leaf_counts[0] > leaf_counts[1] > leaf_counts[2]
    # a thinned level's leaves grow so that the crown's leaf area stays about the same (in units of its blade's area:
    # the lighter levels' blades have fewer rows)
    area = [lod.leaves.merged.area / lod.leaves.model.area for lod in tree.lods[:3]]
    assert area[1] == pytest.approx(area[0], rel=0.1) and area[2] == pytest.approx(area[0], rel=0.1)


def test_a_leafy_tree3d_exports_a_valid_glb(tmp_path):
    text = lsys3d.load_preset("tree3d").text + (
        '\n[leaves]\nleaf_size = 0.12\nleaf_size_variation = 0.2\nleaves_per_cluster = 5\nleaf_shape = "lobed"\n'
        "petiole_length = 0.3\nleaf_light = 0.75\nleaf_droop = 10\n"
    )
    tree = lsys3d.generate(lsys3d.Grammar.from_text(text, str(tmp_path / "oakish.toml")), iterations=4)
    k = len(tree.skeleton.leaf_position)
    assert len(tree.leaves.transforms) == 5 * k
    for name in ("instanced.glb", "merged.glb"):
        options = lsys3d.ExportOptions(instance_leaves=name == "instanced.glb")
        report = validators.validate_gltf(lsys3d.export(tree, tmp_path / name, options))
        assert validators.gltf_issues(report, 0) == [] and validators.gltf_issues(report, 1) == []
        infos = validators.gltf_issues(report, 2)
        assert {i.split(" ")[0] for i in infos} <= validators.HARMLESS_INFOS, infos
    assert report["info"]["totalTriangleCount"] == len(tree.bark.faces) + len(tree.leaves.merged.faces)


def test_every_option_is_in_the_docs_table():
    from dataclasses import fields
    from pathlib import Path

    text = (Path(__file__).resolve().parent.parent / "docs" / "leaves.md").read_text(encoding="utf-8")
    for f in fields(LeafOptions):
        assert f"| `{f.name}`" in text, f.name


def test_clustered_leaves_keep_their_materials_in_the_files(tmp_path):
    from gltf_files import read_glb

    text = """\
axiom = "F(1)[+F(0.5)'(2)~][-F(0.5)'(3)~]"
angle = 40

[materials]
2 = { name = "green", base_color = "#3f8a2a" }
3 = { name = "red", base_color = "#a03020" }

[leaves]
leaves_per_cluster = 3
leaf_size = 0.1
"""
    tree = lsys3d.generate(lsys3d.Grammar.from_text(text, "two.toml"), union=False)
    assert tree.leaves.instance_material.tolist() == [2, 2, 2, 3, 3, 3]
    assert np.bincount(tree.leaves.merged.face_material).tolist()[2:] == [3 * 28, 3 * 28]
    doc, _ = read_glb(lsys3d.export(tree, tmp_path / "two.glb"))
    names = {doc["materials"][p["material"]]["name"] for m in doc["meshes"] for p in m["primitives"]}
    assert {"green", "red"} <= names
    usd = (lsys3d.export(tree, tmp_path / "two.usda")).read_text()
    assert "green" in usd and "red" in usd
