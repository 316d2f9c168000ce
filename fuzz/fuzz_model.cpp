// fuzz_model — libFuzzer target for the builder: bytes -> WKT or
// WKB geometries plus a style -> clean -> build_model. Any input must end in
// a model or a prep::error (input/resource/...), never a crash, hang,
// sanitizer report or another exception type.
//
// Input layout:
//   byte 0   style: bits 0-1 kind (0/3 polygon, 1 line, 2 outline),
//            bits 2-3 corner (round, miter, bevel), bits 4-5 outline mode
//            (normal, inset, offset; only with miter), bit 6 resolution 0.5 m,
//            bit 7 a clip extent around the data centre
//   byte 1   line width in decimetres + 1 (0.1 .. 25.6 m)
//   byte 2   'W' or 'w': the rest is WKT, one geometry per line;
//            anything else: the rest is WKB, one geometry per record, each
//            preceded by a little-endian uint16 length.
// Coordinates are taken as frame metres (the clean stage's input after
// project), so NaN, Inf, 1e300 and degenerate shapes reach clean and build
// unchanged. The seeds in fuzz/corpus/model/ come from the hostile corpus.
#include <geos_c.h>

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "prep/clean.hpp"
#include "prep/error.hpp"
#include "prep/model.hpp"
#include "prep/project.hpp"

