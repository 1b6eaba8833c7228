"""Union: watertight, consistently oriented, volume-bounded; attributes carried; errors raised."""

from __future__ import annotations

import math
import re
import sys

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from skeletons import make_skeleton

import lsys3d
from lsys3d.errors import GeometryError
from lsys3d.mesh.sweep import SweepOptions, Tubes, sweep
from lsys3d.mesh.sweep.tubes import _concat
from lsys3d.mesh.union.union import UnionOptions, _manifold, concatenate, may_touch, union
from lsys3d.turtle.skeleton import Skeleton


def random_tree(seed: int, n: int, spread: float = 0.5, width: float = 0.12) -> Skeleton:
    """``n`` segments, each starting at the end of a random earlier one."""
    rng = np.random.default_rng(seed)
    start, end, par, order = [np.zeros(3)], [np.array([0.0, 1.0, 0.0])], [-1], [0]
    for i in range(1, n):
        p = int(rng.integers(0, i))
        d = end[p] - start[p]
        d = d / np.linalg.norm(d) + rng.normal(scale=spread, size=3)
        start.append(end[p])
        end.append(end[p] + rng.uniform(0.05, 0.8) * d / np.linalg.norm(d))
        par.append(p)
        order.append(order[p] + int(rng.random() < 0.5))
    w = width * 0.85 ** np.array(order)
    return make_skeleton(start, end, w, w * rng.uniform(0.3, 1.0, n), par, order)


def chainy_tree(seed: int, n: int) -> Skeleton:
    """Gently curving, tapering chains of 3-9 segments with a branch at some joints (most spans touch nothing)."""
    rng = np.random.default_rng(seed)
    start, end, w0, w1, par, order = [], [], [], [], [], []
    queue = [(np.zeros(3), np.array([0.0, 1.0, 0.0]), 0.3, 1.0, 0, -1)]
    while queue and len(start) < n:
        p, d, w, step, o, parent = queue.pop(0)
        m = int(rng.integers(3, 10))
        widths = np.linspace(w, 0.5 * w, m + 1)
        for i in range(min(m, n - len(start))):
            d = d + rng.normal(scale=0.08, size=3)
            d /= np.linalg.norm(d)
            q = p + step * d
            start.append(p), end.append(q), w0.append(widths[i]), w1.append(widths[i + 1])
            par.append(parent), order.append(o)
            parent = len(start) - 1
            if i < m - 1 and rng.random() < 0.35:
                side = np.cross(d, rng.normal(size=3))
                cd = d + 1.2 * side / np.linalg.norm(side)
                queue.append((q, cd / np.linalg.norm(cd), 0.6 * widths[i + 1], 0.8 * step, o + 1, parent))
            p = q
    return make_skeleton(start, end, w0, w1, par, order)


def y_junction() -> Skeleton:
    return make_skeleton(
        start=[[0, 0, 0], [0, 1, 0], [0, 1, 0]],
        end=[[0, 1, 0], [0.6, 1.8, 0], [-0.6, 1.8, 0.1]],
        width_start=[0.2, 0.12, 0.1],
        width_end=[0.15, 0.05, 0.05],
        parent=[-1, 0, 0],
        order=[0, 1, 1],
    )


# ---------------------------------------------------------------- checks


def check_union(tubes: Tubes, mesh):
    """The contract of every union result."""
    assert mesh.is_watertight
    assert mesh.is_winding_consistent
    assert mesh.volume > 0
    assert mesh.volume <= tubes.volumes().sum() * (1 + 1e-5)
    # float32 positions in manifold: the union is at least as big as its largest tube
    assert mesh.volume >= tubes.volumes().max() * (1 - 1e-4)
    # welded by manifold's topology (two sheets that only touch may keep two vertices
    # at one place), and no vertex left unused
    assert len(np.unique(mesh.faces)) == len(mesh.vertices)
    n = mesh.normals
    uv = mesh.uv
    assert n.shape == (len(mesh.faces), 3, 3) and n.dtype == np.float32
    assert uv.shape == (len(mesh.faces), 3, 2) and uv.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(n, axis=2), 1.0, atol=1e-5)
    # u runs over whole tiles around each tube (Tubes.tiles), caps around its middle
    assert uv[:, :, 0].min() >= -1e-6 and uv[:, :, 0].max() <= tubes.tiles.max() + 1e-5
    # smooth normals still point out of their faces (slivers have no normal to compare)
    scale = np.linalg.norm(np.ptp(mesh.vertices, axis=0))
    big = mesh.face_areas > 1e-9 * scale**2
    facing = np.einsum("fcj,fj->fc", n[big], mesh.face_normals[big])
    assert np.mean(facing > 0) > 0.97
    check_face_source(tubes, mesh)


def _segment_distance(p, a, b):
    """Distance of points ``p`` (n, 3) from segments ``a - b``."""
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-300), 0.0, 1.0)
    return np.linalg.norm(p - (a + t[:, None] * ab), axis=1)


def triangle_distance(p, tri):
    """Distance of points ``p`` (n, 3) from the triangles ``tri`` (n, 3, 3)."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    n = np.cross(b - a, c - a)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    height = np.einsum("ij,ij->i", p - a, n)
    q = p - height[:, None] * n
    inside = np.ones(len(p), bool)
    for u, v in ((a, b), (b, c), (c, a)):
        inside &= np.einsum("ij,ij->i", np.cross(v - u, q - u), n) >= 0
    edge = np.min([_segment_distance(p, u, v) for u, v in ((a, b), (b, c), (c, a))], axis=0)
    return np.where(inside, np.abs(height), edge)


def check_face_source(tubes: Tubes, mesh):
    """Every face names the tube face it is a piece of: in range, on that face's plane, near that face."""
    src = mesh.face_source
    assert src is not None and src.shape == (len(mesh.faces),)
    assert src.min(initial=0) >= 0 and src.max(initial=0) < len(tubes.faces)  # no temporary cap survives
    tube = np.searchsorted(tubes.face_offsets, src, side="right") - 1
    radius = np.maximum.reduceat(tubes.ring_radius, tubes.ring_offsets[:-1])[tube]
    side = 2 * radius * np.sin(np.pi / tubes.sides[tube])
    source = tubes.points[tubes.face_points[src]]
    corners = mesh.vertices[mesh.faces]
    # within the tube's radius and side of its source face (a piece of a span split by new rings lies in the
    # span's quad); where coplanar tubes cross (flat presets) manifold3d names a far face for a handful of
    # triangles, and the union's repair from their neighbours leaves a few (tree: 7 of 279,780)
    far = triangle_distance(corners.mean(axis=1), source) > radius + side
    assert far.mean() <= 1e-4 or (len(far) < 1e4 and far.sum() <= 1)
    # and on its plane: a boolean cuts a face, it does not move it (float32 and the union's separations aside)
    normal = np.cross(source[:, 1] - source[:, 0], source[:, 2] - source[:, 0])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    off_plane = np.abs(np.einsum("fcj,fj->fc", corners - source[:, :1], normal)).max(axis=1)
    scale = np.abs(tubes.points).max() + 1.0
    assert (off_plane <= 1e-5 * scale + 1e-3 * radius).mean() > 0.999


