// render/index.js — the WebGPU renderer of one decal package over a terrain
// (the interface of the browser renderer, §2): the terrain pass
// (libprep/render/gl_passes.cpp terrain_pass), the static decal query at
// each pixel's ground point (formats/SPEC.md "Drawing rules"; the pixel
// centre exactly for a top-down view; slope widths from the gradient of the
// terrain triangle under it), the dynamic lines (libprep/render/
// gl_dynamic.cpp: update, per-pixel lists, ordered composite;
// wgsl_dynamic.js; LOD lines from the LOD segments the view selects,
// render --lod on at 0.5 pixels) and the composite. Frames are
// shown on the canvas through its WebGPU context, or,
// where that fails (headless Chromium), read back into its 2D context
// (presentPath).
//
// WebGPU objects are typed `any`: the checked lib (es2022 + dom) has no
// WebGPU declarations and the project adds no type packages.

import { DECALS_WGSL, FRAME_BYTES, SLOTS } from "./wgsl_decals.js";
import { TERRAIN_WGSL, TERRAIN_UNIFORM_BYTES, COMPOSITE_WGSL, PRESENT_WGSL } from "./wgsl_frame.js";
import { frameUniforms, terrainMesh, tileFrames } from "./frame.js";
import { DYN_UPDATE_WGSL, DYN_LISTS_WGSL, DYN_COMPOSITE_WGSL, DYN_LOD_WGSL, DYN_UNIFORM_BYTES, DYN_COUNTER_WORDS } from "./wgsl_dynamic.js";
import { LodSelector, lodDrawMap, lodUniform, lodView } from "./lod.js";
import { topdownCamera } from "./camera.js";
import { emptyScene, packScene } from "./scene.js";
import { createWebGL2Renderer, WebGL2Renderer } from "./webgl2.js";

export { topdownCamera };

/** @typedef {import("./camera.js").Camera} Camera */
/** @typedef {{x0: number, y0: number, dx: number, dy: number, nx: number, ny: number,
 *             z: Float64Array, zmin: number, zmax: number}} Terrain */

// GPUBufferUsage / GPUTextureUsage / GPUMapMode bits (WebGPU spec).
const BU = { MAP_READ: 1, COPY_SRC: 4, COPY_DST: 8, INDEX: 16, VERTEX: 32, UNIFORM: 64, STORAGE: 128, INDIRECT: 256,
             QUERY_RESOLVE: 512 };
const TU = { COPY_SRC: 1, TEXTURE_BINDING: 4, RENDER_ATTACHMENT: 16 };
const MAP_READ = 1;
/** Bytes between the frames of a frame's decal dispatches in the frame uniform buffer (a multiple of 256). */
const FRAME_STRIDE = 512;
/** Frames a tileset's tile stays on the GPU without being drawn. */
const KEEP_FRAMES = 30;

/**
 * The flat heightfield render uses without a DEM (terrain.cpp flat_heightfield).
 * @param {number[]} extent [xmin, ymin, xmax, ymax] metres relative to the origin
 * @returns {Terrain}
 */
export function flatTerrain(extent) {
  return {
    x0: extent[0], y0: extent[1], dx: extent[2] - extent[0], dy: extent[3] - extent[1],
    nx: 2, ny: 2, z: new Float64Array(4), zmin: 0, zmax: 0,
  };
}

/** @typedef {"auto" | "webgpu" | "webgl2"} Backend */

/**
 * Creates a renderer. backend: "webgpu" (the default) throws an Error
 * saying what is missing when navigator.gpu or an adapter is absent;
 * "webgl2" is the WebGL2 renderer of static decals (webgl2.js), which
 * throws when WebGL2 is absent; "auto" tries WebGPU, then WebGL2, and
 * throws with both reasons when neither opens. Both renderers have the
 * same interface; `backend` says which one it is.
 * @param {{canvas?: HTMLCanvasElement, backend?: Backend}} [options]
 * @returns {Promise<Renderer | WebGL2Renderer>}
 */
export async function createRenderer(options = {}) {
  const backend = options.backend ?? "webgpu";
  if (backend === "webgl2") return createWebGL2Renderer(options);
  if (backend !== "auto") return createWebGPURenderer(options);
  try {
    return await createWebGPURenderer(options);
  } catch (e) {
    try {
      return createWebGL2Renderer(options);
    } catch (e2) {
      const why = (/** @type {unknown} */ x) => (x instanceof Error ? x.message : String(x));
      throw new Error(`no renderer: ${why(e)}; ${why(e2)}`);
    }
  }
}

/**
 * The WebGPU renderer; throws an Error saying what is missing when
 * navigator.gpu or an adapter is absent.
 * @param {{canvas?: HTMLCanvasElement}} [options]
 */
async function createWebGPURenderer(options = {}) {
  const gpu = /** @type {any} */ (globalThis.navigator)?.gpu;
  if (!gpu) throw new Error("WebGPU is not available: navigator.gpu is missing (a secure origin and a WebGPU-enabled browser are needed)");
  const { device, name } = await openDevice(gpu);
  return new Renderer(device, name, options.canvas ?? null, gpu);
}

/** @param {number} ms */
const sleep = (ms) => new Promise((resolve) => setTimeout(resolve, ms));

/**
 * An adapter's device with the limits the passes need, and its name.
 * tries: requestAdapter calls 250 ms apart while it returns none or throws
 * (after a device loss, until the browser's GPU process is back).
 * @param {any} gpu @param {number} [tries]
 */
async function openDevice(gpu, tries = 1) {
  let adapter = null;
  for (let k = 0; k < tries && !adapter; ++k) {
    if (k > 0) await sleep(250);
    try {
      adapter = await gpu.requestAdapter();
    } catch (e) {
      if (k + 1 === tries) throw e;
    }
  }
  if (!adapter) throw new Error("WebGPU is not available: navigator.gpu.requestAdapter() returned no adapter");
  const lim = adapter.limits;
  // Per-pass GPU times (renderFrame's passTimes) where the adapter has them.
  const features = adapter.features?.has("timestamp-query") ? ["timestamp-query"] : [];
  const device = await adapter.requestDevice({
    requiredFeatures: features,
    requiredLimits: {
      maxStorageBuffersPerShaderStage: Math.min(10, lim.maxStorageBuffersPerShaderStage),
      maxStorageBufferBindingSize: lim.maxStorageBufferBindingSize,
      maxBufferSize: lim.maxBufferSize,
    },
  });
  const info = adapter.info || {};
  const name = `WebGPU ${info.vendor || "unknown"}/${info.architecture || info.device || info.description || "unknown"}`;
  return { device, name };
}

/**
 * Per terrain triangle, the gradient (dh/dx, dh/dy) of
 * Heightfield::triangle_gradient in double, stored as f32: cell (i, j) at
 * 2 (i + (nx - 1) j), the lower triangle (00, 10, 11) then the upper
 * (00, 11, 01).
 * @param {Terrain} t
 */
export function triangleGradients(t) {
  const { nx, ny, z } = t;
  const out = new Float32Array(Math.max(4, 4 * (nx - 1) * (ny - 1)));
  for (let j = 0; j + 1 < ny; ++j)
    for (let i = 0; i + 1 < nx; ++i) {
      const z00 = z[i + nx * j], z10 = z[i + 1 + nx * j], z01 = z[i + nx * (j + 1)], z11 = z[i + 1 + nx * (j + 1)];
      const k = 4 * (i + (nx - 1) * j);
      out[k] = (z10 - z00) / t.dx;
      out[k + 1] = (z11 - z10) / t.dy;
      out[k + 2] = (z11 - z01) / t.dx;
      out[k + 3] = (z01 - z00) / t.dy;
    }
  return out;
}

