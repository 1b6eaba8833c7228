"""``lsys3d edit``'s latency: keypress to tube soup on screen, and the full asset against the command line's time.

Measured in one run, warm (the kernels compiled, the workers started):

- the command line's work for the same tree, in this process: ``generate`` then ``export`` to .glb (best of 3),
  and the ``lsys3d generate -o tree.glb`` command itself (its wall time, interpreter start included);
- the API, from a client in this process: ``POST /api/generate`` (soup, then union) and ``GET`` of its .glb, for
  ``--edits`` edits of the grammar (a define's last digit changed, so no answer comes from a cache);
- the page in headless Chromium (``benchmarks/bench_edit.mjs``), when Chromium and playwright-core are there:
  from the input event of a typed digit to the frame that draws the soup, and then the union; and a burst of
  five digits 60 ms apart (the older work cancelled), timed from the last one.

The goals of issue 35: soup on screen within 250 ms for tree3d (warm, 2 cores); the full asset within the
command line's time + 10 %.  Run: ``python benchmarks/bench_edit.py [--preset tree3d] [--edits 10]``.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

from timing import best_of

from lsys3d.exchange import export
from lsys3d.lsystem.presets import load, preset_text
from lsys3d.pipeline import generate

REPO = Path(__file__).resolve().parents[1]
CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--no-first-run",
    "--use-gl=angle",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
]


def _post(url: str, body: dict) -> dict:
    request = urllib.request.Request(
        url, data=json.dumps(body).encode(), headers={"Content-Type": "application/json"}, method="POST"
    )
    with urllib.request.urlopen(request, timeout=600) as answer:
        return json.loads(answer.read())


def _get(url: str) -> bytes:
    with urllib.request.urlopen(url, timeout=600) as answer:
        return answer.read()


def _summary(values: list[float]) -> str:
    if not values:
        return "-"
    values = sorted(values)
    p90 = values[min(len(values) - 1, round(0.9 * (len(values) - 1)))]
    return f"median {statistics.median(values):7.0f}  p90 {p90:7.0f}  max {values[-1]:7.0f}  (n={len(values)})"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--preset", default="tree3d")
    parser.add_argument("--edits", type=int, default=10)
    parser.add_argument("--no-browser", action="store_true", help="only the API's latency")
    args = parser.parse_args()
    text = preset_text(args.preset)
    if args.preset == "tree3d":
        edits = [text.replace("lr = 1.109", f"lr = 1.10{i % 10}") for i in range(args.edits)]
    else:
        edits = [text + f"\n# edit {i}\n" for i in range(args.edits)]  # the same tree: the worker's own time
    grammar = load(args.preset)
    folder = Path(tempfile.mkdtemp(prefix="lsys3d-bench-edit-"))
    try:
        generate(grammar, union=False)  # warm: the kernels compiled or loaded
        cli_seconds, _ = best_of(lambda: export(generate(grammar), folder / "cli.glb"), repeat=3)
        t0 = time.perf_counter()
        subprocess.run(
            [sys.executable, "-m", "lsys3d", "generate", args.preset, "-o", str(folder / "command.glb"), "-q"],
            check=True,
        )
        command_seconds = time.perf_counter() - t0

        path = folder / "plant.toml"
        path.write_text(text, encoding="utf-8")
        server = subprocess.Popen(
            [sys.executable, "-m", "lsys3d", "edit", str(path), "--port", "0", "--no-browser"],
            stdout=subprocess.PIPE,
            text=True,
        )
        try:
            line = server.stdout.readline()
            url = re.search(r"http://\S+", line).group(0)
            while json.loads(_get(url + "api/status"))["ready"] < 2:
                time.sleep(0.1)
            soup, full = [], []
            for body in edits:
                for kind, times in (("soup", soup), ("full", full)):
                    options = {"union": False} if kind == "soup" else {}
                    t0 = time.perf_counter()
                    made = _post(url + "api/generate", {"text": body, "options": options, "channel": kind})
                    _get(url + made["asset"][1:])
                    times.append(1000 * (time.perf_counter() - t0))
            page = None
            if not args.no_browser and CHROMIUM.exists() and (REPO / "node_modules" / "playwright-core").is_dir():
                done = subprocess.run(
                    [
                        "node",
                        str(REPO / "benchmarks" / "bench_edit.mjs"),
                        url,
                        str(args.edits),
                        str(CHROMIUM),
                        json.dumps(CHROMIUM_ARGS),
                    ],
                    capture_output=True,
                    text=True,
                    timeout=1800,
                    cwd=REPO,
                )
                if done.returncode != 0:
                    print(done.stderr[-3000:], file=sys.stderr)
                    return 1
                page = json.loads(done.stdout.strip().splitlines()[-1])
        finally:
            server.send_signal(signal.SIGTERM)
            server.wait(timeout=60)
    finally:
        shutil.rmtree(folder, ignore_errors=True)

    average = " ".join(Path("/proc/loadavg").read_text().split()[:3]) if Path("/proc/loadavg").exists() else "?"
    print(f"lsys3d edit, {args.preset}, warm, {args.edits} edits (milliseconds); load average {average}")
    print(f"  command line in-process: generate + export .glb   {1000 * cli_seconds:7.0f}  (best of 3)")
    print(f"  command line: lsys3d generate -o tree.glb          {1000 * command_seconds:7.0f}  (interpreter included)")
    print(f"  API soup:  POST + GET .glb    {_summary(soup)}")
    print(f"  API union: POST + GET .glb    {_summary(full)}")
    if full:
        median = statistics.median(full) / 1000
        print(
            f"  API union / command line in-process: {median / cli_seconds:.2f}; "
            f"/ the command: {median / command_seconds:.2f}  (goal <= 1.10)"
        )
    if page is not None:
        print(f"  page: keypress to soup on screen    {_summary(page['soup'])}  (goal <= 250)")
        print(f"     of which the soup's job in the worker  {_summary(page['soupWorker'])}")
        print(f"     and to its .glb received               {_summary(page['soupFetched'])}")
        print(f"  page: keypress to union on screen   {_summary(page['full'])}")
        burst = {x["kind"]: x["ms"] for x in page["burst"]}
        shown = ", ".join(f"{k} {v:.0f}" for k, v in burst.items())
        print(f"  page: five digits 60 ms apart, from the last: {shown}")
    else:
        print("  page: not measured (--no-browser, or Chromium / playwright-core missing)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
