/* vdb_import.c - OpenVDB grid to SVO chunks, one per non-empty L0 cell,
 * laid out and named as the mesh voxelizer's.
 *
 *   1. scan: one pass over the tree's leaves and tiles (vd_vdb_scan) keeps
 *      each node that holds selected voxels as an entry (origin, size) and
 *      the tight bounding box of the selected voxels; no voxel is copied;
 *   2. place: the bounding box fixes the grid depth, the resampling shift
 *      and the offset (see vd_vdb_import in vd_vdb.h); entries are split at
 *      the cells of the finest candidate chunk level F and sorted by cell,
 *      which also gives every cell's exact brick count at every level, so
 *      L0 is the coarsest level whose largest cell fits the budget;
 *   3. cells, in parallel: each cell's entries become (brick key, mask)
 *      pairs - a leaf's mask asked again from OpenVDB, a tile filled brick
 *      by brick without visiting its voxels - sorted, merged and written;
 *      with a colour grid, the cell's colours are then looked up brick by
 *      brick and streamed into its colour chunk.
 * Memory: the grids OpenVDB holds, 32 bytes per entry (about one per leaf),
 * and per worker 16 bytes per brick of its cell plus a fixed colour buffer.
 */
#include "voxdag.h"
#include "util_internal.h"
#include "voxel/voxel_internal.h"

#include <dirent.h>
#include <errno.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

enum {
	MAX_CHUNK_LEVEL = 7,          /* as the mesh voxelizer */
	WORKER_OVERHEAD = 8 << 20,    /* zstd, write buffer, colours, stack */
	COLOUR_BRICKS = 1024,         /* bricks coloured per batch: 192 KiB */
	LEAF_FLAG = 1u << 31,         /* entry.dim: a leaf (mask from OpenVDB) */
};

/* One node's share of one cell of level F. */
struct entry {
	uint64_t cell;       /* Morton code at level F */
	int32_t o[3];        /* OpenVDB index of the node's origin */
	uint32_t dim;        /* side in OpenVDB voxels, | LEAF_FLAG */
	uint64_t bricks;     /* bricks its box has inside the cell */
};

struct pair {
	uint64_t key, mask;
};

struct scan {
	struct entry *e;
	size_t n, cap;
	int64_t lo[3], hi[3];  /* inclusive bbox of selected voxels */
	uint64_t leaves, tiles;
};

static int grow_entries(struct scan *s, size_t need)
{
	if (need <= s->cap)
		return VD_OK;
	size_t cap = s->cap ? s->cap : 4096;
	while (cap < need)
		cap *= 2;
	struct entry *e = realloc(s->e, cap * sizeof *e);
	if (!e)
		return vd_fail(VD_ERR_NOMEM, "%zu node entries", cap);
	s->e = e;
	s->cap = cap;
	return VD_OK;
}

static void widen(struct scan *s, int a, int64_t lo, int64_t hi)
{
	if (lo < s->lo[a])
		s->lo[a] = lo;
	if (hi > s->hi[a])
		s->hi[a] = hi;
}

static int scan_node(void *ctx, const struct vd_vdb_node *n)
{
	struct scan *s = ctx;
	int err = grow_entries(s, s->n + 1);
	if (err)
		return err;
	struct entry *e = &s->e[s->n++];
	memcpy(e->o, n->origin, sizeof e->o);
	e->dim = n->dim | (n->is_leaf ? LEAF_FLAG : 0);
	e->cell = 0;
	e->bricks = 0;
	if (!n->is_leaf) {
		s->tiles++;
		for (int a = 0; a < 3; a++)
			widen(s, a, n->origin[a], (int64_t)n->origin[a] + n->dim - 1);
		return VD_OK;
	}
	s->leaves++;
	/* word x, byte y, bit z */
	uint64_t yz = 0;
	int x0 = 8, x1 = -1;
	for (int x = 0; x < 8; x++)
		if (n->mask[x]) {
			x0 = x0 < x ? x0 : x;
			x1 = x;
			yz |= n->mask[x];
		}
	unsigned z = 0;
	int y0 = 8, y1 = -1;
	for (int y = 0; y < 8; y++) {
		unsigned row = (unsigned)(yz >> 8 * y) & 0xff;
		if (row) {
			y0 = y0 < y ? y0 : y;
			y1 = y;
			z |= row;
		}
	}
	widen(s, 0, n->origin[0] + x0, n->origin[0] + x1);
	widen(s, 1, n->origin[1] + y0, n->origin[1] + y1);
	widen(s, 2, n->origin[2] + __builtin_ctz(z),
	      n->origin[2] + 31 - __builtin_clz(z));
	return VD_OK;
}

/* ----------------------------------------------------------- placement */

struct place {
	int L, F, k;          /* depth, finest cell level, resampling shift */
	int64_t off[3];       /* OpenVDB index of our voxel 0, times 1 */
};

