/* publish.c - durable publishing, the one mechanism every file and
 * directory voxdag writes goes through (DESIGN.md, "Chunk files"; git's
 * lock files, SQLite's and PostgreSQL's rules).
 *
 * Order matters and is the same everywhere: the data, fsync of the file,
 * rename onto the final name, fsync of the directory. Without the file's
 * fsync a power cut can leave the new name on an empty or partial file
 * (ext4 and XFS may write the rename before the data); without the
 * directory's the rename itself may be lost, so a later step that relied
 * on the file (a key in the runner's journal) would outlive it.
 *
 * Temporaries are "<final>.tmp.<pid>", staged outputs "<final>.tmp.<pid>
 * .new" and staging directories "<final>.tmp.<pid>": manifests and the
 * runner skip names holding ".tmp.", and vd_dir_stage sweeps the staging
 * directories of dead processes. */
#include "io/publish.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

int vd_sync_fd(int fd)
{
#ifdef VD_NO_FSYNC
	(void)fd;
	return 0; /* config=nofsync: make bench's price of durability */
#else
	return fsync(fd);
#endif
}

int vd_fsync_dir(const char *dir)
{
	int fd = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
	if (fd < 0) {
		if (errno == EACCES)
			return VD_OK; /* nothing we may do; not the write's fault */
		return vd_fail(VD_ERR_IO, "cannot sync directory '%s': %s", dir,
			       strerror(errno));
	}
	int rc = vd_sync_fd(fd), e = errno;
	close(fd);
	if (rc != 0 && e != EINVAL) {
		errno = e;
		return vd_fail(VD_ERR_IO, "cannot sync directory '%s': %s", dir,
			       strerror(e));
	}
	return VD_OK;
}

/* The directory holding `path` into buf ("." for a bare name; trailing
 * '/' ignored). 0, or -1 when it does not fit. */
static int parent_of(const char *path, char *buf, size_t cap)
{
	size_t n = strlen(path);
	while (n > 1 && path[n - 1] == '/')
		n--;
	while (n > 0 && path[n - 1] != '/')
		n--;
	while (n > 1 && path[n - 1] == '/')
		n--; /* "a//b" -> "a"; "/b" keeps "/" */
	const char *d = n ? path : ".";
	size_t dl = n ? n : 1;
	if (dl >= cap)
		return -1;
	memcpy(buf, d, dl);
	buf[dl] = 0;
	return 0;
}

/* 1 when `dir` is this process's staging directory (vd_dir_stage:
 * "<final>.tmp.<our pid>"). Nothing names a file inside it until it is
 * swapped in, and vd_dir_swap syncs it once before that, so the files
 * published into it need no directory sync each (one per cell was most
 * of voxelize's syncs). */
static int our_staging(const char *dir)
{
	const char *base = strrchr(dir, '/');
	base = base ? base + 1 : dir;
	return vd_staging_pid(base) == (long)getpid() &&
	       !strstr(strstr(base, ".tmp.") + 5, ".");
}

int vd_fsync_parent(const char *path)
{
	size_t cap = strlen(path) + 2;
	char *dir = malloc(cap);
	if (!dir)
		return vd_fail(VD_ERR_NOMEM, "syncing the directory of '%s'",
			       path);
	parent_of(path, dir, cap);
	int err = our_staging(dir) ? VD_OK : vd_fsync_dir(dir);
	free(dir);
	return err;
}

/* vd_replace_file without the directory's fsync (vd_publish_pair syncs
 * once for both files). */
static int replace_nosync(const char *tmp, const char *path)
{
	struct stat st;
	if (lstat(path, &st) == 0 && !S_ISREG(st.st_mode)) {
		int e = S_ISDIR(st.st_mode) ? EISDIR : EEXIST;
		vd_fail(VD_ERR_IO, "'%s' exists and is not a regular file; "
			"refusing to replace it", path);
		errno = e;
		return VD_ERR_IO;
	}
	if (rename(tmp, path) != 0) {
		int e = errno;
		vd_fail(VD_ERR_IO, "cannot rename '%s' to '%s': %s", tmp, path,
			strerror(e));
		errno = e;
		return VD_ERR_IO;
	}
	return VD_OK;
}

