// reader_test.mjs — the browser reader (web/src) against the tool:
//   1. element counts, values and checksums equal `decalprep dump --json` and
//      `decalprep info --json` for the golden scene, the samples, the 1.1
//      and 1.2 legacy files and the valid seeds of fuzz/corpus/read;
//   2. every package of the hostile corpus (fuzz/corpus/read/broken_*, which
//      tests/formats/make_seeds writes; single-bit flips of the golden
//      package in every region; truncations; a trailing byte) that
//      `decalprep verify` rejects is refused with a message, within 1 s
//      each; it never accepts one verify rejects (verify is the oracle);
//   3. reading over HTTP Range requests (a local server) fetches only the
//      header, the table and the blobs asked for, and gives the same bytes.
// Usage: node reader_test.mjs DECALPREP SOURCE_DIR WORK_DIR
// Exit 77 (ctest SKIP_RETURN_CODE) when web/node_modules is missing.
import { execFileSync, spawnSync } from "node:child_process";
import fs from "node:fs";
import http from "node:http";
import path from "node:path";
import { pathToFileURL } from "node:url";

const [toolArg, root, work] = process.argv.slice(2);
const tool = toolArg && path.resolve(toolArg);
if (!tool || !root || !work) {
  console.error("usage: node reader_test.mjs DECALPREP SOURCE_DIR WORK_DIR");
  process.exit(2);
}
const SKIP = 77;
for (const m of ["fzstd", "xxhash-wasm"])
  if (!fs.existsSync(path.join(root, "web", "node_modules", m))) {
    console.log(`SKIP: web/node_modules/${m} is missing (run scripts/deps, or npm ci in web/)`);
    process.exit(SKIP);
  }
const R = await import(pathToFileURL(path.join(root, "web", "src", "index.js")).href);

let failures = 0;
let checks = 0;
/** @param {boolean} ok @param {string} what */
function check(ok, what) {
  ++checks;
  if (!ok) {
    ++failures;
    console.log(`FAIL: ${what}`);
  }
}

fs.rmSync(work, { recursive: true, force: true });
fs.mkdirSync(work, { recursive: true });
const run = (/** @type {string[]} */ args, opts = {}) =>
  spawnSync(tool, args, { encoding: "utf8", maxBuffer: 1 << 30, ...opts });

// ------------------------------------------------------------ packages --
const packages = [];
{
  const golden = path.join(work, "golden.decals");
  const r = run(["build", path.join(root, "tests/tools/golden/scene.toml"), "-o", golden, "-q", "--threads", "1"]);
  check(r.status === 0, `build golden scene: ${r.stderr}`);
  packages.push(golden);
  const raw = path.join(work, "golden_raw.decals");
  run(["build", path.join(root, "tests/tools/golden/scene.toml"), "-o", raw, "-q", "--threads", "1", "--no-compress"]);
  packages.push(raw);
}
for (const d of fs.readdirSync(path.join(root, "samples"), { withFileTypes: true })) {
  if (!d.isDirectory()) continue;
  const scene = path.join(root, "samples", d.name, "scene.toml");
  if (!fs.existsSync(scene)) continue;
  const out = path.join(work, `sample_${d.name}.decals`);
  const r = run(["build", scene, "-o", out, "-q"], { cwd: path.dirname(scene) });
  check(r.status === 0, `build sample ${d.name}: ${r.stderr}`);
  if (r.status === 0) packages.push(out);
}
for (const f of ["golden_v1_1.decals", "golden_v1_2.decals"])
  packages.push(path.join(root, "tests/formats/legacy", f));
for (const f of fs.readdirSync(path.join(root, "fuzz/corpus/read")).sort())
  if (f.startsWith("valid_")) packages.push(path.join(root, "fuzz/corpus/read", f));

