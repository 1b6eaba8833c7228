"""The editor's page in a real browser: headless Chromium driven by playwright-core (``tests/edit_browser.mjs``)
against ``lsys3d edit`` serving a grammar on a free port of 127.0.0.1."""

from __future__ import annotations

import json
import signal
import subprocess
import sys

import pytest

pytest.importorskip("starlette")

from browser import CHROMIUM, CHROMIUM_ARGS, require_browser
from validators import REPO, gltf_issues, validate_gltf

from lsys3d.lsystem.presets import preset_text

#: tree3d at 4 generations, typed down to 3 in the page: every edit regrows and unions it in the server's
#: workers, and the page's checks (fewer triangles, soup then union, errors, sliders, views, levels of detail,
#: export, save and reload) read the same at 4 as at the preset's 6, for a seventh of the CPU per growth
START, TYPED = "iterations = 4", "3"


@pytest.fixture
def server(tmp_path):
    grammar = tmp_path / "plant.toml"
    text = preset_text("tree3d")
    assert text.count("iterations = 6") == 1
    grammar.write_text(text.replace("iterations = 6", START), encoding="utf-8")
    proc = subprocess.Popen(
        [sys.executable, "-m", "lsys3d", "edit", str(grammar), "--port", "0", "--no-browser"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    line = proc.stdout.readline()
    if not line.startswith("lsys3d edit: http://127.0.0.1:"):
        proc.kill()
        pytest.fail(f"lsys3d edit did not start: {line}{proc.stderr.read()}")
    yield line.split()[2], grammar
    proc.send_signal(signal.SIGTERM)
    proc.wait(timeout=60)


@pytest.mark.slow  # an editor server and a headless Chromium
def test_the_editor_in_chromium(server, tmp_path):
    require_browser()
    url, grammar = server
    script = REPO / "tests" / "edit_browser.mjs"
    done = subprocess.run(
        ["node", str(script), url, str(tmp_path), str(CHROMIUM), json.dumps(CHROMIUM_ARGS), START, TYPED],
        capture_output=True,
        text=True,
        timeout=600,
        cwd=REPO,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    seen = json.loads(done.stdout.strip().splitlines()[-1])
    assert seen["errors"] == []
    # typing 3 for 4 iterations: fewer triangles, the soup first, then the union
    assert 0 < seen["trianglesAfter"] < seen["trianglesBefore"]
    assert seen["trianglesSoup"] != seen["trianglesBefore"]
    assert {t["kind"] for t in seen["timings"]} == {"soup", "full"}
    # the bad rule's error, inline on its line
    assert seen["errorLine"] == seen["badLine"] > 0
    assert seen["errorGutter"] == str(seen["badLine"])
    assert "unclosed" in seen["errorText"] or "(" in seen["errorText"]
    # the warning of a symbol with no meaning: listed as the CLI prints it, the symbol marked on its line
    assert seen["warnedSymbol"] == "X" and "no rule and no turtle meaning: 'X'" in seen["warning"]
    assert seen["warningGutter"] == "3"  # the axiom's line
    # the slider wrote the define and the tree changed shape
    assert seen["boundsChanged"]
    # views: the same mesh in wireframe and UV checker; the skeleton view ghosts it; no leaves, fewer
    views = seen["views"]
    assert views["wireframe"] == views["uv"] == views["shaded"] == views["skeleton"] > 0
    assert 0 < seen["trianglesWithoutLeaves"] < views["shaded"]
    # levels of detail: fewer triangles level by level
    lods = seen["lodTriangles"]
    assert lods[0] == views["shaded"] and lods == sorted(lods, reverse=True) and lods[3] < lods[0]
    # the exported .glb is valid glTF
    report = validate_gltf(tmp_path / "exported.glb")
    assert gltf_issues(report, 0) == []
    # saved to the file, and read back by the reloaded page
    text = grammar.read_text(encoding="utf-8")
    assert text == seen["textSaved"] == seen["textReloaded"]
    assert "\nelasticity = 0.5\n" in text and "elasticity = 0.22" not in text
    assert f"iterations = {TYPED}" in text and f"a = {seen['sliderValue']:g}" in text and "a = 18.95" not in text
    assert seen["trianglesReloaded"] == seen["trianglesAfter"] or seen["trianglesReloaded"] > 0
