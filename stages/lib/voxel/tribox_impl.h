/* tribox_impl.h - the separating axes and the rasterizer, written once for
 * two integer types: RT for the axes and the per-triangle and per-row setup
 * (products of coordinates), ST for the state stepped from row to row and
 * column to column (quotients and remainders, which stay near the extent
 * in voxels and the divisors). tribox.c includes it five times: RT = ST =
 * int64_t for small triangles, twice (once built for x86-64-v3, with
 * RN_VEC); RT = __int128, ST = int64_t for large ones whose stepping state
 * fits int64 (every triangle inside the cube at the depths that have large
 * triangles), twice likewise; RT = ST = __int128 for the rest (see the
 * bounds in tribox.c).
 *
 * Define before including: RT, ST and RN(name) (a name suffix); RN_VEC
 * (ST = int64_t only, x86-64-v3) to step three states at once in a
 * vector, and to set the columns of tabled rows four at a time, two rows
 * at once (brick_quads) instead of one by one (brick_cols).
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
	/* unrolled: the axes' indices become constants */
#pragma GCC unroll 3
	for (int k = 0; k < 3; k++)
#pragma GCC unroll 3
		for (int i = 0; i < 3; i++)
			e[k][i] = (RT)t[(k + 1) % 3][i] - (RT)t[k][i];
	x->a[0][0] = e[0][1] * e[1][2] - e[0][2] * e[1][1];
	x->a[0][1] = e[0][2] * e[1][0] - e[0][0] * e[1][2];
	x->a[0][2] = e[0][0] * e[1][1] - e[0][1] * e[1][0];
	/* minima, maxima and signs as selects, not branches: a small
	 * triangle's setup mispredicted some 30 of them. The normal is
	 * orthogonal to the edges, so the three vertices project alike */
	const RT n0 = x->a[0][0] * t[0][0] + x->a[0][1] * t[0][1] +
		      x->a[0][2] * t[0][2];
	x->tmin[0] = x->tmax[0] = n0;
	RT bl = 0, bh = 0;
#pragma GCC unroll 3
	for (int i = 0; i < 3; i++) {
		RT c = x->a[0][i] * s;
		bl += c < 0 ? c : 0;
		bh += c > 0 ? c : 0;
	}
	x->blo[0] = bl;
	x->bhi[0] = bh;
