/* colours.c - the HashDAG's voxel colours: the scene's colour array in
 * depth-first order (colour paper section 3), cut into the cells of one
 * chunk level as voxelize and colorize cut it, so an edit rebuilds only
 * the arrays of the cells its region meets and every other cell's array
 * is shared, by reference, with the previous root of the history. Undo
 * and redo switch tables; gc drops the tables of the roots it drops. The
 * colours are saved as a voxelize-style directory (SVO and colour chunk
 * per cell) whose unchanged cells are links to the source's files. */
#include "edit_internal.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* ------------------------------------------------------------ cells */

static int cell_new(struct vd_hashdag *h, uint64_t n, struct hd_cellcol **out)
{
	struct hd_colours *c = h->col;
	uint64_t more = sizeof **out + 3 * n;
	if (h->o.mem_budget_bytes) {
		uint64_t now = __atomic_add_fetch(&c->bytes, more,
						  __ATOMIC_RELAXED);
		if (now + h->fixed_bytes + h->committed_bytes >
		    h->o.mem_budget_bytes) {
			__atomic_sub_fetch(&c->bytes, more, __ATOMIC_RELAXED);
			return hd_budget_check(h, more, "colours of a cell");
		}
	}
	struct hd_cellcol *p = malloc(more + 1);
	if (!p) {
		if (h->o.mem_budget_bytes)
			__atomic_sub_fetch(&c->bytes, more, __ATOMIC_RELAXED);
		return vd_fail(VD_ERR_NOMEM, "colours of %llu voxels",
			       (unsigned long long)n);
	}
	if (!h->o.mem_budget_bytes)
		__atomic_add_fetch(&c->bytes, more, __ATOMIC_RELAXED);
	p->refs = 1;
	p->n = n;
	*out = p;
	return VD_OK;
}

void hd_cellcol_unref(struct hd_colours *c, struct hd_cellcol *p)
{
	if (p && __atomic_sub_fetch(&p->refs, 1, __ATOMIC_RELAXED) == 0) {
		__atomic_sub_fetch(&c->bytes, sizeof *p + 3 * p->n,
				   __ATOMIC_RELAXED);
		free(p);
	}
}

void hd_coltab_free(struct hd_colours *c, struct hd_cellcol **tab)
{
	if (!tab)
		return;
	for (uint64_t i = 0; i < c->ncells; i++)
		hd_cellcol_unref(c, tab[i]);
	free(tab);
}

void hd_colours_free(struct hd_colours *c)
{
	if (!c)
		return;
	hd_coltab_free(c, c->input);
	free(c->tab);
	free(c->src_dir);
	free(c);
}

int vd_hashdag_has_colours(const struct vd_hashdag *h)
{
	return h->col != NULL;
}

/* The corner of cell `ci` (Morton code at level C). */
static void cell_corner(const struct vd_hashdag *h, uint64_t ci, uint32_t *x,
			uint32_t *y, uint32_t *z)
{
	int s = h->levels - h->col->C;
	vd_morton3_decode(ci, x, y, z);
	*x <<= s;
	*y <<= s;
	*z <<= s;
}

static uint32_t cell_ptr(const struct vd_hashdag *h, uint32_t root,
			 uint64_t ci)
{
	uint32_t x, y, z;
	cell_corner(h, ci, &x, &y, &z);
	return hd_lookup(h, root, h->col->C, x, y, z);
}

/* ---------------------------------------------------- decoding a cell */

/* The set voxels of a subtree as global Morton codes (increasing), or its
 * bricks (keys at level L-2, masks). */
struct vlist {
	uint64_t *m, *mask;
	uint64_t n, cap;
	int bricks;
};

static int vl_push(struct vlist *v, uint64_t m, uint64_t mask)
{
	if (v->n == v->cap) {
		uint64_t cap = v->cap ? 2 * v->cap : 1024;
		uint64_t *a = realloc(v->m, cap * 8);
		if (!a)
			return vd_fail(VD_ERR_NOMEM, "cell decode");
		v->m = a;
		if (v->bricks) {
			a = realloc(v->mask, cap * 8);
			if (!a)
				return vd_fail(VD_ERR_NOMEM, "cell decode");
			v->mask = a;
		}
		v->cap = cap;
	}
	if (v->bricks)
		v->mask[v->n] = mask;
	v->m[v->n++] = m;
	return VD_OK;
}

