// Stage 1 — read. GDAL/OGR sources -> FeatureSet, in the source CRS.
//
// Every input feature appears in the FeatureSet at least once (as one
// SourceFeature per part, or as a placeholder carrying drop_reason), so the
// clean stage can account for 100 % of the features (ARCHITECTURE.md "Guarantees" 4).
#include "prep/read.hpp"

#include <cpl_conv.h>
#include <cpl_error.h>
#include <cpl_vsi.h>
#include <gdal.h>
#include <gdal_priv.h>
#include <ogr_geometry.h>
#include <ogr_spatialref.h>
#include <ogrsf_frmts.h>

#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <memory>
#include <mutex>
#include <optional>

#include "gdal_util.hpp"
#include "osm_xml_order.hpp"
#include "prep/error.hpp"
#include "prep/feature_failure.hpp"
#include "prep/files.hpp"
#include "prep/progress.hpp"
#include "prep/stage_error.hpp"

namespace prep {

namespace {

void register_gdal_once() {
  static std::once_flag once;
  std::call_once(once, [] { GDALAllRegister(); });
}

// Collects GDAL errors raised on this thread while it is alive, so the
// messages can be put into our exceptions (GDAL's last-error slot keeps only
// one, and the default handler would print to stderr).
class ErrorCapture {
 public:
  ErrorCapture() { CPLPushErrorHandlerEx(&ErrorCapture::handler, this); }
  ~ErrorCapture() { CPLPopErrorHandler(); }
  ErrorCapture(const ErrorCapture&) = delete;
  ErrorCapture& operator=(const ErrorCapture&) = delete;

  // The first failure, with how many more followed (GDAL often repeats one
  // problem for every remaining feature).
  std::string failures() const {
    if (count_ <= 1) return first_;
    return first_ + " (and " + std::to_string(count_ - 1) + " more GDAL errors)";
  }
  bool failed() const { return count_ > 0; }
  size_t count() const { return count_; }
  const std::string& last() const { return last_; }
  const std::vector<std::string>& warnings() const { return warnings_; }
  void clear() {
    first_.clear();
    count_ = 0;
    warnings_.clear();
  }

 private:
  static void CPL_STDCALL handler(CPLErr level, CPLErrorNum, const char* msg) {
    auto* self = static_cast<ErrorCapture*>(CPLGetErrorHandlerUserData());
    if (level >= CE_Failure) {
      if (self->count_++ == 0) self->first_ = msg;
      self->last_ = msg;
    } else if (level == CE_Warning && self->warnings_.size() < 20) {
      self->warnings_.emplace_back(msg);
    }
  }
  std::string first_, last_;
  size_t count_ = 0;
  std::vector<std::string> warnings_;
};

struct DatasetCloser {
  void operator()(GDALDataset* ds) const { GDALClose(ds); }
};
using DatasetPtr = std::unique_ptr<GDALDataset, DatasetCloser>;

// GDAL configuration options a read sets for the user (docs/build.md
// "GDAL configuration options decalprep sets"), thread-locally on the
// reading thread for as long as the object lives, each restored afterwards
// (CPLConfigOptionSetter):
//  - OGR_GEOJSON_MAX_OBJ_SIZE=0: GDAL's GeoJSON reader refuses a single
//    object whose parse it estimates above 200 MB ("GeoJSON object too
//    complex/large"); a large coastline or country polygon is such an object.
//    Only when the user has not set it.
//  - OSM_USE_CUSTOM_INDEXING=NO when `plain_osm_index`: OSM XML whose node
//    ids do not increase (osm_xml_order.hpp).
class ReadConfig {
 public:
  explicit ReadConfig(bool plain_osm_index) {
    geojson_.emplace("OGR_GEOJSON_MAX_OBJ_SIZE", "0", /*bSetOnlyIfUndefined=*/true);
    if (plain_osm_index)
      osm_.emplace("OSM_USE_CUSTOM_INDEXING", "NO", /*bSetOnlyIfUndefined=*/false);
  }

 private:
  std::optional<CPLConfigOptionSetter> geojson_, osm_;
};

std::string osm_plain_index_note(const std::string& layer) {
  return "layer '" + layer +
         "': OSM node ids do not increase (Overpass output?); read with "
         "OSM_USE_CUSTOM_INDEXING=NO";
}

// An OSM XML file listing a node after a way or relation: GDAL's OSM driver
// builds a way only from nodes read before it, so it would drop ways and
// multipolygons without a word. Only the `points` layer reads right.
[[noreturn]] void throw_late_nodes(const std::string& source, const std::string& where,
                                   const detail::OsmXmlOrder& order) {
  const std::string found = "OSM XML lists node " + order.late_node_id + " (byte " +
                            std::to_string(order.late_node_offset) + ") after " +
                            order.earlier_kind + " " + order.earlier_id;
  const std::string what_to_do =
      "Put the nodes first: sort the file (osmium sort " + source +
      " -o sorted.osm), or end the Overpass query with '(._;>;); out body;' instead of "
      "'out; >; out skel qt;'";
  fail<input_error>(kNoStage,
                    where + ": " + found +
                        "; GDAL's OSM driver assembles ways and multipolygons only from nodes that "
                        "come before them, so they would be lost. " +
                        what_to_do);
}

std::string where_of(const LayerSpec& spec, const std::string& layer_name) {
  std::string w = stage_message(kReadStage, spec.source);
  if (!spec.sql.empty()) return w + " sql \"" + spec.sql + "\"";
  return w + " layer '" + layer_name + "'";
}

// Per-feature state while splitting a geometry into parts.
struct Splitter {
  const LayerSpec& spec;
  std::vector<SourceFeature>& out;
  SourceFeature proto;  // fid, feature, order/colour values
  int next_part = 0;
  int unusable = 0;  // parts whose type the layer kind cannot draw
  std::string unusable_type;
  bool bad_coordinate = false;
  std::string bad_coordinate_text;
  bool had_zm = false;
  bool closed_ring = false;

