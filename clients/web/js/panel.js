// The side panel: the status line and its messages, the error banner, the
// sources, the last change, the effects and passes of the frame shown, and
// the counters.

import { relief } from "./hooks.js";
import { $, ApiError, el, enumName, formatBytes, formatExtent, ms, num, token } from "./util.js";

/** How long a message stays on the status line. */
const MESSAGE_MS = 6000;

const ui = {
  sceneName: $("scene-name"),
  generation: $("generation"),
  conn: $("status").querySelector(".conn"),
  msg: $("status").querySelector(".msg"),
  manifestError: $("manifest-error"),
  banner: $("source-errors"),
  sources: $("sources").tBodies[0],
  flyTo: $("fly-to"),
  lastChange: $("last-change"),
  effects: $("effects"),
  counters: $("counters"),
};

// ------------------------------------------------------------ status line

let connection = "connecting";

/** The connection's state: connecting, open, reconnecting, refused, paused. */
export function setConn(state) {
  connection = state;
  showStatus();
}

/** The status line: the connection, and not green while a source is in error. */
function showStatus() {
  const failing = sourcesInError().length;
  let text = "live";
  let cls = "live";
  if (connection === "refused") {
    text = token ? "refused" : "needs a token";
    cls = "refused";
  } else if (connection === "reconnecting") {
    text = "reconnecting…";
    cls = "reconnecting";
  } else if (connection === "connecting") {
    text = "connecting…";
    cls = "";
  } else if (connection === "paused") {
    text = "paused (hidden)";
    cls = "";
  } else if (failing) {
    text = `live · ${failing} source${failing === 1 ? "" : "s"} in error`;
    cls = "degraded";
  }
  ui.conn.textContent = text;
  ui.conn.className = `conn ${cls}`.trim();
}

let messageTimer = 0;

function message(text, cls) {
  ui.msg.textContent = text;
  ui.msg.className = cls;
  clearTimeout(messageTimer);
  messageTimer = setTimeout(() => {
    ui.msg.textContent = "";
    ui.msg.className = "msg";
  }, MESSAGE_MS);
}

export function say(text) {
  message(text, "msg");
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

/** Shows an error on the status line for a while; never throws. */
export function report(error, context) {
  let text = String(error?.message ?? error ?? "unknown error");
  if (error instanceof ApiError && error.refused) text = refusalText(error);
  const shown = context ? `${context}: ${text}` : text;
  relief.lastError = shown;
  message(shown, "msg error");
  console.warn("relief:", shown);
}

// ------------------------------------------------------------ scene state

export function setGeneration(generation) {
  relief.generation = generation;
  ui.generation.textContent = String(generation);
}

export function showState(state) {
  relief.state = state;
  ui.sceneName.textContent = state.name || "relief";
  document.title = state.name ? `${state.name} – relief` : "relief";
  showManifestError(state.manifestError ?? "");
  showSources(state.sources ?? []);
  showEffects();
  showCounters(state);
}

export function showManifestError(error) {
  ui.manifestError.hidden = !error;
  ui.manifestError.textContent = error ? `manifest: ${error}` : "";
}

const statusOf = (source) => enumName(source.status, "SOURCE_STATUS_");
const baseName = (path) => String(path).split(/[\\/]/).pop();

function sourcesInError() {
  return (relief.state?.sources ?? []).filter((s) => ["ERROR", "FAILED"].includes(statusOf(s)));
}

/** The banner over the panel: each source in error, with its files' names. */
function showBanner() {
  const failing = sourcesInError();
  ui.banner.hidden = failing.length === 0;
  ui.banner.replaceChildren(
    ...failing.map((source) => {
      const files = (source.files ?? []).map(baseName).join(", ");
      const kept = statusOf(source) === "ERROR" ? " (the last good version is shown)" : "";
      return el(
        "p",
        { dataset: { sourceId: source.id ?? "" } },
        el("strong", {}, `${source.id ?? ""}${files ? ` (${files})` : ""}`),
        `: ${source.error ?? "in error"}${kept}`,
      );
    }),
  );
  showStatus();
}

function showSources(sources) {
  const rows = sources.map((source) => {
    const status = statusOf(source);
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
  showBanner();

  // Fly-to buttons, rebuilt only when the list changes so focus stays put.
  const withExtent = sources.filter((source) => source.extent).map((source) => source.id ?? "");
  const key = withExtent.join("\u0000");
  if (ui.flyTo.dataset.key !== key) {
    ui.flyTo.dataset.key = key;
    ui.flyTo.replaceChildren(
      ...withExtent.map((id) => el("button", { type: "button", dataset: { flyTo: id }, title: `Frame the extent of '${id}'` }, `Fly to ${id}`)),
    );
  }
}

/** A source's row and the banner, updated at once from a sourceError event. */
export function markSourceError(event) {
  const id = event.sourceId ?? "";
  const status = (event.keptLastGood ?? false) ? "ERROR" : "FAILED";
  for (const row of ui.sources.rows) {
    if (row.dataset.sourceId !== id) continue;
    const cell = row.querySelector("td.status");
    cell.textContent = status;
    cell.className = `status status-${status.toLowerCase()}`;
    row.querySelector("td.error").textContent = event.error ?? "";
  }
  const source = (relief.state?.sources ?? []).find((s) => (s.id ?? "") === id);
  if (source) {
    source.status = `SOURCE_STATUS_${status}`;
    source.error = event.error ?? "";
    showBanner();
  }
}

/**
 * The effects as the frame shown ran them: an effect with a pass of its own
 * (shadows, water, atmosphere, fog) costs that pass's time in the frame;
 * lighting and detail run inside the terrain pass and are not counted twice.
 */
export function showEffects() {
  const effects = relief.state?.effects ?? [];
  const passes = relief.lastFrame?.passes ?? [];
  const passMs = new Map(passes.map((pass) => [pass.pass ?? "", num(pass.elapsedMs)]));
  const parts = [];
  if (effects.length) {
    parts.push(
      el(
        "table",
        { class: "effects" },
        el("thead", {}, el("tr", {}, el("th", { scope: "col" }, "Effect"), el("th", { scope: "col" }, "Ran"), el("th", { scope: "col", class: "num" }, "In this frame"))),
        el(
          "tbody",
          {},
          effects.map((effect) => {
            const name = effect.name ?? "";
            const inTerrain = name === "lighting" || name === "detail";
            const ran = inTerrain ? (effect.ran ?? false) && passMs.has("terrain") : passMs.has(name);
            const cost = !relief.lastFrame ? "–" : inTerrain ? (ran ? "in terrain" : "–") : ran ? ms(passMs.get(name)) : "–";
            return el(
              "tr",
              { dataset: { effect: name }, title: (effect.sources ?? []).length ? `needs ${effect.sources.join(", ")}` : null },
              el("td", {}, name),
              el("td", { class: ran ? "ran-yes" : "ran-no" }, ran ? "yes" : "no"),
              el("td", { class: "num" }, cost),
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

export function showChange(generation, change) {
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
