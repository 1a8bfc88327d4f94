#!/usr/bin/env bash
# encode from the outside: usage errors (exit 2), a good run whose files
# match its statistics and tables, and bad inputs (exit 1, one line each,
# no output files left).
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh
E=$BIN/encode
BUNNY=tests/data/bunny.ply

# --- usage errors: exit 2
expect usage_no_args 2 'needs two inputs' $E
expect usage_one_input 2 'needs two inputs' $E a.dag -o "$T/o"
expect usage_four_inputs 2 'more than three inputs' $E a.dag b.ssvdag c d -o "$T/o"
expect usage_no_output 2 'no output directory' $E a.dag b.ssvdag
expect usage_min_level 2 "min-level '0'" $E a.dag b.ssvdag -o "$T/o" --min-level 0
expect usage_threads 2 "threads 'x'" $E a.dag b.ssvdag -o "$T/o" -j x
expect usage_budget 2 "mem-budget 'lots'" $E a.dag b.ssvdag -o "$T/o" --mem-budget lots
expect usage_name 2 "name 'a/b'" $E a.dag b.ssvdag -o "$T/o" --name a/b
expect usage_unknown_option 2 'Try' $E a.dag b.ssvdag -o "$T/o" --frobnicate
expect help 0 'usage: encode' $E --help
help_lists_options help_matches_code encode stages/encode/main.c

# --- inputs: the bunny at 2^7, monolithic and as 8 chunks merged to the root
M="$T/m"
$BIN/voxelize $BUNNY -o "$M" --levels 7 --chunk-level 0 -q &&
$BIN/svo-to-dag -q "$M/chunk-L0-0.svo" -o "$M/root.dag" &&
$BIN/symmetry-merge -q "$M/root.dag" -o "$M/root.ssvdag" || fail inputs
C="$T/c"
$BIN/voxelize $BUNNY -o "$C" --levels 7 --chunk-level 1 -q
for f in "$C"/chunk-L1-*.svo; do $BIN/svo-to-dag -q "$f" -o "${f%.svo}.dag"; done
$BIN/svo-to-dag -q --merge "$C"/chunk-L1-*.dag -o "$C/root.dag"
$BIN/symmetry-merge -q --merge "$C"/chunk-L1-*.dag -o "$C/root.ssvdag"

# --- a good run
expect good_run 0 "encode: 128\^3, [0-9]+ voxels: svdag [0-9]+ B" \
	$E "$M/root.dag" "$M/root.ssvdag" -o "$T/enc" --name bunny --min-level 5 \
	--stats "$M/root.dag.stats.json" --stats "$M/root.ssvdag.stats.json"
ok=1
for f in svdag ussvdag esvdag ssvdag; do
	size=$(stat -c %s "$T/enc/bunny.$f" 2>/dev/null || echo 0)
	case $f in svdag|ussvdag) head=44 ;; *) head=48 ;; esac
	grep -q "\"bytes_$f\": $((size - head))," "$T/enc/bunny.encode.stats.json" || ok=0
	grep -q "\"bytes_$f\": $((size - head))," "$T/enc/bunny.tables.json" || ok=0
done
[ $ok = 1 ] && pass good_sizes_match_files || fail good_sizes_match_files "$(cat "$T/enc/bunny.encode.stats.json")"
if [ "$(wc -l < "$T/enc/bunny.table2.csv")" -eq 4 ] &&
   grep -q '^| 32^3 |' "$T/enc/bunny.tables.md" &&
   grep -q '"seconds_symmetry_merge": ' "$T/enc/bunny.tables.json" &&
   grep -Eq '^7,128,[0-9.]+,[0-9.]+,[0-9.]+$' "$T/enc/bunny.table1.csv"; then
	pass good_tables
else
	fail good_tables "$(cat "$T/enc/bunny.tables.md")"
fi
expect quiet_run 0 '' $E -q "$M/root.dag" "$M/root.ssvdag" -o "$T/q"
[ -z "$(cat "$T/err")" ] && pass quiet_is_silent || fail quiet_is_silent "$(cat "$T/err")"
# the merged root gives the same table rows as the monolithic one
expect chunked_run 0 '' $E -q "$C/root.dag" "$C/root.ssvdag" -o "$T/c-out" --name bunny --min-level 5
cmp -s "$T/enc/bunny.table2.csv" "$T/c-out/bunny.table2.csv" &&
	pass chunked_same_table2 || fail chunked_same_table2 "$(diff "$T/enc/bunny.table2.csv" "$T/c-out/bunny.table2.csv")"

