/* ac3d.c - AC3D, FlightGear's model format (and AC3D's own): text, a
 * header line "AC3Db" (the letter is the version), MATERIAL lines, then
 * objects. An object is "OBJECT <type>", optional attribute lines (name,
 * data, texture, rot, loc, ...), "numvert N" and N vertex lines, "numsurf
 * N" and N surfaces, and last "kids N" followed by its N child objects.
 *
 * Decisions worth knowing:
 * - A surface indexes its own object's vertices only, so one object's
 *   vertices are in memory at a time: memory is bounded by the largest
 *   object, not the model; an object over the vertex limit sends the
 *   whole file to the spill (see mesh_internal.h). They are transformed
 *   to world coordinates as they are read.
 * - Transforms follow OpenSceneGraph's loader, which is what FlightGear
 *   renders with: an object's `rot` r0..r8 is a row-major matrix applied
 *   to column vectors (x' = r0 x + r1 y + r2 z), then its `loc` is added,
 *   and the result goes through the parent's transform, up to the root.
 *   (Some tools read rot transposed; every FlightGear model we know has
 *   identity rotations, so the choice only matters for hand-made files.)
 * - Surface types (flags & 0xF): 0 polygon (fan-triangulated like every
 *   other format), 1 closed line and 2 line (no area: dropped and counted
 *   with the short faces), 4 triangle strip (written by AC3D's .acc
 *   variant). Anything else is refused.
 * - Attribute lines we do not need (texture, texrep, texoff, crease, url,
 *   subdiv, shader, hidden, locked, folded, and future ones) are skipped
 *   if they start with a word, so newer AC3D versions still load; a line
 *   that does not start with a word where a keyword is due is an error,
 *   which is how a wrong numvert or refs count is caught. Extra numbers
 *   on vertex lines (normals, AC3D 8) and ref lines (more UV sets) are
 *   ignored.
 * - "data N" is followed by N raw bytes, skipped by count (they may hold
 *   newlines or keywords), then the rest of that line.
 * - A parse error on the last line of a file that lacks its newline is
 *   reported as truncation: a cut file is the likely cause. */
#include "io/mesh/mesh_internal.h"

#include <errno.h>
#include <inttypes.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

/* Deeper nesting is taken as corruption; each level costs ~150 bytes. */
#define AC_MAX_DEPTH 10000

static const double vd_ac_identity[12] = {1, 0, 0, 0, 1, 0, 0, 0, 1,
					  0, 0, 0};

/* Fails with VD_ERR_FORMAT, or VD_ERR_TRUNCATED when the current line is
 * the file's cut last line. */
static int vd_ac_fail(const struct vd_mesh *m, const char *fmt, ...)
	__attribute__((format(printf, 2, 3)));

static int vd_ac_fail(const struct vd_mesh *m, const char *fmt, ...)
{
	char msg[400];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(msg, sizeof msg, fmt, ap);
	va_end(ap);
	if (m->r.cut)
		return vd_fail(VD_ERR_TRUNCATED, "%s (the file ends inside "
			       "this line)", msg);
	return vd_fail(VD_ERR_FORMAT, "%s", msg);
}

static int vd_is_word_start(char c)
{
	return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_';
}

/* The next non-blank line, leading space skipped. 1, 0 at the end of the
 * file, or a negated error code as vd__rd_line. */
static int vd_ac_line(struct vd_mesh *m, char **s)
{
	for (;;) {
		char *p;
		size_t len;
		int e = vd__rd_line(&m->r, &p, &len, 0);
		if (e <= 0)
			return e;
		if (strlen(p) != len)
			return -vd_fail(VD_ERR_FORMAT, "line %" PRIu64 ": NUL "
					"byte in an AC3D file", m->r.lines);
		p = (char *)vd_skip_space(p);
		if (*p) {
			*s = p;
			return 1;
		}
	}
}

/* Parses "<count>" (the rest of a `what` line): a non-negative integer
 * and nothing after it. */
static int vd_ac_count(const struct vd_mesh *m, const char *p,
		       const char *what, uint64_t *out)
{
	const char *t = vd_skip_space(p), *q;
	int64_t v;
	if (!(q = vd__parse_int(t, &v)) || !vd_is_end(*q) ||
	    *vd_skip_space(q) || v < 0)
		return vd_ac_fail(m, "line %" PRIu64 ": expected '%s <count>', "
				  "found '%s %.40s'", m->r.lines, what, what,
				  t);
	*out = (uint64_t)v;
	return VD_OK;
}

