#!/usr/bin/env bash
# run-unit.sh PROGRAM: runs one unit test program (tests/unit/check.h) and
# prints its PASS/FAIL lines, plus one FAIL line of its own when the program
# did not end the way a finished program does:
#   - it exited with a status other than 0 (or 1 after reporting a FAIL):
#     a signal, a sanitizer report (ASan, UBSan and LSan share one runtime
#     and so one exit status, 86 here), an exit() from inside a test;
#   - it printed no "END n" line, or n differs from the PASS/FAIL lines seen
#     (a program that stopped early, or printed verdicts twice).
# The program's stderr goes to stderr. Exit status 0 when nothing failed.
set -u
prog=$1
out=$(ASAN_OPTIONS=detect_leaks=1:exitcode=86:abort_on_error=0 \
	LSAN_OPTIONS=exitcode=86 \
	UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1:exitcode=86 \
	"$prog" < /dev/null)
rc=$?
printf '%s\n' "$out" | grep -E '^(PASS|FAIL|SKIP) '
verdicts=$(printf '%s\n' "$out" | grep -cE '^(PASS|FAIL) ')
fails=$(printf '%s\n' "$out" | grep -cE '^FAIL ')
end=$(printf '%s\n' "$out" | sed -n 's/^END \([0-9][0-9]*\)$/\1/p' | tail -n 1)
name=$(basename "$prog")
bad=0
case $rc in
0) ;;
1) [ "$fails" -gt 0 ] || { echo "FAIL $name exited 1 without a failed test"; bad=1; } ;;
86) echo "FAIL $name: sanitizer report (ASan, UBSan or LSan; exit 86), see the log"; bad=1 ;;
*) if [ "$rc" -gt 128 ]; then
	echo "FAIL $name killed by signal $((rc - 128))"
   else
	echo "FAIL $name exited $rc"
   fi
   bad=1 ;;
esac
if [ -z "$end" ]; then
	echo "FAIL $name ended early: no END line after $verdicts tests"
	bad=1
elif [ "$end" -ne "$verdicts" ]; then
	echo "FAIL $name ran $end tests but printed $verdicts verdicts"
	bad=1
fi
[ "$bad" -eq 0 ] && [ "$fails" -eq 0 ]
