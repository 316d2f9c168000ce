// glsl_decals.js — the static decal query of wgsl_decals.js as a GLSL ES
// 3.00 fragment shader for the WebGL2 renderer (webgl2.js): the same steps
// (formats/SPEC.md "The static decal query", steps 1–8, aliased), the same
// frame uniform (wgsl_decals.js Frame: a std140 block with the WGSL
// struct's byte layout) and the same precision rules (SPEC "Points, pixels
// and precision": positions are metres relative to the integer anchor
// F.a.xy; stored i32 positions are made relative to it in integers before
// they become floats). The composite of wgsl_frame.js COMPOSITE_WGSL (lit
// decals, unlit layers) follows the query in the same shader, so the
// frame needs no float render target.
//
// Every blob of the package lives in one R32UI array texture read with
// texelFetch (exact words): word k of the packed array (scene.js offsets)
// is texel (k & (2^ws - 1), row & (2^ls - 1)) of layer row >> ls, row = k
// >> ws, with (ws, ls) = u_lin (webgl2.js LinearTexture). The terrain
// heights and triangle gradients are R32F textures of the same layout, the
// layer visibility bits an R32UI one.

/** The fragment shader of the decal pass: final colour, straight decal layer, pick. */
export const DECALS_GLSL = /* glsl */ `#version 300 es
precision highp float;
precision highp int;
precision highp usampler2DArray;
precision highp sampler2DArray;
precision highp usampler2D;

layout(std140) uniform Frame {
  ivec4 a;    // anchor (quanta from the package origin), grid cell of the anchor
  vec4 b;     // anchor minus that cell's lower-left corner (m), cell size (m)
  ivec4 c;    // grid dims nx, ny; grid origin (quanta)
  ivec4 d;    // cell size (quanta); u16 box shift; flags: 1 top-down, 2 lines, 4 polygons
  uvec4 e;    // width, height, polygon rank bias (pre-v1.2 files), min_widths entries (0: none)
  vec4 f;     // top-down: anchor-relative x of column 0's left edge, y of row 0's top edge; pixel size x, -y
  uvec4 off[6];        // word offsets of the blobs (wgsl_decals.js SLOTS)
  mat4 inv_view_proj;  // clip -> anchor-relative world (metres)
  vec4 tg;    // terrain: anchor-relative x, y of vertex (0, 0); spacing dx, dy
  uvec4 tn;   // terrain vertex counts nx, ny; slope-width layer flags (0: none); unlit layer flags (0: none)
  vec4 ro;    // pixel rays: eye (anchor-relative); w: 1 perspective, 0 orthographic
  vec4 rr;    // right (scaled to NDC x = 1)
  vec4 ru;    // up (scaled to NDC y = 1)
  vec4 rf;    // forward
  vec4 mw;    // minimum widths: limit, reach, metres per pixel (ortho), per metre of distance (persp)
  uvec4 pk;   // picking: pixel (x, y); 1 to ask; 1 for a frame drawn for the pick alone
  vec4 cl;    // a tileset's tile: decals only in [x, z) x [y, w), anchor-relative metres
  uvec4 bx;   // z, clip mode: 0 none, 1 the tile's square (pixels outside are left), 2 no decals
} F;

uniform usampler2DArray u_blobs;  // the packed blob words
uniform sampler2DArray u_heights;  // terrain heights, i + nx j
uniform sampler2DArray u_grads;    // per terrain triangle 2t, 2t + 1: dh/dx, dh/dy
uniform usampler2DArray u_vis;     // layer visibility bits
uniform usampler2D u_ground;       // terrain pass: anchor-relative x, y, z bits; w 1 where drawn
uniform sampler2D u_terrain;       // terrain pass colour, its shade in alpha
uniform uvec4 u_lin;               // linear textures: width shift, rows-per-layer shift; visibility words
uniform vec2 u_go;                 // u_ground's points (index anchor) to this frame's anchor, metres (tileset tiles)

layout(location = 0) out vec4 o_rgba;
layout(location = 1) out vec4 o_decals;
layout(location = 2) out uvec4 o_pick;

const float Q = 0.001;
const uint QT_BOX = 0u; const uint QT_NODE = 1u; const uint QT_LLR = 2u; const uint QT_LOOPS = 3u;
const uint QT_VERT = 4u; const uint CPF = 5u; const uint CPE = 6u; const uint CPH = 7u; const uint CH = 8u;
const uint PBVH = 9u; const uint PPROPS = 10u; const uint LV = 11u; const uint LVL = 12u; const uint LP = 13u;
const uint LC = 14u; const uint CLF = 15u; const uint CS = 16u; const uint LBVH = 17u; const uint DT = 18u;
const uint DV = 19u; const uint SL = 20u; const uint UL = 21u; const uint MW = 22u;

vec3 UNLIT;
float KS = 1.0;
float MARGIN = 0.0;
uvec4 TOP = uvec4(0u);
uint CAND; uint CAND_FEATURE; uint CAND_INDEX;
float PX = 0.0;
vec2 GS = vec2(0.0);

ivec3 lin(uint k) {
  uint row = k >> u_lin.x;
  return ivec3(int(k & ((1u << u_lin.x) - 1u)), int(row & ((1u << u_lin.y) - 1u)), int(row >> u_lin.y));
}
uint wo(uint k) { return F.off[k >> 2u][k & 3u]; }
uint w(uint k, uint i) { return texelFetch(u_blobs, lin(wo(k) + i), 0).r; }
int wi(uint k, uint i) { return int(w(k, i)); }
float wf(uint k, uint i) { return uintBitsToFloat(w(k, i)); }
ivec2 iv2(uint k, uint i) { return ivec2(wi(k, 2u * i), wi(k, 2u * i + 1u)); }
uvec2 uv2(uint k, uint i) { return uvec2(w(k, 2u * i), w(k, 2u * i + 1u)); }
float TZ(uint i) { return texelFetch(u_heights, lin(i), 0).r; }
vec2 TG(uint t) { return vec2(texelFetch(u_grads, lin(2u * t), 0).r, texelFetch(u_grads, lin(2u * t + 1u), 0).r); }

// Anchor-relative metres of an integer position (difference in integers first).
vec2 rel(ivec2 q) { return vec2(q - F.a.xy) * Q; }

bool box_contains(ivec4 b, vec2 p) {
  if (b.x > b.z) return false;
  vec2 lo = rel(b.xy);
  vec2 hi = rel(b.zw);
  return p.x >= lo.x && p.x <= hi.x && p.y >= lo.y && p.y <= hi.y;
}
bool box_near(ivec4 b, vec2 p, float m) {
  if (b.x > b.z) return false;
  vec2 lo = rel(b.xy) - m;
  vec2 hi = rel(b.zw) + m;
  return p.x >= lo.x && p.x <= hi.x && p.y >= lo.y && p.y <= hi.y;
}
ivec4 qt_box(uint n) {
  return ivec4(wi(QT_BOX, 4u * n), wi(QT_BOX, 4u * n + 1u), wi(QT_BOX, 4u * n + 2u), wi(QT_BOX, 4u * n + 3u));
}

// Step 8: point-in-ring through the quad-tree from node.
bool qt_contains(uint node0, vec2 p) {
  uint node = node0;
  if (!box_contains(qt_box(node), p)) return false;
  for (;;) {
    ivec2 n = iv2(QT_NODE, node);
    if (n.x == 0) {
      uint c = uint(n.y);
      uint next = 0xffffffffu;
      for (uint k = 0u; k < 4u; k++) {
        if (box_contains(qt_box(c + k), p)) { next = c + k; break; }
      }
      if (next == 0xffffffffu) return false;
      node = next;
      continue;
    }
    if (n.x == 1) return false;
    if (n.x == 2) return true;
    uvec2 r = uv2(QT_LLR, uint(n.y));
    bool inside = false;
    for (uint l = r.x; l < r.x + r.y; l++) {
      uint s0 = 0u;
      if (l > 0u) s0 = w(QT_LOOPS, l - 1u);
      uint s1 = w(QT_LOOPS, l);
      for (uint s = s0; s < s1; s++) {
        uint t = s + 1u;
        if (t >= s1) t = s0;
        vec2 A = rel(iv2(QT_VERT, s)) - p;
        vec2 Bv = rel(iv2(QT_VERT, t)) - p;
        if ((A.y > 0.0) == (Bv.y > 0.0)) continue;
        vec2 L = A; vec2 H = Bv;
        if (A.y > 0.0) { L = Bv; H = A; }
        if ((H.x - L.x) * (-L.y) - (H.y - L.y) * (-L.x) > 0.0) inside = !inside;
      }
    }
    return inside;
  }
  return false;
}

// v1.3 u16 BVH box of a node of a cell with base corner base.xy (quanta), shift base.z.
ivec4 box16(uint k, uint i, ivec3 base) {
  uint a = w(k, 2u * i);
  uint b = w(k, 2u * i + 1u);
  uvec4 u = uvec4(a & 0xffffu, a >> 16u, b & 0xffffu, b >> 16u);
  if (u.x > u.z || u.y > u.w) return ivec4(1, 1, 0, 0);
  return base.xyxy + (ivec4(u) << base.z);
}

// Stack-less walk of a cell's BVH (step 3) as a cursor.
struct Walk { uint first; uint internal; uint count; uint entry; uint i; bool done; uint kind; };

Walk walk_make(uint kind, uint cell) {
  Walk wk;
  wk.kind = kind;
  wk.entry = w(kind, 2u * cell);
  wk.count = w(kind, 2u * cell + 2u) - wk.entry;
  wk.first = w(kind, 2u * cell + 1u);
  uint p = (w(kind, 2u * cell + 3u) - wk.first + 1u) >> 1u;
  wk.internal = p > 0u ? p - 1u : 0u;
  wk.i = 0u;
  wk.done = p == 0u;
  return wk;
}
void walk_advance(inout Walk wk) {
  uint i = wk.i;
  while (i != 0u && (i & 1u) == 0u) i = (i - 1u) >> 1u;
  if (i == 0u) wk.done = true; else wk.i = i + 1u;
}
// The next leaf (list entry index) whose boxes hold p, or -1 at the end.
int walk_next(inout Walk wk, vec2 p, ivec3 base) {
  uint bk = wk.kind == CLF ? LBVH : PBVH;
  for (;;) {
    if (wk.done) return -1;
    uint i = wk.i;
    float m = wk.kind == CLF ? MARGIN : 0.0;
    if (box_near(box16(bk, wk.first + i, base), p, m)) {
      if (i < wk.internal) { wk.i = 2u * i + 1u; continue; }
      uint k = i - wk.internal;
      walk_advance(wk);
      if (k < wk.count) return int(wk.entry + k);
    } else {
      walk_advance(wk);
    }
  }
  return -1;
}

bool visible(uint layer) {
  uint word = layer >> 5u;
  if (word >= u_lin.z) return true;
  return (texelFetch(u_vis, lin(word), 0).r & (1u << (layer & 31u))) != 0u;
}

float cross2(vec2 a, vec2 b) { return a.x * b.y - a.y * b.x; }
bool in_triangle(vec2 a, vec2 b, vec2 c, vec2 d) {
  float c0 = cross2(b - a, d - a);
  float c1 = cross2(c - b, d - b);
  float c2 = cross2(a - c, d - c);
  return (c0 >= 0.0 && c1 >= 0.0 && c2 >= 0.0) || (c0 <= 0.0 && c1 <= 0.0 && c2 <= 0.0);
}
bool is_null(vec2 v) { return v.x == 0.0 && v.y == 0.0; }
vec2 c_miter(uint v) { return KS * vec2(wf(LC, 6u * v), wf(LC, 6u * v + 1u)); }
vec2 c_in(uint v) { return KS * vec2(wf(LC, 6u * v + 2u), wf(LC, 6u * v + 3u)); }
vec2 c_out(uint v) { return KS * vec2(wf(LC, 6u * v + 4u), wf(LC, 6u * v + 5u)); }

// prep::min_width_scale (static_lines.glsl width_scale).
float width_scale(uint line) {
  if (F.e.w == 0u || !(F.mw.x > 0.0)) return 1.0;
  float n = wf(MW, min(w(LP, 8u * line + 5u), F.e.w - 1u));
  if (!(n > 0.0)) return 1.0;
  float f = 0.5;
  if (((w(LP, 8u * line + 3u) >> 2u) & 3u) != 0u) f = 1.0;
  float want = n * f * min(PX, F.mw.x);
  float hw = wf(LP, 8u * line);
  if (want > hw && hw > 0.0) return want / hw;
  return 1.0;
}

const int HIT_NONE = 0; const int HIT_CLIPPED = 1; const int HIT_COVERED = 2;

// Slope widths (formats/SPEC.md "Slope widths", step 6b; slope_widths.glsl).
bool slope_applies(uint line) {
  if (F.tn.z == 0u || (GS.x == 0.0 && GS.y == 0.0)) return false;
  return w(SL, min(w(LP, 8u * line + 5u), F.tn.z - 1u)) != 0u;
}
float gdot(vec2 u, vec2 v) { return dot(u, v) + dot(GS, u) * dot(GS, v); }
vec2 slope_normal(vec2 wv, float hw) {
  float gam = 1.0 + dot(GS, GS);
  float gw = dot(GS, wv);
  return hw / sqrt(dot(wv, wv) - gw * gw / gam) * (wv - gw / gam * GS);
}
vec2 slope_miter(vec2 a, vec2 b, float hw) { return hw * hw / (hw * hw + gdot(a, b)) * (a + b); }
bool slope_overhang(vec2 x, vec2 m, vec2 mg, vec2 wv, float hw, bool ahead) {
  vec2 t = vec2(-wv.y, wv.x);
  if (ahead) t = vec2(wv.y, -wv.x);
  if (cross2(mg, x) * cross2(mg, t) < 0.0 || cross2(m, x) * cross2(m, t) > 0.0) return false;
  float gt = dot(GS, t);
  float c = cross2(t, x);
  return c * c * (1.0 + dot(GS, GS)) <= hw * hw * (dot(t, t) + gt * gt);
}
bool surface_band_covers(vec2 e, vec2 d, float hw, uint corner, uint s, uint ei) {
  float hw2 = hw * hw;
  float ee = dot(e, e);
  float tp = 0.0;
  if (ee > 0.0) tp = clamp(dot(d, e) / ee, 0.0, 1.0);
  vec2 r = d - tp * e;
  if (corner == 0u) {  // round
    float eg = gdot(e, e);
    float t = 0.0;
    if (eg > 0.0) t = clamp(gdot(d, e) / eg, 0.0, 1.0);
    vec2 rg = d - t * e;
    return gdot(rg, rg) <= hw2;
  }
  vec2 pa = c_miter(s);
  vec2 pb = c_miter(ei);
  float reach2 = hw2;
  if (corner == 1u) reach2 = max(hw2, max(dot(pa, pa), dot(pb, pb)));
  if (dot(r, r) > reach2) return false;
  vec2 a_in = c_in(s);
  vec2 a_out = c_out(s);
  vec2 b_in = c_in(ei);
  vec2 b_out = c_out(ei);
  if (corner == 1u) {  // miter
    bool na = is_null(pa);
    bool nb = is_null(pb);
    float sa = cross2(e, a_out) >= 0.0 ? 1.0 : -1.0;
    float sb = cross2(e, b_in) >= 0.0 ? 1.0 : -1.0;
    vec2 ma = slope_normal(sa * a_out, hw);
    if (!na) ma = slope_miter(slope_normal(sa * a_in, hw), slope_normal(sa * a_out, hw), hw);
    vec2 mb = slope_normal(sb * b_in, hw);
    if (!nb) mb = slope_miter(slope_normal(sb * b_in, hw), slope_normal(sb * b_out, hw), hw);
    return in_triangle(-ma, e - mb, e + mb, d) || in_triangle(-ma, e + mb, ma, d) ||
           (na && gdot(d, d) <= hw2) || (nb && gdot(d - e, d - e) <= hw2) ||
           (!na && slope_overhang(d, pa, ma, sa * a_in, hw, false)) ||
           (!nb && slope_overhang(d - e, pb, mb, sb * b_out, hw, true));
  }
  vec2 n = slope_normal(a_out, hw);
  float c = cross2(e, n);
  if (c != 0.0) {
    float sv = cross2(e, d) / c;
    float tv = cross2(d, n) / c;
    if (tv >= 0.0 && tv <= 1.0 && abs(sv) <= 1.0) return true;
  }
  if (is_null(a_in)) {
    if (gdot(d, d) <= hw2) return true;
  } else if (in_triangle(vec2(0.0), slope_normal(a_in, hw), n, d)) return true;
  if (is_null(b_out)) return gdot(d - e, d - e) <= hw2;
  return in_triangle(e, e + slope_normal(b_in, hw), e + slope_normal(b_out, hw), d);
}

// The gradient of the terrain triangle under p (Heightfield::gradient_at): 0 outside the mesh.
vec2 gradient_at(vec2 p) {
  float fx = (p.x - F.tg.x) / F.tg.z;
  float fy = (p.y - F.tg.y) / F.tg.w;
  if (!(fx >= 0.0 && fy >= 0.0 && fx <= float(F.tn.x - 1u) && fy <= float(F.tn.y - 1u))) return vec2(0.0);
  uint i = min(uint(fx), F.tn.x - 2u);
  uint j = min(uint(fy), F.tn.y - 2u);
  bool upper = fx - float(i) < fy - float(j);
  return TG(2u * (i + (F.tn.x - 1u) * j) + (upper ? 1u : 0u));
}

// Step 6: segment (s, ei) of line "line" at p.
int segment_test(uint s, uint ei, vec2 p, uint line) {
  KS = width_scale(line);
  float hw = wf(LP, 8u * line) * KS;
  uint style = w(LP, 8u * line + 3u);
  float hw2 = hw * hw;
  uint corner = style & 3u;
  uint outline = (style >> 2u) & 3u;
  ivec2 ai = iv2(LV, s);
  vec2 e = vec2(iv2(LV, ei) - ai) * Q;
  vec2 d = p - rel(ai);
  bool covered = false;
  if (slope_applies(line)) {
    covered = surface_band_covers(e, d, hw, corner, s, ei);
  } else if (corner == 0u) {
    float ee = dot(e, e);
    float t = 0.0;
    if (ee > 0.0) t = clamp(dot(d, e) / ee, 0.0, 1.0);
    vec2 r = d - t * e;
    covered = dot(r, r) <= hw2;
  } else if (corner == 1u) {
    vec2 ma = c_miter(s);
    vec2 mb = c_miter(ei);
    bool na = is_null(ma);
    bool nb = is_null(mb);
    if (na) { ma = c_out(s); if (cross2(e, ma) < 0.0) ma = -ma; }
    if (nb) { mb = c_in(ei); if (cross2(e, mb) < 0.0) mb = -mb; }
    covered = in_triangle(-ma, e - mb, e + mb, d) || in_triangle(-ma, e + mb, ma, d) ||
              (na && dot(d, d) <= hw2) || (nb && dot(d - e, d - e) <= hw2);
  } else {
    vec2 n = c_out(s);
    float c = cross2(e, n);
    if (c != 0.0) {
      float sv = cross2(e, d) / c;
      float tv = cross2(d, n) / c;
      covered = tv >= 0.0 && tv <= 1.0 && abs(sv) <= 1.0;
    }
    vec2 a_in = c_in(s);
    vec2 b_out = c_out(ei);
    if (!covered) {
      if (is_null(a_in)) covered = dot(d, d) <= hw2; else covered = in_triangle(vec2(0.0), a_in, n, d);
    }
    if (!covered) {
      if (is_null(b_out)) covered = dot(d - e, d - e) <= hw2;
      else covered = in_triangle(e, e + c_in(ei), e + b_out, d);
    }
  }
  if (!covered) return HIT_NONE;
  if (outline == 0u) return HIT_COVERED;
  if ((style & 32u) != 0u) {
    bool inside = qt_contains(w(LP, 8u * line + 7u), p);
    return inside == ((style & 64u) != 0u) ? HIT_COVERED : HIT_CLIPPED;
  }
  float K = outline == 1u ? 1.0 : -1.0;
  if (K * cross2(e, d) < 0.0) return HIT_NONE;
  vec2 cb_out = c_out(ei);
  if (!is_null(cb_out)) {
    float o = cross2(e, c_in(ei)) >= 0.0 ? 1.0 : -1.0;
    if (K * o < 0.0 && K * dot(d - e, o * cb_out) < 0.0) return HIT_NONE;
  }
  vec2 ca_in = c_in(s);
  if (!is_null(ca_in)) {
    float o = cross2(e, c_out(s)) >= 0.0 ? 1.0 : -1.0;
    if (K * o < 0.0 && K * dot(d, o * ca_in) < 0.0) return HIT_NONE;
  }
  return HIT_COVERED;
}

// Step 6c (dash.glsl).
bool dash_covers(uint s, uint ei, vec2 p, uint layer) {
  if (layer >= w(DT, 0u)) return true;
  uint n = w(DT, 2u + 3u * layer);
  if (n == 0u) return true;
  uint first = w(DT, 1u + 3u * layer);
  float period = wf(DT, 3u + 3u * layer);
  ivec2 ai = iv2(LV, s);
  vec2 e = vec2(iv2(LV, ei) - ai) * Q;
  vec2 d = p - rel(ai);
  float ee = dot(e, e);
  float t = 0.0;
  if (ee > 0.0) t = clamp(dot(d, e) / ee, 0.0, 1.0);
  float sd = wf(DV, s) + t * sqrt(ee);
  float r = sd - period * floor(sd / period);
  if (!(r >= 0.0 && r < period)) r = 0.0;
  float a = 0.0;
  for (uint i = 0u; i < n; i++) {
    float len = wf(DT, first + i);
    if (r < a + len || i + 1u == n) return (i & 1u) == 0u;
    a += len;
  }
  return true;
}

// Step 7: exterior polygon entry at p (its cell's holes cut it out).
bool polygon_covers(uint entry, vec2 p) {
  if (!qt_contains(w(CPE, 2u * entry + 1u), p)) return false;
  uint h0 = w(CPH, entry);
  uint h1 = w(CPH, entry + 1u);
  for (uint h = h0; h < h1; h++) {
    if (qt_contains(w(CH, 2u * h + 1u), p)) return false;
  }
  return true;
}

bool layer_unlit(uint layer) {
  if (F.tn.w == 0u) return false;
  return w(UL, min(layer, F.tn.w - 1u)) != 0u;
}

vec4 unpack8(uint v) {
  return vec4(float(v & 255u), float((v >> 8u) & 255u), float((v >> 16u) & 255u), float(v >> 24u)) / 255.0;
}

bool under(inout vec4 acc, uint rgba, uint layer) {
  vec4 c = unpack8(rgba);
  if (TOP.x == 0u && c.a > 0.0) TOP = uvec4(CAND, layer, CAND_FEATURE, CAND_INDEX);
  float wt = (1.0 - acc.a) * c.a;
  acc = vec4(acc.rgb + wt * c.rgb, acc.a + wt);
  if (layer_unlit(layer)) UNLIT += wt * c.rgb;
  return acc.a >= 0.999;
}

uint line_rank(int entry) {
  uint line = w(LVL, w(CS, 2u * uint(entry)));
  return w(LP, 8u * line + 2u);
}
uint poly_rank(int entry) {
  return w(PPROPS, 8u * w(CPE, 2u * uint(entry)) + 1u) + F.e.z;
}

// Steps 1–8 at the anchor-relative point p: premultiplied colour.
vec4 query(vec2 p) {
  vec4 acc = vec4(0.0);
  ivec2 g = F.a.zw + ivec2(floor((F.b.xy + p) / F.b.zw));
  if (g.x < 0 || g.y < 0 || g.x >= F.c.x || g.y >= F.c.y) return acc;
  uint cell = uint(g.x + F.c.x * g.y);
  ivec3 base = ivec3(F.c.zw + g * F.d.xy - ivec2(1 << F.d.z), F.d.z);
  Walk lw; lw.done = true; lw.kind = CLF;
  Walk pw; pw.done = true; pw.kind = CPF;
  if ((F.d.w & 2) != 0) lw = walk_make(CLF, cell);
  if ((F.d.w & 4) != 0) pw = walk_make(CPF, cell);
  int kl = walk_next(lw, p, base);
  int kp = walk_next(pw, p, base);
  uint rl = 0u; uint rp = 0u;
  if (kl >= 0) rl = line_rank(kl);
  if (kp >= 0) rp = poly_rank(kp);
  uint last = 0xffffffffu;
  for (;;) {
    if (kl < 0 && kp < 0) break;
    if (kp < 0 || (kl >= 0 && rl <= rp)) {
      uvec2 seg = uv2(CS, uint(kl));
      uint line = w(LVL, seg.x);
      if (line != last && visible(w(LP, 8u * line + 5u))) {
        int hit = segment_test(seg.x, seg.y, p, line);
        if (hit == HIT_COVERED && !dash_covers(seg.x, seg.y, p, w(LP, 8u * line + 5u))) hit = HIT_NONE;
        if (hit != HIT_NONE) last = line;
        CAND = 1u; CAND_FEATURE = w(LP, 8u * line + 6u); CAND_INDEX = line;
        if (hit == HIT_COVERED && under(acc, w(LP, 8u * line + 1u), w(LP, 8u * line + 5u))) break;
      }
      kl = walk_next(lw, p, base);
      if (kl >= 0) rl = line_rank(kl);
    } else {
      uint poly = w(CPE, 2u * uint(kp));
      if (visible(w(PPROPS, 8u * poly + 4u)) && polygon_covers(uint(kp), p)) {
        CAND = 2u; CAND_FEATURE = w(PPROPS, 8u * poly + 5u); CAND_INDEX = poly;
        if (under(acc, w(PPROPS, 8u * poly), w(PPROPS, 8u * poly + 4u))) break;
      }
      kp = walk_next(pw, p, base);
      if (kp >= 0) rp = poly_rank(kp);
    }
  }
  return acc;
}

vec3 tvertex(uint i, uint j) {
  return vec3(F.tg.x + float(i) * F.tg.z, F.tg.y + float(j) * F.tg.w, TZ(i + F.tn.x * j));
}
// wgsl_decals.js ground_point: the pixel ray meets the plane of the mesh
// triangle under "near", twice.
vec2 ground_point(vec2 ndc, vec2 near) {
  vec3 o = F.ro.xyz;
  vec3 d = F.rf.xyz + ndc.x * F.rr.xyz + ndc.y * F.ru.xyz;
  if (F.ro.w == 0.0) { o = F.ro.xyz + ndc.x * F.rr.xyz + ndc.y * F.ru.xyz; d = F.rf.xyz; }
  vec2 p = near;
  for (int it = 0; it < 2; it++) {
    float fx = (p.x - F.tg.x) / F.tg.z;
    float fy = (p.y - F.tg.y) / F.tg.w;
    uint i = uint(clamp(floor(fx), 0.0, float(F.tn.x - 2u)));
    uint j = uint(clamp(floor(fy), 0.0, float(F.tn.y - 2u)));
    vec3 A = tvertex(i, j);
    vec3 Bv = tvertex(i + 1u, j);
    vec3 C = tvertex(i + 1u, j + 1u);
    if (fy - float(j) > fx - float(i)) { Bv = C; C = tvertex(i, j + 1u); }
    vec3 n = cross(Bv - A, C - A);
    float dn = dot(d, n);
    if (dn == 0.0) break;
    float t = dot(A - o, n) / dn;
    p = (o + t * d).xy;
  }
  return p;
}

// round(clamp(x, 0, 1) * 255) / 255: the composite's quantisation
// (wgsl_frame.js q8), exact through the RGBA8 target's conversion.
vec4 q8(vec4 x) { return floor(clamp(x, 0.0, 1.0) * 255.0 + 0.5) / 255.0; }

void main() {
  // The terrain pass drew row 0 of the image at the bottom of the target
  // (webgl2.js): gl_FragCoord counts pixels from the image's top-left.
  uvec2 gid = uvec2(gl_FragCoord.xy);
  uint W = F.e.x;
  uint H = F.e.y;
  vec4 t = texelFetch(u_terrain, ivec2(gid), 0);
  vec2 p;
  float z = 0.0;
  vec4 c = vec4(0.0);
  UNLIT = vec3(0.0);
  bool drawn = true;
  if ((F.d.w & 1) != 0) {
    // top-down: the pixel centre exactly (SPEC "Points, pixels and precision")
    p = vec2(F.f.x + (float(gid.x) + 0.5) * F.f.z, F.f.y + (float(gid.y) + 0.5) * F.f.w);
  } else {
    // the ray's terrain point, from the terrain pass's interpolated ground point
    uvec4 gp = texelFetch(u_ground, ivec2(gid), 0);
    drawn = gp.w != 0u;
    vec2 ndc = vec2((float(gid.x) + 0.5) / float(W) * 2.0 - 1.0, 1.0 - (float(gid.y) + 0.5) / float(H) * 2.0);
    p = ground_point(ndc, uintBitsToFloat(gp.xy) + u_go);
    z = uintBitsToFloat(gp.z);
  }
  // A tileset: a pass with no decals (clip mode 2) lays the terrain; each
  // tile's pass (mode 1) then draws the pixels whose ground point is in its
  // square and leaves the others.
  if (F.bx.z == 1u && (!drawn || p.x < F.cl.x || p.y < F.cl.y || p.x >= F.cl.z || p.y >= F.cl.w)) discard;
  if (F.bx.z == 2u) drawn = false;
  if (drawn) {
    if (F.tn.z != 0u) GS = gradient_at(p);
    if (F.mw.x > 0.0) {
      PX = F.mw.z;
      if (PX <= 0.0) PX = length(vec3(p, z) - F.ro.xyz) * F.mw.w;
      MARGIN = F.mw.y * min(PX, F.mw.x);
    }
    c = query(p);
  }
  o_pick = TOP;
  vec3 u = UNLIT;
  o_rgba = q8(vec4((c.rgb - u) * t.a + u + (1.0 - c.a) * t.rgb, 1.0));
  o_decals = c.a > 0.0 ? q8(vec4(c.rgb / c.a, c.a)) : vec4(0.0);
}
`;
