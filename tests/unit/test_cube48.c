/* test_cube48.c - the 48 cube symmetries: a group (closure, inverses, 48
 * distinct elements, the element orders of the octahedral group), and their
 * action on child indices, 2x2x2 masks and 4x4x4 bricks equal to coordinate
 * arithmetic written here from the header's definition. */
#include "check.h"
#include "voxdag.h"

/* The permutations as the header names them; output axis i takes the
 * input axis named by letter i. */
static const char *names[6] = {"XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"};

/* Point p of an n-cube moved by t, from the definition: permute, then
 * reflect (m bit 2 = X, 1 = Y, 0 = Z). */
static void coord(unsigned t, unsigned n, const unsigned p[3], unsigned q[3])
{
	const char *nm = names[t / 8];
	for (unsigned i = 0; i < 3; i++) {
		q[i] = p[nm[i] - 'X'];
		if (t >> (2 - i) & 1) q[i] = n - 1 - q[i];
	}
}

static unsigned rng_state = 12345;
static uint64_t rnd64(void)
{
	uint64_t v = 0;
	for (int k = 0; k < 4; k++) {
		rng_state = rng_state * 1103515245u + 12345u;
		v = v << 16 | (rng_state >> 8 & 0xffff);
	}
	return v;
}

static void test_child_and_mask(void)
{
	for (unsigned t = 0; t < VD_G48; t++) {
		for (unsigned c = 0; c < 8; c++) {
			unsigned p[3] = {c >> 2 & 1, c >> 1 & 1, c & 1}, q[3];
			coord(t, 2, p, q);
			CHECK_EQ(vd_g48_child(t, c), q[0] << 2 | q[1] << 1 | q[2]);
		}
		for (unsigned v = 0; v < 256; v++) {
			unsigned want = 0;
			for (unsigned c = 0; c < 8; c++)
				if (v >> c & 1) {
					unsigned p[3] = {c >> 2 & 1, c >> 1 & 1,
							 c & 1}, q[3];
					coord(t, 2, p, q);
					want |= 1u << (q[0] << 2 | q[1] << 1 | q[2]);
				}
			CHECK_EQ(vd_g48_mask((uint8_t)v, t), want);
			if (t < 8) CHECK_EQ(vd_g48_mask((uint8_t)v, t),
					    vd_mask_reflect((uint8_t)v, t));
		}
	}
}

/* Local Morton bit of (x, y, z) in a 4^3 brick (the header's layout). */
static unsigned bit4(const unsigned p[3])
{
	return (p[0] >> 1) << 5 | (p[1] >> 1) << 4 | (p[2] >> 1) << 3 |
	       (p[0] & 1) << 2 | (p[1] & 1) << 1 | (p[2] & 1);
}

static void test_brick(void)
{
	for (int round = 0; round < 200; round++) {
		uint64_t v = rnd64();
		if (round < 64) v = 1ull << round; /* every single voxel */
		for (unsigned t = 0; t < VD_G48; t++) {
			uint64_t want = 0;
			for (unsigned x = 0; x < 4; x++)
				for (unsigned y = 0; y < 4; y++)
					for (unsigned z = 0; z < 4; z++) {
						unsigned p[3] = {x, y, z}, q[3];
						if (!(v >> bit4(p) & 1)) continue;
						coord(t, 4, p, q);
						want |= 1ull << bit4(q);
					}
			CHECK(vd_g48_brick(v, t) == want);
			if (t < 8) CHECK(vd_g48_brick(v, t) ==
					 vd_brick_reflect(v, t));
		}
	}
}

static void test_group(void)
{
	/* 48 distinct elements, identity 0. */
	for (unsigned a = 0; a < VD_G48; a++)
		for (unsigned b = a + 1; b < VD_G48; b++) {
			int same = 1;
			for (unsigned c = 0; c < 8; c++)
				same &= vd_g48_child(a, c) == vd_g48_child(b, c);
			CHECK(!same);
		}
	for (unsigned c = 0; c < 8; c++) CHECK_EQ(vd_g48_child(0, c), c);
	/* Closure: compose(a, b) acts as a after b, on the 4-cube's points. */
	for (unsigned a = 0; a < VD_G48; a++)
		for (unsigned b = 0; b < VD_G48; b++) {
			unsigned ab = vd_g48_compose(a, b);
			CHECK(ab < VD_G48);
			for (unsigned i = 0; i < 64; i++) {
				unsigned p[3] = {i >> 4, i >> 2 & 3, i & 3}, q[3],
					 r[3], s[3];
				coord(b, 4, p, q);
				coord(a, 4, q, r);
				coord(ab, 4, p, s);
				CHECK(r[0] == s[0] && r[1] == s[1] && r[2] == s[2]);
			}
		}
	/* Inverses, both sides. */
	for (unsigned t = 0; t < VD_G48; t++) {
		unsigned u = vd_g48_inverse(t);
		CHECK_EQ(vd_g48_compose(t, u), 0);
		CHECK_EQ(vd_g48_compose(u, t), 0);
	}
	/* Orders of O_h: 1 of order 1, 19 of 2, 8 of 3, 12 of 4, 8 of 6. */
	unsigned hist[7] = {0};
	for (unsigned t = 0; t < VD_G48; t++) {
		unsigned x = t, k = 1;
		while (x != 0 && k < 7) x = vd_g48_compose(t, x), k++;
		CHECK(x == 0);
		if (k < 7) hist[k]++;
	}
	CHECK_EQ(hist[1], 1);
	CHECK_EQ(hist[2], 19);
	CHECK_EQ(hist[3], 8);
	CHECK_EQ(hist[4], 12);
	CHECK_EQ(hist[5], 0);
	CHECK_EQ(hist[6], 8);
}

int main(void)
{
	RUN(test_child_and_mask);
	RUN(test_brick);
	RUN(test_group);
	return CHECK_DONE();
}
