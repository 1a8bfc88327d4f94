#!/usr/bin/env bash
# render --colours on the bundled textured spider: voxelize's colour chunks
# and colorize's lossless files give byte-identical pictures through the DAG
# and an encoding; lossy files stay close (MS-SSIM); colours of another
# scene, a damaged packed file and a stray file are refused with one line.
set -u
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh

M=tests/data/spider/spider.obj
"$BIN/voxelize" $M -o "$T/vox" --levels 8 -q
"$BIN/svo-to-dag" "$T/vox/chunk-L0-0.svo" -o "$T/root.dag" -q
"$BIN/symmetry-merge" "$T/root.dag" -o "$T/root.ssvdag" -q
"$BIN/encode" "$T/root.dag" "$T/root.ssvdag" -o "$T/enc" -q
"$BIN/colorize" "$T/vox" -o "$T/pack" --method vbr,palette,raw -q
"$BIN/colorize" "$T/vox" -o "$T/lossless" --method palette --lossless -q
"$BIN/colorize" "$T/vox" -o "$T/auto" --method auto --lossless -q
"$BIN/colorize" "$T/vox" -o "$T/auto05" --method auto --max-error 0.05 -q
pic() { # pic NAME SCENE COLOURS
	"$BIN/render" "$2" -o "$T/$1.png" -s 200x180 -c iso -q -C "$3"
}
pic dir "$T/root.dag" "$T/vox"
pic raw "$T/root.ssvdag" "$T/pack/colours.raw"
pic lossless "$T/enc/$(ls "$T/enc" | grep '\.ssvdag$')" "$T/lossless/colours.palette"
pic vbr "$T/root.dag" "$T/pack/colours.vbr"
pic auto "$T/enc/$(ls "$T/enc" | grep '\.ssvdag$')" "$T/auto/colours.auto"
pic auto05 "$T/root.dag" "$T/auto05/colours.auto"
"$BIN/render" "$T/root.dag" -o "$T/grey.png" -s 200x180 -c iso -q
cmp -s "$T/dir.png" "$T/raw.png" && pass colour_render_raw_equals_chunks ||
	fail colour_render_raw_equals_chunks
cmp -s "$T/dir.png" "$T/lossless.png" && pass colour_render_lossless_encoding ||
	fail colour_render_lossless_encoding
cmp -s "$T/dir.png" "$T/grey.png" && fail colour_render_is_coloured ||
	pass colour_render_is_coloured
# lossless auto colours looked up through the encoding's voxel counts:
# the same picture as the colour chunks in the SVO's order
cmp -s "$T/dir.png" "$T/auto.png" && pass colour_render_auto_lossless ||
	fail colour_render_auto_lossless
ms=$("$BIN/render" --compare "$T/dir.png" "$T/auto05.png" | sed 's/.*"ms_ssim": \([0-9.]*\).*/\1/')
awk -v m="$ms" 'BEGIN { exit !(m > 0.99) }' && pass colour_render_auto_close ||
	fail colour_render_auto_close "ms_ssim $ms"
ms=$("$BIN/render" --compare "$T/dir.png" "$T/vbr.png" | sed 's/.*"ms_ssim": \([0-9.]*\).*/\1/')
awk -v m="$ms" 'BEGIN { exit !(m > 0.99) }' && pass colour_render_vbr_close ||
	fail colour_render_vbr_close "ms_ssim $ms"

# refusals: another scene's colours, a damaged file, a file without manifest
"$BIN/voxelize" tests/data/textured/scene.obj -o "$T/other" --levels 8 -q
expect colour_render_other_scene 1 'colours for a scene of' \
	"$BIN/render" "$T/root.dag" -o "$T/x.png" -s 20x20 -q -C "$T/other"
"$BIN/voxelize" $M -o "$T/vox7" --levels 7 -q
expect colour_render_other_depth 1 'colours made at depth 7' \
	"$BIN/render" "$T/root.dag" -o "$T/x.png" -s 20x20 -q -C "$T/vox7"
cp "$T/pack/colours.vbr" "$T/stray.vbr"
expect colour_render_no_manifest 1 'stray.vbr' \
	"$BIN/render" "$T/root.dag" -o "$T/x.png" -s 20x20 -q -C "$T/stray.vbr"
printf '\x55' | dd of="$T/pack/colours.vbr" bs=1 seek=200 conv=notrunc status=none
expect colour_render_damaged 1 'colours.vbr' \
	"$BIN/render" "$T/root.dag" -o "$T/x.png" -s 20x20 -q -C "$T/pack/colours.vbr"
printf '\x55' | dd of="$T/auto/colours.auto" bs=1 seek=300 conv=notrunc status=none
expect colour_render_damaged_auto 1 'colours.auto' \
	"$BIN/render" "$T/root.dag" -o "$T/x.png" -s 20x20 -q -C "$T/auto/colours.auto"
"$BIN/colorize" "$T/other" -o "$T/other_auto" --method auto -q
expect colour_render_other_scene_auto 1 'colours for a scene of' \
	"$BIN/render" "$T/root.dag" -o "$T/x.png" -s 20x20 -q -C "$T/other_auto/colours.auto"
[ ! -e "$T/x.png" ] && pass colour_render_no_picture_on_error ||
	fail colour_render_no_picture_on_error
