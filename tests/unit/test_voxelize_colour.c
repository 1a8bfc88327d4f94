/* test_voxelize_colour.c - voxelize's colour pass: colours from meshes
 * into colour chunks, against references written apart from the library:
 * - texture sampling: hand-computed texels and blends of a 2x2 texture;
 * - one big textured / vertex-coloured triangle: voxels whose centres
 *   project inside it must carry the colour at the projection, computed
 *   here with a plain bilinear / barycentric formula;
 * - the nearest-point rule on a real mesh (the bunny as a triangle soup,
 *   each triangle its own colour): every voxel against a brute force over
 *   all triangles with a closest-point routine of its own (plane
 *   projection, then edges), ties to the earlier triangle;
 * - chunked colour arrays concatenated in cell order equal the monolithic
 *   one; the SVO chunks are the same bytes with and without colours;
 * - bad input: missing or corrupt textures, NaN UVs, list colours.
 */
#include "check.h"
#include "scene.h"
#include "voxdag.h"
#include "voxel/voxel_internal.h"

#include <dirent.h>
#include <math.h>
#include <png.h>
#include <sys/stat.h>
#include <unistd.h>

static const char *dir;   /* voxelize output */
static char data[600];    /* hand-made inputs */

/* ------------------------------------------------------------ helpers */

static void write_file(const char *name, const void *p, size_t n)
{
	char path[800];
	snprintf(path, sizeof path, "%s/%s", data, name);
	FILE *f = fopen(path, "wb");
	CHECK(f != NULL);
	if (!f)
		return;
	CHECK_EQ(fwrite(p, 1, n, f), n);
	CHECK_EQ(fclose(f), 0);
}

static void write_text(const char *name, const char *text)
{
	write_file(name, text, strlen(text));
}

static const char *in(const char *name)
{
	static char path[4][800];
	static int k;
	k = (k + 1) % 4;
	snprintf(path[k], sizeof path[k], "%s/%s", data, name);
	return path[k];
}

/* The 2x2 texture of the hand computations, rows top first. */
static const uint8_t tex2[12] = {255, 0, 0,   0, 255, 0,
				 0, 0, 255,   255, 255, 255};

static void write_png2(const char *name)
{
	png_image img;
	memset(&img, 0, sizeof img);
	img.version = PNG_IMAGE_VERSION;
	img.width = img.height = 2;
	img.format = PNG_FORMAT_RGB;
	CHECK(png_image_write_to_file(&img, in(name), 0, tex2, 0, NULL));
}

static int run_voxelize(const char *mesh, int L, int L0, int colours,
			int strict, struct vd_voxelize_result *res)
{
	struct vd_voxelize_opts o = {.levels = L, .chunk_level = L0,
				     .mem_budget_bytes = 1ull << 30,
				     .threads = 2, .quiet = 1, .tool = "test",
				     .provenance = "test", .colours = colours,
				     .strict = strict};
	struct vd_voxelize_result r;
	return vd_voxelize_mesh(mesh, dir, &o, res ? res : &r);
}

/* A coloured voxel, with the cell order it came in. */
struct cvox {
	int64_t x, y, z;
	uint8_t rgb[3];
};

struct cscene {
	struct cvox *v;
	size_t n, cap;
	struct vd_transform tr;
	int chunks, col_files;
};

static int cmp_cell(const void *a, const void *b)
{
	uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
	return (x > y) - (x < y);
}

/* Loads every cell of `dir` in cell order: bricks and colours, checked to
 * belong together. */
static void load_scene(struct cscene *s)
{
	memset(s, 0, sizeof *s);
	DIR *d = opendir(dir);
	CHECK(d != NULL);
	if (!d)
		return;
	uint64_t cells[4096];
	int l0 = -1;
	struct dirent *e;
	while ((e = readdir(d))) {
		size_t n = strlen(e->d_name);
		unsigned lv;
		unsigned long long c;
		if (n > 4 && !strcmp(e->d_name + n - 4, ".col"))
			s->col_files++;
		if (n > 4 && !strcmp(e->d_name + n - 4, ".svo") &&
		    sscanf(e->d_name, "chunk-L%u-%llx", &lv, &c) == 2 &&
		    s->chunks < 4096) {
			cells[s->chunks++] = c;
			l0 = (int)lv;
		}
	}
	closedir(d);
	qsort(cells, (size_t)s->chunks, sizeof *cells, cmp_cell);
	for (int i = 0; i < s->chunks; i++) {
		char name[64], sp[800], cp[800];
		vd_chunk_file_name(name, sizeof name, l0, cells[i], "svo");
		snprintf(sp, sizeof sp, "%s/%s", dir, name);
		vd_chunk_file_name(name, sizeof name, l0, cells[i], "col");
		snprintf(cp, sizeof cp, "%s/%s", dir, name);
		struct vd_svo svo;
		struct vd_chunk_header sh, ch;
		struct vd_colours col;
		CHECK_EQ(vd_svo_load(&svo, &sh, sp), VD_OK);
		int ce = vd_colours_load(&col, &ch, cp);
		CHECK_EQ(ce, VD_OK);
		if (ce) {
			vd_svo_release(&svo);
			continue;
		}
		CHECK_EQ(vd_colours_match(&ch, &col, &sh, &svo), VD_OK);
		s->tr = sh.transform;
		uint64_t k = 0;
		for (size_t b = 0; b < svo.count; b++) {
			uint32_t bx, by, bz;
			vd_morton3_decode(svo.keys[b], &bx, &by, &bz);
			for (int bit = 0; bit < 64; bit++) {
				if (!(svo.masks[b] >> bit & 1))
					continue;
				uint32_t lx, ly, lz;
				vd_morton3_decode((uint64_t)bit, &lx, &ly, &lz);
				if (s->n == s->cap) {
					s->cap = s->cap ? 2 * s->cap : 4096;
					s->v = realloc(s->v, s->cap * sizeof *s->v);
				}
				struct cvox *v = &s->v[s->n++];
				v->x = 4 * (int64_t)bx + lx;
				v->y = 4 * (int64_t)by + ly;
				v->z = 4 * (int64_t)bz + lz;
				CHECK(k < col.voxels);
				memcpy(v->rgb, col.rgb + 3 * (k < col.voxels ? k : 0), 3);
				k++;
			}
		}
		CHECK_EQ(k, col.voxels);
		vd_colours_release(&col);
		vd_svo_release(&svo);
	}
}

/* Field by field: struct cvox has padding. */
static int scene_equal(const struct cscene *a, const struct cscene *b)
{
	if (a->n != b->n)
		return 0;
	for (size_t i = 0; i < a->n; i++)
		if (a->v[i].x != b->v[i].x || a->v[i].y != b->v[i].y ||
		    a->v[i].z != b->v[i].z ||
		    memcmp(a->v[i].rgb, b->v[i].rgb, 3))
			return 0;
	return 1;
}

static void centre(const struct cscene *s, const struct cvox *v, double c[3])
{
	c[0] = s->tr.origin[0] + ((double)v->x + 0.5) * s->tr.voxel_size;
	c[1] = s->tr.origin[1] + ((double)v->y + 0.5) * s->tr.voxel_size;
	c[2] = s->tr.origin[2] + ((double)v->z + 0.5) * s->tr.voxel_size;
}

static int count_files(const char *ext)
{
	DIR *d = opendir(dir);
	if (!d)
		return 0;
	int n = 0;
	struct dirent *e;
	size_t k = strlen(ext);
	while ((e = readdir(d))) {
		size_t m = strlen(e->d_name);
		n += m > k && !strcmp(e->d_name + m - k, ext);
	}
	closedir(d);
	return n;
}

/* ------------------------------------------- the reference computations */

static uint8_t ref_round(double x)
{
	return x <= 0 ? 0 : x >= 255 ? 255 : (uint8_t)floor(x + 0.5);
}

/* Bilinear, repeat, v = 0 bottom; written for this test from the rule's
 * text, with the texel centres at (i + 1/2) / size. */
