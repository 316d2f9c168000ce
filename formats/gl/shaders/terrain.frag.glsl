// terrain.frag.glsl — simple Lambert shading into the G-buffer colour (the
// shade factor itself in its alpha, for lit decals); the
// depth attachment is the G-buffer depth the decal passes back-project
// (and, for slope widths, the triangle's gradient into a second target).
// Heights at or below 0 m (the sea in SRTM tiles) get a water tint.
in vec3 v_normal;
in float v_height;
uniform vec3 u_light_dir;  // towards the light, normalised
uniform vec3 u_albedo;
uniform float u_sea_level;  // metres; below or at it: water (flat terrain: -inf)
layout(location = 0) out vec4 o_color;
#ifdef DECAL_TEXTURE_METHOD
// The texture method (Taibo et al. §4): the decal layer sampled from the
// mipmapped texture of the rasterised features (trilinear), premultiplied.
in vec2 v_ground;
layout(binding = DECAL_UNIT_DECAL_TEXTURE) uniform sampler2D u_decal_texture;
uniform vec4 u_texture_box;  // anchor-relative xmin, ymin and 1 / width, 1 / height (metres)
uniform vec4 u_clip;         // anchor-relative xmin, ymin, xmax, ymax: decals only inside
layout(location = 1) out vec4 o_decal;
#endif
#ifdef DECAL_SLOPE_WIDTHS
// Slope widths (formats/SPEC.md "Slope widths"): the gradient (dh/dx, dh/dy)
// of the terrain triangle, computed per triangle in double on the CPU
// (Heightfield::triangle_gradient) and indexed by primitive, into a
// G-buffer target that the static line pass reads (slope_widths.glsl).
#ifdef DECAL_TEXTURE_METHOD
#error "slope widths are drawn by the decal method only"
#endif
layout(std430, binding = DECAL_SSBO_TERRAIN_GRADIENT) readonly buffer B_terrain_gradient { vec2 d_terrain_gradient[]; };
layout(location = 1) out vec2 o_gradient;
#endif
void main() {
#ifdef DECAL_SLOPE_WIDTHS
  o_gradient = d_terrain_gradient[gl_PrimitiveID];
#endif
#ifdef DECAL_TEXTURE_METHOD
  bool in_clip = v_ground.x >= u_clip.x && v_ground.y >= u_clip.y && v_ground.x < u_clip.z &&
                 v_ground.y < u_clip.w;
  // Sampled outside the condition: implicit derivatives need uniform control.
  vec4 decal = texture(u_decal_texture, (v_ground - u_texture_box.xy) * u_texture_box.zw);
  o_decal = in_clip ? decal : vec4(0.0);
#endif
  float l = max(dot(normalize(v_normal), u_light_dir), 0.0);
  vec3 albedo = v_height <= u_sea_level ? vec3(0.45, 0.58, 0.70) : u_albedo;
  // The shade in alpha: the composite lights the static decal layer with it.
  float shade = 0.35 + 0.65 * l;
  o_color = vec4(albedo * shade, shade);
}
