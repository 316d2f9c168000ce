// webgl2.js — the WebGL2 renderer, for browsers without WebGPU: the
// interface of the WebGPU renderer (index.js Renderer: setScene,
// setLayerVisible, renderFrame, adapterName, gpuBytes, destroy) and the
// same frame, for static decals: the terrain pass (glsl_frame.js), then one
// full-screen fragment pass that runs the static decal query at each pixel
// and composites it (glsl_decals.js, the GLSL port of wgsl_decals.js and
// the composite of wgsl_frame.js). Dynamic lines and LOD are not drawn.
//
// Data lives in textures read with texelFetch: the packed blob words
// (scene.js) in an R32UI array texture, exact on every implementation;
// terrain heights and triangle gradients in R32F ones; the layer
// visibility bits in an R32UI one. Every such "linear" texture has rows of
// 2^ws texels and layers of up to 2^ls rows (ws = ls = log2 of the largest
// power of two within MAX_TEXTURE_SIZE); one whose words need more layers
// than MAX_ARRAY_TEXTURE_LAYERS, or that the GPU cannot allocate, is
// refused with an Error naming its size. No float render target is used
// (the decal pass writes the RGBA8 frame itself), so EXT_color_buffer_float
// is not needed.
//
// The WebGL2 types come from the checked lib (dom).

import { DECALS_GLSL } from "./glsl_decals.js";
import { TERRAIN_VS, TERRAIN_FS, FULLSCREEN_VS } from "./glsl_frame.js";
import { frameUniforms, terrainMesh, tileFrames } from "./frame.js";
import { emptyScene, packScene } from "./scene.js";
import { flatTerrain, triangleGradients } from "./index.js";

/** Frames a tileset's tile stays on the GPU without being drawn (as index.js). */
const KEEP_FRAMES = 30;

/** What this renderer leaves out, in the viewer overlay's words. */
export const WEBGL2_LIMITS = "static decals only; dynamic lines not drawn";

/**
 * A linear texture's shape: `words` values in rows of 2^ws texels, layers
 * of up to 2^ls rows. Throws an Error naming the size when the layers
 * needed pass maxLayers.
 * @param {number} words @param {number} maxSize MAX_TEXTURE_SIZE @param {number} maxLayers MAX_ARRAY_TEXTURE_LAYERS
 * @param {string} what  names the data in the message
 */
export function linearLayout(words, maxSize, maxLayers, what) {
  const ws = Math.floor(Math.log2(Math.max(1, maxSize)));
  const ls = ws;
  const width = 2 ** ws;
  const rows = Math.max(1, Math.ceil(words / width));
  const height = Math.min(rows, 2 ** ls);
  const layers = Math.ceil(rows / 2 ** ls);
  if (layers > maxLayers) {
    throw new Error(`WebGL2: ${what} is ${words} words (${(4 * words / 1048576).toFixed(1)} MiB); ` +
      `the textures here hold at most ${maxLayers} layers of ${width}x${2 ** ls} words ` +
      `(${(maxLayers * width * 2 ** ls * 4 / 1048576).toFixed(0)} MiB)`);
  }
  return { ws, ls, width, height, layers };
}

/**
 * Creates the WebGL2 renderer on `canvas` (an OffscreenCanvas without one);
 * throws an Error saying what is missing when WebGL2 is not available.
 * @param {{canvas?: HTMLCanvasElement | null}} [options]
 */
export function createWebGL2Renderer(options = {}) {
  const canvas = options.canvas ?? null;
  const target = canvas ?? (typeof OffscreenCanvas !== "undefined" ? new OffscreenCanvas(1, 1) : null);
  if (!target) throw new Error("WebGL2 is not available: no canvas to draw on");
  const gl = /** @type {WebGL2RenderingContext | null} */ (target.getContext("webgl2", {
    antialias: false, depth: false, stencil: false, alpha: false, premultipliedAlpha: false,
    preserveDrawingBuffer: false,
  }));
  if (!gl) throw new Error("WebGL2 is not available: getContext('webgl2') returned null");
  return new WebGL2Renderer(gl, canvas);
}

