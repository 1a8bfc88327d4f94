/* test_edit.c - the HashDAG (stages/lib/edit) against an independent
 * brute-force voxel set: dense 4x4x4 bricks indexed by the tests' own bit
 * loop Morton code, edited voxel by voxel. Random seeded sequences of
 * fill, carve (boxes, spheres) and copy on real scenes; undo, redo, gc
 * (minimal afterwards: per-level counts equal svo-to-dag's), thread-count
 * independence, canonical save, full buckets and bad operations. */
#include "check.h"
#include "scene.h"
#include "voxdag.h"

#include <math.h>
#include <unistd.h>

/* xorshift, reproducible across runs */
static uint64_t test_rng = 88172645463325252ULL;
static uint64_t rnd(void)
{
	test_rng ^= test_rng << 13;
	test_rng ^= test_rng >> 7;
	test_rng ^= test_rng << 17;
	return test_rng;
}

/* Morton code by a bit loop (not the library's), x most significant. */
static uint64_t ref_morton(uint64_t x, uint64_t y, uint64_t z, int bits)
{
	uint64_t m = 0;
	for (int i = 0; i < bits; i++)
		m |= (x >> i & 1) << (3 * i + 2) | (y >> i & 1) << (3 * i + 1) |
		     (z >> i & 1) << (3 * i);
	return m;
}

/* The reference: a dense array of bricks, brick (bx, by, bz) at
 * ref_morton(bx, by, bz), voxel (i, j, k) inside at bit ref_morton(i, j, k). */
struct ref {
	int L;
	uint64_t nb;       /* bricks */
	uint64_t *b;
};

static void ref_init(struct ref *r, int L)
{
	r->L = L;
	r->nb = 1ull << 3 * (L - 2);
	r->b = calloc(r->nb, 8);
}

static int ref_get(const struct ref *r, int64_t x, int64_t y, int64_t z)
{
	uint64_t k = ref_morton((uint64_t)x >> 2, (uint64_t)y >> 2,
				(uint64_t)z >> 2, r->L - 2);
	return (int)(r->b[k] >> ref_morton((uint64_t)x & 3, (uint64_t)y & 3, (uint64_t)z & 3, 2) & 1);
}

static void ref_set(struct ref *r, int64_t x, int64_t y, int64_t z, int v)
{
	uint64_t k = ref_morton((uint64_t)x >> 2, (uint64_t)y >> 2,
				(uint64_t)z >> 2, r->L - 2);
	uint64_t bit = 1ull << ref_morton((uint64_t)x & 3, (uint64_t)y & 3, (uint64_t)z & 3, 2);
	r->b[k] = v ? r->b[k] | bit : r->b[k] & ~bit;
}

static void ref_from_svo(struct ref *r, const struct vd_svo *s)
{
	memset(r->b, 0, r->nb * 8);
	for (size_t i = 0; i < s->count; i++)
		r->b[s->keys[i]] = s->masks[i];
}

/* The reference's bricks as an SVO (keys are the dense indices). */
static void ref_to_svo(const struct ref *r, struct vd_svo *s)
{
	memset(s, 0, sizeof *s);
	s->levels = r->L;
	s->keys = malloc(8 * (r->nb + 1));
	s->masks = malloc(8 * (r->nb + 1));
	for (uint64_t k = 0; k < r->nb; k++)
		if (r->b[k]) {
			s->keys[s->count] = k;
			s->masks[s->count++] = r->b[k];
		}
}

/* Brute-force application of one operation, voxel by voxel; copies read
 * a snapshot of the source box first. Returns the voxels changed. */
