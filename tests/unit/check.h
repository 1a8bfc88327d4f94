/* check.h - the unit tests' harness: always-on assertions that count, one
 * PASS/FAIL line per test function and a closing "END n" line, judged by
 * tests/run-unit.sh. */
#ifndef VD_CHECK_H
#define VD_CHECK_H

#undef NDEBUG
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>
#include <string.h>

static int check_failed_;   /* failures inside the running test */
static int tests_failed_, tests_run_;

#define CHECK(cond)                                                          \
	do {                                                                 \
		if (!(cond)) {                                               \
			fprintf(stderr, "%s:%d: CHECK failed: %s\n",         \
				__FILE__, __LINE__, #cond);                  \
			check_failed_++;                                     \
		}                                                            \
	} while (0)

#define CHECK_EQ(a, b)                                                       \
	do {                                                                 \
		long long a_ = (long long)(a), b_ = (long long)(b);          \
		if (a_ != b_) {                                              \
			fprintf(stderr, "%s:%d: CHECK failed: %s == %s "     \
				"(%lld != %lld)\n", __FILE__, __LINE__, #a,  \
				#b, a_, b_);                                 \
			check_failed_++;                                     \
		}                                                            \
	} while (0)

/* Runs one test function and prints its verdict. */
#define RUN(fn)                                                              \
	do {                                                                 \
		check_failed_ = 0;                                           \
		fn();                                                        \
		tests_run_++;                                                \
		if (check_failed_) tests_failed_++;                          \
		printf("%s %s\n", check_failed_ ? "FAIL" : "PASS", #fn);     \
		fflush(stdout);                                              \
	} while (0)

/* Ends main(): prints "END n" with the number of test functions run, so
 * tests/run-unit.sh can tell a program that finished from one that ended
 * early (a crash, a sanitizer report, an exit() in the middle). Returns
 * main's exit status: 1 when a test failed. */
#define CHECK_DONE()                                                         \
	(printf("END %d\n", tests_run_), fflush(stdout),                    \
	 tests_failed_ ? 1 : 0)

/* Directory with the repository's test data and the shared scenes (the
 * latter may be absent: tests then skip). */
static inline const char *test_shared_data(void)
{
	const char *d = getenv("VOXDAG_SHARED_DATA");
	return d ? d : "../shared/data";
}

/* A fresh scratch directory under out/ for this test program. */
static inline const char *test_tmpdir(const char *name)
{
	static char buf[512];
	snprintf(buf, sizeof buf, "out/tmp/%s", name);
	char cmd[1200];
	snprintf(cmd, sizeof cmd, "rm -rf '%s' && mkdir -p '%s'", buf, buf);
	if (system(cmd) != 0) {
		fprintf(stderr, "cannot create %s\n", buf);
		exit(2);
	}
	return buf;
}

/* "DIR/NAME" in one of four rotating buffers, so that a call can take
 * two or three paths at once. */
static inline const char *test_path(const char *dir, const char *name)
{
	static char p[4][700];
	static int k;
	k = (k + 1) % 4;
	snprintf(p[k], sizeof p[k], "%s/%s", dir, name);
	return p[k];
}

/* The whole file at `path`, NUL-terminated (free() it), its size in *n
 * when n is not NULL; NULL when it cannot be read. */
static inline char *test_slurp(const char *path, size_t *n)
{
	FILE *f = fopen(path, "rb");
	if (!f)
		return NULL;
	size_t cap = 1 << 16, len = 0, got;
	char *buf = malloc(cap + 1);
	while (buf && (got = fread(buf + len, 1, cap - len, f)) > 0) {
		len += got;
		if (len == cap) {
			char *b = realloc(buf, 2 * cap + 1);
			if (!b) {
				free(buf);
				buf = NULL;
			}
			buf = b;
			cap *= 2;
		}
	}
	fclose(f);
	if (buf) {
		buf[len] = 0;
		if (n)
			*n = len;
	}
	return buf;
}

/* "<path>.tmp.<pid>": the temporary every writer of the library uses
 * (vd_atomic_open) before it publishes `path`. */
static inline const char *test_tmp_of(const char *path)
{
	static char t[800];
	snprintf(t, sizeof t, "%s.tmp.%ld", path, (long)getpid());
	return t;
}

/* 1 when something (a file, a directory, a dangling link) is at `path`. */
static inline int test_exists(const char *path)
{
	struct stat st;
	return lstat(path, &st) == 0;
}

#endif
