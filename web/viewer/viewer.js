// viewer.js — the viewer page of `decalprep view`: asks the server what it
// serves (/config.json), opens a package (validated: every checksum and
// index) or streams a tileset (web/src/tile_stream.js: the tiles and
// overview levels each view needs, by render's rule, fetched in the
// background and drawn as they arrive), fetches its terrain file (flat
// without one), and draws it with the WebGPU renderer (web/src/render; WebGL2
// where WebGPU is missing) under a map camera, on demand. With ?shot=1
// (`decalprep view --screenshot`) it draws the config's camera once, every
// tile it chose loaded, and POSTs the pixels back (prep/view.hpp).
import { TileStream, createRenderer, fetchTerrain, fetchTileset, flatTerrain, openPackageUrl } from "../src/index.js";
import { MapCamera, attachControls } from "./camera.js";
import { describePick, layerKinds, showLayers, showOverlay, showPick, showStatus } from "./ui.js";

/** @typedef {import("../src/render/camera.js").Camera} Camera */
/** @typedef {import("../src/render/index.js").Terrain} Terrain */
/** @typedef {import("../src/render/index.js").FrameTile} FrameTile */

/**
 * @typedef {{polygons: boolean, lines: boolean, dynamic: boolean}} Kinds
 * @typedef {{width: number, height: number, camera: Camera, albedo: number[], decals: boolean,
 *            ramps: import("../src/render/scene.js").LayerRamp[], only?: Kinds,
 *            frames?: number, picks?: number[][], passTimes?: boolean, standInLevel?: number}} ShotConfig
 * @typedef {{kind: string, url: string, terrain?: string | null, backend?: string,
 *            gpuBudget?: number, screenshot?: ShotConfig | null}} Config
 */

/** Decoded blob bytes a tileset's loaded tiles may hold, unless the config says. */
const CACHE_BYTES = 1 << 30;

const canvas = /** @type {HTMLCanvasElement} */ (document.getElementById("map"));
const shotMode = new URLSearchParams(location.search).get("shot") === "1";

/** @returns {Promise<Config>} */
async function fetchConfig() {
  const res = await fetch("/config.json");
  if (!res.ok) throw new Error(`/config.json: HTTP ${res.status}`);
  return res.json();
}

/** @param {Config} config @returns {Promise<Terrain | null>} */
async function loadTerrain(config) {
  return config.terrain ? fetchTerrain(new URL(config.terrain, location.href).href) : null;
}

/**
 * `extent` grown to take in a top-down view's: where render lays flat
 * ground without a terrain file (libprep/pipeline/render_request.cpp).
 * @param {number[]} extent @param {number[] | null} td
 */
function flatGround(extent, td) {
  return flatTerrain(td ? [Math.min(extent[0], td[0]), Math.min(extent[1], td[1]), Math.max(extent[2], td[2]),
    Math.max(extent[3], td[3])] : extent);
}

/**
 * What the page draws, on the renderer: the package the config names, or
 * the tileset, streamed (`stream`; its tiles come with each view). extent:
 * the data's, metres relative to the camera's origin (the package's, the
 * tileset frame's). metadata: the package's, or a tile's once one arrives.
 * @param {Config} config
 * @param {import("../src/render/index.js").Renderer | import("../src/render/webgl2.js").WebGL2Renderer} renderer
 * @param {{ramps?: import("../src/render/scene.js").LayerRamp[], topdown?: number[] | null,
 *          onLoaded?: () => void}} options
 * @returns {Promise<{extent: number[], terrain: Terrain, metadata: any, stream: TileStream | null}>}
 */
async function openScene(config, renderer, options) {
  const url = new URL(config.url, location.href).href;
  const [data, terrain] = await Promise.all([
    config.kind === "package" ? openPackageUrl(url) : fetchTileset(url), loadTerrain(config)]);
  const td = options.topdown ?? null;
  if (!("tiles" in data)) {
    await data.validate();
    const meta = /** @type {any} */ (data.metadata);
    const extent = Array.isArray(meta?.extent) ? meta.extent : [0, 0, 1000, 1000];
    const ground = terrain ?? flatGround(extent, td);
    await renderer.setScene({ pkg: data, terrain: ground, ramps: options.ramps });
    return { extent, terrain: ground, metadata: meta, stream: null };
  }
  if (data.tiles.length === 0) throw new Error(`${config.url}: the tileset has no tiles`);
  // With a GPU budget (view --gpu-budget) the views are coarsened to fit
  // it and the cache holds as much.
  const budget = config.gpuBudget ?? 0;
  const stream = new TileStream({ tileset: data, baseUrl: new URL(".", url).href,
    maxBytes: budget > 0 ? budget : CACHE_BYTES, gpuBudget: budget, onLoaded: options.onLoaded });
  const extent = stream.extent();
  const ground = terrain ?? flatGround(extent, td);
  // Visibility bits for up to 1024 layers: the layer table comes with the tiles.
  await renderer.setTileScene({ terrain: ground, extent, layerCount: 1024, ramps: options.ramps });
  return { extent, terrain: ground, metadata: null, stream };
}

