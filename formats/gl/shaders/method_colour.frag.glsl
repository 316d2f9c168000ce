// method_colour.frag.glsl — one feature colour, premultiplied: the cover
// pass of the volume method (Schneider & Klein §4.2.2) and the texture
// method's rasterisation. Blended front to back as the decal passes do
// (GL_ONE_MINUS_DST_ALPHA, GL_ONE), i.e. composite_under of
// static_common.glsl.
uniform uint u_rgba;  // straight alpha, R in the low byte
layout(location = 0) out vec4 o_color;
#ifdef DECAL_UNLIT_LAYERS
// The cover of a light = false layer's group also goes to the unlit share
// the composite keeps out of the light (static_common.glsl g_unlit).
uniform bool u_unlit;
layout(location = 1) out vec4 o_unlit;
#endif
void main() {
  vec4 c = unpackUnorm4x8(u_rgba);
  o_color = vec4(c.rgb * c.a, c.a);
#ifdef DECAL_UNLIT_LAYERS
  o_unlit = vec4(u_unlit ? o_color.rgb : vec3(0.0), c.a);
#endif
}
