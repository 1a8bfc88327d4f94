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

/* floor(a / b) for b > 0 */
static inline RT RN(fdiv)(RT a, RT b)
{
	RT q = a / b;
	return q - (a % b != 0 && a < 0);
}

/* Narrows [*k1, *k2] to the integers k with lo <= b + A*k <= hi, exactly
 * (an empty result has *k1 > *k2 and stays empty under more narrowing). */
static inline void RN(bound)(RT b, RT A, RT lo, RT hi, int64_t *k1,
			     int64_t *k2)
{
	RT c1, c2;
	if (A == 0) {
		if (b >= lo && b <= hi)
			return;
		c1 = 1, c2 = 0;
	} else if (A > 0) {
		c1 = -RN(fdiv)(b - lo, A); /* ceil((lo - b) / A) */
		c2 = RN(fdiv)(hi - b, A);
	} else {
		c1 = -RN(fdiv)(hi - b, -A); /* ceil((b - hi) / -A) */
		c2 = RN(fdiv)(b - lo, -A);
	}
	if (c1 > *k1)
		*k1 = c1 > *k2 ? *k2 + 1 : (int64_t)c1;
	if (c2 < *k2)
		*k2 = c2 < *k1 ? *k1 - 1 : (int64_t)c2;
}

/* Narrows [*k1, *k2] to [c1, c2], keeping an empty result empty. */
static inline void RN(clamp)(RT c1, RT c2, int64_t *k1, int64_t *k2)
{
	if (c1 > *k1)
		*k1 = c1 > *k2 ? *k2 + 1 : (int64_t)c1;
	if (c2 < *k2)
		*k2 = c2 < *k1 ? *k1 - 1 : (int64_t)c2;
}

/* The constraint lo <= b + A*k <= hi of RN(bound) while b moves by d a
 * step (a row, or a column): with A != 0, as A' k in [lo', hi'] - b'
 * (A' = |A| > 0, the rest negated with A), b' = A' q + r kept by adding
 * d' = A' dq + dr, so the bounds on k come without a division:
 * ceil((lo' - b') / A') = ql - q + (rl > r), likewise floor for hi'. */
struct RN(dda) {
	RT A, q, r, dq, dr, ql, rl, qh, rh;
	RT b, d, lo, hi;        /* A == 0: b itself */
};

static inline void RN(dda_init)(struct RN(dda) *x, RT A, RT b, RT d, RT lo,
				RT hi)
{
	x->A = A < 0 ? -A : A;
	if (A == 0) {
		x->b = b, x->d = d, x->lo = lo, x->hi = hi;
		return;
	}
	if (A < 0) {
		RT t = lo;
		lo = -hi, hi = -t, b = -b, d = -d;
	}
	x->q = RN(fdiv)(b, x->A), x->r = b - x->q * x->A;
	x->dq = RN(fdiv)(d, x->A), x->dr = d - x->dq * x->A;
	x->ql = RN(fdiv)(lo, x->A), x->rl = lo - x->ql * x->A;
	x->qh = RN(fdiv)(hi, x->A), x->rh = hi - x->qh * x->A;
}

static inline void RN(dda_bound)(const struct RN(dda) *x, int64_t *k1,
				 int64_t *k2)
{
	if (x->A == 0) {
		if (x->b < x->lo || x->b > x->hi)
			RN(clamp)(1, 0, k1, k2);
		return;
	}
	RN(clamp)(x->ql - x->q + (x->rl > x->r), x->qh - x->q - (x->r > x->rh),
		  k1, k2);
}

static inline void RN(dda_step)(struct RN(dda) *x)
{
	if (x->A == 0) {
		x->b += x->d;
		return;
	}
	x->q += x->dq;
	x->r += x->dr;
	if (x->r >= x->A)
		x->r -= x->A, x->q++;
}

/* Rows of at most this many voxels (and vd_raster_table_max) have their
 * per-v bounds tabled; longer ones bound each column on its own. */
enum { RN(VTAB) = 512 };

