/* Colour sources: where render (and edit's paint, and the tests) read the
 * colour of voxel i of the scene's Morton-ordered colour array. One
 * interface over the raw colour chunks voxelize writes and the compressed
 * files colorize writes. */
#include "voxdag.h"

#include <dirent.h>
#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

struct cell_file {
	uint64_t cell;
	char *name;
};

static int by_cell(const void *a, const void *b)
{
	uint64_t x = ((const struct cell_file *)a)->cell,
		 y = ((const struct cell_file *)b)->cell;
	return x < y ? -1 : x > y;
}

static void raw_get(const struct vd_colour_source *s, uint64_t index,
		    uint8_t rgb[3])
{
	const uint8_t *p = (const uint8_t *)s->impl + 3 * index;
	rgb[0] = p[0];
	rgb[1] = p[1];
	rgb[2] = p[2];
}

static void raw_release(struct vd_colour_source *s)
{
	free(s->impl);
}

static void free_cells(struct cell_file *c, size_t n)
{
	for (size_t i = 0; i < n; i++)
		free(c[i].name);
	free(c);
}

/* Lists the colour chunks of `dir` with their cells, sorted. */
static int list_cells(const char *dir, struct cell_file **out, size_t *count,
		      struct vd_chunk_header *first)
{
	DIR *d = opendir(dir);
	if (!d)
		return vd_fail(VD_ERR_IO, "cannot open '%s': %s", dir,
			       strerror(errno));
	struct cell_file *c = NULL;
	size_t n = 0, cap = 0;
	int err = VD_OK;
	struct dirent *e;
	char path[4096];
	while (!err && (e = readdir(d))) {
		size_t len = strlen(e->d_name);
		if (len < 5 || strcmp(e->d_name + len - 4, ".col"))
			continue;
		snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
		struct vd_chunk_header h;
		err = vd_chunk_read_header(path, &h);
		if (err)
			break;
		if (n == 0)
			*first = h;
		else if (h.levels != first->levels ||
			 h.chunk_level != first->chunk_level)
			err = vd_fail(VD_ERR_MISMATCH, "'%s' is a cell of depth "
				      "%u, chunk level %u; others have %u, %u",
				      path, h.levels, h.chunk_level,
				      first->levels, first->chunk_level);
		if (!err && n == cap) {
			cap = cap ? 2 * cap : 64;
			struct cell_file *m = realloc(c, cap * sizeof *c);
			if (!m)
				err = vd_fail(VD_ERR_NOMEM, "out of memory");
			else
				c = m;
		}
		if (!err) {
			c[n].cell = h.cell_morton;
			c[n].name = strdup(e->d_name);
			if (!c[n++].name)
				err = vd_fail(VD_ERR_NOMEM, "out of memory");
		}
	}
	closedir(d);
	if (!err && n == 0)
		err = vd_fail(VD_ERR_EMPTY, "no colour chunks (*.col) in '%s': "
			      "was the mesh voxelized with colours?", dir);
	if (err) {
		free_cells(c, n);
		return err;
	}
	qsort(c, n, sizeof *c, by_cell);
	*out = c;
	*count = n;
	return VD_OK;
}

int vd_colour_chunks_load(const char *dir, uint8_t **rgb, uint64_t *voxels,
			  struct vd_chunk_header *first)
{
	struct cell_file *c = NULL;
	size_t n = 0;
	struct vd_chunk_header h0;
	int err = list_cells(dir, &c, &n, &h0);
	if (err)
		return err;
	uint8_t *all = NULL;
	uint64_t total = 0;
	char path[4096];
	for (size_t i = 0; i < n && !err; i++) {
		struct vd_colours col;
		struct vd_chunk_header ch, sh;
		struct vd_svo svo;
		snprintf(path, sizeof path, "%s/%s", dir, c[i].name);
		err = vd_colours_load(&col, &ch, path);
		if (err)
			break;
		/* the bricks beside it must be the ones coloured */
		size_t len = strlen(path);
		memcpy(path + len - 3, "svo", 3);
		err = vd_svo_load(&svo, &sh, path);
		if (!err)
			err = vd_colours_match(&ch, &col, &sh, &svo);
		if (!err && !vd_transform_equal(&ch.transform, &h0.transform))
			err = vd_fail(VD_ERR_MISMATCH, "'%s' is placed in "
				      "another grid than the other cells",
				      c[i].name);
		vd_svo_release(&svo);
		if (!err) {
			uint8_t *m = realloc(all, 3 * (total + col.voxels) + 1);
			if (!m) {
				err = vd_fail(VD_ERR_NOMEM, "out of memory for "
					      "%llu colours",
					      (unsigned long long)(total + col.voxels));
			} else {
				all = m;
				memcpy(all + 3 * total, col.rgb, 3 * col.voxels);
				total += col.voxels;
			}
		} else {
			memcpy(path + len - 3, "col", 3);
			err = vd_fail(err, "'%s': %s", path, vd_error_detail());
		}
		vd_colours_release(&col);
	}
	free_cells(c, n);
	if (err) {
		free(all);
		return err;
	}
	*rgb = all;
	*voxels = total;
	if (first)
		*first = h0;
	return VD_OK;
}

