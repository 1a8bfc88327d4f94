/* voxelize.c - out-of-core surface voxelization of a triangle mesh into SVO
 * chunks, one per non-empty cell of the chunk level L0.
 *
 * Passes over the mesh:
 *   1. bounds: the tight bounding box fixes the grid;
 *   2. estimate (only when L0 is chosen automatically): an upper bound of
 *      each cell's in-core memory at every candidate level; without
 *      colours, when the reader has every vertex before any face (PLY),
 *      passes 1 and 2 are one on the grid of the vertices' bounds, made
 *      again when the triangles' bounds turn out other (guess_grid);
 *   3. binning: every triangle is appended to the bin file of each cell it
 *      overlaps (bounded in-memory buffers, flushed to disk), snapped and
 *      packed (struct bin_rec); a cell that all the threads will rasterize
 *      together is binned by octant, so each reads only its own;
 * then each cell's bin is rasterized in core, in parallel, and written as
 * one SVO chunk. The driver at the end of this file runs them as passes,
 * each a function saying what it does and what memory it may use:
 * read_bounds, estimate_cells, choose_chunk_level, bin_triangles, then
 * list_cells, start_workers, voxelize_cells, finish_result. The first pass keeps the triangles in memory when they fit
 * in a sixteenth of the budget, and the later passes replay them instead of
 * reading the file again (the budget's shares: budget.h); with one cell (L0 = 0) and no colours, that copy
 * is the cell's bin and no bin file is written.
 *
 * In core, a cell is a hash map of 32^3-voxel blocks allocated when a
 * triangle first touches them, each 512 bricks in Morton order, so memory
 * follows the surface area, not the cell's volume. Emitting the chunk is a
 * walk over the blocks in key order, which is Morton order of the bricks.
 *
 * Colours (only when asked for and the mesh has them; the geometry path
 * never sees them): triangles are binned with their vd_tri_attr and their
 * input index, and each flush sorts by (cell, index), so a bin lists its
 * triangles in input order. Once a cell's voxels are known, the bin is read
 * a second time: every triangle is rasterized again with the same exact
 * overlap test, and each voxel it overlaps keeps the colour of the
 * triangle's point nearest to the voxel's centre if that point is strictly
 * nearer than the voxel's best so far, so ties go to the earlier triangle
 * (schemas/colour-rule.md). A voxel's slot is its rank in the cell's Morton
 * order (prefix popcounts per block), so the colours come out in the order
 * the colour chunk stores them, 8 bytes per voxel while they are built.
 */
#include "voxdag.h"
#include "util_internal.h"
#include "budget.h"
#include "le.h"
#include "voxel/voxel_internal.h"

#include <dirent.h>
#include <errno.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <math.h>
#include <xxhash.h>

enum {
	BLOCK_SHIFT = 5,                  /* blocks of 32^3 voxels */
	BLOCK_WORDS = 512,                /* 8^3 bricks */
	BLOCK_BYTES = BLOCK_WORDS * 8,
	BLOCK_COST = BLOCK_BYTES + 48,    /* with malloc and map overhead */
	MAX_CHUNK_LEVEL = 7,              /* 2M cells: per-cell arrays stay small */
	TRI_BATCH = 16384,
	RASTER_BATCH = 65536,             /* raster_bin's: indices of 16 bits */
	/* Blocks are allocated in slabs: one calloc per 64 blocks, not one
	 * per block (a block allocation cost as much as rasterizing it);
	 * pages of a slab not yet used stay unmapped, so memory still
	 * follows the blocks in use. Past SMALL_SLABS of them (8 MiB), a
	 * slab is mapped and made whole at once: see slab_alloc. */
	SLAB_BLOCKS = 64,
	SMALL_SLABS = 32,
	MAP_RECENT = 512,                 /* block_map's recent[] */
	WORKER_OVERHEAD = 8 << 20,        /* zstd, batches, stack */
	/* With colours, a block's share also pays for its voxels' colour
	 * slots (8 bytes each) and rank tables, planned for 2048 voxels a
	 * block (one surface crossing a 32^3 block sets about 1000-2500;
	 * planning for the worst, 32768, would make cells tiny and runs slow);
	 * a cell with more is caught exactly after its geometry pass and
	 * stops with a budget error naming it. */
	COLOUR_BLOCK_COST = 2048 * 8 + 512 * 2 + 16,
};

/* ------------------------------------------------------------ progress */

struct progress {
	int quiet;
	const char *tool;
	double start, last;
	pthread_mutex_t lock;
};

static void progress_say(struct progress *p, int force, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));

static void progress_say(struct progress *p, int force, const char *fmt, ...)
{
	if (p->quiet)
		return;
	double now = vd_seconds();
	pthread_mutex_lock(&p->lock);
	if (force || now - p->last >= 1.0) {
		p->last = now;
		va_list ap;
		va_start(ap, fmt);
		fprintf(stderr, "%s: [%6.1fs] ", p->tool, now - p->start);
		vfprintf(stderr, fmt, ap);
		fputc('\n', stderr);
		va_end(ap);
	}
	pthread_mutex_unlock(&p->lock);
}

/* A reader's warning: always shown (also with --quiet), one line. */
static void warn_line(void *ctx, const char *line)
{
	struct progress *p = ctx;
	pthread_mutex_lock(&p->lock);
	fprintf(stderr, "%s: warning: %s\n", p->tool, line);
	pthread_mutex_unlock(&p->lock);
}

/* ------------------------------------------------------- mesh streaming */

/* The triangles of the first pass, kept for the passes after it when
 * they fit in `limit` bytes: each pass would otherwise read and decode the
 * whole file again (three passes: bounds, estimate, bins). Attributes
 * (colours) are not kept: a pass that needs them reads the file. */
struct tri_cache {
	struct vd_triangle *t;
	size_t n, cap;
	uint64_t limit;
	int state;             /* 0: first pass to come, 1: whole, -1: unused */
};

uint64_t vd_tri_cache_max = UINT64_MAX;

static void tri_cache_drop(struct tri_cache *c)
{
	free(c->t);
	c->t = NULL;
	c->n = c->cap = 0;
	c->state = -1;
}

static void tri_cache_add(struct tri_cache *c, const struct vd_triangle *t,
			  size_t n)
{
	if (c->n + n > c->cap) {
		size_t cap = c->cap ? 2 * c->cap : TRI_BATCH;
		while (cap < c->n + n)
			cap *= 2;
		if ((uint64_t)cap * sizeof *t > c->limit)
			cap = (size_t)(c->limit / sizeof *t);
		void *q = cap >= c->n + n ? realloc(c->t, cap * sizeof *t) : NULL;
		if (!q) {
			tri_cache_drop(c);
			return;
		}
		c->t = q;
		c->cap = cap;
	}
	memcpy(c->t + c->n, t, n * sizeof *t);
	c->n += n;
}

/* With more than one thread and a budget of FEED_MIN_BUDGET or more, a
 * pass that reads no attributes (all but binning with colours) reads the
 * mesh on a thread of its own, a batch ahead of the one that works on it
 * (estimate, bins): decoding a large file is as much work as the pass.
 * The batches are handed on in the file's order, so a pass sees what it
 * sees on one thread. d->tris then holds FEED_SLOTS batches, allocated
 * before the first pass, so the plan's `base` has them; a smaller budget
 * keeps the one batch it had (its cells' share decides its chunk level,
 * and so its bytes). */
enum { FEED_SLOTS = 2 };
#define FEED_MIN_BUDGET ((uint64_t)256 << 20)

struct feed {
	struct vd_mesh *m;
	struct vd_triangle *buf;     /* FEED_SLOTS batches of TRI_BATCH */
	struct vd_tri_attr *attr;    /* the same, or NULL */
	size_t n[FEED_SLOTS];
	uint64_t made, used;         /* batches read, batches worked on */
	int done, stop, err;
	char detail[512];
	pthread_mutex_t lock;
	pthread_cond_t cond;
};

static void *feed_main(void *arg)
{
	struct feed *f = arg;
	for (;;) {
		pthread_mutex_lock(&f->lock);
		while (f->made - f->used == FEED_SLOTS && !f->stop)
			pthread_cond_wait(&f->cond, &f->lock);
		int stop = f->stop;
		size_t s = (size_t)(f->made % FEED_SLOTS);
		pthread_mutex_unlock(&f->lock);
		if (stop)
			break;
		size_t n = 0;
		struct vd_triangle *t = f->buf + s * TRI_BATCH;
		int err = f->attr ? vd_mesh_read_attr(f->m, t, f->attr +
						      s * TRI_BATCH, TRI_BATCH, &n)
				  : vd_mesh_read(f->m, t, TRI_BATCH, &n);
		pthread_mutex_lock(&f->lock);
		if (err) {
			f->err = err;
			snprintf(f->detail, sizeof f->detail, "%s",
				 vd_error_detail());
		}
		if (err || n == 0) {
			f->done = 1;
		} else {
			f->n[s] = n;
			f->made++;
		}
		pthread_cond_broadcast(&f->cond);
		pthread_mutex_unlock(&f->lock);
		if (err || n == 0)
			break;
	}
	return NULL;
}

/* Reads the mesh once (or its triangles from the cache), calling fn for
 * each batch of triangles; with `attr` (colours), their attributes too.
 * With `threads` > 1 (then `buf` holds FEED_SLOTS batches) and no `attr`,
 * the mesh is read on a thread of its own (struct feed). */
static int for_each_batch(struct vd_mesh *m, struct tri_cache *c,
			  struct vd_triangle *buf, struct vd_tri_attr *attr,
			  int threads,
			  int (*fn)(void *ctx, const struct vd_triangle *t,
				    const struct vd_tri_attr *a, size_t n),
			  void *ctx)
{
	int err = VD_OK;
	if (!attr && c->state == 1) {
		for (size_t i = 0; i < c->n && !err; i += TRI_BATCH)
			err = fn(ctx, c->t + i, NULL,
				 c->n - i < TRI_BATCH ? c->n - i : TRI_BATCH);
		return err;
	}
	int fill = !attr && c->state == 0;
	err = vd_mesh_rewind(m);
	struct feed f = {.m = m, .buf = buf, .attr = attr,
			 .lock = PTHREAD_MUTEX_INITIALIZER,
			 .cond = PTHREAD_COND_INITIALIZER};
	pthread_t th;
	int feeding = !err && threads > 1 && !attr &&
		      pthread_create(&th, NULL, feed_main, &f) == 0;
	while (!err) {
		size_t n;
		struct vd_triangle *t = buf;
		struct vd_tri_attr *a = attr;
		if (feeding) {
			pthread_mutex_lock(&f.lock);
			while (f.made == f.used && !f.done)
				pthread_cond_wait(&f.cond, &f.lock);
			size_t s = (size_t)(f.used % FEED_SLOTS);
			n = f.made == f.used ? 0 : f.n[s];
			pthread_mutex_unlock(&f.lock);
			t = buf + s * TRI_BATCH;
			a = attr ? attr + s * TRI_BATCH : NULL;
		} else {
			err = attr ? vd_mesh_read_attr(m, buf, attr, TRI_BATCH, &n)
				   : vd_mesh_read(m, buf, TRI_BATCH, &n);
		}
		if (err || n == 0)
			break;
		if (fill && c->state == 0)
			tri_cache_add(c, t, n);
		err = fn(ctx, t, a, n);
		if (feeding) {
			pthread_mutex_lock(&f.lock);
			f.used++;
			pthread_cond_broadcast(&f.cond);
			pthread_mutex_unlock(&f.lock);
		}
	}
	if (feeding) {
		pthread_mutex_lock(&f.lock);
		f.stop = 1;
		pthread_cond_broadcast(&f.cond);
		pthread_mutex_unlock(&f.lock);
		pthread_join(th, NULL);
		if (!err && f.err)
			err = vd_fail(f.err, "%s", f.detail);
	}
	if (fill && c->state == 0)
		c->state = err ? -1 : 1;
	if (c->state < 0)
		tri_cache_drop(c);
	return err;
}

struct bounds {
	float lo[3], hi[3];
	uint64_t n;
};

static int bounds_batch(void *ctx, const struct vd_triangle *t,
			const struct vd_tri_attr *attr, size_t n)
{
	struct bounds *b = ctx;
	if (!b->n && n)
		for (int a = 0; a < 3; a++)
			b->lo[a] = b->hi[a] = t[0].v[0][a];
	/* a vd_triangle is its three corners, 3 floats each */
	vd_bounds_widen(t[0].v[0], 3 * n, 3, b->lo, b->hi);
	b->n += n;
	return VD_OK;
}

/* ------------------------------------------------- cells and estimates */

struct grid {
	int L, L0;
	struct vd_transform tr;
};

/* Inclusive voxel range of the triangle's bounding box, clipped to the
 * grid; 0 if it lies outside. */
static int tri_voxel_range(const struct vd_snapped_tri *t, int L,
			   int64_t lo[3], int64_t hi[3])
{
	const int64_t s = vd_snap_voxel(L), top = ((int64_t)1 << L) - 1;
	/* s is 2^sh: shifts of the non-negative values, not six 64-bit
	 * divisions a triangle (3% of the terrain's CPU at 2^14) */
	const int sh = VD_SNAP_ROOT_BITS - L;
#pragma GCC unroll 3
	for (int a = 0; a < 3; a++) {
		int64_t mn = t->v[0][a], mx = t->v[0][a];
		for (int k = 1; k < 3; k++) {
			mn = t->v[k][a] < mn ? t->v[k][a] : mn;
			mx = t->v[k][a] > mx ? t->v[k][a] : mx;
		}
		/* closed voxels: i touches [i*s, (i+1)*s] */
		lo[a] = (mn + s - 1 >= 0 ? (mn + s - 1) >> sh : -1) - 1;
		hi[a] = mx >= 0 ? mx >> sh : -1;
		lo[a] = lo[a] < 0 ? 0 : lo[a];
		hi[a] = hi[a] > top ? top : hi[a];
		if (lo[a] > hi[a])
			return 0;
	}
	return 1;
}

static uint64_t mix(uint64_t k)
{
	k ^= k >> 33;
	k *= 0xff51afd7ed558ccdULL;
	k ^= k >> 33;
	return k;
}

/* The memory bound: the distinct 32^3 blocks that triangles may touch.
 * Blocks are aligned with every cell of 32 voxels or more, so per-cell
 * counts partition them exactly and coarser levels just add up.
 *
 * The keys are appended to a buffer, which, when full, is sorted (radix)
 * and merged into the sorted distinct keys so far. A large triangle
 * gives its blocks in raster order, which a hash set scattered over its
 * slots: one cache miss a block, 85% of voxelize's estimate pass on the
 * Sponza at 2^16 (13.8 s of 178). Appends are sequential, and the result
 * is the sorted array the plan wants anyway.
 *
 * The keys may be at most `max_keys` (their share of the budget). When
 * the mesh touches more blocks than that, the keys are coarsened: they
 * become blocks of 2^(5+coarse) voxels (Morton key >> 3 per step), each
 * standing for at most 8^coarse real blocks. The bound stays an upper
 * bound, only looser, and the memory never grows with the mesh: the
 * sorted keys (below max_keys, plus a buffer's worth while merging), the
 * buffer and the sort's copy of it, each of at most max_keys / 2 keys:
 * 2.5 max_keys in all, against the 2-4 max_keys slots of the hash set
 * this replaced. */
struct estimate {
	struct grid g;
	uint64_t *keys;        /* sorted, distinct (coarse) block keys */
	size_t n, kcap;
	uint64_t *buf, *tmp;   /* keys added since the last merge, unsorted */
	size_t nbuf, bcap;
	int coarse;            /* extra levels of coarsening, 0: exact */
	int raster_coarse;     /* `coarse` when the current raster began */
	size_t max_keys;
	int err;
	/* keys added lately, +1 (by their low bits): consecutive triangles
	 * share most of their blocks */
	uint64_t recent[256];
};

static void estimate_free(struct estimate *e)
{
	free(e->keys);
	free(e->buf);
	free(e->tmp);
	e->keys = e->buf = e->tmp = NULL;
	e->n = e->kcap = e->nbuf = e->bcap = 0;
}

/* Drops repeats from the sorted a[0..n); returns the count left. */
static size_t unique_sorted(uint64_t *a, size_t n)
{
	size_t m = 0;
	for (size_t i = 0; i < n; i++)
		if (m == 0 || a[i] != a[m - 1])
			a[m++] = a[i];
	return m;
}

/* The buffer into the sorted keys; then, past max_keys, every key
 * replaced by its parent until they are at most half of it. */
static int estimate_merge(struct estimate *e)
{
	int bits = 3 * (e->g.L - BLOCK_SHIFT - e->coarse);
	vd_sort_keys(e->buf, e->tmp, e->nbuf, 0, bits < 0 ? 0 : bits);
	size_t m = unique_sorted(e->buf, e->nbuf);
	e->nbuf = 0;
	if (e->n + m > e->kcap) {
		/* doubled, but never past the most it can hold: below
		 * max_keys before a merge, and a buffer */
		size_t most = e->max_keys + e->max_keys / 2;
		size_t cap = e->kcap ? e->kcap : 4096;
		while (cap < e->n + m)
			cap *= 2;
		cap = cap < most ? cap : most;
		cap = cap > e->n + m ? cap : e->n + m;
		uint64_t *k = realloc(e->keys, cap * sizeof *k);
		if (!k)
			return vd_fail(VD_ERR_NOMEM, "block estimate keys");
		e->keys = k;
		e->kcap = cap;
	}
	/* merged from the back, in place: keys[0..n) and buf[0..m) */
	uint64_t *k = e->keys;
	size_t i = e->n, j = m, o = e->n + m;
	while (j > 0) {
		if (i > 0 && k[i - 1] > e->buf[j - 1])
			k[--o] = k[--i];
		else
			k[--o] = e->buf[--j];
	}
	/* o == i: what is below is already in place; repeats across the two
	 * are adjacent now */
	e->n = unique_sorted(k, e->n + m);
	if (e->n >= e->max_keys) {
		while (e->n > e->max_keys / 2 &&
		       e->g.L - BLOCK_SHIFT - e->coarse > 1) {
			e->coarse++;
			for (size_t t = 0; t < e->n; t++)
				k[t] >>= 3; /* Morton order survives */
			e->n = unique_sorted(k, e->n);
		}
		memset(e->recent, 0, sizeof e->recent); /* keys of before */
	}
	return VD_OK;
}

static int estimate_add(struct estimate *e, uint64_t key)
{
	uint64_t *rc = &e->recent[key & 255];
	if (*rc == key + 1)
		return VD_OK;
	*rc = key + 1;
	if (e->nbuf == e->bcap) {
		/* half the keys so far, at least 4096, at most max_keys / 2:
		 * merges stay linear in the keys added, and a small scene's
		 * buffer stays small (the plan measures the process's memory
		 * after this pass) */
		size_t most = e->max_keys / 2 ? e->max_keys / 2 : 1;
		size_t half = e->n / 2 > 4096 ? e->n / 2 : 4096;
		most = half < most ? half : most;
		if (e->bcap < most) {
			/* grown while the mesh is small, up to max_keys */
			size_t cap = e->bcap ? 2 * e->bcap : 4096;
			cap = cap < most ? cap : most;
			uint64_t *b = realloc(e->buf, cap * sizeof *b);
			if (b)
				e->buf = b;
			uint64_t *t = realloc(e->tmp, cap * sizeof *t);
			if (t)
				e->tmp = t;
			if (!b || !t)
				return vd_fail(VD_ERR_NOMEM, "block estimate buffer");
			e->bcap = cap;
		} else {
			int c = e->coarse;
			int err = estimate_merge(e);
			if (err)
				return err;
			key >>= 3 * (e->coarse - c); /* of the lattice before */
		}
	}
	e->buf[e->nbuf++] = key;
	return VD_OK;
}

static void add_block(void *ctx, int64_t x, int64_t y, int64_t z)
{
	struct estimate *e = ctx;
	if (e->err)
		return;
	/* the raster runs on the lattice of before a coarsening: map down */
	int d = e->coarse - e->raster_coarse;
	int err = estimate_add(e, vd_morton3((uint32_t)x, (uint32_t)y,
					     (uint32_t)z) >> 3 * d);
	if (err)
		e->err = err;
}