  bool check(const OGRSimpleCurve& c) {
    for (int i = 0; i < c.getNumPoints(); ++i) {
      double x = c.getX(i), y = c.getY(i);
      if (!std::isfinite(x) || !std::isfinite(y)) {
        bad_coordinate = true;
        bad_coordinate_text = "vertex " + std::to_string(i) + " has a non-finite coordinate (" +
                              std::to_string(x) + ", " + std::to_string(y) + ")";
        return false;
      }
    }
    return true;
  }

  // Copies a polygon ring into an unclosed Ring (first point not repeated).
  Ring to_ring(const OGRSimpleCurve& c) {
    Ring r;
    int n = c.getNumPoints();
    r.reserve(n);
    for (int i = 0; i < n; ++i) r.push_back({c.getX(i), c.getY(i)});
    bool closed = n >= 2 && r.front().x == r.back().x && r.front().y == r.back().y;
    if (closed) r.pop_back();
    if (!closed && n >= 3) closed_ring = true;  // e.g. GeoJSON rings left open
    return r;
  }

  // Copies a line as given; a closed line keeps its repeated end point, which
  // tells clean that it is a ring.
  static Ring to_line(const OGRSimpleCurve& c, bool close) {
    Ring r;
    int n = c.getNumPoints();
    r.reserve(n + 1);
    for (int i = 0; i < n; ++i) r.push_back({c.getX(i), c.getY(i)});
    if (close && n >= 2 && (r.front().x != r.back().x || r.front().y != r.back().y))
      r.push_back(r.front());
    return r;
  }

  void add_point(const OGRPoint& p) {
    if (spec.kind != DecalKind::point) {
      ++unusable;
      unusable_type = "Point";
      return;
    }
    if (!std::isfinite(p.getX()) || !std::isfinite(p.getY())) {
      bad_coordinate = true;
      bad_coordinate_text = "the point has a non-finite coordinate (" + std::to_string(p.getX()) +
                            ", " + std::to_string(p.getY()) + ")";
      return;
    }
    SourceFeature f = proto;
    f.part = next_part++;
    f.is_point = true;
    f.rings.push_back({{p.getX(), p.getY()}});
    out.push_back(std::move(f));
  }

  void add_polygon(const OGRPolygon& p) {
    if (spec.kind == DecalKind::point) {
      ++unusable;
      unusable_type = "Polygon";
      return;
    }
    bool want_polygon = spec.kind != DecalKind::line;
    if (!want_polygon) {
      // A polygon in a line layer: its rings are drawn as closed lines.
      for (const OGRLinearRing* ring : p) add_curve(*ring, true);
      return;
    }
    SourceFeature f = proto;
    f.part = next_part++;
    f.is_polygon = true;
    for (const OGRLinearRing* ring : p) {
      if (!check(*ring)) return;
      f.rings.push_back(to_ring(*ring));
    }
    if (f.rings.empty()) return;
    out.push_back(std::move(f));
  }

  void add_curve(const OGRSimpleCurve& c, bool from_ring = false) {
    if (spec.kind != DecalKind::line && !from_ring) {
      ++unusable;
      unusable_type = "LineString";
      return;
    }
    if (!check(c)) return;
    SourceFeature f = proto;
    f.part = next_part++;
    f.rings.push_back(to_line(c, from_ring));
    out.push_back(std::move(f));
  }

  void add(const OGRGeometry* g) {
    if (g == nullptr || g->IsEmpty()) return;
    if (g->Is3D() || g->IsMeasured()) had_zm = true;
    if (g->hasCurveGeometry()) {
      // Circular arcs and curve polygons: linearised with GDAL's defaults.
      std::unique_ptr<OGRGeometry> linear(g->getLinearGeometry());
      add(linear.get());
      return;
    }
    switch (wkbFlatten(g->getGeometryType())) {
      case wkbPoint: add_point(*g->toPoint()); break;
      case wkbMultiPoint:
        for (const OGRGeometry* sub : *g->toGeometryCollection()) add(sub);
        break;
      case wkbPolygon:
      case wkbTriangle: add_polygon(*g->toPolygon()); break;
      case wkbLineString:
      case wkbLinearRing: add_curve(*g->toLineString()); break;
      case wkbMultiPolygon:
      case wkbMultiLineString:
      case wkbGeometryCollection:
      case wkbPolyhedralSurface:
      case wkbTIN:
        for (const OGRGeometry* sub : *g->toGeometryCollection()) add(sub);
        break;
      default:
        ++unusable;
        unusable_type = OGRGeometryTypeToName(g->getGeometryType());
        break;
    }
  }
};

int field_index(OGRLayer& layer, const std::string& name, const LayerSpec& spec, const char* what) {
  if (name.empty()) return -1;
  int i = layer.GetLayerDefn()->GetFieldIndex(name.c_str());
  if (i < 0) {
    std::string fields;
    for (int k = 0; k < layer.GetLayerDefn()->GetFieldCount(); ++k) {
      fields += (k ? ", " : "") + std::string(layer.GetLayerDefn()->GetFieldDefn(k)->GetNameRef());
    }
    fail<input_error>(kNoStage, where_of(spec, layer.GetName()) + ": " + what + " attribute '" +
                                    name + "' not found (fields: " + fields + ")");
  }
  return i;
}

double field_value(OGRFeature& f, int index) {
  if (index < 0 || !f.IsFieldSetAndNotNull(index)) return std::numeric_limits<double>::quiet_NaN();
  return f.GetFieldAsDouble(index);
}

// One read job's share of the stage "read": layers are read concurrently,
// each job (one layer, or one pass over an OSM file for several layers)
// counts its features into the stage and keeps an estimate of its total
// (the layer's feature count, or features so far / the fraction of the file
// GDAL has read); the stage's total is the sum once every job has one.
class JobProgress {
 public:
  static constexpr uint64_t kUnknown = UINT64_MAX;
  JobProgress() = default;
  JobProgress(ProgressStage* stage, std::vector<std::atomic<uint64_t>>* estimates, size_t job)
      : stage_(stage), estimates_(estimates), job_(job) {}

