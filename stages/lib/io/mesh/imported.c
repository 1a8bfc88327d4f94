/* imported.c - imported scenes: glTF, FBX, Collada and 3DS through the
 * importer voxelize-assimp sets (voxdag.h, "imported formats", and
 * mesh_import.h): the importer reads the whole scene into m->imp; its
 * triangles are then handed out from memory in its order, and their
 * attributes follow the OBJ rule: the material's texture when it loaded
 * and the triangle's corners all have texture coordinates, else the
 * vertices' colours, else the material's colour, else grey. A texture
 * slot stands for one of the scene's textures under one pair of wrap
 * modes (materials may sample one image differently). */
#include "io/mesh/mesh_internal.h"

#include <dirent.h>
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>

static vd_mesh_importer vd_importer;

void vd_mesh_set_importer(vd_mesh_importer fn)
{
	vd_importer = fn;
}

int vd_mesh_is_imported(const char *path)
{
	static const char *const ext[] = {".gltf", ".glb", ".fbx", ".dae",
					  ".3ds"};
	size_t n = path ? strlen(path) : 0;
	for (size_t i = 0; i < sizeof ext / sizeof *ext; i++) {
		size_t e = strlen(ext[i]);
		if (n > e && !strcasecmp(path + n - e, ext[i]))
			return 1;
	}
	return 0;
}

void vd_import_scene_release(struct vd_import_scene *s)
{
	if (!s)
		return;
	free(s->pos);
	free(s->uv);
	free(s->rgb);
	free(s->idx);
	free(s->mat);
	free(s->mats);
	for (size_t i = 0; i < s->ntexs; i++) {
		free(s->texs[i].path);
		free(s->texs[i].data);
		free(s->texs[i].name);
	}
	free(s->texs);
	for (size_t i = 0; i < s->nsources; i++)
		free(s->sources[i].path);
	free(s->sources);
	memset(s, 0, sizeof *s);
}

/* Bytes the scene's arrays take (embedded images included). */
size_t vd__import_bytes(const struct vd_import_scene *s)
{
	size_t b = (size_t)s->nverts * (12 + 8 + 4) +
		   (size_t)s->ntris * (12 + 4) +
		   s->nmats * sizeof *s->mats + s->ntexs * sizeof *s->texs;
	for (size_t i = 0; i < s->ntexs; i++)
		b += s->texs[i].bytes;
	return b;
}

/* A texture file that is not there under its name may be there in
 * another case: 3DS and older FBX files name them as DOS did ("TEST.PNG"
 * for test.png). Replaces *path by the one name of its directory that
 * matches ignoring case, if there is exactly one; else leaves it. */
static void vd_import_fix_case(char **path)
{
	struct stat st;
	if (stat(*path, &st) == 0)
		return;
	char *slash = strrchr(*path, '/');
	if (!slash)
		return;
	*slash = 0;
	DIR *d = opendir(**path ? *path : "/");
	char *found = NULL;
	int matches = 0;
	struct dirent *e;
	while (d && (e = readdir(d)))
		if (!strcasecmp(e->d_name, slash + 1) && matches++ == 0) {
			found = malloc(strlen(*path) + strlen(e->d_name) + 2);
			if (found)
				sprintf(found, "%s/%s", *path, e->d_name);
		}
	if (d)
		closedir(d);
	*slash = '/';
	if (found && matches == 1) {
		free(*path);
		*path = found;
	} else {
		free(found);
	}
}

/* The slot of the scene's texture ti sampled with `wrap`, -1 on
 * failure. */
static int vd_import_slot(struct vd_mesh *m, const char *mesh_path, int ti,
			  const uint8_t wrap[2])
{
	for (size_t i = 0; i < m->ntexs; i++)
		if (m->texs[i].imp_tex == ti && m->texs[i].wrap[0] == wrap[0] &&
		    m->texs[i].wrap[1] == wrap[1])
			return (int)i;
	const struct vd_import_texture *it = &m->imp.texs[ti];
	char *path;
	if (it->path) {
		path = vd__mesh_path(m, NULL, it->path);
		char *asked = path ? strdup(path) : NULL;
		if (path && asked)
			vd_import_fix_case(&path);
		/* the name as given was not there: if it appears, it is the
		 * texture */
		int e = asked && strcmp(asked, path) ? vd__mesh_note(m, asked)
						     : VD_OK;
		if (!asked || e) {
			free(asked);
			free(path);
			return -1;
		}
		free(asked);
	} else {
		const char *nm = it->name ? it->name : "?";
		path = malloc(strlen(mesh_path) + strlen(nm) + 32);
		if (path)
			sprintf(path, "%s, embedded image %s", mesh_path, nm);
	}
	if (!path)
		return -1;
	int slot = vd__mesh_tex_new(m, path);
	if (slot < 0)
		return -1;
	struct vd_tex_slot *t = &m->texs[slot];
	t->imp_tex = ti;
	t->wrap[0] = wrap[0];
	t->wrap[1] = wrap[1];
	t->data = it->data;
	t->bytes = it->bytes;
	t->unsupported = it->unsupported ? "is stored as raw texels, which "
			 "voxelize does not decode" : NULL;
	return slot;
}