/**
 * A package's LOD lines as the LOD passes read them (wgsl_dynamic.js
 * DYN_LOD_WGSL): lod_points, lod_segments, the draw map (lod.js lodDrawMap:
 * vertex and end link per point) and the dynamic lines' flags in one word
 * buffer, at `offsets`.
 * @typedef {{words: Uint32Array, points: number, segments: number, offsets: number[], lines: number}} LodData
 */

/**
 * A package's dynamic lines on the device (Renderer.makeDynSet): the packed
 * blobs (scene.js packDynamic) in `buffer`, the update's per-vertex buffers
 * in `work` (work.lod: the LOD passes' buffers), its LOD data.
 * @typedef {{ds: import("./scene.js").PackedDynamic, buffer: any, lod: LodData | null, work: any}} DynSet
 * One draw of a set's dynamic lines in a frame: its frame's uniforms
 * (frameUniforms), its camera (in the set's frame, for the LOD view) and,
 * for a tileset's tile, the square it draws in (metres in the frame's
 * coordinates) and the offset from the frame's ground points (relative to
 * the index anchor) to the tile's anchor (metres).
 * @typedef {{set: DynSet, u: ReturnType<typeof frameUniforms>, camera: Camera, clip: number[] | null,
 *            go: number[]}} DynDraw
 */

/**
 * The LOD data of a package with LOD lines that map onto its dynamic lines,
 * else null (its lines are then drawn from their full vertex chains).
 * @param {import("../package.js").Package} pkg
 * @returns {Promise<LodData | null>}
 */
async function packLod(pkg) {
  const blobs = await LodSelector.blobsOf(pkg);
  if (!blobs) return null;
  const view = async (/** @type {string} */ n) => {
    const a = /** @type {ArrayBufferView} */ (await pkg.array(n));
    return new Uint32Array(a.buffer, a.byteOffset, a.byteLength / 4);
  };
  const signed = (/** @type {Uint32Array} */ u) => new Int32Array(u.buffer, u.byteOffset, u.length);
  const map = lodDrawMap(blobs.points, blobs.segments, await view("lod_line_range"),
    signed(await view("dyn_vertices")), await view("dyn_line_start"), signed(await view("dyn_prev_next")));
  if (map.lines === 0) return null;
  const np = blobs.points.length / 8, ns = blobs.segments.length / 4;
  const offsets = [0, blobs.points.length, blobs.points.length + blobs.segments.length,
    blobs.points.length + blobs.segments.length + 2 * np];
  const words = new Uint32Array(offsets[3] + map.lineDrawn.length);
  words.set(blobs.points, offsets[0]);
  words.set(blobs.segments, offsets[1]);
  for (let p = 0; p < np; ++p) {
    words[offsets[2] + 2 * p] = map.vertex[p];
    words[offsets[2] + 2 * p + 1] = map.end[p];
  }
  words.set(map.lineDrawn, offsets[3]);
  return { words, points: np, segments: ns, offsets, lines: map.lines };
}


/**
 * A tile of a tileset scene (setTileScene) to draw in a frame: a key that
 * names it while it stays on the GPU, its package, its origin's offset
 * from the tileset frame origin (metres, whole quanta: SPEC "Tilesets"),
 * its own square and the squares it draws in (metres relative to the
 * tileset frame origin; its own square, or those of the finer tiles it
 * stands in for).
 * @typedef {{key: string, pkg: import("../package.js").Package, dx: number, dy: number,
 *            square?: number[], clips: number[][]}} FrameTile
 * @typedef {{camera: Camera, width: number, height: number, albedo?: number[],
 *            decals?: boolean, present?: boolean, readback?: boolean,
 *            pick?: number[] | null, passTimes?: boolean, tiles?: FrameTile[]}} FrameArgs
 * A picked decal: its kind, its layer (index into the metadata layer
 * table), its source feature id (LineProps/PolyProps `feature`) and its
 * index in line_props or poly_props.
 * In a tileset scene, `tile` is the key of the tile that drew it.
 * @typedef {{kind: "line" | "polygon", layer: number, feature: number, index: number,
 *            tile?: string}} Pick
 * Each pass's time in ms: GPU timestamps ("timestamp"), or the wall time of
 * the pass submitted and awaited alone ("wall", which adds the submission's
 * own cost and serialises the frame).
 * dynamic: the dynamic-line passes together (update, lists, composite of
 * the lines; 0 without dynamic lines).
 * @typedef {{timing: "timestamp" | "wall", terrain: number, decals: number, dynamic: number,
 *            composite: number}} PassTimes
 * The dynamic-line pass's counts (render --stats prints GL's): vertices
 * kept, segments drawn, list nodes asked for, regrowths of the node buffer.
 * @typedef {{kept: number, segments: number, nodes: number, grows: number}} DynamicStats
 * uploads: the tileset tiles the frame put on the GPU (their packing and
 * upload are in its ms).
 * @typedef {{rgba: Uint8Array | null, decals: Uint8Array | null, ms: number,
 *            pick: Pick | null, passes: PassTimes | null, dynamic: DynamicStats | null,
 *            uploads: number}} FrameResult
 */

export class Renderer {
  /** @param {any} device @param {string} name @param {HTMLCanvasElement | null} canvas @param {any} gpu */
  constructor(device, name, canvas, gpu) {
    this.adapterName = name;
    /** Which renderer this is, and what it leaves out (the viewer's overlay says). */
    this.backend = "webgpu";
    this.limits = "";
    this.gpuBytes = 0;
    this.canvas = canvas;
    this.gpu = gpu;
    /** @type {any} */ this.context = null;
    /** @type {import("./scene.js").PackedScene | null} */ this.scene = null;
    /**
     * A tileset scene (setTileScene): the restyling every tile takes and
     * the tiles on the GPU by key (their packed scene and blob buffer),
     * kept while frames draw them.
     * @type {{ramps: import("./scene.js").LayerRamp[], slopeWidths: import("./scene.js").SlopeWidths,
     *         uploads: Map<string, {scene: import("./scene.js").PackedScene, blob: any, dyn: DynSet | null,
     *                               used: number}>} | null}
     */
    this.tileset = null;
    /** @type {Terrain | null} */ this.terrain = null;
    /** @type {any} */ this.blobBuffer = null;
    /** @type {any} */ this.visBuffer = null;
    /** @type {any} */ this.heights = null;
    /** @type {any} */ this.gradients = null;
    /** @type {Uint32Array} */ this.visBits = new Uint32Array(1);
    /** @type {any} */ this.mesh = null;
    /** @type {any} */ this.targets = null;
    /** @type {any} */ this.stamps = null;
    /** @type {DynSet | null} */ this.dynSet = null;  // the package's dynamic lines on the device
    /** @type {any} */ this.dynTargets = null; // the per-pixel lists and the dynamic layer, per size
    /**
     * How present: true shows frames: null until the first such frame,
     * "webgpu" (the canvas's WebGPU context), "2d" (read back and put into
     * the canvas's 2D context: where the WebGPU context cannot be
     * configured or presenting fails, e.g. headless Chromium with
     * SwiftShader, whose GPU process has no swap-chain image backing), or
     * "none" (the canvas took a WebGPU context that then failed: frames are
     * still drawn and read back, not shown). presentError says why.
     * @type {"webgpu" | "2d" | "none" | null}
     */
    this.presentPath = null;
    /** @type {string} */ this.presentError = "";
    /** @type {any} */ this.context2d = null;
    this.destroyed = false;
    /** @type {Promise<unknown>} the frame drawing now (renderFrame) */
    this.frameChain = Promise.resolve();
    /** Frames drawn: a tileset's tiles stay on the GPU until KEEP_FRAMES frames have not drawn them. */
    this.frameCount = 0;
    this.initDevice(device);
  }

