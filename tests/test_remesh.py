"""The remeshing operations (:mod:`lsys3d.mesh.remesh`) on small closed meshes: each keeps the mesh a closed
2-manifold and does what it is for."""

from __future__ import annotations

import numpy as np
import pytest
from skeletons import make_skeleton

from lsys3d.mesh import cleanup as cleanup_module
from lsys3d.mesh import remesh
from lsys3d.mesh.sweep import SweepOptions, sweep
from lsys3d.mesh.union.union import union

OCTAHEDRON_POINTS = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], np.float64)
OCTAHEDRON_FACES = np.array(
    [[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]], np.int64
)


def _half_edges(points, faces, scale=1.0, part=None, flat=None, room=16):
    """Half-edges of a closed mesh, every vertex of local scale ``scale``, one part, no flat face unless given."""
    points, faces = np.asarray(points, np.float64), np.asarray(faces, np.int64)
    nf = len(faces)
    part = np.zeros(nf, np.int64) if part is None else np.asarray(part, np.int64)
    flat = np.zeros(nf, bool) if flat is None else np.asarray(flat, bool)
    flags = np.zeros(len(points), np.int64)
    a, b, c = (points[faces[:, k]] for k in range(3))
    n = np.cross(b - a, c - a)
    reference = n / np.linalg.norm(n, axis=1)[:, None]
    return remesh.build(points, faces, flags, np.full(len(points), scale), part, flat, reference, np.arange(nf), room)


def _rules(short=0.0, bad=1e9, fallback=0.0, limit=40.0):
    return remesh.Rules(short, limit, bad, 0.05, 1e9, 1.5, fallback, 10_000)


def _clean(he, rules):
    """``remesh.clean`` everywhere; the operations done: collapses, flips, snaps, splits, fallback collapses.

    No region and no side, as the cleanup passes them (``lsys3d.mesh.cleanup``: an empty int8 side), so the
    kernel is the one the pipeline compiled, not a second compilation for an int64 side."""
    nv = len(he.points)
    return remesh.clean(he, rules, np.zeros(0, bool), np.zeros(0, np.int8), 0, np.zeros(nv, np.int64))


def _closed_manifold(faces: np.ndarray) -> bool:
    """Every directed edge once and its reverse once: closed, consistently oriented, 2-manifold edges."""
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    directed = {tuple(e) for e in edges.tolist()}
    return len(directed) == len(edges) and all((b, a) in directed for a, b in directed)


def _euler(points, faces) -> int:
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    return len(np.unique(faces)) - len(np.unique(edges, axis=0)) + len(faces)


def _aspects(points, faces) -> np.ndarray:
    """Longest edge over (2 sqrt 3 inradius): 1 for an equilateral triangle."""
    a, b, c = (points[faces[:, k]] for k in range(3))
    la, lb, lc = (np.linalg.norm(x - y, axis=1) for x, y in ((b, c), (c, a), (a, b)))
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    inradius = 2 * area / (la + lb + lc)
    return np.maximum(np.maximum(la, lb), lc) / (2 * np.sqrt(3) * inradius)


def _volume(points, faces) -> float:
    a, b, c = (points[faces[:, k]] for k in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def _valences(faces) -> np.ndarray:
    edges = np.unique(np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1), axis=0)
    return np.bincount(edges.ravel())


def test_build_finds_every_opposite_and_compact_gives_the_mesh_back():
    he = _half_edges(OCTAHEDRON_POINTS, OCTAHEDRON_FACES)
    nf = len(OCTAHEDRON_FACES)
    opp = he.opp[: 3 * nf]
    assert (opp >= 0).all() and (opp[opp] == np.arange(3 * nf)).all()  # opposites pair up
    points, faces, *_ = remesh.compact(he)
    assert np.array_equal(points, OCTAHEDRON_POINTS) and np.array_equal(faces, OCTAHEDRON_FACES)


def test_build_refuses_an_open_mesh():
    with pytest.raises(ValueError):
        _half_edges(OCTAHEDRON_POINTS, OCTAHEDRON_FACES[:-1])


