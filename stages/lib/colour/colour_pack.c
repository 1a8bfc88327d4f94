/* Packed colours files (chunk kind 6, schemas/colour-formats.md): the
 * scene's colour array in the VBR, palette or raw form, written segment by
 * segment as the cells arrive, and read back for random access and full
 * decoding. */
#include "voxdag.h"
#include "util_internal.h"
#include "colour/colour_internal.h"
#include "le.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define TAG_CPAR VD_TAG('C', 'P', 'A', 'R')
#define TAG_CSEG VD_TAG('C', 'S', 'E', 'G')
#define TAG_VBLK VD_TAG('V', 'B', 'L', 'K')
#define TAG_VWGT VD_TAG('V', 'W', 'G', 'T')
#define TAG_PGLB VD_TAG('P', 'G', 'L', 'B')
#define TAG_PTAB VD_TAG('P', 'T', 'A', 'B')
#define TAG_PENT VD_TAG('P', 'E', 'N', 'T')
#define TAG_PBLK VD_TAG('P', 'B', 'L', 'K')
#define TAG_POFS VD_TAG('P', 'O', 'F', 'S')
#define TAG_RAWC VD_TAG('R', 'A', 'W', 'C')
#define TAG_ABLK VD_TAG('A', 'B', 'L', 'K')
#define TAG_ADAT VD_TAG('A', 'D', 'A', 'T')

#define CPAR_SIZE 64
#define CSEG_SIZE 40
#define VBLK_SIZE 8
#define PBLK_SIZE 12
#define PTAB_SIZE 8

const char *vd_cpack_method_name(int method)
{
	switch (method) {
	case VD_CPACK_VBR: return "vbr";
	case VD_CPACK_PALETTE: return "palette";
	case VD_CPACK_RAW: return "raw";
	case VD_CPACK_AUTO: return "auto";
	}
	return NULL;
}

static unsigned width_of(uint32_t colours)
{
	unsigned w = 0;
	while ((1ull << w) < colours)
		w++;
	return w;
}

/* Reads `width` (0..32) bits at bit `pos` of `b`, LSB first. */
static uint32_t get_bits(const uint8_t *b, uint64_t pos, unsigned width)
{
	if (!width)
		return 0;
	uint64_t v = 0;
	size_t i = pos >> 3;
	unsigned sh = pos & 7, got = 0;
	while (got < sh + width) {
		v |= (uint64_t)b[i++] << got;
		got += 8;
	}
	return (uint32_t)(v >> sh) & (uint32_t)((1ull << width) - 1);
}

/* Writes values LSB first into consecutive bits of a zeroed buffer, a
 * byte at a time (the bytes a bit-by-bit writer makes). */
struct bitw {
	uint8_t *b;
	size_t at;       /* next byte */
	uint64_t acc;    /* bits not yet written, below 8 + 32 */
	unsigned n;
};

static void bitw_put(struct bitw *o, unsigned width, uint32_t v)
{
	o->acc |= (uint64_t)v << o->n;
	o->n += width;
	while (o->n >= 8) {
		o->b[o->at++] = (uint8_t)o->acc;
		o->acc >>= 8;
		o->n -= 8;
	}
}

static void bitw_flush(struct bitw *o)
{
	if (o->n)
		o->b[o->at++] = (uint8_t)o->acc;
	o->acc = 0;
	o->n = 0;
}

/* ------------------------------------------------------------------ writer */

/* A growable byte buffer (the small tables kept in memory to the end). */
struct buf {
	uint8_t *p;
	size_t n, cap;
};

static int buf_add(struct buf *b, const void *d, size_t n)
{
	if (b->n + n > b->cap) {
		size_t cap = b->cap ? b->cap : 4096;
		while (cap < b->n + n)
			cap *= 2;
		uint8_t *g = realloc(b->p, cap);
		if (!g)
			return vd_fail(VD_ERR_NOMEM, "colour tables of %zu bytes",
				       b->n + n);
		b->p = g;
		b->cap = cap;
	}
	memcpy(b->p + b->n, d, n);
	b->n += n;
	return VD_OK;
}

/* The block palettes seen so far, by content (open addressing over
 * palette ids), so blocks with the same set share one. */
struct palset {
	uint32_t *slot;  /* palette id + 1, 0 empty */
	uint64_t cap, count;
	struct buf tab;  /* PTAB */
	struct buf ent;  /* PENT */
	uint64_t entries;
	unsigned entry_bytes;
};

static uint32_t ent_at(const struct palset *ps, uint64_t i)
{
	const uint8_t *p = ps->ent.p + i * ps->entry_bytes;
	return ps->entry_bytes == 2 ? le_get16(p) : le_get32(p);
}

static uint64_t pal_hash(const uint32_t *v, uint32_t n)
{
	return vd_hash64(v, (size_t)n * sizeof *v, 0x5eed);
}

static int palset_find(struct palset *ps, const uint32_t *v, uint32_t n,
		       uint32_t *id)
{
	if ((ps->count + 1) * 2 > ps->cap) {
		uint64_t cap = ps->cap ? 2 * ps->cap : 1024;
		uint32_t *s = calloc(cap, sizeof *s);
		if (!s)
			return vd_fail(VD_ERR_NOMEM, "block palette table");
		for (uint64_t i = 0; i < ps->cap; i++) {
			if (!ps->slot[i])
				continue;
			uint32_t q = ps->slot[i] - 1;
			const uint8_t *t = ps->tab.p + (size_t)q * PTAB_SIZE;
			uint32_t first = le_get32(t), cnt = le_get32(t + 4);
			uint32_t tmp[4096];
			for (uint32_t k = 0; k < cnt; k++)
				tmp[k] = ent_at(ps, first + k);
			uint64_t h = pal_hash(tmp, cnt) & (cap - 1);
			while (s[h])
				h = (h + 1) & (cap - 1);
			s[h] = ps->slot[i];
		}
		free(ps->slot);
		ps->slot = s;
		ps->cap = cap;
	}
	uint64_t h = pal_hash(v, n) & (ps->cap - 1);
	while (ps->slot[h]) {
		uint32_t q = ps->slot[h] - 1;
		const uint8_t *t = ps->tab.p + (size_t)q * PTAB_SIZE;
		uint32_t first = le_get32(t), cnt = le_get32(t + 4), k = 0;
		if (cnt == n)
			while (k < n && ent_at(ps, first + k) == v[k])
				k++;
		if (cnt == n && k == n) {
			*id = q;
			return VD_OK;
		}
		h = (h + 1) & (ps->cap - 1);
	}
	if (ps->count >= UINT32_MAX || ps->entries + n > UINT32_MAX)
		return vd_fail(VD_ERR_RANGE, "more than 2^32 block palette "
			       "entries");
	uint8_t t[PTAB_SIZE];
	le_put32(t, (uint32_t)ps->entries);
	le_put32(t + 4, n);
	int err = buf_add(&ps->tab, t, sizeof t);
	for (uint32_t k = 0; k < n && !err; k++) {
		uint8_t e[4];
		le_put32(e, v[k]);
		err = buf_add(&ps->ent, e, ps->entry_bytes);
	}
	if (err)
		return err;
	ps->entries += n;
	*id = (uint32_t)ps->count++;
	ps->slot[h] = *id + 1;
	return VD_OK;
}

struct vd_cpack_writer {
	struct vd_chunk_writer *cw;
	struct vd_cpack_params p;
	char *spool_path;
	FILE *spool;          /* VBLK or PBLK, copied in at commit */
	struct buf seg;       /* CSEG */
	struct palset ps;
	uint64_t voxels, segments, blocks, data_bytes;
	uint64_t mode_blocks[VD_AUTO_MODES];
	uint64_t sse;
	unsigned max_dist2;
	int has_cell, cell_level;
	uint64_t cell_morton;
	double t0;
	uint8_t *scratch;
	size_t scratch_cap;
};

static int spool_open(struct vd_cpack_writer *w, const char *path)
{
	size_t n = strlen(path) + 32;
	w->spool_path = malloc(n);
	if (!w->spool_path)
		return vd_fail(VD_ERR_NOMEM, "spool name");
	snprintf(w->spool_path, n, "%s.spool.XXXXXX", path);
	int fd = mkstemp(w->spool_path);
	if (fd < 0)
		return vd_fail(VD_ERR_IO, "cannot create '%s': %s",
			       w->spool_path, strerror(errno));
	/* unlinked at once: a killed run leaves nothing behind */
	unlink(w->spool_path);
	w->spool = fdopen(fd, "w+b");
	if (!w->spool) {
		close(fd);
		return vd_fail(VD_ERR_IO, "spool: %s", strerror(errno));
	}
	return VD_OK;
}

static int auto_block_log(const struct vd_cpack_params *p)
{
	return p->autop.block_log ? p->autop.block_log : 8;
}

