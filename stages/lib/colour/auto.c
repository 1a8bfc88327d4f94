/* The auto colour method (schemas/colour-formats.md, method 4): the colour
 * array cut into blocks of 2^block_log voxels, each block stored in the
 * mode of fewest bytes that keeps every colour within the error limit.
 * Blocks have a fixed length so that a voxel's block is its index shifted
 * (no search over block headers, unlike VBR's variable blocks), and each
 * block decodes alone, so an edit can re-encode one block, or write a
 * constant block for a uniform fill, without touching its neighbours.
 *
 * Every candidate is checked voxel by voxel with the decoder's own rule
 * (vd_auto_decode), so the guarantee does not rest on the fitting's
 * arithmetic: a mode either keeps every colour within the limit or is not
 * taken; raw always is. */
#include "voxdag.h"
#include "colour/colour_internal.h"

#include <math.h>
#include <stdint.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif
#include <stdlib.h>
#include <string.h>

#define MAX_BLOCK (1u << 12)
#define HASH_SLOTS 1024 /* > 2 x 256 distinct colours: short probes */

static unsigned width_of(uint32_t colours)
{
	unsigned w = 0;
	while ((1u << w) < colours)
		w++;
	return w;
}

static uint32_t packed_rgb(const uint8_t *c)
{
	return (uint32_t)c[0] | (uint32_t)c[1] << 8 | (uint32_t)c[2] << 16;
}

/* LSB-first bit writer over a zeroed buffer. */
static void put_bits(uint8_t *b, uint64_t pos, unsigned width, uint32_t v)
{
	uint8_t *p = b + (pos >> 3);
	uint64_t x = (uint64_t)(v & (uint32_t)((1ull << width) - 1)) << (pos & 7);
	for (; x; x >>= 8)
		*p++ |= (uint8_t)x;
}


/* ------------------------------------------------ the coded mode (1.2) */

/* Canonical codes (DEFLATE's rule: by length, then symbol) of the
 * lengths len[0..n), each code's bits reversed for the LSB-first stream;
 * 0 when the lengths over-fill the code space. */
static int canonical(const uint8_t *len, unsigned n, uint16_t *code)
{
	unsigned count[VD_AUTO_MAXLEN + 1] = {0}, next[VD_AUTO_MAXLEN + 2];
	for (unsigned i = 0; i < n; i++)
		count[len[i]]++;
	count[0] = 0;
	unsigned c = 0;
	uint32_t room = 1u << VD_AUTO_MAXLEN, used = 0;
	for (unsigned l = 1; l <= VD_AUTO_MAXLEN; l++) {
		c = (c + count[l - 1]) << 1;
		next[l] = c;
		used += count[l] << (VD_AUTO_MAXLEN - l);
	}
	if (used > room)
		return 0;
	for (unsigned i = 0; i < n; i++) {
		unsigned l = len[i];
		if (!l)
			continue;
		unsigned v = next[l]++, r = 0;
		for (unsigned b = 0; b < l; b++)
			r |= (v >> b & 1) << (l - 1 - b);
		code[i] = (uint16_t)r;
	}
	return 1;
}

/* Each alphabet's first symbol in the table: A in its contexts, B, C. */
static const unsigned alpha_first[VD_AUTO_ALPHABETS + 1] = {
	0, VD_AUTO_SYM_A, 2 * VD_AUTO_SYM_A, VD_AUTO_SYM_B, VD_AUTO_SYM_B + 256,
	VD_AUTO_SYMS};

int vd_auto_code_build(struct vd_auto_code *c, const uint8_t *tab)
{
	const unsigned *first = alpha_first;
	uint8_t len[VD_AUTO_SYMS];
	uint16_t code[VD_AUTO_SYMS];
	if ((VD_AUTO_SYMS & 1) && tab[VD_AUTO_SYMS / 2] >> 4)
		return -1; /* the unused last nibble */
	for (unsigned i = 0; i < VD_AUTO_SYMS; i++) {
		len[i] = (uint8_t)(tab[i >> 1] >> (4 * (i & 1)) & 15);
		if (len[i] > VD_AUTO_MAXLEN)
			return -1;
	}
	memset(c, 0, sizeof *c);
	for (int a = 0; a < VD_AUTO_ALPHABETS; a++) {
		unsigned n = first[a + 1] - first[a];
		if (!canonical(len + first[a], n, code + first[a]))
			return -1;
		for (unsigned i = 0; i < n; i++) {
			unsigned l = len[first[a] + i];
			if (!l)
				continue;
			for (unsigned x = code[first[a] + i]; x < (1u << VD_AUTO_MAXLEN);
			     x += 1u << l)
				c->t[a][x] = (uint16_t)(i << 4 | l);
		}
	}
	return 0;
}

/* The symbols (global numbers: A in context x at x VD_AUTO_SYM_A.., B at
 * VD_AUTO_SYM_B.., C at VD_AUTO_SYM_B + 256..) of
 * voxels 1..n-1 of a block, the list of recent colours kept as the
 * decoder keeps it; a run of L repeats is the longest run symbols that
 * fit, greedily. Returns how many. */
