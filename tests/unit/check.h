/* check.h - the unit tests' harness: always-on assertions that count, one
 * PASS/FAIL line per test function and a closing "END n" line, judged by
 * tests/run-unit.sh. */
#ifndef VD_CHECK_H
#define VD_CHECK_H

#undef NDEBUG
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
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

#endif
