/* mesh_spill.c - the external join of an indexed mesh's faces with
 * tables of records (its vertices, an OBJ's texture coordinates), for
 * meshes whose tables do not fit in the memory budget (mesh_spill.h says
 * what it does; this says how).
 *
 * External sorts of fixed-size records keyed by a uint64 at offset 0:
 *   A: one record per triangle corner and table it has an index in,
 *      (table << 32 | index, corner position 3t+k), sorted by that key,
 *      so its merge gives table 0's corners in index order, then table
 *      1's: one sort serves every table, and the join reads the tables
 *      one after the other, each in order;
 *   B_t, one per table: the join of A's merged runs with table t's file
 *      read in order, (corner position, index, record), sorted by corner
 *      position, so the merges of the B_t in step yield the triangles in
 *      their input order (a corner without an index in table t is simply
 *      absent from B_t).
 * A sort fills a buffer, sorts it and appends it as one run to its file;
 * the merge reads every run through its own small buffer (one pass: with
 * runs of half the budget there are few of them). The triangles' face
 * numbers and lines (for messages) and their own records are already in
 * triangle order and go to a file of their own. All files are unlinked
 * temporaries (O_TMPFILE), written and read with explicit offsets;
 * records are native byte order, as they never leave the process. */
#include "voxdag.h"
#include "io/mesh/mesh_spill.h"

#include <errno.h>
#include <fcntl.h>
#include <malloc.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define SPILL_MIN_MEM (1u << 20)

static const char *spill_dir_name; /* for messages, set by each call */

static int io_fail(const char *what)
{
	return vd_fail(VD_ERR_IO, "cannot %s the vertex spill in '%s': %s",
		       what, spill_dir_name, strerror(errno));
}

/* ------------------------------------------------ buffered file access */

/* Appends to a file at `end`. */
struct wr {
	int fd;
	uint8_t *b;
	size_t cap, n;
	uint64_t end;
};

static int wr_flush(struct wr *w)
{
	int err = vd_pwrite_full(w->fd, w->b, w->n, w->end) ? io_fail("write")
							    : VD_OK;
	if (!err) {
		w->end += w->n;
		w->n = 0;
	}
	return err;
}

static int wr_put(struct wr *w, const void *p, size_t n)
{
	if (w->n + n > w->cap) {
		int err = wr_flush(w);
		if (err)
			return err;
	}
	memcpy(w->b + w->n, p, n);
	w->n += n;
	return VD_OK;
}

/* Reads records of R bytes from [off, end) of a file; the buffer holds a
 * whole number of records so none straddles a refill. */
struct rd {
	int fd;
	size_t R;
	uint64_t off, end;
	uint8_t *b;
	size_t cap, pos, len;
};

static void rd_init(struct rd *r, int fd, size_t R, uint64_t off,
		    uint64_t end, uint8_t *buf, size_t cap)
{
	r->fd = fd;
	r->R = R;
	r->off = off;
	r->end = end;
	r->b = buf;
	r->cap = cap / R * R;
	r->pos = r->len = 0;
}

/* The next record, or NULL at the end (*err set on a read error). */
static const uint8_t *rd_next(struct rd *r, int *err)
{
	if (r->pos == r->len) {
		uint64_t left = r->end - r->off;
		if (left == 0)
			return NULL;
		size_t want = left < r->cap ? (size_t)left : r->cap;
		if (vd_pread_full(r->fd, r->b, want, r->off)) {
			*err = io_fail("read");
			return NULL;
		}
		r->off += want;
		r->pos = 0;
		r->len = want;
	}
	const uint8_t *p = r->b + r->pos;
	r->pos += r->R;
	return p;
}

/* ------------------------------------------------------ external sort */

