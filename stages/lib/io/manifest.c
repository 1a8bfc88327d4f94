/* manifest.c - a directory's list of files with sizes and checksums, and
 * directories published whole (schemas/manifest.md).
 *
 * A stage whose output is a directory (voxelize: one chunk per cell;
 * encode: the four encodings and the tables) builds it under a staging
 * name beside the final one, writes `manifest` last, and swaps the staging
 * directory in with one rename (RENAME_EXCHANGE), so a reader sees the old
 * complete directory or the new complete one, never a mix; a failure at any
 * step leaves the old one as it was. Readers verify files against the
 * manifest: the runner before it trusts a finished output, render and
 * dag-verify before they read an encoding (whose bytes must stay SymVox's,
 * so the checksum cannot live inside the file). */
#include "voxdag.h"
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
#include <xxhash.h>

#define MANIFEST_MAGIC "voxdag-manifest 1"

/* Files of a directory that a manifest lists: regular files, not the
 * manifest itself, not hidden (the runner keeps its `.key` there), not
 * temporaries. */
static int listed_name(const char *name)
{
	return name[0] != '.' && strcmp(name, VD_MANIFEST_NAME) != 0 &&
	       !strstr(name, ".tmp.");
}

int vd_file_xxh3(const char *path, uint64_t *hash, uint64_t *size)
{
	int fd = vd_open_read(path);
	if (fd < 0)
		return vd_fail(VD_ERR_IO, "cannot open '%s': %s", path,
			       strerror(errno));
	XXH3_state_t *s = XXH3_createState();
	if (!s) {
		close(fd);
		return vd_fail(VD_ERR_NOMEM, "checksum state");
	}
	XXH3_64bits_reset(s);
	static _Thread_local uint8_t buf[1 << 16];
	uint64_t total = 0;
	ssize_t n;
	while ((n = read(fd, buf, sizeof buf)) > 0) {
		XXH3_64bits_update(s, buf, (size_t)n);
		total += (uint64_t)n;
	}
	int err = n < 0 ? vd_fail(VD_ERR_IO, "cannot read '%s': %s", path,
				  strerror(errno))
			: VD_OK;
	*hash = XXH3_64bits_digest(s);
	*size = total;
	XXH3_freeState(s);
	close(fd);
	return err;
}

static int cmp_name(const void *a, const void *b)
{
	return strcmp(*(char *const *)a, *(char *const *)b);
}

/* Sorted names of the files a manifest of `dir` lists. */
static int list_dir(const char *dir, char ***out, size_t *count)
{
	DIR *d = opendir(dir);
	if (!d)
		return vd_fail(VD_ERR_IO, "cannot open '%s': %s", dir,
			       strerror(errno));
	char **names = NULL;
	size_t n = 0, cap = 0;
	int err = VD_OK;
	struct dirent *e;
	while (!err && (e = readdir(d))) {
		if (!listed_name(e->d_name))
			continue;
		char path[PATH_MAX + 512];
		struct stat st;
		snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
		if (lstat(path, &st) != 0 || !S_ISREG(st.st_mode)) {
			err = vd_fail(VD_ERR_UNSUPPORTED, "'%s' is not a regular "
				      "file", path);
			break;
		}
		if (n == cap) {
			cap = cap ? 2 * cap : 64;
			char **g = realloc(names, cap * sizeof *names);
			if (!g) {
				err = vd_fail(VD_ERR_NOMEM, "file list");
				break;
			}
			names = g;
		}
		if (!(names[n] = strdup(e->d_name))) {
			err = vd_fail(VD_ERR_NOMEM, "file list");
			break;
		}
		n++;
	}
	closedir(d);
	if (err) {
		for (size_t i = 0; i < n; i++)
			free(names[i]);
		free(names);
		return err;
	}
	qsort(names, n, sizeof *names, cmp_name);
	*out = names;
	*count = n;
	return VD_OK;
}

