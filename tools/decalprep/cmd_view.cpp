// cmd_view.cpp — `decalprep view PACKAGE|TILESET [--bind ADDR] [--port N]`:
// serves the browser viewer and the data over HTTP (prep/view.hpp) until
// SIGINT or SIGTERM. With --screenshot OUT.png it places the camera as
// `decalprep render` does (prep::render::place_render_view, the same code and
// options), has a headless Chromium draw that view with the browser
// renderer and writes what the page sends back (prep::view::screenshot).
#include <algorithm>
#include <array>
#include <charconv>
#include <cstddef>
#include <cstdio>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "command.hpp"
#include "prep/memory_estimate.hpp"
#include "prep/pipeline.hpp"
#include "prep/view.hpp"

namespace {

namespace R = prep::render;

constexpr std::string_view kViewCommand = "view";

struct ViewArgs {
  prep::view::ServeOptions serve;
  // --screenshot: render's camera options and outputs (output, decals_png,
  // extent, extent_crs, eye, target, fit, pitch, fov, ortho, size, ramps).
  R::RenderRequest shot;
  double timeout = 120;
  bool verbose = false;
  bool stats = false;       // --stats: the page's frame times
  std::string gpu_budget;   // --gpu-budget SIZE
  int stand_in_level = -1;  // --stand-in-level L (-1: none)
  // --pick X,Y: pixels whose top decal the page reports (x right, y down).
  std::vector<std::string> picks;
};

// --pick's "X,Y" as two pixel indices inside the image; usage_error otherwise.
std::array<uint32_t, 2> parse_pick(const std::string& text, uint32_t width, uint32_t height) {
  const auto comma = text.find(',');
  const auto whole = [&](std::string_view part, uint32_t limit, const char* axis) {
    uint32_t v = 0;
    const auto [end, ec] = std::from_chars(part.data(), part.data() + part.size(), v);
    if (part.empty() || ec != std::errc() || end != part.data() + part.size() || v >= limit)
      prep::fail<prep::usage_error>(kViewCommand, "--pick '" + text + "': " + axis +
                                                      " must be a whole pixel index below " +
                                                      std::to_string(limit));
    return v;
  };
  if (comma == std::string::npos)
    prep::fail<prep::usage_error>(kViewCommand, "--pick '" + text + "': expected X,Y (pixels)");
  const std::string_view all(text);
  return {whole(all.substr(0, comma), width, "X"), whole(all.substr(comma + 1), height, "Y")};
}

// --gpu-budget SIZE in bytes (as render's: 512M, 2G, 1073741824).
uint64_t parse_budget(const std::string& text) {
  try {
    const uint64_t bytes = prep::parse_memory_size(text);
    if (bytes > 0) return bytes;
  } catch (const prep::usage_error&) {
  }
  prep::fail<prep::usage_error>(kViewCommand,
                                "--gpu-budget: expected a size such as 512M, 2G or "
                                "1073741824 (bytes), got \"" +
                                    text + "\"");
}

nlohmann::json vec3(const prep::render::Vec3& v) {
  return nlohmann::json::array({v[0], v[1], v[2]});
}

// The config's "screenshot" object (web/viewer reads it): the camera as
// prep::render::Camera holds it, metres relative to the package origin.
nlohmann::json shot_config(const R::RenderView& v, bool decals,
                           const std::vector<std::array<uint32_t, 2>>& picks, bool pass_times) {
  const R::Camera& c = v.options.camera;
  nlohmann::json cam = {
      {"projection", c.projection == R::Projection::orthographic ? "orthographic" : "perspective"},
      {"eye", vec3(c.eye)},
      {"target", vec3(c.target)},
      {"up", vec3(c.up)},
      {"fovYDeg", c.fov_y_deg},
      {"orthoW", c.ortho_w},
      {"orthoH", c.ortho_h},
      {"near", c.near},
      {"depthRange", c.depth_range},
      {"topdownExtent", nullptr}};
  if (c.topdown_extent) {
    const prep::Extent& e = *c.topdown_extent;
    cam["topdownExtent"] = {e.xmin, e.ymin, e.xmax, e.ymax};
  }
  // --ramp: [[layer index, [[value, r, g, b, a], ...]], ...]
  nlohmann::json ramps = nlohmann::json::array();
  for (size_t layer = 0; layer < v.ramps.size(); ++layer) {
    if (v.ramps[layer].empty()) continue;
    nlohmann::json stops = nlohmann::json::array();
    for (const prep::ColorStop& s : v.ramps[layer])
      stops.push_back({s.value, s.rgba & 0xff, (s.rgba >> 8) & 0xff, (s.rgba >> 16) & 0xff,
                       (s.rgba >> 24) & 0xff});
    ramps.push_back({layer, stops});
  }
  const auto& a = v.options.albedo;
  // --only: the decal kinds to draw (the page hides the other layers).
  const nlohmann::json only = {{"polygons", v.options.draw_polygons},
                               {"lines", v.options.draw_lines},
                               {"dynamic", v.options.draw_dynamic}};
  return {{"width", v.options.width},
          {"height", v.options.height},
          {"camera", cam},
          {"albedo", {a[0], a[1], a[2]}},
          {"decals", decals},
          {"ramps", ramps},
          {"only", only},
          {"frames", v.options.frames},
          {"picks", picks},
          {"passTimes", pass_times}};
}

// --pick: the page's answers, one line each in the order asked (untrusted
// JSON, as print_stats): "pick X,Y: KIND, layer L 'NAME', fid F" or
// "pick X,Y: no decal".
void print_picks(const std::string& text, size_t asked) {
  const nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
  const bool ok =
      j.is_object() && j.contains("picks") && j["picks"].is_array() && j["picks"].size() == asked;
  if (!ok)
    prep::fail<prep::render_error>(
        kViewCommand, "--pick: the page sent no answer for " + std::to_string(asked) + " pick(s)");
  for (const nlohmann::json& p : j["picks"]) {
    const auto num = [&p](const char* key) {
      return p.is_object() && p.contains(key) && p[key].is_number_unsigned()
                 ? p[key].get<uint64_t>()
                 : uint64_t{0};
    };
    const auto str = [&p](const char* key) {
      return p.is_object() && p.contains(key) && p[key].is_string() ? p[key].get<std::string>()
                                                                    : std::string();
    };
    const std::string kind = str("kind");
    if (kind == "line" || kind == "polygon")
      std::printf("pick %llu,%llu: %s, layer %llu '%s', fid %llu\n",
                  static_cast<unsigned long long>(num("x")),
                  static_cast<unsigned long long>(num("y")), kind.c_str(),
                  static_cast<unsigned long long>(num("layer")), str("layerName").c_str(),
                  static_cast<unsigned long long>(num("feature")));
    else
      std::printf("pick %llu,%llu: no decal\n", static_cast<unsigned long long>(num("x")),
                  static_cast<unsigned long long>(num("y")));
  }
}

// --stats: each pass's median over the warm frames, as the page timed them
// ("timestamp": GPU timestamp queries; "wall": each pass submitted and
// awaited alone); the dynamic-line passes where the records have them.
// Frames whose record is malformed are left out.
void print_pass_times(const nlohmann::json& j) {
  if (!j.contains("passes") || !j["passes"].is_array() || j["passes"].empty()) return;
  const nlohmann::json& all = j["passes"];
  std::string timing;
  std::string line;
  for (const char* pass : {"terrain", "decals", "dynamic", "composite"}) {
    std::vector<double> ms;
    for (size_t i = all.size() > 1 ? 1 : 0; i < all.size(); ++i) {
      const nlohmann::json& f = all[i];
      if (!f.is_object() || !f.contains(pass) || !f[pass].is_number()) continue;
      ms.push_back(f[pass].get<double>());
      if (timing.empty() && f.contains("timing") && f["timing"].is_string())
        timing = f["timing"].get<std::string>();
    }
    // A frame without dynamic lines times their passes as 0: left out.
    if (std::string_view(pass) == "dynamic" &&
        std::all_of(ms.begin(), ms.end(), [](double t) { return t == 0.0; }))
      continue;
    if (ms.empty()) return;
    const auto mid = ms.begin() + static_cast<std::ptrdiff_t>(ms.size() / 2);
    std::nth_element(ms.begin(), mid, ms.end());
    char buf[64];
    std::snprintf(buf, sizeof buf, "%s%s %.3f ms", line.empty() ? "" : ", ", pass, *mid);
    line += buf;
  }
  std::printf("passes (%s, median of the warm frames): %s\n",
              timing == "timestamp" ? "GPU timestamps" : "wall time of each pass alone",
              line.c_str());
}

// --stats of a tileset: the tiles the page chose for the view (per level),
// their package bytes against the full detail's (the level-0 tiles the
// view meets) and what its tile cache fetched.
void print_tile_stats(const nlohmann::json& j) {
  if (!j.contains("tiles") || !j["tiles"].is_object()) return;
  const nlohmann::json& t = j["tiles"];
  const auto num = [&t](const char* key) {
    return t.contains(key) && t[key].is_number() ? t[key].get<double>() : 0.0;
  };
  std::string mix;
  if (t.contains("perLevel") && t["perLevel"].is_array())
    for (size_t l = 0; l < t["perLevel"].size(); ++l)
      if (t["perLevel"][l].is_number() && t["perLevel"][l].get<double>() > 0)
        mix += (mix.empty() ? "" : ", ") + ("L" + std::to_string(l)) + ": " +
               std::to_string(t["perLevel"][l].get<uint64_t>());
  const double full = num("fullDetailBytes");
  std::printf(
      "tiles: %.0f chosen (%s), %.0f drawn; package bytes %.0f of the full detail's %.0f (%.3f%%, "
      "%.0f level-0 tiles in view); the page fetched %.0f tiles, %.0f bytes\n",
      num("chosen"), mix.empty() ? "none" : mix.c_str(), num("drawn"), num("packageBytes"), full,
      full > 0 ? 100.0 * num("packageBytes") / full : 0.0, num("fullDetailTiles"), num("requests"),
      num("fetchedBytes"));
  if (num("gpuBudget") > 0)
    std::printf(
        "gpu budget: %.0f bytes of decoded blobs, %.0f used, %.0f tile groups coarsened to fit; "
        "%.0f tile headers read for their sizes\n",
        num("gpuBudget"), num("blobBytes"), num("coarsened"), num("headerReads"));
}

// --stats: what the page measured (its JSON is the page's, so untrusted:
// a field that is missing or of the wrong type is left out).
void print_stats(const std::string& text, uint32_t width, uint32_t height) {
  const nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
  if (!j.is_object()) {
    std::printf("stats: the page sent no readable frame times\n");
    return;
  }
  const auto str = [&j](const char* key) {
    return j.contains(key) && j[key].is_string() ? j[key].get<std::string>() : std::string("?");
  };
  std::printf("device: %s in %s, %ux%u\n", str("adapter").c_str(), str("browser").c_str(), width,
              height);
  std::vector<double> ms;
  if (j.contains("times") && j["times"].is_array())
    for (const auto& t : j["times"])
      if (t.is_number()) ms.push_back(t.get<double>());
  if (ms.empty()) return;
  std::string all;
  for (double t : ms) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%s%.2f", all.empty() ? "" : ", ", t);
    all += buf;
  }
  std::vector<double> warm(ms.begin() + (ms.size() > 1 ? 1 : 0), ms.end());
  const auto mid = warm.begin() + static_cast<std::ptrdiff_t>(warm.size() / 2);
  std::nth_element(warm.begin(), mid, warm.end());
  std::printf(
      "frame: %.3f ms median of %zu warm frame%s, first %.3f ms (renderFrame: encode, submit "
      "and the queue done, read-back not included); all: %s\n",
      *mid, warm.size(), warm.size() == 1 ? "" : "s", ms.front(), all.c_str());
  print_pass_times(j);
  if (j.contains("gpuBytes") && j["gpuBytes"].is_number())
    std::printf("gpu memory: %.0f bytes of buffers and textures\n", j["gpuBytes"].get<double>());
  print_tile_stats(j);
}

