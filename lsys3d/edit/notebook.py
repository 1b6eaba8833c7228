"""The editor's 3D viewer in a notebook: one self-contained block of HTML, offline.

``Tree._repr_html_`` (Jupyter shows a tree returned by a cell) and ``Tree.show()`` call :func:`viewer_html`:
the tree written as .glb by :func:`lsys3d.exchange.export` (with its skeleton curves, for the skeleton view),
embedded as base64, and the page's own viewer (``static/viewer.js``) with three.js (``static/vendor/three``)
inlined as text.  In the browser the modules are loaded from ``blob:`` URLs, their import specifiers pointed at
each other's, so nothing is fetched from a network or a server.
"""

from __future__ import annotations

import base64
import html
import json
import secrets
import sys
import tempfile
import webbrowser
from pathlib import Path

from ..exchange import export
from ..exchange.common import ExportOptions
from ..tree import Tree

__all__ = ["MODULES", "show", "viewer_html"]

STATIC = Path(__file__).parent / "static"

MODULES = (
    "vendor/three/build/three.core.js",
    "vendor/three/build/three.module.js",
    "vendor/three/examples/jsm/utils/BufferGeometryUtils.js",
    "vendor/three/examples/jsm/utils/SkeletonUtils.js",
    "vendor/three/examples/jsm/loaders/GLTFLoader.js",
    "vendor/three/examples/jsm/controls/OrbitControls.js",
    "viewer.js",
)
"""The viewer's modules in the order they are loaded: each imports only modules before it."""

_LOADER = """
(async () => {
  const root = document.getElementById(%(id)s);
  try {
    const sources = JSON.parse(document.getElementById(%(id)s + '-modules').textContent);
    const urls = {};
    for (const [name, code] of sources) {
      // point each import at the blob of the module it names ('three' is three.module.js)
      const linked = code.replace(/(\\b(?:from|import)\\s*)(['"])([^'"]+)\\2/g, (m, kw, q, spec) => {
        const base = spec === 'three' ? 'three.module.js' : spec.split('/').pop();
        return urls[base] ? kw + q + urls[base] + q : m;
      });
      urls[name.split('/').pop()] = URL.createObjectURL(new Blob([linked], { type: 'text/javascript' }));
    }
    const { createViewer } = await import(urls['viewer.js']);
    const viewer = createViewer(root);
    const glb = Uint8Array.from(atob(document.getElementById(%(id)s + '-glb').textContent), (c) => c.charCodeAt(0));
    await viewer.load(glb.buffer);
    root.dataset.ready = 'true';
  } catch (error) {
    root.textContent = 'lsys3d viewer: ' + error;
  }
})();
"""


MAX_INLINE_BYTES = 64 << 20
"""The largest .glb a notebook output inlines (base64 makes it a third larger, and the notebook file keeps it);
a larger tree shows a note instead: export it and open it elsewhere."""


def _script_text(data: str) -> str:
    """Text safe inside a ``<script>`` element (which ends at the first ``</``)."""
    return data.replace("</", "<\\/")


def glb_of(tree: Tree) -> bytes:
    """``tree`` as the .glb the viewer shows: :func:`lsys3d.exchange.export`'s, with the skeleton curves."""
    with tempfile.TemporaryDirectory(prefix="lsys3d-view-") as folder:
        path = Path(folder) / "tree.glb"
        export(tree, path, ExportOptions(skeleton_curves=True))
        return path.read_bytes()


def viewer_html(tree: Tree, height: int = 480) -> str:
    """The viewer showing ``tree``, as one HTML block needing no network: three.js and the .glb inside.

    Parameters
    ----------
    tree : Tree
    height : int
        Height of the viewer in CSS pixels (its width is the cell's).

    Returns
    -------
    str
        A ``<div class="lsys3d-view">`` with the data and the script that draws it (about 2.3 MB plus the
        .glb's size in base64).
    """
    ident = f"lsys3d-view-{secrets.token_hex(6)}"
    data = glb_of(tree)
    if len(data) > MAX_INLINE_BYTES:
        return (
            f'<div class="lsys3d-view" data-asset="{html.escape(tree.identifier)}">lsys3d: {html.escape(tree.name)} '
            f"is {len(data) / 1e6:,.0f} MB as .glb, more than a notebook output should hold "
            f"({MAX_INLINE_BYTES >> 20} MB): export it (lsys3d.export) and open it in a viewer</div>"
        )
    sources = [[name, (STATIC / name).read_text(encoding="utf-8")] for name in MODULES]
    glb = base64.b64encode(data).decode("ascii")
    return (
        f'<div class="lsys3d-view" data-asset="{html.escape(tree.identifier)}">'
        f'<div id="{ident}" data-testid="lsys3d-viewer" style="width:100%;height:{int(height)}px"></div>'
        f'<script type="application/json" id="{ident}-modules">{_script_text(json.dumps(sources))}</script>'
        f'<script type="application/octet-stream" id="{ident}-glb">{glb}</script>'
        f"<script>{_LOADER % {'id': json.dumps(ident)}}</script>"
        "</div>"
    )


def show(tree: Tree, height: int = 480) -> Path | None:
    """Show ``tree`` in the viewer: inline in a notebook; elsewhere in the default browser, from a temporary
    HTML file (returned)."""
    ipython = sys.modules.get("IPython")
    shell = ipython.get_ipython() if ipython is not None else None
    block = viewer_html(tree, height)
    if shell is not None and getattr(shell, "kernel", None) is not None:
        from IPython.display import HTML, display

        display(HTML(block))
        return None
    page = Path(tempfile.mkdtemp(prefix="lsys3d-view-")) / f"{tree.identifier}.html"
    title = html.escape(tree.name)
    page.write_text(f"<!doctype html><meta charset='utf-8'><title>{title}</title>{block}", encoding="utf-8")
    webbrowser.open(page.as_uri())
    return page
