/* test_vdb.c - OpenVDB import and export against OpenVDB's own counts and
 * a brute-force reference (vd_vdb_test_reference: every voxel of the
 * bounding box through an accessor, the modes' definitions written out
 * again, no node iteration), on grids built here through the OpenVDB API.
 */
#include "check.h"
#include "scene.h"
#include "voxdag.h"
#include "io/vdb_test_grids.h"

#include <dirent.h>
#include <math.h>
#include <unistd.h>

static const char *dir;
static char path_sphere[600], path_fog[600], path_bunny[600], path_two[600],
	path_empty[600], path_rot[600], path_out[600], path_colour[600];

/* ------------------------------------------------------------ voxel sets
 * Voxels as OpenVDB index coordinates, packed 21 bits an axis after adding
 * a bias so negative indices sort too. */

enum { BIAS = 1 << 20 };

static uint64_t pack(int64_t x, int64_t y, int64_t z)
{
	return (uint64_t)(x + BIAS) << 42 | (uint64_t)(y + BIAS) << 21 |
	       (uint64_t)(z + BIAS);
}

/* The voxels of every chunk in `d`, as our grid coordinates shifted by
 * `off` (so the OpenVDB index when no resampling happened). */
static uint64_t offset_key(void *ctx, int64_t x, int64_t y, int64_t z)
{
	const int32_t *off = ctx;
	return pack(off[0] + x, off[1] + y, off[2] + z);
}

static int load_chunks(const char *d, const int32_t off[3], struct vset *out,
		       int *nchunks)
{
	return test_load_chunks(d, offset_key, (void *)off, out, nchunks);
}

static void biased_name(uint64_t key, char *buf, size_t cap)
{
	snprintf(buf, cap, "(%lld,%lld,%lld)", (long long)(key >> 42) - BIAS,
		 (long long)(key >> 21 & 0x1fffff) - BIAS,
		 (long long)(key & 0x1fffff) - BIAS);
}

struct ref_ctx {
	struct vset *s;
	int k;              /* resampling shift */
	int32_t off[3];
};

/* The reference voxel, downsampled as the import does when k > 0; kept
 * in OpenVDB index units of the coarse voxel's first child. */
static void ref_collect(void *vctx, int32_t x, int32_t y, int32_t z)
{
	struct ref_ctx *c = vctx;
	int64_t p[3] = {x, y, z};
	for (int a = 0; a < 3; a++)
		p[a] = c->off[a] + ((p[a] - c->off[a]) >> c->k);
	vset_add(c->s, pack(p[0], p[1], p[2]));
}

static int import(const char *path, const char *grid, int mode, double thr,
		  int levels, int chunk_level, struct vd_vdb_import_result *r)
{
	struct vd_vdb_select sel = {grid, mode, thr, NULL};
	struct vd_voxelize_opts o = {.levels = levels, .chunk_level = chunk_level,
				     .mem_budget_bytes = 1ull << 30,
				     .threads = 2, .quiet = 1};
	int err = vd_vdb_import(path, dir, &sel, &o, r);
	if (err)
		fprintf(stderr, "import %s: %s: %s\n", path, vd_strerror(err),
			vd_error_detail());
	return err;
}

/* Imports and compares with the reference; returns the voxel count. */
static uint64_t check_mode(const char *path, const char *grid, int mode,
			   double thr, int levels, int chunk_level)
{
	struct vd_vdb_import_result r;
	struct vset got = {0}, want = {0};
	int n;
	char what[256];
	snprintf(what, sizeof what, "%s %s levels %d L0 %d", path,
		 vd_vdb_mode_name(mode), levels, chunk_level);
	CHECK_EQ(import(path, grid, mode, thr, levels, chunk_level, &r), VD_OK);
	CHECK_EQ(load_chunks(dir, r.index_offset, &got, &n), VD_OK);
	CHECK_EQ(n, (long long)r.chunks);
	CHECK_EQ(got.n, (long long)r.voxels);
	struct vd_vdb_select sel = {grid, mode, thr, NULL};
	struct ref_ctx rc = {&want, r.resample_shift,
			     {r.index_offset[0], r.index_offset[1], r.index_offset[2]}};
	uint64_t count;
	CHECK_EQ(vd_vdb_test_reference(path, &sel, 2, ref_collect, &rc, &count),
		 VD_OK);
	vset_finish(&want);
	CHECK(want.n > 0);
	CHECK(vset_equal(&got, &want, what, biased_name));
	if (mode == VD_VDB_ACTIVE && !r.resample_shift)
		CHECK_EQ(r.voxels, (long long)r.info.active_voxels);
	if (!r.resample_shift)
		CHECK_EQ(r.voxels, (long long)count);
	else if (mode == VD_VDB_ACTIVE)
		CHECK(r.voxels < r.info.active_voxels);
	free(got.v);
	free(want.v);
	return r.voxels;
}

