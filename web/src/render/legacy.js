// legacy.js — the v1.0–1.2 per-cell ranges, BVH boxes, exterior entries
// and leaf segments encoded to the v1.3 layout the decal pass reads
// (formats/SPEC.md "Compact layout (v1.3)"), exactly as
// formats/gl/src/loader.cpp encode_v13 does with decal/layout.hpp
// (formats/src/layout.cpp): encode_cells, encode_boxes16,
// encode_poly_entries, encode_leaves. Inputs are a validated package's
// blobs; what cannot be encoded throws an Error naming the blob.

/**
 * @typedef {{gx: number, gy: number, cw: number, ch: number, nx: number, ny: number}} Grid
 * @typedef {(name: string) => Uint32Array} Blob  a blob's words (empty when absent)
 */

/** u16 box step shift (layout.cpp box16_shift). @param {number} cw @param {number} ch */
export function box16Shift(cw, ch) {
  const side = Math.max(cw, ch);
  let s = 0;
  while (s < 31 && side + 2 * 2 ** s > 65535 * 2 ** s) ++s;
  return s;
}

/**
 * layout.cpp encode_cells: v1.2 per-cell (first, count) ranges and
 * (first node, leaf slots, internal nodes, 0) trees -> v1.3 firsts (cells + 1
 * pairs), and the list and boxes copied in cell order when the cells' lists
 * or trees do not already follow each other (else null: keep the input's).
 * first is null when no cell holds an entry (the kind is absent).
 * @param {Uint32Array} range @param {Uint32Array} bvh
 * @param {Uint32Array} list @param {number} listWords @param {Uint32Array} boxes
 * @param {string} what  for messages
 */
export function encodeCells(range, bvh, list, listWords, boxes, what) {
  const cells = range.length / 2;
  const listN = list.length / listWords, boxN = boxes.length / 4;
  if (bvh.length / 4 !== cells) throw new Error(`${what}: BVH ranges and cell ranges differ in count`);
  let inOrder = true, entries = 0, nodes = 0;
  for (let c = 0; c < cells; ++c) {
    const n = range[2 * c + 1], p = bvh[4 * c + 1];
    const tree = n ? p + bvh[4 * c + 2] : 0;
    // The v1.2 constraints (a full tree inside the boxes, the list inside its blob).
    if (range[2 * c] + n > listN ||
        (n && (bvh[4 * c] + tree > boxN || (p & (p - 1)) !== 0 || p < n || bvh[4 * c + 2] + 1 !== p)))
      throw new Error(`${what}: per-cell ranges break the index constraints (cell ${c})`);
    if (range[2 * c] !== entries || (n && bvh[4 * c] !== nodes)) inOrder = false;
    entries += n;
    nodes += tree;
  }
  if (entries === 0) return { first: null, list: null, boxes: null };
  const first = new Uint32Array(2 * (cells + 1));
  if (inOrder && entries === listN && nodes === boxN) {
    let fx = 0, fy = 0;
    for (let c = 0; c < cells; ++c) {
      first[2 * c] = fx;
      first[2 * c + 1] = fy;
      const n = range[2 * c + 1];
      fx += n;
      fy += n ? bvh[4 * c + 1] + bvh[4 * c + 2] : 0;
    }
    first[2 * cells] = fx;
    first[2 * cells + 1] = fy;
    return { first, list: null, boxes: null };
  }
  const outList = new Uint32Array(entries * listWords), outBoxes = new Uint32Array(nodes * 4);
  let fx = 0, fy = 0;
  for (let c = 0; c < cells; ++c) {
    first[2 * c] = fx;
    first[2 * c + 1] = fy;
    const n = range[2 * c + 1];
    if (n === 0) continue;
    const tree = bvh[4 * c + 1] + bvh[4 * c + 2];
    outList.set(list.subarray(range[2 * c] * listWords, (range[2 * c] + n) * listWords), fx * listWords);
    outBoxes.set(boxes.subarray(bvh[4 * c] * 4, (bvh[4 * c] + tree) * 4), fy * 4);
    fx += n;
    fy += tree;
  }
  first[2 * cells] = fx;
  first[2 * cells + 1] = fy;
  return { first, list: outList, boxes: outBoxes };
}

