/* edit_internal.h - the HashDAG's internals shared by hashdag.c (tables,
 * load, decode, save, gc), ops.c (fill, carve, copy) and script.c (the
 * line format, the script run and the shell).
 *
 * Levels: 0 (the root) .. L-3 hold inner nodes, L-2 the leaves, 4x4x4
 * bricks stored as two 32-bit words (low word first). An inner node is
 * one word with the 8-bit child mask in its low byte, then one 32-bit
 * pointer per set bit in slot order. A pointer is bucket << M | offset in
 * words inside the bucket, so it never moves; EMPTY (all ones) is the
 * empty subtree and never a valid pointer (P + M <= 30). */
#ifndef VD_EDIT_INTERNAL_H
#define VD_EDIT_INTERNAL_H

#include "voxdag.h"

#include <pthread.h>

#define HD_EMPTY 0xffffffffu
#define HD_LOCKS 1024 /* bucket locks per level (striped) */

struct hd_level {
	uint32_t *words;      /* 2^(P+M) words reserved, committed on touch */
	uint64_t pages;       /* 4 KiB pages touched (budget accounting) */
	uint32_t *used;       /* words used in each of the 2^P buckets */
	int p, m;             /* log2 buckets, log2 words per bucket */
	uint64_t nodes;       /* nodes stored (atomic adds) */
	uint32_t full;        /* the full subtree node, HD_EMPTY if not made */
	pthread_mutex_t lock[HD_LOCKS];
};

/* The colours (RGB8, depth-first) of one segment: the subtree of a node
 * on the segment level S below the cell level C. Shared by reference
 * between the cells' tables that did not change it.
 *
 * A segment no edit has changed stays where it was loaded from (nparts
 * 0): colours src_at .. src_at + n - 1 of its cell's array in the source
 * (a cell's colour chunk, or the packed file), read when an edit, a copy
 * or a save needs them. So loading costs no decoding or encoding, and
 * untouched colours cost no memory: a segment is encoded only when an
 * edit writes it.
 *
 * A segment's colours, once an edit wrote them, kept compressed in the auto codec's blocks
 * (schemas/colour-formats.md, method 4) at max_error 0, so they decode
 * to exactly the colours stored and a saved scene is byte-identical to
 * one kept raw. Blocks are 2^HD_COL_BLOCK_LOG voxels and decode alone: a
 * read touches one directory entry and one block, and a uniform fill of
 * a whole segment is written as constant blocks without a byte of block
 * data. The auto encoder takes at most VD_CPACK_SEGMENT_MAX voxels, so a
 * segment larger than that (a large colour_segment_log2) is several
 * parts of that many voxels end to end. */
#define HD_COL_BLOCK_LOG 8
#define HD_COL_PART_LOG 18 /* VD_CPACK_SEGMENT_MAX */
struct hd_seg {
	uint64_t refs;
	uint64_t n;           /* voxels */
	uint64_t bytes;       /* charged: the struct, directories, data */
	uint64_t src_at;      /* nparts 0: first colour in its cell's source */
	uint32_t nparts;      /* 0: in the source (n > 0 always) */
	struct vd_auto_segment part[];
};

struct hd_cellseg {
	uint64_t code;        /* the segment's node: Morton code at level S */
	struct hd_seg *seg;
};

/* One cell's colours: its non-empty segments in Morton (so depth-first)
 * order, whose arrays put end to end are the cell's colour array. An edit
 * copies the table (a pointer per segment) and rebuilds only the segments
 * its region meets, so its cost follows its size rather than the cell's.
 * The table is shared by reference between the roots of the history that
 * did not change the cell. */
struct hd_cellcol {
	uint64_t refs;
	uint64_t n;           /* voxels */
	uint64_t nseg;
	struct hd_cellseg s[];
};

/* The scene's colours: per root of the history a table of the 8^C cells
 * of chunk level C (NULL: an empty cell), parallel to vd_hashdag.roots. */
struct hd_colours {
	int C, S;                    /* cell and segment levels, C <= S */
	uint64_t ncells;
	struct hd_cellcol ***tab;    /* [cap_roots] */
	struct hd_cellcol **input;   /* the cells as loaded (reuse on save) */
	char *src_dir;               /* the source directory, or NULL */
	/* The source the segments still in it are read from: the cells'
	 * colour chunks in src_dir, or (src_dir NULL) the packed file, open
	 * for the structure's life, cell ci's colours from cell_first[ci]. */
	struct vd_colour_source pack;
	uint64_t *cell_first;
	uint8_t fill_rgb[3];
	uint64_t bytes;              /* of all tables and segments alive */
	/* Set by colours.c when it attaches the colours: the history of roots
	 * (hashdag.c) releases a root's table and, with the scene, the whole
	 * structure through these, so the tables below never call up into the
	 * colour layer. */
	void (*tab_free)(struct hd_colours *c, struct hd_cellcol **tab);
	void (*free)(struct hd_colours *c);
};

