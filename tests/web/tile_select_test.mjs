#!/usr/bin/env node
// tile_select_test.mjs — the browser's tile choice (web/src/tile_select.js
// selectTiles) against `render`'s (prep::render::select_tiles, through
// tests/web/view_oracle.cpp `tiles`): the Monaco sample built as a tileset
// of 500 m tiles with --levels auto, viewed whole from above, obliquely from
// far and from near, and close up from above, each without a budget and
// with budgets that make the C++ rule coarsen; the tiles drawn (level, x,
// y), their decoded blob bytes (from each tile's blob table, read by the
// JavaScript reader) and the byte totals must be the same. A budget below
// the coarsest tiles' needs must be refused by both. pixelScale (the
// viewer's detail under its frame budget) must equal the C++ choice on a
// smaller image, and draw coarser levels.
//
//   node tests/web/tile_select_test.mjs DECALPREP VIEW_ORACLE REPO_ROOT WORK_DIR
import { spawnSync } from "node:child_process";
import { readFileSync, writeFileSync } from "node:fs";
import { join } from "node:path";
import { monacoTileset } from "./monaco_tileset.mjs";

const [decalprep, oracle, root, work] = process.argv.slice(2);
if (!work) {
  console.error("usage: tile_select_test.mjs DECALPREP VIEW_ORACLE REPO_ROOT WORK_DIR");
  process.exit(2);
}
const { openPackage, topdownCamera } = await import(join(root, "web/src/index.js"));
const { selectTiles } = await import(join(root, "web/src/tile_select.js"));

const { dir, ts } = await monacoTileset(decalprep, root, work);
const W = 640, H = 360;
const VIEWS = [
  { name: "whole, top-down", topdown: [-3085, -2295, 3493, 1405] },
  { name: "far oblique", eye: [200, -6500, 3000], target: [200, -400, 0], fov: 45, near: 5 },
  { name: "near oblique", eye: [-300, -1500, 250], target: [0, -500, 0], fov: 45, near: 1 },
  { name: "low oblique", eye: [0, -1100, 120], target: [0, -300, 0], fov: 50, near: 1 },
  { name: "close-up, top-down", topdown: [-200, -700, 120, -520] },
];
const viewsPath = join(work, "views.json");
writeFileSync(viewsPath, JSON.stringify(VIEWS));

/** Each tile's decoded blob bytes: the sum of its blob table's raw sizes. */
const blobCache = new Map();
const blobBytes = (/** @type {number} */ level, /** @type {any} */ t) => {
  if (!blobCache.has(t.file)) throw new Error(`blob bytes of ${t.file} asked before they were read`);
  return blobCache.get(t.file);
};
for (const t of [ts.tiles, ...ts.levels.map((l) => l.tiles)].flat()) {
  const pkg = await openPackage(new Uint8Array(readFileSync(join(dir, t.file))), { label: t.file });
  blobCache.set(t.file, pkg.blobs.reduce((s, b) => s + b.rawSize, 0));
}
const camera = (/** @type {any} */ v) => (v.topdown ? topdownCamera(v.topdown, 0, 0)
  : { projection: "perspective", eye: v.eye, target: v.target, up: [0, 0, 1], fovYDeg: v.fov, orthoW: 0, orthoH: 0,
      near: v.near, depthRange: 1e5, topdownExtent: null });

let failures = 0;
const check = (/** @type {boolean} */ ok, /** @type {string} */ what) => {
  console.log((ok ? "ok   " : "FAIL ") + what);
  if (!ok) failures += 1;
};

/** The C++ selection of every view under `budget` (0: none); a view the budget
 * cannot hold has an "error" instead. */
const cppSelection = (/** @type {number} */ budget) => {
  const r = spawnSync(oracle, ["tiles", dir, viewsPath, String(W), String(H), String(budget)], { encoding: "utf8" });
  if (r.status !== 0) throw new Error("view_oracle: " + r.stderr.trim());
  return JSON.parse(r.stdout);
};

