/* triangles.c - how triangles leave a mesh: each reader's next polygon
 * (the dispatch by format), polygons fanned out into triangles with their
 * attributes, the spilled mesh read back, and the reading half of the API
 * (vd_mesh_read, vd_mesh_read_attr, vd_mesh_rewind). Above the readers and
 * the vertex store (store.c), which never call it. */
#include "io/mesh/mesh_internal.h"

#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Called once a polygon is complete: applies the corner-count rules and the
 * non-finite rule. Sets poly_n to 0 for a dropped face. */
static int vd_mesh_poly_done(struct vd_mesh *m)
{
	if (m->poly_n < 3) {
		m->stats.faces_dropped_short++;
		m->poly_n = 0;
		return VD_OK;
	}
	if (m->poly_n > 3)
		m->stats.polygons_split++;
	/* spilled: checked as the joined triangles come back */
	if (m->nonfinite && !m->spill && !m->spill_wanted) {
		for (size_t i = 0; i < m->poly_n; i++) {
			const float *v = vd_mesh_vert(m, m->poly[i]);
			if (!isfinite(v[0]) || !isfinite(v[1]) || !isfinite(v[2]))
				return vd__mesh_nonfinite(m, m->poly[i], v);
		}
	}
	m->poly_next = 1;
	return VD_OK;
}

/* The positions in m->poly of the corners of the next triangle of the
 * polygon. */
static void vd_mesh_fan(const struct vd_mesh *m, size_t pc[3])
{
	size_t i = m->poly_next;
	pc[0] = 0;
	pc[1] = i;
	pc[2] = i + 1;
	/* A strip's triangle i-1 is (i-1, i, i+1), every other one flipped
	 * to keep the winding. */
	if (m->poly_strip) {
		pc[0] = i - (i & 1 ? 1 : 0);
		pc[1] = i - (i & 1 ? 0 : 1);
	}
}

/* What the polygon decides of the attributes of its triangle of corners
 * pc[] (positions in m->poly): the texture and the corners' uv, and in
 * `base` the colour of a corner whose vertex has none (the material's, or
 * grey). The corners' own colours come from their vertex records
 * (vd_mesh_attr_corners), which a spilled mesh only has after the join. */
static void vd_mesh_attr_face(const struct vd_mesh *m, const size_t pc[3],
			      struct vd_tri_attr *a, uint8_t base[3])
{
	memset(a, 0, sizeof *a);
	a->texture = -1;
	const struct vd_material *mt =
		m->poly_mat >= 0 && (size_t)m->poly_mat < m->nmats
			? &m->mats[m->poly_mat] : NULL;
	int tex = m->kind == MESH_AC3D ? m->ac_tex : mt ? mt->tex : -1;
	if (tex >= 0 && m->texs[tex].state == 1 && m->poly_has_tc) {
		int ok = 1;
		for (int j = 0; j < 3; j++) {
			const float *tc = m->poly_tc + 2 * pc[j];
			ok &= !isnan(tc[0]) && !isnan(tc[1]);
			a->uv[j][0] = tc[0];
			a->uv[j][1] = tc[1];
		}
		if (ok)
			a->texture = tex;
		else
			memset(a->uv, 0, sizeof a->uv);
	}
	for (int k = 0; k < 3; k++)
		base[k] = mt ? mt->rgb[k] : VD_GREY;
}

/* The corners' colours: the vertex's own when its record (rec[j], as
 * bytes: it may be unaligned in the spill) has one, else `base`. */
static void vd_mesh_attr_corners(const struct vd_mesh *m,
				 const uint8_t *const rec[3],
				 const uint8_t base[3], struct vd_tri_attr *a)
{
	for (int j = 0; j < 3; j++) {
		uint8_t c[4] = {0, 0, 0, 0};
		if (m->vfloats == 4)
			memcpy(c, rec[j] + 12, 4);
		const uint8_t *src = c[3] ? c : base;
		for (int k = 0; k < 3; k++)
			a->rgb[j][k] = src[k];
	}
}

/* vd_mesh_attr_face's result as the spill's per-triangle record
 * (MESH_SPILL_ATTR_BYTES): texture (int32), base (3 bytes and a 0), uv
 * (6 floats); native byte order, it never leaves the process. */