/* ------------------------------------------------------------- fixtures */

/* The colour fixture: a fog box 'density', colour grids over the same box
 * with a smaller box inactive (and not the background) in some. */
static const int32_t colour_lo[3] = {-5, -3, 2}, colour_hi[3] = {20, 17, 30};
static const int32_t colour_off_lo[3] = {0, 0, 10}, colour_off_hi[3] = {3, 4, 12};
static const uint8_t colour_bg[3] = {51, 102, 153};

static void make_fixtures(void)
{
	snprintf(path_sphere, sizeof path_sphere, "%s/sphere.vdb", dir);
	snprintf(path_fog, sizeof path_fog, "%s/fog.vdb", dir);
	snprintf(path_bunny, sizeof path_bunny, "%s/bunny.vdb", dir);
	snprintf(path_two, sizeof path_two, "%s/two.vdb", dir);
	snprintf(path_empty, sizeof path_empty, "%s/empty.vdb", dir);
	snprintf(path_rot, sizeof path_rot, "%s/rotated.vdb", dir);
	snprintf(path_out, sizeof path_out, "%s/export.vdb", dir);
	snprintf(path_colour, sizeof path_colour, "%s/colour.vdb", dir);
	struct vd_vdb_test_file *f;
	const double c[3] = {0.3, -5.7, 2.2};
	const int32_t lo[3] = {-13, -2, 0}, hi[3] = {140, 133, 129};
	const int32_t ilo[3] = {-13, 0, 30}, ihi[3] = {-1, 10, 60};

	CHECK_EQ(vd_vdb_test_new(&f), VD_OK);
	CHECK_EQ(vd_vdb_test_add_sphere(f, "ls", 11, c, 1, 3), VD_OK);
	CHECK_EQ(vd_vdb_test_write(f, path_sphere), VD_OK);
	vd_vdb_test_free(f);

	CHECK_EQ(vd_vdb_test_new(&f), VD_OK);
	CHECK_EQ(vd_vdb_test_add_fog_box(f, "density", lo, hi, 1.0f, ilo, ihi,
					 0.25f), VD_OK);
	CHECK_EQ(vd_vdb_test_write(f, path_fog), VD_OK);
	vd_vdb_test_free(f);

	CHECK_EQ(vd_vdb_test_new(&f), VD_OK);
	CHECK_EQ(vd_vdb_test_add_mesh(f, "bunny", "tests/data/bunny.ply", 48, 3),
		 VD_OK);
	CHECK_EQ(vd_vdb_test_write(f, path_bunny), VD_OK);
	vd_vdb_test_free(f);

	CHECK_EQ(vd_vdb_test_new(&f), VD_OK);
	CHECK_EQ(vd_vdb_test_add_empty(f, "first"), VD_OK);
	CHECK_EQ(vd_vdb_test_add_sphere(f, "second", 5, c, 0.5, 2), VD_OK);
	CHECK_EQ(vd_vdb_test_write(f, path_two), VD_OK);
	vd_vdb_test_free(f);

	CHECK_EQ(vd_vdb_test_new(&f), VD_OK);
	CHECK_EQ(vd_vdb_test_add_empty(f, "nothing"), VD_OK);
	CHECK_EQ(vd_vdb_test_write(f, path_empty), VD_OK);
	vd_vdb_test_free(f);

	CHECK_EQ(vd_vdb_test_new(&f), VD_OK);
	CHECK_EQ(vd_vdb_test_add_transformed(f, "rot", 8, 30, 1, 1, 1), VD_OK);
	CHECK_EQ(vd_vdb_test_add_transformed(f, "stretched", 8, 0, 1, 2, 1), VD_OK);
	CHECK_EQ(vd_vdb_test_add_transformed(f, "scaled", 8, 0, 0.25, 0.25, 0.25),
		 VD_OK);
	CHECK_EQ(vd_vdb_test_write(f, path_rot), VD_OK);
	vd_vdb_test_free(f);

	/* density and colour grids of every kind (see test_colour) */
	const double zero[3] = {0, 0, 0}, half[3] = {0.5, 0.5, 0.5};
	const int32_t none_lo[3] = {1, 1, 1}, none_hi[3] = {0, 0, 0};
	const int32_t clo[3] = {-3, -2, 1}, chi[3] = {10, 8, 15};
	int32_t flo[3], fhi[3];
	for (int a = 0; a < 3; a++)
		flo[a] = 2 * colour_lo[a], fhi[a] = 2 * colour_hi[a];
	CHECK_EQ(vd_vdb_test_new(&f), VD_OK);
	CHECK_EQ(vd_vdb_test_add_fog_box(f, "density", colour_lo, colour_hi, 1,
					 none_lo, none_hi, 0), VD_OK);
	CHECK_EQ(vd_vdb_test_add_fog_box(f, "color", colour_lo, colour_hi, 1,
					 none_lo, none_hi, 0), VD_OK);
	CHECK_EQ(vd_vdb_test_add_colour(f, "rgb", "vec3s", 1, zero, colour_lo,
					colour_hi, colour_off_lo, colour_off_hi,
					colour_bg), VD_OK);
	CHECK_EQ(vd_vdb_test_add_colour(f, "ints", "vec3i", 1, zero, colour_lo,
					colour_hi, colour_off_lo, colour_off_hi,
					colour_bg), VD_OK);
	CHECK_EQ(vd_vdb_test_add_colour(f, "doubles", "vec3d", 1, zero,
					colour_lo, colour_hi, colour_off_lo,
					colour_off_hi, colour_bg), VD_OK);
	CHECK_EQ(vd_vdb_test_add_colour(f, "coarse", "vec3s", 2, half, clo, chi,
					none_lo, none_hi, colour_bg), VD_OK);
	CHECK_EQ(vd_vdb_test_add_colour(f, "fine", "vec3s", 0.5, zero, flo, fhi,
					none_lo, none_hi, colour_bg), VD_OK);
	CHECK_EQ(vd_vdb_test_write(f, path_colour), VD_OK);
	vd_vdb_test_free(f);
}

