#!/usr/bin/env bash
# The runner's lossy-cluster and edit stages from the outside: config
# errors (one line, exit 1), the lossy pipeline on the bunny (resume, a
# lost lossy DAG rebuilt byte for byte, its encodings decoded against the
# lossy DAG by dag-verify --diff, the report's lossy Tables 1 and 2 against
# the stages' statistics, the red-difference render), and an edit pipeline
# against the edit tool and the stages run by hand.
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh
R=$BIN/voxdag
NAME=clilossy-$$
D=out/$NAME
trap 'rm -rf "$T" out/$NAME' EXIT

# The runner.log lines of the last run; the jobs it started.
last_run() { awk '/ run /{buf=""} {buf=buf $0 "\n"} END{printf "%s", buf}' $D/logs/runner.log; }
started() { last_run | grep ' started ' | sed 's/.* started \([^ ]*\) .*/\1/' | sort | tr '\n' ' '; }

head_cfg() { # the common part, then the jobs given on stdin
	small_pipeline "$NAME" "$PWD/tests/data/bunny.ply"
}

# --- config errors: one line naming file:line:column, exit 1
bad_cfg() { # bad_cfg NAME PATTERN (jobs on stdin)
	head_cfg > "$T/bad.yaml"
	expect "$1" 1 "$2" $R plan "$T/bad.yaml"
}
echo '  l: {stage: lossy-cluster, needs: [dag], inflate: 2}' |
	bad_cfg lossy_unknown_parameter "bad.yaml:10:43: unknown key 'inflate' in job 'l'"
echo '  l: {stage: lossy-cluster, needs: [dag], inflation: 1}' |
	bad_cfg lossy_inflation_out_of_range "'inflation' is 1, outside \(1..100"
echo '  l: {stage: lossy-cluster, needs: [dag], max_refs: many}' |
	bad_cfg lossy_max_refs_not_number "'max_refs' must be a whole number"
echo '  s: {stage: symmetry-merge, needs: [dag], diff_factor: 2}' |
	bad_cfg lossy_parameter_on_other_stage "'diff_factor' is a parameter of lossy-cluster jobs"
echo '  l: {stage: lossy-cluster, needs: [vox]}' |
	bad_cfg lossy_without_svo_to_dag "bad.yaml:10:3: job 'l' \(stage lossy-cluster\) takes needs: \[an svo-to-dag"
echo '  l: {stage: lossy-cluster}' |
	bad_cfg lossy_without_needs "job 'l' \(stage lossy-cluster\) takes needs"
printf '  e: {stage: edit, needs: [dag], script: none.txt}\n' |
	bad_cfg edit_script_missing "bad.yaml:10:42: edit script '.*/none.txt': No such file"
printf '  e: {stage: edit, needs: [dag]}\n' |
	bad_cfg edit_without_script "edit job 'e' has no 'script'"
printf '  e: {stage: edit, needs: [dag], script: [fill box 0 0 0 1 1 1, [x]]}\n' |
	bad_cfg edit_script_bad_line "'script' lines are strings"
printf '  l: {stage: lossy-cluster, needs: [dag]}\n  s: {stage: symmetry-merge, needs: [dag]}\n  e: {stage: encode, needs: [l, s]}\n' |
	bad_cfg encode_two_scenes "job 'e' \(stage encode\) takes needs: \[a DAG job"
printf '  s: {stage: symmetry-merge, needs: [dag]}\n  e: {stage: encode, needs: [dag, s]}\n  r: {stage: render, needs: [e, dag]}\n' |
	bad_cfg render_diff_not_encode "job 'r' \(stage render\) takes needs: \[an encode job\] or"

# --- the lossy pipeline
CFG=$T/lossy.yaml
head_cfg > "$CFG" <<'EOF'
  ssvdag: {stage: symmetry-merge, needs: [dag]}
  enc:    {stage: encode, needs: [dag, ssvdag]}
  pic:    {stage: render, needs: [enc]}
  lossy:  {stage: lossy-cluster, needs: [dag], inflation: 2.0, diff_factor: 1.0, max_refs: 1}
  lssvdag: {stage: symmetry-merge, needs: [lossy]}
  lenc:   {stage: encode, needs: [lossy, lssvdag]}
  lpic:   {stage: render, needs: [lenc, enc]}
