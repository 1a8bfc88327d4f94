/* vd_dag.h - sparse voxel DAGs (dag/): SVDAG and SSVDAG chunks, the
 * 48-symmetry group, bottom-up reduction and merges, lossy clustering.
 */
#ifndef VD_DAG_H
#define VD_DAG_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include "vd_voxel.h"

#ifdef __cplusplus
extern "C" {
#endif

/* -------------------------------------------------- DAG and SSVDAG (dag/) */
/* Built and merged in build.c, expanded in expand.c, checked in verify.c,
 * stored in dag_file.c, compared with SVOs in compare.c, run as the stages
 * svo-to-dag and symmetry-merge in stage.c. */
/* A DAG chunk in memory: the minimal SVDAG (VD_KIND_DAG) or SSVDAG
 * (VD_KIND_SSVDAG) of one cell at `chunk_level`, or its 48-group version
 * (VD_KIND_SSVDAG48: `refl` holds cube transforms 0..47, see "Cube group"
 * below, and minimality is under all 48). Specified on disk in
 * schemas/chunk-format.md, "DAG and SSVDAG chunks" and "48-group SSVDAG
 * chunks".
 *
 * Levels are indexed by their absolute level l in the grid and run from
 * chunk_level (the cell's root, one node; none when the cell is empty) to
 * levels-1. A node on level l < levels-1 has an 8-bit child mask (bit c set
 * when child c = 4x+2y+z is non-empty) and one reference per set bit, in
 * increasing slot order: node i's references are first[i] .. first[i+1]-1.
 * A reference is the index of a node on level l+1, and in an SSVDAG also a
 * 3-bit reflection. Level levels-1 holds 2x2x2 voxel masks (bit c = voxel c)
 * and no references. Level levels-2 (when levels >= 2) is additionally
 * available as 4x4x4 bricks in `bricks`, in the header's brick layout.
 *
 * Reflections: a 3-bit value m uses child-index bits, bit 2 (4) = mirror
 * along X, bit 1 (2) = along Y, bit 0 (1) = along Z, so reflecting a node by
 * m moves child slot p to slot p ^ m and reflects that child by m too.
 * (The SymVox files put X, Y, Z in pointer bits 13, 14, 15 / 29, 30, 31: the
 * encoder maps bit 2 -> X, 1 -> Y, 0 -> Z.) A reference (i, m) means "node i
 * reflected by m". Reflections compose by XOR down a path: in a node reached
 * with accumulated reflection a, logical child slot p is stored slot p ^ a,
 * and the child is reached with a ^ m. A 2x2x2 mask reflected by m moves bit
 * c to bit c ^ m; a brick reflected by m moves byte c to byte c ^ m and
 * reflects each byte by m (vd_brick_reflect()).
 *
 * Minimality: no two nodes on a level represent the same subtree (DAG), or
 * subtrees equal up to any of the 8 reflections (SSVDAG). Every node is
 * reachable from the root. SSVDAG nodes below the root are the canonical
 * representatives of their class; the root is stored as the cell really is
 * (unreflected), so a chunk never needs a reflection on its root. An SSVDAG
 * reference's reflection is normalized (the smallest of m ^ g over the
 * reflections g its child is invariant under), so equal subtrees are
 * referenced by equal bytes. Nodes on a level are in the order they were
 * first met: deterministic, independent of --threads, meaningless.
 */
struct vd_dag_level {
	uint64_t nodes;   /* nodes on this level */
	uint64_t refs;    /* references held by this level's nodes (0 on L-1) */
	uint8_t *mask;    /* nodes child masks; on level L-1 the voxel masks */
	uint64_t *first;  /* nodes+1 offsets into child/refl; NULL on L-1 */
	uint32_t *child;  /* refs indices into level l+1; NULL on L-1 */
	uint8_t *refl;    /* refs reflections (SSVDAG), transforms 0..47
			     (SSVDAG48); NULL in a DAG */
};

struct vd_dag {
	uint32_t kind;         /* VD_KIND_DAG, VD_KIND_SSVDAG or _SSVDAG48 */
	int levels;            /* grid depth L */
	int chunk_level;       /* level of the cell (its root) */
	uint64_t cell_morton;  /* Morton code of the cell at chunk_level */
	uint64_t voxels;       /* voxels in the cell */
	struct vd_dag_level lv[VD_MAX_LEVELS]; /* [chunk_level, levels-1] used */
	uint64_t *bricks;      /* lv[L-2].nodes bricks of level L-2 (the stored,
				  unreflected nodes); NULL when L < 2, when
				  the root is below level L-2, or the cell is
				  empty */
};

/* Options of the DAG builders. */
struct vd_dag_opts {
	int threads;               /* 0: all cores */
	uint64_t mem_budget_bytes; /* 0: no limit */
	const char *const *part_names; /* merge: names of the parts for error
					  details (file names), or NULL */
};

/* What a build or merge measured. */
struct vd_dag_stats {
	uint64_t input_voxels;
	uint64_t input_nodes;                 /* bricks or part nodes read */
	double seconds_level[VD_MAX_LEVELS];  /* reduction time per level */
	double seconds_build;                 /* whole build */
	uint64_t memory_estimate_bytes;       /* what the budget check used */
};

/* Section tags of DAG chunks. */
#define VD_TAG_DAGM VD_TAG('D', 'A', 'G', 'M') /* node masks, all levels */
#define VD_TAG_DAGC VD_TAG('D', 'A', 'G', 'C') /* child indices, uint32 */
#define VD_TAG_DAGR VD_TAG('D', 'A', 'G', 'R') /* child reflections, uint8 */

/* Reflects a 2x2x2 mask by m (bit c -> bit c ^ m). */
static inline uint8_t vd_mask_reflect(uint8_t v, unsigned m)
{
	if (m & 1) v = (uint8_t)((v & 0x55) << 1 | (v >> 1 & 0x55));
	if (m & 2) v = (uint8_t)((v & 0x33) << 2 | (v >> 2 & 0x33));
	if (m & 4) v = (uint8_t)(v << 4 | v >> 4);
	return v;
}

/* Reflects a brick by m: local Morton bit b -> b ^ (m << 3 | m). */
static inline uint64_t vd_brick_reflect(uint64_t v, unsigned m)
{
	const uint64_t k1 = 0x5555555555555555ULL, k2 = 0x3333333333333333ULL,
		       k4 = 0x0f0f0f0f0f0f0f0fULL, k8 = 0x00ff00ff00ff00ffULL,
		       k16 = 0x0000ffff0000ffffULL;
	if (m & 1) {
		v = (v & k1) << 1 | (v >> 1 & k1);
		v = (v & k8) << 8 | (v >> 8 & k8);
	}
	if (m & 2) {
		v = (v & k2) << 2 | (v >> 2 & k2);
		v = (v & k16) << 16 | (v >> 16 & k16);
	}
	if (m & 4) {
		v = (v & k4) << 4 | (v >> 4 & k4);
		v = v << 32 | v >> 32;
	}
	return v;
}

/* The symmetry class of a 2x2x2 mask: `canon` is the largest value among
 * its 8 reflections, `refl` the smallest m with vd_mask_reflect(mask, m) ==
 * canon (so mask == vd_mask_reflect(canon, refl)), and `inv` the set of
 * reflections leaving the mask unchanged (bit m set for each such m; bit 0
 * always). 46 classes, the empty mask included (Burnside: (256 + 7*16)/8). */
struct vd_leaf_class {
	uint8_t canon, refl, inv;
};

/* The 256-entry leaf table, indexed by mask. */
const struct vd_leaf_class *vd_leaf_classes(void);

/* Builds the minimal DAG of `svo` into *dag: kind VD_KIND_DAG (SVDAG),
 * VD_KIND_SSVDAG or VD_KIND_SSVDAG48 (symmetry-merged directly). `svo` must hold strictly
 * increasing, non-zero bricks inside its cell (VD_ERR_CORRUPT otherwise); an
 * empty SVO gives an empty DAG. VD_ERR_BUDGET if opts->mem_budget_bytes is
 * too small for the estimate. `stats` may be NULL. Release *dag with
 * vd_dag_release() (also after a failure). */
int vd_dag_from_svo(struct vd_dag *dag, const struct vd_svo *svo,
		    uint32_t kind, const struct vd_dag_opts *opts,
		    struct vd_dag_stats *stats);

/* Merge mode: builds the chunk of the cell at `chunk_level` that contains
 * the `n` chunks parts[0..n-1] (any order), reducing again from the leaf
 * level so that subtrees shared across parts become one; cells absent from
 * `parts` are empty. `kind` VD_KIND_DAG needs DAG parts; VD_KIND_SSVDAG
 * accepts DAG and SSVDAG parts (so one DAG part at its own chunk level is
 * the symmetry merge). chunk_level -1 means one level above the shallowest
 * part. VD_KIND_SSVDAG48 accepts parts of all three kinds;
 * VD_KIND_SSVDAG refuses ssvdag48 parts. Errors: VD_ERR_EMPTY (n == 0), VD_ERR_MISMATCH (different depths,
 * overlapping cells, cells not inside one cell at chunk_level),
 * VD_ERR_WRONG_KIND, VD_ERR_BUDGET. Release *out with vd_dag_release(). */
int vd_dag_merge(struct vd_dag *out, const struct vd_dag *const *parts,
		 size_t n, uint32_t kind, int chunk_level,
		 const struct vd_dag_opts *opts, struct vd_dag_stats *stats);

/* vd_dag_merge on parts[0..n-1] it takes over: it frees each part's levels
 * as soon as it has read them (so the merge's lower levels are never held
 * twice, as parts and as output) and releases every part before it
 * returns, whatever the outcome. Its peak is the one
 * vd_dag_estimate_merge() bounds; vd_dag_merge, which only reads its
 * parts, holds them whole to the end and is checked against a larger
 * bound. */
int vd_dag_merge_consume(struct vd_dag *out, struct vd_dag *parts, size_t n,
			 uint32_t kind, int chunk_level,
			 const struct vd_dag_opts *opts,
			 struct vd_dag_stats *stats);

/* Calls fn(ctx, key, brick) for every non-empty brick of `dag` in Morton
 * order, applying reflections (key and brick as in struct vd_svo; for
 * L < 2 one brick, key 0). Stops at and returns the first non-zero return
 * of fn. */
int vd_dag_expand(const struct vd_dag *dag,
		  int (*fn)(void *ctx, uint64_t key, uint64_t brick),
		  void *ctx);

/* The outcome of vd_dag_compare_svo(). */
struct vd_dag_diff {
	uint64_t differing_voxels;   /* 0: equal */
	uint64_t first_voxel_morton; /* the first difference in Morton order,
					a voxel Morton code (3*L bits) */
	int first_in_dag;            /* 1: that voxel is set in the DAG only,
					0: in the SVO chunks only */
};

/* Compares the voxels of `dag` with the union of the SVO chunks
 * svos[0..n-1] (any order), streaming the DAG's expansion. The SVO cells
 * must lie inside the DAG's cell, have its depth and not overlap
 * (VD_ERR_MISMATCH otherwise); voxels of the DAG outside every SVO cell
 * count as differences. Fills *diff and returns VD_OK whether or not they
 * differ. */
int vd_dag_compare_svo(const struct vd_dag *dag,
		       const struct vd_svo *const *svos, size_t n,
		       struct vd_dag_diff *diff);

/* Expands `dag` into a new SVO (release with vd_svo_release()). */
int vd_dag_to_svo(const struct vd_dag *dag, struct vd_svo *svo);

/* Checks the structure: counts, masks, indices and reflections in range,
 * every node referenced, root count. VD_ERR_CORRUPT with the detail naming
 * the first problem. */
int vd_dag_validate(const struct vd_dag *dag);

/* Fills h->kind, levels, chunk_level, cell_morton and level counts from
 * `dag` (the transform is left alone). */
void vd_dag_header(const struct vd_dag *dag, struct vd_chunk_header *h);

/* Writes `dag` as a chunk file at `path` (atomic). */
int vd_dag_save(const struct vd_dag *dag, const struct vd_transform *t,
		const char *path, const char *provenance);
/* The same, with the DAG's check and its reflections section (DAGR)
 * compressed beside the child section on up to `threads` threads (0: all
 * cores); the file is byte for byte vd_dag_save's. Memory: DAGR
 * compressed, held until DAGC is written (at most a byte a reference). */
int vd_dag_save_mt(const struct vd_dag *dag, const struct vd_transform *t,
		   const char *path, const char *provenance, int threads);

/* Reads a DAG chunk file: `kind` VD_KIND_DAG, VD_KIND_SSVDAG,
 * VD_KIND_SSVDAG48, VD_KIND_ANY (dag or ssvdag: what the stages after the
 * symmetry merge read) or VD_KIND_ANY_DAG (any of the three);
 * VD_ERR_WRONG_KIND for other kinds.
 * Validates as vd_dag_validate() and checks the voxel count. `h` may be
 * NULL. Release with vd_dag_release(). */
#define VD_KIND_ANY_DAG 0x100u
int vd_dag_load(struct vd_dag *dag, struct vd_chunk_header *h,
		const char *path, uint32_t kind);

/* The same from an opened chunk. */
int vd_dag_from_chunk(struct vd_dag *dag, const struct vd_chunk *c,
		      uint32_t kind);
/* The same, its sections decompressed on up to `threads` threads. */
int vd_dag_from_chunk_mt(struct vd_dag *dag, const struct vd_chunk *c,
			 uint32_t kind, int threads);

/* Bytes held by `dag`. */
uint64_t vd_dag_memory_bytes(const struct vd_dag *dag);

/* Upper bound of the peak bytes of vd_dag_from_svo() on an SVO with
 * `bricks` bricks, `leaves` non-empty level L-1 nodes and `parents`
 * non-empty level L-3 nodes (the SVO header's per-level counts); input
 * included. A bound, not a guess: it assumes no two nodes are equal, so a
 * real scan needs about half. The stage compares it with --mem-budget
 * before loading anything. */
uint64_t vd_dag_estimate_from_svo(uint64_t bricks, uint64_t leaves,
				  uint64_t parents);

/* The per-level totals of a merge's parts, all that its memory bound
 * needs. Zero it, then add each part (loaded, or by its header). */
struct vd_dag_census {
	int levels;                    /* grid depth L (the first part's) */
	uint64_t parts;                /* parts added */
	uint64_t nodes[VD_MAX_LEVELS]; /* nodes on level l, over the parts */
	uint64_t refs[VD_MAX_LEVELS];  /* references held on level l */
	uint64_t largest;              /* the largest part's section bytes */
	uint64_t big_nodes[VD_MAX_LEVELS]; /* most nodes of one part on l */
	uint64_t big_refs[VD_MAX_LEVELS];  /* most references of one part */
};

/* Adds a loaded part (exact counts). */
void vd_dag_census_add(struct vd_dag_census *c, const struct vd_dag *d);

/* Adds a part by its chunk header: an SVO header's counts bound those of
 * its DAG (references on level l: the SVO's nodes on level l+1); a DAG
 * header's node counts are exact and its references bounded by 8 per node,
 * as headers do not count them. */
void vd_dag_census_add_header(struct vd_dag_census *c,
			      const struct vd_chunk_header *h);

/* Upper bound of the peak bytes of vd_dag_merge_consume() into `kind` on
 * parts with census `c`, loading the parts (vd_dag_run) included. Assumes no
 * two nodes are equal, so a merge that shares much needs less. It is
 * subadditive: the bound of parts A and B together is at most the sum of
 * theirs less VD_DAG_ESTIMATE_FIXED_BYTES, so a planner may sum shares. */
uint64_t vd_dag_estimate_merge(const struct vd_dag_census *c, uint32_t kind);

/* The bound from a chunk header alone, as the stages check it before
 * loading (and as a planner should): for an SVO header, what svo-to-dag
 * needs; for a DAG or SSVDAG header, that input's share of a merge or
 * symmetry merge into its own kind (vd_dag_estimate_merge() of its census
 * for another). Sum the shares of a merge's inputs; each share includes
 * the fixed 16 MiB, so subtract VD_DAG_ESTIMATE_FIXED_BYTES per input
 * beyond the first. */
#define VD_DAG_ESTIMATE_FIXED_BYTES (16ull << 20)
uint64_t vd_dag_estimate_header(const struct vd_chunk_header *h);

/* Writes the statistics of a build (`tool` names the stage; `seconds_load`
 * and `seconds_save` are the caller's phases) as JSON to `path` (atomic):
 * per-level node and reference counts, seconds per phase, peak RSS. */
int vd_dag_write_stats(const struct vd_dag *dag,
		       const struct vd_dag_stats *st, const char *tool,
		       double seconds_load, double seconds_save,
		       const char *path);

/* One run of the svo-to-dag or symmetry-merge stage, as its main() sets
 * it up from the command line. */
struct vd_dag_job {
	const char *tool;          /* "svo-to-dag": messages and statistics */
	uint32_t kind;             /* output: VD_KIND_DAG, VD_KIND_SSVDAG or
				      VD_KIND_SSVDAG48 (--group 48) */
	int merge;                 /* inputs are DAG chunks to merge */
	int to_level;              /* merge: output chunk level, -1 default */
	const char *const *inputs; /* input chunk files */
	size_t n_inputs;
	const char *output;        /* output chunk file; statistics go to
				      output + ".stats.json" */
	const char *provenance;    /* stored in the output, or NULL */
	struct vd_dag_opts opts;
	int quiet;                 /* no summary line on stderr */
};

/* Loads the inputs (an SVO chunk for VD_KIND_DAG, a DAG chunk for
 * VD_KIND_SSVDAG; with `merge`, DAG chunks, and for VD_KIND_SSVDAG also
 * SSVDAG chunks), checks the memory budget before each load, builds,
 * saves the output atomically and writes the statistics. On failure the
 * detail is the whole message after the tool name ("cannot read 'x.svo':
 * truncated file: ...") and nothing is left at the output path. */
int vd_dag_run(const struct vd_dag_job *job);

/* Frees everything `dag` holds and zeroes it. Accepts a zeroed struct. */
void vd_dag_release(struct vd_dag *dag);

/* The whole command line of svo-to-dag and symmetry-merge (stage.c):
 * they share their options and differ in `kind`; `usage` is the tool's
 * --help text. Returns the exit status. */
int vd_dag_stage_main(int argc, char **argv, const char *tool, uint32_t kind,
		      const char *usage);

/* The DAG of `dag` (a root chunk, DAG or SSVDAG) cut at depth `levels`
 * (1 <= levels <= dag->levels): a voxel of the 2^levels grid is set iff a
 * voxel below it is set. Reduced again, so it equals the minimal DAG (or
 * SSVDAG) built directly at that depth. `svo_counts` is
 * vd_dag_svo_counts() of `dag` when the caller has it (the tables cut one
 * DAG at many depths), or NULL. Release *out with vd_dag_release(). */
int vd_dag_cut(const struct vd_dag *dag, int levels,
	       const uint64_t *svo_counts, struct vd_dag *out);

/* Per-level node counts of the (pointerless) SVO a root DAG stands for:
 * svo_nodes[l] for l = 0..L, the last being the voxel count. */
int vd_dag_svo_counts(const struct vd_dag *dag,
		      uint64_t svo_nodes[VD_MAX_LEVELS + 1]);

/* ---- Cube group (symmetry-merge --group 48)
 *
 * The 48 symmetries of the cube, numbered t = 8 * k + m: k (0..5) an axis
 * permutation, m (0..7) a reflection in the bits of the 8-reflection group
 * (bit 2 = X, bit 1 = Y, bit 0 = Z). Transform t maps a point p of an
 * n-cube to q with q[i] = p[perm[k][i]] (axis 0 = X, 1 = Y, 2 = Z), then
 * q[i] = n - 1 - q[i] for each axis i reflected by m: permute first, then
 * reflect. t = 0 is the identity; t < 8 are the SSVDAG's reflections with
 * the same numbering. Permutations k: 0 XYZ, 1 XZY, 2 YXZ, 3 YZX, 4 ZXY,
 * 5 ZYX (output axis i takes input axis perm[k][i]). A transformed subtree
 * holds voxel T(p) for each voxel p of the original. */
#define VD_G48 48
/* The cube group has 98 subgroups (its invariance sets). */
#define VD_G48_SUBGROUPS 98

/* perm[k] of transform t: output axis i takes input axis vd_g48_perm(t)[i]. */
const uint8_t *vd_g48_perm(unsigned t);
/* Child index c (bit 2 = x, 1 = y, 0 = z) moved by t. */
unsigned vd_g48_child(unsigned t, unsigned c);
/* The transform p -> a(b(p)). */
unsigned vd_g48_compose(unsigned a, unsigned b);
/* The transform u with vd_g48_compose(t, u) == 0. */
unsigned vd_g48_inverse(unsigned t);
/* A 2x2x2 mask transformed by t: bit c -> bit vd_g48_child(t, c). */
uint8_t vd_g48_mask(uint8_t v, unsigned t);
/* A brick (byte c = child c's mask) transformed by t: local Morton bit
 * c << 3 | c' -> child(t, c) << 3 | child(t, c'). */
uint64_t vd_g48_brick(uint64_t v, unsigned t);

/* The number of subgroups found (VD_G48_SUBGROUPS; a test checks it). */
unsigned vd_g48_subgroup_count(void);

/* The 256-entry leaf table under the 48: `canon` the largest of the 48
 * transforms of the mask, `refl` the transform t with vd_g48_mask(canon, t)
 * == mask, `inv` the index of its invariance subgroup (not a set). */
const struct vd_leaf_class *vd_leaf_classes48(void);

/* ------------------------------------------------ lossy SVDAGs (lossy.c)
 * van der Laan, Scandolo and Eisemann 2020: on each level from height 2
 * (level L-2) up to the root, nodes whose effective reference count (how
 * often their subtree occurs in the scene) is at most max_refs and whose
 * voxels differ by at most m = h^2 * diff_factor (m = 1 at height 2) from
 * another such node are joined in a similarity graph, clustered by Markov
 * clustering per connected component, and every cluster replaced by its
 * member with the largest sum of similarities; the levels above are then
 * reduced losslessly again. The result is an ordinary minimal SVDAG. */
struct vd_lossy_opts {
	double inflation;          /* MCL inflation, > 1 (default 2.0) */
	double diff_factor;        /* p of m = h^2 * p (default 1.0) */
	uint64_t max_refs;         /* R: candidates have <= R effective refs */
	int threads;               /* 0: all cores */
	uint64_t mem_budget;       /* bytes, 0: none. Every phase stays
				    * under it: a level's arrays that do not
				    * fit fail the run (VD_ERR_BUDGET); a
				    * similarity graph that would pass it is
				    * spilled to a file in $TMPDIR (or /tmp)
				    * and clustered a few components at a
				    * time, the Markov clustering's matrices
				    * counted as they grow, with the same
				    * result; a single component over what is
				    * left fails the run (VD_ERR_BUDGET); the
				    * final difference remembers pairs of
				    * subtrees only within what is left,
				    * walking the others again */
	uint64_t graph_budget;     /* bytes for a level's similarity graph in
				    * memory, 0: what is left of mem_budget
				    * beside the process's RSS when the
				    * search starts (a fixed figure for
				    * tests: the RSS varies, under ASan much) */
	int levels;                /* vd_lossy_run: cut the input at this
				    * depth first (vd_dag_cut), a 2^levels
				    * grid; 0: the input's own */
};

struct vd_lossy_level_stats {
	int level, height;
	uint64_t candidates, graph_nodes, edges, clusters, merged;
	uint64_t level_nodes_before, level_nodes_after; /* on this level */
	uint64_t nodes_before, nodes_after;             /* all levels */
	int graph_spilled;       /* the graph went to disk (--mem-budget) */
	uint64_t spill_buckets;  /* then: the groups of components loaded */
};

struct vd_lossy_stats {
	struct vd_lossy_level_stats level[VD_MAX_LEVELS]; /* bottom-up */
	int n_levels;
	uint64_t nodes_before, nodes_after;
	uint64_t voxels_before, voxels_after, voxels_set, voxels_cleared;
	double seconds_eff, seconds_graph, seconds_cluster, seconds_reduce,
	       seconds_diff;
	/* CPU seconds of the process (all threads) over the four phases
	 * above: on a shared machine wall time is not the work done */
	double cpu_seconds_lossy;
	/* vd_lossy_run with levels: seconds of cutting the input */
	double seconds_cut;
};

/* An edge of a similarity graph: u < v, `diff` voxels apart, similarity
 * s = 1 - diff / (m + 1). */
struct vd_lossy_edge {
	uint32_t u, v, diff;
	double s;
};

/* Clusters the SVDAG `dag` in place (VD_ERR_WRONG_KIND for an SSVDAG,
 * VD_ERR_ARG for parameters out of range). The voxel statistics come from
 * vd_dag_diff() of the input and the result. */
int vd_lossy_cluster(struct vd_dag *dag, const struct vd_lossy_opts *o,
		     struct vd_lossy_stats *st);

/* Effective reference counts of the nodes of levels chunk_level..to_level
 * into new arrays eff[l] (free each; the others are set to NULL): the root
 * counts 1, a node the sum of its parents' counts per reference. */
int vd_lossy_effective_refs(const struct vd_dag *dag, int to_level,
			    uint64_t **eff);

/* The similar pairs among the candidates of level l (eff[i] <= max_refs),
 * edges as node indices of level l sorted by (u, v), in a new array
 * (free()); *candidates gets their number. The same for any `threads`. */
int vd_lossy_similar_pairs(const struct vd_dag *dag, int l,
			   const uint64_t *eff, uint64_t max_refs,
			   double diff_factor, int threads,
			   struct vd_lossy_edge **edges,
			   size_t *n_edges, uint64_t *candidates);

/* Markov clustering of the graph of n nodes and edges e[0..ne-1] (u < v,
 * weights s), per connected component, with mcl's defaults (a loop on every
 * node weighing its largest edge weight, pruning below 1/10000, at most
 * 1100 entries per column). cluster[i] = the smallest node of i's cluster.
 * The same clusters for any `threads`. */
int vd_lossy_mcl(uint32_t n, const struct vd_lossy_edge *e, size_t ne,
		 double inflation, int threads, uint32_t *cluster);

/* Voxels set in a but not in b (*only_a) and in b but not in a (*only_b),
 * walking both SVDAGs of the same cell together (pairs of nodes counted
 * once); *voxels_b gets b's voxel count. */
int vd_dag_diff(const struct vd_dag *a, const struct vd_dag *b,
		uint64_t *only_a, uint64_t *only_b, uint64_t *voxels_b);

/* Writes the statistics of a lossy clustering as JSON to `path` (atomic). */
int vd_lossy_write_stats(const struct vd_dag *dag,
			 const struct vd_lossy_opts *o,
			 const struct vd_lossy_stats *st, double seconds_load,
			 double seconds_save, const char *path);

/* The lossy-cluster stage: reads the DAG chunk `in` (kind dag), clusters
 * it, writes `out` and `out`.stats.json (atomic; neither is left on a
 * failure). mem_budget 0: no limit. */
int vd_lossy_run(const char *in, const char *out,
		 const struct vd_lossy_opts *o, uint64_t mem_budget,
		 const char *provenance, int quiet);

#ifdef __cplusplus
}
#endif

#endif /* VD_DAG_H */