void run_screenshot(ViewArgs& a) {
  R::RenderRequest& r = a.shot;
  r.package = a.serve.path;
  // The camera is placed over the terrain the page draws: the terrain file
  // the server names in /config.json, else flat ground.
  const auto terrain = prep::view::page_terrain(prep::view::resolve_root(r.package));
  r.terrain_file = terrain ? terrain->string() : std::string();
  r.flat = !terrain;
  const R::RenderView v = R::place_render_view(r);
  const auto chromium = prep::view::find_chromium();
  if (!chromium) {
    const char* env = std::getenv("DECALPREP_CHROMIUM");
    prep::fail<prep::error>(
        kViewCommand,
        std::string("--screenshot needs Chromium: ") +
            (env && *env
                 ? "$DECALPREP_CHROMIUM '" + std::string(env) + "' is not an executable file"
                 : "neither chromium nor chromium-headless-shell is on PATH") +
            " (install it with `apt-get install chromium`, or set DECALPREP_CHROMIUM to its path)",
        prep::ExitCode::browser);
  }
  prep::view::ShotOptions s;
  s.width = v.options.width;
  s.height = v.options.height;
  s.decals = !r.decals_png.empty();
  std::vector<std::array<uint32_t, 2>> picks;
  for (const std::string& p : a.picks) picks.push_back(parse_pick(p, s.width, s.height));
  nlohmann::json config = shot_config(v, s.decals, picks, a.stats);
  if (a.stand_in_level >= 0) config["standInLevel"] = a.stand_in_level;
  s.config_json = config.dump();
  s.backend = a.serve.backend;
  s.gpu_budget = a.serve.gpu_budget;
  s.chromium = *chromium;
  s.timeout_s = a.timeout;
  s.verbose = a.verbose;
  s.write_frame = [&](std::span<const uint8_t> rgba) {
    prep::write_png_rgba(r.output, s.width, s.height, rgba);
    if (v.topdown_absolute)
      prep::write_world_file(r.output, *v.topdown_absolute, s.width, s.height, v.frame.crs_wkt);
  };
  s.write_decals = [&](std::span<const uint8_t> rgba) {
    prep::write_png_rgba(r.decals_png, s.width, s.height, rgba);
  };
  bool answered = false;
  if (a.stats || !picks.empty())
    s.on_stats = [&](const std::string& text) {
      if (a.stats) print_stats(text, s.width, s.height);
      if (!picks.empty()) print_picks(text, picks.size());
      answered = true;
    };
  if (a.stats)
    s.on_data = [](uint64_t requests, uint64_t bytes,
                   const std::vector<std::pair<std::string, uint64_t>>& files) {
      std::printf("data: %llu requests, %llu bytes of the package's files sent\n",
                  static_cast<unsigned long long>(requests),
                  static_cast<unsigned long long>(bytes));
      std::string list;
      for (const auto& [file, sent] : files)
        list += (list.empty() ? "" : " ") + file + ":" + std::to_string(sent);
      std::printf("data files (FILE:BYTES sent): %s\n", list.c_str());
    };
  prep::view::screenshot(a.serve.path, s);
  if (!picks.empty() && !answered)
    prep::fail<prep::render_error>(kViewCommand, "--pick: the page sent no answer");
}

