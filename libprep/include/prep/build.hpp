// prep/build.hpp — stage 4: SceneFeatures -> DecalModel (thesis ch. 4.2).
#pragma once

#include "prep/model.hpp"
#include "prep/scene.hpp"

namespace prep {

// Builds every static structure (grid, line segments with corner data,
// polygon quad-trees, per-cell BVHs) and, through build_dynamic(), the
// terrain-matched dynamic lines and LOD segments. Parallel with oneTBB; the
// result is byte-identical at any thread count. Throws resource_error when a
// budget is exceeded. `dem` is the DEM path ("" for flat terrain).
DecalModel build_model(const SceneFeatures& scene, const BuildOptions& options,
                       const std::string& dem = "");

// Fills the dyn_* and lod_* arrays of `model` from scene.dynamic_lines and
// LOD-enabled layers (libprep/terrain, libprep/lod). Appends notes and counts
// to model.manifest.
void build_dynamic(const SceneFeatures& scene, const BuildOptions& options,
                   const std::string& dem, DecalModel& model);

}  // namespace prep
