/* Image comparison for the colour tables (colour paper Table 3): MSE and
 * PSNR over the RGB bytes, SSIM and MS-SSIM (Wang, Simoncelli and Bovik,
 * "Multi-scale structural similarity for image quality assessment", 2003)
 * on luma. Conventions, chosen to match the common reference code so that
 * figures compare with published ones:
 * - luma Y = 0.299 R + 0.587 G + 0.114 B on the 8-bit values, range 255;
 * - an 11x11 Gaussian window, sigma 1.5 (weights exp(-x^2 / 2 sigma^2) for
 *   |x| <= 5, normalised), statistics as population moments;
 *   K1 = 0.01, K2 = 0.03;
 * - the SSIM map is averaged over the pixels whose window lies inside the
 *   image (a 5-pixel border is left out), so no padding rule matters;
 * - MS-SSIM: 5 scales, exponents 0.0448, 0.2856, 0.3001, 0.2363, 0.1333;
 *   contrast-structure at scales 1..4, full SSIM at scale 5; between scales
 *   a 2x2 box average and subsampling by 2 (odd last rows/columns dropped).
 *   The image's short side must be at least 11 * 2^4 = 176 pixels. */
#include "voxdag.h"

#include <errno.h>
#include <math.h>
#include <png.h>
#include <stdlib.h>
#include <string.h>

#define R 5 /* window radius */

static void gauss_weights(double w[2 * R + 1])
{
	double sum = 0;
	for (int i = -R; i <= R; i++)
		sum += w[i + R] = exp(-0.5 * i * i / (1.5 * 1.5));
	for (int i = 0; i <= 2 * R; i++)
		w[i] /= sum;
}

/* Separable filter of `in` (w x h) over the valid region only: out is
 * (w - 2R) x (h - 2R). */
static void filter_valid(const double *in, int w, int h, double *tmp,
			 double *out)
{
	double g[2 * R + 1];
	gauss_weights(g);
	int ow = w - 2 * R, oh = h - 2 * R;
	for (int y = 0; y < h; y++)
		for (int x = 0; x < ow; x++) {
			double s = 0;
			for (int k = 0; k <= 2 * R; k++)
				s += g[k] * in[(size_t)y * w + x + k];
			tmp[(size_t)y * ow + x] = s;
		}
	for (int y = 0; y < oh; y++)
		for (int x = 0; x < ow; x++) {
			double s = 0;
			for (int k = 0; k <= 2 * R; k++)
				s += g[k] * tmp[(size_t)(y + k) * ow + x];
			out[(size_t)y * ow + x] = s;
		}
}

int vd_ssim_scale(const double *a, const double *b, int w, int h,
		  double *ssim, double *cs)
{
	if (w < 2 * R + 1 || h < 2 * R + 1)
		return vd_fail(VD_ERR_ARG, "%dx%d is smaller than the %dx%d "
			       "window", w, h, 2 * R + 1, 2 * R + 1);
	size_t n = (size_t)w * h, on = (size_t)(w - 2 * R) * (h - 2 * R);
	double *buf = malloc((n * 2 + on * 5 + (size_t)(w - 2 * R) * h) *
			     sizeof *buf);
	if (!buf)
		return vd_fail(VD_ERR_NOMEM, "out of memory for SSIM");
	double *prod = buf, *prod2 = buf + n, *mx = prod2 + n, *my = mx + on,
	       *sxx = my + on, *syy = sxx + on, *sxy = syy + on,
	       *tmp = sxy + on;
	filter_valid(a, w, h, tmp, mx);
	filter_valid(b, w, h, tmp, my);
	for (size_t i = 0; i < n; i++) {
		prod[i] = a[i] * a[i];
		prod2[i] = b[i] * b[i];
	}
	filter_valid(prod, w, h, tmp, sxx);
	filter_valid(prod2, w, h, tmp, syy);
	for (size_t i = 0; i < n; i++)
		prod[i] = a[i] * b[i];
	filter_valid(prod, w, h, tmp, sxy);
	const double C1 = (0.01 * 255) * (0.01 * 255),
		     C2 = (0.03 * 255) * (0.03 * 255);
	double s_sum = 0, cs_sum = 0;
	for (size_t i = 0; i < on; i++) {
		double vx = sxx[i] - mx[i] * mx[i], vy = syy[i] - my[i] * my[i],
		       cxy = sxy[i] - mx[i] * my[i];
		double c = (2 * cxy + C2) / (vx + vy + C2);
		cs_sum += c;
		s_sum += c * (2 * mx[i] * my[i] + C1) /
			 (mx[i] * mx[i] + my[i] * my[i] + C1);
	}
	free(buf);
	*ssim = s_sum / (double)on;
	*cs = cs_sum / (double)on;
	return VD_OK;
}

static void luma(const uint8_t *rgb, size_t n, double *y)
{
	for (size_t i = 0; i < n; i++)
		y[i] = 0.299 * rgb[3 * i] + 0.587 * rgb[3 * i + 1] +
		       0.114 * rgb[3 * i + 2];
}

/* 2x2 box average, subsampled: w x h -> w/2 x h/2. */
static void halve(const double *in, int w, int h, double *out)
{
	int ow = w / 2, oh = h / 2;
	for (int y = 0; y < oh; y++)
		for (int x = 0; x < ow; x++) {
			const double *p = in + (size_t)2 * y * w + 2 * x;
			out[(size_t)y * ow + x] = 0.25 * (p[0] + p[1] + p[w] +
							  p[w + 1]);
		}
}

