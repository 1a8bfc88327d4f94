/* fuzz_obj.c - libFuzzer target: the mesh reader on obj input (the format
 * is detected from the content, so the seeds steer it to the obj reader). */
#include "fuzz.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	return fuzz_mesh(data, size, ".obj");
}
