"""The place a plant grows in: scene meshes with roles, as the turtle and the query modules see them.

A grammar's ``[environment]`` table (or ``--environment FILE``) names meshes and their roles::

    [environment]
    support = "scenes/wall.obj"     # climbers adhere to it, climb it, keep within `distance` of it
    obstacle = ["scenes/post.obj"]  # a segment that would enter it slides along it, or is cut
    volume = "scenes/box.obj"       # topiary: a segment that would leave this closed mesh is cut
    mode = "deflect"                # or "prune": what an obstacle does to a segment that would enter it
    distance = 0.12                 # a climber's segment ending farther from the support is cut
    light = [0.3, 1, 0.5]           # the direction toward the light; phototropism bends toward it

The meshes are read as data by the guarded model reader (:func:`lsys3d.external.load_scene`; ``.glb``,
``.gltf``, ``.obj``, ``.ply``, ``.stl``, and ``.usd``/``.usda``/``.usdc``/``.usdz`` through usd-core).
A scene file given with ``--environment`` takes each mesh's role from its name (``support...``,
``obstacle...``, ``volume...``; any other mesh is an obstacle).

The turtle asks the scene at every segment (:func:`lsys3d.turtle.scene._steer`), so its questions cost
a few grid samples: each role's signed distance (positive outside the solid) is sampled once on a grid
over the scene (``resolution`` cells along its longest side).  The distance is exact at the nodes within
a band around the surface (trimesh's closest-point query to the triangles of the nearest surface samples)
and, elsewhere, the distance to the nearest of points sampled on the triangles every half cell (a k-d
tree, scipy; within a third of a cell); the sign of a closed mesh comes from the ray-cast inside test
(trimesh's rays, Embree when ``embreex`` is installed), asked once per region of nodes clear of the
surface.  Between two nodes it is trilinear, which is exact for a plane.  ``?E`` modules are answered by
the same grids, and the light they receive by a ray toward the light against the scene's meshes.
"""

from __future__ import annotations

import hashlib
import logging
import math
from collections import OrderedDict
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np

from ..errors import AssetError, clip
from ..external import grammar_folder, load_scene, read_file, resolve
from ..lsystem.grammar import table_error
from ..lsystem.presets import bundled_folder
from ..options import Options, merge_table, option
from .scene import (
    SCENE_ADHESION,
    SCENE_CLEARANCE,
    SCENE_CLIMB,
    SCENE_DEFLECT,
    SCENE_DISTANCE,
    SCENE_HANG,
    SCENE_LIGHT,
    SCENE_LIGHT_POINT,
    SCENE_PARAMS,
    SCENE_PHOTOTROPISM,
    SCENE_REACH,
    SCENE_RELEASE,
    SCENE_SOLID_SUPPORT,
    Scene,
    probe,
)

__all__ = [
    "GRID_CACHE_BYTES",
    "GRID_CACHE_SIZE",
    "MAX_SCENE_BYTES",
    "MAX_SCENE_EXTENT",
    "MAX_SCENE_TRIANGLES",
    "ROLES",
    "SCENE_SUFFIXES",
    "Environment",
    "EnvironmentOptions",
    "SceneMesh",
    "clear_grid_cache",
    "load_environment",
]

log = logging.getLogger("lsys3d")

ROLES = ("obstacle", "support", "volume")
"""What a scene mesh is to the plant."""
SCENE_SUFFIXES = (".glb", ".gltf", ".obj", ".ply", ".stl", ".usd", ".usda", ".usdc", ".usdz")
"""The scene files lsys3d reads."""
MAX_SCENE_BYTES = 64 << 20
"""Largest scene file read, in bytes."""
MAX_SCENE_TRIANGLES = 500_000
"""Most triangles of one scene file."""
MAX_SCENE_EXTENT = 10_000.0
"""Largest size of a scene, in metres (a scene in millimetres read as metres is refused, not gridded)."""


