// Shader programs from the embedded GLSL files.
#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>

#include <span>
#include <string>
#include <utility>

#include "decal/gl/gl.hpp"

namespace decal::gl {

namespace detail {
std::span<const std::pair<std::string_view, std::string_view>> embedded_shaders();
}

std::string_view shader_source(std::string_view name) {
  for (const auto& [n, text] : detail::embedded_shaders())
    if (n == name) return text;
  return {};
}

std::string glsl_bindings() {
  static constexpr std::pair<BlobGroup, const char*> kGroups[] = {{BlobGroup::quadtree, "QUADTREE"},
                                                                  {BlobGroup::polygons, "POLYGONS"},
                                                                  {BlobGroup::lines, "LINES"},
                                                                  {BlobGroup::dynamic, "DYNAMIC"}};
  std::string out;
  for (const auto& [group, macro] : kGroups) {
    out += "#define DECAL_BLOBS_" + std::string(macro);
    for (const BlobBinding& b : kBlobBindings) {
      if (b.group != group) continue;
      out += " DECAL_BLOB(" + std::to_string(b.index) + ", " + std::string(b.sampler) + ", " +
             std::string(find_blob_info(b.blob)->name) + ", " + std::string(b.element) + ")";
    }
    out += "\n";
  }
  for (const FrameBinding& f : kFrameBindings)
    out += "#define " + std::string(f.macro) + " " + std::to_string(f.index) + "\n";
  return out;
}

namespace {

// The info log of a shader or program (glGetShaderiv/glGetShaderInfoLog or
// the program pair).
template <class GetIv, class GetLog>
std::string info_log(GLuint object, GetIv get_iv, GetLog get_log) {
  GLint len = 0;
  get_iv(object, GL_INFO_LOG_LENGTH, &len);
  std::string log(static_cast<size_t>(len > 0 ? len : 1), '\0');
  get_log(object, len, nullptr, log.data());
  return log;
}

Status compile(GLenum stage, const std::vector<std::string>& files, const std::string& defines,
               GLuint& out) {
  std::string src = "#version 450 core\n" + defines + "\n" + glsl_bindings();
  for (const auto& f : files) {
    std::string_view text = shader_source(f);
    if (text.empty()) return Status::failure("gl loader: no embedded shader named '" + f + "'");
    src += "#line 1\n";
    src.append(text);
    src += "\n";
  }
  GLuint sh = glCreateShader(stage);
  const char* p = src.c_str();
  glShaderSource(sh, 1, &p, nullptr);
  glCompileShader(sh);
  GLint ok = 0;
  glGetShaderiv(sh, GL_COMPILE_STATUS, &ok);
  if (!ok) {
    const std::string log = info_log(sh, glGetShaderiv, glGetShaderInfoLog);
    glDeleteShader(sh);
    std::string names;
    for (const auto& f : files) names += (names.empty() ? "" : "+") + f;
    return Status::failure("gl loader: shader " + names + " failed to compile: " + log);
  }
  out = sh;
  return Status::success();
}

}  // namespace

Status build_program(const ProgramSources& sources, uint32_t& out) {
  GLuint prog = glCreateProgram();
  std::vector<GLuint> shaders;
  auto add = [&](GLenum stage, const std::vector<std::string>& files) -> Status {
    if (files.empty()) return Status::success();
    GLuint sh = 0;
    Status s = compile(stage, files, sources.defines, sh);
    if (!s) return s;
    glAttachShader(prog, sh);
    shaders.push_back(sh);
    return s;
  };
  Status s = add(GL_VERTEX_SHADER, sources.vertex);
  if (s) s = add(GL_GEOMETRY_SHADER, sources.geometry);
  if (s) s = add(GL_FRAGMENT_SHADER, sources.fragment);
  if (s) s = add(GL_COMPUTE_SHADER, sources.compute);
  if (s) {
    glLinkProgram(prog);
    GLint ok = 0;
    glGetProgramiv(prog, GL_LINK_STATUS, &ok);
    if (!ok) {
      s = Status::failure("gl loader: program failed to link: " +
                          info_log(prog, glGetProgramiv, glGetProgramInfoLog));
    }
  }
  for (GLuint sh : shaders) glDeleteShader(sh);
  if (!s) {
    glDeleteProgram(prog);
    return s;
  }
  out = prog;
  return s;
}

}  // namespace decal::gl
