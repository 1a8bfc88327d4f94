/* test_encode48.c - the .ssvdag48 encoding: golden bytes worked out by hand
 * (schemas/encodings.md, "Worked example"), the voxels they decode to from
 * coordinate arithmetic written here, pointer packing, damaged files, and
 * round trips on the bundled bunny, monolithic and chunked + merged,
 * against the voxelizer's SVO. */
#include "check.h"
#include "scene.h"
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

/* ------------------------------------------------------------ pointers */

static void test_pointer_packing(void)
{
	uint16_t w[2];
	unsigned t;
	/* by hand: 5 | 17 << 10 = 0x4405 */
	CHECK_EQ(vd__enc_pack_ptr48(5, 17, w), 1);
	CHECK_EQ(w[0], 0x4405);
	/* 1023 is the last short address */
	CHECK_EQ(vd__enc_pack_ptr48(1023, 47, w), 1);
	CHECK_EQ(w[0], 0xbfff);
	/* 1024 | 47 << 26 = 0xbc000400, high half first */
	CHECK_EQ(vd__enc_pack_ptr48(1024, 47, w), 2);
	CHECK_EQ(w[0], 0xbc00);
	CHECK_EQ(w[1], 0x0400);
	/* address bit 26 goes to the tag: 2^26 + 3 with t 9 = 0x24000003 */
	CHECK_EQ(vd__enc_pack_ptr48((1u << 26) + 3, 9, w), 3);
	CHECK_EQ(w[0], 0x2400);
	CHECK_EQ(w[1], 0x0003);
	CHECK_EQ(vd__enc_unpack_ptr48(3, w, &t), (1u << 26) + 3);
	CHECK_EQ(t, 9);
	for (unsigned k = 0; k < 20000; k++) {
		uint32_t a = (uint32_t)(rnd() % (1u << 27));
		if (k & 1) a &= 0x7ff;
		unsigned tt = (unsigned)(rnd() % 48), tag;
		tag = vd__enc_pack_ptr48(a, tt, w);
		CHECK_EQ(tag == 1, a < 1024);
		CHECK_EQ(vd__enc_unpack_ptr48(tag, w, &t), a);
		CHECK_EQ(t, tt);
	}
}

/* ------------------------------------------------------- golden file */

/* The worked example of schemas/encodings.md: L = 4, root R with child 0
 * = (A, 0) and child 1 = (A, 8); A with child 2 = (B, 17) and child 4 =
 * (B, 0); B the brick with voxels (1,0,0) and (0,0,3): masks M0 = 0x10
 * (child 0) and M1 = 0x02 (child 1). */
static uint8_t r_mask[] = {0x03}, a_mask[] = {0x14}, b_mask[] = {0x03},
	       m_mask[] = {0x10, 0x02};
static uint64_t r_first[] = {0, 2}, a_first[] = {0, 2}, b_first[] = {0, 2};
static uint32_t r_child[] = {0, 0}, a_child[] = {0, 0}, b_child[] = {0, 1};
static uint8_t r_t[] = {0, 8}, a_t[] = {17, 0}, b_t[] = {0, 0};
/* Morton brick: byte c = child c's mask */
static uint64_t g_bricks[] = {0x0210};

static void golden_dag(struct vd_dag *d)
{
	memset(d, 0, sizeof *d);
	d->kind = VD_KIND_SSVDAG48;
	d->levels = 4;
	d->voxels = 8;
	d->lv[0] = (struct vd_dag_level){1, 2, r_mask, r_first, r_child, r_t};
	d->lv[1] = (struct vd_dag_level){1, 2, a_mask, a_first, a_child, a_t};
	d->lv[2] = (struct vd_dag_level){1, 2, b_mask, b_first, b_child, b_t};
	d->lv[3] = (struct vd_dag_level){2, 0, m_mask, NULL, NULL, NULL};
	d->bricks = g_bricks;
}

