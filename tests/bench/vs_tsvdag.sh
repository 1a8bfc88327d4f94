#!/usr/bin/env bash
# Side-by-side benchmark (issue 41): voxdag's encodings against the
# transform-aware SVDAG of Molenaar & Eisemann (I3D 2025, reference code
# mathijs727/i3d2025-voxel-transform-dag, C++), on the SAME voxels: voxdag
# voxelizes the mesh and writes its SymVox-compatible .svdag; the
# reference's svdag_encoding reads that file and builds its .tdag16.
#
#   tests/bench/vs_tsvdag.sh TSVDAG_DIR [MESH...]
#
# MESH defaults to every mesh of ../shared/data (VOXDAG_SHARED_DATA), each
# at the levels VS_TSVDAG_LEVELS (default "10 12"), and the bunny also at
# VS_TSVDAG_BUNNY_LEVELS (default 13; empty for none).
#
# The reference's CPU tools (tools/lib, tools/svdag_encoding,
# tools/voxelizer) are compiled with g++ OUTSIDE the repository's sources:
# the tools folder is copied to $VS_TSVDAG_BUILD/src (default
# out/tsvdag-build), tests/bench/tsvdag-gcc12.patch is applied to the copy
# (GCC 12 / fmt 9 / C++20 fixes with no change of behaviour, and one read
# fix: their .tdag16 reader crashed on a level without Huffman codes) and
# it is built there without CUDA and without CMake (its CMakeLists asks for
# the CUDA renderer's dependencies), -O2 -DNDEBUG -mavx2 as their README's
# RelWithDebInfo build; nothing of it is ever committed. Debian
# packages it needs (benchmark dependencies, not project ones):
#   libabsl-dev libassimp-dev libcli11-dev libeigen3-dev libfmt-dev
#   libfreeimage-dev libfreeimageplus-dev libglm-dev libspdlog-dev
#   libtbb-dev nlohmann-json3-dev
# Three header-only libraries it uses are not packaged by Debian:
# robin_hood (martinus/robin-hood-hashing), libmorton (Forceflow/libmorton)
# and mio (mandreyel/mio). Checkouts of them are looked for beside
# TSVDAG_DIR (robin-hood-hashing/, libmorton/, mio/) or in
# VS_TSVDAG_DEPS. Its CMake also links EASTL, which no source includes.
#
# Their settings are the paper's (the renderer's defaults): symmetry, axis
# permutation, translations up to level 4, pointer tables, Huffman-coded
# transforms (VS_TSVDAG_FLAGS to change). Their build is timed from our
# .svdag to the .tdag16 with --noverify; the check below is separate and
# untimed.
#
# What is checked, per mesh and level:
#  - ours: the .svdag is decoded by dag-verify and compared with the SVO
#    chunks (our voxels);
#  - their reading of it: their voxelizer imports our .svdag and writes it
#    back as .svdag; dag-verify --diff compares the two (0 differing voxels
#    means they read our file as the voxels we meant);
#  - their .tdag16 as written: tests/bench/tsvdag_check.cpp reads it back
#    from disk, looks up every voxel of every non-empty 4^3 brick of our
#    .svdag with their decoder, and counts the .tdag16's voxels with a
#    decoder of its own; equal counts and no mismatch = equal voxel sets.
#
# Ours is the lossless pipeline through the runner (voxelize, svo-to-dag,
# symmetry-merge with groups 8 and 48, encode): wall seconds from the mesh,
# the seconds from our SVDAG (the symmetry-merge and encode jobs, mesh-free
# like theirs) and the largest process's peak (report.csv). Theirs: wall
# seconds and peak RSS of svdag_encoding (GNU time). Bytes: theirs is the
# .tdag16 (file size, and their own count, TransformDAG16::sizeInBytes);
# ours are encode's counted bytes (file minus header) of .svdag, .ssvdag and
# .ssvdag48. One run each, both sides under nice -n 5 (the machine is
# shared): wall seconds are noisy, CPU seconds (also printed) less so.
# VS_TSVDAG_KEEP=1 keeps every output under $VS_TSVDAG_BUILD/runs.
# Long: their translation search dominates. On 2 shared cores their build
# took 11-105 s per mesh at 2^10 and 35 min for the bunny at 2^12 (2115 s,
# 1303 s of CPU: its 16^3 level alone has 206,142 grids to search); all
# meshes at 2^12 and the bunny at 2^13 take hours.
# Part of make bench when TSVDAG_DIR is set (tests/bench.sh).
set -u
cd "$(dirname "$0")/../.."
ROOT=$(pwd)
die() { echo "vs_tsvdag: $*" >&2; exit 1; }
if [ $# -lt 1 ] || [ "$1" = -h ] || [ "$1" = --help ]; then
	echo "usage: tests/bench/vs_tsvdag.sh TSVDAG_DIR [MESH...]" >&2
	exit 2
fi
SRC=$(cd "$1" 2>/dev/null && pwd) || die "cannot open '$1': no such directory"
shift
[ -f "$SRC/tools/svdag_encoding/src/main.cpp" ] ||
	die "cannot find '$SRC/tools/svdag_encoding/src/main.cpp': not an i3d2025-voxel-transform-dag checkout"
LEVELS=${VS_TSVDAG_LEVELS:-10 12}
BUNNY_LEVELS=${VS_TSVDAG_BUNNY_LEVELS-13}
for l in $LEVELS $BUNNY_LEVELS; do
	case $l in *[!0-9]*) die "bad level '$l' in VS_TSVDAG_LEVELS or VS_TSVDAG_BUNNY_LEVELS";; esac
