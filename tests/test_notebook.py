"""A notebook run headless (nbclient and an IPython kernel): a tree returned by a cell shows the editor's viewer
(``Tree._repr_html_``), as does ``tree.show()``; the output, opened offline in headless Chromium, draws the tree."""

from __future__ import annotations

import json
import subprocess

import pytest

nbformat = pytest.importorskip("nbformat")
nbclient = pytest.importorskip("nbclient")
pytest.importorskip("ipykernel")

from browser import CHROMIUM, CHROMIUM_ARGS, browser_available  # noqa: E402
from validators import REPO  # noqa: E402

import lsys3d  # noqa: E402
from lsys3d.edit.notebook import MODULES, viewer_html  # noqa: E402


def _html_outputs(cell) -> list[str]:
    return [o["data"]["text/html"] for o in cell.outputs if "text/html" in o.get("data", {})]


def test_a_notebook_shows_the_viewer(tmp_path):
    notebook = nbformat.v4.new_notebook()
    notebook.cells = [
        nbformat.v4.new_code_cell('import lsys3d\ntree = lsys3d.generate("tree3d", 3)\ntree'),
        nbformat.v4.new_code_cell("tree.show(height=360)"),
    ]
    client = nbclient.NotebookClient(
        notebook, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}
    )
    client.execute()
    (returned,) = _html_outputs(notebook.cells[0])
    (shown,) = _html_outputs(notebook.cells[1])
    for html in (returned, shown):
        assert 'class="lsys3d-view"' in html and 'data-asset="tree3d"' in html
        assert "three.core.js" in html and "createViewer" in html  # three.js and the viewer inlined
        assert "http://" not in html.split("<script>")[-1]  # the loader fetches nothing
    assert "height:360px" in shown
    if not browser_available()[0]:
        return  # the page's drawing is checked below where Chromium is installed
    page = tmp_path / "output.html"
    page.write_text(f"<!doctype html><meta charset='utf-8'><body>{returned}</body>", encoding="utf-8")
    seen = _open(page)
    tree = lsys3d.generate("tree3d", 3)
    leaf = len(tree.leaves.merged.faces) if tree.leaves.merged is not None else 0
    assert seen["triangles"] == len(tree.bark.faces) + leaf
    assert seen["views"] == ["shaded", "wireframe", "skeleton", "uv"]


def _open(page) -> dict:
    done = subprocess.run(
        ["node", str(REPO / "tests" / "notebook_view.mjs"), str(page), str(CHROMIUM), json.dumps(CHROMIUM_ARGS)],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=REPO,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    seen = json.loads(done.stdout.strip().splitlines()[-1])
    assert seen["errors"] == [] and seen["requests"] == []
    return seen


def test_the_viewer_html_is_self_contained():
    tree = lsys3d.generate("koch", 2)
    html = viewer_html(tree, height=200)
    # every module inline, and nothing in the data can end its <script> early
    assert all(name.split("/")[-1] in html for name in MODULES)
    assert html.count("</script>") == 3
    assert "<\\/" in html  # "</" inside the inlined sources is escaped


def test_a_tree_too_large_to_inline_shows_a_note(monkeypatch):
    from lsys3d.edit import notebook

    monkeypatch.setattr(notebook, "MAX_INLINE_BYTES", 1000)
    html = lsys3d.generate("koch", 2)._repr_html_()
    assert "more than a notebook output should hold" in html and "<script" not in html
