/* Variable-bitrate block encoding of a colour array (Dolonius, Sintorn,
 * Kämpe, Assarsson 2017, section 4.2): blocks of any length, two RGB565
 * endpoints each, a fixed-width weight per voxel. The blocks are found by
 * the paper's Algorithm 1: a sweep for single-colour runs, then passes that
 * merge a block with its left or right neighbour while every colour of the
 * merged block stays within the error threshold, preferring the merge of
 * lower mean squared error.
 *
 * Where the paper's pseudo-code and text disagree we follow the text: a
 * merge is possible when its score (the MSE) is >= 0, not > 0 (a perfect
 * fit has MSE 0), and of two possible merges the lower MSE wins, ties to
 * the left (the pseudo-code's "leftmse < rightmse" would merge left when
 * only the right merge is possible). After a block is handled the pass
 * moves two blocks right of the (merged) block, as the text says. */
#include "voxdag.h"

#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

unsigned vd_colour_error_limit(double max_error)
{
	/* dist2 is an integer, so dist2 <= (et*255)^2 iff dist2 <= floor of
	 * it; the tiny slack keeps 0.1*255 = 25.5 from rounding below. */
	if (!(max_error > 0))
		return 0;
	double x = max_error * 255.0;
	x = x * x * (1 + 1e-12);
	return x >= 3 * 255.0 * 255.0 ? 3 * 255 * 255 : (unsigned)x;
}

/* Decoded 8-bit values of the 5- and 6-bit levels (bit replication). */
#define E5(c) ((c) << 3 | (c) >> 2)
#define E6(c) ((c) << 2 | (c) >> 4)
#define E5x4(c) E5(c), E5((c) + 1), E5((c) + 2), E5((c) + 3)
#define E6x4(c) E6(c), E6((c) + 1), E6((c) + 2), E6((c) + 3)
static const uint8_t dec5[32] = {E5x4(0), E5x4(4), E5x4(8), E5x4(12),
				 E5x4(16), E5x4(20), E5x4(24), E5x4(28)};
static const uint8_t dec6[64] = {E6x4(0), E6x4(4), E6x4(8), E6x4(12),
				 E6x4(16), E6x4(20), E6x4(24), E6x4(28),
				 E6x4(32), E6x4(36), E6x4(40), E6x4(44),
				 E6x4(48), E6x4(52), E6x4(56), E6x4(60)};

/* Nearest 5- or 6-bit level (by decoded value) to v in [0, 255], ties to
 * the lower level: the number of midpoints between consecutive decoded
 * levels that lie below v. The midpoints are multiples of 1/2, so with
 * j = floor(2v) that is the count of those below j/2 plus one when a
 * midpoint sits at j/2 and v is above it: two tables by j. (It replaced a
 * search of the rounded scaled value and its neighbours, which finds the
 * same level: checked against it on every multiple of 1/4096 in [0, 255]
 * and the doubles next to every multiple of 1/2.) */
static uint8_t lvl_below[2][511], lvl_at[2][511];
static pthread_once_t lvl_once = PTHREAD_ONCE_INIT;

static void lvl_init(void)
{
	for (int kind = 0; kind < 2; kind++) {
		int top = kind ? 63 : 31;
		const uint8_t *dec = kind ? dec6 : dec5;
		for (int j = 0; j < 511; j++)
			for (int c = 0; c < top; c++) {
				int mid2 = dec[c] + dec[c + 1]; /* twice the midpoint */
				lvl_below[kind][j] += mid2 < j;
				lvl_at[kind][j] |= mid2 == j;
			}
	}
}

static inline unsigned nearest_level(double v, int bits)
{
	int kind = bits == 6;
	double v2 = 2 * v;
	int j = (int)v2;
	return lvl_below[kind][j] + (lvl_at[kind][j] && v2 > j);
}

/* The caller has run vbr_init(). */
static uint16_t to565(const double c[3])
{
	double v[3];
	for (int k = 0; k < 3; k++)
		v[k] = c[k] > 255 ? 255 : c[k] >= 0 ? c[k] : 0; /* NaN: 0 */
	return (uint16_t)(nearest_level(v[0], 5) << 11 |
			  nearest_level(v[1], 6) << 5 |
			  nearest_level(v[2], 5));
}

/* A run of colours twice: interleaved (colour i at rgb + 3 i) for the
 * scalar loops and as three planes (channel c of colour i at
 * pl[c * ps + i]) for the lanes, which then load eight of a channel at
 * once instead of gathering bytes (a tenth of the time). */
struct cols {
	const uint8_t *rgb, *pl;
	size_t ps;
};

static inline struct cols cols_at(const struct cols *C, uint32_t i)
{
	struct cols c = {C->rgb + 3 * (size_t)i, C->pl + i, C->ps};
	return c;
}

int vd_vbr_lanes = 1;

/* Eight lanes of an AVX2 register, on x86-64 CPUs that have it (checked
 * at run time; elsewhere the scalar loop does all). No FMA: C11 mode keeps
 * a*b+c two roundings, so the lanes give the scalar loop's bits. */
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define VBR_LANES 8
#define LANES VBR_LANES
/* The lanes when the CPU has AVX2 and the tests have not turned them off
 * (vd_vbr_lanes = 0: they compare the two paths' bytes). */
static inline int lanes_on(void)
{
	return vd_vbr_lanes && __builtin_cpu_supports("avx2");
}
typedef float vf __attribute__((vector_size(4 * LANES)));
typedef int32_t vi __attribute__((vector_size(4 * LANES)));

/* check_endpoints' rule LANES colours at a time (C's [0..n); the planes
 * readable to LANES - 1 bytes past n), in float lanes where every value is an exact integer: the
 * dot product and squared distances stay below 2^24, the rounded
 * projection is the same float product as the scalar one, and a decoded
 * level (A + D k + m/2) div m is the truncation of (A + D k + m/2 + 1/2) / m
 * computed with a float 1/m (the result lies at least 1/(2m) from the
 * next integer, the float error below 2^-14). Adds to *sse; 0 when a
 * colour is outside the limit, *failed the first index of its run. */
