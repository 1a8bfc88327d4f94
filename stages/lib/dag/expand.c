/* expand.c - a DAG chunk back to its bricks, in Morton order, through
 * the reflections (SSVDAG) or cube transforms (SSVDAG48) on the way down:
 * vd_dag_expand, and vd_dag_to_svo on it. */
#include "dag/dag_internal.h"

#include <stdlib.h>
#include <string.h>

#define NOMEM() vd_fail(VD_ERR_NOMEM, "out of memory in %s", __func__)

struct expander {
	const struct vd_dag *d;
	int (*fn)(void *ctx, uint64_t key, uint64_t brick);
	void *ctx;
};

static int expand_node(const struct expander *x, int l, uint64_t node,
		       unsigned a, uint64_t morton)
{
	const struct vd_dag *d = x->d;
	const struct vd_dag_level *lv = &d->lv[l];
	int L = d->levels;
	unsigned mk = lv->mask[node];
	uint64_t first = lv->first[node];
	for (unsigned p = 0; p < 8; p++) {
		unsigned s = p ^ a;
		if (!(mk >> s & 1)) continue;
		uint64_t j = first + (uint64_t)vd__dag_pop8(mk & ((1u << s) - 1));
		uint32_t c = lv->child[j];
		unsigned ca = a ^ (lv->refl ? lv->refl[j] : 0u);
		int err;
		if (l + 1 == L - 2)
			err = x->fn(x->ctx, morton << 3 | p,
				    vd_brick_reflect(d->bricks[c], ca));
		else
			err = expand_node(x, l + 1, c, ca, morton << 3 | p);
		if (err) return err;
	}
	return 0;
}

/* The same for an ssvdag48: the node is reached with accumulated
 * transform a, so logical slot p is stored slot a^-1(p), and its child,
 * stored as (c, t), is reached with a t. */
static int expand_node48(const struct expander *x, int l, uint64_t node,
			 unsigned a, uint64_t morton)
{
	const struct vd_dag *d = x->d;
	const struct vd_dag_level *lv = &d->lv[l];
	int L = d->levels;
	unsigned mk = lv->mask[node];
	uint64_t first = lv->first[node];
	const uint8_t *back = vd__g48_child[vd__g48_inv[a]];
	for (unsigned p = 0; p < 8; p++) {
		unsigned s = back[p];
		if (!(mk >> s & 1)) continue;
		uint64_t j = first + (uint64_t)vd__dag_pop8(mk & ((1u << s) - 1));
		uint32_t c = lv->child[j];
		unsigned ca = vd__g48_comp[a][lv->refl[j]];
		int err;
		if (l + 1 == L - 2)
			err = x->fn(x->ctx, morton << 3 | p,
				    vd_g48_brick(d->bricks[c], ca));
		else
			err = expand_node48(x, l + 1, c, ca, morton << 3 | p);
		if (err) return err;
	}
	return 0;
}

int vd_dag_expand(const struct vd_dag *dag,
		  int (*fn)(void *ctx, uint64_t key, uint64_t brick),
		  void *ctx)
{
	int L = dag->levels, A = dag->chunk_level;
	if (!dag->lv[A].nodes) return 0;
	if (A == L - 1) {
		uint64_t c = dag->cell_morton;
		return fn(ctx, c >> 3, (uint64_t)dag->lv[A].mask[0] << 8 * (c & 7));
	}
	if (A == L - 2) return fn(ctx, dag->cell_morton, dag->bricks[0]);
	struct expander x = {dag, fn, ctx};
	if (dag->kind == VD_KIND_SSVDAG48) {
		vd__g48_init();
		return expand_node48(&x, A, 0, 0, dag->cell_morton);
	}
	return expand_node(&x, A, 0, 0, dag->cell_morton);
}

struct svo_sink {
	struct vd_svo *svo;
	size_t cap;
};

static int svo_sink_add(void *ctx, uint64_t key, uint64_t brick)
{
	struct svo_sink *k = ctx;
	struct vd_svo *s = k->svo;
	if (s->count == k->cap) {
		size_t c = k->cap ? k->cap * 2 : 1024;
		uint64_t *nk = realloc(s->keys, c * 8);
		if (!nk) return NOMEM();
		s->keys = nk;
		uint64_t *nm = realloc(s->masks, c * 8);
		if (!nm) return NOMEM();
		s->masks = nm;
		k->cap = c;
	}
	s->keys[s->count] = key;
	s->masks[s->count++] = brick;
	return 0;
}

int vd_dag_to_svo(const struct vd_dag *dag, struct vd_svo *svo)
{
	memset(svo, 0, sizeof *svo);
	svo->levels = dag->levels;
	svo->chunk_level = dag->chunk_level;
	svo->cell_morton = dag->cell_morton;
	struct svo_sink k = {svo, 0};
	/* arrays are never NULL, even for an empty DAG */
	int err = svo_sink_add(&k, 0, 0);
	svo->count = 0;
	if (!err) err = vd_dag_expand(dag, svo_sink_add, &k);
	if (err) {
		free(svo->keys);
		free(svo->masks);
		memset(svo, 0, sizeof *svo);
	}
	return err;
}
