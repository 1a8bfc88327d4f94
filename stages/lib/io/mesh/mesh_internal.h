/* mesh_internal.h - private to io/mesh/: the state of a mesh reader
 * (struct vd_mesh) and what its files share. One file per format (ply.c,
 * obj.c, stl.c, ac3d.c, imported.c) over the common parts: read.c (the
 * read buffer, tokens and numbers), store.c (vertices, triangles,
 * reading), colour.c (materials, textures, the files read) and open.c
 * (detection, open, close); mesh_spill.c is the join of a mesh whose
 * vertices do not fit, mesh_import.h the contract with an importer.
 *
 * Streaming triangle readers for PLY, OBJ, STL and AC3D, and the
 * in-memory scenes of an importer (glTF, FBX, Collada, 3DS: Assimp, set by
 * voxelize-assimp only).
 *
 * Memory is bounded by the vertex positions (12 bytes per vertex; an OBJ
 * read with colours adds 8 per `vt`) plus one read buffer: the face body
 * is decoded from a fixed buffer as the caller asks for triangles, never
 * loaded whole, so meshes far larger than memory stream through as long
 * as their vertices fit, and given a spill directory, whatever their size.
 *
 * Decisions worth knowing:
 * - PLY vertices are loaded at open (they precede the faces in every file
 *   we know; a face element before the vertex element is refused), then the
 *   file offset of the face element is remembered so rewind is one seek.
 * - OBJ is read in one pass: vertices are appended as they appear and a face
 *   may use only vertices defined before it (the rule negative indices
 *   already imply). A positive index to a later vertex is VD_ERR_RANGE
 *   rather than a silent pre-pass that would double the I/O of every file.
 * - Polygons are fan-triangulated (0,i,i+1), so the triangle order is the
 *   file order and a rewind reproduces it exactly.
 * - Non-finite coordinates are checked per corner only when the file has
 *   any, so the common clean file pays nothing for the rule.
 * - Colour (voxdag.h, "surface colours") is decoded only when the mesh is
 *   opened with it. A vertex record is then 4 floats instead of 3: the
 *   fourth holds the vertex's R, G, B bytes and a byte saying it has a
 *   colour, copied in and out as bytes (a record is an opaque blob of
 *   m->vfloats floats to everything but vd__mesh_push_vertex and the
 *   triangle assembly). Per-corner texture coordinates travel in
 *   m->poly_tc beside m->poly, and the polygon's material in m->poly_mat.
 * - Vertices over the limit (verts_limit), given a spill directory, are
 *   not refused but joined with the faces on disk (mesh_spill.c): PLY,
 *   OBJ, and AC3D when one object's vertices pass it. OBJ texture
 *   coordinates share the limit with the vertices (the limit is on both
 *   arrays' capacity together) and spill with them: a spilled vt is a
 *   second table of the same join, so a textured corner carries a vertex
 *   index and a vt index. Range errors need only the counts, so they are
 *   raised while the file is read, with the in-memory message; whether a
 *   triangle is textured needs only whether its corners have vt, so it is
 *   decided then too, and only a textured triangle's corners take part
 *   in the vt join. A spilled vertex or vt record is the in-memory one,
 *   and each triangle carries what its polygon decides of its attributes
 *   (texture, AC3D's inline uv, material colour), so spilled reading
 *   hands out the same triangles and attributes.
 * - An AC3D surface indexes its object's vertices; spilled, every
 *   object's vertices go to one table and a surface's indices are offset
 *   by its object's first (ac_vbase), which its triangles keep for the
 *   messages. A file whose objects all fit stays in memory, read once.
 */
#ifndef VD_MESH_INTERNAL_H
#define VD_MESH_INTERNAL_H

#include "voxdag.h"
#include "io/mesh/mesh_spill.h"
#include "io/mesh/mesh_import.h"

#include <float.h>
#include <math.h>
#include <stddef.h>
#include <stdint.h>

/* What a spilled mesh keeps per triangle beside its vertex records when
 * colours are on: the part of its vd_tri_attr its polygon decides
 * (vd_mesh_attr_pack), so that the join gives back the attributes the
 * in-memory reader computes. An AC3D triangle adds 4 bytes: the spill
 * index of its object's first vertex (vd__mesh_spill_open). */
