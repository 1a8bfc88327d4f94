/* voxelize - triangle mesh or OpenVDB grid to SVO chunk files, out of
 * core. */
#include "voxdag.h"
#include "cli.h"

#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdlib.h>
#include <strings.h>
#include <string.h>
#include <unistd.h>

#define TOOL "voxelize"

static const char usage[] =
	"usage: voxelize MESH -o OUTDIR --levels L [options]\n"
	"       voxelize GRID.vdb -o OUTDIR [--levels L] [--grid NAME]\n"
	"                [--vdb-mode MODE] [--fog-threshold X]\n"
	"                [--colour-grid NAME] [options]\n"
	"\n"
	"Voxelizes the surface of a triangle mesh into a grid of 2^L voxels per\n"
	"side and writes one SVO chunk file per non-empty cell of the chunk\n"
	"level L0, plus OUTDIR/voxelize.stats.json, OUTDIR/manifest (every\n"
	"file's size and checksum) and, for a mesh, OUTDIR/sources (the files\n"
	"it pulled in: MTL files, textures, buffers, with their checksums;\n"
	"schemas/manifest.md). The new OUTDIR is built beside the old one\n"
	"and replaces it whole only when complete; a failure leaves the old one\n"
	"as it was.\n"
	"\n"
	"Mesh formats: PLY, OBJ (+ MTL), STL and AC3D are streamed (told apart\n"
	"by their first bytes). glTF 2.0 (.gltf, .glb), FBX (.fbx), Collada\n"
	"(.dae) and 3DS (.3ds), told by the name, are read whole in memory by\n"
	"Assimp (in the sibling program voxelize-assimp), triangulated and\n"
	"moved to world space, with their materials' diffuse / base colour\n"
	"textures (UV channel 0, the file's wrap modes; images embedded in a\n"
	"scene too), vertex colours and material colours.\n"
	"\n"
	"An input named *.vdb is an OpenVDB file: the chosen grid's voxels are\n"
	"imported instead. Without --levels one grid voxel is one voxel and L is\n"
	"the smallest depth that covers the selected voxels; with --levels L a\n"
	"grid too large for 2^L is resampled by the smallest power of two that\n"
	"fits (a voxel is set when any grid voxel inside it is).\n"
	"\n"
	"  -o, --output DIR        directory for the chunks (created if missing)\n"
	"  -l, --levels L          grid depth, 1..21 (2^L voxels per side);\n"
	"                          optional for .vdb input\n"
	"  -c, --chunk-level L0    level of the cells, 0..min(L-2, 7)\n"
	"                          (default: the coarsest that fits the budget)\n"
	"  -m, --mem-budget SIZE   peak memory of the process (default 2GiB);\n"
	"                          e.g. 512M, 4GiB\n"
	"  -j, --threads N         worker threads (default: all cores)\n"
	"  -q, --quiet             no progress lines on stderr\n"
	"  -h, --help              this text\n"
	"\n"
	"Colours: when the mesh has colours (PLY vertex colours, OBJ materials\n"
	"with MTL Kd / map_Kd textures, AC3D materials and textures, the\n"
	"materials and vertex colours of Assimp's formats) each cell also gets\n"
	"chunk-L<L0>-<cell>.col, the sRGB colour of every voxel in the cell's\n"
	"Morton order: the colour of the surface point nearest to the voxel's\n"
	"centre among the triangles overlapping it\n"
	"(schemas/colour-rule.md). An OpenVDB file's colours come from a Vec3\n"
	"grid (--colour-grid). The .svo files are the same either way.\n"
	"      --no-colours        geometry only: no .col files\n"
	"      --strict            a missing or unreadable texture or MTL file\n"
	"                          is an error (default: one warning, and the\n"
	"                          material colour is used)\n"
	"\n"
	"OpenVDB input only:\n"
	"      --grid NAME         the grid to read (default: the first by name)\n"
	"      --vdb-mode MODE     which voxels are set (default: active):\n"
	"                            active            active voxels and tiles\n"
	"                            levelset-surface  value <= 0 with a face\n"
	"                                              neighbour > 0 (one voxel\n"
	"                                              thick zero crossing)\n"
	"                            levelset-solid    value <= 0, inside tiles too\n"
	"                            fog               active, value > threshold\n"
	"      --fog-threshold X   for fog mode (default 0)\n"
	"      --colour-grid NAME  the Vec3 grid (vec3s, vec3d, vec3i) that gives\n"
	"                          the voxels' colours, written as .col files\n"
	"                          like a mesh's (default: the Vec3 grid named\n"
	"                          Cd, else color, colour, rgb; none: no\n"
	"                          colours). Floats 0..1 and ints 0..255 are\n"
	"                          sRGB, clamped, NaN 0; an inactive voxel has\n"
	"                          the grid's background. A grid with another\n"
	"                          transform is read at the voxel nearest to each\n"
	"                          voxel's centre (schemas/colour-rule.md)\n"
	"\n"
	"Exit status: 0 success, 1 failure (bad input, I/O, budget), 2 usage.\n";

