/* test_publish.c - durable publishing (stages/lib/io/publish.c): a commit
 * publishes exactly the bytes written and nothing is under the final name
 * before it; abort, a failed write (RLIMIT_FSIZE makes the disk "full") and
 * a non-regular file in the way each leave the old file intact and no
 * temporary; directory fsync of the right directory (and its errors);
 * vd_stage_name / vd_publish_pair; vd_dir_swap; the staging names of
 * dead processes (zombies too) and their sweep. The order of the system
 * calls (fsync, rename, directory fsync) is checked from the outside, with
 * strace, by tests/cli/publish.sh. */
#include "check.h"
#include "voxdag.h"
#include "io/publish.h"

#include <errno.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

static const char *dir;

/* 1 when `path` holds exactly n bytes `want`. */
static int holds(const char *path, const void *want, size_t n)
{
	FILE *f = fopen(path, "rb");
	if (!f)
		return 0;
	char *buf = malloc(n + 1);
	size_t got = buf ? fread(buf, 1, n + 1, f) : 0;
	fclose(f);
	int same = buf && got == n && memcmp(buf, want, n) == 0;
	free(buf);
	return same;
}

static void put(const char *path, const char *text)
{
	FILE *f = fopen(path, "wb");
	CHECK(f != NULL);
	if (f) {
		fputs(text, f);
		fclose(f);
	}
}

/* Bytes of every value (including NULs and a size over stdio's buffer)
 * reach the final name only at commit; the temporary is the documented
 * name and is gone after; the struct is empty afterwards. */
static void test_commit_exact_bytes(void)
{
	const char *p = test_path(dir, "a.bin");
	put(p, "old");
	size_t n = 300000;
	unsigned char *data = malloc(n);
	for (size_t i = 0; i < n; i++)
		data[i] = (unsigned char)(i * 131 + (i >> 9));
	struct vd_atomic a;
	CHECK_EQ(vd_atomic_open(&a, p), VD_OK);
	CHECK(a.f && !strcmp(a.path, p) && !strcmp(a.tmp, test_tmp_of(p)));
	CHECK(test_exists(test_tmp_of(p)));
	CHECK_EQ(fwrite(data, 1, n, a.f), n);
	CHECK(holds(p, "old", 3)); /* untouched until commit */
	CHECK_EQ(vd_atomic_commit(&a), VD_OK);
	CHECK(!a.f && !a.path && !a.tmp);
	CHECK(holds(p, data, n));
	CHECK(!test_exists(test_tmp_of(p)));
	vd_atomic_abort(&a); /* harmless on the emptied struct */
	CHECK(holds(p, data, n));
	/* an empty file is a file */
	CHECK_EQ(vd_atomic_open(&a, p), VD_OK);
	CHECK_EQ(vd_atomic_commit(&a), VD_OK);
	CHECK(holds(p, "", 0));
	free(data);
}

/* Abort keeps the old file (or no file) and removes the temporary. */
static void test_abort(void)
{
	const char *p = test_path(dir, "b.txt");
	put(p, "old");
	struct vd_atomic a;
	CHECK_EQ(vd_atomic_open(&a, p), VD_OK);
	fputs("new", a.f);
	vd_atomic_abort(&a);
	CHECK(holds(p, "old", 3));
	CHECK(!test_exists(test_tmp_of(p)));
	const char *q = test_path(dir, "never.txt");
	CHECK_EQ(vd_atomic_open(&a, q), VD_OK);
	fputs("new", a.f);
	vd_atomic_abort(&a);
	CHECK(!test_exists(q) && !test_exists(test_tmp_of(q)));
}

/* A write that fails (a file size limit stands in for a full disk) fails
 * the commit with "cannot write '<tmp>': cause", errno the cause; the old
 * file stays, no temporary. */
static void test_failed_write(void)
{
	const char *p = test_path(dir, "c.bin");
	put(p, "old");
	struct rlimit old, lim;
	CHECK_EQ(getrlimit(RLIMIT_FSIZE, &old), 0);
	lim = old;
	lim.rlim_cur = 4096;
	void (*was)(int) = signal(SIGXFSZ, SIG_IGN);
	struct vd_atomic a;
	CHECK_EQ(vd_atomic_open(&a, p), VD_OK);
	CHECK_EQ(setrlimit(RLIMIT_FSIZE, &lim), 0);
	static char big[1 << 16];
	memset(big, 'x', sizeof big);
	fwrite(big, 1, sizeof big, a.f); /* fails at a buffer flush, unchecked */
	vd_error_clear();
	int err = vd_atomic_commit(&a);
	int e = errno;
	setrlimit(RLIMIT_FSIZE, &old);
	signal(SIGXFSZ, was);
	CHECK_EQ(err, VD_ERR_IO);
	CHECK_EQ(e, EFBIG);
	char want[800];
	snprintf(want, sizeof want, "cannot write '%s': %s", test_tmp_of(p),
		 strerror(EFBIG));
	CHECK(!strcmp(vd_error_detail(), want));
	if (strcmp(vd_error_detail(), want))
		fprintf(stderr, "detail: %s\n", vd_error_detail());
	CHECK(holds(p, "old", 3));
	CHECK(!test_exists(test_tmp_of(p)));
	vd_error_clear();
}

