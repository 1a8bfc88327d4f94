#!/usr/bin/env bash
# render from the outside: usage errors and impossible cameras (exit 2),
# good runs on every encoding and on the root chunks (same pixels from
# all), and bad inputs (exit 1, one line each, no image left behind).
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh
R=$BIN/render
BUNNY=tests/data/bunny.ply

# --- usage errors: exit 2
expect usage_no_args 2 'needs one input' $R
expect usage_two_inputs 2 'more than one input' $R a.ssvdag b.ssvdag -o "$T/o.png"
expect usage_no_output 2 'no output image' $R a.ssvdag
expect usage_size_zero 2 "size '0x10'" $R a.ssvdag -o "$T/o.png" --size 0x10
expect usage_size_absurd 2 "size '100000x100000'" $R a.ssvdag -o "$T/o.png" --size 100000x100000
expect usage_size_too_many 2 "size '16384x16384'" $R a.ssvdag -o "$T/o.png" --size 16384x16384
expect usage_size_garbage 2 "size '12'" $R a.ssvdag -o "$T/o.png" --size 12
expect usage_fov_zero 2 "fov '0'" $R a.ssvdag -o "$T/o.png" --fov 0
expect usage_fov_180 2 "fov '180'" $R a.ssvdag -o "$T/o.png" --fov 180
expect usage_fov_nan 2 "fov 'nan'" $R a.ssvdag -o "$T/o.png" --fov nan
expect usage_eye_is_target 2 'same point' $R a.ssvdag -o "$T/o.png" --eye 1,2,3 --target 1,2,3
expect usage_eye_alone 2 'go together' $R a.ssvdag -o "$T/o.png" --eye 1,2,3
expect usage_eye_and_preset 2 'exclude' $R a.ssvdag -o "$T/o.png" --eye 1,2,3 --target 0,0,0 --camera iso
expect usage_eye_garbage 2 "eye '1,2'" $R a.ssvdag -o "$T/o.png" --eye 1,2 --target 0,0,0
expect usage_preset 2 "camera 'back'" $R a.ssvdag -o "$T/o.png" --camera back
expect usage_light 2 "light 'x'" $R a.ssvdag -o "$T/o.png" --light x
expect usage_lod 2 "lod '-1'" $R a.ssvdag -o "$T/o.png" --lod -1
expect usage_threads 2 "threads '0'" $R a.ssvdag -o "$T/o.png" -j 0
expect usage_depth_ext 2 "depth 'd.tiff'" $R a.ssvdag -o "$T/o.png" --depth d.tiff
expect usage_unknown_option 2 'Try' $R a.ssvdag -o "$T/o.png" --frobnicate
expect help 0 'usage: render' $R --help
help_lists_options help_matches_code render stages/render/main.c

# --- inputs: the bunny at 2^6, its chunks and its five encodings
M="$T/m"
$BIN/voxelize $BUNNY -o "$M" --levels 6 --chunk-level 0 -q &&
$BIN/svo-to-dag -q "$M/chunk-L0-0.svo" -o "$M/root.dag" &&
$BIN/symmetry-merge -q "$M/root.dag" -o "$M/root.ssvdag" &&
$BIN/symmetry-merge -q --group 48 "$M/root.dag" -o "$M/root.s48" &&
$BIN/encode -q "$M/root.dag" "$M/root.ssvdag" "$M/root.s48" -o "$M/enc" \
	--name bunny || fail inputs

# --- good runs: every encoding and both chunks give the same image
for f in "$M"/enc/bunny.svdag "$M"/enc/bunny.ussvdag "$M"/enc/bunny.esvdag \
	"$M"/enc/bunny.ssvdag "$M"/enc/bunny.ssvdag48 "$M"/root.dag "$M"/root.ssvdag; do
	n=$(basename "$f" | tr . _)
	expect "good_$n" 0 "render: 160x90 of the .* \(2\^6\)" \
		$R "$f" -o "$T/$n.png" --size 160x90 --camera iso -j 2 \
		--depth "$T/$n.pfm" --voxel-id "$T/$n.bin"
