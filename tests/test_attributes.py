"""Hierarchy and wind attributes: exact values on a small grammar, the seam rule, the writers, the judges."""

from __future__ import annotations

import json

import numpy as np
import pytest
import validators
from gltf_files import accessor, node, read_glb
from pxr import Usd, UsdGeom

import lsys3d
from lsys3d.exchange import ExportOptions, export
from lsys3d.look.attributes import (
    ATTRIBUTES,
    BRANCH_KEYS,
    GLTF_PACKING,
    KEYS,
    VERTEX_KEYS,
    AttributeOptions,
    gltf_attributes,
    nearest_branch,
)
from lsys3d.turtle.hierarchy import hierarchy

# a trunk of 3 segments (0..3 m) with a branch of 2 segments from 1 m, turned 90 degrees; a leaf at each tip
SMALL = lsys3d.Grammar(axiom="!(0.2)F[+!(0.1)FF~]FF~", angle=90, name="small")


@pytest.fixture(scope="module")
def small():
    return lsys3d.generate(SMALL, 0, sides=8, attributes="full")


def test_every_attribute_is_declared_once():
    assert len(KEYS) == len(set(KEYS)) == len(ATTRIBUTES)
    packed = [k for _, keys in GLTF_PACKING for k in keys]
    assert len(packed) == len(set(packed)) and set(packed) <= set(KEYS)
    assert set(VERTEX_KEYS) | set(BRANCH_KEYS) == set(KEYS) and not set(VERTEX_KEYS) & set(BRANCH_KEYS)
    assert AttributeOptions().keys == () and AttributeOptions("compact").keys == VERTEX_KEYS


def test_exact_values_on_a_small_tree(small):
    a = small.bark.attributes
    v = small.bark.vertices
    assert sorted(a) == sorted(KEYS)
    trunk = v[:, 0] ** 2 + v[:, 2] ** 2 < 0.1001**2  # within the trunk's radius of the y axis
    tip_of_branch = v[:, 0] < -1.9  # the branch grows along -x (turned left from +y) to x = -2
    assert (a["branch_id"][tip_of_branch] == 1).all() and (a["branch_id"][trunk & (v[:, 1] > 1.2)] == 0).all()
    assert np.allclose(a["pivot"][a["branch_id"] == 0], [0, 0, 0]) and np.allclose(
        a["pivot"][a["branch_id"] == 1], [0, 1, 0]
    )
    assert np.allclose(a["parent_pivot"][a["branch_id"] == 1], [0, 0, 0])
    assert (a["branch_depth"][a["branch_id"] == 1] == 1).all() and (a["branch_parent"][a["branch_id"] == 1] == 0).all()
    assert np.allclose(a["branch_length"][a["branch_id"] == 0], 3) and np.allclose(
        a["branch_length"][a["branch_id"] == 1], 2
    )
    # t along the trunk is the height over its length, exact on the ring vertices (the caps' rims)
    on_trunk = (a["branch_id"] == 0) & trunk
    assert np.allclose(a["branch_t"][on_trunk], np.clip(v[on_trunk, 1] / 3, 0, 1), atol=1e-6)
    on_branch = (a["branch_id"] == 1) & (np.abs(v[:, 1] - 1) <= 0.05 + 1e-9)
    assert np.allclose(a["branch_t"][on_branch], np.clip(-v[on_branch, 0] / 2, 0, 1), atol=0.03)
    # leaves: the branch they grow from, at its tip
    inst = small.leaves.instance_attributes
    assert inst["branch_id"].tolist() == [1, 0] and inst["branch_t"].tolist() == [1, 1]
    assert small.hierarchy is not None and len(small.hierarchy) == 2


def test_the_seam_belongs_to_the_child(small):
    """Vertices on the seam where the branch cuts the trunk take the branch's values, not an interpolation.

    The seam is found by the tube each triangle is a piece of (``Mesh.face_source``): its vertices are
    in triangles of both tubes.  The junction collar (lsys3d.mesh.cleanup) moves them a little off the trunk.
    """
    from lsys3d.mesh.sweep import sweep

    a = small.bark.attributes
    v = small.bark.vertices
    tubes = sweep(small.skeleton, lsys3d.SweepOptions(sides=8))
    tube = np.searchsorted(tubes.face_offsets, small.bark.face_source, side="right") - 1
    faces = small.bark.faces
    branch_tubes = np.unique(tube[np.isin(tube, np.flatnonzero(tubes.order > 0))])
    on_branch = np.isin(tube, branch_tubes)
    seam = np.intersect1d(faces[on_branch].ravel(), faces[~on_branch].ravel())
    assert len(seam) >= 6  # the intersection curve of the branch with the trunk (the cleanup merges a few)
    assert np.allclose(np.hypot(v[seam, 0], v[seam, 2]), 0.1, atol=0.03)  # on (or faired just off) the trunk
    assert (a["branch_id"][seam] == 1).all() and (a["branch_t"][seam] < 0.06).all()
    assert set(np.unique(a["branch_id"]).tolist()) == {0, 1}  # never a value in between


def test_compact_layout_and_leaves(tmp_path):
    tree = lsys3d.generate(SMALL, 0, sides=8, attributes="compact")
    assert sorted(tree.bark.attributes) == ["branch_id", "branch_t"]
    assert sorted(tree.leaves.merged.attributes) == ["branch_id", "branch_t"]
    off = lsys3d.generate(SMALL, 0, sides=8)
    assert not off.bark.attributes and off.hierarchy is None and not off.leaves.instance_attributes
    assert np.array_equal(off.bark.vertices, tree.bark.vertices)  # attributes never change the geometry


