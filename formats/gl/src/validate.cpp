// The loader's structural validation: the package's one check
// (decal::validate_blobs, formats/src/validate.cpp) with the grid, before
// any GL call, because an out-of-range read on a GPU is undefined
// behaviour, not an exception.
#include "decal/gl/gl.hpp"

namespace decal::gl {

Status validate_blobs(std::span<const BlobBytes> blobs, const Grid& grid) {
  Status s = decal::validate_blobs(blobs, {&grid, false});
  if (!s) s.message = "gl loader: invalid package: " + s.message;
  return s;
}

}  // namespace decal::gl
