/* build.c - minimal SVDAG / SSVDAG construction by bottom-up reduction
 * (Kämpe et al. 2013; SSVDAG paper §3, §4.1, §4.2), the merge of sibling
 * chunks, and the memory bounds of both. Expansion back to bricks is in
 * expand.c, the checks in verify.c, chunk files in dag_file.c, the stage
 * runs in stage.c, the comparison with SVOs in compare.c.
 *
 * One engine does every build. It walks the levels bottom-up; on each level
 * it gathers the nodes of that level from three sources, canonicalizes each
 * (its key under the best reflection for an SSVDAG), and deduplicates keys
 * in a hash table, numbering distinct nodes in the order first met:
 *  - the nodes of the input parts (merge mode), their children renamed
 *    through the part's map of the level below;
 *  - the frontier: the occupied cells of the level below in Morton order
 *    (SVO bricks, or roots of parts and parents built so far), grouped by
 *    parent into new nodes;
 *  - roots of parts whose cell is on this level join the frontier.
 * Level L-2 works on brick values (uint64), which are deduplicated directly;
 * level L-1 (2x2x2 masks) is read off the distinct bricks. The numbering
 * is the serial one (first met, in that order) whatever --threads is: the
 * parallel passes below reproduce it exactly, so the same input gives the
 * same bytes on any number of threads.
 */
#include "dag/dag_internal.h"
#include "util_internal.h"
#include "le.h"

#include <inttypes.h>
#include <stdlib.h>
#include <stdio.h>
#include <string.h>

#define NOMEM() vd_fail(VD_ERR_NOMEM, "out of memory in %s", __func__)

static int grow(void **p, uint64_t need, size_t elem)
{
	void *q = realloc(*p, need ? (size_t)need * elem : 1);
	if (!q) return NOMEM();
	*p = q;
	return VD_OK;
}

/* Next capacity for `need` elements starting from `cap`. */
static uint64_t next_cap(uint64_t cap, uint64_t need)
{
	if (cap < 64) cap = 64;
	while (cap < need) cap += cap / 2;
	return cap;
}

static inline uint64_t key_hash(const uint64_t *key, int k)
{
	uint64_t h = vd_mix64(key[0] + 0x9e3779b97f4a7c15ULL);
	for (int i = 1; i <= k; i++)
		h = vd_mix64(h ^ (key[i] + (uint64_t)i * 0x9e3779b97f4a7c15ULL));
	return h;
}

/* Hash slots: 0 empty, else (hash & ~0xffffffff) | (id + 1). The slot
 * index is taken from the same high 32 bits, so a table doubles without
 * recomputing any hash; hence at most 2^32 slots and, at half load, 2^31
 * distinct nodes per level. */
#define SLOT_TAG(h) ((h) & 0xffffffff00000000ULL)
#define SLOT_INDEX(h, mask) (((h) >> 32) & (mask))
/* ----------------------------------------------------------- brick sets */

struct bset {
	uint64_t n, cap;
	uint64_t *v;    /* distinct brick values (canonical for an SSVDAG) */
	uint8_t *inv;   /* their invariance sets */
	uint64_t *slot; /* hash table */
	uint64_t scap;  /* slots, a power of two */
};

/* A table for about `inputs` insertions. Few of them are distinct in a DAG
 * (a tenth to a hundredth on scanned surfaces), and a table that stays in
 * cache is what makes deduplication fast, so it starts small and doubles
 * at half load. */
static int table_init(uint64_t **slot, uint64_t *scap, uint64_t inputs)
{
	uint64_t c = 1024;
	while (c < inputs / 8) c *= 2;
	*slot = calloc((size_t)c, sizeof(uint64_t));
	if (!*slot) return NOMEM();
	*scap = c;
	return VD_OK;
}

/* A table that holds `inputs` distinct entries at under half load. */
static int table_exact(uint64_t **slot, uint64_t *scap, uint64_t inputs)
{
	uint64_t c = 1024;
	while (c <= 2 * inputs) c *= 2;
	*slot = calloc((size_t)c, sizeof(uint64_t));
	if (!*slot) return NOMEM();
	*scap = c;
	return VD_OK;
}

static int table_rehash(uint64_t **slot, uint64_t *scap)
{
	uint64_t nc = *scap * 2, *old = *slot;
	uint64_t *ns = calloc((size_t)nc, sizeof(uint64_t));
	if (!ns) return NOMEM();
	for (uint64_t i = 0; i < *scap; i++) {
		if (!old[i]) continue;
		uint64_t s = SLOT_INDEX(old[i], nc - 1);
		while (ns[s]) s = (s + 1) & (nc - 1);
		ns[s] = old[i];
	}
	free(old);
	*slot = ns;
	*scap = nc;
	return VD_OK;
}

/* Finds or adds brick v (with invariance set inv); *id its index. */
static inline int bset_insert(struct bset *b, uint64_t v, uint8_t inv,
			      uint32_t *id)
{
	uint64_t h = vd_mix64(v), mask = b->scap - 1, s = SLOT_INDEX(h, mask);
	for (;; s = (s + 1) & mask) {
		uint64_t e = b->slot[s];
		if (!e) break;
		if (SLOT_TAG(e) == SLOT_TAG(h)) {
			uint32_t i = (uint32_t)(e & 0xffffffff) - 1;
			if (b->v[i] == v) {
				*id = i;
				return VD_OK;
			}
		}
	}
	if (b->n >= VD__DAG_MAX_LEVEL_NODES)
		return vd_fail(VD_ERR_RANGE, "more than %llu distinct bricks",
			       (unsigned long long)VD__DAG_MAX_LEVEL_NODES);
	if (b->n == b->cap) {
		uint64_t c = next_cap(b->cap, b->n + 1);
		int err = grow((void **)&b->v, c, 8);
		if (!err) err = grow((void **)&b->inv, c, 1);
		if (err) return err;
		b->cap = c;
	}
	b->slot[s] = SLOT_TAG(h) | (b->n + 1);
	b->v[b->n] = v;
	b->inv[b->n] = inv;
	*id = (uint32_t)b->n++;
	if (2 * b->n > b->scap) return table_rehash(&b->slot, &b->scap);
	return VD_OK;
}

static void bset_free(struct bset *b)
{
	free(b->v);
	free(b->inv);
	free(b->slot);
	memset(b, 0, sizeof *b);
}

/* ------------------------------------------------------------ node sets */

struct nset {
	int sym;
	int shift;       /* reference bits in a key: 3, or 6 for the 48 */
	uint64_t n, cap, nref, rcap;
	uint8_t *mask, *inv;
	uint64_t *first; /* n + 1 entries once finished */
	uint32_t *child;
	uint8_t *refl;   /* only when sym */
	uint64_t *slot, scap;
};

static inline int nset_equal(const struct nset *b, uint32_t i,
			     const uint64_t *key, int k)
{
	if (b->mask[i] != key[0]) return 0;
	const uint32_t *c = b->child + b->first[i];
	if (b->sym) {
		const uint8_t *r = b->refl + b->first[i];
		for (int j = 0; j < k; j++)
			if (((uint64_t)c[j] << b->shift | r[j]) != key[j + 1])
				return 0;
	} else {
		for (int j = 0; j < k; j++)
			if ((uint64_t)c[j] << 3 != key[j + 1]) return 0;
	}
	return 1;
}

/* Finds or adds the node with canonical key key[0..k]; *id its index. */
static int nset_insert(struct nset *b, const uint64_t *key, int k,
		       uint8_t inv, uint32_t *id)
{
	uint64_t h = key_hash(key, k), mask = b->scap - 1, s = SLOT_INDEX(h, mask);
	for (;; s = (s + 1) & mask) {
		uint64_t e = b->slot[s];
		if (!e) break;
		if (SLOT_TAG(e) == SLOT_TAG(h)) {
			uint32_t i = (uint32_t)(e & 0xffffffff) - 1;
			if (nset_equal(b, i, key, k)) {
				*id = i;
				return VD_OK;
			}
		}
	}
	if (b->n >= VD__DAG_MAX_LEVEL_NODES)
		return vd_fail(VD_ERR_RANGE, "more than %llu distinct nodes "
			       "on a level", (unsigned long long)VD__DAG_MAX_LEVEL_NODES);
	int err;
	if (b->n + 1 >= b->cap) {
		uint64_t c = next_cap(b->cap, b->n + 2);
		if ((err = grow((void **)&b->mask, c, 1)) ||
		    (err = grow((void **)&b->inv, c, 1)) ||
		    (err = grow((void **)&b->first, c, 8)))
			return err;
		b->cap = c;
	}
	if (b->nref + (uint64_t)k > b->rcap) {
		uint64_t c = next_cap(b->rcap, b->nref + (uint64_t)k);
		if ((err = grow((void **)&b->child, c, 4))) return err;
		if (b->sym && (err = grow((void **)&b->refl, c, 1))) return err;
		b->rcap = c;
	}
	uint64_t i = b->n;
	b->slot[s] = SLOT_TAG(h) | (i + 1);
	b->mask[i] = (uint8_t)key[0];
	b->inv[i] = inv;
	b->first[i] = b->nref;
	for (int j = 0; j < k; j++) {
		b->child[b->nref + (uint64_t)j] = (uint32_t)(key[j + 1] >> b->shift);
		if (b->sym)
			b->refl[b->nref + (uint64_t)j] =
				(uint8_t)(key[j + 1] & ((1u << b->shift) - 1));
	}
	b->nref += (uint64_t)k;
	b->first[i + 1] = b->nref;
	b->n++;
	*id = (uint32_t)i;
	if (2 * b->n > b->scap) return table_rehash(&b->slot, &b->scap);
	return VD_OK;
}

static void nset_free(struct nset *b)
{
	free(b->mask);
	free(b->inv);
	free(b->first);
	free(b->child);
	free(b->refl);
	free(b->slot);
	memset(b, 0, sizeof *b);
}

/* ------------------------------------------------------------- frontier */

struct felem {
	uint64_t morton; /* cell at the frontier's level, whole grid */
	uint32_t id;     /* node on that level (raw mask on level L-1) */
	uint8_t r;       /* reflection */
};

struct front {
	uint64_t n, cap;
	struct felem *e;
};