#pragma GCC unroll 3
	for (int k = 0; k < 3; k++) {
		/* e x X = (0, ez, -ey), e x Y = (-ez, 0, ex), e x Z = (ey, -ex, 0):
		 * e x unit_a has e_c at b and -e_b at c (b, c the next
		 * axes); e_k is orthogonal to it, so vertices k and k + 1
		 * project alike, and the third (k + 2) is the other end */
		const int64_t *p = t[k], *q = t[(k + 2) % 3];
		/* the box's offsets: s e_i's positive and negative parts */
		RT ps[3], ns[3];
#pragma GCC unroll 3
		for (int i = 0; i < 3; i++) {
			RT c = e[k][i] * s;
			ps[i] = c > 0 ? c : 0;
			ns[i] = c < 0 ? c : 0;
		}
#pragma GCC unroll 3
		for (int a = 0; a < 3; a++) {
			const int b = (a + 1) % 3, c = (a + 2) % 3;
			const int j = 1 + 3 * k + a;
			const RT ec = e[k][c], eb = e[k][b];
			x->a[j][a] = 0, x->a[j][b] = ec, x->a[j][c] = -eb;
			RT dp = ec * p[b] - eb * p[c];
			RT dq = ec * q[b] - eb * q[c];
			x->tmin[j] = dq < dp ? dq : dp;
			x->tmax[j] = dq > dp ? dq : dp;
			x->blo[j] = ns[c] - ps[b];      /* of ec s and -eb s */
			x->bhi[j] = ps[c] - ns[b];
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
static inline RT RN(wdiv)(RT a, RT b)
{
	RT q = a / b;
	return q - (a % b != 0 && a < 0);
}

static inline ST RN(fdiv)(ST a, ST b)
{
	ST q = a / b;
	return q - (a % b != 0 && a < 0);
}

/* 1 if ST holds v with room for the sums of a few such values: |v| < 2^61
 * (always when ST is RT, whose bounds tribox.c checks). */
static inline int RN(fits)(RT v)
{
	return sizeof(ST) == sizeof(RT) ||
	       (v > -((RT)1 << 61) && v < ((RT)1 << 61));
}

/* Narrows [*k1, *k2] to [c1, c2], keeping an empty result empty. */
static inline void RN(clamp)(ST c1, ST c2, int64_t *k1, int64_t *k2)
{
	/* as max(k1, min(c1, k2 + 1)), min(k2, max(c2, k1 - 1)): no
	 * branches (k1 <= k2 + 1 holds throughout) */
	int64_t a = c1 < *k2 + 1 ? (int64_t)c1 : *k2 + 1;
	*k1 = a > *k1 ? a : *k1;
	int64_t b = c2 > *k1 - 1 ? (int64_t)c2 : *k1 - 1;
	*k2 = b < *k2 ? b : *k2;
}

/* The integers k with lo <= b + A*k <= hi (exactly; an empty result has
 * k1 > k2 and stays empty under more narrowing) while b moves by d a step
 * (a row, or a column) from 0: as A' k in [lo', hi'] - b' (A' = |A| > 0,
 * the rest negated with A), b' = A' q + r kept by adding d' = A' dq + dr,
 * so the bounds on k come without a division: ceil((lo' - b') / A') =
 * ql - q + (rl > r), likewise floor for hi'. With A = 0 the condition
 * does not depend on k but on the step alone: it holds for the steps
 * s1..s2, found once, and the stepping bounds nothing (A' = 1, k within
 * +-2^60), so that the steps have no case of their own. */
struct RN(dda) {
	ST A, q, r, dq, dr, ql, rl, qh, rh;
	ST d;                   /* d' */
	int64_t s1, s2;         /* the steps 0..n the condition can hold */
	int noop;               /* A = 0: the stepping bounds nothing */
};

/* 0 (and nothing set) when the state of n steps may not fit ST. Inlined
 * in the vector build (small triangles' setup, 9 calls each: the calls
 * cost more than their bodies' branches); elsewhere the compiler picks. */
#ifdef RN_VEC
#define RN_DDA_INLINE __attribute__((always_inline))
#else
#define RN_DDA_INLINE
#endif
static inline RN_DDA_INLINE int
RN(dda_init)(struct RN(dda) *x, RT wA, RT wd, RT wlo, RT whi, int64_t n)
{
	if (sizeof(ST) < sizeof(RT) &&
	    (!RN(fits)(wA) || !RN(fits)(wlo) || !RN(fits)(whi) ||
	     !RN(fits)((wd < 0 ? -wd : wd) * (n + 1))))
		return 0;
	x->s1 = 0, x->s2 = n;
	x->noop = wA == 0;
	if (wA == 0) {
		/* lo <= d s <= hi */
		RT s1 = 0, s2 = n;
		if (wd > 0)
			s1 = -RN(wdiv)(-wlo, wd), s2 = RN(wdiv)(whi, wd);
		else if (wd < 0)
			s1 = -RN(wdiv)(whi, -wd), s2 = RN(wdiv)(-wlo, -wd);
		else if (wlo > 0 || whi < 0)   /* (a zero axis: never) */
			s1 = 1, s2 = 0;
		x->s1 = s1 < 0 ? 0 : s1 > n ? n + 1 : (int64_t)s1;
		x->s2 = s2 > n ? n : s2 < 0 ? -1 : (int64_t)s2;
		wA = 1, wd = 0;
		wlo = -((RT)1 << 60), whi = (RT)1 << 60;
	}
	ST A = (ST)wA, d = (ST)wd, lo = (ST)wlo, hi = (ST)whi;
	/* negated by masks, not a branch (GCC makes selects one): A's sign
	 * is a coin toss from axis to axis. m is -1 when A < 0 */
	const ST m = -(ST)(A < 0), sw = (lo ^ hi) & m;
	x->A = (A ^ m) - m;
	d = (d ^ m) - m;
	lo ^= sw, hi ^= sw;
	lo = (lo ^ m) - m, hi = (hi ^ m) - m;
	x->q = 0, x->r = 0, x->d = d;
	x->dq = RN(fdiv)(d, x->A), x->dr = d - x->dq * x->A;
	x->ql = RN(fdiv)(lo, x->A), x->rl = lo - x->ql * x->A;
	x->qh = RN(fdiv)(hi, x->A), x->rh = hi - x->qh * x->A;
	return 1;
}
#undef RN_DDA_INLINE

/* *x as x0 after m steps (m <= n of RN(dda_init)): one division. */
static inline void RN(dda_at)(struct RN(dda) *x, const struct RN(dda) *x0,
			      int64_t m)
{
	*x = *x0;
	x->q = RN(fdiv)(x->d * m, x->A);
	x->r = x->d * m - x->q * x->A;
}

static inline void RN(dda_bound)(const struct RN(dda) *x, int64_t *k1,
				 int64_t *k2)
{
	RN(clamp)(x->ql - x->q + (x->rl > x->r), x->qh - x->q - (x->r > x->rh),
		  k1, k2);
}

static inline void RN(dda_step)(struct RN(dda) *x)
{
	x->r += x->dr;
	ST over = -(ST)(x->r >= x->A);  /* no branch: rows toss coins */
	x->r -= x->A & over;
	x->q += x->dq - over;
}

/* The steps three stepping states all admit. */
static inline void RN(dda_steps)(const struct RN(dda) x[3], int64_t *s1,
				 int64_t *s2)
{
	*s1 = x[0].s1, *s2 = x[0].s2;
	for (int k = 1; k < 3; k++) {
		*s1 = x[k].s1 > *s1 ? x[k].s1 : *s1;
		*s2 = x[k].s2 < *s2 ? x[k].s2 : *s2;
	}
}

/* Three stepping states at once, bounding one range: RN(dda3_range)
 * gives [lo, hi] (of RN(dda3_init)) narrowed to its exact intersection
 * with the states' ranges, which the caller finds empty when *k1 > *k2.
 * With ST = int64_t, in the lanes of a vector, the fourth holding
 * [lo, hi] as a state that never moves: the three states of a row or a
 * column cost a few vector instructions instead of some 100. */
#ifdef RN_VEC
typedef ST RN(v4) __attribute__((vector_size(4 * sizeof(ST))));
struct RN(dda3) {
	RN(v4) A, q, r, dq, dr, ql, rl, qh, rh;
};

static inline void RN(dda3_init)(struct RN(dda3) *g,
				 const struct RN(dda) x[3], int64_t lo,
				 int64_t hi)
{
	g->A = (RN(v4)){x[0].A, x[1].A, x[2].A, 1};
	g->q = (RN(v4)){x[0].q, x[1].q, x[2].q, 0};
	g->r = (RN(v4)){x[0].r, x[1].r, x[2].r, 0};
	g->dq = (RN(v4)){x[0].dq, x[1].dq, x[2].dq, 0};
	g->dr = (RN(v4)){x[0].dr, x[1].dr, x[2].dr, 0};
	g->ql = (RN(v4)){x[0].ql, x[1].ql, x[2].ql, lo};
	g->rl = (RN(v4)){x[0].rl, x[1].rl, x[2].rl, 0};
	g->qh = (RN(v4)){x[0].qh, x[1].qh, x[2].qh, hi};
	g->rh = (RN(v4)){x[0].rh, x[1].rh, x[2].rh, 0};
}

/* max(a, b) per int64 lane */
static inline RN(v4) RN(vmax)(RN(v4) a, RN(v4) b)
{
	return (RN(v4))_mm256_blendv_epi8((__m256i)b, (__m256i)a,
					  (__m256i)(a > b));
}

static inline void RN(dda3_range)(const struct RN(dda3) *g, int64_t *k1,
				  int64_t *k2)
{
	/* the lower bounds, and the upper ones negated, each reduced by
	 * max: over the two halves, then (both in one vector) within
	 * them. A comparison is -1 where it holds */
	RN(v4) c1 = g->ql - g->q - (g->rl > g->r);
	RN(v4) n2 = g->q - g->qh - (g->r > g->rh);
	c1 = RN(vmax)(c1, __builtin_shuffle(c1, (RN(v4)){2, 3, 0, 1}));
	n2 = RN(vmax)(n2, __builtin_shuffle(n2, (RN(v4)){2, 3, 0, 1}));
	RN(v4) t = __builtin_shuffle(c1, n2, (RN(v4)){0, 1, 6, 7});
	t = RN(vmax)(t, __builtin_shuffle(t, (RN(v4)){1, 0, 3, 2}));
	*k1 = t[0];
	*k2 = -t[2];
}

static inline void RN(dda3_step)(struct RN(dda3) *g)
{
	g->r += g->dr;
	RN(v4) over = g->r >= g->A;
	g->r -= g->A & over;
	g->q += g->dq - over;
}
#else
/* without vectors, the states that bound something (A != 0) */
struct RN(dda3) {
	struct RN(dda) x[3];
	int n;
	int64_t lo, hi;
};

static inline void RN(dda3_init)(struct RN(dda3) *g,
				 const struct RN(dda) x[3], int64_t lo,
				 int64_t hi)
{
	g->n = 0;
	g->lo = lo, g->hi = hi;
	for (int k = 0; k < 3; k++)
		if (!x[k].noop)
			g->x[g->n++] = x[k];
}

static inline void RN(dda3_range)(const struct RN(dda3) *g, int64_t *k1,
				  int64_t *k2)
{
	*k1 = g->lo, *k2 = g->hi;
	for (int k = 0; k < g->n; k++)
		RN(dda_bound)(&g->x[k], k1, k2);
}

static inline void RN(dda3_step)(struct RN(dda3) *g)
{
	for (int k = 0; k < g->n; k++)
		RN(dda_step)(&g->x[k]);
}
#endif

/* The columns i..i1 of a row of a triangle whose blocks and per-v bounds
 * are tabled and whose plane is not degenerate (P > 0), w being axis W (a
 * constant, so the Morton shifts and masks are): the loop of
 * raster_core's columns, in fewer instructions and mispredicted branches
 * (most of the time of a fine grid):
 *   - the plane's range [k1, k2] from one remainder: with e1 = c + P k1
 *     - pl in [0, P) and ph - pl = P Dq + Dr (0 <= Dr < P), k2 = k1 + Dq
 *     - (e1 > Dr); from column to column e1 moves by dc, in [-P, P], so
 *     by dcp = dc + P kd in [0, P] (kd = 1 when dc < 0) while k1 moves by
 *     kd, and one conditional subtraction of P corrects it;
 *   - a run within two aligned groups of 4 voxels of one block (nearly
 *     all) set as two masks (run_tabs), without a loop whose
 *     exit the branch predictor cannot guess; the rest through
 *     emit_run_cold.
 * The columns are c..cend of the table ct, whose bounds, like k1, r1 and
 * r2, are in the cell's coordinates along w; offv: the cell's coordinate
 * of the triangle's column 0 along v. KD (kd, 0 or 1) is a constant, like
 * W: the loop then keeps its state in registers. */
static inline __attribute__((always_inline)) void
RN(brick_cols)(struct brick_emit *e, const struct col_tab *c,
	       const struct col_tab *cend, ST k1, ST e1, ST P, ST dcp, ST Dq,
	       ST Dr, int64_t r1, int64_t r2, const struct col_tab *ct,
	       uint32_t offv, const int W, const int KD)
{
	const int shw = 2 - W;
	const struct run_tab *rt = &run_tabs[shw];
	const uint32_t mu = e->mu, bu = e->lu >> 5;
	uint64_t **const tab = e->tab + e->rowbase;
	for (; c <= cend; c++) {
		ST k2 = k1 + Dq - (e1 > Dr);
		int64_t w0 = k1 > r1 ? (int64_t)k1 : r1;
		int64_t w1 = k2 < r2 ? (int64_t)k2 : r2;
		e1 += dcp;
		ST over = -(ST)(e1 >= P);      /* no branch: a coin toss */
		e1 -= P & over;
		k1 += KD + over;
		w0 = c->lo > w0 ? c->lo : w0;
		w1 = c->hi < w1 ? c->hi : w1;
		if (w0 > w1)
			continue;
		uint32_t lw = (uint32_t)w0, lw1 = (uint32_t)w1;
		/* j: lw1 from lw's group; one test for j > 7 or another
		 * block */
		uint32_t j = lw1 - (lw & ~3u);
		if ((j | (lw ^ lw1) >> 2) > 7) {
			emit_run_cold(e, (uint32_t)(c - ct) + offv, lw, lw1);
			if (e->stop)
				return;
			continue;
		}
		uint64_t **slot = &tab[c->blk + (int32_t)(lw >> 5)];
		uint64_t *blk = *slot;
		if (!blk && !(blk = emit_fetch(e, slot, bu,
					       ((uint32_t)(c - ct) + offv) >> 5,
					       lw >> 5)))
			return;
		uint32_t m = mu | c->m;
		uint32_t b1 = m | rt->g[lw >> 2 & 7];
		uint32_t b2 = m | rt->g[lw1 >> 2 & 7];
		blk[b1 >> 6] |= rt->m1[(lw & 3) << 3 | j] << (b1 & 63);
		blk[b2 >> 6] |= rt->m2[j] << (b2 & 63);
	}
}

#ifdef RN_VEC
/* brick_quads's steps of the plane's range by m = 0..4 columns (from
 * brick_cols's k1, e1): m dcp = P q[m] + r[m], 0 <= r[m] < P, so k1
 * moves by m kd - q[m] - (e1 + r[m] >= P); in lanes, kq[m] = m kd -
 * q[m] and rl[m] = r[m] (m < 4). */
struct RN(quad) {
	int64_t q[5], r[5];
	__m256i rl;
	__m128i kq;
	/* broadcast: P - 1, P, Dr, r[4]; 4 kd - q[4], Dq */
	__m256i pm1, p, dr, r4;
	__m128i kq4, dq;
};

static void RN(quad_init)(struct RN(quad) *qd, ST P, ST dcp, ST kd, ST Dq,
			  ST Dr)
{
	qd->q[0] = 0, qd->r[0] = 0;
	for (int m = 1; m <= 4; m++) {
		ST r = qd->r[m - 1] + dcp, q = qd->q[m - 1];
		if (r >= P)
			r -= P, q++;
		qd->q[m] = q, qd->r[m] = r;
	}
	qd->rl = _mm256_setr_epi64x(0, qd->r[1], qd->r[2], qd->r[3]);
	qd->kq = _mm_setr_epi32(0, (int32_t)(kd - qd->q[1]),
				(int32_t)(2 * kd - qd->q[2]),
				(int32_t)(3 * kd - qd->q[3]));
	qd->pm1 = _mm256_set1_epi64x(P - 1);
	qd->p = _mm256_set1_epi64x(P);
	qd->dr = _mm256_set1_epi64x(Dr);
	qd->r4 = _mm256_set1_epi64x(qd->r[4]);
	qd->kq4 = _mm_set1_epi32((int32_t)(4 * kd - qd->q[4]));
	qd->dq = _mm_set1_epi32((int32_t)Dq);
}

/* A row for brick_quads: its columns i0..i1, its range r1..r2 of w,
 * and the plane's k1, e1 in its column i0 (all along w in the cell's
 * coordinates, like brick_cols's); cu its coordinate along u. */
struct RN(qrow) {
	int64_t i0, i1, r1, r2, cu;
	ST k1, e1;
};

/* Row r's lanes at the group of columns iq0 (iq0 <= i0, aligned): the
 * plane's reduced remainders in int64 lanes, k1 in int32 lanes. */
static inline __attribute__((always_inline)) void
RN(quad_start)(const struct RN(quad) *qd, const struct RN(qrow) *r,
	       int64_t iq0, uint32_t ov, ST P, ST kd, __m256i *E, __m128i *K1)
{
	const __m256i pack = _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7);
	/* back to r's first group (d columns), then by whole groups */
	const int64_t d = (ov + r->i0) & 3;
	ST eb = r->e1 - qd->r[d];
	ST neg = eb < 0;
	eb += P & -neg;
	ST kb = r->k1 - d * kd + qd->q[d] + neg;
	for (int64_t iq = r->i0 - d; iq > iq0; iq -= 4) {
		eb -= qd->r[4];
		neg = eb < 0;
		eb += P & -neg;
		kb -= 4 * kd - qd->q[4] - neg;
	}
	__m256i e4 = _mm256_add_epi64(_mm256_set1_epi64x(eb), qd->rl);
	__m256i ge = _mm256_cmpgt_epi64(e4, qd->pm1);
	*E = _mm256_sub_epi64(e4, _mm256_and_si256(ge, qd->p));
	*K1 = _mm_add_epi32(_mm_add_epi32(_mm_set1_epi32((int32_t)kb), qd->kq),
		_mm256_castsi256_si128(_mm256_permutevar8x32_epi32(ge, pack)));
}

/* brick_cols's columns of row a and of row b (NULL: none), its
 * neighbour in the same aligned pair along u, four at a time: the
 * aligned groups of 4 columns along v (the cell's coordinate ov + i),
 * whose voxels of both rows lie in the same words of a block. In 8 int32
 * lanes (a's 4, then b's; the plane's remainders in two int64 vectors)
 * each column's range of w, stepped by 4 columns a group, bounded by the
 * per-v table lo, hi (indexed from -4 to the last i1 + 3). When the runs
 * of a group lie within two groups of 4 voxels along w (nearly always),
 * each row's bits are two 16-bit planes (quad_tabs), deposited by pdep
 * into the two words; else each column's run goes through emit_run. */
static inline __attribute__((always_inline)) void
RN(brick_quads)(struct brick_emit *e, const int32_t *lo, const int32_t *hi,
		const struct RN(quad) *qd, const struct RN(qrow) *a,
		const struct RN(qrow) *b, ST P, ST kd, uint32_t ov,
		const int W)
{
	const int shw = 2 - W, shv = 2 - (W + 2) % 3;
	const struct run_tab *rt = &run_tabs[shw];
	const struct quad_tab *qt = &quad_tabs[shw < shv];
	const __m256i ta = _mm256_loadu_si256((const __m256i *)qt->runs);
	const __m256i tb = _mm256_loadu_si256((const __m256i *)(qt->runs + 1));
	const __m256i pv = _mm256_broadcastsi128_si256(
		_mm_loadu_si128((const __m128i *)qt->v));
	const __m256i pack = _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7);
	const struct RN(qrow) *rb = b ? b : a;
	emit_row(e, a->cu);
	const uint32_t mua = e->mu, bu = e->lu >> 5, nbw = e->nbw;
	const uint32_t mub = (uint32_t)d5[(uint32_t)(rb->cu - e->lo[0]) & 31]
			     << e->sh[0];
	const uint64_t ma = quad_m0[W] << (mua & 63);
	const uint64_t mb_ = b ? quad_m0[W] << (mub & 63) : 0;
	/* the table's entry of block (v, w) of the rows: ib + v nbw + w */
	const int32_t ib = (int32_t)(e->rowbase - e->tb[1] * nbw - e->tb[2]);
	/* the first group: both rows' lanes before their i0 are masked,
	 * like those past their i1 */
	int64_t iq = a->i0 < rb->i0 ? a->i0 : rb->i0;
	iq -= (ov + iq) & 3;
	const int64_t iend = a->i1 > rb->i1 ? a->i1 : rb->i1;
	__m256i Ea, Eb;
	__m128i Ka, Kb;
	RN(quad_start)(qd, a, iq, ov, P, kd, &Ea, &Ka);
	RN(quad_start)(qd, rb, iq, ov, P, kd, &Eb, &Kb);
	__m256i K1 = _mm256_setr_m128i(Ka, Kb);
	const __m256i pm1 = qd->pm1, pv4 = qd->p, drv = qd->dr, r4v = qd->r4;
	const __m256i kq4 = _mm256_broadcastsi128_si256(qd->kq4);
	const __m256i dqv = _mm256_broadcastsi128_si256(qd->dq);
	/* without b, its lanes are empty: r1 > r2 */
	const __m256i r1v = _mm256_setr_m128i(_mm_set1_epi32((int32_t)a->r1),
		_mm_set1_epi32(b ? (int32_t)b->r1 : INT32_MAX));
	const __m256i r2v = _mm256_setr_m128i(_mm_set1_epi32((int32_t)a->r2),
		_mm_set1_epi32(b ? (int32_t)b->r2 : -1));
	/* lane l's column less its row's i0, and i1 - i0, both biased by
	 * 2^31 so that one signed comparison finds the lanes outside
	 * i0..i1 */
	const __m256i four = _mm256_set1_epi32(4);
	const __m256i nlim = _mm256_setr_m128i(
		_mm_set1_epi32((int32_t)((uint32_t)(a->i1 - a->i0) ^ 0x80000000u)),
		_mm_set1_epi32((int32_t)((uint32_t)(rb->i1 - rb->i0) ^
					 0x80000000u)));
	__m256i tv = _mm256_add_epi32(_mm256_setr_epi32(0, 1, 2, 3, 0, 1, 2, 3),
		_mm256_setr_m128i(
			_mm_set1_epi32((int32_t)(0x80000000u +
						 (uint32_t)(iq - a->i0))),
			_mm_set1_epi32((int32_t)(0x80000000u +
						 (uint32_t)(iq - rb->i0)))));
	for (; iq <= iend; iq += 4) {
		__m256i c2 = _mm256_permutevar8x32_epi32(_mm256_blend_epi32(
			_mm256_cmpgt_epi64(Ea, drv), _mm256_cmpgt_epi64(Eb, drv),
			0xaa), pack);
		__m256i K2 = _mm256_add_epi32(_mm256_add_epi32(K1, dqv), c2);
		__m256i w0 = _mm256_max_epi32(_mm256_max_epi32(K1, r1v),
			_mm256_broadcastsi128_si256(
				_mm_loadu_si128((const __m128i *)(lo + iq))));
		__m256i w1 = _mm256_min_epi32(_mm256_min_epi32(K2, r2v),
			_mm256_broadcastsi128_si256(
				_mm_loadu_si128((const __m128i *)(hi + iq))));
		__m256i emp = _mm256_or_si256(_mm256_cmpgt_epi32(w0, w1),
					      _mm256_cmpgt_epi32(tv, nlim));
		/* the next group */
		tv = _mm256_add_epi32(tv, four);
		Ea = _mm256_add_epi64(Ea, r4v);
		Eb = _mm256_add_epi64(Eb, r4v);
		__m256i gea = _mm256_cmpgt_epi64(Ea, pm1);
		__m256i geb = _mm256_cmpgt_epi64(Eb, pm1);
		Ea = _mm256_sub_epi64(Ea, _mm256_and_si256(gea, pv4));
		Eb = _mm256_sub_epi64(Eb, _mm256_and_si256(geb, pv4));
		K1 = _mm256_add_epi32(_mm256_add_epi32(K1, kq4),
			_mm256_permutevar8x32_epi32(
				_mm256_blend_epi32(gea, geb, 0xaa), pack));
		int em = _mm256_movemask_ps(_mm256_castsi256_ps(emp));
		if (em == 0xff)
			continue;
		/* the runs' first and last w, empty lanes aside (w >= 0) */
		__m256i x = _mm256_or_si256(w0, emp), y = _mm256_andnot_si256(emp, w1);
		x = _mm256_min_epu32(x, _mm256_shuffle_epi32(x, 0x4e));
		x = _mm256_min_epu32(x, _mm256_shuffle_epi32(x, 0xb1));
		x = _mm256_min_epu32(x, _mm256_permute2x128_si256(x, x, 1));
		y = _mm256_max_epi32(y, _mm256_shuffle_epi32(y, 0x4e));
		y = _mm256_max_epi32(y, _mm256_shuffle_epi32(y, 0xb1));
		y = _mm256_max_epi32(y, _mm256_permute2x128_si256(y, y, 1));
		const uint32_t lw = (uint32_t)_mm256_cvtsi256_si32(x) & ~3u;
		const uint32_t lw1 = (uint32_t)_mm256_cvtsi256_si32(y);
		const uint32_t lv = ov + (uint32_t)iq;
		if (lw1 - lw > 7) {
			int32_t x0[8], x1[8];
			_mm256_storeu_si256((__m256i *)x0, w0);
			_mm256_storeu_si256((__m256i *)x1, w1);
			for (int r = 0; r < 2; r++) {
				if (!(~em >> 4 * r & 15))
					continue;
				emit_row(e, r ? rb->cu : a->cu);
				for (int l = 0; l < 4; l++)
					if (!(em >> (4 * r + l) & 1)) {
						emit_run_cold(e, lv + l,
							      (uint32_t)x0[4 * r + l],
							      (uint32_t)x1[4 * r + l]);
						if (e->stop)
							return;
					}
			}
			continue;
		}
		const __m256i lwv = _mm256_set1_epi32((int32_t)lw);
		__m256i m = _mm256_sub_epi32(
			_mm256_permutevar8x32_epi32(tb, _mm256_sub_epi32(w1, lwv)),
			_mm256_permutevar8x32_epi32(ta, _mm256_sub_epi32(w0, lwv)));
		m = _mm256_sllv_epi32(_mm256_andnot_si256(emp, m), pv);
		m = _mm256_or_si256(m, _mm256_shuffle_epi32(m, 0x4e));
		m = _mm256_or_si256(m, _mm256_shuffle_epi32(m, 0xb1));
		const uint32_t xa = (uint32_t)_mm256_cvtsi256_si32(m);
		const uint32_t xb = (uint32_t)_mm256_extract_epi32(m, 4);
		uint64_t **slot = &e->tab[ib + (int32_t)((lv >> 5) * nbw +
							 (lw >> 5))];
		uint64_t *blk = *slot, *blk2;
		if (!blk && !(blk = emit_fetch(e, slot, bu, lv >> 5, lw >> 5)))
			return;
		/* the second group: in the next block past w = 31 (when it
		 * has no voxels, an OR of 0 into the first group's block) */
		blk2 = blk;
		if ((lw & 31) == 28 && lw1 - lw > 3 &&
		    !(blk2 = slot[1]) &&
		    !(blk2 = emit_fetch(e, slot + 1, bu, lv >> 5,
					(lw >> 5) + 1)))
			return;
		const uint32_t mv = mua | (uint32_t)d5[lv & 31] << shv;
		blk[(mv | rt->g[lw >> 2 & 7]) >> 6] |=
			_pdep_u64(xa & 0xffff, ma) | _pdep_u64(xb & 0xffff, mb_);
		blk2[(mv | rt->g[((lw >> 2) + 1) & 7]) >> 6] |=
			_pdep_u64(xa >> 16, ma) | _pdep_u64(xb >> 16, mb_);
	}
}

