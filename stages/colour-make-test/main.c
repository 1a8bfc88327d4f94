/* colour-make-test - test and benchmark fixtures: colour chunks for every
 * SVO chunk of a voxelize output directory, from a synthetic function of
 * voxel position, until voxelize writes real ones. */
#include "voxdag.h"
#include "cli.h"

#include <dirent.h>
#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define TOOL "colour-make-test"

static const char usage[] =
	"usage: colour-make-test DIR [options]\n"
	"\n"
	"Writes a colour chunk (.col) beside every SVO chunk of DIR (voxelize's\n"
	"output) with colours from a synthetic function of voxel position,\n"
	"then rewrites DIR's manifest. For tests and benchmarks only.\n"
	"\n"
	"  -p, --pattern NAME      mixed (default: flat, smooth, striped and\n"
	"                          noisy materials in regions of the scene),\n"
	"                          smooth, noise (uniform random), flat\n"
	"  -S, --seed N            seed of the pattern (default 1)\n"
	"  -h, --help              this text\n";

static uint32_t hash3(uint32_t a, uint32_t b, uint32_t c, uint32_t seed)
{
	uint64_t h = (uint64_t)a * 0x9E3779B97F4A7C15ull ^
		     (uint64_t)b * 0xC2B2AE3D27D4EB4Full ^
		     (uint64_t)c * 0x165667B19E3779F9ull ^ seed;
	h ^= h >> 29;
	h *= 0xBF58476D1CE4E5B9ull;
	h ^= h >> 32;
	return (uint32_t)h;
}

static uint8_t clamp8(double v)
{
	return (uint8_t)(v < 0 ? 0 : v > 255 ? 255 : v + 0.5);
}

static int pattern;
static uint32_t seed = 1;

/* The colour of voxel (x, y, z) of a 2^L grid. */
static void colour(uint32_t x, uint32_t y, uint32_t z, int L, uint8_t *o)
{
	double s = 1.0 / (double)(1u << L);
	double u = x * s, v = y * s, w = z * s;
	if (pattern == 3) { /* flat */
		o[0] = 200, o[1] = 120, o[2] = 40;
		return;
	}
	if (pattern == 2) { /* noise */
		uint32_t h = hash3(x, y, z, seed);
		o[0] = (uint8_t)h, o[1] = (uint8_t)(h >> 8), o[2] = (uint8_t)(h >> 16);
		return;
	}
	double base[3] = {128 + 100 * sin(6.3 * u + 1), 128 + 100 * sin(5.1 * v + 2),
			  128 + 100 * sin(4.3 * w + 3)};
	if (pattern == 1) { /* smooth */
		for (int k = 0; k < 3; k++)
			o[k] = clamp8(base[k]);
		return;
	}
	/* mixed: a material per region of the scene (6^3 regions) */
	uint32_t m = hash3((uint32_t)(u * 6), (uint32_t)(v * 6), (uint32_t)(w * 6),
			   seed);
	double c[3] = {40 + (m & 0xff) * 0.7, 40 + (m >> 8 & 0xff) * 0.7,
		       40 + (m >> 16 & 0xff) * 0.7};
	switch (m >> 24 & 3) {
	case 0: /* flat material */
		break;
	case 1: /* smooth shading */
		for (int k = 0; k < 3; k++)
			c[k] = c[k] * 0.6 + base[k] * 0.4;
		break;
	case 2: /* a striped texture, 1/64 of the scene per stripe pair */
		if ((int)((u + v) * 128) & 1)
			for (int k = 0; k < 3; k++)
				c[k] = c[k] * 0.5 + 30;
		break;
	default: { /* noisy (scanned or path traced): +-6 per channel */
		uint32_t h = hash3(x, y, z, seed);
		for (int k = 0; k < 3; k++)
			c[k] += (double)((h >> 8 * k & 0xff) % 13) - 6;
	}
	}
	for (int k = 0; k < 3; k++)
		o[k] = clamp8(c[k]);
}