# --- the 48-group (symmetry-merge --group 48): .ssvdag48 beside the others,
# or alone with the plain DAG's; sizes match the files; lossless by
# dag-verify (through the manifest); chunked + merged gives the same rows
$BIN/symmetry-merge -q --group 48 "$M/root.dag" -o "$M/root.s48" &&
$BIN/symmetry-merge -q --group 48 --merge "$C"/chunk-L1-*.dag -o "$C/root.s48" || fail inputs48
expect g48_run 0 "ssvdag48 [0-9]+ B" \
	$E "$M/root.dag" "$M/root.s48" "$M/root.ssvdag" -o "$T/e48" --name bunny --min-level 5
ok=1
for f in svdag ussvdag esvdag ssvdag ssvdag48; do
	size=$(stat -c %s "$T/e48/bunny.$f" 2>/dev/null || echo 0)
	case $f in svdag|ussvdag) head=44 ;; *) head=48 ;; esac
	grep -q "\"bytes_$f\": $((size - head))," "$T/e48/bunny.encode.stats.json" || ok=0
	grep -q "\"bytes_$f\": $((size - head))," "$T/e48/bunny.tables.json" || ok=0
	grep -q "bunny.$f\b" "$T/e48/manifest" || ok=0
done
[ $ok = 1 ] && pass g48_sizes_match_files || fail g48_sizes_match_files "$(cat "$T/e48/bunny.encode.stats.json")"
n48=$(tr -d '\n ' < "$M/root.s48.stats.json" | sed 's/.*"nodes":\([0-9]*\).*/\1/')
grep -q "\"nodes_ssvdag48\": $n48," "$T/e48/bunny.encode.stats.json" &&
grep -q '| nodes SSVDAG48 |' "$T/e48/bunny.tables.md" &&
head -1 "$T/e48/bunny.table2.csv" | grep -q ',nodes_ssvdag48,bytes_ssvdag48,bpv_ssvdag48$' &&
	pass g48_tables || fail g48_tables "$(cat "$T/e48/bunny.tables.md")"
# the paper's columns are unchanged by the 48-group's
cut -d, -f1-16 "$T/e48/bunny.table2.csv" | cmp -s - "$T/enc/bunny.table2.csv" &&
	pass g48_paper_columns_unchanged || fail g48_paper_columns_unchanged
expect g48_verify 0 '' $BIN/dag-verify "$T/e48/bunny.ssvdag48" "$M/chunk-L0-0.svo"
expect g48_verify_chunks 0 '' $BIN/dag-verify "$T/e48/bunny.ssvdag48" "$C"/chunk-L1-*.svo
expect g48_diff_vs_ssvdag 0 '^differing_voxels=0 ' \
	$BIN/dag-verify --diff "$T/e48/bunny.ssvdag48" "$T/e48/bunny.ssvdag"
expect g48_only 0 '' $E -q "$C/root.dag" "$C/root.s48" -o "$T/e48c" --name bunny --min-level 5
ls "$T/e48c" | grep -Eq '\.(ussvdag|ssvdag)$' && fail g48_only_files "$(ls "$T/e48c")" ||
	pass g48_only_files
grep -q '"skipped_ssvdag": "no ssvdag input"' "$T/e48c/bunny.encode.stats.json" &&
	pass g48_only_skipped || fail g48_only_skipped
cmp -s "$T/e48/bunny.ssvdag48" "$T/e48c/bunny.ssvdag48" &&
	pass g48_chunked_same_bytes || fail g48_chunked_same_bytes