static int64_t floor_div(int64_t a, int64_t b)
{
	return a >= 0 ? a / b : -((-a + b - 1) / b);
}

/* Extent in our voxels with shift k, and the offsets that go with it. */
static int64_t extent_at(const struct scan *s, int k, int64_t off[3])
{
	int64_t align = (int64_t)8 << k, e = 0;
	for (int a = 0; a < 3; a++) {
		off[a] = floor_div(s->lo[a], align) * align;
		int64_t ext = ((s->hi[a] + 1 - off[a]) + ((int64_t)1 << k) - 1) >> k;
		e = ext > e ? ext : e;
	}
	return e;
}

static int depth_for(int64_t extent)
{
	int L = 1;
	while (((int64_t)1 << L) < extent)
		L++;
	return L;
}

/* Our voxel box [lo, hi) of an entry, clipped to the grid. */
static void entry_box(const struct place *p, const struct entry *e,
		      int64_t lo[3], int64_t hi[3])
{
	int64_t dim = e->dim & ~LEAF_FLAG, n = (int64_t)1 << p->L;
	for (int a = 0; a < 3; a++) {
		lo[a] = ((int64_t)e->o[a] - p->off[a]) >> p->k;
		hi[a] = ((int64_t)e->o[a] + dim - p->off[a] + ((int64_t)1 << p->k) - 1) >> p->k;
		lo[a] = lo[a] < 0 ? 0 : lo[a];
		hi[a] = hi[a] > n ? n : hi[a];
	}
}

static void cell_box(const struct place *p, uint64_t cell, int64_t lo[3],
		     int64_t hi[3])
{
	uint32_t c[3];
	vd_morton3_decode(cell, &c[0], &c[1], &c[2]);
	int sh = p->L - p->F;
	for (int a = 0; a < 3; a++) {
		lo[a] = (int64_t)c[a] << sh;
		hi[a] = lo[a] + ((int64_t)1 << sh);
	}
}

static uint64_t box_bricks(const int64_t lo[3], const int64_t hi[3])
{
	uint64_t n = 1;
	for (int a = 0; a < 3; a++) {
		if (hi[a] <= lo[a])
			return 0;
		n *= (uint64_t)(((hi[a] - 1) >> 2) - (lo[a] >> 2) + 1);
	}
	return n;
}

/* Gives every entry its level-F cell; a node over several cells gets one
 * entry per cell. */
static int split_entries(struct scan *s, const struct place *p)
{
	size_t n0 = s->n;
	int sh = p->L - p->F;
	for (size_t i = 0; i < n0; i++) {
		int64_t lo[3], hi[3], c0[3], c1[3];
		entry_box(p, &s->e[i], lo, hi);
		for (int a = 0; a < 3; a++)
			c0[a] = lo[a] >> sh, c1[a] = (hi[a] - 1) >> sh;
		int first = 1;
		for (int64_t x = c0[0]; x <= c1[0]; x++)
			for (int64_t y = c0[1]; y <= c1[1]; y++)
				for (int64_t z = c0[2]; z <= c1[2]; z++) {
					struct entry e = s->e[i];
					e.cell = vd_morton3((uint32_t)x, (uint32_t)y, (uint32_t)z);
					int64_t cl[3], ch[3];
					cell_box(p, e.cell, cl, ch);
					for (int a = 0; a < 3; a++) {
						cl[a] = cl[a] > lo[a] ? cl[a] : lo[a];
						ch[a] = ch[a] < hi[a] ? ch[a] : hi[a];
					}
					e.bricks = box_bricks(cl, ch);
					if (first) {
						s->e[i] = e;
						first = 0;
						continue;
					}
					int err = grow_entries(s, s->n + 1);
					if (err)
						return err;
					s->e[s->n++] = e;
				}
	}
	return VD_OK;
}

static int cmp_entry(const void *a, const void *b)
{
	const struct entry *x = a, *y = b;
	return (x->cell > y->cell) - (x->cell < y->cell);
}

static int cmp_pair(const void *a, const void *b)
{
	const struct pair *x = a, *y = b;
	return (x->key > y->key) - (x->key < y->key);
}

/* ------------------------------------------------------------- cells */

struct job {
	size_t begin, end;   /* entries */
	uint64_t cell;       /* at L0 */
	uint64_t bricks;     /* upper bound of its pairs */
};

struct worker {
	struct pair *p;
	size_t cap;
	uint8_t *rgb;        /* COLOUR_BRICKS * 64 colours, with colours */
};

struct run {
	struct vd_vdb *vdb;
	struct vd_vdb_colour *col;    /* NULL: no colours */
	struct place pl;
	int L0;
	struct vd_transform tr;
	const char *outdir;
	const struct vd_voxelize_opts *opts;
	struct entry *e;
	struct job *jobs;
	size_t njobs;
	struct worker *workers;
	uint64_t *level_nodes;        /* levels L0..L */
	uint8_t *written;             /* per job: a chunk was written */
	atomic_ullong voxels, bricks;
	atomic_size_t done;
	atomic_int failed;
	pthread_mutex_t lock;
	int err;
	char detail[512];
	double start, last_say;
};