/* ---------------------------------------------------------------- tests */

static void test_sphere_level_set(void)
{
	uint64_t active = check_mode(path_sphere, NULL, VD_VDB_ACTIVE, 0, 0, -1);
	uint64_t surf = check_mode(path_sphere, NULL, VD_VDB_LEVELSET_SURFACE, 0, 0, -1);
	uint64_t solid = check_mode(path_sphere, "ls", VD_VDB_LEVELSET_SOLID, 0, 0, -1);
	/* a radius-11 ball: about 4/3 pi 11^3 inside, a shell of its area */
	CHECK(solid > 5000 && solid < 6500);
	CHECK(surf > 1000 && surf < 2500);
	CHECK(active > surf);
	/* chunked the same */
	CHECK_EQ(check_mode(path_sphere, NULL, VD_VDB_LEVELSET_SOLID, 0, 0, 3), solid);
}

static void test_fog_box_with_tiles(void)
{
	struct vd_vdb_import_result r;
	CHECK_EQ(import(path_fog, NULL, VD_VDB_ACTIVE, 0, 0, -1, &r), VD_OK);
	CHECK(r.tiles_selected > 0); /* the box is mostly tiles */
	uint64_t all = check_mode(path_fog, NULL, VD_VDB_ACTIVE, 0, 0, -1);
	CHECK_EQ(all, 154ll * 136 * 130);
	uint64_t dense = check_mode(path_fog, NULL, VD_VDB_FOG, 0.5, 0, -1);
	CHECK_EQ(dense, all - 13ll * 11 * 31);
	CHECK_EQ(check_mode(path_fog, NULL, VD_VDB_FOG, 0, 0, -1), all);
	/* many cells: tiles split over cells */
	CHECK_EQ(check_mode(path_fog, NULL, VD_VDB_FOG, 0.5, 0, 4), dense);
}

