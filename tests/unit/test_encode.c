/* test_encode.c - the four SymVox encodings: golden bytes worked out by
 * hand, pointer and brick bit layouts, round trips on real meshes against
 * the voxelizer's SVO chunks, truncated table rows against direct builds at
 * the lower depth, reported sizes against file sizes, edge cases, range
 * errors and damaged files. */
#include "check.h"
#include "scene.h"
/* the DAG tests' grid helpers; this test uses only some of them */
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wunused-variable"
#include "dag_test_util.h"
#pragma GCC diagnostic pop
#include "encode/encode_internal.h"
#include "enc_test_util.h"
#include "voxdag.h"

#include <sys/stat.h>

static struct vd_dag_opts opts = {1, 0, NULL};

/* ------------------------------------------------------------ helpers */

static uint64_t file_size(const char *path)
{
	struct stat st;
	return stat(path, &st) ? 0 : (uint64_t)st.st_size;
}

static const struct vd_dag *dag_for(int f, const struct vd_dag *d,
				    const struct vd_dag *s)
{
	return vd_enc_format_symmetric(f) ? s : d;
}

/* ----------------------------------------------- pointers and bricks */

static void test_pointer_packing(void)
{
	uint16_t w[2];
	/* 16-bit: address 5, reflected along X (our bit 2 -> bit 13) */
	CHECK_EQ(vd__enc_pack_ptr(5, 4, w), 1);
	CHECK_EQ(w[0], 0x2005);
	/* along Y (bit 1 -> 14) and Z (bit 0 -> 15) */
	CHECK_EQ(vd__enc_pack_ptr(8191, 2, w), 1);
	CHECK_EQ(w[0], 0x5fff);
	CHECK_EQ(vd__enc_pack_ptr(0, 1, w), 1);
	CHECK_EQ(w[0], 0x8000);
	/* 32-bit from 2^13 on: high half first, mirrors at bits 29-31 */
	CHECK_EQ(vd__enc_pack_ptr(8192, 4, w), 2);
	CHECK_EQ(w[0], 0x2000);
	CHECK_EQ(w[1], 0x2000);
	/* address bit 29 goes to the tag; X and Z mirrored */
	CHECK_EQ(vd__enc_pack_ptr((1u << 29) | 0x12345, 5, w), 3);
	CHECK_EQ(w[0], 0xa001);
	CHECK_EQ(w[1], 0x2345);
	CHECK_EQ(vd__enc_pack_ptr((1u << 30) - 1, 0, w), 3);
	CHECK_EQ(w[0], 0x1fff);
	CHECK_EQ(w[1], 0xffff);
	/* every reflection and a spread of addresses round-trip */
	static const uint32_t addrs[] = {0, 1, 8191, 8192, 65535, 65536,
					 (1u << 29) - 1, 1u << 29,
					 (1u << 30) - 1};
	for (size_t i = 0; i < sizeof addrs / sizeof *addrs; i++)
		for (unsigned m = 0; m < 8; m++) {
			unsigned tag = vd__enc_pack_ptr(addrs[i], m, w), mm = 9;
			CHECK_EQ(tag, addrs[i] < 8192 ? 1 :
				 addrs[i] < (1u << 29) ? 2 : 3);
			CHECK_EQ(vd__enc_unpack_ptr(tag, w, &mm), addrs[i]);
			CHECK_EQ(mm, m);
		}
}

