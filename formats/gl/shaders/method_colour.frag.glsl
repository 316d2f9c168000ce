// method_colour.frag.glsl — one feature colour, premultiplied: the cover
// pass of the volume method (Schneider & Klein §4.2.2) and the texture
// method's rasterisation. Blended front to back as the decal passes do
// (GL_ONE_MINUS_DST_ALPHA, GL_ONE), i.e. composite_under of
// static_common.glsl.
uniform uint u_rgba;  // straight alpha, R in the low byte
#ifdef DECAL_UNLIT_LAYERS
// A light = false layer's group under lit decals: its colour divided by the
// terrain's shade (the terrain target's alpha), which the composite then
// multiplies back (static_common.glsl layer_light).
uniform bool u_unlit;
layout(binding = DECAL_UNIT_TERRAIN_COLOUR) uniform sampler2D u_terrain;
#endif
layout(location = 0) out vec4 o_color;
void main() {
  vec4 c = unpackUnorm4x8(u_rgba);
#ifdef DECAL_UNLIT_LAYERS
  if (u_unlit) {
    float shade = texelFetch(u_terrain, ivec2(gl_FragCoord.xy), 0).a;
    if (shade > 0.0) c.rgb /= shade;
  }
#endif
  o_color = vec4(c.rgb * c.a, c.a);
}
