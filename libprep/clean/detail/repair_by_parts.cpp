// The repair of hole-heavy polygons by parts: detail/repair_by_parts.hpp.
#include "detail/repair_by_parts.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/partitioner.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <numeric>
#include <optional>

#include "detail/certainly_valid.hpp"
#include "detail/union_find.hpp"
#include "geos_handle.hpp"

namespace prep::detail {
namespace {

using Owned = GeosGeom;

// The hole groups (detail/union_find.hpp: the smaller index is the root,
// so the groups do not depend on the order contacts are found in).
using Groups = UnionFind;

struct Candidates {
  std::vector<uint32_t> found;
};

void on_candidate(void* item, void* user) {
  static_cast<Candidates*>(user)->found.push_back(*static_cast<const uint32_t*>(item));
}

// A closed ring of the rectangle, counter-clockwise.
GEOSGeometry* box_ring(GEOSContextHandle_t h, const Envelope& b) {
  const double xy[10] = {b.x0, b.y0, b.x1, b.y0, b.x1, b.y1, b.x0, b.y1, b.x0, b.y0};
  return GEOSGeom_createLinearRing_r(h, GEOSCoordSeq_copyFromBuffer_r(h, xy, 5, 0, 0));
}

// True when the single ring is a valid polygon on its own (then MakeValid
// of it alone would return its area unchanged).
bool ring_valid(GEOSContextHandle_t h, const GEOSGeometry* ring, const Ring& coords) {
  if (certainly_valid({coords})) return true;
  std::vector<Owned> none;
  Owned poly(h, polygon_of(h, Owned(h, GEOSGeom_clone_r(h, ring)), none));
  return poly && GEOSisValid_r(h, poly.get()) == 1;
}

// Whether two holes are in contact: their rings meet, or one lies inside
// the other; that is, their own areas (the polygon of each ring alone)
// intersect (GEOS Intersects: the point-in-area test by crossing parity,
// which also answers for a self-crossing ring). The areas are built on
// demand; the larger of the two (in vertices) is prepared when it is large.
class RingAreas {
 public:
  RingAreas(GEOSContextHandle_t h, const std::vector<const GEOSGeometry*>& rings)
      : h_(h), rings_(rings), areas_(rings.size()), prepared_(rings.size()) {}

  // 1 in contact, 0 apart, 2 GEOS failed.
  char in_contact(uint32_t i, uint32_t j) {
    if (GEOSGetNumCoordinates_r(h_, rings_[i]) < GEOSGetNumCoordinates_r(h_, rings_[j]))
      std::swap(i, j);
    if (!area(i) || !area(j)) return 2;
    if (GEOSGetNumCoordinates_r(h_, rings_[i]) < kPrepareFrom)
      return GEOSIntersects_r(h_, areas_[i].get(), areas_[j].get());
    if (!prepared_[i]) prepared_[i] = std::make_unique<Prepared>(h_, areas_[i].get());
    if (!prepared_[i]->get()) return 2;
    return GEOSPreparedIntersects_r(h_, prepared_[i]->get(), areas_[j].get());
  }

 private:
  static constexpr int kPrepareFrom = 64;  // vertices

  const GEOSGeometry* area(uint32_t k) {
    if (!areas_[k]) {
      std::vector<Owned> none;
      areas_[k] = Owned(h_, polygon_of(h_, Owned(h_, GEOSGeom_clone_r(h_, rings_[k])), none));
    }
    return areas_[k].get();
  }

