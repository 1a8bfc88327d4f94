/* colours.c - the HashDAG's voxel colours: the scene's colour array in
 * depth-first order (colour paper section 3), cut into the cells of one
 * chunk level as voxelize and colorize cut it, and each cell's array cut
 * again into segments (the subtrees of a deeper level), so an edit
 * rebuilds only the segments its region meets and every other segment and
 * cell is shared, by reference, with the previous root of the history. Undo
 * and redo switch tables; gc drops the tables of the roots it drops. The
 * colours are saved as a voxelize-style directory (SVO and colour chunk
 * per cell) whose unchanged cells are links to the source's files.
 *
 * A segment no edit wrote is only its place in the source, read on
 * demand (a load neither decodes nor encodes colours); one an edit wrote
 * is lossless auto blocks. Reading, rebuilding and saving go segment by
 * segment, in batches: no step holds a cell's colours or bricks whole. */
#include "edit_internal.h"
#include "util_internal.h"

#include <dirent.h>
#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* An edit reads the old colours still in the source of at most this many
 * bytes of segments before rebuilding them, then the next batch: what an
 * edit of the whole scene holds raw at once. */
#define HD_COL_BATCH_BYTES (8ull << 20)

/* ------------------------------------------------------------ cells */

/* dir/name into buf; -1 when it does not fit. */
static int join(char *buf, size_t cap, const char *dir, const char *name)
{
	int n = snprintf(buf, cap, "%s/%s", dir, name);
	return n < 0 || (size_t)n >= cap ? -1 : 0;
}


/* Counts `more` bytes of colours against the budget (VD_ERR_BUDGET). */
static int col_charge(struct vd_hashdag *h, uint64_t more, const char *what)
{
	struct hd_colours *c = h->col;
	uint64_t now = __atomic_add_fetch(&c->bytes, more, __ATOMIC_RELAXED);
	if (h->o.mem_budget_bytes &&
	    now + h->fixed_bytes + h->committed_bytes > h->o.mem_budget_bytes) {
		__atomic_sub_fetch(&c->bytes, more, __ATOMIC_RELAXED);
		return hd_budget_check(h, more, what);
	}
	return VD_OK;
}

static void seg_free(struct hd_seg *p)
{
	for (uint32_t i = 0; p && i < p->nparts; i++)
		vd_auto_segment_release(&p->part[i]);
	free(p);
}

/* A segment of n voxels with its parts' directories and data still to
 * fill (nothing charged yet). */
static int seg_alloc(uint64_t n, struct hd_seg **out)
{
	uint32_t np = n ? (uint32_t)((n - 1) >> HD_COL_PART_LOG) + 1 : 0;
	struct hd_seg *p = calloc(1, sizeof *p + np * sizeof p->part[0]);
	if (!p)
		return vd_fail(VD_ERR_NOMEM, "colours of %llu voxels",
			       (unsigned long long)n);
	p->refs = 1;
	p->n = n;
	p->nparts = np;
	*out = p;
	return VD_OK;
}

/* Voxels of part i of a segment of n, and of block b of part a. */
static uint32_t part_len(uint64_t n, uint32_t i)
{
	uint64_t at = (uint64_t)i << HD_COL_PART_LOG;
	return (uint32_t)(n - at < (1ull << HD_COL_PART_LOG)
				  ? n - at : 1ull << HD_COL_PART_LOG);
}

static uint32_t block_len(const struct vd_auto_segment *a, uint32_t b)
{
	uint32_t first = b << HD_COL_BLOCK_LOG;
	return a->n - first < (1u << HD_COL_BLOCK_LOG) ? a->n - first
						       : 1u << HD_COL_BLOCK_LOG;
}

/* Finishes a segment made part by part: on success charges its bytes
 * (VD_ERR_BUDGET frees it) and hands it to *out; on `err` frees it. */
static int seg_finish(struct vd_hashdag *h, struct hd_seg *p, int err,
		      struct hd_seg **out)
{
	if (err) {
		seg_free(p);
		return err;
	}
	p->bytes = sizeof *p + p->nparts * sizeof p->part[0];
	for (uint32_t i = 0; i < p->nparts; i++)
		p->bytes += 4ull * p->part[i].count + p->part[i].data_bytes +
			    VD_AUTO_PAD;
	if ((err = col_charge(h, p->bytes, "colours of a segment"))) {
		seg_free(p);
		return err;
	}
	*out = p;
	return VD_OK;
}

/* A segment of n voxels whose parts `fill` makes, one call a part (part
 * i: voxels i << HD_COL_PART_LOG.., part_len(n, i) of them); allocation,
 * the part loop and the budget's count are the same for every kind. */
static int seg_build(struct vd_hashdag *h, uint64_t n,
		     int (*fill)(struct vd_auto_segment *a, uint32_t i,
				 uint64_t n, const uint8_t *rgb),
		     const uint8_t *rgb, struct hd_seg **out)
{
	struct hd_seg *p = NULL;
	int err = seg_alloc(n, &p);
	if (err)
		return err;
	for (uint32_t i = 0; !err && i < p->nparts; i++)
		err = fill(&p->part[i], i, n, rgb);
	return seg_finish(h, p, err, out);
}

/* Part i of rgb[0..n) as lossless auto blocks. The encoder's data buffer
 * has room for raw colours; it is cut to what the blocks hold, as that is
 * the memory the colours are meant to save. */
static int fill_encoded(struct vd_auto_segment *a, uint32_t i, uint64_t n,
			const uint8_t *rgb)
{
	static const struct vd_auto_params lossless = {
		.max_error = 0, .block_log = HD_COL_BLOCK_LOG};
	int err = vd_auto_encode(a, rgb + 3 * ((uint64_t)i << HD_COL_PART_LOG),
				 part_len(n, i), &lossless);
	uint8_t *d = err ? NULL : realloc(a->data, a->data_bytes + VD_AUTO_PAD);
	if (d)
		a->data = d;
	return err;
}

/* Part i of n voxels all of colour rgb[0..3): constant blocks only, no
 * per-voxel work. */
static int fill_constant(struct vd_auto_segment *a, uint32_t i, uint64_t n,
			 const uint8_t *rgb)
{
	uint32_t e = (uint32_t)VD_AUTO_CONST << 24 | (uint32_t)rgb[0] |
		     (uint32_t)rgb[1] << 8 | (uint32_t)rgb[2] << 16;
	a->n = part_len(n, i);
	a->count = (a->n + (1u << HD_COL_BLOCK_LOG) - 1) >> HD_COL_BLOCK_LOG;
	a->dir = malloc(4ull * a->count);
	a->data = calloc(1, VD_AUTO_PAD);
	if (!a->dir || !a->data)
		return vd_fail(VD_ERR_NOMEM, "colours of %llu voxels",
			       (unsigned long long)n);
	for (uint32_t b = 0; b < a->count; b++)
		a->dir[b] = e;
	a->mode_blocks[0] = a->count;
	return VD_OK;
}

/* rgb[0..n) as a segment of lossless auto blocks. */
static int seg_encode(struct vd_hashdag *h, const uint8_t *rgb, uint64_t n,
		      struct hd_seg **out)
{
	return seg_build(h, n, fill_encoded, rgb, out);
}

/* n voxels all of colour rgb. */
static int seg_const(struct vd_hashdag *h, const uint8_t rgb[3], uint64_t n,
		     struct hd_seg **out)
{
	return seg_build(h, n, fill_constant, rgb, out);
}

