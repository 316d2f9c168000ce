// tile_select.js — which tiles of a tileset a view draws: the rule of
// `decalprep render` (libprep/tile/tile_select.cpp, prep/tile.hpp
// select_tiles), in double, so that the browser viewer streams the tiles
// and overview levels `render --gpu-budget` would draw for the same view.
//
// The quadtree of levels is walked from the coarsest level down; a tile of
// level L is drawn when the level's resolution r_L is at most the ground
// size of one pixel at the tile's nearest visible point (its square cut to
// the view's ground footprint and the data's extent, between the terrain's
// zmin and zmax, nearest the eye), else its children with data in view are
// visited. Level 0 always qualifies. With a budget, while the drawn tiles'
// decoded blob bytes exceed it, the drawn children of a tile are replaced by
// the tile, the one with the smallest error in pixels (r_L / pixel) first.

import { cameraBasis, mat4Inverse, matMul, projectionMatrix, viewMatrix } from "./render/camera.js";

/** @typedef {import("./render/camera.js").Camera} Camera */
/** @typedef {import("./tileset.js").Tile} Tile */
/** @typedef {import("./tileset.js").Tileset} Tileset */
/** @typedef {{xmin: number, ymin: number, xmax: number, ymax: number}} Box */

/**
 * The ground footprint of a view (camera.cpp ground_footprint): the box
 * (metres relative to the origin the camera is given in) of what the image
 * sees of the slab zmin..zmax, or null when a corner sees the sky.
 * @param {Camera} c @param {number} width @param {number} height
 * @param {number} zmin @param {number} zmax
 * @returns {Box | null}
 */
export function groundFootprint(c, width, height, zmin, zmax) {
  const top = topdownExtent(c);
  if (top) return top;
  const inv = mat4Inverse(matMul(projectionMatrix(c, width / height), viewMatrix(c, c.eye)));
  const forward = cameraBasis(c).f;
  const b = { xmin: Infinity, ymin: Infinity, xmax: -Infinity, ymax: -Infinity };
  const take = (/** @type {number} */ x, /** @type {number} */ y) => {
    b.xmin = Math.min(b.xmin, x); b.ymin = Math.min(b.ymin, y);
    b.xmax = Math.max(b.xmax, x); b.ymax = Math.max(b.ymax, y);
  };
  // The image's corner rays on the slab: a plane's view through a rectangle
  // is a convex quadrilateral, so its corners bound it.
  for (const nx of [-1, 1])
    for (const ny of [-1, 1]) {
      const v = [nx, ny, 1, 1], r = [0, 0, 0, 0];
      for (let row = 0; row < 4; ++row) for (let k = 0; k < 4; ++k) r[row] += inv[k * 4 + row] * v[k];
      const p = [r[0] / r[3], r[1] / r[3], r[2] / r[3]];
      const persp = c.projection === "perspective";
      const o = persp ? c.eye : p;
      const d = persp ? [p[0] - c.eye[0], p[1] - c.eye[1], p[2] - c.eye[2]] : forward;
      if (!(d[2] < 0)) return null;
      if (o[2] < zmax) take(o[0], o[1]);
      for (const z of [zmin, zmax]) {
        const t = (z - o[2]) / d[2];
        if (!(t > 0)) continue;
        take(o[0] + t * d[0], o[1] + t * d[1]);
      }
    }
  return b.xmax >= b.xmin ? b : null;
}

/**
 * A straight-down orthographic camera's extent (camera.cpp is_topdown), or
 * null.
 * @param {Camera} c
 * @returns {Box | null}
 */
function topdownExtent(c) {
  if (c.projection !== "orthographic") return null;
  const { r, u, f } = cameraBasis(c);
  if (!(Math.abs(f[2] + 1) < 1e-12 && Math.abs(r[0] - 1) < 1e-12 && Math.abs(u[1] - 1) < 1e-12)) return null;
  if (c.topdownExtent) {
    const e = c.topdownExtent;
    return { xmin: e[0], ymin: e[1], xmax: e[2], ymax: e[3] };
  }
  return { xmin: c.eye[0] - 0.5 * c.orthoW, ymin: c.eye[1] - 0.5 * c.orthoH,
    xmax: c.eye[0] + 0.5 * c.orthoW, ymax: c.eye[1] + 0.5 * c.orthoH };
}

