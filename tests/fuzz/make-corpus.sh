#!/usr/bin/env bash
# Rebuilds the seed corpora tests/fuzz/corpus/<target>/ from tests/data
# (the bunny, cut small), hand-written meshes and files written by the
# release tools (chunks, encodings, OpenVDB grids) and config/*.yaml.
# Needs `make` first. Keep the corpora small: they live in git.
set -eu
cd "$(dirname "$0")/../.."
BIN=${BIN:-out/bin}
C=tests/fuzz/corpus
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
rm -rf "$C"
mkdir -p $C/ply $C/obj $C/stl $C/ac3d $C/chunk $C/svdag $C/ussvdag \
	$C/esvdag $C/ssvdag $C/ssvdag48 $C/config $C/vdb $C/texture

python3 - "$C" <<'PY'
import struct, sys
C = sys.argv[1]
V = [(0,0,0),(1,0,0),(0,1,0),(0,0,1),(1,1,1)]
F = [(0,1,2),(0,1,3),(0,2,3),(1,2,3),(1,2,4,3)]
def w(p, b):
    open(p, 'wb').write(b if isinstance(b, bytes) else b.encode())
# PLY: ascii, binary both endians, extra properties, a bunny piece
hdr = lambda fmt, extra='': ('ply\nformat %s 1.0\ncomment c\nelement vertex %d\n'
    'property float x\nproperty float y\nproperty float z\n%s'
    'element face %d\nproperty list uchar int vertex_indices\nend_header\n'
    % (fmt, len(V), extra, len(F)))
w(C+'/ply/ascii.ply', hdr('ascii') + ''.join('%g %g %g\n' % v for v in V) +
  ''.join('%d %s\n' % (len(f), ' '.join(map(str, f))) for f in F))
for end, tag in (('<', 'binary_little_endian'), ('>', 'binary_big_endian')):
    b = hdr(tag).encode()
    b += b''.join(struct.pack(end+'3f', *v) for v in V)
    b += b''.join(struct.pack(end+'B%di' % len(f), len(f), *f) for f in F)
    w(C+'/ply/%s.ply' % tag, b)
b = ('ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty double x\n'
     'property double y\nproperty double z\nproperty uchar red\nelement face 1\n'
     'property list uint short vertex_indices\nproperty float q\nend_header\n').encode()
b += b''.join(struct.pack('<3dB', *v, 7) for v in V[:3])
b += struct.pack('<I3hf', 3, 0, 1, 2, 0.5)
w(C+'/ply/types.ply', b)
# OBJ: slashes, negative indices, polygons, groups
w(C+'/obj/cube.obj', '# c\no a\n' + ''.join('v %g %g %g\n' % v for v in V) +
  'vt 0 0\nvn 0 0 1\ng g1\nf 1/1/1 2/1/1 3/1/1\nf -1 -2 -3\nf 1//1 2//1 4//1 5//1\n'
  's off\nusemtl m\nl 1 2\nf 2 3 4\n')
w(C+'/obj/small.obj', 'v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n')
# STL: ascii and binary
w(C+'/stl/ascii.stl', 'solid t\n' + ''.join(
  'facet normal 0 0 1\nouter loop\n' + ''.join('vertex %g %g %g\n' % V[i] for i in f[:3]) +
  'endloop\nendfacet\n' for f in F) + 'endsolid t\n')
b = b'binary stl'.ljust(80, b' ') + struct.pack('<I', len(F))
for f in F:
    b += struct.pack('<3f', 0, 0, 1) + b''.join(struct.pack('<3f', *V[i]) for i in f[:3]) + b'\0\0'
