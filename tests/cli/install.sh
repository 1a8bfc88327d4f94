#!/usr/bin/env bash
# make install from the outside, as a user of the library sees it: the
# tree under PREFIX (tools, static and versioned shared library, headers,
# voxdag.pc), every header compiling alone, examples/read_ssvdag.c built
# with pkg-config against the shared and the static library, and its
# answers on the bunny checked against independent references: the voxel
# count of voxelize's statistics and colours recomputed from
# colour-make-test's formula for each voxel's own coordinates. Then
# DESTDIR and make uninstall. `make test` builds the libraries first
# (test-build), so the installs here only copy.
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh
if ! command -v pkg-config >/dev/null; then
	echo "SKIP install: no pkg-config (make deps installs it)"
	exit 0
fi
P="$T/prefix"
# The flags of a calling make (tests/run.sh under `make test`: its job
# server, -k, ...) are not this make's.
unset MAKEFLAGS MFLAGS MAKELEVEL

# --- the installed tree
if make --no-print-directory -s install PREFIX="$P" >"$T/make.out" 2>&1; then
	pass install_runs
else
	fail install_runs "$(tail -n 5 "$T/make.out")"
fi
# the version the installed headers declare
version=$(sed -n 's/^#define VD_VERSION_STRING "\(.*\)"/\1/p' "$P"/include/voxdag/*.h | head -n 1)
ok=1
for f in lib/libvoxdag.a "lib/libvoxdag.so.$version" include/voxdag/voxdag.h \
	 lib/pkgconfig/voxdag.pc; do
	[ -f "$P/$f" ] || { ok=0; echo "missing $P/$f" >&2; }
done
for h in stages/lib/vd_*.h; do # the per-concern headers, when there are any
	[ -e "$h" ] || continue
	cmp -s "$h" "$P/include/voxdag/${h##*/}" || { ok=0; echo "not installed: $h" >&2; }
done
[ "$(readlink "$P/lib/libvoxdag.so.${version%%.*}")" = "libvoxdag.so.$version" ] &&
[ "$(readlink "$P/lib/libvoxdag.so")" = "libvoxdag.so.${version%%.*}" ] || ok=0
readelf -d "$P/lib/libvoxdag.so.$version" | grep -q "SONAME.*\[libvoxdag.so.${version%%.*}\]" || ok=0
[ $ok = 1 ] && pass tree || fail tree "$(cd "$P" && find . | sort)"
# the installed voxdag view serves the installed page
mkdir -p "$T/served"
(cd "$T" && exec "$P/bin/voxdag" view "$T/served" --port 0 > "$T/view.url" 2>"$T/view.err") &
vpid=$!
for _ in $(seq 50); do [ -s "$T/view.url" ] && break; sleep 0.1; done
if [ -s "$T/view.url" ] && command -v curl >/dev/null &&
	curl -s "$(head -1 "$T/view.url")viewer.js" | cmp -s - viewer/viewer.js; then
	pass installed_view_serves_page
else
	fail installed_view_serves_page "$(cat "$T/view.err")"
fi
kill $vpid 2>/dev/null
wait $vpid 2>/dev/null

export PKG_CONFIG_PATH="$P/lib/pkgconfig"
[ "$(pkg-config --modversion voxdag 2>&1)" = "$version" ] &&
[ "$(pkg-config --variable=prefix voxdag)" = "$P" ] &&
[ "$(echo $(pkg-config --cflags voxdag))" = "-I$P/include/voxdag" ] &&
pkg-config --static --libs voxdag | grep -q -- '-lzstd.*-lstdc++' &&
	pass pkgconfig || fail pkgconfig "$(cat "$P/lib/pkgconfig/voxdag.pc")"