/* Files an OUTDIR written before manifests existed may hold, so it can be
 * replaced; anything else in OUTDIR is the user's and stops the run. */
static int our_file(const char *name)
{
	size_t n = strlen(name);
	return (!strncmp(name, "chunk-L", 7) && n > 4 &&
		(!strcmp(name + n - 4, ".svo") ||
		 !strcmp(name + n - 4, ".col"))) ||
	       !strcmp(name, "voxelize.stats.json") || !strcmp(name, "bins.tmp") ||
	       !strcmp(name, VD_SOURCES_NAME);
}

/* OpenVDB costs a process about 30 MB of memory at start (relocating
 * libopenvdb), and Assimp about 4 MB, which mesh voxelization should not
 * pay against its budget. So this file builds three programs: voxelize,
 * which hands .vdb input and Assimp's formats to a sibling, voxelize-vdb
 * (VOXELIZE_WITH_VDB), which links OpenVDB, and voxelize-assimp
 * (VOXELIZE_WITH_ASSIMP), which links Assimp. */
#if !defined(VOXELIZE_WITH_VDB) || !defined(VOXELIZE_WITH_ASSIMP)
/* Runs the program `name` of our own directory with our arguments; only
 * returns (1, said) when that fails. `what` names the input kind. */
static int exec_sibling(char **argv, const char *name, const char *what)
{
	char path[4096];
	ssize_t n = readlink("/proc/self/exe", path, sizeof path - 32);
	if (n <= 0) {
		fprintf(stderr, "voxelize: cannot find my own directory: %s\n",
			strerror(errno));
		return 1;
	}
	path[n] = 0;
	char *slash = strrchr(path, '/');
	snprintf(slash ? slash + 1 : path, 32, "%s", name);
	execv(path, argv);
	fprintf(stderr, "voxelize: cannot run '%s' for %s input: %s\n",
		path, what, strerror(errno));
	return 1;
}
#endif

/* A .vdb name (any case) selects the OpenVDB import. */
static int is_vdb(const char *path)
{
	size_t n = strlen(path);
	return n >= 4 && strcasecmp(path + n - 4, ".vdb") == 0;
}

enum { OPT_GRID = 256, OPT_VDB_MODE, OPT_FOG_THRESHOLD, OPT_NO_COLOURS,
       OPT_STRICT, OPT_COLOUR_GRID };

/* The command; main owns `provenance` and `argv_given` (argv before
 * getopt_long permutes it), so every early return frees them. Its length
 * is the option switch, a case per option of --help. */
