#!/usr/bin/env bash
# Power cuts: a multi-hundred-job pipeline (bunny 2^8 in cells of 32^3)
# writes to a loop-mounted ext4 image whose power is cut at 20 random
# moments, four in each phase (voxelize, the cells, the merges, encode, the
# report: while it is written or just after the run ended), with ext4's shutdown ioctl without flushing the journal
# (tests/tools/fs_shutdown.c): the file system stops at once and, once
# remounted, holds only what had reached the device. After each cut the
# image is remounted and the same command run again; it must exit 0 with
# outputs byte-identical to an uninterrupted run's, no statistics file
# empty, and no staging entry (NAME.tmp.PID...) left anywhere.
# Needs root, loop devices and mkfs.ext4; skips with one line without them.
# VOXDAG_CUT_SEED repeats a sequence of moments.
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh
R=$BIN/voxdag
CUT=${CUT:-out/tests/fs_shutdown}
M=$T/mnt
D=$M/out
CFG=$T/p.yaml
cleanup() {
	mountpoint -q "$M" 2>/dev/null && umount -l "$M"
	rm -rf "$T"
}
trap cleanup EXIT

why=
if [ "$(id -u)" != 0 ]; then
	why="needs root to mount a file system image"
elif ! command -v mkfs.ext4 >/dev/null || ! command -v losetup >/dev/null; then
	why="needs mkfs.ext4 and losetup (e2fsprogs, mount)"
elif [ ! -x "$CUT" ]; then
	why="$CUT is not built (make test-build)"
else
	mkdir -p "$M"
	truncate -s 256M "$T/img" && mkfs.ext4 -q -F "$T/img" 2>"$T/mkfs.err" ||
		why="mkfs.ext4 failed: $(head -1 "$T/mkfs.err")"
	[ -z "$why" ] && ! mount -o loop "$T/img" "$M" 2>"$T/mount.err" &&
		why="no loop device: $(head -1 "$T/mount.err")"
fi
if [ -n "$why" ]; then
	echo "SKIP powercut ($why)"
	exit 0
fi

SEED=${VOXDAG_CUT_SEED:-$$}
RANDOM=$SEED
echo "powercut.sh: seed $SEED (VOXDAG_CUT_SEED=$SEED repeats it)" >&2
bunny_pipeline pc 8 3 > "$CFG"
echo "outputs: $D" >> "$CFG"

sums() {
	(cd $D && find . -type f \( -name '*.svo' -o -name '*.dag' -o -name '*.sdag' \
		-o -name '*dag' -o -name '*dag48' \) -not -path '*.tmp.*' |
		LC_ALL=C sort | xargs sha256sum)
}

t0=$(date +%s%N)
expect powercut_setup 0 '' $R -q run "$CFG"
echo "powercut.sh: an uninterrupted run takes $((($(date +%s%N) - t0) / 1000000)) ms" >&2
sums > "$T/ref.sums"
cells=$(grep -c ' started dag/cells/' $D/logs/runner.log)

# remount: the image as a power cut left it, the journal replayed
remount() {
	local k
	for k in $(seq 1 100); do
		umount "$M" 2>/dev/null && break
		sleep 0.05
	done
	mountpoint -q "$M" && { echo "cannot unmount $M" >&2; return 1; }
	mount -o loop "$T/img" "$M"
}

# count PATTERN: lines of the running pipeline's runner.log matching it
count() {
	local n
	n=$(grep -c -- "$1" $D/logs/runner.log 2>/dev/null)
	echo "${n:-0}"
}

# one_cut I PHASE: runs the pipeline from nothing, cuts the power when the
# phase's moment comes (a job drawn at random among the phase's jobs has
# started, then 0-20 ms more), remounts and runs it again. Returns 2 when
# the run ended before the cut (the moment is drawn again).
one_cut() {
	local i=$1 phase=$2 pat at pid rc
	rm -rf $D
	sync
	case $phase in
	voxelize) pat=' started vox ('; at=1 ;;
	cells)    pat=' started [a-z]*/cells/'; at=$((RANDOM % (2 * cells) + 1)) ;;
	merges)   pat=' started [a-z]*/root ('; at=$((RANDOM % 2 + 1)) ;;
	encode)   pat=' started enc ('; at=1 ;;
	report)   pat=' finished: '; at=1 ;;
	esac
	# a session of its own: the cut takes the runner and every job down
	setsid $R -q run "$CFG" 2>"$T/cut.err" &
	pid=$!
	while [ "$(count "$pat")" -lt $at ] && kill -0 $pid 2>/dev/null; do
		sleep 0.002
	done
	[ $phase = report ] || sleep "0.0$((RANDOM % 21))"
	if ! kill -0 $pid 2>/dev/null; then
		wait $pid
		# the report is written in a few milliseconds after the last
		# job: a cut just after the run ended tests what it left as
		# much (keys synced at the end, the report), so it counts
		[ $phase = report ] || return 2
	fi
	$CUT "$M" || { fail "powercut_${i}_$phase" "the shutdown ioctl failed"; return 1; }
	kill -9 -- -$pid 2>/dev/null
	wait $pid 2>/dev/null
	remount || { fail "powercut_${i}_$phase" "cannot remount the image"; return 1; }
	# the rerun: exit 0, the same outputs, nothing half-written left
	$R -q run "$CFG" 2>"$T/err"
	rc=$?
	sums > "$T/got.sums"
	local left empty
	left=$(find $D -name '*.tmp.*' | head -3)
	empty=$(find $D -name '*.stats.json' -empty | head -3)
	if [ $rc -ne 0 ]; then
		fail "powercut_${i}_$phase" "rerun exit $rc" "$(head -c 600 "$T/err")"
	elif ! cmp -s "$T/ref.sums" "$T/got.sums"; then
		fail "powercut_${i}_$phase" "outputs differ" "$(diff "$T/ref.sums" "$T/got.sums" | head -4)"
	elif [ -n "$left" ] || [ -n "$empty" ]; then
		fail "powercut_${i}_$phase" "left after the rerun:" $left $empty
	elif [ ! -s $D/report.md ]; then
		fail "powercut_${i}_$phase" "no report after the rerun"
	else
		pass "powercut_${i}_$phase"
	fi
}

phases=(voxelize cells merges encode report)
i=0 late=0
while [ $i -lt 20 ]; do
	phase=${phases[$((i % 5))]}
	one_cut $((i + 1)) $phase
	if [ $? -eq 2 ]; then
		late=$((late + 1))
		if [ $late -ge 20 ]; then
			fail "powercut_$((i + 1))_$phase" "20 runs ended before their moment"
			break
		fi
		continue
	fi
	i=$((i + 1))
done
echo "powercut.sh: 20 cuts, $late runs ended before their moment" >&2