@dataclass(frozen=True)
class EnvironmentOptions(Options):
    """The environment: its meshes, their roles and how the plant answers them (``docs/environment.md``).

    A grammar's ``[environment]`` table sets any field; ``--environment FILE`` (``environment``) adds a
    scene file whose meshes take their role from their names.
    """

    environment: str = option(
        "",
        help="scene file (.glb .gltf .obj .ply .stl .usd*) the plant grows in: meshes named support*, volume* or "
        "obstacle* take that role (any other: obstacle); see docs/environment.md",
        metavar="FILE",
    )
    obstacle: tuple = option((), kind="strings", cli=False, name="env_obstacle", help="obstacle mesh files")
    support: tuple = option((), kind="strings", cli=False, name="env_support", help="support mesh files (climbers)")
    volume: tuple = option((), kind="strings", cli=False, name="env_volume", help="closed pruning volume files")
    mode: str = option(
        "deflect", choices=("deflect", "prune"), cli=False, name="env_mode", help="obstacles deflect or cut"
    )
    distance: float = option(
        0.0, low=0, cli=False, name="env_distance", help="most distance of a climber from its support (0: any)"
    )
    adhesion: float = option(
        0.8, low=0, high=1, cli=False, name="env_adhesion", help="how far the heading is pulled onto the support"
    )
    climb: float = option(
        0.5, low=0, high=10, cli=False, name="env_climb", help="pull of the heading up the support (against gravity)"
    )
    hang: float = option(
        0.0, low=0, high=1, cli=False, name="env_hang", help="bend toward the ground per segment away from a support"
    )
    release: float = option(
        0.0,
        low=0,
        high=1,
        cli=False,
        name="env_release",
        help="a climber lets go where its support's normal points up more than this (0..1; 0: never): over a "
        "top edge or a ledge it leans out and hangs",
    )
    reach: float = option(
        0.0, low=0, cli=False, name="env_reach", help="distance within which the support holds (0: 2 x distance)"
    )
    clearance: float = option(
        0.0, low=0, cli=False, name="env_clearance", help="gap kept between a segment's end and a solid surface"
    )
    light: tuple = option(
        (0.0, 0.0, 0.0), kind="vector", cli=False, name="env_light", help="direction toward the light (0: none)"
    )
    light_point: tuple = option(
        (), kind="vector", cli=False, name="env_light_point", help="a point light instead of a direction: x, y, z"
    )
    phototropism: float = option(
        0.0, low=0, high=1, cli=False, name="env_phototropism", help="bend of each segment toward the light"
    )
    resolution: int = option(
        64, low=8, high=256, cli=False, name="env_resolution", help="grid cells along the scene's longest side"
    )
    bud: str = option(
        "", cli=False, name="env_bud", help="symbol left where the scene cut a segment (a marked bud; '': none)"
    )

    shadow: bool = option(
        False, cli=False, name="env_shadow", help="the plant shades itself: ?E's light through its own area"
    )
    shadow_voxel: float = option(
        0.1, low=1e-4, cli=False, name="env_shadow_voxel", help="voxel size of the shade grid, in metres"
    )
    shadow_extinction: float = option(
        0.5, low=0, high=100, cli=False, name="env_shadow_extinction", help="Beer-Lambert extinction per area density"
    )

    @property
    def active(self) -> bool:
        return bool(
            self.environment or self.obstacle or self.support or self.volume or self.phototropism > 0 or self.shadow
        )

    @classmethod
    def from_grammar(cls, grammar, options: EnvironmentOptions | None = None) -> EnvironmentOptions:
        """The grammar's ``[environment]`` table, with ``options``' non-default fields over it."""
        options = options or cls()
        table = dict(getattr(grammar, "environment", {}) or {})
        if not table:
            return options
        return merge_table(cls, table, options, partial(table_error, grammar, "environment"), as_tuple=ROLES)


@dataclass(frozen=True, eq=False)
class SceneMesh:
    """One mesh of the scene, in the plant's coordinates (metres, Y up).

    Attributes
    ----------
    role : str
        One of :data:`ROLES`.
    name : str
        The mesh's (node's) name in its file.
    vertices : (n, 3) float64
    faces : (f, 3) int64
    closed : bool
        Watertight, with a consistent winding: it has an inside.
    source : str
        The file it came from.
    """

    role: str
    name: str
    vertices: np.ndarray
    faces: np.ndarray
    closed: bool
    source: str = ""

    def trimesh(self):
        import trimesh

        return trimesh.Trimesh(self.vertices, self.faces, process=False)


# ---------------------------------------------------------------- reading


def _too_many(shown: str, count: int) -> str:
    return (
        f"{shown}: the scene has {count:,} triangles, more than {MAX_SCENE_TRIANGLES:,} "
        "(lsys3d.turtle.environment.MAX_SCENE_TRIANGLES)"
    )