int vd_image_metrics(const uint8_t *a, const uint8_t *b, int w, int h,
		     struct vd_image_metrics *m)
{
	memset(m, 0, sizeof *m);
	size_t n = (size_t)w * h;
	double se = 0;
	for (size_t i = 0; i < 3 * n; i++) {
		double d = (double)a[i] - b[i];
		se += d * d;
	}
	m->mse = se / (3.0 * n);
	m->psnr = m->mse > 0 ? 10 * log10(255.0 * 255.0 / m->mse) : INFINITY;
	m->ssim = m->ms_ssim = NAN;
	int small = w < 176 || h < 176;
	if (w < 2 * R + 1 || h < 2 * R + 1)
		return vd_fail(VD_ERR_ARG, "%dx%d is too small for SSIM (11 "
			       "pixels on each side)", w, h);
	double *ya = malloc(2 * n * sizeof *ya), *yb = ya ? ya + n : NULL;
	double *ha = malloc(n / 2 * sizeof *ha), *hb = malloc(n / 2 * sizeof *hb);
	if (!ya || !ha || !hb) {
		free(ya);
		free(ha);
		free(hb);
		return vd_fail(VD_ERR_NOMEM, "out of memory for MS-SSIM");
	}
	luma(a, n, ya);
	luma(b, n, yb);
	static const double beta[5] = {0.0448, 0.2856, 0.3001, 0.2363, 0.1333};
	double ms = 1;
	int err = VD_OK;
	for (int s = 0; s < (small ? 1 : 5) && !err; s++) {
		double ssim, cs;
		err = vd_ssim_scale(ya, yb, w, h, &ssim, &cs);
		if (err)
			break;
		if (s == 0)
			m->ssim = ssim;
		/* negative cs (anti-correlated structure) would give a NaN
		 * power: clamp at 0, as the reference implementations do */
		double v = s < 4 ? cs : ssim;
		ms *= pow(v > 0 ? v : 0, beta[s]);
		if (s < 4) {
			halve(ya, w, h, ha);
			halve(yb, w, h, hb);
			w /= 2;
			h /= 2;
			memcpy(ya, ha, (size_t)w * h * sizeof *ya);
			memcpy(yb, hb, (size_t)w * h * sizeof *yb);
		}
	}
	free(ya);
	free(ha);
	free(hb);
	if (err)
		return err;
	if (small)
		return vd_fail(VD_ERR_ARG, "%dx%d is too small for MS-SSIM (5 "
			       "scales need 176 pixels on each side)",
			       w, h);
	m->ms_ssim = ms;
	return VD_OK;
}

/* ---------------------------------------------------------- PNG input */

struct png_err {
	char msg[200];
};

static void png_err_fn(png_structp p, png_const_charp msg)
{
	struct png_err *e = png_get_error_ptr(p);
	snprintf(e->msg, sizeof e->msg, "%s", msg);
	png_longjmp(p, 1);
}

static void png_warn_fn(png_structp p, png_const_charp msg)
{
	(void)p;
	(void)msg;
}

int vd_png_read_rgb(const char *path, uint8_t **rgb, int *width, int *height)
{
	*rgb = NULL;
	FILE *f = fopen(path, "rb");
	if (!f)
		return vd_fail(VD_ERR_IO, "cannot open '%s': %s", path,
			       strerror(errno));
	uint8_t sig[8];
	if (fread(sig, 1, 8, f) != 8 || png_sig_cmp(sig, 0, 8)) {
		fclose(f);
		return vd_fail(VD_ERR_FORMAT, "'%s' is not a PNG file", path);
	}
	struct png_err e = {{0}};
	png_structp p = png_create_read_struct(PNG_LIBPNG_VER_STRING, &e,
					       png_err_fn, png_warn_fn);
	png_infop info = p ? png_create_info_struct(p) : NULL;
	uint8_t *volatile out = NULL;
	png_bytep *volatile rows = NULL;
	if (!p || !info) {
		png_destroy_read_struct(&p, &info, NULL);
		fclose(f);
		return vd_fail(VD_ERR_NOMEM, "out of memory for '%s'", path);
	}
	if (setjmp(png_jmpbuf(p))) {
		png_destroy_read_struct(&p, &info, NULL);
		fclose(f);
		free(out);
		free(rows);
		return vd_fail(VD_ERR_FORMAT, "'%s': %s", path,
			       e.msg[0] ? e.msg : "damaged PNG");
	}
	png_init_io(p, f);
	png_set_sig_bytes(p, 8);
	png_read_info(p, info);
	png_uint_32 w = png_get_image_width(p, info),
		    h = png_get_image_height(p, info);
	if ((uint64_t)w * h > VD_RENDER_MAX_PIXELS)
		png_error(p, "image too large");
	/* whatever is stored, hand out 8-bit RGB */
	png_set_expand(p);
	png_set_strip_16(p);
	png_set_strip_alpha(p);
	png_set_gray_to_rgb(p);
	png_read_update_info(p, info);
	if (png_get_rowbytes(p, info) != 3 * (size_t)w)
		png_error(p, "unexpected pixel layout");
	out = malloc(3 * (size_t)w * h + 1);
	rows = malloc(h * sizeof *rows + 1);
	if (!out || !rows)
		png_error(p, "out of memory");
	for (png_uint_32 y = 0; y < h; y++)
		rows[y] = out + 3 * (size_t)w * y;
	png_read_image(p, rows);
	png_read_end(p, NULL);
	png_destroy_read_struct(&p, &info, NULL);
	fclose(f);
	free(rows);
	*rgb = out;
	*width = (int)w;
	*height = (int)h;
	return VD_OK;
}
