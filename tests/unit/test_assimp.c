/* test_assimp.c - the Assimp importer (stages/lib/io/assimp.cc) behind the
 * mesh reader's hook, on the hand-written glTF scene of tests/data/gltf
 * (its make.py says what it holds): the triangles in world space and in
 * Assimp's order, their colour attributes worked out by hand from the
 * scene (linear factors to sRGB, vertex colours, texture coordinates with
 * v flipped to the bottom), the texture decoded from a file and from the
 * .glb's buffer, the sampler's wrap modes, a texture named in another
 * case, the files the scene pulled in (vd_mesh_sources); bad scenes and a
 * missing texture are errors or warnings; without the hook the names are
 * refused. Linked with -lassimp (Makefile). */
#include "check.h"
#include "voxdag.h"

#include <math.h>
#include <sys/stat.h>

#define DIR "tests/data/gltf/"

static const char *tmp;

struct want {
	float v[3][3];
	int textured;
	float uv[3][2];
	uint8_t rgb[3][3];
};

/* The scene's five triangles: the textured quad (UVs 0..2 in glTF, v
 * flipped), red, "half" (linear 0.5: sRGB 188), the vertex-coloured one
 * (node 1's two scaled by 1/2 and moved by (1, 0, 1)). */
static const struct want want[5] = {
	{{{0, 0, 0}, {2, 0, 0}, {2, 2, 0}}, 1, {{0, 1}, {2, 1}, {2, -1}}, {{0}}},
	{{{0, 0, 0}, {2, 2, 0}, {0, 2, 0}}, 1, {{0, 1}, {2, -1}, {0, -1}}, {{0}}},
	{{{0, 0, 0}, {0, 2, 0}, {0, 0, 2}}, 0, {{0}},
	 {{255, 0, 0}, {255, 0, 0}, {255, 0, 0}}},
	{{{1, 0, 1}, {2, 0, 1}, {1, 1, 1}}, 0, {{0}},
	 {{188, 188, 188}, {188, 188, 188}, {188, 188, 188}}},
	{{{1, 2, 2}, {3, 2, 2}, {3, 0, 2}}, 0, {{0}},
	 {{255, 0, 0}, {0, 255, 0}, {0, 0, 255}}},
};

static int warnings;
static char last_warning[600];

static void on_warn(void *ctx, const char *line)
{
	(void)ctx;
	warnings++;
	snprintf(last_warning, sizeof last_warning, "%s", line);
}

static struct vd_mesh *open_col(const char *path, int strict, int *err)
{
	struct vd_mesh_open_opts o = {.colours = 1, .strict = strict,
				      .warn = on_warn};
	struct vd_mesh *m = NULL;
	*err = vd_mesh_open_opts(&m, path, &o);
	return m;
}

/* Reads every triangle and checks it against want[]; `tex_ok` says
 * whether the texture loaded (else the quad has the material's white). */
static void check_scene(struct vd_mesh *m, int tex_ok)
{
	struct vd_triangle t[8];
	struct vd_tri_attr a[8];
	size_t n = 0;
	CHECK_EQ(vd_mesh_read_attr(m, t, a, 8, &n), VD_OK);
	CHECK_EQ(n, 5);
	for (size_t i = 0; i < n && i < 5; i++) {
		const struct want *w = &want[i];
		CHECK(!memcmp(t[i].v, w->v, sizeof w->v));
		if (w->textured && tex_ok) {
			CHECK(a[i].texture >= 0);
			CHECK(!memcmp(a[i].uv, w->uv, sizeof w->uv));
		} else {
			CHECK_EQ(a[i].texture, -1);
			for (int j = 0; j < 3; j++)
				for (int c = 0; c < 3; c++)
					CHECK_EQ(a[i].rgb[j][c], w->textured
						 ? 255 : w->rgb[j][c]);
		}
	}
	size_t more = 1;
	CHECK_EQ(vd_mesh_read_attr(m, t, a, 8, &more), VD_OK);
	CHECK_EQ(more, 0);
}

/* The 4x4 texture make.py writes: texel (x, y), row y from the top. */
static void check_texels(const struct vd_texture *tx)
{
	CHECK(tx != NULL);
	if (!tx)
		return;
	CHECK_EQ(tx->width, 4);
	CHECK_EQ(tx->height, 4);
	for (int y = 0; y < 4; y++)
		for (int x = 0; x < 4; x++) {
			const uint8_t *p = tx->rgb + 3 * (4 * y + x);
			CHECK_EQ(p[0], 40 + 60 * x);
			CHECK_EQ(p[1], 30 + 70 * y);
			CHECK_EQ(p[2], 200 - 40 * x - 10 * y);
		}
}

