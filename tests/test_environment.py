"""The environment: obstacles, supports for climbers, pruning volumes, light, and ?E."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from lsys3d import Grammar
from lsys3d.errors import AssetError, GrammarError
from lsys3d.pipeline import GenerateOptions, draw
from lsys3d.turtle.environment import EnvironmentOptions, load_environment, read_scene
from lsys3d.turtle.query import derive_answering


def _write(path, mesh) -> str:
    mesh.export(path)
    return str(path)


def _box(tmp_path, name, lo, hi) -> str:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    m = trimesh.creation.box(extents=hi - lo)
    m.apply_translation((lo + hi) / 2)
    return _write(tmp_path / f"{name}.obj", m)


def _inside(mesh_path, points) -> np.ndarray:
    """Exact signed distance to the mesh: positive inside (trimesh's convention)."""
    return trimesh.proximity.signed_distance(trimesh.load(mesh_path), points)


def _along(sk, k: int = 5) -> np.ndarray:
    t = np.linspace(0.0, 1.0, k)[:, None]
    return (sk.start[:, None] * (1 - t) + sk.end[:, None] * t).reshape(-1, 3)


def _grow(g: Grammar):
    return draw(g, g.iterations, g.seed, GenerateOptions())


BUSH = [
    "A -> F(0.2)[+(uniform(20, 40))/(uniform(0, 360))A][-(uniform(20, 40))/(uniform(0, 360))A]&(uniform(-10, 10))A",
]


@pytest.mark.parametrize("mode", ["prune", "deflect"])
def test_nothing_grows_inside_a_cube(tmp_path, mode):
    cube = _box(tmp_path, "cube", (-0.6, 1.0, -0.6), (0.6, 1.8, 0.6))
    g = Grammar(
        axiom="A",
        rules=BUSH,
        iterations=7,
        seed=2,
        angle=25,
        turtle={"heading": 90},
        environment={"obstacle": cube, "mode": mode, "resolution": 48},
        source=str(tmp_path / "bush.toml"),
    )
    _, sk = _grow(g)
    free = draw(g.replace(environment={}), g.iterations, g.seed)[1]
    assert (_inside(cube, _along(free)) > 0).any()  # without the obstacle, the bush grows through it
    assert len(sk) > 50
    assert _inside(cube, _along(sk)).max() <= 1e-6


def test_deflected_growth_slides_along_the_obstacle(tmp_path):
    # a straight stem, tilted 30 degrees from the vertical, meets a slab's underside and slides along it
    slab = _box(tmp_path, "slab", (-3, 2.0, -3), (3, 2.4, 3))
    common = dict(axiom="+(30)A", rules=["A -> F(0.1)A"], iterations=40, turtle={"heading": 90})
    pruned = _grow(Grammar(**common, environment={"obstacle": slab, "mode": "prune"}, source=str(tmp_path / "a")))[1]
    slid = _grow(Grammar(**common, environment={"obstacle": slab}, source=str(tmp_path / "b")))[1]
    assert len(pruned) < 40 and len(slid) == 40
    assert _inside(slab, _along(slid)).max() <= 1e-6
    assert slid.end[-1, 1] == pytest.approx(2.0, abs=0.1)  # it ends under the slab, beside where it met it
    assert slid.end[-1, 0] < pruned.end[-1, 0] - 1.0


def test_climber_stays_within_distance_of_its_support(tmp_path):
    wall = _box(tmp_path, "wall", (-2, 0, -0.2), (2, 3, 0))
    g = Grammar(
        axiom="^(90)f(0.05)&(90)A",
        rules=[
            "A -> F(0.05)[+(uniform(40, 80))A]A : 0.1",
            "A -> F(0.05)+(uniform(-20, 20))A : 0.9",
        ],
        iterations=40,
        seed=1,
        turtle={"heading": 90},
        environment={"support": wall, "distance": 0.1, "clearance": 0.01, "climb": 0.3},
        source=str(tmp_path / "ivy.toml"),
    )
    _, sk = _grow(g)
    d = _inside(wall, _along(sk))
    assert len(sk) > 100
    assert d.max() <= 1e-6  # none inside the wall
    assert (-d).max() <= 0.1 + 1e-6  # all within the set distance
    assert sk.end[:, 1].max() > 1.0  # it climbed


def test_hanging_from_an_edge(tmp_path):
    # a shelf: a climber crawling along its top goes over the front edge, out of the support's reach (3 cm),
    # and hangs down (with a longer reach it wraps round the edge: the next test)
    shelf = _box(tmp_path, "shelf", (-1, 0.9, -1), (1, 1.0, 0.0))
    g = Grammar(
        axiom="f(1.02)&(90)f(0.5)^(180)A",  # on the shelf's top at z = -0.5, heading (+z) to its edge at z = 0
        rules=["A -> F(0.05)A"],
        iterations=30,
        turtle={"heading": 90},
        environment={"support": shelf, "distance": 0.3, "hang": 0.5, "reach": 0.03, "climb": 0},
        source=str(tmp_path / "hang.toml"),
    )
    _, sk = _grow(g)
    assert sk.end[:, 2].max() > 0.0  # past the edge
    assert sk.end[-1, 1] < 0.85  # hanging below the shelf
    assert sk.heading[-1, 1] < -0.9  # straight down
    assert _inside(shelf, _along(sk)).max() <= 1e-6


def test_a_climber_within_reach_wraps_round_an_edge(tmp_path):
    # the same shelf and strand with a reach of 6 cm: the support holds it round the front edge, down the
    # front and on along the underside, as ivy crawls round a ledge
    shelf = _box(tmp_path, "shelf", (-1, 0.9, -1), (1, 1.0, 0.0))
    g = Grammar(
        axiom="f(1.02)&(90)f(0.5)^(180)A",
        rules=["A -> F(0.05)A"],
        iterations=30,
        turtle={"heading": 90},
        environment={"support": shelf, "distance": 0.3, "hang": 0.5, "reach": 0.06, "climb": 0},
        source=str(tmp_path / "wrap.toml"),
    )
    _, sk = _grow(g)
    d = _inside(shelf, _along(sk))
    assert d.max() <= 1e-6 and (-d).max() <= 0.06
    assert ((sk.end[:, 1] < 0.9) & (sk.end[:, 2] < -0.2)).any()  # under the shelf, back from its front


def _wall_climber(tmp_path, **environment):
    # a wall 1 m high, its face at z = 0 (20 cm thick): a strand climbs its face from the foot
    wall = _box(tmp_path, "wall", (-1, 0, -0.2), (1, 1.0, 0.0))
    g = Grammar(
        axiom="^(90)f(0.02)&(90)A",
        rules=["A -> F(0.05)A"],
        iterations=40,
        turtle={"heading": 90},
        environment={"support": wall, "distance": 0.3, "hang": 0.5, "reach": 0.06, "climb": 0.2, **environment},
        source=str(tmp_path / "climb.toml"),
    )
    _, sk = _grow(g)
    assert _inside(wall, _along(sk)).max() <= 1e-6
    return sk


def test_release_lets_a_climber_go_over_a_top_edge_and_hang_in_front(tmp_path):
    held = _wall_climber(tmp_path)  # off (the default): the wall holds it over the top and down the back
    assert held.end[:, 2].min() < -0.2 and held.end[-1, 1] < 0.9
    sk = _wall_climber(tmp_path, release=0.5)
    top = np.flatnonzero(sk.end[:, 1] > 1.0)
    assert len(top) and sk.end[:, 2].min() > -0.05  # over the edge, never behind the face
    assert sk.end[-1, 1] < 0.8 and sk.end[-1, 2] > 0.0 and sk.heading[-1, 1] < -0.9  # hanging down in front
    assert EnvironmentOptions().release == 0.0


def test_topiary_keeps_every_segment_inside_the_volume(tmp_path):
    box = _box(tmp_path, "box", (-0.5, 0.05, -0.5), (0.5, 1.0, 0.5))
    g = Grammar(
        axiom="f(0.1)A",
        rules=BUSH,
        iterations=9,
        seed=4,
        angle=25,
        turtle={"heading": 90},
        environment={"volume": box, "bud": "B"},
        source=str(tmp_path / "hedge.toml"),
    )
    modules, sk = _grow(g)
    assert len(sk) > 100
    assert _inside(box, _along(sk)).min() >= -1e-6
    assert modules.count("B") > 0  # the cut buds are marked


def test_light_bends_growth_and_is_answered_by_e(tmp_path):
    roof = _box(tmp_path, "roof", (-1, 3, -1), (1, 3.2, 1))
    base = dict(rules=["A -> F(0.1)A"], iterations=20, turtle={"heading": 90})
    g = Grammar(
        axiom="A",
        **base,
        environment={"light": [1, 0, 0], "phototropism": 0.2},
        source=str(tmp_path / "a.toml"),
    )
    _, sk = _grow(g)
    assert sk.heading[-1, 0] > 0.9  # turned toward the light
    q = Grammar(
        axiom="FF?E(0,0,0)[f(2)?E(0,0,0)][f(4)?E(0,0,0)]",
        iterations=0,
        turtle={"heading": 90},
        environment={"obstacle": roof, "light": [0, 1, 0]},
        source=str(tmp_path / "e.toml"),
    )
    env = load_environment(q)
    out = derive_answering(q, environment=env)
    e = [out.module(i)[1] for i in range(len(out)) if out.symbol(i) == "?E"]
    # at y = 2: free, 1 below the roof, in its shadow; at y = 4: in the roof's... above it, lit; at y = 3.1 blocked
    assert e[0][0] == 0 and e[0][1] == pytest.approx(1.0, abs=0.02) and e[0][2] == 0
    assert e[2][0] == 0 and e[2][2] == 1
    assert e[1][0] == 0  # y = 4: above the roof (f(2) from y = 2)


def test_e_reports_blocked_inside_an_obstacle(tmp_path):
    cube = _box(tmp_path, "cube", (-1, 1, -1), (1, 2, 1))
    g = Grammar(axiom="f(1.5)?E(0,0,0)", iterations=0, turtle={"heading": 90}, environment={"obstacle": cube})
    g = g.replace(source=str(tmp_path / "e.toml"))
    out = derive_answering(g, environment=load_environment(g))
    b, d, _ = out.module(1)[1]
    assert b == 1 and d == pytest.approx(0.5, abs=0.02)


def test_same_bytes_with_an_environment(tmp_path):
    wall = _box(tmp_path, "wall", (-2, 0, -0.2), (2, 3, 0))
    g = Grammar(
        axiom="^(90)f(0.05)&(90)A",
        rules=["A -> F(0.05)[+(uniform(40, 80))A]A : 0.1", "A -> F(0.05)+(uniform(-20, 20))A : 0.9"],
        iterations=30,
        seed=9,
        turtle={"heading": 90},
        environment={"support": wall, "distance": 0.1},
        source=str(tmp_path / "ivy.toml"),
    )
    (m1, s1), (m2, s2) = _grow(g), _grow(g)
    assert str(m1) == str(m2)
    assert s1.end.tobytes() == s2.end.tobytes()


def test_a_scene_drawn_again_reuses_its_grid_bytes_for_bytes(tmp_path, monkeypatch):
    """The distance grids are kept for the process by the meshes' content and the grid's options: a second
    environment of the same file is not sampled again and gets the same bytes as a fresh sampling; another
    resolution or a changed file is sampled anew; the grid handed out is a copy."""
    from lsys3d.turtle import environment

    wall = _box(tmp_path, "wall", (-2, 0, -0.2), (2, 3, 0))
    g = Grammar(axiom="A", environment={"support": wall, "distance": 0.1}, source=str(tmp_path / "g.toml"))
    environment.clear_grid_cache()
    sampled = []
    real = environment._signed_distance
    monkeypatch.setattr(environment, "_signed_distance", lambda *a: sampled.append(1) or real(*a))
    first = load_environment(g).scene().support
    first[0, 0, 0] = 123.0  # the caller's copy: the cache keeps its own
    again = load_environment(g).scene().support
    assert len(sampled) == 1
    environment.clear_grid_cache()
    fresh = load_environment(g).scene().support
    assert len(sampled) == 2 and again.tobytes() == fresh.tobytes()
    load_environment(g.replace(environment={"support": wall, "distance": 0.1, "resolution": 32})).scene()
    _box(tmp_path, "wall", (-2, 0, -0.3), (2, 3, 0))
    load_environment(g).scene()
    assert len(sampled) == 4


def test_the_grid_cache_holds_at_most_its_bytes(tmp_path, monkeypatch):
    """Past GRID_CACHE_BYTES the oldest grids are forgotten (a long-running process drawing many scenes), and a
    grid larger than the whole budget is handed out but not kept."""
    from lsys3d.turtle import environment

    wall = _box(tmp_path, "wall", (-2, 0, -0.2), (2, 3, 0))
    g = Grammar(axiom="A", environment={"support": wall, "distance": 0.1}, source=str(tmp_path / "g.toml"))
    environment.clear_grid_cache()
    one = load_environment(g).scene().support.nbytes
    monkeypatch.setattr(environment, "GRID_CACHE_BYTES", 2 * one)
    for resolution in (64, 65, 66):  # three grids of about `one` bytes each: the first is forgotten
        load_environment(g.replace(environment={"support": wall, "distance": 0.1, "resolution": resolution})).scene()
    assert 1 <= len(environment._GRIDS) <= 2
    assert sum(grid.nbytes for grid in environment._GRIDS.values()) <= 2 * one
    monkeypatch.setattr(environment, "GRID_CACHE_BYTES", 0)
    assert load_environment(g).scene().support.nbytes == one  # still answered
    assert len(environment._GRIDS) == 0
    environment.clear_grid_cache()


def test_environment_file_takes_roles_from_mesh_names(tmp_path):
    scene = trimesh.Scene()
    support = trimesh.creation.box(extents=(4, 3, 0.2))
    support.apply_translation((0, 1.5, -0.1))
    scene.add_geometry(support, node_name="support_wall", geom_name="support_wall")
    post = trimesh.creation.box(extents=(0.2, 1, 0.2))
    post.apply_translation((3, 0.5, 0))
    scene.add_geometry(post, node_name="post", geom_name="post")
    path = tmp_path / "scene.glb"
    scene.export(path)
    meshes = read_scene(path)
    assert sorted((m.name, m.role, m.closed) for m in meshes) == [
        ("post", "obstacle", True),
        ("support_wall", "support", True),
    ]
    env = load_environment(Grammar(axiom="F"), EnvironmentOptions(environment=str(path), distance=0.1))
    assert env is not None and env.scene().support.size > 0


@pytest.mark.parametrize(
    ("content", "name", "message"),
    [
        (b"this is not a mesh\n", "junk.ply", "not a readable .ply model"),
        (b"", "empty.obj", "no triangles"),
        (None, "open.obj", "must be a closed mesh"),
        (None, "huge.obj", "is it in millimetres?"),
        (b"x", "scene.fbx", "a scene must be"),
    ],
)
def test_bad_scene_files_get_one_clear_line(tmp_path, content, name, message):
    path = tmp_path / name
    if name == "open.obj":
        m = trimesh.creation.box()
        m.update_faces(np.arange(len(m.faces)) > 0)
        m.export(path)
    elif name == "huge.obj":
        trimesh.creation.box(extents=(50_000, 1, 1)).export(path)
    else:
        path.write_bytes(content)
    g = Grammar(axiom="F", environment={"volume": str(path)}, source=str(tmp_path / "g.toml"))
    with pytest.raises(AssetError) as exc:
        load_environment(g)
    text = str(exc.value)
    assert message in text and "\n" not in text and name in text


def test_bad_environment_table_is_a_grammar_error():
    with pytest.raises(GrammarError, match="unknown key 'walls'"):
        load_environment(Grammar.from_text('axiom = "F"\n[environment]\nwalls = "x.obj"\n', source="g.toml"))
    with pytest.raises(GrammarError, match="adhesion"):
        load_environment(Grammar(axiom="F", environment={"support": "w.obj", "adhesion": 3}))


def test_no_environment_changes_nothing():
    g = Grammar(axiom="A", rules=BUSH, iterations=4, angle=25)
    assert load_environment(g) is None
    assert str(derive_answering(g)) == str(draw(g, 4, 0)[0])


def test_leaves_turn_to_the_environment_light_unless_leaves_name_one():
    from lsys3d.look.leaves import LeafOptions
    from lsys3d.pipeline import _environment_light

    g = Grammar(axiom="F~", environment={"light": [3, 4, 0]}, leaves={"leaf_light": 0.5})
    opts = GenerateOptions()
    turned = _environment_light(g, opts, LeafOptions.from_grammar(g))
    assert turned.light == pytest.approx((0.6, 0.8, 0.0)) and turned.leaf_light == 0.5
    own = g.replace(leaves={"leaf_light": 0.5, "light": [0, 0, 1]})
    assert _environment_light(own, opts, LeafOptions.from_grammar(own)).light == (0.0, 0.0, 1.0)


def test_usd_scene_in_z_up_centimetres_is_read_in_metres_y_up(tmp_path):
    from pxr import Usd, UsdGeom, Vt

    path = tmp_path / "scene.usda"
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)
    box = trimesh.creation.box(extents=(100, 20, 300))  # 1 m wide, 0.2 m deep, 3 m high (Z up)
    box.apply_translation((0, 0, 150))
    mesh = UsdGeom.Mesh.Define(stage, "/World/support_wall")
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(box.vertices.astype(np.float32)))
    mesh.CreateFaceVertexCountsAttr([3] * len(box.faces))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(box.faces.reshape(-1).astype(np.int32)))
    stage.GetRootLayer().Save()
    (wall,) = read_scene(path)
    assert wall.role == "support" and wall.closed
    assert wall.vertices.min(axis=0) == pytest.approx((-0.5, 0.0, -0.1))
    assert wall.vertices.max(axis=0) == pytest.approx((0.5, 3.0, 0.1))
