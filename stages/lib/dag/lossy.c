/* lossy.c - lossy SVDAGs (van der Laan, Scandolo and Eisemann 2020):
 * rarely used subtrees that differ in a few voxels are clustered with
 * Markov clustering and replaced by one representative per cluster, level
 * after level from height 2 to the root, with the lossless reduction of
 * the levels above after each level. Also the voxel difference of two DAGs.
 *
 * Heights: a node on level l has height h = L - l; level L-1 holds the
 * 2x2x2 masks (height 1), level L-2 the nodes over them (height 2, one
 * 64-bit brick each). */
#include "voxdag.h"
#include "util_internal.h"
#include "budget.h"
#include "io/publish.h"

#include <inttypes.h>
#include <malloc.h>
#include <math.h>
#include <stdlib.h>
#include <stdio.h>
#include <string.h>
#include <time.h>
#include <unistd.h>
#include <errno.h>
#include <fcntl.h>
#include <sys/mman.h>

#define NOMEM() vd_fail(VD_ERR_NOMEM, "out of memory in %s", __func__)
#define NONE UINT32_MAX

/* The brick (height-2 encoding) of node i on level L-2: byte c = the leaf
 * mask of child slot c. */
static uint64_t node_brick(const struct vd_dag *d, uint64_t i)
{
	int L = d->levels;
	const struct vd_dag_level *lv = &d->lv[L - 2];
	uint64_t v = 0, j = lv->first[i];
	for (unsigned s = 0; s < 8; s++)
		if (lv->mask[i] >> s & 1)
			v |= (uint64_t)d->lv[L - 1].mask[lv->child[j++]] << (8 * s);
	return v;
}

/* --------------------------------------------- effective reference counts */

int vd_lossy_effective_refs(const struct vd_dag *d, int to_level,
			    uint64_t **eff)
{
	int A = d->chunk_level;
	for (int l = 0; l < VD_MAX_LEVELS; l++) eff[l] = NULL;
	for (int l = A; l <= to_level; l++) {
		eff[l] = calloc(d->lv[l].nodes ? d->lv[l].nodes : 1, 8);
		if (!eff[l]) {
			for (int k = A; k < l; k++) free(eff[k]);
			return NOMEM();
		}
	}
	if (!d->lv[A].nodes) return 0;
	eff[A][0] = 1;
	for (int l = A; l < to_level; l++) {
		const struct vd_dag_level *lv = &d->lv[l];
		for (uint64_t i = 0; i < lv->nodes; i++)
			for (uint64_t j = lv->first[i]; j < lv->first[i + 1]; j++) {
				uint64_t *e = &eff[l + 1][lv->child[j]];
				*e = *e > UINT64_MAX - eff[l][i] ? UINT64_MAX
								   : *e + eff[l][i];
			}
	}
	return 0;
}

/* ------------------------------------------------------ similarity graph */

/* The memory of a similarity graph, per edge: three copies at the worst
 * step (the search's slices, up to twice their edges as they double, and
 * their concatenation; the edges and the radix sort's copy; the edges,
 * the clustering's adjacency, both directions at 12 bytes, and a
 * component's copy of it). */
#define EDGE_BYTES (3 * sizeof(struct vd_lossy_edge))

/* ... and per graph node: the renumbering, clusters, representatives and
 * similarity sums of cluster_edges (20 bytes), the CSR offsets, component
 * arrays and counting sorts of graph_build (44), a component's offsets
 * and clusters (12). */
#define GNODE_BYTES 76

/* ... and per node of the level (graph node or not): the renumbering and
 * the map to representatives (8 bytes), the voxel counts for choosing
 * them (8), and for a spilled graph the
 * union-find roots, per-component counts of edges and nodes and a bit
 * per node (16 1/8). */
#define LNODE_BYTES 33

/* The memory of clustering a graph of ne edges and gn nodes on a level of
 * nl nodes in memory, the Markov clustering's own aside. */
static uint64_t graph_need(uint64_t ne, uint64_t gn, uint64_t nl)
{
	return ne * EDGE_BYTES + gn * GNODE_BYTES + nl * LNODE_BYTES;
}

/* The Markov clustering's own memory (matrices, per-worker scratch, a
 * component's copy of its adjacency) is counted as it is taken, against
 * what the graph leaves of the budget: `limit` 0 is none. A component
 * that would pass it stops with VD_ERR_BUDGET; components clustered in
 * parallel are then clustered again one at a time (the result of each is
 * the same), and only a component alone over the limit fails the run,
 * naming `need`, the most it asked for. */
struct mcl_ledger {
	uint64_t limit;
	uint64_t held; /* atomic */
	uint64_t need; /* atomic max */
};

/* Takes `bytes` (plus `transient` bytes held only while they are taken,
 * as by a realloc) from the ledger; VD_ERR_BUDGET when over its limit. */
static int led_take(struct mcl_ledger *lg, uint64_t *mine, uint64_t bytes,
		    uint64_t transient)
{
	if (!lg || !lg->limit) return 0;
	uint64_t h = __atomic_add_fetch(&lg->held, bytes, __ATOMIC_RELAXED);
	if (h + transient > lg->limit) {
		__atomic_sub_fetch(&lg->held, bytes, __ATOMIC_RELAXED);
		uint64_t want = __atomic_load_n(mine, __ATOMIC_RELAXED) + bytes +
				transient, old = __atomic_load_n(&lg->need,
								 __ATOMIC_RELAXED);
		while (want > old &&
		       !__atomic_compare_exchange_n(&lg->need, &old, want, 0,
						    __ATOMIC_RELAXED, __ATOMIC_RELAXED))
			;
		return VD_ERR_BUDGET;
	}
	__atomic_add_fetch(mine, bytes, __ATOMIC_RELAXED);
	return 0;
}

static void led_give(struct mcl_ledger *lg, uint64_t *mine)
{
	if (!lg || !lg->limit) return;
	__atomic_sub_fetch(&lg->held, *mine, __ATOMIC_RELAXED);
	*mine = 0;
}

/* The budget of a pair search shared by its slices: once the slices'
 * arrays would pass `limit` bytes, the graph goes to the spill file `fd`
 * instead: each slice keeps the array it has (or takes a small one) and
 * writes it out whenever it is full, at offsets reserved atomically. The
 * file's order of edges depends on the threads, but its set does not, and
 * the edges are sorted before they are used. Capacities only grow, so
 * whether the graph spills does not depend on the threads either. */
struct edge_budget {
	uint64_t limit; /* 0: none */
	uint64_t held;  /* bytes of the slices' arrays (atomic) */
	int over;       /* atomic */
	int fd;         /* the spill file, -1: none (yet) */
	uint64_t end;   /* bytes written or reserved in it (atomic) */
};

/* edges a slice takes once over the budget, when it holds none yet */
#define SPILL_EDGES 4096

struct edges {
	struct vd_lossy_edge *e;
	size_t n, cap;
	size_t spilled; /* edges already written to the spill file */
	struct edge_budget *b;
};

static int spill_fail(const char *what)
{
	return vd_fail(VD_ERR_IO, "cannot %s the similarity graph's spill file "
		       "in '%s': %s", what, getenv("TMPDIR") ? getenv("TMPDIR")
		       : "/tmp", strerror(errno));
}

static int spill_read(int fd, void *p, size_t n, uint64_t off)
{
	return vd_pread_full(fd, p, n, off) ? spill_fail("read") : 0;
}

/* The spill file: anonymous, in $TMPDIR (or /tmp). */
static int spill_open(void)
{
	const char *dir = getenv("TMPDIR");
	if (!dir || !*dir) dir = "/tmp";
	return vd_tmpfile(dir, "lossy-graph");
}

static int edge_flush(struct edges *g)
{
	if (!g->n) return 0;
	if (g->b->fd < 0) {
		errno = EBADF;
		return spill_fail("create");
	}
	size_t bytes = g->n * sizeof *g->e;
	uint64_t at = __atomic_fetch_add(&g->b->end, bytes, __ATOMIC_RELAXED);
	int err = vd_pwrite_full(g->b->fd, g->e, bytes, at) ? spill_fail("write") : 0;
	if (err) return err;
	g->spilled += g->n;
	g->n = 0;
	return 0;
}

static int edge_add(struct edges *g, uint32_t u, uint32_t v, uint32_t diff,
		    double s)
{
	if (g->n == g->cap) {
		int over = g->b && __atomic_load_n(&g->b->over, __ATOMIC_RELAXED);
		size_t c = g->cap ? g->cap * 2 : 1024;
		if (!over && g->b && g->b->limit &&
		    __atomic_add_fetch(&g->b->held, (c - g->cap) * sizeof *g->e,
				       __ATOMIC_RELAXED) > g->b->limit) {
			__atomic_store_n(&g->b->over, 1, __ATOMIC_RELAXED);
			over = 1;
		}
		if (over && g->cap) {
			int err = edge_flush(g);
			if (err) return err;
		} else {
			if (over) c = SPILL_EDGES;
			void *p = realloc(g->e, c * sizeof *g->e);
			if (!p) return NOMEM();
			g->e = p;
			g->cap = c;
		}
	}
	g->e[g->n++] = (struct vd_lossy_edge){u, v, diff, s};
	return 0;
}

/* Sorts a[0..n-1] (the rows of one column: mostly a few dozen) without
 * qsort's indirect calls, which took a tenth of the clustering. */
static void u32_sort(uint32_t *a, size_t n)
{
	while (n > 24) {
		uint32_t x = a[0], y = a[n / 2], z = a[n - 1];
		uint32_t p = x < y ? (y < z ? y : (x < z ? z : x))
				   : (x < z ? x : (y < z ? z : y));
		size_t i = 0, j = n - 1;
		for (;;) {
			while (a[i] < p) i++;
			while (a[j] > p) j--;
			if (i >= j) break;
			uint32_t t = a[i];
			a[i++] = a[j];
			a[j--] = t;
		}
		/* a[0..j] <= p <= a[j+1..n-1]: recurse into the smaller part */
		size_t ln = j + 1, rn = n - ln;
		if (ln < rn) {
			u32_sort(a, ln);
			a += ln;
			n = rn;
		} else {
			u32_sort(a + ln, rn);
			n = ln;
		}
	}
	for (size_t i = 1; i < n; i++) {
		uint32_t v = a[i];
		size_t k = i;
		for (; k > 0 && a[k - 1] > v; k--) a[k] = a[k - 1];
		a[k] = v;
	}
}

/* Population count without the libgcc call that __builtin_popcountll
 * becomes on a plain x86-64 build. */
static inline unsigned pop64(uint64_t x)
{
	x = x - ((x >> 1) & 0x5555555555555555ULL);
	x = (x & 0x3333333333333333ULL) + ((x >> 2) & 0x3333333333333333ULL);
	x = (x + (x >> 4)) & 0x0f0f0f0f0f0f0f0fULL;
	return (unsigned)((x * 0x0101010101010101ULL) >> 56);
}

/* Sorts the edges by (u, v), u and v below n: LSD radix sort on the key
 * u * 2^b + v in 11-bit digits (qsort of the 1.5 million edges of the
 * dragon at 2^12 took longer than finding them). Already sorted input
 * (height 2) is left as it is. */
static int edges_sort(struct vd_lossy_edge *e, size_t ne, uint64_t n)
{
	size_t i = 1;
	while (i < ne && (e[i - 1].u < e[i].u ||
			  (e[i - 1].u == e[i].u && e[i - 1].v < e[i].v)))
		i++;
	if (ne < 2 || i == ne) return 0;
	int b = 1;
	while (b < 32 && (1ull << b) < n) b++;
	struct vd_lossy_edge *t = malloc(ne * sizeof *t);
	if (!t) return NOMEM();
	struct vd_lossy_edge *src = e, *dst = t;
	for (int shift = 0; shift < 2 * b; shift += 11) {
		size_t cnt[2048] = {0};
		for (i = 0; i < ne; i++)
			cnt[((uint64_t)src[i].u << b | src[i].v) >> shift & 2047]++;
		size_t at = 0;
		for (int k = 0; k < 2048; k++) {
			size_t c = cnt[k];
			cnt[k] = at;
			at += c;
		}
		for (i = 0; i < ne; i++)
			dst[cnt[((uint64_t)src[i].u << b | src[i].v) >> shift & 2047]++] = src[i];
		struct vd_lossy_edge *x = src;
		src = dst;
		dst = x;
	}
	if (src != e) memcpy(e, src, ne * sizeof *e);
	free(t);
	return 0;
}

