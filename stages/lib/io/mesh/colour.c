/* colour.c - what surface colours need besides the geometry: materials
 * and textures, shared by OBJ (MTL files), AC3D and imported scenes,
 * warnings, and the files read besides the mesh (vd_mesh_sources).
 * Textures are registered by path when a material or object names them
 * and decoded the first time a face uses them, so a library of unused
 * materials costs nothing. */
#include "io/mesh/mesh_internal.h"
#include "util_internal.h"

#include <inttypes.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void vd__mesh_warn(struct vd_mesh *m, const char *fmt, ...)
{
	if (!m->col.warn)
		return;
	char line[600];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(line, sizeof line, fmt, ap);
	va_end(ap);
	m->col.warn(m->col.warn_ctx, line);
}

/* Records `path` as a source just before the reader opens it (or after
 * it looked for it in vain), with `known` (an importer's record) or the
 * hash of its content now: so the content read is this one or a later
 * one, never an earlier one that a check could take for current. A path
 * is recorded once: the first look counts. */
int vd__mesh_note_as(struct vd_mesh *m, const char *path,
		    const struct vd_mesh_source *known)
{
	for (size_t i = 0; i < m->nsrcs; i++)
		if (!strcmp(m->srcs[i].path, path))
			return VD_OK;
	struct vd_mesh_source *p = vd_grow(m->srcs, m->nsrcs, &m->srcs_cap,
					   sizeof *p, 8);
	if (!p)
		return vd_fail(VD_ERR_NOMEM, "the list of files read");
	m->srcs = p;
	struct vd_mesh_source *r = &m->srcs[m->nsrcs];
	memset(r, 0, sizeof *r);
	if (!(r->path = strdup(path)))
		return vd_fail(VD_ERR_NOMEM, "the list of files read");
	if (known) {
		r->found = known->found;
		r->xxh3 = known->xxh3;
		r->size = known->size;
	} else if (!(r->found = vd_source_xxh3(path, &r->xxh3, &r->size) ==
		     VD_OK)) {
		vd_error_clear();
		r->xxh3 = r->size = 0;
	}
	m->nsrcs++;
	return VD_OK;
}

/* The same, hashed now. */
int vd__mesh_note(struct vd_mesh *m, const char *path)
{
	return vd__mesh_note_as(m, path, NULL);
}

const struct vd_mesh_source *vd_mesh_sources(const struct vd_mesh *m,
					     size_t *n)
{
	*n = m->nsrcs;
	return m->srcs;
}

uint8_t vd__unit_byte(double x)
{
	if (!(x > 0))
		return 0;
	return x >= 1 ? 255 : (uint8_t)(x * 255.0 + 0.5);
}

/* `name` relative to the mesh's directory (absolute names as they are);
 * DOS separators become '/'. Returns a malloc'd path or NULL. */
char *vd__mesh_path(const struct vd_mesh *m, const char *dir,
		   const char *name)
{
	size_t n = strlen(name);
	const char *d = dir ? dir : m->dir;
	char *p = malloc(strlen(d) + n + 2);
	if (!p)
		return NULL;
	if (name[0] == '/')
		memcpy(p, name, n + 1);
	else
		sprintf(p, "%s/%s", d, name);
	for (char *q = p; *q; q++)
		if (*q == '\\')
			*q = '/';
	return p;
}

/* A new texture slot for `path` (taken over by the slot), -1 on
 * failure. */
int vd__mesh_tex_new(struct vd_mesh *m, char *path)
{
	struct vd_tex_slot *a = vd_grow(m->texs, m->ntexs, &m->texs_cap,
					sizeof *a, 8);
	if (!a) {
		free(path);
		return -1;
	}
	m->texs = a;
	struct vd_tex_slot *t = &m->texs[m->ntexs];
	memset(t, 0, sizeof *t);
	t->path = path;
	t->imp_tex = -1;
	return (int)m->ntexs++;
}

/* The texture slot of `path` (taken over by the slot), -1 on failure. */
int vd__mesh_tex_slot(struct vd_mesh *m, char *path)
{
	for (size_t i = 0; i < m->ntexs; i++)
		if (!strcmp(m->texs[i].path, path)) {
			free(path);
			return (int)i;
		}
	return vd__mesh_tex_new(m, path);
}

/* Loads texture slot i if not tried yet. A failure is a warning (the slot
 * then stays unusable, and faces fall back to their colours), or with
 * `strict` the error. */
int vd__mesh_tex_use(struct vd_mesh *m, int i)
{
	if (i < 0 || m->texs[i].state != 0)
		return VD_OK;
	struct vd_tex_slot *t = &m->texs[i];
	int e = t->data || t->unsupported ? VD_OK : vd__mesh_note(m, t->path);
	if (e)
		return e;
	e = t->unsupported
		? vd_fail(VD_ERR_UNSUPPORTED, "'%s' %s", t->path, t->unsupported)
		: t->data ? vd_texture_load_mem(&t->t, t->data, t->bytes, t->path)
		: vd_texture_load(&t->t, t->path);
	if (!e) {
		t->t.wrap[0] = t->wrap[0];
		t->t.wrap[1] = t->wrap[1];
		t->state = 1;
		m->tex_loaded++;
		return VD_OK;
	}
	t->state = -1;
	m->tex_missing++;
	if (e == VD_ERR_NOMEM || m->col.strict)
		return vd_fail(e, "texture: %s", vd_error_detail());
	vd__mesh_warn(m, "texture not used (%s): %s; the material's colour "
		     "is used instead", vd_strerror(e), vd_error_detail());
	return VD_OK;
}

void vd__mesh_free_materials(struct vd_mesh *m)
{
	for (size_t i = 0; i < m->nmats; i++)
		free(m->mats[i].name);
	m->nmats = 0;
}

int vd__mesh_add_material(struct vd_mesh *m, const char *name)
{
	struct vd_material *p = vd_grow(m->mats, m->nmats, &m->mats_cap,
					sizeof *p, 16);
	if (!p)
		return vd_fail(VD_ERR_NOMEM, "materials");
	m->mats = p;
	struct vd_material *mt = &m->mats[m->nmats];
	if (!(mt->name = strdup(name)))
		return vd_fail(VD_ERR_NOMEM, "materials");
	mt->rgb[0] = mt->rgb[1] = mt->rgb[2] = VD_GREY;
	mt->tex = -1;
	m->nmats++;
	return VD_OK;
}

/* Grows m->poly_tc and m->poly_ti to hold `need` corners. */
int vd__mesh_grow_tc(struct vd_mesh *m, size_t need)
{
	if (need <= m->poly_tc_cap)
		return VD_OK;
	size_t cap = m->poly_tc_cap ? m->poly_tc_cap * 2 : 64;
	while (cap < need)
		cap *= 2;
	float *p = realloc(m->poly_tc, cap * 2 * sizeof *p);
	if (p)
		m->poly_tc = p;
	uint32_t *q = p ? realloc(m->poly_ti, cap * sizeof *q) : NULL;
	if (!q)
		return vd_fail(VD_ERR_NOMEM, "polygon of %zu corners", need);
	m->poly_ti = q;
	m->poly_tc_cap = cap;
	return VD_OK;
}

/* Parses 3 numbers (a colour in 0..1); returns how many parsed. */
int vd__numbers3(const char *p, double d[3])
{
	for (int k = 0; k < 3; k++) {
		p = vd_skip_space(p);
		if (!*p || !(p = vd__parse_double(p, &d[k])))
			return k;
	}
	return 3;
}