static uint32_t coded_symbols(const uint8_t *rgb, uint32_t n, uint16_t *sym)
{
	/* the list as a ring, as the decoder keeps it (position a at
	 * ring[(h + a) & 15]; a delta inserts in O(1)); the slots not in
	 * the list hold a key no colour has, and the list's colours are
	 * distinct, so a colour matches at most one slot */
	uint32_t ring[VD_AUTO_RECENT], nr = 1, h = 0, m = 0;
	for (int a = 0; a < VD_AUTO_RECENT; a++)
		ring[a] = UINT32_MAX;
	unsigned ctx = 2 * VD_AUTO_SYM_A; /* A's context, as a symbol offset */
	ring[0] = packed_rgb(rgb);
	for (uint32_t i = 1; i < n;) {
		const uint8_t *x = rgb + 3 * i, *p = x - 3;
		uint32_t key = packed_rgb(x);
		if (key == ring[h]) {
			uint32_t len = 1;
			while (i + len < n && packed_rgb(x + 3 * len) == key)
				len++;
			i += len;
			while (len) {
				int r = VD_AUTO_RUNS - 1;
				while (vd_auto_run[r] > len)
					r--;
				sym[m++] = (uint16_t)(ctx + r);
				len -= vd_auto_run[r];
				ctx = 0;
			}
			continue;
		}
		int slot = -1;
#ifdef __SSE2__
		__m128i kv = _mm_set1_epi32((int)key);
		unsigned hit = (unsigned)_mm_movemask_ps(_mm_castsi128_ps(
				       _mm_cmpeq_epi32(kv, _mm_loadu_si128((const __m128i *)ring)))) |
			       (unsigned)_mm_movemask_ps(_mm_castsi128_ps(
				       _mm_cmpeq_epi32(kv, _mm_loadu_si128((const __m128i *)(ring + 4))))) << 4 |
			       (unsigned)_mm_movemask_ps(_mm_castsi128_ps(
				       _mm_cmpeq_epi32(kv, _mm_loadu_si128((const __m128i *)(ring + 8))))) << 8 |
			       (unsigned)_mm_movemask_ps(_mm_castsi128_ps(
				       _mm_cmpeq_epi32(kv, _mm_loadu_si128((const __m128i *)(ring + 12))))) << 12;
		if (hit)
			slot = __builtin_ctz(hit);
#else
		for (int a = 0; a < VD_AUTO_RECENT; a++)
			if (ring[a] == key)
				slot = a;
#endif
		if (slot >= 0) {
			uint32_t a = ((uint32_t)slot - h) & (VD_AUTO_RECENT - 1);
			sym[m++] = (uint16_t)(ctx + VD_AUTO_HIT0 - 1 + a);
			ctx = VD_AUTO_SYM_A;
			for (; a; a--)
				ring[(h + a) & (VD_AUTO_RECENT - 1)] =
					ring[(h + a - 1) & (VD_AUTO_RECENT - 1)];
			ring[h] = key;
		} else {
			unsigned d0 = (x[1] - p[1]) & 255;
			unsigned d1 = ((x[0] - x[1]) - (p[0] - p[1])) & 255;
			unsigned d2 = ((x[2] - x[1]) - (p[2] - p[1])) & 255;
			sym[m++] = (uint16_t)(ctx + VD_AUTO_DELTA0 + d0);
			sym[m++] = (uint16_t)(VD_AUTO_SYM_B + d1);
			sym[m++] = (uint16_t)(VD_AUTO_SYM_B + 256 + d2);
			ctx = 2 * VD_AUTO_SYM_A;
			nr += nr < VD_AUTO_RECENT;
			h = (h - 1) & (VD_AUTO_RECENT - 1);
			ring[h] = key; /* over the last colour when the list is full */
		}
		i++;
	}
	(void)nr;
	return m;
}

/* Huffman code lengths of at most VD_AUTO_MAXLEN bits for freq[0..n)
 * (0: symbol unused): the plain Huffman lengths, the counts halved (kept
 * >= 1) until none is longer. One used symbol gets length 1. */
static void huffman_lengths(const uint32_t *freq, unsigned n, uint8_t *len)
{
	uint32_t f[VD_AUTO_SYM_A];
	for (unsigned i = 0; i < n; i++)
		f[i] = freq[i];
	memset(len, 0, n);
	for (;;) {
		/* nodes: leaves 0..n-1, internal n..; two-queue merge over
		 * leaves sorted by count */
		unsigned idx[VD_AUTO_SYM_A], m = 0;
		for (unsigned i = 0; i < n; i++)
			if (f[i])
				idx[m++] = i;
		if (m == 0)
			return;
		if (m == 1) {
			len[idx[0]] = 1;
			return;
		}
		for (unsigned i = 1; i < m; i++) /* insertion sort, stable */
			for (unsigned j = i; j && f[idx[j - 1]] > f[idx[j]]; j--) {
				unsigned t = idx[j];
				idx[j] = idx[j - 1];
				idx[j - 1] = t;
			}
		uint64_t w[2 * VD_AUTO_SYM_A];
		unsigned parent[2 * VD_AUTO_SYM_A];
		for (unsigned i = 0; i < m; i++)
			w[i] = f[idx[i]];
		unsigned lq = 0, iq = m, in = m;
		for (unsigned k = 0; k + 1 < m; k++) {
			unsigned pick[2];
			for (int t = 0; t < 2; t++)
				pick[t] = (lq < m && (iq == in || w[lq] <= w[iq]))
						  ? lq++ : iq++;
			w[in] = w[pick[0]] + w[pick[1]];
			parent[pick[0]] = parent[pick[1]] = in++;
		}
		unsigned depth[2 * VD_AUTO_SYM_A], maxd = 0;
		depth[in - 1] = 0;
		for (unsigned x = in - 1; x-- > 0;)
			depth[x] = depth[parent[x]] + 1;
		for (unsigned i = 0; i < m; i++)
			maxd = depth[i] > maxd ? depth[i] : maxd;
		if (maxd <= VD_AUTO_MAXLEN) {
			for (unsigned i = 0; i < m; i++)
				len[idx[i]] = (uint8_t)depth[i];
			return;
		}
		for (unsigned i = 0; i < n; i++)
			if (f[i])
				f[i] = (f[i] >> 1) | 1;
	}
}

/* A segment's code: lengths, encoder codes, the bytes of its table. */
struct seg_code {
	uint32_t freq[VD_AUTO_SYMS];
	uint8_t len[VD_AUTO_SYMS];
	uint16_t code[VD_AUTO_SYMS];
	uint8_t table[VD_AUTO_TABLE_BYTES];
	struct vd_auto_code dec;
	/* every block's symbols, from the pass that counts them, so that
	 * try_coded does not derive them again: block b's at
	 * sym[first[b] .. first[b + 1]) (none for a block of one colour) */
	uint16_t *sym;
	uint32_t *first;
};

static void seg_code_make(struct seg_code *sc)
{
	const unsigned *first = alpha_first;
	for (int a = 0; a < VD_AUTO_ALPHABETS; a++) {
		huffman_lengths(sc->freq + first[a], first[a + 1] - first[a],
				sc->len + first[a]);
		canonical(sc->len + first[a], first[a + 1] - first[a],
			  sc->code + first[a]);
	}
	memset(sc->table, 0, sizeof sc->table);
	for (unsigned i = 0; i < VD_AUTO_SYMS; i++)
		sc->table[i >> 1] |= (uint8_t)(sc->len[i] << (4 * (i & 1)));
	vd_auto_code_build(&sc->dec, sc->table);
}