constexpr decalprep::CommandHelp kViewHelp{
    "view", "Serve a package or tileset to the browser viewer",
    "Serves the viewer page (web/, built into decalprep) and the data over HTTP, and prints\n"
    "the URL to open. Only the package and its side files (STEM.* next to STEM.decals), or the\n"
    "files under the tileset folder, are served; never a listing, a path with '..' or a link\n"
    "that leads out. Listens on 127.0.0.1 unless --bind says otherwise. Stop with Ctrl-C.\n"
    "A tileset is streamed: each view fetches the tiles and overview levels it needs (render's\n"
    "rule; --gpu-budget caps their decoded bytes) and draws what has arrived.\n"
    "--screenshot: a headless Chromium (chromium or chromium-headless-shell on PATH, or\n"
    "$DECALPREP_CHROMIUM) draws the view that `render` would draw with the same camera\n"
    "options; exit 12 when there is no Chromium, 8 when the page fails or times out.\n"
    "Examples:\n  decalprep view city.decals\n  decalprep view country/ --port 0\n"
    "  decalprep view city.decals --bind 0.0.0.0 --port 8000\n"
    "  decalprep view country/ --gpu-budget 512M\n"
    "  decalprep view city.decals --screenshot city.png --fit --pitch 50 --size 1280x720\n"
    "  decalprep view city.decals --screenshot city.png --pick 320,180 --pick 10,20\n"
    "  decalprep view city.decals --screenshot city.png --backend webgl2"};