__attribute__((target("avx2")))
static int check_lanes(const struct cols *C, uint32_t n, unsigned limit,
		       int m, const uint8_t a[3], const int d[3], float inv,
		       uint8_t *w, uint64_t *sse, uint32_t *failed)
{
	const vf zf = {0};
	const vi zi = {0};
	const float invm = 1.0f / (float)m;
	/* level numerators at k: A_c + D_c k, with m/2 + 1/2 folded in */
	vf A[3], D[3], ac[3];
	for (int c = 0; c < 3; c++) {
		A[c] = zf + ((float)(a[c] * m + m / 2) + 0.5f);
		D[c] = zf + (float)d[c];
		ac[c] = zf + (float)a[c];
	}
	/* W <= 3: a channel's 2^W levels fit one register, looked up by
	 * weight (vpermps, which wraps the indices -1 and 8 that only the
	 * masked neighbours use) instead of divided: the same integers */
	const int looked = m <= 7;
	vf P[3] = {zf, zf, zf};
	if (looked)
		for (int c = 0; c < 3; c++)
			for (int k = 0; k <= m; k++)
				P[c][k] = (float)((a[c] * (m - k) +
						   (a[c] + d[c]) * k + m / 2) / m);
	const vi vm = zi + m, lane = {0, 1, 2, 3, 4, 5, 6, 7};
	const vf vlim = zf + (float)limit, vbig = zf + 1e9f;
	uint64_t s = 0;
	for (uint32_t i0 = 0; i0 < n; i0 += 4 * LANES) {
		uint32_t end = n - i0 < 4 * LANES ? n : i0 + 4 * LANES;
		vi fail = zi, acc = zi;
		for (uint32_t i = i0; i < end; i += LANES) {
			vf X[3];
			for (int c = 0; c < 3; c++) {
				/* zero-extend eight bytes, convert (exact) */
				__m128i x = _mm_loadl_epi64(
					(const __m128i *)(C->pl + c * C->ps + i));
				X[c] = (vf)_mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(x));
			}
			vf dot = (X[0] - ac[0]) * D[0] + (X[1] - ac[1]) * D[1] +
				 (X[2] - ac[2]) * D[2];
			vi k0 = __builtin_convertvector(dot * inv + 0.5f, vi);
			k0 &= ~(k0 < zi);
			vi over = k0 > vm;
			k0 = (k0 & ~over) | (vm & over);
			vf kf = __builtin_convertvector(k0, vf);
			vf e0 = zf, el = zf, eh = zf;
			vi kl = k0 - 1, kh = k0 + 1;
			for (int c = 0; c < 3; c++) {
				vf p0, pl, ph;
				if (looked) {
					__m256 pc = (__m256)P[c];
					p0 = (vf)_mm256_permutevar8x32_ps(pc, (__m256i)k0);
					pl = (vf)_mm256_permutevar8x32_ps(pc, (__m256i)kl);
					ph = (vf)_mm256_permutevar8x32_ps(pc, (__m256i)kh);
				} else {
					vf num = A[c] + D[c] * kf;
					p0 = __builtin_convertvector(
						__builtin_convertvector(num * invm, vi),
						vf);
					pl = __builtin_convertvector(
						__builtin_convertvector(
							(num - D[c]) * invm, vi),
						vf);
					ph = __builtin_convertvector(
						__builtin_convertvector(
							(num + D[c]) * invm, vi),
						vf);
				}
				vf q0 = X[c] - p0, ql = X[c] - pl, qh = X[c] - ph;
				e0 += q0 * q0;
				el += ql * ql;
				eh += qh * qh;
			}
			/* no weight below 0 or above m */
			vi lo = k0 == zi, hi = k0 == vm;
			el = (vf)(((vi)el & ~lo) | ((vi)vbig & lo));
			eh = (vf)(((vi)eh & ~hi) | ((vi)vbig & hi));
			/* ties to the lower weight */
			vi tl = el <= e0;
			vf best = (vf)(((vi)el & tl) | ((vi)e0 & ~tl));
			vi bk = k0 + tl; /* tl is -1 where true */
			vi th = eh < best;
			best = (vf)(((vi)eh & th) | ((vi)best & ~th));
			bk = (bk & ~th) | ((k0 + 1) & th);
			int valid = n - i < LANES ? (int)(n - i) : LANES;
			if (valid < LANES) /* the lanes past n count nothing */
				best = (vf)((vi)best & (lane < valid));
			fail |= best > vlim;
			acc += __builtin_convertvector(best, vi);
			if (w)
				for (int l = 0; l < valid; l++)
					w[i + (uint32_t)l] = (uint8_t)bk[l];
		}
		uint32_t f = 0, t = 0;
		for (int l = 0; l < LANES; l++) {
			f |= (uint32_t)fail[l];
			t += (uint32_t)acc[l];
		}
		if (f) {
			*failed = i0;
			return 0;
		}
		s += t;
	}
	*sse += s;
	return 1;
}

typedef double vd4 __attribute__((vector_size(32)));
typedef int64_t vl4 __attribute__((vector_size(32)));

/* fit_m's projection on the axis four colours at a time, each lane the
 * scalar loop's operations in its order (no FMA), so the same t[i]; their
 * least and greatest are the same in any order. Does C's [0..n & ~3) and
 * returns that count. */
__attribute__((target("avx2")))
static uint32_t project_lanes(const struct cols *C, uint32_t n,
			      const double mu[3], const double ax[3],
			      double *t, double *tmin, double *tmax)
{
	vd4 M[3], A[3];
	for (int c = 0; c < 3; c++) { /* not z + ax[c], which loses a -0 */
		M[c] = (vd4){mu[c], mu[c], mu[c], mu[c]};
		A[c] = (vd4){ax[c], ax[c], ax[c], ax[c]};
	}
	vd4 lo = {*tmin, *tmin, *tmin, *tmin}, hi = {*tmax, *tmax, *tmax, *tmax};
	uint32_t n4 = n & ~(uint32_t)3;
	for (uint32_t i = 0; i < n4; i += 4) {
		vd4 X[3];
		for (int c = 0; c < 3; c++) {
			int32_t four;
			memcpy(&four, C->pl + c * C->ps + i, sizeof four);
			X[c] = (vd4)_mm256_cvtepi32_pd(
				_mm_cvtepu8_epi32(_mm_cvtsi32_si128(four)));
		}
		vd4 v = (X[0] - M[0]) * A[0] + (X[1] - M[1]) * A[1] +
			(X[2] - M[2]) * A[2];
		memcpy(t + i, &v, sizeof v);
		vl4 below = v < lo, above = v > hi;
		lo = (vd4)(((vl4)v & below) | ((vl4)lo & ~below));
		hi = (vd4)(((vl4)v & above) | ((vl4)hi & ~above));
	}
	for (int l = 0; l < 4; l++) {
		*tmin = lo[l] < *tmin ? lo[l] : *tmin;
		*tmax = hi[l] > *tmax ? hi[l] : *tmax;
	}
	return n4;
}
#endif

