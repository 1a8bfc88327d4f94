/* g48_count - an exact count, independent of the builders, of the nodes of
 * the minimal SVDAG, SSVDAG and 48-group DAG of a scene (issue 13's "node
 * counts equal an independent exact count"): decodes a root chunk (any of
 * dag, ssvdag, ssvdag48) to voxels, and on every level hashes each
 * non-empty subtree's voxel set moved by each transform of the group (1, 8
 * or 48, by coordinate arithmetic written here from the header's
 * definition, not cube48.c's tables), keeps the smallest hash as the
 * class's name, and counts distinct names. The hash of a set is a pair of
 * sums of two 64-bit mixes of its voxels' indices (order-free, so no sort;
 * a false merge needs a 128-bit collision).
 *
 * usage: g48_count ROOT_CHUNK
 * prints: classes svdag=N ssvdag=N g48=N (summed over the levels) */
#include "voxdag.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* output axis i takes input axis names[k][i]; t = 8k + m, then axis i is
 * mirrored when bit 2 - i of m is set */
static const char *const names[6] = {"XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"};

static inline uint64_t mix(uint64_t x, uint64_t k)
{
	x += k;
	x ^= x >> 31;
	x *= 0x7fb5d329728ea185ULL;
	x ^= x >> 27;
	x *= 0x81dadef4bc2dd44dULL;
	x ^= x >> 33;
	return x;
}

struct name {
	uint64_t a, b;
};

static int name_cmp(const void *x, const void *y)
{
	const struct name *p = x, *q = y;
	if (p->a != q->a) return p->a < q->a ? -1 : 1;
	if (p->b != q->b) return p->b < q->b ? -1 : 1;
	return 0;
}

/* a voxel: its Morton code (sort key) and x << 42 | y << 21 | z */
struct vox {
	uint64_t morton, xyz;
};

struct sink {
	struct vox *v;
	size_t n, cap;
	int L;
};

static uint64_t spread(uint64_t v, int L)
{
	uint64_t m = 0;
	for (int i = 0; i < L; i++) m |= (v >> i & 1) << (3 * i);
	return m;
}

static int add(void *ctx, uint64_t key, uint64_t brick)
{
	struct sink *s = ctx;
	uint32_t bx, by, bz;
	vd_morton3_decode(key, &bx, &by, &bz);
	for (unsigned b = 0; b < 64; b++) {
		if (!(brick >> b & 1)) continue;
		uint32_t x, y, z;
		vd_morton3_decode(b, &x, &y, &z);
		if (s->n == s->cap) {
			s->cap = s->cap ? 2 * s->cap : 1u << 20;
			struct vox *nv = realloc(s->v, s->cap * sizeof *nv);
			if (!nv) return VD_ERR_NOMEM;
			s->v = nv;
		}
		uint64_t X = 4ull * bx + x, Y = 4ull * by + y, Z = 4ull * bz + z;
		s->v[s->n++] = (struct vox){spread(X, s->L) << 2 |
					    spread(Y, s->L) << 1 | spread(Z, s->L),
					    X << 42 | Y << 21 | Z};
	}
	return 0;
}

static int vox_cmp(const void *a, const void *b)
{
	uint64_t x = ((const struct vox *)a)->morton,
		 y = ((const struct vox *)b)->morton;
	return x < y ? -1 : x > y;
}

int main(int argc, char **argv)
{
	if (argc != 2) {
		fprintf(stderr, "usage: g48_count ROOT_CHUNK\n");
		return 2;
	}
	struct vd_dag d;
	int err = vd_dag_load(&d, NULL, argv[1], VD_KIND_ANY_DAG);
	struct sink s = {.L = d.levels};
	if (!err && d.chunk_level != 0)
		err = vd_fail(VD_ERR_ARG, "not a root chunk");
	if (!err) err = vd_dag_expand(&d, add, &s);
	int L = d.levels;
	vd_dag_release(&d);
	if (err) {
		fprintf(stderr, "g48_count: '%s': %s: %s\n", argv[1],
			vd_strerror(err), vd_error_detail());
		return 1;
	}
	qsort(s.v, s.n, sizeof *s.v, vox_cmp);
	struct name *names_of = malloc((s.n ? s.n : 1) * sizeof *names_of);
	uint64_t total[3] = {0, 0, 0};
	for (int l = 0; l < L; l++) {
		uint64_t side = 1ull << (L - l);
		int sh = 3 * (L - l);
		for (int gi = 0; gi < 3; gi++) {
			unsigned ng = gi == 0 ? 1 : gi == 1 ? 8 : 48;
			size_t nc = 0;
			for (size_t i = 0; i < s.n;) {
				size_t j = i;
				while (j < s.n && s.v[j].morton >> sh == s.v[i].morton >> sh)
					j++;
				struct name best = {~0ull, ~0ull};
				for (unsigned t = 0; t < ng; t++) {
					struct name c = {mix(j - i, 1), 0};
					for (size_t k = i; k < j; k++) {
						uint64_t v = s.v[k].xyz, q[3];
						uint64_t p[3] = {v >> 42 & (side - 1),
								 v >> 21 & (side - 1),
								 v & (side - 1)};
						for (int a = 0; a < 3; a++) {
							q[a] = p[names[t / 8][a] - 'X'];
							if (t >> (2 - a) & 1) q[a] = side - 1 - q[a];
						}
						uint64_t idx = (q[0] * side + q[1]) * side + q[2];
						c.a += mix(idx, 0x9e3779b97f4a7c15ULL);
						c.b += mix(idx, 0x6a09e667f3bcc909ULL);
					}
					if (name_cmp(&c, &best) < 0) best = c;
				}
				names_of[nc++] = best;
				i = j;
			}
			qsort(names_of, nc, sizeof *names_of, name_cmp);
			for (size_t k = 0; k < nc; k++)
				total[gi] += !k || name_cmp(&names_of[k], &names_of[k - 1]);
		}
	}
	printf("voxels=%zu classes svdag=%llu ssvdag=%llu g48=%llu\n", s.n,
	       (unsigned long long)total[0], (unsigned long long)total[1],
	       (unsigned long long)total[2]);
	free(names_of);
	free(s.v);
	return 0;
}
