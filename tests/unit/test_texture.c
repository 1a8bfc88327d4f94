/* test_texture.c - texture decoding (stages/lib/io/texture.c): headers
 * that claim far more texels than their file can hold, and the SGI image
 * decoder against two independent sources of truth:
 *  - images written by hand here, byte by byte, with their texels worked
 *    out by hand (RLE literal and repeat runs, grey, grey+alpha, RGBA,
 *    16 bits per channel, 1-dimensional);
 *  - random images encoded by netpbm's pnmtosgi (verbatim and RLE, 8 and
 *    16 bits, grey and colour), compared with the pixels it was given;
 * and every cut or corrupted row table of an RLE file is one error, never
 * a read outside the file (the sanitizer build watches). */
#include "check.h"
#include "voxdag.h"

#include <png.h>

static const char *dir;

static const char *path_of(const char *name)
{
	static char p[512];
	snprintf(p, sizeof p, "%s/%s", dir, name);
	return p;
}

static const char *write_file(const char *name, const void *b, size_t n)
{
	const char *p = path_of(name);
	FILE *f = fopen(p, "wb");
	CHECK(f != NULL);
	if (f) {
		CHECK_EQ(fwrite(b, 1, n, f), n);
		fclose(f);
	}
	return p;
}

/* A 512-byte header: storage, bytes per channel, dimension, sizes. */
static size_t header(uint8_t *b, int rle, int bpc, int dim, int w, int h,
		     int z)
{
	memset(b, 0, 512);
	b[0] = 0x01, b[1] = 0xda, b[2] = (uint8_t)rle, b[3] = (uint8_t)bpc;
	b[5] = (uint8_t)dim;
	b[6] = (uint8_t)(w >> 8), b[7] = (uint8_t)w;
	b[8] = (uint8_t)(h >> 8), b[9] = (uint8_t)h;
	b[10] = (uint8_t)(z >> 8), b[11] = (uint8_t)z;
	b[15] = 255; /* pixmax */
	return 512;
}

static void put32(uint8_t *p, uint32_t v)
{
	p[0] = (uint8_t)(v >> 24), p[1] = (uint8_t)(v >> 16);
	p[2] = (uint8_t)(v >> 8), p[3] = (uint8_t)v;
}

/* Where row r's bytes start, from the RLE offset table at `tab`. */
static size_t be_row_start(const uint8_t *b, size_t tab, int r)
{
	const uint8_t *p = b + tab + 4 * r;
	return (size_t)p[0] << 24 | (size_t)p[1] << 16 | (size_t)p[2] << 8 | p[3];
}

static int load_ok(const char *p, uint32_t w, uint32_t h,
		   const uint8_t *want)
{
	struct vd_texture t;
	int e = vd_texture_load(&t, p);
	int ok = e == VD_OK && t.width == w && t.height == h &&
		 !memcmp(t.rgb, want, (size_t)w * h * 3);
	if (!ok)
		fprintf(stderr, "%s: error %d (%s), %ux%u\n", p, e,
			e ? vd_error_detail() : "", t.width, t.height);
	vd_texture_release(&t);
	return ok;
}

/* RGBA 4x2, RLE. Rows are stored bottom first, channel after channel;
 * each row here mixes a repeat run and a literal run:
 *   R bottom: 2x10, then 20 30  -> 10 10 20 30
 *   R top:    literal 1 2 3 4
 *   G bottom: 4x50;  G top: 4x60
 *   B bottom: 1x7, literal 8 9, 1x9 -> 7 8 9 9;  B top: 4x0
 *   A: anything (dropped)
 * so the top row (ours first) is (1,60,0) (2,60,0) (3,60,0) (4,60,0) and
 * the bottom (10,50,7) (10,50,8) (20,50,9) (30,50,9). */