static void vd_mesh_attr_pack(const struct vd_tri_attr *a,
			      const uint8_t base[3], uint8_t *p)
{
	memcpy(p, &a->texture, 4);
	memcpy(p + 4, base, 3);
	p[7] = 0;
	memcpy(p + 8, a->uv, 24);
}

static void vd_mesh_attr_unpack(const uint8_t *p, struct vd_tri_attr *a,
				uint8_t base[3])
{
	memset(a, 0, sizeof *a);
	memcpy(&a->texture, p, 4);
	memcpy(base, p + 4, 3);
	memcpy(a->uv, p + 8, 24);
}

static int vd_mesh_next(struct vd_mesh *m, int *got);
static int vd_mesh_next_polygon(struct vd_mesh *m, int *got);

/* Back to the first face, reading the file again from the start of its
 * body: vd_mesh_rewind without a spill, and the start of reading into
 * one. The materials, textures and MTL files of OBJ stay (an MTL file is
 * read once); AC3D reads its MATERIAL lines again. */
static int vd_mesh_restart(struct vd_mesh *m)
{
	m->done = 0;
	m->poly_n = m->poly_next = 0;
	m->poly_face = 0;
	m->faces_done = 0;
	m->stats.faces_dropped_short = 0;
	m->stats.polygons_split = 0;
	switch (m->kind) {
	case MESH_OBJ:
	case MESH_STL_ASCII:
		m->nverts = 0;
		m->nonfinite = 0;
		m->stl_in_solid = 0;
		m->stl_rest = NULL;
		if (m->kind == MESH_OBJ)
			m->stats.vertices = 0;
		m->nuvs = 0;
		m->cur_mat = -1;
		return vd__rd_seek(&m->r, 0, 0);
	case MESH_STL_BIN:
		return vd__rd_seek(&m->r, m->body_off, 0);
	case MESH_IMPORT:
		m->imp_next = 0;
		m->stats.faces_dropped_short = m->imp.faces_dropped_short;
		return VD_OK;
	case MESH_AC3D:
		m->nverts = 0;
		m->nonfinite = 0;
		m->stats.vertices = 0;
		m->ac_depth = 0;
		m->ac_in_object = m->ac_seen_object = 0;
		m->ac_surf_left = 0;
		m->poly_strip = 0;
		vd__mesh_free_materials(m);
		return vd__rd_seek(&m->r, m->body_off, m->body_lines);
	default:
		if (m->face_elem == m->nelems) {
			m->done = 1;
			return VD_OK;
		}
		return vd__rd_seek(&m->r, m->body_off, m->body_lines);
	}
}

/* Hands the polygon's next triangle to the spill: its corners' vertex
 * indices (AC3D: the object's, made the spill's by ac_vbase), with
 * colours what the polygon decides of its attributes and for a textured
 * OBJ triangle its corners' vt indices (their u v come from the join);
 * AC3D adds ac_vbase, for messages. */
static int vd_mesh_spill_triangle(struct vd_mesh *m)
{
	size_t pc[3];
	uint32_t c[VD_SPILL_MAX_TABLES][3];
	uint8_t extra[MESH_SPILL_ATTR_BYTES + 4];
	size_t ab = vd_mesh_spill_attr_bytes(m);
	uint32_t vbase = m->kind == MESH_AC3D ? (uint32_t)m->ac_vbase : 0;
	struct vd_tri_attr a = {.texture = -1};
	vd_mesh_fan(m, pc);
	if (ab) {
		uint8_t base[3];
		vd_mesh_attr_face(m, pc, &a, base);
		vd_mesh_attr_pack(&a, base, extra);
	}
	memcpy(extra + ab, &vbase, 4);
	for (int j = 0; j < 3; j++) {
		c[MESH_SPILL_VERTS][j] = m->poly[pc[j]] + vbase;
		c[MESH_SPILL_UVS][j] = m->kind == MESH_OBJ && a.texture >= 0
			? m->poly_ti[pc[j]] : VD_SPILL_NONE;
	}
	return vd__spill_triangle(m->spill, c, m->poly_face, m->poly_line,
				 extra);
}

/* Spill mode: the first call reads the whole mesh into the spill (OBJ
 * and AC3D: again from the start, `delivered` triangles having been
 * handed out from memory already) and joins; every call then hands out
 * triangles from the join, with their attributes into attr[] when it is
 * not NULL. */
