// The work folder of a tileset build (tileset_work.hpp): the cleaned parts
// in a GeoPackage with its R-tree, written in scene order and read
// back one tile's window at a time.
#include "tileset_work.hpp"

#include <gdal_priv.h>
#include <ogrsf_frmts.h>
#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <limits>
#include <mutex>
#include <set>

#include "prep/error.hpp"
#include "prep/manifest_json.hpp"
#include "prep/stage_error.hpp"

namespace prep::tiling {

namespace {

void register_gdal_once() {
  static std::once_flag once;
  std::call_once(once, [] { GDALAllRegister(); });
}

// The intermediate's fields, in this order.
enum Field : int {
  f_kind,
  f_seq,
  f_layer,
  f_fid,
  f_part,
  f_closed,
  f_area,
  f_length,
  f_width,
  f_order,
  f_color,
  f_wkb,
  f_keys,
  f_count
};
constexpr const char* kFieldNames[f_count] = {
    "kind",   "seq",   "layer",       "source_fid",  "part", "closed", "area",
    "length", "width", "order_value", "color_value", "wkb",  "keys"};
constexpr OGRFieldType kFieldTypes[f_count] = {
    OFTInteger, OFTInteger64, OFTInteger, OFTInteger64, OFTInteger, OFTInteger, OFTReal,
    OFTReal,    OFTReal,      OFTReal,    OFTReal,      OFTBinary,  OFTBinary};

// Metres a stored box is grown by; a tile's window is grown by more
// (PartReader::read_tile), so no part that reaches the tile is left out.
constexpr double kBoxPad = 0.5;

// One box record of boxes.bin.
struct BoxRecord {
  int32_t kind;
  int32_t pad;
  double xmin, ymin, xmax, ymax;
};

OGRLinearRing* closed_ring(const Ring& r) {
  auto* ring = new OGRLinearRing;
  ring->setNumPoints(static_cast<int>(r.size() + (r.empty() ? 0 : 1)), FALSE);
  for (size_t i = 0; i < r.size(); ++i) ring->setPoint(static_cast<int>(i), r[i].x, r[i].y);
  if (!r.empty()) ring->setPoint(static_cast<int>(r.size()), r[0].x, r[0].y);
  return ring;
}

// The ring's points without the closing point.
Ring open_points(const OGRSimpleCurve& c, bool drop_closing) {
  const int n = c.getNumPoints();
  const int m = drop_closing && n > 0 ? n - 1 : n;
  Ring r(static_cast<size_t>(std::max(0, m)));
  for (int i = 0; i < m; ++i) r[size_t(i)] = {c.getX(i), c.getY(i)};
  return r;
}

}  // namespace

// ---------------------------------------------------------------- writer --

struct PartWriter::Impl {
  std::string path, boxes_path;
  GDALDataset* ds = nullptr;
  OGRLayer* layer = nullptr;
  std::FILE* boxes = nullptr;
};

PartWriter::PartWriter(const WorkPaths& paths) : impl_(std::make_unique<Impl>()) {
  register_gdal_once();
  impl_->path = paths.parts();
  impl_->boxes_path = paths.boxes();
  // GeoPackage: SQLite keeps the memory bounded while it builds the R-tree
  // (GDAL 3.6's FlatGeobuf writer holds every feature in memory to sort
  // them for its index).
  GDALDriver* drv = GetGDALDriverManager()->GetDriverByName("GPKG");
  if (!drv) fail<output_error>(kTilesetStage, "GDAL has no GPKG driver");
  std::remove(impl_->path.c_str());
  // PRAGMA synchronous = OFF (read when the file is opened): no fsync per
  // chunk's transaction. SQLite stays consistent when the process dies; the
  // work folder is an intermediate that nothing fsyncs (plan.json,
  // boxes.bin neither), so a machine that loses power mid-build reruns the
  // prepare step either way. 17% of the prepare step of 10^7 vertices of
  // bench/tileset_scale.py (4.95 -> 4.1 s).
  CPLSetThreadLocalConfigOption("OGR_SQLITE_SYNCHRONOUS", "OFF");
  impl_->ds = drv->Create(impl_->path.c_str(), 0, 0, 0, GDT_Unknown, nullptr);
  CPLSetThreadLocalConfigOption("OGR_SQLITE_SYNCHRONOUS", nullptr);
  if (!impl_->ds)
    fail<output_error>(kTilesetStage, "cannot create " + impl_->path + ": " + CPLGetLastErrorMsg());
  char** opts = CSLSetNameValue(nullptr, "SPATIAL_INDEX", "YES");
  opts = CSLSetNameValue(opts, "GEOMETRY_NAME", "box");
  impl_->layer = impl_->ds->CreateLayer("parts", nullptr, wkbPolygon, opts);
  CSLDestroy(opts);
  if (!impl_->layer)
    fail<output_error>(kTilesetStage,
                       "cannot create a layer in " + impl_->path + ": " + CPLGetLastErrorMsg());
  for (int i = 0; i < f_count; ++i) {
    OGRFieldDefn def(kFieldNames[i], kFieldTypes[i]);
    if (impl_->layer->CreateField(&def) != OGRERR_NONE)
      fail<output_error>(kTilesetStage, "cannot create field " + std::string(kFieldNames[i]) +
                                            " in " + impl_->path);
  }
  impl_->boxes = std::fopen(impl_->boxes_path.c_str(), "wb");
  if (!impl_->boxes)
    fail<output_error>(kTilesetStage,
                       "cannot create " + impl_->boxes_path + ": " + std::strerror(errno));
}

PartWriter::~PartWriter() {
  if (impl_->boxes) std::fclose(impl_->boxes);
  if (impl_->ds) GDALClose(impl_->ds);
}

void PartWriter::add(const SceneFeatures& chunk) {
  OGRFeatureDefn* defn = impl_->layer->GetLayerDefn();
  if (impl_->ds->StartTransaction() != OGRERR_NONE)
    fail<output_error>(kTilesetStage, "cannot write " + impl_->path + ": " + CPLGetLastErrorMsg());
  auto write = [&](PartKind kind, OGRGeometry* geometry, const Ring& boxed, uint32_t layer,
                   const FeatureKeys& id, bool closed, double area, double length, double width) {
    OGRFeature f(defn);
    // The part itself as WKB (doubles exact); the feature's geometry is its
    // box grown by kBoxPad (never degenerate), so that GDAL's spatial
    // filter, which tests geometries exactly, selects by box: every part
    // whose box reaches a tile is in the tile's window (PartReader), and
    // the exact test is tile_range's.
    std::vector<unsigned char> wkb(geometry->WkbSize());
    geometry->exportToWkb(wkbNDR, wkb.data(), wkbVariantIso);
    delete geometry;
    f.SetField(f_wkb, static_cast<int>(wkb.size()), wkb.data());
    const Extent b = ring_box(boxed);
    {
      auto* box = new OGRPolygon;
      auto* ring = new OGRLinearRing;
      ring->setNumPoints(5, FALSE);
      const double x0 = b.xmin - kBoxPad, y0 = b.ymin - kBoxPad;
      const double x1 = b.xmax + kBoxPad, y1 = b.ymax + kBoxPad;
      ring->setPoint(0, x0, y0);
      ring->setPoint(1, x1, y0);
      ring->setPoint(2, x1, y1);
      ring->setPoint(3, x0, y1);
      ring->setPoint(4, x0, y0);
      box->addRingDirectly(ring);
      f.SetGeometryDirectly(box);
    }
    const int k = static_cast<int>(kind);
    f.SetField(f_kind, k);
    f.SetField(f_seq, static_cast<GIntBig>(seq_[k]++));
    f.SetField(f_layer, static_cast<int>(layer));
    f.SetField(f_fid, static_cast<GIntBig>(id.fid));
    f.SetField(f_part, id.part);
    f.SetField(f_closed, closed ? 1 : 0);
    f.SetField(f_area, area);
    f.SetField(f_length, length);
    f.SetField(f_width, width);
    f.SetField(f_order, id.order_value);
    f.SetField(f_color, id.color_value);
    // The keys as their bytes: SQLite keeps neither NaN (NULL) nor the sign
    // of a zero (an integral REAL is stored as an integer); the Real fields
    // above are for people looking at the file.
    const double keys[5] = {area, length, width, id.order_value, id.color_value};
    f.SetField(f_keys, static_cast<int>(sizeof keys), static_cast<const void*>(keys));
    if (impl_->layer->CreateFeature(&f) != OGRERR_NONE)
      fail<output_error>(kTilesetStage,
                         "cannot write a part to " + impl_->path + ": " + CPLGetLastErrorMsg());
    const BoxRecord rec{k, 0, b.xmin, b.ymin, b.xmax, b.ymax};
    if (std::fwrite(&rec, sizeof rec, 1, impl_->boxes) != 1)
      fail<output_error>(kTilesetStage, "cannot write " + impl_->boxes_path);
    extend(box_, boxed);
  };
  for (const ScenePolygon& p : chunk.polygons) {
    auto* poly = new OGRPolygon;
    poly->addRingDirectly(closed_ring(p.shell));
    for (const Ring& h : p.holes) poly->addRingDirectly(closed_ring(h));
    write(PartKind::polygon, poly, p.shell, p.layer, p, false, p.area, 0, 0);
  }
  auto line_geometry = [](const Ring& pts) {
    auto* ls = new OGRLineString;
    ls->setNumPoints(static_cast<int>(pts.size()), FALSE);
    for (size_t i = 0; i < pts.size(); ++i) ls->setPoint(static_cast<int>(i), pts[i].x, pts[i].y);
    return ls;
  };
  for (const SceneLine& l : chunk.lines)
    write(PartKind::line, line_geometry(l.points), l.points, l.layer, l, l.closed, 0, l.length,
          l.width);
  for (const SceneLine& l : chunk.dynamic_lines)
    write(PartKind::dynamic_line, line_geometry(l.points), l.points, l.layer, l, l.closed, 0,
          l.length, l.width);
  if (impl_->ds->CommitTransaction() != OGRERR_NONE)
    fail<output_error>(kTilesetStage, "cannot write " + impl_->path + ": " + CPLGetLastErrorMsg());
  half_width_ = std::max(half_width_, stroke_half_width(chunk));
}

void PartWriter::close() {
  if (impl_->boxes) {
    const bool ok = std::fclose(impl_->boxes) == 0;
    impl_->boxes = nullptr;
    if (!ok) fail<output_error>(kTilesetStage, "cannot write " + impl_->boxes_path);
  }
  if (impl_->ds) {
    // The spatial index is built and written now; GDALClose reports through
    // the error state.
    CPLErrorReset();
    GDALClose(impl_->ds);
    impl_->ds = nullptr;
    if (CPLGetLastErrorType() == CE_Failure || CPLGetLastErrorType() == CE_Fatal)
      fail<output_error>(kTilesetStage,
                         "cannot write " + impl_->path + ": " + CPLGetLastErrorMsg());
  }
}

Extent PartWriter::extent() const {
  return box_.xmax >= box_.xmin ? box_ : Extent{};
}

std::vector<TileKey> planned_tiles(const WorkPaths& paths, const TilePlan& plan) {
  std::FILE* f = std::fopen(paths.boxes().c_str(), "rb");
  if (!f) fail<output_error>(kTilesetStage, "cannot read " + paths.boxes());
  std::set<TileKey> keys;
  const double ox = plan.frame.origin_x, oy = plan.frame.origin_y;
  std::vector<BoxRecord> buf(4096);
  for (;;) {
    const size_t n = std::fread(buf.data(), sizeof(BoxRecord), buf.size(), f);
    for (size_t i = 0; i < n; ++i) {
      const BoxRecord& r = buf[i];
      const double by =
          r.kind == static_cast<int>(PartKind::dynamic_line) ? plan.dynamic_margin : plan.margin;
      const TileRange t = tile_range({r.xmin, r.ymin, r.xmax, r.ymax}, by, ox, oy, plan.size);
      // A part (with its stroke margin) over more tiles than any index can
      // list would plan for ever: refused, with the numbers.
      const double reach = double(t.hi.x - t.lo.x + 1) * double(t.hi.y - t.lo.y + 1);
      if (reach > double(kMaxPlannedTiles) || keys.size() > kMaxPlannedTiles) {
        char m[256];
        std::snprintf(m, sizeof m,
                      "the tiles of %.10g m reached by the parts (each with its stroke margin of "
                      "%.10g m) number more than %zu; use a larger --tile-size or narrower lines",
                      plan.size, by, kMaxPlannedTiles);
        std::fclose(f);
        fail<resource_error>(kTilesetStage, m);
      }
      for (int64_t y = t.lo.y; y <= t.hi.y; ++y)
        for (int64_t x = t.lo.x; x <= t.hi.x; ++x) keys.insert({x, y});
    }
    if (n < buf.size()) break;
  }
  std::fclose(f);
  return {keys.begin(), keys.end()};
}

// ---------------------------------------------------------------- reader --

struct PartReader::Impl {
  std::string path;
  GDALDataset* ds = nullptr;
  OGRLayer* layer = nullptr;
  int field[f_count] = {};
};

PartReader::PartReader(const WorkPaths& paths) : impl_(std::make_unique<Impl>()) {
  register_gdal_once();
  impl_->path = paths.parts();
  impl_->ds = GDALDataset::Open(impl_->path.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY, nullptr,
                                nullptr, nullptr);
  if (!impl_->ds || impl_->ds->GetLayerCount() != 1)
    fail<output_error>(kTilesetStage, "cannot open " + impl_->path + ": " + CPLGetLastErrorMsg());
  impl_->layer = impl_->ds->GetLayer(0);
  OGRFeatureDefn* defn = impl_->layer->GetLayerDefn();
  for (int i = 0; i < f_count; ++i) {
    impl_->field[i] = defn->GetFieldIndex(kFieldNames[i]);
    if (impl_->field[i] < 0)
      fail<output_error>(kTilesetStage, impl_->path + ": no field " + std::string(kFieldNames[i]));
  }
}

PartReader::~PartReader() {
  if (impl_->ds) GDALClose(impl_->ds);
}

void PartReader::read_tile(const TilePlan& plan, const TileKey& key, SceneFeatures& scene,
                           PartFilter* filter) {
  scene.polygons.clear();
  scene.lines.clear();
  scene.dynamic_lines.clear();
  const double ox = plan.frame.origin_x, oy = plan.frame.origin_y;
  const Extent sq = plan.square(key);
  // A window wider than any reach: the exact test is tile_range's.
  const double by = std::max(plan.margin, plan.dynamic_margin) + 2 * kBoxPad + 1.0;
  OGRLayer* layer = impl_->layer;
  layer->SetSpatialFilterRect(sq.xmin - ox - by, sq.ymin - oy - by, sq.xmax - ox + by,
                              sq.ymax - oy + by);
  layer->ResetReading();
  const int* fi = impl_->field;
  std::vector<std::pair<uint64_t, ScenePolygon>> polys;
  std::vector<std::pair<uint64_t, SceneLine>> lines, dyn;
  for (;;) {
    std::unique_ptr<OGRFeature> f(layer->GetNextFeature());
    if (!f) break;
    const int kind = f->GetFieldAsInteger(fi[f_kind]);
    const auto seq = static_cast<uint64_t>(f->GetFieldAsInteger64(fi[f_seq]));
    int wkb_size = 0;
    const GByte* wkb = f->GetFieldAsBinary(fi[f_wkb], &wkb_size);
    OGRGeometry* parsed = nullptr;
    if (!wkb ||
        OGRGeometryFactory::createFromWkb(wkb, nullptr, &parsed, static_cast<size_t>(wkb_size),
                                          wkbVariantIso) != OGRERR_NONE)
      fail<output_error>(kTilesetStage, impl_->path + ": a part whose WKB cannot be read");
    const std::unique_ptr<OGRGeometry> owned(parsed);
    const OGRGeometry* g = parsed;
    int keys_size = 0;
    const GByte* keys_bytes = f->GetFieldAsBinary(fi[f_keys], &keys_size);
    double keys[5];
    if (!keys_bytes || keys_size != static_cast<int>(sizeof keys))
      fail<output_error>(kTilesetStage, impl_->path + ": a part without its keys");
    std::memcpy(keys, keys_bytes, sizeof keys);
    const auto layer_index = static_cast<uint32_t>(f->GetFieldAsInteger(fi[f_layer]));
    FeatureKeys feature_keys;
    feature_keys.fid = f->GetFieldAsInteger64(fi[f_fid]);
    feature_keys.part = f->GetFieldAsInteger(fi[f_part]);
    feature_keys.order_value = keys[3];
    feature_keys.color_value = keys[4];
    if (kind == static_cast<int>(PartKind::polygon)) {
      const auto* poly = dynamic_cast<const OGRPolygon*>(g);
      if (!poly || !poly->getExteriorRing())
        fail<output_error>(kTilesetStage, impl_->path + ": a polygon part that is not a polygon");
      ScenePolygon p;
      p.shell = open_points(*poly->getExteriorRing(), true);
      if (!tile_range(ring_box(p.shell), plan.margin, ox, oy, plan.size).holds(key)) continue;
      for (int h = 0; h < poly->getNumInteriorRings(); ++h)
        p.holes.push_back(open_points(*poly->getInteriorRing(h), true));
      static_cast<FeatureKeys&>(p) = feature_keys;
      p.layer = layer_index;
      p.area = keys[0];
      if (filter && !filter->polygon(p)) continue;
      polys.emplace_back(seq, std::move(p));
    } else {
      const auto* ls = dynamic_cast<const OGRLineString*>(g);
      if (!ls) fail<output_error>(kTilesetStage, impl_->path + ": a line part that is not a line");
      const bool dynamic = kind == static_cast<int>(PartKind::dynamic_line);
      SceneLine l;
      l.points = open_points(*ls, false);
      if (!tile_range(ring_box(l.points), dynamic ? plan.dynamic_margin : plan.margin, ox, oy,
                      plan.size)
               .holds(key))
        continue;
      l.closed = f->GetFieldAsInteger(fi[f_closed]) != 0;
      static_cast<FeatureKeys&>(l) = feature_keys;
      l.layer = layer_index;
      l.length = keys[1];
      l.width = keys[2];
      if (filter && !filter->line(l, dynamic)) continue;
      (dynamic ? dyn : lines).emplace_back(seq, std::move(l));
    }
  }
  auto by_seq = [](const auto& a, const auto& b) { return a.first < b.first; };
  std::sort(polys.begin(), polys.end(), by_seq);
  std::sort(lines.begin(), lines.end(), by_seq);
  std::sort(dyn.begin(), dyn.end(), by_seq);
  for (auto& [s, p] : polys) scene.polygons.push_back(std::move(p));
  for (auto& [s, l] : lines) scene.lines.push_back(std::move(l));
  for (auto& [s, l] : dyn) scene.dynamic_lines.push_back(std::move(l));
}

// --------------------------------------------------------------- entries --

EntryWriter::EntryWriter(const std::string& path) : path_(path) {
  f_ = std::fopen(path.c_str(), "wb");
  if (!f_) fail<output_error>(kTilesetStage, "cannot create " + path + ": " + std::strerror(errno));
}

EntryWriter::~EntryWriter() {
  if (f_) std::fclose(f_);
}

void EntryWriter::add(const ManifestEntry& e) {
  // manifest.json is {"entries": [...]} dumped with indent 1: an entry sits
  // two levels deep, so each of its lines gets two more spaces. Entries
  // are separated by ",\n" (written by write_manifest_from).
  const std::string text = manifest_entry_json(e).dump(1);
  std::string out;
  out.reserve(text.size() + 64);
  if (count_ > 0) out += ",\n";
  out += "  ";
  for (char c : text) {
    out += c;
    if (c == '\n') out += "  ";
  }
  if (std::fwrite(out.data(), 1, out.size(), f_) != out.size())
    fail<output_error>(kTilesetStage, "cannot write " + path_);
  ++count_;
}

void EntryWriter::close() {
  if (!f_) return;
  const bool ok = std::fclose(f_) == 0;
  f_ = nullptr;
  if (!ok) fail<output_error>(kTilesetStage, "cannot write " + path_);
}

void write_manifest_from(const std::vector<std::string>& entry_files, uint64_t entries,
                         const std::string& path) {
  const std::string tmp = path + ".tmp";
  std::FILE* out = std::fopen(tmp.c_str(), "wb");
  if (!out) fail<output_error>(kTilesetStage, "cannot write " + path + ": " + std::strerror(errno));
  bool ok = true;
  auto put = [&](const char* s, size_t n) { ok = ok && std::fwrite(s, 1, n, out) == n; };
  if (entries == 0) {
    const std::string text = "{\n \"entries\": []\n}\n";
    put(text.data(), text.size());
  } else {
    const std::string head = "{\n \"entries\": [\n";
    put(head.data(), head.size());
    bool first = true;
    std::vector<char> buf(1 << 16);
    for (const std::string& file : entry_files) {
      std::FILE* in = std::fopen(file.c_str(), "rb");
      if (!in) {
        std::fclose(out);
        std::remove(tmp.c_str());
        fail<output_error>(kTilesetStage, "cannot read " + file);
      }
      // Each file's entries are joined with ",\n"; files are joined the same way.
      bool any = false;
      for (;;) {
        const size_t n = std::fread(buf.data(), 1, buf.size(), in);
        if (n == 0) break;
        if (!any && !first) put(",\n", 2);
        any = true;
        put(buf.data(), n);
      }
      std::fclose(in);
      if (any) first = false;
    }
    const std::string tail = "\n ]\n}\n";
    put(tail.data(), tail.size());
  }
  ok = std::fclose(out) == 0 && ok;
  if (!ok || std::rename(tmp.c_str(), path.c_str()) != 0) {
    std::remove(tmp.c_str());
    fail<output_error>(kTilesetStage, "cannot write " + path);
  }
}

// ------------------------------------------------------------- plan.json --

namespace {
nlohmann::json number(double v) {
  return std::isnan(v) ? nlohmann::json(nullptr) : nlohmann::json(v);
}
double number_of(const nlohmann::json& j) {
  return j.is_null() ? std::numeric_limits<double>::quiet_NaN() : j.get<double>();
}
}  // namespace

nlohmann::json frame_to_json(const SceneFrame& f) {
  return {{"crs_wkt", f.crs_wkt},   {"description", f.description}, {"origin_x", f.origin_x},
          {"origin_y", f.origin_y}, {"tm_lon0", number(f.tm_lon0)}, {"tm_lat0", number(f.tm_lat0)}};
}

SceneFrame frame_from_json(const nlohmann::json& j) {
  SceneFrame f;
  f.crs_wkt = j.at("crs_wkt").get<std::string>();
  f.description = j.at("description").get<std::string>();
  f.origin_x = j.at("origin_x").get<double>();
  f.origin_y = j.at("origin_y").get<double>();
  f.tm_lon0 = number_of(j.at("tm_lon0"));
  f.tm_lat0 = number_of(j.at("tm_lat0"));
  return f;
}

nlohmann::json counts_to_json(const std::vector<LayerCounts>& layers) {
  nlohmann::json a = nlohmann::json::array();
  for (const LayerCounts& c : layers) a.push_back(layer_counts_json(c));
  return a;
}

std::vector<LayerCounts> counts_from_json(const nlohmann::json& j) {
  std::vector<LayerCounts> out;
  for (const nlohmann::json& c : j) {
    LayerCounts l;
    l.layer = c.at("layer").get<std::string>();
    for (const auto& [name, m] : kLayerCountFields) l.*m = c.at(name).get<uint64_t>();
    out.push_back(std::move(l));
  }
  return out;
}

void remove_tree(const std::string& path) {
  std::error_code ec;
  std::filesystem::remove_all(path, ec);
}

}  // namespace prep::tiling
