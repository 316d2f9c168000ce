#!/usr/bin/env node
// viewer_interactive_test.mjs — the interactive viewer page of `decalprep
// view` on a tileset, driven in headless Chromium through the DevTools
// protocol (--remote-debugging-pipe: no npm deps) as a user drives it: the
// Monaco sample as 500 m tiles with --levels auto (monaco_tileset.mjs),
// served by `decalprep view DIR --port 0`.
//
//   1. The first view streams (a frame budget of 1000 s: SwiftShader's
//      frames of about a second would lower detail at the default 50 ms):
//      the overlay comes to show the tiles, a level
//      mix of overview levels, the bytes fetched and nothing left to come;
//      the status line shows no error.
//   2. Wheel zoom-in: the page fetches more, the level mix turns finer
//      (level 0 appears), the bytes fetched grow.
//   3. A click on a decal names a layer of the tileset, a tile of its index
//      and a source fid that this tile's line_props or poly_props hold
//      (read by the JavaScript reader from the tile's file).
//   4. ?budget=1 (a 1 ms frame budget no frame meets): the viewer lowers
//      detail ("detail 1/N", N > 1) and draws the coarsest level alone.
//   5. ?backend=webgl2: the first view streams, and a click names its tile.
//
//   node tests/web/viewer_interactive_test.mjs DECALPREP REPO_ROOT WORK_DIR   (exit 77: skip)
import { spawn } from "node:child_process";
import { existsSync, mkdtempSync, readFileSync, rmSync } from "node:fs";
import { tmpdir } from "node:os";
import { join } from "node:path";
import { monacoTileset } from "./monaco_tileset.mjs";

const [decalprep, root, work] = process.argv.slice(2);
if (!work) {
  console.error("usage: viewer_interactive_test.mjs DECALPREP REPO_ROOT WORK_DIR");
  process.exit(2);
}
const chromiumPath = process.env.DECALPREP_CHROMIUM || "/usr/bin/chromium";
if (!existsSync(chromiumPath)) {
  console.log(`SKIP: no Chromium at ${chromiumPath}`);
  process.exit(77);
}
const { dir, ts } = await monacoTileset(decalprep, root, work);

let failures = 0;
const check = (/** @type {boolean} */ ok, /** @type {string} */ what) => {
  console.log((ok ? "ok   " : "FAIL ") + what);
  if (!ok) failures += 1;
};
const sleep = (/** @type {number} */ ms) => new Promise((r) => setTimeout(r, ms));

/** `decalprep view DIR --port 0`: resolves to the server's URL. */
function serve() {
  const server = spawn(decalprep, ["view", dir, "--port", "0"], { stdio: ["ignore", "pipe", "inherit"] });
  return new Promise((resolve, reject) => {
    let out = "";
    server.stdout.on("data", (c) => {
      out += c;
      const m = /serving on (http:\/\/\S+)/.exec(out);
      if (m) resolve({ server, url: m[1] });
    });
    server.on("exit", (code) => reject(new Error(`decalprep view exited ${code}: ${out}`)));
  });
}

/**
 * Headless Chromium on `url`, driven over --remote-debugging-pipe (fd 3 in,
 * fd 4 out: JSON messages ending in NUL). Returns send(method, params) for
 * the page's session, and stop().
 */
async function browser(url) {
  const profile = mkdtempSync(join(tmpdir(), "viewer-interactive-"));
  const chromium = spawn(chromiumPath, ["--headless", "--no-sandbox", "--enable-unsafe-webgpu",
    "--enable-unsafe-swiftshader", "--remote-debugging-pipe", `--user-data-dir=${profile}`,
    "--window-size=640,360", "about:blank"], { stdio: ["ignore", "ignore", "ignore", "pipe", "pipe"] });
  const toChromium = /** @type {import("node:stream").Writable} */ (chromium.stdio[3]);
  const fromChromium = /** @type {import("node:stream").Readable} */ (chromium.stdio[4]);
  let id = 0, buffered = "";
  /** @type {Map<number, {resolve: (v: any) => void, reject: (e: Error) => void}>} */
  const waiting = new Map();
  fromChromium.on("data", (chunk) => {
    buffered += chunk.toString();
    for (let end = buffered.indexOf("\0"); end >= 0; end = buffered.indexOf("\0")) {
      const msg = JSON.parse(buffered.slice(0, end));
      buffered = buffered.slice(end + 1);
      const w = msg.id !== undefined ? waiting.get(msg.id) : undefined;
      if (!w) continue;
      waiting.delete(msg.id);
      if (msg.error) w.reject(new Error(`${msg.error.message} (${JSON.stringify(msg.error)})`));
      else w.resolve(msg.result);
    }
  });
  /** @param {string} method @param {object} [params] @param {string} [sessionId] */
  const call = (method, params = {}, sessionId = undefined) => new Promise((resolve, reject) => {
    id += 1;
    waiting.set(id, { resolve, reject });
    toChromium.write(JSON.stringify({ id, method, params, ...(sessionId ? { sessionId } : {}) }) + "\0");
  });
  const { targetInfos } = await call("Target.getTargets");
  const page = targetInfos.find((t) => t.type === "page");
  const { sessionId } = await call("Target.attachToTarget", { targetId: page.targetId, flatten: true });
  const send = (/** @type {string} */ method, /** @type {object} */ params = {}) => call(method, params, sessionId);
  await send("Page.enable");
  await send("Page.navigate", { url });
  return {
    send,
    stop() {
      chromium.kill("SIGKILL");
      try { rmSync(profile, { recursive: true, force: true, maxRetries: 5, retryDelay: 100 }); } catch { /* left in tmp */ }
    },
  };
}

