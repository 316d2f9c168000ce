// PNG output through libpng, plus the world file of top-down images.
#include <png.h>

#include <algorithm>

#include <cmath>
#include <cstdio>
#include <memory>

#include "prep/error.hpp"
#include "prep/evaluate.hpp"
#include "prep/render.hpp"

namespace prep::render {

void write_png(const std::string& path, const std::vector<uint8_t>& rgba, uint32_t width, uint32_t height) {
  if (rgba.size() != size_t(width) * height * 4) throw output_error("render: image buffer size mismatch for " + path);
  std::unique_ptr<FILE, int (*)(FILE*)> f(std::fopen(path.c_str(), "wb"), &std::fclose);
  if (!f) throw output_error("render: cannot open '" + path + "' for writing");
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  if (!png || !info) {
    png_destroy_write_struct(&png, &info);
    throw output_error("render: libpng initialisation failed for '" + path + "'");
  }
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    throw output_error("render: libpng failed writing '" + path + "'");
  }
  png_init_io(png, f.get());
  png_set_IHDR(png, info, width, height, 8, PNG_COLOR_TYPE_RGBA, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
               PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  for (uint32_t y = 0; y < height; ++y)
    png_write_row(png, const_cast<png_bytep>(rgba.data() + size_t(y) * width * 4));
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  if (std::fflush(f.get()) != 0) throw output_error("render: writing '" + path + "' failed");
}

std::vector<uint8_t> quantise(const std::vector<float>& rgba) {
  std::vector<uint8_t> out(rgba.size());
  for (size_t k = 0; k < rgba.size(); ++k)
    out[k] = uint8_t(std::lround(std::clamp(double(rgba[k]), 0.0, 1.0) * 255.0));
  return out;
}

void write_world_file(const std::string& png_path, const Extent& e, uint32_t width, uint32_t height,
                      const SceneFrame& frame) {
  // One writer for every raster (prep/evaluate.hpp): `.pgw` plus `.aux.xml`
  // with the frame's WKT, in absolute frame coordinates so GDAL and QGIS
  // place the image without knowing the scene origin.
  const Extent absolute{frame.origin_x + e.xmin, frame.origin_y + e.ymin, frame.origin_x + e.xmax,
                        frame.origin_y + e.ymax};
  prep::write_world_file(png_path, absolute, width, height, frame.crs_wkt);
}

}  // namespace prep::render