  // `features` read so far by this job, of about `estimate` (kUnknown).
  void update(uint64_t features, uint64_t estimate) {
    if (!stage_ || !stage_->active()) return;
    if (features > counted_) stage_->add(features - counted_);
    counted_ = std::max(counted_, features);
    (*estimates_)[job_].store(estimate, std::memory_order_relaxed);
    uint64_t sum = 0;
    for (const std::atomic<uint64_t>& e : *estimates_) {
      const uint64_t v = e.load(std::memory_order_relaxed);
      if (v == kUnknown) return;  // the stage total stays unknown
      sum += v;
    }
    stage_->set_total(sum);
  }

 private:
  ProgressStage* stage_ = nullptr;
  std::vector<std::atomic<uint64_t>>* estimates_ = nullptr;
  size_t job_ = 0;
  uint64_t counted_ = 0;
};

struct ReadAttempt {
  SourceLayer layer;
  LayerCounts counts;
  std::vector<ManifestEntry> entries;
  std::vector<std::string> notes;
  // Streaming (ReadOptions::chunks): whole features go to chunks->take.
  const ReadChunks* chunks = nullptr;
  size_t scene_layer = 0;

  void start(const ReadChunks* c, size_t index) {
    chunks = c;
    scene_layer = index;
    counted = vertices = 0;
    if (chunks && chunks->restart) chunks->restart(scene_layer);
  }
  size_t counted = 0, vertices = 0;  // of layer.features, since the last chunk

  // After a whole feature: hands a full chunk over (`last`: whatever is left).
  void flush(bool last = false) {
    if (!chunks || layer.features.empty()) return;
    for (; counted < layer.features.size(); ++counted)
      for (const Ring& ring : layer.features[counted].rings) vertices += ring.size();
    if (!last && layer.features.size() < chunks->parts && vertices < chunks->vertices) return;
    chunks->take(scene_layer, layer);
    layer.features.clear();
    counted = vertices = 0;
  }
};

// The feature loop's body for one scene layer: splits a feature into parts
// and accounts for it. Shared by the per-layer read and the one-pass OSM
// read, so both account for a feature the same way.
struct LayerSink {
  const LayerSpec& spec;
  const SceneSpec& scene;
  ReadAttempt& r;
  std::string ogr_layer;  // for error messages
  int order_field = -1, color_field = -1;
  uint64_t zm_features = 0, closed_rings = 0;

  SourceFeature proto_of(OGRFeature& feature) {
    const uint64_t index = r.counts.read++;
    SourceFeature proto;
    proto.fid = feature.GetFID();
    proto.feature = index;
    proto.order_value = field_value(feature, order_field);
    proto.color_value = field_value(feature, color_field);
    return proto;
  }

  void take_geometry(OGRFeature& feature_ref, SourceFeature& proto) {
    OGRFeature* feature = &feature_ref;
    const size_t first = r.layer.features.size();
    Splitter split{spec, r.layer.features, proto};
    split.add(feature->GetGeometryRef());
    if (split.bad_coordinate) {
      r.layer.features.resize(first);
      if (!scene.skip_failures) {
        fail_feature(FailureStage::read, spec.source, ogr_layer.c_str(), proto.fid,
                     split.bad_coordinate_text);
      }
      proto.drop_reason = split.bad_coordinate_text;
      proto.failed_in = FailureStage::read;
      r.layer.features.push_back(proto);
      return;
    }
    if (split.had_zm) ++zm_features;
    if (split.closed_ring) {
      ++closed_rings;
      for (size_t i = first; i < r.layer.features.size(); ++i)
        r.layer.features[i].repairs = "closed an open ring";
    }
    if (r.layer.features.size() == first) {
      // No usable part: keep a placeholder so the feature is accounted for.
      if (feature->GetGeometryRef() == nullptr || feature->GetGeometryRef()->IsEmpty())
        proto.drop_reason = "no geometry";
      else
        proto.drop_reason = "geometry type " + split.unusable_type + " cannot be drawn as kind " +
                            kind_name(spec.kind);
      r.layer.features.push_back(proto);
    } else if (split.unusable > 0) {
      ManifestEntry e;
      e.layer = spec.name;
      e.fid = proto.fid;
      e.action = ManifestAction::part_dropped;
      e.reason = std::to_string(split.unusable) + " " + split.unusable_type +
                 " part(s) cannot be drawn as kind " + kind_name(spec.kind);
      r.entries.push_back(std::move(e));
    }
  }