done
FLAGS=${VS_TSVDAG_FLAGS:---symmetry --axis --translation 4 --pointertables --huffman}
BUILD=${VS_TSVDAG_BUILD:-out/tsvdag-build}
DEPS=${VS_TSVDAG_DEPS:-$(dirname "$SRC")}
PATCH=$ROOT/tests/bench/tsvdag-gcc12.patch
CHECK_SRC=$ROOT/tests/bench/tsvdag_check.cpp
RUNS=()
if [ $# -gt 0 ]; then
	for m in "$@"; do for l in $LEVELS; do RUNS+=("$m $l"); done; done
else
	DATA=${VOXDAG_SHARED_DATA:-../shared/data}
	[ -d "$DATA" ] || { echo "vs_tsvdag: $DATA is absent and no MESH given; nothing to measure"; exit 0; }
	for l in $LEVELS; do
		for m in "$DATA"/*.ply; do RUNS+=("$m $l"); done
	done
	for l in $BUNNY_LEVELS; do RUNS+=("$DATA/stanford_bunny.ply $l"); done
fi
for tool in g++ make patch pkg-config jq /usr/bin/time; do
	command -v "$tool" >/dev/null || die "needs $tool (benchmark dependency, not a project one)"
done
for pc in absl_flat_hash_map assimp fmt spdlog tbb; do
	pkg-config --exists "$pc" 2>/dev/null ||
		die "needs the pkg-config module '$pc' (Debian: see the list at the top of this script)"
done
for h in CLI/App.hpp eigen3/Eigen/Eigen glm/glm.hpp nlohmann/json.hpp FreeImagePlus.h; do
	[ -f "/usr/include/$h" ] || die "needs /usr/include/$h (Debian: see the list at the top of this script)"
done
RH=$DEPS/robin-hood-hashing/src/include
MO=$DEPS/libmorton/include
MI=$DEPS/mio/include
[ -f "$RH/robin_hood.h" ] || die "cannot find '$RH/robin_hood.h': put a robin-hood-hashing checkout beside TSVDAG_DIR or set VS_TSVDAG_DEPS"
[ -f "$MO/libmorton/morton.h" ] || die "cannot find '$MO/libmorton/morton.h': put a libmorton checkout beside TSVDAG_DIR or set VS_TSVDAG_DEPS"
[ -f "$MI/mio/mmap.hpp" ] || die "cannot find '$MI/mio/mmap.hpp': put a mio checkout beside TSVDAG_DIR or set VS_TSVDAG_DEPS"
[ -f "$PATCH" ] || die "cannot find '$PATCH'"
for t in voxdag dag-verify; do
	[ -x "out/bin/$t" ] || die "out/bin/$t is missing: run make first"
done
mkdir -p "$BUILD" || die "cannot create '$BUILD'"
BUILD=$(cd "$BUILD" && pwd)

# ---- a patched copy of their tools (files replaced only when changed) ----
rm -rf "$BUILD/src.new" && mkdir -p "$BUILD/src.new" || die "cannot write '$BUILD/src.new'"
cp -R "$SRC/tools" "$BUILD/src.new/" || die "cannot copy '$SRC/tools'"
patch -s -d "$BUILD/src.new" -p1 < "$PATCH" || die "cannot apply '$PATCH' to '$SRC' (a newer checkout? the patch is for commit aa4a553)"
(cd "$BUILD/src.new" && find . -type f) | while read -r f; do
	if ! cmp -s "$BUILD/src.new/$f" "$BUILD/src/$f"; then
		mkdir -p "$(dirname "$BUILD/src/$f")" && cp "$BUILD/src.new/$f" "$BUILD/src/$f"
	fi
done
rm -rf "$BUILD/src.new"
cp -p "$CHECK_SRC" "$BUILD/src/tsvdag_check.cpp.new"
if cmp -s "$BUILD/src/tsvdag_check.cpp.new" "$BUILD/src/tsvdag_check.cpp"; then
	rm -f "$BUILD/src/tsvdag_check.cpp.new"
else
	mv "$BUILD/src/tsvdag_check.cpp.new" "$BUILD/src/tsvdag_check.cpp"
fi

# ---- build: svdag_encoding, voxelizer, tsvdag_check ----------------------
T=$BUILD/src/tools
cat > "$BUILD/Makefile" <<EOF
# written by tests/bench/vs_tsvdag.sh
CXX = g++
CXXFLAGS = -std=c++20 -O2 -DNDEBUG -fopenmp -mavx -mavx2 -mbmi2 -msse4.1 -w -MMD -MP \\
	-I$T/lib/include -I$T/lib/src -I$T/svdag_encoding/include -I$T/svdag_encoding/src \\
	-I$RH -I$MO -I$MI -I/usr/include/eigen3 \$(shell pkg-config --cflags spdlog fmt tbb assimp)
LDLIBS = -fopenmp \$(shell pkg-config --libs absl_flat_hash_map assimp spdlog fmt tbb) -lfreeimageplus -lfreeimage
LIB = $(cd "$T" && ls lib/src/*/*.cpp | grep -v encoded_octree | sed 's/\.cpp$/.o/' | tr '\n' ' ')
ENC = $(cd "$T" && ls svdag_encoding/src/*.cpp | sed 's/\.cpp$/.o/' | tr '\n' ' ')
VOX = $(cd "$T" && ls voxelizer/src/*.cpp | sed 's/\.cpp$/.o/' | tr '\n' ' ')
all: svdag_encoding voxelizer tsvdag_check
obj/%.o: $T/%.cpp
	@mkdir -p \$(dir \$@)
	\$(CXX) \$(CXXFLAGS) -c -o \$@ \$<
obj/tsvdag_check.o: $BUILD/src/tsvdag_check.cpp
	@mkdir -p \$(dir \$@)
	\$(CXX) \$(CXXFLAGS) -c -o \$@ \$<
svdag_encoding: \$(addprefix obj/,\$(ENC) \$(LIB))
	\$(CXX) -o \$@ \$^ \$(LDLIBS)
voxelizer: \$(addprefix obj/,\$(VOX) \$(LIB))
	\$(CXX) -o \$@ \$^ \$(LDLIBS)
tsvdag_check: obj/tsvdag_check.o \$(addprefix obj/,\$(filter-out %/transform_dag_encoding.o %/main.o,\$(ENC)) \$(LIB))
	\$(CXX) -o \$@ \$^ \$(LDLIBS)
-include \$(shell find obj -name '*.d' 2>/dev/null)
EOF
echo "vs_tsvdag: building the reference's tools in $BUILD (first time: ~10 min on 2 cores)"
nice -n 5 make -s -C "$BUILD" -j"${VS_TSVDAG_JOBS:-1}" > "$BUILD/build.log" 2>&1 ||
	die "cannot build the reference's tools (see $BUILD/build.log)"
ENCODER=$BUILD/svdag_encoding
VOXELIZER=$BUILD/voxelizer
CHECK=$BUILD/tsvdag_check

# ---- runs -----------------------------------------------------------------
summary=$BUILD/summary.txt
: > "$summary"
echo "vs_tsvdag: $(nproc) cores; theirs: svdag_encoding $FLAGS"
for run in "${RUNS[@]}"; do
	mesh=${run% *}; L=${run##* }
	[ -f "$mesh" ] || die "cannot open '$mesh': no such file"
	base=$(basename "$mesh"); base=${base%.*}
	mabs=$(cd "$(dirname "$mesh")" && pwd)/$(basename "$mesh")
	name=vs_tsvdag_$(echo "$base" | tr -c 'A-Za-z0-9_\n-' _)
	d=$BUILD/runs/$base-$L
	rm -rf "$d" && mkdir -p "$d" || die "cannot create '$d'"
	cat > "$d/ours.yaml" <<EOF
# written by tests/bench/vs_tsvdag.sh
version: 1
name: $name
input:
  mesh: $mabs
levels: $L
chunk_level: auto
resolutions: [$L]
outputs: $d/ours
resources:
  jobs: 2
  mem_budget: 8GiB
  job_mem_budget: 4GiB
jobs:
  vox:    {stage: voxelize}
  dag:    {stage: svo-to-dag, needs: [vox]}
  ssvdag: {stage: symmetry-merge, needs: [dag]}
  s48:    {stage: symmetry-merge, needs: [dag], group: 48}
  enc:    {stage: encode, needs: [dag, ssvdag, s48]}
EOF
	t0=$(date +%s.%N)
	if ! /usr/bin/time -f '%U %S' -o "$d/ours.time" nice -n 5 out/bin/voxdag run "$d/ours.yaml" -q > "$d/ours.log" 2>&1; then
		echo "vs_tsvdag: $base 2^$L: voxdag run failed (see $d/ours.log)"
		echo "$base $L FAIL" >> "$summary"
		continue
	fi
	ours_wall=$(awk -v a="$t0" -v b="$(date +%s.%N)" 'BEGIN { printf "%.2f", b - a }')
	ours_cpu=$(awk '{ printf "%.2f", $1 + $2 }' "$d/ours.time")
	enc=$d/ours/enc
	svdag=$enc/$name.svdag
	[ -f "$svdag" ] || die "voxdag wrote no '$svdag'"
	# report.csv: job,stage,processes,seconds,cpu_seconds,peak_rss_bytes,budget_bytes
	read -r ours_from_svdag ours_peak < <(awk -F, 'NR > 1 {
		if ($2 == "symmetry-merge" || $2 == "encode") s += $4
		if ($6 > p) p = $6 }
		END { printf "%.2f %.0f\n", s, p / 1024 }' "$d/ours/report.csv")
	read -r vox b_svdag b_ssvdag b_s48 n_svdag n_ssvdag n_s48 < <(jq -r '"\(.voxels) \(.bytes_svdag) \(.bytes_ssvdag) \(.bytes_ssvdag48) \(.nodes_svdag) \(.nodes_ssvdag) \(.nodes_ssvdag48)"' "$enc/$name.encode.stats.json")
	# the .svdag holds our voxels (decoded, compared with the SVO chunks)
	if out/bin/dag-verify -q "$svdag" "$d"/ours/vox/*.svo 2> "$d/verify.err"; then ours_ok=yes; else ours_ok=NO; fi

	# theirs: our .svdag -> their .svo (their voxelizer: svdag_encoding's
	# own .svdag input skips the toDAG() step and stops on an assertion)
	# -> .tdag16, each timed, svdag_encoding without its verification
	if ! (cd "$d" && /usr/bin/time -f '%e %M' -o "$d/convert.time" "$VOXELIZER" "$svdag" "$L" \
		--out "$d/their.svo" > "$d/convert.log" 2>&1); then
		echo "vs_tsvdag: $base 2^$L: their voxelizer failed on '$svdag' (see $d/convert.log)"
		echo "$base $L FAIL" >> "$summary"
		continue
	fi
	read -r conv_s conv_kib < "$d/convert.time"
	if ! (cd "$d" && /usr/bin/time -f '%e %M %U %S' -o "$d/their.time" nice -n 5 "$ENCODER" "$d/their.svo" \
		--out "$d/their.tdag16" --stats "$d/their.stats.json" $FLAGS --noverify > "$d/their.log" 2>&1); then
		echo "vs_tsvdag: $base 2^$L: svdag_encoding failed (see $d/their.log)"
		echo "$base $L FAIL" >> "$summary"
		continue
	fi
	read -r their_s their_kib their_u their_sys < "$d/their.time"
	their_cpu=$(awk -v u="$their_u" -v s="$their_sys" 'BEGIN { printf "%.2f", u + s }')
	their_file=$(stat -c %s "$d/their.tdag16")
	their_count=$(sed -n 's/.*Size in bytes: \([0-9]*\).*/\1/p' "$d/their.log" | tail -1)
	# their final nodes per level, the 4^3 masks (level 2) included
	their_nodes=$(jq '[.encoding_stats.levels[].num_nodes] | add' "$d/their.stats.json" 2>/dev/null || echo '?')
	# their nodes with symmetry and axis permutation only (before the
	# translation search), levels 2 (4^3 bricks) to the root
	their_nodes_st=$(sed -n 's/.*\] Reduced SVO \(nodes\|leaves\) from [0-9]* to \([0-9]*\) using.*/\2/p' "$d/their.log" |
		awk '{ s += $1 } END { print s + 0 }')
	# their reading of our .svdag: imported and written back by their voxelizer
	if (cd "$d" && "$VOXELIZER" "$svdag" "$L" --svdag "$d/their-roundtrip.svdag" > "$d/roundtrip.log" 2>&1) &&
	   diff=$(out/bin/dag-verify --diff --no-verify "$svdag" "$d/their-roundtrip.svdag" 2>> "$d/roundtrip.log") &&
	   [ "${diff%% *}" = differing_voxels=0 ]; then
		read_ok=yes
	else
		read_ok=NO
	fi
	# their .tdag16 as written, decoded against our .svdag
	if check=$("$CHECK" "$svdag" "$d/their.tdag16" 2> "$d/check.err"); then
		tdag_ok=yes
	else
		tdag_ok=NO
	fi
	echo "$check" > "$d/check.out"
	echo "vs_tsvdag: $base 2^$L: theirs $their_s s (+ $conv_s s .svdag -> .svo) $((their_kib / 1024)) MiB $their_file B; ours $ours_wall s ($ours_from_svdag s from the SVDAG) $((ours_peak / 1024)) MiB; $check"
	printf '%s %s %s %s %s %s %s %s %s %s %s %s %s %s %s %s %s %s %s %s %s %s %s %s %s\n' "$base" "$L" "$vox" \
		"$their_file" "$their_count" "$their_s" "$their_kib" "$b_svdag" "$b_ssvdag" "$b_s48" \
		"$ours_wall" "$ours_from_svdag" "$ours_peak" "$ours_ok" "$read_ok" "$tdag_ok" \
		"$conv_s" "$their_nodes_st" "$their_nodes" "$n_svdag" "$n_ssvdag" "$n_s48" "$conv_kib" "$their_cpu" "$ours_cpu" >> "$summary"
	# their logs and statistics stay (small); the scenes go
	[ "${VS_TSVDAG_KEEP:-0}" = 1 ] || rm -rf "$d/ours" "$d/their-roundtrip.svdag" "$d/their.svo"
done

echo
echo "bytes: theirs = their own count (TransformDAG16::sizeInBytes: nodes, 4^3 masks, pointer tables)"
echo "  and the .tdag16 file (adds its Huffman code tables and vector lengths); ours = encode's"
echo "  counted bytes (file minus header); ratios use the counted bytes"
echo "seconds: theirs = svdag_encoding from their .svo of our .svdag (+ their voxelizer's"
echo "  .svdag -> .svo conversion); ours = the whole pipeline from the mesh, and from the SVDAG"
echo "  (symmetry-merge 8 + 48 and encode jobs); CPU = user + system seconds (GNU time; ours: the"
echo "  runner and all its stages), steadier than wall time on a loaded machine; MiB = peak RSS"
echo "  of the largest process"
echo "checks: ours = our .svdag decoded equals our SVO chunks; read = their import of our .svdag,"
echo "  written back, equals it; tdag16 = their .tdag16 read back and decoded equals our voxels"
echo "  (voxel count of a full decode + every voxel of every non-empty 4^3 brick of ours)"
echo
awk 'function r(a, b) { return b > 0 ? sprintf("%.2f", a / b) : "-" }
BEGIN { print "| mesh | res | voxels | B theirs (.tdag16 file) | B .svdag | B .ssvdag | B .ssvdag48 | theirs/.ssvdag | .ssvdag48/theirs | their s (+conv) | our s mesh / SVDAG | their s / our SVDAG s | CPU s theirs / ours (mesh) | their MiB | our MiB | checked ours/read/tdag16 |"
	print "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|" }
$3 == "FAIL" { printf "| %s | 2^%s | failed |\n", $1, $2; next }
{ printf "| %s | 2^%d | %.0f | %.0f (%.0f) | %.0f | %.0f | %.0f | %s | %s | %.1f (+%.1f) | %.2f / %.2f | %s | %.1f / %.2f | %.0f | %.0f | %s/%s/%s |\n",
	$1, $2, $3, $5, $4, $8, $9, $10, r($5, $9), r($10, $5), $6, $17, $11, $12, r($6, $12),
	$24, $25, $7 / 1024, $13 / 1024, $14, $15, $16 }' "$summary"
echo
echo "nodes: theirs over levels 2 (4^3 bricks) to the root, with symmetry + axis permutation only"
echo "  and with translations too (their final DAG); ours over levels 0..L-1 (2^3 masks included,"
echo "  4^3 bricks not): the two count different levels, compare within a side"
echo
awk 'function r(a, b) { return b > 0 ? sprintf("%.2f", a / b) : "-" }
BEGIN { print "| mesh | res | their nodes sym+perm | their nodes +transl | +transl/sym+perm | our SVDAG | our SSVDAG | our 48 | 48/SSVDAG |"
	print "|---|---:|---:|---:|---:|---:|---:|---:|---:|" }
$3 == "FAIL" { next }
{ printf "| %s | 2^%d | %.0f | %.0f | %s | %.0f | %.0f | %.0f | %s |\n",
	$1, $2, $18, $19, r($19, $18), $20, $21, $22, r($22, $21) }' "$summary"
echo
echo "cores $(nproc), load $(cut -d' ' -f1-3 /proc/loadavg)"
