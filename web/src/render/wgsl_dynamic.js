// wgsl_dynamic.js — the dynamic-line passes (formats/SPEC.md "Dynamic lines:
// drawing"; thesis §4.3, §4.4.2) in WGSL: the port of libprep/render/
// gl_dynamic.cpp and formats/gl/shaders/dyn_common.glsl, dyn_cull.comp.glsl,
// dyn_scan.comp.glsl, dyn_segments.comp.glsl, dyn_box.geom.glsl,
// dyn_scale.glsl, dyn_dash.comp.glsl, dyn_lists.frag.glsl, dash.glsl and
// dyn_composite.frag.glsl, aliased (GL's --aa none), and of lod_mask,
// lod_select and lod_segments.comp.glsl (DYN_LOD_WGSL: LOD lines drawn from
// the LOD segments the view selects).
//
//   update (compute, DYN_UPDATE_WGSL): per vertex the cull and same-pixel
//     removal, the stream compaction of the kept vertices (an exclusive
//     scan in three dispatches) and the segments, appended with an atomic
//     counter that the lists pass draws indirectly; with dashed lines, each
//     kept vertex's screen distance from its line's start (a segmented
//     scan in three more dispatches);
//   lists (render, DYN_LISTS_WGSL): WebGPU has no geometry shader, so each
//     segment's box is pulled by the vertex shader, 36 vertices (six quads)
//     per instance, one instance per segment; its fragments test the pixel's
//     ground point against the segment at the pixel's own scale and push
//     (order, line) onto the pixel's linked list with fragment-stage atomics;
//   composite (compute, DYN_COMPOSITE_WGSL): each pixel's list walked once
//     per line, the smallest order not yet composited each time, front to
//     back until opaque, into the dynamic layer that the frame composite
//     lays over the static decals (wgsl_frame.js COMPOSITE_WGSL).
//
// Positions are metres relative to the frame's anchor (whole quanta), made
// relative in integers first, as the static pass does.

/** Blob slots of the packed dynamic-line buffer (scene.js packDynamic), in the order of DYN.off. */
export const DYN_SLOTS = ["dyn_vertices", "dyn_prev_next", "dyn_line_start", "dyn_line_props", "dyn_min_widths",
                          "dash_table"];

/** Bytes of the uniform of every dynamic pass (the struct Dyn below). */
export const DYN_UNIFORM_BYTES = 192;

/**
 * Counter words (C): 0–3 the indirect draw of the lists pass (36 vertices,
 * the segment count as instances, 0, 0; copied to its own INDIRECT buffer
 * between the passes), 4 kept vertices, 5 list nodes asked for, 6 the node
 * capacity, 7 unused, 8 pixels whose composite reached its step bound.
 */
export const DYN_COUNTER_WORDS = 12;