int vd_manifest_write(const char *dir)
{
	char **names;
	size_t n;
	int err = list_dir(dir, &names, &n);
	if (err)
		return err;
	char path[PATH_MAX];
	snprintf(path, sizeof path, "%s/%s", dir, VD_MANIFEST_NAME);
	struct vd_atomic a;
	int open_err = vd_atomic_open(&a, path);
	err = open_err;
	FILE *f = a.f;
	if (f)
		fprintf(f, MANIFEST_MAGIC "\n");
	for (size_t i = 0; i < n; i++) {
		char file[PATH_MAX + 512];
		uint64_t h, size;
		snprintf(file, sizeof file, "%s/%s", dir, names[i]);
		if (!err)
			err = vd_file_xxh3(file, &h, &size);
		if (!err)
			fprintf(f, "%016llx %llu %s\n", (unsigned long long)h,
				(unsigned long long)size, names[i]);
		free(names[i]);
	}
	free(names);
	if (!open_err) {
		if (!err)
			err = vd_atomic_commit(&a);
		else
			vd_atomic_abort(&a);
	}
	return err;
}

/* One manifest line: checksum, size, name. */
struct entry {
	uint64_t hash, size;
	char name[256];
};

/* Reads dir's manifest: its entries and the XXH3 of its bytes. */
static int manifest_read(const char *dir, struct entry **out, size_t *count,
			 uint64_t *digest)
{
	char path[PATH_MAX + 512];
	snprintf(path, sizeof path, "%s/%s", dir, VD_MANIFEST_NAME);
	FILE *f = fopen(path, "r");
	if (!f)
		return errno == ENOENT
			       ? vd_fail(VD_ERR_TRUNCATED, "'%s' has no manifest "
					 "(its writer did not finish)", dir)
			       : vd_fail(VD_ERR_IO, "cannot open '%s': %s", path,
					 strerror(errno));
	XXH3_state_t *s = XXH3_createState();
	struct entry *e = NULL;
	size_t n = 0, cap = 0;
	int err = s ? VD_OK : vd_fail(VD_ERR_NOMEM, "checksum state");
	char line[512];
	int first = 1;
	if (s)
		XXH3_64bits_reset(s);
	while (!err && fgets(line, sizeof line, f)) {
		XXH3_64bits_update(s, line, strlen(line));
		size_t len = strlen(line);
		if (len == 0 || line[len - 1] != '\n') {
			err = vd_fail(VD_ERR_CORRUPT, "'%s': line %zu is cut or "
				      "too long", path, first ? 1 : n + 2);
			break;
		}
		line[len - 1] = 0;
		if (first) {
			first = 0;
			if (strcmp(line, MANIFEST_MAGIC) != 0)
				err = vd_fail(VD_ERR_CORRUPT, "'%s' is not a "
					      "voxdag manifest (first line '%.40s')",
					      path, line);
			continue;
		}
		if (n == cap) {
			cap = cap ? 2 * cap : 64;
			struct entry *g = realloc(e, cap * sizeof *e);
			if (!g) {
				err = vd_fail(VD_ERR_NOMEM, "manifest");
				break;
			}
			e = g;
		}
		unsigned long long h, size;
		int used = 0;
		/* schemas/manifest.md: exactly 16 lower-case hex digits */
		if (strspn(line, "0123456789abcdef") != 16 || line[16] != ' ' ||
		    sscanf(line, "%16llx %llu %n", &h, &size, &used) != 2 ||
		    !used || !line[used] || strlen(line + used) >= sizeof e->name ||
		    strchr(line + used, '/') || !listed_name(line + used)) {
			err = vd_fail(VD_ERR_CORRUPT, "'%s': line %zu is not "
				      "'CHECKSUM SIZE NAME'", path, n + 2);
			break;
		}
		e[n].hash = h;
		e[n].size = size;
		strcpy(e[n].name, line + used);
		if (n > 0 && strcmp(e[n - 1].name, e[n].name) >= 0) {
			err = vd_fail(VD_ERR_CORRUPT, "'%s': names not sorted "
				      "at line %zu", path, n + 2);
			break;
		}
		n++;
	}
	if (!err && ferror(f))
		err = vd_fail(VD_ERR_IO, "cannot read '%s': %s", path,
			      strerror(errno));
	if (!err && first)
		err = vd_fail(VD_ERR_TRUNCATED, "'%s' is empty", path);
	fclose(f);
	if (s) {
		*digest = XXH3_64bits_digest(s);
		XXH3_freeState(s);
	}
	if (err) {
		free(e);
		return err;
	}
	*out = e;
	*count = n;
	return VD_OK;
}

