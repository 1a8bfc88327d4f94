/* edit_site - prints "x y z", a set voxel of a root DAG chunk near the
 * grid centre, for bench_edit.sh: edits centred there meet the scene's
 * surface (the dragon is hollow at the grid centre, so boxes there copied
 * and painted nothing). Greedy descent: at each level the child nearest
 * to the centre that holds voxels; no search beyond, none needed. */
#include "voxdag.h"

#include <stdlib.h>

static double d2(double ax, double ay, double az, double c)
{
	return (ax - c) * (ax - c) + (ay - c) * (ay - c) + (az - c) * (az - c);
}

int main(int argc, char **argv)
{
	if (argc != 2) {
		fprintf(stderr, "usage: edit_site ROOT.dag\n");
		return 2;
	}
	struct vd_dag d = {0};
	struct vd_chunk_header h;
	if (vd_dag_load(&d, &h, argv[1], VD_KIND_DAG) || !d.voxels) {
		fprintf(stderr, "edit_site: cannot read '%s': %s\n", argv[1],
			vd_error_detail());
		return 1;
	}
	int L = d.levels;
	double c = (double)(1ull << (L - 1));
	uint64_t x = 0, y = 0, z = 0, i = 0;
	for (int l = 0; l < L - 2; l++) {
		uint64_t hs = 1ull << (L - l - 1);
		const struct vd_dag_level *lv = &d.lv[l];
		int best = -1;
		double bd = 0;
		for (int k = 0; k < 8; k++) {
			if (!(lv->mask[i] >> k & 1))
				continue;
			double cx = (double)(x + (k >> 2 & 1) * hs) + hs / 2.0,
			       cy = (double)(y + (k >> 1 & 1) * hs) + hs / 2.0,
			       cz = (double)(z + (k & 1) * hs) + hs / 2.0;
			if (best < 0 || d2(cx, cy, cz, c) < bd)
				best = k, bd = d2(cx, cy, cz, c);
		}
		uint64_t r = lv->first[i] +
			     (uint64_t)__builtin_popcount(lv->mask[i] & ((1u << best) - 1));
		i = lv->child[r];
		x += (uint64_t)(best >> 2 & 1) * hs;
		y += (uint64_t)(best >> 1 & 1) * hs;
		z += (uint64_t)(best & 1) * hs;
	}
	uint64_t b = d.bricks[i];
	int best = -1;
	double bd = 0;
	for (int k = 0; k < 64; k++) {
		if (!(b >> k & 1))
			continue;
		uint32_t bx, by, bz;
		vd_morton3_decode((uint64_t)k, &bx, &by, &bz);
		double dd = d2((double)(x + bx), (double)(y + by), (double)(z + bz), c);
		if (best < 0 || dd < bd)
			best = k, bd = dd;
	}
	uint32_t bx, by, bz;
	vd_morton3_decode((uint64_t)best, &bx, &by, &bz);
	printf("%llu %llu %llu\n", (unsigned long long)(x + bx),
	       (unsigned long long)(y + by), (unsigned long long)(z + bz));
	vd_dag_release(&d);
	return 0;
}