static int vd_mesh_spill_read(struct vd_mesh *m, struct vd_triangle *buf,
			      struct vd_tri_attr *attr, size_t cap, size_t *n,
			      uint64_t delivered)
{
	int e = VD_OK;
	*n = 0;
	if (!m->spill_ready) {
		if (m->spill_wanted) {
			/* OBJ and AC3D: PLY knows at open. The arrays go
			 * first: the spill takes their share. */
			free(m->verts);
			free(m->uvs);
			m->verts = NULL;
			m->uvs = NULL;
			m->verts_cap = m->uvs_cap = 0;
			m->spill_nverts = 0;
			m->spill_wanted = 0;
			m->spill_skip = delivered;
			if ((e = vd__mesh_spill_open(m)) ||
			    (e = vd_mesh_restart(m)))
				return e;
		}
		for (;;) {
			if (m->poly_next && m->poly_next + 1 < m->poly_n) {
				if ((e = vd_mesh_spill_triangle(m)))
					return e;
				m->poly_next++;
				continue;
			}
			int got = 0;
			if ((e = vd_mesh_next_polygon(m, &got)))
				return e;
			if (!got)
				break;
		}
		if (m->kind == MESH_OBJ)
			m->stats.vertices = m->nverts;
		if ((e = vd__spill_finish(m->spill)))
			return e;
		m->spill_ready = 1;
	}
	size_t ab = vd_mesh_spill_attr_bytes(m);
	while (*n < cap) {
		const uint8_t *rec[VD_SPILL_MAX_TABLES][3], *extra;
		uint32_t v[VD_SPILL_MAX_TABLES][3];
		uint64_t face, line;
		int got;
		if ((e = vd__spill_next(m->spill, rec, v, &face, &line, &extra,
				       &got)))
			return e;
		if (!got)
			break;
		if (m->spill_skip) {
			m->spill_skip--;
			continue;
		}
		struct vd_triangle *t = &buf[*n];
		for (int j = 0; j < 3; j++) {
			if (!rec[MESH_SPILL_VERTS][j])
				return vd_fail(VD_ERR_INTERNAL, "face %" PRIu64
					       " without its vertices in the "
					       "spill", face);
			memcpy(t->v[j], rec[MESH_SPILL_VERTS][j], 12);
		}
		/* every triangle checked: AC3D's m->nonfinite is the last
		 * object's only */
		for (int j = 0; j < 3; j++)
			if (!isfinite(t->v[j][0]) || !isfinite(t->v[j][1]) ||
			    !isfinite(t->v[j][2])) {
				uint32_t vbase;
				memcpy(&vbase, extra + ab, 4);
				m->poly_face = face;
				m->poly_line = line;
				return vd__mesh_nonfinite(m,
					v[MESH_SPILL_VERTS][j] -
					(m->kind == MESH_AC3D ? vbase : 0),
					t->v[j]);
			}
		if (attr) {
			uint8_t base[3];
			struct vd_tri_attr *a = &attr[*n];
			vd_mesh_attr_unpack(extra, a, base);
			vd_mesh_attr_corners(m, rec[MESH_SPILL_VERTS], base, a);
			for (int j = 0; a->texture >= 0 && m->kind == MESH_OBJ &&
			     j < 3; j++) {
				if (!rec[MESH_SPILL_UVS][j])
					return vd_fail(VD_ERR_INTERNAL, "face %"
						       PRIu64 " without its "
						       "texture coordinates in "
						       "the spill", face);
				memcpy(a->uv[j], rec[MESH_SPILL_UVS][j], 8);
			}
		}
		(*n)++;
	}
	return VD_OK;
}

static int vd_mesh_next(struct vd_mesh *m, int *got)
{
	switch (m->kind) {
	case MESH_OBJ: return vd__obj_next(m, got);
	case MESH_STL_ASCII: return vd__stl_ascii_next(m, got);
	case MESH_AC3D: return vd__ac_next(m, got);
	default: return vd__ply_next(m, got);
	}
}

/* The next polygon of the file into the polygon state, checked by
 * vd_mesh_poly_done (a dropped face leaves poly_n 0). *got is 0, and the
 * mesh done, at the end of the faces. */
