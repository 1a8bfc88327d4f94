/* scene.h - real scenes for the tests: voxelize a mesh with the library and
 * read the chunks back, as voxel sets or as one SVO. Include after check.h. */
#ifndef VD_TEST_SCENE_H
#define VD_TEST_SCENE_H

#include "voxdag.h"
#include "vset.h"

#include <dirent.h>
#include <string.h>

/* Voxelizes `mesh` at depth L into SVO chunks of level L0 (-1: from the
 * budget) in `dir`. Returns VD_OK or the error, which it prints. */
static inline int test_voxelize(const char *mesh, int L, int L0,
				const char *dir, struct vd_voxelize_result *res)
{
	struct vd_voxelize_opts o = {.levels = L, .chunk_level = L0,
				     .mem_budget_bytes = 1ull << 30,
				     .threads = 2, .quiet = 1, .tool = "test"};
	struct vd_voxelize_result r;
	int err = vd_voxelize_mesh(mesh, dir, &o, res ? res : &r);
	if (err)
		fprintf(stderr, "voxelize %s: %s: %s\n", mesh, vd_strerror(err),
			vd_error_detail());
	return err;
}

/* Voxelizes `mesh` at depth L as one chunk (L0 = 0) and loads it into *svo
 * and its transform into *t. Returns 1 on success (failures are CHECKs). */
static inline int test_voxelize_one(const char *mesh, int L, const char *dir,
				    struct vd_svo *svo, struct vd_transform *t)
{
	int err = test_voxelize(mesh, L, 0, dir, NULL);
	CHECK_EQ(err, VD_OK);
	if (err)
		return 0;
	char name[64], path[800];
	vd_chunk_file_name(name, sizeof name, 0, 0, "svo");
	snprintf(path, sizeof path, "%s/%s", dir, name);
	struct vd_chunk_header h;
	CHECK_EQ(vd_svo_load(svo, &h, path), VD_OK);
	*t = h.transform;
	return 1;
}

/* Adds the voxels of every .svo chunk in `dir` to `out` (then finishes
 * it), each as key(ctx, x, y, z) of its grid coordinates; counts the
 * chunks in *nchunks. Returns VD_OK or the error, which it prints. */
static inline int test_load_chunks(const char *dir,
				   uint64_t (*key)(void *ctx, int64_t x,
						   int64_t y, int64_t z),
				   void *ctx, struct vset *out, int *nchunks)
{
	DIR *dd = opendir(dir);
	struct dirent *e;
	char path[1024];
	*nchunks = 0;
	while (dd && (e = readdir(dd))) {
		size_t n = strlen(e->d_name);
		if (n < 5 || strcmp(e->d_name + n - 4, ".svo"))
			continue;
		snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
		struct vd_svo svo;
		int err = vd_svo_load(&svo, NULL, path);
		if (err) {
			fprintf(stderr, "%s: %s: %s\n", path, vd_strerror(err),
				vd_error_detail());
			closedir(dd);
			return err;
		}
		(*nchunks)++;
		for (size_t i = 0; i < svo.count; i++) {
			uint32_t bx, by, bz;
			vd_morton3_decode(svo.keys[i], &bx, &by, &bz);
			for (int b = 0; b < 64; b++)
				if (svo.masks[i] >> b & 1) {
					uint32_t x, y, z;
					vd_morton3_decode((uint64_t)b, &x, &y, &z);
					vset_add(out, key(ctx, 4 * (int64_t)bx + x,
							  4 * (int64_t)by + y,
							  4 * (int64_t)bz + z));
				}
		}
		vd_svo_release(&svo);
	}
	if (dd)
		closedir(dd);
	vset_finish(out);
	return VD_OK;
}

#endif
