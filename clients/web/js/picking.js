// The cursor readout: longitude, latitude and ground height under the
// mouse, from the view's last frame, asked on the tab's socket one at a
// time (the latest position wins).

import { relief } from "./hooks.js";
import { $, fixed } from "./util.js";

const ui = { cursor: $("cursor") };

let picking = false;
let wanted = null; // the latest position not yet asked about
let inside = false;

/** Asks what lies under `at` (fractions of the image) with `call(kind, body)`. */
export function pick(call, at) {
  inside = true;
  wanted = at;
  if (!picking) next(call);
}

export function pointerLeft() {
  inside = false;
  wanted = null;
  ui.cursor.textContent = "–";
}

async function next(call) {
  picking = true;
  try {
    while (wanted && relief.viewId && relief.lastFrame) {
      const at = wanted;
      wanted = null;
      try {
        const reply = await call("pick", { x: at.x, y: at.y });
        // A newer position is asked about next; one outside shows nothing.
        if (wanted === null && inside) show(reply.pick ?? {});
      } catch {
        ui.cursor.textContent = "–";
      }
    }
  } finally {
    picking = false;
  }
}

function show(hit) {
  if (!(hit.hit ?? false)) {
    ui.cursor.textContent = "sky";
    return;
  }
  const ground = hit.groundHeightM === undefined || hit.groundHeightM === null ? "nodata" : `${fixed(hit.groundHeightM, 1)} m`;
  ui.cursor.textContent = `${fixed(hit.lonDeg, 6)}, ${fixed(hit.latDeg, 6)} · ${ground}`;
}
