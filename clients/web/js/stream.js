// The tab's one connection to reliefd: a WebSocket (`/api/frames/ws` with
// `events=1`) that brings the view's frames (binary) and the scene's events
// (`{"scene": SceneEvent}`), and carries the tab's calls (`{"id", "navigate"
// | "update" | "pick" | "home" | "state"}`, answered by `{"reply": id, ...}`).
// A browser lets a page hold only six connections to one host: one a tab
// leaves room for every other tab.
//
// The socket is closed when the page is hidden or left (`pagehide`, so the
// back/forward cache keeps no stream open) and opened again when it shows.

import { ApiError, errorOf, withToken } from "./util.js";

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

export class TabSocket {
  /**
   * handlers: onOpen(), onFrame(frame, image), onScene(event),
   * onFailed(error) (the view failed: the socket ends), onClose(opened).
   */
  constructor(handlers) {
    this.handlers = handlers;
    this.socket = null;
    this.nextId = 1;
    this.waiting = new Map(); // id -> { resolve, reject }
  }

  get open() {
    return this.socket?.readyState === WebSocket.OPEN;
  }

  /** The query of a view's stream of `size`: also the SSE stream's, to learn why a socket was refused. */
  static query(viewId, size, maxFps) {
    return new URLSearchParams({ view: viewId, width: String(size.width), height: String(size.height), max_fps: String(maxFps) });
  }

  connect(viewId, size, maxFps) {
    this.close();
    const query = TabSocket.query(viewId, size, maxFps);
    query.set("events", "1");
    query.set("from", "0"); // every (re)connection starts with a snapshot
    const url = new URL(withToken(`api/frames/ws?${query}`), location.href);
    url.protocol = url.protocol === "https:" ? "wss:" : "ws:";
    const socket = new WebSocket(url.toString());
    socket.binaryType = "arraybuffer";
    this.socket = socket;
    let opened = false;
    socket.addEventListener("open", () => {
      if (socket !== this.socket) return;
      opened = true;
      this.handlers.onOpen();
    });
    socket.addEventListener("message", (message) => {
      if (socket !== this.socket) return;
      if (typeof message.data === "string") this.text(message.data);
      else {
        const decoded = decodeFrame(message.data);
        if (decoded) this.handlers.onFrame(decoded.frame, decoded.image);
      }
    });
    socket.addEventListener("close", () => {
      if (socket !== this.socket) return;
      this.socket = null;
      this.failWaiting();
      this.handlers.onClose(opened);
    });
  }

  text(data) {
    let body;
    try {
      body = JSON.parse(data);
    } catch {
      return;
    }
    if (body.reply !== undefined) {
      const waiter = this.waiting.get(body.reply);
      this.waiting.delete(body.reply);
      if (!waiter) return;
      if (body.error) waiter.reject(errorOf(body.error));
      else waiter.resolve(body);
    } else if (body.scene) {
      this.handlers.onScene(body.scene);
    } else if (body.error) {
      this.handlers.onFailed(errorOf(body.error));
    }
  }

  /** A call on the socket: `{"id", kind: body}`; resolves with the reply. */
  call(kind, body) {
    if (!this.open) return Promise.reject(new ApiError("UNAVAILABLE", "not connected to reliefd"));
    const id = this.nextId++;
    return new Promise((resolve, reject) => {
      this.waiting.set(id, { resolve, reject });
      this.socket.send(JSON.stringify({ id, [kind]: body ?? {} }));
    });
  }

  failWaiting() {
    for (const waiter of this.waiting.values()) waiter.reject(new ApiError("UNAVAILABLE", "the connection to reliefd closed"));
    this.waiting.clear();
  }

  /** Closes the socket without telling the handlers. */
  close() {
    const socket = this.socket;
    this.socket = null;
    this.failWaiting();
    if (socket && socket.readyState <= WebSocket.OPEN) socket.close(1000, "closed by the page");
  }
}
