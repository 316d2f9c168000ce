// composite.frag.glsl — decal layer (premultiplied) over the terrain colour.
layout(binding = 29) uniform sampler2D u_terrain;
layout(binding = 30) uniform sampler2D u_decals;
layout(location = 0) out vec4 o_color;
void main() {
  ivec2 px = ivec2(gl_FragCoord.xy);
  vec4 t = texelFetch(u_terrain, px, 0);
  vec4 d = texelFetch(u_decals, px, 0);
  o_color = vec4(d.rgb + (1.0 - d.a) * t.rgb, 1.0);
}