/**
 * layout.cpp encode_boxes16: ivec4 boxes (quanta) of the nodes of each cell
 * -> u16 boxes in steps of 2^s from the cell's base corner.
 * @param {Uint32Array} first  v1.3 firsts @param {Int32Array} boxes @param {Grid} g
 */
export function encodeBoxes16(first, boxes, g) {
  const n = boxes.length / 4;
  const out = new Uint32Array(2 * n);
  for (let i = 0; i < n; ++i) out[2 * i] = 65535;  // empty: (0xFFFF, 0)
  const s = box16Shift(g.cw, g.ch), step = 2 ** s;
  const topX = Math.floor((g.cw + 3 * step - 1) / step), topY = Math.floor((g.ch + 3 * step - 1) / step);
  const clamp16 = (/** @type {number} */ v) => (v < 0 ? 0 : v > 65535 ? 65535 : v);
  const cells = first.length / 2 - 1;
  for (let c = 0; c < cells; ++c) {
    const ix = g.nx ? c % g.nx : 0, iy = g.nx ? Math.floor(c / g.nx) : 0;
    const bx = g.gx + ix * g.cw - step, by = g.gy + iy * g.ch - step;
    const stop = Math.min(first[2 * c + 3], n);
    for (let i = first[2 * c + 1]; i < stop; ++i) {
      const b0 = boxes[4 * i], b1 = boxes[4 * i + 1], b2 = boxes[4 * i + 2], b3 = boxes[4 * i + 3];
      if (b0 > b2 || b1 > b3) continue;
      // floor division by the step (exact in doubles: |values| < 2^53)
      const x0 = clamp16(Math.floor((b0 - bx) / step)), y0 = clamp16(Math.floor((b1 - by) / step));
      const x1 = clamp16(Math.min(Math.floor((b2 - bx + step - 1) / step), topX));
      const y1 = clamp16(Math.min(Math.floor((b3 - by + step - 1) / step), topY));
      out[2 * i] = (x0 | (y0 << 16)) >>> 0;
      out[2 * i + 1] = (x1 | (y1 << 16)) >>> 0;
    }
  }
  return out;
}

/**
 * layout.cpp encode_poly_entries: v1.2 cell_polys (polygon, culling node,
 * first hole, hole count) -> entries (polygon, culling node), hole firsts
 * (entries + 1), and the holes copied in entry order when they do not
 * already follow each other (else null).
 * @param {Uint32Array} cellPolys @param {Uint32Array} cellHoles
 */
export function encodePolyEntries(cellPolys, cellHoles) {
  const n = cellPolys.length / 4, nh = cellHoles.length / 2;
  let inOrder = true, h = 0;
  for (let k = 0; k < n; ++k) {
    const f = cellPolys[4 * k + 2], c = cellPolys[4 * k + 3];
    if (f + c > nh) throw new Error(`cell_polys: entry ${k}'s hole range runs past cell_holes`);
    if (c && f !== h) inOrder = false;
    h += c;
  }
  inOrder = inOrder && h === nh;
  const entries = new Uint32Array(2 * n), holeFirst = new Uint32Array(n + 1);
  /** @type {number[]} */
  const holes = [];
  let at = 0;
  for (let k = 0; k < n; ++k) {
    entries[2 * k] = cellPolys[4 * k];
    entries[2 * k + 1] = cellPolys[4 * k + 1];
    holeFirst[k] = at;
    const f = cellPolys[4 * k + 2], c = cellPolys[4 * k + 3];
    if (!inOrder) for (let j = 0; j < c; ++j) holes.push(cellHoles[2 * (f + j)], cellHoles[2 * (f + j) + 1]);
    at += c;
  }
  holeFirst[n] = at;
  return { entries, holeFirst, holes: inOrder ? null : Uint32Array.from(holes) };
}

/**
 * layout.cpp encode_leaves: v1.2 leaf ranges into closed runs of
 * consecutive-vertex segments -> loop ranges and loop ends.
 * @param {Uint32Array} leafRange @param {Uint32Array} segments @param {number} vertexCount
 */