struct xsort {
	size_t R;
	int fd;
	uint64_t end;             /* bytes of runs written */
	uint8_t *buf;             /* the run being filled */
	size_t cap, n;            /* in records */
	uint64_t *runs;           /* start offset of each run, then `end` */
	size_t nruns, runs_cap;
	/* merge */
	struct rd *in;
	const uint8_t **head;     /* each run's current record, NULL at end */
	size_t *heap, nheap;
	uint8_t *mbuf, *cur;
	size_t mbytes;
};

static uint64_t key_of(const uint8_t *p)
{
	uint64_t k;
	memcpy(&k, p, 8);
	return k;
}

static int cmp_key(const void *a, const void *b)
{
	uint64_t x = key_of(a), y = key_of(b);
	return (x > y) - (x < y);
}

static int xs_init(struct xsort *x, const char *dir, size_t R)
{
	memset(x, 0, sizeof *x);
	x->R = R;
	x->fd = vd_tmpfile(dir, "mesh-spill");
	return x->fd < 0 ? io_fail("create") : VD_OK;
}

static int xs_reserve(struct xsort *x, size_t bytes)
{
	x->cap = bytes / x->R;
	if (x->cap < 1)
		x->cap = 1;
	x->buf = malloc(x->cap * x->R);
	return x->buf ? VD_OK : vd_fail(VD_ERR_NOMEM, "spill sort buffer");
}

static int xs_flush_run(struct xsort *x)
{
	if (x->n == 0)
		return VD_OK;
	qsort(x->buf, x->n, x->R, cmp_key);
	if (x->nruns + 2 > x->runs_cap) {
		size_t c = x->runs_cap ? 2 * x->runs_cap : 16;
		uint64_t *g = realloc(x->runs, c * sizeof *g);
		if (!g)
			return vd_fail(VD_ERR_NOMEM, "spill runs");
		x->runs = g;
		x->runs_cap = c;
	}
	int err = vd_pwrite_full(x->fd, x->buf, x->n * x->R, x->end) ?
		  io_fail("write") : VD_OK;
	if (err)
		return err;
	x->runs[x->nruns++] = x->end;
	x->end += x->n * x->R;
	x->runs[x->nruns] = x->end;
	x->n = 0;
	return VD_OK;
}

static int xs_add(struct xsort *x, const void *rec)
{
	if (x->n == x->cap) {
		int err = xs_flush_run(x);
		if (err)
			return err;
	}
	memcpy(x->buf + x->n * x->R, rec, x->R);
	x->n++;
	return VD_OK;
}

/* Ends the input: the last run to disk, the fill buffer freed. */
static int xs_finish(struct xsort *x)
{
	int err = xs_flush_run(x);
	free(x->buf);
	x->buf = NULL;
	return err;
}

static int heap_less(const struct xsort *x, size_t a, size_t b)
{
	uint64_t ka = key_of(x->head[a]), kb = key_of(x->head[b]);
	return ka < kb || (ka == kb && a < b);
}

static void heap_down(struct xsort *x, size_t i)
{
	for (;;) {
		size_t l = 2 * i + 1, m = i;
		if (l < x->nheap && heap_less(x, x->heap[l], x->heap[m]))
			m = l;
		if (l + 1 < x->nheap && heap_less(x, x->heap[l + 1], x->heap[m]))
			m = l + 1;
		if (m == i)
			return;
		size_t t = x->heap[i];
		x->heap[i] = x->heap[m];
		x->heap[m] = t;
		i = m;
	}
}

static void xs_merge_free(struct xsort *x)
{
	free(x->in);
	free(x->head);
	free(x->heap);
	free(x->mbuf);
	free(x->cur);
	x->in = NULL;
	x->head = NULL;
	x->heap = NULL;
	x->mbuf = x->cur = NULL;
	x->mbytes = 0;
}