/* A block's line: decoded endpoints and the 2^W colours on it, for the
 * checks of check_endpoints. */
struct line {
	uint8_t a[3], b[3];
	int d[3], m;
	float inv;
	unsigned limit;
	/* the 2^W decoded colours of this block's line at [1..m+1], by
	 * channel; [0] and [m+2] far outside the cube, so the neighbours of
	 * the first and last weight never win and need no test. Filled
	 * (palette = 1) only when a scalar loop needs them. */
	int palette;
	int pr[258], pg[258], pb[258];
};

/* Fills L's palette for the scalar loop (the lanes compute the levels):
 * vd_vbr_interp's rule, the endpoints decoded once; the paper's W = 3
 * divides by a constant (a multiplication), other widths by m. */
static void line_palette(struct line *L)
{
	const uint8_t *a = L->a, *b = L->b;
	int *pr = L->pr, *pg = L->pg, *pb = L->pb, m = L->m;
	if (m == 7)
		for (int k = 0; k <= 7; k++) {
			pr[k + 1] = (a[0] * (7 - k) + b[0] * k + 3) / 7;
			pg[k + 1] = (a[1] * (7 - k) + b[1] * k + 3) / 7;
			pb[k + 1] = (a[2] * (7 - k) + b[2] * k + 3) / 7;
		}
	else
		for (int k = 0; k <= m; k++) {
			pr[k + 1] = (a[0] * (m - k) + b[0] * k + m / 2) / m;
			pg[k + 1] = (a[1] * (m - k) + b[1] * k + m / 2) / m;
			pb[k + 1] = (a[2] * (m - k) + b[2] * k + m / 2) / m;
		}
	pr[0] = pg[0] = pb[0] = pr[m + 2] = pg[m + 2] = pb[m + 2] = 4096;
	L->palette = 1;
}

/* Checks C's colours [0..n) against the line L. Returns 1 and adds the
 * SSE to *sse, or 0 with *fail the first index of the run of colours that
 * holds one outside the limit. */
static int check_span(struct line *L, struct cols C, uint32_t n,
		      uint8_t *w, uint64_t *sse, uint32_t *fail)
{
	const uint8_t *rgb = C.rgb;
	const uint8_t *a = L->a;
	const int *d = L->d, *pr = L->pr, *pg = L->pg, *pb = L->pb;
	int m = L->m;
	float inv = L->inv;
	unsigned limit = L->limit;
	uint64_t s = 0;
	/* Branch-free over runs of colours, the limit tested once a run: a
	 * colour outside fails the block wherever it is, and the weights of a
	 * failed check are not used. Of the three weights the least error
	 * wins, ties to the lower weight. */
	uint32_t n4 = 0;
#ifdef VBR_LANES
	if (lanes_on()) {
		n4 = n;
		if (n4 && !check_lanes(&C, n4, limit, m, a, d, inv, w, &s,
				       fail))
			return 0;
	}
#endif
	if (n4 < n && !L->palette)
		line_palette(L);
	enum { RUN = 32 };
	uint8_t wrun[RUN];
	for (uint32_t i0 = n4; i0 < n; i0 += RUN) {
		uint32_t len = n - i0 < RUN ? n - i0 : RUN;
		const uint8_t *x = rgb + 3 * (size_t)i0;
		unsigned worst = 0, rs = 0;
		uint8_t *wo = w ? w + i0 : wrun;
		for (uint32_t i = 0; i < len; i++, x += 3) {
			int r = x[0], g = x[1], bl = x[2];
			int dot = (r - a[0]) * d[0] + (g - a[1]) * d[1] +
				  (bl - a[2]) * d[2];
			int k0 = (int)((float)dot * inv + 0.5f);
			k0 = k0 < 0 ? 0 : k0 > m ? m : k0;
			int e0r = r - pr[k0 + 1], e0g = g - pg[k0 + 1],
			    e0b = bl - pb[k0 + 1];
			int elr = r - pr[k0], elg = g - pg[k0], elb = bl - pb[k0];
			int ehr = r - pr[k0 + 2], ehg = g - pg[k0 + 2],
			    ehb = bl - pb[k0 + 2];
			unsigned e0 = (unsigned)(e0r * e0r + e0g * e0g + e0b * e0b);
			unsigned el = (unsigned)(elr * elr + elg * elg + elb * elb);
			unsigned eh = (unsigned)(ehr * ehr + ehg * ehg + ehb * ehb);
			unsigned best = e0;
			int bk = k0;
			if (el <= best) {
				best = el;
				bk = k0 - 1;
			}
			if (eh < best) {
				best = eh;
				bk = k0 + 1;
			}
			worst = best > worst ? best : worst;
			rs += best;
			wo[i] = (uint8_t)bk;
		}
		if (worst > limit) {
			*fail = i0;
			return 0;
		}
		s += rs;
	}
	*sse += s;
	return 1;
}

/* Checks endpoints c0, c1 against rgb[0..n): the best weight of every
 * colour (rounded projection and its neighbours, judged by the exact
 * integer decoder), all within `limit`. Returns 1 and the SSE, or 0 when
 * a colour is outside. *hint (< n, or any value >= n for none) names a
 * colour likely to fail, tested first: the answer is the same whatever
 * the order (a failure anywhere fails the block, the SSE is an integer
 * sum), only found sooner; on a failure it is set to a failing run. */
static int check_endpoints(const struct cols *C, uint32_t n, unsigned limit,
			   int wb, uint16_t c0, uint16_t c1, uint8_t *w,
			   uint64_t *sse, uint32_t *hint)
{
	struct line L;
	const uint8_t *a = L.a, *b = L.b;
	vd_rgb565_decode(c0, L.a);
	vd_rgb565_decode(c1, L.b);
	int m = L.m = (1 << wb) - 1;
	L.palette = 0;
	for (int k = 0; k < 3; k++)
		L.d[k] = b[k] - a[k];
	int len2 = L.d[0] * L.d[0] + L.d[1] * L.d[1] + L.d[2] * L.d[2];
	/* the rounded projection is only where the search starts (it and
	 * its neighbours are judged exactly), so a float product will do */
	L.inv = len2 ? (float)m / (float)len2 : 0.f;
	L.limit = limit;
	/* the hint's run of colours (aligned to the lanes) first, then the
	 * colours before it, then those after: each colour once */
	uint32_t h0 = *hint < n ? *hint & ~(uint32_t)31 : 0;
	uint32_t hn = n - h0 < 32 ? n - h0 : 32, h1 = h0 + hn;
	uint32_t fail = 0;
	uint64_t s = 0;
	if (!check_span(&L, cols_at(C, h0), hn, w ? w + h0 : NULL, &s,
			&fail)) {
		*hint = h0 + fail;
		return 0;
	}
	if (!check_span(&L, *C, h0, w, &s, &fail)) {
		*hint = fail;
		return 0;
	}
	if (!check_span(&L, cols_at(C, h1), n - h1, w ? w + h1 : NULL,
			&s, &fail)) {
		*hint = h1 + fail;
		return 0;
	}
	*sse = s;
	return 1;
}

