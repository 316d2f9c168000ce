// viewer.js — the viewer page of `decalprep view`: asks the server what it
// serves (/config.json), opens the package (a tileset: its first tile, for
// now) with the reader, fetches its terrain file (flat without one), and
// draws it with the WebGPU renderer (web/src/render) under a map camera,
// on demand. With ?shot=1 (`decalprep view --screenshot`) it draws the
// config's camera once and POSTs the pixels back (prep/view.hpp).
import { createRenderer, fetchTerrain, fetchTileset, flatTerrain, openPackageUrl, openTile } from "../src/index.js";
import { MapCamera, attachControls } from "./camera.js";
import { describePick, layerKinds, showLayers, showOverlay, showPick, showStatus } from "./ui.js";

/** @typedef {import("../src/package.js").Package} Package */
/** @typedef {import("../src/render/camera.js").Camera} Camera */
/** @typedef {import("../src/render/index.js").Terrain} Terrain */

/**
 * @typedef {{polygons: boolean, lines: boolean, dynamic: boolean}} Kinds
 * @typedef {{width: number, height: number, camera: Camera, albedo: number[], decals: boolean,
 *            ramps: import("../src/render/scene.js").LayerRamp[], only?: Kinds,
 *            frames?: number, picks?: number[][], passTimes?: boolean}} ShotConfig
 * @typedef {{kind: string, url: string, terrain?: string | null, backend?: string,
 *            screenshot?: ShotConfig | null}} Config
 */

const canvas = /** @type {HTMLCanvasElement} */ (document.getElementById("map"));
const shotMode = new URLSearchParams(location.search).get("shot") === "1";

/** @returns {Promise<Config>} */
async function fetchConfig() {
  const res = await fetch("/config.json");
  if (!res.ok) throw new Error(`/config.json: HTTP ${res.status}`);
  return res.json();
}

/**
 * The package the config names; for a tileset its first tile (streaming
 * the tiles a view needs comes later). Validated: every checksum and index.
 * @param {Config} config
 * @returns {Promise<{pkg: Package, tiles: number}>}
 */
async function openData(config) {
  const url = new URL(config.url, location.href).href;
  /** @type {Package} */
  let pkg;
  if (config.kind === "package") {
    pkg = await openPackageUrl(url);
  } else {
    const ts = await fetchTileset(url);
    if (ts.tiles.length === 0) throw new Error(`${config.url}: the tileset has no tiles`);
    pkg = await openTile(new URL(".", url).href, ts.tiles[0]);
  }
  await pkg.validate();
  return { pkg, tiles: 1 };
}

