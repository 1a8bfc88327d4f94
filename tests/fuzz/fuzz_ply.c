/* fuzz_ply.c - libFuzzer target: the mesh reader on ply input (the format
 * is detected from the content, so the seeds steer it to the ply reader). */
#include "fuzz.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	return fuzz_mesh(data, size, ".ply");
}
