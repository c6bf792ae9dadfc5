// relief viewer: one browser tab's view of a reliefd scene.
//
// Plain ES modules, no framework, no build step; everything comes from the
// daemon that served this page. Each tab opens a view of its own (POST
// /api/views) and then holds one connection: a WebSocket that brings the
// view's frames and the scene's events and carries the tab's gestures,
// picks and view updates (js/stream.js). The page never polls.
//
// The modules: js/util.js (token, requests, elements, formats), js/hooks.js
// (`window.relief`, for tests), js/stream.js (the connection), js/panel.js
// (status, banner, sources, change, effects, counters), js/camera.js (mouse
// and keys), js/picking.js (the cursor readout), js/dirty.js (the last
// change outlined on the picture). This file wires them.

import { steer } from "./js/camera.js";
import { showDirty } from "./js/dirty.js";
import { relief } from "./js/hooks.js";
import * as panel from "./js/panel.js";
import { TabSocket } from "./js/stream.js";
import { $, api, apiError, authorized, backoff, el, formatCamera, num, sleep, whyRefused, withToken } from "./js/util.js";

const MAX_STREAM_WIDTH = 1920;
const MAX_STREAM_HEIGHT = 1080;
const MAX_RENDER_SIDE = 4096; // the daemon's limit per side
const MAX_FPS = 30;
const RESIZE_DEBOUNCE_MS = 200;

const ui = {
  view: $("view"),
  frameInfo: $("frame-info"),
  follow: $("follow"),
  screenshot: $("screenshot"),
  home: $("home"),
  toSceneCamera: $("to-scene-camera"),
  reload: $("reload"),
  camera: $("camera"),
  flyTo: $("fly-to"),
  help: $("help"),
  helpButton: $("help-button"),
};

// ------------------------------------------------------------ the connection

let attempt = 0;
let suspended = false; // hidden or left: no connection until shown again
let size = null; // the stream's size
let reconnectTimer = 0;

const tab = new TabSocket({
  onOpen() {
    attempt = 0;
    relief.refused = null;
    relief.connections += 1;
    panel.setConn("open");
  },
  onFrame: showFrame,
  onScene: onSceneEvent,
  onFailed(error) {
    panel.report(error, "frame");
    if (error.notFound) reopenView();
  },
  onClose(opened) {
    if (suspended) return;
    panel.setConn("reconnecting");
    recover(opened);
  },
});

/** The socket closed or was refused: learn why if it never opened, then connect again. */
async function recover(opened) {
  const delay = backoff(attempt++);
  const viewId = relief.viewId;
  const error = opened || !viewId || !size ? null : await whyRefused(withToken(`api/frames?${TabSocket.query(viewId, size, MAX_FPS)}`));
  if (error) {
    panel.report(error, "connection");
    if (error.refused) panel.setConn("refused");
  }
  clearTimeout(reconnectTimer);
  reconnectTimer = setTimeout(() => {
    if (suspended) return;
    if (error?.notFound || !relief.viewId) reopenView();
    else connect();
  }, opened ? 0 : delay);
}

function connect() {
  size = streamSize();
  if (!relief.viewId || !size || suspended) return;
  panel.setConn(relief.connections ? "reconnecting" : "connecting");
  tab.connect(relief.viewId, size, MAX_FPS);
}

/** A call on the socket, for the modules. */
const call = (kind, body) => tab.call(kind, body);

/** Told of an error a call met: the view may be gone. */
function lost(error) {
  if (error?.notFound) reopenView();
}

// ------------------------------------------------------------ page lifecycle

// Hidden or left (the back/forward cache keeps a left page alive): the
// connection closes, so no stream of a page nobody sees holds a place among
// the browser's connections. Shown again: it reopens at once.
function suspend() {
  if (suspended) return;
  suspended = true;
  clearTimeout(reconnectTimer);
  tab.close();
  panel.setConn("paused");
}

function resume() {
  if (!suspended && tab.socket) return;
  suspended = false;
  relief.framesSinceShow = 0;
  if (relief.viewId) connect();
  else openView();
}

window.addEventListener("pagehide", suspend);
window.addEventListener("pageshow", (event) => {
  if (event.persisted || suspended) resume();
});
document.addEventListener("visibilitychange", () => {
  if (document.visibilityState === "hidden") suspend();
  else resume();
});

// ------------------------------------------------------------ the view

let viewOpening = null;

