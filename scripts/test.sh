#!/usr/bin/env bash
# Builds everything and runs every test, then prints one closing line with
# the totals over all test binaries ("N passed, N failed, N ignored").
set -euo pipefail
cd "$(dirname "$0")/.."
# Mesa's lavapipe wants a private runtime folder (it only warns without one).
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-$(mktemp -d)}

log=$(mktemp)
trap 'rm -f "$log"' EXIT
cargo build --workspace --bins
status=0
cargo test --workspace 2>&1 | tee "$log" || status=$?
# Benches must build (they never run in CI: timings are not assertions).
cargo test --workspace --benches --no-run
awk '/^test result:/ { for (i = 1; i <= NF; i++) { if ($(i+1) ~ /^passed/) p += $i; if ($(i+1) ~ /^failed/) f += $i; if ($(i+1) ~ /^ignored/) g += $i } }
     END { printf "%d passed, %d failed, %d skipped\n", p, f, g }' "$log"
exit "$status"
