/* test_edit_colour.c - edit with colours (stages/lib/edit/colours.c)
 * against a brute-force dense map voxel -> colour with the same operations
 * applied voxel by voxel. Real coloured scenes (the textured spider, the
 * textured test scene) voxelized in several cells; random seeded sequences
 * of fill (with and without a colour), carve, copy and paint, undo, redo
 * and gc; every voxel's colour is looked up through the edited DAG with
 * vd_voxcount and compared with the map, in memory and after saving the
 * colour directory and reopening it as a colour source. Also: unchanged
 * cells are linked from the source, not rewritten; the memory budget;
 * paint without colours. */
#include "check.h"
#include "scene.h"
#include "voxdag.h"

#include <math.h>
#include <sys/stat.h>
#include <unistd.h>

static uint64_t test_rng = 2463534242ULL;
static uint64_t rnd(void)
{
	test_rng ^= test_rng << 13;
	test_rng ^= test_rng >> 7;
	test_rng ^= test_rng << 17;
	return test_rng;
}

/* The reference: a dense array over the grid, x-major (not Morton: the
 * order is the DAG's business), 0 for an empty voxel, else 1 << 24 | rgb. */
struct cref {
	int L;
	int64_t n;
	uint32_t *v;
};

static uint32_t *at(struct cref *r, int64_t x, int64_t y, int64_t z)
{
	return &r->v[(x * r->n + y) * r->n + z];
}

static uint32_t pack(const uint8_t *c)
{
	return 1u << 24 | (uint32_t)c[0] << 16 | (uint32_t)c[1] << 8 | c[2];
}

static const uint8_t grey[3] = VD_EDIT_DEFAULT_RGB;

/* Applies op voxel by voxel: the colour rules of schemas/edit-script.md. */
static void cref_apply(struct cref *r, const struct vd_edit_op *op)
{
	int64_t n = r->n;
	if (op->kind == VD_EDIT_COPY) {
		int64_t s[3];
		for (int a = 0; a < 3; a++)
			s[a] = op->hi[a] - op->lo[a] + 1;
		uint32_t *snap = malloc((size_t)(s[0] * s[1] * s[2]) * 4);
		for (int64_t i = 0; i < s[0]; i++)
			for (int64_t j = 0; j < s[1]; j++)
				for (int64_t k = 0; k < s[2]; k++)
					snap[(i * s[1] + j) * s[2] + k] =
						*at(r, op->lo[0] + i, op->lo[1] + j,
						    op->lo[2] + k);
		for (int64_t i = 0; i < s[0]; i++)
			for (int64_t j = 0; j < s[1]; j++)
				for (int64_t k = 0; k < s[2]; k++)
					*at(r, op->dst[0] + i, op->dst[1] + j,
					    op->dst[2] + k) =
						snap[(i * s[1] + j) * s[2] + k];
		free(snap);
		return;
	}
	for (int64_t x = 0; x < n; x++)
		for (int64_t y = 0; y < n; y++)
			for (int64_t z = 0; z < n; z++) {
				if (op->shape == VD_SHAPE_SPHERE) {
					double dx = x + 0.5 - op->c[0],
					       dy = y + 0.5 - op->c[1],
					       dz = z + 0.5 - op->c[2];
					if (dx * dx + dy * dy + dz * dz >
					    op->r * op->r)
						continue;
				} else if (x < op->lo[0] || x > op->hi[0] ||
					   y < op->lo[1] || y > op->hi[1] ||
					   z < op->lo[2] || z > op->hi[2]) {
					continue;
				}
				uint32_t *v = at(r, x, y, z);
				switch (op->kind) {
				case VD_EDIT_CARVE: *v = 0; break;
				case VD_EDIT_PAINT:
					if (*v)
						*v = pack(op->rgb);
					break;
				default: /* fill */
					if (op->has_rgb)
						*v = pack(op->rgb);
					else if (!*v)
						*v = pack(grey);
				}
			}
}

/* Every voxel of h's scene has r's colour, looked up through the DAG of
 * the scene with vd_voxcount in the colour array `rgb` (n colours), and
 * h has no voxel r lacks. Returns the voxels that differ. */
