#!/usr/bin/env python3
"""Writes the small glTF 2.0 test scene and its OBJ twin (run from this
directory).

scene.gltf + scene.bin + checker.png, the same as one scene.glb (the PNG
embedded), and scene.obj + scene.mtl: the same triangles in the order
Assimp hands them out (its pre-transform step groups them by material, in
material order), the same texture coordinates (OBJ's v = 1 - glTF's v)
and colours. glTF's colour factors and vertex colours are linear light;
the OBJ holds their sRGB values. wrap.gltf is scene.gltf with the
texture clamped in u and mirrored in v (tests/unit/test_assimp.c).

Coordinates, scales and translations are small binary fractions, so the
pre-transformed float positions are exact and equal to the OBJ's.
"""
import json, struct, zlib

def png_bytes(w, h, rgb):
    raw = b''.join(b'\0' + bytes(rgb[y * w * 3:(y + 1) * w * 3]) for y in range(h))
    def chunk(t, d):
        c = struct.pack('>I', len(d)) + t + d
        return c + struct.pack('>I', zlib.crc32(t + d) & 0xffffffff)
    data = b'\x89PNG\r\n\x1a\n' + chunk(b'IHDR', struct.pack('>IIBBBBB', w, h, 8, 2, 0, 0, 0))
    return data + chunk(b'IDAT', zlib.compress(raw)) + chunk(b'IEND', b'')

# 4x4 texels, rows top first, every one different
tex = []
for y in range(4):
    for x in range(4):
        tex += [40 + 60 * x, 30 + 70 * y, 200 - 40 * x - 10 * y]
PNG = png_bytes(4, 4, tex)

def srgb(c):  # linear 0..1 -> sRGB 0..1 (the value voxelize stores / 255)
    return 12.92 * c if c <= 0.0031308 else 1.055 * c ** (1 / 2.4) - 0.055

# primitives: (node, positions, uvs (glTF v), colours, indices, material)
# node 1 is scaled by 1/2 and moved by (1, 0, 1)
prims = [
    (0, [(0, 0, 0), (2, 0, 0), (2, 2, 0), (0, 2, 0)],
     [(0, 0), (2, 0), (2, 2), (0, 2)], None, [0, 1, 2, 0, 2, 3], 0),
    (0, [(0, 0, 0), (0, 2, 0), (0, 0, 2)], None, None, [0, 1, 2], 1),
    (1, [(0, 0, 0), (2, 0, 0), (0, 2, 0)], None, None, [0, 1, 2], 2),
    (1, [(0, 4, 2), (4, 4, 2), (4, 0, 2)], None,
     [(1, 0, 0), (0, 1, 0), (0, 0, 1)], [0, 1, 2], 3),
]
materials = [
    {'name': 'checker', 'pbrMetallicRoughness': {'baseColorTexture': {'index': 0},
     'baseColorFactor': [1, 1, 1, 1]}},
    {'name': 'red', 'pbrMetallicRoughness': {'baseColorFactor': [1, 0, 0, 1]}},
    {'name': 'half', 'pbrMetallicRoughness': {'baseColorFactor': [0.5, 0.5, 0.5, 1]}},
    {'name': 'vcol', 'pbrMetallicRoughness': {'baseColorFactor': [0.2, 0.2, 0.2, 1]}},
]
node_xf = [lambda p: p, lambda p: tuple(0.5 * c + t for c, t in zip(p, (1, 0, 1)))]

