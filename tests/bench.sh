#!/usr/bin/env bash
# make bench: voxelize the shared scenes (../shared/data) at several depths
# and print throughput and peak memory. Skips cleanly when the data is
# absent. Numbers come from each run's voxelize.stats.json and GNU time.
set -u
cd "$(dirname "$0")/.."
DATA=${VOXDAG_SHARED_DATA:-../shared/data}
OUT=out/bench
if [ ! -d "$DATA" ]; then
	echo "bench: $DATA is absent; nothing to measure"
	exit 0
fi
mkdir -p "$OUT"
cores=$(nproc)
printf '%-26s %5s %5s %8s %12s %8s %14s %14s %10s\n' scene L L0 threads voxels seconds 'tri/s' 'voxels/s/core' 'peak MiB'
run() { # run SCENE LEVELS BUDGET
	local scene=$1 L=$2 budget=$3 dir=$OUT/$(basename "$1" .ply)-$2
	if ! /usr/bin/time -f "%M" -o "$OUT/time" \
		out/bin/voxelize "$DATA/$scene" -o "$dir" --levels "$L" \
		--mem-budget "$budget" -q; then
		echo "bench: voxelize $scene at 2^$L failed"
		return
	fi
	local s=$dir/voxelize.stats.json
	get() { sed -n "s/^  \"$1\": \([0-9.e+]*\),*$/\1/p" "$s"; }
	local secs threads
	secs=$(sed -n 's/^    "total": \([0-9.e+]*\)$/\1/p' "$s")
	threads=$(get threads)
	awk -v sc="$scene" -v L="$L" -v l0="$(get chunk_level)" -v th="$threads" \
		-v vox="$(get voxels)" -v t="$secs" -v tri="$(get triangles_read)" \
		-v kb="$(cat "$OUT/time")" -v cores="$cores" 'BEGIN {
		printf "%-26s %5d %5d %8d %12d %8.2f %14.0f %14.0f %10.0f\n",
			sc, L, l0, th, vox, t, tri / t, vox / t / (th < cores ? th : cores), kb / 1024 }'
	rm -rf "$dir"
}
run stanford_dragon.ply 10 2GiB
run stanford_dragon.ply 12 2GiB
run stanford_dragon.ply 14 2GiB
run fg_terrain_reykjavik.ply 14 2GiB
echo "bench: $cores cores; budget 2 GiB per process"
