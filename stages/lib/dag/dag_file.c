/* dag_file.c - DAG chunk files: the header of a DAG (vd_dag_header), its
 * sections written as compressed frames (vd_dag_save, _mt), and read back
 * and checked (vd_dag_from_chunk, _mt, vd_dag_load). The sections are
 * specified in schemas/ (DAGM, DAGC, DAGR). */
#include "dag/dag_internal.h"
#include "util_internal.h"
#include "le.h"

#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define NOMEM() vd_fail(VD_ERR_NOMEM, "out of memory in %s", __func__)

void vd_dag_header(const struct vd_dag *dag, struct vd_chunk_header *h)
{
	h->kind = dag->kind;
	h->levels = (uint32_t)dag->levels;
	h->chunk_level = (uint32_t)dag->chunk_level;
	h->cell_morton = dag->cell_morton;
	h->level_count = (uint32_t)(dag->levels - dag->chunk_level + 1);
	for (int l = dag->chunk_level; l < dag->levels; l++)
		h->level_nodes[l - dag->chunk_level] = dag->lv[l].nodes;
	h->level_nodes[dag->levels - dag->chunk_level] = dag->voxels;
}

/* vd_dag_save's sections, each the concatenation of one array of every
 * level (DAGM: masks of levels A..L-1, a byte a node; DAGC: child indices
 * of levels A..L-2, uint32 little-endian; DAGR: their reflections, a
 * byte a reference), written as frames compressed on the job's threads
 * (vd_chunk_writer_frames: the bytes do not depend on the thread count).
 * A frame is filled from the levels it covers. */
struct dag_stream {
	const struct vd_dag *dag;
	uint32_t tag;
	int size;                       /* bytes an element */
	uint64_t start[VD_MAX_LEVELS + 1]; /* first byte of level A + i */
	int nlev;
};

static void dag_stream_init(struct dag_stream *st, const struct vd_dag *dag,
			    uint32_t tag)
{
	st->dag = dag;
	st->tag = tag;
	st->size = tag == VD_TAG_DAGC ? 4 : 1;
	int last = tag == VD_TAG_DAGM ? dag->levels : dag->levels - 1;
	st->nlev = last - dag->chunk_level;
	st->start[0] = 0;
	for (int i = 0; i < st->nlev; i++) {
		const struct vd_dag_level *lv = &dag->lv[dag->chunk_level + i];
		uint64_t n = tag == VD_TAG_DAGM ? lv->nodes : lv->refs;
		st->start[i + 1] = st->start[i] + n * (uint64_t)st->size;
	}
}

/* Bytes [off, off + n) of the section. Frames start at multiples of
 * VD_CHUNK_FRAME_BYTES, a multiple of 4: no DAGC reference is split. */
static void dag_stream_fill(void *ctx, uint64_t off, uint8_t *buf, size_t n)
{
	const struct dag_stream *st = ctx;
	int i = 0;
	while (n) {
		while (off >= st->start[i + 1])
			i++;
		const struct vd_dag_level *lv =
			&st->dag->lv[st->dag->chunk_level + i];
		uint64_t e = (off - st->start[i]) / (uint64_t)st->size;
		size_t k = st->start[i + 1] - off < n ? (size_t)(st->start[i + 1] - off) : n;
		if (st->tag == VD_TAG_DAGM)
			memcpy(buf, lv->mask + e, k);
		else if (st->tag == VD_TAG_DAGR)
			memcpy(buf, lv->refl + e, k);
		else
			for (size_t j = 0; j < k / 4; j++)
				le_put32(buf + 4 * j, lv->child[e + j]);
		buf += k;
		off += k;
		n -= k;
	}
}

static int save_section(const struct vd_dag *dag, struct vd_chunk_writer *w,
			uint32_t tag, int threads)
{
	struct dag_stream st;
	dag_stream_init(&st, dag, tag);
	/* child indices as byte planes (codec 2): their high bytes change
	 * slowly, so zstd stores them in less time and space */
	return vd_chunk_writer_frames(w, tag, st.start[st.nlev],
				      dag_stream_fill, &st, threads,
				      tag == VD_TAG_DAGC);
}

int vd_dag_save(const struct vd_dag *dag, const struct vd_transform *t,
		const char *path, const char *provenance)
{
	return vd_dag_save_mt(dag, t, path, provenance, 1);
}

int vd_dag_save_mt(const struct vd_dag *dag, const struct vd_transform *t,
		   const char *path, const char *provenance, int threads)
{
	/* the check before anything is written */
	int err = vd_dag_validate(dag);
	if (err) return err;
	struct vd_chunk_header h = {0};
	vd_dag_header(dag, &h);
	h.transform = *t;
	struct vd_chunk_writer *w;
	if ((err = vd_chunk_writer_open(&w, path, &h, provenance))) return err;
	err = save_section(dag, w, VD_TAG_DAGM, threads);
	if (!err) err = save_section(dag, w, VD_TAG_DAGC, threads);
	if (!err && dag->kind != VD_KIND_DAG)
		err = save_section(dag, w, VD_TAG_DAGR, threads);
	if (err) {
		vd_chunk_writer_abort(w);
		return err;
	}
	return vd_chunk_writer_commit(w);
}