static int walk(const struct vd_hashdag *h, int l, uint32_t p, uint64_t key,
		struct vlist *v)
{
	if (p == HD_EMPTY)
		return VD_OK;
	if (l == h->levels - 2) {
		uint64_t b = hd_brick(h, p);
		if (v->bricks)
			return vl_push(v, key, b);
		for (; b; b &= b - 1)
			if (vl_push(v, key << 6 | (uint64_t)__builtin_ctzll(b), 0))
				return VD_ERR_NOMEM;
		return VD_OK;
	}
	for (int c = 0; c < 8; c++) {
		int err = walk(h, l + 1, hd_child(h, l, p, c),
			       key << 3 | (uint64_t)c, v);
		if (err)
			return err;
	}
	return VD_OK;
}

static void vl_free(struct vlist *v)
{
	free(v->m);
	free(v->mask);
	memset(v, 0, sizeof *v);
}

/* ----------------------------------------------------------- loading */

int vd_hashdag_colours_open(struct vd_hashdag *h, const char *src,
			    const uint8_t *fill_rgb)
{
	static const uint8_t grey[3] = VD_EDIT_DEFAULT_RGB;
	if (h->col)
		return vd_fail(VD_ERR_ARG, "the scene has colours already");
	if (h->nroots != 1)
		return vd_fail(VD_ERR_ARG, "colours are opened before any edit");
	struct vd_colour_source s;
	int err = vd_colour_source_open(&s, src);
	if (err)
		return err;
	int L = h->levels;
	if (s.levels != L) {
		vd_colour_source_release(&s);
		return vd_fail(VD_ERR_MISMATCH, "'%s' colours a 2^%d grid, the "
			       "scene is 2^%d", src, s.levels, L);
	}
	struct hd_colours *c = calloc(1, sizeof *c);
	if (!c) {
		vd_colour_source_release(&s);
		return vd_fail(VD_ERR_NOMEM, "colours");
	}
	c->C = s.cell_level >= 0 && s.cell_level <= L - 2
		       ? s.cell_level : (L - 2 < 3 ? L - 2 : 3);
	c->ncells = 1ull << 3 * c->C;
	memcpy(c->fill_rgb, fill_rgb ? fill_rgb : grey, 3);
	struct stat st;
	if (!stat(src, &st) && S_ISDIR(st.st_mode) && !(c->src_dir = strdup(src)))
		err = vd_fail(VD_ERR_NOMEM, "colours");
	c->tab = calloc(h->cap_roots ? h->cap_roots : 1, sizeof *c->tab);
	struct hd_cellcol **tab = calloc(c->ncells, sizeof *tab);
	c->input = calloc(c->ncells, sizeof *tab);
	if (!err && (!c->tab || !tab || !c->input))
		err = vd_fail(VD_ERR_NOMEM, "colour tables");
	h->col = c;
	uint64_t at = 0;
	uint32_t root = h->roots[h->cur];
	for (uint64_t ci = 0; ci < c->ncells && !err; ci++) {
		uint32_t p = cell_ptr(h, root, ci);
		if (p == HD_EMPTY)
			continue;
		uint64_t n = hd_voxels_of(h, c->C, p);
		if (at + n > s.voxels) {
			err = vd_fail(VD_ERR_MISMATCH, "'%s' has %llu colours, "
				      "fewer than the scene's voxels", src,
				      (unsigned long long)s.voxels);
			break;
		}
		if ((err = cell_new(h, n, &tab[ci])))
			break;
		for (uint64_t k = 0; k < n; k++)
			s.get(&s, at + k, tab[ci]->rgb + 3 * k);
		at += n;
		tab[ci]->refs++;
		c->input[ci] = tab[ci];
	}
	if (!err && at != s.voxels)
		err = vd_fail(VD_ERR_MISMATCH, "'%s' has %llu colours for a "
			      "scene of %llu voxels", src,
			      (unsigned long long)s.voxels,
			      (unsigned long long)at);
	vd_colour_source_release(&s);
	if (err) {
		hd_coltab_free(c, tab);
		hd_colours_free(c);
		h->col = NULL;
		return err;
	}
	c->tab[0] = tab;
	return VD_OK;
}