static void test_bunny_level_set(void)
{
	check_mode(path_bunny, NULL, VD_VDB_ACTIVE, 0, 0, -1);
	check_mode(path_bunny, NULL, VD_VDB_LEVELSET_SURFACE, 0, 0, -1);
	check_mode(path_bunny, NULL, VD_VDB_LEVELSET_SOLID, 0, 0, 2);
}

/* --levels smaller than the grid: a coarse voxel is set iff a grid voxel
 * inside it is (the reference is folded the same way). */
static void test_resample(void)
{
	struct vd_vdb_import_result r;
	CHECK_EQ(import(path_bunny, NULL, VD_VDB_LEVELSET_SOLID, 0, 4, -1, &r),
		 VD_OK);
	CHECK_EQ(r.levels, 4);
	CHECK(r.resample_shift >= 2);
	check_mode(path_bunny, NULL, VD_VDB_LEVELSET_SOLID, 0, 4, -1);
	check_mode(path_fog, NULL, VD_VDB_ACTIVE, 0, 5, 1);
	/* larger than needed only pads */
	CHECK_EQ(import(path_sphere, NULL, VD_VDB_ACTIVE, 0, 9, -1, &r), VD_OK);
	CHECK_EQ(r.resample_shift, 0);
	CHECK_EQ(r.levels, 9);
	CHECK_EQ(r.voxels, (long long)r.info.active_voxels);
}

static void test_transform(void)
{
	struct vd_vdb_import_result r;
	CHECK_EQ(import(path_rot, "scaled", VD_VDB_ACTIVE, 0, 0, -1, &r), VD_OK);
	CHECK_EQ(r.voxels, 512);
	CHECK(r.transform.voxel_size == 0.25);
	/* index 0 is centred at 0: its voxel starts half a voxel below */
	CHECK(r.transform.origin[0] == -0.125);
	CHECK(r.transform.bbox_max[0] == 1.875f);
	CHECK_EQ(import(path_rot, "rot", VD_VDB_ACTIVE, 0, 0, -1, &r),
		 VD_ERR_UNSUPPORTED);
	CHECK(strstr(vd_error_detail(), "rotated"));
	CHECK_EQ(import(path_rot, "stretched", VD_VDB_ACTIVE, 0, 0, -1, &r),
		 VD_ERR_UNSUPPORTED);
	CHECK(strstr(vd_error_detail(), "cubic"));
}

/* Export then import: the same voxels at the same world places. */
static void test_round_trip(void)
{
	struct vd_vdb_import_result a, b;
	struct vset va = {0}, vb = {0};
	int n;
	CHECK_EQ(import(path_bunny, NULL, VD_VDB_LEVELSET_SURFACE, 0, 0, 1, &a),
		 VD_OK);
	const int32_t zero[3] = {0, 0, 0};
	CHECK_EQ(load_chunks(dir, zero, &va, &n), VD_OK);
	CHECK(n > 1);
	/* the chunks in name order */
	char *paths[64];
	size_t np = 0;
	DIR *d = opendir(dir);
	struct dirent *e;
	while (d && (e = readdir(d)) && np < 64)
		if (strstr(e->d_name, ".svo")) {
			paths[np] = malloc(strlen(dir) + strlen(e->d_name) + 2);
			sprintf(paths[np++], "%s/%s", dir, e->d_name);
		}
	closedir(d);
	uint64_t voxels = 0;
	CHECK_EQ(vd_vdb_export_svo(path_out, "rt", paths, np, &voxels), VD_OK);
	CHECK_EQ(voxels, (long long)a.voxels);
	/* chunks of another grid do not mix */
	char other_dir[700], other[800];
	snprintf(other_dir, sizeof other_dir, "%s/other", dir);
	struct vd_vdb_select sel = {NULL, VD_VDB_ACTIVE, 0, NULL};
	struct vd_voxelize_opts o = {.mem_budget_bytes = 1ull << 30,
				     .chunk_level = 0, .quiet = 1};
	CHECK_EQ(vd_vdb_import(path_sphere, other_dir, &sel, &o, &b), VD_OK);
	snprintf(other, sizeof other, "%s/chunk-L0-0.svo", other_dir);
	char *two[2] = {paths[0], other};
	CHECK_EQ(vd_vdb_export_svo(path_out, "rt", two, 2, &voxels),
		 VD_ERR_MISMATCH);
	CHECK_EQ(import(path_out, "rt", VD_VDB_ACTIVE, 0, 0, -1, &b), VD_OK);
	CHECK_EQ(load_chunks(dir, b.index_offset, &vb, &n), VD_OK);
	CHECK(vset_equal(&va, &vb, "round trip", biased_name));
	CHECK(fabs(b.transform.voxel_size - a.transform.voxel_size) < 1e-12);
	for (int k = 0; k < 3; k++)
		CHECK(fabs(b.transform.origin[k] - a.transform.origin[k] -
			   b.index_offset[k] * a.transform.voxel_size) < 1e-9);
	for (size_t i = 0; i < np; i++)
		free(paths[i]);
	free(va.v);
	free(vb.v);
}