static int verify_entry(const char *dir, const struct entry *e)
{
	char path[PATH_MAX + 512];
	snprintf(path, sizeof path, "%s/%s", dir, e->name);
	struct stat st;
	if (stat(path, &st) != 0)
		return vd_fail(errno == ENOENT ? VD_ERR_TRUNCATED : VD_ERR_IO,
			       "'%s', listed in the manifest, %s", path,
			       errno == ENOENT ? "is missing" : strerror(errno));
	if (!S_ISREG(st.st_mode))
		return vd_fail(VD_ERR_UNSUPPORTED, "'%s' is not a regular file",
			       path);
	if ((uint64_t)st.st_size != e->size)
		return vd_fail((uint64_t)st.st_size < e->size ? VD_ERR_TRUNCATED
							      : VD_ERR_TRAILING,
			       "'%s' has %llu bytes, the manifest says %llu",
			       path, (unsigned long long)st.st_size,
			       (unsigned long long)e->size);
	uint64_t h, size;
	int err = vd_file_xxh3(path, &h, &size);
	if (err)
		return err;
	if (h != e->hash || size != e->size)
		return vd_fail(VD_ERR_CHECKSUM, "'%s' does not match its "
			       "checksum in the manifest", path);
	return VD_OK;
}

int vd_manifest_verify_except(const char *dir, uint64_t *digest,
			      int (*gone)(void *ctx, const char *dir,
					  const char *name),
			      void *ctx)
{
	struct entry *e;
	size_t n;
	uint64_t d;
	int err = manifest_read(dir, &e, &n, &d);
	if (err)
		return err;
	char **names = NULL;
	size_t m = 0;
	err = list_dir(dir, &names, &m);
	/* both sorted: a walk over the two lists; a listed file that is
	 * absent is whole only when `gone` vouches for it */
	size_t i = 0, k = 0;
	while (!err && (i < n || k < m)) {
		int c = i == n ? 1 : k == m ? -1 : strcmp(e[i].name, names[k]);
		if (c == 0) {
			err = verify_entry(dir, &e[i]);
			i++, k++;
		} else if (c < 0) {
			if (gone && gone(ctx, dir, e[i].name))
				i++;
			else
				err = verify_entry(dir, &e[i]); /* says why */
		} else {
			/* a file the manifest does not list was not part of
			 * the output */
			err = vd_fail(VD_ERR_CORRUPT, "'%s/%s' is not in the "
				      "manifest", dir, names[k]);
		}
	}
	for (k = 0; k < m; k++)
		free(names[k]);
	free(names);
	free(e);
	if (!err && digest)
		*digest = d;
	return err;
}

int vd_manifest_verify(const char *dir, uint64_t *digest)
{
	return vd_manifest_verify_except(dir, digest, NULL, NULL);
}

/* The directory part of path into dir ("." or "/" when it has none) and
 * a pointer to its last component. */
static const char *split_path(const char *path, char *dir, size_t cap)
{
	const char *slash = strrchr(path, '/');
	if (!slash)
		snprintf(dir, cap, ".");
	else if (slash == path)
		snprintf(dir, cap, "/");
	else
		snprintf(dir, cap, "%.*s", (int)(slash - path), path);
	return slash ? slash + 1 : path;
}

