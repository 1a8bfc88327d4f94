/* ops.c - the edits (paper section 3.4): fill and carve of boxes and
 * spheres, copy of a box. An edit descends only into nodes whose cube the
 * shape partly covers; a cube it covers wholly becomes the level's full
 * node (fill), nothing (carve) or, for a copy whose offset is a multiple of
 * the cube's side, the source node itself. Nodes are found or appended by
 * hashing, so unchanged subtrees keep their pointers. Below `split_level`
 * the subtrees are independent jobs run on the thread pool; the levels
 * above are rebuilt afterwards in the same order, so the decoded result
 * does not depend on the thread count (only the order of nodes inside a
 * bucket does). */
#include "edit_internal.h"
#include "util_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { OUTSIDE, INSIDE, PARTIAL };

struct op_jobs;

struct ectx {
	struct vd_hashdag *h;
	const struct vd_edit_op *op;
	uint32_t src_root;     /* copy: the scene before the edit */
	int64_t box_lo[3], box_hi[3]; /* the region written (box or copy dst) */
	struct op_jobs *js;
};

/* One subtree job at the split level. */
struct job {
	uint32_t ptr, result;
	uint32_t x, y, z;
	uint64_t changed;
	int err;
	char detail[240];
};

struct op_jobs {
	struct job *v;
	size_t n, cap, next;
	int err;
};

/* Does the shape cover voxel (x, y, z)? */
static int shape_has(const struct ectx *e, int64_t x, int64_t y, int64_t z)
{
	if (e->op->shape == VD_SHAPE_SPHERE && e->op->kind != VD_EDIT_COPY)
		return hd_sphere_has(e->op, x, y, z);
	return x >= e->box_lo[0] && x <= e->box_hi[0] && y >= e->box_lo[1] &&
	       y <= e->box_hi[1] && z >= e->box_lo[2] && z <= e->box_hi[2];
}

/* How the shape meets the cube of side s at (x, y, z). For spheres the
 * test is on the voxel centres with a margin, so a doubtful cube is
 * descended into and decided voxel by voxel. */
static int classify(const struct ectx *e, int64_t x, int64_t y, int64_t z,
		    int64_t s)
{
	int64_t p[3] = {x, y, z};
	if (e->op->shape == VD_SHAPE_SPHERE && e->op->kind != VD_EDIT_COPY) {
		double near = 0, far = 0;
		for (int a = 0; a < 3; a++) {
			double lo = (double)p[a] + 0.5, hi = (double)(p[a] + s) - 0.5;
			double c = e->op->c[a];
			double dn = c < lo ? lo - c : c > hi ? c - hi : 0;
			double df = fmax(fabs(c - lo), fabs(c - hi));
			near += dn * dn;
			far += df * df;
		}
		double r2 = e->op->r * e->op->r, eps = 1e-9 * (r2 + 1);
		if (near > r2 + eps)
			return OUTSIDE;
		if (far < r2 - eps)
			return INSIDE;
		return PARTIAL;
	}
	int in = 1;
	for (int a = 0; a < 3; a++) {
		if (p[a] + s - 1 < e->box_lo[a] || p[a] > e->box_hi[a])
			return OUTSIDE;
		if (p[a] < e->box_lo[a] || p[a] + s - 1 > e->box_hi[a])
			in = 0;
	}
	return in ? INSIDE : PARTIAL;
}

/* Bit of voxel (x, y, z) (each 0..3) in a brick: local Morton order. */
static inline int brick_bit(int x, int y, int z)
{
	return (x >> 1 & 1) << 5 | (y >> 1 & 1) << 4 | (z >> 1 & 1) << 3 |
	       (x & 1) << 2 | (y & 1) << 1 | (z & 1);
}

/* The voxel (x, y, z) of the copy's source scene. */
static int src_voxel(const struct ectx *e, int64_t x, int64_t y, int64_t z,
		     uint32_t *cache_key, uint64_t *cache)
{
	const struct vd_hashdag *h = e->h;
	uint32_t bx = (uint32_t)x >> 2, by = (uint32_t)y >> 2,
		 bz = (uint32_t)z >> 2;
	uint32_t key = (uint32_t)vd_morton3(bx, by, bz) & 0x7fffffffu;
	int slot = (int)((bx & 1) << 2 | (by & 1) << 1 | (bz & 1));
	if (cache_key[slot] != key) {
		uint32_t p = hd_lookup(h, e->src_root, h->levels - 2,
				       (uint32_t)x, (uint32_t)y, (uint32_t)z);
		cache[slot] = p == HD_EMPTY ? 0 : hd_brick(h, p);
		cache_key[slot] = key;
	}
	return (int)(cache[slot] >> brick_bit((int)(x & 3), (int)(y & 3),
					      (int)(z & 3)) & 1);
}

