#!/usr/bin/env bash
# Builds everything and runs every test: the Rust workspace, then the
# Python client's tests and the QGIS plugin's tests against the reliefd
# just built. Prints one closing line with the totals over all of them
# ("N passed, N failed, N skipped").
set -euo pipefail
cd "$(dirname "$0")/.."
# Mesa's lavapipe wants a private runtime folder (it only warns without one).
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-$(mktemp -d)}
# reliefd keeps tiles on disk in the user's cache folder: the tests get one
# of their own, gone when they end, so no run reads another's tiles.
XDG_CACHE_HOME=$(mktemp -d)
export XDG_CACHE_HOME

log=$(mktemp)
pylog=$(mktemp)
trap 'rm -rf "$log" "$pylog" "$XDG_CACHE_HOME"' EXIT
# One build with one feature set serves the binaries, the tests and the
# benches (benches must build; they never run here: timings are not
# assertions). `cargo build --bins` first would build without the
# dev-dependencies' features, and build much of the workspace twice.
cargo test --workspace --all-targets --no-run
status=0
# Every test binary runs, whatever an earlier one did, so one run shows
# every failure.
cargo test --workspace --no-fail-fast 2>&1 | tee "$log" || status=$?
# The Python client (clients/python) and its example, against this reliefd.
RELIEF_BIN=target/debug/reliefd bash clients/python/scripts/test.sh 2>&1 | tee "$pylog" || status=$?
# The QGIS plugin (clients/qgis) in headless PyQGIS, against this reliefd.
RELIEF_BIN=target/debug/reliefd bash clients/qgis/scripts/test.sh 2>&1 | tee -a "$pylog" || status=$?
{
  awk '/^test result:/ { for (i = 1; i <= NF; i++) { if ($(i+1) ~ /^passed/) p += $i; if ($(i+1) ~ /^failed/) f += $i; if ($(i+1) ~ /^ignored/) g += $i } }
       END { printf "%d %d %d\n", p, f, g }' "$log"
  # pytest's summary: "==== 3 failed, 38 passed, 1 skipped in 9.1s ====".
  awk '/^=+ .* in [0-9.]+s/ { for (i = 1; i <= NF; i++) { if ($(i+1) ~ /^passed/) p += $i; if ($(i+1) ~ /^(failed|errors?)/) f += $i; if ($(i+1) ~ /^skipped/) g += $i } }
       END { printf "%d %d %d\n", p, f, g }' "$pylog"
} | awk '{ p += $1; f += $2; g += $3 } END { printf "%d passed, %d failed, %d skipped\n", p, f, g }'
exit "$status"
