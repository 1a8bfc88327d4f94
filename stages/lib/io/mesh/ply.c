/* ply.c - PLY, ASCII and binary in either byte order: the header, the
 * vertex element loaded at open, the faces streamed. */
#include "io/mesh/mesh_internal.h"

#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum vd_ply_type {
	PLY_NONE, PLY_I8, PLY_U8, PLY_I16, PLY_U16, PLY_I32, PLY_U32,
	PLY_F32, PLY_F64
};

static const unsigned char vd_ply_size[] = {0, 1, 1, 2, 2, 4, 4, 4, 8};

static const struct {
	const char *name;
	unsigned char type;
} vd_ply_types[] = {
	{"char", PLY_I8},    {"int8", PLY_I8},     {"uchar", PLY_U8},
	{"uint8", PLY_U8},   {"short", PLY_I16},   {"int16", PLY_I16},
	{"ushort", PLY_U16}, {"uint16", PLY_U16},  {"int", PLY_I32},
	{"int32", PLY_I32},  {"uint", PLY_U32},    {"uint32", PLY_U32},
	{"float", PLY_F32},  {"float32", PLY_F32}, {"double", PLY_F64},
	{"float64", PLY_F64},
};

static int vd_ply_type_of(const char *name)
{
	for (size_t i = 0; i < sizeof vd_ply_types / sizeof *vd_ply_types; i++)
		if (!strcmp(name, vd_ply_types[i].name))
			return vd_ply_types[i].type;
	return PLY_NONE;
}

/* Integer types only (checked in the header), so no rounding. */
static int64_t vd_ply_decode_int(const unsigned char *p, int type, int be)
{
	switch (type) {
	case PLY_I8: return (int8_t)p[0];
	case PLY_U8: return p[0];
	case PLY_I16: return (int16_t)(uint16_t)vd_ld(p, 2, be);
	case PLY_U16: return (uint16_t)vd_ld(p, 2, be);
	case PLY_I32: return (int32_t)(uint32_t)vd_ld(p, 4, be);
	case PLY_U32: return (uint32_t)vd_ld(p, 4, be);
	}
	return 0;
}

static double vd_ply_decode(const unsigned char *p, int type, int be)
{
	if (type == PLY_F32) {
		uint32_t u = (uint32_t)vd_ld(p, 4, be);
		float f;
		memcpy(&f, &u, 4);
		return f;
	}
	if (type == PLY_F64) {
		uint64_t u = vd_ld(p, 8, be);
		double d;
		memcpy(&d, &u, 8);
		return d;
	}
	return (double)vd_ply_decode_int(p, type, be);
}

/* Checks a raw index of a PLY face and stores it. */
static int vd_ply_corner(struct vd_mesh *m, int64_t idx)
{
	if (idx < 0 || (uint64_t)idx >= m->nverts) {
		char w[48];
		return vd_fail(VD_ERR_RANGE,
			       "%sface %" PRIu64 ": vertex index %" PRId64
			       " out of range (the file has %" PRIu64
			       " vertices)", vd__mesh_where(m, w, sizeof w),
			       m->poly_face, idx, m->nverts);
	}
	m->poly[m->poly_n++] = (uint32_t)idx;
	return VD_OK;
}

static int vd_ply_bad_count(struct vd_mesh *m, int64_t n)
{
	char w[48];
	return vd_fail(VD_ERR_FORMAT,
		       "%sface %" PRIu64 ": %" PRId64 " corners (at most %d "
		       "accepted)", vd__mesh_where(m, w, sizeof w),
		       m->poly_face, n, MESH_MAX_CORNERS);
}

static int vd_ply_truncated(struct vd_mesh *m, int e, const char *what,
			    uint64_t i, uint64_t n)
{
	if (e != VD_ERR_TRUNCATED)
		return e;
	return vd_fail(VD_ERR_TRUNCATED, "file ends inside %s %" PRIu64
		       " of %" PRIu64 " (at byte %" PRIu64 ")", what, i + 1, n,
		       m->r.off + m->r.len);
}