# Every installed tool is there and runs (voxdag-spawn is the runner's
# launcher: no --help, only there).
ok=1
for t in out/bin/*; do
	n=${t##*/}
	[ -x "$P/bin/$n" ] && cmp -s "$t" "$P/bin/$n" ||
		{ ok=0; echo "missing or not the built one: $P/bin/$n" >&2; continue; }
	[ "$n" = voxdag-spawn ] || "$P/bin/$n" --help >/dev/null 2>&1 ||
		{ ok=0; echo "$n --help failed" >&2; }
done
[ $ok = 1 ] && pass tools_run || fail tools_run

# Every header alone, as C11 and as C++ (voxdag.h promises extern "C").
ok=1
for h in "$P"/include/voxdag/*.h; do
	echo "#include <${h##*/}>" > "$T/h.c"
	for lang in "cc -x c -std=c11" "c++ -x c++ -std=c++17"; do
		$lang -Wall -Wextra -Werror -fsyntax-only $(pkg-config --cflags voxdag) \
			"$T/h.c" 2>"$T/h.err" ||
			{ ok=0; echo "$lang: ${h##*/}: $(head -n 3 "$T/h.err")" >&2; }
	done
done
[ $ok = 1 ] && pass headers_compile_alone || fail headers_compile_alone

# --- the example, built as examples/README.md says: shared (found at run
# time through LD_LIBRARY_PATH, so through the soname's link) and static (libvoxdag.a named explicitly,
# since -lvoxdag prefers the .so beside it, plus Libs.private)
X=examples/read_ssvdag.c
cc -std=c11 -Wall -Wextra -Werror -o "$T/shared" $X \
	$(pkg-config --cflags --libs voxdag) 2>"$T/cc.err" &&
	readelf -d "$T/shared" | grep -q "NEEDED.*\[libvoxdag.so.${version%%.*}\]" &&
	pass example_builds_shared || fail example_builds_shared "$(head -n 5 "$T/cc.err")"
static_libs=$(pkg-config --static --libs voxdag)
cc -std=c11 -Wall -Wextra -Werror -o "$T/static" $X $(pkg-config --cflags voxdag) \
	${static_libs/-lvoxdag/-l:libvoxdag.a} 2>"$T/cc.err" &&
	! readelf -d "$T/static" | grep -q 'NEEDED.*libvoxdag' &&
	pass example_builds_static || fail example_builds_static "$(head -n 5 "$T/cc.err")"

# --- a real scene: the bunny at 2^6 in 8 cells through the installed
# tools, with colour-make-test's "noise" colours (a hash of each voxel's
# own coordinates), compressed losslessly by colorize
B="$P/bin" V="$T/vox"
{
	"$B/voxelize" tests/data/bunny.ply -o "$V" --levels 6 --chunk-level 1 -q &&
	"$B/colour-make-test" "$V" --pattern noise &&
	(for f in "$V"/chunk-L1-*.svo; do "$B/svo-to-dag" -q "$f" -o "${f%.svo}.dag" || exit 1; done) &&
	"$B/svo-to-dag" -q --merge "$V"/chunk-L1-*.dag -o "$T/root.dag" &&
	"$B/symmetry-merge" -q --merge "$V"/chunk-L1-*.dag -o "$T/root.ssvdag" &&
	"$B/encode" -q "$T/root.dag" "$T/root.ssvdag" -o "$T/enc" --name bunny &&
	"$B/colorize" -q "$V" -o "$T/pack" --method raw
} 2>"$T/scene.err" || fail scene "$(head -n 5 "$T/scene.err")"
voxels=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["voxels"])' "$V/voxelize.stats.json")
# every voxel of the 64^3 grid, and one point outside it at the end
python3 -c 'r = range(64); print("\n".join(f"{x} {y} {z}" for x in r for y in r for z in r))' > "$T/points"

