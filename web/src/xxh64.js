// xxh64.js — XXH64 with seed 0 (formats/SPEC.md "Conventions"), through
// xxhash-wasm, instantiated once when the module loads.
import xxhash from "xxhash-wasm";

// Instantiated once, when the module loads; after that it hashes
// synchronously.
const { h64Raw } = await xxhash();

/**
 * XXH64 (seed 0) of `bytes`, synchronously.
 * @param {Uint8Array} bytes
 * @returns {bigint}
 */
export function xxh64Sync(bytes) {
  return h64Raw(bytes, 0n);
}

/**
 * XXH64 (seed 0) of `bytes` (the readers' asynchronous form).
 * @param {Uint8Array} bytes
 * @returns {Promise<bigint>}
 */
export async function xxh64(bytes) {
  return xxh64Sync(bytes);
}

/**
 * A 64-bit value as 16 lowercase hex digits.
 * @param {bigint} v
 */
export function hex64(v) {
  return v.toString(16).padStart(16, "0");
}