/* One block's analysis, shared by the modes. */
struct blk {
	const uint8_t *rgb;
	uint32_t n;
	unsigned limit;
	unsigned lo[3], hi[3];
	uint32_t ndist;              /* distinct colours; > 256: many */
	uint32_t dist[256], cnt[256];
	uint16_t id[MAX_BLOCK];      /* voxel -> distinct colour */
	/* the hash of distinct colours, cleared by generation */
	uint32_t key[HASH_SLOTS], gen[HASH_SLOTS], val[HASH_SLOTS], g;
	/* candidates: the cheapest so far in best[], the next in try[] */
	uint8_t bufa[3 * MAX_BLOCK + 1024 + VD_AUTO_PAD];
	uint8_t bufb[3 * MAX_BLOCK + 1024 + VD_AUTO_PAD];
	uint8_t *best, *cand;
	size_t best_bytes;
	uint32_t best_entry;         /* mode << 24 (| colour if constant) */
	uint64_t best_sse;
	unsigned best_max;
	float t[MAX_BLOCK];
	uint8_t w[MAX_BLOCK];        /* the endpoints mode's weights */
	struct seg_code *code;       /* the segment's code, NULL: no coded mode */
	int checked;                 /* verify every candidate (check_best) */
	uint32_t b;                  /* the block's number in its segment */
	size_t plain_bytes;          /* the best without the coded mode */
	uint8_t all[3 * MAX_BLOCK];
};

static void analyse(struct blk *k)
{
	const uint8_t *rgb = k->rgb;
	for (int c = 0; c < 3; c++) {
		k->lo[c] = 255;
		k->hi[c] = 0;
	}
	k->g++;
	k->ndist = 0;
	for (uint32_t i = 0; i < k->n; i++) {
		const uint8_t *x = rgb + 3 * i;
		for (int c = 0; c < 3; c++) {
			if (x[c] < k->lo[c])
				k->lo[c] = x[c];
			if (x[c] > k->hi[c])
				k->hi[c] = x[c];
		}
		if (k->ndist > 256)
			continue;
		uint32_t key = (uint32_t)x[0] | (uint32_t)x[1] << 8 |
			       (uint32_t)x[2] << 16;
		uint32_t h = (key * 2654435761u) >> 22;
		while (k->gen[h] == k->g && k->key[h] != key)
			h = (h + 1) & (HASH_SLOTS - 1);
		if (k->gen[h] != k->g) {
			if (k->ndist == 256) {
				k->ndist = 257;
				continue;
			}
			k->gen[h] = k->g;
			k->key[h] = key;
			k->val[h] = k->ndist;
			k->dist[k->ndist] = key;
			k->cnt[k->ndist++] = 0;
		}
		k->id[i] = (uint16_t)k->val[h];
		k->cnt[k->val[h]]++;
	}
}

/* Adopts the candidate in k->cand if it is cheaper than the best. */
static void offer(struct blk *k, uint32_t entry, size_t bytes, uint64_t sse,
		  unsigned maxd)
{
	if (bytes >= k->best_bytes)
		return;
	uint8_t *t = k->best;
	k->best = k->cand;
	k->cand = t;
	k->best_bytes = bytes;
	k->best_entry = entry;
	k->best_sse = sse;
	k->best_max = maxd;
}

/* Every voxel of the candidate (entry, cand) within the limit; sets *sse
 * and *maxd. */
static int verify(const struct blk *k, uint32_t entry, const uint8_t *d,
		  uint64_t *sse, unsigned *maxd)
{
	uint64_t s = 0;
	unsigned m = 0;
	for (uint32_t i = 0; i < k->n; i++) {
		uint8_t o[3];
		vd_auto_decode(entry, d, k->n, i, o);
		unsigned e = vd_rgb_dist2(o, k->rgb + 3 * i);
		if (e > k->limit)
			return 0;
		s += e;
		if (e > m)
			m = e;
	}
	*sse = s;
	*maxd = m;
	return 1;
}

static uint32_t packed(const uint8_t c[3])
{
	return (uint32_t)c[0] | (uint32_t)c[1] << 8 | (uint32_t)c[2] << 16;
}

/* Constant: one distinct colour, or (lossy) the mean, else the centre of
 * the box, when every colour is within the limit of it. */
static void try_const(struct blk *k)
{
	uint64_t sse;
	unsigned maxd;
	if (k->ndist == 1) {
		offer(k, VD_AUTO_CONST << 24 | k->dist[0], 0, 0, 0);
		return;
	}
	if (!k->limit)
		return;
	/* the box's half-diagonal bounds what any colour can reach: when
	 * even the best centre is too far, skip the pass over the voxels */
	unsigned r2 = 0;
	for (int c = 0; c < 3; c++) {
		unsigned h = (k->hi[c] - k->lo[c]) / 2;
		r2 += h * h;
	}
	if (r2 > k->limit)
		return;
	uint64_t sum[3] = {0, 0, 0};
	for (uint32_t i = 0; i < k->n; i++)
		for (int c = 0; c < 3; c++)
			sum[c] += k->rgb[3 * i + c];
	uint8_t m[3], ctr[3];
	for (int c = 0; c < 3; c++) {
		m[c] = (uint8_t)((sum[c] + k->n / 2) / k->n);
		ctr[c] = (uint8_t)((k->lo[c] + k->hi[c] + 1) / 2);
	}
	uint32_t e = VD_AUTO_CONST << 24 | packed(m);
	if (verify(k, e, NULL, &sse, &maxd)) {
		offer(k, e, 0, sse, maxd);
		return;
	}
	e = VD_AUTO_CONST << 24 | packed(ctr);
	if (verify(k, e, NULL, &sse, &maxd))
		offer(k, e, 0, sse, maxd);
}

static void unpack(uint32_t p, uint8_t c[3])
{
	c[0] = (uint8_t)p;
	c[1] = (uint8_t)(p >> 8);
	c[2] = (uint8_t)(p >> 16);
}

/* Local palette: lossless, the block's distinct colours; lossy, leaders
 * (each distinct colour joins the nearest leader within the limit or
 * becomes one), each moved to its members' weighted mean when all of
 * them stay within the limit (lower GMSE at the same bytes). */