int vd_hashdag_colour_array(const struct vd_hashdag *h, uint8_t **rgb,
			    uint64_t *voxels)
{
	if (!h->col)
		return vd_fail(VD_ERR_UNSUPPORTED, "the scene has no colours");
	struct hd_cellcol **tab = h->col->tab[h->cur];
	uint64_t n = 0;
	for (uint64_t ci = 0; ci < h->col->ncells; ci++)
		n += tab[ci] ? tab[ci]->n : 0;
	uint8_t *a = malloc(3 * n + 1);
	if (!a)
		return vd_fail(VD_ERR_NOMEM, "colour array");
	n = 0;
	for (uint64_t ci = 0; ci < h->col->ncells; ci++)
		if (tab[ci]) {
			memcpy(a + 3 * n, tab[ci]->rgb, 3 * tab[ci]->n);
			n += tab[ci]->n;
		}
	*rgb = a;
	*voxels = n;
	return VD_OK;
}

/* ----------------------------------------------------------- editing */

/* A copy's source cells, decoded in the scene before the edit. */
struct srccell {
	uint64_t ci;
	struct vlist v;
	const struct hd_cellcol *col;
};

struct cjob {
	uint64_t ci;
	struct hd_cellcol *out;
	uint64_t changed;
	int err;
	char detail[240];
};

struct cctx {
	struct vd_hashdag *h;
	const struct vd_edit_op *op;
	uint32_t old_root, new_root;
	struct hd_cellcol **old;
	struct srccell *src;
	size_t nsrc;
	struct cjob *jobs;
};

static int src_colour(const struct cctx *x, uint64_t m, uint8_t rgb[3])
{
	const struct vd_hashdag *h = x->h;
	uint64_t ci = m >> 3 * (h->levels - h->col->C);
	size_t lo = 0, hi = x->nsrc;
	while (lo < hi) {
		size_t mid = (lo + hi) / 2;
		if (x->src[mid].ci < ci)
			lo = mid + 1;
		else
			hi = mid;
	}
	if (lo == x->nsrc || x->src[lo].ci != ci)
		return 0;
	const struct vlist *v = &x->src[lo].v;
	uint64_t a = 0, b = v->n;
	while (a < b) {
		uint64_t mid = (a + b) / 2;
		if (v->m[mid] < m)
			a = mid + 1;
		else
			b = mid;
	}
	if (a == v->n || v->m[a] != m)
		return 0;
	memcpy(rgb, x->src[lo].col->rgb + 3 * a, 3);
	return 1;
}

