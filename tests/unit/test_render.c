/* test_render.c - the ray caster against a brute-force reference: every
 * ray's hit (cell, time, face) through each of the five encodings (the
 * SymVox four and .ssvdag48) and the two DAGs equals the hit of a plain voxel DDA (Amanatides-Woo) through the
 * dense grid decoded by vd_enc_expand(), on the bunny at 2^6 and 2^7 and on
 * synthetic grids full of reflected and permuted copies; axis-parallel, grazing (in face
 * planes, along edges, through corners), inside-starting, clipped and
 * missing rays. Then: identical images from every source, LOD hits against
 * the grid at their level, and PNG / depth / id files read back.
 *
 * Tie-breaking, shared with the tracer because it is the contract in
 * vd_render.h, not because the code is shared: the time of
 * plane k on axis a is ((double)k - o[a]) * (1.0 / d[a]); a voxel is
 * entered at the time of its near plane; all axes whose next plane has the
 * smallest time step together; a ray with d[a] == 0 has voxel coordinate
 * floor(o[a]); the hit axis is the lowest axis whose near plane time is the
 * entry time, -1 when the ray starts inside (time tmin). */
#include "check.h"
#include "scene.h"
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wunused-variable"
#include "dag_test_util.h"
#pragma GCC diagnostic pop
#include "voxdag.h"

#include <math.h>
#include <png.h>

static struct vd_dag_opts opts = {1, 0, NULL};

/* ------------------------------------------------- the reference */

/* A dense bitset of the 2^L grid, index (x << 2L) | (y << L) | z. */
struct dense {
	int L;
	int64_t n;
	uint64_t *bits;
};

static int dense_get(const struct dense *g, int64_t x, int64_t y, int64_t z)
{
	uint64_t i = (uint64_t)x << (2 * g->L) | (uint64_t)y << g->L | (uint64_t)z;
	return (int)(g->bits[i >> 6] >> (i & 63) & 1);
}

static void dense_set(struct dense *g, int64_t x, int64_t y, int64_t z)
{
	uint64_t i = (uint64_t)x << (2 * g->L) | (uint64_t)y << g->L | (uint64_t)z;
	g->bits[i >> 6] |= 1ull << (i & 63);
}

static int dense_add_brick(void *ctx, uint64_t key, uint64_t brick)
{
	struct dense *g = ctx;
	int bb = g->L >= 2 ? g->L - 2 : 0;
	uint32_t bx, by, bz;
	ref_unmorton(key, bb, &bx, &by, &bz);
	for (int b = 0; b < 64; b++) {
		if (!(brick >> b & 1)) continue;
		uint32_t x, y, z;
		ref_unmorton((uint64_t)b, 2, &x, &y, &z);
		dense_set(g, 4 * bx + x, 4 * by + y, 4 * bz + z);
	}
	return 0;
}

/* Decodes `e` into a dense grid. */
static void dense_from_enc(struct dense *g, const struct vd_enc *e)
{
	g->L = (int)e->levels;
	g->n = (int64_t)1 << g->L;
	uint64_t words = ((uint64_t)1 << (3 * g->L)) / 64 + 1;
	g->bits = calloc(words, 8);
	CHECK_EQ(vd_enc_expand(e, dense_add_brick, g), 0);
}

static double ref_tp(const struct vd_ray *r, const double *inv, int a, int64_t k)
{
	return ((double)k - r->o[a]) * inv[a];
}

