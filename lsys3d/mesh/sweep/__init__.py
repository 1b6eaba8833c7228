"""The sweep: a skeleton's chains to closed tubes (:func:`sweep`).

``sweep`` drives it; ``options`` holds :class:`SweepOptions`, ``frames`` the rotation-minimising frames,
``rings`` where rings go, ``forks`` the blended bases of thick children, ``uv`` the texture coordinates and
``tubes`` the tube soup (:class:`Tubes`) built from the rings.
"""

from .options import DEFAULT_MAX_TRIANGLES, SweepOptions
from .sweep import sweep
from .tubes import Tubes
from .uv import wrap_u

__all__ = ["DEFAULT_MAX_TRIANGLES", "SweepOptions", "Tubes", "sweep", "wrap_u"]
