/* zstd_levels - what the chunk sections would cost at each zstd level:
 * reads chunk files, decompresses every section and compresses it again at
 * levels -5..19 (zstd's fast negative levels too), printing per section
 * kind the stored bytes and the compression and decompression speed. The
 * chunk writer's default level is chosen from this table
 * (schemas/chunk-format.md).
 *
 * usage: zstd_levels CHUNK...   (built and run by tests/bench.sh) */
#include "voxdag.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zstd.h>

static const int levels[] = {-5, -1, 1, 2, 3, 5, 9, 19};
#define NL (int)(sizeof levels / sizeof levels[0])
#define NTAG 5
static const char *tags[NTAG] = {"BRKS", "DAGM", "DAGC", "DAGR", "COLS"};

struct acc {
	double raw, stored[NL], csec[NL], dsec[NL];
};

int main(int argc, char **argv)
{
	if (argc < 2) {
		fprintf(stderr, "usage: zstd_levels CHUNK...\n");
		return 2;
	}
	struct acc acc[NTAG] = {{0}};
	for (int f = 1; f < argc; f++) {
		struct vd_chunk *c;
		if (vd_chunk_open(&c, argv[f], VD_KIND_ANY)) {
			fprintf(stderr, "zstd_levels: %s: %s\n", argv[f],
				vd_error_detail());
			return 1;
		}
		for (int t = 0; t < NTAG; t++) {
			uint32_t tag = VD_TAG(tags[t][0], tags[t][1], tags[t][2],
					      tags[t][3]);
			if (!vd_chunk_has_section(c, tag))
				continue;
			void *raw;
			size_t n;
			if (vd_chunk_read_section(c, tag, &raw, &n))
				return 1;
			size_t cap = ZSTD_compressBound(n);
			void *z = malloc(cap), *back = malloc(n + 1);
			acc[t].raw += (double)n;
			for (int l = 0; l < NL; l++) {
				double t0 = vd_seconds();
				size_t zn = ZSTD_compress(z, cap, raw, n, levels[l]);
				double t1 = vd_seconds();
				size_t bn = ZSTD_decompress(back, n + 1, z, zn);
				double t2 = vd_seconds();
				if (ZSTD_isError(zn) || bn != n ||
				    memcmp(back, raw, n)) {
					fprintf(stderr, "zstd_levels: round trip "
						"failed\n");
					return 1;
				}
				acc[t].stored[l] += (double)zn;
				acc[t].csec[l] += t1 - t0;
				acc[t].dsec[l] += t2 - t1;
			}
			free(z);
			free(back);
			free(raw);
		}
		vd_chunk_free(c);
	}
	printf("%-5s %6s %12s %12s %8s %12s %12s\n", "tag", "level", "raw MB",
	       "stored MB", "ratio", "comp MB/s", "decomp MB/s");
	for (int t = 0; t < NTAG; t++) {
		if (acc[t].raw == 0)
			continue;
		for (int l = 0; l < NL; l++)
			printf("%-5s %6d %12.2f %12.2f %8.2f %12.0f %12.0f\n",
			       tags[t], levels[l], acc[t].raw / 1e6,
			       acc[t].stored[l] / 1e6,
			       acc[t].raw / acc[t].stored[l],
			       acc[t].raw / 1e6 / acc[t].csec[l],
			       acc[t].raw / 1e6 / acc[t].dsec[l]);
	}
	return 0;
}
