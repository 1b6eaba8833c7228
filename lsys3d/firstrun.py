"""A first run's compiling, shared between the main process and a helper process (:func:`lsys3d.compiling.ahead`).

On a first run (an empty kernel cache) ``lsys3d generate`` starts ``python -m lsys3d.firstrun``, which compiles
the cleanup's kernels (:mod:`lsys3d.mesh.precompile`) on the other core while the main process derives, draws,
sweeps and unions.  The kernels the main process needs last, after the cleaning (:data:`SPARES`: the cleanup's
uv and each face's tube, its normals and compacting, the export's splitting of the vertices), go to whichever
process is idle first, a group at a time: the helper compiles a group when it is done with the cleanup's
kernels (and the groups before) and the main process has not claimed it; the main process, while it waits for
the helper (:meth:`Helper.idle <lsys3d.compiling.Helper.idle>`), compiles :data:`MAIN_ONLY` (the attributes'
match, which calls a kernel the union compiles), then the groups the helper has not claimed.  Either way they
are out of the part of the run where the main process works alone, after the helper has ended, and the two
processes end their compiling close together (a group apart at most).

They are compiled by signature (numba's ``compile``), for the types the pipeline calls them with (the default
tree's: ``tests/test_compiling.py`` checks that it asks for no other), and compile nothing else but the
kernels of their group (:attr:`Spare.names <lsys3d.compiling.Spare>`) and the geometry's helpers the helper
compiled first.
"""

from __future__ import annotations

from collections.abc import Callable

from numba import types

from . import compiling
from .exchange.common import _first_uses, _number_others, _others
from .look.attributes import _match
from .mesh import precompile
from .mesh.remesh.halfedge import _compact_faces, _corners_used
from .mesh.remesh.normals import _corner_rows, _vertex_normal_sums
from .mesh.sweep.uv import _face_kinds, _uv_at

__all__ = ["MAIN_ONLY", "SIGNATURES", "SPARES", "ahead"]


def _c(dtype, ndim: int = 1) -> types.Array:
    """A C-contiguous array type, as numba types a fresh numpy array."""
    return types.Array(dtype, ndim, "C")


_I64, _F64, _I32, _U32, _F32, _B = types.int64, types.float64, types.int32, types.uint32, types.float32, types.boolean


SIGNATURES = {
    # Tubes.face_kinds: face, offsets, sides, rings -> tube, cap
    _face_kinds: [(_c(_I64),) * 6],
    # Tubes.uv and corner_uv: face, points, faces, per corner, out, lo, hi, then Tubes._charts()
    _uv_at: [
        (
            _c(_I64),
            _c(_F64, 2),
            _c(_I64, 2),
            types.boolean,
            _c(_F32, 3),
            _I64,
            _I64,
            *(_c(_I64),) * 4,
            *(_c(_F64, 2),) * 3,
            *(_c(_F64),) * 3,
        )
    ],
    # exchange.common._split and _first_use_order (int32 new numbers: under 2**31 vertices)
    _others: [(_c(_I64), _I64, _c(_U32, 2), _c(_U32, 2))],
    _number_others: [(_c(_I64), _c(_I64), _I64, _c(_U32))],
    _first_uses: [(_c(_I64), _c(_I32), _c(_I64))],
    # remesh.compact: the half-edges' faces, the live faces, used; then the half-edges' faces, face_part,
    # face_flat, face_source, the live faces, renumber, faces, part, flat, source (int64), lo, hi
    _corners_used: [(_c(_I32, 2), _c(_I64), _c(_B))],
    _compact_faces: [
        (
            _c(_I32, 2),
            _c(_I32),
            _c(_B),
            _c(_I32),
            _c(_I64),
            _c(_I64),
            _c(_I64, 2),
            _c(_I64),
            _c(_B),
            _c(_I64),
            _I64,
            _I64,
        )
    ],
    # remesh.corner_normals: points, faces, flat, vertex normals, some, (out,) lo, hi
    _vertex_normal_sums: [(_c(_F64, 2), _c(_I64, 2), _c(_B), _c(_F64, 2), _c(_B), _I64, _I64)],
    _corner_rows: [(_c(_F64, 2), _c(_I64, 2), _c(_B), _c(_F64, 2), _c(_B), _c(_F32, 3), _I64, _I64)],
}
"""The spare kernels (:data:`SPARES`) and the signatures the pipeline calls them with."""


MAIN_ONLY = {
    # look.attributes.nearest_branch: points, the grid (origin, cell, dims, keys, key_offsets, boxes), lo, hi,
    # a, b, w0, w1, depth, surface, tolerance (it calls arrays.search_left, which the union compiles before)
    _match: [
        (
            _c(_F64, 2),
            _c(_F64),
            _F64,
            *(_c(_I64),) * 4,
            *(_c(_F64, 2),) * 4,
            *(_c(_F64),) * 2,
            _c(_I64),
            _F64,
            _F64,
        )
    ],
}
"""The kernels and signatures only the main process compiles ahead, while it would wait for the helper."""


def _compile(table: dict) -> Callable[[], None]:
    def compile_all() -> None:
        for kernel, signatures in table.items():
            for signature in signatures:
                kernel.compile(signature)

    return compile_all


SPARES = (
    compiling.Spare(
        names=(
            "lsys3d.mesh.sweep.uv.",  # _uv_at, _face_kinds, _face_place
            "lsys3d.mesh.sweep.frames._span_frame",  # called by _uv_at alone
            "lsys3d.arrays.search_right",  # called by _face_place alone
        ),
        compile=_compile({k: SIGNATURES[k] for k in (_face_kinds, _uv_at)}),
    ),
    compiling.Spare(
        names=(
            "lsys3d.exchange.common._others",
            "lsys3d.exchange.common._number_others",
            "lsys3d.exchange.common._first_uses",
        ),
        compile=_compile({k: SIGNATURES[k] for k in (_others, _number_others, _first_uses)}),
    ),
    compiling.Spare(
        names=("lsys3d.mesh.remesh.normals.",),  # _vertex_normal_sums, _corner_rows, _unit_normal
        compile=_compile({k: SIGNATURES[k] for k in (_vertex_normal_sums, _corner_rows)}),
    ),
    compiling.Spare(
        names=(
            "lsys3d.mesh.remesh.halfedge._corners_used",
            "lsys3d.mesh.remesh.halfedge._compact_faces",
        ),
        compile=_compile({k: SIGNATURES[k] for k in (_corners_used, _compact_faces)}),
    ),
)
"""The kernels the main process calls last, in groups for whichever process is idle first, the longest first:
the cleanup's uv (1.3 CPU s of compiling), the export's (0.6), the cleanup's normals (0.5) and its compacting
(0.25); the kernels of one group call none of another's (the normals call the geometry's helpers, which the
helper compiles first).  The caps a seam cuts (:func:`lsys3d.mesh.remesh.cut_caps`, after the compacting) are
in none: only a tree with flat caps calls it (not the default tree), and it is compiled where it is called."""


def ahead():
    """:func:`lsys3d.compiling.ahead` for a first run: this module as the helper, the cleanup's kernels its own,
    :data:`SPARES` for whichever process is idle first, :data:`MAIN_ONLY` for the main process's wait."""
    return compiling.ahead(__name__, precompile.OWN, precompile.ENTRIES, SPARES, _compile(MAIN_ONLY))


if __name__ == "__main__":
    compiling.help_ahead(precompile.OWN, precompile.run, SPARES)