struct enc {
	uint64_t key;  /* encoding, or topology hash */
	uint64_t pop;  /* voxels (taller levels) */
	uint32_t node;
};

static int enc_cmp(const void *a, const void *b)
{
	const struct enc *x = a, *y = b;
	if (x->key != y->key) return x->key < y->key ? -1 : 1;
	if (x->pop != y->pop) return x->pop < y->pop ? -1 : 1;
	return x->node < y->node ? -1 : x->node > y->node;
}

/* Voxel difference of nodes a and b on level l (>= L-2) of equal topology
 * down to level L-2, stopping once over `m`: at level L-2 the popcount of
 * the XORed bricks (the 64 voxels under the node). Returns -1 if the
 * topologies differ (a topology hash collision). */
static int64_t pair_diff(const struct vd_dag *d, const uint64_t *brick, int l,
			 uint32_t a, uint32_t b, int64_t acc, int64_t m)
{
	int L = d->levels;
	const struct vd_dag_level *lv = &d->lv[l];
	if (lv->mask[a] != lv->mask[b]) return -1;
	if (l == L - 2) return acc + pop64(brick[a] ^ brick[b]);
	uint64_t ja = lv->first[a], jb = lv->first[b], k = lv->first[a + 1] - ja;
	for (uint64_t t = 0; t < k; t++) {
		uint32_t ca = lv->child[ja + t], cb = lv->child[jb + t];
		if (ca != cb) {
			acc = pair_diff(d, brick, l + 1, ca, cb, acc, m);
			if (acc < 0) return -1;
			if (acc > m) return acc;
		}
	}
	return acc;
}

/* The pair search over the candidates c[0..nc-1], in fixed slices of the
 * first member (independent of the thread count; the edges are sorted
 * afterwards). Height 2 (keys are bricks, m = 1; c in node order): the
 * 64 one-bit flips of each encoding looked up in a hash table of all
 * candidates' encodings (the encodings are distinct: the DAG is reduced),
 * which gives the edges already sorted. Taller (c sorted by topology hash
 * and voxel count): within a group of equal topology hash only the window
 * of counts within m (|pop a - pop b| <= d) is compared. */
#define PAIR_SLICES 64

struct hslot {
	uint64_t key;
	uint32_t node; /* NONE: empty */
};

struct pair_job {
	const struct vd_dag *d;
	int l, h2;
	const struct enc *c;
	size_t nc;
	int64_t m;
	const struct hslot *slot; /* height 2: hash table of the candidates */
	uint64_t mask;          /* its size - 1 */
	const uint64_t *brick;  /* taller: the bricks of level L-2 */
	struct edges part[PAIR_SLICES];
	int err[PAIR_SLICES];
};

static void pair_slice(void *ctx, size_t k, int worker)
{
	(void)worker;
	struct pair_job *J = ctx;
	const struct enc *c = J->c;
	size_t nc = J->nc, a0 = nc * k / PAIR_SLICES, a1 = nc * (k + 1) / PAIR_SLICES;
	struct edges *g = &J->part[k];
	int64_t m = J->m;
	int err = 0;
	for (size_t a = a0; a < a1 && !err; a++) {
		if (J->h2) {
			/* the 64 slots fetched together: the lookups are cache
			 * misses, two thirds of the search when taken one by one */
			uint32_t nb[64], nn = 0;
			uint64_t at[64];
			for (unsigned b = 0; b < 64; b++) {
				at[b] = vd_mix64(c[a].key ^ (1ull << b)) & J->mask;
				__builtin_prefetch(&J->slot[at[b]]);
			}
			for (unsigned b = 0; b < 64; b++) {
				uint64_t x = c[a].key ^ (1ull << b);
				for (uint64_t s = at[b];; s = (s + 1) & J->mask) {
					const struct hslot *o = &J->slot[s];
					if (o->node == NONE) break;
					if (o->key == x) {
						if (o->node > c[a].node) nb[nn++] = o->node;
						break;
					}
				}
			}
			u32_sort(nb, nn);
			for (uint32_t t = 0; t < nn && !err; t++)
				err = edge_add(g, c[a].node, nb[t], 1, 0.5);
			continue;
		}
		for (size_t b = a + 1; b < nc && !err; b++) {
			if (c[b].key != c[a].key || c[b].pop - c[a].pop > (uint64_t)m)
				break;
			int64_t dd = pair_diff(J->d, J->brick, J->l, c[a].node,
					       c[b].node, 0, m);
			if (dd < 0 || dd > m) continue;
			uint32_t u = c[a].node, v = c[b].node;
			if (u > v) {
				uint32_t t = u;
				u = v;
				v = t;
			}
			err = edge_add(g, u, v, (uint32_t)dd,
				       1.0 - (double)dd / (double)(m + 1));
		}
	}
	J->err[k] = err;
}

/* The spill of a similarity graph: `n` edges, in no particular order, in
 * the anonymous file `fd` (-1: the graph is in memory); `base` is what
 * the process held before the search. */
struct spill {
	int fd;
	uint64_t n, base, avail; /* avail: bytes for the graph */
};

static int search_pairs(const struct vd_dag *d, int l, const struct enc *c,
			size_t nc, int64_t m, const uint64_t *brick,
			int threads, uint64_t budget, uint64_t graph_budget,
			struct edges *g, struct spill *sp)
{
	struct pair_job *J = calloc(1, sizeof *J);
	if (!J) return NOMEM();
	/* what the process holds now, and what is left of the budget */
	struct edge_budget eb = {0, 0, 0, -1, 0};
	/* freed memory that malloc keeps counts in the RSS: the last level's
	 * graph would otherwise take the budget of this one */
	if (budget) malloc_trim(0);
	uint64_t base = budget ? vd_current_rss_bytes() : 0;
	uint64_t avail = graph_budget ? graph_budget
			 : budget ? (base < budget ? budget - base : 1) : 0;
	if (avail) {
		/* the slices' arrays and then their concatenation */
		eb.limit = avail / VD_BUDGET_LOSSY_SLICES_DIV;
		/* opened before the threads start, used only if needed */
		eb.fd = spill_open();
	}
	sp->fd = -1;
	sp->n = 0;
	sp->base = base;
	sp->avail = avail;
	for (int k = 0; k < PAIR_SLICES; k++) J->part[k].b = &eb;
	J->d = d;
	J->l = l;
	J->h2 = d->levels - l == 2;
	J->c = c;
	J->nc = nc;
	J->m = m;
	J->brick = brick;
	struct hslot *slot = NULL;
	int err = 0;
	if (J->h2) {
		uint64_t cap = 16;
		while (cap < 2 * nc) cap *= 2;
		slot = malloc(cap * sizeof *slot);
		if (!slot) {
			free(J);
			if (eb.fd >= 0) close(eb.fd);
			return NOMEM();
		}
		for (uint64_t s = 0; s < cap; s++) slot[s].node = NONE;
		for (size_t a = 0; a < nc; a++) {
			uint64_t s = vd_mix64(c[a].key) & (cap - 1);
			while (slot[s].node != NONE) s = (s + 1) & (cap - 1);
			slot[s] = (struct hslot){c[a].key, c[a].node};
		}
		J->slot = slot;
		J->mask = cap - 1;
	}
	err = vd_parallel_for(PAIR_SLICES, threads, pair_slice, J);
	size_t total = 0;
	for (int k = 0; k < PAIR_SLICES; k++) {
		if (!err && J->err[k]) err = J->err[k];
		total += J->part[k].n + J->part[k].spilled;
	}
	/* the graph in memory, clustered whole: when that passes the budget
	 * (an eighth of it left to the Markov clustering's matrices) the
	 * whole graph goes to the file */
	uint64_t gn = 2 * (uint64_t)total < nc ? 2 * (uint64_t)total : nc;
	if (!err && avail && (eb.over || graph_need(total, gn, d->lv[l].nodes) >
					    avail / VD_BUDGET_LOSSY_MARKOV_DIV *
					    (VD_BUDGET_LOSSY_MARKOV_DIV - 1))) {
		for (int k = 0; k < PAIR_SLICES && !err; k++)
			err = edge_flush(&J->part[k]);
		if (!err) {
			sp->fd = eb.fd;
			sp->n = total;
			eb.fd = -1;
		}
	} else if (!err && total) {
		g->e = malloc(total * sizeof *g->e);
		if (!g->e) err = NOMEM();
		for (int k = 0; k < PAIR_SLICES && !err; k++) {
			if (J->part[k].n)
				memcpy(g->e + g->n, J->part[k].e,
				       J->part[k].n * sizeof *g->e);
			g->n += J->part[k].n;
		}
		g->cap = g->n;
	}
	if (eb.fd >= 0) close(eb.fd);
	for (int k = 0; k < PAIR_SLICES; k++) free(J->part[k].e);
	free(slot);
	free(J);
	return err;
}

static int similar_pairs(const struct vd_dag *d, int l, const uint64_t *eff,
			 uint64_t max_refs, double diff_factor, int threads,
			 uint64_t budget, struct vd_lossy_edge **out,
			 size_t *n_out, uint64_t *candidates, uint64_t graph_budget,
			 struct spill *sp)
{
	int L = d->levels, A = d->chunk_level;
	struct edges g = {0};
	struct enc *c = NULL;
	uint64_t *topo[VD_MAX_LEVELS] = {0}, *vox[VD_MAX_LEVELS] = {0};
	uint64_t *brick = NULL;
	int err = 0;
	*out = NULL;
	*n_out = 0;
	*candidates = 0;
	sp->fd = -1;
	sp->n = 0;
	if (l < A || l > L - 2) return 0;
	const struct vd_dag_level *lv = &d->lv[l];
	size_t nc = 0;
	c = malloc((lv->nodes ? lv->nodes : 1) * sizeof *c);
	if (!c) return NOMEM();
	int h = L - l;
	if (h == 2) {
		for (uint64_t i = 0; i < lv->nodes; i++)
			if (eff[i] <= max_refs)
				c[nc++] = (struct enc){node_brick(d, i), 0, (uint32_t)i};
		*candidates = nc;
		err = search_pairs(d, l, c, nc, 1, NULL, threads, budget,
				   graph_budget, &g, sp);
		goto done;
	}
	/* taller: the bricks of level L-2, topology hashes (masks of levels
	 * l..L-2) and voxel counts bottom-up for every node of levels
	 * L-2..l */
	const struct vd_dag_level *bv = &d->lv[L - 2];
	brick = malloc((bv->nodes ? bv->nodes : 1) * 8);
	if (!brick) {
		err = NOMEM();
		goto done;
	}
	for (uint64_t i = 0; i < bv->nodes; i++) brick[i] = node_brick(d, i);
	for (int k = L - 2; k >= l && !err; k--) {
		const struct vd_dag_level *kv = &d->lv[k];
		topo[k] = malloc((kv->nodes ? kv->nodes : 1) * 8);
		vox[k] = malloc((kv->nodes ? kv->nodes : 1) * 8);
		if (!topo[k] || !vox[k]) {
			err = NOMEM();
			break;
		}
		for (uint64_t i = 0; i < kv->nodes; i++) {
			uint64_t hsh = vd_mix64(kv->mask[i] + 0x9e3779b97f4a7c15ULL), v = 0;
			if (k == L - 2) {
				v = pop64(brick[i]);
			} else {
				for (uint64_t j = kv->first[i]; j < kv->first[i + 1]; j++) {
					uint32_t ch = kv->child[j];
					hsh = vd_mix64(hsh ^ topo[k + 1][ch]) + j - kv->first[i];
					v += vox[k + 1][ch];
				}
			}
			topo[k][i] = hsh;
			vox[k][i] = v;
		}
	}
	if (err) goto done;
	for (uint64_t i = 0; i < lv->nodes; i++)
		if (eff[i] <= max_refs)
			c[nc++] = (struct enc){topo[l][i], vox[l][i], (uint32_t)i};
	*candidates = nc;
	qsort(c, nc, sizeof *c, enc_cmp);
	int64_t m = (int64_t)floor((double)h * h * diff_factor);
	err = search_pairs(d, l, c, nc, m, brick, threads, budget,
			   graph_budget, &g, sp);
done:
	for (int k = 0; k < VD_MAX_LEVELS; k++) {
		free(topo[k]);
		free(vox[k]);
	}
	free(brick);
	free(c);
	if (!err) err = edges_sort(g.e, g.n, lv->nodes);
	if (err) {
		free(g.e);
		return err;
	}
	*out = g.e;
	*n_out = g.n;
	return 0;
}