SYNTHETIC = {
    "single": make_skeleton([[0, 0, 0]], [[0, 1, 0]], 0.1),
    "y-junction": y_junction(),
    "crossing": make_skeleton([[-1, 0, 0], [0, -1, 0.01]], [[1, 0, 0], [0, 1, 0.01]], 0.2, parent=[-1, -1]),
    "disjoint": make_skeleton([[0, 0, 0], [5, 0, 0]], [[0, 1, 0], [5, 1, 0]], 0.1, parent=[-1, -1]),
    "coincident": make_skeleton([[0, 0, 0], [0, 0, 0]], [[0, 1, 0], [0, 1, 0]], 0.1, parent=[-1, -1]),
    "elbow-split": make_skeleton([[0, 0, 0], [0, 1, 0]], [[0, 1, 0], [0.17, 0.02, 0]], 0.1),
    "star": make_skeleton(
        np.zeros((12, 3)),
        [[math.cos(a) * math.sin(b), math.cos(b), math.sin(a) * math.sin(b)] for a in range(4) for b in (0.5, 1.2, 2)],
        0.15,
        parent=[-1] * 12,
    ),
    "random-40": random_tree(1, 40),
    "random-200": random_tree(2, 200, spread=0.3),
    "chainy-300": chainy_tree(4, 300),
}


@pytest.mark.parametrize("name", list(SYNTHETIC))
@pytest.mark.parametrize("layers", [True, False])
def test_synthetic_unions(name, layers):
    tubes = sweep(SYNTHETIC[name])
    mesh = union(tubes, UnionOptions(layers=layers))
    check_union(tubes, mesh)


def test_degenerate_skeleton_unions():
    # zero-length segments, zero widths and a duplicated branch in one tree
    sk = make_skeleton(
        start=[[0, 0, 0], [0, 1, 0], [0, 1, 0], [0, 1, 0], [0, 1, 0], [0, 1, 0]],
        end=[[0, 1, 0], [0, 1, 0], [0, 2, 0], [0.5, 1.5, 0], [0.5, 1.5, 0], [-0.5, 1.5, 0]],
        width_start=[0.2, 0.2, 0.0, 0.08, 0.08, 0.0],
        parent=[-1, 0, 1, 0, 0, 0],
        order=[0, 0, 0, 1, 1, 1],
    )
    tubes = sweep(sk)
    check_union(tubes, union(tubes))


def test_disjoint_tubes_keep_their_volume():
    tubes = sweep(SYNTHETIC["disjoint"])
    mesh = union(tubes)
    assert mesh.volume == pytest.approx(tubes.volumes().sum(), rel=1e-5)
    assert len(mesh.faces) == len(tubes.faces)  # two untouched tubes


def test_coincident_tubes_count_once():
    tubes = sweep(SYNTHETIC["coincident"])
    assert union(tubes).volume == pytest.approx(tubes.volumes()[0], rel=1e-5)


def test_layered_and_plain_unions_agree():
    tubes = sweep(random_tree(5, 120))
    a = union(tubes, UnionOptions(layers=True))
    b = union(tubes, UnionOptions(layers=False))
    assert a.volume == pytest.approx(b.volume, rel=1e-5)


def test_fewer_sides_for_twigs():
    tubes = sweep(random_tree(6, 80), SweepOptions(sides=8, sides_step=2, min_sides=4))
    assert set(tubes.sides.tolist()) > {8}
    check_union(tubes, union(tubes))


def test_local_path_stitches_free_spans(caplog):
    tubes = sweep(chainy_tree(11, 400))
    with caplog.at_level("DEBUG", logger="lsys3d"):
        local = union(tubes)
    assert "pieces in" in caplog.text  # the junction-only boolean ran and stitched
    check_union(tubes, local)
    whole = union(tubes, UnionOptions(local=False))
    assert local.volume == pytest.approx(whole.volume, rel=1e-6)
    assert local.area == pytest.approx(whole.area, rel=1e-5)


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 120), sides=st.integers(3, 9))
def test_any_local_union_is_watertight_or_raises(seed, n, sides):
    tubes = sweep(chainy_tree(seed, n), SweepOptions(sides=sides))
    try:
        mesh = union(tubes, UnionOptions(local_max=1.0))
    except GeometryError:
        return
    check_union(tubes, mesh)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(1, 40),
    spread=st.floats(0.0, 3.0),
    width=st.floats(0.0, 0.5),
    sides=st.integers(3, 10),
)
def test_any_union_is_watertight_or_raises(seed, n, spread, width, sides):
    tubes = sweep(random_tree(seed, n, spread, width), SweepOptions(sides=sides))
    try:
        mesh = union(tubes, UnionOptions(local_max=1.0))
    except GeometryError:
        return
    check_union(tubes, mesh)


# ---------------------------------------------------------------- tube soup


def test_concatenate_keeps_every_tube():
    tubes = sweep(random_tree(3, 30))
    soup = concatenate(tubes)
    assert len(soup.faces) == len(tubes.faces)
    assert len(soup.vertices) == len(tubes.points)
    assert soup.is_watertight and soup.is_winding_consistent
    assert soup.volume == pytest.approx(tubes.volumes().sum())
    assert soup.normals.shape == (len(soup.faces), 3, 3)
    assert soup.uv.dtype == np.float32


# ---------------------------------------------------------------- touch test


