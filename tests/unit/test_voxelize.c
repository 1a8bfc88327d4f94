/* test_voxelize.c - the voxelizer against a brute-force reference.
 *
 * The reference overlap test below is written apart from tribox.c on
 * purpose: it projects all 8 box corners and all 3 vertices onto each of
 * the 13 separating axes with plain __int128 arithmetic, no precomputed
 * offsets, no columns, no fast paths. Only the snapping of float vertices
 * (the definition of the grid) is shared.
 */
#include "check.h"
#include "scene.h"
#include "voxdag.h"
#include "voxel/voxel_internal.h"

#include <dirent.h>
#include <string.h>
#include <math.h>
#include <unistd.h>

typedef __int128 i128;

static const char *dir;

/* ------------------------------------------------------------ reference */

static void cross(const i128 a[3], const i128 b[3], i128 out[3])
{
	out[0] = a[1] * b[2] - a[2] * b[1];
	out[1] = a[2] * b[0] - a[0] * b[2];
	out[2] = a[0] * b[1] - a[1] * b[0];
}

/* 1 if the closed box [lo, lo+side]^3 (snapped units) and the closed
 * triangle t (snapped units) overlap. */
static int ref_overlap(const int64_t t[3][3], const int64_t lo[3], int64_t side)
{
	i128 v[3][3], e[3][3], axes[13][3];
	for (int k = 0; k < 3; k++)
		for (int a = 0; a < 3; a++)
			v[k][a] = t[k][a];
	for (int k = 0; k < 3; k++)
		for (int a = 0; a < 3; a++)
			e[k][a] = v[(k + 1) % 3][a] - v[k][a];
	int n = 0;
	for (int a = 0; a < 3; a++) {
		for (int b = 0; b < 3; b++)
			axes[n][b] = a == b;
		n++;
	}
	cross(e[0], e[1], axes[n++]);
	for (int k = 0; k < 3; k++)
		for (int a = 0; a < 3; a++) {
			i128 unit[3] = {a == 0, a == 1, a == 2};
			cross(e[k], unit, axes[n++]);
		}
	for (int j = 0; j < 13; j++) {
		i128 tmin = 0, tmax = 0, bmin = 0, bmax = 0;
		for (int k = 0; k < 3; k++) {
			i128 d = axes[j][0] * v[k][0] + axes[j][1] * v[k][1] +
				 axes[j][2] * v[k][2];
			if (k == 0 || d < tmin)
				tmin = d;
			if (k == 0 || d > tmax)
				tmax = d;
		}
		for (int c = 0; c < 8; c++) {
			i128 p[3];
			for (int a = 0; a < 3; a++)
				p[a] = (i128)lo[a] + ((c >> a) & 1 ? side : 0);
			i128 d = axes[j][0] * p[0] + axes[j][1] * p[1] +
				 axes[j][2] * p[2];
			if (c == 0 || d < bmin)
				bmin = d;
			if (c == 0 || d > bmax)
				bmax = d;
		}
		if (tmax < bmin || bmax < tmin)
			return 0;
	}
	return 1;
}

/* ------------------------------------------------------------ voxel sets */

static uint64_t morton_key(void *ctx, int64_t x, int64_t y, int64_t z)
{
	(void)ctx;
	return vd_morton3((uint32_t)x, (uint32_t)y, (uint32_t)z);
}

static void morton_name(uint64_t key, char *buf, size_t cap)
{
	uint32_t x, y, z;
	vd_morton3_decode(key, &x, &y, &z);
	snprintf(buf, cap, "(%u,%u,%u)", x, y, z);
}

static void collect(void *ctx, int64_t x, int64_t y, int64_t z)
{
	vset_add(ctx, vd_morton3((uint32_t)x, (uint32_t)y, (uint32_t)z));
}

/* Every voxel of the grid near the triangle, tested by the reference. */
static void ref_voxels(const struct vd_snapped_tri *t, int L, struct vset *out)
{
	const int64_t s = vd_snap_voxel(L), top = ((int64_t)1 << L) - 1;
	int64_t lo[3], hi[3];
	for (int a = 0; a < 3; a++) {
		int64_t mn = t->v[0][a], mx = t->v[0][a];
		for (int k = 1; k < 3; k++) {
			mn = t->v[k][a] < mn ? t->v[k][a] : mn;
			mx = t->v[k][a] > mx ? t->v[k][a] : mx;
		}
		/* a generous margin: the reference decides, not the range */
		lo[a] = mn / s - 2;
		hi[a] = mx / s + 2;
		lo[a] = lo[a] < 0 ? 0 : lo[a];
		hi[a] = hi[a] > top ? top : hi[a];
	}
	for (int64_t x = lo[0]; x <= hi[0]; x++)
		for (int64_t y = lo[1]; y <= hi[1]; y++)
			for (int64_t z = lo[2]; z <= hi[2]; z++) {
				int64_t b[3] = {x * s, y * s, z * s};
				if (ref_overlap(t->v, b, s))
					collect(out, x, y, z);
			}
}

/* ----------------------------------------------------- random triangles */

static uint64_t rng = 88172645463325252ull;
static uint64_t next(void)
{
	rng ^= rng << 13;
	rng ^= rng >> 7;
	rng ^= rng << 17;
	return rng;
}
static int64_t uniform(int64_t n) { return (int64_t)(next() % (uint64_t)n); }

/* Triangles of many kinds inside a 2^L grid: general, tiny, huge, on voxel
 * faces, axis-aligned, degenerate to a segment or a point. */