static uint64_t ref_apply(struct ref *r, const struct vd_edit_op *op)
{
	uint64_t changed = 0;
	int64_t n = 1ll << r->L;
	if (op->kind == VD_EDIT_COPY) {
		int64_t sx = op->hi[0] - op->lo[0] + 1, sy = op->hi[1] - op->lo[1] + 1,
			sz = op->hi[2] - op->lo[2] + 1;
		uint8_t *snap = malloc((size_t)(sx * sy * sz));
		for (int64_t i = 0; i < sx; i++)
			for (int64_t j = 0; j < sy; j++)
				for (int64_t k = 0; k < sz; k++)
					snap[(i * sy + j) * sz + k] = (uint8_t)ref_get(
						r, op->lo[0] + i, op->lo[1] + j, op->lo[2] + k);
		for (int64_t i = 0; i < sx; i++)
			for (int64_t j = 0; j < sy; j++)
				for (int64_t k = 0; k < sz; k++) {
					int64_t x = op->dst[0] + i, y = op->dst[1] + j,
						z = op->dst[2] + k;
					int v = snap[(i * sy + j) * sz + k];
					changed += ref_get(r, x, y, z) != v;
					ref_set(r, x, y, z, v);
				}
		free(snap);
		return changed;
	}
	int64_t lo[3], hi[3];
	for (int a = 0; a < 3; a++) {
		if (op->shape == VD_SHAPE_BOX) {
			lo[a] = op->lo[a];
			hi[a] = op->hi[a];
		} else {
			lo[a] = (int64_t)floor(op->c[a] - op->r) - 1;
			hi[a] = (int64_t)ceil(op->c[a] + op->r) + 1;
			lo[a] = lo[a] < 0 ? 0 : lo[a];
			hi[a] = hi[a] >= n ? n - 1 : hi[a];
		}
	}
	int v = op->kind == VD_EDIT_FILL;
	for (int64_t x = lo[0]; x <= hi[0]; x++)
		for (int64_t y = lo[1]; y <= hi[1]; y++)
			for (int64_t z = lo[2]; z <= hi[2]; z++) {
				if (op->shape == VD_SHAPE_SPHERE) {
					double dx = x + 0.5 - op->c[0],
					       dy = y + 0.5 - op->c[1],
					       dz = z + 0.5 - op->c[2];
					if (dx * dx + dy * dy + dz * dz >
					    op->r * op->r)
						continue;
				}
				changed += ref_get(r, x, y, z) != v;
				ref_set(r, x, y, z, v);
			}
	return changed;
}

/* 1 if the HashDAG's current scene has exactly the voxels of r. */
static int same_voxels(const struct vd_hashdag *h, const struct ref *r)
{
	struct vd_svo s;
	if (vd_hashdag_to_svo(h, &s))
		return 0;
	uint64_t k = 0;
	int ok = 1;
	for (size_t i = 0; i < s.count && ok; i++) {
		for (; k < s.keys[i] && ok; k++)
			if (r->b[k]) {
				fprintf(stderr, "brick %llu missing\n",
					(unsigned long long)k);
				ok = 0;
			}
		if (ok && r->b[k] != s.masks[i]) {
			fprintf(stderr, "brick %llu: %016llx != %016llx\n",
				(unsigned long long)k,
				(unsigned long long)s.masks[i],
				(unsigned long long)r->b[k]);
			ok = 0;
		}
		k++;
	}
	for (; k < r->nb && ok; k++)
		if (r->b[k]) {
			fprintf(stderr, "brick %llu missing (tail)\n",
				(unsigned long long)k);
			ok = 0;
		}
	vd_svo_release(&s);
	return ok;
}

static void random_op(struct vd_edit_op *op, int L)
{
	int64_t n = 1ll << L;
	memset(op, 0, sizeof *op);
	int t = (int)(rnd() % 10);
	op->kind = t < 4 ? VD_EDIT_FILL : t < 8 ? VD_EDIT_CARVE : VD_EDIT_COPY;
	op->shape = op->kind != VD_EDIT_COPY && rnd() % 3 == 0 ? VD_SHAPE_SPHERE
							       : VD_SHAPE_BOX;
	if (op->shape == VD_SHAPE_SPHERE) {
		for (int a = 0; a < 3; a++)
			op->c[a] = (double)(rnd() % (uint64_t)(4 * n)) / 4.0;
		op->r = (double)(rnd() % 160) / 4.0;
		return;
	}
	/* mostly small boxes, sometimes aligned or large ones */
	int64_t maxs = rnd() % 8 == 0 ? n / 2 : 40;
	for (int a = 0; a < 3; a++) {
		int64_t s = 1 + (int64_t)(rnd() % (uint64_t)maxs);
		int64_t lo = (int64_t)(rnd() % (uint64_t)(n - s + 1));
		if (rnd() % 4 == 0) { /* aligned to 8 */
			lo &= ~7ll;
			s = (s + 7) & ~7ll;
			if (lo + s > n) s = n - lo;
		}
		op->lo[a] = lo;
		op->hi[a] = lo + s - 1;
	}
	for (int a = 0; a < 3; a++) {
		int64_t s = op->hi[a] - op->lo[a] + 1;
		op->dst[a] = (int64_t)(rnd() % (uint64_t)(n - s + 1));
		if (rnd() % 3 == 0) /* an offset of whole 16-cubes */
			op->dst[a] = op->lo[a] + (((op->dst[a] - op->lo[a]) / 16) * 16);
	}
}

