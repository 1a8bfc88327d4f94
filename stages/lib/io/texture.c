/* texture.c - texture images for coloured meshes: decoding (libpng,
 * libjpeg-turbo, SGI here, stb_image for the rest) and the sampling rule.
 *
 * Decisions worth knowing:
 * - The format is told by the first bytes, never the name: exporters often
 *   name a JPEG .png.
 * - SGI images (.rgb, .rgba, .bw: FlightGear's and TORCS's older textures)
 *   are decoded here: no Debian library that reads them is maintained
 *   (FreeImage and DevIL are dead upstream; ImageMagick is far too large
 *   for one simple format), and the format is a 512-byte header and
 *   planar rows, verbatim or run-length encoded. Every read is checked
 *   against the file's size, every write against the row; the tests
 *   compare it with netpbm's sgitopnm, and it is fuzzed (fuzz_texture).
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

/* The formats decoded here and by stb_image read past a file's end as if
 * it went on (stb gives zeros), so a 45-byte TGA whose header claims
 * 24456x24288 texels made us allocate 3.5 GB (found by fuzz_texture).
 * Their compression (RLE, LZW) expands a byte into at most a few hundred
 * texels, so more than MAX_EXPANSION bytes of RGB per byte of file is a
 * corrupt header, said before anything is allocated. (libpng and libjpeg
 * stop at the end of the data themselves.) */
#define MAX_EXPANSION 1024

static int tex_expansion_ok(uint64_t w, uint64_t h, uint64_t file_bytes,
			    const char *path)
{
	if (w * h * 3 <= MAX_EXPANSION * file_bytes)
		return VD_OK;
	return vd_fail(VD_ERR_FORMAT, "'%s' claims %llux%llu texels in %llu "
		       "bytes: a corrupt header", path, (unsigned long long)w,
		       (unsigned long long)h, (unsigned long long)file_bytes);
}