/* Voxels under the root, counted bottom-up (reflections keep counts). */
static int dag_count_voxels(const struct vd_dag *d, uint64_t *voxels)
{
	int L = d->levels, A = d->chunk_level;
	*voxels = 0;
	if (!d->lv[A].nodes) return VD_OK;
	uint64_t *below = malloc((size_t)(d->lv[L - 1].nodes ? d->lv[L - 1].nodes : 1) * 8);
	if (!below) return NOMEM();
	for (uint64_t i = 0; i < d->lv[L - 1].nodes; i++)
		below[i] = (uint64_t)vd__dag_pop8(d->lv[L - 1].mask[i]);
	for (int l = L - 2; l >= A; l--) {
		const struct vd_dag_level *lv = &d->lv[l];
		uint64_t *cur = malloc((size_t)(lv->nodes ? lv->nodes : 1) * 8);
		if (!cur) {
			free(below);
			return NOMEM();
		}
		for (uint64_t i = 0; i < lv->nodes; i++) {
			uint64_t s = 0;
			for (uint64_t j = lv->first[i]; j < lv->first[i + 1]; j++)
				s += below[lv->child[j]];
			cur[i] = s;
		}
		free(below);
		below = cur;
	}
	*voxels = below[0];
	free(below);
	return VD_OK;
}

/* The sections of a DAG chunk, decompressed in parallel (each is its
 * own zstd stream). */
struct read_job {
	const struct vd_chunk *c;
	uint32_t tags[3];
	void *data[3];
	size_t size[3];
	int errs[3];
	char details[3][512];
	int threads;
};

static void read_task(void *ctx, size_t i, int worker)
{
	(void)worker;
	struct read_job *rj = ctx;
	rj->errs[i] = vd_chunk_read_section_mt(rj->c, rj->tags[i], &rj->data[i],
					       &rj->size[i], rj->threads);
	if (rj->errs[i])
		snprintf(rj->details[i], sizeof rj->details[i], "%s",
			 vd_error_detail());
}

int vd_dag_from_chunk(struct vd_dag *dag, const struct vd_chunk *c,
		      uint32_t kind)
{
	return vd_dag_from_chunk_mt(dag, c, kind, 1);
}

