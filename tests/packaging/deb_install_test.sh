#!/usr/bin/env bash
# Packaging.DebPassesLintianAndRunsInACleanDebianRoot
#
# Builds the .deb from the build tree (cpack), checks that it holds what
# `cmake --install` installs and that dpkg-shlibdeps filled Depends, runs
# lintian (any error fails), then installs it with apt into a clean Debian
# root (mmdebstrap, the suite and mirror this machine's apt uses) and there
# builds the Monaco sample, verifies the package, renders it on the CPU and
# fetches the browser viewer's page from `decalprep view`: the installed files
# and the Depends line alone must be enough. Then, with the Recommends
# installed (Mesa's EGL), it renders with GL. The source tree is not there:
# the shaders and the viewer must be built into the program.
#
# Without a clean root (not root, no mmdebstrap, no mirror) it unpacks the
# .deb instead and runs it on this machine, with the source and build trees
# hidden behind empty folders in a private mount namespace, and says so.
# When neither can run it exits 77 (ctest: skipped) with the reason.
#
# mmdebstrap's downloads are kept in WORK_DIR/apt-archives, so a second run
# fetches no package again (apt's index files it does fetch).
# Usage: deb_install_test.sh BUILD_DIR SOURCE_DIR WORK_DIR
set -euo pipefail
BUILD="$(cd "$1" && pwd)"
SRC="$(cd "$2" && pwd)"
WORK="$3"
mkdir -p "$WORK"
WORK="$(cd "$WORK" && pwd)"
# mmdebstrap's hooks split their arguments at spaces.
[[ "$WORK" != *" "* ]] || { echo "FAIL: WORK_DIR has a space: $WORK" >&2; exit 1; }

skip() { echo "SKIP: $*"; exit 77; }
fail() { echo "FAIL: $*" >&2; exit 1; }
step() { echo "== [${SECONDS}s] $*"; }

for tool in cpack dpkg-deb python3; do
  command -v "$tool" >/dev/null || skip "$tool is not installed (scripts/deps installs it)"
done
command -v lintian >/dev/null || skip "lintian is not installed (scripts/deps installs it)"
# The viewer's modules are built into the program from web/node_modules.
[ -f "$SRC/web/node_modules/fzstd/esm/index.mjs" ] ||
  fail "web/node_modules is missing: the packaged viewer could not load its reader (npm ci in web/, or scripts/deps)"

# --- build the .deb ---------------------------------------------------------
step "cpack -G DEB"
rm -rf "$WORK/packages" "$WORK/stage" "$WORK/stage-deb" "$WORK/case"
cpack -G DEB --config "$BUILD/CPackConfig.cmake" -B "$WORK/packages" >"$WORK/cpack.log" 2>&1 ||
  { cat "$WORK/cpack.log"; fail "cpack failed"; }