static void test_brick_layout(void)
{
	/* (x, y, z) -> SymVox bit 16x + 4y + z, worked out by hand */
	static const struct { uint32_t x, y, z, bit; } v[] = {
		{0, 0, 0, 0}, {0, 0, 1, 1}, {0, 0, 2, 2}, {0, 1, 0, 4},
		{1, 0, 0, 16}, {2, 0, 0, 32}, {3, 0, 0, 48}, {1, 2, 3, 27},
		{3, 3, 3, 63},
	};
	for (size_t i = 0; i < sizeof v / sizeof *v; i++) {
		uint64_t morton = 1ull << ref_morton(v[i].x, v[i].y, v[i].z, 2);
		CHECK_EQ(vd__enc_brick_to_symvox(morton), 1ull << v[i].bit);
		CHECK_EQ(vd__enc_brick_from_symvox(1ull << v[i].bit), morton);
	}
	/* every voxel on its own, and bricks as the union of their voxels
	 * (the SymVox bit of Morton bit 4x' + 2y' + z' with x' = x & 1...) */
	uint64_t one[64];
	for (unsigned b = 0; b < 64; b++) {
		uint32_t x = (b >> 4 & 2) | (b >> 2 & 1), y = (b >> 3 & 2) | (b >> 1 & 1),
			 z = (b >> 2 & 2) | (b & 1);
		CHECK_EQ(ref_morton(x, y, z, 2), b);
		one[b] = vd__enc_brick_to_symvox(1ull << b);
		CHECK_EQ(one[b], 1ull << (16 * x + 4 * y + z));
	}
	for (int i = 0; i < 1000; i++) {
		uint64_t b = rnd(), want = 0;
		for (unsigned k = 0; k < 64; k++)
			if (b >> k & 1) want |= one[k];
		CHECK_EQ(vd__enc_brick_to_symvox(b), want);
		CHECK_EQ(vd__enc_brick_from_symvox(vd__enc_brick_to_symvox(b)), b);
	}
}

/* ------------------------------------------------------- golden bytes */

/* The hand-made scene, 8^3 (L = 3): voxels A (0,0,0), C (0,0,4) and
 * B (7,0,0). Root children 0 (A), 1 (C) and 4 (B); A and C are the same
 * brick, B is A mirrored along X.
 *
 * Plain DAG, in this node order: level 1 = {B, A}, level 2 = {0x10, 0x01}.
 * SSVDAG: one brick, the canonical (3,3,3) voxel (the largest of the 8
 * reflections); A and C are it reflected by XYZ (7), B by YZ (3); level 2
 * = {0x80}. */
static uint8_t g_mask0[] = {0x13}, g_mask1[] = {0x10, 0x01},
	       g_mask2[] = {0x10, 0x01};
static uint64_t g_first0[] = {0, 3}, g_first1[] = {0, 1, 2};
static uint32_t g_child0[] = {1, 1, 0}, g_child1[] = {0, 1};
static uint64_t g_bricks[] = {1ull << 36, 1ull};

static uint8_t s_mask0[] = {0x13}, s_mask1[] = {0x80}, s_mask2[] = {0x80};
static uint64_t s_first0[] = {0, 3}, s_first1[] = {0, 1};
static uint32_t s_child0[] = {0, 0, 0}, s_child1[] = {0};
static uint8_t s_refl0[] = {7, 7, 3}, s_refl1[] = {0};
static uint64_t s_bricks[] = {1ull << 63};

static void golden_dags(struct vd_dag *d, struct vd_dag *s)
{
	memset(d, 0, sizeof *d);
	d->kind = VD_KIND_DAG;
	d->levels = 3;
	d->voxels = 3;
	d->lv[0] = (struct vd_dag_level){1, 3, g_mask0, g_first0, g_child0, NULL};
	d->lv[1] = (struct vd_dag_level){2, 2, g_mask1, g_first1, g_child1, NULL};
	d->lv[2] = (struct vd_dag_level){2, 0, g_mask2, NULL, NULL, NULL};
	d->bricks = g_bricks;
	memset(s, 0, sizeof *s);
	s->kind = VD_KIND_SSVDAG;
	s->levels = 3;
	s->voxels = 3;
	s->lv[0] = (struct vd_dag_level){1, 3, s_mask0, s_first0, s_child0, s_refl0};
	s->lv[1] = (struct vd_dag_level){1, 1, s_mask1, s_first1, s_child1, s_refl1};
	s->lv[2] = (struct vd_dag_level){1, 0, s_mask2, NULL, NULL, NULL};
	s->bricks = s_bricks;
}

/* Little-endian byte writers for the expected files. */
struct bytes {
	uint8_t b[512];
	size_t n;
};
static void b32(struct bytes *x, uint32_t v)
{
	for (int i = 0; i < 4; i++) x->b[x->n++] = (uint8_t)(v >> 8 * i);
}
static void b16(struct bytes *x, uint16_t v)
{
	x->b[x->n++] = (uint8_t)v;
	x->b[x->n++] = (uint8_t)(v >> 8);
}
static void b8(struct bytes *x, uint8_t v)
{
	x->b[x->n++] = v;
}

