#!/usr/bin/env bash
# colorize from the outside: usage errors (exit 2), good runs whose
# statistics (parsed with python3's json) agree with the files, and bad
# inputs (exit 1, one line each) that leave an earlier output untouched.
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh
C=$BIN/colorize
BUNNY=tests/data/bunny.ply

# --- usage errors: exit 2
expect usage_no_args 2 'needs an input directory' $C
expect usage_two_inputs 2 'more than one input' $C a b -o "$T/o"
expect usage_no_output 2 'no output directory' $C a
expect usage_method 2 "method 'vbr,jpeg'" $C a -o "$T/o" --method vbr,jpeg
expect usage_max_error 2 "max-error '0'" $C a -o "$T/o" --max-error 0
expect usage_max_error_text 2 "max-error 'x'" $C a -o "$T/o" -e x
expect usage_weight_bits 2 "weight-bits '9'" $C a -o "$T/o" --weight-bits 9
expect usage_palette 2 "palette-colours '1'" $C a -o "$T/o" --palette-colours 1
expect usage_threads 2 "threads '0'" $C a -o "$T/o" -j 0
expect usage_unknown_option 2 'Try' $C a -o "$T/o" --frobnicate
expect help 0 'usage: colorize' $C --help
help_lists_options help_matches_code colorize stages/colorize/main.c

# --- inputs: the bunny at 2^7 in 8 cells, synthetic colours
I="$T/in"
$BIN/voxelize $BUNNY -o "$I" --levels 7 --chunk-level 1 -q &&
$BIN/colour-make-test "$I" || fail inputs
voxels=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["voxels"])' "$I/voxelize.stats.json")

# --- a good run, every method
expect good_run 0 'colorize: [0-9]+ voxels in 8 cells: vbr' \
	$C "$I" -o "$T/res" --method vbr,palette,raw --max-error 0.038 \
	--palette-colours 256 --stats "$T/s.json" -j 2
python3 - "$T/s.json" "$T/res" "$voxels" <<'PY' && pass good_stats || fail good_stats "$(cat "$T/s.json")"
import json, os, sys
s = json.load(open(sys.argv[1])); out = sys.argv[2]; n = int(sys.argv[3])
assert s["voxels"] == n and s["cells"] == 8 and s["bytes_raw"] == 3 * n, s
assert s["peak_rss_bytes"] > 0 and s["seconds_total"] > 0
m = s["methods"]
assert set(m) == {"vbr", "palette", "raw"}, m
for k, v in m.items():
    size = os.path.getsize(os.path.join(out, v["file"]))
    assert v["file_bytes"] == size, (k, v, size)
    assert v["bytes"] <= size and v["bytes"] > 0, (k, v)
    assert abs(v["percent_of_raw"] - 100.0 * v["bytes"] / (3 * n)) < 1e-3 * v["percent_of_raw"]
    assert abs(v["ratio"] * 100 - v["percent_of_raw"]) < 1e-6 * v["percent_of_raw"] + 1e-9
    # the paper's unit: e in percent, so GMSE x 10^4 / 255^2
    assert abs(v["gmse_percent2"] - v["gmse"] * 1e4 / 65025) <= 1e-6 * v["gmse"] + 1e-12, (k, v)
assert m["raw"]["gmse"] == 0 and m["raw"]["bytes"] == m["raw"]["file_bytes"]
assert 0 < m["vbr"]["max_error"] <= 0.038 and m["vbr"]["blocks"] > 0
assert m["vbr"]["gmse"] <= (0.038 * 255) ** 2
assert m["vbr"]["weight_bits"] == 3 and m["vbr"]["max_error_limit"] == 0.038
assert m["palette"]["palette_colours"] <= 256 and m["palette"]["lossless"] == 0
# the copy inside the output directory is the same statistics
t = json.load(open(os.path.join(out, "colorize.stats.json")))
assert t["methods"]["vbr"]["bytes"] == m["vbr"]["bytes"]
PY
# the manifest lists exactly the outputs
if [ "$(awk 'NR>1 {print $3}' "$T/res/manifest" | tr '\n' ' ')" = \
     "colorize.stats.json colours.palette colours.raw colours.vbr " ]; then
	pass good_manifest
else
	fail good_manifest "$(cat "$T/res/manifest")"
fi
$BIN/chunk-check "$T/res/colours.vbr" "$T/res/colours.palette" "$T/res/colours.raw" &&
	pass good_chunk_check || fail good_chunk_check

# lossless palette: GMSE 0; default method vbr only
expect lossless_run 0 '' $C -q "$I" -o "$T/ll" --method palette --lossless --stats "$T/ll.json"
python3 -c 'import json,sys; m=json.load(open(sys.argv[1]))["methods"]; assert list(m)==["palette"] and m["palette"]["gmse"]==0 and m["palette"]["max_error"]==0 and m["palette"]["lossless"]==1, m' "$T/ll.json" &&
	pass lossless_exact || fail lossless_exact "$(cat "$T/ll.json")"
expect quiet_default 0 '' $C -q "$I" -o "$T/q"
[ -z "$(cat "$T/err")" ] && [ -f "$T/q/colours.vbr" ] && [ ! -e "$T/q/colours.raw" ] &&
	pass quiet_default_vbr_only || fail quiet_default_vbr_only "$(ls "$T/q")"

