#!/usr/bin/env bash
# Regenerates the golden dump of tests/tools/golden/scene.toml.
# Usage: tests/tools/golden/regenerate.sh [path/to/decalprep]
# Review the diff before committing: a change here is a change of the package.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
tool="${1:-$here/../../../build/release/tools/decalprep/decalprep}"
tmp="$(mktemp -d)"; trap 'rm -rf "$tmp"' EXIT
"$tool" build "$here/scene.toml" -o "$tmp/golden.decals" -q
# Strip what depends on where the checkout lives (absolute paths).
"$tool" dump "$tmp/golden.decals" | sed -e "s#$(cd "$here/../../.." && pwd)#<ROOT>#g" | gzip -9n > "$here/golden.dump.gz"
echo "wrote $here/golden.dump.gz ($(zcat "$here/golden.dump.gz" | wc -l) lines)"