static int edit_leaf(struct ectx *e, uint32_t ptr, int64_t x, int64_t y,
		     int64_t z, uint64_t *changed, uint32_t *out)
{
	const struct vd_hashdag *h = e->h;
	uint64_t old = ptr == HD_EMPTY ? 0 : hd_brick(h, ptr), m = 0, src = 0;
	uint32_t ckey[8];
	uint64_t cache[8];
	memset(ckey, 0xff, sizeof ckey);
	for (int i = 0; i < 4; i++)
		for (int j = 0; j < 4; j++)
			for (int k = 0; k < 4; k++) {
				if (!shape_has(e, x + i, y + j, z + k))
					continue;
				int b = brick_bit(i, j, k);
				m |= 1ull << b;
				if (e->op->kind == VD_EDIT_COPY &&
				    src_voxel(e, x + i - (e->op->dst[0] - e->op->lo[0]),
					      y + j - (e->op->dst[1] - e->op->lo[1]),
					      z + k - (e->op->dst[2] - e->op->lo[2]),
					      ckey, cache))
					src |= 1ull << b;
			}
	uint64_t nw = e->op->kind == VD_EDIT_FILL    ? old | m
		      : e->op->kind == VD_EDIT_CARVE ? old & ~m
						     : (old & ~m) | src;
	*changed += (uint64_t)__builtin_popcountll(old ^ nw);
	if (nw == old) {
		*out = ptr;
		return VD_OK;
	}
	if (!nw) {
		*out = HD_EMPTY;
		return VD_OK;
	}
	return hd_insert_leaf(e->h, nw, out);
}

/* The whole-cube cases: returns 1 and sets *out when the cube of level l
 * at (x, y, z) needs no descent. */
static int whole(struct ectx *e, int l, uint32_t ptr, int64_t x, int64_t y,
		 int64_t z, uint64_t *changed, uint32_t *out, int *in_out)
{
	const struct vd_hashdag *h = e->h;
	int64_t s = (int64_t)1 << (h->levels - l);
	int c = classify(e, x, y, z, s);
	*in_out = c;
	if (c == OUTSIDE) {
		*out = ptr;
		return 1;
	}
	if (c != INSIDE)
		return 0;
	if (e->op->kind == VD_EDIT_COPY) {
		int64_t d[3];
		for (int a = 0; a < 3; a++)
			d[a] = e->op->dst[a] - e->op->lo[a];
		if ((d[0] | d[1] | d[2]) & (s - 1))
			return 0;
		uint32_t src = hd_lookup(h, e->src_root, l, (uint32_t)(x - d[0]),
					 (uint32_t)(y - d[1]),
					 (uint32_t)(z - d[2]));
		*out = src;
		return 1;
	}
	*out = e->op->kind == VD_EDIT_FILL ? h->lv[l].full : HD_EMPTY;
	return 1;
}

#define voxels_of hd_voxels_of

/* Voxels that differ between the subtrees a and b on level l. */
static uint64_t diff_of(const struct vd_hashdag *h, int l, uint32_t a,
			uint32_t b)
{
	if (a == b)
		return 0;
	if (a == HD_EMPTY)
		return voxels_of(h, l, b);
	if (b == HD_EMPTY)
		return voxels_of(h, l, a);
	if (a == h->lv[l].full)
		return voxels_of(h, l, a) - voxels_of(h, l, b);
	if (b == h->lv[l].full)
		return voxels_of(h, l, b) - voxels_of(h, l, a);
	if (l == h->levels - 2)
		return (uint64_t)__builtin_popcountll(hd_brick(h, a) ^
						      hd_brick(h, b));
	uint64_t n = 0;
	for (int c = 0; c < 8; c++)
		n += diff_of(h, l + 1, hd_child(h, l, a, c),
			     hd_child(h, l, b, c));
	return n;
}