static void random_triangle(struct vd_snapped_tri *t, int L, int kind)
{
	const int64_t s = vd_snap_voxel(L), side = s << L;
	int64_t c[3];
	for (int a = 0; a < 3; a++)
		c[a] = uniform(side + 1);
	for (int k = 0; k < 3; k++)
		for (int a = 0; a < 3; a++) {
			int64_t v;
			switch (kind) {
			case 0: /* anywhere */
				v = uniform(side + 1);
				break;
			case 1: /* tiny, within a voxel or two */
				v = c[a] + uniform(2 * s) - s;
				break;
			case 2: /* on the voxel lattice: touching faces and edges */
				v = uniform((side / s) + 1) * s;
				break;
			case 3: /* axis-aligned plane on a voxel face */
				v = a == 0 ? (c[0] / s) * s : uniform(side + 1);
				break;
			case 4: /* half-voxel lattice */
				v = uniform(2 * (side / s) + 1) * (s / 2);
				break;
			default: /* small, a few voxels */
				v = c[a] + uniform(8 * s) - 4 * s;
				break;
			}
			t->v[k][a] = v < 0 ? 0 : v > side ? side : v;
		}
	int degenerate = (int)uniform(6);
	if (degenerate == 0) /* a point */
		for (int a = 0; a < 3; a++)
			t->v[1][a] = t->v[2][a] = t->v[0][a];
	else if (degenerate == 1) /* a repeated vertex: a segment */
		for (int a = 0; a < 3; a++)
			t->v[2][a] = t->v[1][a];
	else if (degenerate == 2) /* collinear: the midpoint */
		for (int a = 0; a < 3; a++)
			t->v[2][a] = (t->v[0][a] + t->v[1][a]) / 2;
}

/* At depth 4 every triangle takes the __int128 path; at depth 14 the
 * small ones take the int64 path. */
static void random_triangles_at(int L, int count)
{
	const int64_t top = ((int64_t)1 << L) - 1;
	const int64_t lo[3] = {0, 0, 0}, hi[3] = {top, top, top};
	int bad = 0;
	for (int i = 0; i < count && bad < 3; i++) {
		struct vd_snapped_tri t;
		random_triangle(&t, L, L > 8 ? (i % 2 ? 1 : 5) : i % 6);
		struct vset got = {0}, want = {0};
		vd_raster_triangle(&t, L, lo, hi, collect, &got);
		size_t raw = got.n;
		vset_finish(&got);
		ref_voxels(&t, L, &want);
		vset_finish(&want);
		if (raw != got.n) {
			fprintf(stderr, "triangle %d: a voxel was reported twice\n", i);
			bad++;
		}
		if (!vset_equal(&got, &want, "random triangle", morton_name)) {
			fprintf(stderr, "  triangle %d kind %d: (%lld %lld %lld) "
				"(%lld %lld %lld) (%lld %lld %lld)\n", i, i % 6,
				(long long)t.v[0][0], (long long)t.v[0][1],
				(long long)t.v[0][2], (long long)t.v[1][0],
				(long long)t.v[1][1], (long long)t.v[1][2],
				(long long)t.v[2][0], (long long)t.v[2][1],
				(long long)t.v[2][2]);
			bad++;
		}
		free(got.v);
		free(want.v);
	}
	CHECK_EQ(bad, 0);
}

static void test_random_triangles(void)
{
	random_triangles_at(4, 6000);
	random_triangles_at(14, 6000);
}

/* Large triangles take the __int128 path; a clip box restricts output. */
static void test_large_and_clipped(void)
{
	const int L = 10;
	const int64_t s = vd_snap_voxel(L);
	int bad = 0;
	for (int i = 0; i < 40 && !bad; i++) {
		struct vd_snapped_tri t;
		random_triangle(&t, L, i % 2 ? 0 : 2);
		/* clip to a random 24^3 window so the reference stays cheap */
		int64_t lo[3], hi[3];
		for (int a = 0; a < 3; a++) {
			int64_t mn = t.v[0][a], mx = t.v[0][a];
			for (int k = 1; k < 3; k++) {
				mn = t.v[k][a] < mn ? t.v[k][a] : mn;
				mx = t.v[k][a] > mx ? t.v[k][a] : mx;
			}
			int64_t span = mx / s - mn / s + 1;
			lo[a] = mn / s + uniform(span > 24 ? span - 23 : 1);
			hi[a] = lo[a] + 23;
		}
		struct vset got = {0}, want = {0};
		vd_raster_triangle(&t, L, lo, hi, collect, &got);
		vset_finish(&got);
		for (int64_t x = lo[0]; x <= hi[0]; x++)
			for (int64_t y = lo[1]; y <= hi[1]; y++)
				for (int64_t z = lo[2]; z <= hi[2]; z++) {
					if (x >= 1 << L || y >= 1 << L || z >= 1 << L)
						continue;
					int64_t b[3] = {x * s, y * s, z * s};
					if (ref_overlap(t.v, b, s))
						collect(&want, x, y, z);
				}
		vset_finish(&want);
		bad += !vset_equal(&got, &want, "large triangle", morton_name);
		free(got.v);
		free(want.v);
	}
	CHECK_EQ(bad, 0);
}

/* Rows longer than the rasterizer's table bound their columns one by
 * one: the same voxels through that path. */
static void test_untabled_rows(void)
{
	int max = vd_raster_table_max;
	vd_raster_table_max = 0;
	random_triangles_at(4, 3000);
	random_triangles_at(14, 3000);
	test_large_and_clipped();
	vd_raster_table_max = max;
}

static void test_box_overlap(void)
{
	const int L = 6;
	const int64_t s = vd_snap_voxel(L);
	int bad = 0;
	for (int i = 0; i < 20000; i++) {
		struct vd_snapped_tri t;
		random_triangle(&t, L, i % 6);
		int64_t size = (int64_t)1 << uniform(5), lo[3], blo[3];
		for (int a = 0; a < 3; a++) {
			lo[a] = uniform(64);
			blo[a] = lo[a] * s;
		}
		bad += vd_tri_box_overlap(&t, L, lo, size) != ref_overlap(t.v, blo, size * s);
	}
	CHECK_EQ(bad, 0);
}