/* A block of one colour x. With the weight w fixed the three channels are
 * independent (each its own endpoint levels), so per channel and w the
 * levels (a, b) whose interpolation decodes nearest x_k are a table, and
 * the best (c0, c1, w) is the w of least summed squared error. Storing the
 * nearest RGB565 instead (w = 0) kept its whole rounding error, up to
 * 6.1/255 and 8.2 in GMSE units on average, on every flat material colour,
 * though two endpoints and a weight decode 98.5% of all 8-bit colours
 * exactly at W = 3. Tables for every weight width, built once: row m + w
 * (m = 2^W - 1, so the widths 1..8 use the disjoint rows 1..510); kind 0
 * the 5-bit channels, 1 the 6-bit one. Ties: the lower w, the decoded value
 * below x, the first (a, b) in a-major order. */
struct near1 {
	uint8_t a, b, err;
};
static struct near1 near_tab[511][2][256];
static pthread_once_t near_once = PTHREAD_ONCE_INIT;

/* The least-squares fit's weights q / m and their products, row m + q as
 * in near_tab: the same doubles the fit would compute per colour, without
 * a division per colour. */
typedef double v2d __attribute__((vector_size(16)));
struct lsw {
	v2d s;       /* 1 - q/m, q/m */
	v2d q;       /* their products aa, ab (ls_lanes reads s, q as one) */
	double bb;
};
static struct lsw ls_tab[511];

#ifdef VBR_LANES
/* fit_m's least-squares sums over C's [0..n & ~3), four colours a step:
 * their weights from t in double lanes (the scalar expression per lane),
 * then the sums colour by colour in order, r0 and r1 sharing a register
 * ({sa, sb, sa, sb} times {r, r, g, g}) and r2 with qab ({sa, sb, aa, ab}
 * times {b, b, 1, 1}, the 1 exact): per lane the scalar loop's operations,
 * so the same bits, in fewer instructions. Returns the count done. */
__attribute__((target("avx2")))
static uint32_t ls_lanes(const struct cols *C, const double *t, uint32_t n,
			 double tmin, double sc, int m, v2d r[4],
			 double *bbp)
{
	const struct lsw *lw = ls_tab + m;
	__m256d r01 = _mm256_setr_pd(r[0][0], r[0][1], r[1][0], r[1][1]);
	__m256d r2q = _mm256_setr_pd(r[2][0], r[2][1], r[3][0], r[3][1]);
	double bb = *bbp;
	const __m256d vmin = _mm256_set1_pd(tmin), vsc = _mm256_set1_pd(sc),
		      half = _mm256_set1_pd(0.5), one = _mm256_set1_pd(1);
	const __m128i vm = _mm_set1_epi32(m);
	uint32_t n4 = n & ~(uint32_t)3;
	for (uint32_t i = 0; i < n4; i += 4) {
		__m256d y = _mm256_add_pd(
			_mm256_mul_pd(_mm256_sub_pd(_mm256_loadu_pd(t + i), vmin),
				      vsc),
			half);
		int32_t q[4];
		_mm_storeu_si128((__m128i *)q,
				 _mm_min_epi32(_mm256_cvttpd_epi32(y), vm));
		__m256d X[3];
		for (int c = 0; c < 3; c++) {
			int32_t four;
			memcpy(&four, C->pl + c * C->ps + i, sizeof four);
			X[c] = _mm256_cvtepi32_pd(
				_mm_cvtepu8_epi32(_mm_cvtsi32_si128(four)));
		}
		/* {r, g} of colours 0, 2 and of 1, 3 */
		__m256d u0 = _mm256_unpacklo_pd(X[0], X[1]),
			u1 = _mm256_unpackhi_pd(X[0], X[1]);
		__m256d x01[4] = {_mm256_permute4x64_pd(u0, 0x50),
				  _mm256_permute4x64_pd(u1, 0x50),
				  _mm256_permute4x64_pd(u0, 0xfa),
				  _mm256_permute4x64_pd(u1, 0xfa)};
		__m256d x2q[4] = {
			_mm256_blend_pd(_mm256_permute4x64_pd(X[2], 0x00), one, 12),
			_mm256_blend_pd(_mm256_permute4x64_pd(X[2], 0x55), one, 12),
			_mm256_blend_pd(_mm256_permute4x64_pd(X[2], 0xaa), one, 12),
			_mm256_blend_pd(_mm256_permute4x64_pd(X[2], 0xff), one, 12)};
		for (int l = 0; l < 4; l++) {
			const struct lsw *e = lw + q[l];
			__m256d s01 = _mm256_broadcast_pd((const __m128d *)&e->s);
			__m256d s2q = _mm256_loadu_pd((const double *)&e->s);
			r01 = _mm256_add_pd(r01, _mm256_mul_pd(s01, x01[l]));
			r2q = _mm256_add_pd(r2q, _mm256_mul_pd(s2q, x2q[l]));
			bb += e->bb;
		}
	}
	double o[8];
	_mm256_storeu_pd(o, r01);
	_mm256_storeu_pd(o + 4, r2q);
	for (int k = 0; k < 4; k++)
		r[k] = (v2d){o[2 * k], o[2 * k + 1]};
	*bbp = bb;
	return n4;
}
#endif

