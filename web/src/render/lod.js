// lod.js — LOCALIS LOD at draw time (formats/SPEC.md "Visibility rule" and
// "Choosing the threshold"): which of a package's LOD segments a view shows,
// chosen per segment in a WebGPU compute pass, the port of
// formats/gl/shaders/lod_select.comp.glsl.
//
// WGSL has no f64, so the rule is evaluated in f32 around an integer anchor
// (SPEC "Visibility rule", "Readers without double precision"): the camera
// is split into whole quanta (ax, ay) and a remainder of at most half a
// quantum, each point's offset from the anchor is an exact i32 difference
// before it becomes a float, so the distance d carries a relative error of a
// few f32 ulps whatever the coordinates, and a point's verdict can differ
// from the double evaluation (decal::visible_segments) only where e* lies
// within that error of eps(d - d*).

/** Metres per stored quantum (formats/SPEC.md "Coordinates"). */
const Q = 0.001;

/**
 * The view's LOD parameters, prep::render::lod_view's: the camera C of the
 * rule and eps(d) = base + slope * max(d, 0). Perspective: C = (eye x, eye
 * y, the eye's height outside the terrain range [zmin, zmax], 0 within it),
 * slope = tolerance * 2 tan(fovy / 2) / height, base 0. Orthographic: base =
 * tolerance * ortho_h / height, C unused.
 * @typedef {{cx: number, cy: number, cz: number, base: number, slope: number}} LodView
 * @param {import("./camera.js").Camera} camera
 * @param {number} height  image height in pixels
 * @param {number} zmin @param {number} zmax  the terrain's height range
 * @param {number} tolerancePx  render --lod-tolerance (0.5 by default)
 * @returns {LodView}
 */
export function lodView(camera, height, zmin, zmax, tolerancePx) {
  if (camera.projection === "orthographic")
    return { cx: 0, cy: 0, cz: 0, base: (tolerancePx * camera.orthoH) / height, slope: 0 };
  const z = camera.eye[2];
  const cz = z > zmax ? z - zmax : z < zmin ? zmin - z : 0;
  const slope = (tolerancePx * 2 * Math.tan((camera.fovYDeg * Math.PI) / 360)) / height;
  return { cx: camera.eye[0], cy: camera.eye[1], cz, base: 0, slope };
}

export const LOD_WGSL = /* wgsl */ `
struct View {
  anchor: vec4<i32>,  // the camera's x, y in whole quanta from the package origin
  rest: vec4f,        // the camera's remainder x, y (metres, |.| <= q / 2); cz; 0
  eps: vec4f,         // eps(d) = base + slope * max(d, 0): base, slope
  n: vec4<u32>,       // LOD segments
}
@group(0) @binding(0) var<uniform> V: View;
// lod_points: 8 words each (x, y, eval_x, eval_y, e_star, d_star, line, flags)
@group(0) @binding(1) var<storage, read> P: array<u32>;
// lod_segments: (a, b, generator, splitter)
@group(0) @binding(2) var<storage, read> S: array<vec4<u32>>;
// [0] the count of visible segments, [4..] their indices (in no order)
@group(0) @binding(3) var<storage, read_write> SEL: array<atomic<u32>>;

const NONE = 0xffffffffu;
const Q: f32 = 0.001;

fn included(i: u32) -> bool {
  let b = 8u * i;
  if ((P[b + 7u] & 1u) != 0u) { return true; }
  // The offset from the anchor in whole quanta first (exact), then metres.
  let dx = f32(bitcast<i32>(P[b + 2u]) - V.anchor.x) * Q - V.rest.x;
  let dy = f32(bitcast<i32>(P[b + 3u]) - V.anchor.y) * Q - V.rest.y;
  let d = sqrt(dx * dx + dy * dy + V.rest.z * V.rest.z) - bitcast<f32>(P[b + 5u]);
  let eps = V.eps.x + V.eps.y * max(d, 0.0);
  return bitcast<f32>(P[b + 4u]) > eps;
}

@compute @workgroup_size(256)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
  let s = gid.x + 65535u * 256u * gid.y;
  if (s >= V.n.x) { return; }
  let g = S[s];
  let generated = g.z == NONE || included(g.z);
  let split = g.w != NONE && included(g.w);
  if (!generated || split) { return; }
  atomicStore(&SEL[4u + atomicAdd(&SEL[0], 1u)], s);
}
`;

// GPUBufferUsage bits (numbers, so that this module loads without WebGPU).
const STORAGE = 128, COPY_SRC = 4, COPY_DST = 8, UNIFORM = 64, MAP_READ = 1;

