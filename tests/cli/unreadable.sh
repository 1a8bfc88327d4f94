#!/usr/bin/env bash
# Unreadable inputs: a chunk directory and an encoding made unreadable (mode
# 000). Each reader (svo-to-dag, encode, dag-verify, render, the runner)
# must exit 1 with one line naming the file and "Permission denied", never
# a crash or a picture. Root ignores file modes, so as root the tools run
# as nobody (setpriv); otherwise as the user itself.
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh
if [ "$(id -u)" = 0 ]; then
	if ! setpriv --reuid=65534 --regid=65534 --clear-groups true 2>/dev/null; then
		echo "SKIP unreadable: root, and setpriv cannot switch to nobody"
		exit 0
	fi
	AS=(setpriv --reuid=65534 --regid=65534 --clear-groups)
else
	AS=()
fi
chmod 777 "$T" # nobody writes its outputs here
if ! "${AS[@]}" test -x "$BIN/encode" -a -r tests/data/bunny.ply; then
	echo "SKIP unreadable: the build or the test data is not readable by the test user"
	exit 0
fi
D=$T/d
mkdir -p "$D"
BUNNY=tests/data/bunny.ply
$BIN/voxelize -q $BUNNY -o "$D/cells" --levels 6 --chunk-level 1 &&
for c in "$D"/cells/*.svo; do $BIN/svo-to-dag -q "$c" -o "${c%.svo}.dag" || exit 1; done &&
$BIN/svo-to-dag -q --merge "$D"/cells/*.dag -o "$D/root.dag" &&
$BIN/symmetry-merge -q "$D/root.dag" -o "$D/root.sdag" &&
$BIN/encode -q "$D/root.dag" "$D/root.sdag" -o "$D/enc" --name s ||
	{ fail inputs; exit 1; }
chmod -R a+rwX "$D"
run() { "${AS[@]}" "$@"; }
DENIED='Permission denied'

# --- a chunk directory made unreadable (and untraversable)
chmod 000 "$D/cells"
cell=$D/cells/chunk-L1-0.dag
expect svo-to-dag-chunk-dir 1 "^svo-to-dag: cannot read '$cell': .*$DENIED" \
	run $BIN/svo-to-dag -q --merge "$D"/cells/chunk-L1-0.dag -o "$T/m.dag"
expect dag-verify-chunk-dir 1 "^dag-verify: .*'$D/cells/chunk-L1-0.svo'.*$DENIED" \
	run $BIN/dag-verify "$D/root.dag" "$D/cells/chunk-L1-0.svo"
expect vdb-export-chunk-dir 1 "^vdb-export: .*'$D/cells'.*$DENIED" \
	run $BIN/vdb-export -o "$T/x.vdb" "$D/cells"
[ ! -e "$T/m.dag" ] && [ -z "$(ls "$T" | grep -E 'tmp|\.vdb')" ] &&
	pass chunk-dir-nothing-written || fail chunk-dir-nothing-written "$(ls "$T")"
chmod 755 "$D/cells"

# --- a root chunk made unreadable
chmod 000 "$D/root.dag"
expect encode-root 1 "^encode: cannot read '$D/root.dag': .*$DENIED" \
	run $BIN/encode -q "$D/root.dag" "$D/root.sdag" -o "$T/enc" --name s
[ ! -e "$T/enc" ] && pass encode-root-nothing-written || fail encode-root-nothing-written "$(ls "$T")"
expect render-root 1 "^render: .*'$D/root.dag'.*$DENIED" \
	run $BIN/render -q "$D/root.dag" -o "$T/r.png" --size 32x32
chmod 644 "$D/root.dag"

# --- an encoding made unreadable, then its directory
chmod 000 "$D/enc/s.ssvdag"
expect render-encoding 1 "^render: .*'$D/enc/s.ssvdag'.*$DENIED" \
	run $BIN/render -q "$D/enc/s.ssvdag" -o "$T/r.png" --size 32x32
expect dag-verify-encoding 1 "^dag-verify: .*'$D/enc/s.ssvdag'.*$DENIED" \
	run $BIN/dag-verify "$D/enc/s.ssvdag" "$D"/cells/*.svo
chmod 644 "$D/enc/s.ssvdag"
chmod 000 "$D/enc"
expect render-encoding-dir 1 "^render: .*'$D/enc/.*$DENIED" \
	run $BIN/render -q "$D/enc/s.ssvdag" -o "$T/r.png" --size 32x32
expect dag-verify-encoding-dir 1 "^dag-verify: .*'$D/enc/.*$DENIED" \
	run $BIN/dag-verify "$D/enc/s.ssvdag" "$D"/cells/*.svo
chmod 755 "$D/enc"
[ ! -e "$T/r.png" ] && pass render-no-picture || fail render-no-picture "$(ls "$T")"

# --- the runner: after a complete run, voxelize's chunk directory and then
# encode's directory made unreadable
P=$T/pipe
cat > "$T/p.yaml" <<YAML
version: 1
name: unreadable
input:
  mesh: $BUNNY
levels: 6
chunk_level: 1
resources: {jobs: 2, mem_budget: 2GiB, job_mem_budget: 512M}
outputs: $P
jobs:
  vox:    {stage: voxelize}
  dag:    {stage: svo-to-dag, needs: [vox]}
  ssvdag: {stage: symmetry-merge, needs: [dag]}
  enc:    {stage: encode, needs: [dag, ssvdag]}
  pic:    {stage: render, needs: [enc]}
YAML
chmod 644 "$T/p.yaml"
# runner_denied NAME DIR: DIR made unreadable, the rerun fails in one line
# naming it; readable again, the rerun succeeds
runner_denied() {
	local name=$1 dir=$2
	chmod 000 "$dir"
	run $BIN/voxdag -q run "$T/p.yaml" >"$T/out" 2>"$T/err"
	local rc=$?
	chmod 755 "$dir"
	[ -n "${VOXDAG_SHOW:-}" ] && cat "$T/err" >&2
	if [ $rc -ne 1 ] || [ "$(grep -c "$DENIED" "$T/err")" -ne 1 ] ||
	   ! grep -q "'$dir" "$T/err"; then
		fail "$name" "exit $rc; expected 1 and one line naming '$dir':" "$(head -c 1500 "$T/err")"
	else
		pass "$name"
	fi
	expect "$name-then-readable" 0 '' run $BIN/voxdag -q run "$T/p.yaml"
}
# The runner starts its stages by absolute path (its own directory), which
# nobody must be able to reach: a clone in a directory of mode 700 (mktemp
# -d) is not, and every job would fail to start (exit 127).
case $BIN in /*) ABS_BIN=$BIN ;; *) ABS_BIN=$(pwd)/$BIN ;; esac
if [ "$(id -u)" = 0 ] && ! run test -x "$ABS_BIN/voxelize"; then
	echo "SKIP runner-*: nobody cannot reach $ABS_BIN (a parent directory is not searchable by others)"
else
	expect runner-setup 0 '' run $BIN/voxdag -q run "$T/p.yaml"
	runner_denied runner-chunk-dir "$P/vox"
	runner_denied runner-encoding-dir "$P/enc"
fi

# --- an output directory that cannot be read is not replaced blind
chmod 000 "$D/enc"
expect encode-over-unreadable-output 1 "^encode: cannot create '$D/enc'.*cannot read '$D/enc': $DENIED|^encode: .*'$D/enc'.*$DENIED" \
	run $BIN/encode -q "$D/root.dag" "$D/root.sdag" -o "$D/enc" --name s
chmod 755 "$D/enc"
[ -z "$(ls "$D" | grep tmp)" ] && [ -e "$D/enc/s.ssvdag" ] &&
	pass unreadable-output-kept || fail unreadable-output-kept "$(ls "$D" "$D/enc")"
