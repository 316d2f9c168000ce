// lod_common.glsl — LOCALIS LOD of the dynamic lines (formats/SPEC.md
// "Visibility rule" and "Choosing the threshold"): the package's lod_points
// and lod_segments, the map from LOD points to dynamic vertices made when
// the package is loaded (prep::lod_draw_map), and the frame's selection,
// at bindings DECAL_SSBO_LOD_*. Instead of dyn_common.glsl it declares the
// four of its buffers the LOD passes use, as dyn_common.glsl does: std430
// blocks are active whether used or not, and a compute shader may have 16
// (llvmpipe).

const uint NONE = 0xffffffffu;
layout(std430, binding = DECAL_SSBO_DYN_FLAGS) buffer DynFlags { uint dyn_flags[]; };      // bit 31 keep, 0..5 outcode
layout(std430, binding = DECAL_SSBO_DYN_SCAN) buffer DynScan { uint dyn_scan[]; };        // keep flag before the scan
layout(std430, binding = DECAL_SSBO_DYN_SEGMENTS) buffer DynSegments { uvec4 dyn_segment[]; };
layout(std430, binding = DECAL_SSBO_DYN_COUNTERS) buffer DynCounters { uint draw_count; };    // the indirect draw's count
uniform uint u_vertex_count;

struct LodPoint { int x; int y; int eval_x; int eval_y; float e_star; float d_star; uint line; uint flags; };
layout(std430, binding = DECAL_SSBO_LOD_POINTS) readonly buffer LodPoints { LodPoint lod_point[]; };
// per segment: (a, b, generator, splitter)
layout(std430, binding = DECAL_SSBO_LOD_SEGMENTS) readonly buffer LodSegments { uvec4 lod_segment[]; };
// per point: (its dynamic vertex, end link) of prep::LodDrawMap
layout(std430, binding = DECAL_SSBO_LOD_MAP) readonly buffer LodMap { uvec2 lod_map[]; };
// per point, this frame: (the visible segment's other point before it, after it); NONE when none
layout(std430, binding = DECAL_SSBO_LOD_LINKS) buffer LodLinks { uvec2 lod_link[]; };
// per dynamic line: 1 when it is drawn from its LOD segments
layout(std430, binding = DECAL_SSBO_LOD_LINE_DRAWN) readonly buffer LodLineDrawn { uint lod_line_drawn[]; };
// the selection: counts, then the visible segments' indices (compacted by
// an atomic counter, in no particular order)
layout(std430, binding = DECAL_SSBO_LOD_SELECTION) buffer LodSelection {
  uint lod_selected; uint lod_drawn; uint lod_reserved0; uint lod_reserved1;
  uint lod_visible[];
};

uniform uint u_lod_segment_count;
uniform dvec3 u_lod_camera;  // C of the visibility rule, metres relative to the package origin
uniform dvec2 u_lod_eps;     // eps(d) = x + y * max(d, 0), metres (prep::render::lod_view)