debs=("$WORK"/packages/decalprep_*_amd64.deb)
if [ ${#debs[@]} -ne 1 ] || [ ! -f "${debs[0]}" ]; then
  fail "expected one decalprep_*_amd64.deb in $WORK/packages: ${debs[*]}"
fi
DEB="${debs[0]}"
echo "$DEB"

# The version is project(VERSION), which the built tool prints too.
version="$(dpkg-deb -f "$DEB" Version)"
tool_version="$("$BUILD/tools/decalprep/decalprep" --version | sed -n '1s/^decalprep //p')"
[ "$version" = "$tool_version" ] || fail "package version '$version' is not the tool's '$tool_version'"
[ "$(basename "$DEB")" = "decalprep_${version}_amd64.deb" ] || fail "file name $(basename "$DEB") does not carry version $version"

# --- contents: everything `cmake --install` installs, and the Debian files ---
step "contents against cmake --install"
cmake --install "$BUILD" --prefix "$WORK/stage" >"$WORK/install.log" 2>&1 ||
  { cat "$WORK/install.log"; fail "cmake --install failed"; }
(cd "$WORK/stage" && find . -type f -o -type l | sed 's|^\./|/usr/|' | sort) >"$WORK/installed.txt"
dpkg-deb --fsys-tarfile "$DEB" | tar -t | sed -n 's|^\./|/|; /[^/]$/p' | sort >"$WORK/deb-files.txt"
missing="$(comm -23 "$WORK/installed.txt" "$WORK/deb-files.txt")"
[ -z "$missing" ] || fail "cmake --install installs files the .deb lacks:
$missing"
for f in /usr/bin/decalprep /usr/share/man/man1/decalprep.1.gz /usr/share/man/man1/decalprep-build.1.gz \
         /usr/share/man/man1/decalprep-render.1.gz /usr/share/doc/decalprep/README.md \
         /usr/share/doc/decalprep/copyright /usr/share/doc/decalprep/changelog.gz \
         /usr/include/decal/format.hpp; do
  grep -qx "$f" "$WORK/deb-files.txt" || fail "the .deb lacks $f"
done
grep -q '/libdecal_reader\.a$' "$WORK/deb-files.txt" || fail "the .deb lacks libdecal_reader.a"
grep -q '/cmake/decal_reader/decal_readerConfig\.cmake$' "$WORK/deb-files.txt" ||
  fail "the .deb lacks decal_readerConfig.cmake"
echo "$(wc -l <"$WORK/deb-files.txt") files"

# What a consumer reads (CMake packages, pkg-config files) names no path of
# this machine: not the build or source tree, and not the configure-time
# install prefix when it is not the package's /usr.
prefix="$(sed -n 's/^CMAKE_INSTALL_PREFIX:PATH=//p' "$BUILD/CMakeCache.txt")"
dpkg-deb -x "$DEB" "$WORK/stage-deb"
leaks=""
while IFS= read -r -d '' f; do
  for p in "$BUILD" "$SRC" ${prefix:+"$prefix"}; do
    [ "$p" = /usr ] && continue
    grep -qF "$p" "$f" && leaks+="${f#"$WORK/stage-deb"} names $p"$'\n'
  done
done < <(find "$WORK/stage-deb/usr/lib" "$WORK/stage-deb/usr/share" \( -name '*.cmake' -o -name '*.pc' \) -type f -print0)
[ -z "$leaks" ] || fail "installed files name paths of this machine:
$leaks"

# Depends comes from dpkg-shlibdeps: the C library and GDAL at least.
depends="$(dpkg-deb -f "$DEB" Depends)"
echo "Depends: $depends"
for lib in libc6 libgdal; do
  [[ "$depends" == *"$lib"* ]] || fail "Depends names no $lib: dpkg-shlibdeps did not run?"
done

# --- lintian -------------------------------------------------------------------
step "lintian --fail-on error"
lintian --fail-on error --tag-display-limit 0 "$DEB" || fail "lintian reports errors"

# --- what runs where the package is installed ----------------------------------
# run.sh PREFIX DIR cpu|gl: the installed tool PREFIX/bin/decalprep on the
# Monaco sample in DIR/monaco, writing DIR/out. cpu: build, verify, render on
# the CPU and serve the viewer, with what Depends brings; gl: render the
# package with GL (the EGL driver that Recommends names). The same script runs
# in the clean root and in the fallback.
cat >"$WORK/run.sh" <<'EOF'
set -eu
tool="$1/bin/decalprep"
dir="$2"
cd "$dir"
mkdir -p out
if [ "$3" = gl ]; then
  [ -f with-gl ] || { echo "GL render: not built (DECALPREP_GL=OFF)"; exit 0; }
  "$tool" render out/monaco.decals --dem /vsizip/monaco/N43E007.hgt.zip/N43E007.hgt \
    --eye 900,-3200,1300 --target 150,-300,60 --fov 45 --size 640x360 \
    -o out/monaco-gl.png --raw out/monaco-gl.raw
  exit 0
fi
"$tool" --version
"$tool" build monaco/scene.toml -o out/monaco.decals --report out/monaco.report.json
"$tool" verify out/monaco.decals
"$tool" render out/monaco.decals --cpu --dem /vsizip/monaco/N43E007.hgt.zip/N43E007.hgt \
  --eye 900,-3200,1300 --target 150,-300,60 --fov 45 --size 640x360 \
  -o out/monaco.png --raw out/monaco.raw
# The viewer page and a module it imports, from the program alone.
: >out/view.txt  # there before the loop reads it, whenever the shell below opens it
"$tool" view out/monaco.decals --port 0 >out/view.txt 2>&1 &
view=$!
url=""
for _ in $(seq 1 100); do
  url="$(sed -n 's|.*serving on http://\([^/]*\)/.*|\1|p' out/view.txt)"
  [ -n "$url" ] && break
  sleep 0.1
done
[ -n "$url" ] || { kill "$view"; cat out/view.txt; echo "view printed no address" >&2; exit 1; }
get() {  # get PATH FILE: HTTP GET over bash's /dev/tcp (no curl in a minimal root)
  exec 3<>"/dev/tcp/${url%:*}/${url##*:}"
  printf 'GET %s HTTP/1.0\r\nHost: %s\r\n\r\n' "$1" "$url" >&3
  cat <&3 >"$2"
  exec 3<&-
}
get / out/view-page.http
get /web/node_modules/fzstd/esm/index.mjs out/view-fzstd.http
kill "$view"
EOF

# check_outputs DIR: what run.sh wrote is there and is not trivial.
check_outputs() {
  local out="$1"
  [ -s "$out/monaco.decals" ] || fail "no package written"
  [ -s "$out/monaco.report.json" ] || fail "no build report written"
  python3 - "$out" <<'EOF' || fail "the outputs are trivial (see above)"
import array, os, struct, sys
out = sys.argv[1]
def image(stem):  # the PNG is 640x360 and not blank; the decal layer is drawn
    png = open(f"{out}/{stem}.png", "rb").read()
    assert png[:8] == b"\x89PNG\r\n\x1a\n", f"{stem}.png is not a PNG"
    w, h = struct.unpack(">II", png[16:24])
    assert (w, h) == (640, 360), f"{stem}.png is {w}x{h}, not 640x360"
    assert len(png) > 20000, f"{stem}.png is {len(png)} bytes: a blank image?"
    raw = array.array("f")
    raw.frombytes(open(f"{out}/{stem}.raw", "rb").read())
    assert len(raw) == 4 * w * h, f"{stem}.raw holds {len(raw)} floats, not {4 * w * h}"
    drawn = sum(1 for a in raw[3::4] if a > 0)
    assert drawn > w * h // 20, f"{stem}: only {drawn} of {w * h} pixels carry a decal"
    print(f"{stem}.png {w}x{h}, {len(png)} bytes; {drawn} of {w * h} pixels carry a decal")
image("monaco")
if os.path.exists(f"{out}/../with-gl"):
    image("monaco-gl")
page = open(f"{out}/view-page.http", "rb").read()
assert page.startswith(b"HTTP/1.1 200") and b"<html" in page.lower(), "view served no page at /"
mod = open(f"{out}/view-fzstd.http", "rb").read()
assert mod.startswith(b"HTTP/1.1 200") and len(mod) > 5000, "view did not serve the fzstd module"
print("viewer: page and modules served")
EOF
}

mkdir -p "$WORK/case"
cp -r "$SRC/samples/monaco" "$WORK/case/monaco"
cp "$WORK/run.sh" "$WORK/case/run.sh"
if [ "$(sed -n 's/^DECALPREP_GL:BOOL=//p' "$BUILD/CMakeCache.txt")" != OFF ]; then
  touch "$WORK/case/with-gl"
fi
# In the clean root: install what the package recommends.
cat >"$WORK/case/recommends.sh" <<'EOF'
set -eu
recommends="$(dpkg-query -W -f='${Recommends}' decalprep | tr ',' ' ')"
DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends $recommends
EOF

# The suite and mirrors this machine's apt uses: every sources file that
# names bookworm ($DECALPREP_DEB_MIRROR, mmdebstrap's MIRROR arguments,
# replaces them).
mirrors=()
if [ -n "${DECALPREP_DEB_MIRROR:-}" ]; then
  read -r -a mirrors <<<"$DECALPREP_DEB_MIRROR"
else
  for f in /etc/apt/sources.list /etc/apt/sources.list.d/*.list /etc/apt/sources.list.d/*.sources; do
    [ -f "$f" ] && grep -qw bookworm "$f" && mirrors+=("$f")
  done
fi

why_no_root=""
[ "$(id -u)" -eq 0 ] || why_no_root="not root"
command -v mmdebstrap >/dev/null || why_no_root="${why_no_root:+$why_no_root; }mmdebstrap is not installed"
[ ${#mirrors[@]} -gt 0 ] || why_no_root="${why_no_root:+$why_no_root; }apt names no bookworm mirror"

if [ -z "$why_no_root" ]; then
  step "clean root: mmdebstrap --variant=apt bookworm (${mirrors[*]}), apt-get install ./$(basename "$DEB")"
  cache="$WORK/apt-archives"
  mkdir -p "$cache"
  rm -f "$WORK/root-made" "$WORK/case/rc" "$WORK/case/rc-gl"
  cp "$DEB" "$WORK/case/"
  # Each run's exit status goes to a file (rc, rc-gl), so that what it wrote
  # is copied out even when it fails. The CPU run has what Depends brings;
  # then the Recommends are installed for the GL run.
  # The root is thrown away: dpkg need not sync every file, and it is made in
  # memory when there is plenty of room (the whole test, warm, on 2 busy
  # cores: about 110 s with the root on disk, 25-52 s in memory).
  tmp="${TMPDIR:-/tmp}"
  shm_free_kb="$(df -Pk /dev/shm 2>/dev/null | awk 'NR == 2 { print $4 }')"
  mem_free_kb="$(awk '/^MemAvailable:/ { print $2 }' /proc/meminfo)"
  if [ "${shm_free_kb:-0}" -gt 4194304 ] && [ "${mem_free_kb:-0}" -gt 6291456 ]; then tmp=/dev/shm; fi
  echo "clean root made in $tmp"
  set +e
  # shellcheck disable=SC2016  # "$1" in a hook is the root, for mmdebstrap's shell
  TMPDIR="$tmp" mmdebstrap --mode=root --variant=apt --dpkgopt=force-unsafe-io \
    --skip=download/empty --skip=essential/unlink \
    --setup-hook='mkdir -p "$1"/var/cache/apt/archives' \
    --setup-hook="sync-in $cache /var/cache/apt/archives/" \
    --customize-hook="touch '$WORK/root-made'" \
    --customize-hook='mkdir -p "$1"/root/case' \
    --customize-hook="sync-in $WORK/case /root/case" \
    --customize-hook='chroot "$1" sh -c "cd /root/case && DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends ./decalprep_*_amd64.deb"' \
    --customize-hook='chroot "$1" sh -c "bash /root/case/run.sh /usr /root/case cpu >/root/case/out.log 2>&1; echo \$? >/root/case/rc"' \
    --customize-hook='chroot "$1" sh /root/case/recommends.sh' \
    --customize-hook="sync-out /var/cache/apt/archives $cache" \
    --customize-hook='chroot "$1" sh -c "bash /root/case/run.sh /usr /root/case gl >/root/case/out-gl.log 2>&1; echo \$? >/root/case/rc-gl"' \
    --customize-hook="sync-out /root/case $WORK/case" \
    bookworm /dev/null "${mirrors[@]}" >"$WORK/mmdebstrap.log" 2>&1
  rc=$?
  set -e
  if [ $rc -ne 0 ]; then
    tail -n 40 "$WORK/mmdebstrap.log"
    if [ -f "$WORK/root-made" ]; then
      fail "installing the .deb into the clean root failed (mmdebstrap exit $rc; $WORK/mmdebstrap.log)"
    fi
    why_no_root="mmdebstrap could not make a root (exit $rc; no mirror?)"
  else
    echo "clean root: $(grep -c '^Unpacking' "$WORK/mmdebstrap.log" || true) packages unpacked after the essential set"
    cat "$WORK/case/out.log"
    [ "$(cat "$WORK/case/rc")" = 0 ] || fail "the installed decalprep failed in the clean root"
    cat "$WORK/case/out-gl.log"
    [ "$(cat "$WORK/case/rc-gl")" = 0 ] ||
      fail "the installed decalprep failed to render with GL in the clean root (with the Recommends)"
    check_outputs "$WORK/case/out"
    step "done (clean root)"
    exit 0
  fi
fi

# --- fallback: this machine, the trees hidden ------------------------------------
echo "no clean root: $why_no_root"
echo "FALLBACK: running the unpacked .deb on this machine with $SRC and $BUILD hidden"
hide=()
if [ "$(id -u)" -eq 0 ]; then hide=(unshare --mount); else hide=(unshare --map-root-user --mount); fi
"${hide[@]}" true 2>/dev/null || skip "no clean root ($why_no_root) and no private mount namespace to hide the trees in"
# The shared libraries the Depends line names must be on this machine.
dpkg --dry-run -i "$DEB" >/dev/null 2>&1 || [ "$(id -u)" -ne 0 ] ||
  fail "this machine lacks what Depends names: $(dpkg --dry-run -i "$DEB" 2>&1 | tail -n 5)"
unpacked="$(mktemp -d /tmp/decalprep-deb.XXXXXX)"
trap 'rm -rf "$unpacked"' EXIT
dpkg-deb -x "$DEB" "$unpacked/root"
cp -r "$WORK/case" "$unpacked/case"
set +e
# The build tree first: it may lie inside the source tree.
# shellcheck disable=SC2016  # the arguments are the inner shell's
"${hide[@]}" sh -c 'mount -t tmpfs none "$1" && mount -t tmpfs none "$2" && bash "$3/case/run.sh" "$3/root/usr" "$3/case" cpu && bash "$3/case/run.sh" "$3/root/usr" "$3/case" gl' \
  hide "$BUILD" "$SRC" "$unpacked" >"$WORK/fallback.log" 2>&1
rc=$?
set -e
cat "$WORK/fallback.log"
[ $rc -eq 0 ] || fail "the unpacked decalprep failed with the trees hidden"
check_outputs "$unpacked/case/out"
step "done (fallback: this machine, trees hidden)"