/* --------------------------------------------------------------- colours
 * The reference: the selected voxels from vd_vdb_test_reference (every
 * voxel of the bounding box through an accessor), folded to ours, sorted
 * by Morton code, each coloured by the fixture's formula at the colour
 * grid voxel the rule names, written out again here per case. */

enum colour_map { SAME, COARSE, FINE };

/* The fixture's colour at index q of a colour grid whose active box is
 * lo..hi less off_lo..off_hi (when `holes`). */
static void fixture_colour(const int64_t q[3], const int32_t lo[3],
			   const int32_t hi[3], int holes, uint8_t rgb[3])
{
	int in = 1, off = holes;
	for (int a = 0; a < 3; a++) {
		in &= q[a] >= lo[a] && q[a] <= hi[a];
		off &= q[a] >= colour_off_lo[a] && q[a] <= colour_off_hi[a];
	}
	if (in && !off)
		vd_vdb_test_colour_of(q[0], q[1], q[2], rgb);
	else
		memcpy(rgb, colour_bg, 3);
}

struct morton_ctx {
	struct vset *s;
	int k;
	int32_t off[3];
};

static void ref_morton(void *vctx, int32_t x, int32_t y, int32_t z)
{
	struct morton_ctx *c = vctx;
	int64_t p[3] = {x, y, z};
	uint32_t v[3];
	for (int a = 0; a < 3; a++)
		v[a] = (uint32_t)((p[a] - c->off[a]) >> c->k);
	vset_add(c->s, vd_morton3(v[0], v[1], v[2]));
}

struct cell_cols {
	uint64_t cell;
	struct vd_colours c;
};

static int cmp_cell_cols(const void *a, const void *b)
{
	const struct cell_cols *x = a, *y = b;
	return (x->cell > y->cell) - (x->cell < y->cell);
}

/* The .col files of `dir` in cell order, concatenated; each checked
 * against its .svo. Returns the colour count, *ncells the files. */
static uint64_t load_colours(uint8_t **rgb, int *ncells)
{
	struct cell_cols cc[512];
	int n = 0;
	DIR *d = opendir(dir);
	struct dirent *e;
	while (d && (e = readdir(d))) {
		size_t len = strlen(e->d_name);
		if (len < 5 || strcmp(e->d_name + len - 4, ".col"))
			continue;
		CHECK(n < 512);
		char path[1200];
		snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
		struct vd_chunk_header h, sh;
		CHECK_EQ(vd_colours_load(&cc[n].c, &h, path), VD_OK);
		cc[n].cell = h.cell_morton;
		strcpy(path + strlen(path) - 3, "svo");
		struct vd_svo svo;
		CHECK_EQ(vd_svo_load(&svo, &sh, path), VD_OK);
		CHECK_EQ(vd_colours_match(&h, &cc[n].c, &sh, &svo), VD_OK);
		vd_svo_release(&svo);
		n++;
	}
	if (d)
		closedir(d);
	qsort(cc, (size_t)n, sizeof *cc, cmp_cell_cols);
	uint64_t total = 0;
	for (int i = 0; i < n; i++)
		total += cc[i].c.voxels;
	*rgb = malloc(3 * total + 1);
	uint64_t at = 0;
	for (int i = 0; i < n; i++) {
		memcpy(*rgb + 3 * at, cc[i].c.rgb, 3 * cc[i].c.voxels);
		at += cc[i].c.voxels;
		vd_colours_release(&cc[i].c);
	}
	*ncells = n;
	return total;
}

