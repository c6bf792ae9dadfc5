// relief-tiles.js: keeps CesiumJS and MapLibre GL JS views of reliefd's
// standard tiles (/tiles/...) live. It listens to /tiles/changes (Server-Sent
// Events, one EventSource) and, for each generation that changed something,
// reloads what that viewer shows of it. An ES module with no dependencies:
// reliefd serves it at /js/relief-tiles.js; copy it beside your page or
// import it from there.
//
//   import { followRelief } from "./relief-tiles.js";
//   const follow = followRelief(reliefUrl, {              // reliefd's address
//     cesium: { viewer, terrain: true, tileset },          // CesiumJS
//     maplibre: { map, terrainSource: "relief-dem", imagerySource: "relief-imagery" },
//     onChange: (change) => console.log(change.generation, change.applied),
//   });
//   ...
//   follow.close();
//
// What each viewer's public API allows, and so what is done:
//
// CesiumJS terrain: the globe cannot reload a range of terrain tiles. Its
// quadtree (QuadtreePrimitive, globe._surface) is private and only offers
// invalidateAllTiles, and a loaded tile's geometry never expires. The one
// public lever is Globe#terrainProvider: a changed terrain gets a new
// CesiumTerrainProvider.fromUrl on layer.json (served no-cache, so it names
// the new version, and every tile URL carries ?v=VERSION past any HTTP
// cache), set once it is ready. Cesium then reloads the globe's tiles; the
// camera is not touched.
//
// CesiumJS 3D Tiles: a loaded tile's content can be reloaded in place with
// public API: setting Cesium3DTile#expireDate to a past date makes the
// tileset request that content again (with an `expired=` query that no
// cache answers) and draw the old content until the new one is ready. That
// is done when every changed content is loaded in the tileset now. Otherwise
// (a content not loaded could come back from the browser's cache under its
// old version's URL, or be a tile the old tileset.json does not have),
// and when every tile changed, a new Cesium3DTileset.fromUrl is loaded
// hidden (preloadWhenHidden) and swapped into scene.primitives in the old
// one's place once its first tiles are in.
//
// MapLibre GL JS: for a changed source, the source's tile URLs move to the
// new version (?v=), then map.refreshTiles(source, tiles) reloads the
// changed tiles in view (MapLibre 5 has it), drawing the old ones until the
// new arrive. MapLibre keeps tiles that left the view in a cache that
// refreshTiles does not reach; a change wider than MAX_REFRESH_TILES tiles,
// or `all`, refreshes every tile (map.refreshTiles(source): the cache is
// emptied). A MapLibre without refreshTiles gets source.setTiles with the
// new version's URLs, which reloads the whole source.
//
// A dropped stream is opened again by the EventSource itself; its first
// `versions` event then tells which schemes changed while it was away,
// and those are refreshed whole.

/** More changed tiles than this in one MapLibre source: refresh it whole. */
const MAX_REFRESH_TILES = 1024;
/** How long a swapped-in tileset may take to load its first tiles before it is shown anyway. */
const TILESET_SWAP_TIMEOUT_MS = 15000;

/**
 * Follows reliefd's /tiles/changes and applies every change to the viewers
 * given. Returns { close(), ready, versions(), generation(), idle() }:
 * `ready` resolves with the first `versions` event; `idle()` resolves once
 * every change received so far is applied.
 *
 * @param {string} baseUrl reliefd's address (its /tiles/ are under it).
 * @param {object} options
 * @param {object} [options.cesium] { viewer, terrain: true to follow the
 *   globe's terrain, tileset: a Cesium3DTileset of /tiles/3d/tileset.json,
 *   Cesium: the namespace (default globalThis.Cesium), requestVertexNormals
 *   (default true), onTileset(newTileset, oldTileset): told of a swap }
 * @param {object} [options.maplibre] { map, terrainSource: the raster-dem
 *   source id fed by /tiles/terrarium.json, imagerySource: the raster
 *   source id fed by /tiles/imagery.json }
 * @param {function} [options.onChange] called after each change is applied
 *   with { generation, changes, applied: ["terrain: ...", ...] }.
 * @param {function} [options.onError] called with an Error when applying
 *   a change failed (the next change tries again).
 * @param {string} [options.token] a bearer token for a reliefd that wants
 *   one, sent as access_token= (an EventSource cannot set headers).
 * @param {function} [options.EventSource] the EventSource class to use.
 */