static void ref_sample(const uint8_t *t, int w, int h, double u, double v,
		       uint8_t out[3])
{
	double x = u * w - 0.5, y = (1 - v) * h - 0.5;
	int i0 = (int)floor(x), j0 = (int)floor(y);
	double fx = x - i0, fy = y - j0;
	for (int c = 0; c < 3; c++) {
		double acc = 0;
		for (int dj = 0; dj < 2; dj++)
			for (int di = 0; di < 2; di++) {
				int i = ((i0 + di) % w + w) % w;
				int j = ((j0 + dj) % h + h) % h;
				double wt = (di ? fx : 1 - fx) * (dj ? fy : 1 - fy);
				acc += wt * t[3 * (j * w + i) + c];
			}
		out[c] = ref_round(acc);
	}
}

/* --------------------------------------------------------------- tests */

static void test_texture_sample_hand(void)
{
	struct vd_texture t = {2, 2, (uint8_t *)tex2,
			       {VD_WRAP_REPEAT, VD_WRAP_REPEAT}};
	static const struct {
		double u, v;
		uint8_t rgb[3];
	} cases[] = {
		{0.25, 0.75, {255, 0, 0}},     /* top-left texel centre */
		{0.75, 0.75, {0, 255, 0}},     /* top-right */
		{0.25, 0.25, {0, 0, 255}},     /* bottom-left: v = 0 is the bottom */
		{0.75, 0.25, {255, 255, 255}},
		{0.5, 0.75, {128, 128, 0}},    /* halfway TL-TR: 127.5 rounds up */
		{0.5, 0.5, {128, 128, 128}},   /* all four alike */
		{0.375, 0.75, {191, 64, 0}},   /* 3/4 TL + 1/4 TR */
		{0.0, 0.75, {128, 128, 0}},    /* the edge blends with the wrap */
		{1.25, 0.75, {255, 0, 0}},     /* repeat */
		{-0.75, 0.75, {255, 0, 0}},
		{0.25, 2.75, {255, 0, 0}},
		{0.25, -1.25, {255, 0, 0}},
		{1e9 + 0.25, 0.75, {255, 0, 0}},
	};
	for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
		uint8_t got[3];
		vd_texture_sample(&t, cases[i].u, cases[i].v, got);
		for (int c = 0; c < 3; c++)
			if (got[c] != cases[i].rgb[c]) {
				fprintf(stderr, "case %zu (u %g v %g) channel %d: "
					"%d, want %d\n", i, cases[i].u, cases[i].v,
					c, got[c], cases[i].rgb[c]);
				CHECK(0);
			}
	}
	/* the reference agrees with the hand values on a fine sweep */
	int bad = 0;
	for (int i = -40; i <= 40; i++)
		for (int j = -40; j <= 40; j++) {
			uint8_t a[3], b[3];
			double u = i / 16.0 + 1 / 64.0, v = j / 16.0 + 1 / 128.0;
			vd_texture_sample(&t, u, v, a);
			ref_sample(tex2, 2, 2, u, v, b);
			bad += memcmp(a, b, 3) != 0;
		}
	CHECK_EQ(bad, 0);
}

/* vd_texture_sample as it was written first (libm's floor, fmod for
 * every repeat), which its fast paths must match bit for bit: the colours
 * of every scene voxelized before them depend on it. */
static void old_pair(double x, uint32_t n, uint32_t *i0, uint32_t *i1)
{
	double r = fmod(x, (double)n);
	if (r < 0)
		r += (double)n;
	uint32_t i = (uint32_t)r;
	*i0 = i < n ? i : n - 1;
	*i1 = *i0 + 1 == n ? 0 : *i0 + 1;
}

static void old_sample(const struct vd_texture *t, double u, double v,
		       uint8_t rgb[3])
{
	uint32_t w = t->width, h = t->height;
	double x = u * w - 0.5, y = (1.0 - v) * h - 0.5;
	if (!isfinite(x) || !isfinite(y))
		x = y = 0;
	double fx = floor(x), fy = floor(y);
	double ax = x - fx, ay = y - fy;
	uint32_t x0, x1, y0, y1;
	old_pair(fx, w, &x0, &x1);
	old_pair(fy, h, &y0, &y1);
	const uint8_t *p00 = t->rgb + 3 * ((size_t)y0 * w + x0),
		      *p10 = t->rgb + 3 * ((size_t)y0 * w + x1),
		      *p01 = t->rgb + 3 * ((size_t)y1 * w + x0),
		      *p11 = t->rgb + 3 * ((size_t)y1 * w + x1);
	for (int c = 0; c < 3; c++) {
		double top = p00[c] + ax * (p10[c] - p00[c]);
		double bot = p01[c] + ax * (p11[c] - p01[c]);
		double g = top + ay * (bot - top);
		rgb[c] = !(g > 0) ? 0 : g >= 255 ? 255 : (uint8_t)(g + 0.5);
	}
}

static void test_texture_sample_same_as_first(void)
{
	/* powers of two take a mask, the others a remainder */
	static const uint32_t sizes[][2] = {{1, 1}, {2, 2}, {7, 5}, {64, 33},
					    {1, 300}, {256, 128}};
	uint64_t seed = 12345;
	int bad = 0;
	for (size_t k = 0; k < sizeof sizes / sizeof *sizes; k++) {
		uint32_t w = sizes[k][0], h = sizes[k][1];
		uint8_t *rgb = malloc(3 * (size_t)w * h);
		for (size_t i = 0; i < 3 * (size_t)w * h; i++) {
			seed = seed * 6364136223846793005ull + 1442695040888963407ull;
			rgb[i] = (uint8_t)(seed >> 56);
		}
		struct vd_texture t = {w, h, rgb, {VD_WRAP_REPEAT, VD_WRAP_REPEAT}};
		for (int i = 0; i < 200000; i++) {
			seed = seed * 6364136223846793005ull + 1442695040888963407ull;
			double u = ((double)(seed >> 11) * 0x1p-53 - 0.5) * 8;
			seed = seed * 6364136223846793005ull + 1442695040888963407ull;
			double v = ((double)(seed >> 11) * 0x1p-53 - 0.5) * 8;
			/* texel edges and centres exactly, and far periods */
			if (i % 4 == 1)
				u = floor(u * w * 2) / (2 * w);
			if (i % 4 == 2)
				v = floor(v * h * 2) / (2 * h), u *= 1e7;
			if (i % 97 == 3)
				u = -0.0, v = 1e300;
			uint8_t a[3], b[3];
			vd_texture_sample(&t, u, v, a);
			old_sample(&t, u, v, b);
			if (memcmp(a, b, 3) && bad++ < 5)
				fprintf(stderr, "%ux%u u %.17g v %.17g: %d %d %d, "
					"first %d %d %d\n", w, h, u, v, a[0],
					a[1], a[2], b[0], b[1], b[2]);
		}
		free(rgb);
	}
	CHECK_EQ(bad, 0);
}

/* voxelize takes a triangle's colour as it is when its three corners
 * have the same colour and no texture, without interpolating, for
 * weights within +-2 (those of every region of the nearest point sum to
 * 1 within a few ulps there): vd_tri_attr_colour must give that colour
 * for every value and such weights, as the regions write them. */
