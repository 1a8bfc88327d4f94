#!/usr/bin/env bash
# The Slurm executor at >= 10,000 jobs (issue 40): the lossless pipeline on
# the bundled bunny at 2^LEVELS with chunk level L0 (default 2^9, L0 6:
# some 13,000 cells, 26,000 jobs) run locally and then on a one-node Slurm
# started here (tests/slurm/local-slurm.sh, Slurm's default limits:
# MaxJobCount 10000, MaxArraySize 1001) with the default bundles (300 s).
# Prints the sbatch calls per 50 cell jobs, the driver's CPU (itself and
# the sbatch/squeue/scontrol it ran) per job and against the stages' CPU,
# slurmctld's CPU, and the wall time against the local executor; checks
# the outputs are the same bytes. Goals: driver and submission <= 2% of
# the stages' CPU, <= 1 sbatch per 50 cell jobs.
# Needs root and Debian's slurm-wlm + munge (make deps); skips otherwise.
#   tests/bench/slurm_bundles.sh [LEVELS [L0 [BUNDLE_SECONDS]]]
set -u
cd "$(dirname "$0")/../.."
. tests/lossless_yaml.sh
L=${1:-9} L0=${2:-6} BS=${3:-300}
if [ "$(id -u)" != 0 ] || ! command -v slurmctld >/dev/null ||
	! command -v munged >/dev/null; then
	echo "bench slurm: skipped (needs root and slurm-wlm + munge: make deps)"
	exit 0
fi
OUT=out/bench/slurm
name=bench-slurm-$L-L$L0
rm -rf "$OUT" && mkdir -p "$OUT"
S=$(mktemp -d /tmp/voxdag-bench-slurm.XXXXXX)
trap 'tests/slurm/local-slurm.sh stop "$S"; rm -rf "$S"' EXIT
if ! env=$(tests/slurm/local-slurm.sh start "$S"); then
	echo "bench slurm: the local Slurm did not start"
	exit 1
fi
eval "$env"

cfg=$OUT/$name.yaml
lossless_yaml "$name" tests/data/bunny.ply "$L" "$L0" \
	"{jobs: 2, threads: 1, mem_budget: 4GiB, job_mem_budget: 1GiB}" > "$cfg"
echo "outputs: $OUT/$name" >> "$cfg"
echo "slurm: {shared_outputs: true, bundle_seconds: $BS}" >> "$cfg"

sums() {
	(cd "$1" && find . -type f \( -name '*.svo' -o -name '*dag' -o \
		-name '*.sdag' -o -name '*.png' \) | LC_ALL=C sort | xargs sha256sum)
}
# field NAME: the number after "NAME" in the last `finished:` line
finished() { grep ' finished: ' "$OUT/$name/logs/runner.log" | tail -n 1; }
field() { finished | sed -n "s/.*$1 \([0-9.]*\)s.*/\1/p"; }
ctld_cpu() { # slurmctld's CPU seconds so far
	awk -v hz="$(getconf CLK_TCK)" '{ printf "%.2f", ($14 + $15) / hz }' \
		"/proc/$(cat "$S/slurmctld.pid")/stat"
}

t0=$(date +%s.%N)
out/bin/voxdag -q run "$cfg" || { echo "bench slurm: local run failed"; exit 1; }
local_wall=$(awk -v a="$t0" -v b="$(date +%s.%N)" 'BEGIN { printf "%.1f", b - a }')
local_stages=$(field 'stages cpu')
sums "$OUT/$name" > "$OUT/local.sum"
rm -rf "${OUT:?}/$name"

c0=$(ctld_cpu)
t0=$(date +%s.%N)
out/bin/voxdag -q run "$cfg" --executor slurm ||
	{ echo "bench slurm: Slurm run failed"; exit 1; }
slurm_wall=$(awk -v a="$t0" -v b="$(date +%s.%N)" 'BEGIN { printf "%.1f", b - a }')
ctld=$(awk -v a="$c0" -v b="$(ctld_cpu)" 'BEGIN { printf "%.1f", b - a }')
sums "$OUT/$name" > "$OUT/slurm.sum"
same=identical
cmp -s "$OUT/local.sum" "$OUT/slurm.sum" || same=DIFFERENT
rl=$OUT/$name/logs/runner.log
jobs=$(finished | sed -n 's/.*, \([0-9]*\) jobs,.*/\1/p')
cells=$(grep -c ' submitted [a-z]*/cells/' "$rl")
sbatch=$(grep -c ' sbatch: ' "$rl")
tasks=$(sed -n 's/.* sbatch: Slurm job [0-9]*, \([0-9]*\) bundles\{0,1\} .*/\1/p' "$rl" |
	awk '{ s += $1 } END { print s + 0 }')
runner=$(field 'runner cpu')
cmds=$(finished | sed -n 's/.*(\([0-9.]*\)s of it in Slurm.*/\1/p')
stages=$(field 'stages cpu')
awk -v L="$L" -v L0="$L0" -v bs="$BS" -v jobs="$jobs" -v cells="$cells" \
	-v sb="$sbatch" -v tasks="$tasks" -v r="$runner" -v cm="$cmds" \
	-v st="$stages" -v lst="$local_stages" -v lw="$local_wall" \
	-v sw="$slurm_wall" -v ctld="$ctld" -v same="$same" \
	-v load="$(cut -d' ' -f1-3 /proc/loadavg)" 'BEGIN {
	printf "bench slurm: bunny 2^%d L0 %d, %d jobs (%d cell jobs), bundles of %d s; outputs %s to local\n", L, L0, jobs, cells, bs, same
	printf "  sbatch calls %d (%d array tasks): %.2f per 50 cell jobs (goal <= 1) %s\n", sb, tasks, 50 * sb / cells, 50 * sb / cells <= 1 ? "met" : "MISSED"
	printf "  driver cpu %.2f s (%.2f s of it sbatch/squeue/scontrol): %.3f ms per job, %.2f%% of the stages cpu %.1f s (goal <= 2%%) %s\n", r, cm, 1000 * r / jobs, 100 * r / st, st, 100 * r / st <= 2 ? "met" : "MISSED"
	printf "  slurmctld cpu %.1f s (%.2f%% of the stages)\n", ctld, 100 * ctld / st
	printf "  wall: Slurm %.1f s, local %.1f s (stages cpu %.1f s): overhead %+.0f%% (load %s)\n", sw, lw, lst, 100 * (sw - lw) / lw, load
}'
rm -rf "${OUT:?}/$name"
