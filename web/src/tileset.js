// tileset.js — a reader of tileset.json (formats/SPEC.md "Tilesets",
// "tileset.json", "Overview levels"). It refuses an index that breaks a
// rule of SPEC, naming the field, and opens a tile only at the path its key
// gives, after checking the tile file's size and XXH64 against the index.
import { FormatError } from "./errors.js";
import { openPackage } from "./package.js";
import { bufferSource } from "./source.js";
import { hex64, xxh64 } from "./xxh64.js";

/** Largest tileset.json a reader accepts (SPEC "tileset.json", Limits). */
export const MAX_TILESET_BYTES = 128 * 1024 * 1024;
/** The tileset major version this reader reads. */
export const TILESET_MAJOR = 1;

const MAX_COUNT = 2 ** 53;
const MAX_COORD = 1e12;
const LAYER_FIELDS = ["read", "kept", "repaired", "clipped_away", "dropped", "parts",
  "vertices_in", "vertices_out"];

/**
 * @typedef {object} Tile
 * @property {number} x
 * @property {number} y
 * @property {number} level       0 for the `tiles` array
 * @property {[number, number, number, number]} square
 * @property {[number, number]} origin
 * @property {string} file        relative to the tileset folder
 * @property {number} bytes
 * @property {string} xxh64       16 lowercase hex digits
 * @property {{polygons: number, lines: number, dynamic_lines: number}} counts
 * @property {any[]} layers
 */

/**
 * @typedef {object} Tileset
 * @property {number} major
 * @property {number} minor
 * @property {any} json           the parsed index
 * @property {number} tileSize    tiling.tile_size_m
 * @property {Tile[]} tiles       level 0
 * @property {{level: number, tileSize: number, resolution: number, tiles: Tile[]}[]} levels
 */

/**
 * Parses and checks a tileset.json text (SPEC "tileset.json").
 * @param {Uint8Array | string} input  the file's bytes or text
 * @param {string} [label]  what messages name
 * @returns {Tileset}
 */
