// scene.js — what the renderer uploads from a package (the CPU side of
// formats/gl/src/loader.cpp and GlRenderer::bind_dashes): the v1.3 blobs
// packed into one u32 array (older layouts encoded to v1.3: legacy.js), the
// dynamic-line blobs packed into another (wgsl_dynamic.js), the
// dash table and per-vertex along-line distances (formats/SPEC.md "Dashed
// lines"), the slope-width layer flags (SPEC "Slope widths"), and `--ramp`
// restyling (SPEC "Colour").

import { SLOTS } from "./wgsl_decals.js";
import { DYN_SLOTS } from "./wgsl_dynamic.js";
import { box16Shift, encodeLegacy } from "./legacy.js";


/** The v1.0–1.2 blobs the v1.3 layout replaced (formats/SPEC.md "Compact layout (v1.3)"). */
const LEGACY = ["cell_segment_range", "line_bvh_range", "line_bvh_box", "cell_poly_range", "poly_bvh_range",
                "poly_bvh_box", "cell_polys", "qt_leaf_range", "qt_leaf_segments"];

/** @typedef {[number, Array<[number, number, number, number, number]>]} LayerRamp */

/** A colour (R low byte) as its four channels. @param {number} c */
const channels = (c) => [c & 255, (c >>> 8) & 255, (c >>> 16) & 255, (c >>> 24) & 255];

/** round half away from zero (std::lround) @param {number} x */
const lround = (x) => (x < 0 ? -Math.round(-x) : Math.round(x));

/**
 * ramp(value) of SPEC "Colour" (prep::ramp_rgba): `fallback` for NaN or an
 * empty ramp; stops [value, r, g, b, a] in increasing value order.
 * @param {Array<[number, number, number, number, number]>} stops
 * @param {number} v  the stored f32 value
 * @param {number} fallback
 */
export function rampRgba(stops, v, fallback) {
  if (stops.length === 0 || !Number.isFinite(v)) return fallback;
  const pack = (/** @type {number[]} */ s) => ((s[1] | (s[2] << 8) | (s[3] << 16) | (s[4] << 24)) >>> 0);
  if (v <= stops[0][0]) return pack(stops[0]);
  if (v >= stops[stops.length - 1][0]) return pack(stops[stops.length - 1]);
  let k = 1;
  while (stops[k][0] < v) ++k;
  const a = stops[k - 1], b = stops[k];
  const t = (v - a[0]) / (b[0] - a[0]);
  let out = 0;
  for (let c = 0; c < 4; ++c)
    out |= Math.min(255, Math.max(0, lround(a[c + 1] + t * (b[c + 1] - a[c + 1])))) << (8 * c);
  return out >>> 0;
}

/**
 * The dash table of prep::dash_gpu_words from the metadata layer table.
 * @param {any[]} layers
 */
export function dashWords(layers) {
  /** @type {number[]} */
  const words = [layers.length];
  for (let l = 0; l < layers.length; ++l) words.push(0, 0, 0);
  const f = new Float32Array(1), u = new Uint32Array(f.buffer);
  const bits = (/** @type {number} */ x) => ((f[0] = x), u[0]);
  for (let l = 0; l < layers.length; ++l) {
    const p = layers[l] && Array.isArray(layers[l].dash) ? /** @type {number[]} */ (layers[l].dash) : [];
    let period = 0;
    for (const x of p) period += x;
    words[1 + 3 * l] = words.length;
    words[2 + 3 * l] = p.length;
    words[3 + 3 * l] = bits(period);
    for (const x of p) words.push(bits(x));
  }
  return Uint32Array.from(words);
}

/** @typedef {"auto" | "on" | "off"} SlopeWidths */

/**
 * The layers whose static lines are measured along the terrain (formats/
 * SPEC.md "Slope widths"; prep::slope_layers of render --slope-widths): per
 * layer-table index 1 when its entry has `slope_widths: true`, then a 0 for
 * a layer past the table; empty when no layer asks. "on": every layer
 * ([1]) when the package has static lines; "off": none.
 * @param {any[]} layers @param {SlopeWidths} mode @param {boolean} haveLines
 */
export function slopeLayers(layers, mode, haveLines) {
  if (mode === "off") return new Uint32Array(0);
  if (mode === "on") return haveLines ? Uint32Array.of(1) : new Uint32Array(0);
  return layerFlags(layers, (l) => l.slope_widths === true);
}

