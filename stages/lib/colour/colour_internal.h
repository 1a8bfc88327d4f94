/* colour_internal.h - what colour/'s files share and users of the library
 * do not need. Not installed. */
#ifndef VD_COLOUR_INTERNAL_H
#define VD_COLOUR_INTERNAL_H

#include "vd_colour.h"

#include <string.h>

/* One segment in the palette format before its block palettes are shared:
 * block b covers start[b].., its palette is the sorted global indices
 * pal[pal_first[b] .. pal_first[b+1]) (pal_first has count+1 entries), each
 * voxel an offset into it (offsets[i] for voxel i, unpacked here). */
struct vd_palette_segment {
	uint32_t n, count;
	uint32_t *start;
	uint32_t *pal_first;
	uint32_t *pal;
	uint32_t *offsets;
	uint64_t sse;
	unsigned max_dist2;
};
int vd_palette_encode(struct vd_palette_segment *s, const uint8_t *rgb,
		      uint32_t n, const struct vd_palette *p);
void vd_palette_segment_release(struct vd_palette_segment *s);

/* The auto method's one decode rule (schemas/colour-formats.md, method
 * 4), shared by the reader and the encoder's own check: colour j of the
 * block whose directory entry is `e` and whose bytes start at `d` (unused
 * for a constant block). Reads at most 4 bytes from any bit position, so
 * the buffer holding the blocks must have VD_AUTO_PAD readable bytes past
 * its end. Corrupt bytes decode to some colour, never outside the block:
 * the reader checks the blocks' sizes and palette indices when it opens
 * the file, and QUANT clamps to 255. */
