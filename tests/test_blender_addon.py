"""The Blender add-on (:mod:`lsys3d.blender`) driven inside Blender: ``tools/blender_addon_check.py`` runs in the
``bpy`` environment in a child process (a Blender crash is a failed test, not a dead run) and reports what the
add-on made, read back from Blender's data; these tests compare it with lsys3d's own counts."""

from __future__ import annotations

import json
import re
import subprocess
import sys

import pytest
from validators import REPO, bpy_python, require

MARK = "LSYS3D-ADDON "


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
    )
    if "No module named 'numba'" in proc.stderr or "No module named 'trimesh'" in proc.stderr:
        require(False, "lsys3d's dependencies are not installed in .venv-bpy: make validators")
    assert proc.returncode == 0, f"Blender exited {proc.returncode}:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith(MARK)]
    assert lines, f"no report:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    return json.loads(lines[-1][len(MARK) :])


@pytest.fixture(scope="module")
def cli_stats() -> dict:
    proc = subprocess.run(
        [sys.executable, "-m", "lsys3d", "stats", "tree3d", "--mesh", "--json"],
        capture_output=True,
        text=True,
        check=True,
        cwd=REPO,
    )
    return json.loads(proc.stdout)


def test_add_plant_counts_equal_the_cli_stats(addon, cli_stats):
    plant = addon["tree3d"]
    assert (plant["vertices"], plant["faces"]) == (cli_stats["bark"]["vertices"], cli_stats["bark"]["faces"])
    # leaves as instances of one model: realised by Blender's depsgraph, they count as lsys3d's merged leaves
    leaves = plant["leaves"]
    assert (leaves["vertices"], leaves["faces"]) == (cli_stats["leaves"]["vertices"], cli_stats["leaves"]["faces"])
    assert leaves["instances"] == cli_stats["interpret"]["leaf_instances"]
    assert plant["parts"] == ["leaves", "leaves_model"]


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
    assert addon["regrown_seed_5"]["recipe"]["seed"] == 5  # the panel's other seed is kept in the recipe


def test_rig_is_an_armature_with_a_group_per_bone(addon):
    rigged = addon["rigged"]
    assert "rig" in rigged["parts"] and rigged["bones"] > 1
    assert rigged["vertex_groups"] == rigged["bones"]
    # a skinned tree's leaves are one weighted mesh (instances cannot be skinned), as the USD writer does
    assert rigged["leaves"]["instances"] == 0 and rigged["leaves"]["faces"] > 0


def test_a_bad_grammar_is_reported_with_file_line_col(addon):
    message = addon["bad_grammar"]
    assert re.match(r"Error: \S*bad\.toml:3:\d+: unbalanced", message), message
    assert "Traceback" not in message
    assert addon["missing_grammar"].startswith("Error: ") and "none.toml" in addon["missing_grammar"]


def test_export_writes_with_lsys3ds_writer(addon):
    assert addon["exported"] > 1000
