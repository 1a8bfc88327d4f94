#!/usr/bin/env python3
"""Writes the small textured test scene (run from this directory).

Every file here is made by this script, except photo.jpg (written by
make-jpeg.c with libjpeg, quality 95), so the scene's colours are known
exactly: textures are tiny, lossless (PNG, TGA, BMP) and hand-chosen.
"""
import struct, zlib

def png(path, w, h, rgb):
    raw = b''.join(b'\0' + bytes(rgb[y * w * 3:(y + 1) * w * 3]) for y in range(h))
    def chunk(t, d):
        c = struct.pack('>I', len(d)) + t + d
        return c + struct.pack('>I', zlib.crc32(t + d) & 0xffffffff)
    data = b'\x89PNG\r\n\x1a\n' + chunk(b'IHDR', struct.pack('>IIBBBBB', w, h, 8, 2, 0, 0, 0))
    data += chunk(b'IDAT', zlib.compress(raw)) + chunk(b'IEND', b'')
    open(path, 'wb').write(data)

def tga(path, w, h, rgb):
    # uncompressed true colour, origin top-left (descriptor bit 5)
    hdr = struct.pack('<BBBHHBHHHHBB', 0, 0, 2, 0, 0, 0, 0, 0, w, h, 24, 0x20)
    px = b''.join(bytes((rgb[3*i+2], rgb[3*i+1], rgb[3*i])) for i in range(w * h))
    open(path, 'wb').write(hdr + px)

def bmp(path, w, h, rgb):
    row = (w * 3 + 3) & ~3
    px = b''
    for y in range(h - 1, -1, -1):  # bottom-up rows
        r = b''.join(bytes((rgb[3*(y*w+x)+2], rgb[3*(y*w+x)+1], rgb[3*(y*w+x)])) for x in range(w))
        px += r + b'\0' * (row - w * 3)
    hdr = b'BM' + struct.pack('<IHHI', 54 + len(px), 0, 0, 54)
    hdr += struct.pack('<IiiHHIIiiII', 40, w, h, 1, 24, 0, len(px), 2835, 2835, 0, 0)
    open(path, 'wb').write(hdr + px)

# 4x4 checker of four colours, rows top first
C = [(230, 30, 30), (30, 200, 40), (20, 40, 220), (240, 220, 30)]
checker = []
for y in range(4):
    for x in range(4):
        checker += C[(x // 2) + 2 * (y // 2)] if (x + y) % 2 == 0 else (250, 250, 250)
png('checker.png', 4, 4, checker)
# 2x2 textures for TGA and BMP
tga('bricks.tga', 2, 2, [180, 60, 40, 200, 200, 190, 200, 200, 190, 180, 60, 40])
bmp('tiles.bmp', 2, 2, [10, 120, 200, 60, 60, 60, 60, 60, 60, 10, 120, 200])

# A unit cube, each face its own material and texture kind.
v = [(0,0,0),(1,0,0),(1,1,0),(0,1,0),(0,0,1),(1,0,1),(1,1,1),(0,1,1)]
faces = [('checker', (0,3,2,1)), ('checker', (4,5,6,7)),  # z = 0, z = 1
         ('bricks', (0,4,7,3)), ('tiles', (1,2,6,5)),     # x = 0, x = 1
         ('red', (0,1,5,4)), ('photo', (3,7,6,2))]        # y = 0, y = 1
with open('scene.obj', 'w') as f:
    f.write('# voxdag textured test scene (tests/data/textured/make.py)\nmtllib scene.mtl\n')
    for p in v:
        f.write('v %g %g %g\n' % p)
    f.write('vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n')
    for mat, q in faces:
        f.write('usemtl %s\nf %s\n' % (mat, ' '.join('%d/%d' % (q[i] + 1, i + 1) for i in range(4))))
with open('scene.mtl', 'w') as f:
    f.write('newmtl checker\nKd 0.5 0.5 0.5\nmap_Kd checker.png\n\n'
            'newmtl bricks\nKd 0.7 0.2 0.1\nmap_Kd -s 1 1 1 bricks.tga\n\n'
            'newmtl tiles\nKd 0.1 0.4 0.8\nmap_Kd tiles.bmp\n\n'
            'newmtl red\nKd 1 0 0\n\n'
            'newmtl photo\nKd 0.2 0.2 0.2\nmap_Kd photo.jpg\n')
# The same cube as AC3D: one object textured with the checker (texrep 2 2),
# one untextured coloured by its material.
with open('scene.ac', 'w') as f:
    f.write('AC3Db\nMATERIAL "grey" rgb 0.5 0.5 0.5  amb 0.2 0.2 0.2  emis 0 0 0  spec 0 0 0  shi 10  trans 0\n'
            'MATERIAL "blue" rgb 0 0 1  amb 0.2 0.2 0.2  emis 0 0 0  spec 0 0 0  shi 10  trans 0\n'
            'OBJECT world\nkids 2\n'
            'OBJECT poly\nname "top"\ntexture "checker.png"\ntexrep 2 2\nnumvert 4\n'
            '0 0 1\n1 0 1\n1 1 1\n0 1 1\nnumsurf 1\nSURF 0x10\nmat 0\nrefs 4\n'
            '0 0 0\n1 1 0\n2 1 1\n3 0 1\nkids 0\n'
            'OBJECT poly\nname "bottom"\nnumvert 3\n0 0 0\n1 0 0\n0 1 0\nnumsurf 1\nSURF 0x10\nmat 1\nrefs 3\n'
            '0 0 0\n1 0 0\n2 0 0\nkids 0\n')
# A vertex-coloured tetrahedron (ASCII PLY, uchar colours).
with open('vcol.ply', 'w') as f:
    f.write('ply\nformat ascii 1.0\ncomment voxdag test: vertex colours\nelement vertex 4\n'
            'property float x\nproperty float y\nproperty float z\n'
            'property uchar red\nproperty uchar green\nproperty uchar blue\n'
            'element face 4\nproperty list uchar int vertex_indices\nend_header\n'
            '0 0 0 255 0 0\n1 0 0 0 255 0\n0 1 0 0 0 255\n0 0 1 255 255 255\n'
            '3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n')
