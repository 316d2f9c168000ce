// ui.js — the viewer's panels: the layer list (a visibility toggle per entry
// of the package metadata's layer table), the overlay (frame time, GPU
// bytes, tiles drawn), the picked decal and the status line.

const el = (/** @type {string} */ id) => /** @type {HTMLElement} */ (document.getElementById(id));

/**
 * Shows `text` in the status panel; an error in red. Empty text hides it.
 * @param {string} text
 * @param {boolean} [isError]
 */
export function showStatus(text, isError = false) {
  const s = el("status");
  s.textContent = text;
  s.className = "panel" + (isError ? " error" : "") + (text ? "" : " hidden");
}

/**
 * Each layer of a package's metadata layer table, in table order: its name
 * ("" for an entry without one, as prep::render::layer_names) and its kind
 * as `render --only` counts it: "dynamic" (a dynamic line), "polygons" (a
 * polygon layer) or "lines" (static lines and outlines).
 * @param {unknown} metadata
 * @returns {{name: string, kind: "polygons" | "lines" | "dynamic"}[]}
 */
export function layerKinds(metadata) {
  const layers = metadata && typeof metadata === "object" ? /** @type {any} */ (metadata).layers : null;
  if (!Array.isArray(layers)) return [];
  return layers.map((l) => ({
    name: l && typeof l === "object" && typeof l.name === "string" ? l.name : "",
    kind: l?.dynamic === true ? "dynamic" : l?.kind === "polygon" ? "polygons" : "lines",
  }));
}

/**
 * Fills the layer list: one checkbox per layer, calling `toggle(index,
 * visible)` when it changes.
 * @param {string[]} names
 * @param {(index: number, visible: boolean) => void} toggle
 */
export function showLayers(names, toggle) {
  const box = el("layers");
  box.replaceChildren();
  names.forEach((name, i) => {
    const label = document.createElement("label");
    const check = document.createElement("input");
    check.type = "checkbox";
    check.checked = true;
    check.addEventListener("change", () => toggle(i, check.checked));
    label.append(check, " ", name || `layer ${i}`);
    box.append(label);
  });
  box.classList.toggle("hidden", names.length === 0);
}

/**
 * The overlay's figures.
 * @param {{ms: number, gpuBytes: number, tiles: number, width: number, height: number, adapter: string,
 *          limits?: string}} f  limits: the backend and what it cannot draw
 */
export function showOverlay(f) {
  const o = el("overlay");
  o.textContent = `${f.ms.toFixed(1)} ms  ${f.width}x${f.height}\n` +
    `${(f.gpuBytes / 1048576).toFixed(1)} MiB GPU  ${f.tiles} tile${f.tiles === 1 ? "" : "s"}\n${f.adapter}` +
    (f.limits ? `\n${f.limits}` : "");
  o.classList.remove("hidden");
}

/**
 * What a click found, in words: the layer (its name and index in the
 * metadata layer table), the source feature id and the kind.
 * @param {import("../src/render/index.js").Pick | null} pick
 * @param {string[]} names  the layer table's names
 */
export function describePick(pick, names) {
  if (!pick) return "no decal here";
  const name = names[pick.layer] || `layer ${pick.layer}`;
  return `${name} (layer ${pick.layer}): fid ${pick.feature}, ${pick.kind}${pick.tile ? `, tile ${pick.tile}` : ""}`;
}

/** Shows a picked decal's description in the pick panel. @param {string} text */
export function showPick(text) {
  const o = el("pick");
  o.textContent = text;
  o.classList.remove("hidden");
}
