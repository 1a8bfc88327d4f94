/* chunk-check - verifies chunk files: silent and exit 0 when every file is
 * good, one line per bad file and exit 1 otherwise (like samtools
 * quickcheck). */
#include "voxdag.h"

#include <getopt.h>
#include <stdlib.h>
#include <string.h>

static const char usage[] =
	"usage: chunk-check [-v] FILE...\n"
	"\n"
	"Verifies voxdag chunk files: magic, version, checksums, structure and,\n"
	"for SVO chunks, the bricks themselves. Prints nothing and exits 0 when\n"
	"every file is good; prints one line per bad file and exits 1 otherwise.\n"
	"\n"
	"  -v, --verbose   also describe each good file on stdout\n"
	"  -h, --help      this text\n"
	"\n"
	"Exit status: 0 all good, 1 a file is bad, 2 usage.\n";

static void describe(const char *path, const struct vd_chunk *c)
{
	const struct vd_chunk_header *h = vd_chunk_header(c);
	printf("%s: %s chunk, format %u.%u, levels %u, chunk level %u, cell %llx, "
	       "voxel size %g\n", path, vd_chunk_kind_name(h->kind), h->major,
	       h->minor, h->levels, h->chunk_level,
	       (unsigned long long)h->cell_morton, h->transform.voxel_size);
	printf("  nodes per level from %u:", h->chunk_level);
	for (uint32_t i = 0; i < h->level_count; i++)
		printf(" %llu", (unsigned long long)h->level_nodes[i]);
	printf("\n  sections:");
	for (uint32_t i = 0; i < vd_chunk_section_count(c); i++) {
		uint32_t t = vd_chunk_section_tag(c, i);
		printf(" %c%c%c%c", t & 0xff, t >> 8 & 0xff, t >> 16 & 0xff, t >> 24);
	}
	printf("\n  provenance: %s\n", vd_chunk_provenance(c));
}

static int check(const char *path, int verbose)
{
	struct vd_chunk *c;
	int err = vd_chunk_open(&c, path, VD_KIND_ANY);
	if (!err && vd_chunk_header(c)->kind == VD_KIND_SVO) {
		struct vd_svo svo;
		err = vd_svo_from_chunk(&svo, c);
		vd_svo_release(&svo);
	}
	if (err) {
		const char *d = vd_error_detail();
		fprintf(stderr, "chunk-check: '%s': %s%s%s\n", path,
			vd_strerror(err), *d ? ": " : "", d);
		vd_chunk_free(c);
		return 1;
	}
	if (verbose)
		describe(path, c);
	vd_chunk_free(c);
	return 0;
}

int main(int argc, char **argv)
{
	static const struct option longopts[] = {
		{"verbose", no_argument, NULL, 'v'},
		{"help", no_argument, NULL, 'h'},
		{NULL, 0, NULL, 0},
	};
	int c, verbose = 0;
	while ((c = getopt_long(argc, argv, "vh", longopts, NULL)) != -1) {
		if (c == 'v') {
			verbose = 1;
		} else if (c == 'h') {
			fputs(usage, stdout);
			return 0;
		} else {
			fprintf(stderr, "Try 'chunk-check --help'.\n");
			return 2;
		}
	}
	if (optind == argc) {
		fprintf(stderr, "chunk-check: no FILE given\nTry 'chunk-check --help'.\n");
		return 2;
	}
	int bad = 0;
	for (int i = optind; i < argc; i++)
		bad |= check(argv[i], verbose);
	return bad;
}
