/* colour_lookup - two helpers of tests/bench/colour_codec.sh:
 *   colour_lookup dump DIR OUT     the colour array of voxelize's colour
 *                                  chunks in DIR, raw RGB8 (for zstd -19)
 *   colour_lookup time FILE [N [B]]
 *                                  N (default 2*10^7) lookups of random
 *                                  voxels in a packed colours file, one
 *                                  thread, one at a time (vd_cpack_colour)
 *                                  or, with B > 0, in batches of B
 *                                  (vd_cpack_colour_many); prints
 *                                  "lookups_per_second X" on CPU time and
 *                                  a checksum of the colours (so the loop
 *                                  is not optimised away, and two runs can
 *                                  be compared: the same N gives the same
 *                                  checksum whatever B).
 * The indices are drawn before the clock starts, so the figure is the
 * lookup alone: a segment search, one directory entry, one block. */
#include "voxdag.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static double cpu_now(void)
{
	struct timespec t;
	clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
	return (double)t.tv_sec + t.tv_nsec * 1e-9;
}

static int dump(const char *dir, const char *out)
{
	uint8_t *rgb;
	uint64_t n;
	int err = vd_colour_chunks_load(dir, &rgb, &n, NULL);
	if (err) {
		fprintf(stderr, "colour_lookup: %s: %s\n", dir, vd_error_detail());
		return 1;
	}
	FILE *f = fopen(out, "wb");
	int bad = !f || fwrite(rgb, 3, n, f) != n;
	if (f && fclose(f))
		bad = 1;
	free(rgb);
	if (bad)
		fprintf(stderr, "colour_lookup: cannot write '%s'\n", out);
	return bad;
}

static int time_lookups(const char *path, uint64_t n, uint64_t batch)
{
	struct vd_cpack *c;
	if (vd_cpack_open(&c, path)) {
		fprintf(stderr, "colour_lookup: %s: %s\n", path, vd_error_detail());
		return 1;
	}
	uint64_t voxels = vd_cpack_voxels(c);
	uint64_t *idx = malloc(n * sizeof *idx), s = 88172645463325252ull;
	if (!idx || !voxels)
		return 1;
	for (uint64_t i = 0; i < n; i++) {
		s ^= s << 13;
		s ^= s >> 7;
		s ^= s << 17;
		idx[i] = s % voxels;
	}
	uint64_t sum = 0;
	uint8_t *out = batch ? malloc(3 * (batch < n ? batch : n) + 1) : NULL;
	if (batch && !out)
		return 1;
	double t0 = cpu_now();
	if (!batch) {
		for (uint64_t i = 0; i < n; i++) {
			uint8_t rgb[3];
			vd_cpack_colour(c, idx[i], rgb);
			sum += (uint64_t)rgb[0] + rgb[1] * 3u + rgb[2] * 7u;
		}
	}
	for (uint64_t i = 0; batch && i < n; i += batch) {
		size_t m = n - i < batch ? (size_t)(n - i) : (size_t)batch;
		if (vd_cpack_colour_many(c, idx + i, m, out)) {
			fprintf(stderr, "colour_lookup: %s\n", vd_error_detail());
			return 1;
		}
		for (size_t q = 0; q < m; q++)
			sum += (uint64_t)out[3 * q] + out[3 * q + 1] * 3u +
			       out[3 * q + 2] * 7u;
	}
	double t = cpu_now() - t0;
	free(out);
	printf("lookups_per_second %.0f\nchecksum %llu\n", t > 0 ? n / t : 0,
	       (unsigned long long)sum);
	free(idx);
	vd_cpack_free(c);
	return 0;
}

int main(int argc, char **argv)
{
	if (argc == 4 && !strcmp(argv[1], "dump"))
		return dump(argv[2], argv[3]);
	if (argc >= 3 && argc <= 5 && !strcmp(argv[1], "time"))
		return time_lookups(argv[2], argc >= 4 ? strtoull(argv[3], NULL, 10)
						       : 20000000ull,
				    argc == 5 ? strtoull(argv[4], NULL, 10) : 0);
	fprintf(stderr, "usage: colour_lookup dump DIR OUT | time FILE [N [B]]\n");
	return 2;
}
