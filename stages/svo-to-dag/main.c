/* svo-to-dag - SVO chunk to minimal SVDAG chunk; merge of sibling DAG chunks. */
#include "voxdag.h"

#include <getopt.h>
#include <stdlib.h>
#include <string.h>

static const char usage[] =
	"usage: svo-to-dag IN.svo -o OUT.dag [options]\n"
	"       svo-to-dag --merge IN.dag... -o OUT.dag [--to-level A] [options]\n"
	"\n"
	"Builds the minimal SVDAG of an SVO chunk: bottom-up, level by level,\n"
	"identical subtrees become one node (Kaempe et al. 2013). With --merge,\n"
	"builds the DAG chunk of the cell containing the given DAG chunks,\n"
	"reducing again from the leaves so subtrees shared across chunks become\n"
	"one; applied up a reduction tree this yields the root chunk (level 0).\n"
	"Statistics go to OUT.dag.stats.json.\n"
	"\n"
	"  -o, --output FILE       output chunk file (written atomically)\n"
	"  -M, --merge             merge the chunks of cells inside one cell:\n"
	"                          inputs of equal depth, no two overlapping\n"
	"  -t, --to-level A        with --merge: level of the output cell\n"
	"                          (default: one above the shallowest input)\n"
	"  -m, --mem-budget SIZE   peak memory of the process (default 2GiB);\n"
	"                          e.g. 512M, 4GiB\n"
	"  -j, --threads N         worker threads (default: all cores); used by\n"
	"                          the brick pass, the largest; the levels above\n"
	"                          are serial (memory-bound), as are merges\n"
	"  -q, --quiet             no summary line on stderr\n"
	"  -h, --help              this text\n"
	"\n"
	"Exit status: 0 success, 1 failure (bad input, I/O, budget), 2 usage.\n";

static int usage_error(const char *fmt, const char *arg)
{
	fprintf(stderr, "svo-to-dag: ");
	fprintf(stderr, fmt, arg);
	fprintf(stderr, "\nTry 'svo-to-dag --help'.\n");
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
		{"merge", no_argument, NULL, 'M'},
		{"to-level", required_argument, NULL, 't'},
		{"mem-budget", required_argument, NULL, 'm'},
		{"threads", required_argument, NULL, 'j'},
		{"quiet", no_argument, NULL, 'q'},
		{"help", no_argument, NULL, 'h'},
		{NULL, 0, NULL, 0},
	};
	struct vd_dag_job job = {.tool = "svo-to-dag", .kind = VD_KIND_DAG,
				 .to_level = -1,
				 .opts = {.mem_budget_bytes = 2ull << 30}};
	int c, have_level = 0;
	while ((c = getopt_long(argc, argv, "o:Mt:m:j:qh", longopts, NULL)) != -1) {
		switch (c) {
		case 'o':
			job.output = optarg;
			break;
		case 'M':
			job.merge = 1;
			break;
		case 't':
			if (parse_int(optarg, 0, VD_MAX_LEVELS - 1, &job.to_level))
				return usage_error("--to-level '%s' is not a level "
						   "from 0 to 20", optarg);
			have_level = 1;
			break;
		case 'm':
			if (vd_parse_size(optarg, &job.opts.mem_budget_bytes) ||
			    job.opts.mem_budget_bytes == 0)
				return usage_error("--mem-budget '%s' is not a "
						   "size (e.g. 512M, 2GiB)", optarg);
			break;
		case 'j':
			if (parse_int(optarg, 1, 1024, &job.opts.threads))
				return usage_error("--threads '%s' is not a "
						   "number from 1 to 1024", optarg);
			break;
		case 'q':
			job.quiet = 1;
			break;
		case 'h':
			fputs(usage, stdout);
			return 0;
		default:
			fprintf(stderr, "Try 'svo-to-dag --help'.\n");
			return 2;
		}
	}
	if (optind >= argc)
		return usage_error("%s", "no input chunk given");
	if (!job.merge && argc - optind > 1)
		return usage_error("%s", "more than one input (use --merge to "
				   "merge chunks)");
	if (have_level && !job.merge)
		return usage_error("%s", "--to-level needs --merge");
	if (!job.output)
		return usage_error("%s", "no output file (-o OUT) given");
	job.inputs = (const char *const *)(argv + optind);
	job.n_inputs = (size_t)(argc - optind);
	job.provenance = vd_provenance_new("svo-to-dag", argc, argv);
	int err = vd_dag_run(&job);
	free((char *)job.provenance);
	if (err) {
		fprintf(stderr, "svo-to-dag: %s\n", vd_error_detail());
		return 1;
	}
	return 0;
}
