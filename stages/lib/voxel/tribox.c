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
 * __int128 (E < 2^40).
 */
#include "voxdag.h"
#include "voxel/voxelize_internal.h"

#include <math.h>
#include <stdlib.h>

typedef __int128 i128;

/* llround without the libm call (a tenth of voxelize's time went to it):
 * halves away from zero. For |g| < 2^52 the truncation and g - i are
 * exact; above, g is an integer and f is 0. */
static inline int64_t round_half_away(double g)
{
	int64_t i = (int64_t)g;
	double f = g - (double)i;
	return i + (f >= 0.5) - (f <= -0.5);
}

int vd_snap_triangle(struct vd_snapped_tri *out, const struct vd_triangle *t,
		     const struct vd_transform *tr)
{
	const double scale = ldexp(1.0, VD_SNAP_ROOT_BITS) / (double)tr->root_side;
	for (int k = 0; k < 3; k++)
		for (int a = 0; a < 3; a++) {
			double g = ((double)t->v[k][a] - tr->origin[a]) * scale;
			if (!isfinite(g) || fabs(g) > 0x1p60)
				return vd_fail(VD_ERR_RANGE, "non-finite or huge "
					       "vertex coordinate %g",
					       (double)t->v[k][a]);
			out->v[k][a] = round_half_away(g);
		}
	return VD_OK;
}

/* floor and ceil without libm calls (values here are far inside int64) */
static inline double vd_floor(double x)
{
	double i = (double)(int64_t)x;
	return i - (x < i);
}

static inline double vd_ceil(double x)
{
	double i = (double)(int64_t)x;
	return i + (x > i);
}

int vd_raster_table_max = 512;

#define RT int64_t
#define RN(name) name##64
#include "voxel/tribox_impl.h"
#undef RT
#undef RN
#define RT i128
#define RN(name) name##128
#include "voxel/tribox_impl.h"
#undef RT
#undef RN

static int64_t floor_div(int64_t a, int64_t b) /* b > 0 */
{
	int64_t q = a / b;
	return q - (a % b != 0 && a < 0);
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

void vd_raster_triangle_spans(const struct vd_snapped_tri *t, int levels,
			      const int64_t clip_lo[3],
			      const int64_t clip_hi[3], vd_span_fn fn,
			      void *ctx)
{
	const int64_t s = vd_snap_voxel(levels);
	int64_t vlo[3], vhi[3], origin[3], extent = 0;
	for (int a = 0; a < 3; a++) {
		int64_t mn = t->v[0][a], mx = t->v[0][a];
		for (int k = 1; k < 3; k++) {
			if (t->v[k][a] < mn)
				mn = t->v[k][a];
			if (t->v[k][a] > mx)
				mx = t->v[k][a];
		}
		/* voxel i spans [i*s, (i+1)*s]: the box axes, exactly */
		vlo[a] = floor_div(mn + s - 1, s) - 1;
		vhi[a] = floor_div(mx, s);
		if (vlo[a] < clip_lo[a])
			vlo[a] = clip_lo[a];
		if (vhi[a] > clip_hi[a])
			vhi[a] = clip_hi[a];
		if (vlo[a] > vhi[a])
			return;
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
	if (extent < ((int64_t)1 << 19))
		raster64(t, vlo, vhi, origin, s, fn, ctx);
	else
		raster128(t, vlo, vhi, origin, s, fn, ctx);
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
