// wgsl_decals.js — the static decal query (formats/SPEC.md "The static decal
// query", steps 1–8) as one WGSL compute pass: the port of
// formats/gl/shaders/static_common.glsl, decal_blobs.glsl,
// static_lines.glsl, static_polygons.glsl, dash.glsl and slope_widths.glsl
// (aliased, no coverage anti-aliasing), with the unlit layers' share and
// the minimum widths (formats/SPEC.md "Lit decals", "Minimum widths"). Unlike the GL renderer, which draws
// one pass per run of ranks, it merges the line and polygon BVH walks by
// rank in one pass, as the CPU evaluator does (step 4); the sum is the same.
//
// Every blob of the package lives in one u32 storage buffer (the word
// offset of each in the frame uniform), so the pass binds 3 storage
// buffers whatever the package holds.
//
// Precision (SPEC "Points, pixels and precision"): positions are metres
// relative to the integer anchor F.a.xy (quanta); stored i32 positions are
// made relative to it in integers before they become floats.

/** Blob slots in the packed buffer, in the order of the frame's offsets. */
export const SLOTS = [
  "qt_node_box", "qt_node", "qt_leaf_loop_range", "qt_leaf_loops", "qt_leaf_vertices",
  "cell_poly_first", "cell_poly_entries", "cell_poly_holes", "cell_holes", "poly_bvh_box16",
  "poly_props", "line_vertices", "line_vertex_line", "line_props", "line_corners",
  "cell_line_first", "cell_segments", "line_bvh_box16", "dash_table", "dash_vertex", "slope_layers",
  "unlit_layers", "min_widths",
];

export const FRAME_BYTES = 416;