const COMMON = /* wgsl */ `
struct Dyn {
  vp: mat4x4f,     // anchor-relative world -> clip (reversed Z)
  a: vec4<i32>,    // anchor (quanta); vertex count; line count
  s: vec4f,        // viewport width, height; clip w of the near plane (perspective, else 0); cos of the miter limit
  e: vec4f,        // eye (anchor-relative); metres per pixel of an orthographic view (0: perspective)
  m: vec4f,        // metres per pixel per metre of distance (perspective); terrain zmin, zmax (m)
  off: vec4<u32>,  // word offsets: dyn_vertices, dyn_prev_next, dyn_line_start, dyn_line_props
  // word offset of the min_width_m table (f32), its entries (0: none); word
  // offset of the dash table (scene.js dashWords); 1 when a line is dashed
  o2: vec4<u32>,
  // A tileset's tile (go.z = 1): its lines only at ground points in
  // [x, z) x [y, w) (anchor-relative metres, gl_passes.cpp set_clip), and
  // composited only where its lists are not empty.
  cl: vec4f,
  // go.xy: a ground point of GP (relative to the frame's index anchor) to
  // this anchor (0 unless a far tile's anchor moved: frame.js tileAnchor).
  go: vec4f,
}
@group(0) @binding(0) var<uniform> D: Dyn;
@group(0) @binding(1) var<storage, read> DB: array<u32>;

const NONE = 0xffffffffu;
const QM: f32 = 0.001;

fn dvertex(v: u32) -> vec4<i32> {
  let o = D.off.x + 4u * v;
  return vec4<i32>(bitcast<i32>(DB[o]), bitcast<i32>(DB[o + 1u]), bitcast<i32>(DB[o + 2u]), bitcast<i32>(DB[o + 3u]));
}
fn dprev_next(v: u32) -> vec2<i32> {
  let o = D.off.y + 2u * v;
  return vec2<i32>(bitcast<i32>(DB[o]), bitcast<i32>(DB[o + 1u]));
}
fn dline_start(l: u32) -> u32 { return DB[D.off.z + l]; }
// (half_width bits, rgba, order, style) of LineProps
fn dprops(l: u32) -> vec4<u32> {
  let o = D.off.w + 8u * l;
  return vec4<u32>(DB[o], DB[o + 1u], DB[o + 2u], DB[o + 3u]);
}
fn dlayer(l: u32) -> u32 { return DB[D.off.w + 8u * l + 5u]; }
fn dpos(v: u32) -> vec3f {
  let q = dvertex(v);
  return vec3f(vec2f(q.xy - D.a.xy) * QM, f32(q.z) * QM);
}
fn vertex_count() -> u32 { return u32(D.a.z); }
fn line_count() -> u32 { return u32(D.a.w); }
fn dash_vertex_at(v: u32) -> u32 { return 3u * vertex_count() + v; }

// Pixel position of clip coordinates.
fn screen_of(c: vec4f) -> vec2f { return (c.xy / c.w * 0.5 + 0.5) * D.s.xy; }
// Screen length, pixels, of the part of the segment between clip points
// ca and cb in front of the near plane (formats/SPEC.md "Dashed lines").
fn screen_length(ca0: vec4f, cb0: vec4f) -> f32 {
  var ca = ca0;
  var cb = cb0;
  let nw = D.s.z;
  if (ca.w < nw && cb.w < nw) { return 0.0; }
  if (ca.w < nw) { ca = mix(ca, cb, (nw - ca.w) / (cb.w - ca.w)); }
  else if (cb.w < nw) { cb = mix(cb, ca, (nw - cb.w) / (ca.w - cb.w)); }
  return length(screen_of(cb) - screen_of(ca));
}

// dyn_scale.glsl: world metres per pixel at p (thesis Eq. 4.1/4.2).
fn metres_per_pixel(p: vec3f) -> f32 {
  if (D.e.w > 0.0) { return D.e.w; }
  return length(p - D.e.xyz) * D.m.x;
}
// Half the line's layer's min_width_m (formats/SPEC.md "Minimum widths"),
// 0 for none; an index past the table takes the last entry.
fn min_half_width(line: u32) -> f32 {
  if (D.o2.y == 0u) { return 0.0; }
  return 0.5 * bitcast<f32>(DB[D.o2.x + min(dlayer(line), D.o2.y - 1u)]);
}
`;

