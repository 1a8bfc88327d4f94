/* The palette baseline the colour paper compares against (Dado et al.
 * 2016): colours quantised to a global palette, the array cut into blocks,
 * each block a small palette of global indices (shared by every block with
 * the same set) and a per-voxel offset of the smallest width into it.
 * This file builds the global palette (median cut + Lloyd) and one
 * segment's blocks; colour_pack.c shares the block palettes and writes. */
#include "voxdag.h"
#include "colour/colour_internal.h"

#include <stdlib.h>
#include <string.h>

#define NCOL (1u << 24)

int vd_colour_hist_init(struct vd_colour_hist *h)
{
	memset(h, 0, sizeof *h);
	h->count = calloc(NCOL, sizeof *h->count);
	if (!h->count)
		return vd_fail(VD_ERR_NOMEM, "colour histogram (64 MiB)");
	return VD_OK;
}

void vd_colour_hist_add(struct vd_colour_hist *h, const uint8_t *rgb,
			uint64_t n)
{
	for (uint64_t i = 0; i < n; i++) {
		const uint8_t *x = rgb + 3 * i;
		uint32_t c = (uint32_t)x[0] << 16 | (uint32_t)x[1] << 8 | x[2];
		if (h->count[c] == 0)
			h->distinct++;
		if (h->count[c] != UINT32_MAX)
			h->count[c]++;
	}
	h->voxels += n;
}

void vd_colour_hist_release(struct vd_colour_hist *h)
{
	free(h->count);
	memset(h, 0, sizeof *h);
}

/* --------------------------------------------- nearest-colour search grid
 * Exact nearest search over the palette (least squared distance, ties to
 * the lower index, as vd_palette_nearest): the RGB cube cut into g^3 cells
 * of side 256/g, the palette's entries listed per cell, and the cells
 * visited in shells of growing Chebyshev distance around the query's own
 * cell. A colour in a cell r shells out differs from the query by at least
 * (r-1) s + 1 in one channel, so the search stops at the first shell whose
 * bound exceeds the best distance found (strictly: an equal distance may
 * still be a lower index). It replaced a k-d tree whose searches took 90%
 * of colorize's time at 16K colours. */
struct grid {
	int shift, g;          /* cell of channel v: v >> shift; g = 256 >> shift */
	uint32_t *first;       /* g^3 + 1 offsets into idx */
	uint32_t *idx;         /* palette indices, by cell, ascending within */
	const uint8_t *rgb;
};

static uint32_t grid_cell(const struct grid *t, const uint8_t *x)
{
	int sh = t->shift, g = t->g;
	return ((uint32_t)(x[0] >> sh) * (uint32_t)g + (uint32_t)(x[1] >> sh)) *
		       (uint32_t)g + (uint32_t)(x[2] >> sh);
}

static int grid_init(struct grid *t, const uint8_t *rgb, uint32_t n)
{
	/* about one palette colour per cell or fewer: g^3 >= n */
	int lg = 0;
	while (lg < 8 && (1ull << (3 * lg)) < n)
		lg++;
	t->g = 1 << lg;
	t->shift = 8 - lg;
	t->rgb = rgb;
	size_t cells = (size_t)t->g * t->g * t->g;
	t->first = calloc(cells + 1, sizeof *t->first);
	t->idx = malloc(((size_t)n + 1) * sizeof *t->idx);
	if (!t->first || !t->idx) {
		free(t->first);
		free(t->idx);
		return vd_fail(VD_ERR_NOMEM, "palette search grid");
	}
	for (uint32_t i = 0; i < n; i++)
		t->first[grid_cell(t, rgb + 3 * (size_t)i) + 1]++;
	for (size_t c = 0; c < cells; c++)
		t->first[c + 1] += t->first[c];
	for (uint32_t i = 0; i < n; i++) {
		uint32_t c = grid_cell(t, rgb + 3 * (size_t)i);
		/* first[c] runs ahead while filling, restored below */
		t->idx[t->first[c]++] = i;
	}
	for (size_t c = cells; c > 0; c--)
		t->first[c] = t->first[c - 1];
	t->first[0] = 0;
	return VD_OK;
}

