/* tribox_impl.h - the separating axes and the rasterizer, written once for
 * an integer type. tribox.c includes it twice: with RT = int64_t for small
 * triangles, RT = __int128 for large ones (see the bounds in tribox.c).
 *
 * Define before including: RT (the type) and RN(name) (a name suffix).
 */

/* The normal (axis 0) and the 9 edge axes e_k x unit_a (axis 1 + 3k + a),
 * each with the triangle's projection interval [tmin, tmax] and the offsets
 * [blo, bhi] of a box's interval from the projection of its low corner. */
struct RN(axes) {
	RT a[10][3];
	RT tmin[10], tmax[10];
	RT blo[10], bhi[10];
};

static void RN(axes_init)(struct RN(axes) *x, const int64_t t[3][3], int64_t s)
{
	RT e[3][3];
	for (int k = 0; k < 3; k++)
		for (int i = 0; i < 3; i++)
			e[k][i] = (RT)t[(k + 1) % 3][i] - (RT)t[k][i];
	x->a[0][0] = e[0][1] * e[1][2] - e[0][2] * e[1][1];
	x->a[0][1] = e[0][2] * e[1][0] - e[0][0] * e[1][2];
	x->a[0][2] = e[0][0] * e[1][1] - e[0][1] * e[1][0];
	for (int k = 0; k < 3; k++) {
		/* e x X = (0, ez, -ey), e x Y = (-ez, 0, ex), e x Z = (ey, -ex, 0) */
		RT *ax = x->a[1 + 3 * k];
		ax[0] = 0, ax[1] = e[k][2], ax[2] = -e[k][1];
		ax[3] = -e[k][2], ax[4] = 0, ax[5] = e[k][0];
		ax[6] = e[k][1], ax[7] = -e[k][0], ax[8] = 0;
	}
	for (int j = 0; j < 10; j++) {
		RT lo = 0, hi = 0;
		for (int k = 0; k < 3; k++) {
			RT d = x->a[j][0] * t[k][0] + x->a[j][1] * t[k][1] +
			       x->a[j][2] * t[k][2];
			if (k == 0 || d < lo)
				lo = d;
			if (k == 0 || d > hi)
				hi = d;
		}
		x->tmin[j] = lo;
		x->tmax[j] = hi;
		x->blo[j] = x->bhi[j] = 0;
		for (int i = 0; i < 3; i++) {
			if (x->a[j][i] < 0)
				x->blo[j] += x->a[j][i] * s;
			else
				x->bhi[j] += x->a[j][i] * s;
		}
	}
}

/* 1 if no axis separates the box with low corner p. */
static inline int RN(axes_overlap)(const struct RN(axes) *x, const int64_t p[3])
{
	for (int j = 0; j < 10; j++) {
		RT d = x->a[j][0] * p[0] + x->a[j][1] * p[1] + x->a[j][2] * p[2];
		if (d + x->bhi[j] < x->tmin[j] || d + x->blo[j] > x->tmax[j])
			return 0;
	}
	return 1;
}

/* Narrows [*lo, *hi] (voxel indices along one axis) to the voxels whose
 * low corner q = index*s - origin may satisfy lower <= a*q <= upper, from
 * a double estimate widened by a margin; the caller's exact tests decide.
 * Values here stay below 2^53 in magnitude or are divided by the largest
 * component, so the estimate errs by far less than the margin. */
static inline void RN(narrow)(double lower, double upper, double a,
			      double origin, double inv_s, int64_t *lo,
			      int64_t *hi)
{
	if (a == 0) {
		if (lower > 0.5 || upper < -0.5) /* integers: 0 must fit */
			*hi = *lo - 1;
		return;
	}
	double q0 = lower / a, q1 = upper / a;
	if (a < 0) {
		double tmp = q0;
		q0 = q1;
		q1 = tmp;
	}
	const double margin = 1.0 / 64; /* lattice steps */
	double f0 = vd_ceil((q0 - margin + origin) * inv_s);
	double f1 = vd_floor((q1 + margin + origin) * inv_s);
	if (f0 > (double)*lo)
		*lo = f0 > (double)*hi ? *hi + 1 : (int64_t)f0;
	if (f1 < (double)*hi)
		*hi = f1 < (double)*lo ? *lo - 1 : (int64_t)f1;
}

/* Visits every voxel of [vlo, vhi] that the triangle overlaps. Columns run
 * along the axis w where the normal is largest, so the plane crosses few
 * voxels of a column. The edge axes e_k x unit_w are constant along a
 * column: per row (fixed u) they bound the range of v, and per column they
 * are tested exactly once. The plane bounds the range of w in a column; the
 * remaining 7 axes are tested exactly per voxel, stepped incrementally. */