static void test_uniform_colour(void)
{
	uint64_t seed = 7;
	int bad = 0;
	for (int c = 0; c < 256; c++) {
		struct vd_tri_attr a;
		memset(&a, 0, sizeof a);
		a.texture = -1;
		for (int k = 0; k < 3; k++)
			a.rgb[k][0] = a.rgb[k][1] = a.rgb[k][2] = (uint8_t)c;
		for (int i = 0; i < 20000; i++) {
			seed = seed * 6364136223846793005ull + 1442695040888963407ull;
			double v = (double)(seed >> 11) * 0x1p-53 * 4 - 2;
			seed = seed * 6364136223846793005ull + 1442695040888963407ull;
			double t = (double)(seed >> 11) * 0x1p-53 * 4 - 2;
			double b[3];
			switch (i % 4) {
			case 0: /* the face */
				b[0] = 1 - v - t, b[1] = v, b[2] = t;
				break;
			case 1: /* an edge */
				b[0] = 1 - v, b[1] = v, b[2] = 0;
				break;
			case 2:
				b[0] = 0, b[1] = 1 - t, b[2] = t;
				break;
			default: /* a corner */
				b[0] = b[1] = 0, b[2] = 1;
			}
			if (fabs(b[0]) > 2 || fabs(b[1]) > 2 || fabs(b[2]) > 2)
				continue;
			uint8_t got[3];
			vd_tri_attr_colour(&a, NULL, b, got);
			if ((got[0] != c || got[1] != c || got[2] != c) && bad++ < 5)
				fprintf(stderr, "colour %d, weights %.17g %.17g "
					"%.17g: %d\n", c, b[0], b[1], b[2], got[0]);
		}
	}
	CHECK_EQ(bad, 0);
}

static void test_texture_formats(void)
{
	/* the bundled scene's lossless textures decode to make.py's texels */
	static const struct {
		const char *file;
		uint32_t w, h;
		uint8_t first[3], last[3];
	} t[] = {
		{"tests/data/textured/checker.png", 4, 4, {230, 30, 30}, {240, 220, 30}},
		{"tests/data/textured/bricks.tga", 2, 2, {180, 60, 40}, {180, 60, 40}},
		{"tests/data/textured/tiles.bmp", 2, 2, {10, 120, 200}, {10, 120, 200}},
	};
	for (size_t i = 0; i < sizeof t / sizeof *t; i++) {
		struct vd_texture x;
		CHECK_EQ(vd_texture_load(&x, t[i].file), VD_OK);
		CHECK_EQ(x.width, t[i].w);
		CHECK_EQ(x.height, t[i].h);
		if (x.rgb) {
			CHECK(!memcmp(x.rgb, t[i].first, 3));
			CHECK(!memcmp(x.rgb + 3 * (x.width * x.height - 1),
				      t[i].last, 3));
		}
		vd_texture_release(&x);
	}
	/* checker.png row 1 (second from the top) starts with white */
	struct vd_texture x;
	CHECK_EQ(vd_texture_load(&x, "tests/data/textured/checker.png"), VD_OK);
	CHECK(x.rgb && x.rgb[12] == 250 && x.rgb[13] == 250);
	vd_texture_release(&x);
	/* a JPEG: 8x8, left half orange, right half teal (lossy: near) */
	CHECK_EQ(vd_texture_load(&x, "tests/data/textured/photo.jpg"), VD_OK);
	CHECK_EQ(x.width, 8);
	if (x.rgb) {
		CHECK(abs(x.rgb[0] - 240) < 12 && abs(x.rgb[2] - 20) < 12);
		CHECK(abs(x.rgb[3 * 7] - 20) < 12 && abs(x.rgb[3 * 7 + 1] - 160) < 12);
	}
	vd_texture_release(&x);
	/* corrupt and missing */
	unsigned char junk[64];
	FILE *f = fopen("tests/data/textured/checker.png", "rb");
	size_t n = f ? fread(junk, 1, 40, f) : 0;
	if (f)
		fclose(f);
	write_file("cut.png", junk, n);
	CHECK_EQ(vd_texture_load(&x, in("cut.png")), VD_ERR_FORMAT);
	write_text("bad.jpg", "\xff\xd8\xff\xe0 not really a jpeg at all");
	CHECK_EQ(vd_texture_load(&x, in("bad.jpg")), VD_ERR_FORMAT);
	CHECK_EQ(vd_texture_load(&x, in("absent.png")), VD_ERR_IO);
	/* an SGI image cut inside its header (tests/unit/test_texture_sgi.c
	 * has the rest) */
	write_text("sgi.rgb", "\x01\xda\x01\x01 sgi");
	CHECK_EQ(vd_texture_load(&x, in("sgi.rgb")), VD_ERR_FORMAT);
}

/* One big triangle in the plane z = Z0 with corner UVs (0,0) (1,0) (0,1)
 * (so uv = (x, y) over it), and two specks at (0,0,0) and (1,1,1) that
 * make the grid a unit cube. Z0 is not dyadic, so the plane lies inside
 * one layer of voxels. */
#define Z0 0.4

static const char *big_obj(const char *name, const char *mtl_body,
			   double du, double dv)
{
	char obj[2048];
	snprintf(obj, sizeof obj,
		 "mtllib %s.mtl\n"
		 "v 0 0 0.4\nv 1 0 0.4\nv 0 1 0.4\n"
		 "v 0 0 0\nv 0.001 0 0\nv 0 0.001 0\n"
		 "v 1 1 1\nv 0.999 1 1\nv 1 0.999 1\n"
		 "vt %.17g %.17g\nvt %.17g %.17g\nvt %.17g %.17g\n"
		 "usemtl tex\nf 1/1 2/2 3/3\nusemtl speck\nf 4 5 6\nf 7 8 9\n",
		 name, du, dv, 1 + du, dv, du, 1 + dv);
	char fname[128];
	snprintf(fname, sizeof fname, "%s.obj", name);
	write_text(fname, obj);
	snprintf(fname, sizeof fname, "%s.mtl", name);
	write_text(fname, mtl_body);
	snprintf(fname, sizeof fname, "%s.obj", name);
	return in(fname);
}

/* Checks every voxel of the scene in `dir` whose centre projects strictly
 * inside the big triangle: its colour must be want(ctx, x, y). Returns
 * how many were checked. */
static int check_big(const struct cscene *s,
		     void (*want)(void *ctx, double x, double y, uint8_t rgb[3]),
		     void *ctx)
{
	int checked = 0, bad = 0;
	double vs = s->tr.voxel_size;
	for (size_t i = 0; i < s->n; i++) {
		double c[3];
		centre(s, &s->v[i], c);
		if (fabs(c[2] - Z0) >= vs / 2 || c[0] <= 1e-9 || c[1] <= 1e-9 ||
		    c[0] + c[1] >= 1 - 1e-9)
			continue;
		uint8_t w[3];
		want(ctx, c[0], c[1], w);
		checked++;
		if (memcmp(w, s->v[i].rgb, 3)) {
			if (bad++ < 5)
				fprintf(stderr, "voxel at (%g %g %g): %d %d %d, "
					"want %d %d %d\n", c[0], c[1], c[2],
					s->v[i].rgb[0], s->v[i].rgb[1],
					s->v[i].rgb[2], w[0], w[1], w[2]);
		}
	}
	CHECK_EQ(bad, 0);
	return checked;
}

struct uvmap {
	double su, sv, du, dv; /* uv = (x * su + du, y * sv + dv) */
};

static void want_tex(void *ctx, double x, double y, uint8_t rgb[3])
{
	const struct uvmap *m = ctx;
	ref_sample(tex2, 2, 2, x * m->su + m->du, y * m->sv + m->dv, rgb);
}

static void test_big_triangle_texture(void)
{
	write_png2("tex2.png");
	static const char mtl[] = "newmtl tex\nKd 0.1 0.1 0.1\nmap_Kd tex2.png\n"
				  "newmtl speck\nKd 1 1 1\n";
	for (int L = 4; L <= 6; L++) {
		struct vd_voxelize_result res;
		CHECK_EQ(run_voxelize(big_obj("big", mtl, 0, 0), L, 0, 1, 0, &res),
			 VD_OK);
		CHECK_EQ(res.colours, 1);
		CHECK_EQ(res.textures_loaded, 1);
		struct cscene s;
		load_scene(&s);
		struct uvmap m = {1, 1, 0, 0};
		int n = check_big(&s, want_tex, &m);
		CHECK(n > (1 << (2 * L)) / 4); /* about half the layer */
		free(s.v);
	}
	/* UVs shifted by whole repeats (and negative) give the same voxels */
	struct cscene a, b;
	CHECK_EQ(run_voxelize(big_obj("big", mtl, 0, 0), 5, 0, 1, 0, NULL), VD_OK);
	load_scene(&a);
	CHECK_EQ(run_voxelize(big_obj("shift", mtl, 3, -2), 5, 0, 1, 0, NULL),
		 VD_OK);
	load_scene(&b);
	CHECK_EQ(a.n, b.n);
	CHECK(scene_equal(&a, &b));
	free(a.v);
	free(b.v);
}

