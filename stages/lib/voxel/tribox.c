/* tribox.c - exact triangle/box overlap and triangle rasterization.
 *
 * The rule: a voxel is set iff the closed voxel cube and the closed
 * triangle overlap. By the separating axis theorem they are disjoint iff one
 * of 13 axes separates their projections: the 3 box axes, the triangle's
 * normal, and the 9 cross products of a triangle edge with a box axis. An
 * axis that is the zero vector (degenerate triangles) separates nothing,
 * which is exactly right for segments and points.
 *
 * Coordinates are snapped integers (VD_SNAP_ROOT_BITS lattice), so every
 * projection is an exact integer. Magnitudes: with coordinates relative to a
 * point near the triangle and extent E (snapped units), edge axes have
 * components <= E, normals <= 2E^2, projections <= 3*2E^2*E. int64 holds
 * that for E < 2^19 (2^(L-5) voxels at depth L); larger triangles use
 * __int128 (E < 2^40) for those products, but step their rows and columns
 * in int64 when the quotients, remainders and divisors fit (below 2^61:
 * every triangle inside the cube once L >= 13; they are bounded by the
 * extent in voxels and by |n| s <= 2E^2 s), which is where their time
 * goes; the rest (triangles reaching far outside the cube) stay __int128.
 * Into bricks, large triangles go a 128^3 tile at a time, so that each
 * tile's blocks are tabled and its columns set four at a time.
 */
#include "voxdag.h"
#include "voxel/voxel_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
/* small triangles have a second build for x86-64-v3 (see raster64v) */
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define RASTER_V3 1
#include <immintrin.h>
#else
#define RASTER_V3 0
#endif

typedef __int128 i128;

/* llround without the libm call (a tenth of voxelize's time went to it):
 * halves away from zero, as trunc(g + copysign(h, g)) with h the double
 * just below 1/2. In round-to-nearest that sum reaches the next integer
 * exactly when g's fraction is >= 1/2: below, it stays more than half a
 * step of the result's grid short of it (the fraction is on g's grid, so
 * 1/2 - f >= ulp(g), and h adds 2^-54); at f = 1/2 it is 2^-54 short,
 * under half a step, or a tie to the even integer for g = 1/2; from 2^52
 * up g is an integer and h under half its step. */
static inline int64_t round_half_away(double g)
{
	double h = copysign(0x1.fffffffffffffp-2, g);
	double s = g + h;       /* its own statement: never fused */
	return (int64_t)s;
}

int vd_snap_triangle(struct vd_snapped_tri *out, const struct vd_triangle *t,
		     const struct vd_transform *tr)
{
	_Static_assert(VD_SNAP_ROOT_BITS == 24, "scale: 2^VD_SNAP_ROOT_BITS");
	const double scale = 0x1p24 / (double)tr->root_side;
	double g[3][3];
	int ok = 1;
	/* one test for the nine, no branch: fabs(NaN) <= x is false too */
#pragma GCC unroll 9
	for (int i = 0; i < 9; i++) {
		int k = i / 3, a = i % 3;
		g[k][a] = ((double)t->v[k][a] - tr->origin[a]) * scale;
		ok &= fabs(g[k][a]) <= 0x1p60;
	}
	if (!ok)
		for (int k = 0; k < 3; k++)
			for (int a = 0; a < 3; a++)
				if (!(fabs(g[k][a]) <= 0x1p60))
					return vd_fail(VD_ERR_RANGE,
						       "non-finite or huge "
						       "vertex coordinate %g",
						       (double)t->v[k][a]);
#pragma GCC unroll 9
	for (int i = 0; i < 9; i++)
		out->v[i / 3][i % 3] = round_half_away(g[i / 3][i % 3]);
	return VD_OK;
}

int vd_raster_table_max = 1 << 16;