def _role_of(name: str, default: str) -> str:
    low = name.lower()
    for role in ROLES:
        if low.startswith(role):
            return role
    return default


def _usd_meshes(path: Path, shown: str) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """The triangles of every UsdGeom.Mesh of a USD file, in world space, metres and Y up."""
    try:
        from pxr import Usd, UsdGeom
    except ImportError:  # pragma: no cover - usd-core is a dependency
        raise AssetError(f"{shown}: reading USD needs usd-core") from None
    read_file(path, MAX_SCENE_BYTES, "scene", "lsys3d.turtle.environment.MAX_SCENE_BYTES")  # the checks only
    try:
        stage = Usd.Stage.Open(str(path))
    except Exception as exc:
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise AssetError(f"{shown}: not a readable USD scene ({clip(reason, 80)})") from None
    if stage is None:
        raise AssetError(f"{shown}: not a readable USD scene")
    scale = UsdGeom.GetStageMetersPerUnit(stage) or 1.0
    z_up = UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    out = []
    cache = UsdGeom.XformCache()
    for prim in stage.Traverse():
        if not prim.IsA(UsdGeom.Mesh):
            continue
        mesh = UsdGeom.Mesh(prim)
        points = np.asarray(mesh.GetPointsAttr().Get() or [], np.float64).reshape(-1, 3)
        counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get() or [], np.int64)
        indices = np.asarray(mesh.GetFaceVertexIndicesAttr().Get() or [], np.int64)
        if not len(points) or not len(counts) or counts.sum() != len(indices) or (counts < 3).any():
            continue
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
        tri = []
        for s, c in zip(starts.tolist(), counts.tolist(), strict=True):  # a fan per polygon
            k = np.arange(1, c - 1)
            tri.append(np.stack([np.full(len(k), indices[s]), indices[s + k], indices[s + k + 1]], -1))
        faces = np.concatenate(tri).reshape(-1, 3)
        if faces.max() >= len(points):
            raise AssetError(f"{shown}: mesh {clip(repr(prim.GetName()))} has a face pointing past its points")
        matrix = np.asarray(cache.GetLocalToWorldTransform(prim), np.float64)
        world = points @ matrix[:3, :3] + matrix[3, :3]
        world *= scale
        if z_up:  # (x, y, z) -> (x, z, -y): a rotation, the winding stays
            world = world[:, [0, 2, 1]] * [1.0, 1.0, -1.0]
        out.append((prim.GetName(), world, faces))
        if sum(len(f) for _, _, f in out) > MAX_SCENE_TRIANGLES:
            raise AssetError(_too_many(shown, sum(len(f) for _, _, f in out)))
    return out


def read_scene(path, default_role: str = "obstacle", names_give_roles: bool = True) -> list[SceneMesh]:
    """The meshes of a scene file, each with its role (from its name, else ``default_role``).

    Raises
    ------
    AssetError
        One line: not a scene file lsys3d reads, unreadable, no triangles, too many, not finite, too large.
    """
    path = Path(path)
    shown = clip(str(path), 100)
    suffix = path.suffix.lower()
    if suffix not in SCENE_SUFFIXES:
        raise AssetError(f"{shown}: a scene must be {', '.join(SCENE_SUFFIXES)}, not {clip(repr(path.suffix))}")
    if suffix.startswith(".usd"):
        parts = _usd_meshes(path, shown)
    else:
        data = read_file(path, MAX_SCENE_BYTES, "scene", "lsys3d.turtle.environment.MAX_SCENE_BYTES")
        if suffix == ".gltf":  # its buffers are files beside it: trimesh resolves them from the folder
            import trimesh

            try:
                scene = trimesh.load(str(path), process=False, force="scene")
            except Exception as exc:
                reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
                raise AssetError(f"{shown}: not a readable .gltf scene ({clip(reason, 80)})") from None
        else:
            scene = load_scene(data, suffix[1:], shown, MAX_SCENE_TRIANGLES, _too_many)
        parts = []
        for node in scene.graph.nodes_geometry:
            transform, geometry = scene.graph[node]
            g = scene.geometry[geometry]
            if not hasattr(g, "faces") or not len(g.faces):
                continue
            v = np.asarray(g.vertices, np.float64) @ transform[:3, :3].T + transform[:3, 3]
            parts.append((str(node if node != geometry else geometry), v, np.asarray(g.faces, np.int64)))
    if not parts:
        raise AssetError(f"{shown}: the scene has no triangles")
    out = []
    for name, v, f in parts:
        if not np.isfinite(v).all():
            raise AssetError(f"{shown}: mesh {clip(repr(name))} has vertices that are not finite numbers")
        if f.min() < 0 or f.max() >= len(v):
            raise AssetError(f"{shown}: mesh {clip(repr(name))} has a face pointing past its vertices")
        extent = float(np.ptp(v, axis=0).max()) if len(v) else 0.0
        if extent > MAX_SCENE_EXTENT or np.abs(v).max() > MAX_SCENE_EXTENT:
            raise AssetError(
                f"{shown}: mesh {clip(repr(name))} reaches {np.abs(v).max():.4g} m, beyond {MAX_SCENE_EXTENT:g} m "
                "(lsys3d.turtle.environment.MAX_SCENE_EXTENT): is it in millimetres?"
            )
        role = _role_of(name, default_role) if names_give_roles else default_role
        out.append(SceneMesh(role, name, v, f, _closed(v, f), shown))
    return out


