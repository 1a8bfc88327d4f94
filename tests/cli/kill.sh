#!/usr/bin/env bash
# kill -9 at 20 random moments of a multi-hundred-job pipeline (bunny 2^8
# in cells of 32^3), ten of the runner and ten of a random running job, in
# two chains: a run is killed, the next run (resuming) is killed again,
# ten times, then a last run finishes and its outputs must be
# byte-identical to an uninterrupted run. Each kill must have interrupted
# something: the killed run had started a job and not finished them all.
# VOXDAG_KILL_SEED repeats a sequence of moments.
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh
R=$BIN/voxdag
NAME=killtest-$$
D=out/$NAME
CFG=$T/p.yaml
trap 'rm -rf "$T" "$D"' EXIT
SEED=${VOXDAG_KILL_SEED:-$$}
RANDOM=$SEED
echo "kill.sh: seed $SEED (VOXDAG_KILL_SEED=$SEED repeats it)" >&2
cat > "$CFG" <<YAML
version: 1
name: $NAME
input:
  mesh: tests/data/bunny.ply
levels: 8
chunk_level: 3
resources: {jobs: 2, threads: 1, mem_budget: 2GiB, job_mem_budget: 512M}
jobs:
  vox:    {stage: voxelize}
  dag:    {stage: svo-to-dag, needs: [vox]}
  ssvdag: {stage: symmetry-merge, needs: [dag]}
  enc:    {stage: encode, needs: [dag, ssvdag]}
YAML
sums() {
	(cd $D && find . -type f \( -name '*.svo' -o -name '*.dag' -o -name '*.sdag' \
		-o -name '*dag' \) | LC_ALL=C sort | xargs sha256sum)
}
t0=$(date +%s%N)
expect kill_setup 0 '' $R -q run "$CFG"
ms=$((($(date +%s%N) - t0) / 1000000))
echo "kill.sh: an uninterrupted run takes $ms ms" >&2
sums > "$T/ref.sums"
total=$(grep -c ' done ' $D/logs/runner.log)
[ "$total" -ge 200 ] && pass kill_setup_hundreds_of_jobs ||
	fail kill_setup_hundreds_of_jobs "$total jobs"

# one_kill I WHAT: runs the pipeline (resuming what is there) and kills the
# runner or one of its running jobs after a random delay. Returns 2 when
# the kill hit nothing (the run ended first, or the chosen job ended
# between being listed and the signal): the caller draws another moment.
one_kill() {
	local i=$1 what=$2 at pid victim rc log before started finished k
	log=$D/logs/runner.log
	before=$(cat $log 2>/dev/null | wc -l)
	at=$((RANDOM % (ms / 3) + 50)) # ms into this run
	$R -q run "$CFG" 2>"$T/kill.err" &
	pid=$!
	sleep "$(awk -v m=$at 'BEGIN { printf "%.3f", m / 1000 }')"
	victim=$pid
	if [ $what = job ]; then
		victim=
		for k in $(seq 1 300); do # a running job (not one that ended
			# and waits to be reaped), at random
			victim=$(ps -o pid=,stat= --ppid $pid | awk '$2 !~ /Z/ { print $1 }' |
				shuf -n 1 --random-source=<(yes $RANDOM))
			[ -n "$victim" ] && kill -9 "$victim" 2>/dev/null && break
			victim=
			sleep 0.01
		done
	fi
	if [ -z "$victim" ] || { [ $what = runner ] && ! kill -9 "$victim" 2>/dev/null; }; then
		wait $pid
		return 2
	fi
	if [ $what = job ]; then
		# the runner reports the killed job at once; then it is stopped
		# too, not left to finish every other job (the test's time)
		for k in $(seq 1 300); do
			grep -q 'killed by signal 9' "$T/kill.err" && break
			kill -0 $pid 2>/dev/null || break
			sleep 0.01
		done
		kill -9 $pid 2>/dev/null
	fi
	wait $pid
	rc=$?
	[ $what = job ] && ! grep -q 'killed by signal 9' "$T/kill.err" && return 2
	# this run's lines of runner.log: it started work and did not finish
	started=$(tail -n +$((before + 1)) $log | grep -c ' started ')
	finished=$(tail -n +$((before + 1)) $log | grep -c ' finished: ')
	if [ $rc -eq 0 ] || [ "$started" -eq 0 ] ||
		{ [ $what = runner ] && [ "$finished" -ne 0 ]; }; then
		[ $rc -eq 0 ] && return 2 # all done before the moment
		fail "kill_${i}_${what}_interrupted" "at ${at} ms: exit $rc, $started started, finished $finished"
		return 1
	fi
	pass "kill_${i}_${what}_interrupted"
}

i=0
for chain in 1 2; do
	rm -rf $D
	for k in $(seq 1 10); do
		i=$((i + 1))
		what=runner; [ $((i % 2)) -eq 0 ] && what=job
		hit=
		for try in 1 2 3 4 5; do
			one_kill $i $what
			[ $? -eq 2 ] || { hit=1; break; }
			rm -rf $D # too late: start this chain's run afresh
		done
		[ -n "$hit" ] || fail "kill_${i}_$what" "five moments in a row interrupted nothing"
	done
	$R -q run "$CFG" 2>"$T/err"
	rc=$?
	sums > "$T/got.sums"
	if [ $rc -ne 0 ]; then
		fail "kill_chain_${chain}_resumed" "rerun exit $rc" "$(cat "$T/err")"
	elif ! cmp -s "$T/ref.sums" "$T/got.sums"; then
		fail "kill_chain_${chain}_resumed" "$(diff "$T/ref.sums" "$T/got.sums" | head -4)"
	else
		pass "kill_chain_${chain}_resumed"
	fi
done
