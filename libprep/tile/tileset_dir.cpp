// The tileset folder's rules (tileset_dir.hpp).
#include "tileset_dir.hpp"

#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <dirent.h>
#include <fcntl.h>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <vector>

#include "prep/error.hpp"
#include "prep/files.hpp"
#include "prep/stage_error.hpp"
#include "prep/tile.hpp"

namespace prep::tiling {

namespace {

std::vector<std::string> entries_of(const std::string& dir) {
  std::vector<std::string> out;
  DIR* d = ::opendir(dir.c_str());
  if (!d) return out;
  while (const dirent* e = ::readdir(d)) {
    const std::string name = e->d_name;
    if (name != "." && name != "..") out.push_back(name);
  }
  ::closedir(d);
  return out;
}

bool is_regular(const std::string& path) {
  struct stat st {};
  return ::lstat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

bool is_real_dir(const std::string& path) {
  struct stat st {};
  return ::lstat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode);
}

// A tile file's path relative to the tileset folder, as the index and the
// records write it: tiles/x<int>_y<int>.decals or tiles/L<n>/x<int>_y<int>.decals.
bool is_tile_path(const std::string& rel) {
  static const std::regex kTile(R"(tiles/(L[1-9][0-9]{0,2}/)?x-?[0-9]+_y-?[0-9]+\.decals)");
  return std::regex_match(rel, kTile);
}

// Adds the "file" of every tile record in the work folder, and its owned
// list, to `out`. Unreadable records add nothing.
void add_work_owned(const WorkPaths& paths, std::set<std::string>& out) {
  auto add = [&](const std::string& rel) {
    if (is_tile_path(rel)) out.insert(rel);
  };
  for (const std::string& name : entries_of(paths.tile_records())) {
    std::ifstream in(paths.tile_records() + "/" + name, std::ios::binary);
    try {
      const nlohmann::json r = nlohmann::json::parse(in);
      if (r.is_object() && r.contains("file") && r["file"].is_string()) add(r["file"]);
    } catch (const nlohmann::json::exception&) {
    }
  }
  std::ifstream in(paths.work() + "/" + kWorkOwnedName, std::ios::binary);
  if (!in) return;
  try {
    const nlohmann::json j = nlohmann::json::parse(in);
    if (j.is_array())
      for (const nlohmann::json& f : j)
        if (f.is_string()) add(f);
  } catch (const nlohmann::json::exception&) {
  }
}

// True for the plan `decalprep build --plan` writes (DIR/plan.json): a
// JSON object with its "steps".
bool is_build_plan(const std::string& path) {
  if (!is_regular(path)) return false;
  std::ifstream in(path, std::ios::binary);
  try {
    const nlohmann::json j = nlohmann::json::parse(in);
    return j.is_object() && j.contains("steps") && j["steps"].is_array();
  } catch (const nlohmann::json::exception&) {
    return false;
  }
}

}  // namespace

TilesetDir::TilesetDir(const std::string& dir, Access access, bool create) : dir_(dir) {
  struct stat st {};
  if (::stat(dir.c_str(), &st) != 0) {
    if (!create)
      fail<output_error>(kTilesetStage, dir + " does not exist (run the prepare step first)");
    if (::mkdir(dir.c_str(), 0777) == 0)
      made_ = true;
    else if (errno != EEXIST)
      fail<output_error>(kTilesetStage, "cannot create " + dir + ": " + std::strerror(errno));
  } else if (!S_ISDIR(st.st_mode)) {
    fail<output_error>(kTilesetStage, dir +
                                          " exists and is not a directory; a tileset is a folder "
                                          "(nothing was written)");
  }
  fd_ = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd_ < 0)
    fail<output_error>(kTilesetStage, "cannot open " + dir + ": " + std::strerror(errno));
  if (::flock(fd_, (access == Access::exclusive ? LOCK_EX : LOCK_SH) | LOCK_NB) != 0 &&
      errno == EWOULDBLOCK) {
    ::close(fd_);
    fd_ = -1;
    fail<output_error>(kTilesetStage,
                       "another decalprep build is writing " + dir +
                           " (it holds the folder's lock); wait for it to end or stop it, "
                           "or build into another folder");
  }
  if (made_) return;

