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

// The 36-byte common header of `buf` with levels in minLevels..21.
function start(buf, name, minLevels) {
  const dv = new DataView(buf);
  const h = header(dv, name);
  if (h.levels < minLevels || h.levels > 21) fail(name, `levels ${h.levels} not in ${minLevels}..21`);
  return { dv, h };
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

// What every decoder returns: the format, the file's name and header,
// the grid's placement, the texture words, and the layout's own fields.
function described(format, name, h, words, layout) {
  return { format, name, header: h, ...placement(h), words, ...layout };
}

// .ssvdag (and .esvdag, the same layout without mirror bits): u16 inner
// nodes, 8-byte bricks, level offsets. Texture words: the inner array as
// u32 (two u16 per word, the lower index in the low half, as the file's
// little-endian bytes), then the bricks, two words each.
function decodeCompact(buf, name, format) {
  const { dv, h } = start(buf, name, 3);
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
  // .ssvdag48: then the cube group's composition table, 48 x 48 words
  const g48 = format === 'ssvdag48';
  const words = new Uint32Array(innerWords + b / 4 + n + (g48 ? 48 * 48 : 0));
  const src = new Uint8Array(buf);
  // the inner u16 array at byte 40, the bricks after it: copy byte-wise
  // into a fresh buffer (40 + 2n need not be 4-aligned)
  new Uint8Array(words.buffer, 0, 2 * n).set(src.subarray(40, 40 + 2 * n));
  new Uint8Array(words.buffer, 4 * innerWords, b).set(src.subarray(leafAt + 4, leafAt + 4 + b));
  const countBase = innerWords + b / 4;
  const voxels = voxelCounts(name, words, n, innerWords, b / 8, levelOffsets, h.levels, countBase, g48);
  if (g48) words.set(cubeComposition(), countBase + n);
  return described(format, name, h, words, {
    brickBase: innerWords,
    countBase,
    compBase: countBase + n,
    voxels,
    levelOffsets,
    countedBytes: 2 * n + b + 4 * (h.levels - 2),
    bricks: b / 8,
  });
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
function voxelCounts(name, words, n, innerWords, bricks, levelOffsets, L, countBase, g48) {
  // pointers (schemas/encodings.md): 13 + 3 or 29 + 3 bits, .ssvdag48
  // 10 + 6 or 26 + 6 bits with transforms below 48
  const abits = g48 ? 10 : 13, lbits = g48 ? 26 : 29;
  const inner = new Uint16Array(words.buffer, 0, n);
  const brickCount = (a) => popcount32(words[innerWords + 2 * a]) + popcount32(words[innerWords + 2 * a + 1]);
  // exact counts (a double holds any count up to 2^53); the texture's
  // u32 words saturate, and only colours need them (colours of more than
  // 2^32 voxels are refused when loaded)
  const exact = new Float64Array(n);
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
          addr = inner[at] & ((1 << abits) - 1);
          if (g48 && inner[at] >>> abits >= 48) fail(name, `transform ${inner[at] >>> abits} >= 48 at ${at}`);
          at += 1;
        } else {
          if (at + 1 >= end) fail(name, `node at ${i} on level ${l} runs past its level`);
          const v = ((inner[at] << 16) | inner[at + 1]) >>> 0;
          addr = (v & ((1 << lbits) - 1)) + (tag & 1) * 2 ** lbits;
          if (g48 && v >>> lbits >= 48) fail(name, `transform ${v >>> lbits} >= 48 at ${at}`);
          at += 2;
        }
        if (l + 1 < L - 2) {
          if (nextStart + addr >= nextEnd) fail(name, `a pointer of level ${l} leaves level ${l + 1}`);
          sum += exact[nextStart + addr];
        } else {
          if (addr >= bricks) fail(name, `a pointer of level ${l} to brick ${addr} of ${bricks}`);
          sum += brickCount(addr);
        }
      }
      exact[i] = sum;
      words[countBase + i] = Math.min(sum, 0xffffffff);
      i = at;
    }
  }
  return exact[0];
}

