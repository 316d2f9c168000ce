// package.js — a reader of .decals packages written from formats/SPEC.md
// ("File structure", "File header", "Blob table", "Metadata", "Validation").
// It treats every file as hostile: before it uses a value it checks it, in
// the order of SPEC "Validation", and refuses the file with a FormatError
// whose message names the field, its byte offset or blob, and the bad value.
//
// Opening reads only the header, the blob table and the metadata (steps
// 1–8 of SPEC "Validation"; the placement of every blob is checked from the
// table alone). A blob's bytes are read, checked (its checksum, the zero
// padding before it, step 9's decoding) and decoded when it is first asked
// for, so over HTTP a viewer fetches only the blobs it draws. validate()
// reads every blob and applies the index constraints and the metadata
// checks `decalprep verify` applies (index.js).
import {
  ALIGN,
  CATALOGUE,
  CODEC_NONE,
  CODEC_ZSTD,
  ELEMENT_TYPES,
  ENTRY_SIZE,
  FLAG_ALL_UNCOMPRESSED,
  HEADER_SIZE,
  MAGIC,
  MAX_METADATA_BYTES,
  RECORD_TYPE,
  REQUIRED_FLAGS_MASK,
  VERSION_MAJOR,
  VERSION_MINOR,
} from "./format.js";
import { bufferSource, urlSource } from "./source.js";
import { hex64, xxh64 } from "./xxh64.js";
import { decodeZstdFrame } from "./zstd.js";
import { checkIndices, checkMetadata } from "./validate.js";
import { FormatError } from "./errors.js";

export { FormatError };

/**
 * One blob table entry, checked.
 * @typedef {object} BlobEntry
 * @property {number} index      position in the table (= in the file)
 * @property {number} id
 * @property {string} name
 * @property {number} type       element type value
 * @property {string} typeName   element type name (`u32`, `record`, ...)
 * @property {number} stride     bytes per element
 * @property {number} codec
 * @property {number} count      elements
 * @property {number} offset     first stored byte
 * @property {number} storedSize
 * @property {number} rawSize    decoded bytes (= count × stride)
 * @property {bigint} checksum   XXH64 of the stored bytes
 * @property {boolean} known     the id is in the catalogue
 * @property {number} padFrom    where the zero padding before the blob starts
 */

/**
 * @typedef {object} OpenOptions
 * @property {boolean} [verifyChecksums]  check blob checksums (default true)
 * @property {number} [maxRawBytes]       refuse a package whose decoded blobs
 *   add up past this (default 2^31 − 1: a typed array's practical limit)
 */

/** @param {number} x */
const align256 = (x) => Math.ceil(x / ALIGN) * ALIGN;

/**
 * A u64 field as a Number, or a FormatError naming it when it is beyond
 * 2^53 (no file this reader can hold is that large).
 * @param {DataView} dv @param {number} at @param {string} what
 */
function u64(dv, at, what) {
  const v = dv.getBigUint64(at, true);
  if (v > BigInt(Number.MAX_SAFE_INTEGER))
    throw new FormatError(`${what} ${v} at byte ${at} is beyond 2^53`);
  return Number(v);
}

/** The checked header fields. */
class Header {
  /** @param {DataView} dv */
  constructor(dv) {
    this.major = dv.getUint16(8, true);
    this.minor = dv.getUint16(10, true);
    this.flags = dv.getUint32(12, true);
    this.headerSize = dv.getUint32(16, true);
    this.entrySize = dv.getUint32(20, true);
    this.blobCount = dv.getUint32(24, true);
    this.reserved0 = dv.getUint32(28, true);
  }
}

/** A checked, open package; blobs are read on demand. */
export class Package {
  /**
   * @param {import("./source.js").ByteSource} source
   * @param {Header} h
   * @param {Uint8Array} metadataBytes
   * @param {BlobEntry[]} blobs
   * @param {OpenOptions} options
   */
  constructor(source, h, metadataBytes, blobs, options) {
    /** what messages name */
    this.label = source.label;
    this.major = h.major;
    this.minor = h.minor;
    this.flags = h.flags;
    this.fileSize = source.size;
    this.metadataText = new TextDecoder("utf-8", { fatal: false }).decode(metadataBytes);
    /** @type {readonly BlobEntry[]} in file order */
    this.blobs = blobs;
    this.source = source;
    this.options = options;
    /** @type {Map<number, Promise<Uint8Array>>} decoded bytes by table index */
    this.cache = new Map();
    /** @type {unknown} */
    this.parsedMetadata = undefined;
  }

