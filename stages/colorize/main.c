/* colorize - a scene's voxel colours (voxelize's colour chunks) compressed:
 * the auto blocks, variable-bitrate blocks, the palette baseline, raw
 * zstd. */
#include "voxdag.h"
#include "cli.h"

#include <getopt.h>
#include <stdlib.h>
#include <string.h>

#define TOOL "colorize"

static const char usage[] =
	"usage: colorize INDIR -o OUTDIR [options]\n"
	"\n"
	"Compresses the colour array of a scene: the colour chunks (.col) that\n"
	"voxelize wrote beside its SVO chunks in INDIR, read cell by cell in\n"
	"cell order, each checked against its SVO chunk. Writes one packed\n"
	"colours file per method (schemas/colour-formats.md) into OUTDIR:\n"
	"colours.auto, colours.vbr, colours.palette, colours.raw, and\n"
	"colorize.stats.json\n"
	"(bytes raw and compressed, percent of raw, GMSE, max error, blocks,\n"
	"seconds, peak memory). OUTDIR is built beside the old one and replaces\n"
	"it whole, with a manifest, only when complete.\n"
	"\n"
	"  -o, --output DIR        output directory\n"
	"  -M, --method LIST       methods, comma-separated: auto (fixed-size\n"
	"                          blocks, each constant, a local palette,\n"
	"                          two endpoints and weights, quantised or\n"
	"                          raw, whichever is smallest), vbr (variable-\n"
	"                          bitrate blocks, Dolonius et al. 2017),\n"
	"                          palette (Dado et al. 2016), raw (zstd);\n"
	"                          default vbr\n"
	"  -e, --max-error X       vbr, auto: largest sRGB distance of a\n"
	"                          decoded colour, channels in [0,1] (default\n"
	"                          0.025; the paper uses 0.025, 0.038, 0.05,\n"
	"                          0.1); vbr: 0.0236 and above always work\n"
	"  -B, --block-size N      auto: voxels per block, a power of two\n"
	"                          from 16 to 4096 (default 256; 512 with\n"
	"                          --lossless)\n"
	"  -w, --weight-bits W     vbr: bits per voxel weight, 1..8 (default 3)\n"
	"  -k, --palette-colours K palette: global palette size, 2..16777216\n"
	"                          (default 4096)\n"
	"  -L, --lossless          palette: every distinct colour (exact);\n"
	"                          auto: every colour exact (max error 0)\n"
	"  -s, --stats FILE        also write the statistics JSON to FILE\n"
	"  -j, --threads N         worker threads (default: all cores)\n"
	"  -q, --quiet             no summary line on stderr\n"
	"  -h, --help              this text\n"
	"\n"
	"Exit status: 0 success, 1 failure (bad input, I/O), 2 usage.\n";

static int parse_methods(const char *s, int *methods)
{
	*methods = 0;
	char buf[256];
	if (strlen(s) >= sizeof buf || !*s)
		return -1;
	strcpy(buf, s);
	for (char *save, *t = strtok_r(buf, ",", &save); t;
	     t = strtok_r(NULL, ",", &save)) {
		int m = 0;
		for (int k = 1; k <= VD_CPACK_AUTO; k++)
			if (!strcmp(t, vd_cpack_method_name(k)))
				m = k;
		if (!m)
			return -1;
		*methods |= 1 << m;
	}
	return *methods ? 0 : -1;
}

int main(int argc, char **argv)
{
	static const struct option longopts[] = {
		{"output", required_argument, NULL, 'o'},
		{"method", required_argument, NULL, 'M'},
		{"max-error", required_argument, NULL, 'e'},
		{"weight-bits", required_argument, NULL, 'w'},
		{"block-size", required_argument, NULL, 'B'},
		{"palette-colours", required_argument, NULL, 'k'},
		{"lossless", no_argument, NULL, 'L'},
		{"stats", required_argument, NULL, 's'},
		{"threads", required_argument, NULL, 'j'},
		{"quiet", no_argument, NULL, 'q'},
		{"help", no_argument, NULL, 'h'},
		{NULL, 0, NULL, 0},
	};
	struct vd_colorize_job job = {
		.methods = 1 << VD_CPACK_VBR,
		.vbr = {.max_error = 0.025, .weight_bits = 3},
		.palette_colours = 4096,
	};
	int c, k;
	char *end;
	while ((c = getopt_long(argc, argv, "o:M:e:w:B:k:Ls:j:qh", longopts,
				NULL)) != -1) {
		switch (c) {
		case 'o':
			job.outdir = optarg;
			break;
		case 'M':
			if (parse_methods(optarg, &job.methods))
				return vd_cli_usage(TOOL, "--method '%s' is not a list "
						    "of auto, vbr, palette, raw", optarg);
			break;
		case 'e':
			job.vbr.max_error = strtod(optarg, &end);
			if (!*optarg || *end || !(job.vbr.max_error > 0) ||
			    !(job.vbr.max_error <= 2))
				return vd_cli_usage(TOOL, "--max-error '%s' is not a "
						    "number in (0, 2]", optarg);
			break;
		case 'w':
			if (vd_cli_int(optarg, 1, 8, &job.vbr.weight_bits))
				return vd_cli_usage(TOOL, "--weight-bits '%s' is not "
						    "a number from 1 to 8", optarg);
			break;
		case 'B':
			if (vd_cli_int(optarg, 16, 4096, &k) || (k & (k - 1)))
				return vd_cli_usage(TOOL, "--block-size '%s' is not "
						    "a power of two from 16 to 4096",
						    optarg);
			for (job.autop.block_log = 0; (1 << job.autop.block_log) < k;)
				job.autop.block_log++;
			break;
		case 'k':
			if (vd_cli_int(optarg, 2, 1 << 24, &k))
				return vd_cli_usage(TOOL, "--palette-colours '%s' is "
						    "not a number from 2 to "
						    "16777216", optarg);
			job.palette_colours = (uint32_t)k;
			break;
		case 'L':
			job.lossless = 1;
			break;
		case 's':
			job.stats_path = optarg;
			break;
		case 'j':
			if (vd_cli_int(optarg, 1, 1024, &job.threads))
				return vd_cli_usage(TOOL, "--threads '%s' is not a "
						    "number from 1 to 1024", optarg);
			break;
		case 'q':
			job.quiet = 1;
			break;
		case 'h':
			fputs(usage, stdout);
			return 0;
		default:
			fprintf(stderr, "Try 'colorize --help'.\n");
			return 2;
		}
	}
	if (argc - optind != 1)
		return vd_cli_usage(TOOL, "%s", argc - optind < 1
				    ? "needs an input directory (voxelize's output)"
				    : "more than one input directory");
	if (!job.outdir)
		return vd_cli_usage(TOOL, "%s", "no output directory (-o DIR) given");
	job.indir = argv[optind];
	job.autop.max_error = job.lossless ? 0 : job.vbr.max_error;
	/* lossless auto: coded segments (format 1.2), the fewest bytes, in
	 * blocks of 512 unless -B says otherwise: 1-9% fewer bytes than 256
	 * on the six bench scenes at 2^12 (Truman at 2^14: 95.6% of zstd
	 * -19 against 101.1%), for lookups 1.5x slower (a coded lookup
	 * decodes its block from the start) */
	job.autop.coded = job.lossless;
	if (job.lossless && !job.autop.block_log)
		job.autop.block_log = 9;
	char *prov = vd_provenance_new(TOOL, argc, argv);
	job.provenance = prov;
	int err = vd_colorize_run(&job);
	free(prov);
	if (err)
		return vd_cli_fail(TOOL, err, "cannot colorize", job.indir);
	return 0;
}