export function followRelief(baseUrl, options = {}) {
  const base = String(baseUrl).replace(/\/+$/, "");
  const cesium = options.cesium ? cesiumFollower(base, options.cesium) : null;
  const maplibre = options.maplibre ? maplibreFollower(options.maplibre) : null;
  const onChange = options.onChange ?? (() => {});
  const onError = options.onError ?? ((error) => console.warn("relief-tiles:", error));
  const Source = options.EventSource ?? globalThis.EventSource;

  let versions = null;
  let generation = 0;
  let work = Promise.resolve();
  let closed = false;
  let resolveReady;
  const ready = new Promise((resolve) => (resolveReady = resolve));

  // Changes are applied one after another, in the order they came.
  const enqueue = (changes) => {
    work = work.then(async () => {
      if (closed) return;
      const applied = [];
      try {
        if (cesium) applied.push(...(await cesium.apply(changes)));
        if (maplibre) applied.push(...maplibre.apply(changes));
      } catch (error) {
        onError(error instanceof Error ? error : new Error(String(error)));
      }
      onChange({ generation: changes.generation ?? generation, changes, applied });
    });
  };

  let url = `${base}/tiles/changes`;
  if (options.token) url += `?access_token=${encodeURIComponent(options.token)}`;
  const events = new Source(url);

  events.addEventListener("versions", (event) => {
    const now = JSON.parse(event.data);
    generation = Number(now.generation ?? 0);
    if (versions === null) {
      versions = now;
      resolveReady(now);
      // What the viewers loaded before the stream opened may be older.
      const stale = { generation };
      for (const scheme of SCHEMES) {
        if (now[scheme] && cesium?.loaded(scheme, now[scheme].version) === false) stale[scheme] = { ...now[scheme], all: true };
        if (now[scheme] && maplibre?.loaded(scheme, now[scheme].version) === false) stale[scheme] = { ...now[scheme], all: true };
      }
      if (Object.keys(stale).length > 1) enqueue(stale);
      return;
    }
    // The stream came back: refresh whole what changed while it was away.
    const missed = { generation };
    for (const scheme of SCHEMES) {
      if (now[scheme] && now[scheme].version !== versions[scheme]?.version) missed[scheme] = { ...now[scheme], all: true };
    }
    versions = now;
    if (Object.keys(missed).length > 1) enqueue(missed);
  });

  events.addEventListener("changes", (event) => {
    const changes = JSON.parse(event.data);
    generation = Number(changes.generation ?? generation);
    versions = { ...(versions ?? {}), generation };
    for (const scheme of SCHEMES) {
      if (changes[scheme]) versions[scheme] = { version: changes[scheme].version };
    }
    enqueue(changes);
  });

  return {
    /** Resolves with the first `versions` event. */
    ready,
    /** The last versions known, per scheme. */
    versions: () => versions,
    /** The last generation known. */
    generation: () => generation,
    /** Resolves when every change received so far is applied. */
    idle: () => work,
    /** The tileset now shown (a swap replaces the one given). */
    tileset: () => cesium?.tileset() ?? null,
    close() {
      closed = true;
      events.close();
    },
  };
}

/** The schemes a change may name, as /tiles/changes names them. */
const SCHEMES = ["terrain", "tileset", "terrarium", "imagery"];