/**
 * Ground metres of one pixel at point p (camera.cpp pixel_ground_size).
 * @param {Camera} c @param {number} width @param {number} height @param {number[]} p
 */
export function pixelGroundSize(c, width, height, p) {
  if (c.projection === "orthographic") return Math.min(c.orthoW / width, c.orthoH / height);
  const d = Math.hypot(p[0] - c.eye[0], p[1] - c.eye[1], p[2] - c.eye[2]);
  return (d * 2 * Math.tan((c.fovYDeg * Math.PI) / 360)) / height;
}

/**
 * @typedef {{level: number, tile: Tile, pixel: number, blobBytes: number}} SelectedTile
 * @typedef {{tiles: SelectedTile[], blobBytes: number, packageBytes: number,
 *            fullDetailBytes: number, fullDetailTiles: number, perLevel: number[],
 *            coarsened: number, footprint: Box | null}} TileSelection
 * pixelScale: each pixel's ground size taken this many times larger (1 by
 * default, render's rule; a viewer over its frame budget asks for more to
 * draw coarser levels).
 * @typedef {{gpuBudget?: number, blobBytes?: (level: number, tile: Tile) => number,
 *            level?: number, pixelScale?: number}} TileSelectOptions
 */

/** Half-open square against the view (prep::tiles_in). @param {number[]} sq @param {Box | null} v */
const meets = (sq, v) => !v || (sq[0] < v.xmax && v.xmin < sq[2] && sq[1] < v.ymax && v.ymin < sq[3]);
/** @param {number} v */
const floorHalf = (v) => (v >= 0 ? Math.trunc(v / 2) : -Math.trunc((-v + 1) / 2));
/** @param {number} x @param {number} y */
const keyOf = (x, y) => `${x},${y}`;

/**
 * The tiles of `ts` to draw for `camera` (metres relative to the tileset's
 * frame origin) on a width x height image over terrain between zmin and
 * zmax: prep::render::select_tiles. Throws an Error naming the budget when
 * even the coarsest tiles exceed it (render: exit 9, resource).
 * @param {Tileset} ts @param {Camera} camera @param {number} width @param {number} height
 * @param {number} zmin @param {number} zmax @param {TileSelectOptions} [options]
 * @returns {TileSelection}
 */
export function selectTiles(ts, camera, width, height, zmin, zmax, options = {}) {
  const [ox, oy] = ts.json.frame.origin;
  const ext = ts.json.extent;
  const top = ts.levels.length;
  const tilesOf = (/** @type {number} */ l) => (l === 0 ? ts.tiles : ts.levels[l - 1].tiles);
  const sizeOf = (/** @type {number} */ l) => (l === 0 ? ts.tileSize : ts.levels[l - 1].tileSize);
  const resOf = (/** @type {number} */ l) => (l === 0 ? ts.json.resolution_m ?? 0 : ts.levels[l - 1].resolution);
  const blobOf = (/** @type {number} */ l, /** @type {Tile} */ t) => (options.blobBytes ? options.blobBytes(l, t) : 0);
  if (options.gpuBudget && !options.blobBytes) throw new Error("selectTiles: a gpuBudget needs blobBytes");
  /** @type {TileSelection} */
  const out = { tiles: [], blobBytes: 0, packageBytes: 0, fullDetailBytes: 0, fullDetailTiles: 0,
    perLevel: new Array(top + 1).fill(0), coarsened: 0, footprint: null };
  const f = groundFootprint(camera, width, height, zmin, zmax);
  if (f) out.footprint = { xmin: f.xmin + ox, ymin: f.ymin + oy, xmax: f.xmax + ox, ymax: f.ymax + oy };
  for (const t of ts.tiles)
    if (meets(t.square, out.footprint)) {
      out.fullDetailTiles += 1;
      out.fullDetailBytes += t.bytes;
    }
  // The nearest visible point of a square and its pixel size.
  const pixelOf = (/** @type {number[]} */ sq) => {
    let b = [Math.max(sq[0], ext[0]), Math.max(sq[1], ext[1]), Math.min(sq[2], ext[2]), Math.min(sq[3], ext[3])];
    const v = out.footprint;
    if (v) b = [Math.max(b[0], v.xmin), Math.max(b[1], v.ymin), Math.min(b[2], v.xmax), Math.min(b[3], v.ymax)];
    if (b[0] > b[2] || b[1] > b[3]) b = sq;  // meets only on an edge
    const clamp = (/** @type {number} */ x, /** @type {number} */ lo, /** @type {number} */ hi) =>
      Math.min(Math.max(x, lo), hi);
    const p = [clamp(camera.eye[0], b[0] - ox, b[2] - ox), clamp(camera.eye[1], b[1] - oy, b[3] - oy),
      clamp(camera.eye[2], Math.min(zmin, zmax), Math.max(zmin, zmax))];
    return (options.pixelScale ?? 1) * pixelGroundSize(camera, width, height, p);
  };
  if (options.level !== undefined) {
    const l = options.level;
    if (!(l >= 0 && l <= top)) throw new Error(`--level ${l}: the tileset has levels 0..${top}`);
    for (const t of tilesOf(l))
      if (meets(t.square, out.footprint)) {
        const blob = blobOf(l, t);
        out.tiles.push({ level: l, tile: t, pixel: pixelOf(t.square), blobBytes: blob });
        out.blobBytes += blob;
        out.packageBytes += t.bytes;
        out.perLevel[l] += 1;
      }
    if (options.gpuBudget && out.blobBytes > options.gpuBudget)
      throw new Error(`--gpu-budget ${options.gpuBudget} bytes is exceeded: level ${l} of this view needs ` +
                      `${out.blobBytes} bytes of decoded blobs`);
    return out;
  }
  walkAndCoarsen(out, { top, tilesOf, sizeOf, resOf, blobOf, pixelOf, budget: options.gpuBudget ?? 0 });
  return out;
}