/**
 * Per layer-table index 1 where `has` holds for the entry, then a 0 for a
 * layer past the table; empty when it holds for none.
 * @param {any[]} layers @param {(entry: any) => boolean} has
 */
function layerFlags(layers, has) {
  /** @type {number[]} */
  let flags = [];
  layers.forEach((l, i) => {
    if (l && has(l)) {
      if (flags.length === 0) flags = new Array(layers.length + 1).fill(0);
      flags[i] = 1;
    }
  });
  return Uint32Array.from(flags);
}

/**
 * Per layer-table index 1 for a layer drawn unlit (`light: false`, formats/
 * SPEC.md "Lit decals"), then a 0 for a layer past the table; empty when
 * every layer is lit.
 * @param {any[]} layers
 */
export function unlitLayers(layers) {
  return layerFlags(layers, (l) => l.light === false);
}

/**
 * Minimum widths (formats/SPEC.md "Minimum widths"): per layer-table index
 * its min_width_px (0: none), then a 0, as f32 (empty when no layer has
 * one); and the BVH box reach of prep::render::min_width_reach: the largest
 * f N, over sin(limit / 2) for a mitred layer, times 1.01.
 * @param {any[]} layers @param {number} miterLimitDeg
 */
export function minWidths(layers, miterLimitDeg) {
  /** @type {number[]} */
  let n = [];
  let reach = 0;
  const half = (Math.min(Math.max(miterLimitDeg, 1), 180) * Math.PI) / 360;
  layers.forEach((l, i) => {
    if (l && typeof l.min_width_px === "number" && l.min_width_px > 0) {
      if (n.length === 0) n = new Array(layers.length + 1).fill(0);
      n[i] = l.min_width_px;
      const f = (l.outline_mode ?? 0) === 0 ? 0.5 : 1.0;
      const miter = (l.corner ?? 0) === 1;
      reach = Math.max(reach, (l.min_width_px * f) / (miter ? Math.sin(half) : 1));
    }
  });
  return { table: new Uint32Array(Float32Array.from(n).buffer), reach: 1.01 * reach };
}

/**
 * D(v) per static-line vertex (prep::line_vertex_distances), in double,
 * stored as f32 (as the GL renderer binds it).
 * @param {Int32Array} verts @param {Uint32Array} vline @param {number[]} start
 */
export function vertexDistances(verts, vline, start) {
  const n = vline.length;
  const out = new Float32Array(n);
  let prev = 0;
  for (let k = 0; k < n; ++k) {
    if (k === 0 || vline[k] !== vline[k - 1]) {
      const l = vline[k];
      prev = l < start.length ? start[l] : 0;
    } else {
      const dx = (verts[2 * k] - verts[2 * k - 2]) * 0.001;
      const dy = (verts[2 * k + 1] - verts[2 * k - 1]) * 0.001;
      prev += Math.hypot(dx, dy);
    }
    out[k] = prev;
  }
  return out;
}

/**
 * @typedef {{
 *   words: Uint32Array, offsets: Uint32Array,
 *   grid: {gx: number, gy: number, cw: number, ch: number, nx: number, ny: number},
 *   shift: number, haveLines: boolean, havePolygons: boolean, polyBias: number,
 *   layerCount: number, slopeCount: number, unlitCount: number,
 *   minWidthCount: number, minWidthLimit: number, minWidthReach: number,
 *   dynamic: PackedDynamic
 * }} PackedScene
 * The dynamic lines (formats/SPEC.md "Dynamic lines: drawing"): their
 * blobs in one u32 array, each at its word offset (DYN_SLOTS order), the
 * vertex and line counts, the entries of the min_width_m table, the
 * package's miter limit (build_options.miter_limit_deg, default 40) and
 * whether a dynamic line's layer has a dash pattern.
 * @typedef {{words: Uint32Array, offsets: Uint32Array, vertices: number, lines: number,
 *            minWidthCount: number, miterLimitDeg: number, dashed: boolean}} PackedDynamic
 */

/**
 * Minimum widths of dynamic lines (formats/SPEC.md "Minimum widths"): per
 * layer-table index its min_width_m in metres (0: none), then a 0, as f32
 * (prep::render::DecalSource min_width_m); empty when no layer has one.
 * @param {any[]} layers
 */
export function minWidthsMetres(layers) {
  /** @type {number[]} */
  let m = [];
  layers.forEach((l, i) => {
    if (l && typeof l.min_width_m === "number") {
      if (m.length === 0) m = new Array(layers.length + 1).fill(0);
      m[i] = l.min_width_m;
    }
  });
  return new Uint32Array(Float32Array.from(m).buffer);
}

