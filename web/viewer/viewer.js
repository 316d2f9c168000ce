// viewer.js — the placeholder viewer page: asks the server what it serves
// (/config.json), loads it with the reader (web/src) and prints its
// summary. The renderer comes later.
import { fetchTileset, hex64, openPackageUrl, openTile } from "../src/index.js";

const statusEl = /** @type {HTMLElement} */ (document.getElementById("status"));
const summaryEl = /** @type {HTMLElement} */ (document.getElementById("summary"));

/** @param {string} line */
function print(line) {
  summaryEl.textContent += line + "\n";
}

/**
 * Prints a package's header, metadata summary and blob table.
 * @param {import("../src/package.js").Package} pkg
 */
function printPackage(pkg) {
  const meta = pkg.metadata;
  print(`${pkg.label}: decals ${pkg.major}.${pkg.minor}, ${pkg.fileSize} bytes, ${pkg.blobs.length} blobs`);
  if (meta && typeof meta === "object") {
    if (typeof meta.frame === "string") print(`frame   ${meta.frame}`);
    if (Array.isArray(meta.extent)) print(`extent  ${meta.extent.join(", ")} m`);
    if (meta.grid && Array.isArray(meta.grid.dims)) print(`grid    ${meta.grid.dims.join(" x ")} cells`);
  }
  for (const b of pkg.blobs)
    print(`  ${b.name.padEnd(20)} ${b.typeName.padEnd(7)} ${String(b.count).padStart(9)} ` +
          `${b.codec === 1 ? "zstd" : "none"} ${hex64(b.checksum)}`);
}

async function main() {
  const res = await fetch("/config.json");
  if (!res.ok) throw new Error(`/config.json: HTTP ${res.status}`);
  /** @type {{kind: string, url: string}} */
  const config = await res.json();
  const url = new URL(config.url, location.href).href;
  if (config.kind === "package") {
    const pkg = await openPackageUrl(url);
    printPackage(pkg);
    await pkg.validate();
    statusEl.textContent = `Package ${config.url}: verified (every checksum and index)`;
  } else {
    const ts = await fetchTileset(url);
    print(`${config.url}: tileset ${ts.major}.${ts.minor}, ${ts.tiles.length} tiles of ` +
          `${ts.tileSize} m, ${ts.levels.length} overview levels`);
    for (const t of ts.tiles) print(`  ${t.file} ${t.bytes} bytes`);
    if (ts.tiles.length > 0) {
      const pkg = await openTile(new URL(".", url).href, ts.tiles[0]);
      printPackage(pkg);
      await pkg.validate();
    }
    statusEl.textContent = `Tileset ${config.url}: index checked`;
  }
  document.title = `decalprep view: ${config.url}`;
}

main().catch((e) => {
  statusEl.textContent = `Error: ${e instanceof Error ? e.message : String(e)}`;
  statusEl.className = "error";
  console.error(e);
});
