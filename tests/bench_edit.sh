#!/usr/bin/env bash
# Benchmark of edit (the CPU HashDAG) on the shared dragon: fill, carve and
# copy of about 1K, 100K and 10M voxels (cubes of side 10, 47, 216 at the
# grid centre) with 1 and 2 threads; memory of the hashed tables against
# the plain DAG; gc time. Figures come from EDITED.dag.stats.json and GNU
# time; the machine is shared, so they are noisy.
#   tests/bench_edit.sh [SCENE LEVELS]...   (default: dragon 12, dragon 14)
set -u
cd "$(dirname "$0")/.."
DATA=${VOXDAG_SHARED_DATA:-../shared/data}
BIN=out/bin
OUT=out/bench-edit
[ -d "$DATA" ] || { echo "bench_edit: $DATA is absent; nothing to measure"; exit 0; }
mkdir -p "$OUT"
get() { tr -d '\n ' < "$2" | grep -o "\"$1\":[^,}]*" | head -1 | cut -d: -f2; }

bench() { # SCENE LEVELS
	local scene=$1 L=$2 name dir
	name=$(basename "$scene" .ply)-$L
	dir=$OUT/$name
	[ -f "$DATA/$scene" ] || { echo "bench_edit: $scene absent"; return; }
	rm -rf "$dir" && mkdir -p "$dir"
	"$BIN/voxelize" "$DATA/$scene" -o "$dir/v" --levels "$L" --chunk-level 0 \
		--mem-budget 3G -q || { echo "bench_edit: voxelize failed"; return; }
	"$BIN/svo-to-dag" "$dir/v/chunk-L0-0.svo" -o "$dir/root.dag" -q \
		--mem-budget 3G || { echo "bench_edit: svo-to-dag failed"; return; }
	rm -rf "$dir/v"
	local c=$((1 << (L - 1))) ops="" s
	for s in 10 47 216; do
		local a=$((c - s / 2)) b=$((c - s / 2 + s - 1))
		ops+="fill box $a $a $a $b $b $b"$'\n'
		ops+="carve box $a $a $a $b $b $b"$'\n'
		ops+="copy $a $a $a $b $b $b to $((a + s + 1)) $((a - s / 2)) $((a + s / 3))"$'\n'
	done
	ops+="gc"$'\n'
	printf '%s' "$ops" > "$dir/script.txt"
	for j in 1 2; do
		/usr/bin/time -f %M -o "$dir/time" "$BIN/edit" "$dir/root.dag" \
			-o "$dir/edited-$j.dag" --script "$dir/script.txt" -j "$j" -q ||
			{ echo "bench_edit: edit failed"; return; }
		local st=$dir/edited-$j.dag.stats.json
		tr -d '\n ' < "$st" | grep -o '{"line":[^}]*}' |
		while read -r o; do
			local op line v sec hb
			line=$(grep -o '"line":[0-9]*' <<<"$o" | cut -d: -f2)
			op=$(grep -o '"op":"[a-z]*"' <<<"$o" | cut -d'"' -f4)
			v=$(grep -o '"voxels_changed":[0-9]*' <<<"$o" | cut -d: -f2)
			sec=$(grep -o '"seconds":[0-9.e+-]*' <<<"$o" | cut -d: -f2)
			hb=$(grep -o '"hash_bytes":[0-9]*' <<<"$o" | cut -d: -f2)
			printf '%-18s %2d %3s %5s %10s %10.4f %10.1f\n' "$name" "$j" \
				"$line" "$op" "$v" "$sec" "$(echo "$hb" | awk '{print $1/1048576}')"
		done
		printf '%-18s %2d  load %.2f s  save %.2f s  hash %.1f MiB  plain DAG %.1f MiB  peak RSS %.0f MiB\n' \
			"$name" "$j" "$(get seconds_load "$st")" "$(get seconds_save "$st")" \
			"$(get hash_bytes "$st" | awk '{print $1/1048576}')" \
			"$(get dag_bytes "$st" | awk '{print $1/1048576}')" \
			"$(awk '{print $1/1024}' "$dir/time")"
	done
}

printf '%-18s %2s %3s %5s %10s %10s %10s\n' scene j line op voxels seconds 'hash MiB'
if [ $# -eq 0 ]; then
	set -- stanford_dragon.ply 12 stanford_dragon.ply 14
fi
while [ $# -ge 2 ]; do
	bench "$1" "$2"
	shift 2
done
