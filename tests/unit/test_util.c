/* test_util.c - the small files at the bottom of the library: util.c
 * (sizes, growth, provenance, chunk names, stage versions), error.c, cli.c
 * and the Morton maths of vd_common.h, against values worked out by hand
 * and bit-by-bit references. */
#include "check.h"
#include "util_internal.h"
#include "voxdag.h"
#include "cli.h"

#include <stdlib.h>
#include <string.h>

static void test_parse_size(void)
{
	uint64_t v;
	CHECK_EQ(vd_parse_size("1024", &v), VD_OK);
	CHECK_EQ(v, 1024);
	CHECK_EQ(vd_parse_size("2GiB", &v), VD_OK);
	CHECK_EQ(v, 2ull << 30);
	CHECK_EQ(vd_parse_size("512M", &v), VD_OK);
	CHECK_EQ(v, 512ull << 20);
	CHECK_EQ(vd_parse_size("1.5k", &v), VD_OK);
	CHECK_EQ(v, 1536);
	CHECK_EQ(vd_parse_size("lots", &v), VD_ERR_ARG);
	CHECK_EQ(vd_parse_size("12Q", &v), VD_ERR_ARG);
	CHECK_EQ(vd_parse_size("-5", &v), VD_ERR_ARG);
	CHECK_EQ(vd_parse_size("", &v), VD_ERR_ARG);
}


/* Bigger and smaller than fits: overflow is refused, not wrapped. */
static void test_parse_size_limits(void)
{
	uint64_t v = 7;
	CHECK_EQ(vd_parse_size("16EiB", &v), VD_ERR_ARG);
	CHECK_EQ(vd_parse_size("1K", &v), VD_OK);
	CHECK_EQ(v, 1024);
	CHECK_EQ(vd_parse_size("3 G", &v), VD_ERR_ARG);
}

static void test_morton(void)
{
	CHECK_EQ(vd_morton3(1, 0, 0), 4);
	CHECK_EQ(vd_morton3(0, 1, 0), 2);
	CHECK_EQ(vd_morton3(0, 0, 1), 1);
	CHECK_EQ(vd_morton3(2, 0, 0), 32);
	uint32_t x, y, z;
	uint64_t seed = 12345;
	for (int i = 0; i < 10000; i++) {
		seed = seed * 6364136223846793005ull + 1442695040888963407ull;
		uint32_t a = (uint32_t)(seed >> 11) & 0x1fffff,
			 b = (uint32_t)(seed >> 32) & 0x1fffff,
			 c = (uint32_t)(seed >> 40) & 0x1fffff;
		vd_morton3_decode(vd_morton3(a, b, c), &x, &y, &z);
		CHECK(x == a && y == b && z == c);
		/* bit by bit reference */
		uint64_t m = 0;
		for (int bit = 0; bit < 21; bit++)
			m |= (uint64_t)((a >> bit) & 1) << (3 * bit + 2) |
			     (uint64_t)((b >> bit) & 1) << (3 * bit + 1) |
			     (uint64_t)((c >> bit) & 1) << (3 * bit);
		CHECK_EQ(vd_morton3(a, b, c), m);
	}
}


/* vd_grow: doubling from `first`, at least n + 1, the old array kept on
 * failure (asked for more than SIZE_MAX bytes). */
static void test_grow(void)
{
	size_t cap = 0;
	int *a = vd_grow(NULL, 0, &cap, sizeof *a, 4);
	CHECK(a != NULL);
	CHECK_EQ(cap, 4);
	CHECK(vd_grow(a, 3, &cap, sizeof *a, 4) == a); /* fits: unchanged */
	a = vd_grow(a, 4, &cap, sizeof *a, 4);
	CHECK_EQ(cap, 8);
	a = vd_grow(a, 100, &cap, sizeof *a, 4);
	CHECK_EQ(cap, 101);
	a[100] = 1;
	size_t big = cap;
	CHECK(vd_grow(a, SIZE_MAX / 2, &big, sizeof *a, 4) == NULL);
	CHECK_EQ(big, cap);
	free(a);
}

/* The provenance line: tool, version, stage version, the arguments
 * shell-quoted, -j/--threads and their values left out. */
static void test_provenance(void)
{
	char *argv[] = {"svo-to-dag", "in dir", "-j", "4", "--threads=2",
			"-j3", "it's", "--threads", "8", "-o", "x"};
	char *s = vd_provenance_new("svo-to-dag", 11, argv);
	char want[256];
	snprintf(want, sizeof want, "tool=svo-to-dag version=%s "
		 "stage_version=%d args='in dir' 'it'\\''s' '-o' 'x'",
		 VD_VERSION_STRING, vd_stage_version("svo-to-dag"));
	CHECK(s && !strcmp(s, want));
	if (s && strcmp(s, want))
		fprintf(stderr, "  got:  %s\n  want: %s\n", s, want);
	free(s);
}

static void test_stage_version(void)
{
	CHECK(vd_stage_version("voxelize") >= 1);
	CHECK(vd_stage_version("encode") >= 1);
	CHECK_EQ(vd_stage_version("no-such-tool"), 0);
}

/* Fixed-width hex, (3 L0 + 3) / 4 digits, so that `ls` sorts by Morton. */
static void test_chunk_file_name(void)
{
	char b[64];
	vd_chunk_file_name(b, sizeof b, 0, 0, "svo");
	CHECK(!strcmp(b, "chunk-L0-0.svo"));
	vd_chunk_file_name(b, sizeof b, 4, 0x5f, "dag");
	CHECK(!strcmp(b, "chunk-L4-05f.dag"));
	vd_chunk_file_name(b, sizeof b, 7, 0x1fffff, "col");
	CHECK(!strcmp(b, "chunk-L7-1fffff.col"));
}

/* error.c: every code has a phrase; the detail is per call and cleared. */
static void test_errors(void)
{
	for (int e = 0; e < VD_ERR_COUNT_; e++)
		CHECK(vd_strerror(e) && *vd_strerror(e));
	CHECK(vd_strerror(VD_ERR_COUNT_) != NULL);
	CHECK(vd_strerror(-1) != NULL);
	CHECK_EQ(vd_fail(VD_ERR_RANGE, "index %u of %d", 9u, 4), VD_ERR_RANGE);
	CHECK(!strcmp(vd_error_detail(), "index 9 of 4"));
	vd_error_clear();
	CHECK(!strcmp(vd_error_detail(), ""));
}

/* cli.c: whole numbers in [lo, hi] only. */
static void test_cli_int(void)
{
	int v = 0;
	CHECK_EQ(vd_cli_int("12", 0, 21, &v), 0);
	CHECK_EQ(v, 12);
	CHECK_EQ(vd_cli_int("-3", -5, 5, &v), 0);
	CHECK_EQ(v, -3);
	CHECK_EQ(vd_cli_int("22", 0, 21, &v), -1);
	CHECK_EQ(vd_cli_int("1x", 0, 21, &v), -1);
	CHECK_EQ(vd_cli_int("", 0, 21, &v), -1);
	CHECK_EQ(v, -3);
}

int main(void)
{
	RUN(test_parse_size);
	RUN(test_parse_size_limits);
	RUN(test_morton);
	RUN(test_grow);
	RUN(test_provenance);
	RUN(test_stage_version);
	RUN(test_chunk_file_name);
	RUN(test_errors);
	RUN(test_cli_int);
	return CHECK_DONE();
}
