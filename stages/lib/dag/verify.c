/* verify.c - the structural checks of a DAG in memory (vd_dag_validate),
 * which every load and save runs. */
#include "dag/dag_internal.h"

#include <inttypes.h>
#include <stdlib.h>

#define NOMEM() vd_fail(VD_ERR_NOMEM, "out of memory in %s", __func__)

int vd_dag_validate(const struct vd_dag *d)
{
	int L = d->levels, A = d->chunk_level;
	if (!vd__dag_is_dag_kind(d->kind))
		return vd_fail(VD_ERR_CORRUPT, "kind %u is not dag, ssvdag or "
			       "ssvdag48", d->kind);
	unsigned nt = d->kind == VD_KIND_SSVDAG48 ? VD_G48 : 8;
	if (L < 1 || L > VD_MAX_LEVELS || A < 0 || A > L - 1)
		return vd_fail(VD_ERR_CORRUPT, "levels %d, chunk level %d", L, A);
	if (A > 0 && d->cell_morton >> (3 * A))
		return vd_fail(VD_ERR_CORRUPT, "cell %" PRIu64 " outside level %d",
			       d->cell_morton, A);
	if (A == 0 && d->cell_morton)
		return vd_fail(VD_ERR_CORRUPT, "root cell %" PRIu64 " is not 0",
			       d->cell_morton);
	if (d->lv[A].nodes == 0) {
		for (int l = A; l < L; l++)
			if (d->lv[l].nodes || d->lv[l].refs)
				return vd_fail(VD_ERR_CORRUPT, "empty root but %"
					       PRIu64 " nodes on level %d",
					       d->lv[l].nodes, l);
		if (d->voxels)
			return vd_fail(VD_ERR_CORRUPT, "empty root but %" PRIu64
				       " voxels", d->voxels);
		return VD_OK;
	}
	if (d->lv[A].nodes != 1)
		return vd_fail(VD_ERR_CORRUPT, "%" PRIu64 " roots on level %d",
			       d->lv[A].nodes, A);
	for (int l = A; l < L; l++) {
		const struct vd_dag_level *lv = &d->lv[l];
		if (lv->nodes > VD__DAG_MAX_LEVEL_NODES + 1)
			return vd_fail(VD_ERR_CORRUPT, "%" PRIu64 " nodes on level"
				       " %d", lv->nodes, l);
		for (uint64_t i = 0; i < lv->nodes; i++)
			if (!lv->mask[i])
				return vd_fail(VD_ERR_CORRUPT, "node %" PRIu64
					       " on level %d has an empty mask",
					       i, l);
		if (l == L - 1) break;
		const struct vd_dag_level *nx = &d->lv[l + 1];
		if ((d->kind != VD_KIND_DAG) != (lv->refl != NULL))
			return vd_fail(VD_ERR_CORRUPT, "level %d: reflections %s"
				       " in a %s", l, lv->refl ? "present" :
				       "missing", vd_chunk_kind_name(d->kind));
		uint64_t j = 0;
		for (uint64_t i = 0; i < lv->nodes; i++) {
			if (lv->first[i] != j)
				return vd_fail(VD_ERR_CORRUPT, "level %d node %"
					       PRIu64 ": references start at %"
					       PRIu64 ", expected %" PRIu64, l, i,
					       lv->first[i], j);
			j += (uint64_t)vd__dag_pop8(lv->mask[i]);
		}
		if (lv->first[lv->nodes] != j || lv->refs != j)
			return vd_fail(VD_ERR_CORRUPT, "level %d: %" PRIu64
				       " references, masks say %" PRIu64, l,
				       lv->refs, j);
		uint8_t *seen = calloc(nx->nodes ? nx->nodes : 1, 1);
		if (!seen) return NOMEM();
		for (uint64_t r = 0; r < lv->refs; r++) {
			if (lv->child[r] >= nx->nodes || (lv->refl && lv->refl[r] >= nt)) {
				free(seen);
				return vd_fail(VD_ERR_CORRUPT, "level %d reference %"
					       PRIu64 ": child %u of %" PRIu64
					       ", %s %u", l, r,
					       lv->child[r], nx->nodes,
					       nt == 8 ? "reflection" : "transform",
					       lv->refl ? lv->refl[r] : 0);
			}
			seen[lv->child[r]] = 1;
		}
		for (uint64_t i = 0; i < nx->nodes; i++)
			if (!seen[i]) {
				free(seen);
				return vd_fail(VD_ERR_CORRUPT, "node %" PRIu64 " on "
					       "level %d is never referenced", i,
					       l + 1);
			}
		free(seen);
	}
	if (A <= L - 2) {
		if (!d->bricks)
			return vd_fail(VD_ERR_INTERNAL, "verify.c: bricks missing");
		for (uint64_t i = 0; i < d->lv[L - 2].nodes; i++) {
			/* (it copied the whole struct vd_dag a brick) */
			if (vd__dag_mask_brick(d, i) != d->bricks[i])
				return vd_fail(VD_ERR_CORRUPT, "brick %" PRIu64
					       " disagrees with its masks", i);
		}
	}
	return VD_OK;
}
