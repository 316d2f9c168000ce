// The tileset folder a build writes (not a public header): what a build may
// find there, which files it may remove, and who holds it.
//
// A tileset build writes only into a folder that is absent (it makes it),
// empty, or holds a tileset (tileset.json), a decalprep work folder
// (.work/owner.json) or the plan `build --plan` wrote (plan.json). It removes only files that the
// index on disk or its own work folder recorded, never follows a symlink out of the folder, and
// holds a lock on the folder while it runs (docs/tilesets.md "Safe in a folder that is not empty").
#pragma once

#include <set>
#include <string>

#include "tileset_internal.hpp"

namespace prep::tiling {

// The work folder's mark of ownership: a .work without it is not
// decalprep's and is never removed.
constexpr const char* kWorkOwnerName = "owner.json";
// The tile files earlier work folders recorded (carried from one work
// folder to the next, so that a tile a killed run wrote can still go).
constexpr const char* kWorkOwnedName = "owned.json";

// A folder inside the tileset (tiles, tiles/L<n>, .work and its folders):
// made, or already a real folder; a symlink or anything else there is an
// output_error (a build never writes or removes through a link).
void make_inner_dir(const std::string& path);

// Makes the work folder afresh with its owner mark. The tile files the
// previous work folder recorded (its tile records and its owned list) are
// carried into the new one's owned list before the old one is removed.
void renew_work_folder(const WorkPaths& paths);

// The files below the tileset folder that a build may replace or remove,
// as paths relative to it ("tiles/x0_y0.decals", "tiles/L1/x0_y0.decals"):
// the tiles of the index on disk (when it parses) and of the work folder's
// tile records and owned list.
std::set<std::string> owned_files(const WorkPaths& paths);

// Removes the files of `owned` not in `keep` (regular files only), the
// named temp files of tile writes killed without O_TMPFILE (exactly
// ".x<int>_y<int>.decals.tmp-<pid>-<n>"), and level folders beyond `levels`
// once they are empty.
void remove_stale(const std::string& dir, const std::set<std::string>& owned,
                  const std::set<std::string>& keep, int levels);

}  // namespace prep::tiling
