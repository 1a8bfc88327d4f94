/* fuzz_chunk.c - libFuzzer target: the chunk file reader
 * (vd_chunk_open_mem, the same checks as vd_chunk_open), then each kind's
 * content reader: SVO bricks, DAG and SSVDAG levels, packed colours (every
 * colour of a file the reader accepts is looked up: its checks must keep
 * each lookup inside the file's arrays). */
#include "fuzz.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	struct vd_chunk *c;
	if (vd_chunk_open_mem(&c, data, size, VD_KIND_ANY))
		return 0;
	const struct vd_chunk_header *h = vd_chunk_header(c);
	(void)vd_chunk_provenance(c);
	uint32_t n = vd_chunk_section_count(c);
	for (uint32_t i = 0; i < n; i++)
		(void)vd_chunk_has_section(c, vd_chunk_section_tag(c, i));
	if (h->kind == VD_KIND_SVO) {
		struct vd_svo s;
		if (!vd_svo_from_chunk(&s, c))
			vd_svo_release(&s);
	} else if (h->kind == VD_KIND_DAG || h->kind == VD_KIND_SSVDAG) {
		struct vd_dag d;
		memset(&d, 0, sizeof d);
		if (!vd_dag_from_chunk(&d, c, h->kind))
			(void)vd_dag_memory_bytes(&d);
		vd_dag_release(&d);
	}
	uint32_t kind = h->kind;
	vd_chunk_free(c);
	struct vd_cpack *p;
	if (kind == VD_KIND_CPACK && !vd_cpack_open_mem(&p, data, size)) {
		uint64_t voxels = vd_cpack_voxels(p);
		for (uint64_t i = 0; i < voxels && i < 100000; i++) {
			uint8_t rgb[3];
			(void)vd_cpack_colour(p, i, rgb);
		}
		/* the batched lookups too, from the end back (a coded file's
		 * are sorted) */
		uint64_t idx[256];
		uint8_t out[3 * 256];
		size_t m = 0;
		for (uint64_t i = voxels; i-- > 0 && m < 256;)
			idx[m++] = i;
		(void)vd_cpack_colour_many(p, idx, m, out);
		vd_cpack_free(p);
	}
	return 0;
}
