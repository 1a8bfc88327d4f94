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
expect usage_three_inputs 2 'more than two inputs' $E a.dag b.ssvdag c -o "$T/o"
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

# --- bad inputs: exit 1, one line, nothing written
no_outputs() {
	if ls "$1" 2>/dev/null | grep -Eq '\.(svdag|ussvdag|esvdag|ssvdag|json|csv|md)$|\.tmp\.'; then
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