def _closed(vertices: np.ndarray, faces: np.ndarray) -> bool:
    import trimesh

    mesh = trimesh.Trimesh(vertices, faces, process=True)
    return bool(mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0)


# ---------------------------------------------------------------- the environment


@dataclass(frozen=True, eq=False)
class Environment:
    """The scene's meshes and the options: what :func:`lsys3d.turtle.kernel.run` and ``?E`` ask.

    Build it with :func:`load_environment`; :meth:`scene` samples the grids (once).
    """

    meshes: tuple[SceneMesh, ...]
    options: EnvironmentOptions

    def role(self, role: str) -> tuple[SceneMesh, ...]:
        return tuple(m for m in self.meshes if m.role == role)

    def combined(self, *roles: str):
        """The meshes of these roles as one trimesh (None when there are none)."""
        import trimesh

        parts = [m.trimesh() for m in self.meshes if m.role in roles]
        return trimesh.util.concatenate(parts) if parts else None

    def scene(self) -> Scene:
        """The kernel's view: signed distance grids per role and the steering parameters."""
        cached = self.__dict__.get("_scene")
        if cached is None:
            cached = _build(self)
            object.__setattr__(self, "_scene", cached)
        return cached

    def probe(self, points: np.ndarray) -> np.ndarray:
        """``?E``'s answers at points: ``(k, 3)`` of blocked (1/0), distance to a surface, light received."""
        sc = self.scene()
        points = np.asarray(points, np.float64).reshape(-1, 3)
        out = np.zeros((len(points), 3))
        if not len(points):
            return out
        out[:, :2] = _probe(sc, points)
        surfaces = self.combined("obstacle", "support")
        if surfaces is not None:  # the distance exactly, on trimesh's R-tree of the triangles
            import trimesh

            out[:, 1] = trimesh.proximity.closest_point(surfaces, points)[1]
        out[:, 2] = self.light_received(points)
        return out

    def light_received(self, points: np.ndarray) -> np.ndarray:
        """1 where a ray from the point toward the light meets no scene mesh, else 0 (1 everywhere without light)."""
        o = self.options
        blockers = self.combined("obstacle", "support")
        if blockers is None or (not any(o.light) and not o.light_point):
            return np.ones(len(points))
        if o.light_point:
            direction = np.asarray(o.light_point, np.float64) - points
        else:
            direction = np.broadcast_to(np.asarray(o.light, np.float64), points.shape).copy()
        norm = np.linalg.norm(direction, axis=1, keepdims=True)
        direction = direction / np.where(norm > 0, norm, 1.0)
        hit = blockers.ray.intersects_any(points + direction * 1e-6, direction)
        if o.light_point:  # only what stands between the point and the light
            loc, ray, _ = blockers.ray.intersects_location(points + direction * 1e-6, direction, multiple_hits=False)
            hit = np.zeros(len(points), bool)
            if len(ray):
                near = np.linalg.norm(loc - points[ray], axis=1) < norm[ray, 0]
                hit[ray[near]] = True
        return (~hit).astype(np.float64)


