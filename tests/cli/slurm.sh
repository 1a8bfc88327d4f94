#!/usr/bin/env bash
# The Slurm executor against a real one-node Slurm on this machine
# (tests/slurm/local-slurm.sh; Debian slurm-wlm + munge, installed by
# `make deps`): the bundled pipeline gives the same bytes as a local run; a
# driver killed while Slurm holds its jobs is resumed by adopting them, no
# job submitted twice; a cancelled job is reported with Slurm's reason and
# blocks its dependents; bad set-ups are refused before anything is
# submitted. Then a cluster with a site's limits (MaxJobCount=60,
# MaxArraySize=20): the bunny at 2^9 in 1,679 jobs, bundled into arrays,
# never more than the cap in the queue, each job run once, the same bytes
# as a local run, also across a killed driver; one array task cancelled
# alone is reported by its jobs' names and a rerun finishes. The daemons
# are stopped by their process ids whatever happens.
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh

if [ "$(id -u)" != 0 ] || ! command -v slurmctld >/dev/null ||
	! command -v munged >/dev/null; then
	echo "SKIP slurm (needs root and Debian's slurm-wlm and munge: make deps)"
	exit 0
fi

# Outputs on one node: under out/ of the checkout, which may itself be
# under /tmp (a clone in a temporary directory), so the pipelines say
# `slurm: {shared_outputs: true}`, as a one-node cluster's user would.
W=out/tmp/slurm-cli
rm -rf "$W" && mkdir -p "$W"
S=$(mktemp -d /tmp/voxdag-slurm.XXXXXX)
S2=$(mktemp -d /tmp/voxdag-slurm.XXXXXX)
trap 'tests/slurm/local-slurm.sh stop "$S"; tests/slurm/local-slurm.sh stop "$S2"; rm -rf "$T" "$S" "$S2"' EXIT
if ! env=$(tests/slurm/local-slurm.sh start "$S" 2>"$T/slurm.err"); then
	fail slurm_starts "the local Slurm did not start:" "$(cat "$T/slurm.err")"
	exit 1
fi
eval "$env"
pass slurm_starts

# pipeline NAME [SLURM_KEYS]: config/default.yaml with outputs in $W and
# `slurm: {shared_outputs: true, SLURM_KEYS}`.
pipeline() {
	sed "s/^name: default/name: $1/" config/default.yaml > "$W/$1.yaml"
	echo "outputs: $W/$1" >> "$W/$1.yaml"
	echo "slurm: {shared_outputs: true${2:+, $2}}" >> "$W/$1.yaml"
}

# The bytes a run leaves: every chunk, encoding and picture.
sums() {
	(cd "$1" && find . -type f \( -name '*.svo' -o -name '*.dag' -o \
		-name '*.sdag' -o -name '*dag' -o -name '*.png' \) | LC_ALL=C sort |
		xargs sha256sum)
}

release_held() { # releases our held jobs (named $2, if given) until the runner $1 exits
	while kill -0 "$1" 2>/dev/null; do
		squeue --me -h -t PD ${2:+-n "$2"} -o %i | xargs -r scontrol release 2>/dev/null
		sleep 0.3
	done
}

wait_log() { # wait_log FILE REGEX SECONDS
	local i
	for i in $(seq $(($3 * 10))); do
		grep -Eq "$2" "$1" 2>/dev/null && return 0
		sleep 0.1
	done
	return 1
}

# --- the same bytes as a local run ---------------------------------------
pipeline same
$BIN/voxdag run "$W/same.yaml" -q 2>"$T/err" || fail slurm_local_run "$(cat "$T/err")"
sums "$W/same" > "$W/local.sum"
$BIN/voxdag clean "$W/same.yaml"
if $BIN/voxdag run "$W/same.yaml" --executor slurm -q 2>"$T/err"; then
	sums "$W/same" > "$W/slurm.sum"
	if [ "$(wc -l < "$W/local.sum")" -ge 30 ] &&
		cmp -s "$W/local.sum" "$W/slurm.sum"; then
		pass slurm_outputs_identical_to_local
	else
		fail slurm_outputs_identical_to_local "$(diff "$W/local.sum" "$W/slurm.sum" | head)"
	fi
	n=$(grep -c '^.* submitted ' "$W/same/logs/runner.log")
	jobs=$(grep -c '^.* done ' "$W/same/logs/runner.log")
	if [ "$n" -eq 21 ] && [ "$jobs" -eq 21 ]; then
		pass slurm_every_job_submitted_once
	else
		fail slurm_every_job_submitted_once "$n submitted, $jobs done (21 jobs)"
	fi
