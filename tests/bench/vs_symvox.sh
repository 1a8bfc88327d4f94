#!/usr/bin/env bash
# Side-by-side benchmark: voxdag against the SSVDAG reference code (SymVox,
# RvanderLaan/SVDAG-Compression, GPL-3), mesh -> SVDAG/SSVDAG encodings on
# the same meshes and depth, runs interleaved (SymVox, voxdag, SymVox, ...).
#
#   tests/bench/vs_symvox.sh /path/to/SVDAG-Compression [LEVEL] [MESH...]
#
# LEVEL defaults to 12; MESH defaults to the dragon, bunny and cruiser of
# ../shared/data. The reference's command-line builder (svbuilder, not the
# OpenGL viewer) is compiled with g++ OUTSIDE the repository tree's sources,
# into $VS_SYMVOX_BUILD (default out/symvox-build/); nothing of it is ever
# committed. Its authors did not publish the small CRS4 "sl" headers it
# includes, nor is liblas needed for meshes: this script writes minimal
# stand-ins for exactly what svbuilder uses into the build directory.
# SymVox reads only ASCII OBJ, so PLY meshes are converted once (python3).
#
# Environment: VS_SYMVOX_RUNS (timed runs per tool and mesh, default 3),
# VS_SYMVOX_STEP (svbuilder numBuildSteps, default 0 = its monolithic
# single-thread build; >0 builds subtrees in parallel with OpenMP),
# VS_SYMVOX_BUILD (build and scratch directory).
# SymVox gets one untimed warm-up run per mesh when its binary mesh cache
# (OBJ.bincache) is absent, to write it, so the timed runs load a binary mesh as voxdag does.
# Wall time and peak RSS come from GNU time (/usr/bin/time); voxdag's peak is
# the largest single process of its pipeline (jobs run as separate processes).
# The figures are medians and are noisy on a shared machine.
# Not part of make test or make bench.
set -u
cd "$(dirname "$0")/../.."
ROOT=$(pwd)
die() { echo "vs_symvox: $*" >&2; exit 1; }
if [ $# -lt 1 ] || [ "$1" = -h ] || [ "$1" = --help ]; then
	echo "usage: tests/bench/vs_symvox.sh SVDAG-COMPRESSION-DIR [LEVEL] [MESH...]" >&2
	exit 2
fi
SRC=$(cd "$1" 2>/dev/null && pwd) || die "cannot open '$1': no such directory"
shift
[ -f "$SRC/src/svbuilder/main.cpp" ] || die "cannot find '$SRC/src/svbuilder/main.cpp': not a SVDAG-Compression checkout"
LEVEL=${1:-12}
[ $# -gt 0 ] && shift
case $LEVEL in ''|*[!0-9]*) die "bad LEVEL '$LEVEL'";; esac
if [ $# -gt 0 ]; then
	MESHES=("$@")
else
	DATA=${VOXDAG_SHARED_DATA:-../shared/data}
	[ -d "$DATA" ] || { echo "vs_symvox: $DATA is absent and no MESH given; nothing to measure"; exit 0; }
	MESHES=("$DATA/stanford_dragon.ply" "$DATA/stanford_bunny.ply" "$DATA/cg57_cruiser.ply")
fi
RUNS=${VS_SYMVOX_RUNS:-3}
STEP=${VS_SYMVOX_STEP:-0}
BUILD=${VS_SYMVOX_BUILD:-out/symvox-build}
for tool in g++ python3 /usr/bin/time; do
	command -v "$tool" >/dev/null || die "needs $tool (benchmark dependency, not a project one)"
done
mkdir -p "$BUILD" || die "cannot create '$BUILD'"
BUILD=$(cd "$BUILD" && pwd)

# ---- stand-ins for the unpublished headers ---------------------------------
INC=$BUILD/include
mkdir -p "$INC/sl" "$INC/liblas"
cat > "$INC/sl/standin.hpp.new" <<'EOF'
// Minimal stand-in for the parts of CRS4's unpublished "sl" library that
// SymVox's svbuilder uses. Written by voxdag's tests/bench/vs_symvox.sh.
#pragma once
#include <cstdint>
#include <cstddef>
#include <cmath>
#include <chrono>
#include <string>
#include <tuple>
#include <ostream>
#include <algorithm>
#include <limits>
#include <map>
#include <set>
#include <vector>
#include <unordered_map>
#include <iostream>
#include <sstream>
#include <cstdio>
#include <cstring>
#include <cstdlib>
#include <functional>
#include <memory>
#include <type_traits>
namespace sl {
using std::int8_t; using std::int16_t; using std::int32_t; using std::int64_t;
using std::uint8_t; using std::uint16_t; using std::uint32_t; using std::uint64_t;
using std::tie;
template <class T> inline const T &min(const T &a, const T &b) { return b < a ? b : a; }
template <class T> inline const T &max(const T &a, const T &b) { return a < b ? b : a; }

enum { K_VEC = 0, K_PT = 1, K_COL = 2 };
template <std::size_t N, class T, int K> struct fsa {
	T v[N];
	fsa() { for (std::size_t i = 0; i < N; i++) v[i] = T(0); }
	template <class... A, class = typename std::enable_if<sizeof...(A) == N && (N > 1)>::type>
	fsa(A... a) : v{static_cast<T>(a)...} {}
	template <int K2> fsa(const fsa<N, T, K2> &o) { for (std::size_t i = 0; i < N; i++) v[i] = o.v[i]; }
	T &operator[](std::size_t i) { return v[i]; }
	const T &operator[](std::size_t i) const { return v[i]; }
	T *to_pointer() { return v; }
	const T *to_pointer() const { return v; }
	fsa<N, T, K_VEC> as_vector() const { return *this; }
	fsa<N, T, K_PT> as_point() const { return *this; }
	T dot(const fsa &o) const { T s = 0; for (std::size_t i = 0; i < N; i++) s += v[i] * o.v[i]; return s; }
	fsa cross(const fsa &o) const {
		return fsa(v[1] * o.v[2] - v[2] * o.v[1], v[2] * o.v[0] - v[0] * o.v[2], v[0] * o.v[1] - v[1] * o.v[0]);
	}
	T two_norm_squared() const { return dot(*this); }
	T two_norm() const { return std::sqrt(two_norm_squared()); }
	fsa ok_normalized() const { T n = two_norm(); fsa r = *this; if (n > T(0)) for (auto &x : r.v) x /= n; return r; }
	T distance_to(const fsa &o) const { T s = 0; for (std::size_t i = 0; i < N; i++) s += (v[i] - o.v[i]) * (v[i] - o.v[i]); return std::sqrt(s); }
	template <int K2> fsa &operator+=(const fsa<N, T, K2> &o) { for (std::size_t i = 0; i < N; i++) v[i] += o.v[i]; return *this; }
	template <int K2> fsa &operator-=(const fsa<N, T, K2> &o) { for (std::size_t i = 0; i < N; i++) v[i] -= o.v[i]; return *this; }
	template <class S> fsa &operator*=(S s) { for (auto &x : v) x *= s; return *this; }
	template <class S> fsa &operator/=(S s) { for (auto &x : v) x /= s; return *this; }
	fsa operator-() const { fsa r = *this; for (auto &x : r.v) x = -x; return r; }
	bool operator==(const fsa &o) const { for (std::size_t i = 0; i < N; i++) if (v[i] != o.v[i]) return false; return true; }
	bool operator!=(const fsa &o) const { return !(*this == o); }
	bool operator<(const fsa &o) const { return std::lexicographical_compare(v, v + N, o.v, o.v + N); }
};
template <std::size_t N, class T, int K1, int K2>
fsa<N, T, K1> operator+(fsa<N, T, K1> a, const fsa<N, T, K2> &b) { return a += b; }
template <std::size_t N, class T, int K1, int K2>
fsa<N, T, (K1 == K_PT && K2 == K_PT) ? K_VEC : K1> operator-(const fsa<N, T, K1> &a, const fsa<N, T, K2> &b) {
	fsa<N, T, (K1 == K_PT && K2 == K_PT) ? K_VEC : K1> r(a); r -= b; return r;
}
template <std::size_t N, class T, int K, class S, class = typename std::enable_if<std::is_arithmetic<S>::value>::type>
fsa<N, T, K> operator*(fsa<N, T, K> a, S s) { return a *= s; }
template <std::size_t N, class T, int K, class S, class = typename std::enable_if<std::is_arithmetic<S>::value>::type>
fsa<N, T, K> operator*(S s, fsa<N, T, K> a) { return a *= s; }
template <std::size_t N, class T, int K, class S, class = typename std::enable_if<std::is_arithmetic<S>::value>::type>
fsa<N, T, K> operator/(fsa<N, T, K> a, S s) { return a /= s; }
template <std::size_t N, class T, int K> std::ostream &operator<<(std::ostream &os, const fsa<N, T, K> &a) {
	os << "[";
	for (std::size_t i = 0; i < N; i++) os << (i ? " " : "") << a.v[i];
	return os << "]";
}
template <std::size_t N, class T> using fixed_size_vector = fsa<N, T, K_VEC>;
template <std::size_t N, class T> using fixed_size_point = fsa<N, T, K_PT>;
typedef fsa<2, float, K_VEC> vector2f; typedef fsa<3, float, K_VEC> vector3f;
typedef fsa<3, double, K_VEC> vector3d; typedef fsa<4, float, K_VEC> vector4f;
typedef fsa<2, float, K_PT> point2f; typedef fsa<3, float, K_PT> point3f;
typedef fsa<3, double, K_PT> point3d; typedef fsa<3, float, K_COL> color3f;

template <std::size_t N, class T> struct axis_aligned_box {
	typedef fsa<N, T, K_PT> point_t;
	point_t c[2];
	axis_aligned_box() { to_empty(); }
	axis_aligned_box(const point_t &a, const point_t &b) { c[0] = a; c[1] = b; }
	point_t &operator[](std::size_t i) { return c[i]; }
	const point_t &operator[](std::size_t i) const { return c[i]; }
	void to_empty() {
		for (std::size_t i = 0; i < N; i++) { c[0][i] = std::numeric_limits<T>::max(); c[1][i] = -std::numeric_limits<T>::max(); }
	}
	bool is_empty() const { for (std::size_t i = 0; i < N; i++) if (c[0][i] > c[1][i]) return true; return false; }
	void merge(const point_t &p) {
		for (std::size_t i = 0; i < N; i++) { c[0][i] = std::min(c[0][i], p[i]); c[1][i] = std::max(c[1][i], p[i]); }
	}
	void merge(const axis_aligned_box &b) { if (!b.is_empty()) { merge(b.c[0]); merge(b.c[1]); } }
	point_t center() const { point_t r; for (std::size_t i = 0; i < N; i++) r[i] = (c[0][i] + c[1][i]) / T(2); return r; }
	fsa<N, T, K_VEC> half_side_lengths() const { fsa<N, T, K_VEC> r; for (std::size_t i = 0; i < N; i++) r[i] = (c[1][i] - c[0][i]) / T(2); return r; }
	fsa<N, T, K_VEC> diagonal() const { return c[1] - c[0]; }
	bool contains(const point_t &p) const { for (std::size_t i = 0; i < N; i++) if (p[i] < c[0][i] || p[i] > c[1][i]) return false; return true; }
};
template <std::size_t N, class T> std::ostream &operator<<(std::ostream &os, const axis_aligned_box<N, T> &b) { return os << b.c[0] << " " << b.c[1]; }
typedef axis_aligned_box<3, float> aabox3f; typedef axis_aligned_box<3, double> aabox3d;

struct time_duration {
	int64_t ns = 0;
	time_duration() {}
	explicit time_duration(int64_t n) : ns(n) {}
	int64_t as_nanoseconds() const { return ns; }
	int64_t as_microseconds() const { return ns / 1000; }
	int64_t as_milliseconds() const { return ns / 1000000; }
	double as_seconds() const { return ns * 1e-9; }
	time_duration operator+(const time_duration &o) const { return time_duration(ns + o.ns); }
	time_duration operator-(const time_duration &o) const { return time_duration(ns - o.ns); }
	time_duration &operator+=(const time_duration &o) { ns += o.ns; return *this; }
	time_duration &operator-=(const time_duration &o) { ns -= o.ns; return *this; }
	template <class S> time_duration operator*(S s) const { return time_duration(int64_t(ns * s)); }
	template <class S> time_duration operator/(S s) const { return time_duration(int64_t(ns / s)); }
};
struct time_point {
	int64_t ns = 0;
	time_duration operator-(const time_point &o) const { return time_duration(ns - o.ns); }
};
struct real_time_clock {
	time_point t0;
	real_time_clock() { restart(); }
	static time_point now() {
		time_point t;
		t.ns = std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch()).count();
		return t;
	}
	void restart() { t0 = now(); }
	time_duration elapsed() const { return now() - t0; }
};
inline std::string hr_(double x, const char *const *units, int n, double step, int prec) {
	int u = 0;
	while (std::fabs(x) >= step && u < n - 1) { x /= step; u++; }
	char b[64];
	snprintf(b, sizeof b, "%.*f%s", u ? prec : 0, x, units[u]);
	return b;
}
inline std::string human_readable_duration(const time_duration &d) {
	char b[64];
	snprintf(b, sizeof b, "%.3fs", d.as_seconds());
	return b;
}
inline std::string human_readable_size(std::size_t n) {
	static const char *const u[] = {"B", "KB", "MB", "GB", "TB"};
	return hr_((double)n, u, 5, 1024.0, 2);
}
inline std::string human_readable_quantity(std::size_t n) {
	static const char *const u[] = {"", "K", "M", "G", "T"};
	return hr_((double)n, u, 5, 1000.0, 2);
}
inline std::string pathname_directory_separators() { return "/"; }
inline std::string pathname_directory(const std::string &p) {
	std::size_t k = p.find_last_of('/');
	return k == std::string::npos ? std::string(".") : p.substr(0, k);
}
inline std::string pathname_base(const std::string &p) {
	std::size_t k = p.find_last_of('/');
	return k == std::string::npos ? p : p.substr(k + 1);
}
inline std::string pathname_without_extension(const std::string &p) {
	std::size_t k = p.find_last_of('.'), s = p.find_last_of('/');
	return (k == std::string::npos || (s != std::string::npos && k < s)) ? p : p.substr(0, k);
}
}
EOF
for h in fixed_size_point fixed_size_vector axis_aligned_box clock cstdint \
	external_array linear_map_factory projective_map rigid_body_map; do
	printf '#pragma once\n#include "standin.hpp"\n' > "$INC/sl/$h.hpp.new"
done
cat > "$INC/liblas/liblas.hpp.new" <<'EOF'
// Stand-in: LAS input is not used by the benchmark (it feeds OBJ files).
#pragma once
#include <istream>
#include <stdexcept>
namespace liblas {
struct Header { unsigned GetPointRecordsCount() const { return 0; } };
struct Point { double GetX() const { return 0; } double GetY() const { return 0; } double GetZ() const { return 0; } };
struct Reader {
	Header h; Point p;
	const Header &GetHeader() const { return h; }
	bool ReadNextPoint() { return false; }
	const Point &GetPoint() const { return p; }
};
struct ReaderFactory {
	Reader CreateWithStream(std::istream &) { throw std::runtime_error("LAS input is not supported by this build"); }
};
}
EOF
# replace a header only when its text changed, so objects are not rebuilt
for f in "$INC"/sl/*.new "$INC"/liblas/*.new; do
	if cmp -s "$f" "${f%.new}"; then rm -f "$f"; else mv "$f" "${f%.new}"; fi
done

# ---- build svbuilder (only when a source or a stand-in changed) ------------
SVB=$BUILD/svbuilder
mkdir -p "$BUILD/obj"
objs=()
for src in "$SRC"/src/symvox/*.cpp "$SRC/src/svbuilder/main.cpp"; do
	o=$BUILD/obj/$(basename "$(dirname "$src")")_$(basename "$src" .cpp).o
	objs+=("$o")
	if [ ! -f "$o" ] || [ "$src" -nt "$o" ] || [ "$INC/sl/standin.hpp" -nt "$o" ]; then
		echo "vs_symvox: compiling $src"
		nice g++ -std=c++14 -O3 -DNDEBUG -fopenmp -w -I "$SRC/src" -I "$INC" \
			-c -o "$o" "$src" || die "cannot compile '$src'"
	fi
done
if [ ! -x "$SVB" ] || [ -n "$(find "$BUILD/obj" -newer "$SVB" -name '*.o')" ]; then
	g++ -fopenmp -o "$SVB" "${objs[@]}" || die "cannot link svbuilder"
fi

[ -x out/bin/voxdag ] || die "out/bin/voxdag is missing: run make first"

# ---- PLY -> ASCII OBJ for SymVox -------------------------------------------
cat > "$BUILD/ply2obj.py" <<'EOF'
import struct, sys
src, dst = sys.argv[1], sys.argv[2]
f = open(src, 'rb')
if f.readline().strip() != b'ply':
    sys.exit("ply2obj: cannot read '%s': not a PLY file" % src)
fmt, elems = None, []
while True:
    w = f.readline().split()
    if not w:
        continue
    if w[0] == b'end_header':
        break
    if w[0] == b'format':
        fmt = w[1].decode()
    elif w[0] == b'element':
        elems.append([w[1].decode(), int(w[2]), []])
    elif w[0] == b'property':
        elems[-1][2].append([x.decode() for x in w[1:]])
T = {'char': 'b', 'int8': 'b', 'uchar': 'B', 'uint8': 'B', 'short': 'h', 'int16': 'h',
     'ushort': 'H', 'uint16': 'H', 'int': 'i', 'int32': 'i', 'uint': 'I', 'uint32': 'I',
     'float': 'f', 'float32': 'f', 'double': 'd', 'float64': 'd'}
end = {'binary_little_endian': '<', 'binary_big_endian': '>'}.get(fmt)
out = open(dst + '.tmp', 'w')
if fmt == 'ascii':
    toks = iter(f.read().split())
for name, n, props in elems:
    if end and all(p[0] != 'list' for p in props):
        st = struct.Struct(end + ''.join(T[p[0]] for p in props))
        names = [p[-1] for p in props]
        buf = f.read(st.size * n)
        ix = [names.index(c) for c in 'xyz'] if name == 'vertex' else None
        if ix:
            out.write(''.join('v %.9g %.9g %.9g\n' % (r[ix[0]], r[ix[1]], r[ix[2]])
                              for r in st.iter_unpack(buf)))
        continue
    lines = []
    for _ in range(n):
        vals = []
        for p in props:
            if p[0] == 'list':
                if end:
                    c = struct.unpack(end + T[p[1]], f.read(struct.calcsize(T[p[1]])))[0]
                    v = struct.unpack(end + T[p[2]] * c, f.read(struct.calcsize(T[p[2]]) * c))
                else:
                    c = int(next(toks)); v = [int(next(toks)) for _ in range(c)]
                vals.append((p[-1], v))
            elif end:
                vals.append((p[-1], struct.unpack(end + T[p[0]], f.read(struct.calcsize(T[p[0]])))[0]))
            else:
                vals.append((p[-1], float(next(toks))))
        d = dict(vals)
        if name == 'vertex':
            lines.append('v %.9g %.9g %.9g\n' % (d['x'], d['y'], d['z']))
        elif name == 'face':
            v = d.get('vertex_indices', d.get('vertex_index'))
            for k in range(1, len(v) - 1):
                lines.append('f %d %d %d\n' % (v[0] + 1, v[k] + 1, v[k + 1] + 1))
    out.write(''.join(lines))
out.close()
import os
os.rename(dst + '.tmp', dst)
EOF

med() { sort -g | awk '{a[NR] = $1} END {print (NR % 2) ? a[(NR + 1) / 2] : (a[NR / 2] + a[NR / 2 + 1]) / 2}'; }
summary=$BUILD/summary.txt
: > "$summary"
echo "vs_symvox: $(nproc) cores, level $LEVEL, $RUNS timed runs each, svbuilder numBuildSteps $STEP"
for mesh in "${MESHES[@]}"; do
	[ -f "$mesh" ] || die "cannot open '$mesh': no such file"
	base=$(basename "$mesh"); base=${base%.*}
	mdir=$BUILD/meshes; mkdir -p "$mdir"
	case $mesh in
	*.obj|*.OBJ) obj=$mdir/$base.obj; [ -f "$obj" ] || cp "$mesh" "$obj";;
	*.ply|*.PLY) obj=$mdir/$base.obj
		if [ ! -f "$obj" ] || [ "$mesh" -nt "$obj" ]; then
			echo "vs_symvox: converting $mesh to OBJ"
			rm -f "$obj.bincache"
			python3 "$BUILD/ply2obj.py" "$mesh" "$obj" || die "cannot convert '$mesh'"
		fi;;
	*) die "cannot use '$mesh': SymVox reads OBJ; this script converts PLY only";;
	esac
	mabs=$(cd "$(dirname "$mesh")" && pwd)/$(basename "$mesh")
	name=vs_symvox_$(echo "$base" | tr -c 'A-Za-z0-9_\n-' _)
	vout=$BUILD/voxdag/$base-$LEVEL
	yaml=$BUILD/voxdag/$base-$LEVEL.yaml
	mkdir -p "$BUILD/voxdag"
	cat > "$yaml" <<EOF
# written by tests/bench/vs_symvox.sh
version: 1
name: $name
input:
  mesh: $mabs
levels: $LEVEL
chunk_level: auto
resolutions: [$LEVEL]
outputs: $vout
resources:
  jobs: 2
  mem_budget: 8GiB
  job_mem_budget: 4GiB
jobs:
  voxelize: {stage: voxelize}
  svdag:    {stage: svo-to-dag, needs: [voxelize]}
  ssvdag:   {stage: symmetry-merge, needs: [svdag]}
  encode:   {stage: encode, needs: [svdag, ssvdag]}
EOF
	run_dir=$BUILD/run; mkdir -p "$run_dir"
	symvox() { # symvox LOG TIMEFILE
		(cd "$run_dir" && /usr/bin/time -f '%e %M' -o "$2" "$SVB" "$obj" "$LEVEL" "$STEP" >"$1" 2>&1)
		local rc=$?
		rm -f "$mdir/${base}_$LEVEL"*.*svdag "$mdir/${base}_$LEVEL"*.svo
		return $rc
	}
	if [ ! -f "$obj.bincache" ]; then
		echo "vs_symvox: $base: SymVox warm-up (writes its binary mesh cache)"
		symvox "$BUILD/$base.symvox.log" "$BUILD/time" || die "svbuilder failed on '$obj' (see $BUILD/$base.symvox.log)"
	fi
	cat "$mesh" > /dev/null
	: > "$BUILD/$base.a"; : > "$BUILD/$base.b"
	for r in $(seq 1 "$RUNS"); do
		symvox "$BUILD/$base.symvox.log" "$BUILD/time" || die "svbuilder failed on '$obj' (see $BUILD/$base.symvox.log)"
		cat "$BUILD/time" >> "$BUILD/$base.a"
		rm -rf "$vout"
		/usr/bin/time -f '%e %M' -o "$BUILD/time" out/bin/voxdag run "$yaml" -q \
			>"$BUILD/$base.voxdag.log" 2>&1 || die "voxdag run '$yaml' failed (see $BUILD/$base.voxdag.log)"
		cat "$BUILD/time" >> "$BUILD/$base.b"
		echo "vs_symvox: $base run $r: SymVox $(cat "$BUILD/$base.a" | tail -1 | awk '{printf "%.2f s %.0f MiB", $1, $2 / 1024}'), voxdag $(tail -1 "$BUILD/$base.b" | awk '{printf "%.2f s %.0f MiB", $1, $2 / 1024}')"
	done
	# SymVox's own counts: "Voxels: 1.2M (N)", "DAG Nodes: ... (N)", "SDAG Nodes: ... (N)"
	sv() { sed -n "s/^$1:.*(\([0-9]*\))$/\1/p" "$BUILD/$base.symvox.log" | tail -1; }
	read -r vv vd vs < <(python3 - "$vout/encode/$name.tables.json" "$LEVEL" <<'EOF'
import json, sys
t = json.load(open(sys.argv[1]))
r = [r for r in t['table2'] if r['levels'] == int(sys.argv[2])][0]
print(r['voxels'], r['nodes_svdag'], r['nodes_ssvdag'])
EOF
	)
	printf '%s %s %s %s %s %s %s %s %s %s %s %s\n' "$base" "$LEVEL" \
		"$(cut -d' ' -f1 "$BUILD/$base.a" | med)" "$(cut -d' ' -f1 "$BUILD/$base.b" | med)" \
		"$(cut -d' ' -f2 "$BUILD/$base.a" | med)" "$(cut -d' ' -f2 "$BUILD/$base.b" | med)" \
		"$(sv Voxels)" "$vv" "$(sv 'DAG Nodes')" "$vd" "$(sv 'SDAG Nodes')" "$vs" >> "$summary"
	rm -rf "$vout"
done

echo
echo "median of $RUNS interleaved runs; wall s and peak MiB (GNU time); ratio = SymVox / voxdag"
awk 'function same(a, b) { return a == b ? "agree" : "DIFFER" }
BEGIN { printf "%-18s %2s %8s %8s %6s %8s %8s %6s  %-34s %-30s %-30s\n", "mesh", "L",
	"SymVox s", "voxdag s", "ratio", "SymVox M", "voxdag M", "ratio",
	"voxels SymVox/voxdag", "SVDAG nodes SymVox/voxdag", "SSVDAG nodes SymVox/voxdag" }
{ printf "%-18s %2d %8.2f %8.2f %5.1fx %8.0f %8.0f %5.1fx  %-34s %-30s %-30s\n", $1, $2,
	$3, $4, $3 / $4, $5 / 1024, $6 / 1024, $5 / $6,
	$7 "/" $8 " " same($7, $8), $9 "/" $10 " " same($9, $10), $11 "/" $12 " " same($11, $12) }' "$summary"
echo "(SymVox numBuildSteps $STEP; its node counts are its own GeomOctree stats, voxdag's are"
echo " encode's table 2: distinct nodes over levels 0..L-1; the two may count leaves differently)"