/**
 * The quadtree walk and the budget's coarsening of selectTiles (the
 * Selector of tile_select.cpp).
 * @param {TileSelection} out
 * @param {{top: number, tilesOf: (l: number) => Tile[], sizeOf: (l: number) => number,
 *          resOf: (l: number) => number, blobOf: (l: number, t: Tile) => number,
 *          pixelOf: (sq: number[]) => number, budget: number}} s
 */
function walkAndCoarsen(out, s) {
  /** @type {Map<string, Tile>[]} */
  const entries = [];
  /** @type {Map<string, number[]>[]} */
  const occupied = [];
  for (let l = 0; l <= s.top; ++l) {
    entries.push(new Map());
    occupied.push(new Map());
    for (const t of s.tilesOf(l)) {
      entries[l].set(keyOf(t.x, t.y), t);
      occupied[l].set(keyOf(t.x, t.y), [t.x, t.y]);
    }
    if (l > 0)
      for (const [x, y] of occupied[l - 1].values()) occupied[l].set(keyOf(floorHalf(x), floorHalf(y)), [floorHalf(x), floorHalf(y)]);
  }
  /**
   * @typedef {{level: number, x: number, y: number, square: number[], tile: Tile | null, pixel: number,
   *            sse: number, blob: number | null, parent: number, children: number[], drawn: boolean}} Node
   * @type {Node[]}
   */
  const nodes = [];
  const squareOf = (/** @type {number} */ l, /** @type {number} */ x, /** @type {number} */ y) => {
    const z = s.sizeOf(l);
    return [x * z, y * z, (x + 1) * z, (y + 1) * z];
  };
  const make = (/** @type {number} */ l, /** @type {number} */ x, /** @type {number} */ y, /** @type {number} */ parent) => {
    const tile = entries[l].get(keyOf(x, y)) ?? null;
    const square = tile ? tile.square : squareOf(l, x, y);
    const pixel = s.pixelOf(square);
    nodes.push({ level: l, x, y, square, tile, pixel, sse: pixel > 0 ? s.resOf(l) / pixel : Infinity, blob: null,
      parent, children: [], drawn: false });
    return nodes.length - 1;
  };
  // Keys in increasing (x, y) order, as the C++ std::set walks them.
  const sorted = (/** @type {Map<string, number[]>} */ m) =>
    [...m.values()].sort((a, b) => (a[0] !== b[0] ? a[0] - b[0] : a[1] - b[1]));
  const stack = [];
  for (const [x, y] of sorted(occupied[s.top]))
    if (meets(squareOf(s.top, x, y), out.footprint)) stack.push(make(s.top, x, y, -1));
  const roots = stack.length;
  while (stack.length > 0) {
    const i = /** @type {number} */ (stack.pop());
    const n = nodes[i];
    if (n.level === 0 || s.resOf(n.level) <= n.pixel) {
      n.drawn = true;
      continue;
    }
    for (let cy = 2 * n.y; cy <= 2 * n.y + 1; ++cy)
      for (let cx = 2 * n.x; cx <= 2 * n.x + 1; ++cx) {
        if (!occupied[n.level - 1].has(keyOf(cx, cy)) || !meets(squareOf(n.level - 1, cx, cy), out.footprint)) continue;
        const j = make(n.level - 1, cx, cy, i);
        nodes[i].children.push(j);
        stack.push(j);
      }
  }
  const blobOf = (/** @type {Node} */ n) => {
    if (!n.tile) return 0;
    if (n.blob === null) n.blob = s.blobOf(n.level, n.tile);
    return n.blob;
  };
  const drawnBlob = (/** @type {Node} */ n) => (n.drawn ? blobOf(n) : 0);
  const drawnPackage = (/** @type {Node} */ n) => (n.drawn && n.tile ? n.tile.bytes : 0);
  for (const n of nodes) {
    out.blobBytes += drawnBlob(n);
    out.packageBytes += drawnPackage(n);
  }
  if (s.budget && out.blobBytes > s.budget) {
    const allChildrenDrawn = (/** @type {Node} */ n) =>
      !n.drawn && n.children.length > 0 && n.children.every((c) => nodes[c].drawn);
    // A min-heap by (sse, index), as std::priority_queue with std::greater on pairs.
    /** @type {[number, number][]} */
    const queue = [];
    const less = (/** @type {[number, number]} */ a, /** @type {[number, number]} */ b) => a[0] < b[0] || (a[0] === b[0] && a[1] < b[1]);
    const push = (/** @type {[number, number]} */ item) => {
      queue.push(item);
      for (let k = queue.length - 1; k > 0;) {
        const p = (k - 1) >> 1;
        if (!less(queue[k], queue[p])) break;
        [queue[k], queue[p]] = [queue[p], queue[k]];
        k = p;
      }
    };
    const pop = () => {
      const topItem = queue[0];
      const last = /** @type {[number, number]} */ (queue.pop());
      if (queue.length > 0) {
        queue[0] = last;
        for (let k = 0; ;) {
          const a = 2 * k + 1, b = a + 1;
          let m = k;
          if (a < queue.length && less(queue[a], queue[m])) m = a;
          if (b < queue.length && less(queue[b], queue[m])) m = b;
          if (m === k) break;
          [queue[k], queue[m]] = [queue[m], queue[k]];
          k = m;
        }
      }
      return topItem;
    };
    nodes.forEach((n, i) => { if (allChildrenDrawn(n)) push([n.sse, i]); });
    while (out.blobBytes > s.budget && queue.length > 0) {
      const i = pop()[1];
      const n = nodes[i];
      for (const c of n.children) {
        out.blobBytes -= drawnBlob(nodes[c]);
        out.packageBytes -= drawnPackage(nodes[c]);
        nodes[c].drawn = false;
      }
      n.drawn = true;
      out.blobBytes += drawnBlob(n);
      out.packageBytes += drawnPackage(n);
      out.coarsened += 1;
      if (n.parent >= 0 && allChildrenDrawn(nodes[n.parent])) push([nodes[n.parent].sse, n.parent]);
    }
    if (out.blobBytes > s.budget)
      throw new Error(`--gpu-budget ${s.budget} bytes is exceeded: the coarsest tiles of this view ` +
                      `(level ${s.top}, ${roots} tiles) need ${out.blobBytes} bytes of decoded blobs`);
  }
  for (const n of nodes)
    if (n.drawn && n.tile) {
      out.tiles.push({ level: n.level, tile: n.tile, pixel: n.pixel, blobBytes: n.blob ?? 0 });
      out.perLevel[n.level] += 1;
    }
  out.tiles.sort((a, b) => a.level - b.level || a.tile.x - b.tile.x || a.tile.y - b.tile.y);
}