/* Parses n numbers from p; with `more`, other tokens may follow them. */
static int vd_ac_numbers(const struct vd_mesh *m, const char *p, double *out,
			 int n, int more, const char *what)
{
	for (int i = 0; i < n; i++) {
		const char *t = vd_skip_space(p);
		if (*t == 0)
			return vd_ac_fail(m, "line %" PRIu64 ": %s has %d "
					  "numbers, needs %d", m->r.lines,
					  what, i, n);
		if (!(p = vd__parse_double(t, &out[i])))
			return vd_ac_fail(m, "line %" PRIu64 ": malformed "
					  "number '%.*s' in %s", m->r.lines,
					  vd__tok40(t), t, what);
	}
	p = vd_skip_space(p);
	if (!more && *p)
		return vd_ac_fail(m, "line %" PRIu64 ": unexpected '%.*s' "
				  "after the %d numbers of %s", m->r.lines,
				  vd__tok40(p), p, n, what);
	return VD_OK;
}

/* The current object's world transform: its parent's after its own. */
static void vd_ac_world(const struct vd_mesh *m, double w[12])
{
	const double *p = m->ac_depth ? m->ac_stack[m->ac_depth - 1].w
		: vd_ac_identity;
	const double *r = m->ac_rot, *l = m->ac_loc;
	for (int i = 0; i < 3; i++) {
		for (int j = 0; j < 3; j++)
			w[3 * i + j] = p[3 * i] * r[j] +
				       p[3 * i + 1] * r[3 + j] +
				       p[3 * i + 2] * r[6 + j];
		w[9 + i] = p[3 * i] * l[0] + p[3 * i + 1] * l[1] +
			   p[3 * i + 2] * l[2] + p[9 + i];
	}
}

/* Skips the n raw bytes of a data block, counting their newlines, then
 * the rest of the line they end on. */
static int vd_ac_skip_data(struct vd_mesh *m, uint64_t n, uint64_t line)
{
	struct vd_rd *r = &m->r;
	while (n > 0) {
		if (r->pos == r->len) {
			int f = vd__rd_fill(r);
			if (f < 0)
				return VD_ERR_IO;
			if (f == 0)
				return vd_fail(VD_ERR_TRUNCATED, "file ends "
					       "inside the data block of "
					       "object '%s' (line %" PRIu64
					       ")", m->ac_name, line);
		}
		size_t take = r->len - r->pos;
		if (take > n)
			take = (size_t)n;
		for (const unsigned char *p = r->buf + r->pos,
		     *end = p + take;
		     (p = memchr(p, '\n', (size_t)(end - p))); p++)
			r->lines++;
		r->pos += take;
		n -= take;
	}
	char *s;
	size_t len;
	int e = vd__rd_line(r, &s, &len, 0);
	return e < 0 ? -e : VD_OK;
}

static void vd_ac_begin_object(struct vd_mesh *m, const char *type)
{
	m->ac_in_object = 1;
	m->ac_seen_object = 1;
	m->ac_surf_left = 0;
	m->ac_object_line = m->r.lines;
	memcpy(m->ac_rot, vd_ac_identity, sizeof m->ac_rot);
	memset(m->ac_loc, 0, sizeof m->ac_loc);
	m->ac_tex = -1;
	m->ac_texrep[0] = m->ac_texrep[1] = 1;
	m->ac_texoff[0] = m->ac_texoff[1] = 0;
	m->nverts = 0;
	m->nonfinite = 0;
	type = vd_skip_space(type);
	snprintf(m->ac_name, sizeof m->ac_name, "%.*s at line %" PRIu64,
		 vd__tok40(type), type, m->r.lines);
}

/* "kids N" closes the object's own part. With kids it becomes the parent
 * of what follows; without, it completes, and so may its ancestors. */