#define MESH_SPILL_ATTR_BYTES 32

/* The spill's tables: the vertex records, and an OBJ's texture
 * coordinates (u v as two floats) when it is read with colours. */
#define MESH_SPILL_VERTS 0
#define MESH_SPILL_UVS 1

/* Large enough that read() calls are rare, small enough to never matter
 * against a memory budget; also the longest text line we accept. */
#define MESH_BUF_BYTES (1u << 20)

/* Polygons with more corners than this are taken as corruption: no real
 * exporter writes them and the bound keeps a list fully in the buffer. */
#define MESH_MAX_CORNERS 65535

/* ------------------------------------------------------------ read buffer
 * (read.c) */

struct vd_rd {
	int fd;
	unsigned char *buf; /* cap + 1 bytes: room for a NUL after a last line */
	size_t cap, pos, len;
	uint64_t off;       /* file offset of buf[0] */
	uint64_t lines;     /* physical lines consumed by vd__rd_line */
	int eof;
	int cut;            /* the last line had no newline: end of file */
};

/* Character tests of the text readers, inline: they run per character. */

static inline int vd_is_space(char c)
{
	return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
}

static inline int vd_is_end(char c)
{
	return c == 0 || vd_is_space(c);
}

static inline const char *vd_skip_space(const char *p)
{
	while (vd_is_space(*p))
		p++;
	return p;
}

static inline const char *vd_token_end(const char *p)
{
	while (!vd_is_end(*p))
		p++;
	return p;
}

/* Out-of-range doubles become infinities explicitly: the plain conversion
 * is undefined behaviour, and the face check then reports them. */
static inline float vd_to_f32(double d)
{
	if (d > FLT_MAX)
		return INFINITY;
	if (d < -FLT_MAX)
		return -INFINITY;
	return (float)d;
}

/* ------------------------------------------------------------------- PLY */

struct vd_ply_prop {
	char name[32];         /* longer names are cut; we match short ones */
	unsigned char type;    /* scalar type, or the list's item type */
	unsigned char count;   /* list count type; PLY_NONE for a scalar */
};

struct vd_ply_elem {
	char name[32];
	uint64_t count;
	struct vd_ply_prop *props;
	size_t nprops, cap;
	size_t min_bytes;      /* binary bytes of one item with empty lists */
	int fixed;             /* no list properties: every item min_bytes */
};

static inline uint64_t vd_ld(const unsigned char *p, int n, int be)
{
	uint64_t v = 0;
	for (int i = 0; i < n; i++)
		v |= (uint64_t)p[be ? n - 1 - i : i] << (8 * i);
	return v;
}

/* ------------------------------------------------------------ the reader */

enum vd_mesh_kind {
	MESH_PLY_LE, MESH_PLY_BE, MESH_PLY_ASCII, MESH_OBJ, MESH_STL_BIN,
	MESH_STL_ASCII, MESH_AC3D, MESH_IMPORT
};

/* An AC3D object whose kids are being read: its world transform (row-major
 * 3x3 matrix in w[0..8], translation in w[9..11], p' = A p + t) and how
 * many of its kids are still to come. */
struct vd_ac_frame {
	double w[12];
	uint64_t kids_left, kids;
	char name[48];
};

/* A material: its colour and its texture slot (-1: none). */
struct vd_material {
	char *name;
	uint8_t rgb[3];
	int tex;
};

/* A texture named by the mesh, loaded the first time a face uses it. */
struct vd_tex_slot {
	char *path;
	int state;             /* 0 not tried, 1 loaded, -1 failed */
	struct vd_texture t;
	/* imported scenes: the image when embedded (owned by m->imp), the
	 * scene's texture and the wrap modes the slot stands for */
	const uint8_t *data;
	size_t bytes;
	int imp_tex;
	uint8_t wrap[2];
	const char *unsupported; /* why it cannot be decoded, or NULL */
};

struct vd_mesh {
	int kind;
	struct vd_rd r;
	uint64_t file_bytes;
	uint64_t body_off, body_lines; /* where rewind restarts */

	float *verts;          /* x y z [rgb] per vertex: vfloats floats */
	int vfloats;           /* 3, or 4 when vertices carry colours */
	uint64_t nverts, verts_cap;
	uint64_t verts_limit;  /* bytes the vertex array may take; 0: any */
	int nonfinite;         /* some vertex has a NaN/inf coordinate */

