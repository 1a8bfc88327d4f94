# lib.sh - helpers for command-line tests, sourced by tests/cli/*.sh.
# Each case prints one "PASS name" or "FAIL name" line; details go to stderr.

BIN=${BIN:-out/bin}
T=$(mktemp -d "${TMPDIR:-/tmp}/voxdag-cli.XXXXXX")
trap 'rm -rf "$T"' EXIT

pass() { echo "PASS $1"; }
fail() { echo "FAIL $1"; shift; printf '  %s\n' "$@" >&2; }

# expect NAME CODE PATTERN CMD...: runs CMD; passes when the exit code is
# CODE and stderr (or stdout for code 0 with a pattern) matches the
# extended regular expression PATTERN ('' matches anything). A failing
# command must print exactly one line on stderr.
expect() {
	local name=$1 code=$2 pattern=$3
	shift 3
	"$@" >"$T/out" 2>"$T/err"
	local rc=$?
	if [ "$rc" -ne "$code" ]; then
		fail "$name" "exit $rc, expected $code: $*" "$(head -c 600 "$T/err")"
		return
	fi
	if [ -n "$pattern" ] && ! grep -Eq -- "$pattern" "$T/err" "$T/out"; then
		fail "$name" "output does not match /$pattern/: $*" "$(head -c 600 "$T/err")"
		return
	fi
	if [ "$code" -eq 1 ] && [ "$(grep -vc '^Try ' "$T/err")" -ne 1 ]; then
		fail "$name" "expected one error line, got:" "$(head -c 600 "$T/err")"
		return
	fi
	pass "$name"
}

# No file in DIR that looks like a finished chunk, nor a temporary.
expect_no_chunks() {
	local name=$1 dir=$2
	if ls "$dir" 2>/dev/null | grep -Eq '\.(svo|dag|ssvdag|col)$|\.tmp\.|stats\.json'; then
		fail "$name" "files left in $dir:" "$(ls "$dir")"
	else
		pass "$name"
	fi
}

# help_lists_options NAME TOOL SOURCE: every long option in the source's
# option table is documented in --help, and --help lists no other.
help_lists_options() {
	local name=$1 tool=$2 src=$3
	local code help
	code=$(grep -oE '^\s*\{"[a-z-]+", (no|required|optional)_argument' "$src" |
		grep -oE '"[a-z-]+"' | tr -d '"' | sort -u)
	help=$("$BIN/$tool" --help | grep -oE -- '--[a-z][a-z-]+' | sed 's/^--//' | sort -u)
	if [ "$code" = "$help" ] && [ -n "$code" ]; then
		pass "$name"
	else
		fail "$name" "options in code: $(echo $code)" "options in --help: $(echo $help)"
	fi
}

. "$(dirname "${BASH_SOURCE[0]}")/../lossless_yaml.sh"

# small_pipeline NAME MESH: a pipeline at 2^8, cells of level 1, with the
# voxelize job `vox` and the DAG job `dag`, then the jobs given on stdin.
small_pipeline() {
	cat <<EOF
version: 1
name: $1
input: {mesh: $2}
levels: 8
chunk_level: 1
resources: {jobs: 2, mem_budget: 2GiB, job_mem_budget: 512M}
jobs:
  vox:    {stage: voxelize}
  dag:    {stage: svo-to-dag, needs: [vox]}
EOF
	cat
}

# bunny_pipeline NAME LEVELS CHUNK_LEVEL: the lossless pipeline on the
# bundled bunny, two 1-thread jobs at a time: the runner tests' common case.
bunny_pipeline() {
	lossless_yaml "$1" tests/data/bunny.ply "$2" "$3" \
		"{jobs: 2, threads: 1, mem_budget: 2GiB, job_mem_budget: 512M}"
}

# chunk_sans_prov FILE: the bytes of a chunk without its PROV section and
# its footer (whose checksums cover the provenance, which names the input
# and the arguments): header, then every other section. Two runs that must
# write the same voxels compare equal through it (schemas/chunk-format.md).
chunk_sans_prov() {
	local f=$1 size hs off tag sz
	size=$(stat -c %s "$f")
	hs=$(od -An -tu4 -j12 -N4 "$f" | tr -d ' ')
	head -c "$hs" "$f"
	off=$hs
	while [ "$off" -lt $((size - 24)) ]; do
		tag=$(dd if="$f" bs=1 skip="$off" count=4 2>/dev/null)
		sz=$(od -An -tu8 -j$((off + 16)) -N8 "$f" | tr -d ' ')
		[ "$tag" = PROV ] || tail -c +$((off + 1)) "$f" | head -c $((32 + sz))
		off=$((off + 32 + sz))
	done
}

# one_warning NAME PATTERN CMD...: CMD succeeds and says exactly one line on
# stderr, which matches PATTERN (kept in $T/warn).
one_warning() {
	local name=$1 pat=$2 rc
	shift 2
	"$@" 2>"$T/warn"
	rc=$?
	if [ $rc -eq 0 ] && [ "$(wc -l < "$T/warn")" -eq 1 ] && grep -q "$pat" "$T/warn"; then
		pass "$name"
	else
		fail "$name" "exit $rc" "$(cat "$T/warn")"
	fi
}

# bad_voxelize NAME PATTERN FILE [ARGS...]: voxelize refuses FILE with exit
# 1 and one line matching PATTERN, and leaves nothing in its OUTDIR.
bad_voxelize() {
	local name=$1 pattern=$2
	shift 2
	rm -rf "$T/bad"
	expect "$name" 1 "$pattern" $BIN/voxelize "$@" -o "$T/bad" -q
	expect_no_chunks "${name}_leaves_nothing" "$T/bad"
}

# kill_runner_after N CONFIG DIR: runs the pipeline, SIGKILLs the runner
# once DIR/logs/runner.log has N "done" lines (or it ended), and prints
# the ids of the jobs it finished, sorted.
kill_runner_after() {
	local n=$1 cfg=$2 dir=$3 pid
	$BIN/voxdag -q run "$cfg" >/dev/null &
	pid=$!
	while kill -0 $pid 2>/dev/null &&
	      [ "$(cat "$dir/logs/runner.log" 2>/dev/null | grep -c ' done ')" -lt "$n" ]; do
		sleep 0.005
	done
	kill -9 $pid 2>/dev/null
	wait $pid 2>/dev/null
	grep -s ' done ' "$dir/logs/runner.log" | sed 's/.* done \([^ ]*\) .*/\1/' | sort
}