/* (Re)starts the merge of every run within about `mem` bytes. */
static int xs_merge_start(struct xsort *x, size_t mem)
{
	size_t k = x->nruns;
	if (!x->in) {
		size_t per = k ? mem / k : mem;
		if (per < 64 * x->R)
			per = 64 * x->R; /* few huge runs never happen at 1 MiB+ */
		per = per / x->R * x->R;
		x->in = calloc(k ? k : 1, sizeof *x->in);
		x->head = calloc(k ? k : 1, sizeof *x->head);
		x->heap = calloc(k ? k : 1, sizeof *x->heap);
		x->mbuf = malloc(k ? k * per : 1);
		x->cur = malloc(x->R);
		x->mbytes = k * per;
		if (!x->in || !x->head || !x->heap || !x->mbuf || !x->cur) {
			xs_merge_free(x);
			return vd_fail(VD_ERR_NOMEM, "spill merge buffers");
		}
		for (size_t i = 0; i < k; i++)
			x->in[i].cap = per;
	}
	x->nheap = 0;
	int err = VD_OK;
	for (size_t i = 0; i < k && !err; i++) {
		size_t per = x->in[i].cap;
		rd_init(&x->in[i], x->fd, x->R, x->runs[i], x->runs[i + 1],
			x->mbuf + i * per, per);
		x->head[i] = rd_next(&x->in[i], &err);
		if (x->head[i])
			x->heap[x->nheap++] = i;
	}
	for (size_t i = x->nheap; i-- > 0;)
		heap_down(x, i);
	return err;
}

/* The next record in key order (copied: valid until the next call), or
 * NULL at the end or on an error (*err set). */
static const uint8_t *xs_merge_next(struct xsort *x, int *err)
{
	if (x->nheap == 0)
		return NULL;
	size_t i = x->heap[0];
	memcpy(x->cur, x->head[i], x->R);
	x->head[i] = rd_next(&x->in[i], err);
	if (*err)
		return NULL;
	if (!x->head[i])
		x->heap[0] = x->heap[--x->nheap];
	heap_down(x, 0);
	return x->cur;
}

static void xs_release(struct xsort *x)
{
	xs_merge_free(x);
	free(x->buf);
	free(x->runs);
	if (x->fd >= 0)
		close(x->fd);
	x->buf = NULL;
	x->runs = NULL;
	x->fd = -1;
}

/* ------------------------------------------------------------ the join */

/* A table: its records in index order in a file of their own, and the
 * sort B of its joined corners. */
struct spill_table {
	size_t rb;                /* record bytes */
	uint64_t n;               /* records appended */
	int fd;
	struct wr w;
	struct xsort b;           /* (corner position, index, record) */
	const uint8_t *head;      /* reading: B's next record, NULL at end */
};

struct vd_spill {
	char *dir;
	size_t ntab;
	struct spill_table t[VD_SPILL_MAX_TABLES];
	size_t mr;                /* meta record: face, line, triangle record */
	uint64_t mem;
	uint64_t ntris;
	int mfd;                  /* the triangles' meta records */
	struct wr mw;
	struct xsort a;           /* (table << 32 | index, corner position) */
	int finished;
	/* reading */
	struct rd meta;
	uint8_t *meta_buf;
	uint8_t *tri;             /* per table the 3 B records of the current
				   * triangle, at tri_off[table] */
	size_t tri_off[VD_SPILL_MAX_TABLES];
	uint64_t next_tri;
};

