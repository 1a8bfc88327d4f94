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

int main(void)
{
	RUN(test_chunk_fstat_fails);
	RUN(test_chunk_not_regular);
	return CHECK_DONE();
}
