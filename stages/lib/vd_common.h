/* vd_common.h - what every part of libvoxdag shares: the versions, the grid's
 * conventions (Morton codes, the world transform), the thread pool and small
 * utilities.
 *
 * Grid conventions: a grid of `levels` L has 2^L voxels per side. Node
 * levels run from 0 (the root) to L-1 (2x2x2 masks); level L is the voxels.
 * Child index c = 4*x + 2*y + z (bit 2 = +X, bit 1 = +Y, bit 0 = +Z). A
 * Morton code is the sequence of child indices from the root, most
 * significant first, so sorting by Morton code is depth-first order.
 *
 * Bricks: a brick is the 4x4x4 block of voxels below one level-(L-2) node,
 * stored as a uint64_t whose bit b is the voxel with local Morton code b
 * (b = morton3(x&3, y&3, z&3)). Byte c of a brick is therefore the 2x2x2
 * mask of the brick's child c, whose bit c' is that child's voxel c'. A
 * brick key is the Morton code of the brick's coordinates (voxel >> 2) in
 * the whole grid. Grids with L < 2 have one brick, key 0, partly used.
 */
#ifndef VD_COMMON_H
#define VD_COMMON_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include "vd_errors.h"

#ifdef __cplusplus
extern "C" {
#endif

#define VD_VERSION_STRING "0.1.0"

/* Every stage's own version. It is part of every resume key the runner
 * computes and of the provenance each file records, so outputs written by
 * older code are rebuilt, never reused. RULE: bump a stage's number in the
 * same commit that changes the bytes or the format of what it writes, and
 * say why beside it. */
#define VD_STAGE_VERSIONS(X)                                                 \
	X("voxelize", 6)       /* 6: sources; 5: .vdb colours (see below); \
				  4: SGI textures; 3: .col; 2: manifest */  \
	/* A .vdb input runs as `voxelize` (which execs voxelize-vdb), so the  \
	 * runner's keys and the chunks' provenance carry voxelize's number:  \
	 * bump both. */                                                      \
	X("voxelize-vdb", 3)   /* 3: .col from a Vec3 grid; 2: manifest */   \
	X("svo-to-dag", 2)     /* 2: stage_version in provenance */          \
	X("symmetry-merge", 2) /* 2: the same */                             \
	X("encode", 3)         /* 3: ssvdag48 columns; 2: manifest */        \
	X("render", 1)                                                      \
	X("lossy-cluster", 3)  /* 3: balanced representatives; seconds_cut */\
	X("edit", 2)           /* 2: paint, colours, cpu_seconds per op */ \
	X("colorize", 2)       /* 2: exact single-colour VBR blocks */

/* The version of the stage named `tool` (as in out/bin/), 0 if unknown. */
int vd_stage_version(const char *tool);

/* Largest grid depth: voxel Morton codes need 3*L bits of a uint64_t. */
#define VD_MAX_LEVELS 21

/* ------------------------------------------------------------ Morton maths */

/* Spreads the low 21 bits of v so that bit i lands at bit 3i. */
static inline uint64_t vd_morton_spread(uint64_t v)
{
	v &= 0x1fffff;
	v = (v | v << 32) & 0x1f00000000ffffULL;
	v = (v | v << 16) & 0x1f0000ff0000ffULL;
	v = (v | v << 8) & 0x100f00f00f00f00fULL;
	v = (v | v << 4) & 0x10c30c30c30c30c3ULL;
	v = (v | v << 2) & 0x1249249249249249ULL;
	return v;
}

/* Inverse of vd_morton_spread: gathers bits 3i into bit i. */
static inline uint64_t vd_morton_compact(uint64_t v)
{
	v &= 0x1249249249249249ULL;
	v = (v ^ (v >> 2)) & 0x10c30c30c30c30c3ULL;
	v = (v ^ (v >> 4)) & 0x100f00f00f00f00fULL;
	v = (v ^ (v >> 8)) & 0x1f0000ff0000ffULL;
	v = (v ^ (v >> 16)) & 0x1f00000000ffffULL;
	v = (v ^ (v >> 32)) & 0x1fffff;
	return v;
}

/* Morton code of (x, y, z), each < 2^21; x is the most significant. */
static inline uint64_t vd_morton3(uint32_t x, uint32_t y, uint32_t z)
{
	return vd_morton_spread(x) << 2 | vd_morton_spread(y) << 1 |
	       vd_morton_spread(z);
}

static inline void vd_morton3_decode(uint64_t m, uint32_t *x, uint32_t *y,
				     uint32_t *z)
{
	*x = (uint32_t)vd_morton_compact(m >> 2);
	*y = (uint32_t)vd_morton_compact(m >> 1);
	*z = (uint32_t)vd_morton_compact(m);
}

/* --------------------------------------------------------- world transform */

/* Where the grid sits in the world. The cube's side is the largest extent
 * of the input's tight bounding box, centred on the box centre (the SymVox
 * convention, see schemas/chunk-format.md); bbox and side are kept as float32
 * because the SymVox encodings store them so. */
struct vd_transform {
	float bbox_min[3];   /* tight bounding box of the input, world units */
	float bbox_max[3];
	float root_side;     /* side of the cube, world units */
	double origin[3];    /* world position of the grid's (0,0,0) corner */
	double voxel_size;   /* world units per voxel at the grid's depth */
};

/* Fills `t` for the given tight bounding box and grid depth. Returns
 * VD_ERR_EMPTY if the box has zero extent on every axis, VD_ERR_RANGE if it
 * is not finite. */
int vd_transform_init(struct vd_transform *t, const float bbox_min[3],
		      const float bbox_max[3], int levels);

/* 1 when `a` and `b` place a grid identically: every field (bounding box,
 * root side, origin, voxel size) has the same bits, so -0 and +0 differ (the
 * encodings store the box's bits) and a NaN equals itself. The one
 * comparison used wherever chunks of one grid are combined. */
int vd_transform_equal(const struct vd_transform *a,
		       const struct vd_transform *b);

/* Number of hardware threads. */
int vd_hardware_threads(void);

/* ------------------------------------------------------------- utilities */

/* Parses "1024", "512K", "2M", "2GiB", "1.5G" (powers of 1024) into bytes.
 * Returns VD_ERR_ARG on anything else. */
int vd_parse_size(const char *s, uint64_t *bytes);

/* Monotonic seconds. */
double vd_seconds(void);

/* Builds the provenance text stored in chunk files:
 * "tool=NAME version=X args='a' 'b' ...", without --threads (-j) and its
 * value, which change no output byte. Returns a malloc'd string (free
 * with free()), NULL when out of memory. */
char *vd_provenance_new(const char *tool, int argc, char **argv);

#ifdef __cplusplus
}
#endif

#endif /* VD_COMMON_H */
