/* vd_vdb.h - OpenVDB grids in and out (io/vdb*.cc, the import driver and the
 * export).
 */
#ifndef VD_VDB_H
#define VD_VDB_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include "vd_mesh.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- OpenVDB (io/vdb.cc reads, io/vdb_write.cc writes)
 * OpenVDB grids in and out. Those two are the only files that include
 * OpenVDB; every exception is caught there and returned as an error code
 * with a detail line. The import driver (vdb_import.c) and the chunk export
 * (vdb_export.c) are C on top of these calls.
 *
 * Index space: an OpenVDB voxel (i, j, k) is centred at index (i, j, k), so
 * it covers [i - 1/2, i + 1/2) in index units; our voxel v covers
 * [origin + v*voxel_size, origin + (v+1)*voxel_size) in world units. */

struct vd_voxelize_opts;

/* What counts as a set voxel when importing. */
enum vd_vdb_mode {
	VD_VDB_ACTIVE = 0,       /* active voxels and active tiles (any type) */
	/* The zero crossing of a level set, one voxel thick: every voxel with
	 * value <= 0 that has a face neighbour (of the 6) with value > 0,
	 * active or not (inactive values are the +-background). This is the
	 * inner shell of levelset-solid: the solid less its 6-erosion. */
	VD_VDB_LEVELSET_SURFACE,
	/* The inside of a level set: every voxel with value <= 0, active or
	 * not, inside tiles included. A background <= 0 (an inside without
	 * end) is refused. */
	VD_VDB_LEVELSET_SOLID,
	/* Active voxels and active tiles whose value is above the threshold
	 * (inactive values, the background, never count). */
	VD_VDB_FOG,
	VD_VDB_MODE_COUNT_
};

/* "active", "levelset-surface", "levelset-solid", "fog"; NULL if unknown. */
const char *vd_vdb_mode_name(int mode);
/* Parses one of those names into *mode. Returns VD_ERR_ARG otherwise. */
int vd_vdb_mode_parse(const char *name, int *mode);

/* Which grid of a file and which of its voxels. */
struct vd_vdb_select {
	const char *grid_name;   /* NULL: the first grid in the file */
	int mode;                /* enum vd_vdb_mode */
	double fog_threshold;    /* VD_VDB_FOG: set when value > this */
	/* The colour grid (vd_vdb_colour_open; used by vd_vdb_import when
	 * opts->colours): NULL picks one by name, or none. */
	const char *colour_grid;
};

/* What vd_vdb_open() found. Index boxes are inclusive, in OpenVDB index
 * coordinates. */
struct vd_vdb_info {
	char grid_name[128];
	char value_type[32];      /* "float", "double", "bool", "mask", ... */
	char grid_class[32];      /* "level set", "fog volume", "unknown", ... */
	double voxel_size;        /* world units per index unit */
	double translation[3];    /* world position of index (0,0,0) */
	uint64_t active_voxels;   /* OpenVDB's activeVoxelCount() */
	uint64_t leaves;          /* leaf nodes in the tree */
	int has_active;           /* 0: no active value at all */
	int32_t active_min[3], active_max[3]; /* evalActiveVoxelBoundingBox */
};

struct vd_vdb;

/* Walks the structure of the OpenVDB file `f` (vdb_walk.c, no OpenVDB):
 * magic number, header, file metadata, grid descriptors and their end
 * offsets, and checks each length against the file's size before OpenVDB
 * trusts it. Sets *grids to the grid count. Errors: VD_ERR_EMPTY,
 * VD_ERR_FORMAT (no magic), VD_ERR_TRUNCATED, VD_ERR_CORRUPT, VD_ERR_IO. */
int vd_vdb_walk(FILE *f, uint64_t *grids);