static void say(const struct vd_voxelize_opts *o, double start, const char *fmt,
		...) __attribute__((format(printf, 3, 4)));

static void say(const struct vd_voxelize_opts *o, double start, const char *fmt,
		...)
{
	if (o->quiet)
		return;
	va_list ap;
	va_start(ap, fmt);
	fprintf(stderr, "%s: [%6.1fs] ", o->tool ? o->tool : "voxelize",
		vd_seconds() - start);
	vfprintf(stderr, fmt, ap);
	fputc('\n', stderr);
	va_end(ap);
}

/* Morton spreading of 2-bit values: a voxel's bit inside its brick. */
static unsigned brick_bit(int64_t x, int64_t y, int64_t z)
{
	static const uint8_t s2[4] = {0, 1, 8, 9};
	return (unsigned)s2[x & 3] << 2 | (unsigned)s2[y & 3] << 1 | s2[z & 3];
}

/* The bits of a brick whose local coordinates lie in the per-axis sets
 * (4 bits each). */
static uint64_t brick_part(unsigned ax, unsigned ay, unsigned az)
{
	uint64_t m = 0;
	for (int x = 0; x < 4; x++)
		for (int y = 0; y < 4; y++)
			for (int z = 0; z < 4; z++)
				if ((ax >> x & 1) && (ay >> y & 1) && (az >> z & 1))
					m |= 1ULL << brick_bit(x, y, z);
	return m;
}

/* Local coordinates of brick b (origin 4b) inside [lo, hi). */
static unsigned axis_set(int64_t b, int64_t lo, int64_t hi)
{
	unsigned s = 0;
	for (int i = 0; i < 4; i++)
		if (4 * b + i >= lo && 4 * b + i < hi)
			s |= 1u << i;
	return s;
}

/* Appends the pairs of one entry, clipped to its level-F cell. */
static int entry_pairs(struct run *r, const struct entry *e, struct pair *out,
		       size_t *n)
{
	const struct place *p = &r->pl;
	int64_t lo[3], hi[3], cl[3], ch[3];
	entry_box(p, e, lo, hi);
	cell_box(p, e->cell, cl, ch);
	for (int a = 0; a < 3; a++) {
		lo[a] = lo[a] > cl[a] ? lo[a] : cl[a];
		hi[a] = hi[a] < ch[a] ? hi[a] : ch[a];
		if (hi[a] <= lo[a])
			return VD_OK;
	}
	int64_t b0[3], b1[3];
	for (int a = 0; a < 3; a++)
		b0[a] = lo[a] >> 2, b1[a] = (hi[a] - 1) >> 2;
	if (!(e->dim & LEAF_FLAG)) {
		/* a tile: whole bricks inside, partial ones on its faces */
		for (int64_t x = b0[0]; x <= b1[0]; x++) {
			unsigned ax = axis_set(x, lo[0], hi[0]);
			for (int64_t y = b0[1]; y <= b1[1]; y++) {
				unsigned ay = axis_set(y, lo[1], hi[1]);
				for (int64_t z = b0[2]; z <= b1[2]; z++) {
					unsigned az = axis_set(z, lo[2], hi[2]);
					uint64_t m = (ax & ay & az) == 15 ? ~0ULL
									  : brick_part(ax, ay, az);
					out[(*n)++] = (struct pair){
						vd_morton3((uint32_t)x, (uint32_t)y, (uint32_t)z), m};
				}
			}
		}
		return VD_OK;
	}
	/* a leaf: its box spans at most 3 bricks per axis */
	uint64_t mask[8], slot[27] = {0};
	int err = vd_vdb_leaf_mask(r->vdb, e->o, mask);
	if (err)
		return err;
	for (int x = 0; x < 8; x++) {
		uint64_t w = mask[x];
		while (w) {
			int b = __builtin_ctzll(w);
			w &= w - 1;
			int64_t v[3] = {(int64_t)e->o[0] + x, (int64_t)e->o[1] + (b >> 3),
					(int64_t)e->o[2] + (b & 7)};
			int in = 1;
			for (int a = 0; a < 3; a++) {
				v[a] = (v[a] - p->off[a]) >> p->k;
				in &= v[a] >= lo[a] && v[a] < hi[a];
			}
			if (!in)
				continue;
			int s = (int)((v[0] >> 2) - b0[0]) * 9 +
				(int)((v[1] >> 2) - b0[1]) * 3 + (int)((v[2] >> 2) - b0[2]);
			slot[s] |= 1ULL << brick_bit(v[0], v[1], v[2]);
		}
	}
	for (int s = 0; s < 27; s++)
		if (slot[s])
			out[(*n)++] = (struct pair){
				vd_morton3((uint32_t)(b0[0] + s / 9), (uint32_t)(b0[1] + s / 3 % 3),
					   (uint32_t)(b0[2] + s % 3)),
				slot[s]};
	return VD_OK;
}