export const DYN_UPDATE_WGSL = COMMON + /* wgsl */ `
// per vertex: bit 31 keep, bits 0..5 frustum outcode
@group(0) @binding(2) var<storage, read_write> FLAGS: array<u32>;
// per vertex: keep flag, then exclusive prefix within its block
@group(0) @binding(3) var<storage, read_write> SCAN: array<u32>;
// per block of 256 vertices: kept count, then exclusive prefix
@group(0) @binding(4) var<storage, read_write> BLOCKS: array<u32>;
// kept vertex indices in original order
@group(0) @binding(5) var<storage, read_write> COMPACT: array<u32>;
// per visible segment: (vertex a, vertex b, kept predecessor of a, kept successor of b)
@group(0) @binding(6) var<storage, read_write> SEGS: array<vec4<u32>>;
@group(0) @binding(7) var<storage, read_write> C: array<atomic<u32>>;
// Dashes (dyn_common.glsl DynDash), n vertices, B blocks: per kept
// position k: [0, n) the screen length to the next kept vertex of its
// line, [n, 2n) the segmented prefix in its block, [2n, 3n) 1 where a line
// starts at or before k in its block; per vertex v: [3n, 4n) the line's
// screen length from its start to v (kept vertices); per block: [4n, 4n +
// 2B) (sum, line start seen), [4n + 2B, 4n + 3B) the carry into it.
@group(0) @binding(8) var<storage, read_write> DASH: array<f32>;

fn outcode(c: vec4f) -> u32 {
  var o = 0u;
  if (c.x < -c.w) { o |= 1u; }
  if (c.x > c.w) { o |= 2u; }
  if (c.y < -c.w) { o |= 4u; }
  if (c.y > c.w) { o |= 8u; }
  if (c.w <= 0.0) { o |= 16u; }  // behind the eye
  return o;
}
fn pixel_of(c: vec4f) -> vec2<i32> { return vec2<i32>(floor((c.xy / c.w * 0.5 + 0.5) * D.s.xy)); }

// dyn_cull.comp.glsl (thesis §4.3.1 step 1): keep a vertex unless it lands
// on its predecessor's pixel (line starts and open ends are kept).
@compute @workgroup_size(256)
fn cull(@builtin(global_invocation_id) g: vec3<u32>) {
  let v = g.x;
  if (v >= vertex_count()) { return; }
  let c = D.vp * vec4f(dpos(v), 1.0);
  let pn = dprev_next(v);
  let line = u32(dvertex(v).w);
  var keep = v == dline_start(line) || pn.x < 0 || pn.y < 0 || c.w <= 0.0;
  if (!keep) {
    let cp = D.vp * vec4f(dpos(u32(pn.x)), 1.0);
    keep = cp.w <= 0.0 || any(pixel_of(cp) != pixel_of(c));
  }
  FLAGS[v] = select(0u, 0x80000000u, keep) | outcode(c);
  SCAN[v] = select(0u, 1u, keep);
}

// dyn_scan.comp.glsl: the stream compaction of the kept vertices.
var<workgroup> S: array<u32, 256>;
// Inclusive Hillis–Steele scan of S; returns invocation i's value.
fn scan_shared(i: u32, x: u32) -> u32 {
  S[i] = x;
  workgroupBarrier();
  for (var off = 1u; off < 256u; off <<= 1u) {
    var add = 0u;
    if (i >= off) { add = S[i - off]; }
    workgroupBarrier();
    S[i] += add;
    workgroupBarrier();
  }
  return S[i];
}

// Per block of 256: exclusive prefix in place, block total out.
@compute @workgroup_size(256)
fn scan_local(@builtin(global_invocation_id) g: vec3<u32>, @builtin(local_invocation_id) l: vec3<u32>,
              @builtin(workgroup_id) wg: vec3<u32>) {
  let v = g.x;
  var x = 0u;
  if (v < vertex_count()) { x = SCAN[v]; }
  let incl = scan_shared(l.x, x);
  if (v < vertex_count()) { SCAN[v] = incl - x; }
  if (l.x == 255u) { BLOCKS[wg.x] = incl; }
}

// One workgroup: exclusive prefix of the block totals, the kept count.
@compute @workgroup_size(256)
fn scan_blocks(@builtin(local_invocation_id) l: vec3<u32>) {
  let i = l.x;
  let blocks = (vertex_count() + 255u) / 256u;
  var carry = 0u;
  for (var base = 0u; base < blocks; base += 256u) {
    let b = base + i;
    var x = 0u;
    if (b < blocks) { x = BLOCKS[b]; }
    let incl = scan_shared(i, x);
    if (b < blocks) { BLOCKS[b] = carry + incl - x; }
    let total = S[255];
    workgroupBarrier();
    carry += total;
  }
  if (i == 0u) { atomicStore(&C[4], carry); }
}

// Kept vertex v -> COMPACT[block prefix + local prefix].
@compute @workgroup_size(256)
fn scatter(@builtin(global_invocation_id) g: vec3<u32>, @builtin(workgroup_id) wg: vec3<u32>) {
  let v = g.x;
  if (v < vertex_count() && (FLAGS[v] & 0x80000000u) != 0u) { COMPACT[BLOCKS[wg.x] + SCAN[v]] = v; }
}

fn kept_pos(v: u32) -> u32 { return BLOCKS[v / 256u] + SCAN[v]; }

// dyn_segments.comp.glsl (thesis §4.3.1 step 3): per kept vertex the
// segment to the next kept vertex of its line (closed lines wrap), with
// the kept neighbours, unless both ends lie outside one frustum plane.
@compute @workgroup_size(256)
fn segments(@builtin(global_invocation_id) g: vec3<u32>) {
  let k = g.x;
  let kept = atomicLoad(&C[4]);
  if (k >= kept) { return; }
  let v = COMPACT[k];
  let line = u32(dvertex(v).w);
  let first = kept_pos(dline_start(line));
  var last = kept - 1u;
  if (line + 1u < line_count()) { last = kept_pos(dline_start(line + 1u)) - 1u; }
  let closed = dprev_next(dline_start(line)).x >= 0;
  var next = NONE;
  if (k < last) { next = k + 1u; } else if (closed) { next = first; }
  if (next == NONE || next == k) { return; }
  var prev = NONE;
  if (k > first) { prev = k - 1u; } else if (closed) { prev = last; }
  var next2 = NONE;
  if (next < last) { next2 = next + 1u; } else if (closed) { next2 = first; }
  let b = COMPACT[next];
  if (((FLAGS[v] & FLAGS[b]) & 31u) != 0u) { return; }  // both outside one plane
  var pv = NONE;
  if (prev != NONE) { pv = COMPACT[prev]; }
  var nv = NONE;
  if (next2 != NONE) { nv = COMPACT[next2]; }
  let slot = atomicAdd(&C[1], 1u);
  SEGS[slot] = vec4<u32>(v, b, pv, nv);
}

// dyn_dash.comp.glsl: the segmented scan of the kept segments' screen
// lengths over the kept positions (a line's kept vertices are consecutive
// in COMPACT), in three dispatches.
var<workgroup> SV: array<f32, 256>;
var<workgroup> SF: array<u32, 256>;
fn clip_of(v: u32) -> vec4f { return D.vp * vec4f(dpos(v), 1.0); }

// Per block of 256: lengths, segmented inclusive prefix, block (sum, line start seen).
@compute @workgroup_size(256)
fn dash_local(@builtin(global_invocation_id) g: vec3<u32>, @builtin(local_invocation_id) l: vec3<u32>,
              @builtin(workgroup_id) wg: vec3<u32>) {
  let n = vertex_count();
  let k = g.x;
  let i = l.x;
  let kept = atomicLoad(&C[4]);
  var len = 0.0;
  var head = 0u;
  if (k < kept) {
    let v = COMPACT[k];
    let line = u32(dvertex(v).w);
    let first = kept_pos(dline_start(line));
    var last = kept - 1u;
    if (line + 1u < line_count()) { last = kept_pos(dline_start(line + 1u)) - 1u; }
    head = select(0u, 1u, k == first);
    if (k < last) { len = screen_length(clip_of(v), clip_of(COMPACT[k + 1u])); }
    DASH[k] = len;
  }
  // (F, V) after (F', V') is (F' | F, F ? V : V' + V).
  SV[i] = len;
  SF[i] = head;
  workgroupBarrier();
  for (var off = 1u; off < 256u; off <<= 1u) {
    var add = 0.0;
    var f = 0u;
    if (i >= off) {
      add = SV[i - off];
      f = SF[i - off];
    }
    workgroupBarrier();
    if (SF[i] == 0u) { SV[i] += add; }
    SF[i] |= f;
    workgroupBarrier();
  }
  if (k < kept) {
    DASH[n + k] = SV[i];
    DASH[2u * n + k] = f32(SF[i]);
  }
  if (i == 255u) {
    DASH[4u * n + 2u * wg.x] = SV[255];
    DASH[4u * n + 2u * wg.x + 1u] = f32(SF[255]);
  }
}

// One invocation: the carry into each block.
@compute @workgroup_size(1)
fn dash_blocks() {
  let n = vertex_count();
  let blocks = (n + 255u) / 256u;
  var carry = 0.0;
  for (var b = 0u; b < blocks; b++) {
    DASH[4u * n + 2u * blocks + b] = carry;
    let sum = DASH[4u * n + 2u * b];
    carry = select(carry + sum, sum, DASH[4u * n + 2u * b + 1u] != 0.0);
  }
}

// Kept vertex -> DASH[dash_vertex_at(v)], the exclusive prefix.
@compute @workgroup_size(256)
fn dash_apply(@builtin(global_invocation_id) g: vec3<u32>, @builtin(workgroup_id) wg: vec3<u32>) {
  let n = vertex_count();
  let k = g.x;
  if (k >= atomicLoad(&C[4])) { return; }
  var incl = DASH[n + k];
  if (DASH[2u * n + k] == 0.0) { incl += DASH[4u * n + 2u * ((n + 255u) / 256u) + wg.x]; }
  DASH[dash_vertex_at(COMPACT[k])] = incl - DASH[k];
}
`;

