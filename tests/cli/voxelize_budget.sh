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
# the vertex array over its share (half the budget): the faces are joined
# with the vertices on disk, and the run stays under the budget with the
# voxels of a run that holds them in memory. 1.69 million vertices (19.3
# MiB, over the 18 MiB share of 36 MiB), 19,602 triangles spread over them.
if command -v perl >/dev/null; then
	perl -e '
	my $n = 1300; my $s = 13; my $c = int(($n - 1) / $s);
	my $nf = 2 * $c * $c;
	print "ply\nformat binary_little_endian 1.0\nelement vertex ", $n * $n,
	    "\nproperty float x\nproperty float y\nproperty float z\n",
	    "element face $nf\nproperty list uchar int vertex_indices\nend_header\n";
	for my $j (0 .. $n - 1) { for my $i (0 .. $n - 1) {
	    print pack("f<3", $i, $j, 20 * sin($i / 37.0) * cos($j / 23.0)); } }
	for my $j (0 .. $c - 1) { for my $i (0 .. $c - 1) {
	    my $a = $s * ($j * $n + $i); my $b = $a + $s; my $d = $a + $s * $n;
	    print pack("Cl<3", 3, $a, $b, $d + $s), pack("Cl<3", 3, $a, $d + $s, $d); } }
	' > "$T/grid.ply"
	expect budget_vertices_spill 0 '' \
		run $V "$T/grid.ply" -o "$T/d" --levels 9 --chunk-level 1 --mem-budget 36M -q
	within budget_vertices_spill_peak 36
	$V "$T/grid.ply" -o "$T/d2" --levels 9 --chunk-level 1 -q
	for f in "$T"/d2/*.svo; do $BIN/svo-to-dag -q "$f" -o "${f%.svo}.dag"; done
	$BIN/svo-to-dag -q --merge "$T"/d2/*.dag -o "$T/d2.dag"
	expect budget_vertices_spill_same_voxels 0 '' \
		$BIN/dag-verify "$T/d2.dag" "$T"/d/*.svo
	[ -z "$(ls -a "$T/d" | grep -i tmp)" ] && pass budget_vertices_spill_clean ||
		fail budget_vertices_spill_clean "$(ls -a "$T/d")"
else
	echo "SKIP budget_vertices_spill (perl absent)"
fi
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
