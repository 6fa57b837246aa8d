#!/usr/bin/env python3
"""The live view of `sweepline sim` queried with the Foxglove WebSocket
protocol's own client library, `@foxglove/ws-protocol` (npm, pinned in
node/package.json, with the `ws` WebSocket library), which offers only the
subprotocol name `foxglove.websocket.v1`.

Usage: foxglove_wsprotocol.py PATH/TO/sweepline

Installs the client into target/conformance-node (needs `node` and `npm`),
starts a simulation serving the live view on a free loopback port, runs
node/live_client.mjs against it and checks what the client saw. Ends with
`foxglove live view conformance: N passed, M failed`.
"""

import json
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from checks import Checks

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]


def install():
    """The pinned client in target/conformance-node, reinstalled when
    package.json changed."""
    dest = ROOT / "target" / "conformance-node"
    src = HERE / "node"
    dest.mkdir(parents=True, exist_ok=True)
    same = (dest / "package.json").exists() and \
        (dest / "package.json").read_bytes() == (src / "package.json").read_bytes()
    if not same or not (dest / "node_modules" / "@foxglove" / "ws-protocol").exists():
        shutil.copy(src / "package.json", dest / "package.json")
        subprocess.run(["npm", "install", "--no-audit", "--no-fund", "--silent"],
                       cwd=dest, check=True, timeout=600)
    shutil.copy(src / "live_client.mjs", dest / "live_client.mjs")
    return dest


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def main():
    if len(sys.argv) != 2:
        print("usage: foxglove_wsprotocol.py PATH/TO/sweepline", file=sys.stderr)
        return 2
    c = Checks()
    t0 = time.monotonic()
    sim = None
    try:
        node_dir = install()
        port = free_port()
        with tempfile.TemporaryDirectory() as d:
            sim = subprocess.Popen(
                [sys.argv[1], "sim", "--live", f"127.0.0.1:{port}", "--time-cap", "900",
                 "--out", str(Path(d) / "sim")],
                cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            out = subprocess.run(["node", "live_client.mjs", f"ws://127.0.0.1:{port}", "8"],
                                 cwd=node_dir, capture_output=True, text=True, timeout=120)
            sim.terminate()
            sim.wait(timeout=30)
        r = json.loads(out.stdout.strip().splitlines()[-1])
        c.check("connected without error", not r["errors"], str(r["errors"]))
        c.check("the server chose foxglove.websocket.v1", r["protocol"] == "foxglove.websocket.v1",
                str(r["protocol"]))
        c.check("serverInfo names sweepline", r["serverName"] == "sweepline", str(r["serverName"]))
        c.check("read-only: no capability (no client publish, services, parameters)",
                r["capabilities"] == [], str(r["capabilities"]))
        ch = r["channels"]
        for topic, schema in [("/scan", "foxglove.LaserScan"), ("/pose", "foxglove.PoseInFrame"),
                              ("/tf", "foxglove.FrameTransform"), ("/map", "foxglove.Grid"),
                              ("/plan", "foxglove.SceneUpdate"), ("/log", "foxglove.Log"),
                              ("/sweepline/status", "sweepline.Status")]:
            c.check(f"{topic} advertised as {schema}",
                    ch.get(topic, {}).get("schemaName") == schema, str(ch.get(topic)))
        n = r["counts"]
        c.check("scans streamed (at least 5 a second over 8 s)", n.get("/scan", 0) >= 40, str(n))
        c.check("poses streamed", n.get("/pose", 0) >= 40, str(n))
        c.check("the map streamed", n.get("/map", 0) >= 2, str(n))
        st = r["status"] or {}
        c.check("the status decodes as JSON with its fields",
                isinstance(st.get("covered_m2"), (int, float)) and "task" in st, str(st)[:200])
    except Exception as e:  # a crash is a failed check, not a traceback
        c.check("script ran to the end", False, f"{type(e).__name__}: {e}")
    finally:
        if sim and sim.poll() is None:
            sim.kill()
    print(f"info took {time.monotonic() - t0:.1f} s")
    return c.close("foxglove live view conformance")


if __name__ == "__main__":
    sys.exit(main())
