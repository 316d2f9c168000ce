// tests/evaluate/sampling.hpp — the sampling frame the evaluator accuracy
// tests share: the counts of a run against a GEOS oracle, the oracle regions
// and their boundaries prepared for point queries, sampling split into chunks
// over TBB, and the summary line. The oracle itself stays in each test.
#pragma once

#include <tbb/parallel_for.h>

#include <cstdint>
#include <cstdio>
#include <mutex>
#include <random>
#include <utility>
#include <vector>

#include "prep/model.hpp"
#include "synthetic.hpp"

namespace synth {

struct Outcome {
  uint64_t tested = 0, excluded = 0, inside = 0, wrong = 0;
  Outcome& operator+=(const Outcome& o) {
    tested += o.tested;
    excluded += o.excluded;
    inside += o.inside;
    wrong += o.wrong;
    return *this;
  }
};

// Oracle regions and their boundaries, prepared for point queries. One per
// thread, on that thread's GEOS context (which must outlive it).
class PreparedRegions {
 public:
  explicit PreparedRegions(GEOSContextHandle_t h) : h_(h) {}
  ~PreparedRegions() {
    for (auto* p : parea_) GEOSPreparedGeom_destroy_r(h_, p);
    for (auto* p : pbound_) GEOSPreparedGeom_destroy_r(h_, p);
  }
  PreparedRegions(const PreparedRegions&) = delete;
  PreparedRegions& operator=(const PreparedRegions&) = delete;

  void add(G region) {
    bound_.push_back(G(h_, GEOSBoundary_r(h_, region.g)));
    area_.push_back(std::move(region));
    parea_.push_back(GEOSPrepare_r(h_, area_.back().g));
    pbound_.push_back(GEOSPrepare_r(h_, bound_.back().g));
  }
  const G& area(size_t i) const { return area_[i]; }
  bool contains(size_t i, const G& pt) const { return GEOSPreparedContains_r(h_, parea_[i], pt.g); }
  // Whether `pt` lies within `band` of region i's boundary.
  bool near_boundary(size_t i, const G& pt, double band) const {
    return GEOSPreparedDistanceWithin_r(h_, pbound_[i], pt.g, band);
  }

 private:
  GEOSContextHandle_t h_;
  std::vector<G> area_, bound_;
  std::vector<const GEOSPreparedGeometry*> parea_, pbound_;
};

// `n` samples in `chunks` chunks run in parallel, each on its own GEOS
// context and random stream (seeded `seed` + chunk index):
// `sample(h, rng, count)` draws `count` points and returns their Outcome; the
// sum is returned.
template <class Sample>
Outcome sample_in_chunks(size_t n, size_t chunks, uint64_t seed, Sample&& sample) {
  std::mutex mu;
  Outcome total;
  tbb::parallel_for(size_t(0), chunks, [&](size_t c) {
    Geos geos;
    std::mt19937_64 rng(seed + c);
    const Outcome o = sample(geos.h, rng, n / chunks + (c < n % chunks ? 1 : 0));
    std::lock_guard<std::mutex> lock(mu);
    total += o;
  });
  return total;
}

// The summary line of one case: `what` is "lines" or "polygons", `inside`
// names the samples the oracle covers.
inline void print_outcome(const char* name, const char* what, const char* inside, const Outcome& o,
                          const prep::DecalModel& model) {
  std::printf(
      "[%s] %s: %llu samples tested, %llu excluded (within 2 mm), %llu %s, "
      "%llu misclassified; grid %ux%u; max representation error %.6f mm\n",
      name, what, (unsigned long long)o.tested, (unsigned long long)o.excluded,
      (unsigned long long)o.inside, inside, (unsigned long long)o.wrong, model.grid.nx,
      model.grid.ny, model.max_representation_error * 1000);
}

}  // namespace synth
