#!/usr/bin/env bash
# --threads does not change what svo-to-dag and symmetry-merge write: the
# bundled bunny at 2^11, whole and in level-2 chunks, reduced on 1, 2, 3
# and 8 threads gives the same chunk, byte for byte but for the provenance
# (which names the arguments), for the DAG of the SVO, the DAG merges (a
# flat one of all the chunks, a reduction step of 8 siblings), the SSVDAG
# and SSVDAG48 of the root and their merges. The scene is chosen so that
# the sharded inner pass runs: 898 thousand bricks and 175 thousand nodes
# on level 8, above the 65536 elements under which a level keeps the
# serial loops (build.c, PAR_MIN); the test checks those sizes, so a smaller
# scene cannot pass it vacuously. Under the least budget a run accepts
# there is no room for the sharded pass and the serial loops run: their
# chunks must be the same too. The multi-threaded outputs verify against
# the SVO (dag-verify).
set -u
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh

PAR_MIN=65536

# same NAME A B: A and B are the same chunk but for the provenance.
same() {
	if [ -f "$2" ] && [ -f "$3" ] &&
	   cmp -s <(chunk_sans_prov "$2") <(chunk_sans_prov "$3"); then
		pass "$1"
	else
		fail "$1" "$2 and $3 differ"
	fi
}

# at_least NAME VALUE MIN
at_least() {
	if [ "${2:-0}" -ge "$3" ] 2>/dev/null; then
		pass "$1"
	else
		fail "$1" "${2:-?} < $3: the scene no longer runs the parallel path"
	fi
}

"$BIN/voxelize" tests/data/bunny.ply -o "$T/whole" --levels 11 --chunk-level 0 -q --no-colours
"$BIN/voxelize" tests/data/bunny.ply -o "$T/cells" --levels 11 --chunk-level 2 -q --no-colours
SVO=$T/whole/chunk-L0-0.svo