  /**
   * Pipelines and uniforms on a device (again after a device loss).
   * @param {any} device
   */
  initDevice(device) {
    this.device = device;
    this.lost = false;
    this.lostMessage = "";
    device.lost.then((/** @type {any} */ info) => {
      if (this.device !== device || this.destroyed) return;
      this.lost = true;
      this.lostMessage = String(info?.message ?? "");
    });
    const d = device;
    const mod = (/** @type {string} */ code) => d.createShaderModule({ code });
    this.decalPipeline = d.createComputePipeline({ layout: "auto", compute: { module: mod(DECALS_WGSL), entryPoint: "main" } });
    this.compositePipeline = d.createComputePipeline({ layout: "auto", compute: { module: mod(COMPOSITE_WGSL), entryPoint: "main" } });
    const tm = mod(TERRAIN_WGSL);
    this.terrainPipeline = d.createRenderPipeline({
      layout: "auto",
      vertex: {
        module: tm, entryPoint: "vs",
        buffers: [{ arrayStride: 24, attributes: [
          { shaderLocation: 0, offset: 0, format: "float32x3" },
          { shaderLocation: 1, offset: 12, format: "float32x3" }] }],
      },
      fragment: { module: tm, entryPoint: "fs", targets: [{ format: "rgba8unorm" }] },
      primitive: { topology: "triangle-list", cullMode: "none" },
      depthStencil: { format: "depth32float", depthWriteEnabled: true, depthCompare: "greater" },
    });
    // One frame per decal dispatch (a tileset's frame has one per tile square), FRAME_STRIDE apart.
    this.frameSlots = 1;
    this.frameUniform = d.createBuffer({ size: FRAME_STRIDE, usage: BU.UNIFORM | BU.COPY_DST });
    this.terrainUniform = d.createBuffer({ size: TERRAIN_UNIFORM_BYTES, usage: BU.UNIFORM | BU.COPY_DST });
    this.sizeUniform = d.createBuffer({ size: 16, usage: BU.UNIFORM | BU.COPY_DST });
    this.dynUniform = d.createBuffer({ size: DYN_UNIFORM_BYTES, usage: BU.UNIFORM | BU.COPY_DST });
    // The stand-in for the ground-point and dynamic-layer bindings of a frame without dynamic lines.
    this.standIn = d.createBuffer({ size: 16, usage: BU.STORAGE });
    /** @type {any} */ this.presentPipeline = null;
    /** @type {any} */ this.dynPipes = null;
    /** @type {LodData | null} */ this.lod = null;
  }

  /** The timestamp query set of passTimes (four passes), made once per device. */
  timestampSet() {
    if (!this.stamps || this.stamps.device !== this.device) {
      const d = this.device;
      this.stamps = { device: d, set: d.createQuerySet({ type: "timestamp", count: 8 }),
        resolve: d.createBuffer({ size: 64, usage: BU.QUERY_RESOLVE | BU.COPY_SRC }),
        read: d.createBuffer({ size: 64, usage: BU.MAP_READ | BU.COPY_DST }) };
    }
    return this.stamps;
  }

  /**
   * The dynamic-line pipelines (wgsl_dynamic.js), made on the first frame
   * with dynamic lines: the update's eight entry points share one explicit
   * layout (one bind group for all). Throws the device's message when one
   * fails to compile or validate.
   */
  async dynamicPipelines() {
    if (this.dynPipes) return this.dynPipes;
    const d = this.device;
    d.pushErrorScope("validation");
    const storage = (/** @type {number} */ binding, /** @type {string} */ type) =>
      ({ binding, visibility: 4 /* COMPUTE */, buffer: { type } });
    const layout = d.createBindGroupLayout({ entries: [
      storage(0, "uniform"), storage(1, "read-only-storage"),
      ...[2, 3, 4, 5, 6, 7, 8].map((b) => storage(b, "storage"))] });
    const um = d.createShaderModule({ code: DYN_UPDATE_WGSL });
    const pl = d.createPipelineLayout({ bindGroupLayouts: [layout] });
    const update = Object.fromEntries(["cull", "scan_local", "scan_blocks", "scatter", "segments", "dash_local",
      "dash_blocks", "dash_apply"].map((entryPoint) =>
      [entryPoint, d.createComputePipeline({ layout: pl, compute: { module: um, entryPoint } })]));
    const lm = d.createShaderModule({ code: DYN_LISTS_WGSL });
    const lists = d.createRenderPipeline({
      layout: "auto",
      vertex: { module: lm, entryPoint: "vs" },
      // No colour is written: the fragments only push onto the lists.
      fragment: { module: lm, entryPoint: "fs", targets: [{ format: "rgba8unorm", writeMask: 0 }] },
      primitive: { topology: "triangle-list", cullMode: "none" },
    });
    const composite = d.createComputePipeline({ layout: "auto",
      compute: { module: d.createShaderModule({ code: DYN_COMPOSITE_WGSL }), entryPoint: "main" } });
    // The LOD passes (wgsl_dynamic.js DYN_LOD_WGSL): one layout for the three.
    const lodLayout = d.createBindGroupLayout({ entries: [
      storage(0, "uniform"), storage(1, "read-only-storage"), ...[2, 3, 4, 5].map((b) => storage(b, "storage")),
      storage(6, "read-only-storage"), storage(7, "storage"), storage(8, "uniform")] });
    const lodModule = d.createShaderModule({ code: DYN_LOD_WGSL });
    const lodPl = d.createPipelineLayout({ bindGroupLayouts: [lodLayout] });
    const lod = Object.fromEntries(["lod_mask", "lod_select", "lod_segments"].map((entryPoint) =>
      [entryPoint, d.createComputePipeline({ layout: lodPl, compute: { module: lodModule, entryPoint } })]));
    const err = await d.popErrorScope();
    if (err) throw new Error(`the dynamic-line pipelines: ${err.message}`);
    this.dynPipes = { layout, update, lists, composite, lodLayout, lod };
    return this.dynPipes;
  }

  /** @param {number} size @param {number} usage */
  buffer(size, usage) {
    const b = this.device.createBuffer({ size: Math.max(16, Math.ceil(size / 4) * 4), usage });
    this.gpuBytes += b.size;
    return b;
  }
  /** @param {any} b */
  free(b) {
    if (!b) return;
    this.gpuBytes -= b.size;
    b.destroy();
  }

  /**
   * Uploads a validated Package and its terrain (or null: flat over the
   * package extent). ramps: render --ramp's stops per layer (SPEC "Colour").
   * slopeWidths: as render --slope-widths (default "auto": the layers whose
   * metadata entry has slope_widths: true measure their static line widths
   * along the terrain; SPEC "Slope widths").
   * @param {{pkg: import("../package.js").Package, terrain: Terrain | null,
   *          ramps?: import("./scene.js").LayerRamp[],
   *          slopeWidths?: import("./scene.js").SlopeWidths}} args
   */
  async setScene({ pkg, terrain, ramps, slopeWidths }) {
    const scene = await packScene(pkg, ramps ?? [], slopeWidths ?? "auto");
    this.freeTiles();
    this.tileset = null;
    this.scene = scene;
    this.lod = scene.dynamic.vertices > 0 ? await packLod(pkg) : null;
    this.visBits = new Uint32Array(Math.max(1, Math.ceil(scene.layerCount / 32))).fill(0xffffffff);
    const ext = pkg.metadata.extent || [0, 0, 1, 1];
    this.terrain = terrain ?? flatTerrain(ext);
    this.uploadScene();
  }

  /**
   * A tileset scene: the terrain (tileset.terrain's mesh, in the tileset's
   * frame; null: flat over `extent`) and the restyling of every tile, which
   * each frame then names (FrameArgs tiles: what a TileCache draw list
   * holds). layerCount: the layer table's length (visibility bits).
   * Each tile draws its static decals and its dynamic lines (LOD lines
   * too) in its squares, as `render` draws a tileset in one frame.
   * @param {{terrain: Terrain | null, extent: number[], layerCount: number,
   *          ramps?: import("./scene.js").LayerRamp[],
   *          slopeWidths?: import("./scene.js").SlopeWidths}} args
   */
  async setTileScene({ terrain, extent, layerCount, ramps, slopeWidths }) {
    this.freeTiles();
    this.tileset = { ramps: ramps ?? [], slopeWidths: slopeWidths ?? "auto", uploads: new Map() };
    this.scene = emptyScene();
    this.lod = null;
    this.visBits = new Uint32Array(Math.max(1, Math.ceil(layerCount / 32))).fill(0xffffffff);
    this.terrain = terrain ?? flatTerrain(extent);
    this.uploadScene();
  }