/**
 * The tiles' load failures, as one Error, or null.
 * @param {TileStream} stream
 */
function loadFailure(stream) {
  const st = stream.cache.stats;
  return st.failed > 0 ? new Error(`${st.failed} tile${st.failed > 1 ? "s" : ""} failed to load: ${st.lastError}`) : null;
}

/**
 * The backend to draw with: ?backend= in the page's URL, else the config's
 * (`decalprep view --backend`), else "auto" (WebGPU, falling back to WebGL2).
 * @param {Config} config
 * @returns {import("../src/render/index.js").Backend}
 */
function chosenBackend(config) {
  const asked = new URLSearchParams(location.search).get("backend") ?? config.backend ?? "auto";
  if (asked === "auto" || asked === "webgpu" || asked === "webgl2") return asked;
  throw new Error(`backend '${asked}': expected auto, webgpu or webgl2`);
}

/**
 * The renderer, or an Error that says what is missing and what to do.
 * @param {HTMLCanvasElement} c @param {import("../src/render/index.js").Backend} backend
 */
async function openRenderer(c, backend) {
  try {
    return await createRenderer({ canvas: c, backend });
  } catch (e) {
    const why = e instanceof Error ? e.message : String(e);
    throw new Error(`this viewer needs WebGPU or WebGL2 (backend ${backend}), which this browser does ` +
      `not offer (${why}); use a recent Chrome, Edge or Chromium (headless: --enable-unsafe-webgpu), ` +
      "or Firefox/Safari with WebGPU or WebGL2 enabled.");
  }
}

/**
 * The overlay's backend line: "WebGL2: static decals only; dynamic lines not drawn".
 * @param {{backend: string, limits: string}} r
 */
function backendLine(r) {
  return `${r.backend === "webgl2" ? "WebGL2" : "WebGPU"}${r.limits ? `: ${r.limits}` : ""}`;
}

/** @param {string} path @param {BodyInit} body */
async function post(path, body) {
  const res = await fetch(path, { method: "POST", body });
  if (!res.ok) throw new Error(`${path}: HTTP ${res.status}: ${await res.text()}`);
}

/**
 * Screenshot mode: one frame of the config's camera, POSTed back. A
 * tileset's view waits for every tile it chose (none stands in).
 * @param {Config} config
 */