/* n voxels still in the source: colours at .. at + n - 1 of the cell's
 * array there (only the struct is charged). */
static int seg_source(struct vd_hashdag *h, uint64_t at, uint64_t n,
		      struct hd_seg **out)
{
	struct hd_seg *p = calloc(1, sizeof *p);
	if (!p)
		return vd_fail(VD_ERR_NOMEM, "colour segments");
	p->refs = 1;
	p->n = n;
	p->src_at = at;
	return seg_finish(h, p, VD_OK, out);
}

/* The segment's colours into rgb (3 n bytes), block by block. */
static void seg_decode(const struct hd_seg *p, uint8_t *rgb)
{
	for (uint32_t i = 0; i < p->nparts; i++) {
		const struct vd_auto_segment *a = &p->part[i];
		for (uint32_t b = 0; b < a->count; b++) {
			uint32_t e = a->dir[b], len = block_len(a, b);
			if (e >> 24 == VD_AUTO_CONST) {
				uint8_t c[3] = {(uint8_t)e, (uint8_t)(e >> 8),
						(uint8_t)(e >> 16)};
				for (uint32_t k = 0; k < len; k++, rgb += 3)
					memcpy(rgb, c, 3);
				continue;
			}
			vd_auto_block_decode(e, a->data, len, rgb);
			rgb += 3 * len;
		}
	}
}

static void seg_unref(struct hd_colours *c, struct hd_seg *p)
{
	if (p && __atomic_sub_fetch(&p->refs, 1, __ATOMIC_RELAXED) == 0) {
		__atomic_sub_fetch(&c->bytes, p->bytes, __ATOMIC_RELAXED);
		seg_free(p);
	}
}

static void seg_ref(struct hd_seg *p)
{
	__atomic_add_fetch(&p->refs, 1, __ATOMIC_RELAXED);
}

/* A cell table of room for `nseg` segments (nseg and n left 0). */
static int cell_new(struct vd_hashdag *h, uint64_t nseg,
		    struct hd_cellcol **out)
{
	uint64_t more = sizeof **out + nseg * sizeof (*out)->s[0];
	int err = col_charge(h, more, "colour table of a cell");
	if (err)
		return err;
	struct hd_cellcol *p = malloc(more);
	if (!p) {
		__atomic_sub_fetch(&h->col->bytes, more, __ATOMIC_RELAXED);
		return vd_fail(VD_ERR_NOMEM, "colour table of %llu segments",
			       (unsigned long long)nseg);
	}
	p->refs = 1;
	p->n = 0;
	p->nseg = 0;
	*out = p;
	return VD_OK;
}

/* The table's bytes as charged: its room is its count (tables are made
 * to size, see cell_new's callers). */