int vd_lossy_similar_pairs(const struct vd_dag *d, int l, const uint64_t *eff,
			   uint64_t max_refs, double diff_factor, int threads,
			   struct vd_lossy_edge **out, size_t *n_out,
			   uint64_t *candidates)
{
	struct spill sp;
	return similar_pairs(d, l, eff, max_refs, diff_factor, threads, 0,
			     out, n_out, candidates, 0, &sp);
}

/* ------------------------------------------------------ Markov clustering */

static uint32_t uf_find(uint32_t *p, uint32_t x)
{
	while (p[x] != x) {
		p[x] = p[p[x]];
		x = p[x];
	}
	return x;
}

static void uf_union(uint32_t *p, uint32_t a, uint32_t b)
{
	a = uf_find(p, a);
	b = uf_find(p, b);
	if (a < b) p[b] = a;
	else if (b < a) p[a] = b;
}

/* A sparse column-stochastic matrix in blocks of MCL_BLOCK columns:
 * column j's entries are blk[j / MCL_BLOCK].row/val[beg[j]..end[j]),
 * sorted by row. Blocks let the columns of one expansion be computed in
 * parallel, each block into its own arrays, with nothing to concatenate;
 * the fixed block size keeps the layout (and so every number) independent
 * of the thread count. */
#define MCL_BLOCK 4096

struct sblk {
	uint32_t *row;
	double *val;
	uint64_t cap;
};

struct smat {
	uint32_t n, nb;
	uint32_t *beg, *end;
	struct sblk *blk;
	struct mcl_ledger *lg; /* NULL: not counted */
	uint64_t *mine;        /* the component's bytes taken from it */
};

#define COL_ROW(M, j) ((M)->blk[(j) / MCL_BLOCK].row)
#define COL_VAL(M, j) ((M)->blk[(j) / MCL_BLOCK].val)

static void smat_free(struct smat *s)
{
	if (s->blk)
		for (uint32_t b = 0; b < s->nb; b++) {
			free(s->blk[b].row);
			free(s->blk[b].val);
		}
	free(s->blk);
	free(s->beg);
	free(s->end);
}

static int smat_init(struct smat *s, uint32_t n, struct mcl_ledger *lg,
		     uint64_t *mine)
{
	s->n = n;
	s->nb = (n + MCL_BLOCK - 1) / MCL_BLOCK;
	s->lg = lg;
	s->mine = mine;
	int err = led_take(lg, mine, 8 * (n + 1ull) + (s->nb + 1ull) * sizeof *s->blk, 0);
	if (err) return err;
	s->beg = malloc((n + 1ull) * 4);
	s->end = malloc((n + 1ull) * 4);
	s->blk = calloc(s->nb + 1ull, sizeof *s->blk);
	return s->beg && s->end && s->blk ? 0 : NOMEM();
}

/* bytes per matrix entry: a row and a value */
#define ENTRY_BYTES (sizeof(uint32_t) + sizeof(double))

static int sblk_reserve(const struct smat *M, struct sblk *s, uint64_t need)
{
	if (need <= s->cap) return 0;
	/* a block's entries are indexed by 32 bits: at most MCL_BLOCK
	 * columns of MCL_SELECT (plus pruning leftovers) entries each */
	if (need > UINT32_MAX) return NOMEM();
	uint64_t c = s->cap ? s->cap : 64;
	while (c < need) c *= 2;
	/* realloc may hold the old and the new array at once */
	int err = led_take(M->lg, M->mine, (c - s->cap) * ENTRY_BYTES,
			   s->cap * ENTRY_BYTES);
	if (err) return err;
	uint32_t *r = realloc(s->row, c * sizeof *r);
	if (!r) return NOMEM();
	s->row = r;
	double *v = realloc(s->val, c * sizeof *v);
	if (!v) return NOMEM();
	s->val = v;
	s->cap = c;
	return 0;
}

#define MCL_PRUNE (1.0 / 10000) /* mcl's -P 10000 */
#define MCL_SELECT 1100         /* mcl's -S 1100 */
#define MCL_MAX_ITER 10000

static int u32_cmp(const void *a, const void *b)
{
	uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
	return x < y ? -1 : x > y;
}

static int dbl_desc(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return x > y ? -1 : x < y;
}

#define MCL_EPS 1e-9

/* The clustering of a converged matrix, as mcl interprets it: attractors
 * (positive diagonal) joined into systems when one flows to another; a
 * node belongs to the system(s) its column flows to; nodes flowing to
 * several systems (overlap, on symmetric graphs) are cut out as clusters
 * of their own, one per set of systems (mcl's default -overlap mode).
 * cluster[j] = the smallest node of j's cluster. `sys` and `tmp` are
 * scratch arrays of n entries. */
static int mcl_interpret(const struct smat *M, uint32_t *cluster,
			 uint32_t *sys, uint32_t *tmp)
{
	uint32_t n = M->n;
	for (uint32_t j = 0; j < n; j++) sys[j] = j;
	for (uint32_t j = 0; j < n; j++) {
		const uint32_t *rr = COL_ROW(M, j);
		const double *vv = COL_VAL(M, j);
		int att = 0;
		for (uint64_t e = M->beg[j]; e < M->end[j]; e++)
			if (rr[e] == j && vv[e] > MCL_EPS) att = 1;
		if (!att) continue;
		for (uint64_t e = M->beg[j]; e < M->end[j]; e++) {
			uint32_t i = rr[e];
			if (vv[e] <= MCL_EPS || i == j) continue;
			/* i is an attractor too when its own column keeps it */
			const uint32_t *ri = COL_ROW(M, i);
			const double *vi = COL_VAL(M, i);
			for (uint64_t f = M->beg[i]; f < M->end[i]; f++)
				if (ri[f] == i && vi[f] > MCL_EPS)
					uf_union(sys, i, j);
		}
	}
	/* each node's systems: their roots, sorted, in a flat list */
	uint64_t *off = malloc((n + 1ull) * 8);
	uint32_t *list = NULL;
	uint64_t cnt = 0;
	for (uint32_t j = 0; j < n; j++)
		cnt += M->end[j] - M->beg[j];
	list = malloc((cnt + 1) * 4);
	if (!off || !list) {
		free(off);
		free(list);
		return NOMEM();
	}
	uint64_t k = 0;
	for (uint32_t j = 0; j < n; j++) {
		const uint32_t *rr = COL_ROW(M, j);
		const double *vv = COL_VAL(M, j);
		off[j] = k;
		for (uint64_t e = M->beg[j]; e < M->end[j]; e++) {
			if (vv[e] <= MCL_EPS) continue;
			list[k++] = uf_find(sys, rr[e]);
		}
		qsort(list + off[j], k - off[j], 4, u32_cmp);
		uint64_t w = off[j];
		for (uint64_t r = off[j]; r < k; r++)
			if (r == off[j] || list[r] != list[w - 1]) list[w++] = list[r];
		k = w;
	}
	off[n] = k;
	/* cluster id: the root of a single system; for overlap the first node
	 * with the same set of systems */
	uint32_t no = 0;
	for (uint32_t j = 0; j < n; j++) {
		uint64_t a = off[j], len = off[j + 1] - a;
		if (len == 1) {
			cluster[j] = list[a];
			continue;
		}
		cluster[j] = n + j; /* a fresh overlap cluster */
		for (uint32_t t = 0; t < no; t++) {
			uint32_t o = tmp[t];
			if (off[o + 1] - off[o] == len &&
			    !memcmp(list + off[o], list + a, len * 4)) {
				cluster[j] = cluster[o];
				break;
			}
		}
		if (cluster[j] == n + j) tmp[no++] = j;
	}
	free(off);
	free(list);
	/* relabel every cluster by its smallest node */
	uint32_t *low = malloc(2ull * n * 4);
	if (!low) return NOMEM();
	for (uint64_t i = 0; i < 2ull * n; i++) low[i] = NONE;
	for (uint32_t j = 0; j < n; j++)
		if (low[cluster[j]] == NONE) low[cluster[j]] = j;
	for (uint32_t j = 0; j < n; j++) cluster[j] = low[cluster[j]];
	free(low);
	return 0;
}

/* Per-worker scratch of an expansion: a dense accumulator (all zero
 * between columns) and marks (bytes, and bits) over the component's rows,
 * the touched rows, the values for pruning. */
struct mcl_scratch {
	double *acc, *tmp;
	uint32_t *touched;
	uint8_t *mark;
	uint64_t *bits;
};

static void scratch_free(struct mcl_scratch *s)
{
	free(s->acc);
	free(s->tmp);
	free(s->touched);
	free(s->mark);
	free(s->bits);
	memset(s, 0, sizeof *s);
}

static int scratch_alloc(struct mcl_scratch *s, uint32_t n)
{
	s->acc = calloc(n + 1ull, sizeof *s->acc);
	s->tmp = malloc((n + 1ull) * sizeof *s->tmp);
	s->touched = malloc((n + 1ull) * sizeof *s->touched);
	s->mark = calloc(n + 1ull, 1);
	s->bits = calloc(n / 64 + 1ull, 8);
	if (s->acc && s->tmp && s->touched && s->mark && s->bits) return 0;
	scratch_free(s);
	return NOMEM();
}

/* Block b of the next matrix N: its columns' expansion (M * M), pruning,
 * inflation and normalization. Every column is computed alone, in the
 * same order of operations whoever computes it. Returns the largest
 * chaos (max - sum of squares) of its columns, -1 when out of memory, -2
 * over the ledger's limit. */
static double mcl_block(const struct smat *M, uint32_t b, double inflation,
			struct mcl_scratch *s, struct smat *N)
{
	double chaos = 0, *acc = s->acc, *tmp = s->tmp;
	uint32_t *touched = s->touched;
	uint8_t *mark = s->mark;
	uint64_t *bits = s->bits;
	struct sblk *o = &N->blk[b];
	uint32_t j0 = b * MCL_BLOCK, j1 = M->n - j0 > MCL_BLOCK ? j0 + MCL_BLOCK : M->n;
	uint64_t nk = 0;
	for (uint32_t j = j0; j < j1; j++) {
		const uint32_t *rj = COL_ROW(M, j);
		const double *vj = COL_VAL(M, j);
		/* the rows column j can reach: at most `most`, words w0..w1 of
		 * the bitmap */
		uint64_t most = 0;
		uint32_t lo = UINT32_MAX, hi = 0, nt = 0;
		for (uint64_t e = M->beg[j]; e < M->end[j]; e++) {
			uint32_t kk = rj[e];
			const uint32_t *rk = COL_ROW(M, kk);
			most += M->end[kk] - M->beg[kk];
			if (rk[M->beg[kk]] < lo) lo = rk[M->beg[kk]];
			if (rk[M->end[kk] - 1] > hi) hi = rk[M->end[kk] - 1];
		}
		uint32_t w0 = lo >> 6, w1 = hi >> 6;
		int sorted = (uint64_t)(w1 - w0) + 1 <= 2 * most;
		if (sorted) {
			/* dense rows: no branch per entry, and the bitmap gives
			 * them in order without a sort (acc is all zero
			 * between columns, and 0 + x is x) */
			for (uint64_t e = M->beg[j]; e < M->end[j]; e++) {
				uint32_t kk = rj[e];
				double w = vj[e];
				const uint32_t *rk = COL_ROW(M, kk);
				const double *vk = COL_VAL(M, kk);
				for (uint64_t f = M->beg[kk]; f < M->end[kk]; f++) {
					uint32_t r = rk[f];
					acc[r] += w * vk[f];
					bits[r >> 6] |= 1ull << (r & 63);
				}
			}
			for (uint32_t wd = w0; wd <= w1; wd++) {
				uint64_t x = bits[wd];
				bits[wd] = 0;
				for (; x; x &= x - 1)
					touched[nt++] = wd << 6 | (uint32_t)__builtin_ctzll(x);
			}
		} else {
			for (uint64_t e = M->beg[j]; e < M->end[j]; e++) {
				uint32_t kk = rj[e];
				double w = vj[e];
				const uint32_t *rk = COL_ROW(M, kk);
				const double *vk = COL_VAL(M, kk);
				for (uint64_t f = M->beg[kk]; f < M->end[kk]; f++) {
					uint32_t r = rk[f];
					if (!mark[r]) {
						mark[r] = 1;
						touched[nt++] = r;
					}
					acc[r] += w * vk[f];
				}
			}
		}
		/* prune entries below 1/P, then keep the S largest */
		uint32_t kept = 0;
		for (uint32_t t = 0; t < nt; t++)
			if (acc[touched[t]] >= MCL_PRUNE) tmp[kept++] = acc[touched[t]];
		double cut = MCL_PRUNE;
		if (kept == 0) {
			/* keep the largest entry: a column never empties */
			double mx = 0;
			for (uint32_t t = 0; t < nt; t++)
				if (acc[touched[t]] > mx) mx = acc[touched[t]];
			cut = mx;
		} else if (kept > MCL_SELECT) {
			qsort(tmp, kept, sizeof *tmp, dbl_desc);
			cut = tmp[MCL_SELECT - 1];
		}
		int rerr = sblk_reserve(N, o, nk + nt);
		if (rerr) {
			for (uint32_t t = 0; t < nt; t++) {
				mark[touched[t]] = 0;
				acc[touched[t]] = 0;
			}
			return rerr == VD_ERR_BUDGET ? -2 : -1;
		}
		/* rows in increasing order */
		if (!sorted) u32_sort(touched, nt);
		N->beg[j] = (uint32_t)nk;
		double sum = 0, mx = 0, sq = 0;
		for (uint32_t t = 0; t < nt; t++) {
			uint32_t r = touched[t];
			double a = acc[r];
			mark[r] = 0;
			acc[r] = 0;
			if (a < cut) continue;
			double v = inflation == 2.0 ? a * a : pow(a, inflation);
			o->row[nk] = r;
			o->val[nk++] = v;
			sum += v;
		}
		for (uint64_t e = N->beg[j]; e < nk; e++) {
			o->val[e] /= sum;
			if (o->val[e] > mx) mx = o->val[e];
			sq += o->val[e] * o->val[e];
		}
		N->end[j] = (uint32_t)nk;
		/* chaos: max - sum of squares, 0 when every entry of the
		 * column is equal (a doubly idempotent limit) */
		if (mx - sq > chaos) chaos = mx - sq;
	}
	return chaos;
}

