// raw_compare A.raw B.raw W H S THRESHOLD — compares two `render --raw`
// decal layers (float32 RGBA, straight alpha, row 0 at the top) of
// (W*S) x (H*S) pixels, for tests/tools/tileset_overview_test.py. Prints
//   point <pixels of the fine images whose RGBA differs by more than 1/255>
//   filtered <pixels of the W x H images whose premultiplied RGBA, averaged
//            over S x S blocks (a box filter: the coverage an anti-aliased
//            render shows), differs by more than THRESHOLD>
//   pixels <W*H> covered <pixels of B's filtered image with alpha > 0>
// Exit 2 on bad arguments or short files.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

namespace {

bool read_raw(const char* path, size_t floats, std::vector<float>& v) {
  v.assign(floats, 0.0f);
  std::ifstream in(path, std::ios::binary);
  in.read(reinterpret_cast<char*>(v.data()), std::streamsize(floats * sizeof(float)));
  return size_t(in.gcount()) == floats * sizeof(float);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 7) {
    std::fprintf(stderr, "usage: raw_compare A.raw B.raw W H S THRESHOLD\n");
    return 2;
  }
  const size_t w = std::strtoul(argv[3], nullptr, 10), h = std::strtoul(argv[4], nullptr, 10),
               s = std::strtoul(argv[5], nullptr, 10);
  const double threshold = std::strtod(argv[6], nullptr);
  if (w == 0 || h == 0 || s == 0) return 2;
  const size_t fw = w * s, fh = h * s;
  std::vector<float> a, b;
  if (!read_raw(argv[1], 4 * fw * fh, a) || !read_raw(argv[2], 4 * fw * fh, b)) {
    std::fprintf(stderr, "raw_compare: %s or %s is shorter than %zux%zu RGBA floats\n", argv[1],
                 argv[2], fw, fh);
    return 2;
  }
  size_t point = 0;
  for (size_t k = 0; k < fw * fh; ++k)
    for (int c = 0; c < 4; ++c)
      if (std::abs(a[4 * k + c] - b[4 * k + c]) > 1.0f / 255) {
        ++point;
        break;
      }
  size_t filtered = 0, covered = 0;
  for (size_t j = 0; j < h; ++j)
    for (size_t i = 0; i < w; ++i) {
      double pa[4] = {0, 0, 0, 0}, pb[4] = {0, 0, 0, 0};
      for (size_t y = j * s; y < (j + 1) * s; ++y)
        for (size_t x = i * s; x < (i + 1) * s; ++x) {
          const size_t k = 4 * (y * fw + x);
          for (int c = 0; c < 3; ++c) {
            pa[c] += double(a[k + c]) * a[k + 3];
            pb[c] += double(b[k + c]) * b[k + 3];
          }
          pa[3] += a[k + 3];
          pb[3] += b[k + 3];
        }
      bool differ = false;
      for (int c = 0; c < 4; ++c) differ |= std::abs(pa[c] - pb[c]) / double(s * s) > threshold;
      filtered += differ;
      covered += pb[3] > 0;
    }
  std::printf("point %zu filtered %zu pixels %zu covered %zu\n", point, filtered, w * h, covered);
  return 0;
}
