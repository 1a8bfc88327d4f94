/* util.c - sizes, clocks, memory accounting, hashing, world transform. */
#include "voxdag.h"
#include "util_internal.h"

#include <ctype.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

#define XXH_INLINE_ALL
#include <xxhash.h>

int vd_parse_size(const char *s, uint64_t *bytes)
{
	char *end;
	if (!s || !*s || !(isdigit((unsigned char)*s) || *s == '.'))
		return vd_fail(VD_ERR_ARG, "'%s' is not a size", s ? s : "");
	double v = strtod(s, &end);
	double mult = 1;
	if (*end) {
		static const char *const units[] = {"K", "M", "G", "T"};
		int i;
		for (i = 0; i < 4; i++) {
			size_t n = strlen(units[i]);
			if (strncasecmp(end, units[i], n) == 0) {
				const char *rest = end + n;
				if (!*rest || !strcasecmp(rest, "B") ||
				    !strcasecmp(rest, "iB"))
					break;
			}
		}
		if (i == 4 && strcasecmp(end, "B") != 0)
			return vd_fail(VD_ERR_ARG, "'%s' is not a size (try 512M or 2GiB)", s);
		if (i < 4)
			mult = ldexp(1.0, 10 * (i + 1));
	}
	v *= mult;
	if (!isfinite(v) || v < 0 || v > 1.8e19)
		return vd_fail(VD_ERR_ARG, "'%s' is not a size", s);
	*bytes = (uint64_t)v;
	return VD_OK;
}

uint64_t vd_peak_rss_bytes(void)
{
	struct rusage ru;
	if (getrusage(RUSAGE_SELF, &ru) != 0)
		return 0;
	return (uint64_t)ru.ru_maxrss * 1024; /* Linux reports KiB */
}

double vd_cpu_seconds(void)
{
	struct timespec t;
	if (clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t) != 0)
		return 0;
	return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

uint64_t vd_current_rss_bytes(void)
{
	FILE *f = fopen("/proc/self/statm", "r");
	unsigned long long size = 0, resident = 0;
	int n = f ? fscanf(f, "%llu %llu", &size, &resident) : 0;
	if (f)
		fclose(f);
	if (n != 2)
		return vd_peak_rss_bytes(); /* no procfs: the safe side */
	return (uint64_t)resident * (uint64_t)sysconf(_SC_PAGESIZE);
}

double vd_seconds(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

uint64_t vd_hash64(const void *data, size_t n, uint64_t seed)
{
	return XXH3_64bits_withSeed(data, n, seed);
}

int vd_transform_init(struct vd_transform *t, const float bbox_min[3],
		      const float bbox_max[3], int levels)
{
	if (levels < 1 || levels > VD_MAX_LEVELS)
		return vd_fail(VD_ERR_RANGE, "levels %d outside 1..%d", levels,
			       VD_MAX_LEVELS);
	float side = 0;
	for (int a = 0; a < 3; a++) {
		if (!isfinite(bbox_min[a]) || !isfinite(bbox_max[a]) ||
		    bbox_max[a] < bbox_min[a])
			return vd_fail(VD_ERR_RANGE, "bounding box is not finite");
		t->bbox_min[a] = bbox_min[a];
		t->bbox_max[a] = bbox_max[a];
		/* float32 like SymVox, so our files compare with theirs */
		float e = bbox_max[a] - bbox_min[a];
		if (e > side)
			side = e;
	}
	if (!(side > 0))
		return vd_fail(VD_ERR_EMPTY, "the mesh has zero extent (all "
			       "vertices at one point)");
	t->root_side = side;
	for (int a = 0; a < 3; a++) {
		float c = 0.5f * bbox_min[a] + 0.5f * bbox_max[a];
		t->origin[a] = (double)c - 0.5 * (double)side;
	}
	t->voxel_size = (double)side / (double)(1u << levels);
	return VD_OK;
}

int vd_transform_equal(const struct vd_transform *a,
		       const struct vd_transform *b)
{
	/* Field by field: the struct has padding whose bytes are unset. */
	return memcmp(a->bbox_min, b->bbox_min, sizeof a->bbox_min) == 0 &&
	       memcmp(a->bbox_max, b->bbox_max, sizeof a->bbox_max) == 0 &&
	       memcmp(&a->root_side, &b->root_side, sizeof a->root_side) == 0 &&
	       memcmp(a->origin, b->origin, sizeof a->origin) == 0 &&
	       memcmp(&a->voxel_size, &b->voxel_size,
		      sizeof a->voxel_size) == 0;
}

void vd_chunk_file_name(char *buf, size_t cap, int chunk_level,
			uint64_t cell_morton, const char *ext)
{
	/* Fixed width so `ls` lists cells in Morton order. */
	int digits = (3 * chunk_level + 3) / 4;
	if (digits < 1)
		digits = 1;
	snprintf(buf, cap, "chunk-L%d-%0*llx.%s", chunk_level, digits,
		 (unsigned long long)cell_morton, ext);
}

int vd_stage_version(const char *tool)
{
#define VD_STAGE_VERSION_CASE(name, v) if (!strcmp(tool, name)) return v;
	VD_STAGE_VERSIONS(VD_STAGE_VERSION_CASE)
#undef VD_STAGE_VERSION_CASE
	return 0;
}

void *vd_grow(void *a, size_t n, size_t *cap, size_t elem, size_t first)
{
	if (n < *cap)
		return a;
	size_t c = *cap ? 2 * *cap : first;
	if (c <= n)
		c = n + 1;
	if (c > SIZE_MAX / elem)
		return NULL;
	void *p = realloc(a, c * elem);
	if (p)
		*cap = c;
	return p;
}

char *vd_provenance_new(const char *tool, int argc, char **argv)
{
	size_t n = strlen(tool) + 64;
	for (int i = 1; i < argc; i++)
		n += 4 * strlen(argv[i]) + 3;
	char *s = malloc(n), *p = s;
	if (!s)
		return NULL;
	p += sprintf(p, "tool=%s version=%s stage_version=%d args=", tool,
		     VD_VERSION_STRING, vd_stage_version(tool));
	int first = 1;
	for (int i = 1; i < argc; i++) {
		/* --threads changes no byte a stage writes, and the runner
		 * gives a job running alone every core: left out, or a rerun
		 * of one lost cell would change its file and so rebuild every
		 * job after it (their keys cover their inputs' bytes) */
		if (!strncmp(argv[i], "--threads=", 10) ||
		    (!strncmp(argv[i], "-j", 2) && argv[i][2]))
			continue;
		if (!strcmp(argv[i], "--threads") || !strcmp(argv[i], "-j")) {
			i++;
			continue;
		}
		/* shell-quoted, so the line can be pasted back */
		if (!first)
			*p++ = ' ';
		first = 0;
		*p++ = '\'';
		for (const char *c = argv[i]; *c; c++) {
			if (*c == '\'') {
				memcpy(p, "'\\''", 4);
				p += 4;
			} else {
				*p++ = *c;
			}
		}
		*p++ = '\'';
	}
	*p = 0;
	return s;
}
