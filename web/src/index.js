// index.js — the public API of the browser reader of decalprep packages and
// tilesets (formats/SPEC.md). See web/README.md.
export { FormatError } from "./errors.js";
export { Package, openPackage, openPackageUrl } from "./package.js";
export { bufferSource, urlSource } from "./source.js";
export { parseTileset, fetchTileset, openTile, MAX_TILESET_BYTES } from "./tileset.js";
export { xxh64, xxh64Sync, hex64 } from "./xxh64.js";
export * from "./format.js";
export { createRenderer, flatTerrain, Renderer, topdownCamera } from "./render/index.js";
// LOCALIS LOD at draw time: the visibility rule in a compute pass.
export { LodSelector, lodView } from "./render/lod.js";
// Terrain files (formats/SPEC.md "Terrain files"): the mesh render draws.
export { parseTerrain, fetchTerrain } from "./terrain.js";
// Tilesets streamed: the tiles a view draws (render's rule), fetched in the
// background and held by a cache, as the renderer's frame tiles.
export { selectTiles } from "./tile_select.js";
export { TileCache } from "./tile_cache.js";
export { TileStream } from "./tile_stream.js";
