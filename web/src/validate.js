// validate.js — the checks `decalprep verify` applies after the byte-level
// checks of package.js: formats/SPEC.md "Index constraints" over the
// decoded blobs, and the metadata (SPEC "Validation": a JSON object,
// `format` = "decals" when present, `counts` agreeing with the blobs).
// Thrown errors are FormatErrors without the file name; the caller adds it.
import { FormatError } from "./errors.js";
import { CATALOGUE, LOD_NONE } from "./format.js";

/** @typedef {{count: number, bytes: Uint8Array}} Decoded */

/**
 * The decoded known blobs by id, read as little-endian words.
 */
class Blobs {
  /** @param {Map<number, Decoded>} byId */
  constructor(byId) {
    this.byId = byId;
  }
  /** @param {number} id */
  count(id) {
    return this.byId.get(id)?.count ?? 0;
  }
  /** @param {number} id */
  name(id) {
    return CATALOGUE.get(id)?.name ?? `blob_${id}`;
  }
  /**
   * A view of blob `id`'s words: u(i, k) / s(i, k) / f(i, k) is component k
   * (4 bytes) of element i as u32 / i32 / f32.
   * @param {number} id
   */
  words(id) {
    const b = this.byId.get(id);
    const bytes = b?.bytes ?? new Uint8Array(0);
    const dv = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
    const stride = CATALOGUE.get(id)?.stride ?? 4;
    return {
      n: b?.count ?? 0,
      /** @param {number} i @param {number} k */
      u: (i, k) => dv.getUint32(i * stride + 4 * k, true),
      /** @param {number} i @param {number} k */
      s: (i, k) => dv.getInt32(i * stride + 4 * k, true),
      /** @param {number} i @param {number} k */
      f: (i, k) => dv.getFloat32(i * stride + 4 * k, true),
    };
  }
  /** `a` and `b` have as many elements. @param {number} a @param {number} b */
  sameCount(a, b) {
    if (this.count(a) !== this.count(b))
      throw new FormatError(`${this.name(a)} has ${this.count(a)} elements but ${this.name(b)} ` +
                            `has ${this.count(b)}; they must match`);
  }
  /**
   * value < #target.
   * @param {number} blob @param {number} i @param {string} field @param {number} value
   * @param {number} target
   */
  index(blob, i, field, value, target) {
    if (value >= this.count(target))
      throw new FormatError(`${this.name(blob)}[${i}].${field} = ${value} is out of range ` +
                            `(${this.name(target)} has ${this.count(target)} elements)`);
  }
  /**
   * first + n <= #target.
   * @param {number} blob @param {number} i @param {number} first @param {number} n
   * @param {number} target
   */
  range(blob, i, first, n, target) {
    if (first + n > this.count(target))
      throw new FormatError(`${this.name(blob)}[${i}] = (first ${first}, count ${n}) runs past ` +
                            `the end of ${this.name(target)} (${this.count(target)} elements)`);
  }
  /**
   * Every element of `blob` is a (first, count) range within `target`.
   * @param {number} blob @param {number} target
   */
  ranges(blob, target) {
    const r = this.words(blob);
    for (let i = 0; i < r.n; ++i) this.range(blob, i, r.u(i, 0), r.u(i, 1), target);
  }
  /**
   * Every element of `blob` is a (start, end) segment of vertices of `target`.
   * @param {number} blob @param {number} target
   */
  segments(blob, target) {
    const s = this.words(blob);
    for (let i = 0; i < s.n; ++i) {
      this.index(blob, i, "start", s.u(i, 0), target);
      this.index(blob, i, "end", s.u(i, 1), target);
    }
  }
}