static int ends_with(const char *s, const char *e)
{
	size_t n = strlen(s), m = strlen(e);
	return n > m && !strcmp(s + n - m, e);
}

int main(int argc, char **argv)
{
	static const struct option longopts[] = {
		{"pattern", required_argument, NULL, 'p'},
		{"seed", required_argument, NULL, 'S'},
		{"help", no_argument, NULL, 'h'},
		{NULL, 0, NULL, 0},
	};
	int c, sd;
	while ((c = getopt_long(argc, argv, "p:S:h", longopts, NULL)) != -1) {
		switch (c) {
		case 'p':
			if (!strcmp(optarg, "mixed"))
				pattern = 0;
			else if (!strcmp(optarg, "smooth"))
				pattern = 1;
			else if (!strcmp(optarg, "noise"))
				pattern = 2;
			else if (!strcmp(optarg, "flat"))
				pattern = 3;
			else
				return vd_cli_usage(TOOL, "--pattern '%s' is not "
						    "mixed, smooth, noise or flat",
						    optarg);
			break;
		case 'S':
			if (vd_cli_int(optarg, 0, 1 << 30, &sd))
				return vd_cli_usage(TOOL, "--seed '%s' is not a "
						    "number", optarg);
			seed = (uint32_t)sd;
			break;
		case 'h':
			fputs(usage, stdout);
			return 0;
		default:
			fprintf(stderr, "Try '%s --help'.\n", TOOL);
			return 2;
		}
	}
	if (argc - optind != 1)
		return vd_cli_usage(TOOL, "%s", "needs one directory");
	const char *dir = argv[optind];
	DIR *d = opendir(dir);
	if (!d) {
		fprintf(stderr, "%s: cannot open '%s': %s\n", TOOL, dir,
			strerror(errno));
		return 1;
	}
	char *prov = vd_provenance_new(TOOL, argc, argv);
	struct dirent *e;
	int rc = 0, has_manifest = 0;
	char path[4096], cpath[4096];
	while (!rc && (e = readdir(d))) {
		if (!strcmp(e->d_name, VD_MANIFEST_NAME))
			has_manifest = 1;
		if (!ends_with(e->d_name, ".svo"))
			continue;
		snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
		snprintf(cpath, sizeof cpath, "%s/%.*s.col", dir,
			 (int)(strlen(e->d_name) - 4), e->d_name);
		struct vd_svo svo;
		struct vd_chunk_header h;
		int err = vd_svo_load(&svo, &h, path);
		if (err) {
			rc = vd_cli_fail(TOOL, err, "cannot read", path);
			break;
		}
		uint64_t n = h.level_nodes[h.level_count - 1], k = 0;
		uint8_t *rgb = malloc(3 * n + 3);
		if (!rgb) {
			fprintf(stderr, "%s: out of memory\n", TOOL);
			rc = 1;
		}
		for (size_t b = 0; !rc && b < svo.count; b++) {
			uint32_t bx, by, bz;
			vd_morton3_decode(svo.keys[b], &bx, &by, &bz);
			for (int bit = 0; bit < 64; bit++) {
				if (!(svo.masks[b] >> bit & 1))
					continue;
				uint32_t lx, ly, lz;
				vd_morton3_decode((uint64_t)bit, &lx, &ly, &lz);
				colour(bx * 4 + lx, by * 4 + ly, bz * 4 + lz,
				       svo.levels, rgb + 3 * k++);
			}
		}
		if (!rc && (err = vd_colours_save(cpath, &h,
						  vd_svo_digest(svo.keys, svo.masks,
								svo.count),
						  rgb, n, prov)))
			rc = vd_cli_fail(TOOL, err, "cannot write", cpath);
		free(rgb);
		vd_svo_release(&svo);
	}
	closedir(d);
	free(prov);
	if (!rc && has_manifest) {
		int err = vd_manifest_write(dir);
		if (err)
			rc = vd_cli_fail(TOOL, err, "cannot write the manifest of", dir);
	}
	return rc;
}
