/* dag_internal.h - what the files of dag/ share: the symmetry canonical
 * forms of bricks and inner nodes (ssvdag.c) that the builder uses, and
 * the helpers that the builder (build.c), expansion (expand.c), checks
 * (verify.c), chunk files (dag_file.c), stage runs (stage.c) and
 * comparison (compare.c) have in common. Not part of the public API. */
#ifndef VD_DAG_INTERNAL_H
#define VD_DAG_INTERNAL_H

#include "voxdag.h"

/* A reference packed for keys and hashing: child index << 3 | reflection. */
#define VD_REF(id, r) ((uint64_t)(id) << 3 | (uint64_t)(r))

/* norm[G][r]: the smallest r ^ g over g in the reflection set G (bit g set
 * for each g). Two references (i, r) and (i, r') to a node whose invariance
 * set is G denote the same subtree iff norm[G][r] == norm[G][r']: this is
 * how equal subtrees get equal keys whatever reflection reached them. */
extern uint8_t vd__refl_norm[256][8];

/* Fills vd__refl_norm and the leaf table once; thread-safe. */
void vd__sym_init(void);

/* Canonical form of a brick: *canon is the largest of its 8 reflections,
 * *m the smallest reflection with vd_brick_reflect(v, m) == *canon, *inv
 * the set of reflections leaving *canon unchanged. */
static inline void vd__brick_canon(uint64_t v, uint64_t *canon, uint8_t *m,
				   uint8_t *inv)
{
	uint64_t r[8];
	r[0] = v;
	r[1] = vd_brick_reflect(v, 1);
	r[2] = vd_brick_reflect(v, 2);
	r[3] = vd_brick_reflect(r[1], 2);
	r[4] = vd_brick_reflect(v, 4);
	r[5] = vd_brick_reflect(r[1], 4);
	r[6] = vd_brick_reflect(r[2], 4);
	r[7] = vd_brick_reflect(r[3], 4);
	uint64_t best = r[0];
	unsigned bm = 0;
	for (unsigned i = 1; i < 8; i++)
		if (r[i] > best) {
			best = r[i];
			bm = i;
		}
	unsigned g = 0;
	for (unsigned i = 0; i < 8; i++)
		if (r[i] == best) g |= 1u << (i ^ bm);
	*canon = best;
	*m = (uint8_t)bm;
	*inv = (uint8_t)g;
}

/* Canonical key of an inner node whose child in slot p (mask bit p set) is
 * node id[p] of the level below, reflected by r[p], that node having the
 * invariance set g[p]. Writes the key of the node reflected by the chosen
 * *m: key[0] = its mask, key[1..k] = VD_REF(child, normalized reflection)
 * in increasing slot order; returns k = popcount(mask). `sym` 0 (a plain
 * DAG) or `asis` 1 (a root, kept unreflected) considers m = 0 only.
 * Otherwise the key is the largest of the 8 reflected keys (lexicographic),
 * *m the smallest reflection giving it (the node is the stored key
 * reflected by *m) and *inv the reflections that leave it unchanged. Equal
 * subtrees give equal keys provided the level below is minimal. */
int vd__node_canon(int sym, int asis, unsigned mask, const uint32_t id[8],
		   const uint8_t r[8], const uint8_t g[8], uint64_t key[9],
		   uint8_t *m, uint8_t *inv);

/* ---- the 48-element cube group (ssvdag.c)
 *
 * A reference packed for 48-group keys: child index << 6 | transform. */
#define VD_REF48(id, t) ((uint64_t)(id) << 6 | (uint64_t)(t))

/* Tables filled by vd__g48_init(): comp[a][b] = vd_g48_compose(a, b),
 * inv[t], child[t][c] = vd_g48_child(t, c), masks[t][v] = vd_g48_mask(v, t);
 * sub[i] the subgroups as 48-bit sets in increasing order (sub[0] = {0});
 * norm[i][t] the smallest element of the coset t sub[i] = {t g}: two
 * references (n, t) and (n, t') to a node invariant under sub[i] denote
 * the same subtree iff norm[i][t] == norm[i][t']. */
