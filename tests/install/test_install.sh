#!/usr/bin/env bash
# test_install: installs this build with `cmake --install` into a scratch prefix and builds a
# program outside the project against it (consumer/read_cache.c), which opens a cache written by
# the installed CLI and reads a frame:
#   - CMake: find_package(flockmorph) with flockmorph::reader, flockmorph::flockmorph and, when
#     built, flockmorph::shared; then find_package(flockmorph COMPONENTS reader) alone;
#   - pkg-config: flockmorph_reader, and flockmorph (shared, and static from a copy of the prefix
#     without the shared library);
#   - the reader programs and libflockmorph_reader.a name none of TetGen, Embree, OpenVDB, assimp
#     (nm) and load none of them (ldd).
# Any failing step fails the test. (No `grep -q` after a pipe: with pipefail, the writer's SIGPIPE
# when grep stops early would fail the check at random.)
#   tests/install/test_install.sh BUILD_DIR SCRATCH_DIR LIBDIR SHARED(ON|OFF) C_COMPILER [CMAKE]
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
build=$1 libdir=$3 shared=$4 cc=$5 cmake=${6:-cmake} # the build's own cmake, from ctest
work=$2/install
rm -rf "$work"
mkdir -p "$work"
prefix=$work/prefix
fail() { echo "test_install: FAIL: $*" >&2; exit 1; }
log() { echo "test_install: $*"; }
# runs a command with its output in $work/NAME.log, shown only when it fails
quiet() { local name=$1; shift; "$@" > "$work/$name.log" 2>&1 || { cat "$work/$name.log"; fail "$name: $*"; }; }

quiet install "$cmake" --install "$build" --prefix "$prefix"
for f in include/flockmorph/flockmorph.h include/flockmorph/cache.h include/flockmorph/version.h \
         "$libdir/libflockmorph.a" "$libdir/libflockmorph_reader.a" bin/flockmorph \
         "$libdir/cmake/flockmorph/flockmorphConfig.cmake" "$libdir/cmake/flockmorph/flockmorphConfigVersion.cmake" \
         "$libdir/pkgconfig/flockmorph.pc" "$libdir/pkgconfig/flockmorph_reader.pc"; do
  [ -e "$prefix/$f" ] || fail "not installed: $f"
done
[ "$shared" = ON ] && { [ -e "$prefix/$libdir/libflockmorph.so" ] || fail "not installed: $libdir/libflockmorph.so"; }
export PKG_CONFIG_PATH=$prefix/$libdir/pkgconfig
version=$(pkg-config --modversion flockmorph)
[ "$(pkg-config --modversion flockmorph_reader)" = "$version" ] || fail "the two .pc files disagree on the version"
[ "$("$prefix/bin/flockmorph" --version)" = "flockmorph $version" ] || fail "installed CLI: $("$prefix/bin/flockmorph" --version), .pc: $version"
man=$prefix/share/man/man1/flockmorph.1
[ -e "$man" ] || fail "not installed: share/man/man1/flockmorph.1"
grep -q "^\.TH FLOCKMORPH 1 .*flockmorph $version" "$man" || fail "the man page does not carry version $version"
if command -v groff > /dev/null; then # renders without a warning
  [ -z "$(groff -man -Tutf8 -ww -z "$man" 2>&1)" ] || fail "groff warns on the man page: $(groff -man -Tutf8 -ww -z "$man" 2>&1)"
fi
log "installed flockmorph $version into $prefix"

# a cache of a tiny run (an octahedron onto itself 6 units away), written by the installed CLI
agents=60
cat > "$work/oct.obj" <<'OBJ'
v 1 0 0
v -1 0 0
v 0 1 0
v 0 -1 0
v 0 0 1
v 0 0 -1
f 1 3 5
f 3 2 5
f 2 4 5
f 4 1 5
f 3 1 6
f 2 3 6
f 4 2 6
f 1 4 6
OBJ
cat > "$work/scene.json" <<JSON
{"source": {"mesh": "oct.obj", "translate": [-3, 0, 0]},
 "target": {"mesh": "oct.obj", "translate": [3, 0, 0]}, "n": $agents}
JSON
quiet run "$prefix/bin/flockmorph" run "$work/scene.json" -o "$work/run" --quiet --threads 2
cache=$work/run/frames.fmc
[ -s "$cache" ] || fail "the installed CLI wrote no $cache"

# the studio's page (docs/studio.md), where this build made it: installed beside the CLI, which
# finds it there (its address comes without "the page is not built")
if [ -f "$build/studio/index.html" ]; then
  [ -f "$prefix/share/flockmorph/studio/index.html" ] && [ -f "$prefix/share/flockmorph/studio/app.js" ] \
    || fail "not installed: share/flockmorph/studio/ (the studio's page)"
  "$prefix/bin/flockmorph" studio "$cache" --port 0 --no-browser > "$work/studio.log" 2>&1 &
  studio_pid=$!
  for _ in $(seq 100); do grep -q "open http" "$work/studio.log" && break; sleep 0.1; done
  kill "$studio_pid"; wait "$studio_pid" || true
  grep -q "open http" "$work/studio.log" || { cat "$work/studio.log"; fail "the installed studio printed no address"; }
  if grep -q "not built" "$work/studio.log"; then fail "the installed studio does not find its page"; fi
  log "the installed studio finds its page"
fi