def test_a_collapse_keeps_the_mesh_closed_and_removes_the_short_edge():
    points = OCTAHEDRON_POINTS.copy()
    # a vertex made by splitting the edge 0-2 very near vertex 0: a short edge 0-6, and two needles
    near = points[0] + 0.02 * (points[2] - points[0])
    points = np.vstack([points, near])
    faces = []
    for f in OCTAHEDRON_FACES.tolist():
        for k in range(3):
            if {f[k], f[(k + 1) % 3]} == {0, 2}:
                a, b, c = f[k], f[(k + 1) % 3], f[(k + 2) % 3]
                faces += [[a, 6, c], [6, b, c]]
                break
        else:
            faces.append(f)
    faces = np.array(faces, np.int64)
    assert _closed_manifold(faces) and _euler(points, faces) == 2
    he = _half_edges(points, faces)
    done = _clean(he, _rules(short=0.1))
    out_points, out_faces, *_ = remesh.compact(he)
    assert done[0] >= 1  # collapses
    assert len(out_points) == 6 and len(out_faces) == 8
    assert _closed_manifold(out_faces) and _euler(out_points, out_faces) == 2
    edges = np.concatenate([out_faces[:, [0, 1]], out_faces[:, [1, 2]], out_faces[:, [2, 0]]])
    assert np.linalg.norm(out_points[edges[:, 0]] - out_points[edges[:, 1]], axis=1).min() > 0.1


def test_a_valence_3_vertex_is_removed():
    """A vertex in the middle of a face (three thin faces around it, valence 3) collapses into a corner."""
    centre = OCTAHEDRON_POINTS[[0, 2, 4]].mean(axis=0) * 1.001  # just off the face, outwards
    points = np.vstack([OCTAHEDRON_POINTS, centre])
    faces = np.vstack([[[0, 2, 6], [2, 4, 6], [4, 0, 6]], OCTAHEDRON_FACES[1:]])
    assert _closed_manifold(faces) and _valences(faces)[6] == 3
    he = _half_edges(points, faces)
    done = _clean(he, _rules(short=0.9))
    assert done[0] == 1
    out_points, out_faces, *_ = remesh.compact(he)
    assert len(out_points) == 6 and _closed_manifold(out_faces) and _euler(out_points, out_faces) == 2
    assert (_valences(out_faces) >= 4).all()
    assert abs(_volume(out_points, out_faces) - _volume(OCTAHEDRON_POINTS, OCTAHEDRON_FACES)) < 1e-2


def test_a_flip_improves_the_aspect():
    """A prism on a flat rhombus whose caps are cut along the long diagonal: flipping to the short one
    makes the caps' triangles far less thin, and the prism stays closed with its volume."""
    rhombus = np.array([[-2.0, 0.0], [0.0, -0.3], [2.0, 0.0], [0.0, 0.3]])
    points = np.vstack([np.c_[rhombus, np.zeros(4)], np.c_[rhombus, np.ones(4)]])
    bottom = [[0, 2, 1], [0, 3, 2]]  # split along 0-2, the long diagonal, facing -z
    top = [[4, 5, 6], [4, 6, 7]]
    sides = []
    for i in range(4):
        j = (i + 1) % 4
        sides += [[i, j, 4 + j], [i, 4 + j, 4 + i]]
    faces = np.array(bottom + top + sides, np.int64)
    assert _closed_manifold(faces) and _volume(points, faces) > 0
    caps = slice(0, 4)
    before = _aspects(points, faces[caps]).max()
    he = _half_edges(points, faces, scale=1.0)
    done = _clean(he, _rules(bad=3.0))
    assert done[1] >= 1 and done[0] == 0  # flips, no collapse
    out_points, out_faces, *_ = remesh.compact(he)
    flat = (
        np.abs(np.cross(*(out_points[out_faces[:, k]] - out_points[out_faces[:, 0]] for k in (1, 2)))[:, :2]).sum(
            axis=1
        )
        < 1e-12
    )  # faces in a plane z = const: the caps
    assert flat.sum() == 4
    assert _aspects(out_points, out_faces[flat]).max() < before / 2
    assert _closed_manifold(out_faces) and len(out_faces) == len(faces)
    assert _volume(out_points, out_faces) == pytest.approx(_volume(points, faces), rel=1e-12)


@pytest.fixture(scope="module")
def fork():
    """The union of a fork: a trunk and two children leaning out of its top, as the cleanup gets it."""
    skeleton = make_skeleton(
        start=[[0, 0, 0], [0, 0, 1], [0, 0, 1]],
        end=[[0, 0, 1], [0.5, 0, 1.8], [-0.4, 0.3, 1.7]],
        width_start=[0.2, 0.14, 0.12],
        width_end=[0.18, 0.1, 0.08],
        parent=[-1, 0, 0],
        order=[0, 1, 1],
    )
    tubes = sweep(skeleton, SweepOptions(sides=8))
    return tubes, union(tubes)


