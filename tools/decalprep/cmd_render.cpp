// decalprep render — draws a package over terrain headless (GL via EGL, or
// the CPU evaluator with --cpu) and writes a PNG. Thin: the options go into
// a prep::render::RenderRequest, prep_render checks and draws it
// (prep/pipeline.hpp), and --stats prints what it drew.
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>

#include "command.hpp"
#include "prep/pipeline.hpp"

namespace {

namespace R = prep::render;

// The request, and --stats: what the command prints after drawing.
struct Args : R::RenderRequest {
  bool stats = false;
};

const char* aa_name(R::AntiAliasing aa) {
  return aa == R::AntiAliasing::msaa4      ? "msaa4"
         : aa == R::AntiAliasing::coverage ? "coverage"
                                           : "none";
}

// --stats: the device and the passes, then what the view drew.
void print_passes(const R::RenderRequest& a, const R::RenderOutcome& out) {
  const R::Image& img = out.image;
  if (out.options.method == R::Method::decal)
    std::printf("device: %s, %ux%u, binding %s, aa %s\n", img.device.c_str(), img.width, img.height,
                a.binding.c_str(), aa_name(out.options.aa));
  else
    std::printf("device: %s, %ux%u, method %s\n", img.device.c_str(), img.width, img.height,
                a.method.c_str());
  std::printf("%-48s %12s %12s\n", "pass", "gpu ms", "wall ms");
  for (const auto& t : img.times)
    std::printf("%-48s %12.3f %12.3f\n", t.pass.c_str(), t.ms, t.wall_ms);
  if (std::isfinite(out.surface_error_bound))
    // not a stage prefix: a --stats label
    std::printf("terrain: %ux%u vertices, within %.6f mm of the DEM surface\n", out.terrain_nx,
                out.terrain_ny, out.surface_error_bound * 1e3);
  else
    std::printf(
        // not a stage prefix: a --stats label
        "terrain: %ux%u vertices on the DEM surface, no bound between them (the mesh is not on "
        "the DEM's cell lattice: the DEM is in another CRS than the frame, or not north-up, or "
        "its lattice was thinned to the vertex limit)\n",
        out.terrain_nx, out.terrain_ny);
  if (out.ramps)
    std::printf("ramps: %llu features recoloured (%zu --ramp)\n",
                static_cast<unsigned long long>(out.recoloured), out.ramps);
  if (out.options.method == R::Method::volume)
    std::printf("volume: %llu prism triangles, %u stencil+cover groups (%u z-fail, %u z-pass)\n",
                static_cast<unsigned long long>(img.prism_triangles), img.volume_groups,
                img.zfail_groups, img.volume_groups - img.zfail_groups);
  if (out.options.method == R::Method::texture)
    std::printf(
        "texture: %ux%u texels at %.3f m, %llu bytes with mipmaps (%.1f MiB), %llu triangles\n",
        img.texture_width, img.texture_height, img.texture_resolution,
        static_cast<unsigned long long>(img.texture_bytes), double(img.texture_bytes) / 1048576.0,
        static_cast<unsigned long long>(img.texture_triangles));
}

// --stats of a tileset: the tiles drawn per level and the bytes they hold.
void print_tiles(const R::RenderOutcome& out) {
  const R::TileSelection& s = out.selection;
  std::printf("tiles: %zu drawn (", s.tiles.size());
  for (size_t l = 0; l < s.per_level.size(); ++l)
    std::printf("%slevel %zu: %zu", l ? ", " : "", l, s.per_level[l]);
  std::printf("), %zu of %zu level-0 tiles meet the view\n", s.full_detail_tiles, out.index_tiles);
  std::printf(
      "bytes: %llu package bytes loaded, %.2f%% of the full-detail %llu of this view; %llu "
      "blob bytes uploaded\n",
      static_cast<unsigned long long>(s.package_bytes),
      s.full_detail_bytes ? 100.0 * double(s.package_bytes) / double(s.full_detail_bytes) : 0.0,
      static_cast<unsigned long long>(s.full_detail_bytes),
      static_cast<unsigned long long>(out.blob_bytes));
  if (out.gpu_budget)
    std::printf(
        "gpu budget: %llu bytes of decoded blobs (GPU memory, not package bytes), %llu "
        "used, %zu tile groups coarsened to fit\n",
        static_cast<unsigned long long>(out.gpu_budget),
        static_cast<unsigned long long>(s.blob_bytes), s.coarsened);
}

// --stats: the frame time, dynamic lines and LOD.
void print_frame(const R::RenderRequest& a, const R::RenderOutcome& out) {
  const R::Image& img = out.image;
  std::printf("frame: %.3f ms (the %s render call, %u frame%s; %s)\n", out.frame_ms,
              a.cpu ? "cpu" : "gl", a.frames, a.frames == 1 ? "" : "s",
              out.tileset ? "each tile read and decoded in it, as it is drawn"
                          : "the package loaded before it");
  if (img.dyn_kept || img.dyn_segments)
    std::printf(
        "dynamic lines: %u vertices kept, %u segments drawn, %u list nodes, %u list regrowths, "
        "%u pixels composited short of their list (step bound)\n",
        img.dyn_kept, img.dyn_segments, img.dyn_nodes, img.list_grows, img.dyn_truncated);
  if (img.lod_lines)
    std::printf(
        // not a stage prefix: a --stats label
        "lod: on, %.3g px: %llu LOD segments drawn of %llu full-detail segments (%.2f%%) on "
        "%llu LOD lines; %llu selected, %llu outside the frustum\n",
        out.options.lod_tolerance_px, static_cast<unsigned long long>(img.lod_drawn),
        static_cast<unsigned long long>(img.lod_full),
        img.lod_full ? 100.0 * double(img.lod_drawn) / double(img.lod_full) : 0.0,
        static_cast<unsigned long long>(img.lod_lines),
        static_cast<unsigned long long>(img.lod_selected),
        static_cast<unsigned long long>(img.lod_selected - img.lod_drawn));
  else if (out.lod_data_unused)
    // not a stage prefix: a --stats label
    std::printf("lod: off (the package has LOD segments; dynamic lines drawn in full)\n");
}

void run(const Args& a) {
  const R::RenderOutcome out = R::render(a);
  if (!a.stats) return;
  print_passes(a, out);
  if (out.tileset) print_tiles(out);
  print_frame(a, out);
}

constexpr decalprep::CommandHelp kRenderHelp{
    "render", "Draw a package over terrain (headless GL, or --cpu) into a PNG",
    "Coordinates: --extent is in absolute coordinates of the package's frame CRS (the crs and\n"
    "origin of `decalprep info`), like build --extent; --extent-crs gives it in another CRS.\n"
    "The .pgw/.aux.xml world file of a top-down view uses the frame CRS's absolute coordinates.\n"
    "--eye and --target are metres relative to the package origin.\n"
    "Examples:\n"
    "  decalprep render city.decals --dem dem.tif --fit --pitch 50 --size 1280x720 -o city.png\n"
    "  decalprep render city.decals --extent 372000,4843200,373600,4844100 --size 800x450 -o "
    "top.png\n"
    "  decalprep render city.decals --extent 7.41,43.73,7.43,43.745 --extent-crs EPSG:4326 --cpu "
    "-o top.png"};

const decalprep::CommandRegistrar kRegister(60, kRenderHelp, [](CLI::App* cmd) {
  auto args = std::make_shared<Args>();
  cmd->add_option("package", args->package, "Package (.decals) or tileset directory")->required();
  cmd->add_option("-o,--output", args->output, "Output PNG")->required();
  cmd->add_option("--dem", args->dem,
                  "DEM raster (any GDAL path); default: the DEM the package was built with, if it "
                  "is a local regular file (or a /vsizip/ path into one) in a self-contained "
                  "format, else flat with a warning; repeat it to mosaic several")
      ->allow_extra_args(false);
  cmd->add_flag("--flat", args->flat, "Flat terrain, even if the package was built with a DEM");
  cmd->add_flag("--strict", args->strict,
                "Make every warning an error (exit 10): a view that misses the package, a DEM "
                "that does not cover the view, a build DEM that cannot be read or is not opened");
  cmd->add_option("--z-scale", args->z_scale,
                  "Height exaggeration (default: the package's build --z-scale, else 1)");
  cmd->add_option(
      "--nodata-fill", args->nodata_fill,
      "Height for DEM no-data, raw DEM units (default: the package's build --nodata-fill, else the "
      "nearest valid cell)");
  cmd->add_option("--assume-crs", args->assume_crs,
                  "CRS of a DEM that has none (default: the package's build --assume-crs; "
                  "otherwise such a DEM is an "
                  "error)");
  cmd->add_option("--extent", args->extent,
                  "Top-down orthographic view xmin,ymin,xmax,ymax in absolute coordinates of the "
                  "package's frame CRS "
                  "(as build --extent and the world file)");
  cmd->add_option("--extent-crs", args->extent_crs,
                  "CRS of --extent (e.g. EPSG:4326, lon/lat order; default: the frame)");
  cmd->add_option("--size", args->size,
                  "Image size WxH (default 640x360; each side 1..16384, at most 8192x8192 "
                  "pixels in all); with --extent also W (or Wx): the height from its aspect");
  cmd->add_flag("--stretch", args->stretch,
                "--extent as given even where its aspect is not --size's (pixels not square); "
                "without it the extent is widened about its centre to square pixels");
  cmd->add_option("--eye", args->eye,
                  "Camera position x,y,z (metres relative to the package origin)");
  cmd->add_option("--target", args->target,
                  "Camera target x,y,z (metres relative to the package origin)");
  cmd->add_option("--fov", args->fov, "Vertical field of view, degrees, in (0, 180)");
  cmd->add_option("--pitch", args->pitch,
                  "--fit: camera pitch below the horizon, degrees, in (0, 90] (default 45)");
  cmd->add_flag("--ortho", args->ortho, "Orthographic projection");
  cmd->add_flag("--fit", args->fit, "Frame the package extent (default without --eye/--extent)");
  cmd->add_flag("--cpu", args->cpu, "Render with the CPU evaluator instead of GL");
  cmd->add_option("--aa", args->aa,
                  "Anti-aliasing: none|coverage|msaa4 (default: msaa4 in GL with --method decal; "
                  "none with --cpu and --method volume|texture, which draw aliased)");
  cmd->add_option("--binding", args->binding, "Blob binding: ssbo|texture");
  cmd->add_option("--method", args->method,
                  "Static decals drawn as: decal (screen-space decals, default), volume (stencil "
                  "shadow volumes) or texture (features rasterised into a mipmapped texture); GL "
                  "only, dynamic lines always as decals");
  cmd->add_option("--slope-widths", args->slope_widths,
                  "Static line widths along the terrain instead of in plan: auto (default: the "
                  "layers whose scene set slope_widths), on (every static line) or off; decal "
                  "method and --cpu");
  cmd->add_option("--decal-light", args->decal_light,
                  "Static decals lit by the terrain's light in the image: on (default; their "
                  "colour times the terrain's shade, as the terrain is lit) or off (flat colour). "
                  "--decals and --raw stay unlit; dynamic lines are never lit");
  cmd->add_option("--texture-resolution", args->texture_resolution,
                  "--method texture: ground metres per texel (default 1, coarser where the "
                  "extent needs more than 8192 texels a side)");
  cmd->add_option("--level", args->level,
                  "Tileset: auto (default: per tile, the coarsest overview level whose "
                  "resolution is within a pixel) or L (that level everywhere; 0: full detail)");
  cmd->add_option("--gpu-budget", args->gpu_budget,
                  "Tileset: GPU memory the drawn tiles may take, as their blobs' decoded bytes "
                  "(not the smaller package bytes; e.g. 512M, 2G); coarser levels where the view "
                  "needs more, exit 6 when even the coarsest do (default: no limit)");
  cmd->add_option("--only", args->only, "Draw only these decal kinds: polygons,lines,dynamic");
  cmd->add_option("--lod", args->lod,
                  "LOCALIS LOD of dynamic lines built with lod = true: on (default; the segments "
                  "this view selects, chosen on the GPU, or on the CPU with --cpu) or off (every "
                  "vertex)");
  cmd->add_option("--lod-tolerance", args->lod_tolerance,
                  "--lod on: screen-space error in pixels a simplified line may have (default "
                  "0.5)");
  cmd->add_option("--ramp", args->ramps,
                  "Colour ramp for a value-coloured layer, applied when drawing (no rebuild): "
                  "LAYER=value:#rrggbb[aa],value:#rrggbb[aa],... (values increasing; linear per "
                  "channel between stops, clamped outside). Repeat for more layers")
      ->expected(1)
      ->take_all();
  cmd->add_option("--frames", args->frames,
                  "GL: render N frames, report the last one's pass times (warm)")
      ->check(CLI::Range(1u, 1000u));
  cmd->add_flag("--stats", args->stats,
                "Print per-pass times (GL timestamp queries and wall time), the frame time, "
                "LOD segments drawn against full detail; a "
                // not a stage prefix: help text
                "tileset: tiles drawn per level, package bytes loaded against full detail, "
                "decoded blob bytes, --gpu-budget; --method "
                "volume: prism triangles and groups; --method texture: texture size and bytes");
  cmd->add_option(
      "--raw", args->raw,
      "Write the static decal layer as float32 RGBA (straight alpha, row 0 at the top)");
  cmd->add_option("--decals", args->decals_png, "Write the decal layer alone as PNG");
  cmd->callback([args] {
    run(*args);
    decalprep::set_exit_code(prep::ExitCode::ok);
  });
});

}  // namespace