static int estimate_batch(void *ctx, const struct vd_triangle *t,
			  const struct vd_tri_attr *attr, size_t n)
{
	struct estimate *e = ctx;
	if (e->g.L <= BLOCK_SHIFT)
		return VD_OK; /* one block holds the whole grid */
	for (size_t i = 0; i < n; i++) {
		struct vd_snapped_tri st;
		int64_t lo[3], hi[3];
		int err = vd_snap_triangle(&st, &t[i], &e->g.tr);
		if (err)
			return err;
		if (!tri_voxel_range(&st, e->g.L, lo, hi))
			continue;
		int sh = BLOCK_SHIFT + e->coarse;
		int64_t b0[3], b1[3], nb = 1;
		for (int a = 0; a < 3; a++) {
			b0[a] = lo[a] >> sh, b1[a] = hi[a] >> sh;
			nb *= b1[a] - b0[a] + 1;
		}
		if (nb <= 8) {
			int c = e->coarse;
			for (int64_t x = b0[0]; x <= b1[0]; x++)
				for (int64_t y = b0[1]; y <= b1[1]; y++)
					for (int64_t z = b0[2]; z <= b1[2]; z++)
						if ((err = estimate_add(e, vd_morton3((uint32_t)x, (uint32_t)y, (uint32_t)z) >> 3 * (e->coarse - c))))
							return err;
			continue;
		}
		/* A large triangle: its blocks are the voxels it overlaps in
		 * the grid 2^sh times coarser (same lattice, same exact rule). */
		e->err = VD_OK;
		e->raster_coarse = e->coarse;
		vd_raster_triangle(&st, e->g.L - sh, b0, b1, add_block, e);
		if (e->err)
			return e->err;
	}
	return VD_OK;
}

static int cmp_u64(const void *a, const void *b)
{
	uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
	return (x > y) - (x < y);
}

/* Hands the candidate block keys over as a sorted array (the cells'
 * Morton order) and frees the rest. */
static int estimate_sorted(struct estimate *e, uint64_t **keys, size_t *n)
{
	int err = e->nbuf ? estimate_merge(e) : VD_OK;
	if (!err && !e->keys && !(e->keys = malloc(sizeof *e->keys)))
		err = vd_fail(VD_ERR_NOMEM, "block estimate");
	if (err)
		return err;
	/* to their size: they stay through the plan, which measures the
	 * process's memory, and the merges grew them by doubling */
	uint64_t *k = realloc(e->keys, (e->n ? e->n : 1) * sizeof *k);
	if (k)
		e->keys = k;
	*keys = e->keys;
	*n = e->n;
	e->keys = NULL;
	estimate_free(e);
	return VD_OK;
}

/* Blocks a whole cell at level l can hold. */
static uint64_t cell_block_cap(int L, int l)
{
	int k = L - l - BLOCK_SHIFT;
	return k <= 0 ? 1 : (uint64_t)1 << 3 * k;
}

/* The bound of the cell of level l whose sorted (coarse) keys start at
 * keys[i]; sets *end past them. A coarse key stands for 8^coarse blocks;
 * one larger than the cell gives the cell's whole capacity. */
static uint64_t cell_bound(const uint64_t *keys, size_t n, size_t i, int L,
			   int l, int coarse, size_t *end, uint64_t *lower)
{
	uint64_t cap = cell_block_cap(L, l);
	int sh = L - BLOCK_SHIFT - coarse - l;
	if (sh < 0) {
		*end = i + 1;
		*lower = 1;
		return cap;
	}
	uint64_t c = keys[i] >> 3 * sh;
	size_t j = i;
	while (j < n && keys[j] >> 3 * sh == c)
		j++;
	*end = j;
	*lower = j - i; /* every coarse key holds at least one block */
	uint64_t b = (uint64_t)(j - i) << 3 * coarse;
	return b < cap ? b : cap;
}


/* ------------------------------------------------------------- binning */

/* Triangles waiting to be appended to their cell's bin: one arena of
 * records of a fixed size (the budget's share), sorted by cell when full
 * and written out, so memory does not grow with the number of cells a mesh
 * touches. With colours the records are bin_rec_col, sorted by (cell,
 * index); what follows `cell` is what the bin file holds.
 *
 * Without colours a bin holds the triangles snapped (vd_snap_triangle),
 * which is all the rasterizer reads of them, so it does not snap them
 * again and a record needs fewer bytes than nine floats: in `.tri` files
 * 24 bytes (bin_pack: per axis the first corner in 25 bits, the other two
 * as differences of 19 bits), in `.big` files nine int32 for a triangle whose
 * numbers do not fit that. The geometry path ORs voxels, so the two files
 * of a cell may be read in any order. */
struct bin_rec {
	uint64_t key;          /* cell << 1 | 1 for a .big record */
	union {
		uint64_t w[3];     /* .tri: bin_pack */
		int32_t v[9];      /* .big */
	} u;
};

enum {
	BIN_V0_BITS = 25,      /* 0 .. 2^24 and then some: the lattice's cube */
	BIN_D_BITS = 19,       /* -2^18 .. 2^18 - 1 */
	BIN_SMALL_BYTES = 24,
	BIN_BIG_BYTES = 36,
};
_Static_assert(BIN_V0_BITS + 2 * BIN_D_BITS <= 64, "an axis a word");

/* Packs `t` into 24 bytes, a 64-bit word an axis: the first corner's
 * coordinate in bits 0-24, the second's and third's differences from it
 * (plus 2^18) in bits 25-43 and 44-62 (constant shifts: no bit stream
 * to walk, a tenth of binning's time when it was one). Returns 0 if a
 * number does not fit (a .big record). */
static int bin_pack(const struct vd_snapped_tri *t, uint64_t w[3])
{
	const int64_t dmax = (int64_t)1 << (BIN_D_BITS - 1);
	int ok = 1;
	for (int a = 0; a < 3; a++) {
		int64_t d1 = t->v[1][a] - t->v[0][a], d2 = t->v[2][a] - t->v[0][a];
		ok &= t->v[0][a] >= 0 && t->v[0][a] < (int64_t)1 << BIN_V0_BITS &&
		      d1 >= -dmax && d1 < dmax && d2 >= -dmax && d2 < dmax;
		w[a] = (uint64_t)t->v[0][a] |
		       (uint64_t)(d1 + dmax) << BIN_V0_BITS |
		       (uint64_t)(d2 + dmax) << (BIN_V0_BITS + BIN_D_BITS);
	}
	return ok;
}

static inline void bin_unpack(const uint64_t w[3], struct vd_snapped_tri *t)
{
	const int64_t dmax = (int64_t)1 << (BIN_D_BITS - 1);
	const uint64_t m0 = ((uint64_t)1 << BIN_V0_BITS) - 1,
		       md = ((uint64_t)1 << BIN_D_BITS) - 1;
	for (int a = 0; a < 3; a++) {
		int64_t v0 = (int64_t)(w[a] & m0);
		t->v[0][a] = v0;
		t->v[1][a] = v0 - dmax + (int64_t)(w[a] >> BIN_V0_BITS & md);
		t->v[2][a] = v0 - dmax +
			     (int64_t)(w[a] >> (BIN_V0_BITS + BIN_D_BITS) & md);
	}
}

/* One geometry bin record at r: nine int32 (a .big bin) or the packed
 * 24-byte form. */
static inline void bin_record(const unsigned char *r, int big,
			      struct vd_snapped_tri *st)
{
	if (big) {
		int32_t v[9];
		memcpy(v, r, sizeof v);
		for (int j = 0; j < 9; j++)
			st->v[j / 3][j % 3] = v[j];
	} else {
		uint64_t wd[3];
		memcpy(wd, r, sizeof wd);
		bin_unpack(wd, st);
	}
}

/* As a .big record: nine int32; 0 if one does not fit (it cannot: the
 * corners lie in the bounds' cube, 0 .. 2^24 give or take rounding). */
static int bin_pack_big(const struct vd_snapped_tri *t, int32_t v[9])
{
	for (int i = 0; i < 9; i++) {
		int64_t x = t->v[i / 3][i % 3];
		if (x < INT32_MIN || x > INT32_MAX)
			return 0;
		v[i] = (int32_t)x;
	}
	return 1;
}

struct bin_rec_col {
	uint64_t cell;
	uint64_t index;        /* the triangle's place in the input */
	float v[9];
	struct vd_tri_attr a;
};

/* Bytes of one triangle where raster_bin reads it: the one cell kept in
 * memory (run.mem_tris: nine floats) or a colour bin file (geometry bin
 * files are raster_snapped's: BIN_SMALL_BYTES, BIN_BIG_BYTES). */
#define BIN_BYTES_GEOM (sizeof(float) * 9)
#define BIN_BYTES_COL (sizeof(struct bin_rec_col) - sizeof(uint64_t))
_Static_assert(sizeof(struct vd_triangle) == BIN_BYTES_GEOM,
	       "the in-memory cell's record is a vd_triangle (run.mem_tris)");

struct binner {
	const struct vd_triangle *tri; /* being binned by bin_cell */
	const struct vd_snapped_tri *st; /* the same, snapped */
	const int64_t *tlo, *thi;      /* its voxel range (tri_voxel_range) */
	const struct vd_tri_attr *attr;/* its attributes (colours) */
	int err;
	struct grid g;
	const char *dir;
	/* octant bins (no colours, a cell to be split over the workers):
	 * a cell's triangles binned by the octants of it they may reach,
	 * keys of level L0 + 1, so an octant's worker reads its own */
	int sub;
	uint64_t *totals;      /* 8^L0: triangles binned to each cell */
	uint64_t records;      /* records written to the bins */
	struct bin_rec *recs;
	struct bin_rec_col *crecs; /* instead of recs, with colours */
	uint32_t *perm;        /* with colours: the order crecs are written */
	size_t buffered, cap;  /* records held in memory */
	uint64_t pairs;
	uint64_t index;        /* triangles seen so far */
};

/* A bin file: of the cell or (octant bins, `sub`) the octant `key`, its
 * 24-byte records (or, with colours, its bin_rec_col) or its .big ones. */
static void bin_file(char *buf, size_t cap, const char *dir, int sub,
		     uint64_t key, int big)
{
	snprintf(buf, cap, "%s/bins.tmp/%s%llx.%s", dir, sub ? "o" : "",
		 (unsigned long long)key, big ? "big" : "tri");
}

static void bin_path(char *buf, size_t cap, const char *dir, uint64_t cell)
{
	bin_file(buf, cap, dir, 0, cell, 0);
}

static int cmp_rec(const void *a, const void *b)
{
	uint64_t x = ((const struct bin_rec *)a)->key,
		 y = ((const struct bin_rec *)b)->key;
	return (x > y) - (x < y);
}

static int cmp_rec_col(const void *a, const void *b)
{
	const struct bin_rec_col *x = a, *y = b;
	if (x->cell != y->cell)
		return x->cell > y->cell ? 1 : -1;
	return (x->index > y->index) - (x->index < y->index);
}

/* 1 if the records are in order already (one cell: a scene binned whole,
 * where sorting hundreds of thousands of records would change nothing) */
static int recs_sorted(const void *recs, size_t n, size_t size,
		       int (*cmp)(const void *, const void *))
{
	const char *p = recs;
	for (size_t i = 1; i < n; i++)
		if (cmp(p + (i - 1) * size, p + i * size) > 0)
			return 0;
	return 1;
}

enum { BUCKET_CELLS = 4096 };

/* The colour path's flush_bins: the same files, longer records, each
 * bin in input order. The records come in input order, so with few
 * cells a stable counting sort of their positions (b->perm) orders them
 * without moving them (qsort of the terrain's 100-byte records, in
 * glibc's merge sort, cost a third of its binning); else qsort. */
static int flush_bins_col(struct binner *b)
{
	char path[4096];
	const size_t n = b->buffered, ncell = (size_t)1 << 3 * b->g.L0;
	uint32_t *perm = b->perm;
	if (recs_sorted(b->crecs, n, sizeof *b->crecs, cmp_rec_col)) {
		for (size_t i = 0; i < n; i++)
			perm[i] = (uint32_t)i;
	} else if (ncell <= BUCKET_CELLS) {
		size_t at[BUCKET_CELLS + 1];
		memset(at, 0, (ncell + 1) * sizeof *at);
		for (size_t i = 0; i < n; i++)
			at[b->crecs[i].cell + 1]++;
		for (size_t c = 0; c < ncell; c++)
			at[c + 1] += at[c];
		for (size_t i = 0; i < n; i++)
			perm[at[b->crecs[i].cell]++] = (uint32_t)i;
	} else {
		qsort(b->crecs, n, sizeof *b->crecs, cmp_rec_col);
		for (size_t i = 0; i < n; i++)
			perm[i] = (uint32_t)i;
	}
	for (size_t i = 0; i < n;) {
		uint64_t c = b->crecs[perm[i]].cell;
		bin_path(path, sizeof path, b->dir, c);
		FILE *f = fopen(path, "ab");
		if (!f)
			return vd_fail(VD_ERR_IO, "cannot write '%s': %s", path,
				       strerror(errno));
		size_t w = 0, j = i;
		for (; j < n && b->crecs[perm[j]].cell == c; j++)
			w += fwrite(&b->crecs[perm[j]].index, BIN_BYTES_COL, 1,
				    f);
		int rc = fclose(f);
		if (w != j - i || rc != 0)
			return vd_fail(VD_ERR_IO, "cannot write '%s': %s", path,
				       strerror(errno));
		i = j;
	}
	b->buffered = 0;
	return VD_OK;
}

/* Groups the records by cell (any order within a cell: the geometry
 * path ORs voxels). Few cells: in place, by counting (qsort of the
 * dragon's records took a tenth of its binning); else qsort. */

static void sort_recs(struct bin_rec *r, size_t n, size_t ncell)
{
	if (ncell > BUCKET_CELLS) {
		qsort(r, n, sizeof *r, cmp_rec);
		return;
	}
	size_t next[BUCKET_CELLS], end[BUCKET_CELLS];
	memset(end, 0, ncell * sizeof *end);
	for (size_t i = 0; i < n; i++)
		end[r[i].key]++;
	for (size_t c = 0, at = 0; c < ncell; c++) {
		next[c] = at;
		at += end[c];
		end[c] = at;
	}
	/* each record is moved straight to its cell's next free place */
	for (size_t c = 0; c < ncell; c++)
		while (next[c] < end[c]) {
			uint64_t d = r[next[c]].key;
			if (d == c) {
				next[c]++;
				continue;
			}
			struct bin_rec t = r[next[d]];
			r[next[d]++] = r[next[c]];
			r[next[c]] = t;
		}
}

/* Bins are scratch files read back by this same process, so they hold the
 * floats as they lie in memory; they are never a format. */
static int flush_bins(struct binner *b)
{
	char path[4096];
	/* keys: (bin << 1 | big), bins of level L0 or L0 + 1 */
	sort_recs(b->recs, b->buffered,
		  (size_t)2 << 3 * (b->g.L0 + b->sub));
	for (size_t i = 0; i < b->buffered;) {
		uint64_t c = b->recs[i].key;
		int big = (int)(c & 1);
		bin_file(path, sizeof path, b->dir, b->sub, c >> 1, big);
		FILE *f = fopen(path, "ab");
		if (!f)
			return vd_fail(VD_ERR_IO, "cannot write '%s': %s", path,
				       strerror(errno));
		size_t w = 0, j = i;
		for (; j < b->buffered && b->recs[j].key == c; j++)
			w += big ? fwrite(b->recs[j].u.v, BIN_BIG_BYTES, 1, f)
				 : fwrite(b->recs[j].u.w, BIN_SMALL_BYTES, 1, f);
		int rc = fclose(f);
		if (w != j - i || rc != 0)
			return vd_fail(VD_ERR_IO, "cannot write '%s': %s", path,
				       strerror(errno));
		i = j;
	}
	b->buffered = 0;
	return VD_OK;
}

static int bin_add_col(struct binner *b, uint64_t cell,
		       const struct vd_triangle *t, const struct vd_tri_attr *a)
{
	struct bin_rec_col *r = &b->crecs[b->buffered++];
	r->cell = cell;
	r->index = b->index;
	memcpy(r->v, t->v, sizeof r->v);
	r->a = *a;
	b->totals[cell]++;
	b->pairs++;
	if (b->buffered == b->cap)
		return flush_bins_col(b);
	return VD_OK;
}

/* One record of the snapped triangle into bin `key`. */
static int bin_put(struct binner *b, uint64_t key,
		   const struct vd_snapped_tri *st)
{
	struct bin_rec *r = &b->recs[b->buffered];
	if (bin_pack(st, r->u.w))
		r->key = key << 1;
	else if (bin_pack_big(st, r->u.v))
		r->key = key << 1 | 1;
	else
		return vd_fail(VD_ERR_RANGE, "snapped corner outside the "
			       "grid's lattice");
	b->buffered++;
	b->records++;
	if (b->buffered == b->cap)
		return flush_bins(b);
	return VD_OK;
}

static int bin_add(struct binner *b, uint64_t cell, const struct vd_triangle *t)
{
	if (b->crecs)
		return bin_add_col(b, cell, t, b->attr);
	b->totals[cell]++;
	b->pairs++;
	if (!b->sub)
		return bin_put(b, cell, b->st);
	/* the octants of the cell its bounding box reaches: a superset of
	 * those it overlaps, which the octant's clip box makes exact */
	int sh = b->g.L - b->g.L0 - 1;
	uint32_t c[3];
	vd_morton3_decode(cell, &c[0], &c[1], &c[2]);
	int64_t o0[3], o1[3];
	for (int a = 0; a < 3; a++) {
		int64_t first = (int64_t)c[a] << 1;
		o0[a] = b->tlo[a] >> sh;
		o1[a] = b->thi[a] >> sh;
		o0[a] = o0[a] < first ? first : o0[a];
		o1[a] = o1[a] > first + 1 ? first + 1 : o1[a];
	}
	int err = VD_OK;
	for (int64_t x = o0[0]; x <= o1[0] && !err; x++)
		for (int64_t y = o0[1]; y <= o1[1] && !err; y++)
			for (int64_t z = o0[2]; z <= o1[2] && !err; z++)
				err = bin_put(b, vd_morton3((uint32_t)x, (uint32_t)y,
							    (uint32_t)z), b->st);
	return err;
}

static void bin_cell(void *ctx, int64_t x, int64_t y, int64_t z)
{
	struct binner *b = ctx;
	if (!b->err)
		b->err = bin_add(b, vd_morton3((uint32_t)x, (uint32_t)y, (uint32_t)z),
				 b->tri);
}

static int bin_batch(void *ctx, const struct vd_triangle *t,
		     const struct vd_tri_attr *attr, size_t n)
{
	struct binner *b = ctx;
	int shift = b->g.L - b->g.L0;
	for (size_t i = 0; i < n; i++, b->index++) {
		struct vd_snapped_tri st;
		if (attr)
			b->attr = &attr[i];
		int64_t lo[3], hi[3];
		int err = vd_snap_triangle(&st, &t[i], &b->g.tr);
		if (err)
			return err;
		if (!tri_voxel_range(&st, b->g.L, lo, hi))
			continue;
		b->st = &st;
		b->tlo = lo;
		b->thi = hi;
		int64_t c0[3], c1[3];
		for (int a = 0; a < 3; a++)
			c0[a] = lo[a] >> shift, c1[a] = hi[a] >> shift;
		if (c0[0] == c1[0] && c0[1] == c1[1] && c0[2] == c1[2]) {
			err = bin_add(b, vd_morton3((uint32_t)c0[0], (uint32_t)c0[1], (uint32_t)c0[2]), &t[i]);
		} else {
			/* the cells it overlaps are the voxels it overlaps in the
			 * grid of depth L0 */
			b->tri = &t[i];
			b->err = VD_OK;
			vd_raster_triangle(&st, b->g.L0, c0, c1, bin_cell, b);
			err = b->err;
		}
		if (err)
			return err;
	}
	return VD_OK;
}

/* ------------------------------------------------ per-cell rasterization */

struct block_map {
	uint64_t *keys;      /* block key + 1; 0 is an empty slot */
	uint64_t **vals;
	size_t cap, count;
	uint64_t **spare;    /* zeroed blocks kept from earlier cells */
	size_t nspare, spare_cap;
	uint64_t **slabs;    /* blocks come SLAB_BLOCKS at a time */
	size_t nslabs, slabs_cap;
	size_t slab_used;    /* blocks taken from the last slab */
	uint64_t last_key;   /* one-entry cache: consecutive voxels */
	uint64_t *last_val;
	/* blocks recently looked up, by the key's low bits (the block's
	 * low coordinate bits): a triangle's blocks are mostly those of the
	 * triangles just before it, and the table's probe costs a cache miss
	 * in keys[] and another in vals[] */
	struct map_recent { uint64_t key1; uint64_t *val; } recent[MAP_RECENT];
	size_t limit;        /* blocks allowed by the budget */
	atomic_size_t *shared; /* if set, the blocks of all the maps that
				* share one cell, which `limit` bounds */
	int over;            /* the limit was hit */
	int clean;           /* its blocks are zero again (write_cell) */
};