// Blob ids (SPEC "Blob catalogue").
const B = {
  line_vertices: 1, line_vertex_line: 2, line_props: 3, line_corners: 4,
  cell_segment_range: 5, cell_segments: 6, cell_line_first: 7, cell_poly_holes: 9,
  poly_props: 10, poly_root_node: 11, qt_node_box: 12, qt_node: 13, qt_leaf_range: 14,
  qt_leaf_segments: 15, qt_leaf_vertices: 16, cell_poly_range: 17, cell_polys: 18,
  cell_holes: 19, line_bvh_range: 20, line_bvh_box: 21, poly_bvh_range: 22, poly_bvh_box: 23,
  qt_leaf_loop_range: 24, qt_leaf_loops: 25, cell_poly_first: 26, line_bvh_box16: 27,
  poly_bvh_box16: 28, cell_poly_entries: 29, dyn_vertices: 30, dyn_prev_next: 31,
  dyn_line_start: 32, dyn_line_props: 33, lod_points: 40, lod_segments: 41, lod_line_range: 42,
};

/** @param {number} x */
const isPow2 = (x) => x > 0 && Math.log2(x) % 1 === 0;

/**
 * SPEC "Index constraints". `newerMinor`: the file's minor version is newer
 * than the reader's, so reserved record fields may carry a meaning.
 * @param {Map<number, Decoded>} byId  decoded bytes of the known blobs
 * @param {boolean} newerMinor
 */
export function checkIndices(byId, newerMinor) {
  const c = new Blobs(byId);
  for (const [id, b] of byId) {
    const stride = CATALOGUE.get(id)?.stride ?? 1;
    if (b.bytes.length !== b.count * stride)
      throw new FormatError(`blob ${c.name(id)} holds ${b.bytes.length} bytes for ${b.count} ` +
                            `elements of ${stride} bytes`);
  }
  checkLines(c, newerMinor);
  checkPolygons(c, newerMinor);
  checkCells(c, B.cell_segment_range, B.cell_segments, B.line_bvh_range, B.line_bvh_box,
             B.cell_line_first);
  checkCells(c, B.cell_poly_range, B.cell_polys, B.poly_bvh_range, B.poly_bvh_box,
             B.cell_poly_first);
  checkCellsFirst(c, B.cell_line_first, B.cell_segments, B.line_bvh_box16,
                  [B.cell_segment_range, B.line_bvh_range, B.line_bvh_box]);
  checkCellsFirst(c, B.cell_poly_first, B.cell_poly_entries, B.poly_bvh_box16,
                  [B.cell_poly_range, B.poly_bvh_range, B.poly_bvh_box]);
  checkDynamic(c, newerMinor);
  checkLod(c);
}

/** @param {Blobs} c @param {boolean} newerMinor */
function checkLines(c, newerMinor) {
  c.sameCount(B.line_vertex_line, B.line_vertices);
  c.sameCount(B.line_corners, B.line_vertices);
  const vl = c.words(B.line_vertex_line);
  for (let i = 0; i < vl.n; ++i) c.index(B.line_vertex_line, i, "line", vl.u(i, 0), B.line_props);
  const props = c.words(B.line_props);
  for (let i = 0; i < props.n; ++i) {
    const hw = props.f(i, 0);
    if (!(hw >= 0 && hw < 1e7))
      throw new FormatError(`line_props[${i}].half_width = ${hw} is not in [0, 1e7) metres`);
    const style = props.u(i, 3), clip = props.u(i, 7);
    if (style & 0x20) c.index(B.line_props, i, "clip_node", clip, B.qt_node);
    else if (clip !== 0 && !newerMinor)
      throw new FormatError(`line_props[${i}].clip_node = ${clip} without style bit 5 ` +
                            `(clipped); must be zero`);
  }
  c.ranges(B.cell_segment_range, B.cell_segments);
  c.segments(B.cell_segments, B.line_vertices);
}