/* brick_quads with the axis w not a constant */
static __attribute__((noinline)) void
RN(brick_quads_w)(struct brick_emit *e, const int32_t *lo, const int32_t *hi,
		  const struct RN(quad) *qd, const struct RN(qrow) *a,
		  const struct RN(qrow) *b, ST P, ST kd, uint32_t ov, int w)
{
	if (w == 0)
		RN(brick_quads)(e, lo, hi, qd, a, b, P, kd, ov, 0);
	else if (w == 1)
		RN(brick_quads)(e, lo, hi, qd, a, b, P, kd, ov, 1);
	else
		RN(brick_quads)(e, lo, hi, qd, a, b, P, kd, ov, 2);
}
#endif

/* Rows of at most this many voxels have their per-v bounds tabled on the
 * stack, longer ones (up to vd_raster_table_max) on the heap; without a
 * table (or memory), a row steps them from its first column. */
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
 *     per v, tabled once per triangle (or stepped along each row from its
 *     first column, for rows longer than the table);
 *   - the plane: its interval is found once per row (a double estimate
 *     and one exact correction) and then stepped from column to column in
 *     integers (it moves by less than one voxel of w per voxel of v,
 *     since |n_v| <= |n_w|).
 * The bounds of the edge axes step from row to row (and v to v) as
 * quotient and remainder (RN(dda)): no division after the triangle's
 * first but three per untabled row. All of it is exact integer
 * arithmetic: the same voxels as testing the 13 axes on every box. Returns 0, having visited nothing,
 * when the stepping state does not fit ST.
 * One function of 300 lines on purpose: it is voxelize's innermost loop,
 * and the stepping state of the rows and columns it carries from one
 * iteration to the next is what the compiler keeps in registers; its
 * steps are the commented blocks below. */
