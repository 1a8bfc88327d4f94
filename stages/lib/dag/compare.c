/* compare.c - a DAG against the SVO chunks it was built from, voxel by
 * voxel (vd_dag_compare_svo, which dag-verify runs). */
#include "dag/dag_internal.h"

#include <inttypes.h>
#include <stdlib.h>
#include <string.h>

#define NOMEM() vd_fail(VD_ERR_NOMEM, "out of memory in %s", __func__)

struct svo_ref {
	const struct vd_svo *s;
	uint64_t start, end; /* voxel Morton range of the cell */
};

static int svo_ref_cmp(const void *a, const void *b)
{
	uint64_t x = ((const struct svo_ref *)a)->start,
		 y = ((const struct svo_ref *)b)->start;
	return x < y ? -1 : x > y;
}

struct cmp_state {
	const struct svo_ref *r;
	size_t n, i, j;      /* cursor: SVO i, brick j */
	int L;
	struct vd_dag_diff *diff;
};

static void cmp_note(struct cmp_state *c, uint64_t key, uint64_t x,
		     uint64_t in_dag)
{
	if (!x) return;
	if (!c->diff->differing_voxels) {
		int b = __builtin_ctzll(x);
		c->diff->first_voxel_morton =
			c->L >= 2 ? key << 6 | (uint64_t)b : (uint64_t)b;
		c->diff->first_in_dag = (int)(in_dag >> b & 1);
	}
	c->diff->differing_voxels += vd__dag_popcount64(x);
}

/* Steps the SVO cursor past every brick before `key`, noting each. */
static void cmp_advance(struct cmp_state *c, uint64_t key, int all)
{
	while (c->i < c->n) {
		const struct vd_svo *s = c->r[c->i].s;
		if (c->j >= s->count) {
			c->i++;
			c->j = 0;
			continue;
		}
		if (!all && s->keys[c->j] >= key) return;
		cmp_note(c, s->keys[c->j], s->masks[c->j], 0);
		c->j++;
	}
}

static int cmp_brick(void *ctx, uint64_t key, uint64_t brick)
{
	struct cmp_state *c = ctx;
	cmp_advance(c, key, 0);
	uint64_t svo = 0;
	if (c->i < c->n && c->r[c->i].s->keys[c->j] == key)
		svo = c->r[c->i].s->masks[c->j++];
	cmp_note(c, key, brick ^ svo, brick);
	return 0;
}

int vd_dag_compare_svo(const struct vd_dag *dag,
		       const struct vd_svo *const *svos, size_t n,
		       struct vd_dag_diff *diff)
{
	memset(diff, 0, sizeof *diff);
	int L = dag->levels, A = dag->chunk_level;
	struct svo_ref *r = malloc((n ? n : 1) * sizeof *r);
	if (!r) return NOMEM();
	for (size_t i = 0; i < n; i++) {
		const struct vd_svo *s = svos[i];
		if (s->levels != L || s->chunk_level < A ||
		    s->cell_morton >> (3 * (s->chunk_level - A)) != dag->cell_morton) {
			free(r);
			return vd_fail(VD_ERR_MISMATCH, "SVO chunk %zu (%d levels, "
				       "cell %" PRIu64 " at level %d) is not "
				       "inside the DAG's cell %" PRIu64 " at "
				       "level %d of %d levels", i, s->levels,
				       s->cell_morton, s->chunk_level,
				       dag->cell_morton, A, L);
		}
		r[i].s = s;
		r[i].start = s->chunk_level ? s->cell_morton *
			vd__dag_cell_span(L, s->chunk_level) : 0;
		r[i].end = r[i].start + vd__dag_cell_span(L, s->chunk_level);
	}
	qsort(r, n, sizeof *r, svo_ref_cmp);
	for (size_t i = 0; i + 1 < n; i++)
		if (r[i].end > r[i + 1].start) {
			int err = vd_fail(VD_ERR_MISMATCH, "two SVO chunks cover "
					  "cell %" PRIu64 " at level %d",
					  r[i + 1].s->cell_morton,
					  r[i + 1].s->chunk_level);
			free(r);
			return err;
		}
	struct cmp_state c = {r, n, 0, 0, L, diff};
	int err = vd_dag_expand(dag, cmp_brick, &c);
	if (!err) cmp_advance(&c, 0, 1);
	free(r);
	return err;
}