int vd_replace_file(const char *tmp, const char *path)
{
	int err = replace_nosync(tmp, path);
	return err ? err : vd_fsync_parent(path);
}

int vd_atomic_open(struct vd_atomic *a, const char *path)
{
	memset(a, 0, sizeof *a);
	size_t n = strlen(path) + 32;
	a->path = strdup(path);
	a->tmp = malloc(n);
	if (!a->path || !a->tmp) {
		vd_atomic_abort(a);
		return vd_fail(VD_ERR_NOMEM, "writing '%s'", path);
	}
	snprintf(a->tmp, n, "%s.tmp.%ld", path, (long)getpid());
	/* "w+": the chunk writer reads its bytes back for the checksum */
	if (!(a->f = fopen(a->tmp, "w+b"))) {
		int e = errno;
		vd_fail(VD_ERR_IO, "cannot create '%s': %s", a->tmp,
			strerror(e));
		free(a->tmp);
		a->tmp = NULL; /* not ours to remove */
		vd_atomic_abort(a);
		errno = e;
		return VD_ERR_IO;
	}
	return VD_OK;
}

int vd_atomic_commit(struct vd_atomic *a)
{
	if (!a->f) {
		vd_atomic_abort(a);
		return vd_fail(VD_ERR_ARG, "vd_atomic_commit without an open "
			       "file");
	}
	int e = 0;
	if (fflush(a->f) != 0)
		e = errno;
	else if (ferror(a->f)) /* a write the caller did not check */
		e = errno ? errno : EIO;
	if (!e && vd_sync_fd(fileno(a->f)) != 0)
		e = errno;
	if (fclose(a->f) != 0 && !e)
		e = errno;
	a->f = NULL;
	int err = VD_OK;
	if (e) {
		err = vd_fail(VD_ERR_IO, "cannot write '%s': %s", a->tmp,
			      strerror(e));
	} else if ((err = replace_nosync(a->tmp, a->path))) {
		e = errno;
	} else {
		free(a->tmp);
		a->tmp = NULL; /* renamed: nothing for abort to remove */
		/* a staged name (vd_stage_name) is renamed once more, and
		 * vd_publish_pair syncs the directory after that: one sync
		 * for the pair, not three */
		const char *base = strrchr(a->path, '/');
		base = base ? base + 1 : a->path;
		if (vd_staging_pid(base) != (long)getpid() &&
		    (err = vd_fsync_parent(a->path)))
			e = errno;
	}
	vd_atomic_abort(a);
	if (err)
		errno = e;
	return err;
}

void vd_atomic_abort(struct vd_atomic *a)
{
	int saved = errno;
	if (a->f)
		fclose(a->f);
	if (a->tmp)
		unlink(a->tmp);
	free(a->tmp);
	free(a->path);
	memset(a, 0, sizeof *a);
	errno = saved;
}

int vd_stage_name(const char *final, char *buf, size_t cap)
{
	if ((size_t)snprintf(buf, cap, "%s.tmp.%ld.new", final,
			     (long)getpid()) >= cap)
		return vd_fail(VD_ERR_RANGE, "output path '%s' is too long",
			       final);
	return VD_OK;
}

int vd_publish_pair(const char *staged_out, const char *out,
		    const char *staged_stats, const char *stats)
{
	int err = replace_nosync(staged_out, out);
	if (!err)
		err = replace_nosync(staged_stats, stats);
	if (err) {
		unlink(staged_out);
		unlink(staged_stats);
		return err;
	}
	size_t cap = strlen(out) + strlen(stats) + 4;
	char *d1 = malloc(cap), *d2 = malloc(cap);
	if (!d1 || !d2) {
		free(d1);
		free(d2);
		return vd_fail(VD_ERR_NOMEM, "publishing '%s'", out);
	}
	parent_of(out, d1, cap);
	parent_of(stats, d2, cap);
	err = vd_fsync_parent(out);
	if (!err && strcmp(d1, d2) != 0)
		err = vd_fsync_parent(stats);
	free(d1);
	free(d2);
	return err;
}

