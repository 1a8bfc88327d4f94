#!/usr/bin/env bash
# The 48-group table (issue 13): every mesh of ../shared/data at 2^10 and
# 2^12 (LEVELS="10 12" to change), voxelized as one chunk (monolithic; when
# one chunk does not fit the budget, in chunks merged to the root, which
# gives the same DAGs), through svo-to-dag, symmetry-merge (8 and 48) and
# encode, as one markdown table: SVDAG, SSVDAG and 48-group node counts
# (distinct nodes over all levels, as the encodings count them) and the
# counted bytes of .esvdag, .ssvdag and .ssvdag48 (file minus header,
# schemas/encodings.md), with bits per voxel of the last two. Every
# .ssvdag48 is checked lossless against the SVO with dag-verify.
# Skips cleanly when the data is absent. KEEP=DIR keeps the statistics.
set -u
cd "$(dirname "$0")/../.."
DATA=${VOXDAG_SHARED_DATA:-../shared/data}
LEVELS=${LEVELS:-10 12}
BUDGET=${BUDGET:-2GiB}
OUT=out/bench/g48
if [ ! -d "$DATA" ]; then
	echo "g48_table: $DATA is absent; nothing to measure"
	exit 0
fi
for t in voxelize svo-to-dag symmetry-merge encode dag-verify; do
	[ -x "out/bin/$t" ] || { echo "g48_table: out/bin/$t missing (make all)"; exit 1; }
done
command -v jq > /dev/null || { echo "g48_table: needs jq"; exit 1; }
B=out/bin
rm -rf "$OUT" && mkdir -p "$OUT" || exit 1

printf '| mesh | res | voxels | nodes SVDAG | nodes SSVDAG | nodes 48 | 48/SSVDAG | B .esvdag | B .ssvdag | B .ssvdag48 | .ssvdag48/.ssvdag | bpv .ssvdag | bpv .ssvdag48 | how | lossless |\n'
printf '|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---|\n'
row() { # row MESH LEVELS
	local m=$1 L=$2 d=$OUT/$(basename "$1" .ply)-$2 how=mono ok
	mkdir -p "$d"
	if $B/voxelize "$m" -o "$d/vox" --levels "$L" --chunk-level 0 --no-colours \
		--mem-budget "$BUDGET" -q 2> "$d/err" &&
	   $B/svo-to-dag -q "$d/vox/chunk-L0-0.svo" -o "$d/root.dag" --mem-budget "$BUDGET" 2>> "$d/err"; then
		:
	else
		how=chunked
		rm -rf "$d/vox"
		$B/voxelize "$m" -o "$d/vox" --levels "$L" --no-colours \
			--mem-budget "$BUDGET" -q 2>> "$d/err" || { echo "| $(basename "$m" .ply) | $L | voxelize failed: $(tail -1 "$d/err") |"; return; }
		for f in "$d"/vox/*.svo; do
			$B/svo-to-dag -q "$f" -o "${f%.svo}.dag" 2>> "$d/err" || return
		done
		$B/svo-to-dag -q --merge --to-level 0 "$d"/vox/*.dag -o "$d/root.dag" 2>> "$d/err" || return
	fi
	$B/symmetry-merge -q "$d/root.dag" -o "$d/root.ssvdag" --mem-budget "$BUDGET" 2>> "$d/err" &&
	$B/symmetry-merge -q --group 48 "$d/root.dag" -o "$d/root.s48" --mem-budget "$BUDGET" 2>> "$d/err" &&
	$B/encode -q "$d/root.dag" "$d/root.ssvdag" "$d/root.s48" -o "$d/enc" -n s \
		--min-level "$L" --mem-budget "$BUDGET" 2>> "$d/err" ||
		{ echo "| $(basename "$m" .ply) | $L | failed: $(tail -1 "$d/err") |"; return; }
	$B/dag-verify -q "$d/enc/s.ssvdag48" "$d"/vox/*.svo 2>> "$d/err" && ok=yes || ok=NO
	jq -r --arg mesh "$(basename "$m" .ply)" --arg how "$how" --arg ok "$ok" '
		def pct(a; b): (10000 * a / b | round) / 100;
		def bpv(b): (8000 * b / .voxels | round) / 1000;
		"| \($mesh) | 2^\(.levels) | \(.voxels) | \(.nodes_svdag) | \(.nodes_ssvdag) | \(.nodes_ssvdag48) | \(pct(.nodes_ssvdag48; .nodes_ssvdag))% | \(.bytes_esvdag) | \(.bytes_ssvdag) | \(.bytes_ssvdag48) | \(pct(.bytes_ssvdag48; .bytes_ssvdag))% | \(bpv(.bytes_ssvdag)) | \(bpv(.bytes_ssvdag48)) | \($how) | \($ok) |"' \
		"$d/enc/s.encode.stats.json"
	if [ -n "${KEEP:-}" ]; then
		mkdir -p "$KEEP" && cp "$d/enc/s.encode.stats.json" "$KEEP/$(basename "$m" .ply)-$L.encode.stats.json"
		cp "$d"/root.*.stats.json "$KEEP/" 2>/dev/null
	fi
	rm -rf "$d"
}
for L in $LEVELS; do
	for m in "$DATA"/*.ply; do
		row "$m" "$L"
	done
done
echo
echo "cores $(nproc), load $(cut -d' ' -f1-3 /proc/loadavg)"
