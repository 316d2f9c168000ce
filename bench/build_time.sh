#!/usr/bin/env bash
# Clean release build time of two commits, side by side: RUNS alternating
# pairs (base, new, base, new, ...), each a fresh build folder configured as
# the `release` preset configures (Ninja, Release, warnings as errors) and
# built whole with -j2, no compiler cache. Alternating spreads what else the
# machine does over both sides. Prints each run and the medians, and writes
# bench/report/build_time.csv (side, run, seconds).
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
echo "side,run,seconds" > "$csv"
for run in $(seq 1 "$runs"); do
  for side in base new; do
    dir="$work/build-$side"
    rm -rf "$dir"
    cmake -S "$work/src-$side" -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=Release \
      -DDECALPREP_WERROR=ON >/dev/null
    t0=$(date +%s.%N)
    cmake --build "$dir" -j2 >"$work/$side-$run.log" 2>&1 ||
      { echo "build of $side failed; see $work/$side-$run.log" >&2; tail -20 "$work/$side-$run.log" >&2; exit 1; }
    t1=$(date +%s.%N)
    s=$(echo "$t1 - $t0" | bc)
    printf '%s run %d: %.1f s\n' "$side" "$run" "$s"
    echo "$side,$run,$s" >> "$csv"
  done
done
python3 - "$csv" <<'PY'
import csv, statistics, sys
rows = list(csv.DictReader(open(sys.argv[1])))
med = {s: statistics.median(float(r["seconds"]) for r in rows if r["side"] == s) for s in ("base", "new")}
print(f"median base {med['base']:.1f} s, new {med['new']:.1f} s, new/base {med['new'] / med['base']:.3f}")
PY