/** The text of element `id` on the page. */
async function text(send, id) {
  const r = await send("Runtime.evaluate", { expression: `document.getElementById(${JSON.stringify(id)})?.textContent ?? ""`,
    returnByValue: true });
  return String(r.result.value ?? "");
}

/** Waits (up to `seconds`) until the overlay shows a settled tileset frame satisfying `ok`. */
async function settledOverlay(send, seconds, ok = (/** @type {string} */ _t) => true) {
  let last = "";
  for (let waited = 0; waited < seconds * 1000; waited += 500) {
    const status = await text(send, "status");
    if (/Error/.test(status)) return { overlay: last, error: status };
    last = await text(send, "overlay");
    if (/levels L/.test(last) && !/to come/.test(last) && ok(last)) {
      await sleep(1500);  // the frame the last tile asked for
      const again = await text(send, "overlay");
      if (!/to come/.test(again) && ok(again)) return { overlay: again, error: "" };
    }
    await sleep(500);
  }
  return { overlay: last, error: `no settled overlay after ${seconds} s` };
}

const levelsOf = (/** @type {string} */ overlay) => {
  const m = /levels ((?:L\d+:\d+ ?)+)/.exec(overlay);
  return m ? Object.fromEntries(m[1].trim().split(" ").map((p) => p.slice(1).split(":").map(Number))) : {};
};
const fetchedOf = (/** @type {string} */ overlay) => {
  const m = /fetched ([\d.]+) MiB in (\d+) requests/.exec(overlay);
  return m ? { mib: Number(m[1]), requests: Number(m[2]) } : { mib: 0, requests: 0 };
};

/**
 * Clicks pixels of the page until one names a decal, then checks it: a
 * layer of the tileset, a tile of its index, a fid that tile's props hold.
 * @param {(method: string, params?: object) => Promise<any>} send @param {string} backend
 */
async function checkPick(send, backend) {
  const b = { send };
  let picked = "";
  /** @type {string[]} */
  const tried = [];
  // Points of the map itself, near the middle (the panels may cover parts of a small window).
  const r = await b.send("Runtime.evaluate", { returnByValue: true, expression: `(() => {
    const out = [];
    for (let y = 60; y < innerHeight - 20 && out.length < 8; y += 23)
      for (let x = innerWidth / 2 - 120; x < innerWidth / 2 + 120 && out.length < 8; x += 37)
        if (document.elementFromPoint(x, y)?.id === "map") out.push([Math.round(x), y]);
    return out; })()` });
  for (const [x, y] of /** @type {number[][]} */ (r.result.value)) {
    await b.send("Runtime.evaluate", { expression: "document.getElementById('pick').textContent = ''" });
    await b.send("Input.dispatchMouseEvent", { type: "mousePressed", x, y, button: "left", clickCount: 1 });
    await b.send("Input.dispatchMouseEvent", { type: "mouseReleased", x, y, button: "left", clickCount: 1 });
    for (let w = 0; w < 60 && !picked; ++w) {
      await sleep(500);
      const p = await text(b.send, "pick");
      if (p) picked = p;
    }
    tried.push(`${x},${y}: ${picked || "no answer"}`);
    if (picked && !/no decal/.test(picked)) break;
    picked = "";
  }
  const m = /^(.*) \(layer (\d+)\): fid (\d+), (line|polygon), tile (\d+)\/(-?\d+),(-?\d+)$/.exec(picked);
  const names = new Set(ts.json.manifest.layers.map((/** @type {any} */ l) => l.layer));
  const tile = m ? [ts.tiles, ...ts.levels.map((l) => l.tiles)][Number(m[5])]?.find(
    (/** @type {any} */ t) => t.x === Number(m[6]) && t.y === Number(m[7])) : null;
  let holds = false;
  if (m && tile) {
    const { openPackage } = await import(join(root, "web/src/index.js"));
    const pkg = await openPackage(new Uint8Array(readFileSync(join(dir, tile.file))), { label: tile.file });
    const props = await pkg.bytes(m[4] === "line" ? "line_props" : "poly_props");
    const words = new Uint32Array(props.buffer, props.byteOffset, props.byteLength / 4);
    const at = m[4] === "line" ? 6 : 5;  // LineProps / PolyProps `feature` (formats/SPEC.md)
    for (let k = at; k < words.length && !holds; k += 8) holds = words[k] === Number(m[3]);
  }
  check(Boolean(m && names.has(m[1]) && tile && holds), `${backend}: a click names a layer of the tileset, a tile of the ` +
        `index and a fid that tile holds: "${picked}"` + (m ? "" : ` (clicked ${tried.join("; ")})`));
}

