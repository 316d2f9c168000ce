// terrain.frag.glsl — simple Lambert shading into the G-buffer colour; the
// depth attachment is the G-buffer depth the decal passes back-project.
in vec3 v_normal;
uniform vec3 u_light_dir;  // towards the light, normalised
uniform vec3 u_albedo;
layout(location = 0) out vec4 o_color;
void main() {
  float l = max(dot(normalize(v_normal), u_light_dir), 0.0);
  o_color = vec4(u_albedo * (0.35 + 0.65 * l), 1.0);
}
