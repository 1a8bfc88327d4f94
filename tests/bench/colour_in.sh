#!/usr/bin/env bash
# The cost of colours in voxelize: the same mesh and depth with and without
# colours (--no-colours), wall seconds, voxels/s and peak memory from each
# run's voxelize.stats.json. Usage:
#   tests/bench/colour_in.sh [MESH] [LEVEL...]
# (default: ../shared/data/cessna_c172p.ply at 10 11 12; skipped when the
# mesh is absent). Run alone: it uses every core it is given (--threads).
set -u
cd "$(dirname "$0")/../.."
MESH=${1:-${VOXDAG_SHARED_DATA:-../shared/data}/cessna_c172p.ply}
shift || true
LEVELS=${*:-10 11 12}
THREADS=${THREADS:-$(nproc)}
OUT=out/bench/colour
if [ ! -f "$MESH" ]; then
	echo "colour_in: $MESH is absent; nothing to measure"
	exit 0
fi
mkdir -p "$OUT"
printf '%-22s %3s %-8s %3s %12s %8s %8s %14s %9s %9s\n' mesh L colours L0 voxels seconds colour_s 'voxels/s' 'peak MiB' '.col MiB'
for L in $LEVELS; do
	for mode in off on; do
		dir=$OUT/$(basename "$MESH" .ply)-$L-$mode
		flag=; [ $mode = off ] && flag=--no-colours
		if ! out/bin/voxelize "$MESH" -o "$dir" --levels "$L" -q \
			--threads "$THREADS" $flag; then
			echo "colour_in: voxelize failed at 2^$L ($mode)"
			continue
		fi
		s=$dir/voxelize.stats.json
		get() { sed -n "s/^ *\"$1\": \([0-9.e+]*\),*$/\1/p" "$s" | head -1; }
		col=$(du -cm "$dir"/*.col 2>/dev/null | tail -1 | cut -f1)
		printf '%-22s %3s %-8s %3s %12s %8.2f %8.2f %14.0f %9d %9s\n' \
			"$(basename "$MESH")" "$L" "$mode" "$(get chunk_level)" \
			"$(get voxels)" "$(get total)" "$(get seconds_colour_workers)" \
			"$(get voxels_per_second)" "$(( $(get peak_rss_bytes) >> 20 ))" "${col:-0}"
	done
done
