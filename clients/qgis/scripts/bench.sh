#!/usr/bin/env bash
# The QGIS plugin's benchmark (clients/qgis/bench/commit_to_frame.py): a
# QGIS commit to a new frame in the dock, in headless PyQGIS against the
# release reliefd. Extra arguments go to the benchmark (--commits N,
# --size WxH).
set -euo pipefail
cd "$(dirname "$0")/../../.."
source clients/python/scripts/venv.sh
cargo build --release -q -p relief-daemon --bin reliefd
export QT_QPA_PLATFORM=offscreen RELIEF_BIN=${RELIEF_BIN:-target/release/reliefd}
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-$(mktemp -d)}
exec "$venv/bin/python" clients/qgis/bench/commit_to_frame.py "$@"