  // What the folder may hold: nothing, a tileset, decalprep's work folder
  // or the plan of a cluster build.
  const std::string work = dir + "/.work";
  const bool has_index = is_regular(dir + "/" + kTilesetIndexName);
  struct stat wst {};
  const bool has_work = ::lstat(work.c_str(), &wst) == 0;
  if (has_work && (!S_ISDIR(wst.st_mode) || !is_regular(work + "/" + kWorkOwnerName)))
    fail<output_error>(kTilesetStage,
                       work + " exists and is not a decalprep work folder (it has no " +
                           kWorkOwnerName +
                           "); move it away: decalprep removes only what it made (nothing was "
                           "written)");
  if (!has_index && !has_work && !is_build_plan(dir + "/plan.json")) {
    const std::vector<std::string> found = entries_of(dir);
    if (!found.empty()) {
      std::string list;
      for (size_t i = 0; i < found.size() && i < 5; ++i) list += (i ? ", " : "") + found[i];
      if (found.size() > 5) list += ", ...";
      fail<output_error>(kTilesetStage,
                         dir + " is not empty (" + list + ") and holds no tileset (no " +
                             kTilesetIndexName +
                             "); a tileset build writes only into an empty folder, a new one "
                             "or a tileset it built (nothing was written)");
    }
  }
  const std::string tiles = dir + "/tiles";
  struct stat tst {};
  if (::lstat(tiles.c_str(), &tst) == 0 && !S_ISDIR(tst.st_mode))
    fail<output_error>(kTilesetStage, tiles +
                                          " is not a folder (a link or a file); decalprep "
                                          "never writes through a link (nothing was written)");
}

TilesetDir::~TilesetDir() {
  if (fd_ >= 0) ::close(fd_);  // closing releases the lock
}

void make_inner_dir(const std::string& path) {
  if (::mkdir(path.c_str(), 0777) == 0) return;
  if (errno != EEXIST)
    fail<output_error>(kTilesetStage, "cannot create " + path + ": " + std::strerror(errno));
  if (!is_real_dir(path))
    fail<output_error>(kTilesetStage, path +
                                          " exists and is not a folder (a link or a file); "
                                          "decalprep never writes through a link");
}

void renew_work_folder(const WorkPaths& paths) {
  std::set<std::string> carried;
  if (is_real_dir(paths.work())) {
    add_work_owned(paths, carried);
    std::error_code ec;
    std::filesystem::remove_all(paths.work(), ec);
    if (ec)
      fail<output_error>(kTilesetStage,
                         "cannot remove the old work folder " + paths.work() + ": " + ec.message());
  }
  make_inner_dir(paths.work());
  write_text_file(
      paths.work() + "/" + kWorkOwnedName,
      nlohmann::json(std::vector<std::string>(carried.begin(), carried.end())).dump() + "\n");
  // The same bytes every run: a step run again leaves the folder as it was.
  write_text_file(paths.work() + "/" + kWorkOwnerName,
                  nlohmann::json{{"made_by", "decalprep"},
                                 {"what",
                                  "work folder of a tileset build (formats/SPEC.md "
                                  "\"Tilesets\"); removed when the build finishes"}}
                          .dump() +
                      "\n");
  make_inner_dir(paths.tile_records());
}

std::set<std::string> owned_files(const WorkPaths& paths) {
  std::set<std::string> out;
  add_work_owned(paths, out);
  if (is_tileset(paths.dir)) {
    try {
      const TilesetIndex old = read_tileset_index(paths.dir);
      for (const TileEntry& t : old.tiles)
        if (is_tile_path(t.file)) out.insert(t.file);
      for (const TileLevel& l : old.levels)
        for (const TileEntry& t : l.tiles)
          if (is_tile_path(t.file)) out.insert(t.file);
    } catch (const std::exception&) {
      // An index that does not parse owns nothing: its tiles stay.
    }
  }
  return out;
}

void remove_stale(const std::string& dir, const std::set<std::string>& owned,
                  const std::set<std::string>& keep, int levels) {
  for (const std::string& rel : owned)
    if (!keep.count(rel) && is_regular(dir + "/" + rel)) ::unlink((dir + "/" + rel).c_str());
  static const std::regex kTemp(R"(\.x-?[0-9]+_y-?[0-9]+\.decals\.tmp-[0-9]+-[0-9]+)");
  static const std::regex kLevel(R"(L([1-9][0-9]{0,2}))");
  const std::string tiles = dir + "/tiles";
  std::vector<std::string> folders = {tiles};
  std::vector<std::string> stale_levels;
  for (const std::string& name : entries_of(tiles)) {
    std::smatch m;
    if (!std::regex_match(name, m, kLevel) || !is_real_dir(tiles + "/" + name)) continue;
    folders.push_back(tiles + "/" + name);
    if (std::stoi(m[1]) > levels) stale_levels.push_back(tiles + "/" + name);
  }
  for (const std::string& f : folders)
    for (const std::string& name : entries_of(f))
      if (std::regex_match(name, kTemp) && is_regular(f + "/" + name))
        ::unlink((f + "/" + name).c_str());
  for (const std::string& l : stale_levels) ::rmdir(l.c_str());  // only when empty
}

std::string remove_after_interrupt(const std::string& dir, bool made_dir) {
  const std::string gone = made_dir ? dir : dir + "/.work";
  const std::string away = gone + ".stopped-" + std::to_string(::getpid());
  std::error_code ec;
  if (std::rename(gone.c_str(), away.c_str()) == 0) {
    std::filesystem::remove_all(away, ec);
  } else {
    std::filesystem::remove_all(gone, ec);
  }
  return "removed " + gone + (made_dir ? " (the build had made it)" : " (the work folder)");
}

}  // namespace prep::tiling
