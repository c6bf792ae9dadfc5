#!/usr/bin/env bash
# Installs what relief's build and tests need, once. First the Debian
# packages (Chromium and curl are for the tests of the browser viewer and the
# HTTP transport; python3-venv for the Python client's tests and the venv
# below; qgis and python3-qgis for the QGIS plugin's tests, which run PyQGIS
# headless; redis-server for the replicas' shared tile cache, which the tests
# start on a private socket; nodejs and npm for the standard-tiles tests,
# which read relief's tiles with CesiumJS, MapLibre and gltf-validator
# installed by `npm ci` from tests/npm's lockfile; a Node.js already here,
# with its npm, is used as it is). Then a Python venv, target/s3, holding a
# pinned moto[server]: the real S3-compatible server the object-storage tests
# start on a free port (tests/src/s3.rs); Debian packages no S3 server.
# Safe to run again: it only calls apt-get when a package is missing and pip
# when target/s3/bin/moto_server is. apt-get retries, because an install on
# this kind of machine has been seen to fail half way (STACK.md).
set -euo pipefail
cd "$(dirname "$0")/.."

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

install_debian_packages() {
  local missing=() p attempt
  for p in "${packages[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  [ ${#missing[@]} -eq 0 ] && return 0

  local sudo_cmd=()
  [ "$(id -u)" -ne 0 ] && sudo_cmd=(sudo)
  echo "installing Debian packages: ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  "${sudo_cmd[@]}" apt-get update -qq
  for attempt in 1 2 3; do
    if "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}"; then
      return 0
    fi
    echo "apt-get install failed (attempt $attempt); repairing and retrying"
    "${sudo_cmd[@]}" apt-get install -f -y -qq || true
    sleep 2
  done
  echo "could not install: ${missing[*]}" >&2
  return 1
}

# moto in server mode, the S3 server of the object-storage tests, pinned so
# every machine tests against the same one. pip runs only when the server's
# script is missing: a venv left half made by a failed install is finished.
moto=5.2.6
install_s3_server() {
  [ -x target/s3/bin/moto_server ] && return 0
  echo "installing moto[server]==$moto into target/s3"
  python3 -m venv target/s3
  target/s3/bin/pip install --quiet --disable-pip-version-check "moto[server]==$moto"
}

install_debian_packages
install_s3_server
