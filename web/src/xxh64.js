// xxh64.js — XXH64 with seed 0 (formats/SPEC.md "Conventions"), through
// xxhash-wasm, instantiated once.
import xxhash from "xxhash-wasm";

/** @type {Promise<import("xxhash-wasm").XXHashAPI> | null} */
let api = null;

/**
 * XXH64 (seed 0) of `bytes`.
 * @param {Uint8Array} bytes
 * @returns {Promise<bigint>}
 */
export async function xxh64(bytes) {
  api ??= xxhash();
  return (await api).h64Raw(bytes, 0n);
}

/**
 * A 64-bit value as 16 lowercase hex digits.
 * @param {bigint} v
 */
export function hex64(v) {
  return v.toString(16).padStart(16, "0");
}