/* Imports `density` of the colour fixture with colour grid `grid` (NULL:
 * the default) and compares the colours with the reference; returns the
 * cells written. */
static int check_colours(const char *grid, enum colour_map map, int holes,
			 int levels, int chunk_level, const char *want_grid)
{
	struct vd_vdb_import_result r;
	struct vd_vdb_select sel = {"density", VD_VDB_ACTIVE, 0, grid};
	struct vd_voxelize_opts o = {.levels = levels, .chunk_level = chunk_level,
				     .mem_budget_bytes = 1ull << 30,
				     .threads = 2, .quiet = 1, .colours = 1};
	char what[200];
	snprintf(what, sizeof what, "colour grid %s levels %d L0 %d",
		 grid ? grid : "(default)", levels, chunk_level);
	int err = vd_vdb_import(path_colour, dir, &sel, &o, &r);
	if (err)
		fprintf(stderr, "%s: %s: %s\n", what, vd_strerror(err),
			vd_error_detail());
	CHECK_EQ(err, VD_OK);
	CHECK_EQ(r.colours, 1);
	CHECK(strcmp(r.colour.grid_name, want_grid) == 0);
	CHECK_EQ(r.colour.same_transform, map == SAME);
	uint8_t *got;
	int ncells;
	uint64_t n = load_colours(&got, &ncells);
	CHECK_EQ(ncells, (long long)r.chunks);
	CHECK_EQ(n, (long long)r.voxels);

	struct vset ref = {0};
	struct morton_ctx mc = {&ref, r.resample_shift,
				{r.index_offset[0], r.index_offset[1],
				 r.index_offset[2]}};
	uint64_t count;
	CHECK_EQ(vd_vdb_test_reference(path_colour, &sel, 0, ref_morton, &mc,
				       &count), VD_OK);
	vset_finish(&ref);
	CHECK_EQ(ref.n, (long long)n);
	int32_t lo[3], hi[3];
	for (int a = 0; a < 3; a++) {
		lo[a] = map == SAME ? colour_lo[a] : map == FINE ? 2 * colour_lo[a]
			: colour_lo[a] >> 1;
		hi[a] = map == SAME ? colour_hi[a] : map == FINE ? 2 * colour_hi[a]
			: colour_hi[a] >> 1;
	}
	uint64_t bad = 0;
	for (size_t i = 0; i < ref.n && i < n; i++) {
		uint32_t v[3];
		vd_morton3_decode(ref.v[i], &v[0], &v[1], &v[2]);
		int64_t q[3];
		for (int a = 0; a < 3; a++) {
			/* the density voxel nearest our voxel's centre */
			int64_t p = mc.off[a] + ((int64_t)v[a] << mc.k) +
				    (mc.k ? (int64_t)1 << (mc.k - 1) : 0);
			/* fine: voxel size 1/2, index 0 at 0; coarse: voxel
			 * size 2, index 0 at 0.5, so world p is index
			 * p/2 - 1/4, nearest floor(p/2) */
			q[a] = map == SAME ? p : map == FINE ? 2 * p
			       : (p >= 0 ? p / 2 : -((-p + 1) / 2));
		}
		uint8_t want[3];
		fixture_colour(q, lo, hi, holes, want);
		if (memcmp(want, got + 3 * i, 3) && bad++ < 5)
			fprintf(stderr, "%s: voxel %zu (%u,%u,%u): got %u %u %u, "
				"want %u %u %u\n", what, i, v[0], v[1], v[2],
				got[3 * i], got[3 * i + 1], got[3 * i + 2],
				want[0], want[1], want[2]);
	}
	CHECK_EQ(bad, 0);
	free(ref.v);
	free(got);
	return ncells;
}