/** Opens this tab's view (again, after the daemon forgot it) and connects. */
function openView() {
  if (viewOpening) return viewOpening;
  viewOpening = (async () => {
    for (let tries = 0; ; tries++) {
      // Keep the place and the mode when reopening.
      const body = {};
      if (ui.follow.checked) body.followSceneCamera = true;
      else if (relief.lastFrame?.camera) body.camera = relief.lastFrame.camera;
      try {
        const view = await api("POST", "api/views", body);
        if (tries > 0 || relief.frames > 0) panel.say("opened a new view");
        relief.viewId = view.viewId ?? null;
        ui.follow.checked = view.followSceneCamera ?? false;
        if (view.camera) ui.camera.textContent = formatCamera(view.camera);
        connect();
        return;
      } catch (error) {
        panel.report(error, "cannot open a view");
        panel.setConn(error.refused ? "refused" : "reconnecting");
        await sleep(backoff(tries));
      }
    }
  })().finally(() => {
    viewOpening = null;
  });
  return viewOpening;
}

function reopenView() {
  tab.close();
  relief.viewId = null;
  if (!suspended) openView();
}

/** The stream size: the view's CSS size in device pixels, within 1920x1080. */
function streamSize() {
  const rect = ui.view.getBoundingClientRect();
  const dpr = window.devicePixelRatio || 1;
  let width = rect.width * dpr;
  let height = rect.height * dpr;
  if (width < 1 || height < 1) return null;
  const scale = Math.min(1, MAX_STREAM_WIDTH / width, MAX_STREAM_HEIGHT / height);
  width = Math.max(1, Math.round(width * scale));
  height = Math.max(1, Math.round(height * scale));
  return { width, height };
}

// ------------------------------------------------------------ scene state

let stateAsking = false;
let stateAgain = false;

/** Asks for the scene state, one request at a time, the last ask always served. */
async function refreshState() {
  if (stateAsking) {
    stateAgain = true;
    return;
  }
  stateAsking = true;
  try {
    const state = tab.open ? (await call("state", {})).state : await api("GET", "api/state");
    // An answer older than what the events already gave is stale.
    if (state && (!relief.state || num(state.generation) >= num(relief.state.generation))) panel.showState(state);
  } catch (error) {
    panel.report(error, "scene state");
  } finally {
    stateAsking = false;
    if (stateAgain) {
      stateAgain = false;
      refreshState();
    }
  }
}

function onSceneEvent(event) {
  const generation = num(event.generation);
  if (event.snapshot) {
    panel.setGeneration(num(event.generation ?? event.snapshot.generation));
    panel.showState(event.snapshot);
  } else if (event.generationChanged) {
    panel.setGeneration(generation);
    panel.showChange(generation, event.generationChanged);
    showDirty(event.generationChanged);
    refreshState();
  } else if (event.sourceError) {
    if (generation) panel.setGeneration(generation);
    panel.markSourceError(event.sourceError);
    refreshState();
  } else if (event.manifestError) {
    if (generation) panel.setGeneration(generation);
    panel.showManifestError(event.manifestError.error ?? "");
    refreshState();
  }
}

// ------------------------------------------------------------ frames

/** The object URL of the frame shown, let go once the next is. */
let frameUrl = null;

function showFrame(frame, image) {
  const entry = { generation: Number(frame.generation ?? 0), received: Date.now(), shown: null };
  relief.frameLog.push(entry);
  if (relief.frameLog.length > 200) relief.frameLog.shift();
  ui.view.addEventListener("load", () => { entry.shown = Date.now(); }, { once: true });
  relief.lastFrame = frame;
  relief.frames += 1;
  relief.framesSinceShow += 1;
  relief.frameBytes = image.byteLength;
  const first = relief.frames === 1;
  if (image.byteLength) {
    if (first) {
      ui.view.addEventListener("load", () => {
        document.body.dataset.ready = "1";
      }, { once: true });
    }
    const type = frame.format === "IMAGE_FORMAT_JPEG" ? "image/jpeg" : "image/png";
    const previous = frameUrl;
    frameUrl = URL.createObjectURL(new Blob([image], { type }));
    ui.view.src = frameUrl;
    if (previous) URL.revokeObjectURL(previous);
  }
  const passes = frame.passes ?? [];
  const total = passes.reduce((sum, pass) => sum + num(pass.elapsedMs), 0);
  ui.frameInfo.textContent = `generation ${num(frame.generation)} · ${num(frame.width)}×${num(frame.height)} · ${total.toFixed(1)} ms`;
  if (frame.camera) ui.camera.textContent = formatCamera(frame.camera);
  ui.screenshot.disabled = false;
  panel.showEffects();
  // The effects declared and whether they ran come with the state: read it
  // once a frame has been rendered for it.
  if (first) refreshState();
}

