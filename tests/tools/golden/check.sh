#!/usr/bin/env bash
# Golden end-to-end test: builds tests/tools/golden/scene.toml with the tool and
# compares `decalprep dump` with the checked-in golden.dump.gz (made by
# regenerate.sh). Prints the first differing lines on failure.
set -euo pipefail
tool="$1"
here="$(cd "$(dirname "$0")" && pwd)"
tmp="$(mktemp -d)"; trap 'rm -rf "$tmp"' EXIT
"$tool" build "$here/scene.toml" -o "$tmp/golden.decals" -q --threads 1
"$tool" dump "$tmp/golden.decals" | sed -e "s#$(cd "$here/../../.." && pwd)#<ROOT>#g" > "$tmp/actual.dump"
zcat "$here/golden.dump.gz" > "$tmp/expected.dump"
if ! cmp -s "$tmp/expected.dump" "$tmp/actual.dump"; then
  echo "golden: dump differs from golden.dump.gz (regenerate with regenerate.sh if the change is intended):"
  diff "$tmp/expected.dump" "$tmp/actual.dump" | head -n 20 | cut -c 1-300
  exit 1
fi
echo "golden: $(wc -l < "$tmp/actual.dump") lines identical (built with 1 thread; golden made with 2)"