def test_may_touch_pairs_neighbours_only():
    sk = make_skeleton(
        [[0, 0, 0], [0, 1, 0], [10, 0, 0]], [[0, 1, 0], [1, 2, 0], [10, 1, 0]], 0.1, parent=[-1, 0, -1], order=[0, 1, 0]
    )
    tubes = sweep(sk)
    # chain 0: segments 0 and 1 (one chain), chain 1: segment 2 far away
    assert len(tubes) == 2
    assert may_touch(tubes).tolist() == []
    tubes = sweep(y_junction())
    assert may_touch(tubes).tolist() == [[0, 1]]


def test_may_touch_never_misses_a_real_overlap():
    tubes = sweep(random_tree(7, 150, spread=1.0))
    pairs = {tuple(p) for p in may_touch(tubes).tolist()}
    boxes = tubes.bounds()
    solids = [_manifold(tubes.select([i]), "test") for i in range(len(tubes))]
    checked = 0
    for i in range(len(tubes)):
        for j in range(i + 1, len(tubes)):
            overlap = (boxes[i, 0] <= boxes[j, 1]).all() and (boxes[j, 0] <= boxes[i, 1]).all()
            if overlap and (i, j) not in pairs:
                checked += 1
                assert (solids[i] ^ solids[j]).volume() == 0, (i, j)
    assert checked > 0  # the span test is finer than the tube boxes
    # every parent-child junction is a pair (a chain split at a sharp bend has several tubes)
    sk = random_tree(7, 150, spread=1.0)
    chain_of = sk.chains.chain_of
    for s in range(len(sk)):
        p = sk.parent[s]
        if p >= 0 and chain_of[s] != chain_of[p]:
            mine = np.flatnonzero(tubes.chain == chain_of[s])
            theirs = np.flatnonzero(tubes.chain == chain_of[p])
            assert any((min(a, b), max(a, b)) in pairs for a in mine for b in theirs)


# ---------------------------------------------------------------- errors


def test_no_tubes_raises():
    with pytest.raises(GeometryError, match="no tubes"):
        union(Tubes.empty())


def test_broken_tube_raises_with_status():
    tubes = sweep(SYNTHETIC["single"])
    faces = tubes.faces.copy()
    faces[0] = faces[0, [0, 2, 1]]  # one face turned inside out: not a manifold
    broken = Tubes(**{**{f: getattr(tubes, f) for f in tubes.__dataclass_fields__}, "faces": faces})
    with pytest.raises(GeometryError, match=r"union: layer 0: manifold3d reported NotManifold"):
        union(broken)


def test_non_finite_tube_raises():
    tubes = sweep(SYNTHETIC["single"])
    points = tubes.points.copy()
    points[0] = np.nan
    broken = Tubes(**{**{f: getattr(tubes, f) for f in tubes.__dataclass_fields__}, "points": points})
    with pytest.raises(GeometryError, match=r"union: tube 0 \(chain 0\) has a point that is not a finite number"):
        union(broken)


# ---------------------------------------------------------------- presets (when the turtle is there)

try:
    from lsys3d.turtle import interpret
except ImportError:  # pragma: no cover - the turtle lands separately
    interpret = None

PRESETS_3D = ["monopodial", "ternary", "bush", "hilbert3d", "abop-1.24a", "abop-1.24c", "abop-1.24e", "abop-1.24f"]


@pytest.mark.skipif(interpret is None, reason="lsys3d.turtle not available")
@pytest.mark.parametrize("name", PRESETS_3D)
def test_presets_union(name):
    g = lsys3d.load_preset(name)
    sk = interpret(lsys3d.derive(g), g)
    tubes = sweep(sk)
    mesh = union(tubes)
    check_union(tubes, mesh)


def _face_touching_boxes(gap: float):
    """Two closed boxes in one mesh, the second starting ``gap`` beyond the first's x = 1 face."""
    from lsys3d.mesh.mesh import Mesh

    return Mesh.concatenate([Mesh.box((0, 0, 0), (1, 1, 1)), Mesh.box((1 + gap, 0, 0), (2, 1, 1))])


@pytest.mark.parametrize("gap", [1e-9, 0.0])
def test_vertices_a_weld_would_break_are_moved_apart(gap):
    """Faces that touch: merging their float32-equal corners would give edges four faces, so they part."""
    import sys

    import trimesh

    weld = sys.modules["lsys3d.mesh.union.weld"]._weld_float32
    mesh = _face_touching_boxes(gap)
    out = weld([mesh])
    v32 = np.asarray(out.vertices, np.float32)
    assert len(out.vertices) == 16 and np.array_equal(out.faces, mesh.faces)
    assert len(np.unique(v32, axis=0)) == 16
    moved = np.abs(out.vertices - mesh.vertices).max(axis=1)
    assert (moved > 0).sum() == 4 and moved.max() < 1e-6  # the second box's four corners at x = 1, a step or two
    assert out.is_watertight and out.is_winding_consistent
    welded = trimesh.Trimesh(v32.astype(np.float64), out.faces, process=False)
    welded.merge_vertices()
    assert len(welded.vertices) == 16 and welded.is_watertight
    assert weld([_face_touching_boxes(1e-3)]).vertices.tolist() == _face_touching_boxes(1e-3).vertices.tolist()


def test_regrouping_only_moved_vertices_finds_the_same_owners():
    """_owners with the rows that may collide listed gives first_equal_row's answer; so does the separation."""
    from lsys3d.arrays import first_equal_row

    mod = sys.modules["lsys3d.mesh.union.weld"]
    rng = np.random.default_rng(7)
    keys = rng.integers(0, 12, (2000, 3))
    full = first_equal_row(keys)
    dirty = np.flatnonzero(full != np.arange(len(keys)))  # the later copies; their owners are distinct
    assert len(dirty) > 100
    assert np.array_equal(mod._owners(keys, dirty), full)
    assert np.array_equal(mod._owners(keys, np.arange(len(keys))), full)
    distinct = np.unique(keys, axis=0)
    assert np.array_equal(mod._owners(distinct, np.zeros(0, np.int64)), np.arange(len(distinct)))

    # crowded vertices: exact duplicates and 1e-9 neighbours near the origin, where float32 steps are < 1e-8
    v = rng.random((3000, 3)) * 0.05
    v[:200] = v[200:400]
    v[400:600] = v[600:800] + rng.normal(0, 1e-9, (200, 3))
    tri = np.array([[0, 1, 2]])
    mesh = lsys3d.Mesh(v, tri, np.tile([0, 0, 1.0], (1, 3, 1)), np.zeros((1, 3, 2)))
    out = mod._separate_float32(mesh)
    assert not np.array_equal(out.vertices, v)
    v32 = out.vertices.astype(np.float32)
    assert len(np.unique(v32, axis=0)) == len(v)
    assert len(np.unique(np.round(v32.astype(np.float64) * 1e8), axis=0)) == len(v)
    # what the weld hands on (no float32 position twice) is told apart the same way, one grouping fewer
    unique32 = v.astype(np.float32).astype(np.float64)
    keep = np.unique(unique32, axis=0, return_index=True)[1]
    welded = lsys3d.Mesh(unique32[np.sort(keep)], tri, mesh.normals, mesh.uv)
    assert np.array_equal(
        mod._separate_float32(welded, float32_unique=True).vertices, mod._separate_float32(welded).vertices
    )


