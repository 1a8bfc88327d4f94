/* json.c - the small JSON writer every stage's statistics go through.
 * Published on close like chunk files (vd_atomic_*: fsync, rename,
 * directory fsync), so a key never outlives the statistics it covers. */
#include "voxdag.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* Statistics nest a few levels; a writer that goes deeper (or closes more
 * than it opened) is a bug, which vd_json_close() reports instead of
 * publishing a file that is not JSON. */
#define JSON_DEPTH 64

struct vd_json {
	struct vd_atomic a;
	FILE *f; /* a.f */
	int depth;
	int bad;       /* nested deeper than JSON_DEPTH, or an end too many */
	int count[JSON_DEPTH]; /* members written so far at each depth */
};

int vd_json_open(struct vd_json **out, const char *path)
{
	struct vd_json *j = calloc(1, sizeof *j);
	if (!j)
		return vd_fail(VD_ERR_NOMEM, "json");
	int err = vd_atomic_open(&j->a, path);
	if (err) {
		free(j);
		return err;
	}
	j->f = j->a.f;
	fputc('{', j->f);
	*out = j;
	return VD_OK;
}

static void sep(struct vd_json *j, const char *key)
{
	int *count = &j->count[j->bad ? 0 : j->depth];
	fputs((*count)++ ? ",\n" : "\n", j->f);
	for (int i = 0; i <= j->depth; i++)
		fputs("  ", j->f);
	if (key)
		fprintf(j->f, "\"%s\": ", key);
}

static void open_nested(struct vd_json *j, const char *key, char c)
{
	sep(j, key);
	fputc(c, j->f);
	if (j->depth + 1 < JSON_DEPTH)
		j->count[++j->depth] = 0;
	else
		j->bad = 1;
}

/* One level up, if there is one. */
static void close_nested(struct vd_json *j)
{
	if (j->depth > 0)
		j->depth--;
	else
		j->bad = 1;
}

void vd_json_object(struct vd_json *j, const char *key) { open_nested(j, key, '{'); }
void vd_json_array(struct vd_json *j, const char *key) { open_nested(j, key, '['); }

void vd_json_end_object(struct vd_json *j)
{
	close_nested(j);
	fputs("\n", j->f);
	for (int i = 0; i <= j->depth; i++)
		fputs("  ", j->f);
	fputc('}', j->f);
}

void vd_json_end_array(struct vd_json *j)
{
	close_nested(j);
	fputc(']', j->f);
}

void vd_json_u64(struct vd_json *j, const char *key, uint64_t v)
{
	sep(j, key);
	fprintf(j->f, "%llu", (unsigned long long)v);
}

void vd_json_f64(struct vd_json *j, const char *key, double v)
{
	sep(j, key);
	if (isfinite(v))
		fprintf(j->f, "%.6g", v);
	else
		fputs("null", j->f);
}

void vd_json_str(struct vd_json *j, const char *key, const char *s)
{
	sep(j, key);
	fputc('"', j->f);
	for (; *s; s++) {
		unsigned char c = (unsigned char)*s;
		if (c == '"' || c == '\\')
			fprintf(j->f, "\\%c", c);
		else if (c < 0x20)
			fprintf(j->f, "\\u%04x", c);
		else
			fputc(c, j->f);
	}
	fputc('"', j->f);
}

void vd_json_u64_array(struct vd_json *j, const char *key, const uint64_t *v,
		       size_t n)
{
	sep(j, key);
	fputc('[', j->f);
	for (size_t i = 0; i < n; i++)
		fprintf(j->f, "%s%llu", i ? ", " : "", (unsigned long long)v[i]);
	fputc(']', j->f);
}

int vd_json_close(struct vd_json *j)
{
	fputs("\n}\n", j->f);
	int err;
	if (j->bad || j->depth != 0) {
		err = vd_fail(VD_ERR_INTERNAL, "'%s': objects and arrays nested "
			      "deeper than %d or not closed in order",
			      j->a.path, JSON_DEPTH);
		vd_atomic_abort(&j->a); /* keeps the detail */
	} else {
		err = vd_atomic_commit(&j->a);
	}
	free(j);
	return err;
}

void vd_json_abort(struct vd_json *j)
{
	if (!j)
		return;
	vd_atomic_abort(&j->a); /* keeps the detail */
	free(j);
}