static int vd_mesh_next_polygon(struct vd_mesh *m, int *got)
{
	*got = 0;
	if (m->done)
		return VD_OK;
	m->poly_n = m->poly_next = 0;
	m->poly_mat = -1;
	m->poly_has_tc = 0;
	int e = vd_mesh_next(m, got);
	if (e)
		return e;
	if (!*got) {
		m->done = 1;
		return VD_OK;
	}
	return vd_mesh_poly_done(m);
}

static int vd_mesh_read_impl(struct vd_mesh *m, struct vd_triangle *buf,
			     struct vd_tri_attr *attr, size_t cap, size_t *n)
{
	if (!n)
		return vd_fail(VD_ERR_ARG, "vd_mesh_read: NULL count");
	*n = 0;
	if (!m || !buf || cap == 0)
		return vd_fail(VD_ERR_ARG, "vd_mesh_read: no mesh or no room");
	if (m->err)
		return vd_fail(m->err, "%s", m->err_detail);
	size_t k = 0;
	int e = VD_OK;
	if (m->kind == MESH_STL_BIN) {
		e = vd__stl_bin_read(m, buf, cap, &k);
		for (size_t i = 0; attr && i < k; i++) {
			memset(&attr[i], 0, sizeof attr[i]);
			memset(attr[i].rgb, VD_GREY, sizeof attr[i].rgb);
			attr[i].texture = -1;
		}
	} else if (m->kind == MESH_IMPORT) {
		e = vd__import_read(m, buf, attr, cap, &k);
	} else {
		while (k < cap && !m->spill) {
			if (m->poly_next && m->poly_next + 1 < m->poly_n) {
				struct vd_triangle *t = &buf[k];
				size_t pc[3];
				const uint8_t *rec[3];
				vd_mesh_fan(m, pc);
				for (int j = 0; j < 3; j++) {
					rec[j] = (const uint8_t *)vd_mesh_vert(
						m, m->poly[pc[j]]);
					memcpy(t->v[j], rec[j], 12);
				}
				if (attr) {
					uint8_t base[3];
					vd_mesh_attr_face(m, pc, &attr[k], base);
					vd_mesh_attr_corners(m, rec, base,
							     &attr[k]);
				}
				k++;
				m->poly_next++;
				continue;
			}
			int got = 0;
			if ((e = vd_mesh_next_polygon(m, &got)) || !got)
				break;
			if (m->spill_wanted)
				break; /* the vertices passed the limit */
		}
		if (!e && (m->spill || m->spill_wanted)) {
			size_t more = 0;
			e = vd_mesh_spill_read(m, buf + k, attr ? attr + k : NULL,
					       cap - k, &more,
					       m->stats.triangles_read + k);
			k += more;
		}
	}
	m->stats.triangles_read += k;
	*n = k;
	if (e) {
		m->err = e;
		snprintf(m->err_detail, sizeof m->err_detail, "%s",
			 vd_error_detail());
	}
	return e;
}

int vd_mesh_read(struct vd_mesh *m, struct vd_triangle *buf, size_t cap,
		 size_t *n)
{
	return vd_mesh_read_impl(m, buf, NULL, cap, n);
}

int vd_mesh_read_attr(struct vd_mesh *m, struct vd_triangle *buf,
		      struct vd_tri_attr *attr, size_t cap, size_t *n)
{
	if (m && !m->col_on) {
		if (n)
			*n = 0;
		return vd_fail(VD_ERR_ARG, "vd_mesh_read_attr: the mesh was "
			       "opened without colours");
	}
	if (!attr)
		return vd_fail(VD_ERR_ARG, "vd_mesh_read_attr: NULL attr");
	return vd_mesh_read_impl(m, buf, attr, cap, n);
}

int vd_mesh_rewind(struct vd_mesh *m)
{
	if (!m)
		return vd_fail(VD_ERR_ARG, "vd_mesh_rewind: NULL mesh");
	m->err = 0;
	m->stats.triangles_read = 0;
	if (m->spill_ready) {
		/* the join is the whole mesh: no file to read again */
		m->spill_skip = 0;
		return vd__spill_rewind(m->spill);
	}
	return vd_mesh_restart(m);
}