/**
 * @param {WebGL2RenderingContext} gl @param {number} type @param {string} source @param {string} name
 */
function compile(gl, type, source, name) {
  const s = /** @type {WebGLShader} */ (gl.createShader(type));
  gl.shaderSource(s, source);
  gl.compileShader(s);
  if (!gl.getShaderParameter(s, gl.COMPILE_STATUS))
    throw new Error(`WebGL2: the ${name} shader does not compile: ${gl.getShaderInfoLog(s)}`);
  return s;
}

/** @param {WebGL2RenderingContext} gl @param {string} vs @param {string} fs @param {string} name */
function program(gl, vs, fs, name) {
  const p = /** @type {WebGLProgram} */ (gl.createProgram());
  gl.attachShader(p, compile(gl, gl.VERTEX_SHADER, vs, name));
  gl.attachShader(p, compile(gl, gl.FRAGMENT_SHADER, fs, name));
  gl.linkProgram(p);
  if (!gl.getProgramParameter(p, gl.LINK_STATUS))
    throw new Error(`WebGL2: the ${name} program does not link: ${gl.getProgramInfoLog(p)}`);
  return p;
}

export class WebGL2Renderer {
  /** @param {WebGL2RenderingContext} gl @param {HTMLCanvasElement | null} canvas */
  constructor(gl, canvas) {
    this.gl = gl;
    this.canvas = canvas;
    this.backend = "webgl2";
    this.limits = WEBGL2_LIMITS;
    const info = gl.getExtension("WEBGL_debug_renderer_info");
    const name = info ? gl.getParameter(info.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER);
    this.adapterName = `WebGL2 ${String(name)}`;
    this.gpuBytes = 0;
    this.maxSize = /** @type {number} */ (gl.getParameter(gl.MAX_TEXTURE_SIZE));
    this.maxLayers = /** @type {number} */ (gl.getParameter(gl.MAX_ARRAY_TEXTURE_LAYERS));
    this.terrainProgram = program(gl, TERRAIN_VS, TERRAIN_FS, "terrain");
    this.decalProgram = program(gl, FULLSCREEN_VS, DECALS_GLSL, "decal");
    gl.uniformBlockBinding(this.terrainProgram, gl.getUniformBlockIndex(this.terrainProgram, "Terrain"), 0);
    gl.uniformBlockBinding(this.decalProgram, gl.getUniformBlockIndex(this.decalProgram, "Frame"), 1);
    gl.useProgram(this.decalProgram);
    ["u_blobs", "u_heights", "u_grads", "u_vis", "u_ground", "u_terrain"].forEach((n, unit) =>
      gl.uniform1i(gl.getUniformLocation(this.decalProgram, n), unit));
    this.linLocation = gl.getUniformLocation(this.decalProgram, "u_lin");
    this.goLocation = gl.getUniformLocation(this.decalProgram, "u_go");
    /** @type {Promise<unknown>} the frame drawing now (renderFrame) */
    this.frameChain = Promise.resolve();
    /** the tiles the last frame uploaded; frames drawn (tiles stay KEEP_FRAMES frames undrawn) */
    this.uploads = 0;
    this.frameCount = 0;
    this.terrainUbo = gl.createBuffer();
    this.frameUbo = gl.createBuffer();
    /** @type {import("./scene.js").PackedScene | null} */ this.scene = null;
    /**
     * A tileset scene (as index.js Renderer.tileset): the restyling and the
     * tiles' packed scenes by key, their blob textures "tile:KEY" in `data`.
     * @type {{ramps: import("./scene.js").LayerRamp[], slopeWidths: import("./scene.js").SlopeWidths,
     *         uploads: Map<string, {scene: import("./scene.js").PackedScene, used: number}>} | null}
     */
    this.tileset = null;
    /** @type {import("./index.js").Terrain | null} */ this.terrain = null;
    /** @type {Map<string, {tex: WebGLTexture, bytes: number}>} */ this.data = new Map();
    /** @type {Uint32Array} */ this.visBits = new Uint32Array(1);
    /** @type {any} */ this.mesh = null;
    /** @type {any} */ this.targets = null;
    /** @type {{ws: number, ls: number}} */ this.lin = { ws: 0, ls: 0 };
    this.destroyed = false;
  }

