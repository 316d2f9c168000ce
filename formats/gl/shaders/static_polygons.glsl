// static_polygons.glsl — fragment shader of the static polygon pass
// (thesis Algorithm 3.5 and §4.4.1 "Polygons"), with decal_blobs.glsl
// (DECAL_POLYGONS) and static_common.glsl. Mirrors prep::evaluate():
// grid cell -> stack-less BVH over the cell's exterior polygons in drawing
// order -> quad-tree descent from the (cell, polygon) culling node -> leaf
// test (outside / inside / even-odd over the leaf polygon) -> the cell's
// interior polygons of that exterior cut it out (nested islands inside
// holes are exterior polygons themselves) -> front-to-back compositing,
// early exit. The numbered steps of the query block at the top of
// libprep/evaluate/evaluate.cpp are the specification.
// Output: premultiplied colour of the polygon layer at this pixel.

layout(location = 0) out vec4 o_color;

// Point-in-polygon through the quad-tree sub-tree rooted at `node`.
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
    uvec2 r = qt_leaf_range(uint(n.y));
    bool inside = false;
    for (uint s = r.x; s < r.x + r.y; ++s) {
      uvec2 e = qt_leaf_segment(s);
      // Step 8 of the query block: A, B relative to the point; the sign of
      // cross(H - L, -L) decides the crossing exactly as the evaluator does.
      vec2 A = rel(qt_leaf_vertex(e.x)) - p, B = rel(qt_leaf_vertex(e.y)) - p;
      if ((A.y > 0.0) == (B.y > 0.0)) continue;
      vec2 L = A.y > 0.0 ? B : A, H = A.y > 0.0 ? A : B;
      if ((H.x - L.x) * (-L.y) - (H.y - L.y) * (-L.x) > 0.0) inside = !inside;
    }
    return inside;
  }
}

// Exterior polygon entry (polygon, culling node, first hole, hole count).
// Step 7: a point in any of the cell's holes of this polygon is outside
// (islands inside holes are exterior polygons of their own).
bool polygon_covers(uvec4 e, vec2 p) {
  if (!qt_contains(e.y, p)) return false;
  for (uint h = e.z; h < e.z + e.w; ++h)
    if (qt_contains(cell_hole(h).y, p)) return false;
  return true;
}

void main() {
  vec3 p;
  if (!pixel_world(p)) discard;
  int cell = cell_of(p.xy);
  if (cell < 0) discard;
  uvec2 range = cell_poly_range(uint(cell));
  uvec4 bvh = poly_bvh_range(uint(cell));
  vec4 acc = vec4(0.0);
  if (bvh.y > 0u) {
    uint internal = bvh.z;
    uint i = 0u;
    do {
      if (box_contains(poly_bvh_box(bvh.x + i), p.xy)) {
        if (i < internal) { i = 2u * i + 1u; continue; }
        uint k = i - internal;  // leaf k = the cell's k-th polygon in drawing order
        if (k < range.y) {
          uvec4 e = cell_poly(range.x + k);
          if (polygon_covers(e, p.xy)) {
            composite_under(acc, poly_rgba(e.x));
            if (opaque(acc)) break;
          }
        }
      }
      i = bvh_next(i);
    } while (i != 0u);
  }
  if (acc.a <= 0.0) discard;
  o_color = acc;
}