export const DYN_LISTS_WGSL = COMMON + /* wgsl */ `
@group(0) @binding(2) var<storage, read> SEGS: array<vec4<u32>>;
// Per pixel: its ground point (anchor-relative x, y, z; w 1, 0 where no
// terrain is drawn), written by the static decal pass (wgsl_decals.js).
@group(0) @binding(3) var<storage, read> GP: array<vec4f>;
// Per pixel: its list's first node plus 1 (0: empty); per node: (order,
// line, next node plus 1, coverage bits).
@group(0) @binding(4) var<storage, read_write> HEADS: array<atomic<u32>>;
@group(0) @binding(5) var<storage, read_write> NODES: array<vec4<u32>>;
@group(0) @binding(6) var<storage, read_write> C: array<atomic<u32>>;
@group(0) @binding(7) var<storage, read> VIS: array<u32>;  // layer visibility bits
// per vertex at dash_vertex_at(v): its line's screen length from the start (DYN_UPDATE_WGSL DASH)
@group(0) @binding(8) var<storage, read> DASH: array<f32>;

struct VOut {
  @builtin(position) pos: vec4f,
  @location(0) @interpolate(flat) seg: u32,
}

fn face_vector(n_here: vec2f, n_other: vec2f, hw: f32) -> vec2f {
  var m = n_here + n_other;
  if (dot(m, m) < 1e-12) { return n_here * hw; }
  m = normalize(m);
  return m * (hw / max(dot(m, n_here), 0.1));
}

// dyn_box.geom.glsl (thesis §4.3.2): the box around segment \`si\`, as wide
// as the line's pixel width at its farther end plus a pixel of margin, as
// high as the terrain range plus a metre, joined to its neighbours by
// common miter faces; open ends extend by half the width for the caps.
// Corner c: bit 0 the side (+), bit 1 the end (b), bit 2 the top. Vertex
// vi of the 36 is a corner of one of the six faces' two triangles.
@vertex
fn vs(@builtin(vertex_index) vi: u32, @builtin(instance_index) si: u32) -> VOut {
  // faces (p, q, r, s) as GL's quads: bottom, top, right, left, at a, at b;
  // triangles (p, q, s), (q, s, r)
  var corners = array<u32, 36>(
    0u, 1u, 2u, 1u, 2u, 3u,   4u, 6u, 5u, 6u, 5u, 7u,   0u, 2u, 4u, 2u, 4u, 6u,
    1u, 5u, 3u, 5u, 3u, 7u,   0u, 4u, 1u, 4u, 1u, 5u,   2u, 3u, 6u, 3u, 6u, 7u);
  let s = SEGS[si];
  let a = dpos(s.x);
  let b = dpos(s.y);
  let line = u32(dvertex(s.x).w);
  let props = dprops(line);
  let mpp = max(metres_per_pixel(a), metres_per_pixel(b));
  let hw = max(bitcast<f32>(props.x) * mpp, min_half_width(line)) * 1.25 + 1.25 * mpp;
  var d = b.xy - a.xy;
  let len = length(d);
  if (len > 0.0) { d = d / len; } else { d = vec2f(1.0, 0.0); }
  let n = vec2f(-d.y, d.x);
  var pa = a.xy;
  var pb = b.xy;
  var ca = n * hw;
  var cb = n * hw;
  if (s.z != NONE) {
    var dp = a.xy - dpos(s.z).xy;
    if (length(dp) > 0.0) { dp = normalize(dp); } else { dp = d; }
    ca = face_vector(n, vec2f(-dp.y, dp.x), hw);
  } else {
    pa -= d * hw;
  }
  if (s.w != NONE) {
    var dn = dpos(s.w).xy - b.xy;
    if (length(dn) > 0.0) { dn = normalize(dn); } else { dn = d; }
    cb = face_vector(n, vec2f(-dn.y, dn.x), hw);
  } else {
    pb += d * hw;
  }
  let c = corners[vi];
  var p = pa;
  var side = ca;
  if ((c & 2u) != 0u) { p = pb; side = cb; }
  if ((c & 1u) != 0u) { p += side; } else { p -= side; }
  let z = select(D.m.y - 1.0, D.m.z + 1.0, (c & 4u) != 0u);
  var o: VOut;
  o.pos = D.vp * vec4f(p, z, 1.0);
  o.seg = si;
  return o;
}

fn cross2(a: vec2f, b: vec2f) -> f32 { return a.x * b.y - a.y * b.x; }
fn in_triangle(p: vec2f, a: vec2f, b: vec2f, c: vec2f) -> bool {
  let d1 = cross2(b - a, p - a);
  let d2 = cross2(c - b, p - b);
  let d3 = cross2(a - c, p - c);
  return !((d1 < 0.0 || d2 < 0.0 || d3 < 0.0) && (d1 > 0.0 || d2 > 0.0 || d3 > 0.0));
}
fn left_normal(u: vec2f, v: vec2f) -> vec2f {
  let d = v - u;
  let l = length(d);
  if (l > 0.0) { return vec2f(-d.y, d.x) / l; }
  return vec2f(0.0);
}
// The miter vector at v between (u -> v) and (v -> w), to the left, or zero
// for a round fallback below the package's miter limit (SPEC step 3).
fn miter_at(u: vec2f, v: vec2f, w: vec2f, hw: f32) -> vec2f {
  let e1 = normalize(u - v);
  let e2 = normalize(w - v);
  if (dot(e1, e2) > D.s.w) { return vec2f(0.0); }
  let n1 = left_normal(u, v);
  let n2 = left_normal(v, w);
  var m = n1 + n2;
  if (dot(m, m) < 1e-12) { return n2 * hw; }
  m = normalize(m);
  return m * (hw / dot(m, n2));
}

// dyn_lists.frag.glsl covers: segment s at plan point p, half width hw.
fn covers(s: vec4<u32>, p: vec2f, hw: f32, corner: u32) -> bool {
  let a = dpos(s.x).xy;
  let b = dpos(s.y).xy;
  let d = b - a;
  let len2 = dot(d, d);
  if (corner == 0u || len2 == 0.0) {
    var t = 0.0;
    if (len2 > 0.0) { t = clamp(dot(p - a, d) / len2, 0.0, 1.0); }
    let q = a + t * d - p;
    return dot(q, q) <= hw * hw;
  }
  let n = vec2f(-d.y, d.x) * (hw / sqrt(len2));
  let has_prev = s.z != NONE;
  let has_next = s.w != NONE;
  var pp = a;
  if (has_prev) { pp = dpos(s.z).xy; }
  var nn = b;
  if (has_next) { nn = dpos(s.w).xy; }
  if (corner == 1u) {
    var ma = vec2f(0.0);
    if (has_prev) { ma = miter_at(pp, a, b, hw); }
    var mb = vec2f(0.0);
    if (has_next) { mb = miter_at(a, b, nn, hw); }
    let ra = all(ma == vec2f(0.0));
    let rb = all(mb == vec2f(0.0));
    let qa = select(ma, n, ra);
    let qb = select(mb, n, rb);
    if (in_triangle(p, a + qa, a - qa, b - qb) || in_triangle(p, a + qa, b - qb, b + qb)) { return true; }
    if (ra && dot(p - a, p - a) <= hw * hw) { return true; }
    if (rb && dot(p - b, p - b) <= hw * hw) { return true; }
    return false;
  }
  // bevel: rectangle, then the corner triangles on the outer side of each turn
  let t = dot(p - a, d) / len2;
  let side = cross2(d, p - a);
  if (t >= 0.0 && t <= 1.0 && side * side <= hw * hw * len2) { return true; }
  if (has_prev) {
    let n1 = left_normal(pp, a) * hw;
    let sg = select(vec2f(1.0), -vec2f(1.0), cross2(a - pp, d) > 0.0);
    if (in_triangle(p, a, a + sg * n1, a + sg * n)) { return true; }
  } else if (dot(p - a, p - a) <= hw * hw) { return true; }
  if (has_next) {
    let n2 = left_normal(b, nn) * hw;
    let sg = select(vec2f(1.0), -vec2f(1.0), cross2(d, nn - b) > 0.0);
    if (in_triangle(p, b, b + sg * n, b + sg * n2)) { return true; }
  } else if (dot(p - b, p - b) <= hw * hw) { return true; }
  return false;
}

// dash.glsl over the dash table at word D.o2.z: [0] the layer count N;
// layer L: [1 + 3L] the first word of its pattern, [2 + 3L] its length (0:
// solid), [3 + 3L] the period (f32 bits); the patterns as f32 bits.
fn dash_solid(layer: u32) -> bool {
  let t = D.o2.z;
  return layer >= DB[t] || DB[t + 2u + 3u * layer] == 0u;
}
// Whether along-line position s (pixels) is in an "on" interval of the
// layer's pattern (formats/SPEC.md "Dashed lines").
fn dash_on(layer: u32, s: f32) -> bool {
  let t = D.o2.z;
  let first = t + DB[t + 1u + 3u * layer];
  let n = DB[t + 2u + 3u * layer];
  let period = bitcast<f32>(DB[t + 3u + 3u * layer]);
  var r = s - period * floor(s / period);
  if (!(r >= 0.0 && r < period)) { r = 0.0; }
  var a = 0.0;
  for (var i = 0u; i < n; i++) {
    let len = bitcast<f32>(DB[first + i]);
    if (r < a + len || i + 1u == n) { return (i & 1u) == 0u; }
    a += len;
  }
  return true;
}
// The pixel's along-line screen distance on segment s: the start vertex's
// plus the screen length to the point of the segment nearest p in plan
// (clamped: a corner's join region takes the vertex's own distance).
fn dash_s(s: vec4<u32>, p: vec2f) -> f32 {
  let a = dpos(s.x);
  let b = dpos(s.y);
  let ab = b.xy - a.xy;
  let len2 = dot(ab, ab);
  var t = 0.0;
  if (len2 > 0.0) { t = clamp(dot(p - a.xy, ab) / len2, 0.0, 1.0); }
  return DASH[dash_vertex_at(s.x)] + screen_length(D.vp * vec4f(a, 1.0), D.vp * vec4f(mix(a, b, t), 1.0));
}
// A dashed line's pixel is tested by the segment on whose side of each
// corner's bisector it lies, so neighbouring segments' dashes do not
// overlap inside a corner.
fn dash_own_side(s: vec4<u32>, p: vec2f) -> bool {
  let a = dpos(s.x).xy;
  let b = dpos(s.y).xy;
  var d = b - a;
  if (dot(d, d) > 0.0) { d = normalize(d); } else { d = vec2f(1.0, 0.0); }
  if (s.z != NONE) {
    let dp = a - dpos(s.z).xy;
    var t = d;
    if (dot(dp, dp) > 0.0) { t = normalize(dp) + d; }
    if (dot(t, t) < 1e-12) { t = d; }
    if (dot(p - a, t) < 0.0) { return false; }
  }
  if (s.w != NONE) {
    let dn = dpos(s.w).xy - b;
    var t = d;
    if (dot(dn, dn) > 0.0) { t = normalize(dn) + d; }
    if (dot(t, t) < 1e-12) { t = d; }
    if (dot(p - b, t) > 0.0) { return false; }
  }
  return true;
}

fn visible(layer: u32) -> bool {
  let word = layer >> 5u;
  if (word >= arrayLength(&VIS)) { return true; }
  return (VIS[word] & (1u << (layer & 31u))) != 0u;
}

// dyn_lists.frag.glsl (thesis §4.3.2 "Linked Lists"): a fragment of the
// box whose pixel's ground point the segment covers (a dashed line's: in
// an "on" interval) pushes (order, line) onto the pixel's list. Nodes past
// the capacity are only counted; the renderer grows the buffer and draws
// the pass again.
@fragment
fn fs(v: VOut) {
  let px = vec2<u32>(v.pos.xy);
  let k = px.x + u32(D.s.x) * px.y;
  var g = GP[k];
  if (g.w == 0.0) { discard; }
  g = vec4f(g.xy + D.go.xy, g.z, g.w);
  if (D.go.z != 0.0 && (g.x < D.cl.x || g.y < D.cl.y || g.x >= D.cl.z || g.y >= D.cl.w)) { discard; }
  let s = SEGS[v.seg];
  let line = u32(dvertex(s.x).w);
  let layer = dlayer(line);
  if (!visible(layer)) { discard; }
  let props = dprops(line);
  let hw = max(bitcast<f32>(props.x) * metres_per_pixel(g.xyz), min_half_width(line));
  if (!covers(s, g.xy, hw, props.w & 3u)) { discard; }
  // A dashed line's pixel on its segment's side of each corner and in an "on" interval.
  if (D.o2.w != 0u && !dash_solid(layer) && (!dash_own_side(s, g.xy) || !dash_on(layer, dash_s(s, g.xy)))) {
    discard;
  }
  let node = atomicAdd(&C[5], 1u);
  if (node < atomicLoad(&C[6])) {
    let next = atomicExchange(&HEADS[k], node + 1u);
    NODES[node] = vec4<u32>(props.z, line, next, bitcast<u32>(1.0));
  }
}
`;