  /** The tiles of a tileset scene on the device, freed. */
  freeTiles() {
    if (!this.tileset) return;
    for (const u of this.tileset.uploads.values()) {
      this.free(u.blob);
      this.freeDynSet(u.dyn);
    }
    this.tileset.uploads.clear();
  }

  /**
   * The packed scene and blob buffer of a tile of a tileset scene, uploaded
   * when it is not on the device yet.
   * @param {FrameTile} t
   */
  async tileUpload(t) {
    const ts = /** @type {NonNullable<Renderer["tileset"]>} */ (this.tileset);
    const have = ts.uploads.get(t.key);
    if (have) return have;
    const scene = await packScene(t.pkg, ts.ramps, ts.slopeWidths);
    const blob = this.buffer(scene.words.byteLength, BU.STORAGE | BU.COPY_DST);
    this.device.queue.writeBuffer(blob, 0, scene.words);
    const lod = scene.dynamic.vertices > 0 ? await packLod(t.pkg) : null;
    /** @type {DynSet | null} */
    let dyn = null;
    try {
      dyn = this.makeDynSet(scene.dynamic, lod, `tile ${t.key}`);
    } catch (e) {
      this.free(blob);
      throw e;
    }
    const u = { scene, blob, dyn, used: this.frameCount };
    ts.uploads.set(t.key, u);
    return u;
  }

  /** The scene's buffers on the device, from what setScene (or setTileScene) kept. */
  uploadScene() {
    const scene = /** @type {import("./scene.js").PackedScene} */ (this.scene);
    this.free(this.blobBuffer);
    this.free(this.visBuffer);
    this.blobBuffer = this.buffer(scene.words.byteLength, BU.STORAGE | BU.COPY_DST);
    this.device.queue.writeBuffer(this.blobBuffer, 0, scene.words);
    this.visBuffer = this.buffer(this.visBits.byteLength, BU.STORAGE | BU.COPY_DST);
    this.device.queue.writeBuffer(this.visBuffer, 0, this.visBits);
    const terrain = /** @type {Terrain} */ (this.terrain);
    this.freeMesh();
    this.free(this.heights);
    this.heights = this.buffer(4 * terrain.z.length, BU.STORAGE | BU.COPY_DST);
    this.device.queue.writeBuffer(this.heights, 0, Float32Array.from(terrain.z));
    // The triangles' gradients: read only for slope widths (F.tn.z, the
    // slope layers' count, not 0); a placeholder otherwise. A tileset's
    // tiles may have slope layers: there they are always made.
    const grad = scene.slopeCount > 0 || this.tileset ? triangleGradients(terrain) : new Float32Array(4);
    this.free(this.gradients);
    this.gradients = this.buffer(grad.byteLength, BU.STORAGE | BU.COPY_DST);
    this.device.queue.writeBuffer(this.gradients, 0, grad);
    this.freeDynamic();
    this.dynSet = this.makeDynSet(scene.dynamic, this.lod ?? null, "setScene");
  }

  /**
   * A package's dynamic lines on the device (as gl_dynamic.cpp
   * DynamicLines::make_buffers): the packed blobs and the update's buffers,
   * n vertices in B blocks; with LOD lines, the LOD words, the links and
   * the selection, the uniform. null without dynamic lines.
   * @param {import("./scene.js").PackedDynamic} dyn @param {LodData | null} lod @param {string} what
   * @returns {DynSet | null}
   */
  makeDynSet(dyn, lod, what) {
    if (!(dyn.vertices > 0 && dyn.lines > 0)) return null;
    const n = dyn.vertices, blocks = Math.ceil(n / 256);
    if (blocks > 65535) throw new Error(`${what}: ${n} dynamic vertices, more than the 65535 workgroups of 256 one dispatch reaches`);
    const buffer = this.buffer(dyn.words.byteLength, BU.STORAGE | BU.COPY_DST);
    this.device.queue.writeBuffer(buffer, 0, dyn.words);
    const rw = BU.STORAGE;
    /** @type {DynSet} */
    const set = { ds: dyn, buffer, lod, work: {
      flags: this.buffer(4 * n, rw), scan: this.buffer(4 * n, rw), blocks: this.buffer(4 * blocks, rw),
      compact: this.buffer(4 * n, rw), segments: this.buffer(16 * n, rw),
      // dyn_dash's distances and carries (wgsl_dynamic.js DASH) where a line is dashed
      dash: this.buffer(dyn.dashed ? 4 * (4 * n + 3 * blocks) : 16, rw),
      counters: this.buffer(4 * DYN_COUNTER_WORDS, rw | BU.COPY_DST | BU.COPY_SRC),
      indirect: this.buffer(16, BU.INDIRECT | BU.COPY_DST),
      readCounters: this.buffer(4 * DYN_COUNTER_WORDS, BU.MAP_READ | BU.COPY_DST),
      groups: blocks,
      lod: null,
    } };
    if (lod) {
      const words = this.buffer(lod.words.byteLength, BU.STORAGE | BU.COPY_DST);
      this.device.queue.writeBuffer(words, 0, lod.words);
      const reset = new Uint32Array(2 * lod.points + 4).fill(0xffffffff);
      reset.fill(0, 2 * lod.points);
      set.work.lod = { words, reset,
        state: this.buffer(4 * (2 * lod.points + 4 + lod.segments), BU.STORAGE | BU.COPY_DST),
        uniform: this.buffer(80, BU.UNIFORM | BU.COPY_DST),
        groups: Math.min(65535, Math.ceil(lod.segments / 256)) };
    }
    return set;
  }

  /** @param {DynSet | null} set */
  freeDynSet(set) {
    if (!set) return;
    this.free(set.buffer);
    const w = set.work;
    if (w.lod) for (const b of [w.lod.words, w.lod.state, w.lod.uniform]) this.free(b);
    for (const b of [w.flags, w.scan, w.blocks, w.compact, w.segments, w.dash, w.counters, w.indirect,
                     w.readCounters]) this.free(b);
  }

  /** The dynamic-line buffers of the scene and of the frame size. */
  freeDynamic() {
    this.freeDynSet(this.dynSet);
    this.dynSet = null;
    const t = this.dynTargets;
    if (t) for (const b of [t.ground, t.heads, t.nodes, t.layer]) this.free(b);
    this.dynTargets = null;
  }

  /**
   * Per-size buffers of the dynamic lines: each pixel's ground point (from
   * the decal pass), list head and dynamic colour, and the list nodes, two
   * per pixel to begin with (grown when a frame needs more), at most what
   * one binding of the device holds.
   * @param {number} W @param {number} H
   */
  dynTargetsFor(W, H) {
    const t = this.dynTargets;
    if (t && t.W === W && t.H === H) return t;
    if (t) for (const b of [t.ground, t.heads, t.nodes, t.layer]) this.free(b);
    const n = W * H, capacity = Math.min(2 * n, this.mostNodes());
    this.dynTargets = { W, H, ground: this.buffer(16 * n, BU.STORAGE), heads: this.buffer(4 * n, BU.STORAGE | BU.COPY_DST),
      capacity, nodes: this.buffer(16 * capacity, BU.STORAGE),
      layer: this.buffer(16 * n, BU.STORAGE | BU.COPY_DST) };  // cleared for a tileset
    return this.dynTargets;
  }