/* The file, byte by byte, as the specification's table lists it. */
static const uint8_t golden[76] = {
	/* bbox (-1,-2,-3)..(1,2,3), side 6 */
	0x00, 0x00, 0x80, 0xbf, 0x00, 0x00, 0x00, 0xc0, 0x00, 0x00, 0x40, 0xc0,
	0x00, 0x00, 0x80, 0x3f, 0x00, 0x00, 0x00, 0x40, 0x00, 0x00, 0x40, 0x40,
	0x00, 0x00, 0xc0, 0x40,
	0x04, 0x00, 0x00, 0x00, /* levels 4 */
	0x05, 0x00, 0x00, 0x00, /* node_count 5 */
	0x06, 0x00, 0x00, 0x00, /* inner_count 6 */
	0x05, 0x00,             /* R: tags 01 for children 0 and 1 */
	0x00, 0x20,             /* R child 1: A (address 0), transform 8 */
	0x00, 0x00,             /* R child 0: A, transform 0 */
	0x10, 0x01,             /* A: tags 01 for children 2 and 4 */
	0x00, 0x00,             /* A child 4: brick 0, transform 0 */
	0x00, 0x44,             /* A child 2: brick 0, transform 17 */
	0x08, 0x00, 0x00, 0x00, /* leaf_bytes 8 */
	0x08, 0x00, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, /* B: bits 3, 16 */
	0x02, 0x00, 0x00, 0x00, /* level_count 2 */
	0x00, 0x00, 0x00, 0x00, /* level 0 at 0 */
	0x03, 0x00, 0x00, 0x00, /* level 1 at 3 */
};

/* The 8 voxels the specification derives by hand. */
static const uint32_t golden_voxels[8][3] = {
	{5, 0, 0}, {4, 0, 3}, {0, 5, 3}, {0, 4, 0},
	{5, 0, 8}, {4, 3, 8}, {0, 3, 13}, {0, 0, 12},
};

