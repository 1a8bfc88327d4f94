/* vd_enc.h - the compact encodings (encode/) and their decoders: loading an
 * encoding, looking up a voxel, traversing it.
 */
#ifndef VD_ENC_H
#define VD_ENC_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include "vd_dag.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- encodings (encode.c) */
/* The compact encodings of the SSVDAG paper (section 4.3), byte-compatible
 * with the files of the SymVox reference code; the byte layout is specified
 * in schemas/encodings.md. Four formats:
 *   .svdag    plain DAG in 32-bit words (from a VD_KIND_DAG root)
 *   .ussvdag  the same layout over the SSVDAG, with mirror bytes
 *   .esvdag   4^3 leaf bricks, 16-bit headers with 2-bit child tags, 16/32-bit
 *             tagged pointers, levels sorted by reference count (DAG root)
 *   .ssvdag   the same over the SSVDAG, with mirror bits in the pointers
 * A `struct vd_enc` is a file in memory: built from a root DAG by
 * vd_enc_build(), or read and validated by vd_enc_load(). Every reading
 * function below may assume a validated struct (built or loaded) and never
 * reads out of its arrays. */

enum vd_enc_format {
	VD_ENC_SVDAG = 0,
	VD_ENC_USSVDAG = 1,
	VD_ENC_ESVDAG = 2,
	VD_ENC_SSVDAG = 3,
	VD_ENC_COUNT_,  /* the four SymVox formats: 0 .. VD_ENC_COUNT_-1 */
	/* voxdag's own: the .ssvdag layout over an ssvdag48 chunk, with a
	 * 6-bit cube transform per pointer (schemas/encodings.md). Outside
	 * VD_ENC_COUNT_ so loops over the paper's four stay as they are. */
	VD_ENC_SSVDAG48 = VD_ENC_COUNT_,
	VD_ENC_ALL_
};

/* Bytes of a file that its counted size leaves out: the fixed fields before
 * and between the arrays (bounding box, side, levels, counts). A file's size
 * is vd_enc_size_bytes() plus this. */
#define VD_ENC_HEADER_BYTES_WORDS 44   /* .svdag, .ussvdag */
#define VD_ENC_HEADER_BYTES_COMPACT 48 /* .esvdag, .ssvdag */

/* "svdag", "ussvdag", "esvdag", "ssvdag", "ssvdag48" (also the file
 * extensions), or "unknown". */
const char *vd_enc_format_name(int format);

/* The format named by the extension of `path`, or -1. */
int vd_enc_format_from_path(const char *path);

/* 1 for the formats that need a symmetric DAG (USSVDAG, SSVDAG). */
static inline int vd_enc_format_symmetric(int format)
{
	return format == VD_ENC_USSVDAG || format == VD_ENC_SSVDAG;
}

/* 1 for the compact formats (ESVDAG, SSVDAG, SSVDAG48). */
static inline int vd_enc_format_compact(int format)
{
	return format == VD_ENC_ESVDAG || format == VD_ENC_SSVDAG ||
	       format == VD_ENC_SSVDAG48;
}

/* The chunk kind a format is built from: VD_KIND_DAG, VD_KIND_SSVDAG or
 * VD_KIND_SSVDAG48. */
static inline uint32_t vd_enc_format_kind(int format)
{
	return format == VD_ENC_SSVDAG48 ? VD_KIND_SSVDAG48
	       : vd_enc_format_symmetric(format) ? VD_KIND_SSVDAG : VD_KIND_DAG;
}

/* One file. Unused arrays are NULL and their counts 0. */
struct vd_enc {
	int format;               /* enum vd_enc_format */
	float bbox_min[3], bbox_max[3]; /* tight bounding box, world units */
	float root_side;          /* side of the cube, world units */
	uint32_t levels;          /* L: 2^L voxels per side */
	uint32_t node_count;      /* distinct DAG nodes on levels 0..L-1 */
	/* .svdag, .ussvdag: nodes level by level from the root */
	uint32_t first_leaf_word; /* word index of the first level L-1 node */
	uint32_t word_count;
	uint32_t *words;
	/* .esvdag, .ssvdag */
	uint32_t inner_count;     /* uint16 units of inner[] (levels 0..L-3) */
	uint16_t *inner;
	uint32_t leaf_bytes;      /* 8 per brick (level L-2 nodes) */
	uint8_t *leaves;
	uint32_t level_count;     /* L-2 */
	uint32_t *level_offsets;  /* start of inner level l in inner[] */
};