  /** The most list nodes (16 bytes each) one storage binding holds. */
  mostNodes() {
    return Math.floor(Math.min(this.device.limits.maxStorageBufferBindingSize, 0x7fffffff) / 16);
  }

  /**
   * A new device after the old one was lost (a GPU process that crashed
   * while presenting): pipelines, uniforms and the scene again.
   */
  async recover() {
    const { device } = await openDevice(this.gpu, 40);
    // The lost device's objects are gone with it.
    this.blobBuffer = this.visBuffer = this.heights = this.gradients = null;
    this.dynSet = this.dynTargets = null;
    if (this.tileset) this.tileset.uploads.clear();
    this.mesh = null;
    this.targets = null;
    this.context = null;
    this.gpuBytes = 0;
    this.initDevice(device);
    if (this.scene) this.uploadScene();
  }

  /**
   * Picks the present path before the canvas takes a context: a WebGPU
   * context configured on a throwaway OffscreenCanvas with this device and
   * one frame submitted to it. Where that throws, reports an error or loses
   * the device (the device is then opened again), frames are shown through
   * the canvas's 2D context.
   */
  async choosePresentPath() {
    const canvas = /** @type {HTMLCanvasElement} */ (this.canvas);
    let ok = false;
    const d = this.device;
    try {
      if (typeof OffscreenCanvas === "undefined") throw new Error("no OffscreenCanvas to try a WebGPU context on");
      const probe = /** @type {any} */ (new OffscreenCanvas(4, 4)).getContext("webgpu");
      if (!probe) throw new Error("OffscreenCanvas.getContext('webgpu') returned null");
      probe.configure({ device: d, format: this.gpu.getPreferredCanvasFormat(), alphaMode: "opaque" });
      d.pushErrorScope("validation");
      const enc = d.createCommandEncoder();
      const rp = enc.beginRenderPass({ colorAttachments: [{ view: probe.getCurrentTexture().createView(),
        clearValue: { r: 0, g: 0, b: 0, a: 1 }, loadOp: "clear", storeOp: "store" }] });
      rp.end();
      d.queue.submit([enc.finish()]);
      await d.queue.onSubmittedWorkDone();
      const err = await d.popErrorScope();
      if (err) throw new Error(err.message);
      // A GPU process that failed to back the texture loses the device soon after.
      await Promise.race([d.lost, sleep(100)]);
      if (this.lost) throw new Error(`the device was lost (${this.lostMessage})`);
      probe.unconfigure();
      ok = true;
    } catch (e) {
      this.presentError = `WebGPU canvas presentation failed: ${e instanceof Error ? e.message : String(e)}`;
    }
    if (this.lost) await this.recover();
    if (ok) {
      try {
        this.context = /** @type {any} */ (canvas.getContext("webgpu"));
        if (!this.context) throw new Error("canvas.getContext('webgpu') returned null (the canvas has another context)");
        this.presentFormat = this.gpu.getPreferredCanvasFormat();
        this.context.configure({ device: this.device, format: this.presentFormat, alphaMode: "opaque" });
        this.presentPath = "webgpu";
        return;
      } catch (e) {
        this.presentError = `WebGPU canvas context: ${e instanceof Error ? e.message : String(e)}`;
        if (this.context) {  // the canvas is WebGPU's now: no 2D context on it
          this.presentPath = "none";
          return;
        }
      }
    }
    this.context2d = canvas.getContext("2d");
    this.presentPath = this.context2d ? "2d" : "none";
    if (!this.context2d) this.presentError += "; canvas.getContext('2d') returned null";
  }

  freeMesh() {
    if (this.mesh) {
      this.free(this.mesh.vbo);
      this.free(this.mesh.ibo);
    }
    this.mesh = null;
  }

  /** @param {number} layerIndex  the metadata layer table's index @param {boolean} visible */
  setLayerVisible(layerIndex, visible) {
    const word = layerIndex >>> 5;
    if (word >= this.visBits.length) return;
    const bit = 1 << (layerIndex & 31);
    this.visBits[word] = visible ? this.visBits[word] | bit : this.visBits[word] & ~bit;
    if (this.visBuffer) this.device.queue.writeBuffer(this.visBuffer, 0, this.visBits);
  }

  /**
   * The terrain mesh relative to the anchor (frame.js terrainMesh) on the
   * device, kept while the anchor stays.
   * @param {number} ax @param {number} ay anchor, metres
   */
  meshFor(ax, ay) {
    if (this.mesh && this.mesh.ax === ax && this.mesh.ay === ay) return this.mesh;
    this.freeMesh();
    const { vertices: v, indices: idx } = terrainMesh(/** @type {Terrain} */ (this.terrain), ax, ay);
    const vbo = this.buffer(v.byteLength, BU.VERTEX | BU.COPY_DST);
    const ibo = this.buffer(idx.byteLength, BU.INDEX | BU.COPY_DST);
    this.device.queue.writeBuffer(vbo, 0, v);
    this.device.queue.writeBuffer(ibo, 0, idx);
    this.mesh = { ax, ay, vbo, ibo, count: idx.length };
    return this.mesh;
  }

  /** Per-size targets and buffers. @param {number} W @param {number} H */
  targetsFor(W, H) {
    if (this.targets && this.targets.W === W && this.targets.H === H) return this.targets;
    this.freeTargets();
    const d = this.device;
    const tex = (/** @type {string} */ format, /** @type {number} */ bpp) => {
      this.gpuBytes += W * H * bpp;
      return d.createTexture({ size: [W, H], format, usage: TU.RENDER_ATTACHMENT | TU.TEXTURE_BINDING });
    };
    const n = W * H;
    this.targets = {
      W, H,
      color: tex("rgba8unorm", 4), depth: tex("depth32float", 4),
      dec: this.buffer(32 * n, BU.STORAGE | BU.COPY_DST),  // colour and unlit share per pixel (cleared for a tileset)
      rgba: this.buffer(4 * n, BU.STORAGE | BU.COPY_SRC),
      decals: this.buffer(4 * n, BU.STORAGE | BU.COPY_SRC),
      readRgba: this.buffer(4 * n, BU.MAP_READ | BU.COPY_DST),
      readDecals: this.buffer(4 * n, BU.MAP_READ | BU.COPY_DST),
      pick: this.buffer(32, BU.STORAGE | BU.COPY_SRC | BU.COPY_DST),  // wgsl_decals.js PICK
      readPick: this.buffer(32, BU.MAP_READ | BU.COPY_DST),
    };
    return this.targets;
  }

  freeTargets() {
    const t = this.targets;
    if (!t) return;
    for (const x of [t.color, t.depth]) x.destroy();
    this.gpuBytes -= t.W * t.H * 8;
    for (const b of [t.dec, t.rgba, t.decals, t.readRgba, t.readDecals, t.pick, t.readPick]) this.free(b);
    this.targets = null;
  }

  /**
   * Draws one frame and returns its pixels (RGBA8, row 0 at the top).
   * present: also show it on the canvas, by the path the first such frame
   * picks (presentPath); rgba is read back for the 2D path even when
   * readback is false (and then not returned).
   * pick: a pixel [x, y] (x right, y down from the top-left) whose top
   * decal the frame's own query reports (Pick; null where the pixel shows
   * no decal).
   * @param {FrameArgs} args
   * @returns {Promise<FrameResult>}
   */
  renderFrame(args) {
    // One frame at a time: a click's pick or a tile's arrival asks for a
    // frame while one is drawing, and frames share targets and uploads.
    const run = this.frameChain.then(() => this.renderFrameNow(args));
    this.frameChain = run.catch(() => {});
    return run;
  }

