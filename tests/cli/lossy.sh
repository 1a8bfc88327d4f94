#!/usr/bin/env bash
# Command-line tests of lossy-cluster and dag-verify --diff on the bundled
# bunny: the reported changed voxels equal the walked difference, --max-refs
# 0 is the identity, --threads does not change the bytes, bad input fails
# with one line and leaves nothing.
set -u
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh

"$BIN/voxelize" tests/data/bunny.ply -o "$T/vox" --levels 8 --chunk-level 0 -q
"$BIN/svo-to-dag" "$T/vox/chunk-L0-0.svo" -o "$T/root.dag" -q
"$BIN/symmetry-merge" "$T/root.dag" -o "$T/root.ssvdag" -q

help_lists_options lossy_help lossy-cluster stages/lossy-cluster/main.c
help_lists_options verify_help dag-verify stages/dag-verify/main.c

expect lossy_run 0 '' "$BIN/lossy-cluster" "$T/root.dag" -o "$T/l1.dag" -q -j 1
expect lossy_run_threads 0 '' "$BIN/lossy-cluster" "$T/root.dag" -o "$T/l2.dag" -q -j 3
# the same chunk for any --threads, provenance (which names the args) aside
if cmp -s <("$BIN/dag-verify" --diff "$T/l1.dag" "$T/l2.dag") \
	<(echo "differing_voxels=0 only_a=0 only_b=0") &&
   [ "$(stat -c %s "$T/l1.dag")" -eq "$(stat -c %s "$T/l2.dag")" ]; then
	pass lossy_threads_same
else
	fail lossy_threads_same
fi
expect lossy_valid 0 '' "$BIN/chunk-check" "$T/l1.dag"
# the stage's count equals the walked difference
want=$(tr -d ' \n' < "$T/l1.dag.stats.json" |
       sed 's/.*"voxels_set":\([0-9]*\),"voxels_cleared":\([0-9]*\).*/only_a=\2 only_b=\1/')
got=$("$BIN/dag-verify" --diff "$T/root.dag" "$T/l1.dag")
if [ "${got#* }" = "$want" ] && [ "$got" != "differing_voxels=0 only_a=0 only_b=0" ]; then
	pass lossy_diff_equals_stats
else
	fail lossy_diff_equals_stats "dag-verify: $got" "stats: $want"
fi
expect lossy_refs0 0 '' "$BIN/lossy-cluster" "$T/root.dag" -o "$T/l0.dag" -q --max-refs 0
expect lossy_refs0_same 0 'differing_voxels=0 ' "$BIN/dag-verify" --diff "$T/root.dag" "$T/l0.dag"
if [ "$(tr -d ' \n' < "$T/l0.dag.stats.json" | grep -o '"nodes_before":[0-9]*,"nodes_after":[0-9]*' |
	head -1 | sed 's/"nodes_before":\([0-9]*\),"nodes_after":\([0-9]*\)/\1 \2/' | awk '{print ($1 == $2)}')" = 1 ]; then
	pass lossy_refs0_nodes
else
	fail lossy_refs0_nodes
fi

# --levels 7: the scene at 2^7, the root DAG cut there, is the one the
# voxelizer makes at 2^7 directly: the same lossy DAG as clustering that
expect lossy_levels 0 '' "$BIN/lossy-cluster" "$T/root.dag" -o "$T/cut7.dag" -q --levels 7
"$BIN/voxelize" tests/data/bunny.ply -o "$T/vox7" --levels 7 --chunk-level 0 -q
"$BIN/svo-to-dag" "$T/vox7/chunk-L0-0.svo" -o "$T/root7.dag" -q
expect lossy_direct7 0 '' "$BIN/lossy-cluster" "$T/root7.dag" -o "$T/direct7.dag" -q
expect lossy_levels_equals_direct 0 '^differing_voxels=0 ' "$BIN/dag-verify" --diff "$T/cut7.dag" "$T/direct7.dag"
if [ "$(jq -c '[.levels, .voxels_before, .nodes_before, .nodes_after, .voxels_changed]' "$T/cut7.dag.stats.json")" = \
     "$(jq -c '[.levels, .voxels_before, .nodes_before, .nodes_after, .voxels_changed]' "$T/direct7.dag.stats.json")" ] &&
   [ "$(jq .levels "$T/cut7.dag.stats.json")" = 7 ]; then
	pass lossy_levels_stats_equal_direct