int vd_manifest_check_file(const char *path)
{
	char dir[PATH_MAX];
	const char *name = split_path(path, dir, sizeof dir);
	struct entry *e;
	size_t n;
	uint64_t d;
	int err = manifest_read(dir, &e, &n, &d);
	if (err == VD_ERR_TRUNCATED && !strstr(vd_error_detail(), "empty"))
		err = vd_fail(VD_ERR_UNSUPPORTED, "no manifest beside '%s' to "
			      "check it against (encode writes one; for a file "
			      "from elsewhere, use --no-verify)", path);
	if (err)
		return err;
	size_t i = 0;
	while (i < n && strcmp(e[i].name, name) != 0)
		i++;
	err = i < n ? verify_entry(dir, &e[i])
		    : vd_fail(VD_ERR_CORRUPT, "'%s' is not in the manifest "
			      "beside it", path);
	free(e);
	return err;
}

/* ---------------------------------------------------- publishing whole */

/* 1 if dir may be replaced by a new output: every file in it but hidden
 * ones is listed in its manifest (a voxdag output) or accepted by `ours`
 * (outputs of versions before manifests). Anything else is the user's:
 * its name goes to `foreign`. */
static int replaceable(const char *dir, int (*ours)(const char *name),
		       char *foreign, size_t cap)
{
	struct entry *e = NULL;
	size_t n = 0;
	uint64_t digest;
	if (manifest_read(dir, &e, &n, &digest) != VD_OK)
		vd_error_clear(); /* none: only `ours` vouches for files */
	DIR *d = opendir(dir);
	if (!d) {
		free(e);
		return 1;
	}
	struct dirent *de;
	int ok = 1;
	while (ok && (de = readdir(d))) {
		const char *name = de->d_name;
		if (name[0] == '.' || !strcmp(name, VD_MANIFEST_NAME) ||
		    (ours && ours(name)))
			continue;
		size_t i = 0;
		while (i < n && strcmp(e[i].name, name) != 0)
			i++;
		if (i == n) {
			snprintf(foreign, cap, "%s", name);
			ok = 0;
		}
	}
	closedir(d);
	free(e);
	return ok;
}

/* Creates the directories of `path` that are missing, parents first
 * (mkdir -p); a path too long for the buffer is an error, never a
 * shorter directory. */
static int mkdir_parents(const char *path)
{
	char tmp[PATH_MAX];
	if ((size_t)snprintf(tmp, sizeof tmp, "%s", path) >= sizeof tmp)
		return vd_fail(VD_ERR_RANGE, "output path '%s' is too long", path);
	for (char *p = tmp + 1;; p++) {
		if (*p && *p != '/')
			continue;
		char c = *p;
		*p = 0;
		if (mkdir(tmp, 0777) != 0 && errno != EEXIST)
			return vd_fail(VD_ERR_IO, "cannot create '%s': %s", tmp,
				       strerror(errno));
		if (!c)
			return VD_OK;
		*p = c;
	}
}

int vd_dir_stage(const char *given, int (*ours)(const char *name),
		 char *staging, size_t cap)
{
	/* "out/" stages as "out.tmp.<pid>" beside it, not inside it */
	char final[PATH_MAX];
	if ((size_t)snprintf(final, sizeof final, "%s", given) >= sizeof final)
		return vd_fail(VD_ERR_RANGE, "output path '%s' is too long", given);
	for (size_t n = strlen(final); n > 1 && final[n - 1] == '/';)
		final[--n] = 0;
	struct stat st;
	if (stat(final, &st) == 0) {
		char foreign[256];
		if (!S_ISDIR(st.st_mode))
			return vd_fail(VD_ERR_IO, "'%s' exists and is not a "
				       "directory", final);
		/* one we cannot list is not known to be ours to replace */
		if (faccessat(AT_FDCWD, final, R_OK | X_OK, AT_EACCESS) != 0)
			return vd_fail(VD_ERR_IO, "cannot read '%s': %s", final,
				       strerror(errno));
		if (!replaceable(final, ours, foreign, sizeof foreign))
			return vd_fail(VD_ERR_IO, "'%s' holds '%s', which this "
				       "tool did not write; give a new or empty "
				       "output directory", final, foreign);
	}
	char parent[PATH_MAX];
	const char *base = split_path(final, parent, sizeof parent);
	/* the tools promise OUTDIR "created if missing": its parents too */
	int err = mkdir_parents(parent);
	if (err)
		return err;
	/* staging directories of runs that died (kill -9, a power cut):
	 * exactly <final>.tmp.<pid> whose process is dead (vd_pid_alive). A
	 * live run's, one we may not signal (EPERM: another user's, alive)
	 * and any other name are left alone. A leftover under our own pid is
	 * an earlier process's: ours is created below. */
	DIR *d = opendir(parent);
	if (d) {
		struct dirent *e;
		size_t bl = strlen(base);
		while ((e = readdir(d))) {
			long pid = vd_staging_pid(e->d_name);
			if (pid <= 0 || strncmp(e->d_name, base, bl) != 0 ||
			    strncmp(e->d_name + bl, ".tmp.", 5) != 0 ||
			    strchr(e->d_name + bl + 5, '.'))
				continue;
			if (pid != (long)getpid() && vd_pid_alive(pid))
				continue;
			char stale[PATH_MAX + 512];
			snprintf(stale, sizeof stale, "%s/%s", parent, e->d_name);
			vd_remove_tree(stale);
		}
		closedir(d);
	}
	if ((size_t)snprintf(staging, cap, "%s.tmp.%ld", final,
			     (long)getpid()) >= cap)
		return vd_fail(VD_ERR_RANGE, "output path '%s' is too long",
			       final);
	if (mkdir(staging, 0777) != 0)
		return vd_fail(VD_ERR_IO, "cannot create '%s': %s", staging,
			       strerror(errno));
	return VD_OK;
}

