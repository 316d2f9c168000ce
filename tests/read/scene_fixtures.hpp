// Scenes, dry runs and manifest lookups the read, project and clean tests
// share (they link libprep; fixtures.hpp stays free of it).
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "prep/features.hpp"
#include "prep/pipeline.hpp"
#include "prep/project.hpp"

namespace prep::test {

// A layer named `name` that reads `source` as `kind`.
inline LayerSpec layer_of(const std::string& name, const std::string& source,
                          DecalKind kind = DecalKind::polygon) {
  LayerSpec l;
  l.name = name;
  l.source = source;
  l.kind = kind;
  return l;
}

// A scene of that one layer.
inline BuildSpec one_layer(const std::string& name, const std::string& source,
                           DecalKind kind = DecalKind::polygon) {
  BuildSpec s;
  s.layers.push_back(layer_of(name, source, kind));
  return s;
}

// The cleaned scene of a dry run of the pipeline (nothing written).
inline SceneFeatures dry_run(const BuildSpec& s) {
  BuildRequest req;
  req.dry_run = true;
  return run_build(s, req).scene;
}

// clean's input of one polygon feature (fid 1, `rings`: shell then holes)
// of layer `name`, read once, in a frame of point scale 1.
inline ProjectedFeatures one_polygon_input(const std::string& name,
                                           const std::vector<Ring>& rings) {
  ProjectedFeatures in;
  SourceLayer layer;
  layer.spec.name = name;
  layer.spec.kind = DecalKind::polygon;
  SourceFeature f;
  f.fid = 1;
  f.is_polygon = true;
  f.rings = rings;
  layer.features.push_back(f);
  in.features.layers.push_back(layer);
  in.features.manifest.layers.push_back({});
  in.features.manifest.layers.back().layer = name;
  in.features.manifest.layers.back().read = 1;
  in.scale = {{1.0}};
  return in;
}

// Whether the manifest has an entry for `fid` with `action`.
inline bool has_entry(const Manifest& m, int64_t fid, ManifestAction action) {
  for (const auto& e : m.entries)
    if (e.fid == fid && e.action == action) return true;
  return false;
}

// Whether one of the manifest's notes contains `text`.
inline bool has_note(const Manifest& m, std::string_view text) {
  for (const auto& n : m.notes)
    if (n.find(text) != std::string::npos) return true;
  return false;
}

}  // namespace prep::test
