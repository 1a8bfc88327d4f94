#!/usr/bin/env bash
# Command-line tests of edit (HashDAG edits of a root DAG chunk): scripts,
# the shell, statistics, and bad input (one line, non-zero exit, nothing
# written, the input untouched). One PASS/FAIL line per case.
set -u
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh
BIN=out/bin

"$BIN/voxelize" tests/data/bunny.ply -o "$T/v" --levels 8 -q &&
	"$BIN/svo-to-dag" "$T/v/chunk-L0-0.svo" -o "$T/b.dag" -q || {
	fail setup "cannot build the bunny DAG"
	exit 1
}
SVO=$T/v/chunk-L0-0.svo
sum0=$(md5sum <"$T/b.dag")

help_lists_options help edit stages/edit/main.c

# edits that cancel out: the saved DAG holds the original voxels
cat >"$T/id.txt" <<'X'
# comment line
fill box 0 0 0 63 63 63   # a corner
carve box 0 0 0 63 63 63
undo
undo
redo
undo
X
expect identity 0 '' "$BIN/edit" "$T/b.dag" -o "$T/id.dag" --script "$T/id.txt" -q
expect identity-verify 0 '' "$BIN/dag-verify" "$T/id.dag" "$SVO"
# same node counts as svo-to-dag's DAG (canonical save)
if [ -f "$T/id.dag" ] && cmp -s <("$BIN/chunk-check" -v "$T/id.dag" 2>&1 | grep 'nodes per level') \
	<("$BIN/chunk-check" -v "$T/b.dag" 2>&1 | grep 'nodes per level'); then
	pass identity-counts
else
	fail identity-counts "level counts differ from svo-to-dag's"
fi

# a 10^3 box in the empty corner: dag-verify counts exactly 1000 new voxels
printf 'carve box 0 0 0 9 9 9\nfill box 0 0 0 9 9 9\n' >"$T/box.txt"
"$BIN/edit" "$T/b.dag" -o "$T/carved.dag" --script <(echo 'carve box 0 0 0 9 9 9') -q
base=$("$BIN/dag-verify" "$T/carved.dag" "$SVO" 2>&1 | grep -oE '^[0-9]+' | head -1)
expect box-run 0 '' "$BIN/edit" "$T/b.dag" -o "$T/box.dag" --script "$T/box.txt" -q -j 1
out=$("$BIN/dag-verify" "$T/box.dag" "$SVO" 2>&1)
n=$(grep -oE '[0-9]+ (differing )?voxels?' <<<"$out" | grep -oE '^[0-9]+' | head -1)
if [ "${n:-0}" -eq $((1000 - ${base:-0})) ] && [ "${n:-0}" -gt 0 ]; then
	pass box-verify
else
	fail box-verify "dag-verify: $out (carve alone: ${base:-0})"
fi
if grep -q '"voxels_changed"' "$T/box.dag.stats.json" 2>/dev/null &&
	grep -q '"nodes_added"' "$T/box.dag.stats.json"; then
	pass stats-json
else
	fail stats-json "no per-operation statistics"
fi

# the shell: edits, undo, gc, stats, save, render
printf 'fill sphere 128 128 128 20\nundo\nredo\ngc\nstats\nsave %s\nrender %s\n' \
	"$T/sh.dag" "$T/sh.png" >"$T/sh.in"
expect shell 0 'reachable' sh -c "'$BIN/edit' --shell '$T/b.dag' <'$T/sh.in'"
[ -s "$T/sh.png" ] && [ -s "$T/sh.dag" ] && pass shell-files || fail shell-files "no png or dag"
expect shell-error 1 'line 1, column 1' sh -c "echo 'explode' | '$BIN/edit' --shell '$T/b.dag'"

# bad input: one line, exit 1, no output, the input untouched
bad() { # NAME PATTERN SCRIPT-TEXT [options]
	local name=$1 pat=$2 text=$3
	shift 3
	printf '%s\n' "$text" >"$T/$name.txt"
	expect "$name" 1 "$pat" "$BIN/edit" "$T/b.dag" -o "$T/$name.dag" --script "$T/$name.txt" "$@"
	if [ -e "$T/$name.dag" ] || [ -e "$T/$name.dag.stats.json" ] ||
		ls "$T" | grep -q '\.tmp\.'; then
		fail "$name-nothing-written" "$(ls "$T")"
	else
		pass "$name-nothing-written"
	fi
}
bad outside 'line 2, column 10: box X 250..256 outside the grid' $'fill box 0 0 0 1 1 1\nfill box 250 0 0 256 1 1'
bad negative 'line 1, column 11: box X -1..3' 'carve box -1 0 0 3 3 3'
bad copy-outside 'copy destination' 'copy 0 0 0 9 9 9 to 250 0 0'
bad malformed 'line 3, column 16: expected a whole number' $'# ok\nfill box 1 2 3 4 5 6\nfill box 1 2 3 x 5 6'
bad missing 'line 1, column .*expected 6 numbers' 'fill box 1 2 3'
bad trailing 'line 1, column 22: expected .*the end of the line' 'fill box 1 2 3 4 5 6 7'
bad no-shape 'line 1, column 6: expected box or sphere' 'fill cube 1 2 3 4 5 6'
bad paint 'no colours' 'paint box 0 0 0 3 3 3'
bad undo-empty 'nothing to undo' 'undo'
bad full-bucket 'full.*run gc' 'fill box 0 0 0 3 3 3' --buckets 2 --bucket-words 4
bad sphere-outside 'sphere centre X' 'fill sphere 999 0 0 3'