def test_union_normals_have_no_negative_zero():
    """The exporter uses the union's corner normals without a copy only when no -0.0 needs folding."""
    sk = make_skeleton([[0, 0, 0], [0, 1, 0]], [[0, 1, 0], [0.3, 1.8, 0]], 0.1, parent=[-1, 0])  # had -0.0 before
    mesh = union(sweep(sk, SweepOptions(sides=8)))
    assert mesh.is_watertight
    assert not (mesh.normals.view(np.uint32) == 0x80000000).any()


# ---------------------------------------------------------------- at scale: culling, refinement, repeats, workers


def whorl(n: int, width: float = 0.08, length: float = 0.6) -> Skeleton:
    """A trunk and ``n`` branches from one node of it (a crowded junction)."""
    k = np.arange(n) + 0.5
    phi = np.arccos(1 - k / n)  # the upper half sphere
    th = np.pi * (1 + 5**0.5) * k
    d = np.stack([np.cos(th) * np.sin(phi), np.cos(phi), np.sin(th) * np.sin(phi)], axis=1)
    node = np.array([0.0, 1.0, 0.0])
    start = np.concatenate([[[0.0, 0.0, 0.0], node], np.tile(node, (n, 1))])
    end = np.concatenate([[node, [0.0, 2.0, 0.0]], node + length * d])
    w = np.concatenate([[0.2, 0.2], np.full(n, width)])
    return make_skeleton(start, end, w, parent=[-1, 0, *[0] * n], order=[0, 0, *[1] * n])


def test_fifty_branches_at_one_node_stay_closed():
    tubes = sweep(whorl(50))
    mesh = union(tubes)
    check_union(tubes, mesh)
    from lsys3d.stats import components

    assert components(mesh.faces, len(mesh.vertices)) == 1


def test_a_twig_buried_in_its_parent_stays_out_and_changes_nothing(caplog):
    # a short thin twig whose every point lies inside the trunk, and one that pokes out
    sk = make_skeleton(
        [[0, 0, 0], [0, 0.5, 0], [0, 0.5, 0]],
        [[0, 1, 0], [0.02, 0.55, 0.0], [0.5, 0.9, 0]],
        [0.3, 0.05, 0.05],
        parent=[-1, 0, 0],
        order=[0, 1, 1],
    )
    tubes = sweep(sk)
    from lsys3d.mesh.union.touch import buried_tubes, pieces, touching

    pcs = pieces(tubes)
    buried = buried_tubes(tubes, pcs, *touching(pcs))
    assert buried.tolist() == [False, True, False]
    with caplog.at_level("DEBUG", logger="lsys3d"):
        mesh = union(tubes)
    assert "1 tubes buried inside another left out" in caplog.text
    check_union(tubes, mesh)
    without = union(tubes.select([0, 2]))
    assert mesh.volume == pytest.approx(without.volume, rel=1e-9)
    assert len(mesh.faces) == len(without.faces)


def test_coincident_branches_are_unioned_once(caplog):
    sk = make_skeleton(np.zeros((300, 3)), np.tile([[0.0, 1.0, 0.0]], (300, 1)), 0.1, parent=[-1] * 300)
    tubes = sweep(sk)
    with caplog.at_level("DEBUG", logger="lsys3d"):
        mesh = union(tubes)
    assert "299 tubes equal to another left out" in caplog.text
    assert mesh.volume == pytest.approx(tubes.volumes()[0], rel=1e-9)
    assert len(mesh.faces) == len(tubes.faces) // 300


def test_a_crowd_of_branches_is_refused_up_front():
    # 1,000 branches from one point: half a million touching pairs, minutes of boolean work
    k = np.arange(1000) + 0.5
    phi, th = np.arccos(1 - 2 * k / 1000), np.pi * (1 + 5**0.5) * k
    d = np.stack([np.cos(th) * np.sin(phi), np.cos(phi), np.sin(th) * np.sin(phi)], axis=1)
    tubes = sweep(make_skeleton(np.zeros((1000, 3)), d, 0.1, parent=[-1] * 1000))
    with pytest.raises(lsys3d.LimitError, match=r"union: more than 400,000 pairs of tube pieces .*--max-union-pairs"):
        union(tubes)
    with pytest.raises(lsys3d.LimitError, match=r"more than 50 pairs .* over 0 s\)"):
        union(tubes.select(np.arange(20)), UnionOptions(max_pairs=50))


def test_long_straight_spans_get_rings_around_their_junctions_only(caplog):
    # a trunk of 40 unit segments (one straight span) with twigs at 5, 20 and 35
    n = 40
    trunk_start = [[0.0, float(i), 0.0] for i in range(n)]
    trunk_end = [[0.0, float(i + 1), 0.0] for i in range(n)]
    twigs = [5, 20, 35]
    start = trunk_start + [trunk_end[i - 1] for i in twigs]
    end = trunk_end + [[0.6, float(i) + 0.8, 0.0] for i in twigs]
    sk = make_skeleton(
        start,
        end,
        [0.06] * n + [0.04] * 3,
        parent=[-1, *range(n - 1), *[i - 1 for i in twigs]],
        order=[0] * n + [1] * 3,
    )
    tubes = sweep(sk)
    assert tubes.rings.tolist() == [2, 2, 2, 2]  # the trunk is one span
    with caplog.at_level("DEBUG", logger="lsys3d"):
        mesh = union(tubes)
    assert "6 rings inserted around touched stretches" in caplog.text  # two on each side of each junction
    check_union(tubes, mesh)
    whole = union(tubes, UnionOptions(local=False))
    assert mesh.volume == pytest.approx(whole.volume, rel=1e-9)
    assert mesh.area == pytest.approx(whole.area, rel=1e-9)


