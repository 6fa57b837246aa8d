#!/usr/bin/env python3
"""Writes the workspace's crate graph into docs/architecture.md.

Reads `cargo metadata` (no network, no build) and replaces the text between
`<!-- crates:begin -->` and `<!-- crates:end -->` with a Mermaid graph of
the workspace crates (an arrow from a crate to each crate it may use) and,
per crate, its direct normal dependencies from crates.io.

    python3 scripts/crate_graph.py          # rewrite the section
    python3 scripts/crate_graph.py --check  # exit 1 if it is out of date
"""
import json
import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "architecture.md"
BEGIN, END = "<!-- crates:begin -->", "<!-- crates:end -->"


def metadata():
    out = subprocess.run(
        ["cargo", "metadata", "--format-version", "1", "--no-deps", "--offline"],
        cwd=ROOT, check=True, capture_output=True, text=True,
    ).stdout
    return json.loads(out)


def section(meta):
    members = {p["name"]: p for p in meta["packages"]}
    lines = [BEGIN, "", "```mermaid", "graph TD"]
    rows = []
    for name in sorted(members):
        pkg = members[name]
        normal = [d for d in pkg["dependencies"] if d.get("kind") is None]
        inner = sorted({d["name"] for d in normal if d["name"] in members})
        outer = sorted({d["name"] for d in normal if d["name"] not in members})
        for dep in inner:
            lines.append(f"    {name} --> {dep}")
        rows.append((name, inner, outer))
    lines += ["```", "", "| crate | uses (workspace) | uses (crates.io) |", "|---|---|---|"]
    for name, inner, outer in rows:
        lines.append(
            f"| `{name}` | {', '.join(f'`{d}`' for d in inner) or '—'} | {', '.join(outer) or '—'} |"
        )
    lines += ["", "Made by `python3 scripts/crate_graph.py` from `cargo metadata`.", "", END]
    return "\n".join(lines)


def main():
    text = DOC.read_text()
    a, b = text.index(BEGIN), text.index(END) + len(END)
    new = text[:a] + section(metadata()) + text[b:]
    if "--check" in sys.argv[1:]:
        if new != text:
            print("docs/architecture.md: crate graph out of date; run python3 scripts/crate_graph.py")
            return 1
        return 0
    DOC.write_text(new)
    return 0


if __name__ == "__main__":
    sys.exit(main())
