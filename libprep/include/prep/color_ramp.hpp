// prep/color_ramp.hpp — a feature's colour from its attribute value through
// a layer's colour ramp (thesis §4.2.1: the value stored per feature, mapped
// through a transfer function). One formula for the build, which bakes the
// colour into LineProps/PolyProps.rgba, and for render --ramp, which maps the
// stored value again when drawing.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "prep/scene.hpp"

namespace prep {

// `value` through `ramp` (stops sorted by increasing value): linear per
// channel (R, G, B, A) between the two stops around it, rounded to the
// nearest integer, clamped to the first and last stop's colour outside them.
// `fallback` when the ramp is empty or the value is not finite (no value).
// The value is taken at float precision, as LineProps/PolyProps store it, so
// the build and a draw-time ramp give the same colour for the same stops.
inline uint32_t ramp_rgba(const std::vector<ColorStop>& ramp, double value, uint32_t fallback) {
  const double v = double(float(value));
  if (ramp.empty() || !std::isfinite(v)) return fallback;
  if (v <= ramp.front().value) return ramp.front().rgba;
  if (v >= ramp.back().value) return ramp.back().rgba;
  size_t k = 1;
  while (ramp[k].value < v) ++k;  // ramp.back().value > v ends the search
  const ColorStop& a = ramp[k - 1];
  const ColorStop& b = ramp[k];
  const double t = (v - a.value) / (b.value - a.value);
  uint32_t out = 0;
  for (int c = 0; c < 4; ++c) {
    const double ca = double((a.rgba >> (8 * c)) & 0xffu), cb = double((b.rgba >> (8 * c)) & 0xffu);
    out |= uint32_t(std::clamp(std::lround(ca + t * (cb - ca)), 0L, 255L)) << (8 * c);
  }
  return out;
}

// A layer's colour for one feature: its constant colour, or the feature's
// value through the ramp when the layer is coloured by an attribute.
inline uint32_t resolve_color(const LayerColor& color, double value) {
  return color.attribute.empty() ? color.rgba : ramp_rgba(color.ramp, value, color.rgba);
}

}  // namespace prep