def test_inserted_rings_lie_on_a_straight_wall():
    tubes = sweep(make_skeleton([[0, 0, 0], [0, 1, 0]], [[0, 1, 0], [0, 3, 0]], [0.3, 0.25], [0.25, 0.15]))
    assert tubes.rings.tolist() == [2]
    more = tubes.insert_rings(np.array([0, 0]), np.array([0, 0]), np.array([0.2, 0.7]))
    assert more.rings.tolist() == [4]
    assert more.mesh().is_watertight and more.mesh().is_winding_consistent
    assert more.volumes()[0] == pytest.approx(tubes.volumes()[0], rel=1e-12)
    assert np.array_equal(more.points[:8], tubes.points[:8])  # the old rings keep their exact points
    from lsys3d.mesh.union.touch import straight_spans

    assert straight_spans(more, [0, 0, 0], [0, 1, 2]).tolist() == [True, True, True]
    bent = sweep(make_skeleton([[0, 0, 0], [0, 1, 0]], [[0, 1, 0], [0.5, 1.8, 0]], 0.1))
    assert straight_spans(bent, [0, 0], [0, 1]).tolist() == [False, False]


def plant(n: int):
    g = lsys3d.Grammar(axiom="X", rules=["X -> F[!+X][!&X]F[!-X]/X", "F -> FF"], angle=22.5, iterations=n)
    return interpret(lsys3d.derive(g), g)


@pytest.mark.skipif(interpret is None, reason="lsys3d.turtle not available")
def test_repeated_junctions_are_unioned_once_and_copied_exactly(caplog, monkeypatch):
    # without the plant's roll (/): the texture seam runs along the top of every branch (the world's +Y,
    # lsys3d.mesh.sweep.frames._seam_side), so a junction rolled about its parent is no rigid copy of another, its
    # rings' vertices lie elsewhere (with the roll 111 of 150 clusters go through the boolean)
    g = lsys3d.Grammar(axiom="X", rules=["X -> F[!+X][!&X]F[!-X]X", "F -> FF"], angle=22.5, iterations=5)
    tubes = sweep(interpret(lsys3d.derive(g), g))
    with caplog.at_level("DEBUG", logger="lsys3d"):
        mesh = union(tubes)
    clusters, unioned = map(int, re.search(r"(\d+) clusters \((\d+) unioned", caplog.text).groups())
    assert unioned < clusters / 2
    check_union(tubes, mesh)
    from lsys3d.mesh.union import repeats

    find = repeats.find

    def no_repeats(*args):
        found = find(*args)
        found.rep = np.arange(len(found))
        found.shift[:] = 0.0
        return found

    monkeypatch.setattr(repeats, "find", no_repeats)
    each = union(tubes)
    assert len(mesh.faces) == len(each.faces)
    assert mesh.volume == pytest.approx(each.volume, rel=1e-9)
    assert mesh.area == pytest.approx(each.area, rel=1e-9)

    # the copies' corners carry the copies' own texture coordinates: the same range of (u, v) at every position
    def uv_range_by_position(m):
        key = np.ascontiguousarray(m.vertices[m.faces].reshape(-1, 3)).view(np.dtype((np.void, 24))).ravel()
        uv = m.uv.reshape(-1, 2).astype(np.float64)
        positions, which = np.unique(key, return_inverse=True)
        lo = np.full((len(positions), 2), np.inf)
        hi = np.full((len(positions), 2), -np.inf)
        np.minimum.at(lo, which.ravel(), uv)
        np.maximum.at(hi, which.ravel(), uv)
        return positions, lo, hi

    (pa, la, ha), (pb, lb, hb) = uv_range_by_position(mesh), uv_range_by_position(each)
    common, ia, ib = np.intersect1d(pa, pb, return_indices=True)
    assert len(common) > len(mesh.vertices) / 2
    np.testing.assert_allclose(la[ia], lb[ib], atol=1e-5)
    np.testing.assert_allclose(ha[ia], hb[ib], atol=1e-5)


@pytest.mark.skipif(interpret is None, reason="lsys3d.turtle not available")
def test_the_result_does_not_depend_on_the_number_of_workers(monkeypatch, caplog):
    from lsys3d.mesh.union import jobs as union_jobs

    monkeypatch.setattr(union_jobs, "POOL_MIN_TRIANGLES", 1)  # worker processes even for a small union
    monkeypatch.setattr(sys.modules["lsys3d.mesh.union.plan"], "_JOB_TRIANGLES", 300)  # and several jobs
    tubes = sweep(random_tree(8, 150, spread=0.4))

    def digest(m):
        arrays = (m.vertices, m.faces, m.normals, m.uv)
        return [np.ascontiguousarray(a).tobytes() for a in arrays]

    one = union(tubes, UnionOptions(workers=1, local=False))
    with caplog.at_level("DEBUG", logger="lsys3d"):
        two = union(tubes, UnionOptions(workers=2, local=False))
    assert re.search(r"in \d+ jobs, 2 workers", caplog.text)
    assert digest(one) == digest(two)
    check_union(tubes, two)


