#!/usr/bin/env bash
# lossy-cluster under a tight --mem-budget (issue 15): the bundled bunny at
# 2^11, whose unlimited run peaks near 60 MiB, clustered within 48 MiB.
# Every phase must stay under the budget (the similarity graph spills and
# is clustered a few components at a time, the Markov clustering's
# matrices and the final difference's tables count against it): the peak
# RSS, as the kernel reports it to GNU time and as the stage's statistics
# record it, is below the budget; and the chunk is byte for byte the
# unlimited run's (its provenance, which names the arguments, aside). A
# budget far too small fails with one line naming what is needed.
set -u
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh

BUDGET_MIB=48

"$BIN/voxelize" tests/data/bunny.ply -o "$T/vox" --levels 11 --chunk-level 0 -q --no-colours
"$BIN/svo-to-dag" "$T/vox/chunk-L0-0.svo" -o "$T/root.dag" -q
rm -rf "$T/vox"

expect budget_free 0 '' "$BIN/lossy-cluster" "$T/root.dag" -o "$T/free.dag" -q
free_peak=$(jq .peak_rss_bytes "$T/free.dag.stats.json")
# the budget is tight only if the unlimited run passes it
if [ "$free_peak" -gt $((BUDGET_MIB << 20)) ]; then
	pass budget_is_tight
else
	fail budget_is_tight "the unlimited run peaked at $free_peak bytes," \
		"under the test's budget of $BUDGET_MIB MiB: raise the scene"
fi

if [ -x /usr/bin/time ]; then
	expect budget_run 0 '' /usr/bin/time -f 'maxrss_kib=%M' -o "$T/time" \
		"$BIN/lossy-cluster" "$T/root.dag" -o "$T/tight.dag" -q --mem-budget ${BUDGET_MIB}M
	kib=$(sed -n 's/^maxrss_kib=//p' "$T/time")
	if [ -n "$kib" ] && [ "$kib" -lt $((BUDGET_MIB * 1024)) ]; then
		pass budget_peak_time
	else
		fail budget_peak_time "GNU time: peak ${kib:-?} KiB, budget $((BUDGET_MIB * 1024)) KiB"
	fi
else
	echo "SKIP budget_peak_time (no /usr/bin/time)"
	expect budget_run 0 '' "$BIN/lossy-cluster" "$T/root.dag" -o "$T/tight.dag" \
		-q --mem-budget ${BUDGET_MIB}M
fi
peak=$(jq .peak_rss_bytes "$T/tight.dag.stats.json" 2>/dev/null || echo 0)
if [ "$peak" -gt 0 ] && [ "$peak" -lt $((BUDGET_MIB << 20)) ]; then
	pass budget_peak_stats
else
	fail budget_peak_stats "stats: peak $peak bytes, budget $((BUDGET_MIB << 20))"
fi
# the budget was felt: some level's graph went to disk in several groups
if [ "$(jq '[.per_level[] | select(.graph_spilled == 1 and .spill_buckets > 1)] | length' \
	"$T/tight.dag.stats.json" 2>/dev/null || echo 0)" -gt 0 ]; then
	pass budget_spilled
else
	fail budget_spilled "no level's graph was split under $BUDGET_MIB MiB"
fi
if [ -f "$T/tight.dag" ] &&
   cmp -s <(chunk_sans_prov "$T/free.dag") <(chunk_sans_prov "$T/tight.dag"); then
	pass budget_same_bytes
else
	fail budget_same_bytes "the chunk under the budget differs from the unlimited one"
fi
# the provenance is the only difference: the check above can see one
if [ -f "$T/tight.dag" ] && ! cmp -s "$T/free.dag" "$T/tight.dag"; then
	pass budget_prov_differs
else
	fail budget_prov_differs "the two chunks are identical with their provenance"
fi

mkdir -p "$T/bad"
expect budget_too_small 1 'needs (at least|about) [0-9]+ MiB, over the budget of 20 MiB' \
	"$BIN/lossy-cluster" "$T/root.dag" -o "$T/bad/x.dag" --mem-budget 20M
expect_no_chunks budget_too_small_leaves_nothing "$T/bad"