static int vd_ac_kids(struct vd_mesh *m, uint64_t kids)
{
	m->ac_in_object = 0;
	if (kids > 0) {
		if (m->ac_depth == AC_MAX_DEPTH)
			return vd_fail(VD_ERR_RANGE, "line %" PRIu64 ": "
				       "objects nested deeper than %d",
				       m->r.lines, AC_MAX_DEPTH);
		if (m->ac_depth == m->ac_cap) {
			size_t cap = m->ac_cap ? m->ac_cap * 2 : 16;
			struct vd_ac_frame *p =
				realloc(m->ac_stack, cap * sizeof *p);
			if (!p)
				return vd_fail(VD_ERR_NOMEM, "%zu nested "
					       "objects", cap);
			m->ac_stack = p;
			m->ac_cap = cap;
		}
		struct vd_ac_frame *f = &m->ac_stack[m->ac_depth];
		vd_ac_world(m, f->w);
		f->kids = f->kids_left = kids;
		memcpy(f->name, m->ac_name, sizeof f->name);
		m->ac_depth++;
		return VD_OK;
	}
	while (m->ac_depth > 0 && --m->ac_stack[m->ac_depth - 1].kids_left == 0)
		m->ac_depth--;
	return VD_OK;
}

/* ---- AC3D colours */

/* A quoted (or bare) string at p into out; returns the text after it. */
static const char *vd_ac_string(const char *p, char *out, size_t cap)
{
	p = vd_skip_space(p);
	const char *e;
	if (*p == '"') {
		p++;
		e = strchr(p, '"');
		if (!e)
			e = p + strlen(p);
	} else {
		e = vd_token_end(p);
	}
	size_t n = (size_t)(e - p);
	snprintf(out, cap, "%.*s", (int)(n < cap ? n : cap - 1), p);
	return *e == '"' ? e + 1 : e;
}

/* MATERIAL "name" rgb r g b amb ... : the name and the diffuse colour. */
static int vd_ac_material(struct vd_mesh *m, const char *p)
{
	char name[256];
	p = vd_ac_string(p, name, sizeof name);
	int e = vd__mesh_add_material(m, name);
	if (e)
		return e;
	const char *q = vd__kw(vd_skip_space(p), "rgb");
	double d[3];
	if (!q || vd__numbers3(q, d) != 3)
		return vd_ac_fail(m, "line %" PRIu64 ": MATERIAL '%s' has no "
				  "'rgb r g b'", m->r.lines, name);
	for (int c = 0; c < 3; c++)
		m->mats[m->nmats - 1].rgb[c] = vd__unit_byte(d[c]);
	m->col_seen = 1;
	return VD_OK;
}

/* texture "path": relative to the .ac file; loaded now (objects name
 * textures only when their surfaces use them).
 *
 * TORCS's .acc variant gives an object up to four texture lines, each
 * with a unit word after the path: "base" (the colour texture, unit 0,
 * whose UVs are the first pair on each ref line), then "tiled" (a detail
 * map), "skids" and "shad" (skid marks and baked shadows, which only
 * darken the base when TORCS renders). Like TORCS's loader we take the
 * base (or a line without a unit word) and skip the others, which would
 * otherwise replace it; "empty_texture_no_mapping" is TORCS's name for
 * no texture. */
static int vd_ac_texture(struct vd_mesh *m, const char *p)
{
	char name[1024], unit[16];
	p = vd_ac_string(p, name, sizeof name);
	vd_ac_string(p, unit, sizeof unit);
	if (unit[0] && strcmp(unit, "base"))
		return VD_OK;
	if (!strcmp(name, "empty_texture_no_mapping"))
		name[0] = 0;
	if (!name[0])
		return VD_OK;
	char *path = vd__mesh_path(m, NULL, name);
	if (!path || (m->ac_tex = vd__mesh_tex_slot(m, path)) < 0)
		return vd_fail(VD_ERR_NOMEM, "textures");
	return vd__mesh_tex_use(m, m->ac_tex);
}

/* "mat N" of a surface. An index past the MATERIAL lines leaves the
 * surface grey, with one warning. */
static int vd_ac_mat(struct vd_mesh *m, const char *p)
{
	uint64_t n;
	int e = vd_ac_count(m, p, "mat", &n);
	if (e)
		return e;
	/* a file without MATERIAL lines has no colours: nothing to say */
	if (n < m->nmats) {
		m->poly_mat = (int)n;
	} else if (!m->warned_mat && m->nmats > 0) {
		m->warned_mat = 1;
		vd__mesh_warn(m, "line %" PRIu64 ": material %" PRIu64 " of %zu "
			     "defined; the surface is grey (further ones not "
			     "reported)", m->r.lines, n, m->nmats);
	}
	return VD_OK;
}

/* The "u v" after a ref's index, mapped by texrep and texoff (as plib and
 * OpenSceneGraph: uv * texrep + texoff). Missing: no coordinates. */
