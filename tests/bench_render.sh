#!/usr/bin/env bash
# Ray casting throughput per core of the four encodings of one scene:
#   tests/bench_render.sh [DIR/NAME] [REPEATS]   (default out/dragon/encode/dragon, 3)
# Build the scene first (make PIPELINE=config/dragon.yaml). One thread,
# 1280x720, the iso preset, primary + shadow rays; the best of REPEATS runs.
# "all" counts primary + shadow rays over the whole render (shading and
# depth normals included); the SSVDAG overhead is over SVDAG's time.
set -u
cd "$(dirname "$0")/.."
base=${1:-out/dragon/encode/dragon}
rep=${2:-3}
if [ ! -e "$base.ssvdag" ]; then
	echo "bench_render: $base.ssvdag is absent; build the scene first"
	exit 0
fi
mkdir -p out/bench
printf '%-8s %10s %10s %12s %12s %10s\n' format primary shadow 'prim Mray/s' 'all Mray/s' 'seconds'
for f in svdag ussvdag esvdag ssvdag; do
	best=
	for i in $(seq "$rep"); do
		line=$(out/bin/render "$base.$f" -o out/bench/render-$f.png --size 1280x720 \
			--camera iso -j 1 2>&1) || { echo "$line"; exit 1; }
		# "... in S s: P primary rays (SP s, ...), H shadow rays (SH s ..."
		s=$(echo "$line" | sed -E 's/.* in ([0-9.]+) s: .*/\1/')
		if [ -z "$best" ] || awk -v a="$s" -v b="$best" 'BEGIN{exit !(a<b)}'; then
			best=$s
			bl=$line
		fi
	done
	echo "$bl" | sed -E 's/.* in ([0-9.]+) s: ([0-9]+) primary rays \(([0-9.]+) s.*, ([0-9]+) shadow rays.*/\1 \2 \3 \4/' |
		awk -v f="$f" '{printf "%-8s %10d %10d %12.2f %12.2f %10.3f\n", f, $2, $4, $2/$3/1e6, ($2+$4)/$1/1e6, $1}'
done | tee out/bench/render.txt
awk '$1=="svdag"{s=$6} $1=="ssvdag"{q=$6} END{if (s>0) printf "SSVDAG time over SVDAG: %+.1f%%\n", 100*(q/s-1)}' out/bench/render.txt