/** The LOD selection of one package on a device. */
export class LodSelector {
  /**
   * @param {any} device  a GPUDevice
   * @param {Uint32Array} points  lod_points as words (8 a point)
   * @param {Uint32Array} segments  lod_segments as words (4 a segment)
   */
  constructor(device, points, segments) {
    this.device = device;
    this.segmentCount = segments.length / 4;
    const d = device;
    const upload = (/** @type {Uint32Array} */ words) => {
      const b = d.createBuffer({ size: Math.max(16, words.byteLength), usage: STORAGE | COPY_DST });
      if (words.byteLength > 0) d.queue.writeBuffer(b, 0, words);
      return b;
    };
    this.points = upload(points);
    this.segments = upload(segments);
    this.selectionBytes = 16 + 4 * Math.max(1, this.segmentCount);
    this.selection = d.createBuffer({ size: this.selectionBytes, usage: STORAGE | COPY_SRC | COPY_DST });
    this.read = d.createBuffer({ size: this.selectionBytes, usage: MAP_READ | COPY_DST });
    this.uniform = d.createBuffer({ size: 64, usage: UNIFORM | COPY_DST });
    this.pipeline = d.createComputePipeline({ layout: "auto",
      compute: { module: d.createShaderModule({ code: LOD_WGSL }), entryPoint: "main" } });
  }

  /**
   * The package's LOD blobs as words, or null when it has none.
   * @param {import("../package.js").Package} pkg
   * @returns {Promise<{points: Uint32Array, segments: Uint32Array} | null>}
   */
  static async blobsOf(pkg) {
    const has = (/** @type {string} */ n) => pkg.blobs.some((b) => b.name === n && b.count > 0);
    if (!has("lod_points") || !has("lod_segments")) return null;
    const words = async (/** @type {string} */ n) => {
      const a = /** @type {ArrayBufferView} */ (await pkg.array(n));
      return new Uint32Array(a.buffer, a.byteOffset, a.byteLength / 4);
    };
    return { points: await words("lod_points"), segments: await words("lod_segments") };
  }

  /**
   * Encodes the selection for `view` (the count reset, then one pass).
   * @param {any} encoder  a GPUCommandEncoder
   * @param {LodView} view
   */
  encode(encoder, view) {
    const ax = Math.round(view.cx / Q), ay = Math.round(view.cy / Q);
    const u = new ArrayBuffer(64);
    new Int32Array(u).set([ax, ay, 0, 0], 0);
    new Float32Array(u).set([view.cx - ax * Q, view.cy - ay * Q, view.cz, 0, view.base, view.slope, 0, 0], 4);
    new Uint32Array(u).set([this.segmentCount, 0, 0, 0], 12);
    this.device.queue.writeBuffer(this.uniform, 0, u);
    this.device.queue.writeBuffer(this.selection, 0, new Uint32Array(4));
    const groups = Math.ceil(this.segmentCount / 256);
    const cp = encoder.beginComputePass();
    cp.setPipeline(this.pipeline);
    cp.setBindGroup(0, this.device.createBindGroup({ layout: this.pipeline.getBindGroupLayout(0),
      entries: [this.uniform, this.points, this.segments, this.selection].map((buffer, binding) =>
        ({ binding, resource: { buffer } })) }));
    cp.dispatchWorkgroups(Math.min(groups, 65535), Math.ceil(groups / 65535));
    cp.end();
  }

  /**
   * Runs the selection for `view` and reads it back: the visible segments'
   * indices in increasing order (decal::visible_segments' order).
   * @param {LodView} view
   * @returns {Promise<Uint32Array>}
   */
  async select(view) {
    const enc = this.device.createCommandEncoder();
    this.encode(enc, view);
    enc.copyBufferToBuffer(this.selection, 0, this.read, 0, this.selectionBytes);
    this.device.queue.submit([enc.finish()]);
    await this.read.mapAsync(MAP_READ);
    const all = new Uint32Array(this.read.getMappedRange().slice(0));
    this.read.unmap();
    return all.subarray(4, 4 + all[0]).sort();
  }

  destroy() {
    for (const b of [this.points, this.segments, this.selection, this.read, this.uniform]) b.destroy();
  }
}

const LOD_NONE = 0xffffffff;