static int map_grow(struct block_map *m)
{
	size_t cap = m->cap ? m->cap * 2 : 1024;
	uint64_t *keys = calloc(cap, sizeof *keys);
	uint64_t **vals = calloc(cap, sizeof *vals);
	if (!keys || !vals) {
		free(keys);
		free(vals);
		return VD_ERR_NOMEM;
	}
	for (size_t i = 0; i < m->cap; i++) {
		if (!m->keys[i])
			continue;
		size_t j = mix(m->keys[i]) & (cap - 1);
		while (keys[j])
			j = (j + 1) & (cap - 1);
		keys[j] = m->keys[i];
		vals[j] = m->vals[i];
	}
	free(m->keys);
	free(m->vals);
	m->keys = keys;
	m->vals = vals;
	m->cap = cap;
	return VD_OK;
}

/* Slab i, zeroed. A large cell's blocks are hundreds of MB, each page
 * faulted in once by the rasterizer's first store (the terrain at 2^14:
 * 130k blocks, 150k faults). From slab SMALL_SLABS on, a slab is its own
 * mapping, its pages made at once by one madvise: the kernel's work a
 * page stays, the trap a page goes (a sixth of the system time), and
 * blocks are page-aligned (a calloc'd slab spans one page more). At most
 * a slab (256 KiB) is held beyond the blocks in use: 2 MiB slabs held
 * up to 2 MiB more, 1.5% of the cruiser's peak at 2^12. (Huge pages
 * instead, MADV_HUGEPAGE, tripled the system time on this VM.) */
