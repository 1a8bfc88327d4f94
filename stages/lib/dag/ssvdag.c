/* ssvdag.c - symmetry: the 256-entry leaf class table, the reflection
 * normalization table and canonical keys of inner nodes (SSVDAG paper
 * §4.1, made exact: invariance is a full set of the 8 reflections, not three
 * per-axis bits, because a subtree can be invariant under X+Y together and
 * under neither X nor Y alone). */
#include "dag/dag_internal.h"

#include <pthread.h>
#include <string.h>

uint8_t vd__refl_norm[256][8];
static struct vd_leaf_class leaf_table[256];
static pthread_once_t sym_once = PTHREAD_ONCE_INIT;

static void sym_init_once(void)
{
	for (unsigned g = 0; g < 256; g++)
		for (unsigned r = 0; r < 8; r++) {
			unsigned best = r;
			for (unsigned x = 0; x < 8; x++)
				if ((g >> x & 1) && (r ^ x) < best)
					best = r ^ x;
			vd__refl_norm[g][r] = (uint8_t)best;
		}
	for (unsigned v = 0; v < 256; v++) {
		unsigned best = v, bm = 0, inv = 0;
		for (unsigned m = 1; m < 8; m++) {
			unsigned x = vd_mask_reflect((uint8_t)v, m);
			if (x > best) {
				best = x;
				bm = m;
			}
		}
		for (unsigned m = 0; m < 8; m++)
			if (vd_mask_reflect((uint8_t)v, m) == v) inv |= 1u << m;
		leaf_table[v].canon = (uint8_t)best;
		leaf_table[v].refl = (uint8_t)bm;
		leaf_table[v].inv = (uint8_t)inv;
	}
}

void vd__sym_init(void)
{
	pthread_once(&sym_once, sym_init_once);
}

const struct vd_leaf_class *vd_leaf_classes(void)
{
	vd__sym_init();
	return leaf_table;
}

int vd__node_canon(int sym, int asis, unsigned mask, const uint32_t id[8],
		   const uint8_t r[8], const uint8_t g[8], uint64_t key[9],
		   uint8_t *m, uint8_t *inv)
{
	int k = 0;
	key[0] = mask;
	if (!sym) {
		for (unsigned p = 0; p < 8; p++)
			if (mask >> p & 1) key[++k] = VD_REF(id[p], 0);
		*m = 0;
		*inv = 1;
		return k;
	}
	for (unsigned p = 0; p < 8; p++)
		if (mask >> p & 1)
			key[++k] = VD_REF(id[p], vd__refl_norm[g[p]][r[p]]);
	if (asis) {
		*m = 0;
		*inv = 1;
		return k;
	}
	/* Try the other 7 reflections; `same` collects those whose key equals
	 * the best so far. */
	unsigned best_m = 0, same = 1;
	for (unsigned x = 1; x < 8; x++) {
		uint64_t cand[9];
		unsigned mx = vd_mask_reflect((uint8_t)mask, x);
		if (mx < key[0]) continue;
		cand[0] = mx;
		int j = 0, cmp = mx > key[0]; /* 1 greater, -1 smaller */
		for (unsigned q = 0; q < 8 && cmp >= 0; q++) {
			if (!(mx >> q & 1)) continue;
			unsigned p = q ^ x;
			cand[++j] = VD_REF(id[p], vd__refl_norm[g[p]][r[p] ^ x]);
			if (!cmp && cand[j] != key[j])
				cmp = cand[j] > key[j] ? 1 : -1;
		}
		if (cmp < 0) continue;
		if (cmp > 0) {
			memcpy(key, cand, sizeof(uint64_t) * (size_t)(k + 1));
			best_m = x;
			same = 1u << x;
		} else {
			same |= 1u << x;
		}
	}
	unsigned gi = 0;
	for (unsigned x = 0; x < 8; x++)
		if (same >> x & 1) gi |= 1u << (x ^ best_m);
	*m = (uint8_t)best_m;
	*inv = (uint8_t)gi;
	return k;
}