/* One expansion of a component of several blocks, blocks in parallel. */
struct mcl_par {
	const struct smat *M;
	struct smat *N;
	double inflation;
	double *chaos;            /* per block */
	struct mcl_scratch *scr;  /* per worker */
};

static void mcl_par_block(void *ctx, size_t b, int worker)
{
	struct mcl_par *P = ctx;
	P->chaos[b] = mcl_block(P->M, (uint32_t)b, P->inflation,
				&P->scr[worker], P->N);
}

/* One MCL run on a connected component of n nodes (local indices), given
 * its symmetric adjacency (CSR: adj_off/adj_to/adj_w, no loops), the
 * blocks of an expansion on up to `threads` threads. Writes the cluster
 * of each node as the smallest local index in it. */
static int mcl_component(uint32_t n, const uint64_t *adj_off,
			 const uint32_t *adj_to, const double *adj_w,
			 double inflation, int threads, uint32_t *cluster,
			 struct mcl_ledger *lg, uint64_t *mine)
{
	struct smat M = {0}, N = {0};
	struct mcl_scratch *scr = NULL;
	double *chaos = NULL;
	int nw = 1, err = 0;
	if ((err = smat_init(&M, n, lg, mine)) || (err = smat_init(&N, n, lg, mine)))
		goto out;
	if (M.nb > 1) {
		nw = threads > 0 ? threads : vd_hardware_threads();
		if ((uint32_t)nw > M.nb) nw = (int)M.nb;
	}
	/* the scratch of each worker, the chaos per block, and the
	 * interpretation's arrays (systems, lists of up to the entries) */
	if ((err = led_take(lg, mine, (uint64_t)nw * (n + 1ull) * 22 +
			    M.nb * 8ull + (n + 1ull) * 32, 0)))
		goto out;
	scr = calloc((size_t)nw, sizeof *scr);
	chaos = malloc(M.nb * sizeof *chaos);
	if (!scr || !chaos) {
		err = NOMEM();
		goto out;
	}
	for (int w = 0; w < nw && !err; w++) err = scratch_alloc(&scr[w], n);
	if (err) goto out;
	/* the start matrix: the weights, a loop on every node weighing the
	 * largest of its edge weights (mcl's default), columns normalized */
	uint64_t k = 0;
	for (uint32_t j = 0; j < n; j++) {
		struct sblk *o = &M.blk[j / MCL_BLOCK];
		if (j % MCL_BLOCK == 0) k = 0;
		uint64_t deg = adj_off[j + 1] - adj_off[j];
		if ((err = sblk_reserve(&M, o, k + deg + 1))) goto out;
		M.beg[j] = (uint32_t)k;
		double mx = 0, sum = 0;
		for (uint64_t e = adj_off[j]; e < adj_off[j + 1]; e++)
			if (adj_w[e] > mx) mx = adj_w[e];
		int placed = 0;
		for (uint64_t e = adj_off[j]; e <= adj_off[j + 1]; e++) {
			if (!placed && (e == adj_off[j + 1] || adj_to[e] > j)) {
				o->row[k] = j;
				o->val[k++] = mx;
				sum += mx;
				placed = 1;
			}
			if (e < adj_off[j + 1]) {
				o->row[k] = adj_to[e];
				o->val[k++] = adj_w[e];
				sum += adj_w[e];
			}
		}
		for (uint64_t e = M.beg[j]; e < k; e++) o->val[e] /= sum;
		M.end[j] = (uint32_t)k;
	}
	struct mcl_par P = {&M, &N, inflation, chaos, scr};
	for (int it = 0; it < MCL_MAX_ITER; it++) {
		P.M = &M;
		P.N = &N;
		if (nw > 1) {
			if ((err = vd_parallel_for(M.nb, nw, mcl_par_block, &P)))
				goto out;
		} else {
			for (uint32_t b = 0; b < M.nb; b++)
				mcl_par_block(&P, b, 0);
		}
		double c = 0;
		for (uint32_t b = 0; b < M.nb; b++) {
			if (chaos[b] < 0) {
				err = chaos[b] < -1.5 ? VD_ERR_BUDGET : NOMEM();
				goto out;
			}
			if (chaos[b] > c) c = chaos[b];
		}
		struct smat t = M;
		M = N;
		N = t;
		if (c < 1e-9) break;
	}
	uint32_t *sys = malloc((n + 1ull) * 4);
	err = sys ? mcl_interpret(&M, cluster, scr[0].touched, sys) : NOMEM();
	free(sys);
out:
	smat_free(&M);
	smat_free(&N);
	if (scr)
		for (int w = 0; w < nw; w++) scratch_free(&scr[w]);
	free(scr);
	free(chaos);
	return err;
}

/* The graph of n nodes in CSR form and its connected components. */
struct graph {
	uint32_t n;
	uint64_t *off;
	uint32_t *to;
	double *w;
	uint32_t *comp;      /* component root (smallest node) per node */
	uint32_t *order;     /* nodes grouped by component, increasing */
	uint64_t *comp_off;  /* component c: order[comp_off[c]..comp_off[c+1]] */
	uint32_t *local;     /* node -> its index inside its component */
	uint64_t ncomp;
};

static void graph_free(struct graph *g)
{
	free(g->off);
	free(g->to);
	free(g->w);
	free(g->comp);
	free(g->order);
	free(g->comp_off);
	free(g->local);
}

static int graph_build(struct graph *g, uint32_t n,
		       const struct vd_lossy_edge *e, size_t ne)
{
	memset(g, 0, sizeof *g);
	g->n = n;
	g->off = calloc(n + 1ull, 8);
	g->to = malloc((2 * ne + 1) * 4);
	g->w = malloc((2 * ne + 1) * 8);
	g->comp = malloc((n + 1ull) * 4);
	g->order = malloc((n + 1ull) * 4);
	g->comp_off = malloc((n + 2ull) * 8);
	g->local = malloc((n + 1ull) * 4);
	uint64_t *fill = calloc(n + 1ull, 8);
	if (!g->off || !g->to || !g->w || !g->comp || !g->order ||
	    !g->comp_off || !g->local || !fill) {
		free(fill);
		return NOMEM();
	}
	for (size_t i = 0; i < ne; i++) {
		g->off[e[i].u + 1]++;
		g->off[e[i].v + 1]++;
	}
	for (uint32_t i = 0; i < n; i++) g->off[i + 1] += g->off[i];
	/* edges sorted by (u, v): filling in order keeps each list sorted
	 * except that lower neighbours (from edges (x, u)) come first, which
	 * is increasing too since those edges are visited by increasing x */
	for (size_t i = 0; i < ne; i++) {
		uint32_t u = e[i].u, v = e[i].v;
		uint64_t pv = g->off[v] + fill[v]++;
		g->to[pv] = u;
		g->w[pv] = e[i].s;
	}
	for (size_t i = 0; i < ne; i++) {
		uint32_t u = e[i].u, v = e[i].v;
		uint64_t pu = g->off[u] + fill[u]++;
		g->to[pu] = v;
		g->w[pu] = e[i].s;
	}
	free(fill);
	for (uint32_t i = 0; i < n; i++) g->comp[i] = i;
	for (size_t i = 0; i < ne; i++) uf_union(g->comp, e[i].u, e[i].v);
	/* counting sort of the nodes by component root */
	uint64_t *cnt = calloc(n + 1ull, 8);
	if (!cnt) return NOMEM();
	for (uint32_t i = 0; i < n; i++) {
		g->comp[i] = uf_find(g->comp, i);
		cnt[g->comp[i]]++;
	}
	uint64_t c = 0, at = 0;
	for (uint32_t i = 0; i < n; i++)
		if (cnt[i]) {
			g->comp_off[c++] = at;
			uint64_t k = cnt[i];
			cnt[i] = at;
			at += k;
		}
	g->comp_off[c] = at;
	g->ncomp = c;
	for (uint32_t i = 0; i < n; i++) {
		uint64_t p = cnt[g->comp[i]]++;
		g->order[p] = i;
	}
	for (uint64_t k = 0; k < c; k++)
		for (uint64_t p = g->comp_off[k]; p < g->comp_off[k + 1]; p++)
			g->local[g->order[p]] = (uint32_t)(p - g->comp_off[k]);
	free(cnt);
	return 0;
}

struct mcl_job {
	const struct graph *g;
	double inflation;
	uint32_t *cluster; /* out: per node, the smallest node of its cluster */
	int err;           /* an error of any component */
	int big;           /* this pass: components of several blocks only;
			    * 2: the components marked in `again` */
	int threads;       /* for the blocks of one big component */
	struct mcl_ledger *lg;
	uint8_t *again;    /* per component: over the ledger in parallel */
	uint64_t again_n;  /* atomic */
};

static void mcl_run_comp(void *ctx, size_t k, int worker)
{
	(void)worker;
	struct mcl_job *J = ctx;
	const struct graph *g = J->g;
	uint64_t a = g->comp_off[k];
	uint32_t n = (uint32_t)(g->comp_off[k + 1] - a);
	const uint32_t *nodes = g->order + a;
	if (J->big == 2 ? !J->again[k] : (n > MCL_BLOCK) != J->big) return;
	if (n <= 2) {
		/* decided directly: a pair is one cluster (with mcl's loops the
		 * 2x2 matrix is already idempotent) */
		for (uint32_t i = 0; i < n; i++) J->cluster[nodes[i]] = nodes[0];
		return;
	}
	uint64_t m = 0;
	for (uint32_t i = 0; i < n; i++)
		m += g->off[nodes[i] + 1] - g->off[nodes[i]];
	uint64_t mine = 0;
	int err = led_take(J->lg, &mine, (n + 1ull) * 12 + (m + 1) * 12, 0);
	if (err == VD_ERR_BUDGET && J->big == 0 && J->threads != 1) {
		/* with the other workers' components: again, alone */
		J->again[k] = 1;
		__atomic_add_fetch(&J->again_n, 1, __ATOMIC_RELAXED);
		return;
	}
	if (err) {
		__atomic_store_n(&J->err, err, __ATOMIC_RELAXED);
		return;
	}
	uint64_t *off = malloc((n + 1ull) * 8);
	uint32_t *to = malloc((m + 1) * 4), *cl = malloc(n * 4ull);
	double *w = malloc((m + 1) * 8);
	if (!off || !to || !cl || !w) {
		err = NOMEM();
	} else {
		uint64_t p = 0;
		for (uint32_t i = 0; i < n; i++) {
			off[i] = p;
			for (uint64_t e = g->off[nodes[i]]; e < g->off[nodes[i] + 1]; e++) {
				to[p] = g->local[g->to[e]];
				w[p++] = g->w[e];
			}
		}
		off[n] = p;
		err = mcl_component(n, off, to, w, J->inflation,
				    J->big ? J->threads : 1, cl, J->lg, &mine);
		if (err == VD_ERR_BUDGET && J->big == 0 && J->threads != 1) {
			J->again[k] = 1;
			__atomic_add_fetch(&J->again_n, 1, __ATOMIC_RELAXED);
			err = 0;
		} else if (!err)
			for (uint32_t i = 0; i < n; i++)
				J->cluster[nodes[i]] = nodes[cl[i]];
	}
	free(off);
	free(to);
	free(cl);
	free(w);
	led_give(J->lg, &mine);
	if (err) __atomic_store_n(&J->err, err, __ATOMIC_RELAXED);
}

