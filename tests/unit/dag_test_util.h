/* dag_test_util.h - independent references for the DAG tests: dense voxel
 * grids indexed by (x, y, z), their own Morton arithmetic (bit loops, not
 * the library's), conversion to SVO bricks and back, and brute-force counts
 * of distinct subtrees (optionally up to the 8 reflections) per level. */
#ifndef VD_DAG_TEST_UTIL_H
#define VD_DAG_TEST_UTIL_H

#include "check.h"
#include "voxdag.h"

struct grid {
	int L;
	uint32_t n;   /* 2^L */
	uint8_t *v;   /* n^3 voxels, index (x * n + y) * n + z */
};

static inline uint8_t *gv(struct grid *g, uint32_t x, uint32_t y, uint32_t z)
{
	return &g->v[((size_t)x * g->n + y) * g->n + z];
}

static void grid_init(struct grid *g, int L)
{
	g->L = L;
	g->n = 1u << L;
	g->v = calloc((size_t)g->n * g->n * g->n, 1);
}

static void grid_free(struct grid *g)
{
	free(g->v);
	g->v = NULL;
}

/* xorshift, reproducible across runs */
static uint64_t test_rng = 88172645463325252ULL;
static inline uint64_t rnd(void)
{
	test_rng ^= test_rng << 13;
	test_rng ^= test_rng >> 7;
	test_rng ^= test_rng << 17;
	return test_rng;
}

/* Morton code of (x, y, z), `bits` bits each, x most significant. */
static uint64_t ref_morton(uint32_t x, uint32_t y, uint32_t z, int bits)
{
	uint64_t m = 0;
	for (int i = 0; i < bits; i++)
		m |= (uint64_t)(x >> i & 1) << (3 * i + 2) |
		     (uint64_t)(y >> i & 1) << (3 * i + 1) |
		     (uint64_t)(z >> i & 1) << (3 * i);
	return m;
}

static void ref_unmorton(uint64_t m, int bits, uint32_t *x, uint32_t *y,
			 uint32_t *z)
{
	*x = *y = *z = 0;
	for (int i = 0; i < bits; i++) {
		*x |= (uint32_t)(m >> (3 * i + 2) & 1) << i;
		*y |= (uint32_t)(m >> (3 * i + 1) & 1) << i;
		*z |= (uint32_t)(m >> (3 * i) & 1) << i;
	}
}

/* The SVO of the cell `cell` at level L0 of grid g. */
static void grid_to_svo(const struct grid *g, int L0, uint64_t cell,
			struct vd_svo *s)
{
	int L = g->L, bb = L >= 2 ? L - 2 : 0; /* brick key bits per axis */
	uint32_t nb = 1u << bb;
	uint64_t nbr = (uint64_t)nb * nb * nb;
	uint64_t *dense = calloc(nbr, 8);
	uint32_t cx, cy, cz, side = g->n >> L0;
	ref_unmorton(cell, L0, &cx, &cy, &cz);
	for (uint32_t x = cx * side; x < (cx + 1) * side; x++)
		for (uint32_t y = cy * side; y < (cy + 1) * side; y++)
			for (uint32_t z = cz * side; z < (cz + 1) * side; z++) {
				if (!g->v[((size_t)x * g->n + y) * g->n + z])
					continue;
				uint64_t k = ref_morton(x >> 2, y >> 2, z >> 2, bb);
				dense[k] |= 1ULL << ref_morton(x & 3, y & 3, z & 3, 2);
			}
	memset(s, 0, sizeof *s);
	s->levels = L;
	s->chunk_level = L0;
	s->cell_morton = cell;
	s->keys = malloc(nbr * 8);
	s->masks = malloc(nbr * 8);
	for (uint64_t k = 0; k < nbr; k++)
		if (dense[k]) {
			s->keys[s->count] = k;
			s->masks[s->count++] = dense[k];
		}
	free(dense);
}

static void svo_free(struct vd_svo *s)
{
	free(s->keys);
	free(s->masks);
	memset(s, 0, sizeof *s);
}

/* Adds the voxels of SVO bricks to g (which must be zeroed where they go);
 * returns the number of voxels found already set (a duplicate). */
