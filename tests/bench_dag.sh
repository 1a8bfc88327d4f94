#!/usr/bin/env bash
# Benchmark of svo-to-dag and symmetry-merge on the shared scenes: voxelize
# (budget-chosen L0, or the L0 given), build a DAG per chunk, merge 8
# siblings at a time to the root, symmetry-merge the root, verify. Prints
# voxels/s per core of each stage (build time, one thread), peak RSS,
# per-level node counts and the SSVDAG/SVDAG node ratio.
#   tests/bench_dag.sh [SCENE LEVELS [L0]]...   (default: dragon 10, 12)
set -u
cd "$(dirname "$0")/.."
DATA=${VOXDAG_SHARED_DATA:-../shared/data}
BIN=out/bin
OUT=out/bench-dag
[ -d "$DATA" ] || { echo "bench_dag: $DATA is absent; nothing to measure"; exit 0; }
mkdir -p "$OUT"

get() { tr -d '\n ' < "$2" | grep -o "\"$1\":[^,}]*" | head -1 | cut -d: -f2; }
arr() { tr -d '\n ' < "$2" | grep -o "\"$1\":\[[^]]*\]" | cut -d: -f2; }
peak=0
timed() { # runs a command, tracking the largest peak RSS (KiB)
	/usr/bin/time -f %M -o "$OUT/time" "$@" || return 1
	local k; k=$(cat "$OUT/time")
	[ "$k" -gt "$peak" ] && peak=$k
	return 0
}
cell_of() { local b=${1##*/}; b=${b%.*}; echo $((16#${b##*-})); }
chunk_name() { local d=$(((3 * $1 + 3) / 4)); [ $d -lt 1 ] && d=1; printf "chunk-L%d-%0*x.%s" "$1" "$d" "$2" "$3"; }
sum_build() { local s=0 f; for f in "$@"; do s=$(awk -v a="$s" -v b="$(get seconds_build "$f")" 'BEGIN{print a+b}'); done; echo "$s"; }

bench() { # SCENE LEVELS [L0]
	local scene=$1 L=$2 l0=${3:-} dir=$OUT/$(basename "$1" .ply)-$2
	rm -rf "$dir"
	peak=0
	timed $BIN/voxelize "$DATA/$scene" -o "$dir" --levels "$L" ${l0:+--chunk-level $l0} -q || { echo "voxelize failed"; return; }
	local vpeak=$peak; peak=0
	local L0; L0=$(get chunk_level "$dir/voxelize.stats.json")
	local vox; vox=$(get voxels "$dir/voxelize.stats.json")
	local f
	for f in "$dir"/chunk-L$L0-*.svo; do
		timed $BIN/svo-to-dag -q -j 1 "$f" -o "${f%.svo}.dag" || { echo "svo-to-dag failed"; return; }
	done
	local t_chunks; t_chunks=$(sum_build "$dir"/chunk-L$L0-*.dag.stats.json)
	local l=$L0 t_merge=0
	while [ "$l" -gt 0 ]; do
		local -A g=()
		for f in "$dir"/chunk-L$l-*.dag; do g[$(($(cell_of "$f") >> 3))]+="$f "; done
		for p in "${!g[@]}"; do
			# shellcheck disable=SC2086
			timed $BIN/svo-to-dag -q -j 1 --merge ${g[$p]} -o "$dir/$(chunk_name $((l - 1)) "$p" dag)" || return
		done
		unset g
		l=$((l - 1))
		t_merge=$(awk -v a="$t_merge" -v b="$(sum_build "$dir"/chunk-L$l-*.dag.stats.json)" 'BEGIN{print a+b}')
	done
	local dpeak=$peak; peak=0
	timed $BIN/symmetry-merge -q -j 1 "$dir/chunk-L0-0.dag" -o "$dir/root.ssvdag" || return
	local speak=$peak
	timed $BIN/dag-verify "$dir/root.ssvdag" "$dir"/chunk-L$L0-*.svo || echo "VERIFY FAILED"
	local dn sn
	dn=$(get nodes "$dir/chunk-L0-0.dag.stats.json")
	sn=$(get nodes "$dir/root.ssvdag.stats.json")
	local ts; ts=$(get seconds_build "$dir/root.ssvdag.stats.json")
	echo "== $scene 2^$L L0=$L0: $vox voxels"
	awk -v v="$vox" -v a="$t_chunks" -v m="$t_merge" -v s="$ts" -v dp="$dpeak" -v sp="$speak" -v vp="$vpeak" 'BEGIN {
		printf "  svo-to-dag:     %.3f s chunks + %.3f s merges = %.1f M voxels/s/core, peak RSS %.0f MiB\n", a, m, v / (a + m) / 1e6, dp / 1024
		printf "  symmetry-merge: %.3f s = %.1f M voxels/s/core, peak RSS %.0f MiB (voxelize peak %.0f MiB)\n", s, v / s / 1e6, sp / 1024, vp / 1024 }'
	echo "  SVDAG  nodes per level $(arr level_nodes "$dir/chunk-L0-0.dag.stats.json") = $dn"
	echo "  SSVDAG nodes per level $(arr level_nodes "$dir/root.ssvdag.stats.json") = $sn"
	awk -v a="$sn" -v b="$dn" 'BEGIN { printf "  SSVDAG/SVDAG nodes %.3f\n", a / b }'
	rm -rf "$dir"
}

if [ $# -eq 0 ]; then
	set -- stanford_dragon.ply 10 stanford_dragon.ply 12
fi
while [ $# -ge 2 ]; do
	if [ $# -ge 3 ] && [[ $3 =~ ^[0-9]+$ ]]; then bench "$1" "$2" "$3"; shift 3
	else bench "$1" "$2"; shift 2; fi
done
