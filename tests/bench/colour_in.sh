#!/usr/bin/env bash
# The cost of colours in voxelize: the same mesh and depth with and without
# colours (--no-colours), as CPU seconds (user + sys, GNU time: they hold
# up under shared load better than wall time), their ratio, peak memory,
# and, from each run's voxelize.stats.json, the voxels and the colour
# pass's wall seconds summed over its workers. Usage:
#   tests/bench/colour_in.sh              the colour benchmark's scenes
#   tests/bench/colour_in.sh MESH LEVEL...   one mesh at those depths
# The scenes (issue 37 asks for at most 1.5x on the first three): TORCS
# brondehach at 2^13, FlightGear CG-57 at 2^12 (config/fetch-colour-
# scenes.sh into $VOXDAG_DATA, else out/data), the Reykjavik terrain at
# 2^14 (vertex colours; ../shared/data), Truman at 2^12 and the bundled
# spider at 2^10; an absent one is skipped with one line. THREADS (default
# 1: CPU seconds of one thread are the steadiest) is passed as --threads.
set -u
cd "$(dirname "$0")/../.."
THREADS=${THREADS:-1}
DATA=${VOXDAG_DATA:-out/data}
SHARED=${VOXDAG_SHARED_DATA:-../shared/data}
OUT=out/bench/colour
mkdir -p "$OUT"

# one run: prints "cpu_seconds peak_kib voxels colour_seconds", or fails
one() { # one MESH LEVEL DIR [FLAG]
	local dir=$3 s
	rm -rf "$dir"
	/usr/bin/time -f "%U %S %M" -o "$OUT/time" out/bin/voxelize "$1" \
		-o "$dir" --levels "$2" -q --threads "$THREADS" ${4:+"$4"} \
		2> "$OUT/err" || return 1
	s=$dir/voxelize.stats.json
	read -r u sy kib < "$OUT/time"
	awk -v u="$u" -v s="$sy" -v k="$kib" \
		-v v="$(sed -n 's/^  "voxels": \([0-9]*\),*$/\1/p' "$s")" \
		-v c="$(sed -n 's/^  "seconds_colour_workers": \([0-9.e+-]*\),*$/\1/p' "$s")" \
		'BEGIN { print u + s, k, v, c }'
	rm -rf "$dir"
}

printf '%-24s %3s %12s %9s %9s %7s %9s %9s %9s\n' mesh L voxels 'cpu off' \
	'cpu on' ratio 'MiB off' 'MiB on' 'colour wall'
row() { # row MESH LEVEL
	local name off on
	name=$(basename "$1")
	if [ ! -f "$1" ]; then
		echo "colour_in: $1 is absent; $name skipped"
		return
	fi
	if ! off=$(one "$1" "$2" "$OUT/$name-$2-off" --no-colours) ||
	   ! on=$(one "$1" "$2" "$OUT/$name-$2-on"); then
		echo "colour_in: voxelize $name at 2^$2 failed: $(head -1 "$OUT/err")"
		return
	fi
	echo "$off $on" | awk -v n="$name" -v L="$2" '{
		printf "%-24s %3d %12.0f %9.2f %9.2f %6.2fx %9.0f %9.0f %9.2f\n",
			n, L, $7, $1, $5, $5 / $1, $2 / 1024, $6 / 1024, $8 }'
}

if [ $# -ge 1 ]; then
	mesh=$1
	shift
	for L in ${*:-10 11 12}; do
		row "$mesh" "$L"
	done
else
	row "$DATA/torcs-brondehach/brondehach.acc" 13
	row "$DATA/fg-cg57/CG-57.ac" 12
	row "$SHARED/fg_terrain_reykjavik.ply" 14
	row "$DATA/fg-truman/truman.ac" 12
	row tests/data/spider/spider.obj 10
fi
echo "colour_in: --threads $THREADS; load $(cut -d' ' -f1-3 /proc/loadavg)"