	/* The polygon being fanned out: vertex indices into verts. */
	uint32_t *poly;
	size_t poly_n, poly_next, poly_cap;
	uint64_t poly_face;    /* 1-based face number, for messages */
	uint64_t poly_line;    /* its line in text formats */

	/* Colours (col_on only). */
	int col_on, col_seen;
	struct vd_mesh_open_opts col;
	char *dir;             /* the mesh file's directory, for relative names */
	float *poly_tc;        /* u v per corner of m->poly; NAN u: none */
	uint32_t *poly_ti;     /* OBJ spilled: the corner's vt index (its u v
				* come from the join; poly_tc holds 0 0) */
	size_t poly_tc_cap;    /* corners of poly_tc and poly_ti */
	int poly_mat;          /* material of the polygon, -1: none */
	int poly_has_tc;       /* poly_tc holds this polygon's corners */
	struct vd_material *mats;
	size_t nmats, mats_cap;
	struct vd_tex_slot *texs;
	size_t ntexs, texs_cap;
	uint64_t tex_missing, tex_loaded;
	int cur_mat;           /* OBJ: the usemtl in force */
	char **mtllibs;        /* OBJ: MTL files already read */
	size_t nmtllibs;
	/* Files read besides the mesh, and names looked for in vain
	 * (vd_mesh_sources): what the output depends on besides the mesh */
	struct vd_mesh_source *srcs;
	size_t nsrcs, srcs_cap;
	float *uvs;            /* OBJ: vt u v (not when spilled) */
	uint64_t nuvs, uvs_cap; /* nuvs: vt lines so far, spilled or not */
	int warned_mat;        /* one warning for unknown materials */
	int icol[3];           /* PLY: red green blue property indices */
	signed char *vslot;    /* PLY: per vertex property, 0-2 xyz, 3-5 rgb */
	int ac_tex;            /* AC3D: the object's texture slot */
	double ac_texrep[2], ac_texoff[2];

	/* PLY */
	struct vd_ply_elem *elems;
	size_t nelems;
	size_t vert_elem, face_elem; /* indices into elems; nelems if none */
	int ix, iy, iz, ilist;       /* property indices */
	uint64_t faces_done;

	/* STL */
	uint64_t stl_count;    /* binary: triangles in the file */
	int stl_in_solid;      /* text: between 'solid' and 'endsolid' */
	char *stl_rest;        /* text: unread part of the current line */

	/* AC3D: m->verts holds the current object's vertices only, already
	 * in world coordinates, since a surface may only use its own
	 * object's vertices (spilled: m->nverts counts them, and ac_vbase
	 * is the spill index of the first). */
	struct vd_ac_frame *ac_stack; /* open ancestors, root first */
	size_t ac_depth, ac_cap;
	int ac_in_object;      /* between OBJECT and its kids line */
	int ac_seen_object;    /* some OBJECT was seen (else truncated) */
	int ac_torcs;          /* a TORCS .acc file (vd_ac_eof) */
	int ac_warned_kids;    /* its short kids count said once */
	double ac_rot[9], ac_loc[3]; /* the object's own rot and loc */
	uint64_t ac_surf_left; /* surfaces of the object still to read */
	uint64_t ac_object_line;
	char ac_name[48];      /* the object's name, for messages */
	uint64_t ac_vbase;
	int poly_strip;        /* m->poly is a triangle strip, not a fan */

	/* MESH_IMPORT: the scene the importer read, handed out from memory */
	struct vd_import_scene imp;
	uint64_t imp_next;     /* the next triangle */

	/* Vertices (and OBJ texture coordinates) over verts_limit with a
	 * spill directory: the faces are resolved by an external join on
	 * disk (mesh_spill.c). PLY knows it at open; OBJ and AC3D when a
	 * vertex or vt would pass the limit (spill_wanted), then the file is
	 * read again from the start into the spill and the triangles already
	 * handed out are skipped (spill_skip). */
	char *spill_dir;
	struct vd_spill *spill;
	int spill_wanted, spill_ready;
	uint64_t spill_skip;
	uint64_t spill_nverts; /* vertex records in the spill (AC3D: of
				* every object so far) */

