#!/usr/bin/env bash
# Tests of the Python client (clients/python) and its example
# (examples/python) against a real reliefd. Makes the virtual environment
# target/python (with the system site packages: GDAL's osgeo and numpy
# come from Debian's python3-gdal), installs ./clients/python[test] into
# it, runs pytest and exits with pytest's status; pytest's last line is the
# summary ("N passed, ...").
#
# Needs: the Debian packages python3-venv and python3-gdal, PyPI, and a
# built reliefd ($RELIEF_BIN, else reliefd on PATH, else the newer of
# target/release/reliefd and target/debug/reliefd). Extra arguments go to
# pytest (say -k reload, or -x).
set -euo pipefail
cd "$(dirname "$0")/../../.."
repo=$(pwd)
# (Without XDG_RUNTIME_DIR, relief.testing gives each reliefd a private one
# for Mesa's lavapipe and removes it afterwards.)
source clients/python/scripts/venv.sh

status=0
"$venv/bin/python" -m pytest -p no:cacheprovider -ra --rootdir "$repo" \
  clients/python/tests examples/python "$@" || status=$?
exit "$status"
