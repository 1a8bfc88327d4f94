/* translation - how many more DAG nodes would merge if subtrees equal up to
 * a translation were merged (issue 13's question, asked before anything
 * is built): for the distinct nodes of an SVDAG root chunk on the levels
 * whose nodes are 4^3, 8^3 and 16^3 voxels, counts
 *   nodes        distinct subtrees (the SVDAG's)
 *   shift<=3     classes when a node may be another moved by up to 3 voxels
 *                along each axis (inside its own cube: nothing may leave
 *                it); the members of a class of equal content are covered
 *                greedily by boxes of +-3 around a representative, so this
 *                is an upper bound on the nodes left (a lower bound on the
 *                saving)
 *   any shift    classes of equal content up to any translation inside
 *                the cube (the most translation could ever save there)
 * A saving here does not count the merges it would cause above (parents
 * that become equal), and the shift would cost pointer bits; the question
 * is whether even this bound reaches the 10% that would justify building
 * it.
 *
 * usage: translation ROOT.dag   (built by make bench, run by tests/bench.sh) */
#include "voxdag.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct node {
	uint64_t *bits;   /* s^3 bits, index (x * s + y) * s + z, normalized */
	uint64_t hash;
	int corner[3];    /* where the normalized content sat */
};

static int side; /* voxels per side of the level's nodes */
static int words; /* uint64 per node */

static int by_content(const void *a, const void *b)
{
	const struct node *x = a, *y = b;
	if (x->hash != y->hash)
		return x->hash < y->hash ? -1 : 1;
	int c = memcmp(x->bits, y->bits, (size_t)words * 8);
	if (c)
		return c;
	for (int k = 0; k < 3; k++)
		if (x->corner[k] != y->corner[k])
			return x->corner[k] - y->corner[k];
	return 0;
}

static inline void setbit(uint64_t *b, int x, int y, int z)
{
	size_t i = ((size_t)x * side + y) * side + z;
	b[i >> 6] |= 1ull << (i & 63);
}

/* Voxels of node i on level l, offset (ox, oy, oz), into b (side-cube). */
static void paint(const struct vd_dag *d, int l, uint64_t i, int ox, int oy,
		  int oz, uint64_t *b)
{
	int L = d->levels;
	if (l == L - 2) {
		uint64_t v = d->bricks[i];
		for (int k = 0; k < 64; k++)
			if (v >> k & 1) {
				uint32_t x, y, z;
				vd_morton3_decode((uint64_t)k, &x, &y, &z);
				setbit(b, ox + (int)x, oy + (int)y, oz + (int)z);
			}
		return;
	}
	const struct vd_dag_level *lv = &d->lv[l];
	int half = 1 << (L - l - 1);
	uint64_t r = lv->first[i];
	for (unsigned c = 0; c < 8; c++)
		if (lv->mask[i] >> c & 1)
			paint(d, l + 1, lv->child[r++], ox + (c >> 2 & 1) * half,
			      oy + (c >> 1 & 1) * half, oz + (c & 1) * half, b);
}

static uint64_t measure(const struct vd_dag *d, int l)
{
	uint64_t n = d->lv[l].nodes;
	side = 1 << (d->levels - l);
	words = (side * side * side + 63) / 64;
	struct node *v = calloc(n, sizeof *v);
	uint64_t *raw = calloc((size_t)words, 8);
	for (uint64_t i = 0; i < n; i++) {
		memset(raw, 0, (size_t)words * 8);
		paint(d, l, i, 0, 0, 0, raw);
		int lo[3] = {side, side, side};
		for (int x = 0; x < side; x++)
			for (int y = 0; y < side; y++)
				for (int z = 0; z < side; z++) {
					size_t k = ((size_t)x * side + y) * side + z;
					if (!(raw[k >> 6] >> (k & 63) & 1))
						continue;
					if (x < lo[0]) lo[0] = x;
					if (y < lo[1]) lo[1] = y;
					if (z < lo[2]) lo[2] = z;
				}
		v[i].bits = calloc((size_t)words, 8);
		for (int x = lo[0]; x < side; x++)
			for (int y = lo[1]; y < side; y++)
				for (int z = lo[2]; z < side; z++) {
					size_t k = ((size_t)x * side + y) * side + z;
					if (raw[k >> 6] >> (k & 63) & 1)
						setbit(v[i].bits, x - lo[0], y - lo[1],
						       z - lo[2]);
				}
		memcpy(v[i].corner, lo, sizeof lo);
		uint64_t h = 1469598103934665603ull;
		for (int w = 0; w < words; w++)
			h = (h ^ v[i].bits[w]) * 1099511628211ull;
		v[i].hash = h;
	}
	qsort(v, n, sizeof *v, by_content);
	uint64_t any = 0, near = 0;
	for (uint64_t i = 0; i < n;) {
		uint64_t j = i;
		while (j < n && v[j].hash == v[i].hash &&
		       !memcmp(v[j].bits, v[i].bits, (size_t)words * 8))
			j++;
		any++;
		/* greedy cover of the corners [i, j) by boxes of +-3 */
		char *done = calloc(j - i, 1);
		for (uint64_t a = i; a < j; a++) {
			if (done[a - i])
				continue;
			near++;
			for (uint64_t b = a; b < j; b++) {
				int ok = 1;
				for (int k = 0; k < 3; k++)
					ok &= abs(v[b].corner[k] - v[a].corner[k]) <= 3;
				if (ok)
					done[b - i] = 1;
			}
		}
		free(done);
		i = j;
	}
	printf("  level %2d (%3d^3 voxels): %10llu nodes, shift<=3 %10llu "
	       "(-%.2f%%), any shift %10llu (-%.2f%%)\n", l, side,
	       (unsigned long long)n, (unsigned long long)near,
	       100.0 * (double)(n - near) / (double)n, (unsigned long long)any,
	       100.0 * (double)(n - any) / (double)n);
	for (uint64_t i = 0; i < n; i++)
		free(v[i].bits);
	free(v);
	free(raw);
	return n - near;
}

int main(int argc, char **argv)
{
	if (argc != 2) {
		fprintf(stderr, "usage: translation ROOT.dag\n");
		return 2;
	}
	struct vd_dag d;
	if (vd_dag_load(&d, NULL, argv[1], VD_KIND_DAG)) {
		fprintf(stderr, "translation: %s: %s\n", argv[1],
			vd_error_detail());
		return 1;
	}
	if (d.chunk_level != 0 || d.levels < 5 || !d.bricks) {
		fprintf(stderr, "translation: needs a root SVDAG chunk of depth "
			"5 or more\n");
		return 1;
	}
	uint64_t total = 0;
	for (int l = 0; l < d.levels; l++)
		total += d.lv[l].nodes;
	printf("%s: 2^%d, %llu SVDAG nodes\n", argv[1], d.levels,
	       (unsigned long long)total);
	uint64_t saved = 0;
	for (int l = d.levels - 2; l >= d.levels - 4; l--)
		saved += measure(&d, l);
	printf("  shift<=3 on these levels: %llu fewer nodes, %.2f%% of the "
	       "SVDAG\n", (unsigned long long)saved,
	       100.0 * (double)saved / (double)total);
	vd_dag_release(&d);
	return 0;
}