extern uint8_t vd__g48_comp[VD_G48][VD_G48];
extern uint8_t vd__g48_inv[VD_G48];
extern uint8_t vd__g48_child[VD_G48][8];
extern uint8_t vd__g48_masks[VD_G48][256];
extern uint8_t vd__g48_norm[VD_G48_SUBGROUPS][VD_G48];
extern uint64_t vd__g48_sub[VD_G48_SUBGROUPS];

/* Fills the tables once; thread-safe. */
void vd__g48_init(void);

/* The index i with sub[i] == set; `set` must be a subgroup. */
unsigned vd__g48_subgroup(uint64_t set);

/* Canonical form of a brick under the 48: *canon the largest of its 48
 * transforms, *t the transform with vd_g48_brick(*canon, *t) == v, *inv the
 * subgroup index of *canon's invariance set. */
void vd__brick_canon48(uint64_t v, uint64_t *canon, uint8_t *t, uint8_t *inv);

/* vd__node_canon for the 48: r[p] the transform of child p (0..47), g[p]
 * its subgroup index; keys hold VD_REF48(child, normalized transform). The
 * key is the largest over the 48 transforms u of the node transformed by
 * u (slot q holds u applied to the child of slot u^-1(q)); the node is
 * the stored key transformed by *t; *inv its invariance subgroup index.
 * `asis` keeps u = 0. */
int vd__node_canon48(int asis, unsigned mask, const uint32_t id[8],
		     const uint8_t r[8], const uint8_t g[8], uint64_t key[9],
		     uint8_t *t, uint8_t *inv);

/* ---- build.c, expand.c, verify.c, dag_file.c, stage.c, compare.c */

/* The most distinct nodes one level may hold: the builder refuses more,
 * the checks call more corrupt. */
#define VD__DAG_MAX_LEVEL_NODES 0x7fffffffULL

/* Bits set in a child mask; the builtin is a libgcc call without
 * -mpopcnt. */
static inline int vd__dag_pop8(unsigned m)
{
	m -= m >> 1 & 0x55;
	m = (m & 0x33) + (m >> 2 & 0x33);
	return (int)((m + (m >> 4)) & 0x0f);
}

/* SWAR popcount: without -mpopcnt the builtin is a libgcc call. */
static inline uint64_t vd__dag_popcount64(uint64_t v)
{
	v -= v >> 1 & 0x5555555555555555ULL;
	v = (v & 0x3333333333333333ULL) + (v >> 2 & 0x3333333333333333ULL);
	v = (v + (v >> 4)) & 0x0f0f0f0f0f0f0f0fULL;
	return v * 0x0101010101010101ULL >> 56;
}

/* Leaf mask m as a reference with transform t reaches it in a chunk of
 * `kind`. */
static inline uint8_t vd__dag_ref_mask(uint32_t kind, uint8_t m, unsigned t)
{
	return kind == VD_KIND_SSVDAG48 ? vd_g48_mask(m, t)
					: vd_mask_reflect(m, t & 7);
}

/* Whether `kind` is one of the DAG kinds: dag, ssvdag or ssvdag48. */
static inline int vd__dag_is_dag_kind(uint32_t kind)
{
	return kind == VD_KIND_DAG || kind == VD_KIND_SSVDAG ||
	       kind == VD_KIND_SSVDAG48;
}

/* The brick value of node i on level L-2 of d from its leaf masks
 * (build.c). */
uint64_t vd__dag_mask_brick(const struct vd_dag *d, uint64_t i);

/* 8^(L - level) as a voxel-range size: the voxels of a cell on `level`
 * of an L-level grid; fits for L - level <= 21 (build.c). */
uint64_t vd__dag_cell_span(int L, int level);

/* Records `need` as the memory estimate in *st (when not NULL) and fails
 * with VD_ERR_BUDGET when o's budget is set and below it (build.c). */
int vd__dag_check_budget(const struct vd_dag_opts *o, uint64_t need,
			 struct vd_dag_stats *st);

/* vd_dag_from_svo; `counts`, when not NULL, the level counts of the chunk
 * header `svo` was read from by vd_svo_from_chunk, which let it skip its
 * own pass over the bricks (build.c). */
int vd__dag_from_svo(struct vd_dag *dag, const struct vd_svo *svo,
		     uint32_t kind, const struct vd_dag_opts *opts,
		     struct vd_dag_stats *stats, const uint64_t *counts);

#endif