int vd__spill_open(struct vd_spill **out, const char *dir, size_t ntables,
		  const size_t rec_bytes[], size_t tri_bytes,
		  uint64_t mem_bytes)
{
	*out = NULL;
	spill_dir_name = dir;
	if (ntables < 1 || ntables > VD_SPILL_MAX_TABLES)
		return vd_fail(VD_ERR_ARG, "a spill of %zu tables (1 to %d)",
			       ntables, VD_SPILL_MAX_TABLES);
	struct vd_spill *s = calloc(1, sizeof *s);
	if (!s)
		return vd_fail(VD_ERR_NOMEM, "vertex spill");
	s->ntab = ntables;
	s->mfd = s->a.fd = -1;
	for (size_t t = 0; t < VD_SPILL_MAX_TABLES; t++)
		s->t[t].fd = s->t[t].b.fd = -1;
	s->mr = 16 + tri_bytes;
	s->mem = mem_bytes < SPILL_MIN_MEM ? SPILL_MIN_MEM : mem_bytes;
	int err = VD_OK;
	if (!(s->dir = strdup(dir)))
		err = vd_fail(VD_ERR_NOMEM, "vertex spill");
	if (!err && (s->mfd = vd_tmpfile(dir, "mesh-spill")) < 0)
		err = io_fail("create");
	for (size_t t = 0; t < ntables && !err; t++) {
		s->t[t].rb = rec_bytes[t];
		if ((s->t[t].fd = vd_tmpfile(dir, "mesh-spill")) < 0)
			err = io_fail("create");
		if (!err)
			err = xs_init(&s->t[t].b, dir, 12 + rec_bytes[t]);
	}
	if (!err)
		err = xs_init(&s->a, dir, 16);
	/* while the input comes: A's run buffer takes half the memory, the
	 * meta writer an eighth and the tables' writers an eighth together */
	size_t mcap = (size_t)(s->mem / 8), tcap = mcap / ntables;
	if (!err) {
		s->mw = (struct wr){.fd = s->mfd, .cap = mcap, .b = malloc(mcap)};
		if (!s->mw.b)
			err = vd_fail(VD_ERR_NOMEM, "vertex spill buffers");
	}
	for (size_t t = 0; t < ntables && !err; t++) {
		s->t[t].w = (struct wr){.fd = s->t[t].fd, .cap = tcap,
					.b = malloc(tcap)};
		if (!s->t[t].w.b)
			err = vd_fail(VD_ERR_NOMEM, "vertex spill buffers");
	}
	if (!err)
		err = xs_reserve(&s->a, (size_t)(s->mem / 2));
	if (err) {
		vd__spill_close(s);
		return err;
	}
	*out = s;
	return VD_OK;
}

int vd__spill_record(struct vd_spill *s, size_t t, const void *rec)
{
	spill_dir_name = s->dir;
	if (t >= s->ntab || s->t[t].n >= VD_SPILL_NONE)
		return vd_fail(VD_ERR_INTERNAL, "record %llu of spill table "
			       "%zu of %zu", (unsigned long long)(t < s->ntab
			       ? s->t[t].n : 0), t, s->ntab);
	s->t[t].n++;
	return wr_put(&s->t[t].w, rec, s->t[t].rb);
}

int vd__spill_triangle(struct vd_spill *s,
		      const uint32_t idx[VD_SPILL_MAX_TABLES][3],
		      uint64_t face, uint64_t line, const void *tri_rec)
{
	spill_dir_name = s->dir;
	int err = VD_OK;
	for (size_t t = 0; t < s->ntab && !err; t++)
		for (int k = 0; k < 3 && !err; k++) {
			if (idx[t][k] == VD_SPILL_NONE)
				continue;
			uint64_t r[2] = {(uint64_t)t << 32 | idx[t][k],
					 3 * s->ntris + (uint64_t)k};
			err = xs_add(&s->a, r);
		}
	uint64_t m[2] = {face, line};
	if (!err)
		err = wr_put(&s->mw, m, sizeof m);
	if (!err && s->mr > 16)
		err = wr_put(&s->mw, tri_rec, s->mr - 16);
	s->ntris++;
	return err;
}

/* Starts (again) the reading of the joined triangles: B's merges take an
 * eighth of the memory together, since they stay for every pass of the
 * caller over the mesh (runs are read sequentially: small buffers are
 * enough). */