  void finish(const ErrorCapture& errors) {
    if (r.counts.read == 0) {
      // Not an error while another layer has data (project fails only when
      // every layer is empty): the package carries the layer, empty.
      r.notes.push_back("layer '" + spec.name + "': no features in " + spec.source +
                        (spec.where.empty() && spec.sql.empty()
                             ? std::string()
                             : std::string(" matching the filter")) +
                        "; the layer is in the package, empty");
    }
    if (zm_features > 0) {
      r.notes.push_back("layer '" + spec.name + "': Z/M values dropped from " +
                        std::to_string(zm_features) +
                        " features (decals are 2D; terrain comes "
                        "from the DEM)");
    }
    if (closed_rings > 0) {
      r.notes.push_back("layer '" + spec.name + "': closed open polygon rings in " +
                        std::to_string(closed_rings) + " features");
    }
    for (const std::string& w : errors.warnings())
      r.notes.push_back("layer '" + spec.name + "': GDAL warning: " + w);
  }
};

// Source CRS: the layer's, else --assume-crs; never a silent guess.
void source_crs(OGRLayer* layer_ptr, const LayerSpec& spec, const SceneSpec& scene,
                const std::string& where, ReadAttempt& r) {
  OGRLayer* layer = layer_ptr;
  if (const OGRSpatialReference* srs = layer->GetSpatialRef()) {
    r.layer.srs_wkt = crs_wkt2(*srs);
  }
  if (r.layer.srs_wkt.empty()) {
    if (scene.assume_crs.empty()) {
      fail<input_error>(kNoStage, where +
                                      ": the source has no CRS; pass --assume-crs (e.g. EPSG:4326) "
                                      "or set assume_crs in the scene file");
    }
    OGRSpatialReference assumed;
    if (assumed.SetFromUserInput(scene.assume_crs.c_str()) != OGRERR_NONE) {
      fail<input_error>(kNoStage, where + ": invalid --assume-crs '" + scene.assume_crs + "'");
    }
    r.layer.srs_wkt = crs_wkt2(assumed);
    r.notes.push_back("layer '" + spec.name + "': source has no CRS, assumed " + scene.assume_crs);
  }
}

bool is_osm(const std::string& path) {
  auto ends = [&](const char* suffix) {
    std::string s(suffix);
    return path.size() >= s.size() && path.compare(path.size() - s.size(), s.size(), s) == 0;
  };
  return ends(".osm") || ends(".pbf") || ends(".osm.bz2") || ends(".OSM") || ends(".PBF");
}

// Fails (gdal_error) when the source of `spec` does not exist, naming the
// scene file and layer when there is a scene file.
void check_source_exists(const LayerSpec& spec, const SceneSpec& scene) {
  VSIStatBufL st;
  if (VSIStatL(spec.source.c_str(), &st) != 0) {
    fail<gdal_error>(kReadStage,
                     spec.source + ": no such file" +
                         (scene.scene_path.empty() ? std::string()
                                                   : " (scene file " + scene.scene_path +
                                                         ", layer '" + spec.name + "')"));
  }
}

// The source of `spec` opened as vector data (under the caller's
// ReadConfig); fails (gdal_error) when GDAL cannot open it, or it has no
// layers and the query is no SQL.
DatasetPtr open_vector_source(const LayerSpec& spec, ErrorCapture& errors) {
  check_input_file(spec.source, "source", InputKind::file_or_directory);
  DatasetPtr ds(GDALDataset::Open(spec.source.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY, nullptr,
                                  nullptr, nullptr));
  if (!ds) {
    fail<gdal_error>(kReadStage,
                     spec.source + ": GDAL cannot open it as vector data" +
                         (errors.failures().empty() ? std::string() : ": " + errors.failures()));
  }
  if (ds->GetLayerCount() == 0 && spec.sql.empty()) {
    fail<gdal_error>(kReadStage, spec.source + ": the source has no vector layers");
  }
  return ds;
}

// A filter's scene layer for its error: "scene layer 'roads'
// (scene.toml:12)", or without the place in the file-less form.
std::string scene_layer_of(const LayerSpec& spec, const SceneSpec& scene) {
  return "scene layer '" + spec.name + "'" + layer_place(scene, spec);
}

// The attribute fields a filter may name: "fields: a, b" (at most 40, then
// how many more).
std::string fields_of(OGRLayer& layer) {
  OGRFeatureDefn* defn = layer.GetLayerDefn();
  const int n = defn->GetFieldCount();
  if (n == 0) return "no attribute fields";
  std::string s = "fields: ";
  for (int i = 0; i < n && i < 40; ++i)
    s += (i ? ", " : "") + std::string(defn->GetFieldDefn(i)->GetNameRef());
  if (n > 40) s += ", ... (" + std::to_string(n - 40) + " more)";
  return s;
}

// The OGR layer the query of `spec` reads: the result set of its SQL
// (`from_sql`: the caller releases it), its named layer, else the first.
// Fails (gdal_error) on invalid SQL or an unknown layer, listing the
// source's layers.
OGRLayer* query_layer(GDALDataset& ds, const LayerSpec& spec, const SceneSpec& scene,
                      ErrorCapture& errors, bool& from_sql) {
  from_sql = false;
  if (!spec.sql.empty()) {
    errors.clear();
    OGRLayer* layer = ds.ExecuteSQL(spec.sql.c_str(), nullptr, nullptr);
    if (!layer) {
      // The source's layers and their fields: what the SQL may name.
      std::string tables;
      for (int i = 0; i < ds.GetLayerCount() && i < 10; ++i)
        tables += std::string(i ? "; " : "") + "layer '" + ds.GetLayer(i)->GetName() + "' " +
                  fields_of(*ds.GetLayer(i));
      fail<gdal_error>(kReadStage,
                       spec.source + ": " + scene_layer_of(spec, scene) + ": invalid SQL \"" +
                           spec.sql + "\"" +
                           (errors.failures().empty() ? std::string() : ": " + errors.failures()) +
                           " (" + tables + ")");
    }
    from_sql = true;
    return layer;
  }
  if (spec.layer.empty()) return ds.GetLayer(0);
  OGRLayer* layer = ds.GetLayerByName(spec.layer.c_str());
  if (!layer) {
    std::string names;
    for (int i = 0; i < ds.GetLayerCount(); ++i)
      names += (i ? ", " : "") + std::string(ds.GetLayer(i)->GetName());
    fail<gdal_error>(kReadStage,
                     spec.source + ": unknown layer '" + spec.layer + "' (layers: " + names + ")");
  }
  return layer;
}

// The layer made ready for the pass: nodes after ways in an OSM XML file
// fail it (but for the points layer), GDAL's OSM driver is told which layer
// it serves (else it assembles the features of every layer while one is
// read, as ogr2ogr tells it too), and the `where` of `spec` is set (a
// filter GDAL refuses throws gdal_error).
void prepare_query_layer(GDALDataset& ds, OGRLayer& layer, const LayerSpec& spec,
                         const SceneSpec& scene, bool from_sql,
                         const detail::OsmXmlOrder& osm_order, const std::string& where,
                         ErrorCapture& errors) {
  if (osm_order.late_node_offset >= 0 && (from_sql || std::string(layer.GetName()) != "points"))
    throw_late_nodes(spec.source, where, osm_order);
  if (!from_sql && is_osm(spec.source))
    ds.ExecuteSQL(("SET interest_layers = " + std::string(layer.GetName())).c_str(), nullptr,
                  nullptr);
  if (!spec.where.empty()) {
    errors.clear();
    if (layer.SetAttributeFilter(spec.where.c_str()) != OGRERR_NONE) {
      fail<gdal_error>(
          kNoStage, where + ": " + scene_layer_of(spec, scene) + ": invalid where \"" + spec.where +
                        "\"" +
                        (errors.failures().empty() ? std::string() : ": " + errors.failures()) +
                        " (" + fields_of(layer) + ")");
    }
  }
}

// The pass over `layer`: each feature to every spec's sink (or, when OGR
// could not decode it and skip_failures is set, dropped in every attempt
// like ogr2ogr -skipfailures does), with progress per 1024 features. The
// stage counts features taken by scene layers, as the manifest's `read`
// does: each feature once per layer of the query. Throws gdal_error when
// GDAL reported an error it did not drop.
void read_shared_features(OGRLayer& layer, const SceneSpec& scene, const std::string& where,
                          std::vector<LayerSink>& sinks, std::vector<ReadAttempt>& attempts,
                          JobProgress& progress, ErrorCapture& errors) {
  const uint64_t n = sinks.size();
  const GIntBig total = layer.GetFeatureCount(FALSE);  // -1 for OSM until read
  const uint64_t estimate = total >= 0 ? uint64_t(total) : JobProgress::kUnknown;
  progress.update(0, estimate == JobProgress::kUnknown ? estimate : estimate * n);

  int64_t first_failing_fid = -1;
  errors.clear();
  layer.ResetReading();
  size_t skipped_errors = 0;  // GDAL errors of features dropped under skip_failures
  for (;;) {
    const size_t errors_before = errors.count();
    std::unique_ptr<OGRFeature> feature(layer.GetNextFeature());
    if (!feature) break;
    // A GDAL error while this feature was fetched: OGR could not decode it
    // (e.g. a corrupt shapefile record). With skip_failures it is dropped
    // like ogr2ogr -skipfailures does; without, the read fails below.
    const bool decode_failed = errors.count() > errors_before;
    if (decode_failed && first_failing_fid < 0) first_failing_fid = feature->GetFID();
    const uint64_t index = attempts.front().counts.read;
    const bool skip = decode_failed && scene.skip_failures;
    if (skip) skipped_errors += errors.count() - errors_before;
    for (size_t k = 0; k < sinks.size(); ++k) {
      SourceFeature proto = sinks[k].proto_of(*feature);
      if (skip) {
        proto.drop_reason = "OGR cannot decode the feature: " + errors.last();
        proto.failed_in = FailureStage::read;
        attempts[k].layer.features.push_back(proto);
      } else {
        sinks[k].take_geometry(*feature, proto);
      }
      attempts[k].flush();
    }
    if (skip) continue;
    if ((index & 1023) == 1023)
      progress.update((index + 1) * n, estimate == JobProgress::kUnknown
                                           ? estimate
                                           : std::max(estimate, index + 1) * n);
  }
  if (errors.count() > skipped_errors) {
    fail<gdal_error>(
        kNoStage,
        where + ": reading failed" +
            (first_failing_fid >= 0 ? " at fid " + std::to_string(first_failing_fid) : "") + " (" +
            std::to_string(attempts.front().counts.read) + " features read): " + errors.failures() +
            (first_failing_fid >= 0 ? " (--skip-failures drops features OGR cannot decode)" : ""));
  }
  const uint64_t read = attempts.front().counts.read * n;
  progress.update(read, read);
}

// Reads the scene layers `specs`, which share one query (same source,
// layer, where and sql: same_query), in one pass over the OGR layer: each
// feature goes to every spec's sink, so each layer gets what a read of its
// own would give. The query and the messages about it are the first
// spec's. `scene_layers`: the specs' indices in the scene.
std::vector<ReadAttempt> read_once(const std::vector<const LayerSpec*>& specs,
                                   const SceneSpec& scene, JobProgress& progress,
                                   ErrorCapture& errors, bool plain_osm_index,
                                   const ReadChunks* chunks,
                                   const std::vector<size_t>& scene_layers) {
  const LayerSpec& spec = *specs.front();
  std::vector<ReadAttempt> attempts(specs.size());
  for (size_t k = 0; k < specs.size(); ++k) {
    ReadAttempt& r = attempts[k];
    r.start(chunks, scene_layers[k]);
    r.layer.spec = *specs[k];
    r.counts.layer = specs[k]->name;
  }
  check_source_exists(spec, scene);
  // OSM XML: its element order decides the node index GDAL opens it with.
  const detail::OsmXmlOrder osm_order = detail::scan_osm_xml(spec.source);
  if (osm_order.scanned && !osm_order.node_ids_increase && !plain_osm_index) {
    plain_osm_index = true;
    for (ReadAttempt& r : attempts) r.notes.push_back(osm_plain_index_note(r.layer.spec.name));
  }
  const ReadConfig config(plain_osm_index);
  DatasetPtr ds = open_vector_source(spec, errors);
  bool from_sql = false;
  OGRLayer* layer = query_layer(*ds, spec, scene, errors, from_sql);
  struct SqlRelease {
    GDALDataset* ds;
    OGRLayer* layer;
    bool active;
    ~SqlRelease() {
      if (active) ds->ReleaseResultSet(layer);
    }
  } release{ds.get(), layer, from_sql};

  const std::string where = where_of(spec, layer->GetName());
  prepare_query_layer(*ds, *layer, spec, scene, from_sql, osm_order, where, errors);
  std::vector<LayerSink> sinks;
  sinks.reserve(specs.size());
  for (size_t k = 0; k < specs.size(); ++k) {
    const LayerSpec& s = *specs[k];
    source_crs(layer, s, scene, where, attempts[k]);
    LayerSink& sink = sinks.emplace_back(LayerSink{s, scene, attempts[k], layer->GetName()});
    sink.order_field = field_index(*layer, s.style.order_attribute, s, "order");
    sink.color_field = field_index(*layer, s.style.color.attribute, s, "colour");
  }
  read_shared_features(*layer, scene, where, sinks, attempts, progress, errors);
  for (LayerSink& sink : sinks) sink.finish(errors);
  for (ReadAttempt& r : attempts) r.flush(true);
  return attempts;
}

// Whether a scene layer may take part in a shared pass over its OSM file
// (read_osm_group): no `sql`, and a `where` only on an OGR layer other than
// multipolygons. GDAL's OSM driver tests a multipolygons filter early, on a
// relation's own tags, and a relation it turns away there leaves its tagged
// closed outer ways to come out as features of their own, which it does not
// emit when the relation passes (OGROSMDataSource::NotifyRelation and
// ProcessPolygonsStandalone). So a multipolygons read depends on its filter
// beyond "does this feature pass it" (Monaco, building IS NOT NULL: ways
// 38545604 and 104863462 come out only under that filter), and only the
// layer's own filter gives ogrinfo's features. On the points, lines,
// multilinestrings and other_relations layers the driver decides feature by
// feature, on the feature's own tags, so a pass under the OR of the scene
// layers' filters, each filter then tested on each feature, gives every
// layer what its own read gives (tests/read/test_osm_accounting.cpp checks
// both against separate reads and ogrinfo).
bool osm_shareable(const LayerSpec& spec) {
  return is_osm(spec.source) && spec.sql.empty() &&
         (spec.where.empty() ||
          (!spec.layer.empty() && !EQUAL(spec.layer.c_str(), "multipolygons")));
}

// One pass over an OSM file for several scene layers (osm_shareable).
// GDAL's OSM driver parses the whole file (and assembles every
// multipolygon) for each layer it serves, so reading each scene layer on
// its own repeats the parse once per layer. Here the features come
// interleaved from one pass (GDALDataset::GetNextFeature, the way ogr2ogr
// reads OSM); each OGR layer in use is filtered by the OR of its scene
// layers' `where`s (none when one of them has none), and each scene layer
// takes the features of its OGR layer that pass its own `where`. Feature
// order per layer is the file order either way. Returns false, with nothing
// in `out`, whenever anything is out of the ordinary (an unknown layer, no
// CRS, a filter GDAL refuses, a GDAL error or a bad feature): the caller
// then reads the layers one by one, which reports the problem exactly as
// before.
bool read_osm_group(const std::vector<const LayerSpec*>& specs, const SceneSpec& scene,
                    JobProgress& progress, std::vector<ReadAttempt>& out, const ReadChunks* chunks,
                    const std::vector<size_t>& scene_layers) {
  try {
    ErrorCapture errors;
    const std::string& source = specs.front()->source;
    // Nodes after ways: the per-layer read says what to do.
    const detail::OsmXmlOrder osm_order = detail::scan_osm_xml(source);
    if (osm_order.late_node_offset >= 0) return false;
    const bool plain_osm_index = osm_order.scanned && !osm_order.node_ids_increase;
    const ReadConfig config(plain_osm_index);
    check_input_file(source, "source", InputKind::file_or_directory);
    DatasetPtr ds(GDALDataset::Open(source.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY, nullptr,
                                    nullptr, nullptr));
    if (!ds || errors.failed()) return false;
    std::vector<ReadAttempt> attempts(specs.size());
    std::vector<OGRLayer*> layers(specs.size(), nullptr);
    std::vector<LayerSink> sinks;
    sinks.reserve(specs.size());
    // Per scene layer its own `where`, tested on each feature of the pass
    // (OGRFeatureQuery: what OGRLayer::SetAttributeFilter compiles).
    std::vector<std::unique_ptr<OGRFeatureQuery>> filters(specs.size());
    std::string interest;
    for (size_t i = 0; i < specs.size(); ++i) {
      const LayerSpec& spec = *specs[i];
      ReadAttempt& r = attempts[i];
      r.start(chunks, scene_layers[i]);
      r.layer.spec = spec;
      r.counts.layer = spec.name;
      OGRLayer* layer =
          spec.layer.empty() ? ds->GetLayer(0) : ds->GetLayerByName(spec.layer.c_str());
      if (!layer) return false;
      layers[i] = layer;
      if (!osm_shareable(spec)) return false;
      if (!spec.where.empty()) {
        filters[i] = std::make_unique<OGRFeatureQuery>();
        if (filters[i]->Compile(layer, spec.where.c_str()) != OGRERR_NONE) return false;
      }
      source_crs(layer, spec, scene, where_of(spec, layer->GetName()), r);
      LayerSink& sink = sinks.emplace_back(LayerSink{spec, scene, r, layer->GetName()});
      sink.order_field = field_index(*layer, spec.style.order_attribute, spec, "order");
      sink.color_field = field_index(*layer, spec.style.color.attribute, spec, "colour");
      const std::string name = layer->GetName();
      if (("," + interest + ",").find("," + name + ",") == std::string::npos)
        interest += (interest.empty() ? "" : ",") + name;
    }
    if (errors.failed()) return false;
    // Only the OGR layers in use are assembled (ogr2ogr does the same).
    ds->ExecuteSQL(("SET interest_layers = " + interest).c_str(), nullptr, nullptr);
    if (errors.failed()) return false;
    // Each OGR layer in use passes what any of its scene layers takes.
    for (size_t i = 0; i < specs.size(); ++i) {
      if (std::find(layers.begin(), layers.begin() + i, layers[i]) != layers.begin() + i) continue;
      std::string any;
      bool whole = false;
      for (size_t k = i; k < specs.size(); ++k) {
        if (layers[k] != layers[i]) continue;
        if (specs[k]->where.empty()) whole = true;
        any += (any.empty() ? "(" : " OR (") + specs[k]->where + ")";
      }
      if (!whole && layers[i]->SetAttributeFilter(any.c_str()) != OGRERR_NONE) return false;
    }
    if (errors.failed()) return false;

    progress.update(0, JobProgress::kUnknown);
    ds->ResetReading();
    // The stage counts features taken by scene layers, as the manifest's
    // `read` does; the file fraction GDAL reports scales it to an estimate.
    uint64_t fetched = 0, taken = 0;
    for (;;) {
      OGRLayer* from = nullptr;
      double fraction = 0;
      std::unique_ptr<OGRFeature> feature(ds->GetNextFeature(&from, &fraction, nullptr, nullptr));
      if (!feature) break;
      if (errors.failed()) return false;
      for (size_t i = 0; i < specs.size(); ++i) {
        if (layers[i] != from || (filters[i] && !filters[i]->Evaluate(feature.get()))) continue;
        SourceFeature proto = sinks[i].proto_of(*feature);
        sinks[i].take_geometry(*feature, proto);
        attempts[i].flush();
        ++taken;
      }
      if ((++fetched & 1023) == 0)
        progress.update(taken, fraction > 0.01 ? std::max(taken, uint64_t(double(taken) / fraction))
                                               : JobProgress::kUnknown);
    }
    if (errors.failed()) return false;
    progress.update(taken, taken);
    for (LayerSink& sink : sinks) sink.finish(errors);
    for (ReadAttempt& r : attempts) r.flush(true);
    if (plain_osm_index)
      for (ReadAttempt& r : attempts) r.notes.push_back(osm_plain_index_note(r.layer.spec.name));
    out = std::move(attempts);
    return true;
  } catch (const std::exception&) {
    return false;
  }
}

// read_once, again with the plain OSM node index when GDAL's OSM driver
// stopped at a node id that does not increase in a file the scan could not
// read (osm_xml_order.hpp). The message is the OSM driver's own.
std::vector<ReadAttempt> read_query(const std::vector<const LayerSpec*>& specs,
                                    const SceneSpec& scene, JobProgress& progress,
                                    const ReadChunks* chunks,
                                    const std::vector<size_t>& scene_layers) {
  ErrorCapture errors;
  try {
    return read_once(specs, scene, progress, errors, /*plain_osm_index=*/false, chunks,
                     scene_layers);
  } catch (const gdal_error& e) {
    const std::string what = e.what();
    if (what.find("OSM_USE_CUSTOM_INDEXING") == std::string::npos) throw;
    errors.clear();
    std::vector<ReadAttempt> attempts;
    try {
      attempts =
          read_once(specs, scene, progress, errors, /*plain_osm_index=*/true, chunks, scene_layers);
    } catch (const gdal_error& again) {
      const std::string& source = specs.front()->source;
      fail<gdal_error>(kNoStage,
                       std::string(again.what()) +
                           " (read again with OSM_USE_CUSTOM_INDEXING=NO after: " + what +
                           "); convert the file to OSM PBF with sorted ids, e.g. osmium sort " +
                           source + " -o sorted.osm.pbf, and build from that");
    }
    for (ReadAttempt& r : attempts) r.notes.push_back(osm_plain_index_note(r.layer.spec.name));
    return attempts;
  }
}

// Moves a read layer's counts, manifest entries and notes into `manifest`.
void account(ReadAttempt& r, Manifest& manifest) {
  manifest.layers.push_back(r.counts);
  for (auto& e : r.entries) manifest.entries.push_back(std::move(e));
  for (auto& n : r.notes) manifest.notes.push_back(std::move(n));
}

}  // namespace

SourceLayer read_layer(const LayerSpec& spec, const SceneSpec& scene, Manifest& manifest,
                       const ReadOptions& options) {
  register_gdal_once();
  ProgressStage stage(options.progress, "read", 0, "features", ProgressTotal::estimate);
  std::vector<std::atomic<uint64_t>> estimates(1);
  estimates[0] = JobProgress::kUnknown;
  JobProgress progress(&stage, &estimates, 0);
  std::vector<ReadAttempt> got = read_query({&spec}, scene, progress, nullptr, {0});
  account(got.front(), manifest);
  stage.finish();
  return std::move(got.front().layer);
}

FeatureSet read_scene(const SceneSpec& scene, const ReadOptions& options) {
  if (scene.layers.empty()) fail<usage_error>(kReadStage, "the scene has no layers");
  register_gdal_once();
  // Layers are read concurrently, each from its own GDAL dataset (GDAL is
  // thread-safe across datasets; errors are captured per thread). Results
  // are gathered in scene order, so the output does not depend on timing.
  const size_t n = scene.layers.size();
  std::vector<SourceLayer> layers(n);
  std::vector<Manifest> manifests(n);
  std::vector<std::exception_ptr> failures(n);
  ProgressStage stage(options.progress, "read", 0, "features", ProgressTotal::estimate);
  std::vector<std::atomic<uint64_t>> estimates(n);  // per scene layer
  for (std::atomic<uint64_t>& e : estimates) e = JobProgress::kUnknown;
  // Jobs: scene layers of one OSM file that osm_shareable allows (no `sql`;
  // a `where` only off the multipolygons layer) share one pass over it;
  // other layers that ask the same query (the fill and the outline of one
  // selection, a layer and its casing) share one read of it; every other
  // layer is a job of its own.
  const auto groupable = osm_shareable;
  auto same_query = [](const LayerSpec& a, const LayerSpec& b) {
    return a.source == b.source && a.layer == b.layer && a.where == b.where && a.sql == b.sql;
  };
  std::vector<std::vector<size_t>> jobs;
  for (size_t i = 0; i < n; ++i) {
    const LayerSpec& spec = scene.layers[i];
    auto same = std::find_if(jobs.begin(), jobs.end(), [&](const std::vector<size_t>& job) {
      const LayerSpec& head = scene.layers[job.front()];
      return groupable(spec) ? groupable(head) && head.source == spec.source
                             : !groupable(head) && same_query(head, spec);
    });
    if (same != jobs.end())
      same->push_back(i);
    else
      jobs.push_back({i});
  }
  auto specs_of = [&](const std::vector<size_t>& job) {
    std::vector<const LayerSpec*> specs;
    for (size_t i : job) specs.push_back(&scene.layers[i]);
    return specs;
  };
  // A job's read counts under its first layer; the others add nothing.
  auto progress_of = [&](const std::vector<size_t>& job) {
    for (size_t k = 1; k < job.size(); ++k) estimates[job[k]] = 0;
    return JobProgress(&stage, &estimates, job.front());
  };
  auto keep = [&](const std::vector<size_t>& job, std::vector<ReadAttempt>& got) {
    for (size_t k = 0; k < job.size(); ++k) {
      account(got[k], manifests[job[k]]);
      layers[job[k]] = std::move(got[k].layer);
    }
  };
  // Reads `job`'s layers with one query; a failure counts as the first's.
  auto read_shared = [&](const std::vector<size_t>& job) {
    try {
      JobProgress progress = progress_of(job);
      std::vector<ReadAttempt> got =
          read_query(specs_of(job), scene, progress, options.chunks, job);
      keep(job, got);
    } catch (...) {
      failures[job.front()] = std::current_exception();
    }
  };
  tbb::parallel_for(size_t(0), jobs.size(), [&](size_t j) {
    const std::vector<size_t>& job = jobs[j];
    if (job.size() > 1 && groupable(scene.layers[job.front()])) {
      std::vector<ReadAttempt> got;
      JobProgress progress = progress_of(job);
      if (read_osm_group(specs_of(job), scene, progress, got, options.chunks, job)) {
        keep(job, got);
        return;
      }
      // Anything out of the ordinary: each layer read on its own reports it.
      for (size_t i : job) estimates[i] = JobProgress::kUnknown;
      for (size_t i : job) read_shared({i});
      return;
    }
    read_shared(job);
  });
  // The first failing layer in scene order is the one reported.
  for (const std::exception_ptr& e : failures)
    if (e) std::rethrow_exception(e);
  stage.finish();
  FeatureSet set;
  for (size_t i = 0; i < n; ++i) {
    set.layers.push_back(std::move(layers[i]));
    Manifest& m = manifests[i];
    for (auto& c : m.layers) set.manifest.layers.push_back(std::move(c));
    for (auto& e : m.entries) set.manifest.entries.push_back(std::move(e));
    for (auto& note : m.notes) set.manifest.notes.push_back(std::move(note));
  }
  return set;
}

}  // namespace prep
