// formats.js - the encodings (schemas/encodings.md) and colour files as the
// shader reads them: each decoder checks the layout as vd_enc_load() does
// (sizes tile the file, levels, offsets) and returns the words to upload
// into one R32UI texture plus the uniforms the shader needs.
// Nothing here trusts the file: a bad one throws an Error whose message the
// page shows; the shader's own loop bound keeps a wrong pointer from
// hanging it.

export class FormatError extends Error {}

function fail(name, what) {
  throw new FormatError(`${name}: ${what}`);
}

// The 36-byte common header.
function header(dv, name) {
  if (dv.byteLength < 36) fail(name, `truncated: ${dv.byteLength} bytes, the header alone is 36`);
  const f = (o) => dv.getFloat32(o, true);
  const h = {
    bboxMin: [f(0), f(4), f(8)],
    bboxMax: [f(12), f(16), f(20)],
    rootSide: f(24),
    levels: dv.getUint32(28, true),
    nodeCount: dv.getUint32(32, true),
  };
  for (const v of [...h.bboxMin, ...h.bboxMax, h.rootSide])
    if (!Number.isFinite(v)) fail(name, 'bounding box or root side is not finite');
  if (!(h.rootSide > 0)) fail(name, `root side ${h.rootSide} is not positive`);
  return h;
}

// Where the grid sits in the world, exactly as vd_render_scene_from_enc():
// the centre in float32 like SymVox, then doubles.
function placement(h) {
  const origin = [0, 1, 2].map((a) => {
    const c = Math.fround(Math.fround(0.5 * h.bboxMin[a]) + Math.fround(0.5 * h.bboxMax[a]));
    return c - 0.5 * h.rootSide;
  });
  return { origin, voxelSize: h.rootSide / 2 ** h.levels };
}

// .ssvdag (and .esvdag, the same layout without mirror bits): u16 inner
// nodes, 8-byte bricks, level offsets. Texture words: the inner array as
// u32 (two u16 per word, the lower index in the low half, as the file's
// little-endian bytes), then the bricks, two words each.
function decodeCompact(buf, name, format) {
  const dv = new DataView(buf);
  const h = header(dv, name);
  if (h.levels < 3 || h.levels > 21) fail(name, `levels ${h.levels} not in 3..21`);
  if (dv.byteLength < 40) fail(name, 'truncated before inner_count');
  const n = dv.getUint32(36, true);
  const leafAt = 40 + 2 * n;
  if (leafAt + 4 > dv.byteLength) fail(name, `truncated: ${n} inner words do not fit`);
  const b = dv.getUint32(leafAt, true);
  if (b % 8) fail(name, `leaf_bytes ${b} is not a multiple of 8`);
  const lcAt = leafAt + 4 + b;
  if (lcAt + 4 > dv.byteLength) fail(name, `truncated: ${b} leaf bytes do not fit`);
  const lc = dv.getUint32(lcAt, true);
  if (lc !== h.levels - 2) fail(name, `level_count ${lc}, expected ${h.levels - 2}`);
  const end = lcAt + 4 + 4 * lc;
  if (end > dv.byteLength) fail(name, 'truncated in the level offsets');
  if (end < dv.byteLength) fail(name, `${dv.byteLength - end} trailing bytes`);
  const levelOffsets = [];
  for (let l = 0; l < lc; l++) {
    const o = dv.getUint32(lcAt + 4 + 4 * l, true);
    if ((l === 0 && o !== 0) || (l > 0 && o < levelOffsets[l - 1]) || o > n)
      fail(name, `level offset ${l} (${o}) out of order or beyond ${n}`);
    levelOffsets.push(o);
  }
  if (n < 1) fail(name, 'no root node');
  const innerWords = (n + 1) >> 1;
  // the per-node voxel counts after the bricks, one word per u16 of the
  // inner array (at each node's first u16), filled by voxelCounts()
  const words = new Uint32Array(innerWords + b / 4 + n);
  const src = new Uint8Array(buf);
  // the inner u16 array at byte 40, the bricks after it: copy byte-wise
  // into a fresh buffer (40 + 2n need not be 4-aligned)
  new Uint8Array(words.buffer, 0, 2 * n).set(src.subarray(40, 40 + 2 * n));
  new Uint8Array(words.buffer, 4 * innerWords, b).set(src.subarray(leafAt + 4, leafAt + 4 + b));
  const countBase = innerWords + b / 4;
  const voxels = voxelCounts(name, words, n, innerWords, b / 8, levelOffsets, h.levels, countBase);
  return {
    format,
    name,
    header: h,
    ...placement(h),
    words,
    brickBase: innerWords,
    countBase,
    voxels,
    levelOffsets,
    countedBytes: 2 * n + b + 4 * (h.levels - 2),
    bricks: b / 8,
  };
}