static void grid_scan(const struct grid *t, int cx, int cy, int cz,
		      const uint8_t *x, unsigned *best, uint32_t *bi)
{
	int g = t->g;
	if (cx < 0 || cy < 0 || cz < 0 || cx >= g || cy >= g || cz >= g)
		return;
	size_t c = ((size_t)cx * g + (size_t)cy) * g + (size_t)cz;
	for (uint32_t j = t->first[c]; j < t->first[c + 1]; j++) {
		uint32_t p = t->idx[j];
		unsigned d = vd_rgb_dist2(x, t->rgb + 3 * (size_t)p);
		if (d < *best || (d == *best && p < *bi)) {
			*best = d;
			*bi = p;
		}
	}
}

static uint32_t grid_nearest(const struct grid *t, const uint8_t *x)
{
	unsigned best = UINT32_MAX;
	uint32_t bi = UINT32_MAX;
	int sh = t->shift, s = 1 << sh, g = t->g;
	int cx = x[0] >> sh, cy = x[1] >> sh, cz = x[2] >> sh;
	for (int r = 0; r < g; r++) {
		if (r > 0) {
			unsigned lb = (unsigned)((r - 1) * s + 1);
			if (lb * lb > best)
				break;
		}
		for (int dx = -r; dx <= r; dx++)
			for (int dy = -r; dy <= r; dy++) {
				if (dx == -r || dx == r || dy == -r || dy == r)
					for (int dz = -r; dz <= r; dz++)
						grid_scan(t, cx + dx, cy + dy, cz + dz,
							  x, &best, &bi);
				else {
					grid_scan(t, cx + dx, cy + dy, cz - r, x,
						  &best, &bi);
					if (r)
						grid_scan(t, cx + dx, cy + dy, cz + r,
							  x, &best, &bi);
				}
			}
	}
	return bi;
}

static void grid_free(struct grid *t)
{
	free(t->first);
	free(t->idx);
}

/* ------------------------------------------------------------ median cut */
struct entry {
	uint32_t c;      /* 24-bit colour */
	uint32_t w;      /* count */
};

struct box {
	uint32_t lo, hi;  /* entries [lo, hi) */
	double sse;       /* weighted squared error about the mean */
	int axis;
};

static int sort_axis;

static int cmp_entry(const void *a, const void *b)
{
	const struct entry *x = a, *y = b;
	int sh = 16 - 8 * sort_axis;
	int d = (int)(x->c >> sh & 255) - (int)(y->c >> sh & 255);
	return d ? d : (x->c > y->c) - (x->c < y->c);
}

static void box_measure(struct box *b, const struct entry *e)
{
	double s[3] = {0, 0, 0}, q[3] = {0, 0, 0}, w = 0;
	for (uint32_t i = b->lo; i < b->hi; i++)
		for (int k = 0; k < 3; k++) {
			double v = e[i].c >> (16 - 8 * k) & 255;
			s[k] += v * e[i].w;
			q[k] += v * v * e[i].w;
			if (k == 0)
				w += e[i].w;
		}
	b->sse = 0;
	b->axis = 0;
	double bestv = -1;
	for (int k = 0; k < 3; k++) {
		double v = q[k] - s[k] * s[k] / w;
		b->sse += v;
		if (v > bestv) {
			bestv = v;
			b->axis = k;
		}
	}
	if (b->hi - b->lo < 2)
		b->sse = -1; /* cannot split */
}