/* Skips or decodes one binary item of element e. With `v` (the vertex
 * element), stores property i in v[m->vslot[i]] (x y z, then r g b when
 * colours are read: v has 6 floats); with `face`, collects the corner list
 * in m->poly. */
static int vd_ply_bin_item(struct vd_mesh *m, const struct vd_ply_elem *el,
			   float *v, int face)
{
	int be = m->kind == MESH_PLY_BE, e;
	struct vd_rd *r = &m->r;
	if (el->fixed && !face) {
		if ((e = vd__rd_need(r, el->min_bytes)))
			return e;
		if (v) {
			const unsigned char *p = r->buf + r->pos;
			for (size_t i = 0; i < el->nprops; i++) {
				int k = m->vslot[i], t = el->props[i].type;
				if (k >= 0 && t == PLY_F32 && !be)
					memcpy(&v[k], p, 4); /* as it is */
				else if (k >= 0)
					v[k] = vd_to_f32(vd_ply_decode(p, t, be));
				p += vd_ply_size[el->props[i].type];
			}
		}
		r->pos += el->min_bytes;
		return VD_OK;
	}
	/* the usual face, alone in its element: a byte 3 and three 32-bit
	 * indices in range, taken in one go (else the walk below, which
	 * reads the same bytes and says what is wrong) */
	if (face && !be && el->nprops == 1 && m->ilist == 0 &&
	    (el->props[0].count == PLY_U8 || el->props[0].count == PLY_I8) &&
	    (el->props[0].type == PLY_I32 || el->props[0].type == PLY_U32) &&
	    m->poly_cap >= 3 && r->len - r->pos >= 13 &&
	    r->buf[r->pos] == 3) {
		uint32_t u[3];
		memcpy(u, r->buf + r->pos + 1, sizeof u);
		uint32_t top = el->props[0].type == PLY_I32 ? INT32_MAX
							     : UINT32_MAX;
		int ok = 1;
		for (int k = 0; k < 3; k++)
			ok &= u[k] <= top && u[k] < m->nverts;
		if (ok) {
			memcpy(m->poly, u, sizeof u);
			m->poly_n = 3;
			r->pos += 13;
			return VD_OK;
		}
	}
	for (size_t i = 0; i < el->nprops; i++) {
		const struct vd_ply_prop *pr = &el->props[i];
		size_t size = vd_ply_size[pr->type];
		if (pr->count == PLY_NONE) {
			if ((e = vd__rd_need(r, size)))
				return e;
			if (v && m->vslot[i] >= 0)
				v[m->vslot[i]] = vd_to_f32(vd_ply_decode(
						r->buf + r->pos, pr->type, be));
			r->pos += size;
			continue;
		}
		if ((e = vd__rd_need(r, vd_ply_size[pr->count])))
			return e;
		int64_t n = vd_ply_decode_int(r->buf + r->pos, pr->count, be);
		r->pos += vd_ply_size[pr->count];
		if (face && (int)i == m->ilist) {
			if (n < 0 || n > MESH_MAX_CORNERS)
				return vd_ply_bad_count(m, n);
			if ((e = vd__mesh_grow_poly(m, (size_t)n)) ||
			    (e = vd__rd_need(r, (size_t)n * size)))
				return e;
			const unsigned char *p = r->buf + r->pos;
			m->poly_n = 0;
			if (!be && (pr->type == PLY_I32 || pr->type == PLY_U32)) {
				/* the usual face list, without a decode call a
				 * corner (a sixth of reading the terrain) */
				for (int64_t j = 0; j < n; j++, p += 4) {
					uint32_t u;
					memcpy(&u, p, 4);
					int64_t idx = pr->type == PLY_I32 ?
						(int64_t)(int32_t)u : (int64_t)u;
					if (idx >= 0 && (uint64_t)idx < m->nverts)
						m->poly[m->poly_n++] = u;
					else if ((e = vd_ply_corner(m, idx)))
						return e;
				}
			} else {
				for (int64_t j = 0; j < n; j++, p += size)
					if ((e = vd_ply_corner(m,
						vd_ply_decode_int(p, pr->type, be))))
						return e;
			}
			r->pos += (size_t)n * size;
			continue;
		}
		if (n < 0)
			return vd_fail(VD_ERR_FORMAT,
				       "element '%s': negative list count "
				       "%" PRId64, el->name, n);
		if ((e = vd__rd_skip(r, (uint64_t)n * size)))
			return e;
	}
	return VD_OK;
}