static void test_golden_file(void)
{
	struct vd_dag d;
	golden_dag(&d);
	CHECK_EQ(vd_dag_validate(&d), VD_OK);
	struct vd_transform t = {{-1, -2, -3}, {1, 2, 3}, 6, {0, 0, 0}, 0.375};
	const char *dir = test_tmpdir("test_encode48_golden");
	struct vd_enc e;
	CHECK_EQ(vd_enc_build(&e, VD_ENC_SSVDAG48, &d, &t), VD_OK);
	CHECK_EQ(vd_enc_size_bytes(&e) + VD_ENC_HEADER_BYTES_COMPACT, 76);
	char path[700];
	snprintf(path, sizeof path, "%s/golden.ssvdag48", dir);
	CHECK_EQ(vd_enc_save(&e, path), VD_OK);
	vd_enc_release(&e);
	size_t n = 0;
	uint8_t *got = read_all(path, &n);
	CHECK_EQ(n, sizeof golden);
	CHECK(got && n == sizeof golden && !memcmp(got, golden, n));
	for (size_t i = 0; got && i < n && i < sizeof golden; i++)
		if (got[i] != golden[i])
			fprintf(stderr, "  byte %zu is %02x, expected %02x\n", i,
				got[i], golden[i]);
	free(got);

	/* decoded (from the golden bytes, not the DAG): exactly the 8 voxels */
	CHECK_EQ(vd_enc_parse(&e, golden, sizeof golden, VD_ENC_SSVDAG48), VD_OK);
	CHECK_EQ(e.node_count, 5);
	struct grid want, have;
	grid_init(&want, 4);
	grid_init(&have, 4);
	for (int i = 0; i < 8; i++)
		*gv(&want, golden_voxels[i][0], golden_voxels[i][1],
		    golden_voxels[i][2]) = 1;
	struct sink s = {0};
	CHECK_EQ(vd_enc_expand(&e, sink_add, &s), 0);
	for (size_t i = 0; i < s.n; i++) {
		uint32_t bx, by, bz, x, y, z;
		vd_morton3_decode(s.keys[i], &bx, &by, &bz);
		for (unsigned b = 0; b < 64; b++)
			if (s.masks[i] >> b & 1) {
				vd_morton3_decode(b, &x, &y, &z);
				*gv(&have, 4 * bx + x, 4 * by + y, 4 * bz + z) = 1;
			}
	}
	CHECK_EQ(grid_count(&have), 8);
	CHECK(grid_equal(&have, &want));
	sink_free(&s);
	/* the chunk decodes to the same voxels (the DAG's own expansion) */
	CHECK(dag_matches_grid(&d, &want));
	vd_enc_release(&e);

	/* damaged: transform 48 and 63 in R's first pointer (bytes 42-43) */
	uint8_t bad[76];
	for (unsigned tt = 48; tt < 64; tt += 15) {
		memcpy(bad, golden, sizeof bad);
		bad[43] = (uint8_t)(tt << 2);
		CHECK_EQ(vd_enc_parse(&e, bad, sizeof bad, VD_ENC_SSVDAG48),
			 VD_ERR_CORRUPT);
		CHECK(strstr(vd_error_detail(), "transform") != NULL);
	}
	/* transform 47 is fine */
	memcpy(bad, golden, sizeof bad);
	bad[43] = 47 << 2;
	CHECK_EQ(vd_enc_parse(&e, bad, sizeof bad, VD_ENC_SSVDAG48), VD_OK);
	vd_enc_release(&e);
	/* a brick address beyond the bricks */
	memcpy(bad, golden, sizeof bad);
	bad[48] = 1;
	CHECK_EQ(vd_enc_parse(&e, bad, sizeof bad, VD_ENC_SSVDAG48),
		 VD_ERR_CORRUPT);
	/* cut at every length: never accepted */
	for (size_t k = 0; k < sizeof golden; k++) {
		int err = vd_enc_parse(&e, golden, k, VD_ENC_SSVDAG48);
		CHECK(err == VD_ERR_TRUNCATED || err == VD_ERR_CORRUPT);
		vd_enc_release(&e);
	}
	uint8_t longer[77];
	memcpy(longer, golden, 76);
	longer[76] = 0;
	CHECK_EQ(vd_enc_parse(&e, longer, 77, VD_ENC_SSVDAG48), VD_ERR_TRAILING);
	/* the other formats refuse the chunk, and this one the others */
	CHECK_EQ(vd_enc_build(&e, VD_ENC_SSVDAG, &d, NULL), VD_ERR_WRONG_KIND);
	vd_enc_release(&e);
	d.kind = VD_KIND_SSVDAG;
	CHECK_EQ(vd_enc_build(&e, VD_ENC_SSVDAG48, &d, NULL), VD_ERR_WRONG_KIND);
	vd_enc_release(&e);
	CHECK_EQ(vd_enc_format_from_path("x/scene.ssvdag48"), VD_ENC_SSVDAG48);
	grid_free(&want);
	grid_free(&have);
}

/* ------------------------------------------------------- real scenes */

static void roundtrip(const struct vd_dag *d, const struct vd_svo *svo,
		      const struct vd_transform *t, const char *dir,
		      int expect_wide)
{
	struct vd_enc e, e2;
	CHECK_EQ(vd_enc_build(&e, VD_ENC_SSVDAG48, d, t), VD_OK);
	char path[800];
	snprintf(path, sizeof path, "%s/scene.ssvdag48", dir);
	CHECK_EQ(vd_enc_save(&e, path), VD_OK);
	vd_enc_release(&e);
	CHECK_EQ(vd_enc_load(&e2, path, -1), VD_OK);
	CHECK_EQ(e2.format, VD_ENC_SSVDAG48);
	CHECK_EQ(e2.node_count, total_nodes(d));
	CHECK(enc_equals_svo(&e2, svo));
	if (expect_wide) CHECK(count_wide(&e2) > 0);
	vd_enc_release(&e2);
}

