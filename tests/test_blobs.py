"""Blobs (lsys3d.mesh.union.blobs, issue 34): dense clusters of short tubes meshed as level sets."""

from __future__ import annotations

import numpy as np
import pytest
from skeletons import make_skeleton

import lsys3d
from lsys3d.mesh.sweep import sweep
from lsys3d.mesh.union.blobs import blob_clusters, level_set
from lsys3d.mesh.union.plan import _unique_pairs
from lsys3d.mesh.union.touch import pieces, touching
from lsys3d.mesh.union.union import UnionOptions, union

FERN = "tests/corpus/lpy/real/02-fractals_barnsleyfern.lpy"


@pytest.fixture(scope="module")
def fern():
    """L-Py's Barnsley-like fern cut to 8 generations: 9,840 segments in 2,187 tubes nested at every apex."""
    from lsys3d.pipeline import draw

    g = lsys3d.load(FERN)
    _, sk = draw(g, 8, g.seed)
    return sweep(sk)


@pytest.fixture(scope="module")
def fern_blobs(fern):
    """The fern's union with blobs (one worker): what three tests look at, computed once per module."""
    return union(fern, UnionOptions(blobs=0.25, max_pairs=10**8, workers=1))


#: The fern at 8 generations through generate with blobs (what two tests grow, with and without the cleanup).
FERN_OPTIONS = {"iterations": 8, "union_blobs": 0.25, "max_union_pairs": 10**8}


@pytest.fixture(scope="module")
def fern_cleaned():
    return lsys3d.generate(FERN, **FERN_OPTIONS).bark


@pytest.fixture(scope="module")
def fern_plain():
    return lsys3d.generate(FERN, cleanup=False, **FERN_OPTIONS).bark


def tube_pairs(tubes):
    pcs = pieces(tubes)
    a, b = touching(pcs, 0.01, 10**9)
    pairs = _unique_pairs(pcs.tube[a], pcs.tube[b])
    return pairs[:, 0], pairs[:, 1]


def test_on_by_default_and_always_in_the_provenance():
    assert UnionOptions().blobs == 0.25
    assert UnionOptions().plain()["blobs"] == 0.25
    # off is recorded too: a file made without them reads back as made without them
    assert UnionOptions(blobs=0).plain()["blobs"] == 0
    for blobs in (0.0, 0.25, 0.1):
        assert UnionOptions.from_plain(UnionOptions(blobs=blobs).plain()) == UnionOptions(blobs=blobs)
    assert lsys3d.generate("abop-1.24a", iterations=2).provenance.options["union"]["blobs"] == 0.25


def test_the_fern_is_a_blob_and_a_sparse_tree_is_not(fern):
    clusters = blob_clusters(fern, *tube_pairs(fern), 0.25)
    assert len(clusters) == 1 and len(clusters[0]) == len(fern)
    # two long branches that touch at a fork: the boolean is cheap there
    sk = make_skeleton(
        [[0, 0, 0], [0, 1, 0], [0, 1, 0]], [[0, 1, 0], [0.5, 2, 0], [-0.5, 2, 0]], 0.05, None, [-1, 0, 0]
    )
    tubes = sweep(sk)
    assert blob_clusters(tubes, *tube_pairs(tubes), 0.25) == []


def test_a_single_capsule_level_set_is_closed_and_near_the_tube():
    sk = make_skeleton([[0, 0, 0]], [[0, 0.3, 0.1]], 0.1, None, [-1])
    tubes = sweep(sk)
    vertices, faces, source = level_set(tubes, np.array([0]), 0.01)
    mesh = lsys3d.Mesh(vertices, faces, np.zeros((len(faces), 3, 3)), np.zeros((len(faces), 3, 2)))
    assert mesh.is_watertight and mesh.is_winding_consistent
    # the cylinder of the area-keeping radius, flat ends as the tube's caps
    assert mesh.volume == pytest.approx(tubes.volumes()[0], rel=0.02)
    kind = tubes.face_kinds(source)[1]
    assert (kind == -1).all()  # every source is a wall face: smooth normals, the wall's uv chart


def test_the_union_with_blobs_is_closed_deterministic_and_near_the_exact_volume(fern, fern_blobs):
    exact = union(fern, UnionOptions(blobs=0, max_pairs=10**8))
    first, again = fern_blobs, union(fern, UnionOptions(blobs=0.25, max_pairs=10**8, workers=2))
    assert first.is_watertight and first.is_winding_consistent
    np.testing.assert_array_equal(first.vertices, again.vertices)
    np.testing.assert_array_equal(first.faces, again.faces)
    np.testing.assert_array_equal(first.uv, again.uv)
    assert first.volume == pytest.approx(exact.volume, rel=0.01)
    assert len(first.faces) < len(exact.faces)
    assert np.isfinite(first.uv).all() and np.allclose(np.linalg.norm(first.normals, axis=2), 1, atol=1e-3)
    assert (first.face_source >= 0).all() and (first.face_source < len(fern.faces)).all()