async function screenshot(config) {
  const s = config.screenshot;
  if (!s) throw new Error("?shot=1, but /config.json has no screenshot (not started with --screenshot)");
  canvas.width = s.width;
  canvas.height = s.height;
  const renderer = await openRenderer(canvas, chosenBackend(config));
  const scene = await openScene(config, renderer, { ramps: s.ramps, topdown: s.camera.topdownExtent });
  /** @type {FrameTile[] | undefined} */
  let tiles;
  let metadata = scene.metadata;
  /** @type {any} */
  let tileStats = null;
  const stream = scene.stream;
  if (stream) {
    const { zmin, zmax } = scene.terrain;
    // --stand-in-level L: only level L's tiles are fetched; they stand in
    // for the view's own (as the viewer shows it while they come).
    const standIn = s.standInLevel ?? -1;
    const first = await stream.view(s.camera, s.width, s.height, zmin, zmax, { fetch: standIn < 0 });
    if (standIn >= 0) await stream.fetchLevel(first.selection.tiles, standIn);
    await stream.settled();
    const failure = loadFailure(stream);
    if (failure) throw failure;
    const v = await stream.view(s.camera, s.width, s.height, zmin, zmax, { fetch: standIn < 0 });
    if (standIn < 0 && v.standIns > 0)
      throw new Error(`${v.standIns} tile${v.standIns > 1 ? "s" : ""} still stand in for the view's own after every fetch ended`);
    tiles = v.tiles;
    metadata = tiles[0]?.pkg.metadata ?? null;
    const sel = v.selection, st = stream.cache.stats;
    tileStats = { chosen: sel.tiles.length, drawn: tiles.length, standIns: v.standIns, perLevel: sel.perLevel,
      packageBytes: sel.packageBytes, fullDetailBytes: sel.fullDetailBytes, fullDetailTiles: sel.fullDetailTiles,
      requests: st.requests, fetchedBytes: st.bytes, gpuBudget: stream.gpuBudget, blobBytes: sel.blobBytes,
      coarsened: sel.coarsened, headerReads: stream.headerReads };
  }
  // --only: the kinds left out are hidden layers. The WebGL2 renderer does
  // not draw dynamic lines: the ones the view asks for are named.
  const only = s.only ?? { polygons: true, lines: true, dynamic: true };
  const undrawn = [];
  const kinds = layerKinds(metadata);
  for (const [i, { name, kind }] of kinds.entries()) {
    renderer.setLayerVisible(i, only[kind]);
    if (kind === "dynamic" && only.dynamic && renderer.backend === "webgl2") undrawn.push(name || `layer ${i}`);
  }
  if (undrawn.length > 0) {
    await post("/__shot/note", `WebGL2 does not draw dynamic lines: layer${undrawn.length > 1 ? "s" : ""} ` +
      `${undrawn.join(", ")} left out (--backend webgpu draws them; render --only polygons,lines draws the same decals)`);
  }
  // --frames N: N frames drawn, the last one sent; their times go to
  // /__shot/stats (view --stats prints them).
  const frames = Math.max(1, Math.min(1000, Math.floor(s.frames ?? 1)));
  const times = [], passes = [];
  let out = null;
  for (let i = 0; i < frames; ++i) {
    const last = i === frames - 1;
    out = await renderer.renderFrame({
      camera: s.camera, width: s.width, height: s.height, albedo: s.albedo, decals: s.decals && last,
      present: false, readback: last, passTimes: Boolean(s.passTimes), tiles,
    });
    times.push(out.ms);
    if (out.passes) passes.push(out.passes);
  }
  if (!out || !out.rgba) throw new Error("renderFrame returned no pixels");
  // --pick X,Y: the top decal under each pixel, from the frame's own query.
  const names = kinds.map((l) => l.name);
  const picks = [];
  for (const xy of s.picks ?? []) {
    const p = (await renderer.renderFrame({
      camera: s.camera, width: s.width, height: s.height, albedo: s.albedo, present: false,
      readback: false, pick: xy, tiles,
    })).pick;
    picks.push({ x: xy[0], y: xy[1], ...(p ? { ...p, layerName: names[p.layer] ?? "" } : { kind: "none" }) });
  }
  await post("/__shot/stats", JSON.stringify({
    adapter: renderer.adapterName,
    browser: /(?:HeadlessChrome|Chrome|Firefox|Safari)\/[\d.]+/.exec(navigator.userAgent)?.[0] ?? navigator.userAgent,
    times, gpuBytes: renderer.gpuBytes, picks, passes, tiles: tileStats,
  }));
  // Each POST is W*H*4 bytes of RGBA8, row 0 at the top.
  await post("/__shot/frame", new Blob([out.rgba]));
  if (s.decals) {
    if (!out.decals) throw new Error("renderFrame returned no decal layer");
    await post("/__shot/decals", new Blob([out.decals]));
  }
  showStatus(`screenshot sent (${s.width}x${s.height}, ${out.ms.toFixed(1)} ms)`);
}

/**
 * The overlay's line for a tileset: the frame budget and the detail it
 * leaves (pixelScale: 1 full, 2 one level coarser...), the chosen level
 * mix, the bytes fetched and held, the fetches still to come.
 * @param {TileStream} stream @param {number} budgetMs @param {number} pixelScale
 */
function streamLine(stream, budgetMs, pixelScale) {
  const sel = stream.selection, st = stream.cache.stats, c = stream.cache;
  const mix = sel ? sel.perLevel.map((n, l) => (n > 0 ? `L${l}:${n}` : "")).filter(Boolean).join(" ") : "";
  const mib = (/** @type {number} */ b) => (b / 1048576).toFixed(1);
  const gpu = stream.gpuBudget > 0 ? `, GPU budget ${mib(stream.gpuBudget)} MiB (${sel?.coarsened ?? 0} coarsened)` : "";
  return `budget ${budgetMs} ms, detail 1/${pixelScale}; levels ${mix || "none"}${gpu}\n` +
    `fetched ${mib(st.bytes)} MiB in ${st.requests} requests, holding ${mib(c.loadedBytes)} of ${mib(c.maxBytes)} MiB` +
    `${c.inFlight.size + c.queue.size > 0 ? `, ${c.inFlight.size + c.queue.size} to come` : ""}` +
    `${st.failed > 0 ? `\n${st.failed} failed: ${st.lastError}` : ""}`;
}