  GEOSContextHandle_t h_;
  const std::vector<const GEOSGeometry*>& rings_;
  std::vector<Owned> areas_;
  std::vector<std::unique_ptr<Prepared>> prepared_;
};

// The holes of `polygon` (its n interior rings, borrowed) and whether each
// lies properly inside the shell: a hole ring that meets no shell segment
// and whose first vertex has odd crossing parity against the shell ring
// (GEOS prepared ContainsProperly of the shell's polygon, which needs no
// valid input: the point-in-area test counts ring crossings). Such a hole
// lies in one face of the shell's noded linework, a face of odd parity, and
// so properly inside the shell's own area, whichever the method (linework
// keeps the faces of odd parity; structure all those the ring winds
// around). The shell's own repair is not needed for it: it is part of the
// base repair, which runs beside the others. False when GEOS fails.
bool holes_inside_shell(GEOSContextHandle_t h, const GEOSGeometry* polygon,
                        const GEOSGeometry* shell_ring, uint32_t n,
                        std::vector<const GEOSGeometry*>& holes, std::vector<char>& clear) {
  holes.assign(n, nullptr);
  clear.assign(n, 0);
  std::vector<Owned> none;
  Owned shell(h, polygon_of(h, Owned(h, GEOSGeom_clone_r(h, shell_ring)), none));
  if (!shell) return false;
  Prepared inside(h, shell.get());
  if (!inside.get()) return false;
  for (uint32_t i = 0; i < n; ++i) {
    holes[i] = GEOSGetInteriorRingN_r(h, polygon, static_cast<int>(i));
    const char c = GEOSPreparedContainsProperly_r(h, inside.get(), holes[i]);
    if (c == 2) return false;
    clear[i] = c;
  }
  return true;
}

// Unites in `groups` the holes in contact: rings that meet, or one inside
// the other (candidates from envelope contact; a continent-sized hole's
// envelope holds thousands of islands that touch nothing). The work is
// bounded: past the budget of envelope contacts it gives up (false, and the
// whole polygon is repaired); false too when GEOS fails.
bool group_holes_in_contact(GEOSContextHandle_t h, const std::vector<const GEOSGeometry*>& holes,
                            Groups& groups) {
  const auto n = static_cast<uint32_t>(holes.size());
  Tree tree(h);
  if (!tree.get()) return false;
  std::vector<uint32_t> ids(n);
  std::iota(ids.begin(), ids.end(), 0u);
  for (uint32_t i = 0; i < n; ++i) GEOSSTRtree_insert_r(h, tree.get(), holes[i], &ids[i]);
  const size_t budget = 64 * size_t(n) + 1'000'000;
  size_t contacts = 0;
  RingAreas areas(h, holes);
  Candidates c;
  for (uint32_t i = 0; i < n; ++i) {
    c.found.clear();
    GEOSSTRtree_query_r(h, tree.get(), holes[i], &on_candidate, &c);
    contacts += c.found.size();
    if (contacts > budget) return false;
    std::sort(c.found.begin(), c.found.end());
    for (uint32_t j : c.found) {
      if (j <= i || groups.find(i) == groups.find(j)) continue;
      const char meet = areas.in_contact(i, j);
      if (meet == 2) return false;
      if (meet) groups.unite(i, j);
    }
  }
  return true;
}

// The holes sorted for the repairs: those of groups that reach the shell
// (a hole not properly inside it) go to the base repair, cloned, in input
// order; the others form the clear groups, in order of their first hole,
// holes in input order.
struct HoleSplit {
  std::vector<Owned> base_holes;
  std::vector<std::vector<uint32_t>> clear_groups;
};

HoleSplit split_holes(GEOSContextHandle_t h, const std::vector<const GEOSGeometry*>& holes,
                      const std::vector<char>& clear, Groups& groups) {
  const auto n = static_cast<uint32_t>(holes.size());
  std::vector<uint32_t> root(n);
  std::vector<char> with_shell(n, 0);
  for (uint32_t i = 0; i < n; ++i) {
    root[i] = groups.find(i);
    if (!clear[i]) with_shell[root[i]] = 1;
  }
  HoleSplit split;
  std::vector<int64_t> group_of_root(n, -1);
  for (uint32_t i = 0; i < n; ++i) {
    if (with_shell[root[i]]) {
      split.base_holes.emplace_back(h, GEOSGeom_clone_r(h, holes[i]));
      continue;
    }
    if (group_of_root[root[i]] < 0) {
      group_of_root[root[i]] = static_cast<int64_t>(split.clear_groups.size());
      split.clear_groups.emplace_back();
    }
    split.clear_groups[size_t(group_of_root[root[i]])].push_back(i);
  }
  return split;
}

// One MakeValid call of the split: the base repair (jobs[0]) or a clear
// group's repair inside a rectangle clear of it (jobs[1 + group]).
struct RepairJob {
  Owned input, fixed;
  Envelope box{};
  bool alone = false;          // a single hole that is a valid ring: no repair
  bool outside = false;        // misses the window: left out
  bool keep_if_valid = false;  // the shell alone: kept as it is when valid
  bool valid = false;          // `fixed` is valid (GEOS isValid)
};

// Accounts in `left_out` (when given) for a clear group whose envelope
// misses the window: a group that needed a repair, or a lone valid hole
// with its GEOS area. False when GEOS fails.
bool count_left_out(GEOSContextHandle_t h, const GEOSGeometry* first_hole, bool alone,
                    LeftOut* left_out) {
  if (!left_out) return true;
  if (!alone) {
    ++left_out->groups;
    return true;
  }
  ++left_out->lone_holes;
  std::vector<Owned> no_holes;
  Owned area(h, polygon_of(h, Owned(h, GEOSGeom_clone_r(h, first_hole)), no_holes));
  double a = 0;
  if (!area || GEOSArea_r(h, area.get(), &a) != 1) return false;
  left_out->lone_hole_area += a;
  return true;
}

// Prepares the job of one clear group: left out when its envelope misses
// `window` (everything the group's repair cuts out or adds lies in that
// envelope, so the repair inside the window is the same without it), no
// repair for a lone valid hole, else the input: a box around the group by
// a margin, with the group's holes. False when GEOS fails.
bool prepare_group_job(GEOSContextHandle_t h, const std::vector<const GEOSGeometry*>& holes,
                       const std::vector<Ring>& rings, const std::vector<uint32_t>& group,
                       const Envelope* window, LeftOut* left_out, RepairJob& job) {
  Envelope b{INFINITY, INFINITY, -INFINITY, -INFINITY};
  for (uint32_t i : group) {
    Envelope e;
    if (!envelope_of(h, holes[i], e)) return false;
    b = {std::min(b.x0, e.x0), std::min(b.y0, e.y0), std::max(b.x1, e.x1), std::max(b.y1, e.y1)};
  }
  const bool alone = group.size() == 1 && ring_valid(h, holes[group[0]], rings[group[0] + 1]);
  if (window &&
      (b.x1 < window->x0 || b.x0 > window->x1 || b.y1 < window->y0 || b.y0 > window->y1)) {
    job.outside = true;
    return count_left_out(h, holes[group[0]], alone, left_out);
  }
  if (alone) {
    job.alone = true;
    return true;
  }
  // Clear of the group by a margin far above the coordinates' precision
  // (|x| <= 1e9 m in clean: an ulp is below 1e-6 m).
  const double margin = 1.0 + 0.01 * std::max(b.x1 - b.x0, b.y1 - b.y0);
  job.box = {b.x0 - margin, b.y0 - margin, b.x1 + margin, b.y1 + margin};
  std::vector<Owned> group_holes;
  for (uint32_t i : group) group_holes.emplace_back(h, GEOSGeom_clone_r(h, holes[i]));
  job.input = Owned(h, polygon_of(h, Owned(h, box_ring(h, job.box)), group_holes));
  return bool(job.input);
}

// Runs the jobs with an input: the MakeValid calls are independent, so they
// run in parallel (oneTBB, most vertices first), each thread with a GEOS
// context of its own; each result is checked (GEOS isValid) into its job,
// so what is put together afterwards, in job order, does not depend on the
// threads. The base's shell alone is kept as it is when valid.
void run_repair_jobs(GEOSContextHandle_t h, const std::vector<Ring>& rings,
                     const MakeValidFn& make_valid, std::vector<RepairJob>& jobs) {
  std::vector<uint32_t> order;  // the jobs with a repair, most vertices first
  std::vector<int> vertices(jobs.size(), 0);
  for (uint32_t k = 0; k < jobs.size(); ++k) {
    if (!jobs[k].input) continue;
    vertices[k] = GEOSGetNumCoordinates_r(h, jobs[k].input.get());
    order.push_back(k);
  }
  std::stable_sort(order.begin(), order.end(),
                   [&](uint32_t a, uint32_t b) { return vertices[a] > vertices[b]; });
  // One context per arena slot, made when its thread takes a first job.
  std::vector<std::optional<GeosContext>> contexts(
      static_cast<size_t>(std::max(tbb::this_task_arena::max_concurrency(), 1)));
  tbb::parallel_for(
      tbb::blocked_range<size_t>(0, order.size(), 1),
      [&](const tbb::blocked_range<size_t>& range) {
        const auto slot = static_cast<size_t>(tbb::this_task_arena::current_thread_index());
        if (slot >= contexts.size()) return;  // not expected; the job stays unrepaired
        if (!contexts[slot]) contexts[slot].emplace();
        GEOSContextHandle_t th = contexts[slot]->handle();
        for (size_t r = range.begin(); r != range.end(); ++r) {
          RepairJob& job = jobs[order[r]];
          if (job.keep_if_valid &&
              ring_valid(th, GEOSGetExteriorRing_r(th, job.input.get()), rings[0])) {
            job.fixed = Owned(h, GEOSGeom_clone_r(th, job.input.get()));
            job.valid = bool(job.fixed);
            continue;
          }
          job.fixed = Owned(h, make_valid(th, job.input.get()));
          job.valid = job.fixed && GEOSisValid_r(th, job.fixed.get()) == 1;
        }
      },
      tbb::simple_partitioner());
}

// What the clear groups' repairs give the assembly: the rings each cuts out
// of the base (to place, with the group each comes from), the islands
// inside them and any collapsed pieces.
struct GroupPieces {
  std::vector<Owned> cut, islands, collapsed;
  std::vector<uint32_t> cut_group;  // the clear group each cut ring comes from
};

// Takes apart the repair of clear group `gi` (its job valid, its input a
// box with holes): the polygon whose shell is the box gives the cut rings,
// the other polygons are islands. False when the repair does not have that
// shape or GEOS fails.
bool take_group_repair(GEOSContextHandle_t h, const RepairJob& job, uint32_t gi,
                       GroupPieces& pieces) {
  const Envelope& b = job.box;
  std::vector<const GEOSGeometry*> polys, other;
  flatten(h, job.fixed.get(), polys, other);
  const GEOSGeometry* around = nullptr;  // the polygon whose shell is the box
  for (const GEOSGeometry* p : polys) {
    Envelope e;
    if (!envelope_of(h, GEOSGetExteriorRing_r(h, p), e)) return false;
    if (e.x0 == b.x0 && e.y0 == b.y0 && e.x1 == b.x1 && e.y1 == b.y1) {
      if (around) return false;
      around = p;
    } else {
      pieces.islands.emplace_back(h, GEOSGeom_clone_r(h, p));
    }
  }
  if (!around) return false;
  const int k = GEOSGetNumInteriorRings_r(h, around);
  for (int j = 0; j < k; ++j) {
    pieces.cut.emplace_back(h, GEOSGeom_clone_r(h, GEOSGetInteriorRingN_r(h, around, j)));
    pieces.cut_group.push_back(gi);
  }
  for (const GEOSGeometry* o : other) pieces.collapsed.emplace_back(h, GEOSGeom_clone_r(h, o));
  return true;
}

// The pieces of every clear group in group order (jobs[1 + gi]): none for
// a group left out, its one hole for a lone valid hole, else its repair
// taken apart. False when a repair failed or has an unexpected shape.
bool collect_group_pieces(GEOSContextHandle_t h, const std::vector<const GEOSGeometry*>& holes,
                          const std::vector<std::vector<uint32_t>>& clear_groups,
                          const std::vector<RepairJob>& jobs, GroupPieces& pieces) {
  for (uint32_t gi = 0; gi < clear_groups.size(); ++gi) {
    const std::vector<uint32_t>& group = clear_groups[gi];
    const RepairJob& job = jobs[gi + 1];
    if (job.outside) continue;
    if (job.alone) {
      pieces.cut.emplace_back(h, GEOSGeom_clone_r(h, holes[group[0]]));
      pieces.cut_group.push_back(gi);
      continue;
    }
    if (!job.valid) return false;
    if (!take_group_repair(h, job, gi, pieces)) return false;
  }
  return true;
}

// For each cut ring, the base polygon that properly contains it (the first
// by index among the STRtree candidates); false when one has none or GEOS
// fails.
bool find_cut_homes(GEOSContextHandle_t h, const std::vector<const GEOSGeometry*>& base_polys,
                    const std::vector<Owned>& cut, std::vector<int64_t>& home) {
  const size_t np = base_polys.size();
  Tree tree(h);
  if (!tree.get()) return false;
  std::vector<uint32_t> ids(np);
  std::iota(ids.begin(), ids.end(), 0u);
  for (size_t k = 0; k < np; ++k) GEOSSTRtree_insert_r(h, tree.get(), base_polys[k], &ids[k]);
  std::vector<std::unique_ptr<Prepared>> prepared(np);
  Candidates c;
  home.assign(cut.size(), -1);
  for (size_t i = 0; i < cut.size(); ++i) {
    c.found.clear();
    GEOSSTRtree_query_r(h, tree.get(), cut[i].get(), &on_candidate, &c);
    std::sort(c.found.begin(), c.found.end());
    for (uint32_t k : c.found) {
      if (!prepared[k]) prepared[k] = std::make_unique<Prepared>(h, base_polys[k]);
      if (!prepared[k]->get()) return false;
      if (GEOSPreparedContainsProperly_r(h, prepared[k]->get(), cut[i].get()) == 1) {
        home[i] = k;
        break;
      }
    }
    if (home[i] < 0) return false;
  }
  return true;
}

// True when no two cut rings of different groups meet (GEOS Intersects on
// STRtree envelope candidates); false when they do or GEOS fails.
bool cut_groups_apart(GEOSContextHandle_t h, const std::vector<Owned>& cut,
                      const std::vector<uint32_t>& cut_group) {
  Tree rings_tree(h);
  if (!rings_tree.get()) return false;
  std::vector<uint32_t> cut_ids(cut.size());
  std::iota(cut_ids.begin(), cut_ids.end(), 0u);
  for (size_t i = 0; i < cut.size(); ++i)
    GEOSSTRtree_insert_r(h, rings_tree.get(), cut[i].get(), &cut_ids[i]);
  // A large ring is prepared (a continent among thousands of islands).
  std::vector<std::unique_ptr<Prepared>> cut_prepared(cut.size());
  auto meet = [&](size_t a, size_t b) -> char {
    if (GEOSGetNumCoordinates_r(h, cut[a].get()) < GEOSGetNumCoordinates_r(h, cut[b].get()))
      std::swap(a, b);
    if (GEOSGetNumCoordinates_r(h, cut[a].get()) < 64)
      return GEOSIntersects_r(h, cut[a].get(), cut[b].get());
    if (!cut_prepared[a]) cut_prepared[a] = std::make_unique<Prepared>(h, cut[a].get());
    if (!cut_prepared[a]->get()) return 2;
    return GEOSPreparedIntersects_r(h, cut_prepared[a]->get(), cut[b].get());
  };
  Candidates c;
  for (size_t i = 0; i < cut.size(); ++i) {
    c.found.clear();
    GEOSSTRtree_query_r(h, rings_tree.get(), cut[i].get(), &on_candidate, &c);
    std::sort(c.found.begin(), c.found.end());
    for (uint32_t j : c.found)
      if (j > i && cut_group[j] != cut_group[i] && meet(i, j) != 0) return false;
  }
  return true;
}

// The repair put together as MakeValid returns it: the area (a Polygon or
// MultiPolygon: the base polygons with their own and their added holes,
// then the islands), alone or first in a GeometryCollection with the
// collapsed pieces (the base's, then the groups'). Null when GEOS fails.
GEOSGeometry* assemble_by_parts(GEOSContextHandle_t h,
                                const std::vector<const GEOSGeometry*>& base_polys,
                                const std::vector<const GEOSGeometry*>& base_other,
                                std::vector<std::vector<Owned>>& added, GroupPieces& pieces) {
  std::vector<Owned> polys;
  for (size_t k = 0; k < base_polys.size(); ++k) {
    const GEOSGeometry* p = base_polys[k];
    std::vector<Owned> hs;
    const int own = GEOSGetNumInteriorRings_r(h, p);
    hs.reserve(size_t(std::max(own, 0)) + added[k].size());
    for (int j = 0; j < own; ++j)
      hs.emplace_back(h, GEOSGeom_clone_r(h, GEOSGetInteriorRingN_r(h, p, j)));
    for (Owned& r : added[k]) hs.push_back(std::move(r));
    polys.emplace_back(
        h, polygon_of(h, Owned(h, GEOSGeom_clone_r(h, GEOSGetExteriorRing_r(h, p))), hs));
    if (!polys.back()) return nullptr;
  }
  for (Owned& p : pieces.islands) polys.push_back(std::move(p));
  Owned area = polys.size() == 1 ? std::move(polys[0]) : collection(h, GEOS_MULTIPOLYGON, polys);
  if (!area) return nullptr;
  std::vector<Owned> collapsed;
  for (const GEOSGeometry* o : base_other) collapsed.emplace_back(h, GEOSGeom_clone_r(h, o));
  for (Owned& o : pieces.collapsed) collapsed.push_back(std::move(o));
  if (collapsed.empty()) return area.release();
  collapsed.insert(collapsed.begin(), std::move(area));
  return collection(h, GEOS_GEOMETRYCOLLECTION, collapsed).release();
}

}  // namespace

GEOSGeometry* make_valid_by_parts(GEOSContextHandle_t h, const GEOSGeometry* polygon,
                                  const std::vector<Ring>& rings, const MakeValidFn& make_valid,
                                  const Envelope* window, LeftOut* left_out) {
  if (left_out) *left_out = LeftOut{};
  if (GEOSGeomTypeId_r(h, polygon) != GEOS_POLYGON) return nullptr;
  const int nh = GEOSGetNumInteriorRings_r(h, polygon);
  if (nh < 0 || size_t(nh) < kRepairByPartsMinHoles || size_t(nh) + 1 != rings.size())
    return nullptr;
  const auto n = static_cast<uint32_t>(nh);
  const GEOSGeometry* shell_ring = GEOSGetExteriorRing_r(h, polygon);

  std::vector<const GEOSGeometry*> holes;
  std::vector<char> clear;  // properly inside the shell's area
  if (!holes_inside_shell(h, polygon, shell_ring, n, holes, clear)) return nullptr;
  Groups groups(n);
  if (!group_holes_in_contact(h, holes, groups)) return nullptr;
  HoleSplit split = split_holes(h, holes, clear, groups);
  if (split.clear_groups.empty()) return nullptr;

  // The base repair (the shell and the groups that reach it; with no such
  // group, the shell's own repair, or the shell as it is when valid), then
  // one job per clear group.
  std::vector<RepairJob> jobs(split.clear_groups.size() + 1);  // [0]: the base
  jobs[0].keep_if_valid = split.base_holes.empty();
  jobs[0].input =
      Owned(h, polygon_of(h, Owned(h, GEOSGeom_clone_r(h, shell_ring)), split.base_holes));
  if (!jobs[0].input) return nullptr;
  for (uint32_t gi = 0; gi < split.clear_groups.size(); ++gi)
    if (!prepare_group_job(h, holes, rings, split.clear_groups[gi], window, left_out, jobs[gi + 1]))
      return nullptr;
  run_repair_jobs(h, rings, make_valid, jobs);

  if (!jobs[0].valid) return nullptr;
  Owned base = std::move(jobs[0].fixed);
  std::vector<const GEOSGeometry*> base_polys, base_other;
  flatten(h, base.get(), base_polys, base_other);
  if (base_polys.empty()) return nullptr;
  GroupPieces pieces;
  if (!collect_group_pieces(h, holes, split.clear_groups, jobs, pieces)) return nullptr;

  // Each cut ring goes into the base polygon that properly contains it (it
  // is drawn from a clear group's linework: inside the shell, away from the
  // base's holes). Cut rings of different groups must not meet.
  std::vector<int64_t> home;
  if (!find_cut_homes(h, base_polys, pieces.cut, home)) return nullptr;
  if (!cut_groups_apart(h, pieces.cut, pieces.cut_group)) return nullptr;
  std::vector<std::vector<Owned>> added(base_polys.size());
  for (size_t i = 0; i < pieces.cut.size(); ++i)
    added[size_t(home[i])].push_back(std::move(pieces.cut[i]));
  return assemble_by_parts(h, base_polys, base_other, added, pieces);
}

}  // namespace prep::detail
