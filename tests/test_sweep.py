"""Sweep: exact counts, closed tubes, frames, normals, uv and degenerate skeletons."""

from __future__ import annotations

import math

import numpy as np
import pytest
from skeletons import make_skeleton

from lsys3d.mesh.sweep import SweepOptions, Tubes, sweep
from lsys3d.turtle.skeleton import Skeleton

# ---------------------------------------------------------------- skeletons


def polyline(points, width=0.1, width_end=None) -> Skeleton:
    """One chain through ``points``."""
    p = np.asarray(points, float)
    return make_skeleton(p[:-1], p[1:], width, width_end)


def zigzag(m: int, angle: float = 20.0) -> np.ndarray:
    """``m + 1`` points of unit steps turning ``angle`` degrees alternately left and right in the XY plane."""
    pts = [np.zeros(3)]
    for i in range(m):
        a = math.radians(90 + (angle / 2 if i % 2 else -angle / 2))
        pts.append(pts[-1] + [math.cos(a), math.sin(a), 0.0])
    return np.array(pts)


def y_junction() -> Skeleton:
    """A trunk with two children at its tip."""
    return make_skeleton(
        start=[[0, 0, 0], [0, 1, 0], [0, 1, 0]],
        end=[[0, 1, 0], [0.6, 1.8, 0], [-0.6, 1.8, 0.1]],
        width_start=[0.2, 0.12, 0.1],
        width_end=[0.15, 0.05, 0.05],
        parent=[-1, 0, 0],
        order=[0, 1, 1],
    )


# ---------------------------------------------------------------- helpers


def counts_ok(tubes: Tubes):
    """The documented formulas: points R*S + 2, triangles 2*S*R, wedges (R + 2)(S + 1)."""
    r, s = tubes.rings, tubes.sides
    assert (np.diff(tubes.point_offsets) == r * s + 2).all()
    assert (np.diff(tubes.face_offsets) == 2 * s * r).all()
    assert (np.diff(tubes.wedge_offsets) == (r + 2) * (s + 1)).all()
    assert len(tubes.points) == (r * s + 2).sum()
    assert len(tubes.faces) == (2 * s * r).sum()


def tubes_closed(tubes: Tubes):
    vols = tubes.volumes()
    for i in range(len(tubes)):
        m = tubes.mesh(i)
        assert m.is_watertight, i
        assert m.is_winding_consistent, i
        assert m.volume > 0, i
        assert math.isclose(m.volume, vols[i], rel_tol=1e-9)


# ---------------------------------------------------------------- counts


@pytest.mark.parametrize("sides", [3, 5, 8, 16])
def test_straight_chain_needs_two_rings(sides):
    # collinear segments of equal width: the joint rings add no shape
    tubes = sweep(polyline([[0, 0, 0], [0, 1, 0], [0, 2, 0], [0, 3, 0]]), SweepOptions(sides=sides))
    assert len(tubes) == 1
    assert tubes.rings.tolist() == [2]
    assert len(tubes.points) == 2 * sides + 2
    assert len(tubes.faces) == 4 * sides
    counts_ok(tubes)
    tubes_closed(tubes)


def test_linear_taper_keeps_no_joint_ring():
    sk = polyline([[0, 0, 0], [0, 1, 0], [0, 2, 0]], width=[0.3, 0.2], width_end=[0.2, 0.1])
    assert sweep(sk).rings.tolist() == [2]
    # a kink in the taper needs its ring
    sk = polyline([[0, 0, 0], [0, 1, 0], [0, 2, 0]], width=[0.3, 0.2], width_end=[0.2, 0.2])
    assert sweep(sk).rings.tolist() == [3]


@pytest.mark.parametrize("m", [1, 2, 7, 30])
@pytest.mark.parametrize("sides", [4, 8])
def test_bent_chain_counts(m, sides):
    tubes = sweep(polyline(zigzag(m)), SweepOptions(sides=sides))
    assert len(tubes) == 1
    assert tubes.rings.tolist() == [m + 1]
    assert len(tubes.points) == (m + 1) * sides + 2
    assert len(tubes.faces) == 2 * sides * (m + 1)
    assert len(tubes.wedge_point) == (m + 3) * (sides + 1)
    counts_ok(tubes)
    tubes_closed(tubes)


