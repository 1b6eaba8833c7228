"""``lsys3d edit``: the grammar editor in the browser, and the same 3D viewer in notebooks.

- :mod:`lsys3d.edit.server`: the Starlette app (the page and its HTTP API, docs/edit.md); needs the ``edit``
  extra (Starlette, uvicorn).
- :mod:`lsys3d.edit.pool` and :mod:`lsys3d.edit.worker`: the worker processes that grow the trees, a newer
  edit superseding the older work.
- :mod:`lsys3d.edit.document`: the grammar's file, saved atomically and never over a change made on disk.
- :mod:`lsys3d.edit.notebook`: the viewer as one self-contained HTML block (``Tree._repr_html_``, ``Tree.show``).
- ``static/``: the page, its script and style, and three.js (``static/vendor/three``, MIT, with its licence).

Nothing here is imported by ``import lsys3d``.
"""