else
	fail slurm_outputs_identical_to_local "$(cat "$T/err")"
fi

# --- kill the driver while Slurm holds its jobs, resume ------------------
# the same pipeline (same bytes expected), its jobs held until released
$BIN/voxdag clean "$W/same.yaml"
sed 's/^slurm: {shared_outputs: true}$/slurm: {shared_outputs: true, sbatch_args: [--hold]}/' \
	"$W/same.yaml" > "$W/resume.yaml"
$BIN/voxdag run "$W/resume.yaml" --executor slurm -q 2>"$T/err1" &
r=$!
release_held $r voxdag:same:voxelize & # the cells' bundle stays held
rel=$!
# kill once the cells are submitted and held, voxelize done
if wait_log "$W/same/logs/runner.log" 'submitted svdag/cells/chunk-L1-7' 60; then
	kill $rel 2>/dev/null; wait $rel 2>/dev/null
	sleep 0.5
	kill -9 $r; wait $r 2>/dev/null
	held=$(squeue --me -h -t PD -o %i | wc -l)
	$BIN/voxdag status "$W/resume.yaml" > "$T/status" 2>&1
	if [ "$held" -ge 1 ] && grep -q 'in Slurm' "$T/status" &&
		grep -q 'PENDING' "$T/status"; then
		pass slurm_status_shows_queued_jobs
	else
		fail slurm_status_shows_queued_jobs "$held held;" "$(cat "$T/status")"
	fi
	$BIN/voxdag run "$W/resume.yaml" --executor slurm -q 2>"$T/err2" &
	r=$!
	release_held $r &
	rel=$!
	wait $r
	rc=$?
	kill $rel 2>/dev/null; wait $rel 2>/dev/null
	sums "$W/same" > "$W/resume.sum"
	# runner.log holds this pipeline's runs since the clean
	subs=$(grep -oE 'submitted [^ ]+' "$W/same/logs/runner.log" | sort | uniq -d)
	adopted=$(grep -c ' adopted ' "$W/same/logs/runner.log")
	if [ $rc -eq 0 ] && cmp -s "$W/local.sum" "$W/resume.sum" &&
		[ -z "$subs" ] && [ "$adopted" -ge 1 ]; then
		pass slurm_resume_adopts_and_matches
	else
		fail slurm_resume_adopts_and_matches "exit $rc, $adopted adopted," \
			"submitted twice: $subs" "$(cat "$T/err2")" \
			"$(diff "$W/local.sum" "$W/resume.sum" | head -5)"
	fi
else
	kill $r $rel 2>/dev/null
	fail slurm_resume_adopts_and_matches "cells were never submitted:" "$(cat "$T/err1")"
fi

# --- a cancelled job: its reason, its dependents not run -----------------
pipeline cancel "sbatch_args: [--hold]"
$BIN/voxdag run "$W/cancel.yaml" --executor slurm -q 2>"$T/err" &
r=$!
if wait_log "$W/cancel/logs/runner.log" 'submitted voxelize' 30; then
	id=$(sed -n 's/.*submitted voxelize (Slurm job \([0-9_]*\).*/\1/p' \
		"$W/cancel/logs/runner.log")
	scancel "$id"
	wait $r
	rc=$?
	if [ $rc -eq 1 ] && grep -Eq "job voxelize did not finish: Slurm job $id(: state CANCELLED| left the queue before it started \(cancelled)" "$T/err" &&
		grep -q '  command: .*voxelize' "$T/err" &&
		grep -q '1 job failed' "$T/err" &&
		! grep -q 'submitted svdag' "$W/cancel/logs/runner.log"; then
		pass slurm_cancelled_job_reported
	else
		fail slurm_cancelled_job_reported "exit $rc" "$(cat "$T/err")"
	fi
