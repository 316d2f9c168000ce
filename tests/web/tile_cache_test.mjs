#!/usr/bin/env node
// tile_cache_test.mjs — the streaming viewer's tile cache (web/src/tile_cache.js)
// on the Monaco sample built as a 500 m tileset with --levels auto, with the
// views' tiles chosen by selectTiles and the fetches held back by the test
// (a stand-in `open` that resolves when told), so that every moment of the
// stream is checked:
//   - nothing is drawn before anything arrives; arrived tiles are drawn;
//   - zooming in, every chosen tile is covered by itself or by a loaded
//     coarser tile clipped to exactly the chosen squares (no hole, no
//     overlap), and coarser levels are fetched first;
//   - a tile is fetched once while it is held; a new view drops the old
//     view's queue; eviction goes least recently drawn first, never a tile
//     of the current frame, and keeps the loaded bytes within the budget;
//   - zooming out after the coarse tiles were evicted, the finer tiles still
//     held cover their part of the view.
//
//   node tests/web/tile_cache_test.mjs DECALPREP REPO_ROOT WORK_DIR
import { execFileSync } from "node:child_process";
import { mkdirSync, readFileSync, rmSync } from "node:fs";
import { join } from "node:path";

const [decalprep, root, work] = process.argv.slice(2);
if (!work) {
  console.error("usage: tile_cache_test.mjs DECALPREP REPO_ROOT WORK_DIR");
  process.exit(2);
}
const { parseTileset, topdownCamera } = await import(join(root, "web/src/index.js"));
const { selectTiles } = await import(join(root, "web/src/tile_select.js"));
const { TileCache } = await import(join(root, "web/src/tile_cache.js"));

rmSync(work, { recursive: true, force: true });
mkdirSync(work, { recursive: true });
const dir = join(work, "monaco");
execFileSync(decalprep, ["build", join(root, "samples/monaco/scene.toml"), "-o", dir, "--tile-size", "500",
  "--levels", "auto", "-q"], { stdio: "inherit" });
const ts = parseTileset(readFileSync(join(dir, "tileset.json"), "utf8"));
const W = 640, H = 360;
const persp = (/** @type {number[]} */ eye, /** @type {number[]} */ target) => ({ projection: "perspective", eye, target,
  up: [0, 0, 1], fovYDeg: 45, orthoW: 0, orthoH: 0, near: 1, depthRange: 1e5, topdownExtent: null });
const choose = (/** @type {any} */ cam) => selectTiles(ts, cam, W, H, 0, 0).tiles;
const whole = choose(topdownCamera([-3085, -2295, 3493, 1405], 0, 0));
const near = choose(persp([-300, -1500, 250], [0, -500, 0]));
const low = choose(persp([0, -1100, 120], [0, -300, 0]));

let failures = 0;
const check = (/** @type {boolean} */ ok, /** @type {string} */ what) => {
  console.log((ok ? "ok   " : "FAIL ") + what);
  if (!ok) failures += 1;
};