# colours: the textured spider in 8 cells; paint, fill with and without a
# colour, carve, copy; the colour directory renders and colorizes
M=tests/data/spider/spider.obj
"$BIN/voxelize" $M -o "$T/cv" --levels 8 --chunk-level 1 -q &&
	for f in "$T"/cv/*.svo; do "$BIN/svo-to-dag" "$f" -o "$T/cd-$(basename "$f" .svo).dag" -q; done &&
	"$BIN/svo-to-dag" --merge "$T"/cd-*.dag -o "$T/c.dag" --to-level 0 -q ||
	fail colour-setup "cannot build the spider"
cat >"$T/paint.txt" <<'X'
paint sphere 128 128 128 40 colour 255 0 0
fill box 0 0 0 9 9 9 colour 0 255 0
fill box 250 250 250 255 255 255
carve sphere 100 100 100 10
copy 100 100 100 139 139 139 to 0 200 0
paint box 0 0 0 255 255 40 colour 0 0 255   # a slab
X
expect colour-edit 0 '' "$BIN/edit" "$T/c.dag" --colours "$T/cv" -o "$T/ce.dag" \
	--colours-out "$T/ce" --script "$T/paint.txt" -q
grep -q '"op": *"paint"' "$T/ce.dag.stats.json" 2>/dev/null && pass colour-stats ||
	fail colour-stats "no paint in the statistics"
expect colour-render 0 '' "$BIN/render" "$T/ce.dag" -o "$T/ce.png" -s 160x120 -c iso -q -C "$T/ce"
"$BIN/render" "$T/c.dag" -o "$T/c.png" -s 160x120 -c iso -q -C "$T/cv"
[ -s "$T/ce.png" ] && ! cmp -s "$T/c.png" "$T/ce.png" && pass colour-render-differs ||
	fail colour-render-differs "the edited picture is the original's"
expect colour-colorize 0 '' "$BIN/colorize" "$T/ce" -o "$T/cpk" --method raw -q
# edits that cancel out give the source's colours back: the same picture
printf 'paint box 0 0 0 255 255 255 colour 1 2 3\nundo\n' >"$T/noop.txt"
"$BIN/edit" "$T/c.dag" --colours "$T/cv" -o "$T/cn.dag" --colours-out "$T/cn" --script "$T/noop.txt" -q
"$BIN/render" "$T/cn.dag" -o "$T/cn.png" -s 160x120 -c iso -q -C "$T/cn"
cmp -s "$T/c.png" "$T/cn.png" && pass colour-undo-identity || fail colour-undo-identity
# a packed colorize file as the source
"$BIN/colorize" "$T/cv" -o "$T/cvp" --method raw -q
expect colour-from-pack 0 '' "$BIN/edit" "$T/c.dag" --colours "$T/cvp/colours.raw" -o "$T/cp.dag" \
	--colours-out "$T/cp" --script "$T/paint.txt" -q
"$BIN/render" "$T/cp.dag" -o "$T/cp.png" -s 160x120 -c iso -q -C "$T/cp"
cmp -s "$T/ce.png" "$T/cp.png" && pass colour-pack-same || fail colour-pack-same
# the shell renders the colours as they are in memory
printf 'render %s\npaint box 0 0 0 255 255 255 colour 255 0 0\nrender %s\n' \
	"$T/sh0.png" "$T/sh1.png" >"$T/shc.in"
expect colour-shell 0 '' sh -c "'$BIN/edit' --shell '$T/c.dag' --colours '$T/cv' <'$T/shc.in'"
"$BIN/render" "$T/c.dag" -o "$T/shg.png" -s 640x480 -c iso -q
[ -s "$T/sh1.png" ] && ! cmp -s "$T/sh0.png" "$T/sh1.png" && ! cmp -s "$T/sh0.png" "$T/shg.png" &&
	pass colour-shell-render || fail colour-shell-render "pictures not coloured"
expect colour-other-scene 1 'colours' "$BIN/edit" "$T/b.dag" --colours "$T/cv" -o "$T/x.dag" \
	--colours-out "$T/x" --script "$T/paint.txt"
echo 'paint box 0 0 0 3 3 3' >"$T/pnc.txt"
expect paint-no-colour 1 "line 1, column .*paint needs 'colour R G B'" "$BIN/edit" "$T/c.dag" \
	-o "$T/pnc.dag" --script "$T/pnc.txt" --colours "$T/cv" --colours-out "$T/pnc"
[ -e "$T/pnc.dag" ] || [ -e "$T/pnc" ] && fail paint-no-colour-nothing-written ||
	pass paint-no-colour-nothing-written
bad colour-no-colours 'needs a scene with colours' 'fill box 0 0 0 3 3 3 colour 1 2 3'
bad colour-range "line 1, column 33: expected a number 0..255" 'fill box 0 0 0 3 3 3 colour 1 2 300'
expect colours-out-alone 2 'needs --colours' "$BIN/edit" "$T/b.dag" -o "$T/x.dag" --script "$T/id.txt" --colours-out "$T/x"
expect colours-no-out 2 'needs --colours-out' "$BIN/edit" "$T/c.dag" -o "$T/x.dag" --script "$T/id.txt" --colours "$T/cv"
# the DAG and its colour directory are replaced together or not at all: a
# failure of the colours (here a file edit did not write in the colour
# directory, which it refuses to replace) leaves the previous DAG, its
# statistics and its colours as they were, and no temporary (edit used to
# publish the DAG, then fail on the colours: a new DAG beside old colours)
state() { (cd "$T" && md5sum ce.dag ce.dag.stats.json ce/* && ls -a ce && ls | grep '\.tmp\.') 2>&1; }
echo x >"$T/ce/foreign.txt"
before=$(state)
expect colours-fail-all-or-nothing 1 "holds 'foreign.txt'" "$BIN/edit" "$T/c.dag" \
	--colours "$T/cv" -o "$T/ce.dag" --colours-out "$T/ce" --script "$T/noop.txt" -q
[ "$(state)" = "$before" ] && pass colours-fail-outputs-untouched ||
	fail colours-fail-outputs-untouched "$(diff <(echo "$before") <(state))"
# the same through the script's save command (the DAG of 'save FILE')
cp "$T/ce.dag" "$T/ce-save.dag"
printf 'paint box 0 0 0 3 3 3 colour 9 9 9\nsave %s\n' "$T/ce-save.dag" >"$T/save.txt"
expect colours-fail-save-command 1 "holds 'foreign.txt'" "$BIN/edit" "$T/c.dag" \
	--colours "$T/cv" -o "$T/ce-x.dag" --colours-out "$T/ce" --script "$T/save.txt" -q
cmp -s "$T/ce.dag" "$T/ce-save.dag" && [ "$(state)" = "$before" ] && [ ! -e "$T/ce-x.dag" ] &&
	pass colours-fail-save-untouched || fail colours-fail-save-untouched "$(ls "$T")"
rm "$T/ce/foreign.txt"
# once the cause is gone, the pair is replaced: the new DAG beside its colours
expect colours-replace 0 '' "$BIN/edit" "$T/c.dag" --colours "$T/cv" -o "$T/ce.dag" \
	--colours-out "$T/ce" --script "$T/noop.txt" -q
"$BIN/render" "$T/ce.dag" -o "$T/ce2.png" -s 160x120 -c iso -q -C "$T/ce"
cmp -s "$T/c.png" "$T/ce2.png" && ! ls "$T" | grep -q '\.tmp\.' && pass colours-replaced ||
	fail colours-replaced "$(ls "$T")"
# the colour source is read while editing: the output cannot replace it
cp -r "$T/cv" "$T/cvsame"
expect colours-out-is-source 1 "is the colour source" "$BIN/edit" "$T/c.dag" \
	--colours "$T/cvsame" -o "$T/same.dag" --colours-out "$T/cvsame" --script "$T/paint.txt" -q
[ ! -e "$T/same.dag" ] && diff -r "$T/cv" "$T/cvsame" >/dev/null && pass colours-out-is-source-untouched ||
	fail colours-out-is-source-untouched
bad mem-budget 'needs .* bytes \(bucket tables\).*--mem-budget of 65536' 'fill box 0 0 0 3 3 3' --mem-budget 64K

head -c 3000 "$T/b.dag" >"$T/trunc.dag"
expect truncated 1 "cannot read '.*trunc.dag': truncated" "$BIN/edit" "$T/trunc.dag" -o "$T/t.dag" --script "$T/id.txt"
[ -e "$T/t.dag" ] && fail truncated-nothing-written || pass truncated-nothing-written
expect ssvdag 1 'SSVDAG' sh -c "'$BIN/symmetry-merge' '$T/b.dag' -o '$T/s.ssvdag' -q && '$BIN/edit' '$T/s.ssvdag' -o '$T/s.dag' --script '$T/id.txt'"
expect no-script 2 'need one of' "$BIN/edit" "$T/b.dag" -o "$T/x.dag"
expect no-output 2 'needs -o' "$BIN/edit" "$T/b.dag" --script "$T/id.txt"
expect bad-threads 2 'threads' "$BIN/edit" "$T/b.dag" -o "$T/x.dag" --script "$T/id.txt" -j 0
[ "$(md5sum <"$T/b.dag")" = "$sum0" ] && pass input-untouched || fail input-untouched
