#!/usr/bin/env bash
# The demo: writes a scene on real terrain (the SRTM crop committed in
# examples/data: the Maritime Alps' southern ranges and Provence, from the
# Lac de Sainte-Croix to Nice), serves it with reliefd on 127.0.0.1:50051,
# asks it a few questions with the relief CLI, renders views of it, and
# keeps serving until Ctrl-C (DEMO_EXIT=1 stops right after the tour).
# RELIEF_BIN=target/debug runs a debug build instead.
set -euo pipefail
cd "$(dirname "$0")/.."

bin=${RELIEF_BIN:-target/release}
out=demo-out
# Mesa's lavapipe wants a private runtime folder (it only warns without one).
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-$(mktemp -d)}
listen=${RELIEF_LISTEN:-127.0.0.1:50051}
export RELIEF_SERVER="http://$listen"
mkdir -p "$out"

manifest=$("$bin/relief-demo-scene" "$out/scene" examples/data/maritime-alps-srtm3.tif)
echo "demo scene written: $manifest"

"$bin/reliefd" serve "$manifest" --listen "$listen" > "$out/reliefd.out" 2> "$out/reliefd.log" &
daemon=$!
trap 'kill "$daemon" 2>/dev/null || true; wait "$daemon" 2>/dev/null || true' EXIT
for _ in $(seq 1 100); do
  grep -q '^listening on' "$out/reliefd.out" 2>/dev/null && break
  if ! kill -0 "$daemon" 2>/dev/null; then
    echo "reliefd did not start:" >&2; cat "$out/reliefd.log" >&2; exit 1
  fi
  sleep 0.1
done
grep '^listening on' "$out/reliefd.out" || { echo "reliefd did not say where it listens" >&2; exit 1; }
viewer=$(sed -n 's/^viewer: //p' "$out/reliefd.out")
echo "live view in a browser: $viewer"

step() { echo; echo "\$ $*"; "$@"; }
step "$bin/relief" state
# The lake, the Préalpes de Castellane, the Vésubie, the void at the
# Var's mouth (null) and a point outside the DEM (null).
step "$bin/relief" elevation 6.1713,43.7706 6.33,43.87 7.33,43.95 7.21,43.6625 9,45
step "$bin/relief" tile dem 9 530 131 -o "$out/dem-9-530-131.tif"
step "$bin/relief" tile ortho 9 530 131 -o "$out/ortho-9-530-131.png"
step "$bin/relief" tile shade 9 530 131 -o "$out/shade-9-530-131.png"
step "$bin/relief" state
# Views of the scene, rendered by reliefd (lavapipe without a GPU). The
# scene's own camera: from over the hills south of the Lac de Sainte-Croix,
# north across it to the Préalpes de Castellane, in the late sun.
step "$bin/relief" render -o "$out/view-range.png"
# From the Verdon gorges' southern rim (1,330 m), looking east-north-east.
step "$bin/relief" render --camera 6.30,43.745,1500,60,-15,0 -o "$out/view-gorges.png"
step "$bin/relief" render --camera 6.85,43.78,75000,0,-90,0 -o "$out/view-above.png"
step "$bin/relief" render --camera 6.85,30,15000000,0,-90,0 -o "$out/view-planet.png"
# The town on the plateau above the lake: 2,000 buildings extruded from
# town.shp, coloured by use.
step "$bin/relief" render --camera 6.135,43.768,900,5,-18,0 -o "$out/view-town.png"
# The forest scatter grows from the land cover (landcover.tif, classified
# by height): from inside the oak wood south of the lake, and over the
# slopes from above.
step "$bin/relief" render --camera 6.20,43.70,700,20,-8,0 -o "$out/view-forest.png"
step "$bin/relief" render --camera 6.45,43.80,2200,20,-20,0 -o "$out/view-slopes.png"
# The lake (lake.tif: SRTM's flat surface, drawn a metre over it) towards
# the low sun, and the ranges' shadows at a shadow-study hour.
step "$bin/relief" render --camera 6.23,43.755,700,285,-8,0 -o "$out/view-lake.png"
step "$bin/relief" render --camera 6.8,43.62,7000,0,-30,0 --sun-time 2026-06-21T20:00:00+02:00 -o "$out/view-shadows.png"
step "$bin/relief" state
echo
echo "views written:"
for v in range gorges above planet town forest slopes lake shadows; do echo "  $out/view-$v.png"; done

cat <<MSG

reliefd is serving the demo scene on $listen (log: $out/reliefd.log).
Watch it live: open $viewer in a browser (drag to orbit, right-drag to pan,
wheel to zoom, WASD to move); edit $out/scene/dem.tif or move a building in
$out/scene/town.shp (QGIS, ogr2ogr) and the view follows.
Try, in another terminal:
  curl -s http://$listen/api/state
  curl -s -o view.png "http://$listen/api/render?width=1280&height=720"
  $bin/relief state --json
  $bin/relief watch                      # then edit or replace $out/scene/dem.tif
  $bin/relief elevation 6.33,43.87
  $bin/relief tile shade 10 1063 262 -o shade.png
  $bin/relief camera set 6.45,43.80,2500,90,-20,0 && $bin/relief render -o view.png
  gdalinfo $out/dem-9-530-131.tif
Press Ctrl-C to stop.
MSG
if [ "${DEMO_EXIT:-0}" = 1 ]; then exit 0; fi
wait "$daemon"