static void test_hand_rle_rgba(void)
{
	uint8_t b[1024];
	size_t n = header(b, 1, 1, 3, 4, 2, 4);
	static const uint8_t rows[8][12] = {
		{0x02, 10, 0x82, 20, 30, 0},    /* R y0 */
		{0x84, 1, 2, 3, 4, 0},          /* R y1 */
		{0x04, 50, 0},                  /* G y0 */
		{0x04, 60, 0},                  /* G y1 */
		{0x01, 7, 0x82, 8, 9, 0x01, 9, 0}, /* B y0 */
		{0x04, 0, 0},                   /* B y1 */
		{0x04, 255, 0},                 /* A y0 */
		{0x04, 128, 0},                 /* A y1 */
	};
	static const size_t len[8] = {6, 6, 3, 3, 8, 3, 3, 3};
	size_t tab = n, data = n + 2 * 4 * 8;
	for (int r = 0; r < 8; r++) {
		put32(b + tab + 4 * r, (uint32_t)data);
		put32(b + tab + 32 + 4 * r, (uint32_t)len[r]);
		memcpy(b + data, rows[r], len[r]);
		data += len[r];
	}
	static const uint8_t want[24] = {1, 60, 0, 2, 60, 0, 3, 60, 0, 4, 60, 0,
					 10, 50, 7, 10, 50, 8, 20, 50, 9, 30, 50, 9};
	const char *p = write_file("hand.rgba", b, data);
	CHECK(load_ok(p, 4, 2, want));
	/* every cut is an error, never a read past the end */
	struct vd_texture t;
	for (size_t cut = 0; cut < data; cut++) {
		write_file("cut.rgb", b, cut);
		int e = vd_texture_load(&t, path_of("cut.rgb"));
		CHECK(e == VD_ERR_FORMAT || (cut < 2 && e != VD_OK));
		vd_texture_release(&t);
	}
	/* a row table entry past the end of the file, a row that decodes to
	 * 5 pixels of 4, a row that ends one short */
	uint8_t c[1024];
	memcpy(c, b, data);
	put32(c + tab + 8, (uint32_t)data + 100);
	CHECK_EQ(vd_texture_load(&t, write_file("far.rgb", c, data)),
		 VD_ERR_FORMAT);
	memcpy(c, b, data);
	c[be_row_start(c, tab, 2)] = 0x05;
	CHECK_EQ(vd_texture_load(&t, write_file("long.rgb", c, data)),
		 VD_ERR_FORMAT);
	memcpy(c, b, data);
	c[be_row_start(c, tab, 2)] = 0x03;
	CHECK_EQ(vd_texture_load(&t, write_file("short.rgb", c, data)),
		 VD_ERR_FORMAT);
	/* colour-mapped: refused as such */
	memcpy(c, b, data);
	c[107] = 1;
	CHECK_EQ(vd_texture_load(&t, write_file("cmap.rgb", c, data)),
		 VD_ERR_UNSUPPORTED);
	/* a storage or channel count that does not exist */
	memcpy(c, b, data);
	c[11] = 5;
	CHECK_EQ(vd_texture_load(&t, write_file("z5.rgb", c, data)),
		 VD_ERR_FORMAT);
}

/* Verbatim grey+alpha 3x2 at 16 bits (the high byte is kept), and a
 * 1-dimensional grey row: grey g is the texel (g, g, g). */
static void test_hand_verbatim(void)
{
	uint8_t b[1024];
	size_t n = header(b, 0, 2, 3, 3, 2, 2);
	/* grey y0: 0x1234 0xff00 0x00ff; y1: 0x8000 0x7fff 0x0100 */
	static const uint8_t grey[12] = {0x12, 0x34, 0xff, 0x00, 0x00, 0xff,
					 0x80, 0x00, 0x7f, 0xff, 0x01, 0x00};
	memcpy(b + n, grey, 12);
	memset(b + n + 12, 0xee, 12); /* alpha */
	static const uint8_t want[18] = {0x80, 0x80, 0x80, 0x7f, 0x7f, 0x7f,
					 1, 1, 1, 0x12, 0x12, 0x12,
					 0xff, 0xff, 0xff, 0, 0, 0};
	CHECK(load_ok(write_file("ga16.rgb", b, n + 24), 3, 2, want));
	/* one row short: cut */
	struct vd_texture t;
	CHECK_EQ(vd_texture_load(&t, write_file("ga16cut.rgb", b, n + 23)),
		 VD_ERR_FORMAT);
	n = header(b, 0, 1, 1, 3, 7, 9); /* dimension 1: h and z ignored */
	b[n] = 5, b[n + 1] = 6, b[n + 2] = 7;
	static const uint8_t row[9] = {5, 5, 5, 6, 6, 6, 7, 7, 7};
	CHECK(load_ok(write_file("row.bw", b, n + 3), 3, 1, row));
}

