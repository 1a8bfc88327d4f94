#!/usr/bin/env bash
# The lossy SVDAG table (issue 15): every mesh of ../shared/data at 2^10
# and 2^12 (LEVELS="10 12" to change), through the stages by hand as the
# runner chains them (voxelize, svo-to-dag, lossy-cluster with the paper's
# defaults 2.0 / 1.0 / 1, symmetry-merge and encode of both DAGs), as one
# markdown table: nodes and MB lossless -> lossy for SVDAG, ESVDAG and
# SSVDAG (sizes are the encodings' bytes), the error rate (voxels changed /
# voxels), the net voxel count change, lossy-cluster's lossy phase (wall
# and CPU seconds: the machine is shared, CPU is the comparable figure)
# and its peak memory (GNU time, wait4), beside the reference figures of
# the issue where they exist. Skips cleanly when the data is absent.
# KEEP=DIR keeps every run's statistics files there.
set -u
cd "$(dirname "$0")/../.."
DATA=${VOXDAG_SHARED_DATA:-../shared/data}
LEVELS=${LEVELS:-10 12}
OUT=out/bench/lossy
if [ ! -d "$DATA" ]; then
	echo "lossy_table: $DATA is absent; nothing to measure"
	exit 0
fi
for t in voxelize svo-to-dag lossy-cluster symmetry-merge encode; do
	[ -x "out/bin/$t" ] || { echo "lossy_table: out/bin/$t missing (make all)"; exit 1; }
done
command -v jq > /dev/null || { echo "lossy_table: needs jq"; exit 1; }
B=out/bin
rm -rf "$OUT" && mkdir -p "$OUT" || exit 1

# The issue's reference (SymVox + van der Laan's code, same meshes, same
# grid, defaults): reachable LSVDAG vs SVDAG nodes, net voxel count change,
# lossy phase seconds.
ref() { # ref MESH L
	case "$1 $2" in
	"stanford_dragon 10") echo "77,276 vs 92,909 (-16.8%), count 0.13%, 1.9 s" ;;
	"stanford_dragon 11") echo "200,235 vs 254,787 (-21.4%), count 0.11%, 7.5 s" ;;
	"cg57_cruiser 10") echo "19,287 vs 21,887 (-11.9%)" ;;
	"cg57_cruiser 11") echo "-14.0%" ;;
	esac
}

echo "lossy_table: $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg), inflation 2.0, diff factor 1.0, max refs 1"
echo
echo "| mesh | L | SVDAG nodes | SVDAG MB | ESVDAG MB | SSVDAG nodes | SSVDAG MB | error | count change | lossy s (CPU s) | peak MiB | reference |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|"
row() { # row MESH.ply L
	local m=$1 L=$2 name d
	name=$(basename "$m" .ply)
	d=$OUT/$name-$L
	mkdir -p "$d"
	if ! { $B/voxelize "$m" -o "$d/vox" --levels "$L" --chunk-level 0 -q --no-colours &&
		$B/svo-to-dag "$d/vox/chunk-L0-0.svo" -o "$d/root.dag" -q &&
		rm -rf "$d/vox" &&
		/usr/bin/time -f %M -o "$d/time" $B/lossy-cluster "$d/root.dag" -o "$d/lossy.dag" -q &&
		$B/symmetry-merge "$d/root.dag" -o "$d/root.sdag" -q &&
		$B/symmetry-merge "$d/lossy.dag" -o "$d/lossy.sdag" -q &&
		$B/encode "$d/root.dag" "$d/root.sdag" -o "$d/enc" --name s --min-level "$L" -q &&
		$B/encode "$d/lossy.dag" "$d/lossy.sdag" -o "$d/lenc" --name s --min-level "$L" -q
	} 2> "$d/err"; then
		echo "| $name | $L | failed: $(tail -n 1 "$d/err") |"
		rm -rf "$d"
		return
	fi
	local a=$d/enc/s.tables.json b=$d/lenc/s.tables.json s=$d/lossy.dag.stats.json
	jq -n -r --slurpfile a "$a" --slurpfile b "$b" --slurpfile s "$s" \
		--arg name "$name" --arg L "$L" --arg kib "$(tail -n 1 "$d/time")" \
		--arg ref "$(ref "$name" "$L")" '
		def mb: . / 1048576 * 100 | round / 100 | tostring;
		def pct(x; y): if y > 0 then (100 * (x - y) / y * 10 | round / 10 | tostring) + "%" else "-" end;
		def pair(f): ($a[0].table2[0][f]) as $x | ($b[0].table2[0][f]) as $y |
			"\($x) → \($y) (\(pct($y; $x)))";
		def mbpair(f): ($a[0].table2[0][f]) as $x | ($b[0].table2[0][f]) as $y |
			"\($x | mb) → \($y | mb) (\(pct($y; $x)))";
		$s[0] as $s |
		"| \($name) | \($L) | \(pair("nodes_svdag")) | \(mbpair("bytes_svdag")) | " +
		"\(mbpair("bytes_esvdag")) | \(pair("nodes_ssvdag")) | \(mbpair("bytes_ssvdag")) | " +
		"\($s.error_rate * 10000 | round / 100)% | " +
		"\(if $s.voxels_before > 0 then (($s.voxels_after - $s.voxels_before) / $s.voxels_before * 10000 | round / 100 | tostring) + "%" else "-" end) | " +
		"\($s.seconds_lossy * 100 | round / 100) (\(($s.cpu_seconds_lossy // null) as $c | if $c then ($c * 100 | round / 100 | tostring) else "-" end)) | " +
		"\($kib | tonumber / 1024 | round) | \($ref) |"'
	if [ -n "${KEEP:-}" ]; then
		mkdir -p "$KEEP/$name-$L" &&
			cp "$s" "$a" "$d/time" "$KEEP/$name-$L/" && cp "$b" "$KEEP/$name-$L/lossy.tables.json"
	fi
	rm -rf "$d"
}
for m in "$DATA"/*.ply; do
	for L in $LEVELS; do
		row "$m" "$L"
	done
done
echo
echo "lossy_table: load at the end $(cut -d' ' -f1-3 /proc/loadavg)"
