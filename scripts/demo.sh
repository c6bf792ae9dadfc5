#!/usr/bin/env bash
# The demo: writes a synthetic mountain scene, serves it with reliefd on
# 127.0.0.1:50051, asks it a few questions with the relief CLI, and keeps
# serving until Ctrl-C (DEMO_EXIT=1 stops right after the tour).
set -euo pipefail
cd "$(dirname "$0")/.."

bin=target/release
out=demo-out
# Mesa's lavapipe wants a private runtime folder (it only warns without one).
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-$(mktemp -d)}
listen=${RELIEF_LISTEN:-127.0.0.1:50051}
export RELIEF_SERVER="http://$listen"
mkdir -p "$out"

manifest=$("$bin/relief-demo-scene" "$out/scene")
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
step "$bin/relief" elevation 6.35,45.18 6.62,45.38 6.2,45.45 9,45
step "$bin/relief" tile dem 9 530 127 -o "$out/dem-9-530-127.tif"
step "$bin/relief" tile ortho 9 530 127 -o "$out/ortho-9-530-127.png"
step "$bin/relief" tile shade 9 530 127 -o "$out/shade-9-530-127.png"
step "$bin/relief" state
# Views of the scene, rendered by reliefd (lavapipe without a GPU).
step "$bin/relief" render -o "$out/view-range.png"
step "$bin/relief" render --camera 6.62,45.05,4500,340,-15,0 -o "$out/view-valley.png"
step "$bin/relief" render --camera 6.5,45.3,120000,0,-90,0 -o "$out/view-above.png"
step "$bin/relief" render --camera 6.5,30,15000000,0,-90,0 -o "$out/view-planet.png"
# The town in the valley: 2,000 buildings extruded from town.shp, coloured by use.
step "$bin/relief" render --camera 6.60,45.065,800,5,-18,0 -o "$out/view-town.png"
# The forest scatter grows from the land cover (landcover.tif): from inside
# the wood south of the town, and over the slopes from above.
step "$bin/relief" render --camera 6.60,45.055,450,5,-8,0 -o "$out/view-forest.png"
step "$bin/relief" render --camera 6.50,45.13,1900,40,-20,0 -o "$out/view-slopes.png"
# The lake (lake.tif, at 430 m over the DEM's void) in the late sun, and
# the range's shadows at a shadow-study hour.
step "$bin/relief" render --camera 6.26,45.40,1200,320,-12,0 -o "$out/view-lake.png"
step "$bin/relief" render --camera 6.45,44.95,9000,15,-25,0 --sun-time 2026-06-21T20:00:00+02:00 -o "$out/view-shadows.png"
step "$bin/relief" state
echo
echo "views written:"
for v in range valley above planet town forest slopes lake shadows; do echo "  $out/view-$v.png"; done

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
  $bin/relief elevation 6.5,45.3
  $bin/relief tile shade 10 1061 254 -o shade.png
  $bin/relief camera set 6.3,45.2,3000,90,-20,0 && $bin/relief render -o view.png
  gdalinfo $out/dem-9-530-127.tif
Press Ctrl-C to stop.
MSG
if [ "${DEMO_EXIT:-0}" = 1 ]; then exit 0; fi
wait "$daemon"