else
	kill $r 2>/dev/null
	fail slurm_cancelled_job_reported "voxelize was never submitted"
fi

# --- set-ups refused before anything is submitted ------------------------
before=$(squeue --me -h | wc -l)
pipeline badpart "partition: nosuch"
expect slurm_unknown_partition 1 "partition 'nosuch' does not exist" \
	$BIN/voxdag run "$W/badpart.yaml" --executor slurm -q
sed "s/^name: default/name: local/" config/default.yaml > "$W/local.yaml"
echo "outputs: $S/outputs" >> "$W/local.yaml"
expect slurm_node_local_outputs 1 "node-local directory.*'outputs:'" \
	$BIN/voxdag run "$W/local.yaml" --executor slurm -q
mkdir -p "$T/bin"
expect slurm_no_sbatch 1 "no 'sbatch' on PATH" \
	env PATH="$T/bin" $BIN/voxdag run "$W/badpart.yaml" --executor slurm -q
sed -e 's/^SlurmctldPort=.*/SlurmctldPort=9/' -e '$a MessageTimeout=2' \
	"$SLURM_CONF" > "$T/down.conf"
expect slurm_controller_down 1 "controller does not answer" \
	env SLURM_CONF="$T/down.conf" $BIN/voxdag run "$W/badpart.yaml" --executor slurm -q
expect slurm_bad_executor 2 "--executor is 'local' or 'slurm'" \
	$BIN/voxdag run "$W/badpart.yaml" --executor cloud
pipeline badtime "time: {svo-to-dag: soon}"
expect slurm_bad_time_limit 1 "not a Slurm time limit" \
	$BIN/voxdag run "$W/badtime.yaml" --executor slurm
sed "s/^slurm: .*/slurm: {shared_outputs: yes}/" "$W/badtime.yaml" > "$W/badshared.yaml"
expect slurm_bad_shared_outputs 1 "'shared_outputs' is true or false" \
	$BIN/voxdag run "$W/badshared.yaml" --executor slurm
after=$(squeue --me -h | wc -l)
if [ "$after" -eq "$before" ] && [ ! -e "$W/badpart/voxelize" ]; then
	pass slurm_refusals_submit_nothing
else
	fail slurm_refusals_submit_nothing "queue $before -> $after"
fi
pipeline badbundle "bundle_seconds: 0"
expect slurm_bad_bundle_seconds 1 "'bundle_seconds' is 0, outside 1" \
	$BIN/voxdag run "$W/badbundle.yaml" --executor slurm
pipeline badqueued "max_queued: many"
expect slurm_bad_max_queued 1 "'max_queued' must be a whole number" \
	$BIN/voxdag run "$W/badqueued.yaml" --executor slurm

# --- job-exec, what a bundle runs ----------------------------------------
expect job_exec_usage 2 "usage: voxdag job-exec LIST" $BIN/voxdag job-exec
expect job_exec_no_list 1 "cannot open '$T/none.list'" \
	$BIN/voxdag job-exec "$T/none.list"
printf 'voxdag-job-list 1\njob a 0\nend %s\n' "$T/a.end" > "$T/cut.list"
expect job_exec_cut_list 1 "is not a job list \(line 3\)" \
	$BIN/voxdag job-exec "$T/cut.list"
# a fails; b needs a (skipped, no end); c does not (runs); one log line each
{
	echo "voxdag-job-list 1"
	printf 'job a 0\nend %s\nlog %s\narg /bin/false\nrun\n' "$T/a.end" "$T/a.log"
	printf 'job b 0\nend %s\nlog %s\nafter %s\narg /bin/true\nrun\n' \
		"$T/b.end" "$T/b.log" "$T/a.end"
	printf 'job c 0\nend %s\nlog %s\narg /bin/echo\narg hi\nrun\n' "$T/c.end" "$T/c.log"
} > "$T/deps.list"
$BIN/voxdag job-exec "$T/deps.list" 2>"$T/err"
rc=$?
if [ $rc -eq 0 ] && grep -q '^exit 1$' "$T/a.end" && [ ! -e "$T/b.end" ] &&
	[ ! -e "$T/b.log" ] && grep -q '^exit 0$' "$T/c.end" &&
	[ "$(cat "$T/c.log")" = "$(printf '$ /bin/echo hi\nhi')" ] &&
	grep -q "job b not run: the job that wrote '$T/a.end' did not succeed" "$T/err"; then
	pass job_exec_skips_dependents_of_a_failure