static void cpack_get(const struct vd_colour_source *s, uint64_t index,
		      uint8_t rgb[3])
{
	/* index < voxels is the interface's promise, so this cannot fail */
	(void)vd_cpack_colour(s->impl, index, rgb);
}

static void cpack_get_many(const struct vd_colour_source *s,
			   const uint64_t *index, size_t n, uint8_t *rgb)
{
	/* the indices are < voxels (the interface's promise), so only
	 * memory can fail: then one by one, which cannot */
	if (vd_cpack_colour_many(s->impl, index, n, rgb) != VD_OK)
		for (size_t q = 0; q < n; q++)
			(void)vd_cpack_colour(s->impl, index[q], rgb + 3 * q);
}

static void cpack_release(struct vd_colour_source *s)
{
	vd_cpack_free(s->impl);
}

/* A packed colours file of colorize, checked against the manifest of its
 * directory first (like the encodings: its checksum is not in doubt when
 * the manifest agrees, and a stray file is refused). */
static int open_cpack(struct vd_colour_source *s, const char *path)
{
	struct vd_chunk_header h;
	int err = vd_manifest_check_file(path);
	if (!err)
		err = vd_chunk_read_header(path, &h);
	if (!err && h.kind != VD_KIND_CPACK)
		err = vd_fail(VD_ERR_WRONG_KIND, "'%s' is a %s chunk, not "
			      "packed colours", path, vd_chunk_kind_name(h.kind));
	struct vd_cpack *c = NULL;
	if (!err)
		err = vd_cpack_open(&c, path);
	if (err)
		return err;
	s->voxels = vd_cpack_voxels(c);
	s->levels = (int)h.levels;
	s->cell_level = vd_cpack_cell_level(c);
	s->get = cpack_get;
	s->get_many = cpack_get_many;
	s->impl = c;
	s->release = cpack_release;
	return VD_OK;
}

int vd_colour_source_open(struct vd_colour_source *s, const char *path)
{
	memset(s, 0, sizeof *s);
	struct stat st;
	if (stat(path, &st) != 0)
		return vd_fail(VD_ERR_IO, "cannot open '%s': %s", path,
			       strerror(errno));
	if (!S_ISDIR(st.st_mode))
		return open_cpack(s, path);
	uint8_t *rgb;
	uint64_t voxels;
	struct vd_chunk_header h;
	int err = vd_colour_chunks_load(path, &rgb, &voxels, &h);
	if (err)
		return err;
	s->voxels = voxels;
	s->levels = (int)h.levels;
	s->cell_level = (int)h.chunk_level;
	s->get = raw_get;
	s->impl = rgb;
	s->release = raw_release;
	return VD_OK;
}

void vd_colour_source_get_many(const struct vd_colour_source *s,
			       const uint64_t *index, size_t n, uint8_t *rgb)
{
	if (s->get_many) {
		s->get_many(s, index, n, rgb);
		return;
	}
	for (size_t q = 0; q < n; q++)
		s->get(s, index[q], rgb + 3 * q);
}

void vd_colour_source_release(struct vd_colour_source *s)
{
	if (s->release)
		s->release(s);
	memset(s, 0, sizeof *s);
}
