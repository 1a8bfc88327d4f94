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

#endif