def test_cylinder_volume_is_prism_volume():
    s, r, length = 8, 0.25, 3.0
    tubes = sweep(polyline([[1, 2, 3], [1, 2 + length, 3]], width=2 * r), SweepOptions(sides=s))
    expected = 0.5 * s * r * r * math.sin(2 * math.pi / s) * length
    assert tubes.volumes()[0] == pytest.approx(expected, rel=1e-12)


def test_y_junction_two_tubes():
    sk = y_junction()
    tubes = sweep(sk)
    assert len(tubes) == len(sk.chains) == 2
    counts_ok(tubes)
    tubes_closed(tubes)


def test_sides_by_order():
    opt = SweepOptions(sides=8, sides_step=3, min_sides=4)
    tubes = sweep(y_junction(), opt)
    assert sorted(tubes.sides.tolist()) == [5, 8]
    counts_ok(tubes)
    tubes_closed(tubes)


def test_random_trees_counts_and_closed():
    rng = np.random.default_rng(3)
    for _ in range(5):
        sk = random_small_tree(rng, 40)
        tubes = sweep(sk, SweepOptions(sides=6, sides_step=1))
        counts_ok(tubes)
        tubes_closed(tubes)
        assert set(tubes.chain.tolist()) == set(range(len(sk.chains)))


def random_small_tree(rng, n) -> Skeleton:
    start, end, par, order = [np.zeros(3)], [np.array([0.0, 1.0, 0.0])], [-1], [0]
    for i in range(1, n):
        p = int(rng.integers(0, i))
        d = end[p] - start[p]
        d = d / np.linalg.norm(d) + rng.normal(scale=0.5, size=3)
        start.append(end[p])
        end.append(end[p] + 0.5 * d / np.linalg.norm(d))
        par.append(p)
        order.append(order[p] + int(rng.random() < 0.5))
    w = 0.12 * 0.85 ** np.array(order)
    return make_skeleton(start, end, w, w * 0.9, par, order)


# ---------------------------------------------------------------- sharp bends


def test_sharp_bend_splits_the_chain():
    sk = polyline([[0, 0, 0], [0, 1, 0], [0.17, 0.02, 0]])  # turns back ~170 degrees
    tubes = sweep(sk)
    assert len(tubes) == 2
    assert (tubes.chain == 0).all()
    counts_ok(tubes)
    tubes_closed(tubes)
    # each piece runs on past the joint to cover the outside of the elbow
    top = tubes.points[:, 1].max()
    assert top > 1.0


def test_thick_tube_with_short_segments_splits_where_it_would_fold():
    # 60 degree turn, radius 0.5, segments 0.3 long: r * tan(30) > 0.15
    sk = polyline([[0, 0, 0], [0, 0.3, 0], [0.26, 0.45, 0]], width=1.0)
    assert len(sweep(sk)) == 2
    # the same turn with a thin tube follows the bend with a mitred ring
    sk = polyline([[0, 0, 0], [0, 0.3, 0], [0.26, 0.45, 0]], width=0.05)
    tubes = sweep(sk)
    assert len(tubes) == 1 and tubes.rings.tolist() == [5]  # and a ring on each side of its mitre
    assert sweep(sk, SweepOptions(elbow_angle=180.0)).rings.tolist() == [3]


def curl(m: int, step: float, turn: float) -> np.ndarray:
    """``m + 1`` points of steps ``step`` long, turning ``turn`` degrees each (a circle arc in the XY plane)."""
    a = np.radians(90 + turn * np.arange(m))
    return np.concatenate([[[0.0, 0.0, 0.0]], np.cumsum(step * np.stack([np.cos(a), np.sin(a), 0 * a], axis=1), 0)])


def test_steps_shorter_than_the_width_merge_into_fewer_rings():
    # a curl of 200 steps of 0.5 mm turning 1 degree each, 1 cm wide: a ring every 0.5 mm adds nothing
    points = curl(200, 0.0005, 1.0)
    sk = polyline(points, width=0.01)
    every = sweep(sk, SweepOptions(merge_deviation=0.0))
    fewer = sweep(sk)
    assert every.rings.sum() == 201
    assert fewer.rings.sum() < every.rings.sum() / 4
    # the axis stays within 2% of the radius of the skeleton: ring centres lie on it, joints near the chords
    centres = fewer.points[: fewer.rings[0] * 8].reshape(-1, 8, 3).mean(axis=1)
    dist = np.linalg.norm(points[:, None, :2] - centres[None, :, :2], axis=2).min(axis=0)
    assert dist.max() < 1e-9  # every ring sits on a skeleton point
    assert fewer.volumes().sum() == pytest.approx(every.volumes().sum(), rel=2e-3)
    assert fewer.mesh().is_watertight


