/* dag_internal.h - what dag.c and ssvdag.c share: symmetry canonical forms
 * of bricks and inner nodes. Not part of the public API. */
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

#endif
