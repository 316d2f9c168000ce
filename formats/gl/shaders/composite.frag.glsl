// composite.frag.glsl — dynamic lines over static decals over the terrain
// colour (both decal layers premultiplied). With u_decal_light the static
// decals are lit: times the terrain pass's shade at the pixel (its alpha),
// all but the share of the layers drawn unlit (u_unlit, formats/SPEC.md
// "Lit decals").
layout(binding = DECAL_UNIT_DYNAMIC_LAYER) uniform sampler2D u_dynamic;
layout(binding = DECAL_UNIT_TERRAIN_COLOUR) uniform sampler2D u_terrain;
layout(binding = DECAL_UNIT_DECAL_LAYER) uniform sampler2D u_decals;
#ifdef DECAL_UNLIT_LAYERS
layout(binding = DECAL_UNIT_UNLIT_LAYER) uniform sampler2D u_unlit;
#endif
uniform bool u_decal_light;
layout(location = 0) out vec4 o_color;
void main() {
  ivec2 px = ivec2(gl_FragCoord.xy);
  vec4 t = texelFetch(u_terrain, px, 0);
  vec4 d = texelFetch(u_decals, px, 0);
  vec4 l = texelFetch(u_dynamic, px, 0);
  vec3 u = vec3(0.0);
#ifdef DECAL_UNLIT_LAYERS
  u = texelFetch(u_unlit, px, 0).rgb;
#endif
  vec3 c = (u_decal_light ? (d.rgb - u) * t.a + u : d.rgb) + (1.0 - d.a) * t.rgb;
  o_color = vec4(l.rgb + (1.0 - l.a) * c, 1.0);
}