static void try_palette(struct blk *k)
{
	if (k->ndist < 2 || k->ndist > 256)
		return;
	uint8_t *d = k->cand;
	uint32_t lead[256], of[256];
	uint32_t np = 0;
	if (!k->limit) {
		for (uint32_t i = 0; i < k->ndist; i++)
			lead[i] = k->dist[i], of[i] = i;
		np = k->ndist;
	} else {
		/* the leaders also sorted by r + g + b: a leader within the
		 * limit of a colour has a sum within R = sqrt(3 limit) of the
		 * colour's (Cauchy-Schwarz), so only that window is searched;
		 * the nearest (the first on a tie) is the same leader as over
		 * all of them whenever one is within the limit */
		int lr[256], lg[256], lb[256];
		unsigned sk[256], R = (unsigned)sqrt(3.0 * k->limit);
		uint8_t sq[256];
		while ((R + 1) * (R + 1) <= 3 * k->limit)
			R++;
		while (R * R > 3 * k->limit)
			R--;
		for (uint32_t i = 0; i < k->ndist; i++) {
			int r = k->dist[i] & 255, g = k->dist[i] >> 8 & 255,
			    b = (int)(k->dist[i] >> 16);
			unsigned key = (unsigned)(r + g + b);
			/* the first key >= key - R, by a search without
			 * branches on the keys (they mispredicted half the time) */
			uint32_t lo = 0;
			if (np) {
				for (uint32_t m = np; m > 1;) {
					uint32_t half = m / 2;
					lo = sk[lo + half] + R < key ? lo + half : lo;
					m -= half;
				}
				lo += sk[lo] + R < key;
			}
			int best = INT32_MAX;
			uint32_t bi = UINT32_MAX;
			for (uint32_t at = lo; at < np && sk[at] <= key + R; at++) {
				uint32_t q = sq[at];
				int e = (r - lr[q]) * (r - lr[q]) +
					(g - lg[q]) * (g - lg[q]) +
					(b - lb[q]) * (b - lb[q]);
				if (e < best || (e == best && q < bi))
					best = e, bi = q;
			}
			if (best <= (int)k->limit) {
				of[i] = bi;
				continue;
			}
			size_t need = 1 + 3 * (size_t)(np + 1) +
				      ((size_t)k->n * width_of(np + 1) + 7) / 8;
			if (need >= k->best_bytes)
				return;
			uint32_t at = lo;
			while (at < np && sk[at] < key)
				at++;
			memmove(sk + at + 1, sk + at, (np - at) * sizeof sk[0]);
			memmove(sq + at + 1, sq + at, np - at);
			sk[at] = key;
			sq[at] = (uint8_t)np;
			of[i] = np;
			lr[np] = r, lg[np] = g, lb[np] = b;
			lead[np++] = k->dist[i];
		}
		if (np < 2)
			return; /* one leader: the constant mode's case */
		uint64_t sum[256][3], wt[256];
		memset(sum, 0, np * sizeof sum[0]);
		memset(wt, 0, np * sizeof wt[0]);
		for (uint32_t i = 0; i < k->ndist; i++) {
			uint8_t a[3];
			unpack(k->dist[i], a);
			for (int c = 0; c < 3; c++)
				sum[of[i]][c] += (uint64_t)a[c] * k->cnt[i];
			wt[of[i]] += k->cnt[i];
		}
		uint8_t mean[256][3];
		uint8_t ok[256];
		for (uint32_t q = 0; q < np; q++) {
			for (int c = 0; c < 3; c++)
				mean[q][c] = (uint8_t)((sum[q][c] + wt[q] / 2) / wt[q]);
			ok[q] = 1;
		}
		for (uint32_t i = 0; i < k->ndist; i++) {
			uint8_t a[3];
			unpack(k->dist[i], a);
			if (vd_rgb_dist2(a, mean[of[i]]) > k->limit)
				ok[of[i]] = 0;
		}
		for (uint32_t q = 0; q < np; q++)
			if (ok[q])
				lead[q] = packed(mean[q]);
	}
	unsigned b = width_of(np);
	size_t bytes = 1 + 3 * (size_t)np + ((size_t)k->n * b + 7) / 8;
	if (bytes >= k->best_bytes)
		return;
	memset(d, 0, bytes + VD_AUTO_PAD);
	d[0] = (uint8_t)(np - 1);
	for (uint32_t q = 0; q < np; q++)
		unpack(lead[q], d + 1 + 3 * q);
	uint8_t *idx = d + 1 + 3 * np;
	for (uint32_t i = 0; i < k->n; i++)
		put_bits(idx, (uint64_t)i * b, b, of[k->id[i]]);
	uint32_t e = (uint32_t)(VD_AUTO_PALETTE | b) << 24;
	uint64_t sse = 0;
	unsigned maxd = 0;
	if (!k->checked || verify(k, e, d, &sse, &maxd))
		offer(k, e, bytes, sse, maxd);
}

/* A run of voxels' bounds and moments: try_endpoints sums them over its
 * smallest parts once and merges them for the larger ones, instead of a
 * pass over the voxels a part and a part size. */
struct moments {
	unsigned lo[3], hi[3];
	long sum[3];
	long sxx[3][3]; /* sum of x_c x_d */
	uint32_t n;
};

static void moments_of(const uint8_t *rgb, uint32_t n, struct moments *m)
{
	unsigned lo[3] = {255, 255, 255}, hi[3] = {0, 0, 0};
	uint32_t sum[3] = {0, 0, 0}, s00 = 0, s01 = 0, s02 = 0, s11 = 0,
		 s12 = 0, s22 = 0; /* n <= 2^12: below 2^32 */
	for (uint32_t i = 0; i < n; i++) {
		uint32_t r = rgb[3 * i], g = rgb[3 * i + 1], b = rgb[3 * i + 2];
		lo[0] = r < lo[0] ? r : lo[0];
		lo[1] = g < lo[1] ? g : lo[1];
		lo[2] = b < lo[2] ? b : lo[2];
		hi[0] = r > hi[0] ? r : hi[0];
		hi[1] = g > hi[1] ? g : hi[1];
		hi[2] = b > hi[2] ? b : hi[2];
		sum[0] += r, sum[1] += g, sum[2] += b;
		s00 += r * r, s01 += r * g, s02 += r * b;
		s11 += g * g, s12 += g * b, s22 += b * b;
	}
	for (int c = 0; c < 3; c++) {
		m->lo[c] = lo[c];
		m->hi[c] = hi[c];
		m->sum[c] = sum[c];
	}
	m->sxx[0][0] = s00, m->sxx[1][1] = s11, m->sxx[2][2] = s22;
	m->sxx[0][1] = m->sxx[1][0] = s01;
	m->sxx[0][2] = m->sxx[2][0] = s02;
	m->sxx[1][2] = m->sxx[2][1] = s12;
	m->n = n;
}

