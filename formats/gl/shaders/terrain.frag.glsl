// terrain.frag.glsl — simple Lambert shading into the G-buffer colour; the
// depth attachment is the G-buffer depth the decal passes back-project.
// Heights at or below 0 m (the sea in SRTM tiles) get a water tint.
in vec3 v_normal;
in float v_height;
uniform vec3 u_light_dir;  // towards the light, normalised
uniform vec3 u_albedo;
uniform float u_sea_level;  // metres; below or at it: water (flat terrain: -inf)
layout(location = 0) out vec4 o_color;
void main() {
  float l = max(dot(normalize(v_normal), u_light_dir), 0.0);
  vec3 albedo = v_height <= u_sea_level ? vec3(0.45, 0.58, 0.70) : u_albedo;
  o_color = vec4(albedo * (0.35 + 0.65 * l), 1.0);
}
