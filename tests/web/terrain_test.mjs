// terrain_test.mjs — the terrain file reader (web/src/terrain.js) against
// the C++ reader (formats/SPEC.md "Terrain files"):
//   1. `decalprep terrain` on the Monaco sample with its DEM: parseTerrain
//      gives the values terrain_dump (prep::render::decode_terrain) prints,
//      every height bit for bit;
//   2. its synchronous XXH64 equals xxhash-wasm's at many lengths;
//   3. a hostile set (truncation at every header field and in the heights,
//      every bit flip of the header and of the first heights, and fields
//      forged with right checksums: bad sizes, NaN and zero spacing, a NaN
//      height) is refused with a FormatError naming the field, within 1 s
//      each, and the C++ reader refuses each too;
//   4. fetchTerrain: null on 404, the terrain on 200.
// Usage: node terrain_test.mjs DECALPREP TERRAIN_DUMP SOURCE_DIR WORK_DIR
// Exit 77 (ctest SKIP_RETURN_CODE) when web/node_modules is missing.
import { spawnSync } from "node:child_process";
import fs from "node:fs";
import path from "node:path";
import { pathToFileURL } from "node:url";

const [toolArg, dumpArg, root, work] = process.argv.slice(2);
if (!toolArg || !dumpArg || !root || !work) {
  console.error("usage: node terrain_test.mjs DECALPREP TERRAIN_DUMP SOURCE_DIR WORK_DIR");
  process.exit(2);
}
const tool = path.resolve(toolArg), dump = path.resolve(dumpArg);
for (const m of ["fzstd", "xxhash-wasm"])
  if (!fs.existsSync(path.join(root, "web", "node_modules", m))) {
    console.log(`SKIP: web/node_modules/${m} is missing (run scripts/deps, or npm ci in web/)`);
    process.exit(77);
  }
const W = await import(pathToFileURL(path.join(root, "web", "src", "index.js")).href);
const { xxh64 } = await import(pathToFileURL(path.join(root, "web", "src", "xxh64.js")).href);

let failures = 0, checks = 0;
/** @param {boolean} ok @param {string} what */
function check(ok, what) {
  ++checks;
  if (!ok) {
    ++failures;
    console.log(`FAIL: ${what}`);
  }
}
const run = (/** @type {string} */ exe, /** @type {string[]} */ args) =>
  spawnSync(exe, args, { encoding: "utf8", maxBuffer: 1 << 30 });

fs.rmSync(work, { recursive: true, force: true });
fs.mkdirSync(work, { recursive: true });

// ------------------------------------------------------------- Monaco --
const pkg = path.join(work, "monaco.decals"), file = path.join(work, "monaco.terrain");
const dem = `/vsizip/${root}/samples/monaco/N43E007.hgt.zip/N43E007.hgt`;
let r = run(tool, ["build", path.join(root, "samples/monaco/scene.toml"), "-o", pkg, "-q"]);
check(r.status === 0, `build Monaco: ${r.stderr}`);
r = run(tool, ["terrain", pkg, "--dem", dem, "-o", file, "-q"]);
check(r.status === 0, `decalprep terrain: ${r.stderr}`);
const bytes = new Uint8Array(fs.readFileSync(file));
r = run(dump, [file]);
check(r.status === 0, `terrain_dump: ${r.stderr}`);
const want = JSON.parse(r.stdout);
const t = W.parseTerrain(bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength),
                         "monaco.terrain");
for (const k of ["nx", "ny", "x0", "y0", "dx", "dy", "zmin", "zmax"])
  check(Object.is(t[k], want[k]), `${k}: ${t[k]} (C++ ${want[k]})`);
check(Object.is(t.origin[0], want.origin_x) && Object.is(t.origin[1], want.origin_y), "origin");
check(want.surface_error_bound === null ? t.surfaceErrorBound === Infinity
  : t.surfaceErrorBound === want.surface_error_bound, "surface_error_bound");
check(t.z.length === want.z.length, `z length ${t.z.length} (C++ ${want.z.length})`);
let worst = 0;
for (let k = 0; k < t.z.length; ++k) worst = Math.max(worst, Math.abs(t.z[k] - want.z[k]));
check(worst === 0, `heights differ from the C++ reader's by up to ${worst} m`);
console.log(`monaco.terrain: ${bytes.length} bytes, ${t.nx}x${t.ny} vertices, ` +
            `max |JS - C++| = ${worst} m`);

// ---------------------------------------------------------------- XXH64 --
for (const n of [0, 1, 3, 4, 5, 7, 8, 9, 15, 16, 31, 32, 33, 63, 64, 65, 255, 1000, 65536 + 7]) {
  const b = new Uint8Array(n);
  for (let i = 0; i < n; ++i) b[i] = (Math.imul(i + 1, 2654435761) >>> 11) & 255;
  check(W.xxh64Sync(b) === await xxh64(b), `xxh64Sync of ${n} bytes`);
}