static uint64_t differ(const struct vd_dag *d, const uint8_t *rgb, uint64_t n,
		       struct cref *r)
{
	struct vd_voxcount vc;
	CHECK_EQ(vd_voxcount_from_dag(&vc, d), VD_OK);
	uint64_t bad = 0, set = 0;
	for (int64_t x = 0; x < r->n; x++)
		for (int64_t y = 0; y < r->n; y++)
			for (int64_t z = 0; z < r->n; z++) {
				uint32_t want = *at(r, x, y, z);
				uint64_t i;
				int has = vd_voxcount_index(&vc, r->L, (uint32_t)x,
							    (uint32_t)y,
							    (uint32_t)z, &i);
				if (!want) {
					bad += has != 0;
					continue;
				}
				set++;
				if (!has || i >= n || pack(rgb + 3 * i) != want) {
					if (bad < 3)
						fprintf(stderr, "voxel (%lld %lld "
							"%lld): %06x, got %s\n",
							(long long)x, (long long)y,
							(long long)z, want & 0xffffff,
							has ? "another" : "none");
					bad++;
				}
			}
	CHECK_EQ(set, n);
	CHECK_EQ(vc.voxels, n);
	vd_voxcount_release(&vc);
	return bad;
}

static uint64_t differ_h(const struct vd_hashdag *h, struct cref *r)
{
	struct vd_dag d;
	uint8_t *rgb = NULL;
	uint64_t n = 0, bad = ~0ull;
	CHECK_EQ(vd_hashdag_to_dag(h, &d), VD_OK);
	CHECK_EQ(vd_hashdag_colour_array(h, &rgb, &n), VD_OK);
	if (rgb)
		bad = differ(&d, rgb, n, r);
	free(rgb);
	vd_dag_release(&d);
	return bad;
}

/* Voxelizes `mesh` with colours at depth L in cells of level L0 into
 * `dir`; the root DAG of the scene into *d, the reference into *r. */
static int coloured_scene(const char *mesh, int L, int L0, const char *dir,
			  struct vd_dag *d, struct vd_transform *t,
			  struct cref *r)
{
	struct vd_voxelize_opts o = {.levels = L, .chunk_level = L0,
				     .mem_budget_bytes = 1ull << 30,
				     .threads = 2, .quiet = 1, .tool = "test",
				     .colours = 1};
	struct vd_voxelize_result res;
	int err = vd_voxelize_mesh(mesh, dir, &o, &res);
	CHECK_EQ(err, VD_OK);
	if (err) {
		fprintf(stderr, "%s\n", vd_error_detail());
		return 0;
	}
	CHECK(res.colours);
	uint8_t *rgb;
	uint64_t nc;
	struct vd_chunk_header h0;
	CHECK_EQ(vd_colour_chunks_load(dir, &rgb, &nc, &h0), VD_OK);
	*t = h0.transform;
	/* the cells' bricks in key order are the scene's (keys are global) */
	struct vd_svo all = {.levels = L};
	size_t cap = 1024;
	all.keys = malloc(cap * 8);
	all.masks = malloc(cap * 8);
	for (uint64_t cell = 0; cell < 1ull << 3 * L0; cell++) {
		char name[64], path[1024];
		vd_chunk_file_name(name, sizeof name, L0, cell, "svo");
		snprintf(path, sizeof path, "%s/%s", dir, name);
		if (access(path, R_OK))
			continue;
		struct vd_svo s;
		CHECK_EQ(vd_svo_load(&s, NULL, path), VD_OK);
		for (size_t i = 0; i < s.count; i++) {
			if (all.count == cap) {
				cap *= 2;
				all.keys = realloc(all.keys, cap * 8);
				all.masks = realloc(all.masks, cap * 8);
			}
			all.keys[all.count] = s.keys[i];
			all.masks[all.count++] = s.masks[i];
		}
		vd_svo_release(&s);
	}
	r->L = L;
	r->n = 1ll << L;
	r->v = calloc((size_t)(r->n * r->n * r->n), 4);
	uint64_t k = 0;
	for (size_t i = 0; i < all.count; i++)
		for (int b = 0; b < 64; b++)
			if (all.masks[i] >> b & 1) {
				uint32_t bx, by, bz, x, y, z;
				vd_morton3_decode(all.keys[i], &bx, &by, &bz);
				vd_morton3_decode((uint64_t)b, &x, &y, &z);
				*at(r, 4 * bx + x, 4 * by + y, 4 * bz + z) =
					pack(rgb + 3 * k++);
			}
	CHECK_EQ(k, nc);
	struct vd_dag_opts dop = {.threads = 2};
	CHECK_EQ(vd_dag_from_svo(d, &all, VD_KIND_DAG, &dop, NULL), VD_OK);
	vd_svo_release(&all);
	free(rgb);
	return 1;
}