export function parseTileset(input, label = "tileset.json") {
  const size = typeof input === "string" ? new TextEncoder().encode(input).length : input.length;
  const bad = (/** @type {string} */ field, /** @type {string} */ why) =>
    new FormatError(`${label}: ${field} ${why}`);
  if (size > MAX_TILESET_BYTES)
    throw new FormatError(`${label}: ${size} bytes is above the reader's limit of ` +
                          `${MAX_TILESET_BYTES} bytes (formats/SPEC.md "tileset.json")`);
  const text = typeof input === "string" ? input : new TextDecoder().decode(input);
  /** @type {any} */
  let j;
  try {
    j = JSON.parse(text);
  } catch (e) {
    throw new FormatError(`${label}: not valid JSON: ${String(e)}`);
  }
  if (!isObject(j)) throw new FormatError(`${label}: not a JSON object`);
  /** @param {any} o @param {string} key @param {string} where */
  const at = (o, key, where) => {
    if (!isObject(o) || !(key in o)) throw bad(where ? `${where}.${key}` : key, "is missing");
    return o[key];
  };
  /** @param {any} v @param {string} field */
  const finite = (v, field) => {
    if (typeof v !== "number" || !Number.isFinite(v) || Math.abs(v) > MAX_COORD)
      throw bad(field, `= ${JSON.stringify(v)} is not a finite number within ±1e12`);
    return v;
  };
  /** @param {any} v @param {string} field */
  const count = (v, field) => {
    if (typeof v !== "number" || !Number.isInteger(v) || v < 0 || v > MAX_COUNT)
      throw bad(field, `= ${JSON.stringify(v)} is not an integer in [0, 2^53]`);
    return v;
  };
  /** @param {any} v @param {string} field */
  const int = (v, field) => {
    if (typeof v !== "number" || !Number.isInteger(v))
      throw bad(field, `= ${JSON.stringify(v)} is not an integer`);
    return v;
  };

  const version = at(j, "tileset_version", "");
  const vm = typeof version === "string" ? /^([1-9][0-9]{0,8}|0)\.([1-9][0-9]{0,8}|0)$/.exec(version) : null;
  if (!vm) throw bad("tileset_version", `'${String(version)}' is not MAJOR.MINOR`);
  const major = Number(vm[1]), minor = Number(vm[2]);
  if (major !== TILESET_MAJOR)
    throw bad("tileset_version", `version ${version} is not supported (this reader: ` +
              `${TILESET_MAJOR}.x)`);
  at(j, "generator", "");
  const frame = at(j, "frame", "");
  if (typeof at(frame, "crs_wkt", "frame") !== "string") throw bad("frame.crs_wkt", "is not a string");
  at(frame, "description", "frame");
  const fo = at(frame, "origin", "frame");
  if (!Array.isArray(fo) || fo.length !== 2) throw bad("frame.origin", "is not [x, y]");
  finite(fo[0], "frame.origin[0]");
  finite(fo[1], "frame.origin[1]");
  const tiling = at(j, "tiling", "");
  if (at(tiling, "scheme", "tiling") !== "grid") throw bad("tiling.scheme", "is not \"grid\"");
  const s = at(tiling, "tile_size_m", "tiling");
  if (typeof s !== "number" || !(s >= 1 && s <= 4000000))
    throw bad("tiling.tile_size_m", `= ${JSON.stringify(s)} is not in [1, 4000000]`);
  for (const k of ["margin_m", "dynamic_margin_m"])
    if (finite(at(tiling, k, "tiling"), `tiling.${k}`) < 0) throw bad(`tiling.${k}`, "is negative");
  const ext = at(j, "extent", "");
  if (!Array.isArray(ext) || ext.length !== 4) throw bad("extent", "is not [xmin, ymin, xmax, ymax]");
  ext.forEach((v, i) => finite(v, `extent[${i}]`));
  if (ext[0] > ext[2] || ext[1] > ext[3]) throw bad("extent", "is inverted");

  const manifest = at(j, "manifest", "");
  const mlayers = at(manifest, "layers", "manifest");
  if (!Array.isArray(mlayers)) throw bad("manifest.layers", "is not an array");
  /** @type {Map<string, number>} kept per layer name */
  const keptByLayer = new Map();
  mlayers.forEach((l, i) => {
    const w = `manifest.layers[${i}]`;
    const c = layerCounts(l, w);
    if (c.read !== c.kept + c.clipped_away + c.dropped)
      throw bad(w, `read ${c.read} != kept ${c.kept} + clipped_away ${c.clipped_away} + ` +
                `dropped ${c.dropped}`);
    if (c.repaired > c.kept) throw bad(w, `repaired ${c.repaired} > kept ${c.kept}`);
    keptByLayer.set(String(l.layer), c.kept);
  });
  if (!Array.isArray(at(manifest, "notes", "manifest"))) throw bad("manifest.notes", "is not an array");
  count(at(manifest, "entry_count", "manifest"), "manifest.entry_count");
  if (at(manifest, "file", "manifest") !== "manifest.json")
    throw bad("manifest.file", "is not \"manifest.json\"");
  count(at(manifest, "bytes", "manifest"), "manifest.bytes");
  hash(at(manifest, "xxh64", "manifest"), "manifest.xxh64");

  /** @param {any} l @param {string} w */
  function layerCounts(l, w) {
    if (!isObject(l)) throw bad(w, "is not an object");
    at(l, "layer", w);
    /** @type {Record<string, number>} */
    const c = {};
    for (const k of LAYER_FIELDS) c[k] = count(at(l, k, w), `${w}.${k}`);
    return c;
  }
  /** @param {any} v @param {string} field */
  function hash(v, field) {
    if (typeof v !== "string" || !/^[0-9a-f]{16}$/.test(v))
      throw bad(field, `= ${JSON.stringify(v)} is not 16 lowercase hex digits`);
    return v;
  }

  /**
   * @param {any} arr @param {string} where @param {number} level @param {number} size
   * @returns {Tile[]}
   */
  function tiles(arr, where, level, size) {
    if (!Array.isArray(arr)) throw bad(where, "is not an array");
    /** @type {Tile[]} */
    const out = [];
    arr.forEach((t, i) => {
      const w = `${where}[${i}]`;
      const x = int(at(t, "x", w), `${w}.x`), y = int(at(t, "y", w), `${w}.y`);
      const prev = out[out.length - 1];
      if (prev && (x < prev.x || (x === prev.x && y <= prev.y)))
        throw bad(w, `(${x}, ${y}) is not after (${prev.x}, ${prev.y}) (sorted by x, then y, unique)`);
      const want = [x * size, y * size, (x + 1) * size, (y + 1) * size];
      const sq = at(t, "square", w);
      if (!Array.isArray(sq) || sq.length !== 4 || sq.some((v, k) => v !== want[k]))
        throw bad(`${w}.square`, "does not match the tile's key and the tile size");
      const o = at(t, "origin", w);
      if (!Array.isArray(o) || o.length !== 2 || o[0] !== (x + 0.5) * size ||
          o[1] !== (y + 0.5) * size)
        throw bad(`${w}.origin`, "is not the centre of the tile's square");
      const file = level === 0 ? `tiles/x${x}_y${y}.decals` : `tiles/L${level}/x${x}_y${y}.decals`;
      if (at(t, "file", w) !== file) throw bad(`${w}.file`, `is not "${file}"`);
      const bytes = count(at(t, "bytes", w), `${w}.bytes`);
      const h = hash(at(t, "xxh64", w), `${w}.xxh64`);
      const cs = at(t, "counts", w);
      const counts = {
        polygons: count(at(cs, "polygons", `${w}.counts`), `${w}.counts.polygons`),
        lines: count(at(cs, "lines", `${w}.counts`), `${w}.counts.lines`),
        dynamic_lines: count(at(cs, "dynamic_lines", `${w}.counts`), `${w}.counts.dynamic_lines`),
      };
      const layers = at(t, "layers", w);
      if (!Array.isArray(layers)) throw bad(`${w}.layers`, "is not an array");
      layers.forEach((l, k) => {
        const lw = `${w}.layers[${k}]`;
        const c = layerCounts(l, lw);
        if (c.read !== c.kept || c.clipped_away !== 0 || c.dropped !== 0)
          throw bad(lw, "must have read = kept and no clipped_away or dropped");
        const kept = keptByLayer.get(String(l.layer));
        if (kept === undefined) throw bad(`${lw}.layer`, `${JSON.stringify(l.layer)} is not a layer of manifest.layers`);
        if (c.kept > kept) throw bad(`${lw}.kept`, `${c.kept} is more than manifest.layers says were kept (${kept})`);
      });
      out.push({ x, y, level, square: /** @type {any} */ (want), origin: [(x + 0.5) * size, (y + 0.5) * size],
        file, bytes, xxh64: h, counts, layers });
    });
    return out;
  }

  const level0 = tiles(at(j, "tiles", ""), "tiles", 0, s);
  // The level-0 tiles together keep at least what the manifest says was kept.
  /** @type {Map<string, number>} */
  const sum = new Map();
  for (const t of level0)
    for (const l of t.layers) sum.set(String(l.layer), (sum.get(String(l.layer)) ?? 0) + l.kept);
  for (const [layer, kept] of keptByLayer)
    if ((sum.get(layer) ?? 0) < kept)
      throw bad("tiles", `keep ${sum.get(layer) ?? 0} features of layer ${JSON.stringify(layer)}, ` +
                `manifest.layers says ${kept} were kept`);
  /** @type {Tileset["levels"]} */
  const levels = [];
  if (minor >= 1) {
    const r = finite(at(j, "resolution_m", ""), "resolution_m");
    if (r < 0) throw bad("resolution_m", "is negative");
    const lv = at(j, "levels", "");
    if (!Array.isArray(lv)) throw bad("levels", "is not an array");
    lv.forEach((l, i) => {
      const w = `levels[${i}]`;
      if (at(l, "level", w) !== i + 1) throw bad(`${w}.level`, `is not ${i + 1}`);
      const size = s * 2 ** (i + 1);
      if (at(l, "tile_size_m", w) !== size || size > 4000000)
        throw bad(`${w}.tile_size_m`, `is not ${size} (tiling.tile_size_m x 2^${i + 1}, at most 4000000)`);
      const res = finite(at(l, "resolution_m", w), `${w}.resolution_m`);
      levels.push({ level: i + 1, tileSize: size, resolution: res, tiles: tiles(at(l, "tiles", w), `${w}.tiles`, i + 1, size) });
    });
  }
  return { major, minor, json: j, tileSize: s, tiles: level0, levels };
}

