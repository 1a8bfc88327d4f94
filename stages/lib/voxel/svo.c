/* svo.c - SVO chunks: the non-empty 4x4x4 bricks of one cell, Morton order.
 *
 * Section BRKS (schemas/chunk-format.md): uint64 count, then count key
 * deltas (the first key, then key[i] - key[i-1]), then count masks, all
 * little-endian uint64. Deltas because sorted keys differ little, which
 * zstd then squeezes to about a byte per brick.
 */
#include "voxdag.h"
#include "util_internal.h"
#include "le.h"
#include "voxel/voxel_internal.h"

#include <stdlib.h>
#include <string.h>
#include <xxhash.h>

uint64_t vd_svo_digest(const uint64_t *keys, const uint64_t *masks, size_t n)
{
	return vd_svo_digest_stride(keys, masks, 1, n);
}

uint64_t vd_svo_digest_stride(const uint64_t *keys, const uint64_t *masks,
			      size_t stride, size_t n)
{
	/* Defined on little-endian (key, mask) pairs rather than on the BRKS
	 * section's bytes, so a writer that streams its bricks and a reader
	 * that holds them as arrays compute it alike. */
	XXH3_state_t *s = XXH3_createState();
	if (!s)
		return 0;
	XXH3_64bits_reset(s);
	uint8_t buf[16 * 256];
	size_t k = 0;
	for (size_t i = 0; i < n; i++) {
		le_put64(buf + 16 * k, keys[i * stride]);
		le_put64(buf + 16 * k + 8, masks[i * stride]);
		if (++k == 256) {
			XXH3_64bits_update(s, buf, sizeof buf);
			k = 0;
		}
	}
	XXH3_64bits_update(s, buf, 16 * k);
	uint64_t h = XXH3_64bits_digest(s);
	XXH3_freeState(s);
	return h;
}

void vd_svo_release(struct vd_svo *svo)
{
	free(svo->keys);
	free(svo->masks);
	svo->keys = svo->masks = NULL;
	svo->count = 0;
}

/* Bits of a brick key below the cell's prefix: the cell at chunk_level
 * spans levels chunk_level..L-2 of brick keys, 3 bits a level. */
static int brick_levels(int levels)
{
	return levels >= 2 ? levels - 2 : 0;
}

void vd_svo_count_levels(const struct vd_svo *svo, uint64_t *counts)
{
	for (int l = svo->chunk_level; l <= svo->levels; l++)
		counts[l - svo->chunk_level] = 0;
	for (size_t i = 0; i < svo->count; i++)
		vd_svo_count_brick(counts, svo->levels, svo->chunk_level, i == 0,
				   i ? svo->keys[i - 1] : 0, svo->keys[i],
				   svo->masks[i]);
}

/* An SVO chunk's header: its node counts zero, for the writer to fill. */
static void svo_header(struct vd_chunk_header *h, int levels, int chunk_level,
		       uint64_t cell, const struct vd_transform *t)
{
	memset(h, 0, sizeof *h);
	h->kind = VD_KIND_SVO;
	h->levels = (uint32_t)levels;
	h->chunk_level = (uint32_t)chunk_level;
	h->cell_morton = cell;
	h->transform = *t;
	h->level_count = (uint32_t)(levels - chunk_level + 1);
}

int vd_svo_write(const char *path, int levels, int chunk_level, uint64_t cell,
		 const struct vd_transform *t, const char *provenance, size_t n,
		 const uint64_t *keys, const uint64_t *masks, size_t stride,
		 uint64_t *counts)
{
	struct vd_chunk_header h;
	svo_header(&h, levels, chunk_level, cell, t);
	for (size_t i = 0; i < n; i++)
		vd_svo_count_brick(h.level_nodes, levels, chunk_level, i == 0,
				   i ? keys[(i - 1) * stride] : 0, keys[i * stride],
				   masks[i * stride]);
	if (counts)
		memcpy(counts, h.level_nodes, h.level_count * sizeof *counts);

	struct vd_chunk_writer *w;
	int err = vd_chunk_writer_open(&w, path, &h, provenance);
	if (err)
		return err;
	enum { BATCH = 4096 };
	uint8_t buf[8 * BATCH];
	le_put64(buf, n);
	err = vd_chunk_writer_begin(w, VD_TAG_BRKS, 0);
	if (!err)
		err = vd_chunk_writer_write(w, buf, 8);
	for (int pass = 0; pass < 2 && !err; pass++) {
		for (size_t i = 0; i < n && !err; i += BATCH) {
			size_t m = n - i < BATCH ? n - i : BATCH;
			for (size_t j = 0; j < m; j++) {
				size_t k = (i + j) * stride;
				uint64_t v = pass ? masks[k]
					   : i + j ? keys[k] - keys[k - stride]
						   : keys[0];
				le_put64(buf + 8 * j, v);
			}
			err = vd_chunk_writer_write(w, buf, 8 * m);
		}
	}
	if (!err)
		err = vd_chunk_writer_end(w);
	if (err) {
		vd_chunk_writer_abort(w);
		return err;
	}
	return vd_chunk_writer_commit(w);
}