static void random_op(struct vd_edit_op *op, int L)
{
	int64_t n = 1ll << L;
	memset(op, 0, sizeof *op);
	int t = (int)(rnd() % 12);
	op->kind = t < 3 ? VD_EDIT_FILL : t < 6 ? VD_EDIT_CARVE
		   : t < 8 ? VD_EDIT_COPY : VD_EDIT_PAINT;
	op->shape = op->kind != VD_EDIT_COPY && rnd() % 3 == 0 ? VD_SHAPE_SPHERE
							       : VD_SHAPE_BOX;
	if (op->kind == VD_EDIT_PAINT || (op->kind == VD_EDIT_FILL && rnd() & 1)) {
		op->has_rgb = 1;
		for (int a = 0; a < 3; a++)
			op->rgb[a] = (uint8_t)rnd();
	}
	if (op->shape == VD_SHAPE_SPHERE) {
		for (int a = 0; a < 3; a++)
			op->c[a] = (double)(rnd() % (uint64_t)(4 * n)) / 4.0;
		op->r = (double)(rnd() % 100) / 4.0;
		return;
	}
	int64_t maxs = rnd() % 8 == 0 ? n / 2 : 30;
	for (int a = 0; a < 3; a++) {
		int64_t s = 1 + (int64_t)(rnd() % (uint64_t)maxs);
		int64_t lo = (int64_t)(rnd() % (uint64_t)(n - s + 1));
		op->lo[a] = lo;
		op->hi[a] = lo + s - 1;
		op->dst[a] = (int64_t)(rnd() % (uint64_t)(n - s + 1));
		if (rnd() % 3 == 0) /* an offset of whole 16-cubes */
			op->dst[a] = lo + ((op->dst[a] - lo) / 16) * 16;
	}
}

/* src: 0 the voxelize directory, 1 a lossless auto file of colorize
 * (the colours read from it on demand); batch: colour_batch_bytes (1:
 * each segment its own batch, so a copy reads and drops its sources
 * between every two destination segments). */
static void random_colours(const char *mesh, int L, int L0, int nops,
			   uint64_t seed, int threads, int seg_log2, int src,
			   uint64_t batch)
{
	char dir[512], out[600];
	snprintf(dir, sizeof dir, "%s/src", test_tmpdir("test_edit_colour"));
	snprintf(out, sizeof out, "%s.out", dir);
	struct vd_dag d0 = {0};
	struct vd_transform t;
	struct cref r, r0;
	if (!coloured_scene(mesh, L, L0, dir, &d0, &t, &r))
		return;
	r0 = r;
	r0.v = malloc((size_t)(r.n * r.n * r.n) * 4);
	memcpy(r0.v, r.v, (size_t)(r.n * r.n * r.n) * 4);
	struct vd_hashdag_opts o = {.threads = threads,
				    .colour_segment_log2 = seg_log2,
				    .colour_batch_bytes = batch};
	struct vd_hashdag *h = NULL;
	CHECK_EQ(vd_hashdag_from_dag(&h, &d0, &t, &o), VD_OK);
	if (!h)
		return;
	char pack[700], packfile[800];
	snprintf(pack, sizeof pack, "%s.pack", dir);
	snprintf(packfile, sizeof packfile, "%s/colours.auto", pack);
	if (src) {
		struct vd_colorize_job cj = {.indir = dir, .outdir = pack,
					     .methods = 1 << VD_CPACK_AUTO,
					     .threads = 2, .quiet = 1,
					     .provenance = "test"};
		CHECK_EQ(vd_colorize_run(&cj), VD_OK);
	}
	CHECK_EQ(vd_hashdag_colours_open(h, src ? packfile : dir, NULL), VD_OK);
	CHECK_EQ(differ_h(h, &r), 0);
	test_rng = seed;
	uint64_t painted = 0;
	for (int i = 0; i < nops; i++) {
		struct vd_edit_op op;
		random_op(&op, L);
		struct vd_edit_stats st;
		int err = vd_hashdag_apply(h, &op, &st);
		CHECK_EQ(err, VD_OK);
		if (err) {
			fprintf(stderr, "op %d: %s\n", i, vd_error_detail());
			break;
		}
		cref_apply(&r, &op);
		if (op.kind == VD_EDIT_PAINT)
			painted += st.voxels_changed;
		if (i == nops / 2) /* gc keeping the history carries colours */
			CHECK_EQ(vd_hashdag_gc(h, 1, NULL), VD_OK);
		if (i % 10 == 9 || i == nops - 1) {
			uint64_t bad = differ_h(h, &r);
			CHECK_EQ(bad, 0);
			if (bad) {
				fprintf(stderr, "after op %d (kind %d shape %d)\n",
					i, op.kind, op.shape);
				break;
			}
		}
	}
	CHECK(painted > 0); /* the sequence did paint something */
	/* undo to the start gives the original colours, redo the edited */
	while (vd_hashdag_undo(h) == VD_OK)
		;
	CHECK_EQ(differ_h(h, &r0), 0);
	while (vd_hashdag_redo(h) == VD_OK)
		;
	CHECK_EQ(differ_h(h, &r), 0);
	CHECK_EQ(vd_hashdag_gc(h, 0, NULL), VD_OK);
	CHECK_EQ(differ_h(h, &r), 0);
	/* saved and read back as a colour source, through the saved DAG */
	CHECK_EQ(vd_hashdag_colours_save(h, out, "test"), VD_OK);
	struct vd_colour_source s;
	int err = vd_colour_source_open(&s, out);
	CHECK_EQ(err, VD_OK);
	if (!err) {
		struct vd_dag d;
		CHECK_EQ(vd_hashdag_to_dag(h, &d), VD_OK);
		uint8_t *rgb = malloc(3 * s.voxels + 1);
		for (uint64_t i = 0; i < s.voxels; i++)
			s.get(&s, i, rgb + 3 * i);
		CHECK_EQ(differ(&d, rgb, s.voxels, &r), 0);
		CHECK_EQ(s.cell_level, L0);
		free(rgb);
		vd_dag_release(&d);
		vd_colour_source_release(&s);
	}
	vd_hashdag_free(h);
	vd_dag_release(&d0);
	free(r.v);
	free(r0.v);
}