void add_screenshot_options(CLI::App* cmd, ViewArgs& a) {
  R::RenderRequest& r = a.shot;
  auto* shot = cmd->add_option("--screenshot", r.output,
                               "Draw one frame in a headless Chromium and write it as PNG "
                               "(the camera options below are render's)");
  auto needs = [shot](CLI::Option* o) { return o->needs(shot); };
  needs(cmd->add_option("--decals", r.decals_png, "--screenshot: the decal layer alone as PNG"));
  needs(
      cmd->add_option("--extent", r.extent,
                      "Top-down view xmin,ymin,xmax,ymax in the package's frame CRS (as render)"));
  needs(cmd->add_option("--extent-crs", r.extent_crs, "CRS of --extent (as render)"));
  needs(cmd->add_option("--eye", r.eye, "Camera position x,y,z (metres relative to the origin)"));
  needs(cmd->add_option("--target", r.target, "Camera target x,y,z (relative to the origin)"));
  needs(cmd->add_flag("--fit", r.fit, "Frame the package extent (the default, as render)"));
  needs(cmd->add_option("--pitch", r.pitch, "--fit: pitch below the horizon, degrees (45)"));
  needs(cmd->add_option("--fov", r.fov, "Vertical field of view, degrees (45)"));
  needs(cmd->add_flag("--ortho", r.ortho, "Orthographic projection"));
  needs(cmd->add_option("--size", r.size,
                        "Image size WxH (default 640x360), or W with --extent (as render)"));
  needs(cmd->add_flag("--stretch", r.stretch,
                      "--extent as given even where its pixels are not square (as render)"));
  needs(cmd->add_option("--only", r.only,
                        "Draw only these decal kinds: polygons,lines,dynamic (as render; "
                        "--backend webgl2 draws no dynamic lines)"));
  needs(cmd->add_option("--ramp", r.ramps,
                        "Colour ramp LAYER=value:#rrggbb[aa],... (as render; repeat for more)")
            ->expected(1)
            ->take_all());
  needs(cmd->add_option("--frames", r.frames,
                        "--screenshot: draw N frames, write the last (for --stats; default 1)")
            ->check(CLI::Range(1, 1000)));
  needs(cmd->add_flag("--stats", a.stats,
                      "--screenshot: print the browser's adapter and frame times"));
  needs(cmd->add_option("--pick", a.picks,
                        "--screenshot: print the top decal (layer, feature id) under pixel X,Y "
                        "(from the top-left; repeat for more)")
            ->expected(1)
            ->take_all());
  needs(cmd->add_option("--timeout", a.timeout,
                        "--screenshot: seconds to wait for the page (default 120)")
            ->check(CLI::PositiveNumber));
  needs(
      cmd->add_option("--stand-in-level", a.stand_in_level,
                      "--screenshot of a tileset: draw the view as the viewer shows it before its "
                      "tiles arrive, from the level-L tiles alone standing in for them")
          ->check(CLI::Range(0, 64)));
  needs(cmd->add_flag("--verbose", a.verbose,
                      "--screenshot: Chromium's log and the page's console on stderr"));
}