// ------------------------------------------------------------ controls

const camera = steer({ call, lost });

ui.follow.addEventListener("change", () => {
  const wanted = ui.follow.checked;
  call("update", { followSceneCamera: wanted })
    .then((reply) => {
      ui.follow.checked = reply.view?.followSceneCamera ?? false;
    })
    .catch((error) => {
      ui.follow.checked = !wanted;
      panel.report(error, "follow the scene camera");
    });
});

ui.flyTo.addEventListener("click", (event) => {
  const button = event.target.closest("button[data-fly-to]");
  if (button) camera.flyTo(button.dataset.flyTo);
});

ui.home.addEventListener("click", () => camera.home());

ui.toSceneCamera.addEventListener("click", async () => {
  try {
    const scene = await api("GET", "api/camera");
    await call("update", { camera: scene });
  } catch (error) {
    panel.report(error, "scene camera");
  }
});

ui.reload.addEventListener("click", async () => {
  ui.reload.disabled = true;
  try {
    panel.showState(await api("POST", "api/reload", {}));
    panel.say("reloaded");
  } catch (error) {
    panel.report(error, "reload");
  } finally {
    ui.reload.disabled = false;
  }
});

// The help and its button sit on the viewport: a press on them is no drag.
for (const node of [ui.help, ui.helpButton]) node.addEventListener("pointerdown", (event) => event.stopPropagation());
ui.helpButton.addEventListener("click", () => {
  ui.help.hidden = !ui.help.hidden;
});
ui.help.addEventListener("click", () => {
  ui.help.hidden = true;
});
document.addEventListener("keydown", (event) => {
  if (event.key === "?" && !event.ctrlKey && !event.metaKey) ui.help.hidden = !ui.help.hidden;
  else if (event.key === "Escape") ui.help.hidden = true;
});

ui.screenshot.addEventListener("click", async () => {
  const frame = relief.lastFrame;
  if (!frame?.camera) {
    panel.report("no frame yet", "screenshot");
    return;
  }
  ui.screenshot.disabled = true;
  try {
    const c = frame.camera;
    const rect = ui.view.getBoundingClientRect();
    const dpr = window.devicePixelRatio || 1;
    let width = Math.max(Math.round(rect.width * dpr), num(frame.width));
    let height = Math.max(Math.round(rect.height * dpr), num(frame.height));
    const scale = Math.min(1, MAX_RENDER_SIDE / width, MAX_RENDER_SIDE / height);
    width = Math.max(1, Math.round(width * scale));
    height = Math.max(1, Math.round(height * scale));
    const query = new URLSearchParams({
      camera: [c.lonDeg, c.latDeg, c.altitudeM, c.headingDeg, c.pitchDeg, c.rollDeg].map(num).join(","),
      width: String(width),
      height: String(height),
    });
    if (c.verticalFovDeg) query.set("fov", String(c.verticalFovDeg));
    panel.say(`rendering ${width}×${height}…`);
    const response = await fetch(`api/render?${query}`, { headers: authorized({ accept: "image/png" }) });
    if (!response.ok) throw await apiError(response);
    const url = URL.createObjectURL(await response.blob());
    const scene = (relief.state?.name || "scene").replace(/[^\w.-]+/g, "-");
    const name = `relief-${scene}-${relief.generation}.png`;
    const link = el("a", { href: url, download: name, hidden: true });
    document.body.append(link);
    link.click();
    link.remove();
    setTimeout(() => URL.revokeObjectURL(url), 10000);
    panel.say(`saved ${name}`);
  } catch (error) {
    panel.report(error, "screenshot");
  } finally {
    ui.screenshot.disabled = false;
  }
});

// ------------------------------------------------------------ resizing

let resizeTimer = 0;

function resized() {
  clearTimeout(resizeTimer);
  resizeTimer = setTimeout(() => {
    const now = streamSize();
    if (!now || !relief.viewId || suspended) return;
    if (tab.socket && size && now.width === size.width && now.height === size.height) return;
    connect();
  }, RESIZE_DEBOUNCE_MS);
}

new ResizeObserver(resized).observe(ui.view);
// A change of devicePixelRatio (zoom, another screen) keeps the CSS size.
window.addEventListener("resize", resized);

// ------------------------------------------------------------ start

if (document.visibilityState === "hidden") suspended = true;
else openView();