w(C+'/stl/binary.stl', b)
# AC3D: nested objects with loc and rot, polygon, strip, line
w(C+'/ac3d/scene.ac', '''AC3Db
MATERIAL "m" rgb 1 1 1  amb 0.2 0.2 0.2  emis 0 0 0  spec 0 0 0  shi 0  trans 0
OBJECT world
kids 1
OBJECT poly
name "a"
loc 1 2 3
rot 1 0 0  0 1 0  0 0 1
numvert 5
0 0 0
1 0 0
0 1 0
0 0 1
1 1 1
numsurf 3
SURF 0x10
mat 0
refs 4
0 0 0
1 1 0
4 1 1
2 0 1
SURF 0x14
refs 4
0 0 0
1 0 0
2 0 0
3 0 0
SURF 0x1
refs 2
0 0 0
1 0 0
kids 1
OBJECT poly
numvert 3
0 0 0
2 0 0
0 2 0
numsurf 1
SURF 0x0
refs 3
0 0 0
1 0 0
2 0 0
kids 0
''')
PY
# A piece of the bunny: its header with small counts and the first bytes.
python3 - "$C" <<'PY'
import sys, struct
C = sys.argv[1]
d = open('tests/data/bunny.ply', 'rb').read()
h = d.index(b'end_header\n') + len(b'end_header\n')
head = d[:h].replace(b'element vertex 34834', b'element vertex 40').replace(
    b'element face 69451', b'element face 20')
body = d[h:h + 40 * 12]
for i in range(20):
    body += struct.pack('<B3i', 3, i, i + 1, i + 2)
open(C + '/ply/bunny-piece.ply', 'wb').write(head + body)
PY

cp config/*.yaml $C/config/

# Chunks and encodings of the bunny at 2^5 and 2^6.
for L in 5 6; do
	$BIN/voxelize tests/data/bunny.ply -o "$T/v$L" --levels $L --chunk-level 1 -q
	$BIN/voxelize tests/data/bunny.ply -o "$T/r$L" --levels $L --chunk-level 0 -q
	f=$(ls "$T/v$L"/chunk-L1-*.svo | head -1)
	cp "$f" $C/chunk/svo-L$L.svo
	$BIN/svo-to-dag -q "$f" -o "$T/c$L.dag"
	cp "$T/c$L.dag" $C/chunk/cell-L$L.dag
	$BIN/svo-to-dag -q "$T/r$L/chunk-L0-0.svo" -o "$T/root$L.dag"
	$BIN/symmetry-merge -q "$T/root$L.dag" -o "$T/root$L.ssvdag"
	cp "$T/root$L.ssvdag" $C/chunk/root-L$L.ssvdag
	$BIN/symmetry-merge -q --group 48 "$T/root$L.dag" -o "$T/root$L.s48"
	$BIN/encode -q "$T/root$L.dag" "$T/root$L.ssvdag" "$T/root$L.s48" \
		-o "$T/e$L" -n b -l 3
	for f in svdag ussvdag esvdag ssvdag ssvdag48; do
		cp "$T/e$L/b.$f" $C/$f/bunny-L$L.$f
	done
done
# A packed colours file of the auto method (its reader's checks).
$BIN/colour-make-test "$T/v5" &&
	$BIN/colorize -q "$T/v5" -o "$T/col5" --method auto --max-error 0.05 &&
	cp "$T/col5/colours.auto" $C/chunk/colours-L5.auto

# Textures: the bundled scene's small images, and SGI images from netpbm's
# pnmtosgi (verbatim and RLE, grey and colour, 8 and 16 bits).
cp tests/data/textured/*.png tests/data/textured/*.tga \
	tests/data/textured/*.bmp tests/data/textured/*.jpg $C/texture/
printf 'P6\n5 3\n255\n%s' "$(head -c 45 /dev/zero | tr '\0' 'a')" > "$T/c.ppm"
printf 'P5\n4 2\n65535\n%s' "$(head -c 16 /dev/zero | tr '\0' 'z')" > "$T/g.pgm"
pnmtosgi -rle "$T/c.ppm" > $C/texture/rle.rgb
pnmtosgi -verbatim "$T/c.ppm" > $C/texture/verbatim.rgb
pnmtosgi -rle "$T/g.pgm" > $C/texture/grey16.bw

# OpenVDB grids: the small test grids, cut to 64 KiB at most.
mkdir -p "$T/vdb"
$BIN/vdb-make-test-grids "$T/vdb" >/dev/null
for f in "$T"/vdb/*.vdb; do
	head -c 16384 "$f" > $C/vdb/$(basename "$f")
done
du -sh $C
