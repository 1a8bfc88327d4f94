#!/usr/bin/env bash
# colorize in the job graph on the bundled textured spider: the report's
# Table 3 rows carry the numbers of colorize's statistics, the pictures
# use the colours, a rerun starts nothing, a lost packed file is rebuilt;
# bad colorize jobs in the YAML give one line.
set -u
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh
R=$BIN/voxdag
NAME=clicolour-$$
D=out/$NAME
VNAME=clicolourvdb-$$
trap 'rm -rf "$T" out/$NAME out/$VNAME' EXIT

cfg() { # the common part, then the jobs given on stdin
	{
		echo "  sdag:   {stage: symmetry-merge, needs: [dag]}"
		echo "  enc:    {stage: encode, needs: [dag, sdag]}"
		cat
	} | small_pipeline "$NAME" "$PWD/tests/data/spider/spider.obj"
}
bad() { # bad NAME PATTERN (jobs on stdin)
	cfg > "$T/bad.yaml"
	expect "$1" 1 "$2" $R plan "$T/bad.yaml"
}
echo '  c: {stage: colorize, needs: [vox], method: jpeg}' |
	bad colour_bad_method "'method' is auto, vbr, palette or raw"
echo '  c: {stage: colorize, needs: [vox], max_error: 0.01, method: vbr}' |
	bad colour_max_error_vbr "'max_error' 0.01 is below 0.0236, the least method vbr"
echo '  c: {stage: colorize, needs: [vox], max_error: 0}' |
	bad colour_max_error_range "'max_error' is 0, outside \(0..1.8"
# auto meets any max_error above 0 (lossless is lossless: true)
echo '  c: {stage: colorize, needs: [vox], max_error: 0.01}' | cfg > "$T/small.yaml"
expect colour_max_error_auto_small 0 '' $R plan "$T/small.yaml"
echo '  c: {stage: colorize, needs: [enc]}' |
	bad colour_needs_voxelize "takes needs: \[a voxelize job\]"
echo '  d2: {stage: svo-to-dag, needs: [vox], weight_bits: 3}' |
	bad colour_param_elsewhere "'weight_bits' is a parameter of colorize"

CFG=$T/c.yaml
cfg > "$CFG" <<'EOF'
  raw:  {stage: colorize, needs: [vox], method: raw}
  vbr:  {stage: colorize, needs: [vox], method: vbr, max_error: 0.05}
  pal:  {stage: colorize, needs: [vox], method: palette, palette_colours: 256}
  aut:  {stage: colorize, needs: [vox], max_error: 0.05}
  p0:   {stage: render, needs: [enc, raw]}
  p1:   {stage: render, needs: [enc, vbr]}
EOF
expect colour_run 0 '' $R -q run "$CFG"
# a colorize job without a method gets the auto blocks
[ -f $D/aut/colours.auto ] && pass colour_default_auto || fail colour_default_auto "$(ls $D/aut)"
# the raw render equals render by hand with voxelize's own colour chunks
$BIN/render $D/enc/$NAME.ssvdag -o "$T/hand.png" --size 960x720 --camera iso -q -C $D/vox
cmp -s "$T/hand.png" $D/p0.png && pass colour_picture_is_the_chunks_colours ||
	fail colour_picture_is_the_chunks_colours
# Table 3's rows: the statistics' numbers, read here with python's json
ok=1
for j in vbr pal aut; do
	read -r m pr gm gp < <(/usr/bin/python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))["methods"]
m = next(iter(d))
print(m, "%.2f" % d[m]["percent_of_raw"], "%.3f" % d[m]["gmse"], "%.3f" % d[m]["gmse_percent2"])' $D/$j/colorize.stats.json)
	grep -E "^\| \`$j\` \| $m \| [^|]* \| $pr \| [0-9.]+ \| $gm \| $gp \|" $D/report.md >/dev/null ||
		{ ok=0; fail colour_table3_row_$j "wanted $m, % $pr, GMSE $gm, $gp" "$(grep "\`$j\`" $D/report.md)"; }
done
[ $ok = 1 ] && pass colour_table3_rows_are_the_stats
grep -qE '^\| `vbr` .*\| [0-9.]+ \| 0\.9[0-9]* \|$' $D/report.md && pass colour_table3_image_metrics ||
	fail colour_table3_image_metrics "$(grep '`vbr`' $D/report.md)"
expect colour_rerun 0 '' $R -q run "$CFG"
started() { awk '/ run /{buf=""} {buf=buf $0 "\n"} END{printf "%s", buf}' $D/logs/runner.log |
	grep ' started ' | sed 's/.* started \([^ ]*\) .*/\1/' | sort | tr '\n' ' '; }
[ -z "$(started)" ] && pass colour_rerun_starts_nothing || fail colour_rerun_starts_nothing "$(started)"
cp $D/vbr/colours.vbr "$T/saved.vbr"
rm $D/vbr/colours.vbr
expect colour_lost 0 '' $R -q run "$CFG"
# rebuilt to the same bytes, so the picture of it is not redrawn
[ "$(started)" = "vbr " ] && pass colour_lost_reruns_only_it || fail colour_lost_reruns_only_it "$(started)"
cmp -s $D/vbr/colours.vbr "$T/saved.vbr" && pass colour_rebuilt_identical || fail colour_rebuilt_identical

# --- an OpenVDB input: colours from its Vec3 grid through the same jobs
mkdir -p "$T/grids"
$BIN/vdb-make-test-grids "$T/grids"
VD=out/$VNAME
vyaml() { # vyaml COLOUR_GRID
	cat <<EOF
version: 1
name: $VNAME
input: {vdb: $T/grids/colour.vdb, grid: density, colour_grid: $1}
levels: 5
chunk_level: 2
resources: {jobs: 2, mem_budget: 2GiB, job_mem_budget: 512M}
jobs:
  vox:  {stage: voxelize}
  dag:  {stage: svo-to-dag, needs: [vox]}
  sdag: {stage: symmetry-merge, needs: [dag]}
  enc:  {stage: encode, needs: [dag, sdag]}
  raw:  {stage: colorize, needs: [vox], method: raw}
  p0:   {stage: render, needs: [enc, raw]}
EOF
}
vyaml Cd_coarse > "$T/v.yaml"
expect vdb_colour_run 0 '' $R -q run "$T/v.yaml"
grep -rq "colours from grid 'Cd_coarse'" $VD/logs/ &&
	pass vdb_colour_grid_passed_on || fail vdb_colour_grid_passed_on "$(ls $VD/logs)"
n_svo=$(ls $VD/vox/*.svo | wc -l)
[ "$n_svo" -gt 1 ] && [ "$(ls $VD/vox/*.col | wc -l)" = "$n_svo" ] &&
	pass vdb_colour_col_per_cell || fail vdb_colour_col_per_cell "$(ls $VD/vox)"
$BIN/render $VD/enc/$VNAME.ssvdag -o "$T/vhand.png" --size 960x720 --camera iso -q -C $VD/vox
cmp -s "$T/vhand.png" $VD/p0.png && pass vdb_colour_picture_is_the_chunks_colours ||
	fail vdb_colour_picture_is_the_chunks_colours
vyaml color > "$T/vbad.yaml"
# the runner's own report of a failed job (several lines) names the cause
$R -q run "$T/vbad.yaml" > "$T/vbad.out" 2>&1
rc=$?
[ $rc = 1 ] && grep -q "colour grid 'color' holds float values" "$T/vbad.out" &&
	pass vdb_colour_grid_not_vec3 || fail vdb_colour_grid_not_vec3 "exit $rc" "$(cat "$T/vbad.out")"