/* A missing directory: VD_ERR_IO naming the temporary, errno kept, the
 * struct empty (no abort needed). */
static void test_open_missing_dir(void)
{
	const char *p = test_path(dir, "no/such/x");
	struct vd_atomic a;
	vd_error_clear();
	CHECK_EQ(vd_atomic_open(&a, p), VD_ERR_IO);
	CHECK_EQ(errno, ENOENT);
	CHECK(!a.f && !a.path && !a.tmp);
	char want[800];
	snprintf(want, sizeof want, "cannot create '%s': %s", test_tmp_of(p),
		 strerror(ENOENT));
	CHECK(!strcmp(vd_error_detail(), want));
	vd_error_clear();
}

/* A directory, a FIFO or a symbolic link under the final name is not
 * replaced: VD_ERR_IO with the refusal, errno EISDIR or EEXIST, the thing
 * in the way untouched, no temporary. */
static void test_refuse_non_regular(void)
{
	char d[600], fifo[600], link[600];
	snprintf(d, sizeof d, "%s", test_path(dir, "isdir"));
	snprintf(fifo, sizeof fifo, "%s", test_path(dir, "isfifo"));
	snprintf(link, sizeof link, "%s", test_path(dir, "islink"));
	CHECK_EQ(mkdir(d, 0777), 0);
	CHECK_EQ(mkfifo(fifo, 0666), 0);
	CHECK_EQ(symlink("target", link), 0);
	const char *paths[3] = {d, fifo, link};
	const int errs[3] = {EISDIR, EEXIST, EEXIST};
	for (int i = 0; i < 3; i++) {
		char p[600];
		snprintf(p, sizeof p, "%s", paths[i]);
		struct vd_atomic a;
		CHECK_EQ(vd_atomic_open(&a, p), VD_OK);
		fputs("new", a.f);
		vd_error_clear();
		CHECK_EQ(vd_atomic_commit(&a), VD_ERR_IO);
		CHECK_EQ(errno, errs[i]);
		char want[800];
		snprintf(want, sizeof want, "'%s' exists and is not a regular "
			 "file; refusing to replace it", p);
		CHECK(!strcmp(vd_error_detail(), want));
		CHECK(!test_exists(test_tmp_of(p)));
	}
	struct stat st;
	CHECK(lstat(d, &st) == 0 && S_ISDIR(st.st_mode));
	CHECK(lstat(fifo, &st) == 0 && S_ISFIFO(st.st_mode));
	CHECK(lstat(link, &st) == 0 && S_ISLNK(st.st_mode));
	vd_error_clear();
}

/* The directory synced is the one holding the file: a missing one is an
 * error naming it; bare names sync "."; trailing slashes are ignored. */
static void test_fsync_dir(void)
{
	CHECK_EQ(vd_fsync_dir(dir), VD_OK);
	CHECK_EQ(vd_fsync_parent(test_path(dir, "anything")), VD_OK);
	CHECK_EQ(vd_fsync_parent("bare-name"), VD_OK);
	CHECK_EQ(vd_fsync_parent("/"), VD_OK);
	char p[700];
	snprintf(p, sizeof p, "%s/", dir);
	CHECK_EQ(vd_fsync_parent(p), VD_OK); /* syncs dir's parent */
	vd_error_clear();
	const char *missing = test_path(dir, "gone");
	CHECK_EQ(vd_fsync_dir(missing), VD_ERR_IO);
	char want[800];
	snprintf(want, sizeof want, "cannot sync directory '%s': %s", missing,
		 strerror(ENOENT));
	CHECK(!strcmp(vd_error_detail(), want));
	vd_error_clear();
	CHECK_EQ(vd_fsync_parent(test_path(dir, "gone/x")), VD_ERR_IO);
	CHECK(!strcmp(vd_error_detail(), want)); /* the parent, by name */
	vd_error_clear();
	CHECK_EQ(vd_fsync_dir(test_path(dir, "a.bin")), VD_ERR_IO); /* not a dir */
	vd_error_clear();
}

/* A pair staged under "<final>.tmp.<pid>.new" is published whole; when the
 * second rename is refused, both staged files are removed. */