EOF
expect lossy_run 0 '' $R -q run "$CFG"
L=$D/lossy/root.dag
expect lossy_root_is_a_dag_chunk 0 '' $BIN/chunk-check $L
# the same as lossy-cluster by hand on the pipeline's root DAG
$BIN/lossy-cluster $D/dag/root.dag -o "$T/hand.dag" -q
expect lossy_equals_by_hand 0 '^differing_voxels=0 ' $BIN/dag-verify --diff "$T/hand.dag" $L
# the LSSVDAG holds the lossy voxels
expect lssvdag_holds_lossy_voxels 0 '^differing_voxels=0 ' \
	$BIN/dag-verify --diff $L $D/lssvdag/root.sdag
# every encoding of the lossy DAG decodes to exactly its voxels...
for f in svdag ussvdag esvdag ssvdag; do
	expect "lossy_${f}_decodes_to_the_lossy_dag" 0 '^differing_voxels=0 only_a=0 only_b=0$' \
		$BIN/dag-verify --diff $L $D/lenc/$NAME.$f
done
# ...and the check can fail: against the lossless DAG it finds exactly the
# voxels lossy-cluster says it changed
changed=$(jq .voxels_changed $L.stats.json)
expect lossy_encoding_differs_from_lossless 0 "^differing_voxels=$changed " \
	$BIN/dag-verify --diff $D/dag/root.dag $D/lenc/$NAME.ssvdag
[ "$changed" -gt 0 ] && pass lossy_changed_some_voxels || fail lossy_changed_some_voxels "$changed"

# the report's Tables 1 and 2 are the statistics files' numbers
S=$L.stats.json T0=$D/enc/$NAME.tables.json T1=$D/lenc/$NAME.tables.json
# Table 1: a row per resolution of the report (levels 8, the default
# resolutions 8..5), each from its own lossy-cluster run: the full one's
# statistics with svo-to-dag's seconds, a lower one's (the root DAG cut
# at its depth) with the cut's; minutes
t1ok=1 rows=0
for r in 8 7 6 5; do
	if [ $r = 8 ]; then
		s=$S cons=$(jq '.table1[0].seconds_svo_to_dag / 60' $T0)
	else
		s=$D/lossy/r$r.dag.stats.json cons=$(jq '.seconds_cut / 60' $s)
	fi
	[ "$(jq .levels $s)" = $r ] || { t1ok=0; fail report_lossy_table1 "$s: levels $(jq .levels $s), not $r"; }
	want=$(printf '| bunny.ply | %d^3 | %.6f | %.6f | %.6f | %.4f | %.4f | %.4f |' $((1 << r)) \
		"$(jq '.voxels_before / 1e6' $s)" "$(jq '[.per_level[].graph_nodes] | add / 1e6' $s)" \
		"$(jq '[.per_level[].edges] | add / 1e6' $s)" "$cons" \
		"$(jq '.seconds_graph / 60' $s)" "$(jq '.seconds_clustering / 60' $s)")
	grep -qF -- "$want" $D/report.md || { t1ok=0; fail report_lossy_table1 "wanted: $want" \
		"$(grep -A8 'similarity graph' $D/report.md)"; }
done
[ "$(sed -n '/^## Table 1: similarity graph/,/^$/p;/^## Table 1: similarity graph/,/^SVDAG/p' $D/report.md |
	grep -c '^| bunny.ply |')" -ge 4 ] || { t1ok=0; fail report_lossy_table1 "not 4 rows"; }
[ $t1ok = 1 ] && pass report_lossy_table1
# a lower resolution's row is the scene at that depth: its voxels are
# the voxels of the root DAG cut there, as the encoder counts them
[ "$(jq .voxels_before $D/lossy/r6.dag.stats.json)" = "$(jq '.table2[] | select(.resolution == 64) | .voxels' $T0 2>/dev/null)" ] &&
	pass report_lossy_table1_cut_voxels ||
	fail report_lossy_table1_cut_voxels "$(jq .voxels_before $D/lossy/r6.dag.stats.json) vs $(jq -c '.table2' $T0 | head -c 400)"
