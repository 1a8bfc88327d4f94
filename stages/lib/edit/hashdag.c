/* hashdag.c - the HashDAG's tables: reservation, hashing, find-or-append,
 * loading a root DAG chunk, decoding the scene, saving it canonically,
 * history and garbage collection (paper sections 3.2, 3.3 and 3.5). */
#include "edit_internal.h"
#include "util_internal.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <stdio.h>
#include <time.h>

/* The leaves' bit mixer (a 64-bit finaliser in the style of splitmix). */
static uint64_t mix64(uint64_t v)
{
	v ^= v >> 31;
	v *= 0x7fb5d329728ea185ULL;
	v ^= v >> 27;
	v *= 0x81dadef4bc2dd44dULL;
	v ^= v >> 33;
	return v;
}

static void level_free(struct hd_level *lv)
{
	if (lv->words)
		munmap(lv->words, (size_t)4 << (lv->p + lv->m));
	free(lv->used);
	if (lv->used)
		for (int i = 0; i < HD_LOCKS; i++)
			pthread_mutex_destroy(&lv->lock[i]);
	memset(lv, 0, sizeof *lv);
}

static int level_init(struct hd_level *lv, int p, int m)
{
	memset(lv, 0, sizeof *lv);
	lv->p = p;
	lv->m = m;
	lv->full = HD_EMPTY;
	size_t bytes = (size_t)4 << (p + m);
	void *w = mmap(NULL, bytes, PROT_READ | PROT_WRITE,
		       MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
	if (w == MAP_FAILED)
		return vd_fail(VD_ERR_NOMEM, "cannot reserve %zu bytes: %s",
			       bytes, strerror(errno));
	/* huge pages where the level spans many of them: buckets are filled
	 * by hash, so a large level touches every small page of its range
	 * anyway, and one fault per 2 MiB instead of 512 is much of the cost
	 * of loading and of gc (a hint: ignored where unsupported) */
	if (bytes >= (size_t)8 << 20)
		(void)madvise(w, bytes, MADV_HUGEPAGE);
	lv->words = w;
	lv->used = calloc((size_t)1 << p, sizeof *lv->used);
	if (!lv->used) {
		munmap(w, bytes);
		lv->words = NULL;
		return vd_fail(VD_ERR_NOMEM, "bucket table");
	}
	for (int i = 0; i < HD_LOCKS; i++)
		pthread_mutex_init(&lv->lock[i], NULL);
	return VD_OK;
}

/* Buckets of level l: 2^min(P, 3l+4) with an explicit P; automatic (P 0)
 * from the words the level holds at load time, so that buckets start at
 * most half full, at least 2^min(3l+4, 10) and at most 2^(30-M). */
static int level_p(const struct vd_hashdag_opts *o, int l, uint64_t words)
{
	int p = 3 * l + 4;
	if (o->buckets_log2)
		return p < o->buckets_log2 ? p : o->buckets_log2;
	if (p > 10)
		p = 10;
	while (p < 30 - o->bucket_words_log2 &&
	       ((uint64_t)1 << (p + o->bucket_words_log2)) < 2 * words)
		p++;
	return p;
}

static int bucket_full(const struct hd_level *lv, int l, uint32_t b)
{
	return vd_fail(VD_ERR_BUDGET,
		       "bucket %u of level %d is full (%u words): run gc, or "
		       "reserve more with --buckets (level %d has 2^%d "
		       "buckets) or --bucket-words (now %d)",
		       b, l, 1u << lv->m, l, lv->p, lv->m);
}

/* Finds the node w[0..n) in its bucket or appends it; with `search` 0 the
 * caller knows the node is absent (gc moving distinct nodes) and it is
 * appended at once, so the bucket's linear scan is skipped. */
static int insert_words(struct vd_hashdag *h, struct hd_level *lv, int l,
			const uint32_t *w, uint32_t n, uint64_t hash,
			int search, uint32_t *out)
{
	uint32_t b = (uint32_t)(hash & (((uint64_t)1 << lv->p) - 1));
	uint32_t *base = lv->words + ((size_t)b << lv->m);
	pthread_mutex_t *lock = &lv->lock[b % HD_LOCKS];
	pthread_mutex_lock(lock);
	uint32_t used = lv->used[b], off = 0;
	while (search && off < used) {
		uint32_t sz = hd_node_words(h, l, base + off);
		if (sz == n && !memcmp(base + off, w, 4 * (size_t)n)) {
			pthread_mutex_unlock(lock);
			*out = b << lv->m | off;
			return VD_OK;
		}
		off += sz;
	}
	if (used + n > 1u << lv->m) {
		pthread_mutex_unlock(lock);
		return bucket_full(lv, l, b);
	}
	/* pages this append touches first (a page a neighbouring bucket
	 * already touched is counted again: an over-estimate only) */
	uint64_t w0 = ((uint64_t)b << lv->m) + used;
	uint64_t first = w0 >> 10, last = (w0 + n - 1) >> 10;
	if (used && (w0 - 1) >> 10 == first)
		first++;
	if (last >= first) {
		uint64_t more = 4096 * (last - first + 1);
		if (h->o.mem_budget_bytes &&
		    __atomic_add_fetch(&h->committed_bytes, more,
				       __ATOMIC_RELAXED) + h->fixed_bytes +
				    (h->col ? h->col->bytes : 0) >
			    h->o.mem_budget_bytes) {
			__atomic_sub_fetch(&h->committed_bytes, more,
					   __ATOMIC_RELAXED);
			pthread_mutex_unlock(lock);
			return hd_budget_check(h, more, "a page of level");
		}
		if (!h->o.mem_budget_bytes)
			__atomic_add_fetch(&h->committed_bytes, more,
					   __ATOMIC_RELAXED);
		__atomic_add_fetch(&lv->pages, last - first + 1,
				   __ATOMIC_RELAXED);
	}
	memcpy(base + used, w, 4 * (size_t)n);
	lv->used[b] = used + n;
	pthread_mutex_unlock(lock);
	__atomic_fetch_add(&lv->nodes, 1, __ATOMIC_RELAXED);
	*out = b << lv->m | used;
	return VD_OK;
}

int hd_insert_inner(struct vd_hashdag *h, int l, uint8_t mask,
		    const uint32_t *child, uint32_t *out)
{
	uint32_t w[9];
	uint32_t n = 1;
	w[0] = mask;
	for (int c = 0; c < 8; c++)
		if (mask >> c & 1)
			w[n++] = child[c];
	return insert_words(h, &h->lv[l], l, w, n,
			    vd_hash64(w, 4 * (size_t)n, (uint64_t)l), 1, out);
}

int hd_insert_leaf(struct vd_hashdag *h, uint64_t brick, uint32_t *out)
{
	uint32_t w[2] = {(uint32_t)brick, (uint32_t)(brick >> 32)};
	return insert_words(h, &h->lv[h->levels - 2], h->levels - 2, w, 2,
			    mix64(brick), 1, out);
}

int hd_make_full(struct vd_hashdag *h)
{
	int L = h->levels, err;
	uint32_t ch[8];
	if (h->lv[L - 2].full == HD_EMPTY &&
	    (err = hd_insert_leaf(h, ~0ull, &h->lv[L - 2].full)))
		return err;
	for (int l = L - 3; l >= 0; l--) {
		if (h->lv[l].full != HD_EMPTY)
			continue;
		for (int c = 0; c < 8; c++)
			ch[c] = h->lv[l + 1].full;
		if ((err = hd_insert_inner(h, l, 0xff, ch, &h->lv[l].full)))
			return err;
	}
	return VD_OK;
}

uint32_t hd_lookup(const struct vd_hashdag *h, uint32_t root, int l,
		   uint32_t x, uint32_t y, uint32_t z)
{
	uint32_t p = root;
	int L = h->levels;
	for (int k = 0; k < l && p != HD_EMPTY; k++) {
		int s = L - 1 - k; /* bit of the child's coordinate */
		int c = (int)((x >> s & 1) << 2 | (y >> s & 1) << 1 |
			      (z >> s & 1));
		p = hd_child(h, k, p, c);
	}
	return p;
}

uint64_t hd_used_bytes(const struct vd_hashdag *h)
{
	return h->fixed_bytes +
	       __atomic_load_n(&h->committed_bytes, __ATOMIC_RELAXED) +
	       (h->col ? h->col->bytes : 0);
}

int hd_budget_check(const struct vd_hashdag *h, uint64_t more,
		    const char *what)
{
	uint64_t used = hd_used_bytes(h), b = h->o.mem_budget_bytes;
	if (!b || used + more <= b)
		return VD_OK;
	return vd_fail(VD_ERR_BUDGET, "the edit needs %llu bytes (%s) beyond "
		       "the %llu in use, over the --mem-budget of %llu bytes: "
		       "raise it, or run gc",
		       (unsigned long long)more, what,
		       (unsigned long long)used, (unsigned long long)b);
}

/* The voxels below node `ptr` of level l (counted down to the bricks; a
 * full node by its size). */
uint64_t hd_voxels_of(const struct vd_hashdag *h, int l, uint32_t ptr)
{
	if (ptr == HD_EMPTY)
		return 0;
	if (ptr == h->lv[l].full)
		return 1ull << 3 * (h->levels - l);
	if (l == h->levels - 2)
		return (uint64_t)__builtin_popcountll(hd_brick(h, ptr));
	uint64_t n = 0;
	for (int c = 0; c < 8; c++)
		n += hd_voxels_of(h, l + 1, hd_child(h, l, ptr, c));
	return n;
}

int hd_push_root(struct vd_hashdag *h, uint32_t root,
		 struct hd_cellcol **tab)
{
	if (h->nroots && h->cur + 1 < h->nroots) {
		if (h->col)
			for (size_t i = h->cur + 1; i < h->nroots; i++)
				h->col->tab_free(h->col, h->col->tab[i]);
		h->nroots = h->cur + 1;
	}
	if (h->nroots == h->cap_roots) {
		size_t cap = h->cap_roots ? 2 * h->cap_roots : 64;
		uint32_t *r = realloc(h->roots, cap * sizeof *r);
		if (!r) {
			if (h->col)
				h->col->tab_free(h->col, tab);
			return vd_fail(VD_ERR_NOMEM, "history of roots");
		}
		h->roots = r;
		if (h->col) {
			struct hd_cellcol ***t = realloc(h->col->tab,
							 cap * sizeof *t);
			if (!t) {
				h->col->tab_free(h->col, tab);
				return vd_fail(VD_ERR_NOMEM, "history of colours");
			}
			h->col->tab = t;
		}
		h->cap_roots = cap;
	}
	if (h->col)
		h->col->tab[h->nroots] = tab;
	h->roots[h->nroots++] = root;
	h->cur = h->nroots - 1;
	return VD_OK;
}

/* Reserves the tables `lv`: bucket counts from `words` per level (NULL:
 * the same as h's tables). */
static int tables_init(struct vd_hashdag *h, struct hd_level *lv,
		       const uint64_t *words)
{
	uint64_t fixed = 0;
	for (int l = 0; l <= h->levels - 2; l++)
		fixed += (uint64_t)4 << (words ? level_p(&h->o, l, words[l])
					       : h->lv[l].p);
	int err = hd_budget_check(h, fixed, "bucket tables");
	if (err)
		return err;
	h->fixed_bytes += fixed;
	for (int l = 0; l <= h->levels - 2; l++) {
		int p = words ? level_p(&h->o, l, words[l]) : h->lv[l].p;
		err = level_init(&lv[l], p, h->o.bucket_words_log2);
		if (err)
			return err;
	}
	return VD_OK;
}

static int hd_new(struct vd_hashdag **out, int L, const struct vd_transform *t,
		  const struct vd_hashdag_opts *o, const uint64_t *words)
{
	struct vd_hashdag *h = calloc(1, sizeof *h);
	if (!h)
		return vd_fail(VD_ERR_NOMEM, "hashdag");
	if (o)
		h->o = *o;
	if (!h->o.bucket_words_log2)
		h->o.bucket_words_log2 = 10;
	if (!h->o.split_level)
		h->o.split_level = 3;
	if (h->o.split_level > L - 2)
		h->o.split_level = L - 2;
	h->levels = L;
	h->t = *t;
	h->fixed_bytes = sizeof *h;
	*out = h;
	if (h->o.buckets_log2 < 0 || h->o.bucket_words_log2 < 4 ||
	    h->o.bucket_words_log2 > 26 ||
	    h->o.buckets_log2 + h->o.bucket_words_log2 > 30)
		return vd_fail(VD_ERR_ARG, "buckets 2^%d of 2^%d words: need "
			       "4 <= words log2 and a sum <= 30",
			       h->o.buckets_log2, h->o.bucket_words_log2);
	return tables_init(h, h->lv, words);
}

void vd_hashdag_free(struct vd_hashdag *h)
{
	if (!h)
		return;
	for (int l = 0; l < VD_MAX_LEVELS; l++)
		if (h->lv[l].words || h->lv[l].used)
			level_free(&h->lv[l]);
	if (h->col) {
		for (size_t i = 0; i < h->nroots; i++)
			h->col->tab_free(h->col, h->col->tab[i]);
		h->col->free(h->col);
	}
	free(h->roots);
	free(h);
}

/* Loading: the nodes of a level of the input go in one after another
 * through a private open-addressing set of the pointers appended so far,
 * so a node equal to one already stored (a chunk that is valid but not
 * minimal) is found in O(1) and every other node is appended without the
 * bucket's linear search, which made loading quadratic in the bucket fill
 * (about 100 s at 2^14). The hashes, buckets and order of appends are
 * those of find-or-append, so the tables come out word for word the same
 * as inserting each node with hd_insert_*. */
struct load_set {
	uint32_t *slot; /* pointers, HD_EMPTY: free */
	uint64_t mask;
};

static int load_set_init(struct load_set *s, uint64_t n)
{
	uint64_t cap = 16;
	while (cap < 2 * n)
		cap *= 2;
	s->slot = malloc(cap * sizeof *s->slot);
	if (!s->slot)
		return vd_fail(VD_ERR_NOMEM, "load set of %llu nodes",
			       (unsigned long long)n);
	memset(s->slot, 0xff, cap * sizeof *s->slot);
	s->mask = cap - 1;
	return VD_OK;
}

static int load_insert(struct vd_hashdag *h, int l, struct load_set *s,
		       const uint32_t *w, uint32_t n, uint64_t hash,
		       uint32_t *out)
{
	struct hd_level *lv = &h->lv[l];
	uint64_t i = (hash >> 32 ^ hash >> 7) & s->mask;
	for (; s->slot[i] != HD_EMPTY; i = (i + 1) & s->mask) {
		const uint32_t *nd = hd_node(h, l, s->slot[i]);
		if (hd_node_words(h, l, nd) == n &&
		    !memcmp(nd, w, 4 * (size_t)n)) {
			*out = s->slot[i];
			return VD_OK;
		}
	}
	int err = insert_words(h, lv, l, w, n, hash, 0, out);
	if (!err)
		s->slot[i] = *out;
	return err;
}

int vd_hashdag_from_dag(struct vd_hashdag **out, const struct vd_dag *dag,
			const struct vd_transform *t,
			const struct vd_hashdag_opts *o)
{
	*out = NULL;
	if (dag->kind != VD_KIND_DAG)
		return vd_fail(VD_ERR_WRONG_KIND, "edit needs a DAG (not an "
			       "SSVDAG) chunk");
	if (dag->chunk_level != 0)
		return vd_fail(VD_ERR_UNSUPPORTED, "edit needs a root chunk "
			       "(chunk level 0), not level %d",
			       dag->chunk_level);
	int L = dag->levels;
	if (L < 3)
		return vd_fail(VD_ERR_UNSUPPORTED, "edit needs a grid of depth "
			       ">= 3, not %d", L);
	struct vd_hashdag *h = NULL;
	uint64_t words[VD_MAX_LEVELS] = {0};
	for (int l = 0; l < L - 2; l++)
		words[l] = dag->lv[l].nodes + dag->lv[l].refs;
	words[L - 2] = 2 * dag->lv[L - 2].nodes;
	int err = hd_new(&h, L, t, o, words);
	*out = h;
	if (err)
		goto fail;
	uint32_t root = HD_EMPTY;
	if (dag->lv[0].nodes) {
		uint64_t n = dag->lv[L - 2].nodes;
		uint32_t *map = malloc((n ? n : 1) * sizeof *map), *up = NULL;
		struct load_set set = {0};
		if (!map) {
			err = vd_fail(VD_ERR_NOMEM, "load remap");
			goto fail;
		}
		err = load_set_init(&set, n);
		for (uint64_t i = 0; i < n && !err; i++) {
			uint64_t b = dag->bricks[i];
			uint32_t w[2] = {(uint32_t)b, (uint32_t)(b >> 32)};
			err = load_insert(h, L - 2, &set, w, 2, mix64(b),
					  &map[i]);
		}
		free(set.slot);
		for (int l = L - 3; l >= 0 && !err; l--) {
			const struct vd_dag_level *dl = &dag->lv[l];
			up = malloc((dl->nodes ? dl->nodes : 1) * sizeof *up);
			if (!up) {
				err = vd_fail(VD_ERR_NOMEM, "load remap");
				break;
			}
			err = load_set_init(&set, dl->nodes);
			for (uint64_t i = 0; i < dl->nodes && !err; i++) {
				uint32_t w[9], k = 1;
				uint64_t r = dl->first[i];
				w[0] = dl->mask[i];
				for (int c = 0; c < 8; c++)
					if (dl->mask[i] >> c & 1)
						w[k++] = map[dl->child[r++]];
				err = load_insert(h, l, &set, w, k,
						  vd_hash64(w, 4 * (size_t)k,
							    (uint64_t)l),
						  &up[i]);
			}
			free(set.slot);
			set.slot = NULL;
			free(map);
			map = up;
		}
		if (!err)
			root = map[0];
		free(map);
		if (err)
			goto fail;
	}
	if ((err = hd_make_full(h)) || (err = hd_push_root(h, root, NULL)))
		goto fail;
	return VD_OK;
fail:
	vd_hashdag_free(h);
	*out = NULL;
	return err;
}

int vd_hashdag_load(struct vd_hashdag **out, const char *path,
		    const struct vd_hashdag_opts *o)
{
	struct vd_dag dag = {0};
	struct vd_chunk_header hd;
	*out = NULL;
	int err = vd_dag_load(&dag, &hd, path, VD_KIND_ANY);
	if (!err)
		err = vd_hashdag_from_dag(out, &dag, &hd.transform, o);
	vd_dag_release(&dag);
	return err;
}

int vd_hashdag_levels(const struct vd_hashdag *h)
{
	return h->levels;
}

const struct vd_transform *vd_hashdag_transform(const struct vd_hashdag *h)
{
	return &h->t;
}

int vd_hashdag_undo(struct vd_hashdag *h)
{
	if (h->cur == 0)
		return vd_fail(VD_ERR_RANGE, "nothing to undo");
	h->cur--;
	return VD_OK;
}

int vd_hashdag_redo(struct vd_hashdag *h)
{
	if (h->cur + 1 >= h->nroots)
		return vd_fail(VD_ERR_RANGE, "nothing to redo");
	h->cur++;
	return VD_OK;
}

/* ------------------------------------------------------------ decoding */

struct svo_buf {
	uint64_t *keys, *masks;
	size_t n, cap;
	int err;
};

static void decode(const struct vd_hashdag *h, int l, uint32_t p,
		   uint64_t key, struct svo_buf *b)
{
	if (p == HD_EMPTY || b->err)
		return;
	if (l == h->levels - 2) {
		if (b->n == b->cap) {
			size_t cap = b->cap ? 2 * b->cap : 4096;
			uint64_t *k = realloc(b->keys, cap * 8);
			if (k)
				b->keys = k;
			uint64_t *m = k ? realloc(b->masks, cap * 8) : NULL;
			if (!k || !m) {
				b->err = vd_fail(VD_ERR_NOMEM, "decode");
				return;
			}
			b->masks = m;
			b->cap = cap;
		}
		b->keys[b->n] = key;
		b->masks[b->n++] = hd_brick(h, p);
		return;
	}
	for (int c = 0; c < 8; c++)
		decode(h, l + 1, hd_child(h, l, p, c), key << 3 | (uint64_t)c,
		       b);
}

int vd_hashdag_to_svo(const struct vd_hashdag *h, struct vd_svo *svo)
{
	struct svo_buf b = {0};
	memset(svo, 0, sizeof *svo);
	decode(h, 0, h->roots[h->cur], 0, &b);
	if (b.err) {
		free(b.keys);
		free(b.masks);
		return b.err;
	}
	svo->levels = h->levels;
	svo->chunk_level = 0;
	svo->cell_morton = 0;
	svo->count = b.n;
	svo->keys = b.keys ? b.keys : malloc(8);
	svo->masks = b.masks ? b.masks : malloc(8);
	if (!svo->keys || !svo->masks)
		return vd_fail(VD_ERR_NOMEM, "decode");
	return VD_OK;
}

/* -------------------------------------------------------- measurements */

/* The live nodes of one level: a bit per word of the level's address
 * space, set at each live node's first word, and the count of live nodes
 * before each block of 64 words. A node's index among the live ones in
 * address order (its rank) then costs one popcount, so gc's remap table is
 * a plain array indexed by rank and the whole collection is linear in the
 * live nodes (plus a scan of 1 bit per reserved word). */
struct live {
	uint64_t *bits;
	uint32_t *before;
	uint64_t blocks, n;
};

static void live_free(struct live *v)
{
	free(v->bits);
	free(v->before);
	memset(v, 0, sizeof *v);
}

static inline uint64_t live_rank(const struct live *v, uint32_t p)
{
	return v->before[p >> 6] +
	       (uint64_t)__builtin_popcountll(v->bits[p >> 6] &
					      ((1ull << (p & 63)) - 1));
}

/* The nodes reachable from ptrs[0..n) (on level 0), per level. */
static int reachable(const struct vd_hashdag *h, const uint32_t *roots,
		     size_t n, struct live *live)
{
	int L = h->levels;
	for (int l = 0; l <= L - 2; l++) {
		const struct hd_level *lv = &h->lv[l];
		struct live *v = &live[l];
		v->blocks = (((uint64_t)1 << (lv->p + lv->m)) + 63) >> 6;
		v->bits = calloc(v->blocks, sizeof *v->bits);
		v->before = malloc(v->blocks * sizeof *v->before);
		if (!v->bits || !v->before) {
			for (int k = 0; k <= l; k++)
				live_free(&live[k]);
			return vd_fail(VD_ERR_NOMEM, "gc bitmaps");
		}
	}
	for (size_t i = 0; i < n; i++)
		if (roots[i] != HD_EMPTY)
			live[0].bits[roots[i] >> 6] |= 1ull << (roots[i] & 63);
	for (int l = 0; l <= L - 2; l++) {
		struct live *v = &live[l];
		uint64_t k = 0;
		for (uint64_t b = 0; b < v->blocks; b++) {
			v->before[b] = (uint32_t)k;
			k += (uint64_t)__builtin_popcountll(v->bits[b]);
		}
		v->n = k;
		if (l == L - 2)
			break;
		uint64_t *next = live[l + 1].bits;
		for (uint64_t b = 0; b < v->blocks; b++)
			for (uint64_t w = v->bits[b]; w; w &= w - 1) {
				uint32_t p = (uint32_t)(b << 6 |
							(uint64_t)__builtin_ctzll(w));
				const uint32_t *nd = hd_node(h, l, p);
				uint32_t sz = hd_node_words(h, l, nd);
				for (uint32_t j = 1; j < sz; j++)
					next[nd[j] >> 6] |= 1ull << (nd[j] & 63);
			}
	}
	return VD_OK;
}

/* -------------------------------------------------------------- saving */

/* Popcount without -mpopcnt (the builtin is a libgcc call there). */
static inline uint64_t popcount64(uint64_t v)
{
	v -= v >> 1 & 0x5555555555555555ULL;
	v = (v & 0x3333333333333333ULL) + (v >> 2 & 0x3333333333333333ULL);
	v = (v + (v >> 4)) & 0x0f0f0f0f0f0f0f0fULL;
	return v * 0x0101010101010101ULL >> 56;
}

static inline uint64_t live_rank_fast(const struct live *v, uint32_t p)
{
	return v->before[p >> 6] +
	       popcount64(v->bits[p >> 6] & ((1ull << (p & 63)) - 1));
}

/* The DAG of the current scene, written from its reachable nodes without
 * decoding: the same bytes as vd_dag_from_svo() of the decoded voxels.
 * That builder numbers the distinct nodes of a level in the order they
 * are first met in Morton order of their cells; the first cell of a node
 * on level l+1 lies under the first cell of some node on level l (an
 * earlier cell of that parent would hold it earlier), so walking the
 * nodes of level l in their own order and numbering children in slot
 * order when first seen gives that order, level by level. The HashDAG
 * is minimal (every insertion finds before it appends; load and gc keep
 * nodes distinct), so its reachable nodes are the minimal DAG's. Level
 * L-1 (2x2x2 masks) is numbered as the builder does: masks first met over
 * the distinct bricks in order, slots in order. */
/* What vd_hashdag_to_dag's steps share, all freed at its end: the
 * reachable nodes per level, each level's nodes in the order numbered
 * (the pool indices), and the buffers a step had when it failed. */
struct to_dag {
	struct live live[VD_MAX_LEVELS];
	uint32_t *order[VD_MAX_LEVELS], *id;
	uint64_t *cnt, *cnt_below;
};

/* Writes inner level l of dag (masks, first references, children) from
 * the nodes of x->order[l], numbering the children of level l+1 when
 * first met into x->order[l+1]; frees what level l no longer needs. */
static int inner_level_to_dag(const struct vd_hashdag *h, struct vd_dag *dag,
			      struct to_dag *x, int l)
{
	const struct live *vb = &x->live[l + 1];
	struct vd_dag_level *dl = &dag->lv[l];
	uint64_t n = x->live[l].n, refs = 0, next = 0;
	for (uint64_t i = 0; i < n; i++)
		refs += popcount64(hd_node(h, l, x->order[l][i])[0] & 0xff);
	dl->nodes = n;
	dl->refs = refs;
	dl->mask = malloc(n);
	dl->first = malloc((n + 1) * sizeof *dl->first);
	dl->child = malloc((refs ? refs : 1) * sizeof *dl->child);
	x->order[l + 1] = malloc((vb->n ? vb->n : 1) * sizeof *x->order[l + 1]);
	x->id = malloc((vb->n ? vb->n : 1) * sizeof *x->id);
	if (!dl->mask || !dl->first || !dl->child || !x->order[l + 1] ||
	    !x->id)
		return vd_fail(VD_ERR_NOMEM, "save of level %d", l);
	uint32_t *id = x->id;
	memset(id, 0xff, (vb->n ? vb->n : 1) * sizeof *id);
	uint64_t j = 0;
	for (uint64_t i = 0; i < n; i++) {
		const uint32_t *nd = hd_node(h, l, x->order[l][i]);
		uint32_t k = hd_node_words(h, l, nd);
		dl->mask[i] = (uint8_t)nd[0];
		dl->first[i] = j;
		for (uint32_t c = 1; c < k; c++) {
			uint64_t r = live_rank_fast(vb, nd[c]);
			if (id[r] == UINT32_MAX) {
				id[r] = (uint32_t)next;
				x->order[l + 1][next++] = nd[c];
			}
			dl->child[j++] = id[r];
		}
	}
	dl->first[n] = j;
	free(x->id);
	x->id = NULL;
	free(x->order[l]);
	x->order[l] = NULL;
	live_free(&x->live[l]);
	if (next != vb->n)
		return vd_fail(VD_ERR_INTERNAL, "hashdag.c: %llu of %llu "
			       "nodes of level %d reached",
			       (unsigned long long)next,
			       (unsigned long long)vb->n, l + 1);
	return VD_OK;
}

/* Writes the bricks of dag and the masks of level L-2 from the nodes of
 * x->order[L-2], with each brick's voxel count in x->cnt_below. */
static int bricks_to_dag(const struct vd_hashdag *h, struct vd_dag *dag,
			 struct to_dag *x)
{
	int L = h->levels;
	struct vd_dag_level *lb = &dag->lv[L - 2];
	uint64_t n = x->live[L - 2].n, refs = 0;
	dag->bricks = malloc(n * sizeof *dag->bricks);
	lb->mask = malloc(n);
	lb->first = malloc((n + 1) * sizeof *lb->first);
	x->cnt_below = malloc(n * sizeof *x->cnt_below);
	if (!dag->bricks || !lb->mask || !lb->first || !x->cnt_below)
		return vd_fail(VD_ERR_NOMEM, "save of the bricks");
	for (uint64_t i = 0; i < n; i++) {
		uint64_t v = hd_brick(h, x->order[L - 2][i]);
		uint8_t mk = 0;
		dag->bricks[i] = v;
		x->cnt_below[i] = popcount64(v);
		lb->first[i] = refs;
		for (unsigned s = 0; s < 8; s++)
			if (v >> 8 * s & 0xff) {
				mk |= (uint8_t)(1u << s);
				refs++;
			}
		lb->mask[i] = mk;
	}
	lb->first[n] = refs;
	lb->nodes = n;
	lb->refs = refs;
	return VD_OK;
}

/* Numbers the leaf masks of level L-1 (2x2x2) as first met over the
 * bricks in order, slots in order: level L-2's children and level L-1. */
static int leaves_to_dag(const struct vd_hashdag *h, struct vd_dag *dag)
{
	int L = h->levels;
	struct vd_dag_level *lb = &dag->lv[L - 2], *ll = &dag->lv[L - 1];
	uint64_t n = lb->nodes, refs = lb->refs;
	uint32_t leaf_id[256], nleaf = 0;
	uint8_t leaf_mask[256];
	memset(leaf_id, 0xff, sizeof leaf_id);
	lb->child = malloc((refs ? refs : 1) * sizeof *lb->child);
	if (!lb->child)
		return vd_fail(VD_ERR_NOMEM, "save of the bricks");
	uint64_t j = 0;
	for (uint64_t i = 0; i < n; i++)
		for (unsigned s = 0; s < 8; s++) {
			uint8_t v = (uint8_t)(dag->bricks[i] >> 8 * s);
			if (!v)
				continue;
			if (leaf_id[v] == UINT32_MAX) {
				leaf_id[v] = nleaf;
				leaf_mask[nleaf++] = v;
			}
			lb->child[j++] = leaf_id[v];
		}
	ll->nodes = nleaf;
	ll->mask = malloc(nleaf ? nleaf : 1);
	if (!ll->mask)
		return vd_fail(VD_ERR_NOMEM, "save of the leaves");
	memcpy(ll->mask, leaf_mask, nleaf);
	return VD_OK;
}

/* Sets dag->voxels: counts per node, bottom-up from the bricks' in
 * x->cnt_below, which ends holding the counts of level 0. */
static int count_voxels(const struct vd_hashdag *h, struct vd_dag *dag,
			struct to_dag *x)
{
	int L = h->levels;
	for (int l = L - 3; l >= 0; l--) {
		const struct vd_dag_level *dl = &dag->lv[l];
		x->cnt = malloc((dl->nodes ? dl->nodes : 1) * sizeof *x->cnt);
		if (!x->cnt)
			return vd_fail(VD_ERR_NOMEM, "save counts");
		for (uint64_t i = 0; i < dl->nodes; i++) {
			uint64_t s = 0;
			for (uint64_t r = dl->first[i];
			     r < dl->first[i + 1]; r++)
				s += x->cnt_below[dl->child[r]];
			x->cnt[i] = s;
		}
		free(x->cnt_below);
		x->cnt_below = x->cnt;
		x->cnt = NULL;
	}
	dag->voxels = x->cnt_below[0];
	return VD_OK;
}

int vd_hashdag_to_dag(const struct vd_hashdag *h, struct vd_dag *dag)
{
	memset(dag, 0, sizeof *dag);
	int L = h->levels, err = VD_OK;
	dag->kind = VD_KIND_DAG;
	dag->levels = L;
	uint32_t root = h->roots[h->cur];
	if (root == HD_EMPTY)
		return VD_OK;
	struct to_dag x;
	memset(&x, 0, sizeof x);
	if ((err = reachable(h, &root, 1, x.live)))
		return err;
	x.order[0] = malloc(sizeof *x.order[0]);
	if (!x.order[0]) {
		err = vd_fail(VD_ERR_NOMEM, "save order");
		goto done;
	}
	x.order[0][0] = root;
	/* inner levels: masks, references; the order of the level below */
	for (int l = 0; l < L - 2; l++)
		if ((err = inner_level_to_dag(h, dag, &x, l)))
			goto done;
	/* bricks, and from them the leaf masks of level L-1 */
	if (!(err = bricks_to_dag(h, dag, &x)) &&
	    !(err = leaves_to_dag(h, dag)))
		err = count_voxels(h, dag, &x);
done:
	for (int l = 0; l < VD_MAX_LEVELS; l++) {
		free(x.order[l]);
		live_free(&x.live[l]);
	}
	free(x.id);
	free(x.cnt);
	free(x.cnt_below);
	if (err)
		vd_dag_release(dag);
	return err;
}

int vd_hashdag_save(const struct vd_hashdag *h, const char *path,
		    const char *provenance)
{
	struct vd_dag dag;
	int err = vd_hashdag_to_dag(h, &dag);
	if (!err)
		err = vd_dag_save(&dag, &h->t, path, provenance);
	vd_dag_release(&dag);
	return err;
}

void vd_hashdag_counts(const struct vd_hashdag *h, uint64_t *stored,
		       uint64_t *reach)
{
	struct live live[VD_MAX_LEVELS];
	memset(live, 0, sizeof live);
	int ok = reach && !reachable(h, &h->roots[h->cur], 1, live);
	for (int l = 0; l <= h->levels - 2; l++) {
		if (stored)
			stored[l] = h->lv[l].nodes;
		if (reach)
			reach[l] = ok ? live[l].n : 0;
		live_free(&live[l]);
	}
}

uint64_t vd_hashdag_memory_bytes(const struct vd_hashdag *h)
{
	uint64_t bytes = sizeof *h + h->cap_roots * 4;
	for (int l = 0; l <= h->levels - 2; l++) {
		const struct hd_level *lv = &h->lv[l];
		uint64_t last = UINT64_MAX, pages = 0;
		for (uint64_t b = 0; b < (uint64_t)1 << lv->p; b++) {
			if (!lv->used[b])
				continue;
			uint64_t w0 = b << lv->m, w1 = w0 + lv->used[b] - 1;
			uint64_t p0 = w0 >> 10, p1 = w1 >> 10; /* 4 KiB pages */
			if (p0 == last)
				p0++;
			if (p1 >= p0)
				pages += p1 - p0 + 1;
			last = p1;
		}
		bytes += pages * 4096 + ((uint64_t)4 << lv->p);
	}
	return bytes;
}

uint32_t vd_hashdag_max_bucket(const struct vd_hashdag *h, int l)
{
	uint32_t mx = 0;
	for (uint64_t b = 0; b < (uint64_t)1 << h->lv[l].p; b++)
		if (h->lv[l].used[b] > mx)
			mx = h->lv[l].used[b];
	return mx;
}

/* ------------------------------------------------------------------ gc */

/* Bitmap blocks (of 64 words) per gc job: small enough that the tests'
 * scenes make several jobs per level. */
#define GC_BLOCKS 256

struct gc_err {
	int err;
	char detail[240];
};

struct gc_move {
	struct vd_hashdag *h;
	struct hd_level *fresh;
	const struct live *live;
	uint32_t **to;
	int l;
	struct gc_err *err;
};

/* Moves the live nodes of bitmap blocks [i GC_BLOCKS, (i+1) GC_BLOCKS) of
 * level m->l into the fresh tables. */
static void gc_move_range(void *ctx, size_t i, int worker)
{
	(void)worker;
	struct gc_move *m = ctx;
	struct vd_hashdag *h = m->h;
	int l = m->l, L = h->levels;
	const struct live *v = &m->live[l], *below = &m->live[l + 1];
	uint64_t b0 = (uint64_t)i * GC_BLOCKS, b1 = b0 + GC_BLOCKS;
	if (b1 > v->blocks)
		b1 = v->blocks;
	if (b0 >= b1)
		return;
	uint32_t *to = m->to[l], *to_below = m->to[l + 1];
	uint64_t r = v->before[b0];
	int err = VD_OK;
	for (uint64_t b = b0; b < b1 && !err; b++)
		for (uint64_t bw = v->bits[b]; bw && !err; bw &= bw - 1) {
			uint32_t p = (uint32_t)(b << 6 |
						(uint64_t)__builtin_ctzll(bw));
			const uint32_t *nd = hd_node(h, l, p);
			uint32_t w[9], n = 1;
			uint64_t hash;
			if (l == L - 2) {
				w[0] = nd[0];
				w[1] = nd[1];
				n = 2;
				hash = mix64((uint64_t)nd[0] |
					     (uint64_t)nd[1] << 32);
			} else {
				uint32_t k = hd_node_words(h, l, nd);
				w[0] = nd[0];
				for (; n < k; n++)
					w[n] = to_below[live_rank(below, nd[n])];
				hash = vd_hash64(w, 4 * (size_t)n, (uint64_t)l);
			}
			err = insert_words(h, &m->fresh[l], l, w, n, hash, 0,
					   &to[r++]);
		}
	if (err) {
		m->err[i].err = err;
		snprintf(m->err[i].detail, sizeof m->err[i].detail, "%s",
			 vd_error_detail());
	}
}

int vd_hashdag_gc(struct vd_hashdag *h, int keep_history,
		  struct vd_edit_stats *st)
{
	double t0 = vd_seconds(), c0 = vd_cpu_seconds();
	int L = h->levels, err;
	const uint32_t *keep = keep_history ? h->roots : &h->roots[h->cur];
	size_t nkeep = keep_history ? h->nroots : 1;
	uint32_t *to[VD_MAX_LEVELS] = {0};
	struct live live[VD_MAX_LEVELS];
	memset(live, 0, sizeof live);
	struct hd_level *fresh = calloc(VD_MAX_LEVELS, sizeof *fresh);
	if (!fresh)
		return vd_fail(VD_ERR_NOMEM, "gc tables");
	if ((err = reachable(h, keep, nkeep, live)))
		goto done;
	if ((err = tables_init(h, fresh, NULL)))
		goto done;
	/* Bottom-up: a level's nodes, in address order (so the i-th is the
	 * one of rank i), are rewritten through the remap of the level below
	 * and appended to the fresh tables without a search: the nodes of a
	 * level are distinct (every insertion finds before it appends) and
	 * the remap is one-to-one, so the rewritten nodes are distinct too.
	 * Ranges of the bitmap are jobs on the thread pool (bucket locks:
	 * only the order inside a bucket depends on the threads). */
	struct gc_move mv = {.h = h, .fresh = fresh, .live = live, .to = to};
	for (int l = L - 2; l >= 0 && !err; l--) {
		const struct live *v = &live[l];
		to[l] = malloc((v->n ? v->n : 1) * sizeof *to[l]);
		if (!to[l]) {
			err = vd_fail(VD_ERR_NOMEM, "gc remap");
			break;
		}
		mv.l = l;
		size_t jobs = (size_t)((v->blocks + GC_BLOCKS - 1) / GC_BLOCKS);
		mv.err = calloc(jobs, sizeof *mv.err);
		if (!mv.err) {
			err = vd_fail(VD_ERR_NOMEM, "gc jobs");
			break;
		}
		if (vd_parallel_for(jobs, h->o.threads, gc_move_range, &mv))
			err = vd_fail(VD_ERR_INTERNAL, "thread pool");
		for (size_t i = 0; i < jobs && !err; i++)
			if (mv.err[i].err)
				err = vd_fail(mv.err[i].err, "%s", mv.err[i].detail);
		free(mv.err);
		if (l + 1 <= L - 2) { /* the level below is done with */
			live_free(&live[l + 1]);
			free(to[l + 1]);
			to[l + 1] = NULL;
		}
	}
	if (err)
		goto done;
	if (!keep_history) { /* only the current root was kept */
		if (h->col) {
			for (size_t i = 0; i < h->nroots; i++)
				if (i != h->cur)
					h->col->tab_free(h->col, h->col->tab[i]);
			h->col->tab[0] = h->col->tab[h->cur];
		}
		h->roots[0] = h->roots[h->cur];
		h->nroots = 1;
		h->cur = 0;
	}
	for (size_t i = 0; i < h->nroots; i++) {
		uint32_t r = h->roots[i];
		if (r != HD_EMPTY)
			r = to[0][live_rank(&live[0], r)];
		h->roots[i] = r;
	}
	/* Swap the tables in (the full nodes are made again on the next
	 * edit, so an unreachable one does not survive the collection). */
	for (int l = 0; l <= L - 2; l++) {
		struct hd_level *a = &h->lv[l], *b = &fresh[l];
		uint32_t *w = a->words, *u = a->used;
		int p = a->p, m = a->m;
		uint64_t pages = a->pages;
		a->words = b->words;
		a->used = b->used;
		a->nodes = b->nodes;
		a->pages = b->pages;
		a->p = b->p;
		a->m = b->m;
		a->full = HD_EMPTY;
		b->words = w;
		b->used = u;
		b->pages = pages;
		b->p = p;
		b->m = m;
	}
	if (st) {
		memset(st, 0, sizeof *st);
		for (int l = 0; l <= L - 2; l++)
			st->nodes_added[l] = h->lv[l].nodes; /* kept */
	}
done:
	/* the tables freed here leave the budget (the old ones after a
	 * collection, the fresh ones after a failure) */
	for (int l = 0; l <= L - 2; l++) {
		if (fresh[l].words || fresh[l].used) {
			h->committed_bytes -= 4096 * fresh[l].pages;
			h->fixed_bytes -= (uint64_t)4 << fresh[l].p;
		}
	}
	for (int l = 0; l <= L - 2; l++) {
		if (fresh[l].words || fresh[l].used)
			level_free(&fresh[l]);
		live_free(&live[l]);
		free(to[l]);
	}
	free(fresh);
	if (st) {
		st->seconds = vd_seconds() - t0;
		st->cpu_seconds = vd_cpu_seconds() - c0;
		st->hash_bytes = vd_hashdag_memory_bytes(h);
	}
	return err;
}