static int spill_read_start(struct vd_spill *s)
{
	int err = VD_OK;
	s->next_tri = 0;
	rd_init(&s->meta, s->mfd, s->mr, 0, s->mr * s->ntris, s->meta_buf,
		1 << 16);
	for (size_t t = 0; t < s->ntab && !err; t++) {
		struct spill_table *tb = &s->t[t];
		err = xs_merge_start(&tb->b, (size_t)(s->mem / 8 / s->ntab));
		if (!err)
			tb->head = xs_merge_next(&tb->b, &err);
	}
	return err;
}

int vd__spill_finish(struct vd_spill *s)
{
	spill_dir_name = s->dir;
	int err = wr_flush(&s->mw);
	free(s->mw.b);
	s->mw.b = NULL;
	size_t bmax = 0;
	for (size_t t = 0; t < s->ntab; t++) {
		if (!err)
			err = wr_flush(&s->t[t].w);
		free(s->t[t].w.b);
		s->t[t].w.b = NULL;
		if (s->t[t].b.R > bmax)
			bmax = s->t[t].b.R;
	}
	if (!err)
		err = xs_finish(&s->a);
	/* the join, one table after the other as A's merge gives them: A's
	 * merge a quarter, the run buffer of the table's B half, the
	 * table's reader an eighth */
	size_t vcap = (size_t)(s->mem / 8);
	uint8_t *vbuf = NULL, *brec = malloc(bmax);
	if (!err && (!(vbuf = malloc(vcap)) || !brec))
		err = vd_fail(VD_ERR_NOMEM, "vertex spill join");
	if (!err)
		err = xs_merge_start(&s->a, (size_t)(s->mem / 4));
	struct rd vr = {0};
	size_t cur = SIZE_MAX;    /* the table being joined */
	uint64_t vi = 0;          /* index of the record after `vrec` */
	const uint8_t *vrec = NULL, *r;
	while (!err && (r = xs_merge_next(&s->a, &err))) {
		uint64_t key, pos;
		memcpy(&key, r, 8);
		memcpy(&pos, r + 8, 8);
		size_t t = (size_t)(key >> 32);
		uint32_t want = (uint32_t)key;
		if (t != cur) {
			if (t >= s->ntab || (cur != SIZE_MAX && t < cur)) {
				err = vd_fail(VD_ERR_INTERNAL, "spill table %zu "
					      "after table %zu", t, cur);
				break;
			}
			if ((cur != SIZE_MAX && (err = xs_finish(&s->t[cur].b))) ||
			    (err = xs_reserve(&s->t[t].b, (size_t)(s->mem / 2))))
				break;
			cur = t;
			rd_init(&vr, s->t[t].fd, s->t[t].rb, 0,
				s->t[t].n * s->t[t].rb, vbuf, vcap);
			vi = 0;
			vrec = NULL;
		}
		while (!err && vi <= want) {
			if (!(vrec = rd_next(&vr, &err)) && !err)
				err = vd_fail(VD_ERR_INTERNAL, "record %lu of %llu "
					      "of table %zu missing from the "
					      "spill", (unsigned long)want,
					      (unsigned long long)s->t[t].n, t);
			vi++;
		}
		if (err)
			break;
		memcpy(brec, &pos, 8);
		memcpy(brec + 8, &want, 4);
		memcpy(brec + 12, vrec, s->t[t].rb);
		err = xs_add(&s->t[t].b, brec);
	}
	if (!err && cur != SIZE_MAX)
		err = xs_finish(&s->t[cur].b);
	free(vbuf);
	free(brec);
	xs_release(&s->a);
	for (size_t t = 0; t < s->ntab; t++) {
		close(s->t[t].fd);
		s->t[t].fd = -1;
	}
	if (!err) {
		size_t off = 0;
		for (size_t t = 0; t < s->ntab; t++) {
			s->tri_off[t] = off;
			off += 3 * s->t[t].b.R;
		}
		s->meta_buf = malloc(1 << 16);
		s->tri = malloc(off);
		if (!s->meta_buf || !s->tri)
			err = vd_fail(VD_ERR_NOMEM, "vertex spill reader");
	}
	if (!err)
		err = spill_read_start(s);
	if (!err)
		s->finished = 1;
	/* the sort buffers are freed, but glibc keeps freed heap pages of
	 * their size (its mmap threshold rises after the first): give them
	 * back, the caller's budget counts resident memory */
	malloc_trim(0);
	return err;
}