t2ok=1
t2row() { # t2row METHOD TABLES NODES_KEY FORMAT
	local nodes bytes bpv
	nodes=$(jq ".table2[0].$3" $2)
	bytes=$(jq ".table2[0].bytes_$4" $2)
	bpv=$(jq ".table2[0].bits_per_voxel_$4" $2)
	printf '| %s | %s | %.6f | %.6f | %g |' "$1" "$nodes" "$(jq -n "$nodes / 1e6")" \
		"$(jq -n "$bytes / 1048576")" "$bpv"
}
while read -r m t k fmt; do
	want=$(t2row "$m" "$t" "$k" "$fmt")
	grep -qF -- "$want" $D/report.md || { t2ok=0; fail report_lossy_table2 "wanted: $want"; }
done <<EOF
SVO $T0 nodes_svo svo
SVDAG $T0 nodes_svdag svdag
LSVDAG $T1 nodes_svdag svdag
ESVDAG $T0 nodes_svdag esvdag
LESVDAG $T1 nodes_svdag esvdag
SSVDAG $T0 nodes_ssvdag ssvdag
LSSVDAG $T1 nodes_ssvdag ssvdag
EOF
[ $t2ok = 1 ] && pass report_lossy_table2
# the LSVDAG's nodes are those lossy-cluster reports, and fewer than the SVDAG's
[ "$(jq .table2[0].nodes_svdag $T1)" = "$(jq .nodes_after $S)" ] &&
	[ "$(jq .table2[0].nodes_svdag $T1)" -lt "$(jq .table2[0].nodes_svdag $T0)" ] &&
	pass report_lsvdag_nodes_are_lossy_clusters || fail report_lsvdag_nodes_are_lossy_clusters
grep -qF "Error rate $(printf %g "$(jq .error_rate $S)") ($changed voxels changed" $D/report.md &&
	pass report_error_rate || fail report_error_rate "$(grep 'Error rate' $D/report.md)"
[ "$(jq -r '.lossy[0] | .job + " " + .stats + " " + .tables_lossless + " " + .tables_lossy' $D/report.json)" = \
  "lossy $S $T0 $T1" ] && pass report_json_lossy_sources || fail report_json_lossy_sources "$(jq .lossy $D/report.json)"
grep -qF '![pic](pic.png) ![lpic](lpic.png)' $D/report.md &&
	pass report_pictures_side_by_side || fail report_pictures_side_by_side

# the red-difference render: a scene against itself is the plain picture;
# against the lossless scene, some pixels are red
$BIN/render $D/enc/$NAME.ssvdag -o "$T/a.png" --size 200x150 --camera iso -q
$BIN/render $D/enc/$NAME.ssvdag -o "$T/b.png" --size 200x150 --camera iso -q \
	--diff $D/enc/$NAME.svdag
cmp -s "$T/a.png" "$T/b.png" && pass render_diff_self_is_plain || fail render_diff_self_is_plain
expect render_diff_lossy 0 ' [1-9][0-9]* pixels show voxels set in only one' \
	$BIN/render $D/lenc/$NAME.ssvdag -o "$T/c.png" --size 200x150 --camera iso \
	--diff $D/enc/$NAME.ssvdag
$BIN/voxelize tests/data/bunny.ply -o "$T/v7" --levels 7 --chunk-level 0 -q &&
	$BIN/svo-to-dag "$T/v7/chunk-L0-0.svo" -o "$T/other.dag" -q
expect render_diff_other_grid 1 'render: cannot render .*not on one grid' \
	$BIN/render $D/lenc/$NAME.ssvdag -o "$T/d.png" --size 20x15 --diff "$T/other.dag"
expect render_diff_lod 2 'no --lod' $BIN/render $D/lenc/$NAME.ssvdag -o "$T/d.png" \
	--diff $D/enc/$NAME.ssvdag --lod 2

# resume: a second run starts nothing; a lost lossy DAG is rebuilt byte
# for byte, and what follows it is not rerun (same bytes)
cp $L "$T/lossy.saved"
expect lossy_rerun 0 '' $R -q run "$CFG"
[ -z "$(started)" ] && pass lossy_rerun_starts_nothing || fail lossy_rerun_starts_nothing "$(started)"
rm $L
expect lossy_lost 0 '' $R -q run "$CFG"
[ "$(started)" = "lossy/root " ] && pass lossy_lost_reruns_only_it || fail lossy_lost_reruns_only_it "$(started)"
cmp -s $L "$T/lossy.saved" && pass lossy_rebuilt_identical || fail lossy_rebuilt_identical
# a changed parameter reruns the lossy branch only
sed -i 's/max_refs: 1}/max_refs: 2}/' "$CFG"
expect lossy_param_changed 0 '' $R -q run "$CFG"
[ "$(started)" = "lenc lossy/r5 lossy/r6 lossy/r7 lossy/root lpic lssvdag/root " ] &&
	pass lossy_param_reruns_the_branch ||
	fail lossy_param_reruns_the_branch "$(started)"
