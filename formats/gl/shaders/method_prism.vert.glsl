// method_prism.vert.glsl — the geometry of `render --method volume|texture`:
// prism faces (Schneider & Klein §4.1) or tessellated features (Taibo et al.
// §4.2), positions in metres relative to the camera anchor (volume) or to
// the texture's corner (texture), computed in double on the CPU.
layout(location = 0) in vec3 a_position;
uniform mat4 u_view_proj;
void main() {
  gl_Position = u_view_proj * vec4(a_position, 1.0);
}