else
	fail job_exec_skips_dependents_of_a_failure "exit $rc" "$(cat "$T/err")"
fi

# --- a cluster with a site's limits ---------------------------------------
# The first cluster goes (its CPUs are the test's), a capped one comes.
# MinJobAge=5: ended jobs count against MaxJobCount until purged.
tests/slurm/local-slurm.sh stop "$S"
if ! env=$(tests/slurm/local-slurm.sh start "$S2" MaxJobCount=60 \
	MaxArraySize=20 MinJobAge=5 2>"$T/slurm.err"); then
	fail slurm_capped_starts "the capped Slurm did not start:" "$(cat "$T/slurm.err")"
	exit 1
fi
eval "$env"

# bunny NAME L0 [SLURM_KEYS]: the bunny at 2^9 with chunk level L0 (4:
# 1,679 jobs), bundles of about 2 s so that there are more than the queue
# holds
bunny() {
	sed -e "s/^name: default/name: $1/" -e "s/^chunk_level: 1 .*/chunk_level: $2/" \
		config/default.yaml > "$W/$1.yaml"
	echo "outputs: $W/$1" >> "$W/$1.yaml"
	echo "slurm: {shared_outputs: true, bundle_seconds: 2${3:+, $3}}" >> "$W/$1.yaml"
}
sample_queue() { # the queue's length every 0.3 s into $1 until killed
	while :; do squeue --me -h -r | wc -l >> "$1"; sleep 0.3; done
}
# once NAME: every job of the run ran exactly once: one end file per job,
# one "$ command" line in each job's log (job-exec appends one per run)
once() {
	local d=$W/$1 jobs ends twice
	jobs=$(sed -n 's/.* finished: .*, \([0-9]*\) jobs, .*/\1/p' "$d/logs/runner.log" | tail -1)
	ends=$(ls "$d/slurm" | grep -c '\.end$')
	twice=$(cd "$d/logs" && grep -c '^\$ ' -- *.log |
		grep -v -e '^b[0-9]' -e '^runner.log:' | grep -vc ':1$')
	[ -n "$jobs" ] && [ "$ends" -eq "$jobs" ] && [ "$twice" -eq 0 ] && return 0
	echo "$jobs jobs, $ends end files, $twice logs without exactly one run"
	return 1
}

bunny capped 4
t0=$SECONDS
$BIN/voxdag run "$W/capped.yaml" -q 2>"$T/err" || fail slurm_capped_local_run "$(cat "$T/err")"
sums "$W/capped" > "$W/capped-local.sum"
local_s=$((SECONDS - t0))
$BIN/voxdag clean "$W/capped.yaml"
sample_queue "$W/queue" &
smp=$!
t0=$SECONDS
$BIN/voxdag run "$W/capped.yaml" --executor slurm -q 2>"$T/err"
rc=$?
slurm_s=$((SECONDS - t0))
kill $smp; wait $smp 2>/dev/null
echo "  (capped bunny: local ${local_s}s, Slurm ${slurm_s}s)" >&2
sums "$W/capped" > "$W/capped-slurm.sum"
rl=$W/capped/logs/runner.log
cap=$(sed -n 's/.*at most \([0-9]*\) bundles in the queue (MaxJobCount 60).*/\1/p' "$rl")
most=$(sort -n "$W/queue" | tail -1)
arrays=$(grep -c ' sbatch: ' "$rl")
widest=$(sed -n 's/.* sbatch: Slurm job [0-9]*, \([0-9]*\) bundles\{0,1\} of.*/\1/p' "$rl" | sort -n | tail -1)
if [ $rc -eq 0 ] && [ "$(wc -l < "$W/capped-local.sum")" -ge 1600 ] &&
	cmp -s "$W/capped-local.sum" "$W/capped-slurm.sum"; then
	pass slurm_capped_outputs_identical_to_local