static int voxelize_main(int argc, char **argv, char *provenance,
			 char **argv_given)
{
	static const struct option longopts[] = {
		{"output", required_argument, NULL, 'o'},
		{"levels", required_argument, NULL, 'l'},
		{"chunk-level", required_argument, NULL, 'c'},
		{"mem-budget", required_argument, NULL, 'm'},
		{"threads", required_argument, NULL, 'j'},
		{"quiet", no_argument, NULL, 'q'},
		{"help", no_argument, NULL, 'h'},
		{"grid", required_argument, NULL, OPT_GRID},
		{"vdb-mode", required_argument, NULL, OPT_VDB_MODE},
		{"fog-threshold", required_argument, NULL, OPT_FOG_THRESHOLD},
		{"no-colours", no_argument, NULL, OPT_NO_COLOURS},
		{"strict", no_argument, NULL, OPT_STRICT},
		{"colour-grid", required_argument, NULL, OPT_COLOUR_GRID},
		{NULL, 0, NULL, 0},
	};
	struct vd_voxelize_opts o = {.levels = 0, .chunk_level = -1,
				     .mem_budget_bytes = 2ull << 30,
				     .tool = "voxelize", .colours = 1};
	const char *outdir = NULL;
	int c, have_levels = 0, vdb_opts = 0;
	struct vd_vdb_select sel = {.mode = VD_VDB_ACTIVE};
	char *end;
	while ((c = getopt_long(argc, argv, "o:l:c:m:j:qh", longopts, NULL)) != -1) {
		switch (c) {
		case 'o':
			outdir = optarg;
			break;
		case 'l':
			if (vd_cli_int(optarg, 1, VD_MAX_LEVELS, &o.levels))
				return vd_cli_usage(TOOL, "--levels '%s' is not a whole "
						   "number from 1 to 21", optarg);
			have_levels = 1;
			break;
		case 'c':
			if (vd_cli_int(optarg, 0, VD_MAX_LEVELS, &o.chunk_level))
				return vd_cli_usage(TOOL, "--chunk-level '%s' is not a "
						   "level", optarg);
			break;
		case 'm':
			if (vd_parse_size(optarg, &o.mem_budget_bytes) ||
			    o.mem_budget_bytes == 0)
				return vd_cli_usage(TOOL, "--mem-budget '%s' is not a "
						   "size (e.g. 512M, 2GiB)", optarg);
			break;
		case 'j':
			if (vd_cli_int(optarg, 1, 1024, &o.threads))
				return vd_cli_usage(TOOL, "--threads '%s' is not a "
						   "number from 1 to 1024", optarg);
			break;
		case OPT_GRID:
			sel.grid_name = optarg;
			vdb_opts = 1;
			break;
		case OPT_VDB_MODE:
			if (vd_vdb_mode_parse(optarg, &sel.mode))
				return vd_cli_usage(TOOL, "--vdb-mode '%s' is not one of "
						   "active, levelset-surface, "
						   "levelset-solid, fog", optarg);
			vdb_opts = 1;
			break;
		case OPT_FOG_THRESHOLD:
			sel.fog_threshold = strtod(optarg, &end);
			if (!*optarg || *end || !isfinite(sel.fog_threshold))
				return vd_cli_usage(TOOL, "--fog-threshold '%s' is not a "
						   "number", optarg);
			vdb_opts = 1;
			break;
		case OPT_COLOUR_GRID:
			sel.colour_grid = optarg;
			vdb_opts = 1;
			break;
		case OPT_NO_COLOURS:
			o.colours = 0;
			break;
		case OPT_STRICT:
			o.strict = 1;
			break;
		case 'q':
			o.quiet = 1;
			break;
		case 'h':
			fputs(usage, stdout);
			return 0;
		default:
			fprintf(stderr, "Try 'voxelize --help'.\n");
			return 2;
		}
	}
	if (optind != argc - 1)
		return vd_cli_usage(TOOL, "%s", optind >= argc ? "no MESH given"
							: "more than one MESH given");
	if (!outdir)
		return vd_cli_usage(TOOL, "%s", "no output directory (-o OUTDIR) given");
	const char *mesh = argv[optind];
	int vdb = is_vdb(mesh);
	if (!have_levels && !vdb)
		return vd_cli_usage(TOOL, "%s", "no grid depth (--levels L) given");
	if (vdb_opts && !vdb)
		return vd_cli_usage(TOOL, "%s", "--grid, --vdb-mode, --fog-threshold "
				   "and --colour-grid are for OpenVDB (.vdb) "
				   "input only");
	if (sel.colour_grid && !o.colours)
		return vd_cli_usage(TOOL, "%s", "--colour-grid and --no-colours "
				   "contradict each other");
	o.provenance = provenance;

	int sibling_rc = -1; /* exec_sibling only returns on failure */
#ifndef VOXELIZE_WITH_VDB
	if (vdb) {
		(void)sel;
		sibling_rc = exec_sibling(argv_given, "voxelize-vdb", "OpenVDB");
	}
#endif
#ifndef VOXELIZE_WITH_ASSIMP
	if (vd_mesh_is_imported(mesh))
		sibling_rc = exec_sibling(argv_given, "voxelize-assimp",
					  "glTF, FBX, Collada or 3DS");
#else
	vd_mesh_set_importer(vd_assimp_import);
#endif
	if (sibling_rc >= 0)
		return sibling_rc; /* main frees the provenance and argv copy */
	/* all or nothing: build beside OUTDIR, then swap it in whole */
	char stage[4096], path[4200];
	int err = vd_dir_stage(outdir, our_file, stage, sizeof stage);
	if (!err) {
		snprintf(path, sizeof path, "%s/voxelize.stats.json", stage);
		if (vdb) {
#ifdef VOXELIZE_WITH_VDB
			struct vd_vdb_import_result res;
			err = vd_vdb_import(mesh, stage, &sel, &o, &res);
			if (!err)
				err = vd_vdb_import_write_stats(&res, path);
#endif
		} else {
			struct vd_voxelize_result res;
			err = vd_voxelize_mesh(mesh, stage, &o, &res);
			if (!err)
				err = vd_voxelize_write_stats(&res, path);
		}
		if (!err)
			err = vd_dir_publish(stage, outdir);
		if (err)
			vd_dir_abandon(stage);
	}
	if (err) {
		const char *d = vd_error_detail();
		fprintf(stderr, "voxelize: cannot voxelize '%s': %s%s%s\n", mesh,
			vd_strerror(err), *d ? ": " : "", d);
		return 1;
	}
	return 0;
}

int main(int argc, char **argv)
{
	/* before getopt_long permutes argv */
	char *provenance = vd_provenance_new("voxelize", argc, argv);
	char **argv_given = calloc((size_t)argc + 1, sizeof *argv_given);
	int rc = 1;
	if (argv_given && provenance) {
		memcpy(argv_given, argv, (size_t)argc * sizeof *argv);
		rc = voxelize_main(argc, argv, provenance, argv_given);
	} else {
		fprintf(stderr, "voxelize: out of memory\n");
	}
	free(provenance);
	free(argv_given);
	return rc;
}
