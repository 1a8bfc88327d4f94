/* budget.h - how a stage splits its --mem-budget: every fixed fraction of
 * a budget lives here, named, with what it pays for and why that size.
 * Internal: not installed.
 *
 * Every stage keeps DESIGN.md's contract: it stays under --mem-budget or
 * stops with an error naming it. A stage sizes a few buffers of its own
 * choosing as a share of the budget (below); what is left after them and
 * after what the process already holds (vd_current_rss_bytes) goes to the
 * work whose size the input decides (voxelize's cells, lossy-cluster's
 * graphs), which checks itself against that rest.
 *
 * A share is a divisor: `budget / DIV`, integer division, in the order
 * written here. Keep it so: voxelize's automatic chunk level is chosen from
 * what these shares leave, and the chunk level decides every chunk file, so
 * changing a share (or its rounding) changes output bytes. */
#ifndef VD_BUDGET_H
#define VD_BUDGET_H

#include <stddef.h>
#include <stdint.h>

/* ------------------------------------------------------------ voxelize */

enum {
	/* An indexed mesh's vertices (and an OBJ's texture coordinates)
	 * held in memory while its faces are read; beyond this share they
	 * are joined with the faces on disk (io/mesh_spill.c). The largest
	 * share: every pass over the faces looks vertices up, so keeping
	 * them is the fast path, and they stay held through the
	 * rasterization (counted in the plan's `base`, so whatever they
	 * take the cells do not get); a mesh whose vertices need more than
	 * half leaves too little for its cells anyway, and only then is the
	 * slower join on disk worth it. */
	VD_BUDGET_VERTICES_DIV = 2,
	/* The first pass's copy of the triangles, replayed by the estimate
	 * and binning passes instead of reading and decoding the file again
	 * (and, for one cell without colours, the cell's bin itself). A
	 * speed-up only, never needed, so small: it is still held when the
	 * plan measures `base`, and takes from the cells what it holds. */
	VD_BUDGET_TRI_CACHE_DIV = 16,
	/* The estimate's keys of the 32^3 blocks triangles may touch
	 * (estimate pass: sorted keys, a buffer and its sort's copy).
	 * Freed before the plan: its peak is its own, not added to the
	 * cells'. Past its share the keys coarsen (a looser bound), they
	 * never grow; an eighth keeps the bound exact for all but the
	 * largest scenes of a budget. */
	VD_BUDGET_ESTIMATE_DIV = 8,
	/* Keys of the estimate: 8 bytes each, max_keys of them a quarter of
	 * the share (the arrays hold 2.5 max_keys at most); never fewer
	 * than VD_BUDGET_ESTIMATE_MIN_KEYS, so a tiny budget still gets a
	 * usable bound. */
	VD_BUDGET_ESTIMATE_KEY_BYTES = 8,
	VD_BUDGET_ESTIMATE_LOAD_DIV = 4,
	VD_BUDGET_ESTIMATE_MIN_KEYS = 4096,
	/* The binning pass's record buffer, sorted by cell and appended to
	 * the bin files when full: larger means fewer, longer writes, which
	 * stop paying above 256 MiB; below 16 MiB the writes become tiny
	 * and many (a small budget still gets 16 MiB: the plan counts it, so
	 * such a budget is refused rather than exceeded). Held beside the
	 * plan's `base` when the workers' share is worked out. */
	VD_BUDGET_BINS_DIV = 8,
};
#define VD_BUDGET_BINS_MIN_BYTES ((uint64_t)(16 << 20))
#define VD_BUDGET_BINS_MAX_BYTES ((uint64_t)(256u << 20))

/* What voxelize's fixed shares come to for a budget of `budget` bytes.
 * The rest (budget less the process's RSS, the bin buffer and the per-cell
 * arrays) is the workers': shared equally, each paying WORKER_OVERHEAD and
 * then its cell's blocks (voxelize.c, plan_budget). */
struct vd_voxelize_budget {
	uint64_t vertex_bytes;     /* vd_mesh_open_opts.max_vertex_bytes */
	uint64_t tri_cache_bytes;  /* the first pass's copy of triangles */
	size_t estimate_keys;      /* the estimate's set, in keys */
	uint64_t bin_bytes;        /* the binning pass's record buffer */
};

static inline struct vd_voxelize_budget vd_voxelize_budget(uint64_t budget)
{
	struct vd_voxelize_budget s;
	s.vertex_bytes = budget / VD_BUDGET_VERTICES_DIV;
	s.tri_cache_bytes = budget / VD_BUDGET_TRI_CACHE_DIV;
	s.estimate_keys = (size_t)(budget / VD_BUDGET_ESTIMATE_DIV /
				   VD_BUDGET_ESTIMATE_KEY_BYTES /
				   VD_BUDGET_ESTIMATE_LOAD_DIV);
	if (s.estimate_keys < VD_BUDGET_ESTIMATE_MIN_KEYS)
		s.estimate_keys = VD_BUDGET_ESTIMATE_MIN_KEYS;
	uint64_t bins = budget / VD_BUDGET_BINS_DIV;
	s.bin_bytes = bins < VD_BUDGET_BINS_MIN_BYTES ? VD_BUDGET_BINS_MIN_BYTES
		      : bins > VD_BUDGET_BINS_MAX_BYTES ? VD_BUDGET_BINS_MAX_BYTES
		      : bins;
	return s;
}


/* ------------------------------------------------------- lossy-cluster
 * A level's similarity graph gets `avail`: what the budget leaves beside
 * the process (or vd_lossy_opts.graph_budget when fixed). */
enum {
	/* The pair search's slices hold their edges in memory up to this
	 * share of `avail`, then spill them to a file: half, because the
	 * slices' arrays are then concatenated into one of the same size. */
	VD_BUDGET_LOSSY_SLICES_DIV = 2,
	/* The graph is clustered in memory only when it needs at most
	 * `avail / DIV * (DIV - 1)`: the last part is left to the Markov
	 * clustering's matrices (an eighth: they are counted as they are
	 * taken, against what the graph leaves, and components that do not
	 * fit side by side are clustered one at a time, so a small part
	 * suffices for all but a component alone too large). */
	VD_BUDGET_LOSSY_MARKOV_DIV = 8,
	/* A spilled graph is read back a group of components at a time: a
	 * group's graph within this share of what is left beside the level's
	 * arrays, the rest for the Markov clustering of its components (a
	 * budget this tight is one where several groups are read anyway). */
	VD_BUDGET_LOSSY_GROUP_DIV = 2,
	/* The difference's tables of pairs get what the budget leaves beside
	 * the process and both DAGs' voxel counts, less 2 MiB and this share
	 * of the budget: a margin for the heap's own overhead (freed blocks
	 * malloc keeps, fragmentation), which grows with what was allocated. */
	VD_BUDGET_LOSSY_HEAP_MARGIN_DIV = 64,
};
#define VD_BUDGET_LOSSY_HEAP_MARGIN_BYTES ((uint64_t)(2u << 20))

#endif
