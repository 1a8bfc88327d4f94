#!/usr/bin/env bash
# The libFuzzer targets (tests/fuzz/, built by `make fuzz-build` into
# out/fuzz/) run a few seconds each on their seed corpus: a crash, a
# sanitizer report, a leak or a hang (-timeout) is a FAIL. `make fuzz`
# runs them for long.
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh
F=${FUZZ_BIN:-out/fuzz}
S=${FUZZ_TEST_SECONDS:-5}
for src in tests/fuzz/fuzz_*.c; do
	n=$(basename "$src" .c)
	if [ ! -x "$F/$n" ]; then
		if command -v clang >/dev/null; then
			fail "$n" "$F/$n is missing: run make fuzz-build"
		else
			echo "SKIP $n (no clang)"
		fi
		continue
	fi
	mkdir -p "$T/$n" "$T/crash-$n"
	if "$F/$n" -max_total_time="$S" -timeout=10 -rss_limit_mb=2048 \
		-artifact_prefix="$T/crash-$n/" "$T/$n" \
		"tests/fuzz/corpus/${n#fuzz_}" >"$T/$n.log" 2>&1; then
		pass "$n"
	else
		fail "$n" "$(grep -E 'ERROR|SUMMARY|Test unit written' "$T/$n.log" | head -5)"
	fi
done