rm -rf $D

# --- an edit pipeline: the same encodings as the edit tool and the stages
# by hand on the pipeline's root DAG
cat > "$T/edits.txt" <<'EOF'
fill box 0 0 0 20 20 20
carve sphere 128 120 128 30.5
copy 100 100 100 140 140 140 to 10 200 10
EOF
CFG=$T/edit.yaml
head_cfg > "$CFG" <<'EOF'
  ed:     {stage: edit, needs: [dag], script: edits.txt}
  ssvdag: {stage: symmetry-merge, needs: [ed]}
  enc:    {stage: encode, needs: [ed, ssvdag]}
EOF
expect edit_run 0 '' $R -q run "$CFG"
# the edit job runs within the per-job budget (512M), as every stage does
$R plan "$CFG" | grep -q -- '^done ed/root: .* --mem-budget 536870912 ' &&
	pass edit_gets_the_job_budget ||
	fail edit_gets_the_job_budget "$($R plan "$CFG" | grep '^done ed/')"
H=$T/hand
mkdir -p $H
$BIN/edit $D/dag/root.dag -o $H/e.dag --script "$T/edits.txt" -q &&
	$BIN/symmetry-merge $H/e.dag -o $H/e.sdag -q &&
	$BIN/encode $H/e.dag $H/e.sdag -o $H/enc --name $NAME -q --min-level 5
same=1
for f in svdag ussvdag esvdag ssvdag; do
	cmp -s $D/enc/$NAME.$f $H/enc/$NAME.$f || { same=0; fail "edit_${f}_equals_by_hand"; }
done
[ $same = 1 ] && pass edit_encodings_equal_by_hand
expect edit_changed_the_scene 0 '^differing_voxels=[1-9]' $BIN/dag-verify --diff $D/dag/root.dag $D/ed/root.dag
# the script's content is in the key: unchanged, nothing reruns; changed,
# the edit and what follows rerun
expect edit_rerun 0 '' $R -q run "$CFG"
[ -z "$(started)" ] && pass edit_rerun_starts_nothing || fail edit_rerun_starts_nothing "$(started)"
echo 'carve box 0 0 0 5 5 5' >> "$T/edits.txt"
expect edit_script_changed 0 '' $R -q run "$CFG"
[ "$(started)" = "ed/root enc ssvdag/root " ] && pass edit_script_change_reruns ||
	fail edit_script_change_reruns "$(started)"
# the same lines inline give the same encodings
cp -r $D/enc "$T/enc.file"
head_cfg > "$CFG" <<'EOF'
  ed:     {stage: edit, needs: [dag], script: ["fill box 0 0 0 20 20 20", "carve sphere 128 120 128 30.5", "copy 100 100 100 140 140 140 to 10 200 10", "carve box 0 0 0 5 5 5"]}
  ssvdag: {stage: symmetry-merge, needs: [ed]}
  enc:    {stage: encode, needs: [ed, ssvdag]}
EOF
expect edit_inline_run 0 '' $R -q run "$CFG"
same=1
for f in svdag ussvdag esvdag ssvdag; do
	cmp -s $D/enc/$NAME.$f "$T/enc.file/$NAME.$f" || same=0
done
[ $same = 1 ] && pass edit_inline_equals_file || fail edit_inline_equals_file
# a bad line fails the run with the edit tool's one line naming it
head_cfg > "$CFG" <<'EOF'
  ed:     {stage: edit, needs: [dag], script: ["fill box 0 0 0 20 20 20", "fill cube 1 2 3"]}
