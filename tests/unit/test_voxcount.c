/* test_voxcount.c - colour/voxcount.c, colour indices through the DAG
 * (colour paper §3):
 * for every voxel of real scenes, the index found by summing voxel counts
 * along the path through an SVDAG, an SSVDAG (with reflections) and each
 * encoding equals the voxel's rank in the brute-force Morton order of the
 * SVO's voxels; cells of coarser levels (level-of-detail hits) get the rank
 * of their first voxel; empty cells are reported empty. */
#include "check.h"
#include "scene.h"

#include <unistd.h>

static char dir[] = "/tmp/vd_coldag_XXXXXX";

/* The reference: every voxel's Morton code at depth L relative to the
 * cell, in increasing order (the SVO's bricks in key order, bits in
 * order). */
static uint64_t *voxel_list(const struct vd_svo *s, uint64_t *n)
{
	uint64_t count = 0;
	for (size_t i = 0; i < s->count; i++)
		count += (uint64_t)__builtin_popcountll(s->masks[i]);
	uint64_t *v = malloc((count ? count : 1) * sizeof *v), k = 0;
	int shift = 3 * (s->levels - s->chunk_level);
	uint64_t rel = shift >= 64 ? ~0ull : (1ull << shift) - 1;
	for (size_t i = 0; i < s->count; i++)
		for (int b = 0; b < 64; b++)
			if (s->masks[i] >> b & 1)
				v[k++] = (s->keys[i] << 6 | (uint64_t)b) & rel;
	*n = count;
	return v;
}

static int find(const uint64_t *v, uint64_t n, uint64_t m)
{
	uint64_t lo = 0, hi = n;
	while (lo < hi) {
		uint64_t mid = (lo + hi) / 2;
		if (v[mid] < m)
			lo = mid + 1;
		else
			hi = mid;
	}
	return lo < n && v[lo] == m;
}

/* Checks vc against the list for every voxel, every coarser cell holding
 * a voxel, and `probes` pseudo-random cells (empty ones must be empty).
 * Coordinates are absolute; the chunk's cell origin is `base` at depth L. */
static void check_all(const struct vd_voxcount *vc, const uint64_t *v,
		      uint64_t n, int L, int L0, uint64_t cell)
{
	CHECK_EQ(vc->voxels, n);
	uint64_t bad = 0;
	for (int level = L0; level <= L; level++) {
		int sh = 3 * (L - level);
		uint64_t prev = ~0ull;
		for (uint64_t i = 0; i < n; i++) {
			uint64_t c = v[i] >> sh;
			if (c == prev)
				continue; /* the rank of the cell's first voxel */
			prev = c;
			uint64_t abs = cell << 3 * (level - L0) | c, idx = ~0ull;
			uint32_t x, y, z;
			vd_morton3_decode(abs, &x, &y, &z);
			if (vd_voxcount_index(vc, level, x, y, z, &idx) != 1 ||
			    idx != i)
				bad++;
		}
	}
	CHECK_EQ(bad, 0);
	uint64_t state = 12345, wrong = 0;
	for (int k = 0; k < 20000; k++) {
		state = state * 6364136223846793005ull + 1442695040888963407ull;
		uint64_t rel = (state >> 11) & ((1ull << 3 * (L - L0)) - 1);
		uint32_t x, y, z;
		vd_morton3_decode(cell << 3 * (L - L0) | rel, &x, &y, &z);
		uint64_t idx;
		int set = vd_voxcount_index(vc, L, x, y, z, &idx);
		wrong += set != find(v, n, rel);
	}
	CHECK_EQ(wrong, 0);
	/* outside the grid */
	uint64_t idx;
	CHECK_EQ(vd_voxcount_index(vc, L, 1u << L, 0, 0, &idx), 0);
}

