/* vdb-make-test-grids - writes small OpenVDB files built through the
 * OpenVDB API, for the command-line tests and the benchmarks. */
#include "voxdag.h"
#include "io/vdb_test_grids.h"
#include "cli.h"

#include <getopt.h>
#include <stdlib.h>
#include <string.h>

#define TOOL "vdb-make-test-grids"

static const char usage[] =
	"usage: vdb-make-test-grids OUTDIR\n"
	"       vdb-make-test-grids --mesh MESH --resolution N -o OUT.vdb\n"
	"\n"
	"The first form writes the test fixtures into OUTDIR: sphere.vdb (a\n"
	"level set 'sphere' of radius 20 voxels), fog.vdb (a fog box 'density'\n"
	"with whole tiles and a fainter core), two.vdb (grids 'b', a sphere,\n"
	"then 'a', a 10^3 fog box),\n"
	"empty.vdb (a grid without active voxels), rotated.vdb and\n"
	"nonuniform.vdb (transforms voxdag refuses), colour.vdb (a fog box\n"
	"'density' of indices -5..20, -3..17, 2..30 and colour grids beside it:\n"
	"'color' (float, not a colour), 'Cd' (vec3s, the same transform, indices\n"
	"0..3, 0..4, 10..12 inactive, background (51, 102, 153)), 'rgb8' (vec3i),\n"
	"'Cd_double' (vec3d), 'Cd_coarse' (vec3s, voxel size 2, index 0 at\n"
	"world 0.5); colour of index (x, y, z): vd_vdb_test_colour_of, in\n"
	"0..1 for floats). The second converts a mesh\n"
	"to a level set named 'surface' with N voxels across its largest extent\n"
	"(OpenVDB tools::meshToLevelSet, half width 3 voxels).\n"
	"\n"
	"  -m, --mesh MESH         mesh to convert (PLY, OBJ, STL)\n"
	"  -r, --resolution N      voxels across the mesh's largest extent\n"
	"  -o, --output FILE       the .vdb file to write\n"
	"  -h, --help              this text\n"
	"\n"
	"Exit status: 0 success, 1 failure, 2 usage.\n";


/* Writes one file from a fresh vd_vdb_test_file filled by `add`. */
static int make(const char *dir, const char *name,
		int (*add)(struct vd_vdb_test_file *f))
{
	char path[4096];
	snprintf(path, sizeof path, "%s/%s", dir, name);
	struct vd_vdb_test_file *f;
	int err = vd_vdb_test_new(&f);
	if (!err)
		err = add(f);
	if (!err)
		err = vd_vdb_test_write(f, path);
	vd_vdb_test_free(f);
	return err ? vd_cli_fail(TOOL, err, "cannot write", path) : 0;
}

static const double centre[3] = {0.5, -3.25, 7};
static const int32_t none_lo[3] = {1, 1, 1}, none_hi[3] = {0, 0, 0};

static int add_sphere(struct vd_vdb_test_file *f)
{
	return vd_vdb_test_add_sphere(f, "sphere", 20, centre, 1, 3);
}

static int add_fog(struct vd_vdb_test_file *f)
{
	/* holds the 128^3 tile [0,127]^3; the core lies outside it */
	const int32_t lo[3] = {-10, -3, 0}, hi[3] = {140, 133, 135};
	const int32_t ilo[3] = {-10, 0, 30}, ihi[3] = {-1, 10, 60};
	return vd_vdb_test_add_fog_box(f, "density", lo, hi, 1.0f, ilo, ihi, 0.25f);
}

static int add_two(struct vd_vdb_test_file *f)
{
	/* 'b' first: the file's first grid is not the first by name */
	const int32_t lo[3] = {0, 0, 0}, hi[3] = {9, 9, 9};
	int err = vd_vdb_test_add_sphere(f, "b", 10, centre, 0.5, 3);
	return err ? err : vd_vdb_test_add_fog_box(f, "a", lo, hi, 1, none_lo,
						   none_hi, 0);
}

static int add_empty(struct vd_vdb_test_file *f)
{
	return vd_vdb_test_add_empty(f, "nothing");
}