static void test_ac3d_texrep_texoff(void)
{
	write_png2("tex2.png");
	write_text("big.ac",
		   "AC3Db\n"
		   "MATERIAL \"m\" rgb 1 1 1 amb 0 0 0 emis 0 0 0 spec 0 0 0 shi 0 trans 0\n"
		   "OBJECT world\nkids 2\n"
		   "OBJECT poly\ntexture \"tex2.png\"\ntexrep 2 3\ntexoff 0.25 0.125\n"
		   "numvert 3\n0 0 0.4\n1 0 0.4\n0 1 0.4\nnumsurf 1\nSURF 0x10\nmat 0\n"
		   "refs 3\n0 0 0\n1 1 0\n2 0 1\nkids 0\n"
		   "OBJECT poly\nnumvert 6\n0 0 0\n0.001 0 0\n0 0.001 0\n"
		   "1 1 1\n0.999 1 1\n1 0.999 1\nnumsurf 2\nSURF 0x10\nmat 0\n"
		   "refs 3\n0 0 0\n1 0 0\n2 0 0\nSURF 0x10\nmat 0\nrefs 3\n"
		   "3 0 0\n4 0 0\n5 0 0\nkids 0\n");
	CHECK_EQ(run_voxelize(in("big.ac"), 5, 0, 1, 0, NULL), VD_OK);
	struct cscene s;
	load_scene(&s);
	struct uvmap m = {2, 3, 0.25, 0.125};
	CHECK(check_big(&s, want_tex, &m) > 200);
	free(s.v);
}

/* TORCS's .acc: four texture lines per object (base, tiled, skids, shad)
 * and one UV pair per unit on each ref line. The base texture with the
 * first pair must colour the triangle; the tiled unit (a grey PNG, its
 * UVs scrambled) and the "empty_texture_no_mapping" units must not
 * replace it, and under --strict the latter are not missing files. */
static void test_acc_base_texture(void)
{
	write_png2("tex2.png");
	static const uint8_t grey[12] = {90, 90, 90, 90, 90, 90,
					 90, 90, 90, 90, 90, 90};
	png_image img;
	memset(&img, 0, sizeof img);
	img.version = PNG_IMAGE_VERSION;
	img.width = img.height = 2;
	img.format = PNG_FORMAT_RGB;
	CHECK(png_image_write_to_file(&img, in("grey.png"), 0, grey, 0, NULL));
	write_text("big.acc",
		   "AC3Db\n"
		   "MATERIAL \"m\" rgb 1 1 1 amb 0 0 0 emis 0 0 0 spec 0 0 0 shi 0 trans 0\n"
		   "OBJECT world\nkids 2\n"
		   "OBJECT poly\nname \"track\"\ntexture \"tex2.png\" base\n"
		   "texture \"grey.png\" tiled\n"
		   "texture empty_texture_no_mapping skids\n"
		   "texture empty_texture_no_mapping shad\n"
		   "numvert 3\n0 0 0.4 0 0 1\n1 0 0.4 0 0 1\n0 1 0.4 0 0 1\n"
		   "numsurf 1\nSURF 0x10\nmat 0\n"
		   "refs 3\n0 0 0 0.7 0.3\n1 1 0 0.2 0.9\n2 0 1 0.5 0.5\nkids 0\n"
		   "OBJECT poly\ntexture empty_texture_no_mapping base\n"
		   "numvert 6\n0 0 0\n0.001 0 0\n0 0.001 0\n"
		   "1 1 1\n0.999 1 1\n1 0.999 1\nnumsurf 2\nSURF 0x10\nmat 0\n"
		   "refs 3\n0 0 0\n1 0 0\n2 0 0\nSURF 0x10\nmat 0\nrefs 3\n"
		   "3 0 0\n4 0 0\n5 0 0\nkids 0\n");
	CHECK_EQ(run_voxelize(in("big.acc"), 5, 0, 1, 1, NULL), VD_OK);
	struct cscene s;
	load_scene(&s);
	struct uvmap m = {1, 1, 0, 0};
	CHECK(check_big(&s, want_tex, &m) > 200);
	free(s.v);
}

struct bary_ctx {
	uint8_t c[3][3];
};

static void want_bary(void *ctx, double x, double y, uint8_t rgb[3])
{
	const struct bary_ctx *b = ctx;
	double w[3] = {1 - x - y, x, y};
	for (int k = 0; k < 3; k++)
		rgb[k] = ref_round(w[0] * b->c[0][k] + w[1] * b->c[1][k] +
				   w[2] * b->c[2][k]);
}

/* The big triangle as a PLY with vertex colours of property type `type`
 * (the corners red, green, blue at full scale `one`). */
static const char *big_ply(const char *name, const char *type, double one)
{
	char text[2048];
	snprintf(text, sizeof text,
		 "ply\nformat ascii 1.0\nelement vertex 9\n"
		 "property float x\nproperty float y\nproperty float z\n"
		 "property %s red\nproperty %s green\nproperty %s blue\n"
		 "property %s alpha\n"
		 "element face 3\nproperty list uchar int vertex_indices\n"
		 "end_header\n"
		 "0 0 0.4 %g 0 0 %g\n1 0 0.4 0 %g 0 %g\n0 1 0.4 0 0 %g %g\n"
		 "0 0 0 0 0 0 0\n0.001 0 0 0 0 0 0\n0 0.001 0 0 0 0 0\n"
		 "1 1 1 0 0 0 0\n0.999 1 1 0 0 0 0\n1 0.999 1 0 0 0 0\n"
		 "3 0 1 2\n3 3 4 5\n3 6 7 8\n",
		 type, type, type, type, one, one, one, one, one, one);
	write_text(name, text);
	return in(name);
}

static void test_big_triangle_vertex_colours(void)
{
	struct bary_ctx b = {{{255, 0, 0}, {0, 255, 0}, {0, 0, 255}}};
	static const struct {
		const char *type;
		double one;
	} types[] = {{"uchar", 255}, {"float", 1}, {"double", 1},
		     {"ushort", 65535}};
	struct cscene first = {0};
	for (size_t t = 0; t < sizeof types / sizeof *types; t++) {
		CHECK_EQ(run_voxelize(big_ply("big.ply", types[t].type,
					      types[t].one), 6, 0, 1, 0, NULL),
			 VD_OK);
		struct cscene s;
		load_scene(&s);
		CHECK(check_big(&s, want_bary, &b) > 1000);
		if (t == 0)
			first = s;
		else {
			CHECK(scene_equal(&s, &first));
			free(s.v);
		}
	}
	free(first.v);
	/* OBJ vertex colours, the "v x y z r g b" extension, alike */
	write_text("vc.obj", "v 0 0 0.4 1 0 0\nv 1 0 0.4 0 1 0\nv 0 1 0.4 0 0 1\n"
		   "v 0 0 0\nv 0.001 0 0\nv 0 0.001 0\n"
		   "v 1 1 1\nv 0.999 1 1\nv 1 0.999 1\nf 1 2 3\nf 4 5 6\nf 7 8 9\n");
	CHECK_EQ(run_voxelize(in("vc.obj"), 6, 0, 1, 0, NULL), VD_OK);
	struct cscene s;
	load_scene(&s);
	CHECK(check_big(&s, want_bary, &b) > 1000);
	free(s.v);
}

/* Exact ties go to the earlier triangle: two coincident triangles of
 * different colours, in both orders, and across chunkings. */