/* Plain voxel DDA. Returns 1 and fills *h (level L) on a hit. */
static int ref_trace(const struct dense *g, const struct vd_ray *r,
		     struct vd_hit *h)
{
	const int64_t N = g->n;
	double inv[3];
	int step[3];
	double t0 = r->tmin, t1 = r->tmax;
	int moving = 0;
	for (int a = 0; a < 3; a++) {
		step[a] = r->d[a] > 0 ? 1 : r->d[a] < 0 ? -1 : 0;
		inv[a] = step[a] ? 1.0 / r->d[a] : 0;
		if (!step[a]) {
			if (!(floor(r->o[a]) >= 0 && floor(r->o[a]) < (double)N))
				return 0;
			continue;
		}
		moving = 1;
		double tn = ref_tp(r, inv, a, step[a] > 0 ? 0 : N);
		double tf = ref_tp(r, inv, a, step[a] > 0 ? N : 0);
		if (tn > t0) t0 = tn;
		if (tf < t1) t1 = tf;
	}
	if (!moving || !(t0 < t1)) return 0;
	int64_t c[3];
	for (int a = 0; a < 3; a++) {
		if (!step[a]) {
			c[a] = (int64_t)floor(r->o[a]);
			continue;
		}
		double p = floor(r->o[a] + t0 * r->d[a]);
		int64_t k = p < 0 ? 0 : p > (double)(N - 1) ? N - 1 : (int64_t)p;
		/* c is the voxel with tp(near) <= t0 < tp(far) */
		if (step[a] > 0) {
			while (k + 1 <= N - 1 && ref_tp(r, inv, a, k + 1) <= t0) k++;
			while (k > 0 && ref_tp(r, inv, a, k) > t0) k--;
		} else {
			while (k > 0 && ref_tp(r, inv, a, k) <= t0) k--;
			while (k < N - 1 && ref_tp(r, inv, a, k + 1) > t0) k++;
		}
		c[a] = k;
	}
	for (;;) {
		if (dense_get(g, c[0], c[1], c[2])) {
			double tin = -INFINITY;
			int ax = -1;
			for (int a = 0; a < 3; a++) {
				if (!step[a]) continue;
				double tn = ref_tp(r, inv, a, step[a] > 0 ? c[a] : c[a] + 1);
				if (tn > tin) {
					tin = tn;
					ax = a;
				}
			}
			h->t = tin < r->tmin ? r->tmin : tin;
			h->axis = tin < r->tmin ? -1 : ax;
			for (int a = 0; a < 3; a++) h->cell[a] = (uint32_t)c[a];
			h->level = g->L;
			return 1;
		}
		double tm[3], tn = INFINITY;
		for (int a = 0; a < 3; a++) {
			tm[a] = step[a] ? ref_tp(r, inv, a, step[a] > 0 ? c[a] + 1 : c[a])
					: INFINITY;
			if (tm[a] < tn) tn = tm[a];
		}
		if (!(tn < r->tmax)) return 0;
		for (int a = 0; a < 3; a++)
			if (step[a] && tm[a] == tn) {
				c[a] += step[a];
				if (c[a] < 0 || c[a] >= N) return 0;
			}
	}
}

/* --------------------------------------------------------- sources */

/* A scene in all its forms: the five encodings and the two DAGs render
 * reads (dag[2], the ssvdag48, is rendered through its encoding). */
struct scene6 {
	int L;
	struct vd_transform t;
	struct vd_dag dag[3];
	struct vd_enc enc[VD_ENC_ALL_];
	int has_enc[VD_ENC_ALL_];
	struct vd_render_scene rs[VD_ENC_ALL_ + 2];
	int n_rs;
	const char *name[VD_ENC_ALL_ + 2];
	struct dense ref;  /* decoded from the SSVDAG (or the SVDAG for L < 3) */
};

static void scene6_build(struct scene6 *s, const struct vd_svo *svo,
			 const struct vd_transform *t)
{
	memset(s, 0, sizeof *s);
	s->L = svo->levels;
	s->t = *t;
	CHECK_EQ(vd_dag_from_svo(&s->dag[0], svo, VD_KIND_DAG, &opts, NULL), VD_OK);
	CHECK_EQ(vd_dag_from_svo(&s->dag[1], svo, VD_KIND_SSVDAG, &opts, NULL), VD_OK);
	CHECK_EQ(vd_dag_from_svo(&s->dag[2], svo, VD_KIND_SSVDAG48, &opts, NULL),
		 VD_OK);
	for (int f = 0; f < VD_ENC_ALL_; f++) {
		if (vd_enc_format_compact(f) && s->L < 3) continue;
		const struct vd_dag *d = &s->dag[f == VD_ENC_SSVDAG48 ? 2 :
						 vd_enc_format_symmetric(f)];
		CHECK_EQ(vd_enc_build(&s->enc[f], f, d, t), VD_OK);
		s->has_enc[f] = 1;
		CHECK_EQ(vd_render_scene_from_enc(&s->rs[s->n_rs], &s->enc[f]), VD_OK);
		s->name[s->n_rs++] = vd_enc_format_name(f);
	}
	for (int k = 0; k < 2; k++) {
		CHECK_EQ(vd_render_scene_from_dag(&s->rs[s->n_rs], &s->dag[k], t), VD_OK);
		s->name[s->n_rs++] = k ? "ssvdag chunk" : "dag chunk";
	}
	dense_from_enc(&s->ref, &s->enc[s->L >= 3 ? VD_ENC_SSVDAG : VD_ENC_SVDAG]);
	/* every encoding decodes to the same grid */
	for (int f = 0; f < VD_ENC_ALL_; f++) {
		if (!s->has_enc[f]) continue;
		struct dense g;
		dense_from_enc(&g, &s->enc[f]);
		size_t words = ((size_t)1 << (3 * s->L)) / 64 + 1;
		CHECK(memcmp(g.bits, s->ref.bits, words * 8) == 0);
		free(g.bits);
	}
}

static void scene6_free(struct scene6 *s)
{
	for (int f = 0; f < VD_ENC_ALL_; f++) vd_enc_release(&s->enc[f]);
	for (int k = 0; k < 3; k++) vd_dag_release(&s->dag[k]);
	free(s->ref.bits);
}

