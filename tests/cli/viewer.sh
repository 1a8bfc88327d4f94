#!/usr/bin/env bash
# voxdag view and the browser viewer: the server serves only what is under
# the output directory and the page's own files (no '..', encoded or not,
# no hidden files, no directories), honours ranges, refuses a damaged
# encoding; headless Debian chromium on the page reads back the id and
# depth buffers for three cameras and they equal render's (but for at
# most 0.05% of the hit pixels, rays grazing voxel edges in float).
set -u
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh

# ---- the server (needs only curl)
{ bunny_pipeline vbunny 8 1; echo "outputs: $T/scene"; } > "$T/bunny.yaml"
"$BIN/voxdag" run "$T/bunny.yaml" -q || { fail viewer_pipeline "voxdag run failed"; exit 1; }

grep -q "voxdag view $T/bunny.yaml" "$T/scene/report.md" && pass view_report_links ||
	fail view_report_links "no 'voxdag view' line in report.md"

pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null; wait "$p" 2>/dev/null; done; rm -rf "$T"; }
trap cleanup EXIT

# serve NAME ARGS...: starts voxdag view on a free port; sets URL
serve() {
	local name=$1
	shift
	"$BIN/voxdag" view "$@" --port 0 > "$T/$name.url" 2> "$T/$name.err" &
	pids+=($!)
	for _ in $(seq 50); do
		[ -s "$T/$name.url" ] && break
		sleep 0.1
	done
	URL=$(head -1 "$T/$name.url")
}
serve main "$T/bunny.yaml"
ENC=enc/$(ls "$T/scene/enc" | grep '\.ssvdag$')
code() { curl -s --path-as-is -o "$T/body" -w '%{http_code}' "$@"; }