/** @param {Blobs} c @param {boolean} newerMinor */
function checkPolygons(c, newerMinor) {
  c.sameCount(B.poly_root_node, B.poly_props);
  c.sameCount(B.qt_node_box, B.qt_node);
  const props = c.words(B.poly_props);
  for (let i = 0; i < props.n; ++i) {
    if ((props.u(i, 6) !== 0 || props.u(i, 7) !== 0) && !newerMinor)
      throw new FormatError(`poly_props[${i}].reserved is not zero`);
    const ext = props.s(i, 2);
    if (ext < -1 || ext >= props.n)
      throw new FormatError(`poly_props[${i}].exterior = ${ext} is out of range ` +
                            `(${props.n} polygons)`);
  }
  const roots = c.words(B.poly_root_node);
  for (let i = 0; i < roots.n; ++i) c.index(B.poly_root_node, i, "node", roots.u(i, 0), B.qt_node);
  // A partial node indexes the v1.3 loop ranges in the loop layout, the
  // v1.0–1.2 leaf ranges otherwise; a package has one layout.
  const loopLayout = c.count(B.qt_leaf_loop_range) > 0 || c.count(B.qt_leaf_loops) > 0;
  if (loopLayout && (c.count(B.qt_leaf_range) > 0 || c.count(B.qt_leaf_segments) > 0))
    throw new FormatError("qt_leaf_range/qt_leaf_segments (v1.2 layout) and " +
                          "qt_leaf_loop_range/qt_leaf_loops (v1.3) are both present");
  const leafBlob = loopLayout ? B.qt_leaf_loop_range : B.qt_leaf_range;
  const nodes = c.words(B.qt_node);
  for (let i = 0; i < nodes.n; ++i) {
    const type = nodes.s(i, 0), off = nodes.s(i, 1);
    if (type < 0 || type > 3)
      throw new FormatError(`qt_node[${i}].type = ${type} is not a node type 0..3`);
    if (off < 0) throw new FormatError(`qt_node[${i}].offset = ${off} is negative`);
    if (type === 0) {
      if (off <= i)
        throw new FormatError(`qt_node[${i}].offset = ${off}: children must come after their ` +
                              `parent`);
      c.range(B.qt_node, i, off, 4, B.qt_node);
    } else if (type === 3) {
      c.index(B.qt_node, i, "offset", off, leafBlob);
    }
  }
  c.ranges(B.qt_leaf_loop_range, B.qt_leaf_loops);
  const loops = c.words(B.qt_leaf_loops);
  for (let i = 0, prev = 0; i < loops.n; prev = loops.u(i, 0), ++i) {
    const end = loops.u(i, 0);
    if (end < prev)
      throw new FormatError(`qt_leaf_loops[${i}] = ${end} is less than the previous loop's end ` +
                            `${prev}`);
    if (end > c.count(B.qt_leaf_vertices))
      throw new FormatError(`qt_leaf_loops[${i}] = ${end} runs past the end of ` +
                            `qt_leaf_vertices (${c.count(B.qt_leaf_vertices)} elements)`);
  }
  c.ranges(B.qt_leaf_range, B.qt_leaf_segments);
  c.segments(B.qt_leaf_segments, B.qt_leaf_vertices);
  checkLeafRuns(c);
  c.ranges(B.cell_poly_range, B.cell_polys);
  const cpolys = c.words(B.cell_polys);
  for (let i = 0; i < cpolys.n; ++i) {
    c.index(B.cell_polys, i, "polygon", cpolys.u(i, 0), B.poly_props);
    c.index(B.cell_polys, i, "node", cpolys.u(i, 1), B.qt_node);
    c.range(B.cell_polys, i, cpolys.u(i, 2), cpolys.u(i, 3), B.cell_holes);
  }
  const entries = c.words(B.cell_poly_entries);
  const holeFirst = c.words(B.cell_poly_holes);
  if (entries.n > 0 || holeFirst.n > 0) {
    if (cpolys.n > 0)
      throw new FormatError("cell_polys (v1.2 layout) and cell_poly_entries (v1.3) are both present");
    if (holeFirst.n !== entries.n + 1)
      throw new FormatError(`cell_poly_holes has ${holeFirst.n} elements for ${entries.n} ` +
                            `cell_poly_entries (must be entries + 1)`);
    const h0 = holeFirst.u(0, 0), hn = holeFirst.u(holeFirst.n - 1, 0);
    if (h0 !== 0 || hn !== c.count(B.cell_holes))
      throw new FormatError(`cell_poly_holes runs from ${h0} to ${hn}; it must run from 0 to ` +
                            `${c.count(B.cell_holes)} (#cell_holes)`);
    for (let i = 0; i < entries.n; ++i) {
      c.index(B.cell_poly_entries, i, "polygon", entries.u(i, 0), B.poly_props);
      c.index(B.cell_poly_entries, i, "node", entries.u(i, 1), B.qt_node);
      if (holeFirst.u(i + 1, 0) < holeFirst.u(i, 0))
        throw new FormatError(`cell_poly_holes[${i + 1}] = ${holeFirst.u(i + 1, 0)} is less ` +
                              `than cell_poly_holes[${i}] = ${holeFirst.u(i, 0)}`);
    }
  }
  const holes = c.words(B.cell_holes);
  for (let i = 0; i < holes.n; ++i) {
    c.index(B.cell_holes, i, "polygon", holes.u(i, 0), B.poly_props);
    c.index(B.cell_holes, i, "node", holes.u(i, 1), B.qt_node);
  }
}