/* The same for one ASCII line. */
static int vd_ply_ascii_item(struct vd_mesh *m, const struct vd_ply_elem *el,
			     float *v, int face, uint64_t index)
{
	char *s;
	size_t len;
	int e;
	do {
		e = vd__rd_line(&m->r, &s, &len, 0);
		if (e < 0)
			return -e;
		if (e == 0)
			return vd_fail(VD_ERR_TRUNCATED,
				       "file ends after %" PRIu64 " of %" PRIu64
				       " items of element '%s' (line %" PRIu64
				       ")", index, el->count, el->name,
				       m->r.lines);
		if (strlen(s) != len)
			return vd_fail(VD_ERR_FORMAT, "line %" PRIu64 ": NUL "
				       "byte in an ASCII PLY body", m->r.lines);
		s = (char *)vd_skip_space(s);
	} while (*s == 0);
	m->poly_line = m->r.lines;
	const char *p = s;
	for (size_t i = 0; i < el->nprops; i++) {
		const struct vd_ply_prop *pr = &el->props[i];
		p = vd_skip_space(p);
		if (*p == 0)
			return vd_fail(VD_ERR_FORMAT,
				       "line %" PRIu64 ": %s %" PRIu64
				       " ends before property '%s'", m->r.lines,
				       el->name, index + 1, pr->name);
		const char *t = p;
		if (pr->count == PLY_NONE) {
			double d;
			if (!(p = vd__parse_double(t, &d)))
				goto bad;
			if (v && m->vslot[i] >= 0)
				v[m->vslot[i]] = vd_to_f32(d);
			continue;
		}
		int64_t n;
		if (!(p = vd__parse_int(t, &n)) || !vd_is_end(*p))
			goto bad;
		int corners = face && (int)i == m->ilist;
		if (corners) {
			if (n < 0 || n > MESH_MAX_CORNERS)
				return vd_ply_bad_count(m, n);
			if ((e = vd__mesh_grow_poly(m, (size_t)n)))
				return e;
			m->poly_n = 0;
		} else if (n < 0) {
			return vd_fail(VD_ERR_FORMAT,
				       "line %" PRIu64 ": negative list count "
				       "%" PRId64, m->r.lines, n);
		}
		for (int64_t j = 0; j < n; j++) {
			p = vd_skip_space(p);
			t = p;
			if (*p == 0)
				return vd_fail(VD_ERR_FORMAT,
					"line %" PRIu64 ": list '%s' ends after "
					"%" PRId64 " of %" PRId64 " items",
					m->r.lines, pr->name, j, n);
			if (corners) {
				int64_t idx;
				if (!(p = vd__parse_int(t, &idx)) ||
				    !vd_is_end(*p))
					goto bad;
				if ((e = vd_ply_corner(m, idx)))
					return e;
			} else {
				double d;
				if (!(p = vd__parse_double(t, &d)))
					goto bad;
			}
		}
		continue;
	bad:
		return vd_fail(VD_ERR_FORMAT,
			       "line %" PRIu64 ": malformed number '%.*s' for "
			       "property '%s'", m->r.lines,
			       (int)(vd_token_end(t) - t > 40 ? 40 :
				     vd_token_end(t) - t), t, pr->name);
	}
	p = vd_skip_space(p);
	if (*p != 0)
		return vd_fail(VD_ERR_FORMAT,
			       "line %" PRIu64 ": unexpected '%.*s' after the "
			       "%zu properties of element '%s'", m->r.lines,
			       (int)(vd_token_end(p) - p > 40 ? 40 :
				     vd_token_end(p) - p), p, el->nprops,
			       el->name);
	return VD_OK;
}