const free = cppSelection(0);
// Budgets: none; just below each view's unbounded need, then 97%, 93% and
// 85% of it (the rule coarsens more and more, or refuses where even the
// coarsest tiles need more: Monaco's coarsest level lists its thin lines
// farther out than its children); a third of it; 1 byte (refused).
let coarsenedViews = 0;
for (const [k, v] of VIEWS.entries()) {
  const need = free[k].blob_bytes;
  for (const budget of [0, need - 1, ...[0.97, 0.93, 0.85, 1 / 3].map((f) => Math.floor(f * need)), 1]) {
    const cpp = budget === 0 ? free : cppSelection(budget);
    const name = `${v.name}, budget ${budget === 0 ? "none" : budget}`;
    let js = null, jsError = null;
    try {
      js = selectTiles(ts, camera(v), W, H, 0, 0, budget ? { gpuBudget: budget, blobBytes } : { blobBytes });
    } catch (e) {
      jsError = String(e instanceof Error ? e.message : e);
    }
    const c = cpp[k];
    if (c.error) {
      check(jsError !== null && /gpu-budget/.test(jsError), `${name}: refused by both (C++: ${c.error.slice(0, 90)}; ` +
            `browser: ${jsError ? jsError.slice(0, 90) : "accepted"})`);
      continue;
    }
    if (!js) {
      check(false, `${name}: the browser refused (${jsError}) what C++ drew`);
      continue;
    }
    const cTiles = c.tiles.map((/** @type {number[]} */ t) => t.join(",")).join(" ");
    const jTiles = js.tiles.map((t) => [t.level, t.tile.x, t.tile.y, t.blobBytes].join(",")).join(" ");
    const levels = js.perLevel.map((n, l) => `L${l}:${n}`).join(" ");
    if (js.coarsened > 0) coarsenedViews += 1;
    check(cTiles === jTiles && c.blob_bytes === js.blobBytes && c.package_bytes === js.packageBytes &&
          c.full_detail_bytes === js.fullDetailBytes && c.full_detail_tiles === js.fullDetailTiles &&
          c.coarsened === js.coarsened,
          `${name}: ${js.tiles.length} tiles (${levels}), ${js.packageBytes} of ${js.fullDetailBytes} ` +
          `full-detail package bytes, ${js.blobBytes} blob bytes, ${js.coarsened} coarsened` +
          (cTiles === jTiles ? "" : `\n  C++:     ${cTiles}\n  browser: ${jTiles}`));
  }
}
// The budget's coarsening must have been exercised, not only refusals.
check(coarsenedViews >= 3, `${coarsenedViews} selections coarsened to fit a budget (at least 3)`);

// pixelScale k (what the viewer lowers detail with over its frame budget)
// takes each pixel as k times larger: for the perspective views that is
// the C++ choice of the same view on an image k times smaller each way
// (the footprint depends on the aspect alone); it must draw coarser levels.
let coarser = 0;
for (const k of [2, 4]) {
  const r = spawnSync(oracle, ["tiles", dir, viewsPath, String(W / k), String(H / k), "0"], { encoding: "utf8" });
  if (r.status !== 0) throw new Error("view_oracle: " + r.stderr.trim());
  const small = JSON.parse(r.stdout);
  for (const [i, v] of VIEWS.entries()) {
    if (v.topdown) continue;
    const js = selectTiles(ts, camera(v), W, H, 0, 0, { blobBytes, pixelScale: k });
    const full = selectTiles(ts, camera(v), W, H, 0, 0, { blobBytes });
    const cTiles = small[i].tiles.map((/** @type {number[]} */ t) => t.join(",")).join(" ");
    const jTiles = js.tiles.map((t) => [t.level, t.tile.x, t.tile.y, t.blobBytes].join(",")).join(" ");
    // Coarser: where a tile of the scaled choice meets a tile of the full
    // one, the full one is of its level or finer.
    const meet = (/** @type {number[]} */ a, /** @type {number[]} */ b) => a[0] < b[2] && b[0] < a[2] && a[1] < b[3] && b[1] < a[3];
    const finer = js.tiles.every((t) => full.tiles.every((f) => !meet(t.tile.square, f.tile.square) || f.level <= t.level));
    const levels = (/** @type {any} */ s) => s.perLevel.map((n, l) => `L${l}:${n}`).join(" ");
    if (js.tiles.some((t) => full.tiles.some((f) => meet(t.tile.square, f.tile.square) && f.level < t.level))) coarser += 1;
    check(cTiles === jTiles && finer,
          `${v.name}, pixelScale ${k}: ${js.tiles.length} tiles (${levels(js)}; full detail ${levels(full)}), ` +
          `no finer anywhere, as C++ chooses at ${W / k}x${H / k}` +
          (cTiles === jTiles ? "" : `\n  C++:     ${cTiles}\n  browser: ${jTiles}`));
  }
}
check(coarser >= 3, `${coarser} scaled choices draw a coarser level somewhere than full detail (at least 3)`);
console.log(`${failures} failed`);
process.exit(failures ? 1 : 0);
