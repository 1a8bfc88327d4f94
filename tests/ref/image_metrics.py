#!/usr/bin/python3
"""Independent reference for `render --compare`: MSE, PSNR, SSIM and
MS-SSIM of two PNG images, written from the papers with numpy and scipy
(Debian python3-numpy, python3-scipy), sharing no code with render.

Conventions as documented in stages/lib/render/metrics.c: luma
0.299R + 0.587G + 0.114B, Gaussian window sigma 1.5 truncated at radius 5,
population moments, K1 = 0.01, K2 = 0.03, L = 255, the map averaged over
the pixels 5 away from every border; MS-SSIM over 5 scales with Wang et
al.'s exponents, 2x2 mean and subsampling between scales.

Usage: image_metrics.py A.png B.png  -> one JSON line."""
import json
import struct
import sys
import zlib

import numpy as np
from scipy import ndimage


def read_png(path):
    """8-bit RGB or RGBA, non-interlaced (what libpng writes by default)."""
    data = open(path, "rb").read()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", path
    pos, idat, w = 8, b"", None
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        if kind == b"IHDR":
            w, h, depth, ctype, _, _, interlace = struct.unpack(">IIBBBBB", body)
            assert depth == 8 and ctype in (2, 6) and interlace == 0
            bpp = 3 if ctype == 2 else 4
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    raw = zlib.decompress(idat)
    stride = w * bpp
    out = np.zeros((h, stride), dtype=np.int64)
    prev = np.zeros(stride, dtype=np.int64)
    for y in range(h):
        f = raw[y * (stride + 1)]
        line = np.frombuffer(raw, np.uint8, stride, y * (stride + 1) + 1).astype(np.int64)
        cur = np.zeros(stride, dtype=np.int64)
        for x in range(stride):
            a = cur[x - bpp] if x >= bpp else 0
            b = prev[x]
            c = prev[x - bpp] if x >= bpp else 0
            if f == 0:
                p = 0
            elif f == 1:
                p = a
            elif f == 2:
                p = b
            elif f == 3:
                p = (a + b) // 2
            else:
                pa, pb, pc = abs(b - c), abs(a - c), abs(a + b - 2 * c)
                p = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
            cur[x] = (line[x] + p) & 255
        out[y] = cur
        prev = cur
    return out.reshape(h, w, bpp)[:, :, :3].astype(np.float64)


def ssim_cs(x, y):
    win = lambda im: ndimage.gaussian_filter(im, 1.5, truncate=5 / 1.5 + 1e-9)[5:-5, 5:-5]
    mx, my = win(x), win(y)
    vx = win(x * x) - mx * mx
    vy = win(y * y) - my * my
    cxy = win(x * y) - mx * my
    c1, c2 = (0.01 * 255) ** 2, (0.03 * 255) ** 2
    cs = (2 * cxy + c2) / (vx + vy + c2)
    lum = (2 * mx * my + c1) / (mx * mx + my * my + c1)
    return float(np.mean(lum * cs)), float(np.mean(cs))


def main():
    a, b = read_png(sys.argv[1]), read_png(sys.argv[2])
    mse = float(np.mean((a - b) ** 2))
    ya = a @ np.array([0.299, 0.587, 0.114])
    yb = b @ np.array([0.299, 0.587, 0.114])
    res = {"mse": mse, "psnr": 10 * np.log10(255 ** 2 / mse) if mse else None}
    res["ssim"] = ssim_cs(ya, yb)[0]
    beta = [0.0448, 0.2856, 0.3001, 0.2363, 0.1333]
    ms = 1.0
    for s in range(5):
        ssim, cs = ssim_cs(ya, yb)
        ms *= max(cs if s < 4 else ssim, 0.0) ** beta[s]
        if s < 4:
            h, w = ya.shape[0] // 2 * 2, ya.shape[1] // 2 * 2
            ya = ya[:h, :w].reshape(h // 2, 2, w // 2, 2).mean(axis=(1, 3))
            yb = yb[:h, :w].reshape(h // 2, 2, w // 2, 2).mean(axis=(1, 3))
    res["ms_ssim"] = ms
    print(json.dumps(res))


main()