/* ------------------------------------------------------- brick emitter
 * Sets a column's run straight into its block (vd_brick_sink): the
 * Morton index of a voxel in its block is its three spread coordinates
 * ORed, the row's part computed once per row, the column's once per
 * column. A triangle's blocks are looked up once each, through a table
 * over the blocks of its bounding box when that is small (a fine grid's
 * triangles cover a few blocks, and consecutive columns alternate
 * between them). */

/* 5 bits spread to every third bit */
static const uint16_t d5[32] = {
	0, 1, 8, 9, 64, 65, 72, 73, 512, 513, 520, 521, 576, 577, 584, 585,
	4096, 4097, 4104, 4105, 4160, 4161, 4168, 4169, 4608, 4609, 4616,
	4617, 4672, 4673, 4680, 4681};

enum { EMIT_TAB = 64 };
/* large triangles are rasterized in cubes of this many voxels, aligned:
 * 4 x 4 x 4 blocks of 32, EMIT_TAB */
enum { RASTER_TILE = 128 };

/* A column's run is mostly 1 to 3 voxels (the plane crosses a column
 * of the axis where the normal is largest in at most 3): within two
 * aligned groups of 4 along w, one word of a brick each. For the run
 * a..j of voxels from the first group's (a <= j < 8), row sh (the Morton
 * shift of w) of run_tabs, m1[8 a + j] has the bits of its voxels in the
 * first group's word, m2[j] those in the second's (one table, so the
 * column loop keeps one address). */
struct run_tab {
	uint64_t m1[32], m2[8];
	uint16_t g[8];          /* group k's spread w: d5[4 k] << sh */
};
static const struct run_tab run_tabs[3] = {
	{{0x1, 0x3, 0x103, 0x303, 0x303, 0x303, 0x303, 0x303, 0, 0x2, 0x102,
	  0x302, 0x302, 0x302, 0x302, 0x302, 0, 0, 0x100, 0x300, 0x300, 0x300,
	  0x300, 0x300, 0, 0, 0, 0x200, 0x200, 0x200, 0x200, 0x200},
	 {0, 0, 0, 0, 0x1, 0x3, 0x103, 0x303},
	 {0, 64, 512, 576, 4096, 4160, 4608, 4672}},
	{{0x1, 0x5, 0x10005, 0x50005, 0x50005, 0x50005, 0x50005, 0x50005, 0,
	  0x4, 0x10004, 0x50004, 0x50004, 0x50004, 0x50004, 0x50004, 0, 0,
	  0x10000, 0x50000, 0x50000, 0x50000, 0x50000, 0x50000, 0, 0, 0,
	  0x40000, 0x40000, 0x40000, 0x40000, 0x40000},
	 {0, 0, 0, 0, 0x1, 0x5, 0x10005, 0x50005},
	 {0, 128, 1024, 1152, 8192, 8320, 9216, 9344}},
	{{0x1, 0x11, 0x100000011, 0x1100000011, 0x1100000011, 0x1100000011,
	  0x1100000011, 0x1100000011, 0, 0x10, 0x100000010, 0x1100000010,
	  0x1100000010, 0x1100000010, 0x1100000010, 0x1100000010, 0, 0,
	  0x100000000, 0x1100000000, 0x1100000000, 0x1100000000, 0x1100000000,
	  0x1100000000, 0, 0, 0, 0x1000000000, 0x1000000000, 0x1000000000,
	  0x1000000000, 0x1000000000},
	 {0, 0, 0, 0, 0x1, 0x11, 0x100000011, 0x1100000011},
	 {0, 256, 2048, 2304, 16384, 16640, 18432, 18688}}};

#if RASTER_V3
/* For raster64v's quads of columns (brick_quads): a row's 4 columns of
 * an aligned group of 4 along v and the 8 voxels of two groups of 4
 * along w make two 16-bit planes (v, w) of two words, in the order of
 * their bits in a word: Morton order of (v, w), w the low bit unless the
 * Morton shift of v is lower (w = x). The table of a plane's order
 * (w_low 0 or 1): runs[j], the bits of w = 0..j-1 in column 0 (w 4..7 in
 * the high half), so a run a..b is runs[b + 1] - runs[a]; v[l], column
 * l's shift. quad_m0[W]: the 16 bits of a word with u's bits 0, W the
 * axis w, that a plane is deposited into (pdep). */