static void moments_merge(struct moments *m, const struct moments *a)
{
	for (int c = 0; c < 3; c++) {
		m->lo[c] = a->lo[c] < m->lo[c] ? a->lo[c] : m->lo[c];
		m->hi[c] = a->hi[c] > m->hi[c] ? a->hi[c] : m->hi[c];
		m->sum[c] += a->sum[c];
		for (int d = 0; d < 3; d++)
			m->sxx[c][d] += a->sxx[c][d];
	}
	m->n += a->n;
}

/* The line through one part's colours (moments m): endpoints the part's
 * colours at the two ends of its principal direction (the widest channel,
 * the others signed by their covariance with it), t[i] each colour's
 * projection on the segment between them, in [0, 1]. Returns 0, leaving
 * t unfinished, when a colour lies farther than thr (squared) from the
 * line through the ends: no weights fit that part (try_endpoints). */
static int fit_line(const uint8_t *rgb, const struct moments *mo,
		    uint8_t c0[3], uint8_t c1[3], float *t, float thr)
{
	uint32_t n = mo->n;
	const unsigned *lo = mo->lo, *hi = mo->hi;
	const long *sum = mo->sum;
	int p = 0;
	for (int c = 1; c < 3; c++)
		if (hi[c] - lo[c] > hi[p] - lo[p])
			p = c;
	/* n times the scatter matrix, exactly (below 2^41 for n <= 2^12):
	 * the sum over the voxels of (n x_c - S_c)(n x_d - S_d), the
	 * covariance whose sign orients the direction, is n of it */
	long nc[3][3];
	for (int c = 0; c < 3; c++)
		for (int d = 0; d < 3; d++)
			nc[c][d] = (long)n * mo->sxx[c][d] - sum[c] * sum[d];
	/* no line lies nearer the colours, in the mean of the squared
	 * distances, than the principal axis, whose mean is (trace -
	 * lambda1) / n of the scatter matrix, and lambda1 is at most its
	 * Frobenius norm; the largest distance is at least the mean. So
	 * when that bound is above thr (with a margin far beyond the float
	 * arithmetic of the distances below, < 0.1), the voxel pass would
	 * find a colour farther than thr: skipped. */
	double tr = (double)(nc[0][0] + nc[1][1] + nc[2][2]), fr = 0;
	for (int c = 0; c < 3; c++)
		for (int d = 0; d < 3; d++)
			fr += (double)nc[c][d] * (double)nc[c][d];
	if ((tr - sqrt(fr)) * (1 - 1e-9) > ((double)thr + 1) * n * n)
		return 0;
	int dir[3];
	for (int c = 0; c < 3; c++)
		dir[c] = (nc[p][c] < 0 ? -1 : 1) * (int)(hi[c] - lo[c]);
	/* the products below stay under 2^18: int arithmetic, exactly */
	int d0 = dir[0], d1 = dir[1], d2 = dir[2];
	int tmin = d0 * rgb[0] + d1 * rgb[1] + d2 * rgb[2], tmax = tmin;
	uint32_t imin = 0, imax = 0;
	for (uint32_t i = 1; i < n; i++) {
		const uint8_t *x = rgb + 3 * i;
		int v = d0 * x[0] + d1 * x[1] + d2 * x[2];
		if (v < tmin)
			tmin = v, imin = i;
		if (v > tmax)
			tmax = v, imax = i;
	}
	memcpy(c0, rgb + 3 * imin, 3);
	memcpy(c1, rgb + 3 * imax, 3);
	int D0 = c1[0] - c0[0], D1 = c1[1] - c0[1], D2 = c1[2] - c0[2];
	int L = D0 * D0 + D1 * D1 + D2 * D2;
	float inv = L ? 1.0f / (float)L : 0;
	for (uint32_t i = 0; i < n; i++) {
		const uint8_t *y = rgb + 3 * i;
		int x0 = y[0] - c0[0], x1 = y[1] - c0[1], x2 = y[2] - c0[2];
		int v = x0 * D0 + x1 * D1 + x2 * D2;
		int r2 = x0 * x0 + x1 * x1 + x2 * x2;
		float x = (float)v * inv;
		float p2 = (float)r2 - (float)v * x;
		if (p2 > thr)
			return 0;
		t[i] = x < 0 ? 0 : x > 1 ? 1 : x;
	}
	return 1;
}

static int endpoints_parts(struct blk *k, int s, uint32_t parts, int esz,
			   uint8_t e[64][6], unsigned wlo);

/* Endpoints and W-bit weights, the VBR idea with 8-bit endpoints: the
 * block cut into parts of 2^s voxels (s from block_log down by up to 3,
 * so a block that holds two or more gradients still fits, as VBR's
 * variable blocks would), each part two endpoints (fit_line), every voxel
 * the weight whose decoded colour is nearest of the two around its
 * projection; the fewest bytes over parts and weight bits that keep every
 * colour within the limit. */
static void try_endpoints(struct blk *k, int block_log)
{
	if (k->ndist < 2)
		return;
	const uint8_t *rgb = k->rgb;
	uint32_t n = k->n;
	int sf = block_log - 3 > 4 ? block_log - 3 : 4; /* the smallest parts */
	if (sf > block_log)
		sf = block_log;
	uint32_t nch = (n + (1u << sf) - 1) >> sf;
	struct moments ch[8];
	int have = 0;
	for (int s = block_log; s >= block_log - 3 && s >= 4; s--) {
		uint32_t len = 1u << s, parts = (n + len - 1) >> s;
		if (1 + 4 * (size_t)parts + (n + 7) / 8 >= k->best_bytes)
			return; /* more parts only cost more */
		uint8_t e[64][6];
		if (!have) {
			for (uint32_t q = 0; q < nch; q++)
				moments_of(rgb + 3 * ((size_t)q << sf),
					   q + 1 < nch ? 1u << sf : n - (q << sf), &ch[q]);
			have = 1;
		}
		/* a colour farther from the line through its part's ends
		 * than the limit fits no weights on it (RGB565 endpoints
		 * move the line a little: a heuristic there, and every
		 * candidate is verified anyway); the first such colour ends
		 * the try of these parts */
		uint32_t q = 0;
		for (; q < parts; q++) {
			uint32_t c = q << (s - sf), ce = (q + 1) << (s - sf);
			struct moments mo = ch[c];
			for (c++; c < ce && c < nch; c++)
				moments_merge(&mo, &ch[c]);
			if (!fit_line(rgb + 3 * (size_t)q * len, &mo, e[q], e[q] + 3,
				      k->t + q * len, (float)k->limit + 0.5f))
				break;
		}
		if (q < parts)
			continue;
		unsigned wlo = 1;
		/* RGB565 endpoints first (4 bytes a part, as VBR stores them),
		 * then RGB8 */
		for (int esz = 4; esz <= 6; esz += 2)
			if (endpoints_parts(k, s, parts, esz, e, wlo))
				break;
	}
}

