/* voxel_internal.h - pieces of voxel/ shared between its files
 * and the tests; not part of the public API. */
#ifndef VD_VOXEL_INTERNAL_H
#define VD_VOXEL_INTERNAL_H

#include "voxdag.h"

/* Receives one voxel (grid coordinates) that a triangle overlaps. */
typedef void (*vd_voxel_fn)(void *ctx, int64_t x, int64_t y, int64_t z);

/* Receives a run of n >= 1 voxels that a triangle overlaps: (x, y, z) and
 * the n - 1 voxels after it along `axis` (0, 1, 2: x, y, z). */
typedef void (*vd_span_fn)(void *ctx, int axis, int64_t x, int64_t y,
			   int64_t z, int64_t n);

/* Calls fn once for every voxel inside [clip_lo, clip_hi] (inclusive, in
 * voxels of a grid of depth `levels`) whose closed cube overlaps the closed
 * triangle `t`. */
void vd_raster_triangle(const struct vd_snapped_tri *t, int levels,
			const int64_t clip_lo[3], const int64_t clip_hi[3],
			vd_voxel_fn fn, void *ctx);

/* The same voxels as runs: each voxel in exactly one call. */
void vd_raster_triangle_spans(const struct vd_snapped_tri *t, int levels,
			      const int64_t clip_lo[3],
			      const int64_t clip_hi[3], vd_span_fn fn,
			      void *ctx);

/* Where vd_raster_triangle_bricks sets voxels: the 32^3-voxel blocks of a
 * cell, each 512 words, word i the 4^3 brick of Morton index i in its
 * block and bit j of it the voxel of Morton index j in its brick (so the
 * voxel of Morton index m in its block is bit m & 63 of word m >> 6). */
struct vd_brick_sink {
	int64_t lo[3];  /* the cell's first voxel: block coordinates count
			 * from it */
	/* The block of Morton key `key` (of its block coordinates), to OR
	 * voxels into; NULL drops the rest of the triangle (the caller
	 * records why). */
	uint64_t *(*block)(void *ctx, uint64_t key);
	void *ctx;
};

/* The voxels of vd_raster_triangle, set in the sink's blocks (the clip
 * box must lie inside the cell). The same voxels as the callbacks, set
 * without one call per run: the per-voxel cost of a fine grid. */
void vd_raster_triangle_bricks(const struct vd_snapped_tri *t, int levels,
			       const int64_t clip_lo[3],
			       const int64_t clip_hi[3],
			       struct vd_brick_sink *sink);

/* The longest row (in voxels) whose per-column bounds the rasterizer
 * tables once per triangle (2^16; rows over 512 voxels on the heap): tests
 * set it to 0 to exercise the untabled path. */
extern int vd_raster_table_max;

/* Whether small triangles take the rasterizer built for x86-64-v3 (AVX2)
 * when the processor has it (1, the default): tests set 0 to compare the
 * other with the brute-force reference too. */
extern int vd_raster_simd;

/* Whether voxelize's colour pass takes its fast paths (1, the default):
 * a triangle's voxels from the brick rasterizer, walked a brick at a
 * time, and nearest points four at a time in AVX2 when the processor has
 * it. Tests set 0 (the span rasterizer, one nearest point at a time) to
 * compare the two, bit for bit. */
extern int vd_colour_fast;

/* For the tests: the nearest points of the triangle of snapped corners v
 * (grid depth `levels`) to the centres of the voxels vox[0..4), by the
 * rule's scalar arithmetic into d2[0], w[0] (distances, weights by
 * corner and voxel) and by the colour pass's AVX2 path into d2[1], w[1].
 * Returns -1 without AVX2, else the AVX2 path's lanes without area (bit
 * l: d2[1][l] and w[1][..][l] not computed), plus 16 when the triangle
 * took the exact shortcut of precomputed edge products. */
int vd__nearest_check(const int64_t v[3][3], int levels,
		      const int64_t vox[4][3], float d2[2][4],
		      double w[2][3][4]);

/* The most bytes voxelize keeps of a mesh's triangles between its passes
 * over the file (besides a sixteenth of the budget): tests set 0 (every
 * pass reads the file) or a size a mesh overflows midway. */
extern uint64_t vd_tri_cache_max;