static void test_scene(const char *name, int wrap_u, int wrap_v)
{
	int err;
	struct vd_mesh *m = open_col(name, 1, &err);
	CHECK_EQ(err, VD_OK);
	if (!m)
		return;
	CHECK_EQ(vd_mesh_has_colours(m), 1);
	CHECK_EQ(vd_mesh_textures_loaded(m), 1);
	CHECK_EQ(vd_mesh_stats(m)->vertices, 4 + 3 + 3 + 3);
	check_scene(m, 1);
	const struct vd_texture *tx = vd_mesh_texture(m, 0);
	check_texels(tx);
	if (tx) {
		CHECK_EQ(tx->wrap[0], wrap_u);
		CHECK_EQ(tx->wrap[1], wrap_v);
	}
	/* a second pass hands out the same */
	CHECK_EQ(vd_mesh_rewind(m), VD_OK);
	check_scene(m, 1);
	vd_mesh_close(m);
}

static void test_gltf(void)
{
	test_scene(DIR "scene.gltf", VD_WRAP_REPEAT, VD_WRAP_REPEAT);
	int err;
	struct vd_mesh *m = open_col(DIR "scene.gltf", 0, &err);
	CHECK(m && !strcmp(vd_mesh_format(m), "gltf (assimp)"));
	vd_mesh_close(m);
}

static void test_glb_embedded(void)
{
	test_scene(DIR "scene.glb", VD_WRAP_REPEAT, VD_WRAP_REPEAT);
}

static void test_wrap_modes(void)
{
	test_scene(DIR "wrap.gltf", VD_WRAP_CLAMP, VD_WRAP_MIRROR);
}

static void test_geometry_only(void)
{
	struct vd_mesh *m = NULL;
	CHECK_EQ(vd_mesh_open(&m, DIR "scene.glb"), VD_OK);
	if (!m)
		return;
	struct vd_triangle t[8];
	struct vd_tri_attr a[8];
	size_t n = 0;
	CHECK_EQ(vd_mesh_read(m, t, 8, &n), VD_OK);
	CHECK_EQ(n, 5);
	for (size_t i = 0; i < n && i < 5; i++)
		CHECK(!memcmp(t[i].v, want[i].v, sizeof want[i].v));
	CHECK_EQ(vd_mesh_read_attr(m, t, a, 8, &n), VD_ERR_ARG);
	vd_mesh_close(m);
}

static const char *copy_to(const char *from, const char *name, long cut)
{
	static char p[600];
	snprintf(p, sizeof p, "%s/%s", tmp, name);
	FILE *f = fopen(from, "rb"), *g = fopen(p, "wb");
	CHECK(f && g);
	int c;
	long k = 0;
	while (f && g && (cut < 0 || k < cut) && (c = getc(f)) != EOF) {
		putc(c, g);
		k++;
	}
	if (f)
		fclose(f);
	if (g)
		CHECK_EQ(fclose(g), 0);
	return p;
}

/* Without the texture: one warning naming it and the material's white
 * (not strict), or an error naming it (strict). */
static void test_missing_texture(void)
{
	copy_to(DIR "scene.bin", "scene.bin", -1);
	const char *p = copy_to(DIR "scene.gltf", "scene.gltf", -1);
	int err;
	warnings = 0;
	struct vd_mesh *m = open_col(p, 0, &err);
	CHECK_EQ(err, VD_OK);
	CHECK_EQ(warnings, 1);
	CHECK(strstr(last_warning, "checker.png") != NULL);
	if (m) {
		CHECK_EQ(vd_mesh_textures_missing(m), 1);
		check_scene(m, 0);
		vd_mesh_close(m);
	}
	m = open_col(p, 1, &err);
	CHECK(m == NULL);
	CHECK_EQ(err, VD_ERR_IO);
	CHECK(strstr(vd_error_detail(), "checker.png") != NULL);
}

/* A texture named in another case than its file's (3DS's DOS names) is
 * found; with two such files, neither is guessed. */
static void test_texture_case(void)
{
	static char sub[600];
	snprintf(sub, sizeof sub, "%s/case", tmp);
	mkdir(sub, 0755);
	copy_to(DIR "scene.bin", "case/scene.bin", -1);
	copy_to(DIR "checker.png", "case/Checker.PNG", -1);
	char p[600]; /* copy_to's buffer is reused below */
	snprintf(p, sizeof p, "%s", copy_to(DIR "scene.gltf", "case/scene.gltf",
					    -1));
	int err;
	struct vd_mesh *m = open_col(p, 1, &err);
	CHECK_EQ(err, VD_OK);
	if (m) {
		check_scene(m, 1);
		check_texels(vd_mesh_texture(m, 0));
		vd_mesh_close(m);
	}
	copy_to(DIR "checker.png", "case/CHECKER.png", -1);
	m = open_col(p, 1, &err);
	CHECK(m == NULL);
	CHECK_EQ(err, VD_ERR_IO);
}

/* The files the scene pulled in (vd_mesh_sources): a .gltf's buffer and
 * texture, hashed as vd_file_xxh3 does, not the scene itself; nothing for
 * a .glb; the buffer without colours; a texture name not there in its own
 * case, looked for in vain, beside the file found in another case. */