/* The weight of colour v (projection t) between decoded endpoints c0, c1
 * with m = 2^w - 1 (r = vd_auto_recip[w]): of the two around t, the one
 * whose decoded colour (the decoder's arithmetic) is nearest, the first
 * on a tie; its squared distance in *err. */
static inline unsigned endpoint_weight(const uint8_t *c0, const uint8_t *c1,
				       unsigned m, uint64_t r, float t,
				       const uint8_t *v, unsigned *err)
{
	unsigned x = (unsigned)(t * (float)m), er = ~0u, xb = x;
	for (unsigned y = x ? x - 1 : 0; y <= x + 1 && y <= m; y++) {
		uint8_t o[3];
		for (int c = 0; c < 3; c++)
			o[c] = (uint8_t)(((uint64_t)(c0[c] * (m - y) + c1[c] * y +
						     m / 2) * r) >> 32);
		unsigned e1 = vd_rgb_dist2(o, v);
		if (e1 < er)
			er = e1, xb = y;
	}
	*err = er;
	return xb;
}

/* Endpoints mode of `parts` parts of 2^s voxels with the fitted endpoints
 * e (RGB8), stored in esz = 4 (RGB565, nearest) or 6 bytes: the fewest
 * weight bits that keep every colour within the limit, offered. Returns 1
 * when one was found. */
static int endpoints_parts(struct blk *k, int s, uint32_t parts, int esz,
			   uint8_t e[64][6], unsigned wlo)
{
	const uint8_t *rgb = k->rgb;
	uint32_t n = k->n, len = 1u << s;
	uint8_t ed[64][6]; /* the endpoints as decoded */
	uint16_t e565[64][2];
	for (uint32_t q = 0; q < parts; q++) {
		if (esz == 6) {
			memcpy(ed[q], e[q], 6);
			continue;
		}
		for (int h = 0; h < 2; h++) {
			const uint8_t *c = e[q] + 3 * h;
			e565[q][h] = (uint16_t)(((c[0] * 31 + 127) / 255) << 11 |
						((c[1] * 63 + 127) / 255) << 5 |
						((c[2] * 31 + 127) / 255));
			vd_rgb565_decode(e565[q][h], ed[q] + 3 * h);
		}
	}
	/* the voxels that failed a weight width: tried first at the next,
	 * where they mostly fail again, before a pass over the block */
	uint32_t fails[4], nf = 0;
	for (unsigned w = wlo; w <= 8; w++) {
		size_t bytes = 1 + (size_t)esz * parts + ((size_t)n * w + 7) / 8;
		if (bytes >= k->best_bytes)
			return 0;
		unsigned m = (1u << w) - 1, er;
		uint64_t r = vd_auto_recip[w];
		uint32_t f = 0;
		while (f < nf) {
			uint32_t i = fails[f], q = i >> s;
			endpoint_weight(ed[q], ed[q] + 3, m, r, k->t[i], rgb + 3 * i, &er);
			if (er > k->limit)
				break;
			f++;
		}
		if (f < nf)
			continue;
		uint32_t i = 0;
		for (uint32_t q = 0; q < parts && i == q * len; q++) {
			/* the decoded colours tabled when the part has at least
			 * as many voxels as levels, else decoded on demand */
			const uint8_t *c0 = ed[q], *c1 = ed[q] + 3;
			uint32_t end = q + 1 < parts ? (q + 1) * len : n;
			if (m + 1 > end - i) {
				for (; i < end; i++) {
					k->w[i] = (uint8_t)endpoint_weight(c0, c1, m, r, k->t[i],
									  rgb + 3 * i, &er);
					if (er > k->limit)
						break;
				}
				continue;
			}
			uint8_t lv[256][4];
			for (unsigned y = 0; y <= m; y++)
				for (int c = 0; c < 3; c++)
					lv[y][c] = (uint8_t)(((uint64_t)(c0[c] * (m - y) + c1[c] * y +
									 m / 2) * r) >> 32);
			for (; i < end; i++) {
				const uint8_t *v = rgb + 3 * i;
				unsigned x = (unsigned)(k->t[i] * (float)m), xb = x;
				er = ~0u;
				for (unsigned y = x ? x - 1 : 0; y <= x + 1 && y <= m; y++) {
					unsigned e1 = vd_rgb_dist2(lv[y], v);
					if (e1 < er)
						er = e1, xb = y;
				}
				k->w[i] = (uint8_t)xb;
				if (er > k->limit)
					break;
			}
		}
		if (i < n) {
			fails[nf < 4 ? nf++ : 3] = i;
			continue;
		}
		uint8_t *d = k->cand;
		memset(d, 0, bytes + VD_AUTO_PAD);
		d[0] = (uint8_t)(s | (esz == 4 ? 16 : 0));
		for (uint32_t q = 0; q < parts; q++) {
			if (esz == 6) {
				memcpy(d + 1 + 6 * q, ed[q], 6);
				continue;
			}
			for (int h = 0; h < 2; h++) {
				d[1 + 4 * q + 2 * h] = (uint8_t)e565[q][h];
				d[2 + 4 * q + 2 * h] = (uint8_t)(e565[q][h] >> 8);
			}
		}
		uint8_t *wb = d + 1 + esz * parts;
		for (i = 0; i < n; i++)
			put_bits(wb, (uint64_t)i * w, w, k->w[i]);
		uint32_t en = (uint32_t)(VD_AUTO_ENDPOINTS | w) << 24;
		uint64_t sse = 0;
		unsigned maxd = 0;
		if (!k->checked || verify(k, en, d, &sse, &maxd)) {
			offer(k, en, bytes, sse, maxd);
			return 1;
		}
	}
	return 0;
}

/* Per-channel offsets from the block's minimum in steps of s, each channel
 * as many bits as its range needs: s odd and 3 ((s - 1) / 2)^2 <= limit,
 * so the rounding keeps every colour within it (s = 1: lossless). */