struct quad_tab {
	int32_t runs[9];
	int32_t v[4];
};
static const struct quad_tab quad_tabs[2] = {
	{{0x0, 0x1, 0x5, 0x105, 0x505, 0x10505, 0x50505, 0x1050505,
	  0x5050505}, {0, 1, 4, 5}},
	{{0x0, 0x1, 0x3, 0x13, 0x33, 0x10033, 0x30033, 0x130033, 0x330033},
	 {0, 2, 8, 10}}};
static const uint64_t quad_m0[3] = {0x333300003333, 0x55005500550055,
				    0xf0f0f0f};
#endif

struct brick_emit {
	struct vd_brick_sink *sink;
	int ax[3];              /* u, v, w */
	int sh[3];              /* their Morton shifts: x 2, y 1, z 0 */
	int64_t lo[3];          /* the cell's first voxel along u, v, w */
	uint32_t tb[3];         /* the triangle's first block along u, v, w */
	uint32_t nbv, nbw;      /* table strides */
	int tabled, stop;
	uint32_t lu, mu;        /* the row: u within the cell, spread */
	uint32_t rowbase;       /* the row's first table entry */
	uint32_t last[3];       /* untabled: the last block */
	uint64_t *last_blk;
	uint64_t *tab[EMIT_TAB];
};

static void emit_init(struct brick_emit *e, struct vd_brick_sink *sink,
		      int u, int v, int w, const int64_t vlo[3],
		      const int64_t vhi[3])
{
	e->sink = sink;
	e->ax[0] = u, e->ax[1] = v, e->ax[2] = w;
	uint32_t n[3];
	for (int i = 0; i < 3; i++) {
		int a = e->ax[i];
		e->sh[i] = 2 - a;
		e->lo[i] = sink->lo[a];
		e->tb[i] = (uint32_t)(vlo[a] - sink->lo[a]) >> 5;
		n[i] = ((uint32_t)(vhi[a] - sink->lo[a]) >> 5) - e->tb[i] + 1;
	}
	e->nbv = n[1], e->nbw = n[2];
	e->tabled = (uint64_t)n[0] * n[1] * n[2] <= EMIT_TAB;
	if (e->tabled)
		memset(e->tab, 0, n[0] * n[1] * n[2] * sizeof *e->tab);
	e->last_blk = NULL;
	e->stop = 0;
}

static inline void emit_row(struct brick_emit *e, int64_t cu)
{
	e->lu = (uint32_t)(cu - e->lo[0]);
	e->mu = (uint32_t)d5[e->lu & 31] << e->sh[0];
	e->rowbase = ((e->lu >> 5) - e->tb[0]) * e->nbv * e->nbw;
}

/* The block at block coordinates (bu, bv, bw) of the cell from the sink,
 * remembered; NULL stops the triangle. */
static uint64_t *emit_fetch(struct brick_emit *e, uint64_t **slot,
			    uint32_t bu, uint32_t bv, uint32_t bw)
{
	uint32_t b[3];
	b[e->ax[0]] = bu, b[e->ax[1]] = bv, b[e->ax[2]] = bw;
	uint64_t *blk = e->sink->block(e->sink->ctx,
				       vd_morton3(b[0], b[1], b[2]));
	if (!blk) {
		e->stop = 1;
		return NULL;
	}
	if (slot)
		*slot = blk;
	e->last[0] = bu, e->last[1] = bv, e->last[2] = bw;
	e->last_blk = blk;
	return blk;
}

/* The voxels lv (along v) and lw..lw1 (along w, both within the cell) of
 * the row, a block at a time: through the table, or (an untabled
 * triangle) the last block, which the next column mostly shares. */
