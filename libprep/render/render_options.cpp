// The one check of the renderer's options (prep/render.hpp
// check_render_options): the GL renderer and `decalprep render`'s request
// (prep/pipeline.hpp) both call it, so each option is refused in one
// place and in one wording.
#include <cmath>
#include <cstdint>
#include <string>

#include "prep/error.hpp"
#include "prep/render.hpp"
#include "prep/stage_error.hpp"

namespace prep::render {

namespace {

const char* method_name(Method m) {
  switch (m) {
    case Method::decal: return "decal";
    case Method::volume: return "volume";
    case Method::texture: return "texture";
  }
  return "?";
}

}  // namespace

void check_render_options(const RenderOptions& opt) {
  const uint32_t W = opt.width, H = opt.height;
  if (W == 0 || H == 0 || W > kMaxImageSide || H > kMaxImageSide)
    fail<usage_error>(kRenderStage, "image size must be 1..16384 pixels");
  if (opt.method != Method::decal && opt.aa != AntiAliasing::none)
    fail<usage_error>(kRenderStage, std::string("--method ") + method_name(opt.method) +
                                        " draws without anti-aliasing; use --aa none");
  if (!(opt.texture_resolution >= 0) || !std::isfinite(opt.texture_resolution))
    fail<usage_error>(kRenderStage, "--texture-resolution must be a positive number of metres");
  if (opt.slope_widths == SlopeWidths::on && opt.method != Method::decal)
    fail<usage_error>(kRenderStage,
                      std::string("--slope-widths on needs --method decal (--method ") +
                          method_name(opt.method) + " draws the features' plan geometry)");
}

}  // namespace prep::render