static inline int front_push(struct front *f, uint64_t morton, uint32_t id,
			     uint8_t r)
{
	if (f->n == f->cap) {
		uint64_t c = next_cap(f->cap, f->n + 1);
		int err = grow((void **)&f->e, c, sizeof *f->e);
		if (err) return err;
		f->cap = c;
	}
	f->e[f->n++] = (struct felem){morton, id, r};
	return VD_OK;
}

static int felem_cmp(const void *a, const void *b)
{
	uint64_t x = ((const struct felem *)a)->morton,
		 y = ((const struct felem *)b)->morton;
	return x < y ? -1 : x > y;
}

static void front_sort(struct front *f)
{
	for (uint64_t i = 1; i < f->n; i++)
		if (f->e[i - 1].morton > f->e[i].morton) {
			qsort(f->e, (size_t)f->n, sizeof *f->e, felem_cmp);
			return;
		}
}

static void front_free(struct front *f)
{
	free(f->e);
	memset(f, 0, sizeof *f);
}

/* --------------------------------------------------------------- engine */

/* What a part's nodes on the level below became: node i of the part is
 * node id[i] of the output reflected by r[i]. */
struct remap {
	uint32_t *id;
	uint8_t *r;
};

struct engine {
	int sym, L, A;
	int g48;                           /* sym over the 48, not the 8 */
	uint64_t cellA;
	struct vd_dag *const *parts;       /* non-empty, sorted by cell */
	size_t np;
	int consume;                       /* free parts' levels once read */
	const struct vd_svo *svo;          /* or NULL */
	struct vd_dag *out;
	struct vd_dag_stats *st;
	struct front fr;                   /* frontier on level l+1 */
	struct remap *rm;                  /* per part, level l+1 */
	uint8_t *inv_below;                /* invariance sets on level l+1 */
	int threads;                       /* as struct vd_dag_opts */
	uint64_t spare_bytes;              /* budget less the estimate */
};

static void remaps_free(struct remap *rm, size_t np)
{
	if (!rm) return;
	for (size_t i = 0; i < np; i++) {
		free(rm[i].id);
		free(rm[i].r);
	}
	free(rm);
}

/* Makes the level just built the one the next level up works from: its
 * invariance sets, its front of part roots and the parts' remaps move into
 * the engine (the caller's pointers are emptied, so its cleanup frees
 * nothing twice). */
static void engine_advance(struct engine *e, uint8_t **inv, struct front *nf,
			   struct remap **rm)
{
	free(e->inv_below);
	e->inv_below = *inv;
	*inv = NULL;
	front_free(&e->fr);
	e->fr = *nf;
	*nf = (struct front){0};
	remaps_free(e->rm, e->np);
	e->rm = *rm;
	*rm = NULL;
}

/* Part p's level l is read: when the engine owns the parts, its arrays go
 * now (the counts stay), so a merge never holds the parts' lower levels
 * together with the output built from them. Level L-2 takes the bricks
 * and the leaf masks with it. */
static void part_drop(struct engine *e, size_t p, int l)
{
	if (!e->consume) return;
	struct vd_dag *d = e->parts[p];
	for (int k = l; k < (l == e->L - 2 ? e->L : l + 1); k++) {
		struct vd_dag_level *lv = &d->lv[k];
		free(lv->mask);
		free(lv->first);
		free(lv->child);
		free(lv->refl);
		lv->mask = NULL;
		lv->first = NULL;
		lv->child = NULL;
		lv->refl = NULL;
	}
	if (l == e->L - 2) {
		free(d->bricks);
		d->bricks = NULL;
	}
}

static struct remap *remaps_new(struct engine *e, int l)
{
	struct remap *rm = calloc(e->np ? e->np : 1, sizeof *rm);
	if (!rm) return NULL;
	for (size_t p = 0; p < e->np; p++) {
		const struct vd_dag *d = e->parts[p];
		if (d->chunk_level > l) continue;
		size_t n = (size_t)d->lv[l].nodes;
		rm[p].id = malloc(n ? n * 4 : 1);
		rm[p].r = malloc(n ? n : 1);
		if (!rm[p].id || !rm[p].r) {
			remaps_free(rm, e->np);
			return NULL;
		}
	}
	return rm;
}

/* The brick value of node i on level L-2 of d from its leaf masks. */
uint64_t vd__dag_mask_brick(const struct vd_dag *d, uint64_t i)
{
	int L = d->levels;
	const struct vd_dag_level *lv = &d->lv[L - 2];
	uint64_t v = 0, j = lv->first[i];
	for (unsigned s = 0; s < 8; s++) {
		if (!(lv->mask[i] >> s & 1)) continue;
		uint8_t m = d->lv[L - 1].mask[lv->child[j]];
		if (lv->refl) m = vd__dag_ref_mask(d->kind, m, lv->refl[j]);
		v |= (uint64_t)m << (8 * s);
		j++;
	}
	return v;
}

/* The brick value of node i on level L-2 of part d (unreflected). */
static uint64_t part_brick(const struct vd_dag *d, uint64_t i)
{
	return d->bricks ? d->bricks[i] : vd__dag_mask_brick(d, i);
}

static inline int brick_add(struct engine *e, struct bset *b, uint64_t v,
			    int asis, uint32_t *id, uint8_t *r)
{
	uint64_t c = v;
	uint8_t m = 0, inv = 1;
	if (e->g48) {
		inv = 0; /* the trivial subgroup, for a root kept as is */
		if (!asis) vd__brick_canon48(v, &c, &m, &inv);
	} else if (e->sym && !asis) {
		vd__brick_canon(v, &c, &m, &inv);
	}
	*r = m;
	return bset_insert(b, c, inv, id);
}

/* ------------------------------------------------------ parallel passes
 * The SVO brick pass, the largest, runs in ranges: each range deduplicates
 * into a private set, then the private sets are merged into the level's
 * set serially, range after range, and finally every element's private id
 * is renamed. Merging in range order numbers the distinct nodes exactly as
 * the serial pass would (first met, in element order), so the output does
 * not depend on the thread count. This pays because bricks repeat a lot
 * (the dragon at 2^12: 87 thousand distinct of 2.7 million), so the serial
 * merge is small. The inner levels, where half the nodes are distinct,
 * shard by hash instead (see "parallel inner levels"). */

#define PAR_MIN 65536 /* elements below which a pass stays serial */

struct prange {
	uint64_t lo, hi;      /* elements */
	struct bset b;        /* private brick set */
	uint32_t *map;        /* private id -> level id */
	int err;
};

struct ppass {
	struct engine *e;
	struct prange *r;
	int asis;
	struct front *nf;
};

static size_t range_count(const struct engine *e, uint64_t n)
{
	int t = e->threads > 0 ? e->threads : vd_hardware_threads();
	if (t <= 1 || n < PAR_MIN) return 1;
	uint64_t k = (uint64_t)t * 4;
	if (k > n / (PAR_MIN / 4)) k = n / (PAR_MIN / 4);
	return k < 2 ? 2 : (size_t)k;
}

/* Threads to run a parallel pass with: the request, at most the cores.
 * More threads than cores only make TBB complain; the ranges (and so the
 * code path) still follow the request, which the tests use. */
static int pass_threads(const struct engine *e)
{
	int hw = vd_hardware_threads();
	return e->threads > 0 && e->threads < hw ? e->threads : hw;
}

static void prange_free(struct prange *r, size_t nr)
{
	for (size_t i = 0; i < nr; i++) {
		bset_free(&r[i].b);
		free(r[i].map);
	}
	free(r);
}

static void svo_range_dedup(void *ctx, size_t k, int worker)
{
	struct ppass *pp = ctx;
	struct prange *r = &pp->r[k];
	const struct vd_svo *s = pp->e->svo;
	r->err = table_init(&r->b.slot, &r->b.scap, r->hi - r->lo);
	for (uint64_t i = r->lo; i < r->hi && !r->err; i++)
		r->err = brick_add(pp->e, &r->b, s->masks[i], pp->asis,
				   &pp->nf->e[i].id, &pp->nf->e[i].r);
}

static void svo_range_rename(void *ctx, size_t k, int worker)
{
	struct ppass *pp = ctx;
	struct prange *r = &pp->r[k];
	for (uint64_t i = r->lo; i < r->hi; i++) {
		pp->nf->e[i].morton = pp->e->svo->keys[i];
		pp->nf->e[i].id = r->map[pp->nf->e[i].id];
	}
}

/* All SVO bricks into brick set b; their cells (in order) into nf. */
static int svo_bricks(struct engine *e, struct bset *b, int asis,
		      struct front *nf)
{
	const struct vd_svo *s = e->svo;
	uint64_t n = s->count;
	size_t nr = range_count(e, n);
	int err;
	if (nr == 1) {
		/* one element a brick: sized once, not grown by halves */
		if (nf->cap < nf->n + n) {
			if ((err = grow((void **)&nf->e, nf->n + n, sizeof *nf->e)))
				return err;
			nf->cap = nf->n + n;
		}
		for (uint64_t i = 0; i < n; i++) {
			uint32_t id;
			uint8_t r;
			if ((err = brick_add(e, b, s->masks[i], asis, &id, &r)) ||
			    (err = front_push(nf, s->keys[i], id, r)))
				return err;
		}
		return VD_OK;
	}
	if ((err = grow((void **)&nf->e, nf->n + n, sizeof *nf->e))) return err;
	nf->cap = nf->n + n;
	struct front sub = {n, n, nf->e + nf->n};
	struct prange *r = calloc(nr, sizeof *r);
	if (!r) return NOMEM();
	for (size_t k = 0; k < nr; k++) {
		r[k].lo = n * k / nr;
		r[k].hi = n * (k + 1) / nr;
	}
	struct ppass pp = {e, r, asis, &sub};
	int t = pass_threads(e);
	err = vd_parallel_for(nr, t, svo_range_dedup, &pp);
	for (size_t k = 0; k < nr && !err; k++) {
		err = r[k].err;
		if (!err && !(r[k].map = malloc((r[k].b.n ? r[k].b.n : 1) * 4)))
			err = NOMEM();
		for (uint64_t j = 0; j < r[k].b.n && !err; j++)
			err = bset_insert(b, r[k].b.v[j], r[k].b.inv[j], &r[k].map[j]);
	}
	if (!err) err = vd_parallel_for(nr, t, svo_range_rename, &pp);
	if (!err) nf->n += n;
	prange_free(r, nr);
	return err;
}