@pytest.mark.skipif(interpret is None, reason="lsys3d.turtle not available")
def test_inner_merges_run_in_the_job_of_their_halves(monkeypatch):
    # a crowded cluster split into leaves: the merges of up to a quarter of the work are done in the leaves' job
    from lsys3d.mesh.union import jobs as union_jobs

    monkeypatch.setattr(sys.modules["lsys3d.mesh.union.plan"], "_JOB_TRIANGLES", 300)
    tubes = sweep(random_tree(8, 150, spread=0.4))
    plans = []
    real_plan = union_jobs.plan

    def spy(*args, **kw):
        plans.append(real_plan(*args, **kw))
        return plans[-1]

    monkeypatch.setattr(union_jobs, "plan", spy)
    with_inner = union(tubes, UnionOptions(workers=1, local=False))
    jobs = plans[-1]
    total = jobs.weight[: len(jobs.leaves)].sum()
    merge_weight = jobs.weight[len(jobs.leaves) :]
    assert jobs.inner.any() and not jobs.inner.all()
    assert np.array_equal(jobs.inner, merge_weight <= total / 4)
    for k, (x, y) in enumerate(jobs.merges):  # the halves of an inner merge are inner too
        for child in (x, y):
            if jobs.inner[k] and child >= len(jobs.leaves):
                assert jobs.inner[child - len(jobs.leaves)]

    # the same plan with every merge going out as a mesh: the same solid
    monkeypatch.setattr(union_jobs, "plan", lambda *args, **kw: real_plan(*args, **{**kw, "job": 0.0}))
    without = union(tubes, UnionOptions(workers=1, local=False))
    check_union(tubes, with_inner)
    assert with_inner.volume == pytest.approx(without.volume, rel=1e-9)
    assert with_inner.area == pytest.approx(without.area, rel=1e-6)

    # run() runs one job per leaf or merge that is not a half of an inner merge (the same bytes again)
    ran = []
    real_run_job = union_jobs.run_job
    monkeypatch.setattr(union_jobs, "run_job", lambda *args: ran.append(args) or real_run_job(*args))
    monkeypatch.setattr(union_jobs, "plan", lambda *args, **kw: jobs)
    again = union(tubes, UnionOptions(workers=1, local=False))
    assert len(ran) == len(jobs.weight) - 2 * int(jobs.inner.sum())  # each inner merge takes in its two halves
    assert any(tree for _, _, tree in ran)
    assert np.array_equal(again.vertices, with_inner.vertices) and np.array_equal(again.faces, with_inner.faces)


def test_plan_splits_a_crowded_cluster_into_leaves_of_its_own_size():
    from lsys3d.mesh.union import jobs as union_jobs

    # a chain of 64 touching items (one crowded cluster) and 20 lone ones, 10 triangles each
    n = 84
    weight = np.full(n, 10.0)
    centre = np.stack([np.arange(n, dtype=float), np.zeros(n), np.zeros(n)], axis=1)
    a, b = np.arange(63), np.arange(1, 64)
    jobs = union_jobs.plan(weight, centre, a, b, target=100.0, job=160.0, leaf=40.0)
    sizes = [weight[items].sum() for items in jobs.leaves]
    crowded = [s for items, s in zip(jobs.leaves, sizes, strict=True) if items.max() < 64]
    packed = [s for items, s in zip(jobs.leaves, sizes, strict=True) if items.min() >= 64]
    assert max(crowded) <= 40 and min(crowded) > 10  # 640 triangles halved (at the median) down to 40 at most
    assert packed == [100.0, 100.0]  # lone items are still packed to the target
    assert sorted(np.concatenate(jobs.leaves).tolist()) == list(range(n))
    assert len(jobs.merges) == len(crowded) - 1 and len(jobs.weight) - 1 in jobs.roots
    merge_weight = jobs.weight[len(jobs.leaves) :]
    assert np.array_equal(jobs.inner, merge_weight <= 160)
    assert jobs.inner.any() and not jobs.inner.all() and merge_weight[-1] == 640  # the top merges go out
    assert union_jobs.plan(weight, centre, a, b, target=100.0).inner.sum() == 0  # by default none is inner


def test_a_failing_worker_job_raises_a_geometry_error(monkeypatch):
    from lsys3d.mesh.union import jobs as union_jobs

    monkeypatch.setattr(union_jobs, "POOL_MIN_TRIANGLES", 1)
    monkeypatch.setattr(sys.modules["lsys3d.mesh.union.plan"], "_JOB_TRIANGLES", 300)
    tubes = sweep(random_tree(8, 150, spread=0.4))
    faces = tubes.faces.copy()
    faces[0] = faces[0, [0, 2, 1]]
    broken = Tubes(**{**{f: getattr(tubes, f) for f in tubes.__dataclass_fields__}, "faces": faces})
    with pytest.raises(GeometryError, match=r"manifold3d reported NotManifold"):
        union(broken, UnionOptions(workers=2, local=False))


def test_progress_goes_from_0_to_1():
    seen = []
    union(sweep(chainy_tree(4, 300)), progress=seen.append)
    assert seen[0] == 0.0 and seen[-1] == 1.0
    assert seen == sorted(seen)


def test_union_options_are_checked():
    for bad in ({"workers": -1}, {"workers": 1.5}, {"max_pairs": 0}, {"max_pairs": True}):
        with pytest.raises(lsys3d.OptionsError, match="UnionOptions"):
            UnionOptions(**bad)


def test_the_worker_count_is_not_part_of_the_recipe():
    # how the work runs, not what it makes: the files' provenance is the same with any number of workers
    from lsys3d.pipeline import GenerateOptions

    assert "workers" not in UnionOptions(workers=3).plain()
    assert UnionOptions(max_pairs=7).plain()["max_pairs"] == 7
    assert GenerateOptions.from_flat(workers=1).plain() == GenerateOptions().plain()
    assert GenerateOptions.from_flat(workers=2, max_union_pairs=9).union.max_pairs == 9