static struct vd_hashdag *scene(const char *mesh, int L, struct ref *r,
				struct vd_dag *dag0,
				const struct vd_hashdag_opts *o)
{
	const char *dir = test_tmpdir("test_edit");
	struct vd_svo svo;
	struct vd_transform t;
	if (!test_voxelize_one(mesh, L, dir, &svo, &t))
		return NULL;
	ref_init(r, L);
	ref_from_svo(r, &svo);
	struct vd_dag_opts dopt = {.threads = 2};
	CHECK_EQ(vd_dag_from_svo(dag0, &svo, VD_KIND_DAG, &dopt, NULL), VD_OK);
	vd_svo_release(&svo);
	struct vd_hashdag *h = NULL;
	CHECK_EQ(vd_hashdag_from_dag(&h, dag0, &t, o), VD_OK);
	return h;
}

/* Per-level node counts of h after gc equal those of the minimal DAG of
 * the reference voxels, built by vd_dag_from_svo. */
static void check_minimal(const struct vd_hashdag *h, const struct ref *r)
{
	struct vd_svo s;
	ref_to_svo(r, &s);
	struct vd_dag d = {0};
	struct vd_dag_opts o = {.threads = 1};
	CHECK_EQ(vd_dag_from_svo(&d, &s, VD_KIND_DAG, &o, NULL), VD_OK);
	uint64_t stored[VD_MAX_LEVELS], reach[VD_MAX_LEVELS];
	vd_hashdag_counts(h, stored, reach);
	for (int l = 0; l <= r->L - 2; l++) {
		CHECK_EQ(stored[l], d.lv[l].nodes);
		CHECK_EQ(reach[l], d.lv[l].nodes);
	}
	vd_dag_release(&d);
	vd_svo_release(&s);
}

/* Two DAGs are the same in every array (what vd_dag_save writes, and the
 * bricks it is checked against). */
static int same_dag(const struct vd_dag *a, const struct vd_dag *b)
{
	if (a->kind != b->kind || a->levels != b->levels ||
	    a->chunk_level != b->chunk_level || a->voxels != b->voxels ||
	    a->cell_morton != b->cell_morton)
		return 0;
	int L = a->levels;
	for (int l = a->chunk_level; l < L; l++) {
		const struct vd_dag_level *x = &a->lv[l], *y = &b->lv[l];
		if (x->nodes != y->nodes || x->refs != y->refs ||
		    memcmp(x->mask, y->mask, x->nodes))
			return 0;
		if (l < L - 1 &&
		    (memcmp(x->first, y->first, 8 * (x->nodes + 1)) ||
		     memcmp(x->child, y->child, 4 * x->refs)))
			return 0;
	}
	if (a->lv[a->chunk_level].nodes && L >= 2 &&
	    memcmp(a->bricks, b->bricks, 8 * a->lv[L - 2].nodes))
		return 0;
	return 1;
}

/* The DAG saved from h is, array for array, the one svo-to-dag builds
 * from the reference voxels (the save walks the HashDAG; the reference
 * decodes and rebuilds). */
