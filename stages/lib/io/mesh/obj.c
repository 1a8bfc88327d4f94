/* obj.c - Wavefront OBJ, read in one pass; with colours, also its vertex
 * colours, texture coordinates and MTL material libraries. */
#include "io/mesh/mesh_internal.h"

#include <errno.h>
#include <inttypes.h>
#include <libgen.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

/* ------------------------------------------------------------------- MTL */

/* The file name of a map_Kd line: options (-o 1 2 3, -clamp on, ...)
 * skipped, the rest taken whole (names may hold spaces). */
static const char *vd_mtl_map_name(const char *p)
{
	p = vd_skip_space(p);
	while (*p == '-') {
		p = vd_skip_space(vd_token_end(p));
		for (;;) {
			double d;
			const char *e = vd_token_end(p);
			size_t n = (size_t)(e - p);
			if (n == 0 || !(vd__parse_double(p, &d) ||
					(n == 2 && !strncmp(p, "on", 2)) ||
					(n == 3 && !strncmp(p, "off", 3))))
				break;
			p = vd_skip_space(e);
		}
	}
	return p;
}

static void vd_rtrim(char *s)
{
	size_t n = strlen(s);
	while (n > 0 && (vd_is_space(s[n - 1]) || s[n - 1] == '\n'))
		s[--n] = 0;
}

/* Reads the MTL file `path`: newmtl, Kd, map_Kd (relative to the MTL's
 * own directory). A missing file is a warning, or with `strict` an
 * error. */
static int vd_obj_read_mtl(struct vd_mesh *m, const char *path)
{
	int e = vd__mesh_note(m, path);
	if (e)
		return e;
	struct stat st;
	FILE *f = stat(path, &st) != 0 ? NULL
		: !S_ISREG(st.st_mode) ? (errno = EINVAL, NULL)
		: fopen(path, "r");
	if (!f) {
		m->tex_missing++;
		if (m->col.strict)
			return vd_fail(VD_ERR_IO, "cannot open material library "
				       "'%s': %s", path, strerror(errno));
		vd__mesh_warn(m, "cannot open material library '%s': %s; its "
			     "materials are grey", path, strerror(errno));
		return VD_OK;
	}
	char *dir_buf = strdup(path);
	if (!dir_buf) {
		fclose(f);
		return vd_fail(VD_ERR_NOMEM, "material library");
	}
	const char *dir = dirname(dir_buf);
	char *line = NULL;
	size_t cap = 0;
	uint64_t ln = 0;
	struct vd_material *cur = NULL;
	while (!e && getline(&line, &cap, f) >= 0) {
		ln++;
		vd_rtrim(line);
		const char *p = vd_skip_space(line), *q;
		if ((q = vd__kw(p, "newmtl"))) {
			e = vd__mesh_add_material(m, vd_skip_space(q));
			cur = e ? NULL : &m->mats[m->nmats - 1];
		} else if (cur && (q = vd__kw(p, "Kd"))) {
			double d[3];
			if (vd__numbers3(q, d) == 3)
				for (int c = 0; c < 3; c++)
					cur->rgb[c] = vd__unit_byte(d[c]);
		} else if (cur && (q = vd__kw(p, "map_Kd"))) {
			const char *name = vd_mtl_map_name(q);
			if (!*name)
				continue;
			char *tp = vd__mesh_path(m, dir, name);
			if (!tp || (cur->tex = vd__mesh_tex_slot(m, tp)) < 0)
				e = vd_fail(VD_ERR_NOMEM, "textures");
		}
	}
	if (!e && ferror(f))
		e = vd_fail(VD_ERR_IO, "cannot read '%s' (line %" PRIu64 ")",
			    path, ln);
	free(line);
	free(dir_buf);
	fclose(f);
	return e;
}

/* "mtllib a.mtl [b.mtl ...]": each file read once per reader (a rewind
 * keeps the materials). A name with spaces is tried whole first. */
