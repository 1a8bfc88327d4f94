#!/usr/bin/env bash
# voxelize and chunk-check from the outside: exit codes and messages for
# good and bad input; nothing that looks complete is left after a failure.
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh
V=$BIN/voxelize
BUNNY=tests/data/bunny.ply

# --- usage errors: exit 2
expect usage_no_args 2 'no MESH' $V
expect usage_levels_0 2 'levels .0.' $V $BUNNY -o "$T/o" --levels 0
expect usage_levels_40 2 'levels .40.' $V $BUNNY -o "$T/o" --levels 40
expect usage_levels_text 2 'levels' $V $BUNNY -o "$T/o" --levels ten
expect usage_no_output 2 'output' $V $BUNNY --levels 5
expect usage_bad_budget 2 'mem-budget' $V $BUNNY -o "$T/o" --levels 5 --mem-budget lots
expect usage_unknown_option 2 'Try' $V $BUNNY -o "$T/o" --levels 5 --frobnicate
expect help 0 'usage: voxelize' $V --help
help_lists_options help_matches_code voxelize stages/voxelize/main.c
help_lists_options help_matches_code_chunk_check chunk-check stages/chunk-check/main.c

# --- a good run
expect good_run 0 '' $V $BUNNY -o "$T/good" --levels 7 -q
printf 'AC3Db\nOBJECT world\nkids 1\nOBJECT poly\nloc 5 0 0\nnumvert 4\n0 0 0\n1 0 0\n1 1 0\n0 1 1\nnumsurf 1\nSURF 0x10\nmat 0\nrefs 4\n0 0 0\n1 0 0\n2 0 0\n3 0 0\nkids 0\n' > "$T/quad.ac"
expect good_run_ac3d 0 '' $V "$T/quad.ac" -o "$T/good-ac" --levels 5 -q
if grep -q '"input_format": "ac3d"' "$T/good-ac/voxelize.stats.json" &&
   grep -q '"triangles_read": 2' "$T/good-ac/voxelize.stats.json"; then
	pass good_stats_ac3d
else
	fail good_stats_ac3d "$(cat "$T/good-ac/voxelize.stats.json")"