/** @param {Config} config @returns {Promise<Terrain | null>} */
async function loadTerrain(config) {
  return config.terrain ? fetchTerrain(new URL(config.terrain, location.href).href) : null;
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

/** Screenshot mode: one frame of the config's camera, POSTed back. @param {Config} config */
async function screenshot(config) {
  const s = config.screenshot;
  if (!s) throw new Error("?shot=1, but /config.json has no screenshot (not started with --screenshot)");
  const [{ pkg }, terrain] = await Promise.all([openData(config), loadTerrain(config)]);
  canvas.width = s.width;
  canvas.height = s.height;
  const renderer = await openRenderer(canvas, chosenBackend(config));
  // Without a terrain file, flat ground where render lays it
  // (libprep/pipeline/render_request.cpp): the package extent, grown to
  // take in a top-down view.
  const td = s.camera.topdownExtent, ext = /** @type {any} */ (pkg.metadata).extent;
  const ground = terrain ?? (td && Array.isArray(ext) ? flatTerrain([Math.min(ext[0], td[0]),
    Math.min(ext[1], td[1]), Math.max(ext[2], td[2]), Math.max(ext[3], td[3])]) : null);
  await renderer.setScene({ pkg, terrain: ground, ramps: s.ramps });
  // --only: the kinds left out are hidden layers. The WebGL2 renderer does
  // not draw dynamic lines: the ones the view asks for are named.
  const only = s.only ?? { polygons: true, lines: true, dynamic: true };
  const undrawn = [];
  for (const [i, { name, kind }] of layerKinds(pkg.metadata).entries()) {
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
      present: false, readback: last, passTimes: Boolean(s.passTimes),
    });
    times.push(out.ms);
    if (out.passes) passes.push(out.passes);
  }
  if (!out || !out.rgba) throw new Error("renderFrame returned no pixels");
  // --pick X,Y: the top decal under each pixel, from the frame's own query.
  const names = layerKinds(pkg.metadata).map((l) => l.name);
  const picks = [];
  for (const xy of s.picks ?? []) {
    const p = (await renderer.renderFrame({
      camera: s.camera, width: s.width, height: s.height, albedo: s.albedo, present: false,
      readback: false, pick: xy,
    })).pick;
    picks.push({ x: xy[0], y: xy[1], ...(p ? { ...p, layerName: names[p.layer] ?? "" } : { kind: "none" }) });
  }
  await post("/__shot/stats", JSON.stringify({
    adapter: renderer.adapterName,
    browser: /(?:HeadlessChrome|Chrome|Firefox|Safari)\/[\d.]+/.exec(navigator.userAgent)?.[0] ?? navigator.userAgent, times, gpuBytes: renderer.gpuBytes,
    picks, passes,
  }));
  // Each POST is W*H*4 bytes of RGBA8, row 0 at the top.
  await post("/__shot/frame", new Blob([out.rgba]));
  if (s.decals) {
    if (!out.decals) throw new Error("renderFrame returned no decal layer");
    await post("/__shot/decals", new Blob([out.decals]));
  }
  showStatus(`screenshot sent (${s.width}x${s.height}, ${out.ms.toFixed(1)} ms)`);
}

/** The interactive viewer. @param {Config} config */
async function interactive(config) {
  const [{ pkg, tiles }, terrain] = await Promise.all([openData(config), loadTerrain(config)]);
  const renderer = await openRenderer(canvas, chosenBackend(config));
  await renderer.setScene({ pkg, terrain, ramps: [] });
  const meta = /** @type {any} */ (pkg.metadata);
  const extent = Array.isArray(meta?.extent) ? meta.extent : [0, 0, 1000, 1000];
  const cam = new MapCamera(extent, terrain ? (terrain.zmin + terrain.zmax) / 2 : 0);
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
      const out = await renderer.renderFrame({ camera: cam.camera(), width, height, present: true, readback: false });
      showOverlay({ ms: out.ms, gpuBytes: renderer.gpuBytes, tiles, width, height, adapter: renderer.adapterName,
        limits: backendLine(renderer) });
    } finally {  // a failure reaches failed() through "unhandledrejection"
      busy = false;
    }
    if (dirty) requestAnimationFrame(() => void draw());
  };
  const redraw = () => {
    dirty = true;
    requestAnimationFrame(() => void draw());
  };
  attachControls(canvas, cam, redraw);
  // A click (a press and release without a drag) names the decal under it.
  const names = layerKinds(pkg.metadata).map((l) => l.name);
  let press = { x: 0, y: 0 };
  canvas.addEventListener("pointerdown", (e) => { press = { x: e.clientX, y: e.clientY }; });
  canvas.addEventListener("pointerup", (e) => {
    if (e.button !== 0 || Math.hypot(e.clientX - press.x, e.clientY - press.y) > 3) return;
    const r = canvas.getBoundingClientRect();
    const x = Math.floor(((e.clientX - r.left) * canvas.width) / r.width);
    const y = Math.floor(((e.clientY - r.top) * canvas.height) / r.height);
    void renderer.renderFrame({ camera: cam.camera(), width: canvas.width, height: canvas.height,
      present: false, readback: false, pick: [x, y] })
      .then((out) => showPick(describePick(out.pick, names)));
  });
  const listed = layerKinds(pkg.metadata).map(({ name, kind }) => (kind !== "dynamic" ? name
    : `${name} (dynamic${renderer.backend === "webgl2" ? ": not drawn by WebGL2" : ""})`));
  showLayers(listed, (i, visible) => {
    renderer.setLayerVisible(i, visible);
    redraw();
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