static int edit_node(struct ectx *e, int l, uint32_t ptr, int64_t x,
		     int64_t y, int64_t z, uint64_t *changed, uint32_t *out)
{
	struct vd_hashdag *h = e->h;
	int cls;
	if (whole(e, l, ptr, x, y, z, changed, out, &cls)) {
		if (cls == INSIDE)
			*changed += diff_of(h, l, ptr, *out);
		return VD_OK;
	}
	if (l == h->levels - 2)
		return edit_leaf(e, ptr, x, y, z, changed, out);
	int64_t hs = (int64_t)1 << (h->levels - l - 1);
	uint32_t ch[8];
	uint8_t mask = 0;
	int same = 1;
	for (int c = 0; c < 8; c++) {
		uint32_t old = hd_child(h, l, ptr, c);
		int err = edit_node(e, l + 1, old, x + (c >> 2 & 1) * hs,
				    y + (c >> 1 & 1) * hs, z + (c & 1) * hs,
				    changed, &ch[c]);
		if (err)
			return err;
		if (ch[c] != old)
			same = 0;
		if (ch[c] != HD_EMPTY)
			mask |= (uint8_t)(1u << c);
	}
	if (same) {
		*out = ptr;
		return VD_OK;
	}
	if (!mask) {
		*out = HD_EMPTY;
		return VD_OK;
	}
	return hd_insert_inner(h, l, mask, ch, out);
}

static void run_job(void *ctx, size_t i, int worker)
{
	(void)worker;
	struct ectx *e = ctx;
	struct op_jobs *js = e->js;
	struct job *j = &js->v[i];
	j->err = edit_node(e, e->h->o.split_level, j->ptr, j->x, j->y, j->z,
			   &j->changed, &j->result);
	if (j->err)
		snprintf(j->detail, sizeof j->detail, "%s",
			 vd_error_detail());
}

/* The levels above the split: pass 0 collects the jobs in order, pass 1
 * consumes their results in the same order. */
static int edit_top(struct ectx *e, struct op_jobs *js, int pass, int l,
		    uint32_t ptr, int64_t x, int64_t y, int64_t z,
		    uint64_t *changed, uint32_t *out)
{
	struct vd_hashdag *h = e->h;
	if (l == h->o.split_level) {
		int64_t s = (int64_t)1 << (h->levels - l);
		if (classify(e, x, y, z, s) == OUTSIDE) {
			*out = ptr;
			return VD_OK;
		}
		if (pass == 0) {
			if (js->n == js->cap) {
				size_t cap = js->cap ? 2 * js->cap : 64;
				struct job *v = realloc(js->v, cap * sizeof *v);
				if (!v)
					return vd_fail(VD_ERR_NOMEM, "jobs");
				js->v = v;
				js->cap = cap;
			}
			struct job *j = &js->v[js->n++];
			memset(j, 0, sizeof *j);
			j->ptr = ptr;
			j->x = (uint32_t)x;
			j->y = (uint32_t)y;
			j->z = (uint32_t)z;
			*out = ptr;
			return VD_OK;
		}
		struct job *j = &js->v[js->next++];
		*changed += j->changed;
		*out = j->result;
		return VD_OK;
	}
	int cls;
	uint64_t dummy = 0;
	if (whole(e, l, ptr, x, y, z, pass ? changed : &dummy, out, &cls)) {
		if (pass && cls == INSIDE)
			*changed += diff_of(h, l, ptr, *out);
		return VD_OK;
	}
	int64_t hs = (int64_t)1 << (h->levels - l - 1);
	uint32_t ch[8];
	uint8_t mask = 0;
	int same = 1;
	for (int c = 0; c < 8; c++) {
		uint32_t old = hd_child(h, l, ptr, c);
		int err = edit_top(e, js, pass, l + 1, old,
				   x + (c >> 2 & 1) * hs, y + (c >> 1 & 1) * hs,
				   z + (c & 1) * hs, changed, &ch[c]);
		if (err)
			return err;
		if (ch[c] != old)
			same = 0;
		if (ch[c] != HD_EMPTY)
			mask |= (uint8_t)(1u << c);
	}
	if (pass == 0 || same) {
		*out = ptr;
		return VD_OK;
	}
	if (!mask) {
		*out = HD_EMPTY;
		return VD_OK;
	}
	return hd_insert_inner(h, l, mask, ch, out);
}