static int add_rotated(struct vd_vdb_test_file *f)
{
	return vd_vdb_test_add_transformed(f, "rotated", 8, 30, 1, 1, 1);
}

static int add_nonuniform(struct vd_vdb_test_file *f)
{
	return vd_vdb_test_add_transformed(f, "stretched", 8, 0, 1, 2, 1);
}

/* The colour fixture: density with colour grids of every kind. */
static int add_colour(struct vd_vdb_test_file *f)
{
	static const int32_t lo[3] = {-5, -3, 2}, hi[3] = {20, 17, 30};
	static const int32_t off_lo[3] = {0, 0, 10}, off_hi[3] = {3, 4, 12};
	static const int32_t clo[3] = {-3, -2, 1}, chi[3] = {10, 8, 15};
	static const uint8_t bg[3] = {51, 102, 153};
	static const double zero[3] = {0, 0, 0}, half[3] = {0.5, 0.5, 0.5};
	int err = vd_vdb_test_add_fog_box(f, "density", lo, hi, 1, none_lo,
					  none_hi, 0);
	if (!err)
		err = vd_vdb_test_add_fog_box(f, "color", lo, hi, 1, none_lo,
					      none_hi, 0);
	if (!err)
		err = vd_vdb_test_add_colour(f, "Cd", "vec3s", 1, zero, lo, hi,
					     off_lo, off_hi, bg);
	if (!err)
		err = vd_vdb_test_add_colour(f, "rgb8", "vec3i", 1, zero, lo, hi,
					     none_lo, none_hi, bg);
	if (!err)
		err = vd_vdb_test_add_colour(f, "Cd_double", "vec3d", 1, zero, lo,
					     hi, none_lo, none_hi, bg);
	if (!err)
		err = vd_vdb_test_add_colour(f, "Cd_coarse", "vec3s", 2, half, clo,
					     chi, none_lo, none_hi, bg);
	return err;
}

int main(int argc, char **argv)
{
	static const struct option longopts[] = {
		{"mesh", required_argument, NULL, 'm'},
		{"resolution", required_argument, NULL, 'r'},
		{"output", required_argument, NULL, 'o'},
		{"help", no_argument, NULL, 'h'},
		{NULL, 0, NULL, 0},
	};
	const char *mesh = NULL, *out = NULL;
	int c, res = 0;
	while ((c = getopt_long(argc, argv, "m:r:o:h", longopts, NULL)) != -1) {
		switch (c) {
		case 'm':
			mesh = optarg;
			break;
		case 'r':
			res = atoi(optarg);
			break;
		case 'o':
			out = optarg;
			break;
		case 'h':
			fputs(usage, stdout);
			return 0;
		default:
			fprintf(stderr, "Try 'vdb-make-test-grids --help'.\n");
			return 2;
		}
	}
	if (mesh) {
		if (!out || res < 1 || res > (1 << 20) || optind != argc) {
			fprintf(stderr, "vdb-make-test-grids: --mesh needs "
				"--resolution N (1..2^20) and -o FILE\n"
				"Try 'vdb-make-test-grids --help'.\n");
			return 2;
		}
		struct vd_vdb_test_file *f;
		int err = vd_vdb_test_new(&f);
		if (!err)
			err = vd_vdb_test_add_mesh(f, "surface", mesh, res, 3);
		if (!err)
			err = vd_vdb_test_write(f, out);
		vd_vdb_test_free(f);
		return err ? vd_cli_fail(TOOL, err, "cannot write", out) : 0;
	}
	if (optind != argc - 1) {
		fprintf(stderr, "vdb-make-test-grids: give one OUTDIR\n"
			"Try 'vdb-make-test-grids --help'.\n");
		return 2;
	}
	const char *dir = argv[optind];
	return make(dir, "sphere.vdb", add_sphere) ||
	       make(dir, "fog.vdb", add_fog) || make(dir, "two.vdb", add_two) ||
	       make(dir, "empty.vdb", add_empty) ||
	       make(dir, "rotated.vdb", add_rotated) ||
	       make(dir, "nonuniform.vdb", add_nonuniform) ||
	       make(dir, "colour.vdb", add_colour);
}
