/* fuzz_ac3d.c - libFuzzer target: the mesh reader on ac3d input (the format
 * is detected from the content, so the seeds steer it to the ac3d reader). */
#include "fuzz.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	return fuzz_mesh(data, size, ".ac");
}
