// source.js — where a reader's bytes come from: an ArrayBuffer in memory, or
// a URL read with HTTP Range requests (only the byte ranges asked for).

/**
 * A random-access byte source.
 * @typedef {object} ByteSource
 * @property {string} label   what to name in messages (a file name or URL)
 * @property {number} size    total bytes
 * @property {(offset: number, length: number) => Promise<Uint8Array>} read
 *   exactly `length` bytes from `offset`; rejects when they are not there
 */

/**
 * A source over bytes already in memory.
 * @param {ArrayBuffer | Uint8Array} buffer
 * @param {string} [label]
 * @returns {ByteSource}
 */
export function bufferSource(buffer, label = "buffer") {
  const bytes = buffer instanceof Uint8Array ? buffer : new Uint8Array(buffer);
  return {
    label,
    size: bytes.byteLength,
    read(offset, length) {
      if (offset < 0 || length < 0 || offset + length > bytes.byteLength)
        return Promise.reject(
          new Error(`${label}: read of ${length} bytes at byte ${offset} is past the end ` +
                    `of the ${bytes.byteLength}-byte file`));
      return Promise.resolve(bytes.subarray(offset, offset + length));
    },
  };
}

/**
 * A source over a URL, read with single-range HTTP Range requests. The
 * size comes from the first response's Content-Range ("bytes 0-0/SIZE");
 * a server that ignores Range (200 with the whole body) is refused, since
 * the reader would then fetch whole files where it asked for a header.
 * @param {string} url
 * @param {{fetch?: typeof fetch}} [options]  a fetch to use (tests)
 * @returns {Promise<ByteSource>}
 */
export async function urlSource(url, options = {}) {
  const get = options.fetch ?? globalThis.fetch;
  /** @param {number} first @param {number} last inclusive */
  async function range(first, last) {
    const res = await get(url, { headers: { Range: `bytes=${first}-${last}` } });
    if (res.status !== 206)
      throw new Error(`${url}: Range request bytes=${first}-${last} answered ${res.status}, ` +
                      `not 206 Partial Content`);
    const cr = res.headers.get("Content-Range") ?? "";
    const m = /^bytes (\d+)-(\d+)\/(\d+)$/.exec(cr);
    if (!m || Number(m[1]) !== first || Number(m[2]) !== last)
      throw new Error(`${url}: Content-Range '${cr}' does not answer bytes=${first}-${last}`);
    const body = new Uint8Array(await res.arrayBuffer());
    if (body.byteLength !== last - first + 1)
      throw new Error(`${url}: ${body.byteLength} bytes for the ${last - first + 1} asked for`);
    return { body, total: Number(m[3]) };
  }
  // The size, without reading the file: an empty file cannot answer a
  // range at all (416), which the package check then names as empty.
  const probe = await get(url, { headers: { Range: "bytes=0-0" } });
  let size;
  if (probe.status === 416) {
    const cr = probe.headers.get("Content-Range") ?? "";
    const m = /^bytes \*\/(\d+)$/.exec(cr);
    if (!m) throw new Error(`${url}: 416 without a Content-Range of bytes */SIZE`);
    size = Number(m[1]);
  } else if (probe.status === 206) {
    const m = /^bytes 0-0\/(\d+)$/.exec(probe.headers.get("Content-Range") ?? "");
    if (!m) throw new Error(`${url}: Content-Range of the first byte is not bytes 0-0/SIZE`);
    size = Number(m[1]);
  } else {
    throw new Error(`${url}: answered ${probe.status} to a Range request, not 206`);
  }
  await probe.arrayBuffer().catch(() => undefined);
  return {
    label: url,
    size,
    async read(offset, length) {
      if (offset < 0 || length < 0 || offset + length > size)
        throw new Error(`${url}: read of ${length} bytes at byte ${offset} is past the end ` +
                        `of the ${size}-byte file`);
      if (length === 0) return new Uint8Array(0);
      const { body, total } = await range(offset, offset + length - 1);
      if (total !== size)
        throw new Error(`${url}: the file changed size (${size} -> ${total} bytes) while read`);
      return body;
    },
  };
}