// -------------------------------------------------------------- hostile --
const HEADER = 144;
/** Re-seals a file: heights checksum, then header checksum. @param {Uint8Array} b */
function seal(b) {
  const dv = new DataView(b.buffer, b.byteOffset, b.byteLength);
  dv.setBigUint64(128, W.xxh64Sync(b.subarray(HEADER)), true);
  dv.setBigUint64(136, W.xxh64Sync(b.subarray(0, 136)), true);
  return b;
}
/** @param {number} at @param {(dv: DataView) => void} set */
function forged(at, set) {
  const b = bytes.slice();
  set(new DataView(b.buffer));
  return seal(b);
}
// The Monaco heights stored uncompressed (codec none), with vertex 7 NaN.
function nanHeight() {
  const n = t.nx * t.ny, planes = new Uint8Array(n * 8), z = t.z.slice();
  z[7] = NaN;
  const zb = new Uint8Array(z.buffer);
  for (let v = 0; v < n; ++v) for (let k = 0; k < 8; ++k) planes[k * n + v] = zb[v * 8 + k];
  const b = new Uint8Array(HEADER + planes.length);
  b.set(bytes.subarray(0, HEADER));
  b.set(planes, HEADER);
  const dv = new DataView(b.buffer);
  dv.setUint32(20, 0, true);
  dv.setBigUint64(32, BigInt(b.length), true);
  dv.setBigUint64(120, BigInt(planes.length), true);
  return seal(b);
}
/** @type {[string, Uint8Array, string][]} name, bytes, field the message names */
const hostile = [];
for (const n of [0, 7, 8, 10, 12, 15, 16, 20, 24, 28, 32, 40, 48, 56, 64, 72, 80, 88, 96, 104,
                 112, 120, 128, 136, 143, 144, 145, bytes.length - 1])
  hostile.push([`truncated at ${n}`, bytes.slice(0, n), ""]);
for (let k = 0; k < HEADER + 64; ++k)
  for (let bit = 0; bit < 8; bit += 3) {
    const b = bytes.slice();
    b[k] ^= 1 << bit;
    hostile.push([`byte ${k} bit ${bit} flipped`, b, ""]);
  }
const f64 = (/** @type {number} */ at, /** @type {number} */ v) =>
  forged(at, (dv) => dv.setFloat64(at, v, true));
const u32 = (/** @type {number} */ at, /** @type {number} */ v) =>
  forged(at, (dv) => dv.setUint32(at, v, true));
hostile.push(
  ["version 2", forged(8, (dv) => dv.setUint16(8, 2, true)), "version_major"],
  ["header_size 100", u32(12, 100), "header_size"],
  ["header_size 152", u32(12, 152), "header_checksum"],
  ["required flag", u32(16, 1), "flags"],
  ["codec 2", u32(20, 2), "codec"],
  ["nx 1", u32(24, 1), "nx"],
  ["ny 0", u32(28, 0), "ny"],
  ["nx 16385", u32(24, 16385), "nx"],
  ["nx*ny too many", forged(24, (dv) => { dv.setUint32(24, 16384, true); dv.setUint32(28, 16384, true); }), "nx * ny"],
  ["nx 57", u32(24, 57), "heights"],
  ["file_size", forged(32, (dv) => dv.setBigUint64(32, 1n << 40n, true)), "file_size"],
  ["x0 NaN", f64(40, NaN), "x0"],
  ["y0 inf", f64(48, Infinity), "y0"],
  ["dx 0", f64(56, 0), "dx"],
  ["dy negative", f64(64, -66), "dy"],
  ["dx huge", f64(56, 1e11), "dx"],
  ["zmin wrong", f64(72, -5), "zmin"],
  ["zmax NaN", f64(80, NaN), "zmax"],
  ["zmin > zmax", f64(72, 1e6), "zmin"],
  ["bound NaN", f64(88, NaN), "surface_error_bound"],
  ["bound negative", f64(88, -1), "surface_error_bound"],
  ["origin NaN", f64(96, NaN), "origin_x"],
  ["heights_size", forged(120, (dv) => dv.setBigUint64(120, 12n, true)), "heights_size"],
  ["NaN height", nanHeight(), "heights"],
);
let slowest = 0, cppChecked = 0;
for (const [index, [name, b, field]] of hostile.entries()) {
  const start = performance.now();
  let message = "";
  try {
    W.parseTerrain(b, "hostile");
  } catch (err) {
    message = err instanceof W.FormatError ? err.message : `not a FormatError: ${err}`;
  }
  const ms = performance.now() - start;
  slowest = Math.max(slowest, ms);
  check(message.startsWith("hostile: "), `${name}: accepted or not refused properly (${message})`);
  if (field) check(message.startsWith(`hostile: ${field}`), `${name}: "${message}" names not ${field}`);
  check(ms < 1000, `${name}: ${ms.toFixed(0)} ms`);
  // The C++ reader refuses it too (a sample: every named case, every 8th other).
  if (field || index % 8 === 0) {
    const p = path.join(work, "hostile.terrain");
    fs.writeFileSync(p, b);
    const c = run(dump, [p]);
    check(c.status === 5, `${name}: C++ reader exit ${c.status}`);
    ++cppChecked;
  }
}
console.log(`${hostile.length} hostile files refused, slowest ${slowest.toFixed(1)} ms; ` +
            `${cppChecked} also by the C++ reader`);

// --------------------------------------------------------- fetchTerrain --
{
  /** @param {number} status @param {Uint8Array} body */
  const fake = (status, body) => /** @type {typeof fetch} */ (async () =>
    new Response(status === 200 ? body : null, { status }));
  check(await W.fetchTerrain("x.terrain", { fetch: fake(404, bytes) }) === null, "404 gives null");
  const got = await W.fetchTerrain("x.terrain", { fetch: fake(200, bytes) });
  check(got !== null && got.nx === t.nx && got.z[5] === t.z[5], "200 gives the terrain");
  let threw = false;
  try {
    await W.fetchTerrain("x.terrain", { fetch: fake(500, bytes) });
  } catch {
    threw = true;
  }
  check(threw, "500 throws");
}

console.log(`${checks} checks, ${failures} failures`);
process.exit(failures ? 1 : 0);