/** The element of blob `b` at i as `dump --json` prints it. */
function dumpElement(b, dv, i) {
  const at = i * b.entry.stride;
  const f = (k) => { const v = dv.getFloat32(at + 4 * k, true); return Number.isFinite(v) ? v : null; };
  const u = (k) => dv.getUint32(at + 4 * k, true);
  const s = (k) => dv.getInt32(at + 4 * k, true);
  const n = R.ELEMENT_TYPES.get(b.entry.type).components;
  const many = (g) => { const a = []; for (let k = 0; k < n; ++k) a.push(g(k)); return n === 1 ? a[0] : a; };
  switch (b.entry.typeName) {
    case "u8": return dv.getUint8(at);
    case "u32": case "uvec2": case "uvec4": return many(u);
    case "i32": case "ivec2": case "ivec4": return many(s);
    case "f32": case "vec2": case "vec4": return many(f);
  }
  switch (b.entry.name) {
    case "line_props": case "dyn_line_props":
      return { half_width: f(0), rgba: u(1), order: u(2), style: u(3), value: f(4), layer: u(5), feature: u(6), clip_node: u(7) };
    case "line_corners": return { miter: [f(0), f(1)], bevel_in: [f(2), f(3)], bevel_out: [f(4), f(5)] };
    case "poly_props": return { rgba: u(0), order: u(1), exterior: s(2), value: f(3), layer: u(4), feature: u(5), reserved: [u(6), u(7)] };
    case "lod_points": return { x: s(0), y: s(1), eval_x: s(2), eval_y: s(3), e_star: f(4), d_star: f(5), line: u(6), flags: u(7) };
    case "lod_segments": {
      const idx = (v) => (v === R.LOD_NONE ? null : v);
      return { a: u(0), b: u(1), generator: idx(u(2)), splitter: idx(u(3)) };
    }
  }
  let hex = "";
  for (let k = 0; k < b.entry.stride; ++k) hex += dv.getUint8(at + k).toString(16).padStart(2, "0");
  return hex;
}

const deepEqual = (a, b) => JSON.stringify(a) === JSON.stringify(b);

for (const file of packages) {
  const name = path.relative(root, file).startsWith("..") ? path.basename(file) : path.relative(root, file);
  let pkg;
  try {
    pkg = await R.openPackage(fs.readFileSync(file), { label: name });
    await pkg.validate();
  } catch (e) {
    check(false, `${name}: the reader refuses a package verify accepts: ${e.message}`);
    continue;
  }
  const dump = JSON.parse(execFileSync(tool, ["dump", file, "--json"], { maxBuffer: 1 << 30, encoding: "utf8" }));
  const info = JSON.parse(execFileSync(tool, ["info", file, "--json"], { maxBuffer: 1 << 28, encoding: "utf8" }));
  check(pkg.major === dump.version.major && pkg.minor === dump.version.minor, `${name}: version`);
  check(deepEqual(pkg.metadata, dump.metadata), `${name}: metadata differs from dump --json`);
  check(pkg.blobs.length === dump.blobs.length, `${name}: ${pkg.blobs.length} blobs, dump lists ${dump.blobs.length}`);
  const infoBlobs = new Map(info.blobs.map((b) => [b.name, b]));
  let elements = 0;
  for (let k = 0; k < pkg.blobs.length && k < dump.blobs.length; ++k) {
    const e = pkg.blobs[k], d = dump.blobs[k];
    const w = `${name}: blob ${e.name}`;
    check(e.id === d.id && e.name === d.name && e.typeName === d.type && e.stride === d.stride, `${w}: id/name/type/stride`);
    check(e.count === d.count, `${w}: count ${e.count}, dump ${d.count}`);
    const ib = infoBlobs.get(e.name);
    check(ib !== undefined && ib.xxh64 === R.hex64(e.checksum), `${w}: checksum ${R.hex64(e.checksum)}, info ${ib?.xxh64}`);
    const bytes = await pkg.bytes(e.name);
    check(bytes.length === e.count * e.stride, `${w}: ${bytes.length} decoded bytes`);
    if (e.name === "manifest_entries") {
      check(deepEqual(JSON.parse(new TextDecoder().decode(bytes)), d.elements), `${w}: entries differ`);
      continue;
    }
    const dv = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
    let same = d.elements.length === e.count;
    for (let i = 0; same && i < e.count; ++i) same = deepEqual(dumpElement({ entry: e }, dv, i), d.elements[i]);
    check(same, `${w}: elements differ from dump --json`);
    elements += e.count;
  }
  console.log(`ok ${name}: v${pkg.major}.${pkg.minor}, ${pkg.blobs.length} blobs, ${elements} elements equal dump --json`);
}