/* Reads grid `sel->grid_name` (the first grid when NULL) of the OpenVDB
 * file `path` into memory (OpenVDB holds the tree; nothing is copied
 * densely) and checks it can be read in mode `sel->mode`. Errors:
 * VD_ERR_IO (cannot open), VD_ERR_FORMAT (not an OpenVDB file),
 * VD_ERR_TRUNCATED (the file ends early or its data is damaged: OpenVDB
 * cannot tell the two apart), VD_ERR_EMPTY (no grid in the file),
 * VD_ERR_ARG (no grid of that name; the detail lists the names),
 * VD_ERR_UNSUPPORTED (a value type the mode cannot read, a rotated,
 * non-uniform or non-linear transform: voxdag grids are axis-aligned cubes,
 * so such a grid must first be resampled, e.g. with OpenVDB's
 * tools::resampleToMatch; or a level set whose background is <= 0).
 * Fills `info` when not NULL. Close with vd_vdb_close(). */
int vd_vdb_open(struct vd_vdb **out, const char *path,
		const struct vd_vdb_select *sel, struct vd_vdb_info *info);
void vd_vdb_close(struct vd_vdb *v);

/* A node of the tree that holds selected voxels. A leaf (is_leaf) covers
 * the 8^3 voxels from `origin`; voxel (x, y, z) of it (0..7 each) is set
 * when bit 8*y + z of mask[x] is. A tile covers dim^3 voxels from `origin`,
 * all set; mask is unused. */
struct vd_vdb_node {
	int32_t origin[3];
	uint32_t dim;
	int is_leaf;
	uint64_t mask[8];
};

/* Calls fn for every leaf with at least one selected voxel and every tile
 * (at any level) whose voxels are all selected, in the tree's order; stops
 * at the first non-zero return of fn and returns it. Tiles are reported
 * whole: their voxels are never visited. */
int vd_vdb_scan(struct vd_vdb *v,
		int (*fn)(void *ctx, const struct vd_vdb_node *n), void *ctx);

/* The selected voxels of the leaf at `origin` (as vd_vdb_node.mask; all 0
 * when there is no leaf there). Safe to call from several threads. */
int vd_vdb_leaf_mask(struct vd_vdb *v, const int32_t origin[3],
		     uint64_t mask[8]);

/* Colour from a Vec3 grid beside the density grid; the rule, value ranges
 * and sampling are in schemas/colour-rule.md ("OpenVDB colour grids"). */
struct vd_vdb_colour;

struct vd_vdb_colour_info {
	char grid_name[128];
	char value_type[32];   /* "vec3s", "vec3d" or "vec3i" */
	/* 1: the colour grid's transform is the density grid's, so a voxel's
	 * colour is read at its own index; 0: read at the colour grid's voxel
	 * nearest to the voxel centre's world position */
	int same_transform;
};

/* Reads the colour grid of the OpenVDB file `path` beside the density grid
 * `density` (open): the grid named `name`, or when `name` is NULL a grid
 * named Cd, color, colour or rgb whose values are Vec3
 * (vec3s, vec3d or vec3i), names tried in that order (OpenVDB lists a
 * file's grids by name, so a file order is not to be had); with no such
 * grid *out is NULL and VD_OK is
 * returned (no colours). Errors: those of vd_vdb_open(), VD_ERR_ARG (no
 * grid `name`; the detail lists the names), VD_ERR_UNSUPPORTED (grid `name`
 * is not a Vec3 grid, or has a non-linear transform). Fills `info` when
 * there is a grid and `info` is not NULL. Close with
 * vd_vdb_colour_close(). */
int vd_vdb_colour_open(struct vd_vdb_colour **out, const char *path,
		       const char *name, const struct vd_vdb *density,
		       struct vd_vdb_colour_info *info);
void vd_vdb_colour_close(struct vd_vdb_colour *c);

/* The sRGB colours (R, G, B bytes, rgb[0..3V) for V the voxels of the
 * bricks) of the voxels of n bricks of an import, bricks in the order
 * given, within a brick in mask bit order: brick i's key is
 * keys[i * stride], its mask masks[i * stride]. Our voxel v is the
 * OpenVDB voxels off + v 2^shift .. off + (v + 1) 2^shift - 1 of the density
 * grid (vd_vdb_import_result.index_offset, resample_shift); its colour is
 * read at its centre. Safe to call from several threads. */
int vd_vdb_colour_bricks(const struct vd_vdb_colour *c, const int32_t off[3],
			 int shift, const uint64_t *keys,
			 const uint64_t *masks, size_t stride, size_t n,
			 uint8_t *rgb);

