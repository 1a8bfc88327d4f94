/* texture.c - texture images for coloured meshes: decoding (libpng,
 * libjpeg-turbo, stb_image for the rest) and the sampling rule.
 *
 * Decisions worth knowing:
 * - The format is told by the first bytes, never the name: exporters often
 *   name a JPEG .png.
 * - Texels are kept as RGB8 (alpha dropped, unpremultiplied): a voxel's
 *   colour is the surface's albedo; transparency is not a colour.
 * - Sampling is bilinear with repeat wrapping, v = 0 at the bottom row
 *   (OpenGL's convention, which OBJ and AC3D follow). Coordinates are
 *   reduced with fmod before any conversion to integer, so a huge but
 *   finite coordinate is still a valid, deterministic sample.
 */
#include "voxdag.h"

#include <errno.h>
#include <math.h>
#include <setjmp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include <jpeglib.h>
#include <png.h>
#include <stb/stb_image.h>

/* Larger textures are taken as corruption (32768^2 RGB is 3 GiB). */
#define TEX_MAX_SIDE 32768

static int tex_size_ok(uint64_t w, uint64_t h, const char *path)
{
	if (w == 0 || h == 0)
		return vd_fail(VD_ERR_FORMAT, "'%s' has no texels (%llux%llu)",
			       path, (unsigned long long)w,
			       (unsigned long long)h);
	if (w > TEX_MAX_SIDE || h > TEX_MAX_SIDE)
		return vd_fail(VD_ERR_RANGE, "'%s' is %llux%llu texels (at most "
			       "%d per side)", path, (unsigned long long)w,
			       (unsigned long long)h, TEX_MAX_SIDE);
	return VD_OK;
}

static int load_png(struct vd_texture *t, const char *path)
{
	png_image img;
	memset(&img, 0, sizeof img);
	img.version = PNG_IMAGE_VERSION;
	if (!png_image_begin_read_from_file(&img, path))
		return vd_fail(VD_ERR_FORMAT, "'%s': %s", path, img.message);
	int err = tex_size_ok(img.width, img.height, path);
	if (err) {
		png_image_free(&img);
		return err;
	}
	/* RGBA, then the alpha dropped: without it libpng would composite
	 * the texels over a background. */
	img.format = PNG_FORMAT_RGBA;
	size_t n = (size_t)img.width * img.height;
	uint8_t *rgba = malloc(4 * n);
	if (!rgba) {
		png_image_free(&img);
		return vd_fail(VD_ERR_NOMEM, "texture '%s'", path);
	}
	if (!png_image_finish_read(&img, NULL, rgba, 0, NULL)) {
		free(rgba);
		err = vd_fail(VD_ERR_FORMAT, "'%s': %s", path, img.message);
		png_image_free(&img);
		return err;
	}
	for (size_t i = 0; i < n; i++)
		memmove(rgba + 3 * i, rgba + 4 * i, 3);
	uint8_t *rgb = realloc(rgba, 3 * n);
	t->rgb = rgb ? rgb : rgba;
	t->width = img.width;
	t->height = img.height;
	return VD_OK;
}

struct jpeg_err {
	struct jpeg_error_mgr mgr;
	jmp_buf jump;
	char msg[JMSG_LENGTH_MAX];
};

static void jpeg_fail(j_common_ptr c)
{
	struct jpeg_err *e = (struct jpeg_err *)c->err;
	(*c->err->format_message)(c, e->msg);
	longjmp(e->jump, 1);
}

/* Corrupt-data warnings would otherwise go to stderr: a texture with
 * them is still decoded (libjpeg fills what it cannot read with grey). */
static void jpeg_quiet(j_common_ptr c, int level)
{
	(void)c;
	(void)level;
}

static int load_jpeg(struct vd_texture *t, const char *path, FILE *f)
{
	struct jpeg_decompress_struct c;
	struct jpeg_err e;
	/* volatile: changed between setjmp and a longjmp back */
	uint8_t *volatile rgb = NULL;
	c.err = jpeg_std_error(&e.mgr);
	e.mgr.error_exit = jpeg_fail;
	e.mgr.emit_message = jpeg_quiet;
	e.msg[0] = 0;
	if (setjmp(e.jump)) {
		jpeg_destroy_decompress(&c);
		free(rgb);
		return vd_fail(VD_ERR_FORMAT, "'%s': %s", path, e.msg);
	}
	jpeg_create_decompress(&c);
	jpeg_stdio_src(&c, f);
	jpeg_read_header(&c, TRUE);
	c.out_color_space = JCS_RGB;
	int err = tex_size_ok(c.image_width, c.image_height, path);
	if (err) {
		jpeg_destroy_decompress(&c);
		return err;
	}
	jpeg_start_decompress(&c);
	if (c.output_components != 3) {
		jpeg_destroy_decompress(&c);
		return vd_fail(VD_ERR_UNSUPPORTED, "'%s': JPEG with %d "
			       "components", path, c.output_components);
	}
	rgb = malloc((size_t)c.output_width * c.output_height * 3);
	if (!rgb) {
		jpeg_destroy_decompress(&c);
		return vd_fail(VD_ERR_NOMEM, "texture '%s'", path);
	}
	while (c.output_scanline < c.output_height) {
		JSAMPROW row = rgb + (size_t)c.output_scanline *
				     c.output_width * 3;
		jpeg_read_scanlines(&c, &row, 1);
	}
	jpeg_finish_decompress(&c);
	t->width = c.output_width;
	t->height = c.output_height;
	t->rgb = rgb;
	jpeg_destroy_decompress(&c);
	return VD_OK;
}