/* Encodes the root chunk `dag` (chunk_level 0) into `e` in `format`, with
 * the bounding box and side of `t`. The symmetric formats need a
 * VD_KIND_SSVDAG `dag`, the others a VD_KIND_DAG one (VD_ERR_WRONG_KIND).
 * The compact formats need L >= 3, one inner level above the bricks
 * (VD_ERR_UNSUPPORTED). VD_ERR_RANGE when a level holds more than the
 * format can address (compact: addresses from 2^30 on, more than 2^29 - 1
 * bricks; words: 2^32 words or more). An empty `dag` gives the empty scene
 * of schemas/encodings.md. Release `e` with vd_enc_release(), also after a
 * failure. */
int vd_enc_build(struct vd_enc *e, int format, const struct vd_dag *dag,
		 const struct vd_transform *t);

/* The counted size in bytes (schemas/encodings.md): 4*word_count, or
 * 2*inner_count + leaf_bytes + 4*level_count. */
uint64_t vd_enc_size_bytes(const struct vd_enc *e);

/* Writes `e` to `path` atomically (vd_atomic_*: temporary name, fsync,
 * rename, directory fsync). */
int vd_enc_save(const struct vd_enc *e, const char *path);

/* Reads and validates the file `path`; `format` -1 takes it from the
 * extension. Errors: VD_ERR_IO, VD_ERR_ARG (unknown extension),
 * VD_ERR_TRUNCATED, VD_ERR_TRAILING, VD_ERR_CORRUPT (a pointer out of its
 * level, a node overlapping the next level, an empty brick, ...),
 * VD_ERR_UNSUPPORTED (levels out of 1..21, compact with L < 3). */
int vd_enc_load(struct vd_enc *e, const char *path, int format);

/* The same on `size` bytes in memory (copied). */
int vd_enc_parse(struct vd_enc *e, const void *data, size_t size,
		 int format);

/* Frees the arrays of `e` and zeroes it; accepts a zeroed struct. */
void vd_enc_release(struct vd_enc *e);

/* A node reached from the root, for traversal (render): its level, where
 * it is stored and the reflection accumulated on the way (child-index bits,
 * as in the DAG block). The view below applies the reflection, so callers
 * work with logical child slots and voxels only. */
struct vd_enc_node {
	int level;      /* 0 (root) .. L-1 */
	uint64_t at;    /* words: index of the node's first word; compact:
			   index in inner[] (levels < L-2) or byte offset in
			   leaves[] (level L-2) */
	unsigned refl;  /* accumulated reflection, 0..7; for .ssvdag48 the
			   accumulated cube transform, 0..47 ("Cube group") */
};

/* The root (level 0, unreflected). */
void vd_enc_root(const struct vd_enc *e, struct vd_enc_node *n);

/* The level whose nodes are bricks: L-2 for the compact formats; for the
 * word formats L-2 too (a brick is assembled from the 8 masks below), or
 * -1 when L == 1 (the root is a 2x2x2 mask). */
int vd_enc_brick_level(const struct vd_enc *e);

/* The logical child mask of `n` (bit p set when child p = 4x+2y+z is not
 * empty); for a level L-1 node of a word format, its voxel mask. */
unsigned vd_enc_node_mask(const struct vd_enc *e, const struct vd_enc_node *n);

/* Fills *child with logical child p (0..7) of `n`, a node above the brick
 * level. Returns 1, or 0 when that child is empty. */
int vd_enc_child(const struct vd_enc *e, const struct vd_enc_node *n,
		 unsigned p, struct vd_enc_node *child);

/* The 4x4x4 voxels of `n`, a node on the brick level, in the header's
 * brick layout (Morton bits) and logical orientation. */
uint64_t vd_enc_brick(const struct vd_enc *e, const struct vd_enc_node *n);

