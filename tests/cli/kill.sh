#!/usr/bin/env bash
# kill -9 at 20 random moments of a multi-hundred-job pipeline (bunny 2^8
# in cells of 32^3), ten of the runner and ten of a random running job
# (alternately), each when the run has started a job drawn at random among
# those left. Kills come in chains: a run is killed, the next run
# (resuming) is killed again, and so on; when a run ends on its own before
# its moment, it has resumed every kill of its chain and its outputs must
# be byte-identical to an uninterrupted run's (the chain is checked and a
# new one starts from nothing). A last run ends the last chain the same
# way, and leave no staging entry (NAME.tmp.PID...) of the killed
# processes: runs sweep them when they start and end. Each run starts
# right after the kill before it and must never be refused because of the
# dead runner (its lock). Each kill must have interrupted something: a killed runner had
# started a job and not finished; a killed job was stopped (SIGSTOP)
# before the kill, so it was running, and the runner reported it killed.
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
bunny_pipeline $NAME 8 3 > "$CFG"
# The outputs' checksums.
sums() {
	(cd $D && find . -type f \( -name '*.svo' -o -name '*.dag' -o -name '*.sdag' \
		-o -name '*dag' \) | LC_ALL=C sort | xargs sha256sum)
}
t0=$(date +%s%N)
expect kill_setup 0 '' $R -q run "$CFG"
echo "kill.sh: an uninterrupted run takes $((($(date +%s%N) - t0) / 1000000)) ms" >&2
sums > "$T/ref.sums"
total=$(grep -c ' done ' $D/logs/runner.log)
[ "$total" -ge 200 ] && pass kill_setup_hundreds_of_jobs ||
	fail kill_setup_hundreds_of_jobs "$total jobs"

# children PID: the pids of PID's children.
children() { cat /proc/$1/task/$1/children 2>/dev/null; }

# pick_job RUNNER: sets victim to one of the runner's jobs, at random,
# stopped (SIGSTOP) so that it cannot end before the kill: cells take a few
# milliseconds, and a job that ended and waits to be reaped takes a kill
# without being interrupted. The runner starts each job through its
# launcher, voxdag-spawn, so jobs are its grandchildren (its children when
# voxdag-spawn is absent). Returns 1 when no job is running.
pick_job() {
	local kids stages v s n
	kids=$(children $1)
	stages=
	for v in $kids; do stages="$stages $(children $v)"; done
	[ -n "${stages// /}" ] || stages=$kids
	for v in $(printf '%s\n' $stages | shuf --random-source=<(yes $RANDOM)); do
		kill -STOP $v 2>/dev/null || continue
		# it stops when it next runs, which under load can take a
		# while; it cannot end in between except on its own (Z)
		for n in $(seq 1 400); do
			s=$(sed 's/.*) \(.\).*/\1/' /proc/$v/stat 2>/dev/null)
			[ "$s" = T ] || [ "$s" = t ] || [ "$s" = Z ] || [ -z "$s" ] && break
			sleep 0.005
		done
		if [ "$s" = T ] || [ "$s" = t ]; then
			victim=$v
			return 0
		fi
		kill -CONT $v 2>/dev/null
	done
	return 1
}