static int load_stb(struct vd_texture *t, const char *path, FILE *f)
{
	int w, h, n;
	if (!stbi_info_from_file(f, &w, &h, &n))
		return vd_fail(VD_ERR_FORMAT, "'%s': not an image stb_image "
			       "reads (%s)", path, stbi_failure_reason());
	int err = tex_size_ok((uint64_t)w, (uint64_t)h, path);
	if (err)
		return err;
	uint8_t *p = stbi_load_from_file(f, &w, &h, &n, 3);
	if (!p)
		return vd_fail(VD_ERR_FORMAT, "'%s': %s", path,
			       stbi_failure_reason());
	/* stb's allocator is malloc; copied anyway so vd_texture_release
	 * need not know who decoded */
	size_t bytes = (size_t)w * (size_t)h * 3;
	t->rgb = malloc(bytes);
	if (!t->rgb) {
		stbi_image_free(p);
		return vd_fail(VD_ERR_NOMEM, "texture '%s'", path);
	}
	memcpy(t->rgb, p, bytes);
	stbi_image_free(p);
	t->width = (uint32_t)w;
	t->height = (uint32_t)h;
	return VD_OK;
}

int vd_texture_load(struct vd_texture *t, const char *path)
{
	memset(t, 0, sizeof *t);
	/* a name in a mesh may point anywhere: only regular files (a FIFO
	 * would block, /dev/zero never end) */
	struct stat st;
	if (stat(path, &st) != 0)
		return vd_fail(VD_ERR_IO, "cannot open '%s': %s", path,
			       strerror(errno));
	if (!S_ISREG(st.st_mode))
		return vd_fail(VD_ERR_IO, "'%s' is not a regular file", path);
	FILE *f = fopen(path, "rb");
	if (!f)
		return vd_fail(VD_ERR_IO, "cannot open '%s': %s", path,
			       strerror(errno));
	unsigned char m[8] = {0};
	size_t got = fread(m, 1, sizeof m, f);
	int err;
	if (got == 0) {
		err = vd_fail(VD_ERR_FORMAT, "'%s' is empty", path);
	} else if (got >= 8 && !memcmp(m, "\x89PNG\r\n\x1a\n", 8)) {
		fclose(f);
		f = NULL;
		err = load_png(t, path);
	} else if (got >= 3 && m[0] == 0xff && m[1] == 0xd8 && m[2] == 0xff) {
		rewind(f);
		err = load_jpeg(t, path, f);
	} else if (got >= 2 && m[0] == 0x01 && m[1] == 0xda) {
		err = vd_fail(VD_ERR_UNSUPPORTED, "'%s' is an SGI image, which "
			      "is not supported (convert it to PNG)", path);
	} else {
		rewind(f);
		err = load_stb(t, path, f);
	}
	if (f)
		fclose(f);
	if (err)
		vd_texture_release(t);
	return err;
}

void vd_texture_release(struct vd_texture *t)
{
	if (!t)
		return;
	free(t->rgb);
	memset(t, 0, sizeof *t);
}

/* x mod n in [0, n) for a finite x already floored. */
static uint32_t wrap(double x, uint32_t n)
{
	double r = fmod(x, (double)n);
	if (r < 0)
		r += (double)n;
	uint32_t i = (uint32_t)r;
	return i < n ? i : n - 1; /* r + n may round up to n */
}

static uint8_t round_u8(double x)
{
	if (!(x > 0))
		return 0;
	if (x >= 255)
		return 255;
	return (uint8_t)(x + 0.5);
}

void vd_texture_sample(const struct vd_texture *t, double u, double v,
		       uint8_t rgb[3])
{
	uint32_t w = t->width, h = t->height;
	double x = u * w - 0.5, y = (1.0 - v) * h - 0.5;
	if (!isfinite(x) || !isfinite(y))
		x = y = 0; /* |u| near DBL_MAX: any texel is as good */
	double fx = floor(x), fy = floor(y);
	double ax = x - fx, ay = y - fy;
	uint32_t x0 = wrap(fx, w), y0 = wrap(fy, h);
	uint32_t x1 = x0 + 1 == w ? 0 : x0 + 1, y1 = y0 + 1 == h ? 0 : y0 + 1;
	const uint8_t *p00 = t->rgb + 3 * ((size_t)y0 * w + x0),
		      *p10 = t->rgb + 3 * ((size_t)y0 * w + x1),
		      *p01 = t->rgb + 3 * ((size_t)y1 * w + x0),
		      *p11 = t->rgb + 3 * ((size_t)y1 * w + x1);
	for (int c = 0; c < 3; c++) {
		double top = p00[c] + ax * (p10[c] - p00[c]);
		double bot = p01[c] + ax * (p11[c] - p01[c]);
		rgb[c] = round_u8(top + ay * (bot - top));
	}
}

void vd_tri_attr_colour(const struct vd_tri_attr *a,
			const struct vd_texture *tex, const double b[3],
			uint8_t rgb[3])
{
	if (a->texture >= 0 && tex) {
		double u = b[0] * a->uv[0][0] + b[1] * a->uv[1][0] +
			   b[2] * a->uv[2][0];
		double v = b[0] * a->uv[0][1] + b[1] * a->uv[1][1] +
			   b[2] * a->uv[2][1];
		vd_texture_sample(tex, u, v, rgb);
		return;
	}
	for (int c = 0; c < 3; c++)
		rgb[c] = round_u8(b[0] * a->rgb[0][c] + b[1] * a->rgb[1][c] +
				  b[2] * a->rgb[2][c]);
}