/* ------------------------------------------------------------ rays */

static double frand(void)
{
	return (double)(rnd() >> 11) / 9007199254740992.0;
}

/* Counts per kind, so a test can check that the interesting cases
 * happened (a reference that never hits proves nothing). */
struct tally {
	uint64_t rays, hits, inside, axis_hits[3];
	uint64_t mismatches;
};

static int hits_equal(const struct vd_hit *a, const struct vd_hit *b)
{
	return a->t == b->t && a->axis == b->axis && a->level == b->level &&
	       a->cell[0] == b->cell[0] && a->cell[1] == b->cell[1] &&
	       a->cell[2] == b->cell[2];
}

/* Traces r through every source and the reference; counts mismatches. */
static void check_ray(const struct scene6 *s, const struct vd_ray *r,
		      struct tally *ty)
{
	struct vd_hit want, got;
	memset(&want, 0, sizeof want);
	int hw = ref_trace(&s->ref, r, &want);
	ty->rays++;
	if (hw) {
		ty->hits++;
		if (want.axis < 0) ty->inside++;
		else ty->axis_hits[want.axis]++;
	}
	for (int k = 0; k < s->n_rs; k++) {
		memset(&got, 0, sizeof got);
		int hg = vd_render_trace(&s->rs[k], r, &got);
		if (hg != hw || (hw && !hits_equal(&got, &want))) {
			if (ty->mismatches++ < 5)
				fprintf(stderr, "  %s L=%d ray o=(%.17g %.17g %.17g) "
					"d=(%.17g %.17g %.17g) t=[%g,%g): got %d "
					"(%u %u %u) t=%.17g axis %d, want %d (%u %u "
					"%u) t=%.17g axis %d\n", s->name[k], s->L,
					r->o[0], r->o[1], r->o[2], r->d[0], r->d[1],
					r->d[2], r->tmin, r->tmax, hg, got.cell[0],
					got.cell[1], got.cell[2], got.t, got.axis, hw,
					want.cell[0], want.cell[1], want.cell[2],
					want.t, want.axis);
		}
	}
}

static void ray_set(struct vd_ray *r, double ox, double oy, double oz,
		    double dx, double dy, double dz)
{
	r->o[0] = ox;
	r->o[1] = oy;
	r->o[2] = oz;
	r->d[0] = dx;
	r->d[1] = dy;
	r->d[2] = dz;
	r->tmin = 0;
	r->tmax = INFINITY;
	r->lod = 0;
}

/* A random direction; with probability 1/4 one or two components zero. */
static void random_dir(double *d)
{
	do {
		for (int a = 0; a < 3; a++) d[a] = 2 * frand() - 1;
		unsigned z = (unsigned)(rnd() % 16);
		if (z < 3) d[z] = 0;
		else if (z == 3) d[0] = d[1] = 0;
	} while (d[0] == 0 && d[1] == 0 && d[2] == 0);
}

