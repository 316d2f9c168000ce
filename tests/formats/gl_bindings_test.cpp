// The shaders against the one table of binding points and texture units
// (formats/gl/include/decal/gl/bindings.hpp): every program the renderer
// builds is compiled with the table's GLSL (glsl_bindings()), and every
// storage block and sampler it declares must sit at the table's index (blob
// blocks B_<name> and samplers t_<name> at binding_of, the others at their
// kFrameBindings row); no shader spells a binding as a bare number.
#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>
#include <gtest/gtest.h>

#include <optional>
#include <regex>
#include <string>
#include <vector>

#include "decal/gl/gl.hpp"

// One test binary holds several files (a unity build): each keeps its
// names in a namespace of its own.
namespace formats_gl_bindings {

namespace {

namespace G = decal::gl;

struct Program {
  std::string label;
  G::ProgramSources sources;
};

// The programs of libprep/render (gl_passes.cpp, gl_dynamic.cpp,
// gl_methods.cpp), in each binding mode.
std::vector<Program> renderer_programs() {
  std::vector<Program> out;
  const std::vector<std::string> lines_fs = {"decal_blobs.glsl", "static_common.glsl",
                                             "slope_widths.glsl", "dash.glsl", "static_lines.glsl"};
  for (const std::string mode : {"", "#define DECAL_TEXTURE 1\n"}) {
    const std::string m = mode.empty() ? "ssbo " : "texture ";
    for (const std::string aa : {"", "#define DECAL_AA_COVERAGE 1\n", "#define DECAL_MSAA 1\n"}) {
      for (const std::string unlit : {"", "#define DECAL_UNLIT_LAYERS 1\n"}) {
        out.push_back({m + "polygons " + aa + unlit,
                       {{"fullscreen.vert.glsl"},
                        {},
                        {"decal_blobs.glsl", "static_common.glsl", "static_polygons.glsl"},
                        {},
                        mode + aa + unlit + "#define DECAL_POLYGONS 1\n"}});
        for (const std::string slope : {"", "#define DECAL_SLOPE_WIDTHS 1\n"})
          out.push_back({m + "lines " + aa + slope + unlit,
                         {{"fullscreen.vert.glsl"},
                          {},
                          lines_fs,
                          {},
                          mode + aa + slope + unlit + "#define DECAL_LINES 1\n"}});
      }
    }
    const std::string dd = mode + "#define DECAL_DYNAMIC 1\n";
    for (const char* f : {"lod_mask.comp.glsl", "lod_select.comp.glsl", "lod_segments.comp.glsl"})
      out.push_back({m + f, {{}, {}, {}, {"decal_blobs.glsl", "lod_common.glsl", f}, dd}});
    for (const auto& [f, extra] : std::vector<std::pair<std::string, std::string>>{
             {"dyn_cull.comp.glsl", ""},
             {"dyn_scan.comp.glsl", "#define SCAN_LOCAL 1\n"},
             {"dyn_scan.comp.glsl", "#define SCAN_BLOCKS 1\n"},
             {"dyn_scan.comp.glsl", "#define SCATTER 1\n"},
             {"dyn_segments.comp.glsl", ""},
             {"dyn_dash.comp.glsl", "#define DASH_LOCAL 1\n"},
             {"dyn_dash.comp.glsl", "#define DASH_BLOCKS 1\n"},
             {"dyn_dash.comp.glsl", "#define DASH_APPLY 1\n"}})
      out.push_back({m + f + " " + extra,
                     {{}, {}, {}, {"decal_blobs.glsl", "dyn_common.glsl", f}, dd + extra}});
    for (const std::string widths : {"", "#define DECAL_DYN_MIN_WIDTHS 1\n"})
      out.push_back(
          {m + "dyn lists " + widths,
           {{"dyn_box.vert.glsl"},
            {"decal_blobs.glsl", "dyn_common.glsl", "dyn_scale.glsl", "dyn_box.geom.glsl"},
            {"decal_blobs.glsl", "dyn_common.glsl", "dyn_scale.glsl", "dash.glsl",
             "dyn_lists.frag.glsl"},
            {},
            dd + widths}});
    out.push_back({m + "dyn composite",
                   {{"fullscreen.vert.glsl"},
                    {},
                    {"decal_blobs.glsl", "dyn_common.glsl", "dyn_composite.frag.glsl"},
                    {},
                    dd}});
  }
  out.push_back({"terrain", {{"terrain.vert.glsl"}, {}, {"terrain.frag.glsl"}, {}, ""}});
  out.push_back(
      {"terrain slope",
       {{"terrain.vert.glsl"}, {}, {"terrain.frag.glsl"}, {}, "#define DECAL_SLOPE_WIDTHS 1\n"}});
  out.push_back(
      {"terrain texture method",
       {{"terrain.vert.glsl"}, {}, {"terrain.frag.glsl"}, {}, "#define DECAL_TEXTURE_METHOD 1\n"}});
  out.push_back({"composite", {{"fullscreen.vert.glsl"}, {}, {"composite.frag.glsl"}, {}, ""}});
  out.push_back({"composite unlit",
                 {{"fullscreen.vert.glsl"},
                  {},
                  {"composite.frag.glsl"},
                  {},
                  "#define DECAL_UNLIT_LAYERS 1\n"}});
  out.push_back(
      {"method prism", {{"method_prism.vert.glsl"}, {}, {"method_colour.frag.glsl"}, {}, ""}});
  out.push_back({"method cover unlit",
                 {{"fullscreen.vert.glsl"},
                  {},
                  {"method_colour.frag.glsl"},
                  {},
                  "#define DECAL_UNLIT_LAYERS 1\n"}});
  return out;
}

// The table's index of a storage block (ssbo) or sampler uniform (unit).
std::optional<uint32_t> table_index(const std::string& name, G::FrameKind kind) {
  const std::string blob_prefix = kind == G::FrameKind::ssbo ? "B_" : "t_";
  if (name.rfind(blob_prefix, 0) == 0)
    for (const G::BlobBinding& b : G::kBlobBindings)
      if (decal::find_blob_info(b.blob)->name == name.substr(2)) return b.index;
  for (const G::FrameBinding& f : G::kFrameBindings)
    if (f.kind == kind && f.resource == name) return f.index;
  return std::nullopt;
}

bool is_sampler(GLint type) {
  switch (type) {
    case GL_SAMPLER_2D:
    case GL_SAMPLER_2D_MULTISAMPLE:
    case GL_SAMPLER_BUFFER:
    case GL_INT_SAMPLER_BUFFER:
    case GL_UNSIGNED_INT_SAMPLER_BUFFER:
    case GL_UNSIGNED_INT_SAMPLER_2D: return true;
    default: return false;
  }
}

// "program: what" for every block or sampler not where the table says.
std::vector<std::string> mismatches(GLuint prog, const std::string& label) {
  std::vector<std::string> out;
  // `noun` NAME (a storage block, a sampler) was found `at` index `got`.
  auto check = [&](const char* noun, const std::string& name, G::FrameKind kind, const char* at,
                   GLint got) {
    const auto want = table_index(name, kind);
    const std::string what = label + ": " + noun + " " + name;
    if (!want)
      out.push_back(what + " is not in the table");
    else if (GLint(*want) != got)
      out.push_back(what + " " + at + " " + std::to_string(got) + ", the table says " +
                    std::to_string(*want));
  };
  char name[256];
  GLint n = 0;
  glGetProgramInterfaceiv(prog, GL_SHADER_STORAGE_BLOCK, GL_ACTIVE_RESOURCES, &n);
  for (GLint i = 0; i < n; ++i) {
    glGetProgramResourceName(prog, GL_SHADER_STORAGE_BLOCK, GLuint(i), sizeof name, nullptr, name);
    const GLenum prop = GL_BUFFER_BINDING;
    GLint binding = -1;
    glGetProgramResourceiv(prog, GL_SHADER_STORAGE_BLOCK, GLuint(i), 1, &prop, 1, nullptr,
                           &binding);
    check("storage block", name, G::FrameKind::ssbo, "at binding", binding);
  }
  glGetProgramInterfaceiv(prog, GL_UNIFORM, GL_ACTIVE_RESOURCES, &n);
  for (GLint i = 0; i < n; ++i) {
    glGetProgramResourceName(prog, GL_UNIFORM, GLuint(i), sizeof name, nullptr, name);
    const GLenum props[2] = {GL_TYPE, GL_LOCATION};
    GLint v[2] = {};
    glGetProgramResourceiv(prog, GL_UNIFORM, GLuint(i), 2, props, 2, nullptr, v);
    if (!is_sampler(v[0])) continue;
    GLint unit = -1;
    glGetUniformiv(prog, v[1], &unit);
    check("sampler", name, G::FrameKind::unit, "on unit", unit);
  }
  return out;
}

TEST(GlBindings, EveryShaderBindsWhereTheTableSays) {
  std::unique_ptr<G::Context> ctx;
  if (decal::Status s = G::Context::create(ctx); !s) GTEST_SKIP() << s.message;
  size_t checked = 0;
  for (const Program& p : renderer_programs()) {
    uint32_t prog = 0;
    const decal::Status s = G::build_program(p.sources, prog);
    ASSERT_TRUE(s.ok) << p.label << ": " << s.message;
    for (const std::string& m : mismatches(prog, p.label)) ADD_FAILURE() << m;
    glDeleteProgram(prog);
    ++checked;
  }
  EXPECT_GT(checked, 40u);
}

TEST(GlBindings, NoShaderSpellsABindingAsANumber) {
  const std::regex bare(R"(binding\s*=\s*[0-9])");
  std::set<std::string> files;
  for (const Program& p : renderer_programs())
    for (const auto* stage :
         {&p.sources.vertex, &p.sources.geometry, &p.sources.fragment, &p.sources.compute})
      files.insert(stage->begin(), stage->end());
  for (const std::string& f : files) {
    const std::string text(G::shader_source(f));
    ASSERT_FALSE(text.empty()) << f;
    EXPECT_FALSE(std::regex_search(text, bare)) << f << " binds at a bare number";
  }
}

TEST(GlBindings, BlobBindingsAreDistinctAndBelowTheFrameBindings) {
  std::set<uint32_t> seen;
  for (const G::BlobBinding& b : G::kBlobBindings) {
    EXPECT_TRUE(seen.insert(b.index).second) << "binding " << b.index << " twice";
    EXPECT_LT(b.index, G::kBindingFrameFirst);
    EXPECT_NE(decal::find_blob_info(b.blob), nullptr);
  }
  for (const G::FrameBinding& f : G::kFrameBindings)
    EXPECT_GE(f.index, G::kBindingFrameFirst) << f.macro;
}

}  // namespace

}  // namespace formats_gl_bindings