static inline int node_canon(const struct engine *e, int asis, unsigned mk,
			     const uint32_t id[8], const uint8_t r[8],
			     const uint8_t g[8], uint64_t key[9], uint8_t *m,
			     uint8_t *inv)
{
	if (e->g48) return vd__node_canon48(asis, mk, id, r, g, key, m, inv);
	return vd__node_canon(e->sym, asis, mk, id, r, g, key, m, inv);
}

/* The key of the node grouping the frontier's entries from *i on (the
 * children of one parent); *i moves past them, *parent is their cell. */
static inline int group_key(const struct engine *e, uint64_t *i, int asis,
			    uint64_t *parent, uint64_t key[9], uint8_t *m,
			    uint8_t *inv)
{
	const struct felem *fe = e->fr.e;
	const uint8_t *gb = e->inv_below;
	uint64_t n = e->fr.n, j = *i, par = fe[j].morton >> 3;
	uint32_t id[8];
	uint8_t r[8], g[8];
	unsigned mk = 0;
	for (; j < n && fe[j].morton >> 3 == par; j++) {
		unsigned s = fe[j].morton & 7;
		mk |= 1u << s;
		id[s] = fe[j].id;
		r[s] = fe[j].r;
		g[s] = gb[id[s]];
	}
	*i = j;
	*parent = par;
	return node_canon(e, asis, mk, id, r, g, key, m, inv);
}

/* The key of node i on level l of part p, its children renamed through
 * the part's map of the level below. */
static inline int part_key(const struct engine *e, size_t p, int l,
			   uint64_t i, int asis, uint64_t key[9], uint8_t *m,
			   uint8_t *inv)
{
	const struct vd_dag_level *lv = &e->parts[p]->lv[l];
	const struct remap *below = &e->rm[p];
	const uint8_t *gb = e->inv_below;
	uint32_t id[8];
	uint8_t r[8], g[8];
	uint64_t j = lv->first[i];
	unsigned mk = lv->mask[i];
	for (unsigned s = 0; s < 8; s++) {
		if (!(mk >> s & 1)) continue;
		uint32_t c = lv->child[j];
		id[s] = below->id[c];
		/* the part's child is refl[j] applied to below->r[c]
		 * applied to output node id[s] */
		uint8_t t = lv->refl ? lv->refl[j] : 0;
		r[s] = e->g48 ? vd__g48_comp[t][below->r[c]]
			      : (uint8_t)(below->r[c] ^ t);
		g[s] = gb[id[s]];
		j++;
	}
	return node_canon(e, asis, mk, id, r, g, key, m, inv);
}

/* The frontier's groups (new parents) into node set b, their cells into
 * nf, in order. */
static int frontier_groups(struct engine *e, struct nset *b, int asis,
			   struct front *nf)
{
	uint64_t key[9], parent;
	uint8_t m, inv;
	int err;
	for (uint64_t i = 0; i < e->fr.n;) {
		int k = group_key(e, &i, asis, &parent, key, &m, &inv);
		uint32_t nid;
		if ((err = nset_insert(b, key, k, inv, &nid)) ||
		    (err = front_push(nf, parent, nid, m)))
			return err;
	}
	return VD_OK;
}

/* Level L-1: the frontier of raw 2x2x2 masks (roots of cells on L-1). */
static int level_leaf(struct engine *e)
{
	int L = e->L, err;
	for (size_t p = 0; p < e->np; p++) {
		const struct vd_dag *d = e->parts[p];
		if (d->chunk_level == L - 1 &&
		    (err = front_push(&e->fr, d->cell_morton, d->lv[L - 1].mask[0], 0)))
			return err;
	}
	if (e->svo && e->svo->chunk_level == L - 1 && e->svo->count) {
		uint64_t cell = e->svo->cell_morton;
		uint8_t m = (uint8_t)(e->svo->masks[0] >> 8 * (cell & 7));
		if ((err = front_push(&e->fr, cell, m, 0))) return err;
	}
	front_sort(&e->fr);
	if (e->A == L - 1) {
		struct vd_dag_level *lv = &e->out->lv[L - 1];
		lv->mask = malloc(1);
		if (!lv->mask) return NOMEM();
		lv->mask[0] = (uint8_t)e->fr.e[0].id;
		lv->nodes = 1;
	}
	return VD_OK;
}

/* Level L-2: bricks, and from them level L-1. */
static int level_brick(struct engine *e)
{
	int L = e->L, l = L - 2, asis = e->A == l, err = VD_OK;
	struct bset b = {0};
	struct front nf = {0};
	struct remap *rm = remaps_new(e, l);
	uint64_t expect = 0;
	for (size_t p = 0; p < e->np; p++)
		if (e->parts[p]->chunk_level <= l)
			expect += e->parts[p]->lv[l].nodes;
	if (e->svo && e->svo->chunk_level <= l) expect += e->svo->count;
	if (!rm) return NOMEM();
	if ((err = table_init(&b.slot, &b.scap, expect))) goto out;

	for (size_t p = 0; p < e->np; p++) {
		const struct vd_dag *d = e->parts[p];
		if (d->chunk_level <= l)
			for (uint64_t i = 0; i < d->lv[l].nodes; i++)
				if ((err = brick_add(e, &b, part_brick(d, i), asis,
						     &rm[p].id[i], &rm[p].r[i])))
					goto out;
		part_drop(e, p, l);
	}
	if (e->svo && e->svo->chunk_level <= l &&
	    (err = svo_bricks(e, &b, asis, &nf)))
		goto out;
	for (uint64_t i = 0; i < e->fr.n;) {
		uint64_t parent = e->fr.e[i].morton >> 3, v = 0;
		for (; i < e->fr.n && e->fr.e[i].morton >> 3 == parent; i++)
			v |= (uint64_t)(uint8_t)e->fr.e[i].id
			     << 8 * (e->fr.e[i].morton & 7);
		uint32_t id;
		uint8_t r;
		if ((err = brick_add(e, &b, v, asis, &id, &r)) ||
		    (err = front_push(&nf, parent, id, r)))
			goto out;
	}
	for (size_t p = 0; p < e->np; p++) {
		const struct vd_dag *d = e->parts[p];
		if (d->chunk_level == l &&
		    (err = front_push(&nf, d->cell_morton, rm[p].id[0], rm[p].r[0])))
			goto out;
	}
	front_sort(&nf);
	free(b.slot); /* the table is done with: lower the peak */
	b.slot = NULL;

	/* Levels L-2 and L-1 of the output from the distinct bricks. */
	{
		struct vd_dag_level *lb = &e->out->lv[l], *ll = &e->out->lv[L - 1];
		const struct vd_leaf_class *lt = e->g48 ? vd_leaf_classes48()
						       : vd_leaf_classes();
		uint32_t leaf_id[256];
		uint8_t leaf_mask[256];
		uint32_t nleaf = 0;
		memset(leaf_id, 0xff, sizeof leaf_id);
		uint64_t nref = 0;
		for (uint64_t i = 0; i < b.n; i++)
			for (unsigned s = 0; s < 8; s++)
				nref += (b.v[i] >> 8 * s & 0xff) != 0;
		lb->nodes = b.n;
		lb->refs = nref;
		lb->mask = malloc(b.n ? b.n : 1);
		lb->first = malloc((b.n + 1) * 8);
		lb->child = malloc(nref ? nref * 4 : 1);
		if (e->sym) lb->refl = malloc(nref ? nref : 1);
		if (!lb->mask || !lb->first || !lb->child || (e->sym && !lb->refl)) {
			err = NOMEM();
			goto out;
		}
		uint64_t j = 0;
		for (uint64_t i = 0; i < b.n; i++) {
			uint8_t mk = 0;
			lb->first[i] = j;
			for (unsigned s = 0; s < 8; s++) {
				uint8_t v = (uint8_t)(b.v[i] >> 8 * s);
				if (!v) continue;
				mk |= (uint8_t)(1u << s);
				uint8_t c = e->sym ? lt[v].canon : v;
				if (leaf_id[c] == UINT32_MAX) {
					leaf_id[c] = nleaf;
					leaf_mask[nleaf++] = c;
				}
				lb->child[j] = leaf_id[c];
				if (e->sym) lb->refl[j] = lt[v].refl;
				j++;
			}
			lb->mask[i] = mk;
		}
		lb->first[b.n] = j;
		ll->nodes = nleaf;
		ll->mask = malloc(nleaf ? nleaf : 1);
		if (!ll->mask) {
			err = NOMEM();
			goto out;
		}
		memcpy(ll->mask, leaf_mask, nleaf);
		e->out->bricks = b.v;
		b.v = NULL;
	}
	engine_advance(e, &b.inv, &nf, &rm);
out:
	bset_free(&b);
	front_free(&nf);
	remaps_free(rm, e->np);
	return err;
}

/* ------------------------------------------------- parallel inner levels
 * Half the nodes of an inner level are distinct, so private sets per range
 * merged serially would redo most of the work (1.6 times the serial CPU,
 * measured). An inner level is deduplicated by hash shards instead. Every
 * element (the parts' nodes, then the frontier's groups: the serial order)
 * is keyed once, in ranges; the elements are bucketed by the low bits of
 * their hash, in element order; each shard deduplicates its elements in a
 * table small enough to stay in cache, keeping the first element of each
 * distinct node; the distinct nodes are then numbered by that first
 * element, a prefix sum over the ranges. That is the serial numbering
 * (first met, in element order) whatever the thread, range and shard
 * counts, so the bytes written do not depend on --threads. Keys are kept
 * where they were computed (a group's in its frontier entries, which are
 * not needed any more, a part node's in a buffer laid out like the part's
 * references) and copied into the shards' records. Cache-sized tables
 * read in a row make this faster than the serial loops even on one thread
 * (the dragon at 2^13: 0.53 s instead of 1.07 s for the inner levels of a
 * merge), so it runs on any thread count; the serial loops remain for
 * small levels and for budgets without room for its extra memory, and
 * give the same nodes. */