/* Sorts a[0..n) by bits [lo, lo + bits) of each value (LSD radix, 8 bits
 * a pass, `tmp` as long as `a`), keeping the order of equal keys. */
void vd_sort_keys(uint64_t *a, uint64_t *tmp, size_t n, int lo, int bits);

/* Population count: the instruction where the build targets it, else the
 * bit trick, inline (on a plain x86-64 build __builtin_popcountll is a
 * libgcc call, once per brick or block word). */
static inline uint64_t vd_popcount64(uint64_t v)
{
#ifdef __POPCNT__
	return (uint64_t)__builtin_popcountll(v);
#else
	v -= v >> 1 & 0x5555555555555555ull;
	v = (v & 0x3333333333333333ull) + (v >> 2 & 0x3333333333333333ull);
	v = (v + (v >> 4)) & 0x0f0f0f0f0f0f0f0full;
	return v * 0x0101010101010101ull >> 56;
#endif
}

/* Adds one brick to streaming per-level counts (as vd_svo_count_levels):
 * `prev` is the previous brick's key, `first` says there is none. Inline:
 * voxelize's nz pass calls it for every brick. */
static inline void vd_svo_count_brick(uint64_t *counts, int levels,
				      int chunk_level, int first,
				      uint64_t prev, uint64_t key,
				      uint64_t mask)
{
	int L = levels, L0 = chunk_level, bl = L >= 2 ? L - 2 : 0;
	/* A node at level l < L-2 is new when the key differs from the
	 * previous one in the bits above level l's children, bits from
	 * 3 * (bl - l) up: so exactly the levels from the one of the highest
	 * differing bit down (keys rise, so they differ; this runs once per
	 * brick in voxelize and in every SVO load, where a test per level
	 * cost a tenth of svo-to-dag). */
	int from = L0;
	if (!first) {
		uint64_t x = prev ^ key;
		int top = x ? 63 - __builtin_clzll(x) : -1;
		from = top < 0 ? bl : bl - top / 3;
		if (from < L0)
			from = L0;
	}
	for (int l = from; l < bl; l++)
		counts[l - L0]++;
	if (L >= 2) {
		counts[bl - L0]++;
		/* the non-zero bytes of the mask: its level L-1 nodes */
		uint64_t b = mask | mask >> 4;
		b |= b >> 2;
		b |= b >> 1;
		b &= 0x0101010101010101ull;
		counts[L - 1 - L0] += (b * 0x0101010101010101ull) >> 56;
	} else {
		counts[0] += 1; /* L == 1: the root is the 2x2x2 mask */
	}
	counts[L - L0] += vd_popcount64(mask);
}

/* Writes n bricks (keys strictly increasing) as an SVO chunk at `path`
 * (atomic), reading key i at keys[i * stride] and its mask at
 * masks[i * stride], so arrays of {key, mask} pairs need no copy. Fills
 * counts[0..levels-chunk_level] with the per-level counts if not NULL. */
int vd_svo_write(const char *path, int levels, int chunk_level, uint64_t cell,
		 const struct vd_transform *t, const char *provenance, size_t n,
		 const uint64_t *keys, const uint64_t *masks, size_t stride,
		 uint64_t *counts);

/* Removes the chunk files (and their temporaries) and the statistics in
 * `dir`: what an earlier run left, or what a failed run must not leave. */
void vd_remove_chunks(const char *dir);

/* What every voxelize statistics file reports, whatever the input. */
struct vd_voxelize_totals {
	int levels;
	uint64_t voxels, bricks, chunks;
	const uint64_t *level_nodes;  /* levels 0..levels */
	double seconds_total;
	int threads;
	uint64_t peak_rss_bytes, mem_budget_bytes;
	const struct vd_transform *transform;
};

/* Opens voxelize's statistics file at `path` with the fields every input
 * starts with: stage, version and input_format (`format`: "ply", "vdb",
 * ...). The mesh and OpenVDB writers add their own fields after them. */
int vd_voxelize_stats_open(struct vd_json **j, const char *path,
			   const char *format);

/* Writes those fields into an open statistics object (mesh and OpenVDB
 * writers add their own around them). */
void vd_voxelize_stats_totals(struct vd_json *j,
			      const struct vd_voxelize_totals *t);

#endif
