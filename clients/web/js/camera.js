// Steering the tab's camera: mouse and keys become gestures (orbit, pan,
// zoom, move) sent on the tab's socket, at most one in flight and the rest
// merged meanwhile; frames go interactive while they come and back to full
// quality at rest. reliefd keeps every gesture above the ground and inside
// the scene, so none can lose the camera; Home brings it back anyway.

import { relief } from "./hooks.js";
import { report } from "./panel.js";
import { pick, pointerLeft } from "./picking.js";
import { $, formatCamera } from "./util.js";

const ORBIT_DEG_PER_PX = 0.3;
const ZOOM_PER_NOTCH = 0.85;
const MOVE_STEP = 0.1; // of the camera's height above the ground (reliefd keeps a floor)
const TURN_STEP_DEG = 5;
const INTERACTIVE_IDLE_MS = 250;

const ui = { viewport: $("viewport"), view: $("view"), camera: $("camera") };

/**
 * Wires the viewport. `tab.call(kind, body)` sends a call on the socket;
 * `tab.lost(error)` is told of an error that may mean the view is gone.
 */
export function steer(tab) {
  // Gestures waiting to be sent, by kind, in the order they started.
  const pending = new Map();
  let navigating = false;
  let interactive = false;
  let idleTimer = 0;

  function failed(error, context) {
    report(error, context);
    tab.lost(error);
  }

  function queue(kind, merge) {
    pending.set(kind, merge(pending.get(kind)));
    pump();
  }

  async function pump() {
    if (navigating || pending.size === 0) return;
    navigating = true;
    try {
      while (pending.size) {
        const [kind, gesture] = pending.entries().next().value;
        pending.delete(kind);
        if (!relief.viewId) continue;
        try {
          const reply = await tab.call("navigate", { [kind]: gesture });
          ui.camera.textContent = formatCamera(reply.camera);
        } catch (error) {
          failed(error, "navigate");
        }
      }
    } finally {
      navigating = false;
    }
  }

  /** Every gesture: frames go interactive, and back to full quality at rest. */
  function moving() {
    if (!interactive) {
      interactive = true;
      tab.call("update", { interactive: true }).catch((error) => failed(error, "view"));
    }
    clearTimeout(idleTimer);
    idleTimer = setTimeout(rest, INTERACTIVE_IDLE_MS);
  }

  function rest() {
    // Wait for the last gesture's answer: full quality is for where it lands.
    if (navigating || pending.size) {
      idleTimer = setTimeout(rest, 50);
      return;
    }
    interactive = false;
    tab.call("update", { interactive: false }).catch((error) => failed(error, "view"));
  }

  const clamp01 = (value) => Math.min(1, Math.max(0, value));

  /** A pointer position as fractions of the view's displayed size. */
  function fraction(event) {
    const rect = ui.view.getBoundingClientRect();
    return { x: clamp01((event.clientX - rect.left) / rect.width), y: clamp01((event.clientY - rect.top) / rect.height) };
  }

  function orbit(dx, dy) {
    moving();
    queue("orbit", (o = { headingDeg: 0, pitchDeg: 0 }) => ({
      headingDeg: o.headingDeg + dx * ORBIT_DEG_PER_PX,
      pitchDeg: o.pitchDeg - dy * ORBIT_DEG_PER_PX,
    }));
  }

  function pan(from, to) {
    moving();
    queue("pan", (p) => ({ fromX: p ? p.fromX : from.x, fromY: p ? p.fromY : from.y, toX: to.x, toY: to.y }));
  }

  function zoom(factor, at) {
    moving();
    queue("zoom", (z) => ({ factor: Math.min(100, Math.max(0.01, (z ? z.factor : 1) * factor)), x: at.x, y: at.y }));
  }

  function move(step) {
    moving();
    queue("move", (m = { forward: 0, right: 0, up: 0, turnDeg: 0 }) => ({
      forward: m.forward + (step.forward ?? 0),
      right: m.right + (step.right ?? 0),
      up: m.up + (step.up ?? 0),
      turnDeg: m.turnDeg + (step.turnDeg ?? 0),
    }));
  }

  let drag = null; // { mode: "orbit" | "pan", clientX, clientY, pointerId }

  ui.viewport.addEventListener("contextmenu", (event) => event.preventDefault());

  ui.viewport.addEventListener("pointerdown", (event) => {
    ui.viewport.focus({ preventScroll: true });
    if (drag) return;
    let mode = null;
    if (event.button === 0) mode = event.shiftKey ? "pan" : "orbit";
    else if (event.button === 1 || event.button === 2) mode = "pan";
    if (!mode) return;
    event.preventDefault();
    drag = { mode, pointerId: event.pointerId, clientX: event.clientX, clientY: event.clientY };
    ui.viewport.setPointerCapture(event.pointerId);
    ui.viewport.classList.add(mode === "pan" ? "panning" : "dragging");
  });

  ui.viewport.addEventListener("pointermove", (event) => {
    if (drag && event.pointerId === drag.pointerId) {
      const dx = event.clientX - drag.clientX;
      const dy = event.clientY - drag.clientY;
      if (dx === 0 && dy === 0) return;
      if (drag.mode === "orbit") orbit(dx, dy);
      else pan(fraction(drag), fraction(event));
      drag.clientX = event.clientX;
      drag.clientY = event.clientY;
      return;
    }
    pick(tab.call, fraction(event));
  });

  function endDrag(event) {
    if (!drag || event.pointerId !== drag.pointerId) return;
    drag = null;
    ui.viewport.classList.remove("dragging", "panning");
    if (ui.viewport.hasPointerCapture(event.pointerId)) ui.viewport.releasePointerCapture(event.pointerId);
  }
  ui.viewport.addEventListener("pointerup", endDrag);
  ui.viewport.addEventListener("pointercancel", endDrag);
  ui.viewport.addEventListener("pointerleave", pointerLeft);

  ui.viewport.addEventListener(
    "wheel",
    (event) => {
      event.preventDefault();
      // Notches: about 100 pixels, 3 lines or one page each.
      const perNotch = event.deltaMode === 1 ? 3 : event.deltaMode === 2 ? 1 : 100;
      const notches = Math.max(-5, Math.min(5, event.deltaY / perNotch));
      if (notches === 0) return;
      zoom(ZOOM_PER_NOTCH ** -notches, fraction(event));
    },
    { passive: false },
  );

  ui.viewport.addEventListener("dblclick", (event) => {
    event.preventDefault();
    zoom(0.5, fraction(event));
  });

  const KEYS = {
    w: { forward: MOVE_STEP },
    s: { forward: -MOVE_STEP },
    a: { right: -MOVE_STEP },
    d: { right: MOVE_STEP },
    q: { up: MOVE_STEP },
    e: { up: -MOVE_STEP },
    ArrowUp: { forward: MOVE_STEP },
    ArrowDown: { forward: -MOVE_STEP },
    ArrowLeft: { turnDeg: -TURN_STEP_DEG },
    ArrowRight: { turnDeg: TURN_STEP_DEG },
    PageUp: { up: MOVE_STEP },
    PageDown: { up: -MOVE_STEP },
  };

  ui.viewport.addEventListener("keydown", (event) => {
    if (event.ctrlKey || event.metaKey || event.altKey) return;
    if (event.key === "Home" || event.key === "h") {
      event.preventDefault();
      home();
      return;
    }
    const step = KEYS[event.key.length === 1 ? event.key.toLowerCase() : event.key];
    if (!step) return;
    event.preventDefault();
    move(step);
  });

  /** A jump, not a drag: frames stay at full quality; it replaces what still waits. */
  function flyTo(sourceId) {
    pending.clear();
    queue("flyToSource", () => sourceId);
  }

  /** Back to the scene's default view (the manifest's camera). */
  async function home() {
    pending.clear();
    try {
      const reply = await tab.call("home", {});
      ui.camera.textContent = formatCamera(reply.camera);
    } catch (error) {
      failed(error, "home");
    }
  }

  return { flyTo, home, zoom };
}
