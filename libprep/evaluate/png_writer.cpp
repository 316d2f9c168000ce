// libprep/evaluate/png_writer.cpp — the one PNG and world-file writer, for
// `decalprep render --cpu` (and anything else that writes rasters).
#include <png.h>

#include <cstdio>
#include <sstream>
#include <string>
#include <vector>

#include "prep/error.hpp"
#include "prep/evaluate.hpp"
#include "prep/files.hpp"
#include "prep/stage_error.hpp"

namespace prep {

void write_png_rgba(const std::string& path, uint32_t width, uint32_t height,
                    std::span<const uint8_t> rgba8) {
  if (rgba8.size() != size_t(width) * height * 4)
    fail<output_error>(kRenderStage, path + ": image buffer has " + std::to_string(rgba8.size()) +
                                         " bytes, expected " +
                                         std::to_string(size_t(width) * height * 4));
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  image.width = width;
  image.height = height;
  image.format = PNG_FORMAT_RGBA;
  // Encoded in memory, then written whole (write_file_atomically): the
  // target is a regular file or nothing, and never half a PNG.
  png_alloc_size_t bytes = 0;
  std::string encoded;
  bool ok = png_image_write_to_memory(&image, nullptr, &bytes, 0, rgba8.data(), 0, nullptr) != 0;
  if (ok) {
    encoded.resize(bytes);
    ok =
        png_image_write_to_memory(&image, encoded.data(), &bytes, 0, rgba8.data(), 0, nullptr) != 0;
    encoded.resize(bytes);
  }
  if (!ok) {
    const std::string msg = image.message;
    png_image_free(&image);
    fail<output_error>(kRenderStage, "cannot encode PNG " + path + ": " + msg);
  }
  write_file_atomically(path, encoded, "PNG");
}

namespace {
std::string xml_escape(const std::string& s) {
  std::string o;
  for (char c : s) {
    switch (c) {
      case '<': o += "&lt;"; break;
      case '>': o += "&gt;"; break;
      case '&': o += "&amp;"; break;
      case '"': o += "&quot;"; break;
      default: o += c;
    }
  }
  return o;
}
}  // namespace

void write_world_file(const std::string& png_path, const Extent& ex, uint32_t width,
                      uint32_t height, const std::string& crs_wkt) {
  const double pw = (ex.xmax - ex.xmin) / width, ph = (ex.ymax - ex.ymin) / height;
  std::ostringstream pgw;
  pgw.precision(17);
  // ESRI world file: A, D, B, E, C, F with C/F the centre of the top-left pixel.
  pgw << pw << "\n0\n0\n"
      << -ph << "\n"
      << ex.xmin + 0.5 * pw << "\n"
      << ex.ymax - 0.5 * ph << "\n";
  std::ostringstream aux;
  aux.precision(17);
  aux << "<PAMDataset>\n";
  if (!crs_wkt.empty())
    aux << "  <SRS dataAxisToSRSAxisMapping=\"1,2\">" << xml_escape(crs_wkt) << "</SRS>\n";
  aux << "  <GeoTransform>" << ex.xmin << ", " << pw << ", 0, " << ex.ymax << ", 0, " << -ph
      << "</GeoTransform>\n";
  aux << "</PAMDataset>\n";
  const std::vector<std::string> paths = world_file_paths(png_path);
  write_file_atomically(paths[0], pgw.str(), "world file");
  write_file_atomically(paths[1], aux.str(), "world file");
}

std::vector<std::string> world_file_paths(const std::string& png_path) {
  std::string base = png_path;
  const auto dot = base.find_last_of('.');
  const auto slash = base.find_last_of('/');
  if (dot != std::string::npos && (slash == std::string::npos || dot > slash)) base.resize(dot);
  return {base + ".pgw", png_path + ".aux.xml"};
}

}  // namespace prep
