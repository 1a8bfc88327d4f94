/* test_errpaths.c - error paths that need a failing system call: fstat is
 * replaced in this program (the executable's definition wins over libc's)
 * so that it fails on demand. */
#include "check.h"
#include "voxdag.h"

#include <errno.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <unistd.h>

static int fstat_fails;

int fstat(int fd, struct stat *st)
{
	if (fstat_fails) {
		/* What an uninitialised struct may hold: a directory's mode. */
		memset(st, 0, sizeof *st);
		st->st_mode = S_IFDIR | 0755;
		errno = EIO;
		return -1;
	}
	return (int)syscall(SYS_fstat, fd, st);
}

/* A failing fstat is reported as such, never judged by st_mode. */
static void test_chunk_fstat_fails(void)
{
	char path[] = "/tmp/voxdag-errpaths-XXXXXX";
	int fd = mkstemp(path);
	CHECK(fd >= 0);
	CHECK_EQ(write(fd, "VOXDAG", 6), 6);
	close(fd);
	struct vd_chunk *c = NULL;
	fstat_fails = 1;
	int err = vd_chunk_open(&c, path, VD_KIND_ANY);
	fstat_fails = 0;
	CHECK_EQ(err, VD_ERR_IO);
	CHECK(strstr(vd_error_detail(), "cannot stat: ") != NULL);
	CHECK(strstr(vd_error_detail(), strerror(EIO)) != NULL);
	CHECK(strstr(vd_error_detail(), "directory") == NULL);
	unlink(path);
}

/* Not a regular file: said so, not a stale errno. */
static void test_chunk_not_regular(void)
{
	struct vd_chunk *c = NULL;
	errno = 0;
	CHECK_EQ(vd_chunk_open(&c, "/dev/null", VD_KIND_ANY), VD_ERR_IO);
	CHECK(strstr(vd_error_detail(), "not a regular file") != NULL);
	CHECK_EQ(vd_chunk_open(&c, "/tmp", VD_KIND_ANY), VD_ERR_IO);
	CHECK(strstr(vd_error_detail(), "is a directory") != NULL);
}

/* Writes `text` to a temporary file; returns its path (static buffer). */
static const char *stats_file(const char *text)
{
	static char path[64];
	snprintf(path, sizeof path, "/tmp/voxdag-stats-XXXXXX");
	int fd = mkstemp(path);
	CHECK(fd >= 0);
	size_t n = strlen(text);
	CHECK_EQ(write(fd, text, n), (long long)n);
	close(fd);
	return path;
}

/* Statistics files are parsed as JSON: the top-level numbers count, not
 * the first text that looks like the key (the old strstr parser took the
 * nested 100 and the string "seconds_load", and accepted a file without
 * its closing brace or with its tool only in a nested object). */
static void test_enc_timing_json(void)
{
	struct vd_enc_timing t = {-1, -1};
	const char *p = stats_file(
		"{\"note\": \"seconds_load\", \"child\": {\"seconds_load\": 100,"
		" \"tool\": \"symmetry-merge\"},\n \"seconds_save\": 4,"
		" \"seconds_build\": 2, \"tool\": \"svo-to-dag\","
		" \"seconds_load\": 1}");
	CHECK_EQ(vd_enc_timing_add(&t, p), VD_OK);
	CHECK(t.seconds_svo_to_dag == 7);
	CHECK(t.seconds_symmetry_merge < 0);
	unlink(p);

	static const struct {
		const char *text, *detail;
	} bad[] = {
		{"{\"tool\": \"svo-to-dag\", \"seconds_load\": 1, "
		 "\"seconds_build\": 2, \"seconds_save\": 3",
		 "not a statistics file (invalid JSON at line 1"},
		{"{\"tool\": \"encode\", \"up\": {\"tool\": \"svo-to-dag\"}, "
		 "\"seconds_load\": 1, \"seconds_build\": 2, \"seconds_save\": 3}",
		 "(\"tool\" is \"encode\")"},
		{"[\"tool\", \"svo-to-dag\"]", "not a JSON object"},
		{"{\"tool\": \"symmetry-merge\", \"seconds_load\": \"1\", "
		 "\"seconds_build\": 2, \"seconds_save\": 3}",
		 "no \"seconds_load\" number"},
		{"{\"tool\": \"symmetry-merge\", \"x\": {\"seconds_build\": 2}, "
		 "\"seconds_load\": 1, \"seconds_save\": 3}",
		 "no \"seconds_build\" number"},
		{"{\"tool\": \"symmetry-merge\", \"seconds_load\": 1, "
		 "\"seconds_build\": 2, \"seconds_save\": 3, \"seconds_save\": 3}",
		 "duplicate object key"},
		{"", "invalid JSON"},
	};
	for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
		p = stats_file(bad[i].text);
		CHECK_EQ(vd_enc_timing_add(&t, p), VD_ERR_FORMAT);
		if (!strstr(vd_error_detail(), bad[i].detail))
			fprintf(stderr, "case %zu: %s\n", i, vd_error_detail());
		CHECK(strstr(vd_error_detail(), bad[i].detail) != NULL);
		CHECK(strchr(vd_error_detail(), '\n') == NULL);
		unlink(p);
	}
	CHECK(t.seconds_svo_to_dag == 7 && t.seconds_symmetry_merge < 0);
	CHECK_EQ(vd_enc_timing_add(&t, "/nonexistent/x.stats.json"), VD_ERR_IO);
	CHECK(strstr(vd_error_detail(), strerror(ENOENT)) != NULL);
}

int main(void)
{
	RUN(test_chunk_fstat_fails);
	RUN(test_chunk_not_regular);
	RUN(test_enc_timing_json);
	return CHECK_DONE();
}