int vd_cpack_writer_open(struct vd_cpack_writer **out, const char *path,
			 const struct vd_cpack_params *p, int levels,
			 const struct vd_transform *t,
			 const char *provenance)
{
	*out = NULL;
	if (!vd_cpack_method_name(p->method) ||
	    (p->method == VD_CPACK_PALETTE && !p->palette))
		return vd_fail(VD_ERR_ARG, "colour method %d", p->method);
	if (levels < 1 || levels > VD_MAX_LEVELS)
		return vd_fail(VD_ERR_ARG, "depth %d", levels);
	struct vd_cpack_writer *w = calloc(1, sizeof *w);
	if (!w)
		return vd_fail(VD_ERR_NOMEM, "colour writer");
	w->p = *p;
	w->t0 = vd_seconds();
	w->ps.entry_bytes = p->palette && p->palette->k > 65536 ? 4 : 2;
	struct vd_chunk_header h = {.kind = VD_KIND_CPACK,
				    .levels = (uint32_t)levels,
				    .transform = *t,
				    .level_count = 1};
	int err = vd_chunk_writer_open(&w->cw, path, &h, provenance);
	if (!err && p->method != VD_CPACK_RAW)
		err = spool_open(w, path);
	if (!err) {
		uint32_t tag = p->method == VD_CPACK_VBR ? TAG_VWGT
			       : p->method == VD_CPACK_PALETTE ? TAG_POFS
			       : p->method == VD_CPACK_AUTO ? TAG_ADAT
							       : TAG_RAWC;
		int lvl = p->method == VD_CPACK_RAW
				  ? (p->zstd_level ? p->zstd_level : 9)
				  : -1;
		err = vd_chunk_writer_begin(w->cw, tag, lvl);
	}
	if (err) {
		vd_cpack_writer_abort(w);
		return err;
	}
	*out = w;
	return VD_OK;
}

struct seg_job {
	const struct vd_cpack_params *p;
	const uint8_t *rgb;
	uint64_t n;
	struct vd_vbr_segment *vbr;
	struct vd_palette_segment *pal;
	struct vd_auto_segment *aut;
	int *errs;
	char (*details)[256];
};

static void seg_run(void *ctx, size_t i, int worker)
{
	struct seg_job *j = ctx;
	uint64_t first = (uint64_t)i * VD_CPACK_SEGMENT_MAX;
	uint32_t n = (uint32_t)(j->n - first < VD_CPACK_SEGMENT_MAX
					? j->n - first
					: VD_CPACK_SEGMENT_MAX);
	const uint8_t *rgb = j->rgb + 3 * first;
	int err = j->p->method == VD_CPACK_VBR
			  ? vd_vbr_encode(&j->vbr[i], rgb, n, &j->p->vbr)
		  : j->p->method == VD_CPACK_AUTO
			  ? vd_auto_encode(&j->aut[i], rgb, n, &j->p->autop)
			  : vd_palette_encode(&j->pal[i], rgb, n, j->p->palette);
	j->errs[i] = err;
	if (err)
		snprintf(j->details[i], sizeof j->details[i], "%s",
			 vd_error_detail());
}

static int write_seg_entry(struct vd_cpack_writer *w, uint32_t n,
			   uint64_t first_block)
{
	uint8_t e[CSEG_SIZE];
	le_put64(e, w->voxels);
	le_put64(e + 8, first_block);
	le_put64(e + 16, w->data_bytes);
	le_put64(e + 24, w->cell_morton);
	le_put32(e + 32, (uint32_t)w->cell_level);
	le_put32(e + 36, n);
	return buf_add(&w->seg, e, sizeof e);
}

static int spool_write(struct vd_cpack_writer *w, const void *d, size_t n)
{
	if (fwrite(d, 1, n, w->spool) != n)
		return vd_fail(VD_ERR_IO, "spool write: %s", strerror(errno));
	return VD_OK;
}

/* Appends one encoded VBR segment: its weights to the open section, its
 * block headers to the spool. */
static int put_vbr(struct vd_cpack_writer *w, const struct vd_vbr_segment *s)
{
	int err = write_seg_entry(w, s->n, w->blocks);
	size_t wb = ((size_t)s->n * s->weight_bits + 7) / 8;
	if (!err)
		err = vd_chunk_writer_write(w->cw, s->weights, wb);
	uint8_t hb[VBLK_SIZE * 256];
	size_t k = 0;
	for (uint32_t b = 0; b < s->count && !err; b++) {
		le_put32(hb + VBLK_SIZE * k, s->start[b]);
		le_put16(hb + VBLK_SIZE * k + 4, s->c0[b]);
		le_put16(hb + VBLK_SIZE * k + 6, s->c1[b]);
		if (++k == 256) {
			err = spool_write(w, hb, sizeof hb);
			k = 0;
		}
	}
	if (!err && k)
		err = spool_write(w, hb, VBLK_SIZE * k);
	w->blocks += s->count;
	w->data_bytes += wb;
	w->sse += s->sse;
	if (s->max_dist2 > w->max_dist2)
		w->max_dist2 = s->max_dist2;
	return err;
}

/* Appends one auto segment: its blocks' bytes to the open section, their
 * directory entries to the spool. */
static int put_auto(struct vd_cpack_writer *w, const struct vd_auto_segment *s)
{
	int err = write_seg_entry(w, s->n, w->blocks);
	if (!err)
		err = vd_chunk_writer_write(w->cw, s->data, s->data_bytes);
	uint8_t hb[4 * 1024];
	size_t k = 0;
	for (uint32_t b = 0; b < s->count && !err; b++) {
		le_put32(hb + 4 * k, s->dir[b]);
		if (++k == 1024) {
			err = spool_write(w, hb, sizeof hb);
			k = 0;
		}
	}
	if (!err && k)
		err = spool_write(w, hb, 4 * k);
	w->blocks += s->count;
	w->data_bytes += s->data_bytes;
	w->sse += s->sse;
	for (int m = 0; m < VD_AUTO_MODES; m++)
		w->mode_blocks[m] += s->mode_blocks[m];
	if (s->max_dist2 > w->max_dist2)
		w->max_dist2 = s->max_dist2;
	return err;
}

/* Appends one palette segment: its blocks' palettes shared through the
 * table, their headers to the spool, the offsets packed at the smallest
 * width to the open section. */
static int put_pal(struct vd_cpack_writer *w,
		   const struct vd_palette_segment *s)
{
	int err = write_seg_entry(w, s->n, w->blocks);
	uint64_t bits = 0;
	for (uint32_t b = 0; b < s->count; b++) {
		uint32_t end = b + 1 < s->count ? s->start[b + 1] : s->n;
		bits += (uint64_t)(end - s->start[b]) *
			width_of(s->pal_first[b + 1] - s->pal_first[b]);
	}
	size_t nb = (size_t)((bits + 7) / 8);
	if (!err && nb + 1 > w->scratch_cap) {
		free(w->scratch);
		w->scratch_cap = nb + 1;
		w->scratch = malloc(w->scratch_cap);
		if (!w->scratch)
			err = vd_fail(VD_ERR_NOMEM, "offsets of %zu bytes", nb);
	}
	if (err)
		return err;
	memset(w->scratch, 0, nb + 1);
	uint64_t pos = 0;
	struct bitw bw = {.b = w->scratch};
	for (uint32_t b = 0; b < s->count && !err; b++) {
		uint32_t cnt = s->pal_first[b + 1] - s->pal_first[b], id;
		err = palset_find(&w->ps, s->pal + s->pal_first[b], cnt, &id);
		if (err)
			break;
		uint8_t hb[PBLK_SIZE];
		le_put32(hb, s->start[b]);
		le_put32(hb + 4, id);
		le_put32(hb + 8, (uint32_t)pos);
		err = spool_write(w, hb, sizeof hb);
		unsigned width = width_of(cnt);
		uint32_t end = b + 1 < s->count ? s->start[b + 1] : s->n;
		for (uint32_t i = s->start[b]; i < end; i++, pos += width)
			bitw_put(&bw, width, s->offsets[i]);
	}
	bitw_flush(&bw);
	if (!err)
		err = vd_chunk_writer_write(w->cw, w->scratch, nb);
	w->blocks += s->count;
	w->data_bytes += nb;
	w->sse += s->sse;
	if (s->max_dist2 > w->max_dist2)
		w->max_dist2 = s->max_dist2;
	return err;
}