static int vd_ply_item(struct vd_mesh *m, const struct vd_ply_elem *el,
		       float *v, int face, uint64_t index)
{
	if (m->kind == MESH_PLY_ASCII)
		return vd_ply_ascii_item(m, el, v, face, index);
	int e = vd_ply_bin_item(m, el, v, face);
	return e ? vd_ply_truncated(m, e, el->name, index, el->count) : VD_OK;
}

static int vd_ply_add_elem(struct vd_mesh *m, const char *name,
			   uint64_t count)
{
	struct vd_ply_elem *p =
		realloc(m->elems, (m->nelems + 1) * sizeof *p);
	if (!p)
		return vd_fail(VD_ERR_NOMEM, "PLY header");
	m->elems = p;
	struct vd_ply_elem *el = &m->elems[m->nelems++];
	memset(el, 0, sizeof *el);
	snprintf(el->name, sizeof el->name, "%s", name);
	el->count = count;
	el->fixed = 1;
	return VD_OK;
}

static int vd_ply_add_prop(struct vd_mesh *m, const char *name, int type,
			   int count)
{
	struct vd_ply_elem *el = &m->elems[m->nelems - 1];
	if (el->nprops == el->cap) {
		size_t cap = el->cap ? el->cap * 2 : 8;
		struct vd_ply_prop *p = realloc(el->props, cap * sizeof *p);
		if (!p)
			return vd_fail(VD_ERR_NOMEM, "PLY header");
		el->props = p;
		el->cap = cap;
	}
	struct vd_ply_prop *pr = &el->props[el->nprops++];
	snprintf(pr->name, sizeof pr->name, "%s", name);
	pr->type = (unsigned char)type;
	pr->count = (unsigned char)count;
	if (count != PLY_NONE) {
		el->fixed = 0;
		el->min_bytes += vd_ply_size[count];
	} else {
		el->min_bytes += vd_ply_size[type];
	}
	return VD_OK;
}

/* Splits s in place at spaces into at most max tokens; returns how many
 * there were (max + 1 means more). */
static int vd_split(char *s, char **tok, int max)
{
	int n = 0;
	for (;;) {
		while (vd_is_space(*s))
			*s++ = 0;
		if (!*s)
			return n;
		if (n == max)
			return n + 1;
		tok[n++] = s;
		while (*s && !vd_is_space(*s))
			s++;
	}
}

