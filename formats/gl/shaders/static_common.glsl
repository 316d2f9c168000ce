// static_common.glsl — what both static decal passes share (thesis §4.4.1):
// back-projection of the pixel centre with the terrain depth, the grid cell
// of that point, and front-to-back compositing.
//
// Precision (ARCHITECTURE.md "Guarantees" 1): every position in these shaders is metres
// relative to the camera anchor u_anchor_q (integer quanta from the package
// origin). Stored vertices are int32 quanta; the shader subtracts the anchor
// in integers first and converts the small difference to float, so no
// absolute float32 coordinate ever appears.

const float QUANTUM = 0.001;  // decal::kQuantumMetres

layout(binding = DECAL_UNIT_DEPTH) uniform sampler2D u_depth;  // terrain depth (reversed Z, float)
uniform mat4 u_inv_view_proj;     // clip -> anchor-relative world (metres)
uniform vec2 u_viewport;          // pixels
uniform ivec2 u_anchor_q;         // anchor, quanta from the package origin
uniform ivec2 u_anchor_cell;      // grid cell holding the anchor
uniform vec2 u_anchor_in_cell;    // anchor minus that cell's lower-left corner, metres
uniform vec2 u_cell_size;         // metres
uniform ivec2 u_grid_n;           // nx, ny
uniform ivec2 u_grid_origin_q;    // grid lower-left corner, quanta from the package origin
uniform ivec2 u_cell_q;           // cell size, quanta
uniform int u_box16_shift;        // step shift of the u16 BVH boxes (decal::layout::box16_shift)
uniform vec4 u_clip;              // decals only in [x, z) x [y, w), anchor-relative metres (a tileset's tile)

// Anti-aliasing: the pixel's footprint in metres at a point (the scale of
// thesis Eq. 4.1/4.2) for coverage AA; the sample position for MSAA.
uniform vec3 u_eye_rel;
uniform float u_mpp_ortho;       // > 0: orthographic metres per pixel
uniform float u_mpp_per_metre;   // perspective: metres per pixel per metre of distance
float pixel_metres(vec3 p) { return u_mpp_ortho > 0.0 ? u_mpp_ortho : length(p - u_eye_rel) * u_mpp_per_metre; }
#ifdef DECAL_MSAA
vec2 sample_offset() { return gl_SamplePosition; }  // forces per-sample shading
#else
vec2 sample_offset() { return vec2(0.5); }
#endif

// Anchor-relative metres of an integer position.
vec2 rel(ivec2 q) { return vec2(q - u_anchor_q) * QUANTUM; }

// Thesis Algorithm 3.5 lines 1-2: pixel centre + terrain depth -> world.
// Returns false where no terrain was drawn.
bool pixel_world(out vec3 p) {
  float depth = texelFetch(u_depth, ivec2(gl_FragCoord.xy), 0).r;
  if (depth <= 0.0) return false;  // reversed Z: cleared to 0 (far)
  vec2 ndc = (floor(gl_FragCoord.xy) + sample_offset()) / u_viewport * 2.0 - 1.0;
  vec4 w = u_inv_view_proj * vec4(ndc, depth, 1.0);
  p = w.xyz / w.w;
  return true;
}

// Thesis Eq. 4.3/4.4; -1 outside the grid.
int cell_of(vec2 p) {
  if (p.x < u_clip.x || p.y < u_clip.y || p.x >= u_clip.z || p.y >= u_clip.w) return -1;
  ivec2 g = u_anchor_cell + ivec2(floor((u_anchor_in_cell + p) / u_cell_size));
  if (any(lessThan(g, ivec2(0))) || any(greaterThanEqual(g, u_grid_n))) return -1;
  return g.x + u_grid_n.x * g.y;
}

// Base corner of a cell's u16 BVH boxes (decal/layout.hpp): its lower-left
// corner minus one step, in quanta; z: the step shift.
ivec3 cell_box_base(int cell) {
  ivec2 g = ivec2(cell % u_grid_n.x, cell / u_grid_n.x);
  return ivec3(u_grid_origin_q + g * u_cell_q - (1 << u_box16_shift), u_box16_shift);
}

