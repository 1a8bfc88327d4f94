#!/usr/bin/env bash
# Does a change leave every output byte as it was? Runs the same pipelines
# with two builds and compares the sha256 of everything they write, but the
# statistics (seconds, peak memory): *.json, logs, reports, the tables and
# the lock; a manifest is compared without its lines for those files.
#
#   tests/bench/same_outputs.sh OLD_BIN NEW_BIN
#
# OLD_BIN and NEW_BIN are out/bin directories of two builds (for example a
# worktree of the commit before: `git worktree add /tmp/old HEAD~1 && make
# -C /tmp/old -j2`, then /tmp/old/out/bin). The pipelines: the bundled
# bunny (config/default.yaml) and textured spider (config/spider-colours.
# yaml, every colour method), and when ../shared/data is there the dragon
# at 2^12 through every stage (voxelize, svo-to-dag, symmetry-merge with 8
# and 48 symmetries, lossy-cluster, edit, encode, render) and the cruiser
# at 2^11 with colours (colorize raw, vbr, palette; edit with paint).
# Both builds write to the same paths (chunk files record their command
# line), one after the other. Prints one line per pipeline and exits 1 on
# any difference, listing the files. Not part of make test: minutes.
set -u
cd "$(dirname "$0")/../.."
die() { echo "same_outputs: $*" >&2; exit 2; }
[ $# -eq 2 ] || die "usage: tests/bench/same_outputs.sh OLD_BIN NEW_BIN"
old=$(cd "$1" && pwd) || die "no directory '$1'"
new=$(cd "$2" && pwd) || die "no directory '$2'"
for b in "$old" "$new"; do
	[ -x "$b/voxdag" ] || die "'$b' has no voxdag: not an out/bin"
done
data=${VOXDAG_SHARED_DATA:-../shared/data}
work=$(mktemp -d "${TMPDIR:-/tmp}/same_outputs.XXXXXX")
trap 'rm -rf "$work"' EXIT

# The pipelines, written with absolute paths so that they run from $work.
cp config/default.yaml config/spider-colours.yaml "$work/"
sed -i "s|tests/data/|$PWD/tests/data/|" "$work/default.yaml" \
	"$work/spider-colours.yaml"
pipelines="default spider-colours"
if [ -f "$data/stanford_dragon.ply" ] && [ -f "$data/cg57_cruiser.ply" ]; then
	data=$(cd "$data" && pwd)
	cat > "$work/dragon12.yaml" <<EOF
version: 1
name: dragon12
input:
  mesh: $data/stanford_dragon.ply
levels: 12
chunk_level: 3
resolutions: [12, 11, 10]
resources: {jobs: 2, mem_budget: 6GiB, job_mem_budget: 3GiB}
jobs:
  voxelize: {stage: voxelize}
  svdag:    {stage: svo-to-dag, needs: [voxelize]}
  ssvdag:   {stage: symmetry-merge, needs: [svdag]}
  s48:      {stage: symmetry-merge, needs: [svdag], group: 48}
  encode:   {stage: encode, needs: [svdag, ssvdag]}
  picture:  {stage: render, needs: [encode]}
  lsvdag:   {stage: lossy-cluster, needs: [svdag]}
  lssvdag:  {stage: symmetry-merge, needs: [lsvdag]}
  lencode:  {stage: encode, needs: [lsvdag, lssvdag]}
  lpicture: {stage: render, needs: [lencode, encode]}
  edited:   {stage: edit, needs: [svdag], script: ["fill box 0 0 0 900 900 900", "carve sphere 2048 2048 2048 700"]}
  essvdag:  {stage: symmetry-merge, needs: [edited]}
  eencode:  {stage: encode, needs: [edited, essvdag]}
EOF
	cat > "$work/cruiser11.yaml" <<EOF
version: 1
name: cruiser11
input:
  mesh: $data/cg57_cruiser.ply
levels: 11
chunk_level: 2
resolutions: [11, 10]
resources: {jobs: 2, mem_budget: 6GiB, job_mem_budget: 3GiB}
jobs:
  voxelize: {stage: voxelize}
  svdag:    {stage: svo-to-dag, needs: [voxelize]}
  ssvdag:   {stage: symmetry-merge, needs: [svdag]}
  encode:   {stage: encode, needs: [svdag, ssvdag]}
  raw:      {stage: colorize, needs: [voxelize], method: raw}
  vbr:      {stage: colorize, needs: [voxelize], method: vbr, max_error: 0.025}
  pal:      {stage: colorize, needs: [voxelize], method: palette, palette_colours: 256}
  picture:  {stage: render, needs: [encode, vbr]}
  edited:   {stage: edit, needs: [svdag, voxelize], script: ["fill box 0 0 0 300 300 300", "paint sphere 1000 1000 1000 300 colour 255 0 0"]}
  ecol:     {stage: colorize, needs: [edited], method: vbr}
  essvdag:  {stage: symmetry-merge, needs: [edited]}
  eencode:  {stage: encode, needs: [edited, essvdag]}
  epic:     {stage: render, needs: [eencode, ecol]}
EOF
	pipelines="$pipelines dragon12 cruiser11"
else
	echo "same_outputs: no $data/stanford_dragon.ply and cg57_cruiser.ply: the bundled scenes only"
fi

# sums BIN NAME: runs pipeline NAME with BIN into $work/out/NAME and prints
# the sums of what it wrote.
sums() {
	local bin=$1 name=$2 d
	rm -rf "$work/out"
	mkdir -p "$work/out"
	(cd "$work" && "$bin/voxdag" run "$work/$name.yaml" \
		> "$work/$name.log" 2>&1) ||
		{ tail -n 5 "$work/$name.log" >&2; die "$bin/voxdag run $name failed"; }
	d=$work/out/$name
	(cd "$d" && find . -type f ! -name '*.json' ! -name '*.log' \
		! -name 'report.*' ! -name keys ! -name .lock ! -path '*/logs/*' \
		! -name '*tables.md' ! -name '*.csv' ! -name manifest \
		-print0 | sort -z | xargs -0 sha256sum)
	(cd "$d" && find . -name manifest | sort | while read -r m; do
		printf '%s  %s (without statistics)\n' "$(grep -Ev \
			'\.json$|tables\.md$|\.csv$' "$m" | sha256sum | cut -d' ' -f1)" "$m"
	done)
}

bad=0
for p in $pipelines; do
	sums "$old" "$p" > "$work/$p.old"
	sums "$new" "$p" > "$work/$p.new"
	n=$(wc -l < "$work/$p.new")
	if cmp -s "$work/$p.old" "$work/$p.new"; then
		echo "same: $p ($n files, sha256 of the list $(sha256sum < "$work/$p.new" | cut -c1-16))"
	else
		echo "DIFFERENT: $p"
		diff "$work/$p.old" "$work/$p.new" | sed -n 's/^> [0-9a-f]*  /  /p'
		bad=1
	fi
done
exit $bad