/* bbox (-1,-2,-3)..(1,2,3), side 6: float32 bit patterns by hand */
static void golden_header(struct bytes *x, uint32_t nodes)
{
	static const uint32_t f[7] = {0xbf800000, 0xc0000000, 0xc0400000,
				      0x3f800000, 0x40000000, 0x40400000,
				      0x40c00000};
	for (int i = 0; i < 7; i++) b32(x, f[i]);
	b32(x, 3);     /* levels */
	b32(x, nodes);
}

static void expected_file(int f, struct bytes *x)
{
	x->n = 0;
	switch (f) {
	case VD_ENC_SVDAG: {
		golden_header(x, 5);
		b32(x, 8);  /* first leaf word */
		b32(x, 10); /* words */
		/* root: mask, pointers for children 4 (B), 1 (A), 0 (A) */
		static const uint32_t w[10] = {0x13, 4, 6, 6, 0x10, 8, 0x01, 9,
					       0x10, 0x01};
		for (int i = 0; i < 10; i++) b32(x, w[i]);
		break;
	}
	case VD_ENC_USSVDAG: {
		golden_header(x, 3);
		b32(x, 6);
		b32(x, 7);
		/* mirrorZ 0x13 (slots 0,1,4), mirrorY 0x13, mirrorX 0x03 */
		static const uint32_t w[7] = {0x13130313, 4, 4, 4, 0x80, 6, 0x80};
		for (int i = 0; i < 7; i++) b32(x, w[i]);
		break;
	}
	case VD_ENC_ESVDAG:
		golden_header(x, 5);
		b32(x, 4);          /* inner words */
		b16(x, 0x0105);     /* tags 01 for children 0, 1, 4 */
		b16(x, 0x0001);     /* child 4: B, referenced once: brick 1 */
		b16(x, 0x0000);     /* child 1: A, referenced twice: brick 0 */
		b16(x, 0x0000);     /* child 0: A */
		b32(x, 16);         /* leaf bytes */
		for (int i = 0; i < 8; i++) b8(x, i == 0 ? 1 : 0); /* A: bit 0 */
		for (int i = 0; i < 8; i++) b8(x, i == 6 ? 1 : 0); /* B: bit 48 */
		b32(x, 1);          /* level offsets */
		b32(x, 0);
		break;
	case VD_ENC_SSVDAG:
		golden_header(x, 3);
		b32(x, 4);
		b16(x, 0x0105);
		b16(x, 0xc000);     /* child 4: brick 0 mirrored Y, Z */
		b16(x, 0xe000);     /* child 1: mirrored X, Y, Z */
		b16(x, 0xe000);     /* child 0 */
		b32(x, 8);
		for (int i = 0; i < 8; i++) b8(x, i == 7 ? 0x80 : 0); /* bit 63 */
		b32(x, 1);
		b32(x, 0);
		break;
	}
}