static int vd_ac_ref_uv(struct vd_mesh *m, const char *p, size_t corner)
{
	float *tc = m->poly_tc + 2 * corner;
	double d[2];
	p = vd_skip_space(p);
	if (!*p) {
		tc[0] = tc[1] = NAN;
		return VD_OK;
	}
	int e = vd_ac_numbers(m, p, d, 2, 1, "a ref's texture coordinates");
	if (e)
		return e;
	for (int k = 0; k < 2; k++) {
		double x = d[k] * m->ac_texrep[k] + m->ac_texoff[k];
		if (!isfinite(x))
			return vd_fail(VD_ERR_RANGE, "line %" PRIu64 ": texture "
				       "coordinate %g is not finite",
				       m->r.lines, x);
		tc[k] = (float)x;
	}
	return VD_OK;
}

/* Reads "numvert N"'s N vertex lines into m->verts, in world coordinates. */
static int vd_ac_vertices(struct vd_mesh *m, uint64_t count)
{
	if (count > UINT32_MAX)
		return vd_fail(VD_ERR_RANGE, "line %" PRIu64 ": object '%s' "
			       "declares %" PRIu64 " vertices (at most %" PRIu32
			       " supported)", m->r.lines, m->ac_name, count,
			       UINT32_MAX);
	double w[12];
	vd_ac_world(m, w);
	int identity = 1;
	for (int i = 0; i < 12; i++)
		identity &= w[i] == vd_ac_identity[i];
	m->nverts = 0;
	m->nonfinite = 0;
	m->ac_vbase = m->spill_nverts;
	m->stats.vertices += count;
	for (uint64_t i = 0; i < count; i++) {
		char *s;
		double d[3];
		float v[3];
		int e = vd_ac_line(m, &s);
		if (e < 0)
			return -e;
		if (e == 0)
			return vd_fail(VD_ERR_TRUNCATED, "file ends after %"
				       PRIu64 " of the %" PRIu64 " vertices of "
				       "object '%s' (line %" PRIu64 ")", i,
				       count, m->ac_name, m->r.lines);
		if ((e = vd_ac_numbers(m, s, d, 3, 1, "a vertex")))
			return e;
		/* The identity is common and kept exact, -0 included. */
		for (int k = 0; k < 3; k++)
			v[k] = vd_to_f32(identity ? d[k] :
				w[3 * k] * d[0] + w[3 * k + 1] * d[1] +
				w[3 * k + 2] * d[2] + w[9 + k]);
		if ((e = vd__mesh_push_vertex(m, v)))
			return e;
	}
	return VD_OK;
}

/* Reads one surface into m->poly (a line leaves it empty, so that it is
 * dropped and counted). */