/* ------------------------------------------------------- brick sink */

/* A cell of 2^k voxels (k >= 5) as a dense array of blocks. */
struct dense_cell {
	int k;                 /* blocks per side: 2^(k-5) */
	uint64_t *blocks;      /* block i at i * 512 words */
	size_t nblocks;
	int fetched;
};

static uint64_t *dense_block(void *ctx, uint64_t key)
{
	struct dense_cell *c = ctx;
	uint32_t x, y, z;
	vd_morton3_decode(key, &x, &y, &z);
	uint32_t n = 1u << (c->k - 5);
	CHECK(x < n && y < n && z < n);
	c->fetched++;
	return c->blocks + ((size_t)(x * n + y) * n + z) * 512;
}

/* The voxels set in the cell, as grid Morton keys, into `out`. */
static void dense_voxels(const struct dense_cell *c, const int64_t lo[3],
			 struct vset *out)
{
	uint32_t n = 1u << (c->k - 5);
	for (size_t i = 0; i < c->nblocks; i++)
		for (int j = 0; j < 512; j++)
			for (uint64_t bits = c->blocks[i * 512 + (size_t)j];
			     bits; bits &= bits - 1) {
				uint32_t m = (uint32_t)j << 6 |
					     (uint32_t)__builtin_ctzll(bits), l[3];
				vd_morton3_decode(m, &l[0], &l[1], &l[2]);
				int64_t b[3] = {(int64_t)(i / n / n),
						(int64_t)(i / n % n),
						(int64_t)(i % n)};
				collect(out, lo[0] + 32 * b[0] + l[0],
					lo[1] + 32 * b[1] + l[1],
					lo[2] + 32 * b[2] + l[2]);
			}
}

/* vd_raster_triangle_bricks sets the voxels of the span rasterizer (itself
 * checked against the reference above) and, for small triangles, of the
 * reference directly: at depth 14 in a cell of 2^7 (int64 path, tabled
 * and untabled blocks), runs across blocks, clip boxes of an octant, and
 * at depths 4 and 8 (the __int128 path; a cell smaller than a block). */
static void bricks_at(int L, int k, int count, int maxsize, int ref)
{
	const int64_t s = vd_snap_voxel(L), top = ((int64_t)1 << L) - 1;
	struct dense_cell c = {.k = k < 5 ? 5 : k};
	c.nblocks = (size_t)1 << 3 * (c.k - 5);
	c.blocks = calloc(c.nblocks * 512, sizeof *c.blocks);
	int bad = 0;
	for (int i = 0; i < count && bad < 3; i++) {
		/* a cell of the grid, and a triangle around it */
		int64_t lo[3], hi[3], clo[3], chi[3];
		struct vd_snapped_tri t;
		for (int a = 0; a < 3; a++) {
			lo[a] = k >= L ? 0 : uniform((int64_t)1 << (L - k)) << k;
			hi[a] = lo[a] + ((int64_t)1 << k) - 1;
			hi[a] = hi[a] > top ? top : hi[a];
		}
		int64_t size = 1 + uniform(maxsize);
		int64_t ctr[3];
		for (int a = 0; a < 3; a++)
			ctr[a] = (lo[a] - 2 + uniform(hi[a] - lo[a] + 5)) * s +
				 uniform(s);
		for (int j = 0; j < 3; j++)
			for (int a = 0; a < 3; a++) {
				int64_t v = ctr[a] + uniform(2 * size * s + 1) -
					    size * s;
				if (i % 7 == 0) /* on the lattice of voxels */
					v = v / s * s;
				t.v[j][a] = v < 0 ? 0 : v > (top + 1) * s ?
					    (top + 1) * s : v;
			}
		if (i % 11 == 0) /* a segment */
			for (int a = 0; a < 3; a++)
				t.v[2][a] = t.v[1][a];
		/* clip to the cell, or to one octant of it */
		for (int a = 0; a < 3; a++) {
			clo[a] = lo[a], chi[a] = hi[a];
			if (i % 3 == 0 && k > 5) {
				int64_t half = (int64_t)1 << (k - 1);
				clo[a] += (int64_t)(i >> a & 1) * half;
				chi[a] = clo[a] + half - 1;
			}
		}
		memset(c.blocks, 0, c.nblocks * 512 * sizeof *c.blocks);
		struct vd_brick_sink sink = {.block = dense_block, .ctx = &c};
		memcpy(sink.lo, lo, sizeof sink.lo);
		vd_raster_triangle_bricks(&t, L, clo, chi, &sink);
		struct vset got = {0}, want = {0};
		dense_voxels(&c, lo, &got);
		vset_finish(&got);
		vd_raster_triangle(&t, L, clo, chi, collect, &want);
		vset_finish(&want);
		bad += !vset_equal(&got, &want, "bricks vs spans", morton_name);
		if (ref && size <= 12) {
			struct vset all = {0}, in = {0};
			ref_voxels(&t, L, &all);
			for (size_t q = 0; q < all.n; q++) {
				uint32_t x, y, z;
				vd_morton3_decode(all.v[q], &x, &y, &z);
				if (x >= clo[0] && x <= chi[0] && y >= clo[1] &&
				    y <= chi[1] && z >= clo[2] && z <= chi[2])
					vset_add(&in, all.v[q]);
			}
			vset_finish(&in);
			bad += !vset_equal(&got, &in, "bricks vs reference",
					   morton_name);
			free(all.v);
			free(in.v);
		}
		free(got.v);
		free(want.v);
	}
	free(c.blocks);
	CHECK_EQ(bad, 0);
}

