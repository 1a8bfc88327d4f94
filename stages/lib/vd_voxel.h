/* vd_voxel.h - voxels (voxel/): SVO chunks and the colour chunks beside them,
 * the exact triangle/box test, the out-of-core voxelizer and the import of
 * OpenVDB grids (vdb_import.c, vdb_export.c: the calls in vd_vdb.h).
 */
#ifndef VD_VOXEL_H
#define VD_VOXEL_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include "vd_chunk.h"
#include "vd_mesh.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ------------------------------------------------------------------- SVO
 * The content of an SVO chunk: the non-empty bricks of one cell in Morton
 * order. This is also the in-memory form stages pass around. */
struct vd_svo {
	int levels;            /* grid depth L */
	int chunk_level;       /* L0 of the cell */
	uint64_t cell_morton;  /* cell Morton code at chunk_level */
	size_t count;          /* number of non-empty bricks */
	uint64_t *keys;        /* brick keys, strictly increasing */
	uint64_t *masks;       /* brick masks, never 0 */
};

/* Reads an SVO chunk file and verifies that its bricks are strictly
 * increasing, non-empty, inside the cell and the grid, and agree with the
 * header's counts. Free with vd_svo_release(). */
int vd_svo_load(struct vd_svo *svo, struct vd_chunk_header *h,
		const char *path);

/* Same, from an already opened chunk of kind SVO. */
int vd_svo_from_chunk(struct vd_svo *svo, const struct vd_chunk *c);
/* The same, the bricks' zstd frames decompressed on up to `threads`. */
int vd_svo_from_chunk_mt(struct vd_svo *svo, const struct vd_chunk *c,
			 int threads);

/* Computes the per-level non-empty node counts of the bricks in `svo` for
 * levels chunk_level..levels into counts[0..levels-chunk_level]. */
void vd_svo_count_levels(const struct vd_svo *svo, uint64_t *counts);

/* Writes `svo` as an SVO chunk file at `path` (atomic). `t` is the world
 * transform, `provenance` as for vd_chunk_writer_open(). */
int vd_svo_save(const struct vd_svo *svo, const struct vd_transform *t,
		const char *path, const char *provenance);

/* Writing an SVO chunk without holding the cell's bricks (edit writes
 * cells it holds as a DAG): open with the number of bricks `n`, give the
 * n keys in increasing order (vd_svo_writer_keys, any number of calls),
 * then the same bricks again with their masks (vd_svo_writer_masks), then
 * commit. The file is byte for byte what vd_svo_save writes for the same
 * bricks. Keys out of order, bricks missing or extra, an empty mask:
 * VD_ERR_ARG. Commit publishes the file (atomic, as vd_svo_save), puts
 * the bricks' vd_svo_digest() in *digest (may be NULL) and frees w either
 * way; abort drops an unfinished one (accepts NULL). */
struct vd_svo_writer;
int vd_svo_writer_open(struct vd_svo_writer **w, const char *path,
		       int levels, int chunk_level, uint64_t cell_morton,
		       const struct vd_transform *t, const char *provenance,
		       uint64_t n);
int vd_svo_writer_keys(struct vd_svo_writer *w, const uint64_t *keys,
		       size_t m);
int vd_svo_writer_masks(struct vd_svo_writer *w, const uint64_t *keys,
			const uint64_t *masks, size_t m);
int vd_svo_writer_commit(struct vd_svo_writer *w, uint64_t *digest);
void vd_svo_writer_abort(struct vd_svo_writer *w);

void vd_svo_release(struct vd_svo *svo);

/* ---------------------------------------------------- triangle/box overlap
 * Voxelization decides overlap exactly on snapped coordinates: a vertex is
 * placed on a lattice of 2^-VD_SNAP_ROOT_BITS of the cube's side
 * (vd_snap_triangle), and then every test is integer arithmetic without
 * rounding, so touching counts as overlap with no epsilon and results never
 * depend on evaluation order. The lattice is the same at every grid depth,
 * so a coarse voxel is set exactly when one of its children is; 2^-24 of
 * the side is about what float32 coordinates resolve, and a voxel at depth
 * L is 2^(24-L) lattice steps (8 at the deepest, L = 21). */
#define VD_SNAP_ROOT_BITS 24

/* Lattice steps per voxel at grid depth `levels`. */
static inline int64_t vd_snap_voxel(int levels)
{
	return (int64_t)1 << (VD_SNAP_ROOT_BITS - levels);
}

/* Snapped coordinates of a triangle, in lattice steps from the grid's
 * (0,0,0) corner. */
struct vd_snapped_tri {
	int64_t v[3][3];
};

/* Snaps `t` onto the lattice of `tr`. Returns VD_ERR_RANGE if a coordinate
 * is not finite. */
int vd_snap_triangle(struct vd_snapped_tri *out, const struct vd_triangle *t,
		     const struct vd_transform *tr);

/* Returns 1 if the closed triangle and the closed axis-aligned cube
 * [lo, lo + size] (in voxels of a grid of depth `levels`, per axis)
 * overlap, else 0. Degenerate triangles are treated as the segment or point
 * they are. */
int vd_tri_box_overlap(const struct vd_snapped_tri *t, int levels,
		       const int64_t lo[3], int64_t size);

/* ------------------------------------------------------------ voxelizer */

struct vd_voxelize_opts {
	int levels;               /* L, 1..VD_MAX_LEVELS */
	int chunk_level;          /* L0, or -1 to choose from the budget */
	uint64_t mem_budget_bytes;/* per-process budget */
	int threads;              /* 0: all cores */
	int quiet;                /* no progress on stderr */
	const char *provenance;   /* stored in every chunk */
	const char *tool;         /* prefix for progress lines */
	/* Write each non-empty cell's colour chunk ("col", vd_colours_save)
	 * when the mesh has colours (vd_mesh_has_colours) or the OpenVDB file
	 * a colour grid (vd_vdb_colour_open); rules in
	 * schemas/colour-rule.md. The SVO chunks' voxels are the same either
	 * way. */
	int colours;
	int strict;               /* a missing texture or MTL is an error */
};