/** @param {unknown} v @returns {v is Record<string, any>} */
function isObject(v) {
  return typeof v === "object" && v !== null && !Array.isArray(v);
}

/**
 * Fetches and checks a tileset.json from a URL.
 * @param {string} url
 * @param {{fetch?: typeof fetch}} [options]
 */
export async function fetchTileset(url, options = {}) {
  const get = options.fetch ?? globalThis.fetch;
  const res = await get(url);
  if (!res.ok) throw new Error(`${url}: HTTP ${res.status}`);
  const len = Number(res.headers.get("Content-Length") ?? "0");
  if (len > MAX_TILESET_BYTES)
    throw new FormatError(`${url}: ${len} bytes is above the reader's limit of ` +
                          `${MAX_TILESET_BYTES} bytes (formats/SPEC.md "tileset.json")`);
  return parseTileset(new Uint8Array(await res.arrayBuffer()), url);
}

/**
 * Opens one tile's package: fetches the whole file at the path its key
 * gives (relative to `baseUrl`, the tileset folder's URL) with one Range
 * request of the size the index gives (a server that ignores Range answers
 * 200 with the whole file, which is taken too), checks its size and XXH64
 * against the index, then opens it as a package.
 * @param {string} baseUrl  the folder URL, ending in "/"
 * @param {Tile} tile
 * @param {{fetch?: typeof fetch}} [options]
 */
export async function openTile(baseUrl, tile, options = {}) {
  const get = options.fetch ?? globalThis.fetch;
  const url = new URL(tile.file, baseUrl).href;
  const res = await get(url, { headers: { Range: `bytes=0-${Math.max(0, tile.bytes - 1)}` } });
  if (!res.ok) throw new Error(`${url}: HTTP ${res.status}`);
  const bytes = new Uint8Array(await res.arrayBuffer());
  if (res.status === 206) {
    const m = /^bytes 0-(\d+)\/(\d+)$/.exec(res.headers.get("Content-Range") ?? "");
    if (!m || Number(m[2]) !== tile.bytes)
      throw new FormatError(`${url}: Content-Range '${res.headers.get("Content-Range")}', tileset.json says ` +
                            `${tile.bytes} bytes`);
  }
  if (bytes.length !== tile.bytes)
    throw new FormatError(`${url}: ${bytes.length} bytes, tileset.json says ${tile.bytes}`);
  const h = hex64(await xxh64(bytes));
  if (h !== tile.xxh64)
    throw new FormatError(`${url}: xxh64 ${h}, tileset.json says ${tile.xxh64}`);
  return openPackage(bufferSource(bytes, url));
}