struct ipart {
	size_t p;      /* the part's index in the engine */
	uint64_t base; /* its first element */
	uint32_t *kid; /* key children of its nodes, at the part's first[] */
	uint8_t *kr;   /* their reflections (sym only) */
};

struct irange {
	size_t part;     /* index in ip->pa, or ip->npa: the frontier */
	uint64_t lo, hi; /* part nodes, or frontier entries (whole groups) */
	uint64_t e0, e1; /* elements */
	uint64_t *cnt;   /* elements per shard, then scatter cursors */
	uint64_t fresh;  /* distinct nodes first met here, then the first id */
};

struct ishard {
	uint64_t *slot, scap;
	uint32_t *rep; /* per distinct node: its first element */
	uint64_t *off; /* per distinct node: its record */
	uint32_t *id;  /* per distinct node: its level id */
	uint64_t n, cap;
	int err;
};

struct ipass {
	struct engine *e;
	int l, asis, shift;
	uint64_t npe, n;     /* part elements; all elements */
	struct ipart *pa;
	size_t npa;
	struct irange *r;
	size_t nr, kf;       /* ranges; the first over the frontier */
	struct ishard *sh;
	unsigned ns;         /* shards, a power of two */
	uint64_t *h;         /* per element: hash, then shard << 32 | index */
	uint8_t *mask, *inv; /* per element: key[0], invariance set */
	uint64_t *gstart;    /* per group: its first frontier entry */
	uint8_t *rec;        /* key records shard after shard, in order */
	uint64_t *sbase;     /* ns + 1 byte bounds in rec */
	uint32_t *of;        /* per level id: its first element */
	struct felem *nf;    /* per group: its cell, id and reflection */
	struct remap *rm;    /* the level's remaps */
	struct nset *b;      /* the level's output arrays */
};

/* A key record: the hash (8 bytes), the element (4), key[0] (1), then k
 * children (4 bytes each) and for a symmetric DAG their reflections (1
 * each). A shard reads its records in a row and compares within them, so
 * its deduplication touches nothing outside its own few hundred KiB. */
#define REC_SIZE(ip, k) ((uint64_t)13 + (uint64_t)(k) * ((ip)->e->sym ? 5 : 4))

/* Where element x's key children are: ids and reflections at strides. */
struct kview {
	const uint8_t *id, *r;
	size_t sid, sr;
};

static inline void elem_view(const struct ipass *ip, uint64_t x,
			     struct kview *v)
{
	if (x >= ip->npe) {
		const struct felem *f = ip->e->fr.e + ip->gstart[x - ip->npe];
		v->id = (const uint8_t *)&f->id;
		v->r = &f->r;
		v->sid = v->sr = sizeof *f;
		return;
	}
	size_t a = 0, z = ip->npa; /* the last part starting at or before x */
	while (z - a > 1) {
		size_t c = (a + z) / 2;
		if (ip->pa[c].base <= x) a = c;
		else z = c;
	}
	const struct ipart *pa = &ip->pa[a];
	uint64_t j = ip->e->parts[pa->p]->lv[ip->l].first[x - pa->base];
	v->id = (const uint8_t *)(pa->kid + j);
	v->r = pa->kr ? pa->kr + j : NULL;
	v->sid = 4;
	v->sr = 1;
}

#define KID(v, j) (*(const uint32_t *)((v)->id + (size_t)(j) * (v)->sid))
#define KR(v, j) ((v)->r[(size_t)(j) * (v)->sr])

/* Counts the groups of frontier range kf + k into its e1. */
static void inner_count_groups(void *ctx, size_t k, int worker)
{
	struct ipass *ip = ctx;
	struct irange *r = &ip->r[ip->kf + k];
	const struct felem *fe = ip->e->fr.e;
	uint64_t g = 0;
	for (uint64_t i = r->lo; i < r->hi; i++)
		g += i == r->lo || fe[i].morton >> 3 != fe[i - 1].morton >> 3;
	r->e1 = g;
	(void)worker;
}

static void inner_keys(void *ctx, size_t k, int worker)
{
	struct ipass *ip = ctx;
	struct irange *r = &ip->r[k];
	const struct engine *e = ip->e;
	uint64_t key[9], x = r->e0, sm = ip->ns - 1;
	uint8_t m, inv, rbits = (uint8_t)((1u << ip->shift) - 1);
	(void)worker;
	if (r->part < ip->npa) {
		const struct ipart *pa = &ip->pa[r->part];
		const uint64_t *first = e->parts[pa->p]->lv[ip->l].first;
		uint8_t *rr = ip->rm[pa->p].r;
		for (uint64_t i = r->lo; i < r->hi; i++, x++) {
			int n = part_key(e, pa->p, ip->l, i, ip->asis, key, &m,
					 &inv);
			uint64_t h = key_hash(key, n);
			ip->h[x] = h;
			ip->mask[x] = (uint8_t)key[0];
			ip->inv[x] = inv;
			rr[i] = m;
			uint32_t *kid = pa->kid + first[i];
			for (int j = 0; j < n; j++)
				kid[j] = (uint32_t)(key[j + 1] >> ip->shift);
			if (pa->kr)
				for (int j = 0; j < n; j++)
					pa->kr[first[i] + (uint64_t)j] =
						(uint8_t)(key[j + 1] & rbits);
			r->cnt[h & sm] += REC_SIZE(ip, n);
		}
		return;
	}
	struct felem *fe = e->fr.e;
	for (uint64_t i = r->lo; i < r->hi; x++) {
		uint64_t g = i, parent;
		int n = group_key(e, &i, ip->asis, &parent, key, &m, &inv);
		uint64_t h = key_hash(key, n);
		ip->h[x] = h;
		ip->mask[x] = (uint8_t)key[0];
		ip->inv[x] = inv;
		ip->gstart[x - ip->npe] = g;
		ip->nf[x - ip->npe] = (struct felem){parent, 0, m};
		/* the group's entries were read: they hold its key now */
		for (int j = 0; j < n; j++) {
			struct felem *f = &fe[g + (uint64_t)j];
			f->id = (uint32_t)(key[j + 1] >> ip->shift);
			f->r = (uint8_t)(key[j + 1] & rbits);
		}
		r->cnt[h & sm] += REC_SIZE(ip, n);
	}
}

static void inner_scatter(void *ctx, size_t k, int worker)
{
	struct ipass *ip = ctx;
	struct irange *r = &ip->r[k];
	uint64_t sm = ip->ns - 1;
	struct kview v;
	(void)worker;
	for (uint64_t x = r->e0; x < r->e1; x++) {
		uint64_t h = ip->h[x];
		uint8_t *q = ip->rec + r->cnt[h & sm];
		uint32_t x32 = (uint32_t)x;
		int n = vd__dag_pop8(ip->mask[x]);
		memcpy(q, &h, 8);
		memcpy(q + 8, &x32, 4);
		q[12] = ip->mask[x];
		elem_view(ip, x, &v);
		for (int j = 0; j < n; j++) {
			uint32_t c = KID(&v, j);
			memcpy(q + 13 + 4 * j, &c, 4);
		}
		if (ip->e->sym)
			for (int j = 0; j < n; j++) q[13 + 4 * n + j] = KR(&v, j);
		r->cnt[h & sm] += REC_SIZE(ip, n);
	}
}

static void inner_dedup(void *ctx, size_t s, int worker)
{
	struct ipass *ip = ctx;
	struct ishard *sh = &ip->sh[s];
	uint64_t lo = ip->sbase[s], hi = ip->sbase[s + 1], m = 0;
	(void)worker;
	for (uint64_t t = lo; t < hi; m++) /* records */
		t += REC_SIZE(ip, vd__dag_pop8(ip->rec[t + 12]));
	/* room for every record at half load, so the table never doubles;
	 * only the shards being worked on have one */
	uint64_t c = 256;
	while (c < 2 * m) c *= 2;
	if (!(sh->slot = calloc((size_t)c, 8))) {
		sh->err = NOMEM();
		return;
	}
	sh->scap = c;
	for (uint64_t t = lo; t < hi;) {
		const uint8_t *q = ip->rec + t;
		uint64_t h, size = REC_SIZE(ip, vd__dag_pop8(q[12]));
		uint32_t x;
		memcpy(&h, q, 8);
		memcpy(&x, q + 8, 4);
		uint64_t mask = sh->scap - 1, i = SLOT_INDEX(h, mask);
		uint64_t found = UINT64_MAX;
		for (;; i = (i + 1) & mask) {
			uint64_t v = sh->slot[i];
			if (!v) break;
			if (SLOT_TAG(v) != SLOT_TAG(h)) continue;
			const uint8_t *o = ip->rec + sh->off[(v & 0xffffffff) - 1];
			if (o[12] == q[12] && !memcmp(o + 13, q + 13, size - 13)) {
				found = (v & 0xffffffff) - 1;
				break;
			}
		}
		if (found == UINT64_MAX) {
			if (sh->n == sh->cap) {
				uint64_t nc = next_cap(sh->cap, sh->n + 1);
				if ((sh->err = grow((void **)&sh->rep, nc, 4)) ||
				    (sh->err = grow((void **)&sh->off, nc, 8)))
					return;
				sh->cap = nc;
			}
			sh->slot[i] = SLOT_TAG(h) | (sh->n + 1);
			sh->rep[sh->n] = x;
			sh->off[sh->n] = t;
			found = sh->n++;
			if (2 * sh->n > sh->scap &&
			    (sh->err = table_rehash(&sh->slot, &sh->scap)))
				return;
		}
		ip->h[x] = (uint64_t)s << 32 | found;
		t += size;
	}
	free(sh->slot);
	sh->slot = NULL;
	free(sh->off);
	sh->off = NULL;
	if (!(sh->id = malloc(sh->n ? (size_t)sh->n * 4 : 4))) sh->err = NOMEM();
}

/* Whether element x is the first of its distinct node. */
#define IS_FIRST(ip, x) \
	((ip)->sh[(ip)->h[x] >> 32].rep[(ip)->h[x] & 0xffffffff] == (x))