EOF
$R -q run "$CFG" 2> "$T/bad.err"
rc=$?
[ $rc -eq 1 ] && grep -q "job ed/root failed" "$T/bad.err" &&
	grep -q "edit: cannot parse .*: line 2, column 6: expected box or sphere" "$T/bad.err" &&
	pass edit_bad_line_fails || fail edit_bad_line_fails "rc=$rc" "$(cat "$T/bad.err")"

# --- an edit pipeline with colours: with the voxelize job as a second need
# the edit takes its colour chunks and writes the edited ones beside its
# DAG (<job>/colours), and a colorize job needing the edit packs those:
# the same as the tools by hand; a rerun starts nothing; a lost colour
# directory reruns the edit alone (the same colours: colorize stays)
cedit_cfg() {
	small_pipeline "$NAME" "$PWD/tests/data/spider/spider.obj"
}
rm -rf $D
CFG=$T/cedit.yaml
cedit_cfg > "$CFG" <<'EOF'
  ced: {stage: edit, needs: [dag, vox], script: ["paint sphere 128 128 128 40 colour 255 0 0", "carve sphere 100 100 100 10"]}
  col: {stage: colorize, needs: [ced], method: raw}
  raw: {stage: colorize, needs: [vox], method: raw}
EOF
expect colour_edit_run 0 '' $R -q run "$CFG"
H=$T/chand
mkdir -p $H
printf 'paint sphere 128 128 128 40 colour 255 0 0\ncarve sphere 100 100 100 10\n' > $H/s.txt
$BIN/edit $D/dag/root.dag --colours $D/vox -o $H/e.dag --colours-out $H/ecol \
	--script $H/s.txt -q && $BIN/colorize $H/ecol -o $H/pk --method raw -q
expect colour_edit_dag_by_hand 0 '^differing_voxels=0 ' $BIN/dag-verify --diff $H/e.dag $D/ced/root.dag
# (the files record their command lines: compared through pictures)
pic() { $BIN/render "$1" -o "$3" -s 160x120 -c iso -q -C "$2"; }
pic $H/e.dag $H/ecol $H/hand-dir.png && pic $H/e.dag $H/pk/colours.raw $H/hand-pk.png &&
	pic $D/ced/root.dag $D/ced/colours $H/run-dir.png &&
	pic $D/ced/root.dag $D/col/colours.raw $H/run-pk.png &&
	pic $D/dag/root.dag $D/raw/colours.raw $H/before.png &&
	cmp -s $H/hand-dir.png $H/run-dir.png && cmp -s $H/hand-pk.png $H/run-pk.png &&
	cmp -s $H/hand-pk.png $H/hand-dir.png && pass colour_edit_colours_by_hand ||
	fail colour_edit_colours_by_hand "$(ls $D/ced/colours $D/col)"
! cmp -s $H/before.png $H/run-pk.png && pass colour_edit_colours_edited ||
	fail colour_edit_colours_edited "the picture is the unedited scene's"
expect colour_edit_rerun 0 '' $R -q run "$CFG"
[ -z "$(started)" ] && pass colour_edit_rerun_starts_nothing ||
	fail colour_edit_rerun_starts_nothing "$(started)"
rm -rf $D/ced/colours
expect colour_edit_lost_colours 0 '' $R -q run "$CFG"
[ "$(started)" = "ced/root " ] && [ -f $D/ced/colours/manifest ] &&
	pass colour_edit_lost_colours_rerun || fail colour_edit_lost_colours_rerun "$(started)"
# the colours are those of svo-to-dag's scene: not after another stage
cedit_cfg > "$CFG" <<'EOF'
  ed:  {stage: edit, needs: [dag], script: ["fill box 0 0 0 3 3 3"]}
  ced: {stage: edit, needs: [ed, vox], script: ["fill box 0 0 0 3 3 3"]}
EOF
expect colour_edit_after_edit_refused 1 "job 'ced' \(stage edit\) takes .*with colours, \[an svo-to-dag job, the voxelize job\]" $R -q run "$CFG"
cedit_cfg > "$CFG" <<'EOF'
  ed:  {stage: edit, needs: [dag], script: ["fill box 0 0 0 3 3 3"]}
  col: {stage: colorize, needs: [ed], method: raw}
EOF
expect colorize_of_colourless_edit_refused 1 "job 'col' \(stage colorize\) takes needs: \[a voxelize job\] or \[an edit job with colours\]" $R -q run "$CFG"
