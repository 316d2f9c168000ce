// camera.js — the view and projection matrices of libprep/render/camera.cpp
// (view_matrix, projection_matrix: infinite reversed Z for perspective, depth
// 1 at the eye plane to 0 at depth_range for orthographic), in double,
// column-major, relative to the frame's anchor.

/**
 * @typedef {{
 *   projection: "perspective" | "orthographic",
 *   eye: number[], target: number[], up: number[],
 *   fovYDeg: number, orthoW: number, orthoH: number,
 *   near: number, depthRange: number,
 *   topdownExtent: number[] | null
 * }} Camera
 */

/** @param {number[]} a @param {number[]} b */
const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
/** @param {number[]} a @param {number[]} b */
const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
/** @param {number[]} a @param {number[]} b */
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
/** @param {number[]} a */
const normalize = (a) => {
  const l = Math.sqrt(dot(a, a));
  return [a[0] / l, a[1] / l, a[2] / l];
};
export { normalize };

/**
 * Column-major view matrix of the camera with its eye at eye_rel.
 * @param {Camera} c @param {number[]} eyeRel
 */
export function viewMatrix(c, eyeRel) {
  const f = normalize(sub(c.target, c.eye));
  const r = normalize(cross(f, c.up));
  const u = cross(r, f);
  const m = new Array(16).fill(0);
  for (let k = 0; k < 3; ++k) {
    m[k * 4 + 0] = r[k];
    m[k * 4 + 1] = u[k];
    m[k * 4 + 2] = -f[k];
  }
  m[12] = -dot(r, eyeRel);
  m[13] = -dot(u, eyeRel);
  m[14] = dot(f, eyeRel);
  m[15] = 1;
  return m;
}

/** @param {Camera} c @param {number} aspect */
export function projectionMatrix(c, aspect) {
  const p = new Array(16).fill(0);
  if (c.projection === "perspective") {
    const f = 1 / Math.tan((c.fovYDeg * Math.PI) / 360);
    p[0] = f / aspect;
    p[5] = f;
    p[14] = c.near;
    p[11] = -1;
  } else {
    p[0] = 2 / c.orthoW;
    p[5] = 2 / c.orthoH;
    p[10] = 1 / c.depthRange;
    p[14] = 1;
    p[15] = 1;
  }
  return p;
}

/** a·b of column-major 4×4 matrices. @param {number[]} a @param {number[]} b */
export function matMul(a, b) {
  const m = new Array(16).fill(0);
  for (let col = 0; col < 4; ++col)
    for (let row = 0; row < 4; ++row) {
      let s = 0;
      for (let k = 0; k < 4; ++k) s += a[k * 4 + row] * b[col * 4 + k];
      m[col * 4 + row] = s;
    }
  return m;
}

/**
 * The camera render uses for `--extent` (camera.cpp topdown_camera): straight
 * down over the extent, orthographic, north up.
 * @param {number[]} e [xmin, ymin, xmax, ymax] metres relative to the origin
 * @param {number} zmin @param {number} zmax
 * @returns {Camera}
 */
export function topdownCamera(e, zmin, zmax) {
  const cx = 0.5 * (e[0] + e[2]), cy = 0.5 * (e[1] + e[3]);
  const top = zmax + Math.max(100, 0.1 * (zmax - zmin));
  return {
    projection: "orthographic",
    eye: [cx, cy, top],
    target: [cx, cy, zmin - 1],
    up: [0, 1, 0],
    fovYDeg: 45,
    orthoW: e[2] - e[0],
    orthoH: e[3] - e[1],
    near: 0.1,
    depthRange: top - zmin + 1000,
    topdownExtent: e.slice(),
  };
}