def test_generate_with_blobs_cleans_and_exports(fern_cleaned, fern_plain):
    bark = fern_cleaned
    assert bark.is_watertight and bark.is_winding_consistent
    assert fern_plain.is_watertight and fern_plain.volume == pytest.approx(bark.volume, rel=1e-6)


def test_a_branching_plant_has_no_blob_and_keeps_its_union():
    # the benchmark's 3D plant: its twigs are thin and its clusters overlap little, so the boolean stays
    with_blobs = lsys3d.generate("tree3d", iterations=4).bark
    without = lsys3d.generate("tree3d", iterations=4, union_blobs=0).bark
    np.testing.assert_array_equal(with_blobs.vertices, without.vertices)
    np.testing.assert_array_equal(with_blobs.faces, without.faces)


def test_the_pairs_found_for_the_blobs_are_refused_as_before():
    # no blob: the pairs found for the blobs' test are the union's own, and over max_pairs still refused
    from lsys3d.errors import LimitError

    tubes = sweep(lsys3d.generate("tree3d", iterations=4, union=False).skeleton)
    pairs = len(touching(pieces(tubes), 0.01, 10**9)[0])
    for blobs in (0.0, 0.25):
        with pytest.raises(LimitError, match=f"more than {pairs - 1:,} pairs"):
            union(tubes, UnionOptions(blobs=blobs, max_pairs=pairs - 1, workers=1))
        assert union(tubes, UnionOptions(blobs=blobs, max_pairs=pairs, workers=1)).is_watertight


def test_a_blob_beside_a_cluster_that_keeps_the_boolean(fern, fern_blobs):
    # the fern (a blob) and, far from it, two long branches at a fork (the boolean): one closed mesh of both
    from lsys3d.mesh.sweep.tubes import _concat

    sk = make_skeleton([[5, 0, 0], [5, 1, 0], [5, 1, 0]], [[5, 1, 0], [5.5, 2, 0], [4.5, 2, 0]], 0.05, None, [-1, 0, 0])
    fork = sweep(sk)
    both = _concat([fern, fork])
    opt = UnionOptions(blobs=0.25, max_pairs=10**8, workers=1)
    mesh = union(both, opt)
    alone = fern_blobs, union(fork, opt)
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert len(mesh.faces) == len(alone[0].faces) + len(alone[1].faces)
    assert mesh.volume == pytest.approx(alone[0].volume + alone[1].volume, rel=1e-9)
    # the fork's faces name the fork's tube faces, after the fern's
    assert (mesh.face_source >= len(fern.faces)).sum() == len(alone[1].faces)


def _uv_continuity(mesh, which):
    """Share of the edges between two faces of ``which`` whose two corners have the same uv on both faces.

    Each edge's occurrences are paired in the order of the faces (the first with the second, a third with a
    fourth); a pair counts as the same when both ends' uv match within ``np.isclose(atol=1e-5)``.
    """
    faces = mesh.faces[which]
    uv = mesh.uv[which]
    a, b = faces.reshape(-1), np.roll(faces, -1, axis=1).reshape(-1)  # each face's edges (j, j + 1)
    uv_a, uv_b = uv.reshape(-1, 2), np.roll(uv, -1, axis=1).reshape(-1, 2)
    low, high = np.minimum(a, b), np.maximum(a, b)
    uv_low = np.where((a >= b)[:, None], uv_b, uv_a)  # an edge from a vertex to itself: its second corner's
    uv_high = np.where((a > b)[:, None], uv_a, uv_b)
    order = np.lexsort((np.arange(len(low)), high, low))  # by edge, each edge's occurrences in face order
    low, high = low[order], high[order]
    start = np.r_[True, (low[1:] != low[:-1]) | (high[1:] != high[:-1])]
    first = np.maximum.accumulate(np.where(start, np.arange(len(low)), 0))
    later = np.flatnonzero((np.arange(len(low)) - first) % 2 == 1)  # the second of each pair
    mine, other = order[later], order[later - 1]
    same = np.isclose(uv_low[mine], uv_low[other], atol=1e-5).all(axis=1)
    same &= np.isclose(uv_high[mine], uv_high[other], atol=1e-5).all(axis=1)
    return int(same.sum()) / max(len(later), 1)


