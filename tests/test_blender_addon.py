"""The Blender add-on (:mod:`lsys3d.blender`) driven inside Blender: ``tools/blender_addon_check.py`` runs in the
``bpy`` environment in a child process (a Blender crash is a failed test, not a dead run) and reports what the
add-on made, read back from Blender's data; these tests compare it with lsys3d's own counts."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import tomllib
import zipfile

import pytest
from validators import REPO, bpy_lsys3d_env, bpy_python, in_ci, require
from wheels import lsys3d_wheel

MARK = "LSYS3D-ADDON "

#: One Blender session grows the module's plants (the ``addon`` fixture): slow as a whole, and its tests kept
#: together (the ``slow`` tests run first, tests/conftest.py).
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def addon(tmp_path_factory) -> dict:
    python = bpy_python()
    require(python is not None and python.exists(), "Blender (bpy) is not installed: make validators")
    scratch = tmp_path_factory.mktemp("addon")
    proc = subprocess.run(
        [str(python), str(REPO / "tools" / "blender_addon_check.py"), str(scratch)],
        capture_output=True,
        text=True,
        timeout=900,
        cwd=REPO,
        env=bpy_lsys3d_env(python),
    )
    if "No module named 'numba'" in proc.stderr or "No module named 'trimesh'" in proc.stderr:
        require(False, "lsys3d's dependencies are not installed in .venv-bpy: make validators")
    assert proc.returncode == 0, f"Blender exited {proc.returncode}:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith(MARK)]
    assert lines, f"no report:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    return json.loads(lines[-1][len(MARK) :])


@pytest.fixture(scope="module")
def cli_stats() -> dict:
    """``lsys3d stats tree3d --mesh --json``, the command line's main in this process (a child would add its
    interpreter, imports and kernels' loading: the JSON is the same)."""
    import contextlib
    import io

    from lsys3d.cli import main

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["stats", "tree3d", "--mesh", "--json"]) == 0
    return json.loads(out.getvalue())


def test_add_plant_counts_equal_the_cli_stats(addon, cli_stats):
    plant = addon["tree3d"]
    assert (plant["vertices"], plant["faces"]) == (cli_stats["bark"]["vertices"], cli_stats["bark"]["faces"])
    # leaves as instances of one model: realised by Blender's depsgraph, they count as lsys3d's merged leaves
    leaves = plant["leaves"]
    assert (leaves["vertices"], leaves["faces"]) == (cli_stats["leaves"]["vertices"], cli_stats["leaves"]["faces"])
    assert leaves["instances"] == cli_stats["interpret"]["leaf_instances"]
    assert plant["parts"] == ["leaves", "leaves_model"]


def test_the_menus_click_grows_tree3d(addon):
    assert addon["default_preset"] == "tree3d"


def test_add_plant_is_shaded_and_z_up(addon, cli_stats):
    plant = addon["tree3d"]
    assert plant["uv"] == ["UVMap"] and plant["custom_normals"] and plant["materials"] == ["bark"]
    # lsys3d's Y (the trunk) is Blender's Z: the plant stands on the ground, as tall as lsys3d's bbox is high
    low, high = plant["z_extent"]
    assert low == pytest.approx(cli_stats["bbox"]["min"][1], abs=1e-5)
    assert high <= cli_stats["bbox"]["max"][1] + 1e-5 and high > 0.9 * cli_stats["interpret"]["bbox_max"][1]
    assert plant["recipe"]["preset"] == "tree3d" and plant["recipe"]["seed"] == 0


def test_another_seed_grows_another_plant_of_a_stochastic_grammar(addon):
    a, b = addon["stochastic_0"], addon["stochastic_1"]
    assert (a["vertices"], a["faces"], a["position_sum"]) != (b["vertices"], b["faces"], b["position_sum"])
    assert (a["recipe"]["seed"], b["recipe"]["seed"]) == (0, 1)


