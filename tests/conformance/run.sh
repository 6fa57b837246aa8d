#!/usr/bin/env bash
# The conformance tier: the emulators, the recordings and the live view
# driven by client libraries nobody here wrote (Basicmicro's `basicmicro`,
# the community's `pycreate2`, the `mcap` Python library and its protobuf
# decoder, installed pinned into a virtual environment under target/; the
# Foxglove WebSocket protocol's `@foxglove/ws-protocol`, installed by npm
# under target/). Usage:
#
#   bash tests/conformance/run.sh [path/to/sweepline]
#
# Without an argument it builds and uses target/release/sweepline.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
target="${CARGO_TARGET_DIR:-$root/target}"
bin="${1:-}"
if [ -z "$bin" ]; then
    (cd "$root" && cargo build --release --quiet)
    bin="$target/release/sweepline"
fi
venv="$target/conformance-venv"
if [ ! -x "$venv/bin/python" ] || ! cmp -s "$here/requirements.txt" "$venv/requirements.txt"; then
    python3 -m venv "$venv"
    "$venv/bin/pip" install --quiet --disable-pip-version-check -r "$here/requirements.txt"
    cp "$here/requirements.txt" "$venv/requirements.txt"
fi
status=0
passed=0
failed=0
for script in "$here"/*_*.py; do
    echo "== $(basename "$script")"
    log="$(mktemp)"
    "$venv/bin/python" "$script" "$bin" | tee "$log" || status=1
    # Each script closes with `NAME: N passed, M failed` (NAME: lower-case
    # letters, digits and spaces).
    read -r p f < <(tail -n 1 "$log" | sed -nE 's/^[a-z0-9 ]+: ([0-9]+) passed, ([0-9]+) failed$/\1 \2/p') || { p=0; f=1; status=1; }
    passed=$((passed + ${p:-0}))
    failed=$((failed + ${f:-1}))
    rm -f "$log"
done
echo "conformance: $passed passed, $failed failed"
exit $status