/* netpbm's pnmtosgi as the independent encoder: random images, every
 * combination of storage, depth and channels, compared with the pixels
 * they were made from. */
static void test_pnmtosgi(void)
{
	if (system("command -v pnmtosgi >/dev/null 2>&1") != 0) {
		/* make deps installs netpbm; without it this is a failure */
		fprintf(stderr, "pnmtosgi (netpbm) is not installed\n");
		CHECK(0);
		return;
	}
	uint32_t seed = 12345;
	for (int k = 0; k < 8; k++) {
		int colour = k & 1, deep = k >> 1 & 1, rle = k >> 2 & 1;
		uint32_t w = 1 + k * 37 % 61, h = 1 + k * 53 % 29;
		int ch = colour ? 3 : 1, bytes = deep ? 2 : 1;
		size_t n = (size_t)w * h * ch;
		uint8_t *pix = malloc(n * bytes), *want = malloc((size_t)w * h * 3);
		/* runs and noise, so RLE has both kinds of packet */
		for (size_t i = 0; i < n * bytes; i++) {
			seed = seed * 1103515245u + 12345u;
			pix[i] = (seed >> 20) % 4 ? (uint8_t)(i / 7 % 5 * 40)
						   : (uint8_t)(seed >> 8);
		}
		for (size_t i = 0; i < (size_t)w * h; i++)
			for (int c = 0; c < 3; c++)
				want[3 * i + c] =
					pix[(i * ch + (colour ? c : 0)) * bytes];
		char pnm[64], cmd[1400];
		snprintf(pnm, sizeof pnm, "in%d.pnm", k);
		char head[64];
		int hl = snprintf(head, sizeof head, "P%c\n%u %u\n%d\n",
				  colour ? '6' : '5', w, h, deep ? 65535 : 255);
		uint8_t *file = malloc(hl + n * bytes);
		memcpy(file, head, hl);
		memcpy(file + hl, pix, n * bytes);
		write_file(pnm, file, hl + n * bytes);
		char in_path[512];
		snprintf(in_path, sizeof in_path, "%s", path_of(pnm));
		snprintf(cmd, sizeof cmd, "pnmtosgi %s '%s' > '%s/out%d.rgb' "
			 "2>/dev/null", rle ? "-rle" : "-verbatim", in_path,
			 dir, k);
		CHECK_EQ(system(cmd), 0);
		char name[32];
		snprintf(name, sizeof name, "out%d.rgb", k);
		int ok = load_ok(path_of(name), w, h, want);
		CHECK(ok);
		if (!ok)
			fprintf(stderr, "pnmtosgi case %d: colour %d, 16-bit %d, "
				"rle %d, %ux%u\n", k, colour, deep, rle, w, h);
		free(file);
		free(pix);
		free(want);
	}
}

/* fuzz_texture's first find: a 45-byte TGA whose header claims 24456x24288
 * texels; stb_image decodes it (zeros past the end), so we allocated
 * 3.5 GB. Now refused from the header, as is an SGI header that claims a
 * whole verbatim image its file does not hold. */
static void test_expansion_bomb(void)
{
	static const uint8_t tga[45] = {
		0x00, 0x00, 0x02, 0x00, 0x00, 0x00, 0x00, 0x00, 0x71, 0x00,
		0x00, 0x00, 0x40, 0x60, 0x4a, 0x5e, 0x18, 0x20, 0x28, 0x00,
		0x00, 0x00, 0x0b, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
		0x00, 0x00, 0x00, 0xb4, 0x00, 0x04, 0x08, 0xff, 0x08, 0x00,
		0x00, 0xe2, 0xe2, 0x3c, 0xb4};
	struct vd_texture t;
	CHECK_EQ(vd_texture_load(&t, write_file("bomb.tga", tga, sizeof tga)),
		 VD_ERR_FORMAT);
	uint8_t b[600];
	size_t n = header(b, 0, 1, 3, 30000, 30000, 3);
	memset(b + n, 7, sizeof b - n);
	CHECK_EQ(vd_texture_load(&t, write_file("bomb.rgb", b, sizeof b)),
		 VD_ERR_FORMAT);
	/* a real (if tiny) TGA still decodes */
	CHECK_EQ(vd_texture_load(&t, "tests/data/textured/bricks.tga"), VD_OK);
	vd_texture_release(&t);
}