  /** The file's minor version is newer than this reader's (SPEC "Versioning"). */
  get newerMinor() {
    return this.minor > VERSION_MINOR;
  }

  /**
   * The metadata as parsed JSON; a FormatError when it is not valid JSON.
   * @returns {any}
   */
  get metadata() {
    if (this.parsedMetadata === undefined) {
      try {
        this.parsedMetadata = JSON.parse(this.metadataText);
      } catch (e) {
        throw new FormatError(`${this.label}: metadata is not valid JSON: ${String(e)}`);
      }
    }
    return this.parsedMetadata;
  }

  /**
   * The entry of a blob by name or id, or undefined when the package has none.
   * @param {string | number} which
   */
  entry(which) {
    return this.blobs.find((b) => (typeof which === "number" ? b.id === which : b.name === which));
  }

  /**
   * A blob's decoded bytes (count × stride), read, checked and decoded on
   * first use; an absent blob reads as empty (SPEC "Blob catalogue").
   * @param {string | number} which  name or id
   * @returns {Promise<Uint8Array>}
   */
  bytes(which) {
    const e = this.entry(which);
    if (!e) return Promise.resolve(new Uint8Array(0));
    let p = this.cache.get(e.index);
    if (!p) {
      p = this.load(e);
      this.cache.set(e.index, p);
    }
    return p;
  }

  /**
   * A blob's elements as a typed array of its components (Int32Array for
   * ivec*, Uint32Array for u32/uvec*, Float32Array for f32/vec*, Uint8Array
   * for u8 and records). Components are little-endian in the file; the
   * views assume a little-endian host, as every WebGPU/WebGL host is.
   * @param {string | number} which
   */
  async array(which) {
    const bytes = await this.bytes(which);
    const e = this.entry(which);
    const kind = e ? /** @type {NonNullable<ReturnType<typeof ELEMENT_TYPES.get>>} */ (ELEMENT_TYPES.get(e.type)).kind : "u8";
    const copy = bytes.byteOffset % 4 === 0 ? bytes : bytes.slice();
    switch (kind) {
      case "i32": return new Int32Array(copy.buffer, copy.byteOffset, copy.byteLength / 4);
      case "u32": return new Uint32Array(copy.buffer, copy.byteOffset, copy.byteLength / 4);
      case "f32": return new Float32Array(copy.buffer, copy.byteOffset, copy.byteLength / 4);
      default: return copy;
    }
  }

  /**
   * Reads every blob and applies the checks of `decalprep verify`: every
   * checksum and decoding, the index constraints (SPEC "Index constraints")
   * and the metadata (valid JSON object, `format`, `counts`). Resolves to
   * the package; rejects with a FormatError naming the first problem.
   */
  async validate() {
    let total = 0;
    for (const e of this.blobs) total += e.rawSize;
    const limit = this.options.maxRawBytes ?? 2 ** 31 - 1;
    if (total > limit)
      throw new FormatError(`${this.label}: package inflates beyond the ${limit}-byte limit ` +
                            `(maxRawBytes): its blobs decode to ${total} bytes`);
    for (const e of this.blobs) await this.bytes(e.id);
    /** @type {Map<number, {count: number, bytes: Uint8Array}>} */
    const byId = new Map();
    for (const e of this.blobs)
      if (e.known) byId.set(e.id, { count: e.count, bytes: await this.bytes(e.id) });
    try {
      checkIndices(byId, this.newerMinor);
      checkMetadata(this.metadata, this.blobs);
    } catch (err) {
      if (err instanceof FormatError) throw new FormatError(`${this.label}: ${err.message}`);
      throw err;
    }
    return this;
  }

  /**
   * Reads, checks and decodes one blob (SPEC "Validation" steps 8's padding and 9).
   * @param {BlobEntry} e
   */
  async load(e) {
    const label = `${this.label}: ${entryLabel(e)}`;
    // The padding before the blob and its stored bytes in one read.
    const region = await this.source.read(e.padFrom, e.offset + e.storedSize - e.padFrom);
    const pad = e.offset - e.padFrom;
    for (let i = 0; i < pad; ++i)
      if (region[i] !== 0)
        throw new FormatError(`${this.label}: padding byte ${e.padFrom + i} before ` +
                              `${entryLabel(e)} is not zero`);
    const stored = region.subarray(pad);
    if (this.options.verifyChecksums ?? true) {
      const got = await xxh64(stored);
      if (got !== e.checksum)
        throw new FormatError(`${label}: checksum mismatch: stored ${hex64(e.checksum)}, ` +
                              `computed ${hex64(got)}`);
    }
    if (e.codec === CODEC_NONE) return stored;
    return decodeZstdFrame(stored, e.rawSize, (what) => new FormatError(`${label}: ${what}`), {
      notOne: "stored bytes are not exactly one zstd frame",
      size: `zstd frame content size does not match raw_size ${e.rawSize}`,
    });
  }
}