def load_environment(grammar, options: EnvironmentOptions | None = None) -> Environment | None:
    """The environment of a grammar (its ``[environment]`` table, over it ``options``), None without one.

    Raises
    ------
    GrammarError
        A bad key or value in ``[environment]``.
    AssetError
        A scene file that cannot be used, in one line (``file: what``).
    """
    opts = EnvironmentOptions.from_grammar(grammar, options)
    if not opts.active:
        return None
    folder = bundled_folder(grammar) or grammar_folder(grammar)
    meshes: list[SceneMesh] = []
    for role in ROLES:
        for name in getattr(opts, role):
            path = resolve(folder, name, f"[environment] {role}")
            meshes += read_scene(path, role, names_give_roles=False)
    if opts.environment:
        meshes += read_scene(Path(opts.environment), "obstacle")
    for m in meshes:
        if m.role == "volume" and not m.closed:
            raise AssetError(
                f"{m.source}: mesh {clip(repr(m.name))} is a pruning volume: it must be a closed mesh (watertight, "
                "consistently wound) to have an inside"
            )
    if opts.distance > 0 and not any(m.role == "support" for m in meshes):
        log.warning("environment: distance is set but the scene has no support: it has no effect")
    return Environment(tuple(meshes), opts)


# ---------------------------------------------------------------- grids


def _grid_frame(env: Environment) -> tuple[np.ndarray, float, tuple[int, int, int]]:
    o = env.options
    lo = np.min([m.vertices.min(axis=0) for m in env.meshes], axis=0)
    hi = np.max([m.vertices.max(axis=0) for m in env.meshes], axis=0)
    extent = float((hi - lo).max())
    cell = max(extent, 1e-6) / o.resolution
    margin = max(2.0 * cell, 2.0 * _reach(o), o.distance) + 2.0 * cell
    lo = lo - margin
    hi = hi + margin
    shape = tuple(math.ceil(x / cell) + 1 for x in (hi - lo))
    return lo, cell, shape


def _reach(o: EnvironmentOptions) -> float:
    return o.reach if o.reach > 0 else 2.0 * o.distance


def _signed_distance(meshes: tuple[SceneMesh, ...], origin, cell, shape, band: float, most: float) -> np.ndarray:
    """Signed distance (positive outside) to these meshes at the grid's nodes; unsigned for open meshes.

    Distances beyond ``most`` are ``most`` (the turtle compares them with nothing larger).
    A k-d tree (scipy) over points sampled on the triangles every half cell gives each node its
    nearest samples: their distance bounds the node's from above (within a third of a cell), and
    within ``band`` of the surface the exact distance to the samples' triangles (trimesh) replaces it.
    """
    import trimesh
    from scipy.spatial import cKDTree

    mesh = trimesh.util.concatenate([m.trimesh() for m in meshes])
    closed = all(m.closed for m in meshes)
    nodes = np.stack(np.meshgrid(*[np.arange(n) for n in shape], indexing="ij"), -1).reshape(-1, 3)
    points = origin + nodes * cell
    samples, owner = _surface_points(mesh, 0.5 * cell)
    # the nearest sample's distance is the same whatever the tree's shape; this one answers the grid's many
    # queries that find nothing within ``most`` in about half the time of the default (topiary, ivy-wall)
    bound = cKDTree(samples, leafsize=64, balanced_tree=False, compact_nodes=False)
    distance, _ = bound.query(points, k=1, distance_upper_bound=most, workers=-1)
    distance = np.minimum(distance, most)
    # the samples lie within a third of a cell of every surface point: beyond 1.5 cells a node is a cell clear
    clear = distance > 1.5 * cell
    near = np.flatnonzero(distance <= band)
    if len(near):
        _, idx = cKDTree(samples).query(points[near], k=4, workers=-1)
        candidates = np.sort(owner[idx], axis=1)  # (k, 4) triangles
        # each (node, triangle) pair once: the nearest samples often lie on one triangle
        first = np.ones(candidates.shape, bool)
        first[:, 1:] = candidates[:, 1:] != candidates[:, :-1]
        row = np.broadcast_to(near[:, None], candidates.shape)[first]
        closest = trimesh.triangles.closest_point(mesh.triangles[candidates[first]], points[row])
        gap = np.full(candidates.shape, np.inf)
        gap[first] = np.linalg.norm(closest - points[row], axis=1)
        distance[near] = gap.min(axis=1)
    if closed:
        distance = np.where(_inside(mesh, points, shape, clear), -distance, distance)
    return np.ascontiguousarray(distance.reshape(shape))