/* vd_lossy_mcl() with the clustering's memory counted in `lg` (NULL:
 * not counted); VD_ERR_BUDGET with no message when a component alone
 * passes its limit. */
static int mcl_run(uint32_t n, const struct vd_lossy_edge *e, size_t ne,
		   double inflation, int threads, uint32_t *cluster,
		   struct mcl_ledger *lg)
{
	struct graph g;
	int err = graph_build(&g, n, e, ne);
	uint8_t *again = NULL;
	if (!err && !(again = calloc(g.ncomp + 1, 1))) err = NOMEM();
	if (!err) {
		/* the components of several blocks one after another, each
		 * on all threads (a scene's graph often has one giant
		 * component); then the rest, components in parallel, and
		 * those that found the ledger full beside the others again,
		 * alone */
		struct mcl_job J = {&g, inflation, cluster, 0, 1, threads, lg,
				    again, 0};
		for (uint64_t k = 0; k < g.ncomp && !J.err; k++)
			mcl_run_comp(&J, k, 0);
		J.big = 0;
		if (!J.err)
			err = vd_parallel_for(g.ncomp, threads, mcl_run_comp, &J);
		if (!err && !J.err && J.again_n) {
			J.big = 2;
			J.threads = 1;
			for (uint64_t k = 0; k < g.ncomp && !J.err; k++)
				mcl_run_comp(&J, k, 0);
		}
		if (!err && J.err == VD_ERR_BUDGET)
			err = VD_ERR_BUDGET;
		else if (!err && J.err)
			err = vd_fail(VD_ERR_NOMEM, "out of memory clustering");
	}
	free(again);
	graph_free(&g);
	return err;
}

int vd_lossy_mcl(uint32_t n, const struct vd_lossy_edge *e, size_t ne,
		 double inflation, int threads, uint32_t *cluster)
{
	return mcl_run(n, e, ne, inflation, threads, cluster, NULL);
}

/* --------------------------------------------------- lossless reduction */

/* Removes the nodes not reachable from the root, keeping the order. */
static int dag_gc(struct vd_dag *d)
{
	int L = d->levels, A = d->chunk_level;
	uint32_t *nid[VD_MAX_LEVELS] = {0};
	int err = 0;
	for (int l = A; l < L; l++) {
		nid[l] = malloc((d->lv[l].nodes ? d->lv[l].nodes : 1) * 4);
		if (!nid[l]) {
			err = NOMEM();
			goto out;
		}
		for (uint64_t i = 0; i < d->lv[l].nodes; i++) nid[l][i] = NONE;
	}
	if (!d->lv[A].nodes) goto out;
	nid[A][0] = 0;
	for (int l = A; l < L - 1; l++) {
		struct vd_dag_level *lv = &d->lv[l];
		for (uint64_t i = 0; i < lv->nodes; i++)
			if (nid[l][i] != NONE)
				for (uint64_t j = lv->first[i]; j < lv->first[i + 1]; j++)
					nid[l + 1][lv->child[j]] = 0;
		uint32_t c = 0;
		for (uint64_t i = 0; i < d->lv[l + 1].nodes; i++)
			if (nid[l + 1][i] != NONE) nid[l + 1][i] = c++;
	}
	for (int l = A; l < L; l++) {
		struct vd_dag_level *lv = &d->lv[l];
		uint64_t n = 0, r = 0;
		for (uint64_t i = 0; i < lv->nodes; i++) {
			if (nid[l][i] == NONE) continue;
			lv->mask[n] = lv->mask[i];
			if (l < L - 1) {
				uint64_t f = lv->first[i], t = lv->first[i + 1];
				lv->first[n] = r;
				for (uint64_t j = f; j < t; j++)
					lv->child[r++] = nid[l + 1][lv->child[j]];
			}
			n++;
		}
		lv->nodes = n;
		if (l < L - 1) {
			lv->first[n] = r;
			lv->refs = r;
		}
	}
out:
	for (int l = 0; l < VD_MAX_LEVELS; l++) free(nid[l]);
	return err;
}

/* Merges identical nodes on levels `from` up to the root (each level's
 * references already point at the representatives below), then removes
 * what is unreachable. */
static int dag_dedupe_up(struct vd_dag *d, int from)
{
	int A = d->chunk_level;
	int err = 0;
	for (int l = from; l >= A && !err; l--) {
		struct vd_dag_level *lv = &d->lv[l];
		uint64_t cap = 16;
		while (cap < 2 * lv->nodes) cap *= 2;
		uint32_t *slot = malloc(cap * 4), *rep = malloc((lv->nodes + 1) * 4);
		if (!slot || !rep) {
			free(slot);
			free(rep);
			return NOMEM();
		}
		memset(slot, 0xff, cap * 4);
		for (uint64_t i = 0; i < lv->nodes; i++) {
			uint64_t f = lv->first[i], k = lv->first[i + 1] - f;
			uint64_t h = vd_mix64(lv->mask[i]);
			for (uint64_t j = 0; j < k; j++) h = vd_mix64(h ^ lv->child[f + j]);
			uint64_t s = h & (cap - 1);
			for (;;) {
				uint32_t o = slot[s];
				if (o == NONE) {
					slot[s] = (uint32_t)i;
					rep[i] = (uint32_t)i;
					break;
				}
				if (lv->mask[o] == lv->mask[i] &&
				    !memcmp(lv->child + lv->first[o], lv->child + f, k * 4)) {
					rep[i] = o;
					break;
				}
				s = (s + 1) & (cap - 1);
			}
		}
		if (l > A) {
			struct vd_dag_level *pv = &d->lv[l - 1];
			for (uint64_t j = 0; j < pv->refs; j++)
				pv->child[j] = rep[pv->child[j]];
		}
		free(slot);
		free(rep);
	}
	return dag_gc(d);
}

/* ------------------------------------------------------------ the stage */

static int dag_diff(const struct vd_dag *a, const struct vd_dag *b,
		    uint64_t *only_a, uint64_t *only_b, uint64_t *voxels_b,
		    uint64_t memo_limit);

static uint64_t dag_nodes(const struct vd_dag *d)
{
	uint64_t n = 0;
	for (int l = d->chunk_level; l < d->levels; l++) n += d->lv[l].nodes;
	return n;
}

/* The arrays of the pair search of level l before its graph: effective
 * counts of levels A..l (8 bytes per node), candidates (24 per node of
 * l), and at height 2 the hash table of their bricks (at most 32 per
 * node), else the bricks of level L-2 (8 per node) and the topology
 * hashes and voxel counts of levels l..L-2 (16 per node). */
static uint64_t level_need(const struct vd_dag *d, int l)
{
	int L = d->levels;
	uint64_t n = 0;
	for (int k = d->chunk_level; k <= l; k++) n += 8 * d->lv[k].nodes;
	n += 24 * d->lv[l].nodes;
	if (L - l == 2) return n + 32 * d->lv[l].nodes + 256;
	n += 8 * d->lv[L - 2].nodes;
	for (int k = l; k <= L - 2; k++) n += 16 * d->lv[k].nodes;
	return n + 256;
}

static int rebuild_bricks(struct vd_dag *d)
{
	int L = d->levels;
	free(d->bricks);
	d->bricks = NULL;
	if (L < 2 || d->chunk_level > L - 2 || !d->lv[d->chunk_level].nodes)
		return 0;
	uint64_t n = d->lv[L - 2].nodes;
	d->bricks = malloc((n ? n : 1) * 8);
	if (!d->bricks) return NOMEM();
	for (uint64_t i = 0; i < n; i++) d->bricks[i] = node_brick(d, i);
	return 0;
}

static int u64_cmp(const void *a, const void *b)
{
	uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
	return x < y ? -1 : x > y;
}

/* The representative of each cluster (graph nodes 0..gn-1, cl[i] the
 * smallest node of i's cluster) into best[cluster]: the member with the
 * largest sum of similarities to the others (the paper's rule); among
 * members whose sums are equal (within rounding), the one that changes
 * the cluster's voxel count least (every member's subtree counted as
 * often as it occurs: effective count times the voxels gained or lost),
 * then the one that brings the run's net change *net closest to zero,
 * then the smallest node. The second rule keeps a cluster's members
 * that have more voxels and those that have fewer from all following one
 * of them; the third decides pairs (whose two members have equal sums
 * and opposite changes), which otherwise went to the smaller node and so
 * leant one way over the whole scene. The clusters are taken in the
 * order of their components' smallest nodes, then their own smallest
 * node: the order a spilled graph's groups keep. */
static int pick_representatives(const struct vd_lossy_edge *e, size_t ne,
				uint32_t gn, const uint32_t *cl,
				const double *simsum, const uint32_t *gnode,
				const uint64_t *eff, const uint64_t *vox,
				int64_t *net, uint32_t *best)
{
	uint32_t *root = malloc((gn + 1ull) * 4), *moff = calloc(gn + 2ull, 4);
	uint32_t *mem = malloc((gn + 1ull) * 4);
	uint64_t *key = malloc((gn + 1ull) * 8);
	if (!root || !moff || !mem || !key) {
		free(root);
		free(moff);
		free(mem);
		free(key);
		return NOMEM();
	}
	for (uint32_t i = 0; i < gn; i++) root[i] = i;
	for (size_t k = 0; k < ne; k++) uf_union(root, e[k].u, e[k].v);
	/* members grouped by cluster */
	for (uint32_t i = 0; i < gn; i++) moff[cl[i] + 1]++;
	for (uint32_t i = 0; i < gn; i++) moff[i + 1] += moff[i];
	for (uint32_t i = 0; i < gn; i++) best[i] = moff[i];
	for (uint32_t i = 0; i < gn; i++) mem[best[cl[i]]++] = i;
	uint64_t nk = 0;
	for (uint32_t i = 0; i < gn; i++)
		if (cl[i] == i) key[nk++] = (uint64_t)uf_find(root, i) << 32 | i;
	qsort(key, nk, 8, u64_cmp);
	for (uint64_t k = 0; k < nk; k++) {
		uint32_t c = (uint32_t)key[k], a = moff[c], z = moff[c + 1];
		double most = simsum[mem[a]];
		__int128 occ = 0, sum = 0;
		for (uint32_t t = a; t < z; t++) {
			uint32_t i = mem[t];
			if (simsum[i] > most) most = simsum[i];
			occ += eff[gnode[i]];
			sum += (__int128)eff[gnode[i]] * vox[gnode[i]];
		}
		double tie = most - 1e-9 * (most > 1 ? most : 1);
		uint32_t r = NONE;
		__int128 rd = 0;
		for (uint32_t t = a; t < z; t++) {
			uint32_t i = mem[t];
			if (simsum[i] < tie) continue;
			/* the change if i represents the cluster */
			__int128 d = occ * vox[gnode[i]] - sum;
			if (r == NONE) {
				r = i;
				rd = d;
				continue;
			}
			__int128 ad = d < 0 ? -d : d, ar = rd < 0 ? -rd : rd;
			__int128 bd = *net + d, br = *net + rd;
			if (bd < 0) bd = -bd;
			if (br < 0) br = -br;
			/* members in increasing order: i > r */
			if (ad < ar || (ad == ar && bd < br)) {
				r = i;
				rd = d;
			}
		}
		best[c] = r;
		*net += (int64_t)rd;
	}
	free(root);
	free(moff);
	free(mem);
	free(key);
	return 0;
}