int vd_palette_build(struct vd_palette *p, struct vd_colour_hist *h,
		     uint32_t k, int lossless, int threads)
{
	memset(p, 0, sizeof *p);
	if (k < 2 || k > NCOL)
		return vd_fail(VD_ERR_ARG, "palette of %u colours (2..2^24)", k);
	uint64_t d = h->distinct;
	if (d == 0)
		return vd_fail(VD_ERR_EMPTY, "no colours for a palette");
	struct entry *e = malloc(d * sizeof *e);
	if (!e)
		return vd_fail(VD_ERR_NOMEM, "palette: %llu colours",
			       (unsigned long long)d);
	uint64_t n = 0;
	for (uint32_t c = 0; c < NCOL; c++)
		if (h->count[c])
			e[n++] = (struct entry){c, h->count[c]};
	int err = VD_OK;
	if (lossless || d <= k) {
		/* exact: every distinct colour, in colour order */
		p->lossless = 1;
		p->k = (uint32_t)d;
		p->rgb = malloc(3 * d);
		if (!p->rgb) {
			free(e);
			return vd_fail(VD_ERR_NOMEM, "palette of %llu colours",
				       (unsigned long long)d);
		}
		for (uint64_t i = 0; i < d; i++) {
			p->rgb[3 * i] = (uint8_t)(e[i].c >> 16);
			p->rgb[3 * i + 1] = (uint8_t)(e[i].c >> 8);
			p->rgb[3 * i + 2] = (uint8_t)e[i].c;
			h->count[e[i].c] = (uint32_t)i;
		}
		p->index = h->count;
		h->count = NULL;
		free(e);
		return VD_OK;
	}
	/* median cut: repeatedly split the box of largest squared error at
	 * the weighted median of its widest axis */
	struct box *bx = malloc((size_t)k * sizeof *bx);
	p->rgb = malloc(3 * (size_t)k);
	double *acc = calloc((size_t)k * 4, sizeof *acc);
	if (!bx || !p->rgb || !acc) {
		err = vd_fail(VD_ERR_NOMEM, "palette of %u colours", k);
		goto out;
	}
	uint32_t nb = 1;
	bx[0] = (struct box){0, (uint32_t)d, 0, 0};
	box_measure(&bx[0], e);
	while (nb < k) {
		uint32_t bi = 0;
		for (uint32_t i = 1; i < nb; i++)
			if (bx[i].sse > bx[bi].sse)
				bi = i;
		if (bx[bi].sse <= 0)
			break;
		struct box *b = &bx[bi];
		sort_axis = b->axis;
		qsort(e + b->lo, b->hi - b->lo, sizeof *e, cmp_entry);
		uint64_t tot = 0, run = 0;
		for (uint32_t i = b->lo; i < b->hi; i++)
			tot += e[i].w;
		uint32_t cut = b->lo + 1;
		for (uint32_t i = b->lo; i < b->hi - 1; i++) {
			run += e[i].w;
			cut = i + 1;
			if (2 * run >= tot)
				break;
		}
		bx[nb] = (struct box){cut, b->hi, 0, 0};
		b->hi = cut;
		box_measure(b, e);
		box_measure(&bx[nb], e);
		nb++;
	}
	/* the palette: each box's weighted mean, then Lloyd iterations over
	 * the distinct colours (weighted by their counts) */
	for (uint32_t i = 0; i < nb; i++) {
		double s[3] = {0, 0, 0}, w = 0;
		for (uint32_t j = bx[i].lo; j < bx[i].hi; j++) {
			for (int c = 0; c < 3; c++)
				s[c] += (double)(e[j].c >> (16 - 8 * c) & 255) * e[j].w;
			w += e[j].w;
		}
		for (int c = 0; c < 3; c++)
			p->rgb[3 * i + c] = (uint8_t)(s[c] / w + 0.5);
	}
	p->k = nb;
	for (int it = 0; it < 4; it++) {
		struct grid t;
		if ((err = grid_init(&t, p->rgb, p->k)))
			goto out;
		memset(acc, 0, (size_t)k * 4 * sizeof *acc);
		for (uint64_t i = 0; i < d; i++) {
			uint8_t x[3] = {(uint8_t)(e[i].c >> 16),
					(uint8_t)(e[i].c >> 8), (uint8_t)e[i].c};
			uint32_t q = grid_nearest(&t, x);
			for (int c = 0; c < 3; c++)
				acc[4 * q + c] += (double)x[c] * e[i].w;
			acc[4 * q + 3] += e[i].w;
		}
		grid_free(&t);
		for (uint32_t i = 0; i < p->k; i++)
			if (acc[4 * i + 3] > 0)
				for (int c = 0; c < 3; c++)
					p->rgb[3 * i + c] = (uint8_t)(
						acc[4 * i + c] / acc[4 * i + 3] + 0.5);
	}
	/* the map of every colour seen to its nearest palette colour */
	{
		struct grid t;
		if ((err = grid_init(&t, p->rgb, p->k)))
			goto out;
		for (uint64_t i = 0; i < d; i++) {
			uint8_t x[3] = {(uint8_t)(e[i].c >> 16),
					(uint8_t)(e[i].c >> 8), (uint8_t)e[i].c};
			h->count[e[i].c] = grid_nearest(&t, x);
		}
		grid_free(&t);
	}
	p->index = h->count;
	h->count = NULL;
out:
	(void)threads;
	free(e);
	free(bx);
	free(acc);
	if (err)
		vd_palette_release(p);
	return err;
}