static void check_saved(const struct vd_hashdag *h, const struct ref *r)
{
	struct vd_svo rs;
	ref_to_svo(r, &rs);
	struct vd_dag got = {0}, want = {0};
	struct vd_dag_opts dop = {.threads = 1};
	CHECK_EQ(vd_hashdag_to_dag(h, &got), VD_OK);
	CHECK_EQ(vd_dag_from_svo(&want, &rs, VD_KIND_DAG, &dop, NULL), VD_OK);
	const struct vd_svo *sp = &rs;
	struct vd_dag_diff diff;
	CHECK_EQ(vd_dag_compare_svo(&got, &sp, 1, &diff), VD_OK);
	CHECK_EQ(diff.differing_voxels, 0);
	CHECK(same_dag(&got, &want));
	vd_dag_release(&got);
	vd_dag_release(&want);
	vd_svo_release(&rs);
}

static void random_sequence(const char *mesh, int L, int nops, uint64_t seed)
{
	struct ref r, r0;
	struct vd_dag dag0 = {0};
	struct vd_hashdag_opts o = {.threads = 2};
	test_rng = seed;
	struct vd_hashdag *h = scene(mesh, L, &r, &dag0, &o);
	if (!h)
		return;
	ref_init(&r0, L);
	memcpy(r0.b, r.b, r.nb * 8);
	CHECK(same_voxels(h, &r));
	int bad = 0;
	for (int i = 0; i < nops && !bad; i++) {
		struct vd_edit_op op;
		random_op(&op, L);
		struct vd_edit_stats st;
		CHECK_EQ(vd_hashdag_apply(h, &op, &st), VD_OK);
		uint64_t want = ref_apply(&r, &op);
		CHECK_EQ(st.voxels_changed, want);
		if (i % 20 == 19 || i == nops - 1) {
			int ok = same_voxels(h, &r);
			CHECK(ok);
			if (!ok) {
				fprintf(stderr, "L=%d op %d differs (kind %d "
					"shape %d)\n", L, i, op.kind, op.shape);
				bad = 1;
			}
		}
	}
	/* the saved DAG is the one svo-to-dag builds from the expected voxels */
	check_saved(h, &r);
	/* gc keeping the whole history, then undo to the start and redo */
	struct vd_edit_stats gst;
	CHECK_EQ(vd_hashdag_gc(h, 1, &gst), VD_OK);
	CHECK(same_voxels(h, &r));
	int undone = 0;
	while (vd_hashdag_undo(h) == VD_OK)
		undone++;
	CHECK_EQ(undone, nops);
	CHECK(same_voxels(h, &r0));
	check_saved(h, &r0);
	while (vd_hashdag_redo(h) == VD_OK)
		;
	CHECK(same_voxels(h, &r));
	/* gc keeping only the current root: same voxels, minimal tables */
	CHECK_EQ(vd_hashdag_gc(h, 0, &gst), VD_OK);
	CHECK(same_voxels(h, &r));
	check_minimal(h, &r);
	check_saved(h, &r);
	CHECK_EQ(vd_hashdag_undo(h), VD_ERR_RANGE);
	/* editing after gc still works (full nodes made again) */
	struct vd_edit_op op = {.kind = VD_EDIT_FILL, .shape = VD_SHAPE_BOX,
				.lo = {0, 0, 0}, .hi = {(1 << L) / 2 - 1, 7, 63}};
	CHECK_EQ(vd_hashdag_apply(h, &op, NULL), VD_OK);
	ref_apply(&r, &op);
	CHECK(same_voxels(h, &r));
	vd_hashdag_free(h);
	vd_dag_release(&dag0);
	free(r.b);
	free(r0.b);
}

static void test_random_bunny_8(void)
{
	random_sequence("tests/data/bunny.ply", 8, 300, 12345);
}

static void test_random_bunny_9(void)
{
	random_sequence("tests/data/bunny.ply", 9, 200, 777);
}

static void test_random_dragon_10(void)
{
	char path[600];
	snprintf(path, sizeof path, "%s/stanford_dragon.ply",
		 test_shared_data());
	if (access(path, R_OK)) {
		printf("SKIP %s absent\n", path);
		return;
	}
	random_sequence(path, 10, 100, 4242);
}

/* The same operations with 1 and 2 threads and different split levels
 * decode to the same voxels. */