struct vd_svo_writer {
	struct vd_chunk_writer *w;
	int levels, chunk_level;
	uint64_t n, got, prev;
	int pass;                  /* 0 keys, 1 masks */
	uint64_t counts[VD_MAX_LEVELS + 1];
	uint32_t level_count;
	XXH3_state_t *dig;
};

int vd_svo_writer_open(struct vd_svo_writer **out, const char *path,
		       int levels, int chunk_level, uint64_t cell_morton,
		       const struct vd_transform *t, const char *provenance,
		       uint64_t n)
{
	*out = NULL;
	struct vd_svo_writer *s = calloc(1, sizeof *s);
	if (!s || !(s->dig = XXH3_createState())) {
		free(s);
		return vd_fail(VD_ERR_NOMEM, "SVO writer");
	}
	XXH3_64bits_reset(s->dig);
	s->levels = levels;
	s->chunk_level = chunk_level;
	s->n = n;
	struct vd_chunk_header h;
	svo_header(&h, levels, chunk_level, cell_morton, t);
	s->level_count = h.level_count;
	uint8_t buf[8];
	le_put64(buf, n);
	int err = vd_chunk_writer_open(&s->w, path, &h, provenance);
	if (!err)
		err = vd_chunk_writer_begin(s->w, VD_TAG_BRKS, 0);
	if (!err)
		err = vd_chunk_writer_write(s->w, buf, 8);
	if (err) {
		vd_svo_writer_abort(s);
		return err;
	}
	*out = s;
	return VD_OK;
}

int vd_svo_writer_keys(struct vd_svo_writer *s, const uint64_t *keys,
		       size_t m)
{
	enum { BATCH = 4096 };
	uint8_t buf[8 * BATCH];
	if (s->pass != 0 || m > s->n - s->got)
		return vd_fail(VD_ERR_ARG, "more than %llu brick keys",
			       (unsigned long long)s->n);
	for (size_t i = 0; i < m;) {
		size_t k = 0;
		for (; k < BATCH && i < m; k++, i++, s->got++) {
			if (s->got && keys[i] <= s->prev)
				return vd_fail(VD_ERR_ARG, "brick keys out of "
					       "order");
			le_put64(buf + 8 * k, s->got ? keys[i] - s->prev : keys[i]);
			s->prev = keys[i];
		}
		int err = vd_chunk_writer_write(s->w, buf, 8 * k);
		if (err)
			return err;
	}
	return VD_OK;
}

int vd_svo_writer_masks(struct vd_svo_writer *s, const uint64_t *keys,
			const uint64_t *masks, size_t m)
{
	enum { BATCH = 256 };
	uint8_t buf[8 * BATCH], pair[16 * BATCH];
	if (s->pass == 0) {
		if (s->got != s->n)
			return vd_fail(VD_ERR_ARG, "%llu brick keys of %llu",
				       (unsigned long long)s->got,
				       (unsigned long long)s->n);
		s->pass = 1;
		s->got = 0;
	}
	if (m > s->n - s->got)
		return vd_fail(VD_ERR_ARG, "more than %llu brick masks",
			       (unsigned long long)s->n);
	for (size_t i = 0; i < m;) {
		size_t k = 0;
		for (; k < BATCH && i < m; k++, i++, s->got++) {
			if (!masks[i])
				return vd_fail(VD_ERR_ARG, "an empty brick");
			vd_svo_count_brick(s->counts, s->levels, s->chunk_level,
					   s->got == 0, s->prev, keys[i],
					   masks[i]);
			s->prev = keys[i];
			le_put64(buf + 8 * k, masks[i]);
			le_put64(pair + 16 * k, keys[i]);
			le_put64(pair + 16 * k + 8, masks[i]);
		}
		XXH3_64bits_update(s->dig, pair, 16 * k);
		int err = vd_chunk_writer_write(s->w, buf, 8 * k);
		if (err)
			return err;
	}
	return VD_OK;
}

