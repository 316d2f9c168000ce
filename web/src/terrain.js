// terrain.js — a reader of terrain files (formats/SPEC.md "Terrain files"):
// the heightfield mesh `decalprep render` draws, written beside a package
// as STEM.terrain by `decalprep terrain`. It treats every file as hostile:
// each field is checked, in the order of SPEC "Terrain files"
// (Validation), before it is used, and a bad file is refused with a
// FormatError naming the field and the bad value.
//
// Synchronous: the checksums use xxhash-wasm's synchronous hash
// (xxh64.js, instantiated when the module loads) and fzstd decodes in place.
import { FormatError } from "./errors.js";
import { xxh64Sync } from "./xxh64.js";
import { decodeZstdFrame } from "./zstd.js";

/**
 * The mesh render draws: vertex (i, j) at (x0 + i dx, y0 + j dy), metres
 * relative to the package origin, height z[i + nx j]; cell (i, j) splits
 * into the triangles (00, 10, 11) and (00, 11, 01).
 * @typedef {{
 *   x0: number, y0: number,
 *   dx: number, dy: number,
 *   nx: number, ny: number,
 *   z: Float64Array,
 *   zmin: number, zmax: number,
 *   surfaceErrorBound: number,
 *   origin: [number, number],
 *   sourceXxh64: string
 * }} Terrain
 */

export const TERRAIN_MAGIC = Object.freeze([0x89, 0x44, 0x54, 0x52, 0x0d, 0x0a, 0x1a, 0x0a]);
export const TERRAIN_VERSION_MAJOR = 1;
export const TERRAIN_VERSION_MINOR = 0;
export const TERRAIN_HEADER_SIZE = 144;
export const TERRAIN_MAX_SIDE = 16384;
export const TERRAIN_MAX_VERTICES = 16777216;
const MAX_METRES = 1e12;
const CODEC_NONE = 0, CODEC_ZSTD = 1;

// --------------------------------------------------------------- reader --

/**
 * Parses and checks a terrain file (SPEC "Terrain files", Validation, in
 * its order). Throws FormatError "<label>: <field>: <why>".
 * @param {ArrayBuffer | Uint8Array} input
 * @param {string} [label]
 * @returns {Terrain}
 */