static int vd_ply_header(struct vd_mesh *m)
{
	char *s, *tok[8];
	size_t len;
	int e, have_format = 0;
	for (;;) {
		e = vd__rd_line(&m->r, &s, &len, 0);
		if (e < 0)
			return -e;
		if (e == 0)
			return vd_fail(VD_ERR_TRUNCATED,
				       "PLY header ends at byte %" PRIu64
				       " (line %" PRIu64 ") without end_header",
				       m->file_bytes, m->r.lines);
		uint64_t ln = m->r.lines;
		for (size_t i = 0; i < len; i++)
			if (s[i] == 0 || (unsigned char)s[i] >= 0x7f ||
			    ((unsigned char)s[i] < 0x20 && !vd_is_space(s[i])))
				return vd_fail(VD_ERR_FORMAT,
					"line %" PRIu64 ": binary bytes in the "
					"PLY header (end_header missing?)", ln);
		/* A header line cut by the end of the file says nothing
		 * reliable (a cut keyword, a cut version number). */
		if (m->r.cut && strncmp(s, "end_header", 10))
			return vd_fail(VD_ERR_TRUNCATED,
				       "PLY header ends at byte %" PRIu64
				       " (line %" PRIu64 ") without end_header",
				       m->file_bytes, m->r.lines);
		if (ln == 1) /* "ply", checked by the detection */
			continue;
		int n = vd_split(s, tok, 8);
		if (n == 0)
			continue;
		if (!strcmp(tok[0], "comment") || !strcmp(tok[0], "obj_info"))
			continue;
		if (!strcmp(tok[0], "end_header"))
			break;
		if (!strcmp(tok[0], "format")) {
			if (n != 3)
				return vd_fail(VD_ERR_FORMAT,
					"line %" PRIu64 ": expected 'format "
					"<type> 1.0'", ln);
			if (!strcmp(tok[1], "ascii"))
				m->kind = MESH_PLY_ASCII;
			else if (!strcmp(tok[1], "binary_little_endian"))
				m->kind = MESH_PLY_LE;
			else if (!strcmp(tok[1], "binary_big_endian"))
				m->kind = MESH_PLY_BE;
			else
				return vd_fail(VD_ERR_UNSUPPORTED,
					"line %" PRIu64 ": unknown PLY format "
					"'%.40s'", ln, tok[1]);
			if (strcmp(tok[2], "1.0") && strcmp(tok[2], "1"))
				return vd_fail(VD_ERR_UNSUPPORTED,
					"line %" PRIu64 ": PLY version '%.20s' "
					"(only 1.0 is known)", ln, tok[2]);
			have_format = 1;
			continue;
		}
		if (!strcmp(tok[0], "element")) {
			int64_t count;
			const char *p;
			if (n != 3 || !(p = vd__parse_int(tok[2], &count)) ||
			    *p || count < 0)
				return vd_fail(VD_ERR_FORMAT,
					"line %" PRIu64 ": expected 'element "
					"<name> <count>'", ln);
			if ((e = vd_ply_add_elem(m, tok[1], (uint64_t)count)))
				return e;
			continue;
		}
		if (!strcmp(tok[0], "property")) {
			if (m->nelems == 0)
				return vd_fail(VD_ERR_FORMAT,
					"line %" PRIu64 ": property before "
					"any element", ln);
			int list = n >= 2 && !strcmp(tok[1], "list");
			if (n != (list ? 5 : 3))
				return vd_fail(VD_ERR_FORMAT,
					"line %" PRIu64 ": expected 'property "
					"<type> <name>' or 'property list "
					"<count type> <type> <name>'", ln);
			int count = PLY_NONE, type;
			for (int i = 1 + list; i < n - 1; i++)
				if (vd_ply_type_of(tok[i]) == PLY_NONE)
					return vd_fail(VD_ERR_FORMAT,
						"line %" PRIu64 ": unknown PLY "
						"type '%.40s'", ln, tok[i]);
			if (list) {
				count = vd_ply_type_of(tok[2]);
				if (count >= PLY_F32)
					return vd_fail(VD_ERR_FORMAT,
						"line %" PRIu64 ": list count "
						"type '%s' is not an integer",
						ln, tok[2]);
			}
			type = vd_ply_type_of(tok[n - 2]);
			if ((e = vd_ply_add_prop(m, tok[n - 1], type, count)))
				return e;
			continue;
		}
		return vd_fail(VD_ERR_FORMAT,
			       "line %" PRIu64 ": unknown PLY header keyword "
			       "'%.40s'", ln, tok[0]);
	}
	if (!have_format)
		return vd_fail(VD_ERR_FORMAT, "PLY header has no format line");
	return VD_OK;
}

/* With colours: finds the vertex colour properties (red green blue, or
 * diffuse_red ...), refuses ones that are lists, and builds m->vslot, the
 * property -> float slot table the item readers use (also without
 * colours: 0-2 for x y z). */
