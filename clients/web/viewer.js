// relief viewer: one browser tab's view of a reliefd scene.
//
// Plain ES2020, no framework, no build step. Everything comes from the daemon
// that served this page: scene events and frames over Server-Sent Events,
// gestures and picks over small JSON requests. The JSON is the proto3 mapping
// of relief.v1, so fields equal to their default are absent (read them with
// `?? 0`, `?? false`, `?? ""`, `?? []`) and uint64 values are strings.
//
// Each tab opens a view of its own (POST /api/views); the server renders its
// frames and pushes them whenever the generation or the view's camera
// changes. The page never polls.
//
// A reliefd serving with --token-file wants a bearer token on every call but
// serves this page to anyone. The page takes the token from its own address,
// `#token=TOKEN` (never sent to the server) or `?access_token=TOKEN`, and
// sends it as `authorization: Bearer TOKEN` on every fetch and as
// `access_token=TOKEN` in the URLs of its event streams (EventSource cannot
// set headers).

"use strict";

(() => {
  // ------------------------------------------------------------ hooks

  // Kept up to date for tests driving the page (and for the curious, from
  // the console).
  const relief = {
    viewId: null,
    generation: 0, // from the event stream
    frames: 0, // frames shown
    lastFrame: null, // the last RenderResponse (its image came beside it)
    frameBytes: 0, // the last frame image's size on the wire
    state: null, // the last SceneState
    lastError: null, // the last error shown, as text
    refused: null, // the HTTP status (401, 403) of the last refusal, if any
    // The last 200 frames: generation, and wall-clock ms when the frame
    // arrived and when its image was decoded and shown (benchmarks).
    frameLog: [],
  };
  window.relief = relief;

  // ------------------------------------------------------------ constants

  const MAX_STREAM_WIDTH = 1920;
  const MAX_STREAM_HEIGHT = 1080;
  const MAX_RENDER_SIDE = 4096; // the daemon's limit per side
  const MAX_FPS = 30;
  const ORBIT_DEG_PER_PX = 0.3;
  const ZOOM_PER_NOTCH = 0.85;
  const MOVE_STEP = 0.1; // of the camera's height above the ground
  const TURN_STEP_DEG = 5;
  const INTERACTIVE_IDLE_MS = 250;
  const RESIZE_DEBOUNCE_MS = 200;
  const RETRY_MIN_MS = 1000;
  const RETRY_MAX_MS = 15000;

  // ------------------------------------------------------------ the token

  /** The bearer token from the page's address: `#token=` or `?access_token=`. */
  const token = (param(location.hash.replace(/^#/, ""), "token") || param(location.search.replace(/^\?/, ""), "access_token")).trim();

  // The token leaves the address at once: it is not kept in the history,
  // shown over a shoulder, or copied with the link.
  if (token) {
    const without = (text, name) => text.split("&").filter((pair) => pair && !pair.startsWith(`${name}=`)).join("&");
    const search = without(location.search.replace(/^\?/, ""), "access_token");
    const hash = without(location.hash.replace(/^#/, ""), "token");
    history.replaceState(history.state, "", `${location.pathname}${search ? `?${search}` : ""}${hash ? `#${hash}` : ""}`);
  }

  /** A parameter of `a=1&b=2`, percent-decoded; "+" stays "+" (tokens hold it). */
  function param(text, name) {
    for (const pair of text.split("&")) {
      const at = pair.indexOf("=");
      if (at < 0 || pair.slice(0, at) !== name) continue;
      try {
        return decodeURIComponent(pair.slice(at + 1));
      } catch {
        return pair.slice(at + 1);
      }
    }
    return "";
  }

  /** `headers` with the token's authorization header, when there is a token. */
  function authorized(headers) {
    if (token) headers.authorization = `Bearer ${token}`;
    return headers;
  }

  /** `url` with the token as its `access_token` parameter, for EventSource. */
  function withToken(url) {
    if (!token) return url;
    // reliefd compares the parameter as sent: escape only what would end it.
    const value = token.replace(/[%&#\s]/g, (c) => encodeURIComponent(c));
    return `${url}${url.includes("?") ? "&" : "?"}access_token=${value}`;
  }

  // ------------------------------------------------------------ elements

  const $ = (id) => document.getElementById(id);
  const ui = {
    viewport: $("viewport"),
    view: $("view"),
    frameInfo: $("frame-info"),
    sceneName: $("scene-name"),
    generation: $("generation"),
    status: $("status"),
    conn: $("status").querySelector(".conn"),
    msg: $("status").querySelector(".msg"),
    manifestError: $("manifest-error"),
    follow: $("follow"),
    screenshot: $("screenshot"),
    toSceneCamera: $("to-scene-camera"),
    reload: $("reload"),
    camera: $("camera"),
    cursor: $("cursor"),
    sources: $("sources").tBodies[0],
    flyTo: $("fly-to"),
    lastChange: $("last-change"),
    effects: $("effects"),
    counters: $("counters"),
  };

  /** Builds an element: el("td", { class: "num" }, "12", child...). */
  function el(tag, attrs, ...children) {
    const node = document.createElement(tag);
    for (const [key, value] of Object.entries(attrs ?? {})) {
      if (value === undefined || value === null || value === false) continue;
      if (key === "class") node.className = value;
      else if (key === "dataset") Object.assign(node.dataset, value);
      else node.setAttribute(key, value === true ? "" : String(value));
    }
    for (const child of children.flat(Infinity)) {
      if (child === undefined || child === null) continue;
      node.append(child instanceof Node ? child : String(child));
    }
    return node;
  }

  // ------------------------------------------------------------ formatting

  const num = (value) => Number(value ?? 0);
  const fixed = (value, digits) => num(value).toFixed(digits);
  const ms = (value) => `${fixed(value, 1)} ms`;
  const enumName = (value, prefix) => String(value ?? `${prefix}UNSPECIFIED`).replace(prefix, "");

  function formatCamera(camera) {
    if (!camera) return "–";
    return (
      `${fixed(camera.lonDeg, 6)}, ${fixed(camera.latDeg, 6)}, ${fixed(camera.altitudeM, 0)} m` +
      ` · heading ${fixed(camera.headingDeg, 1)}° pitch ${fixed(camera.pitchDeg, 1)}°`
    );
  }

  /** Decimals that show an extent to about a thousandth of its size. */
  function extentDigits(extent) {
    const span = Math.max(num(extent.maxX) - num(extent.minX), num(extent.maxY) - num(extent.minY));
    if (!(span > 0) || !Number.isFinite(span)) return 3;
    return Math.min(7, Math.max(0, Math.ceil(-Math.log10(span)) + 3));
  }

  function formatExtent(extent) {
    const d = extentDigits(extent);
    return `${fixed(extent.minX, d)},${fixed(extent.minY, d)} – ${fixed(extent.maxX, d)},${fixed(extent.maxY, d)}`;
  }

  function formatBytes(bytes) {
    const n = num(bytes);
    if (n >= 1 << 30) return `${(n / (1 << 30)).toFixed(1)} GiB`;
    if (n >= 1 << 20) return `${(n / (1 << 20)).toFixed(1)} MiB`;
    if (n >= 1 << 10) return `${(n / (1 << 10)).toFixed(1)} KiB`;
    return `${n} B`;
  }

  // ------------------------------------------------------------ status line

  // The status line is the connection state, then the last message.
  const conn = { events: "connecting", frames: "connecting" };

  function setConn(stream, state) {
    conn[stream] = state;
    const states = Object.values(conn);
    let text = "live";
    let cls = "live";
    if (states.includes("refused")) {
      text = token ? "refused" : "needs a token";
      cls = "refused";
    } else if (states.includes("reconnecting")) {
      text = "reconnecting…";
      cls = "reconnecting";
    } else if (states.includes("connecting")) {
      text = "connecting…";
      cls = "";
    }
    ui.conn.textContent = text;
    ui.conn.className = `conn ${cls}`.trim();
  }

  function say(text) {
    ui.msg.textContent = text;
    ui.msg.className = "msg";
  }

  /** What a refusal (HTTP 401 or 403) means for this page, in words. */
  function refusalText(error) {
    if (error.status === 401 || error.code === "UNAUTHENTICATED") {
      relief.refused = 401;
      return token
        ? `reliefd does not accept this page's token (${error.message}); open the page as /#token=TOKEN with a token of its token file`
        : `this reliefd wants a token (${error.message}); open the page as /#token=TOKEN`;
    }
    relief.refused = 403;
    return `this page's token may not do that: ${error.message}`;
  }

  /** Shows an error on the status line; never throws. */
  function report(error, context) {
    let text = String(error?.message ?? error ?? "unknown error");
    if (error instanceof ApiError && error.refused) text = refusalText(error);
    const message = context ? `${context}: ${text}` : text;
    relief.lastError = message;
    ui.msg.textContent = message;
    ui.msg.className = "msg error";
    console.warn("relief:", message);
  }

  // ------------------------------------------------------------ requests

  class ApiError extends Error {
    constructor(code, message, status = 0) {
      super(message);
      this.code = code;
      this.status = status;
    }

    get notFound() {
      return this.code === "NOT_FOUND" || this.status === 404;
    }

    /** reliefd refused the token (401: none or unknown; 403: it may only read). */
    get refused() {
      return this.status === 401 || this.status === 403 || this.code === "UNAUTHENTICATED" || this.code === "PERMISSION_DENIED";
    }
  }

  /** Reads an error answer ({code, message}) into an ApiError. */
  async function apiError(response) {
    const text = await response.text().catch(() => "");
    try {
      const body = JSON.parse(text);
      return new ApiError(body.code ?? `HTTP ${response.status}`, body.message ?? text, response.status);
    } catch {
      const message = text.trim() || `${response.status} ${response.statusText}`.trim();
      return new ApiError(`HTTP ${response.status}`, message, response.status);
    }
  }

  /** A JSON request to reliefd; rejects with an ApiError. */
  async function api(method, path, body) {
    const init = { method, headers: authorized({ accept: "application/json" }) };
    // reliefd takes bodies as JSON only (a page of another site cannot send
    // that without its leave): a call without one sends {}.
    if (method !== "GET") {
      init.headers["content-type"] = "application/json";
      init.body = JSON.stringify(body ?? {});
    }
    let response;
    try {
      response = await fetch(path, init);
    } catch (error) {
      throw new ApiError("UNAVAILABLE", `cannot reach reliefd (${error.message})`);
    }
    if (!response.ok) throw await apiError(response);
    const text = await response.text();
    return text ? JSON.parse(text) : {};
  }

  const viewPath = (suffix = "") => `api/views/${encodeURIComponent(relief.viewId)}${suffix}`;

  const sleep = (millis) => new Promise((resolve) => setTimeout(resolve, millis));
  const backoff = (attempt) => Math.min(RETRY_MAX_MS, RETRY_MIN_MS * 2 ** Math.min(attempt, 4));

  // ------------------------------------------------------------ scene state

  let stateFetch = null; // the request in flight
  let stateAgain = false; // another was asked for meanwhile

  /** Refetches /api/state, one request at a time, the last ask always served. */
  function refreshState() {
    if (stateFetch) {
      stateAgain = true;
      return;
    }
    stateFetch = api("GET", "api/state")
      .then((state) => {
        // An answer older than what the event stream already gave is stale.
        if (!relief.state || num(state.generation) >= num(relief.state.generation)) showState(state);
      })
      .catch((error) => report(error, "scene state"))
      .finally(() => {
        stateFetch = null;
        if (stateAgain) {
          stateAgain = false;
          refreshState();
        }
      });
  }

  function showState(state) {
    relief.state = state;
    ui.sceneName.textContent = state.name || "relief";
    document.title = state.name ? `${state.name} – relief` : "relief";
    const manifestError = state.manifestError ?? "";
    ui.manifestError.hidden = !manifestError;
    ui.manifestError.textContent = manifestError ? `manifest: ${manifestError}` : "";
    showSources(state.sources ?? []);
    showEffects();
    showCounters(state);
  }

  function showSources(sources) {
    const rows = sources.map((source) => {
      const status = enumName(source.status, "SOURCE_STATUS_");
      const files = (source.files ?? []).join("\n");
      return el(
        "tr",
        { dataset: { sourceId: source.id ?? "" }, class: (source.active ?? false) ? null : "inactive", title: files || null },
        el("td", {}, source.id ?? ""),
        el("td", {}, source.kind ?? ""),
        el("td", { class: `status status-${status === "UNSPECIFIED" ? "unknown" : status.toLowerCase()}` }, status),
        el("td", { class: "error" }, source.error ?? ""),
      );
    });
    ui.sources.replaceChildren(...rows);

    // Fly-to buttons, rebuilt only when the list changes so focus stays put.
    const withExtent = sources.filter((source) => source.extent).map((source) => source.id ?? "");
    const key = withExtent.join("\u0000");
    if (ui.flyTo.dataset.key !== key) {
      ui.flyTo.dataset.key = key;
      ui.flyTo.replaceChildren(
        ...withExtent.map((id) =>
          el("button", { type: "button", dataset: { flyTo: id }, title: `Frame the extent of '${id}'` }, `Fly to ${id}`),
        ),
      );
    }
  }

  /** A source's row, updated at once from a sourceError event. */
  function markSourceError(event) {
    const id = event.sourceId ?? "";
    for (const row of ui.sources.rows) {
      if (row.dataset.sourceId !== id) continue;
      const status = (event.keptLastGood ?? false) ? "ERROR" : "FAILED";
      const cell = row.querySelector("td.status");
      cell.textContent = status;
      cell.className = `status status-${status.toLowerCase()}`;
      row.querySelector("td.error").textContent = event.error ?? "";
    }
  }

  function showEffects() {
    const effects = relief.state?.effects ?? [];
    const passes = relief.lastFrame?.passes ?? [];
    const parts = [];
    if (effects.length) {
      parts.push(
        el(
          "table",
          { class: "effects" },
          el("thead", {}, el("tr", {}, el("th", { scope: "col" }, "Effect"), el("th", { scope: "col" }, "Ran"), el("th", { scope: "col", class: "num" }, "Last cost"))),
          el(
            "tbody",
            {},
            effects.map((effect) => {
              const ran = effect.ran ?? false;
              return el(
                "tr",
                { dataset: { effect: effect.name ?? "" }, title: (effect.sources ?? []).length ? `needs ${effect.sources.join(", ")}` : null },
                el("td", {}, effect.name ?? ""),
                el("td", { class: ran ? "ran-yes" : "ran-no" }, ran ? "yes" : "no"),
                el("td", { class: "num" }, ms(effect.lastCostMs)),
              );
            }),
          ),
        ),
      );
    } else {
      parts.push(el("p", { class: "muted" }, "no effects declared"));
    }
    if (passes.length) {
      const total = passes.reduce((sum, pass) => sum + num(pass.elapsedMs), 0);
      parts.push(
        el(
          "table",
          { class: "passes" },
          el("thead", {}, el("tr", {}, el("th", { scope: "col" }, "Last frame's passes"), el("th", { scope: "col", class: "num" }, "Time"))),
          el(
            "tbody",
            {},
            passes.map((pass) => el("tr", {}, el("td", {}, pass.pass ?? ""), el("td", { class: "num" }, ms(pass.elapsedMs)))),
            el("tr", { class: "total" }, el("th", { scope: "row" }, "total"), el("td", { class: "num" }, ms(total))),
          ),
        ),
      );
    }
    ui.effects.replaceChildren(...parts);
  }

  function showCounters(state) {
    const c = state.counters ?? {};
    const rows = [
      ["Tiles generated", num(c.tilesGenerated)],
      ["Cache", `${num(c.cacheEntries)} tiles, ${formatBytes(c.cacheBytes)} of ${formatBytes(c.cacheBudgetBytes)}`],
      ["Cache hits / misses", `${num(c.cacheHits)} / ${num(c.cacheMisses)}`],
      ["Frames rendered", num(c.framesRendered)],
      ["Reads retried", num(c.readsRetried)],
    ];
    const grid = state.grid ?? {};
    rows.push(["Grid", `${grid.kind ?? ""} ${grid.crs ?? ""}, tile ${num(grid.tileSize)}`.trim()]);
    for (const [name, id] of Object.entries(state.layers ?? {}).sort()) rows.push([`Layer ${name}`, id]);
    for (const [name, value] of Object.entries(state.quality ?? {}).sort()) rows.push([name, value]);
    if (state.manifest) rows.push(["Manifest", state.manifest]);
    ui.counters.replaceChildren(el("dl", {}, rows.map(([name, value]) => [el("dt", {}, name), el("dd", {}, value)])));
  }

  function showChange(generation, change) {
    const changed = change.changedSources ?? [];
    const dirty = [];
    for (const region of change.dirty ?? []) {
      const extents = region.extents ?? [];
      const shown = extents.slice(0, 6).map(formatExtent);
      if (extents.length > shown.length) shown.push(`… ${extents.length - shown.length} more`);
      dirty.push(el("div", {}, el("span", { class: "muted" }, `${region.sourceId ?? ""}: `), shown.join("; ") || "whole source"));
    }
    const tiles = [`${num(change.tilesRebuilt)} rebuilt`];
    if (num(change.tilesInvalidated)) tiles.push(`${num(change.tilesInvalidated)} dropped`);
    if (num(change.tilesCarriedOver)) tiles.push(`${num(change.tilesCarriedOver)} kept`);
    if (num(change.tilesCutOff)) tiles.push(`${num(change.tilesCutOff)} cut off`);
    const rows = [
      ["Generation", generation],
      ["Changed", changed.join(", ") || "–"],
      ["Dirty", dirty.length ? dirty : "–"],
      ["Tiles", tiles.join(", ")],
      ["Elapsed", ms(change.elapsedMs)],
    ];
    if (change.reason) rows.push(["Reason", change.reason]);
    ui.lastChange.replaceChildren(el("dl", {}, rows.map(([name, value]) => [el("dt", {}, name), el("dd", {}, value)])));
  }

  function setGeneration(generation) {
    relief.generation = generation;
    ui.generation.textContent = String(generation);
  }

  // ------------------------------------------------------------ scene events

  let events = null;
  let eventsAttempt = 0;

  function openEvents() {
    events?.close();
    setConn("events", "connecting");
    // from=0 on every (re)connection: the stream starts with a snapshot.
    const url = withToken("api/events?from=0");
    const source = new EventSource(url);
    events = source;
    source.addEventListener("open", () => {
      eventsAttempt = 0;
      relief.refused = null;
      setConn("events", "open");
    });
    source.addEventListener("scene", (message) => {
      let event;
      try {
        event = JSON.parse(message.data);
      } catch (error) {
        report(error, "scene event");
        return;
      }
      onSceneEvent(event);
    });
    source.addEventListener("error", (message) => {
      if (source !== events) return;
      if (message.data) {
        // An `event: error` the server sent: {code, message}.
        report(parseStreamError(message.data), "scene events");
      } else if (source.readyState === EventSource.CLOSED) {
        // Refused (not a dropped connection): EventSource gives up, we do not.
        eventsRefused(source, url);
      } else {
        setConn("events", "reconnecting");
      }
    });
  }

  /** The events stream was refused: ask again to learn why, then retry. */
  async function eventsRefused(source, url) {
    setConn("events", "reconnecting");
    const delay = backoff(eventsAttempt++);
    const error = await whyRefused(url);
    if (source !== events) return;
    if (error) {
      report(error, "scene events");
      if (error.refused) setConn("events", "refused");
    }
    await sleep(delay);
    if (source === events) openEvents();
  }

  /** Why reliefd refused a stream's URL (an ApiError), or null when it
   * cannot be reached now or serves it after all. */
  async function whyRefused(url) {
    const abort = new AbortController();
    try {
      const response = await fetch(url, { signal: abort.signal, headers: authorized({ accept: "text/event-stream" }) });
      return response.ok ? null : await apiError(response);
    } catch {
      return null; // Unreachable now: try again after the delay, as EventSource would.
    } finally {
      abort.abort();
    }
  }

  function parseStreamError(data) {
    try {
      const body = JSON.parse(data);
      return new ApiError(body.code ?? "UNKNOWN", body.message ?? data);
    } catch {
      return new ApiError("UNKNOWN", data);
    }
  }

  function onSceneEvent(event) {
    const generation = num(event.generation);
    if (event.snapshot) {
      setGeneration(num(event.generation ?? event.snapshot.generation));
      showState(event.snapshot);
    } else if (event.generationChanged) {
      setGeneration(generation);
      showChange(generation, event.generationChanged);
      refreshState();
    } else if (event.sourceError) {
      if (generation) setGeneration(generation);
      markSourceError(event.sourceError);
      refreshState();
    } else if (event.manifestError) {
      if (generation) setGeneration(generation);
      const error = event.manifestError.error ?? "";
      ui.manifestError.hidden = !error;
      ui.manifestError.textContent = error ? `manifest: ${error}` : "";
      refreshState();
    }
  }

  // ------------------------------------------------------------ the view

  let viewOpening = null;

  /** Opens this tab's view (again, after the daemon forgot it) and its frames. */
  function openView() {
    if (viewOpening) return viewOpening;
    viewOpening = (async () => {
      for (let attempt = 0; ; attempt++) {
        // Keep the place and the mode when reopening.
        const body = {};
        if (ui.follow.checked) body.followSceneCamera = true;
        else if (relief.lastFrame?.camera) body.camera = relief.lastFrame.camera;
        try {
          const view = await api("POST", "api/views", body);
          if (attempt > 0 || relief.frames > 0) say("opened a new view");
          relief.viewId = view.viewId ?? null;
          ui.follow.checked = view.followSceneCamera ?? false;
          if (view.camera) ui.camera.textContent = formatCamera(view.camera);
          interactive = false;
          openFrames();
          return;
        } catch (error) {
          report(error, "cannot open a view");
          setConn("frames", error.refused ? "refused" : "reconnecting");
          await sleep(backoff(attempt));
        }
      }
    })().finally(() => {
      viewOpening = null;
    });
    return viewOpening;
  }

  /** Chained view updates, so they reach the daemon in the order made. */
  let viewUpdates = Promise.resolve();

  function updateView(body) {
    const sent = viewUpdates.then(async () => {
      if (!relief.viewId) return null;
      return api("PATCH", viewPath(), body);
    });
    viewUpdates = sent.catch(() => null);
    return sent;
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

  // ------------------------------------------------------------ frames

  let frames = null;
  let framesSize = null;
  let framesAttempt = 0;

  function framesQuery(size) {
    return new URLSearchParams({
      view: relief.viewId,
      width: String(size.width),
      height: String(size.height),
      max_fps: String(MAX_FPS),
    });
  }

  /** The frames WebSocket's URL: binary frames, JPEG while dragging, PNG at rest. */
  function framesUrl(size) {
    const url = new URL(withToken(`api/frames/ws?${framesQuery(size)}`), location.href);
    url.protocol = url.protocol === "https:" ? "wss:" : "ws:";
    return url.toString();
  }

  /**
   * A binary frame message: u32 (little-endian) header length, the header
   * `{"frame": RenderResponse}` as JSON, then the image's bytes.
   */
  function decodeFrame(buffer) {
    if (buffer.byteLength < 4) return null;
    const length = new DataView(buffer).getUint32(0, true);
    if (4 + length > buffer.byteLength) return null;
    const header = JSON.parse(new TextDecoder().decode(new Uint8Array(buffer, 4, length)));
    if (!header.frame) return null;
    return { frame: header.frame, image: new Uint8Array(buffer, 4 + length) };
  }

  function openFrames() {
    frames?.close();
    frames = null;
    const size = streamSize();
    if (!relief.viewId || !size) return;
    framesSize = size;
    setConn("frames", "connecting");
    const socket = new WebSocket(framesUrl(size));
    socket.binaryType = "arraybuffer";
    frames = socket;
    let opened = false;
    socket.addEventListener("open", () => {
      opened = true;
      framesAttempt = 0;
      relief.refused = null;
      setConn("frames", "open");
    });
    socket.addEventListener("message", (message) => {
      if (socket !== frames) return;
      if (typeof message.data === "string") {
        // {"error": {code, message}}: the view failed; the socket closes.
        let body;
        try {
          body = JSON.stringify(JSON.parse(message.data).error ?? {});
        } catch {
          body = message.data;
        }
        const error = parseStreamError(body);
        report(error, "frame");
        if (error.notFound) reopenView(socket);
        return;
      }
      let decoded;
      try {
        decoded = decodeFrame(message.data);
      } catch (error) {
        report(error, "frame");
        return;
      }
      if (decoded) showFrame(decoded.frame, decoded.image);
    });
    socket.addEventListener("close", () => {
      if (socket !== frames) return;
      // Refused at the upgrade: the same stream over HTTP says why.
      framesRefused(socket, withToken(`api/frames?${framesQuery(size)}`), opened);
    });
  }

  /** The stream closed or was refused: learn why if it never opened, then recover. */
  async function framesRefused(source, url, opened) {
    setConn("frames", "reconnecting");
    const delay = backoff(framesAttempt++);
    const error = opened ? null : await whyRefused(url);
    if (source !== frames) return;
    if (error) {
      report(error, "frames");
      if (error.refused) setConn("frames", "refused");
    }
    await sleep(delay);
    if (source !== frames) return;
    if (error?.notFound) reopenView(source);
    else openFrames();
  }

  function reopenView(source) {
    if (source !== frames) return;
    frames?.close();
    frames = null;
    relief.viewId = null;
    openView();
  }

  /** The object URL of the frame shown, let go once the next is. */
  let frameUrl = null;

  function showFrame(frame, image) {
    const entry = { generation: Number(frame.generation ?? 0), received: Date.now(), shown: null };
    relief.frameLog.push(entry);
    if (relief.frameLog.length > 200) relief.frameLog.shift();
    ui.view.addEventListener("load", () => { entry.shown = Date.now(); }, { once: true });
    relief.lastFrame = frame;
    relief.frames += 1;
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
    showEffects();
    // The effects' "ran" and cost come with the state: read it once a frame
    // has been rendered for it.
    if (first) refreshState();
  }

  // ------------------------------------------------------------ navigation

  // Gestures waiting to be sent, by kind, in the order they started; at most
  // one navigate request is in flight and the rest accumulate meanwhile.
  const pending = new Map();
  let navigating = false;

  function queueGesture(kind, merge) {
    pending.set(kind, merge(pending.get(kind)));
    pump();
  }

  async function pump() {
    if (navigating || pending.size === 0) return;
    navigating = true;
    try {
      while (pending.size) {
        // Sent after the view update that made it interactive.
        await viewUpdates;
        const [kind, gesture] = pending.entries().next().value;
        pending.delete(kind);
        if (!relief.viewId) continue;
        try {
          const camera = await api("POST", viewPath("/navigate"), { [kind]: gesture });
          ui.camera.textContent = formatCamera(camera);
        } catch (error) {
          report(error, "navigate");
          if (error.notFound) reopenView(frames);
        }
      }
    } finally {
      navigating = false;
    }
  }

  let interactive = false;
  let idleTimer = 0;

  /** Every gesture: frames go interactive, and back to full quality at rest. */
  function gesture() {
    if (!interactive) {
      interactive = true;
      updateView({ interactive: true }).catch((error) => {
        report(error, "view");
        if (error.notFound) reopenView(frames);
      });
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
    updateView({ interactive: false }).catch((error) => report(error, "view"));
  }

  const clamp01 = (value) => Math.min(1, Math.max(0, value));

  /** A pointer position as fractions of the view's displayed size. */
  function fraction(event) {
    const rect = ui.view.getBoundingClientRect();
    return {
      x: clamp01((event.clientX - rect.left) / rect.width),
      y: clamp01((event.clientY - rect.top) / rect.height),
    };
  }

  function orbit(dx, dy) {
    gesture();
    queueGesture("orbit", (o = { headingDeg: 0, pitchDeg: 0 }) => ({
      headingDeg: o.headingDeg + dx * ORBIT_DEG_PER_PX,
      pitchDeg: o.pitchDeg - dy * ORBIT_DEG_PER_PX,
    }));
  }

  function pan(from, to) {
    gesture();
    queueGesture("pan", (p) => ({
      fromX: p ? p.fromX : from.x,
      fromY: p ? p.fromY : from.y,
      toX: to.x,
      toY: to.y,
    }));
  }

  function zoom(factor, at) {
    gesture();
    queueGesture("zoom", (z) => ({ factor: (z ? z.factor : 1) * factor, x: at.x, y: at.y }));
  }

  function move(step) {
    gesture();
    queueGesture("move", (m = { forward: 0, right: 0, up: 0, turnDeg: 0 }) => ({
      forward: m.forward + (step.forward ?? 0),
      right: m.right + (step.right ?? 0),
      up: m.up + (step.up ?? 0),
      turnDeg: m.turnDeg + (step.turnDeg ?? 0),
    }));
  }

  function flyTo(sourceId) {
    // A jump, not a drag: frames stay at full quality. It replaces whatever
    // was still waiting to be sent.
    pending.clear();
    queueGesture("flyToSource", () => sourceId);
  }

  // ------------------------------------------------------------ mouse and keys

  let drag = null; // { mode: "orbit" | "pan", last: {clientX, clientY}, pointerId }

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
    pick(fraction(event));
  });

  function endDrag(event) {
    if (!drag || event.pointerId !== drag.pointerId) return;
    drag = null;
    ui.viewport.classList.remove("dragging", "panning");
    if (ui.viewport.hasPointerCapture(event.pointerId)) ui.viewport.releasePointerCapture(event.pointerId);
  }
  ui.viewport.addEventListener("pointerup", endDrag);
  ui.viewport.addEventListener("pointercancel", endDrag);

  ui.viewport.addEventListener("pointerenter", () => {
    pointerInside = true;
  });
  ui.viewport.addEventListener("pointerleave", () => {
    pointerInside = false;
    pickWanted = null;
    ui.cursor.textContent = "–";
  });

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
    const step = KEYS[event.key.length === 1 ? event.key.toLowerCase() : event.key];
    if (!step) return;
    event.preventDefault();
    move(step);
  });

  // ------------------------------------------------------------ cursor readout

  let picking = false;
  let pickWanted = null; // the latest position not yet asked about
  let pointerInside = false;

  function pick(at) {
    pointerInside = true;
    pickWanted = at;
    if (!picking) pickNext();
  }

  async function pickNext() {
    picking = true;
    try {
      while (pickWanted && relief.viewId && relief.lastFrame) {
        const at = pickWanted;
        pickWanted = null;
        try {
          const hit = await api("GET", `${viewPath("/pick")}?x=${at.x.toFixed(5)}&y=${at.y.toFixed(5)}`);
          // A newer position is asked about next; one outside shows nothing.
          if (pickWanted === null && pointerInside) showPick(hit);
        } catch (error) {
          ui.cursor.textContent = "–";
          report(error, "pick");
        }
      }
    } finally {
      picking = false;
    }
  }

  function showPick(hit) {
    if (!(hit.hit ?? false)) {
      ui.cursor.textContent = "sky";
      return;
    }
    const ground = hit.groundHeightM === undefined || hit.groundHeightM === null ? "nodata" : `${fixed(hit.groundHeightM, 1)} m`;
    ui.cursor.textContent = `${fixed(hit.lonDeg, 6)}, ${fixed(hit.latDeg, 6)} · ${ground}`;
  }

  // ------------------------------------------------------------ panel controls

  ui.follow.addEventListener("change", () => {
    const wanted = ui.follow.checked;
    updateView({ followSceneCamera: wanted })
      .then((view) => {
        if (view) ui.follow.checked = view.followSceneCamera ?? false;
      })
      .catch((error) => {
        ui.follow.checked = !wanted;
        report(error, "follow the scene camera");
      });
  });

  ui.flyTo.addEventListener("click", (event) => {
    const button = event.target.closest("button[data-fly-to]");
    if (button) flyTo(button.dataset.flyTo);
  });

  ui.toSceneCamera.addEventListener("click", async () => {
    try {
      const camera = await api("GET", "api/camera");
      await updateView({ camera });
    } catch (error) {
      report(error, "scene camera");
    }
  });

  ui.reload.addEventListener("click", async () => {
    ui.reload.disabled = true;
    try {
      const state = await api("POST", "api/reload", {});
      showState(state);
      say("reloaded");
    } catch (error) {
      report(error, "reload");
    } finally {
      ui.reload.disabled = false;
    }
  });

  ui.screenshot.addEventListener("click", async () => {
    const frame = relief.lastFrame;
    if (!frame?.camera) {
      report("no frame yet", "screenshot");
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
      say(`rendering ${width}×${height}…`);
      const response = await fetch(`api/render?${query}`, { headers: authorized({ accept: "image/png" }) });
      if (!response.ok) throw await apiError(response);
      const blob = await response.blob();
      const url = URL.createObjectURL(blob);
      const scene = (relief.state?.name || "scene").replace(/[^\w.-]+/g, "-");
      const name = `relief-${scene}-${relief.generation}.png`;
      const link = el("a", { href: url, download: name, hidden: true });
      document.body.append(link);
      link.click();
      link.remove();
      setTimeout(() => URL.revokeObjectURL(url), 10000);
      say(`saved ${name}`);
    } catch (error) {
      report(error, "screenshot");
    } finally {
      ui.screenshot.disabled = false;
    }
  });

  // ------------------------------------------------------------ resizing

  let resizeTimer = 0;

  function resized() {
    clearTimeout(resizeTimer);
    resizeTimer = setTimeout(() => {
      const size = streamSize();
      if (!size || !relief.viewId) return;
      if (frames && framesSize && size.width === framesSize.width && size.height === framesSize.height) return;
      openFrames();
    }, RESIZE_DEBOUNCE_MS);
  }

  new ResizeObserver(resized).observe(ui.view);
  // A change of devicePixelRatio (zoom, another screen) keeps the CSS size.
  window.addEventListener("resize", resized);

  // ------------------------------------------------------------ start

  openEvents();
  openView();
})();