/* Clusters the graph e[0..ne-1] (edges of level nodes below nl, sorted
 * by (u, v)) and points map[] of each merged node at its cluster's
 * representative. Also called on a few whole components at a time of a
 * spilled graph: each component is clustered alone, its nodes numbered
 * in the same order and its edges met in the same order as in the whole
 * graph, so the result is the same. gid: nl entries of NONE, left so.
 * avail: the bytes this may take (its arrays, the graph's adjacency, the
 * Markov clustering), 0: no limit. eff, vox: per node of the level, its
 * effective reference count and voxels; *net: the voxel count change of
 * the run so far, updated. */
static int cluster_edges(struct vd_lossy_edge *e, size_t ne, uint64_t nl,
			 const struct vd_lossy_opts *o,
			 struct vd_lossy_level_stats *ls, uint32_t *gid,
			 uint32_t *map, uint64_t avail, const uint64_t *eff,
			 const uint64_t *vox, int64_t *net)
{
	/* graph nodes: the candidates with an edge, renumbered */
	for (size_t k = 0; k < ne; k++) gid[e[k].u] = gid[e[k].v] = 0;
	uint32_t gn = 0;
	for (uint64_t i = 0; i < nl; i++)
		if (gid[i] != NONE) gid[i] = gn++;
	uint32_t *gnode = malloc((gn + 1ull) * 4), *cl = malloc((gn + 1ull) * 4);
	uint32_t *best = malloc((gn + 1ull) * 4);
	double *simsum = calloc(gn + 1ull, 8);
	int err = 0;
	if (!gnode || !cl || !simsum || !best) {
		err = NOMEM();
		for (uint64_t i = 0; i < nl; i++) gid[i] = NONE;
		goto out;
	}
	for (uint64_t i = 0; i < nl; i++)
		if (gid[i] != NONE) gnode[gid[i]] = (uint32_t)i;
	for (size_t k = 0; k < ne; k++) {
		e[k].u = gid[e[k].u];
		e[k].v = gid[e[k].v];
	}
	for (uint32_t i = 0; i < gn; i++) gid[gnode[i]] = NONE;
	ls->graph_nodes += gn;
	/* the arrays here (20 bytes per node) and graph_build's (the
	 * adjacency, 24 bytes per edge, and 44 per node) */
	uint64_t own = 24 * (uint64_t)ne + 64 * (uint64_t)gn;
	struct mcl_ledger lg = {avail ? (avail > own ? avail - own : 1) : 0, 0, 0};
	err = mcl_run(gn, e, ne, o->inflation, o->threads, cl, &lg);
	if (err == VD_ERR_BUDGET)
		err = vd_fail(VD_ERR_BUDGET, "the Markov clustering of level %d "
			      "needs more than %" PRIu64 " MiB for a component "
			      "beside its graph (%zu edges, %" PRIu32 " nodes, %"
			      PRIu64 " MiB), over the %" PRIu64 " MiB left of the "
			      "budget of %" PRIu64 " MiB (--mem-budget)", ls->level,
			      lg.need >> 20, ne, gn, own >> 20, avail >> 20,
			      o->mem_budget >> 20);
	if (err) goto out;
	for (size_t k = 0; k < ne; k++)
		if (cl[e[k].u] == cl[e[k].v]) {
			simsum[e[k].u] += e[k].s;
			simsum[e[k].v] += e[k].s;
		}
	err = pick_representatives(e, ne, gn, cl, simsum, gnode, eff, vox,
				   net, best);
	if (err) goto out;
	for (uint32_t i = 0; i < gn; i++) {
		if (cl[i] == i) ls->clusters++;
		uint32_t r = best[cl[i]];
		map[gnode[i]] = gnode[r];
		if (r != i) ls->merged++;
	}
out:
	free(gnode);
	free(cl);
	free(best);
	free(simsum);
	return err;
}

/* The voxels under each node of level l (>= L-2) into a new array:
 * bottom-up from the bricks, two levels held at a time. */
static int level_voxels(const struct vd_dag *d, int l, uint64_t **out)
{
	int L = d->levels;
	const struct vd_dag_level *bv = &d->lv[L - 2];
	uint64_t *v = malloc((bv->nodes ? bv->nodes : 1) * 8);
	if (!v) return NOMEM();
	for (uint64_t i = 0; i < bv->nodes; i++) v[i] = pop64(node_brick(d, i));
	for (int k = L - 3; k >= l; k--) {
		const struct vd_dag_level *kv = &d->lv[k];
		uint64_t *u = malloc((kv->nodes ? kv->nodes : 1) * 8);
		if (!u) {
			free(v);
			return NOMEM();
		}
		for (uint64_t i = 0; i < kv->nodes; i++) {
			u[i] = 0;
			for (uint64_t j = kv->first[i]; j < kv->first[i + 1]; j++)
				u[i] += v[kv->child[j]];
		}
		free(v);
		v = u;
	}
	*out = v;
	return 0;
}

/* edges read from a spill file at a time */
#define SPILL_READ 65536

/* Clusters the spilled graph of level l: its connected components by
 * union-find over the level's nodes (memory per node, not per edge), then
 * groups of consecutive components (by smallest node), each group's edges
 * within what is left of the budget, read from the file one group at a
 * time, sorted and clustered as in memory. */
static int cluster_spilled(int l, uint64_t nl, const struct spill *sp,
			   const struct vd_lossy_opts *o,
			   struct vd_lossy_level_stats *ls, uint32_t *gid,
			   uint32_t *map, const uint64_t *eff,
			   const uint64_t *vox, int64_t *net)
{
	uint32_t *root = malloc((nl + 1) * 4), *ncnt = calloc(nl + 1, 4);
	uint64_t *cnt = calloc(nl + 1, 8), *bsz = NULL, nb = 0, bcap = 0;
	uint64_t *seen = calloc(nl / 64 + 1, 8);
	size_t nbuf = sp->n < SPILL_READ ? (size_t)sp->n + 1 : SPILL_READ;
	struct vd_lossy_edge *buf = malloc(nbuf * sizeof *buf), *e = NULL;
	int err = 0;
	if (!root || !ncnt || !cnt || !seen || !buf) {
		err = NOMEM();
		goto out;
	}
	for (uint64_t i = 0; i < nl; i++) root[i] = (uint32_t)i;
	for (int pass = 0; pass < 2 && !err; pass++) {
		for (uint64_t at = 0; at < sp->n && !err; at += SPILL_READ) {
			size_t k = sp->n - at < SPILL_READ ? (size_t)(sp->n - at) : SPILL_READ;
			if ((err = spill_read(sp->fd, buf, k * sizeof *buf,
					     at * sizeof *buf)))
				break;
			for (size_t t = 0; t < k; t++) {
				if (pass == 0) {
					uf_union(root, buf[t].u, buf[t].v);
					continue;
				}
				cnt[root[buf[t].u]]++;
				seen[buf[t].u >> 6] |= 1ull << (buf[t].u & 63);
				seen[buf[t].v >> 6] |= 1ull << (buf[t].v & 63);
			}
		}
		if (pass == 0)
			for (uint64_t i = 0; i < nl; i++) root[i] = uf_find(root, i);
	}
	if (err) goto out;
	for (uint64_t i = 0; i < nl; i++)
		if (seen[i >> 6] >> (i & 63) & 1) ncnt[root[i]]++;
	/* what is left beside this function's arrays and the caller's
	 * (LNODE_BYTES per node), a group's graph within its share of it
	 * (budget.h) */
	uint64_t fixed = nl * LNODE_BYTES + nbuf * sizeof *buf,
		 left = sp->avail > fixed ? sp->avail - fixed : 0,
		 cap = left / VD_BUDGET_LOSSY_GROUP_DIV, big = 0, bige = 0;
	for (uint64_t i = 0; i < nl; i++)
		if (cnt[i] && graph_need(cnt[i], ncnt[i], 0) > big) {
			big = graph_need(cnt[i], ncnt[i], 0);
			bige = cnt[i];
		}
	if (big > cap) {
		err = vd_fail(VD_ERR_BUDGET, "the similarity graph of level %d "
			      "(%" PRIu64 " candidates, %" PRIu64 " edges) needs "
			      "about %" PRIu64 " MiB for its largest component "
			      "(%" PRIu64 " edges), over the %" PRIu64 " MiB "
			      "left of the budget of %" PRIu64 " MiB beside the %"
			      PRIu64 " MiB in use (--mem-budget)", l,
			      ls->candidates, sp->n, (big + fixed) >> 20,
			      bige, sp->avail >> 20, o->mem_budget >> 20,
			      sp->base >> 20);
		goto out;
	}
	/* cnt[root] becomes the component's group */
	uint64_t acc = 0;
	for (uint64_t r = 0; r < nl; r++) {
		if (!cnt[r]) continue;
		uint64_t need = graph_need(cnt[r], ncnt[r], 0);
		if (!nb || acc + need > cap) {
			if (nb == bcap) {
				bcap = bcap ? 2 * bcap : 16;
				void *p = realloc(bsz, bcap * 8);
				if (!p) {
					err = NOMEM();
					goto out;
				}
				bsz = p;
			}
			bsz[nb++] = 0;
			acc = 0;
		}
		acc += need;
		bsz[nb - 1] += cnt[r];
		cnt[r] = nb - 1;
	}
	ls->spill_buckets = nb;
	for (uint64_t b = 0; b < nb && !err; b++) {
		e = malloc(bsz[b] * sizeof *e);
		if (!e) {
			err = NOMEM();
			break;
		}
		size_t ne = 0;
		for (uint64_t at = 0; at < sp->n && !err; at += SPILL_READ) {
			size_t k = sp->n - at < SPILL_READ ? (size_t)(sp->n - at) : SPILL_READ;
			if ((err = spill_read(sp->fd, buf, k * sizeof *buf,
					     at * sizeof *buf)))
				break;
			for (size_t t = 0; t < k; t++)
				if (cnt[root[buf[t].u]] == b && ne < bsz[b])
					e[ne++] = buf[t];
		}
		if (!err && ne != bsz[b])
			err = vd_fail(VD_ERR_INTERNAL, "the spill file of level "
				      "%d changed under the clustering", l);
		if (!err) err = edges_sort(e, ne, nl);
		if (!err) {
			uint64_t eb = ne * sizeof *e;
			err = cluster_edges(e, ne, nl, o, ls, gid, map,
					    left > eb ? left - eb : 1, eff, vox, net);
		}
		free(e);
		e = NULL;
	}
out:
	free(root);
	free(ncnt);
	free(seen);
	free(cnt);
	free(bsz);
	free(buf);
	return err;
}

/* Copies d's levels A..L-1 into orig (its other fields d's, no bricks),
 * for the final voxel difference; -1 when out of memory (orig then holds
 * what was copied, for vd_dag_release). */
static int copy_levels(struct vd_dag *orig, const struct vd_dag *d)
{
	int L = d->levels, A = d->chunk_level;
	for (int l = A; l < L; l++) {
		const struct vd_dag_level *s = &d->lv[l];
		struct vd_dag_level *t = &orig->lv[l];
		t->nodes = s->nodes;
		t->refs = s->refs;
		t->mask = malloc(s->nodes + 1);
		if (!t->mask) return -1;
		memcpy(t->mask, s->mask, s->nodes);
		if (l < L - 1) {
			t->first = malloc((s->nodes + 1) * 8);
			t->child = malloc((s->refs + 1) * 4);
			if (!t->first || !t->child) return -1;
			memcpy(t->first, s->first, (s->nodes + 1) * 8);
			memcpy(t->child, s->child, s->refs * 4);
		}
	}
	return 0;
}

/* With a memory budget, refuses level l when its arrays would not fit
 * beside what the process holds: they come before its graph's budget is
 * measured. */
static int level_fits(const struct vd_dag *d, int l,
		      const struct vd_lossy_opts *o)
{
	int err = 0;
	if (o->mem_budget) {
		/* the level's arrays come before its graph's budget
		 * is measured: they must fit beside what is held */
		malloc_trim(0);
		uint64_t rss = vd_current_rss_bytes(), need = level_need(d, l);
		if (rss + need > o->mem_budget) {
			err = vd_fail(VD_ERR_BUDGET, "the arrays of level %d "
				      "(%" PRIu64 " nodes) need about %" PRIu64
				      " MiB beside the %" PRIu64 " MiB in use, "
				      "over the budget of %" PRIu64 " MiB "
				      "(--mem-budget)", l, d->lv[l].nodes,
				      need >> 20, rss >> 20, o->mem_budget >> 20);
			return err;
		}
	}
	return err;
}

/* Clusters level l: its effective references, the graph of similar
 * nodes (in memory or spilled), the groups merged into representatives
 * (map: node to its representative), the level above pointed at them and
 * deduplicated; adds the level's stats to st and the voxel count change
 * to *net. */