else
	fail lossy_levels_stats_equal_direct "$(jq -c '[.levels, .voxels_before, .nodes_before, .nodes_after]' "$T/cut7.dag.stats.json" "$T/direct7.dag.stats.json")"
fi

mkdir -p "$T/bad"
expect bad_levels_deeper 1 "lossy-cluster: cannot cut .* at 9 levels: it has only 8 levels" \
	"$BIN/lossy-cluster" "$T/root.dag" -o "$T/bad/x.dag" --levels 9
expect bad_levels_zero 2 'levels' "$BIN/lossy-cluster" "$T/root.dag" -o "$T/bad/x.dag" --levels 0
expect bad_svo 1 'lossy-cluster: cannot read' "$BIN/lossy-cluster" "$T/vox/chunk-L0-0.svo" -o "$T/bad/x.dag"
expect bad_ssvdag 1 'lossy-cluster: cannot read.*ssvdag' "$BIN/lossy-cluster" "$T/root.ssvdag" -o "$T/bad/x.dag"
head -c 300 "$T/root.dag" > "$T/trunc.dag"
expect bad_truncated 1 'lossy-cluster: cannot read' "$BIN/lossy-cluster" "$T/trunc.dag" -o "$T/bad/x.dag"
expect bad_missing 1 'lossy-cluster: cannot read' "$BIN/lossy-cluster" "$T/none.dag" -o "$T/bad/x.dag"
expect bad_inflation 2 'inflation' "$BIN/lossy-cluster" "$T/root.dag" -o "$T/bad/x.dag" --inflation 1
expect bad_inflation_neg 2 'inflation' "$BIN/lossy-cluster" "$T/root.dag" -o "$T/bad/x.dag" --inflation -3
expect bad_inflation_nan 2 'inflation' "$BIN/lossy-cluster" "$T/root.dag" -o "$T/bad/x.dag" --inflation nan
expect bad_diff 2 'diff-factor' "$BIN/lossy-cluster" "$T/root.dag" -o "$T/bad/x.dag" --diff-factor -1
expect bad_diff_huge 2 'diff-factor' "$BIN/lossy-cluster" "$T/root.dag" -o "$T/bad/x.dag" --diff-factor 1e300
expect bad_refs 2 'max-refs' "$BIN/lossy-cluster" "$T/root.dag" -o "$T/bad/x.dag" --max-refs -1
expect bad_refs_huge 2 'max-refs' "$BIN/lossy-cluster" "$T/root.dag" -o "$T/bad/x.dag" --max-refs 99999999999
expect bad_threads 2 'threads' "$BIN/lossy-cluster" "$T/root.dag" -o "$T/bad/x.dag" -j 0
expect bad_budget 1 'budget' "$BIN/lossy-cluster" "$T/root.dag" -o "$T/bad/x.dag" --mem-budget 1K
expect bad_no_output 2 'no output' "$BIN/lossy-cluster" "$T/root.dag"
expect_no_chunks bad_leaves_nothing "$T/bad"
# an SSVDAG chunk or an encoding is expanded to bricks: the same voxels
expect diff_ssvdag 0 '^differing_voxels=0 only_a=0 only_b=0$' "$BIN/dag-verify" --diff "$T/root.dag" "$T/root.ssvdag"
expect diff_ssvdag_lossy 0 "^differing_voxels=$(jq .voxels_changed "$T/l1.dag.stats.json") " \
	"$BIN/dag-verify" --diff "$T/root.ssvdag" "$T/l1.dag"
expect diff_svo 1 'dag-verify: cannot read' "$BIN/dag-verify" --diff "$T/root.dag" "$T/vox/chunk-L0-0.svo"
expect diff_unknown 1 'dag-verify: cannot read' "$BIN/dag-verify" --diff "$T/root.dag" "$T/none.svdag"
expect diff_one 2 'two' "$BIN/dag-verify" --diff "$T/root.dag"