/** @param {BlobEntry} e */
function entryLabel(e) {
  return `blob #${e.index} '${e.name}' (id ${e.id})`;
}

/**
 * Opens a package: checks steps 1–8 of SPEC "Validation" (reading the
 * header, the table and the metadata only). Blobs are read when asked for.
 * @param {import("./source.js").ByteSource | ArrayBuffer | Uint8Array} input
 * @param {OpenOptions & {label?: string}} [options]
 * @returns {Promise<Package>}
 */
export async function openPackage(input, options = {}) {
  const source = input instanceof ArrayBuffer || input instanceof Uint8Array
    ? bufferSource(input, options.label) : input;
  try {
    return await openSource(source, options);
  } catch (err) {
    if (err instanceof FormatError && !err.message.startsWith(`${source.label}: `))
      throw new FormatError(`${source.label}: ${err.message}`);
    throw err;
  }
}

/**
 * Opens a package over HTTP with Range requests (see openPackage).
 * @param {string} url
 * @param {OpenOptions & {fetch?: typeof fetch}} [options]
 */
export async function openPackageUrl(url, options = {}) {
  return openPackage(await urlSource(url, options), options);
}

/**
 * @param {import("./source.js").ByteSource} src
 * @param {OpenOptions} options
 */
async function openSource(src, options) {
  const size = src.size;
  const fail = (/** @type {string} */ m) => new FormatError(m);
  // 1. Not empty, the magic, a full header.
  if (size === 0) throw fail("empty file (0 bytes): not a .decals package");
  const first = await src.read(0, Math.min(size, HEADER_SIZE));
  for (let i = 0; i < MAGIC.length; ++i)
    if (i >= first.length || first[i] !== MAGIC[i])
      throw fail("not a .decals package: magic bytes do not match at byte 0");
  if (size < HEADER_SIZE)
    throw fail(`truncated package: ${size} bytes, the header alone needs ${HEADER_SIZE}`);
  let dv = new DataView(first.buffer, first.byteOffset, first.byteLength);
  const h = new Header(dv);
  // 2. The major version, before any checksum.
  if (h.major !== VERSION_MAJOR)
    throw fail(`unsupported package major version ${h.major} (minor ${h.minor}); ` +
               `this reader reads major version ${VERSION_MAJOR}`);
  // 3. header_size, then the header checksum (the header's last 8 bytes).
  if (h.headerSize < HEADER_SIZE || h.headerSize % 8 !== 0 || h.headerSize > size)
    throw fail(`header_size ${h.headerSize} at byte 16 is invalid (must be >= ${HEADER_SIZE}, ` +
               `a multiple of 8 and within the ${size}-byte file)`);
  const header = h.headerSize === HEADER_SIZE ? first : await src.read(0, h.headerSize);
  dv = new DataView(header.buffer, header.byteOffset, header.byteLength);
  const storedHeaderSum = dv.getBigUint64(h.headerSize - 8, true);
  const headerSum = await xxh64(header.subarray(0, h.headerSize - 8));
  if (storedHeaderSum !== headerSum)
    throw fail(`header checksum mismatch at byte ${h.headerSize - 8}: stored ` +
               `${hex64(storedHeaderSum)}, computed ${hex64(headerSum)}`);
  // 4. file_size.
  const fileSize = dv.getBigUint64(32, true);
  if (fileSize !== BigInt(size))
    throw fail(`file_size mismatch: header says ${fileSize} bytes at byte 32, file has ${size}` +
               (BigInt(size) < fileSize ? " (truncated)" : " (trailing bytes)"));
  // 5. Flags and reserved fields.
  const required = h.flags & REQUIRED_FLAGS_MASK;
  if (required !== 0)
    throw fail(`unsupported required flag bits 0x${hex32(required)} in flags ` +
               `0x${hex32(h.flags)} at byte 12`);
  const ownMinor = h.minor <= VERSION_MINOR;
  if (ownMinor) {
    if ((h.flags & ~FLAG_ALL_UNCOMPRESSED) >>> 0 !== 0)
      throw fail(`undefined optional flag bits set in flags 0x${hex32(h.flags)} at byte 12 ` +
                 `(version ${h.major}.${h.minor})`);
    if (h.reserved0 !== 0) throw fail(`reserved0 at byte 28 is not zero (${h.reserved0})`);
    if (dv.getBigUint64(80, true) !== 0n) throw fail("reserved1 at byte 80 is not zero");
    for (let i = HEADER_SIZE - 8; i < h.headerSize - 8; ++i)
      if (header[i] !== 0)
        throw fail(`header byte ${i} (past the v${h.major}.${h.minor} fields) is not zero`);
  }
  // 6. The blob table.
  if (h.entrySize < ENTRY_SIZE || h.entrySize % 8 !== 0)
    throw fail(`blob_entry_size ${h.entrySize} at byte 20 is invalid (must be >= ${ENTRY_SIZE} ` +
               `and a multiple of 8)`);
  const tableOffset = dv.getBigUint64(40, true);
  if (tableOffset !== BigInt(h.headerSize))
    throw fail(`table_offset ${tableOffset} at byte 40 must equal header_size ${h.headerSize}`);
  const tableBytes = h.blobCount * h.entrySize;
  if (h.headerSize + tableBytes > size)
    throw fail(`blob table (${h.blobCount} entries x ${h.entrySize} bytes at byte ` +
               `${h.headerSize}) runs past the end of the ${size}-byte file`);
  const table = await src.read(h.headerSize, tableBytes);
  const storedTableSum = dv.getBigUint64(48, true);
  const tableSum = await xxh64(table);
  if (storedTableSum !== tableSum)
    throw fail(`blob table checksum mismatch (table_checksum at byte 48): stored ` +
               `${hex64(storedTableSum)}, computed ${hex64(tableSum)}`);
  // 7. The metadata.
  const metadataOffset = dv.getBigUint64(56, true);
  const metaAt = h.headerSize + tableBytes;
  if (metadataOffset !== BigInt(metaAt))
    throw fail(`metadata_offset ${metadataOffset} at byte 56 must equal the end of the blob ` +
               `table, ${metaAt}`);
  const metadataSize = dv.getBigUint64(64, true);
  if (metadataSize < 2n || BigInt(metaAt) + metadataSize > BigInt(size))
    throw fail(`metadata (metadata_size ${metadataSize} at byte 64, at byte ${metaAt}) must be ` +
               `at least 2 bytes and within the ${size}-byte file`);
  if (metadataSize > BigInt(MAX_METADATA_BYTES))
    throw fail(`metadata_size ${metadataSize} at byte 64 is above the reader's limit of ` +
               `${MAX_METADATA_BYTES} bytes (formats/SPEC.md "Metadata")`);
  const metaSize = Number(metadataSize);
  const metadata = await src.read(metaAt, metaSize);
  const storedMetaSum = dv.getBigUint64(72, true);
  const metaSum = await xxh64(metadata);
  if (storedMetaSum !== metaSum)
    throw fail(`metadata checksum mismatch (metadata_checksum at byte 72): stored ` +
               `${hex64(storedMetaSum)}, computed ${hex64(metaSum)}`);
  if (metadata[0] !== 0x7b || metadata[metaSize - 1] !== 0x7d)
    throw fail(`metadata at byte ${metaAt} is not a JSON object (must start with '{' and ` +
               `end with '}')`);
  if (metadata.includes(0)) throw fail("metadata contains a NUL byte");
  // 8. The entries, and the placement of every region.
  const tv = new DataView(table.buffer, table.byteOffset, table.byteLength);
  /** @type {BlobEntry[]} */
  const blobs = [];
  /** @type {Map<number, number>} */
  const seen = new Map();
  let prevEnd = metaAt + metaSize;
  let prevLabel = "the metadata";
  const allUncompressed = (h.flags & FLAG_ALL_UNCOMPRESSED) !== 0;
  for (let i = 0; i < h.blobCount; ++i) {
    const at = i * h.entrySize;
    const byteAt = h.headerSize + at;
    const id = tv.getUint32(at, true);
    const nameBytes = table.subarray(at + 56, at + 88);
    let n = 0;
    while (n < 32 && nameBytes[n] !== 0) ++n;
    let nameOk = n >= 1 && n <= 31;
    for (let k = 0; k < 32 && nameOk; ++k) {
      const c = nameBytes[k];
      if (k < n) nameOk = (c >= 0x61 && c <= 0x7a) || (c >= 0x30 && c <= 0x39) || c === 0x5f;
      else nameOk = c === 0;
    }
    const name = nameOk ? String.fromCharCode(...nameBytes.subarray(0, n)) : "?";
    const label = `blob #${i} '${name}' (id ${id})`;
    if (!nameOk)
      throw fail(`${label}, table entry at byte ${byteAt}: name must be 1-31 characters ` +
                 `[a-z0-9_], NUL-padded`);
    if (ownMinor) {
      if (tv.getUint32(at + 88, true) !== 0 || tv.getUint32(at + 92, true) !== 0)
        throw fail(`${label}: reserved entry field at byte ${byteAt + 88} is not zero`);
      for (let k = ENTRY_SIZE; k < h.entrySize; ++k)
        if (table[at + k] !== 0)
          throw fail(`${label}: entry bytes past the v1 fields are not zero ` +
                     `(byte ${byteAt + k})`);
    }
    const type = tv.getUint32(at + 4, true);
    const stride = tv.getUint32(at + 8, true);
    const codec = tv.getUint32(at + 12, true);
    const info = ELEMENT_TYPES.get(type);
    if (!info) throw fail(`${label}: unknown element_type ${type}`);
    if (type === RECORD_TYPE) {
      if (stride === 0 || stride % 4 !== 0)
        throw fail(`${label}: record stride ${stride} is not a positive multiple of 4`);
    } else if (stride !== info.stride) {
      throw fail(`${label}: stride ${stride} does not match element type ${info.name} ` +
                 `(std430 stride ${info.stride})`);
    }
    const row = CATALOGUE.get(id);
    if (row) {
      if (row.name !== name) throw fail(`${label}: id ${id} is '${row.name}' in the catalogue`);
      if (row.type !== type || row.stride !== stride)
        throw fail(`${label}: element type ${info.name} stride ${stride}, catalogue says ` +
                   `${ELEMENT_TYPES.get(row.type)?.name} stride ${row.stride}`);
    }
    const dup = seen.get(id);
    if (dup !== undefined) throw fail(`${label}: duplicate blob id (also entry #${dup})`);
    seen.set(id, i);
    const count = tv.getBigUint64(at + 16, true);
    const offset = tv.getBigUint64(at + 24, true);
    const storedSize = tv.getBigUint64(at + 32, true);
    const rawSize = tv.getBigUint64(at + 40, true);
    const raw = count * BigInt(stride);
    if (raw > 0xffffffffffffffffn)
      throw fail(`${label}: count ${count} x stride ${stride} overflows uint64`);
    if (raw !== rawSize) throw fail(`${label}: raw_size ${rawSize} != count ${count} x stride ${stride}`);
    if (codec === CODEC_NONE) {
      if (storedSize !== rawSize)
        throw fail(`${label}: uncompressed but stored_size ${storedSize} != raw_size ${rawSize}`);
    } else if (codec === CODEC_ZSTD) {
      if (allUncompressed) throw fail(`${label}: zstd codec in a package flagged all-uncompressed`);
      if (rawSize > storedSize * 32768n + 131072n)
        throw fail(`${label}: raw_size ${rawSize} cannot come from ${storedSize} zstd bytes`);
    } else {
      throw fail(`${label}: unknown codec ${codec}`);
    }
    if (offset % BigInt(ALIGN) !== 0n)
      throw fail(`${label}: offset ${offset} is not a multiple of ${ALIGN}`);
    if (offset + storedSize > BigInt(size))
      throw fail(`${label}: ${storedSize} bytes at offset ${offset} run past the end of the ` +
                 `${size}-byte file`);
    if (offset < BigInt(prevEnd))
      throw fail(`${label}: offset ${offset} overlaps ${prevLabel}, which ends at byte ${prevEnd}`);
    if (offset !== BigInt(align256(prevEnd)))
      throw fail(`${label}: offset ${offset} leaves a gap; the next aligned offset after byte ` +
                 `${prevEnd} is ${align256(prevEnd)}`);
    // Every value below is within the file, so below 2^53.
    if (rawSize > BigInt(Number.MAX_SAFE_INTEGER))
      throw fail(`${label}: raw_size ${rawSize} is beyond what this reader can hold`);
    blobs.push({
      index: i, id, name, type, typeName: info.name, stride, codec,
      count: Number(count), offset: Number(offset), storedSize: Number(storedSize),
      rawSize: Number(rawSize), checksum: tv.getBigUint64(at + 48, true),
      known: row !== undefined, padFrom: prevEnd,
    });
    prevEnd = Number(offset + storedSize);
    prevLabel = label;
  }
  if (prevEnd !== size)
    throw fail(`${size - prevEnd} unexplained bytes after ${prevLabel} (byte ${prevEnd} to ${size})`);
  // The padding between the metadata and blob 0 is checked with blob 0.
  return new Package(src, h, metadata, blobs, options);
}

/** @param {number} v */
function hex32(v) {
  return (v >>> 0).toString(16).padStart(8, "0");
}
