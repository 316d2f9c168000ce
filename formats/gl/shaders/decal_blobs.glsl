// decal_blobs.glsl — declarations of the package blobs and one accessor per
// element, for SSBO binding (std430, default) or buffer-texture binding
// (#define DECAL_TEXTURE). The declarations themselves (binding, sampler
// and element types, blob name) are DECAL_BLOBS_<GROUP>, made by
// build_program from the table in formats/gl/include/decal/gl/bindings.hpp.
// Define DECAL_POLYGONS and/or DECAL_LINES to declare only what a pass reads
// (a fragment shader may use at most 16 storage blocks).

// DECAL_FETCH(T, fn, name, swizzle) defines `T fn(uint i)`, element i of
// blob `name`: the texel's `swizzle` components, or the buffer's element.
#ifdef DECAL_TEXTURE
#define DECAL_BLOB(bp, stex, name, stype) layout(binding = bp) uniform stex t_##name;
#define DECAL_FETCH(T, fn, name, swz) T fn(uint i) { return texelFetch(t_##name, int(i))swz; }
#else
#define DECAL_BLOB(bp, stex, name, stype) layout(std430, binding = bp) readonly buffer B_##name { stype d_##name[]; };
#define DECAL_FETCH(T, fn, name, swz) T fn(uint i) { return d_##name[i]; }
#endif

// Quad-tree blobs: the polygon pass reads them for polygons, the line pass
// for the rings of clipped outlines (LineProps bit 5).
#if defined(DECAL_POLYGONS) || defined(DECAL_LINES)
#define DECAL_QUADTREE 1
DECAL_BLOBS_QUADTREE
DECAL_FETCH(ivec4, qt_node_box, qt_node_box, .xyzw)
DECAL_FETCH(ivec2, qt_node, qt_node, .xy)
DECAL_FETCH(uvec2, qt_leaf_loop_range, qt_leaf_loop_range, .xy)
DECAL_FETCH(uint, qt_leaf_loop_end, qt_leaf_loops, .x)
DECAL_FETCH(ivec2, qt_leaf_vertex, qt_leaf_vertices, .xy)
// v1.3 leaf loops (SPEC.md "Compact layout (v1.3)"): loop l holds vertices
// [qt_leaf_loop_start(l), qt_leaf_loop_end(l)), edges v -> v + 1 and the
// last back to the first.
uint qt_leaf_loop_start(uint l) { return l == 0u ? 0u : qt_leaf_loop_end(l - 1u); }
// v1.3 cell-relative u16 BVH boxes (SPEC.md "Compact layout (v1.3)",
// decal/layout.hpp): base.xy is the cell's base corner in quanta (its
// lower-left corner minus one step), base.z the step shift. Returns the box
// in quanta; an empty node gives xmin > xmax.
ivec4 bvh_box16(uvec2 b, ivec3 base) {
  uvec4 u = uvec4(b.x & 0xffffu, b.x >> 16, b.y & 0xffffu, b.y >> 16);
  if (u.x > u.z || u.y > u.w) return ivec4(1, 1, 0, 0);
  return base.xyxy + (ivec4(u) << base.z);
}
#endif  // DECAL_POLYGONS || DECAL_LINES

#ifdef DECAL_POLYGONS
struct PolyProps { uint rgba; uint order; int exterior; float value; uint layer; uint feature; uint r0; uint r1; };
DECAL_BLOBS_POLYGONS
DECAL_FETCH(uvec2, cell_poly_first, cell_poly_first, .xy)
DECAL_FETCH(uvec2, cell_poly_entry, cell_poly_entries, .xy)
DECAL_FETCH(uint, cell_poly_hole_first, cell_poly_holes, .x)
// (polygon, culling node, first hole, hole count) of entry i (v1.3:
// SPEC.md "Compact layout (v1.3)")
uvec4 cell_poly(uint i) {
  uint h = cell_poly_hole_first(i);
  return uvec4(cell_poly_entry(i), h, cell_poly_hole_first(i + 1u) - h);
}
DECAL_FETCH(uvec2, cell_hole, cell_holes, .xy)
DECAL_FETCH(uvec2, poly_bvh_box16, poly_bvh_box16, .xy)
ivec4 poly_bvh_box(uint i, ivec3 base) { return bvh_box16(poly_bvh_box16(i), base); }
DECAL_FETCH(uint, poly_root, poly_root_node, .x)
// v1.3 per-cell firsts (SPEC.md "Compact layout (v1.3)"): the cell's
// (first, count) into cell_polys and (first node, leaf slots, internal
// nodes, 0) of its BVH in poly_bvh_box.
uvec2 cell_poly_range(uint c) { return uvec2(cell_poly_first(c).x, cell_poly_first(c + 1u).x - cell_poly_first(c).x); }
uvec4 poly_bvh_range(uint c) {
  uint f = cell_poly_first(c).y, p = (cell_poly_first(c + 1u).y - f + 1u) >> 1;
  return uvec4(f, p, p > 0u ? p - 1u : 0u, 0u);
}
#ifdef DECAL_TEXTURE
uint  poly_rgba(uint i)         { return texelFetch(t_poly_props, int(2u * i)).x; }
uint  poly_order(uint i)        { return texelFetch(t_poly_props, int(2u * i)).y; }
uint  poly_layer(uint i)        { return texelFetch(t_poly_props, int(2u * i + 1u)).x; }
#else
uint  poly_rgba(uint i)         { return d_poly_props[i].rgba; }
uint  poly_order(uint i)        { return d_poly_props[i].order; }
uint  poly_layer(uint i)        { return d_poly_props[i].layer; }
#endif
#endif  // DECAL_POLYGONS