const decalprep::CommandRegistrar kView(70, kViewHelp, [](CLI::App* cmd) {
  auto args = std::make_shared<ViewArgs>();
  prep::view::ServeOptions& opt = args->serve;
  cmd->add_option("PATH", opt.path,
                  "the .decals package, or a tileset folder (or its tileset.json)")
      ->required();
  cmd->add_option("--bind", opt.bind,
                  "the address to listen on (default 127.0.0.1: this machine only)");
  cmd->add_option("--port", opt.port, "the port (default 8080; 0: a free one)")
      ->check(CLI::Range(0, 65535));
  cmd->add_option("--backend", opt.backend,
                  "the page's renderer: auto (WebGPU, else WebGL2; the default), webgpu, or "
                  "webgl2 (static decals only)")
      ->check(CLI::IsMember({"auto", "webgpu", "webgl2"}));
  cmd->add_option("--gpu-budget", args->gpu_budget,
                  "A tileset: decoded blob bytes the page may hold on the GPU (512M, 2G, ...): "
                  "each view's tiles are coarsened to fit, as render --gpu-budget");
  add_screenshot_options(cmd, *args);
  cmd->callback([args] {
    if (!args->gpu_budget.empty()) {
      args->serve.gpu_budget = parse_budget(args->gpu_budget);
      if (prep::view::resolve_root(args->serve.path).kind != prep::view::ServeRoot::Kind::tileset)
        prep::fail<prep::usage_error>(kViewCommand, "--gpu-budget applies to a tileset; '" +
                                                        args->serve.path +
                                                        "' is a package (drawn whole)");
    }
    if (!args->shot.output.empty()) {
      run_screenshot(*args);
    } else {
      prep::view::serve(args->serve, [](const std::string& url) {
        std::printf("decalprep view: serving on %s (Ctrl-C stops)\n", url.c_str());
        std::fflush(stdout);
      });
    }
    decalprep::set_exit_code(prep::ExitCode::ok);
  });
});

}  // namespace
