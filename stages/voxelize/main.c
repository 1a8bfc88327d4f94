/* voxelize - triangle mesh to SVO chunk files, out of core. */
#include "voxdag.h"

#include <getopt.h>
#include <stdlib.h>
#include <string.h>

static const char usage[] =
	"usage: voxelize MESH -o OUTDIR --levels L [options]\n"
	"\n"
	"Voxelizes the surface of a triangle mesh (PLY, OBJ, STL or AC3D) into\n"
	"a grid of 2^L voxels per side and writes one SVO chunk file per\n"
	"non-empty cell of the chunk level L0, plus OUTDIR/voxelize.stats.json.\n"
	"Earlier chunk files in OUTDIR are replaced.\n"
	"\n"
	"  -o, --output DIR        directory for the chunks (created if missing)\n"
	"  -l, --levels L          grid depth, 1..21 (2^L voxels per side)\n"
	"  -c, --chunk-level L0    level of the cells, 0..min(L-2, 7)\n"
	"                          (default: the coarsest that fits the budget)\n"
	"  -m, --mem-budget SIZE   peak memory of the process (default 2GiB);\n"
	"                          e.g. 512M, 4GiB\n"
	"  -j, --threads N         worker threads (default: all cores)\n"
	"  -q, --quiet             no progress lines on stderr\n"
	"  -h, --help              this text\n"
	"\n"
	"Exit status: 0 success, 1 failure (bad input, I/O, budget), 2 usage.\n";

static int usage_error(const char *fmt, const char *arg)
{
	fprintf(stderr, "voxelize: ");
	fprintf(stderr, fmt, arg);
	fprintf(stderr, "\nTry 'voxelize --help'.\n");
	return 2;
}

static int parse_int(const char *s, int lo, int hi, int *out)
{
	char *end;
	long v = strtol(s, &end, 10);
	if (!*s || *end || v < lo || v > hi)
		return -1;
	*out = (int)v;
	return 0;
}

int main(int argc, char **argv)
{
	static const struct option longopts[] = {
		{"output", required_argument, NULL, 'o'},
		{"levels", required_argument, NULL, 'l'},
		{"chunk-level", required_argument, NULL, 'c'},
		{"mem-budget", required_argument, NULL, 'm'},
		{"threads", required_argument, NULL, 'j'},
		{"quiet", no_argument, NULL, 'q'},
		{"help", no_argument, NULL, 'h'},
		{NULL, 0, NULL, 0},
	};
	struct vd_voxelize_opts o = {.levels = 0, .chunk_level = -1,
				     .mem_budget_bytes = 2ull << 30,
				     .tool = "voxelize"};
	const char *outdir = NULL;
	int c, have_levels = 0;
	/* before getopt_long permutes argv */
	char *provenance = vd_provenance_new("voxelize", argc, argv);
	while ((c = getopt_long(argc, argv, "o:l:c:m:j:qh", longopts, NULL)) != -1) {
		switch (c) {
		case 'o':
			outdir = optarg;
			break;
		case 'l':
			if (parse_int(optarg, 1, VD_MAX_LEVELS, &o.levels))
				return usage_error("--levels '%s' is not a whole "
						   "number from 1 to 21", optarg);
			have_levels = 1;
			break;
		case 'c':
			if (parse_int(optarg, 0, VD_MAX_LEVELS, &o.chunk_level))
				return usage_error("--chunk-level '%s' is not a "
						   "level", optarg);
			break;
		case 'm':
			if (vd_parse_size(optarg, &o.mem_budget_bytes) ||
			    o.mem_budget_bytes == 0)
				return usage_error("--mem-budget '%s' is not a "
						   "size (e.g. 512M, 2GiB)", optarg);
			break;
		case 'j':
			if (parse_int(optarg, 1, 1024, &o.threads))
				return usage_error("--threads '%s' is not a "
						   "number from 1 to 1024", optarg);
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
		return usage_error("%s", optind >= argc ? "no MESH given"
							: "more than one MESH given");
	if (!outdir)
		return usage_error("%s", "no output directory (-o OUTDIR) given");
	if (!have_levels)
		return usage_error("%s", "no grid depth (--levels L) given");
	const char *mesh = argv[optind];
	o.provenance = provenance;

	struct vd_voxelize_result res;
	int err = vd_voxelize_mesh(mesh, outdir, &o, &res);
	if (!err) {
		char path[4096];
		snprintf(path, sizeof path, "%s/voxelize.stats.json", outdir);
		err = vd_voxelize_write_stats(&res, path);
	}
	free(provenance);
	if (err) {
		const char *d = vd_error_detail();
		fprintf(stderr, "voxelize: cannot voxelize '%s': %s%s%s\n", mesh,
			vd_strerror(err), *d ? ": " : "", d);
		return 1;
	}
	return 0;
}