static int vd_ply_colour_layout(struct vd_mesh *m,
				const struct vd_ply_elem *v)
{
	static const char *const names[2][3] = {
		{"red", "green", "blue"},
		{"diffuse_red", "diffuse_green", "diffuse_blue"}};
	m->vslot = malloc(v->nprops ? v->nprops : 1);
	if (!m->vslot)
		return vd_fail(VD_ERR_NOMEM, "PLY header");
	for (size_t i = 0; i < v->nprops; i++)
		m->vslot[i] = (int)i == m->ix ? 0 : (int)i == m->iy ? 1
			: (int)i == m->iz ? 2 : -1;
	m->icol[0] = m->icol[1] = m->icol[2] = -1;
	if (!m->col_on)
		return VD_OK;
	for (int set = 0; set < 2; set++)
		for (size_t i = 0; i < v->nprops; i++)
			for (int c = 0; c < 3; c++) {
				if (strcmp(v->props[i].name, names[set][c]) ||
				    m->icol[c] >= 0)
					continue;
				if (v->props[i].count != PLY_NONE)
					return vd_fail(VD_ERR_FORMAT, "PLY "
						"vertex colour property '%s' is "
						"a list (a colour is one "
						"number)", v->props[i].name);
				m->icol[c] = (int)i;
			}
	if (m->icol[0] < 0 || m->icol[1] < 0 || m->icol[2] < 0) {
		m->icol[0] = m->icol[1] = m->icol[2] = -1;
		return VD_OK; /* no colours (a lone 'red' is not one) */
	}
	for (int c = 0; c < 3; c++)
		m->vslot[m->icol[c]] = (signed char)(3 + c);
	m->vfloats = 4;
	m->col_seen = 1;
	return VD_OK;
}

/* A PLY colour value of `type` as an sRGB byte: integers as they are
 * (ushort scaled from 0..65535), floats from 0..1; clamped, NaN 0. */
static uint8_t vd_ply_colour_byte(float x, int type)
{
	double d = x;
	if (type == PLY_U16 || type == PLY_I16)
		d = d * 255.0 / 65535.0;
	else if (type == PLY_F32 || type == PLY_F64)
		d *= 255.0;
	if (!(d > 0))
		return 0;
	return d >= 255 ? 255 : (uint8_t)(d + 0.5);
}