static void test_publish_pair(void)
{
	char out[600], st[600], out2[600], st2[600];
	snprintf(out, sizeof out, "%s", test_path(dir, "o.dag"));
	snprintf(st, sizeof st, "%s", test_path(dir, "o.dag.stats.json"));
	snprintf(out2, sizeof out2, "%s", test_path(dir, "p.dag"));
	snprintf(st2, sizeof st2, "%s", test_path(dir, "p.stats"));
	char so[700], ss[700];
	CHECK_EQ(vd_stage_name(out, so, sizeof so), VD_OK);
	CHECK_EQ(vd_stage_name(st, ss, sizeof ss), VD_OK);
	char want[700];
	snprintf(want, sizeof want, "%s.new", test_tmp_of(out));
	CHECK(!strcmp(so, want));
	char tiny[8];
	CHECK_EQ(vd_stage_name(out, tiny, sizeof tiny), VD_ERR_RANGE);
	put(so, "dag");
	put(ss, "{}");
	CHECK_EQ(vd_publish_pair(so, out, ss, st), VD_OK);
	CHECK(holds(out, "dag", 3) && holds(st, "{}", 2));
	CHECK(!test_exists(so) && !test_exists(ss));
	/* the statistics' name taken by a directory */
	CHECK_EQ(mkdir(st2, 0777), 0);
	CHECK_EQ(vd_stage_name(out2, so, sizeof so), VD_OK);
	CHECK_EQ(vd_stage_name(st2, ss, sizeof ss), VD_OK);
	put(so, "dag");
	put(ss, "{}");
	vd_error_clear();
	CHECK_EQ(vd_publish_pair(so, out2, ss, st2), VD_ERR_IO);
	CHECK(!test_exists(so) && !test_exists(ss));
	vd_error_clear();
}

/* vd_dir_swap: into an absent place, then over an old directory (the old
 * one is then under the staging name), and back with vd_dir_unswap. */
static void test_dir_swap(void)
{
	char final[600], stage[600]; /* path_of's buffers are reused */
	snprintf(final, sizeof final, "%s", test_path(dir, "d"));
	snprintf(stage, sizeof stage, "%s", test_path(dir, "d.tmp.1"));
	CHECK_EQ(mkdir(stage, 0777), 0);
	put(test_path(dir, "d.tmp.1/f"), "one");
	int had_old = -1;
	CHECK_EQ(vd_dir_swap(stage, final, &had_old), VD_OK);
	CHECK_EQ(had_old, 0);
	CHECK(holds(test_path(dir, "d/f"), "one", 3) && !test_exists(stage));
	CHECK_EQ(mkdir(stage, 0777), 0);
	put(test_path(dir, "d.tmp.1/f"), "two");
	CHECK_EQ(vd_dir_swap(stage, final, &had_old), VD_OK);
	CHECK_EQ(had_old, 1);
	CHECK(holds(test_path(dir, "d/f"), "two", 3));
	CHECK(holds(test_path(dir, "d.tmp.1/f"), "one", 3));
	CHECK_EQ(vd_dir_unswap(stage, final, had_old), VD_OK);
	CHECK(holds(test_path(dir, "d/f"), "one", 3));
	CHECK(holds(test_path(dir, "d.tmp.1/f"), "two", 3));
}

static void test_staging_pid(void)
{
	CHECK_EQ(vd_staging_pid("a.dag.tmp.123"), 123);
	CHECK_EQ(vd_staging_pid("a.dag.tmp.123.new"), 123);
	CHECK_EQ(vd_staging_pid("keys.tmp.77"), 77);
	CHECK_EQ(vd_staging_pid("r.dag.tmp.12.new.tmp.456"), 456);
	CHECK_EQ(vd_staging_pid("vox.tmp.9"), 9);
	/* not staging names: no digits, other text after them, no stem */
	CHECK_EQ(vd_staging_pid("bins.tmp"), 0);
	CHECK_EQ(vd_staging_pid("a.tmp."), 0);
	CHECK_EQ(vd_staging_pid("a.tmp.12x"), 0);
	CHECK_EQ(vd_staging_pid("a.tmp.12.old"), 0);
	CHECK_EQ(vd_staging_pid(".tmp.5"), 0);
	CHECK_EQ(vd_staging_pid("a.tmp.99999999999999"), 0);
	CHECK_EQ(vd_staging_pid("chunk-L3-00b.dag"), 0);
}