# check NAME OUTPUT: every set voxel has the colour colour-make-test gave
# its coordinates, the set ones are as many as voxelize counted, and the
# walk's count agrees
check() {
	python3 - "$2" "$voxels" <<'PY' && pass "$1" || fail "$1" "$(head -n 3 "$2")"
import sys
M = (1 << 64) - 1
def noise(x, y, z, seed=1):  # stages/colour-make-test/main.c, hash3
    h = (x * 0x9E3779B97F4A7C15 ^ y * 0xC2B2AE3D27D4EB4F ^
         z * 0x165667B19E3779F9 ^ seed) & M
    h ^= h >> 29
    h = h * 0xBF58476D1CE4E5B9 & M
    h ^= h >> 32
    return [h & 0xff, h >> 8 & 0xff, h >> 16 & 0xff]
lines = open(sys.argv[1]).read().splitlines()
n = int(sys.argv[2])
assert lines[0] == "levels 6" and lines[1] == f"voxels {n}", lines[:2]
assert lines[-1] == f"queried {64 ** 3}, set {n}", lines[-1]
body = [l.split() for l in lines[2:-1]]
assert len(body) == 64 ** 3
seen = set()
for w in body:
    p = tuple(map(int, w[:3]))
    seen.add(p)
    if w[3] == "set":
        assert list(map(int, w[4:])) == noise(*p), w
    else:
        assert w[3:] == ["empty"], w
assert sum(w[3] == "set" for w in body) == n and len(seen) == 64 ** 3
PY
}
export LD_LIBRARY_PATH="$P/lib"
"$T/shared" "$T/enc/bunny.ssvdag" "$T/pack/colours.raw" < "$T/points" > "$T/shared.out" 2>"$T/run.err"
check shared_answers_match "$T/shared.out"
"$T/static" "$T/enc/bunny.ssvdag" "$T/pack/colours.raw" < "$T/points" > "$T/static.out" 2>"$T/run.err"
cmp -s "$T/shared.out" "$T/static.out" && pass static_same_answers || fail static_same_answers "$(head -n 3 "$T/run.err")"
# the other formats, with the colour chunks themselves
for f in esvdag svdag; do
	"$T/shared" "$T/enc/bunny.$f" "$V" < "$T/points" > "$T/$f.out" 2>"$T/run.err"
	check "answers_match_$f" "$T/$f.out"
done
expect example_outside_grid 1 'outside the 64\^3 grid' "$T/shared" "$T/enc/bunny.ssvdag" \
	< <(echo 64 0 0)
mkdir -p "$T/small"
"$B/voxelize" tests/data/bunny.ply -o "$T/small" --levels 5 -q && "$B/colour-make-test" "$T/small"
expect example_other_scene_colours 1 'colours at depth 5 for' "$T/shared" "$T/enc/bunny.ssvdag" "$T/small" < /dev/null
expect example_bad_scene 1 "cannot read '$T/points.ssvdag'" "$T/shared" "$T/points.ssvdag" < /dev/null

# --- DESTDIR (what a package build does), then uninstall leaves no file
D="$T/dest"
if make --no-print-directory -s install DESTDIR="$D" PREFIX=/usr >"$T/make.out" 2>&1 &&
   [ -f "$D/usr/lib/libvoxdag.a" ] && [ -x "$D/usr/bin/voxdag" ] &&
   grep -qx 'prefix=/usr' "$D/usr/lib/pkgconfig/voxdag.pc" &&
   PKG_CONFIG_SYSROOT_DIR="$D" PKG_CONFIG_PATH="$D/usr/lib/pkgconfig" \
	pkg-config --cflags voxdag | grep -q -- "^-I$D/usr/include/voxdag *\$"; then
	pass destdir
else
	fail destdir "$(tail -n 5 "$T/make.out")" "$(cat "$D/usr/lib/pkgconfig/voxdag.pc")"
fi
make --no-print-directory -s uninstall DESTDIR="$D" PREFIX=/usr >"$T/make.out" 2>&1 &&
	[ -z "$(find "$D" ! -type d)" ] && pass uninstall ||
	fail uninstall "$(tail -n 3 "$T/make.out")" "$(find "$D" ! -type d)"
