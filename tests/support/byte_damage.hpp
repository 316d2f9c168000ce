// Damaged copies of a file's bytes for the hostile-input tests: every single
// bit flipped in turn, each checked by the caller while it is flipped.
#pragma once

#include <gtest/gtest.h>

#include <cstddef>
#include <vector>

namespace prep::test {

// Flips each bit of the first `end` bytes of `bytes` in turn and asks
// `rejected(damaged)` (an AssertionResult) whether the reader refused it.
// Fails at the first flip it did not, naming the byte and the bit; passes
// with the number of flips tried in `flips` when every one was refused.
template <class Rejected>
::testing::AssertionResult every_bit_flip_rejected(std::vector<std::byte> bytes, size_t end,
                                                   Rejected&& rejected, size_t* flips = nullptr) {
  size_t tried = 0;
  for (size_t i = 0; i < end && i < bytes.size(); ++i)
    for (int bit = 0; bit < 8; ++bit, ++tried) {
      bytes[i] ^= std::byte(1u << bit);
      const ::testing::AssertionResult r = rejected(bytes);
      if (!r)
        return ::testing::AssertionFailure()
               << "flip of bit " << bit << " of byte " << i << " was accepted: " << r.message();
      bytes[i] ^= std::byte(1u << bit);
    }
  if (flips) *flips = tried;
  return ::testing::AssertionSuccess();
}

}  // namespace prep::test
