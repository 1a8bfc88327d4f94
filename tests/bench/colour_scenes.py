#!/usr/bin/python3
"""colour_scenes.py MESH.ply OUTDIR: the two smooth-coloured scenes of the
colour benchmark (issue 37), made from a real uncoloured mesh (binary PLY
of ../shared/data, float x y z, triangle faces):

  OUTDIR/<mesh>-position.ply  vertex colours varying smoothly with position
                              (sines of the coordinates at a few scales: the
                              gradients a colour codec's endpoints fit)
  OUTDIR/<mesh>-baked.ply     baked lighting: a slowly varying albedo times
                              diffuse light from two directional lights and
                              a sky term, from area-weighted vertex normals
                              (what a light-mapped or path-traced scene
                              stores per voxel, like the paper's Sponza)

Colours are sRGB bytes per vertex; voxelize interpolates them over each
triangle (schemas/colour-rule.md). Deterministic: the same mesh gives the
same files. Needs python3-numpy."""
import os
import sys

import numpy as np


def read_ply(path):
    with open(path, "rb") as f:
        nv = nf = 0
        props = []
        face_fmt = None
        in_vertex = False
        while True:
            line = f.readline().decode("ascii").strip()
            if line.startswith("format") and "binary_little_endian" not in line:
                sys.exit(f"{path}: not a binary little-endian PLY")
            if line.startswith("element vertex"):
                nv, in_vertex = int(line.split()[2]), True
            elif line.startswith("element face"):
                nf, in_vertex = int(line.split()[2]), False
            elif line.startswith("property list"):
                face_fmt = line.split()[2:4]
            elif line.startswith("property") and in_vertex:
                props.append(line.split()[1:3])
            elif line == "end_header":
                break
        sizes = {"float": "f4", "uchar": "u1", "int": "i4", "double": "f8"}
        vt = np.dtype([(n, "<" + sizes[t]) for t, n in props])
        v = np.frombuffer(f.read(nv * vt.itemsize), dtype=vt, count=nv)
        if face_fmt != ["uchar", "int"]:
            sys.exit(f"{path}: faces are not uchar/int lists")
        ft = np.dtype([("n", "u1"), ("i", "<i4", 3)])
        fc = np.frombuffer(f.read(nf * ft.itemsize), dtype=ft, count=nf)
        if (fc["n"] != 3).any():
            sys.exit(f"{path}: faces that are not triangles")
    xyz = np.stack([v["x"], v["y"], v["z"]], axis=1).astype(np.float64)
    return xyz, fc["i"].astype(np.int64)


def write_ply(path, xyz, faces, rgb):
    vt = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"),
                   ("r", "u1"), ("g", "u1"), ("b", "u1")])
    v = np.empty(len(xyz), dtype=vt)
    v["x"], v["y"], v["z"] = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    v["r"], v["g"], v["b"] = rgb[:, 0], rgb[:, 1], rgb[:, 2]
    ft = np.dtype([("n", "u1"), ("i", "<i4", 3)])
    fc = np.empty(len(faces), dtype=ft)
    fc["n"], fc["i"] = 3, faces
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        f.write((f"ply\nformat binary_little_endian 1.0\n"
                 f"comment colour_scenes.py (voxdag tests/bench)\n"
                 f"element vertex {len(xyz)}\nproperty float x\nproperty float y\n"
                 f"property float z\nproperty uchar red\nproperty uchar green\n"
                 f"property uchar blue\nelement face {len(faces)}\n"
                 f"property list uchar int vertex_indices\nend_header\n").encode())
        f.write(v.tobytes())
        f.write(fc.tobytes())
    os.replace(tmp, path)


def to_srgb8(x):
    return np.clip(np.round(x * 255.0), 0, 255).astype(np.uint8)


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: colour_scenes.py MESH.ply OUTDIR")
    xyz, faces = read_ply(sys.argv[1])
    os.makedirs(sys.argv[2], exist_ok=True)
    base = os.path.join(sys.argv[2], os.path.splitext(os.path.basename(sys.argv[1]))[0])
    lo, hi = xyz.min(axis=0), xyz.max(axis=0)
    p = (xyz - lo) / (hi - lo).max()          # in the unit cube

    # 1. colours varying with position: sines at two scales per channel
    pos = np.empty_like(p)
    for c in range(3):
        a = p[:, c] * 2.0 * np.pi
        b = p[:, (c + 1) % 3] * 6.0 * np.pi
        pos[:, c] = 0.5 + 0.35 * np.sin(a + c) + 0.15 * np.sin(b + 2 * c)
    write_ply(base + "-position.ply", xyz, faces, to_srgb8(pos))

    # 2. baked lighting: area-weighted normals, two lights and a sky
    e1 = xyz[faces[:, 1]] - xyz[faces[:, 0]]
    e2 = xyz[faces[:, 2]] - xyz[faces[:, 0]]
    fn = np.cross(e1, e2)
    n = np.zeros_like(xyz)
    for k in range(3):
        np.add.at(n, faces[:, k], fn)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
    l1 = np.array([0.5, 0.8, 0.3]) / np.linalg.norm([0.5, 0.8, 0.3])
    l2 = np.array([-0.7, 0.2, -0.4]) / np.linalg.norm([-0.7, 0.2, -0.4])
    sky = 0.5 + 0.5 * n[:, 1]
    light = (0.75 * np.clip(n @ l1, 0, None)[:, None] * np.array([1.0, 0.95, 0.85])
             + 0.25 * np.clip(n @ l2, 0, None)[:, None] * np.array([0.6, 0.7, 1.0])
             + 0.2 * sky[:, None] * np.array([0.55, 0.65, 0.8]))
    albedo = np.stack([0.75 + 0.2 * np.sin(3 * np.pi * p[:, 0]),
                       0.6 + 0.2 * np.sin(2 * np.pi * p[:, 1] + 1),
                       0.45 + 0.2 * np.sin(4 * np.pi * p[:, 2] + 2)], axis=1)
    lin = np.clip(albedo * light, 0, 1)
    srgb = np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * lin ** (1 / 2.4) - 0.055)
    write_ply(base + "-baked.ply", xyz, faces, to_srgb8(srgb))


if __name__ == "__main__":
    main()
