// monaco_tileset.mjs — the tileset the browser's tileset tests share
// (tile_select_test.mjs, tile_cache_test.mjs): the Monaco sample built into
// WORK/monaco as 500 m tiles with --levels auto (57 tiles and 3 overview
// levels), read back by the JavaScript reader.
import { execFileSync } from "node:child_process";
import { mkdirSync, readFileSync, rmSync } from "node:fs";
import { join } from "node:path";

/**
 * Builds the tileset (WORK is emptied first) and returns its folder and its
 * parsed index.
 * @param {string} decalprep @param {string} root @param {string} work
 */
export async function monacoTileset(decalprep, root, work) {
  const { parseTileset } = await import(join(root, "web/src/index.js"));
  rmSync(work, { recursive: true, force: true });
  mkdirSync(work, { recursive: true });
  const dir = join(work, "monaco");
  execFileSync(decalprep, ["build", join(root, "samples/monaco/scene.toml"), "-o", dir, "--tile-size", "500",
    "--levels", "auto", "-q"], { stdio: "inherit" });
  return { dir, ts: parseTileset(readFileSync(join(dir, "tileset.json"), "utf8")) };
}