int vd_cpack_writer_add(struct vd_cpack_writer *w, int chunk_level,
			uint64_t cell_morton, const uint8_t *rgb, uint64_t n)
{
	if (w->has_cell && (chunk_level != w->cell_level ||
			    cell_morton <= w->cell_morton))
		return vd_fail(VD_ERR_ARG, "cell %d:%llx after cell %d:%llx: "
			       "cells must come in increasing order",
			       chunk_level, (unsigned long long)cell_morton,
			       w->cell_level,
			       (unsigned long long)w->cell_morton);
	w->has_cell = 1;
	w->cell_level = chunk_level;
	w->cell_morton = cell_morton;
	if (n == 0)
		return VD_OK;
	if (w->p.method == VD_CPACK_RAW) {
		/* segments of the raw array only mark the cells */
		int err = VD_OK;
		for (uint64_t f = 0; f < n && !err; f += VD_CPACK_SEGMENT_MAX) {
			uint32_t m = (uint32_t)(n - f < VD_CPACK_SEGMENT_MAX
							? n - f
							: VD_CPACK_SEGMENT_MAX);
			err = write_seg_entry(w, m, 0);
			w->voxels += m;
			w->data_bytes += 3 * (uint64_t)m;
			w->segments++;
		}
		if (!err)
			err = vd_chunk_writer_write(w->cw, rgb, (size_t)(3 * n));
		return err;
	}
	size_t nseg = (size_t)((n + VD_CPACK_SEGMENT_MAX - 1) /
			       VD_CPACK_SEGMENT_MAX);
	struct seg_job j = {.p = &w->p, .rgb = rgb, .n = n};
	j.errs = calloc(nseg, sizeof *j.errs);
	j.details = calloc(nseg, sizeof *j.details);
	if (w->p.method == VD_CPACK_VBR)
		j.vbr = calloc(nseg, sizeof *j.vbr);
	else if (w->p.method == VD_CPACK_AUTO)
		j.aut = calloc(nseg, sizeof *j.aut);
	else
		j.pal = calloc(nseg, sizeof *j.pal);
	int err = VD_OK;
	if (!j.errs || !j.details || (!j.vbr && !j.pal && !j.aut))
		err = vd_fail(VD_ERR_NOMEM, "%zu segments", nseg);
	if (!err)
		err = vd_parallel_for(nseg, w->p.threads, seg_run, &j);
	for (size_t i = 0; i < nseg && !err; i++)
		if (j.errs[i])
			err = vd_fail(j.errs[i], "%s", j.details[i]);
	for (size_t i = 0; i < nseg && !err; i++) {
		err = j.vbr ? put_vbr(w, &j.vbr[i])
		      : j.aut ? put_auto(w, &j.aut[i])
			      : put_pal(w, &j.pal[i]);
		uint32_t m = j.vbr ? j.vbr[i].n : j.aut ? j.aut[i].n : j.pal[i].n;
		w->voxels += m;
		w->segments++;
	}
	for (size_t i = 0; i < nseg; i++) {
		if (j.vbr)
			vd_vbr_segment_release(&j.vbr[i]);
		if (j.pal)
			vd_palette_segment_release(&j.pal[i]);
		if (j.aut)
			vd_auto_segment_release(&j.aut[i]);
	}
	free(j.vbr);
	free(j.aut);
	free(j.pal);
	free(j.errs);
	free(j.details);
	return err;
}

/* The tables are stored, not zstd'ed: the file holds the structure a
 * reader maps, byte for byte (raw's RAWC is the one compressed section). */
static int stored(struct vd_chunk_writer *cw, uint32_t tag, const void *d,
		  size_t n)
{
	int err = vd_chunk_writer_begin(cw, tag, -1);
	if (!err)
		err = vd_chunk_writer_write(cw, d, n);
	return err ? err : vd_chunk_writer_end(cw);
}

static int copy_spool(struct vd_cpack_writer *w, uint32_t tag)
{
	int err = vd_chunk_writer_begin(w->cw, tag, -1);
	if (err)
		return err;
	if (fflush(w->spool) || fseek(w->spool, 0, SEEK_SET))
		return vd_fail(VD_ERR_IO, "spool: %s", strerror(errno));
	uint8_t b[1 << 16];
	size_t n;
	while (!err && (n = fread(b, 1, sizeof b, w->spool)) > 0)
		err = vd_chunk_writer_write(w->cw, b, n);
	if (!err && ferror(w->spool))
		err = vd_fail(VD_ERR_IO, "spool read: %s", strerror(errno));
	return err ? err : vd_chunk_writer_end(w->cw);
}

int vd_cpack_writer_commit(struct vd_cpack_writer *w,
			   struct vd_cpack_stats *st)
{
	int err = vd_chunk_writer_end(w->cw);
	uint8_t par[CPAR_SIZE] = {0};
	le_put32(par, (uint32_t)w->p.method);
	le_put32(par + 4, w->p.method == VD_CPACK_VBR ? (uint32_t)w->p.vbr.weight_bits
			  : w->p.method == VD_CPACK_AUTO ? (uint32_t)auto_block_log(&w->p)
							 : 0);
	le_put64(par + 8, w->voxels);
	le_put64(par + 16, w->segments);
	le_put64(par + 24, w->blocks);
	double et = w->p.method == VD_CPACK_VBR ? w->p.vbr.max_error
		    : w->p.method == VD_CPACK_AUTO ? w->p.autop.max_error
						   : 0;
	uint64_t etb;
	memcpy(&etb, &et, 8);
	le_put64(par + 32, etb);
	if (w->p.method == VD_CPACK_AUTO && w->p.autop.coded)
		le_put32(par + 48, 1); /* coded segments (1.2) */
	if (w->p.method == VD_CPACK_PALETTE) {
		le_put32(par + 40, w->p.palette->k);
		le_put32(par + 44, w->p.palette_colours);
		le_put32(par + 48, w->p.palette->lossless ? 1 : 0);
		le_put32(par + 52, w->ps.entry_bytes);
		le_put64(par + 56, w->ps.count);
	}
	if (!err)
		err = stored(w->cw, TAG_CPAR, par, sizeof par);
	if (!err)
		err = stored(w->cw, TAG_CSEG, w->seg.p, w->seg.n);
	uint64_t bytes = w->seg.n;
	if (!err && w->p.method == VD_CPACK_VBR) {
		err = copy_spool(w, TAG_VBLK);
		bytes += w->blocks * VBLK_SIZE + w->data_bytes;
	}
	if (!err && w->p.method == VD_CPACK_AUTO) {
		err = copy_spool(w, TAG_ABLK);
		bytes += w->blocks * 4 + w->data_bytes;
	}
	if (!err && w->p.method == VD_CPACK_PALETTE) {
		const struct vd_palette *pl = w->p.palette;
		err = stored(w->cw, TAG_PGLB, pl->rgb,
					      3 * (size_t)pl->k);
		if (!err)
			err = stored(w->cw, TAG_PTAB, w->ps.tab.p,
						      w->ps.tab.n);
		if (!err)
			err = stored(w->cw, TAG_PENT, w->ps.ent.p,
						      w->ps.ent.n);
		if (!err)
			err = copy_spool(w, TAG_PBLK);
		bytes += 3 * (uint64_t)pl->k + w->ps.tab.n + w->ps.ent.n +
			 w->blocks * PBLK_SIZE + w->data_bytes;
	}
	if (!err)
		err = vd_chunk_writer_set_counts(w->cw, &w->voxels, 1);
	struct vd_cpack_stats s = {
		.voxels = w->voxels, .segments = w->segments,
		.blocks = w->blocks, .palettes = w->ps.count,
		.palette_entries = w->ps.entries, .sse = w->sse,
		.max_dist2 = w->max_dist2};
	memcpy(s.mode_blocks, w->mode_blocks, sizeof s.mode_blocks);
	if (!err) {
		err = vd_chunk_writer_commit(w->cw);
		w->cw = NULL;
	}
	s.seconds = vd_seconds() - w->t0;
	s.bytes = bytes;
	if (st)
		*st = s;
	vd_cpack_writer_abort(w);
	return err;
}

void vd_cpack_writer_abort(struct vd_cpack_writer *w)
{
	if (!w)
		return;
	vd_chunk_writer_abort(w->cw);
	if (w->spool)
		fclose(w->spool);
	free(w->spool_path);
	free(w->seg.p);
	free(w->ps.slot);
	free(w->ps.tab.p);
	free(w->ps.ent.p);
	free(w->scratch);
	free(w);
}

/* ------------------------------------------------------------------ reader */

struct vd_cpack {
	int method, weight_bits, lossless;
	int cell_level;              /* of the segments' cells, -1: none */
	uint64_t voxels, segments, blocks, bytes;
	double max_error;
	/* segments */
	uint64_t *seg_first, *seg_block, *seg_data;
	uint32_t *seg_n;
	/* blocks */
	uint32_t *blk_start;
	uint16_t *c0, *c1;           /* vbr */
	uint32_t *blk_pal, *blk_bit; /* palette */
	/* auto: per block its directory entry (low 32 bits) and its
	 * layout (vd_auto_layout, high 32): 4 bytes a block more than the
	 * file's directory, 1/64 byte a voxel at 2^8 voxels a block */
	uint64_t *dir;
	/* auto: seg_at[p] the segment holding voxel p << 18, so a lookup
	 * searches only the segments that start in its 2^18 window */
	uint32_t *seg_at;
	int block_log;               /* auto */
	int coded;                   /* auto: segments carry code tables */
	struct vd_auto_code **code;  /* auto, coded: per segment, NULL: none */
	/* auto, coded: the restart points of coded block b at
	 * restart[blk_restart[b] ..], (2^block_log - 1) / VD_AUTO_RESTART
	 * of them (UINT32_MAX: not coded), taken while the block is checked
	 * at open */
	struct vd_auto_coded_state *restart;
	uint32_t *blk_restart;
	uint8_t *data;               /* VWGT, POFS or the raw array */
	size_t data_size;
	/* palette */
	uint32_t k, npal;
	uint8_t *glb;
	uint32_t *pal_first, *pal_count, *ent;
	uint64_t nent;
};