def test_the_recipe_survives_save_and_reopen_and_regrows_the_same(addon):
    first, reopened, regrown = addon["tree3d"], addon["reopened"], addon["regrown"]
    keys = ("vertices", "faces", "leaves", "recipe", "position_sum")
    assert {k: reopened[k] for k in keys} == {k: first[k] for k in keys}
    assert {k: regrown[k] for k in keys} == {k: first[k] for k in keys}
    # the panel's other seed, on the stochastic plant: kept in the recipe, and another plant in the same object
    seed_5, seed_1 = addon["regrown_seed_5"], addon["stochastic_1"]
    assert seed_5["recipe"]["seed"] == 5 and seed_5["name"] == seed_1["name"]
    assert (seed_5["vertices"], seed_5["faces"], seed_5["position_sum"]) != (
        seed_1["vertices"],
        seed_1["faces"],
        seed_1["position_sum"],
    )
    # plants of one look share their materials, and a regrow reuses them (no bark.001 left behind)
    assert addon["stochastic_1"]["materials"] == addon["regrown_seed_5"]["materials"] == ["bark"]


def test_rig_is_an_armature_with_a_group_per_bone(addon):
    rigged = addon["rigged"]
    assert "rig" in rigged["parts"] and rigged["bones"] > 1
    assert rigged["vertex_groups"] == rigged["bones"]
    # a skinned tree's leaves are one weighted mesh (instances cannot be skinned), as the USD writer does
    assert rigged["leaves"]["instances"] == 0 and rigged["leaves"]["faces"] > 0


def test_textures_are_packed_image_nodes(addon):
    """fern's leaf texture: an Image Texture node of the tree's own PNG bytes, packed in the .blend file."""
    from lsys3d import load_preset
    from lsys3d.look.materials import material_table

    texture = material_table(load_preset("fern")).leaf.texture
    images = addon["textured"]["images"]
    assert [texture.width, texture.height] in [size for _, size, _ in images]
    assert all(packed for _, _, packed in images)
    assert addon["textured_reopened"]["images"] == images
    assert addon["untextured"]["images"] == []


def test_the_armature_deforms_the_bark_by_lsys3ds_weights(addon):
    """Two trunk bones posed: every bark vertex where lsys3d's skin (joints and weights) puts it."""
    assert addon["skinning"]["max_moved"] > 0.1
    assert addon["skinning"]["max_error"] < 1e-4


def test_organs_are_instances(addon):
    """Two L-Py spheres (``@O``): two instances of one sphere model, as many vertices and faces as lsys3d's
    merged organs."""
    import lsys3d

    grammar = lsys3d.Grammar.from_text(
        'axiom = "_(0.05)F(1)[+F(1)@O(0.2)][-F(1)@O(0.3)]"\ndialect = "lpy"\niterations = 0\n'
    )
    merged = lsys3d.generate(grammar).organs.merged[0]
    assert addon["organs"] == {"instances": 2, "vertices": len(merged.vertices), "faces": len(merged.faces)}


def test_a_bad_grammar_is_reported_with_file_line_col(addon):
    message = addon["bad_grammar"]
    assert re.match(r"Error: \S*bad\.toml:3:\d+: unbalanced", message), message
    assert "Traceback" not in message
    assert addon["missing_grammar"].startswith("Error: ") and "none.toml" in addon["missing_grammar"]


def test_export_writes_with_lsys3ds_writer(addon):
    assert addon["exported"] > 1000