int vd_dir_swap(const char *staging, const char *final, int *had_old)
{
	struct stat st;
	/* its files' names, once for all (vd_fsync_parent skipped them) */
	int err = vd_fsync_dir(staging);
	if (err)
		return err;
	*had_old = stat(final, &st) == 0;
	if (!*had_old) {
		if (rename(staging, final) != 0)
			return vd_fail(VD_ERR_IO, "cannot rename '%s' to '%s': %s",
				       staging, final, strerror(errno));
		goto sync;
	}
	/* one step: readers see the old whole directory or the new one */
	if (renameat2(AT_FDCWD, staging, AT_FDCWD, final, RENAME_EXCHANGE) != 0)
		return vd_fail(VD_ERR_IO, "cannot swap '%s' into '%s': %s",
			       staging, final, strerror(errno));
sync:
	/* the files inside are durable already (each fsynced by
	 * vd_atomic_commit, their names above); the swap is in final's
	 * parent. If that cannot be synced, the swap is undone: callers
	 * take a failed swap for one that did not happen. */
	if (vd_fsync_parent(final) != VD_OK) {
		char detail[512];
		snprintf(detail, sizeof detail, "%s", vd_error_detail());
		vd_dir_unswap(staging, final, *had_old);
		return vd_fail(VD_ERR_IO, "%s", detail);
	}
	return VD_OK;
}

int vd_dir_unswap(const char *staging, const char *final, int had_old)
{
	int r = had_old ? renameat2(AT_FDCWD, staging, AT_FDCWD, final,
				    RENAME_EXCHANGE)
			: rename(final, staging);
	if (r != 0)
		return vd_fail(VD_ERR_IO, "cannot put '%s' back: %s", final,
			       strerror(errno));
	return vd_fsync_parent(final);
}

int vd_dir_publish(const char *staging, const char *final)
{
	int err = vd_manifest_write(staging), had_old;
	if (err || (err = vd_dir_swap(staging, final, &had_old)))
		return err;
	/* the old output, now under the staging name. The new one is in
	 * place whatever happens here: a failure to remove the old (a
	 * directory made unreadable) is not the run's failure, and the next
	 * vd_dir_stage removes what is left as a dead run's staging. */
	if (had_old && vd_remove_tree(staging) != VD_OK)
		vd_error_clear();
	return VD_OK;
}

void vd_dir_abandon(const char *staging)
{
	int saved = errno;
	char detail[512];
	snprintf(detail, sizeof detail, "%s", vd_error_detail());
	vd_remove_tree(staging);
	if (*detail)
		vd_fail(VD_OK, "%s", detail); /* keep the caller's detail */
	errno = saved;
}