void vd_cpack_free(struct vd_cpack *c)
{
	if (!c)
		return;
	free(c->seg_first);
	free(c->seg_block);
	free(c->seg_data);
	free(c->seg_n);
	free(c->blk_start);
	free(c->c0);
	free(c->c1);
	free(c->blk_pal);
	free(c->blk_bit);
	free(c->dir);
	free(c->seg_at);
	if (c->code)
		for (uint64_t s = 0; s < c->segments; s++)
			free(c->code[s]);
	free(c->code);
	free(c->restart);
	free(c->blk_restart);
	free(c->data);
	free(c->glb);
	free(c->pal_first);
	free(c->pal_count);
	free(c->ent);
	free(c);
}

static int section(const struct vd_chunk *ch, uint32_t tag, uint8_t **d,
		   size_t *n, size_t unit, const char *name)
{
	int err = vd_chunk_read_section(ch, tag, (void **)d, n);
	if (err)
		return err;
	if (unit && *n % unit)
		return vd_fail(VD_ERR_CORRUPT, "%s section of %zu bytes, not a "
			       "multiple of %zu", name, *n, unit);
	return VD_OK;
}

/* The CPAR section: the method, counts and parameters, checked against
 * the header; the palette's entry width and block palette count go to
 * *entry_bytes and *npal for the palette sections. */
static int read_cpar(struct vd_cpack *c, const struct vd_chunk *ch,
		     unsigned *entry_bytes, uint64_t *npal)
{
	const struct vd_chunk_header *h = vd_chunk_header(ch);
	uint8_t *par = NULL;
	size_t n;
	int err;
	if ((err = section(ch, TAG_CPAR, &par, &n, 0, "CPAR")))
		return err;
	if (n < CPAR_SIZE) {
		free(par);
		return vd_fail(VD_ERR_CORRUPT, "CPAR of %zu bytes", n);
	}
	c->method = (int)le_get32(par);
	c->weight_bits = (int)le_get32(par + 4);
	c->voxels = le_get64(par + 8);
	c->segments = le_get64(par + 16);
	c->blocks = le_get64(par + 24);
	uint64_t etb = le_get64(par + 32);
	memcpy(&c->max_error, &etb, 8);
	c->k = le_get32(par + 40);
	c->lossless = (int)le_get32(par + 48);
	*entry_bytes = le_get32(par + 52);
	*npal = le_get64(par + 56);
	free(par);
	if (!vd_cpack_method_name(c->method))
		return vd_fail(VD_ERR_UNSUPPORTED, "colour method %d (written by "
			       "a newer colorize?)", c->method);
	if (c->voxels != h->level_nodes[0])
		return vd_fail(VD_ERR_CORRUPT, "%llu colours, header says %llu",
			       (unsigned long long)c->voxels,
			       (unsigned long long)h->level_nodes[0]);
	if (c->method == VD_CPACK_VBR && (c->weight_bits < 1 || c->weight_bits > 8))
		return vd_fail(VD_ERR_CORRUPT, "%d weight bits", c->weight_bits);
	if (c->method == VD_CPACK_AUTO) {
		c->block_log = c->weight_bits;
		c->weight_bits = 0;
		c->coded = c->lossless;
		c->lossless = 0;
		if ((unsigned)c->coded > 1)
			return vd_fail(VD_ERR_CORRUPT, "auto flags 0x%x",
				       (unsigned)c->coded);
		if (c->coded && c->max_error != 0)
			return vd_fail(VD_ERR_CORRUPT, "coded segments with max "
				       "error %g (coded is lossless only)",
				       c->max_error);
		if (c->block_log < 4 || c->block_log > 12)
			return vd_fail(VD_ERR_CORRUPT, "blocks of 2^%d colours",
				       c->block_log);
	}
	return VD_OK;
}

/* The CSEG section: segments tile the array in order, each
 * 1..SEGMENT_MAX voxels, all in cells of one level, cells not
 * decreasing. */
static int read_segments(struct vd_cpack *c, const struct vd_chunk *ch)
{
	uint8_t *seg = NULL;
	size_t n;
	int err;
	/* segments: tile the array in order, each 1..SEGMENT_MAX voxels */
	if ((err = section(ch, TAG_CSEG, &seg, &n, CSEG_SIZE, "CSEG")))
		return err;
	if (n / CSEG_SIZE != c->segments) {
		free(seg);
		return vd_fail(VD_ERR_CORRUPT, "%zu segments, CPAR says %llu",
			       n / CSEG_SIZE, (unsigned long long)c->segments);
	}
	size_t S = (size_t)c->segments;
	c->seg_first = malloc((S + 1) * 8);
	c->seg_block = malloc((S + 1) * 8);
	c->seg_data = malloc((S + 1) * 8);
	c->seg_n = malloc((S + 1) * 4);
	if (!c->seg_first || !c->seg_block || !c->seg_data || !c->seg_n) {
		free(seg);
		return vd_fail(VD_ERR_NOMEM, "%zu segments", S);
	}
	uint64_t v = 0, prev_cell = 0;
	uint32_t cell_level = 0;
	for (size_t s = 0; s < S; s++) {
		const uint8_t *e = seg + CSEG_SIZE * s;
		c->seg_first[s] = le_get64(e);
		c->seg_block[s] = le_get64(e + 8);
		c->seg_data[s] = le_get64(e + 16);
		uint64_t cell = le_get64(e + 24);
		uint32_t lvl = le_get32(e + 32);
		c->seg_n[s] = le_get32(e + 36);
		if (s == 0)
			cell_level = lvl;
		if (c->seg_first[s] != v || c->seg_n[s] == 0 ||
		    c->seg_n[s] > VD_CPACK_SEGMENT_MAX || lvl != cell_level ||
		    (s && cell < prev_cell)) {
			free(seg);
			return vd_fail(VD_ERR_CORRUPT, "segment %zu: first voxel "
				       "%llu, %u voxels, cell %u:%llx", s,
				       (unsigned long long)c->seg_first[s],
				       c->seg_n[s], lvl, (unsigned long long)cell);
		}
		prev_cell = cell;
		v += c->seg_n[s];
	}
	free(seg);
	c->cell_level = S ? (int)cell_level : -1;
	c->seg_first[S] = v;
	c->seg_block[S] = c->blocks;
	if (v != c->voxels)
		return vd_fail(VD_ERR_CORRUPT, "segments hold %llu voxels, CPAR "
			       "says %llu", (unsigned long long)v,
			       (unsigned long long)c->voxels);
	return VD_OK;
}

/* The raw method's RAWC section: three bytes a voxel, each segment's at
 * three times its first voxel. */
static int read_raw(struct vd_cpack *c, const struct vd_chunk *ch)
{
	size_t S = (size_t)c->segments;
	int err;
	if ((err = section(ch, TAG_RAWC, &c->data, &c->data_size, 3, "RAWC")))
		return err;
	if (c->data_size != 3 * c->voxels)
		return vd_fail(VD_ERR_CORRUPT, "%zu raw bytes for %llu "
			       "colours", c->data_size,
			       (unsigned long long)c->voxels);
	for (size_t s = 0; s < S; s++)
		if (c->seg_data[s] != 3 * c->seg_first[s])
			return vd_fail(VD_ERR_CORRUPT, "segment %zu: raw "
				       "offset", s);
	return VD_OK;
}

/* The VBLK (vbr: start, two endpoint colours) or PBLK (palette: start,
 * block palette, first offset bit) section, bsz bytes a block. */
static int read_blocks(struct vd_cpack *c, const struct vd_chunk *ch,
		       int vbr, size_t bsz)
{
	uint8_t *blk = NULL;
	size_t n;
	int err;
	if ((err = section(ch, vbr ? TAG_VBLK : TAG_PBLK, &blk, &n, bsz,
			   vbr ? "VBLK" : "PBLK")))
		return err;
	if (n / bsz != c->blocks) {
		free(blk);
		return vd_fail(VD_ERR_CORRUPT, "%zu blocks, CPAR says %llu",
			       n / bsz, (unsigned long long)c->blocks);
	}
	size_t B = (size_t)c->blocks;
	c->blk_start = malloc((B + 1) * 4);
	if (vbr) {
		c->c0 = malloc((B + 1) * 2);
		c->c1 = malloc((B + 1) * 2);
	} else {
		c->blk_pal = malloc((B + 1) * 4);
		c->blk_bit = malloc((B + 1) * 4);
	}
	if (!c->blk_start || (vbr ? !c->c0 || !c->c1 : !c->blk_pal || !c->blk_bit)) {
		free(blk);
		return vd_fail(VD_ERR_NOMEM, "%zu blocks", B);
	}
	for (size_t b = 0; b < B; b++) {
		const uint8_t *e = blk + bsz * b;
		c->blk_start[b] = le_get32(e);
		if (vbr) {
			c->c0[b] = le_get16(e + 4);
			c->c1[b] = le_get16(e + 6);
		} else {
			c->blk_pal[b] = le_get32(e + 4);
			c->blk_bit[b] = le_get32(e + 8);
		}
	}
	free(blk);
	return VD_OK;
}

