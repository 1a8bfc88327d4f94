#!/usr/bin/env bash
# keep: in the pipeline YAML. The outputs of the jobs it does not list are
# deleted once everything that reads them has finished; what is kept (the
# encodings, the picture, the report's tables) is byte-identical to a run
# without keep:, a second run starts nothing, a run killed at any moment
# resumes without rerunning a finished job, and a job that needs a deleted
# file again (its output lost, its arguments changed) gets it back: the
# jobs that wrote it run again first, and the result equals a fresh run's.
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh
R=$BIN/voxdag
NAME=keeptest-$$
D=out/$NAME
REF=out/$NAME-ref
trap 'rm -rf "$T" "$D" "$REF"' EXIT

# cfg NAME KEEP: the lossless bunny pipeline at 2^8 in cells of level 2
# (89 jobs) with a picture; KEEP the keep: line ("" for none)
cfg() {
	lossless_yaml "$1" tests/data/bunny.ply 8 2 \
		"{jobs: 2, threads: 1, mem_budget: 2GiB, job_mem_budget: 512M}"
	echo "  pic:    {stage: render, needs: [enc]}"
	echo "$2"
}
cfg "$NAME" "keep: [enc]" > "$T/k.yaml"
cfg "$NAME-ref" "" > "$T/r.yaml"
last_run() { awk '/ run /{buf=""} {buf=buf $0 "\n"} END{printf "%s", buf}' $D/logs/runner.log; }
# what a user keeps: the encodings and the picture, and the report's
# tables of nodes and bytes
kept() { # kept DIR
	local f
	for f in "$1"/enc/*dag "$1"/pic.png; do
		echo "${f##*.} $(sha256sum < "$f")"
	done
	sed -n '/^## Table 2/,/^## The run/p' "$1/report.md"
}
# the data files of the intermediates still there
left() { find "$1/vox" "$1/dag" "$1/ssvdag" -name '*.svo' -o -name '*.col' \
	-o -name '*.dag' -o -name '*.sdag' 2>/dev/null | sort; }

# --- the YAML
printf 'version: 1\nname: x\ninput: {mesh: tests/data/bunny.ply}\nlevels: 6\nkeep: [w]\njobs: {v: {stage: voxelize}}\n' > "$T/bad.yaml"
expect keep_names_a_job 1 'bad.yaml:5:8: .keep. names .w., which is not a job' $R plan "$T/bad.yaml"
printf 'version: 1\nname: x\ninput: {mesh: tests/data/bunny.ply}\nlevels: 6\nkeep: v\njobs: {v: {stage: voxelize}}\n' > "$T/bad.yaml"
expect keep_is_a_list 1 'bad.yaml:5:7: .keep. must be a list' $R plan "$T/bad.yaml"

# --- a run: the intermediates go, what is kept equals a run without keep:
expect keep_reference_run 0 '' $R -q run "$T/r.yaml"
kept $REF > "$T/ref.kept"
[ "$(left $REF | wc -l)" -gt 100 ] && pass keep_reference_has_intermediates ||
	fail keep_reference_has_intermediates "$(left $REF | wc -l) files"
expect keep_run 0 '' $R -q run "$T/k.yaml"
kept $D > "$T/got.kept"
cmp -s "$T/ref.kept" "$T/got.kept" && pass keep_outputs_identical ||
	fail keep_outputs_identical "$(diff "$T/ref.kept" "$T/got.kept" | head -5)"
[ -z "$(left $D)" ] && pass keep_intermediates_deleted ||
	fail keep_intermediates_deleted "$(left $D | head -3)"
# a file of a directory output goes as soon as its readers finished: the
# first cell's SVO chunk before the last cell's DAG is built
first_del=$(grep -n 'deleted vox/chunk-' $D/logs/runner.log | head -n 1 | cut -d: -f1)
last_cell=$(grep -n ' done dag/cells/' $D/logs/runner.log | tail -n 1 | cut -d: -f1)
[ -n "$first_del" ] && [ -n "$last_cell" ] && [ "$first_del" -lt "$last_cell" ] &&
	pass keep_file_goes_with_its_reader ||
	fail keep_file_goes_with_its_reader "first deletion at line $first_del, last cell at $last_cell"
# nothing went before its last reader finished: no job needed it again
! grep -q 'starting over' $D/logs/runner.log && pass keep_run_no_start_over ||
	fail keep_run_no_start_over "$(grep -m3 'keep: deleted' $D/logs/runner.log)"
# each deleted file has its G record; statistics and manifests stay
gone=$(cut -c18- $D/keys | grep -c '^G ')
[ "$gone" -eq "$(left $REF | wc -l)" ] && pass keep_journal_records_each ||
	fail keep_journal_records_each "$gone G records, $(left $REF | wc -l) files"
[ -s $D/vox/manifest ] && [ -s $D/vox/voxelize.stats.json ] &&
	[ -s $D/dag/root.dag.stats.json ] && [ -s $D/ssvdag/root.sdag.stats.json ] &&
	pass keep_statistics_stay || fail keep_statistics_stay "$(ls $D/vox $D/dag)"
expect keep_rerun 0 '' $R -q run "$T/k.yaml"
[ "$(last_run | grep -c ' started ')" -eq 0 ] && pass keep_rerun_starts_nothing ||
	fail keep_rerun_starts_nothing "$(last_run | grep ' started ' | head -3)"
# the plan of a finished run with its intermediates gone: all done
n_todo=$($R plan "$T/k.yaml" | grep -c '^todo ')
[ "$n_todo" -eq 0 ] && pass keep_plan_all_done || fail keep_plan_all_done "$n_todo todo"

# --- a lost output whose inputs are gone: its writers run again first
rm -rf $D/enc
expect keep_lost_output_run 0 '' $R -q run "$T/k.yaml"
kept $D > "$T/got.kept"
cmp -s "$T/ref.kept" "$T/got.kept" && pass keep_lost_output_identical ||
	fail keep_lost_output_identical "$(diff "$T/ref.kept" "$T/got.kept" | head -5)"
overs=$(grep -c 'starting over' $D/logs/runner.log)
[ "$overs" -eq 1 ] && pass keep_lost_output_one_start_over ||
	fail keep_lost_output_one_start_over "$overs"
[ -z "$(left $D)" ] && pass keep_lost_output_deleted_again ||
	fail keep_lost_output_deleted_again "$(left $D | head -3)"

# --- a changed reader: symmetry-merge with the 48 symmetries reads the
# deleted DAG cells; the result equals a fresh run of that YAML
sed -i 's/stage: symmetry-merge, needs: \[dag\]/&, group: 48/' "$T/k.yaml" "$T/r.yaml"
rm -rf $REF
expect keep_changed_reference 0 '' $R -q run "$T/r.yaml"
kept $REF > "$T/ref48.kept"
expect keep_changed_run 0 '' $R -q run "$T/k.yaml"
kept $D > "$T/got48.kept"
cmp -s "$T/ref48.kept" "$T/got48.kept" && ! cmp -s "$T/ref.kept" "$T/ref48.kept" &&
	pass keep_changed_reader_identical ||
	fail keep_changed_reader_identical "$(diff "$T/ref48.kept" "$T/got48.kept" | head -5)"
sed -i 's/, group: 48//' "$T/k.yaml" "$T/r.yaml"

# --- SIGKILL of the runner after N finished jobs (before, during and
# after the deletions), then resume: no finished job runs again
for n in 5 44 80 88; do
	rm -rf $D
	before=$(kill_runner_after "$n" "$T/k.yaml" $D)
	expect "keep_resume_after_kill_at_$n" 0 '' $R -q run "$T/k.yaml"
	kept $D > "$T/got.kept"
	cmp -s "$T/ref.kept" "$T/got.kept" && [ -z "$(left $D)" ] &&
		pass "keep_resume_after_kill_at_${n}_identical" ||
		fail "keep_resume_after_kill_at_${n}_identical" \
		     "$(diff "$T/ref.kept" "$T/got.kept" | head -5)" "$(left $D | head -3)"
	second=$(last_run | grep ' started ' | sed 's/.* started \([^ ]*\) .*/\1/' | sort)
	again=$(comm -12 <(echo "$before") <(echo "$second") | grep -c .)
	[ "$again" -eq 0 ] && ! grep -q 'starting over' $D/logs/runner.log &&
		pass "keep_resume_after_kill_at_${n}_no_rerun" ||
		fail "keep_resume_after_kill_at_${n}_no_rerun" \
		     "rerun: $(comm -12 <(echo "$before") <(echo "$second") | head -3)"
done

# --- keep: listing an intermediate keeps it, and only it
sed -i 's/^keep: \[enc\]/keep: [dag, enc]/' "$T/k.yaml"
rm -rf $D
expect keep_two_run 0 '' $R -q run "$T/k.yaml"
ndag=$(find $D/dag -name '*.dag' | wc -l)
[ "$ndag" -eq "$(find $REF/dag -name '*.dag' | wc -l)" ] &&
	[ -z "$(find $D/vox $D/ssvdag -name '*.svo' -o -name '*.sdag')" ] &&
	pass keep_listed_job_stays || fail keep_listed_job_stays "$ndag dag files"