static void test_threads_independent(void)
{
	struct ref r;
	struct vd_dag d0 = {0};
	struct vd_hashdag_opts o1 = {.threads = 1, .split_level = 1},
			       o2 = {.threads = 2, .split_level = 4};
	struct vd_hashdag *a = scene("tests/data/bunny.ply", 8, &r, &d0, &o1);
	if (!a)
		return;
	struct vd_hashdag *b = NULL;
	struct vd_transform t = *vd_hashdag_transform(a);
	CHECK_EQ(vd_hashdag_from_dag(&b, &d0, &t, &o2), VD_OK);
	test_rng = 99;
	for (int i = 0; i < 80; i++) {
		struct vd_edit_op op;
		random_op(&op, 8);
		struct vd_edit_stats sa, sb;
		CHECK_EQ(vd_hashdag_apply(a, &op, &sa), VD_OK);
		CHECK_EQ(vd_hashdag_apply(b, &op, &sb), VD_OK);
		CHECK_EQ(sa.voxels_changed, sb.voxels_changed);
	}
	struct vd_svo sa, sb;
	CHECK_EQ(vd_hashdag_to_svo(a, &sa), VD_OK);
	CHECK_EQ(vd_hashdag_to_svo(b, &sb), VD_OK);
	CHECK_EQ(sa.count, sb.count);
	if (sa.count == sb.count) {
		CHECK(!memcmp(sa.keys, sb.keys, 8 * sa.count));
		CHECK(!memcmp(sa.masks, sb.masks, 8 * sa.count));
	}
	vd_svo_release(&sa);
	vd_svo_release(&sb);
	vd_hashdag_free(a);
	vd_hashdag_free(b);
	vd_dag_release(&d0);
	free(r.b);
}

/* Full buckets fail cleanly and leave the scene as it was; gc makes room;
 * bad operations are refused. */
static void test_errors(void)
{
	struct ref r;
	struct vd_dag d0 = {0};
	struct vd_hashdag_opts big = {.threads = 2};
	struct vd_hashdag *h = scene("tests/data/bunny.ply", 8, &r, &d0, &big);
	if (!h)
		return;
	struct vd_transform t = *vd_hashdag_transform(h);
	/* a reservation too small to load the scene */
	struct vd_hashdag *tiny = NULL;
	struct vd_hashdag_opts to = {.buckets_log2 = 2, .bucket_words_log2 = 4};
	CHECK_EQ(vd_hashdag_from_dag(&tiny, &d0, &t, &to), VD_ERR_BUDGET);
	CHECK(strstr(vd_error_detail(), "full") != NULL);
	CHECK(tiny == NULL);
	/* a reservation the scene fits, where edits soon fill a bucket of
	 * the root levels */
	struct vd_hashdag_opts so = {.buckets_log2 = 16, .bucket_words_log2 = 5,
				     .threads = 2};
	struct vd_hashdag *s = NULL;
	int err = vd_hashdag_from_dag(&s, &d0, &t, &so);
	CHECK_EQ(err, VD_OK);
	if (!err) {
		struct ref cur;
		ref_init(&cur, 8);
		memcpy(cur.b, r.b, r.nb * 8);
		int i, e = VD_OK;
		test_rng = 5;
		for (i = 0; i < 2000; i++) {
			struct vd_edit_op op;
			random_op(&op, 8);
			if ((e = vd_hashdag_apply(s, &op, NULL)))
				break;
			ref_apply(&cur, &op);
		}
		CHECK_EQ(e, VD_ERR_BUDGET);
		CHECK(strstr(vd_error_detail(), "run gc") != NULL);
		CHECK(same_voxels(s, &cur)); /* the failed edit changed nothing */
		CHECK_EQ(vd_hashdag_gc(s, 0, NULL), VD_OK);
		CHECK(same_voxels(s, &cur));
		check_minimal(s, &cur);
		vd_hashdag_free(s);
		free(cur.b);
	}
	/* operations outside the grid, paint without colours */
	struct vd_edit_op op = {.kind = VD_EDIT_FILL, .shape = VD_SHAPE_BOX,
				.lo = {0, 0, 0}, .hi = {256, 3, 3}};
	CHECK_EQ(vd_hashdag_apply(h, &op, NULL), VD_ERR_RANGE);
	op.hi[0] = 3;
	op.lo[1] = -1;
	CHECK_EQ(vd_hashdag_apply(h, &op, NULL), VD_ERR_RANGE);
	op.lo[1] = 0;
	op.kind = VD_EDIT_COPY;
	op.dst[0] = 254;
	CHECK_EQ(vd_hashdag_apply(h, &op, NULL), VD_ERR_RANGE);
	op.kind = VD_EDIT_PAINT;
	CHECK_EQ(vd_hashdag_apply(h, &op, NULL), VD_ERR_UNSUPPORTED);
	CHECK(strstr(vd_error_detail(), "colour") != NULL);
	CHECK_EQ(vd_hashdag_undo(h), VD_ERR_RANGE);
	CHECK_EQ(vd_hashdag_redo(h), VD_ERR_RANGE);
	CHECK(same_voxels(h, &r));
	/* an SSVDAG is refused */
	struct vd_dag ss = {0};
	struct vd_svo sv;
	ref_to_svo(&r, &sv);
	struct vd_dag_opts dop = {.threads = 1};
	CHECK_EQ(vd_dag_from_svo(&ss, &sv, VD_KIND_SSVDAG, &dop, NULL), VD_OK);
	struct vd_hashdag *x = NULL;
	CHECK_EQ(vd_hashdag_from_dag(&x, &ss, &t, NULL), VD_ERR_WRONG_KIND);
	vd_dag_release(&ss);
	vd_svo_release(&sv);
	vd_hashdag_free(h);
	vd_dag_release(&d0);
	free(r.b);
}