def _inside(mesh, points: np.ndarray, shape, clear: np.ndarray) -> np.ndarray:
    """trimesh's ray-cast inside test at the grid's nodes, asked once per region of nodes clear of the surface.

    ``clear`` marks the nodes more than a cell from the surface: a node and its neighbour (a cell away) of
    which one is clear lie on the same side, so each 6-connected region of clear nodes is inside or outside as
    a whole. The test is asked at the other nodes and at the first and last node of each region; a region
    whose two answers differ (the ray test's own doubt) has it asked at each of its nodes. The same answers as
    asking every node (topiary's grid: 0.5 CPU s -> 0.05).
    """
    from scipy import ndimage

    labels, count = ndimage.label(clear.reshape(shape))
    labels = labels.reshape(-1)
    inside = np.zeros(len(points), bool)
    first = last = np.empty(0, np.int64)
    if count:  # label 0: the nodes not clear
        first = np.unique(labels, return_index=True)[1][1:]
        last = len(labels) - 1 - np.unique(labels[::-1], return_index=True)[1][1:]
    ask = np.union1d(np.flatnonzero(labels == 0), np.concatenate([first, last]))
    inside[ask] = _ray_inside(mesh, points[ask])
    if count:
        agree = np.ones(count + 1, bool)
        agree[1:] = inside[first] == inside[last]
        side = np.zeros(count + 1, bool)
        side[1:] = inside[first]
        region = labels > 0
        settled = region & agree[labels]
        inside[settled] = side[labels[settled]]
        doubt = np.flatnonzero(region & ~agree[labels])
        if len(doubt):
            inside[doubt] = _ray_inside(mesh, points[doubt])
    return inside


_RAYS = (np.array([0.4395064455, 0.617598629942, 0.652231566745]), np.array([-0.5183, 0.3079, 0.7979]))
"""The directions of :func:`_ray_inside`'s rays: trimesh's own, then a fixed one where it takes a random one."""


def _ray_inside(mesh, points: np.ndarray) -> np.ndarray:
    """trimesh's inside test (``Trimesh.contains``) with its second try along a fixed direction: the same
    answer in every process.

    From each point inside the mesh's bounds a ray goes both ways along one direction: inside when both cross
    the surface an odd number of times, outside when both an even number; a point whose two rays disagree, both
    crossing something (on the surface, or the ray grazing an edge), is asked again along another direction
    (trimesh takes a random one, so a node on the surface could come out inside in one process and outside in
    another: four nodes of ivy-wall's wall did) and stays outside if they still disagree.
    """
    from trimesh.bounds import contains

    inside = np.zeros(len(points), bool)
    todo = np.flatnonzero(contains(mesh.bounds, points))
    for direction in _RAYS:
        if not len(todo):
            break
        rays = np.tile(direction, (len(todo), 1))
        _, ray, _ = mesh.ray.intersects_location(
            np.vstack((points[todo], points[todo])), np.vstack((rays, -rays)), multiple_hits=True
        )
        hits = np.bincount(ray, minlength=2 * len(todo)).reshape(2, -1)
        odd = hits % 2 == 1
        agree = odd[0] == odd[1]
        inside[todo[agree]] = odd[0][agree]
        todo = todo[~agree & (hits > 0).all(axis=0)]
    return inside


def _surface_points(mesh, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Points on every triangle at most ``spacing`` apart (a barycentric lattice), and each one's triangle."""
    tri = mesh.triangles
    longest = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).max(axis=1)
    steps = np.maximum(1, np.ceil(longest / spacing).astype(np.int64))
    points, owner = [], []
    for k in np.unique(steps).tolist():
        which = np.flatnonzero(steps == k)
        i, j = np.meshgrid(np.arange(k + 1), np.arange(k + 1), indexing="ij")
        keep = i + j <= k
        a, b = i[keep] / k, j[keep] / k
        w = np.stack([1 - a - b, a, b], -1)  # (p, 3)
        points.append(np.einsum("pc,tcd->tpd", w, tri[which]).reshape(-1, 3))
        owner.append(np.repeat(which, len(w)))
    return np.concatenate(points), np.concatenate(owner)