static void inner_fresh(void *ctx, size_t k, int worker)
{
	struct ipass *ip = ctx;
	struct irange *r = &ip->r[k];
	uint64_t f = 0;
	for (uint64_t x = r->e0; x < r->e1; x++) f += IS_FIRST(ip, x);
	r->fresh = f;
	(void)worker;
}

static void inner_number(void *ctx, size_t k, int worker)
{
	struct ipass *ip = ctx;
	struct irange *r = &ip->r[k];
	uint32_t id = (uint32_t)r->fresh;
	for (uint64_t x = r->e0; x < r->e1; x++)
		if (IS_FIRST(ip, x)) {
			ip->sh[ip->h[x] >> 32].id[ip->h[x] & 0xffffffff] = id;
			ip->of[id++] = (uint32_t)x;
		}
	(void)worker;
}

static void inner_rename(void *ctx, size_t k, int worker)
{
	struct ipass *ip = ctx;
	struct irange *r = &ip->r[k];
	uint32_t *rid = r->part < ip->npa ? ip->rm[ip->pa[r->part].p].id : NULL;
	uint64_t base = r->part < ip->npa ? ip->pa[r->part].base : ip->npe;
	for (uint64_t x = r->e0; x < r->e1; x++) {
		uint32_t id = ip->sh[ip->h[x] >> 32].id[ip->h[x] & 0xffffffff];
		if (rid) rid[x - base] = id;
		else ip->nf[x - base].id = id;
	}
	(void)worker;
}

/* The output's children, ids [n * k / nr, n * (k + 1) / nr). */
static void inner_children(void *ctx, size_t k, int worker)
{
	struct ipass *ip = ctx;
	struct nset *b = ip->b;
	uint64_t lo = b->n * k / ip->nr, hi = b->n * (k + 1) / ip->nr;
	struct kview v;
	for (uint64_t i = lo; i < hi; i++) {
		elem_view(ip, ip->of[i], &v);
		uint64_t j = b->first[i], n = b->first[i + 1] - j;
		for (uint64_t q = 0; q < n; q++) b->child[j + q] = KID(&v, q);
		if (b->refl)
			for (uint64_t q = 0; q < n; q++) b->refl[j + q] = KR(&v, q);
	}
	(void)worker;
}

static void ipass_free(struct ipass *ip)
{
	for (size_t i = 0; ip->pa && i < ip->npa; i++) {
		free(ip->pa[i].kid);
		free(ip->pa[i].kr);
	}
	for (size_t i = 0; ip->r && i < ip->nr; i++) free(ip->r[i].cnt);
	for (unsigned s = 0; ip->sh && s < ip->ns; s++) {
		free(ip->sh[s].slot);
		free(ip->sh[s].rep);
		free(ip->sh[s].off);
		free(ip->sh[s].id);
	}
	free(ip->pa);
	free(ip->r);
	free(ip->sh);
	free(ip->h);
	free(ip->mask);
	free(ip->inv);
	free(ip->gstart);
	free(ip->rec);
	free(ip->sbase);
	free(ip->of);
}

/* Bytes the parallel pass needs beyond the serial one, for `groups`
 * frontier groups (at most e->fr.n). Per element: hash 8, mask and set 2,
 * first-element and id maps 12, record offset 8, record 13 and 5 a
 * reference, shard table at work 8 at most (51); a group's start 8 more; a
 * part node's key children 5 a reference. The parts' level stays whole
 * until the pass ends, where the serial pass frees it part by part and the
 * estimate counts one part's: 9 a node and 5 a reference more. The serial
 * pass's table, which the estimates count, is not made: this is an upper
 * bound. */
static uint64_t inner_extra_bytes(const struct engine *e, int l,
				  uint64_t groups)
{
	uint64_t b = (1 << 20) + groups * (51 + 8) + e->fr.n * 5;
	for (size_t p = 0; p < e->np; p++)
		if (e->parts[p]->chunk_level <= l)
			b += e->parts[p]->lv[l].nodes * 60 +
			     e->parts[p]->lv[l].refs * 15;
	return b;
}

/* Whether inner level l runs the sharded pass: enough elements to pay,
 * few enough for 32-bit element numbers, and room in the budget for the
 * pass's extra memory (else the serial loops, which give the same nodes,
 * run: the budget is never exceeded for speed). */
static int inner_parallel_pays(const struct engine *e, int l)
{
	uint64_t n = e->fr.n / 4, all = e->fr.n;
	for (size_t p = 0; p < e->np; p++)
		if (e->parts[p]->chunk_level <= l) {
			n += e->parts[p]->lv[l].nodes;
			all += e->parts[p]->lv[l].nodes;
		}
	if (n < PAR_MIN || all > UINT32_MAX) return 0;
	if (inner_extra_bytes(e, l, e->fr.n) <= e->spare_bytes) return 1;
	uint64_t groups = 0; /* the bound was for single-child groups */
	for (uint64_t i = 0; i < e->fr.n; i++)
		groups += !i ||
			  e->fr.e[i].morton >> 3 != e->fr.e[i - 1].morton >> 3;
	return inner_extra_bytes(e, l, groups) <= e->spare_bytes;
}

/* inner_parallel's first step: the parts with nodes on level ip->l, the
 * ranges of elements over them and the frontier, and the shards (ip->pa,
 * npa, npe, r, nr, kf, sh, ns, sbase). On an error ipass_free releases
 * what it made. */
static int inner_plan(struct ipass *ip)
{
	struct engine *e = ip->e;
	int l = ip->l;
	int treq = e->threads > 0 ? e->threads : vd_hardware_threads();
	/* the parts with nodes on this level, and ranges over them and the
	 * frontier of about `chunk` elements each, several per thread */
	uint64_t est = e->fr.n / 4;
	for (size_t p = 0; p < e->np; p++)
		if (e->parts[p]->chunk_level <= l) {
			ip->npa++;
			est += e->parts[p]->lv[l].nodes;
		}
	uint64_t chunk = est / ((uint64_t)treq * 8);
	if (chunk < PAR_MIN / 4) chunk = PAR_MIN / 4;
	size_t nr = e->fr.n ? (size_t)((e->fr.n / 4 + chunk - 1) / chunk) : 0;
	if (nr == 0 && e->fr.n) nr = 1;
	for (size_t p = 0; p < e->np; p++)
		if (e->parts[p]->chunk_level <= l)
			nr += (size_t)((e->parts[p]->lv[l].nodes + chunk - 1) /
				       chunk);
	ip->pa = calloc(ip->npa ? ip->npa : 1, sizeof *ip->pa);
	ip->r = calloc(nr ? nr : 1, sizeof *ip->r);
	/* shards of about 16 thousand elements, so that a table (at most 4
	 * slots of 8 bytes an element: 512 KiB) stays in cache; several per
	 * thread, which balance the load */
	unsigned ns = 8;
	while (ns < 1024 && ((uint64_t)ns << 14 < est || ns < 4u * (unsigned)treq))
		ns *= 2;
	ip->ns = ns;
	ip->sh = calloc(ns, sizeof *ip->sh);
	ip->sbase = calloc(ns + 1, 8);
	if (!ip->pa || !ip->r || !ip->sh || !ip->sbase)
		return NOMEM();
	size_t a = 0, k = 0;
	uint64_t base = 0;
	for (size_t p = 0; p < e->np; p++) {
		const struct vd_dag *d = e->parts[p];
		if (d->chunk_level > l) continue;
		struct ipart *pa = &ip->pa[a];
		uint64_t n = d->lv[l].nodes, refs = d->lv[l].refs;
		pa->p = p;
		pa->base = base;
		pa->kid = malloc(refs ? (size_t)refs * 4 : 4);
		if (e->sym) pa->kr = malloc(refs ? (size_t)refs : 1);
		if (!pa->kid || (e->sym && !pa->kr))
			return NOMEM();
		for (uint64_t lo = 0; lo < n; lo += chunk, k++) {
			ip->r[k].part = a;
			ip->r[k].lo = lo;
			ip->r[k].hi = n - lo < chunk ? n : lo + chunk;
			ip->r[k].e0 = base + lo;
			ip->r[k].e1 = base + ip->r[k].hi;
		}
		base += n;
		a++;
	}
	ip->npe = base;
	/* frontier ranges end on group boundaries */
	size_t kf = k, nfr = nr - kf;
	const struct felem *fe = e->fr.e;
	for (size_t q = 0; q < nfr; q++, k++) {
		uint64_t lo = e->fr.n * q / nfr;
		while (lo > 0 && lo < e->fr.n &&
		       fe[lo].morton >> 3 == fe[lo - 1].morton >> 3)
			lo++;
		ip->r[k].part = ip->npa;
		ip->r[k].lo = lo;
		if (q) ip->r[k - 1].hi = lo;
	}
	if (nfr) ip->r[nr - 1].hi = e->fr.n;
	ip->nr = nr;
	for (k = 0; k < nr; k++)
		if (!(ip->r[k].cnt = calloc(ns, 8)))
			return NOMEM();
	ip->kf = kf;
	return VD_OK;
}

/* Level l's nodes into b (its arrays exact, b->slot unused), the parts'
 * remaps into rm, the groups into nf; the same as the serial loops. */