static void test_bricks(void)
{
	bricks_at(14, 7, 3000, 12, 1);   /* small: tabled, vs reference */
	bricks_at(14, 7, 4000, 2, 1);    /* tiny: runs of 1-3 voxels set as
					  * masks, across groups of 4 and
					  * blocks, every axis and slope */
	bricks_at(14, 7, 1500, 90, 0);   /* larger: untabled, clipped */
	bricks_at(14, 8, 300, 400, 0);   /* across the cell */
	bricks_at(8, 6, 1000, 40, 1);    /* one cell of 2^6 at depth 8 */
	bricks_at(4, 4, 1000, 16, 1);    /* __int128, cell < block */
}

/* vd_sort_keys (raster_bin's triangle order) against qsort: keys of 0 to
 * 41 bits above 16 bits of rising index, so a stable sort by the key is
 * the sort by the whole value; odd and even numbers of passes. */
static void test_sort_keys(void)
{
	enum { N = 5000 };
	static uint64_t a[N], tmp[N], want[N];
	int bad = 0;
	for (int bits = 0; bits <= 41; bits += 1 + bits / 4) {
		size_t n = bits == 9 ? 1 : 1 + (size_t)uniform(N);
		for (size_t i = 0; i < n; i++) {
			/* few distinct keys at times: many ties */
			uint64_t k = (uint64_t)uniform((int64_t)1 << 40);
			if (bits % 3 == 0)
				k %= 7;
			k &= bits ? ~0ull >> (64 - bits) : 0;
			a[i] = want[i] = k << 16 | i;
		}
		vd_sort_keys(a, tmp, n, 16, bits);
		qsort(want, n, sizeof *want, vset_cmp_u64);
		bad += memcmp(a, want, n * sizeof *a) != 0;
	}
	CHECK_EQ(bad, 0);
}

/* ------------------------------------------------- large triangles */

/* The voxels of the triangle in the box [lo, hi] (inside the grid): the
 * span rasterizer, and the reference on every voxel of the box. */
static int box_agrees(const struct vd_snapped_tri *t, int L,
		      const int64_t lo[3], const int64_t hi[3],
		      const char *what)
{
	const int64_t s = vd_snap_voxel(L);
	struct vset got = {0}, want = {0};
	vd_raster_triangle(t, L, lo, hi, collect, &got);
	size_t raw = got.n;
	vset_finish(&got);
	for (int64_t x = lo[0]; x <= hi[0]; x++)
		for (int64_t y = lo[1]; y <= hi[1]; y++)
			for (int64_t z = lo[2]; z <= hi[2]; z++) {
				int64_t b[3] = {x * s, y * s, z * s};
				if (ref_overlap(t->v, b, s))
					collect(&want, x, y, z);
			}
	vset_finish(&want);
	int ok = raw == got.n && vset_equal(&got, &want, what, morton_name);
	free(got.v);
	free(want.v);
	return ok;
}

/* The voxel (clamped to the grid) of a random point of the triangle whose
 * weight of vertex 0 is at most b0max, and the triangle's dominant normal
 * axis. */
static int point_on(const struct vd_snapped_tri *t, int L, double b0max,
		    int64_t c[3])
{
	const int64_t s = vd_snap_voxel(L), top = ((int64_t)1 << L) - 1;
	double b0 = b0max * (double)uniform(1 << 20) / (1 << 20);
	double b1 = (1 - b0) * (double)uniform(1 << 20) / (1 << 20);
	double b2 = 1 - b0 - b1;
	for (int a = 0; a < 3; a++) {
		double p = b0 * (double)t->v[0][a] + b1 * (double)t->v[1][a] +
			   b2 * (double)t->v[2][a];
		c[a] = (int64_t)(p / (double)s);
		c[a] = c[a] < 0 ? 0 : c[a] > top ? top : c[a];
	}
	i128 e1[3], e2[3], n[3];
	for (int a = 0; a < 3; a++) {
		e1[a] = (i128)t->v[1][a] - t->v[0][a];
		e2[a] = (i128)t->v[2][a] - t->v[0][a];
	}
	cross(e1, e2, n);
	int w = 0;
	for (int a = 1; a < 3; a++)
		if ((n[a] < 0 ? -n[a] : n[a]) > (n[w] < 0 ? -n[w] : n[w]))
			w = a;
	return w;
}

/* [c - below, c + above] along one axis, inside the grid */
static void box_axis(int64_t c, int64_t below, int64_t above, int L,
		     int64_t *lo, int64_t *hi)
{
	const int64_t top = ((int64_t)1 << L) - 1;
	*lo = c - below < 0 ? 0 : c - below;
	*hi = c + above > top ? top : c + above;
}

/* Triangles across the cube at depths 16..21 (extents of 2^19 snapped
 * units and more: an __int128 setup, int64 stepping), and triangles
 * reaching 2^38 units outside the cube (all __int128): small boxes
 * around a point of each, every voxel against the reference, through
 * the stack table, rows of 600 voxels through the heap table and with
 * no table, 600 rows (each with its plane estimate), and the brick
 * sink. */