else
	fail slurm_capped_outputs_identical_to_local "exit $rc" "$(cat "$T/err")" \
		"$(diff "$W/capped-local.sum" "$W/capped-slurm.sum" | head -5)"
fi
if [ "$cap" = 30 ] && [ "${most:-99}" -le 30 ] && [ "$most" -ge 20 ] &&
	[ "$widest" -le 20 ] && [ "$arrays" -le 34 ]; then
	pass slurm_capped_within_limits
else
	fail slurm_capped_within_limits "cap '$cap', at most $most in the queue," \
		"widest array $widest, $arrays sbatch for 1,679 jobs (<= 1 per 50)"
fi
if why=$(once capped); then
	pass slurm_capped_every_job_once
else
	fail slurm_capped_every_job_once "$why"
fi

# --- kill the driver while bundles run, restart: adopted, nothing twice --
$BIN/voxdag clean "$W/capped.yaml"
$BIN/voxdag run "$W/capped.yaml" --executor slurm -q 2>"$T/err1" &
r=$!
if wait_log "$W/capped/logs/runner.log" 'sbatch: .* svdag jobs' 60; then
	sleep 1.5
	kill -9 $r; wait $r 2>/dev/null
	inq=$(squeue --me -h -r | wc -l)
	$BIN/voxdag run "$W/capped.yaml" --executor slurm -q 2>"$T/err2"
	rc=$?
	sums "$W/capped" > "$W/capped-resume.sum"
	subs=$(grep -oE 'submitted [^ ]+' "$rl" | sort | uniq -d | head -3)
	adopted=$(grep -c ' adopted ' "$rl")
	if [ $rc -eq 0 ] && [ "$inq" -ge 1 ] && [ "$adopted" -ge 1 ] && [ -z "$subs" ] &&
		cmp -s "$W/capped-local.sum" "$W/capped-resume.sum" && why=$(once capped); then
		pass slurm_capped_resume_adopts_runs_once
	else
		fail slurm_capped_resume_adopts_runs_once "exit $rc, $inq in Slurm at the kill," \
			"$adopted adopted, submitted twice: $subs" "$why" "$(cat "$T/err2")" \
			"$(diff "$W/capped-local.sum" "$W/capped-resume.sum" | head -5)"
	fi
else
	kill $r 2>/dev/null
	fail slurm_capped_resume_adopts_runs_once "no bundle was submitted:" "$(cat "$T/err1")"
fi