def test_steps_longer_than_the_width_keep_their_rings():
    sk = polyline(curl(30, 0.05, 0.2), width=0.01)  # nearly straight, but 5 times longer than wide
    assert sweep(sk).rings.sum() == sweep(sk, SweepOptions(merge_deviation=0.0)).rings.sum() == 31


def test_mitre_ring_keeps_the_width():
    # a 90 degree elbow: the joint ring lies on both cylinders (radius 0.1 about
    # the Y axis and about the line y = 2, z = 0)
    sk = polyline([[0, 0, 0], [0, 2, 0], [2, 2, 0]], width=0.2)
    tubes = sweep(sk, SweepOptions(sides=8))
    joint = int(np.flatnonzero(np.all(np.isclose(tubes.ring_center, [0, 2, 0]), axis=1))[0])
    x, y, z = (tubes.points[8 * joint : 8 * joint + 8] - [0, 2, 0]).T
    np.testing.assert_allclose(np.hypot(x, z), 0.1, rtol=1e-12)
    np.testing.assert_allclose(np.hypot(y, z), 0.1, rtol=1e-12)


# ---------------------------------------------------------------- frames, normals, uv


def test_frame_does_not_twist():
    # a chain bending in the XY plane: the ring's first vertex keeps its angle to +Z
    tubes = sweep(polyline(zigzag(12, angle=30)), SweepOptions(sides=8))
    s = 8
    centers = np.array(zigzag(12, angle=30))
    # mitre rings stretch within the XY plane only, so the Z offset shows any twist
    first = tubes.points[0 : 13 * s : s] - centers
    assert np.ptp(first[:, 2]) < 1e-9


def test_helix_frame_is_rotation_minimising():
    t = np.linspace(0, 4 * np.pi, 80)
    pts = np.stack([np.cos(t), 0.3 * t, np.sin(t)], axis=1)
    tubes = sweep(polyline(pts, width=0.05), SweepOptions(sides=6))
    assert len(tubes) == 1
    # the ring frame turns about the tangent by as little as possible: consecutive
    # first ring vertices (relative to the centres) stay close to parallel
    first = tubes.points[0 : 80 * 6 : 6] - pts
    first /= np.linalg.norm(first, axis=1, keepdims=True)
    assert (np.einsum("ij,ij->i", first[1:], first[:-1]) > math.cos(math.radians(12))).all()


def test_normals_unit_and_sharp_caps():
    tubes = sweep(polyline(zigzag(5)))
    n = tubes.wedge_normal
    assert n.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-6)
    m = tubes.mesh(0)
    corner = m.normals
    assert corner.shape == (len(m.faces), 3, 3) and corner.dtype == np.float32
    # smooth around: normals point away from the axis; caps: every corner has the face normal
    cap = slice(len(m.faces) - 16, None)
    np.testing.assert_allclose(corner[cap], np.repeat(m.face_normals[cap][:, None], 3, axis=1), atol=1e-6)
    body = slice(0, len(m.faces) - 16)
    assert (np.einsum("fcj,fj->fc", corner[body], m.face_normals[body]) > 0.8).all()


def test_normals_lean_with_the_taper():
    tubes = sweep(polyline([[0, 0, 0], [0, 1, 0]], width=1.0, width_end=0.0), SweepOptions(min_width=1e-3))
    body = tubes.wedge_normal[: 2 * 9]
    # a cone narrowing along +Y: its side normals lean towards +Y
    assert (body[:, 1] > 0.3).all()


def test_uv_tiles_around_and_square_texels_along():
    pts = zigzag(6)
    sk = polyline(pts)  # width 0.1: perimeter 16 * 0.05 * sin(pi / 8) = 0.306 m, one tile around
    tubes = sweep(sk, SweepOptions(sides=8))
    assert tubes.tiles.tolist() == [1.0]
    uv = tubes.wedge_uv
    assert uv.dtype == np.float32
    ring_uv = uv[: 7 * 9].reshape(7, 9, 2)
    np.testing.assert_allclose(ring_uv[:, :, 0], np.tile(np.arange(9) / 8, (7, 1)), atol=1e-7)
    perimeter = 16 * 0.05 * math.sin(math.pi / 8)
    np.testing.assert_allclose(np.diff(ring_uv[:, 0, 1]), sk.lengths() / perimeter, rtol=1e-6)
    # a square of texture is square on the tube: a mitred joint ring of a bend b shears it by at most
    # tan(b / 2) (its far side ahead of its near side), a stretch of at most (s / 2 + sqrt(1 + s^2 / 4))^2
    from lsys3d.mesh.quality import uv_stretch

    m = tubes.mesh()
    stretch = uv_stretch(m.vertices, m.faces, m.uv)
    s = math.tan(math.radians(10.0))
    assert np.nanmax(stretch) < (s / 2 + math.sqrt(1 + s * s / 4)) ** 2 + 1e-6
    assert np.nanmedian(stretch) < 1.15


