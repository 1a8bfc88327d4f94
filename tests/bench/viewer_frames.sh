#!/usr/bin/env bash
# The browser viewer's load and frame times for make bench: the default
# pipeline's bunny (2^9) served by voxdag view, drawn by headless Debian
# chromium on SwiftShader (so CPU time, not a GPU's), at three image
# sizes. Skips with one line when chromium, node or the npm packages
# (make test-build) are missing.
set -u
cd "$(dirname "$0")/../.."
if ! [ -x /usr/bin/chromium ] || ! command -v node >/dev/null ||
	! [ -d tests/viewer/node_modules/puppeteer-core ]; then
	echo "bench: viewer frames skipped (chromium, node or tests/viewer/node_modules missing)"
	exit 0
fi
out/bin/voxdag run config/default.yaml -q || exit 1
log=$(mktemp)
out/bin/voxdag view config/default.yaml --port 0 > "$log" 2>/dev/null &
pid=$!
trap 'kill $pid 2>/dev/null; wait $pid 2>/dev/null; rm -f "$log"' EXIT
for _ in $(seq 50); do [ -s "$log" ] && break; sleep 0.1; done
echo "bench: the viewer on the default bunny (headless chromium, SwiftShader, $(nproc) cores)"
node tests/viewer/frames.mjs "$(head -1 "$log")" \
	'{"eye": [0.2, 0.2, 0.25], "target": [-0.017, 0.11, 0], "fov": 40}'

# The Sponza at 2^16 from inside the atrium (config/sponza.camera.json),
# when config/sponza-64k.yaml has been run (4-5 minutes: not started
# here): frame times and the picture, out/bench/sponza-64k-viewer.png.
if [ -f out/sponza-64k/encode/sponza-64k.ssvdag ]; then
	kill $pid 2>/dev/null; wait $pid 2>/dev/null
	: > "$log"
	out/bin/voxdag view out/sponza-64k --port 0 \
		--camera-file config/sponza.camera.json > "$log" 2>/dev/null &
	pid=$!
	for _ in $(seq 50); do [ -s "$log" ] && break; sleep 0.1; done
	echo "bench: the viewer on the Sponza at 2^16 (headless chromium, SwiftShader, $(nproc) cores)"
	node tests/viewer/frames.mjs "$(head -1 "$log")" "$(cat config/sponza.camera.json)"
	mkdir -p out/bench
	node tests/viewer/shot.mjs "$(head -1 "$log")" out/bench/sponza-64k-viewer.png
else
	echo "bench: no Sponza in the viewer (run config/sponza-64k.yaml first)"
fi