static void near_init(void)
{
	for (int m = 1; m < 256; m = 2 * m + 1)
		for (int q = 0; q <= m; q++) {
			struct lsw *e = &ls_tab[m + q];
			double sb = (double)q / m, sa = 1 - sb;
			e->s = (v2d){sa, sb};
			e->q = (v2d){sa * sa, sa * sb};
			e->bb = sb * sb;
		}
	for (int wb = 1; wb <= 8; wb++) {
		int m = (1 << wb) - 1;
		for (int kind = 0; kind < 2; kind++) {
			int bits = kind ? 6 : 5, L = 1 << bits;
			for (int w = 0; w <= m; w++) {
				int16_t ha[256], hb[256];
				for (int v = 0; v < 256; v++)
					ha[v] = hb[v] = -1;
				for (int a = 0; a < L; a++)
					for (int b = 0; b < L; b++) {
						int ea = bits == 5 ? (a << 3 | a >> 2)
								   : (a << 2 | a >> 4);
						int eb = bits == 5 ? (b << 3 | b >> 2)
								   : (b << 2 | b >> 4);
						int v = (ea * (m - w) + eb * w + m / 2) / m;
						if (ha[v] < 0) {
							ha[v] = (int16_t)a;
							hb[v] = (int16_t)b;
						}
					}
				struct near1 *t = near_tab[m + w][kind];
				for (int x = 0; x < 256; x++)
					for (int d = 0; d < 256; d++) {
						int v = x - d >= 0 && ha[x - d] >= 0 ? x - d
							: x + d < 256 && ha[x + d] >= 0 ? x + d
											: -1;
						if (v < 0)
							continue;
						t[x].a = (uint8_t)ha[v];
						t[x].b = (uint8_t)hb[v];
						t[x].err = (uint8_t)d;
						break;
					}
			}
		}
	}
}

static int fit_flat(const uint8_t *x, unsigned limit, int wb, uint16_t *c0,
		    uint16_t *c1, uint8_t *wt, uint64_t *sse)
{
	int m = (1 << wb) - 1, bw = 0;
	unsigned best = UINT32_MAX;
	for (int w = 0; w <= m; w++) {
		const struct near1 *r = &near_tab[m + w][0][x[0]],
				   *g = &near_tab[m + w][1][x[1]],
				   *b = &near_tab[m + w][0][x[2]];
		unsigned d = (unsigned)(r->err * r->err + g->err * g->err +
					b->err * b->err);
		if (d < best) {
			best = d;
			bw = w;
		}
	}
	if (best > limit)
		return 0;
	const struct near1 *r = &near_tab[m + bw][0][x[0]],
			   *g = &near_tab[m + bw][1][x[1]],
			   *b = &near_tab[m + bw][0][x[2]];
	*c0 = (uint16_t)(r->a << 11 | g->a << 5 | b->a);
	*c1 = (uint16_t)(r->b << 11 | g->b << 5 | b->b);
	*wt = (uint8_t)bw;
	*sse = best;
	return 1;
}

/* The tables of to565, fit_flat and fit_m, built once: the entry points
 * run this, not each fit (a call per fit was 1.5% of the time). */
static void vbr_init(void)
{
	pthread_once(&lvl_once, lvl_init);
	pthread_once(&near_once, near_init);
}

/* Fills the planes of C (COLS_BYTES(n) at pl, ps = n) from rgb[0..n);
 * the bytes past the last plane are zeros the lanes may read. */
#define COLS_BYTES(n) (3 * (size_t)(n) + 16)
static void cols_split(struct cols *C, const uint8_t *rgb, uint8_t *pl,
		       uint32_t n)
{
	for (uint32_t i = 0; i < n; i++)
		for (int c = 0; c < 3; c++)
			pl[(size_t)c * n + i] = rgb[3 * (size_t)i + c];
	memset(pl + 3 * (size_t)n, 0, 16);
	C->rgb = rgb;
	C->pl = pl;
	C->ps = n;
}

/* Sums of a block's colours and of their products, exact integers, so the
 * moments of a merged block are the sum of its parts' (O(1) per merge)
 * and every path computes the same fit bit for bit. */
struct mom {
	uint64_t n, s[3], q[6]; /* q: rr rg rb gg gb bb */
};

static void mom_of(struct mom *m, const uint8_t *rgb, uint32_t n)
{
	memset(m, 0, sizeof *m);
	m->n = n;
	for (uint32_t i = 0; i < n; i++) {
		const uint8_t *x = rgb + 3 * (size_t)i;
		unsigned r = x[0], g = x[1], b = x[2];
		m->s[0] += r;
		m->s[1] += g;
		m->s[2] += b;
		m->q[0] += r * r;
		m->q[1] += r * g;
		m->q[2] += r * b;
		m->q[3] += g * g;
		m->q[4] += g * b;
		m->q[5] += b * b;
	}
}

static void mom_add(struct mom *a, const struct mom *b)
{
	a->n += b->n;
	for (int k = 0; k < 3; k++)
		a->s[k] += b->s[k];
	for (int k = 0; k < 6; k++)
		a->q[k] += b->q[k];
}

/* Largest eigenvalue of the symmetric 3x3 matrix c (closed form,
 * Smith 1961), for the bound below. */
static double lambda_max(const double c[6])
{
	double p1 = c[1] * c[1] + c[2] * c[2] + c[4] * c[4];
	double tr = c[0] + c[3] + c[5];
	if (p1 < 1e-30)
		return fmax(c[0], fmax(c[3], c[5]));
	double q = tr / 3;
	double a = c[0] - q, d = c[3] - q, f = c[5] - q;
	double p2 = a * a + d * d + f * f + 2 * p1;
	double p = sqrt(p2 / 6);
	/* det((C - qI) / p) / 2 */
	double b0 = a / p, b1 = c[1] / p, b2 = c[2] / p, b3 = d / p,
	       b4 = c[4] / p, b5 = f / p;
	double det = b0 * (b3 * b5 - b4 * b4) - b1 * (b1 * b5 - b4 * b2) +
		     b2 * (b1 * b4 - b3 * b2);
	double r = det / 2;
	double phi = r <= -1 ? M_PI / 3 : r >= 1 ? 0 : acos(r) / 3;
	return q + 2 * p * cos(phi);
}

/* fit_m's steps below are static with one caller each, so GCC inlines
 * them (-finline-functions-called-once, on at -O2): the same code as one
 * function, in the merge passes' hot path. */

/* A bound that rejects without reading the colours: every decoded
 * colour lies within sqrt(3)/2 (the rounding) of the line through
 * its endpoints, and no line is nearer the colours in the squared
 * sum than the principal axis, whose sum is trace - lambda_max. So
 * if that exceeds n (sqrt(limit) + 0.8661)^2 no endpoints can keep
 * every colour within the limit. The margins keep it sound against
 * rounding in the eigenvalue. Being sound it changes no answer, only
 * the time: on a few colours reading them costs less than the
 * eigenvalue (its acos and cos), so small blocks go without.
 * 1: no endpoints can do. */
