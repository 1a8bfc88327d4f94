/* store.c - what every reader fills: the vertex store (in memory, or past
 * the vertex limit handed to the spill join) and the polygon being read.
 * The readers (ply.c, obj.c, stl.c, ac3d.c, imported.c) call it; how
 * triangles leave it is triangles.c, which calls the readers. */
#include "io/mesh/mesh_internal.h"

#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int vd__mesh_grow_poly(struct vd_mesh *m, size_t need)
{
	if (need <= m->poly_cap)
		return VD_OK;
	size_t cap = m->poly_cap ? m->poly_cap * 2 : 64;
	while (cap < need)
		cap *= 2;
	uint32_t *p = realloc(m->poly, cap * sizeof *p);
	if (!p)
		return vd_fail(VD_ERR_NOMEM, "polygon of %zu corners", need);
	m->poly = p;
	m->poly_cap = cap;
	return VD_OK;
}

/* A spilled vertex record is the in-memory one (m->vfloats floats: the
 * position, and with colours the packed colour), so the join hands back
 * exactly what vd_mesh_vert() would; a spilled vt is the in-memory pair
 * of floats. */
int vd__mesh_can_spill(const struct vd_mesh *m)
{
	/* indexed formats only: an ASCII STL holds one facet's vertices,
	 * and spilling them handed out its first triangle over and over */
	return m->spill_dir != NULL && m->kind != MESH_STL_ASCII &&
	       m->kind != MESH_STL_BIN;
}

/* Opens the spill (PLY at open, OBJ and AC3D when reading starts over):
 * the vertex table, the vt table for OBJ with colours, and per triangle
 * what its polygon decides of its attributes (with colours) and for AC3D
 * ac_vbase (4 bytes). Within verts_limit: the share the arrays had. */
int vd__mesh_spill_open(struct vd_mesh *m)
{
	size_t rb[VD_SPILL_MAX_TABLES];
	rb[MESH_SPILL_VERTS] = 4 * (size_t)m->vfloats;
	rb[MESH_SPILL_UVS] = 2 * sizeof(float);
	size_t ntab = m->kind == MESH_OBJ && m->col_on ? 2 : 1;
	size_t tri = vd_mesh_spill_attr_bytes(m) +
		     (m->kind == MESH_AC3D ? 4 : 0);
	return vd__spill_open(&m->spill, m->spill_dir, ntab, rb, tri,
			     m->verts_limit);
}

/* Fills the record of a vertex: the position, and in 4-float records the
 * colour bytes R G B and 1 (0 0 0 0 when `rgb` is NULL). */
static void vd_mesh_vrec(const struct vd_mesh *m, const float v[3],
			 const uint8_t *rgb, float *d)
{
	d[0] = v[0];
	d[1] = v[1];
	d[2] = v[2];
	if (m->vfloats == 4) {
		uint8_t c[4] = {0, 0, 0, 0};
		if (rgb)
			c[0] = rgb[0], c[1] = rgb[1], c[2] = rgb[2], c[3] = 1;
		memcpy(d + 3, c, 4);
	}
}

/* The error for an in-memory array that would pass verts_limit without a
 * spill directory to go to. */
int vd__mesh_over_limit(const struct vd_mesh *m)
{
	char uvs[64] = "";
	if (m->nuvs)
		snprintf(uvs, sizeof uvs, " and %" PRIu64 " texture "
			 "coordinates", m->nuvs);
	return vd_fail(VD_ERR_BUDGET, "more than %" PRIu64 " vertices%s need "
		       "more than %" PRIu64 " KiB in memory, the vertex share "
		       "(half) of the memory budget", m->nverts, uvs,
		       m->verts_limit >> 10);
}

/* The capacity an in-memory array of `n` items of `item` bytes may grow
 * to within what verts_limit leaves beside `other` bytes of the other
 * array (vertices and vt share the limit), at most `most`; n when it
 * cannot grow. It doubles while that fits, then grows by an eighth: a
 * jump to all the room left would leave none to the other array, and
 * the mesh would spill with both arrays' contents far under the limit. */
