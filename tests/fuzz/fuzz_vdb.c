/* fuzz_vdb.c - libFuzzer target: the OpenVDB file walk (vd_vdb_walk, the
 * structure check run before OpenVDB reads a file), on a memory stream. */
#include "fuzz.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	if (!size)
		return 0;
	FILE *f = fmemopen((void *)data, size, "rb");
	if (!f)
		abort();
	uint64_t grids;
	(void)vd_vdb_walk(f, &grids);
	fclose(f);
	return 0;
}