export function encodeLeaves(leafRange, segments, vertexCount) {
  const fail = () => new Error("quad-tree leaf segments are not closed runs of consecutive vertices; " +
                               "the renderer reads leaf loops only (SPEC.md \"Compact layout (v1.3)\")");
  const leaves = leafRange.length / 2, nseg = segments.length / 2;
  const loopRange = new Uint32Array(2 * leaves);
  /** @type {number[]} */
  const loopEnd = [];
  let end = 0;  // end of the last loop
  for (let r = 0; r < leaves; ++r) {
    let firstLoop = loopEnd.length;
    let s = leafRange[2 * r];
    const stop = s + leafRange[2 * r + 1];
    if (stop > nseg) throw fail();
    while (s < stop) {
      // A loop: (a, a+1), (a+1, a+2), ..., (b, a) with b >= a + 1.
      const a = segments[2 * s];
      let v = a;
      while (s < stop && segments[2 * s] === v && segments[2 * s + 1] === v + 1) {
        ++v;
        ++s;
      }
      if (s >= stop || segments[2 * s] !== v || segments[2 * s + 1] !== a || v === a) throw fail();
      ++s;
      // An orphan vertex between leaves becomes a loop of one vertex.
      if (a < end) throw fail();
      if (a > end) {
        if (a - end > 1 || loopEnd.length !== firstLoop) throw fail();
        loopEnd.push(a);
        ++firstLoop;
      }
      loopEnd.push(v + 1);
      end = v + 1;
    }
    loopRange[2 * r] = firstLoop;
    loopRange[2 * r + 1] = loopEnd.length - firstLoop;
  }
  if (end > vertexCount) throw fail();
  return { loopRange, loopEnd: Uint32Array.from(loopEnd) };
}

/**
 * Replaces, in `arrays` (the decal pass's blobs by name), what a pre-v1.3
 * package stores in the older layout (loader.cpp encode_v13): the lines'
 * and polygons' per-cell ranges and BVH boxes, the exterior entries and
 * the leaf segments. A v1.3 package is left as it is.
 * @param {Blob} blob  the package's blob words by name
 * @param {Map<string, Uint32Array>} arrays
 * @param {Grid} grid
 * @param {string} label  the package, for messages
 */
export function encodeLegacy(blob, arrays, grid, label) {
  const has = (/** @type {string} */ name) => blob(name).length > 0;
  const cells = (/** @type {string} */ range, /** @type {string} */ bvh, /** @type {string} */ list,
                 /** @type {number} */ listWords, /** @type {string} */ box, /** @type {string} */ first,
                 /** @type {string} */ box16) => {
    if (!has(range)) return null;
    const e = encodeCells(blob(range), blob(bvh), blob(list), listWords, blob(box), `${label}: ${range}`);
    if (!e.first) {  // no entries: the kind is absent
      arrays.set(first, new Uint32Array(0));
      arrays.set(box16, new Uint32Array(0));
      return null;
    }
    const boxes = e.boxes ?? blob(box);
    arrays.set(box16, encodeBoxes16(e.first, new Int32Array(boxes.buffer, boxes.byteOffset, boxes.length), grid));
    arrays.set(first, e.first);
    return e.list ?? blob(list);
  };
  const segs = cells("cell_segment_range", "line_bvh_range", "cell_segments", 2, "line_bvh_box",
                     "cell_line_first", "line_bvh_box16");
  if (segs) arrays.set("cell_segments", segs);
  let cellPolys = cells("cell_poly_range", "poly_bvh_range", "cell_polys", 4, "poly_bvh_box",
                        "cell_poly_first", "poly_bvh_box16");
  if (!cellPolys && has("cell_polys")) cellPolys = blob("cell_polys");
  if (cellPolys && cellPolys.length > 0) {
    const e = encodePolyEntries(cellPolys, blob("cell_holes"));
    arrays.set("cell_poly_entries", e.entries);
    arrays.set("cell_poly_holes", e.holeFirst);
    if (e.holes) arrays.set("cell_holes", e.holes);
  }
  if (has("qt_leaf_range") || has("qt_leaf_segments")) {
    const e = encodeLeaves(blob("qt_leaf_range"), blob("qt_leaf_segments"), blob("qt_leaf_vertices").length / 2);
    arrays.set("qt_leaf_loop_range", e.loopRange);
    arrays.set("qt_leaf_loops", e.loopEnd);
  }
}