static void test_large_triangles(void)
{
	const int max = vd_raster_table_max;
	struct dense_cell cell = {.k = 5, .nblocks = 1};
	cell.blocks = calloc(512, sizeof *cell.blocks);
	int bad = 0;
	for (int i = 0; i < 120 && bad < 3; i++) {
		const int far = i % 3 == 2;
		const int L = far ? 10 + (int)uniform(7) : 16 + i % 6;
		const int64_t s = vd_snap_voxel(L), side = s << L;
		struct vd_snapped_tri t;
		random_triangle(&t, L, i % 4 < 2 ? 0 : i % 4 == 2 ? 2 : 4);
		if (i % 3 == 1) {
			/* edges of long multiples of small lattice steps: a
			 * normal of small integers times a large factor, so
			 * the plane often meets voxel corners exactly (where
			 * the per-row estimate is most likely off by one) */
			int64_t m1 = 1 + uniform((int64_t)1 << (L - 2)),
				m2 = 1 + uniform((int64_t)1 << (L - 2));
			for (int a = 0; a < 3; a++) {
				t.v[0][a] = uniform((int64_t)1 << (L - 1)) * s;
				t.v[1][a] = t.v[0][a] + m1 * (uniform(7) - 3) * s;
				t.v[2][a] = t.v[0][a] + m2 * (uniform(7) - 3) * s;
				for (int k = 1; k < 3; k++)
					t.v[k][a] = t.v[k][a] < 0 ? 0 :
						    t.v[k][a] > side ? side :
						    t.v[k][a];
			}
		}
		if (far) { /* one vertex far outside, on any side */
			int a = (int)uniform(3);
			t.v[0][a] = uniform(2) ? -((int64_t)1 << 38) :
				    side + ((int64_t)1 << 38);
		}
		int64_t c[3], lo[3], hi[3];
		/* far: a point within the cube */
		int w = point_on(&t, L, far ? 0x1p-16 : 1, c);
		int u = (w + 1) % 3, v = (w + 2) % 3;
		/* the small box, inside c's block of 32^3 voxels */
		for (int a = 0; a < 3; a++) {
			box_axis(c[a], 4, 4, L, &lo[a], &hi[a]);
			int64_t b = c[a] & ~(int64_t)31;
			lo[a] = lo[a] < b ? b : lo[a];
			hi[a] = hi[a] > b + 31 ? b + 31 : hi[a];
		}
		bad += !box_agrees(&t, L, lo, hi, "large triangle, small box");
		struct vd_brick_sink sink = {.block = dense_block, .ctx = &cell};
		for (int a = 0; a < 3; a++)
			sink.lo[a] = c[a] & ~(int64_t)31;
		memset(cell.blocks, 0, 512 * sizeof *cell.blocks);
		vd_raster_triangle_bricks(&t, L, lo, hi, &sink);
		struct vset got = {0}, want = {0};
		dense_voxels(&cell, sink.lo, &got);
		vset_finish(&got);
		vd_raster_triangle(&t, L, lo, hi, collect, &want);
		vset_finish(&want);
		bad += !vset_equal(&got, &want, "large triangle, bricks",
				   morton_name);
		free(got.v);
		free(want.v);
		/* long rows: 600 voxels along v, 5 along u and w */
		for (int a = 0; a < 3; a++)
			box_axis(c[a], a == v ? 300 : 2, a == v ? 300 : 2, L,
				 &lo[a], &hi[a]);
		bad += !box_agrees(&t, L, lo, hi, "large triangle, heap table");
		vd_raster_table_max = 0;
		bad += !box_agrees(&t, L, lo, hi, "large triangle, no table");
		vd_raster_table_max = max;
		/* many rows: 600 voxels along u */
		for (int a = 0; a < 3; a++)
			box_axis(c[a], a == u ? 300 : 1, a == u ? 300 : 1, L,
				 &lo[a], &hi[a]);
		bad += !box_agrees(&t, L, lo, hi, "large triangle, many rows");
	}
	free(cell.blocks);
	CHECK_EQ(bad, 0);
}

/* Large triangles over a cell of 512^3 voxels at depths 16..18: the
 * brick rasterizer takes them a 128^3 tile at a time (tables and vector
 * quads within each); the voxels must be those of the span rasterizer,
 * which is not tiled (and is checked against the reference above), over
 * the whole cell and over clip boxes whose faces cut tiles, with the
 * vector build and without it. */
static void test_large_tiled(void)
{
	struct dense_cell cell = {.k = 9};
	cell.nblocks = (size_t)1 << 3 * (cell.k - 5);
	cell.blocks = calloc(cell.nblocks * 512, sizeof *cell.blocks);
	int bad = 0;
	size_t voxels = 0;
	for (int i = 0; i < 24 && bad < 3; i++) {
		const int L = 16 + i % 3;
		struct vd_snapped_tri t;
		random_triangle(&t, L, i % 4 < 2 ? 0 : i % 4 == 2 ? 2 : 4);
		int64_t c[3], clo[3], chi[3];
		point_on(&t, L, 1, c);
		struct vd_brick_sink sink = {.block = dense_block, .ctx = &cell};
		for (int a = 0; a < 3; a++) {
			sink.lo[a] = c[a] & ~(int64_t)511;
			clo[a] = sink.lo[a] + (i % 2 ? 37 + 5 * a : 0);
			chi[a] = sink.lo[a] + 511 - (i % 2 ? 100 - a : 0);
		}
		vd_raster_simd = i % 4 != 3;
		memset(cell.blocks, 0, cell.nblocks * 512 * sizeof *cell.blocks);
		vd_raster_triangle_bricks(&t, L, clo, chi, &sink);
		struct vset got = {0}, want = {0};
		dense_voxels(&cell, sink.lo, &got);
		vset_finish(&got);
		vd_raster_triangle(&t, L, clo, chi, collect, &want);
		vset_finish(&want);
		voxels += want.n;
		bad += !vset_equal(&got, &want, "large triangle, tiles",
				   morton_name);
		free(got.v);
		free(want.v);
	}
	vd_raster_simd = 1;
	free(cell.blocks);
	CHECK_EQ(bad, 0);
	/* the triangles did cross tiles: some 10^4 voxels each */
	CHECK(voxels > 24 * 10000);
}

/* ------------------------------------------------------------ snapping */

/* vd_snap_triangle against libm's llround (halves away from zero), on a
 * lattice of one world unit (scale exactly 1, so g = v - origin is exact):
 * halves, the doubles on either side of them, 2^52 and above, random
 * values; and the bounds of the range it accepts. */
