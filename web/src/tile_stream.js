// tile_stream.js — a tileset streamed for a moving view: each view's tiles
// and overview levels chosen by selectTiles (tile_select.js, the rule of
// `decalprep render`), fetched in the background and held by a TileCache
// (tile_cache.js: coarser levels first, a loaded coarser tile standing in
// where a chosen one has not arrived, least recently drawn evicted), and
// handed to the renderer as the tiles of its frame (render/index.js
// FrameTile: offsets and squares relative to the tileset's frame origin,
// the frame the camera is given in).

import { selectTiles } from "./tile_select.js";
import { TileCache } from "./tile_cache.js";
import { openTile } from "./tileset.js";
import { openPackage } from "./package.js";
import { urlSource } from "./source.js";

/** @typedef {import("./tileset.js").Tileset} Tileset */
/** @typedef {import("./tileset.js").Tile} Tile */
/** @typedef {import("./render/camera.js").Camera} Camera */
/** @typedef {import("./render/index.js").FrameTile} FrameTile */
/** @typedef {import("./tile_select.js").TileSelection} TileSelection */

export class TileStream {
  /**
   * @param {{tileset: Tileset, baseUrl: string, maxBytes: number, concurrency?: number, gpuBudget?: number,
   *          onLoaded?: () => void}} options
   *   maxBytes: the decoded blob bytes the loaded tiles may hold; gpuBudget:
   *   each view's tiles coarsened until their decoded blob bytes fit, as
   *   `render --gpu-budget` (0: none; the tiles' sizes come from their
   *   headers, one Range read each, or from the tiles once loaded);
   *   onLoaded: called as each tile arrives (to draw again).
   */
  constructor(options) {
    this.tileset = options.tileset;
    this.baseUrl = options.baseUrl;
    this.gpuBudget = options.gpuBudget ?? 0;
    /** @type {Map<string, number>} decoded blob bytes by tile file */
    this.sizes = new Map();
    /** header reads made for the budget */
    this.headerReads = 0;
    /** @type {(() => void)[]} */
    this.waiters = [];
    const onLoaded = options.onLoaded ?? (() => {});
    const open = async (/** @type {string} */ base, /** @type {Tile} */ t) => {
      const pkg = await openTile(base, t);
      this.sizes.set(t.file, pkg.blobs.reduce((s, b) => s + b.rawSize, 0));
      return pkg;
    };
    this.cache = new TileCache({ tileset: options.tileset, baseUrl: options.baseUrl, maxBytes: options.maxBytes,
      concurrency: options.concurrency, open, onLoaded: () => {
        if (this.idle()) for (const w of this.waiters.splice(0)) w();
        onLoaded();
      } });
    const [ox, oy] = this.tileset.json.frame.origin;
    /** The tileset's frame origin (absolute frame CRS metres). */
    this.origin = [ox, oy];
    /** @type {TileSelection | null} the last view's choice */
    this.selection = null;
  }

  /** The data's extent relative to the frame origin ([xmin, ymin, xmax, ymax], metres). */
  extent() {
    const e = this.tileset.json.extent, [ox, oy] = this.origin;
    return [e[0] - ox, e[1] - oy, e[2] - ox, e[3] - oy];
  }