uint32_t vd_palette_nearest(const struct vd_palette *p, const uint8_t rgb[3])
{
	unsigned best = UINT32_MAX;
	uint32_t bi = 0;
	for (uint32_t i = 0; i < p->k; i++) {
		unsigned d = vd_rgb_dist2(rgb, p->rgb + 3 * (size_t)i);
		if (d < best) {
			best = d;
			bi = i;
		}
	}
	return bi;
}

void vd_palette_release(struct vd_palette *p)
{
	free(p->rgb);
	free(p->index);
	memset(p, 0, sizeof *p);
}

/* ---------------------------------------------------------------- blocks
 * Dado et al. choose blocks so that their palettes stay small; we take the
 * first block that minimises its cost per voxel: header (96 bits) + its
 * palette (64 bits + one entry per colour) + n * ceil(log2 colours) bits,
 * scanning on while a longer block may still be cheaper per voxel (it
 * cannot be once the offset width alone exceeds the best cost) and at most
 * LOOKAHEAD voxels past the best end. */
#define LOOKAHEAD 1024
#define HEADER_BITS 96
#define PAL_BITS 64

static unsigned width_of(uint32_t colours)
{
	unsigned w = 0;
	while ((1ull << w) < colours)
		w++;
	return w;
}

/* Sorts v[0..n) ascending (LSD radix, 8 bits a pass, only the passes the
 * largest value needs); tmp holds n. */
static void radix_sort(uint32_t *v, uint32_t n, uint32_t *tmp)
{
	uint32_t hi = 0;
	for (uint32_t i = 0; i < n; i++)
		hi |= v[i];
	uint32_t *src = v, *dst = tmp;
	for (int sh = 0; sh < 32 && (hi >> sh); sh += 8) {
		uint32_t cnt[257] = {0};
		for (uint32_t i = 0; i < n; i++)
			cnt[(src[i] >> sh & 255) + 1]++;
		for (int k = 0; k < 256; k++)
			cnt[k + 1] += cnt[k];
		for (uint32_t i = 0; i < n; i++)
			dst[cnt[src[i] >> sh & 255]++] = src[i];
		uint32_t *t = src;
		src = dst;
		dst = t;
	}
	if (src != v)
		memcpy(v, src, n * sizeof *v);
}

