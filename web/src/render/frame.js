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
 * @param {{scene: import("./scene.js").PackedScene, terrain: import("./index.js").Terrain,
 *          camera: import("./camera.js").Camera, W: number, H: number, albedo?: number[],
 *          pick: number[] | null, pickOnly: boolean}} args
 */
export function frameUniforms({ scene, terrain, camera, W, H, albedo, pick, pickOnly }) {
  const axq = Math.round(camera.eye[0] / Q), ayq = Math.round(camera.eye[1] / Q);
  const ax = axq * Q, ay = ayq * Q;
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
