#!/usr/bin/env bash
# voxelize on Assimp's formats (voxelize-assimp), from the outside: the
# bundled glTF scene (tests/data/gltf, written by its make.py) as .gltf
# and as .glb gives the same voxels and colours as its OBJ twin read by
# the streaming OBJ reader; the plain voxelize does not link libassimp;
# a missing texture is one warning (an error with --strict); truncated
# and corrupt scenes are one error line and leave nothing behind.
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh
V=$BIN/voxelize
S=tests/data/gltf
NAME=cliassimp-$$
trap 'rm -rf "$T" out/$NAME' EXIT

# body DIR: the voxel and colour content of DIR's chunks, without the
# provenance (which names the input)
body() {
	(shopt -s nullglob
	 for f in "$1"/*.svo "$1"/*.col; do
		echo "${f##*/} $(chunk_sans_prov "$f" | sha256sum)"
	 done)
}

expect help_gltf 0 'glTF 2.0 \(\.gltf, \.glb\)' $V --help
expect help_others 0 'FBX \(\.fbx\), Collada' $V --help

# --- only the sibling carries Assimp (voxelize's memory budget)
if ldd "$V" | grep -q libassimp; then
	fail voxelize_without_assimp "$(ldd "$V" | grep assimp)"
else
	pass voxelize_without_assimp
fi
ldd "$BIN/voxelize-assimp" | grep -q libassimp && pass sibling_links_assimp ||
	fail sibling_links_assimp

# --- the scene as .gltf, .glb and OBJ: same .svo and .col content
for f in scene.obj scene.gltf scene.glb; do
	expect "good_$f" 0 '' $V "$S/$f" -o "$T/$f" --levels 6 --chunk-level 1 -q
done
body "$T/scene.obj" > "$T/obj.body"
body "$T/scene.gltf" > "$T/gltf.body"
body "$T/scene.glb" > "$T/glb.body"
[ "$(grep -c '\.svo ' "$T/obj.body")" -gt 1 ] &&
	[ "$(grep -c '\.col ' "$T/obj.body")" -eq "$(grep -c '\.svo ' "$T/obj.body")" ] &&
	pass twin_has_colours || fail twin_has_colours "$(cat "$T/obj.body")"
diff "$T/obj.body" "$T/gltf.body" >/dev/null && pass gltf_equals_obj ||
	fail gltf_equals_obj "$(diff "$T/obj.body" "$T/gltf.body")"
diff "$T/obj.body" "$T/glb.body" >/dev/null && pass glb_embedded_equals_obj ||
	fail glb_embedded_equals_obj "$(diff "$T/obj.body" "$T/glb.body")"
grep -q '"input_format": "glb (assimp)"' "$T/scene.glb/voxelize.stats.json" &&
	grep -q '"textures_loaded": 1' "$T/scene.glb/voxelize.stats.json" &&
	pass glb_stats || fail glb_stats "$(cat "$T/scene.glb/voxelize.stats.json")"
