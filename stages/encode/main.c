/* encode - root DAG and SSVDAG chunks to the SymVox encodings (and an
 * ssvdag48 chunk to .ssvdag48) and the SSVDAG paper's tables. */
#include "voxdag.h"
#include "cli.h"

#include <errno.h>
#include <getopt.h>
#include <stdlib.h>
#include <string.h>

#define TOOL "encode"

static const char usage[] =
	"usage: encode ROOT.dag ROOT.ssvdag [ROOT.ssvdag48] -o DIR [options]\n"
	"\n"
	"Writes the compact encodings of the SSVDAG paper (section 4.3) of a\n"
	"scene, byte-compatible with the SymVox files (schemas/encodings.md):\n"
	"DIR/NAME.svdag and DIR/NAME.esvdag from the root DAG chunk,\n"
	"DIR/NAME.ussvdag and DIR/NAME.ssvdag from the root SSVDAG chunk (both\n"
	"at chunk level 0, as svo-to-dag and symmetry-merge leave them), and\n"
	"DIR/NAME.ssvdag48 from a root chunk of the 48-group symmetry merge (voxdag's\n"
	"own format). The symmetric inputs are told apart by their chunk kind: an\n"
	"ssvdag, an ssvdag48 or one of each. Grids of fewer than 3 levels get no\n"
	".esvdag/.ssvdag/.ssvdag48 (they need 4^3 bricks below an inner level).\n"
	"Also writes the paper's Table 1 and Table 2 for every resolution from\n"
	"the full one down to 2^MIN (the lower ones are the same DAG cut at a\n"
	"shallower depth and reduced again) as DIR/NAME.tables.json,\n"
	"DIR/NAME.table1.csv, DIR/NAME.table2.csv and DIR/NAME.tables.md, and\n"
	"statistics as DIR/NAME.encode.stats.json.\n"
	"\n"
	"  -o, --output DIR        output directory (created if missing)\n"
	"  -n, --name NAME         base name of the output files (default scene)\n"
	"  -s, --stats FILE        statistics JSON of an svo-to-dag or\n"
	"                          symmetry-merge run, for Table 1's seconds\n"
	"                          (repeat for every chunk and merge run)\n"
	"  -S, --stats-list FILE   the same for every path in FILE, one a line\n"
	"                          (what the runner passes: no limit on their\n"
	"                          number)\n"
	"  -l, --min-level MIN     lowest resolution of the tables, 2^MIN\n"
	"                          (default 6)\n"
	"  -m, --mem-budget SIZE   peak memory of the process (default 2GiB);\n"
	"                          e.g. 512M, 4GiB\n"
	"  -j, --threads N         table rows computed in parallel (default:\n"
	"                          all cores)\n"
	"  -q, --quiet             no summary line on stderr\n"
	"  -h, --help              this text\n"
	"\n"
	"Exit status: 0 success, 1 failure (bad input, I/O, budget), 2 usage.\n";



/* Appends the text of `path` to *buf, each line ending in NUL (one path a
 * line). Prints one line and returns non-zero when it cannot be read. */
static int read_list(const char *path, char **buf, size_t *len)
{
	FILE *f = fopen(path, "r");
	if (!f) {
		fprintf(stderr, "encode: cannot open '%s': %s\n", path,
			strerror(errno));
		return 1;
	}
	int ch;
	size_t cap = *len;
	while ((ch = fgetc(f)) != EOF) {
		if (*len + 2 > cap) {
			cap = cap ? 2 * cap : 4096;
			char *g = realloc(*buf, cap);
			if (!g) {
				fclose(f);
				fprintf(stderr, "encode: out of memory\n");
				return 1;
			}
			*buf = g;
		}
		(*buf)[(*len)++] = ch == '\n' ? 0 : (char)ch;
	}
	int bad = ferror(f);
	fclose(f);
	if (bad) {
		fprintf(stderr, "encode: cannot read '%s': %s\n", path,
			strerror(EIO));
		return 1;
	}
	if (*len && (*buf)[*len - 1]) /* a last line without its newline */
		(*buf)[(*len)++] = 0;
	return 0;
}

