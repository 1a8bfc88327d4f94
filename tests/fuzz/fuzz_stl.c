/* fuzz_stl.c - libFuzzer target: the mesh reader on stl input (the format
 * is detected from the content, so the seeds steer it to the stl reader). */
#include "fuzz.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	return fuzz_mesh(data, size, ".stl");
}