bool box_contains(ivec4 b, vec2 p) {
  if (b.x > b.z) return false;  // empty BVH node
  vec2 lo = rel(b.xy), hi = rel(b.zw);
  return p.x >= lo.x && p.x <= hi.x && p.y >= lo.y && p.y <= hi.y;
}
#ifdef DECAL_QUADTREE
// Step 8 of the query block (libprep/evaluate/evaluate.cpp): point-in-ring
// through the quad-tree sub-tree rooted at `node`. The polygon pass queries
// polygon rings from their culling nodes; the line pass the ring of a
// clipped outline from its root (LineProps.clip_node).
bool qt_contains(uint node, vec2 p) {
  if (!box_contains(qt_node_box(node), p)) return false;
  for (;;) {
    ivec2 n = qt_node(node);
    if (n.x == 0) {  // internal: descend into the child holding p (SW, SE, NW, NE)
      uint c = uint(n.y);
      uint next = 0xffffffffu;
      for (uint k = 0u; k < 4u; ++k) {
        if (box_contains(qt_node_box(c + k), p)) { next = c + k; break; }
      }
      if (next == 0xffffffffu) return false;
      node = next;
      continue;
    }
    if (n.x == 1) return false;  // fully outside
    if (n.x == 2) return true;   // fully inside
    // partial leaf: even-odd rule over the leaf polygon (closing segments included)
    uvec2 r = qt_leaf_loop_range(uint(n.y));
    bool inside = false;
    for (uint l = r.x; l < r.x + r.y; ++l) {
      uint s0 = qt_leaf_loop_start(l), s1 = qt_leaf_loop_end(l);
      for (uint s = s0; s < s1; ++s) {
        uvec2 e = uvec2(s, s + 1u < s1 ? s + 1u : s0);
        // Step 8 of the query block: A, B relative to the point; the sign of
        // cross(H - L, -L) decides the crossing exactly as the evaluator does.
        vec2 A = rel(qt_leaf_vertex(e.x)) - p, B = rel(qt_leaf_vertex(e.y)) - p;
        if ((A.y > 0.0) == (B.y > 0.0)) continue;
        vec2 L = A.y > 0.0 ? B : A, H = A.y > 0.0 ? A : B;
        if ((H.x - L.x) * (-L.y) - (H.y - L.y) * (-L.x) > 0.0) inside = !inside;
      }
    }
    return inside;
  }
}
#endif  // DECAL_QUADTREE

// The same with the box grown by `m` metres (coverage AA reaches beyond it).
bool box_near(ivec4 b, vec2 p, float m) {
  if (b.x > b.z) return false;
  vec2 lo = rel(b.xy) - m, hi = rel(b.zw) + m;
  return p.x >= lo.x && p.x <= hi.x && p.y >= lo.y && p.y <= hi.y;
}
// Lit decals (formats/SPEC.md "Lit decals"): the composite multiplies the
// decal layer by the terrain's shade, all but the share of the layers
// drawn unlit (light = false, flagged in u_unlit_layers, an index past the
// end taking the last flag), which the passes also sum into g_unlit and
// write to a second target, blended alike (its alpha is the decal layer's).
vec3 g_unlit = vec3(0.0);
#ifdef DECAL_UNLIT_LAYERS
layout(binding = DECAL_UNIT_UNLIT_LAYERS) uniform usamplerBuffer u_unlit_layers;
bool layer_unlit(uint layer) {
  int last = textureSize(u_unlit_layers) - 1;
  return texelFetch(u_unlit_layers, int(min(layer, uint(last)))).x != 0u;
}
#else
bool layer_unlit(uint layer) { return false; }
#endif

