/* colour_fixture.h - what the colour tests share: the xorshift generator
 * of their pseudo-random colours (each test keeps its own state and seed,
 * so its arrays do not depend on the others) and damaging packed colours
 * files. Reading a whole file is check.h's test_slurp. */
#ifndef VD_COLOUR_FIXTURE_H
#define VD_COLOUR_FIXTURE_H

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "voxdag.h"

/* Marsaglia's xorshift64, top bits: deterministic on every platform. */
static inline uint32_t test_xorshift(uint64_t *s)
{
	*s ^= *s << 13;
	*s ^= *s >> 7;
	*s ^= *s << 17;
	return (uint32_t)(*s >> 11);
}

/* How many damaged copies of the packed colours file b[0..n) the reader
 * accepts (it must accept none): every truncation, then `flip` xored into
 * every `step`-th byte in turn (b is restored). */
static inline int test_cpack_damage_accepted(uint8_t *b, size_t n,
					     size_t step, uint8_t flip)
{
	struct vd_cpack *c;
	int accepted = 0;
	for (size_t cut = 0; cut < n; cut++)
		if (vd_cpack_open_mem(&c, b, cut) == VD_OK) {
			accepted++;
			vd_cpack_free(c);
		}
	for (size_t i = 0; i < n; i += step) {
		b[i] ^= flip;
		if (vd_cpack_open_mem(&c, b, n) == VD_OK) {
			accepted++;
			vd_cpack_free(c);
		}
		b[i] ^= flip;
	}
	return accepted;
}

/* How many colours vd_cpack_colour_many gives that differ from want[0 ..
 * 3 total) (each voxel's colour by other means): every voxel once in a
 * shuffled order, then as many drawn at random (duplicates), in batches
 * of 1, 7, 1000 and all at once; with `big`, one batch of 2^20 + 4099
 * random voxels too (past the reader's 2^20 sorted at once). A batch
 * whose last index is `total` must fail with VD_ERR_RANGE and leave its
 * output as it was, else that counts as a difference too. */
static inline uint64_t test_cpack_many_bad(const struct vd_cpack *c,
					   const uint8_t *want,
					   uint64_t total, int big,
					   uint64_t *seed)
{
	uint64_t m = 2 * total, bad = 0;
	uint64_t mb = big && m < (1u << 20) + 4099 ? (1u << 20) + 4099 : m;
	uint64_t *idx = malloc((mb + 1) * sizeof *idx);
	uint8_t *out = malloc(3 * (mb + 1));
	if (!idx || !out || !total) {
		free(idx);
		free(out);
		return total ? 1 : 0;
	}
	for (uint64_t i = 0; i < total; i++)
		idx[i] = i;
	for (uint64_t i = total; i > 1; i--) {
		uint64_t j = test_xorshift(seed) % i, t = idx[i - 1];
		idx[i - 1] = idx[j];
		idx[j] = t;
	}
	for (uint64_t i = total; i < mb; i++)
		idx[i] = test_xorshift(seed) % total;
	static const uint64_t sizes[] = {1, 7, 1000, 0};
	for (int k = 0; k < 4; k++) {
		uint64_t b = sizes[k] ? sizes[k] : m;
		memset(out, 0, 3 * m);
		for (uint64_t i = 0; i < m; i += b)
			if (vd_cpack_colour_many(c, idx + i, m - i < b ? m - i : b,
						 out + 3 * i) != VD_OK)
				bad++;
		for (uint64_t i = 0; i < m; i++)
			bad += memcmp(out + 3 * i, want + 3 * idx[i], 3) != 0;
	}
	if (mb > m) {
		if (vd_cpack_colour_many(c, idx, mb, out) != VD_OK)
			bad++;
		for (uint64_t i = 0; i < mb; i++)
			bad += memcmp(out + 3 * i, want + 3 * idx[i], 3) != 0;
	}
	idx[m] = total;
	memset(out, 0x5a, 3 * (m + 1));
	bad += vd_cpack_colour_many(c, idx, m + 1, out) != VD_ERR_RANGE;
	for (uint64_t i = 0; i < 3 * (m + 1); i++)
		bad += out[i] != 0x5a;
	free(idx);
	free(out);
	return bad;
}

/* Writes a packed colours file at `path` with a header of `voxels`
 * colours and the n sections tags[i] of len[i] bytes (good checksums,
 * any structure) and returns what the reader says of it. */
static inline int test_cpack_crafted(const char *path,
				     const struct vd_transform *tr,
				     uint64_t voxels, int n,
				     const uint32_t *tags,
				     const void *const *data,
				     const size_t *len)
{
	struct vd_chunk_header h = {.kind = VD_KIND_CPACK, .levels = 12,
				    .level_count = 1, .transform = *tr};
	h.level_nodes[0] = voxels;
	struct vd_chunk_writer *w;
	CHECK_EQ(vd_chunk_writer_open(&w, path, &h, NULL), VD_OK);
	for (int i = 0; i < n; i++)
		vd_chunk_writer_section(w, tags[i], data[i], len[i]);
	CHECK_EQ(vd_chunk_writer_commit(w), VD_OK);
	struct vd_cpack *c;
	int err = vd_cpack_open(&c, path);
	vd_cpack_free(c);
	return err;
}

#endif /* VD_COLOUR_FIXTURE_H */