/* Colours of a cell's bricks, batch by batch (vd_colours_write). */
struct colour_feed {
	struct run *r;
	struct worker *w;
	const struct pair *pr;
	size_t n, next;
};

static int next_colours(void *ctx, const uint8_t **rgb, size_t *n)
{
	struct colour_feed *f = ctx;
	size_t b = f->n - f->next < COLOUR_BRICKS ? f->n - f->next : COLOUR_BRICKS;
	*rgb = f->w->rgb;
	*n = 0;
	if (b == 0)
		return VD_OK;
	const struct pair *p = f->pr + f->next;
	int32_t off[3];
	for (int a = 0; a < 3; a++)
		off[a] = (int32_t)f->r->pl.off[a];
	int err = vd_vdb_colour_bricks(f->r->col, off, f->r->pl.k, &p[0].key,
				       &p[0].mask, 2, b, f->w->rgb);
	if (err)
		return err;
	for (size_t i = 0; i < b; i++)
		*n += (size_t)__builtin_popcountll(p[i].mask);
	f->next += b;
	return VD_OK;
}

/* Writes the colour chunk of a cell whose SVO chunk holds the n pairs pr
 * with per-level counts `counts`. */
static int write_colours(struct run *r, struct worker *w, uint64_t cell,
			 const struct pair *pr, size_t n, const uint64_t *counts)
{
	if (!w->rgb && !(w->rgb = malloc(COLOUR_BRICKS * 64 * 3)))
		return vd_fail(VD_ERR_NOMEM, "colour buffer");
	/* the SVO chunk's header, as vd_svo_write() made it */
	struct vd_chunk_header h = {0};
	h.kind = VD_KIND_SVO;
	h.levels = (uint32_t)r->pl.L;
	h.chunk_level = (uint32_t)r->L0;
	h.cell_morton = cell;
	h.transform = r->tr;
	h.level_count = (uint32_t)(r->pl.L - r->L0 + 1);
	memcpy(h.level_nodes, counts, h.level_count * sizeof *counts);
	char path[4096], name[64];
	vd_chunk_file_name(name, sizeof name, r->L0, cell, "col");
	snprintf(path, sizeof path, "%s/%s", r->outdir, name);
	struct colour_feed f = {r, w, pr, n, 0};
	return vd_colours_write(path, &h,
				vd_svo_digest_stride(&pr[0].key, &pr[0].mask, 2, n),
				counts[h.level_count - 1], next_colours, &f,
				r->opts->provenance);
}

/* Writes sorted, merged pairs as the cell's SVO chunk. */
static int write_chunk(struct run *r, uint64_t cell, const struct pair *pr,
		       size_t n, uint64_t *counts)
{
	char path[4096], name[64];
	vd_chunk_file_name(name, sizeof name, r->L0, cell, "svo");
	snprintf(path, sizeof path, "%s/%s", r->outdir, name);
	return vd_svo_write(path, r->pl.L, r->L0, cell, &r->tr,
			    r->opts->provenance, n, n ? &pr[0].key : NULL,
			    n ? &pr[0].mask : NULL, 2,
			    counts);
}

static int do_cell(struct run *r, struct worker *w, const struct job *j,
		   int *written)
{
	if (j->bricks > w->cap) {
		free(w->p);
		w->p = malloc(j->bricks * sizeof *w->p);
		w->cap = w->p ? j->bricks : 0;
		if (!w->p)
			return vd_fail(VD_ERR_NOMEM, "%llu bricks of cell %llx",
				       (unsigned long long)j->bricks,
				       (unsigned long long)j->cell);
	}
	size_t n = 0;
	for (size_t i = j->begin; i < j->end; i++) {
		int err = entry_pairs(r, &r->e[i], w->p, &n);
		if (err)
			return err;
	}
	/* leaves of a resampled grid share bricks: merge them */
	qsort(w->p, n, sizeof *w->p, cmp_pair);
	size_t m = 0;
	for (size_t i = 0; i < n; i++) {
		if (m && w->p[m - 1].key == w->p[i].key)
			w->p[m - 1].mask |= w->p[i].mask;
		else
			w->p[m++] = w->p[i];
	}
	*written = 0;
	if (m == 0)
		return VD_OK;
	uint64_t counts[VD_MAX_LEVELS + 1];
	int err = write_chunk(r, j->cell, w->p, m, counts);
	if (!err && r->col)
		err = write_colours(r, w, j->cell, w->p, m, counts);
	if (err)
		return err;
	*written = 1;
	int k = r->pl.L - r->L0;
	atomic_fetch_add(&r->bricks, m);
	atomic_fetch_add(&r->voxels, counts[k]);
	pthread_mutex_lock(&r->lock);
	for (int l = 0; l <= k; l++)
		r->level_nodes[l] += counts[l];
	pthread_mutex_unlock(&r->lock);
	return VD_OK;
}