static void test_spider_random(void)
{
	random_colours("tests/data/spider/spider.obj", 7, 2, 150, 31337, 2, 0,
		       0, 0);
}

/* Cells cut into many segments (bricks, then 8-cubes): edits meet a few
 * segments of a cell and must splice their rebuilt colours between the
 * kept ones, drop segments they empty and insert the ones they fill. */
static void test_segments_random(void)
{
	random_colours("tests/data/spider/spider.obj", 7, 1, 150, 4242, 2, 2,
		       0, 0);
	random_colours("tests/data/textured/scene.obj", 7, 2, 120, 77, 1, 3,
		       0, 0);
}

static void test_textured_random(void)
{
	random_colours("tests/data/textured/scene.obj", 7, 1, 120, 99, 1, 0,
		       0, 0);
}

/* The colours read from a packed file of colorize rather than the colour
 * chunks, and edits cut into batches of one segment (copies reading and
 * dropping their sources between destination segments). */
static void test_sources_and_batches(void)
{
	random_colours("tests/data/spider/spider.obj", 7, 2, 120, 5150, 2, 3,
		       1, 0);
	random_colours("tests/data/spider/spider.obj", 7, 2, 120, 8086, 2, 3,
		       0, 1);
	random_colours("tests/data/textured/scene.obj", 7, 1, 100, 6502, 1, 2,
		       1, 1);
}

/* Non-constant blocks of the current scene's colours. */
static uint64_t mixed_blocks(const struct vd_hashdag_colour_stats *st)
{
	return st->mode_blocks[1] + st->mode_blocks[2] + st->mode_blocks[3] +
	       st->mode_blocks[4];
}

/* Uniform fills and paints of whole segments are held as constant blocks
 * of the auto codec (the colours stay compressed), and the colours follow
 * the brute-force reference through fill, paint, undo, redo and gc. The
 * spider at 2^7, cells 2^2, segments 8^3 (512 voxels, two blocks). */