/**
 * v1.0–1.2 leaf polygons: each leaf's segments are closed loops of
 * consecutive vertices, (a, a+1), ..., (b−1, b), (b, a) with b > a, each
 * loop starting where the previous one ended (one orphan vertex allowed
 * before a leaf's first loop), within qt_leaf_vertices: the form every
 * writer wrote and the v1.3 leaf loops express (SPEC "Compact layout
 * (v1.3)", "Leaf loops"). This rule is decalprep's (`decalprep verify`
 * refuses other segment lists); SPEC's "Index constraints" does not list it.
 * @param {Blobs} c
 */
function checkLeafRuns(c) {
  const leaves = c.words(B.qt_leaf_range), segs = c.words(B.qt_leaf_segments);
  if (leaves.n === 0) return;
  const bad = () => new FormatError("qt_leaf_segments: the segments of a leaf are not closed " +
                                    "runs of consecutive vertices (SPEC.md \"Compact layout (v1.3)\")");
  let end = 0;
  for (let r = 0; r < leaves.n; ++r) {
    let s = leaves.u(r, 0);
    const stop = s + leaves.u(r, 1);
    if (stop > segs.n) throw bad();
    let firstLoop = true;
    while (s < stop) {
      const a = segs.u(s, 0);
      let v = a;
      while (s < stop && segs.u(s, 0) === v && segs.u(s, 1) === v + 1) {
        ++v;
        ++s;
      }
      if (s >= stop || segs.u(s, 0) !== v || segs.u(s, 1) !== a || v === a) throw bad();
      ++s;
      if (a < end) throw bad();
      if (a > end && (a - end > 1 || !firstLoop)) throw bad();
      firstLoop = false;
      end = v + 1;
    }
  }
  if (end > c.count(B.qt_leaf_vertices)) throw bad();
}

/**
 * v1.0–1.2 per-cell ranges and BVHs: (first box, leaf slots, internal
 * nodes) is a full binary tree over the cell's entries inside the box blob.
 * @param {Blobs} c @param {number} rangeId @param {number} listId @param {number} bvhId
 * @param {number} boxId @param {number} firstId
 */
