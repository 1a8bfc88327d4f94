#!/usr/bin/env bash
# Command-line tests of svo-to-dag, symmetry-merge and dag-verify, run from
# the outside on the release executables: one PASS/FAIL line per case.
set -u
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh # help_lists_options; this file keeps its own expect
BIN=out/bin
T=out/tmp/cli-dag
rm -rf "$T" && mkdir -p "$T"

pass() { echo "PASS $1"; }
fail() { echo "FAIL $1${2:+: $2}"; }

# expect NAME RC PATTERN CMD...: runs CMD, checks its exit status and that
# its stderr+stdout matches PATTERN (grep -E; '' for silence).
expect() {
	local name=$1 rc=$2 pat=$3
	shift 3
	local out got
	out=$("$@" 2>&1)
	got=$?
	if [ "$got" -ne "$rc" ]; then
		fail "$name" "exit $got, expected $rc; output: $out"
	elif [ -z "$pat" ] && [ -n "$out" ]; then
		fail "$name" "expected no output, got: $out"
	elif [ -n "$pat" ] && ! grep -qE -- "$pat" <<<"$out"; then
		fail "$name" "output does not match '$pat': $out"
	else
		pass "$name"
	fi
}

# level_nodes of a stats file, as one line
counts() { tr -d '\n ' < "$1" | sed 's/.*"level_nodes":\[\([0-9,]*\)\].*/\1/'; }

