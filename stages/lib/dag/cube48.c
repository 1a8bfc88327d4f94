/* cube48.c - the 48 symmetries of the cube (6 axis permutations times 8
 * reflections) as a small table: composition, inverse, and their action on
 * child indices, 2x2x2 masks and 4x4x4 bricks. The conventions are in
 * vd_dag.h ("Cube group"). */
#include "voxdag.h"

/* Axis permutations: output axis i (0 = X, 1 = Y, 2 = Z) takes input axis
 * perm[k][i]. Index 0 is the identity. */
static const uint8_t perm[6][3] = {
	{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0},
};

static unsigned perm_index(unsigned a0, unsigned a1, unsigned a2)
{
	for (unsigned k = 0; k < 6; k++)
		if (perm[k][0] == a0 && perm[k][1] == a1 && perm[k][2] == a2)
			return k;
	return 0; /* unreachable for a permutation */
}

/* Reflection bit of axis i in a 3-bit reflection m: X is bit 2, Z bit 0. */
static unsigned rbit(unsigned m, unsigned axis)
{
	return m >> (2 - axis) & 1;
}

const uint8_t *vd_g48_perm(unsigned t)
{
	return perm[t / 8 % 6];
}

unsigned vd_g48_child(unsigned t, unsigned c)
{
	const uint8_t *p = perm[t / 8];
	unsigned m = t & 7, out = 0;
	for (unsigned i = 0; i < 3; i++) {
		unsigned bit = (c >> (2 - p[i]) & 1) ^ rbit(m, i);
		out |= bit << (2 - i);
	}
	return out;
}

unsigned vd_g48_compose(unsigned a, unsigned b)
{
	const uint8_t *pa = perm[a / 8], *pb = perm[b / 8];
	unsigned ma = a & 7, mb = b & 7, m = 0, q[3];
	for (unsigned i = 0; i < 3; i++) {
		q[i] = pb[pa[i]];
		m |= (rbit(ma, i) ^ rbit(mb, pa[i])) << (2 - i);
	}
	return perm_index(q[0], q[1], q[2]) * 8 + m;
}

unsigned vd_g48_inverse(unsigned t)
{
	for (unsigned u = 0; u < VD_G48; u++)
		if (vd_g48_compose(t, u) == 0) return u;
	return 0; /* unreachable: the 48 form a group */
}

uint8_t vd_g48_mask(uint8_t v, unsigned t)
{
	unsigned out = 0;
	for (unsigned c = 0; c < 8; c++)
		if (v >> c & 1) out |= 1u << vd_g48_child(t, c);
	return (uint8_t)out;
}

uint64_t vd_g48_brick(uint64_t v, unsigned t)
{
	uint8_t map[8];
	for (unsigned c = 0; c < 8; c++) map[c] = (uint8_t)vd_g48_child(t, c);
	uint64_t out = 0;
	for (unsigned c = 0; c < 8; c++) {
		uint8_t b = (uint8_t)(v >> (8 * c));
		if (!b) continue;
		unsigned o = 0;
		for (unsigned k = 0; k < 8; k++)
			if (b >> k & 1) o |= 1u << map[k];
		out |= (uint64_t)o << (8 * map[c]);
	}
	return out;
}