@pytest.mark.parametrize("turn", [60.0, 90.0, 110.0])
def test_sharp_joints_keep_the_shear_in_a_band_at_the_elbow(turn):
    from lsys3d.mesh.quality import uv_stretch

    a = math.radians(90.0 - turn)
    pts = [[0, 0, 0], [0, 1, 0], [math.cos(a), 1 + math.sin(a), 0], [math.cos(a), 2 + math.sin(a), 0]]
    plain = sweep(polyline(pts), SweepOptions(sides=8, elbow_angle=180.0))
    tubes = sweep(polyline(pts), SweepOptions(sides=8))
    # two rings more at each of the two sharp joints, across the span, clear of the mitre (r tan(turn / 2))
    assert plain.rings.tolist() == [4] and tubes.rings.tolist() == [8]
    reach = 0.05 * math.tan(math.radians(turn / 2))
    centre = tubes.ring_center
    gaps = np.linalg.norm(np.diff(centre, axis=0), axis=1)
    at = min(4 * reach, 0.4)
    np.testing.assert_allclose(gaps, [1 - at, at, at, 1 - 2 * at, at, at, 1 - at], rtol=1e-9)
    assert at > 1.25 * reach
    tubes_closed(tubes)
    assert tubes.volumes().sum() == pytest.approx(plain.volumes().sum(), rel=1e-12)  # the shape is the same
    for t, most in ((plain, 1.5), (tubes, 1.2)):
        m = t.mesh()
        body = slice(0, 2 * 8 * (t.rings[0] - 1))
        median = np.nanmedian(uv_stretch(m.vertices, m.faces[body], m.uv[body]))
        assert (median > most) if t is plain and turn > 60 else (median < most), (turn, median)


def test_gentle_joints_get_no_elbow_rings():
    tubes = sweep(polyline(zigzag(6, angle=40.0)), SweepOptions(sides=8))
    assert tubes.rings.tolist() == [7]
    assert sweep(polyline(zigzag(6, angle=40.0)), SweepOptions(sides=8, elbow_angle=30.0)).rings.tolist() == [17]


def test_thick_chains_get_whole_tiles_around():
    # a 1 m wide trunk: perimeter 8 * 2 * 0.5 * sin(pi / 8) = 3.06 m, 6 tiles of 0.5 m (uv_tile)
    tubes = sweep(polyline([[0, 0, 0], [0, 2, 0]], width=1.0), SweepOptions(sides=8))
    assert tubes.tiles.tolist() == [6.0]
    assert tubes.wedge_uv[:9, 0].max() == pytest.approx(6.0)
    tubes = sweep(polyline([[0, 0, 0], [0, 2, 0]], width=1.0), SweepOptions(sides=8, uv_tile=2.0))
    assert tubes.tiles.tolist() == [2.0]


def test_tapering_tube_keeps_square_texels():
    sk = polyline([[0, 0, 0], [0, 3, 0]], width=0.4, width_end=0.05)
    tubes = sweep(sk, SweepOptions(sides=12, ring_spacing=1.0))
    from lsys3d.mesh.quality import uv_stretch

    m = tubes.mesh()
    body = slice(0, 2 * 12 * (tubes.rings[0] - 1))
    stretch = uv_stretch(m.vertices, m.faces[body], m.uv[body])
    assert np.nanmax(stretch) < 1.1


