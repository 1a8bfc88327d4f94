/* encode_internal.h - what encode.c shares with its tests: the address
 * limits (lowered by tests to reach the range errors without gigabytes),
 * the pointer packing of the compact formats and the brick bit orders. Not
 * part of the public API. */
#ifndef VD_ENCODE_INTERNAL_H
#define VD_ENCODE_INTERNAL_H

#include "voxdag.h"

/* Compact formats: a child address must be below this (2^30: 29 pointer
 * bits plus the tag bit); the number of bricks must be below
 * vd__enc_max_bricks (leaf_bytes = 8 * bricks is a uint32). Word formats:
 * at most vd__enc_max_words words (word indices are uint32). Tests lower
 * these; nothing else writes them. */
extern uint64_t vd__enc_max_address;
extern uint64_t vd__enc_max_bricks;
extern uint64_t vd__enc_max_words;

/* Our reflection m (bit 2 = X, 1 = Y, 0 = Z) as SymVox mirror bits
 * (bit 0 = X, 1 = Y, 2 = Z), and back: the bits reversed. */
static inline unsigned vd__enc_mirror(unsigned m)
{
	return (m >> 2 & 1) | (m & 2) | (m & 1) << 2;
}

/* Packs a compact child pointer to address `addr` (< 2^30) with our
 * reflection m: writes 1 or 2 uint16 words to out[] and returns the 2-bit
 * header tag (01: 16-bit, 10/11: 32-bit whose low tag bit is address bit
 * 29). The word count is 1 for tag 1, else 2. */
static inline unsigned vd__enc_pack_ptr(uint32_t addr, unsigned m,
					uint16_t out[2])
{
	unsigned mir = vd__enc_mirror(m);
	if (addr < (1u << 13)) {
		out[0] = (uint16_t)(addr | mir << 13);
		return 1;
	}
	uint32_t v = (addr & ((1u << 29) - 1)) | (uint32_t)mir << 29;
	out[0] = (uint16_t)(v >> 16);
	out[1] = (uint16_t)v;
	return 2 | (addr >> 29 & 1);
}

/* Inverse of vd__enc_pack_ptr for tag 1..3: the address and our
 * reflection. */
static inline uint32_t vd__enc_unpack_ptr(unsigned tag, const uint16_t *w,
					  unsigned *m)
{
	if (tag == 1) {
		*m = vd__enc_mirror(w[0] >> 13);
		return w[0] & ((1u << 13) - 1);
	}
	uint32_t v = (uint32_t)w[0] << 16 | w[1];
	*m = vd__enc_mirror(v >> 29);
	return (v & ((1u << 29) - 1)) | (uint32_t)(tag & 1) << 29;
}

/* .ssvdag48 pointers (schemas/encodings.md): the transform t (0..47, the
 * numbering of voxdag.h's "Cube group") takes 6 bits, so a 16-bit pointer
 * keeps 10 address bits and a 32-bit one 26, plus the tag bit: addresses
 * below 2^27. Same tags as vd__enc_pack_ptr. */
#define VD__ENC48_MAX_ADDRESS (1ull << 27)

static inline unsigned vd__enc_pack_ptr48(uint32_t addr, unsigned t,
					  uint16_t out[2])
{
	if (addr < (1u << 10)) {
		out[0] = (uint16_t)(addr | t << 10);
		return 1;
	}
	uint32_t v = (addr & ((1u << 26) - 1)) | (uint32_t)t << 26;
	out[0] = (uint16_t)(v >> 16);
	out[1] = (uint16_t)v;
	return 2 | (addr >> 26 & 1);
}

/* Inverse of vd__enc_pack_ptr48: the address and the transform (0..63:
 * the reader refuses 48..63). */
static inline uint32_t vd__enc_unpack_ptr48(unsigned tag, const uint16_t *w,
					    unsigned *t)
{
	if (tag == 1) {
		*t = w[0] >> 10;
		return w[0] & ((1u << 10) - 1);
	}
	uint32_t v = (uint32_t)w[0] << 16 | w[1];
	*t = v >> 26;
	return (v & ((1u << 26) - 1)) | (uint32_t)(tag & 1) << 26;
}

/* A brick in our Morton layout (bit morton3(x, y, z)) as the SymVox leaf
 * (bit 16x + 4y + z), and back. */
uint64_t vd__enc_brick_to_symvox(uint64_t morton_brick);
uint64_t vd__enc_brick_from_symvox(uint64_t symvox_brick);

#endif