static int rebuild(struct cctx *x, uint64_t ci, struct hd_cellcol **out,
		   uint64_t *changed)
{
	struct vd_hashdag *h = x->h;
	const struct vd_edit_op *op = x->op;
	const struct hd_cellcol *old = x->old[ci];
	uint32_t np = cell_ptr(h, x->new_root, ci),
		 op_ = cell_ptr(h, x->old_root, ci);
	*out = NULL;
	if (np == HD_EMPTY)
		return VD_OK;
	struct vlist ov = {0}, nv = {0};
	int err = walk(h, h->col->C, op_, ci, &ov);
	if (!err)
		err = walk(h, h->col->C, np, ci, &nv);
	if (!err && ov.n != (old ? old->n : 0))
		err = vd_fail(VD_ERR_INTERNAL, "cell %llx: %llu voxels, %llu "
			      "colours", (unsigned long long)ci,
			      (unsigned long long)ov.n,
			      (unsigned long long)(old ? old->n : 0));
	struct hd_cellcol *c = NULL;
	if (!err)
		err = cell_new(h, nv.n, &c);
	int64_t d[3] = {0, 0, 0};
	if (op->kind == VD_EDIT_COPY)
		for (int a = 0; a < 3; a++)
			d[a] = op->dst[a] - op->lo[a];
	uint64_t j = 0, ch = 0;
	for (uint64_t i = 0; i < nv.n && !err; i++) {
		uint64_t m = nv.m[i];
		while (j < ov.n && ov.m[j] < m)
			j++;
		int had = j < ov.n && ov.m[j] == m;
		const uint8_t *was = had ? old->rgb + 3 * j : NULL;
		uint8_t *to = c->rgb + 3 * i;
		uint32_t vx, vy, vz;
		vd_morton3_decode(m, &vx, &vy, &vz);
		int ok = 1;
		if (!hd_op_has(op, vx, vy, vz)) {
			if (had)
				memcpy(to, was, 3);
			else
				ok = 0;
		} else if (op->kind == VD_EDIT_COPY) {
			ok = src_colour(x, vd_morton3((uint32_t)(vx - d[0]),
						      (uint32_t)(vy - d[1]),
						      (uint32_t)(vz - d[2])),
					to);
		} else if (op->kind == VD_EDIT_PAINT ||
			   (op->kind == VD_EDIT_FILL && op->has_rgb)) {
			memcpy(to, op->rgb, 3);
		} else if (op->kind == VD_EDIT_FILL) {
			memcpy(to, had ? was : h->col->fill_rgb, 3);
		} else {
			ok = 0; /* a carved voxel cannot be set */
		}
		if (!ok)
			err = vd_fail(VD_ERR_INTERNAL, "voxel (%u, %u, %u) has "
				      "no colour after the edit", vx, vy, vz);
		else if (had && memcmp(to, was, 3))
			ch++;
	}
	/* an unchanged cell (voxels and colours) keeps sharing its array,
	 * and so its source files */
	int same = !err && old && ov.n == nv.n &&
		   !memcmp(ov.m, nv.m, 8 * nv.n) &&
		   !memcmp(old->rgb, c->rgb, 3 * c->n);
	vl_free(&ov);
	vl_free(&nv);
	if (err) {
		hd_cellcol_unref(h->col, c);
		return err;
	}
	if (same) {
		hd_cellcol_unref(h->col, c);
		c = x->old[ci];
		__atomic_add_fetch(&c->refs, 1, __ATOMIC_RELAXED);
	}
	*out = c;
	*changed = ch;
	return VD_OK;
}

static void run_cjob(void *ctx, size_t i, int worker)
{
	(void)worker;
	struct cctx *x = ctx;
	struct cjob *j = &x->jobs[i];
	j->err = rebuild(x, j->ci, &j->out, &j->changed);
	if (j->err)
		snprintf(j->detail, sizeof j->detail, "%s", vd_error_detail());
}

/* The cells (codes at level C) the box lo..hi meets, in increasing order. */
static int cells_of(const struct vd_hashdag *h, const int64_t *lo,
		    const int64_t *hi, uint64_t **out, size_t *n)
{
	int s = h->levels - h->col->C;
	int64_t a[3], b[3];
	uint64_t k = 1;
	for (int i = 0; i < 3; i++) {
		a[i] = lo[i] >> s;
		b[i] = hi[i] >> s;
		k *= (uint64_t)(b[i] - a[i] + 1);
	}
	uint64_t *v = malloc(k * sizeof *v);
	if (!v)
		return vd_fail(VD_ERR_NOMEM, "cell list");
	size_t m = 0;
	for (int64_t x = a[0]; x <= b[0]; x++)
		for (int64_t y = a[1]; y <= b[1]; y++)
			for (int64_t z = a[2]; z <= b[2]; z++)
				v[m++] = vd_morton3((uint32_t)x, (uint32_t)y,
						    (uint32_t)z);
	/* sort: cells are few next to their voxels */
	for (size_t i = 1; i < m; i++) {
		uint64_t t = v[i];
		size_t j = i;
		for (; j && v[j - 1] > t; j--)
			v[j] = v[j - 1];
		v[j] = t;
	}
	*out = v;
	*n = m;
	return VD_OK;
}

