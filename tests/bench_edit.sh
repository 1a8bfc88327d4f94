#!/usr/bin/env bash
# Benchmark of edit (the CPU HashDAG) on the shared dragon: copy, fill,
# paint and carve of cubes of about 1K, 100K, 10M and 300M voxels (sides
# 10, 47, 216, 669, those at most half the grid's side; centred on a set voxel near the grid centre (tests/bench/edit_site.c;
# the dragon is hollow there); the copy first, so its source is the scene's
# own surface, to a destination clamped inside the grid) with 1 and 2
# threads, on a coloured scene (colour-make-test colours, cells of level 3:
# paint and the colours of every edit are measured too) and on the same
# scene without colours (no paint); memory of the hashed tables against
# the plain DAG; gc time. Every edit of a run is applied in one process
# (the interactive case: loading and saving are reported apart), and its
# seconds and CPU seconds (all threads) come from EDITED.dag.stats.json;
# peak RSS from GNU time; the machine is shared, so they are noisy. The
# scene is built once per depth and kept in out/bench-edit/.
#   tests/bench_edit.sh [SCENE LEVELS]...   (default: dragon 12, dragon 14)
#   SCENE is a file of the shared data folder, or a path (with a '/');
#   VOXDAG_BENCH_MODES="plain" skips the coloured runs (when edit held
#   the colours raw, 3 bytes a voxel, the 777 at 2^16, 3.5 G voxels,
#   peaked at 20 GB with them, 1.07 GB without; now colours no edit wrote
#   stay in the source), e.g.
#     VOXDAG_BENCH_MODES=plain tests/bench_edit.sh \
#         out/data/boeing777/77L.ac 16
#   VOXDAG_BENCH_BIN=DIR takes the tools from DIR (default out/bin), to
#   measure another build on the same scenes; VOXDAG_BENCH_OUT=DIR keeps
#   the scenes and results there (default out/bench-edit).
set -u
cd "$(dirname "$0")/.."
DATA=${VOXDAG_SHARED_DATA:-../shared/data}
BIN=${VOXDAG_BENCH_BIN:-out/bin}
OUT=${VOXDAG_BENCH_OUT:-out/bench-edit}
MODES=${VOXDAG_BENCH_MODES:-col plain}
[ -d "$DATA" ] || { echo "bench_edit: $DATA is absent; nothing to measure"; exit 0; }
mkdir -p "$OUT"
get() { tr -d '\n ' < "$2" | grep -o "\"$1\":[^,}]*" | head -1 | cut -d: -f2; }
clamp() { local v=$1 lo=$2 hi=$3; [ "$v" -lt "$lo" ] && v=$lo; [ "$v" -gt "$hi" ] && v=$hi; echo "$v"; }