static void RN(raster)(const struct vd_snapped_tri *tri, const int64_t vlo[3],
		       const int64_t vhi[3], const int64_t origin[3], int64_t s,
		       vd_voxel_fn fn, void *ctx)
{
	int64_t t[3][3];
	for (int k = 0; k < 3; k++)
		for (int a = 0; a < 3; a++)
			t[k][a] = tri->v[k][a] - origin[a];
	struct RN(axes) x;
	RN(axes_init)(&x, t, s);
	int w = 0;
	for (int a = 1; a < 3; a++)
		if ((x.a[0][a] < 0 ? -x.a[0][a] : x.a[0][a]) >
		    (x.a[0][w] < 0 ? -x.a[0][w] : x.a[0][w]))
			w = a;
	const int u = (w + 1) % 3, v = (w + 2) % 3;
	int col[3], vox[7], nvox = 0;
	for (int k = 0; k < 3; k++)
		col[k] = 1 + 3 * k + w;
	vox[nvox++] = 0;
	for (int j = 1; j < 10; j++)
		if ((j - 1) % 3 != w)
			vox[nvox++] = j;
	/* per-voxel axes packed as lo <= a.p <= hi */
	RT wstep[7], vstep[7], colvstep[3], lo[7], hi[7], clo[3], chi[3];
	RT cin_lo[3], cin_hi[3];
	for (int i = 0; i < 7; i++) {
		wstep[i] = x.a[vox[i]][w] * s;
		vstep[i] = x.a[vox[i]][v] * s;
		lo[i] = x.tmin[vox[i]] - x.bhi[vox[i]];
		hi[i] = x.tmax[vox[i]] - x.blo[vox[i]];
	}
	for (int k = 0; k < 3; k++) {
		colvstep[k] = x.a[col[k]][v] * s;
		clo[k] = x.tmin[col[k]] - x.bhi[col[k]];
		chi[k] = x.tmax[col[k]] - x.blo[col[k]];
		/* the column's square lies inside the triangle's projection */
		cin_lo[k] = x.tmin[col[k]] - x.blo[col[k]];
		cin_hi[k] = x.tmax[col[k]] - x.bhi[col[k]];
	}
	const double inv_s = 1.0 / (double)s;
	const double nw = (double)x.a[0][w];
	const double inv_nw = nw != 0 ? 1.0 / nw : 0;
	int64_t p[3];
	for (int64_t cu = vlo[u]; cu <= vhi[u]; cu++) {
		p[u] = cu * s - origin[u];
		int64_t v0 = vlo[v], v1 = vhi[v];
		for (int k = 0; k < 3 && v0 <= v1; k++) {
			const RT *ax = x.a[col[k]];
			RT au = ax[u] * p[u];
			RN(narrow)((double)(x.tmin[col[k]] - x.bhi[col[k]] - au),
				   (double)(x.tmax[col[k]] - x.blo[col[k]] - au),
				   (double)ax[v], (double)origin[v], inv_s, &v0, &v1);
		}
		if (v0 > v1)
			continue;
		p[v] = v0 * s - origin[v];
		RT cd[3], base[7];
		for (int k = 0; k < 3; k++)
			cd[k] = x.a[col[k]][u] * p[u] + x.a[col[k]][v] * p[v];
		for (int i = 0; i < 7; i++)
			base[i] = x.a[vox[i]][u] * p[u] + x.a[vox[i]][v] * p[v];
		for (int64_t cv = v0; cv <= v1; cv++) {
			int skip = 0, inner = 1;
			for (int k = 0; k < 3; k++) {
				skip |= cd[k] < clo[k] || cd[k] > chi[k];
				inner &= cd[k] >= cin_lo[k] && cd[k] <= cin_hi[k];
				cd[k] += colvstep[k];
			}
			RT b[7];
			for (int i = 0; i < 7; i++) {
				b[i] = base[i];
				base[i] += vstep[i];
			}
			if (skip)
				continue;
			int64_t w0 = vlo[w], w1 = vhi[w];
			if (nw != 0) {
				/* plane: lo[0] <= n.p <= hi[0] */
				double g0 = (double)(lo[0] - b[0]) * inv_nw,
				       g1 = (double)(hi[0] - b[0]) * inv_nw;
				if (g0 > g1) {
					double tmp = g0;
					g0 = g1;
					g1 = tmp;
				}
				const double margin = 1.0 / 64;
				double f0 = vd_ceil((g0 - margin + (double)origin[w]) * inv_s);
				double f1 = vd_floor((g1 + margin + (double)origin[w]) * inv_s);
				if (f0 > (double)w0)
					w0 = (int64_t)f0;
				if (f1 < (double)w1)
					w1 = (int64_t)f1;
			}
			if (w0 > w1)
				continue;
			/* Each axis admits an interval of w, so the voxels of
			 * the column form one interval: find its ends exactly
			 * and take everything between without testing. Where
			 * the column's square lies inside the triangle's
			 * projection, a box meets the triangle iff it meets its
			 * plane, and the plane alone is tested. */
			int naxes = inner && nw != 0 ? 1 : 7;
			RT d[7];
			int64_t pw = w0 * s - origin[w];
			for (int i = 0; i < naxes; i++)
				d[i] = b[i] + x.a[vox[i]][w] * pw;
			int64_t first = w0;
			for (;; first++) {
				if (first > w1)
					break;
				int ok = 1;
				for (int i = 0; i < naxes; i++) {
					ok &= d[i] >= lo[i] && d[i] <= hi[i];
					d[i] += wstep[i];
				}
				if (ok)
					break;
			}
			if (first > w1)
				continue;
			int64_t last = w1;
			pw = w1 * s - origin[w];
			for (int i = 0; i < naxes; i++)
				d[i] = b[i] + x.a[vox[i]][w] * pw;
			for (; last > first; last--) {
				int ok = 1;
				for (int i = 0; i < naxes; i++) {
					ok &= d[i] >= lo[i] && d[i] <= hi[i];
					d[i] -= wstep[i];
				}
				if (ok)
					break;
			}
			int64_t out[3];
			out[u] = cu, out[v] = cv;
			for (int64_t cw = first; cw <= last; cw++) {
				out[w] = cw;
				fn(ctx, out[0], out[1], out[2]);
			}
		}
	}
}
