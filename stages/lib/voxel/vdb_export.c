/* vdb_export.c - SVO chunk files to one OpenVDB grid, through the brick
 * callback of vd_vdb_export() so only one chunk is in memory at a time (the
 * OpenVDB grid being built holds the voxels, sparsely). */
#include "voxdag.h"

#include <string.h>

struct svo_feed {
	char *const *paths;
	size_t n, next;
	struct vd_svo svo;
	struct vd_chunk_header first;
};


static int feed_svo(void *ctx, const uint64_t **keys, const uint64_t **masks,
		    size_t *n)
{
	struct svo_feed *f = ctx;
	vd_svo_release(&f->svo);
	*n = 0;
	while (f->next < f->n) {
		const char *path = f->paths[f->next++];
		struct vd_chunk_header h;
		int err = vd_svo_load(&f->svo, &h, path);
		if (!err && (h.levels != f->first.levels ||
			     !vd_transform_equal(&h.transform, &f->first.transform)))
			err = vd_fail(VD_ERR_MISMATCH, "depth %u or transform "
				      "differs from '%s' (depth %u): chunks "
				      "of different grids", h.levels,
				      f->paths[0], f->first.levels);
		if (err) {
			char d[512];
			snprintf(d, sizeof d, "%s", vd_error_detail());
			vd_svo_release(&f->svo);
			return vd_fail(err, "'%s': %s", path, d);
		}
		if (f->svo.count) {
			*keys = f->svo.keys;
			*masks = f->svo.masks;
			*n = f->svo.count;
			return VD_OK;
		}
	}
	return VD_OK;
}

int vd_vdb_export_svo(const char *path, const char *grid_name,
		      char *const *paths, size_t n, uint64_t *voxels)
{
	if (n == 0)
		return vd_fail(VD_ERR_EMPTY, "no chunk files to export");
	struct svo_feed f = {.paths = paths, .n = n};
	struct vd_chunk *c;
	int err = vd_chunk_open(&c, paths[0], VD_KIND_SVO);
	if (err) {
		char d[512];
		snprintf(d, sizeof d, "%s", vd_error_detail());
		return vd_fail(err, "'%s': %s", paths[0], d);
	}
	f.first = *vd_chunk_header(c);
	vd_chunk_free(c);
	err = vd_vdb_export(path, grid_name, (int)f.first.levels,
			    &f.first.transform, feed_svo, &f, voxels);
	vd_svo_release(&f.svo);
	return err;
}