static void test_golden_files(void)
{
	struct vd_dag d, s;
	golden_dags(&d, &s);
	CHECK_EQ(vd_dag_validate(&d), VD_OK);
	CHECK_EQ(vd_dag_validate(&s), VD_OK);
	struct vd_transform t = {{-1, -2, -3}, {1, 2, 3}, 6, {0, 0, 0}, 0.75};
	const char *dir = test_tmpdir("test_encode_golden");
	/* the voxels, from coordinates */
	struct grid g;
	grid_init(&g, 3);
	*gv(&g, 0, 0, 0) = *gv(&g, 0, 0, 4) = *gv(&g, 7, 0, 0) = 1;
	struct vd_svo svo;
	grid_to_svo(&g, 0, 0, &svo);
	for (int f = 0; f < VD_ENC_COUNT_; f++) {
		struct vd_enc e;
		CHECK_EQ(vd_enc_build(&e, f, dag_for(f, &d, &s), &t), VD_OK);
		char path[700];
		snprintf(path, sizeof path, "%s/golden.%s", dir, vd_enc_format_name(f));
		CHECK_EQ(vd_enc_save(&e, path), VD_OK);
		vd_enc_release(&e);
		struct bytes x;
		expected_file(f, &x);
		size_t n = 0;
		uint8_t *got = read_all(path, &n);
		CHECK_EQ(n, x.n);
		CHECK(got && n == x.n && !memcmp(got, x.b, n));
		if (got && n == x.n)
			for (size_t i = 0; i < n; i++)
				if (got[i] != x.b[i]) {
					fprintf(stderr, "  %s: byte %zu is %02x, "
						"expected %02x\n", path, i, got[i],
						x.b[i]);
					break;
				}
		/* the reader gives the voxels back */
		CHECK_EQ(vd_enc_load(&e, path, -1), VD_OK);
		CHECK(enc_equals_svo(&e, &svo));
		CHECK_EQ(e.bbox_min[2], -3.0f);
		CHECK_EQ(e.root_side, 6.0f);
		vd_enc_release(&e);
		/* every cut of the file is truncated, one more byte trailing */
		for (size_t k = 0; got && k < n; k++) {
			int err = vd_enc_parse(&e, got, k, f);
			if (err != VD_ERR_TRUNCATED) {
				CHECK_EQ(err, VD_ERR_TRUNCATED);
				fprintf(stderr, "  %s cut at %zu: %s\n",
					vd_enc_format_name(f), k, vd_error_detail());
				break;
			}
		}
		if (got) {
			uint8_t *more = malloc(n + 1);
			memcpy(more, got, n);
			more[n] = 0;
			CHECK_EQ(vd_enc_parse(&e, more, n + 1, f), VD_ERR_TRAILING);
			free(more);
		}
		free(got);
	}
	/* the DAG engine's own build of the scene decodes the same */
	struct vd_dag built[2];
	CHECK_EQ(vd_dag_from_svo(&built[0], &svo, VD_KIND_DAG, &opts, NULL), VD_OK);
	CHECK_EQ(vd_dag_from_svo(&built[1], &svo, VD_KIND_SSVDAG, &opts, NULL), VD_OK);
	CHECK_EQ(built[0].lv[1].nodes + built[0].lv[2].nodes, 4);
	CHECK_EQ(built[1].lv[1].nodes + built[1].lv[2].nodes, 2);
	for (int f = 0; f < VD_ENC_COUNT_; f++) {
		struct vd_enc e;
		CHECK_EQ(vd_enc_build(&e, f, dag_for(f, &built[0], &built[1]), &t), VD_OK);
		CHECK(enc_equals_svo(&e, &svo));
		vd_enc_release(&e);
	}
	vd_dag_release(&built[0]);
	vd_dag_release(&built[1]);
	svo_free(&svo);
	grid_free(&g);
}

