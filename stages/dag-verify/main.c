/* dag-verify - checks that a DAG or SSVDAG chunk holds exactly the voxels
 * of SVO chunks: silent on success, like a quick checker should be. */
#include "voxdag.h"

#include <getopt.h>
#include <inttypes.h>
#include <stdlib.h>
#include <string.h>

static const char usage[] =
	"usage: dag-verify DAG SVO... [options]\n"
	"\n"
	"Expands a DAG or SSVDAG chunk, applying the reflections, and compares\n"
	"its voxels with the union of the SVO chunks, which must lie inside the\n"
	"DAG's cell and not overlap (cells without a chunk are empty). Prints\n"
	"nothing when they are equal; otherwise the number of differing voxels\n"
	"and the first one in Morton order.\n"
	"\n"
	"  -m, --mem-budget SIZE   peak memory of the process (default 2GiB)\n"
	"  -q, --quiet             no message on a difference (exit status only)\n"
	"  -h, --help              this text\n"
	"\n"
	"Exit status: 0 equal, 1 different or failure (bad input, I/O, budget),\n"
	"2 usage.\n";

static int usage_error(const char *fmt, const char *arg)
{
	fprintf(stderr, "dag-verify: ");
	fprintf(stderr, fmt, arg);
	fprintf(stderr, "\nTry 'dag-verify --help'.\n");
	return 2;
}

static int fail(int err, const char *what, const char *path)
{
	const char *d = vd_error_detail();
	fprintf(stderr, "dag-verify: %s '%s': %s%s%s\n", what, path,
		vd_strerror(err), *d ? ": " : "", d);
	return 1;
}

int main(int argc, char **argv)
{
	static const struct option longopts[] = {
		{"mem-budget", required_argument, NULL, 'm'},
		{"quiet", no_argument, NULL, 'q'},
		{"help", no_argument, NULL, 'h'},
		{NULL, 0, NULL, 0},
	};
	uint64_t budget = 2ull << 30;
	int c, quiet = 0;
	while ((c = getopt_long(argc, argv, "m:qh", longopts, NULL)) != -1) {
		switch (c) {
		case 'm':
			if (vd_parse_size(optarg, &budget) || budget == 0)
				return usage_error("--mem-budget '%s' is not a "
						   "size (e.g. 512M, 2GiB)", optarg);
			break;
		case 'q':
			quiet = 1;
			break;
		case 'h':
			fputs(usage, stdout);
			return 0;
		default:
			fprintf(stderr, "Try 'dag-verify --help'.\n");
			return 2;
		}
	}
	if (argc - optind < 2)
		return usage_error("%s", "needs a DAG chunk and at least one "
				   "SVO chunk");
	const char *dag_path = argv[optind];
	size_t n = (size_t)(argc - optind - 1);
	struct vd_dag dag;
	int err = vd_dag_load(&dag, NULL, dag_path, VD_KIND_ANY);
	if (err) return fail(err, "cannot read", dag_path);
	uint64_t used = vd_dag_memory_bytes(&dag);
	struct vd_svo *svos = calloc(n, sizeof *svos);
	const struct vd_svo **sp = calloc(n, sizeof *sp);
	int rc = 0;
	if (!svos || !sp) {
		fprintf(stderr, "dag-verify: out of memory\n");
		rc = 1;
	}
	for (size_t i = 0; i < n && !rc; i++) {
		const char *path = argv[optind + 1 + i];
		struct vd_chunk *ch;
		if ((err = vd_chunk_open(&ch, path, VD_KIND_SVO))) {
			rc = fail(err, "cannot read", path);
			break;
		}
		const struct vd_chunk_header *h = vd_chunk_header(ch);
		uint64_t bricks = h->level_count >= 3 ?
			h->level_nodes[h->level_count - 3] : 1;
		used += 16 * bricks;
		if (used > budget) {
			vd_chunk_free(ch);
			fprintf(stderr, "dag-verify: cannot load '%s': memory budget"
				" too small: the chunks need about %" PRIu64 " MiB, "
				"budget --mem-budget %" PRIu64 " MiB\n", path,
				used >> 20, budget >> 20);
			rc = 1;
			break;
		}
		err = vd_svo_from_chunk(&svos[i], ch);
		vd_chunk_free(ch);
		if (err) {
			rc = fail(err, "cannot read", path);
			break;
		}
		sp[i] = &svos[i];
	}
	if (!rc) {
		struct vd_dag_diff diff;
		err = vd_dag_compare_svo(&dag, sp, n, &diff);
		if (err) {
			rc = fail(err, "cannot compare", dag_path);
		} else if (diff.differing_voxels) {
			uint32_t x, y, z;
			vd_morton3_decode(diff.first_voxel_morton, &x, &y, &z);
			if (!quiet)
				fprintf(stderr, "dag-verify: '%s' differs from the "
					"SVO chunks in %" PRIu64 " voxels; first at "
					"voxel (%u, %u, %u), set in the %s only\n",
					dag_path, diff.differing_voxels, x, y, z,
					diff.first_in_dag ? "DAG" : "SVO chunks");
			rc = 1;
		}
	}
	for (size_t i = 0; i < n; i++) vd_svo_release(&svos[i]);
	free(svos);
	free(sp);
	vd_dag_release(&dag);
	return rc;
}
