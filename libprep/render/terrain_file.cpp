// Terrain files (formats/SPEC.md "Terrain files"): the heightfield mesh
// render draws (terrain.cpp), written beside a package for readers without
// GDAL, and read back as hostile input.
#include <unistd.h>
#include <xxhash.h>
#include <zstd.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>

#include "decal/reader.hpp"
#include "prep/error.hpp"
#include "prep/render.hpp"
#include "prep/stage_error.hpp"

namespace prep::render {

namespace terrain_format {
namespace {

// SPEC "Terrain files": header layout, codecs.
constexpr uint16_t kMajor = kTerrainFileMajor, kMinor = kTerrainFileMinor;
constexpr uint32_t kHeaderSize = 144;
constexpr uint32_t kCodecNone = 0, kCodecZstd = 1;
constexpr uint32_t kRequiredFlags = 0x0000ffffu;
// Coordinates and heights beyond this many metres are refused.
constexpr double kMaxMetres = 1e12;
constexpr int kZstdLevel = 12;

enum Offset : size_t {
  kVersionMajor = 8,
  kVersionMinor = 10,
  kHeaderSizeAt = 12,
  kFlags = 16,
  kCodec = 20,
  kNx = 24,
  kNy = 28,
  kFileSize = 32,
  kX0 = 40,
  kY0 = 48,
  kDx = 56,
  kDy = 64,
  kZmin = 72,
  kZmax = 80,
  kBound = 88,
  kOriginX = 96,
  kOriginY = 104,
  kSourceHash = 112,
  kHeightsSize = 120,
  kHeightsChecksum = 128,
  kHeaderChecksum = 136,
};

static_assert(std::endian::native == std::endian::little, "terrain files are little-endian");

template <class T>
void put(std::string& out, size_t at, T v) {
  std::memcpy(out.data() + at, &v, sizeof v);
}

template <class T>
T get(std::span<const uint8_t> b, size_t at) {
  T v;
  std::memcpy(&v, b.data() + at, sizeof v);
  return v;
}

std::string num(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

// The raw heights: byte k of vertex v's little-endian f64 at k * n + v
// (byte planes, so that zstd sees the slowly varying high bytes together).
std::string planes_of(const std::vector<double>& z) {
  const size_t n = z.size();
  std::string raw(n * 8, '\0');
  for (size_t v = 0; v < n; ++v) {
    const uint64_t bits = std::bit_cast<uint64_t>(z[v]);
    for (size_t k = 0; k < 8; ++k) raw[k * n + v] = char((bits >> (8 * k)) & 0xff);
  }
  return raw;
}

std::vector<double> heights_of(std::span<const uint8_t> raw, size_t n) {
  std::vector<double> z(n);
  for (size_t v = 0; v < n; ++v) {
    uint64_t bits = 0;
    for (size_t k = 0; k < 8; ++k) bits |= uint64_t(raw[k * n + v]) << (8 * k);
    z[v] = std::bit_cast<double>(bits);
  }
  return z;
}

[[noreturn]] void bad_mesh(const std::string& what) {
  fail<usage_error>(kTerrainStage, "cannot write a terrain file: " + what);
}

// The checks encode_terrain makes of what it writes (the reader's limits).
void check_mesh(const TerrainFile& t) {
  const Heightfield& h = t.mesh;
  if (h.nx < 2 || h.ny < 2 || h.nx > kTerrainMaxSide || h.ny > kTerrainMaxSide ||
      uint64_t(h.nx) * h.ny > kTerrainMaxVertices)
    bad_mesh("a mesh of " + std::to_string(h.nx) + "x" + std::to_string(h.ny) +
             " vertices is beyond the format's limits");
  if (h.z.size() != size_t(h.nx) * h.ny) bad_mesh("heights do not match nx * ny");
  for (double v : {h.x0, h.y0, h.dx, h.dy, t.origin_x, t.origin_y, h.zmin, h.zmax})
    if (!std::isfinite(v) || std::abs(v) > kMaxMetres) bad_mesh("a number is not finite");
  if (!(h.dx > 0 && h.dy > 0)) bad_mesh("the spacing is not positive");
  if (std::isnan(h.surface_error_bound) || h.surface_error_bound < 0)
    bad_mesh("the surface error bound is not a length");
  const auto [lo, hi] = std::minmax_element(h.z.begin(), h.z.end());
  for (double v : h.z)
    if (!std::isfinite(v) || std::abs(v) > kMaxMetres) bad_mesh("a height is not finite");
  if (*lo != h.zmin || *hi != h.zmax) bad_mesh("zmin, zmax are not the heights' range");
}

}  // namespace
}  // namespace terrain_format

TerrainFile make_terrain(const DemSpec& dem, const SceneFrame& frame, const Extent& extent,
                         uint64_t source_xxh64) {
  TerrainFile t;
  t.mesh = load_heightfield(dem, frame, extent, kMeshSamples);
  t.origin_x = frame.origin_x;
  t.origin_y = frame.origin_y;
  t.source_xxh64 = source_xxh64;
  return t;
}

std::string encode_terrain(const TerrainFile& t) {
  using namespace terrain_format;
  check_mesh(t);
  const Heightfield& h = t.mesh;
  const std::string raw = planes_of(h.z);
  std::string stored(ZSTD_compressBound(raw.size()), '\0');
  ZSTD_CCtx* cctx = ZSTD_createCCtx();
  if (!cctx) fail<output_error>(kTerrainStage, "out of memory for the zstd compressor");
  ZSTD_CCtx_setParameter(cctx, ZSTD_c_compressionLevel, kZstdLevel);
  ZSTD_CCtx_setParameter(cctx, ZSTD_c_checksumFlag, 1);
  ZSTD_CCtx_setParameter(cctx, ZSTD_c_contentSizeFlag, 1);
  const size_t n = ZSTD_compress2(cctx, stored.data(), stored.size(), raw.data(), raw.size());
  ZSTD_freeCCtx(cctx);
  if (ZSTD_isError(n))
    fail<output_error>(kTerrainStage,
                       std::string("zstd compression failed: ") + ZSTD_getErrorName(n));
  stored.resize(n);

  std::string out(kHeaderSize, '\0');
  std::memcpy(out.data(), kTerrainMagic.data(), 8);
  put<uint16_t>(out, kVersionMajor, kMajor);
  put<uint16_t>(out, kVersionMinor, kMinor);
  put<uint32_t>(out, kHeaderSizeAt, kHeaderSize);
  put<uint32_t>(out, kCodec, kCodecZstd);
  put<uint32_t>(out, kNx, h.nx);
  put<uint32_t>(out, kNy, h.ny);
  put<uint64_t>(out, kFileSize, uint64_t(kHeaderSize) + stored.size());
  put<double>(out, kX0, h.x0);
  put<double>(out, kY0, h.y0);
  put<double>(out, kDx, h.dx);
  put<double>(out, kDy, h.dy);
  put<double>(out, kZmin, h.zmin);
  put<double>(out, kZmax, h.zmax);
  put<double>(out, kBound, h.surface_error_bound);
  put<double>(out, kOriginX, t.origin_x);
  put<double>(out, kOriginY, t.origin_y);
  put<uint64_t>(out, kSourceHash, t.source_xxh64);
  put<uint64_t>(out, kHeightsSize, stored.size());
  put<uint64_t>(out, kHeightsChecksum, XXH64(stored.data(), stored.size(), 0));
  put<uint64_t>(out, kHeaderChecksum, XXH64(out.data(), kHeaderChecksum, 0));
  return out + stored;
}

namespace terrain_format {
namespace {

// Steps 1-6 of SPEC "Terrain files" (Validation): magic, version, header
// size and checksum, file size, flags and the bytes a newer minor adds.
uint32_t check_header(std::span<const uint8_t> b, const std::string& label) {
  auto bad = [&](const std::string& what) {
    fail<format_error>(kTerrainStage, label + ": " + what);
  };
  if (b.size() < 8 || std::memcmp(b.data(), kTerrainMagic.data(), 8) != 0)
    bad("magic: not a terrain file (the first 8 bytes are not 89 44 54 52 0d 0a 1a 0a)");
  if (b.size() < 16)
    bad("header: truncated, " + std::to_string(b.size()) + " bytes (the header has " +
        std::to_string(kHeaderSize) + ")");
  const uint16_t major = get<uint16_t>(b, kVersionMajor), minor = get<uint16_t>(b, kVersionMinor);
  if (major != kMajor)
    bad("version_major: unsupported terrain file version " + std::to_string(major) + "." +
        std::to_string(minor) + "; this reader reads major version 1");
  const uint32_t header = get<uint32_t>(b, kHeaderSizeAt);
  if (header < kHeaderSize || header % 8 != 0)
    bad("header_size: " + std::to_string(header) + " (at least 144, a multiple of 8)");
  if (header > b.size())
    bad("header_size: " + std::to_string(header) + " bytes, but the file holds " +
        std::to_string(b.size()) + " (truncated)");
  const uint64_t want = get<uint64_t>(b, header - 8), got = XXH64(b.data(), header - 8, 0);
  if (want != got) bad("header_checksum: mismatch (the header is damaged)");
  if (const uint64_t size = get<uint64_t>(b, kFileSize); size != b.size())
    bad("file_size: " + std::to_string(size) + ", but the file holds " + std::to_string(b.size()) +
        " bytes");
  const uint32_t flags = get<uint32_t>(b, kFlags);
  if (flags & kRequiredFlags)
    bad("flags: " + std::to_string(flags) + " sets a required flag this reader does not know");
  if (minor <= kMinor) {
    if (flags) bad("flags: " + std::to_string(flags) + " (no flag is defined in version 1.0)");
    for (size_t k = kHeaderChecksum; k + 8 < header; ++k)
      if (b[k]) bad("header: byte " + std::to_string(k) + " beyond the 1.0 fields is not zero");
  }
  return header;
}

// Steps 7-9: codec, sizes and numbers.
void check_fields(std::span<const uint8_t> b, const TerrainFile& t, uint32_t codec,
                  const std::string& label) {
  auto bad = [&](const std::string& what) {
    fail<format_error>(kTerrainStage, label + ": " + what);
  };
  if (codec != kCodecNone && codec != kCodecZstd)
    bad("codec: " + std::to_string(codec) + " (0 none or 1 zstd)");
  const Heightfield& h = t.mesh;
  if (h.nx < 2 || h.nx > kTerrainMaxSide) bad("nx: " + std::to_string(h.nx) + " not in 2..16384");
  if (h.ny < 2 || h.ny > kTerrainMaxSide) bad("ny: " + std::to_string(h.ny) + " not in 2..16384");
  if (uint64_t(h.nx) * h.ny > kTerrainMaxVertices)
    bad("nx * ny: " + std::to_string(uint64_t(h.nx) * h.ny) + " vertices exceed 16777216");
  for (const auto& [name, v] : terrain_fields(t))
    if (!std::isfinite(v) || std::abs(v) > kMaxMetres)
      bad(std::string(name) + ": " + num(v) + " is not a finite number within 1e12");
  if (!(h.dx > 0)) bad("dx: " + num(h.dx) + " is not positive");
  if (!(h.dy > 0)) bad("dy: " + num(h.dy) + " is not positive");
  if (!(std::abs(h.x0 + h.dx * (h.nx - 1)) <= kMaxMetres))
    bad("dx: the grid's last column " + num(h.x0 + h.dx * (h.nx - 1)) + " is beyond 1e12");
  if (!(std::abs(h.y0 + h.dy * (h.ny - 1)) <= kMaxMetres))
    bad("dy: the grid's last row " + num(h.y0 + h.dy * (h.ny - 1)) + " is beyond 1e12");
  if (!(h.zmin <= h.zmax)) bad("zmin: " + num(h.zmin) + " exceeds zmax " + num(h.zmax));
  if (!(h.surface_error_bound >= 0))
    bad("surface_error_bound: " + num(h.surface_error_bound) + " (a length, or +infinity)");
  const uint64_t raw = uint64_t(h.nx) * h.ny * 8, stored = get<uint64_t>(b, kHeightsSize);
  const uint64_t header = get<uint32_t>(b, kHeaderSizeAt);
  if (codec == kCodecNone && stored != raw)
    bad("heights_size: " + std::to_string(stored) +
        " (codec none stores nx * ny * 8 = " + std::to_string(raw) + ")");
  if (codec == kCodecZstd && (stored == 0 || raw > stored * 32768 + 131072))
    bad("heights_size: " + std::to_string(stored) + " zstd bytes cannot hold " +
        std::to_string(raw));
  if (stored != b.size() - header)
    bad("heights_size: " + std::to_string(stored) + ", but " + std::to_string(b.size() - header) +
        " bytes follow the header");
}

}  // namespace
}  // namespace terrain_format

std::array<std::pair<const char*, double>, 8> terrain_fields(const TerrainFile& t) {
  const Heightfield& h = t.mesh;
  return {{{"x0", h.x0},
           {"y0", h.y0},
           {"dx", h.dx},
           {"dy", h.dy},
           {"zmin", h.zmin},
           {"zmax", h.zmax},
           {"origin_x", t.origin_x},
           {"origin_y", t.origin_y}}};
}

TerrainFile decode_terrain(std::span<const uint8_t> b, const std::string& label) {
  using namespace terrain_format;
  auto bad = [&](const std::string& what) {
    fail<format_error>(kTerrainStage, label + ": " + what);
  };
  const uint32_t header = check_header(b, label);
  TerrainFile t;
  Heightfield& h = t.mesh;
  h.nx = get<uint32_t>(b, kNx);
  h.ny = get<uint32_t>(b, kNy);
  h.x0 = get<double>(b, kX0);
  h.y0 = get<double>(b, kY0);
  h.dx = get<double>(b, kDx);
  h.dy = get<double>(b, kDy);
  h.zmin = get<double>(b, kZmin);
  h.zmax = get<double>(b, kZmax);
  h.surface_error_bound = get<double>(b, kBound);
  t.origin_x = get<double>(b, kOriginX);
  t.origin_y = get<double>(b, kOriginY);
  t.source_xxh64 = get<uint64_t>(b, kSourceHash);
  const uint32_t codec = get<uint32_t>(b, kCodec);
  check_fields(b, t, codec, label);
  const std::span<const uint8_t> stored = b.subspan(header);
  if (get<uint64_t>(b, kHeightsChecksum) != XXH64(stored.data(), stored.size(), 0))
    bad("heights_checksum: mismatch (the heights are damaged)");
  const size_t n = size_t(h.nx) * h.ny;
  std::vector<uint8_t> raw;
  std::span<const uint8_t> planes = stored;
  if (codec == kCodecZstd) {
    const unsigned long long content = ZSTD_getFrameContentSize(stored.data(), stored.size());
    if (content != n * 8)
      bad("heights: the zstd frame's content size is not nx * ny * 8 = " + std::to_string(n * 8));
    if (ZSTD_findFrameCompressedSize(stored.data(), stored.size()) != stored.size())
      bad("heights: the stored bytes are not exactly one zstd frame");
    raw.resize(n * 8);
    const size_t got = ZSTD_decompress(raw.data(), raw.size(), stored.data(), stored.size());
    if (ZSTD_isError(got) || got != raw.size())
      bad(std::string("heights: zstd decoding failed: ") +
          (ZSTD_isError(got) ? ZSTD_getErrorName(got) : "short output"));
    planes = raw;
  }
  h.z = heights_of(planes, n);
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (size_t v = 0; v < n; ++v) {
    if (!std::isfinite(h.z[v]) || std::abs(h.z[v]) > kMaxMetres)
      bad("heights: vertex " + std::to_string(v) + " (i " + std::to_string(v % h.nx) + ", j " +
          std::to_string(v / h.nx) + ") is " + num(h.z[v]) + ", not a finite height");
    lo = std::min(lo, h.z[v]);
    hi = std::max(hi, h.z[v]);
  }
  if (lo != h.zmin) bad("zmin: " + num(h.zmin) + " is not the lowest height " + num(lo));
  if (hi != h.zmax) bad("zmax: " + num(h.zmax) + " is not the highest height " + num(hi));
  return t;
}

TerrainFile read_terrain_file(const std::string& path) {
  using terrain_format::kHeaderSize;
  // A header, the largest mesh's raw heights, and room for a longer header.
  constexpr uint64_t kMaxBytes = kHeaderSize + kTerrainMaxVertices * 8 + (uint64_t(1) << 20);
  int fd = -1;
  uint64_t size = 0;
  if (const decal::Status s = decal::open_regular_file(path, fd, size); !s)
    fail<input_error>(kTerrainStage, "cannot read the terrain file: " + s.message);
  if (size > kMaxBytes) {
    ::close(fd);
    fail<input_error>(kTerrainStage, path + ": " + std::to_string(size) +
                                         " bytes, more than a terrain file holds");
  }
  std::vector<uint8_t> bytes(size);
  for (size_t done = 0; done < bytes.size();) {
    const ssize_t n = ::read(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int err = errno;
      ::close(fd);
      fail<input_error>(kTerrainStage, "cannot read " + path + ": " +
                                           (n == 0 ? "the file shrank" : std::strerror(err)));
    }
    done += size_t(n);
  }
  ::close(fd);
  return decode_terrain(bytes, path);
}

}  // namespace prep::render