/* Calls fn(ctx, key, brick) for every non-empty brick in Morton order, as
 * vd_dag_expand() does (for L < 2 one brick, key 0). Stops at and returns
 * the first non-zero return of fn. */
int vd_enc_expand(const struct vd_enc *e,
		  int (*fn)(void *ctx, uint64_t key, uint64_t brick),
		  void *ctx);

/* One row of the SSVDAG paper's Table 2 (and the voxels of Table 1). Node
 * counts as schemas/encodings.md says: distinct nodes over levels
 * 0..levels-1. */
struct vd_enc_row {
	int levels;                     /* resolution 2^levels */
	uint64_t voxels;
	uint64_t svo_nodes;             /* SVO nodes, levels 0..levels-1 */
	uint64_t dag_nodes;             /* SVDAG = ESVDAG */
	uint64_t ssvdag_nodes;          /* SSVDAG = USSVDAG (0 without one) */
	uint64_t ssvdag48_nodes;        /* SSVDAG48 (0 without one) */
	int has_ssvdag, has_ssvdag48;   /* which symmetric DAGs were given */
	uint64_t svo_bytes;             /* one byte per SVO node */
	uint64_t bytes[VD_ENC_ALL_];    /* vd_enc_size_bytes() per format */
	int has[VD_ENC_ALL_];           /* 0: not encodable (compact, L < 3)
					   or its DAG not given */
};

/* Computes the row of resolution 2^levels from the root DAG and the
 * SSVDAG and/or 48-group SSVDAG of one scene (same depth and voxels, else
 * VD_ERR_MISMATCH; `ssvdag` or `ssvdag48` may be NULL, not both), cutting
 * each at `levels` and encoding the cuts in memory. */
int vd_enc_table_row(const struct vd_dag *dag, const struct vd_dag *ssvdag,
		     const struct vd_dag *ssvdag48, int levels,
		     struct vd_enc_row *row);

/* Build times for Table 1, summed over the statistics files of the DAG
 * stages (load + build + save of each); negative when not given. */
struct vd_enc_timing {
	double seconds_svo_to_dag;
	double seconds_symmetry_merge;
};

/* Adds the seconds of one statistics file written by svo-to-dag or
 * symmetry-merge (by its "tool" field) to `t`. VD_ERR_FORMAT when the file
 * is not such a statistics file. */
int vd_enc_timing_add(struct vd_enc_timing *t, const char *stats_path);

/* Writes the tables as DIR/NAME.tables.json, DIR/NAME.table1.csv,
 * DIR/NAME.table2.csv and DIR/NAME.tables.md (each atomically). rows[0] is
 * the highest resolution. */
int vd_enc_write_tables(const char *dir, const char *name,
			const struct vd_enc_row *rows, size_t n,
			const struct vd_enc_timing *t, double seconds_encode);

/* One run of the encode stage, as its main() sets it up. */
struct vd_enc_job {
	const char *tool;          /* "encode", for messages */
	const char *dag_path;      /* root DAG chunk */
	const char *ssvdag_path;   /* root SSVDAG chunk, or NULL */
	const char *ssvdag48_path; /* root ssvdag48 chunk, or NULL (not both) */
	const char *outdir;        /* created if missing */
	const char *name;          /* output base name ("scene") */
	const char *const *stats_paths; /* DAG stage statistics, or NULL */
	size_t n_stats;
	int min_level;             /* lowest resolution row, 2^min_level */
	uint64_t mem_budget_bytes; /* 0: no limit */
	int threads;               /* rows computed in parallel; 0: all */
	int quiet;                 /* no summary on stderr */
};

/* Loads the root chunks, writes DIR/NAME.{svdag,esvdag}, with an SSVDAG
 * DIR/NAME.{ussvdag,ssvdag}, with an ssvdag48 DIR/NAME.ssvdag48,
 * the tables and DIR/NAME.encode.stats.json. On failure the detail is the
 * whole message after the tool name ("cannot read 'x.dag': truncated file:
 * ..."). */
int vd_enc_run(const struct vd_enc_job *job);

#ifdef __cplusplus
}
#endif

#endif /* VD_ENC_H */
