// shader.js - the fragment shader that ray casts a compact encoding
// (.ssvdag, .esvdag) straight from its words, a port of vd_render_trace()
// (stages/lib/render/render.c) in float: the same octree DDA with a stack
// of (address, reflection) per level, the same "pop to the deepest level
// holding the next cell" step, the same decisions by plane times
// tp(a, k) = (k - o[a]) * inv[a]. Doubles there, floats here: the two
// agree except where a ray passes within float rounding of a voxel edge
// (tests/viewer/ counts those pixels).
//
// Two outputs per pixel when ID is defined: RGBA32UI (x, y, z, level) of
// the hit cell, all 0xffffffff on a miss, as render --voxel-id writes; and
// RGBA32UI (depth bits, 1 on a hit, 0, 0). Without ID: a shaded colour.

export const vertexSource = `#version 300 es
in vec2 aPos;
void main() { gl_Position = vec4(aPos, 0.0, 1.0); }
`;

export function fragmentSource(ids) {
  return `#version 300 es
precision highp float;
precision highp int;
precision highp usampler2D;
${ids ? '#define ID 1' : ''}
uniform usampler2D uData;
uniform int uTexWidthLog2;
uniform int uL;          // levels
uniform int uCut;        // hit cells of this level (uL: voxels)
uniform float uLod;      // level of detail: a node of side S voxels whose
                         // S <= uLod * t (its projection at most the
                         // chosen pixels) is hit whole, as render --lod
uniform uint uLevelOff[22];
uniform uint uBrickBase; // word index of the first brick
uniform uint uCountBase; // word index of the voxel counts
uniform int uFormat;     // 0: compact (.ssvdag, .esvdag), 1: words (.svdag, .ussvdag)
uniform int uG48;        // .ssvdag48: a reflection is one of the 48 cube symmetries
uniform uint uCompBase;  // .ssvdag48: word index of the 48 x 48 composition table
uniform sampler2D uColours; // the colour array, 4096 wide (RGB)
uniform int uHasColours;
uniform int uShade;      // 0: the voxel's colour as it is (tests)
uniform vec3 uEye;       // grid coordinates
uniform vec3 uFwd, uRight, uUp; // unit, world
uniform float uInvVs;    // 1 / voxel size
uniform float uTanHalf, uAspect;
uniform vec2 uSize;      // image size in pixels
uniform vec3 uLightDir;
uniform vec2 uOffset;    // this view's lower-left pixel in the canvas
#ifdef ID
layout(location = 0) out uvec4 outId;
layout(location = 1) out uvec4 outDepth;
#else
out vec4 outColour;
#endif

uint word(uint i) {
  return texelFetch(uData, ivec2(int(i & ((1u << uTexWidthLog2) - 1u)), int(i >> uTexWidthLog2)), 0).r;
}
uint u16at(uint i) {
  uint w = word(i >> 1);
  return (i & 1u) == 0u ? (w & 0xffffu) : (w >> 16);
}
// SymVox mirror bits (bit 0 X, 1 Y, 2 Z) to ours (4 X, 2 Y, 1 Z)
uint mirror(uint m) { return (m >> 2 & 1u) | (m & 2u) | (m & 1u) << 2; }

// GLSL ES 3.00 has neither bitCount nor findMSB
uint popcount16(uint x) {
  x = x - ((x >> 1) & 0x5555u);
  x = (x & 0x3333u) + ((x >> 2) & 0x3333u);
  x = (x + (x >> 4)) & 0x0f0fu;
  return (x + (x >> 8)) & 0x1fu;
}
// exact for 0 < x < 2^24: the exponent of float(x)
int msb(int x) { return int(floatBitsToUint(float(x)) >> 23) - 127; }

// The cube symmetry t = 8k + m (formats.js, vd_dag.h): q[i] = p[PERM[k][i]],
// then the axes of m mirrored. Its inverse on a point q of an n-cube:
const ivec3 PERM[6] = ivec3[6](ivec3(0, 1, 2), ivec3(0, 2, 1), ivec3(1, 0, 2),
                               ivec3(1, 2, 0), ivec3(2, 0, 1), ivec3(2, 1, 0));
uvec3 cubeUnapply(uint t, uvec3 q, uint n) {
  if ((t & 4u) != 0u) q.x = n - 1u - q.x;
  if ((t & 2u) != 0u) q.y = n - 1u - q.y;
  if ((t & 1u) != 0u) q.z = n - 1u - q.z;
  ivec3 k = PERM[t >> 3];
  uvec3 p;
  p[k.x] = q.x;
  p[k.y] = q.y;
  p[k.z] = q.z;
  return p;
}

// The stored child slot of logical slot p in a node seen through refl.
uint storedSlot(uint refl, uint p) {
  if (uG48 == 0) return (p ^ refl) & 7u;
  uvec3 s = cubeUnapply(refl, uvec3(p >> 2 & 1u, p >> 1 & 1u, p & 1u), 2u);
  return s.x << 2 | s.y << 1 | s.z;
}

// The reflection (transform) of a child reached through t from refl.
uint compose(uint refl, uint t) {
  if (uG48 == 0) return refl ^ t;
  return texelFetch(uData, ivec2(int((uCompBase + 48u * refl + t) & ((1u << uTexWidthLog2) - 1u)),
                                 int((uCompBase + 48u * refl + t) >> uTexWidthLog2)), 0).r;
}

float INF() { return uintBitsToFloat(0x7f800000u); }
float tp(vec3 o, vec3 inv, int a, int k) { return (float(k) - o[a]) * inv[a]; }

uint stackAt[22];
uint stackRefl[22];
uint brickLo, brickHi, brickRefl;

uint popcount32(uint x) {
  x = x - ((x >> 1) & 0x55555555u);
  x = (x & 0x33333333u) + ((x >> 2) & 0x33333333u);
  return (((x + (x >> 4)) & 0x0f0f0f0fu) * 0x01010101u) >> 24;
}

bool brickVoxel(uvec3 v) { // logical coordinates in the current brick
  if (uG48 != 0) {
    v = cubeUnapply(brickRefl, v, 4u);
  } else {
    if ((brickRefl & 4u) != 0u) v.x = 3u - v.x;
    if ((brickRefl & 2u) != 0u) v.y = 3u - v.y;
    if ((brickRefl & 1u) != 0u) v.z = 3u - v.z;
  }
  uint bit = 16u * v.x + 4u * v.y + v.z;
  uint w = bit >= 32u ? brickHi : brickLo;
  return (w >> (bit & 31u) & 1u) != 0u;
}

uint popcount8(uint x) { return popcount16(x & 0xffu); }

// .svdag/.ussvdag: the child pointer of stored slot s of the node at "at"
// (header h) and its mirror bits in our order.
uint wordChild(uint at, uint h, uint s, out uint m) {
  m = (h >> (8u + s) & 1u) << 2 | (h >> (16u + s) & 1u) << 1 | (h >> (24u + s) & 1u);
  return word(at + popcount8((h & 0xffu) >> s));
}

bool childSet(int level, uint p, ivec3 clo) {
  if (uFormat == 1) {
    uint s = (p ^ stackRefl[level]) & 7u;
    return (word(stackAt[level]) >> s & 1u) != 0u;
  }
  if (level < uL - 2) {
    uint h = u16at(stackAt[level]);
    uint s = storedSlot(stackRefl[level], p);
    return (h >> (2u * s) & 3u) != 0u;
  }
  if (level == uL - 2) {
    uint s = storedSlot(brickRefl, p);
    uint w = (s & 4u) != 0u ? brickHi : brickLo;
    uint by = s >> 1 & 1u, bz = s & 1u;
    return (w & (0x00330033u << (8u * by + 2u * bz))) != 0u;
  }
  return brickVoxel(uvec3(clo & 3));
}

// The pointer of stored slot s (present) of the node at "at" with header
// h: the address relative to the child's level, *m our reflection bits.
uint pointerAt(uint at, uint h, uint s, out uint m) {
  uint lo = h & 0x5555u, hi = h >> 1 & 0x5555u;
  uint above = 0xffffu << (2u * s + 2u) & 0xffffu;
  uint off = at + 1u + popcount16((lo | hi) & above) + popcount16(hi & above);
  uint tag = h >> (2u * s) & 3u;
  if (uG48 != 0) { // 10 + 6 or 26 + 6 bits, the transform as it is
    if (tag == 1u) {
      uint w = u16at(off);
      m = w >> 10;
      return w & 0x3ffu;
    }
    uint v = u16at(off) << 16 | u16at(off + 1u);
    m = v >> 26;
    return (v & 0x3ffffffu) | (tag & 1u) << 26;
  }
  if (tag == 1u) {
    uint w = u16at(off);
    m = mirror(w >> 13);
    return w & 0x1fffu;
  }
  uint v = u16at(off) << 16 | u16at(off + 1u);
  m = mirror(v >> 29);
  return (v & 0x1fffffffu) | (tag & 1u) << 29;
}

void descend(int level, uint p) {
  uint at = stackAt[level], refl = stackRefl[level];
  if (uFormat == 1) {
    uint m;
    stackAt[level + 1] = wordChild(at, word(at), (p ^ refl) & 7u, m);
    stackRefl[level + 1] = refl ^ m;
    return;
  }
  uint s = storedSlot(refl, p);
  uint m;
  uint addr = pointerAt(at, u16at(at), s, m);
  uint crefl = compose(refl, m);
  if (level + 1 < uL - 2) {
    stackAt[level + 1] = uLevelOff[level + 1] + addr;
    stackRefl[level + 1] = crefl;
  } else {
    brickLo = word(uBrickBase + 2u * addr);
    brickHi = word(uBrickBase + 2u * addr + 1u);
    brickRefl = crefl;
  }
}

// The colour index of the first voxel of the hit cell (cell on the
// 2^lev grid): the voxels of the preceding logical siblings summed down
// its path (vd_voxcount_index), counts read at the stored nodes.
uint colourIndex(ivec3 cell, int lev) {
  int L = uL;
  ivec3 v = cell << (L - lev);
  uint idx = 0u, at = 0u, refl = 0u;
  if (uFormat == 1) {
    for (int level = 0; level < lev; level++) {
      int sh = L - level - 1;
      uint p = uint((v.x >> sh & 1) << 2 | (v.y >> sh & 1) << 1 | (v.z >> sh & 1));
      uint h = word(at), m;
      if (level == L - 1) { // the leaf mask: its voxels before p
        for (uint q = 0u; q < p; q++) idx += h >> ((q ^ refl) & 7u) & 1u;
        break;
      }
      for (uint q = 0u; q < p; q++) {
        uint s = (q ^ refl) & 7u;
        if ((h >> s & 1u) == 0u) continue;
        idx += word(uCountBase + wordChild(at, h, s, m));
      }
      at = wordChild(at, h, (p ^ refl) & 7u, m);
      refl ^= m;
    }
    return idx;
  }
  int top = min(lev, L - 2);
  for (int level = 0; level < top; level++) {
    int sh = L - level - 1;
    uint p = uint((v.x >> sh & 1) << 2 | (v.y >> sh & 1) << 1 | (v.z >> sh & 1));
    uint h = u16at(at);
    for (uint q = 0u; q < p; q++) {
      uint s = storedSlot(refl, q);
      if ((h >> (2u * s) & 3u) == 0u) continue;
      uint m;
      uint a = pointerAt(at, h, s, m);
      if (level + 1 < L - 2) idx += word(uCountBase + uLevelOff[level + 1] + a);
      else idx += popcount32(word(uBrickBase + 2u * a)) + popcount32(word(uBrickBase + 2u * a + 1u));
    }
    uint m;
    uint a = pointerAt(at, h, storedSlot(refl, p), m);
    refl = compose(refl, m);
    if (level + 1 < L - 2) {
      at = uLevelOff[level + 1] + a;
    } else {
      brickLo = word(uBrickBase + 2u * a);
      brickHi = word(uBrickBase + 2u * a + 1u);
      brickRefl = refl;
    }
  }
  if (lev > L - 2) { // inside the brick: its set voxels before v in Morton order
    uvec3 lv = uvec3(v & 3);
    uint mv = (lv.x >> 1) << 5 | (lv.y >> 1) << 4 | (lv.z >> 1) << 3 | (lv.x & 1u) << 2 | (lv.y & 1u) << 1 | (lv.z & 1u);
    for (uint k = 0u; k < mv; k++) {
      uvec3 u = uvec3((k >> 5 & 1u) << 1 | (k >> 2 & 1u), (k >> 4 & 1u) << 1 | (k >> 1 & 1u), (k >> 3 & 1u) << 1 | (k & 1u));
      if (brickVoxel(u)) idx++;
    }
  }
  return idx;
}

// Returns true on a hit: cell on the 2^hitLevel grid, entry time (world
// units), the face axis (-1: started inside).
bool trace(vec3 o, vec3 d, out ivec3 cell, out int hitLevel, out float tHit, out int axis) {
  int L = uL;
  int N = 1 << L;
  vec3 inv = vec3(0.0);
  ivec3 dir = ivec3(0);
  ivec3 fo = ivec3(0);
  float t = 0.0;
  for (int a = 0; a < 3; a++) {
    if (d[a] != 0.0 && !isinf(1.0 / d[a])) {
      dir[a] = d[a] > 0.0 ? 1 : -1;
      inv[a] = 1.0 / d[a];
      t = max(t, tp(o, inv, a, dir[a] > 0 ? 0 : N));
    } else {
      float f = floor(o[a]);
      if (!(f >= 0.0 && f < float(N))) return false;
      fo[a] = int(f);
    }
  }
  float tend = INF();
  for (int a = 0; a < 3; a++)
    if (dir[a] != 0) tend = min(tend, tp(o, inv, a, dir[a] > 0 ? N : 0));
  if (!(t < tend)) return false;
  int level = 0;
  ivec3 lo = ivec3(0);
  stackAt[0] = 0u;
  stackRefl[0] = 0u;
  // a bound only against a runaway loop (a GPU watchdog resets the page):
  // a ray crossing a 2^16 scene along a floor of single voxels visits tens
  // of thousands of empty nodes, and a ray cut short would be a wrong miss
  for (int iter = 0; iter < 262144; iter++) {
    int half_ = 1 << (L - level - 1);
    uint p = 0u;
    ivec3 clo;
    for (int a = 0; a < 3; a++) {
      int mid = lo[a] + half_;
      bool up = dir[a] > 0 ? tp(o, inv, a, mid) <= t :
                dir[a] < 0 ? tp(o, inv, a, mid) > t : fo[a] >= mid;
      p |= uint(up) << (2 - a);
      clo[a] = up ? mid : lo[a];
    }
    if (childSet(level, p, clo)) {
      if (level + 1 >= uCut || float(half_) <= uLod * t) {
        float tin = -INF();
        int ax = -1;
        for (int a = 0; a < 3; a++) {
          if (dir[a] == 0) continue;
          float near = tp(o, inv, a, dir[a] > 0 ? clo[a] : clo[a] + half_);
          if (near > tin) { tin = near; ax = a; }
        }
        if (tin < 0.0) { tHit = 0.0; axis = -1; } else { tHit = tin; axis = ax; }
        cell = clo >> (L - level - 1);
        hitLevel = level + 1;
        return true;
      }
      if (level < L - 2 || (uFormat == 1 && level < L - 1)) descend(level, p);
      level++;
      lo = clo;
      continue;
    }
    vec3 far = vec3(INF());
    float tx = INF();
    for (int a = 0; a < 3; a++) {
      if (dir[a] != 0) far[a] = tp(o, inv, a, dir[a] > 0 ? clo[a] + half_ : clo[a]);
      tx = min(tx, far[a]);
    }
    if (isinf(tx)) return false;
    int diff = 0;
    ivec3 nc = clo;
    for (int a = 0; a < 3; a++) {
      if (far[a] == tx) {
        nc[a] = dir[a] > 0 ? clo[a] + half_ : clo[a] - 1;
        if (nc[a] < 0 || nc[a] >= N) return false;
        diff |= nc[a] ^ clo[a];
      }
    }
    int nl = L - msb(diff) - 1;
    level = min(level, nl);
    int cmask = ~((1 << (L - level)) - 1);
    lo = nc & cmask;
    t = tx;
  }
  return false;
}

void main() {
  vec2 px = gl_FragCoord.xy - uOffset; // x from the left, y from the bottom
  // render's pixel (x, ytop) centre: u = 2(x+0.5)/W - 1, v = 1 - 2(ytop+0.5)/H
  float u = (2.0 * px.x / uSize.x - 1.0) * uTanHalf * uAspect;
  float v = (2.0 * px.y / uSize.y - 1.0) * uTanHalf;
  vec3 dw = normalize(uFwd + u * uRight + v * uUp);
  vec3 dg = dw * uInvVs;
  ivec3 cell; int lev; float th; int axis;
  bool hit = trace(uEye, dg, cell, lev, th, axis);
#ifndef ID
  // render's normal from the depth buffer, from this pixel's quad partner
  // (derivatives here, in uniform flow): the surface, not the voxel
  // staircase, whose faces alias into moire once voxels are smaller than
  // pixels. A partner more than 4 cells or pixels away in depth is another
  // surface: then the hit face's normal.
  float tq = hit ? th : 1e30;
  vec3 hp = uEye + dg * tq;
  vec3 ex = dFdx(hp), ey = dFdy(hp);
  float dtx = abs(dFdx(tq)), dty = abs(dFdy(tq));
#endif
#ifdef ID
  if (hit) {
    outId = uvec4(uvec3(cell), uint(lev));
    outDepth = uvec4(floatBitsToUint(th), 1u, 0u, 0u);
  } else {
    outId = uvec4(0xffffffffu);
    outDepth = uvec4(floatBitsToUint(INF()), 0u, 0u, 0u);
  }
#else
  if (!hit) { outColour = vec4(0.12, 0.13, 0.16, 1.0); return; }
  vec3 n = vec3(0.0);
  if (axis >= 0) n[axis] = dg[axis] > 0.0 ? -1.0 : 1.0; else n = -dw;
  float cellSide = float(1 << (uL - lev)) / uInvVs;
  float limit = 4.0 * max(cellSide, th * 2.0 * uTanHalf / uSize.y);
  vec3 ns = cross(ex, ey);
  if (dtx < limit && dty < limit && dot(ns, ns) > 0.0) {
    n = normalize(ns);
    if (dot(n, dw) > 0.0) n = -n;
  }
  vec3 base = vec3(0.82, 0.76, 0.66); // render's grey (linear)
  if (uHasColours != 0) {
    uint i = colourIndex(cell, lev);
    vec3 srgb = texelFetch(uColours, ivec2(int(i & 4095u), int(i >> 12)), 0).rgb;
    if (uShade == 0) { outColour = vec4(srgb, 1.0); return; }
    base = pow(srgb, vec3(2.2));
  }
  float lambert = max(dot(n, normalize(uLightDir)), 0.0);
  float sky = 0.5 + 0.5 * n.y;
  vec3 c = base * (0.10 + 0.12 * sky + 0.80 * lambert);
  outColour = vec4(pow(c, vec3(1.0 / 2.2)), 1.0);
#endif
}
`;
}