/* The bunny: monolithic at 2^8..2^10, and voxelized in 64 chunks whose
 * ssvdag48s are merged to the root; both decode to the monolithic SVO. */
static void test_bunny(void)
{
	const char *dir = test_tmpdir("test_encode48_bunny");
	for (int L = 8; L <= 10; L++) {
		struct vd_svo svo;
		struct vd_transform t;
		if (!test_voxelize_one("tests/data/bunny.ply", L, dir, &svo, &t))
			return;
		struct vd_dag d, d8;
		CHECK_EQ(vd_dag_from_svo(&d, &svo, VD_KIND_SSVDAG48, &opts, NULL),
			 VD_OK);
		CHECK_EQ(vd_dag_from_svo(&d8, &svo, VD_KIND_SSVDAG, &opts, NULL),
			 VD_OK);
		CHECK(total_nodes(&d) < total_nodes(&d8));
		roundtrip(&d, &svo, &t, dir, L == 10);

		if (L == 9) {
			/* chunked at level 2 and merged */
			const char *cdir = "out/tmp/test_encode48_bunny/chunks";
			CHECK_EQ(test_voxelize("tests/data/bunny.ply", L, 2, cdir,
					       NULL), VD_OK);
			struct vd_dag parts[64], root;
			const struct vd_dag *pp[64];
			size_t np = 0;
			for (uint64_t c = 0; c < 64; c++) {
				char name[64], path[800];
				vd_chunk_file_name(name, sizeof name, 2, c, "svo");
				snprintf(path, sizeof path, "%s/%s", cdir, name);
				struct vd_svo s;
				if (vd_svo_load(&s, NULL, path)) continue;
				CHECK_EQ(vd_dag_from_svo(&parts[np], &s,
							 VD_KIND_SSVDAG48, &opts,
							 NULL), VD_OK);
				pp[np] = &parts[np];
				np++;
				vd_svo_release(&s);
			}
			CHECK(np > 4);
			CHECK_EQ(vd_dag_merge(&root, pp, np, VD_KIND_SSVDAG48, 0,
					      &opts, NULL), VD_OK);
			for (int l = 0; l < L; l++)
				CHECK_EQ(root.lv[l].nodes, d.lv[l].nodes);
			roundtrip(&root, &svo, &t, dir, 0);
			vd_dag_release(&root);
			for (size_t i = 0; i < np; i++) vd_dag_release(&parts[i]);
		}
		vd_dag_release(&d);
		vd_dag_release(&d8);
		vd_svo_release(&svo);
	}
}

/* Addresses beyond the format's are VD_ERR_RANGE, never a wrong file. */
static void test_range(void)
{
	const char *dir = test_tmpdir("test_encode48_range");
	struct vd_svo svo;
	struct vd_transform t;
	if (!test_voxelize_one("tests/data/bunny.ply", 8, dir, &svo, &t)) return;
	struct vd_dag d;
	CHECK_EQ(vd_dag_from_svo(&d, &svo, VD_KIND_SSVDAG48, &opts, NULL), VD_OK);
	struct vd_enc e;
	uint64_t keep = vd__enc_max_address;
	vd__enc_max_address = 64;
	CHECK_EQ(vd_enc_build(&e, VD_ENC_SSVDAG48, &d, &t), VD_ERR_RANGE);
	vd_enc_release(&e);
	vd__enc_max_address = keep;
	CHECK_EQ(vd_enc_build(&e, VD_ENC_SSVDAG48, &d, &t), VD_OK);
	vd_enc_release(&e);
	vd_dag_release(&d);
	vd_svo_release(&svo);
}

int main(void)
{
	RUN(test_pointer_packing);
	RUN(test_golden_file);
	RUN(test_bunny);
	RUN(test_range);
	return CHECK_DONE();
}