/* The palette method's PGLB (global palette of k colours) and PENT
 * (entries of entry_bytes each, every one a colour of the global
 * palette) sections; adds their bytes to c->bytes. */
static int read_palette_entries(struct vd_cpack *c, const struct vd_chunk *ch,
				unsigned entry_bytes)
{
	uint8_t *ent = NULL;
	size_t n;
	int err;
	if ((err = section(ch, TAG_PGLB, &c->glb, &n, 3, "PGLB")))
		return err;
	if (n / 3 != c->k || c->k == 0)
		return vd_fail(VD_ERR_CORRUPT, "global palette of %zu "
			       "colours, CPAR says %u", n / 3, c->k);
	c->bytes += n;
	if (entry_bytes != 2 && entry_bytes != 4)
		return vd_fail(VD_ERR_CORRUPT, "palette entries of %u "
			       "bytes", entry_bytes);
	if ((err = section(ch, TAG_PENT, &ent, &n, entry_bytes, "PENT")))
		return err;
	c->bytes += n;
	c->nent = n / entry_bytes;
	c->ent = malloc((c->nent + 1) * 4);
	if (!c->ent) {
		free(ent);
		return vd_fail(VD_ERR_NOMEM, "palette entries");
	}
	for (uint64_t i = 0; i < c->nent; i++) {
		c->ent[i] = entry_bytes == 2 ? le_get16(ent + 2 * i)
					     : le_get32(ent + 4 * i);
		if (c->ent[i] >= c->k) {
			free(ent);
			return vd_fail(VD_ERR_CORRUPT, "palette entry %llu "
				       "is colour %u of %u",
				       (unsigned long long)i, c->ent[i], c->k);
		}
	}
	free(ent);
	return VD_OK;
}

/* The palette method's PTAB section: npal block palettes, each a
 * non-empty run of the entries in increasing colour order; adds its
 * bytes to c->bytes. */
static int read_block_palettes(struct vd_cpack *c, const struct vd_chunk *ch,
			       uint64_t npal)
{
	uint8_t *tab = NULL;
	size_t n;
	int err;
	if ((err = section(ch, TAG_PTAB, &tab, &n, PTAB_SIZE, "PTAB")))
		return err;
	c->bytes += n;
	if (n / PTAB_SIZE != npal || npal > UINT32_MAX) {
		free(tab);
		return vd_fail(VD_ERR_CORRUPT, "%zu block palettes, CPAR "
			       "says %llu", n / PTAB_SIZE,
			       (unsigned long long)npal);
	}
	c->npal = (uint32_t)npal;
	c->pal_first = malloc((npal + 1) * 4);
	c->pal_count = malloc((npal + 1) * 4);
	if (!c->pal_first || !c->pal_count) {
		free(tab);
		return vd_fail(VD_ERR_NOMEM, "block palettes");
	}
	for (uint64_t i = 0; i < npal; i++) {
		c->pal_first[i] = le_get32(tab + PTAB_SIZE * i);
		c->pal_count[i] = le_get32(tab + PTAB_SIZE * i + 4);
		int sorted = 1;
		if (c->pal_count[i] &&
		    (uint64_t)c->pal_first[i] + c->pal_count[i] <= c->nent)
			for (uint32_t q = 1; q < c->pal_count[i]; q++)
				sorted &= c->ent[c->pal_first[i] + q] >
					  c->ent[c->pal_first[i] + q - 1];
		if (c->pal_count[i] == 0 || !sorted ||
		    (uint64_t)c->pal_first[i] + c->pal_count[i] > c->nent) {
			free(tab);
			return vd_fail(VD_ERR_CORRUPT, "block palette %llu: "
				       "entries %u..+%u of %llu",
				       (unsigned long long)i,
				       c->pal_first[i], c->pal_count[i],
				       (unsigned long long)c->nent);
		}
	}
	free(tab);
	return VD_OK;
}

/* Blocks per segment: starts from 0, increasing, inside the segment; the
 * data of each segment where its offset says, exactly, and all of it
 * used. */
static int check_segment_blocks(const struct vd_cpack *c, int vbr)
{
	size_t S = (size_t)c->segments;
	uint64_t data = 0;
	for (size_t s = 0; s < S; s++) {
		uint64_t b0 = c->seg_block[s], b1 = s + 1 < S ? c->seg_block[s + 1]
								: c->blocks;
		if (b1 <= b0 || b1 > c->blocks || c->seg_data[s] != data)
			return vd_fail(VD_ERR_CORRUPT, "segment %zu: blocks "
				       "%llu..%llu, data at %llu", s,
				       (unsigned long long)b0,
				       (unsigned long long)b1,
				       (unsigned long long)c->seg_data[s]);
		uint64_t bits = 0;
		for (uint64_t b = b0; b < b1; b++) {
			uint32_t st = c->blk_start[b];
			uint32_t end = b + 1 < b1 ? c->blk_start[b + 1] : c->seg_n[s];
			if ((b == b0 && st != 0) || st >= end)
				return vd_fail(VD_ERR_CORRUPT, "segment %zu, block "
					       "%llu: voxels %u..%u", s,
					       (unsigned long long)b, st, end);
			if (!vbr) {
				if (c->blk_pal[b] >= c->npal ||
				    c->blk_bit[b] != bits)
					return vd_fail(VD_ERR_CORRUPT, "block %llu: "
						       "palette %u of %u, offsets "
						       "at bit %u",
						       (unsigned long long)b,
						       c->blk_pal[b], c->npal,
						       c->blk_bit[b]);
				bits += (uint64_t)(end - st) *
					width_of(c->pal_count[c->blk_pal[b]]);
			}
		}
		if (vbr)
			bits = (uint64_t)c->seg_n[s] * c->weight_bits;
		if (bits > UINT32_MAX)
			return vd_fail(VD_ERR_CORRUPT, "segment %zu: %llu bits", s,
				       (unsigned long long)bits);
		data += (bits + 7) / 8;
	}
	if (data != c->data_size)
		return vd_fail(VD_ERR_CORRUPT, "%zu bytes of %s, the blocks need "
			       "%llu", c->data_size, vbr ? "weights" : "offsets",
			       (unsigned long long)data);
	return VD_OK;
}

/* The palette method: every voxel's offset inside its block palette
 * (nothing to check where the palette fills its offsets' width). */
static int check_offsets(const struct vd_cpack *c)
{
	size_t S = (size_t)c->segments;
	for (size_t s = 0; s < S; s++)
		for (uint64_t b = c->seg_block[s]; b < c->seg_block[s + 1]; b++) {
			uint32_t cnt = c->pal_count[c->blk_pal[b]];
			unsigned wd = width_of(cnt);
			uint32_t end = b + 1 < c->seg_block[s + 1]
					       ? c->blk_start[b + 1]
					       : c->seg_n[s];
			uint64_t pos = 8 * c->seg_data[s] + c->blk_bit[b];
			if ((1ull << wd) == cnt)
				continue;
			for (uint32_t i = c->blk_start[b]; i < end; i++, pos += wd)
				if (get_bits(c->data, pos, wd) >= cnt)
					return vd_fail(VD_ERR_CORRUPT,
						       "voxel %llu: offset "
						       "outside its block "
						       "palette",
						       (unsigned long long)(
							       c->seg_first[s] + i));
		}
	return VD_OK;
}

static int read_auto_blocks(struct vd_cpack *c, uint8_t *scratch);

/* The auto method's ABLK (directory) and ADAT (blocks) sections: per
 * segment exactly ceil(n / 2^block_log) blocks, each of a known mode, its
 * bytes where the running sum of the segment's earlier blocks ends, every
 * palette index below its palette's size, the data all used. The data is
 * kept with VD_AUTO_PAD zero bytes after it for the 4-byte bit reads. */
