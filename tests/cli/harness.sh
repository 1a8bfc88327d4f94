#!/usr/bin/env bash
# The test harness itself: a unit test program that crashes, trips a
# sanitizer, leaks, or ends early must be a FAIL in tests/run-unit.sh, and a
# clean one must pass. Each case builds a tiny program on tests/unit/check.h
# with the sanitizer flags of `make config=sanitize`.
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh

SAN="-fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=undefined"

# harness_case NAME WANT BODY: WANT is "pass" or a regex the FAIL line of
# run-unit.sh must match. BODY is the statement inside the second of two
# test functions (the first always passes).
harness_case() {
	local name=$1 want=$2 body=$3
	cat > "$T/$name.c" <<-C
	#include "check.h"
	#include <limits.h>
	static void test_first(void) { CHECK_EQ(1 + 1, 2); }
	static void test_second(void) { $body }
	int main(void)
	{
		RUN(test_first);
		RUN(test_second);
		return CHECK_DONE();
	}
	C
	if ! gcc -std=c11 -D_GNU_SOURCE -O1 -g $SAN -Itests/unit -w \
		-o "$T/$name" "$T/$name.c" 2>"$T/cc.err"; then
		fail "harness_$name" "cannot compile:" "$(head -c 600 "$T/cc.err")"
		return
	fi
	tests/run-unit.sh "$T/$name" >"$T/verdict" 2>/dev/null
	local rc=$?
	if [ "$want" = pass ]; then
		if [ $rc -eq 0 ] && [ "$(grep -c '^PASS' "$T/verdict")" -eq 2 ] &&
			! grep -q '^FAIL' "$T/verdict"; then
			pass "harness_$name"
		else
			fail "harness_$name" "a clean program was judged:" "$(cat "$T/verdict")"
		fi
	elif [ $rc -ne 0 ] && grep -Eq "^FAIL .*($want)" "$T/verdict"; then
		pass "harness_$name"
	else
		fail "harness_$name" "exit $rc, expected a FAIL matching /$want/:" \
			"$(cat "$T/verdict")"
	fi
}

harness_case clean pass 'CHECK(1);'
harness_case check_fails 'test_second' 'CHECK_EQ(2, 3);'
harness_case heap_overflow 'sanitizer report' \
	'volatile char *p = malloc(8); p[8] = 1; free((void *)p);'
harness_case leak 'sanitizer report' \
	'volatile char *p = malloc(64); p[0] = 1; p = 0;'
harness_case signed_overflow 'sanitizer report' \
	'volatile int x = INT_MAX; x = x + 1; CHECK(x != 0);'
harness_case null_write 'sanitizer report|signal' \
	'volatile int *p = 0; *p = 1;'
harness_case abort 'signal 6' 'abort();'
harness_case exit_zero_early 'ended early' 'exit(0);'
harness_case exit_one_early 'exited 1 without' 'exit(1);'
