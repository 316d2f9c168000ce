#!/usr/bin/env node
// webgpu_compare.mjs — pixel agreement of two PNGs of the same size:
//   node tests/web/webgpu_compare.mjs REFERENCE.png OTHER.png [--tol 1] [--min 0.999] [--all]
// The edge band: pixels whose 3×3 neighbourhood in REFERENCE is not uniform
// (image borders: the neighbours inside). Prints pixels compared (outside
// the band), the mismatches there (a channel differs by more than tol/255),
// the largest channel difference, and exits 1 when the agreement is below min
// (with --all: the agreement over every pixel, the edge band included).
import { readFileSync } from "node:fs";
import { decodePng } from "./webgpu_png.mjs";

const argv = process.argv.slice(2);
const opt = (name, def) => {
  const i = argv.indexOf(name);
  return i >= 0 ? Number(argv[i + 1]) : def;
};
const a = decodePng(readFileSync(argv[0]));
const b = decodePng(readFileSync(argv[1]));
if (a.width !== b.width || a.height !== b.height) {
  console.error(`sizes differ: ${a.width}x${a.height} vs ${b.width}x${b.height}`);
  process.exit(2);
}
const tol = opt("--tol", 1), min = opt("--min", 0.999);
const { width: W, height: H } = a;
const same = (i, j) => a.rgba[4 * i] === a.rgba[4 * j] && a.rgba[4 * i + 1] === a.rgba[4 * j + 1] &&
                       a.rgba[4 * i + 2] === a.rgba[4 * j + 2] && a.rgba[4 * i + 3] === a.rgba[4 * j + 3];
let compared = 0, band = 0, bad = 0, maxOut = 0, maxAll = 0, badAll = 0;
for (let y = 0; y < H; ++y)
  for (let x = 0; x < W; ++x) {
    const k = x + W * y;
    let uniform = true;
    for (let dy = -1; dy <= 1 && uniform; ++dy)
      for (let dx = -1; dx <= 1; ++dx) {
        const xx = x + dx, yy = y + dy;
        if (xx < 0 || yy < 0 || xx >= W || yy >= H) continue;
        if (!same(k, xx + W * yy)) { uniform = false; break; }
      }
    let diff = 0;
    for (let c = 0; c < 4; ++c) diff = Math.max(diff, Math.abs(a.rgba[4 * k + c] - b.rgba[4 * k + c]));
    maxAll = Math.max(maxAll, diff);
    if (diff > tol) ++badAll;
    if (!uniform) { ++band; continue; }
    ++compared;
    maxOut = Math.max(maxOut, diff);
    if (diff > tol) ++bad;
  }
const all = argv.includes("--all");
const agree = all ? (W * H - badAll) / (W * H) : compared ? (compared - bad) / compared : 1;
console.log(`${W}x${H}: ${compared} pixels outside the edge band (${band} in it); ` +
            `${bad} differ by more than ${tol}/255 (agreement ${(100 * agree).toFixed(4)}%), ` +
            `max channel difference ${maxOut} outside the band, ${maxAll} overall; ` +
            `${badAll} mismatches in all`);
process.exit(agree >= min ? 0 : 1);
