// zstd.js — one zstd frame (RFC 8878) decoded as formats/SPEC.md asks of a
// stored blob and of a terrain file's heights: exactly one frame, nothing
// after it, its Frame_Content_Size the expected size, and its content
// checksum (the low 32 bits of XXH64) when it has one.
import { decompress } from "fzstd";
import { xxh64Sync } from "./xxh64.js";

/**
 * Decodes `stored` when it is exactly one zstd frame of `raw` content
 * bytes; else throws fail(what), `what` saying the problem: say.notOne when
 * the bytes are not exactly one frame, say.size when its content size is
 * missing or not `raw`, "zstd decoding failed: ..." otherwise.
 * @param {Uint8Array} stored @param {number} raw
 * @param {(what: string) => Error} fail
 * @param {{notOne: string, size: string}} say
 * @returns {Uint8Array}
 */
export function decodeZstdFrame(stored, raw, fail, say) {
  const dv = new DataView(stored.buffer, stored.byteOffset, stored.byteLength);
  if (stored.length < 6 || dv.getUint32(0, true) !== 0xfd2fb528) throw fail(say.notOne);
  const fhd = stored[4];
  if (fhd & 0x08) throw fail(say.notOne);  // reserved bit
  const single = (fhd >> 5) & 1, hasChecksum = (fhd >> 2) & 1, fcsFlag = fhd >> 6;
  const fcsBytes = fcsFlag === 0 ? single : [0, 2, 4, 8][fcsFlag];
  let at = 5 + (single ? 0 : 1) + [0, 1, 2, 4][fhd & 3];
  if (fcsBytes === 0 || at + fcsBytes > stored.length) throw fail(say.size);
  const fcs = fcsBytes === 1 ? stored[at]
    : fcsBytes === 2 ? dv.getUint16(at, true) + 256
      : fcsBytes === 4 ? dv.getUint32(at, true) : Number(dv.getBigUint64(at, true));
  if (fcs !== raw) throw fail(say.size);
  at += fcsBytes;
  // Walk the blocks to find where the frame ends.
  for (;;) {
    if (at + 3 > stored.length) throw fail(say.notOne);
    const bh = stored[at] | (stored[at + 1] << 8) | (stored[at + 2] << 16);
    const type = (bh >> 1) & 3;
    if (type === 3) throw fail("zstd decoding failed: reserved block type");
    at += 3 + (type === 1 ? 1 : bh >>> 3);
    if (bh & 1) break;
  }
  if (at + (hasChecksum ? 4 : 0) !== stored.length) throw fail(say.notOne);
  let out;
  try {
    out = decompress(stored);
  } catch (err) {
    throw fail(`zstd decoding failed: ${err instanceof Error ? err.message : String(err)}`);
  }
  if (out.length !== raw)
    throw fail(`zstd decoding failed: ${out.length} bytes decoded, not ${raw}`);
  if (hasChecksum &&
      dv.getUint32(stored.length - 4, true) !== Number(xxh64Sync(out) & 0xffffffffn))
    throw fail("zstd decoding failed: content checksum mismatch");
  return out;
}