static void test_tie_earlier_wins(void)
{
	static const char mtl[] = "newmtl red\nKd 1 0 0\nnewmtl blue\nKd 0 0 1\n";
	write_text("tie.mtl", mtl);
	for (int order = 0; order < 2; order++) {
		char obj[512];
		snprintf(obj, sizeof obj, "mtllib tie.mtl\nv 0 0 0.4\nv 1 0 0.4\n"
			 "v 0 1 0.4\nv 0 0 0\nv 1 1 1\nusemtl %s\nf 1 2 3\n"
			 "usemtl %s\nf 3 1 2\nf 4 4 4\nf 5 5 5\n",
			 order ? "blue" : "red", order ? "red" : "blue");
		write_text("tie.obj", obj);
		for (int L0 = 0; L0 <= 2; L0 += 2) {
			CHECK_EQ(run_voxelize(in("tie.obj"), 6, L0, 1, 0, NULL),
				 VD_OK);
			struct cscene s;
			load_scene(&s);
			int want = order ? 2 : 0, good = 0, bad = 0;
			for (size_t i = 0; i < s.n; i++) {
				double c[3];
				centre(&s, &s.v[i], c);
				if (fabs(c[2] - Z0) > s.tr.voxel_size)
					continue; /* the two points */
				if (s.v[i].rgb[want] == 255)
					good++;
				else
					bad++;
			}
			CHECK(good > 1000);
			CHECK_EQ(bad, 0);
			free(s.v);
		}
	}
}

/* ------------------------------------------- nearest point: brute force */

