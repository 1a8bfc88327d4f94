/* vdb_test_grids.h - OpenVDB test grids for the tests and vdb-make-test-grids (io/
 * vdb_write.cc). Not part of the installed library's interface.
 */
#ifndef VD_VDB_TEST_GRIDS_H
#define VD_VDB_TEST_GRIDS_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include "vd_vdb.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Test support (used by the tests and vdb-make-test-grids, not by the
 * pipeline): builds grids through the OpenVDB API and writes them. Each
 * vd_vdb_test_add_* appends one grid to `f`; vd_vdb_test_write() writes
 * them all to `path`. */
struct vd_vdb_test_file;
int vd_vdb_test_new(struct vd_vdb_test_file **f);
/* Level set sphere (tools::createLevelSetSphere): radius and centre in
 * world units, `half_width` voxels of narrow band each side. */
int vd_vdb_test_add_sphere(struct vd_vdb_test_file *f, const char *name,
			   double radius, const double centre[3],
			   double voxel_size, double half_width);
/* Fog volume: float grid, background 0, the inclusive index box lo..hi
 * filled active with `value` (tree.fill: whole tiles where the box
 * covers them), then the inclusive box inner_lo..inner_hi set to
 * `inner_value` unless inner_lo[0] > inner_hi[0]. */
int vd_vdb_test_add_fog_box(struct vd_vdb_test_file *f, const char *name,
			    const int32_t lo[3], const int32_t hi[3],
			    float value, const int32_t inner_lo[3],
			    const int32_t inner_hi[3], float inner_value);
/* Level set of a mesh file (read with vd_mesh_*) by
 * tools::meshToLevelSet, `resolution` voxels across the mesh's largest
 * extent. */
int vd_vdb_test_add_mesh(struct vd_vdb_test_file *f, const char *name,
			 const char *mesh_path, int resolution,
			 double half_width);
/* A float grid with no active value (background 0). */
int vd_vdb_test_add_empty(struct vd_vdb_test_file *f, const char *name);
/* A float fog box (value 1) of side `n` at the origin whose transform is
 * rotated about Z by `rotate_deg` and scaled by (sx, sy, sz). */
int vd_vdb_test_add_transformed(struct vd_vdb_test_file *f,
				const char *name, int n, double rotate_deg,
				double sx, double sy, double sz);
/* The test colour of OpenVDB index (x, y, z), sRGB 0..255: a fixed
 * function of the coordinate that vd_vdb_test_add_colour() stores. */
void vd_vdb_test_colour_of(int64_t x, int64_t y, int64_t z, uint8_t rgb[3]);
/* A colour grid of `type` ("vec3s", "vec3d": vd_vdb_test_colour_of / 255;
 * "vec3i": as it is) with voxel size `voxel_size` and index (0,0,0) at world
 * `translation`: every index of the inclusive box lo..hi active with its
 * test colour, then those of off_lo..off_hi made inactive (their values
 * kept) unless off_lo[0] > off_hi[0]; the background is `bg` in the same
 * encoding. Voxel by voxel: small boxes only. */
int vd_vdb_test_add_colour(struct vd_vdb_test_file *f, const char *name,
			   const char *type, double voxel_size,
			   const double translation[3], const int32_t lo[3],
			   const int32_t hi[3], const int32_t off_lo[3],
			   const int32_t off_hi[3], const uint8_t bg[3]);
/* A colour grid of `type` (as above; background 0) whose index (i, 0, 0)
 * holds values[3i .. 3i+2] (converted to the type), active, i < n. */
int vd_vdb_test_add_colour_values(struct vd_vdb_test_file *f,
				  const char *name, const char *type, int n,
				  const double *values);
int vd_vdb_test_write(struct vd_vdb_test_file *f, const char *path);
void vd_vdb_test_free(struct vd_vdb_test_file *f);

/* Brute force reference for tests: evaluates the mode's definition at
 * every voxel of the grid's active bounding box grown by `margin` voxels
 * (with an accessor, no node iteration) and calls fn for each selected
 * one; *count gets their number. Slow: small grids only. */
int vd_vdb_test_reference(const char *path, const struct vd_vdb_select *sel,
			  int margin,
			  void (*fn)(void *ctx, int32_t x, int32_t y,
				     int32_t z),
			  void *ctx, uint64_t *count);

#ifdef __cplusplus
}
#endif

#endif /* VD_VDB_TEST_GRIDS_H */
