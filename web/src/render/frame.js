// frame.js — one frame's uniforms, the same bytes for both renderers
// (index.js drawFrame and webgl2.js): the anchor
// (the eye rounded to whole quanta, gl_passes.cpp view_uniforms), the
// terrain pass's uniform (wgsl_frame.js TERRAIN_WGSL) and the decal pass's
// frame (wgsl_decals.js Frame, which glsl_decals.js declares as a std140
// block of the same layout).

import { FRAME_BYTES } from "./wgsl_decals.js";
import { TERRAIN_UNIFORM_BYTES } from "./wgsl_frame.js";
import { viewMatrix, projectionMatrix, matMul, mat4Inverse, normalize, cameraBasis } from "./camera.js";

const Q = 0.001;

/** Integer floor division. @param {number} a @param {number} b */
const floorDiv = (a, b) => Math.floor(a / b);

/**
 * The anchor (axq, ayq whole quanta; ax, ay metres), the eye relative to it,
 * the view-projection matrix, the terrain uniform and the decal frame of a
 * W x H frame of `camera`.
 * pick: the pick pixel (x, y) or null; pickOnly: the frame is drawn for it alone.
 * clip: a tileset tile's square [xmin, ymin, xmax, ymax] (metres in the
 * camera's frame): decals only at ground points inside it, half-open, as
 * gl_passes.cpp set_clip. box: the pixel the decal dispatch starts at (the
 * tile's box; a pick-only frame starts at the pick pixel's 8x8 block).
 * anchorQ: the anchor in whole quanta where it is not the eye's (a tile
 * beyond the reach of 32-bit quanta from the eye: tileFrames). shiftQ: a
 * tileset tile's offset from the frame's origin in whole quanta: the
 * scene's integer positions are the tile's, so the integer anchor and its
 * grid cell are taken in the tile's frame (the anchor minus the shift),
 * while every float (eye, matrices, terrain, clip, top-down extent) stays
 * relative to the frame's anchor, bit for bit the index frame's
 * (gl_passes.cpp load_tile). Returns axq, ayq in the scene's frame, ax, ay
 * (metres) in the camera's.
 * @param {{scene: import("./scene.js").PackedScene, terrain: import("./index.js").Terrain,
 *          camera: import("./camera.js").Camera, W: number, H: number, albedo?: number[],
 *          pick: number[] | null, pickOnly: boolean, clip?: number[] | null, box?: number[],
 *          anchorQ?: number[], shiftQ?: number[]}} args
 */
export function frameUniforms({ scene, terrain, camera, W, H, albedo, pick, pickOnly, clip, box, anchorQ, shiftQ }) {
  const aq = anchorQ ?? [Math.round(camera.eye[0] / Q), Math.round(camera.eye[1] / Q)];
  const ax = aq[0] * Q, ay = aq[1] * Q;
  const axq = aq[0] - (shiftQ?.[0] ?? 0), ayq = aq[1] - (shiftQ?.[1] ?? 0);
  const eyeRel = [camera.eye[0] - ax, camera.eye[1] - ay, camera.eye[2]];
  const vp = matMul(projectionMatrix(camera, W / H), viewMatrix(camera, eyeRel));
  const light = normalize([-0.4, -0.5, 0.75]);
  const alb = albedo ?? [0.62, 0.66, 0.58];
  const tu = new Float32Array(TERRAIN_UNIFORM_BYTES / 4);
  tu.set(vp, 0);
  tu.set([light[0], light[1], light[2], terrain.zmax > terrain.zmin ? 0 : -1e30], 16);
  tu.set([alb[0], alb[1], alb[2], 1], 20);
  const g = scene.grid;
  const rx = axq - g.gx, ry = ayq - g.gy;
  const cx = floorDiv(rx, g.cw), cy = floorDiv(ry, g.ch);
  const fb = new ArrayBuffer(FRAME_BYTES);
  const fi = new Int32Array(fb), ff = new Float32Array(fb), fu = new Uint32Array(fb);
  fi.set([axq, ayq, cx, cy], 0);
  ff.set([(rx - cx * g.cw) * Q, (ry - cy * g.ch) * Q, g.cw * Q, g.ch * Q], 4);
  fi.set([g.nx, g.ny, g.gx, g.gy], 8);
  const td = camera.topdownExtent;
  const flags = (td ? 1 : 0) | (scene.haveLines ? 2 : 0) | (scene.havePolygons ? 4 : 0);
  fi.set([g.cw, g.ch, scene.shift, flags], 12);
  fu.set([W, H, scene.polyBias, scene.minWidthCount], 16);
  if (td) ff.set([td[0] - ax, td[3] - ay, (td[2] - td[0]) / W, -(td[3] - td[1]) / H], 20);
  fu.set(scene.offsets, 24);
  ff.set(mat4Inverse(vp), 48);
  ff.set([terrain.x0 - ax, terrain.y0 - ay, terrain.dx, terrain.dy], 64);
  fu.set([terrain.nx, terrain.ny, scene.slopeCount, scene.unlitCount], 68);
  const basis = cameraBasis(camera);
  const persp = camera.projection === "perspective";
  const th = Math.tan((camera.fovYDeg * Math.PI) / 360);
  const sx = persp ? th * (W / H) : 0.5 * camera.orthoW, sy = persp ? th : 0.5 * camera.orthoH;
  ff.set([...eyeRel, persp ? 1 : 0], 72);
  ff.set([...basis.r.map((x) => x * sx), 0, ...basis.u.map((x) => x * sy), 0, ...basis.f, 0], 76);
  ff.set([scene.minWidthLimit, scene.minWidthReach, persp ? 0 : camera.orthoH / H,
          persp ? (2 * th) / H : 0], 88);
  if (pick) fu.set([pick[0], pick[1], 1, pickOnly ? 1 : 0], 92);
  if (clip) {
    ff.set([clip[0] - ax, clip[1] - ay, clip[2] - ax, clip[3] - ay], 96);
    fu[102] = 1;
  }
  if (pick && pickOnly) fu.set([pick[0] & ~7, pick[1] & ~7], 100);
  else if (box) fu.set([box[0], box[1]], 100);
  return { axq, ayq, ax, ay, eyeRel, vp, terrainUniform: tu, frame: fb };
}

