/* open.c - vd_mesh_open and its kin: the detection that hands a file to
 * its format's reader (ply.c, obj.c, stl.c, ac3d.c, imported.c), the
 * accessors, and vd_mesh_close. */
#include "io/mesh/mesh_internal.h"
#include "util_internal.h"

#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <libgen.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

static const char *const vd_mesh_kind_names[] = {
	"ply-binary-le", "ply-binary-be", "ply-ascii", "obj", "stl-binary",
	"stl-ascii", "ac3d", "imported"};

/* ------------------------------------------------------------- detection */

/* Text as far as we can tell: no NUL or control bytes but whitespace.
 * Bytes >= 0x80 pass so that UTF-8 names and comments are fine. */
static int vd_is_text(const unsigned char *p, size_t n)
{
	for (size_t i = 0; i < n; i++)
		if ((p[i] < 0x20 && p[i] != '\n' && !vd_is_space((char)p[i])) ||
		    p[i] == 0x7f)
			return 0;
	return 1;
}

/* The first statement is one only OBJ files start with. */
static int vd_looks_like_obj(const unsigned char *p, size_t n)
{
	static const char *const kw[] = {"v", "vn", "vt", "vp", "f", "o", "g",
					 "s", "usemtl", "mtllib", "l", "p"};
	if (!vd_is_text(p, n))
		return 0;
	size_t i = 0;
	while (i < n) {
		while (i < n && (vd_is_space((char)p[i]) || p[i] == '\n'))
			i++;
		if (i < n && p[i] == '#') {
			while (i < n && p[i] != '\n')
				i++;
			continue;
		}
		size_t j = i;
		while (j < n && p[j] > ' ')
			j++;
		if (j == n || !vd_is_space((char)p[j]))
			return 0;
		for (size_t k = 0; k < sizeof kw / sizeof *kw; k++)
			if (strlen(kw[k]) == j - i &&
			    !memcmp(kw[k], p + i, j - i))
				return 1;
		return 0;
	}
	return 0;
}

/* Says what the file starts with, for the "unsupported" detail. */
static void vd_describe_start(const unsigned char *p, size_t n, char *out,
			      size_t cap)
{
	size_t k = 0;
	while (k < n && k < 24 && p[k] >= 0x20 && p[k] < 0x7f)
		k++;
	if (k >= 4 || k == n) {
		snprintf(out, cap, "starts with '%.*s'", (int)k,
			 (const char *)p);
		return;
	}
	size_t w = (size_t)snprintf(out, cap, "starts with bytes");
	for (size_t i = 0; i < n && i < 8 && w + 4 < cap; i++)
		w += (size_t)snprintf(out + w, cap - w, " %02x", p[i]);
}

static int vd_mesh_detect(struct vd_mesh *m, const char *path)
{
	struct vd_rd *r = &m->r;
	size_t want = m->file_bytes < 4096 ? (size_t)m->file_bytes : 4096;
	int e = vd__rd_need(r, want);
	if (e == VD_ERR_TRUNCATED)
		return vd_fail(e, "'%s' shrank while being opened", path);
	if (e)
		return e;
	const unsigned char *head = r->buf;
	size_t hn = r->len;

	if (hn >= 3 && !memcmp(head, "ply", 3) &&
	    (hn == 3 || head[3] == '\n' || head[3] == '\r'))
		return vd__ply_open(m);
	if (hn >= 4 && !memcmp(head, "AC3D", 4))
		return vd__ac_open(m, path);

	if (m->file_bytes >= 84 &&
	    84 + 50 * vd_ld(head + 80, 4, 0) == m->file_bytes) {
		m->kind = MESH_STL_BIN;
		m->stl_count = vd_ld(head + 80, 4, 0);
		m->body_off = 84;
		return vd__rd_seek(r, m->body_off, 0);
	}
	size_t i = 0;
	while (i < hn && (vd_is_space((char)head[i]) || head[i] == '\n'))
		i++;
	int solid = hn - i >= 5 && !strncasecmp((const char *)head + i,
						"solid", 5) &&
		(hn - i == 5 || vd_is_end((char)head[i + 5]) ||
		 head[i + 5] == '\n');
	if (solid && vd_is_text(head, hn)) {
		m->kind = MESH_STL_ASCII;
		return vd__rd_seek(r, 0, 0);
	}
	if (solid || vd__has_ext(path, ".stl"))
		return vd__stl_size_error(m, head, hn);
	if (vd__has_ext(path, ".obj") || vd_looks_like_obj(head, hn)) {
		m->kind = MESH_OBJ;
		return vd__rd_seek(r, 0, 0);
	}
	char what[80];
	vd_describe_start(head, hn, what, sizeof what);
	return vd_fail(VD_ERR_UNSUPPORTED, "not a PLY, OBJ, STL or AC3D file "
		       "(%s)", what);
}