struct vd_hashdag {
	int levels;                  /* grid depth L (>= 3) */
	struct vd_transform t;       /* where the grid sits in the world */
	struct vd_hashdag_opts o;
	struct hd_level lv[VD_MAX_LEVELS]; /* 0 .. L-2 */
	uint32_t *roots;             /* history of roots, oldest first */
	size_t nroots, cap_roots, cur; /* roots[cur] is the scene */
	struct hd_colours *col;      /* NULL: no colours */
	uint64_t fixed_bytes;        /* bucket tables, bookkeeping */
	uint64_t committed_bytes;    /* pages of every level (atomic) */
};

/* Node size in words: leaves 2, inner 1 + children. */
static inline uint32_t hd_node_words(const struct vd_hashdag *h, int l,
				     const uint32_t *n)
{
	return l == h->levels - 2 ? 2 : 1 + (uint32_t)__builtin_popcount(n[0] & 0xff);
}

static inline const uint32_t *hd_node(const struct vd_hashdag *h, int l,
				      uint32_t ptr)
{
	return h->lv[l].words + ptr;
}

static inline uint64_t hd_brick(const struct vd_hashdag *h, uint32_t ptr)
{
	const uint32_t *w = hd_node(h, h->levels - 2, ptr);
	return (uint64_t)w[0] | (uint64_t)w[1] << 32;
}

/* The pointer of child slot c of inner node `ptr` on level l (HD_EMPTY
 * when absent or ptr is HD_EMPTY). */
static inline uint32_t hd_child(const struct vd_hashdag *h, int l,
				uint32_t ptr, int c)
{
	if (ptr == HD_EMPTY)
		return HD_EMPTY;
	const uint32_t *n = hd_node(h, l, ptr);
	uint32_t m = n[0] & 0xff;
	if (!(m >> c & 1))
		return HD_EMPTY;
	return n[1 + __builtin_popcount(m & ((1u << c) - 1))];
}

/* Finds or appends a node (thread-safe: bucket locks). *out its pointer.
 * VD_ERR_BUDGET when its bucket is full. */
int hd_insert_inner(struct vd_hashdag *h, int l, uint8_t mask,
		    const uint32_t *child, uint32_t *out);
int hd_insert_leaf(struct vd_hashdag *h, uint64_t brick, uint32_t *out);

/* Makes (finds) the full subtree nodes of every level (not thread-safe:
 * called before an edit's parallel part). */
int hd_make_full(struct vd_hashdag *h);

/* The node on level `l` covering voxel (x, y, z) in the tree of `root`. */
uint32_t hd_lookup(const struct vd_hashdag *h, uint32_t root, int l,
		   uint32_t x, uint32_t y, uint32_t z);

/* Pushes a new scene root (drops the redo part of the history) with its
 * colour table `tab` (taken over; NULL without colours). */
int hd_push_root(struct vd_hashdag *h, uint32_t root,
		 struct hd_cellcol **tab);

/* VD_ERR_BUDGET when `more` bytes would take the structure over the
 * budget; `what` names them. */
int hd_budget_check(const struct vd_hashdag *h, uint64_t more,
		    const char *what);
uint64_t hd_used_bytes(const struct vd_hashdag *h);

/* Colours (colours.c). */
void hd_cellcol_unref(struct hd_colours *c, struct hd_cellcol *p);
void hd_coltab_free(struct hd_colours *c, struct hd_cellcol **tab);
void hd_colours_free(struct hd_colours *c);
/* The colour table of the edit `op` that turned old_root into new_root
 * (both in h); *changed_colours counts voxels whose colour changed. */
int hd_colours_edit(struct vd_hashdag *h, const struct vd_edit_op *op,
		    uint32_t old_root, uint32_t new_root,
		    struct hd_cellcol ***out, uint64_t *changed_colours,
		    uint64_t *cells_rebuilt);
/* The regions of the edits, inline so that the edits (ops.c) and the
 * colours (colours.c) test voxels alike without calling each other. A
 * voxel is in a sphere when its centre is. */
static inline int hd_sphere_has(const struct vd_edit_op *op, int64_t x,
				 int64_t y, int64_t z)
{
	double dx = (double)x + 0.5 - op->c[0], dy = (double)y + 0.5 - op->c[1],
	       dz = (double)z + 0.5 - op->c[2];
	return dx * dx + dy * dy + dz * dz <= op->r * op->r;
}

/* 1 when voxel (x, y, z) lies in the region `op` writes (for a copy, its
 * destination box). */
static inline int hd_op_has(const struct vd_edit_op *op, int64_t x,
			    int64_t y, int64_t z)
{
	if (op->shape == VD_SHAPE_SPHERE && op->kind != VD_EDIT_COPY)
		return hd_sphere_has(op, x, y, z);
	int64_t p[3] = {x, y, z};
	for (int a = 0; a < 3; a++) {
		int64_t d = op->kind == VD_EDIT_COPY ? op->dst[a] - op->lo[a] : 0;
		if (p[a] < op->lo[a] + d || p[a] > op->hi[a] + d)
			return 0;
	}
	return 1;
}

/* Voxels of the subtree of ptr on level l (hashdag.c). */
uint64_t hd_voxels_of(const struct vd_hashdag *h, int l, uint32_t ptr);

#endif
