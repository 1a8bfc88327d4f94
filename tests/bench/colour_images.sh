#!/usr/bin/env bash
# colour_images.sh INDIR [NAME]: the image columns of the colour paper's
# Table 3 (image MSE and MS-SSIM) for a coloured voxelize output of one
# cell (--chunk-level 0): renders the scene with its exact colours and
# with each compressed setting (VBR et 0.025/0.038/0.05/0.1, palette
# 16K/4K/2K/256 colours) from the iso and side cameras (WxH from SIZE,
# default 640x480) and prints the mean over the views of render --compare's
# MSE and MS-SSIM. The paper renders with its own viewpoints; ours are the
# presets. Not part of `make test`.
set -eu
cd "$(dirname "$0")/../.."
IN=$1 NAME=${2:-$(basename "$1")}
BIN=${BIN:-out/bin}
SIZE=${SIZE:-640x480}
VIEWS=${VIEWS:-iso side}
W=$(mktemp -d "${TMPDIR:-/tmp}/colour-images.XXXXXX")
trap '[ -z "${KEEP:-}" ] || { mkdir -p "$KEEP" && cp "$W"/*.png "$KEEP"/; }; rm -rf "$W"' EXIT
svo=$(ls "$IN"/*.svo)
[ "$(echo "$svo" | wc -l)" = 1 ] || {
	echo "colour_images: '$IN' has more than one cell; voxelize with --chunk-level 0" >&2
	exit 1
}
nice -n 10 "$BIN/svo-to-dag" "$svo" -o "$W/scene.dag" -j 1 -q
img() { # img TAG SRC
	for v in $VIEWS; do
		nice -n 10 "$BIN/render" "$W/scene.dag" -o "$W/$1-$v.png" -s "$SIZE" \
			-c "$v" -j 1 -q -C "$2"
	done
}
cmp_all() { # cmp_all TAG: "mse ms_ssim" averaged over the views
	for v in $VIEWS; do
		"$BIN/render" --compare "$W/ref-$v.png" "$W/$1-$v.png"
	done | python3 -c '
import json, sys
r = [json.loads(l) for l in sys.stdin if l.strip()]
print("%.2f %.4f" % (sum(x["mse"] for x in r) / len(r), sum(x["ms_ssim"] for x in r) / len(r)))'
}
img ref "$IN"
echo "### $NAME: image MSE and MS-SSIM (views: $VIEWS, $SIZE)"
echo
echo "| method | setting | % of raw | GMSE | image MSE | MS-SSIM |"
echo "|---|---|---:|---:|---:|---:|"
set -- 0.025:16384:16K 0.038:4096:4K 0.05:2048:2K 0.1:256:256
rows=
for s in "$@"; do
	et=${s%%:*} k=${s#*:} k=${k%%:*} kn=${s##*:}
	nice -n 10 "$BIN/colorize" -q "$IN" -o "$W/c" -j 1 --method vbr,palette \
		--max-error "$et" --palette-colours "$k" --stats "$W/s.json"
	img vbr "$W/c/colours.vbr"
	img pal "$W/c/colours.palette"
	read -r vp vg pp pg < <(python3 -c 'import json, sys
m = json.load(open(sys.argv[1]))["methods"]
print("%.1f%% %.2f %.1f%% %.2f" % (m["vbr"]["percent_of_raw"], m["vbr"]["gmse"], m["palette"]["percent_of_raw"], m["palette"]["gmse"]))' "$W/s.json")
	echo "| Ours (VBR) | et: $et | $vp | $vg | $(cmp_all vbr | sed 's/ / | /') |"
	rows="$rows| Dado (palette) | colors: $kn | $pp | $pg | $(cmp_all pal | sed 's/ / | /') |
"
done
printf '%s' "$rows"
