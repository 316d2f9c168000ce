// Read features spilled to disk (not a public header): the prepare step of
// a tileset reads every source once, writing each scene layer's features
// (prep/features.hpp SourceFeature, every field, coordinates as the read stage
// gave them) to a file of its own in DIR/.work; the frame, the projection's
// fit and the cleaned chunks then come from these files, read front to back.
// A scratch file of this process's own structs, never kept: a record is the
// SourceFeature's fields in order, little-endian as in memory.
#pragma once

#include <cstdint>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

#include "prep/features.hpp"
#include "prep/project.hpp"

namespace prep::tiling {

class SpillWriter {
 public:
  explicit SpillWriter(std::string path);
  ~SpillWriter();
  SpillWriter(const SpillWriter&) = delete;
  SpillWriter& operator=(const SpillWriter&) = delete;
  // Appends the chunk's features.
  void write(const SourceLayer& chunk);
  // Forgets everything written (the layer is read again).
  void restart();
  void close();
  uint64_t parts() const { return parts_; }

 private:
  void open();
  std::string path_;
  std::FILE* f_ = nullptr;
  uint64_t parts_ = 0;
  std::vector<char> buf_;
};

// The spilled layers as a FeatureSource (prep/project.hpp), and in chunks.
class SpillSource final : public FeatureSource {
 public:
  // layers[i]: spec and srs_wkt of scene layer i (its features are in paths[i]).
  SpillSource(const std::vector<SourceLayer>& layers, std::vector<std::string> paths);
  size_t layer_count() const override { return layers_.size(); }
  const LayerSpec& spec(size_t layer) const override { return layers_[layer].spec; }
  const std::string& srs_wkt(size_t layer) const override { return layers_[layer].srs_wkt; }
  void for_each(size_t layer,
                const std::function<void(const SourceFeature&)>& visit) const override;
  // The layer's features in chunks of at least `parts` parts or
  // `vertices` vertices (the last may be smaller), each ending with a whole
  // input feature; the chunk carries the layer's spec and srs_wkt, and
  // `take` may move its features out.
  void chunks(size_t layer, size_t parts, size_t vertices,
              const std::function<void(SourceLayer&)>& take) const;

 private:
  const std::vector<SourceLayer>& layers_;
  std::vector<std::string> paths_;
};

}  // namespace prep::tiling