static inline __attribute__((always_inline)) int
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
	const int64_t nu = vhi[u] - vlo[u] + 1, nv = vhi[v] - vlo[v] + 1;
	/* per v: the range of k = cw - vlo[w] the axes tv admit (origin[w]
	 * is the low corner of voxel vlo[w], so p[w] = k * s; likewise
	 * p[v] = i * s for cv = vlo[v] + i) */
	struct RN(dda) dtv[3];
	for (int k = 0; k < 3; k++)
		if (!RN(dda_init)(&dtv[k], x.a[tv[k]][w] * s,
				  x.a[tv[k]][v] * s, lo[tv[k]], hi[tv[k]], nv))
			return 0;
	/* per row (fixed u, p[u] = j * s): the range of i the axes col
	 * admit, the range of k the axes ru admit */
	struct RN(dda) dcol[3], dru[3];
	for (int k = 0; k < 3; k++)
		if (!RN(dda_init)(&dcol[k], x.a[col[k]][v] * s,
				  x.a[col[k]][u] * s, lo[col[k]], hi[col[k]],
				  nu) ||
		    !RN(dda_init)(&dru[k], x.a[ru[k]][w] * s,
				  x.a[ru[k]][u] * s, lo[ru[k]], hi[ru[k]], nu))
			return 0;
	/* The plane in a column: lo[0] <= b + wstep * k <= hi[0]. Negated
	 * when wstep < 0, it reads pl <= c + P * k <= ph with P > 0,
	 * c = sg * b. A zero normal (degenerate triangle) is a zero axis: it
	 * passes every box. With c = P qc + rc, pl = P ql + rl and
	 * ph = P qh + rh, the range is ql - qc + (rl > rc) .. qh - qc -
	 * (rc > rh). c needs RT, but c / P = sg (n_u j + n_v i) / |n_w|
	 * (row j, column i) is within the rows and columns (|n_u|, |n_v| <=
	 * |n_w|): a double estimate of qc, then the exact remainder and one
	 * correction, instead of a division a row. */
	const RT wstep = x.a[0][w] * s;
	const RT wP = wstep < 0 ? -wstep : wstep;
	const RT sg = wstep < 0 ? -1 : 1;
	const RT pl = wstep < 0 ? -hi[0] : lo[0];
	const RT ph = wstep < 0 ? -lo[0] : hi[0];
	RT pql = 0, pqh = 0;
	double fu = 0, fv = 0;
	if (wP != 0) {
		pql = RN(wdiv)(pl, wP), pqh = RN(wdiv)(ph, wP);
		if (!RN(fits)(wP) || !RN(fits)(pql) || !RN(fits)(pqh))
			return 0;
		const double n = (double)(sg * x.a[0][w]);
		fu = (double)(sg * x.a[0][u]) / n;
		fv = (double)(sg * x.a[0][v]) / n;
	}
	/* e1, e2 + dc stay within (-P, 2P) */
	const ST P = (ST)wP, dc = (ST)(sg * x.a[0][v] * s);
	const ST prl = (ST)(pl - pql * wP), prh = (ST)(ph - pqh * wP);
	struct brick_emit e;
	if (sink)
		emit_init(&e, sink, u, v, w, vlo, vhi);
	struct col_tab cts[RN(VTAB)], *ct = cts, *heap = NULL;
	int tabled = nv <= vd_raster_table_max;
	if (tabled && nv > RN(VTAB))
		tabled = (ct = heap = malloc((size_t)nv * sizeof *heap)) != NULL;
	/* brick_cols's triangles table their bounds in the cell's
	 * coordinates along w */
	const int bricks = sink && tabled && e.tabled && wP != 0;
	const int64_t ctoff = bricks ? vlo[w] - e.lo[2] : 0;
