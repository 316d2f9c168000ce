// lod_select.comp.glsl — LOCALIS §3.5 Eq. (4) per attributed segment, the
// visibility rule of formats/SPEC.md: visible iff its generator is included
// (or it has none) and its splitter is not (or it has none); a point is
// included iff it is always drawn or e* > eps(d - d*). In double precision,
// in the order of prep::lod_point_included (`precise`: no fused
// multiply-add), so the set equals prep::visible_segments for the same
// camera and threshold. Visible segments are appended to lod_visible and
// link their points for lod_segments.
layout(local_size_x = 256) in;

bool included(uint i) {
  LodPoint p = lod_point[i];
  if ((p.flags & 1u) != 0u) return true;
  precise double dx = double(p.eval_x) * 0.001LF - u_lod_camera.x;
  precise double dy = double(p.eval_y) * 0.001LF - u_lod_camera.y;
  precise double d = sqrt(dx * dx + dy * dy + u_lod_camera.z * u_lod_camera.z) - double(p.d_star);
  precise double eps = u_lod_eps.x + u_lod_eps.y * (d > 0.0LF ? d : 0.0LF);
  return double(p.e_star) > eps;
}

void main() {
  uint s = gl_GlobalInvocationID.x;
  if (s >= u_lod_segment_count) return;
  uvec4 g = lod_segment[s];
  bool generated = g.z == NONE || included(g.z);
  bool split = g.w != NONE && included(g.w);
  if (!generated || split) return;
  lod_visible[atomicAdd(lod_selected, 1u)] = s;
  lod_link[g.x].y = g.y;
  lod_link[g.y].x = g.x;
}