static double rdot(const double a[3], const double b[3])
{
	return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* Squared distance from the origin to segment (a, b). */
static double ref_seg(const double a[3], const double b[3])
{
	double d[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
	double l = rdot(d, d), t = l > 0 ? -rdot(a, d) / l : 0;
	t = t < 0 ? 0 : t > 1 ? 1 : t;
	double q[3] = {a[0] + t * d[0], a[1] + t * d[1], a[2] + t * d[2]};
	return rdot(q, q);
}

/* Squared distance from the origin to triangle (a, b, c): the foot of
 * the perpendicular on the plane if it is inside, else the nearest edge. */
static double ref_tri(const double a[3], const double b[3], const double c[3])
{
	double e1[3], e2[3], n[3];
	for (int i = 0; i < 3; i++)
		e1[i] = b[i] - a[i], e2[i] = c[i] - a[i];
	n[0] = e1[1] * e2[2] - e1[2] * e2[1];
	n[1] = e1[2] * e2[0] - e1[0] * e2[2];
	n[2] = e1[0] * e2[1] - e1[1] * e2[0];
	double nn = rdot(n, n);
	if (nn > 0) {
		double t = rdot(a, n) / nn, f[3]; /* foot of the origin */
		for (int i = 0; i < 3; i++)
			f[i] = t * n[i];
		const double *p[3] = {a, b, c};
		int inside = 1;
		for (int k = 0; k < 3; k++) {
			const double *u = p[k], *v = p[(k + 1) % 3];
			double ev[3] = {v[0] - u[0], v[1] - u[1], v[2] - u[2]};
			double fu[3] = {f[0] - u[0], f[1] - u[1], f[2] - u[2]};
			double cr[3] = {ev[1] * fu[2] - ev[2] * fu[1],
					ev[2] * fu[0] - ev[0] * fu[2],
					ev[0] * fu[1] - ev[1] * fu[0]};
			inside &= rdot(cr, n) >= 0;
		}
		if (inside)
			return rdot(f, f);
	}
	double d = ref_seg(a, b), d2 = ref_seg(b, c), d3 = ref_seg(c, a);
	return fmin(d, fmin(d2, d3));
}

/* The bunny as a triangle soup in which triangle i has colour i + 1. */
/* Writes the n triangles t, corner k of triangle i coloured
 * rgb[9i + 3k ..], as a binary PLY of separate triangles at `path`. */
static void write_tri_ply(const char *path, size_t n,
			  const struct vd_triangle *t, const uint8_t *rgb)
{
	FILE *f = fopen(path, "wb");
	fprintf(f, "ply\nformat binary_little_endian 1.0\nelement vertex %zu\n"
		"property float x\nproperty float y\nproperty float z\n"
		"property uchar red\nproperty uchar green\nproperty uchar blue\n"
		"element face %zu\nproperty list uchar int vertex_indices\n"
		"end_header\n", 3 * n, n);
	for (size_t i = 0; i < n; i++)
		for (int k = 0; k < 3; k++) {
			fwrite(t[i].v[k], 4, 3, f);
			fwrite(rgb + 9 * i + 3 * k, 1, 3, f);
		}
	for (size_t i = 0; i < n; i++) {
		uint8_t three = 3;
		int32_t idx[3] = {(int32_t)(3 * i), (int32_t)(3 * i + 1),
				  (int32_t)(3 * i + 2)};
		fwrite(&three, 1, 1, f);
		fwrite(idx, 4, 3, f);
	}
	CHECK_EQ(fclose(f), 0);
}

static const char *bunny_soup(uint32_t *ntri)
{
	struct vd_mesh *m;
	CHECK_EQ(vd_mesh_open(&m, "tests/data/bunny.ply"), VD_OK);
	static struct vd_triangle buf[4096];
	size_t n, cap = 0, count = 0;
	struct vd_triangle *all = NULL;
	while (vd_mesh_read(m, buf, 4096, &n) == VD_OK && n) {
		if (count + n > cap) {
			cap = 2 * (count + n);
			all = realloc(all, cap * sizeof *all);
		}
		memcpy(all + count, buf, n * sizeof *buf);
		count += n;
	}
	vd_mesh_close(m);
	/* each triangle's colour is its number, from 1 */
	uint8_t *rgb = malloc(9 * count);
	for (size_t i = 0; i < count; i++)
		for (int k = 0; k < 3; k++) {
			uint32_t id = (uint32_t)i + 1;
			rgb[9 * i + 3 * k] = (uint8_t)(id >> 16);
			rgb[9 * i + 3 * k + 1] = (uint8_t)(id >> 8);
			rgb[9 * i + 3 * k + 2] = (uint8_t)id;
		}
	const char *path = in("soup.ply");
	write_tri_ply(path, count, all, rgb);
	free(rgb);
	free(all);
	*ntri = (uint32_t)count;
	return path;
}

static void test_nearest_brute_force(void)
{
	uint32_t ntri;
	const char *soup = bunny_soup(&ntri);
	const int L = 7;
	CHECK(ntri > 60000);
	CHECK_EQ(run_voxelize(soup, L, 0, 1, 0, NULL), VD_OK);
	struct cscene s;
	load_scene(&s);
	CHECK(s.n > 10000);

	/* the same grid from the same triangles */
	struct vd_mesh *m;
	CHECK_EQ(vd_mesh_open(&m, soup), VD_OK);
	struct vd_snapped_tri *st = malloc(ntri * sizeof *st);
	static struct vd_triangle buf[4096];
	size_t n, k = 0;
	while (vd_mesh_read(m, buf, 4096, &n) == VD_OK && n)
		for (size_t i = 0; i < n; i++, k++)
			CHECK_EQ(vd_snap_triangle(&st[k], &buf[i], &s.tr), VD_OK);
	vd_mesh_close(m);
	CHECK_EQ(k, ntri);

	/* every triangle, every voxel of its box, the exact overlap test */
	size_t side = (size_t)1 << L;
	double *best = malloc(side * side * side * sizeof *best);
	uint32_t *who = calloc(side * side * side, sizeof *who);
	for (size_t i = 0; i < side * side * side; i++)
		best[i] = INFINITY;
	const int64_t u = vd_snap_voxel(L);
	for (uint32_t t = 0; t < ntri; t++) {
		int64_t lo[3], hi[3];
		for (int a = 0; a < 3; a++) {
			int64_t mn = st[t].v[0][a], mx = mn;
			for (int c = 1; c < 3; c++) {
				mn = st[t].v[c][a] < mn ? st[t].v[c][a] : mn;
				mx = st[t].v[c][a] > mx ? st[t].v[c][a] : mx;
			}
			lo[a] = mn / u - 1, hi[a] = mx / u;
			lo[a] = lo[a] < 0 ? 0 : lo[a];
			hi[a] = hi[a] >= (int64_t)side ? (int64_t)side - 1 : hi[a];
		}
		for (int64_t x = lo[0]; x <= hi[0]; x++)
			for (int64_t y = lo[1]; y <= hi[1]; y++)
				for (int64_t z = lo[2]; z <= hi[2]; z++) {
					int64_t p[3] = {x, y, z};
					if (!vd_tri_box_overlap(&st[t], L, p, 1))
						continue;
					double q[3][3];
					for (int c = 0; c < 3; c++)
						for (int a = 0; a < 3; a++)
							q[c][a] = ((double)st[t].v[c][a] -
								   ((double)p[a] + 0.5) * (double)u) /
								  (double)u;
					double d = ref_tri(q[0], q[1], q[2]);
					size_t i = ((size_t)x * side + (size_t)y) * side + (size_t)z;
					if (d < best[i]) {
						best[i] = d;
						who[i] = t + 1;
					}
				}
	}
	/* same voxels; each the nearest triangle's colour, or within
	 * rounding of it (two triangles at the same distance: a shared edge
	 * or vertex, where the last bits decide) */
	size_t refn = 0, mismatch = 0, near_tie = 0;
	for (size_t i = 0; i < side * side * side; i++)
		refn += who[i] != 0;
	CHECK_EQ(refn, s.n);
	for (size_t i = 0; i < s.n; i++) {
		const struct cvox *v = &s.v[i];
		size_t g = ((size_t)v->x * side + (size_t)v->y) * side + (size_t)v->z;
		uint32_t id = (uint32_t)v->rgb[0] << 16 | (uint32_t)v->rgb[1] << 8 |
			      v->rgb[2];
		if (id == who[g])
			continue;
		if (id == 0 || id > ntri) {
			mismatch++;
			continue;
		}
		double q[3][3];
		int64_t p[3] = {v->x, v->y, v->z};
		for (int c = 0; c < 3; c++)
			for (int a = 0; a < 3; a++)
				q[c][a] = ((double)st[id - 1].v[c][a] -
					   ((double)p[a] + 0.5) * (double)u) /
					  (double)u;
		double d = ref_tri(q[0], q[1], q[2]);
		if (fabs(d - best[g]) <= 1e-6 * (best[g] + 1e-3))
			near_tie++;
		else if (mismatch++ < 5)
			fprintf(stderr, "voxel %lld %lld %lld: triangle %u at %.9g, "
				"the nearest is %u at %.9g\n", (long long)v->x,
				(long long)v->y, (long long)v->z, id - 1, d,
				who[g] - 1, best[g]);
	}
	CHECK_EQ(mismatch, 0);
	/* ties are rare: a real disagreement would not hide among them */
	CHECK(near_tie * 50 < s.n);
	fprintf(stderr, "nearest: %zu voxels, %zu near ties\n", s.n, near_tie);
	free(best);
	free(who);
	free(st);
	free(s.v);
}

/* A soup of random triangles with random vertex colours, a third of
 * them without area (a repeated corner, or three corners on a line), so
 * that every Voronoi region of nearest_bary and the segments of a flat
 * triangle are met, in every lane of a batch. */
static const char *random_soup(uint32_t ntri)
{
	struct vd_triangle *t = malloc(ntri * sizeof *t);
	uint8_t *rgb = malloc(9 * (size_t)ntri);
	uint64_t seed = 99;
	for (uint32_t i = 0; i < ntri; i++) {
		float (*v)[3] = t[i].v;
		for (int k = 0; k < 9; k++) {
			seed = seed * 6364136223846793005ull + 1442695040888963407ull;
			v[k / 3][k % 3] = (float)((double)(seed >> 40) * 0x1p-24);
			rgb[9 * (size_t)i + (size_t)k] = (uint8_t)(seed >> 32);
		}
		if (i % 3 == 1) /* a repeated corner */
			memcpy(v[2], v[0], sizeof v[0]);
		if (i % 3 == 2) /* on a line */
			for (int a = 0; a < 3; a++)
				v[2][a] = (v[0][a] + v[1][a]) / 2;
	}
	const char *path = in("random.ply");
	write_tri_ply(path, ntri, t, rgb);
	free(t);
	free(rgb);
	return path;
}

/* The AVX2 nearest points (nearest4, with its shortcut of edge products
 * computed once per triangle) against the rule's scalar arithmetic
 * (nearest_bary), bit for bit, on random triangles at random depths:
 * small ones around a voxel, large ones, slivers, ones without area, and
 * corners at the ends of the shortcut's range and beyond it (which must
 * take the six dot products), seen from voxels near them and anywhere. */
static uint64_t near_seed = 7;
static uint64_t near_rand(uint64_t n)
{
	near_seed = near_seed * 6364136223846793005ull + 1442695040888963407ull;
	return (near_seed >> 16) % n;
}

static void test_nearest4_same_as_scalar(void)
{
	const int64_t top = (int64_t)1 << 24, edge = (int64_t)1 << 22;
	int exact = 0, inexact = 0, lanes = 0;
	for (int it = 0; it < 200000; it++) {
		int L = 1 + (int)near_rand(21);
		int64_t s = vd_snap_voxel(L), side = (int64_t)1 << L;
		int64_t v[3][3], vox[4][3];
		int kind = (int)near_rand(6);
		int64_t span = kind == 0 ? 4 * s : kind == 1 ? top : 64 * s;
		for (int a = 0; a < 3; a++) {
			int64_t o = (int64_t)near_rand((uint64_t)top);
			for (int k = 0; k < 3; k++)
				v[k][a] = o + (int64_t)near_rand((uint64_t)span) -
					  span / 2;
		}
		if (kind == 2) /* a sliver: c a hair off the middle of ab */
			for (int a = 0; a < 3; a++)
				v[2][a] = (v[0][a] + v[1][a]) / 2 +
					  (a == 0 ? (int64_t)near_rand(3) - 1 : 0);
		if (kind == 3) /* no area: a repeated corner */
			memcpy(v[2], v[1], sizeof v[1]);
		if (kind == 4) /* corners at the shortcut's ends */
			for (int k = 0; k < 3; k++)
				for (int a = 0; a < 3; a++)
					v[k][a] = near_rand(2) ? -edge - 1 +
						  (int64_t)near_rand(2) :
						  top + edge + (int64_t)near_rand(2);
		if (kind == 5) /* beyond it */
			v[near_rand(3)][near_rand(3)] =
				(int64_t)near_rand(2) ? ((int64_t)1 << 40) :
				-((int64_t)1 << 33);
		for (int l = 0; l < 4; l++)
			for (int a = 0; a < 3; a++) {
				int64_t x = l < 2 ? v[near_rand(3)][a] / s +
						    (int64_t)near_rand(5) - 2 :
						    (int64_t)near_rand((uint64_t)side);
				vox[l][a] = x < 0 ? 0 : x >= side ? side - 1 : x;
			}
		float d2[2][4];
		double w[2][3][4];
		int r = vd__nearest_check(v, L, vox, d2, w);
		if (r < 0) {
			printf("SKIP no AVX2\n");
			return;
		}
		if (r & 16)
			exact++;
		else
			inexact++;
		int in = 1;
		for (int k = 0; k < 3; k++)
			for (int a = 0; a < 3; a++)
				in &= v[k][a] >= -edge && v[k][a] <= top + edge;
		CHECK_EQ(!!(r & 16), in);
		for (int l = 0; l < 4; l++) {
			if (r >> l & 1)
				continue; /* no area: nearest_bary's own */
			lanes++;
			CHECK(!memcmp(&d2[0][l], &d2[1][l], sizeof(float)));
			for (int k = 0; k < 3; k++)
				CHECK(w[0][k][l] == w[1][k][l]);
		}
	}
	CHECK(exact > 100000);
	CHECK(inexact > 10000);
	CHECK(lanes > 600000);
}

/* The colour pass's fast paths (brick walks, nearest points four at a
 * time in AVX2) and its reference (spans, one at a time): the same
 * colours, bit for bit, on random triangles, flat ones, a scan and a
 * textured model, whole and in cells. */
static void test_simd_same_as_scalar(void)
{
	uint32_t ntri;
	const char *meshes[3] = {random_soup(3000), bunny_soup(&ntri),
				 "tests/data/spider/spider.obj"};
	const int levels[3] = {7, 8, 9};
	for (int i = 0; i < 3; i++)
		for (int L0 = 0; L0 <= 1; L0++) {
			struct cscene a, b;
			vd_colour_fast = 0;
			CHECK_EQ(run_voxelize(meshes[i], levels[i], L0, 1, 0, NULL),
				 VD_OK);
			load_scene(&a);
			vd_colour_fast = 1;
			CHECK_EQ(run_voxelize(meshes[i], levels[i], L0, 1, 0, NULL),
				 VD_OK);
			load_scene(&b);
			CHECK(a.n > 1000);
			CHECK(scene_equal(&a, &b));
			free(a.v);
			free(b.v);
		}
}

static void test_chunked_concat(void)
{
	uint32_t ntri;
	const char *soup = bunny_soup(&ntri);
	struct cscene mono;
	CHECK_EQ(run_voxelize(soup, 8, 0, 1, 0, NULL), VD_OK);
	load_scene(&mono);
	CHECK_EQ(mono.chunks, 1);
	for (int L0 = 1; L0 <= 2; L0++) {
		struct cscene s;
		CHECK_EQ(run_voxelize(soup, 8, L0, 1, 0, NULL), VD_OK);
		load_scene(&s);
		CHECK(s.chunks > 1);
		CHECK_EQ(s.col_files, s.chunks);
		CHECK_EQ(s.n, mono.n);
		CHECK(scene_equal(&s, &mono));
		free(s.v);
	}
	free(mono.v);
	/* a real textured model (five JPEG textures) */
	struct vd_voxelize_result res;
	CHECK_EQ(run_voxelize("tests/data/spider/spider.obj", 8, 0, 1, 0, &res),
		 VD_OK);
	CHECK_EQ(res.textures_loaded, 4); /* Brusttex is defined, not used */
	CHECK_EQ(res.textures_missing, 0);
	load_scene(&mono);
	CHECK(mono.n > 50000);
	for (int L0 = 1; L0 <= 2; L0++) {
		struct cscene s;
		CHECK_EQ(run_voxelize("tests/data/spider/spider.obj", 8, L0, 1, 0,
				      NULL), VD_OK);
		load_scene(&s);
		CHECK(s.chunks > 1);
		CHECK(scene_equal(&s, &mono));
		free(s.v);
	}
	free(mono.v);
	/* a textured scene too */
	write_png2("tex2.png");
	static const char mtl[] = "newmtl tex\nmap_Kd tex2.png\nnewmtl speck\nKd 1 0 1\n";
	CHECK_EQ(run_voxelize(big_obj("big", mtl, 0, 0), 6, 0, 1, 0, NULL), VD_OK);
	load_scene(&mono);
	struct cscene s;
	CHECK_EQ(run_voxelize(big_obj("big", mtl, 0, 0), 6, 2, 1, 0, NULL), VD_OK);
	load_scene(&s);
	CHECK(scene_equal(&s, &mono));
	free(s.v);
	free(mono.v);
}

/* Reads a whole file; NULL if absent. */
/* The .svo files of a run with colours and one without: the same bytes
 * (the provenance is the same string here). */
static void test_svo_identical(void)
{
	uint32_t ntri;
	const char *meshes[] = {bunny_soup(&ntri), "tests/data/textured/scene.obj",
				"tests/data/textured/scene.ac",
				"tests/data/textured/vcol.ply"};
	for (size_t i = 0; i < 4; i++) {
		char keep[800];
		snprintf(keep, sizeof keep, "%s/keep", data);
		mkdir(keep, 0777);
		CHECK_EQ(run_voxelize(meshes[i], 7, 1, 1, 0, NULL), VD_OK);
		CHECK(count_files(".col") > 0);
		CHECK_EQ(count_files(".col"), count_files(".svo"));
		/* keep the coloured run's .svo files */
		DIR *d = opendir(dir);
		struct dirent *e;
		int svo = 0;
		while (d && (e = readdir(d))) {
			size_t n = strlen(e->d_name);
			if (n > 4 && !strcmp(e->d_name + n - 4, ".svo")) {
				char a[1200], b[1200];
				snprintf(a, sizeof a, "%s/%s", dir, e->d_name);
				snprintf(b, sizeof b, "%s/%s", keep, e->d_name);
				CHECK_EQ(rename(a, b), 0);
				svo++;
			}
		}
		if (d)
			closedir(d);
		CHECK_EQ(run_voxelize(meshes[i], 7, 1, 0, 0, NULL), VD_OK);
		CHECK_EQ(count_files(".col"), 0);
		CHECK_EQ(count_files(".svo"), svo);
		d = opendir(keep);
		while (d && (e = readdir(d))) {
			if (e->d_name[0] == '.')
				continue;
			char a[1200], b[1200];
			snprintf(a, sizeof a, "%s/%s", dir, e->d_name);
			snprintf(b, sizeof b, "%s/%s", keep, e->d_name);
			size_t na = 0, nb = 0;
			unsigned char *pa = (unsigned char *)test_slurp(a, &na), *pb = (unsigned char *)test_slurp(b, &nb);
			CHECK(pa && pb && na == nb && !memcmp(pa, pb, na));
			free(pa);
			free(pb);
			unlink(b);
		}
		if (d)
			closedir(d);
		rmdir(keep);
	}
}

/* The bundled scene: each face of the cube its own source. */
static void test_bundled_scene(void)
{
	struct vd_voxelize_result res;
	CHECK_EQ(run_voxelize("tests/data/textured/scene.obj", 5, 0, 1, 0, &res),
		 VD_OK);
	CHECK_EQ(res.textures_loaded, 4);
	CHECK_EQ(res.textures_missing, 0);
	struct cscene s;
	load_scene(&s);
	/* voxels nearest to the middle of the y = 0 face (Kd 1 0 0): red */
	int red = 0, other = 0;
	for (size_t i = 0; i < s.n; i++) {
		double c[3];
		centre(&s, &s.v[i], c);
		if (c[1] < s.tr.voxel_size && c[0] > 0.2 && c[0] < 0.8 &&
		    c[2] > 0.2 && c[2] < 0.8) {
			if (s.v[i].rgb[0] == 255 && !s.v[i].rgb[1] && !s.v[i].rgb[2])
				red++;
			else
				other++;
		}
	}
	CHECK(red > 50);
	CHECK_EQ(other, 0);
	free(s.v);
}

/* ------------------------------------------------------------ bad input */

/* Empties the output directory: a library call that fails before it
 * starts writing leaves what was there (the tool's staging directory is
 * what keeps a failed run from replacing a good one). */
static void clear_dir(void)
{
	DIR *d = opendir(dir);
	struct dirent *e;
	while (d && (e = readdir(d))) {
		char p[1200];
		if (e->d_name[0] == '.')
			continue;
		snprintf(p, sizeof p, "%s/%s", dir, e->d_name);
		unlink(p);
	}
	if (d)
		closedir(d);
}

static int no_chunks(void)
{
	return count_files(".svo") == 0 && count_files(".col") == 0;
}

static void test_bad_input(void)
{
	struct vd_voxelize_result res;
	/* a missing texture: the material colour, counted; strict: error */
	static const char mtl[] = "newmtl tex\nKd 0 1 0\nmap_Kd nowhere.png\n"
				  "newmtl speck\nKd 1 1 1\n";
	const char *obj = big_obj("miss", mtl, 0, 0);
	CHECK_EQ(run_voxelize(obj, 5, 0, 1, 0, &res), VD_OK);
	CHECK_EQ(res.textures_missing, 1);
	struct cscene s;
	load_scene(&s);
	struct bary_ctx green = {{{0, 255, 0}, {0, 255, 0}, {0, 255, 0}}};
	CHECK(check_big(&s, want_bary, &green) > 100);
	free(s.v);
	clear_dir();
	CHECK_EQ(run_voxelize(obj, 5, 0, 1, 1, &res), VD_ERR_IO);
	CHECK(strstr(vd_error_detail(), "nowhere.png") != NULL);
	CHECK(no_chunks());

	/* a corrupt PNG and a corrupt JPEG: warned, or strict errors */
	unsigned char junk[64];
	FILE *f = fopen("tests/data/textured/checker.png", "rb");
	size_t n = f ? fread(junk, 1, 50, f) : 0;
	if (f)
		fclose(f);
	write_file("cut.png", junk, n);
	obj = big_obj("cut", "newmtl tex\nKd 0 0 1\nmap_Kd cut.png\nnewmtl speck\n", 0, 0);
	CHECK_EQ(run_voxelize(obj, 5, 0, 1, 0, &res), VD_OK);
	CHECK_EQ(res.textures_missing, 1);
	clear_dir();
	CHECK_EQ(run_voxelize(obj, 5, 0, 1, 1, &res), VD_ERR_FORMAT);
	CHECK(no_chunks());
	write_text("bad.jpg", "\xff\xd8\xff\xe0\x00\x10JFIF garbage");
	obj = big_obj("badjpg", "newmtl tex\nmap_Kd bad.jpg\nnewmtl speck\n", 0, 0);
	CHECK_EQ(run_voxelize(obj, 5, 0, 1, 0, &res), VD_OK);
	CHECK_EQ(res.textures_missing, 1);
	clear_dir();
	CHECK_EQ(run_voxelize(obj, 5, 0, 1, 1, &res), VD_ERR_FORMAT);
	CHECK(no_chunks());
	/* a missing MTL: warned; strict: error */
	write_text("nomtl.obj", "mtllib absent.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 1\n"
		   "usemtl x\nf 1 2 3\n");
	CHECK_EQ(run_voxelize(in("nomtl.obj"), 4, 0, 1, 0, &res), VD_OK);
	clear_dir();
	CHECK_EQ(run_voxelize(in("nomtl.obj"), 4, 0, 1, 1, &res), VD_ERR_IO);
	CHECK(no_chunks());

	/* NaN texture coordinates: an error, whatever the mode */
	write_text("nan.obj", "v 0 0 0\nv 1 0 0\nv 0 1 1\nvt nan 0\nvt 1 0\nvt 0 1\n"
		   "f 1/1 2/2 3/3\n");
	clear_dir();
	CHECK_EQ(run_voxelize(in("nan.obj"), 4, 0, 1, 0, &res), VD_ERR_RANGE);
	CHECK(strstr(vd_error_detail(), "line 4") != NULL);
	CHECK(no_chunks());
	/* ... but geometry alone does not read them */
	CHECK_EQ(run_voxelize(in("nan.obj"), 4, 0, 0, 0, &res), VD_OK);
	write_text("nanac.ac", "AC3Db\nMATERIAL \"m\" rgb 1 1 1\nOBJECT poly\n"
		   "texture \"x.png\"\nnumvert 3\n0 0 0\n1 0 0\n0 1 1\nnumsurf 1\n"
		   "SURF 0\nmat 0\nrefs 3\n0 inf 0\n1 1 0\n2 0 1\nkids 0\n");
	clear_dir();
	CHECK_EQ(run_voxelize(in("nanac.ac"), 4, 0, 1, 0, &res), VD_ERR_RANGE);
	CHECK(no_chunks());
	/* a texture coordinate index out of range */
	write_text("vtidx.obj", "v 0 0 0\nv 1 0 0\nv 0 1 1\nvt 0 0\nf 1/1 2/2 3/1\n");
	clear_dir();
	CHECK_EQ(run_voxelize(in("vtidx.obj"), 4, 0, 1, 0, &res), VD_ERR_RANGE);

	/* a PLY colour that is a list */
	write_text("list.ply", "ply\nformat ascii 1.0\nelement vertex 3\n"
		   "property float x\nproperty float y\nproperty float z\n"
		   "property list uchar uchar red\nproperty uchar green\n"
		   "property uchar blue\nelement face 1\n"
		   "property list uchar int vertex_indices\nend_header\n"
		   "0 0 0 1 9 0 0\n1 0 0 1 9 0 0\n0 1 1 1 9 0 0\n3 0 1 2\n");
	clear_dir();
	CHECK_EQ(run_voxelize(in("list.ply"), 4, 0, 1, 0, &res), VD_ERR_FORMAT);
	CHECK(strstr(vd_error_detail(), "'red'") != NULL);
	CHECK(no_chunks());
	CHECK_EQ(run_voxelize(in("list.ply"), 4, 0, 0, 0, &res), VD_OK);

	/* no colour source at all: no .col files, the run says so */
	CHECK_EQ(run_voxelize("tests/data/bunny.ply", 5, 0, 1, 0, &res), VD_OK);
	CHECK_EQ(res.colours, 0);
	CHECK_EQ(count_files(".col"), 0);
}

/* The attribute API read directly: geometry-only reads are unchanged. */
static void test_read_attr_api(void)
{
	struct vd_mesh *m;
	struct vd_mesh_open_opts o = {.colours = 1};
	CHECK_EQ(vd_mesh_open_opts(&m, "tests/data/textured/vcol.ply", &o), VD_OK);
	struct vd_triangle t[8];
	struct vd_tri_attr a[8];
	size_t n;
	CHECK_EQ(vd_mesh_read_attr(m, t, a, 8, &n), VD_OK);
	CHECK_EQ(n, 4);
	CHECK(vd_mesh_has_colours(m));
	/* face 0 is 0 2 1: red, blue, green */
	CHECK(a[0].texture == -1 && a[0].rgb[0][0] == 255 && a[0].rgb[1][2] == 255 &&
	      a[0].rgb[2][1] == 255);
	vd_mesh_close(m);
	CHECK_EQ(vd_mesh_open(&m, "tests/data/textured/vcol.ply"), VD_OK);
	CHECK_EQ(vd_mesh_read_attr(m, t, a, 8, &n), VD_ERR_ARG);
	CHECK(!vd_mesh_has_colours(m));
	vd_mesh_close(m);
	/* OBJ: the checker face's corners carry their UVs and texture */
	CHECK_EQ(vd_mesh_open_opts(&m, "tests/data/textured/scene.obj", &o), VD_OK);
	CHECK_EQ(vd_mesh_read_attr(m, t, a, 8, &n), VD_OK);
	CHECK_EQ(n, 8);
	CHECK(a[0].texture >= 0 && vd_mesh_texture(m, a[0].texture) != NULL);
	CHECK(a[0].uv[0][0] == 0 && a[0].uv[1][0] == 1 && a[0].uv[2][1] == 1);
	CHECK_EQ(vd_mesh_textures_loaded(m), 3); /* photo.jpg: not yet used */
	vd_mesh_close(m);
}

int main(void)
{
	dir = test_tmpdir("colour-in");
	snprintf(data, sizeof data, "%s.data", dir);
	mkdir(data, 0777);
	RUN(test_texture_sample_hand);
	RUN(test_texture_sample_same_as_first);
	RUN(test_uniform_colour);
	RUN(test_texture_formats);
	RUN(test_big_triangle_texture);
	RUN(test_ac3d_texrep_texoff);
	RUN(test_acc_base_texture);
	RUN(test_big_triangle_vertex_colours);
	RUN(test_tie_earlier_wins);
	RUN(test_nearest_brute_force);
	RUN(test_nearest4_same_as_scalar);
	RUN(test_simd_same_as_scalar);
	RUN(test_chunked_concat);
	RUN(test_svo_identical);
	RUN(test_bundled_scene);
	RUN(test_bad_input);
	RUN(test_read_attr_api);
	return CHECK_DONE();
}