  /**
   * A linear texture named `key` holding `values` (replacing the old one).
   * @param {string} key @param {Uint32Array | Float32Array} values @param {string} what
   */
  linearTexture(key, values, what) {
    const gl = this.gl;
    this.freeData(key);
    const lay = linearLayout(values.length, this.maxSize, this.maxLayers, what);
    this.lin = { ws: lay.ws, ls: lay.ls };
    const float = values instanceof Float32Array;
    const tex = /** @type {WebGLTexture} */ (gl.createTexture());
    gl.bindTexture(gl.TEXTURE_2D_ARRAY, tex);
    while (gl.getError() !== gl.NO_ERROR) { /* clear earlier errors */ }
    gl.texStorage3D(gl.TEXTURE_2D_ARRAY, 1, float ? gl.R32F : gl.R32UI, lay.width, lay.height, lay.layers);
    if (gl.getError() !== gl.NO_ERROR) {
      gl.deleteTexture(tex);
      throw new Error(`WebGL2: cannot allocate a ${lay.width}x${lay.height}x${lay.layers} texture ` +
        `(${(lay.width * lay.height * lay.layers * 4 / 1048576).toFixed(1)} MiB) for ${what}`);
    }
    for (const p of [gl.TEXTURE_MIN_FILTER, gl.TEXTURE_MAG_FILTER]) gl.texParameteri(gl.TEXTURE_2D_ARRAY, p, gl.NEAREST);
    const format = float ? gl.RED : gl.RED_INTEGER, type = float ? gl.FLOAT : gl.UNSIGNED_INT;
    const perLayer = lay.width * lay.height;
    for (let l = 0; l < lay.layers; ++l) {
      const start = l * perLayer, count = Math.min(values.length - start, perLayer);
      if (count <= 0) break;
      const full = Math.floor(count / lay.width), rest = count - full * lay.width;
      if (full > 0)
        gl.texSubImage3D(gl.TEXTURE_2D_ARRAY, 0, 0, 0, l, lay.width, full, 1, format, type, values, start);
      if (rest > 0)
        gl.texSubImage3D(gl.TEXTURE_2D_ARRAY, 0, 0, full, l, rest, 1, 1, format, type, values, start + full * lay.width);
    }
    const bytes = 4 * lay.width * lay.height * lay.layers;
    this.gpuBytes += bytes;
    this.data.set(key, { tex, bytes });
  }

  /** @param {string} key */
  freeData(key) {
    const d = this.data.get(key);
    if (!d) return;
    this.gl.deleteTexture(d.tex);
    this.gpuBytes -= d.bytes;
    this.data.delete(key);
  }

  /**
   * As index.js Renderer.setScene: a validated Package and its terrain (or
   * null: flat over the package extent), ramps, slope widths.
   * @param {{pkg: import("../package.js").Package, terrain: import("./index.js").Terrain | null,
   *          ramps?: import("./scene.js").LayerRamp[],
   *          slopeWidths?: import("./scene.js").SlopeWidths}} args
   */
  async setScene({ pkg, terrain, ramps, slopeWidths }) {
    const scene = await packScene(pkg, ramps ?? [], slopeWidths ?? "auto");
    this.freeTiles();
    this.tileset = null;
    this.useScene(scene, scene.layerCount, terrain ?? flatTerrain(pkg.metadata.extent || [0, 0, 1, 1]),
      `the package's static blobs (${pkg.label})`);
  }

