#!/usr/bin/env bash
# Regenerates golden.summary.txt, the `decalprep dump --summary` of
# tests/tools/golden/scene.toml (built with the scene's 2 threads).
# Usage: tests/tools/golden/regenerate.sh [path/to/decalprep]
# Review the diff before committing: a change here is a change of the package.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
tool="${1:-$here/../../../build/release/tools/decalprep/decalprep}"
tmp="$(mktemp -d)"; trap 'rm -rf "$tmp"' EXIT
"$tool" build "$here/scene.toml" -o "$tmp/golden.decals" -q
# Strip what depends on where the checkout lives (absolute paths).
"$tool" dump "$tmp/golden.decals" --summary | sed -e "s#$(cd "$here/../../.." && pwd)#<ROOT>#g" > "$here/golden.summary.txt"
echo "wrote $here/golden.summary.txt ($(wc -l < "$here/golden.summary.txt") lines)"
