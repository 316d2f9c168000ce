// The validity fast path of clean (libprep/clean/clean.cpp): a one-sided
// proof that a polygon is valid in GEOS's sense, without GEOS.
//
// Most parts arrive valid; GEOS's isValid (noding every ring, building a
// topology graph) and the copies into and out of GEOS cost more than reading
// them. `certainly_valid` proves validity for the plain case with filtered
// predicates and answers false whenever it cannot be sure, so GEOS still
// decides every doubtful part (and repairs the invalid ones): a false
// "valid" is impossible, a false "not sure" only costs time
// (tests/clean/test_certainly_valid.cpp checks it against GEOS isValid).
#pragma once

#include <vector>

#include "prep/features.hpp"

namespace prep::detail {

// Proves a polygon (rings[0] shell, then holes; unclosed, consecutive
// vertices distinct, finite) valid in GEOS's sense: at every vertex the two
// edges turn (certain orientation: adjacent edges then meet only at their
// shared vertex), no two non-adjacent edges meet (certainly apart), every
// hole strictly inside the shell and outside the other holes. Then no rings
// cross or touch, so the interior is connected and the holes are where they
// belong. False: not proven (GEOS decides). The work is bounded; past the
// budget the answer is false. Up to 8 holes are placed by testing each
// against every ring; more are placed through a row index of the shell's
// edges and a cell index of the hole boxes (near-linear). Thread-safe
// (per-thread scratch).
bool certainly_valid(const std::vector<Ring>& rings);

}  // namespace prep::detail