  /**
   * As index.js Renderer.setTileScene: a tileset's terrain and restyling;
   * each frame names its tiles (FrameArgs tiles).
   * @param {{terrain: import("./index.js").Terrain | null, extent: number[], layerCount: number,
   *          ramps?: import("./scene.js").LayerRamp[],
   *          slopeWidths?: import("./scene.js").SlopeWidths}} args
   */
  async setTileScene({ terrain, extent, layerCount, ramps, slopeWidths }) {
    this.freeTiles();
    this.tileset = { ramps: ramps ?? [], slopeWidths: slopeWidths ?? "auto", uploads: new Map() };
    this.useScene(emptyScene(), layerCount, terrain ?? flatTerrain(extent), "no blobs");
  }

  /**
   * The scene's textures: its blobs, the visibility bits of `layers`
   * layers, the terrain's heights and gradients.
   * @param {import("./scene.js").PackedScene} scene @param {number} layers
   * @param {import("./index.js").Terrain} t @param {string} what
   */
  useScene(scene, layers, t, what) {
    this.scene = scene;
    this.visBits = new Uint32Array(Math.max(1, Math.ceil(layers / 32))).fill(0xffffffff);
    this.terrain = t;
    this.linearTexture("blobs", scene.words, what);
    this.linearTexture("vis", this.visBits, "the layer visibility bits");
    this.linearTexture("heights", Float32Array.from(t.z), `the terrain's ${t.nx}x${t.ny} heights`);
    // The gradients are read only for slope widths (a tileset's tiles may
    // have them); a placeholder otherwise.
    const grad = scene.slopeCount > 0 || this.tileset ? triangleGradients(t) : new Float32Array(4);
    this.linearTexture("grads", grad, "the terrain's triangle gradients");
    this.freeMesh();
  }

  /** A tileset scene's tile textures, freed. */
  freeTiles() {
    if (!this.tileset) return;
    for (const key of this.tileset.uploads.keys()) this.freeData(`tile:${key}`);
    this.tileset.uploads.clear();
  }

  /**
   * The packed scenes of a frame's tiles, their blob textures made where
   * missing; the tiles the frame does not draw are freed.
   * @param {import("./index.js").FrameTile[]} tiles
   */
  async tileScenes(tiles) {
    const ts = /** @type {NonNullable<WebGL2Renderer["tileset"]>} */ (this.tileset);
    const keep = new Set(tiles.map((t) => t.key));
    // As index.js tileJobs: tiles not drawn for KEEP_FRAMES frames go.
    this.frameCount += 1;
    for (const [key, u] of [...ts.uploads])
      if (keep.has(key)) {
        u.used = this.frameCount;
      } else if (this.frameCount - u.used > KEEP_FRAMES) {
        this.freeData(`tile:${key}`);
        ts.uploads.delete(key);
      }
    const out = [];
    for (const t of tiles) {
      let u = ts.uploads.get(t.key);
      if (!u) {
        this.uploads += 1;
        const scene = await packScene(t.pkg, ts.ramps, ts.slopeWidths);
        this.linearTexture(`tile:${t.key}`, scene.words, `the static blobs of tile ${t.key} (${t.pkg.label})`);
        u = { scene, used: this.frameCount };
        ts.uploads.set(t.key, u);
      }
      out.push(u.scene);
    }
    return out;
  }

  /** @param {number} layerIndex  the metadata layer table's index @param {boolean} visible */
  setLayerVisible(layerIndex, visible) {
    const word = layerIndex >>> 5;
    if (word >= this.visBits.length) return;
    const bit = 1 << (layerIndex & 31);
    this.visBits[word] = visible ? this.visBits[word] | bit : this.visBits[word] & ~bit;
    const d = this.data.get("vis");
    if (!d) return;
    const gl = this.gl;
    const width = 2 ** this.lin.ws, row = Math.floor(word / width);
    gl.bindTexture(gl.TEXTURE_2D_ARRAY, d.tex);
    gl.texSubImage3D(gl.TEXTURE_2D_ARRAY, 0, word - row * width, row % 2 ** this.lin.ls,
      Math.floor(row / 2 ** this.lin.ls), 1, 1, 1, gl.RED_INTEGER, gl.UNSIGNED_INT, this.visBits, word);
  }