  /** renderFrame, the frame before it done. @param {FrameArgs} args @returns {Promise<FrameResult>} */
  async renderFrameNow(args) {
    const show = Boolean(args.present && this.canvas);
    if (show && this.presentPath === null) await this.choosePresentPath();
    try {
      return await this.drawFrame(args, show);
    } catch (e) {
      if (!(show && this.presentPath === "webgpu" && this.lost)) throw e;
      // Presenting lost the device: draw again on a new one, frames not shown.
      this.presentError = `presenting lost the device (${this.lostMessage})`;
      this.presentPath = "none";
      await this.recover();
      return this.drawFrame(args, false);
    }
  }

  /**
   * @param {FrameArgs} args
   * @param {boolean} show  show the frame on the canvas by the present path
   * @returns {Promise<FrameResult>}
   */
  async drawFrame({ camera, width, height, albedo, decals, readback, pick, passTimes, tiles }, show) {
    const scene = this.scene;
    if (!scene) throw new Error("renderFrame: no scene (call setScene first)");
    const t0 = performance.now();
    const d = this.device, W = width, H = height;
    const T = this.targetsFor(W, H);
    const terrain = /** @type {Terrain} */ (this.terrain);
    const px = pick ? Math.floor(pick[0]) : -1, py = pick ? Math.floor(pick[1]) : -1;
    const picking = px >= 0 && py >= 0 && px < W && py < H;
    // A frame drawn only for its pick runs the query on the pick's 8x8 block alone.
    const pickOnly = picking && readback === false && !decals && !show;
    // The anchor (the eye rounded to whole quanta), the terrain pass's
    // uniform and the decal pass's frame: frame.js, which WebGL2 shares.
    const u = frameUniforms({ scene, terrain, camera, W, H, albedo, pick: picking ? [px, py] : null, pickOnly });
    const { ax, ay, vp } = u;
    d.queue.writeBuffer(this.terrainUniform, 0, u.terrainUniform);
    const gx = Math.ceil(W / 8), gy = Math.ceil(H / 8);
    // The decal dispatches: the package's over the frame, or a tileset's,
    // one per tile square in view, each with its own frame.
    const tileOut = this.tileset
      ? await this.tileJobs(tiles ?? [], { camera, terrain, W, H, albedo, pick: picking ? [px, py] : null,
        pickOnly, vp, ax, ay })
      : null;
    // Dynamic lines (not in a frame drawn for its pick alone): the
    // package's, or each tile square's.
    /** @type {DynDraw[]} */
    const dynDraws = tileOut ? tileOut.dynamic
      : this.dynSet ? [{ set: this.dynSet, u, camera, clip: null, go: [0, 0] }] : [];
    const dyn = !pickOnly && dynDraws.length > 0 ? this.dynTargetsFor(W, H) : null;
    const jobs = tileOut ? tileOut.jobs
      : [{ frame: u.frame, blob: this.blobBuffer, nx: pickOnly ? 1 : gx, ny: pickOnly ? 1 : gy, key: "" }];
    if (tileOut && dyn) {
      // The ground points of every pixel, in the index frame, for the
      // tiles' dynamic lines (clip mode 2: no decals).
      const ground = u.frame.slice(0);
      new Uint32Array(ground)[102] = 2;
      jobs.unshift({ frame: ground, blob: this.blobBuffer, nx: gx, ny: gy, key: "" });
    }
    this.frameSlotsFor(jobs.length);
    jobs.forEach((j, k) => {
      new Uint32Array(j.frame)[103] = k;  // F.bx.w: which dispatch wrote the pick
      d.queue.writeBuffer(this.frameUniform, k * FRAME_STRIDE, j.frame);
    });
    d.queue.writeBuffer(this.sizeUniform, 0, Uint32Array.of(W, H, dyn ? 1 : 0, 0));

    if (picking) d.queue.writeBuffer(T.pick, 0, new Uint32Array(8));
    const mesh = this.meshFor(ax, ay);
    let enc = d.createCommandEncoder();
    // passTimes: each pass's time, from timestamp queries where the device
    // has them, else the wall time of the pass submitted alone.
    const stamps = passTimes && this.device.features.has("timestamp-query") ? this.timestampSet() : null;
    const wallPasses = Boolean(passTimes) && !stamps;
    /** @type {number[]} */
    const wall = [];
    let mark = performance.now();
    const passDone = async () => {
      if (!wallPasses) return;
      d.queue.submit([enc.finish()]);
      await d.queue.onSubmittedWorkDone();
      const now = performance.now();
      wall.push(now - mark);
      mark = now;
      enc = d.createCommandEncoder();
    };
    /** @param {number} k */
    const stampWrites = (k) => (stamps ? { timestampWrites: {
      querySet: stamps.set, beginningOfPassWriteIndex: 2 * k, endOfPassWriteIndex: 2 * k + 1 } } : {});
    const rp = enc.beginRenderPass({
      ...stampWrites(0),
      colorAttachments: [
        { view: T.color.createView(), clearValue: { r: 0.8, g: 0.86, b: 0.93, a: 1 }, loadOp: "clear", storeOp: "store" },
      ],
      depthStencilAttachment: { view: T.depth.createView(), depthClearValue: 0, depthLoadOp: "clear", depthStoreOp: "store" },
    });
    rp.setPipeline(this.terrainPipeline);
    rp.setBindGroup(0, d.createBindGroup({ layout: this.terrainPipeline.getBindGroupLayout(0),
      entries: [{ binding: 0, resource: { buffer: this.terrainUniform } }] }));
    rp.setVertexBuffer(0, mesh.vbo);
    rp.setIndexBuffer(mesh.ibo, "uint32");
    rp.drawIndexed(mesh.count);
    rp.end();
    await passDone();
    /**
     * One compute pass of `pipeline` over the frame, its resources bound in order.
     * @param {number} k @param {any} pipeline @param {any[]} resources @param {number} [nx] @param {number} [ny]
     */
    const dispatch = (k, pipeline, resources, nx = gx, ny = gy) => {
      const cp = enc.beginComputePass(stampWrites(k));
      cp.setPipeline(pipeline);
      cp.setBindGroup(0, d.createBindGroup({ layout: pipeline.getBindGroupLayout(0),
        entries: resources.map((resource, binding) => ({ binding, resource })) }));
      cp.dispatchWorkgroups(nx, ny);
      cp.end();
    };
    /** @param {any} buffer */
    const buf = (buffer) => ({ buffer });
    // A tileset's squares leave the pixels no tile draws: cleared first.
    if (this.tileset) enc.clearBuffer(T.dec);
    if (this.tileset && dyn) enc.clearBuffer(dyn.layer);
    {
      const cp = enc.beginComputePass(stampWrites(1));
      cp.setPipeline(this.decalPipeline);
      const layout = this.decalPipeline.getBindGroupLayout(0);
      const depth = T.depth.createView();
      jobs.forEach((j, k) => {
        const resources = [{ buffer: this.frameUniform, offset: k * FRAME_STRIDE, size: FRAME_BYTES },
          buf(j.blob), buf(this.visBuffer), depth, buf(T.dec), buf(this.heights), buf(this.gradients),
          buf(T.pick), buf(dyn ? dyn.ground : this.standIn)];
        cp.setBindGroup(0, d.createBindGroup({ layout, entries: resources.map((resource, binding) => ({ binding, resource })) }));
        cp.dispatchWorkgroups(j.nx, j.ny);
      });
      cp.end();
    }
    await passDone();
    /** @type {DynamicStats | null} */
    let dynStats = null;
    if (dyn) {
      // The lists pass reads its node count back: what is encoded goes first.
      d.queue.submit([enc.finish()]);
      dynStats = { kept: 0, segments: 0, nodes: 0, grows: 0 };
      for (const [i, e] of dynDraws.entries()) {
        this.writeDynUniforms(e, W, H, terrain, Boolean(tileOut));
        const st = await this.dynamicPasses(dyn, T, W, H, stamps, e.set, i === 0, i === dynDraws.length - 1);
        dynStats.kept += st.kept;
        dynStats.segments += st.segments;
        dynStats.nodes += st.nodes;
        dynStats.grows += st.grows;
      }
      enc = d.createCommandEncoder();
      if (wallPasses) {
        await d.queue.onSubmittedWorkDone();
        const now = performance.now();
        wall.push(now - mark);
        mark = now;
      }
    } else if (wallPasses) {
      wall.push(0);
    }
    if (!pickOnly) {
      dispatch(2, this.compositePipeline, [buf(this.sizeUniform), T.color.createView(), buf(T.dec),
        buf(T.rgba), buf(T.decals), buf(dyn ? dyn.layer : this.standIn)]);
      await passDone();
    }
    if (stamps) {
      // Queries 6 and 7 are written only by a frame with dynamic lines.
      enc.resolveQuerySet(stamps.set, 0, dyn ? 8 : 6, stamps.resolve, 0);
      enc.copyBufferToBuffer(stamps.resolve, 0, stamps.read, 0, 64);
    }
    const wantRgba = readback !== false;
    const put2d = show && this.presentPath === "2d";
    if (wantRgba || put2d) enc.copyBufferToBuffer(T.rgba, 0, T.readRgba, 0, 4 * W * H);
    if (decals) enc.copyBufferToBuffer(T.decals, 0, T.readDecals, 0, 4 * W * H);
    if (picking) enc.copyBufferToBuffer(T.pick, 0, T.readPick, 0, 32);
    if (show && this.presentPath === "webgpu") this.encodePresent(enc, T, W, H);
    d.queue.submit([enc.finish()]);
    await d.queue.onSubmittedWorkDone();
    const ms = performance.now() - t0;
    /** @param {any} b */
    const read = async (b) => {
      await b.mapAsync(MAP_READ);
      const out = new Uint8Array(b.getMappedRange().slice(0));
      b.unmap();
      return out;
    };
    const rgba = wantRgba || put2d ? await read(T.readRgba) : null;
    if (put2d && rgba) this.put2d(rgba, W, H);
    if (this.lost) throw new Error(`renderFrame: the WebGPU device was lost (${this.lostMessage})`);
    /** @type {Pick | null} */
    let top = null;
    if (picking) {
      const [kind, layer, feature, index, job] = new Uint32Array((await read(T.readPick)).buffer);
      if (kind !== 0) top = { kind: kind === 1 ? "line" : "polygon", layer, feature, index };
      if (top && this.tileset) top.tile = jobs[job]?.key ?? "";
    }
    /** @type {PassTimes | null} */
    let passes = null;
    if (stamps) {
      const ns = new BigInt64Array((await read(stamps.read)).buffer);
      const span = (/** @type {number} */ k) => Number(ns[2 * k + 1] - ns[2 * k]) / 1e6;
      passes = { timing: "timestamp", terrain: span(0), decals: span(1), dynamic: dyn ? span(3) : 0,
        composite: pickOnly ? 0 : span(2) };
    } else if (wallPasses) {
      passes = { timing: "wall", terrain: wall[0], decals: wall[1], dynamic: wall[2] ?? 0, composite: wall[3] ?? 0 };
    }
    return { rgba: wantRgba ? rgba : null, decals: decals ? await read(T.readDecals) : null, ms, pick: top,
      passes, dynamic: dynStats, uploads: tileOut ? tileOut.uploads : 0 };
  }

