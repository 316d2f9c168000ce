// The validity decision of clean (libprep/clean/detail/certainly_valid.hpp
// polygon_validity) against GEOS isValid, on polygons whose rings touch:
// it must never call valid what GEOS calls invalid, nor invalid what GEOS
// calls valid; "unsure" (GEOS decides) is counted and printed.
//
// Generated polygons, from fixed seeds, on a lattice of 4 x 4 cells inside
// a rectangular shell (its boundary vertices at every lattice point, every
// other one or only at the corners, so that a touch falls on a vertex or
// inside an edge): one hole per cell, a convex ring whose four sides each
// stay inside the cell, reach its border at a point (touching the
// neighbour or the shell at a vertex or inside an edge) or lie along it (a
// touch along a segment where the neighbour does the same). Then chains
// and cycles of touching holes arise by themselves; the variants add holes
// that cross, nest (apart or touching), lie outside the shell (touching it
// or not), repeated points, rings that touch themselves, and explicit
// cycles and chains of holes. Placed exactly (power-of-two scales and
// offsets keep the small integers exact) or rotated (every coordinate
// rounded: touches mostly become crossings or gaps, decided exactly).
//
// Real data: every polygon part of the Monaco and Liechtenstein OSM
// multipolygons (GDAL's OSM driver), and the earth-seas set when present
// (scripts/fetch-data earth-seas; skipped without it).
#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <ogrsf_frmts.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "detail/certainly_valid.hpp"
#include "geos_oracle.hpp"
#include "prep/clean.hpp"
#include "test_support.hpp"