  /** The terrain mesh relative to the anchor. @param {number} ax @param {number} ay */
  meshFor(ax, ay) {
    if (this.mesh && this.mesh.ax === ax && this.mesh.ay === ay) return this.mesh;
    this.freeMesh();
    const gl = this.gl;
    const { vertices, indices } = terrainMesh(/** @type {import("./index.js").Terrain} */ (this.terrain), ax, ay);
    const vao = gl.createVertexArray();
    gl.bindVertexArray(vao);
    const vbo = gl.createBuffer(), ibo = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, vbo);
    gl.bufferData(gl.ARRAY_BUFFER, vertices, gl.STATIC_DRAW);
    gl.enableVertexAttribArray(0);
    gl.vertexAttribPointer(0, 3, gl.FLOAT, false, 24, 0);
    gl.enableVertexAttribArray(1);
    gl.vertexAttribPointer(1, 3, gl.FLOAT, false, 24, 12);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, ibo);
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, indices, gl.STATIC_DRAW);
    gl.bindVertexArray(null);
    const bytes = vertices.byteLength + indices.byteLength;
    this.gpuBytes += bytes;
    this.mesh = { ax, ay, vao, vbo, ibo, count: indices.length, bytes };
    return this.mesh;
  }

  freeMesh() {
    const m = this.mesh;
    if (!m) return;
    const gl = this.gl;
    gl.deleteVertexArray(m.vao);
    gl.deleteBuffer(m.vbo);
    gl.deleteBuffer(m.ibo);
    this.gpuBytes -= m.bytes;
    this.mesh = null;
  }

  /** Per-size targets. @param {number} W @param {number} H */
  targetsFor(W, H) {
    if (this.targets && this.targets.W === W && this.targets.H === H) return this.targets;
    this.freeTargets();
    const gl = this.gl;
    const tex = (/** @type {number} */ format) => {
      const t = /** @type {WebGLTexture} */ (gl.createTexture());
      gl.bindTexture(gl.TEXTURE_2D, t);
      gl.texStorage2D(gl.TEXTURE_2D, 1, format, W, H);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
      return t;
    };
    const colour = tex(gl.RGBA8), ground = tex(gl.RGBA32UI);
    const depth = gl.createRenderbuffer();
    gl.bindRenderbuffer(gl.RENDERBUFFER, depth);
    gl.renderbufferStorage(gl.RENDERBUFFER, gl.DEPTH_COMPONENT32F, W, H);
    const terrainFbo = gl.createFramebuffer();
    gl.bindFramebuffer(gl.FRAMEBUFFER, terrainFbo);
    gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, colour, 0);
    gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT1, gl.TEXTURE_2D, ground, 0);
    gl.framebufferRenderbuffer(gl.FRAMEBUFFER, gl.DEPTH_ATTACHMENT, gl.RENDERBUFFER, depth);
    const check = (/** @type {string} */ what) => {
      const s = gl.checkFramebufferStatus(gl.FRAMEBUFFER);
      if (s !== gl.FRAMEBUFFER_COMPLETE) throw new Error(`WebGL2: the ${what} framebuffer is incomplete (0x${s.toString(16)})`);
    };
    check("terrain");
    const rgba = tex(gl.RGBA8), decals = tex(gl.RGBA8), pick = tex(gl.RGBA32UI);
    const decalFbo = gl.createFramebuffer();
    gl.bindFramebuffer(gl.FRAMEBUFFER, decalFbo);
    gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, rgba, 0);
    gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT1, gl.TEXTURE_2D, decals, 0);
    gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT2, gl.TEXTURE_2D, pick, 0);
    check("decal");
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    const bytes = W * H * (4 + 16 + 4 + 4 + 4 + 16);
    this.gpuBytes += bytes;
    this.targets = { W, H, colour, ground, depth, terrainFbo, rgba, decals, pick, decalFbo, bytes };
    return this.targets;
  }

  freeTargets() {
    const t = this.targets;
    if (!t) return;
    const gl = this.gl;
    for (const x of [t.colour, t.ground, t.rgba, t.decals, t.pick]) gl.deleteTexture(x);
    gl.deleteRenderbuffer(t.depth);
    gl.deleteFramebuffer(t.terrainFbo);
    gl.deleteFramebuffer(t.decalFbo);
    this.gpuBytes -= t.bytes;
    this.targets = null;
  }

  /**
   * As index.js Renderer.renderFrame. present: the frame is shown on the
   * canvas (blitted to its WebGL2 drawing buffer). passTimes: the wall time
   * of each pass, waited for alone ("wall"; this renderer asks for no timer
   * queries).
   * @param {import("./index.js").FrameArgs} args
   * @returns {Promise<import("./index.js").FrameResult>}
   */
  renderFrame(args) {
    // One frame at a time (as index.js Renderer.renderFrame).
    const run = this.frameChain.then(() => this.renderFrameNow(args));
    this.frameChain = run.catch(() => {});
    return run;
  }

  /**
   * renderFrame, the frame before it done.
   * @param {import("./index.js").FrameArgs} args
   * @returns {Promise<import("./index.js").FrameResult>}
   */
  async renderFrameNow({ camera, width, height, albedo, decals, present, readback, pick, passTimes, tiles }) {
    const scene = this.scene;
    if (!scene) throw new Error("renderFrame: no scene (call setScene first)");
    const gl = this.gl;
    if (gl.isContextLost()) throw new Error("renderFrame: the WebGL2 context was lost");
    const t0 = performance.now();
    const W = width, H = height;
    const T = this.targetsFor(W, H);
    const px = pick ? Math.floor(pick[0]) : -1, py = pick ? Math.floor(pick[1]) : -1;
    const picking = px >= 0 && py >= 0 && px < W && py < H;
    const show = Boolean(present && this.canvas);
    const pickOnly = picking && readback === false && !decals && !show;
    const terrain = /** @type {import("./index.js").Terrain} */ (this.terrain);
    const u = frameUniforms({ scene, terrain, camera, W, H, albedo, pick: picking ? [px, py] : null, pickOnly });
    // A tileset: a pass without decals over the frame (clip mode 2), then
    // one per square of each tile, scissored to its box (frame.js tileFrames).
    /** @type {{frame: ArrayBuffer, box: number[], key: string, go: number[]}[]} */
    const passes = [{ frame: u.frame, box: [0, 0, W, H], key: "blobs", go: [0, 0] }];
    this.uploads = 0;
    if (this.tileset) {
      new Uint32Array(u.frame)[102] = 2;
      const list = tiles ?? [];
      const scenes = await this.tileScenes(list);
      const f = { camera, terrain, W, H, albedo, pick: picking ? [px, py] : null, pickOnly, vp: u.vp, ax: u.ax, ay: u.ay };
      list.forEach((t, k) => {
        for (const { frame, box, go } of tileFrames(t, scenes[k], f)) passes.push({ frame, box, key: `tile:${t.key}`, go });
      });
    }
    const probe = new Uint8Array(4);
    /** @type {number[]} */
    const wall = [];
    let mark = performance.now();
    // A pass's wall time: a one-pixel read waits for it.
    const passDone = (/** @type {WebGLFramebuffer | null} */ fbo) => {
      if (!passTimes) return;
      gl.bindFramebuffer(gl.READ_FRAMEBUFFER, fbo);
      gl.readBuffer(gl.COLOR_ATTACHMENT0);
      gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, probe);
      const now = performance.now();
      wall.push(now - mark);
      mark = now;
    };

    // The terrain pass.
    const mesh = this.meshFor(u.ax, u.ay);
    gl.bindFramebuffer(gl.DRAW_FRAMEBUFFER, T.terrainFbo);
    gl.viewport(0, 0, W, H);
    gl.disable(gl.SCISSOR_TEST);
    gl.disable(gl.BLEND);
    gl.disable(gl.CULL_FACE);
    gl.drawBuffers([gl.COLOR_ATTACHMENT0, gl.COLOR_ATTACHMENT1]);
    gl.clearBufferfv(gl.COLOR, 0, [0.8, 0.86, 0.93, 1]);
    gl.clearBufferuiv(gl.COLOR, 1, [0, 0, 0, 0]);
    gl.depthMask(true);
    gl.clearBufferfv(gl.DEPTH, 0, [0]);
    gl.enable(gl.DEPTH_TEST);
    gl.depthFunc(gl.GREATER);
    gl.useProgram(this.terrainProgram);
    gl.bindBuffer(gl.UNIFORM_BUFFER, this.terrainUbo);
    gl.bufferData(gl.UNIFORM_BUFFER, u.terrainUniform, gl.DYNAMIC_DRAW);
    gl.bindBufferBase(gl.UNIFORM_BUFFER, 0, this.terrainUbo);
    gl.bindVertexArray(mesh.vao);
    gl.drawElements(gl.TRIANGLES, mesh.count, gl.UNSIGNED_INT, 0);
    gl.bindVertexArray(null);
    gl.disable(gl.DEPTH_TEST);
    passDone(T.terrainFbo);

    // The decal query and the composite, one fragment per pixel (a
    // pick-only frame: the pick's pixel alone).
    gl.bindFramebuffer(gl.DRAW_FRAMEBUFFER, T.decalFbo);
    gl.useProgram(this.decalProgram);
    gl.uniform4ui(this.linLocation, this.lin.ws, this.lin.ls, this.visBits.length, 0);
    const units = [["blobs", gl.TEXTURE_2D_ARRAY], ["heights", gl.TEXTURE_2D_ARRAY], ["grads", gl.TEXTURE_2D_ARRAY],
      ["vis", gl.TEXTURE_2D_ARRAY], [T.ground, gl.TEXTURE_2D], [T.colour, gl.TEXTURE_2D]];
    units.forEach(([what, target], unit) => {
      gl.activeTexture(gl.TEXTURE0 + unit);
      const tex = typeof what === "string" ? /** @type {{tex: WebGLTexture}} */ (this.data.get(what)).tex : what;
      gl.bindTexture(/** @type {number} */ (target), /** @type {WebGLTexture} */ (tex));
    });
    gl.activeTexture(gl.TEXTURE0);
    if (picking) {
      gl.drawBuffers([gl.NONE, gl.NONE, gl.COLOR_ATTACHMENT2]);
      gl.clearBufferuiv(gl.COLOR, 2, [0, 0, 0, 0]);
    }
    gl.drawBuffers(pickOnly ? [gl.NONE, gl.NONE, gl.COLOR_ATTACHMENT2]
      : [gl.COLOR_ATTACHMENT0, gl.COLOR_ATTACHMENT1, picking ? gl.COLOR_ATTACHMENT2 : gl.NONE]);
    gl.enable(gl.SCISSOR_TEST);
    // A tileset's pick: the tile whose pass first writes a decal at the
    // pick pixel (each pixel is drawn by one tile square at most).
    let pickTile = "";
    const pickProbe = new Uint32Array(4);
    for (const p of passes) {
      // Rows count from the image's top (the terrain pass drew it upside down).
      const b = pickOnly ? [Math.max(px, p.box[0]), Math.max(py, p.box[1]), Math.min(px + 1, p.box[2]),
        Math.min(py + 1, p.box[3])] : p.box;
      if (b[2] <= b[0] || b[3] <= b[1]) continue;
      gl.scissor(b[0], b[1], b[2] - b[0], b[3] - b[1]);
      gl.bindBuffer(gl.UNIFORM_BUFFER, this.frameUbo);
      gl.bufferData(gl.UNIFORM_BUFFER, new Uint8Array(p.frame), gl.DYNAMIC_DRAW);
      gl.bindBufferBase(gl.UNIFORM_BUFFER, 1, this.frameUbo);
      gl.activeTexture(gl.TEXTURE0);
      gl.bindTexture(gl.TEXTURE_2D_ARRAY, /** @type {{tex: WebGLTexture}} */ (this.data.get(p.key)).tex);
      gl.uniform2f(this.goLocation, p.go[0], p.go[1]);
      gl.drawArrays(gl.TRIANGLES, 0, 3);
      if (picking && this.tileset && !pickTile && p.key.startsWith("tile:") &&
          px >= b[0] && px < b[2] && py >= b[1] && py < b[3]) {
        gl.bindFramebuffer(gl.READ_FRAMEBUFFER, T.decalFbo);
        gl.readBuffer(gl.COLOR_ATTACHMENT2);
        gl.readPixels(px, py, 1, 1, gl.RGBA_INTEGER, gl.UNSIGNED_INT, pickProbe);
        if (pickProbe[0] !== 0) pickTile = p.key.slice(5);
      }
    }
    gl.disable(gl.SCISSOR_TEST);
    passDone(T.decalFbo);

    // Wait for the frame (a one-pixel read) before timing it, as the WebGPU
    // renderer times up to the queue done, read-back not included.
    gl.bindFramebuffer(gl.READ_FRAMEBUFFER, T.decalFbo);
    gl.readBuffer(pickOnly ? gl.COLOR_ATTACHMENT2 : gl.COLOR_ATTACHMENT0);
    if (pickOnly) gl.readPixels(px, py, 1, 1, gl.RGBA_INTEGER, gl.UNSIGNED_INT, new Uint32Array(4));
    else gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, probe);
    const ms = performance.now() - t0;
    /** @param {number} attachment */
    const read = (attachment) => {
      const out = new Uint8Array(4 * W * H);
      gl.readBuffer(attachment);
      gl.readPixels(0, 0, W, H, gl.RGBA, gl.UNSIGNED_BYTE, out);
      return out;
    };
    const rgba = readback !== false && !pickOnly ? read(gl.COLOR_ATTACHMENT0) : null;
    const decalPixels = decals ? read(gl.COLOR_ATTACHMENT1) : null;
    /** @type {import("./index.js").Pick | null} */
    let top = null;
    if (picking) {
      const p = new Uint32Array(4);
      gl.readBuffer(gl.COLOR_ATTACHMENT2);
      gl.readPixels(px, py, 1, 1, gl.RGBA_INTEGER, gl.UNSIGNED_INT, p);
      if (p[0] !== 0) top = { kind: p[0] === 1 ? "line" : "polygon", layer: p[1], feature: p[2], index: p[3] };
      if (top && this.tileset) top.tile = pickTile;
    }
    if (show) this.present(T, W, H);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    /** @type {import("./index.js").PassTimes | null} */
    const times = passTimes ? { timing: "wall", terrain: wall[0], decals: wall[1], dynamic: 0, composite: 0 } : null;
    return { rgba, decals: decalPixels, ms, pick: top, passes: times, dynamic: null, uploads: this.uploads };
  }

  /** Shows the frame on the canvas, its rows flipped back. @param {any} T @param {number} W @param {number} H */
  present(T, W, H) {
    const gl = this.gl;
    const canvas = /** @type {HTMLCanvasElement} */ (this.canvas);
    if (canvas.width !== W || canvas.height !== H) {
      canvas.width = W;
      canvas.height = H;
    }
    gl.bindFramebuffer(gl.READ_FRAMEBUFFER, T.decalFbo);
    gl.readBuffer(gl.COLOR_ATTACHMENT0);
    gl.bindFramebuffer(gl.DRAW_FRAMEBUFFER, null);
    gl.blitFramebuffer(0, 0, W, H, 0, H, W, 0, gl.COLOR_BUFFER_BIT, gl.NEAREST);
  }

  destroy() {
    this.destroyed = true;
    this.freeTiles();
    this.freeTargets();
    this.freeMesh();
    for (const key of [...this.data.keys()]) this.freeData(key);
    const gl = this.gl;
    gl.deleteProgram(this.terrainProgram);
    gl.deleteProgram(this.decalProgram);
    gl.deleteBuffer(this.terrainUbo);
    gl.deleteBuffer(this.frameUbo);
    gl.getExtension("WEBGL_lose_context")?.loseContext();
  }
}