export const DECALS_WGSL = /* wgsl */ `
struct Frame {
  a: vec4<i32>,    // anchor (quanta from the package origin), grid cell of the anchor
  b: vec4f,        // anchor minus that cell's lower-left corner (m), cell size (m)
  c: vec4<i32>,    // grid dims nx, ny; grid origin (quanta)
  d: vec4<i32>,    // cell size (quanta); u16 box shift; flags: 1 top-down, 2 lines, 4 polygons
  e: vec4<u32>,    // width, height, polygon rank bias (pre-v1.2 files), min_widths entries (0: none)
  f: vec4f,        // top-down: anchor-relative x of column 0's left edge, y of row 0's top edge; pixel size x, -y
  off: array<vec4<u32>, 6>,  // word offsets of the blobs (SLOTS)
  inv_view_proj: mat4x4f,    // clip -> anchor-relative world (metres)
  tg: vec4f,       // terrain: anchor-relative x, y of vertex (0, 0); spacing dx, dy
  tn: vec4<u32>,   // terrain vertex counts nx, ny; slope-width layer flags (0: none); unlit layer flags (0: none)
  ro: vec4f,       // pixel rays: eye (anchor-relative); w: 1 perspective, 0 orthographic
  rr: vec4f,       // right (scaled to NDC x = 1)
  ru: vec4f,       // up (scaled to NDC y = 1)
  rf: vec4f,       // forward
  // Minimum widths: the package's pixel limit (0: none), the box reach
  // (prep::render::min_width_reach), metres per pixel orthographic (0:
  // perspective), metres per pixel per metre of distance (perspective).
  mw: vec4f,
  // Picking: the pixel (x, y) whose top decal goes to PICK[0]; 1 to ask; 1
  // when the frame is drawn for the pick alone (one workgroup, no colours).
  pk: vec4<u32>,
  // A tileset's tile (clip mode 1): decals only at ground points in [x, z) x
  // [y, w), anchor-relative metres (the tile's square, as gl_passes.cpp
  // set_clip); elsewhere the pixel is left as it is.
  cl: vec4f,
  // The pixel of workgroup (0, 0)'s first invocation (a tile's box, the
  // pick pixel's 8x8 block); clip mode: 0 none, 1 the tile's square, 2 the
  // ground points alone; w:
  // the dispatch's number in its frame (PICK[1].x: which tile drew the pick).
  bx: vec4<u32>,
}
@group(0) @binding(0) var<uniform> F: Frame;
@group(0) @binding(1) var<storage, read> B: array<u32>;
@group(0) @binding(2) var<storage, read> VIS: array<u32>;     // layer visibility bits
@group(0) @binding(3) var depthTex: texture_depth_2d;            // terrain depth (reversed: 0 = nothing drawn)
// Per pixel: 2k the premultiplied decal colour, 2k + 1 its unlit layers' share.
@group(0) @binding(4) var<storage, read_write> OUT: array<vec4f>;
@group(0) @binding(5) var<storage, read> TZ: array<f32>;       // terrain heights, i + nx j
// Per terrain triangle (cell i + (nx - 1) j, lower then upper): (dh/dx, dh/dy).
@group(0) @binding(6) var<storage, read> TG: array<vec2f>;
// The pick pixel's top decal: (kind: 0 none, 1 static line, 2 polygon;
// layer; the source feature id, LineProps/PolyProps.feature; its index).
@group(0) @binding(7) var<storage, read_write> PICK: array<vec4<u32>>;
// Per pixel: its ground point (anchor-relative x, y, z; w 1, 0 where no
// terrain is drawn) for the dynamic-line pass (wgsl_dynamic.js); a frame
// without dynamic lines binds a one-entry stand-in that nothing reads.
@group(0) @binding(8) var<storage, read_write> GROUND: array<vec4f>;

const Q: f32 = 0.001;
const QT_BOX = 0u; const QT_NODE = 1u; const QT_LLR = 2u; const QT_LOOPS = 3u; const QT_VERT = 4u;
const CPF = 5u; const CPE = 6u; const CPH = 7u; const CH = 8u; const PBVH = 9u; const PPROPS = 10u;
const LV = 11u; const LVL = 12u; const LP = 13u; const LC = 14u; const CLF = 15u; const CS = 16u;
const LBVH = 17u; const DT = 18u; const DV = 19u; const SL = 20u; const UL = 21u; const MW = 22u;

// The pixel's unlit share so far (under), its line scale (min_width_scale)
// and the margin the line BVH's boxes are grown by (metres).
var<private> UNLIT: vec3f;
var<private> KS: f32 = 1.0;
var<private> MARGIN: f32 = 0.0;
// The first decal the query composites (the top one), for picking.
var<private> TOP: vec4<u32>;
// The decal under() composites next (kind, feature, index; TOP's fields).
var<private> CAND: u32;
var<private> CAND_FEATURE: u32;
var<private> CAND_INDEX: u32;

fn wo(k: u32) -> u32 { return F.off[k >> 2u][k & 3u]; }
fn w(k: u32, i: u32) -> u32 { return B[wo(k) + i]; }
fn wi(k: u32, i: u32) -> i32 { return bitcast<i32>(B[wo(k) + i]); }
fn wf(k: u32, i: u32) -> f32 { return bitcast<f32>(B[wo(k) + i]); }
fn iv2(k: u32, i: u32) -> vec2<i32> { return vec2<i32>(wi(k, 2u * i), wi(k, 2u * i + 1u)); }
fn uv2(k: u32, i: u32) -> vec2<u32> { return vec2<u32>(w(k, 2u * i), w(k, 2u * i + 1u)); }

// Anchor-relative metres of an integer position (difference in integers first).
fn rel(q: vec2<i32>) -> vec2f { return vec2f(q - F.a.xy) * Q; }

fn box_contains(b: vec4<i32>, p: vec2f) -> bool {
  if (b.x > b.z) { return false; }
  let lo = rel(b.xy);
  let hi = rel(b.zw);
  return p.x >= lo.x && p.x <= hi.x && p.y >= lo.y && p.y <= hi.y;
}
fn box_near(b: vec4<i32>, p: vec2f, m: f32) -> bool {
  if (b.x > b.z) { return false; }
  let lo = rel(b.xy) - m;
  let hi = rel(b.zw) + m;
  return p.x >= lo.x && p.x <= hi.x && p.y >= lo.y && p.y <= hi.y;
}
fn qt_box(n: u32) -> vec4<i32> {
  return vec4<i32>(wi(QT_BOX, 4u * n), wi(QT_BOX, 4u * n + 1u), wi(QT_BOX, 4u * n + 2u), wi(QT_BOX, 4u * n + 3u));
}

// Step 8: point-in-ring through the quad-tree from node.
fn qt_contains(node0: u32, p: vec2f) -> bool {
  var node = node0;
  if (!box_contains(qt_box(node), p)) { return false; }
  loop {
    let n = iv2(QT_NODE, node);
    if (n.x == 0) {
      let c = u32(n.y);
      var next = 0xffffffffu;
      for (var k = 0u; k < 4u; k++) {
        if (box_contains(qt_box(c + k), p)) { next = c + k; break; }
      }
      if (next == 0xffffffffu) { return false; }
      node = next;
      continue;
    }
    if (n.x == 1) { return false; }
    if (n.x == 2) { return true; }
    let r = uv2(QT_LLR, u32(n.y));
    var inside = false;
    for (var l = r.x; l < r.x + r.y; l++) {
      var s0 = 0u;
      if (l > 0u) { s0 = w(QT_LOOPS, l - 1u); }
      let s1 = w(QT_LOOPS, l);
      for (var s = s0; s < s1; s++) {
        var t = s + 1u;
        if (t >= s1) { t = s0; }
        let A = rel(iv2(QT_VERT, s)) - p;
        let Bv = rel(iv2(QT_VERT, t)) - p;
        if ((A.y > 0.0) == (Bv.y > 0.0)) { continue; }
        var L = A; var H = Bv;
        if (A.y > 0.0) { L = Bv; H = A; }
        if ((H.x - L.x) * (-L.y) - (H.y - L.y) * (-L.x) > 0.0) { inside = !inside; }
      }
    }
    return inside;
  }
}

// v1.3 u16 BVH box of a node of a cell with base corner base.xy (quanta), shift base.z.
fn box16(k: u32, i: u32, base: vec3<i32>) -> vec4<i32> {
  let a = w(k, 2u * i);
  let b = w(k, 2u * i + 1u);
  let u = vec4<u32>(a & 0xffffu, a >> 16u, b & 0xffffu, b >> 16u);
  if (u.x > u.z || u.y > u.w) { return vec4<i32>(1, 1, 0, 0); }
  return base.xyxy + (vec4<i32>(u) << vec4<u32>(u32(base.z)));
}

// Stack-less walk of a cell's BVH (step 3) as a cursor.
struct Walk { first: u32, internal: u32, count: u32, entry: u32, i: u32, done: bool, kind: u32 }

fn walk_make(kind: u32, cell: u32) -> Walk {
  var wk: Walk;
  wk.kind = kind;
  wk.entry = w(kind, 2u * cell);
  wk.count = w(kind, 2u * cell + 2u) - wk.entry;
  wk.first = w(kind, 2u * cell + 1u);
  let p = (w(kind, 2u * cell + 3u) - wk.first + 1u) >> 1u;
  wk.internal = select(0u, p - 1u, p > 0u);
  wk.i = 0u;
  wk.done = p == 0u;
  return wk;
}
fn walk_advance(wk: ptr<function, Walk>) {
  var i = (*wk).i;
  while (i != 0u && (i & 1u) == 0u) { i = (i - 1u) >> 1u; }
  if (i == 0u) { (*wk).done = true; } else { (*wk).i = i + 1u; }
}
// The next leaf (list entry index) whose boxes hold p, or -1 at the end.
fn walk_next(wk: ptr<function, Walk>, p: vec2f, base: vec3<i32>) -> i32 {
  let bk = select(PBVH, LBVH, (*wk).kind == CLF);
  loop {
    if ((*wk).done) { return -1; }
    let i = (*wk).i;
    var m = 0.0;
    if ((*wk).kind == CLF) { m = MARGIN; }
    if (box_near(box16(bk, (*wk).first + i, base), p, m)) {
      if (i < (*wk).internal) { (*wk).i = 2u * i + 1u; continue; }
      let k = i - (*wk).internal;
      walk_advance(wk);
      if (k < (*wk).count) { return i32((*wk).entry + k); }
    } else {
      walk_advance(wk);
    }
  }
}

fn visible(layer: u32) -> bool {
  let word = layer >> 5u;
  if (word >= arrayLength(&VIS)) { return true; }
  return (VIS[word] & (1u << (layer & 31u))) != 0u;
}

fn cross2(a: vec2f, b: vec2f) -> f32 { return a.x * b.y - a.y * b.x; }
fn in_triangle(a: vec2f, b: vec2f, c: vec2f, d: vec2f) -> bool {
  let c0 = cross2(b - a, d - a);
  let c1 = cross2(c - b, d - b);
  let c2 = cross2(a - c, d - c);
  return (c0 >= 0.0 && c1 >= 0.0 && c2 >= 0.0) || (c0 <= 0.0 && c1 <= 0.0 && c2 <= 0.0);
}
fn is_null(v: vec2f) -> bool { return v.x == 0.0 && v.y == 0.0; }
fn c_miter(v: u32) -> vec2f { return KS * vec2f(wf(LC, 6u * v), wf(LC, 6u * v + 1u)); }
fn c_in(v: u32) -> vec2f { return KS * vec2f(wf(LC, 6u * v + 2u), wf(LC, 6u * v + 3u)); }
fn c_out(v: u32) -> vec2f { return KS * vec2f(wf(LC, 6u * v + 4u), wf(LC, 6u * v + 5u)); }

// prep::min_width_scale: the factor line \`line\` is drawn wider at a pixel
// of PX metres (static_lines.glsl width_scale).
var<private> PX: f32 = 0.0;
fn width_scale(line: u32) -> f32 {
  if (F.e.w == 0u || !(F.mw.x > 0.0)) { return 1.0; }
  let n = wf(MW, min(w(LP, 8u * line + 5u), F.e.w - 1u));
  if (!(n > 0.0)) { return 1.0; }
  var f = 0.5;
  if (((w(LP, 8u * line + 3u) >> 2u) & 3u) != 0u) { f = 1.0; }
  let want = n * f * min(PX, F.mw.x);
  let hw = wf(LP, 8u * line);
  if (want > hw && hw > 0.0) { return want / hw; }
  return 1.0;
}

const HIT_NONE = 0; const HIT_CLIPPED = 1; const HIT_COVERED = 2;

// Slope widths (formats/SPEC.md "Slope widths", step 6b): the port of
// formats/gl/shaders/slope_widths.glsl. GS: the terrain gradient g under
// the pixel (0: plan widths).
var<private> GS: vec2f;
// Step 6b applies: a flagged layer (an index past the flags takes the
// last) where the ground is not level.
fn slope_applies(line: u32) -> bool {
  if (F.tn.z == 0u || (GS.x == 0.0 && GS.y == 0.0)) { return false; }
  return w(SL, min(w(LP, 8u * line + 5u), F.tn.z - 1u)) != 0u;
}
// <u, v>_G = u.v + (g.u)(g.v)
fn gdot(u: vec2f, v: vec2f) -> f32 { return dot(u, v) + dot(GS, u) * dot(GS, v); }
// N(w) = hw (w - g (g.w) / gam) / sqrt(w.w - (g.w)^2 / gam)
fn slope_normal(wv: vec2f, hw: f32) -> vec2f {
  let gam = 1.0 + dot(GS, GS);
  let gw = dot(GS, wv);
  return hw / sqrt(dot(wv, wv) - gw * gw / gam) * (wv - gw / gam * GS);
}
// M(a, b) = hw^2 (a + b) / (hw^2 + <a, b>_G)
fn slope_miter(a: vec2f, b: vec2f, hw: f32) -> vec2f { return hw * hw / (hw * hw + gdot(a, b)) * (a + b); }
// O(x, m, mg, w): x in the neighbouring segment's ground piece past the
// plan miter line m, onto this segment's side; \`ahead\` for the next one.
fn slope_overhang(x: vec2f, m: vec2f, mg: vec2f, wv: vec2f, hw: f32, ahead: bool) -> bool {
  var t = vec2f(-wv.y, wv.x);
  if (ahead) { t = vec2f(wv.y, -wv.x); }
  if (cross2(mg, x) * cross2(mg, t) < 0.0 || cross2(m, x) * cross2(m, t) > 0.0) { return false; }
  let gt = dot(GS, t);
  let c = cross2(t, x);
  return c * c * (1.0 + dot(GS, GS)) <= hw * hw * (dot(t, t) + gt * gt);
}
// The band of segment (s, ei) measured in G; d and e as in segment_test.
fn surface_band_covers(e: vec2f, d: vec2f, hw: f32, corner: u32, s: u32, ei: u32) -> bool {
  let hw2 = hw * hw;
  let ee = dot(e, e);
  var tp = 0.0;
  if (ee > 0.0) { tp = clamp(dot(d, e) / ee, 0.0, 1.0); }
  let r = d - tp * e;
  if (corner == 0u) {  // round
    let eg = gdot(e, e);
    var t = 0.0;
    if (eg > 0.0) { t = clamp(gdot(d, e) / eg, 0.0, 1.0); }
    let rg = d - t * e;
    return gdot(rg, rg) <= hw2;
  }
  // Within hw (bevel) or the longer plan miter of the segment in plan.
  let pa = c_miter(s);
  let pb = c_miter(ei);
  var reach2 = hw2;
  if (corner == 1u) { reach2 = max(hw2, max(dot(pa, pa), dot(pb, pb))); }
  if (dot(r, r) > reach2) { return false; }
  let a_in = c_in(s);
  let a_out = c_out(s);
  let b_in = c_in(ei);
  let b_out = c_out(ei);
  if (corner == 1u) {  // miter; sa, sb make the stored (outer) bevels left
    let na = is_null(pa);
    let nb = is_null(pb);
    let sa = select(-1.0, 1.0, cross2(e, a_out) >= 0.0);
    let sb = select(-1.0, 1.0, cross2(e, b_in) >= 0.0);
    var ma = slope_normal(sa * a_out, hw);
    if (!na) { ma = slope_miter(slope_normal(sa * a_in, hw), slope_normal(sa * a_out, hw), hw); }
    var mb = slope_normal(sb * b_in, hw);
    if (!nb) { mb = slope_miter(slope_normal(sb * b_in, hw), slope_normal(sb * b_out, hw), hw); }
    return in_triangle(-ma, e - mb, e + mb, d) || in_triangle(-ma, e + mb, ma, d) ||
           (na && gdot(d, d) <= hw2) || (nb && gdot(d - e, d - e) <= hw2) ||
           (!na && slope_overhang(d, pa, ma, sa * a_in, hw, false)) ||
           (!nb && slope_overhang(d - e, pb, mb, sb * b_out, hw, true));
  }
  // bevel
  let n = slope_normal(a_out, hw);
  let c = cross2(e, n);
  if (c != 0.0) {
    let sv = cross2(e, d) / c;
    let tv = cross2(d, n) / c;
    if (tv >= 0.0 && tv <= 1.0 && abs(sv) <= 1.0) { return true; }
  }
  if (is_null(a_in)) {
    if (gdot(d, d) <= hw2) { return true; }
  } else if (in_triangle(vec2f(0.0), slope_normal(a_in, hw), n, d)) { return true; }
  if (is_null(b_out)) { return gdot(d - e, d - e) <= hw2; }
  return in_triangle(e, e + slope_normal(b_in, hw), e + slope_normal(b_out, hw), d);
}

// The gradient of the terrain triangle under p (Heightfield::gradient_at):
// 0 outside the mesh.
fn gradient_at(p: vec2f) -> vec2f {
  let fx = (p.x - F.tg.x) / F.tg.z;
  let fy = (p.y - F.tg.y) / F.tg.w;
  if (!(fx >= 0.0 && fy >= 0.0 && fx <= f32(F.tn.x - 1u) && fy <= f32(F.tn.y - 1u))) { return vec2f(0.0); }
  let i = min(u32(fx), F.tn.x - 2u);
  let j = min(u32(fy), F.tn.y - 2u);
  let upper = fx - f32(i) < fy - f32(j);
  return TG[2u * (i + (F.tn.x - 1u) * j) + select(0u, 1u, upper)];
}

// Step 6: segment (s, ei) of line \`line\` at p.
fn segment_test(s: u32, ei: u32, p: vec2f, line: u32) -> i32 {
  KS = width_scale(line);
  let hw = wf(LP, 8u * line) * KS;
  let style = w(LP, 8u * line + 3u);
  let hw2 = hw * hw;
  let corner = style & 3u;
  let outline = (style >> 2u) & 3u;
  let ai = iv2(LV, s);
  let e = vec2f(iv2(LV, ei) - ai) * Q;
  let d = p - rel(ai);
  var covered = false;
  if (slope_applies(line)) {
    // Step 6b: the band measured along the terrain replaces the plan band.
    covered = surface_band_covers(e, d, hw, corner, s, ei);
  } else if (corner == 0u) {
    let ee = dot(e, e);
    var t = 0.0;
    if (ee > 0.0) { t = clamp(dot(d, e) / ee, 0.0, 1.0); }
    let r = d - t * e;
    covered = dot(r, r) <= hw2;
  } else if (corner == 1u) {
    var ma = c_miter(s);
    var mb = c_miter(ei);
    let na = is_null(ma);
    let nb = is_null(mb);
    if (na) { ma = c_out(s); if (cross2(e, ma) < 0.0) { ma = -ma; } }
    if (nb) { mb = c_in(ei); if (cross2(e, mb) < 0.0) { mb = -mb; } }
    covered = in_triangle(-ma, e - mb, e + mb, d) || in_triangle(-ma, e + mb, ma, d) ||
              (na && dot(d, d) <= hw2) || (nb && dot(d - e, d - e) <= hw2);
  } else {
    let n = c_out(s);
    let c = cross2(e, n);
    if (c != 0.0) {
      let sv = cross2(e, d) / c;
      let tv = cross2(d, n) / c;
      covered = tv >= 0.0 && tv <= 1.0 && abs(sv) <= 1.0;
    }
    let a_in = c_in(s);
    let b_out = c_out(ei);
    if (!covered) {
      if (is_null(a_in)) { covered = dot(d, d) <= hw2; } else { covered = in_triangle(vec2f(0.0), a_in, n, d); }
    }
    if (!covered) {
      if (is_null(b_out)) { covered = dot(d - e, d - e) <= hw2; }
      else { covered = in_triangle(e, e + c_in(ei), e + b_out, d); }
    }
  }
  if (!covered) { return HIT_NONE; }
  if (outline == 0u) { return HIT_COVERED; }
  if ((style & 32u) != 0u) {
    let inside = qt_contains(w(LP, 8u * line + 7u), p);
    return select(HIT_CLIPPED, HIT_COVERED, inside == ((style & 64u) != 0u));
  }
  let K = select(-1.0, 1.0, outline == 1u);
  if (K * cross2(e, d) < 0.0) { return HIT_NONE; }
  let cb_out = c_out(ei);
  if (!is_null(cb_out)) {
    let o = select(-1.0, 1.0, cross2(e, c_in(ei)) >= 0.0);
    if (K * o < 0.0 && K * dot(d - e, o * cb_out) < 0.0) { return HIT_NONE; }
  }
  let ca_in = c_in(s);
  if (!is_null(ca_in)) {
    let o = select(-1.0, 1.0, cross2(e, c_out(s)) >= 0.0);
    if (K * o < 0.0 && K * dot(d, o * ca_in) < 0.0) { return HIT_NONE; }
  }
  return HIT_COVERED;
}

// Step 6c (dash.glsl): the dash table is [layer count N; per layer: first
// word, length (0: solid), period (f32 bits); the patterns (f32 bits)].
fn dash_covers(s: u32, ei: u32, p: vec2f, layer: u32) -> bool {
  if (layer >= w(DT, 0u)) { return true; }
  let n = w(DT, 2u + 3u * layer);
  if (n == 0u) { return true; }
  let first = w(DT, 1u + 3u * layer);
  let period = wf(DT, 3u + 3u * layer);
  let ai = iv2(LV, s);
  let e = vec2f(iv2(LV, ei) - ai) * Q;
  let d = p - rel(ai);
  let ee = dot(e, e);
  var t = 0.0;
  if (ee > 0.0) { t = clamp(dot(d, e) / ee, 0.0, 1.0); }
  let sd = wf(DV, s) + t * sqrt(ee);
  var r = sd - period * floor(sd / period);
  if (!(r >= 0.0 && r < period)) { r = 0.0; }
  var a = 0.0;
  for (var i = 0u; i < n; i++) {
    let len = wf(DT, first + i);
    if (r < a + len || i + 1u == n) { return (i & 1u) == 0u; }
    a += len;
  }
  return true;
}

// Step 7: exterior polygon entry at p (its cell's holes cut it out).
fn polygon_covers(entry: u32, p: vec2f) -> bool {
  if (!qt_contains(w(CPE, 2u * entry + 1u), p)) { return false; }
  let h0 = w(CPH, entry);
  let h1 = w(CPH, entry + 1u);
  for (var h = h0; h < h1; h++) {
    if (qt_contains(w(CH, 2u * h + 1u), p)) { return false; }
  }
  return true;
}

// A layer drawn unlit (light = false; an index past the table takes the last flag).
fn layer_unlit(layer: u32) -> bool {
  if (F.tn.w == 0u) { return false; }
  return w(UL, min(layer, F.tn.w - 1u)) != 0u;
}

fn under(acc: ptr<function, vec4f>, rgba: u32, layer: u32) -> bool {
  let c = unpack4x8unorm(rgba);
  if (TOP.x == 0u && c.a > 0.0) { TOP = vec4<u32>(CAND, layer, CAND_FEATURE, CAND_INDEX); }
  let wt = (1.0 - (*acc).a) * c.a;
  *acc = vec4f((*acc).rgb + wt * c.rgb, (*acc).a + wt);
  if (layer_unlit(layer)) { UNLIT += wt * c.rgb; }
  return (*acc).a >= 0.999;
}

fn line_rank(entry: i32) -> u32 {
  let line = w(LVL, w(CS, 2u * u32(entry)));
  return w(LP, 8u * line + 2u);
}
fn poly_rank(entry: i32) -> u32 {
  return w(PPROPS, 8u * w(CPE, 2u * u32(entry)) + 1u) + F.e.z;
}

// Steps 1–8 at the anchor-relative point p: premultiplied colour.
fn query(p: vec2f) -> vec4f {
  var acc = vec4f(0.0);
  let g = F.a.zw + vec2<i32>(floor((F.b.xy + p) / F.b.zw));
  if (g.x < 0 || g.y < 0 || g.x >= F.c.x || g.y >= F.c.y) { return acc; }
  let cell = u32(g.x + F.c.x * g.y);
  let base = vec3<i32>(F.c.zw + g * F.d.xy - vec2<i32>(1 << u32(F.d.z)), F.d.z);
  var lw: Walk; lw.done = true; lw.kind = CLF;
  var pw: Walk; pw.done = true; pw.kind = CPF;
  if ((F.d.w & 2) != 0) { lw = walk_make(CLF, cell); }
  if ((F.d.w & 4) != 0) { pw = walk_make(CPF, cell); }
  var kl = walk_next(&lw, p, base);
  var kp = walk_next(&pw, p, base);
  var rl = 0u; var rp = 0u;
  if (kl >= 0) { rl = line_rank(kl); }
  if (kp >= 0) { rp = poly_rank(kp); }
  var last = 0xffffffffu;
  loop {
    if (kl < 0 && kp < 0) { break; }
    if (kp < 0 || (kl >= 0 && rl <= rp)) {
      let seg = uv2(CS, u32(kl));
      let line = w(LVL, seg.x);
      if (line != last && visible(w(LP, 8u * line + 5u))) {
        var hit = segment_test(seg.x, seg.y, p, line);
        if (hit == HIT_COVERED && !dash_covers(seg.x, seg.y, p, w(LP, 8u * line + 5u))) { hit = HIT_NONE; }
        if (hit != HIT_NONE) { last = line; }
        CAND = 1u; CAND_FEATURE = w(LP, 8u * line + 6u); CAND_INDEX = line;
        if (hit == HIT_COVERED && under(&acc, w(LP, 8u * line + 1u), w(LP, 8u * line + 5u))) { break; }
      }
      kl = walk_next(&lw, p, base);
      if (kl >= 0) { rl = line_rank(kl); }
    } else {
      let poly = w(CPE, 2u * u32(kp));
      if (visible(w(PPROPS, 8u * poly + 4u)) && polygon_covers(u32(kp), p)) {
        CAND = 2u; CAND_FEATURE = w(PPROPS, 8u * poly + 5u); CAND_INDEX = poly;
        if (under(&acc, w(PPROPS, 8u * poly), w(PPROPS, 8u * poly + 4u))) { break; }
      }
      kp = walk_next(&pw, p, base);
      if (kp >= 0) { rp = poly_rank(kp); }
    }
  }
  return acc;
}

fn tvertex(i: u32, j: u32) -> vec3f {
  return vec3f(F.tg.x + f32(i) * F.tg.z, F.tg.y + f32(j) * F.tg.w, TZ[i + F.tn.x * j]);
}
// The pixel ray (libprep/render PixelRays) meets the plane of the mesh
// triangle (00, 10, 11) or (00, 11, 01) under \`near\`: the ground point
// without the depth buffer's rounding along the ray. Twice: the second time
// on the triangle under the first answer.
fn ground_point(ndc: vec2f, near: vec2f) -> vec2f {
  var o = F.ro.xyz;
  var d = F.rf.xyz + ndc.x * F.rr.xyz + ndc.y * F.ru.xyz;
  if (F.ro.w == 0.0) { o = F.ro.xyz + ndc.x * F.rr.xyz + ndc.y * F.ru.xyz; d = F.rf.xyz; }
  var p = near;
  for (var it = 0; it < 2; it++) {
    let fx = (p.x - F.tg.x) / F.tg.z;
    let fy = (p.y - F.tg.y) / F.tg.w;
    let i = u32(clamp(floor(fx), 0.0, f32(F.tn.x - 2u)));
    let j = u32(clamp(floor(fy), 0.0, f32(F.tn.y - 2u)));
    let A = tvertex(i, j);
    var Bv = tvertex(i + 1u, j);
    var C = tvertex(i + 1u, j + 1u);
    if (fy - f32(j) > fx - f32(i)) { Bv = C; C = tvertex(i, j + 1u); }
    let n = cross(Bv - A, C - A);
    let dn = dot(d, n);
    if (dn == 0.0) { break; }
    let t = dot(A - o, n) / dn;
    p = (o + t * d).xy;
  }
  return p;
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) g0: vec3<u32>) {
  // The dispatch covers a box of the frame (a tile's, or the pick pixel's
  // 8x8 block for a frame drawn for its pick alone) from F.bx.xy. Clip
  // mode 1: a tileset's tile, which draws only the pixels whose ground
  // point is in its square and leaves GROUND alone (its anchor may not be
  // the frame's); mode 2: the ground points alone (the index frame, for a
  // tileset's dynamic lines).
  let gid = vec3<u32>(g0.xy + F.bx.xy, 0u);
  let clipped = F.bx.z == 1u;
  let ground_only = F.bx.z == 2u;
  let W = F.e.x;
  let H = F.e.y;
  if (gid.x >= W || gid.y >= H) { return; }
  var p: vec2f;
  var z = 0.0;
  let k = gid.x + W * gid.y;
  if ((F.d.w & 1) != 0) {
    // top-down: the pixel centre exactly (SPEC "Points, pixels and precision")
    p = vec2f(F.f.x + (f32(gid.x) + 0.5) * F.f.z, F.f.y + (f32(gid.y) + 0.5) * F.f.w);
  } else {
    // the ray's terrain point from the depth (static_common.glsl pixel_world)
    let depth = textureLoad(depthTex, vec2<i32>(gid.xy), 0);
    if (depth <= 0.0) {
      if (clipped) { return; }
      OUT[2u * k] = vec4f(0.0);
      OUT[2u * k + 1u] = vec4f(0.0);
      if (k < arrayLength(&GROUND)) { GROUND[k] = vec4f(0.0); }
      return;
    }
    let ndc = vec2f((f32(gid.x) + 0.5) / f32(W) * 2.0 - 1.0, 1.0 - (f32(gid.y) + 0.5) / f32(H) * 2.0);
    let wp = F.inv_view_proj * vec4f(ndc, depth, 1.0);
    p = ground_point(ndc, wp.xy / wp.w);
    z = wp.z / wp.w;
  }
  if (!clipped && k < arrayLength(&GROUND)) { GROUND[k] = vec4f(p, z, 1.0); }
  if (ground_only) { return; }
  if (clipped && (p.x < F.cl.x || p.y < F.cl.y || p.x >= F.cl.z || p.y >= F.cl.w)) { return; }
  if (F.tn.z != 0u) { GS = gradient_at(p); }
  // Minimum widths: the pixel's ground size (static_common.glsl pixel_metres).
  if (F.mw.x > 0.0) {
    PX = F.mw.z;
    if (PX <= 0.0) { PX = length(vec3f(p, z) - F.ro.xyz) * F.mw.w; }
    MARGIN = F.mw.y * min(PX, F.mw.x);
  }
  UNLIT = vec3f(0.0);
  let c = query(p);
  if (F.pk.z != 0u && gid.x == F.pk.x && gid.y == F.pk.y) {
    PICK[0] = TOP;
    PICK[1] = vec4<u32>(F.bx.w, 0u, 0u, 0u);
  }
  OUT[2u * k] = c;
  OUT[2u * k + 1u] = vec4f(UNLIT, c.a);
}
`;