static inline __attribute__((always_inline)) void
emit_run(struct brick_emit *e, uint32_t lv, uint32_t lw, uint32_t lw1)
{
	uint32_t m = e->mu | (uint32_t)d5[lv & 31] << e->sh[1];
	const uint32_t bu = e->lu >> 5, bv = lv >> 5;
	const int sw = e->sh[2];
	for (;;) {
		uint32_t bw = lw >> 5, end = lw | 31;
		uint64_t **slot = NULL, *blk;
		if (e->tabled) {
			slot = &e->tab[e->rowbase + (bv - e->tb[1]) * e->nbw +
				       bw - e->tb[2]];
			blk = *slot;
		} else {
			blk = e->last_blk && bu == e->last[0] &&
			      bv == e->last[1] && bw == e->last[2] ?
			      e->last_blk : NULL;
		}
		if (!blk && !(blk = emit_fetch(e, slot, bu, bv, bw)))
			return;
		if (end > lw1)
			end = lw1;
		for (; lw <= end; lw++) {
			uint32_t mm = m | (uint32_t)d5[lw & 31] << sw;
			blk[mm >> 6] |= 1ull << (mm & 63);
		}
		if (lw > lw1)
			return;
	}
}

/* Per v of a triangle (one column of each row): the range of w the
 * axes e_k x unit_u admit (lo > hi: none); for the brick emitter, the
 * column's spread v within its block, shifted into place (m), and its
 * row of blocks' offset in the emitter's table (blk). kmax < 2^21. */
struct col_tab {
	int32_t lo, hi;
	uint32_t m;
	int32_t blk;
};

/* emit_run out of the way of a loop whose runs mostly take masks */
static __attribute__((noinline)) void emit_run_cold(struct brick_emit *e,
						    uint32_t lv, uint32_t lw,
						    uint32_t lw1)
{
	emit_run(e, lv, lw, lw1);
}

#define RT int64_t
#define ST int64_t
#define RN(name) name##64
#include "voxel/tribox_impl.h"
#undef RT
#undef ST
#undef RN
#define RT i128
#define ST int64_t
#define RN(name) name##128s
#include "voxel/tribox_impl.h"
#undef RT
#undef ST
#undef RN
#define RT i128
#define ST i128
#define RN(name) name##128
#include "voxel/tribox_impl.h"
#undef RT
#undef ST
#undef RN

/* Small triangles once more for x86-64-v3 (AVX2, BMI2): the stepping
 * states of rows and columns in vector lanes, shifts without the count
 * in cl. Chosen at run time, when the processor has it. */
#if RASTER_V3
#pragma GCC push_options
#pragma GCC target("arch=x86-64-v3")
#define RN_VEC
#define RT int64_t
#define ST int64_t
#define RN(name) name##64v
#include "voxel/tribox_impl.h"
#undef RT
#undef ST
#undef RN
/* and large triangles whose stepping fits int64: the Sponza's, two
 * thirds of its voxelize time in raster_bricks128s before */
#define RT i128
#define ST int64_t
#define RN(name) name##128sv
#include "voxel/tribox_impl.h"
#undef RT
#undef ST
#undef RN
#undef RN_VEC
#pragma GCC pop_options
#endif

int vd_raster_simd = 1;

#if RASTER_V3
/* 1 when small triangles take raster64v */
static int raster_v3(void)
{
	return vd_raster_simd && __builtin_cpu_supports("x86-64-v3");
}
#endif

/* floor(a / 2^sh), without relying on >> of a negative value:
 * floor(a / s) = -1 - floor((-1 - a) / s) */
static inline int64_t floor_shift(int64_t a, int sh)
{
	return a >= 0 ? a >> sh : ~(~a >> sh);
}