/* Damaged content: each gives VD_ERR_CORRUPT, never a crash. */
static void test_corrupt_files(void)
{
	struct vd_dag d, s;
	golden_dags(&d, &s);
	struct bytes x;
	struct vd_enc e;
	/* svdag: word 1 is the pointer of child 4; point it backwards */
	expected_file(VD_ENC_SVDAG, &x);
	x.b[44 + 4] = 0;
	CHECK_EQ(vd_enc_parse(&e, x.b, x.n, VD_ENC_SVDAG), VD_ERR_CORRUPT);
	expected_file(VD_ENC_SVDAG, &x);
	x.b[44 + 4] = 200; /* beyond the words */
	CHECK_EQ(vd_enc_parse(&e, x.b, x.n, VD_ENC_SVDAG), VD_ERR_CORRUPT);
	expected_file(VD_ENC_SVDAG, &x);
	x.b[44 + 1] = 1;   /* a mirror bit in a plain svdag */
	CHECK_EQ(vd_enc_parse(&e, x.b, x.n, VD_ENC_SVDAG), VD_ERR_CORRUPT);
	expected_file(VD_ENC_USSVDAG, &x);
	x.b[44 + 1] = 0x04; /* mirror X of absent child 2 */
	CHECK_EQ(vd_enc_parse(&e, x.b, x.n, VD_ENC_USSVDAG), VD_ERR_CORRUPT);
	/* esvdag: brick 2 of 2 */
	expected_file(VD_ENC_ESVDAG, &x);
	x.b[40 + 2] = 2;
	CHECK_EQ(vd_enc_parse(&e, x.b, x.n, VD_ENC_ESVDAG), VD_ERR_CORRUPT);
	/* an empty brick */
	expected_file(VD_ENC_ESVDAG, &x);
	x.b[40 + 8 + 4] = 0;
	CHECK_EQ(vd_enc_parse(&e, x.b, x.n, VD_ENC_ESVDAG), VD_ERR_CORRUPT);
	/* a 32-bit tag whose pointer runs past the inner words */
	expected_file(VD_ENC_SSVDAG, &x);
	x.b[40] = 0x06;
	CHECK_EQ(vd_enc_parse(&e, x.b, x.n, VD_ENC_SSVDAG), VD_ERR_CORRUPT);
	/* wrong level count */
	expected_file(VD_ENC_SSVDAG, &x);
	x.b[x.n - 8] = 2;
	CHECK(vd_enc_parse(&e, x.b, x.n, VD_ENC_SSVDAG) != VD_OK);
	/* levels 0 */
	expected_file(VD_ENC_SVDAG, &x);
	x.b[28] = 0;
	CHECK_EQ(vd_enc_parse(&e, x.b, x.n, VD_ENC_SVDAG), VD_ERR_UNSUPPORTED);
	CHECK_EQ(vd_enc_load(&e, "out/tmp/no/such.svdag", -1), VD_ERR_IO);
	CHECK_EQ(vd_enc_load(&e, "x.txt", -1), VD_ERR_ARG);
	/* wrong kinds and non-root chunks */
	CHECK_EQ(vd_enc_build(&e, VD_ENC_SVDAG, &s, NULL), VD_ERR_WRONG_KIND);
	CHECK_EQ(vd_enc_build(&e, VD_ENC_SSVDAG, &d, NULL), VD_ERR_WRONG_KIND);
	d.chunk_level = 1;
	CHECK_EQ(vd_enc_build(&e, VD_ENC_ESVDAG, &d, NULL), VD_ERR_ARG);
	vd_enc_release(&e);
}

/* --------------------------------------------------------- edge cases */

static void encode_grid(struct grid *g, int expect_compact)
{
	struct vd_svo svo;
	grid_to_svo(g, 0, 0, &svo);
	struct vd_dag dd[2];
	CHECK_EQ(vd_dag_from_svo(&dd[0], &svo, VD_KIND_DAG, &opts, NULL), VD_OK);
	CHECK_EQ(vd_dag_from_svo(&dd[1], &svo, VD_KIND_SSVDAG, &opts, NULL), VD_OK);
	for (int f = 0; f < VD_ENC_COUNT_; f++) {
		struct vd_enc e, e2;
		int err = vd_enc_build(&e, f, dag_for(f, &dd[0], &dd[1]), NULL);
		if (vd_enc_format_compact(f) && !expect_compact) {
			CHECK_EQ(err, VD_ERR_UNSUPPORTED);
			vd_enc_release(&e);
			continue;
		}
		CHECK_EQ(err, VD_OK);
		if (err) {
			fprintf(stderr, "  L=%d %s: %s\n", g->L,
				vd_enc_format_name(f), vd_error_detail());
			continue;
		}
		CHECK(enc_equals_svo(&e, &svo));
		/* through the file format */
		char path[700];
		snprintf(path, sizeof path, "out/tmp/test_encode_edge/x.%s",
			 vd_enc_format_name(f));
		CHECK_EQ(vd_enc_save(&e, path), VD_OK);
		CHECK_EQ(vd_enc_load(&e2, path, -1), VD_OK);
		CHECK(enc_equals_svo(&e2, &svo));
		CHECK_EQ(file_size(path), vd_enc_size_bytes(&e) +
			 (vd_enc_format_compact(f) ? VD_ENC_HEADER_BYTES_COMPACT
						   : VD_ENC_HEADER_BYTES_WORDS));
		vd_enc_release(&e);
		vd_enc_release(&e2);
	}
	vd_dag_release(&dd[0]);
	vd_dag_release(&dd[1]);
	svo_free(&svo);
}