static int cluster_level(struct vd_dag *d, int l, const struct vd_lossy_opts *o,
			 struct vd_lossy_stats *st, int64_t *net)
{
	int L = d->levels, A = d->chunk_level, err = 0;
	struct vd_lossy_level_stats *ls = &st->level[st->n_levels++];
	ls->level = l;
	ls->height = L - l;
	ls->nodes_before = dag_nodes(d);
	ls->level_nodes_before = d->lv[l].nodes;
	double t0 = vd_seconds();
	uint64_t *eff[VD_MAX_LEVELS];
	if ((err = level_fits(d, l, o))) return err;
	if ((err = vd_lossy_effective_refs(d, l, eff))) return err;
	double t1 = vd_seconds();
	st->seconds_eff += t1 - t0;
	struct vd_lossy_edge *e = NULL;
	size_t ne = 0;
	struct spill sp;
	uint64_t *vox = NULL;
	err = similar_pairs(d, l, eff[l], o->max_refs, o->diff_factor,
			    o->threads, o->mem_budget, &e, &ne,
			    &ls->candidates, o->graph_budget, &sp);
	/* eff[l] stays for the representatives, and their voxel
	 * counts come now: made during the search, they stayed
	 * between the heap's freed arrays, and the graph's sort
	 * then took new memory (the dragon at 2^12 peaked 25 MiB
	 * higher) */
	for (int k = 0; k < VD_MAX_LEVELS; k++)
		if (k != l) free(eff[k]);
	if (!err && (sp.fd >= 0 ? sp.n : ne))
		err = level_voxels(d, l, &vox);
	if (err) {
		free(eff[l]);
		free(e);
		if (sp.fd >= 0) close(sp.fd);
		return err;
	}
	double t2 = vd_seconds();
	st->seconds_graph += t2 - t1;
	ls->edges = sp.fd >= 0 ? sp.n : ne;
	if (!ls->edges) {
		free(eff[l]);
		free(vox);
		free(e);
		ls->nodes_after = ls->nodes_before;
		ls->level_nodes_after = d->lv[l].nodes;
		return 0;
	}
	uint64_t nl = d->lv[l].nodes;
	uint32_t *gid = malloc(nl * 4), *map = malloc(nl * 4);
	if (!gid || !map) {
		err = NOMEM();
	} else {
		for (uint64_t i = 0; i < nl; i++) {
			map[i] = (uint32_t)i;
			gid[i] = NONE;
		}
		if (sp.fd >= 0) {
			ls->graph_spilled = 1;
			err = cluster_spilled(l, nl, &sp, o, ls, gid, map,
					      eff[l], vox, net);
		} else {
			/* what is left beside the edges, the two
			 * arrays above and the voxel counts */
			uint64_t hold = ne * sizeof *e + nl * 16;
			err = cluster_edges(e, ne, nl, o, ls, gid, map,
					    sp.avail > hold ? sp.avail - hold :
					    sp.avail ? 1 : 0, eff[l], vox, net);
		}
	}
	if (sp.fd >= 0) close(sp.fd);
	free(e);
	free(gid);
	free(eff[l]);
	free(vox);
	double t3 = vd_seconds();
	st->seconds_cluster += t3 - t2;
	if (!err && l > A) {
		struct vd_dag_level *pv = &d->lv[l - 1];
		for (uint64_t j = 0; j < pv->refs; j++)
			pv->child[j] = map[pv->child[j]];
		err = dag_dedupe_up(d, l - 1);
	}
	st->seconds_reduce += vd_seconds() - t3;
	free(map);
	ls->nodes_after = dag_nodes(d);
	ls->level_nodes_after = d->lv[l].nodes;
	return err;
}

/* The voxels the clustering cleared and set: d against orig, the tables
 * of pairs within what the budget leaves; d->voxels becomes the new
 * count. */
static int diff_levels(const struct vd_dag *orig, struct vd_dag *d,
		       const struct vd_lossy_opts *o, struct vd_lossy_stats *st)
{
	int err;
	double t0 = vd_seconds();
	/* the difference's tables of pairs get what the budget leaves
	 * beside the process and the voxel counts of both DAGs */
	uint64_t memo_limit = 0;
	if (o->mem_budget) {
		malloc_trim(0);
		uint64_t hold = vd_current_rss_bytes() +
				8 * (st->nodes_before + dag_nodes(d) + 2 * VD_MAX_LEVELS);
		/* and a margin for the heap's own overhead */
		hold += VD_BUDGET_LOSSY_HEAP_MARGIN_BYTES +
			o->mem_budget / VD_BUDGET_LOSSY_HEAP_MARGIN_DIV;
		memo_limit = o->mem_budget > hold ? o->mem_budget - hold : 1;
	}
	err = dag_diff(orig, d, &st->voxels_cleared, &st->voxels_set,
		       &st->voxels_after, memo_limit);
	d->voxels = st->voxels_after;
	st->seconds_diff = vd_seconds() - t0;
	return err;
}

int vd_lossy_cluster(struct vd_dag *d, const struct vd_lossy_opts *o,
		     struct vd_lossy_stats *st)
{
	int L = d->levels, A = d->chunk_level, err = 0;
	memset(st, 0, sizeof *st);
	if (d->kind != VD_KIND_DAG)
		return vd_fail(VD_ERR_WRONG_KIND, "lossy clustering needs a dag "
			       "(SVDAG) chunk, not %s", vd_chunk_kind_name(d->kind));
	if (!(o->inflation > 1.0) || !(o->inflation <= 100.0))
		return vd_fail(VD_ERR_ARG, "inflation %g is not in (1, 100]",
			       o->inflation);
	if (!(o->diff_factor >= 0) || !(o->diff_factor <= 1e6))
		return vd_fail(VD_ERR_ARG, "diff factor %g is not in [0, 1e6]",
			       o->diff_factor);
	struct vd_dag orig = {0};
	/* a copy of the input for the final voxel difference */
	orig = *d;
	memset(orig.lv, 0, sizeof orig.lv);
	orig.bricks = NULL;
	if (copy_levels(&orig, d)) goto nomem;
	st->nodes_before = dag_nodes(d);
	st->voxels_before = d->voxels;
	double cpu0 = vd_cpu_seconds();
	int64_t net = 0; /* the voxel count change so far */
	for (int l = L - 2; l >= A && !err; l--)
		err = cluster_level(d, l, o, st, &net);
	st->cpu_seconds_lossy = vd_cpu_seconds() - cpu0;
	if (!err) err = rebuild_bricks(d);
	if (!err) err = diff_levels(&orig, d, o, st);
	st->nodes_after = dag_nodes(d);
	vd_dag_release(&orig);
	return err;
nomem:
	vd_dag_release(&orig);
	return NOMEM();
}

/* ------------------------------------------------------- voxel difference */

/* Pairs (node of a, node of b) already counted, per level, with their
 * counts: an open-addressing table. */
struct pmemo {
	uint64_t *key;   /* a << 32 | b, UINT64_MAX empty */
	uint64_t *only;  /* [2*s]: only in a, only in b */
	uint64_t cap, n;
};

struct differ {
	const struct vd_dag *a, *b;
	uint64_t *vox[2][VD_MAX_LEVELS]; /* voxels under each node */
	struct pmemo memo[VD_MAX_LEVELS];
	int err;
	/* the tables' bytes, and their limit (0: none): the tables only
	 * save walking a pair of subtrees twice, so a full table stops
	 * growing and later pairs are walked each time they occur */
	uint64_t memo_bytes, memo_limit;
};

#define MEMO_SLOT_BYTES 24

/* 0: grown; -1: at its limit (left as it is); else an error */
/* The tables are mapped, not taken from the heap: the heap kept the
 * holes of the outgrown tables of the levels, growing in turn, and the
 * RSS passed the tables' bytes by half. */
