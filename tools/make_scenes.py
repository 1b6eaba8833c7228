"""Write the scene meshes the environment presets grow in (assets/presets/scenes/*.obj).

Run from the repository root: ``python tools/make_scenes.py``.  Each scene is a closed mesh made with
manifold3d's booleans (exact, watertight) and written as OBJ with six decimals, so the files are the
same on every run.
"""

from __future__ import annotations

from pathlib import Path

import manifold3d as m3d
import numpy as np

OUT = Path(__file__).resolve().parent.parent / "assets" / "presets" / "scenes"


def box(lo, hi) -> m3d.Manifold:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    return m3d.Manifold.cube(tuple(hi - lo)).translate(tuple(lo))


def write_obj(path: Path, solid: m3d.Manifold, name: str) -> None:
    mesh = solid.to_mesh()
    v = np.asarray(mesh.vert_properties)[:, :3]
    f = np.asarray(mesh.tri_verts)
    lines = [f"# {name}: written by tools/make_scenes.py", f"o {name}"]
    lines += [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in v]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in f]
    path.write_text("\n".join(lines) + "\n")


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    # a wall 4 m wide, 3 m high, 0.2 m thick, its face at z = 0, with a window (1 x 1 m) and a sill
    wall = box((-2.0, 0.0, -0.2), (2.0, 3.0, 0.0)) - box((-0.5, 1.2, -0.3), (0.5, 2.2, 0.1))
    wall = wall + box((-0.65, 1.1, -0.2), (0.65, 1.2, 0.12))
    write_obj(OUT / "wall_window.obj", wall, "wall")
    # a plain wall beside a tree: 6 m wide, 5 m high, its face at x = 1
    write_obj(OUT / "wall.obj", box((1.0, 0.0, -3.0), (1.3, 5.0, 3.0)), "wall")
    # the topiary's box: 1.2 x 1.0 x 1.2 m, standing on the ground
    write_obj(OUT / "hedge_box.obj", box((-0.6, 0.0, -0.6), (0.6, 1.0, 0.6)), "box")
    # a post 2.4 m high, 0.12 m across (16 sides)
    post = m3d.Manifold.cylinder(2.4, 0.06, 0.06, 16).rotate((-90.0, 0.0, 0.0))
    write_obj(OUT / "post.obj", post, "post")


if __name__ == "__main__":
    main()