// -------------------------------------------------------- hostile files --
const hostile = [];
for (const f of fs.readdirSync(path.join(root, "fuzz/corpus/read")).sort())
  if (f.startsWith("broken_")) hostile.push(path.join(root, "fuzz/corpus/read", f));
// Single-bit flips of the golden package: one in the header, the table, the
// metadata, the padding and each blob, and a truncation after each region.
{
  const src = fs.readFileSync(packages[0]);
  const pkg = await R.openPackage(src);
  const spots = [3, 9, 20, 30, 60, 100, 96 + 5, 96 + 40, 96 + 60];
  const metaAt = 96 + 96 * pkg.blobs.length;
  spots.push(metaAt, metaAt + 10, metaAt + pkg.metadataText.length - 1);
  for (const e of pkg.blobs) {
    if (e.padFrom < e.offset) spots.push(e.padFrom);
    if (e.storedSize > 0) spots.push(e.offset, e.offset + (e.storedSize >> 1), e.offset + e.storedSize - 1);
  }
  spots.forEach((at, i) => {
    const b = Buffer.from(src);
    b[at] ^= 1 << (i % 8);
    const out = path.join(work, `flip_${at}.decals`);
    fs.writeFileSync(out, b);
    hostile.push(out);
  });
  for (const cut of [0, 50, 97, metaAt + 3, pkg.blobs[3].offset + 1, src.length - 1]) {
    const out = path.join(work, `cut_${cut}.decals`);
    fs.writeFileSync(out, src.subarray(0, cut));
    hostile.push(out);
  }
  const trailing = path.join(work, "trailing.decals");
  fs.writeFileSync(trailing, Buffer.concat([src, Buffer.alloc(1)]));
  hostile.push(trailing);
}
let refused = 0, both = 0, slowest = 0;
for (const file of hostile) {
  const name = path.basename(file);
  const v = run(["verify", file]);
  const verifyOk = v.status === 0;
  const t0 = performance.now();
  let message = null;
  try {
    const pkg = await R.openPackage(fs.readFileSync(file), { label: name });
    await pkg.validate();
  } catch (e) {
    message = e instanceof Error ? e.message : String(e);
  }
  const ms = performance.now() - t0;
  slowest = Math.max(slowest, ms);
  check(ms < 1000, `${name}: took ${ms.toFixed(0)} ms`);
  if (!verifyOk) {
    check(message !== null, `${name}: verify rejects it (${v.stdout.trim()} ${v.stderr.trim()}) but the reader accepts it`);
    check(message === null || (message.length > name.length + 10 && !(message.includes("undefined"))),
          `${name}: the message does not say why: ${message}`);
    if (message !== null) {
      ++refused;
      if (process.env.VERBOSE) console.log(`  ${name}: ${message}`);
    }
  } else {
    check(message === null, `${name}: verify accepts it but the reader refuses: ${message}`);
    ++both;
  }
}
console.log(`ok hostile: ${refused} refused with a message (verify rejects them too), ${both} accepted by both, slowest ${slowest.toFixed(0)} ms`);

