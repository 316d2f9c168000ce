// method_colour.frag.glsl — one feature colour, premultiplied: the cover
// pass of the volume method (Schneider & Klein §4.2.2) and the texture
// method's rasterisation. Blended front to back as the decal passes do
// (GL_ONE_MINUS_DST_ALPHA, GL_ONE), i.e. composite_under of
// static_common.glsl.
uniform uint u_rgba;  // straight alpha, R in the low byte
layout(location = 0) out vec4 o_color;
void main() {
  vec4 c = unpackUnorm4x8(u_rgba);
  o_color = vec4(c.rgb * c.a, c.a);
}