static int vd_ac_surface(struct vd_mesh *m)
{
	char *s;
	const char *p;
	int e = vd_ac_line(m, &s);
	if (e < 0)
		return -e;
	if (e == 0)
		goto cut;
	m->poly_face++;
	m->poly_line = m->r.lines;
	m->poly_n = 0;
	if (!(p = vd__kw(s, "SURF")))
		return vd_ac_fail(m, "line %" PRIu64 ": expected 'SURF' (the "
				  "numsurf count of object '%s' says more "
				  "surfaces follow), found '%.*s'", m->r.lines,
				  m->ac_name, vd__tok40(s), s);
	const char *t = vd_skip_space(p);
	char *end;
	errno = 0;
	unsigned long flags = strtoul(t, &end, 0);
	if (end == t || !vd_is_end(*end) || *vd_skip_space(end) ||
	    errno || *t == '-')
		return vd_ac_fail(m, "line %" PRIu64 ": malformed surface "
				  "flags '%.*s'", m->r.lines, vd__tok40(t), t);
	unsigned type = (unsigned)(flags & 0xf);
	if (type != 0 && type != 1 && type != 2 && type != 4)
		return vd_ac_fail(m, "line %" PRIu64 ": surface type %u (flags "
				  "0x%lx) is none of polygon (0), closed line "
				  "(1), line (2), triangle strip (4)",
				  m->r.lines, type, flags);
	uint64_t refs;
	m->poly_mat = -1;
	for (;;) {
		if ((e = vd_ac_line(m, &s)) < 0)
			return -e;
		if (e == 0)
			goto cut;
		if ((p = vd__kw(s, "mat"))) {
			if (m->col_on && (e = vd_ac_mat(m, p)))
				return e;
			continue;
		}
		if ((p = vd__kw(s, "refs")))
			break;
		return vd_ac_fail(m, "line %" PRIu64 ": expected 'mat' or "
				  "'refs', found '%.*s'", m->r.lines,
				  vd__tok40(s), s);
	}
	if ((e = vd_ac_count(m, p, "refs", &refs)))
		return e;
	if (refs > MESH_MAX_CORNERS)
		return vd_fail(VD_ERR_FORMAT, "line %" PRIu64 ": surface with %"
			       PRIu64 " refs (at most %d accepted)",
			       m->r.lines, refs, MESH_MAX_CORNERS);
	if ((e = vd__mesh_grow_poly(m, (size_t)refs)))
		return e;
	if (m->col_on && (e = vd__mesh_grow_tc(m, (size_t)refs)))
		return e;
	for (uint64_t j = 0; j < refs; j++) {
		int64_t idx;
		if ((e = vd_ac_line(m, &s)) < 0)
			return -e;
		if (e == 0)
			goto cut;
		/* The UV pair after the index: only with colours. */
		if (!(p = vd__parse_int(s, &idx)) || !vd_is_end(*p))
			return vd_ac_fail(m, "line %" PRIu64 ": malformed "
					  "vertex index '%.*s'", m->r.lines,
					  vd__tok40(s), s);
		if (m->col_on && (e = vd_ac_ref_uv(m, p, m->poly_n)))
			return e;
		if (idx < 0 || (uint64_t)idx >= m->nverts)
			return vd_fail(VD_ERR_RANGE, "line %" PRIu64 ": "
				       "surface %" PRIu64 ": vertex index %"
				       PRId64 " out of range (object '%s' "
				       "has %" PRIu64 " vertices)", m->r.lines,
				       m->poly_face, idx, m->ac_name,
				       m->nverts);
		m->poly[m->poly_n++] = (uint32_t)idx;
	}
	m->poly_strip = type == 4;
	m->poly_has_tc = m->col_on;
	if (type == 1 || type == 2)
		m->poly_n = 0;
	return VD_OK;
cut:
	return vd_fail(VD_ERR_TRUNCATED, "file ends inside a surface of "
		       "object '%s' (line %" PRIu64 ")", m->ac_name,
		       m->r.lines);
}

static int vd_ac_eof(struct vd_mesh *m, int *got)
{
	if (m->ac_in_object)
		return vd_fail(VD_ERR_TRUNCATED, "file ends inside object '%s' "
			       "(before its kids line)", m->ac_name);
	if (m->ac_depth > 0) {
		const struct vd_ac_frame *f = &m->ac_stack[m->ac_depth - 1];
		if (!m->ac_torcs)
			return vd_fail(VD_ERR_TRUNCATED, "file ends after %"
				       PRIu64 " of the %" PRIu64 " kids of "
				       "object '%s'", f->kids - f->kids_left,
				       f->kids, f->name);
		/* TORCS's track generator declares more kids than it writes
		 * (22 of its 25 tracks), and TORCS reads to the end of the
		 * file: so do we, saying so once (every pass reads it) */
		if (!m->ac_warned_kids) {
			m->ac_warned_kids = 1;
			vd__mesh_warn(m, "the file ends after %" PRIu64 " of the %"
				     PRIu64 " kids of object '%s', between two "
				     "objects: read as complete, as TORCS does "
				     "with its .acc files (a file cut there "
				     "would look the same)",
				     f->kids - f->kids_left, f->kids, f->name);
		}
	}
	if (!m->ac_seen_object)
		return vd_fail(VD_ERR_TRUNCATED, "AC3D file without any OBJECT "
			       "(a complete one has at least the world "
			       "object)");
	*got = 0;
	return VD_OK;
}