int vd_tri_box_overlap(const struct vd_snapped_tri *t, int levels,
		       const int64_t lo[3], int64_t size)
{
	const int64_t unit = vd_snap_voxel(levels), s = size * unit;
	int64_t p[3];
	for (int a = 0; a < 3; a++) {
		/* the 3 box axes */
		int64_t mn = t->v[0][a], mx = t->v[0][a];
		for (int k = 1; k < 3; k++) {
			if (t->v[k][a] < mn)
				mn = t->v[k][a];
			if (t->v[k][a] > mx)
				mx = t->v[k][a];
		}
		p[a] = lo[a] * unit;
		if (mx < p[a] || mn > p[a] + s)
			return 0;
	}
	/* relative to the box corner: magnitudes stay within the grid */
	int64_t r[3][3], zero[3] = {0, 0, 0};
	for (int k = 0; k < 3; k++)
		for (int a = 0; a < 3; a++)
			r[k][a] = t->v[k][a] - p[a];
	struct axes128 x;
	axes_init128(&x, r, s);
	return axes_overlap128(&x, zero);
}

/* The triangle's voxel range clipped to [clip_lo, clip_hi], the origin
 * (vlo's low corner) and whether int64 holds the tests; 0 if empty. s is
 * a voxel's side (vd_snap_voxel: a power of two). */
static int raster_range(const struct vd_snapped_tri *t, int64_t s,
			const int64_t clip_lo[3], const int64_t clip_hi[3],
			int64_t vlo[3], int64_t vhi[3], int64_t origin[3],
			int *small)
{
	int64_t extent = 0;
	/* s is a voxel, 2^sh lattice steps: shifts, not six 64-bit
	 * divisions a triangle */
	const int sh = __builtin_ctzll((unsigned long long)s);
#pragma GCC unroll 3
	for (int a = 0; a < 3; a++) {
		int64_t mn = t->v[0][a], mx = t->v[0][a];
		for (int k = 1; k < 3; k++) {
			mn = t->v[k][a] < mn ? t->v[k][a] : mn;
			mx = t->v[k][a] > mx ? t->v[k][a] : mx;
		}
		/* voxel i spans [i*s, (i+1)*s]: the box axes, exactly */
		vlo[a] = floor_shift(mn + s - 1, sh) - 1;
		vhi[a] = floor_shift(mx, sh);
		if (vlo[a] < clip_lo[a])
			vlo[a] = clip_lo[a];
		if (vhi[a] > clip_hi[a])
			vhi[a] = clip_hi[a];
		if (vlo[a] > vhi[a])
			return 0;
		origin[a] = vlo[a] * s;
		/* the largest relative coordinate a test will meet */
		int64_t e = (vhi[a] + 1) * s - origin[a];
		if (mx - origin[a] > e)
			e = mx - origin[a];
		if (origin[a] - mn > e)
			e = origin[a] - mn;
		if (e > extent)
			extent = e;
	}
	*small = extent < ((int64_t)1 << 19);
	return 1;
}

/* raster128s, in vectors where the processor has them */
static int raster_large(const struct vd_snapped_tri *t, const int64_t vlo[3],
			const int64_t vhi[3], const int64_t origin[3],
			int64_t s, vd_span_fn fn, void *ctx)
{
#if RASTER_V3
	if (raster_v3())
		return raster128sv(t, vlo, vhi, origin, s, fn, ctx);
#endif
	return raster128s(t, vlo, vhi, origin, s, fn, ctx);
}

void vd_raster_triangle_spans(const struct vd_snapped_tri *t, int levels,
			      const int64_t clip_lo[3],
			      const int64_t clip_hi[3], vd_span_fn fn,
			      void *ctx)
{
	const int64_t s = vd_snap_voxel(levels);
	int64_t vlo[3], vhi[3], origin[3];
	int small;
	if (!raster_range(t, s, clip_lo, clip_hi, vlo, vhi, origin, &small))
		return;
	if (small) {
#if RASTER_V3
		if (raster_v3()) {
			raster64v(t, vlo, vhi, origin, s, fn, ctx);
			return;
		}
#endif
		raster64(t, vlo, vhi, origin, s, fn, ctx);
	}
	else if (!raster_large(t, vlo, vhi, origin, s, fn, ctx))
		raster128(t, vlo, vhi, origin, s, fn, ctx);
}