def _fork_half_edges(fork):
    """The cleanup's half-edges of the fork's union: classified (tube, cap, scale) and marked (seams, rims)."""
    tubes, raw = fork
    return cleanup_module._half_edges(raw, tubes, 16), raw


def test_collar_and_fairing_round_the_crease_and_keep_the_volume(fork):
    he, raw = _fork_half_edges(fork)
    before = _volume(raw.vertices, raw.faces)
    closeness = np.zeros(len(he.points))
    in_collar = remesh.collar(he, 3.0, closeness)
    seam = (he.flags[: len(raw.vertices)] & remesh.SEAM) != 0
    assert seam.any() and in_collar > seam.sum()
    assert (closeness[: len(raw.vertices)][seam] == 1.0).all() and ((closeness >= 0) & (closeness <= 1)).all()
    start = he.points.copy()
    faired = remesh.fair(he, closeness, 10, 0.8, 0.5, False)
    assert faired > 0
    moved = np.linalg.norm(he.points - start, axis=1) > 0
    assert moved.any() and (closeness[moved] > 0).all()  # only collar vertices move
    points, faces, *_ = remesh.compact(he)
    assert _closed_manifold(faces)
    after = _volume(points, faces)
    assert after >= before  # outwards only: the crease fills
    assert after == pytest.approx(before, rel=0.02)


def test_rescue_keeps_the_fork_closed(fork):
    he, raw = _fork_half_edges(fork)
    remesh.rescue(he, 50.0, 1e-6, 0.5)
    points, faces, *_ = remesh.compact(he)
    assert _closed_manifold(faces)
    assert _volume(points, faces) == pytest.approx(_volume(raw.vertices, raw.faces), rel=1e-3)
    assert _aspects(raw.vertices, raw.faces).max() > 1000 and _aspects(points, faces).max() < 50.0


def test_corner_normals_of_a_cube_are_its_faces_normals():
    corners = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], np.float64)
    quads = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    faces = np.array([t for a, b, c, d in quads for t in ([a, b, c], [a, c, d])], np.int64)
    assert _closed_manifold(faces) and _volume(corners, faces) == pytest.approx(1.0)
    normals = remesh.corner_normals(corners, faces, np.ones(len(faces), bool))
    a, b, c = (corners[faces[:, k]] for k in range(3))
    own = np.cross(b - a, c - a)
    own /= np.linalg.norm(own, axis=1)[:, None]
    assert normals.shape == (12, 3, 3) and normals.dtype == np.float32
    assert np.allclose(normals, own[:, None, :])
    assert np.allclose(np.abs(own).max(axis=1), 1.0)  # axis-aligned


def test_corner_normals_of_a_cylinder_are_radial_on_the_wall_and_axial_on_the_caps():
    sides = 16
    angle = 2 * np.pi * np.arange(sides) / sides
    ring = np.c_[np.cos(angle), np.sin(angle)]
    points = np.vstack([np.c_[ring, np.zeros(sides)], np.c_[ring, np.ones(sides)], [[0, 0, 0], [0, 0, 1]]])
    bottom_centre, top_centre = 2 * sides, 2 * sides + 1
    wall, caps = [], []
    for i in range(sides):
        j = (i + 1) % sides
        wall += [[i, j, sides + j], [i, sides + j, sides + i]]
        caps += [[bottom_centre, j, i], [top_centre, sides + i, sides + j]]
    faces = np.array(wall + caps, np.int64)
    assert _closed_manifold(faces) and _volume(points, faces) > 0
    flat = np.r_[np.zeros(len(wall), bool), np.ones(len(caps), bool)]
    normals = remesh.corner_normals(points, faces, flat).astype(np.float64)
    wall_normals = normals[: len(wall)].reshape(-1, 3)
    wall_points = points[faces[: len(wall)].ravel()]
    radial = np.c_[wall_points[:, :2], np.zeros(len(wall_points))]
    assert np.allclose(wall_normals, radial, atol=1e-6)  # smooth across the wall: the ring's own radial direction
    cap_normals = normals[len(wall) :].reshape(-1, 3)
    cap_z = np.repeat(np.where(np.arange(len(caps)) % 2 == 0, -1.0, 1.0), 3)
    assert np.allclose(cap_normals, np.c_[np.zeros((len(cap_z), 2)), cap_z], atol=1e-6)