export function parseTerrain(input, label = "terrain file") {
  const b = input instanceof Uint8Array ? input : new Uint8Array(input);
  const dv = new DataView(b.buffer, b.byteOffset, b.byteLength);
  /** @param {string} what */
  const bad = (what) => new FormatError(`${label}: ${what}`);
  // 1. Magic. 2. Version. 3. Header size and checksum. 4. File size.
  if (b.length < 8 || TERRAIN_MAGIC.some((v, k) => b[k] !== v))
    throw bad("magic: not a terrain file (the first 8 bytes are not 89 44 54 52 0d 0a 1a 0a)");
  if (b.length < 16)
    throw bad(`header: truncated, ${b.length} bytes (the header has ${TERRAIN_HEADER_SIZE})`);
  const major = dv.getUint16(8, true), minor = dv.getUint16(10, true);
  if (major !== TERRAIN_VERSION_MAJOR)
    throw bad(`version_major: unsupported terrain file version ${major}.${minor}; ` +
              "this reader reads major version 1");
  const header = dv.getUint32(12, true);
  if (header < TERRAIN_HEADER_SIZE || header % 8 !== 0)
    throw bad(`header_size: ${header} (at least 144, a multiple of 8)`);
  if (header > b.length)
    throw bad(`header_size: ${header} bytes, but the file holds ${b.length} (truncated)`);
  if (dv.getBigUint64(header - 8, true) !== xxh64Sync(b.subarray(0, header - 8)))
    throw bad("header_checksum: mismatch (the header is damaged)");
  const fileSize = dv.getBigUint64(32, true);
  if (fileSize !== BigInt(b.length))
    throw bad(`file_size: ${fileSize}, but the file holds ${b.length} bytes`);
  // 5. Flags and the bytes of a newer minor.
  const flags = dv.getUint32(16, true);
  if (flags & 0xffff) throw bad(`flags: ${flags} sets a required flag this reader does not know`);
  if (minor <= TERRAIN_VERSION_MINOR) {
    if (flags) throw bad(`flags: ${flags} (no flag is defined in version 1.0)`);
    for (let k = 136; k + 8 < header; ++k)
      if (b[k]) throw bad(`header: byte ${k} beyond the 1.0 fields is not zero`);
  }
  // 6. Codec, sizes, numbers.
  const codec = dv.getUint32(20, true);
  if (codec !== CODEC_NONE && codec !== CODEC_ZSTD) throw bad(`codec: ${codec} (0 none or 1 zstd)`);
  const nx = dv.getUint32(24, true), ny = dv.getUint32(28, true);
  if (nx < 2 || nx > TERRAIN_MAX_SIDE) throw bad(`nx: ${nx} not in 2..16384`);
  if (ny < 2 || ny > TERRAIN_MAX_SIDE) throw bad(`ny: ${ny} not in 2..16384`);
  if (nx * ny > TERRAIN_MAX_VERTICES) throw bad(`nx * ny: ${nx * ny} vertices exceed 16777216`);
  const f = (/** @type {number} */ at) => dv.getFloat64(at, true);
  const t = { x0: f(40), y0: f(48), dx: f(56), dy: f(64), zmin: f(72), zmax: f(80) };
  const bound = f(88), origin = /** @type {[number, number]} */ ([f(96), f(104)]);
  /** @type {[string, number][]} */
  const numbers = [...Object.entries(t), ["origin_x", origin[0]], ["origin_y", origin[1]]];
  for (const [name, v] of numbers)
    if (!Number.isFinite(v) || Math.abs(v) > MAX_METRES)
      throw bad(`${name}: ${v} is not a finite number within 1e12`);
  if (!(t.dx > 0)) throw bad(`dx: ${t.dx} is not positive`);
  if (!(t.dy > 0)) throw bad(`dy: ${t.dy} is not positive`);
  if (!(Math.abs(t.x0 + t.dx * (nx - 1)) <= MAX_METRES))
    throw bad(`dx: the grid's last column ${t.x0 + t.dx * (nx - 1)} is beyond 1e12`);
  if (!(Math.abs(t.y0 + t.dy * (ny - 1)) <= MAX_METRES))
    throw bad(`dy: the grid's last row ${t.y0 + t.dy * (ny - 1)} is beyond 1e12`);
  if (!(t.zmin <= t.zmax)) throw bad(`zmin: ${t.zmin} exceeds zmax ${t.zmax}`);
  if (!(bound >= 0)) throw bad(`surface_error_bound: ${bound} (a length, or +infinity)`);
  const raw = nx * ny * 8, stored = dv.getBigUint64(120, true);
  if (codec === CODEC_NONE && stored !== BigInt(raw))
    throw bad(`heights_size: ${stored} (codec none stores nx * ny * 8 = ${raw})`);
  if (codec === CODEC_ZSTD && (stored === 0n || BigInt(raw) > stored * 32768n + 131072n))
    throw bad(`heights_size: ${stored} zstd bytes cannot hold ${raw}`);
  if (stored !== BigInt(b.length - header))
    throw bad(`heights_size: ${stored}, but ${b.length - header} bytes follow the header`);
  // 7. Checksum. 8. Decoding.
  const heights = b.subarray(header);
  if (dv.getBigUint64(128, true) !== xxh64Sync(heights))
    throw bad("heights_checksum: mismatch (the heights are damaged)");
  const planes = codec === CODEC_ZSTD
    ? decodeZstdFrame(heights, raw, (what) => bad(`heights: ${what}`), {
      notOne: "the stored bytes are not exactly one zstd frame",
      size: `the zstd frame's content size is not nx * ny * 8 = ${raw}`,
    })
    : heights;
  // 9. The heights: byte plane k holds byte k of every vertex's f64.
  const n = nx * ny, z = new Float64Array(n), bytes = new Uint8Array(z.buffer);
  for (let v = 0; v < n; ++v)
    for (let k = 0; k < 8; ++k) bytes[v * 8 + k] = planes[k * n + v];
  let lo = Infinity, hi = -Infinity;
  for (let v = 0; v < n; ++v) {
    const h = z[v];
    if (!Number.isFinite(h) || Math.abs(h) > MAX_METRES)
      throw bad(`heights: vertex ${v} (i ${v % nx}, j ${Math.floor(v / nx)}) is ${h}, ` +
                "not a finite height");
    if (h < lo) lo = h;
    if (h > hi) hi = h;
  }
  if (lo !== t.zmin) throw bad(`zmin: ${t.zmin} is not the lowest height ${lo}`);
  if (hi !== t.zmax) throw bad(`zmax: ${t.zmax} is not the highest height ${hi}`);
  const source = dv.getBigUint64(112, true).toString(16).padStart(16, "0");
  return { ...t, nx, ny, z, surfaceErrorBound: bound, origin, sourceXxh64: source };
}


/**
 * Fetches and parses a terrain file; null when the server answers 404 (no
 * terrain beside the package: draw flat terrain).
 * @param {string} url
 * @param {{fetch?: typeof fetch}} [options]
 * @returns {Promise<Terrain | null>}
 */
export async function fetchTerrain(url, options = {}) {
  const response = await (options.fetch ?? fetch)(url);
  if (response.status === 404) return null;
  if (!response.ok) throw new Error(`${url}: HTTP ${response.status} ${response.statusText}`);
  return parseTerrain(await response.arrayBuffer(), url);
}