/* Visits every voxel of [vlo, vhi] that the triangle overlaps, as runs
 * along one axis. Columns run along the axis w where the normal is
 * largest, so the plane crosses few voxels of a column. Every axis bounds
 * the w of a column's voxels to an interval, so the column's voxels are
 * one interval, the intersection of:
 *   - the box axes: the clip box [vlo, vhi];
 *   - the edge axes e_k x unit_w, constant along a column: per row (fixed
 *     u) they bound the range of v;
 *   - the edge axes e_k x unit_v, whose projections do not depend on v:
 *     one interval per row;
 *   - the edge axes e_k x unit_u, which do not depend on u: one interval
 *     per v, tabled once per triangle;
 *   - the plane: its interval is found by one exact division per row and
 *     then stepped from column to column in integers (it moves by less
 *     than one voxel of w per voxel of v, since |n_v| <= |n_w|).
 * The bounds of the edge axes step from row to row (and v to v) as
 * quotient and remainder (RN(dda)): no division after the triangle's
 * first. All of it is exact integer arithmetic: the same voxels as
 * testing the 13 axes on every box. */
static inline __attribute__((always_inline)) void
RN(raster_core)(const struct vd_snapped_tri *tri, const int64_t vlo[3],
		const int64_t vhi[3], const int64_t origin[3], int64_t s,
		vd_span_fn fn, void *ctx, struct vd_brick_sink *sink)
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
	struct brick_emit e;
	if (sink)
		emit_init(&e, sink, u, v, w, vlo, vhi);
	/* axes as lo <= a.p <= hi; col: e_k x unit_w, ru: e_k x unit_v
	 * (per row), tv: e_k x unit_u (per v) */
	int col[3], ru[3], tv[3];
	for (int k = 0; k < 3; k++) {
		col[k] = 1 + 3 * k + w;
		ru[k] = 1 + 3 * k + v;
		tv[k] = 1 + 3 * k + u;
	}
	RT lo[10], hi[10];
	for (int j = 0; j < 10; j++) {
		lo[j] = x.tmin[j] - x.bhi[j];
		hi[j] = x.tmax[j] - x.blo[j];
	}
	const int64_t kmax = vhi[w] - vlo[w];
	const int64_t nv = vhi[v] - vlo[v] + 1;
	/* per v: the range of k = cw - vlo[w] the axes tv admit (origin[w]
	 * is the low corner of voxel vlo[w], so p[w] = k * s; likewise
	 * p[v] = i * s for cv = vlo[v] + i) */
	int64_t tv1[RN(VTAB)], tv2[RN(VTAB)];
	const int tabled = nv <= RN(VTAB) && nv <= vd_raster_table_max;
	if (tabled) {
		struct RN(dda) d[3];
		for (int k = 0; k < 3; k++)
			RN(dda_init)(&d[k], x.a[tv[k]][w] * s, 0,
				     x.a[tv[k]][v] * s, lo[tv[k]], hi[tv[k]]);
		for (int64_t i = 0; i < nv; i++) {
			tv1[i] = 0, tv2[i] = kmax;
			for (int k = 0; k < 3; k++) {
				RN(dda_bound)(&d[k], &tv1[i], &tv2[i]);
				RN(dda_step)(&d[k]);
			}
		}
	}
	/* per row (fixed u, p[u] = j * s): the range of i the axes col
	 * admit, the range of k the axes ru admit */
	struct RN(dda) dcol[3], dru[3];
	for (int k = 0; k < 3; k++) {
		RN(dda_init)(&dcol[k], x.a[col[k]][v] * s, 0,
			     x.a[col[k]][u] * s, lo[col[k]], hi[col[k]]);
		RN(dda_init)(&dru[k], x.a[ru[k]][w] * s, 0, x.a[ru[k]][u] * s,
			     lo[ru[k]], hi[ru[k]]);
	}
	/* The plane in a column: lo[0] <= b + wstep * k <= hi[0]. Negated
	 * when wstep < 0, it reads pl <= c + P * k <= ph with P > 0,
	 * c = sg * b. A zero normal (degenerate triangle) is a zero axis: it
	 * passes every box. With c = P qc + rc, pl = P ql + rl and
	 * ph = P qh + rh, the range is ql - qc + (rl > rc) .. qh - qc -
	 * (rc > rh): one division a row. */
	const RT wstep = x.a[0][w] * s;
	const RT P = wstep < 0 ? -wstep : wstep;
	const RT sg = wstep < 0 ? -1 : 1;
	const RT pl = wstep < 0 ? -hi[0] : lo[0];
	const RT ph = wstep < 0 ? -lo[0] : hi[0];
	const RT dc = sg * x.a[0][v] * s;
	RT pql = 0, prl = 0, pqh = 0, prh = 0;
	if (P != 0) {
		pql = RN(fdiv)(pl, P), prl = pl - pql * P;
		pqh = RN(fdiv)(ph, P), prh = ph - pqh * P;
	}
	int64_t p[3];
	for (int64_t cu = vlo[u]; cu <= vhi[u]; cu++) {
		p[u] = cu * s - origin[u];
		if (sink) {
			if (e.stop)
				return;
			emit_row(&e, cu);
		}
		int64_t i0 = 0, i1 = nv - 1, r1 = 0, r2 = kmax;
		for (int k = 0; k < 3; k++) {
			RN(dda_bound)(&dcol[k], &i0, &i1);
			RN(dda_step)(&dcol[k]);
			RN(dda_bound)(&dru[k], &r1, &r2);
			RN(dda_step)(&dru[k]);
		}
		if (i0 > i1 || r1 > r2)
			continue;
		p[v] = i0 * s;
		/* the plane's exact range of k in the first column, and the
		 * slack e1 = c + P*k1 - pl, e2 = ph - c - P*k2 in [0, P) */
		RT k1 = 0, k2 = kmax, e1 = 0, e2 = 0;
		if (P != 0) {
			RT c = sg * (x.a[0][u] * p[u] + x.a[0][v] * p[v]);
			RT qc = RN(fdiv)(c, P), rc = c - qc * P;
			k1 = pql - qc + (prl > rc);
			k2 = pqh - qc - (rc > prh);
			e1 = rc - prl + (prl > rc ? P : 0);
			e2 = prh - rc + (rc > prh ? P : 0);
		}
		for (int64_t i = i0; i <= i1; i++) {
			int64_t w0 = k1 > r1 ? (int64_t)k1 : r1;
			int64_t w1 = k2 < r2 ? (int64_t)k2 : r2;
			if (P != 0) {
				/* step the plane's range to the next column
				 * (|dc| <= P: one correction at most) */
				e1 += dc;
				RT m1 = (e1 >= P) - (e1 < 0);
				k1 -= m1, e1 -= m1 * P;
				e2 -= dc;
				RT m2 = (e2 >= P) - (e2 < 0);
				k2 += m2, e2 -= m2 * P;
			}
			if (tabled) {
				w0 = tv1[i] > w0 ? tv1[i] : w0;
				w1 = tv2[i] < w1 ? tv2[i] : w1;
			} else if (w0 <= w1) {
				RT pv = (RT)i * s;
				for (int k = 0; k < 3; k++)
					RN(bound)(x.a[tv[k]][v] * pv,
						  x.a[tv[k]][w] * s, lo[tv[k]],
						  hi[tv[k]], &w0, &w1);
			}
			if (w0 > w1)
				continue;
			int64_t cv = vlo[v] + i;
			if (sink) {
				emit_run(&e, cv, vlo[w] + w0, vlo[w] + w1);
				continue;
			}
			int64_t out[3];
			out[u] = cu, out[v] = cv, out[w] = vlo[w] + w0;
			fn(ctx, w, out[0], out[1], out[2], w1 - w0 + 1);
		}
	}
}

static void RN(raster)(const struct vd_snapped_tri *tri, const int64_t vlo[3],
		       const int64_t vhi[3], const int64_t origin[3], int64_t s,
		       vd_span_fn fn, void *ctx)
{
	RN(raster_core)(tri, vlo, vhi, origin, s, fn, ctx, NULL);
}

static void RN(raster_bricks)(const struct vd_snapped_tri *tri,
			      const int64_t vlo[3], const int64_t vhi[3],
			      const int64_t origin[3], int64_t s,
			      struct vd_brick_sink *sink)
{
	RN(raster_core)(tri, vlo, vhi, origin, s, NULL, NULL, sink);
}