static void scene(const char *mesh, int L)
{
	struct vd_svo svo;
	struct vd_transform t;
	if (!test_voxelize_one(mesh, L, dir, &svo, &t))
		return;
	uint64_t n, *v = voxel_list(&svo, &n);
	struct vd_dag_opts o = {.threads = 2};
	struct vd_dag d[2];
	CHECK_EQ(vd_dag_from_svo(&d[0], &svo, VD_KIND_DAG, &o, NULL), VD_OK);
	CHECK_EQ(vd_dag_from_svo(&d[1], &svo, VD_KIND_SSVDAG, &o, NULL), VD_OK);
	/* the SSVDAG must really use reflections, or the test proves less */
	uint64_t reflected = 0;
	for (int l = 0; l < L - 1; l++)
		for (uint64_t k = 0; k < d[1].lv[l].refs; k++)
			reflected += d[1].lv[l].refl[k] != 0;
	CHECK(reflected > 0);
	for (int k = 0; k < 2; k++) {
		struct vd_voxcount vc;
		CHECK_EQ(vd_voxcount_from_dag(&vc, &d[k]), VD_OK);
		check_all(&vc, v, n, L, 0, 0);
		CHECK(vd_voxcount_stored_bytes(&vc) > 0);
		vd_voxcount_release(&vc);
	}
	for (int f = 0; f < VD_ENC_COUNT_; f++) {
		struct vd_enc e;
		CHECK_EQ(vd_enc_build(&e, f, &d[vd_enc_format_symmetric(f)], &t),
			 VD_OK);
		struct vd_voxcount vc;
		CHECK_EQ(vd_voxcount_from_enc(&vc, &e), VD_OK);
		check_all(&vc, v, n, L, 0, 0);
		vd_voxcount_release(&vc);
		vd_enc_release(&e);
	}
	vd_dag_release(&d[0]);
	vd_dag_release(&d[1]);
	free(v);
	vd_svo_release(&svo);
}

static void test_bunny(void) { scene("tests/data/bunny.ply", 7); }

static void test_dragon(void)
{
	char path[512];
	snprintf(path, sizeof path, "%s/stanford_dragon_res4.ply",
		 test_shared_data());
	if (access(path, R_OK) != 0) {
		printf("SKIP test_dragon: %s absent\n", path);
		return;
	}
	scene(path, 8);
}

/* Cells below the root: indices count from the cell's first voxel, and
 * the cells' counts add up to the root's. */
static void test_cells(void)
{
	CHECK_EQ(test_voxelize("tests/data/bunny.ply", 7, 2, dir, NULL), VD_OK);
	uint64_t total = 0;
	int cells = 0;
	for (uint64_t cell = 0; cell < 64; cell++) {
		char name[64], path[800];
		vd_chunk_file_name(name, sizeof name, 2, cell, "svo");
		snprintf(path, sizeof path, "%s/%s", dir, name);
		if (access(path, F_OK) != 0)
			continue;
		struct vd_svo svo;
		CHECK_EQ(vd_svo_load(&svo, NULL, path), VD_OK);
		uint64_t n, *v = voxel_list(&svo, &n);
		struct vd_dag d;
		struct vd_dag_opts o = {.threads = 1};
		CHECK_EQ(vd_dag_from_svo(&d, &svo, VD_KIND_SSVDAG, &o, NULL),
			 VD_OK);
		struct vd_voxcount vc;
		CHECK_EQ(vd_voxcount_from_dag(&vc, &d), VD_OK);
		check_all(&vc, v, n, 7, 2, cell);
		total += vc.voxels;
		cells++;
		vd_voxcount_release(&vc);
		vd_dag_release(&d);
		vd_svo_release(&svo);
		free(v);
	}
	CHECK(cells > 4);
	struct vd_svo one;
	struct vd_transform t;
	char sub[300];
	snprintf(sub, sizeof sub, "%s/one", dir);
	if (test_voxelize_one("tests/data/bunny.ply", 7, sub, &one, &t)) {
		uint64_t n;
		free(voxel_list(&one, &n));
		CHECK_EQ(total, n);
		vd_svo_release(&one);
	}
}

/* A colour source over the reference list: red for voxels with x < 2^(L-1),
 * blue for the others, so every pixel of a render says which voxel's
 * colour it got. */
struct halves {
	const uint64_t *v;
	uint32_t half;
};

static void halves_get(const struct vd_colour_source *s, uint64_t index,
		       uint8_t rgb[3])
{
	const struct halves *h = s->impl;
	uint32_t x, y, z;
	vd_morton3_decode(h->v[index], &x, &y, &z);
	rgb[0] = x < h->half ? 255 : 0;
	rgb[1] = 0;
	rgb[2] = x < h->half ? 0 : 255;
}

