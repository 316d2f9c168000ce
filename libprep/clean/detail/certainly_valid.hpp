// The validity fast path of clean (libprep/clean/clean.cpp): GEOS's
// validity of a polygon decided without GEOS, in near-linear time.
//
// Most parts arrive valid; GEOS's isValid (noding every ring, building a
// topology graph, and placing every hole by a point-in-ring walk over the
// whole shell: time holes x shell vertices) and the copies into and out of
// GEOS cost more than reading them. `polygon_validity` decides the polygon
// with exact predicates (a filtered orientation, CGAL's exact one where the
// filter cannot tell) and answers `unsure` whenever it cannot decide, so
// GEOS still decides every doubtful part (and repairs the invalid ones): a
// false "valid" is impossible, an "unsure" only costs time
// (tests/clean/test_certainly_valid.cpp and test_validity_touching.cpp check
// it against GEOS isValid).
#pragma once

#include <cstdint>
#include <vector>

#include "prep/features.hpp"

namespace prep::detail {

enum class Validity { valid, invalid, unsure };

// GEOS's (OGC's) validity of a polygon: rings[0] the shell, then the holes;
// unclosed. The rules, as GEOS IsValidOp applies them:
// - finite coordinates; consecutive repeated points are ignored, and every
//   ring keeps at least 3 distinct points (4 closed);
// - no two edges cross, overlap along a segment, or meet away from their
//   shared vertex; a ring never meets itself elsewhere (a spike, a
//   self-touch), rings of the polygon may touch each other at single
//   points where they do not cross;
// - the rings and their touch points form no cycle (no two rings touch
//   twice, no chain of touching holes closes on itself or on the shell):
//   else the interior is disconnected;
// - every hole lies inside the shell and outside every other hole (decided
//   by one vertex of the hole that touches nothing).
// `unsure`: not decided here (the work budget ran out, a hole whose every
// vertex is a touch point, very many rings through one point); GEOS decides.
// `invalid` says only that GEOS would say so (it still gives the reason).
// Cost O(n log n) in the vertices for the usual shapes (a sweep over
// monotone chains, row and cell indexes to place the holes); past a budget
// linear in n the answer is `unsure`. Thread-safe (per-thread scratch).
//
// `culprits`, when given, gets on `invalid` every problem of the first
// phase that finds one (the edge sweep; the touch points; the hole
// placement), each as one entry per ring in it: the ring, and a point of
// it where the problem lies (the middle of an edge that crosses or
// overlaps another, a touch point, the vertex of a hole found outside the
// shell or inside another hole), or `whole` for a ring of too few points.
// It is empty on any other answer.
struct Culprit {
  uint32_t ring = 0;
  Point2 at;
  bool whole = false;
};
Validity polygon_validity(const std::vector<Ring>& rings, std::vector<Culprit>* culprits = nullptr);

// polygon_validity(rings) == valid: a one-sided proof (false: invalid or
// not decided).
bool certainly_valid(const std::vector<Ring>& rings);

}  // namespace prep::detail
