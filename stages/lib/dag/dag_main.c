/* dag_main.c - the command line of svo-to-dag and symmetry-merge, which
 * take the same options and differ only in the kind they build. */
#include "voxdag.h"
#include "cli.h"

#include <getopt.h>
#include <stdlib.h>
#include <string.h>

int vd_dag_stage_main(int argc, char **argv, const char *tool, uint32_t kind,
		      const char *usage)
{
	static const struct option longopts[] = {
		{"output", required_argument, NULL, 'o'},
		{"merge", no_argument, NULL, 'M'},
		{"to-level", required_argument, NULL, 't'},
		{"mem-budget", required_argument, NULL, 'm'},
		{"threads", required_argument, NULL, 'j'},
		{"quiet", no_argument, NULL, 'q'},
		{"group", required_argument, NULL, 'g'},
		{"help", no_argument, NULL, 'h'},
		{NULL, 0, NULL, 0},
	};
	struct vd_dag_job job = {.tool = tool, .kind = kind, .to_level = -1,
				 .opts = {.mem_budget_bytes = 2ull << 30}};
	int c, have_level = 0;
	while ((c = getopt_long(argc, argv, "o:Mt:m:j:qg:h", longopts, NULL)) != -1) {
		switch (c) {
		case 'o':
			job.output = optarg;
			break;
		case 'M':
			job.merge = 1;
			break;
		case 't':
			if (vd_cli_int(optarg, 0, VD_MAX_LEVELS - 1, &job.to_level))
				return vd_cli_usage(tool, "--to-level '%s' is not a "
						    "level from 0 to 20", optarg);
			have_level = 1;
			break;
		case 'm':
			if (vd_parse_size(optarg, &job.opts.mem_budget_bytes) ||
			    job.opts.mem_budget_bytes == 0)
				return vd_cli_usage(tool, "--mem-budget '%s' is not "
						    "a size (e.g. 512M, 2GiB)", optarg);
			break;
		case 'j':
			if (vd_cli_int(optarg, 1, 1024, &job.opts.threads))
				return vd_cli_usage(tool, "--threads '%s' is not a "
						    "number from 1 to 1024", optarg);
			break;
		case 'q':
			job.quiet = 1;
			break;
		case 'g':
			/* symmetry-merge only: svo-to-dag builds no symmetry */
			if (kind != VD_KIND_SSVDAG)
				return vd_cli_usage(tool, "unknown option --group");
			if (strcmp(optarg, "8") && strcmp(optarg, "48"))
				return vd_cli_usage(tool, "--group '%s' is not 8 "
						    "or 48", optarg);
			job.kind = strcmp(optarg, "48") ? VD_KIND_SSVDAG
							: VD_KIND_SSVDAG48;
			break;
		case 'h':
			fputs(usage, stdout);
			return 0;
		default:
			fprintf(stderr, "Try '%s --help'.\n", tool);
			return 2;
		}
	}
	if (optind >= argc)
		return vd_cli_usage(tool, "no input chunk given");
	if (!job.merge && argc - optind > 1)
		return vd_cli_usage(tool, "more than one input (use --merge to "
				    "merge chunks)");
	if (have_level && !job.merge)
		return vd_cli_usage(tool, "--to-level needs --merge");
	if (!job.output)
		return vd_cli_usage(tool, "no output file (-o OUT) given");
	job.inputs = (const char *const *)(argv + optind);
	job.n_inputs = (size_t)(argc - optind);
	job.provenance = vd_provenance_new(tool, argc, argv);
	int err = vd_dag_run(&job);
	free((char *)job.provenance);
	if (err) {
		fprintf(stderr, "%s: %s\n", tool, vd_error_detail());
		return 1;
	}
	return 0;
}