static void test_colour(void)
{
	/* the default: 'rgb', the one Vec3 grid of the four names ('color'
	 * holds floats); one cell and many */
	CHECK_EQ(check_colours(NULL, SAME, 1, 0, 0, "rgb"), 1);
	CHECK(check_colours(NULL, SAME, 1, 0, 2, "rgb") > 8);
	CHECK(check_colours("ints", SAME, 1, 0, 1, "ints") > 1);
	CHECK(check_colours("doubles", SAME, 1, 0, 2, "doubles") > 8);
	/* other transforms: the nearest colour voxel to each centre */
	CHECK(check_colours("coarse", COARSE, 0, 0, 2, "coarse") > 8);
	CHECK_EQ(check_colours("fine", FINE, 0, 0, 0, "fine"), 1);
	/* resampled by 2: read at the centre, half up */
	CHECK(check_colours("rgb", SAME, 1, 4, 1, "rgb") > 1);

	/* no colours asked, or no colour grid: no .col */
	struct vd_vdb_import_result r;
	struct vd_vdb_select sel = {"density", VD_VDB_ACTIVE, 0, "rgb"};
	struct vd_voxelize_opts o = {.chunk_level = 1, .quiet = 1,
				     .mem_budget_bytes = 1ull << 30};
	uint8_t *got;
	int ncells;
	CHECK_EQ(vd_vdb_import(path_colour, dir, &sel, &o, &r), VD_OK);
	CHECK_EQ(r.colours, 0);
	CHECK_EQ(load_colours(&got, &ncells), 0);
	CHECK_EQ(ncells, 0);
	free(got);
	o.colours = 1;
	sel.grid_name = NULL;
	sel.colour_grid = NULL;
	CHECK_EQ(vd_vdb_import(path_fog, dir, &sel, &o, &r), VD_OK);
	CHECK_EQ(r.colours, 0);
	CHECK_EQ(load_colours(&got, &ncells), 0);
	free(got);
	/* a colour grid that is not Vec3, or not there */
	sel.grid_name = "density";
	sel.colour_grid = "color";
	CHECK_EQ(vd_vdb_import(path_colour, dir, &sel, &o, &r),
		 VD_ERR_UNSUPPORTED);
	CHECK(strstr(vd_error_detail(), "'color' holds float values"));
	sel.colour_grid = "Cd";
	CHECK_EQ(vd_vdb_import(path_colour, dir, &sel, &o, &r), VD_ERR_ARG);
	CHECK(strstr(vd_error_detail(), "no grid named 'Cd'"));
}

/* Value ranges: floats 0..1 times 255, ints as they are; rounded half up,
 * clamped, NaN 0. The voxels lie along x, so Morton order is index order. */
static void test_colour_values(void)
{
	const double f[] = {0.5, -0.1, 1.7,  NAN, INFINITY, -INFINITY,
			    0.25, 1, 0,      1e30, -1e30, 0.999};
	const uint8_t fwant[] = {128, 0, 255,  0, 255, 0,
				 64, 255, 0,   255, 0, 255};
	const double i[] = {-5, 300, 128,  0, 255, 1};
	const uint8_t iwant[] = {0, 255, 128,  0, 255, 1};
	const struct {
		const char *type;
		int n;
		const double *v;
		const uint8_t *want;
	} cases[] = {{"vec3s", 4, f, fwant}, {"vec3d", 4, f, fwant},
		     {"vec3i", 2, i, iwant}};
	char path[700];
	snprintf(path, sizeof path, "%s/values.vdb", dir);
	for (size_t c = 0; c < sizeof cases / sizeof *cases; c++) {
		struct vd_vdb_test_file *tf;
		const int32_t lo[3] = {0, 0, 0}, hi[3] = {cases[c].n - 1, 0, 0};
		const int32_t none_lo[3] = {1, 1, 1}, none_hi[3] = {0, 0, 0};
		CHECK_EQ(vd_vdb_test_new(&tf), VD_OK);
		CHECK_EQ(vd_vdb_test_add_fog_box(tf, "density", lo, hi, 1, none_lo,
						 none_hi, 0), VD_OK);
		CHECK_EQ(vd_vdb_test_add_colour_values(tf, "Cd", cases[c].type,
						       cases[c].n, cases[c].v),
			 VD_OK);
		CHECK_EQ(vd_vdb_test_write(tf, path), VD_OK);
		vd_vdb_test_free(tf);
		struct vd_vdb_import_result r;
		struct vd_vdb_select sel = {"density", VD_VDB_ACTIVE, 0, NULL};
		struct vd_voxelize_opts o = {.chunk_level = 0, .quiet = 1,
					     .colours = 1,
					     .mem_budget_bytes = 1ull << 30};
		CHECK_EQ(vd_vdb_import(path, dir, &sel, &o, &r), VD_OK);
		CHECK_EQ(r.colours, 1);
		uint8_t *got;
		int ncells;
		CHECK_EQ(load_colours(&got, &ncells), cases[c].n);
		if (memcmp(got, cases[c].want, 3 * (size_t)cases[c].n)) {
			fprintf(stderr, "%s:", cases[c].type);
			for (int k = 0; k < 3 * cases[c].n; k++)
				fprintf(stderr, " %u/%u", got[k], cases[c].want[k]);
			fprintf(stderr, " (got/want)\n");
			CHECK(0);
		}
		free(got);
	}
}