/* Wrap modes, hand-computed on a 4x1 texture whose red is 0, 80, 160,
 * 240: x = 4u - 0.5 is the texel coordinate; repeat wraps to the far
 * side, clamp holds the edge texel, mirror reflects (texel -1 is texel 0,
 * texel 4 is texel 3, texel 5 is texel 2). */
static void test_wrap_modes(void)
{
	uint8_t texels[12] = {0, 1, 2, 80, 1, 2, 160, 1, 2, 240, 1, 2};
	struct vd_texture t = {4, 1, texels, {0, 0}};
	static const struct {
		double u;
		uint8_t red[3]; /* repeat, clamp, mirror */
	} cases[] = {
		{0.375, {80, 80, 80}},     /* texel 1's centre */
		{-0.125, {240, 0, 0}},     /* texel -1 */
		{1.125, {0, 240, 240}},    /* texel 4 */
		{1.375, {80, 240, 160}},   /* texel 5 */
		{0.0, {120, 0, 0}},        /* half texel -1, half texel 0 */
		{1.0, {120, 240, 240}},    /* half texel 3, half texel 4 */
		{-0.625, {80, 0, 160}},    /* texel -3: 1 wrapped, 2 mirrored */
		{-0.5, {120, 0, 120}},     /* texel -2.5 (mirrored: 1.5) */
	};
	for (size_t i = 0; i < sizeof cases / sizeof *cases; i++)
		for (int m = 0; m < 3; m++) {
			uint8_t rgb[3];
			t.wrap[0] = (uint8_t)m;
			vd_texture_sample(&t, cases[i].u, 0.5, rgb);
			if (rgb[0] != cases[i].red[m])
				fprintf(stderr, "u %g mode %d: red %d, want %d\n",
					cases[i].u, m, rgb[0], cases[i].red[m]);
			CHECK_EQ(rgb[0], cases[i].red[m]);
			CHECK_EQ(rgb[1], 1);
			CHECK_EQ(rgb[2], 2);
		}
}

/* An image in memory (a .glb's embedded PNG) decodes to the texels it was
 * written from; cut short, it is an error naming it. */
static void test_load_mem(void)
{
	uint8_t px[2 * 3 * 3];
	for (int i = 0; i < 18; i++)
		px[i] = (uint8_t)(i * 13 + 7);
	png_image img;
	memset(&img, 0, sizeof img);
	img.version = PNG_IMAGE_VERSION;
	img.width = 3;
	img.height = 2;
	img.format = PNG_FORMAT_RGB;
	png_alloc_size_t n = 0;
	CHECK(png_image_write_to_memory(&img, NULL, &n, 0, px, 0, NULL));
	uint8_t *b = malloc(n);
	CHECK(b != NULL);
	CHECK(png_image_write_to_memory(&img, b, &n, 0, px, 0, NULL));
	struct vd_texture t;
	CHECK_EQ(vd_texture_load_mem(&t, b, n, "x.glb, embedded image *0"),
		 VD_OK);
	CHECK_EQ(t.width, 3u);
	CHECK_EQ(t.height, 2u);
	CHECK(t.rgb && !memcmp(t.rgb, px, sizeof px));
	CHECK_EQ(t.wrap[0], VD_WRAP_REPEAT);
	vd_texture_release(&t);
	CHECK(vd_texture_load_mem(&t, b, n / 2, "cut *0") != VD_OK);
	CHECK(strstr(vd_error_detail(), "cut *0") != NULL);
	CHECK(t.rgb == NULL);
	CHECK(vd_texture_load_mem(&t, b, 0, "empty *0") != VD_OK);
	free(b);
}

int main(void)
{
	dir = test_tmpdir("texture");
	RUN(test_expansion_bomb);
	RUN(test_hand_rle_rgba);
	RUN(test_hand_verbatim);
	RUN(test_pnmtosgi);
	RUN(test_wrap_modes);
	RUN(test_load_mem);
	return CHECK_DONE();
}