prep() { # DIR MESH LEVELS: cells, colours, a DAG per cell, the root DAG
	local dir=$1 mesh=$2 L=$3 c=3 f
	[ "$L" -lt 6 ] && c=1
	[ -f "$dir/root.dag" ] && [ -d "$dir/v" ] && return 0
	rm -rf "$dir" && mkdir -p "$dir/cells"
	"$BIN/voxelize" "$mesh" -o "$dir/v" --levels "$L" --chunk-level $c \
		--mem-budget 3G --no-colours -q || return 1
	case " $MODES " in
	*" col "*) "$BIN/colour-make-test" "$dir/v" || return 1 ;;
	esac
	for f in "$dir"/v/*.svo; do
		"$BIN/svo-to-dag" "$f" -o "$dir/cells/$(basename "$f" .svo).dag" -q || return 1
	done
	"$BIN/svo-to-dag" --merge "$dir"/cells/*.dag -o "$dir/root.dag" --to-level 0 -q || return 1
	rm -rf "$dir/cells"
}

bench() { # SCENE LEVELS
	local scene=$1 L=$2 name dir mesh
	case $scene in */*) mesh=$scene ;; *) mesh=$DATA/$scene ;; esac
	name=$(basename "$scene"); name=${name%.*}-$L
	dir=$OUT/$name
	[ -f "$mesh" ] || { echo "bench_edit: $mesh absent"; return; }
	prep "$dir" "$mesh" "$L" || { echo "bench_edit: building $name failed"; return; }
	# the boxes are centred on a set voxel near the grid centre, so the
	# copies copy surface and the paints meet voxels
	local n=$((1 << L)) ops="" s site
	site=$(out/bench/edit_site "$dir/root.dag") ||
		{ echo "bench_edit: edit_site failed"; return; }
	for s in 10 47 216 669; do
		[ "$s" -gt $((n / 2)) ] && continue
		local x y z ax ay az
		read -r x y z <<<"$site"
		ax=$(clamp $((x - s / 2)) 0 $((n - s)))
		ay=$(clamp $((y - s / 2)) 0 $((n - s)))
		az=$(clamp $((z - s / 2)) 0 $((n - s)))
		local bx=$((ax + s - 1)) by=$((ay + s - 1)) bz=$((az + s - 1))
		local dx dy dz
		dx=$(clamp $((ax + s + 1)) 0 $((n - s)))
		dy=$(clamp $((ay - s / 2)) 0 $((n - s)))
		dz=$(clamp $((az + s / 3)) 0 $((n - s)))
		ops+="copy $ax $ay $az $bx $by $bz to $dx $dy $dz"$'\n'
		ops+="paint box $ax $ay $az $bx $by $bz colour 200 30 30"$'\n'
		ops+="fill box $ax $ay $az $bx $by $bz"$'\n'
		ops+="carve box $ax $ay $az $bx $by $bz"$'\n'
	done
	ops+="gc"$'\n'
	printf '%s' "$ops" > "$dir/script.txt"
	grep -v '^paint' "$dir/script.txt" > "$dir/script-plain.txt"
	local mode j col script
	for mode in $MODES; do
	for j in 1 2; do
		col=() script=$dir/script-plain.txt
		[ "$mode" = col ] && col=(--colours "$dir/v" --colours-out "$dir/edited-$j.col") &&
			script=$dir/script.txt
		/usr/bin/time -f %M -o "$dir/time" "$BIN/edit" "$dir/root.dag" \
			-o "$dir/edited-$j.dag" --script "$script" -j "$j" -q \
			"${col[@]}" ||
			{ echo "bench_edit: edit failed"; return; }
		local st=$dir/edited-$j.dag.stats.json
		tr -d '\n ' < "$st" | grep -o '{"line":[^}]*}' |
		while read -r o; do
			local op line v sec cpu cells hb
			line=$(grep -o '"line":[0-9]*' <<<"$o" | cut -d: -f2)
			op=$(grep -o '"op":"[a-z]*"' <<<"$o" | cut -d'"' -f4)
			v=$(grep -o '"voxels_changed":[0-9]*' <<<"$o" | cut -d: -f2)
			sec=$(grep -o '"seconds":[0-9.e+-]*' <<<"$o" | cut -d: -f2)
			cpu=$(grep -o '"cpu_seconds":[0-9.e+-]*' <<<"$o" | cut -d: -f2)
			cells=$(grep -o '"colour_cells_rebuilt":[0-9]*' <<<"$o" | cut -d: -f2)
			hb=$(grep -o '"hash_bytes":[0-9]*' <<<"$o" | cut -d: -f2)
			printf '%-18s %-5s %2d %3s %5s %10s %9.4f %9.4f %5s %9.1f\n' "$name" "$mode" "$j" \
				"$line" "$op" "$v" "$sec" "$cpu" "${cells:--}" \
				"$(echo "$hb" | awk '{print $1/1048576}')"
		done
		printf '%-18s %-5s %2d  load %.2f s  save %.2f s  hash %.1f MiB  plain DAG %.1f MiB  peak RSS %.0f MiB  load average %s\n' \
			"$name" "$mode" "$j" "$(get seconds_load "$st")" "$(get seconds_save "$st")" \
			"$(get hash_bytes "$st" | awk '{print $1/1048576}')" \
			"$(get dag_bytes "$st" | awk '{print $1/1048576}')" \
			"$(awk '{print $1/1024}' "$dir/time")" "$(cut -d' ' -f1 /proc/loadavg)"
		rm -rf "$dir/edited-$j.col"
	done
	done
}

printf '%-18s %-5s %2s %3s %5s %10s %9s %9s %5s %9s\n' scene mode j line op voxels seconds cpu_s cells 'hash MiB'
if [ $# -eq 0 ]; then
	set -- stanford_dragon.ply 12 stanford_dragon.ply 14
fi
while [ $# -ge 2 ]; do
	bench "$1" "$2"
	shift 2
done
