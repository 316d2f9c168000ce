// tile_cache.js — the tiles a streaming viewer holds: fetched in the
// background, at most `concurrency` at a time (coarser levels first, so a
// coarse cover arrives before the detail), drawn as they arrive, with a
// loaded coarser tile standing in for a chosen tile that has not arrived
// (clipped to the squares it stands in for, so a view never shows a hole
// where a coarser level is loaded; finer tiles of an earlier view cover what
// they can where nothing coarser is), and evicted least recently drawn first
// once their decoded blob bytes pass a budget. The tiles to want come from
// selectTiles (tile_select.js).

import { openTile } from "./tileset.js";

/** @typedef {import("./tileset.js").Tile} Tile */
/** @typedef {import("./tileset.js").Tileset} Tileset */
/** @typedef {import("./tile_select.js").SelectedTile} SelectedTile */
/** @typedef {import("./package.js").Package} Package */

/** @param {number} v */
const floorHalf = (v) => (v >= 0 ? Math.trunc(v / 2) : -Math.trunc((-v + 1) / 2));
/** @param {number} level @param {number} x @param {number} y */
const keyOf = (level, x, y) => `${level}/${x},${y}`;

/**
 * What to draw: a loaded tile and the squares (absolute frame coordinates)
 * it is drawn in: its own square when it was chosen, else the squares of
 * the chosen tiles it stands in for.
 * @typedef {{level: number, tile: Tile, pkg: Package, clips: number[][], standIn: boolean}} DrawTile
 */

export class TileCache {
  /**
   * @param {{tileset: Tileset, baseUrl: string, maxBytes: number, concurrency?: number,
   *          open?: (baseUrl: string, tile: Tile) => Promise<Package>,
   *          onLoaded?: () => void}} options
   *   maxBytes: decoded blob bytes the loaded tiles may hold (the GPU budget);
   *   open: how a tile is fetched and opened (openTile: one GET of the file,
   *   its size and XXH64 checked against the index); onLoaded: called when a
   *   tile arrives (to draw again).
   */
  constructor(options) {
    this.tileset = options.tileset;
    this.baseUrl = options.baseUrl;
    this.maxBytes = options.maxBytes;
    this.concurrency = options.concurrency ?? 4;
    this.open = options.open ?? ((base, t) => openTile(base, t));
    this.onLoaded = options.onLoaded ?? (() => {});
    /** @type {Map<string, {level: number, tile: Tile, pkg: Package, bytes: number, used: number}>} */
    this.loaded = new Map();
    /** @type {Map<string, {level: number, tile: Tile}>} wanted, not started, by key */
    this.queue = new Map();
    /** @type {Set<string>} */
    this.inFlight = new Set();
    /** @type {Map<string, Tile>[]} per level: the index's tiles by x,y */
    this.byLevel = [this.tileset.tiles, ...this.tileset.levels.map((l) => l.tiles)].map((tiles) =>
      new Map(tiles.map((t) => [`${t.x},${t.y}`, t])));
    this.frame = 0;
    this.loadedBytes = 0;
    /** requests started, package bytes fetched, tiles evicted, failures (the last error kept) */
    this.stats = { requests: 0, bytes: 0, evicted: 0, failed: 0, lastError: "" };
  }

  /**
   * A new view's choice: every chosen tile not loaded is queued (replacing
   * the previous view's queue, so tiles the view left are not fetched),
   * coarser levels first; fetches start up to the concurrency.
   * @param {SelectedTile[]} chosen
   */
  want(chosen) {
    this.queue.clear();
    const sorted = [...chosen].sort((a, b) => b.level - a.level || a.pixel - b.pixel);
    for (const s of sorted) {
      const k = keyOf(s.level, s.tile.x, s.tile.y);
      if (!this.loaded.has(k) && !this.inFlight.has(k)) this.queue.set(k, { level: s.level, tile: s.tile });
    }
    this.pump();
  }

  /** Starts queued fetches while fewer than `concurrency` are in flight. */
  pump() {
    for (const [k, w] of this.queue) {
      if (this.inFlight.size >= this.concurrency) return;
      this.queue.delete(k);
      this.inFlight.add(k);
      this.stats.requests += 1;
      this.open(this.baseUrl, w.tile).then((pkg) => {
        const bytes = pkg.blobs.reduce((s, b) => s + b.rawSize, 0);
        this.loaded.set(k, { level: w.level, tile: w.tile, pkg, bytes, used: this.frame });
        this.loadedBytes += bytes;
        this.stats.bytes += w.tile.bytes;
      }, (e) => {
        this.stats.failed += 1;
        this.stats.lastError = String(e instanceof Error ? e.message : e);
      }).finally(() => {
        this.inFlight.delete(k);
        this.pump();
        this.onLoaded();
      });
    }
  }

  /**
   * The tiles to draw for a view's choice now: each chosen tile that is
   * loaded, and for each one that is not, its nearest loaded coarser tile,
   * drawn only in the chosen squares it stands in for. A chosen tile with no
   * loaded tile above it is not drawn yet (nothing coarser has arrived).
   * Marks what it returns as drawn in this frame, then evicts: least
   * recently drawn first, never a tile of this frame, until the loaded
   * tiles' decoded bytes are within maxBytes.
   * @param {SelectedTile[]} chosen
   * @returns {DrawTile[]}
   */
  drawList(chosen) {
    this.frame += 1;
    /** @type {Map<string, DrawTile>} */
    const out = new Map();
    const top = this.byLevel.length - 1;
    for (const s of chosen) {
      const own = keyOf(s.level, s.tile.x, s.tile.y);
      let hit = this.loaded.get(own);
      let x = s.tile.x, y = s.tile.y;
      for (let l = s.level + 1; !hit && l <= top; ++l) {
        x = floorHalf(x);
        y = floorHalf(y);
        if (this.byLevel[l].has(`${x},${y}`)) hit = this.loaded.get(keyOf(l, x, y));
      }
      if (hit) {
        this.add(out, hit, s.tile.square, own);
        continue;
      }
      // Nothing coarser: finer tiles loaded for an earlier view cover what
      // they can of the square.
      const sq = s.tile.square;
      for (const v of this.loaded.values()) {
        const t = v.tile.square;
        if (v.level < s.level && t[0] >= sq[0] && t[2] <= sq[2] && t[1] >= sq[1] && t[3] <= sq[3])
          this.add(out, v, t, own);
      }
    }
    this.evict();
    return [...out.values()];
  }

  /**
   * Draws loaded tile `v` in `clip` for the chosen tile whose key is `own`.
   * @param {Map<string, DrawTile>} out
   * @param {{level: number, tile: Tile, pkg: Package, used: number}} v
   * @param {number[]} clip @param {string} own
   */
  add(out, v, clip, own) {
    const k = keyOf(v.level, v.tile.x, v.tile.y);
    v.used = this.frame;
    const d = out.get(k) ?? { level: v.level, tile: v.tile, pkg: v.pkg, clips: [], standIn: k !== own };
    d.clips.push(clip);
    out.set(k, d);
  }

  /** Least recently drawn first, never one drawn in the current frame. */
  evict() {
    if (this.loadedBytes <= this.maxBytes) return;
    const old = [...this.loaded.entries()].filter(([, v]) => v.used < this.frame).sort((a, b) => a[1].used - b[1].used);
    for (const [k, v] of old) {
      if (this.loadedBytes <= this.maxBytes) return;
      this.loaded.delete(k);
      this.loadedBytes -= v.bytes;
      this.stats.evicted += 1;
    }
  }
}