// ------------------------------------------------------- HTTP, lazily --
{
  const file = packages[0];
  const data = fs.readFileSync(file);
  const requests = [];
  const server = http.createServer((req, res) => {
    const m = /^bytes=(\d+)-(\d+)$/.exec(req.headers.range ?? "");
    if (!m) { res.writeHead(400); res.end(); return; }
    const a = Number(m[1]), b = Math.min(Number(m[2]), data.length - 1);
    requests.push([a, b]);
    if (a >= data.length) { res.writeHead(416, { "Content-Range": `bytes */${data.length}` }); res.end(); return; }
    res.writeHead(206, { "Content-Range": `bytes ${a}-${b}/${data.length}`, "Content-Length": b - a + 1 });
    res.end(data.subarray(a, b + 1));
  });
  await new Promise((ok) => server.listen(0, "127.0.0.1", ok));
  const url = `http://127.0.0.1:${server.address().port}/p.decals`;
  try {
    const pkg = await R.openPackageUrl(url);
    const opened = requests.reduce((n, [a, b]) => n + b - a + 1, 0);
    const metaEnd = 96 + 96 * pkg.blobs.length + pkg.metadataText.length;
    check(opened <= metaEnd + 1, `HTTP open read ${opened} bytes, the header, table and metadata are ${metaEnd}`);
    const local = await R.openPackage(data);
    const name = pkg.blobs.find((b) => b.count > 0 && b.codec === 1)?.name ?? pkg.blobs[0].name;
    const before = requests.length;
    const got = await pkg.bytes(name);
    const want = await local.bytes(name);
    check(Buffer.compare(Buffer.from(got), Buffer.from(want)) === 0, `HTTP blob ${name} differs`);
    const e = pkg.entry(name);
    const fetched = requests.slice(before).reduce((n, [a, b]) => n + b - a + 1, 0);
    check(requests.length === before + 1 && fetched === e.offset + e.storedSize - e.padFrom,
          `HTTP blob ${name}: ${requests.length - before} requests, ${fetched} bytes for a ${e.storedSize}-byte blob`);
    await pkg.validate();
    console.log(`ok HTTP: open read ${opened} of ${data.length} bytes; blob ${name} alone ${fetched} bytes`);
  } catch (e) {
    check(false, `HTTP read: ${e.stack}`);
  }
  server.close();
}

// ------------------------------------------------------------ tileset --
{
  const dir = path.join(work, "tileset");
  const scene = path.join(root, "tests/tools/golden/scene.toml");
  const r = run(["build", scene, "-o", dir, "--tile-size", "500", "-q", "--threads", "1"]);
  if (r.status !== 0) {
    check(false, `tileset build: ${r.stderr}`);
  } else {
    const text = fs.readFileSync(path.join(dir, "tileset.json"));
    try {
      const ts = R.parseTileset(text, "tileset.json");
      for (const t of ts.tiles) {
        const bytes = fs.readFileSync(path.join(dir, t.file));
        check(bytes.length === t.bytes && R.hex64(await R.xxh64(bytes)) === t.xxh64, `tile ${t.file}: size or hash`);
        const p = await R.openPackage(bytes, { label: t.file });
        await p.validate();
      }
      console.log(`ok tileset: ${ts.tiles.length} tiles, ${ts.levels.length} levels`);
      // Broken indexes are refused, naming the field.
      const j = JSON.parse(text.toString());
      const cases = [
        ["tileset_version", (x) => { x.tileset_version = "1.0garbage"; }],
        ["tiles[0].file", (x) => { x.tiles[0].file = "../../etc/passwd"; }],
        ["tiles[0].square", (x) => { x.tiles[0].square[0] += 1; }],
        ["tiling.tile_size_m", (x) => { x.tiling.tile_size_m = 0.5; }],
        ["manifest.layers[0]", (x) => { x.manifest.layers[0].read += 1; }],
        ["extent", (x) => { x.extent = [1, 0, 0, 0]; }],
      ];
      for (const [field, edit] of cases) {
        const x = structuredClone(j);
        edit(x);
        let msg = null;
        try { R.parseTileset(JSON.stringify(x)); } catch (e) { msg = e.message; }
        check(msg !== null && msg.includes(field), `tileset.json with a bad ${field}: ${msg}`);
      }
    } catch (e) {
      check(false, `tileset: ${e.stack}`);
    }
  }
}

console.log(`${checks - failures} of ${checks} checks passed`);
if (!failures) fs.rmSync(work, { recursive: true, force: true });  // kept to look at on failure
process.exit(failures ? 1 : 0);
