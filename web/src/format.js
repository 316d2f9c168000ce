// format.js — the constants of the .decals package format, transcribed from
// formats/SPEC.md ("Magic number", "File header", "Element types", "Codecs",
// "Blob catalogue", "Records").

/** The 8 magic bytes (SPEC "Magic number"). */
export const MAGIC = Uint8Array.of(0x89, 0x44, 0x43, 0x4c, 0x0d, 0x0a, 0x1a, 0x0a);

/** The version this reader implements. */
export const VERSION_MAJOR = 1;
export const VERSION_MINOR = 3;

/** Header and table entry sizes of v1.0–1.3 (the minimum a file may use). */
export const HEADER_SIZE = 96;
export const ENTRY_SIZE = 96;

/** Blob placement alignment (SPEC "Blobs, alignment and padding"). */
export const ALIGN = 256;

/** Largest metadata chunk a reader accepts (SPEC "Metadata"). */
export const MAX_METADATA_BYTES = 16 * 1024 * 1024;

/** Flag bits (SPEC "Flags"). */
export const FLAG_ALL_UNCOMPRESSED = 1 << 16;
export const REQUIRED_FLAGS_MASK = 0xffff;

/** Codecs (SPEC "Codecs"). */
export const CODEC_NONE = 0;
export const CODEC_ZSTD = 1;

/** `LodSegment` generator/splitter meaning "none" (SPEC "LodSegment"). */
export const LOD_NONE = 0xffffffff;

/**
 * Element types: value -> [name, components, component kind, std430 stride]
 * (stride 0 for `record`, whose stride the blob id gives).
 * @type {ReadonlyMap<number, {name: string, components: number, kind: "u8"|"u32"|"i32"|"f32"|"record", stride: number}>}
 */
export const ELEMENT_TYPES = new Map([
  [1, { name: "u8", components: 1, kind: "u8", stride: 1 }],
  [2, { name: "u32", components: 1, kind: "u32", stride: 4 }],
  [3, { name: "i32", components: 1, kind: "i32", stride: 4 }],
  [4, { name: "f32", components: 1, kind: "f32", stride: 4 }],
  [5, { name: "ivec2", components: 2, kind: "i32", stride: 8 }],
  [6, { name: "uvec2", components: 2, kind: "u32", stride: 8 }],
  [7, { name: "ivec4", components: 4, kind: "i32", stride: 16 }],
  [8, { name: "uvec4", components: 4, kind: "u32", stride: 16 }],
  [9, { name: "vec2", components: 2, kind: "f32", stride: 8 }],
  [10, { name: "vec4", components: 4, kind: "f32", stride: 16 }],
  [11, { name: "record", components: 0, kind: "record", stride: 0 }],
]);
export const RECORD_TYPE = 11;

/**
 * One row of the blob catalogue.
 * @typedef {{id: number, name: string, type: number, stride: number, record?: string}} CatalogueRow
 */

/** @type {CatalogueRow[]} SPEC "Blob catalogue", in its order. */
const ROWS = [
  { id: 1, name: "line_vertices", type: 5, stride: 8 },
  { id: 2, name: "line_vertex_line", type: 2, stride: 4 },
  { id: 3, name: "line_props", type: 11, stride: 32, record: "LineProps" },
  { id: 4, name: "line_corners", type: 11, stride: 24, record: "LineCorner" },
  { id: 5, name: "cell_segment_range", type: 6, stride: 8 },
  { id: 6, name: "cell_segments", type: 6, stride: 8 },
  { id: 7, name: "cell_line_first", type: 6, stride: 8 },
  { id: 10, name: "poly_props", type: 11, stride: 32, record: "PolyProps" },
  { id: 11, name: "poly_root_node", type: 2, stride: 4 },
  { id: 12, name: "qt_node_box", type: 7, stride: 16 },
  { id: 13, name: "qt_node", type: 5, stride: 8 },
  { id: 14, name: "qt_leaf_range", type: 6, stride: 8 },
  { id: 15, name: "qt_leaf_segments", type: 6, stride: 8 },
  { id: 16, name: "qt_leaf_vertices", type: 5, stride: 8 },
  { id: 17, name: "cell_poly_range", type: 6, stride: 8 },
  { id: 18, name: "cell_polys", type: 8, stride: 16 },
  { id: 19, name: "cell_holes", type: 6, stride: 8 },
  { id: 20, name: "line_bvh_range", type: 8, stride: 16 },
  { id: 21, name: "line_bvh_box", type: 7, stride: 16 },
  { id: 22, name: "poly_bvh_range", type: 8, stride: 16 },
  { id: 23, name: "poly_bvh_box", type: 7, stride: 16 },
  { id: 24, name: "qt_leaf_loop_range", type: 6, stride: 8 },
  { id: 25, name: "qt_leaf_loops", type: 2, stride: 4 },
  { id: 26, name: "cell_poly_first", type: 6, stride: 8 },
  { id: 27, name: "line_bvh_box16", type: 6, stride: 8 },
  { id: 28, name: "poly_bvh_box16", type: 6, stride: 8 },
  { id: 29, name: "cell_poly_entries", type: 6, stride: 8 },
  { id: 9, name: "cell_poly_holes", type: 2, stride: 4 },
  { id: 30, name: "dyn_vertices", type: 7, stride: 16 },
  { id: 31, name: "dyn_prev_next", type: 5, stride: 8 },
  { id: 32, name: "dyn_line_start", type: 2, stride: 4 },
  { id: 33, name: "dyn_line_props", type: 11, stride: 32, record: "LineProps" },
  { id: 40, name: "lod_points", type: 11, stride: 32, record: "LodPoint" },
  { id: 41, name: "lod_segments", type: 11, stride: 16, record: "LodSegment" },
  { id: 42, name: "lod_line_range", type: 6, stride: 8 },
  { id: 50, name: "manifest_entries", type: 1, stride: 1 },
];

/** @type {ReadonlyMap<number, CatalogueRow>} catalogue rows by id */
export const CATALOGUE = new Map(ROWS.map((r) => [r.id, r]));
/** @type {ReadonlyMap<string, CatalogueRow>} catalogue rows by name */
export const CATALOGUE_BY_NAME = new Map(ROWS.map((r) => [r.name, r]));

/** Positions in quanta of this many metres (SPEC "Coordinates"). */
export const QUANTUM_M = 0.001;