done
same=1
for n in bunny_ussvdag bunny_esvdag bunny_ssvdag bunny_ssvdag48 root_dag root_ssvdag; do
	cmp -s "$T/bunny_svdag.png" "$T/$n.png" || same=0
	cmp -s "$T/bunny_svdag.bin" "$T/$n.bin" || same=0
	cmp -s "$T/bunny_svdag.pfm" "$T/$n.pfm" || same=0
done
[ $same = 1 ] && pass same_image_every_source || fail same_image_every_source
size=$(stat -c %s "$T/bunny_svdag.bin" 2>/dev/null || echo 0)
[ "$size" = $((16 + 16 * 160 * 90)) ] && pass voxel_id_size || fail voxel_id_size "size $size"
expect good_eye 0 '' $R "$M/enc/bunny.ssvdag" -o "$T/eye.png" --size 33x17 \
	--eye 0.3,0.2,0.4 --target 0,0.1,0 --fov 60 --light 1,1,1 --no-shadows --lod 1 -q
# --camera-file: the camera and size of --eye/--target/--fov/--size, from
# the JSON file the browser viewer reads too (schemas/render-outputs.md)
echo '{"eye": [0.3, 0.2, 0.4], "target": [0, 0.1, 0], "up": [0, 1, 0], "fov": 60, "width": 33, "height": 17}' > "$T/cam.json"
$R "$M/enc/bunny.ssvdag" -o "$T/eye2.png" --size 33x17 --eye 0.3,0.2,0.4 \
	--target 0,0.1,0 --fov 60 -q --voxel-id "$T/eye2.bin"
expect camera_file 0 '' $R "$M/enc/bunny.ssvdag" -o "$T/camf.png" \
	--camera-file "$T/cam.json" -q --voxel-id "$T/camf.bin"
cmp -s "$T/eye2.png" "$T/camf.png" && cmp -s "$T/eye2.bin" "$T/camf.bin" &&
	pass camera_file_equals_eye || fail camera_file_equals_eye
expect camera_file_size_wins 0 '' $R "$M/enc/bunny.ssvdag" -o "$T/camf2.png" \
	--camera-file "$T/cam.json" -q --size 20x10 --voxel-id "$T/camf2.bin"
[ "$(stat -c %s "$T/camf2.bin")" = $((16 + 16 * 200)) ] && pass camera_file_size_flag ||
	fail camera_file_size_flag
expect camera_file_missing 1 "cannot read camera file '$T/nocam.json': No such file" \
	$R "$M/enc/bunny.ssvdag" -o "$T/bad.png" --camera-file "$T/nocam.json"
# NAME|JSON|the error's pattern: one line, exit 1 each
while IFS='|' read -r name json pattern; do
	echo "$json" > "$T/$name.json"
	expect "$name" 1 "cannot read camera file '$T/$name.json': $pattern" \
		$R "$M/enc/bunny.ssvdag" -o "$T/bad.png" --camera-file "$T/$name.json"