static void cell_task(void *ctx, size_t i, int worker)
{
	struct run *r = ctx;
	if (atomic_load(&r->failed))
		return;
	int written = 0;
	int err = do_cell(r, &r->workers[worker], &r->jobs[i], &written);
	r->written[i] = (uint8_t)written;
	if (err) {
		pthread_mutex_lock(&r->lock);
		if (!r->err) {
			r->err = err;
			snprintf(r->detail, sizeof r->detail, "%s", vd_error_detail());
		}
		atomic_store(&r->failed, 1);
		pthread_mutex_unlock(&r->lock);
		return;
	}
	size_t done = atomic_fetch_add(&r->done, 1) + 1;
	if (r->opts->quiet)
		return;
	pthread_mutex_lock(&r->lock);
	double now = vd_seconds();
	if (now - r->last_say >= 1.0 || done == r->njobs) {
		r->last_say = now;
		say(r->opts, r->start, "cells %zu/%zu, %llu voxels", done, r->njobs,
		    (unsigned long long)atomic_load(&r->voxels));
	}
	pthread_mutex_unlock(&r->lock);
}

static int cmp_job(const void *a, const void *b)
{
	const struct job *x = a, *y = b;
	if (x->bricks != y->bricks)
		return x->bricks < y->bricks ? 1 : -1; /* largest first */
	return (x->cell > y->cell) - (x->cell < y->cell);
}

static int cmp_u64(const void *a, const void *b)
{
	uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
	return (x > y) - (x < y);
}

/* ------------------------------------------------------------ the driver */

/* Chooses L, k and the offsets (the rule is in vd_vdb.h). */
static int choose_place(const struct scan *s, int levels, struct place *p)
{
	int64_t off[3];
	int64_t e = extent_at(s, 0, off);
	if (levels == 0) {
		int L = depth_for(e);
		if (L > VD_MAX_LEVELS)
			return vd_fail(VD_ERR_RANGE, "the selected voxels span "
				       "%lld voxels, more than 2^%d: pass "
				       "--levels to resample", (long long)e,
				       VD_MAX_LEVELS);
		p->L = L;
		p->k = 0;
	} else {
		int k = 0;
		while (e > ((int64_t)1 << levels))
			e = extent_at(s, ++k, off);
		p->L = levels;
		p->k = k;
	}
	memcpy(p->off, off, sizeof off);
	return VD_OK;
}

/* Opens the colour grid when asked, fills res's grid fields and refuses a
 * grid that alone takes more than the memory budget. */
static int read_grids(struct run *r, const char *vdb_path,
		      const struct vd_vdb_select *sel,
		      struct vd_vdb_import_result *res)
{
	const struct vd_voxelize_opts *opts = r->opts;
	double t0 = r->start;
	int err;
	if (opts->colours &&
	    (err = vd_vdb_colour_open(&r->col, vdb_path, sel->colour_grid, r->vdb,
				      &res->colour)))
		return err;
	res->colours = r->col != NULL;
	res->mode = sel->mode;
	res->fog_threshold = sel->fog_threshold;
	res->seconds_read = vd_seconds() - t0;
	uint64_t grid_rss = vd_peak_rss_bytes();
	if (grid_rss > opts->mem_budget_bytes) {
		err = vd_fail(VD_ERR_BUDGET, "the grid%s alone take%s %llu MiB, "
			      "over --mem-budget %llu MiB", r->col ? "s" : "",
			      r->col ? "" : "s",
			      (unsigned long long)(grid_rss >> 20),
			      (unsigned long long)(opts->mem_budget_bytes >> 20));
		return err;
	}
	say(opts, t0, "read grid '%s' (%s, %s, %llu active voxels) in %.2fs",
	    res->info.grid_name, res->info.value_type, res->info.grid_class,
	    (unsigned long long)res->info.active_voxels, res->seconds_read);
	if (r->col)
		say(opts, t0, "colours from grid '%s' (%s, %s)",
		    res->colour.grid_name, res->colour.value_type,
		    res->colour.same_transform ? "same transform: read at each "
		    "voxel's index" : "other transform: nearest voxel to each "
		    "voxel's centre");
	return VD_OK;
}

/* Step 1: collects the entries (leaves and tiles) the mode selects;
 * refuses a grid with none. */