expect gltf_chunk_check 0 '' $BIN/chunk-check "$T/scene.gltf"/*.svo "$T/scene.gltf"/*.col
# the same at another chunk level and one thread (input order decides
# ties, not the schedule)
expect good_gltf_l2 0 '' $V "$S/scene.gltf" -o "$T/g2" --levels 6 --chunk-level 2 -j 1 -q
expect good_obj_l2 0 '' $V "$S/scene.obj" -o "$T/o2" --levels 6 --chunk-level 2 -j 1 -q
[ "$(body "$T/g2")" = "$(body "$T/o2")" ] && pass gltf_equals_obj_l2 ||
	fail gltf_equals_obj_l2
# --no-colours: the same .svo files, no .col
expect gltf_no_colours 0 '' $V "$S/scene.gltf" -o "$T/geo" --levels 6 --chunk-level 1 -q --no-colours
[ -z "$(ls "$T/geo" | grep '\.col$')" ] &&
	[ "$(body "$T/geo")" = "$(grep '\.svo ' "$T/obj.body")" ] &&
	pass gltf_no_colours_same_svo || fail gltf_no_colours_same_svo

# the scene as Assimp's own exporter writes it (another .glb writer than
# make.py; assimp-utils, which `make deps` installs)
if command -v assimp >/dev/null; then
	cp "$S/checker.png" "$T/"
	assimp export "$S/scene.gltf" "$T/rt.glb" -fglb2 >/dev/null 2>&1 &&
		pass assimp_export || fail assimp_export
	expect good_assimp_glb 0 '' $V "$T/rt.glb" -o "$T/rt" --levels 6 --chunk-level 1 -q
	[ "$(body "$T/rt")" = "$(cat "$T/obj.body")" ] && pass assimp_glb_equals_obj ||
		fail assimp_glb_equals_obj
else
	echo "SKIP assimp_export: no assimp (Debian assimp-utils)"
fi

# --- in a pipeline: the runner's voxelize job runs the sibling too (with
# a colorize job, so that voxelize computes the colours)
echo '  col: {stage: colorize, needs: [vox], method: raw}' |
	small_pipeline "$NAME" "$PWD/$S/scene.glb" > "$T/p.yaml"
expect pipeline_glb 0 '' $BIN/voxdag -q run "$T/p.yaml"
expect twin_l8 0 '' $V "$S/scene.obj" -o "$T/o8" --levels 8 --chunk-level 1 -q
[ -n "$(ls out/$NAME/vox/*.col 2>/dev/null)" ] &&
	[ "$(body out/$NAME/vox)" = "$(body "$T/o8")" ] && pass pipeline_glb_equals_obj ||
	fail pipeline_glb_equals_obj "$(ls out/$NAME/vox)"

# --- a missing texture: one warning naming it, the material's colour
mkdir -p "$T/miss"
cp "$S/scene.gltf" "$S/scene.bin" "$T/miss/"
one_warning missing_texture_one_warning "warning: .*checker.png" \
	$V "$T/miss/scene.gltf" -o "$T/miss-out" --levels 6 --chunk-level 1 -q
grep -q '"textures_missing": 1' "$T/miss-out/voxelize.stats.json" && pass missing_texture_counted ||
	fail missing_texture_counted
# the comparison above can fail: without the texture the colours differ
# (and the voxels do not)
body "$T/miss-out" > "$T/miss.body"
if [ "$(grep '\.svo ' "$T/miss.body")" = "$(grep '\.svo ' "$T/obj.body")" ] &&
	! diff -q "$T/miss.body" "$T/obj.body" >/dev/null; then
	pass missing_texture_other_colours
else
	fail missing_texture_other_colours
fi
cp -r "$T/miss-out" "$T/miss-keep"
expect missing_texture_strict 1 'checker.png' $V "$T/miss/scene.gltf" -o "$T/miss-out" --levels 6 -q --strict
diff -r "$T/miss-out" "$T/miss-keep" >/dev/null && pass strict_failure_keeps_old_outdir ||
	fail strict_failure_keeps_old_outdir
expect missing_texture_strict_new 1 'checker.png' $V "$T/miss/scene.gltf" -o "$T/strict-new" --levels 6 -q --strict
expect_no_chunks strict_leaves_nothing "$T/strict-new"

# --- bad scenes: one line, exit 1, nothing that looks complete
bad() { bad_voxelize "$@" --levels 5; } # bad NAME PATTERN FILE
size=$(stat -c %s "$S/scene.glb")
for n in 0 11 100 1200 $((size - 300)) $((size - 1)); do
	head -c $n "$S/scene.glb" > "$T/cut$n.glb"
	bad "glb_cut_at_$n" "^voxelize: cannot voxelize '.*cut$n.glb': " "$T/cut$n.glb"
done
mkdir -p "$T/g"
cp "$S/scene.bin" "$T/g/"
head -c 1500 "$S/scene.gltf" > "$T/g/cut.gltf"
bad gltf_cut "cannot voxelize '.*cut.gltf': malformed input" "$T/g/cut.gltf"
cp "$S/scene.gltf" "$T/g/nobin.gltf"
rm "$T/g/scene.bin"
bad gltf_missing_bin "scene.bin" "$T/g/nobin.gltf"
head -c 100 "$S/scene.bin" > "$T/g/scene.bin"
bad gltf_short_bin "cannot voxelize '.*nobin.gltf'" "$T/g/nobin.gltf"
for e in fbx dae 3ds; do
	echo "not a scene at all" > "$T/junk.$e"
	bad "junk_$e" "cannot voxelize '.*junk.$e': malformed input: Assimp: " "$T/junk.$e"
done
# a good OUTDIR survives a bad scene
cp -r "$T/scene.glb" "$T/keep"
expect bad_keeps_outdir_run 1 'cut1200.glb' $V "$T/cut1200.glb" -o "$T/scene.glb" --levels 6 -q
diff -r "$T/scene.glb" "$T/keep" >/dev/null && pass bad_keeps_outdir || fail bad_keeps_outdir

# --- voxelize without its sibling says so
mkdir -p "$T/lonely"
cp "$V" "$T/lonely/"
expect no_sibling 1 "cannot run '.*voxelize-assimp' for glTF" "$T/lonely/voxelize" "$S/scene.glb" -o "$T/ls" --levels 5 -q