int vd_dag_from_chunk_mt(struct vd_dag *dag, const struct vd_chunk *c,
			 uint32_t kind, int threads)
{
	memset(dag, 0, sizeof *dag);
	const struct vd_chunk_header *h = vd_chunk_header(c);
	/* VD_KIND_ANY keeps meaning dag or ssvdag: the stages after the
	 * symmetry merge (encode, render, edit, lossy) do not know the 48
	 * yet and refuse an ssvdag48 chunk here with a clear line. */
	int ok_kind = kind == VD_KIND_ANY_DAG ? vd__dag_is_dag_kind(h->kind)
		      : kind == VD_KIND_ANY ? h->kind == VD_KIND_DAG ||
					      h->kind == VD_KIND_SSVDAG
		      : h->kind == kind && vd__dag_is_dag_kind(kind);
	if (!ok_kind)
		return vd_fail(VD_ERR_WRONG_KIND, "a %s chunk, expected %s",
			       vd_chunk_kind_name(h->kind),
			       kind == VD_KIND_ANY ? "dag or ssvdag"
			       : kind == VD_KIND_ANY_DAG ? "dag, ssvdag or ssvdag48"
			       : vd_chunk_kind_name(kind));
	int L = (int)h->levels, A = (int)h->chunk_level;
	if (L < 1 || L > VD_MAX_LEVELS || A < 0 || A > L - 1 ||
	    h->level_count != (uint32_t)(L - A + 1))
		return vd_fail(VD_ERR_CORRUPT, "levels %d, chunk level %d, %u "
			       "level counts", L, A, h->level_count);
	dag->kind = h->kind;
	dag->levels = L;
	dag->chunk_level = A;
	dag->cell_morton = h->cell_morton;
	int sym = h->kind != VD_KIND_DAG;
	void *m = NULL, *cdata = NULL, *r = NULL;
	size_t msize, csize, rsize = 0;
	struct read_job rj = {c, {VD_TAG_DAGM, VD_TAG_DAGC, VD_TAG_DAGR},
			      {NULL}, {0}, {0}, {{0}}, threads};
	int err = vd_parallel_for(sym ? 3 : 2, threads, read_task, &rj);
	for (int i = 0; i < (sym ? 3 : 2) && !err; i++)
		if (rj.errs[i]) err = vd_fail(rj.errs[i], "%s", rj.details[i]);
	m = rj.data[0], msize = rj.size[0];
	cdata = rj.data[1], csize = rj.size[1];
	r = rj.data[2], rsize = rj.size[2];
	if (err) goto out;
	/* masks, and from them the reference counts */
	uint64_t need = 0, nref = 0;
	for (int l = A; l < L; l++) need += h->level_nodes[l - A];
	if (need != msize) {
		err = vd_fail(VD_ERR_CORRUPT, "mask section of %zu bytes, the "
			      "level counts say %" PRIu64, msize, need);
		goto out;
	}
	const uint8_t *mp = m;
	for (int l = A; l < L; l++) {
		struct vd_dag_level *lv = &dag->lv[l];
		lv->nodes = h->level_nodes[l - A];
		lv->mask = malloc(lv->nodes ? (size_t)lv->nodes : 1);
		if (!lv->mask) {
			err = NOMEM();
			goto out;
		}
		memcpy(lv->mask, mp, (size_t)lv->nodes);
		mp += lv->nodes;
		if (l == L - 1) break;
		lv->first = malloc((size_t)(lv->nodes + 1) * 8);
		if (!lv->first) {
			err = NOMEM();
			goto out;
		}
		uint64_t j = 0;
		for (uint64_t i = 0; i < lv->nodes; i++) {
			lv->first[i] = j;
			j += (uint64_t)vd__dag_pop8(lv->mask[i]);
		}
		lv->first[lv->nodes] = j;
		lv->refs = j;
		nref += j;
	}
	if (csize != 4 * nref || (sym && rsize != nref)) {
		err = vd_fail(VD_ERR_CORRUPT, "reference sections of %zu and %zu"
			      " bytes for %" PRIu64 " references", csize, rsize,
			      nref);
		goto out;
	}
	const uint8_t *cp = cdata, *rp = r;
	for (int l = A; l < L - 1; l++) {
		struct vd_dag_level *lv = &dag->lv[l];
		lv->child = malloc(lv->refs ? (size_t)lv->refs * 4 : 4);
		if (sym) lv->refl = malloc(lv->refs ? (size_t)lv->refs : 1);
		if (!lv->child || (sym && !lv->refl)) {
			err = NOMEM();
			goto out;
		}
		for (uint64_t j = 0; j < lv->refs; j++) lv->child[j] = le_get32(cp + 4 * j);
		cp += 4 * lv->refs;
		if (sym) {
			memcpy(lv->refl, rp, (size_t)lv->refs);
			rp += lv->refs;
		}
	}
	/* bricks of level L-2 (checked indices first) */
	dag->bricks = NULL;
	if (A <= L - 2 && dag->lv[A].nodes) {
		const struct vd_dag_level *lb = &dag->lv[L - 2];
		for (uint64_t j = 0; j < lb->refs; j++)
			if (lb->child[j] >= dag->lv[L - 1].nodes) {
				err = vd_fail(VD_ERR_CORRUPT, "level %d reference %"
					      PRIu64 " to leaf %u of %" PRIu64,
					      L - 2, j, lb->child[j],
					      dag->lv[L - 1].nodes);
				goto out;
			}
		dag->bricks = malloc((size_t)(lb->nodes ? lb->nodes : 1) * 8);
		if (!dag->bricks) {
			err = NOMEM();
			goto out;
		}
		for (uint64_t i = 0; i < lb->nodes; i++) {
			uint64_t v = 0, j = lb->first[i];
			for (unsigned s = 0; s < 8; s++) {
				if (!(lb->mask[i] >> s & 1)) continue;
				uint8_t x = dag->lv[L - 1].mask[lb->child[j]];
				if (lb->refl) x = vd__dag_ref_mask(h->kind, x, lb->refl[j] % VD_G48);
				v |= (uint64_t)x << 8 * s;
				j++;
			}
			dag->bricks[i] = v;
		}
	}
	dag->voxels = h->level_nodes[L - A];
	if ((err = vd_dag_validate(dag))) goto out;
	uint64_t v;
	if ((err = dag_count_voxels(dag, &v))) goto out;
	if (v != dag->voxels)
		err = vd_fail(VD_ERR_CORRUPT, "%" PRIu64 " voxels, the header "
			      "says %" PRIu64, v, dag->voxels);
out:
	free(m);
	free(cdata);
	free(r);
	if (err) vd_dag_release(dag);
	return err;
}

int vd_dag_load(struct vd_dag *dag, struct vd_chunk_header *h,
		const char *path, uint32_t kind)
{
	memset(dag, 0, sizeof *dag);
	struct vd_chunk *c;
	int err = vd_chunk_open(&c, path, VD_KIND_ANY);
	if (err) return err;
	if (h) *h = *vd_chunk_header(c);
	err = vd_dag_from_chunk(dag, c, kind);
	vd_chunk_free(c);
	return err;
}