/**
 * Packs the dynamic-line blobs: dyn_vertices, dyn_prev_next,
 * dyn_line_start, dyn_line_props (restyled by `byLayer` as the static
 * lines are, SPEC "Colour"), the min_width_m table and the dash table.
 * @param {import("../package.js").Package} pkg @param {any[]} layers
 * @param {Map<number, Array<[number, number, number, number, number]>>} byLayer
 * @returns {Promise<PackedDynamic>}
 */
async function packDynamic(pkg, layers, byLayer) {
  const miterLimitDeg = pkg.metadata.build_options?.miter_limit_deg ?? 40;
  /** @type {Map<string, Uint32Array>} */
  const arrays = new Map();
  for (const name of DYN_SLOTS) {
    if (name === "dyn_min_widths" || name === "dash_table") continue;
    const copy = (await pkg.bytes(name)).slice();
    arrays.set(name, new Uint32Array(copy.buffer, 0, copy.byteLength >>> 2));
  }
  const props = /** @type {Uint32Array} */ (arrays.get("dyn_line_props"));
  if (byLayer.size > 0) {
    const pf = new Float32Array(props.buffer, props.byteOffset, props.length);
    for (let i = 0; i < props.length; i += 8) {
      const stops = byLayer.get(props[i + 5]);
      if (stops) props[i + 1] = rampRgba(stops, pf[i + 4], props[i + 1]);
    }
  }
  const widths = minWidthsMetres(layers);
  arrays.set("dyn_min_widths", widths);
  const dashes = dashWords(layers);
  arrays.set("dash_table", dashes);
  let dashed = false;
  for (let i = 5; i < props.length && !dashed; i += 8)
    dashed = props[i] < layers.length && dashes[2 + 3 * props[i]] !== 0;
  let total = 0;
  for (const a of arrays.values()) total += a.length;
  const words = new Uint32Array(Math.max(4, total));
  const offsets = new Uint32Array(DYN_SLOTS.length);
  let at = 0;
  DYN_SLOTS.forEach((name, k) => {
    const a = /** @type {Uint32Array} */ (arrays.get(name));
    offsets[k] = at;
    words.set(a, at);
    at += a.length;
  });
  const vertices = (/** @type {Uint32Array} */ (arrays.get("dyn_vertices"))).length >>> 2;
  const lines = (/** @type {Uint32Array} */ (arrays.get("dyn_line_start"))).length;
  return { words, offsets, vertices, lines: props.length >>> 3 === lines ? lines : 0,
           minWidthCount: widths.length, miterLimitDeg, dashed };
}

/**
 * Reads the package's static blobs and packs them for the decal pass.
 * @param {import("../package.js").Package} pkg
 * @param {LayerRamp[]} ramps
 * @param {SlopeWidths} [slopeWidths]
 * @returns {Promise<PackedScene>}
 */