static void test_edge_cases(void)
{
	test_tmpdir("test_encode_edge");
	for (int L = 1; L <= 5; L++) {
		struct grid g;
		/* empty scene */
		grid_init(&g, L);
		encode_grid(&g, L >= 3);
		/* a single voxel, at a corner and inside */
		*gv(&g, g.n - 1, 0, g.n / 2) = 1;
		encode_grid(&g, L >= 3);
		/* a full cube */
		memset(g.v, 1, (size_t)g.n * g.n * g.n);
		encode_grid(&g, L >= 3);
		grid_free(&g);
	}
	/* the empty scene's bytes: one empty root */
	struct vd_dag d = {0};
	d.kind = VD_KIND_DAG;
	d.levels = 5;
	struct vd_enc e;
	CHECK_EQ(vd_enc_build(&e, VD_ENC_SVDAG, &d, NULL), VD_OK);
	CHECK_EQ(e.word_count, 1);
	CHECK_EQ(e.words[0], 0);
	CHECK_EQ(e.node_count, 0);
	vd_enc_release(&e);
	CHECK_EQ(vd_enc_build(&e, VD_ENC_ESVDAG, &d, NULL), VD_OK);
	CHECK_EQ(e.inner_count, 1);
	CHECK_EQ(e.inner[0], 0);
	CHECK_EQ(e.leaf_bytes, 0);
	CHECK_EQ(e.level_count, 3);
	CHECK_EQ(vd_enc_size_bytes(&e), 2 + 12);
	vd_enc_release(&e);
	/* a full cube's DAG is one node per level */
	struct grid g;
	grid_init(&g, 4);
	memset(g.v, 1, 16 * 16 * 16);
	struct vd_svo svo;
	grid_to_svo(&g, 0, 0, &svo);
	CHECK_EQ(vd_dag_from_svo(&d, &svo, VD_KIND_DAG, &opts, NULL), VD_OK);
	CHECK_EQ(vd_enc_build(&e, VD_ENC_SVDAG, &d, NULL), VD_OK);
	CHECK_EQ(e.node_count, 4);
	CHECK_EQ(e.word_count, 9 + 9 + 9 + 1);
	vd_enc_release(&e);
	CHECK_EQ(vd_enc_build(&e, VD_ENC_ESVDAG, &d, NULL), VD_OK);
	CHECK_EQ(e.inner_count, 18);
	CHECK_EQ(e.leaf_bytes, 8);
	CHECK_EQ(e.leaves[0], 0xff);
	vd_enc_release(&e);
	vd_dag_release(&d);
	svo_free(&svo);
	grid_free(&g);
}

/* ------------------------------------------------------- real meshes */

static void build_both(const struct vd_svo *svo, struct vd_dag d[2])
{
	CHECK_EQ(vd_dag_from_svo(&d[0], svo, VD_KIND_DAG, &opts, NULL), VD_OK);
	CHECK_EQ(vd_dag_from_svo(&d[1], svo, VD_KIND_SSVDAG, &opts, NULL), VD_OK);
}

/* Round trip of the four files, reported sizes against file sizes, and
 * the 2^(L-1) row against a direct build at L-1. */
