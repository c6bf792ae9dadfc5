// The last change, shown on the picture: each generation's dirty extents
// (the generation events carry them) outlined on the image for a few
// seconds, following the ground (heights from /api/elevation), on scenes
// whose grid is longitude and latitude. A checkbox turns it off.

import { relief } from "./hooks.js";
import { $, api, num } from "./util.js";

/** How long an outline stays on the picture. */
const SHOWN_MS = 4000;
/** Points along each side of an outline. */
const SIDE_POINTS = 12;
/** Extents outlined a generation at most. */
const MAX_EXTENTS = 16;

const WGS84_A = 6378137.0;
const WGS84_E2 = 6.69437999014e-3;

const ui = { svg: $("dirty"), toggle: $("show-dirty"), view: $("view") };

let hideTimer = 0;

ui.toggle.addEventListener("change", () => {
  if (!ui.toggle.checked) ui.svg.replaceChildren();
});

function ecef(lonDeg, latDeg, h) {
  const lon = (lonDeg * Math.PI) / 180;
  const lat = (latDeg * Math.PI) / 180;
  const n = WGS84_A / Math.sqrt(1 - WGS84_E2 * Math.sin(lat) ** 2);
  return [(n + h) * Math.cos(lat) * Math.cos(lon), (n + h) * Math.cos(lat) * Math.sin(lon), (n * (1 - WGS84_E2) + h) * Math.sin(lat)];
}

const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
const add = (a, b, s) => [a[0] + b[0] * s, a[1] + b[1] * s, a[2] + b[2] * s];
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];

/** Projects geodetic points into a frame of `camera` sized w x h: [x, y] or null behind the eye. */
export function projector(camera, w, h) {
  const lon = (num(camera.lonDeg) * Math.PI) / 180;
  const lat = (num(camera.latDeg) * Math.PI) / 180;
  const e = [-Math.sin(lon), Math.cos(lon), 0];
  const n = [-Math.sin(lat) * Math.cos(lon), -Math.sin(lat) * Math.sin(lon), Math.cos(lat)];
  const u = [Math.cos(lat) * Math.cos(lon), Math.cos(lat) * Math.sin(lon), Math.sin(lat)];
  const heading = (num(camera.headingDeg) * Math.PI) / 180;
  const pitch = (num(camera.pitchDeg) * Math.PI) / 180;
  const roll = (num(camera.rollDeg) * Math.PI) / 180;
  const level = add(add([0, 0, 0], e, Math.sin(heading)), n, Math.cos(heading));
  const forward = add(add([0, 0, 0], level, Math.cos(pitch)), u, Math.sin(pitch));
  const right0 = add(add([0, 0, 0], e, Math.cos(heading)), n, -Math.sin(heading));
  const up0 = cross(right0, forward);
  const up = add(add([0, 0, 0], up0, Math.cos(roll)), right0, -Math.sin(roll));
  const right = cross(forward, up);
  const eye = ecef(num(camera.lonDeg), num(camera.latDeg), num(camera.altitudeM));
  const tanHalf = Math.tan(((num(camera.verticalFovDeg) || 50) * Math.PI) / 360);
  const aspect = w / h;
  return ([lonDeg, latDeg, height]) => {
    const v = sub(ecef(lonDeg, latDeg, height), eye);
    const z = dot(v, forward);
    if (z <= 1) return null;
    const x = dot(v, right) / (z * tanHalf * aspect);
    const y = dot(v, up) / (z * tanHalf);
    return [((x + 1) / 2) * w, ((1 - y) / 2) * h];
  };
}

/** An extent's outline as points along its four sides. */
function ring(extent) {
  const [x0, y0, x1, y1] = [num(extent.minX), num(extent.minY), num(extent.maxX), num(extent.maxY)];
  const points = [];
  const side = (ax, ay, bx, by) => {
    for (let i = 0; i < SIDE_POINTS; i++) points.push([ax + ((bx - ax) * i) / SIDE_POINTS, ay + ((by - ay) * i) / SIDE_POINTS]);
  };
  side(x0, y0, x1, y0);
  side(x1, y0, x1, y1);
  side(x1, y1, x0, y1);
  side(x0, y1, x0, y0);
  points.push([x0, y0]);
  return points;
}

/** Outlines a generation's dirty extents on the picture for a few seconds. */
export async function showDirty(change) {
  if (!ui.toggle.checked) return;
  const grid = relief.state?.grid ?? {};
  if (grid.kind && grid.kind !== "geodetic") return;
  const extents = (change.dirty ?? []).flatMap((region) => region.extents ?? []).slice(0, MAX_EXTENTS);
  if (!extents.length) return;
  const rings = extents.map(ring);
  const points = rings.flat();
  let heights = [];
  try {
    const answer = await api("POST", "api/elevation", { points: points.map(([lonDeg, latDeg]) => ({ lonDeg, latDeg })) });
    heights = (answer.samples ?? []).map((s) => num(s.heightM));
  } catch {
    heights = [];
  }
  const frame = relief.lastFrame;
  if (!frame?.camera || !ui.toggle.checked) return;
  const w = num(frame.width);
  const h = num(frame.height);
  const project = projector(frame.camera, w, h);
  ui.svg.setAttribute("viewBox", `0 0 ${w} ${h}`);
  let at = 0;
  const lines = [];
  for (const r of rings) {
    // Broken where a point is behind the eye.
    let run = [];
    for (const [lon, lat] of r) {
      const p = project([lon, lat, (heights[at++] ?? 0) + 2]);
      if (p) run.push(p);
      else if (run.length) {
        lines.push(run);
        run = [];
      }
    }
    if (run.length > 1) lines.push(run);
  }
  // The <svg> in the page is in the SVG namespace: its children must be too.
  const ns = ui.svg.namespaceURI;
  ui.svg.replaceChildren(
    ...lines.map((run) => {
      const line = document.createElementNS(ns, "polyline");
      line.setAttribute("points", run.map(([x, y]) => `${x.toFixed(1)},${y.toFixed(1)}`).join(" "));
      return line;
    }),
  );
  relief.dirtyShown += 1;
  relief.dirtyLines = lines.length;
  clearTimeout(hideTimer);
  hideTimer = setTimeout(() => ui.svg.replaceChildren(), SHOWN_MS);
}