static int inner_parallel(struct engine *e, int l, int asis, struct nset *b,
			  struct front *nf, struct remap *rm)
{
	struct ipass ip = {.e = e, .l = l, .asis = asis, .shift = b->shift,
			   .rm = rm, .b = b};
	int t = pass_threads(e), err = inner_plan(&ip);
	if (err) goto out;
	size_t nr = ip.nr, kf = ip.kf, nfr = nr - kf, k;
	unsigned ns = ip.ns;
	if ((err = vd_parallel_for(nfr, t, inner_count_groups, &ip))) goto out;
	uint64_t groups = 0;
	for (k = kf; k < nr; k++) {
		uint64_t g = ip.r[k].e1;
		ip.r[k].e0 = ip.npe + groups;
		ip.r[k].e1 = ip.r[k].e0 + g;
		groups += g;
	}
	ip.n = ip.npe + groups;
	ip.h = malloc(ip.n ? (size_t)ip.n * 8 : 8);
	ip.mask = malloc(ip.n ? (size_t)ip.n : 1);
	ip.inv = malloc(ip.n ? (size_t)ip.n : 1);
	ip.gstart = malloc(groups ? (size_t)groups * 8 : 8);
	if ((err = grow((void **)&nf->e, groups ? groups : 1, sizeof *nf->e)))
		goto out;
	nf->cap = groups ? groups : 1;
	nf->n = groups;
	ip.nf = nf->e;
	if (!ip.h || !ip.mask || !ip.inv || !ip.gstart) {
		err = NOMEM();
		goto out;
	}
	if ((err = vd_parallel_for(nr, t, inner_keys, &ip))) goto out;
	/* bucket by shard: the records of shard s from sbase[s], range after
	 * range */
	uint64_t at = 0;
	for (unsigned s = 0; s < ns; s++) {
		ip.sbase[s] = at;
		for (k = 0; k < nr; k++) {
			uint64_t c = ip.r[k].cnt[s];
			ip.r[k].cnt[s] = at;
			at += c;
		}
	}
	ip.sbase[ns] = at;
	if (!(ip.rec = malloc(at ? (size_t)at : 1))) {
		err = NOMEM();
		goto out;
	}
	if ((err = vd_parallel_for(nr, t, inner_scatter, &ip))) goto out;
	if ((err = vd_parallel_for(ns, t, inner_dedup, &ip))) goto out;
	free(ip.rec);
	ip.rec = NULL;
	uint64_t distinct = 0;
	for (unsigned s = 0; s < ns; s++) {
		/* a worker's detail line is its own: say it again here */
		if (ip.sh[s].err) {
			err = NOMEM();
			goto out;
		}
		distinct += ip.sh[s].n;
	}
	if (distinct > VD__DAG_MAX_LEVEL_NODES) {
		err = vd_fail(VD_ERR_RANGE, "more than %llu distinct nodes on a "
			      "level", (unsigned long long)VD__DAG_MAX_LEVEL_NODES);
		goto out;
	}
	if (!(ip.of = malloc(distinct ? (size_t)distinct * 4 : 4))) {
		err = NOMEM();
		goto out;
	}
	if ((err = vd_parallel_for(nr, t, inner_fresh, &ip))) goto out;
	uint64_t id = 0;
	for (k = 0; k < nr; k++) {
		uint64_t f = ip.r[k].fresh;
		ip.r[k].fresh = id;
		id += f;
	}
	if ((err = vd_parallel_for(nr, t, inner_number, &ip))) goto out;
	if ((err = vd_parallel_for(nr, t, inner_rename, &ip))) goto out;
	free(ip.h);
	ip.h = NULL;
	/* the output: masks, sets and offsets in id order, then the
	 * children copied from the first elements' keys in ranges */
	b->n = distinct;
	b->mask = malloc(distinct ? (size_t)distinct : 1);
	b->inv = malloc(distinct ? (size_t)distinct : 1);
	b->first = malloc((size_t)(distinct + 1) * 8);
	if (!b->mask || !b->inv || !b->first) {
		err = NOMEM();
		goto out;
	}
	uint64_t j = 0;
	for (uint64_t i = 0; i < distinct; i++) {
		uint32_t x = ip.of[i];
		b->mask[i] = ip.mask[x];
		b->inv[i] = ip.inv[x];
		b->first[i] = j;
		j += (uint64_t)vd__dag_pop8(ip.mask[x]);
	}
	b->first[distinct] = j;
	b->nref = j;
	b->child = malloc(j ? (size_t)j * 4 : 4);
	if (e->sym) b->refl = malloc(j ? (size_t)j : 1);
	if (!b->child || (e->sym && !b->refl)) {
		err = NOMEM();
		goto out;
	}
	err = vd_parallel_for(nr, t, inner_children, &ip);
out:
	ipass_free(&ip);
	return err;
}

/* An inner level l < L-2. */
static int level_inner(struct engine *e, int l)
{
	int asis = e->A == l, err = VD_OK;
	struct nset b = {.sym = e->sym, .shift = e->g48 ? 6 : 3};
	struct front nf = {0};
	struct remap *rm = remaps_new(e, l);
	uint64_t expect = e->fr.n / 4;
	for (size_t p = 0; p < e->np; p++)
		if (e->parts[p]->chunk_level <= l)
			expect += e->parts[p]->lv[l].nodes;
	if (!rm) return NOMEM();
	if (inner_parallel_pays(e, l)) {
		if ((err = inner_parallel(e, l, asis, &b, &nf, rm))) goto out;
		for (size_t p = 0; p < e->np; p++)
			if (e->parts[p]->chunk_level <= l) part_drop(e, p, l);
	} else {
		/* A merge's inner levels are about half distinct: a table
		 * for all of them at once never doubles, so it is never held
		 * twice (and its size is known before the level starts:
		 * the parts' nodes and a group per frontier cell at most). */
		if (e->np ? (err = table_exact(&b.slot, &b.scap, expect -
					       e->fr.n / 4 + e->fr.n))
			  : (err = table_init(&b.slot, &b.scap, expect)))
			goto out;
		uint8_t m, inv;
		uint64_t key[9];
		for (size_t p = 0; p < e->np; p++) {
			if (e->parts[p]->chunk_level > l) continue;
			for (uint64_t i = 0; i < e->parts[p]->lv[l].nodes; i++) {
				int k = part_key(e, p, l, i, asis, key, &m, &inv);
				if ((err = nset_insert(&b, key, k, inv,
						       &rm[p].id[i])))
					goto out;
				rm[p].r[i] = m;
			}
			part_drop(e, p, l);
		}
		if ((err = frontier_groups(e, &b, asis, &nf))) goto out;
	}
	for (size_t p = 0; p < e->np; p++) {
		const struct vd_dag *d = e->parts[p];
		if (d->chunk_level == l &&
		    (err = front_push(&nf, d->cell_morton, rm[p].id[0], rm[p].r[0])))
			goto out;
	}
	front_sort(&nf);
	free(b.slot);
	b.slot = NULL;

	struct vd_dag_level *lv = &e->out->lv[l];
	lv->nodes = b.n;
	lv->refs = b.nref;
	/* Hand the arrays over, trimmed: they live as long as the DAG. */
	if (b.n) {
		void *q;
		if ((q = realloc(b.mask, (size_t)b.n))) b.mask = q;
		if ((q = realloc(b.inv, (size_t)b.n))) b.inv = q;
		if ((q = realloc(b.first, (size_t)(b.n + 1) * 8))) b.first = q;
		if ((q = realloc(b.child, (size_t)b.nref * 4))) b.child = q;
		if (b.refl && (q = realloc(b.refl, (size_t)b.nref))) b.refl = q;
	}
	lv->mask = b.mask ? b.mask : malloc(1);
	lv->first = b.first ? b.first : calloc(1, 8);
	lv->child = b.child ? b.child : malloc(1);
	if (e->sym) lv->refl = b.refl ? b.refl : malloc(1);
	b.mask = NULL;
	b.first = NULL;
	b.child = NULL;
	b.refl = NULL;
	if (!lv->mask || !lv->first || !lv->child || (e->sym && !lv->refl)) {
		err = NOMEM();
		goto out;
	}
	engine_advance(e, &b.inv, &nf, &rm);
out:
	nset_free(&b);
	front_free(&nf);
	remaps_free(rm, e->np);
	return err;
}

static int run_engine(struct engine *e)
{
	int err = VD_OK;
	vd__sym_init();
	if (e->g48) /* ~10 ms of tables: only the 48-symmetry DAG needs them */
		vd__g48_init();
	for (int l = e->L - 1; l >= e->A && !err; l--) {
		double t0 = vd_seconds();
		if (l == e->L - 1)
			err = level_leaf(e);
		else if (l == e->L - 2)
			err = level_brick(e);
		else
			err = level_inner(e, l);
		if (e->st) e->st->seconds_level[l] = vd_seconds() - t0;
	}
	if (!err && e->fr.n != 1)
		err = vd_fail(VD_ERR_INTERNAL, "build.c: %llu roots at level %d",
			      (unsigned long long)e->fr.n, e->A);
	front_free(&e->fr);
	remaps_free(e->rm, e->np);
	e->rm = NULL;
	free(e->inv_below);
	e->inv_below = NULL;
	return err;
}

/* ------------------------------------------------------------ public API */

void vd_dag_release(struct vd_dag *dag)
{
	if (!dag) return;
	for (int l = 0; l < VD_MAX_LEVELS; l++) {
		free(dag->lv[l].mask);
		free(dag->lv[l].first);
		free(dag->lv[l].child);
		free(dag->lv[l].refl);
	}
	free(dag->bricks);
	memset(dag, 0, sizeof *dag);
}

uint64_t vd_dag_memory_bytes(const struct vd_dag *dag)
{
	uint64_t b = 0;
	for (int l = dag->chunk_level; l < dag->levels; l++) {
		const struct vd_dag_level *lv = &dag->lv[l];
		b += lv->nodes * (1 + (lv->first ? 8 : 0)) + lv->refs * 4 +
		     (lv->refl ? lv->refs : 0);
	}
	if (dag->bricks) b += dag->lv[dag->levels - 2].nodes * 8;
	return b;
}

/* The peak is at the brick level or at level L-3. Per brick B: the SVO
 * (16), the frontier (16), the brick set (8 + 1, and a table of up to 4
 * slots of 8 per distinct brick, 6 while it doubles: 48). After the brick
 * level the table is freed and the output holds bricks, masks and offsets
 * (17 per brick) and 4 per reference, at most one per leaf L1. Level L-3
 * with N3 parents adds the new frontier (16), the node set (10 per node, 4
 * per reference: at most one per brick) and its table (48 per node).
 * Growing arrays may be half empty: the node terms count 1.5 times. */
uint64_t vd_dag_estimate_from_svo(uint64_t bricks, uint64_t leaves,
				  uint64_t parents)
{
	uint64_t brick_phase = bricks * (16 + 16 + 9 + 48);
	uint64_t inner_phase = bricks * (16 + 16 + 17 + 4) + leaves * 4 +
			       parents * (16 + 10 + 48) * 3 / 2;
	return (brick_phase > inner_phase ? brick_phase : inner_phase) +
	       VD_DAG_ESTIMATE_FIXED_BYTES;
}

