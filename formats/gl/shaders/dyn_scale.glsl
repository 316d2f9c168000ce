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
