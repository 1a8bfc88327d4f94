#!/usr/bin/env bash
# What durability costs (issue 36): the same pipeline run from nothing
# with the release build and with `make config=nofsync` (every fsync
# skipped, io/publish.c's vd_sync_fd), the two interleaved run by run so
# that drift in the machine's speed falls on both; the median wall time of
# each and their ratio, and the fsyncs of one durable run (strace -c).
#
#   tests/bench/durability.sh [RUNS]      (from make bench; RUNS default 3)
#
# Cases: the bundled bunny at 2^10 in cells of level 4 (~1,700 jobs: the
# per-job cost), and Dabrovic's Sponza at 2^14 when config/fetch-sponza.sh
# has fetched it ($VOXDAG_DATA, else out/data), and the Stanford dragon
# at 2^14 from ../shared/data ($VOXDAG_SHARED_DATA). The outputs go to
# out/bench-durability-* and are deleted after.
cd "$(dirname "$0")/../.."
. tests/lossless_yaml.sh
RUNS=${1:-3}
A=out/bin/voxdag
B=out/nofsync/bin/voxdag
if [ ! -x "$A" ] || [ ! -x "$B" ]; then
	echo "durability: needs $A and $B (make all; make config=nofsync all)"
	exit 0
fi

# one NAME BIN CFG: seconds of a run from nothing
one() {
	rm -rf "out/$1"
	local t0=$(date +%s.%N)
	"$2" -q run "$3" || { echo "durability: $2 run $3 failed" >&2; return 1; }
	awk -v a="$t0" -v b="$(date +%s.%N)" 'BEGIN { printf "%.3f\n", b - a }'
}
median() { sort -g | awk '{ v[NR] = $1 } END { print v[int((NR + 1) / 2)] }'; }

case_() { # case_ LABEL MESH LEVELS CHUNK_LEVEL
	local name=bench-durability-$1 cfg=out/bench-durability-$1.yaml i
	lossless_yaml "$name" "$2" "$3" "$4" \
		"{jobs: 2, threads: 1, mem_budget: 8GiB, job_mem_budget: 2GiB}" > "$cfg"
	: > out/dur-a.txt
	: > out/dur-b.txt
	for i in $(seq 1 "$RUNS"); do
		one "$name" "$A" "$cfg" >> out/dur-a.txt || return
		one "$name" "$B" "$cfg" >> out/dur-b.txt || return
	done
	local jobs=$(grep -c ' done ' "out/$name/logs/runner.log")
	local syncs=-
	if command -v strace >/dev/null; then
		rm -rf "out/$name"
		strace -f -c -o out/dur-strace.txt -e trace=fsync,fdatasync \
			"$A" -q run "$cfg" >/dev/null 2>&1 &&
			syncs=$(awk '$NF == "total" { print $(NF - 1) }' out/dur-strace.txt)
	fi
	local a=$(median < out/dur-a.txt) b=$(median < out/dur-b.txt)
	printf '%-22s %6d jobs %8.2f s durable %8.2f s without fsync %6.3fx %7s fsyncs (%.1f a job)\n' \
		"$1" "$jobs" "$a" "$b" "$(awk -v a="$a" -v b="$b" 'BEGIN { print a / b }')" \
		"$syncs" "$(awk -v s="$syncs" -v j="$jobs" 'BEGIN { print (s + 0) / j }')"
	rm -rf "out/$name" "$cfg" out/dur-a.txt out/dur-b.txt out/dur-strace.txt
}

echo "durability: median of $RUNS interleaved runs each, $(nproc) cores, load $(cut -d' ' -f1 /proc/loadavg)"
case_ bunny-10-L4 tests/data/bunny.ply 10 4
SPONZA=${VOXDAG_DATA:-out/data}/sponza/sponza.obj
if [ -f "$SPONZA" ]; then
	case_ sponza-14 "$SPONZA" 14 auto
else
	echo "durability: $SPONZA is absent (config/fetch-sponza.sh fetches it); no Sponza row"
fi
DRAGON=${VOXDAG_SHARED_DATA:-../shared/data}/stanford_dragon.ply
[ -f "$DRAGON" ] && case_ dragon-14 "$DRAGON" 14 auto