int vd_open_read(const char *path)
{
	int fd = open(path, O_RDONLY | O_CLOEXEC | O_NOATIME);
	if (fd < 0 && errno == EPERM) /* not ours: O_NOATIME is refused */
		fd = open(path, O_RDONLY | O_CLOEXEC);
	return fd;
}

/* ------------------------------------------------------- staging sweeps */

int vd_pid_alive(long pid)
{
	if (pid <= 0 || pid > INT_MAX)
		return 0;
	if (kill((pid_t)pid, 0) != 0)
		return errno != ESRCH; /* EPERM: another user's, alive */
	/* a zombie has exited: it writes nothing more, whoever reaps it */
	char path[64], buf[512];
	snprintf(path, sizeof path, "/proc/%ld/stat", pid);
	int fd = open(path, O_RDONLY | O_CLOEXEC);
	if (fd < 0)
		return errno != ENOENT; /* no /proc: take it for alive */
	ssize_t n = read(fd, buf, sizeof buf - 1);
	close(fd);
	if (n <= 0)
		return 1;
	buf[n] = 0;
	/* "pid (comm) S ...": comm may hold spaces and parentheses */
	const char *c = strrchr(buf, ')');
	return !(c && c[1] == ' ' && (c[2] == 'Z' || c[2] == 'X'));
}

long vd_staging_pid(const char *name)
{
	const char *t = NULL;
	for (const char *at = strstr(name, ".tmp."); at;
	     at = strstr(at + 1, ".tmp."))
		t = at;
	if (!t || t == name)
		return 0;
	const char *d = t + 5;
	long pid = 0;
	if (*d < '0' || *d > '9')
		return 0;
	for (; *d >= '0' && *d <= '9'; d++) {
		if (pid > INT_MAX / 10)
			return 0;
		pid = pid * 10 + (*d - '0');
	}
	return !*d || !strcmp(d, ".new") ? pid : 0;
}

int vd_remove_tree(const char *dir)
{
	DIR *d = opendir(dir);
	if (!d)
		return errno == ENOENT ? VD_OK
				       : vd_fail(VD_ERR_IO, "cannot open '%s': %s",
						 dir, strerror(errno));
	struct dirent *e;
	char path[PATH_MAX + 512];
	while ((e = readdir(d))) {
		if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, ".."))
			continue;
		snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
		struct stat st;
		if (lstat(path, &st) == 0 && S_ISDIR(st.st_mode))
			vd_remove_tree(path); /* e.g. voxelize's bins.tmp */
		else
			unlink(path);
	}
	closedir(d);
	if (rmdir(dir) != 0 && errno != ENOENT)
		return vd_fail(VD_ERR_IO, "cannot remove '%s': %s", dir,
			       strerror(errno));
	return VD_OK;
}

long vd_staging_sweep(const char *dir, int all)
{
	DIR *d = opendir(dir);
	if (!d)
		return 0;
	long removed = 0;
	struct dirent *e;
	char path[PATH_MAX + 512];
	while ((e = readdir(d))) {
		const char *nm = e->d_name;
		if (!strcmp(nm, ".") || !strcmp(nm, ".."))
			continue;
		if ((size_t)snprintf(path, sizeof path, "%s/%s", dir, nm) >=
		    sizeof path)
			continue;
		long pid = vd_staging_pid(nm);
		int isdir = e->d_type == DT_DIR;
		if (e->d_type == DT_UNKNOWN) {
			struct stat st;
			isdir = lstat(path, &st) == 0 && S_ISDIR(st.st_mode);
		}
		if (pid > 0 && (all || !vd_pid_alive(pid))) {
			if (isdir ? vd_remove_tree(path) == VD_OK
				  : unlink(path) == 0)
				removed++;
			vd_error_clear();
		} else if (isdir && !pid) {
			removed += vd_staging_sweep(path, all);
		}
	}
	closedir(d);
	return removed;
}