/* Import: the selected voxels of a grid into SVO chunk files, one per
 * non-empty L0 cell, named and laid out as vd_voxelize_mesh() does.
 *
 * Placement: the grid covers the bounding box of the selected voxels.
 * With opts->levels == 0 one OpenVDB voxel is one voxel, and L is the
 * smallest depth whose 2^L voxels cover the box from its minimum rounded
 * down to a multiple of 8 (so OpenVDB leaves fall on our 4^3 bricks and
 * never straddle a cell). With opts->levels == L the same holds if the box
 * fits; otherwise the grid is resampled by the smallest power of two 2^k
 * that makes it fit: one of our voxels is 2^k OpenVDB voxels per side and
 * is set when any of them is (no new voxel appears, thin features stay),
 * the box's minimum rounded down to a multiple of 8*2^k. A larger L than
 * needed only pads. Returns what vd_vdb_open() returns, VD_ERR_EMPTY when
 * no voxel is selected, VD_ERR_RANGE when the grid needs more than 2^21
 * voxels per side (pass opts->levels to resample), VD_ERR_BUDGET. */
struct vd_vdb_import_result {
	int levels, chunk_level;
	struct vd_transform transform;
	struct vd_vdb_info info;
	int mode;
	double fog_threshold;
	int resample_shift;          /* k above; 0: no resampling */
	int32_t index_offset[3];     /* OpenVDB index of our voxel (0,0,0) */
	uint64_t leaves_selected;    /* leaves with a selected voxel */
	uint64_t tiles_selected;     /* tiles wholly selected */
	uint64_t voxels, chunks, bricks;
	uint64_t level_nodes[VD_MAX_LEVELS + 1]; /* whole grid, levels 0..L */
	double seconds_read, seconds_scan, seconds_voxelize, seconds_total;
	uint64_t peak_rss_bytes, mem_budget_bytes;
	int threads;
	int colours;                 /* colour chunks were written */
	struct vd_vdb_colour_info colour; /* their grid, when colours */
};

/* opts->levels: 0 to fit (see above), or the depth to resample to. With
 * opts->colours and a colour grid (vd_vdb_colour_open with
 * sel->colour_grid), each cell also gets its colour chunk, as
 * vd_voxelize_mesh() writes them. */
int vd_vdb_import(const char *vdb_path, const char *outdir,
		  const struct vd_vdb_select *sel,
		  const struct vd_voxelize_opts *opts,
		  struct vd_vdb_import_result *res);

/* Writes `res` as JSON to `path` (atomic), with the fields of
 * vd_voxelize_write_stats() that apply plus the grid and the mode. */
int vd_vdb_import_write_stats(const struct vd_vdb_import_result *res,
			      const char *path);

/* Export. Bricks arrive through `next`: each call sets *keys, *masks to
 * *n bricks (any order, keys as in the grid conventions of a grid of
 * depth `levels`) and returns VD_OK; *n == 0 ends; a non-zero return
 * aborts the export and is returned. The voxels are written to `path`
 * (replaced atomically) as one BoolGrid named `grid_name`, active and
 * true, with the transform of `t`: our voxel v is OpenVDB index v, voxel
 * size t->voxel_size, index (0,0,0) centred at t->origin + voxel_size/2.
 * Full 8^3 leaves are pruned into tiles. *voxels (if not NULL) gets the
 * active voxel count of the written grid, as OpenVDB counts it. */
int vd_vdb_export(const char *path, const char *grid_name, int levels,
		  const struct vd_transform *t,
		  int (*next)(void *ctx, const uint64_t **keys,
			      const uint64_t **masks, size_t *n),
		  void *ctx, uint64_t *voxels);

/* Exports the SVO chunk files paths[0..n) (cells of one grid: same depth
 * and transform, else VD_ERR_MISMATCH) with vd_vdb_export(), one chunk in
 * memory at a time. */
int vd_vdb_export_svo(const char *path, const char *grid_name,
		      char *const *paths, size_t n, uint64_t *voxels);

#ifdef __cplusplus
}
#endif

#endif /* VD_VDB_H */