static int has_source(struct vd_mesh *m, const char *path, int found)
{
	size_t n = 0;
	const struct vd_mesh_source *s = vd_mesh_sources(m, &n);
	for (size_t i = 0; i < n; i++) {
		if (strcmp(s[i].path, path))
			continue;
		uint64_t h = 0, size = 0;
		int ok = vd_file_xxh3(path, &h, &size) == VD_OK;
		vd_error_clear();
		return s[i].found == found && ok == found &&
		       (!found || (s[i].xxh3 == h && s[i].size == size));
	}
	return 0;
}

static void test_sources(void)
{
	int err;
	size_t n = 9;
	struct vd_mesh *m = open_col(DIR "scene.gltf", 1, &err);
	if (m) {
		check_scene(m, 1);
		vd_mesh_sources(m, &n);
		CHECK_EQ(n, 2);
		CHECK(has_source(m, DIR "scene.bin", 1));
		CHECK(has_source(m, DIR "checker.png", 1));
		vd_mesh_close(m);
	}
	m = open_col(DIR "scene.glb", 1, &err);
	CHECK(m && (vd_mesh_sources(m, &n), n == 0));
	vd_mesh_close(m);
	m = NULL;
	CHECK_EQ(vd_mesh_open(&m, DIR "scene.gltf"), VD_OK);
	if (m) {
		vd_mesh_sources(m, &n);
		CHECK_EQ(n, 1);
		CHECK(has_source(m, DIR "scene.bin", 1));
		vd_mesh_close(m);
	}
	char p[600], q[600];
	snprintf(p, sizeof p, "%s/case2", tmp);
	mkdir(p, 0755);
	copy_to(DIR "scene.bin", "case2/scene.bin", -1);
	copy_to(DIR "checker.png", "case2/Checker.PNG", -1);
	snprintf(p, sizeof p, "%s", copy_to(DIR "scene.gltf",
					    "case2/scene.gltf", -1));
	m = open_col(p, 1, &err);
	CHECK(m != NULL);
	if (m) {
		snprintf(q, sizeof q, "%s/case2/checker.png", tmp);
		CHECK(has_source(m, q, 0));
		snprintf(q, sizeof q, "%s/case2/Checker.PNG", tmp);
		CHECK(has_source(m, q, 1));
		snprintf(q, sizeof q, "%s/case2/scene.bin", tmp);
		CHECK(has_source(m, q, 1));
		vd_mesh_close(m);
	}
}

/* A scene cut anywhere is one error from Assimp, never a crash (the
 * sanitizer build watches), and no reader is left. */
static void test_cut(void)
{
	FILE *f = fopen(DIR "scene.glb", "rb");
	CHECK(f != NULL);
	if (!f)
		return;
	fseek(f, 0, SEEK_END);
	long size = ftell(f);
	fclose(f);
	for (long cut = 1; cut < size; cut += 37) {
		const char *p = copy_to(DIR "scene.glb", "cut.glb", cut);
		int err;
		struct vd_mesh *m = open_col(p, 0, &err);
		if (m || err != VD_ERR_FORMAT)
			fprintf(stderr, "cut at %ld: error %d\n", cut, err);
		CHECK(m == NULL);
		CHECK_EQ(err, VD_ERR_FORMAT);
		CHECK(!strncmp(vd_error_detail(), "Assimp: ", 8));
		vd_mesh_close(m);
	}
}

static void test_without_importer(void)
{
	vd_mesh_set_importer(NULL);
	struct vd_mesh *m = NULL;
	CHECK_EQ(vd_mesh_open(&m, DIR "scene.glb"), VD_ERR_UNSUPPORTED);
	CHECK(m == NULL);
	CHECK(strstr(vd_error_detail(), "voxelize-assimp") != NULL);
	vd_mesh_set_importer(vd_assimp_import);
	CHECK_EQ(vd_mesh_is_imported("a/b.GLB"), 1);
	CHECK_EQ(vd_mesh_is_imported("x.dae"), 1);
	CHECK_EQ(vd_mesh_is_imported("x.3ds"), 1);
	CHECK_EQ(vd_mesh_is_imported("x.fbx"), 1);
	CHECK_EQ(vd_mesh_is_imported("x.gltf"), 1);
	CHECK_EQ(vd_mesh_is_imported("x.obj"), 0);
	CHECK_EQ(vd_mesh_is_imported(".glb"), 0);
}

int main(void)
{
	tmp = test_tmpdir("assimp");
	vd_mesh_set_importer(vd_assimp_import);
	RUN(test_gltf);
	RUN(test_glb_embedded);
	RUN(test_wrap_modes);
	RUN(test_geometry_only);
	RUN(test_missing_texture);
	RUN(test_texture_case);
	RUN(test_sources);
	RUN(test_cut);
	RUN(test_without_importer);
	return CHECK_DONE();
}
