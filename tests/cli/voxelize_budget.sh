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
# the same with colours: a PLY with vertex colours and an OBJ with vt, a
# texture and two materials, each 1.21 million vertices of 16 bytes (19.4
# MiB, over the 18 MiB share of 36 MiB). Their .svo and .col chunks are
# the bytes of a run that holds the vertices in memory, but for the
# provenance section, which names the arguments (--mem-budget).
strip_prov() { perl -e '
	local $/; my $b = <STDIN>;
	my $hs = unpack("V", substr($b, 12, 4)); my $ns = unpack("V", substr($b, 100, 4));
	print substr($b, 0, $hs); my $p = $hs;
	for (1 .. $ns) { my $st = unpack("Q<", substr($b, $p + 16, 8));
		print substr($b, $p, 32 + $st) if substr($b, $p, 4) ne "PROV";
		$p += 32 + $st; }' < "$1"; }
same_chunks() { # NAME SPILLED_DIR MEMORY_DIR
	local f n=0 diff=
	for f in "$3"/*.svo "$3"/*.col; do
		[ -f "$f" ] || continue
		n=$((n + 1))
		cmp -s <(strip_prov "$f") <(strip_prov "$2/${f##*/}") || diff="$diff ${f##*/}"
	done
	local col
	col=$(ls "$3" | grep -c '\.col$')
	if [ -z "$diff" ] && [ "$col" -gt 1 ] &&
	   [ "$(ls "$2" | grep -cE '\.(svo|col)$')" -eq "$n" ]; then
		pass "$1"
	else
		fail "$1" "differ:${diff:- none}; $n files, $col .col"
	fi
}
if command -v perl >/dev/null; then
	perl -e '
	my $n = 1100; my $s = 11; my $c = int(($n - 1) / $s);
	print "ply\nformat binary_little_endian 1.0\nelement vertex ", $n * $n,
	    "\nproperty float x\nproperty float y\nproperty float z\n",
	    "property uchar red\nproperty uchar green\nproperty uchar blue\n",
	    "element face ", 2 * $c * $c,
	    "\nproperty list uchar int vertex_indices\nend_header\n";
	for my $j (0 .. $n - 1) { for my $i (0 .. $n - 1) {
	    print pack("f<3C3", $i, $j, 20 * sin($i / 37.0) * cos($j / 23.0),
		($i * 7) % 256, ($j * 5) % 256, ($i + $j) % 256); } }
	for my $j (0 .. $c - 1) { for my $i (0 .. $c - 1) {
	    my $a = $s * ($j * $n + $i); my $b = $a + $s; my $d = $a + $s * $n;
	    print pack("Cl<3", 3, $a, $b, $d + $s), pack("Cl<3", 3, $a, $d + $s, $d); } }
	' > "$T/gridc.ply"
	mkdir -p "$T/tex"
	cp tests/data/textured/checker.png "$T/tex/"
	printf 'newmtl kd\nKd 0.2 0.7 0.3\nnewmtl chk\nKd 1 1 1\nmap_Kd checker.png\n' \
		> "$T/tex/grid.mtl"
	perl -e '
	my $n = 1100; my $s = 11; my $c = int(($n - 1) / $s);
	print "mtllib grid.mtl\nvt 0 0\nvt 1 0\nvt 0 1\nvt 1 1\n";
	for my $j (0 .. $n - 1) { for my $i (0 .. $n - 1) {
	    printf "v %d %d %.3f\n", $i, $j, 20 * sin($i / 37.0) * cos($j / 23.0); } }
	for my $j (0 .. $c - 1) {
	    print $j % 3 ? "usemtl chk\n" : "usemtl kd\n";
	    for my $i (0 .. $c - 1) {
		my $a = 1 + $s * ($j * $n + $i); my $b = $a + $s;
		my $d = $a + $s * $n; my $e = $d + $s;
		if ($i % 4) { print "f $a/1 $b/2 $e/4 $d/3\n" }
		else { print "f $a $b $e\nf $a $e $d\n" } } }
	' > "$T/tex/grid.obj"
	for m in "$T/gridc.ply" "$T/tex/grid.obj"; do
		n=$(basename "${m%.*}")_${m##*.}
		expect "budget_spill_colour_$n" 0 '' \
			run $V "$m" -o "$T/sc_$n" --levels 9 --chunk-level 1 --mem-budget 36M -q
		within "budget_spill_colour_${n}_peak" 36
		$V "$m" -o "$T/mc_$n" --levels 9 --chunk-level 1 -q
		same_chunks "budget_spill_colour_${n}_same_bytes" "$T/sc_$n" "$T/mc_$n"
	done
	grep -q '"textures_loaded": 1' "$T/sc_grid_obj/voxelize.stats.json" &&
		pass budget_spill_colour_textured ||
		fail budget_spill_colour_textured "$(cat "$T/sc_grid_obj/voxelize.stats.json")"
else
	echo "SKIP budget_spill_colour (perl absent)"
fi
# texture coordinates count against the same share and spill with the
# vertices: an OBJ of 1.0 million vertices (15.3 MiB, under the 18 MiB
# share of 36 MiB) with a vt each (7.6 MiB more, over it), indexed
# absolutely, relatively and crosswise, a textured and a plain material;
# and an AC3D file whose one big object (1.69 million vertices, 19.3 MiB)
# is over the share, between small objects, textured, with strips and
# under a rotated parent. Spilled, each stays under the budget and its
# .svo and .col chunks are the bytes of an in-memory run.
if command -v perl >/dev/null; then
	mkdir -p "$T/vt"
	cp tests/data/textured/checker.png "$T/vt/"
	printf 'newmtl kd\nKd 0.2 0.7 0.3\nnewmtl chk\nKd 1 1 1\nmap_Kd checker.png\n' \
		> "$T/vt/vt.mtl"
	perl -e '
	my $n = 1000; my $s = 11; my $c = int(($n - 1) / $s); my $nv = $n * $n;
	print "mtllib vt.mtl\n";
	for my $j (0 .. $n - 1) { for my $i (0 .. $n - 1) {
	    printf "v %d %d %.3f\nvt %.4f %.4f\n", $i, $j,
		20 * sin($i / 37.0) * cos($j / 23.0), $i / 97.0, $j / 89.0; } }
	for my $j (0 .. $c - 1) {
	    print $j % 3 ? "usemtl chk\n" : "usemtl kd\n";
	    for my $i (0 .. $c - 1) {
		my $a = 1 + $s * ($j * $n + $i); my $b = $a + $s;
		my $d = $a + $s * $n; my $e = $d + $s;
		if ($i % 4 == 1) { print "f $a/$a $b/$b $e/$e $d/$d\n" }
		elsif ($i % 4 == 2) { my ($x, $y, $z) = map { $_ - $nv - 1 } ($a, $b, $e);
		    print "f $x/$x $y/$y $z/$z\nf $a/$a/1 $e/$e/1 $d/$d/1\n" }
		elsif ($i % 7 == 0) { print "f $a $b/$b $e/$e\nf $a/$a $e/$e $d/$d\n" }
		else { print "f $a/$e $b/$d $e/$a\nf $a/$b $e/$a $d/$b\n" } } }
	' > "$T/vt/vt.obj"
	mkdir -p "$T/ac"
	cp tests/data/textured/checker.png "$T/ac/"
	perl -e '
	my $n = 1300; my $s = 7; my $c = int(($n - 1) / $s);
	my $m = "rgb 0.9 0.1 0.1  amb 0.2 0.2 0.2  emis 0 0 0  spec 0 0 0  shi 10  trans 0";
	print "AC3Db\nMATERIAL \"red\" $m\nMATERIAL \"sea\" $m\nOBJECT world\nkids 3\n";
	print "OBJECT poly\nname \"small\"\nloc 1 2 3\nnumvert 4\n0 0 0\n100 0 0\n",
	    "100 100 0\n0 100 50\nnumsurf 1\nSURF 0x10\nmat 1\nrefs 4\n0 0 0\n",
	    "1 1 0\n2 1 1\n3 0 1\nkids 0\n";
	print "OBJECT group\nrot 0 1 0 -1 0 0 0 0 1\nloc 5 -3 1\nkids 1\n";
	print "OBJECT poly\nname \"grid\"\ntexture \"checker.png\"\ntexrep 2 2\n",
	    "numvert ", $n * $n, "\n";
	for my $j (0 .. $n - 1) { for my $i (0 .. $n - 1) {
	    printf "%d %d %.3f\n", $i, $j, 20 * sin($i / 37.0) * cos($j / 23.0); } }
	print "numsurf ", $c * $c, "\n";
	for my $j (0 .. $c - 1) { for my $i (0 .. $c - 1) {
	    my $a = $s * ($j * $n + $i); my $b = $a + $s; my $d = $a + $s * $n;
	    my $e = $d + $s; my $k = ($i + $j) % 2;
	    if ($i % 5 == 3) { print "SURF 0x14\nmat $k\nrefs 4\n$a 0 0\n$b 1 0\n$d 0 1\n$e 1 1\n" }
	    else { print "SURF 0x10\nmat $k\nrefs 4\n$a 0 0\n$b 0.3 0\n$e 1 1\n$d 0 1\n" } } }
	print "kids 0\nOBJECT poly\nname \"last\"\nnumvert 3\n0 0 0\n900 0 0\n",
	    "0 900 9\nnumsurf 1\nSURF 0x10\nmat 0\nrefs 3\n0\n1\n2\nkids 0\n";
	' > "$T/ac/big.ac"
	for m in "$T/vt/vt.obj" "$T/ac/big.ac"; do
		n=spill_$(basename "${m%.*}")_${m##*.}
		expect "budget_$n" 0 '' \
			run $V "$m" -o "$T/s_$n" --levels 9 --chunk-level 1 --mem-budget 36M -q
		within "budget_${n}_peak" 36
		$V "$m" -o "$T/m_$n" --levels 9 --chunk-level 1 -q
		same_chunks "budget_${n}_same_bytes" "$T/s_$n" "$T/m_$n"
		grep -q '"textures_loaded": 1' "$T/s_$n/voxelize.stats.json" &&
			pass "budget_${n}_textured" ||
			fail "budget_${n}_textured" "$(cat "$T/s_$n/voxelize.stats.json")"
	done
else
	echo "SKIP budget_spill_vt, budget_spill_ac3d (perl absent)"
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