static void try_quant(struct blk *k)
{
	unsigned s = 1;
	if (k->limit) {
		unsigned h = (unsigned)sqrt(k->limit / 3.0);
		while (3 * (h + 1) * (h + 1) <= k->limit)
			h++;
		while (h && 3 * h * h > k->limit)
			h--;
		s = 2 * h + 1;
		if (s > 255)
			s = 255;
	}
	unsigned half = s / 2, wd[3], wsum = 0;
	uint8_t q[3][256];
	for (int c = 0; c < 3; c++) {
		unsigned range = k->hi[c] - k->lo[c];
		for (unsigned o = 0; o <= range; o++)
			q[c][o] = (uint8_t)((o + half) / s);
		wd[c] = width_of(q[c][range] + 1u);
		wsum += wd[c];
	}
	size_t bytes = 6 + ((size_t)k->n * wsum + 7) / 8;
	if (bytes >= k->best_bytes)
		return;
	uint8_t *d = k->cand;
	memset(d, 0, bytes + VD_AUTO_PAD);
	for (int c = 0; c < 3; c++)
		d[c] = (uint8_t)k->lo[c];
	d[3] = (uint8_t)s;
	d[4] = (uint8_t)(wd[0] | wd[1] << 4);
	d[5] = (uint8_t)wd[2];
	for (uint32_t i = 0; i < k->n; i++) {
		const uint8_t *x = k->rgb + 3 * i;
		uint32_t v = q[0][x[0] - k->lo[0]] |
			     (uint32_t)q[1][x[1] - k->lo[1]] << wd[0] |
			     (uint32_t)q[2][x[2] - k->lo[2]] << (wd[0] + wd[1]);
		put_bits(d + 6, (uint64_t)i * wsum, wsum, v);
	}
	uint32_t e = (uint32_t)VD_AUTO_QUANT << 24;
	uint64_t sse = 0;
	unsigned maxd = 0;
	if (!k->checked || verify(k, e, d, &sse, &maxd))
		offer(k, e, bytes, sse, maxd);
}

/* Coded (lossless, with the segment's code): the block's symbols, priced
 * by the code's lengths; a symbol the code lacks rules the mode out. */
static void try_coded(struct blk *k)
{
	struct seg_code *sc = k->code;
	if (!sc || k->n < 2 || k->limit)
		return;
	const uint16_t *sym = sc->sym + sc->first[k->b];
	uint32_t m = sc->first[k->b + 1] - sc->first[k->b];
	uint64_t bits = 0;
	for (uint32_t i = 0; i < m; i++) {
		unsigned l = sc->len[sym[i]];
		if (!l)
			return;
		bits += l;
	}
	size_t bytes = 5 + (size_t)((bits + 7) / 8);
	if (bytes >= k->best_bytes || bytes - 5 > 65535)
		return;
	uint8_t *d = k->cand;
	memset(d, 0, bytes + VD_AUTO_PAD);
	d[0] = (uint8_t)(bytes - 5);
	d[1] = (uint8_t)((bytes - 5) >> 8);
	memcpy(d + 2, k->rgb, 3);
	uint64_t pos = 0;
	for (uint32_t i = 0; i < m; i++) {
		unsigned l = sc->len[sym[i]];
		put_bits(d + 5, pos, l, sc->code[sym[i]]);
		pos += l;
	}
	uint8_t last[3];
	if (vd_auto_coded_decode(&sc->dec, d, k->n - 1, last, k->all) !=
		    (int64_t)bits ||
	    memcmp(k->all, k->rgb, 3 * (size_t)k->n))
		return; /* cannot happen: the decoder is the rule */
	offer(k, (uint32_t)VD_AUTO_CODED << 24, bytes, 0, 0);
}

/* The palette, endpoints and quantised candidates keep every colour
 * within the limit by construction (each voxel's index, weight or step is
 * chosen with the decoder's arithmetic), so only the one kept is decoded
 * and checked, which also gives its errors; were it ever off, the block is
 * encoded again with every candidate checked (k->checked), as the
 * constant mode's always is. Returns 1 when the best passed. */
static int check_best(struct blk *k)
{
	uint32_t e = k->best_entry;
	unsigned m = e >> 28;
	if (k->checked || m == VD_AUTO_CONST >> 4 || m == VD_AUTO_RAW >> 4)
		return 1;
	vd_auto_decode_all(e, k->best, k->n, k->all);
	uint64_t sse = 0;
	unsigned maxd = 0;
	for (uint32_t i = 0; i < k->n; i++) {
		unsigned d = vd_rgb_dist2(k->all + 3 * i, k->rgb + 3 * i);
		if (d > k->limit)
			return 0;
		sse += d;
		maxd = d > maxd ? d : maxd;
	}
	k->best_sse = sse;
	k->best_max = maxd;
	return 1;
}

static void encode_block(struct blk *k, int block_log)
{
	/* raw is the fallback every other mode must beat */
	k->best_bytes = 3 * (size_t)k->n;
	memcpy(k->best, k->rgb, k->best_bytes);
	k->best_entry = (uint32_t)VD_AUTO_RAW << 24;
	k->best_sse = 0;
	k->best_max = 0;
	k->best_bytes++; /* so that a mode as large as raw is not taken */
	analyse(k);
	/* the cheap modes first: the palette's leader search stops as soon
	 * as it cannot beat them; but a block of a few colours tries the
	 * palette first, so that it wins a tie (its colours are exact) */
	try_const(k);
	if (k->ndist <= 16)
		try_palette(k);
	try_endpoints(k, block_log);
	try_quant(k);
	if (k->ndist > 16)
		try_palette(k);
	if (!check_best(k)) {
		k->checked = 1;
		encode_block(k, block_log);
		k->checked = 0;
		return;
	}
	k->plain_bytes = k->best_bytes -
			 (k->best_entry >> 24 == VD_AUTO_RAW ? 1 : 0);
	try_coded(k);
	if (k->best_entry >> 24 == VD_AUTO_RAW)
		k->best_bytes--;
}

/* The blocks of s (n voxels of rgb, blocks of 2^bl) after `head` bytes
 * of the data; returns what the coded blocks saved against the best
 * other mode. */