int vd__import_open(struct vd_mesh *m, const char *path)
{
	if (!vd_importer)
		return vd_fail(VD_ERR_UNSUPPORTED, "glTF, FBX, Collada and 3DS "
			       "files are read by voxelize (through its sibling "
			       "voxelize-assimp), not by this program");
	m->kind = MESH_IMPORT;
	struct vd_import_scene *s = &m->imp;
	int e = vd_importer(path, s);
	if (e)
		return e;
	size_t bytes = vd__import_bytes(s);
	if (m->verts_limit && bytes > m->verts_limit)
		return vd_fail(VD_ERR_BUDGET, "'%s' takes %zu bytes in memory "
			       "once read (its scene is held whole), over the "
			       "%" PRIu64 " bytes allowed for a mesh's vertices",
			       path, bytes, m->verts_limit);
	for (uint64_t t = 0; t < s->ntris; t++)
		for (int j = 0; j < 3; j++)
			if (s->idx[3 * t + j] >= s->nverts)
				return vd_fail(VD_ERR_INTERNAL, "the importer's "
					       "triangle %" PRIu64 " uses vertex "
					       "%" PRIu32 " of %" PRIu64, t,
					       s->idx[3 * t + j], s->nverts);
	m->stats.vertices = s->nverts;
	m->stats.faces_dropped_short = s->faces_dropped_short;
	/* the files the importer read besides the scene (a .gltf's buffers,
	 * hashed as it opened them): the geometry depends on them too */
	for (size_t i = 0; i < s->nsources; i++)
		if ((e = vd__mesh_note_as(m, s->sources[i].path, &s->sources[i])))
			return e;
	if (!m->col_on)
		return VD_OK;
	m->col_seen = s->has_colours;
	for (size_t i = 0; i < s->nmats; i++) {
		if ((e = vd__mesh_add_material(m, "")))
			return e;
		struct vd_material *mt = &m->mats[i];
		memcpy(mt->rgb, s->mats[i].rgb, 3);
		int ti = s->mats[i].tex;
		if (ti >= 0 && (size_t)ti < s->ntexs &&
		    (mt->tex = vd_import_slot(m, path, ti, s->mats[i].wrap)) < 0)
			return vd_fail(VD_ERR_NOMEM, "textures");
	}
	/* the textures of the materials some triangle uses, now: the first
	 * pass over the triangles must see them loaded (voxelize.c) */
	for (uint64_t t = 0; t < s->ntris; t++) {
		int32_t mi = s->mat[t];
		if (mi >= 0 && (size_t)mi < m->nmats &&
		    (e = vd__mesh_tex_use(m, m->mats[mi].tex)))
			return e;
	}
	return VD_OK;
}

/* The attributes of triangle t (corners ix). */
static int vd_import_attr(struct vd_mesh *m, uint64_t t, const uint32_t *ix,
			  struct vd_tri_attr *a)
{
	const struct vd_import_scene *s = &m->imp;
	memset(a, 0, sizeof *a);
	a->texture = -1;
	int32_t mi = s->mat[t];
	const struct vd_material *mt =
		mi >= 0 && (size_t)mi < m->nmats ? &m->mats[mi] : NULL;
	int tex = mt ? mt->tex : -1;
	if (tex >= 0 && m->texs[tex].state == 1 && (s->rgb[4 * ix[0] + 3] &
	    s->rgb[4 * ix[1] + 3] & s->rgb[4 * ix[2] + 3] & 2)) {
		for (int j = 0; j < 3; j++) {
			const float *uv = s->uv + 2 * (size_t)ix[j];
			if (!isfinite(uv[0]) || !isfinite(uv[1]))
				return vd_fail(VD_ERR_RANGE, "triangle %" PRIu64
					       ": the texture coordinates of "
					       "vertex %" PRIu32 " are not "
					       "finite (%g %g)", t + 1, ix[j],
					       uv[0], uv[1]);
			a->uv[j][0] = uv[0];
			a->uv[j][1] = uv[1];
		}
		a->texture = tex;
	}
	static const uint8_t grey[3] = {VD_GREY, VD_GREY, VD_GREY};
	const uint8_t *base = mt ? mt->rgb : grey;
	for (int j = 0; j < 3; j++) {
		const uint8_t *c = s->rgb + 4 * (size_t)ix[j];
		memcpy(a->rgb[j], c[3] & 1 ? c : base, 3);
	}
	return VD_OK;
}

int vd__import_read(struct vd_mesh *m, struct vd_triangle *buf,
		   struct vd_tri_attr *attr, size_t cap, size_t *n)
{
	const struct vd_import_scene *s = &m->imp;
	size_t k = 0;
	int e = VD_OK;
	for (; !e && k < cap && m->imp_next < s->ntris; m->imp_next++) {
		uint64_t t = m->imp_next;
		const uint32_t *ix = s->idx + 3 * t;
		for (int j = 0; j < 3; j++) {
			const float *v = s->pos + 3 * (size_t)ix[j];
			if (!isfinite(v[0]) || !isfinite(v[1]) ||
			    !isfinite(v[2])) {
				m->poly_face = t + 1;
				e = vd__mesh_nonfinite(m, ix[j], v);
				break;
			}
			memcpy(buf[k].v[j], v, 12);
		}
		if (!e && attr)
			e = vd_import_attr(m, t, ix, &attr[k]);
		if (!e)
			k++;
	}
	*n = k;
	return e;
}
