/* edit - HashDAG edits of a root DAG chunk: a script, or an interactive
 * shell (argument handling only; the work is in stages/lib/edit/). */
#include "voxdag.h"
#include "cli.h"

#include <getopt.h>
#include <stdlib.h>
#include <string.h>

#define TOOL "edit"

static const char usage[] =
	"usage: edit ROOT.dag -o EDITED.dag --script EDITS.txt [options]\n"
	"       edit ROOT.dag --colours SRC -o EDITED.dag --colours-out DIR\n"
	"            --script EDITS.txt [options]\n"
	"       edit --shell ROOT.dag [-o EDITED.dag] [options]\n"
	"\n"
	"Loads a root DAG chunk into a HashDAG (Careil et al. 2020) and applies\n"
	"edits: fill and carve of boxes and spheres, copy of a box, with undo,\n"
	"redo and garbage collection. The line format is in\n"
	"schemas/edit-script.md. A script is parsed and checked whole before\n"
	"anything is edited; the result is saved as the minimal DAG chunk that\n"
	"svo-to-dag builds for the same voxels, with per-operation statistics in\n"
	"EDITED.dag.stats.json. The shell reads one line at a time from stdin\n"
	"(also render FILE.png, save [FILE], stats, quit).\n"
	"\n"
	"Colours: with --colours SRC (a voxelize output directory with .col\n"
	"chunks, or a colorize packed file, of the same scene) edits carry the\n"
	"voxel colours along and `paint` recolours a region; fill takes its\n"
	"'colour R G B' or the default, carved voxels drop theirs, copies take\n"
	"their source's. The edited colours go to --colours-out DIR as a\n"
	"voxelize-style directory (SVO and .col chunk per cell; unchanged cells\n"
	"linked from SRC), which render --colours and colorize take.\n"
	"\n"
	"  -o, --output FILE       edited chunk (written atomically)\n"
	"  -s, --script FILE       the edits, one per line\n"
	"  -S, --shell             interactive: lines from stdin\n"
	"  -j, --threads N         worker threads (default: all cores)\n"
	"  -P, --buckets P         2^min(P, 3l+4) buckets on level l (default:\n"
	"                          from each level's size, at most half full)\n"
	"  -M, --bucket-words M    2^M 32-bit words per bucket (default 10;\n"
	"                          4 <= M, P + M <= 30)\n"
	"  -c, --colours SRC       the scene's colours (see above)\n"
	"  -C, --colours-out DIR   where the edited colours go (needed with\n"
	"                          --colours and --script)\n"
	"  -F, --fill-colour R,G,B colour of voxels a fill without a colour\n"
	"                          adds (default 128,128,128)\n"
	"  -m, --mem-budget SIZE   bound on the bucket tables, their committed\n"
	"                          pages and the colour arrays (default: none);\n"
	"                          e.g. 512M, 4GiB\n"
	"  -q, --quiet             no summary line on stderr\n"
	"  -h, --help              this text\n"
	"\n"
	"A full bucket stops the edit with an error: run gc, or raise -P/-M;\n"
	"so does passing --mem-budget: run gc, or raise it.\n"
	"Exit status: 0 success, 1 failure (bad input, full bucket, I/O), 2 usage.\n";

int main(int argc, char **argv)
{
	static const struct option longs[] = {
		{"output", required_argument, NULL, 'o'},
		{"script", required_argument, NULL, 's'},
		{"shell", no_argument, NULL, 'S'},
		{"threads", required_argument, NULL, 'j'},
		{"buckets", required_argument, NULL, 'P'},
		{"bucket-words", required_argument, NULL, 'M'},
		{"colours", required_argument, NULL, 'c'},
		{"colours-out", required_argument, NULL, 'C'},
		{"fill-colour", required_argument, NULL, 'F'},
		{"mem-budget", required_argument, NULL, 'm'},
		{"quiet", no_argument, NULL, 'q'},
		{"help", no_argument, NULL, 'h'},
		{NULL, 0, NULL, 0}};
	struct vd_edit_job job = {.tool = TOOL};
	int shell = 0, c;
	while ((c = getopt_long(argc, argv, "o:s:Sj:P:M:c:C:F:m:qh", longs, NULL)) !=
	       -1) {
		switch (c) {
		case 'o': job.output = optarg; break;
		case 's': job.script = optarg; break;
		case 'S': shell = 1; break;
		case 'j':
			if (vd_cli_int(optarg, 1, 1024, &job.opts.threads))
				return vd_cli_usage(TOOL, "bad --threads '%s'",
						    optarg);
			break;
		case 'P':
			if (vd_cli_int(optarg, 0, 26, &job.opts.buckets_log2))
				return vd_cli_usage(TOOL, "bad --buckets "
						    "'%s' (0..26)", optarg);
			break;
		case 'M':
			if (vd_cli_int(optarg, 4, 26,
				       &job.opts.bucket_words_log2))
				return vd_cli_usage(TOOL, "bad "
						    "--bucket-words '%s' "
						    "(4..26)", optarg);
			break;
		case 'c': job.colours = optarg; break;
		case 'C': job.colours_out = optarg; break;
		case 'F': {
			unsigned r, g, b;
			char end;
			if (sscanf(optarg, "%u,%u,%u%c", &r, &g, &b, &end) != 3 ||
			    r > 255 || g > 255 || b > 255)
				return vd_cli_usage(TOOL, "bad --fill-colour "
						    "'%s' (R,G,B, each 0..255)",
						    optarg);
			job.fill_rgb[0] = (uint8_t)r;
			job.fill_rgb[1] = (uint8_t)g;
			job.fill_rgb[2] = (uint8_t)b;
			job.has_fill_rgb = 1;
			break;
		}
		case 'm':
			if (vd_parse_size(optarg, &job.opts.mem_budget_bytes) ||
			    !job.opts.mem_budget_bytes)
				return vd_cli_usage(TOOL, "bad --mem-budget "
						    "'%s'", optarg);
			break;
		case 'q': job.quiet = 1; break;
		case 'h': fputs(usage, stdout); return 0;
		default: return vd_cli_usage(TOOL, "bad option");
		}
	}
	if (optind + 1 != argc)
		return vd_cli_usage(TOOL, "need exactly one input ROOT.dag");
	job.input = argv[optind];
	if (shell == !!job.script)
		return vd_cli_usage(TOOL, "need one of --script FILE or "
				    "--shell");
	if (job.script && !job.output)
		return vd_cli_usage(TOOL, "--script needs -o EDITED.dag");
	if (job.colours_out && !job.colours)
		return vd_cli_usage(TOOL, "--colours-out needs --colours SRC");
	if (job.colours && job.script && !job.colours_out)
		return vd_cli_usage(TOOL, "--colours with --script needs "
				    "--colours-out DIR");
	if (job.has_fill_rgb && !job.colours)
		return vd_cli_usage(TOOL, "--fill-colour needs --colours SRC");
	if (job.opts.buckets_log2 && job.opts.bucket_words_log2 &&
	    job.opts.buckets_log2 + job.opts.bucket_words_log2 > 30)
		return vd_cli_usage(TOOL, "--buckets + --bucket-words "
				    "must be at most 30");
	char *prov = vd_provenance_new(TOOL, argc, argv);
	job.provenance = prov;
	int err = vd_edit_run(&job);
	free(prov);
	if (err) {
		if (*vd_error_detail()) /* the shell reported its own */
			fprintf(stderr, "%s: %s\n", TOOL, vd_error_detail());
		return 1;
	}
	return 0;
}