  /**
   * A view: its tiles chosen (selectTiles with `options`; pixelScale > 1
   * asks for coarser levels, as if each pixel were that much larger: what
   * a viewer over its frame budget lowers detail with), the ones not loaded
   * queued, and the tiles to draw now (loaded ones, and stand-ins).
   * @param {Camera} camera  metres relative to the frame origin
   * @param {number} width @param {number} height
   * @param {number} zmin @param {number} zmax  the terrain's height range
   * @param {import("./tile_select.js").TileSelectOptions & {fetch?: boolean}} [options]
   *   fetch: false draws what is loaded without queueing the view's tiles
   * @returns {Promise<{selection: TileSelection, tiles: FrameTile[], standIns: number}>}
   */
  async view(camera, width, height, zmin, zmax, options = {}) {
    const selection = await this.choose(camera, width, height, zmin, zmax, options);
    this.selection = selection;
    if (options.fetch !== false) this.cache.want(selection.tiles);
    const [ox, oy] = this.origin;
    const list = this.cache.drawList(selection.tiles);
    return {
      selection,
      standIns: list.filter((d) => d.standIn).length,
      tiles: list.map((d) => ({
        key: `${d.level}/${d.tile.x},${d.tile.y}`, pkg: d.pkg, dx: d.tile.origin[0] - ox, dy: d.tile.origin[1] - oy,
        square: [d.tile.square[0] - ox, d.tile.square[1] - oy, d.tile.square[2] - ox, d.tile.square[3] - oy],
        clips: d.clips.map((c) => [c[0] - ox, c[1] - oy, c[2] - ox, c[3] - oy]),
      })),
    };
  }

  /**
   * selectTiles, under the GPU budget when there is one: the choice is
   * made again after reading the sizes of the tiles it asked about that are
   * not known yet, until it asks about none.
   * @param {Camera} camera @param {number} width @param {number} height
   * @param {number} zmin @param {number} zmax @param {import("./tile_select.js").TileSelectOptions} options
   */
  async choose(camera, width, height, zmin, zmax, options) {
    if (!this.gpuBudget) return selectTiles(this.tileset, camera, width, height, zmin, zmax, options);
    for (;;) {
      /** @type {Map<string, Tile>} */
      const missing = new Map();
      const blobBytes = (/** @type {number} */ _level, /** @type {Tile} */ t) => {
        const b = this.sizes.get(t.file);
        if (b !== undefined) return b;
        missing.set(t.file, t);
        return 0;
      };
      const sel = selectTiles(this.tileset, camera, width, height, zmin, zmax,
        { ...options, gpuBudget: this.gpuBudget, blobBytes });
      if (missing.size === 0) return sel;
      await this.readSizes([...missing.values()]);
    }
  }

  /**
   * The decoded blob bytes of `tiles` from their headers and blob tables
   * (Range reads; the package's checks of those parts), six at a time.
   * @param {Tile[]} tiles
   */
  async readSizes(tiles) {
    const queue = [...tiles];
    const worker = async () => {
      for (let t = queue.pop(); t; t = queue.pop()) {
        const pkg = await openPackage(await urlSource(new URL(t.file, this.baseUrl).href));
        this.headerReads += 1;
        this.sizes.set(t.file, pkg.blobs.reduce((s, b) => s + b.rawSize, 0));
      }
    };
    await Promise.all(Array.from({ length: Math.min(6, queue.length) }, worker));
  }

  /**
   * Fetches the tiles of `level` whose squares meet the squares of
   * `chosen` (what stands in for them, or fills them, before they arrive).
   * @param {import("./tile_select.js").SelectedTile[]} chosen @param {number} level
   */
  async fetchLevel(chosen, level) {
    const tiles = level === 0 ? this.tileset.tiles : this.tileset.levels[level - 1]?.tiles;
    if (!tiles) throw new Error(`level ${level}: the tileset has levels 0..${this.tileset.levels.length}`);
    const meet = (/** @type {number[]} */ a, /** @type {number[]} */ b) =>
      a[0] < b[2] && b[0] < a[2] && a[1] < b[3] && b[1] < a[3];
    const want = tiles.filter((t) => chosen.some((c) => meet(c.tile.square, t.square)));
    this.cache.want(want.map((tile) => ({ level, tile, pixel: 0, blobBytes: 0 })));
    await this.settled();
  }

  /** Whether no fetch is queued or in flight. */
  idle() {
    return this.cache.queue.size === 0 && this.cache.inFlight.size === 0;
  }

  /** Resolves once no fetch is queued or in flight. @returns {Promise<void>} */
  settled() {
    if (this.idle()) return Promise.resolve();
    return new Promise((resolve) => this.waiters.push(resolve));
  }
}
