/* fuzz_texture.c - libFuzzer target: the texture decoders (PNG, JPEG, SGI,
 * stb_image's formats; told apart by the first bytes) and, when an image
 * decodes, a sample at each corner. */
#include "fuzz.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	struct vd_texture t;
	if (vd_texture_load(&t, fuzz_file(data, size, ".img")) == VD_OK) {
		uint8_t rgb[3];
		vd_texture_sample(&t, 0.0, 0.0, rgb);
		vd_texture_sample(&t, 0.999, 0.999, rgb);
		vd_texture_release(&t);
	}
	return 0;
}