function cesiumFollower(base, { viewer, terrain = false, tileset = null, Cesium = globalThis.Cesium, requestVertexNormals = true, onTileset = () => {} }) {
  if (!viewer) throw new Error("followRelief: cesium.viewer is required");
  if (!Cesium) throw new Error("followRelief: pass cesium.Cesium, or load Cesium as a global");
  const layerUrl = `${base}/tiles/terrain/`;
  const tilesetUrl = `${base}/tiles/3d/tileset.json`;
  let current = tileset;

  async function replaceTerrain() {
    const provider = await Cesium.CesiumTerrainProvider.fromUrl(layerUrl, { requestVertexNormals });
    viewer.scene.globe.terrainProvider = provider;
    return "terrain: provider replaced";
  }

  /** Tiles of `set` with content, by the content's path relative to tileset.json. */
  function contentTiles(set) {
    const dir = new URL(".", new URL(tilesetUrl, location.href)).pathname;
    const found = new Map();
    const stack = set.root ? [set.root] : [];
    while (stack.length > 0) {
      const tile = stack.pop();
      const url = tile.content?.url;
      if (url) {
        const path = new URL(url, location.href).pathname;
        if (path.startsWith(dir)) found.set(decodeURIComponent(path.slice(dir.length)), tile);
      }
      stack.push(...(tile.children ?? []));
    }
    return found;
  }

  async function swapTileset(version) {
    const old = current;
    const url = version ? `${tilesetUrl}?v=${encodeURIComponent(version)}` : tilesetUrl;
    const next = await Cesium.Cesium3DTileset.fromUrl(url, { show: false, preloadWhenHidden: true });
    if (old?.style) next.style = old.style;
    viewer.scene.primitives.add(next);
    await new Promise((resolve) => {
      const timer = setTimeout(done, TILESET_SWAP_TIMEOUT_MS);
      const remove = next.initialTilesLoaded.addEventListener(done);
      function done() {
        clearTimeout(timer);
        remove();
        resolve();
      }
    });
    next.show = old ? old.show : true;
    if (old) viewer.scene.primitives.remove(old);
    current = next;
    onTileset(next, old);
    return "tileset: replaced";
  }

  async function refreshTileset(change) {
    if (!current) return null;
    const listed = change.content ?? [];
    if (!change.all && listed.length > 0) {
      const loaded = contentTiles(current);
      if (listed.every((uri) => loaded.has(uri))) {
        const past = Cesium.JulianDate.fromDate(new Date(Date.now() - 1000));
        for (const uri of listed) loaded.get(uri).expireDate = past;
        return `tileset: ${listed.length} contents reloaded`;
      }
    }
    return swapTileset(change.version);
  }

  return {
    /** false when the viewer shows a version of `scheme` other than `version`; null when it cannot tell. */
    loaded(scheme, version) {
      if (scheme === "tileset" && current?.asset?.tilesetVersion !== undefined) return current.asset.tilesetVersion === version;
      return null;
    },
    tileset: () => current,
    async apply(changes) {
      const applied = [];
      if (terrain && changes.terrain) applied.push(await replaceTerrain());
      if (changes.tileset) {
        const done = await refreshTileset(changes.tileset);
        if (done) applied.push(done);
      }
      return applied;
    },
  };
}

function maplibreFollower({ map, terrainSource = null, imagerySource = null }) {
  if (!map) throw new Error("followRelief: maplibre.map is required");
  const sources = { terrarium: terrainSource, imagery: imagerySource };

  /** `urls` with their v= parameter set to `version`. */
  const versioned = (urls, version) =>
    urls.map((url) => url.replace(/([?&]v=)[^&#]*/, `$1${encodeURIComponent(version)}`));

  function refresh(scheme, change) {
    const id = sources[scheme];
    const source = id ? map.getSource(id) : null;
    if (!source || !Array.isArray(source.tiles)) return null;
    const tiles = versioned(source.tiles, change.version);
    if (typeof map.refreshTiles !== "function") {
      source.setTiles(tiles);
      return `${scheme}: source ${id} set to version ${change.version}`;
    }
    // Tiles loaded from now on (and the refreshed ones) use the new URLs.
    source.tiles = tiles;
    const ids = change.all ? null : tileIds(change.tiles ?? [], source.maxzoom ?? 22);
    if (ids === null) {
      map.refreshTiles(id);
      return `${scheme}: source ${id} refreshed whole`;
    }
    map.refreshTiles(id, ids);
    return `${scheme}: ${ids.length} tiles of ${id} refreshed`;
  }

  return {
    loaded(scheme, version) {
      const id = sources[scheme];
      const tiles = id ? map.getSource(id)?.tiles : null;
      const v = Array.isArray(tiles) ? /[?&]v=([^&#]*)/.exec(tiles[0] ?? "") : null;
      return v ? decodeURIComponent(v[1]) === version : null;
    },
    apply(changes) {
      const applied = [];
      for (const scheme of ["terrarium", "imagery"]) {
        if (changes[scheme]) {
          const done = refresh(scheme, changes[scheme]);
          if (done) applied.push(done);
        }
      }
      return applied;
    },
  };
}

/** Every {z, x, y} in the inclusive ranges, up to `maxzoom`; null past MAX_REFRESH_TILES. */
function tileIds(ranges, maxzoom) {
  const ids = [];
  for (const { z, x, y } of ranges) {
    if (z > maxzoom) continue;
    const count = (x[1] - x[0] + 1) * (y[1] - y[0] + 1);
    if (ids.length + count > MAX_REFRESH_TILES) return null;
    for (let tx = x[0]; tx <= x[1]; tx++) {
      for (let ty = y[0]; ty <= y[1]; ty++) ids.push({ z, x: tx, y: ty });
    }
  }
  return ids;
}
