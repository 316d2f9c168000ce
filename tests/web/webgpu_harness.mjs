#!/usr/bin/env node
// webgpu_harness.mjs — renders one frame of a package with the WebGPU
// renderer (web/src/render/) in headless Chromium and writes the frame and
// its decal layer as PNGs. No npm deps: chromium_page.mjs serves the
// repository's web/ folder, the package, the job and a page; the page POSTs
// the RGBA bytes back.
//
//   node tests/web/webgpu_harness.mjs --pkg P.decals --size 480x270 --out /tmp/x \
//        (--extent xmin,ymin,xmax,ymax | --camera cam.json) [--terrain t.json] [--frames N]
//        [--ramps RAMPS] [--hide 1,3] [--present 1]
//
// --extent: top-down, metres relative to the package origin (as render's
// --extent minus the origin). --camera: a renderFrame camera as JSON.
// --terrain: a Terrain as JSON ({x0, y0, dx, dy, nx, ny, z: [...], zmin, zmax}).
// --ramps: setScene's RAMPS as JSON ([[layerIndex, [[value, r, g, b, a], ...]], ...]).
// --hide: layer-table indices drawn hidden (setLayerVisible(i, false)).
// --present 1: renderFrame shows the frame on the page's canvas; the canvas
// is then read back through a 2D canvas (drawImage) into OUT_canvas.png and
// the renderer's presentPath is printed.
// Writes OUT_rgba.png and OUT_decals.png; prints the frame times.
import { readFileSync, writeFileSync } from "node:fs";
import { IMPORT_MAP, runPage } from "./chromium_page.mjs";
import { encodePng } from "./webgpu_png.mjs";

const args = Object.fromEntries(
  process.argv.slice(2).reduce((acc, a, i, all) => (a.startsWith("--") ? [...acc, [a.slice(2), all[i + 1]]] : acc), []));
if (!args.pkg || !args.size || !args.out || !(args.extent || args.camera)) {
  console.error("usage: webgpu_harness.mjs --pkg P --size WxH --out PREFIX (--extent a,b,c,d | --camera C.json) [--terrain T.json] [--frames N]");
  process.exit(2);
}
const [W, H] = args.size.split("x").map(Number);
const job = {
  width: W, height: H, frames: Number(args.frames ?? 1),
  extent: args.extent ? args.extent.split(",").map(Number) : null,
  camera: args.camera ? JSON.parse(readFileSync(args.camera, "utf8")) : null,
  terrain: Boolean(args.terrain),
  present: Boolean(args.present),
  ramps: args.ramps ? JSON.parse(args.ramps) : [],
  hide: args.hide ? args.hide.split(",").map(Number) : [],
};

const PAGE = `<!doctype html><html><head><meta charset="utf-8">
${IMPORT_MAP}</head>
<body style="margin:0"><canvas id="c"></canvas><script type="module">
const post = (path, body) => fetch(path, { method: "POST", body });
const step = (m) => post("/result/log", m);
try {
  const { openPackage, createRenderer, flatTerrain, topdownCamera } = await import("/web/src/index.js");
  const job = await (await fetch("/job.json")).json();
  const pkg = await openPackage(await (await fetch("/pkg.decals")).arrayBuffer(), { label: "pkg.decals" });
  await pkg.validate();
  await step("validated");
  const r = await createRenderer({ canvas: document.getElementById("c") });
  let terrain = null;
  if (job.terrain) {
    const t = await (await fetch("/terrain.json")).json();
    terrain = { ...t, z: Float64Array.from(t.z) };
  }
  await step("renderer " + r.adapterName);
  r.device.onuncapturederror = (e) => step("gpu error: " + e.error.message);
  r.device.lost.then((i) => step("device lost: " + i.message));
  await r.setScene({ pkg, terrain, ramps: job.ramps });
  for (const layer of job.hide) r.setLayerVisible(layer, false);
  await step("scene");
  const t = terrain ?? flatTerrain(pkg.metadata.extent);
  const camera = job.camera ?? topdownCamera(job.extent, t.zmin, t.zmax);
  const times = [];
  let out;
  for (let i = 0; i < job.frames; ++i) {
    out = await r.renderFrame({ camera, width: job.width, height: job.height, decals: true, present: job.present });
    times.push(out.ms);
  }
  if (job.present) {
    // What the page shows: the canvas drawn into a 2D canvas and read back.
    const c = document.getElementById("c");
    const copy = document.createElement("canvas");
    copy.width = c.width;
    copy.height = c.height;
    const g = copy.getContext("2d");
    g.drawImage(c, 0, 0);
    const img = g.getImageData(0, 0, copy.width, copy.height);
    await post("/result/canvas", JSON.stringify({ width: copy.width, height: copy.height, path: r.presentPath }));
    await post("/result/canvaspx", img.data);
  }
  await post("/result/info", JSON.stringify({ adapter: r.adapterName, gpuBytes: r.gpuBytes, times }));
  await post("/result/rgba", out.rgba);
  await post("/result/decals", out.decals);
  await post("/result/done", "");
} catch (e) {
  await post("/result/error", String(e && e.stack || e));
}
</script></body></html>`;

let results;
try {
  results = await runPage({ page: PAGE, width: W, height: H, timeoutS: Number(args.timeout ?? 600),
    files: { "/job.json": { json: job }, "/pkg.decals": args.pkg,
             ...(args.terrain ? { "/terrain.json": args.terrain } : {}) } });
} catch (e) {
  console.error(String(e.message ?? e));
  process.exit(1);
}
const info = JSON.parse(results.info.toString());
writeFileSync(`${args.out}_rgba.png`, encodePng(W, H, new Uint8Array(results.rgba)));
writeFileSync(`${args.out}_decals.png`, encodePng(W, H, new Uint8Array(results.decals)));
if (job.present) {
  const c = JSON.parse(results.canvas.toString());
  writeFileSync(`${args.out}_canvas.png`, encodePng(c.width, c.height, new Uint8Array(results.canvaspx)));
  console.log(`presentPath ${c.path}: canvas ${c.width}x${c.height}`);
}
console.log(`${info.adapter}: ${W}x${H}, frame ms ${info.times.map((t) => t.toFixed(1)).join(", ")}, gpuBytes ${info.gpuBytes}`);
