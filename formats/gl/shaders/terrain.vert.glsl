// terrain.vert.glsl — heightfield mesh; positions are metres relative to the
// camera anchor (computed in double on the CPU), so no float32 world jitter.
layout(location = 0) in vec3 a_position;
layout(location = 1) in vec3 a_normal;
uniform mat4 u_view_proj;  // anchor-relative world -> clip (reversed Z)
out vec3 v_normal;
out float v_height;
void main() {
  v_normal = a_normal;
  v_height = a_position.z;
  gl_Position = u_view_proj * vec4(a_position, 1.0);
}
