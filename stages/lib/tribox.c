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
#include "voxelize_internal.h"

#include <math.h>
#include <stdlib.h>

typedef __int128 i128;

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
			out->v[k][a] = llround(g);
		}
	return VD_OK;
}

/* Interval [lo, hi] of a box's projection onto axis a: the box has its low
 * corner at p and side s (snapped units). */
#define BOX_RANGE(T, a, lo_off, hi_off, s)                                     \
	do {                                                                   \
		lo_off = 0;                                                    \
		hi_off = 0;                                                    \
		for (int i_ = 0; i_ < 3; i_++) {                               \
			if ((a)[i_] < 0)                                       \
				lo_off += (T)(a)[i_] * (s);                    \
			else                                                   \
				hi_off += (T)(a)[i_] * (s);                    \
		}                                                              \
	} while (0)

/* Precomputed separating axes of one triangle in one integer type: the
 * normal and the 9 edge axes, each with the triangle's projection interval
 * and the offsets of a box's interval from the projection of its low
 * corner. */
#define DEFINE_AXES(T, NAME)                                                   \
	struct NAME {                                                          \
		T a[10][3];                                                    \
		T tmin[10], tmax[10];                                          \
		T blo[10], bhi[10];                                            \
	};                                                                     \
	static void NAME##_init(struct NAME *x, const int64_t t[3][3],         \
				int64_t s)                                     \
	{                                                                      \
		T e[3][3];                                                     \
		for (int k = 0; k < 3; k++)                                    \
			for (int i = 0; i < 3; i++)                            \
				e[k][i] = (T)t[(k + 1) % 3][i] - (T)t[k][i];   \
		x->a[0][0] = e[0][1] * e[1][2] - e[0][2] * e[1][1];            \
		x->a[0][1] = e[0][2] * e[1][0] - e[0][0] * e[1][2];            \
		x->a[0][2] = e[0][0] * e[1][1] - e[0][1] * e[1][0];            \
		for (int k = 0; k < 3; k++) {                                  \
			/* e x X = (0, ez, -ey), e x Y = (-ez, 0, ex),         \
			 * e x Z = (ey, -ex, 0) */                             \
			T *ax = x->a[1 + 3 * k];                               \
			ax[0] = 0, ax[1] = e[k][2], ax[2] = -e[k][1];          \
			ax[3] = -e[k][2], ax[4] = 0, ax[5] = e[k][0];          \
			ax[6] = e[k][1], ax[7] = -e[k][0], ax[8] = 0;          \
		}                                                              \
		for (int j = 0; j < 10; j++) {                                 \
			T lo = 0, hi = 0;                                      \
			for (int k = 0; k < 3; k++) {                          \
				T d = x->a[j][0] * t[k][0] +                   \
				      x->a[j][1] * t[k][1] +                   \
				      x->a[j][2] * t[k][2];                    \
				if (k == 0 || d < lo)                          \
					lo = d;                                \
				if (k == 0 || d > hi)                          \
					hi = d;                                \
			}                                                      \
			x->tmin[j] = lo;                                       \
			x->tmax[j] = hi;                                       \
			BOX_RANGE(T, x->a[j], x->blo[j], x->bhi[j], s);        \
		}                                                              \
	}                                                                      \
	/* 1 if no axis separates the box with low corner p. */                \
	static inline int NAME##_overlap(const struct NAME *x,                 \
					 const int64_t p[3])                   \
	{                                                                      \
		for (int j = 0; j < 10; j++) {                                 \
			T d = x->a[j][0] * p[0] + x->a[j][1] * p[1] +          \
			      x->a[j][2] * p[2];                               \
			if (d + x->bhi[j] < x->tmin[j] ||                      \
			    d + x->blo[j] > x->tmax[j])                        \
				return 0;                                      \
		}                                                              \
		return 1;                                                      \
	}

DEFINE_AXES(int64_t, axes64)
DEFINE_AXES(i128, axes128)

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
	axes128_init(&x, r, s);
	return axes128_overlap(&x, zero);
}

/* Visits every voxel of [clip_lo, clip_hi] (inclusive, voxels) that the
 * triangle overlaps. Columns run along the axis w where the normal is
 * largest, so the plane crosses few voxels of a column; the edge axes
 * perpendicular to w do not change along a column and are tested once per
 * column; the others are stepped incrementally. Only the voxels near the
 * plane (found in double, widened by one voxel each way) are tested, and
 * every test is exact. */