int vd_edit_op_check(const struct vd_hashdag *h, const struct vd_edit_op *op)
{
	int64_t n = (int64_t)1 << h->levels;
	static const char ax[] = "XYZ";
	if (op->kind == VD_EDIT_PAINT && !h->col)
		return vd_fail(VD_ERR_UNSUPPORTED, "cannot paint: the scene "
			       "has no colours (give edit --colours DIR, a "
			       "voxelize output with .col chunks, or a "
			       "colorize file)");
	if (op->kind == VD_EDIT_PAINT && !op->has_rgb)
		return vd_fail(VD_ERR_ARG, "paint needs a colour");
	if (op->has_rgb && !h->col)
		return vd_fail(VD_ERR_UNSUPPORTED, "a colour needs a scene "
			       "with colours (edit --colours)");
	if (op->shape == VD_SHAPE_SPHERE && op->kind != VD_EDIT_COPY) {
		for (int a = 0; a < 3; a++)
			if (!isfinite(op->c[a]) || op->c[a] < 0 ||
			    op->c[a] > (double)n)
				return vd_fail(VD_ERR_RANGE, "sphere centre %c "
					       "= %g outside the grid [0, %lld]",
					       ax[a], op->c[a], (long long)n);
		if (!isfinite(op->r) || op->r < 0 || op->r > 2.0 * (double)n)
			return vd_fail(VD_ERR_RANGE, "sphere radius %g outside "
				       "[0, %lld]", op->r, 2 * (long long)n);
		return VD_OK;
	}
	for (int a = 0; a < 3; a++) {
		if (op->lo[a] < 0 || op->hi[a] >= n || op->lo[a] > op->hi[a])
			return vd_fail(VD_ERR_RANGE, "box %c %lld..%lld outside "
				       "the grid [0, %lld] or reversed", ax[a],
				       (long long)op->lo[a],
				       (long long)op->hi[a], (long long)n - 1);
		if (op->kind == VD_EDIT_COPY &&
		    (op->dst[a] < 0 ||
		     op->dst[a] + op->hi[a] - op->lo[a] >= n))
			return vd_fail(VD_ERR_RANGE, "copy destination %c "
				       "%lld..%lld outside the grid [0, %lld]",
				       ax[a], (long long)op->dst[a],
				       (long long)(op->dst[a] + op->hi[a] -
						   op->lo[a]),
				       (long long)n - 1);
	}
	return VD_OK;
}

int vd_hashdag_apply(struct vd_hashdag *h, const struct vd_edit_op *op,
		     struct vd_edit_stats *st)
{
	double t0 = vd_seconds(), c0 = vd_cpu_seconds();
	int err = vd_edit_op_check(h, op);
	if (err)
		return err;
	uint64_t before[VD_MAX_LEVELS];
	for (int l = 0; l <= h->levels - 2; l++)
		before[l] = h->lv[l].nodes;
	if ((err = hd_make_full(h)))
		return err;
	struct {
		struct ectx e;
		struct op_jobs js;
	} c;
	memset(&c, 0, sizeof c);
	c.e.h = h;
	c.e.op = op;
	c.e.src_root = h->roots[h->cur];
	c.e.js = &c.js;
	for (int a = 0; a < 3; a++) {
		int64_t d = op->kind == VD_EDIT_COPY ? op->dst[a] - op->lo[a] : 0;
		c.e.box_lo[a] = op->lo[a] + d;
		c.e.box_hi[a] = op->hi[a] + d;
	}
	uint64_t changed = 0;
	uint32_t root = h->roots[h->cur], out = root;
	if (op->kind != VD_EDIT_PAINT) /* paint leaves the voxels alone */
		err = edit_top(&c.e, &c.js, 0, 0, root, 0, 0, 0, &changed,
			       &out);
	if (!err && c.js.n &&
	    vd_parallel_for(c.js.n, h->o.threads, run_job, &c.e))
		err = vd_fail(VD_ERR_INTERNAL, "thread pool");
	for (size_t i = 0; i < c.js.n && !err; i++)
		if (c.js.v[i].err)
			err = vd_fail(c.js.v[i].err, "%s", c.js.v[i].detail);
	if (!err && op->kind != VD_EDIT_PAINT)
		err = edit_top(&c.e, &c.js, 1, 0, root, 0, 0, 0, &changed,
			       &out);
	free(c.js.v);
	struct hd_cellcol **tab = NULL;
	uint64_t recoloured = 0, rebuilt = 0;
	if (!err && h->col)
		err = hd_colours_edit(h, op, root, out, &tab, &recoloured,
				      &rebuilt);
	if (op->kind == VD_EDIT_PAINT)
		changed = recoloured;
	if (!err)
		err = hd_push_root(h, out, tab);
	/* On failure the nodes appended so far stay (unreachable; gc drops
	 * them) and the scene is unchanged. */
	if (st) {
		memset(st, 0, sizeof *st);
		st->voxels_changed = err ? 0 : changed;
		st->colour_cells_rebuilt = err ? 0 : rebuilt;
		for (int l = 0; l <= h->levels - 2; l++)
			st->nodes_added[l] = h->lv[l].nodes - before[l];
		st->seconds = vd_seconds() - t0;
		st->cpu_seconds = vd_cpu_seconds() - c0;
		st->hash_bytes = vd_hashdag_memory_bytes(h);
	}
	return err;
}