/* Finds the vertex and face elements and refuses what we cannot stream. */
static int vd_ply_layout(struct vd_mesh *m)
{
	m->vert_elem = m->face_elem = m->nelems;
	m->ix = m->iy = m->iz = m->ilist = -1;
	for (size_t i = 0; i < m->nelems; i++) {
		/* Items of nothing take no bytes: a huge count would spin
		 * without ever reaching the end of the file. */
		if (m->elems[i].count > 0 && m->elems[i].nprops == 0)
			return vd_fail(VD_ERR_FORMAT, "PLY element '%s' has %"
				       PRIu64 " items but no properties",
				       m->elems[i].name, m->elems[i].count);
		if (!strcmp(m->elems[i].name, "vertex") &&
		    m->vert_elem == m->nelems)
			m->vert_elem = i;
		if (!strcmp(m->elems[i].name, "face") &&
		    m->face_elem == m->nelems)
			m->face_elem = i;
	}
	if (m->face_elem < m->nelems) {
		const struct vd_ply_elem *f = &m->elems[m->face_elem];
		for (size_t i = 0; i < f->nprops; i++)
			if (!strcmp(f->props[i].name, "vertex_indices") ||
			    !strcmp(f->props[i].name, "vertex_index"))
				m->ilist = (int)i;
		if (m->ilist < 0)
			return vd_fail(VD_ERR_FORMAT, "PLY element 'face' has "
				       "no vertex_indices property");
		const struct vd_ply_prop *p = &f->props[m->ilist];
		if (p->count == PLY_NONE || p->type >= PLY_F32)
			return vd_fail(VD_ERR_FORMAT, "PLY face property '%s' "
				       "must be a list of integers", p->name);
		if (m->vert_elem == m->nelems)
			return vd_fail(VD_ERR_FORMAT, "PLY file has faces but "
				       "no element 'vertex'");
		if (m->face_elem < m->vert_elem)
			return vd_fail(VD_ERR_UNSUPPORTED, "PLY element 'face' "
				       "comes before element 'vertex'");
	}
	if (m->vert_elem < m->nelems) {
		const struct vd_ply_elem *v = &m->elems[m->vert_elem];
		for (size_t i = 0; i < v->nprops; i++) {
			int *slot = !strcmp(v->props[i].name, "x") ? &m->ix
				: !strcmp(v->props[i].name, "y") ? &m->iy
				: !strcmp(v->props[i].name, "z") ? &m->iz
				: NULL;
			if (!slot || *slot >= 0)
				continue;
			if (v->props[i].count != PLY_NONE)
				return vd_fail(VD_ERR_FORMAT, "PLY vertex "
					"property '%s' is a list",
					v->props[i].name);
			*slot = (int)i;
		}
		if (m->ix < 0 || m->iy < 0 || m->iz < 0)
			return vd_fail(VD_ERR_FORMAT, "PLY element 'vertex' "
				       "lacks property %s",
				       m->ix < 0 ? "x" : m->iy < 0 ? "y" : "z");
		int e = vd_ply_colour_layout(m, v);
		if (e)
			return e;
		if (v->count > UINT32_MAX)
			return vd_fail(VD_ERR_RANGE, "PLY file declares %"
				       PRIu64 " vertices (at most %" PRIu32
				       " supported)", v->count, UINT32_MAX);
	}
	/* Every item takes at least min_bytes (binary) or two characters per
	 * property (text), so a count the rest of the file cannot hold is
	 * caught here, before anything is allocated for it. */
	size_t last = m->face_elem < m->nelems ? m->face_elem
		: m->vert_elem < m->nelems ? m->vert_elem : 0;
	uint64_t after = m->file_bytes - (m->r.off + m->r.pos), need = 0;
	/* The last text line may lack its newline. */
	uint64_t left = after + (m->kind == MESH_PLY_ASCII);
	for (size_t i = 0; i < m->nelems && i <= last; i++) {
		const struct vd_ply_elem *el = &m->elems[i];
		uint64_t per = m->kind == MESH_PLY_ASCII ? 2 * el->nprops
			: el->min_bytes;
		if (per && el->count > (left - need) / per)
			return vd_fail(VD_ERR_TRUNCATED,
				"PLY header declares %" PRIu64 " items of "
				"element '%s' (at least %" PRIu64 " bytes each)"
				" but only %" PRIu64 " of the %" PRIu64 " bytes "
				"after the header are left for them", el->count,
				el->name, per, need > after ? 0 : after - need,
				after);
		need += el->count * per;
	}
	return VD_OK;
}