/* The whole battery of rays on one scene. */
static void ray_battery(const struct scene6 *s, int random_rays)
{
	const double N = (double)s->ref.n;
	struct tally ty = {0};
	struct vd_ray r;
	/* random rays from outside the cube towards a point inside */
	for (int i = 0; i < random_rays; i++) {
		double p[3], d[3];
		for (int a = 0; a < 3; a++) p[a] = N * frand();
		random_dir(d);
		double back = 2 * N;
		ray_set(&r, p[0] - back * d[0], p[1] - back * d[1],
			p[2] - back * d[2], d[0], d[1], d[2]);
		check_ray(s, &r, &ty);
	}
	/* starting inside the grid, from random points and voxel centres,
	 * some with tmin > 0 or a finite tmax */
	for (int i = 0; i < random_rays; i++) {
		double d[3];
		random_dir(d);
		int64_t v[3];
		for (int a = 0; a < 3; a++) v[a] = (int64_t)(rnd() % (uint64_t)s->ref.n);
		if (i % 2)
			ray_set(&r, v[0] + 0.5, v[1] + 0.5, v[2] + 0.5, d[0], d[1], d[2]);
		else
			ray_set(&r, N * frand(), N * frand(), N * frand(), d[0], d[1], d[2]);
		if (i % 5 == 1) r.tmin = 3 * frand();
		if (i % 7 == 2) r.tmax = r.tmin + N * frand() / 4;
		if (i % 11 == 3) r.tmin = -N * frand();
		check_ray(s, &r, &ty);
	}
	/* axis-parallel rays through voxel centres, on faces and on edges */
	for (int a = 0; a < 3; a++)
		for (int sgn = -1; sgn <= 1; sgn += 2)
			for (int i = 0; i < random_rays / 8; i++) {
				double o[3], d[3] = {0, 0, 0};
				for (int b = 0; b < 3; b++) {
					double v = (double)(rnd() % (uint64_t)s->ref.n);
					unsigned kind = (unsigned)(rnd() % 3);
					o[b] = kind == 0 ? v + 0.5 : kind == 1 ? v : v + frand();
				}
				o[a] = sgn > 0 ? -3.25 : N + 2;
				d[a] = sgn;
				ray_set(&r, o[0], o[1], o[2], d[0], d[1], d[2]);
				check_ray(s, &r, &ty);
			}
	/* grazing: in a face plane (one zero component, integer origin there),
	 * through edges and corners (diagonals from integer points) */
	for (int i = 0; i < random_rays / 2; i++) {
		double o[3], d[3];
		for (int a = 0; a < 3; a++) o[a] = (double)(rnd() % (uint64_t)s->ref.n);
		unsigned kind = (unsigned)(rnd() % 4);
		if (kind == 0) { /* in the plane x = o[0] */
			d[0] = 0;
			d[1] = 2 * frand() - 1;
			d[2] = 2 * frand() - 1;
			if (d[1] == 0 && d[2] == 0) d[2] = 1;
		} else if (kind == 1) { /* diagonal through corners */
			for (int a = 0; a < 3; a++) d[a] = rnd() & 1 ? 1 : -1;
		} else if (kind == 2) { /* diagonal in a face plane: along edges' corners */
			d[0] = rnd() & 1 ? 1 : -1;
			d[1] = rnd() & 1 ? 2 : -2;
			d[2] = 0;
		} else { /* directions with equal components and half offsets */
			d[0] = 0.5;
			d[1] = -0.25;
			d[2] = 0.125;
			o[0] += 0.5;
		}
		ray_set(&r, o[0], o[1], o[2], d[0], d[1], d[2]);
		check_ray(s, &r, &ty);
		/* the same line from outside the grid */
		double back = 2 * N;
		ray_set(&r, o[0] - back * d[0], o[1] - back * d[1], o[2] - back * d[2],
			d[0], d[1], d[2]);
		check_ray(s, &r, &ty);
	}
	/* misses: pointing away, passing beside, lying outside, tmax too short,
	 * zero direction */
	ray_set(&r, -1, -1, -1, -1, -0.5, -0.25);
	check_ray(s, &r, &ty);
	ray_set(&r, -1, N + 0.5, 0.5, 1, 0, 0);
	check_ray(s, &r, &ty);
	ray_set(&r, N, 0.5, 0.5, 0, 1, 0); /* in the plane x = N: outside */
	check_ray(s, &r, &ty);
	ray_set(&r, -5, 0.5, 0.5, 1, 0, 0);
	r.tmax = 5; /* ends exactly at the grid */
	check_ray(s, &r, &ty);
	ray_set(&r, 1.5, 1.5, 1.5, 0, 0, 0);
	check_ray(s, &r, &ty);
	for (int k = 0; k < s->n_rs; k++) {
		struct vd_hit h;
		CHECK_EQ(vd_render_trace(&s->rs[k], &r, &h), 0);
		/* no ray: NaN origin or bound; a subnormal direction component
		 * counts as zero (and must terminate) */
		struct vd_ray q;
		ray_set(&q, NAN, 1, 1, 1, 0, 0);
		CHECK_EQ(vd_render_trace(&s->rs[k], &q, &h), 0);
		ray_set(&q, -1, 1, 1, 1, 0, 0);
		q.tmax = NAN;
		CHECK_EQ(vd_render_trace(&s->rs[k], &q, &h), 0);
		ray_set(&q, -1, 0.5, 2, 1, 1e-320, -1e-320);
		struct vd_hit h2;
		int a1 = vd_render_trace(&s->rs[k], &q, &h);
		ray_set(&q, -1, 0.5, 2, 1, 0, 0);
		CHECK_EQ(a1, vd_render_trace(&s->rs[k], &q, &h2));
	}

	CHECK_EQ(ty.mismatches, 0);
	/* the battery did exercise hits, misses, inside starts and faces */
	CHECK(ty.hits > ty.rays / 8);
	CHECK(ty.hits < ty.rays);
	CHECK(ty.inside > 0);
	for (int a = 0; a < 3; a++) CHECK(ty.axis_hits[a] > 0);
	fprintf(stderr, "  L=%d: %" PRIu64 " rays x %d sources, %" PRIu64
		" hits (%" PRIu64 " inside), faces %" PRIu64 "/%" PRIu64 "/%" PRIu64
		"\n", s->L, ty.rays, s->n_rs, ty.hits, ty.inside, ty.axis_hits[0],
		ty.axis_hits[1], ty.axis_hits[2]);
}

/* -------------------------------------------------------------- scenes */