@pytest.mark.parametrize("blend", [0.0, 1.5])
def test_v_runs_on_from_parent_into_child(blend):
    tubes = sweep(y_junction(), SweepOptions(fork_blend=0.0))
    blended = sweep(y_junction(), SweepOptions(fork_blend=blend))
    # a blended base (fork_blend) changes the first radii of the children, not the v of their tips
    ends = np.cumsum(tubes.rings) - 1
    assert blended.ring_v[np.cumsum(blended.rings) - 1] == pytest.approx(tubes.ring_v[ends])
    # the second child is a tube of its own: its base ring's v is the trunk's v at the junction
    trunk = np.flatnonzero(tubes.order == 0)[0]
    child = np.flatnonzero(tubes.order == 1)[0]
    first, last = tubes.ring_offsets[trunk], tubes.ring_offsets[trunk + 1]
    # the trunk's ring at the junction (y = 1) is its second ring
    junction_v = tubes.ring_v[first:last][np.argmin(np.abs(tubes.ring_center[first:last, 1] - 1.0))]
    assert tubes.ring_v[tubes.ring_offsets[child]] == pytest.approx(junction_v)
    assert junction_v > 0


@pytest.mark.parametrize(
    "skeleton", [y_junction(), polyline([[0, 0, 0], [0, 1, 0], [1, 1, 0], [1, 2, 0]])], ids=["fork", "elbows"]
)
def test_uv_at_gives_each_vertex_its_own_uv(skeleton):
    tubes = sweep(skeleton, SweepOptions(sides=7))
    from lsys3d.mesh.sweep import wrap_u

    m = tubes.mesh()
    uv = tubes.uv_at(np.repeat(m.face_source, 3), m.vertices[m.faces].reshape(-1, 3)).reshape(-1, 3, 2)
    tube = np.searchsorted(tubes.face_offsets, m.face_source, side="right") - 1
    uv = wrap_u(uv, tubes.tiles[tube])
    np.testing.assert_allclose(uv, m.uv, atol=2e-5)
    # the compiled corner uv (the cleanup's) is the same, bit for bit, in two ranges as in one
    both = np.full((len(m.faces), 3, 2), np.nan)
    half = len(m.faces) // 2
    tubes.corner_uv(m.face_source, m.vertices, m.faces, both, 0, half)
    tubes.corner_uv(m.face_source, m.vertices, m.faces, both, half)
    np.testing.assert_array_equal(both, uv)


def test_seam_faces_the_turtles_down():
    # an upright stem of the default turtle (heading +Y, up +Z): the first ring vertex (u = 0) at the back, -Z
    import lsys3d
    from lsys3d.pipeline import draw

    grammar = lsys3d.load("tree3d")
    skeleton = draw(grammar, 1, 0)[1]
    tubes = sweep(skeleton)
    trunk = skeleton.chains.segments[0]
    assert skeleton.up[trunk] == pytest.approx([0, 0, 1])
    ring0 = tubes.points[tubes.point_offsets[0]] - tubes.ring_center[0]
    assert ring0 / np.linalg.norm(ring0) == pytest.approx([0, 0, -1])
    # every chain: its first ring's u = 0 vertex lies along -U of its first segment, in the ring's plane (a
    # blended thick child's first ring, fork_blend, faces along its parent's heading rather than its own)
    for t in range(len(tubes)):
        seg = skeleton.chains.segments[skeleton.chains.offsets[tubes.chain[t]]]
        r = tubes.ring_offsets[t]
        first = tubes.points[tubes.point_offsets[t]] - tubes.ring_center[r]
        down = -skeleton.up[seg] + np.dot(skeleton.up[seg], tubes.ring_tangent[r]) * tubes.ring_tangent[r]
        assert np.dot(first / np.linalg.norm(first), down / np.linalg.norm(down)) > 0.999


def _rotated(skeleton, rotation, shift):
    """The skeleton moved by a rigid motion (its turtle frames turned with it)."""
    from dataclasses import replace

    turn = {k: getattr(skeleton, k) @ rotation.T for k in ("heading", "left", "up")}
    return replace(skeleton, start=skeleton.start @ rotation.T + shift, end=skeleton.end @ rotation.T + shift, **turn)


def test_congruent_skeletons_get_congruent_tubes_and_the_same_uv():
    # the seam is placed by the turtle's frame, not the world's: a plant turned and moved gets the same
    # texture coordinates, and its tubes are the first ones turned and moved (lsys3d.mesh.union.repeats relies on it)
    import lsys3d
    from lsys3d.pipeline import draw

    skeleton = draw(lsys3d.load("tree3d"), 3, 0)[1]
    q, _ = np.linalg.qr(np.array([[0.3, -0.8, 0.5], [0.9, 0.1, -0.2], [0.1, 0.6, 0.7]]))
    rotation = q * np.sign(np.linalg.det(q))
    shift = np.array([3.0, -1.0, 2.0])
    a = sweep(skeleton, SweepOptions(sides=6))
    b = sweep(_rotated(skeleton, rotation, shift), SweepOptions(sides=6))
    np.testing.assert_allclose(b.points, a.points @ rotation.T + shift, atol=1e-9)
    np.testing.assert_allclose(b.wedge_uv, a.wedge_uv, atol=2e-6)
    np.testing.assert_allclose(b.wedge_normal, a.wedge_normal @ rotation.T.astype(np.float32), atol=2e-6)


