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
venv=target/python

# (Without XDG_RUNTIME_DIR, relief.testing gives each reliefd a private one
# for Mesa's lavapipe and removes it afterwards.)
# Bytecode caches beside the venv, not in the work tree.
export PYTHONPYCACHEPREFIX="$repo/$venv/pycache"
export PIP_DISABLE_PIP_VERSION_CHECK=1

if [ ! -x "$venv/bin/python" ]; then
  /usr/bin/python3 -m venv --system-site-packages "$venv"
fi
if ! "$venv/bin/python" -c 'import osgeo.gdal, numpy' 2>/dev/null; then
  echo "GDAL's Python bindings are missing: apt-get install python3-gdal (and python3-venv)" >&2
  exit 1
fi

# Install from a clean copy: setuptools keeps build/ between builds in the
# source folder, where a module removed since would live on in the wheel.
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cp -r clients/python "$work/relief"
rm -rf "$work/relief/build" "$work/relief/src/"*.egg-info
"$venv/bin/python" -m pip install --quiet "$work/relief[test]"

status=0
"$venv/bin/python" -m pytest -p no:cacheprovider -ra --rootdir "$repo" \
  clients/python/tests examples/python "$@" || status=$?
exit "$status"
