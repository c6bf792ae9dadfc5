# Sourced by the test scripts of clients/python and clients/qgis, from the
# repository root: makes the virtual environment target/python (with the
# system site packages: GDAL's osgeo, numpy and PyQGIS come from Debian)
# and installs ./clients/python[test] into it. Sets $venv.
venv=target/python

# Bytecode caches beside the venv, not in the work tree.
export PYTHONPYCACHEPREFIX="$PWD/$venv/pycache"
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
relief_copy=$(mktemp -d)
cp -r clients/python "$relief_copy/relief"
rm -rf "$relief_copy/relief/build" "$relief_copy/relief/src/"*.egg-info
"$venv/bin/python" -m pip install --quiet "$relief_copy/relief[test]"
rm -rf "$relief_copy"