static void real_mesh(const char *mesh, int L, int check_rows)
{
	const char *dir = test_tmpdir("test_encode_mesh");
	struct vd_svo svo;
	struct vd_transform t;
	if (!test_voxelize_one(mesh, L, dir, &svo, &t)) return;
	struct vd_dag d[2];
	build_both(&svo, d);
	struct vd_enc_row row;
	CHECK_EQ(vd_enc_table_row(&d[0], &d[1], NULL, L, &row), VD_OK);
	CHECK_EQ(row.voxels, d[0].voxels);
	CHECK_EQ(row.dag_nodes, total_nodes(&d[0]));
	CHECK_EQ(row.ssvdag_nodes, total_nodes(&d[1]));
	int wide = 0;
	for (int f = 0; f < VD_ENC_COUNT_; f++) {
		struct vd_enc e, e2;
		CHECK_EQ(vd_enc_build(&e, f, dag_for(f, &d[0], &d[1]), &t), VD_OK);
		char path[800];
		snprintf(path, sizeof path, "%s/scene.%s", dir, vd_enc_format_name(f));
		CHECK_EQ(vd_enc_save(&e, path), VD_OK);
		vd_enc_release(&e);
		CHECK_EQ(vd_enc_load(&e2, path, -1), VD_OK);
		CHECK(enc_equals_svo(&e2, &svo));
		/* the tables' size is the file minus its header */
		CHECK_EQ(row.bytes[f], file_size(path) -
			 (vd_enc_format_compact(f) ? VD_ENC_HEADER_BYTES_COMPACT
						   : VD_ENC_HEADER_BYTES_WORDS));
		CHECK_EQ(e2.node_count, vd_enc_format_symmetric(f) ?
			 row.ssvdag_nodes : row.dag_nodes);
		if (vd_enc_format_compact(f)) wide += count_wide(&e2);
		vd_enc_release(&e2);
	}
	if (L >= 10) CHECK(wide > 0); /* 32-bit pointers were exercised */
	if (check_rows) {
		/* the cut at L-1 equals voxelizing at L-1 and building */
		const char *dir2 = "out/tmp/test_encode_mesh/low";
		struct vd_svo low;
		struct vd_transform t2;
		if (test_voxelize_one(mesh, L - 1, dir2, &low, &t2)) {
			struct vd_dag dl[2];
			build_both(&low, dl);
			struct vd_enc_row r1;
			CHECK_EQ(vd_enc_table_row(&d[0], &d[1], NULL, L - 1, &r1), VD_OK);
			CHECK_EQ(r1.voxels, dl[0].voxels);
			CHECK_EQ(r1.dag_nodes, total_nodes(&dl[0]));
			CHECK_EQ(r1.ssvdag_nodes, total_nodes(&dl[1]));
			uint64_t svo_nodes = 0;
			uint64_t counts[VD_MAX_LEVELS + 1];
			CHECK_EQ(vd_dag_svo_counts(&dl[0], counts), VD_OK);
			for (int l = 0; l < L - 1; l++) svo_nodes += counts[l];
			CHECK_EQ(r1.svo_nodes, svo_nodes);
			CHECK_EQ(counts[L - 1], low.count ? r1.voxels : 0);
			for (int k = 0; k < 2; k++) {
				struct vd_dag cut;
				CHECK_EQ(vd_dag_cut(&d[k], L - 1, NULL, &cut), VD_OK);
				for (int l = 0; l < L - 1; l++)
					CHECK_EQ(cut.lv[l].nodes, dl[k].lv[l].nodes);
				CHECK_EQ(cut.voxels, dl[k].voxels);
				/* the cut decodes to the direct voxelization */
				struct vd_enc e;
				int f = k ? VD_ENC_SSVDAG : VD_ENC_ESVDAG;
				CHECK_EQ(vd_enc_build(&e, f, &cut, NULL), VD_OK);
				CHECK(enc_equals_svo(&e, &low));
				/* the row counts the compact sizes without
				 * encoding: the encoding's own size */
				CHECK_EQ(r1.bytes[f], vd_enc_size_bytes(&e));
				vd_enc_release(&e);
				/* word formats: the size only depends on the DAG */
				int w = k ? VD_ENC_USSVDAG : VD_ENC_SVDAG;
				CHECK_EQ(vd_enc_build(&e, w, &dl[k], NULL), VD_OK);
				CHECK_EQ(r1.bytes[w], vd_enc_size_bytes(&e));
				vd_enc_release(&e);
				vd_dag_release(&cut);
			}
			vd_dag_release(&dl[0]);
			vd_dag_release(&dl[1]);
			vd_svo_release(&low);
		}
	}
	vd_dag_release(&d[0]);
	vd_dag_release(&d[1]);
	vd_svo_release(&svo);
}

static void test_real_meshes(void)
{
	for (int L = 8; L <= 10; L++) real_mesh("tests/data/bunny.ply", L, L != 10);
	char dragon[600];
	snprintf(dragon, sizeof dragon, "%s/stanford_dragon_res2.ply",
		 test_shared_data());
	FILE *f = fopen(dragon, "rb");
	if (f) {
		fclose(f);
		real_mesh(dragon, 8, 1);
		real_mesh(dragon, 10, 0);
	} else {
		printf("SKIP test_real_meshes_dragon (no %s)\n", dragon);
	}
}