static void test_snap_rounding(void)
{
	struct vd_transform tr;
	memset(&tr, 0, sizeof tr);
	tr.root_side = 0x1p24f;
	static const double frac[] = {0.0, 0.5, 0.25, 0.75, 0x1p-30};
	int bad = 0, n = 0;
	uint64_t r = 7; /* its own: the other tests keep their triangles */
	for (int it = 0; it < 200000; it++) {
		struct vd_triangle t;
		for (int k = 0; k < 3; k++)
			for (int a = 0; a < 3; a++) {
				r = r * 6364136223846793005ull +
				      1442695040888963407ull;
				int e = (int)(r >> 58);       /* 0..63 */
				float v = (float)((r >> 20 & 0xffff) *
						  ldexp(1.0, e % 40 - 8));
				t.v[k][a] = (r >> 19 & 1) ? -v : v;
			}
		for (int a = 0; a < 3; a++) {
			r = r * 6364136223846793005ull +
			      1442695040888963407ull;
			double o = frac[(r >> 61) % 5];
			/* the doubles beside o */
			int step = (int)(r >> 40 & 3);
			if (step == 1)
				o = nextafter(o, 1.0);
			else if (step == 2)
				o = nextafter(o, -1.0);
			tr.origin[a] = (r >> 39 & 1) ? -o : o;
		}
		struct vd_snapped_tri st;
		if (vd_snap_triangle(&st, &t, &tr) != VD_OK) {
			bad++;
			continue;
		}
		for (int k = 0; k < 3; k++)
			for (int a = 0; a < 3; a++, n++)
				bad += st.v[k][a] !=
				       llround((double)t.v[k][a] - tr.origin[a]);
	}
	CHECK_EQ(bad, 0);
	CHECK(n > 1000000);
	/* the edges: g = 1/2 - 2^-54, 1/2, 2^52 + 1, 2^53 - 1, +-2^60,
	 * -1/2 */
	static const float v[] = {0.0f, 1.0f, 0x1p52f, 0x1p53f, 0x1p60f,
				  -0x1p60f, 0.0f};
	static const double o[] = {-0x1.fffffffffffffp-2, 0.5, -1.0, 1.0, 0,
				   0, 0.5};
	for (int i = 0; i < 7; i++) {
		struct vd_triangle t = {{{v[i], 0, 0}, {0, 0, 0}, {0, 0, 0}}};
		struct vd_snapped_tri st;
		tr.origin[0] = o[i], tr.origin[1] = tr.origin[2] = 0;
		CHECK_EQ(vd_snap_triangle(&st, &t, &tr), VD_OK);
		CHECK_EQ(st.v[0][0], llround((double)v[i] - o[i]));
	}
	/* beyond 2^60 and not finite, at any of the nine */
	memset(tr.origin, 0, sizeof tr.origin);
	static const float badv[] = {0x1p61f, -0x1p61f, INFINITY, NAN};
	for (int i = 0; i < 4; i++)
		for (int j = 0; j < 9; j++) {
			struct vd_triangle t;
			memset(&t, 0, sizeof t);
			t.v[j / 3][j % 3] = badv[i];
			struct vd_snapped_tri st;
			CHECK_EQ(vd_snap_triangle(&st, &t, &tr), VD_ERR_RANGE);
		}
}

/* --------------------------------------------------------- real meshes */

/* The brute-force voxel set of a whole mesh: every triangle, every voxel
 * of its bounding box, the reference test. */
static void ref_mesh(const char *mesh, int L, struct vset *out)
{
	struct vd_mesh *m;
	CHECK_EQ(vd_mesh_open(&m, mesh), VD_OK);
	static struct vd_triangle buf[4096];
	size_t n;
	float lo[3] = {1e30f, 1e30f, 1e30f}, hi[3] = {-1e30f, -1e30f, -1e30f};
	while (vd_mesh_read(m, buf, 4096, &n) == VD_OK && n)
		for (size_t i = 0; i < n; i++)
			for (int k = 0; k < 3; k++)
				for (int a = 0; a < 3; a++) {
					float v = buf[i].v[k][a];
					lo[a] = v < lo[a] ? v : lo[a];
					hi[a] = v > hi[a] ? v : hi[a];
				}
	struct vd_transform tr;
	CHECK_EQ(vd_transform_init(&tr, lo, hi, L), VD_OK);
	CHECK_EQ(vd_mesh_rewind(m), VD_OK);
	while (vd_mesh_read(m, buf, 4096, &n) == VD_OK && n)
		for (size_t i = 0; i < n; i++) {
			struct vd_snapped_tri t;
			CHECK_EQ(vd_snap_triangle(&t, &buf[i], &tr), VD_OK);
			ref_voxels(&t, L, out);
		}
	vd_mesh_close(m);
	vset_finish(out);
}

/* With the triangles kept between passes over the file, with none kept,
 * and with a cache the mesh overflows after its first batch; in cells
 * from the budget and in one cell (L0 = 0: with the whole mesh kept, its
 * triangles are rasterized from memory, without a bin file). */
static void test_real_mesh_brute_force(void)
{
	static const uint64_t cache_max[3] = {UINT64_MAX, 0,
					      20000 * sizeof(struct vd_triangle)};
	for (int L = 6; L <= 8; L++) {
		struct vset got = {0}, want = {0};
		int n;
		ref_mesh("tests/data/bunny.ply", L, &want);
		CHECK(want.n > 1000);
		for (int c = 0; c < 6; c++) {
			vd_tri_cache_max = cache_max[c % 3];
			CHECK_EQ(test_voxelize("tests/data/bunny.ply", L,
					       c < 3 ? -1 : 0, dir, NULL), VD_OK);
			CHECK_EQ(test_load_chunks(dir, morton_key, NULL, &got, &n), VD_OK);
			CHECK(vset_equal(&got, &want, "bunny", morton_name));
			free(got.v);
			got = (struct vset){0};
		}
		free(want.v);
	}
	vd_tri_cache_max = UINT64_MAX;
}

/* A mesh for the bins: small triangles (some of them across 2^18 of the
 * lattice, the most a 24-byte record holds), a few spanning the whole cube
 * (too large for a 24-byte bin record: the .big bins) and, after them, a
 * vertex no face uses, beyond the triangles' bounds (with `far`): the grid
 * is the triangles' bounds, so the voxels must be those of the same mesh
 * without it, whatever the vertices' bounds guess. */
