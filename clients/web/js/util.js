// Small helpers every module shares: the token, JSON requests to reliefd,
// elements and number formats. The JSON is the proto3 mapping of relief.v1,
// so fields equal to their default are absent (read them with `?? 0`,
// `?? false`, `?? ""`, `?? []`) and uint64 values are strings.
//
// A reliefd serving with --token-file wants a bearer token on every call but
// serves this page to anyone. The page takes the token from its own address,
// `#token=TOKEN` (never sent to the server) or `?access_token=TOKEN`, and
// sends it as `authorization: Bearer TOKEN` on every fetch and as
// `access_token=TOKEN` in the URL of its WebSocket (which cannot set headers).

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

/** The bearer token from the page's address: `#token=` or `?access_token=`. */
export const token = (param(location.hash.replace(/^#/, ""), "token") || param(location.search.replace(/^\?/, ""), "access_token")).trim();

// The token leaves the address at once: it is not kept in the history,
// shown over a shoulder, or copied with the link.
if (token) {
  const without = (text, name) => text.split("&").filter((pair) => pair && !pair.startsWith(`${name}=`)).join("&");
  const search = without(location.search.replace(/^\?/, ""), "access_token");
  const hash = without(location.hash.replace(/^#/, ""), "token");
  history.replaceState(history.state, "", `${location.pathname}${search ? `?${search}` : ""}${hash ? `#${hash}` : ""}`);
}

/** `headers` with the token's authorization header, when there is a token. */
export function authorized(headers) {
  if (token) headers.authorization = `Bearer ${token}`;
  return headers;
}

/** `url` with the token as its `access_token` parameter (WebSocket, EventSource). */
export function withToken(url) {
  if (!token) return url;
  // reliefd compares the parameter as sent: escape only what would end it.
  const value = token.replace(/[%&#\s]/g, (c) => encodeURIComponent(c));
  return `${url}${url.includes("?") ? "&" : "?"}access_token=${value}`;
}

// ------------------------------------------------------------ elements

export const $ = (id) => document.getElementById(id);

/** Builds an element: el("td", { class: "num" }, "12", child...). */
export function el(tag, attrs, ...children) {
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

export const num = (value) => Number(value ?? 0);
export const fixed = (value, digits) => num(value).toFixed(digits);
export const ms = (value) => `${fixed(value, 1)} ms`;
export const enumName = (value, prefix) => String(value ?? `${prefix}UNSPECIFIED`).replace(prefix, "");

export function formatCamera(camera) {
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

export function formatExtent(extent) {
  const d = extentDigits(extent);
  return `${fixed(extent.minX, d)},${fixed(extent.minY, d)} – ${fixed(extent.maxX, d)},${fixed(extent.maxY, d)}`;
}

export function formatBytes(bytes) {
  const n = num(bytes);
  if (n >= 1 << 30) return `${(n / (1 << 30)).toFixed(1)} GiB`;
  if (n >= 1 << 20) return `${(n / (1 << 20)).toFixed(1)} MiB`;
  if (n >= 1 << 10) return `${(n / (1 << 10)).toFixed(1)} KiB`;
  return `${n} B`;
}

// ------------------------------------------------------------ requests

export class ApiError extends Error {
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

/** An error body ({code, message}) as an ApiError. */
export function errorOf(body, fallback = "") {
  return new ApiError(body?.code ?? "UNKNOWN", body?.message ?? fallback);
}

/** Reads an error answer ({code, message}) into an ApiError. */
export async function apiError(response) {
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
export async function api(method, path, body) {
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

/** Why reliefd refused a stream's URL (an ApiError), or null when it
 * cannot be reached now or serves it after all. */
export async function whyRefused(url) {
  const abort = new AbortController();
  try {
    const response = await fetch(url, { signal: abort.signal, headers: authorized({ accept: "text/event-stream" }) });
    return response.ok ? null : await apiError(response);
  } catch {
    return null;
  } finally {
    abort.abort();
  }
}

export const sleep = (millis) => new Promise((resolve) => setTimeout(resolve, millis));
const RETRY_MIN_MS = 500;
const RETRY_MAX_MS = 15000;
export const backoff = (attempt) => Math.min(RETRY_MAX_MS, RETRY_MIN_MS * 2 ** Math.min(attempt, 5));