/* ------------------------------------------------------------ public API */

int vd_mesh_open(struct vd_mesh **out, const char *path)
{
	return vd_mesh_open_limited(out, path, 0);
}

int vd_mesh_open_limited(struct vd_mesh **out, const char *path,
			 uint64_t max_vertex_bytes)
{
	struct vd_mesh_open_opts o = {.max_vertex_bytes = max_vertex_bytes};
	return vd_mesh_open_opts(out, path, &o);
}

int vd_mesh_open_spill(struct vd_mesh **out, const char *path,
		       uint64_t max_vertex_bytes, const char *spill_dir)
{
	struct vd_mesh_open_opts o = {.max_vertex_bytes = max_vertex_bytes,
				      .spill_dir = spill_dir};
	return vd_mesh_open_opts(out, path, &o);
}

int vd_mesh_open_opts(struct vd_mesh **out, const char *path,
		      const struct vd_mesh_open_opts *o)
{
	if (!out || !path || !o)
		return vd_fail(VD_ERR_ARG, "vd_mesh_open: NULL argument");
	*out = NULL;
	struct vd_mesh *m = calloc(1, sizeof *m);
	if (!m)
		return vd_fail(VD_ERR_NOMEM, "mesh reader");
	m->vfloats = 3;
	m->poly_mat = m->cur_mat = m->ac_tex = -1;
	if (o->spill_dir && o->max_vertex_bytes &&
	    !(m->spill_dir = strdup(o->spill_dir))) {
		free(m);
		return vd_fail(VD_ERR_NOMEM, "mesh reader");
	}
	/* warnings are said with or without colours */
	m->col.warn = o->warn;
	m->col.warn_ctx = o->warn_ctx;
	if (o->colours) {
		m->col_on = 1;
		m->col = *o;
		m->col.spill_dir = NULL; /* m->spill_dir is the copy */
		char *d = strdup(path);
		m->dir = d ? strdup(dirname(d)) : NULL;
		free(d);
		if (!m->dir) {
			free(m->spill_dir);
			free(m);
			return vd_fail(VD_ERR_NOMEM, "mesh reader");
		}
	}
	m->r.fd = open(path, O_RDONLY | O_CLOEXEC);
	if (m->r.fd < 0) {
		int e = vd_fail(VD_ERR_IO, "cannot open '%s': %s", path,
				strerror(errno));
		free(m->dir);
		free(m->spill_dir);
		free(m);
		return e;
	}
	int e;
	struct stat st;
	if (fstat(m->r.fd, &st) < 0)
		e = vd_fail(VD_ERR_IO, "cannot stat '%s': %s", path,
			    strerror(errno));
	else if (S_ISDIR(st.st_mode))
		e = vd_fail(VD_ERR_IO, "cannot read '%s': %s", path,
			    strerror(EISDIR));
	else if (!S_ISREG(st.st_mode))
		/* Rewind and the size checks need a seekable, sized file. */
		e = vd_fail(VD_ERR_UNSUPPORTED, "'%s' is not a regular file",
			    path);
	else if (st.st_size == 0)
		e = vd_fail(VD_ERR_EMPTY, "'%s' is empty (0 bytes)", path);
	else if (vd_mesh_is_imported(path)) {
		/* the importer reads the file itself */
		close(m->r.fd);
		m->r.fd = -1;
		m->verts_limit = o->max_vertex_bytes;
		m->file_bytes = (uint64_t)st.st_size;
		e = vd__import_open(m, path);
	} else if (!(m->r.buf = malloc(MESH_BUF_BYTES + 1)))
		e = vd_fail(VD_ERR_NOMEM, "read buffer");
	else {
		m->r.cap = MESH_BUF_BYTES;
		m->verts_limit = o->max_vertex_bytes;
		m->file_bytes = (uint64_t)st.st_size;
		e = vd_mesh_detect(m, path);
		/* OBJ may colour any vertex ("v x y z r g b") */
		if (!e && m->col_on && m->kind == MESH_OBJ)
			m->vfloats = 4;
	}
	if (e) {
		vd_mesh_close(m);
		return e;
	}
	*out = m;
	return VD_OK;
}