static int scan_grid(struct run *r, struct scan *s,
		     const struct vd_vdb_select *sel,
		     struct vd_vdb_import_result *res)
{
	int err = vd_vdb_scan(r->vdb, scan_node, s);
	if (err)
		return err;
	res->leaves_selected = s->leaves;
	res->tiles_selected = s->tiles;
	if (s->n == 0) {
		err = vd_fail(VD_ERR_EMPTY, "grid '%s' has no voxel that mode "
			      "%s selects", res->info.grid_name,
			      vd_vdb_mode_name(sel->mode));
		return err;
	}
	return VD_OK;
}

/* Step 2: places the entries in the cube (levels, resampling, offset),
 * splits them at cell edges and sorts them by cell; fills max_bricks (the
 * most bricks in one cell at each chunk level 0..F) and the transform. */
static int place_entries(struct run *r, struct scan *s,
			 const struct vd_vdb_import_result *res,
			 uint64_t max_bricks[MAX_CHUNK_LEVEL + 1])
{
	const struct vd_voxelize_opts *opts = r->opts;
	int err = choose_place(s, opts->levels, &r->pl);
	if (err)
		return err;
	int L = r->pl.L;
	int maxl = L - 2 > 0 ? L - 2 : 0;
	maxl = maxl > MAX_CHUNK_LEVEL ? MAX_CHUNK_LEVEL : maxl;
	if (opts->chunk_level > maxl) {
		err = vd_fail(VD_ERR_RANGE, "--chunk-level %d is outside 0..%d "
			      "for %d levels", opts->chunk_level, maxl, L);
		return err;
	}
	/* cells of 8 voxels or more: a leaf then never straddles two */
	r->pl.F = opts->chunk_level >= 0 ? opts->chunk_level
		 : L - 3 > MAX_CHUNK_LEVEL ? MAX_CHUNK_LEVEL : L - 3 > 0 ? L - 3 : 0;
	err = split_entries(s, &r->pl);
	if (err)
		return err;
	qsort(s->e, s->n, sizeof *s->e, cmp_entry);
	r->e = s->e;
	int F = r->pl.F;
	for (int l = 0; l <= F; l++) {
		int sh = 3 * (F - l);
		for (size_t i = 0; i < s->n;) {
			uint64_t sum = 0, c = s->e[i].cell >> sh;
			for (; i < s->n && s->e[i].cell >> sh == c; i++)
				sum += s->e[i].bricks;
			max_bricks[l] = sum > max_bricks[l] ? sum : max_bricks[l];
		}
	}
	double vs_src = res->info.voxel_size;
	double vs = vs_src * (double)((int64_t)1 << r->pl.k);
	for (int a = 0; a < 3; a++) {
		const double *t = res->info.translation;
		r->tr.origin[a] = t[a] + ((double)r->pl.off[a] - 0.5) * vs_src;
		r->tr.bbox_min[a] = (float)(t[a] + ((double)s->lo[a] - 0.5) * vs_src);
		r->tr.bbox_max[a] = (float)(t[a] + ((double)s->hi[a] + 0.5) * vs_src);
	}
	r->tr.voxel_size = vs;
	r->tr.root_side = (float)(vs * (double)((int64_t)1 << L));
	return VD_OK;
}

/* Chooses the chunk level r->L0 and the number of workers: the most
 * threads, then the coarsest level, whose cells fit the memory left. */
static int choose_workers(struct run *r, const struct scan *s,
			  const uint64_t max_bricks[MAX_CHUNK_LEVEL + 1],
			  int *nworkers)
{
	const struct vd_voxelize_opts *opts = r->opts;
	int L = r->pl.L, F = r->pl.F;
	int err;
	int threads = opts->threads > 0 ? opts->threads : vd_hardware_threads();
	uint64_t base = vd_peak_rss_bytes();
	uint64_t avail = opts->mem_budget_bytes > base ? opts->mem_budget_bytes - base : 0;
	r->L0 = -1;
	for (int want = threads; want >= 1 && r->L0 < 0; want = want > 1 ? 1 : 0)
		for (int l = opts->chunk_level >= 0 ? F : 0; l <= F; l++) {
			uint64_t per = max_bricks[l] * sizeof(struct pair) + WORKER_OVERHEAD;
			if ((uint64_t)want * per <= avail) {
				r->L0 = l;
				*nworkers = want;
				break;
			}
		}
	if (r->L0 < 0) {
		err = vd_fail(VD_ERR_BUDGET, "--mem-budget %llu MiB cannot hold "
			      "the grid (%llu MiB) and one cell at chunk level "
			      "%d (%llu MiB)",
			      (unsigned long long)(opts->mem_budget_bytes >> 20),
			      (unsigned long long)(base >> 20), F,
			      (unsigned long long)((max_bricks[F] * sizeof(struct pair) +
						    WORKER_OVERHEAD) >> 20) + 1);
		return err;
	}
	say(opts, r->start, "%llu leaves and %llu tiles selected; %d levels%s, "
	    "chunk level %d, %d threads", (unsigned long long)s->leaves,
	    (unsigned long long)s->tiles, L, r->pl.k ? " (resampled)" : "", r->L0,
	    *nworkers);
	return VD_OK;
}