int vd_svo_writer_commit(struct vd_svo_writer *s, uint64_t *digest)
{
	int err = VD_OK;
	if ((s->pass == 0 && s->n) || s->got != s->n)
		err = vd_fail(VD_ERR_ARG, "%llu bricks of %llu given",
			      (unsigned long long)s->got,
			      (unsigned long long)s->n);
	if (!err)
		err = vd_chunk_writer_end(s->w);
	if (!err)
		err = vd_chunk_writer_set_counts(s->w, s->counts,
						 s->level_count);
	if (err) {
		vd_svo_writer_abort(s);
		return err;
	}
	if (digest)
		*digest = XXH3_64bits_digest(s->dig);
	err = vd_chunk_writer_commit(s->w);
	s->w = NULL;
	vd_svo_writer_abort(s);
	return err;
}

void vd_svo_writer_abort(struct vd_svo_writer *s)
{
	if (!s)
		return;
	vd_chunk_writer_abort(s->w);
	XXH3_freeState(s->dig);
	free(s);
}

int vd_svo_save(const struct vd_svo *svo, const struct vd_transform *t,
		const char *path, const char *provenance)
{
	return vd_svo_write(path, svo->levels, svo->chunk_level, svo->cell_morton,
			    t, provenance, svo->count, svo->keys, svo->masks, 1,
			    NULL);
}

/* BRKS decoded in parts on several threads: pass 0 sums each part's
 * deltas (the first part's first is the first key), pass 1 makes the keys
 * from the part's first (the sums before it) and checks them, exactly as
 * one pass in order would; the first error in brick order wins. */
enum { PARSE_PARTS = 16 };

struct parse_job {
	const uint8_t *p; /* the deltas, then the masks */
	uint64_t n;
	int bl, chunk_level, levels;
	uint64_t cell;
	uint64_t *keys, *masks;
	uint64_t sum[PARSE_PARTS], base[PARSE_PARTS];
	int errs[PARSE_PARTS];
	char details[PARSE_PARTS][128];
	int pass;
	uint64_t counts[PARSE_PARTS][VD_MAX_LEVELS + 1];
};

static void parse_part(void *ctx, size_t k, int worker)
{
	(void)worker;
	struct parse_job *pj = ctx;
	int parts = pj->n >= PARSE_PARTS * 4096 ? PARSE_PARTS : 1;
	uint64_t lo = pj->n * k / (uint64_t)parts;
	uint64_t hi = pj->n * (k + 1) / (uint64_t)parts;
	const uint8_t *p = pj->p;
	if (pj->pass == 0) {
		uint64_t s = 0;
		for (uint64_t i = lo; i < hi; i++)
			s += le_get64(p + 8 * i);
		pj->sum[k] = s;
		return;
	}
	int below = 3 * (pj->bl - pj->chunk_level);
	uint64_t key = pj->base[k];
	int err = VD_OK;
	for (uint64_t i = lo; i < hi && !err; i++) {
		uint64_t d = le_get64(p + 8 * i);
		if (i > 0 && (d == 0 || key + d < key))
			err = vd_fail(VD_ERR_CORRUPT, "brick %llu out of order",
				      (unsigned long long)i);
		key = i ? key + d : d;
		uint64_t m = le_get64(p + 8 * pj->n + 8 * i);
		if (m == 0)
			err = vd_fail(VD_ERR_CORRUPT, "brick %llu is empty",
				      (unsigned long long)i);
		if (key >> below != pj->cell || key >> 3 * pj->bl != 0)
			err = vd_fail(VD_ERR_CORRUPT, "brick %llu lies outside "
				      "cell %llx", (unsigned long long)i,
				      (unsigned long long)pj->cell);
		pj->keys[i] = key;
		pj->masks[i] = m;
		/* the previous key: the part's base at its first brick */
		if (!err)
			vd_svo_count_brick(pj->counts[k], pj->levels,
					   pj->chunk_level, i == 0,
					   i == lo ? pj->base[k] : pj->keys[i - 1],
					   key, m);
	}
	pj->errs[k] = err;
	if (err)
		snprintf(pj->details[k], sizeof pj->details[k], "%s",
			 vd_error_detail());
}

int vd_svo_from_chunk(struct vd_svo *svo, const struct vd_chunk *c)
{
	return vd_svo_from_chunk_mt(svo, c, 1);
}