// The stand-in fetch: each request waits until the test releases it.
/** @type {Map<string, () => void>} */
const held = new Map();
/** @type {string[]} */
const order = [];
const open = (/** @type {string} */ _base, /** @type {any} */ t) => new Promise((resolve) => {
  order.push(t.file);
  held.set(t.file, () => resolve({ blobs: [{ rawSize: 3 * t.bytes }] }));
});
const settle = () => new Promise((r) => setTimeout(r, 0));
const release = async (/** @type {(f: string) => boolean} */ which) => {
  for (const [f, go] of [...held]) if (which(f)) { held.delete(f); go(); }
  for (let i = 0; i < 5; ++i) await settle();
};
/** Releases every fetch, and those they start, until none is held. */
const drain = async () => {
  while (held.size > 0) await release(() => true);
};
const levelOf = (/** @type {string} */ f) => Number(/\/L(\d+)\//.exec(f)?.[1] ?? 0);
const sq = (/** @type {number[]} */ s) => s.join(",");
/** Every chosen square covered exactly once by the clips, and nothing else. */
const covers = (/** @type {any[]} */ list, /** @type {any[]} */ chosen) => {
  const clips = list.flatMap((d) => d.clips.map(sq)).sort();
  return JSON.stringify(clips) === JSON.stringify(chosen.map((c) => sq(c.tile.square)).sort());
};

const wholeBytes = whole.reduce((s, c) => s + 3 * c.tile.bytes, 0);
const nearBytes = near.reduce((s, c) => s + 3 * c.tile.bytes, 0);
// Room for the near view and a little more, not for the whole view's tiles too.
const cache = new TileCache({ tileset: ts, baseUrl: "http://x/", maxBytes: nearBytes + 1, concurrency: 4, open });

// 1. The whole extent from above: the coarsest level.
cache.want(whole);
check(cache.drawList(whole).length === 0, `whole view: nothing drawn before a tile arrives (${whole.length} chosen, ` +
      `${cache.stats.requests} requests started, at most 4 at a time)`);
await release((f) => f === whole[0].tile.file);
const first = cache.drawList(whole);
check(first.length === 1 && !first[0].standIn && first[0].tile === whole[0].tile, "whole view: the tile that arrived is drawn alone");
await drain();
const all = cache.drawList(whole);
check(all.length === whole.length && covers(all, whole) && all.every((d) => !d.standIn),
      `whole view: all ${whole.length} chosen tiles drawn once arrived; ${cache.stats.requests} requests`);

// 2. Zoom in: the coarse tiles stand in, clipped to the chosen squares.
const before = cache.stats.requests;
cache.want(near);
const levels = near.map((c) => c.level);
const firstFetched = order.slice(before, before + 4).map(levelOf);
check(firstFetched.every((l) => l === Math.max(...levels)),
      `near view: the first fetches are of the coarsest chosen level (${firstFetched.join(", ")})`);
const standIn = cache.drawList(near);
check(standIn.length > 0 && standIn.every((d) => d.standIn) && covers(standIn, near),
      `near view: before any of its ${near.length} tiles arrives, ${standIn.length} loaded coarser tiles cover ` +
      "exactly its squares (no hole, no overlap)");
await release((f) => levelOf(f) === 2);
const mixed = cache.drawList(near);
check(covers(mixed, near) && mixed.some((d) => !d.standIn) && mixed.some((d) => d.standIn),
      `near view: with level 2 arrived, ${mixed.filter((d) => !d.standIn).length} own tiles and ` +
      `${mixed.filter((d) => d.standIn).length} stand-ins still cover it exactly`);
await drain();
const done = cache.drawList(near);
check(done.length === near.length && done.every((d) => !d.standIn) && covers(done, near),
      `near view: all ${near.length} own tiles drawn; ${cache.stats.requests - before} requests for them`);
check(cache.loadedBytes <= cache.maxBytes && cache.stats.evicted >= whole.length - 1,
      `eviction: ${cache.loadedBytes} of at most ${cache.maxBytes} bytes held, ${cache.stats.evicted} evicted ` +
      "(the whole view's coarse tiles, drawn least recently)");
check(done.every((d) => cache.loaded.has(`${d.level}/${d.tile.x},${d.tile.y}`)), "eviction: no tile of the current frame evicted");

// 3. Held tiles are not fetched again; a new view drops the old queue.
const r0 = cache.stats.requests;
cache.want(near);
check(cache.stats.requests === r0, "the same view again: no request");
const slow = new TileCache({ tileset: ts, baseUrl: "http://x/", maxBytes: 1e12, concurrency: 1, open });
const o0 = order.length;
slow.want(near);
slow.want(whole);
await drain();
const fetched = order.slice(o0);
check(fetched.length === 1 + whole.length && fetched.slice(1).every((f) => whole.some((c) => c.tile.file === f)),
      `a new view drops the old queue: ${fetched.length} fetches (1 of the old view in flight, ${whole.length} of the new)`);

// 4. Zoom out after the coarse tiles were evicted: the finer tiles cover their part.
const out = cache.drawList(whole);
const covered = out.filter((d) => !d.standIn).length === 0 && out.length > 0 &&
  out.every((d) => d.level < 3 && d.clips.every((c) => sq(c) === sq(d.tile.square)));
check(covered, `zoomed out with level 3 evicted: ${out.length} finer tiles held draw in their own squares meanwhile`);
check(wholeBytes > 0 && cache.stats.failed === 0, `no fetch failed; ${cache.stats.requests} requests, ${cache.stats.bytes} package bytes`);

console.log(`${failures} failed`);
process.exit(failures ? 1 : 0);