/**
 * The terrain mesh relative to the anchor (metres, double then float, as
 * gl_passes.cpp upload_terrain_mesh), normals of Heightfield::normal_at:
 * per vertex x, y, z, nx, ny, nz; two triangles per cell, (00, 10, 11) and
 * (00, 11, 01). Both renderers upload it (index.js and webgl2.js meshFor).
 * @param {import("./index.js").Terrain} t @param {number} ax @param {number} ay anchor, metres
 */
export function terrainMesh(t, ax, ay) {
  const { nx, ny } = t;
  const v = new Float32Array(nx * ny * 6);
  const zat = (/** @type {number} */ a, /** @type {number} */ b) =>
    t.z[Math.min(Math.max(a, 0), nx - 1) + nx * Math.min(Math.max(b, 0), ny - 1)];
  for (let j = 0; j < ny; ++j)
    for (let i = 0; i < nx; ++i) {
      const gx = (zat(i + 1, j) - zat(i - 1, j)) / (2 * t.dx);
      const gy = (zat(i, j + 1) - zat(i, j - 1)) / (2 * t.dy);
      const n = normalize([-gx, -gy, 1]);
      const k = 6 * (i + nx * j);
      v[k] = t.x0 + i * t.dx - ax;
      v[k + 1] = t.y0 + j * t.dy - ay;
      v[k + 2] = t.z[i + nx * j];
      v[k + 3] = n[0]; v[k + 4] = n[1]; v[k + 5] = n[2];
    }
  const idx = new Uint32Array((nx - 1) * (ny - 1) * 6);
  let at = 0;
  for (let j = 0; j + 1 < ny; ++j)
    for (let i = 0; i + 1 < nx; ++i) {
      const v00 = i + nx * j, v10 = v00 + 1, v01 = v00 + nx, v11 = v01 + 1;
      idx.set([v00, v10, v11, v00, v11, v01], at);
      at += 6;
    }
  return { vertices: v, indices: idx };
}

/**
 * The pixels a square can draw in (gl_passes.cpp tile_scissor, rows from
 * the top): the box of the images of its corners at the terrain's lowest
 * and highest height, grown by 2 pixels and cut to the frame, as [x0, y0,
 * x1, y1) ; the whole frame when a corner is not in front of the camera;
 * null when the box is empty.
 * @param {Float32Array | number[]} vp  the view-projection relative to the anchor (column-major)
 * @param {number[]} sq  [xmin, ymin, xmax, ymax] relative to the anchor
 * @param {number} zmin @param {number} zmax @param {number} W @param {number} H
 * @returns {number[] | null}
 */
export function squareBox(vp, sq, zmin, zmax, W, H) {
  let x0 = Infinity, y0 = Infinity, x1 = -Infinity, y1 = -Infinity;
  for (let k = 0; k < 8; ++k) {
    const p = [sq[k & 1 ? 2 : 0], sq[k & 2 ? 3 : 1], k & 4 ? zmax : zmin];
    const c = [0, 1, 2, 3].map((r) => vp[r] * p[0] + vp[4 + r] * p[1] + vp[8 + r] * p[2] + vp[12 + r]);
    if (!(c[3] > 1e-6) || !Number.isFinite(c[0] / c[3]) || !Number.isFinite(c[1] / c[3])) return [0, 0, W, H];
    const px = (0.5 * c[0] / c[3] + 0.5) * W, py = (0.5 - 0.5 * c[1] / c[3]) * H;
    x0 = Math.min(x0, px); x1 = Math.max(x1, px); y0 = Math.min(y0, py); y1 = Math.max(y1, py);
  }
  const clamp = (/** @type {number} */ v, /** @type {number} */ hi) => Math.min(Math.max(v, 0), hi);
  const b = [clamp(Math.floor(x0) - 2, W), clamp(Math.floor(y0) - 2, H), clamp(Math.ceil(x1) + 2, W),
    clamp(Math.ceil(y1) + 2, H)];
  return b[2] > b[0] && b[3] > b[1] ? b : null;
}