int vd_svo_from_chunk_mt(struct vd_svo *svo, const struct vd_chunk *c,
			 int threads)
{
	memset(svo, 0, sizeof *svo);
	const struct vd_chunk_header *h = vd_chunk_header(c);
	if (h->kind != VD_KIND_SVO)
		return vd_fail(VD_ERR_WRONG_KIND, "a %s chunk, expected svo",
			       vd_chunk_kind_name(h->kind));
	svo->levels = (int)h->levels;
	svo->chunk_level = (int)h->chunk_level;
	svo->cell_morton = h->cell_morton;
	if (h->level_count != h->levels - h->chunk_level + 1)
		return vd_fail(VD_ERR_CORRUPT, "%u level counts for levels "
			       "%u..%u", h->level_count, h->chunk_level,
			       h->levels);
	int bl = brick_levels(svo->levels);
	if (svo->chunk_level > bl && svo->levels >= 2)
		return vd_fail(VD_ERR_CORRUPT, "chunk level %d below the brick "
			       "level %d", svo->chunk_level, bl);
	void *data;
	size_t size;
	int err = vd_chunk_read_section_mt(c, VD_TAG_BRKS, &data, &size,
					   threads);
	if (err)
		return err;
	const uint8_t *p = data;
	uint64_t n = size >= 8 ? le_get64(p) : 0;
	if (size < 8 || (size - 8) / 16 != n || (size - 8) % 16) {
		free(data);
		return vd_fail(VD_ERR_CORRUPT, "brick section of %zu bytes", size);
	}
	svo->keys = malloc(n ? 8 * n : 1);
	svo->masks = malloc(n ? 8 * n : 1);
	if (!svo->keys || !svo->masks) {
		free(data);
		vd_svo_release(svo);
		return vd_fail(VD_ERR_NOMEM, "%llu bricks", (unsigned long long)n);
	}
	svo->count = n;
	struct parse_job pj = {.p = p + 8, .n = n, .bl = bl,
			       .chunk_level = svo->chunk_level,
			       .levels = svo->levels, .cell = svo->cell_morton,
			       .keys = svo->keys, .masks = svo->masks};
	int parts = n >= PARSE_PARTS * 4096 ? PARSE_PARTS : 1;
	/* the deltas' sums per part, then each part's keys from its first */
	pj.pass = 0;
	err = vd_parallel_for((size_t)parts, threads, parse_part, &pj);
	uint64_t base = 0;
	for (int k = 0; k < parts && !err; k++) {
		if (pj.errs[k])
			err = vd_fail(pj.errs[k], "%s", pj.details[k]);
		uint64_t sum = pj.sum[k];
		pj.base[k] = base;
		base += sum;
	}
	if (!err) {
		pj.pass = 1;
		err = vd_parallel_for((size_t)parts, threads, parse_part, &pj);
		for (int k = 0; k < parts && !err; k++)
			if (pj.errs[k])
				err = vd_fail(pj.errs[k], "%s", pj.details[k]);
	}
	free(data);
	if (!err && svo->levels < 2) {
		/* a 2^L grid with L < 2 uses only the voxels < 2^L per axis */
		uint64_t allowed = svo->levels == 1 ? 0xff : 0x1;
		if (n > 1 || (n == 1 && (svo->masks[0] & ~allowed)))
			err = vd_fail(VD_ERR_CORRUPT, "voxels outside a 2^%d grid",
				      svo->levels);
	}
	if (!err) {
		uint64_t counts[VD_MAX_LEVELS + 1] = {0};
		for (int k = 0; k < PARSE_PARTS; k++)
			for (uint32_t l = 0; l < h->level_count; l++)
				counts[l] += pj.counts[k][l];
		for (uint32_t l = 0; l < h->level_count && !err; l++)
			if (counts[l] != h->level_nodes[l])
				err = vd_fail(VD_ERR_CORRUPT, "level %u has %llu "
					      "nodes, header says %llu",
					      h->chunk_level + l,
					      (unsigned long long)counts[l],
					      (unsigned long long)h->level_nodes[l]);
	}
	if (err)
		vd_svo_release(svo);
	return err;
}

int vd_svo_load(struct vd_svo *svo, struct vd_chunk_header *h,
		const char *path)
{
	memset(svo, 0, sizeof *svo);
	struct vd_chunk *c;
	int err = vd_chunk_open(&c, path, VD_KIND_SVO);
	if (err)
		return err;
	if (h)
		*h = *vd_chunk_header(c);
	err = vd_svo_from_chunk(svo, c);
	vd_chunk_free(c);
	return err;
}
