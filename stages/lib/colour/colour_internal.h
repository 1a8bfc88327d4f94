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

static inline void vd_auto_decode(uint32_t e, const uint8_t *d, uint32_t n,
				  uint32_t j, uint8_t rgb[3])
{
	unsigned mode = e >> 24, b = mode & 15;
	switch (mode >> 4) {
	case VD_AUTO_CONST >> 4:
		rgb[0] = (uint8_t)e;
		rgb[1] = (uint8_t)(e >> 8);
		rgb[2] = (uint8_t)(e >> 16);
		return;
	case VD_AUTO_PALETTE >> 4: {
		unsigned k = d[0] + 1u;
		unsigned x = vd_auto_bits(d + 1 + 3 * k, (uint64_t)j * b, b);
		memcpy(rgb, d + 1 + 3 * x, 3);
		return;
	}
	case VD_AUTO_ENDPOINTS >> 4: {
		/* d[0]: log2 of the part length, bit 4 RGB565 endpoints (4
		 * bytes a part) instead of RGB8 (6); the parts' endpoint
		 * pairs; the weights */
		unsigned m = (1u << b) - 1, len = d[0] & 15;
		unsigned esz = d[0] & 16 ? 4 : 6;
		unsigned parts = (n + (1u << len) - 1) >> len;
		const uint8_t *ep = d + 1 + esz * (j >> len);
		uint8_t c0[3], c1[3];
		if (esz == 4) {
			vd_rgb565_decode((uint16_t)(ep[0] | ep[1] << 8), c0);
			vd_rgb565_decode((uint16_t)(ep[2] | ep[3] << 8), c1);
		} else {
			memcpy(c0, ep, 3);
			memcpy(c1, ep + 3, 3);
		}
		unsigned w = vd_auto_bits(d + 1 + esz * parts, (uint64_t)j * b, b);
		for (int c = 0; c < 3; c++)
			rgb[c] = (uint8_t)(((uint64_t)(c0[c] * (m - w) + c1[c] * w +
						       m / 2) * vd_auto_recip[b]) >> 32);
		return;
	}
	case VD_AUTO_QUANT >> 4: {
		unsigned wr = d[4] & 15, wg = d[4] >> 4, wb = d[5] & 15;
		unsigned wsum = wr + wg + wb;
		uint32_t q = vd_auto_bits(d + 6, (uint64_t)j * wsum, wsum);
		unsigned qv[3] = {q & ((1u << wr) - 1),
				  q >> wr & ((1u << wg) - 1),
				  q >> (wr + wg) & ((1u << wb) - 1)};
		for (int c = 0; c < 3; c++) {
			unsigned v = d[c] + qv[c] * d[3];
			rgb[c] = (uint8_t)(v > 255 ? 255 : v);
		}
		return;
	}
	default: /* VD_AUTO_RAW */
		memcpy(rgb, d + 3 * (size_t)j, 3);
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
	default:
		return 3 * (size_t)n;
	}
}

#endif /* VD_COLOUR_INTERNAL_H */