int vd__ply_open(struct vd_mesh *m)
{
	int e;
	if ((e = vd_ply_header(m)) || (e = vd_ply_layout(m)))
		return e;
	if (m->vert_elem == m->nelems) {
		m->done = 1;
		return VD_OK;
	}
	const struct vd_ply_elem *ve = &m->elems[m->vert_elem];
	size_t end = m->face_elem < m->nelems ? m->face_elem : m->vert_elem + 1;
	for (size_t i = 0; i < end; i++) {
		const struct vd_ply_elem *el = &m->elems[i];
		if (i != m->vert_elem) {
			for (uint64_t j = 0; j < el->count; j++)
				if ((e = vd_ply_item(m, el, NULL, 0, j)))
					return e;
			continue;
		}
		uint64_t vbytes = 4 * (uint64_t)m->vfloats;
		int spill = m->verts_limit && ve->count * vbytes > m->verts_limit;
		if (spill && vd__mesh_can_spill(m)) {
			/* the records go to the spill (vd__mesh_push_vertex_rgb) */
			if ((e = vd__mesh_spill_open(m)))
				return e;
		} else if (spill)
			return vd_fail(VD_ERR_BUDGET, "%" PRIu64 " vertices need "
				       "%" PRIu64 " KiB in memory, more than the "
				       "vertex share (%" PRIu64 " KiB, half) of "
				       "the memory budget", ve->count,
				       (ve->count * vbytes >> 10) + 1,
				       m->verts_limit >> 10);
		else {
			m->verts = malloc(ve->count
					  ? (size_t)(ve->count * vbytes) : 16);
			if (!m->verts)
				return vd_fail(VD_ERR_NOMEM, "%" PRIu64
					       " vertices", ve->count);
			m->verts_cap = ve->count;
		}
		m->stats.vertices = ve->count;
		int col = m->vfloats == 4;
		/* the usual binary record, fixed size with float x y z and
		 * no colours read: the floats are copied from their offsets,
		 * without vd_ply_bin_item's walk over every property (most
		 * of reading the terrain's 1.2M vertices) */
		size_t off[3], at = 0;
		int fast = m->kind == MESH_PLY_LE && ve->fixed && !col;
		for (size_t q = 0; fast && q < ve->nprops; q++) {
			int k = m->vslot[q];
			if (k >= 0 && ve->props[q].type != PLY_F32)
				fast = 0;
			else if (k >= 0)
				off[k] = at;
			at += vd_ply_size[ve->props[q].type];
		}
		for (uint64_t j = 0; fast && j < ve->count; j++) {
			float v[3];
			struct vd_rd *r = &m->r;
			if ((e = vd__rd_need(r, ve->min_bytes)))
				return vd_ply_truncated(m, e, ve->name, j,
							ve->count);
			const unsigned char *p = r->buf + r->pos;
			memcpy(&v[0], p + off[0], 4);
			memcpy(&v[1], p + off[1], 4);
			memcpy(&v[2], p + off[2], 4);
			r->pos += ve->min_bytes;
			if ((e = vd__mesh_push_vertex_rgb(m, v, NULL)))
				return e;
		}
		for (uint64_t j = 0; !fast && j < ve->count; j++) {
			float v[6];
			uint8_t rgb[3];
			if ((e = vd_ply_item(m, ve, v, 0, j)))
				return e;
			if (col)
				for (int c = 0; c < 3; c++)
					rgb[c] = vd_ply_colour_byte(v[3 + c],
						ve->props[m->icol[c]].type);
			if ((e = vd__mesh_push_vertex_rgb(m, v,
							 col ? rgb : NULL)))
				return e;
		}
	}
	m->body_off = m->r.off + m->r.pos;
	m->body_lines = m->r.lines;
	if (m->face_elem == m->nelems)
		m->done = 1;
	return VD_OK;
}

/* Reads the next face into m->poly; *got = 0 at the end. */
int vd__ply_next(struct vd_mesh *m, int *got)
{
	const struct vd_ply_elem *f = &m->elems[m->face_elem];
	if (m->faces_done == f->count) {
		/* Elements after the faces carry nothing we use, but walking
		 * them is how a file cut inside them is noticed. */
		for (size_t i = m->face_elem + 1; i < m->nelems; i++)
			for (uint64_t j = 0; j < m->elems[i].count; j++) {
				int e = vd_ply_item(m, &m->elems[i], NULL, 0,
						    j);
				if (e)
					return e;
			}
		*got = 0;
		return VD_OK;
	}
	m->poly_face = ++m->faces_done;
	m->poly_n = 0;
	int e = vd_ply_item(m, f, NULL, 1, m->faces_done - 1);
	if (e)
		return e;
	*got = 1;
	return VD_OK;
}