static int read_auto(struct vd_cpack *c, const struct vd_chunk *ch)
{
	uint8_t *blk = NULL;
	size_t n;
	int err;
	if ((err = section(ch, TAG_ABLK, &blk, &n, 4, "ABLK")))
		return err;
	if (n / 4 != c->blocks) {
		free(blk);
		return vd_fail(VD_ERR_CORRUPT, "%zu blocks, CPAR says %llu",
			       n / 4, (unsigned long long)c->blocks);
	}
	c->dir = malloc((size_t)c->blocks * 8 + 8);
	if (!c->dir) {
		free(blk);
		return vd_fail(VD_ERR_NOMEM, "%llu blocks",
			       (unsigned long long)c->blocks);
	}
	for (uint64_t b = 0; b < c->blocks; b++)
		c->dir[b] = le_get32(blk + 4 * b);
	free(blk);
	if ((err = section(ch, TAG_ADAT, &c->data, &c->data_size, 0, "ADAT")))
		return err;
	uint8_t *g = realloc(c->data, c->data_size + VD_AUTO_PAD);
	if (!g)
		return vd_fail(VD_ERR_NOMEM, "colour blocks");
	c->data = g;
	memset(c->data + c->data_size, 0, VD_AUTO_PAD);
	c->bytes = CSEG_SIZE * (size_t)c->segments + 4 * (size_t)c->blocks +
		   c->data_size;
	if (c->coded && !(c->code = calloc((size_t)c->segments + 1,
					   sizeof *c->code)))
		return vd_fail(VD_ERR_NOMEM, "code tables");
	/* a coded block's bytes and what 33 bits a voxel can read past them */
#define SCRATCH_PAD ((33u << 12) / 8 + 16)
	uint8_t *scratch = c->coded ? malloc(5 + 65535 + SCRATCH_PAD +
					     3 * ((size_t)1 << c->block_log))
				    : NULL;
	if (c->coded && !scratch)
		return vd_fail(VD_ERR_NOMEM, "colour blocks");
	if (c->coded) {
		uint64_t coded = 0;
		unsigned per = ((1u << c->block_log) - 1) / VD_AUTO_RESTART;
		c->blk_restart = malloc((size_t)c->blocks * sizeof *c->blk_restart);
		for (uint64_t b = 0; b < c->blocks && c->blk_restart; b++) {
			c->blk_restart[b] = UINT32_MAX;
			if ((uint32_t)c->dir[b] >> 24 == VD_AUTO_CODED && per &&
			    coded * per < UINT32_MAX - per)
				c->blk_restart[b] = (uint32_t)(coded++ * per);
		}
		if (!c->blk_restart || (coded && !(c->restart = malloc(
				(size_t)(coded * per) * sizeof *c->restart)))) {
			free(scratch);
			return vd_fail(VD_ERR_NOMEM, "restart points of %llu coded "
				       "blocks", (unsigned long long)coded);
		}
	}
	err = read_auto_blocks(c, scratch);
	free(scratch);
	return err;
}

/* read_auto's per segment checks (scratch: a coded block's copy). */
static int read_auto_blocks(struct vd_cpack *c, uint8_t *scratch)
{
	uint64_t data = 0;
	uint32_t bs = 1u << c->block_log;
	for (size_t s = 0; s < (size_t)c->segments; s++) {
		uint64_t nb = (c->seg_n[s] + bs - 1) >> c->block_log;
		if (c->seg_block[s] + nb > c->blocks ||
		    (s + 1 < c->segments && c->seg_block[s + 1] != c->seg_block[s] + nb) ||
		    (s + 1 == c->segments && c->seg_block[s] + nb != c->blocks) ||
		    c->seg_data[s] != data)
			return vd_fail(VD_ERR_CORRUPT, "segment %zu: blocks from "
				       "%llu, data at %llu (expected %llu blocks "
				       "there, data at %llu)", s,
				       (unsigned long long)c->seg_block[s],
				       (unsigned long long)c->seg_data[s],
				       (unsigned long long)nb,
				       (unsigned long long)data);
		uint64_t at = 0;
		struct vd_auto_code *code = NULL;
		if (c->coded) {
			/* u16 T, then T bytes of code table (0 or the table's size) */
			uint32_t T = data + 2 <= c->data_size
					     ? le_get16(c->data + data) : 1;
			if ((T != 0 && T != VD_AUTO_TABLE_BYTES) ||
			    data + 2 + T > c->data_size)
				return vd_fail(VD_ERR_CORRUPT, "segment %zu: code "
					       "table of %u bytes", s, T);
			if (T) {
				code = c->code[s] = malloc(sizeof *code);
				if (!code)
					return vd_fail(VD_ERR_NOMEM, "code tables");
				if (vd_auto_code_build(code, c->data + data + 2))
					return vd_fail(VD_ERR_CORRUPT, "segment %zu: "
						       "code lengths over 11 "
						       "bits or more than the "
						       "code space", s);
			}
			at = 2 + T;
		}
		for (uint64_t b = 0; b < nb; b++) {
			uint64_t bi = c->seg_block[s] + b;
			uint32_t e = (uint32_t)c->dir[bi], m = e >> 24;
			uint32_t len = b + 1 < nb ? bs : c->seg_n[s] - (uint32_t)b * bs;
			if (m == VD_AUTO_CONST)
				continue;
			int known = (m >> 4 == VD_AUTO_PALETTE >> 4 ||
				     m >> 4 == VD_AUTO_ENDPOINTS >> 4)
					    ? (m & 15) >= 1 && (m & 15) <= 8
					    : m == VD_AUTO_QUANT || m == VD_AUTO_RAW ||
						      (m == VD_AUTO_CODED && code);
			uint64_t off = data + (e & 0xffffff);
			/* the header bytes the size depends on must be there */
			if (!known || (e & 0xffffff) != at ||
			    off + 6 > c->data_size + (m == VD_AUTO_RAW ? 6 : 0))
				return vd_fail(VD_ERR_CORRUPT, "block %llu: mode "
					       "0x%02x at byte %u of its "
					       "segment (expected %llu)",
					       (unsigned long long)bi, m,
					       e & 0xffffff, (unsigned long long)at);
			const uint8_t *d = c->data + off;
			int bad = 0;
			if (m >> 4 == VD_AUTO_PALETTE >> 4)
				bad = d[0] + 1u < 2 || width_of(d[0] + 1u) != (m & 15);
			if (m >> 4 == VD_AUTO_ENDPOINTS >> 4)
				bad = (d[0] & 15) > c->block_log || d[0] > 31;
			if (m == VD_AUTO_QUANT)
				bad = d[3] == 0 || (d[4] & 15) > 8 || d[4] >> 4 > 8 ||
				      d[5] > 8;
			size_t sz = bad ? 0 : vd_auto_block_bytes(e, d, len);
			if (bad || off + sz > c->data_size)
				return vd_fail(VD_ERR_CORRUPT, "block %llu: mode "
					       "0x%02x header %s", (unsigned long long)bi,
					       m, bad ? "invalid" : "runs past the data");
			if (m >> 4 == VD_AUTO_PALETTE >> 4) {
				unsigned k = d[0] + 1u, w = m & 15;
				for (uint32_t j = 0; j < len && (1u << w) != k; j++)
					if (vd_auto_bits(d + 1 + 3 * k, (uint64_t)j * w, w) >= k)
						return vd_fail(VD_ERR_CORRUPT, "block %llu: "
							       "index outside its %u-colour "
							       "palette", (unsigned long long)bi, k);
			}
			if (m == VD_AUTO_CODED) {
				/* decoded from a copy padded with zeros, so that a
				 * corrupt stream cannot run past the data */
				uint8_t last[3], *all = scratch + 5 + 65535 + SCRATCH_PAD;
				memset(scratch, 0, sz + SCRATCH_PAD);
				memcpy(scratch, d, sz);
				struct vd_auto_coded_state st;
				vd_auto_coded_start(scratch, &st);
				memcpy(all, scratch + 2, 3);
				int64_t bits = len < 2 ? -1
					: vd_auto_coded_resume(code, scratch, &st, len - 1, last,
							       all, c->blk_restart[bi] == UINT32_MAX
							       ? NULL : c->restart + c->blk_restart[bi]);
				if (bits < 0 || (uint64_t)(bits + 7) / 8 != sz - 5)
					return vd_fail(VD_ERR_CORRUPT, "block %llu: "
						       "coded colours %s",
						       (unsigned long long)bi,
						       bits < 0 ? "with a code, a recent "
						       "colour or a run that is not "
						       "there" : "not filling their "
						       "bytes");
			}
			c->dir[bi] = e | (uint64_t)vd_auto_layout(e, d, len) << 32;
			at += sz;
		}
		data += at;
	}
	if (data != c->data_size)
		return vd_fail(VD_ERR_CORRUPT, "%zu bytes of blocks, the blocks "
			       "need %llu", c->data_size, (unsigned long long)data);
	uint64_t windows = (c->voxels >> 18) + 2;
	c->seg_at = malloc(windows * sizeof *c->seg_at);
	if (!c->seg_at)
		return vd_fail(VD_ERR_NOMEM, "segment index");
	size_t s = 0;
	for (uint64_t p = 0; p < windows; p++) {
		while (s + 1 < c->segments && c->seg_first[s + 1] <= p << 18)
			s++;
		c->seg_at[p] = (uint32_t)s;
	}
	return VD_OK;
}

