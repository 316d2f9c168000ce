// cmd_verify.cpp — `decalprep verify PACKAGE...`: every checksum and every
// structural check a package can be given (formats/SPEC.md §"Validation").
// Prints one line per package; exits 0 when all are good, 5 (verify_failed)
// otherwise.
#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "command.hpp"
#include "decal/inspect.hpp"
#include "decal/reader.hpp"
#include "prep/tileset.hpp"

namespace {

// The metadata must be a JSON object; where it states a format or blob
// counts (SPEC.md §"Metadata"), they must agree with the package.
decal::Status check_metadata(const decal::Package& p) {
  nlohmann::json meta;
  try {
    meta = nlohmann::json::parse(p.metadata_json());
  } catch (const nlohmann::json::exception& e) {
    return decal::Status::failure(std::string("metadata is not valid JSON: ") + e.what());
  }
  if (!meta.is_object()) return decal::Status::failure("metadata is not a JSON object");
  if (auto f = meta.find("format"); f != meta.end() && *f != "decals")
    return decal::Status::failure("metadata format is " + f->dump() + ", expected \"decals\"");
  if (auto counts = meta.find("counts"); counts != meta.end() && counts->is_object())
    for (const decal::BlobView& b : p.blobs()) {
      auto c = counts->find(b.name);
      if (c == counts->end()) continue;
      if (!c->is_number_unsigned() || c->get<uint64_t>() != b.count)
        return decal::Status::failure("metadata counts." + b.name + " = " + c->dump() +
                                      " but the blob has " + std::to_string(b.count) + " elements");
    }
  return decal::Status::success();
}

decal::Status verify_one(const std::string& path, std::string& summary) {
  decal::Package p;
  decal::OpenOptions opt;
  opt.verify_checksums = true;
  if (decal::Status s = decal::Package::open(path, p, opt); !s) return s;
  if (decal::Status s = decal::validate_indices(p); !s)
    return decal::Status::failure(path + ": " + s.message);
  if (decal::Status s = check_metadata(p); !s)
    return decal::Status::failure(path + ": " + s.message);
  uint64_t raw = 0;
  for (const auto& b : p.blobs()) raw += b.bytes.size();
  summary = "v" + std::to_string(p.major()) + "." + std::to_string(p.minor()) + ", " +
            std::to_string(p.blobs().size()) + " blobs, " + std::to_string(raw) + " raw bytes";
  return decal::Status::success();
}

// A tileset: the index, manifest.json's and every tile's bytes and XXH64
// against the index, then every tile as a package. Returns false when any
// fails (each failure printed).
bool verify_tileset(const std::string& dir) {
  prep::TilesetIndex ix;
  try {
    ix = prep::read_tileset_index(dir);
  } catch (const prep::error& e) {
    std::fprintf(stderr, "%s: FAILED: %s\n", dir.c_str(), e.what());
    return false;
  }
  bool good = true;
  auto check_file = [&](const std::string& rel, uint64_t bytes, uint64_t hash) {
    const std::string path = dir + "/" + rel;
    const std::optional<prep::FileDigest> d = prep::file_digest(path);
    std::string why;
    if (!d)
      why = "missing";
    else if (d->bytes != bytes)
      why = std::to_string(d->bytes) + " bytes, tileset.json says " + std::to_string(bytes);
    else if (d->xxh64 != hash)
      why = "xxh64 " + prep::hex64(d->xxh64) + ", tileset.json says " + prep::hex64(hash);
    if (why.empty()) return true;
    std::fprintf(stderr, "%s: FAILED: %s\n", path.c_str(), why.c_str());
    good = false;
    return false;
  };
  check_file(prep::kTilesetManifestName, ix.manifest_bytes, ix.manifest_xxh64);
  auto check_tiles = [&](const std::vector<prep::TileEntry>& tiles) {
    for (const prep::TileEntry& t : tiles) {
      if (!check_file(t.file, t.bytes, t.xxh64)) continue;
      std::string summary;
      const std::string path = dir + "/" + t.file;
      if (const decal::Status s = verify_one(path, summary); !s) {
        std::fprintf(stderr, "%s: FAILED: %s\n", path.c_str(), s.message.c_str());
        good = false;
      }
    }
  };
  check_tiles(ix.tiles);
  // Overview levels: every level's tiles the same way.
  size_t level_tiles = 0;
  for (const prep::TileLevel& l : ix.levels) {
    check_tiles(l.tiles);
    level_tiles += l.tiles.size();
  }
  if (good && ix.levels.empty())
    std::printf("%s: ok (tileset %d.%d, %zu tiles, index and manifest hashes match)\n", dir.c_str(),
                ix.major, ix.minor, ix.tiles.size());
  else if (good)
    std::printf(
        "%s: ok (tileset %d.%d, %zu tiles and %zu on %zu overview levels, index and "
        "manifest hashes match)\n",
        dir.c_str(), ix.major, ix.minor, ix.tiles.size(), level_tiles, ix.levels.size());
  return good;
}

const decalprep::CommandRegistrar kVerify(21, [](CLI::App& app) {
  auto* cmd = app.add_subcommand("verify", "Check packages: checksums, structure and indices");
  cmd->footer(
      "Prints '<path>: ok (...)' or '<path>: FAILED: <reason>' per package.\n"
      "Exit code 0 when every package is good, 5 when any is not.\n"
      "A tileset directory: tileset.json, the bytes and XXH64 of manifest.json and of every tile\n"
      "against it, then every tile as a package; the same for every overview level's tiles.\n"
      "Example:\n  decalprep verify city.decals roads.decals");
  auto paths = std::make_shared<std::vector<std::string>>();
  cmd->add_option("PACKAGE", *paths, "the .decals files, or tileset directories")->required();
  cmd->callback([paths] {
    bool all_good = true;
    for (const std::string& path : *paths) {
      if (prep::is_tileset(path)) {
        all_good = verify_tileset(path) && all_good;
        continue;
      }
      std::string summary;
      const decal::Status s = verify_one(path, summary);
      if (s) {
        std::printf("%s: ok (%s)\n", path.c_str(), summary.c_str());
      } else {
        all_good = false;
        // Reader messages usually start with the path already.
        const std::string& m = s.message;
        const bool has_path = m.compare(0, path.size() + 2, path + ": ") == 0;
        std::fprintf(stderr, "%s: FAILED: %s\n", path.c_str(),
                     has_path ? m.c_str() + path.size() + 2 : m.c_str());
      }
    }
    std::fflush(stdout);
    decalprep::set_exit_code(all_good ? prep::ExitCode::ok : prep::ExitCode::verify_failed);
  });
});

}  // namespace