static void write_bins_mesh(const char *path, int far)
{
	enum { SMALL = 3000, LARGE = 4 };
	uint32_t nv = 3 * (SMALL + LARGE) + (far ? 1 : 0);
	FILE *f = fopen(path, "wb");
	CHECK(f != NULL);
	if (!f)
		return;
	fprintf(f, "ply\nformat binary_little_endian 1.0\nelement vertex %u\n"
		"property float x\nproperty float y\nproperty float z\n"
		"element face %u\nproperty list uchar int vertex_indices\n"
		"end_header\n", nv, SMALL + LARGE);
	for (int i = 0; i < SMALL + LARGE; i++) {
		float c[3], e = i < SMALL ? 0.03f : 1.0f;
		for (int a = 0; a < 3; a++)
			c[a] = i < SMALL ? (float)uniform(1000) / 1000.0f : 0.0f;
		for (int k = 0; k < 3; k++) {
			float v[3];
			for (int a = 0; a < 3; a++)
				v[a] = c[a] + (i < SMALL ? e * (float)uniform(1000) /
					       1000.0f : (float)((k + a + i) % 3 == 0)
					       * e);
			fwrite(v, 4, 3, f);
		}
	}
	if (far) {
		float v[3] = {5.0f, -3.0f, 7.0f};
		fwrite(v, 4, 3, f);
	}
	for (int i = 0; i < SMALL + LARGE; i++) {
		unsigned char n = 3;
		int32_t ix[3] = {3 * i, 3 * i + 1, 3 * i + 2};
		fwrite(&n, 1, 1, f);
		fwrite(ix, 4, 3, f);
	}
	CHECK_EQ(fclose(f), 0);
}

/* The bins (snapped 24-byte records, .big records, octant bins for a
 * cell split over the workers) and the grid guessed from the vertices:
 * every chunk level, with the triangles kept in memory and without,
 * gives the brute-force voxels of the triangles' grid. */
static void test_bins_snapped(void)
{
	char mesh[800], plain[800];
	snprintf(mesh, sizeof mesh, "%s.far.ply", dir);
	snprintf(plain, sizeof plain, "%s.plain.ply", dir);
	uint64_t seed = rng;
	write_bins_mesh(mesh, 1);
	rng = seed;
	write_bins_mesh(plain, 0);
	for (int L = 6; L <= 7; L++) {
		struct vset want = {0};
		ref_mesh(plain, L, &want);
		CHECK(want.n > 1000);
		for (int c = 0; c < 8; c++) {
			struct vset got = {0};
			int n;
			vd_tri_cache_max = c & 1 ? 0 : UINT64_MAX;
			int L0 = (c >> 1) - 1; /* -1 (automatic) .. 2 */
			CHECK_EQ(test_voxelize(mesh, L, L0, dir, NULL), VD_OK);
			CHECK_EQ(test_load_chunks(dir, morton_key, NULL, &got, &n),
				 VD_OK);
			CHECK(vset_equal(&got, &want, "bins", morton_name));
			free(got.v);
		}
		free(want.v);
	}
	vd_tri_cache_max = UINT64_MAX;
	unlink(mesh);
	unlink(plain);
}

static void test_chunked_equals_monolithic(void)
{
	struct vset base = {0};
	int n;
	CHECK_EQ(test_voxelize("tests/data/bunny.ply", 8, 0, dir, NULL), VD_OK);
	CHECK_EQ(test_load_chunks(dir, morton_key, NULL, &base, &n), VD_OK);
	CHECK_EQ(n, 1);
	for (int L0 = 1; L0 <= 3; L0++) {
		struct vset got = {0};
		CHECK_EQ(test_voxelize("tests/data/bunny.ply", 8, L0, dir, NULL), VD_OK);
		CHECK_EQ(test_load_chunks(dir, morton_key, NULL, &got, &n), VD_OK);
		CHECK(n > 1 && n <= 1 << 3 * L0);
		CHECK(vset_equal(&got, &base, "chunked", morton_name));
		free(got.v);
	}
	free(base.v);
}

/* A coarse voxel is set iff one of its 8 children is. */
static void test_resolutions_agree(void)
{
	struct vset fine = {0}, coarse = {0}, up = {0};
	int n;
	CHECK_EQ(test_voxelize("tests/data/bunny.ply", 9, 1, dir, NULL), VD_OK);
	CHECK_EQ(test_load_chunks(dir, morton_key, NULL, &fine, &n), VD_OK);
	CHECK_EQ(test_voxelize("tests/data/bunny.ply", 8, 2, dir, NULL), VD_OK);
	CHECK_EQ(test_load_chunks(dir, morton_key, NULL, &coarse, &n), VD_OK);
	for (size_t i = 0; i < fine.n; i++)
		vset_add(&up, fine.v[i] >> 3); /* Morton: parent = drop 3 bits */
	vset_finish(&up);
	CHECK(vset_equal(&up, &coarse, "2^9 folded vs 2^8", morton_name));
	free(fine.v);
	free(coarse.v);
	free(up.v);
}

/* ------------------------------------------ oa_am_underworks2 vs SymVox */

/* Every voxel of the triangle's closed bounding box (voxel side `side`,
 * coordinates as given: no snapping), tested by the reference. */