def test_the_crowd_takes_a_box_projection_and_the_stems_their_chart(fern, fern_blobs):
    from lsys3d.mesh.union.blob_uv import BOX_LENGTH

    mesh = fern_blobs
    boxed = mesh.face_box_uv > 0
    assert 0.2 < boxed.mean() < 1.0  # the apices' crowd, not the long tubes
    # the long tubes' faces keep their chart: the tube of each unboxed face is at least BOX_LENGTH widths long
    tube, _ = fern.face_kinds(mesh.face_source[~boxed])
    first = fern.ring_offsets[tube]
    last = first + fern.rings[tube] - 1
    length = np.linalg.norm(fern.ring_center[last] - fern.ring_center[first], axis=1)
    assert (length > 0.5 * BOX_LENGTH * 2 * fern.ring_radius[first]).mean() > 0.95
    # the texture runs on across the crowd: most edges inside it join equal uv, where each face's own nearest
    # tube's chart (what the blobs gave before) joins few
    chart = fern.corner_uv(mesh.face_source, mesh.vertices, mesh.faces, np.empty(mesh.uv.shape, np.float32))
    charted = lsys3d.Mesh(mesh.vertices, mesh.faces, mesh.normals, chart)
    box, before = _uv_continuity(mesh, boxed), _uv_continuity(charted, boxed)
    assert box > 0.8 and before < 0.6, (box, before)
    # texels as square as the tubes': a face's uv area is its area times density^2, foreshortened by at most 1/sqrt(3)
    tri, uv = mesh.vertices[mesh.faces[boxed]], mesh.uv[boxed].astype(np.float64)
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    e1, e2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    uv_area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    ratio = uv_area / (area * mesh.face_box_uv[boxed].astype(np.float64) ** 2)
    big = area > np.median(area) * 0.1
    assert (ratio[big] > 1 / np.sqrt(3) - 1e-3).all() and (ratio[big] < 1 + 1e-3).all()


def test_the_cleanup_keeps_the_box_projection(fern_cleaned, fern_plain, monkeypatch):
    import lsys3d.mesh.union.blob_uv as blob_uv

    plain = fern_plain
    assert plain.face_box_uv is not None and (plain.face_box_uv > 0).mean() > 0.2
    # the cleanup remakes every uv from the face sources: the crowd's faces get the box projection again
    cleaned = fern_cleaned
    assert np.isfinite(cleaned.uv).all()
    monkeypatch.setattr(blob_uv, "BOX_LENGTH", 0.0)  # every tube its own chart, as before
    charted = lsys3d.generate(FERN, **FERN_OPTIONS).bark
    np.testing.assert_array_equal(cleaned.faces, charted.faces)  # the uv alone differs
    everything = np.arange(len(cleaned.faces))
    assert _uv_continuity(cleaned, everything) > _uv_continuity(charted, everything) + 0.05


def test_without_scikit_image_the_blobs_go_through_the_boolean(fern, monkeypatch, caplog):
    # Blender's extension bundles no scikit-image: the union must still work there, as the exact boolean
    import lsys3d.mesh.union.blobs as blobs
    from lsys3d.errors import OptionsError

    monkeypatch.setattr(blobs, "_marching_cubes", lambda: None)
    with caplog.at_level("WARNING", logger="lsys3d"):
        meshes, meshed = blobs.blob_meshes(fern, *tube_pairs(fern), 0.25)
    assert meshes == [] and not meshed.any()
    assert "scikit-image does not import" in caplog.text
    with pytest.raises(OptionsError, match="scikit-image"):
        level_set(fern, np.arange(len(fern)), 0.005)


def _chain(n, step, turn_degrees, width):
    """A skeleton of ``n`` segments ``step`` long, each turned ``turn_degrees`` from the last, in one plane."""
    points, d, a = [np.zeros(3)], np.array([0.0, 1.0, 0.0]), np.radians(turn_degrees)
    for _ in range(n):
        points.append(points[-1] + step * d)
        d = np.array([np.cos(a) * d[0] - np.sin(a) * d[1], np.sin(a) * d[0] + np.cos(a) * d[1], 0.0])
    points = np.array(points)
    return make_skeleton(points[:-1], points[1:], width, None, np.arange(-1, n - 1))


def test_short_spans_keep_the_volume_of_one_long_span():
    # a tube of 20 spans as long as its radius loses no more volume than one long span: inside it, on its inner
    # rings, the samples keep the wall's distance (when each span was cut on both sides of every ring they fell
    # to zero there and the wall next to every ring dented inwards: 4.5% apart at this edge)
    edge = 0.075  # a quarter of the width, the default
    ratios = []
    for sk in (_chain(1, 3.0, 0, 0.3), _chain(20, 0.15, 5, 0.3)):
        tubes = sweep(sk)
        assert len(tubes) == 1 and (len(tubes.ring_center) > 10) == (len(sk) > 1)
        vertices, faces, _ = level_set(tubes, np.array([0]), edge)
        mesh = lsys3d.Mesh(vertices, faces, np.zeros((len(faces), 3, 3)), np.zeros((len(faces), 3, 2)))
        ratios.append(mesh.volume / tubes.volumes()[0])
    assert abs(ratios[0] - ratios[1]) < 0.015, ratios
    assert all(abs(r - 1) < 0.03 for r in ratios), ratios