function checkCells(c, rangeId, listId, bvhId, boxId, firstId) {
  const ranges = c.words(rangeId), bvh = c.words(bvhId);
  if (ranges.n === 0 && bvh.n === 0 && (c.count(listId) === 0 || c.count(firstId) > 0)) return;
  c.sameCount(bvhId, rangeId);
  const boxes = c.count(boxId);
  for (let i = 0; i < bvh.n; ++i) {
    const first = bvh.u(i, 0), slots = bvh.u(i, 1), internal = bvh.u(i, 2);
    const entries = ranges.u(i, 1);
    const full = slots === 0 ? internal === 0 : isPow2(slots) && internal + 1 === slots;
    if (slots < entries || !full || first + slots + internal > boxes)
      throw new FormatError(`${c.name(bvhId)}[${i}] = (first ${first}, leaves ${slots}, ` +
                            `internal ${internal}) is not a full binary tree over the cell's ` +
                            `${entries} entries inside ${c.name(boxId)} (${boxes} boxes)`);
  }
}

/**
 * v1.3 per-cell firsts (SPEC "Compact layout (v1.3)", "Per-cell firsts").
 * @param {Blobs} c @param {number} firstId @param {number} listId @param {number} boxId
 * @param {number[]} oldIds  the v1.2 blobs of the same kind
 */
function checkCellsFirst(c, firstId, listId, boxId, oldIds) {
  const first = c.words(firstId);
  if (first.n === 0) {
    if (c.count(boxId) > 0)
      throw new FormatError(`${c.name(boxId)} has ${c.count(boxId)} elements but ` +
                            `${c.name(firstId)} is absent`);
    return;
  }
  if (oldIds.some((id) => c.count(id) > 0))
    throw new FormatError(`${c.name(firstId)} (v1.3) and ` +
                          `${oldIds.map((id) => c.name(id)).join("/")} (v1.2 layout) are both present`);
  const x0 = first.u(0, 0), y0 = first.u(0, 1);
  const xn = first.u(first.n - 1, 0), yn = first.u(first.n - 1, 1);
  if (x0 !== 0 || y0 !== 0 || xn !== c.count(listId) || yn !== c.count(boxId))
    throw new FormatError(`${c.name(firstId)} runs from (${x0}, ${y0}) to (${xn}, ${yn}); it ` +
                          `must run from (0, 0) to (${c.count(listId)}, ${c.count(boxId)}), the ` +
                          `element counts of ${c.name(listId)} and ${c.name(boxId)}`);
  for (let i = 0; i + 1 < first.n; ++i) {
    const ax = first.u(i, 0), ay = first.u(i, 1), bx = first.u(i + 1, 0), by = first.u(i + 1, 1);
    if (bx < ax || by < ay)
      throw new FormatError(`${c.name(firstId)}[${i + 1}] = (${bx}, ${by}) is less than ` +
                            `${c.name(firstId)}[${i}] = (${ax}, ${ay})`);
    const n = bx - ax, d = by - ay, p = (d + 1) / 2;
    const full = n === 0 ? d === 0 : d % 2 === 1 && isPow2(p) && p >= n;
    if (!full)
      throw new FormatError(`${c.name(firstId)}[${i}]: ${d} nodes are not a full binary tree ` +
                            `over the cell's ${n} entries`);
  }
}