def test_gltf_attributes_and_branch_table(small, tmp_path):
    path = export(small, tmp_path / "small.glb", ExportOptions(instance_leaves=True))
    report = validators.validate_gltf(path)
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0
    doc, binary = read_glb(path)
    bark = doc["meshes"][node(doc, "bark")["mesh"]]["primitives"][0]["attributes"]
    assert {"_BRANCH", "_HIERARCHY", "_PIVOT", "_PARENT_PIVOT"} <= set(bark)
    branch = accessor(doc, binary, bark["_BRANCH"])
    position = accessor(doc, binary, bark["POSITION"])
    assert branch.shape == (len(position), 3)  # id, t, phase
    assert set(np.unique(branch[:, 0]).tolist()) == {0.0, 1.0}
    table = node(doc, "small")["extras"]["lsys3d_branches"]
    assert table["count"] == 2
    assert accessor(doc, binary, table["pivot"]).tolist() == [[0, 0, 0], [0, 1, 0]]
    assert accessor(doc, binary, table["branch_depth"]).tolist() == [0, 1]
    leaf = node(doc, "leaf")["extensions"]["EXT_mesh_gpu_instancing"]["attributes"]
    assert accessor(doc, binary, leaf["_BRANCH"])[:, 0].tolist() == [1, 0]


def test_usd_primvars_in_the_file_frame(small, tmp_path):
    path = export(small, tmp_path / "small.usda", ExportOptions(up_axis="Z", units="cm"))
    assert validators.usd_problems(path) == []
    stage = Usd.Stage.Open(str(path))
    root = stage.GetDefaultPrim()
    bark = UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/small/Geom/bark"))
    pivots = np.array(bark.GetPrimvar("pivot").Get())
    ids = np.array(bark.GetPrimvar("branch_id").Get())
    assert bark.GetPrimvar("pivot").GetInterpolation() == UsdGeom.Tokens.vertex
    # Y up, metres -> Z up, centimetres: the branch's pivot (0, 1, 0) m is (0, 0, 100) cm
    assert np.allclose(pivots[ids == 1], [0, 0, 100]) and np.allclose(pivots[ids == 0], 0)
    table = UsdGeom.PrimvarsAPI(root)
    assert np.allclose(np.array(table.GetPrimvar("branches:pivot").Get()), [[0, 0, 0], [0, 0, 100]])
    assert table.GetPrimvar("branches:pivot").GetInterpolation() == UsdGeom.Tokens.constant
    instancer = UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/small/Geom/leaf"))
    assert list(instancer.GetPrimvar("branch_id").Get()) == [1, 0]
    data = json.loads(root.GetCustomDataByKey("lsys3d")["provenance"])
    assert data["options"]["attributes"] == {"layout": "full"}


def test_geometric_match_agrees_with_the_tubes():
    """On a preset's tubes, every vertex on the surface of the union matches its own tube's branch, or a child's."""
    from lsys3d.mesh.sweep import sweep
    from lsys3d.turtle import interpret

    g = lsys3d.load_preset("tree3d")
    sk = interpret(lsys3d.derive(g, 4), g)
    h = hierarchy(sk)
    tubes = sweep(sk)
    owner = np.repeat(np.arange(len(tubes)), np.diff(tubes.point_offsets))
    expected = tubes.chain[owner]
    points = tubes.points
    # vertices inside another branch's tube are not on the union's surface: leave them out
    surface = np.ones(len(points), bool)
    for start in range(0, len(points), 500):  # every point against every segment, in chunks
        p = points[start : start + 500, None, :]
        d = sk.end - sk.start
        f = np.clip(((p - sk.start) * d).sum(-1) / (d * d).sum(-1), 0, 1)
        dist = np.linalg.norm(p - (sk.start + f[..., None] * d), axis=-1)
        r = 0.5 * (sk.width_start + f * (sk.width_end - sk.width_start))
        other = h.branch_of[None, :] != expected[start : start + 500, None]
        surface[start : start + 500] = ~((dist / r < 0.999) & other).any(axis=1)
    segment, t = nearest_branch(points, sk, h)
    got = h.branch_of[segment]
    assert (segment >= 0).all() and ((t >= 0) & (t <= 1)).all()
    differs = (got != expected) & surface
    # where it differs, the vertex lies on the seam with a branch at least as deep (a child, or a sibling it touches)
    assert (h.depth[got[differs]] >= h.depth[expected[differs]]).all()
    assert differs.sum() < 0.15 * surface.sum()


def test_packing():
    values = {k: np.arange(3, dtype=np.float32) if k != "pivot" else np.ones((3, 3)) for k in ("branch_id", "pivot")}
    packed = gltf_attributes(values)
    assert list(packed) == ["_BRANCH", "_PIVOT"] and packed["_BRANCH"].shape == (3, 1)


@pytest.mark.parametrize("name", ["tree3d", "bush"])
def test_presets_with_attributes_pass_the_judges(name, tmp_path):
    tree = lsys3d.generate(name, iterations=4 if name == "bush" else 5, attributes="full")
    glb = export(tree, tmp_path / f"{name}.glb")
    report = validators.validate_gltf(glb)
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0
    usd = export(tree, tmp_path / f"{name}.usdc")
    assert validators.usd_problems(usd) == []


def test_the_docs_table_is_the_attribute_table():
    from lsys3d.look.attributes import attributes_markdown

    text = (validators.REPO / "docs" / "engines.md").read_text(encoding="utf-8")
    assert attributes_markdown() in text