static int vd_obj_mtllib(struct vd_mesh *m, const char *rest)
{
	char *names = strdup(vd_skip_space(rest));
	if (!names)
		return vd_fail(VD_ERR_NOMEM, "mtllib");
	vd_rtrim(names);
	int e = VD_OK;
	char *whole = vd__mesh_path(m, NULL, names);
	struct stat st;
	int one = whole && stat(whole, &st) == 0;
	/* a name with spaces looked for whole in vain: if it appears, the
	 * MTL files read change */
	if (whole && !one && strpbrk(names, " \t"))
		e = vd__mesh_note(m, whole);
	free(whole);
	char *save = NULL;
	for (char *t = one ? names : strtok_r(names, " \t", &save); t && !e;
	     t = one ? NULL : strtok_r(NULL, " \t", &save)) {
		char *path = vd__mesh_path(m, NULL, t);
		if (!path) {
			e = vd_fail(VD_ERR_NOMEM, "mtllib");
			break;
		}
		size_t i = 0;
		while (i < m->nmtllibs && strcmp(m->mtllibs[i], path))
			i++;
		if (i < m->nmtllibs) {
			free(path);
			continue;
		}
		char **l = realloc(m->mtllibs, (m->nmtllibs + 1) * sizeof *l);
		if (!l) {
			free(path);
			e = vd_fail(VD_ERR_NOMEM, "mtllib");
			break;
		}
		m->mtllibs = l;
		m->mtllibs[m->nmtllibs++] = path;
		e = vd_obj_read_mtl(m, path);
	}
	free(names);
	return e;
}

/* "usemtl NAME": the material in force from here on (unknown: none, with
 * one warning per file); its texture is loaded now. */
static int vd_obj_usemtl(struct vd_mesh *m, const char *rest)
{
	char name[512];
	snprintf(name, sizeof name, "%s", vd_skip_space(rest));
	vd_rtrim(name);
	m->cur_mat = -1;
	for (size_t i = 0; i < m->nmats; i++)
		if (!strcmp(m->mats[i].name, name)) {
			m->cur_mat = (int)i;
			m->col_seen = 1;
			return vd__mesh_tex_use(m, m->mats[i].tex);
		}
	if (!m->warned_mat) {
		m->warned_mat = 1;
		vd__mesh_warn(m, "line %" PRIu64 ": material '%.80s' is not "
			     "defined in any mtllib read so far; its faces are "
			     "grey (further unknown materials not reported)",
			     m->r.lines, name);
	}
	return VD_OK;
}

/* ------------------------------------------------------------------- OBJ */

/* "vt u [v [w]]" (colours only). A non-finite coordinate is an error:
 * no wrap gives it a meaning. */
static int vd_obj_vt(struct vd_mesh *m, uint64_t ln, const char *p)
{
	double d[2] = {0, 0};
	for (int k = 0; k < 2; k++) {
		const char *t = vd_skip_space(p);
		if (*t == 0) {
			if (k == 0)
				return vd_fail(VD_ERR_FORMAT, "line %" PRIu64
					       ": vt without coordinates", ln);
			break;
		}
		if (!(p = vd__parse_double(t, &d[k])))
			return vd_fail(VD_ERR_FORMAT, "line %" PRIu64 ": "
				       "malformed texture coordinate '%.*s'",
				       ln, vd__tok40(t), t);
		if (!isfinite(d[k]))
			return vd_fail(VD_ERR_RANGE, "line %" PRIu64 ": texture "
				       "coordinate '%.*s' is not finite", ln,
				       vd__tok40(t), t);
	}
	/* an index is below VD_SPILL_NONE, spilled or not */
	if (m->nuvs >= UINT32_MAX)
		return vd_fail(VD_ERR_RANGE, "line %" PRIu64 ": more than %"
			       PRIu32 " texture coordinates", ln, UINT32_MAX);
	float uv[2] = {(float)d[0], (float)d[1]};
	const uint64_t vbytes = 4 * (uint64_t)m->vfloats,
		       other = m->verts_cap * vbytes;
	if (!m->spill && !m->spill_wanted && m->verts_limit &&
	    (m->nuvs + 1) * sizeof uv + other > m->verts_limit &&
	    vd__mesh_can_spill(m))
		m->spill_wanted = 1; /* they share the vertices' limit */
	if (m->spill || m->spill_wanted) {
		m->nuvs++;
		return m->spill ? vd__spill_record(m->spill, MESH_SPILL_UVS, uv)
				: VD_OK;
	}
	if (m->nuvs == m->uvs_cap) {
		uint64_t cap = vd__mesh_grow_cap(m, m->nuvs, sizeof uv, other,
						UINT32_MAX);
		if (cap == m->nuvs)
			return vd__mesh_over_limit(m);
		float *q = realloc(m->uvs, (size_t)cap * sizeof uv);
		if (!q)
			return vd_fail(VD_ERR_NOMEM, "texture coordinates");
		m->uvs = q;
		m->uvs_cap = cap;
	}
	memcpy(m->uvs + 2 * m->nuvs, uv, sizeof uv);
	m->nuvs++;
	return VD_OK;
}

