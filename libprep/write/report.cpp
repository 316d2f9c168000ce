// The build's report and a package's metadata (prep/write.hpp): the JSON
// of the manifest, the frame, the layers and the sources, and the paths a
// package records.
#include "prep/write.hpp"

#include <algorithm>
#include <filesystem>
#include <string_view>

#include "prep/files.hpp"
#include "prep/manifest_json.hpp"

namespace prep {

namespace {

nlohmann::json manifest_json(const Manifest& m, bool with_entries) {
  nlohmann::json layers = nlohmann::json::array();
  for (const LayerCounts& c : m.layers) layers.push_back(layer_counts_json(c));
  nlohmann::json j = {{"layers", layers}, {"totals", totals_json(m)}, {"notes", m.notes}};
  if (with_entries) {
    nlohmann::json entries = nlohmann::json::array();
    for (const ManifestEntry& e : m.entries) entries.push_back(manifest_entry_json(e));
    j["entries"] = std::move(entries);
  }
  j["entry_count"] = m.entries.size();
  return j;
}

nlohmann::json frame_json(const SceneFrame& f, const Extent& e) {
  return {{"crs_wkt", f.crs_wkt},
          {"description", f.description},
          {"origin", {f.origin_x, f.origin_y}},
          {"extent", {e.xmin, e.ymin, e.xmax, e.ymax}}};
}

nlohmann::json layers_json(const std::vector<LayerSpec>& layers) {
  nlohmann::json out = nlohmann::json::array();
  for (const LayerSpec& l : layers) {
    out.push_back({{"name", l.name},
                   {"source", l.source},
                   {"layer", l.layer},
                   {"where", l.where},
                   {"sql", l.sql},
                   {"kind", kind_name(l.kind)},
                   {"dynamic", l.dynamic},
                   {"width", l.style.width},
                   {"width_unit", l.dynamic ? "pixel" : "ground metre"},
                   {"color_rgba", l.style.color.rgba},
                   {"color_attribute", l.style.color.attribute},
                   {"corner", static_cast<uint32_t>(l.style.corner)},
                   {"outline_mode", static_cast<uint32_t>(l.style.outline)},
                   {"order_attribute", l.style.order_attribute}});
    if (!l.casing_of.empty()) out.back()["casing_of"] = l.casing_of;
    if (l.slope_widths) out.back()["slope_widths"] = true;
    if (!l.light) out.back()["light"] = false;  // formats/SPEC.md "Lit decals"
    if (l.min_width_px > 0) out.back()["min_width_px"] = l.min_width_px;  // "Minimum widths"
    if (l.min_width_m > 0) out.back()["min_width_m"] = l.min_width_m;
    if (!l.dash.empty()) out.back()["dash"] = l.dash;  // formats/SPEC.md "Dashed lines"
    // The stops an attribute-coloured layer's values went through (the
    // colours baked into the props); `render --ramp` maps them anew.
    if (!l.style.color.attribute.empty()) {
      nlohmann::json stops = nlohmann::json::array();
      for (const ColorStop& c : l.style.color.ramp) stops.push_back({c.value, c.rgba});
      out.back()["color_ramp"] = stops;
    }
  }
  return out;
}

}  // namespace

// The manifest's "totals": every count summed over the layers, without "layer".
nlohmann::json totals_json(const Manifest& m) {
  nlohmann::json totals = layer_counts_json(manifest_totals(m));
  totals.erase("layer");
  return totals;
}

// Provenance: path, size and XXH64 of every local source (formats/SPEC.md "Metadata").
nlohmann::json provenance_json(const BuildSpec& scene) {
  nlohmann::json sources = nlohmann::json::array();
  std::vector<std::string> paths;
  for (const LayerSpec& l : scene.layers) paths.push_back(l.source);
  for (const std::string& dem : dem_paths(scene)) paths.push_back(dem);
  std::sort(paths.begin(), paths.end());
  paths.erase(std::unique(paths.begin(), paths.end()), paths.end());
  for (const std::string& p : paths) {
    nlohmann::json s = {{"path", p}};
    // Hash the file itself (for /vsizip/x.zip/y: the archive).
    std::string file = p;
    if (file.rfind("/vsizip/", 0) == 0) {
      file = file.substr(8);
      auto zip = file.find(".zip");
      if (zip != std::string::npos) file = file.substr(0, zip + 4);
    }
    if (const std::optional<FileDigest> d = file_digest(file)) {
      s["file"] = file;
      s["bytes"] = d->bytes;
      s["xxh64"] = hex64(d->xxh64);
    }
    sources.push_back(std::move(s));
  }
  return sources;
}

nlohmann::json report_object(const SceneFeatures& scene, const std::string& output,
                             const std::vector<std::pair<std::string, double>>& timings,
                             bool package_written) {
  nlohmann::json j;
  j["report_version"] = 1;
  j["output"] = output;
  j["package_written"] = package_written;
  j["frame"] = frame_json(scene.frame, scene.extent);
  j["layers"] = layers_json(scene.layers);
  j["manifest"] = manifest_json(scene.manifest, true);
  j["output_counts"] = {{"polygons", scene.polygons.size()},
                        {"lines", scene.lines.size()},
                        {"dynamic_lines", scene.dynamic_lines.size()}};
  nlohmann::json t = nlohmann::json::object();
  for (const auto& [stage, s] : timings) t[stage] = s;
  j["timings_s"] = t;
  return j;
}

LayerCounts manifest_totals(const Manifest& manifest) {
  LayerCounts total;
  for (const LayerCounts& c : manifest.layers) total += c;
  return total;
}

std::string report_json(const SceneFeatures& scene, const std::string& output,
                        const std::vector<std::pair<std::string, double>>& timings,
                        bool package_written) {
  return report_object(scene, output, timings, package_written).dump(2) + "\n";
}

namespace {

// ------------------------------------------------------ recorded paths --
// The folder a package's paths are recorded relative to: the scene file's,
// or the working folder for the file-less form (whose paths are as typed,
// relative to it). Absolute and lexically normal.
std::filesystem::path record_base(const BuildSpec& scene) {
  namespace fs = std::filesystem;
  const fs::path cwd = fs::current_path();
  if (scene.scene_path.empty()) return cwd.lexically_normal();
  return (cwd / fs::path(scene.scene_path)).parent_path().lexically_normal();
}

// A path as a package records it (formats/SPEC.md "Metadata"): relative to
// `base` when the two share a folder below the root, so that a package's
// bytes do not depend on where a checkout lives, on the working folder or on
// how the scene path was typed; absolute when they share only the root (a
// chain of ../ up to it would say no more). The archive path of /vsizip/,
// /vsigzip/, /vsitar/ and /vsi7z/ is recorded so, behind its prefix; what is
// not a local path (a URL, "PG:...", another /vsi handler) is kept as given.
// Lexical only: no file is opened and symbolic links are not followed.
std::string recorded_path(const std::string& path, const std::filesystem::path& base) {
  namespace fs = std::filesystem;
  if (path.empty() || path.find("://") != std::string::npos) return path;
  std::string prefix, rest = path;
  if (path.rfind("/vsi", 0) == 0) {
    for (std::string_view p : {"/vsizip/", "/vsigzip/", "/vsitar/", "/vsi7z/"})
      if (path.rfind(p, 0) == 0) prefix = p;
    if (prefix.empty()) return path;
    rest = path.substr(prefix.size());
    if (rest.empty() || rest[0] == '{' || rest.rfind("/vsi", 0) == 0) return path;
  } else {
    const auto colon = path.find(':');
    if (colon != std::string::npos && colon > 1 && path.find('/') > colon) return path;
  }
  const fs::path abs = (fs::current_path() / fs::path(rest)).lexically_normal();
  const fs::path rel = abs.lexically_relative(base);
  if (rel.empty()) return path;
  size_t up = 0, depth = 0;
  for (const fs::path& part : rel) up += part == "..";
  for (const fs::path& part : base.relative_path()) depth += !part.empty();
  if (up >= depth) return prefix + abs.string();  // only the root in common
  return prefix + rel.string();
}

// The provenance a package records: its "path" and "file" as recorded_path,
// sorted by the recorded path (as provenance_json sorts the given ones, whose
// order depends on the folders).
nlohmann::json recorded_provenance(const nlohmann::json& provenance,
                                   const std::filesystem::path& base) {
  nlohmann::json out = provenance;
  if (!out.is_array()) return out;
  for (nlohmann::json& s : out)
    for (const char* key : {"path", "file"})
      if (s.contains(key) && s[key].is_string())
        s[key] = recorded_path(s[key].get<std::string>(), base);
  std::stable_sort(out.begin(), out.end(), [](const nlohmann::json& a, const nlohmann::json& b) {
    return a.value("path", std::string()) < b.value("path", std::string());
  });
  return out;
}

}  // namespace

// The manifest a package records: its notes and entry reasons name the
// sources and the DEM as recorded_path records them (a note describes the
// DEM by its path as given, a read note its source's).
void record_manifest_paths(const BuildSpec& scene, Manifest& manifest) {
  const std::filesystem::path base = record_base(scene);
  std::vector<std::pair<std::string, std::string>> paths;
  auto add = [&](const std::string& p) {
    const std::string r = recorded_path(p, base);
    if (!p.empty() && r != p) paths.emplace_back(p, r);
  };
  for (const std::string& dem : dem_paths(scene)) add(dem);
  for (const LayerSpec& l : scene.layers) add(l.source);
  // Longest first: a path that holds another is replaced whole.
  std::sort(paths.begin(), paths.end(),
            [](const auto& a, const auto& b) { return a.first.size() > b.first.size(); });
  auto fix = [&](std::string& text) {
    for (const auto& [given, recorded] : paths)
      for (size_t at = text.find(given); at != std::string::npos;
           at = text.find(given, at + recorded.size()))
        text.replace(at, given.size(), recorded);
  };
  for (std::string& n : manifest.notes) fix(n);
  for (ManifestEntry& e : manifest.entries) fix(e.reason);
}

// Keys must not collide with write_model's. Paths are recorded relative to
// the scene file's folder (recorded_path), the DEM relative to the
// package's own folder when `package_path` is given, since `render` looks
// for it there (formats/SPEC.md "Metadata"); the report keeps them as given.
nlohmann::json package_metadata(const BuildSpec& scene, const Manifest& manifest,
                                const nlohmann::json& provenance, const std::string& package_path) {
  const std::filesystem::path base = record_base(scene);
  auto record_dem = [&](const std::string& path) {
    return package_path.empty()
               ? path
               : recorded_path(path, (std::filesystem::current_path() / package_path)
                                         .lexically_normal()
                                         .parent_path());
  };
  // One raster: its path, as before mosaics; a mosaic: the list.
  nlohmann::json dem = record_dem(scene.dem);
  if (!scene.dem_more.empty()) {
    dem = nlohmann::json::array();
    for (const std::string& p : dem_paths(scene)) dem.push_back(record_dem(p));
  }
  nlohmann::json totals = totals_json(manifest);
  nlohmann::json extra;
  extra["manifest"]["totals"] = totals;
  extra["layers"] = layers_json(scene.layers);
  for (nlohmann::json& l : extra["layers"])
    l["source"] = recorded_path(l["source"].get<std::string>(), base);
  extra["provenance"] = recorded_provenance(provenance, base);
  extra["scene_file"] = recorded_path(scene.scene_path, base);
  extra["build_options"] = {
      {"resolution_m", scene.resolution},
      {"repair", scene.repair == RepairMethod::structure ? "structure" : "linework"},
      {"crs", scene.crs},
      {"dem", dem},
      {"grid", {scene.model.grid_nx, scene.model.grid_ny}},
      {"qt_leaf_capacity", scene.model.qt_leaf_capacity},
      {"qt_max_depth", scene.model.qt_max_depth},
      {"miter_limit_deg", scene.model.miter_limit_deg}};
  // What decides the DEM surface (prep/dem.hpp), so that `decalprep render`
  // draws the surface the dynamic lines were matched to. Only with a DEM.
  if (!scene.dem.empty()) {
    auto& bo = extra["build_options"];
    bo["dem_assume_crs"] = scene.assume_crs;
    bo["z_scale"] = scene.model.z_scale;
    bo["nodata_fill"] = scene.model.nodata_fill ? nlohmann::json(*scene.model.nodata_fill)
                                                : nlohmann::json(nullptr);
  }
  return extra;
}

}  // namespace prep