def build(embed):
    bin_ = b''
    views, accessors, gprims = [], [], {0: [], 1: []}
    def add(data, target=None):
        nonlocal bin_
        while len(bin_) % 4:
            bin_ += b'\0'
        v = {'buffer': 0, 'byteOffset': len(bin_), 'byteLength': len(data)}
        if target:
            v['target'] = target
        views.append(v)
        bin_ += data
        return len(views) - 1
    def acc(vals, typ, n, comp=5126, minmax=False):
        fmt = {5126: 'f', 5125: 'I'}[comp]
        flat = [x for v in vals for x in (v if isinstance(v, tuple) else (v,))]
        view = add(struct.pack('<%d%s' % (len(flat), fmt), *flat),
                   34962 if comp == 5126 else 34963)
        a = {'bufferView': view, 'componentType': comp, 'count': len(vals), 'type': typ}
        if minmax:
            a['min'] = [min(v[i] for v in vals) for i in range(n)]
            a['max'] = [max(v[i] for v in vals) for i in range(n)]
        accessors.append(a)
        return len(accessors) - 1
    for node, pos, uv, col, idx, mat in prims:
        attrs = {'POSITION': acc([tuple(map(float, p)) for p in pos], 'VEC3', 3, minmax=True)}
        if uv:
            attrs['TEXCOORD_0'] = acc([tuple(map(float, t)) for t in uv], 'VEC2', 2)
        if col:
            attrs['COLOR_0'] = acc([tuple(map(float, c)) for c in col], 'VEC3', 3)
        p = {'attributes': attrs, 'indices': acc(idx, 'SCALAR', 1, 5125)}
        p['material'] = mat
        gprims[node].append(p)
    g = {'asset': {'version': '2.0', 'generator': 'voxdag tests/data/gltf/make.py'},
         'scene': 0, 'scenes': [{'nodes': [0, 1]}],
         'nodes': [{'mesh': 0}, {'mesh': 1, 'scale': [0.5, 0.5, 0.5],
                                 'translation': [1, 0, 1]}],
         'meshes': [{'primitives': gprims[0]}, {'primitives': gprims[1]}]}
    g['materials'] = materials
    g['samplers'] = [{'wrapS': 10497, 'wrapT': 10497}]
    g['textures'] = [{'source': 0, 'sampler': 0}]
    if embed:
        g['images'] = [{'bufferView': add(PNG), 'mimeType': 'image/png'}]
    else:
        g['images'] = [{'uri': 'checker.png'}]
    g['bufferViews'] = views
    g['accessors'] = accessors
    while len(bin_) % 4:
        bin_ += b'\0'
    g['buffers'] = [{'byteLength': len(bin_)}]
    return g, bin_

g, b = build(False)
g['buffers'][0]['uri'] = 'scene.bin'
open('scene.gltf', 'w').write(json.dumps(g, indent=1) + '\n')
open('scene.bin', 'wb').write(b)
open('checker.png', 'wb').write(PNG)
# the same with the texture clamped in u and mirrored in v
g['samplers'] = [{'wrapS': 33071, 'wrapT': 33648}]
open('wrap.gltf', 'w').write(json.dumps(g, indent=1) + '\n')

g, b = build(True)
js = json.dumps(g, separators=(',', ':')).encode()
js += b' ' * (-len(js) % 4)
glb = struct.pack('<4sII', b'glTF', 2, 12 + 8 + len(js) + 8 + len(b))
glb += struct.pack('<I4s', len(js), b'JSON') + js + struct.pack('<I4s', len(b), b'BIN\0') + b
open('scene.glb', 'wb').write(glb)

# the OBJ twin, faces in material order (Assimp's order after
# aiProcess_PreTransformVertices)
obj = ['# voxdag glTF test scene twin (tests/data/gltf/make.py)', 'mtllib scene.mtl']
nv = nt = 0
for node, pos, uv, col, idx, mat in sorted(prims, key=lambda p: p[5]):
    for k, p in enumerate(pos):
        q = node_xf[node](p)
        line = 'v %g %g %g' % q
        if col:
            line += ' %g %g %g' % tuple(srgb(c) for c in col[k])
        obj.append(line)
    if uv:
        for u, v in uv:
            obj.append('vt %g %g' % (u, 1 - v))
    obj.append('usemtl %s' % materials[mat]['name'])
    for i in range(0, len(idx), 3):
        c = [idx[i + j] for j in range(3)]
        if uv:
            obj.append('f ' + ' '.join('%d/%d' % (nv + x + 1, nt + x + 1) for x in c))
        else:
            obj.append('f ' + ' '.join('%d' % (nv + x + 1) for x in c))
    nv += len(pos)
    nt += len(uv) if uv else 0
open('scene.obj', 'w').write('\n'.join(obj) + '\n')
mtl = []
for m in materials:
    f = m['pbrMetallicRoughness']['baseColorFactor']
    mtl += ['newmtl ' + m['name'], 'Kd %.6f %.6f %.6f' % tuple(srgb(c) for c in f[:3])]
    if 'baseColorTexture' in m['pbrMetallicRoughness']:
        mtl.append('map_Kd checker.png')
    mtl.append('')
open('scene.mtl', 'w').write('\n'.join(mtl))
