// wgsl_frame.js — the terrain pass (formats/gl/shaders/terrain.vert.glsl and
// terrain.frag.glsl: Lambert shading, its shade in alpha, water tint at or
// below sea level, reversed depth), the composite (composite.frag.glsl: the
// dynamic lines over the lit static decals over the terrain)
// and the blit that shows a frame on a canvas.

export const TERRAIN_UNIFORM_BYTES = 96;

export const TERRAIN_WGSL = /* wgsl */ `
struct T {
  view_proj: mat4x4f,  // anchor-relative world -> clip (reversed Z)
  light: vec4f,        // xyz: towards the light, normalised; w: sea level (m)
  albedo: vec4f,
}
@group(0) @binding(0) var<uniform> U: T;
struct VOut {
  @builtin(position) pos: vec4f,
  @location(0) normal: vec3f,
  @location(1) ground: vec3f,
}
@vertex
fn vs(@location(0) p: vec3f, @location(1) n: vec3f) -> VOut {
  var o: VOut;
  o.pos = U.view_proj * vec4f(p, 1.0);
  o.normal = n;
  o.ground = p;
  return o;
}
@fragment
fn fs(v: VOut) -> @location(0) vec4f {
  let l = max(dot(normalize(v.normal), U.light.xyz), 0.0);
  var albedo = U.albedo.rgb;
  if (v.ground.z <= U.light.w) { albedo = vec3f(0.45, 0.58, 0.70); }
  // The shade in alpha: the composite lights the decals with it.
  let shade = 0.35 + 0.65 * l;
  return vec4f(albedo * shade, shade);
}
`;

export const COMPOSITE_WGSL = /* wgsl */ `
struct C { size: vec4<u32> }  // width, height; 1 when DYN holds the frame's dynamic layer
@group(0) @binding(0) var<uniform> U: C;
@group(0) @binding(1) var terrain: texture_2d<f32>;
@group(0) @binding(2) var<storage, read> DEC: array<vec4f>;
@group(0) @binding(3) var<storage, read_write> RGBA: array<u32>;
@group(0) @binding(4) var<storage, read_write> DECALS: array<u32>;
// Per pixel: the dynamic lines, premultiplied (wgsl_dynamic.js).
@group(0) @binding(5) var<storage, read> DYN: array<vec4f>;

// round(clamp(x, 0, 1) * 255), as the PNG writers quantise.
fn q8(x: f32) -> u32 { return u32(floor(clamp(x, 0.0, 1.0) * 255.0 + 0.5)); }
fn pack(c: vec4f) -> u32 { return q8(c.r) | (q8(c.g) << 8u) | (q8(c.b) << 16u) | (q8(c.a) << 24u); }

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
  if (gid.x >= U.size.x || gid.y >= U.size.y) { return; }
  let k = gid.x + U.size.x * gid.y;
  let t = textureLoad(terrain, vec2<i32>(gid.xy), 0);
  let d = DEC[2u * k];
  let u = DEC[2u * k + 1u].rgb;
  // Lit decals (formats/SPEC.md "Lit decals"): the decal colour times the
  // terrain's shade, the terrain target's alpha, but for the share of the
  // layers drawn unlit.
  let c = (d.rgb - u) * t.a + u + (1.0 - d.a) * t.rgb;
  // The dynamic lines over it, unlit (formats/SPEC.md "Compositing the layers").
  var l = vec4f(0.0);
  if (U.size.z != 0u) { l = DYN[k]; }
  RGBA[k] = pack(vec4f(l.rgb + (1.0 - l.a) * c, 1.0));
  // straight alpha: (C / A, A), 0 where A = 0 (SPEC step 4)
  var s = vec4f(0.0);
  if (d.a > 0.0) { s = vec4f(d.rgb / d.a, d.a); }
  DECALS[k] = pack(s);
}
`;

export const PRESENT_WGSL = /* wgsl */ `
struct C { size: vec4<u32> }
@group(0) @binding(0) var<uniform> U: C;
@group(0) @binding(1) var<storage, read> RGBA: array<u32>;
@vertex
fn vs(@builtin(vertex_index) i: u32) -> @builtin(position) vec4f {
  let p = vec2f(f32((i << 1u) & 2u), f32(i & 2u));
  return vec4f(p * 2.0 - 1.0, 0.0, 1.0);
}
@fragment
fn fs(@builtin(position) pos: vec4f) -> @location(0) vec4f {
  let x = min(u32(pos.x), U.size.x - 1u);
  let y = min(u32(pos.y), U.size.y - 1u);
  return unpack4x8unorm(RGBA[x + U.size.x * y]);
}
`;