fi
expect good_chunks_check 0 '' $BIN/chunk-check "$T"/good/*.svo
if grep -q '"voxels": [1-9]' "$T/good/voxelize.stats.json" &&
   grep -q '"triangles_read": 69451' "$T/good/voxelize.stats.json" &&
   grep -q '"peak_rss_bytes": [1-9]' "$T/good/voxelize.stats.json"; then
	pass good_stats
else
	fail good_stats "$(cat "$T/good/voxelize.stats.json")"
fi
expect chunk_level_too_deep 1 'chunk-level 6 is outside 0..5' $V $BUNNY -o "$T/cl" --levels 7 --chunk-level 6 -q
expect chunked_run 0 '' $V $BUNNY -o "$T/chunked" --levels 7 --chunk-level 2 -q
n=$(ls "$T"/chunked/*.svo | wc -l)
[ "$n" -gt 8 ] && pass chunked_many_files || fail chunked_many_files "$n chunks"

# --- bad meshes: exit 1, one line, the cause named, nothing left behind
bad() { # bad NAME PATTERN FILE
	rm -rf "$T/bad"
	expect "$1" 1 "$2" $V "$3" -o "$T/bad" --levels 6 -q
	expect_no_chunks "$1_leaves_nothing" "$T/bad"
}
bad missing_file 'No such file' "$T/nonexistent.ply"
bad directory 'directory' tests
echo "hello world" > "$T/hello.txt"
bad unsupported_format 'not a PLY, OBJ, STL or AC3D' "$T/hello.txt"
cp "$T/good/voxelize.stats.json" "$T/stats.ply"
bad json_named_ply 'malformed|unsupported' "$T/stats.ply"
head -c 300 $BUNNY > "$T/header_cut.ply"
bad truncated_header 'truncated|malformed' "$T/header_cut.ply"
head -c 1000000 $BUNNY > "$T/body_cut.ply"
bad truncated_body 'truncated' "$T/body_cut.ply"
printf 'ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\nnan 1 0\n0 0 1\n3 0 1 2\n' > "$T/nan.ply"
bad nan_vertex 'non-finite|nan' "$T/nan.ply"
printf 'ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\ninf 1 0\n0 0 1\n3 0 1 2\n' > "$T/inf.ply"
bad inf_vertex 'non-finite|inf' "$T/inf.ply"
printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n' > "$T/range.obj"
bad index_out_of_range 'out of range|range' "$T/range.obj"
printf 'AC3Db\nOBJECT world\nkids 1\nOBJECT poly\nnumvert 3\n0 0 0\n1 0 0\n0 1 0\nnumsurf 1\nSURF 0x10\nmat 0\nrefs 3\n0 0 0\n1 0 0\n3 0 0\nkids 0\n' > "$T/range.ac"
bad ac3d_index_out_of_range 'line 15: .*out of range' "$T/range.ac"
head -c 60 "$T/range.ac" > "$T/cut.ac"
bad ac3d_truncated 'truncated' "$T/cut.ac"
printf 'ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n' > "$T/empty.ply"
bad empty_mesh 'empty|no triangles' "$T/empty.ply"
: > "$T/zero.stl"
bad zero_byte_file 'empty' "$T/zero.stl"
printf 'v 1 1 1\nv 1 1 1\nv 1 1 1\nf 1 2 3\n' > "$T/point.obj"
bad zero_extent 'zero extent' "$T/point.obj"
printf 'solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0\n' > "$T/cut.stl"
bad ascii_stl_cut 'truncated|malformed' "$T/cut.stl"
rm -rf "$T/bad"
expect budget_too_small 1 'budget' $V $BUNNY -o "$T/bad" --levels 12 --mem-budget 1M -q
expect_no_chunks budget_too_small_leaves_nothing "$T/bad"

# bad input found before any writing leaves an earlier result untouched
cp -r "$T/good" "$T/reuse"
expect rerun_bad_input 1 'truncated' $V "$T/body_cut.ply" -o "$T/reuse" --levels 6 -q
expect rerun_bad_input_keeps_earlier_result 0 '' $BIN/chunk-check "$T"/reuse/*.svo

# --- chunk-check verdicts
f=$(ls "$T"/good/*.svo | head -n 1)
expect check_good_silent 0 '' $BIN/chunk-check "$f"
[ ! -s "$T/out" ] && [ ! -s "$T/err" ] && pass check_good_prints_nothing || fail check_good_prints_nothing "$(cat "$T/out" "$T/err")"
head -c 100 "$f" > "$T/cut.svo"
expect check_truncated 1 "'.*cut.svo': truncated file" $BIN/chunk-check "$T/cut.svo"
cp "$f" "$T/trail.svo"; echo garbage >> "$T/trail.svo"
expect check_trailing 1 'trailing bytes' $BIN/chunk-check "$T/trail.svo"
cp "$f" "$T/flip.svo"; printf '\x55' | dd of="$T/flip.svo" bs=1 seek=200 conv=notrunc 2>/dev/null
expect check_flipped 1 'checksum mismatch' $BIN/chunk-check "$T/flip.svo"
expect check_not_chunk 1 'not a chunk file' $BIN/chunk-check $BUNNY
cp "$f" "$T/major.svo"; printf '\x09' | dd of="$T/major.svo" bs=1 seek=8 conv=notrunc 2>/dev/null
expect check_newer_version 1 'version too new' $BIN/chunk-check "$T/major.svo"
expect check_verbose 0 'svo chunk, format 1.0, levels 7' $BIN/chunk-check -v "$f"
expect check_no_args 2 'no FILE' $BIN/chunk-check

# --- an atomic writer never renames over something that is not a file
expect writer_refuses_device 1 'not a regular file' $BIN/svo-to-dag "$f" -o /dev/null
[ -c /dev/null ] && pass writer_device_intact || fail writer_device_intact "$(ls -la /dev/null)"