function popcount32(x) {
  x -= (x >>> 1) & 0x55555555;
  x = (x & 0x33333333) + ((x >>> 2) & 0x33333333);
  return (((x + (x >>> 4)) & 0x0f0f0f0f) * 0x01010101) >>> 24;
}

// Voxels below every inner node (colour paper section 3: a voxel's colour
// index is the sum of its preceding siblings' counts along its path; the
// shader sums them). One pass per level from the deepest inner level up:
// a node's children are on the next level (counts already known) or are
// bricks (popcounts). Reflections move voxels, never add any, so a count
// per stored node is enough. Also checks that every pointer lands inside
// its level, so the shader never reads beyond what was checked. Returns
// the root's count: the scene's voxels.
function voxelCounts(name, words, n, innerWords, bricks, levelOffsets, L, countBase) {
  const inner = new Uint16Array(words.buffer, 0, n);
  const brickCount = (a) => popcount32(words[innerWords + 2 * a]) + popcount32(words[innerWords + 2 * a + 1]);
  for (let l = L - 3; l >= 0; l--) {
    const start = levelOffsets[l], end = l + 1 < L - 2 ? levelOffsets[l + 1] : n;
    const nextStart = l + 1 < L - 2 ? levelOffsets[l + 1] : 0;
    const nextEnd = l + 2 < L - 2 ? levelOffsets[l + 2] : n;
    let i = start;
    while (i < end) {
      const h = inner[i];
      if (h === 0 && !(l === 0 && n === 1)) fail(name, `empty node at ${i} on level ${l}`);
      let at = i + 1, sum = 0;
      for (let c = 7; c >= 0; c--) {
        const tag = (h >> (2 * c)) & 3;
        if (!tag) continue;
        let addr;
        if (tag === 1) {
          if (at >= end) fail(name, `node at ${i} on level ${l} runs past its level`);
          addr = inner[at] & 0x1fff;
          at += 1;
        } else {
          if (at + 1 >= end) fail(name, `node at ${i} on level ${l} runs past its level`);
          addr = (((inner[at] << 16) | inner[at + 1]) & 0x1fffffff) + (tag & 1) * 2 ** 29;
          at += 2;
        }
        if (l + 1 < L - 2) {
          if (nextStart + addr >= nextEnd) fail(name, `a pointer of level ${l} leaves level ${l + 1}`);
          sum += words[countBase + nextStart + addr];
        } else {
          if (addr >= bricks) fail(name, `a pointer of level ${l} to brick ${addr} of ${bricks}`);
          sum += brickCount(addr);
        }
      }
      if (sum > 0xffffffff) fail(name, 'more than 2^32 voxels: too large for this viewer');
      words[countBase + i] = sum;
      i = at;
    }
  }
  return words[countBase];
}

export const decoders = {
  ssvdag: (buf, name) => decodeCompact(buf, name, 'ssvdag'),
  esvdag: (buf, name) => decodeCompact(buf, name, 'esvdag'),
};

export function formatOf(path) {
  const m = /\.([a-z0-9]+)$/.exec(path);
  return m && decoders[m[1]] ? m[1] : null;
}