#define DEFINE_RASTER(T, NAME, AXES)                                           \
	static void NAME(const struct vd_snapped_tri *tri,                     \
			 const int64_t vlo[3], const int64_t vhi[3],           \
			 const int64_t origin[3], int64_t s, vd_voxel_fn fn,   \
			 void *ctx)                                            \
	{                                                                      \
		int64_t t[3][3];                                               \
		for (int k = 0; k < 3; k++)                                    \
			for (int a = 0; a < 3; a++)                            \
				t[k][a] = tri->v[k][a] - origin[a];            \
		struct AXES x;                                                 \
		AXES##_init(&x, t, s);                                         \
		int w = 0;                                                     \
		double best = -1;                                              \
		for (int a = 0; a < 3; a++) {                                  \
			double m = fabs((double)x.a[0][a]);                    \
			if (m > best)                                          \
				best = m, w = a;                               \
		}                                                              \
		int u = (w + 1) % 3, v = (w + 2) % 3;                          \
		/* axes 1 + 3k + w are e_k x (unit w): zero w component */     \
		int col[3], nvox = 0, vox_ax[7];                               \
		for (int k = 0; k < 3; k++)                                    \
			col[k] = 1 + 3 * k + w;                                \
		vox_ax[nvox++] = 0;                                            \
		for (int j = 1; j < 10; j++)                                   \
			if ((j - 1) % 3 != w)                                  \
				vox_ax[nvox++] = j;                            \
		T step[7];                                                     \
		for (int i = 0; i < 7; i++)                                    \
			step[i] = x.a[vox_ax[i]][w] * s;                       \
		double nw = (double)x.a[0][w];                                 \
		double inv_s = 1.0 / (double)s;                                \
		for (int64_t cu = vlo[u]; cu <= vhi[u]; cu++) {                \
			int64_t pu = cu * s - origin[u];                       \
			for (int64_t cv = vlo[v]; cv <= vhi[v]; cv++) {        \
				int64_t pv = cv * s - origin[v];               \
				int skip = 0;                                  \
				for (int k = 0; k < 3 && !skip; k++) {         \
					const T *ax = x.a[col[k]];             \
					T d = ax[u] * pu + ax[v] * pv;         \
					skip = d + x.bhi[col[k]] <             \
						       x.tmin[col[k]] ||       \
					       d + x.blo[col[k]] >             \
						       x.tmax[col[k]];         \
				}                                              \
				if (skip)                                      \
					continue;                              \
				int64_t w0 = vlo[w], w1 = vhi[w];              \
				if (nw != 0) {                                 \
					double r = (double)(x.tmin[0] -        \
						x.a[0][u] * pu -               \
						x.a[0][v] * pv);               \
					double ga = (r - (double)x.bhi[0]) /   \
						    nw,                        \
					       gb = (r - (double)x.blo[0]) /   \
						    nw;                        \
					double g0 = ga < gb ? ga : gb,         \
					       g1 = ga < gb ? gb : ga;         \
					/* [g0, g1]: low corners passing the  \
					 * plane test; the double error is    \
					 * far below the 1e-6 voxel margin.  \
					 */                                   \
					double o = (double)origin[w];          \
					double f0 = ceil((g0 + o) * inv_s -    \
							 1e-6),                \
					       f1 = floor((g1 + o) * inv_s +   \
							  1e-6);               \
					if (f0 > (double)w0)                   \
						w0 = (int64_t)f0;              \
					if (f1 < (double)w1)                   \
						w1 = (int64_t)f1;              \
				}                                              \
				if (w0 > w1)                                   \
					continue;                              \
				T d[7];                                        \
				int64_t pw = w0 * s - origin[w];               \
				for (int i = 0; i < 7; i++) {                  \
					const T *ax = x.a[vox_ax[i]];          \
					d[i] = ax[u] * pu + ax[v] * pv +       \
					       ax[w] * pw;                     \
				}                                              \
				int64_t vox[3];                                \
				vox[u] = cu, vox[v] = cv;                      \
				for (int64_t cw = w0; cw <= w1; cw++) {        \
					int ok = 1;                            \
					for (int i = 0; i < 7; i++) {          \
						int j = vox_ax[i];             \
						ok &= d[i] + x.bhi[j] >=       \
							      x.tmin[j] &&     \
						      d[i] + x.blo[j] <=       \
							      x.tmax[j];       \
						d[i] += step[i];               \
					}                                      \
					if (ok) {                              \
						vox[w] = cw;                   \
						fn(ctx, vox[0], vox[1],        \
						   vox[2]);                    \
					}                                      \
				}                                              \
			}                                              \
		}                                                      \
	}

DEFINE_RASTER(int64_t, raster64, axes64)
DEFINE_RASTER(i128, raster128, axes128)

void vd_raster_triangle(const struct vd_snapped_tri *t, int levels,
			const int64_t clip_lo[3], const int64_t clip_hi[3],
			vd_voxel_fn fn, void *ctx)
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