@pytest.mark.skipif(interpret is None, reason="lsys3d.turtle not available")
@pytest.mark.parametrize("path", ["small", "jobs", "workers", "local", "culled"])
def test_face_source_names_the_tube_face_on_every_path(path, caplog, monkeypatch):
    """``Mesh.face_source`` on every path of the union, as the cleanup needs it (:func:`check_face_source`)."""
    tubes = sweep(plant(4))
    options = UnionOptions()
    if path == "small":  # every tube to manifold's own batch union
        options = UnionOptions(layers=False)
    elif path == "jobs":  # whole tubes in jobs
        options = UnionOptions(local=False)
    elif path == "workers":  # junction jobs in worker processes
        monkeypatch.setattr(sys.modules["lsys3d.mesh.union.jobs"], "POOL_MIN_TRIANGLES", 1)
        monkeypatch.setattr(sys.modules["lsys3d.mesh.union.plan"], "_JOB_TRIANGLES", 300)
        options = UnionOptions(workers=2)
    elif path == "culled":  # a tube given twice, and a twig buried in the trunk, left out of the boolean
        twig = make_skeleton([[0, 0.3, 0]], [[0, 0.34, 0.001]], 0.004)
        tubes = _concat([tubes.select([0, *range(len(tubes)), 0]), sweep(twig)])
    with caplog.at_level("DEBUG", logger="lsys3d"):
        mesh = union(tubes, options)
    check_union(tubes, mesh)
    log = caplog.text
    if path in ("local", "workers", "culled"):
        assert "clusters" in log and "rings inserted" in log
        clusters, unioned = map(int, re.search(r"(\d+) clusters \((\d+) unioned", log).groups())
        assert unioned < clusters  # some junctions are copies
        # untouched pieces stitched back: faces equal to their source face, corner for corner (those on spans
        # split by new rings are smaller than their source face)
        same = (mesh.vertices[mesh.faces] == tubes.points[tubes.face_points[mesh.face_source]]).all(axis=(1, 2))
        assert same.mean() > 0.05
    if path == "workers":
        assert re.search(r"jobs, [2-9] workers", log)
    if path == "culled":
        assert "2 tubes equal to another left out" in log and "1 tubes buried inside another left out" in log
        # the faces of tubes left out are never named: of equal tubes the first is unioned
        tube = np.searchsorted(tubes.face_offsets, mesh.face_source, side="right") - 1
        assert not np.isin([1, len(tubes) - 2, len(tubes) - 1], tube).any()


# ---------------------------------------------------------------- memory (issue 19): the same result, less held


@pytest.mark.parametrize("options", [UnionOptions(), UnionOptions(local=False), UnionOptions(layers=False)])
def test_without_corners_the_same_geometry(options):
    """``corners=False`` (the cleanup makes its own normals and uv) gives the same triangles on the same points
    with the same face sources (the points alone go through the boolean: they may come out in another order),
    and its zero normals and uv take no memory."""
    tubes = sweep(chainy_tree(11, 120))
    full, bare = union(tubes, options), union(tubes, options, corners=False)

    def triangles(mesh):  # each triangle's corners from its least one on, and its source: in one order
        corners = mesh.vertices[mesh.faces]
        first = np.array([min(range(3), key=lambda k: tuple(c[k])) for c in corners])
        turned = corners[np.arange(len(corners))[:, None], (first[:, None] + np.arange(3)) % 3]
        rows = np.concatenate([turned.reshape(len(corners), 9), mesh.face_source[:, None]], axis=1)
        return rows[np.lexsort(rows.T[::-1])]

    assert len(bare.vertices) == len(full.vertices)
    assert np.array_equal(triangles(bare), triangles(full))
    for name, shape in (("normals", (3, 3)), ("uv", (3, 2))):
        values = getattr(bare, name)
        assert values.shape == (len(bare.faces), *shape) and values.strides[0] == 0 and not values.any()
    assert np.abs(full.normals).sum() > 0


@pytest.mark.skipif(interpret is None, reason="lsys3d.turtle not available")
def test_repeated_junctions_found_the_same_a_block_at_a_time(monkeypatch):
    """repeats.find compares the shading of candidates a block at a time: the blocks' size changes nothing."""
    from lsys3d.mesh.union import repeats

    g = lsys3d.Grammar(axiom="X", rules=["X -> F[!+X][!&X]F[!-X]X", "F -> FF"], angle=22.5, iterations=4)
    tubes = sweep(interpret(lsys3d.derive(g), g))
    found = []
    find = repeats.find

    def spy(*args):
        found.append(find(*args))
        return found[-1]

    monkeypatch.setattr(repeats, "find", spy)
    whole = union(tubes)
    monkeypatch.setattr(repeats, "_CHECKED", 1)  # one candidate at a time
    blocks = union(tubes)
    a, b = found
    assert (a.rep != np.arange(len(a))).sum() > 10
    assert np.array_equal(a.rep, b.rep) and np.array_equal(a.shift, b.shift)
    for name in ("vertices", "faces", "normals", "uv", "face_source"):
        assert getattr(blocks, name).tobytes() == getattr(whole, name).tobytes()


def test_components_are_labelled_by_their_smallest_node():
    """Whatever the order of the edges: each node gets the smallest node it is connected to (a plain search)."""
    from lsys3d.arrays import components

    rng = np.random.default_rng(3)
    a, b = rng.integers(0, 5000, 4000), rng.integers(0, 5000, 4000)
    labels = components(5000, a, b)
    assert len(np.unique(labels)) > 1000
    order = rng.permutation(len(a))
    assert np.array_equal(components(5000, b[order], a[order].astype(np.int32)), labels)
    near = [[] for _ in range(5000)]
    for x, y in zip(a.tolist(), b.tolist(), strict=True):
        near[x].append(y)
        near[y].append(x)
    expected = np.full(5000, -1)
    for start in range(5000):  # in order: the first node met of each component is its smallest
        if expected[start] < 0:
            expected[start], stack = start, [start]
            while stack:
                for y in near[stack.pop()]:
                    if expected[y] < 0:
                        expected[y] = start
                        stack.append(y)
    assert np.array_equal(labels, expected)
    assert components(3, np.zeros(0, np.int64), np.zeros(0, np.int64)).tolist() == [0, 1, 2]


# ---------------------------------------------------------------- compiled helpers against plain numpy references


def _closed_by_sorting(faces, nverts, near=None):
    """Every directed edge once and its reverse once, by sorting the edges' keys (the plain numpy check)."""
    a, b = faces.ravel(), np.roll(faces, -1, axis=1).ravel()
    if near is not None:
        mine = near[a] | near[b]
        a, b = a[mine], b[mine]
    fwd, rev = np.sort(a * nverts + b), np.sort(b * nverts + a)
    return bool(not (fwd[1:] == fwd[:-1]).any() and np.array_equal(fwd, rev))


def test_closed_check_agrees_with_sorting_the_edges():
    from lsys3d.mesh.union.parts import _closed

    rng = np.random.default_rng(5)
    meshes = [lsys3d.union(sweep(random_tree(s, 12))) for s in range(3)]
    fan = np.array([[0, k, k + 1] for k in range(1, 40)] + [[0, 40, 1]])  # a vertex with 40 edges (sorted lists)
    fan = np.concatenate([fan, np.array([[41, k + 1, k] for k in range(1, 40)] + [[41, 1, 40]])])
    cases = [(fan, 42)] + [(m.faces, len(m.vertices)) for m in meshes]
    seen = set()
    for faces, nv in cases:
        flipped = faces.copy()
        flipped[0] = flipped[0, [1, 0, 2]]
        for f in (faces, faces[1:], faces[:, [0, 2, 1]], np.concatenate([faces, faces]), flipped):
            for near in (None, rng.random(nv) < 0.2, np.zeros(nv, bool)):
                want = _closed_by_sorting(f, nv, near)
                assert _closed(f, nv, near) == want
                seen.add(want)
    assert seen == {True, False}


