#!/usr/bin/env bash
# voxelize within --mem-budget, measured from the outside (GNU time's
# maximum resident set size): each run either succeeds under the budget or
# fails early with one line saying how much it needs; never killed.
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh
V=$BIN/voxelize
BUNNY=tests/data/bunny.ply
if [ ! -x /usr/bin/time ]; then
	echo "SKIP voxelize_budget (/usr/bin/time absent)"
	exit 0
fi

# within NAME BUDGET_MIB: GNU time's peak of the last run is under budget
within() {
	local kib
	kib=$(tail -n 1 "$T/rss")
	if [ -n "$kib" ] && [ "$kib" -le $(($2 * 1024)) ]; then
		pass "$1"
	else
		fail "$1" "peak ${kib:-?} KiB over --mem-budget $2 MiB"
	fi
}
run() { /usr/bin/time -f %M -o "$T/rss" "$@"; }

# 2^21 at one cell: the estimate stays bounded and the plan refuses
expect budget_l21_chunk0 1 'about [0-9]+ MiB needed' \
	run $V $BUNNY -o "$T/a" --levels 21 --chunk-level 0 --mem-budget 64M -q
within budget_l21_chunk0_peak 64
expect_no_chunks budget_l21_chunk0_clean "$T/a"
# 2^16 with a budget too small for any chunk level
expect budget_l16_small 1 'about [0-9]+ MiB needed' \
	run $V $BUNNY -o "$T/b" --levels 16 --mem-budget 40M -q
within budget_l16_small_peak 40
# a fixed chunk level whose cells are too large
expect budget_fixed_level 1 'chunk level 1 .about [0-9]+ MiB needed' \
	run $V $BUNNY -o "$T/c" --levels 14 --chunk-level 1 --mem-budget 48M -q
within budget_fixed_level_peak 48
# the vertex array over its share (half the budget), refused from the header
expect budget_vertices 1 '34834 vertices need 409 KiB' \
	run $V $BUNNY -o "$T/d" --levels 8 --mem-budget 600K -q
within budget_vertices_peak 16
# a run that fits: under the budget by GNU time and by its own report
expect budget_fits 0 '' run $V $BUNNY -o "$T/e" --levels 12 --mem-budget 64M -q
within budget_fits_peak 64
peak=$(sed -n 's/^  "peak_rss_bytes": \([0-9]*\),*$/\1/p' "$T/e/voxelize.stats.json")
if [ -n "$peak" ] && [ "$peak" -le $((64 << 20)) ] &&
   [ "$peak" -ge $(( $(tail -n 1 "$T/rss") * 1024 * 9 / 10 )) ]; then
	pass budget_fits_own_report
else
	fail budget_fits_own_report "stats peak ${peak:-?} vs GNU time $(tail -n 1 "$T/rss") KiB"
fi