static int bunny(int L, struct scene6 *s)
{
	const char *dir = test_tmpdir("test_render_bunny");
	struct vd_svo svo;
	struct vd_transform t;
	if (!test_voxelize_one("tests/data/bunny.ply", L, dir, &svo, &t)) return 0;
	scene6_build(s, &svo, &t);
	vd_svo_release(&svo);
	return 1;
}

/* A 2^L grid tiled with 8^3 blocks, each empty or one of three random
 * patterns under a random reflection and axis permutation, so the SSVDAG
 * is full of mirrored references and the ssvdag48 of permuted ones at
 * several levels. */
static void synthetic(int L, struct scene6 *s)
{
	struct grid g;
	grid_init(&g, L);
	uint8_t pat[3][8][8][8];
	for (int k = 0; k < 3; k++)
		for (int x = 0; x < 8; x++)
			for (int y = 0; y < 8; y++)
				for (int z = 0; z < 8; z++)
					pat[k][x][y][z] = rnd() % 100 < (k == 0 ? 40 : 12);
	uint32_t nb = g.n / 8;
	for (uint32_t bx = 0; bx < nb; bx++)
		for (uint32_t by = 0; by < nb; by++)
			for (uint32_t bz = 0; bz < nb; bz++) {
				unsigned pick = (unsigned)(rnd() % 5);
				if (bx + by + bz == 0) pick = 0;
				if (pick >= 3) continue;
				unsigned m = (unsigned)(rnd() % 8);
				unsigned k = (unsigned)(rnd() % 6);
				for (uint32_t x = 0; x < 8; x++)
					for (uint32_t y = 0; y < 8; y++)
						for (uint32_t z = 0; z < 8; z++) {
							/* axes rotated k % 3 times, then
							 * Y and Z swapped when k >= 3 */
							uint32_t q[3] = {x, y, z}, r[3];
							for (int a = 0; a < 3; a++)
								r[a] = q[(a + k) % 3];
							if (k >= 3) {
								uint32_t tmp = r[1];
								r[1] = r[2];
								r[2] = tmp;
							}
							uint32_t px = m & 4 ? 7 - r[0] : r[0],
								 py = m & 2 ? 7 - r[1] : r[1],
								 pz = m & 1 ? 7 - r[2] : r[2];
							if (pat[pick][px][py][pz])
								*gv(&g, 8 * bx + x, 8 * by + y,
								    8 * bz + z) = 1;
						}
			}
	struct vd_svo svo;
	grid_to_svo(&g, 0, 0, &svo);
	struct vd_transform t;
	float lo[3] = {-1, -2, -3}, hi[3] = {3, 2, 1};
	CHECK_EQ(vd_transform_init(&t, lo, hi, L), VD_OK);
	scene6_build(s, &svo, &t);
	svo_free(&svo);
	grid_free(&g);
}

/* ---------------------------------------------------------------- tests */

static void test_bunny_rays(void)
{
	for (int L = 6; L <= 7; L++) {
		struct scene6 s;
		if (!bunny(L, &s)) return;
		ray_battery(&s, L == 6 ? 4000 : 2000);
		scene6_free(&s);
	}
}

static void test_synthetic_rays(void)
{
	for (int L = 3; L <= 6; L++) {
		struct scene6 s;
		synthetic(L, &s);
		/* the SSVDAG really uses reflections */
		int mirrored = 0;
		for (int l = 0; l + 1 < s.dag[1].levels; l++)
			for (uint64_t k = 0; k < s.dag[1].lv[l].refs; k++)
				mirrored |= s.dag[1].lv[l].refl[k] != 0;
		if (L >= 5) CHECK(mirrored);
		/* and the ssvdag48 permutations */
		int permuted = 0;
		for (int l = 0; l + 1 < s.dag[2].levels; l++)
			for (uint64_t k = 0; k < s.dag[2].lv[l].refs; k++)
				permuted |= s.dag[2].lv[l].refl[k] >= 8;
		if (L >= 5) CHECK(permuted);
		ray_battery(&s, 1500);
		scene6_free(&s);
	}
}

/* Grids of one and two levels: only the word formats and the DAGs. */
static void test_tiny_grids(void)
{
	for (int L = 1; L <= 2; L++)
		for (int rep = 0; rep < 20; rep++) {
			struct grid g;
			grid_init(&g, L);
			for (size_t i = 0; i < (size_t)g.n * g.n * g.n; i++)
				g.v[i] = rnd() % 3 == 0;
			g.v[rnd() % ((size_t)g.n * g.n * g.n)] = 1;
			struct vd_svo svo;
			grid_to_svo(&g, 0, 0, &svo);
			struct vd_transform t;
			float lo[3] = {0, 0, 0}, hi[3] = {1, 1, 1};
			CHECK_EQ(vd_transform_init(&t, lo, hi, L), VD_OK);
			struct scene6 s;
			scene6_build(&s, &svo, &t);
			struct tally ty = {0};
			for (int i = 0; i < 300; i++) {
				struct vd_ray r;
				double d[3], p[3];
				random_dir(d);
				for (int a = 0; a < 3; a++)
					p[a] = (double)g.n * frand();
				ray_set(&r, p[0] - 3 * d[0], p[1] - 3 * d[1],
					p[2] - 3 * d[2], d[0], d[1], d[2]);
				check_ray(&s, &r, &ty);
			}
			CHECK_EQ(ty.mismatches, 0);
			scene6_free(&s);
			svo_free(&svo);
			grid_free(&g);
		}
}