int vd_mesh_vertex_bounds(const struct vd_mesh *m, float lo[3], float hi[3])
{
	if (!m || (m->kind != MESH_PLY_LE && m->kind != MESH_PLY_BE &&
		   m->kind != MESH_PLY_ASCII) || m->spill || m->spill_wanted ||
	    m->nonfinite || !m->verts || m->nverts == 0)
		return 0;
	for (int a = 0; a < 3; a++)
		lo[a] = hi[a] = m->verts[a];
	vd_bounds_widen(m->verts, m->nverts, (size_t)m->vfloats, lo, hi);
	return 1;
}

int vd_mesh_has_colours(const struct vd_mesh *m)
{
	return m && m->col_on && m->col_seen;
}

const struct vd_texture *vd_mesh_texture(const struct vd_mesh *m, int i)
{
	if (!m || i < 0 || (size_t)i >= m->ntexs || m->texs[i].state != 1)
		return NULL;
	return &m->texs[i].t;
}

uint64_t vd_mesh_textures_missing(const struct vd_mesh *m)
{
	return m ? m->tex_missing : 0;
}

uint64_t vd_mesh_textures_loaded(const struct vd_mesh *m)
{
	return m ? m->tex_loaded : 0;
}

const char *vd_mesh_format(const struct vd_mesh *m)
{
	if (m && m->kind == MESH_IMPORT)
		return m->imp.format;
	return m ? vd_mesh_kind_names[m->kind] : "none";
}

size_t vd_mesh_memory_bytes(const struct vd_mesh *m)
{
	if (!m)
		return 0;
	size_t b = sizeof *m + (m->r.buf ? m->r.cap + 1 : 0) +
		   (size_t)m->verts_cap * 4 * (size_t)m->vfloats +
		   m->poly_cap * sizeof *m->poly +
		   m->ac_cap * sizeof *m->ac_stack +
		   m->poly_tc_cap * (2 * sizeof(float) + sizeof(uint32_t)) +
		   (size_t)m->uvs_cap * 2 * sizeof(float) +
		   m->mats_cap * sizeof *m->mats +
		   m->texs_cap * sizeof *m->texs +
		   vd__spill_memory_bytes(m->spill) + vd__import_bytes(&m->imp);
	for (size_t i = 0; i < m->ntexs; i++)
		b += 3 * (size_t)m->texs[i].t.width * m->texs[i].t.height;
	for (size_t i = 0; i < m->nelems; i++)
		b += sizeof m->elems[i] +
		     m->elems[i].cap * sizeof *m->elems[i].props;
	return b;
}

const struct vd_mesh_stats *vd_mesh_stats(const struct vd_mesh *m)
{
	return &m->stats;
}

void vd_mesh_close(struct vd_mesh *m)
{
	if (!m)
		return;
	if (m->r.fd >= 0)
		close(m->r.fd);
	free(m->r.buf);
	free(m->verts);
	free(m->poly);
	free(m->ac_stack);
	vd__mesh_free_materials(m);
	free(m->mats);
	for (size_t i = 0; i < m->ntexs; i++) {
		free(m->texs[i].path);
		vd_texture_release(&m->texs[i].t);
	}
	free(m->texs);
	for (size_t i = 0; i < m->nmtllibs; i++)
		free(m->mtllibs[i]);
	free(m->mtllibs);
	for (size_t i = 0; i < m->nsrcs; i++)
		free(m->srcs[i].path);
	free(m->srcs);
	free(m->uvs);
	free(m->poly_tc);
	free(m->poly_ti);
	free(m->vslot);
	free(m->dir);
	vd__spill_close(m->spill);
	free(m->spill_dir);
	for (size_t i = 0; i < m->nelems; i++)
		free(m->elems[i].props);
	free(m->elems);
	vd_import_scene_release(&m->imp);
	free(m);
}
