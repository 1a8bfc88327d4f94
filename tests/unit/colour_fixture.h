/* colour_fixture.h - what the colour tests share: the xorshift generator
 * of their pseudo-random colours (each test keeps its own state and seed,
 * so its arrays do not depend on the others) and damaging packed colours
 * files. Reading a whole file is check.h's test_slurp. */
#ifndef VD_COLOUR_FIXTURE_H
#define VD_COLOUR_FIXTURE_H

#include <stdint.h>

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
