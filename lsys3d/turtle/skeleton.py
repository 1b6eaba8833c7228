"""The branch skeleton: what the turtle draws, as arrays.

This is the contract between the turtle (:mod:`lsys3d.turtle`) and the mesh
stages (:mod:`lsys3d.mesh.sweep`, :mod:`lsys3d.mesh.union.union`).  Every array is indexed by
segment (``n`` segments), leaf polygon or leaf instance; none holds Python
objects.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from .commands import BUILT_IN_ORGANS

__all__ = ["MAX_COORDINATE", "Chains", "Skeleton", "organ_names"]

MAX_COORDINATE = 1e9
"""Largest distance from the origin along any axis, and largest width or leaf size, a skeleton may hold.

A million kilometres: far beyond any plant, and far inside what the mesh stages compute with (the sweep squares
lengths, the union welds on a 1e-8 grid of 64-bit integers, the files store 32-bit floats).  The turtle refuses
to go past it, naming the module; the sweep refuses a skeleton built some other way that does.
"""


@dataclass(frozen=True)
class Chains:
    """Unbranched runs of segments, stored like a CSR matrix.

    ``segments[offsets[c]:offsets[c + 1]]`` are the segment indices of chain
    ``c`` from its base to its tip.  ``chain_of[s]`` is the chain of segment ``s``.
    """

    offsets: np.ndarray  # (c + 1,) int64
    segments: np.ndarray  # (n,) int64
    chain_of: np.ndarray  # (n,) int64

    def __len__(self) -> int:
        return len(self.offsets) - 1

    def lengths(self) -> np.ndarray:
        """Number of segments of each chain, ``(c,) int64``."""
        return np.diff(self.offsets)


@dataclass(frozen=True, eq=False)
class Skeleton:
    """Segments, leaves and leaf instances drawn by the turtle.

    Segments (``n``):

    start, end : (n, 3) float64
        End points, world coordinates (Y up, metres by convention).
    width_start, width_end : (n,) float64
        Branch diameter at each end.
    heading, left, up : (n, 3) float64
        The turtle frame while the segment was drawn (orthonormal, H x L = U).
    parent : (n,) int64
        The segment whose end this one starts from, or -1.
    order : (n,) int32
        Branch order: 0 for the trunk, +1 per lateral branch (bracket level
        relative to the parent).
    material : (n,) int32
        Material / colour index set with ``'``.
    module : (n,) int64
        Index of the module that drew the segment, in the string the turtle read
        (after the homomorphism rules: :func:`lsys3d.lsystem.derive.interpretation`).

    Leaf polygons (``p`` polygons, drawn with ``{ . }``):

    polygon_points : (q, 3) float64
    polygon_offsets : (p + 1,) int64
        Points of polygon ``i`` are ``polygon_points[polygon_offsets[i]:polygon_offsets[i+1]]``.
    polygon_material : (p,) int32
    polygon_segment : (p,) int64 or None
        The segment the polygon grows from (the last segment drawn in its
        branch when ``{`` opened it), -1 for none; None when unknown.

    Leaf instances (``k``, placed by the leaf symbol):

    leaf_position, leaf_heading, leaf_left, leaf_up : (k, 3) float64
    leaf_size : (k,) float64
        Scale of the leaf model (the step length in force).
    leaf_material : (k,) int32
    leaf_segment : (k,) int64 or None
        The segment (twig) the leaf grows from, -1 for none; None when unknown.

    Organs (``o``, recorded by the dialects' spheres, discs, named surfaces and
    instances: cpfg's and L-Py's ``@O``, ``@c``, ``@o``, ``~l``, Houdini's ``J``;
    the skeleton records them, the mesh stages do not build them yet):

    organ_kind : (o,) int8
        What each organ is (:class:`lsys3d.turtle.Organ`: sphere, disc, circle, surface, instance, box).
    organ_position, organ_heading, organ_left, organ_up : (o, 3) float64
    organ_size : (o,) float64
        The diameter of a sphere, disc or circle (in width units, as widths), the
        scale of a surface or instance.
    organ_material : (o,) int32
    organ_segment : (o,) int64
        The segment the organ grows from, -1 for none.
    organ_module : (o,) int64
        The index of the module that recorded it, in the string the turtle read (after
        the grammar's homomorphism rules).
    organ_name : (o,) str
        The name of that module as written (``@O``, ``~l``, ``J``): a surface's or an
        instance's name, kept so that the mesh stages need not keep the string.
    organ_scale : (o, 3) float64 or None
        Each organ's scale along left, up and heading relative to ``organ_size`` (cpfg's
        ``~l(sx, sy, sz)``: ``(1, sz / sx, sy / sx)``, :mod:`lsys3d.turtle.selections`); None: uniform.

    Times (only when the plant's development was asked for: :func:`lsys3d.turtle.timing.timed`; None
    otherwise), in the plant's time of :mod:`lsys3d.lsystem.ages`:

    birth, mature : (n,) float64
        When each segment's module was born, and when it is full grown.
    growth_function : (n,) int8
        Each segment's growth function (an index into :data:`lsys3d.lsystem.ages.FUNCTION_NAMES`).
    leaf_birth, leaf_mature : (k,) float64
        When each leaf instance starts to unfold and when it is unfolded.
    organ_birth, organ_mature : (o,) float64
        The same for each organ.

    Sides (only when the grammar sets them: cpfg's ``@!``, :mod:`lsys3d.turtle.sides`; None otherwise):

    sides : (n,) int32
        The sides of each segment's tube, 0 where the grammar set none (the sweep's ``sides`` then).
    organ_sides : (o,) int32
        The sides of each sphere and disc (cpfg's slices), 0 where the grammar set none (the organs' options).
    """

    start: np.ndarray
    end: np.ndarray
    width_start: np.ndarray
    width_end: np.ndarray
    heading: np.ndarray
    left: np.ndarray
    up: np.ndarray
    parent: np.ndarray
    order: np.ndarray
    material: np.ndarray
    module: np.ndarray
    polygon_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    polygon_offsets: np.ndarray = field(default_factory=lambda: np.zeros(1, np.int64))
    polygon_material: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int32))
    leaf_position: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    leaf_heading: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    leaf_left: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    leaf_up: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    leaf_size: np.ndarray = field(default_factory=lambda: np.zeros(0))
    leaf_material: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int32))
    polygon_segment: np.ndarray | None = None
    leaf_segment: np.ndarray | None = None
    organ_kind: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int8))
    organ_position: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    organ_heading: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    organ_left: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    organ_up: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    organ_size: np.ndarray = field(default_factory=lambda: np.zeros(0))
    organ_material: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int32))
    organ_segment: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    organ_module: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    organ_name: np.ndarray = field(default_factory=lambda: np.zeros(0, "U1"))
    organ_scale: np.ndarray | None = None
    birth: np.ndarray | None = None
    mature: np.ndarray | None = None
    leaf_birth: np.ndarray | None = None
    leaf_mature: np.ndarray | None = None
    organ_birth: np.ndarray | None = None
    organ_mature: np.ndarray | None = None
    growth_function: np.ndarray | None = None
    sides: np.ndarray | None = None
    organ_sides: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.start.shape[0])

    @classmethod
    def from_segments(
        cls,
        start,
        end,
        width_start=0.1,
        width_end=None,
        parent=None,
        order=None,
        *,
        left_hint=(0.31, 0.52, 0.79),
        **leaves,
    ) -> Skeleton:
        """A skeleton from bare segments (tests, benchmarks, skeletons made outside the turtle).

        Parameters
        ----------
        start, end : (n, 3) array_like
        width_start, width_end : float or (n,) array_like
            Diameters; ``width_end`` defaults to ``width_start``.
        parent : (n,) array_like, optional
            Default: a single chain, ``parent[s] = s - 1``.
        order : (n,) array_like, optional
            Default: all 0.
        left_hint : 3 floats
            The turtle frames follow the segment directions: heading along the
            segment, left perpendicular to it and to this hint.
        **leaves
            Polygon and leaf-instance fields (``polygon_points``, ``leaf_position``...).

        Examples
        --------
        >>> sk = Skeleton.from_segments([[0, 0, 0], [0, 1, 0]], [[0, 1, 0], [0, 2, 0]], 0.2)
        >>> len(sk), sk.parent.tolist(), len(sk.chains)
        (2, [-1, 0], 1)
        """
        start = np.asarray(start, np.float64).reshape(-1, 3)
        end = np.asarray(end, np.float64).reshape(-1, 3)
        n = len(start)
        w0 = np.broadcast_to(np.asarray(width_start, np.float64), (n,)).copy()
        w1 = w0.copy() if width_end is None else np.broadcast_to(np.asarray(width_end, np.float64), (n,)).copy()
        parent = np.arange(n, dtype=np.int64) - 1 if parent is None else np.asarray(parent, np.int64)
        order = np.zeros(n, np.int32) if order is None else np.asarray(order, np.int32)
        h = end - start
        norm = np.linalg.norm(h, axis=1, keepdims=True)
        h = np.where(norm > 0, h / np.where(norm > 0, norm, 1.0), [[0.0, 1.0, 0.0]])
        left = np.cross(np.asarray(left_hint, np.float64), h)
        left /= np.maximum(np.linalg.norm(left, axis=1, keepdims=True), 1e-300)
        return cls(
            start=start,
            end=end,
            width_start=w0,
            width_end=w1,
            heading=h,
            left=left,
            up=np.cross(h, left),
            parent=parent,
            order=order,
            material=np.zeros(n, np.int32),
            module=np.arange(n, dtype=np.int64),
            **leaves,
        )

    @property
    def n_polygons(self) -> int:
        return len(self.polygon_offsets) - 1

    @property
    def n_organs(self) -> int:
        """Organs recorded (spheres, discs, surfaces...), built by :mod:`lsys3d.look.organs`."""
        return int(self.organ_kind.shape[0])

    @property
    def n_leaves(self) -> int:
        """Leaf polygons plus leaf instances."""
        return self.n_polygons + int(self.leaf_position.shape[0])

    def lengths(self) -> np.ndarray:
        """Length of each segment, ``(n,) float64``."""
        return np.linalg.norm(self.end - self.start, axis=1)

    def bounds(self) -> np.ndarray:
        """``(2, 3)``: min and max corner of all segment end points (zeros when empty)."""
        if not len(self):
            return np.zeros((2, 3))
        pts = np.concatenate([self.start, self.end])
        return np.stack([pts.min(axis=0), pts.max(axis=0)])

    @cached_property
    def chains(self) -> Chains:
        """Split the segments into chains (unbranched runs).

        A segment continues its parent's chain when it is the parent's first
        child (in drawing order) of the parent's own branch order; when no
        child has that order, the first child drawn continues it.  Every other
        segment starts a new chain.
        """
        n = len(self)
        parent = self.parent
        has_parent = np.flatnonzero(parent >= 0)
        # preferred child of each parent: same order first, then earliest drawn
        same = self.order[has_parent] != self.order[parent[has_parent]]
        key = np.lexsort((has_parent, same, parent[has_parent]))
        ranked = has_parent[key]
        first = np.ones(len(ranked), dtype=bool)
        first[1:] = parent[ranked[1:]] != parent[ranked[:-1]]
        successor = np.full(n, -1, np.int64)
        successor[parent[ranked[first]]] = ranked[first]
        continues = np.zeros(n, dtype=bool)
        continues[successor[successor >= 0]] = True
        heads = np.flatnonzero(~continues)
        # walk each chain; total work is O(n)
        segments = np.empty(n, np.int64)
        offsets = np.zeros(len(heads) + 1, np.int64)
        succ = successor.tolist()
        k = 0
        for c, h in enumerate(heads.tolist()):
            s = h
            while s >= 0:
                segments[k] = s
                k += 1
                s = succ[s]
            offsets[c + 1] = k
        chain_of = np.empty(n, np.int64)
        chain_of[segments] = np.repeat(np.arange(len(heads)), np.diff(offsets))
        return Chains(offsets, segments, chain_of)

    def validate(self) -> None:
        """Check shapes, finiteness and parent indices; raise ValueError if broken."""
        n = len(self)
        for name in ("start", "end", "heading", "left", "up"):
            a = getattr(self, name)
            if a.shape != (n, 3):
                raise ValueError(f"skeleton.{name} has shape {a.shape}, expected ({n}, 3)")
            if not np.isfinite(a).all():
                raise ValueError(f"skeleton.{name} holds a NaN or infinite value")
        for name in ("width_start", "width_end", "parent", "order", "material", "module"):
            a = getattr(self, name)
            if a.shape != (n,):
                raise ValueError(f"skeleton.{name} has shape {a.shape}, expected ({n},)")
        if n and (self.parent >= np.arange(n)).any():
            raise ValueError("skeleton.parent must point to an earlier segment")

    def save_npz(self, path) -> None:
        """Write every array to a NumPy ``.npz`` file."""
        arrays = {k: getattr(self, k) for k in self.__dataclass_fields__ if getattr(self, k) is not None}
        np.savez(path, **arrays)

    @classmethod
    def load_npz(cls, path) -> Skeleton:
        with np.load(path) as data:
            return cls(**{k: data[k] for k in cls.__dataclass_fields__ if k in data})

    def polylines(self) -> list[np.ndarray]:
        """Each chain as a polyline of points ``(segments + 1, 3)``."""
        ch = self.chains
        out = []
        for c in range(len(ch)):
            segs = ch.segments[ch.offsets[c] : ch.offsets[c + 1]]
            out.append(np.concatenate([self.start[segs[:1]], self.end[segs]]))
        return out


def organ_names(skeleton: Skeleton) -> np.ndarray:
    """The prototype name of each organ the turtle recorded: ``sphere``, ``disc``, ``circle``, ``box``, or a
    surface's name (``~flower`` -> ``flower``; Houdini's instance symbols ``J``, ``K``, ``M`` by their own name).
    """
    names = []
    for kind, module in zip(skeleton.organ_kind.tolist(), skeleton.organ_name.tolist(), strict=True):
        name = BUILT_IN_ORGANS.get(kind)
        if name is None:  # a named surface or an instance: the [surfaces] entry of that name
            name = module[1:] if module.startswith("~") and len(module) > 1 else module
        names.append(name)
    return np.asarray(names, dtype=str)
