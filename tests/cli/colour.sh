#!/usr/bin/env bash
# voxelize with colours, from the outside: .col chunks beside the .svo
# chunks and in the manifest; --no-colours; one warning line for a missing
# texture and an error with --strict; nothing that looks complete is left
# after a failure, and a failed run leaves an earlier OUTDIR as it was.
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh
V=$BIN/voxelize
S=tests/data/textured

expect help_colours 0 'no-colours' $V --help
expect help_strict 0 'strict' $V --help

# --- the bundled textured scene, each format
for f in scene.obj scene.ac vcol.ply; do
	n=${f%.*}_${f#*.}
	expect "good_$n" 0 '' $V "$S/$f" -o "$T/$n" --levels 6 --chunk-level 1 -q
	svo=$(ls "$T/$n"/*.svo 2>/dev/null | wc -l)
	col=$(ls "$T/$n"/*.col 2>/dev/null | wc -l)
	[ "$svo" -gt 1 ] && [ "$svo" -eq "$col" ] && pass "${n}_col_per_svo" ||
		fail "${n}_col_per_svo" "$svo svo, $col col"
	if [ "$(grep -c '\.col$' "$T/$n/manifest")" -eq "$col" ]; then
		pass "${n}_col_in_manifest"
	else
		fail "${n}_col_in_manifest" "$(cat "$T/$n/manifest")"
	fi
	expect "${n}_chunk_check" 0 '' $BIN/chunk-check "$T/$n"/*.svo "$T/$n"/*.col
	grep -q '"colours": 1' "$T/$n/voxelize.stats.json" && pass "${n}_stats" ||
		fail "${n}_stats" "$(cat "$T/$n/voxelize.stats.json")"
done
grep -q '"textures_loaded": 4' "$T/scene_obj/voxelize.stats.json" &&
	pass obj_four_textures || fail obj_four_textures "$(cat "$T/scene_obj/voxelize.stats.json")"

# --- --no-colours: the same .svo files, no .col
expect no_colours 0 '' $V "$S/scene.obj" -o "$T/geo" --levels 6 --chunk-level 1 -q --no-colours
[ -z "$(ls "$T/geo" | grep '\.col$')" ] && pass no_colours_no_col || fail no_colours_no_col "$(ls "$T/geo")"
grep -q '"colours": 0' "$T/geo/voxelize.stats.json" && pass no_colours_stats || fail no_colours_stats
# a mesh without colours writes none either
expect bunny_no_col 0 '' $V tests/data/bunny.ply -o "$T/bunny" --levels 5 -q
[ -z "$(ls "$T/bunny" | grep '\.col$')" ] && pass bunny_no_col_files || fail bunny_no_col_files

# --- a missing texture: one warning naming it, the run succeeds
mkdir -p "$T/miss"
cp "$S/scene.obj" "$S/checker.png" "$S/bricks.tga" "$S/tiles.bmp" "$T/miss/"
sed 's/photo.jpg/gone.jpg/' "$S/scene.mtl" > "$T/miss/scene.mtl"
one_warning missing_texture_one_warning "warning: .*gone.jpg" \
	$V "$T/miss/scene.obj" -o "$T/miss-out" --levels 5 -q
grep -q '"textures_missing": 1' "$T/miss-out/voxelize.stats.json" && pass missing_texture_counted ||
	fail missing_texture_counted
# --strict: an error, and the earlier good OUTDIR is left as it was
cp -r "$T/miss-out" "$T/miss-keep"
expect missing_texture_strict 1 'gone.jpg' $V "$T/miss/scene.obj" -o "$T/miss-out" --levels 5 -q --strict
diff -r "$T/miss-out" "$T/miss-keep" >/dev/null && pass strict_failure_keeps_old_outdir ||
	fail strict_failure_keeps_old_outdir
rm -rf "$T/strict-new"
expect missing_texture_strict_new 1 'gone.jpg' $V "$T/miss/scene.obj" -o "$T/strict-new" --levels 5 -q --strict
expect_no_chunks strict_leaves_nothing "$T/strict-new"

# --- corrupt textures: warned; strict errors naming the file
head -c 50 "$S/checker.png" > "$T/miss/checker.png"
$V "$T/miss/scene.obj" -o "$T/cut-out" --levels 5 -q 2>"$T/warn"
grep -q "checker.png" "$T/warn" && pass corrupt_png_warned || fail corrupt_png_warned "$(cat "$T/warn")"
expect corrupt_png_strict 1 'checker.png' $V "$T/miss/scene.obj" -o "$T/cut-strict" --levels 5 -q --strict
expect_no_chunks corrupt_png_strict_leaves_nothing "$T/cut-strict"

# --- bad colour data: errors, one line, nothing left
bad() { bad_voxelize "$@" --levels 5; } # bad NAME PATTERN FILE
printf 'v 0 0 0\nv 1 0 0\nv 0 1 1\nvt nan 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n' > "$T/nan_uv.obj"
bad nan_uv 'line 4.*not finite' "$T/nan_uv.obj"
expect nan_uv_geometry_only 0 '' $V "$T/nan_uv.obj" -o "$T/nan-geo" --levels 5 -q --no-colours
printf 'ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nproperty list uchar uchar red\nproperty uchar green\nproperty uchar blue\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0 1 9 0 0\n1 0 0 1 9 0 0\n0 1 1 1 9 0 0\n3 0 1 2\n' > "$T/list.ply"
bad list_colour "colour property 'red' is a list" "$T/list.ply"
printf 'v 0 0 0\nv 1 0 0\nv 0 1 1\nvt 0 0\nf 1/1 2/2 3/1\n' > "$T/vt_range.obj"
bad vt_out_of_range 'texture coordinate index 2 out of range' "$T/vt_range.obj"
