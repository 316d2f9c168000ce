// dyn_common.glsl — per-frame buffers of the dynamic-line update (thesis
// §4.3, Fig. 4.3) and helpers shared by its passes. Bindings from 24 up
// (decal::gl::kBindingFrameFirst). Positions are anchor-relative metres.

const uint NONE = 0xffffffffu;
const float QUANTUM_M = 0.001;

// per vertex: bit 31 keep, bits 0..5 frustum outcode
layout(std430, binding = 24) buffer DynFlags { uint dyn_flags[]; };
// per vertex: keep flag, then exclusive prefix within its block
layout(std430, binding = 25) buffer DynScan { uint dyn_scan[]; };
// per block of 256 vertices: kept count, then exclusive prefix
layout(std430, binding = 26) buffer DynBlocks { uint dyn_block[]; };
// kept vertex indices in original order (stream compaction result)
layout(std430, binding = 27) buffer DynCompact { uint dyn_compact[]; };
// per visible segment: (vertex a, vertex b, kept predecessor of a, kept successor of b)
layout(std430, binding = 28) buffer DynSegments { uvec4 dyn_segment[]; };
// DrawArraysIndirectCommand (segment count as points), then counters
layout(std430, binding = 29) buffer DynCounters {
  uint draw_count; uint draw_instances; uint draw_first; uint draw_base;
  uint kept; uint list_nodes; uint list_capacity; uint n_vertices;
  uint composite_truncated;  // pixels whose composite reached its step bound
};
// per pixel: head of its linked list; per node: (order, line, next, 0)
layout(std430, binding = 31) buffer DynHeads { uint dyn_head[]; };
layout(std430, binding = 32) buffer DynNodes { uvec4 dyn_node[]; };

uniform ivec2 u_anchor_q;      // quanta
uniform mat4 u_view_proj;      // anchor-relative world -> clip
uniform vec2 u_viewport;
uniform uint u_vertex_count;
uniform uint u_line_count;

vec3 dyn_position(uint v) {
  ivec4 q = dyn_vertex(v);
  return vec3(vec2(q.xy - u_anchor_q) * QUANTUM_M, float(q.z) * QUANTUM_M);
}