/* A merge's memory, from its engine (vd_dag_run, vd_dag_merge_consume,
 * run_engine). Parts are loaded one by one: per node a mask (1) and an
 * offset (8; none on level L-1), per reference a child (4) and a
 * reflection (1, symmetric kinds), per level L-2 node a brick (8). While
 * part i loads, its file image, its sections and the voxel count's two
 * levels of 8 bytes are in flight (`largest`). The engine then builds the
 * output bottom-up, one level l at a time, and what a level needs besides
 * the output is freed before the next level starts; so the peak is the
 * parts still held, plus the output of the levels built so far, plus the
 * largest single level's working set, never a sum over levels:
 *  - the parts: all of them up to the brick level (L-2), which frees
 *    levels L-2 and L-1 part by part; on an inner level l, their levels
 *    above l, and of level l the one part being read (the others' are
 *    either still unread or freed and replaced by the output, which is
 *    counted in full below and has no more nodes nor references than
 *    what it was read from);
 *  - the parts' renaming maps of levels l and l+1 (id 4 + reflection 1
 *    per part node) and the invariance sets of levels l and l+1 (1 per
 *    output node);
 *  - the hash table: on the brick level at most 4 slots of 8 bytes per
 *    distinct brick after it doubles, 6 while it doubles (48), or its
 *    first size, at most 2 bytes per input brick; on an inner level one
 *    table for all its part nodes and frontier cells at under half load,
 *    a power of two of 8-byte slots made once: at most 4 slots per node
 *    (counted so, not rounded, the bound stays subadditive), 1024 at
 *    least; frontiers of part roots (16 per part);
 *  - the level's output: masks and offsets (9 per node), references
 *    (4 or 5), bricks on level L-2 (8). On level L-2 the table is freed
 *    before the masks, offsets and references are made, so the two are
 *    not counted together there. Level L-1 of a merge holds at most the
 *    256 distinct leaf masks.
 * A level's distinct nodes are bounded by its part nodes plus one new
 * parent per part (cells above the parts' roots), its references by the
 * parts' plus one per part. The heap keeps holes: arrays that grow by
 * realloc may leave old copies behind (half the growing arrays again), and
 * the loads' freed images and sections, below glibc's rising mmap
 * threshold, stay resident and are reused only in part (the dragon's
 * merges at 2^15: up to 30% of the largest part's load beyond the parts
 * once all are loaded; half of it is counted). The fixed 16 MiB holds the
 * code and threads (about 4 MiB resident), zstd and small arrays. The
 * parallel inner pass needs more (inner_extra_bytes); it runs only when
 * the budget covers that beyond this bound. vd_dag_merge, which leaves
 * its parts whole, holds them all to the end (`keep`). Measured serial
 * peaks sit 1.1-1.6 times under it, closest on small merges whose freed
 * arrays stay in the heap (the dragon's root from its L1 chunks at 2^13:
 * bound 200 MiB, peak 186; at 2^15: 2119 and 1551; at 2^17: 256 M input
 * nodes, bound 15.0 GiB, peak 9.3 GiB, where the parts held whole and a
 * doubling table gave a bound of 22.0 GiB and a peak of 13.9 GiB). */
void vd_dag_census_add(struct vd_dag_census *c, const struct vd_dag *d)
{
	if (!c->parts++) c->levels = d->levels;
	uint64_t n = 0, r = 0;
	for (int l = d->chunk_level; l < d->levels && l < VD_MAX_LEVELS; l++) {
		c->nodes[l] += d->lv[l].nodes;
		c->refs[l] += d->lv[l].refs;
		if (d->lv[l].nodes > c->big_nodes[l])
			c->big_nodes[l] = d->lv[l].nodes;
		if (d->lv[l].refs > c->big_refs[l]) c->big_refs[l] = d->lv[l].refs;
		n += d->lv[l].nodes;
		r += d->lv[l].refs;
	}
	if (11 * n + 10 * r > c->largest) c->largest = 11 * n + 10 * r;
}

void vd_dag_census_add_header(struct vd_dag_census *c,
			      const struct vd_chunk_header *h)
{
	int L = (int)h->levels, A = (int)h->chunk_level;
	if (!c->parts++) c->levels = L;
	uint64_t n = 0, r = 0;
	for (int l = A; l < L && l < VD_MAX_LEVELS &&
	     (uint32_t)(l - A) + 1 < h->level_count; l++) {
		uint64_t nl = h->level_nodes[l - A], rl = 0;
		if (l < L - 1)
			rl = h->kind == VD_KIND_SVO ? h->level_nodes[l - A + 1]
						    : 8 * nl;
		c->nodes[l] += nl;
		c->refs[l] += rl;
		if (nl > c->big_nodes[l]) c->big_nodes[l] = nl;
		if (rl > c->big_refs[l]) c->big_refs[l] = rl;
		n += nl;
		r += rl;
	}
	if (11 * n + 10 * r > c->largest) c->largest = 11 * n + 10 * r;
}

static uint64_t estimate_merge(const struct vd_dag_census *c, uint32_t kind,
			       int keep)
{
	int L = c->levels < VD_MAX_LEVELS ? c->levels : VD_MAX_LEVELS;
	uint64_t np = c->parts, rb = kind == VD_KIND_DAG ? 4 : 5;
	const uint64_t *n = c->nodes, *r = c->refs;
	if (L < 1) return VD_DAG_ESTIMATE_FIXED_BYTES;
	/* the parts (an ssvdag merge counts their references at 5), and
	 * those of their levels above l */
	uint64_t above[VD_MAX_LEVELS + 1];
	above[0] = 8 * np * (uint64_t)L;
	for (int l = 0; l < L; l++)
		above[l + 1] = above[l] + (l < L - 1 ? 9 * n[l] + rb * r[l]
						     : n[l]) +
			       (l == L - 2 ? 8 * n[l] : 0);
	uint64_t parts = above[L];
	uint64_t peak = parts + c->largest, holes = c->largest / 2;
	/* the output below level l, and level l at work */
	uint64_t below = n[L - 1] + np < 256 ? n[L - 1] + np : 256;
	for (int l = L - 2; l >= 0; l--) {
		uint64_t d = n[l] + np, ro = r[l] + np, dn = n[l + 1] + np;
		uint64_t out = 9 * d + rb * ro, work, held = parts;
		if (l == L - 2) {
			uint64_t table = 48 * d + 2 * n[l] + (8 << 10);
			out += 8 * d;
			uint64_t late = 9 * d + rb * ro; /* after the table */
			work = 5 * n[l] + 9 * d + 9 * d / 2 +
			       (table > late ? table : late);
		} else {
			work = out + out / 2 + 5 * n[l] + 5 * n[l + 1] + d +
			       dn + 8 * (4 * d > 1024 ? 4 * d : 1024);
			if (!keep)
				held = above[l] + 9 * c->big_nodes[l] +
				       rb * c->big_refs[l];
		}
		work += 16 * np + holes;
		if (held + below + work > peak) peak = held + below + work;
		below += out;
	}
	return peak + VD_DAG_ESTIMATE_FIXED_BYTES;
}

uint64_t vd_dag_estimate_merge(const struct vd_dag_census *c, uint32_t kind)
{
	return estimate_merge(c, kind, 0);
}

uint64_t vd_dag_estimate_header(const struct vd_chunk_header *h)
{
	uint32_t n = h->level_count;
	if (h->kind == VD_KIND_SVO) /* levels L-1, L-2, L-3 of L0..L */
		return vd_dag_estimate_from_svo(n >= 3 ? h->level_nodes[n - 3] : 1,
						n >= 2 ? h->level_nodes[n - 2] : 1,
						n >= 4 ? h->level_nodes[n - 4] : 1);
	struct vd_dag_census c = {0};
	vd_dag_census_add_header(&c, h);
	return vd_dag_estimate_merge(&c, h->kind);
}

static int check_kind_out(uint32_t kind)
{
	if (!vd__dag_is_dag_kind(kind))
		return vd_fail(VD_ERR_ARG, "output kind %u is not dag, ssvdag "
			       "or ssvdag48", kind);
	return VD_OK;
}

int vd__dag_check_budget(const struct vd_dag_opts *o, uint64_t need,
			 struct vd_dag_stats *st)
{
	if (st) st->memory_estimate_bytes = need;
	if (o && o->mem_budget_bytes && need > o->mem_budget_bytes)
		return vd_fail(VD_ERR_BUDGET, "needs about %llu MiB, budget "
			       "--mem-budget %llu MiB",
			       (unsigned long long)(need >> 20),
			       (unsigned long long)(o->mem_budget_bytes >> 20));
	return VD_OK;
}

/* What the budget leaves beyond the estimate `need` (which it covers). */
static uint64_t spare(const struct vd_dag_opts *o, uint64_t need)
{
	if (!o || !o->mem_budget_bytes) return UINT64_MAX;
	return o->mem_budget_bytes > need ? o->mem_budget_bytes - need : 0;
}

/* vd_dag_from_svo; `counts`, when not NULL, are the per-level counts of
 * the chunk header `svo` was read from by vd_svo_from_chunk, which has
 * checked the bricks (increasing, non-empty, inside the cell) and these
 * counts against them: the pass below that checks and counts them again
 * is then skipped where the counts hold what it counts (it was a serial
 * twentieth of svo-to-dag). */