/* Levels too large for the format's addresses are VD_ERR_RANGE. */
static void test_range_errors(void)
{
	const char *dir = test_tmpdir("test_encode_range");
	struct vd_svo svo;
	struct vd_transform t;
	if (!test_voxelize_one("tests/data/bunny.ply", 7, dir, &svo, &t)) return;
	struct vd_dag d[2];
	build_both(&svo, d);
	struct vd_enc e;
	uint64_t a = vd__enc_max_address, b = vd__enc_max_bricks,
		 w = vd__enc_max_words;
	vd__enc_max_address = 16;
	CHECK_EQ(vd_enc_build(&e, VD_ENC_SSVDAG, &d[1], NULL), VD_ERR_RANGE);
	vd_enc_release(&e);
	CHECK_EQ(vd_enc_build(&e, VD_ENC_ESVDAG, &d[0], NULL), VD_ERR_RANGE);
	vd_enc_release(&e);
	vd__enc_max_address = a;
	vd__enc_max_bricks = d[0].lv[5].nodes - 1;
	CHECK_EQ(vd_enc_build(&e, VD_ENC_ESVDAG, &d[0], NULL), VD_ERR_RANGE);
	vd_enc_release(&e);
	vd__enc_max_bricks = d[0].lv[5].nodes;
	CHECK_EQ(vd_enc_build(&e, VD_ENC_ESVDAG, &d[0], NULL), VD_OK);
	vd_enc_release(&e);
	vd__enc_max_bricks = b;
	vd__enc_max_words = 100;
	CHECK_EQ(vd_enc_build(&e, VD_ENC_SVDAG, &d[0], NULL), VD_ERR_RANGE);
	vd_enc_release(&e);
	CHECK_EQ(vd_enc_build(&e, VD_ENC_USSVDAG, &d[1], NULL), VD_ERR_RANGE);
	vd_enc_release(&e);
	vd__enc_max_words = w;
	vd_dag_release(&d[0]);
	vd_dag_release(&d[1]);
	vd_svo_release(&svo);
}

/* Levels sorted by decreasing reference count, ties by DAG order. */
static void test_level_order(void)
{
	const char *dir = test_tmpdir("test_encode_order");
	struct vd_svo svo;
	struct vd_transform t;
	if (!test_voxelize_one("tests/data/bunny.ply", 8, dir, &svo, &t)) return;
	struct vd_dag d;
	CHECK_EQ(vd_dag_from_svo(&d, &svo, VD_KIND_DAG, &opts, NULL), VD_OK);
	struct vd_enc e;
	CHECK_EQ(vd_enc_build(&e, VD_ENC_ESVDAG, &d, NULL), VD_OK);
	/* references per brick index, counted from the file */
	int L = d.levels;
	uint64_t nb = e.leaf_bytes / 8;
	uint32_t *cnt = calloc(nb, 4);
	uint64_t at = e.level_offsets[L - 3];
	while (at < e.inner_count) {
		unsigned h = e.inner[at++];
		for (int s = 7; s >= 0; s--) {
			unsigned tag = h >> 2 * s & 3, m;
			if (!tag) continue;
			cnt[vd__enc_unpack_ptr(tag, e.inner + at, &m)]++;
			at += tag == 1 ? 1 : 2;
		}
	}
	int sorted = 1;
	for (uint64_t i = 1; i < nb; i++) sorted &= cnt[i] <= cnt[i - 1];
	CHECK(sorted);
	CHECK(cnt[0] > 1);
	free(cnt);
	vd_enc_release(&e);
	vd_dag_release(&d);
	vd_svo_release(&svo);
}

int main(void)
{
	RUN(test_pointer_packing);
	RUN(test_brick_layout);
	RUN(test_golden_files);
	RUN(test_corrupt_files);
	RUN(test_edge_cases);
	RUN(test_range_errors);
	RUN(test_level_order);
	RUN(test_real_meshes);
	return CHECK_DONE();
}