static int from_chunk(struct vd_cpack *c, const struct vd_chunk *ch)
{
	const struct vd_chunk_header *h = vd_chunk_header(ch);
	unsigned entry_bytes = 0;
	uint64_t npal = 0;
	int err;
	if (h->level_count != 1)
		return vd_fail(VD_ERR_CORRUPT, "%u counts in the header, "
			       "expected 1", h->level_count);
	if ((err = read_cpar(c, ch, &entry_bytes, &npal)))
		return err;
	if ((err = read_segments(c, ch)))
		return err;
	if (c->method == VD_CPACK_RAW)
		return read_raw(c, ch); /* raw costs its file's size (zstd) */
	if (c->method == VD_CPACK_AUTO)
		return read_auto(c, ch);
	int vbr = c->method == VD_CPACK_VBR;
	size_t bsz = vbr ? VBLK_SIZE : PBLK_SIZE;
	if ((err = read_blocks(c, ch, vbr, bsz)))
		return err;
	if ((err = section(ch, vbr ? TAG_VWGT : TAG_POFS, &c->data,
			   &c->data_size, 0, vbr ? "VWGT" : "POFS")))
		return err;
	c->bytes = 40 * (size_t)c->segments + bsz * (size_t)c->blocks +
		   c->data_size;
	if (!vbr) {
		/* the global palette and the block palettes */
		if ((err = read_palette_entries(c, ch, entry_bytes)))
			return err;
		if ((err = read_block_palettes(c, ch, npal)))
			return err;
	}
	if ((err = check_segment_blocks(c, vbr)))
		return err;
	if (!vbr) /* every offset inside its block palette */
		return check_offsets(c);
	return VD_OK;
}

static int open_common(struct vd_cpack **out, struct vd_chunk *ch, int err)
{
	*out = NULL;
	if (err)
		return err;
	struct vd_cpack *c = calloc(1, sizeof *c);
	if (!c) {
		vd_chunk_free(ch);
		return vd_fail(VD_ERR_NOMEM, "colour reader");
	}
	err = from_chunk(c, ch);
	vd_chunk_free(ch);
	if (err) {
		vd_cpack_free(c);
		return err;
	}
	*out = c;
	return VD_OK;
}

int vd_cpack_open(struct vd_cpack **out, const char *path)
{
	struct vd_chunk *ch = NULL;
	int err = vd_chunk_open(&ch, path, VD_KIND_CPACK);
	return open_common(out, ch, err);
}

int vd_cpack_open_mem(struct vd_cpack **out, const void *data, size_t size)
{
	struct vd_chunk *ch = NULL;
	int err = vd_chunk_open_mem(&ch, data, size, VD_KIND_CPACK);
	return open_common(out, ch, err);
}

int vd_cpack_method(const struct vd_cpack *c) { return c->method; }
int vd_cpack_cell_level(const struct vd_cpack *c) { return c->cell_level; }
uint64_t vd_cpack_voxels(const struct vd_cpack *c) { return c->voxels; }
uint64_t vd_cpack_bytes(const struct vd_cpack *c) { return c->bytes; }
uint64_t vd_cpack_blocks(const struct vd_cpack *c) { return c->blocks; }

/* Colour of voxel i of segment s, block b. */
static void colour_in(const struct vd_cpack *c, size_t s, uint64_t b,
		      uint32_t i, uint8_t rgb[3])
{
	if (c->method == VD_CPACK_VBR) {
		uint64_t pos = 8 * c->seg_data[s] + (uint64_t)i * c->weight_bits;
		unsigned w = get_bits(c->data, pos, (unsigned)c->weight_bits);
		vd_vbr_interp(c->c0[b], c->c1[b], w, c->weight_bits, rgb);
		return;
	}
	uint32_t p = c->blk_pal[b], cnt = c->pal_count[p];
	unsigned wd = width_of(cnt);
	uint64_t pos = 8 * c->seg_data[s] + c->blk_bit[b] +
		       (uint64_t)(i - c->blk_start[b]) * wd;
	uint32_t g = c->ent[c->pal_first[p] + get_bits(c->data, pos, wd)];
	memcpy(rgb, c->glb + 3 * (size_t)g, 3);
}

/* The segment of voxel i among segments lo..hi-1: the last whose first
 * voxel is <= i (the caller knows it is in that range). */
static size_t segment_in(const struct vd_cpack *c, uint64_t i, size_t lo,
			 size_t hi)
{
	while (hi - lo > 1) {
		size_t mid = lo + (hi - lo) / 2;
		if (c->seg_first[mid] <= i)
			lo = mid;
		else
			hi = mid;
	}
	return lo;
}

/* The auto method's lookup: the segment, then the block is the index
 * shifted (blocks have a fixed length), then one entry and its block. */
static void auto_colour(const struct vd_cpack *c, uint64_t i, uint8_t rgb[3])
{
	uint64_t p = i >> 18;
	size_t s = segment_in(c, i, c->seg_at[p], c->seg_at[p + 1] + 1);
	uint32_t k = (uint32_t)(i - c->seg_first[s]);
	uint64_t x = c->dir[c->seg_block[s] + (k >> c->block_log)];
	uint32_t e = (uint32_t)x;
	uint32_t first = k >> c->block_log << c->block_log;
	if (e >> 24 == VD_AUTO_CODED) {
		/* from the restart point at or before the voxel: one past it
		 * means a run that covers the voxel (the step before it ended
		 * before the point), so its colour is the point's */
		const uint8_t *d = c->data + c->seg_data[s] + (e & 0xffffff);
		uint32_t j = k - first, q = j / VD_AUTO_RESTART;
		uint32_t r = c->blk_restart[c->seg_block[s] + (k >> c->block_log)];
		if (q == 0 || r == UINT32_MAX) {
			vd_auto_coded_decode(c->code[s], d, j, rgb, NULL);
			return;
		}
		const struct vd_auto_coded_state *st = c->restart + r + q - 1;
		if (st->i > j) {
			rgb[0] = (uint8_t)st->cur;
			rgb[1] = (uint8_t)(st->cur >> 8);
			rgb[2] = (uint8_t)(st->cur >> 16);
			return;
		}
		vd_auto_coded_resume(c->code[s], d, st, j, rgb, NULL, NULL);
		return;
	}
	vd_auto_decode_laid(e, (uint32_t)(x >> 32), c->data + c->seg_data[s] +
			    (e & 0xffffff), k - first, rgb);
}

int vd_cpack_colour(const struct vd_cpack *c, uint64_t i, uint8_t rgb[3])
{
	if (i >= c->voxels)
		return vd_fail(VD_ERR_RANGE, "colour %llu of %llu",
			       (unsigned long long)i,
			       (unsigned long long)c->voxels);
	if (c->method == VD_CPACK_RAW) {
		memcpy(rgb, c->data + 3 * i, 3);
		return VD_OK;
	}
	if (c->method == VD_CPACK_AUTO) {
		auto_colour(c, i, rgb);
		return VD_OK;
	}
	size_t lo = segment_in(c, i, 0, (size_t)c->segments);
	uint32_t k = (uint32_t)(i - c->seg_first[lo]);
	uint64_t bl = c->seg_block[lo], bh = c->seg_block[lo + 1];
	while (bh - bl > 1) { /* the paper's binary search over headers */
		uint64_t mid = bl + (bh - bl) / 2;
		if (c->blk_start[mid] <= k)
			bl = mid;
		else
			bh = mid;
	}
	colour_in(c, lo, bl, k, rgb);
	return VD_OK;
}

/* ---------------------------------------------- batched lookups (auto) */

/* vd_cpack_colour_many's pipeline: a lookup goes through three stages,
 * LK_D lookups apart, each of which prefetches what the next one reads:
 * (1) its segment and block, prefetch the directory entry; (2) the entry
 * and the block's layout, prefetch the header and the voxel's bits (and
 * its part's endpoints; a coded block's restart point); (3) decode. A
 * single lookup waits for the entry's miss, then the data's; in the
 * batch, 2 LK_D lookups are in flight at once, so the misses overlap.
 * LK_D: enough to cover a miss to memory with the few ns a stage costs. */
#ifndef LK_D
#define LK_D 16
#endif
#define LK_RING 64 /* > 2 LK_D, a power of two */
#define LK_CHUNK (1u << 20) /* coded lookups sorted at once, at most */

struct lk {
	const uint8_t *d;   /* the block's bytes */
	uint32_t e, lay;    /* directory entry, layout */
	uint32_t j;         /* voxel in the block */
	uint32_t s;         /* segment */
	uint64_t bi;        /* block */
};

static inline void lk_locate(const struct vd_cpack *c, uint64_t i,
			     struct lk *l)
{
	uint64_t p = i >> 18;
	size_t s = segment_in(c, i, c->seg_at[p], c->seg_at[p + 1] + 1);
	uint32_t k = (uint32_t)(i - c->seg_first[s]);
	l->s = (uint32_t)s;
	l->bi = c->seg_block[s] + (k >> c->block_log);
	l->j = k & ((1u << c->block_log) - 1);
}

/* Colours of the coded lookups keys[0..m) (voxel << 20 | position in
 * out) into out: sorted by voxel, so each block touched is decoded once,
 * from the restart point at or before its first voxel asked, or from
 * where the previous voxel asked left the decoder when that is later. */
