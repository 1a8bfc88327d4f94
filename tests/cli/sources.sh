#!/usr/bin/env bash
# Resume sees the files a mesh pulls in: an OBJ's MTL and the textures it
# names, an AC3D file's textures, a .gltf's buffer. Changing one (or
# deleting it, or bringing back one that was missing) reruns voxelize and
# the colorize job after it, whose colours then differ; a rerun with
# nothing changed starts nothing; a geometry-only pipeline does not read
# MTL files, so their changes do not rerun it (schemas/pipeline.md,
# "Resume").
set -u
cd "$(dirname "$0")/../.."
. tests/cli/lib.sh
R=$BIN/voxdag
NAME=clisources-$$
D=out/$NAME
trap 'rm -rf "$T" out/$NAME' EXIT

# png FILE R G B: a 4x4 PNG of one colour (the scene's checker is 4x4)
png() {
	/usr/bin/python3 - "$@" <<'EOF'
import struct, sys, zlib
path, rgb = sys.argv[1], bytes(int(c) for c in sys.argv[2:5])
raw = b''.join(b'\0' + rgb * 4 for _ in range(4))
def chunk(t, d):
    c = struct.pack('>I', len(d)) + t + d
    return c + struct.pack('>I', zlib.crc32(t + d) & 0xffffffff)
open(path, 'wb').write(b'\x89PNG\r\n\x1a\n' +
    chunk(b'IHDR', struct.pack('>IIBBBBB', 4, 4, 8, 2, 0, 0, 0)) +
    chunk(b'IDAT', zlib.compress(raw)) + chunk(b'IEND', b''))
EOF
}

# pipeline MESH [--no-colours]: voxelize, its DAG, and a raw colorize job
# (none with --no-colours, so voxelize runs without colours)
pipeline() {
	if [ "${2:-}" = --no-colours ]; then
		small_pipeline "$NAME" "$1" </dev/null
	else
		echo "  col:    {stage: colorize, needs: [vox], method: raw}" |
			small_pipeline "$NAME" "$1"
	fi > "$T/p.yaml"
}
# the jobs the last run started, sorted, on one line
started() { awk '/ run /{buf=""} {buf=buf $0 "\n"} END{printf "%s", buf}' $D/logs/runner.log |
	grep ' started ' | sed 's/.* started \([^ ]*\) .*/\1/' | sort | tr '\n' ' '; }
run() { $R -q run "$T/p.yaml" 2>"$T/run.err" || { cat "$T/run.err" >&2; return 1; }; }

# rerun_after NAME WANT: after a change, a run starts exactly the jobs
# WANT ("col vox ": not the DAG, whose voxels did not change) and the
# colours differ from the previous run's (kept in $T/prev.raw)
rerun_after() {
	local name=$1 want=$2
	run || { fail "$name" "the run failed"; return; }
	if [ "$(started)" != "$want" ]; then
		fail "$name" "started '$(started)', wanted '$want'" "$(cat "$T/run.err")"
	elif [ -f "$T/prev.raw" ] && cmp -s "$T/prev.raw" $D/col/colours.raw; then
		fail "$name" "the colours did not change"
	else
		pass "$name"
	fi
	[ -f $D/col/colours.raw ] && cp $D/col/colours.raw "$T/prev.raw"
}
nothing_started() {
	run && [ -z "$(started)" ] && pass "$1" || fail "$1" "started '$(started)'"
}

# --- OBJ + MTL + textures
S=$T/obj
mkdir -p "$S"
cp tests/data/textured/* "$S/"
pipeline "$S/scene.obj"
run && pass sources_first_run || fail sources_first_run
cp $D/col/colours.raw "$T/prev.raw"
grep -Eq '^[0-9a-f]{16} [0-9]+ .*/checker.png$' $D/vox/sources &&
	grep -Eq '^[0-9a-f]{16} [0-9]+ .*/scene.mtl$' $D/vox/sources &&
	pass sources_lists_mtl_and_texture || fail sources_lists_mtl_and_texture "$(cat $D/vox/sources)"
nothing_started sources_unchanged_starts_nothing
png "$S/checker.png" 10 200 90
rerun_after sources_texture_changed "col vox "
nothing_started sources_texture_change_settled
sed -i 's/^Kd 1 0 0$/Kd 0 0 1/' "$S/scene.mtl"
rerun_after sources_mtl_kd_changed "col vox "
mv "$S/checker.png" "$S/gone.png"
rerun_after sources_texture_deleted "col vox "
grep -q "warning: texture not used.*checker.png" $D/logs/vox.log 2>/dev/null &&
	pass sources_texture_deleted_warns ||
	fail sources_texture_deleted_warns "$(cat $D/logs/vox.log)"
nothing_started sources_missing_texture_settled
mv "$S/gone.png" "$S/checker.png"
rerun_after sources_texture_back "col vox "
touch "$S/checker.png" "$S/scene.mtl"
nothing_started sources_touch_is_no_change

# --- without colours voxelize reads no MTL: its changes rerun nothing
pipeline "$S/scene.obj" --no-colours
run
sed -i 's/^Kd 0 0 1$/Kd 0 1 0/' "$S/scene.mtl"
png "$S/checker.png" 1 2 3
nothing_started sources_no_colours_ignores_mtl

# --- AC3D: its texture
rm -rf $D "$T/prev.raw"
pipeline "$S/scene.ac"
run
cp $D/col/colours.raw "$T/prev.raw"
png "$S/checker.png" 250 20 20
rerun_after sources_ac3d_texture_changed "col vox "

# --- glTF: its buffer (texture coordinates, then a vertex)
rm -rf $D "$T/prev.raw"
G=$T/gltf
mkdir -p "$G"
cp tests/data/gltf/scene.gltf tests/data/gltf/scene.bin tests/data/gltf/checker.png "$G/"
pipeline "$G/scene.gltf"
run
cp $D/col/colours.raw "$T/prev.raw"
nothing_started sources_gltf_unchanged_starts_nothing
# accessor 1 (bytes 48..79): every corner's uv to (0.1, 0.1), one texel
/usr/bin/python3 - "$G/scene.bin" <<'EOF'
import struct, sys
p = sys.argv[1]
b = bytearray(open(p, 'rb').read())
b[48:80] = struct.pack('<8f', *([0.1] * 8))
open(p, 'wb').write(b)
EOF
rerun_after sources_gltf_buffer_changed "col vox "
# the same scene without colours: its buffer holds the geometry
pipeline "$G/scene.gltf" --no-colours
run
/usr/bin/python3 - "$G/scene.bin" <<'EOF'
import struct, sys
p = sys.argv[1]
b = bytearray(open(p, 'rb').read())
b[0:12] = struct.pack('<3f', 0.5, 0.5, 0.0)  # the first vertex moves
open(p, 'wb').write(b)
EOF
run
case "$(started)" in
*vox*) pass sources_gltf_geometry_buffer_changed ;;
*) fail sources_gltf_geometry_buffer_changed "started '$(started)'" ;;
esac
