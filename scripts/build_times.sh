#!/usr/bin/env bash
# Build times of a checkout on this machine: a clean `cargo build --release`,
# then the incremental rebuild after one line changes in the planner, in the
# SCIP decoder and in the daemon's localise stage, each separately (a comment
# appended to the file, so the code is the same; the file is restored
# afterwards).
#
#   scripts/build_times.sh [CHECKOUT] [TARGET_DIR]
#
# CHECKOUT defaults to this repository, TARGET_DIR to a fresh directory under
# /tmp (the clean build needs an empty one). Run it on a quiet machine and
# compare checkouts measured in the same session.
set -euo pipefail
repo="$(cd "${1:-$(dirname "$0")/..}" && pwd)"
target="${2:-$(mktemp -d /tmp/sweepline-build-times.XXXXXX)}"
cd "$repo"
export CARGO_TARGET_DIR="$target" CARGO_TERM_COLOR=never
timed() {
    local t0 t1
    t0=$(date +%s.%N)
    cargo build --release -q
    t1=$(date +%s.%N)
    python3 -c "print(f'{$t1 - $t0:.1f}')"
}
touch_line() {
    # The first tracked file whose path ends with $1.
    local f
    f=$(git ls-files | grep -E "$1\$" | head -n1)
    [ -n "$f" ] || { echo "no file matching $1 in $repo" >&2; exit 1; }
    cp "$f" "$target/touched.bak"
    echo "// build-times probe" >>"$f"
    echo "$f"
}
restore() { cp "$target/touched.bak" "$1"; }
echo "checkout: $(git -C "$repo" rev-parse --short HEAD) ($repo), $(nproc) cores"
echo "clean cargo build --release: $(timed) s"
for probe in "plan/planner/mod.rs" "scip/decoder.rs" "daemon/stages/localise.rs"; do
    f=$(touch_line "$probe")
    s=$(timed)
    restore "$f"
    echo "rebuild after one line in $f: $s s"
    timed >/dev/null
done