const { server, url } = await serve();
try {
  // 1. The first view (a budget no CPU rasteriser's frame passes: full detail).
  let b = await browser(url + "?budget=1000000");
  let s = await settledOverlay(b.send, 240);
  check(!s.error, `first view settles: ${s.error || s.overlay.replace(/\n/g, " | ")}`);
  const first = levelsOf(s.overlay), f1 = fetchedOf(s.overlay);
  const top = ts.levels.length;
  check(Object.keys(first).length > 0 && Math.min(...Object.keys(first).map(Number)) > 0,
        `the whole view draws overview levels only: ${JSON.stringify(first)} (levels 0..${top})`);
  check(f1.requests > 0 && f1.requests < ts.tiles.length, `it fetched ${f1.requests} tiles of ${ts.tiles.length} level-0 ones`);

  // 2. Zoom in at the centre: finer levels, more bytes.
  for (let k = 0; k < 6; ++k)
    await b.send("Input.dispatchMouseEvent", { type: "mouseWheel", x: 320, y: 200, deltaX: 0, deltaY: -400 });
  s = await settledOverlay(b.send, 300, (o) => 0 in levelsOf(o));
  const near = levelsOf(s.overlay), f2 = fetchedOf(s.overlay);
  check(!s.error && 0 in near && f2.requests > f1.requests && f2.mib > f1.mib,
        `zoomed in: levels ${JSON.stringify(near)}, ${f2.requests} requests (${f2.mib} MiB) after ${f1.requests} ` +
        `(${f1.mib} MiB)${s.error ? `: ${s.error}` : ""}`);

  // 3. Click where the frame shows a decal: layer, fid and tile named.
  await checkPick(b.send, "WebGPU");  b.stop();

  // 4. A frame budget no frame meets: detail lowered to the coarsest level.
  b = await browser(url + "?budget=1");
  s = await settledOverlay(b.send, 300, (o) => /detail 1\/(\d+)/.test(o) && Number(/detail 1\/(\d+)/.exec(o)?.[1]) > 1);
  const lv = levelsOf(s.overlay), detail = /detail 1\/(\d+)/.exec(s.overlay);
  check(!s.error && Boolean(detail) && Number(detail?.[1]) > 1 && Object.keys(lv).every((l) => Number(l) === top),
        `over a 1 ms budget the viewer lowers detail: ${s.overlay.replace(/\n/g, " | ")}${s.error ? `: ${s.error}` : ""}`);
  b.stop();

  // 5. WebGL2: the first view streams, zooms in, and a click names its tile too.
  b = await browser(url + "?budget=1000000&backend=webgl2");
  s = await settledOverlay(b.send, 240);
  check(!s.error && /WebGL2/.test(s.overlay), `WebGL2: the first view settles: ${s.error || s.overlay.replace(/\n/g, " | ")}`);
  for (let k = 0; k < 6; ++k)
    await b.send("Input.dispatchMouseEvent", { type: "mouseWheel", x: 540, y: 150, deltaX: 0, deltaY: -400 });
  s = await settledOverlay(b.send, 300, (o) => 0 in levelsOf(o));
  check(!s.error, `WebGL2: zoomed in: levels ${JSON.stringify(levelsOf(s.overlay))}${s.error ? `: ${s.error}` : ""}`);
  await checkPick(b.send, "WebGL2");
  b.stop();
} finally {
  server.kill("SIGTERM");
}
console.log(`${failures} failed`);
process.exit(failures ? 1 : 0);