static void test_uniform_fill_blocks(void)
{
	char dir[512];
	snprintf(dir, sizeof dir, "%s/uni", test_tmpdir("test_edit_colour"));
	struct vd_dag d0 = {0};
	struct vd_transform t;
	struct cref r, r0;
	if (!coloured_scene("tests/data/spider/spider.obj", 7, 2, dir, &d0, &t,
			    &r))
		return;
	size_t bytes = (size_t)(r.n * r.n * r.n) * 4;
	r0 = r;
	r0.v = malloc(bytes);
	memcpy(r0.v, r.v, bytes);
	struct vd_hashdag_opts o = {.threads = 2, .colour_segment_log2 = 3};
	struct vd_hashdag *h = NULL;
	CHECK_EQ(vd_hashdag_from_dag(&h, &d0, &t, &o), VD_OK);
	if (!h)
		return;
	CHECK_EQ(vd_hashdag_colours_open(h, dir, NULL), VD_OK);
	struct vd_hashdag_colour_stats s0, s1, s2;
	CHECK_EQ(vd_hashdag_colour_stats(h, &s0), VD_OK);
	/* loading decodes and encodes nothing: every colour is still only
	 * in the source, charged at a segment's bookkeeping */
	CHECK_EQ(s0.source_voxels, s0.voxels);
	CHECK_EQ(mixed_blocks(&s0) + s0.mode_blocks[0], 0);
	CHECK(s0.bytes <= 64 * s0.segments);

	/* one octant, aligned to segments: 512 segments of 512 voxels,
	 * 1024 constant blocks, and no block of another mode inside it */
	struct vd_edit_op op = {.kind = VD_EDIT_FILL, .shape = VD_SHAPE_BOX,
				.lo = {64, 64, 64}, .hi = {127, 127, 127},
				.has_rgb = 1, .rgb = {10, 200, 30}};
	CHECK_EQ(vd_hashdag_apply(h, &op, NULL), VD_OK);
	cref_apply(&r, &op);
	CHECK_EQ(differ_h(h, &r), 0);
	CHECK_EQ(vd_hashdag_colour_stats(h, &s1), VD_OK);
	CHECK(s1.mode_blocks[0] >= 2 * 512);
	CHECK(mixed_blocks(&s1) <= mixed_blocks(&s0));

	/* the whole grid painted: every block constant, 2 per segment */
	struct vd_edit_op paint = {.kind = VD_EDIT_PAINT, .shape = VD_SHAPE_BOX,
				   .lo = {0, 0, 0}, .hi = {127, 127, 127},
				   .has_rgb = 1, .rgb = {1, 2, 250}};
	CHECK_EQ(vd_hashdag_apply(h, &paint, NULL), VD_OK);
	cref_apply(&r, &paint);
	CHECK_EQ(differ_h(h, &r), 0);
	CHECK_EQ(vd_hashdag_colour_stats(h, &s2), VD_OK);
	CHECK_EQ(mixed_blocks(&s2), 0);
	CHECK_EQ(s2.voxels, s1.voxels);
	CHECK_EQ(s2.source_voxels, 0); /* every segment written */
	CHECK(s2.bytes <= 256 * s2.segments); /* no block data */

	/* and filled whole: 4096 segments of constant blocks */
	op.lo[0] = op.lo[1] = op.lo[2] = 0;
	CHECK_EQ(vd_hashdag_apply(h, &op, NULL), VD_OK);
	cref_apply(&r, &op);
	CHECK_EQ(vd_hashdag_colour_stats(h, &s2), VD_OK);
	CHECK_EQ(s2.voxels, 128 * 128 * 128);
	CHECK_EQ(s2.segments, 4096);
	CHECK_EQ(s2.mode_blocks[0], 8192);
	CHECK_EQ(mixed_blocks(&s2), 0);
	CHECK_EQ(differ_h(h, &r), 0);

	/* the history: back to the textured colours and forward again */
	while (vd_hashdag_undo(h) == VD_OK)
		;
	CHECK_EQ(differ_h(h, &r0), 0);
	CHECK_EQ(vd_hashdag_colour_stats(h, &s1), VD_OK);
	CHECK_EQ(mixed_blocks(&s1), mixed_blocks(&s0));
	CHECK_EQ(s1.source_voxels, s0.source_voxels);
	while (vd_hashdag_redo(h) == VD_OK)
		;
	CHECK_EQ(differ_h(h, &r), 0);
	CHECK_EQ(vd_hashdag_gc(h, 0, NULL), VD_OK);
	CHECK_EQ(differ_h(h, &r), 0);
	CHECK_EQ(vd_hashdag_colour_stats(h, &s1), VD_OK);
	CHECK_EQ(s1.mode_blocks[0], 8192);
	vd_hashdag_free(h);
	vd_dag_release(&d0);
	free(r.v);
	free(r0.v);
}