  /**
   * The uniforms of one draw of dynamic lines (wgsl_dynamic.js Dyn;
   * gl_dynamic.cpp set_uniforms) and, with LOD lines, of its LOD passes.
   * tileMode: a tileset's tile, drawn only in its square, composited only
   * where its lists are not empty.
   * @param {DynDraw} e @param {number} W @param {number} H @param {Terrain} terrain @param {boolean} tileMode
   */
  writeDynUniforms(e, W, H, terrain, tileMode) {
    const d = this.device, { u, camera, set } = e, ds = set.ds;
    const persp = camera.projection === "perspective";
    const th = Math.tan((camera.fovYDeg * Math.PI) / 360);
    const du = new ArrayBuffer(DYN_UNIFORM_BYTES);
    const di = new Int32Array(du), df = new Float32Array(du), dw = new Uint32Array(du);
    df.set(u.vp, 0);
    di.set([u.axq, u.ayq, ds.vertices, ds.lines], 16);
    df.set([W, H, persp ? camera.near : 0, Math.cos((ds.miterLimitDeg * Math.PI) / 180)], 20);
    df.set([...u.eyeRel, persp ? 0 : camera.orthoH / H], 24);
    df.set([persp ? (2 * th) / H : 0, terrain.zmin, terrain.zmax, 0], 28);
    dw.set([...ds.offsets.subarray(0, 5), ds.minWidthCount, ds.offsets[5], ds.dashed ? 1 : 0], 32);
    const c = e.clip;
    df.set(c ? [c[0] - u.ax, c[1] - u.ay, c[2] - u.ax, c[3] - u.ay] : [-3e38, -3e38, 3e38, 3e38], 40);
    df.set([e.go[0], e.go[1], tileMode ? 1 : 0, 0], 44);
    d.queue.writeBuffer(this.dynUniform, 0, du);
    const lw = set.work.lod, lod = set.lod;
    if (lw && lod) {
      // render --lod on, --lod-tolerance 0.5 (prep::render::lod_view).
      const view = lodView(camera, H, terrain.zmin, terrain.zmax, 0.5);
      d.queue.writeBuffer(lw.uniform, 0, lodUniform(view, [lod.points, lod.segments], lod.offsets));
      d.queue.writeBuffer(lw.state, 0, lw.reset);
    }
  }