# a level-1 cell whose 8 children at level 2 all have chunks: a reduction
# step merges them
sib=$(ls "$T/cells" | sed -n 's/^chunk-L2-\([0-9a-f]*\)\.svo$/\1/p' |
	while read -r h; do echo $((16#$h >> 3)); done | uniq -c |
	awk '$1 == 8 {print $2; exit}')

for t in 1 2 3 8; do
	d=$T/t$t
	mkdir -p "$d/cells"
	ok=1
	"$BIN/svo-to-dag" -q -j $t "$SVO" -o "$d/root.dag" || ok=0
	"$BIN/symmetry-merge" -q -j $t "$d/root.dag" -o "$d/root.ssvdag" || ok=0
	"$BIN/symmetry-merge" -q -j $t --group 48 "$d/root.dag" -o "$d/root.s48" || ok=0
	for f in "$T"/cells/chunk-L2-*.svo; do
		b=$(basename "$f" .svo)
		"$BIN/svo-to-dag" -q -j $t "$f" -o "$d/cells/$b.dag" || ok=0
	done
	"$BIN/svo-to-dag" -q -j $t --merge --to-level 0 "$d"/cells/chunk-L2-*.dag \
		-o "$d/flat.dag" || ok=0
	"$BIN/symmetry-merge" -q -j $t --merge --to-level 0 "$d"/cells/chunk-L2-*.dag \
		-o "$d/flat.ssvdag" || ok=0
	"$BIN/symmetry-merge" -q -j $t --group 48 --merge --to-level 0 \
		"$d/root.ssvdag" -o "$d/root48.s48" || ok=0
	if [ -n "$sib" ]; then
		# shellcheck disable=SC2046
		"$BIN/svo-to-dag" -q -j $t --merge $(for c in 0 1 2 3 4 5 6 7; do
			printf '%s/cells/chunk-L2-%02x.dag ' "$d" $((sib * 8 + c)); done) \
			-o "$d/step.dag" || ok=0
	fi
	[ $ok = 1 ] && pass "threads_${t}_runs" || fail "threads_${t}_runs" "a stage failed on $t threads"
done

# the parallel passes ran: sizes over the serial threshold
at_least bricks_over_threshold "$(jq .input_nodes "$T/t3/root.dag.stats.json")" $((4 * PAR_MIN))
at_least dag_level_over_threshold "$(jq '.level_nodes | max' "$T/t3/root.dag.stats.json")" $PAR_MIN
at_least ssvdag_level_over_threshold "$(jq '.level_nodes | max' "$T/t3/root.ssvdag.stats.json")" $PAR_MIN
at_least flat_inputs_over_threshold "$(jq .input_nodes "$T/t3/flat.dag.stats.json")" $((2 * PAR_MIN))

for t in 2 3 8; do
	same "svo_to_dag_t$t" "$T/t1/root.dag" "$T/t$t/root.dag"
	same "symmetry_merge_t$t" "$T/t1/root.ssvdag" "$T/t$t/root.ssvdag"
	same "symmetry_merge_g48_t$t" "$T/t1/root.s48" "$T/t$t/root.s48"
	same "merge_flat_t$t" "$T/t1/flat.dag" "$T/t$t/flat.dag"
	same "symmetry_merge_flat_t$t" "$T/t1/flat.ssvdag" "$T/t$t/flat.ssvdag"
	same "symmetry_merge_g48_of_ssvdag_t$t" "$T/t1/root48.s48" "$T/t$t/root48.s48"
	if [ -n "$sib" ]; then
		same "merge_step_t$t" "$T/t1/step.dag" "$T/t$t/step.dag"
	fi
done
[ -n "$sib" ] && pass have_sibling_step || fail have_sibling_step "no level-1 cell with 8 chunks"

# the flat merge is the root's DAG; the provenance check above can fail
same merge_flat_is_root "$T/t1/root.dag" "$T/t3/flat.dag"
if ! cmp -s "$T/t1/root.dag" "$T/t3/root.dag"; then
	pass provenance_differs
else
	fail provenance_differs "the comparison above cannot see a difference"
fi

# the multi-threaded outputs are lossless
for f in root.dag root.ssvdag root.s48 flat.dag flat.ssvdag; do
	expect "verify_t3_$f" 0 '' "$BIN/dag-verify" "$T/t3/$f" "$SVO"
done

# A budget with no room for the sharded pass's extra memory: the serial
# loops run instead, on 3 threads too, within the budget, and write the
# same chunk as the sharded pass (which the runs above use on 1 thread too)
# tight NAME OUT CMD...: runs CMD under the least budget it accepts (a
# merge checks its inputs one by one: raise the budget until it loads)
tight() {
	local name=$1 out=$2 need=0 next i peak
	shift 2
	for i in $(seq 100); do
		next=$("$@" --mem-budget $((need + 1))M -o "$T/x.chunk" 2>&1 |
			sed -n 's/.*needs about \([0-9]*\) MiB.*/\1/p')
		[ -z "$next" ] && break
		need=$next
	done
	expect "tight_${name}_runs" 0 '' "$@" --mem-budget $((${need:-0} + 1))M -o "$out"
	peak=$(jq .peak_rss_bytes "$out.stats.json" 2>/dev/null)
	if [ -n "$need" ] && [ "${peak:-0}" -gt 0 ] &&
	   [ "$peak" -le $(((need + 1) << 20)) ]; then
		pass "tight_${name}_peak"
	else
		fail "tight_${name}_peak" "peak ${peak:-?} bytes over the budget of $((${need:-0} + 1)) MiB"
	fi
}
tight svo_to_dag "$T/tight.dag" "$BIN/svo-to-dag" -q -j 3 "$SVO"
same tight_svo_to_dag_same "$T/t1/root.dag" "$T/tight.dag"
tight symmetry_merge "$T/tight.ssvdag" "$BIN/symmetry-merge" -q -j 3 "$T/t1/root.dag"
same tight_symmetry_merge_same "$T/t1/root.ssvdag" "$T/tight.ssvdag"
tight merge_flat "$T/tight-flat.dag" "$BIN/svo-to-dag" -q -j 3 --merge --to-level 0 \
	"$T"/t1/cells/chunk-L2-*.dag
same tight_merge_flat_same "$T/t1/flat.dag" "$T/tight-flat.dag"
