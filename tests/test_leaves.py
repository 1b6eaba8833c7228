"""Leaves: the built-in leaf, instance transforms, baked instances and polygon leaves."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

import lsys3d
from lsys3d.look.leaves import Leaves, default_leaf, instance_leaves, leaf_transforms, leaves, polygon_leaves
from lsys3d.mesh.mesh import Mesh
from lsys3d.turtle.skeleton import Skeleton


def leafy_skeleton(polygons=(), instances=()) -> Skeleton:
    """No segments; ``polygons`` are point lists, ``instances`` (position, heading, left, size)."""
    pts = [np.asarray(p, float) for p in polygons]
    offsets = np.concatenate([[0], np.cumsum([len(p) for p in pts])]).astype(np.int64)
    pos = np.array([i[0] for i in instances], float).reshape(-1, 3)
    head = np.array([i[1] for i in instances], float).reshape(-1, 3)
    left = np.array([i[2] for i in instances], float).reshape(-1, 3)
    return Skeleton.from_segments(
        np.zeros((0, 3)),
        np.zeros((0, 3)),
        polygon_points=np.concatenate(pts) if pts else np.zeros((0, 3)),
        polygon_offsets=offsets,
        polygon_material=np.zeros(len(pts), np.int32),
        leaf_position=pos,
        leaf_heading=head,
        leaf_left=left,
        leaf_up=np.cross(head, left),
        leaf_size=np.array([i[3] for i in instances], float),
        leaf_material=np.zeros(len(pos), np.int32),
    )


def attributes_ok(mesh: trimesh.Trimesh):
    n = mesh.normals
    uv = mesh.uv
    assert n.shape == (len(mesh.faces), 3, 3) and n.dtype == np.float32
    assert uv.shape == (len(mesh.faces), 3, 2) and uv.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(n, axis=2), 1.0, atol=1e-6)
    assert uv.min() >= -1e-6 and uv.max() <= 1 + 1e-6
    # flat leaves: every corner normal is its face normal
    np.testing.assert_allclose(n, np.repeat(mesh.face_normals[:, None], 3, axis=1), atol=1e-5)


# ---------------------------------------------------------------- the built-in leaf


@pytest.mark.parametrize("points", [1, 2, 7])
def test_default_leaf(points):
    m = default_leaf(points)
    assert len(m.faces) == 4 * points
    assert len(m.vertices) == 3 * points + 2
    assert (m.face_normals[:, 1] > 0.999).all()  # front faces +y (up)
    assert m.bounds[0, 2] == 0 and m.bounds[1, 2] == 1  # base at the origin, tip at z = 1
    assert m.area > 0.1
    attributes_ok(m)


def test_default_leaf_rejects_no_rows():
    with pytest.raises(ValueError, match="default_leaf"):
        default_leaf(0)


# ---------------------------------------------------------------- instances


def test_leaf_transforms_columns():
    sk = leafy_skeleton(instances=[([1, 2, 3], [0, 1, 0], [-1, 0, 0], 0.5), ([0, 0, 0], [1, 0, 0], [0, 0, 1], 2.0)])
    t = leaf_transforms(sk)
    assert t.shape == (2, 4, 4)
    np.testing.assert_allclose(t[0, :3, 0], [-0.5, 0, 0])  # left
    np.testing.assert_allclose(t[0, :3, 1], [0, 0, 0.5])  # up = heading x left
    np.testing.assert_allclose(t[0, :3, 2], [0, 0.5, 0])  # heading
    np.testing.assert_allclose(t[0, :3, 3], [1, 2, 3])
    np.testing.assert_allclose(t[:, 3], [[0, 0, 0, 1]] * 2)


def test_instances_follow_the_turtle_frame():
    sk = leafy_skeleton(instances=[([1, 2, 3], [0, 1, 0], [-1, 0, 0], 0.5)])
    model = default_leaf()
    baked = instance_leaves(model, leaf_transforms(sk))
    assert len(baked.faces) == len(model.faces)
    # the blade runs along the heading from the position, one leaf size long
    np.testing.assert_allclose(baked.bounds[:, 1], [2, 2.5])
    # its front faces the turtle's up
    np.testing.assert_allclose(baked.face_normals, np.tile([0, 0, 1.0], (len(baked.faces), 1)), atol=1e-12)
    attributes_ok(baked)
    np.testing.assert_array_equal(baked.uv, model.uv)


def test_mirroring_transform_keeps_fronts_and_normals_together():
    mirror = np.diag([-1.0, 1, 1, 1])[None]
    baked = instance_leaves(default_leaf(), mirror)
    attributes_ok(baked)


def test_zero_size_instances_are_dropped():
    t = np.zeros((2, 4, 4))
    t[:, 3, 3] = 1
    assert instance_leaves(default_leaf(), t) is None


def test_user_leaf_model():
    square = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1]], [[0, 2, 1], [0, 3, 2]], process=False)
    sk = leafy_skeleton(instances=[([0, 0, 0], [0, 1, 0], [1, 0, 0], 1.0)] * 3)
    got = leaves(sk, model=square)
    assert isinstance(got.model, Mesh) and np.array_equal(got.model.faces, square.faces)
    assert len(got.merged.faces) == 6
    n = got.merged.normals
    np.testing.assert_allclose(np.linalg.norm(n, axis=2), 1.0)


# ---------------------------------------------------------------- polygons


def test_square_polygon():
    sk = leafy_skeleton(polygons=[[[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]])
    m = polygon_leaves(sk)
    assert len(m.faces) == 2 and len(m.vertices) == 4
    assert m.area == pytest.approx(1.0)
    np.testing.assert_allclose(m.face_normals, [[0, 0, 1]] * 2)
    attributes_ok(m)
    uv = m.uv.reshape(-1, 2)
    assert uv.min() == 0 and uv.max() == 1


def test_concave_polygon_is_triangulated_inside():
    # an L in a tilted plane, wound clockwise seen from +z
    pts = np.array([[0, 0, 0], [0, 2, 0], [1, 2, 0], [1, 1, 0], [2, 1, 0], [2, 0, 0]], float)
    rot = trimesh.transformations.rotation_matrix(0.7, [1, 1, 0])[:3, :3]
    m = polygon_leaves(leafy_skeleton(polygons=[pts @ rot.T]))
    assert len(m.faces) == 4
    assert m.area == pytest.approx(3.0)
    attributes_ok(m)


def test_degenerate_polygons_are_dropped():
    line = [[0, 0, 0], [1, 0, 0], [2, 0, 0]]
    tri = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
    m = polygon_leaves(leafy_skeleton(polygons=[line, tri, tri[:2]]))
    assert len(m.faces) == 1
    assert polygon_leaves(leafy_skeleton(polygons=[line])) is None


def test_no_leaves():
    got = leaves(leafy_skeleton())
    assert isinstance(got, Leaves)
    assert got.merged is None and got.model is None and got.polygons is None
    assert got.transforms.shape == (0, 4, 4)


def test_merged_holds_polygons_and_instances():
    sk = leafy_skeleton(
        polygons=[[[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]] * 2,
        instances=[([0, 0, 0], [0, 1, 0], [1, 0, 0], 1.0)] * 5,
    )
    got = leaves(sk)
    assert len(got.polygons.faces) == 4
    assert got.transforms.shape == (5, 4, 4)
    assert len(got.merged.faces) == 4 + 5 * len(got.model.faces)
    attributes_ok(got.merged)


try:
    from lsys3d.turtle import interpret
except ImportError:  # pragma: no cover - the turtle lands separately
    interpret = None


@pytest.mark.skipif(interpret is None, reason="lsys3d.turtle not available")
def test_bush_preset_leaves():
    g = lsys3d.load_preset("bush")
    sk = interpret(lsys3d.derive(g), g)
    got = leaves(sk)
    assert sk.n_polygons > 0
    assert got.polygons is not None and len(got.polygons.faces) >= sk.n_polygons
    attributes_ok(got.polygons)
