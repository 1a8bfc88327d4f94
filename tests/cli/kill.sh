#!/usr/bin/env bash
# kill -9 at random moments of a multi-hundred-job pipeline (bunny 2^8 in
# cells of 32^3): ten times the runner, ten times a random running job,
# each from an empty output directory. Each kill must have interrupted
# something (a job had started and not every job had finished), and the
# rerun must end with outputs byte-identical to an uninterrupted run.
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
sums > "$T/ref.sums"
total=$(grep -c ' done ' $D/logs/runner.log)
[ "$total" -ge 200 ] && pass kill_setup_hundreds_of_jobs ||
	fail kill_setup_hundreds_of_jobs "$total jobs"

for i in $(seq 1 20); do
	what=runner; [ $i -gt 10 ] && what=job
	rm -rf $D
	at=$((RANDOM % (ms * 9 / 10) + ms / 20)) # ms into the run
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
		fail "kill_${i}_$what" "nothing to kill at ${at} ms"
		continue
	fi
	wait $pid
	rc=$?
	log=$D/logs/runner.log
	started=$(grep -c ' started ' $log 2>/dev/null)
	finished=$(grep -cE ' (done|skipped) ' $log 2>/dev/null)
	if [ $what = job ] && ! grep -q 'killed by signal 9' "$T/kill.err"; then
		fail "kill_${i}_${what}_interrupted" "at ${at} ms: no job reported killed" "$(head -3 "$T/kill.err")"
		continue
	fi
	if [ "${started:-0}" -eq 0 ] || [ "${finished:-0}" -ge "$total" ] || [ $rc -eq 0 ]; then
		fail "kill_${i}_${what}_interrupted" "at ${at} ms: exit $rc, $started started, $finished of $total finished"
		continue
	fi
	$R -q run "$CFG" 2>"$T/err"
	rc=$?
	sums > "$T/got.sums"
	if [ $rc -ne 0 ]; then
		fail "kill_${i}_${what}_resumed" "at ${at} ms: rerun exit $rc" "$(cat "$T/err")"
	elif ! cmp -s "$T/ref.sums" "$T/got.sums"; then
		fail "kill_${i}_${what}_resumed" "at ${at} ms:" "$(diff "$T/ref.sums" "$T/got.sums" | head -4)"
	else
		pass "kill_${i}_${what}_resumed"
	fi
done
