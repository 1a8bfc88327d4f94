/* stl.c - STL: ASCII read by tokens, binary by 50-byte records. */
#include "io/mesh/mesh_internal.h"

#include <inttypes.h>
#include <math.h>
#include <string.h>
#include <strings.h>

/* Returns 1 with the next whitespace-separated token in *t, 0 at the end,
 * or a negated error code as vd__rd_line.
 * ASCII STL is read by tokens, not lines, because writers disagree on line
 * breaks. stl_rest stays valid between calls: the buffer only moves inside
 * vd__rd_line, after the current line is used up. */
static int vd_stl_token(struct vd_mesh *m, char **t)
{
	for (;;) {
		if (m->stl_rest) {
			char *p = (char *)vd_skip_space(m->stl_rest);
			if (*p) {
				char *q = (char *)vd_token_end(p);
				m->stl_rest = *q ? q + 1 : q;
				*q = 0;
				*t = p;
				return 1;
			}
		}
		char *s;
		size_t len;
		int e = vd__rd_line(&m->r, &s, &len, 0);
		if (e <= 0)
			return e;
		if (strlen(s) != len)
			return -vd_fail(VD_ERR_FORMAT, "line %" PRIu64 ": NUL "
					"byte in an ASCII STL file",
					m->r.lines);
		m->stl_rest = s;
	}
}

/* Reads a token that must be there (we are inside a facet). */
static int vd_stl_inner(struct vd_mesh *m, char **t)
{
	int e = vd_stl_token(m, t);
	if (e == 0)
		return vd_fail(VD_ERR_TRUNCATED, "file ends inside facet %"
			       PRIu64 " (line %" PRIu64 ")", m->poly_face,
			       m->r.lines);
	return e < 0 ? -e : VD_OK;
}

static int vd_stl_expect(struct vd_mesh *m, const char *want)
{
	char *t;
	int e = vd_stl_inner(m, &t);
	if (e)
		return e;
	if (strcasecmp(t, want))
		return vd_fail(VD_ERR_FORMAT, "line %" PRIu64 ": expected "
			       "'%s', found '%.40s'", m->r.lines, want, t);
	return VD_OK;
}

static int vd_stl_numbers(struct vd_mesh *m, float v[3])
{
	for (int k = 0; k < 3; k++) {
		char *t;
		double d;
		int e = vd_stl_inner(m, &t);
		if (e)
			return e;
		if (!vd__parse_double(t, &d))
			return vd_fail(VD_ERR_FORMAT, "line %" PRIu64 ": "
				       "malformed number '%.40s'", m->r.lines,
				       t);
		v[k] = vd_to_f32(d);
	}
	return VD_OK;
}

/* The facet's corners go to m->verts (reset per facet) so that the polygon
 * code is shared with the indexed formats. */