/* The jobs: runs of entries in one L0 cell, largest first (cmp_job); also
 * allocates the per-job and per-worker arrays. */
static int make_jobs(struct run *r, const struct scan *s, int nworkers)
{
	int F = r->pl.F;
	int err;
	int jsh = 3 * (F - r->L0);
	size_t nj = 0;
	for (size_t i = 0; i < s->n; i++)
		nj += i == 0 || s->e[i].cell >> jsh != s->e[i - 1].cell >> jsh;
	r->jobs = calloc(nj, sizeof *r->jobs);
	r->written = calloc(nj, 1);
	r->workers = calloc((size_t)nworkers, sizeof *r->workers);
	if (!r->jobs || !r->written || !r->workers) {
		err = vd_fail(VD_ERR_NOMEM, "%zu cells", nj);
		return err;
	}
	for (size_t i = 0; i < s->n;) {
		struct job *j = &r->jobs[r->njobs++];
		j->begin = i;
		j->cell = s->e[i].cell >> jsh;
		for (; i < s->n && s->e[i].cell >> jsh == j->cell; i++)
			j->bricks += s->e[i].bricks;
		j->end = i;
	}
	qsort(r->jobs, r->njobs, sizeof *r->jobs, cmp_job);
	return VD_OK;
}

/* Step 3: voxelizes and writes the cells' chunks in parallel into outdir
 * (created, its old chunks removed: *cleaned then set); nodes gets the
 * node counts of levels L0..L. */
static int write_cells(struct run *r, const char *outdir, int nworkers,
		       uint64_t nodes[VD_MAX_LEVELS + 1], int *cleaned)
{
	int err;
	if (mkdir(outdir, 0777) != 0 && errno != EEXIST) {
		err = vd_fail(VD_ERR_IO, "cannot create '%s': %s", outdir,
			      strerror(errno));
		return err;
	}
	vd_remove_chunks(outdir);
	*cleaned = 1;
	r->level_nodes = nodes;
	err = vd_parallel_for(r->njobs, nworkers, cell_task, r);
	if (!err && r->err)
		err = vd_fail(r->err, "%s", r->detail);
	return err;
}

/* Fills res: the node counts of the levels above L0 (distinct prefixes
 * of the non-empty cells, sorted into *cells, which the caller frees),
 * the placement and totals; refuses a run whose peak memory went over the
 * budget. */
static int fill_result(struct run *r, const uint64_t nodes[VD_MAX_LEVELS + 1],
		       int nworkers, uint64_t **cells_out,
		       struct vd_vdb_import_result *res)
{
	const struct vd_voxelize_opts *opts = r->opts;
	double t0 = r->start;
	int L = r->pl.L;
	int err = VD_OK;
	uint64_t *cells = malloc((r->njobs ? r->njobs : 1) * sizeof *cells);
	*cells_out = cells;
	if (!cells) {
		err = vd_fail(VD_ERR_NOMEM, "cells");
		return err;
	}
	size_t nonempty = 0;
	for (size_t i = 0; i < r->njobs; i++)
		if (r->written[i])
			cells[nonempty++] = r->jobs[i].cell;
	qsort(cells, nonempty, sizeof *cells, cmp_u64);
	for (int l = 0; l < r->L0; l++) {
		int sh = 3 * (r->L0 - l);
		for (size_t i = 0; i < nonempty; i++)
			res->level_nodes[l] += i == 0 || cells[i] >> sh != cells[i - 1] >> sh;
	}
	for (int l = r->L0; l <= L; l++)
		res->level_nodes[l] = nodes[l - r->L0];
	res->levels = L;
	res->chunk_level = r->L0;
	res->transform = r->tr;
	res->resample_shift = r->pl.k;
	for (int a = 0; a < 3; a++)
		res->index_offset[a] = (int32_t)r->pl.off[a];
	res->voxels = atomic_load(&r->voxels);
	res->bricks = atomic_load(&r->bricks);
	res->chunks = nonempty;
	res->threads = nworkers;
	res->mem_budget_bytes = opts->mem_budget_bytes;
	res->seconds_total = vd_seconds() - t0;
	res->peak_rss_bytes = vd_peak_rss_bytes();
	say(opts, t0, "%llu voxels in %llu chunks, %.2fs",
	    (unsigned long long)res->voxels, (unsigned long long)res->chunks,
	    res->seconds_total);
	if (res->peak_rss_bytes > opts->mem_budget_bytes)
		err = vd_fail(VD_ERR_BUDGET, "peak memory %llu MiB exceeded "
			      "--mem-budget %llu MiB",
			      (unsigned long long)(res->peak_rss_bytes >> 20),
			      (unsigned long long)(opts->mem_budget_bytes >> 20));
	return err;
}

