#!/usr/bin/env bash
# Golden end-to-end test: builds tests/tools/golden/scene.toml with the tool and
# compares `decalprep dump --summary` with the checked-in golden.summary.txt
# (made by regenerate.sh). Prints the first differing lines on failure.
# The summary holds every blob's xxh64, so a change of any element or any
# manifest entry changes a line; it also checks those hashes against the
# checksums the writer stores for an uncompressed build of the same scene.
set -euo pipefail
tool="$1"
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../../.." && pwd)"
tmp="$(mktemp -d)"; trap 'rm -rf "$tmp"' EXIT
"$tool" build "$here/scene.toml" -o "$tmp/golden.decals" -q --threads 1
"$tool" dump "$tmp/golden.decals" --summary | sed -e "s#$root#<ROOT>#g" > "$tmp/actual.txt"
if ! cmp -s "$here/golden.summary.txt" "$tmp/actual.txt"; then
  echo "golden: dump --summary differs from golden.summary.txt (regenerate with regenerate.sh if the change is intended):"
  diff -u "$here/golden.summary.txt" "$tmp/actual.txt" | head -n 40 | cut -c 1-300
  exit 1
fi

# The same scene stored uncompressed: the summary depends only on the package
# contents, and each blob's xxh64 in it is the checksum `info` lists (for an
# uncompressed blob, the writer's XXH64 of its stored = decoded bytes).
"$tool" build "$here/scene.toml" -o "$tmp/raw.decals" -q --threads 1 --no-compress
"$tool" dump "$tmp/raw.decals" --summary | sed -e "s#$root#<ROOT>#g" > "$tmp/raw.txt"
if ! cmp -s "$tmp/actual.txt" "$tmp/raw.txt"; then
  echo "golden: dump --summary of the uncompressed build differs from the compressed one:"
  diff -u "$tmp/actual.txt" "$tmp/raw.txt" | head -n 40 | cut -c 1-300
  exit 1
fi
"$tool" info "$tmp/raw.decals" --json > "$tmp/info.json"
python3 - "$tmp/info.json" "$tmp/raw.txt" <<'PY'
import json, re, sys
info = json.load(open(sys.argv[1]))
listed = {b["name"]: b["xxh64"] for b in info["blobs"]}
summary = dict(re.findall(r"^blob (\S+) .* xxh64=([0-9a-f]{16})$", open(sys.argv[2]).read(), re.M))
if summary != listed:
    bad = sorted(k for k in set(summary) | set(listed) if summary.get(k) != listed.get(k))
    sys.exit("golden: summary xxh64 differs from `info` for %s: summary %s, info %s"
             % (bad, [summary.get(k) for k in bad], [listed.get(k) for k in bad]))
PY
echo "golden: $(wc -l < "$tmp/actual.txt") lines identical (built with 1 thread; golden made with 2);" \
     "blob hashes equal the uncompressed package's checksums"
