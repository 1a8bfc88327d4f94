#!/usr/bin/env bash
# voxelize's OUTDIR from the outside: created with its missing parents
# (--help says "created if missing"), a trailing slash stages beside it,
# and the staging directories of dead runs (<OUTDIR>.tmp.<pid>, left by a
# kill -9) are removed by the next run, while a live run's and any other
# name are left alone.
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh
V=$BIN/voxelize
BUNNY=tests/data/bunny.ply

# missing parents
expect outdir_parents 0 '' $V $BUNNY -o "$T/a/b/c" --levels 6 -q
[ -f "$T/a/b/c/manifest" ] && ls "$T/a/b/c" | grep -q '\.svo$' &&
	pass outdir_parents_chunks || fail outdir_parents_chunks "$(ls -R "$T/a")"
# a parent that is a file: one line naming it
: > "$T/file"
expect outdir_parent_is_file 1 "'$T/file/x.tmp.[0-9]+': Not a directory" \
	$V $BUNNY -o "$T/file/x" --levels 6 -q
# a trailing slash: the output is the directory, staged beside it
expect outdir_slash 0 '' $V $BUNNY -o "$T/s/" --levels 6 -q
[ -f "$T/s/manifest" ] && [ -z "$(ls -a "$T/s" "$T" | grep '\.tmp\.')" ] &&
	pass outdir_slash_clean || fail outdir_slash_clean "$(ls -a "$T" "$T/s")"

# staging directories beside OUTDIR: a dead pid's (a process that ran and
# was reaped), a live one's, and names that only look like staging
sh -c 'exit 0' &
dead=$!
wait $dead
sleep 300 &
live=$!
if kill -0 $dead 2>/dev/null; then
	echo "SKIP outdir_stale (pid $dead was reused)"
else
	for n in "o.tmp.$dead" "o.tmp.$live" "o.tmp.+$dead" "o.tmp.${dead}x" \
		 "o.tmp." "ox.tmp.$dead" "o.tmp.$dead.new"; do
		mkdir -p "$T/$n/bins.tmp"
		echo x > "$T/$n/chunk-L0-0.svo"
		echo x > "$T/$n/bins.tmp/0.bin"
	done
	expect outdir_stale_run 0 '' $V $BUNNY -o "$T/o" --levels 6 -q
	[ ! -e "$T/o.tmp.$dead" ] && pass outdir_stale_dead_removed ||
		fail outdir_stale_dead_removed "$(ls -a "$T")"
	left=$(cd "$T" && ls -d o.tmp.* ox.tmp.* | sort | tr '\n' ' ')
	want=$(printf '%s\n' "o.tmp.$live" "o.tmp.+$dead" "o.tmp.${dead}x" \
		"o.tmp." "ox.tmp.$dead" "o.tmp.$dead.new" | sort | tr '\n' ' ')
	[ "$left" = "$want" ] && [ -f "$T/o.tmp.$live/bins.tmp/0.bin" ] &&
		pass outdir_stale_others_kept ||
		fail outdir_stale_others_kept "left: $left" "want: $want"
	[ -f "$T/o/manifest" ] && pass outdir_stale_output || fail outdir_stale_output
fi
kill $live 2>/dev/null
wait $live 2>/dev/null
# a run killed with -9 leaves its staging; the next run removes it
$V $BUNNY -o "$T/k" --levels 12 -j 1 -q 2>/dev/null &
p=$!
for i in $(seq 50); do [ -d "$T/k.tmp.$p" ] && break; sleep 0.1; done
kill -9 $p 2>/dev/null
wait $p 2>/dev/null
[ -d "$T/k.tmp.$p" ] && pass outdir_kill9_leaves_staging ||
	echo "SKIP outdir_kill9_leaves_staging (the run ended first)"
expect outdir_kill9_rerun 0 '' $V $BUNNY -o "$T/k" --levels 6 -q
[ -z "$(ls -a "$T" | grep '^k\.tmp\.')" ] && pass outdir_kill9_cleaned ||
	fail outdir_kill9_cleaned "$(ls -a "$T")"