static uint64_t svo_to_grid(const struct vd_svo *s, struct grid *g)
{
	int bb = g->L >= 2 ? g->L - 2 : 0;
	uint64_t dup = 0;
	for (size_t i = 0; i < s->count; i++) {
		uint32_t bx, by, bz;
		ref_unmorton(s->keys[i], bb, &bx, &by, &bz);
		for (int b = 0; b < 64; b++) {
			if (!(s->masks[i] >> b & 1)) continue;
			uint32_t x, y, z;
			ref_unmorton((uint64_t)b, 2, &x, &y, &z);
			x += 4 * bx;
			y += 4 * by;
			z += 4 * bz;
			if (x >= g->n || y >= g->n || z >= g->n) {
				dup++;
				continue;
			}
			uint8_t *p = gv(g, x, y, z);
			dup += *p;
			*p = 1;
		}
	}
	return dup;
}

static uint64_t grid_count(const struct grid *g)
{
	uint64_t c = 0;
	for (size_t i = 0; i < (size_t)g->n * g->n * g->n; i++) c += g->v[i];
	return c;
}

static int grid_equal(const struct grid *a, const struct grid *b)
{
	return a->L == b->L &&
	       !memcmp(a->v, b->v, (size_t)a->n * a->n * a->n);
}

/* Expands a DAG into a fresh grid and compares with g; returns 1 if equal. */
static int dag_matches_grid(const struct vd_dag *d, const struct grid *g)
{
	struct vd_svo s;
	if (vd_dag_to_svo(d, &s)) return 0;
	for (size_t i = 1; i < s.count; i++)
		if (s.keys[i] <= s.keys[i - 1]) {
			svo_free(&s);
			return 0;
		}
	struct grid h;
	grid_init(&h, g->L);
	uint64_t dup = svo_to_grid(&s, &h);
	int ok = dup == 0 && grid_equal(&h, g);
	svo_free(&s);
	grid_free(&h);
	return ok;
}

/* Content of the subtree at (cx, cy, cz) of side `side`, reflected by m
 * (bit 2 = X, 1 = Y, 0 = Z), as side^3 bits packed into out. Returns 1 if
 * any voxel is set. */
static int subtree_bits(const struct grid *g, uint32_t cx, uint32_t cy,
			uint32_t cz, uint32_t side, unsigned m, uint8_t *out)
{
	size_t bytes = ((size_t)side * side * side + 7) / 8, i = 0;
	int any = 0;
	memset(out, 0, bytes);
	for (uint32_t x = 0; x < side; x++)
		for (uint32_t y = 0; y < side; y++)
			for (uint32_t z = 0; z < side; z++, i++) {
				uint32_t sx = m & 4 ? side - 1 - x : x;
				uint32_t sy = m & 2 ? side - 1 - y : y;
				uint32_t sz = m & 1 ? side - 1 - z : z;
				if (g->v[((size_t)(cx * side + sx) * g->n +
					  cy * side + sy) * g->n + cz * side + sz]) {
					out[i >> 3] |= (uint8_t)(1u << (i & 7));
					any = 1;
				}
			}
	return any;
}

static size_t bf_bytes;
static int bf_cmp(const void *a, const void *b)
{
	return memcmp(a, b, bf_bytes);
}

/* Distinct non-empty subtrees on level l of the cell (L0, cell) of g; with
 * sym, distinct up to the 8 reflections (each subtree is replaced by the
 * largest of its reflections, byte-wise). */