int vd__spill_next(struct vd_spill *s,
		  const uint8_t *rec[VD_SPILL_MAX_TABLES][3],
		  uint32_t idx[VD_SPILL_MAX_TABLES][3], uint64_t *face,
		  uint64_t *line, const uint8_t **tri_rec, int *got)
{
	spill_dir_name = s->dir;
	*got = 0;
	if (!s->finished)
		return vd_fail(VD_ERR_INTERNAL, "vertex spill read before finish");
	if (s->next_tri == s->ntris)
		return VD_OK;
	int err = VD_OK;
	for (size_t t = 0; t < s->ntab; t++) {
		struct spill_table *tb = &s->t[t];
		for (int k = 0; k < 3; k++) {
			uint64_t want = 3 * s->next_tri + (uint64_t)k, pos = 0;
			rec[t][k] = NULL;
			idx[t][k] = VD_SPILL_NONE;
			if (tb->head)
				memcpy(&pos, tb->head, 8);
			if (!tb->head || pos > want)
				continue; /* no index in this table */
			if (pos < want)
				return vd_fail(VD_ERR_INTERNAL, "vertex spill out "
					       "of order at triangle %llu",
					       (unsigned long long)s->next_tri);
			uint8_t *d = s->tri + s->tri_off[t] +
				     (size_t)k * tb->b.R;
			memcpy(d, tb->head, tb->b.R);
			memcpy(&idx[t][k], d + 8, 4);
			rec[t][k] = d + 12;
			tb->head = xs_merge_next(&tb->b, &err);
			if (err)
				return err;
		}
	}
	const uint8_t *m = rd_next(&s->meta, &err);
	if (!m)
		return err ? err : vd_fail(VD_ERR_INTERNAL, "vertex spill "
					   "without the faces of its triangles");
	memcpy(face, m, 8);
	memcpy(line, m + 8, 8);
	*tri_rec = m + 16;
	s->next_tri++;
	*got = 1;
	return VD_OK;
}

int vd__spill_rewind(struct vd_spill *s)
{
	spill_dir_name = s->dir;
	if (!s->finished)
		return vd_fail(VD_ERR_INTERNAL, "vertex spill rewound before finish");
	return spill_read_start(s);
}

size_t vd__spill_memory_bytes(const struct vd_spill *s)
{
	if (!s)
		return 0;
	size_t b = sizeof *s + (s->mw.b ? s->mw.cap : 0) +
		   (s->meta_buf ? 1 << 16 : 0) +
		   (s->a.buf ? s->a.cap * s->a.R : 0) + s->a.mbytes;
	for (size_t t = 0; t < s->ntab; t++) {
		const struct spill_table *tb = &s->t[t];
		b += (tb->w.b ? tb->w.cap : 0) + 3 * tb->b.R +
		     (tb->b.buf ? tb->b.cap * tb->b.R : 0) + tb->b.mbytes;
	}
	return b;
}

void vd__spill_close(struct vd_spill *s)
{
	if (!s)
		return;
	xs_release(&s->a);
	for (size_t t = 0; t < VD_SPILL_MAX_TABLES; t++) {
		xs_release(&s->t[t].b);
		if (s->t[t].fd >= 0)
			close(s->t[t].fd);
		free(s->t[t].w.b);
	}
	if (s->mfd >= 0)
		close(s->mfd);
	free(s->mw.b);
	free(s->meta_buf);
	free(s->tri);
	free(s->dir);
	free(s);
}
