#!/usr/bin/env bash
# Tests of the QGIS plugin (clients/qgis) in headless PyQGIS
# (QT_QPA_PLATFORM=offscreen) against a real reliefd. Runs in the virtual
# environment target/python that clients/python's tests use (PyQGIS comes
# from Debian's python3-qgis through the system site packages; the relief
# package gives the tests their daemon and scene). Exits with pytest's
# status; pytest's last line is the summary ("N passed, ...").
#
# Needs: the Debian packages qgis and python3-qgis, and what
# clients/python/scripts/test.sh needs. Extra arguments go to pytest.
set -euo pipefail
cd "$(dirname "$0")/../../.."
repo=$(pwd)
source clients/python/scripts/venv.sh
if ! "$venv/bin/python" -c 'import qgis.core' 2>/dev/null; then
  echo "PyQGIS is missing: apt-get install qgis python3-qgis" >&2
  exit 1
fi
export QT_QPA_PLATFORM=offscreen
status=0
"$venv/bin/python" -m pytest -p no:cacheprovider -ra --rootdir "$repo" clients/qgis/tests "$@" || status=$?
exit "$status"