// .svdag and .ussvdag: 32-bit words, a header word (child mask, and for
// .ussvdag the mirror bits per child at 8/16/24 for X/Y/Z) then absolute
// pointers, highest child first; level L-1 nodes are one mask word.
// Texture words: the file's words, then a voxel count per word (at each
// node's header), filled by one depth-first walk that also checks every
// pointer lands after its parent and inside the file.
function decodeWords(buf, name, format) {
  const { dv, h } = start(buf, name, 1);
  if (dv.byteLength < 44) fail(name, 'truncated before the words');
  const w = dv.getUint32(40, true);
  if (44 + 4 * w > dv.byteLength) fail(name, `truncated: ${w} words do not fit`);
  if (44 + 4 * w < dv.byteLength) fail(name, `${dv.byteLength - 44 - 4 * w} trailing bytes`);
  if (w < 1) fail(name, 'no root node');
  if (h.levels < 2) fail(name, 'a scene of one 2x2x2 node: nothing to view');
  const words = new Uint32Array(2 * w);
  new Uint8Array(words.buffer, 0, 4 * w).set(new Uint8Array(buf, 44, 4 * w));
  const L = h.levels, plain = format === 'svdag';
  const done = new Uint8Array(w);
  const exact = new Float64Array(w); // as in voxelCounts: words saturate
  const count = (at, level) => {
    if (done[at]) return exact[at];
    const hw = words[at], mask = hw & 0xff;
    if (!mask && !(at === 0 && w === 1)) fail(name, `empty node at word ${at}`);
    let sum = 0;
    if (level === L - 1) {
      if (hw >>> 8) fail(name, `bits above the mask of leaf word ${at}`);
      for (let c = 0; c < 8; c++) sum += (mask >> c) & 1;
    } else {
      if (plain && hw >>> 8) fail(name, `mirror bits in the plain header at word ${at}`);
      let k = 1;
      for (let c = 7; c >= 0; c--) {
        if (!((mask >> c) & 1)) continue;
        const pi = at + k++;
        if (pi >= w) fail(name, `node at word ${at} runs past the file`);
        const child = words[pi];
        if (child <= pi || child >= w) fail(name, `pointer at word ${pi} out of order or beyond the file`);
        sum += count(child, level + 1);
      }
    }
    done[at] = 1;
    exact[at] = sum;
    words[w + at] = Math.min(sum, 0xffffffff);
    return sum;
  };
  const voxels = count(0, 0);
  return described(format, name, h, words, {
    brickBase: 0,
    countBase: w,
    levelOffsets: [],
    voxels,
    countedBytes: 4 * w,
  });
}

// The 48 cube symmetries, t = 8k + m (vd_dag.h, "Cube group"): output
// axis i takes input axis PERM[k][i], then the axes of m mirrored (bit 2
// X, bit 1 Y, bit 0 Z) in an n-cube.
const PERM = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]];
function cubeApply(t, p, n) {
  const k = t >> 3, m = t & 7;
  const q = [p[PERM[k][0]], p[PERM[k][1]], p[PERM[k][2]]];
  for (let i = 0; i < 3; i++) if ((m >> (2 - i)) & 1) q[i] = n - 1 - q[i];
  return q;
}

// comp[48 a + t]: the transform p -> a(t(p)), found by its action on the
// 2-cube's corners (which tell the 48 apart).
function cubeComposition() {
  const corners = [...Array(8).keys()].map((c) => [(c >> 2) & 1, (c >> 1) & 1, c & 1]);
  const key = (f) => corners.map((p) => f(p).join('')).join(',');
  const byKey = new Map([...Array(48).keys()].map((c) => [key((p) => cubeApply(c, p, 2)), c]));
  const comp = new Uint32Array(48 * 48);
  for (let a = 0; a < 48; a++)
    for (let t = 0; t < 48; t++) comp[48 * a + t] = byKey.get(key((p) => cubeApply(a, cubeApply(t, p, 2), 2)));
  return comp;
}

export const decoders = {
  ssvdag: (buf, name) => decodeCompact(buf, name, 'ssvdag'),
  esvdag: (buf, name) => decodeCompact(buf, name, 'esvdag'),
  ssvdag48: (buf, name) => decodeCompact(buf, name, 'ssvdag48'),
  svdag: (buf, name) => decodeWords(buf, name, 'svdag'),
  ussvdag: (buf, name) => decodeWords(buf, name, 'ussvdag'),
};

// 0: compact (16-bit nodes, bricks), 1: 32-bit words; the shader's uFormat
export const layoutOf = (scene) => (scene.format === 'svdag' || scene.format === 'ussvdag' ? 1 : 0);

export function formatOf(path) {
  const m = /\.([a-z0-9]+)$/.exec(path);
  return m && decoders[m[1]] ? m[1] : null;
}
