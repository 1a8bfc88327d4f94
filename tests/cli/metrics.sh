#!/usr/bin/env bash
# render --compare (MSE, PSNR, SSIM, MS-SSIM of two images) against an
# independent numpy/scipy implementation (tests/ref/image_metrics.py) on
# renders of the bundled bunny; identical images; bad input.
set -u
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh

"$BIN/voxelize" tests/data/bunny.ply -o "$T/vox" --levels 8 --chunk-level 0 -q
"$BIN/svo-to-dag" "$T/vox/chunk-L0-0.svo" -o "$T/root.dag" -q
"$BIN/render" "$T/root.dag" -o "$T/a.png" -s 240x200 -q
"$BIN/render" "$T/root.dag" -o "$T/b.png" -s 240x200 -q -S -c iso
"$BIN/render" "$T/root.dag" -o "$T/c.png" -s 240x200 -q -L 3
"$BIN/render" "$T/root.dag" -o "$T/small.png" -s 100x60 -q

# close: every figure within 1e-5 relative of the reference
close() {
	/usr/bin/python3 - "$1" "$2" <<'PY'
import json, sys
a, b = json.loads(sys.argv[1]), json.loads(sys.argv[2])
ok = all(abs(a[k] - b[k]) <= 1e-5 * max(1.0, abs(b[k])) for k in b)
sys.exit(0 if ok and set(a) == set(b) else 1)
PY
}

if ! /usr/bin/python3 -c 'import numpy, scipy.ndimage' 2>/dev/null; then
	echo "SKIP metrics_vs_reference: /usr/bin/python3 has no numpy/scipy (make deps installs them)"
else
	for p in b c; do
		got=$("$BIN/render" --compare "$T/a.png" "$T/$p.png")
		want=$(/usr/bin/python3 tests/ref/image_metrics.py "$T/a.png" "$T/$p.png")
		if close "$got" "$want"; then
			pass "metrics_vs_reference_$p"
		else
			fail "metrics_vs_reference_$p" "render: $got" "reference: $want"
		fi
	done
fi
expect metrics_identical 0 '"mse": 0.000000, "psnr": null, "ssim": 1.000000, "ms_ssim": 1.000000' \
	"$BIN/render" --compare "$T/a.png" "$T/a.png"
expect metrics_small_no_msssim 0 '"ms_ssim": null' "$BIN/render" --compare "$T/small.png" "$T/small.png"
expect metrics_size_mismatch 1 'is 240x200' "$BIN/render" --compare "$T/a.png" "$T/small.png"
expect metrics_not_png 1 'not a PNG' "$BIN/render" --compare "$T/a.png" "$T/root.dag"
head -c 500 "$T/a.png" > "$T/cut.png"
expect metrics_truncated_png 1 'cut.png' "$BIN/render" --compare "$T/a.png" "$T/cut.png"
expect metrics_one_arg 2 'two images' "$BIN/render" --compare "$T/a.png"
help_lists_options render_help render stages/render/main.c
