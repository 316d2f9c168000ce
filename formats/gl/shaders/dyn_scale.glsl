// dyn_scale.glsl — world metres per pixel at a point (thesis Eq. 4.1/4.2,
// normalised to one pixel): orthographic views use one constant for the
// whole view (Eq. 4.1); perspective views scale with the distance to the eye
// times tan(FOVmin / 2) (Eq. 4.2), here 2 tan(fov_y / 2) / height.
uniform vec3 u_eye_rel;          // eye, anchor-relative
uniform float u_mpp_ortho;       // > 0: orthographic metres per pixel
uniform float u_mpp_per_metre;   // perspective: metres per pixel per metre of distance
float metres_per_pixel(vec3 p) {
  return u_mpp_ortho > 0.0 ? u_mpp_ortho : length(p - u_eye_rel) * u_mpp_per_metre;
}

// Minimum widths of dynamic lines (scene file min_width_m; formats/SPEC.md
// "Minimum widths"): half the line's layer's min_width_m in metres, 0 for
// none (an index past the table takes the last entry).
#ifdef DECAL_DYN_MIN_WIDTHS
layout(binding = DECAL_UNIT_DYN_MIN_WIDTHS) uniform samplerBuffer u_dyn_min_widths;
float dyn_min_half_width(uint line) {
  int last = textureSize(u_dyn_min_widths) - 1;
  return 0.5 * texelFetch(u_dyn_min_widths, int(min(dyn_line_layer(line), uint(last)))).x;
}
#else
float dyn_min_half_width(uint line) { return 0.0; }
#endif
