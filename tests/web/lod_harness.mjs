#!/usr/bin/env node
// lod_harness.mjs — the browser's LOD selection (web/src/render/lod.js, a
// WebGPU compute pass) of a package for a list of views, in headless
// Chromium, as JSON on stdout: per view the LodView that lodView() makes of
// the camera and the visible segments the pass keeps, read back and sorted.
//
//   node tests/web/lod_harness.mjs --pkg P.decals --views VIEWS.json --height H --tolerance T
//
// VIEWS.json as tests/web/view_oracle.cpp reads it ({"name", "eye", "target",
// "fov"} or {"name", "topdown": extent}), metres relative to the package
// origin, over flat ground at height 0.
import { readFileSync } from "node:fs";
import { IMPORT_MAP, runPage } from "./chromium_page.mjs";

const args = Object.fromEntries(
  process.argv.slice(2).reduce((acc, a, i, all) => (a.startsWith("--") ? [...acc, [a.slice(2), all[i + 1]]] : acc), []));
if (!args.pkg || !args.views || !args.height || !args.tolerance) {
  console.error("usage: lod_harness.mjs --pkg P --views VIEWS.json --height H --tolerance T");
  process.exit(2);
}
const job = { views: JSON.parse(readFileSync(args.views, "utf8")), height: Number(args.height),
  tolerance: Number(args.tolerance) };

const PAGE = `<!doctype html><html><head><meta charset="utf-8">${IMPORT_MAP}</head><body><script type="module">
const post = (path, body) => fetch(path, { method: "POST", body });
try {
  const { openPackage, LodSelector, lodView, topdownCamera } = await import("/web/src/index.js");
  const job = await (await fetch("/job.json")).json();
  const pkg = await openPackage(await (await fetch("/pkg.decals")).arrayBuffer(), { label: "pkg.decals" });
  await pkg.validate();
  const adapter = await navigator.gpu.requestAdapter();
  const device = await adapter.requestDevice({ requiredLimits: {
    maxStorageBufferBindingSize: adapter.limits.maxStorageBufferBindingSize, maxBufferSize: adapter.limits.maxBufferSize } });
  const blobs = await LodSelector.blobsOf(pkg);
  if (!blobs) throw new Error("the package has no LOD segments");
  const sel = new LodSelector(device, blobs.points, blobs.segments);
  const out = [];
  for (const v of job.views) {
    const camera = v.topdown ? topdownCamera(v.topdown, 0, 0)
      : { projection: "perspective", eye: v.eye, target: v.target, up: [0, 0, 1], fovYDeg: v.fov };
    const view = lodView(camera, job.height, 0, 0, job.tolerance);
    const t0 = performance.now();
    const visible = await sel.select(view);
    out.push({ name: v.name, view, ms: performance.now() - t0, visible: Array.from(visible) });
  }
  sel.destroy();
  await post("/result/selection", JSON.stringify({ adapter: adapter.info?.architecture ?? "", views: out }));
  await post("/result/done", "");
} catch (e) {
  await post("/result/error", String(e && e.stack || e));
}
</script></body></html>`;

try {
  const results = await runPage({ page: PAGE, files: { "/job.json": { json: job }, "/pkg.decals": args.pkg },
    timeoutS: Number(args.timeout ?? 600) });
  process.stdout.write(results.selection.toString() + "\n");
} catch (e) {
  console.error(String(e.message ?? e));
  process.exit(1);
}
