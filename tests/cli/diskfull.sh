#!/usr/bin/env bash
# Disk full, in every stage and in the runner. Each output goes to a small
# tmpfs that a filler file has filled up to a few amounts of free space
# (none, half, and all but the last page of what the output needs). Every time:
# exit 1 with one error line saying "No space left on device" (no crash,
# no sanitizer report), the tmpfs holds exactly what it held before (a
# previous complete output stays byte for byte, no temporary is left),
# and once the filler is gone the same command succeeds with outputs
# byte-identical to a run on an ordinary disk.
#
# Needs a mount: as root directly, otherwise in a user and mount namespace
# (unshare -Urm); when neither works it prints one SKIP line.
cd "$(dirname "$0")/../.."
if [ "$(id -u)" != 0 ] && [ -z "${VOXDAG_DISKFULL_NS:-}" ]; then
	if unshare -Urm true 2>/dev/null; then
		VOXDAG_DISKFULL_NS=1 exec unshare -Urm bash "$0" "$@"
	fi
	echo "SKIP diskfull: not root and no user namespaces (unshare -Urm failed)"
	exit 0
fi
. tests/cli/lib.sh
F=$T/full
mkdir -p "$F"
if ! mount -t tmpfs -o size=4m tmpfs "$F" 2>"$T/mount.err"; then
	echo "SKIP diskfull: cannot mount a tmpfs: $(head -n 1 "$T/mount.err")"
	exit 0
fi
trap 'umount "$F" 2>/dev/null; rm -rf "$T"' EXIT

SECONDS=0
# The sanitizer build when there is one (make test builds it), so that an
# error path that overflows, leaks or invokes undefined behaviour is a FAIL.
SB=out/sanitize/bin
[ -z "${VOXDAG_NO_SANITIZE:-}" ] && [ -x "$SB/encode" ] && [ -x "$SB/voxdag" ] && BIN=$SB
export ASAN_OPTIONS=detect_leaks=1:exitcode=86 LSAN_OPTIONS=exitcode=86
export UBSAN_OPTIONS=halt_on_error=1:exitcode=86
BUNNY=tests/data/bunny.ply