#ifdef DECAL_LINES
struct LineProps { float half_width; uint rgba; uint order; uint style; float value; uint layer; uint feature; uint clip_node; };
struct LineCorner { vec2 miter; vec2 bevel_in; vec2 bevel_out; };
DECAL_BLOBS_LINES
DECAL_FETCH(ivec2, line_vertex, line_vertices, .xy)
DECAL_FETCH(uint, line_of_vertex, line_vertex_line, .x)
DECAL_FETCH(uvec2, cell_line_first, cell_line_first, .xy)
DECAL_FETCH(uvec2, cell_segment, cell_segments, .xy)
DECAL_FETCH(uvec2, line_bvh_box16, line_bvh_box16, .xy)
ivec4 line_bvh_box(uint i, ivec3 base) { return bvh_box16(line_bvh_box16(i), base); }
// v1.3 per-cell firsts, as for polygons.
uvec2 cell_segment_range(uint c) { return uvec2(cell_line_first(c).x, cell_line_first(c + 1u).x - cell_line_first(c).x); }
uvec4 line_bvh_range(uint c) {
  uint f = cell_line_first(c).y, p = (cell_line_first(c + 1u).y - f + 1u) >> 1;
  return uvec4(f, p, p > 0u ? p - 1u : 0u, 0u);
}
#ifdef DECAL_TEXTURE
// (half_width, rgba, order, style) of a line
uvec4 line_props(uint l)         { return texelFetch(t_line_props, int(2u * l)); }
uint  line_clip_node(uint l)     { return texelFetch(t_line_props, int(2u * l + 1u)).w; }
uint  line_layer(uint l)         { return texelFetch(t_line_props, int(2u * l + 1u)).y; }
vec2  corner_miter(uint v)       { return texelFetch(t_line_corners, int(3u * v)).xy; }
vec2  corner_bevel_in(uint v)    { return texelFetch(t_line_corners, int(3u * v + 1u)).xy; }
vec2  corner_bevel_out(uint v)   { return texelFetch(t_line_corners, int(3u * v + 2u)).xy; }
#else
uvec4 line_props(uint l)         { LineProps p = d_line_props[l]; return uvec4(floatBitsToUint(p.half_width), p.rgba, p.order, p.style); }
uint  line_clip_node(uint l)     { return d_line_props[l].clip_node; }
uint  line_layer(uint l)         { return d_line_props[l].layer; }
vec2  corner_miter(uint v)       { return d_line_corners[v].miter; }
vec2  corner_bevel_in(uint v)    { return d_line_corners[v].bevel_in; }
vec2  corner_bevel_out(uint v)   { return d_line_corners[v].bevel_out; }
#endif
#endif  // DECAL_LINES

#ifdef DECAL_DYNAMIC
#ifndef DECAL_LINES
struct LineProps { float half_width; uint rgba; uint order; uint style; float value; uint layer; uint feature; uint clip_node; };
#endif
DECAL_BLOBS_DYNAMIC
DECAL_FETCH(ivec4, dyn_vertex, dyn_vertices, .xyzw)
DECAL_FETCH(ivec2, dyn_prev_next, dyn_prev_next, .xy)
DECAL_FETCH(uint, dyn_line_start, dyn_line_start, .x)
#ifdef DECAL_TEXTURE
uvec4 dyn_line_props(uint l)   { return texelFetch(t_dyn_line_props, int(2u * l)); }
uint  dyn_line_layer(uint l)   { return texelFetch(t_dyn_line_props, int(2u * l + 1u)).y; }
#else
uvec4 dyn_line_props(uint l)   { LineProps p = d_dyn_line_props[l]; return uvec4(floatBitsToUint(p.half_width), p.rgba, p.order, p.style); }
uint  dyn_line_layer(uint l)   { return d_dyn_line_props[l].layer; }
#endif
#endif  // DECAL_DYNAMIC