  /**
   * The dynamic-line passes of a frame (gl_dynamic.cpp dynamic_pass):
   * update (cull, compaction, segments; dashes' screen distances), lists
   * (segment boxes into per-pixel linked lists: drawn again with a larger
   * node buffer, at most three times, when the nodes asked for pass its
   * capacity; past the fourth try, or the device's binding size, the nodes
   * beyond it are left out), composite into dyn.layer. The node count is
   * read back after each lists pass. Timestamps 6 and 7 (passTimes) span
   * the three (first: the update of the frame's first set of lines writes
   * 6; last: the composite of its last writes 7).
   * @param {any} dyn  dynTargetsFor's @param {any} T  targetsFor's
   * @param {number} W @param {number} H @param {any} stamps
   * @param {DynSet} set @param {boolean} first @param {boolean} last
   * @returns {Promise<DynamicStats>}
   */
  async dynamicPasses(dyn, T, W, H, stamps, set, first, last) {
    const d = this.device, w = set.work, P = await this.dynamicPipelines();
    const init = new Uint32Array(DYN_COUNTER_WORDS);
    init.set([36, 0, 0, 0, 0, 0, dyn.capacity, set.ds.vertices]);
    d.queue.writeBuffer(w.counters, 0, init);
    const group = (/** @type {any} */ layout, /** @type {any[]} */ buffers) => d.createBindGroup({ layout,
      entries: buffers.map((buffer, binding) => ({ binding, resource: { buffer } })) });
    let enc = d.createCommandEncoder();
    const cp = enc.beginComputePass(stamps && first ? { timestampWrites: { querySet: stamps.set, beginningOfPassWriteIndex: 6 } } : {});
    const updateGroup = group(P.layout, [this.dynUniform, set.buffer, w.flags, w.scan, w.blocks, w.compact,
      w.segments, w.counters, w.dash]);
    const lodGroup = w.lod ? group(P.lodLayout, [this.dynUniform, set.buffer, w.flags, w.scan, w.segments,
      w.counters, w.lod.words, w.lod.state, w.lod.uniform]) : null;
    // With LOD lines (gl_dynamic.cpp update): lod_mask after the cull, the
    // selection and its segments after the update's segments.
    const entries = ["cull", ...(lodGroup ? ["lod_mask"] : []), "scan_local", "scan_blocks", "scatter", "segments",
      ...(lodGroup ? ["lod_select", "lod_segments"] : [])];
    if (set.ds.dashed) entries.push("dash_local", "dash_blocks", "dash_apply");
    for (const entry of entries) {
      const isLod = entry.startsWith("lod_");
      cp.setPipeline(isLod ? P.lod[entry] : P.update[entry]);
      cp.setBindGroup(0, isLod ? lodGroup : updateGroup);
      const groups = entry === "scan_blocks" || entry === "dash_blocks" ? 1
        : entry === "lod_select" || entry === "lod_segments" ? w.lod.groups : w.groups;
      cp.dispatchWorkgroups(groups);
    }
    cp.end();
    enc.copyBufferToBuffer(w.counters, 0, w.indirect, 0, 16);
    let grows = 0;
    /** @type {Uint32Array} */
    let counts = new Uint32Array(DYN_COUNTER_WORDS);
    for (let attempt = 0; attempt < 4; ++attempt) {
      if (attempt > 0) {
        enc = d.createCommandEncoder();
        d.queue.writeBuffer(w.counters, 20, Uint32Array.of(0, dyn.capacity));
      }
      enc.clearBuffer(dyn.heads);
      const rp = enc.beginRenderPass({ colorAttachments: [{ view: T.color.createView(), loadOp: "load", storeOp: "store" }] });
      rp.setPipeline(P.lists);
      rp.setBindGroup(0, group(P.lists.getBindGroupLayout(0), [this.dynUniform, set.buffer, w.segments, dyn.ground,
        dyn.heads, dyn.nodes, w.counters, this.visBuffer, w.dash]));
      rp.drawIndirect(w.indirect, 0);
      rp.end();
      enc.copyBufferToBuffer(w.counters, 0, w.readCounters, 0, 4 * DYN_COUNTER_WORDS);
      d.queue.submit([enc.finish()]);
      await w.readCounters.mapAsync(MAP_READ);
      counts = new Uint32Array(w.readCounters.getMappedRange().slice(0));
      w.readCounters.unmap();
      // The last try's lists stand: its buffer holds the nodes they link.
      if (counts[5] <= dyn.capacity || attempt === 3) break;
      // Grow as gl_dynamic.cpp does, within the device's binding size.
      const capacity = Math.min(Math.floor((counts[5] * 5) / 4) + 1024, this.mostNodes());
      if (capacity <= dyn.capacity) break;
      this.free(dyn.nodes);
      dyn.capacity = capacity;
      dyn.nodes = this.buffer(16 * capacity, BU.STORAGE);
      ++grows;
    }
    enc = d.createCommandEncoder();
    const comp = enc.beginComputePass(stamps && last ? { timestampWrites: { querySet: stamps.set, endOfPassWriteIndex: 7 } } : {});
    comp.setPipeline(P.composite);
    comp.setBindGroup(0, group(P.composite.getBindGroupLayout(0), [this.dynUniform, set.buffer, dyn.heads,
      dyn.nodes, w.counters, dyn.layer]));
    comp.dispatchWorkgroups(Math.ceil(W / 8), Math.ceil(H / 8));
    comp.end();
    d.queue.submit([enc.finish()]);
    return { kept: counts[4], segments: counts[1], nodes: counts[5], grows };
  }

  /** The frame uniform buffer, grown to hold `n` frames. @param {number} n */
  frameSlotsFor(n) {
    if (n <= this.frameSlots) return;
    this.frameUniform.destroy();
    this.frameSlots = Math.max(n, 2 * this.frameSlots);
    this.frameUniform = this.device.createBuffer({ size: this.frameSlots * FRAME_STRIDE,
      usage: BU.UNIFORM | BU.COPY_DST });
  }

  /**
   * The decal dispatches of a tileset frame: per square of each tile that
   * the image meets, the tile's frame over the square's pixel box
   * (frame.js tileFrames). Tiles not on the device are uploaded; those
   * this frame does not draw are freed.
   * Tiles with dynamic lines add a draw of them per square.
   * @param {FrameTile[]} tiles @param {import("./frame.js").TileFrameArgs} f
   * @returns {Promise<{jobs: {frame: ArrayBuffer, blob: any, nx: number, ny: number, key: string}[],
   *                    dynamic: DynDraw[], uploads: number}>}
   */
  async tileJobs(tiles, f) {
    const ts = /** @type {NonNullable<Renderer["tileset"]>} */ (this.tileset);
    const keep = new Set(tiles.map((t) => t.key));
    // Tiles this frame draws are kept; the others go once KEEP_FRAMES
    // frames have not drawn them (a view that goes back and forth between
    // two detail levels does not upload its tiles again each time).
    this.frameCount += 1;
    for (const [key, u] of ts.uploads)
      if (keep.has(key)) {
        u.used = this.frameCount;
      } else if (this.frameCount - u.used > KEEP_FRAMES) {
        this.free(u.blob);
        this.freeDynSet(u.dyn);
        ts.uploads.delete(key);
      }
    const jobs = [];
    /** @type {DynDraw[]} */
    const dynamic = [];
    let uploads = 0;
    for (const t of tiles) {
      if (!ts.uploads.has(t.key)) uploads += 1;
      const { scene, blob, dyn } = await this.tileUpload(t);
      for (const { frame, box, u, camera, clip, go } of tileFrames(t, scene, f)) {
        jobs.push({ frame, blob, key: t.key, nx: f.pickOnly ? 1 : Math.ceil((box[2] - box[0]) / 8),
          ny: f.pickOnly ? 1 : Math.ceil((box[3] - box[1]) / 8) });
        if (dyn) dynamic.push({ set: dyn, u, camera, clip, go });
      }
    }
    return { jobs, dynamic, uploads };
  }

  /** The 2D present path. @param {Uint8Array} rgba @param {number} W @param {number} H */
  put2d(rgba, W, H) {
    const canvas = /** @type {HTMLCanvasElement} */ (this.canvas);
    if (canvas.width !== W || canvas.height !== H) {
      canvas.width = W;
      canvas.height = H;
    }
    const px = new Uint8ClampedArray(rgba.buffer, rgba.byteOffset, rgba.byteLength);
    this.context2d.putImageData(new ImageData(px, W, H), 0, 0);
  }

  /** @param {any} enc @param {any} T @param {number} W @param {number} H */
  encodePresent(enc, T, W, H) {
    const d = this.device;
    const canvas = /** @type {HTMLCanvasElement} */ (this.canvas);
    if (!this.presentPipeline) {
      const m = d.createShaderModule({ code: PRESENT_WGSL });
      this.presentPipeline = d.createRenderPipeline({ layout: "auto",
        vertex: { module: m, entryPoint: "vs" },
        fragment: { module: m, entryPoint: "fs", targets: [{ format: this.presentFormat }] } });
    }
    if (canvas.width !== W || canvas.height !== H) {
      canvas.width = W;
      canvas.height = H;
    }
    const rp = enc.beginRenderPass({ colorAttachments: [{ view: this.context.getCurrentTexture().createView(),
      clearValue: { r: 0, g: 0, b: 0, a: 1 }, loadOp: "clear", storeOp: "store" }] });
    rp.setPipeline(this.presentPipeline);
    rp.setBindGroup(0, d.createBindGroup({ layout: this.presentPipeline.getBindGroupLayout(0), entries: [
      { binding: 0, resource: { buffer: this.sizeUniform } },
      { binding: 1, resource: { buffer: T.rgba } }] }));
    rp.draw(3);
    rp.end();
  }

  destroy() {
    this.destroyed = true;
    this.freeTiles();
    this.freeTargets();
    this.freeMesh();
    this.free(this.blobBuffer);
    this.free(this.visBuffer);
    this.free(this.heights);
    this.free(this.gradients);
    this.freeDynamic();
    this.blobBuffer = this.visBuffer = this.heights = this.gradients = null;
    this.device.destroy();
  }
}

export { SLOTS };