/* The reference's grid at a coarser level: is the cell non-empty? */
static int cell_nonempty(const struct dense *g, const struct vd_hit *h)
{
	int64_t side = (int64_t)1 << (g->L - h->level);
	for (int64_t x = 0; x < side; x++)
		for (int64_t y = 0; y < side; y++)
			for (int64_t z = 0; z < side; z++)
				if (dense_get(g, h->cell[0] * side + x,
					      h->cell[1] * side + y,
					      h->cell[2] * side + z))
					return 1;
	return 0;
}

/* With LOD, a hit is a non-empty cell no later than the exact hit, the
 * same for every source, and coarser cells come with larger lod. */
static void test_lod(void)
{
	struct scene6 s;
	if (!bunny(6, &s)) return;
	uint64_t coarse = 0, bad = 0;
	for (int i = 0; i < 3000; i++) {
		double p[3], d[3];
		for (int a = 0; a < 3; a++) p[a] = 64 * frand();
		random_dir(d);
		struct vd_ray r;
		ray_set(&r, p[0] - 200 * d[0], p[1] - 200 * d[1], p[2] - 200 * d[2],
			d[0], d[1], d[2]);
		struct vd_hit exact, h0, h;
		int he = ref_trace(&s.ref, &r, &exact);
		r.lod = 0.02 * (double)(i % 5);
		int hl = vd_render_trace(&s.rs[0], &r, &h0);
		if (he && (!hl || h0.t > exact.t)) bad++;
		if (hl && !cell_nonempty(&s.ref, &h0)) bad++;
		if (hl && h0.level < s.L) coarse++;
		if (r.lod == 0 && (hl != he || (he && !hits_equal(&h0, &exact)))) bad++;
		for (int k = 1; k < s.n_rs; k++) {
			int hk = vd_render_trace(&s.rs[k], &r, &h);
			if (hk != hl || (hl && !hits_equal(&h, &h0))) bad++;
		}
	}
	CHECK_EQ(bad, 0);
	CHECK(coarse > 100);
	scene6_free(&s);
}

static struct vd_render_opts image_opts(const struct vd_render_scene *rs,
					const char *preset, int w, int h)
{
	struct vd_render_opts o = {.width = w, .height = h, .shadows = 1};
	CHECK_EQ(vd_camera_preset(&o.cam, rs, preset, 40, w, h), VD_OK);
	for (int a = 0; a < 3; a++)
		o.light[a] = o.cam.eye[a] + (a == 1 ? 2.0 : -0.5) *
			     (o.cam.eye[a] - o.cam.target[a] + 0.3);
	o.threads = 2;
	return o;
}

/* The same picture from every source: identical hits and pixels. */
static void test_identical_images(void)
{
	struct scene6 s;
	if (!bunny(7, &s)) return;
	static const char *presets[] = {"front", "side", "top", "iso"};
	for (int k = 0; k < 4; k++)
		for (int lod = 0; lod <= 1; lod++) {
			struct vd_image first = {0};
			for (int i = 0; i < s.n_rs; i++) {
				struct vd_render_opts o = image_opts(&s.rs[0], presets[k],
								     97, 61);
				o.lod_pixels = lod ? 2.5 : 0;
				struct vd_image img;
				CHECK_EQ(vd_render_image(&s.rs[i], &o, &img), VD_OK);
				if (i == 0) {
					first = img;
					uint64_t hits = 0;
					for (size_t p = 0; p < 97 * 61; p++)
						hits += img.hits[p].level >= 0;
					CHECK(hits > 97 * 61 / 20);
					if (hits <= 97 * 61 / 20) fprintf(stderr, "  %s: %" PRIu64 " hits\n", presets[k], hits);
					CHECK(hits < 97 * 61);
					CHECK(img.shadow_rays > 0);
					continue;
				}
				CHECK(memcmp(img.rgb, first.rgb, 3 * 97 * 61) == 0);
				int same = 1;
				for (size_t p = 0; p < 97 * 61; p++)
					same &= img.hits[p].level == first.hits[p].level &&
						(img.hits[p].level < 0 ||
						 hits_equal(&img.hits[p], &first.hits[p]));
				CHECK(same);
				if (!same)
					fprintf(stderr, "  %s differs (%s, lod %d)\n",
						s.name[i], presets[k], lod);
				vd_image_release(&img);
			}
			vd_image_release(&first);
		}
	scene6_free(&s);
}