export const DYN_COMPOSITE_WGSL = COMMON + /* wgsl */ `
@group(0) @binding(2) var<storage, read> HEADS: array<u32>;
@group(0) @binding(3) var<storage, read> NODES: array<vec4<u32>>;
@group(0) @binding(4) var<storage, read_write> C: array<atomic<u32>>;
// Per pixel: the dynamic layer, premultiplied.
@group(0) @binding(5) var<storage, read_write> OUT: array<vec4f>;

// dyn_composite.frag.glsl (thesis §4.3.3, §4.4.2): every line on the
// pixel's list, front to back in drawing order: the list is walked once
// per line, each walk selecting the smallest order not yet composited (a
// line's entries share its order; its coverage is the largest over them),
// until the pixel is opaque. One flat loop of at most STEPS list entries
// (n lines on a pixel read about n^2); a pixel that reaches it is counted
// (C[8]) and keeps what it has.
const STEPS = 1048576;

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
  let W = u32(D.s.x);
  if (gid.x >= W || gid.y >= u32(D.s.y)) { return; }
  let k = gid.x + W * gid.y;
  let head = HEADS[k];
  // A tileset's tile composites only its own pixels (the others have empty lists).
  if (D.go.z != 0.0 && head == 0u) { return; }
  var acc = vec4f(0.0);
  var lo = 0u;  // orders below this are composited
  var best = NONE;
  var best_line = 0u;
  var best_cov = 0.0;
  var n = head;
  var finished = head == 0u;
  for (var step = 0; step < STEPS && !finished; step++) {
    if (n == 0u) {  // a walk ends: composite the line it selected
      if (best == NONE) {
        finished = true;
        break;
      }
      var c = unpack4x8unorm(dprops(best_line).y);
      c.a *= best_cov;
      acc += (1.0 - acc.a) * vec4f(c.rgb * c.a, c.a);
      if (acc.a >= 1.0) {
        finished = true;
        break;
      }
      lo = best + 1u;
      best = NONE;
      best_cov = 0.0;
      n = head;
      continue;
    }
    let e = NODES[n - 1u];
    n = e.z;
    if (e.x < lo) { continue; }
    let cov = bitcast<f32>(e.w);
    if (e.x < best) {
      best = e.x;
      best_line = e.y;
      best_cov = cov;
    } else if (e.x == best) {
      best_cov = max(best_cov, cov);
    }
  }
  if (!finished) { atomicAdd(&C[8], 1u); }
  OUT[k] = acc;
}
`;