[[ "$URL" =~ ^http://127\.0\.0\.1:[0-9]+/$ ]] && pass view_prints_url ||
	fail view_prints_url "got '$URL'" "$(cat "$T/main.err")"
[ "$(code "$URL")" = 200 ] && grep -q '<canvas' "$T/body" && pass view_serves_page ||
	fail view_serves_page
ct=$(curl -s -o /dev/null -w '%{content_type}' "${URL}viewer.js")
[[ "$ct" == text/javascript* ]] && pass view_js_content_type ||
	fail view_js_content_type "Content-Type '$ct'"
[ "$(code "${URL}data/$ENC")" = 200 ] && cmp -s "$T/body" "$T/scene/$ENC" &&
	pass view_serves_encoding || fail view_serves_encoding
[ "$(code "${URL}scene.json")" = 200 ] && grep -q "\"$ENC\"" "$T/body" &&
	pass view_scene_lists_encodings || fail view_scene_lists_encodings "$(head -c 300 "$T/body")"
echo secret > "$T/secret"
ln -s "$T/secret" "$T/scene/enc/link" 2>/dev/null
bad=0
for p in "data/../secret" "data/%2e%2e/secret" "data/%2E%2E/secret" \
	 "data/enc/..%2f..%2fsecret" "data/enc%2f..%2f..%2fsecret" \
	 "../secret" "%2e%2e/secret" "data/enc/link" "data/.lock" \
	 "data/enc" "data/enc/" "data/" "data//etc/passwd" \
	 "data/%2fetc%2fpasswd" "..%2fREADME.md" "data/enc/.%2e/.%2e/secret"; do
	c=$(code "$URL$p")
	if [ "$c" = 200 ] || grep -q secret "$T/body"; then
		bad=1
		echo "  $p answered $c" >&2
	fi
done
rm -f "$T/scene/enc/link"
[ $bad = 0 ] && pass view_no_traversal || fail view_no_traversal
[ "$(code "${URL}data/enc/missing.ssvdag")" = 404 ] && pass view_missing_404 ||
	fail view_missing_404
size=$(stat -c %s "$T/scene/$ENC")
c=$(curl -s -D "$T/hdr" -o "$T/body" -w '%{http_code}' -H 'Range: bytes=100-199' "${URL}data/$ENC")
[ "$c" = 206 ] && [ "$(stat -c %s "$T/body")" = 100 ] &&
	grep -qi "content-range: bytes 100-199/$size" "$T/hdr" &&
	cmp -s "$T/body" <(tail -c +101 "$T/scene/$ENC" | head -c 100) &&
	pass view_range || fail view_range "code $c" "$(cat "$T/hdr")"
c=$(curl -s -o "$T/body" -w '%{http_code}' -H 'Range: bytes=-10' "${URL}data/$ENC")
[ "$c" = 206 ] && cmp -s "$T/body" <(tail -c 10 "$T/scene/$ENC") &&
	pass view_range_suffix || fail view_range_suffix "code $c"
[ "$(code -H "Range: bytes=$size-" "${URL}data/$ENC")" = 416 ] &&
	pass view_range_unsatisfiable || fail view_range_unsatisfiable
expect view_port_busy 1 'cannot listen on 127\.0\.0\.1:[0-9]+: Address already in use' \
	"$BIN/voxdag" view "$T/scene" --port "$(echo "$URL" | sed 's|.*:\([0-9]*\)/|\1|')"
expect view_no_dir 1 "cannot serve '$T/nothere'" "$BIN/voxdag" view "$T/nothere" --port 0
expect view_bad_port 2 'not a port' "$BIN/voxdag" view "$T/scene" --port 70000

# --help lists exactly the options of view.c's table
codeopts=$(grep -oE '^\s*\{"[a-z-]+", (no|required|optional)_argument' pipeline/view.c |
	grep -oE '"[a-z-]+"' | tr -d '"' | sort -u)
helpopts=$("$BIN/voxdag" view --help | grep -oE -- '--[a-z][a-z-]+' | sed 's/^--//' | sort -u)
[ "$codeopts" = "$helpopts" ] && pass view_help_matches_code ||
	fail view_help_matches_code "code: $(echo $codeopts)" "help: $(echo $helpopts)"

# a damaged copy: one byte changed (the manifest's checksum catches it),
# one truncated, and a truncated file without a manifest (the page's own
# reader catches it)
cp -r "$T/scene" "$T/bad"
rm -f "$T/bad/.lock"
cp "$T/scene/$ENC" "$T/bad/enc/cut.ssvdag"
mkdir "$T/bad/loose"
head -c 1000 "$T/scene/$ENC" > "$T/bad/loose/short.ssvdag"
printf '\x55' | dd of="$T/bad/$ENC" bs=1 seek=300 conv=notrunc status=none
truncate -s 5000 "$T/bad/enc/cut.ssvdag"
serve bad "$T/bad"
BADURL=$URL
[ "$(code "${BADURL}data/$ENC")" = 409 ] && grep -q 'checksum\|XXH3\|differ\|changed' "$T/body" &&
	pass view_refuses_damaged || fail view_refuses_damaged "$(cat "$T/body")"

# ---- the page in headless chromium
if ! command -v node >/dev/null || ! [ -x /usr/bin/chromium ]; then
	echo "SKIP viewer_chromium (node or /usr/bin/chromium missing: make deps)"
	exit 0
fi
if ! [ -d tests/viewer/node_modules/puppeteer-core ]; then
	PUPPETEER_SKIP_DOWNLOAD=1 npm ci --prefix tests/viewer --no-audit --no-fund \
		>/dev/null 2>"$T/npm.err" || {
		echo "SKIP viewer_chromium (npm ci failed: $(head -1 "$T/npm.err"))"
		exit 0
	}
fi

# three cameras on the bunny (bounding box about (-0.095, 0.033, -0.062)
# .. (0.061, 0.187, 0.059)): front, a high oblique one, a close-up
# inside the box's corner region
cat > "$T/cam1.json" <<EOF
{"eye": [-0.017, 0.11, 0.45], "target": [-0.017, 0.11, 0.0], "up": [0, 1, 0], "fov": 40, "width": 256, "height": 192}
EOF
cat > "$T/cam2.json" <<EOF
{"eye": [0.25, 0.3, 0.2], "target": [-0.01, 0.1, -0.003], "up": [0, 1, 0], "fov": 35, "width": 256, "height": 192}
EOF
cat > "$T/cam3.json" <<EOF
{"eye": [-0.2, 0.12, -0.12], "target": [-0.03, 0.09, 0.0], "up": [0.1, 1, 0], "fov": 50, "width": 256, "height": 192}
EOF
cases=
for k in 1 2 3; do
	"$BIN/render" "$T/scene/$ENC" --camera-file "$T/cam$k.json" -o "$T/r$k.png" \
		--voxel-id "$T/r$k.vid" --depth "$T/r$k.pfm" -q -S ||
		fail viewer_render_cam$k
	cases="$cases{\"name\": \"viewer_bunny_cam$k\", \"file\": \"$ENC\", \"camera\": \"$T/cam$k.json\", \"ids\": \"$T/r$k.vid\", \"depth\": \"$T/r$k.pfm\"},"
done
# level of detail: the page's lod=2 against render --lod 2 (the bunny's
# 512 voxels span about 150 pixels here, so whole nodes are hit)
"$BIN/render" "$T/scene/$ENC" --camera-file "$T/cam2.json" -o "$T/rl.png" --lod 2 \
	--voxel-id "$T/rl.vid" --depth "$T/rl.pfm" -q -S || fail viewer_render_lod
cases="$cases{\"name\": \"viewer_bunny_lod2\", \"file\": \"$ENC\", \"query\": \"lod=2\", \"camera\": \"$T/cam2.json\", \"ids\": \"$T/rl.vid\", \"depth\": \"$T/rl.pfm\"},"
# voxdag view --camera-file: the printed URL carries the camera, and the
# page starts there, number for number (render's doubles survive the trip)
serve cam "$T/scene" --camera-file "$T/cam2.json"
CAMQ=${URL#*\?}
[[ "$URL" =~ ^http://127\.0\.0\.1:[0-9]+/\?camera=%7B ]] && pass view_camera_url ||
	fail view_camera_url "got '$URL'" "$(cat "$T/cam.err")"
echo '{"eye": [1, 2, 3], "target": [1, 2, 3]}' > "$T/badcam.json"
expect view_bad_camera_file 1 "camera file '$T/badcam.json'" \
	"$BIN/voxdag" view "$T/scene" --port 0 --camera-file "$T/badcam.json"
expect view_camera_file_dir 1 "camera file '$T': Is a directory" \
	"$BIN/voxdag" view "$T/scene" --port 0 --camera-file "$T"
cases="$cases{\"name\": \"viewer_starts_at_camera_file\", \"file\": \"$ENC\", \"query\": \"$CAMQ\", \"expectCamera\": \"$T/cam2.json\"},"
cases="$cases{\"name\": \"viewer_shows_bad_camera\", \"file\": \"$ENC\", \"query\": \"camera=%7B%22eye%22%3A%5B1%2C2%5D%7D\", \"expectError\": \"camera: .eye. is not 3 numbers\"},"
cat > "$T/spec.json" <<EOF
{"url": "$(head -1 "$T/main.url")", "maxMismatch": 0.0005, "cases": [${cases%,}]}
EOF
cat > "$T/spec-bad.json" <<EOF
{"url": "$BADURL", "cases": [
 {"name": "viewer_shows_damaged", "file": "$ENC", "expectError": "409"},
 {"name": "viewer_shows_truncated", "file": "enc/cut.ssvdag", "expectError": "409"},
 {"name": "viewer_shows_bad_file", "file": "loose/short.ssvdag", "expectError": "truncated"},
 {"name": "viewer_shows_missing", "file": "enc/none.ssvdag", "expectError": "404"}]}
EOF
# the spider with colorize's raw colours, served as a directory: the ids
# and depths again, and each hit pixel of render's picture must be the
# page's colour for that voxel times one shading factor
M=tests/data/spider/spider.obj
mkdir -p "$T/spider"
"$BIN/voxelize" $M -o "$T/spider/vox" --levels 8 -q &&
	"$BIN/svo-to-dag" "$T/spider/vox/chunk-L0-0.svo" -o "$T/sp.dag" -q &&
	"$BIN/symmetry-merge" "$T/sp.dag" -o "$T/sp.ssvdag" -q &&
	"$BIN/symmetry-merge" --group 48 "$T/sp.dag" -o "$T/sp.s48" -q &&
	"$BIN/encode" "$T/sp.dag" "$T/sp.ssvdag" "$T/sp.s48" -o "$T/spider/enc" -q &&
	"$BIN/colorize" "$T/spider/vox" -o "$T/spider/pack" --method raw,vbr,palette,auto -q &&
	"$BIN/lossy-cluster" "$T/sp.dag" -o "$T/lossy.dag" -q &&
	"$BIN/symmetry-merge" "$T/lossy.dag" -o "$T/lossy.ssvdag" -q &&
	"$BIN/encode" "$T/lossy.dag" "$T/lossy.ssvdag" -o "$T/spider/lossy" --name lossy -q ||
	fail viewer_spider_build
"$BIN/voxelize" tests/data/bunny.ply -o "$T/spider/vox-bunny" --levels 8 -q &&
	"$BIN/svo-to-dag" "$T/spider/vox-bunny/chunk-L0-0.svo" -o "$T/bn.dag" -q &&
	"$BIN/symmetry-merge" "$T/bn.dag" -o "$T/bn.ssvdag" -q &&
	"$BIN/encode" "$T/bn.dag" "$T/bn.ssvdag" -o "$T/spider/benc" --name bunny -q ||
	fail viewer_spider_bunny_build
serve spider "$T/spider"
SPURL=$URL
SPENC=enc/$(ls "$T/spider/enc" | grep '\.ssvdag$')
# the spider's box: about (-93, -42, -107) .. (58, 38, 87)
echo '{"eye": [-17, 60, 300], "target": [-17, -2, -10], "up": [0, 1, 0], "fov": 45, "width": 256, "height": 192}' > "$T/sc1.json"
echo '{"eye": [160, 140, 170], "target": [-17, -2, -10], "up": [0, 1, 0], "fov": 45, "width": 256, "height": 192}' > "$T/sc2.json"
echo '{"eye": [-260, -20, 60], "target": [-17, -2, -10], "up": [0, 1, 0.1], "fov": 40, "width": 256, "height": 192}' > "$T/sc3.json"
spcases=
for k in 1 2 3; do
	"$BIN/render" "$T/spider/$SPENC" --camera-file "$T/sc$k.json" -o "$T/s$k.png" \
		--voxel-id "$T/s$k.vid" --depth "$T/s$k.pfm" -q -C "$T/spider/pack/colours.raw" ||
		fail viewer_render_spider$k
	spcases="$spcases{\"name\": \"viewer_spider_cam$k\", \"file\": \"$SPENC\", \"colours\": \"pack/colours.raw\", \"camera\": \"$T/sc$k.json\", \"ids\": \"$T/s$k.vid\", \"depth\": \"$T/s$k.pfm\", \"png\": \"$T/s$k.png\"},"
done
# the word encodings and the 48-group one too (one camera each; the
# same voxels, so render's buffers of the .ssvdag)
for f in svdag ussvdag ssvdag48; do
	spcases="$spcases{\"name\": \"viewer_spider_$f\", \"file\": \"${SPENC%.ssvdag}.$f\", \"colours\": \"pack/colours.raw\", \"camera\": \"$T/sc2.json\", \"ids\": \"$T/s2.vid\", \"depth\": \"$T/s2.pfm\", \"png\": \"$T/s2.png\"},"
done
# the other colour sources, decoded by the library on the server: vbr
# and palette files, voxelize's colour chunks (one camera each)
for c in pack/colours.vbr pack/colours.palette vox; do
	n=$(echo "$c" | tr '/.' '__')
	"$BIN/render" "$T/spider/$SPENC" --camera-file "$T/sc2.json" -o "$T/c_$n.png" \
		-q -C "$T/spider/$c" || fail viewer_render_colours_$n
	spcases="$spcases{\"name\": \"viewer_spider_colours_$n\", \"file\": \"$SPENC\", \"colours\": \"$c\", \"camera\": \"$T/sc2.json\", \"ids\": \"$T/s2.vid\", \"depth\": \"$T/s2.pfm\", \"png\": \"$T/c_$n.png\"},"
done
# lossless and lossy side by side: the pixels the page marks red are
# the ones render --diff counts
ndiff=$("$BIN/render" "$T/spider/$SPENC" --diff "$T/spider/lossy/lossy.ssvdag" \
	--camera-file "$T/sc2.json" -o "$T/diff.png" 2>&1 |
	sed -n 's/.*: \([0-9]*\) pixels show voxels set in only one.*/\1/p')
[ -n "$ndiff" ] && [ "$ndiff" -gt 0 ] || fail viewer_render_diff "render --diff counted '$ndiff'"
spcases="$spcases{\"name\": \"viewer_side_by_side_diff\", \"file\": \"$SPENC\", \"file2\": \"lossy/lossy.ssvdag\", \"camera\": \"$T/sc2.json\", \"renderDiff\": ${ndiff:-0}},"
spcases="$spcases{\"name\": \"viewer_side_by_side_same\", \"file\": \"$SPENC\", \"file2\": \"${SPENC%.ssvdag}.svdag\", \"camera\": \"$T/sc2.json\", \"renderDiff\": 0},"
# no colours in the URL: the pipeline's compressed colours (auto), and
# grey with the reason for a scene they do not cover (the bunny's)
spcases="$spcases{\"name\": \"viewer_default_colours\", \"file\": \"$SPENC\", \"expectColours\": \"pack/colours.auto\"},"
spcases="$spcases{\"name\": \"viewer_default_colours_grey\", \"file\": \"benc/bunny.svdag\", \"expectColours\": \"\", \"expectStatus\": \"in grey: colours .* cover [0-9]+ voxels, the scene has [0-9]+\"},"
cat > "$T/spec-spider.json" <<EOF
{"url": "$SPURL", "maxMismatch": 0.0005, "maxColourOff": 0.01, "cases": [$spcases
 {"name": "viewer_refuses_other_colours", "file": "$SPENC", "colours": "vox-bunny", "expectError": "colours"}]}
EOF
timeout 240 node tests/viewer/compare.mjs "$T/spec.json" "$T/spec-bad.json" "$T/spec-spider.json" ||
	fail viewer_compare "node exited $?"
