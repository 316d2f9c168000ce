// decal/layout.hpp: the u16 BVH boxes of the v1.3 layout. The build stage
// makes each cell's tree on encoded leaf boxes (libprep/model/bvh.cpp), which
// gives the bytes of encoding the full-precision tree only because every
// encoded bound is a monotone function of its bound. Checked here against
// encoding the union directly, on random boxes in, around and beyond cells
// of grids with and without a step shift.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <random>

#include "decal/layout.hpp"

// One test binary holds several files (a unity build): each keeps its
// names in a namespace of its own.
namespace formats_layout {

namespace {

namespace L = decal::layout;
using Box = std::array<int32_t, 4>;

Box unite(const Box& a, const Box& b) {
  return {std::min(a[0], b[0]), std::min(a[1], b[1]), std::max(a[2], b[2]), std::max(a[3], b[3])};
}

void check_grid(const L::CellGrid& g, uint32_t ny, uint32_t expect_shift) {
  ASSERT_EQ(L::box16_shift(g.cell_w, g.cell_h), expect_shift);
  const L::Box16Encoder encode(g);
  std::mt19937_64 rng(g.cell_w * 31 + g.origin_x);
  std::uniform_int_distribution<uint32_t> cell_of(0, g.nx * ny - 1);
  std::uniform_real_distribution<double> u(-0.3, 1.3);  // around the cell, past its sides
  int nonempty_unions = 0;
  for (int t = 0; t < 20000; ++t) {
    const uint32_t c = cell_of(rng);
    const int64_t x0 = g.origin_x + int64_t(c % g.nx) * g.cell_w,
                  y0 = g.origin_y + int64_t(c / g.nx) * g.cell_h;
    auto box = [&] {
      int64_t a = x0 + int64_t(u(rng) * double(g.cell_w)),
              b = x0 + int64_t(u(rng) * double(g.cell_w));
      int64_t p = y0 + int64_t(u(rng) * double(g.cell_h)),
              q = y0 + int64_t(u(rng) * double(g.cell_h));
      return Box{int32_t(std::min(a, b)), int32_t(std::min(p, q)), int32_t(std::max(a, b)),
                 int32_t(std::max(p, q))};
    };
    const Box a = box(), b = box();
    const L::u2 ea = encode(c, a), eb = encode(c, b);
    EXPECT_EQ(L::box16_union(ea, eb), encode(c, unite(a, b)))
        << "cell " << c << " boxes " << a[0] << "," << a[1] << "," << a[2] << "," << a[3] << " / "
        << b[0] << "," << b[1] << "," << b[2] << "," << b[3];
    nonempty_unions += L::box16_union(ea, eb) != L::Box16Encoder::kEmpty;
    // An empty node is neutral, on either side.
    EXPECT_EQ(L::box16_union(ea, L::Box16Encoder::kEmpty), ea);
    EXPECT_EQ(L::box16_union(L::Box16Encoder::kEmpty, eb), eb);
    // The element encoder is the one encode_boxes16 applies.
    const std::vector<L::u2> first{{0, 0}, {0, 1}};
    if (c == 0) {
      EXPECT_EQ(L::encode_boxes16(first, std::vector<Box>{a}, g)[0], ea);
    }
    if (::testing::Test::HasFailure()) return;
  }
  EXPECT_GT(nonempty_unions, 19000);
}

TEST(Box16, UnionOfEncodedBoxesIsTheEncodedUnion) {
  check_grid({-1000000, 250000, 4470, 4470, 40}, 30, 0);      // thesis-sized cells
  check_grid({-5, -7, 65533, 65533, 3}, 3, 0);                // the largest cell at shift 0
  check_grid({-3000000, -2000000, 200000, 150000, 9}, 7, 2);  // steps of 4 quanta
  check_grid({100, 100, 9000000, 9000000, 2}, 2, 8);          // steps of 256 quanta
}

TEST(Box16, EmptyBoxEncodesAsTheEmptyNode) {
  const L::Box16Encoder encode({0, 0, 1000, 1000, 4});
  EXPECT_EQ(encode(5, Box{10, 10, 9, 20}), L::Box16Encoder::kEmpty);
  EXPECT_EQ(encode(5, Box{10, 10, 20, 9}), L::Box16Encoder::kEmpty);
  EXPECT_NE(encode(5, Box{1000, 1000, 1000, 1000}), L::Box16Encoder::kEmpty);
}

}  // namespace

}  // namespace formats_layout
