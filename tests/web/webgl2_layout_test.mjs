// The WebGL2 renderer's linear textures (web/src/render/webgl2.js
// linearLayout; tests/web/CMakeLists.txt, Web.WebGL2TextureLayout): for
// sizes around the layer and row boundaries, every word k has the texel
// glsl_decals.js lin(k) reads (column k & (2^ws - 1), row (k >> ws) &
// (2^ls - 1), layer (k >> ws) >> ls), inside the texture, and it is the
// texel the upload writes it to (layer by layer, row by row); a size past
// MAX_ARRAY_TEXTURE_LAYERS is refused with a message naming it.
import { linearLayout } from "../../web/src/render/webgl2.js";

let failures = 0;
const check = (ok, what) => {
  if (!ok) {
    failures += 1;
    console.log(`FAIL ${what}`);
  }
};

for (const [maxSize, maxLayers] of [[8192, 2048], [16, 4], [20, 3]]) {
  const W = 2 ** Math.floor(Math.log2(maxSize));
  for (const words of [0, 1, W - 1, W, W + 1, W * W - 1, W * W, W * W + 1, 2 * W * W + 3]) {
    if (words > maxLayers * W * W) continue;
    const lay = linearLayout(words, maxSize, maxLayers, "test data");
    check(lay.width === 2 ** lay.ws && lay.width <= maxSize && lay.height <= maxSize &&
          lay.layers >= 1 && lay.layers <= maxLayers, `${words} words, max ${maxSize}: shape ${JSON.stringify(lay)}`);
    check(lay.width * lay.height * lay.layers >= words, `${words} words do not fit ${JSON.stringify(lay)}`);
    // Only small textures are walked word by word.
    if (words > 5000) continue;
    const perLayer = lay.width * lay.height;
    for (let k = 0; k < words; ++k) {
      const row = k >>> lay.ws;
      const read = [k & (lay.width - 1), row & (2 ** lay.ls - 1), row >>> lay.ls];
      const l = Math.floor(k / perLayer), i = k - l * perLayer;
      const written = [i % lay.width, Math.floor(i / lay.width), l];
      if (read.join() !== written.join() || read[1] >= lay.height || read[2] >= lay.layers) {
        check(false, `${words} words, max ${maxSize}: word ${k} read at ${read}, written at ${written}`);
        break;
      }
    }
  }
}
// Too large: more layers than the limit.
try {
  linearLayout(4 * 16 * 16 + 1, 16, 4, "the package's static blobs");
  check(false, "a texture past MAX_ARRAY_TEXTURE_LAYERS was not refused");
} catch (e) {
  const m = e instanceof Error ? e.message : String(e);
  check(/static blobs is 1025 words .*at most 4 layers of 16x16 words/.test(m), `refusal message: ${m}`);
}
console.log(failures ? `${failures} failure(s)` : "ok: the WebGL2 texture layout");
process.exit(failures ? 1 : 0);