/**
 * What a tileset frame's tiles are drawn with: the frame's camera, terrain
 * (in the tileset's frame), size, albedo and pick, its view-projection and
 * anchor (metres; frameUniforms of the index frame).
 * @typedef {{camera: import("./camera.js").Camera, terrain: import("./index.js").Terrain, W: number, H: number,
 *            albedo?: number[], pick: number[] | null, pickOnly: boolean, vp: Float32Array | number[],
 *            ax: number, ay: number}} TileFrameArgs
 */

/** The most quanta a stored i32 position may lie from the anchor on an axis. */
const REACH = 2 ** 31 - 1;

/**
 * The anchor (whole quanta) a tile whose square is `sq` (metres in the
 * tile's frame) draws with: `at` (the eye's) when every point of the
 * square, grown by 1% for the margin, lies within 2^31 - 1 quanta of it on
 * each axis, else the nearest anchor that does (gl_passes.cpp load_tile),
 * so that the shaders' integer differences q - anchor do not overflow.
 * @param {number[]} sq @param {number[]} at
 */
export function tileAnchor(sq, at) {
  const pad = 0.01 * (sq[2] - sq[0]);
  const reach = (/** @type {number} */ lo, /** @type {number} */ hi, /** @type {number} */ a) => {
    const l = (hi + pad) / Q - REACH, h = (lo - pad) / Q + REACH;
    return l > h ? a : Math.min(Math.max(a, Math.ceil(l)), Math.floor(h));
  };
  return [reach(sq[0], sq[2], at[0]), reach(sq[1], sq[3], at[1])];
}

/**
 * The decal frames of one tile of a tileset frame (gl_passes.cpp load_tile
 * and tile_scissor): per square of the tile that the image meets, the
 * tile's frame (the index frame with the integer anchor moved by the tile's
 * offset, a whole number of quanta, so every anchor-relative float is the
 * index frame's: frameUniforms shiftQ; for a tile beyond 32-bit reach of
 * the eye, tileAnchor's anchor, the matrices made again around it) with
 * the square as its clip, and the square's pixel box (squareBox). A
 * pick-only frame keeps the squares whose box holds the pick.
 * @param {import("./index.js").FrameTile} t
 * @param {import("./scene.js").PackedScene} scene  the tile's
 * @param {TileFrameArgs} f
 * Each also gives its uniforms (frameUniforms), the camera in the tile's
 * frame (for its LOD view), the square (in the index frame) and, for its
 * dynamic lines and WebGL2's ground points, the offset from a ground point
 * relative to the index anchor to one relative to the tile's (0 unless the
 * anchor moved).
 * @returns {{frame: ArrayBuffer, box: number[], u: ReturnType<typeof frameUniforms>,
 *            camera: import("./camera.js").Camera, clip: number[], go: number[]}[]}
 */
export function tileFrames(t, scene, f) {
  const shift = (/** @type {number[]} */ v) => [v[0] - t.dx, v[1] - t.dy, v[2]];
  const td = f.camera.topdownExtent;
  const camera = { ...f.camera, eye: shift(f.camera.eye), target: shift(f.camera.target),
    topdownExtent: td ? [td[0] - t.dx, td[1] - t.dy, td[2] - t.dx, td[3] - t.dy] : null };
  const own = t.square ?? [Math.min(...t.clips.map((c) => c[0])), Math.min(...t.clips.map((c) => c[1])),
    Math.max(...t.clips.map((c) => c[2])), Math.max(...t.clips.map((c) => c[3]))];
  // The tile's offset and the index anchor, whole quanta; the anchor in
  // the tile's frame is their difference, exactly.
  const shiftQ = [Math.round(t.dx / Q), Math.round(t.dy / Q)];
  const eyeQ = [Math.round(f.ax / Q), Math.round(f.ay / Q)];
  const at = [eyeQ[0] - shiftQ[0], eyeQ[1] - shiftQ[1]];
  const moved = tileAnchor([own[0] - t.dx, own[1] - t.dy, own[2] - t.dx, own[3] - t.dy], at);
  const far = moved[0] !== at[0] || moved[1] !== at[1];
  const anchorQ = far ? [moved[0] + shiftQ[0], moved[1] + shiftQ[1]] : undefined;
  const go = [(at[0] - moved[0]) * Q, (at[1] - moved[1]) * Q];
  const out = [];
  for (const c of t.clips) {
    const box = squareBox(f.vp, [c[0] - f.ax, c[1] - f.ay, c[2] - f.ax, c[3] - f.ay],
      f.terrain.zmin, f.terrain.zmax, f.W, f.H);
    if (!box) continue;
    const p = f.pick;
    if (f.pickOnly && p && !(p[0] >= box[0] && p[0] < box[2] && p[1] >= box[1] && p[1] < box[3])) continue;
    const u = frameUniforms({ scene, terrain: f.terrain, camera: f.camera, W: f.W, H: f.H, albedo: f.albedo,
      pick: f.pick, pickOnly: f.pickOnly, clip: c, box, anchorQ, shiftQ });
    out.push({ frame: u.frame, box, u, camera, clip: c, go });
  }
  return out;
}