int vd__stl_ascii_next(struct vd_mesh *m, int *got)
{
	char *t;
	float v[3];
	int e;
	for (;;) {
		e = vd_stl_token(m, &t);
		if (e < 0)
			return -e;
		if (e == 0) {
			/* A missing endsolid loses nothing; tolerate it. */
			*got = 0;
			return VD_OK;
		}
		if (!m->stl_in_solid) {
			if (strcasecmp(t, "solid"))
				return vd_fail(VD_ERR_FORMAT, "line %" PRIu64
					       ": expected 'solid', found "
					       "'%.40s'", m->r.lines, t);
			m->stl_in_solid = 1;
			m->stl_rest = NULL; /* the solid's name */
			continue;
		}
		if (!strcasecmp(t, "endsolid")) {
			m->stl_in_solid = 0;
			m->stl_rest = NULL;
			continue;
		}
		if (strcasecmp(t, "facet"))
			return vd_fail(VD_ERR_FORMAT, "line %" PRIu64 ": "
				       "expected 'facet' or 'endsolid', found "
				       "'%.40s'", m->r.lines, t);
		m->poly_face++;
		m->poly_line = m->r.lines;
		if ((e = vd_stl_expect(m, "normal")) ||
		    (e = vd_stl_numbers(m, v)) ||
		    (e = vd_stl_expect(m, "outer")) ||
		    (e = vd_stl_expect(m, "loop")))
			return e;
		m->nverts = 0;
		m->nonfinite = 0;
		m->poly_n = 0;
		for (;;) {
			if ((e = vd_stl_inner(m, &t)))
				return e;
			if (!strcasecmp(t, "endloop"))
				break;
			if (strcasecmp(t, "vertex"))
				return vd_fail(VD_ERR_FORMAT, "line %" PRIu64
					       ": expected 'vertex' or "
					       "'endloop', found '%.40s'",
					       m->r.lines, t);
			if (m->poly_n == MESH_MAX_CORNERS)
				return vd_fail(VD_ERR_FORMAT, "line %" PRIu64
					       ": facet %" PRIu64 " has more "
					       "than %d vertices", m->r.lines,
					       m->poly_face, MESH_MAX_CORNERS);
			if ((e = vd_stl_numbers(m, v)) ||
			    (e = vd__mesh_push_vertex(m, v)) ||
			    (e = vd__mesh_grow_poly(m, m->poly_n + 1)))
				return e;
			m->poly[m->poly_n] = (uint32_t)m->poly_n;
			m->poly_n++;
		}
		if ((e = vd_stl_expect(m, "endfacet")))
			return e;
		*got = 1;
		return VD_OK;
	}
}

static float vd_ld_f32le(const unsigned char *p)
{
	uint32_t u = (uint32_t)vd_ld(p, 4, 0);
	float f;
	memcpy(&f, &u, 4);
	return f;
}

int vd__stl_bin_read(struct vd_mesh *m, struct vd_triangle *buf,
		    size_t cap, size_t *n)
{
	struct vd_rd *r = &m->r;
	size_t k = 0;
	while (k < cap && m->faces_done < m->stl_count) {
		int e = vd__rd_need(r, 50);
		if (e) {
			*n = k;
			return e == VD_ERR_TRUNCATED ? vd_fail(e,
				"file ends inside triangle %" PRIu64 " of %"
				PRIu64, m->faces_done + 1, m->stl_count) : e;
		}
		/* A record: normal (ignored; we trust the corners), three
		 * corners, attribute word; all little-endian float32. */
		const unsigned char *p = r->buf + r->pos + 12;
		struct vd_triangle *t = &buf[k];
		for (int c = 0; c < 3; c++)
			for (int a = 0; a < 3; a++)
				t->v[c][a] = vd_ld_f32le(p + 12 * c + 4 * a);
		for (int c = 0; c < 3; c++)
			if (!isfinite(t->v[c][0]) || !isfinite(t->v[c][1]) ||
			    !isfinite(t->v[c][2])) {
				*n = k;
				return vd_fail(VD_ERR_RANGE, "triangle %" PRIu64
					       " has a non-finite vertex (%g %g"
					       " %g)", m->faces_done + 1,
					       t->v[c][0], t->v[c][1],
					       t->v[c][2]);
			}
		r->pos += 50;
		m->faces_done++;
		k++;
	}
	*n = k;
	return VD_OK;
}

int vd__stl_size_error(struct vd_mesh *m, const unsigned char *head,
		      size_t hn)
{
	if (m->file_bytes < 84)
		return vd_fail(VD_ERR_TRUNCATED, "binary STL needs at least 84 "
			       "bytes, the file has %" PRIu64, m->file_bytes);
	uint64_t count = vd_ld(head + 80, 4, 0), want = 84 + 50 * count;
	return vd_fail(want > m->file_bytes ? VD_ERR_TRUNCATED
		       : VD_ERR_TRAILING, "binary STL declares %" PRIu64
		       " triangles (%" PRIu64 " bytes) but the file has %"
		       PRIu64 " bytes", count, want, m->file_bytes);
}