int main(int argc, char **argv)
{
	static const struct option longopts[] = {
		{"output", required_argument, NULL, 'o'},
		{"name", required_argument, NULL, 'n'},
		{"stats", required_argument, NULL, 's'},
		{"stats-list", required_argument, NULL, 'S'},
		{"min-level", required_argument, NULL, 'l'},
		{"mem-budget", required_argument, NULL, 'm'},
		{"threads", required_argument, NULL, 'j'},
		{"quiet", no_argument, NULL, 'q'},
		{"help", no_argument, NULL, 'h'},
		{NULL, 0, NULL, 0},
	};
	struct vd_enc_job job = {.tool = "encode", .name = "scene",
				 .min_level = 6,
				 .mem_budget_bytes = 2ull << 30};
	size_t stats_cap = (size_t)argc + 1;
	const char **stats = calloc(stats_cap, sizeof *stats);
	char *lists = NULL; /* the --stats-list files' text, paths inside */
	size_t lists_len = 0;
	if (!stats) {
		fprintf(stderr, "encode: out of memory\n");
		return 1;
	}
	int c, rc = 0;
	while ((c = getopt_long(argc, argv, "o:n:s:S:l:m:j:qh", longopts, NULL)) != -1) {
		switch (c) {
		case 'o':
			job.outdir = optarg;
			break;
		case 'n':
			if (!*optarg || strchr(optarg, '/')) {
				rc = vd_cli_usage(TOOL, "--name '%s' must be a plain file "
						 "name", optarg);
				goto done;
			}
			job.name = optarg;
			break;
		case 's':
			stats[job.n_stats++] = optarg;
			break;
		case 'S':
			if (read_list(optarg, &lists, &lists_len)) {
				rc = 1;
				goto done;
			}
			break;
		case 'l':
			if (vd_cli_int(optarg, 1, VD_MAX_LEVELS, &job.min_level)) {
				rc = vd_cli_usage(TOOL, "--min-level '%s' is not a level "
						 "from 1 to 21", optarg);
				goto done;
			}
			break;
		case 'm':
			if (vd_parse_size(optarg, &job.mem_budget_bytes) ||
			    job.mem_budget_bytes == 0) {
				rc = vd_cli_usage(TOOL, "--mem-budget '%s' is not a size "
						 "(e.g. 512M, 2GiB)", optarg);
				goto done;
			}
			break;
		case 'j':
			if (vd_cli_int(optarg, 1, 1024, &job.threads)) {
				rc = vd_cli_usage(TOOL, "--threads '%s' is not a number "
						 "from 1 to 1024", optarg);
				goto done;
			}
			break;
		case 'q':
			job.quiet = 1;
			break;
		case 'h':
			fputs(usage, stdout);
			goto done;
		default:
			fprintf(stderr, "Try 'encode --help'.\n");
			rc = 2;
			goto done;
		}
	}
	if (argc - optind < 2 || argc - optind > 3) {
		rc = vd_cli_usage(TOOL, "%s", argc - optind < 2 ?
				 "needs two inputs: ROOT.dag ROOT.ssvdag" :
				 "more than three inputs (ROOT.dag ROOT.ssvdag "
				 "ROOT.ssvdag48)");
		goto done;
	}
	if (!job.outdir) {
		rc = vd_cli_usage(TOOL, "%s", "no output directory (-o DIR) given");
		goto done;
	}
	job.dag_path = argv[optind];
	for (int i = optind + 1; i < argc; i++) {
		/* by kind; an unreadable file goes on as the ssvdag, whose
		 * loading then names the problem */
		struct vd_chunk_header h;
		int is48 = vd_chunk_read_header(argv[i], &h) == VD_OK &&
			   h.kind == VD_KIND_SSVDAG48;
		vd_error_clear();
		const char **slot = is48 ? &job.ssvdag48_path : &job.ssvdag_path;
		if (*slot) {
			rc = vd_cli_usage(TOOL, "'%s' and '%s' are both %s chunks: "
					 "give one ssvdag and/or one ssvdag48",
					 *slot, argv[i], is48 ? "ssvdag48" : "ssvdag");
			goto done;
		}
		*slot = argv[i];
	}
	/* the --stats-list files' lines, after the --stats options */
	for (size_t i = 0; i < lists_len; i += strlen(lists + i) + 1) {
		if (!lists[i])
			continue;
		if ((size_t)job.n_stats + 1 >= stats_cap) {
			stats_cap *= 2;
			const char **g = realloc(stats, stats_cap * sizeof *stats);
			if (!g) {
				fprintf(stderr, "encode: out of memory\n");
				rc = 1;
				goto done;
			}
			stats = g;
		}
		stats[job.n_stats++] = lists + i;
		stats[job.n_stats] = NULL;
	}
	job.stats_paths = stats;
	if (vd_enc_run(&job)) {
		fprintf(stderr, "encode: %s\n", vd_error_detail());
		rc = 1;
	}
done:
	free(stats);
	free(lists);
	return rc;
}