static int fit_bound_rejects(const double cov[6], uint32_t n, unsigned limit)
{
	if (n >= 32) {
		double tr = cov[0] + cov[3] + cov[5];
		double resid = tr - lambda_max(cov);
		double reach = sqrt((double)limit) + 0.8661;
		if (resid > n * reach * reach * (1 + 1e-9) + 1e-6 * (tr + 1))
			return 1;
	}
	return 0;
}

/* The principal axis of cov into ax, by power iteration from the widest
 * channel. */
static void fit_axis(const double cov[6], double ax[3])
{
	int wide = cov[0] >= cov[3] && cov[0] >= cov[5] ? 0
		   : cov[3] >= cov[5]                    ? 1
							 : 2;
	ax[wide] = 1;
	for (int it = 0; it < 8; it++) {
		double y[3] = {cov[0] * ax[0] + cov[1] * ax[1] + cov[2] * ax[2],
			       cov[1] * ax[0] + cov[3] * ax[1] + cov[4] * ax[2],
			       cov[2] * ax[0] + cov[4] * ax[1] + cov[5] * ax[2]};
		double l = sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2]);
		if (l < 1e-12)
			break;
		double nx[3] = {y[0] / l, y[1] / l, y[2] / l};
		/* a step that changes nothing is a fixed point: the steps
		 * left would repeat it bit for bit */
		if (nx[0] == ax[0] && nx[1] == ax[1] && nx[2] == ax[2])
			break;
		for (int k = 0; k < 3; k++)
			ax[k] = nx[k];
	}
}

/* Each colour's place on the axis through mu into t[0..n), and the
 * extremes into *tmin and *tmax. */
static void fit_project(const struct cols *C, uint32_t n, const double mu[3],
			const double ax[3], double *t, double *tmin_out,
			double *tmax_out)
{
	const uint8_t *rgb = C->rgb;
	double tmin = 1e30, tmax = -1e30;
	uint32_t i0 = 0;
#ifdef VBR_LANES
	if (lanes_on())
		i0 = project_lanes(C, n, mu, ax, t, &tmin, &tmax);
#endif
	for (uint32_t i = i0; i < n; i++) {
		const uint8_t *x = rgb + 3 * (size_t)i;
		double v = (x[0] - mu[0]) * ax[0] + (x[1] - mu[1]) * ax[1] +
			   (x[2] - mu[2]) * ax[2];
		t[i] = v;
		tmin = v < tmin ? v : tmin;
		tmax = v > tmax ? v : tmax;
	}
	*tmin_out = tmin;
	*tmax_out = tmax;
}

/* Least squares: each colour's weight from its place between the
 * extremes of the axis, then the two endpoints minimising the squared
 * error for those weights (2x2 normal equations shared by the
 * channels) into l0 and l1, which keep the extremes when the places
 * coincide or the equations are singular. */
static void fit_least_squares(const struct cols *C, const double *t,
			      uint32_t n, double tmin, double tmax,
			      int weight_bits, double l0[3], double l1[3])
{
	const uint8_t *rgb = C->rgb;
	int m = (1 << weight_bits) - 1;
	if (tmax - tmin > 1e-9) {
		double sc = m / (tmax - tmin);
		/* two sums a lane (a's, b's), each lane the same operations
		 * in the same order as one scalar sum: the same bits */
		v2d r0 = {0, 0}, r1 = {0, 0}, r2 = {0, 0}, qab = {0, 0};
		double bb = 0;
		const struct lsw *lw = ls_tab + m;
		uint32_t done = 0;
#ifdef VBR_LANES
		if (lanes_on()) {
			v2d r[4] = {r0, r1, r2, qab};
			done = ls_lanes(C, t, n, tmin, sc, m, r, &bb);
			r0 = r[0], r1 = r[1], r2 = r[2], qab = r[3];
		}
#endif
		for (uint32_t i = done; i < n; i++) {
			const uint8_t *x = rgb + 3 * (size_t)i;
			int q = (int)((t[i] - tmin) * sc + 0.5);
			const struct lsw *e = lw + (q > m ? m : q);
			r0 += e->s * (double)x[0];
			r1 += e->s * (double)x[1];
			r2 += e->s * (double)x[2];
			qab += e->q;
			bb += e->bb;
		}
		double aa = qab[0], ab = qab[1];
		double ra[3] = {r0[0], r1[0], r2[0]}, rb[3] = {r0[1], r1[1], r2[1]};
		double det = aa * bb - ab * ab;
		if (fabs(det) > 1e-9)
			for (int k = 0; k < 3; k++) {
				l0[k] = (bb * ra[k] - ab * rb[k]) / det;
				l1[k] = (aa * rb[k] - ab * ra[k]) / det;
			}
	}
}

/* The fit of rgb[0..n) whose moments are `m`; `t` is scratch for n
 * doubles. `hint` (n for none) is a colour likely to fail the check
 * (check_endpoints), which changes only the time. */
static int fit_m(const struct cols *C, uint32_t n, unsigned limit,
		 int weight_bits, const struct mom *mo, double *t,
		 uint16_t *c0, uint16_t *c1, uint8_t *w, uint64_t *sse,
		 uint32_t hint)
{
	const uint8_t *rgb = C->rgb;
	if (n == 0) {
		*c0 = *c1 = 0;
		*sse = 0;
		return 1;
	}
	double mu[3], cov[6];
	for (int k = 0; k < 3; k++)
		mu[k] = (double)mo->s[k] / n;
	static const int ix[6][2] = {{0, 0}, {0, 1}, {0, 2},
				     {1, 1}, {1, 2}, {2, 2}};
	/* n q - s s' is exact in 64 bits (n <= 2^20, s <= 2^28, q <= 2^36) */
	int64_t num[6];
	for (int k = 0; k < 6; k++) {
		num[k] = (int64_t)(n * mo->q[k]) -
			 (int64_t)(mo->s[ix[k][0]] * mo->s[ix[k][1]]);
		cov[k] = (double)num[k] / n;
	}
	uint64_t s;
	uint16_t a, b;
	if (num[0] + num[3] + num[5] == 0) {
		/* one colour: the endpoints and weight nearest it */
		uint8_t wv;
		if (!fit_flat(rgb, limit, weight_bits, &a, &b, &wv, &s))
			return 0;
		if (w)
			memset(w, wv, n);
		*c0 = a;
		*c1 = b;
		*sse = s * n;
		return 1;
	}
	if (fit_bound_rejects(cov, n, limit))
		return 0;
	double ax[3] = {0, 0, 0};
	fit_axis(cov, ax);
	double tmin, tmax;
	fit_project(C, n, mu, ax, t, &tmin, &tmax);
	double e0[3], e1[3], l0[3], l1[3];
	for (int k = 0; k < 3; k++) {
		l0[k] = e0[k] = mu[k] + tmin * ax[k];
		l1[k] = e1[k] = mu[k] + tmax * ax[k];
	}
	fit_least_squares(C, t, n, tmin, tmax, weight_bits, l0, l1);
	/* the least-squares endpoints first; the extremes of the axis when
	 * RGB565 rounding pushed a colour outside */
	a = to565(l0);
	b = to565(l1);
	if (check_endpoints(C, n, limit, weight_bits, a, b, w, &s, &hint)) {
		*c0 = a;
		*c1 = b;
		*sse = s;
		return 1;
	}
	uint16_t a2 = to565(e0), b2 = to565(e1);
	if ((a2 != a || b2 != b) &&
	    check_endpoints(C, n, limit, weight_bits, a2, b2, w, &s, &hint)) {
		*c0 = a2;
		*c1 = b2;
		*sse = s;
		return 1;
	}
	/* last, the first colour's nearest RGB565 for all: the rule the
	 * first sweep grows its single-colour runs by, so every run it finds
	 * is a block this fit accepts */
	double f[3] = {rgb[0], rgb[1], rgb[2]};
	a = to565(f);
	if (check_endpoints(C, n, limit, weight_bits, a, a, w, &s, &hint)) {
		*c0 = *c1 = a;
		*sse = s;
		return 1;
	}
	return 0;
}

