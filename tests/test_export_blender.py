"""Blender imports our files: bark vertex count, upright tree, materials, leaves drawn.

Blender runs as ``bpy`` in its own environment (``.venv-bpy``, Python 3.11,
``bpy==5.0.1``) in a child process; see ``tests/validators.py``.  The files of a test's cases are imported
by one Blender, one after another, each into an empty scene (``validators.blender_imports``): a Blender start
(half a CPU second) once, not once per file.
"""

from __future__ import annotations

import re

import export_fixtures as fx
import numpy as np
import pytest
import validators
from grown import grown

from lsys3d.exchange import ExportOptions, export

CASES = [
    ("tree.glb", ExportOptions()),
    ("instanced.glb", ExportOptions(instance_leaves=True)),
    ("tree.usda", ExportOptions()),
    ("tree.usdc", ExportOptions(up_axis="Z", units="cm")),
    ("tree.usdz", ExportOptions()),
    ("merged.usdc", ExportOptions(instance_leaves=False)),
]


@pytest.fixture(scope="module")
def tree():
    return fx.make_tree()


@pytest.fixture(scope="module")
def imported(tree, tmp_path_factory) -> dict:
    """Every case's file, exported, and Blender's report of it (one Blender for the six)."""
    folder = tmp_path_factory.mktemp("export_blender")
    paths = [export(tree, folder / name, options) for name, options in CASES]
    return dict(
        zip([name for name, _ in CASES], zip(paths, validators.blender_imports(paths), strict=True), strict=True)
    )


@pytest.mark.parametrize("name", [c[0] for c in CASES])
def test_blender_imports(tree, imported, name):
    path, report = imported[name]
    objects = {o["name"]: o for o in report["objects"]}
    bark = objects.get("bark")
    assert bark is not None, sorted(objects)
    # glTF splits vertices at seams; Blender keeps those, but the welded positions are all there
    assert bark["unique_positions"] == len(tree.bark.vertices)
    if path.suffix != ".glb":
        assert bark["vertices"] == len(tree.bark.vertices)
    assert bark["faces"] == len(tree.bark.faces)
    assert bark["materials"] == ["bark"]
    assert not any(o.get("repaired") for o in report["objects"]), "Blender's Mesh.validate repaired a mesh"

    # upright and true to size in Blender's Z-up metres, whatever the file's units and up axis
    lo, hi = np.array(bark["bbox"])
    size = hi - lo
    assert np.argmax(size) == 2
    np.testing.assert_allclose(size[2], 2.0, rtol=1e-4)
    np.testing.assert_allclose(lo[2], 0.0, atol=1e-4)
    # leaves land where they belong, instanced or not: everything drawn matches the merged leaves
    everything = np.vstack([tree.bark.vertices, tree.leaves.merged.vertices])
    expected = np.array([everything.min(0), everything.max(0)])[:, [0, 2, 1]] * [1, -1, 1]  # Y up -> Z up
    expected = np.sort(expected, axis=0)
    np.testing.assert_allclose(report["drawn_bbox"], expected, atol=2e-3)

    materials = {m["name"]: m for m in report["materials"]}
    for m in (tree.bark_material, tree.leaf_material):
        assert m.name in materials, sorted(materials)
        np.testing.assert_allclose(materials[m.name]["base_color"], m.base_color, atol=1e-3)
        assert materials[m.name]["roughness"] == pytest.approx(m.roughness, abs=1e-3)


SPECIES = ["oak.glb", "palm.glb", "spruce.usdz"]


@pytest.fixture(scope="module")
def species_imported(tmp_path_factory) -> dict:
    """Each species' file and Blender's report of it (one Blender for the three)."""
    folder = tmp_path_factory.mktemp("species")
    paths = [export(grown(name.split(".")[0]), folder / name) for name in SPECIES]
    return dict(zip(SPECIES, validators.blender_imports(paths), strict=True))


@pytest.mark.parametrize("name", SPECIES)
def test_blender_imports_species(species_imported, name):
    """A few species (a broadleaf, the palm, a conifer with cards) import whole, unrepaired, with their bark
    material textured."""
    tree = grown(name.split(".")[0])
    report = species_imported[name]
    objects = {o["name"]: o for o in report["objects"]}
    assert objects["bark"]["faces"] == len(tree.bark.faces)
    assert objects["bark"]["unique_positions"] == len(tree.bark.vertices)
    assert not any(o.get("repaired") for o in report["objects"]), "Blender's Mesh.validate repaired a mesh"
    names = {re.sub(r"\W", "_", m["name"]) for m in report["materials"]}  # USD prim names: "spruce_bark"
    assert re.sub(r"\W", "_", tree.bark_material.name) in names, names


def test_a_blender_crash_is_a_failure(tmp_path, monkeypatch):
    """A segfault in the child is reported as a test failure, not a lost test run."""
    fake = tmp_path / "python"
    fake.write_text("#!/bin/sh\nkill -SEGV $$\n")
    fake.chmod(0o755)
    monkeypatch.setenv("LSYS3D_BPY_PYTHON", str(fake))
    with pytest.raises(pytest.fail.Exception, match="Blender crashed \\(signal 11\\)"):
        validators.blender_import(tmp_path / "tree.usda")