/**
 * The LOD passes (formats/gl/shaders/lod_mask.comp.glsl, lod_select.comp.glsl,
 * lod_segments.comp.glsl) between the update's: after the cull, the
 * vertices of lines drawn from their LOD segments leave the chains
 * (lod_mask); after the segments, the visible LOD segments are chosen
 * (lod_select: the rule of lod.js, binary32 around an integer anchor) and
 * become segments between their points' dynamic vertices with their visible
 * neighbours (lod_segments), appended to the same list as the update's.
 * LW holds lod_points (8 words a point), lod_segments (4), the draw map
 * (vertex, end link per point; lod.js lodDrawMap) and the lines' flags, at
 * L.off; LS the links per point (before, after) and then the selection:
 * count, drawn count, 2 reserved, the visible segments' indices.
 */
export const DYN_LOD_WGSL = COMMON + /* wgsl */ `
@group(0) @binding(2) var<storage, read_write> FLAGS: array<u32>;
@group(0) @binding(3) var<storage, read_write> SCAN: array<u32>;
@group(0) @binding(4) var<storage, read_write> SEGS: array<vec4<u32>>;
@group(0) @binding(5) var<storage, read_write> C: array<atomic<u32>>;
@group(0) @binding(6) var<storage, read> LW: array<u32>;
@group(0) @binding(7) var<storage, read_write> LS: array<atomic<u32>>;
struct Lod {
  anchor: vec4<i32>,  // the camera's x, y in whole quanta from the package origin
  rest: vec4f,        // its remainder x, y (metres); cz
  eps: vec4f,         // eps(d) = base + slope * max(d, 0)
  n: vec4<u32>,       // LOD points, LOD segments
  off: vec4<u32>,     // word offsets in LW: points, segments, map, line flags
}
@group(0) @binding(8) var<uniform> L: Lod;

fn lod_included(i: u32) -> bool {
  let b = L.off.x + 8u * i;
  if ((LW[b + 7u] & 1u) != 0u) { return true; }
  let dx = f32(bitcast<i32>(LW[b + 2u]) - L.anchor.x) * QM - L.rest.x;
  let dy = f32(bitcast<i32>(LW[b + 3u]) - L.anchor.y) * QM - L.rest.y;
  let d = sqrt(dx * dx + dy * dy + L.rest.z * L.rest.z) - bitcast<f32>(LW[b + 5u]);
  return bitcast<f32>(LW[b + 4u]) > L.eps.x + L.eps.y * max(d, 0.0);
}
fn lod_segment(s: u32) -> vec4<u32> {
  let o = L.off.y + 4u * s;
  return vec4<u32>(LW[o], LW[o + 1u], LW[o + 2u], LW[o + 3u]);
}
fn lod_map(p: u32) -> vec2<u32> { return vec2<u32>(LW[L.off.z + 2u * p], LW[L.off.z + 2u * p + 1u]); }
fn sel_at() -> u32 { return 2u * L.n.x; }

@compute @workgroup_size(256)
fn lod_mask(@builtin(global_invocation_id) g: vec3<u32>) {
  let v = g.x;
  if (v >= vertex_count()) { return; }
  if (LW[L.off.w + u32(dvertex(v).w)] == 0u) { return; }
  FLAGS[v] &= 0x7fffffffu;
  SCAN[v] = 0u;
}

@compute @workgroup_size(256)
fn lod_select(@builtin(global_invocation_id) g: vec3<u32>) {
  let s = g.x;
  if (s >= L.n.y) { return; }
  let seg = lod_segment(s);
  let generated = seg.z == NONE || lod_included(seg.z);
  let split = seg.w != NONE && lod_included(seg.w);
  if (!generated || split) { return; }
  atomicStore(&LS[sel_at() + 4u + atomicAdd(&LS[sel_at()], 1u)], s);
  atomicStore(&LS[2u * seg.x + 1u], seg.y);
  atomicStore(&LS[2u * seg.y], seg.x);
}

fn link(p: u32) -> vec2<u32> { return vec2<u32>(atomicLoad(&LS[2u * p]), atomicLoad(&LS[2u * p + 1u])); }
fn vertex_of(p: u32) -> u32 { if (p == NONE) { return NONE; } return lod_map(p).x; }

@compute @workgroup_size(256)
fn lod_segments(@builtin(global_invocation_id) g: vec3<u32>) {
  let k = g.x;
  if (k >= atomicLoad(&LS[sel_at()])) { return; }
  let seg = lod_segment(atomicLoad(&LS[sel_at() + 4u + k]));
  let ma = lod_map(seg.x);
  let mb = lod_map(seg.y);
  let va = ma.x;
  let vb = mb.x;
  if (va == NONE || vb == NONE) { return; }
  if (((FLAGS[va] & FLAGS[vb]) & 31u) != 0u) { return; }  // both outside one plane
  var pa = NONE;
  if (ma.y == NONE) { pa = link(seg.x).x; } else if (ma.y != seg.x) { pa = link(ma.y).x; }
  var nb = NONE;
  if (mb.y == NONE) { nb = link(seg.y).y; } else if (mb.y != seg.y) { nb = link(mb.y).y; }
  var pv = NONE;
  var nv = NONE;
  if (va != vb) { pv = vertex_of(pa); nv = vertex_of(nb); }
  let slot = atomicAdd(&C[1], 1u);
  SEGS[slot] = vec4<u32>(va, vb, pv, nv);
  atomicAdd(&LS[sel_at() + 1u], 1u);
}
`;
