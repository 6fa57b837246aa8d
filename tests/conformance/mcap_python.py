#!/usr/bin/env python3
"""A `sweepline sim` recording (`run.mcap`) read by readers nobody here
wrote: the `mcap` Python library and its protobuf decoder
(mcap-protobuf-support), pinned in requirements.txt.

Usage: mcap_python.py PATH/TO/sweepline

Runs a short simulation with the recording on, then reads it with the
library's indexed reader (summary, statistics, channels, schemas), decodes
every Foxglove message with the schemas the file carries, parses the JSON
channels, and reads a copy cut in the middle (as a killed daemon leaves it)
with the library's non-seeking reader. Ends with
`mcap conformance: N passed, M failed`.
"""

import json
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from mcap.reader import make_reader, NonSeekingReader
from mcap_protobuf.decoder import DecoderFactory

from checks import Checks

EXPECTED = {
    "/scan": ("foxglove.LaserScan", "protobuf"),
    "/sweepline/scan_input": ("sweepline.ScanInput", "json"),
    "/sweepline/odometry_input": ("sweepline.OdometryInput", "json"),
    "/pose": ("foxglove.PoseInFrame", "protobuf"),
    "/odom": ("foxglove.PoseInFrame", "protobuf"),
    "/tf": ("foxglove.FrameTransform", "protobuf"),
    "/map": ("foxglove.Grid", "protobuf"),
    "/swept": ("foxglove.Grid", "protobuf"),
    "/plan": ("foxglove.SceneUpdate", "protobuf"),
    "/log": ("foxglove.Log", "protobuf"),
    "/sweepline/status": ("sweepline.Status", "json"),
    "/sim/truth": ("foxglove.PoseInFrame", "protobuf"),
}


def record(binary, out):
    # From the repository root: the default world is hw/worlds/paper.world.
    root = Path(__file__).resolve().parents[2]
    subprocess.run([binary, "sim", "--live", "off", "--time-cap", "60", "--out", str(out)],
                   check=False, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                   timeout=600, cwd=root)
    return out / "run.mcap"


def whole_file(path, c):
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        c.check("the file has a summary (closed by its writer)", summary is not None)
        topics = {ch.topic: (summary.schemas[ch.schema_id].name, ch.message_encoding)
                  for ch in summary.channels.values()}
        for topic, want in EXPECTED.items():
            c.check(f"{topic} is a channel with schema {want[0]} ({want[1]})",
                    topics.get(topic) == want, str(topics.get(topic)))
        counts = {summary.channels[k].topic: v
                  for k, v in summary.statistics.channel_message_counts.items()}
        c.check("as many LaserScans as scan inputs",
                counts.get("/scan") == counts.get("/sweepline/scan_input") and counts["/scan"] > 300,
                f"{counts.get('/scan')} / {counts.get('/sweepline/scan_input')}")
        c.check("wheel odometry at 30 Hz or more (the motor stage polls at 50 Hz)",
                counts.get("/sweepline/odometry_input", 0) > 30 * 60,
                f"{counts.get('/sweepline/odometry_input')} readings in 60 s")
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
        c.check("metadata: clock, setup, map_to_world",
                {"clock", "setup", "map_to_world"} <= metadata.keys(), str(sorted(metadata)))
        last, decoded, bad = {}, 0, []
        scans, inputs = [], []
        for schema, channel, message, proto in reader.iter_decoded_messages(
                topics=[t for t, (s, e) in EXPECTED.items() if e == "protobuf"]):
            decoded += 1
            t = channel.topic
            if message.log_time < last.get(t, 0):
                bad.append(t)
            last[t] = message.log_time
            if t == "/scan" and len(scans) < 50:
                scans.append(proto)
        c.check("every protobuf message decodes with the schema in the file", decoded > 1000,
                f"{decoded} decoded")
        c.check("log times never go backwards on a channel", not bad, str(sorted(set(bad))))
        for schema, channel, message in reader.iter_messages(
                topics=["/sweepline/scan_input", "/sweepline/status"]):
            doc = json.loads(message.data)
            if channel.topic == "/sweepline/scan_input" and len(inputs) < 50:
                inputs.append(doc)
        same = all(
            len(s.ranges) == len(i["ranges"]) and all(
                (math.isnan(a) if k in set(i["invalid"]) else a == b)
                for k, (a, b) in enumerate(zip(s.ranges, i["ranges"])))
            for s, i in zip(scans, inputs))
        c.check("a LaserScan's ranges are the scan input's (invalid beams NaN)",
                same and len(scans) == 50)
        return path.stat().st_size


def cut_file(path, size, c):
    cut = path.with_name("cut.mcap")
    cut.write_bytes(path.read_bytes()[: size // 2])
    n = 0
    try:
        with open(cut, "rb") as f:
            reader = NonSeekingReader(f, validate_crcs=True)
            # In file order: sorting by log time would read to the end first.
            for _ in reader.iter_messages(log_time_order=False):
                n += 1
    except Exception as e:  # the reader stops at the cut
        print(f"info the reader stopped at the cut: {type(e).__name__}")
    c.check("a file cut in half still yields its messages up to the cut", n > 500, f"{n} messages")


def main():
    if len(sys.argv) != 2:
        print("usage: mcap_python.py PATH/TO/sweepline", file=sys.stderr)
        return 2
    c = Checks()
    t0 = time.monotonic()
    try:
        with tempfile.TemporaryDirectory() as d:
            path = record(sys.argv[1], Path(d) / "sim")
            if c.check("sweepline sim wrote run.mcap", path.exists()):
                size = whole_file(path, c)
                cut_file(path, size, c)
    except Exception as e:  # a crash is a failed check, not a traceback
        c.check("script ran to the end", False, f"{type(e).__name__}: {e}")
    print(f"info took {time.monotonic() - t0:.1f} s")
    return c.close("mcap conformance")


if __name__ == "__main__":
    sys.exit(main())