/* Stores the texture coordinates of corner m->poly_n: vt index `ti`
 * (1-based, negative relative, INT64_MIN none). */
static int vd_obj_corner_uv(struct vd_mesh *m, uint64_t ln, int64_t ti)
{
	int e = vd__mesh_grow_tc(m, m->poly_n + 1);
	if (e)
		return e;
	float *tc = m->poly_tc + 2 * m->poly_n;
	if (ti == INT64_MIN) {
		tc[0] = tc[1] = NAN;
		return VD_OK;
	}
	int64_t i = ti > 0 ? ti - 1 : (int64_t)m->nuvs + ti;
	if (ti == 0 || i < 0 || (uint64_t)i >= m->nuvs)
		return vd_fail(VD_ERR_RANGE, "line %" PRIu64 ": face %" PRIu64
			       ": texture coordinate index %" PRId64 " out of "
			       "range (%" PRIu64 " defined so far)", ln,
			       m->poly_face, ti, m->nuvs);
	if (m->spill || m->spill_wanted) {
		/* the u v come from the join (wanted: they are not kept, and
		 * the polygon is read again into the spill) */
		tc[0] = tc[1] = 0;
		m->poly_ti[m->poly_n] = (uint32_t)i;
		return VD_OK;
	}
	tc[0] = m->uvs[2 * i];
	tc[1] = m->uvs[2 * i + 1];
	return VD_OK;
}

/* The rest of a vertex line, after its "v": appends the vertex. */
static int vd_obj_vertex(struct vd_mesh *m, uint64_t ln, const char *p)
{
	float v[3];
	for (int k = 0; k < 3; k++) {
		double d;
		const char *t = vd_skip_space(p);
		if (*t == 0)
			return vd_fail(VD_ERR_FORMAT, "line %" PRIu64 ": vertex "
				       "has %d coordinates, needs 3", ln, k);
		if (!(p = vd__parse_double(t, &d)))
			return vd_fail(VD_ERR_FORMAT, "line %" PRIu64 ": malformed "
				       "number '%.*s'", ln,
				       (int)(vd_token_end(t) - t > 40
					     ? 40 : vd_token_end(t) - t), t);
		v[k] = vd_to_f32(d);
	}
	/* w may follow (ignored), or with colours the common extension
	 * "v x y z r g b" (0..1). */
	uint8_t rgb[3];
	int col = 0;
	if (m->col_on) {
		double d[3], x;
		const char *q = p;
		int k = 0;
		for (; k < 4; k++) {
			q = vd_skip_space(q);
			if (!*q || !(q = vd__parse_double(q, &x)))
				break;
			if (k < 3)
				d[k] = x;
		}
		if (k == 3) {
			for (int c = 0; c < 3; c++)
				rgb[c] = vd__unit_byte(d[c]);
			col = m->col_seen = 1;
		}
	}
	int e = vd__mesh_push_vertex_rgb(m, v, col ? rgb : NULL);
	if (e)
		return e;
	m->stats.vertices = m->nverts;
	return VD_OK;
}

