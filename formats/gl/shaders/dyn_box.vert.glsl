// dyn_box.vert.glsl — one point per visible segment; the geometry shader
// builds its box.
flat out uint v_seg;
void main() {
  v_seg = uint(gl_VertexID);
  gl_Position = vec4(0.0, 0.0, 0.0, 1.0);
}