/* The statistics of copies (what bench_edit.sh prints): voxels changed
 * equal the brute force's count, for boxes of the scene copied onto the
 * scene at offsets aligned to nothing, to 4, to 64, and an emptied box
 * copied over the scene (every destination voxel cleared). */
static void test_copy_stats(void)
{
	struct ref r;
	struct vd_dag d0 = {0};
	struct vd_hashdag_opts o = {.threads = 2};
	struct vd_hashdag *h = scene("tests/data/bunny.ply", 8, &r, &d0, &o);
	if (!h)
		return;
	static const int64_t box[][9] = {
		{100, 100, 100, 139, 139, 139, 10, 150, 77},  /* unaligned */
		{64, 64, 64, 127, 127, 127, 0, 128, 64},      /* aligned 64 */
		{80, 40, 120, 131, 91, 171, 84, 44, 124},     /* aligned 4 */
		{0, 0, 0, 255, 255, 127, 0, 0, 128},          /* half the grid */
	};
	uint64_t total = 0;
	for (size_t i = 0; i < sizeof box / sizeof box[0]; i++) {
		struct vd_edit_op op = {.kind = VD_EDIT_COPY,
					.shape = VD_SHAPE_BOX};
		for (int a = 0; a < 3; a++) {
			op.lo[a] = box[i][a];
			op.hi[a] = box[i][3 + a];
			op.dst[a] = box[i][6 + a];
		}
		struct vd_edit_stats st;
		CHECK_EQ(vd_hashdag_apply(h, &op, &st), VD_OK);
		uint64_t want = ref_apply(&r, &op);
		CHECK_EQ(st.voxels_changed, want);
		total += want;
	}
	CHECK(total > 0);
	/* an emptied source: the copy clears what was at the destination */
	struct vd_edit_op carve = {.kind = VD_EDIT_CARVE, .shape = VD_SHAPE_BOX,
				   .lo = {100, 100, 100}, .hi = {150, 150, 150}};
	CHECK_EQ(vd_hashdag_apply(h, &carve, NULL), VD_OK);
	ref_apply(&r, &carve);
	struct vd_edit_op cp = {.kind = VD_EDIT_COPY, .shape = VD_SHAPE_BOX,
				.lo = {100, 100, 100}, .hi = {150, 150, 150},
				.dst = {60, 30, 90}};
	struct vd_edit_stats st;
	CHECK_EQ(vd_hashdag_apply(h, &cp, &st), VD_OK);
	uint64_t want = ref_apply(&r, &cp);
	CHECK_EQ(st.voxels_changed, want);
	CHECK(want > 0);
	CHECK(same_voxels(h, &r));
	vd_hashdag_free(h);
	vd_dag_release(&d0);
	free(r.b);
}