	struct vd_mesh_stats stats;
	int done;
	int err;               /* sticky: reads after a failure repeat it */
	char err_detail[512];
};

/* The position of vertex i. */
static inline const float *vd_mesh_vert(const struct vd_mesh *m, uint64_t i)
{
	return m->verts + (size_t)m->vfloats * i;
}

/* ------------------------------------------------ shared between the files
 * Each is described where it is defined. */

/* read.c */
int vd__rd_fill(struct vd_rd *r);
int vd__rd_need(struct vd_rd *r, size_t n);
int vd__rd_skip(struct vd_rd *r, uint64_t n);
int vd__rd_seek(struct vd_rd *r, uint64_t off, uint64_t lines);
int vd__rd_line(struct vd_rd *r, char **s, size_t *len, int join);
const char *vd__parse_double(const char *p, double *out);
const char *vd__parse_int(const char *p, int64_t *out);
int vd__tok40(const char *t);
const char *vd__kw(const char *p, const char *kw);
int vd__has_ext(const char *path, const char *ext);

/* store.c */
int vd__mesh_grow_poly(struct vd_mesh *m, size_t need);
int vd__mesh_can_spill(const struct vd_mesh *m);
int vd__mesh_spill_open(struct vd_mesh *m);
/* Bytes of MESH_SPILL_ATTR_BYTES in a spilled triangle's record. */
static inline size_t vd_mesh_spill_attr_bytes(const struct vd_mesh *m)
{
	return m->col_on ? MESH_SPILL_ATTR_BYTES : 0;
}
int vd__mesh_over_limit(const struct vd_mesh *m);
uint64_t vd__mesh_grow_cap(const struct vd_mesh *m, uint64_t n,
			  uint64_t item, uint64_t other, uint64_t most);
int vd__mesh_push_vertex_rgb(struct vd_mesh *m, const float v[3],
			    const uint8_t *rgb);
int vd__mesh_push_vertex(struct vd_mesh *m, const float v[3]);
const char *vd__mesh_where(const struct vd_mesh *m, char *buf,
			  size_t cap);
int vd__mesh_nonfinite(const struct vd_mesh *m, uint32_t vi,
		      const float *v);

/* colour.c */
void vd__mesh_warn(struct vd_mesh *m, const char *fmt, ...)
	__attribute__((format(printf, 2, 3)));
int vd__mesh_note_as(struct vd_mesh *m, const char *path,
		    const struct vd_mesh_source *known);
int vd__mesh_note(struct vd_mesh *m, const char *path);
uint8_t vd__unit_byte(double x);
char *vd__mesh_path(const struct vd_mesh *m, const char *dir,
		   const char *name);
int vd__mesh_tex_new(struct vd_mesh *m, char *path);
int vd__mesh_tex_slot(struct vd_mesh *m, char *path);
int vd__mesh_tex_use(struct vd_mesh *m, int i);
void vd__mesh_free_materials(struct vd_mesh *m);
int vd__mesh_add_material(struct vd_mesh *m, const char *name);
int vd__mesh_grow_tc(struct vd_mesh *m, size_t need);
int vd__numbers3(const char *p, double d[3]);

/* ply.c */
int vd__ply_open(struct vd_mesh *m);
int vd__ply_next(struct vd_mesh *m, int *got);

/* obj.c */
int vd__obj_next(struct vd_mesh *m, int *got);

/* stl.c */
int vd__stl_ascii_next(struct vd_mesh *m, int *got);
int vd__stl_bin_read(struct vd_mesh *m, struct vd_triangle *buf,
		    size_t cap, size_t *n);
int vd__stl_size_error(struct vd_mesh *m, const unsigned char *head,
		      size_t hn);

/* ac3d.c */
int vd__ac_open(struct vd_mesh *m, const char *path);
int vd__ac_next(struct vd_mesh *m, int *got);

/* imported.c */
size_t vd__import_bytes(const struct vd_import_scene *s);
int vd__import_open(struct vd_mesh *m, const char *path);
int vd__import_read(struct vd_mesh *m, struct vd_triangle *buf,
		   struct vd_tri_attr *attr, size_t cap, size_t *n);

#endif
