#include <stdio.h>
#include <jpeglib.h>
int main(void)
{
	/* 8x8: left half orange, right half teal */
	unsigned char px[8 * 8 * 3];
	for (int y = 0; y < 8; y++)
		for (int x = 0; x < 8; x++) {
			unsigned char *p = px + 3 * (8 * y + x);
			p[0] = x < 4 ? 240 : 20; p[1] = x < 4 ? 140 : 160; p[2] = x < 4 ? 20 : 150;
		}
	struct jpeg_compress_struct c;
	struct jpeg_error_mgr e;
	c.err = jpeg_std_error(&e);
	jpeg_create_compress(&c);
	FILE *f = fopen("photo.jpg", "wb");
	jpeg_stdio_dest(&c, f);
	c.image_width = 8; c.image_height = 8; c.input_components = 3; c.in_color_space = JCS_RGB;
	jpeg_set_defaults(&c);
	jpeg_set_quality(&c, 95, TRUE);
	jpeg_start_compress(&c, TRUE);
	while (c.next_scanline < 8) { JSAMPROW r = px + 24 * c.next_scanline; jpeg_write_scanlines(&c, &r, 1); }
	jpeg_finish_compress(&c);
	fclose(f);
	return 0;
}