static uint64_t *slab_alloc(size_t i)
{
	if (i < SMALL_SLABS)
		return calloc((size_t)SLAB_BLOCKS * BLOCK_WORDS, sizeof(uint64_t));
	size_t bytes = (size_t)SLAB_BLOCKS * BLOCK_BYTES;
	char *p = mmap(NULL, bytes, PROT_READ | PROT_WRITE,
		       MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
	if (p == MAP_FAILED)
		return NULL;
#ifdef MADV_POPULATE_WRITE
	(void)madvise(p, bytes, MADV_POPULATE_WRITE);
#endif
	return (uint64_t *)p;
}

static void slab_free(uint64_t *slab, size_t i)
{
	if (i < SMALL_SLABS)
		free(slab);
	else if (slab)
		munmap(slab, (size_t)SLAB_BLOCKS * BLOCK_BYTES);
}

/* A zeroed block: a spare one, or the next of the current slab. */
static uint64_t *map_new_block(struct block_map *m)
{
	if (m->nspare)
		return m->spare[--m->nspare];
	if (!m->nslabs || m->slab_used == SLAB_BLOCKS) {
		if (m->nslabs == m->slabs_cap) {
			size_t cap = m->slabs_cap ? 2 * m->slabs_cap : 16;
			uint64_t **sl = realloc(m->slabs, cap * sizeof *sl);
			if (!sl)
				return NULL;
			m->slabs = sl;
			m->slabs_cap = cap;
		}
		uint64_t *slab = slab_alloc(m->nslabs);
		if (!slab)
			return NULL;
		m->slabs[m->nslabs++] = slab;
		m->slab_used = 0;
	}
	return m->slabs[m->nslabs - 1] + (size_t)BLOCK_WORDS * m->slab_used++;
}

static uint64_t *map_get(struct block_map *m, uint64_t key)
{
	if (m->last_val && m->last_key == key)
		return m->last_val;
	uint64_t k1 = key + 1;
	struct map_recent *rc = &m->recent[key & (MAP_RECENT - 1)];
	if (rc->key1 == k1) {
		m->last_key = key;
		return m->last_val = rc->val;
	}
	size_t j = m->cap ? mix(k1) & (m->cap - 1) : 0;
	if (m->cap) {
		while (m->keys[j]) {
			if (m->keys[j] == k1) {
				m->last_key = key;
				rc->key1 = k1;
				return rc->val = m->last_val = m->vals[j];
			}
			j = (j + 1) & (m->cap - 1);
		}
	}
	if (m->count >= m->limit ||
	    (m->shared && atomic_fetch_add(m->shared, 1) >= m->limit)) {
		m->over = 1;
		return NULL;
	}
	if (2 * (m->count + 1) > m->cap) {
		if (map_grow(m)) {
			m->over = 1;
			return NULL;
		}
		j = mix(k1) & (m->cap - 1);
		while (m->keys[j])
			j = (j + 1) & (m->cap - 1);
	}
	uint64_t *blk = map_new_block(m);
	if (!blk) {
		m->over = 1;
		return NULL;
	}
	m->keys[j] = k1;
	m->vals[j] = blk;
	m->count++;
	m->last_key = key;
	rc->key1 = k1;
	return rc->val = m->last_val = blk;
}

/* Returns every block to the spare list, zeroed, and empties the map. */
static int map_reset(struct block_map *m)
{
	if (m->nspare + m->count > m->spare_cap) {
		size_t cap = m->nspare + m->count + 64;
		uint64_t **s = realloc(m->spare, cap * sizeof *s);
		if (!s)
			return VD_ERR_NOMEM;
		m->spare = s;
		m->spare_cap = cap;
	}
	for (size_t i = 0; i < m->cap; i++)
		if (m->keys[i]) {
			if (!m->clean)
				memset(m->vals[i], 0, BLOCK_BYTES);
			m->spare[m->nspare++] = m->vals[i];
			m->keys[i] = 0;
		}
	m->count = 0;
	m->last_val = NULL;
	memset(m->recent, 0, sizeof m->recent);
	m->over = 0;
	m->clean = 0;
	return VD_OK;
}

static void map_free(struct block_map *m)
{
	map_reset(m);
	for (size_t i = 0; i < m->nslabs; i++)
		slab_free(m->slabs[i], i);
	free(m->slabs);
	free(m->spare);
	free(m->keys);
	free(m->vals);
	memset(m, 0, sizeof *m);
}

/* Morton spreading of 3-bit and 2-bit values. */
static const uint16_t spread3[8] = {0, 1, 8, 9, 64, 65, 72, 73};

/* The rasterizer's sink: blocks of the worker's map (block keys are
 * Morton keys of block coordinates within the cell). */
static uint64_t *sink_block(void *ctx, uint64_t key)
{
	return map_get(ctx, key);
}

/* A voxel's colour while the cell's triangles are visited: the squared
 * distance (in voxels) from its centre to the nearest point so far and
 * that point's colour. */
struct vox_col {
	float d2;
	uint8_t rgb[3];
	uint8_t set;
};

struct worker {
	struct block_map map;
	struct vd_triangle *tris;  /* bin read buffer (raster_batch() records) */
	uint64_t *order_tri;       /* raster_bin: the batch's order, 2 *
				    * RASTER_BATCH (keys, the sort's spare) */
	uint64_t *order;
	uint64_t **bptr;           /* the block of order[i] */
	size_t order_cap;
	uint64_t *nz;              /* write_cell: non-empty bricks per block */
	uint64_t *nz_start;        /* write_cell: bricks before each block */
	size_t nz_cap;
	/* colours: per block in key order its pointer, first rank and per
	 * word ranks within it; per voxel its colour slot */
	uint64_t **blk;
	uint64_t *base;
	uint16_t *prefix;
	size_t blk_cap;
	struct vox_col *vox;
	size_t vox_cap;
	double seconds_colour;
};

struct cell_job {
	uint64_t cell;
	uint64_t blocks;
};

struct run {
	struct grid g;
	const char *outdir;
	const struct vd_voxelize_opts *opts;
	int colours;             /* bins hold bin_rec_col; write .col chunks */
	int sub_bins;            /* octant bins (binner.sub) */
	/* one cell (L0 = 0) and the whole mesh in the triangle cache: the
	 * cell's triangles are read from there, and no bin is written */
	const struct vd_triangle *mem_tris;
	size_t mem_n;
	struct tri_cache *mem_cache; /* holds mem_tris: dropped once the
				      * cell is rasterized (tri_cache_done) */
	int mem_once;            /* mem_tris are read once, in order (no
				  * split cell): raster_bin releases them
				  * as it goes */
	struct vd_mesh *mesh;    /* for its textures (read only by now) */
	uint64_t worker_bytes;   /* each worker's share of the budget */
	struct cell_job *jobs;
	size_t njobs;
	struct worker *workers;
	int nworkers;
	size_t block_limit;
	struct progress *prog;
	atomic_size_t done;
	atomic_ullong voxels, bricks;
	atomic_ullong pairs_done;  /* triangle-cell pairs rasterized */
	uint64_t pairs_total;
	uint64_t *level_nodes;  /* levels L0..L, summed under lock */
	pthread_mutex_t lock;
	atomic_int failed;
	int err;
	char detail[512];
	atomic_size_t split_blocks;  /* split_cell: the cell's blocks */
};

/* What a user can do about a cell too large for a worker's share: a
 * deeper chunk level has smaller cells (while there is one), fewer
 * threads give each worker more of the budget. */
static const char *budget_advice(const struct run *r)
{
	int max_level = r->g.L - 2 < MAX_CHUNK_LEVEL ? r->g.L - 2 :
		MAX_CHUNK_LEVEL;
	if (r->g.L0 < max_level)
		return "use a larger --mem-budget, fewer --threads or a larger "
		       "--chunk-level (smaller cells)";
	if (r->nworkers > 1)
		return "use a larger --mem-budget or fewer --threads (the "
		       "cells are already the smallest)";
	return "use a larger --mem-budget (the cells are already the "
	       "smallest)";
}

static void run_fail(struct run *r, int err)
{
	pthread_mutex_lock(&r->lock);
	if (!r->err) {
		r->err = err;
		snprintf(r->detail, sizeof r->detail, "%s", vd_error_detail());
	}
	atomic_store(&r->failed, 1);
	pthread_mutex_unlock(&r->lock);
}

/* The one cell rasterized from memory is rasterized: its triangles
 * (the terrain's: 50 MB) go before its bricks are written. */
static void tri_cache_done(struct run *r)
{
	if (!r->mem_tris)
		return;
	tri_cache_drop(r->mem_cache);
	r->mem_tris = NULL;
	r->mem_n = 0;
}

/* Where a cell's blocks are: one worker's map, or, for a cell whose
 * octants were rasterized by several workers (split_cell), the map of
 * the worker that did each octant (block key >> part_shift). */
struct cell_blocks {
	struct block_map *map[8];
	int part_shift;
};

struct key_ptr {
	uint64_t key;
	uint64_t *p;
};

static int cmp_key_ptr(const void *a, const void *b)
{
	uint64_t x = ((const struct key_ptr *)a)->key;
	uint64_t y = ((const struct key_ptr *)b)->key;
	return (x > y) - (x < y);
}

/* The keys of the blocks in maps[0..n), sorted (Morton order), into
 * w->order, and their blocks into w->bptr: the passes over the cell's
 * bricks then walk arrays, not the hash table (a cache miss a block). */
static int gather_blocks(struct worker *w, struct block_map *const *maps,
			 int n, size_t *nb_out)
{
	size_t total = 0;
	for (int k = 0; k < n; k++)
		total += maps[k]->count;
	if (total > w->order_cap) {
		size_t cap = total * 2;
		uint64_t *o = realloc(w->order, cap * sizeof *o);
		if (o)
			w->order = o;
		uint64_t **bp = realloc(w->bptr, cap * sizeof *bp);
		if (bp)
			w->bptr = bp;
		if (!o || !bp)
			return vd_fail(VD_ERR_NOMEM, "block order");
		w->order_cap = cap;
	}
	struct key_ptr *kp = malloc((total ? total : 1) * sizeof *kp);
	if (!kp)
		return vd_fail(VD_ERR_NOMEM, "block order");
	size_t nb = 0;
	for (int k = 0; k < n; k++)
		for (size_t i = 0; i < maps[k]->cap; i++)
			if (maps[k]->keys[i])
				kp[nb++] = (struct key_ptr){
					maps[k]->keys[i] - 1, maps[k]->vals[i]};
	qsort(kp, nb, sizeof *kp, cmp_key_ptr);
	for (size_t i = 0; i < nb; i++) {
		w->order[i] = kp[i].key;
		w->bptr[i] = kp[i].p;
	}
	free(kp);
	*nb_out = nb;
	return VD_OK;
}

/* The cell's bricks in Morton order as the BRKS section lays them out
 * (schemas/chunk-format.md): any range of its raw bytes can be made on its
 * own, so the section's zstd frames are made and compressed on several
 * threads (vd_chunk_writer_frames). Block i holds bricks start[i] ..
 * start[i + 1] - 1, the set bits of its 8 words nz[8i..8i+7]. */
struct brick_src {
	uint64_t *const *blk;     /* the block of order[i] */
	const uint64_t *order, *nz, *start;
	size_t nb;
	uint64_t prefix, count;
};

struct brick_it {
	size_t blk;
	int qw;
	uint64_t bits;
	const uint64_t *words; /* the block's masks, packed by nz_range */
	size_t r;              /* the brick's rank in its block */
};

/* Positions `it` at brick i (< count). */
static void brick_seek(const struct brick_src *b, uint64_t i,
		       struct brick_it *it)
{
	size_t lo = 0, hi = b->nb;
	while (hi - lo > 1) {
		size_t mid = lo + (hi - lo) / 2;
		if (b->start[mid] <= i)
			lo = mid;
		else
			hi = mid;
	}
	uint64_t skip = i - b->start[lo];
	it->r = (size_t)skip;
	it->blk = lo;
	it->qw = 0;
	it->bits = b->nz[8 * lo];
	for (;;) {
		uint64_t pc = vd_popcount64(it->bits);
		if (skip < pc)
			break;
		skip -= pc;
		it->bits = b->nz[8 * lo + ++it->qw];
	}
	while (skip--)
		it->bits &= it->bits - 1;
	it->words = b->blk[lo];
}

/* The brick at `it` (there must be one), then steps past it; its mask
 * only if asked (the keys come from nz[] alone: no block memory). */
static inline void brick_next(const struct brick_src *b, struct brick_it *it,
			      uint64_t *key, uint64_t *mask)
{
	while (!it->bits) {
		if (++it->qw == 8) {
			it->qw = 0;
			it->blk++;
			it->words = b->blk[it->blk];
			it->r = 0;
		}
		it->bits = b->nz[8 * it->blk + it->qw];
	}
	int j = 64 * it->qw + __builtin_ctzll(it->bits);
	it->bits &= it->bits - 1;
	*key = b->prefix | b->order[it->blk] << 9 | (uint64_t)j;
	if (mask)
		*mask = it->words[it->r];
	it->r++;
}

/* Raw BRKS bytes [off, off + n): word 0 the count, words 1..count the key
 * deltas, then the masks. Whole words: frames are multiples of 8 bytes. */
static void brick_fill(void *ctx, uint64_t off, uint8_t *buf, size_t n)
{
	const struct brick_src *b = ctx;
	uint64_t w = off / 8, w1 = (off + n) / 8, key, mask, prev = 0;
	struct brick_it it;
	if (w == 0) {
		le_put64(buf, b->count);
		buf += 8;
		w++;
	}
	if (w < w1 && w <= b->count) {
		uint64_t i = w - 1, end = w1 - 1 < b->count ? w1 - 1 : b->count;
		brick_seek(b, i ? i - 1 : 0, &it);
		if (i)
			brick_next(b, &it, &prev, NULL);
		for (; i < end; i++, buf += 8) {
			brick_next(b, &it, &key, NULL);
			le_put64(buf, i ? key - prev : key);
			prev = key;
		}
		w = end + 1;
	}
	/* each mask is read here once, the block's last use: zeroing it
	 * in the line just read spares map_reset a memset of the block */
	if (w < w1) {
		uint64_t i = w - 1 - b->count, end = w1 - 1 - b->count;
		brick_seek(b, i, &it);
		for (; i < end; i++, buf += 8) {
			brick_next(b, &it, &key, &mask);
			le_put64(buf, mask);
			((uint64_t *)it.words)[it.r - 1] = 0;
		}
	}
}

/* Which bricks of blocks [k * NZ_RANGE, ...) are non-empty, and how many
 * (into start[], made starts by the caller), and the range's part of the
 * per-level counts while the block is in cache: all of them but the nodes
 * above the blocks' level (bl - 3), which the caller adds from the keys
 * of consecutive non-empty blocks. A block's first brick is counted as
 * new from that level down: a previous key differing in bit 9 alone. */
enum { NZ_RANGE = 1024 };

struct nz_job {
	uint64_t *const *blk;
	const uint64_t *order;
	uint64_t *nz, *start;
	uint64_t (*counts)[VD_MAX_LEVELS + 1]; /* per range */
	size_t nb;
	int L, L0;
};

static void nz_range(void *ctx, size_t k, int worker)
{
	(void)worker;
	struct nz_job *nj = ctx;
	uint64_t *counts = nj->counts[k];
	size_t end = (k + 1) * NZ_RANGE < nj->nb ? (k + 1) * NZ_RANGE : nj->nb;
	for (size_t i = k * NZ_RANGE; i < end; i++) {
		uint64_t *blk = nj->blk[i];
		uint64_t *nz = nj->nz + 8 * i, c = 0;
		/* the next block's lines on their way while this one is
		 * scanned, a line for each line read: blocks lie anywhere in
		 * the slabs, a page each, so the hardware's prefetch starts
		 * late on every one (the 64 prefetches issued at once before
		 * the scan stalled on the full line buffers: a quarter of
		 * nz_range's time) */
		const uint64_t *next = i + 1 < end ? nj->blk[i + 1] : blk;
		for (int q = 0; q < 8; q++) {
			uint64_t bits = 0;
			for (int j = 0; j < 64; j += 8) {
				/* a line at a time: most are empty */
				const uint64_t *l = blk + 64 * q + j;
				__builtin_prefetch(next + 64 * q + j);
				if (!(l[0] | l[1] | l[2] | l[3] | l[4] | l[5] |
				      l[6] | l[7]))
					continue;
				for (int t = 0; t < 8; t++)
					bits |= (uint64_t)(l[t] != 0) << (j + t);
			}
			nz[q] = bits;
			c += vd_popcount64(bits);
		}
		nj->start[i] = c;
		/* keys within the block: the brick index; the bits above
		 * are the same for all and cancel in prev ^ key. The masks
		 * are packed to the block's front (the block is not read as
		 * a grid again), so later passes read c words in a row. */
		uint64_t prev = 1ull << 9;
		size_t r = 0;
		for (int q = 0; q < 8; q++)
			for (uint64_t bits = nz[q]; bits; bits &= bits - 1) {
				uint64_t key = (uint64_t)(64 * q +
						__builtin_ctzll(bits));
				uint64_t m = blk[key];
				vd_svo_count_brick(counts, nj->L, nj->L0, 0,
						   prev, key, m);
				prev = key;
				if (r != key) {
					blk[r] = m;
					blk[key] = 0;
				}
				r++;
			}
	}
}

/* Writes the cell's bricks (blocks w->order[0..nb), sorted, found
 * through cb), in Morton order, into an SVO chunk, the section's frames
 * compressed on `threads` threads. With `hout`, also returns the chunk's
 * header and the vd_svo_digest() of its bricks, for the colour chunk. */
static int write_cell(struct run *r, struct worker *w,
		      const struct cell_blocks *cb, uint64_t cell, size_t nb,
		      int threads, uint64_t *counts, uint64_t *nbricks,
		      struct vd_chunk_header *hout, uint64_t *digest)
{
	int L = r->g.L, L0 = r->g.L0, k = L - L0;
	/* brick key = cell prefix | block key | brick within block */
	int cell_shift = k >= 2 ? 3 * (k - 2) : 0;
	uint64_t prefix = cell << cell_shift;

	uint64_t count = 0;
	for (int l = 0; l <= k; l++)
		counts[l] = 0;
	/* per block, which of its 512 bricks are non-empty (8 words), and
	 * the bricks before it: the passes below visit those only */
	if (nb + 1 > w->nz_cap) {
		free(w->nz);
		free(w->nz_start);
		w->nz_cap = 0;
		w->nz = malloc((nb + 1) * 2 * 8 * sizeof *w->nz);
		w->nz_start = malloc((nb + 1) * 2 * sizeof *w->nz_start);
		if (!w->nz || !w->nz_start)
			return vd_fail(VD_ERR_NOMEM, "brick masks");
		w->nz_cap = (nb + 1) * 2;
	}
	/* each block's words read once (4 KiB a block: hundreds of MB for a
	 * large cell), on the threads; its count then becomes a start */
	size_t nranges = (nb + NZ_RANGE - 1) / NZ_RANGE;
	struct nz_job nj = {w->bptr, w->order, w->nz, w->nz_start,
			    calloc(nranges ? nranges : 1, sizeof *nj.counts),
			    nb, L, L0};
	if (!nj.counts)
		return vd_fail(VD_ERR_NOMEM, "brick counts");
	int perr = vd_parallel_for(nranges, threads, nz_range, &nj);
	if (perr) {
		free(nj.counts);
		return perr;
	}
	for (size_t p = 0; p < nranges; p++)
		for (int l = 0; l <= k; l++)
			counts[l] += nj.counts[p][l];
	free(nj.counts);
	/* the nodes above the blocks: as vd_svo_count_brick() finds them
	 * for a block's first brick, down to where nz_range took over */
	int bl = L >= 2 ? L - 2 : 0, first = 1;
	uint64_t pb = 0;
	for (size_t i = 0; i < nb; i++) {
		uint64_t c = w->nz_start[i];
		w->nz_start[i] = count;
		count += c;
		if (!c)
			continue;
		int from = L0;
		if (!first) {
			uint64_t x = (pb ^ w->order[i]) << 9;
			from = bl - (63 - __builtin_clzll(x)) / 3;
			if (from < L0)
				from = L0;
		}
		for (int l = from; l < bl - 3; l++)
			counts[l - L0]++;
		pb = w->order[i];
		first = 0;
	}
	w->nz_start[nb] = count;
	*nbricks = count;
	if (count == 0) {
		for (int q = 0; q < 8; q++)
			cb->map[q]->clean = 1; /* no word was set */
		return VD_OK; /* touched only by triangles outside its voxels */
	}
	struct brick_src src = {w->bptr, w->order, w->nz, w->nz_start, nb,
				prefix, count};

	/* the digest as vd_svo_digest() computes it: one pass in order */
	XXH3_state_t *xs = NULL;
	if (hout) {
		if (!(xs = XXH3_createState()))
			return vd_fail(VD_ERR_NOMEM, "digest");
		XXH3_64bits_reset(xs);
	}
	if (xs) {
		struct brick_it it;
		brick_seek(&src, 0, &it);
		for (uint64_t i = 0; i < count; i++) {
			uint64_t key, mask;
			brick_next(&src, &it, &key, &mask);
			uint8_t kv[16];
			le_put64(kv, key);
			le_put64(kv + 8, mask);
			XXH3_64bits_update(xs, kv, 16);
		}
		*digest = XXH3_64bits_digest(xs);
		XXH3_freeState(xs);
	}

	struct vd_chunk_header h = {0};
	h.kind = VD_KIND_SVO;
	h.levels = (uint32_t)L;
	h.chunk_level = (uint32_t)L0;
	h.cell_morton = cell;
	h.transform = r->g.tr;
	h.level_count = (uint32_t)k + 1;
	for (int l = 0; l <= k; l++)
		h.level_nodes[l] = counts[l];
	char path[4096], name[64];
	vd_chunk_file_name(name, sizeof name, L0, cell, "svo");
	snprintf(path, sizeof path, "%s/%s", r->outdir, name);
	struct vd_chunk_writer *cw;
	int err = vd_chunk_writer_open(&cw, path, &h, r->opts->provenance);
	if (err)
		return err;
	err = vd_chunk_writer_frames(cw, VD_TAG_BRKS, 8 + 16 * count,
				     brick_fill, &src, threads, 0);
	if (err) {
		vd_chunk_writer_abort(cw);
		return err;
	}
	for (int q = 0; q < 8; q++)
		cb->map[q]->clean = 1;
	if (hout)
		*hout = h;
	return vd_chunk_writer_commit(cw);
}


/* --------------------------------------------------------------- colours */

static double dot3(const double a[3], const double b[3])
{
	return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* Nearest point of segment (a, b) to the origin: t along it. */
static double seg_t(const double a[3], const double b[3])
{
	double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
	double l = dot3(ab, ab);
	if (!(l > 0))
		return 0;
	double t = -dot3(a, ab) / l;
	return t < 0 ? 0 : t > 1 ? 1 : t;
}

/* Barycentric coordinates of the point of triangle (a, b, c) nearest to
 * the origin (Ericson, Real-Time Collision Detection, 5.1.5: Voronoi
 * regions of the vertices, then the edges, then the face); a degenerate
 * triangle is the nearest of its three segments. Returns the squared
 * distance. */
static double nearest_bary(const double a[3], const double b[3],
			   const double c[3], double w[3])
{
	double ab[3], ac[3], ap[3], bp[3], cp[3];
	for (int i = 0; i < 3; i++) {
		ab[i] = b[i] - a[i];
		ac[i] = c[i] - a[i];
		ap[i] = -a[i];
		bp[i] = -b[i];
		cp[i] = -c[i];
	}
	double d1 = dot3(ab, ap), d2 = dot3(ac, ap);
	double d3 = dot3(ab, bp), d4 = dot3(ac, bp);
	double d5 = dot3(ab, cp), d6 = dot3(ac, cp);
	double vc = d1 * d4 - d3 * d2, vb = d5 * d2 - d1 * d6,
	       va = d3 * d6 - d5 * d4;
	if (d1 <= 0 && d2 <= 0) {
		w[0] = 1, w[1] = 0, w[2] = 0;
	} else if (d3 >= 0 && d4 <= d3) {
		w[0] = 0, w[1] = 1, w[2] = 0;
	} else if (d6 >= 0 && d5 <= d6) {
		w[0] = 0, w[1] = 0, w[2] = 1;
	} else if (!(va + vb + vc > 0)) {
		/* no area: the nearest of the three segments, first wins */
		const double *p[3] = {a, b, c};
		double best = INFINITY;
		for (int e = 0; e < 3; e++) {
			const double *s0 = p[e], *s1 = p[(e + 1) % 3];
			double t = seg_t(s0, s1), q[3];
			for (int i = 0; i < 3; i++)
				q[i] = s0[i] + t * (s1[i] - s0[i]);
			double d = dot3(q, q);
			if (d < best) {
				best = d;
				w[0] = w[1] = w[2] = 0;
				w[e] = 1 - t;
				w[(e + 1) % 3] = t;
			}
		}
	} else if (vc <= 0 && d1 >= 0 && d3 <= 0) {
		double v = d1 / (d1 - d3);
		w[0] = 1 - v, w[1] = v, w[2] = 0;
	} else if (vb <= 0 && d2 >= 0 && d6 <= 0) {
		double t = d2 / (d2 - d6);
		w[0] = 1 - t, w[1] = 0, w[2] = t;
	} else if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) {
		double t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
		w[0] = 0, w[1] = 1 - t, w[2] = t;
	} else {
		double den = 1 / (va + vb + vc);
		double v = vb * den, t = vc * den;
		w[0] = 1 - v - t, w[1] = v, w[2] = t;
	}
	double q[3];
	for (int i = 0; i < 3; i++)
		q[i] = w[0] * a[i] + w[1] * b[i] + w[2] * c[i];
	return dot3(q, q);
}

/* A triangle as the nearest-point arithmetic sees it: its corners a, b, c
 * in voxels (tv: lattice integers over a power of two, exact), and, when
 * every lattice coordinate is within [-2^22, 2^24 + 2^22] (`exact`; a
 * mesh's own cube is [0, 2^24]), its edges ab = b - a, ac = c - a and the
 * dot products ab.a, ac.a, ab.ab, ab.ac, ac.ac. nearest_bary's six dot
 * products d1..d6 of the edges with the corners seen from a voxel centre
 * q (ap = q - a, ...) are then exact: in lattice units every factor is an
 * integer below 1.5 * 2^24 in magnitude (q's too: a voxel's centre is an
 * integer number of lattice steps from the origin, as a voxel has at
 * least 8 of them), so every product is an integer below 2.25 * 2^48,
 * every sum of three below 2^51, exactly representable; scaling by
 * powers of two to voxels keeps them exact. So d1 = ab.q - ab.a and
 * d2 = ac.q - ac.a, exact in the same way, and d3 = ab.bp = d1 - ab.ab,
 * d4 = ac.bp = d2 - ab.ac, d5 = ab.cp = d1 - ab.ac, d6 = ac.cp = d2 -
 * ac.ac, each an exact difference, are the values nearest_bary computes,
 * bit for bit up to the sign of a zero, which no comparison sees and which
 * leaves every weight and distance as it was (a zero weight times a corner
 * is added to the others' products or squared). */
struct near_tri {
	double tv[3][3];
	int exact;
	double ab[3], ac[3];
	double ab_a, ac_a, ab_ab, ab_ac, ac_ac;
};

/* t's fields from the snapped corners v and the lattice steps per voxel
 * s (a power of two). */
static void near_tri_init(struct near_tri *t, const int64_t v[3][3],
			  int64_t s)
{
	const double inv_s = 1.0 / (double)s; /* exact */
	const int64_t lo = -((int64_t)1 << 22),
		      hi = ((int64_t)1 << 24) + ((int64_t)1 << 22);
	t->exact = 1;
	for (int k = 0; k < 3; k++)
		for (int a = 0; a < 3; a++) {
			t->tv[k][a] = (double)v[k][a] * inv_s;
			t->exact &= v[k][a] >= lo && v[k][a] <= hi;
		}
	for (int a = 0; a < 3; a++) {
		t->ab[a] = t->tv[1][a] - t->tv[0][a];
		t->ac[a] = t->tv[2][a] - t->tv[0][a];
	}
	t->ab_a = dot3(t->ab, t->tv[0]);
	t->ac_a = dot3(t->ac, t->tv[0]);
	t->ab_ab = dot3(t->ab, t->ab);
	t->ab_ac = dot3(t->ab, t->ac);
	t->ac_ac = dot3(t->ac, t->ac);
}

/* The nearest points of four voxel centres at once, in the lanes of
 * AVX2 vectors, when the processor has them: the same operations as
 * nearest_bary in the same order (IEEE double, rounded alike; no FMA,
 * which avx2 alone does not enable), so the same bits. Branches become
 * masks: every region's weights are computed and the first region that
 * holds, in nearest_bary's order, is kept. */
#if defined(__x86_64__) && defined(__GNUC__)
#define NEAR_AVX2 1
#include <immintrin.h>
#else
#define NEAR_AVX2 0
#endif

int vd_colour_fast = 1;

#if NEAR_AVX2
typedef double v4d __attribute__((vector_size(32)));
typedef long long v4l __attribute__((vector_size(32)));

__attribute__((target("avx2"))) static inline v4d v4_dot(const v4d a[3],
							  const v4d b[3])
{
	return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* m ? x : y, lane by lane */
__attribute__((target("avx2"))) static inline v4d v4_sel(v4l m, v4d x,
							  v4d y)
{
	return (v4d)(((v4l)x & m) | ((v4l)y & ~m));
}

__attribute__((target("avx2"))) static inline int v4_any(v4l m)
{
	return _mm256_movemask_pd((__m256d)m) != 0;
}

/* nearest_bary of the triangle nt seen from the centres (cx[l], cy[l],
 * cz[l]) of lanes l = 0..3: the squared distance rounded to float into
 * d2[l], the weights into w[0..2][l]. Returns the lanes (bit l) whose
 * triangle has no area there, whose nearest point (of three segments)
 * the caller finds with nearest_bary itself. */
__attribute__((target("avx2"))) static int
nearest4(const struct near_tri *nt, const double *const c[3], float d2[4],
	 double *const w[3])
{
	/* the centres straight from their arrays: copied through the stack
	 * in two halves they were read back whole, which the store buffer
	 * cannot forward (perf put a third of nearest4 there) */
	v4d p[3][3], cv[3], d1, d2_, d3, d4, d5, d6;
	for (int i = 0; i < 3; i++) {
		cv[i] = (v4d)_mm256_loadu_pd(c[i]);
		for (int k = 0; k < 3; k++)
			p[k][i] = nt->tv[k][i] - cv[i];
	}
	if (nt->exact) {
		/* two dot products instead of six, the same values (see
		 * struct near_tri) */
		d1 = nt->ab[0] * cv[0] + nt->ab[1] * cv[1] + nt->ab[2] * cv[2] -
		     nt->ab_a;
		d2_ = nt->ac[0] * cv[0] + nt->ac[1] * cv[1] + nt->ac[2] * cv[2] -
		      nt->ac_a;
		d3 = d1 - nt->ab_ab;
		d4 = d2_ - nt->ab_ac;
		d5 = d1 - nt->ab_ac;
		d6 = d2_ - nt->ac_ac;
	} else {
		v4d ab[3], ac[3], ap[3], bp[3], cp[3];
		for (int i = 0; i < 3; i++) {
			ab[i] = p[1][i] - p[0][i];
			ac[i] = p[2][i] - p[0][i];
			ap[i] = -p[0][i];
			bp[i] = -p[1][i];
			cp[i] = -p[2][i];
		}
		d1 = v4_dot(ab, ap), d2_ = v4_dot(ac, ap);
		d3 = v4_dot(ab, bp), d4 = v4_dot(ac, bp);
		d5 = v4_dot(ab, cp), d6 = v4_dot(ac, cp);
	}
	const v4d vc = d1 * d4 - d3 * d2_, vb = d5 * d2_ - d1 * d6,
		  va = d3 * d6 - d5 * d4;
	const v4d zero = {0, 0, 0, 0}, one = {1, 1, 1, 1};
	const v4d sum = va + vb + vc;
	v4l done = (d1 <= 0) & (d2_ <= 0);
	v4d w0 = v4_sel(done, one, zero), w1 = zero, w2 = zero;
	v4l m = ~done & (d3 >= 0) & (d4 <= d3);
	w1 = v4_sel(m, one, w1);
	done |= m;
	m = ~done & (d6 >= 0) & (d5 <= d6);
	w2 = v4_sel(m, one, w2);
	done |= m;
	const v4l flat = ~done & ~(sum > 0);
	done |= flat;
	const v4l mab = ~done & (vc <= 0) & (d1 >= 0) & (d3 <= 0);
	done |= mab;
	const v4l mac = ~done & (vb <= 0) & (d2_ >= 0) & (d6 <= 0);
	done |= mac;
	const v4d d43 = d4 - d3, d56 = d5 - d6;
	const v4l mbc = ~done & (va <= 0) & (d43 >= 0) & (d56 >= 0);
	done |= mbc;
	const v4l face = ~done;
	if (v4_any(mab | mac | mbc | face)) {
		/* one division for the four lanes, each its region's: the
		 * edges' parameters and the face's 1 / sum */
		v4d num = v4_sel(mab, d1, v4_sel(mac, d2_, v4_sel(mbc, d43,
								one)));
		v4d den = v4_sel(mab, d1 - d3,
				 v4_sel(mac, d2_ - d6,
					v4_sel(mbc, d43 + d56, sum)));
		v4d r = num / den;
		w0 = v4_sel(mab | mac, 1 - r, w0);
		w1 = v4_sel(mab, r, v4_sel(mbc, 1 - r, w1));
		w2 = v4_sel(mac | mbc, r, w2);
		v4d v = vb * r, t = vc * r;
		w0 = v4_sel(face, 1 - v - t, w0);
		w1 = v4_sel(face, v, w1);
		w2 = v4_sel(face, t, w2);
	}
	v4d q[3];
	for (int i = 0; i < 3; i++)
		q[i] = w0 * p[0][i] + w1 * p[1][i] + w2 * p[2][i];
	_mm_storeu_ps(d2, _mm256_cvtpd_ps((__m256d)v4_dot(q, q)));
	_mm256_storeu_pd(w[0], (__m256d)w0);
	_mm256_storeu_pd(w[1], (__m256d)w1);
	_mm256_storeu_pd(w[2], (__m256d)w2);
	return _mm256_movemask_pd((__m256d)flat);
}

static int near_avx2(void)
{
	return vd_colour_fast && __builtin_cpu_supports("avx2");
}
#endif

int vd__nearest_check(const int64_t v[3][3], int levels,
		      const int64_t vox[4][3], float d2[2][4],
		      double w[2][3][4])
{
	struct near_tri nt;
	near_tri_init(&nt, v, vd_snap_voxel(levels));
	double c[3][4];
	for (int l = 0; l < 4; l++)
		for (int a = 0; a < 3; a++)
			c[a][l] = (double)vox[l][a] + 0.5;
	int flat = 0;
	for (int l = 0; l < 4; l++) {
		double p[3][3], b[3];
		for (int k = 0; k < 3; k++)
			for (int a = 0; a < 3; a++)
				p[k][a] = nt.tv[k][a] - c[a][l];
		d2[0][l] = (float)nearest_bary(p[0], p[1], p[2], b);
		for (int k = 0; k < 3; k++)
			w[0][k][l] = b[k];
	}
#if NEAR_AVX2
	if (!__builtin_cpu_supports("avx2"))
		return -1;
	const double *cp[3] = {c[0], c[1], c[2]};
	double *wp[3] = {w[1][0], w[1][1], w[1][2]};
	flat = nearest4(&nt, cp, d2[1], wp);
	return flat | nt.exact << 4;
#else
	(void)flat;
	return -1;
#endif
}

/* A triangle's voxels go through two queues. Its bricks' words first
 * (block, word, the triangle's bits there), whose geometry word and rank
 * are fetched into the cache as they are queued and read when the queue
 * is drained, a queue later; each voxel then gets its slot (its rank in
 * the cell's Morton order), fetched too, and joins the voxels waiting for
 * their nearest points, whose slots are read a batch later. perf put the
 * colour pass's time in waiting on those loads when each voxel's word,
 * rank and slot were fetched 8 voxels ahead. */
enum {
	WORD_QUEUE = 64,          /* words whose geometry is being fetched */
	NEAR_BATCH = 32           /* voxels whose nearest points go together */
};

struct colour_ctx {
	struct worker *w;
	size_t nb;
	int64_t lo[3];            /* cell corner, voxels */
	int64_t s;                /* lattice steps per voxel */
	const struct vd_snapped_tri *st;
	struct near_tri nt;       /* its corners in voxels: st / s, exact */
	const struct vd_tri_attr *a;
	const struct vd_texture *tex;
	uint32_t last_b[3];       /* block of the last voxel, */
	size_t last;              /* its index in w->order */
	int have_last;
	int simd;                 /* nearest4 */
	/* the triangle's colour does not depend on where: no texture, and
	 * its three corners alike (a material's colour; test_uniform_colour
	 * holds vd_tri_attr_colour to it for weights within +-2) */
	int uniform;
	/* the words waiting: block index in w->order, word, the triangle's
	 * bits in it, the brick's first voxel */
	int nw;
	uint32_t wb[WORD_QUEUE];
	uint16_t ww[WORD_QUEUE];
	uint64_t wm[WORD_QUEUE];
	int64_t wc[WORD_QUEUE][3];
	/* the voxels waiting: centres (voxels) by axis, and their slots */
	int nq;
	double qc[3][NEAR_BATCH];
	struct vox_col *qv[NEAR_BATCH];
};

/* The nearest points of the waiting voxels, then their colours, in the
 * order the voxels came (each voxel comes once per triangle, so the
 * order only matters between triangles, and every triangle's voxels are
 * done before the next one's). */
static void colour_flush(struct colour_ctx *c)
{
	float d2[NEAR_BATCH];
	double b[3][NEAR_BATCH];
	struct vox_col *const *qv = c->qv;
	const int n = c->nq;
	_Static_assert(NEAR_BATCH < 64 && NEAR_BATCH % 4 == 0, "lane masks");
	uint64_t flat = (1ull << n) - 1;
#if NEAR_AVX2
	if (c->simd) {
		/* the lanes past n repeat voxel 0: computed, not used */
		for (int i = n; i < (n + 3) / 4 * 4; i++)
			for (int a = 0; a < 3; a++)
				c->qc[a][i] = c->qc[a][0];
		flat = 0;
		for (int g = 0; g < n; g += 4) {
			const double *cg[3] = {&c->qc[0][g], &c->qc[1][g],
					       &c->qc[2][g]};
			double *wg[3] = {&b[0][g], &b[1][g], &b[2][g]};
			flat |= (uint64_t)nearest4(&c->nt, cg, d2 + g, wg) << g;
		}
		flat &= (1ull << n) - 1;
	}
#endif
	/* without AVX2 every voxel, with it the lanes without area: the
	 * corners relative to the voxel's centre, in voxels: exact (lattice
	 * integers over a power of two, less a half-integer, well inside 53
	 * bits) and so the same in every chunking */
	for (; flat; flat &= flat - 1) {
		int i = __builtin_ctzll(flat);
		double p[3][3], bi[3];
		for (int k = 0; k < 3; k++)
			for (int a = 0; a < 3; a++)
				p[k][a] = c->nt.tv[k][a] - c->qc[a][i];
		d2[i] = (float)nearest_bary(p[0], p[1], p[2], bi);
		for (int k = 0; k < 3; k++)
			b[k][i] = bi[k];
	}
	/* the voxels this triangle is nearer to, their texels found and
	 * fetched before any is read */
	uint64_t take = 0, texels = 0;
	struct vd_texel_quad tq[NEAR_BATCH];
	for (int i = 0; i < n; i++) {
		struct vox_col *v = qv[i];
		if (v->set && !(d2[i] < v->d2))
			continue; /* an earlier triangle is as near: it stays */
		take |= 1ull << i;
		if (c->tex) {
			double bi[3] = {b[0][i], b[1][i], b[2][i]};
			texels |= (uint64_t)vd_tri_attr_texels(c->a, c->tex, bi,
							      &tq[i]) << i;
		}
	}
	for (; take; take &= take - 1) {
		int i = __builtin_ctzll(take);
		struct vox_col *v = qv[i];
		v->d2 = d2[i];
		v->set = 1;
		if (texels >> i & 1) {
			vd_texel_quad_colour(&tq[i], v->rgb);
			continue;
		}
		if (c->uniform && fabs(b[0][i]) <= 2 && fabs(b[1][i]) <= 2 &&
		    fabs(b[2][i]) <= 2) {
			memcpy(v->rgb, c->a->rgb[0], 3);
			continue;
		}
		double bi[3] = {b[0][i], b[1][i], b[2][i]};
		vd_tri_attr_colour(c->a, c->tex, bi, v->rgb);
	}
	c->nq = 0;
}

/* The waiting words' voxels into the nearest-point batches: a word's
 * geometry and rank are read once for its voxels. */
static void colour_drain(struct colour_ctx *c)
{
	const struct worker *w = c->w;
	for (int k = 0; k < c->nw; k++) {
		size_t bi = c->wb[k];
		unsigned wi = c->ww[k];
		uint64_t word = w->blk[bi][wi];
		uint64_t m = c->wm[k] & word; /* other bits cannot be: the
					       * geometry pass set them */
		uint64_t rank = w->base[bi] + w->prefix[bi * BLOCK_WORDS + wi];
		const int64_t *o = c->wc[k];
		for (; m; m &= m - 1) {
			unsigned j = (unsigned)__builtin_ctzll(m);
			int q = c->nq;
			struct vox_col *v = &w->vox[rank + (uint64_t)
				vd_popcount64(word & ((1ull << j) - 1))];
			__builtin_prefetch(v, 1);
			c->qv[q] = v;
			c->qc[0][q] = (double)(o[0] + (j >> 2 & 1) +
					       (j >> 4 & 2)) + 0.5;
			c->qc[1][q] = (double)(o[1] + (j >> 1 & 1) +
					       (j >> 3 & 2)) + 0.5;
			c->qc[2][q] = (double)(o[2] + (j & 1) + (j >> 2 & 2)) +
				      0.5;
			if ((c->nq = q + 1) == NEAR_BATCH)
				colour_flush(c);
		}
	}
	c->nw = 0;
}

/* The triangle's bits m of word wi of block bi (its index in w->order),
 * whose brick's first voxel is (x, y, z), join the words waiting. */
static inline void colour_word(struct colour_ctx *c, size_t bi, unsigned wi,
			       uint64_t m, int64_t x, int64_t y, int64_t z)
{
	const struct worker *w = c->w;
	__builtin_prefetch(&w->blk[bi][wi]);
	__builtin_prefetch(&w->prefix[bi * BLOCK_WORDS + wi]);
	int k = c->nw;
	c->wb[k] = (uint32_t)bi;
	c->ww[k] = (uint16_t)wi;
	c->wm[k] = m;
	c->wc[k][0] = x, c->wc[k][1] = y, c->wc[k][2] = z;
	if ((c->nw = k + 1) == WORD_QUEUE)
		colour_drain(c);
}

/* A triangle's voxels are all queued: their colours now. */
static void colour_finish(struct colour_ctx *c)
{
	colour_drain(c);
	if (c->nq)
		colour_flush(c);
}

/* The index in w->order[0..nb) of the block of Morton key `key`, nb if
 * none. */
static size_t block_index(const struct worker *w, size_t nb, uint64_t key)
{
	size_t lo = 0, hi = nb;
	while (lo < hi) {
		size_t mid = lo + (hi - lo) / 2;
		if (w->order[mid] < key)
			lo = mid + 1;
		else
			hi = mid;
	}
	return lo < nb && w->order[lo] == key ? lo : nb;
}

static inline void colour_voxel(struct colour_ctx *c, int64_t x, int64_t y,
				int64_t z)
{
	struct worker *w = c->w;
	uint32_t lx = (uint32_t)(x - c->lo[0]), ly = (uint32_t)(y - c->lo[1]),
		 lz = (uint32_t)(z - c->lo[2]);
	const uint32_t bx = lx >> BLOCK_SHIFT, by = ly >> BLOCK_SHIFT,
		       bz = lz >> BLOCK_SHIFT;
	if (!c->have_last || bx != c->last_b[0] || by != c->last_b[1] ||
	    bz != c->last_b[2]) {
		size_t i = block_index(w, c->nb, vd_morton3(bx, by, bz));
		if (i == c->nb)
			return; /* cannot be: the geometry pass set it */
		c->last = i;
		c->last_b[0] = bx, c->last_b[1] = by, c->last_b[2] = bz;
		c->have_last = 1;
	}
	unsigned wi = (unsigned)spread3[(lx >> 2) & 7] << 2 |
		      (unsigned)spread3[(ly >> 2) & 7] << 1 |
		      spread3[(lz >> 2) & 7];
	unsigned bit = (unsigned)spread3[lx & 3] << 2 |
		       (unsigned)spread3[ly & 3] << 1 | spread3[lz & 3];
	colour_word(c, c->last, wi, 1ull << bit, x & ~(int64_t)3,
		    y & ~(int64_t)3, z & ~(int64_t)3);
}

/* A run of voxels, in the order vd_raster_triangle visits them: the
 * voxels' work inlined, without a call through two pointers a voxel. */
static void colour_span(void *vctx, int axis, int64_t x, int64_t y,
			int64_t z, int64_t n)
{
	struct colour_ctx *c = vctx;
	int64_t p[3] = {x, y, z};
	for (int64_t i = 0; i < n; i++, p[axis]++)
		colour_voxel(c, p[0], p[1], p[2]);
}

/* A triangle's voxels for the colour pass as the geometry pass finds
 * them: set by the brick rasterizer as bits of scratch blocks, then
 * walked a brick at a time. perf put a quarter of the terrain's colour
 * run in the span rasterizer and its one call a span (runs of 1-3
 * voxels); the bits cost what the geometry's did, and a brick's word and
 * rank are looked up once for all its voxels. A triangle over more than
 * TRI_BLOCKS blocks takes the spans. */
enum { TRI_BLOCKS = 64 };

struct tri_blocks {
	int n, overflow;
	uint64_t key[TRI_BLOCKS];
	uint64_t *mem;            /* TRI_BLOCKS zeroed blocks, block i at
				   * mem + i * BLOCK_WORDS */
};

static uint64_t *tri_block(void *ctx, uint64_t key)
{
	struct tri_blocks *t = ctx;
	for (int i = t->n - 1; i >= 0; i--)
		if (t->key[i] == key)
			return t->mem + (size_t)i * BLOCK_WORDS;
	if (t->n == TRI_BLOCKS) {
		t->overflow = 1;
		return NULL;
	}
	t->key[t->n] = key;
	return t->mem + (size_t)t->n++ * BLOCK_WORDS;
}

/* The voxels of triangle st within [clip_lo, clip_hi] into c's batches,
 * through the scratch blocks tb (left zeroed). Returns 0, having left
 * nothing behind, when they are too many blocks. */
static int colour_walk(struct colour_ctx *c, struct tri_blocks *tb,
		       const struct vd_snapped_tri *st, int L,
		       const int64_t clip_lo[3], const int64_t clip_hi[3])
{
	struct vd_brick_sink sink = {.block = tri_block, .ctx = tb};
	memcpy(sink.lo, c->lo, sizeof sink.lo);
	tb->n = tb->overflow = 0;
	vd_raster_triangle_bricks(st, L, clip_lo, clip_hi, &sink);
	if (tb->overflow) {
		memset(tb->mem, 0, (size_t)tb->n * BLOCK_WORDS * 8);
		return 0;
	}
	/* the bricks to look at: the triangle's voxel box (a voxel wider
	 * than the rasterizer's on every side), clipped, within the cell */
	const int sh = __builtin_ctzll((unsigned long long)c->s);
	int64_t vlo[3], vhi[3];
	for (int a = 0; a < 3; a++) {
		int64_t mn = st->v[0][a], mx = mn;
		for (int k = 1; k < 3; k++) {
			mn = st->v[k][a] < mn ? st->v[k][a] : mn;
			mx = st->v[k][a] > mx ? st->v[k][a] : mx;
		}
		vlo[a] = (mn >> sh) - 1;
		vhi[a] = (mx >> sh) + 1;
		vlo[a] = (vlo[a] < clip_lo[a] ? clip_lo[a] : vlo[a]) - c->lo[a];
		vhi[a] = (vhi[a] > clip_hi[a] ? clip_hi[a] : vhi[a]) - c->lo[a];
	}
	const struct worker *w = c->w;
	for (int i = 0; i < tb->n; i++) {
		uint64_t *tw = tb->mem + (size_t)i * BLOCK_WORDS;
		uint32_t b[3];
		vd_morton3_decode(tb->key[i], &b[0], &b[1], &b[2]);
		size_t bi = block_index(w, c->nb, tb->key[i]);
		int64_t k0[3], k1[3], org[3];
		for (int a = 0; a < 3; a++) {
			int64_t first = (int64_t)b[a] << BLOCK_SHIFT;
			int64_t l = vlo[a] > first ? vlo[a] : first;
			int64_t h = vhi[a] < first + 31 ? vhi[a] : first + 31;
			k0[a] = (l - first) >> 2;
			k1[a] = (h - first) >> 2;
			org[a] = c->lo[a] + first;
		}
		for (int64_t x = k0[0]; x <= k1[0]; x++)
			for (int64_t y = k0[1]; y <= k1[1]; y++)
				for (int64_t z = k0[2]; z <= k1[2]; z++) {
					unsigned wi = (unsigned)spread3[x] << 2 |
						      (unsigned)spread3[y] << 1 |
						      spread3[z];
					uint64_t m = tw[wi];
					if (!m)
						continue;
					tw[wi] = 0;
					if (bi == c->nb)
						continue; /* cannot be */
					colour_word(c, bi, wi, m, org[0] + 4 * x,
						    org[1] + 4 * y, org[2] + 4 * z);
				}
	}
	return 1;
}

/* The colour pass of a cell (whose geometry is complete; w->order[0..nb)
 * its sorted blocks, found through cb) in three steps: colour_tables
 * makes w's rank tables and zeroed colour slots, colour_pass visits the
 * cell's triangles again within a clip box (the cell, or one octant of
 * it on each worker), colour_compact leaves the colours in
 * w->vox[0..voxels) as RGB8 in place (the bytes at (uint8_t *)w->vox). */
static int colour_tables(struct run *r, struct worker *w,
			 const struct cell_blocks *cb, uint64_t cell,
			 size_t nb, uint64_t *voxels_out)
{
	if (nb > w->blk_cap) {
		size_t cap = nb * 2;
		uint64_t **bp = realloc(w->blk, cap * sizeof *bp);
		if (bp)
			w->blk = bp;
		uint64_t *base = realloc(w->base, cap * sizeof *base);
		if (base)
			w->base = base;
		uint16_t *pre = realloc(w->prefix, cap * BLOCK_WORDS *
					sizeof *pre);
		if (pre)
			w->prefix = pre;
		if (!bp || !base || !pre)
			return vd_fail(VD_ERR_NOMEM, "colour rank tables");
		w->blk_cap = cap;
	}
	uint64_t voxels = 0;
	for (size_t i = 0; i < nb; i++) {
		uint64_t *blk = w->bptr[i];
		w->blk[i] = blk;
		w->base[i] = voxels;
		unsigned in = 0;
		for (int j = 0; j < BLOCK_WORDS; j++) {
			w->prefix[i * BLOCK_WORDS + (size_t)j] = (uint16_t)in;
			in += (unsigned)vd_popcount64(blk[j]);
		}
		voxels += in;
	}
	/* exactly, now that the voxels are known: blocks, rank tables and
	 * colour slots within the worker's share */
	uint64_t need = (uint64_t)nb * BLOCK_COST +
			(uint64_t)w->blk_cap * (16 + BLOCK_WORDS * 2) +
			voxels * sizeof(struct vox_col);
	if (need > r->worker_bytes)
		return vd_fail(VD_ERR_BUDGET, "the colours of cell %llx (%llu "
			       "voxels) need %llu MiB with its blocks, more "
			       "than the budget's share per worker (%llu MiB); "
			       "%s", (unsigned long long)cell,
			       (unsigned long long)voxels,
			       (unsigned long long)(need >> 20) + 1,
			       (unsigned long long)(r->worker_bytes >> 20),
			       budget_advice(r));
	if (voxels > w->vox_cap) {
		free(w->vox);
		w->vox_cap = 0;
		if (!(w->vox = malloc(voxels * sizeof *w->vox)))
			return vd_fail(VD_ERR_NOMEM, "colours of %llu voxels",
				       (unsigned long long)voxels);
		w->vox_cap = voxels;
	}
	memset(w->vox, 0, voxels * sizeof *w->vox);
	*voxels_out = voxels;
	return VD_OK;
}

/* The colour pass over the voxels inside [clip_lo, clip_hi] of the cell
 * whose first voxel is `lo`, into w's tables, reading the bin with
 * `rd`'s buffer (w's own, or another worker's for an octant). */
static int colour_pass(struct run *r, struct worker *w, struct worker *rd,
		       size_t nb, const char *bin, const int64_t lo[3],
		       const int64_t clip_lo[3], const int64_t clip_hi[3])
{
	FILE *f = fopen(bin, "rb");
	if (!f)
		return vd_fail(VD_ERR_IO, "cannot read '%s': %s", bin,
			       strerror(errno));
	struct colour_ctx cc = {.w = w, .nb = nb, .s = vd_snap_voxel(r->g.L)};
#if NEAR_AVX2
	cc.simd = near_avx2();
#endif
	memcpy(cc.lo, lo, sizeof cc.lo);
	/* without the scratch blocks (or in the tests' reference pass),
	 * every triangle takes the spans */
	struct tri_blocks tb = {0};
	if (vd_colour_fast)
		tb.mem = calloc((size_t)TRI_BLOCKS * BLOCK_WORDS, 8);
	int err = VD_OK;
	size_t n;
	unsigned char *rb = (unsigned char *)rd->tris;
	while (!err && (n = fread(rb, BIN_BYTES_COL, TRI_BATCH, f)) > 0) {
		for (size_t i = 0; i < n && !err; i++) {
			struct bin_rec_col rec;
			memcpy(&rec.index, rb + i * BIN_BYTES_COL,
			       BIN_BYTES_COL);
			struct vd_triangle t;
			struct vd_snapped_tri st;
			memcpy(t.v, rec.v, sizeof t.v);
			err = vd_snap_triangle(&st, &t, &r->g.tr);
			if (err)
				break;
			cc.st = &st;
			near_tri_init(&cc.nt, st.v, cc.s);
			cc.a = &rec.a;
			cc.tex = vd_mesh_texture(r->mesh, rec.a.texture);
			cc.uniform = !(rec.a.texture >= 0 && cc.tex) &&
				     !memcmp(rec.a.rgb[0], rec.a.rgb[1], 3) &&
				     !memcmp(rec.a.rgb[0], rec.a.rgb[2], 3);
			if (!tb.mem || !colour_walk(&cc, &tb, &st, r->g.L,
						    clip_lo, clip_hi))
				vd_raster_triangle_spans(&st, r->g.L, clip_lo,
							 clip_hi, colour_span,
							 &cc);
			colour_finish(&cc);
		}
	}
	if (!err && ferror(f))
		err = vd_fail(VD_ERR_IO, "cannot read '%s'", bin);
	fclose(f);
	free(tb.mem);
	return err;
}

static int colour_compact(struct worker *w, uint64_t cell, uint64_t voxels)
{
	/* RGB8 in place: byte 3i is written after slot i was read */
	uint8_t *rgb = (uint8_t *)w->vox;
	for (uint64_t i = 0; i < voxels; i++) {
		if (!w->vox[i].set)
			return vd_fail(VD_ERR_INTERNAL, "cell %llx: voxel %llu "
				       "got no colour", (unsigned long long)cell,
				       (unsigned long long)i);
		uint8_t c[3] = {w->vox[i].rgb[0], w->vox[i].rgb[1],
				w->vox[i].rgb[2]};
		memcpy(rgb + 3 * i, c, 3);
	}
	return VD_OK;
}

static int colour_cell(struct run *r, struct worker *w,
		       const struct cell_blocks *cb, uint64_t cell, size_t nb,
		       const char *bin, const int64_t lo[3],
		       const int64_t hi[3], uint64_t *voxels_out)
{
	double t0 = vd_seconds();
	uint64_t voxels = 0;
	int err = colour_tables(r, w, cb, cell, nb, &voxels);
	if (!err)
		err = colour_pass(r, w, w, nb, bin, lo, lo, hi);
	if (!err)
		err = colour_compact(w, cell, voxels);
	*voxels_out = voxels;
	w->seconds_colour += vd_seconds() - t0;
	return err;
}

/* Adds a written cell's counts to the run's. */
static void cell_counted(struct run *r, const uint64_t *counts,
			 uint64_t nbricks)
{
	atomic_fetch_add(&r->bricks, nbricks);
	atomic_fetch_add(&r->voxels, counts[r->g.L - r->g.L0]);
	pthread_mutex_lock(&r->lock);
	for (int l = 0; l <= r->g.L - r->g.L0; l++)
		r->level_nodes[l] += counts[l];
	pthread_mutex_unlock(&r->lock);
}

struct split_cell {
	struct run *r;
	uint64_t cell;
	int64_t lo[3];        /* the cell's first voxel */
	int64_t half;         /* an octant's side, voxels */
	int owner[8];         /* the worker that did each octant */
	char path[4096];      /* the cell's bin */
	size_t nb;            /* its blocks (colour pass) */
	/* the triangles in memory (run.mem_tris): those that may reach
	 * octant k are sel[sel_at[k] .. sel_at[k + 1]) */
	uint32_t *sel;
	size_t sel_at[9];
};

static int colour_split(struct run *r, struct split_cell *sc,
			const struct cell_blocks *cb, uint64_t *voxels_out);

/* Removes the bin files of `cell` (its bin at `path`, or its geometry
 * bins: .tri and .big, of the cell or of its octants). */
static void unlink_bins(const struct run *r, uint64_t cell, const char *path)
{
	unlink(path);
	if (r->colours)
		return;
	char p[4096];
	for (uint64_t k = 0; k < (r->sub_bins ? 8u : 1u); k++)
		for (int big = 0; big < 2; big++) {
			bin_file(p, sizeof p, r->outdir, r->sub_bins,
				 r->sub_bins ? cell << 3 | k : cell, big);
			unlink(p);
		}
}

/* The rest of a cell once its geometry is in maps[0..nmaps) (found
 * through cb): the colour pass when there are colours (here, or on every
 * worker for a split cell `sc`), the bin removed, the SVO chunk and the
 * colour chunk written, the counts added. */
static int finish_cell(struct run *r, struct worker *w,
		       const struct cell_blocks *cb,
		       struct block_map *const *maps, int nmaps,
		       uint64_t cell, const char *path, const int64_t lo[3],
		       const int64_t hi[3], struct split_cell *sc)
{
	uint64_t counts[VD_MAX_LEVELS + 1], nbricks = 0, ncol = 0;
	size_t nb = 0;
	int err = gather_blocks(w, maps, nmaps, &nb);
	if (sc)
		sc->nb = nb;
	if (!err && r->colours && nb)
		err = sc ? colour_split(r, sc, cb, &ncol)
			 : colour_cell(r, w, cb, cell, nb, path, lo, hi, &ncol);
	unlink_bins(r, cell, path);
	if (!err && atomic_load(&r->failed))
		return VD_OK; /* a worker's failure, said by the caller */
	struct vd_chunk_header h;
	uint64_t digest = 0;
	if (!err)
		/* a split cell's other workers wait for this one: the
		 * section's frames are compressed on all of them */
		err = write_cell(r, w, cb, cell, nb, sc ? r->nworkers : 1,
				 counts, &nbricks,
				 r->colours ? &h : NULL, &digest);
	if (!err && r->colours && nbricks) {
		char name[64], cpath[4096];
		vd_chunk_file_name(name, sizeof name, r->g.L0, cell, "col");
		snprintf(cpath, sizeof cpath, "%s/%s", r->outdir, name);
		err = vd_colours_save(cpath, &h, digest, (uint8_t *)w->vox,
				      ncol, r->opts->provenance);
	}
	if (!err && nbricks)
		cell_counted(r, counts, nbricks);
	return err;
}

void vd_sort_keys(uint64_t *a, uint64_t *tmp, size_t n, int lo, int bits)
{
	for (int sh = lo; sh < lo + bits; sh += 8) {
		size_t cnt[257] = {0};
		for (size_t i = 0; i < n; i++)
			cnt[(a[i] >> sh & 255) + 1]++;
		for (int d = 0; d < 256; d++)
			cnt[d + 1] += cnt[d];
		for (size_t i = 0; i < n; i++)
			tmp[cnt[a[i] >> sh & 255]++] = a[i];
		uint64_t *t = a;
		a = tmp;
		tmp = t;
	}
	if (((bits + 7) / 8) & 1)
		memcpy(tmp, a, n * sizeof *a); /* back into the caller's */
}

/* Triangles raster_bin reads at a time: fewer with colours, whose
 * records are more than twice as long, so the buffer stays a small part
 * of WORKER_OVERHEAD. */
/* The clip box in world units, a voxel wider on every side: a triangle
 * whose bounds miss it cannot reach the clip box (snapping moves a vertex
 * by far less than a voxel), so it is not snapped and clipped only to be
 * dropped, which an octant of a split cell would do for 7 of every 8
 * triangles. */
static void clip_world(const struct run *r, const int64_t clip_lo[3],
		       const int64_t clip_hi[3], double wlo[3], double whi[3])
{
	const double vs = (double)r->g.tr.root_side / (double)((int64_t)1 << r->g.L);
	for (int a = 0; a < 3; a++) {
		wlo[a] = r->g.tr.origin[a] + (double)(clip_lo[a] - 1) * vs;
		whi[a] = r->g.tr.origin[a] + (double)(clip_hi[a] + 2) * vs;
	}
}

/* 1 if the triangle's bounds miss the box of clip_world. NaN bounds miss
 * nothing: such a triangle goes on to the snap, which rejects it. */
static inline int tri_misses(const float v[3][3], const double wlo[3],
			     const double whi[3])
{
	int miss = 0;
	for (int a = 0; a < 3; a++) {
		float mn = v[0][a], mx = v[0][a];
		for (int k = 1; k < 3; k++) {
			mn = v[k][a] < mn ? v[k][a] : mn;
			mx = v[k][a] > mx ? v[k][a] : mx;
		}
		miss |= (double)mx < wlo[a] || (double)mn > whi[a];
	}
	return miss;
}

/* Gives back the whole pages of mem_tris before triangle `at`, from
 * *released (bytes) on: the last blocks of a cell are made while its first
 * triangles are no longer needed, and the end of its rasterization is the
 * run's peak (the terrain at 2^14: 50 MB of triangles beside 510 MB of
 * blocks). The pages read as zeros after: nothing reads them again. */
static void release_tris(const struct run *r, size_t at, uintptr_t *released)
{
	const uintptr_t page = 4096;
	uintptr_t base = (uintptr_t)r->mem_tris;
	uintptr_t lo = (base + *released + page - 1) & ~(page - 1);
	uintptr_t hi = (base + at * sizeof *r->mem_tris) & ~(page - 1);
	if (hi > lo && !madvise((void *)lo, hi - lo, MADV_DONTNEED))
		*released = hi - base;
}

static size_t raster_batch(const struct run *r)
{
	return r->colours ? TRI_BATCH : RASTER_BATCH;
}

/* progress inside a cell (large cells take minutes): n more of the
 * r->pairs_total records rasterized */
static void raster_progress(struct run *r, size_t n)
{
	uint64_t pd = atomic_fetch_add(&r->pairs_done, n) + n;
	double el = vd_seconds() - r->prog->start;
	progress_say(r->prog, 0, "voxelizing: %llu of %llu triangles "
		     "(in cells), %zu/%zu cells done, ETA %.0fs",
		     (unsigned long long)pd,
		     (unsigned long long)r->pairs_total,
		     atomic_load(&r->done), r->njobs,
		     pd && pd < r->pairs_total ?
		     el / (double)pd * (double)(r->pairs_total - pd) : 0);
}

static int budget_fail(struct run *r, struct worker *w, uint64_t cell)
{
	return vd_fail(VD_ERR_BUDGET, "cell %llx needs more than %llu "
		       "MiB, the budget's share per %s (%zu blocks of "
		       "32^3 voxels); %s", (unsigned long long)cell,
		       (unsigned long long)(r->worker_bytes >> 20),
		       w->map.shared ? "cell" : "worker", w->map.limit,
		       budget_advice(r));
}

/* The sink that puts a cell's bricks into w's blocks, from the cell's
 * first voxel; returns the levels below the cell (L - L0). */
static int cell_sink(const struct run *r, struct worker *w, uint64_t cell,
		     struct vd_brick_sink *sink)
{
	int shift = r->g.L - r->g.L0;
	uint32_t c[3];
	vd_morton3_decode(cell, &c[0], &c[1], &c[2]);
	*sink = (struct vd_brick_sink){.block = sink_block, .ctx = &w->map};
	for (int a = 0; a < 3; a++)
		sink->lo[a] = (int64_t)c[a] << shift;
	return shift;
}

/* raster_bin of a geometry bin (snapped records, bin_rec): the .tri and
 * .big files of bin `key` (a cell of L0, or of L0 + 1 with octant bins)
 * of `cell`, clipped to [clip_lo, clip_hi]. Same order of work as
 * raster_bin (a batch in the Morton order of its first corners); the
 * triangles whose bounds miss the clip box are not rasterized. */
static int raster_snapped(struct run *r, struct worker *w, uint64_t cell,
			  uint64_t key, const int64_t clip_lo[3],
			  const int64_t clip_hi[3], int count)
{
	struct vd_brick_sink sink;
	int shift = cell_sink(r, w, cell, &sink);
	/* the clip box on the lattice, a voxel wider on every side (a
	 * triangle whose bounds miss it reaches no voxel of the box) */
	const int vsh = VD_SNAP_ROOT_BITS - r->g.L;
	int64_t blo[3], bhi[3];
	for (int a = 0; a < 3; a++) {
		blo[a] = (clip_lo[a] - 1) * ((int64_t)1 << vsh);
		bhi[a] = (clip_hi[a] + 2) * ((int64_t)1 << vsh);
	}
	/* raster_bin's batch order: blocks of 2^ksh voxels */
	int ksh = BLOCK_SHIFT;
	if (shift - ksh > 10)
		ksh = shift - 10;
	const uint32_t kmax = shift > ksh ? (1u << (shift - ksh)) - 1 : 0;
	const int qsh = vsh + ksh;
	int err = VD_OK;
	char path[4096];
	for (int big = 0; big < 2 && !err && !w->map.over; big++) {
		bin_file(path, sizeof path, r->outdir, r->sub_bins, key, big);
		FILE *f = fopen(path, "rb");
		if (!f) {
			if (errno == ENOENT)
				continue; /* no triangle of this kind */
			return vd_fail(VD_ERR_IO, "cannot read '%s': %s", path,
				       strerror(errno));
		}
		size_t rec = big ? BIN_BIG_BYTES : BIN_SMALL_BYTES, n;
		const unsigned char *rb = (const unsigned char *)w->tris;
		while (!err && !w->map.over &&
		       (n = fread(w->tris, rec, RASTER_BATCH, f)) > 0) {
			uint64_t *ord = w->order_tri;
			size_t m = 0;
			for (size_t i = 0; i < n; i++) {
				struct vd_snapped_tri st;
				bin_record(rb + rec * i, big, &st);
				int miss = 0;
				uint32_t q[3];
				for (int a = 0; a < 3; a++) {
					int64_t mn = st.v[0][a], mx = st.v[0][a];
					for (int k = 1; k < 3; k++) {
						mn = st.v[k][a] < mn ? st.v[k][a] : mn;
						mx = st.v[k][a] > mx ? st.v[k][a] : mx;
					}
					miss |= mx < blo[a] || mn > bhi[a];
					int64_t g = (st.v[0][a] >> qsh) -
						    (sink.lo[a] >> ksh);
					q[a] = g < 0 ? 0 : g >= (int64_t)kmax ? kmax
									   : (uint32_t)g;
				}
				if (!miss)
					ord[m++] = vd_morton3(q[0], q[1], q[2]) << 16 | i;
			}
			vd_sort_keys(ord, ord + RASTER_BATCH, m, 16,
				     3 * (shift > ksh ? shift - ksh : 0));
			for (size_t o = 0; o < m && !w->map.over; o++) {
				size_t i = (size_t)(ord[o] & 0xffff);
				if (o + 4 < m)
					__builtin_prefetch(rb + rec * (ord[o + 4] & 0xffff));
				struct vd_snapped_tri st;
				bin_record(rb + rec * i, big, &st);
				vd_raster_triangle_bricks(&st, r->g.L, clip_lo,
							  clip_hi, &sink);
			}
			if (count)
				raster_progress(r, n);
		}
		if (ferror(f))
			err = vd_fail(VD_ERR_IO, "cannot read '%s'", path);
		fclose(f);
	}
	if (!err && w->map.over)
		err = budget_fail(r, w, cell);
	return err;
}

/* Rasterizes the triangles of `cell`'s bin (at `path`, or r->mem_tris)
 * into w's map, clipped to [clip_lo, clip_hi]: the whole cell, or one
 * octant of a split cell. With `sel`, only mem_tris[sel[0..nsel)] (those
 * that may reach the octant). `count`: this pass counts the triangles for
 * the progress line (a split cell's octants all read them; one counts). */
static int raster_bin(struct run *r, struct worker *w, uint64_t cell,
		      const char *path, const uint32_t *sel, size_t nsel,
		      const int64_t clip_lo[3], const int64_t clip_hi[3],
		      int count)
{
	struct vd_brick_sink sink;
	int shift = cell_sink(r, w, cell, &sink);
	FILE *f = NULL;
	if (!r->mem_tris && !(f = fopen(path, "rb")))
		return vd_fail(VD_ERR_IO, "cannot read '%s': %s", path,
			       strerror(errno));
	/* with colours a record is bin_rec_col after its cell: index,
	 * then the corners */
	size_t rec = r->colours ? BIN_BYTES_COL : BIN_BYTES_GEOM;
	size_t off = r->colours ? sizeof(uint64_t) : 0;
	double wlo[3], whi[3];
	clip_world(r, clip_lo, clip_hi, wlo, whi);
	/* the batch is rasterized in the Morton order of its triangles'
	 * first corners (blocks of 2^ksh voxels, 10 bits an axis at most),
	 * so the triangles that share a block come together while its
	 * lines are in cache: a mesh's own order returns to a block
	 * after a whole strip of others (a tenth of the terrain's time was
	 * the misses of setting voxels) */
	int ksh = BLOCK_SHIFT;
	if (shift - ksh > 10)
		ksh = shift - 10;
	const double kscale = (double)((int64_t)1 << r->g.L) /
			      (double)r->g.tr.root_side / (double)((int64_t)1 << ksh);
	const uint32_t kmax = shift > ksh ? (1u << (shift - ksh)) - 1 : 0;
	int err = VD_OK;
	size_t n, at = 0;
	uintptr_t released = 0; /* bytes of mem_tris given back */
	while (!err && !w->map.over) {
		const unsigned char *rb = (const unsigned char *)w->tris;
		if (f) {
			n = fread(w->tris, rec, raster_batch(r), f);
		} else if (sel) {
			n = nsel - at < RASTER_BATCH ? nsel - at : RASTER_BATCH;
			struct vd_triangle *to = w->tris;
			for (size_t i = 0; i < n; i++)
				to[i] = r->mem_tris[sel[at + i]];
			at += n;
		} else {
			/* mem_tris: a vd_triangle a record (BIN_BYTES_GEOM) */
			n = r->mem_n - at < RASTER_BATCH ? r->mem_n - at
							 : RASTER_BATCH;
			rb = (const unsigned char *)(r->mem_tris + at);
			at += n;
		}
		if (n == 0)
			break;
		uint64_t *ord = w->order_tri;
		size_t m = 0; /* triangles kept: an octant keeps about 1/8 */
		for (size_t i = 0; i < n; i++) {
			float v[3][3];
			memcpy(v, rb + rec * i + off, sizeof v);
			if (tri_misses(v, wlo, whi))
				continue;
			uint32_t q[3];
			for (int a = 0; a < 3; a++) {
				double g = ((double)v[0][a] - r->g.tr.origin[a]) *
					   kscale - (double)(sink.lo[a] >> ksh);
				q[a] = !(g > 0) ? 0 : g >= (double)kmax ? kmax :
				       (uint32_t)g;
			}
			ord[m++] = vd_morton3(q[0], q[1], q[2]) << 16 | i;
		}
		vd_sort_keys(ord, ord + RASTER_BATCH, m, 16,
			  3 * (shift > ksh ? shift - ksh : 0));
		for (size_t o = 0; o < m && !err && !w->map.over; o++) {
			size_t i = (size_t)(ord[o] & 0xffff);
			if (o + 4 < m) /* the batch is 2.4 MB: past L2 */
				__builtin_prefetch(rb + rec * (ord[o + 4] & 0xffff) + off);
			struct vd_triangle t;
			struct vd_snapped_tri st;
			memcpy(t.v, rb + rec * i + off, sizeof t.v);
			err = vd_snap_triangle(&st, &t, &r->g.tr);
			if (!err)
				vd_raster_triangle_bricks(&st, r->g.L, clip_lo,
							  clip_hi, &sink);
		}
		if (r->mem_once && !f && !sel)
			release_tris(r, at, &released);
		if (count)
			raster_progress(r, n);
	}
	if (f && !err && ferror(f))
		err = vd_fail(VD_ERR_IO, "cannot read '%s'", path);
	if (f)
		fclose(f);
	if (!err && w->map.over)
		err = budget_fail(r, w, cell);
	return err;
}

static int voxelize_cell(struct run *r, struct worker *w, uint64_t cell)
{
	int shift = r->g.L - r->g.L0;
	uint32_t c[3];
	vd_morton3_decode(cell, &c[0], &c[1], &c[2]);
	int64_t lo[3], hi[3];
	int64_t top = ((int64_t)1 << r->g.L) - 1;
	for (int a = 0; a < 3; a++) {
		lo[a] = (int64_t)c[a] << shift;
		hi[a] = lo[a] + ((int64_t)1 << shift) - 1;
		if (hi[a] > top)
			hi[a] = top;
	}
	w->map.limit = r->block_limit;

	char path[4096];
	bin_path(path, sizeof path, r->outdir, cell);
	int err = VD_OK;
	if (r->colours || r->mem_tris) {
		err = raster_bin(r, w, cell, path, NULL, 0, lo, hi, 1);
	} else if (!r->sub_bins) {
		err = raster_snapped(r, w, cell, cell, lo, hi, 1);
	} else {
		/* octant bins of a cell planned to be split: each octant's
		 * triangles clipped to it, into the one map */
		int64_t half = ((int64_t)1 << shift) / 2;
		for (uint64_t k = 0; k < 8 && !err; k++) {
			int64_t plo[3], phi[3];
			for (int a = 0; a < 3; a++) {
				plo[a] = lo[a] + (int64_t)(k >> (2 - a) & 1) * half;
				phi[a] = plo[a] + half - 1;
			}
			err = raster_snapped(r, w, cell, cell << 3 | k, plo, phi, 1);
		}
	}
	tri_cache_done(r); /* one cell: this one */
	struct block_map *mp = &w->map;
	struct cell_blocks cb = {.part_shift = 0};
	for (int k = 0; k < 8; k++)
		cb.map[k] = mp;
	if (!err)
		err = finish_cell(r, w, &cb, &mp, 1, cell, path, lo, hi, NULL);
	else
		unlink_bins(r, cell, path);
	if (map_reset(&w->map) && !err)
		err = vd_fail(VD_ERR_NOMEM, "block list");
	return err;
}

/* ------------------------------------------ one cell on all the threads
 * When there are few cells for the threads (a scene of one cell, or a few
 * large ones), whole cells per thread leave threads idle. Then the cells
 * go one after another and each is rasterized by all the workers, an
 * octant at a time: a worker reads the cell's bin, keeps the triangles
 * that reach its octant and rasterizes them clipped to it, into its own
 * map. Octants are whole blocks, so every block is in one map, and the
 * cell's bricks are written from all the maps in Morton order: the same
 * chunk as one worker writes. The colour pass goes the same way, an
 * octant per worker, into one set of rank tables. */


static void octant_box(const struct split_cell *sc, size_t k,
		       int64_t plo[3], int64_t phi[3])
{
	for (int a = 0; a < 3; a++) {
		/* Morton: x is the high bit of the octant, z the low */
		plo[a] = sc->lo[a] + (int64_t)(k >> (2 - a) & 1) * sc->half;
		phi[a] = plo[a] + sc->half - 1;
	}
}

static void octant_task(void *ctx, size_t k, int worker)
{
	struct split_cell *sc = ctx;
	struct run *r = sc->r;
	sc->owner[k] = worker;
	if (atomic_load(&r->failed))
		return;
	int64_t plo[3], phi[3];
	octant_box(sc, k, plo, phi);
	int err;
	if (r->colours || r->mem_tris)
		err = raster_bin(r, &r->workers[worker], sc->cell, sc->path,
				 sc->sel ? sc->sel + sc->sel_at[k] : NULL,
				 sc->sel ? sc->sel_at[k + 1] - sc->sel_at[k] : 0,
				 plo, phi, k == 0);
	else
		err = raster_snapped(r, &r->workers[worker], sc->cell,
				     r->sub_bins ? sc->cell << 3 | k : sc->cell,
				     plo, phi, r->sub_bins || k == 0);
	if (err)
		run_fail(r, err);
}

/* The colour pass of octant k, into worker 0's tables. */
static void colour_octant_task(void *ctx, size_t k, int worker)
{
	struct split_cell *sc = ctx;
	struct run *r = sc->r;
	if (atomic_load(&r->failed))
		return;
	int64_t plo[3], phi[3];
	octant_box(sc, k, plo, phi);
	int err = colour_pass(r, &r->workers[0], &r->workers[worker], sc->nb,
			      sc->path, sc->lo, plo, phi);
	if (err)
		run_fail(r, err);
}

/* The colour pass of a split cell on every worker, an octant each: each
 * voxel is in one octant and sees the cell's triangles in bin order, so
 * the colours are those of one worker's pass. */
static int colour_split(struct run *r, struct split_cell *sc,
			const struct cell_blocks *cb, uint64_t *voxels_out)
{
	struct worker *w = &r->workers[0];
	double t0 = vd_seconds();
	uint64_t voxels = 0;
	int err = colour_tables(r, w, cb, sc->cell, sc->nb, &voxels);
	if (!err)
		err = vd_parallel_for(8, r->nworkers, colour_octant_task, sc);
	if (!err && atomic_load(&r->failed))
		return VD_OK; /* said by the caller, from r->err */
	if (!err)
		err = colour_compact(w, sc->cell, voxels);
	*voxels_out = voxels;
	w->seconds_colour += vd_seconds() - t0;
	return err;
}

/* A split cell rasterized from memory: the triangles that may reach each
 * octant (raster_bin's test, with the bounds of a triangle found once),
 * listed once instead of all eight octants testing every triangle. When
 * the list cannot be made, sc->sel stays NULL and the octants test. */
static void select_octants(struct split_cell *sc)
{
	const struct run *r = sc->r;
	size_t n = r->mem_n;
	if (!r->mem_tris || n > UINT32_MAX)
		return;
	/* per axis, the low half's box (octant 0) and the high half's (7) */
	double wlo[2][3], whi[2][3];
	for (int h = 0; h < 2; h++) {
		int64_t plo[3], phi[3];
		octant_box(sc, h ? 7 : 0, plo, phi);
		clip_world(r, plo, phi, wlo[h], whi[h]);
	}
	uint8_t *mask = malloc(n ? n : 1);
	if (!mask)
		return;
	size_t cnt[8] = {0};
	for (size_t i = 0; i < n; i++) {
		const struct vd_triangle *t = &r->mem_tris[i];
		unsigned in[3]; /* bit h: reaches half h of the axis */
		for (int a = 0; a < 3; a++) {
			float mn = t->v[0][a], mx = t->v[0][a];
			for (int k = 1; k < 3; k++) {
				mn = t->v[k][a] < mn ? t->v[k][a] : mn;
				mx = t->v[k][a] > mx ? t->v[k][a] : mx;
			}
			in[a] = 0;
			for (int h = 0; h < 2; h++)
				in[a] |= (unsigned)!((double)mx < wlo[h][a] ||
						     (double)mn > whi[h][a]) << h;
		}
		unsigned m = 0;
		for (int k = 0; k < 8; k++) /* Morton: x is k's high bit */
			m |= (in[0] >> (k >> 2 & 1) & in[1] >> (k >> 1 & 1) &
			      in[2] >> (k & 1) & 1u) << k;
		mask[i] = (uint8_t)m;
		for (int k = 0; k < 8; k++)
			cnt[k] += m >> k & 1;
	}
	size_t at[9] = {0};
	for (int k = 0; k < 8; k++)
		at[k + 1] = at[k] + cnt[k];
	sc->sel = malloc((at[8] ? at[8] : 1) * sizeof *sc->sel);
	if (sc->sel) {
		memcpy(sc->sel_at, at, sizeof at);
		for (size_t i = 0; i < n; i++)
			for (int k = 0; k < 8; k++)
				if (mask[i] >> k & 1)
					sc->sel[at[k]++] = (uint32_t)i;
	}
	free(mask);
}

static int split_cell(struct run *r, uint64_t cell)
{
	int shift = r->g.L - r->g.L0;
	uint32_t c[3];
	vd_morton3_decode(cell, &c[0], &c[1], &c[2]);
	struct split_cell sc = {.r = r, .cell = cell,
				.half = (int64_t)1 << (shift - 1)};
	for (int a = 0; a < 3; a++)
		sc.lo[a] = (int64_t)c[a] << shift;
	bin_path(sc.path, sizeof sc.path, r->outdir, cell);
	/* the cell's blocks, wherever they are, within one limit */
	atomic_store(&r->split_blocks, 0);
	for (int i = 0; i < r->nworkers; i++) {
		r->workers[i].map.limit = r->block_limit;
		r->workers[i].map.shared = &r->split_blocks;
	}
	select_octants(&sc);
	int err = vd_parallel_for(8, r->nworkers, octant_task, &sc);
	tri_cache_done(r);
	free(sc.sel);
	sc.sel = NULL;
	struct block_map *maps[8];
	struct cell_blocks cb = {.part_shift = 3 * (shift - 1 - BLOCK_SHIFT)};
	int nmaps = 0;
	for (int k = 0; k < 8; k++) {
		struct block_map *m = &r->workers[sc.owner[k]].map;
		cb.map[k] = m;
		int seen = 0;
		for (int j = 0; j < nmaps; j++)
			seen |= maps[j] == m;
		if (!seen)
			maps[nmaps++] = m;
	}
	/* a worker's failure is in r->err and r->detail, said by the caller */
	if (!err && !atomic_load(&r->failed)) {
		int64_t hi[3];
		for (int a = 0; a < 3; a++)
			hi[a] = sc.lo[a] + 2 * sc.half - 1;
		err = finish_cell(r, &r->workers[0], &cb, maps, nmaps, cell,
				  sc.path, sc.lo, hi, &sc);
	} else {
		unlink_bins(r, cell, sc.path);
	}
	/* freed, not kept: the next cell's blocks may fall to other
	 * workers, and kept blocks would add up beyond one cell's */
	for (int i = 0; i < r->nworkers; i++)
		map_free(&r->workers[i].map);
	return err;
}

/* One more cell done: the count and the progress line. */
static void cell_done(struct run *r)
{
	size_t done = atomic_fetch_add(&r->done, 1) + 1;
	double el = vd_seconds() - r->prog->start;
	progress_say(r->prog, 0, "voxelizing cells %zu/%zu, %llu voxels, "
		     "ETA %.0fs", done, r->njobs,
		     (unsigned long long)atomic_load(&r->voxels),
		     el / (double)done * (double)(r->njobs - done));
}

static void cell_task(void *ctx, size_t i, int worker)
{
	struct run *r = ctx;
	if (atomic_load(&r->failed))
		return;
	int err = voxelize_cell(r, &r->workers[worker], r->jobs[i].cell);
	if (err) {
		run_fail(r, err);
		return;
	}
	cell_done(r);
}

static int cmp_jobs(const void *a, const void *b)
{
	const struct cell_job *x = a, *y = b;
	if (x->blocks != y->blocks)
		return x->blocks < y->blocks ? 1 : -1; /* largest first */
	return (x->cell > y->cell) - (x->cell < y->cell);
}

/* Removes the scratch directory of bins. */
static void remove_bins(const char *dir)
{
	char bins[4096], f[4400];
	snprintf(bins, sizeof bins, "%s/bins.tmp", dir);
	DIR *d = opendir(bins);
	if (!d)
		return;
	struct dirent *e;
	while ((e = readdir(d)))
		if (e->d_name[0] != '.') {
			snprintf(f, sizeof f, "%s/%s", bins, e->d_name);
			unlink(f);
		}
	closedir(d);
	rmdir(bins);
}

void vd_remove_chunks(const char *dir)
{
	DIR *d = opendir(dir);
	if (!d)
		return;
	struct dirent *e;
	char path[4400];
	while ((e = readdir(d))) {
		size_t n = strlen(e->d_name);
		if ((strncmp(e->d_name, "chunk-L", 7) == 0 &&
		     ((n > 4 && strcmp(e->d_name + n - 4, ".svo") == 0) ||
		      (n > 4 && strcmp(e->d_name + n - 4, ".col") == 0) ||
		      strstr(e->d_name, ".svo.tmp.") ||
		      strstr(e->d_name, ".col.tmp."))) ||
		    strcmp(e->d_name, "voxelize.stats.json") == 0) {
			snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
			unlink(path);
		}
	}
	closedir(d);
}

/* Deletes chunk files and bins of an earlier run in `dir`. */
static int clean_outdir(const char *dir)
{
	if (mkdir(dir, 0777) != 0 && errno != EEXIST)
		return vd_fail(VD_ERR_IO, "cannot create '%s': %s", dir,
			       strerror(errno));
	vd_remove_chunks(dir);
	char path[4096];
	remove_bins(dir);
	snprintf(path, sizeof path, "%s/bins.tmp", dir);
	if (mkdir(path, 0777) != 0)
		return vd_fail(VD_ERR_IO, "cannot create '%s': %s", path,
			       strerror(errno));
	return VD_OK;
}

/* ------------------------------------------------------------ the driver */

struct plan {
	int L0, threads;
	size_t block_limit;
	uint64_t worker_bytes;  /* each worker's share */
	int want;               /* the threads asked for */
	uint64_t avail;         /* the budget left for the workers */
	uint64_t cell_blocks;   /* the blocks planned for the largest cell */
};

/* Per-cell arrays of the binning and the jobs at chunk level l: allocated
 * for every cell but resident only in the pages of the bins array that
 * non-empty cells touch (`pages`, counted by the estimate) and the job list
 * (`pages` is 0 when unknown: all of it). */
static uint64_t cell_arrays_bytes(int l, uint64_t pages)
{
	uint64_t all = ((uint64_t)1 << 3 * l) *
		       (sizeof(uint64_t) + sizeof(struct cell_job));
	uint64_t touched = pages * (4096 + 512 * sizeof(struct cell_job));
	return pages && touched < all ? touched : all;
}

/* Memory the workers may use: the budget less what the process holds. */
static int plan_budget(const struct vd_voxelize_opts *o, uint64_t base,
		       int max_level, const uint64_t *max_blocks,
		       const uint64_t *nonempty, int coarse,
		       uint64_t block_cost, struct plan *p)
{
	int threads = o->threads > 0 ? o->threads : vd_hardware_threads();
	for (int want = threads; want >= 1; want = want > 1 ? 1 : 0) {
		for (int l = 0; l <= max_level; l++) {
			if (max_blocks[l] == UINT64_MAX)
				continue; /* level not a candidate */
			uint64_t held = base + cell_arrays_bytes(l, nonempty[l]);
			uint64_t avail = o->mem_budget_bytes > held
						 ? o->mem_budget_bytes - held : 0;
			uint64_t cells = (uint64_t)1 << 3 * l;
			int t = (uint64_t)want > cells ? (int)cells : want;
			uint64_t per = max_blocks[l] * block_cost + WORKER_OVERHEAD;
			if ((uint64_t)t * per <= avail) {
				p->L0 = l;
				p->threads = t;
				/* each worker may grow to its share */
				uint64_t share = avail / (uint64_t)t - WORKER_OVERHEAD;
				p->block_limit = (size_t)(share / block_cost);
				p->worker_bytes = share;
				p->want = threads;
				p->avail = avail;
				p->cell_blocks = max_blocks[l];
				return VD_OK;
			}
		}
	}
	int l = max_level;
	while (l > 0 && max_blocks[l] == UINT64_MAX)
		l--;
	uint64_t need = max_blocks[l] * block_cost + WORKER_OVERHEAD + base +
			cell_arrays_bytes(l, nonempty[l]);
	return vd_fail(VD_ERR_BUDGET, "--mem-budget %llu MiB cannot hold one "
		       "cell even at chunk level %d (about %llu MiB needed%s)",
		       (unsigned long long)(o->mem_budget_bytes >> 20), l,
		       (unsigned long long)(need >> 20) + 1,
		       coarse ? ", a coarse upper bound" : "");
}

/* What the driver's passes share. vd_voxelize_mesh sets it up; each pass
 * reads what the passes before it left and adds its own; driver_release
 * frees it, whatever pass stopped. */
struct driver {
	const char *mesh_path, *outdir;
	const struct vd_voxelize_opts *opts;
	struct vd_voxelize_result *res;
	struct vd_voxelize_budget share; /* the fixed shares (budget.h) */
	double t0;
	int max_level;           /* the deepest chunk level --levels allows */
	int F;                   /* the deepest candidate chunk level */
	struct progress prog;
	struct vd_mesh *mesh;
	struct vd_triangle *tris;  /* a pass's batch: TRI_BATCH, or
				    * FEED_SLOTS of them (struct feed) */
	struct vd_tri_attr *attrs; /* its attributes, with colours */
	int feed_threads;          /* > 1: the mesh is read on a thread of
				    * its own (struct feed) */
	struct tri_cache cache;    /* the first pass's copy of the triangles */
	struct bounds bd;
	struct estimate est;
	uint64_t *bkeys;           /* the estimate's block keys, sorted */
	size_t nbkeys;
	/* per candidate level: the largest cell's blocks (UINT64_MAX: not a
	 * candidate), at level F also a lower bound of it, and the pages of
	 * the per-cell arrays non-empty cells touch (0: all) */
	uint64_t max_blocks[MAX_CHUNK_LEVEL + 1];
	uint64_t min_blocks[MAX_CHUNK_LEVEL + 1];
	uint64_t cells_hit[MAX_CHUNK_LEVEL + 1];
	uint64_t block_cost;       /* bytes a block costs a worker */
	struct plan plan;
	struct binner b;
	struct run r;
	uint64_t nodes[VD_MAX_LEVELS + 1]; /* levels L0..L, summed by workers */
	int split;                 /* each cell on all the workers */
	int cleaned;               /* outdir cleaned: a failure empties it */
	int guessed;               /* estimate_cells gathers the bounds too
				    * (guess_grid) */
};

/* Pass 1, bounds: reads the whole mesh once for its tight bounding box,
 * which fixes the grid (d->r.g.tr, g.L), and keeps the triangles in
 * d->cache when they fit its share. Memory: the mesh reader (vertices up
 * to share.vertex_bytes), the batch, the cache (share.tri_cache_bytes)
 * and, with colours, the textures the file names. */
static int bounds_grid(struct driver *d);

static int read_bounds(struct driver *d)
{
	progress_say(&d->prog, 1, "reading %s (%s)", d->mesh_path,
		     vd_mesh_format(d->mesh));
	int err = for_each_batch(d->mesh, &d->cache, d->tris, NULL,
				 d->feed_threads, bounds_batch, &d->bd);
	if (err)
		return err;
	return bounds_grid(d);
}

/* The grid of the triangles' bounds d->bd, once a whole pass has seen
 * them (read_bounds, or estimate_cells when the grid was guessed). */
static int bounds_grid(struct driver *d)
{
	struct run *r = &d->r;
	int err;
	/* the whole file has been seen: its colour sources are known, its
	 * textures loaded (and so inside `base` below) */
	r->colours = d->opts->colours && vd_mesh_has_colours(d->mesh);
	r->mesh = d->mesh;
	if (r->colours && !(d->attrs = malloc(TRI_BATCH * sizeof *d->attrs)))
		return vd_fail(VD_ERR_NOMEM, "triangle buffer");
	d->res->mesh = *vd_mesh_stats(d->mesh);
	if (d->bd.n == 0)
		return vd_fail(VD_ERR_EMPTY, "'%s' has no triangles",
			       d->mesh_path);
	err = vd_transform_init(&r->g.tr, d->bd.lo, d->bd.hi, d->opts->levels);
	if (err)
		return err;
	r->g.L = d->opts->levels;
	d->res->seconds_bounds = vd_seconds() - d->t0;
	return VD_OK;
}

static int estimate_bounds_batch(void *ctx, const struct vd_triangle *t,
				 const struct vd_tri_attr *attr, size_t n);

/* Pass 2, estimate: one more pass over the triangles collects the 32^3
 * blocks they may touch (at most share.estimate_keys keys,
 * coarsened past it), sorted into d->bkeys; from them, per candidate
 * chunk level (every level to F, or only --chunk-level), the largest
 * cell's blocks and the pages of per-cell arrays touched. Memory: the
 * keys (their share; estimate_sorted frees all but the sorted keys)
 * beside what pass 1 holds. */
static int estimate_cells(struct driver *d)
{
	const struct vd_voxelize_opts *opts = d->opts;
	struct estimate *est = &d->est;
	int L = opts->levels;
	est->g = d->r.g;
	est->max_keys = d->share.estimate_keys;
	d->F = opts->chunk_level >= 0 ? opts->chunk_level : d->max_level;
	int F = d->F;
	if (d->guessed)
		progress_say(&d->prog, 1, "reading %s (%s); estimating memory "
			     "per cell", d->mesh_path, vd_mesh_format(d->mesh));
	else
		progress_say(&d->prog, 1, "%llu triangles; estimating memory "
			     "per cell", (unsigned long long)d->bd.n);
	int err = for_each_batch(d->mesh, &d->cache, d->tris, NULL,
				 d->feed_threads,
				 d->guessed ? estimate_bounds_batch : estimate_batch,
				 d->guessed ? (void *)d : est);
	if (!err)
		err = estimate_sorted(est, &d->bkeys, &d->nbkeys);
	if (err)
		return err;
	const uint64_t *bkeys = d->bkeys;
	size_t nbkeys = d->nbkeys;
	uint64_t *max_blocks = d->max_blocks, *min_blocks = d->min_blocks;
	uint64_t *cells_hit = d->cells_hit;
	/* per level: the largest cell's bound */
	for (int l = 0; l <= MAX_CHUNK_LEVEL; l++)
		max_blocks[l] = min_blocks[l] = UINT64_MAX;
	for (int l = 0; l <= F; l++) {
		if (opts->chunk_level >= 0 && l != opts->chunk_level)
			continue;
		max_blocks[l] = 0;
		uint64_t lo = 0, last_page = 0;
		int all_pages = L - l <= BLOCK_SHIFT;
		for (size_t i = 0; i < nbkeys;) {
			uint64_t lower;
			uint64_t nb = cell_bound(bkeys, nbkeys, i, L, l,
						 est->coarse, &i, &lower);
			if (nb > max_blocks[l])
				max_blocks[l] = nb;
			/* pages of the totals array: 512 cells a page */
			int sh = L - BLOCK_SHIFT - est->coarse - l;
			if (sh < 0) {
				all_pages = 1;
			} else {
				uint64_t page = bkeys[i - 1] >> 3 * sh >> 9;
				if (!cells_hit[l] || page != last_page)
					cells_hit[l]++;
				last_page = page;
			}
			if (lower > lo)
				lo = lower;
		}
		uint64_t cap = cell_block_cap(L, l);
		if (max_blocks[l] > cap || L - l <= BLOCK_SHIFT)
			max_blocks[l] = cap;
		if (all_pages)
			cells_hit[l] = 0;
		if (l == F)
			min_blocks[l] = lo < max_blocks[l] ? lo : max_blocks[l];
	}
	return VD_OK;
}

/* Passes 1 and 2 in one when the grid can be guessed: a PLY's vertices
 * are in memory before its faces are read, and their bounds are the
 * triangles' unless a vertex no face uses reaches further. The estimate
 * pass then gathers the triangles' bounds too; when they are not the
 * guess's, bit for bit, the estimate is dropped and made again on the
 * grid of the triangles (the cache, when it holds them, replays them), so
 * the grid, and every chunk, is what the two passes give. Geometry only:
 * with colours, pass 1 also decides whether there are any. Returns 0
 * with nothing done when there is no guess. */
static int estimate_bounds_batch(void *ctx, const struct vd_triangle *t,
				 const struct vd_tri_attr *attr, size_t n)
{
	struct driver *d = ctx;
	bounds_batch(&d->bd, t, attr, n);
	return estimate_batch(&d->est, t, attr, n);
}

static int guess_grid(struct driver *d, int *done)
{
	struct run *r = &d->r;
	float lo[3], hi[3];
	*done = 0;
	if (d->opts->colours || !vd_mesh_vertex_bounds(d->mesh, lo, hi) ||
	    vd_transform_init(&r->g.tr, lo, hi, d->opts->levels) != VD_OK)
		return VD_OK; /* two passes: read_bounds says what is wrong */
	r->g.L = d->opts->levels;
	r->mesh = d->mesh;
	d->res->seconds_bounds = vd_seconds() - d->t0;
	d->guessed = 1;
	int err = estimate_cells(d);
	d->guessed = 0;
	if (err)
		return err;
	*done = 1;
	if (!memcmp(lo, d->bd.lo, sizeof lo) && !memcmp(hi, d->bd.hi, sizeof hi)) {
		d->res->mesh = *vd_mesh_stats(d->mesh);
		return d->bd.n ? VD_OK : vd_fail(VD_ERR_EMPTY, "'%s' has no "
						 "triangles", d->mesh_path);
	}
	/* the triangles' grid, and the estimate made on it */
	estimate_free(&d->est);
	memset(&d->est, 0, sizeof d->est);
	free(d->bkeys);
	d->bkeys = NULL;
	d->nbkeys = 0;
	memset(d->cells_hit, 0, sizeof d->cells_hit);
	if ((err = bounds_grid(d)))
		return err;
	d->res->seconds_bounds = vd_seconds() - d->t0;
	return estimate_cells(d);
}

/* Chooses the chunk level L0 and the workers' share (d->plan, d->r.g.L0):
 * the coarsest candidate level whose largest cell fits a worker's share of
 * what the budget leaves beside the process as it is now (`base`: the
 * mesh reader, buffers, the cache, the sorted estimate) and the bin
 * buffer (share.bin_bytes), which pass 3 allocates next. Allocates
 * nothing; the RSS it measures is what the choice depends on. */
static int choose_chunk_level(struct driver *d)
{
	const struct vd_voxelize_opts *opts = d->opts;
	/* what the process holds now: vertices, buffers, the sorted
	 * estimate (the estimate's set is freed: its peak was its share) */
	uint64_t base = vd_current_rss_bytes();
	uint64_t bin_bytes = d->share.bin_bytes;
	d->block_cost = BLOCK_COST + (d->r.colours ? COLOUR_BLOCK_COST : 0);
	int err = plan_budget(opts, base + bin_bytes, d->F, d->max_blocks,
			      d->cells_hit, d->est.coarse, d->block_cost,
			      &d->plan);
	if (err && d->est.coarse) {
		/* The coarse bound is loose: if the cells of level F may fit
		 * (the lower bound does), take F and let each cell's block
		 * limit decide while rasterizing, largest cell first. */
		err = plan_budget(opts, base + bin_bytes, d->F, d->min_blocks,
				  d->cells_hit, 0, d->block_cost, &d->plan);
		if (err)
			return err;
		progress_say(&d->prog, 1, "memory estimate coarsened %d times; "
			     "cells of level %d checked while rasterizing",
			     d->est.coarse, d->F);
	}
	if (err)
		return err;
	d->r.g.L0 = d->plan.L0;
	return VD_OK;
}

/* With `ncells` cells to voxelize, whether each goes on all the threads
 * (split_cell): the threads asked for are more than one and have too few
 * cells, octants are whole blocks, and what the budget leaves the workers
 * holds the largest cell's blocks plus every worker's overhead. Returns
 * the block limit they then share, else 0. */
static size_t split_limit(const struct driver *d, size_t ncells)
{
	const struct plan *plan = &d->plan;
	if (plan->want <= 1 || ncells >= 4 * (size_t)plan->want ||
	    d->opts->levels - d->r.g.L0 <= BLOCK_SHIFT)
		return 0;
	uint64_t over = (uint64_t)plan->want * WORKER_OVERHEAD;
	size_t limit = plan->avail > over ?
		(size_t)((plan->avail - over) / d->block_cost) : 0;
	return limit >= plan->cell_blocks ? limit : 0;
}

/* The non-empty cells of L0 by the estimate (its keys reach them; when
 * coarsened past L0, every cell). */
static size_t estimated_cells(const struct driver *d)
{
	int L = d->opts->levels, L0 = d->r.g.L0;
	int sh = L - BLOCK_SHIFT - d->est.coarse - L0;
	if (sh < 0)
		return (size_t)1 << 3 * L0;
	size_t n = 0;
	for (size_t i = 0; i < d->nbkeys; i++)
		n += i == 0 || d->bkeys[i] >> 3 * sh != d->bkeys[i - 1] >> 3 * sh;
	return n;
}

/* Pass 3, binning: empties the output directory (a failure from here on
 * removes what this run wrote) and appends every triangle to the bin file
 * of each cell of level L0 it overlaps, counting them per cell
 * (d->b.totals). One cell without colours, the mesh in the cache: the
 * cache is the cell's bin, and no file is written. Memory: the record
 * buffer (share.bin_bytes) and 8 bytes per cell of L0, beside pass 1's;
 * the cache is dropped at the end (the bins hold the triangles now). */
static int bin_triangles(struct driver *d)
{
	struct run *r = &d->r;
	struct binner *b = &d->b;
	double t1 = vd_seconds();
	int err = clean_outdir(d->outdir);
	if (err)
		return err;
	d->cleaned = 1;
	b->g = r->g;
	b->dir = d->outdir;
	b->totals = calloc((size_t)1 << 3 * r->g.L0, sizeof *b->totals);
	if (!b->totals)
		return vd_fail(VD_ERR_NOMEM, "bins");
	if (!r->colours && r->g.L0 == 0 && d->cache.state == 1) {
		/* One cell, the mesh in memory: it is the bin. (Every
		 * triangle is inside the bounds' cube, as a bin would hold.) */
		r->mem_tris = d->cache.t;
		r->mem_n = d->cache.n;
		r->mem_cache = &d->cache;
		b->totals[0] = b->pairs = d->cache.n;
	} else {
		uint64_t bin_bytes = d->share.bin_bytes;
		/* cells that will be split get octant bins: each octant's
		 * worker then reads its triangles, not the whole cell's */
		if (!r->colours && r->g.L0 + 1 <= MAX_CHUNK_LEVEL &&
		    split_limit(d, estimated_cells(d)))
			b->sub = r->sub_bins = 1;
		if (r->colours) {
			/* the order of the writes out of the same share */
			b->cap = bin_bytes / (sizeof *b->crecs + sizeof *b->perm);
			if (b->cap > UINT32_MAX)
				b->cap = UINT32_MAX;
			b->crecs = malloc(b->cap * sizeof *b->crecs);
			b->perm = malloc(b->cap * sizeof *b->perm);
		} else {
			b->cap = bin_bytes / sizeof *b->recs;
			b->recs = malloc(b->cap * sizeof *b->recs);
		}
		if (!(b->recs || (b->crecs && b->perm)))
			return vd_fail(VD_ERR_NOMEM, "bins");
		progress_say(&d->prog, 1, "binning triangles into cells of "
			     "level %d%s (%d threads, budget %llu MiB)", r->g.L0,
			     b->sub ? ", by octant" : "", d->plan.threads,
			     (unsigned long long)(d->opts->mem_budget_bytes >> 20));
		err = for_each_batch(d->mesh, &d->cache, d->tris, d->attrs,
				     d->feed_threads, bin_batch, b);
		if (!err)
			err = r->colours ? flush_bins_col(b) : flush_bins(b);
		tri_cache_drop(&d->cache); /* the bins have them now */
		if (err)
			return err;
	}
	d->res->triangles_binned = b->pairs;
	d->res->seconds_bin += vd_seconds() - t1;
	return VD_OK;
}

/* The cells to voxelize (d->r.jobs): every non-empty cell of L0 with its
 * planned blocks from the estimate, largest first, so the cells that may
 * fail the budget fail early and the long ones start first. Frees the
 * estimate's keys and the binning's arrays: the job list (16 bytes per
 * cell of L0, resident for the non-empty ones) takes their place. */
static int list_cells(struct driver *d)
{
	struct run *r = &d->r;
	struct binner *b = &d->b;
	int L = d->opts->levels;
	size_t ncell = (size_t)1 << 3 * r->g.L0;
	r->jobs = malloc(ncell * sizeof *r->jobs);
	if (!r->jobs)
		return vd_fail(VD_ERR_NOMEM, "jobs");
	const uint64_t *bkeys = d->bkeys;
	size_t nbkeys = d->nbkeys;
	for (size_t c = 0, i = 0; c < ncell; c++) {
		/* bkeys are sorted, cells visited in order: one merge walk */
		uint64_t nb = 1;
		if (L - r->g.L0 > BLOCK_SHIFT) {
			int sh = L - BLOCK_SHIFT - d->est.coarse - r->g.L0;
			if (sh >= 0) {
				while (i < nbkeys && bkeys[i] >> 3 * sh < c)
					i++;
				size_t j = i;
				nb = 0;
				uint64_t lower;
				if (i < nbkeys && bkeys[i] >> 3 * sh == c)
					nb = cell_bound(bkeys, nbkeys, i, L,
							r->g.L0, d->est.coarse,
							&j, &lower);
				i = j;
			} else {
				nb = cell_block_cap(L, r->g.L0);
			}
		}
		if (b->totals[c])
			r->jobs[r->njobs++] = (struct cell_job){c, nb};
	}
	free(d->bkeys);
	d->bkeys = NULL;
	free(b->totals);
	free(b->recs);
	free(b->crecs);
	free(b->perm);
	b->totals = NULL;
	b->recs = NULL;
	b->crecs = NULL;
	b->perm = NULL;
	qsort(r->jobs, r->njobs, sizeof *r->jobs, cmp_jobs);
	return VD_OK;
}

/* The workers of pass 4, from the plan: a cell per worker, or, with few
 * cells for the threads, each cell on all of them (split_cell) when what
 * the budget leaves the workers holds the largest cell's blocks plus every
 * worker's overhead; then the threads asked for all work and share one
 * block limit. Memory: per worker its read buffer and sort keys, inside
 * its WORKER_OVERHEAD. */
static int start_workers(struct driver *d)
{
	struct run *r = &d->r;
	const struct plan *plan = &d->plan;
	r->level_nodes = d->nodes;
	r->outdir = d->outdir;
	r->opts = d->opts;
	r->prog = &d->prog;
	r->block_limit = plan->block_limit;
	r->worker_bytes = plan->worker_bytes;
	/* progress counts records: with octant bins, those of the octants */
	r->pairs_total = r->sub_bins ? d->b.records : d->b.pairs;
	int nw = plan->threads;
	size_t limit = split_limit(d, r->njobs);
	if (limit) {
		d->split = 1;
		nw = plan->want;
		r->block_limit = limit;
		r->worker_bytes = (uint64_t)limit * d->block_cost;
	}
	r->mem_once = !d->split;
	r->workers = calloc((size_t)nw, sizeof *r->workers);
	if (!r->workers)
		return vd_fail(VD_ERR_NOMEM, "workers");
	r->nworkers = nw;
	size_t rec_bytes = r->colours ? BIN_BYTES_COL : sizeof(struct vd_triangle);
	rec_bytes *= raster_batch(r); /* colour_pass reads TRI_BATCH */
	for (int i = 0; i < nw; i++)
		if (!(r->workers[i].tris = malloc(rec_bytes)) ||
		    !(r->workers[i].order_tri = malloc(2 * RASTER_BATCH *
					sizeof *r->workers[i].order_tri)))
			return vd_fail(VD_ERR_NOMEM, "workers");
	return VD_OK;
}

/* Pass 4, voxelize the cells: each cell's bin rasterized in core and
 * written as its SVO chunk (and colour chunk), by the workers of
 * start_workers, largest cell first. Memory: each worker its share
 * (r->worker_bytes), checked block by block against r->block_limit. */
static int voxelize_cells(struct driver *d)
{
	struct run *r = &d->r;
	int err = VD_OK;
	if (d->split) {
		progress_say(&d->prog, 1, "%zu cells for %d threads: each cell "
			     "rasterized by all of them", r->njobs, r->nworkers);
		for (size_t i = 0; i < r->njobs && !err && !r->err; i++) {
			err = split_cell(r, r->jobs[i].cell);
			cell_done(r);
		}
	} else {
		err = vd_parallel_for(r->njobs, d->plan.threads, cell_task, r);
	}
	if (!err && r->err)
		err = vd_fail(r->err, "%s", r->detail);
	return err;
}

/* The result's counts: the nodes of the levels above L0 (distinct
 * prefixes of the cells that got a chunk) and, from L0 down, the workers'
 * sums. Memory: 8 bytes per non-empty cell. */
static int count_levels(struct driver *d)
{
	struct run *r = &d->r;
	struct vd_voxelize_result *res = d->res;
	uint64_t *cells = malloc((r->njobs ? r->njobs : 1) * sizeof *cells);
	size_t nonempty = 0;
	if (!cells)
		return vd_fail(VD_ERR_NOMEM, "cells");
	char name[64], path[4096];
	for (size_t i = 0; i < r->njobs; i++) {
		vd_chunk_file_name(name, sizeof name, r->g.L0, r->jobs[i].cell,
				   "svo");
		snprintf(path, sizeof path, "%s/%s", d->outdir, name);
		if (access(path, F_OK) == 0)
			cells[nonempty++] = r->jobs[i].cell;
	}
	qsort(cells, nonempty, sizeof *cells, cmp_u64);
	for (int l = 0; l < r->g.L0; l++) {
		uint64_t n = 0;
		int sh = 3 * (r->g.L0 - l);
		for (size_t i = 0; i < nonempty; i++)
			n += i == 0 || cells[i] >> sh != cells[i - 1] >> sh;
		res->level_nodes[l] = n;
	}
	free(cells);
	for (int l = r->g.L0; l <= d->opts->levels; l++)
		res->level_nodes[l] = d->nodes[l - r->g.L0];
	res->chunks = nonempty;
	return VD_OK;
}

/* The statistics of the run into d->res (the caller writes them with
 * vd_voxelize_write_stats), the budget checked against the peak RSS, and
 * the list of files the mesh pulled in written beside the chunks.
 * Allocates nothing that outlives it. */
static int finish_result(struct driver *d)
{
	const struct vd_voxelize_opts *opts = d->opts;
	struct run *r = &d->r;
	struct vd_voxelize_result *res = d->res;
	int err = count_levels(d);
	if (err)
		return err;
	res->levels = opts->levels;
	res->chunk_level = r->g.L0;
	res->threads = r->nworkers;
	res->mem_budget_bytes = opts->mem_budget_bytes;
	snprintf(res->format, sizeof res->format, "%s", vd_mesh_format(d->mesh));
	res->transform = r->g.tr;
	res->voxels = atomic_load(&r->voxels);
	res->bricks = atomic_load(&r->bricks);
	res->colours = r->colours;
	res->textures_loaded = vd_mesh_textures_loaded(d->mesh);
	res->textures_missing = vd_mesh_textures_missing(d->mesh);
	for (int i = 0; i < r->nworkers; i++)
		res->seconds_colour += r->workers[i].seconds_colour;
	res->seconds_total = vd_seconds() - d->t0;
	res->peak_rss_bytes = vd_peak_rss_bytes();
	progress_say(&d->prog, 1, "%llu voxels in %llu chunks, %.2fs",
		     (unsigned long long)res->voxels,
		     (unsigned long long)res->chunks, res->seconds_total);
	if (res->peak_rss_bytes > opts->mem_budget_bytes)
		return vd_fail(VD_ERR_BUDGET, "peak memory %llu MiB exceeded "
			       "--mem-budget %llu MiB",
			       (unsigned long long)(res->peak_rss_bytes >> 20),
			       (unsigned long long)(opts->mem_budget_bytes >> 20));
	/* the files the mesh pulled in (MTL, textures, buffers): the runner
	 * reruns this job when one of them changes */
	size_t ns;
	const struct vd_mesh_source *src = vd_mesh_sources(d->mesh, &ns);
	char sp[4200];
	snprintf(sp, sizeof sp, "%s/" VD_SOURCES_NAME, d->outdir);
	return vd_sources_write(sp, src, ns);
}

/* Frees whatever the passes left, closes the mesh, removes the bins and,
 * after a failure once the output directory was cleaned, the chunks
 * written (no partial set of chunks survives). Returns `err`. */
static int driver_release(struct driver *d, int err)
{
	struct run *r = &d->r;
	free(d->b.totals);
	free(d->b.recs);
	free(d->b.crecs);
	free(d->b.perm);
	free(d->attrs);
	if (r->workers) {
		for (int i = 0; i < r->nworkers; i++) {
			struct worker *w = &r->workers[i];
			map_free(&w->map);
			free(w->tris);
			free(w->order_tri);
			free(w->order);
			free(w->bptr);
			free(w->nz);
			free(w->nz_start);
			free(w->blk);
			free(w->base);
			free(w->prefix);
			free(w->vox);
		}
		free(r->workers);
	}
	free(r->jobs);
	estimate_free(&d->est);
	free(d->bkeys);
	free(d->tris);
	tri_cache_drop(&d->cache);
	vd_mesh_close(d->mesh);
	remove_bins(d->outdir);
	if (err && d->cleaned)
		vd_remove_chunks(d->outdir);
	return err;
}

int vd_voxelize_mesh(const char *mesh_path, const char *outdir,
		     const struct vd_voxelize_opts *opts,
		     struct vd_voxelize_result *res)
{
	memset(res, 0, sizeof *res);
	double t0 = vd_seconds();
	int L = opts->levels;
	if (L < 1 || L > VD_MAX_LEVELS)
		return vd_fail(VD_ERR_RANGE, "--levels %d is outside 1..%d", L,
			       VD_MAX_LEVELS);
	int max_level = L - 2 > 0 ? L - 2 : 0;
	if (max_level > MAX_CHUNK_LEVEL)
		max_level = MAX_CHUNK_LEVEL;
	if (opts->chunk_level > max_level)
		return vd_fail(VD_ERR_RANGE, "--chunk-level %d is outside 0..%d "
			       "for --levels %d", opts->chunk_level, max_level, L);
	struct driver d = {
		.mesh_path = mesh_path, .outdir = outdir, .opts = opts,
		.res = res, .t0 = t0, .max_level = max_level,
		/* the fixed shares of the budget: budget.h says what each
		 * pays for */
		.share = vd_voxelize_budget(opts->mem_budget_bytes),
		.prog = {.quiet = opts->quiet,
			 .tool = opts->tool ? opts->tool : "voxelize",
			 .start = t0, .lock = PTHREAD_MUTEX_INITIALIZER},
		.r = {.lock = PTHREAD_MUTEX_INITIALIZER}};
	/* spilled vertices go to unlinked files of the output (staging)
	 * directory */
	struct vd_mesh_open_opts mo = {
		.max_vertex_bytes = d.share.vertex_bytes,
		.colours = opts->colours, .strict = opts->strict,
		.warn = warn_line, .warn_ctx = &d.prog,
		.spill_dir = outdir};
	int err = vd_mesh_open_opts(&d.mesh, mesh_path, &mo);
	if (err)
		return err;
	d.feed_threads = opts->threads > 0 ? opts->threads
					   : vd_hardware_threads();
	if (opts->mem_budget_bytes < FEED_MIN_BUDGET)
		d.feed_threads = 1;
	d.tris = malloc((d.feed_threads > 1 ? FEED_SLOTS : 1) * TRI_BATCH *
			sizeof *d.tris);
	/* the plan counts it in `base` */
	d.cache.limit = d.share.tri_cache_bytes;
	if (d.cache.limit > vd_tri_cache_max)
		d.cache.limit = vd_tri_cache_max;
	if (!d.tris)
		return driver_release(&d, vd_fail(VD_ERR_NOMEM,
						  "triangle buffer"));
	/* planning is timed with binning (with a guessed grid, from open) */
	double t1 = vd_seconds();
	int guessed;
	if ((err = guess_grid(&d, &guessed)))
		return driver_release(&d, err);
	if (!guessed && (err = read_bounds(&d)))
		return driver_release(&d, err);
	if (!guessed)
		t1 = vd_seconds();
	if ((!guessed && (err = estimate_cells(&d))) ||
	    (err = choose_chunk_level(&d)))
		return driver_release(&d, err);
	res->seconds_bin = vd_seconds() - t1;
	if ((err = bin_triangles(&d)))
		return driver_release(&d, err);
	t1 = vd_seconds();
	if ((err = list_cells(&d)) || (err = start_workers(&d)) ||
	    (err = voxelize_cells(&d)))
		return driver_release(&d, err);
	res->seconds_voxelize = vd_seconds() - t1;
	return driver_release(&d, finish_result(&d));
}

int vd_voxelize_stats_open(struct vd_json **j, const char *path,
			   const char *format)
{
	int err = vd_json_open(j, path);
	if (err)
		return err;
	vd_json_str(*j, "stage", "voxelize");
	vd_json_str(*j, "version", VD_VERSION_STRING);
	vd_json_str(*j, "input_format", format);
	return VD_OK;
}

void vd_voxelize_stats_totals(struct vd_json *j,
			      const struct vd_voxelize_totals *t)
{
	vd_json_u64(j, "voxels", t->voxels);
	vd_json_u64(j, "bricks", t->bricks);
	vd_json_u64(j, "chunks", t->chunks);
	vd_json_u64_array(j, "level_nodes", t->level_nodes,
			  (size_t)t->levels + 1);
	double secs = t->seconds_total > 0 ? t->seconds_total : 1e-9;
	vd_json_f64(j, "voxels_per_second", (double)t->voxels / secs);
	vd_json_u64(j, "threads", (uint64_t)t->threads);
	vd_json_u64(j, "peak_rss_bytes", t->peak_rss_bytes);
	vd_json_f64(j, "process_cpu_seconds", vd_cpu_seconds());
	vd_json_u64(j, "mem_budget_bytes", t->mem_budget_bytes);
	vd_json_object(j, "transform");
	vd_json_f64(j, "origin_x", t->transform->origin[0]);
	vd_json_f64(j, "origin_y", t->transform->origin[1]);
	vd_json_f64(j, "origin_z", t->transform->origin[2]);
	vd_json_f64(j, "voxel_size", t->transform->voxel_size);
	vd_json_f64(j, "root_side", t->transform->root_side);
	vd_json_end_object(j);
}

int vd_voxelize_write_stats(const struct vd_voxelize_result *res,
			    const char *path)
{
	struct vd_json *j;
	int err = vd_voxelize_stats_open(&j, path, res->format);
	if (err)
		return err;
	vd_json_u64(j, "levels", (uint64_t)res->levels);
	vd_json_u64(j, "chunk_level", (uint64_t)res->chunk_level);
	vd_json_u64(j, "triangles_read", res->mesh.triangles_read);
	vd_json_object(j, "triangles_dropped");
	vd_json_u64(j, "short_face", res->mesh.faces_dropped_short);
	vd_json_end_object(j);
	vd_json_u64(j, "polygons_split", res->mesh.polygons_split);
	vd_json_u64(j, "triangle_cell_pairs", res->triangles_binned);
	vd_json_object(j, "seconds");
	vd_json_f64(j, "bounds", res->seconds_bounds);
	vd_json_f64(j, "plan_and_bin", res->seconds_bin);
	vd_json_f64(j, "voxelize", res->seconds_voxelize);
	vd_json_f64(j, "total", res->seconds_total);
	vd_json_end_object(j);
	double t = res->seconds_total > 0 ? res->seconds_total : 1e-9;
	vd_json_f64(j, "triangles_per_second", (double)res->mesh.triangles_read / t);
	vd_json_u64(j, "colours", (uint64_t)res->colours);
	vd_json_u64(j, "textures_loaded", res->textures_loaded);
	vd_json_u64(j, "textures_missing", res->textures_missing);
	vd_json_f64(j, "seconds_colour_workers", res->seconds_colour);
	struct vd_voxelize_totals tot = {
		res->levels, res->voxels, res->bricks, res->chunks,
		res->level_nodes, res->seconds_total, res->threads,
		res->peak_rss_bytes, res->mem_budget_bytes, &res->transform};
	vd_voxelize_stats_totals(j, &tot);
	return vd_json_close(j);
}
