#!/usr/bin/env bash
# A job's peak memory is its own, not the runner's. The kernel starts a
# process's peak (wait4's ru_maxrss) at that of the memory it had before
# its exec, and a job the runner vforks had the runner's: on a 100,000-cell
# plan every job "peaked" at the runner's 119 MiB. Here the runner is made
# large on purpose (a preloaded library that holds 256 MiB, written so it
# is resident, and keeps it from the jobs' environment), and every job of
# a small pipeline must still report a peak far below it, in runner.log
# and in the report's per-stage figures.
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh
R=$BIN/voxdag
NAME=peaktest-$$
D=out/$NAME
CFG=$T/p.yaml
trap 'rm -rf "$T" "$D"' EXIT

cat > "$T/ballast.c" <<'C'
#define _GNU_SOURCE
#include <errno.h>
#include <stdlib.h>
#include <string.h>
char *ballast; /* exported: the writes cannot be optimised away */
__attribute__((constructor)) static void hold(void)
{
	if (strcmp(program_invocation_short_name, "voxdag") != 0)
		return; /* env, on its way to the runner */
	ballast = malloc(256u << 20);
	if (ballast)
		memset(ballast, 1, 256u << 20);
	unsetenv("LD_PRELOAD"); /* the runner's only: not its jobs' */
}
C
if ! cc -shared -fPIC -O1 -o "$T/ballast.so" "$T/ballast.c"; then
	fail peak_setup "cannot build the ballast library"
	exit 0
fi
bunny_pipeline $NAME 6 1 > "$CFG"
expect peak_run 0 '' env LD_PRELOAD="$T/ballast.so" $R -q run "$CFG"
log=$D/logs/runner.log
# the test means something only if the runner really held the ballast
rp=$(sed -n 's/.* finished: .*runner peak \([0-9]*\) MiB.*/\1/p' $log | tail -1)
[ "${rp:-0}" -ge 256 ] && pass peak_runner_is_large ||
	fail peak_runner_is_large "runner peak '${rp}' MiB, expected >= 256"
jobs=$(grep -c ' done .* peak ' $log)
big=$(sed -n 's/.* done \([^ ]*\) in .* peak \([0-9]*\) MiB.*/\1 \2/p' $log |
	awk '$2 >= 100')
[ "$jobs" -ge 10 ] && [ -z "$big" ] && pass peak_jobs_their_own ||
	fail peak_jobs_their_own "$jobs jobs; peaks of 100 MiB or more:" "$big"
# the report's per-stage peaks (MiB) come from the same figures
big=$(python3 - "$D/report.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
def walk(o):
    if isinstance(o, dict):
        for k, v in o.items():
            if 'peak' in k and isinstance(v, (int, float)):
                yield k, v
            yield from walk(v)
    elif isinstance(o, list):
        for v in o:
            yield from walk(v)
peaks = list(walk(r))
if not peaks:
    print('no peak figures')
for k, v in peaks:
    mib = v / 2**20 if 'bytes' in k or v > 1e6 else v
    if mib >= 100:
        print(k, v)
PY
)
[ -z "$big" ] && pass peak_report ||
	fail peak_report "report.json peaks:" "$big"