static inline uint32_t vd_auto_bits(const uint8_t *d, uint64_t pos,
				    unsigned width)
{
	const uint8_t *p = d + (pos >> 3);
	uint32_t v = (uint32_t)p[0] | (uint32_t)p[1] << 8 |
		     (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
	return (v >> (pos & 7)) & ((1u << width) - 1);
}

/* x / (2^w - 1) for x < 2^16 as (x * R[w]) >> 32, exactly (R = floor(2^32
 * / m) + 1 errs by less than x / 2^32 < 1/m): a lookup's three divisions
 * cost more than the rest of it. */
static const uint64_t vd_auto_recip[9] = {
	0, 0x100000001ull, 0x55555556ull, 0x24924925ull, 0x11111112ull,
	0x8421085ull, 0x4104105ull, 0x2040811ull, 0x1010102ull};

/* A part's endpoint pair at ep: RGB565 (esz 4 bytes) or RGB8 (6). */
static inline void vd_auto_endpoints(const uint8_t *ep, unsigned esz,
				     uint8_t c0[3], uint8_t c1[3])
{
	if (esz == 4) {
		vd_rgb565_decode((uint16_t)(ep[0] | ep[1] << 8), c0);
		vd_rgb565_decode((uint16_t)(ep[2] | ep[3] << 8), c1);
	} else {
		memcpy(c0, ep, 3);
		memcpy(c1, ep + 3, 3);
	}
}

/* A quantized voxel's colour: its packed steps q (wr bits of red, wg of
 * green, the rest blue: vd_auto_bits gives no more bits than the three
 * widths) from the block's base colour d[0..3) by step d[3], clamped to
 * 255. */
static inline void vd_auto_quant(const uint8_t *d, unsigned wr, unsigned wg,
				 uint32_t q, uint8_t rgb[3])
{
	unsigned qv[3] = {q & ((1u << wr) - 1), q >> wr & ((1u << wg) - 1),
			  q >> (wr + wg)};
	for (int c = 0; c < 3; c++) {
		unsigned v = d[c] + qv[c] * d[3];
		rgb[c] = (uint8_t)(v > 255 ? 255 : v);
	}
}

/* Where a block's bits are, from its header: the offset of the voxels'
 * bits from the block's first byte (bits 0-15), the bits a voxel (16-20),
 * for the endpoints mode log2 of the part length (21-24) and 1 for RGB565
 * endpoints (25); 0 for a constant or coded block. The reader keeps it
 * beside each directory entry (4 bytes a block), so that a lookup finds
 * the voxel's bits without reading the header first: the two cache
 * misses (header, bits) are independent, not one after the other. */
static inline uint32_t vd_auto_layout(uint32_t e, const uint8_t *d,
				      uint32_t n)
{
	unsigned mode = e >> 24, b = mode & 15;
	switch (mode >> 4) {
	case VD_AUTO_PALETTE >> 4:
		return (1 + 3 * (d[0] + 1u)) | b << 16;
	case VD_AUTO_ENDPOINTS >> 4: {
		unsigned len = d[0] & 15, esz = d[0] & 16 ? 4 : 6;
		unsigned parts = (n + (1u << len) - 1) >> len;
		return (1 + esz * parts) | b << 16 | len << 21 |
		       (uint32_t)(esz == 4) << 25;
	}
	case VD_AUTO_QUANT >> 4:
		return 6 | (unsigned)((d[4] & 15) + (d[4] >> 4) + (d[5] & 15)) << 16;
	case VD_AUTO_RAW >> 4:
		return 24u << 16;
	default:
		return 0;
	}
}

/* vd_auto_decode with the block's layout (vd_auto_layout) given. */
static inline void vd_auto_decode_laid(uint32_t e, uint32_t lay,
				       const uint8_t *d, uint32_t j,
				       uint8_t rgb[3])
{
	unsigned mode = e >> 24, b = mode & 15;
	const uint8_t *bits = d + (lay & 0xffff);
	unsigned bpv = lay >> 16 & 31;
	switch (mode >> 4) {
	case VD_AUTO_CONST >> 4:
		rgb[0] = (uint8_t)e;
		rgb[1] = (uint8_t)(e >> 8);
		rgb[2] = (uint8_t)(e >> 16);
		return;
	case VD_AUTO_PALETTE >> 4: {
		unsigned x = vd_auto_bits(bits, (uint64_t)j * b, b);
		memcpy(rgb, d + 1 + 3 * x, 3);
		return;
	}
	case VD_AUTO_ENDPOINTS >> 4: {
		/* d[0]: log2 of the part length, bit 4 RGB565 endpoints (4
		 * bytes a part) instead of RGB8 (6); the parts' endpoint
		 * pairs; the weights */
		unsigned m = (1u << b) - 1, len = lay >> 21 & 15;
		unsigned esz = lay >> 25 & 1 ? 4 : 6;
		uint8_t c0[3], c1[3];
		vd_auto_endpoints(d + 1 + esz * (j >> len), esz, c0, c1);
		unsigned w = vd_auto_bits(bits, (uint64_t)j * b, b);
		for (int c = 0; c < 3; c++)
			rgb[c] = (uint8_t)(((uint64_t)(c0[c] * (m - w) + c1[c] * w +
						       m / 2) * vd_auto_recip[b]) >> 32);
		return;
	}
	case VD_AUTO_QUANT >> 4:
		vd_auto_quant(d, d[4] & 15, d[4] >> 4,
			      vd_auto_bits(bits, (uint64_t)j * bpv, bpv), rgb);
		return;
	default: /* VD_AUTO_RAW */
		memcpy(rgb, d + 3 * (size_t)j, 3);
	}
}

static inline void vd_auto_decode(uint32_t e, const uint8_t *d, uint32_t n,
				  uint32_t j, uint8_t rgb[3])
{
	vd_auto_decode_laid(e, vd_auto_layout(e, d, n), d, j, rgb);
}

/* Every colour of a block that is not coded (entry e, bytes at d, n
 * voxels) into rgb[0 .. 3n): vd_auto_decode's rule, with the mode's
 * header read once a block (a part, for the endpoints) instead of once a
 * voxel. The encoder's check of the block it keeps and the reader's range
 * decoding. */
static inline void vd_auto_decode_all(uint32_t e, const uint8_t *d,
				      uint32_t n, uint8_t *rgb)
{
	unsigned mode = e >> 24, b = mode & 15;
	switch (mode >> 4) {
	case VD_AUTO_CONST >> 4:
		for (uint32_t j = 0; j < n; j++) {
			rgb[3 * j] = (uint8_t)e;
			rgb[3 * j + 1] = (uint8_t)(e >> 8);
			rgb[3 * j + 2] = (uint8_t)(e >> 16);
		}
		return;
	case VD_AUTO_PALETTE >> 4: {
		unsigned k = d[0] + 1u;
		const uint8_t *idx = d + 1 + 3 * k;
		for (uint32_t j = 0; j < n; j++)
			memcpy(rgb + 3 * j,
			       d + 1 + 3 * vd_auto_bits(idx, (uint64_t)j * b, b), 3);
		return;
	}
	case VD_AUTO_ENDPOINTS >> 4: {
		unsigned m = (1u << b) - 1, len = d[0] & 15;
		unsigned esz = d[0] & 16 ? 4 : 6;
		unsigned parts = (n + (1u << len) - 1) >> len;
		const uint8_t *wb = d + 1 + esz * parts;
		uint64_t r = vd_auto_recip[b];
		for (uint32_t q = 0, j = 0; q < parts; q++) {
			uint8_t c0[3], c1[3];
			vd_auto_endpoints(d + 1 + esz * q, esz, c0, c1);
			uint32_t end = (q + 1) << len < n ? (q + 1) << len : n;
			for (; j < end; j++) {
				unsigned w = vd_auto_bits(wb, (uint64_t)j * b, b);
				for (int c = 0; c < 3; c++)
					rgb[3 * j + c] = (uint8_t)(((uint64_t)(
						c0[c] * (m - w) + c1[c] * w + m / 2) * r) >> 32);
			}
		}
		return;
	}
	case VD_AUTO_QUANT >> 4: {
		unsigned wr = d[4] & 15, wg = d[4] >> 4, wb = d[5] & 15;
		unsigned wsum = wr + wg + wb;
		for (uint32_t j = 0; j < n; j++)
			vd_auto_quant(d, wr, wg, vd_auto_bits(d + 6, (uint64_t)j *
							      wsum, wsum),
				      rgb + 3 * j);
		return;
	}
	default: /* VD_AUTO_RAW */
		memcpy(rgb, d, 3 * (size_t)n);
	}
}

/* Bytes of a block of n voxels after its directory entry (mode `e >> 24`,
 * header bytes at `d`): 0 for a constant one. The reader's check and the
 * encoder's layout. */
static inline size_t vd_auto_block_bytes(uint32_t e, const uint8_t *d,
					 uint32_t n)
{
	unsigned mode = e >> 24, b = mode & 15;
	switch (mode >> 4) {
	case VD_AUTO_CONST >> 4:
		return 0;
	case VD_AUTO_PALETTE >> 4:
		return 1 + 3 * (d[0] + 1u) + ((size_t)n * b + 7) / 8;
	case VD_AUTO_ENDPOINTS >> 4:
		return 1 + (d[0] & 16 ? 4 : 6) *
			       (size_t)((n + (1u << (d[0] & 15)) - 1) >> (d[0] & 15)) +
		       ((size_t)n * b + 7) / 8;
	case VD_AUTO_QUANT >> 4:
		return 6 + ((size_t)n * ((d[4] & 15) + (d[4] >> 4) +
					 (d[5] & 15)) + 7) / 8;
	case VD_AUTO_CODED >> 4:
		return 5 + (size_t)(d[0] | d[1] << 8);
	default:
		return 3 * (size_t)n;
	}
}


/* ---- the coded mode (format 1.2, lossless): a block's colours as
 * symbols of its segment's canonical Huffman code. After the block's
 * first voxel (3 bytes), each step is one symbol of alphabet A:
 *   0..19   a run: the previous colour repeated vd_auto_run[s] times;
 *   20..34  a hit: the colour at position 1..15 of the list of the
 *           block's last VD_AUTO_RECENT distinct colours, most recent
 *           first (position 0 is the previous colour: runs);
 *   35..290 a delta from the previous voxel in the decorrelated space
 *           y = (G, R - G, B - G) mod 256: dy0 = s - 35, then dy1 as one
 *           symbol of alphabet B and dy2 of alphabet C.
 * A is coded in one of three contexts (below); B and C have one code.
 * Why: textured scenes are noisy but neighbours in Morton order are close
 * (deltas of few bits), few-colour areas alternate between a handful of
 * colours (hits), flat ones repeat (runs: a Huffman code spends at least
 * a bit a symbol, so a voxel a symbol would cost a bit a voxel); one code
 * per segment fits each scene's statistics, which zstd learns across the
 * array and a per-block mode cannot. */
#define VD_AUTO_RECENT 16
#define VD_AUTO_RUNS 20
#define VD_AUTO_HIT0 VD_AUTO_RUNS                        /* 20: position 1 */
#define VD_AUTO_DELTA0 (VD_AUTO_RUNS + VD_AUTO_RECENT - 1) /* 35 */
#define VD_AUTO_SYM_A (VD_AUTO_DELTA0 + 256)             /* 291 */
/* A has one code per context, the kind of the previous step: 0 after a
 * run, 1 after a hit, 2 after a delta or at the block's start (a run is
 * seldom followed by another, a hit often by a hit) */
#define VD_AUTO_CTX 3
#define VD_AUTO_SYM_B (VD_AUTO_CTX * VD_AUTO_SYM_A)      /* 873 */
#define VD_AUTO_SYMS (VD_AUTO_SYM_B + 512)               /* 1385 */
#define VD_AUTO_TABLE_BYTES ((VD_AUTO_SYMS + 1) / 2)     /* 693 */
#define VD_AUTO_ALPHABETS (VD_AUTO_CTX + 2)
#define VD_AUTO_MAXLEN 11

static const uint16_t vd_auto_run[VD_AUTO_RUNS] = {
	1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 32, 64, 128, 256};

/* Decode tables of one segment: per alphabet, for every 11-bit window of
 * the stream (LSB first), symbol << 4 | code length (0: no code). */
struct vd_auto_code {
	uint16_t t[VD_AUTO_ALPHABETS][1 << VD_AUTO_MAXLEN];
};

/* Builds c from the table's VD_AUTO_TABLE_BYTES bytes (symbol i's length
 * in nibble i, low nibble first; A's symbols, then B's, then C's).
 * Returns 0, or -1 when a length exceeds VD_AUTO_MAXLEN or an alphabet's
 * lengths over-fill the code space. */
int vd_auto_code_build(struct vd_auto_code *c, const uint8_t *tab);

static inline uint32_t vd_auto_peek(const uint8_t *d, uint64_t pos)
{
	const uint8_t *p = d + (pos >> 3);
	uint64_t v;
	memcpy(&v, p, 8); /* the data keeps VD_AUTO_PAD bytes after it */
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
	v = __builtin_bswap64(v);
#endif
	return (uint32_t)(v >> (pos & 7)) & ((1u << VD_AUTO_MAXLEN) - 1);
}

/* A coded block's decoder between two steps: voxels 0 .. i-1 decoded,
 * cur the colour of voxel i - 1, pos the bits of the stream read, the
 * recent colours as a ring (position q at ring[(h + q) & 15]: a delta,
 * the common step of noisy textures, inserts in O(1)), ctx the context of
 * the next symbol of alphabet A. The reader keeps one every
 * VD_AUTO_RESTART voxels of each coded block (a restart point), so that a
 * lookup decodes at most that many voxels, not the block from its start:
 * memory only, the file is unchanged. */
#define VD_AUTO_RESTART 64
struct vd_auto_coded_state {
	uint32_t ring[VD_AUTO_RECENT];
	uint32_t cur, pos, i;
	uint8_t h, nr, ctx;
};

static inline void vd_auto_coded_start(const uint8_t *d,
				       struct vd_auto_coded_state *st)
{
	st->cur = (uint32_t)d[2] | (uint32_t)d[3] << 8 | (uint32_t)d[4] << 16;
	st->ring[0] = st->cur;
	st->pos = 0;
	st->i = 1;
	st->h = 0;
	st->nr = 1;
	st->ctx = 2;
}

/* The decoder's state, as vd_auto_coded_run keeps it between voxels. */
static inline void vd_auto_coded_save(struct vd_auto_coded_state *o,
				      const uint32_t *ring, uint32_t cur,
				      uint64_t pos, uint32_t i, uint32_t h,
				      uint32_t nr, unsigned ctx)
{
	memcpy(o->ring, ring, sizeof o->ring);
	o->cur = cur;
	o->pos = (uint32_t)pos;
	o->i = i;
	o->h = (uint8_t)h;
	o->nr = (uint8_t)nr;
	o->ctx = (uint8_t)ctx;
}

/* Decodes the coded block at d (u16 stream bytes S, R, G, B of voxel 0,
 * the stream) from state st on until voxel j is decoded (st->i > j), and
 * puts its colour in rgb; st is left at the state after that step, so a
 * later voxel of the block can go on from it (vd_auto_coded_resume
 * below leaves its state as it was). Returns
 * the bits of the stream read, or -1 for a symbol with no code, a hit
 * past the list, or (when all != NULL) a run past voxel j. With all set,
 * every colour decoded goes to all[3 st->i ..]. With snap set, the state
 * when it first reaches voxel k * VD_AUTO_RESTART (1 <= k, k
 * VD_AUTO_RESTART <= j) goes to snap[k - 1] (a run across several such
 * voxels fills each of them). */
static inline int64_t vd_auto_coded_run(const struct vd_auto_code *c,
					const uint8_t *d,
					struct vd_auto_coded_state *st,
					uint32_t j, uint8_t rgb[3],
					uint8_t *all,
					struct vd_auto_coded_state *snap)
{
	uint32_t ring[VD_AUTO_RECENT], nr = st->nr, h = st->h;
	uint32_t cur = st->cur, i = st->i;
	memcpy(ring, st->ring, sizeof ring);
	const uint8_t *s = d + 5;
	uint64_t pos = st->pos;
	unsigned ctx = st->ctx;
	uint32_t next = snap ? ((i + VD_AUTO_RESTART - 1) / VD_AUTO_RESTART
				+ (i == 0)) * VD_AUTO_RESTART : UINT32_MAX;
	for (;;) {
		while (i >= next && next <= j) {
			vd_auto_coded_save(snap + next / VD_AUTO_RESTART - 1, ring,
					   cur, pos, i, h, nr, ctx);
			next += VD_AUTO_RESTART;
		}
		if (i > j)
			break;
		uint32_t e = c->t[ctx][vd_auto_peek(s, pos)];
		if (!(e & 15))
			return -1;
		pos += e & 15;
		uint32_t a = e >> 4;
		if (a < VD_AUTO_RUNS) {
			uint32_t run = vd_auto_run[a];
			if (all) {
				if (run > j + 1 - i)
					return -1;
				for (uint32_t q = i; q < i + run; q++) {
					all[3 * q] = (uint8_t)cur;
					all[3 * q + 1] = (uint8_t)(cur >> 8);
					all[3 * q + 2] = (uint8_t)(cur >> 16);
				}
			}
			i += run;
			ctx = 0;
			continue;
		}
		if (a < VD_AUTO_DELTA0) {
			a -= VD_AUTO_HIT0 - 1;
			if (a >= nr)
				return -1;
			cur = ring[(h + a) & (VD_AUTO_RECENT - 1)];
			for (; a; a--)
				ring[(h + a) & (VD_AUTO_RECENT - 1)] =
					ring[(h + a - 1) & (VD_AUTO_RECENT - 1)];
			ring[h] = cur;
			ctx = 1;
		} else {
			uint32_t e1 = c->t[VD_AUTO_CTX][vd_auto_peek(s, pos)];
			pos += e1 & 15;
			uint32_t e2 = c->t[VD_AUTO_CTX + 1][vd_auto_peek(s, pos)];
			pos += e2 & 15;
			if (!(e1 & 15) || !(e2 & 15))
				return -1;
			unsigned r = cur & 255, g = cur >> 8 & 255, b = cur >> 16;
			unsigned g2 = (g + a - VD_AUTO_DELTA0) & 255;
			unsigned r2 = (g2 + ((r - g + (e1 >> 4)) & 255)) & 255;
			unsigned b2 = (g2 + ((b - g + (e2 >> 4)) & 255)) & 255;
			cur = r2 | g2 << 8 | b2 << 16;
			nr += nr < VD_AUTO_RECENT;
			h = (h - 1) & (VD_AUTO_RECENT - 1);
			ring[h] = cur;
			ctx = 2;
		}
		if (all) {
			all[3 * i] = (uint8_t)cur;
			all[3 * i + 1] = (uint8_t)(cur >> 8);
			all[3 * i + 2] = (uint8_t)(cur >> 16);
		}
		i++;
	}
	rgb[0] = (uint8_t)cur;
	rgb[1] = (uint8_t)(cur >> 8);
	rgb[2] = (uint8_t)(cur >> 16);
	vd_auto_coded_save(st, ring, cur, pos, i, h, nr, ctx);
	return (int64_t)pos;
}

/* vd_auto_coded_run from a copy of st: st stays as it was (a restart
 * point the reader keeps). */
static inline int64_t vd_auto_coded_resume(const struct vd_auto_code *c,
					   const uint8_t *d,
					   const struct vd_auto_coded_state *st,
					   uint32_t j, uint8_t rgb[3],
					   uint8_t *all,
					   struct vd_auto_coded_state *snap)
{
	struct vd_auto_coded_state t = *st;
	return vd_auto_coded_run(c, d, &t, j, rgb, all, snap);
}

/* Colour of voxel j of the coded block at d into rgb, decoding from the
 * block's start (vd_auto_coded_resume from the start state). The reader
 * runs every block through this once with j = n - 1 and all set (every
 * voxel's colour, 3 bytes each, goes to all[0..3(j+1))) and compares the
 * bits with S. */
static inline int64_t vd_auto_coded_decode(const struct vd_auto_code *c,
					   const uint8_t *d, uint32_t j,
					   uint8_t rgb[3], uint8_t *all)
{
	struct vd_auto_coded_state st;
	vd_auto_coded_start(d, &st);
	if (all)
		memcpy(all, d + 2, 3);
	return vd_auto_coded_resume(c, d, &st, j, rgb, all, NULL);
}

#endif /* VD_COLOUR_INTERNAL_H */