static size_t encode_blocks(struct vd_auto_segment *s, struct blk *k,
			    const uint8_t *rgb, uint32_t n, int bl, size_t head)
{
	uint32_t bs = 1u << bl, nb = s->count;
	size_t at = head, saved = 0;
	s->sse = 0;
	s->max_dist2 = 0;
	memset(s->mode_blocks, 0, sizeof s->mode_blocks);
	for (uint32_t b = 0; b < nb; b++) {
		k->b = b;
		k->rgb = rgb + 3 * (size_t)b * bs;
		k->n = b + 1 < nb ? bs : n - b * bs;
		/* a block of one colour is the constant block whatever the
		 * limit (no mode beats 0 bytes): found without the analysis,
		 * as flat areas and edits' fills are most blocks */
		uint32_t same = 1;
		while (same < k->n && !memcmp(k->rgb + 3 * same, k->rgb, 3))
			same++;
		if (same == k->n) {
			uint32_t e = VD_AUTO_CONST << 24 | packed(k->rgb);
			s->dir[b] = e;
			s->mode_blocks[0]++;
			continue;
		}
		encode_block(k, bl);
		uint32_t e = k->best_entry;
		if (e >> 24 == VD_AUTO_CODED)
			saved += k->plain_bytes - k->best_bytes;
		if (e >> 24 != VD_AUTO_CONST) {
			e |= (uint32_t)at;
			memcpy(s->data + at, k->best, k->best_bytes);
			at += k->best_bytes;
		}
		s->dir[b] = e;
		s->sse += k->best_sse;
		if (k->best_max > s->max_dist2)
			s->max_dist2 = k->best_max;
		s->mode_blocks[e >> 28]++;
	}
	s->data_bytes = at;
	return saved;
}

/* Coded segments (format 1.2): the code is fitted to the symbols of every
 * block of more than one colour (a constant block stays constant), and
 * kept only when the blocks it codes save more than its table costs;
 * else the segment is encoded again without it (u16 0, no table). */
int vd_auto_encode(struct vd_auto_segment *s, const uint8_t *rgb, uint32_t n,
		   const struct vd_auto_params *p)
{
	memset(s, 0, sizeof *s);
	int bl = p->block_log ? p->block_log : 8;
	if (bl < 4 || bl > 12 || n == 0 || n > VD_CPACK_SEGMENT_MAX ||
	    !(p->max_error >= 0) || (p->coded && p->max_error != 0))
		return vd_fail(VD_ERR_ARG, "auto colour blocks of 2^%d, %u "
			       "colours, max error %g%s", bl, n, p->max_error,
			       p->coded ? ", coded" : "");
	uint32_t bs = 1u << bl;
	uint32_t nb = (n + bs - 1) >> bl;
	size_t head = p->coded ? 2 + VD_AUTO_TABLE_BYTES : 0;
	struct blk *k = malloc(sizeof *k);
	struct seg_code *sc = p->coded ? calloc(1, sizeof *sc) : NULL;
	if (sc) {
		sc->sym = malloc(3 * (size_t)n * sizeof *sc->sym);
		sc->first = malloc(((size_t)nb + 1) * sizeof *sc->first);
	}
	s->dir = malloc((size_t)nb * 4);
	s->data = malloc(head + 3 * (size_t)n + VD_AUTO_PAD);
	if (!k || !s->dir || !s->data ||
	    (p->coded && (!sc || !sc->sym || !sc->first))) {
		free(k);
		if (sc) {
			free(sc->sym);
			free(sc->first);
		}
		free(sc);
		vd_auto_segment_release(s);
		return vd_fail(VD_ERR_NOMEM, "auto colour segment of %u", n);
	}
	memset(k->gen, 0, sizeof k->gen);
	k->g = 0;
	k->best = k->bufa;
	k->cand = k->bufb;
	k->limit = vd_colour_error_limit(p->max_error);
	k->code = NULL;
	k->checked = 0;
	s->n = n;
	s->count = nb;
	if (sc) {
		uint32_t at = 0;
		for (uint32_t b = 0; b < nb; b++) {
			const uint8_t *x = rgb + 3 * (size_t)b * bs;
			uint32_t m = b + 1 < nb ? bs : n - b * bs, i = 1;
			sc->first[b] = at;
			while (i < m && !memcmp(x + 3 * i, x, 3))
				i++;
			if (i == m)
				continue;
			uint32_t c = coded_symbols(x, m, sc->sym + at);
			for (uint32_t q = 0; q < c; q++)
				sc->freq[sc->sym[at + q]]++;
			at += c;
		}
		sc->first[nb] = at;
		seg_code_make(sc);
		k->code = sc;
		if (encode_blocks(s, k, rgb, n, bl, head) > VD_AUTO_TABLE_BYTES) {
			s->table_bytes = VD_AUTO_TABLE_BYTES;
			memcpy(s->data + 2, sc->table, VD_AUTO_TABLE_BYTES);
		} else {
			k->code = NULL;
			head = 2;
			encode_blocks(s, k, rgb, n, bl, head);
		}
		s->data[0] = (uint8_t)s->table_bytes;
		s->data[1] = (uint8_t)(s->table_bytes >> 8);
	} else {
		encode_blocks(s, k, rgb, n, bl, 0);
	}
	memset(s->data + s->data_bytes, 0, VD_AUTO_PAD);
	if (sc) {
		free(sc->sym);
		free(sc->first);
	}
	free(sc);
	free(k);
	return VD_OK;
}

void vd_auto_segment_colour(const struct vd_auto_segment *s, int block_log,
			    uint32_t j, uint8_t rgb[3])
{
	int bl = block_log ? block_log : 8;
	uint32_t e = s->dir[j >> bl], first = j >> bl << bl;
	uint32_t n = s->n - first < (1u << bl) ? s->n - first : 1u << bl;
	if (e >> 24 == VD_AUTO_CODED) {
		/* the tables are built on every call: a check, not a reader */
		struct vd_auto_code *c = malloc(sizeof *c);
		if (c && !vd_auto_code_build(c, s->data + 2))
			vd_auto_coded_decode(c, s->data + (e & 0xffffff),
					     j - first, rgb, NULL);
		else
			memset(rgb, 0, 3);
		free(c);
		return;
	}
	vd_auto_decode(e, s->data + (e & 0xffffff), n, j - first, rgb);
}

void vd_auto_block_decode(uint32_t entry, const uint8_t *data, uint32_t n,
			  uint8_t *rgb)
{
	const uint8_t *d = data + (entry & 0xffffff);
	for (uint32_t k = 0; k < n; k++)
		vd_auto_decode(entry, d, n, k, rgb + 3 * k);
}

void vd_auto_segment_release(struct vd_auto_segment *s)
{
	free(s->dir);
	free(s->data);
	memset(s, 0, sizeof *s);
}