uint64_t vd__mesh_grow_cap(const struct vd_mesh *m, uint64_t n,
			  uint64_t item, uint64_t other, uint64_t most)
{
	uint64_t cap = n ? n * 2 : 4096;
	if (cap > most)
		cap = most;
	if (m->verts_limit && cap * item + other > m->verts_limit) {
		uint64_t room = m->verts_limit > other
			? (m->verts_limit - other) / item : 0;
		cap = n + n / 8 + 1;
		if (cap > room)
			cap = room;
		if (cap > most)
			cap = most;
	}
	return cap > n ? cap : n;
}

/* Appends a vertex; `rgb` (NULL: none) is kept only in 4-float records. */
int vd__mesh_push_vertex_rgb(struct vd_mesh *m, const float v[3],
			    const uint8_t *rgb)
{
	const uint64_t vbytes = 4 * (uint64_t)m->vfloats;
	if (m->spill || m->spill_wanted) {
		if (m->nverts >= UINT32_MAX || m->spill_nverts >= UINT32_MAX)
			return vd_fail(VD_ERR_RANGE, "more than %" PRIu32
				       " vertices%s", UINT32_MAX,
				       m->nverts < UINT32_MAX ? " in all "
				       "objects (the most a spilled AC3D file "
				       "may have)" : "");
		m->nverts++;
		if (!isfinite(v[0]) || !isfinite(v[1]) || !isfinite(v[2]))
			m->nonfinite = 1;
		/* wanted: this pass is dropped and read again into a spill */
		if (!m->spill)
			return VD_OK;
		float d[4];
		vd_mesh_vrec(m, v, rgb, d);
		m->spill_nverts++;
		return vd__spill_record(m->spill, MESH_SPILL_VERTS, d);
	}
	const uint64_t other = m->uvs_cap * 2 * sizeof(float);
	if (m->verts_limit &&
	    (m->nverts + 1) * vbytes + other > m->verts_limit &&
	    vd__mesh_can_spill(m)) {
		m->spill_wanted = 1;
		return vd__mesh_push_vertex_rgb(m, v, rgb);
	}
	if (m->nverts == m->verts_cap) {
		if (m->nverts >= UINT32_MAX)
			return vd_fail(VD_ERR_RANGE,
				       "more than %" PRIu32 " vertices",
				       UINT32_MAX);
		uint64_t cap = vd__mesh_grow_cap(m, m->nverts, vbytes, other,
						UINT32_MAX);
		if (cap == m->nverts)
			return vd__mesh_over_limit(m);
		float *p = realloc(m->verts, (size_t)(cap * vbytes));
		if (!p)
			return vd_fail(VD_ERR_NOMEM, "%" PRIu64 " vertices",
				       cap);
		m->verts = p;
		m->verts_cap = cap;
	}
	vd_mesh_vrec(m, v, rgb, m->verts + (size_t)m->vfloats * m->nverts++);
	if (!isfinite(v[0]) || !isfinite(v[1]) || !isfinite(v[2]))
		m->nonfinite = 1;
	return VD_OK;
}

int vd__mesh_push_vertex(struct vd_mesh *m, const float v[3])
{
	return vd__mesh_push_vertex_rgb(m, v, NULL);
}

/* "line 12: " for text formats, "" otherwise, for details. */
const char *vd__mesh_where(const struct vd_mesh *m, char *buf,
			  size_t cap)
{
	if (m->kind == MESH_PLY_ASCII || m->kind == MESH_OBJ ||
	    m->kind == MESH_STL_ASCII || m->kind == MESH_AC3D)
		snprintf(buf, cap, "line %" PRIu64 ": ", m->poly_line);
	else
		buf[0] = 0;
	return buf;
}

/* The error for vertex vi of face m->poly_face whose position v is not
 * finite. */
int vd__mesh_nonfinite(const struct vd_mesh *m, uint32_t vi,
		      const float *v)
{
	char w[48];
	vd__mesh_where(m, w, sizeof w);
	if (m->kind == MESH_STL_ASCII)
		return vd_fail(VD_ERR_RANGE, "%sfacet %" PRIu64 " has a "
			       "non-finite vertex (%g %g %g)", w, m->poly_face,
			       v[0], v[1], v[2]);
	return vd_fail(VD_ERR_RANGE, "%sface %" PRIu64 " uses vertex %" PRIu32
		       "%s whose position is not finite (%g %g %g)", w,
		       m->poly_face, vi + (m->kind == MESH_OBJ),
		       m->kind == MESH_OBJ ? " (1-based)" : "", v[0], v[1],
		       v[2]);
}