/** The interactive viewer. @param {Config} config */
async function interactive(config) {
  const renderer = await openRenderer(canvas, chosenBackend(config));
  let redraw = () => {};
  const scene = await openScene(config, renderer, { onLoaded: () => redraw() });
  const { extent, terrain, stream } = scene;
  const cam = new MapCamera(extent, (terrain.zmin + terrain.zmax) / 2);
  // A tileset's frame budget (?budget=MS, 50 by default): a frame over it
  // (that uploaded no tile: packing and upload are not drawing) makes the
  // next one draw coarser levels (each pixel taken twice as large, up to 64
  // times); one under a third of it finer again, but never as fine as a
  // detail already found too slow since the camera last moved.
  const budgetMs = Number(new URLSearchParams(location.search).get("budget") ?? 50);
  let pixelScale = 1, slowScale = 0;
  /** @type {FrameTile[] | undefined} */
  let tiles;
  let names = /** @type {string[]} */ ([]);
  const listLayers = (/** @type {any} */ metadata) => {
    const kinds = layerKinds(metadata);
    names = kinds.map((l) => l.name);
    const listed = kinds.map(({ name, kind }) => (kind !== "dynamic" ? name
      : `${name} (dynamic${renderer.backend === "webgl2" ? ": not drawn by WebGL2" : ""})`));
    showLayers(listed, (i, visible) => {
      renderer.setLayerVisible(i, visible);
      redraw();
    });
  };
  if (scene.metadata) listLayers(scene.metadata);
  let dirty = true, busy = false;
  const draw = async () => {
    if (busy || !dirty) return;
    busy = true;
    dirty = false;
    try {
      const scale = Math.min(window.devicePixelRatio || 1, 2);
      const width = Math.max(1, Math.round(canvas.clientWidth * scale));
      const height = Math.max(1, Math.round(canvas.clientHeight * scale));
      if (canvas.width !== width || canvas.height !== height) [canvas.width, canvas.height] = [width, height];
      const camera = cam.camera();
      if (stream) {
        tiles = (await stream.view(camera, width, height, terrain.zmin, terrain.zmax, { pixelScale })).tiles;
        if (names.length === 0 && tiles.length > 0) listLayers(tiles[0].pkg.metadata);
      }
      const out = await renderer.renderFrame({ camera, width, height, present: true, readback: false, tiles });
      const line = stream ? streamLine(stream, budgetMs, pixelScale) : "";
      if (stream && out.uploads === 0 && out.ms > budgetMs && pixelScale < 64) {
        slowScale = Math.max(slowScale, pixelScale);
        pixelScale *= 2;
        dirty = true;
      } else if (stream && out.uploads === 0 && out.ms < budgetMs / 3 && pixelScale / 2 > slowScale &&
                 pixelScale > 1) {
        pixelScale /= 2;
        dirty = true;
      }
      showOverlay({ ms: out.ms, gpuBytes: renderer.gpuBytes, tiles: stream ? (tiles ?? []).length : 1, width, height,
        adapter: renderer.adapterName, limits: backendLine(renderer) + (line ? `\n${line}` : "") });
    } finally {  // a failure reaches failed() through "unhandledrejection"
      busy = false;
    }
    if (dirty) requestAnimationFrame(() => void draw());
  };
  redraw = () => {
    dirty = true;
    requestAnimationFrame(() => void draw());
  };
  attachControls(canvas, cam, () => {
    slowScale = 0;  // a new view may afford more detail
    redraw();
  });
  // A click (a press and release without a drag) names the decal under it.
  let press = { x: 0, y: 0 };
  canvas.addEventListener("pointerdown", (e) => { press = { x: e.clientX, y: e.clientY }; });
  canvas.addEventListener("pointerup", (e) => {
    if (e.button !== 0 || Math.hypot(e.clientX - press.x, e.clientY - press.y) > 3) return;
    const r = canvas.getBoundingClientRect();
    const x = Math.floor(((e.clientX - r.left) * canvas.width) / r.width);
    const y = Math.floor(((e.clientY - r.top) * canvas.height) / r.height);
    void renderer.renderFrame({ camera: cam.camera(), width: canvas.width, height: canvas.height,
      present: false, readback: false, pick: [x, y], tiles })
      .then((out) => showPick(describePick(out.pick, names)));
  });
  new ResizeObserver(redraw).observe(canvas);
  document.title = `decalprep view: ${config.url}`;
  showStatus("");
  redraw();
}

/** @param {unknown} e */
const message = (e) => (e instanceof Error ? e.message : String(e));

async function main() {
  const config = await fetchConfig();
  if (shotMode) await screenshot(config);
  else await interactive(config);
}

let reported = false;
/** A failure: shown, and in screenshot mode POSTed to the server once. @param {unknown} e */
function failed(e) {
  showStatus(`Error: ${message(e)}`, true);
  console.error(e);
  if (shotMode && !reported) {
    reported = true;
    fetch("/__shot/error", { method: "POST", body: message(e) }).catch(() => {});
  }
}
window.addEventListener("error", (e) => failed(e.error ?? e.message));
window.addEventListener("unhandledrejection", (e) => failed(e.reason));
main().catch(failed);