/* render --diff (vd_render_opts.diff): a scene against itself is the plain
 * picture; against a scene with some bricks thinned and others thickened,
 * every pixel shows the nearer of the two scenes' own hits, and it is red
 * exactly when that voxel is set in one of the two dense reference grids
 * only. */
static void test_diff_images(void)
{
	struct scene6 a, b;
	const char *dir = test_tmpdir("test_render_diff");
	struct vd_svo svo;
	struct vd_transform t;
	if (!test_voxelize_one("tests/data/bunny.ply", 7, dir, &svo, &t)) return;
	scene6_build(&a, &svo, &t);
	for (size_t i = 0; i < svo.count; i++) {
		uint64_t m = svo.masks[i];
		if (i % 5 == 0 && (m & (m - 1))) /* drop the lowest voxel */
			svo.masks[i] = m & (m - 1);
		else if (i % 5 == 1) /* and add a neighbour */
			svo.masks[i] = m | m << 1 | 1;
	}
	scene6_build(&b, &svo, &t);
	vd_svo_release(&svo);
	const int W = 101, H = 77;
	const struct vd_render_scene *ra = &a.rs[a.n_rs - 2], *rb = &b.rs[b.n_rs - 1];
	struct vd_render_opts o = image_opts(ra, "iso", W, H);
	struct vd_image plain, self, pa, pb, dif;
	CHECK_EQ(vd_render_image(ra, &o, &plain), VD_OK);
	o.diff = &a.rs[a.n_rs - 1]; /* the same voxels, as an SSVDAG */
	CHECK_EQ(vd_render_image(ra, &o, &self), VD_OK);
	CHECK(memcmp(plain.rgb, self.rgb, 3 * (size_t)W * H) == 0);
	CHECK_EQ(self.differing_pixels, 0);
	o.diff = NULL;
	CHECK_EQ(vd_render_image(ra, &o, &pa), VD_OK);
	CHECK_EQ(vd_render_image(rb, &o, &pb), VD_OK);
	o.diff = rb;
	CHECK_EQ(vd_render_image(ra, &o, &dif), VD_OK);
	uint64_t red = 0, bad = 0;
	for (size_t p = 0; p < (size_t)W * H; p++) {
		const struct vd_hit *h = &dif.hits[p], *ha = &pa.hits[p],
				    *hb = &pb.hits[p];
		if (h->level < 0) {
			bad += ha->level >= 0 || hb->level >= 0 || dif.differs[p];
			continue;
		}
		/* the nearer of the two own hits */
		int is_a = ha->level >= 0 && hits_equal(h, ha),
		    is_b = hb->level >= 0 && hits_equal(h, hb);
		bad += !is_a && !is_b;
		bad += (ha->level >= 0 && ha->t < h->t) || (hb->level >= 0 && hb->t < h->t);
		int in_a = dense_get(&a.ref, h->cell[0], h->cell[1], h->cell[2]),
		    in_b = dense_get(&b.ref, h->cell[0], h->cell[1], h->cell[2]);
		bad += !(in_a | in_b);
		bad += dif.differs[p] != (in_a != in_b);
		red += dif.differs[p];
	}
	CHECK_EQ(bad, 0);
	CHECK_EQ(red, dif.differing_pixels);
	CHECK(red > 50);
	/* on another grid, or with LOD: refused */
	struct scene6 c;
	if (bunny(6, &c)) {
		o.diff = &c.rs[0];
		struct vd_image x;
		CHECK_EQ(vd_render_image(ra, &o, &x), VD_ERR_MISMATCH);
		vd_image_release(&x);
		scene6_free(&c);
	}
	o.diff = rb;
	o.lod_pixels = 2;
	struct vd_image y;
	CHECK_EQ(vd_render_image(ra, &o, &y), VD_ERR_ARG);
	vd_image_release(&y);
	vd_image_release(&plain);
	vd_image_release(&self);
	vd_image_release(&pa);
	vd_image_release(&pb);
	vd_image_release(&dif);
	scene6_free(&a);
	scene6_free(&b);
}

/* Images are written so that libpng reads them back as they were; the depth
 * and id files have the documented sizes and headers. */
