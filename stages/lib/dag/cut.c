/* cut.c - a root DAG seen at a coarser depth: the per-level node counts of
 * the SVO it stands for, and the DAG cut at a shallower level and reduced
 * again (the rows of the papers' tables at lower resolutions, and the
 * lossy stage's cut to the scene's depth). */
#include "voxdag.h"
#include "dag/dag_internal.h"

#include <stdlib.h>
#include <string.h>

#define NOMEM() vd_fail(VD_ERR_NOMEM, "out of memory in %s", __func__)

int vd_dag_svo_counts(const struct vd_dag *d,
		      uint64_t svo_nodes[VD_MAX_LEVELS + 1])
{
	int L = d->levels;
	memset(svo_nodes, 0, (VD_MAX_LEVELS + 1) * sizeof *svo_nodes);
	if (d->chunk_level != 0)
		return vd_fail(VD_ERR_ARG, "chunk level %d is not a root chunk",
			       d->chunk_level);
	if (!d->lv[0].nodes) return VD_OK;
	/* occ[i]: how many times node i of level l occurs in the SVO */
	uint64_t *occ = calloc(1, 8);
	if (!occ) return NOMEM();
	occ[0] = 1;
	for (int l = 0; l < L; l++) {
		const struct vd_dag_level *lv = &d->lv[l];
		uint64_t below = 0;
		for (uint64_t i = 0; i < lv->nodes; i++) {
			svo_nodes[l] += occ[i];
			below += occ[i] * (uint64_t)__builtin_popcount(lv->mask[i]);
		}
		if (l == L - 1) {
			svo_nodes[L] = below; /* the voxels */
			break;
		}
		uint64_t *nocc = calloc(d->lv[l + 1].nodes ? d->lv[l + 1].nodes : 1, 8);
		if (!nocc) {
			free(occ);
			return NOMEM();
		}
		for (uint64_t i = 0; i < lv->nodes; i++)
			for (uint64_t j = lv->first[i]; j < lv->first[i + 1]; j++)
				nocc[lv->child[j]] += occ[i];
		free(occ);
		occ = nocc;
	}
	free(occ);
	return VD_OK;
}

int vd_dag_cut(const struct vd_dag *dag, int levels, const uint64_t *counts,
	       struct vd_dag *out)
{
	memset(out, 0, sizeof *out);
	int L = dag->levels;
	if (dag->chunk_level != 0)
		return vd_fail(VD_ERR_ARG, "chunk level %d is not a root chunk",
			       dag->chunk_level);
	if (levels < 1 || levels > L)
		return vd_fail(VD_ERR_RANGE, "cut depth %d out of 1..%d",
			       levels, L);
	uint64_t own[VD_MAX_LEVELS + 1];
	int err = VD_OK;
	if (!counts) {
		if ((err = vd_dag_svo_counts(dag, own))) return err;
		counts = own;
	}
	if (!dag->lv[0].nodes) {
		out->kind = dag->kind;
		out->levels = levels;
		return VD_OK;
	}
	/* A view of levels 0..levels-1 whose last level keeps only the masks:
	 * a level `levels`-1 node's child mask is its 2x2x2 mask of coarse
	 * voxels. The merge engine reduces it again from the leaves. */
	struct vd_dag v;
	memset(&v, 0, sizeof v);
	v.kind = dag->kind;
	v.levels = levels;
	v.chunk_level = 0;
	v.voxels = counts[levels];
	for (int l = 0; l < levels; l++) v.lv[l] = dag->lv[l];
	struct vd_dag_level *last = &v.lv[levels - 1];
	last->refs = 0;
	last->first = NULL;
	last->child = NULL;
	last->refl = NULL;
	v.bricks = levels == L ? dag->bricks : NULL;
	const struct vd_dag *parts[1] = {&v};
	err = vd_dag_merge(out, parts, 1, dag->kind, 0, NULL, NULL);
	if (err) vd_dag_release(out);
	return err;
}