#ifdef RN_VEC
	/* brick_quads: the per-v bounds as two arrays, from -4 to nv + 3 */
	const int quads = bricks && nv <= RN(VTAB);
	int32_t qlo[RN(VTAB) + 8], qhi[RN(VTAB) + 8];
	if (quads)
		for (int k = 0; k < 4; k++) {
			qlo[k] = qhi[k] = 0;
			qlo[nv + 4 + k] = qhi[nv + 4 + k] = 0;
		}
#endif
	/* the columns (v) and rows (u) that axes with A = 0 admit */
	int64_t vs1, vs2, us1, us2, s1, s2;
	RN(dda_steps)(dtv, &vs1, &vs2);
	RN(dda_steps)(dcol, &us1, &us2);
	RN(dda_steps)(dru, &s1, &s2);
	us1 = s1 > us1 ? s1 : us1;
	us2 = s2 < us2 ? s2 : us2;
	if (tabled) {
		struct RN(dda3) g;
		RN(dda3_init)(&g, dtv, 0, kmax);
		for (int64_t i = 0; i < nv; i++) {
			int64_t t1, t2;
			RN(dda3_range)(&g, &t1, &t2);
			RN(dda3_step)(&g);
			/* within int32 (empty: t1 > t2) */
			t1 = t1 > kmax + 1 ? kmax + 1 : t1;
			t2 = t2 < -1 ? -1 : t2;
#ifdef RN_VEC
			if (quads) {
				qlo[i + 4] = (int32_t)(t1 + ctoff);
				qhi[i + 4] = (int32_t)(t2 + ctoff);
				continue;
			}
#endif
			ct[i].lo = (int32_t)(t1 + ctoff);
			ct[i].hi = (int32_t)(t2 + ctoff);
			if (sink) {
				uint32_t lv = (uint32_t)(vlo[v] - e.lo[1] + i);
				ct[i].m = (uint32_t)d5[lv & 31] << e.sh[1];
				/* exact for a tabled triangle */
				ct[i].blk = (int32_t)(((lv >> 5) - e.tb[1]) *
						      e.nbw - e.tb[2]);
			}
		}
		/* the columns that axes with A = 0 exclude: none that the
		 * tests reach (such an axis is the box axis v, which
		 * raster_range's bounds already apply); kept for the rule */
		for (int64_t i = 0; i < nv && (vs1 > 0 || vs2 < nv - 1); i++) {
			if (i >= vs1 && i <= vs2)
				continue;
#ifdef RN_VEC
			if (quads) {
				qlo[i + 4] = (int32_t)(kmax + 1 + ctoff);
				qhi[i + 4] = (int32_t)(-1 + ctoff);
				continue;
			}
#endif
			ct[i].lo = (int32_t)(kmax + 1 + ctoff);
			ct[i].hi = (int32_t)(-1 + ctoff);
		}
	}
	/* brick_cols: the plane's thickness, and its step made >= 0 */
	const ST Dq = (ST)pqh - (ST)pql - (prl > prh);
	const ST Dr = prh - prl + (prl > prh ? P : 0);
	const ST kd = dc < 0, dcp = dc < 0 ? dc + P : dc;