static int load_png(struct vd_texture *t, const char *path, FILE *f)
{
	png_image img;
	memset(&img, 0, sizeof img);
	img.version = PNG_IMAGE_VERSION;
	if (!png_image_begin_read_from_stdio(&img, f))
		return vd_fail(VD_ERR_FORMAT, "'%s': %s", path, img.message);
	int err = tex_size_ok(img.width, img.height, path);
	if (err) {
		png_image_free(&img);
		return err;
	}
	/* An image with alpha (or a tRNS chunk) is read as RGBA, then the
	 * alpha dropped: read as RGB, libpng would composite its texels over
	 * a background. One without is read as RGB straight away: the same
	 * texels (there is nothing to composite) without a quarter more to
	 * decode and copy. */
	const int alpha = (img.format & PNG_FORMAT_FLAG_ALPHA) != 0;
	img.format = alpha ? PNG_FORMAT_RGBA : PNG_FORMAT_RGB;
	size_t n = (size_t)img.width * img.height;
	uint8_t *rgba = malloc((alpha ? 4 : 3) * n);
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
	uint8_t *rgb = rgba;
	if (alpha) {
		/* in place, forwards: texel i's bytes move down to 3i <= 4i
		 * (byte by byte: memmove of 3 bytes was a call a texel) */
		for (size_t i = 0; i < n; i++) {
			rgba[3 * i] = rgba[4 * i];
			rgba[3 * i + 1] = rgba[4 * i + 1];
			rgba[3 * i + 2] = rgba[4 * i + 2];
		}
		rgb = realloc(rgba, 3 * n);
	}
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

static int load_stb(struct vd_texture *t, const char *path, FILE *f,
		    uint64_t size)
{
	int w, h, n;
	if (!stbi_info_from_file(f, &w, &h, &n))
		return vd_fail(VD_ERR_FORMAT, "'%s': not an image stb_image "
			       "reads (%s)", path, stbi_failure_reason());
	int err = tex_size_ok((uint64_t)w, (uint64_t)h, path);
	if (!err)
		err = tex_expansion_ok((uint64_t)w, (uint64_t)h, size, path);
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

/* SGI image (Haeberli's format): a 512-byte big-endian header, then the
 * channels one after another, each as rows bottom to top; verbatim, or
 * run-length encoded with a table of each row's offset and length. 8 or
 * 16 bits per channel (16 keeps its high byte); 1 channel is grey, 2 grey
 * and alpha, 3 RGB, 4 RGBA. Colour-mapped images (obsolete) are refused. */
#define SGI_HEADER 512

static uint32_t be16(const uint8_t *p)
{
	return (uint32_t)p[0] << 8 | p[1];
}

static uint32_t be32(const uint8_t *p)
{
	return (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 |
	       (uint32_t)p[2] << 8 | p[3];
}

/* One row of one channel into out[0..w) (8-bit values). Returns 0, or -1
 * when the row runs past `end` or does not hold exactly w values. */
static int sgi_row(const uint8_t *in, const uint8_t *end, int rle, int bpc,
		   uint32_t w, uint8_t *out)
{
	if (!rle) {
		if ((size_t)(end - in) < (size_t)w * (size_t)bpc)
			return -1;
		for (uint32_t x = 0; x < w; x++)
			out[x] = in[(size_t)x * (size_t)bpc];
		return 0;
	}
	uint32_t x = 0;
	for (;;) {
		if (end - in < bpc)
			return -1;
		uint32_t c = bpc == 1 ? in[0] : be16(in);
		in += bpc;
		uint32_t n = c & 0x7f;
		if (n == 0)
			return x == w ? 0 : -1;
		if (n > w - x)
			return -1;
		if (c & 0x80) { /* n literal values */
			if ((size_t)(end - in) < (size_t)n * (size_t)bpc)
				return -1;
			for (uint32_t i = 0; i < n; i++, in += bpc)
				out[x++] = in[0];
		} else { /* one value n times */
			if (end - in < bpc)
				return -1;
			memset(out + x, in[0], n);
			x += n;
			in += bpc;
		}
	}
}

static int load_sgi(struct vd_texture *t, const char *path, FILE *f,
		    uint64_t file_bytes)
{
	if (file_bytes < SGI_HEADER)
		return vd_fail(VD_ERR_FORMAT, "'%s': SGI image cut inside its "
			       "header (%llu bytes)", path,
			       (unsigned long long)file_bytes);
	/* a texture is at most TEX_MAX_SIDE^2 texels of 4 channels of 16
	 * bits, and RLE at most doubles that: anything larger is corrupt */
	if (file_bytes > 8ull * TEX_MAX_SIDE * TEX_MAX_SIDE * 4 + SGI_HEADER)
		return vd_fail(VD_ERR_FORMAT, "'%s': %llu bytes is too large "
			       "for an SGI image", path,
			       (unsigned long long)file_bytes);
	size_t size = (size_t)file_bytes;
	uint8_t *b = malloc(size);
	if (!b)
		return vd_fail(VD_ERR_NOMEM, "texture '%s'", path);
	rewind(f);
	int err = VD_OK;
	if (fread(b, 1, size, f) != size) {
		err = vd_fail(VD_ERR_IO, "cannot read '%s'", path);
		goto out;
	}
	int rle = b[2], bpc = b[3];
	uint32_t dim = be16(b + 4), w = be16(b + 6), h = be16(b + 8),
		 zs = be16(b + 10), cmap = be32(b + 104);
	/* a 1-dimensional image is one row of one channel */
	if (dim == 1)
		h = zs = 1;
	else if (dim == 2)
		zs = 1;
	if (rle > 1 || (bpc != 1 && bpc != 2) || dim < 1 || dim > 3 ||
	    zs < 1 || zs > 4) {
		err = vd_fail(VD_ERR_FORMAT, "'%s': not a valid SGI image "
			      "(storage %d, %d bytes per channel, dimension "
			      "%u, %u channels)", path, rle, bpc, dim, zs);
		goto out;
	}
	if (cmap != 0) {
		err = vd_fail(VD_ERR_UNSUPPORTED, "'%s' is a colour-mapped SGI "
			      "image (colormap %u), which is not supported",
			      path, cmap);
		goto out;
	}
	if ((err = tex_size_ok(w, h, path)) ||
	    (err = tex_expansion_ok(w, h, size, path)))
		goto out;
	const uint8_t *end = b + size;
	const uint8_t *tab = b + SGI_HEADER;
	size_t rows = (size_t)h * zs;
	if (rle ? (size_t)(end - tab) / 8 < rows :
		  (size_t)(end - tab) / w / (size_t)bpc < rows) {
		err = vd_fail(VD_ERR_FORMAT, "'%s': SGI image cut inside its "
			      "%s", path, rle ? "row tables" : "rows");
		goto out;
	}
	uint8_t *plane = malloc((size_t)w * h * zs);
	t->rgb = malloc((size_t)w * h * 3);
	if (!plane || !t->rgb) {
		free(plane);
		err = vd_fail(VD_ERR_NOMEM, "texture '%s'", path);
		goto out;
	}
	for (size_t r = 0; r < rows && !err; r++) {
		const uint8_t *in;
		const uint8_t *stop = end;
		if (rle) {
			uint32_t off = be32(tab + 4 * r);
			uint32_t len = be32(tab + 4 * rows + 4 * r);
			if (off < SGI_HEADER || off > size || len > size - off) {
				err = -1;
				break;
			}
			in = b + off;
			stop = in + len;
		} else { /* every row is in the file (checked above) */
			in = b + SGI_HEADER + (size_t)w * (size_t)bpc * r;
		}
		if (sgi_row(in, stop, rle, bpc, w, plane + (size_t)w * r))
			err = -1;
	}
	if (err) {
		free(plane);
		err = vd_fail(VD_ERR_FORMAT, "'%s': SGI image with a row cut or "
			      "longer than %u pixels", path, w);
		goto out;
	}
	/* channel c's row y (from the bottom) is plane row c*h + y; our row
	 * j is from the top */
	for (uint32_t j = 0; j < h; j++) {
		size_t y = h - 1 - j;
		uint8_t *o = t->rgb + (size_t)j * w * 3;
		for (uint32_t x = 0; x < w; x++)
			for (int c = 0; c < 3; c++) {
				uint32_t z = zs >= 3 ? (uint32_t)c : 0;
				o[3 * x + c] = plane[((size_t)z * h + y) * w + x];
			}
	}
	free(plane);
	t->width = w;
	t->height = h;
out:
	free(b);
	return err;
}

/* Decodes the `size` bytes of stream f (a file or an image in memory);
 * `path` names it in messages. Closes f. */
static int tex_decode(struct vd_texture *t, const char *path, FILE *f,
		      uint64_t size)
{
	unsigned char m[8] = {0};
	size_t got = fread(m, 1, sizeof m, f);
	int err;
	rewind(f);
	if (got == 0) {
		err = vd_fail(VD_ERR_FORMAT, "'%s' is empty", path);
	} else if (got >= 8 && !memcmp(m, "\x89PNG\r\n\x1a\n", 8)) {
		err = load_png(t, path, f);
	} else if (got >= 3 && m[0] == 0xff && m[1] == 0xd8 && m[2] == 0xff) {
		err = load_jpeg(t, path, f);
	} else if (got >= 2 && m[0] == 0x01 && m[1] == 0xda) {
		err = load_sgi(t, path, f, size);
	} else {
		err = load_stb(t, path, f, size);
	}
	fclose(f);
	if (err)
		vd_texture_release(t);
	return err;
}

int vd_texture_load_mem(struct vd_texture *t, const void *data, size_t bytes,
			const char *name)
{
	memset(t, 0, sizeof *t);
	if (!data || bytes == 0)
		return vd_fail(VD_ERR_FORMAT, "'%s' is empty", name);
	/* the decoders read streams: a read-only stream over the bytes */
	FILE *f = fmemopen((void *)data, bytes, "rb");
	if (!f)
		return vd_fail(VD_ERR_NOMEM, "texture '%s': %s", name,
			       strerror(errno));
	return tex_decode(t, name, f, bytes);
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
	return tex_decode(t, path, f, (uint64_t)st.st_size);
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

/* Texel column (or row) of the floored coordinate x and of x + 1 under
 * wrap mode `mode` (enum vd_tex_wrap): repeat, clamp to the edge texels,
 * or mirrored repeat (period 2n, the second half reversed; GL's
 * MIRRORED_REPEAT). */
static void texel_pair(double x, uint32_t n, int mode, uint32_t *i0,
		       uint32_t *i1)
{
	if (mode == VD_WRAP_CLAMP) {
		*i0 = x < 0 ? 0 : x >= n - 1 ? n - 1 : (uint32_t)x;
		*i1 = x + 1 < 0 ? 0 : x + 1 >= n - 1 ? n - 1 : (uint32_t)(x + 1);
		return;
	}
	if (mode == VD_WRAP_MIRROR) {
		uint32_t a = wrap(x, 2 * n), b = a + 1 == 2 * n ? 0 : a + 1;
		*i0 = a < n ? a : 2 * n - 1 - a;
		*i1 = b < n ? b : 2 * n - 1 - b;
		return;
	}
	*i0 = wrap(x, n);
	*i1 = *i0 + 1 == n ? 0 : *i0 + 1;
}

/* floor(x) without libm's call where (int32_t)x is exact (the colour
 * pass samples once per voxel). It may give +0 where floor gives -0,
 * which neither texel_pair nor the weight x - floor(x) can tell apart. */
static inline double floor_near(double x)
{
	if (!(x > -0x1p31 && x < 0x1p31))
		return floor(x);
	double t = (double)(int32_t)x;
	return t > x ? t - 1 : t;
}

/* texel_pair, with the common cases first: repeat wrapping of a floored
 * x within [0, n - 1), where fmod would return x itself, and of one within
 * 2^31 either side (a tiled texture's coordinates), where fmod of an
 * integer is the integer remainder, exactly. */
static inline void texel_pair_fast(double x, uint32_t n, int mode,
				   uint32_t *i0, uint32_t *i1)
{
	if (mode == VD_WRAP_REPEAT && x >= 0 && x < (double)(n - 1)) {
		*i0 = (uint32_t)x;
		*i1 = *i0 + 1;
		return;
	}
	if (mode == VD_WRAP_REPEAT && x > -0x1p31 && x < 0x1p31) {
		if (!(n & (n - 1))) {
			/* a power of two (most textures): the mask is the
			 * remainder, negative x too, without a division */
			*i0 = (uint32_t)((int64_t)x & (int64_t)(n - 1));
			*i1 = (*i0 + 1) & (n - 1);
			return;
		}
		int64_t r = (int64_t)x % (int64_t)n;
		*i0 = (uint32_t)(r < 0 ? r + n : r);
		*i1 = *i0 + 1 == n ? 0 : *i0 + 1;
		return;
	}
	texel_pair(x, n, mode, i0, i1);
}

/* The four texels around (u, v) (p[0] p[1] the upper row, left and
 * right, p[2] p[3] the lower) and the weights of the right column and of
 * the lower row. */
static inline void texel_quad(const struct vd_texture *t, double u, double v,
			      const uint8_t *p[4], double *ax, double *ay)
{
	uint32_t w = t->width, h = t->height;
	double x = u * w - 0.5, y = (1.0 - v) * h - 0.5;
	if (!isfinite(x) || !isfinite(y))
		x = y = 0; /* |u| near DBL_MAX: any texel is as good */
	double fx = floor_near(x), fy = floor_near(y);
	*ax = x - fx, *ay = y - fy;
	uint32_t x0, x1, y0, y1;
	texel_pair_fast(fx, w, t->wrap[0], &x0, &x1);
	texel_pair_fast(fy, h, t->wrap[1], &y0, &y1);
	p[0] = t->rgb + 3 * ((size_t)y0 * w + x0);
	p[1] = t->rgb + 3 * ((size_t)y0 * w + x1);
	p[2] = t->rgb + 3 * ((size_t)y1 * w + x0);
	p[3] = t->rgb + 3 * ((size_t)y1 * w + x1);
}

/* The bilinear blend of q's texels, rounded. */
static inline void quad_blend(const struct vd_texel_quad *q, uint8_t rgb[3])
{
	const uint8_t *p00 = q->p[0], *p10 = q->p[1], *p01 = q->p[2],
		      *p11 = q->p[3];
	const double ax = q->ax, ay = q->ay;
	for (int c = 0; c < 3; c++) {
		double top = p00[c] + ax * (p10[c] - p00[c]);
		double bot = p01[c] + ax * (p11[c] - p01[c]);
		rgb[c] = round_u8(top + ay * (bot - top));
	}
}

void vd_texture_sample(const struct vd_texture *t, double u, double v,
		       uint8_t rgb[3])
{
	struct vd_texel_quad q;
	texel_quad(t, u, v, q.p, &q.ax, &q.ay);
	quad_blend(&q, rgb);
}

/* The texture coordinates at barycentric coordinates b. */
static inline void attr_uv(const struct vd_tri_attr *a, const double b[3],
			   double *u, double *v)
{
	*u = b[0] * a->uv[0][0] + b[1] * a->uv[1][0] + b[2] * a->uv[2][0];
	*v = b[0] * a->uv[0][1] + b[1] * a->uv[1][1] + b[2] * a->uv[2][1];
}

int vd_tri_attr_texels(const struct vd_tri_attr *a,
		       const struct vd_texture *tex, const double b[3],
		       struct vd_texel_quad *q)
{
	if (a->texture < 0 || !tex)
		return 0;
	double u, v;
	attr_uv(a, b, &u, &v);
	texel_quad(tex, u, v, q->p, &q->ax, &q->ay);
	/* the right texels are mostly on their left neighbours' lines */
	__builtin_prefetch(q->p[0]);
	__builtin_prefetch(q->p[2]);
	return 1;
}

void vd_texel_quad_colour(const struct vd_texel_quad *q, uint8_t rgb[3])
{
	quad_blend(q, rgb);
}

void vd_tri_attr_colour(const struct vd_tri_attr *a,
			const struct vd_texture *tex, const double b[3],
			uint8_t rgb[3])
{
	if (a->texture >= 0 && tex) {
		double u, v;
		attr_uv(a, b, &u, &v);
		vd_texture_sample(tex, u, v, rgb);
		return;
	}
	for (int c = 0; c < 3; c++)
		rgb[c] = round_u8(b[0] * a->rgb[0][c] + b[1] * a->rgb[1][c] +
				  b[2] * a->rgb[2][c]);
}