# --- bad inputs: exit 1, one line, the earlier output untouched
before=$(cat "$T/res/manifest")
bad() { # bad NAME PATTERN DIR [options]: fails into $T/res, which stays
	local name=$1 pattern=$2 dir=$3
	shift 3
	expect "$name" 1 "$pattern" $C -q "$dir" -o "$T/res" "$@"
	if [ "$(cat "$T/res/manifest")" = "$before" ] && $BIN/chunk-check "$T/res/colours.vbr" &&
	   ! ls "$T" | grep -q 'res\.tmp\.'; then
		pass "${name}_output_kept"
	else
		fail "${name}_output_kept" "$(ls "$T")"
	fi
}
bad not_a_dir 'cannot open directory' "$T/nothing"
mkdir -p "$T/empty"
bad empty_dir 'no SVO chunks' "$T/empty"
B="$T/b" && cp -r "$I" "$B"
one=$(ls "$B"/*.col | head -1)
rm "$one"
bad missing_col 'has no colour chunk' "$B"
rm -rf "$B" && cp -r "$I" "$B"
first=$(ls "$B"/*.col | head -1) second=$(ls "$B"/*.col | tail -1)
cp "$second" "$first"
bad other_cells_col 'do not match: .*colours of cell 1:7' "$B"
rm -rf "$B" && cp -r "$I" "$B"
python3 - "$(ls "$B"/*.col | head -1)" <<'PY'
import sys
p = sys.argv[1]; b = bytearray(open(p, 'rb').read()); b[len(b) // 2] ^= 0x40
open(p, 'wb').write(b)
PY
bad corrupt_col 'checksum' "$B"
# colours of another voxelization of the same cells (2^8): the count or
# the brick digest differs
O="$T/other"
$BIN/voxelize $BUNNY -o "$O" --levels 8 --chunk-level 1 -q && $BIN/colour-make-test "$O"
rm -rf "$B" && cp -r "$I" "$B"
cp "$O/$(basename "$first")" "$first"
bad other_grid_col 'do not match: .*at depth 8, bricks of cell 1:0 at depth 7' "$B"
rm -rf "$B" && cp -r "$I" "$B"
touch "$B/chunk-L1-99.col"
bad stray_col 'colour chunks for' "$B"
# (with 3-bit weights a block of one colour decodes it exactly for 98.5% of
# colours, every colour of this scene among them; with 1 bit most colours
# have no exact pair of RGB565 endpoints)
bad max_error_too_small 'too small for RGB565' "$I" --max-error 0.001 --weight-bits 1
# an output directory holding someone else's file is never replaced
mkdir -p "$T/foreign" && echo mine > "$T/foreign/notes.txt"
expect foreign_output 1 'did not write' $C -q "$I" -o "$T/foreign"
[ "$(cat "$T/foreign/notes.txt")" = mine ] && pass foreign_kept || fail foreign_kept

# --- the auto method from the outside: its statistics, lossless exact,
# files that chunk-check accepts, a block size that is no power of two
# refused (every colour against its original: test_colour_auto)
expect auto_run 0 'auto' $C "$I" -o "$T/auto" --method auto,raw --max-error 0.05 \
	--block-size 64 --stats "$T/auto.json"
python3 - "$T/auto.json" <<'PY' && pass auto_stats || fail auto_stats "$(cat "$T/auto.json")"
import json, sys
m = json.load(open(sys.argv[1]))["methods"]["auto"]
assert m["file"] == "colours.auto" and m["block_voxels"] == 64, m
assert 0 < m["max_error"] <= 0.05 and m["max_error_limit"] == 0.05 and m["lossless"] == 0, m
assert sum(m["mode_blocks"].values()) == m["blocks"] > 0, m
PY
expect auto_lossless 0 '' $C -q "$I" -o "$T/autoll" --method auto --lossless --stats "$T/autoll.json"
python3 -c 'import json,sys; m=json.load(open(sys.argv[1]))["methods"]["auto"]; assert m["gmse"]==0 and m["max_error"]==0 and m["lossless"]==1 and "coded" in m["mode_blocks"] and sum(m["mode_blocks"].values())==m["blocks"], m' "$T/autoll.json" &&
	pass auto_lossless_exact || fail auto_lossless_exact "$(cat "$T/autoll.json")"
$BIN/chunk-check "$T/auto/colours.auto" "$T/autoll/colours.auto" &&
	pass auto_chunk_check || fail auto_chunk_check
# a lossless (coded, format 1.2) file with one byte of its blocks changed
# and the checksums left as they were: one line, exit 1
cp "$T/autoll/colours.auto" "$T/autoll-bad.auto"
python3 - "$T/autoll-bad.auto" <<'PY'
import sys
b = bytearray(open(sys.argv[1], "rb").read())
i = b.find(b"ADAT")
b[i + 64] ^= 0x40
open(sys.argv[1], "wb").write(b)
PY
expect auto_coded_damaged 1 'autoll-bad.auto' $BIN/chunk-check "$T/autoll-bad.auto"
expect usage_block_size 2 "block-size '100'" $C a -o "$T/o" --block-size 100