/* The bounding box of the voxels op writes, clipped to the grid. */
static void op_bbox(const struct vd_hashdag *h, const struct vd_edit_op *op,
		    int64_t *lo, int64_t *hi)
{
	int64_t n = (int64_t)1 << h->levels;
	for (int a = 0; a < 3; a++) {
		if (op->kind == VD_EDIT_COPY) {
			lo[a] = op->dst[a];
			hi[a] = op->dst[a] + op->hi[a] - op->lo[a];
		} else if (op->shape == VD_SHAPE_SPHERE) {
			double l = op->c[a] - op->r - 1, u = op->c[a] + op->r;
			lo[a] = l < 0 ? 0 : (int64_t)l;
			hi[a] = u >= (double)n ? n - 1 : (int64_t)u;
		} else {
			lo[a] = op->lo[a];
			hi[a] = op->hi[a];
		}
	}
}

int hd_colours_edit(struct vd_hashdag *h, const struct vd_edit_op *op,
		    uint32_t old_root, uint32_t new_root,
		    struct hd_cellcol ***out, uint64_t *changed_colours,
		    uint64_t *cells_rebuilt)
{
	struct hd_colours *c = h->col;
	struct cctx x = {.h = h, .op = op, .old_root = old_root,
			 .new_root = new_root, .old = c->tab[h->cur]};
	int64_t lo[3], hi[3];
	uint64_t *cells = NULL, *scells = NULL;
	size_t n = 0, ns = 0;
	*changed_colours = 0;
	struct hd_cellcol **tab = malloc(c->ncells * sizeof *tab);
	if (!tab)
		return vd_fail(VD_ERR_NOMEM, "colour table");
	memcpy(tab, x.old, c->ncells * sizeof *tab);
	op_bbox(h, op, lo, hi);
	int err = cells_of(h, lo, hi, &cells, &n);
	/* a fill without a colour or a carve changes the colours of the
	 * cells whose voxels it changes only */
	int geometry_only = (op->kind == VD_EDIT_FILL && !op->has_rgb) ||
			    op->kind == VD_EDIT_CARVE;
	size_t k = 0;
	for (size_t i = 0; i < n && !err; i++)
		if (!geometry_only || cell_ptr(h, old_root, cells[i]) !=
					      cell_ptr(h, new_root, cells[i]))
			cells[k++] = cells[i];
	n = k;
	*cells_rebuilt = n;
	if (!err && op->kind == VD_EDIT_COPY && n) {
		err = cells_of(h, op->lo, op->hi, &scells, &ns);
		x.src = err ? NULL : calloc(ns ? ns : 1, sizeof *x.src);
		if (!err && !x.src)
			err = vd_fail(VD_ERR_NOMEM, "copy sources");
		for (size_t i = 0; i < ns && !err; i++) {
			x.src[x.nsrc].ci = scells[i];
			x.src[x.nsrc].col = x.old[scells[i]];
			err = walk(h, c->C, cell_ptr(h, old_root, scells[i]),
				   scells[i], &x.src[x.nsrc].v);
			x.nsrc++;
		}
	}
	x.jobs = err ? NULL : calloc(n ? n : 1, sizeof *x.jobs);
	if (!err && !x.jobs)
		err = vd_fail(VD_ERR_NOMEM, "colour jobs");
	for (size_t i = 0; i < n && !err; i++)
		x.jobs[i].ci = cells[i];
	if (!err && n && vd_parallel_for(n, h->o.threads, run_cjob, &x))
		err = vd_fail(VD_ERR_INTERNAL, "thread pool");
	for (size_t i = 0; i < n && !err; i++)
		if (x.jobs[i].err)
			err = vd_fail(x.jobs[i].err, "%s", x.jobs[i].detail);
	/* every other cell is shared with the previous root */
	for (uint64_t ci = 0; ci < c->ncells && !err; ci++)
		if (tab[ci])
			tab[ci]->refs++;
	for (size_t i = 0; i < n && !err; i++) {
		uint64_t ci = cells[i];
		hd_cellcol_unref(c, tab[ci]);
		tab[ci] = x.jobs[i].out;
		x.jobs[i].out = NULL;
		*changed_colours += x.jobs[i].changed;
	}
	for (size_t i = 0; x.jobs && i < n; i++)
		hd_cellcol_unref(c, x.jobs[i].out);
	for (size_t i = 0; i < x.nsrc; i++)
		vl_free(&x.src[i].v);
	free(x.src);
	free(x.jobs);
	free(cells);
	free(scells);
	if (err) {
		free(tab);
		return err;
	}
	*out = tab;
	return VD_OK;
}