# --- inputs and reference outputs on an ordinary disk, at two depths:
# level 7 is the run under test, level 6 the previous output it replaces
R=$T/ref
mkdir -p "$R"
RB=out/bin # inputs from the release build: they are not under test
for L in 6 7; do
	$RB/voxelize -q $BUNNY -o "$R/cells$L" --levels $L --chunk-level 1 &&
	$RB/voxelize -q $BUNNY -o "$R/mono$L" --levels $L --chunk-level 0 &&
	$RB/svo-to-dag -q "$R/mono$L/chunk-L0-0.svo" -o "$R/root$L.dag" &&
	$RB/symmetry-merge -q "$R/root$L.dag" -o "$R/root$L.sdag" &&
	$RB/encode -q "$R/root$L.dag" "$R/root$L.sdag" -o "$R/enc$L" --name s ||
		{ fail inputs "level $L"; exit 1; }
	# a coloured scene in 8 cells for edit --colours (its root DAG)
	$RB/voxelize -q $BUNNY -o "$R/col$L" --levels $L --chunk-level 1 &&
	$RB/colour-make-test "$R/col$L" &&
	for f in "$R/col$L"/*.svo; do
		$RB/svo-to-dag -q "$f" -o "$R/col$L-$(basename "$f" .svo).dag" || exit 1
	done &&
	$RB/svo-to-dag -q --merge "$R/col$L"-*.dag -o "$R/colroot$L.dag" --to-level 0 ||
		{ fail inputs "colours, level $L"; exit 1; }
done
echo 'carve box 0 0 0 40 40 40' > "$R/edit.txt"
echo 'paint box 0 0 0 40 40 40 colour 9 8 7' > "$R/paint.txt"

# run_stage WHAT L OUT: the command of each stage at depth L, writing OUT
run_stage() {
	local L=$2 out=$3
	case $1 in
	voxelize) $BIN/voxelize -q $BUNNY -o "$out" --levels $L --chunk-level 1 ;;
	svo-to-dag) $BIN/svo-to-dag -q "$R/mono$L/chunk-L0-0.svo" -o "$out" ;;
	symmetry-merge) $BIN/symmetry-merge -q "$R/root$L.dag" -o "$out" ;;
	lossy-cluster) $BIN/lossy-cluster -q "$R/root$L.dag" -o "$out" ;;
	encode) $BIN/encode -q "$R/root$L.dag" "$R/root$L.sdag" -o "$out" --name s ;;
	render) $BIN/render -q "$R/enc$L/s.ssvdag" -o "$out" --size 96x64 ;;
	edit) $BIN/edit -q "$R/root$L.dag" -o "$out" --script "$R/edit.txt" ;;
	# the DAG and its colour directory beside it: both or neither
	edit-colours) $BIN/edit -q "$R/colroot$L.dag" --colours "$R/col$L" \
		-o "$out" --colours-out "$out.col" --script "$R/paint.txt" ;;
	vdb-export) $BIN/vdb-export -o "$out" "$R/cells$L" >/dev/null ;;
	esac
}

# snapshot: every file of the tmpfs but the filler, with its checksum
snapshot() {
	(cd "$F" && find . -mindepth 1 ! -name filler ! -type f | LC_ALL=C sort &&
		find . -type f ! -name filler -print0 | LC_ALL=C sort -z |
		xargs -0 -r sha256sum)
}

# fill FREE_KIB: leaves about FREE_KIB of free space on the tmpfs
fill() {
	rm -f "$F/filler"
	local avail=$(($(stat -f -c '%a * %S' "$F")))
	local size=$((avail - $1 * 1024))
	[ $size -gt 0 ] && fallocate -l $size "$F/filler"
	[ "$(stat -f -c %a "$F")" -le $(($1 / 4 + 1)) ] ||
		fail "fill-$1k" "$(df -k "$F" | tail -n 1)"
}

# deterministic files of an output (statistics and manifests hold seconds;
# an OpenVDB file holds a random UUID in bytes 22..57)
same_bytes() { # A B: file or directory
	local a=$1 b=$2 f
	case $a in *.vdb)
		cmp -s <(head -c 21 "$a"; tail -c +58 "$a") <(head -c 21 "$b"; tail -c +58 "$b")
		return ;;
	esac
	if [ -f "$a" ]; then cmp -s "$a" "$b"; return; fi
	for f in "$a"/*; do
		case $f in *.json | */manifest | *.md | *.csv) continue ;; esac
		cmp -s "$f" "$b/${f##*/}" || return 1
	done
	[ "$(ls "$a" | grep -cvE '\.json$|^manifest$|\.md$|\.csv$')" = \
	  "$(ls "$b" | grep -cvE '\.json$|^manifest$|\.md$|\.csv$')" ]
}

# one_failure NAME: the last command failed as a full disk should
one_failure() {
	local name=$1 rc=$2
	if [ "$rc" -ne 1 ]; then
		fail "$name" "exit $rc, expected 1" "$(head -c 800 "$T/err")"
		return 1
	fi
	if grep -qE 'Sanitizer|runtime error|Segmentation|Aborted' "$T/err"; then
		fail "$name" "sanitizer report or crash:" "$(head -c 800 "$T/err")"
		return 1
	fi
	if [ "$(wc -l < "$T/err")" -ne 1 ] || ! grep -q 'No space left on device' "$T/err"; then
		fail "$name" "expected one line naming ENOSPC, got:" "$(head -c 800 "$T/err")"
		return 1
	fi
	return 0
}

