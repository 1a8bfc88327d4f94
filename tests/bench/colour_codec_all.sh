#!/usr/bin/env bash
# colour_codec_all.sh: tests/bench/colour_codec.sh over the colour
# benchmark of issue 37, each scene voxelized with colours at each depth of
# LEVELS (default "12"; "12 14" for both): the bundled spider, the three
# real scenes of config/fetch-colour-scenes.sh (CG-57, Truman, Brondehach,
# looked for in $VOXDAG_DATA, then out/data; skipped when absent), and two
# smooth-coloured scenes made from the Stanford dragon of ../shared/data by
# tests/bench/colour_scenes.py (colours varying with position; baked
# lighting). Prints one table per scene and depth, then a one-line summary
# per table. `make bench` runs it (VOXDAG_BENCH_COLOUR=0 skips it).
set -u
cd "$(dirname "$0")/../.."
LEVELS=${LEVELS:-12}
SHARED=${VOXDAG_SHARED_DATA:-../shared/data}
W=${COLOUR_BENCH_DIR:-out/bench/colour}
mkdir -p "$W"
data_dir() { # the directory holding the fetched scene $1, or nothing
	for d in ${VOXDAG_DATA:-} out/data; do
		[ -d "$d/$1" ] && { echo "$d/$1"; return; }
	done
}
scenes=("spider tests/data/spider/spider.obj")
for s in "fg-cg57 CG-57.ac" "fg-truman truman.ac" "torcs-brondehach brondehach.acc"; do
	set -- $s
	d=$(data_dir "$1")
	if [ -n "$d" ] && [ -f "$d/$2" ]; then
		scenes+=("$1 $d/$2")
	else
		echo "colour bench: $1 absent (config/fetch-colour-scenes.sh); skipped"
	fi
done
if [ -f "$SHARED/stanford_dragon.ply" ] && /usr/bin/python3 -c 'import numpy' 2>/dev/null; then
	[ -f "$W/scenes/stanford_dragon-baked.ply" ] ||
		/usr/bin/python3 tests/bench/colour_scenes.py "$SHARED/stanford_dragon.ply" "$W/scenes"
	scenes+=("dragon-position $W/scenes/stanford_dragon-position.ply"
		 "dragon-baked $W/scenes/stanford_dragon-baked.ply")
else
	echo "colour bench: no $SHARED/stanford_dragon.ply or python3-numpy; smooth scenes skipped"
fi
: > "$W/summary"
for L in $LEVELS; do
	for s in "${scenes[@]}"; do
		set -- $s
		name=$1 mesh=$2 vox=$W/vox-$1-$L
		if ! nice -n 5 out/bin/voxelize "$mesh" -o "$vox" --levels "$L" -q; then
			echo "colour bench: voxelize $name at 2^$L failed"
			continue
		fi
		tests/bench/colour_codec.sh "$vox" "$name 2^$L" | tee "$W/table-$name-$L.md"
		echo "$name 2^$L: $(tail -1 "$W/table-$name-$L.md")" >> "$W/summary"
		[ "${KEEP_VOXELS:-}" ] || rm -rf "$vox"
	done
done
echo
cat "$W/summary"
