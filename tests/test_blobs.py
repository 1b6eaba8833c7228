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

pytest.importorskip("skimage")

FERN = "tests/corpus/lpy/real/02-fractals_barnsleyfern.lpy"


@pytest.fixture(scope="module")
def fern():
    """L-Py's Barnsley-like fern cut to 8 generations: 9,840 segments in 2,187 tubes nested at every apex."""
    from lsys3d.pipeline import draw

    g = lsys3d.load(FERN)
    _, sk = draw(g, 8, g.seed)
    return sweep(sk)


def tube_pairs(tubes):
    pcs = pieces(tubes)
    a, b = touching(pcs, 0.01, 10**9)
    pairs = _unique_pairs(pcs.tube[a], pcs.tube[b])
    return pairs[:, 0], pairs[:, 1]


def test_off_by_default_and_in_the_provenance_only_when_on():
    assert UnionOptions().blobs == 0.0
    assert "blobs" not in UnionOptions().plain()
    assert UnionOptions(blobs=0.25).plain()["blobs"] == 0.25
    assert UnionOptions.from_plain(UnionOptions(blobs=0.25).plain()) == UnionOptions(blobs=0.25)


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


def test_the_union_with_blobs_is_closed_deterministic_and_near_the_exact_volume(fern):
    exact = union(fern, UnionOptions(max_pairs=10**8))
    opt = UnionOptions(blobs=0.25, max_pairs=10**8, workers=1)
    first, again = union(fern, opt), union(fern, UnionOptions(blobs=0.25, max_pairs=10**8, workers=2))
    assert first.is_watertight and first.is_winding_consistent
    np.testing.assert_array_equal(first.vertices, again.vertices)
    np.testing.assert_array_equal(first.faces, again.faces)
    np.testing.assert_array_equal(first.uv, again.uv)
    assert first.volume == pytest.approx(exact.volume, rel=0.01)
    assert len(first.faces) < len(exact.faces)
    assert np.isfinite(first.uv).all() and np.allclose(np.linalg.norm(first.normals, axis=2), 1, atol=1e-3)
    assert (first.face_source >= 0).all() and (first.face_source < len(fern.faces)).all()


def test_generate_with_blobs_cleans_and_exports(tmp_path):
    tree = lsys3d.generate(FERN, iterations=8, union_blobs=0.25, max_union_pairs=10**8)
    bark = tree.bark
    assert bark.is_watertight and bark.is_winding_consistent
    plain = lsys3d.generate(FERN, iterations=8, union_blobs=0.25, max_union_pairs=10**8, cleanup=False)
    assert plain.bark.is_watertight and plain.bark.volume == pytest.approx(bark.volume, rel=1e-6)


def test_a_branching_plant_has_no_blob_and_keeps_its_union():
    # the benchmark's 3D plant: its twigs are thin and its clusters overlap little, so the boolean stays
    options = {"iterations": 4, "union_blobs": 0.25}
    with_blobs = lsys3d.generate("tree3d", **options).bark
    without = lsys3d.generate("tree3d", iterations=4).bark
    np.testing.assert_array_equal(with_blobs.vertices, without.vertices)
    np.testing.assert_array_equal(with_blobs.faces, without.faces)


def test_a_blob_beside_a_cluster_that_keeps_the_boolean(fern):
    # the fern (a blob) and, far from it, two long branches at a fork (the boolean): one closed mesh of both
    from lsys3d.mesh.sweep.tubes import _concat

    sk = make_skeleton([[5, 0, 0], [5, 1, 0], [5, 1, 0]], [[5, 1, 0], [5.5, 2, 0], [4.5, 2, 0]], 0.05, None, [-1, 0, 0])
    fork = sweep(sk)
    both = _concat([fern, fork])
    opt = UnionOptions(blobs=0.25, max_pairs=10**8, workers=1)
    mesh = union(both, opt)
    alone = union(fern, opt), union(fork, opt)
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert len(mesh.faces) == len(alone[0].faces) + len(alone[1].faces)
    assert mesh.volume == pytest.approx(alone[0].volume + alone[1].volume, rel=1e-9)
    # the fork's faces name the fork's tube faces, after the fern's
    assert (mesh.face_source >= len(fern.faces)).sum() == len(alone[1].faces)
