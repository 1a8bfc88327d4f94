/* lossy-cluster - lossy SVDAG (van der Laan et al. 2020): similar, rarely
 * used subtrees of a DAG chunk clustered and merged. */
#include "voxdag.h"
#include "cli.h"

#include <getopt.h>
#include <malloc.h>
#include <math.h>
#include <stdlib.h>

#define TOOL "lossy-cluster"

static const char usage[] =
	"usage: lossy-cluster ROOT.dag -o LOSSY.dag [options]\n"
	"\n"
	"Lossy SVDAG (van der Laan, Scandolo and Eisemann 2020). From height 2\n"
	"up to the root, the subtrees whose effective reference count (how often\n"
	"they occur in the scene) is at most R and whose voxels differ by at\n"
	"most m = h^2 * P from another such subtree of the same topology (m = 1\n"
	"at height 2) form a similarity graph; Markov clustering of each of its\n"
	"connected components groups them, and every group is replaced by its\n"
	"member most similar to the others. The levels above are then reduced\n"
	"losslessly again. The output is an ordinary dag chunk; statistics\n"
	"(per level, voxels changed, error rate, seconds, peak RSS) go to\n"
	"LOSSY.dag.stats.json.\n"
	"\n"
	"  -o, --output FILE       output chunk file (written atomically)\n"
	"  -I, --inflation X       MCL inflation, 1 < X <= 100 (default 2.0)\n"
	"  -p, --diff-factor P     P of the threshold m = h^2 * P, 0 to 1e6\n"
	"                          (default 1.0)\n"
	"  -r, --max-refs R        candidates: at most R effective references,\n"
	"                          0 (none: the output equals the input) to\n"
	"                          1000000 (default 1)\n"
	"  -m, --mem-budget SIZE   peak memory of the process (default 2GiB);\n"
	"                          e.g. 512M, 4GiB\n"
	"  -L, --levels N          cluster the scene at 2^N voxels a side: the\n"
	"                          input (a root chunk of at least N levels)\n"
	"                          cut at depth N first (default: its own)\n"
	"  -j, --threads N         worker threads for the clustering of the\n"
	"                          components (default: all cores); the output\n"
	"                          is the same for any N\n"
	"  -q, --quiet             no summary line on stderr\n"
	"  -h, --help              this text\n"
	"\n"
	"Exit status: 0 success, 1 failure (bad input, I/O, budget), 2 usage.\n";

static int parse_double(const char *s, double lo, double hi, int lo_open,
			double *out)
{
	char *end;
	double v = strtod(s, &end);
	if (!*s || *end || !isfinite(v) || v > hi || v < lo ||
	    (lo_open && v == lo))
		return -1;
	*out = v;
	return 0;
}

int main(int argc, char **argv)
{
	static const struct option longopts[] = {
		{"output", required_argument, NULL, 'o'},
		{"inflation", required_argument, NULL, 'I'},
		{"diff-factor", required_argument, NULL, 'p'},
		{"max-refs", required_argument, NULL, 'r'},
		{"mem-budget", required_argument, NULL, 'm'},
		{"threads", required_argument, NULL, 'j'},
		{"levels", required_argument, NULL, 'L'},
		{"quiet", no_argument, NULL, 'q'},
		{"help", no_argument, NULL, 'h'},
		{NULL, 0, NULL, 0},
	};
	struct vd_lossy_opts o = {.inflation = 2.0, .diff_factor = 1.0,
				  .max_refs = 1, .threads = 0};
	uint64_t budget = 2ull << 30;
	const char *output = NULL;
	int c, quiet = 0, r;
	while ((c = getopt_long(argc, argv, "o:I:p:r:m:j:L:qh", longopts, NULL)) != -1) {
		switch (c) {
		case 'o':
			output = optarg;
			break;
		case 'I':
			if (parse_double(optarg, 1.0, 100.0, 1, &o.inflation))
				return vd_cli_usage(TOOL, "--inflation '%s' is not "
						    "a number in (1, 100]", optarg);
			break;
		case 'p':
			if (parse_double(optarg, 0.0, 1e6, 0, &o.diff_factor))
				return vd_cli_usage(TOOL, "--diff-factor '%s' is not "
						    "a number from 0 to 1e6", optarg);
			break;
		case 'r':
			if (vd_cli_int(optarg, 0, 1000000, &r))
				return vd_cli_usage(TOOL, "--max-refs '%s' is not a "
						    "number from 0 to 1000000", optarg);
			o.max_refs = (uint64_t)r;
			break;
		case 'm':
			if (vd_parse_size(optarg, &budget) || budget == 0)
				return vd_cli_usage(TOOL, "--mem-budget '%s' is not "
						    "a size (e.g. 512M, 2GiB)", optarg);
			break;
		case 'j':
			if (vd_cli_int(optarg, 1, 1024, &o.threads))
				return vd_cli_usage(TOOL, "--threads '%s' is not a "
						    "number from 1 to 1024", optarg);
			break;
		case 'L':
			if (vd_cli_int(optarg, 1, VD_MAX_LEVELS, &o.levels))
				return vd_cli_usage(TOOL, "--levels '%s' is not a "
						    "number from 1 to %d", optarg,
						    VD_MAX_LEVELS);
			break;
		case 'q':
			quiet = 1;
			break;
		case 'h':
			fputs(usage, stdout);
			return 0;
		default:
			fprintf(stderr, "Try '%s --help'.\n", TOOL);
			return 2;
		}
	}
	if (optind >= argc)
		return vd_cli_usage(TOOL, "no input chunk given");
	if (argc - optind > 1)
		return vd_cli_usage(TOOL, "more than one input chunk");
	if (!output)
		return vd_cli_usage(TOOL, "no output file (-o OUT) given");
	/* The clustering allocates and frees arrays of a few MB per level
	 * and per graph component; glibc returned them to the kernel each
	 * time (mmap, heap trimming), and the page faults of getting them
	 * back were a quarter of the lossy phase on the dragon at 2^12. Freed
	 * memory stays in the heap instead (the peak grew by a tenth there,
	 * 146 to 161 MB, for 0.5 s less CPU). */
	mallopt(M_MMAP_THRESHOLD, 256 << 20);
	mallopt(M_TRIM_THRESHOLD, 1 << 30);
	char *prov = vd_provenance_new(TOOL, argc, argv);
	int err = vd_lossy_run(argv[optind], output, &o, budget, prov, quiet);
	free(prov);
	if (err) {
		fprintf(stderr, "%s: %s\n", TOOL, vd_error_detail());
		return 1;
	}
	return 0;
}