static void test_errors(void)
{
	struct vd_vdb_import_result r;
	struct vd_vdb_select sel = {NULL, VD_VDB_ACTIVE, 0, NULL};
	struct vd_vdb *v;
	CHECK_EQ(import(path_empty, NULL, VD_VDB_ACTIVE, 0, 0, -1, &r), VD_ERR_EMPTY);
	CHECK_EQ(import(path_two, NULL, VD_VDB_ACTIVE, 0, 0, -1, &r), VD_ERR_EMPTY);
	CHECK_EQ(import(path_two, "second", VD_VDB_ACTIVE, 0, 0, -1, &r), VD_OK);
	CHECK_EQ(import(path_two, "third", VD_VDB_ACTIVE, 0, 0, -1, &r), VD_ERR_ARG);
	CHECK(strstr(vd_error_detail(), "'first', 'second'"));
	CHECK_EQ(import("tests/data/bunny.ply", NULL, VD_VDB_ACTIVE, 0, 0, -1, &r),
		 VD_ERR_FORMAT);
	CHECK_EQ(import("out/tmp/no/such.vdb", NULL, VD_VDB_ACTIVE, 0, 0, -1, &r),
		 VD_ERR_IO);
	CHECK_EQ(import(path_fog, NULL, VD_VDB_LEVELSET_SOLID, 0, 0, -1, &r),
		 VD_ERR_UNSUPPORTED);
	CHECK(strstr(vd_error_detail(), "background"));
	CHECK_EQ(import(path_sphere, NULL, VD_VDB_FOG, 1e9, 0, -1, &r), VD_ERR_EMPTY);
	/* the budget */
	struct vd_voxelize_opts o = {.mem_budget_bytes = 1 << 20, .chunk_level = -1,
				     .quiet = 1};
	CHECK_EQ(vd_vdb_import(path_sphere, dir, &sel, &o, &r), VD_ERR_BUDGET);
	/* cut at many lengths: an error each time, never a crash */
	FILE *f = fopen(path_sphere, "rb");
	CHECK(f != NULL);
	static unsigned char buf[1 << 20];
	size_t size = f ? fread(buf, 1, sizeof buf, f) : 0;
	if (f)
		fclose(f);
	CHECK(size > 1000 && size < sizeof buf);
	char cut[700];
	snprintf(cut, sizeof cut, "%s/cut.vdb", dir);
	int bad = 0;
	for (size_t len = 0; len < size; len += len < 600 ? 1 : 997) {
		FILE *g = fopen(cut, "wb");
		fwrite(buf, 1, len, g);
		fclose(g);
		int err = vd_vdb_open(&v, cut, &sel, NULL);
		if (!err) {
			vd_vdb_close(v);
			fprintf(stderr, "cut at %zu of %zu: opened\n", len, size);
			bad++;
		} else if (err != VD_ERR_TRUNCATED && !(len == 0 && err == VD_ERR_EMPTY)) {
			fprintf(stderr, "cut at %zu: %s: %s\n", len, vd_strerror(err),
				vd_error_detail());
			bad++;
		}
	}
	CHECK_EQ(bad, 0);
	CHECK_EQ(vd_vdb_mode_parse("fog", &sel.mode), VD_OK);
	CHECK_EQ(sel.mode, VD_VDB_FOG);
	CHECK_EQ(vd_vdb_mode_parse("solid", &sel.mode), VD_ERR_ARG);
}

int main(void)
{
	dir = test_tmpdir("vdb");
	RUN(make_fixtures);
	RUN(test_sphere_level_set);
	RUN(test_fog_box_with_tiles);
	RUN(test_bunny_level_set);
	RUN(test_resample);
	RUN(test_transform);
	RUN(test_round_trip);
	RUN(test_colour);
	RUN(test_colour_values);
	RUN(test_errors);
	return CHECK_DONE();
}
