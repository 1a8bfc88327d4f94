/* test_colour_chunk.c - colour chunks: round trip, the brick digest against
 * an independent packing, and every refusal (wrong count, other cell, other
 * bricks, damaged sections). */
#include "check.h"
#include "voxdag.h"

#include <unistd.h>
#include <xxhash.h>

static char dir[] = "/tmp/vd_colchunk_XXXXXX";

/* A 2^4 grid, chunk level 1, cell 5: three bricks of the cell. */
static uint64_t keys[3], masks[3] = {0x1ull, 0x8000000000000000ull, 0xF0F0ull};

static void make_svo(struct vd_svo *s, struct vd_transform *t)
{
	/* Brick keys at depth 4 have 3*(4-2) = 6 bits; cell 5 at level 1 is
	 * their top 3 bits. */
	keys[0] = 5u << 3 | 0;
	keys[1] = 5u << 3 | 3;
	keys[2] = 5u << 3 | 7;
	*s = (struct vd_svo){.levels = 4, .chunk_level = 1, .cell_morton = 5,
			     .count = 3, .keys = keys, .masks = masks};
	float lo[3] = {0, 0, 0}, hi[3] = {1, 2, 3};
	CHECK_EQ(vd_transform_init(t, lo, hi, 4), VD_OK);
}

static uint64_t digest_by_hand(void)
{
	uint8_t b[48];
	for (int i = 0; i < 3; i++)
		for (int j = 0; j < 8; j++) {
			b[16 * i + j] = (uint8_t)(keys[i] >> 8 * j);
			b[16 * i + 8 + j] = (uint8_t)(masks[i] >> 8 * j);
		}
	return XXH3_64bits(b, sizeof b);
}

static void test_round_trip(void)
{
	struct vd_svo s;
	struct vd_transform t;
	make_svo(&s, &t);
	char svo_path[256], col_path[256];
	snprintf(svo_path, sizeof svo_path, "%s/c.svo", dir);
	snprintf(col_path, sizeof col_path, "%s/c.col", dir);
	CHECK_EQ(vd_svo_save(&s, &t, svo_path, NULL), VD_OK);
	struct vd_svo back;
	struct vd_chunk_header sh;
	CHECK_EQ(vd_svo_load(&back, &sh, svo_path), VD_OK);
	uint64_t voxels = sh.level_nodes[sh.level_count - 1];
	CHECK_EQ(voxels, 1 + 1 + 8); /* popcounts of the masks */
	CHECK(vd_svo_digest(keys, masks, 3) == digest_by_hand());
	uint8_t rgb[30];
	for (int i = 0; i < 30; i++)
		rgb[i] = (uint8_t)(7 * i + 1);
	uint64_t dig = vd_svo_digest(back.keys, back.masks, back.count);
	CHECK_EQ(vd_colours_save(col_path, &sh, dig, rgb, 9, NULL),
		 VD_ERR_MISMATCH);
	CHECK(access(col_path, F_OK) != 0);
	CHECK_EQ(vd_colours_save(col_path, &sh, dig, rgb, 10, "tool=test"),
		 VD_OK);
	struct vd_colours c;
	struct vd_chunk_header ch;
	CHECK_EQ(vd_colours_load(&c, &ch, col_path), VD_OK);
	CHECK_EQ(ch.kind, VD_KIND_COLOURS);
	CHECK_EQ(c.voxels, 10);
	CHECK(c.rgb && memcmp(c.rgb, rgb, 30) == 0);
	CHECK_EQ(vd_colours_match(&ch, &c, &sh, &back), VD_OK);

	/* Other bricks with the same counts: the digest catches it. */
	uint64_t other_masks[3] = {0x2ull, masks[1], masks[2]};
	struct vd_svo other = back;
	other.masks = other_masks;
	CHECK_EQ(vd_colours_match(&ch, &c, &sh, &other), VD_ERR_MISMATCH);
	/* Another cell. */
	struct vd_chunk_header sh2 = sh;
	sh2.cell_morton = 4;
	CHECK_EQ(vd_colours_match(&ch, &c, &sh2, NULL), VD_ERR_MISMATCH);
	/* Another grid placement. */
	sh2 = sh;
	sh2.transform.voxel_size *= 2;
	CHECK_EQ(vd_colours_match(&ch, &c, &sh2, NULL), VD_ERR_MISMATCH);
	/* An SVO chunk is not a colour chunk. */
	struct vd_colours c2;
	CHECK_EQ(vd_colours_load(&c2, NULL, svo_path), VD_ERR_WRONG_KIND);
	vd_colours_release(&c);
	vd_svo_release(&back);
}

/* A colour chunk whose COLS size disagrees with the voxel count, or with a
 * short BDIG, or without COLS: corrupt. */
static void test_damaged(void)
{
	struct vd_svo s;
	struct vd_transform t;
	make_svo(&s, &t);
	struct vd_chunk_header h = {0};
	h.kind = VD_KIND_COLOURS;
	h.levels = 4;
	h.chunk_level = 1;
	h.cell_morton = 5;
	h.transform = t;
	h.level_count = 4;
	vd_svo_count_levels(&s, h.level_nodes);
	char path[256];
	snprintf(path, sizeof path, "%s/bad.col", dir);
	uint8_t rgb[33] = {0}, dig[8] = {0};
	for (int variant = 0; variant < 3; variant++) {
		struct vd_chunk_writer *w;
		CHECK_EQ(vd_chunk_writer_open(&w, path, &h, NULL), VD_OK);
		CHECK_EQ(vd_chunk_writer_section(w, VD_TAG_BDIG, dig,
						 variant == 1 ? 7 : 8), VD_OK);
		if (variant != 2)
			CHECK_EQ(vd_chunk_writer_section(w, VD_TAG_COLS, rgb,
							 variant == 0 ? 33 : 30),
				 VD_OK);
		CHECK_EQ(vd_chunk_writer_commit(w), VD_OK);
		struct vd_colours c;
		CHECK_EQ(vd_colours_load(&c, NULL, path), VD_ERR_CORRUPT);
		CHECK(c.rgb == NULL);
	}
}

int main(void)
{
	if (!mkdtemp(dir))
		return 1;
	RUN(test_round_trip);
	RUN(test_damaged);
	char cmd[300];
	snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
	if (system(cmd) != 0)
		return 1;
	return CHECK_DONE();
}
