/* vd_edit.h - editing the compressed DAG in place (edit/): the HashDAG, edit
 * operations, undo, garbage collection.
 */
#ifndef VD_EDIT_H
#define VD_EDIT_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include "vd_dag.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ------------------------------------------------------- edit (lib/edit/)
 * The HashDAG of Careil, Billeter and Eisemann (2020) on the CPU: a root
 * DAG chunk loaded into per-level hashed tables so that edits (fill, carve,
 * copy) descend only where they change something, find or append the new
 * nodes by hashing and yield a new root while the old roots stay valid
 * (undo / redo). Per level, 2^P buckets of 2^M 32-bit words are reserved
 * as virtual memory (mmap MAP_NORESERVE) and committed only when touched;
 * a node's pointer is bucket << M | offset. Inner nodes are hashed with
 * XXH3, the 4x4x4 leaf bricks with a 64-bit bit mixer. A full bucket fails
 * the edit with VD_ERR_BUDGET (the scene is left as it was): run gc, or
 * reserve more (larger buckets_log2 / bucket_words_log2). Saving writes the
 * minimal DAG svo-to-dag would build for the same voxels, byte for byte.
 * The line format of edit scripts and the shell: schemas/edit-script.md. */
struct vd_hashdag;

struct vd_hashdag_opts {
	int buckets_log2;      /* P: level l gets 2^min(P, 3 l + 4) buckets;
				  0: automatic, from the level's size at
				  load (buckets at most half full, at least
				  2^min(3 l + 4, 10)) */
	int bucket_words_log2; /* M (0: 10); P + M <= 30 */
	int threads;           /* 0: all cores */
	int split_level;       /* edits run one job per node of this level
				  (0: 3, clamped to L-2) */
	uint64_t mem_budget_bytes; /* 0: none. Else the bucket tables, the
				  committed pages of every level (counted
				  per 4 KiB page a bucket touches, so an
				  over-estimate when buckets are smaller than
				  a page) and the colour arrays stay under it:
				  loading or an edit that would pass it fails
				  with VD_ERR_BUDGET naming what it needs */
	int colour_segment_log2; /* with colours: each cell's colour array is
				  kept in segments, the subtrees of side
				  2^this, so an edit rebuilds the segments
				  it meets only (0: 6; clamped to the cell
				  and brick sides) */
	uint64_t colour_batch_bytes; /* with colours: an edit reads the old
				  colours still in the source and a copy
				  its source segments for batches of
				  segments holding about this many bytes
				  at once (0: 8 MiB); for tests */
};

enum vd_edit_kind { VD_EDIT_FILL, VD_EDIT_CARVE, VD_EDIT_COPY,
		    VD_EDIT_PAINT };
enum vd_edit_shape { VD_SHAPE_BOX, VD_SHAPE_SPHERE };

/* One edit in voxel coordinates. Box: voxels lo..hi inclusive, inside the
 * grid. Sphere: voxels whose centre (x + 0.5, y + 0.5, z + 0.5) is at
 * distance <= r of c. Copy: the box lo..hi of the scene before the edit is
 * written (set and cleared voxels) at dst..dst + hi - lo. */
struct vd_edit_op {
	int kind;              /* enum vd_edit_kind */
	int shape;             /* enum vd_edit_shape (copy: box) */
	int64_t lo[3], hi[3];  /* box */
	double c[3], r;        /* sphere */
	int64_t dst[3];        /* copy destination corner */
	int has_rgb;           /* fill, paint: rgb given (paint needs it) */
	uint8_t rgb[3];        /* sRGB colour */
};

/* What one edit (or gc) did. */
struct vd_edit_stats {
	uint64_t voxels_changed;
	uint64_t nodes_added[VD_MAX_LEVELS];  /* per level 0..L-2 */
	double seconds;
	uint64_t hash_bytes;                  /* committed bytes afterwards */
	double cpu_seconds;                   /* CPU time of the process
						 (all threads): the machine
						 may be shared */
	uint64_t colour_cells_rebuilt;        /* with colours: cells whose
						 colour array was rebuilt */
};

/* Loads a root DAG chunk (kind dag, chunk_level 0, L >= 3). `o` may be
 * NULL. Free with vd_hashdag_free(). */
int vd_hashdag_load(struct vd_hashdag **out, const char *path,
		    const struct vd_hashdag_opts *o);
/* The same from a DAG in memory placed by `t`. */
int vd_hashdag_from_dag(struct vd_hashdag **out, const struct vd_dag *dag,
			const struct vd_transform *t,
			const struct vd_hashdag_opts *o);
void vd_hashdag_free(struct vd_hashdag *h);

int vd_hashdag_levels(const struct vd_hashdag *h);
const struct vd_transform *vd_hashdag_transform(const struct vd_hashdag *h);

/* Checks `op` against the grid (VD_ERR_RANGE, detail says what). */
int vd_edit_op_check(const struct vd_hashdag *h, const struct vd_edit_op *op);

/* Applies `op` to the current scene and makes the result current (the redo
 * part of the history is dropped). VD_ERR_UNSUPPORTED for paint or a
 * colour without colours (vd_hashdag_colours_open), VD_ERR_BUDGET for a
 * full bucket or the memory budget (nothing changes). `st` may be NULL.
 * With colours, the scene's colour array follows the edit (colour rules
 * in schemas/edit-script.md): filled voxels take op->rgb, or the default
 * colour when the op has none; carved voxels drop theirs; copied voxels
 * take their source's; paint sets op->rgb on the set voxels of the region
 * (for paint, voxels_changed counts the voxels whose colour changed). Only
 * the colours of the segments (opts.colour_segment_log2) the region meets
 * are rebuilt; the others are shared with the previous root of the
 * history, so an edit costs what its region holds, not what its cells
 * hold. */