# nm and ldd: nothing of the engine's heavy libraries in what only reads caches
check_reader_only() {
  local file=$1
  if nm "$file" 2>/dev/null | grep -E ' (rtc[A-Z]|ai[A-Z]|_ZN7openvdb|json_|XXH|GOMP_)|tetgenio|tetrahedralize' > "$work/nm.txt"; then
    head "$work/nm.txt"; fail "$file names symbols of the engine's libraries"
  fi
  if [ -x "$file" ] && ldd "$file" | grep -E 'lib(tet|embree|openvdb|assimp|tbb|jansson|png|xxhash|gomp|stdc\+\+)' > "$work/ldd.txt"; then
    cat "$work/ldd.txt"; fail "$file loads the engine's libraries"
  fi
  return 0
}
check_reader_only "$prefix/$libdir/libflockmorph_reader.a"

# CMake: find_package(flockmorph)
quiet cmake_configure "$cmake" -S "$here/consumer" -B "$work/cmake" -DCMAKE_PREFIX_PATH="$prefix" \
  -DCMAKE_C_COMPILER="$cc" -DCMAKE_BUILD_TYPE=Release
quiet cmake_build "$cmake" --build "$work/cmake"
programs="read_cache_reader read_cache_static"
[ "$shared" = ON ] && programs="$programs read_cache_shared"
for p in $programs; do
  "$work/cmake/$p" "$cache" "$agents" || fail "$p (find_package)"
done
for p in run_scene_static $([ "$shared" = ON ] && echo run_scene_shared); do
  "$work/cmake/$p" "$work/scene.json" "$agents" "$work/$p.png" || fail "$p (find_package)"
done
check_reader_only "$work/cmake/read_cache_reader"
[ "$shared" != ON ] || ldd "$work/cmake/read_cache_shared" | grep 'libflockmorph\.so' > /dev/null || fail "read_cache_shared does not load libflockmorph.so"

# CMake: find_package(flockmorph COMPONENTS reader), which must not need the engine's packages
quiet cmake_reader_configure "$cmake" -S "$here/consumer" -B "$work/cmake_reader" -DCMAKE_PREFIX_PATH="$prefix" \
  -DCMAKE_C_COMPILER="$cc" -DFM_READER_ONLY=ON
grep -q -i "openvdb\|embree\|assimp" "$work/cmake_reader/CMakeCache.txt" && fail "COMPONENTS reader looked for the engine's packages"
quiet cmake_reader_build "$cmake" --build "$work/cmake_reader"
"$work/cmake_reader/read_cache_reader" "$cache" "$agents" || fail "read_cache_reader (COMPONENTS reader)"

# pkg-config
compile() { # SOURCE OUTPUT PKG_CONFIG_PATH pkg-config-arguments...
  local source=$1 out=$2 path=$3; shift 3
  local flags
  flags=$(PKG_CONFIG_PATH=$path pkg-config "$@") || fail "pkg-config $*"
  # shellcheck disable=SC2086 # the flags are words
  quiet "cc_$(basename "$out")" "$cc" -o "$out" "$here/consumer/$source" -DEXPECTED_VERSION="\"$version\"" $flags ${extra_flags:-}
}
compile read_cache.c "$work/pc_reader" "$PKG_CONFIG_PATH" --cflags --libs flockmorph_reader
"$work/pc_reader" "$cache" "$agents" || fail "pc_reader (pkg-config flockmorph_reader)"
check_reader_only "$work/pc_reader"
if [ "$shared" = ON ]; then
  # without an rpath the program does not find the library when it starts (docs/install.md)...
  compile read_cache.c "$work/pc_shared_no_rpath" "$PKG_CONFIG_PATH" --cflags --libs flockmorph
  env -u LD_LIBRARY_PATH ldd "$work/pc_shared_no_rpath" | grep 'libflockmorph\.so\.[0-9.]* => not found' > /dev/null \
    || fail "pc_shared_no_rpath found libflockmorph.so without an rpath: the documented flags are not tested"
  # ...and with the documented flags it does, LD_LIBRARY_PATH unset
  extra_flags="-Wl,-rpath,$(pkg-config --variable=libdir flockmorph)" \
    compile read_cache.c "$work/pc_shared" "$PKG_CONFIG_PATH" --cflags --libs flockmorph
  loaded=$(env -u LD_LIBRARY_PATH ldd "$work/pc_shared" | awk '/libflockmorph\.so/ { print $3 }')
  [ -n "$loaded" ] && [ "$(realpath "$loaded")" = "$(realpath "$prefix/$libdir/libflockmorph.so")" ] \
    || fail "pc_shared does not load the installed libflockmorph.so (ldd: ${loaded:-none})"
  env -u LD_LIBRARY_PATH "$work/pc_shared" "$cache" "$agents" || fail "pc_shared (pkg-config flockmorph, -Wl,-rpath)"
  # the static library through pkg-config --static, where no shared one is beside it
  cp -a "$prefix" "$work/static_prefix"
  rm -f "$work/static_prefix/$libdir"/libflockmorph.so*
  pc_static=("$work/static_prefix/$libdir/pkgconfig" --static --cflags --libs flockmorph)
else
  pc_static=("$PKG_CONFIG_PATH" --cflags --libs flockmorph)
fi
compile read_cache.c "$work/pc_static" "${pc_static[@]}"
compile run_scene.c "$work/pc_run_scene" "${pc_static[@]}"
for p in pc_static pc_run_scene; do
  ldd "$work/$p" | grep 'libflockmorph\.so' > /dev/null && fail "$p loads libflockmorph.so"
done
"$work/pc_static" "$cache" "$agents" || fail "pc_static (pkg-config flockmorph, static)"
"$work/pc_run_scene" "$work/scene.json" "$agents" "$work/pc_run_scene.png" || fail "pc_run_scene (pkg-config flockmorph, static)"
log "ok"