void hd_cellcol_unref(struct hd_colours *c, struct hd_cellcol *p)
{
	if (p && __atomic_sub_fetch(&p->refs, 1, __ATOMIC_RELAXED) == 0) {
		for (uint64_t i = 0; i < p->nseg; i++)
			seg_unref(c, p->s[i].seg);
		__atomic_sub_fetch(&c->bytes,
				   sizeof *p + p->nseg * sizeof p->s[0],
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
	free(c->cell_first);
	if (c->pack.release)
		vd_colour_source_release(&c->pack);
	free(c);
}

/* The segment of `code` (level S) in cell table t, or NULL. */
static struct hd_seg *seg_find(const struct hd_cellcol *t, uint64_t code)
{
	if (!t)
		return NULL;
	uint64_t lo = 0, hi = t->nseg;
	while (lo < hi) {
		uint64_t mid = (lo + hi) / 2;
		if (t->s[mid].code < code)
			lo = mid + 1;
		else
			hi = mid;
	}
	return lo < t->nseg && t->s[lo].code == code ? t->s[lo].seg : NULL;
}

/* ------------------------------------------------ reading the source */

/* Reads segments still in the source, one cell's colours held at a time:
 * a colour chunk is decompressed whole, so its segments are best read
 * together, in cell order. */
struct srcread {
	const struct hd_colours *c;
	uint64_t ci;              /* the cell in rgb, UINT64_MAX: none */
	uint8_t *rgb;
	uint64_t n;
};

static void sr_init(struct srcread *r, const struct hd_colours *c)
{
	r->c = c;
	r->ci = UINT64_MAX;
	r->rgb = NULL;
	r->n = 0;
}

static void sr_release(struct srcread *r)
{
	free(r->rgb);
	sr_init(r, r->c);
}

/* Colours at .. at + n - 1 of cell ci's array in the source into out. */
static int sr_get(struct srcread *r, uint64_t ci, uint64_t at, uint64_t n,
		  uint8_t *out)
{
	const struct hd_colours *c = r->c;
	uint64_t want = c->input[ci] ? c->input[ci]->n : 0;
	if (!c->src_dir) {
		/* in batches: a packed file's run of voxels then decodes each
		 * coded block once, not from a restart point for every voxel
		 * (vd_cpack_colour_many) */
		const struct vd_colour_source *s = &c->pack;
		uint64_t idx[1024];
		for (uint64_t k = 0; k < n; k += 1024) {
			size_t m = n - k < 1024 ? (size_t)(n - k) : 1024;
			for (size_t q = 0; q < m; q++)
				idx[q] = c->cell_first[ci] + at + k + q;
			vd_colour_source_get_many(s, idx, m, out + 3 * k);
		}
		return VD_OK;
	}
	if (r->ci != ci) {
		sr_release(r);
		char name[64], path[4096];
		vd_chunk_file_name(name, sizeof name, c->C, ci, "col");
		if (snprintf(path, sizeof path, "%s/%s", c->src_dir, name) >=
		    (int)sizeof path)
			return vd_fail(VD_ERR_ARG, "directory name too long");
		/* the bricks beside the colours must be the ones coloured:
		 * checked from the chunk's digest and count before its colours
		 * are decompressed, so the cell's bricks and its colours are
		 * never held together */
		struct vd_chunk *ch = NULL;
		struct vd_colours col = {0};
		struct vd_chunk_header hd, sh;
		struct vd_svo svo;
		void *dig = NULL;
		size_t dsize = 0;
		int err = vd_chunk_open(&ch, path, VD_KIND_COLOURS);
		if (!err) {
			hd = *vd_chunk_header(ch);
			col.voxels = hd.level_count ?
				     hd.level_nodes[hd.level_count - 1] : 0;
			err = vd_chunk_read_section(ch, VD_TAG_BDIG, &dig, &dsize);
		}
		if (!err && dsize != 8)
			err = vd_fail(VD_ERR_CORRUPT, "brick digest of %zu bytes",
				      dsize);
		for (int k = 7; !err && k >= 0; k--)
			col.svo_digest = col.svo_digest << 8 |
					 ((const uint8_t *)dig)[k];
		free(dig);
		size_t len = strlen(path);
		memcpy(path + len - 3, "svo", 3);
		if (!err && !(err = vd_svo_load(&svo, &sh, path))) {
			err = vd_colours_match(&hd, &col, &sh, &svo);
			vd_svo_release(&svo);
		}
		memcpy(path + len - 3, "col", 3);
		if (!err && (hd.cell_morton != ci ||
			     hd.chunk_level != (uint32_t)c->C || col.voxels != want))
			err = vd_fail(VD_ERR_MISMATCH, "not the colours loaded "
				      "(%llu colours, %llu when loaded): was "
				      "it replaced?",
				      (unsigned long long)col.voxels,
				      (unsigned long long)want);
		if (!err)
			err = vd_colours_from_chunk(&col, ch);
		vd_chunk_free(ch);
		if (err)
			return vd_fail(err, "'%s': %s", path, vd_error_detail());
		r->ci = ci;
		r->rgb = col.rgb;
		r->n = col.voxels;
	}
	if (at > r->n || n > r->n - at)
		return vd_fail(VD_ERR_INTERNAL, "colours %llu..+%llu of a cell "
			       "of %llu", (unsigned long long)at,
			       (unsigned long long)n, (unsigned long long)r->n);
	memcpy(out, r->rgb + 3 * at, 3 * n);
	return VD_OK;
}

/* Segment p of `code` (level S) into rgb (3 p->n bytes), wherever it is. */
static int seg_read(struct srcread *r, uint64_t code, const struct hd_seg *p,
		    uint8_t *rgb)
{
	if (p->nparts) {
		seg_decode(p, rgb);
		return VD_OK;
	}
	return sr_get(r, code >> 3 * (r->c->S - r->c->C), p->src_at, p->n, rgb);
}

/* The cell's colours end to end into rgb (3 n bytes). */
static int cell_gather(struct srcread *r, const struct hd_cellcol *t,
		       uint8_t *rgb)
{
	for (uint64_t i = 0; i < t->nseg; i++) {
		int err = seg_read(r, t->s[i].code, t->s[i].seg, rgb);
		if (err)
			return err;
		rgb += 3 * t->s[i].seg->n;
	}
	return VD_OK;
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

/* Nodes of the segment level S: code (Morton at level S) and the node in
 * the scene before (p) and after (q) an edit. */
struct plist {
	uint64_t *code;
	uint32_t *p, *q;
	uint64_t n, cap;
};

static void pl_free(struct plist *v)
{
	free(v->code);
	free(v->p);
	free(v->q);
	memset(v, 0, sizeof *v);
}

static int pl_push(struct plist *v, uint64_t code, uint32_t p, uint32_t q)
{
	if (v->n == v->cap) {
		uint64_t cap = v->cap ? 2 * v->cap : 64;
		uint64_t *c = realloc(v->code, cap * sizeof *c);
		if (c)
			v->code = c;
		uint32_t *a = c ? realloc(v->p, cap * sizeof *a) : NULL;
		if (a)
			v->p = a;
		uint32_t *b = a ? realloc(v->q, cap * sizeof *b) : NULL;
		if (!b)
			return vd_fail(VD_ERR_NOMEM, "segment list");
		v->q = b;
		v->cap = cap;
	}
	v->code[v->n] = code;
	v->p[v->n] = p;
	v->q[v->n++] = q;
	return VD_OK;
}

/* The nodes of level S under the nodes p (before) and q (after) of level
 * l at (x, y, z) whose cube meets the box lo..hi and which are non-empty
 * in either scene; with `changed` only those where p != q. In Morton
 * order. */
static int segs_in(const struct vd_hashdag *h, int l, uint32_t p, uint32_t q,
		   const int64_t *xyz, uint64_t code, const int64_t *lo,
		   const int64_t *hi, int changed, struct plist *out)
{
	if ((p == HD_EMPTY && q == HD_EMPTY) || (changed && p == q))
		return VD_OK;
	int64_t s = (int64_t)1 << (h->levels - l);
	for (int a = 0; a < 3; a++)
		if (xyz[a] + s - 1 < lo[a] || xyz[a] > hi[a])
			return VD_OK;
	if (l == h->col->S)
		return pl_push(out, code, p, q);
	int64_t hs = s / 2;
	for (int c = 0; c < 8; c++) {
		int64_t cx[3] = {xyz[0] + (c >> 2 & 1) * hs,
				 xyz[1] + (c >> 1 & 1) * hs, xyz[2] + (c & 1) * hs};
		int err = segs_in(h, l + 1, hd_child(h, l, p, c),
				  hd_child(h, l, q, c), cx, code << 3 | (uint64_t)c,
				  lo, hi, changed, out);
		if (err)
			return err;
	}
	return VD_OK;
}

/* ----------------------------------------------------------- loading */

/* The chunk level and the number of the colour chunks in `dir`. */
static int dir_cells(const char *dir, int *C, uint64_t *count)
{
	DIR *d = opendir(dir);
	if (!d)
		return vd_fail(VD_ERR_IO, "cannot open '%s': %s", dir,
			       strerror(errno));
	struct dirent *e;
	char path[4096];
	int err = VD_OK;
	*count = 0;
	*C = -1;
	while (!err && (e = readdir(d))) {
		size_t len = strlen(e->d_name);
		if (len < 5 || strcmp(e->d_name + len - 4, ".col"))
			continue;
		if (++*count > 1)
			continue;
		struct vd_chunk_header hd;
		if (join(path, sizeof path, dir, e->d_name))
			err = vd_fail(VD_ERR_ARG, "directory name too long");
		else if ((err = vd_chunk_read_header(path, &hd)))
			err = vd_fail(err, "'%s': %s", path, vd_error_detail());
		else
			*C = (int)hd.chunk_level;
	}
	closedir(d);
	if (!err && !*count)
		err = vd_fail(VD_ERR_EMPTY, "no colour chunks (*.col) in '%s': "
			      "was the mesh voxelized with colours?", dir);
	return err;
}

/* Voxels below the nodes of levels S .. L-3, memoized per node (a hash
 * per level): the segments' counts at load visit each distinct node of
 * the DAG once rather than every brick of the scene. */
struct vmemo {
	uint32_t *key;            /* node + 1, 0: free */
	uint64_t *val;
	uint64_t cap, used;
};

static uint64_t memo_slot(uint32_t key, uint64_t cap)
{
	return (key * 0x9e3779b97f4a7c15ull >> 29) & (cap - 1);
}

static uint64_t memo_voxels(const struct vd_hashdag *h, struct vmemo *m,
			    int l, uint32_t p, int *err)
{
	if (p == HD_EMPTY || *err)
		return 0;
	if (p == h->lv[l].full)
		return 1ull << 3 * (h->levels - l);
	if (l == h->levels - 2)
		return (uint64_t)__builtin_popcountll(hd_brick(h, p));
	struct vmemo *t = &m[l];
	if (2 * (t->used + 1) > t->cap) {
		uint64_t cap = t->cap ? 2 * t->cap : 1024;
		uint32_t *k = calloc(cap, sizeof *k);
		uint64_t *v = malloc(cap * sizeof *v);
		if (!k || !v) {
			free(k);
			free(v);
			*err = vd_fail(VD_ERR_NOMEM, "voxel counts");
			return 0;
		}
		for (uint64_t i = 0; i < t->cap; i++) {
			if (!t->key[i])
				continue;
			uint64_t j = memo_slot(t->key[i], cap);
			while (k[j])
				j = (j + 1) & (cap - 1);
			k[j] = t->key[i];
			v[j] = t->val[i];
		}
		free(t->key);
		free(t->val);
		t->key = k;
		t->val = v;
		t->cap = cap;
	}
	uint64_t j = memo_slot(p + 1, t->cap);
	while (t->key[j] && t->key[j] != p + 1)
		j = (j + 1) & (t->cap - 1);
	if (t->key[j])
		return t->val[j];
	uint64_t n = 0;
	for (int c = 0; c < 8; c++)
		n += memo_voxels(h, m, l + 1, hd_child(h, l, p, c), err);
	/* slot j still holds: the children are on deeper levels, whose
	 * tables are others */
	t->key[j] = p + 1;
	t->val[j] = n;
	t->used++;
	return n;
}

/* Cell ci's colour chunk in the source directory is whole (its
 * checksums) and belongs to the scene: its depth, cell and grid, and `n`
 * colours, the scene's voxels in the cell. Its colours stay compressed
 * on disk until an edit needs them; then they are checked against the
 * bricks of the SVO chunk beside them (sr_get), as a load checked them
 * before. `first` is the first cell's header (set when *have_first is
 * 0). */
static int check_chunk(const struct vd_hashdag *h, uint64_t ci, uint64_t n,
		       struct vd_chunk_header *first, int *have_first)
{
	const struct hd_colours *c = h->col;
	char name[64], path[4096];
	vd_chunk_file_name(name, sizeof name, c->C, ci, "col");
	if (join(path, sizeof path, c->src_dir, name))
		return vd_fail(VD_ERR_ARG, "directory name too long");
	struct vd_chunk *ch;
	int err = vd_chunk_open(&ch, path, VD_KIND_COLOURS);
	if (err)
		return vd_fail(err, "'%s': %s", path, vd_error_detail());
	const struct vd_chunk_header *hd = vd_chunk_header(ch);
	uint64_t cn = hd->level_count ? hd->level_nodes[hd->level_count - 1] : 0;
	if (hd->levels != (uint32_t)h->levels || hd->cell_morton != ci)
		err = vd_fail(VD_ERR_MISMATCH, "colours of a cell of another "
			      "grid or place");
	else if (cn != n)
		err = vd_fail(VD_ERR_MISMATCH, "%llu colours for the scene's "
			      "%llu voxels of the cell", (unsigned long long)cn,
			      (unsigned long long)n);
	else if (*have_first && !vd_transform_equal(&hd->transform,
						    &first->transform))
		err = vd_fail(VD_ERR_MISMATCH, "placed in another grid than "
			      "the other cells");
	if (!err && !*have_first) {
		*first = *hd;
		*have_first = 1;
	}
	vd_chunk_free(ch);
	if (err)
		return vd_fail(err, "'%s': %s", path, vd_error_detail());
	return VD_OK;
}

int vd_hashdag_colours_open(struct vd_hashdag *h, const char *src,
			    const uint8_t *fill_rgb)
{
	static const uint8_t grey[3] = VD_EDIT_DEFAULT_RGB;
	if (h->col)
		return vd_fail(VD_ERR_ARG, "the scene has colours already");
	if (h->nroots != 1)
		return vd_fail(VD_ERR_ARG, "colours are opened before any edit");
	int L = h->levels;
	struct stat st;
	if (stat(src, &st) != 0)
		return vd_fail(VD_ERR_IO, "cannot open '%s': %s", src,
			       strerror(errno));
	struct hd_colours *c = calloc(1, sizeof *c);
	if (!c)
		return vd_fail(VD_ERR_NOMEM, "colours");
	c->tab_free = hd_coltab_free;
	c->free = hd_colours_free;
	memcpy(c->fill_rgb, fill_rgb ? fill_rgb : grey, 3);
	/* a directory's chunks are read when needed; a packed file stays
	 * open (in memory, compressed) for the structure's life */
	int err = VD_OK, C = -1, levels = L;
	uint64_t nfiles = 0, src_voxels = 0;
	if (S_ISDIR(st.st_mode)) {
		if (!(c->src_dir = strdup(src)))
			err = vd_fail(VD_ERR_NOMEM, "colours");
		else
			err = dir_cells(src, &C, &nfiles);
	} else if (!(err = vd_colour_source_open(&c->pack, src))) {
		C = c->pack.cell_level;
		levels = c->pack.levels;
		src_voxels = c->pack.voxels;
	}
	if (err) {
		hd_colours_free(c);
		return err;
	}
	if (levels != L) {
		hd_colours_free(c);
		return vd_fail(VD_ERR_MISMATCH, "'%s' colours a 2^%d grid, the "
			       "scene is 2^%d", src, levels, L);
	}
	if (c->src_dir && (C < 0 || C > L - 2)) {
		hd_colours_free(c);
		return vd_fail(VD_ERR_MISMATCH, "'%s' has cells of level %d in "
			       "a 2^%d grid", src, C, L);
	}
	c->C = C >= 0 && C <= L - 2 ? C : (L - 2 < 3 ? L - 2 : 3);
	c->ncells = 1ull << 3 * c->C;
	c->tab = calloc(h->cap_roots ? h->cap_roots : 1, sizeof *c->tab);
	struct hd_cellcol **tab = calloc(c->ncells, sizeof *tab);
	c->input = calloc(c->ncells, sizeof *tab);
	if (!c->src_dir)
		c->cell_first = calloc(c->ncells, sizeof *c->cell_first);
	if (!c->tab || !tab || !c->input || (!c->src_dir && !c->cell_first))
		err = vd_fail(VD_ERR_NOMEM, "colour tables");
	h->col = c;
	int sl = h->o.colour_segment_log2 ? h->o.colour_segment_log2 : 6;
	c->S = L - sl;
	if (c->S > L - 2)
		c->S = L - 2;
	if (c->S < c->C)
		c->S = c->C;
	uint64_t at = 0, ncells = 0;
	uint32_t root = h->roots[h->cur];
	const int64_t all_lo[3] = {0, 0, 0};
	const int64_t all_hi[3] = {INT64_MAX, INT64_MAX, INT64_MAX};
	struct plist segs = {0};
	struct vd_chunk_header first;
	int have_first = 0;
	struct vmemo memo[VD_MAX_LEVELS] = {{0}};
	for (uint64_t ci = 0; ci < c->ncells && !err; ci++) {
		uint32_t p = cell_ptr(h, root, ci);
		if (p == HD_EMPTY)
			continue;
		uint32_t cx, cy, cz;
		cell_corner(h, ci, &cx, &cy, &cz);
		int64_t xyz[3] = {cx, cy, cz};
		segs.n = 0;
		if ((err = segs_in(h, c->C, p, HD_EMPTY, xyz, ci, all_lo, all_hi,
				   0, &segs)) ||
		    (err = cell_new(h, segs.n, &tab[ci])))
			break;
		struct hd_cellcol *t = tab[ci];
		for (uint64_t i = 0; i < segs.n && !err; i++) {
			uint64_t n = memo_voxels(h, memo, c->S, segs.p[i], &err);
			t->s[t->nseg].code = segs.code[i];
			err = seg_source(h, t->n, n, &t->s[t->nseg].seg);
			if (!err)
				t->nseg++;
			t->n += n;
		}
		if (err)
			break;
		ncells++;
		if (c->cell_first)
			c->cell_first[ci] = at;
		at += t->n;
		if (!c->src_dir && at > src_voxels)
			err = vd_fail(VD_ERR_MISMATCH, "'%s' has %llu colours, "
				      "fewer than the scene's voxels", src,
				      (unsigned long long)src_voxels);
		if (!err && c->src_dir)
			err = check_chunk(h, ci, t->n, &first, &have_first);
		if (err)
			break;
		t->refs++;
		c->input[ci] = t;
	}
	pl_free(&segs);
	for (int l = 0; l < VD_MAX_LEVELS; l++) {
		free(memo[l].key);
		free(memo[l].val);
	}
	if (!err && !c->src_dir && at != src_voxels)
		err = vd_fail(VD_ERR_MISMATCH, "'%s' has %llu colours for a "
			      "scene of %llu voxels", src,
			      (unsigned long long)src_voxels,
			      (unsigned long long)at);
	if (!err && c->src_dir && nfiles != ncells)
		err = vd_fail(VD_ERR_MISMATCH, "'%s' has colours of %llu cells, "
			      "the scene %llu non-empty cells", src,
			      (unsigned long long)nfiles,
			      (unsigned long long)ncells);
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
	struct srcread r;
	sr_init(&r, h->col);
	int err = VD_OK;
	for (uint64_t ci = 0; ci < h->col->ncells && !err; ci++)
		if (tab[ci]) {
			err = cell_gather(&r, tab[ci], a + 3 * n);
			n += tab[ci]->n;
		}
	sr_release(&r);
	if (err) {
		free(a);
		return err;
	}
	*rgb = a;
	*voxels = n;
	return VD_OK;
}

int vd_hashdag_colour_stats(const struct vd_hashdag *h,
			    struct vd_hashdag_colour_stats *st)
{
	memset(st, 0, sizeof *st);
	if (!h->col)
		return vd_fail(VD_ERR_UNSUPPORTED, "the scene has no colours");
	struct hd_cellcol **tab = h->col->tab[h->cur];
	for (uint64_t ci = 0; ci < h->col->ncells; ci++)
		for (uint64_t i = 0; tab[ci] && i < tab[ci]->nseg; i++) {
			const struct hd_seg *g = tab[ci]->s[i].seg;
			st->voxels += g->n;
			st->segments++;
			st->bytes += g->bytes;
			st->source_voxels += g->nparts ? 0 : g->n;
			for (uint32_t k = 0; k < g->nparts; k++)
				for (int m = 0; m < 5; m++)
					st->mode_blocks[m] +=
						g->part[k].mode_blocks[m];
		}
	return VD_OK;
}

/* ----------------------------------------------------------- editing */

/* A copy's source segments, decoded in the scene before the edit. */
struct srcseg {
	uint64_t code;
	uint32_t p;               /* its node before the edit */
	const struct hd_seg *col;
	/* read for the batch of jobs that needs it (need), then dropped: a
	 * large copy holds the sources of a batch, not all of them */
	int need, loaded;
	struct vlist v;
	uint8_t *rgb;
};

/* One segment to rebuild. */
struct sjob {
	uint64_t code;
	uint32_t op, np;          /* its node before and after the edit */
	size_t cell;              /* index in the list of cells */
	struct hd_seg *old, *out; /* out NULL: empty after the edit */
	uint8_t *old_rgb;         /* old's colours when it is in the source,
				   * read before the jobs run */
	uint64_t changed;
	int err;
	char detail[240];
};

struct cctx {
	struct vd_hashdag *h;
	const struct vd_edit_op *op;
	struct srcseg *src;
	size_t nsrc;
	struct sjob *jobs;
	size_t base;              /* of the batch of jobs running */
};

static int src_colour(const struct cctx *x, uint64_t m, uint8_t rgb[3])
{
	const struct vd_hashdag *h = x->h;
	uint64_t code = m >> 3 * (h->levels - h->col->S);
	size_t lo = 0, hi = x->nsrc;
	while (lo < hi) {
		size_t mid = (lo + hi) / 2;
		if (x->src[mid].code < code)
			lo = mid + 1;
		else
			hi = mid;
	}
	if (lo == x->nsrc || x->src[lo].code != code || !x->src[lo].col ||
	    !x->src[lo].loaded)
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
	memcpy(rgb, x->src[lo].rgb + 3 * a, 3);
	return 1;
}

/* Marks the source segments the copy reads for destination segment
 * `code` (its cube moved back by the copy's offset, within the copied
 * box: at most 8 segments). Returns the bytes of the newly marked ones
 * not read yet. */
static uint64_t mark_sources(struct cctx *x, uint64_t code)
{
	const struct vd_hashdag *h = x->h;
	const struct vd_edit_op *op = x->op;
	int sh = h->levels - h->col->S;
	uint32_t xyz[3];
	vd_morton3_decode(code, &xyz[0], &xyz[1], &xyz[2]);
	int64_t a[3], b[3];
	for (int k = 0; k < 3; k++) {
		int64_t d = op->dst[k] - op->lo[k];
		int64_t lo = ((int64_t)xyz[k] << sh) - d;
		int64_t hi = lo + (1ll << sh) - 1;
		lo = lo < op->lo[k] ? op->lo[k] : lo;
		hi = hi > op->hi[k] ? op->hi[k] : hi;
		if (lo > hi)
			return 0;
		a[k] = lo >> sh;
		b[k] = hi >> sh;
	}
	uint64_t bytes = 0;
	for (int64_t i = a[0]; i <= b[0]; i++)
		for (int64_t j = a[1]; j <= b[1]; j++)
			for (int64_t k = a[2]; k <= b[2]; k++) {
				uint64_t c = vd_morton3((uint32_t)i, (uint32_t)j,
							(uint32_t)k);
				size_t lo = 0, hi = x->nsrc;
				while (lo < hi) {
					size_t mid = (lo + hi) / 2;
					if (x->src[mid].code < c)
						lo = mid + 1;
					else
						hi = mid;
				}
				struct srcseg *g = &x->src[lo];
				if (lo == x->nsrc || g->code != c || g->need)
					continue;
				g->need = 1;
				if (!g->loaded && g->col)
					bytes += 11 * g->col->n;
			}
	return bytes;
}

/* Reads a source segment the batch needs (its voxels and colours), or
 * drops one it does not. */
static int src_load(struct cctx *x, struct srcread *r, struct srcseg *g)
{
	if (!g->need || !g->col) {
		if (g->loaded) {
			vl_free(&g->v);
			free(g->rgb);
			g->rgb = NULL;
			g->loaded = 0;
		}
		return VD_OK;
	}
	if (g->loaded)
		return VD_OK;
	int err = walk(x->h, x->h->col->S, g->p, g->code, &g->v);
	if (!err && !(g->rgb = malloc(3 * g->col->n)))
		err = vd_fail(VD_ERR_NOMEM, "copy sources");
	if (!err)
		err = seg_read(r, g->code, g->col, g->rgb);
	g->loaded = !err;
	return err;
}

/* 1 when op is a box whose region holds segment `code`'s whole cube. */
static int cube_in_box(const struct vd_hashdag *h, const struct vd_edit_op *op,
		       uint64_t code)
{
	if (op->shape != VD_SHAPE_BOX || op->kind == VD_EDIT_COPY)
		return 0;
	int sh = h->levels - h->col->S;
	uint32_t xyz[3];
	vd_morton3_decode(code, &xyz[0], &xyz[1], &xyz[2]);
	for (int a = 0; a < 3; a++) {
		int64_t lo = (int64_t)xyz[a] << sh, hi = lo + (1ll << sh) - 1;
		if (lo < op->lo[a] || hi > op->hi[a])
			return 0;
	}
	return 1;
}

/* The one colour every voxel of the segment after the edit takes, so
 * that it is constant blocks without a walk of its voxels, or NULL: a
 * box fill with a colour or a box paint whose region holds the segment's
 * whole cube (a fill sets every voxel of it, a paint colours every voxel
 * it has), or any fill of a segment that was empty (every voxel it has
 * now is the fill's: its colour, or the fill colour). */
static const uint8_t *seg_uniform(const struct vd_hashdag *h,
				  const struct vd_edit_op *op,
				  const struct sjob *jb)
{
	if (op->kind == VD_EDIT_FILL && jb->op == HD_EMPTY)
		return op->has_rgb ? op->rgb : h->col->fill_rgb;
	if ((op->kind == VD_EDIT_PAINT ||
	     (op->kind == VD_EDIT_FILL && op->has_rgb)) &&
	    cube_in_box(h, op, jb->code))
		return op->rgb;
	return NULL;
}

/* A box fill without a colour over the segment's whole cube: every voxel
 * of the cube is set, the old ones keep their colours, the others take
 * the fill colour. In Morton order the cube's voxels are its indices, so
 * the old colours are put in place without a walk of the new voxels. */
static int rebuild_full(struct cctx *x, struct sjob *jb)
{
	struct vd_hashdag *h = x->h;
	struct hd_seg *old = jb->old;
	int sh = 3 * (h->levels - h->col->S);
	uint64_t n = 1ull << sh, base = jb->code << sh;
	if (old && old->n == n) { /* full before: nothing changes */
		seg_ref(old);
		jb->out = old;
		return VD_OK;
	}
	struct vlist ov = {0};
	int err = walk(h, h->col->S, jb->op, jb->code, &ov);
	if (!err && ov.n != old->n)
		err = vd_fail(VD_ERR_INTERNAL, "segment %llx: %llu voxels, %llu "
			      "colours", (unsigned long long)jb->code,
			      (unsigned long long)ov.n,
			      (unsigned long long)old->n);
	uint8_t *was = NULL, *rgb = NULL;
	if (!err) {
		was = jb->old_rgb ? jb->old_rgb : malloc(3 * ov.n + 1);
		rgb = malloc(3 * n);
		if (!was || !rgb)
			err = vd_fail(VD_ERR_NOMEM, "colours of a segment");
		else if (!jb->old_rgb)
			seg_decode(old, was);
	}
	if (!err) {
		const uint8_t *f = h->col->fill_rgb;
		for (uint64_t i = 0; i < n; i++)
			memcpy(rgb + 3 * i, f, 3);
		for (uint64_t j = 0; j < ov.n; j++)
			memcpy(rgb + 3 * (ov.m[j] - base), was + 3 * j, 3);
		err = seg_encode(h, rgb, n, &jb->out);
	}
	vl_free(&ov);
	if (was != jb->old_rgb)
		free(was);
	free(rgb);
	return err;
}

/* Voxels of `old` whose colour is not rgb: whole constant blocks at once,
 * the others decoded (old_rgb: old's colours when it is in the source). */
static uint64_t seg_count_not(const struct hd_seg *old, const uint8_t *old_rgb,
			      const uint8_t rgb[3])
{
	uint64_t ch = 0;
	if (old && !old->nparts) {
		for (uint64_t k = 0; k < old->n; k++)
			ch += memcmp(old_rgb + 3 * k, rgb, 3) != 0;
		return ch;
	}
	uint32_t want = (uint32_t)rgb[0] | (uint32_t)rgb[1] << 8 |
			(uint32_t)rgb[2] << 16;
	for (uint32_t i = 0; old && i < old->nparts; i++) {
		const struct vd_auto_segment *a = &old->part[i];
		for (uint32_t b = 0; b < a->count; b++) {
			uint32_t e = a->dir[b], len = block_len(a, b);
			if (e >> 24 == VD_AUTO_CONST) {
				ch += (e & 0xffffff) != want ? len : 0;
				continue;
			}
			uint8_t c[3 << HD_COL_BLOCK_LOG];
			vd_auto_block_decode(e, a->data, len, c);
			for (uint32_t k = 0; k < len; k++)
				ch += memcmp(c + 3 * k, rgb, 3) != 0;
		}
	}
	return ch;
}

/* The colours of one segment after the edit, from its voxels before and
 * after (the same rules as a whole cell: see vd_hashdag_apply). The old
 * blocks are decoded, the new colours made raw and encoded again; a
 * uniform fill or paint of the whole segment writes constant blocks. */
static int rebuild(struct cctx *x, struct sjob *jb)
{
	struct vd_hashdag *h = x->h;
	const struct vd_edit_op *op = x->op;
	struct hd_seg *old = jb->old;
	jb->out = NULL;
	jb->changed = 0;
	if (jb->np == HD_EMPTY)
		return VD_OK;
	const uint8_t *u = seg_uniform(h, op, jb);
	if (u) {
		uint64_t n = hd_voxels_of(h, h->col->S, jb->np);
		uint64_t ch = seg_count_not(old, jb->old_rgb, u);
		/* a full cube before and after, all of one colour already */
		if (old && old->n == n && !ch) {
			seg_ref(old);
			jb->out = old;
			return VD_OK;
		}
		jb->changed = ch;
		return seg_const(h, u, n, &jb->out);
	}
	if (op->kind == VD_EDIT_FILL && cube_in_box(h, op, jb->code))
		return rebuild_full(x, jb);
	struct vlist ov = {0}, nv = {0};
	int err = walk(h, h->col->S, jb->op, jb->code, &ov);
	if (!err)
		err = walk(h, h->col->S, jb->np, jb->code, &nv);
	if (!err && ov.n != (old ? old->n : 0))
		err = vd_fail(VD_ERR_INTERNAL, "segment %llx: %llu voxels, %llu "
			      "colours", (unsigned long long)jb->code,
			      (unsigned long long)ov.n,
			      (unsigned long long)(old ? old->n : 0));
	uint8_t *was_rgb = NULL, *rgb = NULL;
	if (!err) {
		was_rgb = jb->old_rgb ? jb->old_rgb : malloc(3 * ov.n + 1);
		rgb = malloc(3 * nv.n + 1);
		if (!was_rgb || !rgb)
			err = vd_fail(VD_ERR_NOMEM, "colours of a segment");
		else if (old && !jb->old_rgb)
			seg_decode(old, was_rgb);
	}
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
		const uint8_t *was = had ? was_rgb + 3 * j : NULL;
		uint8_t *to = rgb + 3 * i;
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
	/* an unchanged segment (voxels and colours) keeps being shared */
	int same = !err && old && ov.n == nv.n &&
		   !memcmp(ov.m, nv.m, 8 * nv.n) &&
		   !memcmp(was_rgb, rgb, 3 * nv.n);
	struct hd_seg *c = NULL;
	if (!err && same) {
		c = old;
		seg_ref(c);
	} else if (!err) {
		err = seg_encode(h, rgb, nv.n, &c);
	}
	vl_free(&ov);
	vl_free(&nv);
	if (was_rgb != jb->old_rgb)
		free(was_rgb);
	free(rgb);
	if (err)
		return err;
	jb->out = c;
	jb->changed = ch;
	return VD_OK;
}

static void run_sjob(void *ctx, size_t i, int worker)
{
	(void)worker;
	struct cctx *x = ctx;
	struct sjob *j = &x->jobs[x->base + i];
	j->err = rebuild(x, j);
	if (j->err)
		snprintf(j->detail, sizeof j->detail, "%s", vd_error_detail());
}

/* The table of cell `old` with the segments jobs[0..n) (increasing codes)
 * rebuilt: *out is `old` itself (one more reference) when none changed,
 * NULL when the cell is empty now. */
static int cell_merge(struct vd_hashdag *h, struct hd_cellcol *old,
		      struct sjob *jobs, size_t n, struct hd_cellcol **out)
{
	int same = 1;
	uint64_t oi = 0, nseg = old ? old->nseg : 0;
	for (size_t i = 0; i < n; i++) {
		if (jobs[i].out != jobs[i].old)
			same = 0;
		nseg += (jobs[i].out != NULL) - (jobs[i].old != NULL);
	}
	*out = NULL;
	if (same) {
		if (old)
			__atomic_add_fetch(&old->refs, 1, __ATOMIC_RELAXED);
		*out = old;
		return VD_OK;
	}
	if (!nseg)
		return VD_OK;
	struct hd_cellcol *t;
	int err = cell_new(h, nseg, &t);
	if (err)
		return err;
	for (size_t i = 0; i <= n; i++) {
		uint64_t end = i < n ? jobs[i].code : UINT64_MAX;
		for (; old && oi < old->nseg && old->s[oi].code < end; oi++) {
			t->s[t->nseg++] = old->s[oi];
			seg_ref(old->s[oi].seg);
			t->n += old->s[oi].seg->n;
		}
		if (i == n)
			break;
		if (old && oi < old->nseg && old->s[oi].code == end)
			oi++; /* replaced */
		if (jobs[i].out) {
			t->s[t->nseg].code = jobs[i].code;
			t->s[t->nseg++].seg = jobs[i].out;
			seg_ref(jobs[i].out);
			t->n += jobs[i].out->n;
		}
	}
	*out = t;
	return VD_OK;
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
	struct hd_cellcol **old = c->tab[h->cur];
	struct cctx x = {.h = h, .op = op};
	struct srcread r;
	sr_init(&r, c);
	int64_t lo[3], hi[3];
	uint64_t *cells = NULL, *scells = NULL;
	size_t n = 0, ns = 0;
	struct plist segs = {0};
	*changed_colours = 0;
	struct hd_cellcol **tab = malloc(c->ncells * sizeof *tab);
	if (!tab)
		return vd_fail(VD_ERR_NOMEM, "colour table");
	memcpy(tab, old, c->ncells * sizeof *tab);
	op_bbox(h, op, lo, hi);
	int err = cells_of(h, lo, hi, &cells, &n);
	/* a fill without a colour or a carve changes the colours of the
	 * segments whose voxels it changes only */
	int geometry_only = (op->kind == VD_EDIT_FILL && !op->has_rgb) ||
			    op->kind == VD_EDIT_CARVE;
	size_t k = 0;
	for (size_t i = 0; i < n && !err; i++)
		if (!geometry_only || cell_ptr(h, old_root, cells[i]) !=
					      cell_ptr(h, new_root, cells[i]))
			cells[k++] = cells[i];
	n = k;
	*cells_rebuilt = n;
	/* the segments of those cells the region meets, in order */
	size_t *first = err ? NULL : malloc((n + 1) * sizeof *first);
	if (!err && !first)
		err = vd_fail(VD_ERR_NOMEM, "segment list");
	for (size_t i = 0; i < n && !err; i++) {
		uint32_t cx, cy, cz;
		cell_corner(h, cells[i], &cx, &cy, &cz);
		int64_t xyz[3] = {cx, cy, cz};
		first[i] = segs.n;
		err = segs_in(h, c->C, cell_ptr(h, old_root, cells[i]),
			      cell_ptr(h, new_root, cells[i]), xyz, cells[i],
			      lo, hi, geometry_only, &segs);
	}
	if (first)
		first[n] = segs.n;
	if (!err && op->kind == VD_EDIT_COPY && segs.n) {
		struct plist ss = {0};
		err = cells_of(h, op->lo, op->hi, &scells, &ns);
		for (size_t i = 0; i < ns && !err; i++) {
			uint32_t cx, cy, cz;
			cell_corner(h, scells[i], &cx, &cy, &cz);
			int64_t xyz[3] = {cx, cy, cz};
			uint32_t p = cell_ptr(h, old_root, scells[i]);
			err = segs_in(h, c->C, p, p, xyz, scells[i], op->lo,
				      op->hi, 0, &ss);
		}
		x.src = err ? NULL : calloc(ss.n ? ss.n : 1, sizeof *x.src);
		if (!err && !x.src)
			err = vd_fail(VD_ERR_NOMEM, "copy sources");
		for (uint64_t i = 0; i < ss.n && !err; i++) {
			uint64_t cell = ss.code[i] >> 3 * (c->S - c->C);
			x.src[x.nsrc].code = ss.code[i];
			x.src[x.nsrc].p = ss.p[i];
			x.src[x.nsrc++].col = seg_find(old[cell], ss.code[i]);
		}
		pl_free(&ss);
	}
	x.jobs = err ? NULL : calloc(segs.n ? segs.n : 1, sizeof *x.jobs);
	if (!err && !x.jobs)
		err = vd_fail(VD_ERR_NOMEM, "colour jobs");
	for (size_t i = 0; i < n && !err; i++)
		for (size_t s = first[i]; s < first[i + 1]; s++) {
			struct sjob *j = &x.jobs[s];
			j->code = segs.code[s];
			j->op = segs.p[s];
			j->np = segs.q[s];
			j->cell = i;
			j->old = seg_find(old[cells[i]], j->code);
		}
	/* the jobs in batches, each with the colours of its old segments
	 * still in the source read first, in cell order (a cell's chunk is
	 * decompressed once), at most HD_COL_BATCH_BYTES of them */
	uint64_t batch = h->o.colour_batch_bytes ? h->o.colour_batch_bytes
						 : HD_COL_BATCH_BYTES;
	for (size_t b0 = 0, b1; b0 < segs.n && !err; b0 = b1) {
		uint64_t bytes = 0;
		for (size_t i = 0; i < x.nsrc; i++)
			x.src[i].need = 0;
		for (b1 = b0; b1 < segs.n && !err &&
			      (b1 == b0 || bytes < batch); b1++) {
			struct sjob *j = &x.jobs[b1];
			if (op->kind == VD_EDIT_COPY && j->np != HD_EMPTY)
				bytes += mark_sources(&x, j->code);
			if (!j->old || j->old->nparts || j->np == HD_EMPTY)
				continue;
			if (!(j->old_rgb = malloc(3 * j->old->n)))
				err = vd_fail(VD_ERR_NOMEM, "colours of a segment");
			else
				err = seg_read(&r, j->code, j->old, j->old_rgb);
			bytes += 3 * j->old->n;
		}
		for (size_t i = 0; i < x.nsrc && !err; i++)
			err = src_load(&x, &r, &x.src[i]);
		x.base = b0;
		if (!err && vd_parallel_for(b1 - b0, h->o.threads, run_sjob, &x))
			err = vd_fail(VD_ERR_INTERNAL, "thread pool");
		for (size_t q = b0; q < b1; q++) {
			free(x.jobs[q].old_rgb);
			x.jobs[q].old_rgb = NULL;
		}
	}
	sr_release(&r);
	for (size_t i = 0; i < segs.n && !err; i++)
		if (x.jobs[i].err)
			err = vd_fail(x.jobs[i].err, "%s", x.jobs[i].detail);
	/* the cells met get new tables (made first, so a failure leaves
	 * every old one as it was); every other cell is shared */
	struct hd_cellcol **fresh = err ? NULL : calloc(n ? n : 1,
							sizeof *fresh);
	if (!err && !fresh)
		err = vd_fail(VD_ERR_NOMEM, "colour tables");
	for (size_t i = 0; i < n && !err; i++)
		err = cell_merge(h, old[cells[i]], x.jobs + first[i],
				 first[i + 1] - first[i], &fresh[i]);
	for (uint64_t ci = 0; ci < c->ncells && !err; ci++)
		if (tab[ci])
			__atomic_add_fetch(&tab[ci]->refs, 1, __ATOMIC_RELAXED);
	for (size_t i = 0; i < n && !err; i++) {
		uint64_t ci = cells[i];
		hd_cellcol_unref(c, tab[ci]);
		tab[ci] = fresh[i];
		fresh[i] = NULL;
	}
	for (size_t i = 0; x.jobs && i < segs.n; i++) {
		if (!err)
			*changed_colours += x.jobs[i].changed;
		seg_unref(c, x.jobs[i].out);
	}
	for (size_t i = 0; fresh && i < n; i++)
		hd_cellcol_unref(c, fresh[i]);
	for (size_t i = 0; i < x.nsrc; i++) {
		vl_free(&x.src[i].v);
		free(x.src[i].rgb);
	}
	free(fresh);
	free(first);
	pl_free(&segs);
	free(x.src);
	free(x.jobs);
	free(cells);
	free(scells);
	sr_release(&r);
	if (err) {
		free(tab);
		return err;
	}
	*out = tab;
	return VD_OK;
}

/* ------------------------------------------------------------ saving */

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

/* The colours of a cell one segment at a time (vd_colours_write's
 * `next`): a saved cell costs a segment of raw colours, not the cell's. */
struct segstream {
	struct srcread *r;
	const struct hd_cellcol *cell;
	uint64_t i;
	uint8_t *buf;
	uint64_t cap;
};

static int next_seg(void *ctx, const uint8_t **rgb, size_t *n)
{
	struct segstream *w = ctx;
	*n = 0;
	if (w->i == w->cell->nseg)
		return VD_OK;
	const struct hd_cellseg *g = &w->cell->s[w->i++];
	if (g->seg->n > w->cap) {
		free(w->buf);
		w->cap = g->seg->n;
		if (!(w->buf = malloc(3 * w->cap)))
			return vd_fail(VD_ERR_NOMEM, "colours of a segment");
	}
	int err = seg_read(w->r, g->code, g->seg, w->buf);
	*rgb = w->buf;
	*n = (size_t)g->seg->n;
	return err;
}

/* The bricks of a cell passed to the SVO writer in batches: pass -1
 * counts them, 0 gives the keys, 1 the keys and masks. */
struct bstream {
	struct vd_svo_writer *w;
	int pass;
	uint64_t count;
	size_t k;
	uint64_t key[1024], mask[1024];
};

static int bs_flush(struct bstream *b)
{
	int err = VD_OK;
	if (b->pass == 0)
		err = vd_svo_writer_keys(b->w, b->key, b->k);
	else if (b->pass == 1)
		err = vd_svo_writer_masks(b->w, b->key, b->mask, b->k);
	b->k = 0;
	return err;
}

/* Every brick (key at level L-2, mask) of the subtree of p, in order. */
static int walk_bricks(const struct vd_hashdag *h, int l, uint32_t p,
		       uint64_t key, struct bstream *b)
{
	if (p == HD_EMPTY)
		return VD_OK;
	if (l == h->levels - 2) {
		b->count++;
		if (b->pass < 0)
			return VD_OK;
		b->key[b->k] = key;
		b->mask[b->k++] = hd_brick(h, p);
		return b->k == 1024 ? bs_flush(b) : VD_OK;
	}
	for (int c = 0; c < 8; c++) {
		int err = walk_bricks(h, l + 1, hd_child(h, l, p, c),
				      key << 3 | (uint64_t)c, b);
		if (err)
			return err;
	}
	return VD_OK;
}

/* A cell's SVO chunk and colour chunk, streamed: its bricks walked in
 * the DAG three times (count, keys, masks) and its colours a segment at
 * a time, so saving a cell holds neither its bricks nor its colours. */
static int write_cell(const struct vd_hashdag *h, struct srcread *r,
		      uint64_t ci, const struct hd_cellcol *cell,
		      const char *dir, const char *svo_name,
		      const char *col_name, const char *provenance)
{
	char path[4096];
	struct segstream w = {.r = r, .cell = cell};
	struct bstream *b = calloc(1, sizeof *b);
	if (!b)
		return vd_fail(VD_ERR_NOMEM, "bricks of a cell");
	uint32_t cp = cell_ptr(h, h->roots[h->cur], ci);
	int C = h->col->C;
	b->pass = -1;
	int err = walk_bricks(h, C, cp, ci, b);
	uint64_t digest = 0;
	if (!err && join(path, sizeof path, dir, svo_name))
		err = vd_fail(VD_ERR_ARG, "directory name too long");
	if (!err)
		err = vd_svo_writer_open(&b->w, path, h->levels, C, ci, &h->t,
					 provenance, b->count);
	for (int pass = 0; pass < 2 && !err; pass++) {
		b->pass = pass;
		b->k = 0;
		err = walk_bricks(h, C, cp, ci, b);
		if (!err && b->k)
			err = bs_flush(b);
	}
	if (!err)
		err = vd_svo_writer_commit(b->w, &digest);
	else
		vd_svo_writer_abort(b->w);
	free(b);
	struct vd_chunk_header sh;
	if (!err)
		err = vd_chunk_read_header(path, &sh);
	if (!err && join(path, sizeof path, dir, col_name))
		err = vd_fail(VD_ERR_ARG, "directory name too long");
	if (!err)
		err = vd_colours_write(path, &sh, digest, cell->n, next_seg, &w,
				       provenance);
	free(w.buf);
	return err;
}

int vd_hashdag_colours_stage(const struct vd_hashdag *h, const char *dir,
			     const char *provenance, char *staging,
			     size_t cap)
{
	if (!h->col)
		return vd_fail(VD_ERR_UNSUPPORTED, "the scene has no colours");
	const struct hd_colours *c = h->col;
	/* the source is read while the scene's colours are in it, and its
	 * files are linked into the output: the output cannot replace it */
	struct stat a, b;
	if (c->src_dir && !stat(c->src_dir, &a) && !stat(dir, &b) &&
	    a.st_dev == b.st_dev && a.st_ino == b.st_ino)
		return vd_fail(VD_ERR_ARG, "'%s' is the colour source, read "
			       "while editing: write the colours elsewhere",
			       dir);
	int err = vd_dir_stage(dir, NULL, staging, cap);
	if (err)
		return err;
	struct hd_cellcol **tab = c->tab[h->cur];
	struct srcread r;
	sr_init(&r, c);
	for (uint64_t ci = 0; ci < c->ncells && !err; ci++) {
		if (!tab[ci])
			continue;
		char svo[64], col[64];
		vd_chunk_file_name(svo, sizeof svo, c->C, ci, "svo");
		vd_chunk_file_name(col, sizeof col, c->C, ci, "col");
		if (c->src_dir && tab[ci] == c->input[ci] &&
		    !link_cell(c->src_dir, staging, svo, col))
			continue;
		err = write_cell(h, &r, ci, tab[ci], staging, svo, col,
				 provenance);
	}
	sr_release(&r);
	if (!err)
		err = vd_manifest_write(staging);
	if (err)
		vd_dir_abandon(staging);
	return err;
}

int vd_hashdag_colours_save(const struct vd_hashdag *h, const char *dir,
			    const char *provenance)
{
	char staging[4096];
	int had_old, err = vd_hashdag_colours_stage(h, dir, provenance,
						    staging, sizeof staging);
	if (err)
		return err;
	if ((err = vd_dir_swap(staging, dir, &had_old))) {
		vd_dir_abandon(staging);
		return err;
	}
	if (had_old) { /* the old output; the new one is in place */
		vd_dir_abandon(staging);
		vd_error_clear();
	}
	return VD_OK;
}