static void exact_voxels(const int64_t t[3][3], int L, int64_t side,
			 struct vset *out)
{
	const int64_t top = ((int64_t)1 << L) - 1;
	int64_t lo[3], hi[3];
	for (int a = 0; a < 3; a++) {
		int64_t mn = t[0][a], mx = t[0][a];
		for (int k = 1; k < 3; k++) {
			mn = t[k][a] < mn ? t[k][a] : mn;
			mx = t[k][a] > mx ? t[k][a] : mx;
		}
		lo[a] = mn / side - 1;
		hi[a] = mx / side;
		lo[a] = lo[a] < 0 ? 0 : lo[a];
		hi[a] = hi[a] > top ? top : hi[a];
	}
	for (int64_t x = lo[0]; x <= hi[0]; x++)
		for (int64_t y = lo[1]; y <= hi[1]; y++)
			for (int64_t z = lo[2]; z <= hi[2]; z++) {
				int64_t b[3] = {x * side, y * side, z * side};
				if (ref_overlap(t, b, side))
					collect(out, x, y, z);
			}
}

/* oa_am_underworks2 (a Quake 3 map) has mostly integer vertices (82% of
 * the corner coordinates are multiples of 2^-13; the rest are curved
 * patches), faces lying exactly on voxel faces and edges ending exactly on
 * voxel edges: exact touching everywhere. Its cube side, 3072, is not a
 * power of two times the coordinate unit, so snapping to 2^-24 of the side
 * moves most integer vertices (by < 1e-4) and breaks touches the real
 * geometry has. SymVox tests unsnapped coordinates in double precision,
 * exact for these integers. Pinned: our 2^9 count is the 1,249,500 SymVox
 * was compared with (issue 10), and the reference test on a 2^-13 lattice,
 * which holds the integer coordinates exactly, gives SymVox's 1,255,539
 * within 0.08% (406 over when rounding the finer coordinates, 203 under
 * when truncating them), not 0.5% below. */
static void test_underworks_vs_symvox(void)
{
	char mesh[1024];
	snprintf(mesh, sizeof mesh, "%s/oa_am_underworks2.ply",
		 test_shared_data());
	if (access(mesh, R_OK) != 0) {
		printf("skip: %s absent\n", mesh);
		return;
	}
	const int L = 9;
	struct vd_mesh *m;
	CHECK_EQ(vd_mesh_open(&m, mesh), VD_OK);
	static struct vd_triangle buf[4096];
	size_t n;
	double lo[3] = {1e30, 1e30, 1e30}, hi[3] = {-1e30, -1e30, -1e30};
	while (vd_mesh_read(m, buf, 4096, &n) == VD_OK && n)
		for (size_t i = 0; i < n; i++)
			for (int k = 0; k < 3; k++)
				for (int a = 0; a < 3; a++) {
					double v = buf[i].v[k][a];
					lo[a] = v < lo[a] ? v : lo[a];
					hi[a] = v > hi[a] ? v : hi[a];
				}
	/* the grid: cube of the largest extent, centred on the box. Every
	 * coordinate is below 2048 in magnitude, so a float is a multiple of
	 * 2^-13: scaled by 2^(14+L), coordinates relative to the origin are
	 * exact integers (the centre may be a half-ulp) and a voxel is
	 * 2^14 * side units. */
	double side = 0;
	for (int a = 0; a < 3; a++)
		side = hi[a] - lo[a] > side ? hi[a] - lo[a] : side;
	CHECK(side == 3072);
	const double unit = 0x1p13;
	int64_t vside = 2 * (int64_t)side * (int64_t)unit;
	int integral = 1;
	struct vset exact = {0};
	CHECK_EQ(vd_mesh_rewind(m), VD_OK);
	while (vd_mesh_read(m, buf, 4096, &n) == VD_OK && n)
		for (size_t i = 0; i < n; i++) {
			int64_t t[3][3];
			for (int k = 0; k < 3; k++)
				for (int a = 0; a < 3; a++) {
					/* 2 (v - (c - side/2)) = 2v - (lo+hi) + side,
					 * exact in double at this scale */
					double w = (2.0 * buf[i].v[k][a] -
						    (lo[a] + hi[a]) + side) * unit;
					integral += w == (double)(int64_t)w;
					t[k][a] = llround(w) << L;
				}
			exact_voxels(t, L, vside, &exact);
		}
	vd_mesh_close(m);
	printf("underworks: %d corner coordinates on the 2^-13 lattice\n",
	       integral);
	vset_finish(&exact);
	printf("underworks 2^9: %zu voxels on the 2^-13 lattice, SymVox "
	       "1255539\n", exact.n);

	struct vset got = {0};
	int nc;
	CHECK_EQ(test_voxelize(mesh, L, 1, dir, NULL), VD_OK);
	CHECK_EQ(test_load_chunks(dir, morton_key, NULL, &got, &nc), VD_OK);
	CHECK_EQ(got.n, (size_t)1249500);
	/* the snapped lattice loses ~6000 voxels of touching; the lattice
	 * that holds the integer coordinates lands within 0.08% of SymVox
	 * (what remains: rounding the curved patches' finer coordinates) */
	CHECK(exact.n > got.n + 5000);
	CHECK(exact.n > 1255539 - 1000 && exact.n < 1255539 + 1000);
	free(exact.v);
	free(got.v);
}

/* The rasterizer's tests again without the x86-64-v3 build of small
 * triangles (where the processor has it, the tests above ran it). */
static void test_plain_rasterizer(void)
{
	vd_raster_simd = 0;
	test_random_triangles();
	test_untabled_rows();
	test_bricks();
	test_large_triangles();
	vd_raster_simd = 1;
}

int main(void)
{
	dir = test_tmpdir("voxelize");
	RUN(test_random_triangles);
	RUN(test_large_and_clipped);
	RUN(test_untabled_rows);
	RUN(test_box_overlap);
	RUN(test_snap_rounding);
	RUN(test_bricks);
	RUN(test_sort_keys);
	RUN(test_large_triangles);
	RUN(test_large_tiled);
	RUN(test_real_mesh_brute_force);
	RUN(test_plain_rasterizer);
	RUN(test_chunked_equals_monolithic);
	RUN(test_bins_snapped);
	RUN(test_resolutions_agree);
	RUN(test_underworks_vs_symvox);
	return CHECK_DONE();
}
