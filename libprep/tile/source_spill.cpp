// Read features spilled to disk (source_spill.hpp).
#include "source_spill.hpp"

#include <cerrno>
#include <cstring>
#include <type_traits>

#include "prep/error.hpp"
#include "prep/stage_error.hpp"

namespace prep::tiling {

namespace {

// Appends raw bytes (resize and memcpy: GCC 12 warns falsely on
// vector::insert of a few bytes).
void put_bytes(std::vector<char>& b, const void* p, size_t n) {
  const size_t at = b.size();
  b.resize(at + n);
  if (n > 0) std::memcpy(b.data() + at, p, n);
}

template <class T>
void put(std::vector<char>& b, const T& v) {
  static_assert(std::is_trivially_copyable_v<T>);
  put_bytes(b, &v, sizeof v);
}

void put_string(std::vector<char>& b, const std::string& s) {
  put(b, uint64_t(s.size()));
  put_bytes(b, s.data(), s.size());
}

// Buffered reads of one spill file.
class Reader {
 public:
  explicit Reader(const std::string& path) : path_(path), f_(std::fopen(path.c_str(), "rb")) {
    if (!f_) fail<output_error>(kTilesetStage, "cannot read " + path + ": " + std::strerror(errno));
    std::setvbuf(f_, nullptr, _IOFBF, 1 << 20);
  }
  ~Reader() { std::fclose(f_); }
  Reader(const Reader&) = delete;
  Reader& operator=(const Reader&) = delete;

  // The next feature into `f`; false at the end of the file.
  bool next(SourceFeature& f) {
    int64_t fid = 0;
    if (std::fread(&fid, sizeof fid, 1, f_) != 1) return false;
    f.fid = fid;
    get(f.part);
    get(f.feature);
    uint8_t flags = 0, stage = 0;
    get(flags);
    get(stage);
    f.is_polygon = (flags & 1) != 0;
    f.is_point = (flags & 4) != 0;
    f.failed_in =
        (flags & 2) ? std::optional<FailureStage>(static_cast<FailureStage>(stage)) : std::nullopt;
    get(f.order_value);
    get(f.color_value);
    get_string(f.repairs);
    get_string(f.drop_reason);
    uint64_t rings = 0;
    get(rings);
    f.rings.resize(rings);
    for (Ring& r : f.rings) {
      uint64_t n = 0;
      get(n);
      r.resize(n);
      if (n > 0 && std::fread(r.data(), sizeof(Point2), n, f_) != n) truncated();
    }
    return true;
  }

 private:
  template <class T>
  void get(T& v) {
    if (std::fread(&v, sizeof v, 1, f_) != 1) truncated();
  }
  void get_string(std::string& s) {
    uint64_t n = 0;
    get(n);
    s.resize(n);
    if (n > 0 && std::fread(s.data(), 1, n, f_) != n) truncated();
  }
  [[noreturn]] void truncated() { fail<output_error>(kTilesetStage, path_ + " is truncated"); }

  std::string path_;
  std::FILE* f_;
};

}  // namespace

SpillWriter::SpillWriter(std::string path) : path_(std::move(path)) {
  open();
}

SpillWriter::~SpillWriter() {
  if (f_) std::fclose(f_);
}

void SpillWriter::open() {
  f_ = std::fopen(path_.c_str(), "wb");
  if (!f_)
    fail<output_error>(kTilesetStage, "cannot create " + path_ + ": " + std::strerror(errno));
  std::setvbuf(f_, nullptr, _IOFBF, 1 << 20);
}

void SpillWriter::write(const SourceLayer& chunk) {
  static_assert(sizeof(Point2) == 2 * sizeof(double));
  for (const SourceFeature& f : chunk.features) {
    buf_.clear();
    put(buf_, int64_t(f.fid));
    put(buf_, f.part);
    put(buf_, f.feature);
    put(buf_, uint8_t((f.is_polygon ? 1 : 0) | (f.failed_in ? 2 : 0) | (f.is_point ? 4 : 0)));
    put(buf_, uint8_t(f.failed_in ? static_cast<int>(*f.failed_in) : 0));
    put(buf_, f.order_value);
    put(buf_, f.color_value);
    put_string(buf_, f.repairs);
    put_string(buf_, f.drop_reason);
    put(buf_, uint64_t(f.rings.size()));
    bool ok = std::fwrite(buf_.data(), 1, buf_.size(), f_) == buf_.size();
    for (const Ring& r : f.rings) {
      const uint64_t n = r.size();
      ok = ok && std::fwrite(&n, sizeof n, 1, f_) == 1;
      ok = ok && (n == 0 || std::fwrite(r.data(), sizeof(Point2), n, f_) == n);
    }
    if (!ok)
      fail<output_error>(kTilesetStage, "cannot write " + path_ + ": " + std::strerror(errno));
    ++parts_;
  }
}

void SpillWriter::restart() {
  if (f_) std::fclose(f_);
  f_ = nullptr;
  parts_ = 0;
  open();
}

void SpillWriter::close() {
  if (!f_) return;
  const bool ok = std::fclose(f_) == 0;
  f_ = nullptr;
  if (!ok) fail<output_error>(kTilesetStage, "cannot write " + path_);
}

SpillSource::SpillSource(const std::vector<SourceLayer>& layers, std::vector<std::string> paths)
    : layers_(layers), paths_(std::move(paths)) {}

void SpillSource::for_each(size_t layer,
                           const std::function<void(const SourceFeature&)>& visit) const {
  Reader in(paths_[layer]);
  SourceFeature f;
  while (in.next(f)) visit(f);
}

void SpillSource::chunks(size_t layer, size_t parts, size_t vertices,
                         const std::function<void(SourceLayer&)>& take) const {
  Reader in(paths_[layer]);
  SourceLayer chunk;
  chunk.spec = layers_[layer].spec;
  chunk.srs_wkt = layers_[layer].srs_wkt;
  SourceFeature f;
  size_t held = 0;  // vertices in the chunk
  while (in.next(f)) {
    if ((chunk.features.size() >= parts || held >= vertices) &&
        chunk.features.back().feature != f.feature) {
      take(chunk);
      chunk.features.clear();
      held = 0;
    }
    for (const Ring& r : f.rings) held += r.size();
    chunk.features.push_back(std::move(f));
    f = SourceFeature{};
  }
  if (!chunk.features.empty()) take(chunk);
}

}  // namespace prep::tiling
