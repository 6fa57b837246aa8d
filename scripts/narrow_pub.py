#!/usr/bin/env python3
"""Narrows `pub` to `pub(crate)` in one crate where nothing outside it names the item.

Usage: scripts/narrow_pub.py CRATE_DIR [--dry-run]

For every item-level `pub` (fn, struct, enum, const, static, type, trait,
mod, fields, methods) in CRATE_DIR/src, looks for its name as a whole word
in every other Rust file of the workspace (other crates, `src/`, `tests/`,
`bench/`, the crate's own `tests/` and `benches/`). An item whose name
appears nowhere outside its crate becomes `pub(crate)`; `pub use`
re-exports and `lib.rs` are left alone. Conservative: a common name
(`new`, `len`) found anywhere keeps its `pub`. The compiler then tells what
is still too narrow (a private type in a public signature, a re-export of a
narrowed item): widen those by hand, and let the dead-code lint show what
nothing uses at all.
"""
import os
import re
import sys

ITEM = re.compile(
    r"^(\s*)pub (?P<kw>(?:const fn|async fn|unsafe fn|fn|struct|enum|const|static|type|trait|mod)) "
    r"(?P<name>[A-Za-z_][A-Za-z0-9_]*)"
)
FIELD = re.compile(r"^(\s+)pub (?P<name>[a-z_][a-z0-9_]*)\s*:")


def rust_files(root):
    for d, dirs, files in os.walk(root):
        dirs[:] = [x for x in dirs if x not in ("target", ".git", "fuzz")]
        for f in files:
            if f.endswith(".rs"):
                yield os.path.join(d, f)


def main():
    crate = os.path.abspath(sys.argv[1])
    dry = "--dry-run" in sys.argv
    ws = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
    src = os.path.join(crate, "src")
    outside = []
    for f in rust_files(ws):
        if not f.startswith(src + os.sep):
            outside.append(open(f, encoding="utf-8").read())
    words = set()
    for text in outside:
        words.update(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", text))
    narrowed = kept = 0
    for f in rust_files(src):
        if os.path.basename(f) == "lib.rs":
            continue
        lines = open(f, encoding="utf-8").read().split("\n")
        changed = False
        for i, line in enumerate(lines):
            m = ITEM.match(line) or FIELD.match(line)
            if not m:
                continue
            if m.group("name") in words:
                kept += 1
                continue
            lines[i] = line.replace("pub ", "pub(crate) ", 1)
            changed = True
            narrowed += 1
        if changed and not dry:
            open(f, "w", encoding="utf-8").write("\n".join(lines))
    print(f"{narrowed} narrowed, {kept} kept pub (named outside {os.path.relpath(crate, ws)})")


if __name__ == "__main__":
    main()