/* ------------------------------------------------------------ saving */

/* dir/name into buf; -1 when it does not fit. */
static int join(char *buf, size_t cap, const char *dir, const char *name)
{
	int n = snprintf(buf, cap, "%s/%s", dir, name);
	return n < 0 || (size_t)n >= cap ? -1 : 0;
}

/* Links the cell's two files from the source directory (0), or -1. */
static int link_cell(const char *src, const char *dst, const char *svo,
		     const char *col)
{
	char a[4096], b[4096], b2[4096];
	if (join(a, sizeof a, src, svo) || join(b, sizeof b, dst, svo) ||
	    link(a, b))
		return -1;
	if (join(a, sizeof a, src, col) || join(b2, sizeof b2, dst, col) ||
	    link(a, b2)) {
		unlink(b);
		return -1;
	}
	return 0;
}

static int write_cell(const struct vd_hashdag *h, uint64_t ci,
		      const struct hd_cellcol *cell, const char *dir,
		      const char *svo_name, const char *col_name,
		      const char *provenance)
{
	struct vlist v = {.bricks = 1};
	char path[4096];
	int err = walk(h, h->col->C, cell_ptr(h, h->roots[h->cur], ci), ci, &v);
	struct vd_svo s = {.levels = h->levels, .chunk_level = h->col->C,
			   .cell_morton = ci, .count = v.n, .keys = v.m,
			   .masks = v.mask};
	struct vd_chunk_header sh;
	if (!err && join(path, sizeof path, dir, svo_name))
		err = vd_fail(VD_ERR_ARG, "directory name too long");
	if (!err)
		err = vd_svo_save(&s, &h->t, path, provenance);
	if (!err)
		err = vd_chunk_read_header(path, &sh);
	if (!err && join(path, sizeof path, dir, col_name))
		err = vd_fail(VD_ERR_ARG, "directory name too long");
	if (!err)
		err = vd_colours_save(path, &sh, vd_svo_digest(v.m, v.mask, v.n),
				      cell->rgb, cell->n, provenance);
	vl_free(&v);
	return err;
}

int vd_hashdag_colours_save(const struct vd_hashdag *h, const char *dir,
			    const char *provenance)
{
	if (!h->col)
		return vd_fail(VD_ERR_UNSUPPORTED, "the scene has no colours");
	const struct hd_colours *c = h->col;
	char staging[4096];
	int err = vd_dir_stage(dir, NULL, staging, sizeof staging);
	if (err)
		return err;
	struct hd_cellcol **tab = c->tab[h->cur];
	for (uint64_t ci = 0; ci < c->ncells && !err; ci++) {
		if (!tab[ci])
			continue;
		char svo[64], col[64];
		vd_chunk_file_name(svo, sizeof svo, c->C, ci, "svo");
		vd_chunk_file_name(col, sizeof col, c->C, ci, "col");
		if (c->src_dir && tab[ci] == c->input[ci] &&
		    !link_cell(c->src_dir, staging, svo, col))
			continue;
		err = write_cell(h, ci, tab[ci], staging, svo, col, provenance);
	}
	if (!err)
		err = vd_dir_publish(staging, dir);
	else
		vd_dir_abandon(staging);
	return err;
}
