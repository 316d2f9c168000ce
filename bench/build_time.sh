#!/usr/bin/env bash
# Clean release build time of two commits, side by side: RUNS alternating
# pairs (base, new, base, new, ...), each a fresh build folder configured as
# the `release` preset configures (Ninja, Release, warnings as errors) and
# built whole with -j2, no compiler cache. Alternating spreads what else the
# machine does over both sides; the CPU time (user + system of the build and
# every compiler it runs) is the figure that other load on the machine
# barely moves, the wall time the one a user waits. Prints each run and the
# medians, and writes bench/report/build_time.csv (side, run, wall_s, cpu_s).
# Usage: bench/build_time.sh BASE_REV [NEW_REV (default HEAD)] [RUNS (default 3)]
set -euo pipefail
cd "$(dirname "$0")/.."
base_rev=${1:?usage: bench/build_time.sh BASE_REV [NEW_REV] [RUNS]}
new_rev=${2:-HEAD}
runs=${3:-3}
work=$(mktemp -d /tmp/decalprep-build-time.XXXXXX)
trap 'git worktree remove --force "$work/src-base" 2>/dev/null || true;
      git worktree remove --force "$work/src-new" 2>/dev/null || true; rm -rf "$work"' EXIT
git worktree add --detach "$work/src-base" "$base_rev" >/dev/null
git worktree add --detach "$work/src-new" "$new_rev" >/dev/null
# The viewer embeds its npm modules when they are there (a side without
# web/ has no viewer); the new side gets this checkout's.
[ -d web/node_modules ] && [ -d "$work/src-new/web" ] && cp -r web/node_modules "$work/src-new/web/"
csv=bench/report/build_time.csv
echo "side,run,wall_s,cpu_s" > "$csv"
for run in $(seq 1 "$runs"); do
  for side in base new; do
    dir="$work/build-$side"
    rm -rf "$dir"
    cmake -S "$work/src-$side" -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=Release \
      -DDECALPREP_WERROR=ON >/dev/null
    /usr/bin/time -f '%e %U %S' -o "$work/time" cmake --build "$dir" -j2 >"$work/$side-$run.log" 2>&1 ||
      { echo "build of $side failed; see $work/$side-$run.log" >&2; tail -20 "$work/$side-$run.log" >&2; exit 1; }
    read -r wall user sys < <(tail -1 "$work/time")
    cpu=$(echo "$user + $sys" | bc)
    printf '%s run %d: wall %.1f s, cpu %.1f s\n' "$side" "$run" "$wall" "$cpu"
    echo "$side,$run,$wall,$cpu" >> "$csv"
  done
done
python3 - "$csv" <<'PY'
import csv, statistics, sys
rows = list(csv.DictReader(open(sys.argv[1])))
for col in ("wall_s", "cpu_s"):
    med = {s: statistics.median(float(r[col]) for r in rows if r["side"] == s) for s in ("base", "new")}
    print(f"{col}: median base {med['base']:.1f}, new {med['new']:.1f}, new/base {med['new'] / med['base']:.3f}")
PY