# hex Morton code of a chunk file name chunk-L<l>-<hex>.<ext>
cell_of() { local b=${1##*/}; b=${b%.*}; echo $((16#${b##*-})); }
chunk_name() { # level cell ext
	local digits=$(((3 * $1 + 3) / 4))
	[ "$digits" -lt 1 ] && digits=1
	printf "chunk-L%d-%0*x.%s" "$1" "$digits" "$2" "$3"
}

# reduce STAGE DIR L0 EXT: merges the chunks DIR/chunk-L<L0>-*.EXT 8
# siblings at a time up to DIR/chunk-L0-0.EXT.
reduce() {
	local stage=$1 dir=$2 l=$3 ext=$4
	while [ "$l" -gt 0 ]; do
		local -A groups=()
		local f
		for f in "$dir"/chunk-L$l-*."$ext"; do
			local p=$(($(cell_of "$f") >> 3))
			groups[$p]+="$f "
		done
		for p in "${!groups[@]}"; do
			# shellcheck disable=SC2086
			$BIN/$stage -q --merge ${groups[$p]} \
				-o "$dir/$(chunk_name $((l - 1)) "$p" "$ext")" || return 1
		done
		unset groups
		l=$((l - 1))
	done
}

# reduce_g48 DIR L0: the same tree for ssvdag48 chunks (*.s48).
reduce_g48() {
	local dir=$1 l=$2
	while [ "$l" -gt 0 ]; do
		local -A groups=()
		local f
		for f in "$dir"/chunk-L$l-*.s48; do
			local p=$(($(cell_of "$f") >> 3))
			groups[$p]+="$f "
		done
		for p in "${!groups[@]}"; do
			# shellcheck disable=SC2086
			$BIN/symmetry-merge -q --group 48 --merge ${groups[$p]} \
				-o "$dir/$(chunk_name $((l - 1)) "$p" s48)" || return 1
		done
		unset groups
		l=$((l - 1))
	done
}

SHARED_DATA=${VOXDAG_SHARED_DATA:-../shared/data}

for t in svo-to-dag symmetry-merge dag-verify; do
	expect "$t-help" 0 'mem-budget' $BIN/$t --help
	expect "$t-no-args" 2 "Try '$t --help'" $BIN/$t
	expect "$t-bad-option" 2 "Try '$t --help'" $BIN/$t --frobnicate x
done
expect svo-to-dag-bad-threads 2 "--threads 'x'" $BIN/svo-to-dag --threads x a.svo -o b.dag
expect svo-to-dag-no-output 2 "no output" $BIN/svo-to-dag a.svo
expect svo-to-dag-two-inputs 2 "use --merge" $BIN/svo-to-dag a.svo b.svo -o c.dag
expect svo-to-dag-to-level-alone 2 "needs --merge" $BIN/svo-to-dag --to-level 1 a.svo -o c.dag

# --- the bundled bunny at 2^8: monolithic, then chunked with L0 = 1, 2, 3
MESH=tests/data/bunny.ply
L=8
$BIN/voxelize "$MESH" -o "$T/m" --levels $L --chunk-level 0 -q || fail voxelize
expect mono-svo-to-dag 0 '' $BIN/svo-to-dag -q "$T/m/chunk-L0-0.svo" -o "$T/m/chunk-L0-0.dag"
expect mono-symmetry-merge 0 '' $BIN/symmetry-merge -q "$T/m/chunk-L0-0.dag" -o "$T/m/chunk-L0-0.ssvdag"
expect mono-verify-dag 0 '' $BIN/dag-verify "$T/m/chunk-L0-0.dag" "$T/m/chunk-L0-0.svo"
expect mono-verify-ssvdag 0 '' $BIN/dag-verify "$T/m/chunk-L0-0.ssvdag" "$T/m/chunk-L0-0.svo"
expect summary-line 0 "wrote '.*chunk-L0-0.dag': dag of [0-9]+ voxels" \
	$BIN/svo-to-dag "$T/m/chunk-L0-0.svo" -o "$T/m/chunk-L0-0.dag"
if grep -q '"peak_rss_bytes": [1-9]' "$T/m/chunk-L0-0.dag.stats.json" &&
   grep -q '"level_refs": \[' "$T/m/chunk-L0-0.ssvdag.stats.json" &&
   grep -q '"input_voxels": [1-9]' "$T/m/chunk-L0-0.dag.stats.json"; then
	pass stats-json
else
	fail stats-json
fi
# a one-part merge at the part's own level (the runner's root step when
# the whole scene is one chunk) checks and rebuilds it unchanged
expect one-part-merge 0 '' $BIN/svo-to-dag -q --merge --to-level 0 "$T/m/chunk-L0-0.dag" -o "$T/m/one.dag"
expect one-part-symmetry-merge 0 '' $BIN/symmetry-merge -q --merge --to-level 0 "$T/m/chunk-L0-0.ssvdag" -o "$T/m/one.ssvdag"
[ "$(counts "$T/m/one.dag.stats.json")" = "$(counts "$T/m/chunk-L0-0.dag.stats.json")" ] &&
[ "$(counts "$T/m/one.ssvdag.stats.json")" = "$(counts "$T/m/chunk-L0-0.ssvdag.stats.json")" ] &&
	pass one-part-merge-counts || fail one-part-merge-counts
expect root-has-no-parent 1 "already root chunks" $BIN/svo-to-dag --merge "$T/m/chunk-L0-0.dag" -o "$T/m/x.dag"
dag_counts=$(counts "$T/m/chunk-L0-0.dag.stats.json")
ssv_counts=$(counts "$T/m/chunk-L0-0.ssvdag.stats.json")

for L0 in 1 2 3; do
	d="$T/c$L0"
	$BIN/voxelize "$MESH" -o "$d" --levels $L --chunk-level "$L0" -q || fail "voxelize-L0-$L0"
	ok=1
	for f in "$d"/chunk-L$L0-*.svo; do
		$BIN/svo-to-dag -q "$f" -o "${f%.svo}.dag" &&
		$BIN/symmetry-merge -q "${f%.svo}.dag" -o "${f%.svo}.ssvdag" || ok=0
	done
	[ $ok = 1 ] && pass "chunks-L0-$L0" || fail "chunks-L0-$L0"
	# a reduction tree of 8-sibling merges, for both kinds
	mkdir -p "$d/tree"
	cp "$d"/chunk-L$L0-*.dag "$d"/chunk-L$L0-*.ssvdag "$d/tree/"
	if reduce svo-to-dag "$d/tree" "$L0" dag && reduce symmetry-merge "$d/tree" "$L0" ssvdag; then
		[ "$(counts "$d/tree/chunk-L0-0.dag.stats.json")" = "$dag_counts" ] &&
			pass "tree-dag-counts-L0-$L0" ||
			fail "tree-dag-counts-L0-$L0" "$(counts "$d/tree/chunk-L0-0.dag.stats.json") != $dag_counts"
		[ "$(counts "$d/tree/chunk-L0-0.ssvdag.stats.json")" = "$ssv_counts" ] &&
			pass "tree-ssvdag-counts-L0-$L0" ||
			fail "tree-ssvdag-counts-L0-$L0" "$(counts "$d/tree/chunk-L0-0.ssvdag.stats.json") != $ssv_counts"
		expect "tree-verify-dag-L0-$L0" 0 '' $BIN/dag-verify "$d/tree/chunk-L0-0.dag" "$d"/*.svo
		expect "tree-verify-ssvdag-L0-$L0" 0 '' $BIN/dag-verify "$d/tree/chunk-L0-0.ssvdag" "$d"/*.svo
	else
		fail "tree-L0-$L0"
	fi
	# all at once, and a symmetry merge of DAG chunks straight to the root
	expect "flat-merge-L0-$L0" 0 '' $BIN/svo-to-dag -q --merge --to-level 0 "$d"/chunk-L$L0-*.dag -o "$d/root.dag"
	expect "flat-symmetry-merge-L0-$L0" 0 '' $BIN/symmetry-merge -q --merge --to-level 0 "$d"/chunk-L$L0-*.dag -o "$d/root.ssvdag"
	[ "$(counts "$d/root.dag.stats.json")" = "$dag_counts" ] &&
	[ "$(counts "$d/root.ssvdag.stats.json")" = "$ssv_counts" ] &&
		pass "flat-counts-L0-$L0" || fail "flat-counts-L0-$L0"
	expect "flat-verify-L0-$L0" 0 '' $BIN/dag-verify "$d/root.ssvdag" "$d"/*.svo
done

# --- symmetry-merge --group 48 (kind ssvdag48): monolithic and chunked,
# lossless by dag-verify, the reduction tree and the flat merge giving the
# monolithic counts; --group 8 the default
expect group-bad 2 "--group '12' is not 8 or 48" $BIN/symmetry-merge --group 12 a.dag -o b.ssvdag
expect group-svo-to-dag 2 "unknown option --group" $BIN/svo-to-dag --group 48 a.svo -o b.dag
expect g48-mono 0 '' $BIN/symmetry-merge -q --group 48 "$T/m/chunk-L0-0.dag" -o "$T/m/chunk-L0-0.s48"
expect g48-mono-verify 0 '' $BIN/dag-verify "$T/m/chunk-L0-0.s48" "$T/m/chunk-L0-0.svo"
grep -q '"kind": "ssvdag48"' "$T/m/chunk-L0-0.s48.stats.json" && pass g48-kind || fail g48-kind
s48_counts=$(counts "$T/m/chunk-L0-0.s48.stats.json")
total() { tr -d '\n ' < "$1" | sed 's/.*"nodes":\([0-9]*\).*/\1/'; }
[ "$(total "$T/m/chunk-L0-0.s48.stats.json")" -lt "$(total "$T/m/chunk-L0-0.ssvdag.stats.json")" ] &&
	pass g48-fewer-nodes || fail g48-fewer-nodes "$s48_counts vs $ssv_counts"
$BIN/symmetry-merge -q --group 8 "$T/m/chunk-L0-0.dag" -o "$T/m/g8.ssvdag"
grep -q '"kind": "ssvdag"' "$T/m/g8.ssvdag.stats.json" &&
[ "$(counts "$T/m/g8.ssvdag.stats.json")" = "$ssv_counts" ] &&
	pass group-8-is-default || fail group-8-is-default
for L0 in 1 2; do
	d="$T/c$L0"
	mkdir -p "$d/t48"
	ok=1
	for f in "$d"/chunk-L$L0-*.dag; do
		b=${f##*/}
		$BIN/symmetry-merge -q --group 48 "$f" -o "$d/t48/${b%.dag}.s48" || ok=0
	done
	[ $ok = 1 ] && pass "g48-chunks-L0-$L0" || fail "g48-chunks-L0-$L0"
	# the reduction tree: --merge with --group 48 at every step
	if reduce_g48 "$d/t48" "$L0"; then
		[ "$(counts "$d/t48/chunk-L0-0.s48.stats.json")" = "$s48_counts" ] &&
			pass "g48-tree-counts-L0-$L0" ||
			fail "g48-tree-counts-L0-$L0" "$(counts "$d/t48/chunk-L0-0.s48.stats.json") != $s48_counts"
		expect "g48-tree-verify-L0-$L0" 0 '' $BIN/dag-verify "$d/t48/chunk-L0-0.s48" "$d"/*.svo
	else
		fail "g48-tree-L0-$L0"
	fi
	# mixed inputs: dag and ssvdag chunks merge into an ssvdag48
	expect "g48-flat-mixed-L0-$L0" 0 '' $BIN/symmetry-merge -q --group 48 --merge --to-level 0 \
		"$d"/chunk-L$L0-*.ssvdag -o "$d/root.s48"
	[ "$(counts "$d/root.s48.stats.json")" = "$s48_counts" ] &&
		pass "g48-flat-counts-L0-$L0" || fail "g48-flat-counts-L0-$L0"
	expect "g48-flat-verify-L0-$L0" 0 '' $BIN/dag-verify "$d/root.s48" "$d"/*.svo
	expect "g48-diff-vs-ssvdag-L0-$L0" 0 '^differing_voxels=0 ' $BIN/dag-verify --diff "$d/root.s48" "$d/root.ssvdag"
done
one48=$(ls "$T"/c2/t48/chunk-L2-*.s48 | head -1)
expect g48-into-ssvdag-refused 1 "wrong chunk kind: a ssvdag48 chunk, expected dag or ssvdag" \
	$BIN/symmetry-merge --merge "$one48" -o "$T/x.ssvdag"
# encode writes it as .ssvdag48 (tests/cli/encode.sh); render reads that
# encoding, not the chunk: a clear refusal
expect g48-encode 0 '' \
	$BIN/encode -q "$T/m/chunk-L0-0.dag" "$T/m/chunk-L0-0.s48" -o "$T/enc"
expect g48-render-refused 1 "ssvdag48" \
	$BIN/render "$T/m/chunk-L0-0.s48" -o "$T/x.png"
# the issue's figure (issue 13): the Stanford bunny at 2^9
if [ -f "$SHARED_DATA/stanford_bunny.ply" ]; then
	B="$T/bunny9"
	$BIN/voxelize "$SHARED_DATA/stanford_bunny.ply" -o "$B" --levels 9 --chunk-level 0 -q &&
	$BIN/svo-to-dag -q "$B/chunk-L0-0.svo" -o "$B/a.dag" &&
	$BIN/symmetry-merge -q "$B/a.dag" -o "$B/a.ssvdag" &&
	$BIN/symmetry-merge -q --group 48 "$B/a.dag" -o "$B/a.s48"
	got="$(total "$B/a.dag.stats.json") $(total "$B/a.ssvdag.stats.json") $(total "$B/a.s48.stats.json")"
	[ "$got" = "39969 25540 19288" ] && pass bunny9-issue-figure ||
		fail bunny9-issue-figure "SVDAG SSVDAG 48-group: $got, expected 39969 25540 19288"
	expect bunny9-g48-verify 0 '' $BIN/dag-verify "$B/a.s48" "$B/chunk-L0-0.svo"
else
	echo "SKIP bunny9-issue-figure (no $SHARED_DATA/stanford_bunny.ply)"
fi

# --- bad input: one clear line and exit 1 each, nothing left behind
S="$T/c2"
first=$(ls "$S"/chunk-L2-*.svo | head -1)
second=$(ls "$S"/chunk-L2-*.svo | sed -n 2p)
expect wrong-kind-svo-to-dag 1 "^svo-to-dag: cannot read '.*': wrong chunk kind: a dag chunk, expected svo$" \
	$BIN/svo-to-dag "${first%.svo}.dag" -o "$T/x.dag"
expect wrong-kind-symmetry-merge 1 "^symmetry-merge: cannot read '.*': wrong chunk kind: a svo chunk, expected dag" \
	$BIN/symmetry-merge "$first" -o "$T/x.ssvdag"
expect wrong-kind-merge-ssvdag-into-dag 1 "wrong chunk kind" \
	$BIN/svo-to-dag --merge "${first%.svo}.ssvdag" -o "$T/x.dag"
expect wrong-kind-merge-svo 1 "wrong chunk kind: a svo chunk, expected dag or ssvdag" \
	$BIN/symmetry-merge --merge "$first" -o "$T/x.ssvdag"
$BIN/voxelize "$MESH" -o "$T/L9" --levels 9 --chunk-level 2 -q
other=$(ls "$T"/L9/chunk-L2-*.svo | head -1)
$BIN/svo-to-dag -q "$other" -o "$T/L9.dag"
expect mismatched-depths 1 "inputs do not match: .* has 9 levels, .* has 8" \
	$BIN/svo-to-dag --merge "${first%.svo}.dag" "$T/L9.dag" -o "$T/x.dag"
expect overlapping-cells 1 "inputs do not match: overlapping cells" \
	$BIN/svo-to-dag --merge "${first%.svo}.dag" "${first%.svo}.dag" -o "$T/x.dag"
expect not-one-ancestor 1 "is not inside cell" \
	$BIN/svo-to-dag --merge --to-level 2 "${first%.svo}.dag" "${second%.svo}.dag" -o "$T/x.dag"
expect to-level-below-inputs 1 "below part chunk level" \
	$BIN/symmetry-merge --merge --to-level 3 "${first%.svo}.dag" -o "$T/x.ssvdag"
size=$(stat -c %s "${first%.svo}.dag")
head -c $((size / 2)) "${first%.svo}.dag" > "$T/cut.dag"
expect truncated 1 "^svo-to-dag: cannot read '.*cut.dag': truncated file" \
	$BIN/svo-to-dag --merge "$T/cut.dag" -o "$T/x.dag"
head -c $((size - 1)) "${first%.svo}.dag" > "$T/cut1.dag"
expect truncated-by-one 1 "cannot read '.*cut1.dag': (truncated file|checksum)" \
	$BIN/dag-verify "$T/cut1.dag" "$first"
expect missing-file 1 "cannot read '.*nonexistent.svo': I/O error" \
	$BIN/svo-to-dag "$T/nonexistent.svo" -o "$T/x.dag"
expect budget-svo-to-dag 1 "memory budget too small: needs about [0-9]+ MiB, budget --mem-budget 0 MiB" \
	$BIN/svo-to-dag --mem-budget 1K "$T/m/chunk-L0-0.svo" -o "$T/x.dag"
expect budget-merge 1 "memory budget too small" \
	$BIN/symmetry-merge --mem-budget 1M --merge "$S"/chunk-L2-*.dag -o "$T/x.ssvdag"
[ ! -e "$T/x.dag" ] && [ ! -e "$T/x.ssvdag" ] && [ -z "$(ls "$T" | grep tmp)" ] &&
	pass nothing-left-behind || fail nothing-left-behind "$(ls "$T")"
# dag-verify catches a difference: a missing chunk, another scene
expect verify-missing-chunk 1 "differs from the SVO chunks in [0-9]+ voxels; first at voxel \([0-9]+, [0-9]+, [0-9]+\), set in the DAG only" \
	$BIN/dag-verify "$S/root.dag" $(ls "$S"/*.svo | tail -n +2)
SHARED=${VOXDAG_SHARED_DATA:-../shared/data}
if [ -f "$SHARED/stanford_dragon_res4.ply" ]; then
	$BIN/voxelize "$SHARED/stanford_dragon_res4.ply" -o "$T/dr" --levels $L --chunk-level 0 -q
	expect verify-other-scene 1 "differs from the SVO chunks in [0-9]+ voxels; first at voxel" \
		$BIN/dag-verify "$T/m/chunk-L0-0.ssvdag" "$T/dr/chunk-L0-0.svo"
else
	echo "SKIP verify-other-scene (no $SHARED/stanford_dragon_res4.ply)"
fi
expect verify-overlap 1 "two SVO chunks cover" \
	$BIN/dag-verify "$S/root.dag" "$first" "$first"
expect verify-depths 1 "is not inside the DAG's cell" \
	$BIN/dag-verify "$S/root.dag" "$other"

# --help lists exactly the options in the code (both stages share theirs)
help_lists_options help_matches_code_svo_to_dag svo-to-dag stages/lib/dag/stage.c
help_lists_options help_matches_code_symmetry_merge symmetry-merge stages/lib/dag/stage.c
help_lists_options help_matches_code_dag_verify dag-verify stages/dag-verify/main.c
exit 0
