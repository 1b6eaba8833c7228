"""Synthetic trees for the export tests: geometry made here, assembled as lsys3d assembles real trees.

A trunk and two branches are trimesh cylinders unioned by manifold3d, with
corner normals (smooth, creased at the caps) and cylindrical UVs computed
here; leaves are quads placed by instance transforms and baked by
:func:`lsys3d.look.leaves.instance_leaves`; one leaf is a polygon.  The provenance
is built by :meth:`lsys3d.provenance.Provenance.of`, the pipeline's own builder,
so the writers read exactly what they read from a generated tree.
"""

from __future__ import annotations

import numpy as np
import trimesh

from lsys3d.look.leaves import Leaves, instance_leaves
from lsys3d.lsystem.grammar import Grammar
from lsys3d.mesh.mesh import Mesh
from lsys3d.pipeline import GenerateOptions
from lsys3d.provenance import Provenance
from lsys3d.tree import StageCounts, Tree
from lsys3d.turtle.skeleton import Skeleton

GRAMMAR = Grammar(axiom="F[+F][-F]", name="synthetic", iterations=3, seed=42, angle=25.0)
PROVENANCE = Provenance.of(GRAMMAR, 3, 42, GenerateOptions())
COUNTS = StageCounts(modules=9, segments=4, tubes=3, tube_vertices=0, tube_faces=0)


def corner_attributes(mesh: trimesh.Trimesh, crease_degrees: float = 40.0) -> Mesh:
    """A :class:`~lsys3d.mesh.mesh.Mesh` of a welded trimesh with corner normals and uv made here.

    Normals are the vertex normals, except at corners whose face turns more
    than ``crease_degrees`` away from them (caps), which take the face normal.
    UVs: u = angle around the Y axis in [0, 1] (seam fixed per triangle), v = y.
    """
    faces = mesh.faces
    # area-weighted vertex normals (trimesh's own wants scipy for speed)
    cross = np.cross(*(mesh.vertices[faces[:, 1:]] - mesh.vertices[faces[:, :1]]).transpose(1, 0, 2))
    summed = np.zeros_like(mesh.vertices)
    for c in range(3):
        np.add.at(summed, faces[:, c], cross)
    vertex_normals = summed / np.linalg.norm(summed, axis=1, keepdims=True)
    vn = vertex_normals[faces]
    fn = np.repeat(mesh.face_normals[:, None, :], 3, axis=1)
    sharp = np.einsum("fci,fci->fc", vn, fn) < np.cos(np.radians(crease_degrees))
    normals = np.where(sharp[..., None], fn, vn)
    p = mesh.vertices[faces]
    u = np.arctan2(p[..., 0], p[..., 2]) / (2 * np.pi) + 0.5
    # a triangle straddling the seam gets its small u values moved past 1
    wrap = (u.max(axis=1) - u.min(axis=1)) > 0.5
    u = np.where(wrap[:, None] & (u < 0.5), u + 1.0, u)
    uv = np.stack([u, p[..., 1]], axis=-1)
    return Mesh(mesh.vertices, faces, normals, uv)


def _cylinder(start, end, radius, sections=24) -> trimesh.Trimesh:
    return trimesh.creation.cylinder(radius=radius, segment=np.array([start, end]), sections=sections)


def leaf_quad(length: float = 1.0, width: float = 0.5) -> Mesh:
    """A leaf model in its own frame: x = left, y = up (the normal), z = heading (the blade)."""
    v = np.array([[-width / 2, 0, 0], [width / 2, 0, 0], [width / 2, 0, length], [-width / 2, 0, length]], float)
    faces = np.array([[0, 2, 1], [0, 3, 2]])
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)
    return Mesh(v, faces, np.tile(np.float32([0, 1, 0]), (2, 3, 1)), uv[faces])