static void test_outputs(void)
{
	struct scene6 s;
	if (!bunny(6, &s)) return;
	const char *dir = test_tmpdir("test_render_out");
	struct vd_render_opts o = image_opts(&s.rs[3], "iso", 123, 45);
	struct vd_image img;
	CHECK_EQ(vd_render_image(&s.rs[3], &o, &img), VD_OK);
	char path[600];
	snprintf(path, sizeof path, "%s/a.png", dir);
	CHECK_EQ(vd_image_write_png(&img, path), VD_OK);
	png_image pi;
	memset(&pi, 0, sizeof pi);
	pi.version = PNG_IMAGE_VERSION;
	CHECK(png_image_begin_read_from_file(&pi, path));
	CHECK_EQ(pi.width, 123);
	CHECK_EQ(pi.height, 45);
	pi.format = PNG_FORMAT_RGB;
	uint8_t *buf = malloc(PNG_IMAGE_SIZE(pi));
	CHECK(png_image_finish_read(&pi, NULL, buf, 0, NULL));
	CHECK(memcmp(buf, img.rgb, 3 * 123 * 45) == 0);
	free(buf);

	snprintf(path, sizeof path, "%s/d.png", dir);
	CHECK_EQ(vd_image_write_depth(&img, path), VD_OK);
	memset(&pi, 0, sizeof pi);
	pi.version = PNG_IMAGE_VERSION;
	CHECK(png_image_begin_read_from_file(&pi, path));
	CHECK_EQ(pi.width, 123);
	CHECK_EQ(pi.height, 45);
	png_image_free(&pi);

	snprintf(path, sizeof path, "%s/d.pfm", dir);
	CHECK_EQ(vd_image_write_depth(&img, path), VD_OK);
	size_t n = 0;
	FILE *f = fopen(path, "rb");
	uint8_t *b = malloc(1 << 20);
	if (f) {
		n = fread(b, 1, 1 << 20, f);
		fclose(f);
	}
	const char head[] = "Pf\n123 45\n-1.0\n";
	CHECK_EQ(n, strlen(head) + 4 * 123 * 45);
	CHECK(memcmp(b, head, strlen(head)) == 0);
	/* the last row of the image is the first in the file */
	float v;
	memcpy(&v, b + strlen(head) + 4 * 7, 4);
	CHECK(v == img.depth[44 * 123 + 7] || (isinf(v) && isinf(img.depth[44 * 123 + 7])));

	snprintf(path, sizeof path, "%s/ids.bin", dir);
	CHECK_EQ(vd_image_write_ids(&img, path), VD_OK);
	f = fopen(path, "rb");
	n = 0;
	if (f) {
		n = fread(b, 1, 1 << 20, f);
		fclose(f);
	}
	CHECK_EQ(n, 16 + 16 * 123 * 45);
	CHECK(b[0] == 0x89 && b[1] == 'V' && b[2] == 'I' && b[3] == 'D');
	CHECK_EQ(b[8] | b[9] << 8, 123);
	CHECK_EQ(b[12] | b[13] << 8, 45);
	size_t p = 0;
	while (p < 123 * 45 && img.hits[p].level < 0) p++;
	CHECK(p < 123 * 45);
	if (p < 123 * 45) {
		const uint8_t *q = b + 16 + 16 * p;
		CHECK_EQ(q[0] | q[1] << 8, img.hits[p].cell[0]);
		CHECK_EQ(q[12], 6);
	}
	CHECK_EQ(b[16], 0xff); /* the corner pixel is sky */
	free(b);

	snprintf(path, sizeof path, "%s/d.tiff", dir);
	CHECK_EQ(vd_image_write_depth(&img, path), VD_ERR_ARG);
	vd_image_release(&img);
	scene6_free(&s);
}

static void test_bad_cameras(void)
{
	struct vd_camera c = {{0, 0, 1}, {0, 0, 1}, {0, 1, 0}, 40};
	CHECK_EQ(vd_camera_check(&c), VD_ERR_ARG);
	c.eye[2] = 2;
	CHECK_EQ(vd_camera_check(&c), VD_OK);
	c.fov_deg = 180;
	CHECK_EQ(vd_camera_check(&c), VD_ERR_ARG);
	c.fov_deg = 0;
	CHECK_EQ(vd_camera_check(&c), VD_ERR_ARG);
	c.fov_deg = NAN;
	CHECK_EQ(vd_camera_check(&c), VD_ERR_ARG);
	c.fov_deg = 60;
	c.up[1] = 0;
	c.up[2] = 1;
	CHECK_EQ(vd_camera_check(&c), VD_ERR_ARG); /* parallel */
	struct vd_render_scene rs = {.levels = 3, .voxel_size = 1};
	CHECK_EQ(vd_camera_preset(&c, &rs, "nowhere", 40, 10, 10), VD_ERR_ARG);
	struct vd_render_opts o = {.width = 0, .height = 10, .cam = c};
	struct vd_image img;
	CHECK_EQ(vd_render_image(&rs, &o, &img), VD_ERR_ARG);
	vd_image_release(&img);
}

int main(void)
{
	RUN(test_synthetic_rays);
	RUN(test_tiny_grids);
	RUN(test_bunny_rays);
	RUN(test_lod);
	RUN(test_identical_images);
	RUN(test_diff_images);
	RUN(test_outputs);
	RUN(test_bad_cameras);
	return CHECK_DONE();
}