def test_cap_points_match_each_ring_point_once_whatever_the_rotation():
    """The temporary caps' triangles come back from the boolean with their corners in any of three rotations, on
    points of their own numbering: each ring point is found on exactly one of them, by position."""
    from lsys3d.mesh.union.parts import _cap_points

    rng = np.random.default_rng(6)
    points = rng.normal(size=(6, 3))  # a ring of 6 tube points, one wedge each
    wedge_point = np.arange(6)
    cap_faces = np.array([[0, j, j + 1] for j in range(1, 5)])  # a fan from ring point 0
    nf = 10
    order = rng.permutation(6)  # the boolean's numbering of the points
    pos = np.empty((6, 3))
    pos[order] = points
    point_of = np.arange(6)
    tri = np.array([np.roll(order[f], r) for r, f in zip([0, 1, 2, 1], cap_faces, strict=True)])
    fid = nf + np.arange(4)

    def run(pos, tri):
        seam_of = np.full(6, -1, np.int64)
        return _cap_points(tri, fid, nf, point_of, pos, cap_faces, wedge_point, points, seam_of), seam_of

    ok, seam_of = run(pos, tri)
    assert ok and np.array_equal(seam_of, order)
    moved = pos.copy()
    moved[order[3], 1] += 1e-12  # a ring point the boolean moved: no rotation matches
    assert not run(moved, tri)[0]
    twice = pos.copy()
    twice[5] = twice[order[0]]  # a point at ring point 0's position too: a ring point matched twice, or none
    tri2 = tri.copy()
    tri2[0] = np.roll([5, order[1], order[2]], 0)
    assert not run(twice, tri2)[0]


def test_weld_cells_are_numpys_rounding():
    """The compiled grid cells of _separate_float32 are numpy's rounding (half to even) of the float32 positions
    scaled by 1e8, halves and signed zeros included."""
    from lsys3d.mesh.union.weld import _weld_cells

    rng = np.random.default_rng(1)
    for trial in range(30):
        scale = [1e-8, 0.5e-8, 1.5e-8, 0.3, 2.5e-8][trial % 5]
        v = (rng.integers(-50, 50, (2000, 3)) * scale).astype(np.float32)
        v[0] = [-0.0, 0.0, 2.5e-8]
        v[1] = [0.5e-8, -0.5e-8, 1.5e-8]
        assert np.array_equal(_weld_cells(v), np.round(v.astype(np.float64) * 1e8).astype(np.int64))


def test_corner_repair_and_float32_weld_kernels():
    from lsys3d.mesh.mesh import Mesh, face_normals
    from lsys3d.mesh.union.weld import _repair_corners, _welded_faces

    rng = np.random.default_rng(8)
    vertices = rng.normal(size=(30, 3))
    faces = rng.integers(0, 30, (40, 3))
    normals = rng.choice([0.0, -0.0, 1.0, -2.0, np.nan, np.inf], size=(40, 3, 3)).astype(np.float32)
    normals[0] = 0.0  # a zero normal is bad too
    uv = rng.choice([-0.0, 0.5, np.nan, -np.inf], size=(40, 3, 2)).astype(np.float32)
    bad = ~np.isfinite(normals).all(axis=2) | (normals == 0).all(axis=2)
    want = normals + np.float32(0.0)
    fn = np.nan_to_num(face_normals(vertices, faces).astype(np.float32))
    fn[np.abs(fn).sum(axis=1) == 0] = (0.0, 1.0, 0.0)
    want[bad] = np.broadcast_to(fn[:, None, :], want.shape)[bad] + np.float32(0.0)
    want_uv = np.where(np.isfinite(uv), uv, np.float32(0.0))
    mesh = Mesh(vertices, faces, normals, uv)
    _repair_corners(mesh)
    assert mesh.normals.tobytes() == want.tobytes() and mesh.uv.tobytes() == want_uv.tobytes()
    assert not np.signbit(mesh.normals[mesh.normals == 0]).any()

    point = rng.integers(0, 12, 30)  # the welded point of each vertex: many faces collapse
    welded, keep = _welded_faces(faces, point)
    p = point[faces]
    want_keep = (p[:, 0] != p[:, 1]) & (p[:, 1] != p[:, 2]) & (p[:, 2] != p[:, 0])
    assert np.array_equal(keep, want_keep) and np.array_equal(welded, p[want_keep]) and 0 < keep.sum() < 40


def test_crumbs_are_small_flat_closed_pieces():
    """A flat tetrahedron beside a box is a crumb, a small real box is not; inside out counts only when asked."""
    from lsys3d.mesh.mesh import Mesh, crumbs

    box = Mesh.box()
    far = box.vertices + 10.0
    flat = np.array([[0.0, 0, 0], [1e-3, 0, 0], [0, 1e-3, 0], [1e-3, 1e-3, 1e-12]]) + 5.0  # encloses ~nothing
    tetra = np.array([[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]])
    small = 0.01 * box.vertices - 5.0  # a real part, just small
    turned = box.faces[:, ::-1]  # an inside-out box: negative volume
    vertices = np.concatenate([box.vertices, flat, small, far])
    faces = np.concatenate([box.faces, tetra + 8, box.faces + 12, turned + 20])
    nb = len(box.faces)
    crumb = crumbs(vertices, faces, 1e-2)
    assert crumb[nb : nb + 4].all() and not crumb[:nb].any() and not crumb[nb + 4 :].any()
    # inside out: the turned box is flat by its signed volume, but too large a share of the area to go
    assert not crumbs(vertices, faces, 1e-2, inside_out=True)[-nb:].any()
    assert crumbs(vertices, faces, 0.5, inside_out=True)[-nb:].all()
    assert not crumbs(box.vertices, box.faces, 1.0).any()  # one piece: nothing to drop