int vd_palette_encode(struct vd_palette_segment *s, const uint8_t *rgb,
		      uint32_t n, const struct vd_palette *p)
{
	memset(s, 0, sizeof *s);
	s->n = n;
	unsigned entry_bits = p->k <= 65536 ? 16 : 32;
	uint32_t *gi = malloc(((size_t)n + 1) * sizeof *gi);
	s->offsets = malloc(((size_t)n + 1) * sizeof *s->offsets);
	s->start = malloc(((size_t)n + 1) * sizeof *s->start);
	s->pal_first = malloc(((size_t)n + 2) * sizeof *s->pal_first);
	s->pal = malloc(((size_t)n + 1) * sizeof *s->pal);
	/* a small open hash set of the block's global indices */
	uint32_t hcap = 4096;
	uint32_t *hset = malloc(hcap * sizeof *hset);
	uint32_t *hrank = malloc(hcap * sizeof *hrank);
	uint32_t *tmp = malloc(hcap * sizeof *tmp);
	if (!gi || !s->offsets || !s->start || !s->pal_first || !s->pal ||
	    !hset || !hrank || !tmp) {
		free(gi);
		free(hset);
		free(hrank);
		free(tmp);
		vd_palette_segment_release(s);
		return vd_fail(VD_ERR_NOMEM, "palette blocks of %u colours", n);
	}
	for (uint32_t i = 0; i < n; i++) {
		const uint8_t *x = rgb + 3 * (size_t)i;
		uint32_t c = (uint32_t)x[0] << 16 | (uint32_t)x[1] << 8 | x[2];
		gi[i] = p->index[c];
		unsigned e = vd_rgb_dist2(x, p->rgb + 3 * (size_t)gi[i]);
		s->sse += e;
		if (e > s->max_dist2)
			s->max_dist2 = e;
	}
	uint32_t nblk = 0, npal = 0;
	for (uint32_t i = 0; i < n;) {
		memset(hset, 0xff, hcap * sizeof *hset);
		uint32_t d = 0, best_end = i + 1;
		double best = 1e30;
		for (uint32_t j = i; j < n; j++) {
			uint32_t v = gi[j], h = (v * 2654435761u) & (hcap - 1);
			while (hset[h] != UINT32_MAX && hset[h] != v)
				h = (h + 1) & (hcap - 1);
			if (hset[h] == UINT32_MAX) {
				if (d + 1 > hcap / 2)
					break; /* block palettes stay below 2048 */
				hset[h] = v;
				d++;
			}
			uint64_t len = j - i + 1;
			unsigned w = width_of(d);
			double cost = (HEADER_BITS + PAL_BITS +
				       (double)d * entry_bits + (double)len * w) /
				      (double)len;
			if (cost < best) {
				best = cost;
				best_end = j + 1;
			}
			if (w >= best || j + 1 - best_end >= LOOKAHEAD)
				break;
		}
		/* the block [i, best_end): its sorted set and offsets. Its
		 * distinct indices by the hash set again (at most d of them),
		 * sorted by radix, each slot then holding its value's rank */
		s->start[nblk] = i;
		s->pal_first[nblk] = npal;
		uint32_t first = npal;
		memset(hset, 0xff, hcap * sizeof *hset);
		for (uint32_t j = i; j < best_end; j++) {
			uint32_t v = gi[j], h = (v * 2654435761u) & (hcap - 1);
			while (hset[h] != UINT32_MAX && hset[h] != v)
				h = (h + 1) & (hcap - 1);
			if (hset[h] == UINT32_MAX) {
				hset[h] = v;
				s->pal[npal++] = v;
			}
		}
		radix_sort(s->pal + first, npal - first, tmp);
		for (uint32_t q = first; q < npal; q++) {
			uint32_t v = s->pal[q], h = (v * 2654435761u) & (hcap - 1);
			while (hset[h] != v)
				h = (h + 1) & (hcap - 1);
			hrank[h] = q - first;
		}
		for (uint32_t j = i; j < best_end; j++) {
			uint32_t v = gi[j], h = (v * 2654435761u) & (hcap - 1);
			while (hset[h] != v)
				h = (h + 1) & (hcap - 1);
			s->offsets[j] = hrank[h];
		}
		nblk++;
		i = best_end;
	}
	s->count = nblk;
	s->pal_first[nblk] = npal;
	free(gi);
	free(hset);
	free(hrank);
	free(tmp);
	return VD_OK;
}

void vd_palette_segment_release(struct vd_palette_segment *s)
{
	free(s->start);
	free(s->pal_first);
	free(s->pal);
	free(s->offsets);
	memset(s, 0, sizeof *s);
}
