#!/usr/bin/env bash
# Resume never trusts a damaged intermediate: after a complete run, one file
# of each kind is deleted, truncated or corrupted (one byte in its middle),
# and the next run must notice it, rebuild it and what follows, and end with
# outputs byte-identical to the uninterrupted run. Directory outputs are
# all-or-nothing: a failed voxelize or encode leaves the previous output.
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh
R=$BIN/voxdag
NAME=resumetest-$$
D=out/$NAME
CFG=$T/p.yaml
trap 'rm -rf "$T" "$D"' EXIT
cat > "$CFG" <<YAML
version: 1
name: $NAME
input:
  mesh: tests/data/bunny.ply
levels: 8
chunk_level: 2
resources: {jobs: 2, mem_budget: 2GiB, job_mem_budget: 512M}
jobs:
  vox:    {stage: voxelize}
  dag:    {stage: svo-to-dag, needs: [vox]}
  ssvdag: {stage: symmetry-merge, needs: [dag]}
  enc:    {stage: encode, needs: [dag, ssvdag]}
  pic:    {stage: render, needs: [enc]}
YAML

# every byte a run leaves that a later stage or a user reads (manifests
# list the statistics files too, whose seconds differ from run to run)
sums() {
	(cd $D && find . -type f \( -name '*.svo' -o -name '*.dag' -o -name '*.sdag' \
		-o -name '*dag' -o -name '*.png' \) |
		LC_ALL=C sort | xargs sha256sum)
}
last_run() { awk '/ run /{buf=""} {buf=buf $0 "\n"} END{printf "%s", buf}' $D/logs/runner.log; }

expect resume_setup 0 '' $R -q run "$CFG"
sums > "$T/ref.sums"
[ "$(wc -l < "$T/ref.sums")" -gt 60 ] && pass resume_setup_has_outputs ||
	fail resume_setup_has_outputs "$(wc -l < "$T/ref.sums") files"

# damage HOW FILE: delete, truncate to half, or flip one byte in the middle
damage() {
	case $1 in
	delete) rm -f "$2" ;;
	truncate) truncate -s $(($(stat -c %s "$2") / 2)) "$2" ;;
	corrupt)
		local off=$(($(stat -c %s "$2") / 2))
		local b=$(od -An -tu1 -j $off -N1 "$2" | tr -d ' ')
		printf "$(printf '\\%03o' $(((b + 1) % 256)))" |
			dd of="$2" bs=1 seek=$off conv=notrunc 2>/dev/null ;;
	esac
}

# kind FILE JOB: the job that must run again for that file
for spec in \
	"svo:$(cd $D && ls vox/*.svo | sed -n 3p):vox" \
	"vox-manifest:vox/manifest:vox" \
	"vox-sources:vox/sources:vox" \
	"dag-cell:$(cd $D && ls dag/cells/*.dag | sed -n 2p):dag/cells/" \
	"dag-root:dag/root.dag:dag/root" \
	"sdag-cell:$(cd $D && ls ssvdag/cells/*.sdag | sed -n 4p):ssvdag/cells/" \
	"sdag-root:ssvdag/root.sdag:ssvdag/root" \
	"encoding:enc/$NAME.ssvdag:enc" \
	"enc-manifest:enc/manifest:enc" \
	"picture:pic.png:pic"; do
	kind=${spec%%:*}; rest=${spec#*:}; file=${rest%%:*}; job=${rest#*:}
	for how in delete truncate corrupt; do
		name="resume_${how}_${kind}"
		[ -f "$D/$file" ] || { fail "$name" "no file $file"; continue; }
		damage $how "$D/$file"
		$R -q run "$CFG" 2>"$T/err"
		rc=$?
		sums > "$T/got.sums"
		if [ $rc -ne 0 ]; then
			fail "$name" "rerun exit $rc" "$(cat "$T/err")"
		elif ! last_run | grep -q " started $job"; then
			fail "$name" "$job was not rerun:" "$(last_run | grep started)"
		elif ! cmp -s "$T/ref.sums" "$T/got.sums"; then
			fail "$name" "$(diff "$T/ref.sums" "$T/got.sums" | head -4)"
		else
			pass "$name"
		fi
	done
done

# --- all or nothing: a voxelize or encode that fails keeps the old output
cp -a $D/vox "$T/vox.before"
out/bin/voxelize tests/data/bunny.ply -o $D/vox --levels 8 --chunk-level 2 \
	--mem-budget 1K -q 2>"$T/err"
if [ $? -eq 1 ] && diff -r "$T/vox.before" $D/vox >/dev/null &&
	[ -z "$(ls -d $D/vox.tmp.* 2>/dev/null)" ]; then
	pass voxelize_failure_keeps_old_output
else
	fail voxelize_failure_keeps_old_output "$(cat "$T/err")" "$(ls $D)"
fi
cp -a $D/enc "$T/enc.before"
out/bin/encode $D/dag/root.dag $D/vox/$(ls $D/vox | head -n 1) -o $D/enc \
	-n $NAME -q 2>"$T/err"
if [ $? -eq 1 ] && diff -r "$T/enc.before" $D/enc >/dev/null &&
	[ -z "$(ls -d $D/enc.tmp.* 2>/dev/null)" ]; then
	pass encode_failure_keeps_old_output
else
	fail encode_failure_keeps_old_output "$(cat "$T/err")" "$(ls $D)"
fi
expect resume_after_failures_fresh 0 '' $R -q run "$CFG"
started=$(last_run | grep -c ' started ')
[ "$started" -eq 0 ] && pass failed_tools_left_outputs_fresh ||
	fail failed_tools_left_outputs_fresh "$started jobs started"

# a file that is not the tool's in an output directory stops it
touch $D/vox/notes.txt
expect voxelize_keeps_foreign_files 1 "holds 'notes.txt', which this tool did not write" \
	out/bin/voxelize tests/data/bunny.ply -o $D/vox --levels 8 -q
[ -f $D/vox/notes.txt ] && pass foreign_file_kept || fail foreign_file_kept