#ifdef RN_VEC
	struct RN(quad) qd;
	if (quads)
		RN(quad_init)(&qd, P, dcp, kd, Dq, Dr);
#endif
#ifdef RN_VEC
	struct RN(qrow) qrows[2], *pend = NULL;
#endif
	struct RN(dda3) gcol, gru;
	RN(dda3_init)(&gcol, dcol, 0, nv - 1);
	RN(dda3_init)(&gru, dru, 0, kmax);
	int64_t p[3];
	for (int64_t j = 0; j < nu; j++) {
		const int64_t cu = vlo[u] + j;
		p[u] = j * s;
		if (sink) {
			if (e.stop)
				break;
			emit_row(&e, cu);
		}
		int64_t i0, i1, r1, r2;
		RN(dda3_range)(&gcol, &i0, &i1);
		RN(dda3_step)(&gcol);
		RN(dda3_range)(&gru, &r1, &r2);
		RN(dda3_step)(&gru);
		if (i0 > i1 || r1 > r2 || j < us1 || j > us2)
			continue;
		p[v] = i0 * s;
		/* the plane's exact range of k in the first column, and the
		 * slack e1 = c + P*k1 - pl, e2 = ph - c - P*k2 in [0, P) */
		ST k1 = 0, k2 = kmax, e1 = 0, e2 = 0, rc = 0;
		if (P != 0) {
			/* g is c / P within (nu + nv) 2^-50, so
			 * floor(g - 1/2) is qc or qc - 1 */
			RT c = sg * (x.a[0][u] * p[u] + x.a[0][v] * p[v]);
			double g = (double)j * fu + (double)i0 * fv - 0.5;
#ifdef RN_VEC
			/* one vroundsd: no conversion back and compare */
			int64_t qc = (int64_t)floor(g);
#else
			int64_t qc = (int64_t)g;
			qc -= (double)qc > g;
#endif
			RT wrc = c - (RT)qc * wP;
			if (wrc >= wP)
				wrc -= wP, qc++;
			rc = (ST)wrc;
			k1 = (ST)pql - qc + (prl > rc);
			e1 = rc - prl + (prl > rc ? P : 0);
			/* (k2 and e2 below: brick_cols does without) */
			k2 = (ST)pqh - qc;
		}
		if (bricks) {
			const uint32_t ov = (uint32_t)(vlo[v] - e.lo[1]);
			const struct col_tab *c = ct + i0, *cend = ct + i1;
			k1 += ctoff, r1 += ctoff, r2 += ctoff;
#ifdef RN_VEC
			if (quads) {
				/* rows 2n and 2n + 1 (of the cell) go together:
				 * a row waits in its slot for the next (in
				 * place: copying it would stall on
				 * store-to-load forwarding) */
				struct RN(qrow) *row = &qrows[pend == qrows];
				row->i0 = i0, row->i1 = i1, row->r1 = r1;
				row->r2 = r2, row->cu = cu, row->k1 = k1;
				row->e1 = e1;
				const int32_t *ql = qlo + 4, *qh = qhi + 4;
				if (pend && pend->cu + 1 == cu) {
					RN(brick_quads_w)(&e, ql, qh, &qd, pend,
							  row, P, kd, ov, w);
					pend = NULL;
					continue;
				}
				if (pend)
					RN(brick_quads_w)(&e, ql, qh, &qd, pend,
							  NULL, P, kd, ov, w);
				pend = !((cu - e.lo[0]) & 1) && j + 1 < nu ?
				       row : NULL;
				if (!pend)
					RN(brick_quads_w)(&e, ql, qh, &qd, row,
							  NULL, P, kd, ov, w);
				continue;
			}
#endif
			if (w == 0 && kd)
				RN(brick_cols)(&e, c, cend, k1, e1, P, dcp, Dq, Dr,
					       r1, r2, ct, ov, 0, 1);
			else if (w == 0)
				RN(brick_cols)(&e, c, cend, k1, e1, P, dcp, Dq, Dr,
					       r1, r2, ct, ov, 0, 0);
			else if (w == 1 && kd)
				RN(brick_cols)(&e, c, cend, k1, e1, P, dcp, Dq, Dr,
					       r1, r2, ct, ov, 1, 1);
			else if (w == 1)
				RN(brick_cols)(&e, c, cend, k1, e1, P, dcp, Dq, Dr,
					       r1, r2, ct, ov, 1, 0);
			else if (kd)
				RN(brick_cols)(&e, c, cend, k1, e1, P, dcp, Dq, Dr,
					       r1, r2, ct, ov, 2, 1);
			else
				RN(brick_cols)(&e, c, cend, k1, e1, P, dcp, Dq, Dr,
					       r1, r2, ct, ov, 2, 0);
			continue;
		}
		if (P != 0) {
			k2 -= rc > prh;
			e2 = prh - rc + (rc > prh ? P : 0);
		}
		struct RN(dda) dt[3];
		if (!tabled)
			for (int k = 0; k < 3; k++)
				RN(dda_at)(&dt[k], &dtv[k], i0);
		for (int64_t i = i0; i <= i1; i++) {
			int64_t w0 = k1 > r1 ? (int64_t)k1 : r1;
			int64_t w1 = k2 < r2 ? (int64_t)k2 : r2;
			if (P != 0) {
				/* step the plane's range to the next column
				 * (|dc| <= P: one correction at most) */
				e1 += dc;
				ST m1 = (e1 >= P) - (e1 < 0);
				k1 -= m1, e1 -= m1 * P;
				e2 -= dc;
				ST m2 = (e2 >= P) - (e2 < 0);
				k2 += m2, e2 -= m2 * P;
			}
			if (tabled) {
				w0 = ct[i].lo > w0 ? ct[i].lo : w0;
				w1 = ct[i].hi < w1 ? ct[i].hi : w1;
			} else {
				for (int k = 0; k < 3; k++) {
					RN(dda_bound)(&dt[k], &w0, &w1);
					RN(dda_step)(&dt[k]);
				}
				if (i < vs1 || i > vs2)
					continue;
			}
			if (w0 > w1)
				continue;
			int64_t cv = vlo[v] + i;
			if (sink) {
				emit_run(&e, (uint32_t)(cv - e.lo[1]),
					 (uint32_t)(vlo[w] + w0 - e.lo[2]),
					 (uint32_t)(vlo[w] + w1 - e.lo[2]));
				continue;
			}
			int64_t out[3];
			out[u] = cu, out[v] = cv, out[w] = vlo[w] + w0;
			fn(ctx, w, out[0], out[1], out[2], w1 - w0 + 1);
		}
	}
#ifdef RN_VEC
	if (pend && !e.stop)
		RN(brick_quads_w)(&e, qlo + 4, qhi + 4, &qd, pend, NULL, P, kd,
				  (uint32_t)(vlo[v] - e.lo[1]), w);
#endif
	free(heap);
	return 1;
}

static int RN(raster)(const struct vd_snapped_tri *tri, const int64_t vlo[3],
		      const int64_t vhi[3], const int64_t origin[3], int64_t s,
		      vd_span_fn fn, void *ctx)
{
	return RN(raster_core)(tri, vlo, vhi, origin, s, fn, ctx, NULL);
}

static int RN(raster_bricks)(const struct vd_snapped_tri *tri,
			     const int64_t vlo[3], const int64_t vhi[3],
			     const int64_t origin[3], int64_t s,
			     struct vd_brick_sink *sink)
{
	return RN(raster_core)(tri, vlo, vhi, origin, s, NULL, NULL, sink);
}