static void *memo_map(uint64_t bytes)
{
	void *p = mmap(NULL, bytes, PROT_READ | PROT_WRITE,
		       MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
	return p == MAP_FAILED ? NULL : p;
}

static void memo_unmap(void *p, uint64_t bytes)
{
	if (p) munmap(p, bytes);
}

static int memo_grow(struct differ *x, struct pmemo *m)
{
	uint64_t nc = m->cap ? m->cap * 2 : 1024;
	/* the old table and the new one at once */
	if (x->memo_limit && x->memo_bytes + nc * MEMO_SLOT_BYTES > x->memo_limit)
		return -1;
	uint64_t *k = memo_map(nc * 8), *o = memo_map(nc * 16);
	if (!k || !o) {
		memo_unmap(k, nc * 8);
		memo_unmap(o, nc * 16);
		return NOMEM();
	}
	memset(k, 0xff, nc * 8);
	for (uint64_t i = 0; i < m->cap; i++) {
		if (m->key[i] == UINT64_MAX) continue;
		uint64_t s = vd_mix64(m->key[i]) & (nc - 1);
		while (k[s] != UINT64_MAX) s = (s + 1) & (nc - 1);
		k[s] = m->key[i];
		o[2 * s] = m->only[2 * i];
		o[2 * s + 1] = m->only[2 * i + 1];
	}
	memo_unmap(m->key, m->cap * 8);
	memo_unmap(m->only, m->cap * 16);
	x->memo_bytes += (nc - m->cap) * MEMO_SLOT_BYTES;
	m->key = k;
	m->only = o;
	m->cap = nc;
	return 0;
}

static void diff_node(struct differ *x, int l, uint32_t na, uint32_t nb,
		      uint64_t *oa, uint64_t *ob)
{
	const struct vd_dag *a = x->a, *b = x->b;
	int L = a->levels;
	*oa = *ob = 0;
	if (x->err) return;
	if (l == L - 1) {
		*oa = (uint64_t)__builtin_popcount(a->lv[l].mask[na] & ~b->lv[l].mask[nb]);
		*ob = (uint64_t)__builtin_popcount(b->lv[l].mask[nb] & ~a->lv[l].mask[na]);
		return;
	}
	struct pmemo *m = &x->memo[l];
	uint64_t key = (uint64_t)na << 32 | nb;
	if (m->cap) {
		uint64_t s = vd_mix64(key) & (m->cap - 1);
		while (m->key[s] != UINT64_MAX) {
			if (m->key[s] == key) {
				*oa = m->only[2 * s];
				*ob = m->only[2 * s + 1];
				return;
			}
			s = (s + 1) & (m->cap - 1);
		}
	}
	const struct vd_dag_level *la = &a->lv[l], *lb = &b->lv[l];
	unsigned ma = la->mask[na], mb = lb->mask[nb];
	uint64_t ja = la->first[na], jb = lb->first[nb];
	for (unsigned s = 0; s < 8; s++) {
		int ia = ma >> s & 1, ib = mb >> s & 1;
		if (ia && ib) {
			uint64_t ca, cb;
			diff_node(x, l + 1, la->child[ja++], lb->child[jb++], &ca, &cb);
			*oa += ca;
			*ob += cb;
		} else if (ia) {
			*oa += x->vox[0][l + 1][la->child[ja++]];
		} else if (ib) {
			*ob += x->vox[1][l + 1][lb->child[jb++]];
		}
	}
	if (x->err) return;
	if (2 * (m->n + 1) > m->cap) {
		int g = memo_grow(x, m);
		if (g < 0) return; /* full: not remembered */
		if (g) {
			x->err = g;
			return;
		}
	}
	uint64_t s = vd_mix64(key) & (m->cap - 1);
	while (m->key[s] != UINT64_MAX) s = (s + 1) & (m->cap - 1);
	m->key[s] = key;
	m->only[2 * s] = *oa;
	m->only[2 * s + 1] = *ob;
	m->n++;
}

/* vd_dag_diff() with its tables of pairs within memo_limit bytes (0: no
 * limit); the voxel counts per node (8 bytes per node of each) come
 * first. */
static int dag_diff(const struct vd_dag *a, const struct vd_dag *b,
		    uint64_t *only_a, uint64_t *only_b, uint64_t *voxels_b,
		    uint64_t memo_limit)
{
	int L = a->levels, A = a->chunk_level;
	if (a->kind != VD_KIND_DAG || b->kind != VD_KIND_DAG)
		return vd_fail(VD_ERR_WRONG_KIND, "the voxel difference needs "
			       "two dag (SVDAG) chunks");
	if (b->levels != L || b->chunk_level != A ||
	    b->cell_morton != a->cell_morton)
		return vd_fail(VD_ERR_MISMATCH, "the chunks are of different "
			       "cells or depths");
	struct differ x = {a, b, {{0}}, {{0}}, 0, 0, memo_limit};
	int err = 0;
	const struct vd_dag *ds[2] = {a, b};
	for (int s = 0; s < 2 && !err; s++)
		for (int l = L - 1; l >= A; l--) {
			const struct vd_dag_level *lv = &ds[s]->lv[l];
			uint64_t *v = x.vox[s][l] = malloc((lv->nodes + 1) * 8);
			if (!v) {
				err = NOMEM();
				break;
			}
			for (uint64_t i = 0; i < lv->nodes; i++) {
				if (l == L - 1) {
					v[i] = (uint64_t)__builtin_popcount(lv->mask[i]);
					continue;
				}
				v[i] = 0;
				for (uint64_t j = lv->first[i]; j < lv->first[i + 1]; j++)
					v[i] += x.vox[s][l + 1][lv->child[j]];
			}
		}
	if (!err) {
		uint64_t va = a->lv[A].nodes ? x.vox[0][A][0] : 0,
			 vb = b->lv[A].nodes ? x.vox[1][A][0] : 0;
		*voxels_b = vb;
		if (!a->lv[A].nodes || !b->lv[A].nodes) {
			*only_a = va;
			*only_b = vb;
		} else {
			diff_node(&x, A, 0, 0, only_a, only_b);
			err = x.err;
		}
	}
	for (int s = 0; s < 2; s++)
		for (int l = 0; l < VD_MAX_LEVELS; l++) free(x.vox[s][l]);
	for (int l = 0; l < VD_MAX_LEVELS; l++) {
		memo_unmap(x.memo[l].key, x.memo[l].cap * 8);
		memo_unmap(x.memo[l].only, x.memo[l].cap * 16);
	}
	return err;
}

int vd_dag_diff(const struct vd_dag *a, const struct vd_dag *b,
		uint64_t *only_a, uint64_t *only_b, uint64_t *voxels_b)
{
	return dag_diff(a, b, only_a, only_b, voxels_b, 0);
}

/* ------------------------------------------------------------ stage run */

int vd_lossy_write_stats(const struct vd_dag *dag,
			 const struct vd_lossy_opts *o,
			 const struct vd_lossy_stats *st, double seconds_load,
			 double seconds_save, const char *path)
{
	struct vd_json *j;
	int err = vd_json_open(&j, path);
	if (err) return err;
	vd_json_str(j, "tool", "lossy-cluster");
	vd_json_str(j, "version", VD_VERSION_STRING);
	vd_json_str(j, "kind", vd_chunk_kind_name(dag->kind));
	vd_json_u64(j, "levels", (uint64_t)dag->levels);
	vd_json_u64(j, "chunk_level", (uint64_t)dag->chunk_level);
	vd_json_f64(j, "inflation", o->inflation);
	vd_json_f64(j, "diff_factor", o->diff_factor);
	vd_json_u64(j, "max_refs", o->max_refs);
	vd_json_u64(j, "nodes_before", st->nodes_before);
	vd_json_u64(j, "nodes_after", st->nodes_after);
	vd_json_u64(j, "voxels_before", st->voxels_before);
	vd_json_u64(j, "voxels_after", st->voxels_after);
	vd_json_u64(j, "voxels_set", st->voxels_set);
	vd_json_u64(j, "voxels_cleared", st->voxels_cleared);
	vd_json_u64(j, "voxels_changed", st->voxels_set + st->voxels_cleared);
	vd_json_f64(j, "error_rate", st->voxels_before ?
		    (double)(st->voxels_set + st->voxels_cleared) /
		    (double)st->voxels_before : 0);
	vd_json_array(j, "per_level");
	for (int i = 0; i < st->n_levels; i++) {
		const struct vd_lossy_level_stats *l = &st->level[i];
		vd_json_object(j, NULL);
		vd_json_u64(j, "level", (uint64_t)l->level);
		vd_json_u64(j, "height", (uint64_t)l->height);
		vd_json_u64(j, "candidates", l->candidates);
		vd_json_u64(j, "graph_nodes", l->graph_nodes);
		vd_json_u64(j, "edges", l->edges);
		vd_json_u64(j, "graph_spilled", (uint64_t)l->graph_spilled);
		vd_json_u64(j, "spill_buckets", l->spill_buckets);
		vd_json_u64(j, "clusters", l->clusters);
		vd_json_u64(j, "merged", l->merged);
		vd_json_u64(j, "level_nodes_before", l->level_nodes_before);
		vd_json_u64(j, "level_nodes_after", l->level_nodes_after);
		vd_json_u64(j, "nodes_before", l->nodes_before);
		vd_json_u64(j, "nodes_after", l->nodes_after);
		vd_json_end_object(j);
	}
	vd_json_end_array(j);
	vd_json_f64(j, "seconds_load", seconds_load);
	vd_json_f64(j, "seconds_cut", st->seconds_cut);
	vd_json_f64(j, "seconds_effective_refs", st->seconds_eff);
	vd_json_f64(j, "seconds_graph", st->seconds_graph);
	vd_json_f64(j, "seconds_clustering", st->seconds_cluster);
	vd_json_f64(j, "seconds_reduction", st->seconds_reduce);
	vd_json_f64(j, "seconds_diff", st->seconds_diff);
	vd_json_f64(j, "seconds_lossy", st->seconds_eff + st->seconds_graph +
		    st->seconds_cluster + st->seconds_reduce);
	vd_json_f64(j, "cpu_seconds_lossy", st->cpu_seconds_lossy);
	vd_json_f64(j, "seconds_save", seconds_save);
	vd_json_u64(j, "peak_rss_bytes", vd_peak_rss_bytes());
	vd_json_f64(j, "process_cpu_seconds", vd_cpu_seconds());
	return vd_json_close(j);
}

/* The least memory of a clustering run, its similarity graphs and their
 * clustering aside (each level's graph gets what is left and spills or
 * names what it needs; the final difference's tables of pairs are
 * optional): the DAG twice (the working copy and the original, for the
 * final difference: a mask byte and an offset per node, 4 bytes per
 * reference) and the libraries; once loaded (d not NULL) also the
 * largest level's arrays (level_need) and the final difference's voxel
 * counts (8 bytes per node of each DAG). */
static uint64_t lossy_need(uint64_t nodes, uint64_t refs, const struct vd_dag *d)
{
	uint64_t n = 2 * (9 * nodes + 4 * refs) + VD_DAG_ESTIMATE_FIXED_BYTES, most = 0;
	if (!d) return n;
	for (int l = d->chunk_level; l <= d->levels - 2; l++)
		if (level_need(d, l) > most) most = level_need(d, l);
	return n + most + 16 * nodes;
}

int vd_lossy_run(const char *in, const char *out,
		 const struct vd_lossy_opts *o, uint64_t mem_budget,
		 const char *provenance, int quiet)
{
	struct vd_dag d = {0};
	struct vd_chunk_header h;
	struct vd_chunk *c = NULL;
	double t0 = vd_seconds();
	int err = vd_chunk_open(&c, in, VD_KIND_ANY);
	if (!err && vd_chunk_header(c)->kind != VD_KIND_DAG)
		err = vd_fail(VD_ERR_WRONG_KIND, "a %s chunk, not dag (the "
			      "clustering works on the plain SVDAG)",
			      vd_chunk_kind_name(vd_chunk_header(c)->kind));
	if (err) {
		vd_chunk_free(c);
		return vd_fail(err, "cannot read '%s': %s: %s", in,
			       vd_strerror(err), vd_error_detail());
	}
	h = *vd_chunk_header(c);
	/* before loading, with the fewest references the node counts allow
	 * (every node below the root has a parent) */
	uint64_t hn = 0, hr = 0;
	for (uint32_t i = 0; i + 1 < h.level_count; i++) {
		hn += h.level_nodes[i];
		if (i > 0) hr += h.level_nodes[i];
	}
	uint64_t est = lossy_need(hn, hr, NULL);
	if (mem_budget && est > mem_budget) {
		vd_chunk_free(c);
		return vd_fail(VD_ERR_BUDGET, "cannot cluster '%s': needs at least "
			       "%" PRIu64 " MiB, over the budget of %" PRIu64
			       " MiB (--mem-budget)", in, est >> 20, mem_budget >> 20);
	}
	err = vd_dag_from_chunk(&d, c, VD_KIND_DAG);
	vd_chunk_free(c);
	if (err) {
		vd_dag_release(&d);
		return vd_fail(err, "cannot read '%s': %s: %s", in,
			       vd_strerror(err), vd_error_detail());
	}
	double t_cut = 0;
	if (!err && o->levels && o->levels != d.levels) {
		/* a lower resolution of the same scene (the paper's tables
		 * per resolution): the DAG cut at that depth, reduced */
		double tc = vd_seconds();
		struct vd_dag cut;
		if (d.chunk_level != 0 || o->levels > d.levels)
			err = d.chunk_level ?
			      vd_fail(VD_ERR_ARG, "it is not a root chunk") :
			      vd_fail(VD_ERR_ARG, "it has only %d levels", d.levels);
		else
			err = vd_dag_cut(&d, o->levels, NULL, &cut);
		if (err) {
			vd_dag_release(&d);
			return vd_fail(err, "cannot cut '%s' at %d levels: %s",
				       in, o->levels, vd_error_detail());
		}
		vd_dag_release(&d);
		d = cut;
		/* the same cube, coarser voxels */
		h.transform.voxel_size *= (double)(1ull << (h.levels - o->levels));
		t_cut = vd_seconds() - tc;
	}
	uint64_t refs = 0;
	for (int l = d.chunk_level; l < d.levels - 1; l++) refs += d.lv[l].refs;
	est = lossy_need(dag_nodes(&d), refs, &d);
	if (mem_budget && est > mem_budget) {
		vd_dag_release(&d);
		return vd_fail(VD_ERR_BUDGET, "cannot cluster '%s': needs about "
			       "%" PRIu64 " MiB, over the budget of %" PRIu64
			       " MiB (--mem-budget)", in, est >> 20, mem_budget >> 20);
	}
	double t_load = vd_seconds() - t0;
	struct vd_lossy_stats st;
	struct vd_lossy_opts ob = *o;
	if (!ob.mem_budget) ob.mem_budget = mem_budget;
	if ((err = vd_lossy_cluster(&d, &ob, &st))) {
		vd_dag_release(&d);
		return vd_fail(err, "cannot cluster '%s': %s: %s", in,
			       vd_strerror(err), vd_error_detail());
	}
	st.seconds_cut = t_cut;
	/* the chunk and its statistics replace the previous pair together */
	size_t plen = strlen(out) + 64;
	char *sp = malloc(3 * plen);
	if (!sp) {
		vd_dag_release(&d);
		return NOMEM();
	}
	char *staged = sp + plen, *staged_sp = sp + 2 * plen;
	snprintf(sp, plen, "%s.stats.json", out);
	err = vd_stage_name(out, staged, plen);
	if (!err) err = vd_stage_name(sp, staged_sp, plen);
	double t1 = vd_seconds();
	if (!err) err = vd_dag_save(&d, &h.transform, staged, provenance);
	double t_save = vd_seconds() - t1;
	if (!err) err = vd_lossy_write_stats(&d, o, &st, t_load, t_save, staged_sp);
	if (!err) err = vd_publish_pair(staged, out, staged_sp, sp);
	if (err) {
		unlink(staged);
		err = vd_fail(err, "cannot write '%s': %s: %s", out,
			      vd_strerror(err), vd_error_detail());
	} else if (!quiet) {
		fprintf(stderr, "lossy-cluster: wrote '%s': %" PRIu64 " -> %"
			PRIu64 " nodes (%.1f%%), %" PRIu64 " voxels changed "
			"(%.3f%%), %.3f s lossy, %.3f s total\n", out,
			st.nodes_before, st.nodes_after,
			st.nodes_before ? 100.0 * ((double)st.nodes_after -
						   (double)st.nodes_before) /
				(double)st.nodes_before : 0,
			st.voxels_set + st.voxels_cleared,
			st.voxels_before ? 100.0 * (double)(st.voxels_set +
				st.voxels_cleared) / (double)st.voxels_before : 0,
			st.seconds_eff + st.seconds_graph + st.seconds_cluster +
				st.seconds_reduce, vd_seconds() - t0);
	}
	free(sp);
	vd_dag_release(&d);
	return err;
}
