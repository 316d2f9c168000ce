// prep/scene_file.hpp — the TOML scene file: what to read and how to draw it.
// Every key is described in samples/README.md. Parsed with toml++; lives in
// the read stage because it is the "what to read" specification.
#pragma once

#include <string>

#include "prep/scene.hpp"

namespace prep {

// Parses scene-file text. `path` is used for messages and to resolve relative
// source and DEM paths (against the file's directory, also inside /vsizip/
// and friends). Unknown keys, wrong types and bad values throw scene_error
// whose message names the file, the key and its line:
//   scene.toml:12: layer[2].kind: expected polygon|line|outline, got "poly"
// Thread-safe (no shared state).
SceneSpec parse_scene(const std::string& text, const std::string& path);

// Reads and parses a scene file. Throws scene_error if it cannot be read.
SceneSpec load_scene_file(const std::string& path);

// Resolves a GDAL path written in a scene file against `base_dir`: a plain
// relative path becomes base_dir/path, and a /vsizip/, /vsigzip/, /vsitar/ or
// /vsi7z/ path with a relative archive path gets base_dir inserted after the
// prefix. Absolute paths, URLs and other /vsi prefixes are returned as given.
std::string resolve_scene_path(const std::string& path, const std::string& base_dir);

// Parses a colour: "#rrggbb", "#rrggbbaa" or a CSS-like name list is not
// supported. Returns RGBA with R in the low byte. Throws usage_error.
uint32_t parse_color(const std::string& text);

// Parses "round|miter|bevel", "normal|inset|offset", "polygon|line|outline".
// Throw usage_error naming the accepted values.
decal::CornerStyle parse_corner(const std::string& text);
decal::OutlineMode parse_outline_mode(const std::string& text);
// Parses "linework|structure" (SceneSpec::repair).
RepairMethod parse_repair_method(const std::string& text);
DecalKind parse_kind(const std::string& text);

}  // namespace prep