/**
 * How the LOD segments are drawn on the package's dynamic lines
 * (decal::lod_draw_map, formats/SPEC.md "Choosing the threshold"): per LOD
 * point its dyn_vertices index and its end link (NONE inside a line; the
 * point itself at an open line's ends; the other end at a closed ring's),
 * and per dynamic line 1 when it is drawn from its LOD segments. A LOD line
 * whose points do not all map, or whose dynamic line another LOD line also
 * names, is drawn from its full vertex chain instead.
 * @param {Uint32Array} points  lod_points words (8 a point: x, y, eval_x, eval_y, e*, d*, line, flags)
 * @param {Uint32Array} segments  lod_segments words (a, b, generator, splitter)
 * @param {Uint32Array} lineRange  lod_line_range words (first, count)
 * @param {Int32Array} dynVertices  dyn_vertices (x, y, z, line)
 * @param {Uint32Array} dynLineStart
 * @param {Int32Array} dynPrevNext
 * @returns {{vertex: Uint32Array, end: Uint32Array, lineDrawn: Uint32Array, lines: number}}
 */
export function lodDrawMap(points, segments, lineRange, dynVertices, dynLineStart, dynPrevNext) {
  const np = points.length / 8, ns = segments.length / 4, nv = dynVertices.length / 4, nl = dynLineStart.length;
  const m = { vertex: new Uint32Array(np).fill(LOD_NONE), end: new Uint32Array(np).fill(LOD_NONE),
    lineDrawn: new Uint32Array(Math.max(1, nl)), lines: 0 };
  if (nv === 0 || dynPrevNext.length !== 2 * nv) return m;
  const px = (/** @type {number} */ p) => points[8 * p] | 0, py = (/** @type {number} */ p) => points[8 * p + 1] | 0;
  const lineOf = (/** @type {number} */ p) => points[8 * p + 6];
  /** @type {{first: number, last: number, dyn: number}[]} */
  const lines = [];
  const claims = new Uint32Array(Math.max(1, nl));
  for (let r = 0; r < lineRange.length; r += 2) {
    const f0 = lineRange[r], n = lineRange[r + 1];
    if (n === 0 || f0 + n > ns) continue;
    let first = LOD_NONE, last = 0;
    for (let s = f0; s < f0 + n; ++s) {
      first = Math.min(first, segments[4 * s], segments[4 * s + 1]);
      last = Math.max(last, segments[4 * s], segments[4 * s + 1]);
    }
    if (last >= np || first >= last) continue;
    const dyn = lineOf(first);
    let same = dyn < nl;
    for (let p = first; same && p <= last; ++p) same = lineOf(p) === dyn;
    if (!same) continue;
    claims[dyn] += 1;
    lines.push({ first, last, dyn });
  }
  for (const l of lines) {
    if (claims[l.dyn] !== 1) continue;
    const start = dynLineStart[l.dyn];
    const stop = l.dyn + 1 < nl ? dynLineStart[l.dyn + 1] : nv;
    if (start >= stop || stop > nv) continue;
    const closed = dynPrevNext[2 * start] >= 0;
    const sameXY = (/** @type {number} */ v, /** @type {number} */ p) => dynVertices[4 * v] === px(p) && dynVertices[4 * v + 1] === py(p);
    const found = [];
    let v = start;
    for (let p = l.first; p <= l.last; ++p) {
      if (closed && p === l.last) {  // the ring's repeated first point
        if (sameXY(start, p)) found.push(start);
        break;
      }
      while (v < stop && !sameXY(v, p)) ++v;
      if (v === stop) break;
      found.push(v);
    }
    if (found.length !== l.last - l.first + 1) continue;
    for (let p = l.first; p <= l.last; ++p) m.vertex[p] = found[p - l.first];
    m.end[l.first] = closed ? l.last : l.first;
    m.end[l.last] = closed ? l.first : l.last;
    m.lineDrawn[l.dyn] = 1;
    m.lines += 1;
  }
  return m;
}

/**
 * The uniform of the LOD passes for `view` (wgsl_dynamic.js struct Lod): the
 * camera as whole quanta and a remainder, eps, the counts and word offsets.
 * @param {LodView} view @param {number[]} counts  points, segments
 * @param {number[]} offsets  words of points, segments, map, line flags in the LOD buffer
 */
export function lodUniform(view, counts, offsets) {
  const ax = Math.round(view.cx / Q), ay = Math.round(view.cy / Q);
  const u = new ArrayBuffer(80);
  new Int32Array(u).set([ax, ay, 0, 0], 0);
  new Float32Array(u).set([view.cx - ax * Q, view.cy - ay * Q, view.cz, 0, view.base, view.slope, 0, 0], 4);
  new Uint32Array(u).set([counts[0], counts[1], 0, 0, ...offsets], 12);
  return u;
}