/* raster_bricks128s, in vectors where the processor has them */
static int raster_bricks_large(const struct vd_snapped_tri *t,
			       const int64_t vlo[3], const int64_t vhi[3],
			       const int64_t origin[3], int64_t s,
			       struct vd_brick_sink *sink)
{
#if RASTER_V3
	if (raster_v3())
		return raster_bricks128sv(t, vlo, vhi, origin, s, sink);
#endif
	return raster_bricks128s(t, vlo, vhi, origin, s, sink);
}

void vd_raster_triangle_bricks(const struct vd_snapped_tri *t, int levels,
			       const int64_t clip_lo[3],
			       const int64_t clip_hi[3],
			       struct vd_brick_sink *sink)
{
	const int64_t s = vd_snap_voxel(levels);
	int64_t vlo[3], vhi[3], origin[3];
	int small;
	if (!raster_range(t, s, clip_lo, clip_hi, vlo, vhi, origin, &small))
		return;
	if (small) {
#if RASTER_V3
		if (raster_v3()) {
			raster_bricks64v(t, vlo, vhi, origin, s, sink);
			return;
		}
#endif
		raster_bricks64(t, vlo, vhi, origin, s, sink);
		return;
	}
	/* A large triangle a tile at a time: the rasterizer tables a
	 * triangle's blocks (and sets them four columns at a time) only when
	 * its box spans at most EMIT_TAB of them, 4 x 4 x 4 of 32 voxels;
	 * the Sponza's triangles at 2^14 span hundreds, and took the column
	 * by column path (two thirds of voxelize's time). Tiles are disjoint
	 * and each rasterized exactly within its box, so the voxels are the
	 * same; a tile the triangle misses costs one exact box test. */
	int64_t first[3], last[3], tile[3], tlo[3], thi[3];
	for (int a = 0; a < 3; a++) {
		first[a] = vlo[a] / RASTER_TILE * RASTER_TILE;
		last[a] = vhi[a] / RASTER_TILE * RASTER_TILE;
	}
	for (tile[0] = first[0]; tile[0] <= last[0]; tile[0] += RASTER_TILE)
	for (tile[1] = first[1]; tile[1] <= last[1]; tile[1] += RASTER_TILE)
	for (tile[2] = first[2]; tile[2] <= last[2]; tile[2] += RASTER_TILE) {
		if (!vd_tri_box_overlap(t, levels, tile, RASTER_TILE))
			continue;
		for (int a = 0; a < 3; a++) {
			tlo[a] = tile[a] > vlo[a] ? tile[a] : vlo[a];
			thi[a] = tile[a] + RASTER_TILE - 1 < vhi[a] ?
				 tile[a] + RASTER_TILE - 1 : vhi[a];
		}
		int64_t rlo[3], rhi[3];
		if (!raster_range(t, s, tlo, thi, rlo, rhi, origin, &small))
			continue;
		if (!raster_bricks_large(t, rlo, rhi, origin, s, sink))
			raster_bricks128(t, rlo, rhi, origin, s, sink);
	}
}

struct each_voxel {
	vd_voxel_fn fn;
	void *ctx;
};

static void each_voxel(void *vctx, int axis, int64_t x, int64_t y, int64_t z,
		       int64_t n)
{
	const struct each_voxel *e = vctx;
	int64_t p[3] = {x, y, z};
	for (int64_t i = 0; i < n; i++, p[axis]++)
		e->fn(e->ctx, p[0], p[1], p[2]);
}

void vd_raster_triangle(const struct vd_snapped_tri *t, int levels,
			const int64_t clip_lo[3], const int64_t clip_hi[3],
			vd_voxel_fn fn, void *ctx)
{
	struct each_voxel e = {fn, ctx};
	vd_raster_triangle_spans(t, levels, clip_lo, clip_hi, each_voxel, &e);
}