/* An empty scene: fill, carve everything back, undo. */
static void test_empty_scene(void)
{
	struct vd_dag d = {0};
	struct vd_svo s = {.levels = 6};
	s.keys = malloc(8);
	s.masks = malloc(8);
	struct vd_dag_opts dop = {.threads = 1};
	CHECK_EQ(vd_dag_from_svo(&d, &s, VD_KIND_DAG, &dop, NULL), VD_OK);
	struct vd_transform t = {.voxel_size = 1};
	struct vd_hashdag *h = NULL;
	CHECK_EQ(vd_hashdag_from_dag(&h, &d, &t, NULL), VD_OK);
	if (h) {
		struct ref r;
		ref_init(&r, 6);
		struct vd_edit_op op = {.kind = VD_EDIT_FILL,
					.shape = VD_SHAPE_BOX,
					.hi = {63, 63, 63}};
		struct vd_edit_stats st;
		CHECK_EQ(vd_hashdag_apply(h, &op, &st), VD_OK);
		CHECK_EQ(st.voxels_changed, 64 * 64 * 64);
		ref_apply(&r, &op);
		CHECK(same_voxels(h, &r));
		/* the whole grid is one full node per level */
		uint64_t reach[VD_MAX_LEVELS];
		vd_hashdag_counts(h, NULL, reach);
		for (int l = 0; l <= 4; l++)
			CHECK_EQ(reach[l], 1);
		op.kind = VD_EDIT_CARVE;
		op.shape = VD_SHAPE_SPHERE;
		op.c[0] = op.c[1] = op.c[2] = 32;
		op.r = 20;
		CHECK_EQ(vd_hashdag_apply(h, &op, &st), VD_OK);
		CHECK_EQ(st.voxels_changed, ref_apply(&r, &op));
		CHECK(same_voxels(h, &r));
		CHECK_EQ(vd_hashdag_undo(h), VD_OK);
		CHECK_EQ(vd_hashdag_undo(h), VD_OK);
		struct vd_svo e;
		CHECK_EQ(vd_hashdag_to_svo(h, &e), VD_OK);
		CHECK_EQ(e.count, 0);
		vd_svo_release(&e);
		free(r.b);
	}
	vd_hashdag_free(h);
	vd_dag_release(&d);
	vd_svo_release(&s);
}

/* A copy of `in` where one node of level l that is referenced at least
 * twice has a duplicate (appended last) taking over its last reference:
 * a valid DAG that is not minimal. 0 if no node of l is shared. */
static int dag_with_duplicate(const struct vd_dag *in, int l,
			      struct vd_dag *out)
{
	int L = in->levels;
	const struct vd_dag_level *up = &in->lv[l - 1];
	uint32_t *seen = calloc(in->lv[l].nodes, 4);
	uint64_t dup = UINT64_MAX, last = 0;
	for (uint64_t j = 0; j < up->refs; j++)
		if (++seen[up->child[j]] == 2 && dup == UINT64_MAX)
			dup = up->child[j];
	free(seen);
	if (dup == UINT64_MAX)
		return 0;
	for (uint64_t j = 0; j < up->refs; j++)
		if (up->child[j] == dup)
			last = j;
	*out = *in;
	for (int k = 0; k < L; k++) {
		const struct vd_dag_level *a = &in->lv[k];
		struct vd_dag_level *b = &out->lv[k];
		uint64_t extra = k == l, xr = k == l && k < L - 1 ?
			(uint64_t)__builtin_popcount(a->mask[dup]) : 0;
		b->nodes = a->nodes + extra;
		b->refs = a->refs + xr;
		b->mask = malloc(b->nodes);
		memcpy(b->mask, a->mask, a->nodes);
		if (extra)
			b->mask[a->nodes] = a->mask[dup];
		b->first = NULL;
		b->child = NULL;
		b->refl = NULL;
		if (k == L - 1)
			continue;
		b->first = malloc(8 * (b->nodes + 1));
		memcpy(b->first, a->first, 8 * (a->nodes + 1));
		b->child = malloc(4 * (b->refs ? b->refs : 1));
		memcpy(b->child, a->child, 4 * a->refs);
		if (extra) {
			memcpy(b->child + a->refs, a->child + a->first[dup],
			       4 * xr);
			b->first[b->nodes] = b->refs;
		}
	}
	out->lv[l - 1].child[last] = (uint32_t)in->lv[l].nodes;
	uint64_t nb = out->lv[L - 2].nodes;
	out->bricks = malloc(8 * nb);
	memcpy(out->bricks, in->bricks, 8 * in->lv[L - 2].nodes);
	if (l == L - 2)
		out->bricks[nb - 1] = in->bricks[dup];
	return 1;
}