int vd_vbr_fit(const uint8_t *rgb, uint32_t n, unsigned limit,
	       int weight_bits, uint16_t *c0, uint16_t *c1, uint8_t *w,
	       uint64_t *sse)
{
	struct mom m;
	mom_of(&m, rgb, n);
	double *t = malloc(((size_t)n + 1) * sizeof *t);
	uint8_t *pl = malloc(COLS_BYTES(n));
	int ok = 0;
	if (t && pl) {
		struct cols C;
		cols_split(&C, rgb, pl, n);
		vbr_init();
		ok = fit_m(&C, n, limit, weight_bits, &m, t, c0, c1, w, sse, n);
	}
	free(t);
	free(pl);
	return ok;
}

/* Algorithm 1 over one segment. Blocks form a doubly linked list indexed
 * by their first voxel; `stuck[b]` caches "block b cannot merge with its
 * right neighbour", valid until either of the two changes (the paper's
 * "which blocks were modified in the last pass"). A possible merge needs
 * no cache: of a block's two possible merges the one not taken involves
 * the block itself, which the taken one changed. */
struct blocks {
	uint32_t *next, *prev, *end;
	uint8_t *stuck;
	struct mom *mom;   /* moments of the block starting there */
	double *t;         /* scratch of the fit */
};

#define NIL UINT32_MAX

/* MSE of the merged block [s, e) (blocks at s and l2 = the right part's
 * head) or -1 when a colour would fall outside. */
static double eval(const struct cols *C, const struct blocks *B, uint32_t s,
		   uint32_t l2, unsigned limit, int wb)
{
	uint16_t a, b;
	uint64_t sse;
	struct mom m = B->mom[s];
	mom_add(&m, &B->mom[l2]);
	uint32_t n = B->end[l2] - s;
	/* a colour outside is likelier in the smaller part: the fit leans
	 * to the larger */
	uint32_t k = l2 - s;
	struct cols Cs = cols_at(C, s);
	if (!fit_m(&Cs, n, limit, wb, &m, B->t, &a, &b, NULL, &sse,
		   n - k < k ? k : 0)) {
		return -1;
	}
	return (double)sse / n;
}

/* The first sweep: greedy runs that one colour (the nearest RGB565 of
 * the run's first colour) stores within the threshold; every other
 * colour its own block (all of them so with no_single). Links the blocks
 * and sets their ends and moments. */
static void first_sweep(struct blocks *B, const uint8_t *rgb, uint32_t n,
			unsigned limit, int no_single)
{
	uint32_t last = NIL;
	for (uint32_t i = 0; i < n;) {
		uint32_t j = i + 1;
		if (!no_single) {
			double c[3] = {rgb[3 * (size_t)i], rgb[3 * (size_t)i + 1],
				       rgb[3 * (size_t)i + 2]};
			uint8_t d[3];
			vd_rgb565_decode(to565(c), d);
			if (vd_rgb_dist2(rgb + 3 * (size_t)i, d) <= limit)
				while (j < n &&
				       vd_rgb_dist2(rgb + 3 * (size_t)j, d) <= limit)
					j++;
		}
		B->prev[i] = last;
		if (last != NIL)
			B->next[last] = i;
		B->end[i] = j;
		mom_of(&B->mom[i], rgb + 3 * (size_t)i, j - i);
		last = i;
		i = j;
	}
	if (last != NIL)
		B->next[last] = NIL;
}

/* The merge passes (Algorithm 1): every second block merges with the
 * neighbour giving the lower MSE when the merged fit keeps every colour
 * within the limit, until a pass merges nothing; counts the passes in
 * seg->passes. */
static void merge_passes(struct vd_vbr_segment *seg, struct blocks *B,
			 const struct cols *C, uint32_t head, unsigned limit,
			 int wb)
{
	int merged;
	do {
		merged = 0;
		seg->passes++;
		uint32_t b = head == NIL ? NIL : B->next[head];
		while (b != NIL) {
			uint32_t l = B->prev[b], r = B->next[b];
			double lm = -1, rm = -1;
			if (l != NIL && !B->stuck[l]) {
				lm = eval(C, B, l, b, limit, wb);
				if (lm < 0)
					B->stuck[l] = 1;
			}
			if (r != NIL && !B->stuck[b]) {
				rm = eval(C, B, b, r, limit, wb);
				if (rm < 0)
					B->stuck[b] = 1;
			}
			uint32_t m = b;
			if (lm >= 0 && (rm < 0 || lm <= rm)) {
				/* b joins its left neighbour */
				B->end[l] = B->end[b];
				mom_add(&B->mom[l], &B->mom[b]);
				B->next[l] = r;
				if (r != NIL)
					B->prev[r] = l;
				m = l;
				merged = 1;
			} else if (rm >= 0) {
				B->end[b] = B->end[r];
				mom_add(&B->mom[b], &B->mom[r]);
				uint32_t rr = B->next[r];
				B->next[b] = rr;
				if (rr != NIL)
					B->prev[rr] = b;
				B->stuck[b] = B->stuck[r] = 0;
				merged = 1;
			}
			if (m != b || rm >= 0) {
				B->stuck[m] = 0;
				if (B->prev[m] != NIL)
					B->stuck[B->prev[m]] = 0;
			}
			uint32_t nx = B->next[m];
			b = nx == NIL ? NIL : B->next[nx];
		}
	} while (merged);
}