/* One small paint: only its cell is written, the others are links to the
 * source's files; paint without a colour source is refused. */
static void test_reuse_and_refusals(void)
{
	char dir[512], out[600];
	snprintf(dir, sizeof dir, "%s/src", test_tmpdir("test_edit_colour"));
	snprintf(out, sizeof out, "%s.out", dir);
	struct vd_dag d0 = {0};
	struct vd_transform t;
	struct cref r;
	const int L = 7, L0 = 2;
	if (!coloured_scene("tests/data/spider/spider.obj", L, L0, dir, &d0,
			    &t, &r))
		return;
	struct vd_hashdag *h = NULL;
	CHECK_EQ(vd_hashdag_from_dag(&h, &d0, &t, NULL), VD_OK);
	struct vd_edit_op op = {.kind = VD_EDIT_PAINT, .shape = VD_SHAPE_BOX,
				.has_rgb = 1, .rgb = {255, 0, 0}};
	/* the first set voxel's 3-cube */
	int64_t v0 = -1;
	for (int64_t i = 0; i < r.n * r.n * r.n && v0 < 0; i++)
		if (r.v[i])
			v0 = i;
	op.lo[0] = v0 / (r.n * r.n);
	op.lo[1] = v0 / r.n % r.n;
	op.lo[2] = v0 % r.n;
	for (int a = 0; a < 3; a++) {
		op.hi[a] = op.lo[a] + 2 < r.n ? op.lo[a] + 2 : r.n - 1;
		op.lo[a] = op.hi[a] - 2;
	}
	CHECK_EQ(vd_hashdag_apply(h, &op, NULL), VD_ERR_UNSUPPORTED);
	CHECK(strstr(vd_error_detail(), "no colours") != NULL);
	CHECK_EQ(vd_hashdag_colours_open(h, dir, NULL), VD_OK);
	struct vd_edit_stats st;
	CHECK_EQ(vd_hashdag_apply(h, &op, &st), VD_OK);
	cref_apply(&r, &op);
	CHECK(st.voxels_changed > 0);
	/* a 3-cube meets one to eight cells of the 64 */
	CHECK(st.colour_cells_rebuilt >= 1 && st.colour_cells_rebuilt <= 8);
	CHECK_EQ(differ_h(h, &r), 0);
	CHECK_EQ(vd_hashdag_colours_save(h, out, "test"), VD_OK);
	int shift = L - L0, linked = 0, written = 0, wrong = 0;
	for (uint64_t cell = 0; cell < 1ull << 3 * L0; cell++) {
		char name[64], path[1024];
		vd_chunk_file_name(name, sizeof name, L0, cell, "col");
		snprintf(path, sizeof path, "%s/%s", out, name);
		struct stat sb;
		if (stat(path, &sb))
			continue;
		uint32_t x, y, z;
		vd_morton3_decode(cell, &x, &y, &z);
		int touched = 1;
		int64_t c[3] = {x, y, z};
		for (int a = 0; a < 3; a++)
			if (op.hi[a] >> shift < c[a] || op.lo[a] >> shift > c[a])
				touched = 0;
		if (cell == vd_morton3((uint32_t)(v0 / (r.n * r.n) >> shift),
				       (uint32_t)(v0 / r.n % r.n >> shift),
				       (uint32_t)(v0 % r.n >> shift)))
			written++, wrong += sb.st_nlink != 1;
		else if (!touched)
			linked++, wrong += sb.st_nlink < 2;
	}
	CHECK(written >= 1);
	CHECK(linked >= 1);
	CHECK_EQ(wrong, 0);
	vd_hashdag_free(h);
	/* a load reads the colour chunks' headers only; the bricks beside a
	 * chunk are checked when its colours are first read: here the painted
	 * cell's SVO chunk is another cell's, so the paint fails, one clear
	 * error, and the scene keeps its colours */
	char bad[700], cmd[4096], name[64], other[64];
	snprintf(bad, sizeof bad, "%s.bad", dir);
	uint64_t pc = vd_morton3((uint32_t)(v0 / (r.n * r.n) >> shift),
				 (uint32_t)(v0 / r.n % r.n >> shift),
				 (uint32_t)(v0 % r.n >> shift));
	vd_chunk_file_name(name, sizeof name, L0, pc, "svo");
	other[0] = 0;
	for (uint64_t cell = 0; cell < 1ull << 3 * L0 && !other[0]; cell++) {
		char path[1024];
		vd_chunk_file_name(other, sizeof other, L0, cell, "svo");
		snprintf(path, sizeof path, "%s/%s", dir, other);
		if (cell == pc || access(path, R_OK))
			other[0] = 0;
	}
	snprintf(cmd, sizeof cmd, "rm -rf '%s' && cp -r '%s' '%s' && cp '%s/%s' "
		 "'%s/%s'", bad, dir, bad, dir, other, bad, name);
	CHECK(other[0] && system(cmd) == 0);
	CHECK_EQ(vd_hashdag_from_dag(&h, &d0, &t, NULL), VD_OK);
	CHECK_EQ(vd_hashdag_colours_open(h, bad, NULL), VD_OK);
	CHECK_EQ(vd_hashdag_apply(h, &op, NULL), VD_ERR_MISMATCH);
	CHECK(strstr(vd_error_detail(), "bricks of cell") != NULL);
	CHECK_EQ(vd_hashdag_undo(h), VD_ERR_RANGE); /* no root was pushed */
	vd_hashdag_free(h);
	vd_dag_release(&d0);
	free(r.v);
}