int vd_hashdag_apply(struct vd_hashdag *h, const struct vd_edit_op *op,
		     struct vd_edit_stats *st);

/* Steps through the history: VD_ERR_RANGE when there is nothing to undo or
 * redo. */
int vd_hashdag_undo(struct vd_hashdag *h);
int vd_hashdag_redo(struct vd_hashdag *h);

/* Garbage collection: keeps the current root (keep_history 0; the history
 * becomes that one root) or every root of the history, drops every other
 * node and compacts each level bottom-up into fresh tables. Afterwards the
 * tables hold exactly the nodes reachable from the kept roots. */
int vd_hashdag_gc(struct vd_hashdag *h, int keep_history,
		  struct vd_edit_stats *st);

/* Per level 0..L-2: nodes stored, and nodes reachable from the current
 * root (either may be NULL). */
void vd_hashdag_counts(const struct vd_hashdag *h, uint64_t *stored,
		       uint64_t *reachable);
/* Bytes of the committed pages of the tables plus their bookkeeping. */
uint64_t vd_hashdag_memory_bytes(const struct vd_hashdag *h);
/* Fullest bucket of level l, in words used. */
uint32_t vd_hashdag_max_bucket(const struct vd_hashdag *h, int l);

/* The current scene as SVO bricks (Morton order), as the minimal DAG that
 * svo-to-dag builds from those bricks, or saved as a root DAG chunk. */
int vd_hashdag_to_svo(const struct vd_hashdag *h, struct vd_svo *svo);
int vd_hashdag_to_dag(const struct vd_hashdag *h, struct vd_dag *dag);
int vd_hashdag_save(const struct vd_hashdag *h, const char *path,
		    const char *provenance);

/* Colours (stages/lib/edit/colours.c). The scene's colour array (the
 * colour paper's depth-first order) kept per cell of the source's chunk
 * level (a packed file's cells; min(3, L-2) when unknown) in segments,
 * each cell's table of segments and each segment shared between the roots
 * of the history that did not change it,
 * so undo, redo and gc carry colours along. `src` is what
 * vd_colour_source_open() takes (a voxelize directory of .col chunks or a
 * colorize packed file); it must hold exactly the current scene's voxels
 * at the same depth (VD_ERR_MISMATCH). `fill_rgb` is the colour of voxels
 * a fill without a colour adds (NULL: VD_EDIT_DEFAULT_RGB). */
#define VD_EDIT_DEFAULT_RGB {128, 128, 128}
int vd_hashdag_colours_open(struct vd_hashdag *h, const char *src,
			    const uint8_t *fill_rgb);
/* 1 when the scene has colours. */
int vd_hashdag_has_colours(const struct vd_hashdag *h);
/* The current scene's colour array, 3 bytes per voxel in depth-first
 * order (*rgb: free with free()); VD_ERR_UNSUPPORTED without colours. */
int vd_hashdag_colour_array(const struct vd_hashdag *h, uint8_t **rgb,
			    uint64_t *voxels);
/* How the current scene's colours are held: voxels, segments, the bytes
 * of their compressed blocks as charged against the memory budget (each
 * segment counted once per cell of the scene holding it), blocks per
 * mode of the auto codec (enum vd_auto_mode >> 4) of the segments edits
 * wrote, and the voxels of the segments no edit wrote, whose colours are
 * still only in the source (read on demand, no blocks, no bytes).
 * VD_ERR_UNSUPPORTED without colours. */
struct vd_hashdag_colour_stats {
	uint64_t voxels, segments, bytes;
	uint64_t mode_blocks[5];
	uint64_t source_voxels;
};
int vd_hashdag_colour_stats(const struct vd_hashdag *h,
			    struct vd_hashdag_colour_stats *st);
/* Writes the current scene as a voxelize-style directory `dir`: per
 * non-empty cell its SVO chunk and colour chunk (chunk-L<C>-<cell>.svo,
 * .col) and a manifest, staged and published whole (vd_dir_stage). Cells
 * whose colours and voxels are those loaded from a source directory are
 * hard links to the source's files (copies when links fail); the others
 * are written. So render --colours DIR and colorize DIR take it. */
int vd_hashdag_colours_save(const struct vd_hashdag *h, const char *dir,
			    const char *provenance);

/* The first half of vd_hashdag_colours_save, for publishing the colours
 * together with the DAG: writes the directory complete (cells and
 * manifest) under the staging name it puts in `staging` (cap bytes), for
 * the caller to publish with vd_dir_swap() or drop with vd_dir_abandon().
 * On failure nothing is left behind. */
int vd_hashdag_colours_stage(const struct vd_hashdag *h, const char *dir,
			     const char *provenance, char *staging,
			     size_t cap);

/* One run of the edit tool (script.c). */
struct vd_edit_job {
	const char *tool;         /* "edit" */
	const char *input;        /* root DAG chunk */
	const char *output;       /* edited chunk; statistics beside it with
				     ".stats.json" (script mode) */
	const char *script;       /* script file, or NULL for the shell */
	FILE *in, *out;           /* shell streams */
	const char *provenance;
	struct vd_hashdag_opts opts;
	int quiet;
	const char *colours;      /* colour source, or NULL */
	const char *colours_out;  /* colour directory written beside output */
	int has_fill_rgb;
	uint8_t fill_rgb[3];      /* default fill colour (has_fill_rgb) */
};

/* Script mode: parses and checks the whole script first (errors name line
 * and column), loads, applies, saves and writes the statistics. Shell mode
 * (script NULL): reads lines from job->in and answers on job->out. On
 * failure the detail is the whole message after the tool name. */
int vd_edit_run(const struct vd_edit_job *job);

#ifdef __cplusplus
}
#endif

#endif /* VD_EDIT_H */
