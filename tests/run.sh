#!/usr/bin/env bash
# Runs every test and prints one closing line: "N passed, N failed".
# Unit tests run from the sanitizer build, judged by tests/run-unit.sh (a
# crash, a sanitizer report or a program that ends early is a FAIL);
# command-line tests run the release executables from the outside
# (tests/cli/*.sh); a script that exits non-zero is a FAIL too.
#
# The programs are independent (each CLI script works in its own mktemp
# directory), so TEST_JOBS of them (default: the core count) run at once;
# each one's lines are printed together when it ends, and counted at the
# end in a fixed order, whatever order they finished in.
set -u
cd "$(dirname "$0")/.."
log=out/tests.log
R=out/tests.run
rm -rf "$R"
mkdir -p "$R"
: > "$log"
jobs=${TEST_JOBS:-$(nproc)}

# The slowest first (seconds on 2 cores, 2026-11), so that the long ones
# do not start last and leave one core idle at the end.
progs=()
for t in out/sanitize/tests/test_voxelize out/sanitize/tests/test_edit_colour \
	 tests/cli/fuzz.sh tests/cli/slurm.sh tests/cli/powercut.sh \
	 tests/cli/runner.sh; do
	progs+=("$t")
done
for t in out/sanitize/tests/test_* tests/cli/*.sh; do
	case "$t" in *.o|*/lib.sh) continue ;; esac
	case " ${progs[*]} " in *" $t "*) continue ;; esac
	progs+=("$t")
done

run_one() { # run_one INDEX PROGRAM: its lines, stderr and seconds in $R
	local i=$1 t=$2 t0=$SECONDS
	{
		echo "== $t"
		case "$t" in
		*.sh) bash "$t"; rc=$?
		      [ $rc -eq 0 ] || echo "FAIL $t exited $rc" ;;
		*) tests/run-unit.sh "$t" ;;
		esac
	} > "$R/$i.out" 2> "$R/$i.err" < /dev/null
	echo $((SECONDS - t0)) > "$R/$i.sec"
	cat "$R/$i.out"
}

for i in "${!progs[@]}"; do
	while [ "$(jobs -rp | wc -l)" -ge "$jobs" ]; do
		wait -n
	done
	run_one "$i" "${progs[$i]}" &
done
wait

passed=0 failed=0 skipped=0 times=
for i in "${!progs[@]}"; do
	[ -f "$R/$i.sec" ] || echo "FAIL ${progs[$i]} did not finish" >> "$R/$i.out"
	while IFS= read -r line; do
		case "$line" in
		PASS*) passed=$((passed + 1)) ;;
		FAIL*) failed=$((failed + 1)) ;;
		SKIP*) skipped=$((skipped + 1)) ;;
		esac
	done < "$R/$i.out"
	{ echo "== ${progs[$i]}"; cat "$R/$i.err"; } >> "$log"
	times="$times$(printf '%6ds  %s' "$(cat "$R/$i.sec" 2>/dev/null || echo 0)" "${progs[$i]}")
"
done
echo "--- seconds per test program ($jobs at a time), slowest first:"
printf '%s' "$times" | sort -rn | head -n 8
if [ "$failed" -gt 0 ]; then
	for i in "${!progs[@]}"; do
		grep -q '^FAIL' "$R/$i.out" || continue
		echo "--- ${progs[$i]}: its failures and the end of its stderr"
		grep '^FAIL' "$R/$i.out"
		tail -n 30 "$R/$i.err"
	done
	echo "(every program's stderr: $log)"
fi
echo "$passed passed, $failed failed, $skipped skipped"
[ "$failed" -eq 0 ]
