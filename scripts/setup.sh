#!/usr/bin/env bash
# Installs the Debian packages relief needs, once (Chromium and curl are for
# the tests of the browser viewer and the HTTP transport; python3-venv for the
# Python client's tests; qgis and python3-qgis for the QGIS plugin's tests,
# which run PyQGIS headless; redis-server for the replicas' shared tile
# cache, which the tests start on a private socket; nodejs and npm for the
# standard-tiles tests, which read relief's tiles with CesiumJS, MapLibre and
# gltf-validator installed by `npm ci` from tests/npm's lockfile; a Node.js
# already here, with its npm, is used as it is). Safe to run again: it only
# calls apt-get when something is missing. Retries once, because an install on
# this kind of machine has been seen to fail half way (STACK.md).
set -euo pipefail

packages=(
  libgdal-dev gdal-bin python3-gdal libproj-dev proj-bin
  mesa-vulkan-drivers libvulkan1 pkg-config
  chromium curl
  python3-venv
  qgis python3-qgis
  redis-server
)
# A Node.js from elsewhere (NodeSource's carries npm) stays; Debian's
# otherwise.
if ! command -v node >/dev/null || ! command -v npm >/dev/null; then
  packages+=(nodejs npm)
fi

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0

sudo_cmd=()
[ "$(id -u)" -ne 0 ] && sudo_cmd=(sudo)
echo "installing Debian packages: ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
"${sudo_cmd[@]}" apt-get update -qq
for attempt in 1 2 3; do
  if "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"; then
    exit 0
  fi
  echo "apt-get install failed (attempt $attempt); repairing and retrying"
  "${sudo_cmd[@]}" apt-get install -f -y -qq || true
  sleep 2
done
echo "could not install: ${missing[*]}" >&2
exit 1