def test_the_extension_zip_installs_in_blender(tmp_path):
    """``tools/blender_extension.py`` for this platform, installed as "Install from Disk" does, registers the
    add-on from the bundled wheels (lsys3d imported from the extension's site-packages, not this checkout)."""
    python = bpy_python()
    require(python is not None and python.exists(), "Blender (bpy) is not installed: make validators")
    built = subprocess.run(
        [
            sys.executable,
            str(REPO / "tools" / "blender_extension.py"),
            "--platforms",
            "linux-x64",
            "--out",
            str(tmp_path),
            "--wheel",  # lsys3d's wheel, built once in the run (tests/wheels.py)
            str(lsys3d_wheel()),
        ],
        capture_output=True,
        text=True,
        timeout=900,
    )
    if built.returncode != 0 and not in_ci():  # pip could not reach the package index
        pytest.skip(f"the extension's wheels could not be downloaded: {built.stderr[-500:]}")
    assert built.returncode == 0, built.stderr[-3000:]
    (archive,) = tmp_path.glob("lsys3d-blender-*.zip")
    with zipfile.ZipFile(archive) as z:
        manifest = tomllib.loads(z.read("blender_manifest.toml").decode())
        names = set(z.namelist())
    assert manifest["type"] == "add-on" and manifest["blender_version_min"] == "4.2.0"
    assert {w.removeprefix("./") for w in manifest["wheels"]} <= names
    assert any("lsys3d-" in w for w in manifest["wheels"]) and any("numba-" in w for w in manifest["wheels"])
    bad = tmp_path / "bad.toml"
    bad.write_text('axiom = "F"\nrules = ["F -> F[+F]F]"]\n')
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["BLENDER_USER_RESOURCES"] = str(tmp_path / "blender")
    proc = subprocess.run(
        [str(python), str(REPO / "tools" / "blender_extension_check.py"), str(archive), str(bad)],
        capture_output=True,
        text=True,
        timeout=900,
        cwd=tmp_path,
        env=env,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    (line,) = [ln for ln in proc.stdout.splitlines() if ln.startswith("LSYS3D-EXTENSION ")]
    report = json.loads(line.split(" ", 1)[1])
    assert report["install"] == ["FINISHED"] and report["enabled"] and report["operator"]
    assert report["lsys3d"].startswith(str(tmp_path / "blender")), report["lsys3d"]
    assert re.match(r"Error: \S*bad\.toml:2:\d+: unbalanced", report["error"]), report["error"]


def test_the_docs_python_example_runs_in_blender(addon):
    assert addon["doc_examples"] >= 1 and addon["doc_export"]


def test_lod_level_is_lighter(addon):
    assert addon["lod_2"]["recipe"]["lod"] == 2
    assert 0 < addon["lod_2"]["faces"] < addon["tree3d"]["faces"]


def test_a_slow_union_shows_the_soup_first_then_the_union(addon, cli_stats):
    soup, settled = addon["soup"], addon["settled"]
    assert (soup["vertices"], soup["faces"]) == (cli_stats["sweep"]["vertices"], cli_stats["sweep"]["faces"])
    assert soup["recipe"]["union"] is False
    assert (settled["vertices"], settled["faces"]) == (cli_stats["bark"]["vertices"], cli_stats["bark"]["faces"])
    assert settled["recipe"]["union"] is True and settled["name"] == soup["name"]


def test_wind_attributes_are_mesh_and_point_attributes(addon):
    from lsys3d.look.attributes import KEYS

    assert set(KEYS) <= set(addon["attributes"]["attributes"])
    assert set(KEYS) <= set(addon["leaf_point_attributes"])  # per leaf instance, beside its matrix
    assert "lsys3d_transform" in addon["leaf_point_attributes"]
    assert not set(KEYS) & set(addon["tree3d"]["attributes"])  # off by default


def test_wind_animation_is_the_armatures_action(addon):
    """2 s at 24 fps: frames 1 to 49; the bark sways at a quarter of the loop and is back at its end."""
    wind = addon["wind"]
    assert wind["frames"] == [1, 49] and wind["fps"] == 24
    assert wind["moved_quarter"] > 1e-3
    assert wind["moved_end"] < 1e-4
    assert addon["wind_without_rig"].startswith("Error: ") and "rig" in addon["wind_without_rig"]


def test_wind_moves_the_bark_as_the_gltf_file_does(addon):
    """The same tree written by lsys3d's glTF writer and read by Blender's importer (its skin and its
    animation) has, at a quarter of the loop, the box the add-on's armature gives the bark."""
    w = addon["wind_gltf"]
    assert w["ours"] != pytest.approx(w["rest"], abs=1e-3)  # it has moved
    assert w["ours"] == pytest.approx(w["gltf"], abs=1e-4)
