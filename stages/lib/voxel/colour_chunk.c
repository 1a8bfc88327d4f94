/* Colour chunks: the sRGB colours of one cell's voxels in the cell's
 * depth-first (Morton) order, beside the cell's SVO chunk. The format is in
 * schemas/chunk-format.md ("Colour chunks"); colours never enter the DAG
 * (DESIGN.md, colour paper §3), so the SVO chunk's bytes do not change when
 * colours are present. */
#include "voxdag.h"
#include "le.h"

#include <stdlib.h>
#include <string.h>

struct whole {
	const uint8_t *rgb;
	uint64_t voxels;
	int given;
};

static int next_whole(void *ctx, const uint8_t **rgb, size_t *n)
{
	struct whole *w = ctx;
	*rgb = w->rgb;
	*n = w->given ? 0 : (size_t)w->voxels;
	w->given = 1;
	return VD_OK;
}

int vd_colours_save(const char *path, const struct vd_chunk_header *svo_h,
		    uint64_t svo_digest, const uint8_t *rgb, uint64_t voxels,
		    const char *provenance)
{
	struct whole w = {rgb, voxels, 0};
	return vd_colours_write(path, svo_h, svo_digest, voxels, next_whole, &w,
				provenance);
}

int vd_colours_write(const char *path, const struct vd_chunk_header *svo_h,
		     uint64_t svo_digest, uint64_t voxels,
		     int (*next)(void *ctx, const uint8_t **rgb, size_t *n),
		     void *ctx, const char *provenance)
{
	if (svo_h->kind != VD_KIND_SVO || svo_h->level_count == 0)
		return vd_fail(VD_ERR_ARG, "colours need the header of an svo "
			       "chunk");
	uint64_t want = svo_h->level_nodes[svo_h->level_count - 1];
	if (voxels != want)
		return vd_fail(VD_ERR_MISMATCH, "%llu colours for %llu voxels",
			       (unsigned long long)voxels,
			       (unsigned long long)want);
	struct vd_chunk_header h = *svo_h;
	h.kind = VD_KIND_COLOURS;
	struct vd_chunk_writer *w;
	int err = vd_chunk_writer_open(&w, path, &h, provenance);
	if (err)
		return err;
	uint8_t dig[8];
	le_put64(dig, svo_digest);
	err = vd_chunk_writer_section(w, VD_TAG_BDIG, dig, sizeof dig);
	if (!err)
		err = vd_chunk_writer_begin(w, VD_TAG_COLS, 0);
	uint64_t got = 0;
	while (!err) {
		const uint8_t *rgb;
		size_t n = 0;
		err = next(ctx, &rgb, &n);
		if (err || n == 0)
			break;
		if (n > voxels - got) {
			err = vd_fail(VD_ERR_MISMATCH, "more than %llu colours "
				      "for %llu voxels",
				      (unsigned long long)(got + n),
				      (unsigned long long)voxels);
			break;
		}
		got += n;
		err = vd_chunk_writer_write(w, rgb, 3 * n);
	}
	if (!err && got != voxels)
		err = vd_fail(VD_ERR_MISMATCH, "%llu colours for %llu voxels",
			      (unsigned long long)got, (unsigned long long)voxels);
	if (!err)
		err = vd_chunk_writer_end(w);
	if (err) {
		vd_chunk_writer_abort(w);
		return err;
	}
	return vd_chunk_writer_commit(w);
}

int vd_colours_from_chunk(struct vd_colours *c, const struct vd_chunk *ch)
{
	memset(c, 0, sizeof *c);
	const struct vd_chunk_header *h = vd_chunk_header(ch);
	if (h->kind != VD_KIND_COLOURS)
		return vd_fail(VD_ERR_WRONG_KIND, "a %s chunk, expected colours",
			       vd_chunk_kind_name(h->kind));
	if (h->level_count == 0 ||
	    h->level_count != h->levels - h->chunk_level + 1)
		return vd_fail(VD_ERR_CORRUPT, "%u level counts for levels "
			       "%u..%u", h->level_count, h->chunk_level,
			       h->levels);
	void *dig, *rgb;
	size_t dsize, size;
	int err = vd_chunk_read_section(ch, VD_TAG_BDIG, &dig, &dsize);
	if (err)
		return err;
	if (dsize != 8) {
		free(dig);
		return vd_fail(VD_ERR_CORRUPT, "brick digest of %zu bytes",
			       dsize);
	}
	c->svo_digest = le_get64(dig);
	free(dig);
	err = vd_chunk_read_section(ch, VD_TAG_COLS, &rgb, &size);
	if (err)
		return err;
	uint64_t voxels = h->level_nodes[h->level_count - 1];
	if (size != 3 * voxels) {
		free(rgb);
		return vd_fail(VD_ERR_CORRUPT, "%zu colour bytes for %llu "
			       "voxels", size, (unsigned long long)voxels);
	}
	c->voxels = voxels;
	c->rgb = rgb;
	return VD_OK;
}

int vd_colours_load(struct vd_colours *c, struct vd_chunk_header *h,
		    const char *path)
{
	memset(c, 0, sizeof *c);
	struct vd_chunk *ch;
	int err = vd_chunk_open(&ch, path, VD_KIND_COLOURS);
	if (err)
		return err;
	if (h)
		*h = *vd_chunk_header(ch);
	err = vd_colours_from_chunk(c, ch);
	vd_chunk_free(ch);
	return err;
}

int vd_colours_match(const struct vd_chunk_header *col_h,
		     const struct vd_colours *c,
		     const struct vd_chunk_header *svo_h,
		     const struct vd_svo *svo)
{
	if (col_h->levels != svo_h->levels ||
	    col_h->chunk_level != svo_h->chunk_level ||
	    col_h->cell_morton != svo_h->cell_morton)
		return vd_fail(VD_ERR_MISMATCH, "colours of cell %u:%llx at "
			       "depth %u, bricks of cell %u:%llx at depth %u",
			       col_h->chunk_level,
			       (unsigned long long)col_h->cell_morton,
			       col_h->levels, svo_h->chunk_level,
			       (unsigned long long)svo_h->cell_morton,
			       svo_h->levels);
	if (!vd_transform_equal(&col_h->transform, &svo_h->transform))
		return vd_fail(VD_ERR_MISMATCH, "colours and bricks placed in "
			       "different grids");
	uint64_t voxels = svo_h->level_nodes[svo_h->level_count - 1];
	if (c->voxels != voxels)
		return vd_fail(VD_ERR_MISMATCH, "%llu colours for %llu voxels",
			       (unsigned long long)c->voxels,
			       (unsigned long long)voxels);
	if (svo && vd_svo_digest(svo->keys, svo->masks, svo->count) !=
			   c->svo_digest)
		return vd_fail(VD_ERR_MISMATCH, "colours written for other "
			       "bricks (brick digest differs)");
	return VD_OK;
}

void vd_colours_release(struct vd_colours *c)
{
	free(c->rgb);
	memset(c, 0, sizeof *c);
}
