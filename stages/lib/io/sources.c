/* sources.c - the files a mesh pulled in besides itself, recorded by
 * voxelize in OUTDIR/sources and checked by the runner before it trusts
 * the output again (schemas/manifest.md, "Sources").
 *
 * The runner's key of a voxelize job covers the mesh file it names; an
 * OBJ's MTL files, the textures they name, a glTF's buffers are found
 * only by reading the mesh. The reader knows exactly which files it read
 * (it resolved them), so it lists them with the hash of their content,
 * and names it looked for in vain: one rule for every format, and the
 * runner never parses a mesh. */
#include "voxdag.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define SOURCES_MAGIC "voxdag-sources 1"

int vd_source_xxh3(const char *path, uint64_t *hash, uint64_t *size)
{
	/* O_NONBLOCK: opening a FIFO must not wait for a writer */
	int fd = open(path, O_RDONLY | O_CLOEXEC | O_NONBLOCK);
	if (fd < 0)
		return vd_fail(VD_ERR_IO, "cannot open '%s': %s", path,
			       strerror(errno));
	struct stat st;
	int regular = fstat(fd, &st) == 0 && S_ISREG(st.st_mode);
	close(fd);
	if (!regular)
		return vd_fail(VD_ERR_IO, "'%s' is not a regular file", path);
	return vd_file_xxh3(path, hash, size);
}

/* A path on one line: '\' and newline escaped ("\\", "\n"); every other
 * byte as it is. */
static void put_path(FILE *f, const char *p)
{
	for (; *p; p++) {
		if (*p == '\\')
			fputs("\\\\", f);
		else if (*p == '\n')
			fputs("\\n", f);
		else
			fputc(*p, f);
	}
}

/* Undoes put_path in place; 0 on a bad escape. */
static int unescape(char *p)
{
	char *w = p;
	for (; *p; p++) {
		if (*p != '\\') {
			*w++ = *p;
			continue;
		}
		p++;
		if (*p == '\\')
			*w++ = '\\';
		else if (*p == 'n')
			*w++ = '\n';
		else
			return 0;
	}
	*w = 0;
	return 1;
}

int vd_sources_write(const char *path, const struct vd_mesh_source *s,
		     size_t n)
{
	struct vd_atomic a;
	int err = vd_atomic_open(&a, path);
	if (err)
		return err;
	FILE *f = a.f;
	fputs(SOURCES_MAGIC "\n", f);
	for (size_t i = 0; i < n; i++) {
		if (s[i].found)
			fprintf(f, "%016llx %llu ",
				(unsigned long long)s[i].xxh3,
				(unsigned long long)s[i].size);
		else
			fputs("- - ", f);
		put_path(f, s[i].path);
		fputc('\n', f);
	}
	return vd_atomic_commit(&a);
}

/* "XXH3 SIZE " at the start of a found file's line: 16 lower-case hex
 * digits, a decimal size; returns where the path starts, NULL if
 * malformed. */
static char *parse_found(char *line, unsigned long long *h,
			 unsigned long long *size)
{
	if (strspn(line, "0123456789abcdef") != 16 || line[16] != ' ')
		return NULL;
	*h = strtoull(line, NULL, 16);
	char *p = line + 17;
	size_t nd = strspn(p, "0123456789");
	if (nd == 0 || nd > 19 || p[nd] != ' ')
		return NULL; /* 19 digits: any size a file can have */
	*size = strtoull(p, NULL, 10);
	return p + nd + 1;
}

int vd_sources_check(const char *path)
{
	FILE *f = fopen(path, "r");
	if (!f)
		return vd_fail(VD_ERR_IO, "cannot open '%s': %s", path,
			       strerror(errno));
	char *line = NULL;
	size_t cap = 0;
	ssize_t len;
	uint64_t ln = 0;
	int err = VD_OK;
	while (!err && (len = getline(&line, &cap, f)) >= 0) {
		ln++;
		if (len == 0 || line[len - 1] != '\n') {
			err = vd_fail(VD_ERR_FORMAT, "'%s' line %llu: no line "
				      "end (truncated)", path,
				      (unsigned long long)ln);
			break;
		}
		line[--len] = 0;
		if (ln == 1) {
			if (strcmp(line, SOURCES_MAGIC))
				err = vd_fail(VD_ERR_FORMAT, "'%s' does not start "
					      "with '" SOURCES_MAGIC "'", path);
			continue;
		}
		unsigned long long want_h = 0, want_size = 0;
		int found = strncmp(line, "- - ", 4) != 0;
		char *name = found ? parse_found(line, &want_h, &want_size)
				   : line + 4;
		if (!name || !*name || !unescape(name)) {
			err = vd_fail(VD_ERR_FORMAT, "'%s' line %llu is malformed",
				      path, (unsigned long long)ln);
			break;
		}
		uint64_t h, size;
		int readable = vd_source_xxh3(name, &h, &size) == VD_OK;
		vd_error_clear();
		if (found && !readable)
			err = vd_fail(VD_ERR_MISMATCH, "'%s' is missing or "
				      "unreadable", name);
		else if (found && (h != want_h || size != want_size))
			err = vd_fail(VD_ERR_MISMATCH, "'%s' changed", name);
		else if (!found && readable)
			err = vd_fail(VD_ERR_MISMATCH, "'%s' can be read now",
				      name);
	}
	if (!err && ferror(f))
		err = vd_fail(VD_ERR_IO, "cannot read '%s': %s", path,
			      strerror(errno));
	if (!err && ln == 0)
		err = vd_fail(VD_ERR_FORMAT, "'%s' is empty", path);
	free(line);
	fclose(f);
	return err;
}