static int same_file(const char *a, const char *b)
{
	FILE *f = fopen(a, "rb"), *g = fopen(b, "rb");
	int same = f && g, x = 0, y = 0;
	while (same && (x = getc(f)) == (y = getc(g)) && x != EOF)
		;
	same = same && x == y;
	if (f)
		fclose(f);
	if (g)
		fclose(g);
	return same;
}

/* Load then save without edits gives the input back: the DAG arrays, and
 * the chunk file byte for byte (same provenance). A valid chunk that is
 * not minimal (a duplicated node on a level) loads into the same tables
 * and saves as the minimal DAG. */
static void test_load_save_identity(void)
{
	int L = 8;
	struct ref r;
	struct vd_dag d0 = {0};
	struct vd_hashdag_opts o = {.threads = 1};
	struct vd_hashdag *h = scene("tests/data/bunny.ply", L, &r, &d0, &o);
	if (!h)
		return;
	struct vd_dag got = {0};
	CHECK_EQ(vd_hashdag_to_dag(h, &got), VD_OK);
	CHECK(same_dag(&got, &d0));
	vd_dag_release(&got);
	const char *dir = test_tmpdir("test_edit_identity");
	char in[600], out[600];
	snprintf(in, sizeof in, "%s/in.dag", dir);
	snprintf(out, sizeof out, "%s/out.dag", dir);
	const struct vd_transform *t = vd_hashdag_transform(h);
	CHECK_EQ(vd_dag_save(&d0, t, in, "test"), VD_OK);
	struct vd_hashdag *h2 = NULL;
	CHECK_EQ(vd_hashdag_load(&h2, in, &o), VD_OK);
	if (h2) {
		CHECK_EQ(vd_hashdag_save(h2, out, "test"), VD_OK);
		CHECK(same_file(in, out));
	}
	vd_hashdag_free(h2);
	uint64_t st0[VD_MAX_LEVELS], st1[VD_MAX_LEVELS];
	vd_hashdag_counts(h, st0, NULL);
	int tried = 0;
	for (int l = 1; l <= L - 2; l++) {
		struct vd_dag dd;
		if (!dag_with_duplicate(&d0, l, &dd))
			continue;
		tried++;
		CHECK_EQ(vd_dag_validate(&dd), VD_OK);
		struct vd_hashdag *h3 = NULL;
		CHECK_EQ(vd_hashdag_from_dag(&h3, &dd, t, &o), VD_OK);
		if (h3) {
			vd_hashdag_counts(h3, st1, NULL);
			for (int k = 0; k <= L - 2; k++)
				CHECK_EQ(st1[k], st0[k]);
			CHECK_EQ(vd_hashdag_to_dag(h3, &got), VD_OK);
			CHECK(same_dag(&got, &d0));
			vd_dag_release(&got);
		}
		vd_hashdag_free(h3);
		vd_dag_release(&dd);
	}
	CHECK(tried >= 3);
	vd_hashdag_free(h);
	vd_dag_release(&d0);
	free(r.b);
}

int main(void)
{
	RUN(test_load_save_identity);
	RUN(test_empty_scene);
	RUN(test_random_bunny_8);
	RUN(test_random_bunny_9);
	RUN(test_threads_independent);
	RUN(test_errors);
	RUN(test_copy_stats);
	RUN(test_random_dragon_10);
	return CHECK_DONE();
}