static uint64_t brute_distinct(const struct grid *g, int L0, uint64_t cell,
			       int l, int sym)
{
	uint32_t side = g->n >> l, per = 1u << (l - L0);
	uint32_t cx, cy, cz;
	ref_unmorton(cell, L0, &cx, &cy, &cz);
	size_t bytes = ((size_t)side * side * side + 7) / 8;
	size_t cells = (size_t)per * per * per, n = 0;
	uint8_t *all = malloc(cells * bytes), *tmp = malloc(bytes);
	for (uint32_t x = 0; x < per; x++)
		for (uint32_t y = 0; y < per; y++)
			for (uint32_t z = 0; z < per; z++) {
				uint8_t *dst = all + n * bytes;
				if (!subtree_bits(g, cx * per + x, cy * per + y,
						  cz * per + z, side, 0, dst))
					continue;
				for (unsigned m = 1; sym && m < 8; m++) {
					subtree_bits(g, cx * per + x, cy * per + y,
						     cz * per + z, side, m, tmp);
					if (memcmp(tmp, dst, bytes) > 0)
						memcpy(dst, tmp, bytes);
				}
				n++;
			}
	bf_bytes = bytes;
	qsort(all, n, bytes, bf_cmp);
	uint64_t d = 0;
	for (size_t i = 0; i < n; i++)
		if (!i || memcmp(all + i * bytes, all + (i - 1) * bytes, bytes))
			d++;
	free(all);
	free(tmp);
	return d;
}

/* Test scenes. */
enum { SC_RANDOM, SC_SPARSE, SC_SHELL, SC_PLANES, SC_FULL, SC_ONE,
       SC_TILES, SC_SYMXY, SC_COUNT };
static const char *scene_name[SC_COUNT] = {
	"random", "sparse", "shell", "planes", "full", "one", "tiles", "symxy"};

static void make_scene(struct grid *g, int L, int sc)
{
	grid_init(g, L);
	uint32_t n = g->n;
	for (uint32_t x = 0; x < n; x++)
		for (uint32_t y = 0; y < n; y++)
			for (uint32_t z = 0; z < n; z++) {
				uint8_t v = 0;
				double dx = x - (n - 1) / 2.0, dy = y - (n - 1) / 2.0,
				       dz = z - (n - 1) / 2.0;
				double r2 = dx * dx + dy * dy + dz * dz, R = n * 0.4;
				switch (sc) {
				case SC_RANDOM: v = rnd() % 3 == 0; break;
				case SC_SPARSE: v = rnd() % 61 == 0; break;
				case SC_SHELL:
					v = r2 <= R * R && r2 >= (R - 1.5) * (R - 1.5);
					break;
				case SC_PLANES: v = x == n / 3 || y == 2 * n / 3 ||
						    x + z == n; break;
				case SC_FULL: v = 1; break;
				case SC_ONE: v = x == n / 2 && y == n / 3 && z == 1;
					break;
				default: break;
				}
				*gv(g, x, y, z) = v;
			}
	if (sc == SC_TILES || sc == SC_SYMXY) {
		/* Tiles of side t, each empty or a random reflection of one of
		 * three random patterns: much sharing up to symmetry. For
		 * SC_SYMXY t is 8 and every pattern is invariant under X and Y
		 * mirrored together but (almost surely) under nothing else, an
		 * invariance that per-axis bits cannot express. */
		uint32_t t = sc == SC_TILES ? 4 : 8;
		if (t > n) t = n;
		uint8_t pat[3][512];
		for (int p = 0; p < 3; p++)
			for (uint32_t x = 0; x < t; x++)
				for (uint32_t y = 0; y < t; y++)
					for (uint32_t z = 0; z < t; z++) {
						uint8_t v = rnd() % 4 == 0;
						if (sc == SC_SYMXY && x >= t / 2)
							continue; /* set as a mirror */
						pat[p][(x * t + y) * t + z] = v;
						if (sc == SC_SYMXY && x < t / 2)
							pat[p][((t - 1 - x) * t + t - 1 - y) * t + z] = v;
					}
		for (uint32_t bx = 0; bx < n / t; bx++)
			for (uint32_t by = 0; by < n / t; by++)
				for (uint32_t bz = 0; bz < n / t; bz++) {
					int p = (int)(rnd() % 4);
					unsigned m = (unsigned)(rnd() % 8);
					if (p == 3) continue;
					for (uint32_t x = 0; x < t; x++)
						for (uint32_t y = 0; y < t; y++)
							for (uint32_t z = 0; z < t; z++) {
								uint32_t sx = m & 4 ? t - 1 - x : x;
								uint32_t sy = m & 2 ? t - 1 - y : y;
								uint32_t sz = m & 1 ? t - 1 - z : z;
								*gv(g, bx * t + x, by * t + y, bz * t + z) =
									pat[p][(sx * t + sy) * t + sz];
							}
				}
	}
}

#endif