/** @param {Blobs} c @param {boolean} newerMinor */
function checkDynamic(c, newerMinor) {
  c.sameCount(B.dyn_prev_next, B.dyn_vertices);
  const verts = c.words(B.dyn_vertices);
  for (let i = 0; i < verts.n; ++i) {
    const line = verts.s(i, 3);
    if (line < 0) throw new FormatError(`dyn_vertices[${i}].line = ${line} is negative`);
    c.index(B.dyn_vertices, i, "line", line, B.dyn_line_props);
  }
  const links = c.words(B.dyn_prev_next);
  for (let i = 0; i < links.n; ++i)
    for (let k = 0; k < 2; ++k) {
      const v = links.s(i, k);
      if (v < -1 || v >= verts.n)
        throw new FormatError(`dyn_prev_next[${i}].${k === 0 ? "previous" : "next"} = ${v} is ` +
                              `out of range (${verts.n} vertices)`);
    }
  const starts = c.words(B.dyn_line_start);
  for (let i = 0; i < starts.n; ++i)
    c.index(B.dyn_line_start, i, "vertex", starts.u(i, 0), B.dyn_vertices);
  if (verts.n > 0) {
    c.sameCount(B.dyn_line_start, B.dyn_line_props);
    if (starts.n === 0 || starts.u(0, 0) !== 0)
      throw new FormatError("dyn_line_start[0] must be 0 when dynamic vertices exist");
    for (let l = 0; l < starts.n; ++l) {
      const begin = starts.u(l, 0);
      const end = l + 1 < starts.n ? starts.u(l + 1, 0) : verts.n;
      if (end <= begin)
        throw new FormatError(`dyn_line_start[${l + 1}] = ${end} does not increase`);
      for (let v = begin; v < end; ++v)
        if (verts.s(v, 3) !== l)
          throw new FormatError(`dyn_vertices[${v}].line = ${verts.s(v, 3)} lies in the run of ` +
                                `line ${l}`);
    }
  }
  const props = c.words(B.dyn_line_props);
  for (let i = 0; i < props.n; ++i)
    if (props.u(i, 7) !== 0 && !newerMinor)
      throw new FormatError(`dyn_line_props[${i}].clip_node = ${props.u(i, 7)}, must be zero ` +
                            `(dynamic lines are never clipped)`);
}

/** @param {Blobs} c */
function checkLod(c) {
  const points = c.words(B.lod_points);
  for (let i = 0; i < points.n; ++i) {
    c.index(B.lod_points, i, "line", points.u(i, 6), B.dyn_line_props);
    const flags = points.u(i, 7);
    if ((flags & ~1) !== 0)
      throw new FormatError(`lod_points[${i}].flags = ${flags}, only bit 0 may be set`);
  }
  const segs = c.words(B.lod_segments);
  for (let i = 0; i < segs.n; ++i) {
    c.index(B.lod_segments, i, "a", segs.u(i, 0), B.lod_points);
    c.index(B.lod_segments, i, "b", segs.u(i, 1), B.lod_points);
    if (segs.u(i, 2) !== LOD_NONE) c.index(B.lod_segments, i, "generator", segs.u(i, 2), B.lod_points);
    if (segs.u(i, 3) !== LOD_NONE) c.index(B.lod_segments, i, "splitter", segs.u(i, 3), B.lod_points);
  }
  c.ranges(B.lod_line_range, B.lod_segments);
}

/**
 * The metadata checks of `decalprep verify` (SPEC "Validation", "Metadata"):
 * a JSON object; `format`, when present, is "decals"; each `counts` entry
 * that names a blob of the package is a non-negative integer equal to that
 * blob's element count.
 * @param {unknown} meta  the parsed metadata
 * @param {readonly {name: string, count: number}[]} blobs
 */
export function checkMetadata(meta, blobs) {
  if (typeof meta !== "object" || meta === null || Array.isArray(meta))
    throw new FormatError("metadata is not a JSON object");
  const m = /** @type {Record<string, unknown>} */ (meta);
  if ("format" in m && m.format !== "decals")
    throw new FormatError(`metadata format is ${JSON.stringify(m.format)}, expected "decals"`);
  const counts = m.counts;
  if (typeof counts === "object" && counts !== null && !Array.isArray(counts)) {
    const cs = /** @type {Record<string, unknown>} */ (counts);
    for (const b of blobs) {
      if (!Object.prototype.hasOwnProperty.call(cs, b.name)) continue;
      const v = cs[b.name];
      if (typeof v !== "number" || !Number.isInteger(v) || v < 0 || v !== b.count)
        throw new FormatError(`metadata counts.${b.name} = ${JSON.stringify(v)} but the blob ` +
                              `has ${b.count} elements`);
    }
  }
}