export async function packScene(pkg, ramps, slopeWidths = "auto") {
  const meta = pkg.metadata;
  const g = meta.grid || { origin: [0, 0], cell: [1, 1], dims: [0, 0] };
  const grid = { gx: g.origin[0], gy: g.origin[1], cw: g.cell[0], ch: g.cell[1], nx: g.dims[0], ny: g.dims[1] };
  const cells = grid.nx * grid.ny;
  const layers = Array.isArray(meta.layers) ? meta.layers : [];
  const count = (/** @type {string} */ name) => pkg.entry(name)?.count ?? 0;
  /** @type {Map<string, Uint32Array>} */
  const arrays = new Map();
  const read = async (/** @type {string} */ name) => {
    const copy = (await pkg.bytes(name)).slice();
    return new Uint32Array(copy.buffer, 0, copy.byteLength >>> 2);
  };
  for (const name of SLOTS) {
    if (name === "dash_table" || name === "dash_vertex" || name === "slope_layers" ||
        name === "unlit_layers" || name === "min_widths") continue;
    arrays.set(name, await read(name));
  }
  // Older layouts (v1.0–1.2) encoded to v1.3 on upload, as the GL loader does.
  /** @type {Map<string, Uint32Array>} */
  const legacy = new Map();
  for (const name of LEGACY) if (count(name) > 0) legacy.set(name, await read(name));
  if (legacy.size > 0) {
    const original = new Map(arrays);
    const blob = (/** @type {string} */ name) => legacy.get(name) ?? original.get(name) ?? new Uint32Array(0);
    encodeLegacy(blob, arrays, grid, pkg.label);
  }
  // --ramp restyling (SPEC "Colour"): line and exterior polygon colours.
  /** @type {Map<number, Array<[number, number, number, number, number]>>} */
  const byLayer = new Map();
  for (const [layer, stops] of ramps) byLayer.set(layer, stops);
  if (byLayer.size > 0) {
    const lp = /** @type {Uint32Array} */ (arrays.get("line_props"));
    const lpf = new Float32Array(lp.buffer, lp.byteOffset, lp.length);
    for (let i = 0; i < lp.length; i += 8) {
      const stops = byLayer.get(lp[i + 5]);
      if (stops) lp[i + 1] = rampRgba(stops, lpf[i + 4], lp[i + 1]);
    }
    const pp = /** @type {Uint32Array} */ (arrays.get("poly_props"));
    const ppf = new Float32Array(pp.buffer, pp.byteOffset, pp.length);
    const ppi = new Int32Array(pp.buffer, pp.byteOffset, pp.length);
    for (let i = 0; i < pp.length; i += 8) {
      if (ppi[i + 2] >= 0) continue;  // interior polygons are drawn by their exterior
      const stops = byLayer.get(pp[i + 4]);
      if (stops) pp[i] = rampRgba(stops, ppf[i + 3], pp[i]);
    }
  }
  arrays.set("dash_table", dashWords(layers));
  const slope = slopeLayers(layers, slopeWidths, count("line_props") > 0);
  arrays.set("slope_layers", slope);
  const unlit = unlitLayers(layers);
  arrays.set("unlit_layers", unlit);
  const limit = typeof meta.min_width_pixel_m === "number" ? meta.min_width_pixel_m : 0;
  const miterLimit = meta.build_options?.miter_limit_deg ?? 40;
  const widths = limit > 0 ? minWidths(layers, miterLimit) : { table: new Uint32Array(0), reach: 0 };
  arrays.set("min_widths", widths.table);
  const lv = /** @type {Uint32Array} */ (arrays.get("line_vertices"));
  const start = Array.isArray(meta.line_dash_start) ? meta.line_dash_start.map(Number) : [];
  const dist = vertexDistances(new Int32Array(lv.buffer, lv.byteOffset, lv.length),
                               /** @type {Uint32Array} */ (arrays.get("line_vertex_line")), start);
  arrays.set("dash_vertex", new Uint32Array(dist.buffer));
  let total = 0;
  for (const a of arrays.values()) total += a.length;
  const words = new Uint32Array(Math.max(4, total));
  const offsets = new Uint32Array(SLOTS.length);
  let at = 0;
  SLOTS.forEach((name, k) => {
    const a = /** @type {Uint32Array} */ (arrays.get(name));
    offsets[k] = at;
    words.set(a, at);
    at += a.length;
  });
  return {
    words, offsets, grid,
    shift: box16Shift(grid.cw, grid.ch),
    haveLines: cells > 0 && (arrays.get("cell_line_first")?.length ?? 0) === 2 * (cells + 1),
    havePolygons: cells > 0 && (arrays.get("cell_poly_first")?.length ?? 0) === 2 * (cells + 1),
    polyBias: pkg.major === 1 && pkg.minor < 2 ? count("line_props") : 0,
    layerCount: layers.length,
    slopeCount: slope.length,
    unlitCount: unlit.length,
    minWidthCount: widths.table.length,
    minWidthLimit: widths.table.length > 0 ? limit : 0,
    minWidthReach: widths.reach,
    dynamic: await packDynamic(pkg, layers, byLayer),
  };
}

/**
 * A scene with no decals: the frame a tileset's terrain pass is drawn in
 * (index.js, a tileset scene), before any tile has arrived.
 * @returns {PackedScene}
 */
export function emptyScene() {
  return {
    words: new Uint32Array(4), offsets: new Uint32Array(SLOTS.length),
    grid: { gx: 0, gy: 0, cw: 1, ch: 1, nx: 0, ny: 0 },
    shift: 0, haveLines: false, havePolygons: false, polyBias: 0, layerCount: 0, slopeCount: 0,
    unlitCount: 0, minWidthCount: 0, minWidthLimit: 0, minWidthReach: 0,
    dynamic: { words: new Uint32Array(4), offsets: new Uint32Array(DYN_SLOTS.length), vertices: 0, lines: 0,
      minWidthCount: 0, miterLimitDeg: 40, dashed: false },
  };
}