done <<'CASES'
camera_file_malformed|{"eye": [0, 0, 1], "target": [0, 0|line [0-9]+:
camera_file_no_eye|{"target": [0, 0, 0]}|no "eye"
camera_file_fov|{"eye": [0, 0, 1], "target": [0, 0, 0], "fov": 0}|field of view 0
camera_file_width|{"eye": [0, 0, 1], "target": [0, 0, 0], "width": 0}|"width" is not a number of pixels
camera_file_up|{"eye": [0, 0, 1], "target": [0, 0, 0], "up": [0, 0, 2]}|up vector is parallel
camera_file_not_object|[1, 2, 3]|not a JSON object
CASES
expect camera_file_and_preset 2 'excludes' \
	$R "$M/enc/bunny.ssvdag" -o "$T/bad.png" --camera-file "$T/cam.json" --camera iso
expect good_depth_png 0 '' $R "$M/enc/bunny.esvdag" -o "$T/d.png" --size 40x30 \
	--camera top --depth "$T/depth.png" -q
file "$T/depth.png" 2>/dev/null | grep -q '16-bit grayscale' && pass depth_png_16bit ||
	{ command -v file >/dev/null && fail depth_png_16bit "$(file "$T/depth.png")" || pass depth_png_16bit; }

# --- bad inputs: exit 1, one line, nothing written
expect missing_file 1 "cannot open '$T/none.ssvdag': No such file" \
	$R "$T/none.ssvdag" -o "$T/bad.png"
echo "hello" > "$T/scene.txt"
expect unknown_format 1 "cannot read '$T/scene.txt': unknown format" \
	$R "$T/scene.txt" -o "$T/bad.png"
# the decoders themselves (files without a manifest, as SymVox writes them)
for f in ssvdag esvdag svdag ssvdag48; do
	head -c 100 "$M/enc/bunny.$f" > "$T/cut.$f"
	expect "truncated_$f" 1 "cannot read '$T/cut.$f': truncated file" \
		$R "$T/cut.$f" -o "$T/bad.png" --no-verify
	cp "$M/enc/bunny.$f" "$T/long.$f" && echo x >> "$T/long.$f"
	expect "trailing_$f" 1 "cannot read '$T/long.$f': trailing bytes" \
		$R "$T/long.$f" -o "$T/bad.png" --no-verify
done
# encode's files are checked against the manifest beside them first: a
# flipped bit in a brick, a cut or a longer file never becomes a picture
cp -r "$M/enc" "$T/enc2"
expect manifest_intact 0 '' $R "$T/enc2/bunny.ssvdag" -o "$T/ok.png" --size 8x8 -q
size=$(stat -c %s "$T/enc2/bunny.ssvdag")
# the last word of an .ssvdag is in its leaf bricks
b=$(od -An -tu1 -j $((size - 1)) -N1 "$T/enc2/bunny.ssvdag" | tr -d ' ')
printf "$(printf '\\%03o' $((b ^ 1)))" |
	dd of="$T/enc2/bunny.ssvdag" bs=1 seek=$((size - 1)) conv=notrunc 2>/dev/null
expect manifest_bit_flip 1 "cannot read '$T/enc2/bunny.ssvdag': checksum mismatch: .*does not match its checksum" \
	$R "$T/enc2/bunny.ssvdag" -o "$T/bad.png"
truncate -s 100 "$T/enc2/bunny.esvdag"
expect manifest_cut 1 "bunny.esvdag' has 100 bytes, the manifest says" \
	$R "$T/enc2/bunny.esvdag" -o "$T/bad.png"
cp "$M/enc/bunny.svdag" "$T/lonely.svdag"
expect manifest_missing 1 "no manifest beside '$T/lonely.svdag'.*--no-verify" \
	$R "$T/lonely.svdag" -o "$T/bad.png"
expect manifest_missing_no_verify 0 '' $R "$T/lonely.svdag" -o "$T/ok2.png" --size 8x8 -q --no-verify
expect dag_verify_bit_flip 1 "checksum" \
	$BIN/dag-verify "$T/enc2/bunny.ssvdag" "$M/chunk-L0-0.svo"
expect dag_verify_intact 0 '' $BIN/dag-verify "$M/enc/bunny.ssvdag" "$M/chunk-L0-0.svo"
head -c 300 "$M/root.ssvdag" > "$T/cut_chunk.ssvdag"
expect truncated_chunk 1 "cannot read '$T/cut_chunk.ssvdag': truncated file" \
	$R "$T/cut_chunk.ssvdag" -o "$T/bad.png"
expect svo_chunk 1 "cannot read '$M/chunk-L0-0.svo': wrong chunk kind" \
	$R "$M/chunk-L0-0.svo" -o "$T/bad.png"
: > "$T/empty.esvdag"
expect empty_file 1 "cannot read '$T/empty.esvdag': truncated file" \
	$R "$T/empty.esvdag" -o "$T/bad.png" --no-verify
expect unwritable_output 1 "cannot write '$T/nodir/x.png'" \
	$R "$M/enc/bunny.ssvdag" -o "$T/nodir/x.png" --size 8x8
[ ! -e "$T/bad.png" ] && ! ls "$T" | grep -q '\.tmp\.' && pass nothing_left ||
	fail nothing_left "$(ls "$T")"