/* --mem-budget: loading needs the bucket tables; edits stop with
 * VD_ERR_BUDGET before the committed pages pass it, the scene unchanged. */
static void test_budget(void)
{
	char dir[512];
	snprintf(dir, sizeof dir, "%s/src", test_tmpdir("test_edit_colour"));
	struct vd_dag d0 = {0};
	struct vd_transform t;
	struct cref r;
	if (!coloured_scene("tests/data/spider/spider.obj", 7, 2, dir, &d0, &t,
			    &r))
		return;
	struct vd_hashdag *h = NULL;
	struct vd_hashdag_opts o = {.mem_budget_bytes = 4096};
	CHECK_EQ(vd_hashdag_from_dag(&h, &d0, &t, &o), VD_ERR_BUDGET);
	CHECK(strstr(vd_error_detail(), "bucket tables") != NULL);
	CHECK(strstr(vd_error_detail(), "--mem-budget of 4096") != NULL);
	CHECK(h == NULL);
	/* what the loaded scene takes, plus room for a few edits */
	struct vd_hashdag_opts big = {.threads = 1};
	CHECK_EQ(vd_hashdag_from_dag(&h, &d0, &t, &big), VD_OK);
	CHECK_EQ(vd_hashdag_colours_open(h, dir, NULL), VD_OK);
	uint64_t base = vd_hashdag_memory_bytes(h);
	vd_hashdag_free(h);
	h = NULL;
	o.mem_budget_bytes = base + (256 << 10);
	o.threads = 2;
	CHECK_EQ(vd_hashdag_from_dag(&h, &d0, &t, &o), VD_OK);
	if (!h)
		return;
	CHECK_EQ(vd_hashdag_colours_open(h, dir, NULL), VD_OK);
	test_rng = 7;
	int e = VD_OK, i;
	for (i = 0; i < 3000; i++) {
		struct vd_edit_op op;
		random_op(&op, 7);
		if ((e = vd_hashdag_apply(h, &op, NULL)))
			break;
		cref_apply(&r, &op);
	}
	CHECK_EQ(e, VD_ERR_BUDGET);
	CHECK(strstr(vd_error_detail(), "--mem-budget") != NULL);
	CHECK(vd_hashdag_memory_bytes(h) <= o.mem_budget_bytes);
	CHECK_EQ(differ_h(h, &r), 0); /* the failed edit changed nothing */
	/* gc needs room for the kept nodes beside the old tables: it may
	 * fail on the budget too, and then changes nothing either */
	e = vd_hashdag_gc(h, 0, NULL);
	CHECK(e == VD_OK || e == VD_ERR_BUDGET);
	CHECK_EQ(differ_h(h, &r), 0);
	vd_hashdag_free(h);
	vd_dag_release(&d0);
	free(r.v);
}

int main(void)
{
	RUN(test_reuse_and_refusals);
	RUN(test_spider_random);
	RUN(test_textured_random);
	RUN(test_segments_random);
	RUN(test_sources_and_batches);
	RUN(test_budget);
	RUN(test_uniform_fill_blocks);
	return CHECK_DONE();
}