namespace {

void geos_quiet(const char*, void*) {}

// Appends the rings of `g` (polygons: shell then holes; lines: one ring) as
// source features, walking collections.
void collect(GEOSContextHandle_t h, const GEOSGeometry* g, int64_t fid, prep::SourceLayer& layer,
             int depth = 0) {
  if (!g || depth > 8) return;
  auto ring_of = [&](const GEOSGeometry* r) {
    prep::Ring out;
    const GEOSCoordSequence* cs = GEOSGeom_getCoordSeq_r(h, r);
    unsigned n = 0;
    if (!cs || !GEOSCoordSeq_getSize_r(h, cs, &n)) return out;
    for (unsigned i = 0; i < n; ++i) {
      double x = 0, y = 0;
      GEOSCoordSeq_getXY_r(h, cs, i, &x, &y);
      out.push_back({x, y});
    }
    // Rings come closed from GEOS; SourceFeature rings are open.
    if (out.size() > 1 && out.front().x == out.back().x && out.front().y == out.back().y)
      out.pop_back();
    return out;
  };
  const int type = GEOSGeomTypeId_r(h, g);
  if (type == GEOS_POLYGON) {
    prep::SourceFeature f;
    f.fid = fid;
    f.part = int(layer.features.size());
    f.is_polygon = true;
    if (GEOSisEmpty_r(h, g) == 1) {
      f.drop_reason = "empty";
    } else {
      f.rings.push_back(ring_of(GEOSGetExteriorRing_r(h, g)));
      const int nh = GEOSGetNumInteriorRings_r(h, g);
      for (int i = 0; i < nh && i < 1000; ++i)
        f.rings.push_back(ring_of(GEOSGetInteriorRingN_r(h, g, i)));
    }
    layer.features.push_back(std::move(f));
  } else if (type == GEOS_LINESTRING || type == GEOS_LINEARRING) {
    prep::SourceFeature f;
    f.fid = fid;
    f.part = int(layer.features.size());
    f.rings.push_back(ring_of(g));
    if (f.rings[0].empty()) f.drop_reason = "empty";
    layer.features.push_back(std::move(f));
  } else if (type == GEOS_MULTIPOLYGON || type == GEOS_MULTILINESTRING ||
             type == GEOS_GEOMETRYCOLLECTION) {
    const int n = GEOSGetNumGeometries_r(h, g);
    for (int i = 0; i < n && i < 1000; ++i)
      collect(h, GEOSGetGeometryN_r(h, g, i), fid, layer, depth + 1);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 4 || size > 64 * 1024) return 0;
  const uint8_t style = data[0];
  const double width = (data[1] + 1) * 0.1;
  const bool wkt = data[2] == 'W' || data[2] == 'w';

  GEOSContextHandle_t h = GEOS_init_r();
  GEOSContext_setNoticeMessageHandler_r(h, geos_quiet, nullptr);
  GEOSContext_setErrorMessageHandler_r(h, geos_quiet, nullptr);

  prep::BuildSpec scene;
  prep::LayerSpec spec;
  spec.name = "fuzz";
  const int kind = style & 3;
  spec.kind = kind == 1   ? prep::DecalKind::line
              : kind == 2 ? prep::DecalKind::outline
                          : prep::DecalKind::polygon;
  const int corner = (style >> 2) & 3;
  spec.style.corner = corner == 1   ? decal::CornerStyle::miter
                      : corner == 2 ? decal::CornerStyle::bevel
                                    : decal::CornerStyle::round;
  const int mode = (style >> 4) & 3;
  if (spec.style.corner == decal::CornerStyle::miter && spec.kind == prep::DecalKind::outline)
    spec.style.outline = mode == 1   ? decal::OutlineMode::inset
                         : mode == 2 ? decal::OutlineMode::offset
                                     : decal::OutlineMode::normal;
  spec.style.width = width;
  if (style & 0x40) scene.resolution = 0.5;
  scene.layers.push_back(spec);

  prep::ProjectedFeatures in;
  in.frame.description = "fuzz frame (metres)";
  prep::SourceLayer layer;
  layer.spec = spec;
  const uint8_t* p = data + 3;
  const uint8_t* end = data + size;
  int64_t fid = 0;
  if (wkt) {
    GEOSWKTReader* r = GEOSWKTReader_create_r(h);
    while (p < end && fid < 64) {
      const uint8_t* nl = static_cast<const uint8_t*>(std::memchr(p, '\n', size_t(end - p)));
      const uint8_t* stop = nl ? nl : end;
      const std::string text(reinterpret_cast<const char*>(p), size_t(stop - p));
      GEOSGeometry* g = GEOSWKTReader_read_r(h, r, text.c_str());
      if (g) {
        collect(h, g, fid++, layer);
        GEOSGeom_destroy_r(h, g);
      }
      p = nl ? nl + 1 : end;
    }
    GEOSWKTReader_destroy_r(h, r);
  } else {
    GEOSWKBReader* r = GEOSWKBReader_create_r(h);
    while (end - p >= 2 && fid < 64) {
      const size_t len = size_t(p[0]) | (size_t(p[1]) << 8);
      p += 2;
      const size_t take = std::min(len, size_t(end - p));
      GEOSGeometry* g = GEOSWKBReader_read_r(h, r, p, take);
      if (g) {
        collect(h, g, fid++, layer);
        GEOSGeom_destroy_r(h, g);
      }
      p += take;
    }
    GEOSWKBReader_destroy_r(h, r);
  }
  GEOS_finish_r(h);
  if (layer.features.empty() || layer.features.size() > 4096) return 0;

  for (size_t i = 0; i < layer.features.size(); ++i) layer.features[i].feature = i;
  in.scale.push_back(std::vector<double>(layer.features.size(), 1.0));
  in.features.layers.push_back(std::move(layer));
  if (style & 0x80) in.clip = prep::Extent{-50, -50, 50, 50};
  // Bounded work per input: the fuzzer's -timeout catches hangs; these keep
  // legitimate big inputs from looking like one.
  scene.model.threads = 1;
  scene.model.max_cells = 1u << 16;
  // Failing features (non-finite coordinates, GEOS errors) are dropped, as
  // with --skip-failures, so the build stage still sees the rest.
  scene.skip_failures = true;
  try {
    prep::CleanOptions co;
    co.threads = 1;
    const prep::SceneFeatures cleaned = prep::clean(in, scene, co);
    const prep::DecalModel model = prep::build_model(cleaned, scene.model);
    (void)model;
  } catch (const prep::error&) {
    // A reported failure is a correct answer to a hostile input.
  }
  return 0;
}