/* The final blocks: fit again for their endpoints and weights, into
 * seg's arrays (allocated here) and its packed weights; sums the error
 * and keeps the largest distance. w is scratch for the longest block. */
static int final_blocks(struct vd_vbr_segment *seg, const struct blocks *B,
			const struct cols *C, const uint8_t *rgb,
			uint32_t head, unsigned limit, int wb, uint8_t *w,
			double max_error)
{
	uint32_t count = 0;
	for (uint32_t b = head; b != NIL; b = B->next[b])
		count++;
	seg->count = count;
	seg->start = malloc(((size_t)count + 1) * sizeof *seg->start);
	seg->c0 = malloc(((size_t)count + 1) * sizeof *seg->c0);
	seg->c1 = malloc(((size_t)count + 1) * sizeof *seg->c1);
	if (!seg->start || !seg->c0 || !seg->c1)
		return vd_fail(VD_ERR_NOMEM, "vbr: %u blocks", count);
	uint32_t k = 0;
	for (uint32_t b = head; b != NIL; b = B->next[b], k++) {
		uint64_t sse;
		uint32_t len = B->end[b] - b;
		struct cols Cb = cols_at(C, b);
		if (!fit_m(&Cb, len, limit, wb, &B->mom[b], B->t, &seg->c0[k],
			   &seg->c1[k], w, &sse, len)) {
			/* only a first block of one colour can get here: merges
			 * were all checked */
			return vd_fail(VD_ERR_RANGE, "max error %g is too small for "
				       "RGB565 endpoints: colour (%u, %u, %u) cannot "
				       "be stored within it (0.0236 always works)",
				       max_error, rgb[3 * (size_t)b],
				       rgb[3 * (size_t)b + 1], rgb[3 * (size_t)b + 2]);
		}
		seg->start[k] = b;
		seg->sse += sse;
		for (uint32_t i = 0; i < len; i++) {
			uint64_t bit = (uint64_t)(b + i) * wb;
			unsigned v = w[i];
			/* weights are at most 8 bits: two bytes at most */
			seg->weights[bit >> 3] |= (uint8_t)(v << (bit & 7));
			if ((bit & 7) + wb > 8)
				seg->weights[(bit >> 3) + 1] |=
					(uint8_t)(v >> (8 - (bit & 7)));
			uint8_t d[3];
			vd_vbr_interp(seg->c0[k], seg->c1[k], v, wb, d);
			unsigned e = vd_rgb_dist2(rgb + 3 * ((size_t)b + i), d);
			if (e > seg->max_dist2)
				seg->max_dist2 = e;
		}
	}
	return VD_OK;
}

/* The steps run once a segment (the time is in eval's fits), so the
 * split costs nothing per block. */
int vd_vbr_encode(struct vd_vbr_segment *seg, const uint8_t *rgb, uint32_t n,
		  const struct vd_vbr_params *p)
{
	memset(seg, 0, sizeof *seg);
	if (p->weight_bits < 1 || p->weight_bits > 8 || n > VD_CPACK_SEGMENT_MAX ||
	    !(p->max_error > 0) || !(p->max_error <= 2))
		return vd_fail(VD_ERR_ARG, "vbr: weight bits %d, max error %g, "
			       "%u colours", p->weight_bits, p->max_error, n);
	int wb = p->weight_bits;
	vbr_init();
	unsigned limit = vd_colour_error_limit(p->max_error);
	seg->n = n;
	seg->weight_bits = wb;
	struct blocks B = {0};
	B.next = malloc(((size_t)n + 1) * sizeof *B.next);
	B.prev = malloc(((size_t)n + 1) * sizeof *B.prev);
	B.end = malloc(((size_t)n + 1) * sizeof *B.end);
	B.stuck = calloc((size_t)n + 1, 1);
	B.mom = malloc(((size_t)n + 1) * sizeof *B.mom);
	B.t = malloc(((size_t)n + 1) * sizeof *B.t);
	seg->weights = calloc(((size_t)n * wb + 7) / 8 + 1, 1);
	uint8_t *w = malloc((size_t)n + 1);
	uint8_t *pl = malloc(COLS_BYTES(n));
	int err = VD_OK;
	if (!B.next || !B.prev || !B.end || !B.stuck || !B.mom || !B.t ||
	    !seg->weights || !w || !pl) {
		err = vd_fail(VD_ERR_NOMEM, "vbr: blocks of %u colours", n);
		goto out;
	}
	struct cols C;
	cols_split(&C, rgb, pl, n);
	uint32_t head = n ? 0 : NIL;
	first_sweep(&B, rgb, n, limit, p->no_single_sweep);
	merge_passes(seg, &B, &C, head, limit, wb);
	err = final_blocks(seg, &B, &C, rgb, head, limit, wb, w, p->max_error);
out:
	free(B.next);
	free(B.prev);
	free(B.end);
	free(B.stuck);
	free(B.mom);
	free(B.t);
	free(w);
	free(pl);
	if (err)
		vd_vbr_segment_release(seg);
	return err;
}

void vd_vbr_segment_colour(const struct vd_vbr_segment *s, uint32_t i,
			   uint8_t rgb[3])
{
	uint32_t lo = 0, hi = s->count; /* last block with start <= i */
	while (hi - lo > 1) {
		uint32_t mid = lo + (hi - lo) / 2;
		if (s->start[mid] <= i)
			lo = mid;
		else
			hi = mid;
	}
	uint64_t bit = (uint64_t)i * s->weight_bits;
	unsigned v = s->weights[bit >> 3] >> (bit & 7);
	if ((bit & 7) + s->weight_bits > 8)
		v |= (unsigned)s->weights[(bit >> 3) + 1] << (8 - (bit & 7));
	v &= (1u << s->weight_bits) - 1;
	vd_vbr_interp(s->c0[lo], s->c1[lo], v, s->weight_bits, rgb);
}

void vd_vbr_segment_release(struct vd_vbr_segment *s)
{
	free(s->start);
	free(s->c0);
	free(s->c1);
	free(s->weights);
	memset(s, 0, sizeof *s);
}