/* Reads up to the next surface; *got = 0 at the end. */
int vd__ac_next(struct vd_mesh *m, int *got)
{
	char *s;
	const char *p;
	uint64_t n;
	int e;
	for (;;) {
		if (m->ac_surf_left > 0) {
			m->ac_surf_left--;
			*got = 1;
			return vd_ac_surface(m);
		}
		if ((e = vd_ac_line(m, &s)) < 0)
			return -e;
		if (e == 0)
			return vd_ac_eof(m, got);
		uint64_t ln = m->r.lines;
		if (!m->ac_in_object) {
			if ((p = vd__kw(s, "OBJECT"))) {
				vd_ac_begin_object(m, p);
				continue;
			}
			if (m->ac_depth > 0) {
				const struct vd_ac_frame *f =
					&m->ac_stack[m->ac_depth - 1];
				return vd_ac_fail(m, "line %" PRIu64 ": "
					"expected OBJECT (kid %" PRIu64 " of %"
					PRIu64
					" of object '%s'), found '%.*s'", ln,
					f->kids - f->kids_left + 1, f->kids,
					f->name, vd__tok40(s), s);
			}
			/* MATERIAL lines and their AC3Dc kin. */
			if (m->col_on && (p = vd__kw(s, "MATERIAL"))) {
				if ((e = vd_ac_material(m, p)))
					return e;
				continue;
			}
			if (vd_is_word_start(*s))
				continue;
			return vd_ac_fail(m, "line %" PRIu64 ": unexpected "
					  "'%.*s' outside any object", ln,
					  vd__tok40(s), s);
		}
		if ((p = vd__kw(s, "name"))) {
			p = vd_skip_space(p);
			size_t k = strlen(p);
			if (k >= 2 && p[0] == '"' && p[k - 1] == '"') {
				p++;
				k -= 2;
			}
			snprintf(m->ac_name, sizeof m->ac_name, "%.*s",
				 (int)(k > 47 ? 47 : k), p);
		} else if ((p = vd__kw(s, "data"))) {
			if ((e = vd_ac_count(m, p, "data", &n)) ||
			    (e = vd_ac_skip_data(m, n, ln)))
				return e;
		} else if ((p = vd__kw(s, "rot"))) {
			if ((e = vd_ac_numbers(m, p, m->ac_rot, 9, 0, "rot")))
				return e;
		} else if ((p = vd__kw(s, "loc"))) {
			if ((e = vd_ac_numbers(m, p, m->ac_loc, 3, 0, "loc")))
				return e;
		} else if ((p = vd__kw(s, "numvert"))) {
			if ((e = vd_ac_count(m, p, "numvert", &n)) ||
			    (e = vd_ac_vertices(m, n)))
				return e;
		} else if (m->col_on && (p = vd__kw(s, "texture"))) {
			if ((e = vd_ac_texture(m, p)))
				return e;
		} else if (m->col_on && (p = vd__kw(s, "texrep"))) {
			if ((e = vd_ac_numbers(m, p, m->ac_texrep, 2, 0,
					       "texrep")))
				return e;
		} else if (m->col_on && (p = vd__kw(s, "texoff"))) {
			if ((e = vd_ac_numbers(m, p, m->ac_texoff, 2, 0,
					       "texoff")))
				return e;
		} else if ((p = vd__kw(s, "numsurf"))) {
			if ((e = vd_ac_count(m, p, "numsurf", &n)))
				return e;
			m->ac_surf_left = n;
		} else if ((p = vd__kw(s, "kids"))) {
			if ((e = vd_ac_count(m, p, "kids", &n)) ||
			    (e = vd_ac_kids(m, n)))
				return e;
		} else if (vd__kw(s, "OBJECT")) {
			return vd_ac_fail(m, "line %" PRIu64 ": OBJECT before "
					  "the kids line of object '%s'", ln,
					  m->ac_name);
		} else if (vd__kw(s, "SURF") || vd__kw(s, "refs") ||
			   vd__kw(s, "mat")) {
			return vd_ac_fail(m, "line %" PRIu64 ": '%.*s' beyond "
					  "the numsurf count of object '%s'",
					  ln, vd__tok40(s), s, m->ac_name);
		} else if (!vd_is_word_start(*s)) {
			return vd_ac_fail(m, "line %" PRIu64 ": unexpected "
					  "'%.*s' in object '%s' (wrong "
					  "numvert or refs count?)", ln,
					  vd__tok40(s), s, m->ac_name);
		}
		/* Any other word: an attribute we do not need. */
	}
}

/* The detection saw "AC3D"; the rest of the first line is the version. */
int vd__ac_open(struct vd_mesh *m, const char *path)
{
	char *s;
	size_t len;
	m->kind = MESH_AC3D;
	m->ac_torcs = vd__has_ext(path, ".acc");
	int e = vd__rd_line(&m->r, &s, &len, 0);
	if (e < 0)
		return -e;
	m->body_off = m->r.off + m->r.pos;
	m->body_lines = m->r.lines;
	return VD_OK;
}