int vd__obj_next(struct vd_mesh *m, int *got)
{
	char *s;
	size_t len;
	int e;
	for (;;) {
		e = vd__rd_line(&m->r, &s, &len, 1);
		if (e < 0)
			return -e;
		if (e == 0) {
			*got = 0;
			return VD_OK;
		}
		uint64_t ln = m->r.lines;
		if (strlen(s) != len)
			return vd_fail(VD_ERR_FORMAT, "line %" PRIu64 ": NUL "
				       "byte in an OBJ file", ln);
		const char *p = vd_skip_space(s);
		if (*p == 0 || *p == '#')
			continue;
		if (p[0] == 'v' && vd_is_end(p[1])) {
			if ((e = vd_obj_vertex(m, ln, p + 1)))
				return e;
			continue;
		}
		if (p[0] == 'f' && vd_is_end(p[1])) {
			m->poly_face++;
			m->poly_line = ln;
			m->poly_n = 0;
			for (p++;;) {
				const char *t = vd_skip_space(p);
				if (*t == 0)
					break;
				int64_t i;
				if (!(p = vd__parse_int(t, &i)))
					goto bad_corner;
				/* texture and normal indices: the texture
				 * index only with colours */
				int64_t ti = INT64_MIN; /* none */
				if (*p == '/' && m->col_on &&
				    ((p[1] >= '0' && p[1] <= '9') || p[1] == '-')
				    && !(p = vd__parse_int(p + 1, &ti)))
					goto bad_corner;
				if (*p == '/')
					while ((*p >= '0' && *p <= '9') ||
					       *p == '/' || *p == '-')
						p++;
				if (!vd_is_end(*p))
					goto bad_corner;
				if (i == 0)
					return vd_fail(VD_ERR_RANGE,
						"line %" PRIu64 ": face %" PRIu64
						": vertex index 0 (OBJ indices "
						"start at 1)", ln, m->poly_face);
				int64_t idx = i > 0 ? i - 1 : (int64_t)m->nverts + i;
				if (idx < 0 || (uint64_t)idx >= m->nverts)
					return vd_fail(VD_ERR_RANGE,
						"line %" PRIu64 ": face %" PRIu64
						": vertex index %" PRId64 " out "
						"of range (%" PRIu64 " vertices "
						"defined so far)", ln,
						m->poly_face, i, m->nverts);
				if (m->poly_n == MESH_MAX_CORNERS)
					return vd_fail(VD_ERR_FORMAT,
						"line %" PRIu64 ": face %" PRIu64
						" has more than %d corners", ln,
						m->poly_face, MESH_MAX_CORNERS);
				if ((e = vd__mesh_grow_poly(m, m->poly_n + 1)))
					return e;
				if (m->col_on &&
				    (e = vd_obj_corner_uv(m, ln, ti)))
					return e;
				m->poly[m->poly_n++] = (uint32_t)idx;
				continue;
			bad_corner:
				return vd_fail(VD_ERR_FORMAT,
					"line %" PRIu64 ": malformed face "
					"corner '%.*s'", ln,
					(int)(vd_token_end(t) - t > 40 ? 40 :
					      vd_token_end(t) - t), t);
			}
			m->poly_mat = m->cur_mat;
			m->poly_has_tc = m->col_on;
			*got = 1;
			return VD_OK;
		}
		if (m->col_on) {
			const char *q;
			if ((q = vd__kw(p, "vt"))) {
				if ((e = vd_obj_vt(m, ln, q)))
					return e;
				continue;
			}
			if ((q = vd__kw(p, "usemtl"))) {
				if ((e = vd_obj_usemtl(m, q)))
					return e;
				continue;
			}
			if ((q = vd__kw(p, "mtllib"))) {
				if ((e = vd_obj_mtllib(m, q)))
					return e;
				continue;
			}
		}
		/* vn vt o g s usemtl mtllib l p and the rest of the spec
		 * describe things we do not voxelize. Only non-words are
		 * refused, to catch binary files named .obj. */
		if ((*p >= 'a' && *p <= 'z') || (*p >= 'A' && *p <= 'Z') ||
		    *p == '_')
			continue;
		return vd_fail(VD_ERR_FORMAT, "line %" PRIu64 ": unexpected "
			       "'%.*s' in an OBJ file", ln,
			       (int)(vd_token_end(p) - p > 40 ? 40 :
				     vd_token_end(p) - p), p);
	}
}