struct vd_voxelize_result {
	int levels, chunk_level;
	struct vd_transform transform;
	struct vd_mesh_stats mesh;
	uint64_t triangles_binned;   /* triangle-cell pairs written to bins */
	uint64_t voxels;
	uint64_t chunks;
	uint64_t bricks;
	uint64_t level_nodes[VD_MAX_LEVELS + 1]; /* whole grid, levels 0..L */
	double seconds_bounds, seconds_bin, seconds_voxelize, seconds_total;
	uint64_t peak_rss_bytes;
	uint64_t mem_budget_bytes;
	int threads;                 /* workers used for the cells */
	char format[32];             /* input format, vd_mesh_format() */
	int colours;                 /* colour chunks were written */
	uint64_t textures_loaded, textures_missing;
	double seconds_colour;       /* summed over workers */
};

/* Voxelizes the mesh at `mesh_path` into SVO chunk files
 * OUTDIR/chunk-L<L0>-<morton>.svo, one per non-empty cell, and with
 * opts->colours, when the mesh has colours, a colour chunk
 * chunk-L<L0>-<morton>.col beside each. Existing chunk files of an
 * earlier run in `outdir` are removed first. */
int vd_voxelize_mesh(const char *mesh_path, const char *outdir,
		     const struct vd_voxelize_opts *opts,
		     struct vd_voxelize_result *res);

/* Writes `res` as JSON to `path` (atomic). */
int vd_voxelize_write_stats(const struct vd_voxelize_result *res,
			    const char *path);

/* Name of a cell's chunk file inside a directory: "chunk-L3-000123.svo".
 * Writes at most `cap` bytes into `buf`. */
void vd_chunk_file_name(char *buf, size_t cap, int chunk_level,
			uint64_t cell_morton, const char *ext);

/* --------------------------------------------------------- colour chunks
 * A colour chunk (kind VD_KIND_COLOURS, file vd_chunk_file_name(.., "col")
 * beside the cell's "svo" chunk) holds the sRGB colours (R, G, B bytes) of
 * one cell's voxels in the cell's depth-first Morton order: bricks in key
 * order, within a brick voxels in mask bit order. That is the order of a
 * depth-first walk of the cell's octree visiting children 0..7, so the
 * cells' arrays in cell order are the scene's colour array. The header is
 * the SVO chunk's (depth, cell, transform, counts) with the kind changed,
 * and a BDIG section holds vd_svo_digest() of the bricks the colours were
 * written for. Spec: schemas/chunk-format.md, "Colour chunks". */
#define VD_TAG_COLS VD_TAG('C', 'O', 'L', 'S') /* RGB8 per voxel */
#define VD_TAG_BDIG VD_TAG('B', 'D', 'I', 'G') /* digest of the bricks */

struct vd_colours {
	uint64_t voxels;      /* number of colours = voxels of the cell */
	uint8_t *rgb;         /* 3 * voxels bytes */
	uint64_t svo_digest;  /* vd_svo_digest() of the cell's bricks */
};

/* XXH3-64 over the little-endian (key, mask) u64 pairs of n bricks. */
uint64_t vd_svo_digest(const uint64_t *keys, const uint64_t *masks,
		       size_t n);
/* The same with key i at keys[i * stride], mask i at masks[i * stride]. */
uint64_t vd_svo_digest_stride(const uint64_t *keys, const uint64_t *masks,
			      size_t stride, size_t n);

/* Writes the colours `rgb` (3 * voxels bytes) of the cell whose SVO chunk
 * header is `svo_h` (its voxel count must equal `voxels`: VD_ERR_MISMATCH)
 * and whose bricks have digest `svo_digest`, atomically at `path`. */
int vd_colours_save(const char *path, const struct vd_chunk_header *svo_h,
		    uint64_t svo_digest, const uint8_t *rgb, uint64_t voxels,
		    const char *provenance);

/* The same, the colours streamed: each call of `next` sets *rgb to the next
 * *n colours (3 * *n bytes, valid until the next call) and returns VD_OK;
 * *n == 0 ends, a non-zero return aborts the write and is returned. More
 * or fewer than `voxels` colours in all: VD_ERR_MISMATCH, nothing
 * written. */
int vd_colours_write(const char *path, const struct vd_chunk_header *svo_h,
		     uint64_t svo_digest, uint64_t voxels,
		     int (*next)(void *ctx, const uint8_t **rgb, size_t *n),
		     void *ctx, const char *provenance);

/* Reads and verifies a colour chunk. Free with vd_colours_release(). */
int vd_colours_load(struct vd_colours *c, struct vd_chunk_header *h,
		    const char *path);
int vd_colours_from_chunk(struct vd_colours *c, const struct vd_chunk *ch);

/* VD_OK when colour chunk (`col_h`, `c`) belongs to the SVO chunk
 * (`svo_h`, `svo`): same depth, cell, grid, voxel count, and (when `svo` is
 * not NULL) brick digest; VD_ERR_MISMATCH with a detail otherwise. */
int vd_colours_match(const struct vd_chunk_header *col_h,
		     const struct vd_colours *c,
		     const struct vd_chunk_header *svo_h,
		     const struct vd_svo *svo);

void vd_colours_release(struct vd_colours *c);

#ifdef __cplusplus
}
#endif

#endif /* VD_VOXEL_H */