# check_stage WHAT OUTNAME: over a previous output (made at 2^6), for
# each amount of free space, the stage fails cleanly and leaves the tmpfs
# as it was; with the filler gone it succeeds with the reference's bytes
check_stage() {
	local what=$1 out=$F/$2 ref=$T/ref-$2
	# the reference at the same path: chunks record their command line
	rm -rf "${F:?}"/*
	run_stage $what 7 "$out" 2>"$T/err" || { fail "$what-reference" "$(cat "$T/err")"; return; }
	local need=$(du -sk "$F" | cut -f1)
	mv "$out" "$ref"
	local ok=1 free rc
	# nothing, some, all but the last page (the statistics file)
	for free in 0 $((need / 2)) $((need - 4)); do
		rm -rf "${F:?}"/*
		run_stage $what 6 "$out" 2>"$T/err" ||
			{ fail "$what-previous" "$(cat "$T/err")"; return; }
		snapshot > "$T/before"
		fill $free
		run_stage $what 7 "$out" 2>"$T/err"
		rc=$?
		one_failure "$what-full-free${free}k" $rc || { ok=0; break; }
		[ -n "${VOXDAG_DISKFULL_SHOW:-}" ] && echo "  $(cat "$T/err")" >&2
		snapshot > "$T/after"
		if ! cmp -s "$T/before" "$T/after"; then
			fail "$what-full-free${free}k-unchanged" \
				"$(diff "$T/before" "$T/after" | head -n 20)"
			ok=0
			break
		fi
	done
	[ $ok = 1 ] && pass "$what-disk-full"
	rm -f "$F/filler"
	run_stage $what 7 "$out" 2>"$T/err"
	rc=$?
	if [ $rc -ne 0 ]; then
		fail "$what-after-freeing" "exit $rc" "$(head -c 800 "$T/err")"
	elif ! same_bytes "$ref" "$out"; then
		fail "$what-after-freeing" "output differs from the reference run"
	else
		pass "$what-after-freeing"
	fi
}

echo "diskfull: inputs ${SECONDS}s" >&2
check_stage voxelize vox
check_stage svo-to-dag root.dag
check_stage symmetry-merge root.sdag
check_stage lossy-cluster lossy.dag
check_stage encode enc
check_stage render pic.png
check_stage edit edited.dag
check_stage edit-colours painted.dag
check_stage vdb-export scene.vdb

# --- the runner: a pipeline whose outputs are on the tmpfs. A complete
# run at 2^6 is there first; the run at 2^7 then meets a full disk at
# several points. Each time: exit 1, the cause named once, no temporary
# left, and every output under its final name whole (its chunk checks,
# its manifest verifies); once space is freed the same command finishes
# with the outputs of a run that never failed.
pipeline() { # LEVELS DIR: the pipeline file of depth LEVELS writing DIR
	lossless_yaml diskfull "$BUNNY" "$1" 1 \
		"{jobs: 2, mem_budget: 2GiB, job_mem_budget: 512M}"
	echo "  pic:    {stage: render, needs: [enc]}"
	echo "outputs: $2"
}
pipeline 6 "$F/pipe" > "$T/p6.yaml"
pipeline 7 "$F/pipe" > "$T/p7.yaml"
# the final outputs' bytes (statistics, manifests, logs and reports hold
# seconds)
final_sums() {
	(cd "$1" && find . -type f \( -name '*.svo' -o -name '*.dag' -o -name '*.sdag' \
		-o -name '*dag' -o -name '*.png' \) | LC_ALL=C sort | xargs sha256sum)
}
# whole DIR: no temporary, every chunk passes chunk-check, every manifest
# matches its directory
whole() {
	local d=$1 bad
	bad=$(find "$d" -name '*.tmp*')
	[ -z "$bad" ] || { echo "temporaries: $bad"; return 1; }
	find "$d" \( -name '*.svo' -o -name '*.dag' -o -name '*.sdag' \) -print0 |
		xargs -0 -r $BIN/chunk-check || return 1
	local m dir h size name
	for m in $(find "$d" -name manifest); do
		dir=$(dirname "$m")
		while read -r h size name; do
			[ "$h" = voxdag-manifest ] && continue
			[ "$(stat -c %s "$dir/$name" 2>/dev/null)" = "$size" ] ||
				{ echo "$dir/$name: not the size its manifest says"; return 1; }
		done < "$m"
		[ "$(ls "$dir" | grep -vc '^manifest$')" = "$(($(wc -l < "$m") - 1))" ] ||
			{ echo "$dir: files not in its manifest"; return 1; }
	done
	return 0
}
# runner_full NAME PREPARE FREE...: for each FREE, PREPARE sets the stage
# (an earlier run, lost outputs), the disk is filled up to FREE KiB, and
# the 2^7 run must fail cleanly; after freeing, finish like the reference
runner_full() {
	local name=$1 prepare=$2 free rc why failed=0
	shift 2
	for free in "$@"; do
		rm -f "$F/filler"
		$prepare || { fail "$name-prepare" "$(cat "$T/err")"; return; }
		fill $free
		$BIN/voxdag -q run "$T/p7.yaml" >"$T/out" 2>"$T/err"
		rc=$?
		[ -n "${VOXDAG_DISKFULL_SHOW:-}" ] && sed "s/^/  $name $free: /" "$T/err" >&2
		if [ $rc -eq 0 ]; then
			: # room enough after all: the outputs are checked below
		elif [ $rc -ne 1 ] || grep -qE 'Sanitizer|runtime error' "$T/err" ||
		     [ "$(grep -c 'No space left on device' "$T/err")" -ne 1 ]; then
			fail "$name-free${free}k" "exit $rc; expected 1 and the cause once:" \
				"$(head -c 1500 "$T/err")"
			return
		else
			failed=$((failed + 1))
		fi
		if ! why=$(whole "$F/pipe" 2>&1); then
			fail "$name-free${free}k-whole" "$why"
			return
		fi
		rm -f "$F/filler"
		$BIN/voxdag -q run "$T/p7.yaml" >"$T/out" 2>"$T/err"
		rc=$?
		final_sums "$F/pipe" > "$T/sums"
		if [ $rc -ne 0 ] || ! cmp -s "$T/sums" "$T/pipe7.sums"; then
			fail "$name-free${free}k-rerun" "exit $rc" "$(head -c 800 "$T/err")" \
				"$(diff "$T/pipe7.sums" "$T/sums" | head -n 10)"
			return
		fi
	done
	# most amounts must really have failed, or the case tests nothing
	if [ $failed -ge $(($# > 1 ? $# - 1 : 1)) ]; then
		pass "$name"
	else
		fail "$name" "only $failed of $# runs met a full disk"
	fi
}

echo "diskfull: stages ${SECONDS}s" >&2
# the runner from the release build: its runs start ~20 stage processes
# each, whose error paths the sanitizer build has just been through above
BIN=${RELEASE_BIN:-out/bin}
rm -rf "${F:?}"/*
$BIN/voxdag -q run "$T/p7.yaml" 2>"$T/err" || fail runner-reference "$(cat "$T/err")"
final_sums "$F/pipe" > "$T/pipe7.sums"
cp -a "$F/pipe" "$T/pipe7"

# nothing there yet: the runner cannot even begin a log
fresh() { rm -rf "${F:?}"/*; }
runner_full runner-fresh-disk-full fresh 0

# a complete 2^6 run there: voxelize (whose bins need the most) fails
previous() { rm -rf "${F:?}"/*; $BIN/voxdag -q run "$T/p6.yaml" 2>"$T/err"; }
runner_full runner-voxelize-disk-full previous 0 1000

# the 2^7 run complete but its later outputs lost: the symmetry-merge
# cells and root, encode, render, the report meet the full disk
lost() {
	rm -rf "${F:?}"/*
	cp -a "$T/pipe7" "$F/pipe" &&
	rm -rf "$F/pipe/ssvdag" "$F/pipe/enc" "$F/pipe"/pic.png*
}
lost
need=$(($(du -sk "$T/pipe7" | cut -f1) - $(du -sk "$F/pipe" | cut -f1)))
runner_full runner-later-jobs-disk-full lost 0 $((need / 4)) $((need / 2)) \
	$((3 * need / 4))

# everything done but the report: the previous report stays as it was
done_all() { rm -rf "${F:?}"/*; cp -a "$T/pipe7" "$F/pipe"; }
runner_full runner-report-disk-full done_all 0
done_all
fill 0
$BIN/voxdag -q run "$T/p7.yaml" >"$T/out" 2>"$T/err"
if [ $? -eq 1 ] && cmp -s "$F/pipe/report.md" "$T/pipe7/report.md" &&
   cmp -s "$F/pipe/report.csv" "$T/pipe7/report.csv" &&
   grep -q "^voxdag: cannot write the report: cannot write '.*report.md': No space left on device" "$T/err"; then
	pass runner-report-kept
else
	fail runner-report-kept "$(cat "$T/err")"
fi
echo "diskfull: ${SECONDS}s" >&2