/* Renders with colours through the DAG, the SSVDAG and every encoding:
 * each hit pixel has the colour of its hit voxel (no green, red exactly on
 * the voxels of the low half) and the images are byte-identical. */
static void test_render(void)
{
	const int L = 7;
	struct vd_svo svo;
	struct vd_transform t;
	if (!test_voxelize_one("tests/data/bunny.ply", L, dir, &svo, &t))
		return;
	uint64_t n, *v = voxel_list(&svo, &n);
	struct halves hv = {v, 1u << (L - 1)};
	struct vd_colour_source src = {.voxels = n, .levels = L,
				       .get = halves_get, .impl = &hv};
	struct vd_dag d[2];
	struct vd_dag_opts o = {.threads = 2};
	CHECK_EQ(vd_dag_from_svo(&d[0], &svo, VD_KIND_DAG, &o, NULL), VD_OK);
	CHECK_EQ(vd_dag_from_svo(&d[1], &svo, VD_KIND_SSVDAG, &o, NULL), VD_OK);
	struct vd_enc e[VD_ENC_COUNT_];
	for (int f = 0; f < VD_ENC_COUNT_; f++)
		CHECK_EQ(vd_enc_build(&e[f], f, &d[vd_enc_format_symmetric(f)],
				      &t), VD_OK);
	uint8_t *first = NULL;
	for (int k = 0; k < 2 + VD_ENC_COUNT_; k++) {
		struct vd_render_scene sc;
		if (k < 2)
			CHECK_EQ(vd_render_scene_from_dag(&sc, &d[k], &t), VD_OK);
		else
			CHECK_EQ(vd_render_scene_from_enc(&sc, &e[k - 2]), VD_OK);
		struct vd_render_opts ro = {.width = 96, .height = 80,
					    .threads = 2, .shadows = 1,
					    .colours = &src};
		CHECK_EQ(vd_camera_preset(&ro.cam, &sc, "iso", 40, 96, 80), VD_OK);
		ro.light[0] = ro.cam.eye[0];
		ro.light[1] = ro.cam.eye[1] + 1;
		ro.light[2] = ro.cam.eye[2];
		struct vd_image img;
		CHECK_EQ(vd_render_image(&sc, &ro, &img), VD_OK);
		uint64_t hits = 0, wrong = 0, red = 0;
		for (int i = 0; i < 96 * 80; i++) {
			const struct vd_hit *h = &img.hits[i];
			if (h->level < 0)
				continue;
			hits++;
			const uint8_t *px = img.rgb + 3 * i;
			int low = h->cell[0] < hv.half;
			red += low;
			wrong += px[1] != 0 || (px[0] > 0) != low ||
				 (px[2] > 0) == low;
		}
		CHECK(hits > 500);
		CHECK(red > 50 && red < hits - 50);
		CHECK_EQ(wrong, 0);
		if (!first) {
			first = malloc(3 * 96 * 80);
			memcpy(first, img.rgb, 3 * 96 * 80);
		} else {
			CHECK(memcmp(first, img.rgb, 3 * 96 * 80) == 0);
		}
		vd_image_release(&img);
	}
	/* a source of another length is refused */
	struct vd_render_scene sc;
	CHECK_EQ(vd_render_scene_from_dag(&sc, &d[0], &t), VD_OK);
	src.voxels = n - 1;
	struct vd_render_opts ro = {.width = 8, .height = 8, .colours = &src};
	CHECK_EQ(vd_camera_preset(&ro.cam, &sc, "front", 40, 8, 8), VD_OK);
	struct vd_image img;
	CHECK_EQ(vd_render_image(&sc, &ro, &img), VD_ERR_MISMATCH);
	vd_image_release(&img);
	free(first);
	for (int f = 0; f < VD_ENC_COUNT_; f++)
		vd_enc_release(&e[f]);
	vd_dag_release(&d[0]);
	vd_dag_release(&d[1]);
	free(v);
	vd_svo_release(&svo);
}

int main(void)
{
	if (!mkdtemp(dir))
		return 1;
	RUN(test_bunny);
	RUN(test_dragon);
	RUN(test_cells);
	RUN(test_render);
	char cmd[300];
	snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
	if (system(cmd) != 0)
		return 1;
	return CHECK_DONE();
}