/* A child that has exited: a zombie until reap_it. */
static pid_t zombie(void)
{
	pid_t pid = fork();
	if (pid == 0)
		_exit(0);
	char path[64], buf[256];
	snprintf(path, sizeof path, "/proc/%ld/stat", (long)pid);
	for (int i = 0; i < 2000; i++) { /* until it is a zombie */
		FILE *f = fopen(path, "r");
		size_t n = f ? fread(buf, 1, sizeof buf - 1, f) : 0;
		if (f)
			fclose(f);
		buf[n] = 0;
		char *c = strrchr(buf, ')');
		if (c && c[1] == ' ' && c[2] == 'Z')
			break;
		usleep(1000);
	}
	return pid;
}

static void test_pid_alive(void)
{
	CHECK_EQ(vd_pid_alive(getpid()), 1);
	CHECK_EQ(vd_pid_alive(1), 1); /* init: alive (or not ours: EPERM) */
	pid_t z = zombie();
	CHECK_EQ(vd_pid_alive(z), 0); /* exited: it writes nothing more */
	waitpid(z, NULL, 0);
	CHECK_EQ(vd_pid_alive(z), 0);
	CHECK_EQ(vd_pid_alive(0), 0);
	CHECK_EQ(vd_pid_alive(-5), 0);
}

static void test_staging_sweep(void)
{
	pid_t z = zombie();
	long dead = (long)z, me = (long)getpid();
	char root[600], name[700];
	snprintf(root, sizeof root, "%s", test_path(dir, "sweep"));
	CHECK_EQ(mkdir(root, 0777), 0);
	CHECK_EQ(mkdir(test_path(dir, "sweep/cells"), 0777), 0);
	/* what a killed run leaves: a temporary, a staged file, a staging
	 * directory with files and a folder in it */
	snprintf(name, sizeof name, "sweep/keys.tmp.%ld", dead);
	put(test_path(dir, name), "k");
	snprintf(name, sizeof name, "sweep/cells/c.dag.tmp.%ld.new", dead);
	put(test_path(dir, name), "c");
	snprintf(name, sizeof name, "sweep/vox.tmp.%ld", dead);
	CHECK_EQ(mkdir(test_path(dir, name), 0777), 0);
	snprintf(name, sizeof name, "sweep/vox.tmp.%ld/bins.tmp", dead);
	CHECK_EQ(mkdir(test_path(dir, name), 0777), 0);
	snprintf(name, sizeof name, "sweep/vox.tmp.%ld/bins.tmp/b", dead);
	put(test_path(dir, name), "b");
	snprintf(name, sizeof name, "sweep/vox.tmp.%ld/chunk.svo", dead);
	put(test_path(dir, name), "s");
	/* what must stay: a live process's, outputs, names that only look
	 * alike */
	snprintf(name, sizeof name, "sweep/cells/d.dag.tmp.%ld.new", me);
	put(test_path(dir, name), "live");
	put(test_path(dir, "sweep/cells/c.dag"), "out");
	put(test_path(dir, "sweep/bins.tmp"), "x");
	put(test_path(dir, "sweep/a.tmp.12.old"), "x");
	CHECK_EQ(vd_staging_sweep(root, 0), 3);
	snprintf(name, sizeof name, "sweep/keys.tmp.%ld", dead);
	CHECK(!test_exists(test_path(dir, name)));
	snprintf(name, sizeof name, "sweep/cells/c.dag.tmp.%ld.new", dead);
	CHECK(!test_exists(test_path(dir, name)));
	snprintf(name, sizeof name, "sweep/vox.tmp.%ld", dead);
	CHECK(!test_exists(test_path(dir, name)));
	snprintf(name, sizeof name, "sweep/cells/d.dag.tmp.%ld.new", me);
	CHECK(holds(test_path(dir, name), "live", 4));
	CHECK(holds(test_path(dir, "sweep/cells/c.dag"), "out", 3));
	CHECK(test_exists(test_path(dir, "sweep/bins.tmp")));
	CHECK(test_exists(test_path(dir, "sweep/a.tmp.12.old")));
	/* nothing more the second time; with `all`, the live one too */
	CHECK_EQ(vd_staging_sweep(root, 0), 0);
	CHECK_EQ(vd_staging_sweep(root, 1), 1);
	CHECK(!test_exists(test_path(dir, name)));
	waitpid(z, NULL, 0);
}

int main(void)
{
	dir = test_tmpdir("test_publish");
	RUN(test_commit_exact_bytes);
	RUN(test_abort);
	RUN(test_failed_write);
	RUN(test_open_missing_dir);
	RUN(test_refuse_non_regular);
	RUN(test_fsync_dir);
	RUN(test_publish_pair);
	RUN(test_dir_swap);
	RUN(test_staging_pid);
	RUN(test_pid_alive);
	RUN(test_staging_sweep);
	return CHECK_DONE();
}
