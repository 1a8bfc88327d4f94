/* le.h - little-endian loads and stores, the one set every file format of
 * the library uses (chunk files, encodings, colour chunks, images).
 * Internal: not installed.
 *
 * On a little-endian host each is one unaligned load or store (memcpy of
 * a fixed size, which GCC and Clang compile to a single mov); elsewhere
 * the bytes are assembled lowest first. Hot loops rely on that: decoding
 * the bricks of an SVO chunk and writing the encodings' references. */
#ifndef VD_LE_H
#define VD_LE_H

#include <stdint.h>
#include <string.h>

#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
#define VD_LE_HOST 1
#else
#define VD_LE_HOST 0
#endif

static inline void le_put16(uint8_t *p, uint16_t v)
{
	if (VD_LE_HOST) {
		memcpy(p, &v, 2);
		return;
	}
	p[0] = (uint8_t)v;
	p[1] = (uint8_t)(v >> 8);
}

static inline void le_put32(uint8_t *p, uint32_t v)
{
	if (VD_LE_HOST) {
		memcpy(p, &v, 4);
		return;
	}
	for (int i = 0; i < 4; i++)
		p[i] = (uint8_t)(v >> 8 * i);
}

static inline void le_put64(uint8_t *p, uint64_t v)
{
	if (VD_LE_HOST) {
		memcpy(p, &v, 8);
		return;
	}
	for (int i = 0; i < 8; i++)
		p[i] = (uint8_t)(v >> 8 * i);
}

static inline uint16_t le_get16(const uint8_t *p)
{
	return (uint16_t)(p[0] | p[1] << 8);
}

static inline uint32_t le_get32(const uint8_t *p)
{
	if (VD_LE_HOST) {
		uint32_t v;
		memcpy(&v, p, 4);
		return v;
	}
	return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 |
	       (uint32_t)p[3] << 24;
}

static inline uint64_t le_get64(const uint8_t *p)
{
	if (VD_LE_HOST) {
		uint64_t v;
		memcpy(&v, p, 8);
		return v;
	}
	return (uint64_t)le_get32(p) | (uint64_t)le_get32(p + 4) << 32;
}

/* IEEE float32 and float64 by their bits. */
static inline void le_putf32(uint8_t *p, float f)
{
	uint32_t v;
	memcpy(&v, &f, 4);
	le_put32(p, v);
}

static inline void le_putf64(uint8_t *p, double f)
{
	uint64_t v;
	memcpy(&v, &f, 8);
	le_put64(p, v);
}

static inline float le_getf32(const uint8_t *p)
{
	uint32_t v = le_get32(p);
	float f;
	memcpy(&f, &v, 4);
	return f;
}

static inline double le_getf64(const uint8_t *p)
{
	uint64_t v = le_get64(p);
	double f;
	memcpy(&f, &v, 8);
	return f;
}

#endif /* VD_LE_H */