int vd_vdb_import(const char *vdb_path, const char *outdir,
		  const struct vd_vdb_select *sel,
		  const struct vd_voxelize_opts *opts,
		  struct vd_vdb_import_result *res)
{
	memset(res, 0, sizeof *res);
	double t0 = vd_seconds();
	if (opts->levels < 0 || opts->levels > VD_MAX_LEVELS)
		return vd_fail(VD_ERR_RANGE, "--levels %d is outside 1..%d",
			       opts->levels, VD_MAX_LEVELS);
	struct run r = {.lock = PTHREAD_MUTEX_INITIALIZER, .opts = opts,
			.outdir = outdir, .start = t0};
	struct scan s = {.lo = {INT64_MAX, INT64_MAX, INT64_MAX},
			 .hi = {INT64_MIN, INT64_MIN, INT64_MIN}};
	uint64_t *cells = NULL;
	int cleaned = 0, nworkers = 0;
	int err = vd_vdb_open(&r.vdb, vdb_path, sel, &res->info);
	if (err)
		return err;
	if ((err = read_grids(&r, vdb_path, sel, res)))
		goto out;

	/* 1. scan */
	double t1 = vd_seconds();
	if ((err = scan_grid(&r, &s, sel, res)))
		goto out;

	/* 2. place, split, plan */
	uint64_t max_bricks[MAX_CHUNK_LEVEL + 1] = {0};
	if ((err = place_entries(&r, &s, res, max_bricks)))
		goto out;
	res->seconds_scan = vd_seconds() - t1;
	if ((err = choose_workers(&r, &s, max_bricks, &nworkers)))
		goto out;
	if ((err = make_jobs(&r, &s, nworkers)))
		goto out;

	/* 3. cells */
	t1 = vd_seconds();
	uint64_t nodes[VD_MAX_LEVELS + 1] = {0};
	if ((err = write_cells(&r, outdir, nworkers, nodes, &cleaned)))
		goto out;
	res->seconds_voxelize = vd_seconds() - t1;
	err = fill_result(&r, nodes, nworkers, &cells, res);
out:
	if (r.workers)
		for (int i = 0; i < nworkers; i++) {
			free(r.workers[i].p);
			free(r.workers[i].rgb);
		}
	free(r.workers);
	free(r.jobs);
	free(r.written);
	free(cells);
	free(s.e);
	vd_vdb_colour_close(r.col);
	vd_vdb_close(r.vdb);
	if (err && cleaned)
		vd_remove_chunks(outdir); /* no partial set of chunks survives */
	return err;
}

int vd_vdb_import_write_stats(const struct vd_vdb_import_result *res,
			      const char *path)
{
	struct vd_json *j;
	int err = vd_voxelize_stats_open(&j, path, "vdb");
	if (err)
		return err;
	vd_json_object(j, "vdb");
	vd_json_str(j, "grid", res->info.grid_name);
	vd_json_str(j, "value_type", res->info.value_type);
	vd_json_str(j, "grid_class", res->info.grid_class);
	vd_json_str(j, "mode", vd_vdb_mode_name(res->mode));
	vd_json_f64(j, "fog_threshold", res->fog_threshold);
	vd_json_f64(j, "voxel_size", res->info.voxel_size);
	vd_json_u64(j, "active_voxels", res->info.active_voxels);
	vd_json_u64(j, "leaves", res->info.leaves);
	vd_json_u64(j, "leaves_selected", res->leaves_selected);
	vd_json_u64(j, "tiles_selected", res->tiles_selected);
	vd_json_u64(j, "resample_factor", (uint64_t)1 << res->resample_shift);
	if (res->colours) {
		vd_json_str(j, "colour_grid", res->colour.grid_name);
		vd_json_str(j, "colour_value_type", res->colour.value_type);
		vd_json_str(j, "colour_lookup", res->colour.same_transform
			    ? "index" : "nearest to centre");
	}
	vd_json_end_object(j);
	vd_json_u64(j, "colours", (uint64_t)res->colours);
	vd_json_u64(j, "levels", (uint64_t)res->levels);
	vd_json_u64(j, "chunk_level", (uint64_t)res->chunk_level);
	vd_json_object(j, "seconds");
	vd_json_f64(j, "read", res->seconds_read);
	vd_json_f64(j, "scan_and_plan", res->seconds_scan);
	vd_json_f64(j, "voxelize", res->seconds_voxelize);
	vd_json_f64(j, "total", res->seconds_total);
	vd_json_end_object(j);
	struct vd_voxelize_totals tot = {
		res->levels, res->voxels, res->bricks, res->chunks,
		res->level_nodes, res->seconds_total, res->threads,
		res->peak_rss_bytes, res->mem_budget_bytes, &res->transform};
	vd_voxelize_stats_totals(j, &tot);
	return vd_json_close(j);
}