// Front-to-back compositing of a feature covering the share `cov` of the
// pixel (coverage AA). The share goes first to the part of the pixel that
// no earlier feature of the pass covers (1 - g_area), then under the earlier
// features at their mean transmission there (1 - acc.a / g_area): two
// polygons sharing an edge each cover half of a pixel on it and together
// all of it, where compositing the coverage as opacity ("conflation") left
// a quarter to the background; a feature wholly under another composites
// as without coverage. formats/SPEC.md "Anti-aliasing".
float g_area = 0.0;
void composite_under_cov(inout vec4 acc, uint rgba, float cov, uint layer) {
  vec4 c = unpackUnorm4x8(rgba);
  float u = min(cov, 1.0 - g_area);
  float t = g_area > 0.0 ? clamp(1.0 - acc.a / g_area, 0.0, 1.0) : 1.0;
  float w = c.a * (u + (cov - u) * t);
  acc.rgb += w * c.rgb;
  if (layer_unlit(layer)) g_unlit += w * c.rgb;
  acc.a += w;
  g_area += u;
}
// Thöny et al. §3.5: coverage of a pixel of width wpix by a band of width
// wline whose centre line lies at distance d from the pixel centre.
float band_coverage(float d, float wline, float wpix) {
  return clamp((min(0.5 * wpix - d, 0.5 * wline) + min(0.5 * wpix + d, 0.5 * wline)) / wpix, 0.0, 1.0);
}

// Front-to-back compositing of a straight-alpha colour under `acc`
// (premultiplied).
void composite_under(inout vec4 acc, uint rgba, uint layer) {
  vec4 c = unpackUnorm4x8(rgba);
  float w = (1.0 - acc.a) * c.a;
  acc.rgb += w * c.rgb;
  if (layer_unlit(layer)) g_unlit += w * c.rgb;
  acc.a += w;
}
bool opaque(vec4 acc) { return acc.a >= 0.999; }

// The pass's colour at the pixel so far (premultiplied), front to back.
vec4 g_acc = vec4(0.0);
// composite_under / composite_under_cov into g_acc; true once it is opaque.
bool under_opaque(uint rgba, uint layer) { composite_under(g_acc, rgba, layer); return opaque(g_acc); }
bool under_opaque_cov(uint rgba, float cov, uint layer) {
  composite_under_cov(g_acc, rgba, cov, layer);
  return opaque(g_acc);
}

float g_wpix = 0.0;  // coverage AA: pixel_metres at the pixel's point

// The pixel's back-projected point and its grid cell; false where the pass
// draws nothing (no terrain, outside the grid or the clip). Starts g_acc
// (and g_wpix) for the pixel.
bool pixel_cell(out vec3 p, out int cell) {
  if (!pixel_world(p)) return false;
  cell = cell_of(p.xy);
  g_acc = vec4(0.0);
  g_area = 0.0;
  g_unlit = vec3(0.0);
#ifdef DECAL_AA_COVERAGE
  g_wpix = pixel_metres(p);
#endif
  return cell >= 0;
}

// Next node of the stack-less traversal of a full binary tree stored in heap
// order (thesis Eq. 4.5-4.7): climb while on a right child (even index), then
// step to the right sibling. Returns 0 when the traversal is complete.
uint bvh_next(uint i) {
  while (i != 0u && (i & 1u) == 0u) i = (i - 1u) >> 1;
  return i == 0u ? 0u : i + 1u;
}

// The stack-less walk of a cell's BVH, one for both static passes: every
// leaf whose box, grown by `margin` metres, holds p is handed in drawing
// order to bvh_leaf(range.x + k, p) (k: the cell's k-th entry), until
// bvh_leaf returns false. bvh = (first node, leaf slots, internal nodes, 0)
// of the cell (poly_bvh_range / line_bvh_range), base its cell_box_base.
// The pass defines bvh_box (its BVH's node boxes) and bvh_leaf (its test
// and compositing of one entry).
ivec4 bvh_box(uint node, ivec3 base);
bool bvh_leaf(uint entry, vec2 p);
void bvh_walk(uvec2 range, uvec4 bvh, ivec3 base, vec2 p, float margin) {
  if (bvh.y == 0u) return;
  uint internal = bvh.z;
  uint i = 0u;
  do {
    if (box_near(bvh_box(bvh.x + i, base), p, margin)) {
      if (i < internal) { i = 2u * i + 1u; continue; }
      uint k = i - internal;
      if (k < range.y && !bvh_leaf(range.x + k, p)) break;
    }
    i = bvh_next(i);
  } while (i != 0u);
}
