#!/usr/bin/env bash
# colour_codec.sh INDIR [NAME]: the goals of issue 37 for the auto colour
# method on one coloured voxelize output: at each of the paper's max
# errors (0.025, 0.038, 0.05, 0.1) auto beside VBR (Algorithm 1), the
# palette (lossless, 16K, 4K, 256 colours) against the cheapest auto
# setting of equal or lower GMSE, lossless auto against zstd -19 of the raw
# array; bytes, bits per voxel, GMSE, build M voxels per CPU second (one
# thread) and random lookups per CPU second (tests/bench/colour_lookup),
# and a verdict per goal. Not part of `make test`; tests/bench.sh runs it
# over the colour scenes.
set -eu
cd "$(dirname "$0")/../.."
IN=$1 NAME=${2:-$(basename "$1")}
BIN=${BIN:-out/bin}
LOOK=${LOOK:-out/bench/colour_lookup}
LOOKUPS=${LOOKUPS:-10000000}
W=$(mktemp -d "${TMPDIR:-/tmp}/colour-codec.XXXXXX")
trap '[ -z "${KEEP:-}" ] || { mkdir -p "$KEEP" && cp "$W"/*.json "$W"/*.look "$KEEP"/ 2>/dev/null; }; rm -rf "$W"' EXIT
run() { # run TAG METHOD ARGS...: one colorize, its statistics in $W/TAG.json
	local tag=$1 m=$2
	shift 2
	nice -n 5 "$BIN/colorize" -q "$IN" -o "$W/o-$tag" -j 1 --method "$m" \
		--stats "$W/$tag.json" "$@"
	if [ "$m" != raw ]; then
		"$LOOK" time "$W/o-$tag/colours.$m" "$LOOKUPS" > "$W/$tag.look"
	fi
	[ "${KEEP_FILES:-}" ] || rm -rf "$W/o-$tag"
}
for et in 0.025 0.038 0.05 0.1; do
	run "auto-$et" auto --max-error $et
	run "vbr-$et" vbr --max-error $et
done
# lower max errors: the points of auto's curve that the palette's GMSE
# is compared with
for et in 0.01 0.015 0.02; do run "auto-$et" auto --max-error $et; done
run auto-lossless auto --lossless
run pal-lossless palette --lossless
for k in 16384 4096 256; do run "pal-$k" palette --palette-colours $k; done
run raw raw
"$LOOK" dump "$IN" "$W/raw.rgb"
zstd -19 -T1 -q "$W/raw.rgb" -o "$W/raw.rgb.zst"
stat -c %s "$W/raw.rgb.zst" > "$W/zstd19.bytes"
rm -f "$W/raw.rgb"
python3 - "$W" "$NAME" <<'PY'
import json, os, sys
w, name = sys.argv[1], sys.argv[2]
def load(tag):
    s = json.load(open(os.path.join(w, tag + ".json")))
    m = next(iter(s["methods"].values()))
    look = os.path.join(w, tag + ".look")
    m["lookups"] = 0.0
    if os.path.exists(look):
        for line in open(look):
            k, v = line.split()
            if k == "lookups_per_second":
                m["lookups"] = float(v)
    return s, m
s, raw = load("raw")
N = s["voxels"]
z19 = int(open(os.path.join(w, "zstd19.bytes")).read())
print(f"### {name}: {N:,} voxels at 2^{s['levels']}, {s['cells']} cells, raw {3 * N:,} B, zstd -19 {z19:,} B\n")
print("| method | setting | bytes | bits/voxel | % of raw | GMSE | max error | build M vox/s/core | lookup M/s | goal |")
print("|---|---|---:|---:|---:|---:|---:|---:|---:|---|")
autos = {}
for tag in ["auto-lossless", "auto-0.01", "auto-0.015", "auto-0.02", "auto-0.025", "auto-0.038", "auto-0.05", "auto-0.1"]:
    autos[tag] = load(tag)[1]
def cheapest_auto(gmse):
    c = [(m["bytes"], t) for t, m in autos.items() if m["gmse"] <= gmse + 1e-9]
    return min(c) if c else None
def row(meth, setting, m, goal):
    b = m["bytes"]
    print(f"| {meth} | {setting} | {b:,} | {8 * b / N:.3f} | {100 * b / (3 * N):.2f}% | {m['gmse']:.2f} | "
          f"{m['max_error']:.4f} | {m['voxels_per_cpu_second'] / 1e6:.1f} | "
          f"{m['lookups'] / 1e6:.1f} | {goal} |")
ok = lambda c: "met" if c else "**MISSED**"
misses = 0
for et in ["0.025", "0.038", "0.05", "0.1"]:
    a, v = autos["auto-" + et], load("vbr-" + et)[1]
    good = a["bytes"] < v["bytes"]
    misses += not good
    speed = f"build {ok(a['voxels_per_cpu_second'] >= 50e6)}, lookup {ok(a['lookups'] >= 100e6)}"
    row("auto", f"max error {et}", a, f"{100 * a['bytes'] / v['bytes']:.0f}% of VBR: {ok(good)}; {speed}")
    row("VBR (Algorithm 1)", f"et {et}", v, "")
for et in ["0.01", "0.015", "0.02"]:
    row("auto", f"max error {et}", autos["auto-" + et], "")
a = autos["auto-lossless"]
good = a["bytes"] < z19
misses += not good
row("auto", "lossless", a, f"{100 * a['bytes'] / z19:.0f}% of zstd -19: {ok(good)}")
for tag, setting in [("pal-lossless", "lossless"), ("pal-16384", "16K colours"),
                     ("pal-4096", "4K colours"), ("pal-256", "256 colours")]:
    p = load(tag)[1]
    c = cheapest_auto(p["gmse"])
    good = c is not None and c[0] < p["bytes"]
    misses += not good
    row("palette (Dado)", setting, p,
        f"auto at GMSE <= {p['gmse']:.2f}: {c[1] if c else 'none'}, "
        f"{100 * c[0] / p['bytes']:.0f}% of its bytes: {ok(good)}" if c else "**MISSED**")
print(f"| zstd -19 | lossless | {z19:,} | {8 * z19 / N:.3f} | {100 * z19 / (3 * N):.2f}% | 0.00 | 0 | | | |")
row("raw zstd (colorize)", "level 9", raw, "")
print(f"\n{misses} size goals missed.")
PY