GRID_CACHE_SIZE = 16
"""Distance grids kept in memory for the process (:func:`_cached_distance`): a scene drawn again (the pipeline's
``draw()`` in a loop, the editor, levels of detail, variants) is not sampled again."""
GRID_CACHE_BYTES = 256 * 2**20
"""Most bytes those grids hold together (a grid at ``env_resolution`` 256 alone is 134 MB): the oldest go first,
so a long-running process (a batch worker, the editor) drawing many scenes does not grow without bound."""
_GRIDS: OrderedDict[bytes, np.ndarray] = OrderedDict()


def clear_grid_cache() -> None:
    """Forget the distance grids sampled so far in this process (the next :meth:`Environment.scene` samples)."""
    _GRIDS.clear()


def _cached_distance(meshes: tuple[SceneMesh, ...], origin, cell, shape, band: float, most: float) -> np.ndarray:
    """:func:`_signed_distance`, kept by what it is computed from: the meshes' triangles and closedness, and
    the grid (origin, cell, shape, band, most), hashed (SHA-256), so the same scene file and options give
    the grid again, bytes for bytes, without sampling it; a copy is handed out (the turtle's arrays are its own)."""
    h = hashlib.sha256()
    for m in meshes:
        h.update(b"closed" if m.closed else b"open")
        for a in (np.ascontiguousarray(m.vertices, np.float64), np.ascontiguousarray(m.faces, np.int64)):
            h.update(np.array(a.shape, np.int64).tobytes())
            h.update(a.tobytes())
    h.update(np.array([*np.asarray(origin, np.float64), cell, band, most], np.float64).tobytes())
    h.update(np.array(shape, np.int64).tobytes())
    key = h.digest()
    found = _GRIDS.get(key)
    if found is None:
        found = _signed_distance(meshes, origin, cell, shape, band, most)
        _GRIDS[key] = found.copy()
        while len(_GRIDS) > GRID_CACHE_SIZE or sum(g.nbytes for g in _GRIDS.values()) > GRID_CACHE_BYTES:
            _GRIDS.popitem(last=False)
    else:
        _GRIDS.move_to_end(key)
        found = found.copy()
    return found


def _build(env: Environment) -> Scene:
    o = env.options
    empty = np.zeros((0, 0, 0))
    if not env.meshes:
        origin, cell, shape = np.zeros(3), 1.0, (0, 0, 0)
    else:
        origin, cell, shape = _grid_frame(env)
    band = max(o.clearance, 1.5 * cell)
    most = max(_reach(o), o.distance, o.clearance) + 4.0 * cell
    grids = {}
    for role in ROLES:
        meshes = env.role(role)
        grids[role] = _cached_distance(meshes, origin, cell, shape, band, most) if meshes else empty
    params = np.zeros(SCENE_PARAMS)
    params[SCENE_DISTANCE] = o.distance
    params[SCENE_ADHESION] = o.adhesion
    params[SCENE_CLIMB] = o.climb
    params[SCENE_HANG] = o.hang
    params[SCENE_PHOTOTROPISM] = o.phototropism if (any(o.light) or o.light_point) else 0.0
    if o.light_point:
        params[SCENE_LIGHT : SCENE_LIGHT + 3] = o.light_point
        params[SCENE_LIGHT_POINT] = 1.0
    else:
        params[SCENE_LIGHT : SCENE_LIGHT + 3] = o.light
    params[SCENE_DEFLECT] = 1.0 if o.mode == "deflect" else 0.0
    # a tenth of a cell more: between the nodes near a solid's edge or corner the trilinear distance is a
    # little larger than the true one
    params[SCENE_CLEARANCE] = o.clearance + 0.1 * cell
    params[SCENE_SOLID_SUPPORT] = 1.0 if all(m.closed for m in env.role("support")) else 0.0
    params[SCENE_REACH] = _reach(o) if _reach(o) > 0 else 4.0 * cell
    params[SCENE_RELEASE] = o.release
    log.info("environment: %d mesh(es), grid %s of %.4g m", len(env.meshes), "x".join(map(str, shape)), cell)
    return Scene(np.asarray(origin, np.float64), np.array([cell]), grids["obstacle"], grids["volume"],
                        grids["support"], params)  # fmt: skip


def _probe(scene: Scene, points: np.ndarray) -> np.ndarray:
    out = np.empty((len(points), 2))
    probe(scene, points, out)
    return out
