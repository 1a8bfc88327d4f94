#!/usr/bin/env bash
# Runs every test and prints one closing line: "N passed, N failed".
# Unit tests run from the sanitizer build, judged by tests/run-unit.sh (a
# crash, a sanitizer report or a program that ends early is a FAIL);
# command-line tests run the release executables from the outside
# (tests/cli/*.sh); a script that exits non-zero is a FAIL too.
set -u
cd "$(dirname "$0")/.."
passed=0 failed=0 skipped=0
log=out/tests.log
: > "$log"

tally() { # reads PASS/FAIL/SKIP lines on stdin, echoes them, counts them
	while IFS= read -r line; do
		echo "$line"
		case "$line" in
		PASS*) passed=$((passed + 1)) ;;
		FAIL*) failed=$((failed + 1)) ;;
		SKIP*) skipped=$((skipped + 1)) ;;
		esac
	done
}

times=
timed() { # timed NAME: after a program, note its seconds for the summary
	times="$times$(printf '%6ds  %s' $((SECONDS - t0)) "$1")
"
}
for t in out/sanitize/tests/test_*; do
	case "$t" in *.o) continue ;; esac
	echo "== $t"
	t0=$SECONDS
	tally < <(tests/run-unit.sh "$t" 2>>"$log")
	timed "$t"
done
for t in tests/cli/*.sh; do
	[ "$(basename "$t")" = lib.sh ] && continue
	echo "== $t"
	t0=$SECONDS
	tally < <(bash "$t" 2>>"$log"; rc=$?; [ $rc -eq 0 ] || echo "FAIL $t exited $rc")
	timed "$t"
done
echo "--- seconds per test program, slowest first:"
printf '%s' "$times" | sort -rn | head -n 8
if [ "$failed" -gt 0 ]; then
	echo "--- stderr of the tests (out/tests.log), last 60 lines:"
	tail -n 60 "$log"
fi
echo "$passed passed, $failed failed, $skipped skipped"
[ "$failed" -eq 0 ]