# one_kill I WHAT: runs the pipeline (resuming what is there) and kills the
# runner or one of its running jobs at a random moment. Returns 2 when the
# run ended on its own (exit 0) before the moment.
one_kill() {
	local i=$1 what=$2 at left pid rc log before started finished k
	log=$D/logs/runner.log
	before=$(cat $log 2>/dev/null | wc -l)
	# the moment: when this run has started its at-th job, at drawn
	# among the jobs left (a moment in the work, not in time: the same
	# under any load, and never after the run's end)
	left=$((total - $(cat $log 2>/dev/null | grep -c ' done ')))
	[ $left -lt 1 ] && left=1
	at=$((RANDOM % left + 1))
	$R -q run "$CFG" 2>"$T/kill.err" &
	pid=$!
	while [ "$(tail -n +$((before + 1)) $log 2>/dev/null | grep -c ' started ')" -lt $at ]; do
		kill -0 $pid 2>/dev/null || break
		sleep 0.005
	done
	victim=$pid
	if [ $what = job ]; then
		victim=
		for k in $(seq 1 300); do
			pick_job $pid && break
			kill -0 $pid 2>/dev/null || break # the run ended first
			sleep 0.01
		done
	fi
	if grep -q 'another runner' "$T/kill.err"; then
		fail "kill_${i}_${what}_not_refused" "a run right after a kill was refused" "$(cat "$T/kill.err")"
		return 1
	fi
	if [ -z "$victim" ] || ! kill -9 "$victim" 2>/dev/null; then
		wait $pid # nothing hit: the run ends on its own
		rc=$?
		[ $rc -eq 0 ] && return 2
		fail "kill_${i}_${what}_run" "a run exit $rc" "$(cat "$T/kill.err")"
		return 1
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
	if [ $what = job ] && ! grep -q 'killed by signal 9' "$T/kill.err"; then
		fail "kill_${i}_job_reported" "a stopped job was killed; the runner did not say so" "$(cat "$T/kill.err")"
		return 1
	fi
	# this run's lines of runner.log: it started work and did not finish
	started=$(tail -n +$((before + 1)) $log | grep -c ' started ')
	finished=$(tail -n +$((before + 1)) $log | grep -c ' finished: ')
	if [ $what = runner ] && [ $rc -ne 0 ] && [ "$finished" -ne 0 ]; then
		# the run had written its last line when the kill came: it hit
		# nothing. Resume it to the end, as a run that ended on its own.
		$R -q run "$CFG" 2>"$T/kill.err" && return 2
		fail "kill_${i}_runner_late" "the resume after a late kill failed" "$(cat "$T/kill.err")"
		return 1
	fi
	if [ $rc -eq 0 ] || [ "$started" -eq 0 ] ||
		{ [ $what = runner ] && [ "$finished" -ne 0 ]; }; then
		[ $rc -eq 0 ] && return 2 # all done before the moment
		fail "kill_${i}_${what}_interrupted" "at job ${at} of ${left}: exit $rc, $started started, finished $finished"
		return 1
	fi
	pass "kill_${i}_${what}_interrupted"
}

# check_chain: the outputs of a run that ended on its own (exit RC, its
# stderr in $T/err) are an uninterrupted run's.
chain=0
check_chain() {
	chain=$((chain + 1))
	sums > "$T/got.sums"
	local left
	left=$(find $D -name '*.tmp.*' | head -3)
	if [ $1 -ne 0 ]; then
		fail "kill_chain_${chain}_resumed" "rerun exit $1" "$(cat "$T/err")"
	elif ! cmp -s "$T/ref.sums" "$T/got.sums"; then
		fail "kill_chain_${chain}_resumed" "$(diff "$T/ref.sums" "$T/got.sums" | head -4)"
	elif [ -n "$left" ]; then
		fail "kill_chain_${chain}_resumed" "staging entries left:" $left
	else
		pass "kill_chain_${chain}_resumed"
	fi
}

rm -rf $D
i=0 idle=0
while [ $i -lt 20 ]; do
	what=runner; [ $((i % 2)) -eq 1 ] && what=job
	one_kill $((i + 1)) $what
	rc=$?
	if [ $rc -eq 2 ]; then
		# the run resumed its chain's kills to the end
		idle=$((idle + 1))
		cp "$T/kill.err" "$T/err"
		check_chain 0
		rm -rf $D
		if [ $idle -ge 5 ]; then
			fail "kill_$((i + 1))_$what" "five runs in a row ended before their moment"
			break
		fi
		continue
	fi
	idle=0
	i=$((i + 1))
done
$R -q run "$CFG" 2>"$T/err"
check_chain $?
echo "kill.sh: 20 kills in $chain chains" >&2
