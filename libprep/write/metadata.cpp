// metadata.cpp — write_model: the JSON metadata chunk of a package built
// from a DecalModel (formats/SPEC.md §"Metadata"), then write_package.
#include <cmath>
#include <nlohmann/json.hpp>
#include <span>
#include <string>

#include "decal/inspect.hpp"
#include "prep/error.hpp"
#include "prep/manifest_json.hpp"
#include "prep/stage_error.hpp"
#include "prep/write.hpp"
#include "write_internal.hpp"

namespace prep {

namespace {

using json = nlohmann::json;

// The manifest summary for the metadata chunk; the entries go to the
// manifest_entries blob (manifest_entries_json).
json manifest_json(const Manifest& m) {
  json layers = json::array();
  for (const LayerCounts& l : m.layers) layers.push_back(layer_counts_json(l));
  return {{"layers", layers}, {"notes", m.notes}, {"entry_count", m.entries.size()}};
}

std::string manifest_entries_json(const Manifest& m) {
  json entries = json::array();
  for (const ManifestEntry& e : m.entries) entries.push_back(manifest_entry_json(e));
  return entries.dump();
}

// Adds `extra` into `base`; objects present in both merge recursively, any
// other key present in both is a conflict (the model's own facts are not
// silently replaced).
void merge(json& base, const json& extra, const std::string& where, const std::string& path) {
  for (auto it = extra.begin(); it != extra.end(); ++it) {
    auto found = base.find(it.key());
    if (found == base.end()) {
      base[it.key()] = it.value();
    } else if (found->is_object() && it.value().is_object()) {
      merge(*found, it.value(), where + it.key() + ".", path);
    } else {
      fail<output_error>(kWriteStage, path + ": extra metadata key '" + where + it.key() +
                                          "' conflicts with a key write_model sets");
    }
  }
}

// The structural check `decalprep verify` runs on a package's blobs
// (decal::validate_blobs, formats/SPEC.md "Index constraints"), on a
// model's blobs before any byte is written: the build never writes a
// package its own verify refuses (a line 2·10^7 m wide, an index out of
// range). write_package itself stays a raw writer (tests make hostile
// packages with it). Linear in the blobs' bytes.
void check_blobs_verify(const std::string& path, const std::vector<BlobInput>& blobs,
                        const GridParams& g) {
  std::vector<decal::BlobBytes> known;
  known.reserve(blobs.size());
  for (const BlobInput& b : blobs)
    if (decal::find_blob_info(b.id) && b.stride == decal::find_blob_info(b.id)->stride &&
        b.bytes.size() == b.count * uint64_t(b.stride))
      known.push_back({b.id, b.count, b.bytes});
  // With the grid: its int32 range and one per-cell element per cell, as
  // the evaluator and the GL loader check them.
  const decal::Grid grid{g.origin_x, g.origin_y, g.cell_w, g.cell_h, g.nx, g.ny};
  if (const decal::Status s = decal::validate_blobs(known, {&grid}); !s)
    fail<output_error>(kWriteStage,
                       path + ": the package would not verify, not written: " + s.message);
}

// write_model of `model`'s blobs `blobs` (model_blobs or take_model_blobs:
// the model's blob arrays are not read here, they may have been taken).
void write_model_blobs(const std::string& path, const DecalModel& model,
                       std::vector<BlobInput> blobs_in, const std::string& extra_metadata_json,
                       const WriteOptions& options) {
  json extra;
  if (!extra_metadata_json.empty()) {
    try {
      extra = json::parse(extra_metadata_json);
    } catch (const json::exception& e) {
      fail<output_error>(kWriteStage, path + ": extra metadata is not valid JSON: " + e.what());
    }
    if (!extra.is_object())
      fail<output_error>(kWriteStage, path + ": extra metadata must be a JSON object");
  }
  // The writer compresses the model's arrays while one of its threads makes
  // the metadata.
  if (options.check_blobs) check_blobs_verify(path, blobs_in, model.grid);
  PackageSource source;
  source.blobs = std::move(blobs_in);
  std::vector<BlobInput>& blobs = source.blobs;
  // The counts the metadata gives, from the blobs (before any is freed).
  json counts = json::object();
  uint64_t lines = 0, polygons = 0, dynamic_lines = 0, lod_lines = 0;
  for (const BlobInput& b : blobs) {
    counts[std::string(decal::find_blob_info(b.id)->name)] = b.count;
    if (b.id == decal::BlobId::line_props) lines = b.count;
    if (b.id == decal::BlobId::poly_props) polygons = b.count;
    if (b.id == decal::BlobId::dyn_line_props) dynamic_lines = b.count;
    if (b.id == decal::BlobId::lod_line_range) lod_lines = b.count;
  }
  counts["lines"] = lines;
  counts["polygons"] = polygons;
  counts["dynamic_lines"] = dynamic_lines;
  counts["lod_lines"] = lod_lines;
  const std::string entries = manifest_entries_json(model.manifest);
  blobs.push_back({decal::BlobId::manifest_entries, decal::ElementType::u8, 1, entries.size(),
                   std::as_bytes(std::span(entries.data(), entries.size()))});
  counts["manifest_entries"] = entries.size();
  source.complete = [&]() -> std::string {
    const GridParams& g = model.grid;
    json meta = {
        {"format", "decals"},
        {"quantum_m", decal::kQuantumMetres},
        {"crs_wkt", model.frame.crs_wkt},
        {"frame", model.frame.description},
        {"origin", {{"x", model.frame.origin_x}, {"y", model.frame.origin_y}}},
        {"extent", {model.extent.xmin, model.extent.ymin, model.extent.xmax, model.extent.ymax}},
        {"grid",
         {{"origin", {g.origin_x, g.origin_y}},
          {"cell", {g.cell_w, g.cell_h}},
          {"dims", {g.nx, g.ny}}}},
        {"max_representation_error_m", model.max_representation_error},
        {"terrain", {{"min", model.terrain_min}, {"max", model.terrain_max}}},
        {"counts", counts},
        {"manifest", manifest_json(model.manifest)},
    };
    if (!extra.is_null()) merge(meta, extra, "", path);
    // Keys are sorted (nlohmann::json is map-backed), so the text is
    // deterministic; non-finite numbers are written as null.
    return meta.dump();
  };
  write_package_consuming(path, source, options);
}

}  // namespace

void write_model(const std::string& path, const DecalModel& model,
                 const std::string& extra_metadata_json, const WriteOptions& options) {
  write_model_blobs(path, model, model_blobs(model, /*include_empty=*/true), extra_metadata_json,
                    options);
}

void write_model(const std::string& path, DecalModel&& model,
                 const std::string& extra_metadata_json, const WriteOptions& options) {
  std::vector<BlobInput> blobs = take_model_blobs(model);
  write_model_blobs(path, model, std::move(blobs), extra_metadata_json, options);
}

}  // namespace prep