namespace clean_validity_touching {

namespace {

using prep::Point2;
using prep::Ring;
using prep::detail::Validity;
using Rings = std::vector<Ring>;

using prep::test::describe;
using prep::test::Rng;

// ------------------------------------------------------------ lattice --

enum class SideKind { inner, point, flat };

struct LatticeOptions {
  int max_cells = 5;    // columns and rows: 1 .. max_cells
  double empty = 0.25;  // a cell without a hole
  double point = 0.35;  // a side reaching the border at a point
  double flat = 0.1;    // a side along the border
  int shell_step = -1;  // boundary vertices every 1, 2 or 4 units; -1: any
};

// A hole in the cell whose centre is c: its east, north, west and south
// sides, counter-clockwise; `reach` the distance of a side from c (1: inside
// the cell, 2: on its border).
Ring cell_hole(Point2 c, const std::array<SideKind, 4>& sides, double reach_far = 2) {
  static constexpr double d[4][2] = {{1, 0}, {0, 1}, {-1, 0}, {0, -1}};
  Ring r;
  for (int s = 0; s < 4; ++s) {
    const double dx = d[s][0], dy = d[s][1], tx = -dy, ty = dx;
    const double reach = sides[s] == SideKind::inner ? 1 : reach_far;
    const Point2 m{c.x + reach * dx, c.y + reach * dy};
    if (sides[s] == SideKind::flat) {
      r.push_back({m.x - tx, m.y - ty});
      r.push_back({m.x + tx, m.y + ty});
    } else {
      r.push_back(m);
    }
  }
  return r;
}

// The rectangle [0, w] x [0, h] counter-clockwise with a vertex every
// `step` units along its boundary.
Ring rectangle(double w, double h, double step) {
  Ring r;
  const int nx = int(std::ceil(w / step)), ny = int(std::ceil(h / step));
  for (int i = 0; i < nx; ++i) r.push_back({i * step, 0});
  for (int j = 0; j < ny; ++j) r.push_back({w, j * step});
  for (int i = 0; i < nx; ++i) r.push_back({w - i * step, h});
  for (int j = 0; j < ny; ++j) r.push_back({0, h - j * step});
  return r;
}

SideKind side_kind(Rng& rng, const LatticeOptions& o) {
  const double u = rng.uniform();
  return u < o.flat ? SideKind::flat : (u < o.flat + o.point ? SideKind::point : SideKind::inner);
}

struct Lattice {
  int cols = 1, rows = 1;
  Rings rings;                // shell, then the holes
  std::vector<Point2> cells;  // the centre of each hole's cell
};

Lattice lattice(Rng& rng, const LatticeOptions& o) {
  Lattice l;
  l.cols = 1 + rng.below(o.max_cells);
  l.rows = 1 + rng.below(o.max_cells);
  static constexpr int steps[3] = {1, 2, 4};
  const int step = o.shell_step > 0 ? o.shell_step : steps[rng.below(3)];
  l.rings.push_back(rectangle(4.0 * l.cols, 4.0 * l.rows, step));
  for (int j = 0; j < l.rows; ++j)
    for (int i = 0; i < l.cols; ++i) {
      if (rng.uniform() < o.empty) continue;
      const Point2 c{4.0 * i + 2, 4.0 * j + 2};
      std::array<SideKind, 4> sides;
      for (SideKind& s : sides) s = side_kind(rng, o);
      l.rings.push_back(cell_hole(c, sides));
      l.cells.push_back(c);
    }
  return l;
}

// -------------------------------------------------------- disturbances --

// Orientation and start vertex of every ring at random (GEOS places a hole
// by its first points; the decision must not depend on them).
void shuffle_rings(Rng& rng, Rings& rings) {
  for (Ring& r : rings) {
    if (rng.below(2) == 0) std::reverse(r.begin(), r.end());
    std::rotate(r.begin(), r.begin() + rng.below(int(r.size())), r.end());
  }
  if (rings.size() > 2) std::reverse(rings.begin() + 1, rings.end());
}

// Repeats a few vertices in place (GEOS ignores consecutive repeats).
void repeat_points(Rng& rng, Rings& rings) {
  for (int k = 1 + rng.below(4); k > 0; --k) {
    Ring& r = rings[rng.below(int(rings.size()))];
    const size_t i = size_t(rng.below(int(r.size())));
    r.insert(r.begin() + std::ptrdiff_t(i), r[i]);
  }
}

// A hole of the lattice `l` (index in l.cells) stretched over its cell's
// border on one side: across the neighbour hole or the shell.
void cross_neighbour(Rng& rng, Lattice& l) {
  if (l.cells.empty()) return;
  const int h = rng.below(int(l.cells.size()));
  std::array<SideKind, 4> sides{SideKind::inner, SideKind::inner, SideKind::inner, SideKind::inner};
  sides[rng.below(4)] = rng.below(2) == 0 ? SideKind::point : SideKind::flat;
  l.rings[size_t(h) + 1] = cell_hole(l.cells[size_t(h)], sides, 3);
}

// A small hole inside hole h: apart from it, or touching it from inside at
// the vertex of its east side.
void nest(Rng& rng, Lattice& l) {
  if (l.cells.empty()) return;
  const size_t h = size_t(rng.below(int(l.cells.size())));
  const Point2 c = l.cells[h];
  const Ring& outer = l.rings[h + 1];
  if (rng.below(2) == 0) {
    l.rings.push_back({{c.x - 0.5, c.y}, {c.x, c.y - 0.5}, {c.x + 0.5, c.y}, {c.x, c.y + 0.5}});
  } else {  // a triangle from the outer hole's first vertex towards the centre
    const Point2 v = outer[0];
    l.rings.push_back({v, {c.x + 0.25, c.y - 0.25}, {c.x - 0.25, c.y + 0.25}});
  }
}

// A hole west of the shell: apart (radius 1) or touching it from outside
// at a point (radius 2).
void outside(Rng& rng, Lattice& l) {
  const double r = rng.below(2) == 0 ? 1 : 2, y = 4.0 * rng.below(l.rows) + 2;
  l.rings.push_back({{-2 + r, y}, {-2, y + r}, {-2 - r, y}, {-2, y - r}});
}

// A hole that touches itself at its centre (two triangles joined at a
// vertex), replacing hole h; or the shell pinched down to its own bottom
// edge, touching it inside the edge or at a vertex of it (GEOS: "Ring
// Self-intersection").
void self_touch(Rng& rng, Lattice& l) {
  if (!l.cells.empty() && rng.below(2) == 0) {
    const size_t h = size_t(rng.below(int(l.cells.size())));
    const Point2 c = l.cells[h];
    l.rings[h + 1] = {{c.x - 1.5, c.y - 1}, {c.x, c.y}, {c.x + 1.5, c.y - 1},
                      {c.x + 1.5, c.y + 1}, {c.x, c.y}, {c.x - 1.5, c.y + 1}};
    return;
  }
  const double w = 4.0 * l.cols, h = 4.0 * l.rows, m = 2.0 * l.cols;
  l.rings[0] = {{0, 0}, {w, 0}, {w, h}, {m + 0.5, h}, {m, 0}, {m - 0.5, h}, {0, h}};
  if (rng.below(2) == 0) l.rings[0].insert(l.rings[0].begin() + 1, {m, 0});
}

// ---------------------------------------------------- explicit chains --

// k x k holes of radius 2 in the middle of a (k + 2) x (k + 2) lattice:
// each touches its neighbours, so every 2 x 2 block closes a cycle
// (invalid) unless `chain`, where only the touches of one path through
// them stay (a spanning tree: valid).
Rings touch_cycle(Rng& rng, bool chain) {
  const int k = 2 + rng.below(3), n = k + 2;
  Rings rings{rectangle(4.0 * n, 4.0 * n, 1 + rng.below(2))};
  for (int j = 0; j < k; ++j)
    for (int i = 0; i < k; ++i) {
      // Serpentine path: row j runs east on even rows, west on odd ones,
      // and climbs at its end.
      const bool east_run = j % 2 == 0;
      std::array<SideKind, 4> sides{SideKind::point, SideKind::point, SideKind::point,
                                    SideKind::point};
      if (i == k - 1) sides[0] = SideKind::inner;  // the lattice's outer cells stay empty
      if (i == 0) sides[2] = SideKind::inner;
      if (j == k - 1) sides[1] = SideKind::inner;
      if (j == 0) sides[3] = SideKind::inner;
      if (chain) {
        const bool last_in_run = east_run ? i == k - 1 : i == 0;
        const bool first_in_run = east_run ? i == 0 : i == k - 1;
        sides[1] = last_in_run && j < k - 1 ? SideKind::point : SideKind::inner;
        sides[3] = first_in_run && j > 0 ? SideKind::point : SideKind::inner;
      }
      rings.push_back(cell_hole({4.0 * (i + 1) + 2, 4.0 * (j + 1) + 2}, sides));
    }
  return rings;
}

// A chain of holes from the shell's west side to its east side (each
// touching the next at a point): the shell closes the cycle (invalid);
// with one link of the chain broken: valid.
Rings shell_to_shell(Rng& rng, bool broken) {
  const int k = 1 + rng.below(5);
  Rings rings{rectangle(4.0 * k, 4.0, 1 + rng.below(4))};
  const int gap = broken ? rng.below(k + 1) : -1;  // the border that stays open
  for (int i = 0; i < k; ++i) {
    std::array<SideKind, 4> sides{SideKind::point, SideKind::inner, SideKind::point,
                                  SideKind::inner};
    if (gap == i) sides[2] = SideKind::inner;
    if (gap == i + 1) sides[0] = SideKind::inner;
    rings.push_back(cell_hole({4.0 * i + 2, 2}, sides));
  }
  return rings;
}

// -------------------------------------------------------------- place --

// Exact (a power-of-two scale and an offset that keep the lattice's
// quarter units exact) or rotated (every coordinate rounded).
Rings place(const Rings& rings, Rng& rng, bool rotate) {
  const double scale = std::ldexp(1.0, rng.below(21) - 10);
  const bool far = rng.below(2) == 0;
  const double ox = far ? 500000 : 0, oy = far ? 4800000 : 0;
  return prep::test::placed(rings, scale, ox, oy, 2 * M_PI * rng.uniform(), rotate);
}

// ------------------------------------------------------------- oracle --

// GEOS isValid of the polygon; nullopt when GEOS cannot build it.
std::optional<bool> geos_valid(GEOSContextHandle_t h, const Rings& rings) {
  for (const Ring& r : rings)
    if (r.size() < 3) return std::nullopt;
  try {
    const prep::test::G g = prep::test::polygon(h, rings[0], Rings(rings.begin() + 1, rings.end()));
    const char v = GEOSisValid_r(h, g.g);
    if (v == 2) return std::nullopt;
    return v == 1;
  } catch (const std::runtime_error&) {
    return std::nullopt;
  }
}

struct Tally {
  int samples = 0, geos_valid = 0, valid = 0, invalid = 0, unsure = 0, wrong = 0;
  Tally& operator+=(const Tally& o) {
    for (int Tally::*m : {&Tally::samples, &Tally::geos_valid, &Tally::valid, &Tally::invalid,
                          &Tally::unsure, &Tally::wrong})
      this->*m += o.*m;
    return *this;
  }
};

// Decides one sample both ways and counts it under `kind`; a decision that
// GEOS contradicts fails the test.
void check(GEOSContextHandle_t h, const std::string& kind, const Rings& rings,
           std::map<std::string, Tally>& tally) {
  const Validity v = prep::detail::polygon_validity(rings);
  const std::optional<bool> g = geos_valid(h, rings);
  // Asked for culprits, the sweep goes on past a problem: the same answer,
  // and an invalid one names rings of the polygon and points of them.
  std::vector<prep::detail::Culprit> culprits;
  EXPECT_EQ(prep::detail::polygon_validity(rings, &culprits), v) << kind << ": " << describe(rings);
  if (v == Validity::invalid) {
    EXPECT_FALSE(culprits.empty()) << kind << ": " << describe(rings);
  }
  for (const prep::detail::Culprit& c : culprits) EXPECT_LT(c.ring, rings.size()) << kind;
  Tally& t = tally[kind];
  ++t.samples;
  t.valid += v == Validity::valid;
  t.invalid += v == Validity::invalid;
  t.unsure += v == Validity::unsure;
  const bool oracle = g.value_or(false);  // GEOS cannot build it: not valid
  t.geos_valid += oracle;
  if (v == Validity::unsure) return;
  const bool wrong = (v == Validity::valid) != oracle;
  t.wrong += wrong;
  EXPECT_FALSE(wrong) << kind << ": decided " << (v == Validity::valid ? "valid" : "invalid")
                      << ", GEOS says " << (oracle ? "valid" : "invalid") << ": "
                      << describe(rings);
}

Tally print(const std::map<std::string, Tally>& tally) {
  Tally all;
  std::printf("%-40s %7s %7s %7s %7s %7s\n", "kind", "samples", "GEOS ok", "valid", "invalid",
              "unsure");
  for (const auto& [kind, t] : tally) {
    std::printf("%-40s %7d %7d %7d %7d %7d\n", kind.c_str(), t.samples, t.geos_valid, t.valid,
                t.invalid, t.unsure);
    all += t;
  }
  std::printf("%-40s %7d %7d %7d %7d %7d (%d agree with GEOS, %d deferred to it)\n", "all",
              all.samples, all.geos_valid, all.valid, all.invalid, all.unsure,
              all.valid + all.invalid - all.wrong, all.unsure);
  return all;
}

// One generated kind: `n` samples, one in four rotated.
void run(GEOSContextHandle_t h, Rng& rng, const std::string& kind, int n,
         const std::function<Rings(Rng&)>& make, std::map<std::string, Tally>& tally) {
  for (int k = 0; k < n; ++k) {
    Rings rings = make(rng);
    shuffle_rings(rng, rings);
    const bool rotate = k % 4 == 3;
    check(h, kind + (rotate ? ", rotated" : ""), place(rings, rng, rotate), tally);
  }
}

TEST(ValidityTouching, DecidesAsGeosOnTouchingHoles) {
  const prep::test::Geos geos;
  Rng rng(20260611);
  std::map<std::string, Tally> tally;
  const LatticeOptions points{5, 0.25, 0.4, 0.0, -1}, flats{5, 0.25, 0.3, 0.2, -1};
  run(
      geos.h, rng, "touch at a vertex", 2000,
      [&](Rng& r) {
        LatticeOptions o = points;
        o.shell_step = 1 + r.below(2);
        return lattice(r, o).rings;
      },
      tally);
  run(
      geos.h, rng, "touch inside a segment", 1200,
      [&](Rng& r) {
        LatticeOptions o = flats;
        o.flat = 0.12;
        o.shell_step = 4;
        return lattice(r, o).rings;
      },
      tally);
  // A lattice of `o`, then changed by `modify` (none: as it is).
  const auto altered = [](const LatticeOptions& o, void (*modify)(Rng&, Lattice&)) {
    return [o, modify](Rng& r) {
      Lattice l = lattice(r, o);
      if (modify) modify(r, l);
      return l.rings;
    };
  };
  LatticeOptions along = flats;
  along.flat = 0.4;
  run(geos.h, rng, "touch along a segment", 800, altered(along, nullptr), tally);
  run(geos.h, rng, "crossing holes", 800, altered(points, cross_neighbour), tally);
  run(geos.h, rng, "nested holes", 800, altered(points, nest), tally);
  run(geos.h, rng, "hole outside the shell", 800, altered(points, outside), tally);
  run(geos.h, rng, "repeated points", 1000,
      altered(flats, [](Rng& r, Lattice& l) { repeat_points(r, l.rings); }), tally);
  for (const bool open : {false, true})
    run(
        geos.h, rng, open ? "chain of touching holes" : "cycle of touching holes", 600,
        [open](Rng& r) { return touch_cycle(r, open); }, tally);
  for (const bool broken : {false, true})
    run(
        geos.h, rng, broken ? "broken chain from shell to shell" : "chain from shell to shell", 500,
        [broken](Rng& r) { return shell_to_shell(r, broken); }, tally);
  run(geos.h, rng, "self-touching rings", 800, altered(points, self_touch), tally);
  run(
      geos.h, rng, "mixed", 1600,
      [&](Rng& r) {
        LatticeOptions o = flats;
        o.max_cells = 7;
        Lattice l = lattice(r, o);
        for (int k = r.below(3); k > 0; --k) switch (r.below(5)) {
            case 0: cross_neighbour(r, l); break;
            case 1: nest(r, l); break;
            case 2: outside(r, l); break;
            case 3: repeat_points(r, l.rings); break;
            default: self_touch(r, l);
          }
        return l.rings;
      },
      tally);
  const Tally all = print(tally);
  EXPECT_GE(all.samples, 10000);
  EXPECT_EQ(all.wrong, 0);
  // Both answers occur, and GEOS is rarely needed.
  EXPECT_GT(all.geos_valid, all.samples / 5);
  EXPECT_GT(all.samples - all.geos_valid, all.samples / 5);
  EXPECT_LT(all.unsure, all.samples / 100);
  for (const char* kind : {"touch at a vertex", "touch inside a segment", "chain of touching holes",
                           "broken chain from shell to shell"})
    EXPECT_GT(tally[kind].geos_valid, 0) << kind;
  for (const char* kind :
       {"touch along a segment", "crossing holes", "nested holes", "hole outside the shell",
        "cycle of touching holes", "chain from shell to shell", "self-touching rings"})
    EXPECT_LT(tally[kind].geos_valid, tally[kind].samples) << kind;
  EXPECT_EQ(tally["cycle of touching holes"].geos_valid, 0);
  EXPECT_EQ(tally["chain of touching holes"].geos_valid, tally["chain of touching holes"].samples);
}

// ----------------------------------------------------------- real data --

// The polygon parts of every feature of a GDAL vector data set's layer
// (all layers when `layer` is empty), as rings without the closing point.
std::vector<Rings> polygon_parts(const std::string& path, const std::string& layer) {
  GDALAllRegister();
  GDALDatasetUniquePtr ds(GDALDataset::Open(path.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY));
  std::vector<Rings> parts;
  if (!ds) return parts;
  std::function<void(const OGRGeometry*)> walk = [&](const OGRGeometry* g) {
    if (const auto* p = dynamic_cast<const OGRPolygon*>(g)) {
      Rings rings;
      for (const OGRLinearRing* r : *p) {
        Ring ring;
        for (int i = 0; i + 1 < r->getNumPoints(); ++i) ring.push_back({r->getX(i), r->getY(i)});
        rings.push_back(std::move(ring));
      }
      if (!rings.empty()) parts.push_back(std::move(rings));
    } else if (const auto* c = dynamic_cast<const OGRGeometryCollection*>(g)) {
      for (const OGRGeometry* part : c) walk(part);
    }
  };
  for (OGRLayer* l : ds->GetLayers()) {
    if (!layer.empty() && layer != l->GetName()) continue;
    for (auto& feature : *l)
      if (const OGRGeometry* g = feature->GetGeometryRef()) walk(g);
  }
  return parts;
}

// True when no vertex of one ring equals a vertex of another (the usual
// form of a touch in OSM data, where rings share nodes).
bool no_ring_touches(const Rings& rings) {
  std::vector<std::pair<double, double>> pts;
  for (const Ring& r : rings)
    for (const Point2& p : r) pts.push_back({p.x + 0.0, p.y + 0.0});
  const size_t n = pts.size();
  std::sort(pts.begin(), pts.end());
  return std::unique(pts.begin(), pts.end()) - pts.begin() == std::ptrdiff_t(n);
}

struct RealTally {
  int parts = 0, holes_touching = 0;
  Tally t;
  double proof_s = 0, geos_s = 0;
};

// Decides every part both ways, timing each.
RealTally decide_all(GEOSContextHandle_t h, const std::vector<Rings>& parts) {
  using clock = std::chrono::steady_clock;
  RealTally r;
  std::map<std::string, Tally> tally;
  for (const Rings& rings : parts) {
    const auto t0 = clock::now();
    const Validity v = prep::detail::polygon_validity(rings);
    const auto t1 = clock::now();
    const std::optional<bool> g = geos_valid(h, rings);
    const auto t2 = clock::now();
    r.proof_s += std::chrono::duration<double>(t1 - t0).count();
    r.geos_s += std::chrono::duration<double>(t2 - t1).count();
    ++r.parts;
    // Parts with holes that the previous proof (no ring may touch another)
    // left to GEOS and that are valid: touching rings.
    if (rings.size() > 1 && v == Validity::valid && !no_ring_touches(rings)) ++r.holes_touching;
    Tally& t = r.t;
    ++t.samples;
    t.valid += v == Validity::valid;
    t.invalid += v == Validity::invalid;
    t.unsure += v == Validity::unsure;
    t.geos_valid += g.value_or(false);
    if (v != Validity::unsure && (v == Validity::valid) != g.value_or(false)) {
      ++t.wrong;
      ADD_FAILURE() << "decided " << (v == Validity::valid ? "valid" : "invalid")
                    << ", GEOS says otherwise: " << describe(rings).substr(0, 2000);
    }
  }
  return r;
}

void report(const char* name, const RealTally& r) {
  std::printf(
      "%s: %d polygon parts, %d valid for GEOS; decided %d valid (%d with touching rings), %d "
      "invalid, %d deferred to GEOS, %d against GEOS; %.3f s deciding, %.3f s in GEOS isValid\n",
      name, r.parts, r.t.geos_valid, r.t.valid, r.holes_touching, r.t.invalid, r.t.unsure,
      r.t.wrong, r.proof_s, r.geos_s);
}

// The OSM extracts the real-data tests read: the Monaco sample and the
// shared Liechtenstein extract; `test` runs on each present one's polygon
// parts. False when neither is there (the caller skips).
bool for_each_osm_extract(const std::function<void(const std::string&, std::vector<Rings>)>& test) {
  const std::string files[] = {
      prep::test::monaco_sample("monaco.osm.pbf"),
      prep::test::shared_data("liechtenstein/liechtenstein-2013-08-03.osm.pbf")};
  bool found = false;
  for (const std::string& path : files) {
    if (!prep::test::exists(path)) continue;
    found = true;
    std::vector<Rings> parts = polygon_parts(path, "multipolygons");
    EXPECT_GT(parts.size(), 100u) << path;
    if (parts.size() > 100u) test(path, std::move(parts));
  }
  return found;
}

TEST(ValidityTouching, DecidesAsGeosOnOsmMultipolygons) {
  const prep::test::Geos geos;
  const bool found = for_each_osm_extract([&](const std::string& path, std::vector<Rings> parts) {
    const RealTally r = decide_all(geos.h, parts);
    report(path.c_str(), r);
    EXPECT_EQ(r.t.wrong, 0);
    EXPECT_LE(r.t.unsure, r.parts / 1000 + 1) << path;
  });
  if (!found) GTEST_SKIP() << "missing the Monaco sample and the Liechtenstein extract";
}

// The overview levels' simplifier (prep/clean.hpp PartSimplifier) on the
// same real parts, at three tolerances in degrees (about 1, 10 and 100 m):
// GEOS isValid of every result and GEOS's Hausdorff distance within the
// tolerance (the oracle); how many parts the sweep proved and how many it
// left to GEOS.
TEST(ValidityTouching, SimplifiedRealPartsStayValidWithinTheTolerance) {
  const prep::test::Geos geos;
  const bool found = for_each_osm_extract([&](const std::string& path, std::vector<Rings> all) {
    std::vector<prep::ScenePolygon> parts;
    for (Rings& rings : all) {
      if (geos_valid(geos.h, rings) != true) continue;  // clean() repairs those first
      prep::ScenePolygon p;
      p.shell = std::move(rings[0]);
      if (prep::test::ring_area(p.shell) < 0) std::reverse(p.shell.begin(), p.shell.end());
      for (size_t i = 1; i < rings.size(); ++i) {
        if (prep::test::ring_area(rings[i]) > 0) std::reverse(rings[i].begin(), rings[i].end());
        p.holes.push_back(std::move(rings[i]));
      }
      parts.push_back(std::move(p));
    }
    ASSERT_GT(parts.size(), 100u) << path;
    for (const double tol : {1e-5, 1e-4, 1e-3}) {
      prep::PartSimplifier s(tol);
      int kept = 0;
      for (const prep::ScenePolygon& before : parts) {
        prep::ScenePolygon p = before;
        if (!s.polygon(p, "real")) continue;
        ++kept;
        ASSERT_TRUE(prep::test::is_valid(geos.h, p))
            << path << " tolerance " << tol << ": " << describe(Rings{before.shell});
        double d = -1;
        ASSERT_EQ(GEOSHausdorffDistance_r(geos.h, prep::test::polygon(geos.h, before).g,
                                          prep::test::polygon(geos.h, p).g, &d),
                  1);
        EXPECT_LE(d, tol * (1 + 1e-9)) << path << " tolerance " << tol;
      }
      const prep::PartSimplifier::Counts& c = s.counts();
      std::printf(
          "%s, tolerance %g deg: %zu valid parts, %d kept; %llu proved valid (%llu after "
          "giving %llu sections back), %llu left to GEOS\n",
          path.c_str(), tol, parts.size(), kept, (unsigned long long)c.proved,
          (unsigned long long)c.with_sections_back, (unsigned long long)c.sections_back,
          (unsigned long long)c.geos);
      EXPECT_LE(c.geos, parts.size() / 100 + 1) << path << " tolerance " << tol;
    }
  });
  if (!found) GTEST_SKIP() << "missing the Monaco sample and the Liechtenstein extract";
}

// The earth-seas set: the world ocean (one polygon with many thousand
// islands as holes, some touching the shell or each other) and the seas.
TEST(ValidityTouching, DecidesAsGeosOnEarthSeas) {
  const std::string seas = DECALPREP_EARTH_SEAS;
  if (!prep::test::exists(seas))
    GTEST_SKIP() << "missing " << seas << ": run scripts/fetch-data earth-seas";
  const prep::test::Geos geos;
  const std::vector<Rings> parts = polygon_parts(seas, "");
  ASSERT_FALSE(parts.empty());
  const RealTally r = decide_all(geos.h, parts);
  report(seas.c_str(), r);
  EXPECT_EQ(r.t.wrong, 0);
}

}  // namespace

}  // namespace clean_validity_touching
