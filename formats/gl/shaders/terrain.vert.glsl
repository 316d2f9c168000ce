// terrain.vert.glsl — heightfield mesh; positions are metres relative to the
// camera anchor (computed in double on the CPU), so no float32 world jitter.
layout(location = 0) in vec3 a_position;
layout(location = 1) in vec3 a_normal;
uniform mat4 u_view_proj;  // anchor-relative world -> clip (reversed Z)
out vec3 v_normal;
out float v_height;
#ifdef DECAL_TEXTURE_METHOD
out vec2 v_ground;  // anchor-relative ground position (texture method)
#endif
void main() {
#ifdef DECAL_TEXTURE_METHOD
  v_ground = a_position.xy;
#endif
  v_normal = a_normal;
  v_height = a_position.z;
  gl_Position = u_view_proj * vec4(a_position, 1.0);
}