expect g48_chunked_verify 0 '' $BIN/dag-verify "$T/e48c/bunny.ssvdag48" "$M/chunk-L0-0.svo"
expect g48_two_48 2 "both ssvdag48 chunks" $E "$M/root.dag" "$M/root.s48" "$C/root.s48" -o "$T/o"
# damaged .ssvdag48: the manifest catches a changed byte; without it the
# decoder names a transform of 48 or more, or the truncation
cp "$T/e48/bunny.ssvdag48" "$T/bad.ssvdag48"
printf '\xff' | dd of="$T/bad.ssvdag48" bs=1 seek=43 conv=notrunc 2>/dev/null
expect g48_bad_transform 1 "^dag-verify: cannot read '.*bad.ssvdag48': .*transform (6[0-3]|5[0-9]|4[89]) \(not below 48\)$" \
	$BIN/dag-verify --no-verify "$T/bad.ssvdag48" "$M/chunk-L0-0.svo"
head -c 100 "$T/e48/bunny.ssvdag48" > "$T/cut.ssvdag48"
expect g48_truncated 1 "^dag-verify: cannot read '.*cut.ssvdag48': truncated file" \
	$BIN/dag-verify --no-verify "$T/cut.ssvdag48" "$M/chunk-L0-0.svo"
cp "$T/e48/bunny.ssvdag48" "$T/e48/copy.ssvdag48"
printf '\x01' | dd of="$T/e48/bunny.ssvdag48" bs=1 seek=60 conv=notrunc 2>/dev/null
expect g48_manifest 1 "^dag-verify: cannot read '.*bunny.ssvdag48': " \
	$BIN/dag-verify "$T/e48/bunny.ssvdag48" "$M/chunk-L0-0.svo"

# --- bad inputs: exit 1, one line, nothing written
no_outputs() {
	if ls "$1" 2>/dev/null | grep -Eq '\.(svdag|ussvdag|esvdag|ssvdag|ssvdag48|json|csv|md)$|\.tmp\.'; then
		fail "$2" "files left in $1: $(ls "$1")"
	else
		pass "$2"
	fi
}
expect wrong_kind_svo 1 "^encode: cannot read '.*chunk-L0-0.svo': wrong chunk kind" \
	$E "$M/chunk-L0-0.svo" "$M/root.ssvdag" -o "$T/bad1"
no_outputs "$T/bad1" wrong_kind_svo_nothing_written
expect swapped_inputs 1 "^encode: cannot read '.*root.ssvdag': wrong chunk kind" \
	$E "$M/root.ssvdag" "$M/root.dag" -o "$T/bad2"
first=$(ls "$C"/chunk-L1-*.dag | head -1)
expect not_root_chunk 1 "^encode: cannot encode '.*chunk-L1-.*dag': not a root chunk \(chunk level 1" \
	$E "$first" "$C/root.ssvdag" -o "$T/bad3"
no_outputs "$T/bad3" not_root_nothing_written
size=$(stat -c %s "$M/root.dag")
head -c $((size / 2)) "$M/root.dag" > "$T/cut.dag"
expect truncated 1 "^encode: cannot read '.*cut.dag': truncated file: " \
	$E "$T/cut.dag" "$M/root.ssvdag" -o "$T/bad4"
no_outputs "$T/bad4" truncated_nothing_written
expect missing_file 1 "^encode: cannot read '.*nonexistent.dag': I/O error" \
	$E "$T/nonexistent.dag" "$M/root.ssvdag" -o "$T/bad5"
$BIN/voxelize $BUNNY -o "$T/l6" --levels 6 --chunk-level 0 -q
$BIN/svo-to-dag -q "$T/l6/chunk-L0-0.svo" -o "$T/l6/root.dag"
expect other_scene 1 "^encode: .*inputs do not match|^encode: cannot encode .* not the same scene" \
	$E "$T/l6/root.dag" "$M/root.ssvdag" -o "$T/bad6"
no_outputs "$T/bad6" other_scene_nothing_written
expect bad_stats 1 "^encode: cannot read '.*bunny.ply': malformed input: not a statistics file" \
	$E "$M/root.dag" "$M/root.ssvdag" -o "$T/bad7" --stats $BUNNY
expect budget 1 "^encode: cannot load '.*root.dag': needs about [0-9]+ MiB, budget --mem-budget 0 MiB" \
	$E "$M/root.dag" "$M/root.ssvdag" -o "$T/bad8" --mem-budget 1K
expect unwritable_output 1 "^encode: cannot create '/proc/nope" \
	$E "$M/root.dag" "$M/root.ssvdag" -o /proc/nope