static void coded_sorted(const struct vd_cpack *c, uint64_t *keys,
			 uint64_t *tmp, size_t m, uint8_t *out)
{
	/* LSD radix sort, 11 bits a pass, over the bits the keys use */
	unsigned bits = 20;
	while (bits < 64 && c->voxels > 1ull << (bits - 20))
		bits++;
	for (unsigned sh = 0; sh < bits; sh += 11) {
		size_t cnt[2048] = {0};
		for (size_t q = 0; q < m; q++)
			cnt[keys[q] >> sh & 2047]++;
		size_t at = 0;
		for (unsigned v = 0; v < 2048; v++) {
			size_t t = cnt[v];
			cnt[v] = at;
			at += t;
		}
		for (size_t q = 0; q < m; q++)
			tmp[cnt[keys[q] >> sh & 2047]++] = keys[q];
		uint64_t *x = keys;
		keys = tmp;
		tmp = x;
	}
	struct vd_auto_coded_state st;
	uint64_t cur_bi = UINT64_MAX;
	for (size_t q = 0; q < m; q++) {
		struct lk l;
		lk_locate(c, keys[q] >> 20, &l);
		uint8_t *rgb = out + 3 * (keys[q] & (LK_CHUNK - 1));
		uint32_t e = (uint32_t)c->dir[l.bi], j = l.j;
		const uint8_t *d = c->data + c->seg_data[l.s] + (e & 0xffffff);
		if (l.bi != cur_bi) {
			vd_auto_coded_start(d, &st);
			cur_bi = l.bi;
		}
		uint32_t r = c->blk_restart[l.bi], p = j / VD_AUTO_RESTART;
		if (p && r != UINT32_MAX && c->restart[r + p - 1].i > st.i)
			st = c->restart[r + p - 1];
		if (j == 0 || st.i > j) {
			/* voxel 0, or inside the step that ended at st (a
			 * run: the voxels asked come in order) */
			uint32_t v = j == 0 ? (uint32_t)d[2] | (uint32_t)d[3] << 8 |
						      (uint32_t)d[4] << 16 : st.cur;
			rgb[0] = (uint8_t)v;
			rgb[1] = (uint8_t)(v >> 8);
			rgb[2] = (uint8_t)(v >> 16);
			continue;
		}
		vd_auto_coded_run(c->code[l.s], d, &st, j, rgb, NULL, NULL);
	}
}

static int auto_many(const struct vd_cpack *c, const uint64_t *idx,
		     size_t n, uint8_t *rgb)
{
	struct lk r[LK_RING];
	uint64_t *keys = NULL, *tmp = NULL;
	size_t m = 0;
	/* coded lookups are sorted only where the keys hold the voxel */
	int sort = c->coded && c->blk_restart && c->voxels <= 1ull << 44;
	if (sort) {
		size_t cap = n < LK_CHUNK ? n : LK_CHUNK;
		keys = malloc(cap * sizeof *keys);
		tmp = malloc(cap * sizeof *tmp);
		if (!keys || !tmp) {
			free(keys);
			free(tmp);
			return vd_fail(VD_ERR_NOMEM, "%zu colour lookups", cap);
		}
	}
	for (size_t base = 0; base < n; base += LK_CHUNK) {
		size_t cn = n - base < LK_CHUNK ? n - base : LK_CHUNK;
		const uint64_t *ix = idx + base;
		uint8_t *out = rgb + 3 * base;
		m = 0;
		for (size_t t = 0; t < cn + 2 * LK_D; t++) {
			if (t < cn) {
				struct lk *l = &r[t & (LK_RING - 1)];
				lk_locate(c, ix[t], l);
				__builtin_prefetch(&c->dir[l->bi]);
			}
			if (t >= LK_D && t - LK_D < cn) {
				struct lk *l = &r[(t - LK_D) & (LK_RING - 1)];
				uint64_t x = c->dir[l->bi];
				l->e = (uint32_t)x;
				l->lay = (uint32_t)(x >> 32);
				l->d = c->data + c->seg_data[l->s] + (l->e & 0xffffff);
				unsigned mode = l->e >> 24;
				if (mode == VD_AUTO_CODED) {
					uint32_t rp = c->blk_restart[l->bi];
					uint32_t p = l->j / VD_AUTO_RESTART;
					if (p && rp != UINT32_MAX)
						__builtin_prefetch(&c->restart[rp + p - 1]);
				} else if (mode != VD_AUTO_CONST) {
					/* the header, the bits, and for the endpoints
					 * mode the part's pair (else the header again) */
					unsigned len = l->lay >> 21 & 15;
					unsigned esz = l->lay >> 25 & 1 ? 4 : 6;
					__builtin_prefetch(l->d);
					__builtin_prefetch(l->d + (l->lay & 0xffff) +
							   (((uint64_t)l->j * (l->lay >> 16 & 31)) >> 3));
					__builtin_prefetch(mode >> 4 == VD_AUTO_ENDPOINTS >> 4
							   ? l->d + 1 + esz * (l->j >> len) : l->d);
				}
			}
			if (t >= 2 * LK_D) {
				size_t q = t - 2 * LK_D;
				struct lk *l = &r[q & (LK_RING - 1)];
				if (l->e >> 24 != VD_AUTO_CODED)
					vd_auto_decode_laid(l->e, l->lay, l->d, l->j, out + 3 * q);
				else if (sort)
					keys[m++] = ix[q] << 20 | q;
				else
					auto_colour(c, ix[q], out + 3 * q);
			}
		}
		if (m)
			coded_sorted(c, keys, tmp, m, out);
	}
	free(keys);
	free(tmp);
	return VD_OK;
}

int vd_cpack_colour_many(const struct vd_cpack *c, const uint64_t *idx,
			 size_t n, uint8_t *rgb)
{
	for (size_t q = 0; q < n; q++)
		if (idx[q] >= c->voxels)
			return vd_fail(VD_ERR_RANGE, "colour %llu of %llu (lookup "
				       "%zu of %zu)", (unsigned long long)idx[q],
				       (unsigned long long)c->voxels, q, n);
	if (c->method == VD_CPACK_AUTO)
		return auto_many(c, idx, n, rgb);
	for (size_t q = 0; q < n; q++)
		vd_cpack_colour(c, idx[q], rgb + 3 * q);
	return VD_OK;
}

int vd_cpack_decode(const struct vd_cpack *c, uint64_t first, uint64_t n,
		    uint8_t *rgb)
{
	if (first > c->voxels || n > c->voxels - first)
		return vd_fail(VD_ERR_RANGE, "colours %llu..+%llu of %llu",
			       (unsigned long long)first, (unsigned long long)n,
			       (unsigned long long)c->voxels);
	if (!n)
		return VD_OK;
	if (c->method == VD_CPACK_RAW) {
		memcpy(rgb, c->data + 3 * first, 3 * n);
		return VD_OK;
	}
	if (c->method == VD_CPACK_AUTO) {
		/* a coded block decodes from its start: decode it whole once
		 * for the voxels of the range it holds */
		uint8_t all[3 << 12];
		for (uint64_t k = 0; k < n;) {
			uint64_t i = first + k, p = i >> 18;
			size_t s = segment_in(c, i, c->seg_at[p], c->seg_at[p + 1] + 1);
			uint32_t j = (uint32_t)(i - c->seg_first[s]);
			uint32_t e = (uint32_t)c->dir[c->seg_block[s] + (j >> c->block_log)];
			uint32_t b0 = j >> c->block_log << c->block_log;
			uint32_t len = c->seg_n[s] - b0 < (1u << c->block_log)
					       ? c->seg_n[s] - b0 : 1u << c->block_log;
			if (e >> 24 != VD_AUTO_CODED) {
				auto_colour(c, i, rgb + 3 * k++);
				continue;
			}
			uint8_t last[3];
			vd_auto_coded_decode(c->code[s], c->data + c->seg_data[s] +
						 (e & 0xffffff), len - 1, last, all);
			uint64_t m = b0 + len - j < n - k ? b0 + len - j : n - k;
			memcpy(rgb + 3 * k, all + 3 * (size_t)(j - b0), 3 * m);
			k += m;
		}
		return VD_OK;
	}
	/* walk blocks sequentially from the first voxel's */
	size_t s = segment_in(c, first, 0, (size_t)c->segments);
	uint64_t done = 0;
	while (done < n) {
		uint32_t k = (uint32_t)(first + done - c->seg_first[s]);
		uint64_t b = c->seg_block[s];
		while (b + 1 < c->seg_block[s + 1] && c->blk_start[b + 1] <= k)
			b++;
		for (; b < c->seg_block[s + 1] && done < n; b++) {
			uint32_t end = b + 1 < c->seg_block[s + 1]
					       ? c->blk_start[b + 1]
					       : c->seg_n[s];
			for (; k < end && done < n; k++, done++)
				colour_in(c, s, b, k, rgb + 3 * done);
		}
		s++;
	}
	return VD_OK;
}
