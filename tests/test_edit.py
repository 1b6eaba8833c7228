"""``lsys3d edit``'s HTTP API through Starlette's test client: answers, errors, limits, cancellation, concurrent
requests, saving, and what the server refuses (docs/edit.md).  The workers are real processes."""

from __future__ import annotations

import hashlib
import json
import os
import time
from concurrent.futures import ThreadPoolExecutor

import pytest
from grown import grown

pytest.importorskip("starlette")
pytest.importorskip("httpx2")

from starlette.testclient import TestClient
from validators import REPO, gltf_issues, validate_gltf

from lsys3d.edit.server import MAX_BODY, EditSettings, make_app
from lsys3d.lsystem.presets import preset_text
from lsys3d.pipeline import Limits

BASE = "http://127.0.0.1"
TREE3D = preset_text("tree3d")


def _client(settings: EditSettings) -> TestClient:
    return TestClient(make_app(settings), base_url=BASE, raise_server_exceptions=False)


def _wait_ready(client: TestClient, workers: int) -> None:
    deadline = time.monotonic() + 300  # a first run compiles the kernels
    while client.get("/api/status").json()["ready"] < workers:
        assert time.monotonic() < deadline, client.get("/api/status").json()
        time.sleep(0.1)


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    path = tmp_path_factory.mktemp("edit")
    (path / "plant.toml").write_text(TREE3D, encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def client(folder):
    settings = EditSettings(str(folder / "plant.toml"), limits=Limits(max_modules=200_000))
    with _client(settings) as c:
        _wait_ready(c, 2)
        yield c


def test_generate_soup_then_union_is_the_cli_tree(client, tmp_path):
    soup = client.post("/api/generate", json={"text": TREE3D, "options": {"union": False}})
    assert soup.status_code == 200, soup.text
    full = client.post("/api/generate", json={"text": TREE3D, "suffix": ".toml", "iterations": 6, "seed": 0})
    assert full.status_code == 200, full.text
    s, f = soup.json()["stats"], full.json()["stats"]
    assert (s["unioned"], f["unioned"]) == (False, True)
    assert f["watertight"] is True
    assert s["segments"] == f["segments"] == 1457
    tree = grown("tree3d")  # the command line's tree (generate("tree3d"), grown once in the run): the same counts
    assert f["triangles"] == len(tree.bark.faces) and s["triangles"] == tree.counts.tube_faces
    assert set(f["seconds"]) >= {"derive", "interpret", "union", "cleanup", "export", "total"}
    glb = client.get(full.json()["asset"])
    assert glb.status_code == 200 and glb.headers["content-type"] == "model/gltf-binary"
    path = tmp_path / "tree.glb"
    path.write_bytes(glb.content)
    report = validate_gltf(path)
    assert gltf_issues(report, 0) == []
    # the same request, the same asset id and bytes (the asset's determinism)
    again = client.post("/api/generate", json={"text": TREE3D, "iterations": 6, "seed": 0})
    assert again.json()["id"] == full.json()["id"]
    assert client.get(again.json()["asset"]).content == glb.content


def test_other_formats_of_an_asset(client):
    made = client.post("/api/generate", json={"text": TREE3D, "iterations": 3}).json()
    for suffix, magic in ((".svg", b"<?xml"), (".usdc", b"PXR-USDC"), (".usdz", b"PK")):
        got = client.get(f"/api/asset/{made['id']}{suffix}")
        assert got.status_code == 200, got.text
        assert got.content.startswith(magic), (suffix, got.content[:20])
        assert "attachment" in got.headers["content-disposition"]
    assert client.get(f"/api/asset/{made['id']}.fbx").status_code == 404
    assert client.get("/api/asset/0123456789abcdef01234567.glb").status_code == 404


def test_a_bad_grammar_is_a_422_with_line_and_column(client):
    text = TREE3D.replace('"F(l) -> F(l*lr)"', '"F(l) -> F(l*lr"')
    got = client.post("/api/generate", json={"text": text})
    assert got.status_code == 422
    error = got.json()["error"]
    line = next(i for i, row in enumerate(text.splitlines(), 1) if "F(l*lr" in row)
    assert error["line"] == line and isinstance(error["col"], int) and error["message"]


def test_warnings_are_the_clis(client):
    text = 'axiom = "F X"\niterations = 1\nrules = ["F -> F[+F]F"]\n'
    got = client.post("/api/generate", json={"text": text, "options": {"union": False}})
    assert got.status_code == 200, got.text
    (warning,) = got.json()["diagnostics"]
    assert warning["severity"] == "warning" and "no rule and no turtle meaning" in warning["message"]


def test_native_dialects(client):
    lpy = "Axiom: F\nderivation length: 2\nproduction:\nF --> F[+F]F[-F]F\nendlsystem\n"
    got = client.post("/api/generate", json={"text": lpy, "suffix": ".lpy", "options": {"union": False}})
    assert got.status_code == 200, got.text
    assert got.json()["grammar"]["dialect"] == "lpy"


@pytest.mark.parametrize(
    ("body", "status", "words"),
    [
        ({"text": TREE3D, "options": {"no_such_option": 1}}, 422, "unknown option"),
        ({"text": TREE3D, "options": {"sides": 2}}, 422, "sides"),
        ({"text": TREE3D, "options": {"max_modules": 10**9}}, 422, "at most 200,000"),
        ({"text": TREE3D, "options": {"workers": 10**4}}, 422, "workers"),
        ({"text": TREE3D, "options": {"turtle": {"nope": 1}}}, 422, "nope"),
        ({"text": TREE3D, "export": {"up_axis": "Z"}}, 422, "up_axis"),
        ({"text": TREE3D, "iterations": -1}, 400, "iterations"),
        ({"text": TREE3D, "seed": "x"}, 400, "seed"),
        ({"text": 3}, 400, "text"),
        ({"text": TREE3D, "suffix": ".py"}, 400, "suffix"),
        ({"text": TREE3D, "path": "/etc/passwd"}, 400, "unknown field"),
        ([1, 2], 400, "object"),
    ],
)
def test_bad_requests_are_clear_json_errors(client, body, status, words):
    got = client.post("/api/generate", json=body)
    assert got.status_code == status, got.text
    assert words in got.json()["error"]["message"]


def test_limits_and_sizes(client):
    # the derivation's limit, predicted before allocating: a clear 422, not a worker's death
    got = client.post("/api/generate", json={"text": TREE3D, "iterations": 40})
    assert got.status_code == 422 and "max_modules" in got.text
    too_big = "#" * MAX_BODY
    got = client.post(
        "/api/generate", content=json.dumps({"text": too_big}), headers={"content-type": "application/json"}
    )
    assert got.status_code == 413
    got = client.post("/api/generate", content=b'{"text": "x"', headers={"content-type": "application/json"})
    assert got.status_code == 400 and "JSON" in got.json()["error"]["message"]
    got = client.post("/api/generate", content=b"text=1", headers={"content-type": "application/x-www-form-urlencoded"})
    assert got.status_code == 415
    assert client.get("/no/such/page").json()["error"]["message"]


def test_a_newer_request_on_a_channel_cancels_the_older(client):
    started = client.get("/api/status").json()["started"]
    slow = {"text": TREE3D, "iterations": 7, "channel": "full"}  # a union of seconds
    fast = {"text": TREE3D, "iterations": 2, "channel": "full"}
    with ThreadPoolExecutor(2) as pool:
        first = pool.submit(client.post, "/api/generate", json=slow)
        deadline = time.monotonic() + 60
        while client.get("/api/status").json()["busy"] == 0:  # the slow one is running in a worker
            assert time.monotonic() < deadline
            time.sleep(0.02)
        second = pool.submit(client.post, "/api/generate", json=fast)
        old, new = first.result(timeout=300), second.result(timeout=300)
    assert old.status_code == 409 and "superseded" in old.json()["error"]["message"]
    assert new.status_code == 200 and new.json()["stats"]["modules"] < 1000
    # the superseded worker was killed and another started in its place
    _wait_ready(client, 2)
    assert client.get("/api/status").json()["started"] == started + 1


def test_concurrent_requests_on_other_channels_all_answer(client):
    bodies = [{"text": TREE3D, "iterations": 3 + i % 2, "seed": i, "channel": f"c{i}"} for i in range(5)]
    with ThreadPoolExecutor(5) as pool:
        answers = list(pool.map(lambda b: client.post("/api/generate", json=b), bodies))
    assert [a.status_code for a in answers] == [200] * 5
    assert len({a.json()["id"] for a in answers}) == 5


def test_files_outside_the_grammars_folder_are_refused(client, folder):
    outside = folder.parent / "outside.png"
    outside.write_bytes(b"\x89PNG\r\n\x1a\n")
    for name in (str(outside), "../outside.png"):
        text = TREE3D + f'\n[materials]\nbark = {{ texture = "{name}" }}\n'
        got = client.post("/api/generate", json={"text": text, "options": {"union": False}})
        assert got.status_code == 422, got.text
        assert "outside the grammar's folder" in got.json()["error"]["message"]
    assert client.get("/api/asset/..%2F..%2Fetc%2Fpasswd").status_code == 404
    assert client.get("/static/../server.py").status_code == 404


def test_save_is_atomic_and_refuses_a_file_changed_on_disk(client, folder):
    path = folder / "plant.toml"
    doc = client.get("/api/document").json()
    assert doc["text"] == path.read_text() and doc["suffix"] == ".toml" and not doc["read_only"]
    edited = doc["text"].replace("iterations = 6", "iterations = 5")
    saved = client.post("/api/save", json={"text": edited, "version": doc["version"]})
    assert saved.status_code == 200, saved.text
    assert path.read_text() == edited
    assert saved.json()["version"]["sha256"] == hashlib.sha256(edited.encode()).hexdigest()
    # the old version is stale now: saving with it is refused
    again = client.post("/api/save", json={"text": "axiom = 'F'\n", "version": doc["version"]})
    assert again.status_code == 409 and path.read_text() == edited
    # another program writes the file: the page's version no longer matches, nothing is overwritten
    path.write_text(edited + "# changed by hand\n")
    refused = client.post("/api/save", json={"text": edited, "version": saved.json()["version"]})
    assert refused.status_code == 409 and "changed on disk" in refused.json()["error"]["message"]
    assert path.read_text().endswith("# changed by hand\n")
    assert [p.name for p in folder.iterdir() if p.name.startswith(".")] == []  # no temporary file left
    path.write_text(TREE3D)


def test_a_preset_is_read_only():
    with _client(EditSettings("koch", workers=1)) as c:
        doc = c.get("/api/document").json()
        assert doc["read_only"] and doc["name"] == "koch"
        got = c.post("/api/save", json={"text": doc["text"], "version": doc["version"]})
        assert got.status_code == 403 and "read-only" in got.json()["error"]["message"]


def test_hosts_origins_and_tokens(folder):
    with _client(EditSettings(str(folder / "plant.toml"), workers=1, token="s3cret", hosts=None)) as c:
        assert c.get("/api/status").status_code == 401
        assert c.get("/api/status", headers={"X-Lsys3d-Token": "wrong"}).status_code == 401
        assert c.get("/api/status", headers={"X-Lsys3d-Token": "s3cret"}).status_code == 200
        assert c.get("/api/status?token=s3cret").status_code == 200
        assert c.get("/").status_code == 200  # the page holds no secret; the API does
    with _client(EditSettings(str(folder / "plant.toml"), workers=1)) as c:
        assert c.get("/api/status", headers={"Host": "evil.example:80"}).status_code == 421
        got = c.get("/api/status", headers={"Origin": "http://evil.example"})
        assert got.status_code == 403 and "another site" in got.json()["error"]["message"]


def test_the_page_and_its_files_are_served(client):
    page = client.get("/")
    assert page.status_code == 200 and "importmap" in page.text
    for name in ("app.js", "editor.js", "viewer.js", "style.css", "vendor/three/build/three.module.js"):
        assert client.get(f"/static/{name}").status_code == 200, name
    assert "MIT" in client.get("/static/vendor/three/LICENSE").text
    specs = client.get("/api/options").json()
    names = {(s["group"], s["name"]) for s in specs["options"]}
    assert {("option", "sides"), ("turtle", "tropism"), ("turtle", "width_jitter")} <= names


def test_the_cli_serves_and_stops(folder):
    """``lsys3d edit --port 0 --no-browser`` prints its address, serves, and ends its workers on SIGTERM."""
    import signal
    import subprocess
    import sys
    import urllib.request

    proc = subprocess.Popen(
        [sys.executable, "-m", "lsys3d", "edit", str(folder / "plant.toml"), "--port", "0", "--no-browser"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        line = proc.stdout.readline()
        assert line.startswith("lsys3d edit: http://127.0.0.1:"), line + proc.stderr.read()
        url = line.split()[2]
        with urllib.request.urlopen(url + "api/document", timeout=30) as answer:
            assert json.loads(answer.read())["name"] == "plant.toml"
        with urllib.request.urlopen(url + "api/status", timeout=30) as answer:
            pids = json.loads(answer.read())["pids"]
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=60)
    assert proc.returncode == 128 + signal.SIGTERM  # the CLI's exit status for SIGTERM, after its cleanup
    assert len(pids) == 2
    for pid in pids:  # the workers ended with the server
        with pytest.raises(ProcessLookupError):
            os.kill(pid, 0)


HOST_ARGS = ("--host", "127.0.0.2", "--port", "0", "--no-browser", "--jobs", "1")


def test_another_address_needs_a_token(folder):
    """``--host`` other than the loopback's 127.0.0.1: the address printed carries a token the API insists on."""
    import signal
    import subprocess
    import sys
    import urllib.error
    import urllib.request

    proc = subprocess.Popen(
        [sys.executable, "-m", "lsys3d", "edit", str(folder / "plant.toml"), *HOST_ARGS],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        url = proc.stdout.readline().split()[2]
        base, _, token = url.partition("?token=")
        assert base.startswith("http://127.0.0.2:") and len(token) >= 20
        with pytest.raises(urllib.error.HTTPError) as refused:
            urllib.request.urlopen(base + "api/document", timeout=30)
        assert refused.value.code == 401
        with urllib.request.urlopen(f"{base}api/document?token={token}", timeout=30) as answer:
            assert json.loads(answer.read())["name"] == "plant.toml"
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=60)


def test_a_full_queue_is_a_503_and_a_dead_worker_a_500(folder):
    """One worker and room for one waiting request: a third is refused at once; a worker killed mid-union (as
    the system's out-of-memory killer would) fails its request with a clear 500 and is replaced."""
    import os
    import signal

    slow = {"text": TREE3D, "iterations": 7}  # busy for the seconds the next requests take to queue
    small = {"text": TREE3D, "iterations": 3}  # the replacement runs it whole: its size is not the point
    with _client(EditSettings(str(folder / "plant.toml"), workers=1, queue=1)) as c:
        _wait_ready(c, 1)
        with ThreadPoolExecutor(2) as pool:
            running = pool.submit(c.post, "/api/generate", json={**slow, "channel": "a"})
            _until(c, lambda s: s["busy"] == 1)
            waiting = pool.submit(c.post, "/api/generate", json={**small, "seed": 1, "channel": "b"})
            _until(c, lambda s: s["waiting"] == 1)
            refused = c.post("/api/generate", json={**small, "seed": 2, "channel": "c"})
            assert refused.status_code == 503 and "waiting" in refused.json()["error"]["message"]
            (pid,) = c.get("/api/status").json()["pids"]
            os.kill(pid, signal.SIGKILL)
            died = running.result(timeout=300)
            assert died.status_code == 500 and "worker ended" in died.json()["error"]["message"]
            assert waiting.result(timeout=300).status_code == 200  # the replacement worker took it
        assert c.get("/api/status").json()["started"] == 2


def _until(client: TestClient, condition) -> None:
    deadline = time.monotonic() + 120
    while not condition(client.get("/api/status").json()):
        assert time.monotonic() < deadline, client.get("/api/status").json()
        time.sleep(0.02)


def test_a_missing_file_is_made_on_the_first_save(folder):
    path = folder / "new-plant.toml"
    with _client(EditSettings(str(path), workers=1)) as c:
        doc = c.get("/api/document").json()
        assert not doc["exists"] and not doc["read_only"] and "axiom" in doc["text"]
        saved = c.post("/api/save", json={"text": doc["text"], "version": doc["version"]})
        assert saved.status_code == 200 and path.read_text() == doc["text"]


def test_workers_that_cannot_start_fail_requests_with_the_reason(folder):
    """A worker that dies before it is ready (here: not even Python) is not restarted forever."""
    import asyncio

    from lsys3d.edit.pool import Pool, WorkerFailed

    async def attempt():
        pool = Pool(1, python="/bin/false")
        await pool.start()
        for _ in range(200):
            if pool.broken:
                break
            await asyncio.sleep(0.02)
        try:
            with pytest.raises(WorkerFailed, match="in a row ended before they were ready"):
                await pool.run({"options": {}, "key": "k"})
            return pool.started
        finally:
            await pool.close()

    assert asyncio.run(attempt()) == 3


def test_a_first_runs_compiling_is_reported(tmp_path):
    """While a worker compiles the kernels (a first run) the pool's status says how far it is: the page's
    status line and the terminal show it.  A stand-in worker reports one kernel of five, then waits."""
    import asyncio
    import stat
    import sys

    from lsys3d.edit.pool import Pool

    script = tmp_path / "python"
    script.write_text(
        f"#!{sys.executable}\n"
        "import sys\n"
        f"sys.path.insert(0, {str(REPO)!r})\n"
        "from lsys3d.edit import frames\n"
        "sys.stdout.buffer.write(frames.encode({'kind': 'compiling', 'done': 1, 'total': 5}))\n"
        "sys.stdout.buffer.flush()\n"
        "sys.stdin.buffer.read()\n"
    )
    script.chmod(script.stat().st_mode | stat.S_IEXEC)

    async def watch():
        pool = Pool(1, python=str(script))
        await pool.start()
        try:
            for _ in range(500):
                if pool.status["compiling"]:
                    return pool.status
                await asyncio.sleep(0.02)
        finally:
            await pool.close()

    status = asyncio.run(watch())
    assert status["compiling"] == {"done": 1, "total": 5} and status["ready"] == 0
