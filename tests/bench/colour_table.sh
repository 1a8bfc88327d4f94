#!/usr/bin/env bash
# colour_table.sh INDIR [NAME]: colorize a voxelize output directory that
# has colour chunks at the colour paper's settings and print its Table 3
# (method, setting, % of raw, GMSE) plus blocks, seconds and voxels/s per
# core. VBR: et 0.025, 0.038, 0.05, 0.1 (W = 3); palette (Dado et al.):
# lossless, 16K, 4K, 2K, 256 colours; raw zstd. One thread, so the rates are
# per core. Not part of `make test`.
set -eu
cd "$(dirname "$0")/../.."
IN=$1 NAME=${2:-$(basename "$1")}
BIN=${BIN:-out/bin}
W=$(mktemp -d "${TMPDIR:-/tmp}/colour-table.XXXXXX")
# KEEP=DIR keeps every run's statistics JSON there (for scripts that
# collect tables over several scenes).
trap '[ -z "${KEEP:-}" ] || { mkdir -p "$KEEP" && cp "$W"/*.json "$KEEP"/; }; rm -rf "$W"' EXIT
run() { # run TAG ARGS...: one colorize, its statistics in $W/TAG.json
	local tag=$1
	shift
	nice -n 10 "$BIN/colorize" -q "$IN" -o "$W/o-$tag" -j 1 --stats "$W/$tag.json" "$@"
}
for et in 0.025 0.038 0.05 0.1; do run "vbr-$et" --method vbr --max-error $et; done
run pal-lossless --method palette --lossless
for k in 16384 4096 2048 256; do run "pal-$k" --method palette --palette-colours $k; done
run raw --method raw
python3 - "$W" "$NAME" <<'PY'
import json, sys, os
w, name = sys.argv[1], sys.argv[2]
def load(tag):
    s = json.load(open(os.path.join(w, tag + ".json")))
    return s, next(iter(s["methods"].values()))
s, _ = load("raw")
print(f"### {name}: {s['voxels']:,} voxels at 2^{s['levels']}, {s['cells']} cells, raw {s['bytes_raw']:,} B\n")
print("| method | setting | % of raw | GMSE | max error | blocks | CPU s | Mvoxels/s per core |")
print("|---|---|---:|---:|---:|---:|---:|---:|")
rows = [("Ours (VBR)", f"et: {et}", f"vbr-{et}") for et in ("0.025", "0.038", "0.05", "0.1")]
rows += [("Dado (palette)", "lossless", "pal-lossless")]
rows += [("Dado (palette)", f"colors: {k}", f"pal-{n}") for k, n in (("16K", 16384), ("4K", 4096), ("2K", 2048), ("256", 256))]
rows += [("raw zstd", "level 9", "raw")]
for meth, setting, tag in rows:
    s, m = load(tag)
    print(f"| {meth} | {setting} | {m['percent_of_raw']:.1f}% | {m['gmse']:.2f} | {m['max_error']:.4f} | "
          f"{m['blocks']:,} | {m['cpu_seconds']:.2f} | {m['voxels_per_cpu_second'] / 1e6:.2f} |")
PY
