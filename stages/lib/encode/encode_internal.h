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

/* The compact pointers of every compact format, with `abits` address
 * bits in the 16-bit form and `lbits` in the 32-bit one (plus the tag
 * bit), the remaining high bits holding `code` (the mirror bits or the
 * transform): writes 1 or 2 uint16 words to out[] (the high half first)
 * and returns the 2-bit header tag (01: 16-bit, 10/11: 32-bit whose low
 * tag bit is address bit lbits). The word count is 1 for tag 1, else 2. */
static inline unsigned vd__enc_pack_bits(uint32_t addr, unsigned code,
					 unsigned abits, unsigned lbits,
					 uint16_t out[2])
{
	if (addr < (1u << abits)) {
		out[0] = (uint16_t)(addr | code << abits);
		return 1;
	}
	uint32_t v = (addr & ((1u << lbits) - 1)) | (uint32_t)code << lbits;
	out[0] = (uint16_t)(v >> 16);
	out[1] = (uint16_t)v;
	return 2 | (addr >> lbits & 1);
}

/* Inverse of vd__enc_pack_bits for tag 1..3: the address and *code. */
static inline uint32_t vd__enc_unpack_bits(unsigned tag, const uint16_t *w,
					   unsigned abits, unsigned lbits,
					   unsigned *code)
{
	if (tag == 1) {
		*code = w[0] >> abits;
		return w[0] & ((1u << abits) - 1);
	}
	uint32_t v = (uint32_t)w[0] << 16 | w[1];
	*code = v >> lbits;
	return (v & ((1u << lbits) - 1)) | (uint32_t)(tag & 1) << lbits;
}

/* .esvdag/.ssvdag: 13 + 3 or 29 + 3 bits, our reflection m stored as
 * SymVox mirror bits; addresses below 2^30. */
static inline unsigned vd__enc_pack_ptr(uint32_t addr, unsigned m,
					uint16_t out[2])
{
	return vd__enc_pack_bits(addr, vd__enc_mirror(m), 13, 29, out);
}

static inline uint32_t vd__enc_unpack_ptr(unsigned tag, const uint16_t *w,
					  unsigned *m)
{
	uint32_t a = vd__enc_unpack_bits(tag, w, 13, 29, m);
	*m = vd__enc_mirror(*m);
	return a;
}

/* .ssvdag48 pointers (schemas/encodings.md): the transform t (0..47, the
 * numbering of vd_dag.h's "Cube group") takes 6 bits, so a 16-bit pointer
 * keeps 10 address bits and a 32-bit one 26, plus the tag bit: addresses
 * below 2^27. The reader refuses t of 48..63. */
#define VD__ENC48_MAX_ADDRESS (1ull << 27)

static inline unsigned vd__enc_pack_ptr48(uint32_t addr, unsigned t,
					  uint16_t out[2])
{
	return vd__enc_pack_bits(addr, t, 10, 26, out);
}

static inline uint32_t vd__enc_unpack_ptr48(unsigned tag, const uint16_t *w,
					    unsigned *t)
{
	return vd__enc_unpack_bits(tag, w, 10, 26, t);
}

/* A brick in our Morton layout (bit morton3(x, y, z)) as the SymVox leaf
 * (bit 16x + 4y + z), and back. */
uint64_t vd__enc_brick_to_symvox(uint64_t morton_brick);
uint64_t vd__enc_brick_from_symvox(uint64_t symvox_brick);

#endif
