// glsl_frame.js — the terrain pass of wgsl_frame.js TERRAIN_WGSL in GLSL ES
// 3.00 for the WebGL2 renderer (webgl2.js), and the full-screen triangle
// the decal pass (glsl_decals.js) runs on.
//
// The terrain pass writes two targets: the shaded colour with its shade in
// alpha (RGBA8, as TERRAIN_WGSL), and the fragment's interpolated
// anchor-relative ground point as f32 bits with w = 1 (RGBA32UI, cleared to
// 0: no terrain), the first guess the decal pass's ground_point refines.
// Depth is reversed as in the WebGPU renderer (clip z / w from 1 at the
// near plane to 0), written through gl_FragDepth into a 32-bit float depth
// buffer so that it keeps its float precision near 0 without a clip-control
// extension; fragments past the orthographic depth range (z < 0, which
// WebGPU clips and GL does not) are discarded. y is negated in clip space:
// the image's row 0 lands on the target's row 0, so that readPixels returns
// rows top first and gl_FragCoord counts rows from the image's top.

export const TERRAIN_VS = /* glsl */ `#version 300 es
layout(std140) uniform Terrain {
  mat4 view_proj;  // anchor-relative world -> clip (reversed Z, WebGPU depth range)
  vec4 light;      // xyz: towards the light, normalised; w: sea level (m)
  vec4 albedo;
} U;
layout(location = 0) in vec3 a_pos;
layout(location = 1) in vec3 a_normal;
out vec3 v_normal;
out vec3 v_ground;
out vec2 v_zw;
void main() {
  vec4 c = U.view_proj * vec4(a_pos, 1.0);
  v_normal = a_normal;
  v_ground = a_pos;
  v_zw = c.zw;
  gl_Position = vec4(c.x, -c.y, c.z, c.w);
}
`;

export const TERRAIN_FS = /* glsl */ `#version 300 es
precision highp float;
layout(std140) uniform Terrain {
  mat4 view_proj;
  vec4 light;
  vec4 albedo;
} U;
in vec3 v_normal;
in vec3 v_ground;
in vec2 v_zw;
layout(location = 0) out vec4 o_colour;
layout(location = 1) out uvec4 o_ground;
void main() {
  float depth = v_zw.x / v_zw.y;
  if (depth < 0.0) discard;
  gl_FragDepth = depth;
  float l = max(dot(normalize(v_normal), U.light.xyz), 0.0);
  vec3 albedo = U.albedo.rgb;
  if (v_ground.z <= U.light.w) albedo = vec3(0.45, 0.58, 0.70);
  float shade = 0.35 + 0.65 * l;
  o_colour = vec4(albedo * shade, shade);
  o_ground = uvec4(floatBitsToUint(v_ground), 1u);
}
`;

/** A triangle that covers the viewport (gl_VertexID 0, 1, 2). */
export const FULLSCREEN_VS = /* glsl */ `#version 300 es
void main() {
  vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
  gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
`;