def _frame(heading, size):
    h = np.asarray(heading, float)
    h /= np.linalg.norm(h)
    helper = np.array([0.0, 0.0, 1.0]) if abs(h[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    left = np.cross(helper, h)
    left /= np.linalg.norm(left)
    up = np.cross(h, left)
    return np.stack([left, up, h], axis=1) * size


def make_tree(instanced: bool = True, polygons: bool = True, unioned: bool = True) -> Tree:
    """A small tree: 2 m trunk along +Y, two branches, 6 leaves, one polygon leaf."""
    trunk = [(0, 0, 0), (0, 1, 0), (0, 2, 0)]
    branches = [((0, 1, 0), (0.6, 1.6, 0.1)), ((0, 1.2, 0), (-0.5, 1.8, -0.2))]
    parts = [_cylinder(trunk[0], trunk[2], 0.1)]
    parts += [_cylinder(a, b, 0.05, sections=16) for a, b in branches]
    bark = trimesh.boolean.union(parts, engine="manifold") if unioned else trimesh.util.concatenate(parts)
    bark = corner_attributes(trimesh.Trimesh(bark.vertices, bark.faces, process=False))

    start = np.array([trunk[0], trunk[1], branches[0][0], branches[1][0]], float)
    end = np.array([trunk[1], trunk[2], branches[0][1], branches[1][1]], float)
    heading = (end - start) / np.linalg.norm(end - start, axis=1, keepdims=True)
    frames = np.stack([_frame(h, 1.0) for h in heading])
    n = len(start)
    skeleton = Skeleton(
        start=start,
        end=end,
        width_start=np.array([0.2, 0.2, 0.1, 0.1]),
        width_end=np.array([0.2, 0.15, 0.05, 0.05]),
        heading=heading,
        left=frames[:, :, 0],
        up=frames[:, :, 1],
        parent=np.array([-1, 0, 0, 0]),
        order=np.array([0, 0, 1, 1], np.int32),
        material=np.zeros(n, np.int32),
        module=np.arange(n),
    )

    model = leaf_quad(0.2, 0.1)
    tips = [end[1], end[2], end[3], (0.3, 1.3, 0.05), (-0.25, 1.5, -0.1), (0, 1.9, 0)]
    dirs = [(0.2, 1, 0.3), (1, 0.5, 0.2), (-1, 0.5, -0.3), (1, 0.2, 0.5), (-1, 0.3, 0), (0, 0.2, 1)]
    transforms = np.tile(np.eye(4), (len(tips), 1, 1))
    for i, (p, d) in enumerate(zip(tips, dirs, strict=True)):
        transforms[i, :3, :3] = _frame(d, 0.8 + 0.1 * i)
        transforms[i, :3, 3] = p
    # one mirrored instance would be unusual for a turtle; keep every frame right-handed

    polygon = None
    if polygons:
        pv = np.array([[0.0, 2.0, 0.0], [0.15, 2.1, 0.0], [0.1, 2.25, 0.02], [-0.05, 2.2, 0.0], [-0.1, 2.1, -0.01]])
        pf = np.array([[0, 1, 2], [0, 2, 3], [0, 3, 4]])
        polygon = Mesh.flat(pv, pf, uv=(pv[pf][..., :2] * 4))

    merged = Mesh.concatenate([instance_leaves(model, transforms), polygon])
    leaves = Leaves(
        merged=merged,
        model=model if instanced else None,
        transforms=transforms if instanced else np.zeros((0, 4, 4)),
        polygons=polygon,
    )
    return Tree(bark=bark, skeleton=skeleton, leaves=leaves, provenance=PROVENANCE, counts=COUNTS, unioned=unioned)


def make_tube(around: int = 1000, along: int = 500, scramble: bool = False, seed: int = 0) -> Mesh:
    """A welded open tube of ``2 * around * along`` triangles along +Y with corner normals and UVs.

    ``scramble=True`` permutes the vertex numbering at random (as a boolean union does).
    """
    theta = np.linspace(0, 2 * np.pi, around, endpoint=False)
    y = np.linspace(0, 10, along + 1)
    ring = np.stack([np.sin(theta), np.zeros(around), np.cos(theta)], axis=1) * 0.2
    vertices = (ring[None] + y[:, None, None] * np.array([0, 1, 0])).reshape(-1, 3)
    i = np.arange(along)[:, None]
    j = np.arange(around)[None, :]
    a = i * around + j
    b = i * around + (j + 1) % around
    c = a + around
    d = b + around
    faces = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)])
    if scramble:
        perm = np.random.default_rng(seed).permutation(len(vertices))
        inverse = np.empty_like(perm)
        inverse[perm] = np.arange(len(perm))
        vertices = vertices[perm]
        faces = inverse[faces]
    p = vertices[faces]
    normals = p * np.array([1.0, 0.0, 1.0])
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    u = np.arctan2(p[..., 0], p[..., 2]) / (2 * np.pi) + 0.5
    wrap = (u.max(axis=1) - u.min(axis=1)) > 0.5
    u = np.where(wrap[:, None] & (u < 0.5), u + 1.0, u)
    return Mesh(vertices, faces, normals, np.stack([u, p[..., 1]], axis=-1))


def tree_from_bark(bark: Mesh) -> Tree:
    """A Tree with only a bark mesh (for timing)."""
    skeleton = make_tree().skeleton
    return Tree(bark=bark, skeleton=skeleton, provenance=PROVENANCE, counts=COUNTS)