def test_ring_spacing_adds_rings_on_long_spans():
    sk = polyline([[0, 0, 0], [0, 4, 0]], width=0.2)
    assert sweep(sk).rings.tolist() == [2]
    side = 0.2 * math.sin(math.pi / 8)  # 2 r sin(pi / S)
    tubes = sweep(sk, SweepOptions(ring_spacing=2.0))
    assert tubes.rings.tolist() == [math.ceil(4 / (2 * side)) + 1]
    # bark displacement asks for rings by itself: a side apart, but at most two per bump of the noise
    tubes = sweep(sk, SweepOptions(bark_displacement=0.2, bark_frequency=8))
    assert tubes.rings.tolist() == [math.ceil(4 / max(side, 0.5 / 8)) + 1]
    counts_ok(tubes)
    tubes_closed(tubes)


# ---------------------------------------------------------------- degenerate input


def test_zero_length_segments_are_dropped():
    clean = sweep(polyline(zigzag(4)))
    pts = zigzag(4)
    dup = np.insert(pts, [2, 2, 4], pts[[2, 2, 4]], axis=0)  # three zero-length segments
    tubes = sweep(polyline(dup))
    assert len(tubes) == 1
    assert tubes.rings.tolist() == clean.rings.tolist()
    np.testing.assert_allclose(tubes.points, clean.points, atol=1e-12)
    tubes_closed(tubes)


def test_only_zero_length_segments_give_no_tubes():
    tubes = sweep(polyline([[1, 1, 1], [1, 1, 1], [1, 1, 1]]))
    assert len(tubes) == 0 and len(tubes.points) == 0 and tubes.mesh().is_empty


def test_empty_skeleton():
    sk = make_skeleton(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))
    assert len(sweep(sk)) == 0


@pytest.mark.parametrize("width", [0.0, 1e-9, -1.0])
def test_zero_width_is_clamped(width):
    opt = SweepOptions(min_width=0.01)
    tubes = sweep(polyline(zigzag(3), width=width), opt)
    tubes_closed(tubes)
    ring0 = tubes.points[:8] - [0, 0, 0]
    np.testing.assert_allclose(np.linalg.norm(ring0, axis=1), 0.005)


def test_duplicated_segments_make_coincident_tubes():
    sk = make_skeleton([[0, 0, 0], [0, 0, 0]], [[0, 1, 0], [0, 1, 0]], 0.1, parent=[-1, -1])
    tubes = sweep(sk)
    assert len(tubes) == 2
    np.testing.assert_array_equal(tubes.points[: len(tubes.points) // 2], tubes.points[len(tubes.points) // 2 :])
    tubes_closed(tubes)


def test_gap_in_a_chain_splits_without_extension():
    # a segment whose parent ends elsewhere (turtle moves with f break parents, but be safe)
    sk = make_skeleton([[0, 0, 0], [0, 2, 0]], [[0, 1, 0], [0, 3, 0]], 0.1, parent=[-1, 0])
    tubes = sweep(sk)
    assert len(tubes) == 2
    assert tubes.points[:, 1].max() == pytest.approx(3.0)


@pytest.mark.parametrize(
    "bad",
    [
        {"sides": 2},
        {"sides": 8.5},
        {"min_width": 0},
        {"max_bend": 180},
        {"min_length": -1},
        {"merge_angle": float("nan")},
        {"sides_step": True},
        {"merge_deviation": -0.1},
        {"merge_deviation": 0.6},
    ],
)
def test_bad_options(bad):
    with pytest.raises(ValueError, match="SweepOptions"):
        SweepOptions(**bad)


def test_select_round_trip():
    tubes = sweep(random_small_tree(np.random.default_rng(0), 30))
    part = tubes.select([2, 0])
    assert len(part) == 2
    np.testing.assert_array_equal(part.mesh(0).faces, tubes.mesh(2).faces)
    np.testing.assert_allclose(part.mesh(1).vertices, tubes.mesh(0).vertices)
    counts_ok(part)
