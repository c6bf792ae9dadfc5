// What the page knows, kept up to date for tests driving the page (and for
// the curious, from the console) as `window.relief`.

export const relief = {
  viewId: null,
  generation: 0, // from the scene events
  frames: 0, // frames shown
  framesSinceShow: 0, // frames shown since the page last showed (a load, back, a visible tab)
  lastFrame: null, // the last RenderResponse (its image came beside it)
  frameBytes: 0, // the last frame image's size on the wire
  state: null, // the last SceneState
  lastError: null, // the last error shown, as text
  refused: null, // the HTTP status (401, 403) of the last refusal, if any
  connections: 0, // sockets this page opened
  dirtyShown: 0, // generations whose dirty extents were outlined
  // The last 200 frames: generation, and wall-clock ms when the frame
  // arrived and when its image was decoded and shown (benchmarks).
  frameLog: [],
};
window.relief = relief;