# --- one array task cancelled alone: its jobs by name, rerun finishes ----
# chunk level 2 (some 30 cells: a few bundles of cells), every array held
# until released: voxelize's at once, the cells' once one task is cancelled
bunny onetask 2 "bundle_seconds: 1, sbatch_args: [--hold]"
sed -i 's/bundle_seconds: 2, //' "$W/onetask.yaml"
sed 's/, sbatch_args: .*/}/' "$W/onetask.yaml" > "$W/onetask-rerun.yaml"
$BIN/voxdag run "$W/onetask.yaml" -q 2>"$T/err" || fail slurm_onetask_local_run "$(cat "$T/err")"
sums "$W/onetask" > "$W/onetask-local.sum"
$BIN/voxdag clean "$W/onetask.yaml"
rl=$W/onetask/logs/runner.log
# start_held_run: the onetask pipeline on Slurm in the background (pid
# r), its voxelize released (rel); once the svdag bundles are submitted,
# arr is their array's Slurm job. 1 when they never come.
start_held_run() {
	$BIN/voxdag run "$W/onetask.yaml" --executor slurm -q 2>"$T/err" &
	r=$!
	release_held $r voxdag:onetask:voxelize &
	rel=$!
	wait_log "$rl" 'sbatch: .* [2-9] bundles of [0-9]* svdag jobs' 60 || return 1
	arr=$(sed -n 's/.* sbatch: Slurm job \([0-9]*\), [2-9] bundles of [0-9]* svdag jobs.*/\1/p' "$rl" | head -1)
}
# finish_held_run: releases every held job of the run r until it ends;
# rc is its exit status.
finish_held_run() {
	kill $rel 2>/dev/null; wait $rel 2>/dev/null
	release_held $r &
	rel=$!
	wait $r
	rc=$?
	kill $rel 2>/dev/null; wait $rel 2>/dev/null
}
if start_held_run; then
	victim=$(grep " (Slurm job ${arr}_1, " "$rl" | sed 's/.* submitted \([^ ]*\) .*/\1/' | head -1)
	scancel "${arr}_1"
	finish_held_run
	ssv=ssvdag/cells/${victim#svdag/cells/}
	if [ $rc -eq 1 ] && [ -n "$victim" ] &&
		grep -q "job $victim did not finish: Slurm job ${arr}_1 left the queue before it started" "$T/err" &&
		grep -q "  log: .*/logs/${victim//\//.}.log" "$T/err" &&
		grep -q 'jobs\{0,1\} failed' "$T/err" && grep -q "submitted svdag/cells/" "$rl" &&
		! grep -q "submitted $ssv " "$rl" && ! grep -q "submitted svdag/root " "$rl"; then
		pass slurm_array_task_cancelled_reported
	else
		fail slurm_array_task_cancelled_reported "exit $rc, victim '$victim' of $arr" \
			"$(head -5 "$T/err")"
	fi
	$BIN/voxdag run "$W/onetask-rerun.yaml" --executor slurm -q 2>"$T/err"
	rc=$?
	sums "$W/onetask" > "$W/onetask-rerun.sum"
	if [ $rc -eq 0 ] && [ "$(wc -l < "$W/onetask-local.sum")" -ge 30 ] &&
		cmp -s "$W/onetask-local.sum" "$W/onetask-rerun.sum"; then
		pass slurm_array_task_rerun_finishes
	else
		fail slurm_array_task_rerun_finishes "exit $rc" "$(cat "$T/err")"
	fi
else
	kill $r $rel 2>/dev/null
	fail slurm_array_task_cancelled_reported "no array of svdag bundles:" \
		"$(grep sbatch: "$rl")"
fi
# --- a job failing inside a bundle: named, with its log; only its --------
# dependents not run; the others of its bundle and stage go on
# (the same pipeline: the picture is named after it)
$BIN/voxdag clean "$W/onetask-rerun.yaml"
if start_held_run; then
	victim=$(grep " (Slurm job ${arr}_0, " "$rl" | sed 's/.* submitted \([^ ]*\) .*/\1/' | sed -n 2p)
	cell=${victim#svdag/cells/}
	truncate -s 100 "$W/onetask/voxelize/$cell.svo" # a cut chunk: svo-to-dag refuses it
	finish_held_run
	if [ $rc -eq 1 ] && [ -n "$cell" ] &&
		grep -q "job $victim failed (exit [1-9]" "$T/err" &&
		grep -q "  log: .*/logs/svdag.cells.$cell.log" "$T/err" && grep -q '  | ' "$T/err" &&
		grep -q "done svdag/cells/" "$rl" && grep -q "done ssvdag/cells/" "$rl" &&
		! grep -q "submitted ssvdag/cells/$cell " "$rl" && ! grep -q "submitted svdag/root " "$rl"; then
		pass slurm_failed_job_in_bundle_reported
	else
		fail slurm_failed_job_in_bundle_reported "exit $rc, victim '$victim'" "$(head -8 "$T/err")"
	fi
	# the cut chunk no longer matches voxelize's key: rebuilt, then all
	$BIN/voxdag run "$W/onetask-rerun.yaml" --executor slurm -q 2>"$T/err"
	rc=$?
	sums "$W/onetask" > "$W/failjob-rerun.sum"
	if [ $rc -eq 0 ] && cmp -s "$W/onetask-local.sum" "$W/failjob-rerun.sum"; then
		pass slurm_failed_job_rerun_finishes
	else
		fail slurm_failed_job_rerun_finishes "exit $rc" "$(cat "$T/err")" \
			"$(diff "$W/onetask-local.sum" "$W/failjob-rerun.sum" | head -5)"
	fi
else
	kill $r $rel 2>/dev/null
	fail slurm_failed_job_in_bundle_reported "no array of svdag bundles:" \
		"$(grep sbatch: "$rl")"
fi
rm -rf "$W"