int vd__dag_from_svo(struct vd_dag *dag, const struct vd_svo *svo,
		     uint32_t kind, const struct vd_dag_opts *opts,
		     struct vd_dag_stats *stats, const uint64_t *counts)
{
	memset(dag, 0, sizeof *dag);
	int err = check_kind_out(kind);
	if (err) return err;
	int L = svo->levels, L0 = svo->chunk_level;
	if (L < 1 || L > VD_MAX_LEVELS || L0 < 0 || L0 > L - 1)
		return vd_fail(VD_ERR_RANGE, "levels %d, chunk level %d", L, L0);
	if (L0 < VD_MAX_LEVELS && (L0 == 0 ? svo->cell_morton != 0
				   : svo->cell_morton >> (3 * L0) != 0))
		return vd_fail(VD_ERR_RANGE, "cell %" PRIu64 " outside level %d",
			       svo->cell_morton, L0);
	/* The bricks must be strictly increasing, non-empty and in the cell. */
	uint64_t voxels = 0, leaves = 0, parents = 0;
	int known = counts && L >= 3 && L0 <= L - 3;
	if (known) {
		voxels = counts[L - L0];
		leaves = counts[L - 1 - L0];
		parents = counts[L - 3 - L0];
	}
	for (size_t i = 0; i < svo->count && !known; i++) {
		uint64_t k = svo->keys[i], v = svo->masks[i];
		for (unsigned c = 0; c < 8; c++) leaves += (v >> 8 * c & 0xff) != 0;
		parents += i == 0 || k >> 3 != svo->keys[i - 1] >> 3;
		int in;
		if (L0 <= L - 2)
			in = k >> (3 * (L - 2 - L0)) == svo->cell_morton;
		else /* the cell is one 2x2x2 byte of the brick */
			in = k == svo->cell_morton >> 3 &&
			     (v & ~(0xffULL << 8 * (svo->cell_morton & 7))) == 0;
		if (!in || !v || (i && k <= svo->keys[i - 1]))
			return vd_fail(VD_ERR_CORRUPT, "brick %zu (key %" PRIu64
				       ") is %s", i, k, !v ? "empty" : !in
				       ? "outside the cell" : "out of order");
		voxels += vd__dag_popcount64(v);
	}
	if (stats) {
		memset(stats, 0, sizeof *stats);
		stats->input_voxels = voxels;
		stats->input_nodes = svo->count;
	}
	uint64_t need = vd_dag_estimate_from_svo(svo->count, leaves, parents);
	if ((err = vd__dag_check_budget(opts, need, stats))) return err;
	dag->kind = kind;
	dag->levels = L;
	dag->chunk_level = L0;
	dag->cell_morton = svo->cell_morton;
	dag->voxels = voxels;
	if (!svo->count) return VD_OK;
	double t0 = vd_seconds();
	struct engine e = {.sym = kind != VD_KIND_DAG,
			   .g48 = kind == VD_KIND_SSVDAG48, .L = L, .A = L0,
			   .cellA = svo->cell_morton, .svo = svo, .out = dag,
			   .st = stats, .threads = opts ? opts->threads : 0,
			   .spare_bytes = spare(opts, need)};
	err = run_engine(&e);
	if (stats) stats->seconds_build = vd_seconds() - t0;
	return err;
}

int vd_dag_from_svo(struct vd_dag *dag, const struct vd_svo *svo,
		    uint32_t kind, const struct vd_dag_opts *opts,
		    struct vd_dag_stats *stats)
{
	return vd__dag_from_svo(dag, svo, kind, opts, stats, NULL);
}

struct part_ref {
	const struct vd_dag *d;
	size_t idx;
	uint64_t start, end; /* voxel Morton range of the cell */
};

static int part_cmp(const void *a, const void *b)
{
	uint64_t x = ((const struct part_ref *)a)->start,
		 y = ((const struct part_ref *)b)->start;
	return x < y ? -1 : x > y;
}

/* 8^k as a voxel-range size; k <= 21 so it fits (8^21 = 2^63). */
uint64_t vd__dag_cell_span(int L, int level)
{
	return (uint64_t)1 << (3 * (L - level));
}

/* How a detail names part i: its file name when the caller gave names. */
#define PART(i, b) part_name(opts, i, namebuf[b])
static const char *part_name(const struct vd_dag_opts *o, size_t i,
			     char *buf)
{
	if (o && o->part_names) return o->part_names[i];
	snprintf(buf, 32, "part %zu", i);
	return buf;
}

/* The merge; with `consume` the engine frees the parts' levels as it reads
 * them, else it leaves the parts as they are (and only reads them). */
static int merge(struct vd_dag *out, struct vd_dag *const *parts, size_t n,
		 uint32_t kind, int chunk_level, const struct vd_dag_opts *opts,
		 struct vd_dag_stats *stats, int consume)
{
	memset(out, 0, sizeof *out);
	char namebuf[2][32];
	int err = check_kind_out(kind);
	if (err) return err;
	if (n == 0) return vd_fail(VD_ERR_EMPTY, "no chunks to merge");
	int L = parts[0]->levels, top = parts[0]->chunk_level;
	for (size_t i = 0; i < n; i++) {
		const struct vd_dag *d = parts[i];
		if (!vd__dag_is_dag_kind(d->kind))
			return vd_fail(VD_ERR_WRONG_KIND, "%s is a %s chunk",
				       PART(i, 0), vd_chunk_kind_name(d->kind));
		/* the 8 reflections are the 48's first 8 transforms, so
		 * an ssvdag part merges into an ssvdag48, not back */
		if (kind == VD_KIND_SSVDAG && d->kind == VD_KIND_SSVDAG48)
			return vd_fail(VD_ERR_WRONG_KIND, "%s is an ssvdag48 "
				       "chunk; an ssvdag merge needs dag or "
				       "ssvdag chunks (use --group 48)",
				       PART(i, 0));
		if (kind == VD_KIND_DAG && d->kind != VD_KIND_DAG)
			return vd_fail(VD_ERR_WRONG_KIND, "%s is an ssvdag "
				       "chunk; a dag merge needs dag chunks",
				       PART(i, 0));
		if (d->levels != L)
			return vd_fail(VD_ERR_MISMATCH, "%s has %d levels, %s "
				       "has %d", PART(i, 0), d->levels, PART(0, 1), L);
		if (d->chunk_level < top) top = d->chunk_level;
	}
	int A = chunk_level;
	if (A < 0) {
		if (top == 0)
			return vd_fail(VD_ERR_ARG, "the parts are already root "
				       "chunks (chunk level 0)");
		A = top - 1;
	}
	if (A > top)
		return vd_fail(VD_ERR_MISMATCH, "target level %d is below part "
			       "chunk level %d", A, top);
	struct part_ref *pr = malloc(n * sizeof *pr);
	struct vd_dag **nonempty = malloc(n * sizeof *nonempty);
	if (!pr || !nonempty) {
		free(pr);
		free(nonempty);
		return NOMEM();
	}
	uint64_t cellA = parts[0]->cell_morton >>
			 (3 * (parts[0]->chunk_level - A));
	uint64_t nodes = 0, voxels = 0;
	struct vd_dag_census cen = {0};
	size_t np = 0;
	for (size_t i = 0; i < n; i++) {
		const struct vd_dag *d = parts[i];
		uint64_t c = d->cell_morton >> (3 * (d->chunk_level - A));
		if (c != cellA) {
			err = vd_fail(VD_ERR_MISMATCH, "%s (cell %" PRIu64
				      " at level %d) is not inside cell %" PRIu64
				      " at level %d, like %s", PART(i, 0),
				      d->cell_morton, d->chunk_level, cellA, A,
				      PART(0, 1));
			goto out;
		}
		pr[i].d = d;
		pr[i].idx = i;
		pr[i].start = d->chunk_level == 0 ? 0 :
			d->cell_morton * vd__dag_cell_span(L, d->chunk_level);
		pr[i].end = pr[i].start + vd__dag_cell_span(L, d->chunk_level);
		for (int l = d->chunk_level; l < L; l++) nodes += d->lv[l].nodes;
		vd_dag_census_add(&cen, d);
		voxels += d->voxels;
	}
	qsort(pr, n, sizeof *pr, part_cmp);
	for (size_t i = 0; i + 1 < n; i++)
		if (pr[i].end > pr[i + 1].start) {
			err = vd_fail(VD_ERR_MISMATCH, "overlapping cells: %s "
				      "(cell %" PRIu64 " at level %d) and %s "
				      "(cell %" PRIu64 " at level %d)",
				      PART(pr[i].idx, 0), pr[i].d->cell_morton,
				      pr[i].d->chunk_level, PART(pr[i + 1].idx, 1),
				      pr[i + 1].d->cell_morton,
				      pr[i + 1].d->chunk_level);
			goto out;
		}
	for (size_t i = 0; i < n; i++)
		if (pr[i].d->lv[pr[i].d->chunk_level].nodes)
			nonempty[np++] = parts[pr[i].idx];
	if (stats) {
		memset(stats, 0, sizeof *stats);
		stats->input_voxels = voxels;
		stats->input_nodes = nodes;
	}
	uint64_t need = estimate_merge(&cen, kind, !consume);
	if ((err = vd__dag_check_budget(opts, need, stats))) goto out;
	out->kind = kind;
	out->levels = L;
	out->chunk_level = A;
	out->cell_morton = cellA;
	out->voxels = voxels;
	if (np) {
		double t0 = vd_seconds();
		struct engine e = {.sym = kind != VD_KIND_DAG,
				   .g48 = kind == VD_KIND_SSVDAG48, .L = L,
				   .A = A, .cellA = cellA, .parts = nonempty,
				   .np = np, .consume = consume, .out = out,
				   .st = stats,
				   .threads = opts ? opts->threads : 0,
				   .spare_bytes = spare(opts, need)};
		err = run_engine(&e);
		if (stats) stats->seconds_build = vd_seconds() - t0;
	}
out:
	free(pr);
	free(nonempty);
	return err;
}

int vd_dag_merge(struct vd_dag *out, const struct vd_dag *const *parts,
		 size_t n, uint32_t kind, int chunk_level,
		 const struct vd_dag_opts *opts, struct vd_dag_stats *stats)
{
	/* not written: without consume the engine only reads the parts */
	return merge(out, (struct vd_dag *const *)parts, n, kind, chunk_level,
		     opts, stats, 0);
}

int vd_dag_merge_consume(struct vd_dag *out, struct vd_dag *parts, size_t n,
			 uint32_t kind, int chunk_level,
			 const struct vd_dag_opts *opts,
			 struct vd_dag_stats *stats)
{
	struct vd_dag **pp = malloc((n ? n : 1) * sizeof *pp);
	int err;
	if (!pp) {
		err = NOMEM();
	} else {
		for (size_t i = 0; i < n; i++) pp[i] = &parts[i];
		err = merge(out, pp, n, kind, chunk_level, opts, stats, 1);
		free(pp);
	}
	for (size_t i = 0; i < n; i++) vd_dag_release(&parts[i]);
	return err;
}
