"""The HTTP side of ``lsys3d edit``: a Starlette app serving the page and the API it uses (docs/edit.md).

Starlette (routing, requests, responses) and uvicorn (the ASGI server) are the ``edit`` extra's dependencies;
this module is imported only by ``lsys3d edit`` and the tests, never by ``import lsys3d``.

The API grows trees with the command line's own functions, in the worker processes of :mod:`lsys3d.edit.pool`
(:func:`lsys3d.edit.worker.run_job`).  It reads and writes one file, the grammar being edited
(:class:`~lsys3d.edit.document.Document`); the files a grammar names are read from its folder only.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import hashlib
import hmac
import json
import logging
import math
import os
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

from starlette.applications import Starlette
from starlette.exceptions import HTTPException
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, Response
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles

from ..errors import LSystemError, OptionsError
from ..exchange import SUPPORTED_SUFFIXES
from ..exchange.common import ExportOptions
from ..lsystem.grammar import MAX_GRAMMAR_BYTES
from ..options import flat_fields, spec_of
from ..pipeline import GenerateOptions, Limits
from ..turtle.options import GRAMMAR_KEYS, TurtleOptions, TurtleOverrides
from .document import EDITABLE_SUFFIXES, Conflict, Document, ReadOnly, Version
from .pool import Busy, Pool, Superseded, WorkerFailed

__all__ = ["EditSettings", "make_app"]

log = logging.getLogger("lsys3d")

STATIC = Path(__file__).parent / "static"
"""The page: index.html, its script and style, and three.js (``vendor/three``, with its licence)."""

MAX_BODY = MAX_GRAMMAR_BYTES + (64 << 10)
"""Largest request body: the largest grammar the command line reads, and room for the options."""

ASSET_SUFFIXES = tuple(s for s in SUPPORTED_SUFFIXES if s != ".gltf")  # .gltf is two files: .glb is the one
"""What ``GET /api/asset/<id><suffix>`` writes."""

MAX_ASSETS = 64
"""Requests remembered (for their assets), the oldest forgotten first."""

MAX_ASSET_BYTES = 512 << 20
"""The .glb files kept in memory at most, in all."""

CHANNEL_LENGTH = 64


@dataclass(frozen=True)
class EditSettings:
    """How the server runs: the grammar, the limits of every request, the workers, who may call it.

    Attributes
    ----------
    grammar : str
        The grammar file (or a preset's name) to edit.
    limits : Limits
        The most a request may ask for (``max_modules``, ``max_segments``, ``max_triangles``): the command
        line's defaults unless ``lsys3d edit`` was given others; a request may ask for less.
    workers : int
        Worker processes, the jobs that run at once.
    queue : int
        Requests that may wait for a worker.
    token : str or None
        When set, every API call must carry it (header ``X-Lsys3d-Token`` or ``?token=``): needed when the
        server listens on another address than the loopback.
    hosts : tuple of str or None
        The ``Host`` headers accepted (no other site's page can reach the API through DNS rebinding); None:
        any (a server listening on another address than the loopback, behind its token).
    """

    grammar: str
    limits: Limits = dataclasses.field(default_factory=Limits)
    workers: int = 2
    queue: int = 16
    token: str | None = None
    hosts: tuple[str, ...] | None = ("127.0.0.1", "localhost", "[::1]")


def _error(status: int, message: str, line=None, col=None, **extra) -> JSONResponse:
    return JSONResponse({"error": {"line": line, "col": col, "message": message, **extra}}, status_code=status)


class _Refused(Exception):
    def __init__(self, status: int, message: str):
        super().__init__(message)
        self.status = status


def option_specs() -> list[dict]:
    """The numeric and boolean options the page makes controls of: flat name, kind, range, default and help.

    ``group`` is ``option`` (a :class:`GenerateOptions` flat name, sent in ``options``) or ``turtle`` (a key of
    the grammar's ``[turtle]`` table, sent in ``options.turtle``).
    """
    out = []
    defaults = GenerateOptions()
    for name, path in flat_fields(GenerateOptions).items():
        owner = defaults
        for step in path[:-1]:
            owner = getattr(owner, step)
        spec = spec_of(_field(type(owner), path[-1]))
        if spec.kind in (int, float, bool) and not spec.optional:
            out.append(_spec_json("option", name, spec, getattr(owner, path[-1])))
    turtle = TurtleOptions()
    for f in dataclasses.fields(TurtleOptions):
        spec = spec_of(f)
        if f.name in GRAMMAR_KEYS and spec is not None and (spec.kind in (int, float) or spec.kind == "vector"):
            out.append(_spec_json("turtle", f.name, spec, getattr(turtle, f.name)))
    return out


def _field(cls, name: str) -> dataclasses.Field:
    return next(f for f in dataclasses.fields(cls) if f.name == name)


def _spec_json(group: str, name: str, spec, default) -> dict:
    kind = spec.kind if isinstance(spec.kind, str) else spec.kind.__name__

    def finite(x):
        return x if x is not None and math.isfinite(x) else None

    return {
        "group": group,
        "name": name,
        "kind": kind,
        "low": finite(spec.low),
        "high": finite(spec.high),
        "default": list(default) if isinstance(default, tuple) else default,
        "help": spec.help,
    }


class Editor:
    """The state behind the routes: the document, the pool and the assets made."""

    def __init__(self, settings: EditSettings):
        self.settings = settings
        self.document = Document.open(settings.grammar)
        self.pool = Pool(settings.workers, settings.queue)
        self.requests: OrderedDict[str, dict] = OrderedDict()
        self.assets: OrderedDict[str, bytes] = OrderedDict()
        self.flat = flat_fields(GenerateOptions)
        self.export_flat = flat_fields(ExportOptions)

    # -------------------------------------------------------------- requests
    def job(self, data) -> tuple[dict, str | None]:
        """The worker's job for a ``POST /api/generate`` body, checked; and its channel."""
        if not isinstance(data, dict):
            raise _Refused(400, "the body must be a JSON object")
        unknown = sorted(set(data) - {"text", "suffix", "iterations", "seed", "options", "export", "channel"})
        if unknown:
            raise _Refused(400, f"unknown field {unknown[0]!r}")
        text = data.get("text")
        if not isinstance(text, str):
            raise _Refused(400, "'text' must be the grammar's text (a string)")
        if len(text.encode("utf-8", "surrogatepass")) > MAX_GRAMMAR_BYTES:
            raise _Refused(413, f"the grammar is larger than {MAX_GRAMMAR_BYTES} bytes")
        suffix = data.get("suffix", self.document.suffix)
        if suffix not in EDITABLE_SUFFIXES:
            raise _Refused(400, f"'suffix' must be one of {', '.join(EDITABLE_SUFFIXES)}")
        iterations, seed = data.get("iterations"), data.get("seed")
        for name, value in (("iterations", iterations), ("seed", seed)):
            if value is not None and (not isinstance(value, int) or isinstance(value, bool) or value < 0):
                raise _Refused(400, f"'{name}' must be a whole number >= 0 or null")
        if seed is not None and seed >= 1 << 63:
            raise _Refused(400, "'seed' must be below 2**63")
        options = dict(data.get("options") or {})
        turtle = options.pop("turtle", None) or {}
        exported = dict(data.get("export") or {})
        channel = data.get("channel")
        if channel is not None and (not isinstance(channel, str) or not 0 < len(channel) <= CHANNEL_LENGTH):
            raise _Refused(400, f"'channel' must be a string of 1 to {CHANNEL_LENGTH} characters")
        for name in options:
            if name not in self.flat:
                raise _Refused(422, f"unknown option {name!r} (the flat names of GenerateOptions, as the CLI's flags)")
        for name in exported:
            if name not in self.export_flat or name == "no_clobber":
                raise _Refused(422, f"unknown export option {name!r}")
        ceiling = self.settings.limits
        for name in ("max_modules", "max_segments", "max_triangles"):
            most = getattr(ceiling, name)
            asked = options.setdefault(name, most)
            if isinstance(asked, int) and not isinstance(asked, bool) and asked > most:
                raise _Refused(422, f"{name}: at most {most:,} on this server (lsys3d edit --{name.replace('_', '-')})")
        workers = options.get("workers")
        if isinstance(workers, int) and workers > (os.cpu_count() or 1):
            raise _Refused(422, f"workers: at most {os.cpu_count() or 1} (the cores of this machine)")
        try:  # the same checks the worker makes: a bad option fails at once, without a worker
            generate_options = GenerateOptions.from_flat(**options)
            if turtle:
                if not isinstance(turtle, dict):
                    raise OptionsError("options.turtle must be an object of [turtle] settings")
                generate_options = replace(generate_options, turtle=TurtleOverrides(turtle))
            ExportOptions.from_flat(**exported)
        except (OptionsError, TypeError, ValueError) as exc:
            raise _Refused(422, str(exc)) from None
        source = self.document.source
        if suffix != self.document.suffix:
            source = str(Path(source).with_suffix(suffix))
        tree = {
            "text": text,
            "source": source,
            "iterations": iterations,
            "seed": seed,
            "options": options,
            "turtle": dict(turtle),
        }
        key = hashlib.sha256(json.dumps(tree, sort_keys=True, default=str).encode()).hexdigest()[:24]
        job = {**tree, "folder": str(self.document.folder), "export": exported, "key": key, "format": ".glb"}
        del generate_options
        return job, channel

    @staticmethod
    def asset_id(job: dict) -> str:
        return hashlib.sha256(f"{job['key']}|{json.dumps(job['export'], sort_keys=True)}".encode()).hexdigest()[:24]

    def remember(self, asset: str, job: dict, glb: bytes | None) -> None:
        self.requests[asset] = job
        self.requests.move_to_end(asset)
        while len(self.requests) > MAX_ASSETS:
            self.requests.popitem(last=False)
        if glb is not None:
            self.assets[asset] = glb
            self.assets.move_to_end(asset)
        while self.assets and (sum(map(len, self.assets.values())) > MAX_ASSET_BYTES or len(self.assets) > MAX_ASSETS):
            self.assets.popitem(last=False)

    async def run(self, job: dict, channel: str | None) -> dict:
        try:
            return await self.pool.run(job, channel)
        except Superseded as exc:
            raise _Refused(409, str(exc)) from None
        except Busy as exc:
            raise _Refused(503, str(exc)) from None
        except WorkerFailed as exc:
            raise _Refused(500, f"{exc}: the grammar may need more memory than this machine has") from None


async def _json_body(request: Request):
    kind = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if kind != "application/json":  # a form on another site cannot send this without asking first (CORS)
        raise _Refused(415, "the body must be JSON (Content-Type: application/json)")
    declared = request.headers.get("content-length")
    if declared is not None and declared.isdigit() and int(declared) > MAX_BODY:
        raise _Refused(413, f"the request is larger than {MAX_BODY} bytes")
    chunks, size = [], 0
    async for chunk in request.stream():
        size += len(chunk)
        if size > MAX_BODY:
            raise _Refused(413, f"the request is larger than {MAX_BODY} bytes")
        chunks.append(chunk)
    try:
        return json.loads(b"".join(chunks))
    except (ValueError, RecursionError):
        raise _Refused(400, "the body is not valid JSON") from None


def make_app(settings: EditSettings, announce: Callable[[str], None] | None = None) -> Starlette:
    """The editor's ASGI app: the page at ``/``, three.js and the page's files under ``/static``, the API under
    ``/api`` (docs/edit.md).  ``announce`` is told, once a second while it lasts, how the first run's compiling
    of the kernels goes (the command line prints it)."""
    editor = Editor(settings)

    async def index(request: Request) -> Response:
        return FileResponse(STATIC / "index.html", headers={"Cache-Control": "no-store"})

    async def favicon(request: Request) -> Response:
        return Response(status_code=204)

    async def document(request: Request) -> Response:
        doc = editor.document
        text, version = doc.read()
        return JSONResponse(
            {
                "name": doc.name,
                "path": None if doc.path is None else str(doc.path),
                "suffix": doc.suffix,
                "text": text,
                "version": version.to_json(),
                "read_only": doc.path is None,
                "exists": doc.path is not None and doc.path.exists(),
                "formats": list(ASSET_SUFFIXES),
            }
        )

    async def save(request: Request) -> Response:
        data = await _json_body(request)
        if not isinstance(data, dict) or not isinstance(data.get("text"), str):
            raise _Refused(400, "the body must be {text, version}")
        try:
            opened = Version.from_json(data.get("version"))
        except ValueError as exc:
            raise _Refused(400, str(exc)) from None
        try:
            version = editor.document.save(data["text"], opened)
        except ReadOnly as exc:
            raise _Refused(403, str(exc)) from None
        except Conflict as exc:
            return _error(409, str(exc), current=editor.document.current().to_json())
        return JSONResponse({"version": version.to_json(), "path": str(editor.document.path)})

    async def generate(request: Request) -> Response:
        job, channel = editor.job(await _json_body(request))
        asset = editor.asset_id(job)
        answer = await editor.run(job, channel)
        if not answer["ok"]:
            error = answer["error"]
            return _error(422, error["message"], error["line"], error["col"], diagnostics=answer["diagnostics"])
        editor.remember(asset, job, answer["data"])
        return JSONResponse(
            {
                "id": asset,
                "asset": f"/api/asset/{asset}.glb",
                "stats": answer["stats"],
                "diagnostics": [{"severity": "warning", "message": m} for m in answer["diagnostics"]],
                "grammar": answer["grammar"],
            }
        )

    async def asset(request: Request) -> Response:
        name = request.path_params["name"]
        asset, dot, suffix = name.partition(".")
        suffix = dot + suffix
        if suffix not in ASSET_SUFFIXES:
            raise _Refused(404, f"unknown format {suffix!r}; one of {', '.join(ASSET_SUFFIXES)}")
        job = editor.requests.get(asset)
        if job is None:
            raise _Refused(404, f"no asset {asset!r} (made by POST /api/generate; the oldest are forgotten)")
        stem = Path(editor.document.name).stem or "tree"
        headers = {"Content-Disposition": f'attachment; filename="{stem}{suffix}"', "Cache-Control": "no-store"}
        kinds = {".glb": "model/gltf-binary", ".svg": "image/svg+xml", ".usdz": "model/vnd.usdz+zip"}
        kind = kinds.get(suffix, "application/octet-stream")
        if suffix == ".glb" and asset in editor.assets:
            return Response(editor.assets[asset], media_type=kind, headers=headers)
        answer = await editor.run({**job, "format": suffix}, None)
        if not answer["ok"]:
            error = answer["error"]
            return _error(422, error["message"], error["line"], error["col"])
        if suffix == ".glb":
            editor.remember(asset, job, answer["data"])
        return Response(answer["data"], media_type=kind, headers=headers)

    async def status(request: Request) -> Response:
        return JSONResponse(editor.pool.status)

    async def options(request: Request) -> Response:
        limits = settings.limits
        return JSONResponse(
            {
                "options": option_specs(),
                "limits": {k: getattr(limits, k) for k in ("max_modules", "max_segments", "max_triangles")},
            }
        )

    async def refused(request: Request, exc: _Refused) -> Response:
        return _error(exc.status, str(exc))

    async def http_error(request: Request, exc: HTTPException) -> Response:
        return _error(exc.status_code, exc.detail if isinstance(exc.detail, str) else "error")

    async def user_error(request: Request, exc: LSystemError) -> Response:
        return _error(422, str(exc))

    async def crashed(request: Request, exc: Exception) -> Response:
        log.error("lsys3d edit: %s: %s", type(exc).__name__, exc)
        return _error(500, f"internal error: {type(exc).__name__} (see the server's log)")

    @contextlib.asynccontextmanager
    async def lifespan(app):
        await editor.pool.start()
        watcher = asyncio.get_running_loop().create_task(_announce(editor.pool, announce)) if announce else None
        try:
            yield
        finally:
            if watcher is not None:
                watcher.cancel()
            await editor.pool.close()

    app = Starlette(
        routes=[
            Route("/", index),
            Route("/favicon.ico", favicon),
            Route("/api/document", document),
            Route("/api/save", save, methods=["POST"]),
            Route("/api/generate", generate, methods=["POST"]),
            Route("/api/asset/{name}", asset),
            Route("/api/status", status),
            Route("/api/options", options),
            Mount("/static", StaticFiles(directory=STATIC), name="static"),
        ],
        exception_handlers={_Refused: refused, HTTPException: http_error, LSystemError: user_error, Exception: crashed},
        lifespan=lifespan,
    )
    app.state.editor = editor
    return _Guard(app, settings)


async def _announce(pool: Pool, announce: Callable[[str], None]) -> None:
    shown = False
    while True:
        await asyncio.sleep(1.0)
        if pool.compiling is not None:
            done, total = pool.compiling
            announce(f"compiling lsys3d's kernels (first run only): {done} of up to {total}...")
            shown = True
        elif shown and pool.status["ready"]:
            announce("")
            shown = False


class _Guard:
    """ASGI middleware: the ``Host`` must be one of ours (DNS rebinding), an ``Origin`` our own page's, and the
    token right when one is set.  Refusals are JSON like every other error."""

    def __init__(self, app, settings: EditSettings):
        self.app = app
        self.settings = settings
        self.state = app.state

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http":
            return await self.app(scope, receive, send)
        headers = {k.decode("latin-1").lower(): v.decode("latin-1") for k, v in scope["headers"]}
        host = headers.get("host", "")
        name = host.rsplit(":", 1)[0] if not host.endswith("]") else host
        problem = None
        if self.settings.hosts is not None and name not in self.settings.hosts:
            problem = (421, f"unknown host {host!r} (this server answers {', '.join(self.settings.hosts)})")
        origin = headers.get("origin")
        if problem is None and origin is not None and origin.split("://", 1)[-1] != host:
            problem = (403, "requests from another site's page are refused")
        if problem is None and self.settings.token and scope["path"].startswith("/api/"):
            query = dict(p.partition("=")[::2] for p in scope.get("query_string", b"").decode("latin-1").split("&"))
            given = headers.get("x-lsys3d-token") or query.get("token") or ""
            if not hmac.compare_digest(given.encode(), self.settings.token.encode()):
                problem = (401, "a token is needed: open the address 'lsys3d edit' printed, with its ?token=")
        if problem is None:
            return await self.app(scope, receive, send)
        await _error(*problem)(scope, receive, send)
