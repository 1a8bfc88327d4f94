/* mesh.c - streaming triangle readers for PLY, OBJ, STL and AC3D, and the
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
 *   m->vfloats floats to everything but vd_mesh_push_vertex and the
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
#include "voxdag.h"
#include "io/mesh/mesh_spill.h"
#include "io/mesh/mesh_import.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <float.h>
#include <inttypes.h>
#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <libgen.h>
#include <sys/stat.h>
#include <unistd.h>

/* What a spilled mesh keeps per triangle beside its vertex records when
 * colours are on: the part of its vd_tri_attr its polygon decides
 * (vd_mesh_attr_pack), so that the join gives back the attributes the
 * in-memory reader computes. An AC3D triangle adds 4 bytes: the spill
 * index of its object's first vertex (vd_mesh_spill_open). */
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

static const char *vd_kw(const char *p, const char *kw);
static int vd_tok40(const char *t);

/* ------------------------------------------------------------ read buffer */

struct vd_rd {
	int fd;
	unsigned char *buf; /* cap + 1 bytes: room for a NUL after a last line */
	size_t cap, pos, len;
	uint64_t off;       /* file offset of buf[0] */
	uint64_t lines;     /* physical lines consumed by vd_rd_line */
	int eof;
	int cut;            /* the last line had no newline: end of file */
};

/* Returns 1 if bytes were added, 0 at end of file or when the buffer is full
 * of unread bytes, -1 after a failed read (detail set). */
static int vd_rd_fill(struct vd_rd *r)
{
	if (r->pos > 0) {
		memmove(r->buf, r->buf + r->pos, r->len - r->pos);
		r->off += r->pos;
		r->len -= r->pos;
		r->pos = 0;
	}
	if (r->eof || r->len == r->cap)
		return 0;
	for (;;) {
		ssize_t k = read(r->fd, r->buf + r->len, r->cap - r->len);
		if (k < 0 && errno == EINTR)
			continue;
		if (k < 0) {
			vd_fail(VD_ERR_IO, "read failed at byte %" PRIu64 ": %s",
				r->off + r->len, strerror(errno));
			return -1;
		}
		if (k == 0) {
			r->eof = 1;
			return 0;
		}
		r->len += (size_t)k;
		return 1;
	}
}

/* Makes n (<= cap) bytes available at buf + pos. Returns VD_OK,
 * VD_ERR_TRUNCATED without a detail (the caller knows what was cut), or
 * VD_ERR_IO with one. */
static int vd_rd_need(struct vd_rd *r, size_t n)
{
	while (r->len - r->pos < n) {
		int f = vd_rd_fill(r);
		if (f < 0)
			return VD_ERR_IO;
		if (f == 0)
			return VD_ERR_TRUNCATED;
	}
	return VD_OK;
}

/* Skips n bytes, which may be more than the buffer holds. Same returns as
 * vd_rd_need. */
static int vd_rd_skip(struct vd_rd *r, uint64_t n)
{
	while (n > 0) {
		if (r->pos == r->len) {
			int f = vd_rd_fill(r);
			if (f < 0)
				return VD_ERR_IO;
			if (f == 0)
				return VD_ERR_TRUNCATED;
		}
		size_t take = r->len - r->pos;
		if (take > n)
			take = (size_t)n;
		r->pos += take;
		n -= take;
	}
	return VD_OK;
}

static int vd_rd_seek(struct vd_rd *r, uint64_t off, uint64_t lines)
{
	if (lseek(r->fd, (off_t)off, SEEK_SET) < 0)
		return vd_fail(VD_ERR_IO, "seek to byte %" PRIu64 ": %s", off,
			       strerror(errno));
	r->off = off;
	r->pos = r->len = 0;
	r->eof = 0;
	r->lines = lines;
	return VD_OK;
}

/* Returns the next line in *s (NUL-terminated, without "\n" or "\r\n",
 * valid until the next vd_rd_* call) and its length. With `join`, a line
 * ending in a backslash continues on the next one (OBJ). Returns 1 for a
 * line, 0 at the end of the file, or a negated error code (detail set):
 * -VD_ERR_IO, or -VD_ERR_FORMAT for a line longer than the buffer. The
 * codes are negated because VD_ERR_IO is 1, the value meaning "a line". */
static int vd_rd_line(struct vd_rd *r, char **s, size_t *len, int join)
{
	size_t scan = r->pos;
	for (;;) {
		unsigned char *nl =
			memchr(r->buf + scan, '\n', r->len - scan);
		if (nl) {
			size_t e = (size_t)(nl - r->buf), end = e;
			r->lines++;
			if (end > r->pos && r->buf[end - 1] == '\r')
				end--;
			if (join && end > r->pos && r->buf[end - 1] == '\\') {
				memset(r->buf + end - 1, ' ', e - end + 2);
				scan = e + 1;
				continue;
			}
			r->buf[end] = 0;
			*s = (char *)r->buf + r->pos;
			*len = end - r->pos;
			r->pos = e + 1;
			r->cut = 0;
			return 1;
		}
		size_t rel = r->len - r->pos;
		int f = vd_rd_fill(r);
		scan = rel;
		if (f < 0)
			return -VD_ERR_IO;
		if (f > 0)
			continue;
		if (r->len == r->cap)
			return -vd_fail(VD_ERR_FORMAT, "line %" PRIu64
					": longer than %u bytes",
					r->lines + 1, MESH_BUF_BYTES);
		if (r->pos == r->len)
			return 0;
		/* A last line without its newline. */
		size_t end = r->len;
		r->lines++;
		if (end > r->pos && r->buf[end - 1] == '\r')
			end--;
		r->buf[end] = 0;
		*s = (char *)r->buf + r->pos;
		*len = end - r->pos;
		r->pos = r->len;
		r->cut = 1;
		return 1;
	}
}

/* --------------------------------------------------------- number parsing
 * Hand-written because strtod dominates text parsing; the fast path below is
 * Clinger's: a mantissa below 2^53 times an exact power of ten up to 1e22 is
 * one correctly rounded IEEE operation, so results equal strtod's. Anything
 * else (long mantissas, big exponents, nan, inf, hex) goes to strtod. */

static int vd_is_space(char c)
{
	return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
}

static int vd_is_end(char c)
{
	return c == 0 || vd_is_space(c);
}

static const char *vd_skip_space(const char *p)
{
	while (vd_is_space(*p))
		p++;
	return p;
}

static const char *vd_token_end(const char *p)
{
	while (!vd_is_end(*p))
		p++;
	return p;
}

/* Parses one number token at p (no leading space). Returns the character
 * after it, or NULL if the token is not a number. */
static const char *vd_parse_double(const char *p, double *out)
{
	static const double pow10[] = {
		1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,
		1e8,  1e9,  1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
		1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};
	const char *s = p;
	int neg = 0, any = 0, inexact = 0, digits = 0;
	long exp10 = 0;
	uint64_t mant = 0;

	if (*p == '-' || *p == '+')
		neg = *p++ == '-';
	for (; *p >= '0' && *p <= '9'; p++, any = 1) {
		if (digits < 19) {
			mant = mant * 10 + (uint64_t)(*p - '0');
			digits += mant != 0;
		} else {
			exp10++;
			inexact |= *p != '0';
		}
	}
	if (*p == '.') {
		for (p++; *p >= '0' && *p <= '9'; p++, any = 1) {
			if (digits < 19) {
				mant = mant * 10 + (uint64_t)(*p - '0');
				digits += mant != 0;
				exp10--;
			} else {
				inexact |= *p != '0';
			}
		}
	}
	if (!any)
		goto slow;
	if (*p == 'e' || *p == 'E') {
		int eneg = 0;
		long e = 0;
		p++;
		if (*p == '-' || *p == '+')
			eneg = *p++ == '-';
		if (!(*p >= '0' && *p <= '9'))
			return NULL;
		for (; *p >= '0' && *p <= '9'; p++)
			if (e < 100000)
				e = e * 10 + (*p - '0');
		exp10 += eneg ? -e : e;
	}
	if (!vd_is_end(*p))
		return NULL;
	if (inexact || mant > (1ULL << 53) || exp10 < -22 || exp10 > 22)
		goto slow;
	double d = (double)mant;
	d = exp10 < 0 ? d / pow10[-exp10] : d * pow10[exp10];
	*out = neg ? -d : d;
	return p;
slow:;
	char *end;
	errno = 0;
	*out = strtod(s, &end);
	if (end == s || !vd_is_end(*end))
		return NULL;
	return end;
}

/* Parses an integer token; NULL if it is not one or exceeds 2^62. */
static const char *vd_parse_int(const char *p, int64_t *out)
{
	int neg = 0;
	int64_t v = 0;
	if (*p == '-' || *p == '+')
		neg = *p++ == '-';
	if (!(*p >= '0' && *p <= '9'))
		return NULL;
	for (; *p >= '0' && *p <= '9'; p++) {
		if (v > (INT64_C(1) << 62) / 10)
			return NULL;
		v = v * 10 + (*p - '0');
	}
	*out = neg ? -v : v;
	return p;
}

/* Out-of-range doubles become infinities explicitly: the plain conversion
 * is undefined behaviour, and the face check then reports them. */
static float vd_to_f32(double d)
{
	if (d > FLT_MAX)
		return INFINITY;
	if (d < -FLT_MAX)
		return -INFINITY;
	return (float)d;
}

/* ------------------------------------------------------------------- PLY */

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

static uint64_t vd_ld(const unsigned char *p, int n, int be)
{
	uint64_t v = 0;
	for (int i = 0; i < n; i++)
		v |= (uint64_t)p[be ? n - 1 - i : i] << (8 * i);
	return v;
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


/* ------------------------------------------------------------ the reader */

enum vd_mesh_kind {
	MESH_PLY_LE, MESH_PLY_BE, MESH_PLY_ASCII, MESH_OBJ, MESH_STL_BIN,
	MESH_STL_ASCII, MESH_AC3D, MESH_IMPORT
};

static const char *const vd_mesh_kind_names[] = {
	"ply-binary-le", "ply-binary-be", "ply-ascii", "obj", "stl-binary",
	"stl-ascii", "ac3d", "imported"};

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

static int vd_mesh_grow_poly(struct vd_mesh *m, size_t need)
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
static int vd_mesh_can_spill(const struct vd_mesh *m)
{
	/* indexed formats only: an ASCII STL holds one facet's vertices,
	 * and spilling them handed out its first triangle over and over */
	return m->spill_dir != NULL && m->kind != MESH_STL_ASCII &&
	       m->kind != MESH_STL_BIN;
}

/* Bytes of MESH_SPILL_ATTR_BYTES in a spilled triangle's record. */
static size_t vd_mesh_spill_attr_bytes(const struct vd_mesh *m)
{
	return m->col_on ? MESH_SPILL_ATTR_BYTES : 0;
}

/* Opens the spill (PLY at open, OBJ and AC3D when reading starts over):
 * the vertex table, the vt table for OBJ with colours, and per triangle
 * what its polygon decides of its attributes (with colours) and for AC3D
 * ac_vbase (4 bytes). Within verts_limit: the share the arrays had. */
static int vd_mesh_spill_open(struct vd_mesh *m)
{
	size_t rb[VD_SPILL_MAX_TABLES];
	rb[MESH_SPILL_VERTS] = 4 * (size_t)m->vfloats;
	rb[MESH_SPILL_UVS] = 2 * sizeof(float);
	size_t ntab = m->kind == MESH_OBJ && m->col_on ? 2 : 1;
	size_t tri = vd_mesh_spill_attr_bytes(m) +
		     (m->kind == MESH_AC3D ? 4 : 0);
	return vd_spill_open(&m->spill, m->spill_dir, ntab, rb, tri,
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
static int vd_mesh_over_limit(const struct vd_mesh *m)
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
static uint64_t vd_mesh_grow_cap(const struct vd_mesh *m, uint64_t n,
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
static int vd_mesh_push_vertex_rgb(struct vd_mesh *m, const float v[3],
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
		return vd_spill_record(m->spill, MESH_SPILL_VERTS, d);
	}
	const uint64_t other = m->uvs_cap * 2 * sizeof(float);
	if (m->verts_limit &&
	    (m->nverts + 1) * vbytes + other > m->verts_limit &&
	    vd_mesh_can_spill(m)) {
		m->spill_wanted = 1;
		return vd_mesh_push_vertex_rgb(m, v, rgb);
	}
	if (m->nverts == m->verts_cap) {
		if (m->nverts >= UINT32_MAX)
			return vd_fail(VD_ERR_RANGE,
				       "more than %" PRIu32 " vertices",
				       UINT32_MAX);
		uint64_t cap = vd_mesh_grow_cap(m, m->nverts, vbytes, other,
						UINT32_MAX);
		if (cap == m->nverts)
			return vd_mesh_over_limit(m);
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

static int vd_mesh_push_vertex(struct vd_mesh *m, const float v[3])
{
	return vd_mesh_push_vertex_rgb(m, v, NULL);
}

/* The position of vertex i. */
static inline const float *vd_mesh_vert(const struct vd_mesh *m, uint64_t i)
{
	return m->verts + (size_t)m->vfloats * i;
}

/* "line 12: " for text formats, "" otherwise, for details. */
static const char *vd_mesh_where(const struct vd_mesh *m, char *buf,
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
static int vd_mesh_nonfinite(const struct vd_mesh *m, uint32_t vi,
			     const float *v)
{
	char w[48];
	vd_mesh_where(m, w, sizeof w);
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
				return vd_mesh_nonfinite(m, m->poly[i], v);
		}
	}
	m->poly_next = 1;
	return VD_OK;
}

/* Checks a raw index of a PLY face and stores it. */
static int vd_ply_corner(struct vd_mesh *m, int64_t idx)
{
	if (idx < 0 || (uint64_t)idx >= m->nverts) {
		char w[48];
		return vd_fail(VD_ERR_RANGE,
			       "%sface %" PRIu64 ": vertex index %" PRId64
			       " out of range (the file has %" PRIu64
			       " vertices)", vd_mesh_where(m, w, sizeof w),
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
		       "accepted)", vd_mesh_where(m, w, sizeof w),
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
		if ((e = vd_rd_need(r, el->min_bytes)))
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
			if ((e = vd_rd_need(r, size)))
				return e;
			if (v && m->vslot[i] >= 0)
				v[m->vslot[i]] = vd_to_f32(vd_ply_decode(
						r->buf + r->pos, pr->type, be));
			r->pos += size;
			continue;
		}
		if ((e = vd_rd_need(r, vd_ply_size[pr->count])))
			return e;
		int64_t n = vd_ply_decode_int(r->buf + r->pos, pr->count, be);
		r->pos += vd_ply_size[pr->count];
		if (face && (int)i == m->ilist) {
			if (n < 0 || n > MESH_MAX_CORNERS)
				return vd_ply_bad_count(m, n);
			if ((e = vd_mesh_grow_poly(m, (size_t)n)) ||
			    (e = vd_rd_need(r, (size_t)n * size)))
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
		if ((e = vd_rd_skip(r, (uint64_t)n * size)))
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
		e = vd_rd_line(&m->r, &s, &len, 0);
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
			if (!(p = vd_parse_double(t, &d)))
				goto bad;
			if (v && m->vslot[i] >= 0)
				v[m->vslot[i]] = vd_to_f32(d);
			continue;
		}
		int64_t n;
		if (!(p = vd_parse_int(t, &n)) || !vd_is_end(*p))
			goto bad;
		int corners = face && (int)i == m->ilist;
		if (corners) {
			if (n < 0 || n > MESH_MAX_CORNERS)
				return vd_ply_bad_count(m, n);
			if ((e = vd_mesh_grow_poly(m, (size_t)n)))
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
				if (!(p = vd_parse_int(t, &idx)) ||
				    !vd_is_end(*p))
					goto bad;
				if ((e = vd_ply_corner(m, idx)))
					return e;
			} else {
				double d;
				if (!(p = vd_parse_double(t, &d)))
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
		e = vd_rd_line(&m->r, &s, &len, 0);
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
			if (n != 3 || !(p = vd_parse_int(tok[2], &count)) ||
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

static int vd_ply_open(struct vd_mesh *m)
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
		if (spill && vd_mesh_can_spill(m)) {
			/* the records go to the spill (vd_mesh_push_vertex_rgb) */
			if ((e = vd_mesh_spill_open(m)))
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
			if ((e = vd_rd_need(r, ve->min_bytes)))
				return vd_ply_truncated(m, e, ve->name, j,
							ve->count);
			const unsigned char *p = r->buf + r->pos;
			memcpy(&v[0], p + off[0], 4);
			memcpy(&v[1], p + off[1], 4);
			memcpy(&v[2], p + off[2], 4);
			r->pos += ve->min_bytes;
			if ((e = vd_mesh_push_vertex_rgb(m, v, NULL)))
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
			if ((e = vd_mesh_push_vertex_rgb(m, v,
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
static int vd_ply_next(struct vd_mesh *m, int *got)
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

/* ---------------------------------------------------------------- colours
 * Materials and textures, shared by OBJ (MTL files) and AC3D. Textures are
 * registered by path when a material or object names them and decoded the
 * first time a face uses them, so a library of unused materials costs
 * nothing. */

static void vd_mesh_warn(struct vd_mesh *m, const char *fmt, ...)
	__attribute__((format(printf, 2, 3)));

static void vd_mesh_warn(struct vd_mesh *m, const char *fmt, ...)
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
static int vd_mesh_note_as(struct vd_mesh *m, const char *path,
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
static int vd_mesh_note(struct vd_mesh *m, const char *path)
{
	return vd_mesh_note_as(m, path, NULL);
}

const struct vd_mesh_source *vd_mesh_sources(const struct vd_mesh *m,
					     size_t *n)
{
	*n = m->nsrcs;
	return m->srcs;
}

static uint8_t vd_unit_byte(double x)
{
	if (!(x > 0))
		return 0;
	return x >= 1 ? 255 : (uint8_t)(x * 255.0 + 0.5);
}

/* `name` relative to the mesh's directory (absolute names as they are);
 * DOS separators become '/'. Returns a malloc'd path or NULL. */
static char *vd_mesh_path(const struct vd_mesh *m, const char *dir,
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
static int vd_mesh_tex_new(struct vd_mesh *m, char *path)
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
static int vd_mesh_tex_slot(struct vd_mesh *m, char *path)
{
	for (size_t i = 0; i < m->ntexs; i++)
		if (!strcmp(m->texs[i].path, path)) {
			free(path);
			return (int)i;
		}
	return vd_mesh_tex_new(m, path);
}

/* Loads texture slot i if not tried yet. A failure is a warning (the slot
 * then stays unusable, and faces fall back to their colours), or with
 * `strict` the error. */
static int vd_mesh_tex_use(struct vd_mesh *m, int i)
{
	if (i < 0 || m->texs[i].state != 0)
		return VD_OK;
	struct vd_tex_slot *t = &m->texs[i];
	int e = t->data || t->unsupported ? VD_OK : vd_mesh_note(m, t->path);
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
	vd_mesh_warn(m, "texture not used (%s): %s; the material's colour "
		     "is used instead", vd_strerror(e), vd_error_detail());
	return VD_OK;
}

static void vd_mesh_free_materials(struct vd_mesh *m)
{
	for (size_t i = 0; i < m->nmats; i++)
		free(m->mats[i].name);
	m->nmats = 0;
}

static int vd_mesh_add_material(struct vd_mesh *m, const char *name)
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
static int vd_mesh_grow_tc(struct vd_mesh *m, size_t need)
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
static int vd_numbers3(const char *p, double d[3])
{
	for (int k = 0; k < 3; k++) {
		p = vd_skip_space(p);
		if (!*p || !(p = vd_parse_double(p, &d[k])))
			return k;
	}
	return 3;
}

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
			if (n == 0 || !(vd_parse_double(p, &d) ||
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
	int e = vd_mesh_note(m, path);
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
		vd_mesh_warn(m, "cannot open material library '%s': %s; its "
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
		if ((q = vd_kw(p, "newmtl"))) {
			e = vd_mesh_add_material(m, vd_skip_space(q));
			cur = e ? NULL : &m->mats[m->nmats - 1];
		} else if (cur && (q = vd_kw(p, "Kd"))) {
			double d[3];
			if (vd_numbers3(q, d) == 3)
				for (int c = 0; c < 3; c++)
					cur->rgb[c] = vd_unit_byte(d[c]);
		} else if (cur && (q = vd_kw(p, "map_Kd"))) {
			const char *name = vd_mtl_map_name(q);
			if (!*name)
				continue;
			char *tp = vd_mesh_path(m, dir, name);
			if (!tp || (cur->tex = vd_mesh_tex_slot(m, tp)) < 0)
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
	char *whole = vd_mesh_path(m, NULL, names);
	struct stat st;
	int one = whole && stat(whole, &st) == 0;
	/* a name with spaces looked for whole in vain: if it appears, the
	 * MTL files read change */
	if (whole && !one && strpbrk(names, " \t"))
		e = vd_mesh_note(m, whole);
	free(whole);
	char *save = NULL;
	for (char *t = one ? names : strtok_r(names, " \t", &save); t && !e;
	     t = one ? NULL : strtok_r(NULL, " \t", &save)) {
		char *path = vd_mesh_path(m, NULL, t);
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
			return vd_mesh_tex_use(m, m->mats[i].tex);
		}
	if (!m->warned_mat) {
		m->warned_mat = 1;
		vd_mesh_warn(m, "line %" PRIu64 ": material '%.80s' is not "
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
		if (!(p = vd_parse_double(t, &d[k])))
			return vd_fail(VD_ERR_FORMAT, "line %" PRIu64 ": "
				       "malformed texture coordinate '%.*s'",
				       ln, vd_tok40(t), t);
		if (!isfinite(d[k]))
			return vd_fail(VD_ERR_RANGE, "line %" PRIu64 ": texture "
				       "coordinate '%.*s' is not finite", ln,
				       vd_tok40(t), t);
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
	    vd_mesh_can_spill(m))
		m->spill_wanted = 1; /* they share the vertices' limit */
	if (m->spill || m->spill_wanted) {
		m->nuvs++;
		return m->spill ? vd_spill_record(m->spill, MESH_SPILL_UVS, uv)
				: VD_OK;
	}
	if (m->nuvs == m->uvs_cap) {
		uint64_t cap = vd_mesh_grow_cap(m, m->nuvs, sizeof uv, other,
						UINT32_MAX);
		if (cap == m->nuvs)
			return vd_mesh_over_limit(m);
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
	int e = vd_mesh_grow_tc(m, m->poly_n + 1);
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

static int vd_obj_next(struct vd_mesh *m, int *got)
{
	char *s;
	size_t len;
	int e;
	for (;;) {
		e = vd_rd_line(&m->r, &s, &len, 1);
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
			float v[3];
			p++;
			for (int k = 0; k < 3; k++) {
				double d;
				const char *t = vd_skip_space(p);
				if (*t == 0)
					return vd_fail(VD_ERR_FORMAT,
						"line %" PRIu64 ": vertex has "
						"%d coordinates, needs 3", ln,
						k);
				if (!(p = vd_parse_double(t, &d)))
					return vd_fail(VD_ERR_FORMAT,
						"line %" PRIu64 ": malformed "
						"number '%.*s'", ln,
						(int)(vd_token_end(t) - t > 40
						      ? 40 : vd_token_end(t) - t),
						t);
				v[k] = vd_to_f32(d);
			}
			/* w may follow (ignored), or with colours the
			 * common extension "v x y z r g b" (0..1). */
			uint8_t rgb[3];
			int col = 0;
			if (m->col_on) {
				double d[3], x;
				const char *q = p;
				int k = 0;
				for (; k < 4; k++) {
					q = vd_skip_space(q);
					if (!*q || !(q = vd_parse_double(q, &x)))
						break;
					if (k < 3)
						d[k] = x;
				}
				if (k == 3) {
					for (int c = 0; c < 3; c++)
						rgb[c] = vd_unit_byte(d[c]);
					col = m->col_seen = 1;
				}
			}
			if ((e = vd_mesh_push_vertex_rgb(m, v,
							 col ? rgb : NULL)))
				return e;
			m->stats.vertices = m->nverts;
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
				if (!(p = vd_parse_int(t, &i)))
					goto bad_corner;
				/* texture and normal indices: the texture
				 * index only with colours */
				int64_t ti = INT64_MIN; /* none */
				if (*p == '/' && m->col_on &&
				    ((p[1] >= '0' && p[1] <= '9') || p[1] == '-')
				    && !(p = vd_parse_int(p + 1, &ti)))
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
				if ((e = vd_mesh_grow_poly(m, m->poly_n + 1)))
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
			if ((q = vd_kw(p, "vt"))) {
				if ((e = vd_obj_vt(m, ln, q)))
					return e;
				continue;
			}
			if ((q = vd_kw(p, "usemtl"))) {
				if ((e = vd_obj_usemtl(m, q)))
					return e;
				continue;
			}
			if ((q = vd_kw(p, "mtllib"))) {
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

/* ------------------------------------------------------------------- STL */

/* ------------------------------------------------------------------- STL */

/* Returns 1 with the next whitespace-separated token in *t, 0 at the end,
 * or a negated error code as vd_rd_line.
 * ASCII STL is read by tokens, not lines, because writers disagree on line
 * breaks. stl_rest stays valid between calls: the buffer only moves inside
 * vd_rd_line, after the current line is used up. */
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
		int e = vd_rd_line(&m->r, &s, &len, 0);
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
		if (!vd_parse_double(t, &d))
			return vd_fail(VD_ERR_FORMAT, "line %" PRIu64 ": "
				       "malformed number '%.40s'", m->r.lines,
				       t);
		v[k] = vd_to_f32(d);
	}
	return VD_OK;
}

/* The facet's corners go to m->verts (reset per facet) so that the polygon
 * code is shared with the indexed formats. */
static int vd_stl_ascii_next(struct vd_mesh *m, int *got)
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
			    (e = vd_mesh_push_vertex(m, v)) ||
			    (e = vd_mesh_grow_poly(m, m->poly_n + 1)))
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

static int vd_stl_bin_read(struct vd_mesh *m, struct vd_triangle *buf,
			   size_t cap, size_t *n)
{
	struct vd_rd *r = &m->r;
	size_t k = 0;
	while (k < cap && m->faces_done < m->stl_count) {
		int e = vd_rd_need(r, 50);
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

/* ------------------------------------------------------------------ AC3D
 * FlightGear's model format (and AC3D's own): text, a header line "AC3Db"
 * (the letter is the version), MATERIAL lines, then objects. An object is
 * "OBJECT <type>", optional attribute lines (name, data, texture, rot, loc,
 * ...), "numvert N" and N vertex lines, "numsurf N" and N surfaces, and
 * last "kids N" followed by its N child objects.
 *
 * Decisions worth knowing:
 * - A surface indexes its own object's vertices only, so one object's
 *   vertices are in memory at a time: memory is bounded by the largest
 *   object, not the model; an object over the vertex limit sends the
 *   whole file to the spill (see the top of this file). They are
 *   transformed to world coordinates as they are read.
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

/* Length of the token at t, at most 40, for messages. */
static int vd_tok40(const char *t)
{
	ptrdiff_t n = vd_token_end(t) - t;
	return n > 40 ? 40 : (int)n;
}

/* Returns the text after keyword kw if line p starts with it, else NULL. */
static const char *vd_kw(const char *p, const char *kw)
{
	size_t n = strlen(kw);
	return !strncmp(p, kw, n) && vd_is_end(p[n]) ? p + n : NULL;
}

static int vd_is_word_start(char c)
{
	return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_';
}

/* The next non-blank line, leading space skipped. 1, 0 at the end of the
 * file, or a negated error code as vd_rd_line. */
static int vd_ac_line(struct vd_mesh *m, char **s)
{
	for (;;) {
		char *p;
		size_t len;
		int e = vd_rd_line(&m->r, &p, &len, 0);
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
	if (!(q = vd_parse_int(t, &v)) || !vd_is_end(*q) ||
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
		if (!(p = vd_parse_double(t, &out[i])))
			return vd_ac_fail(m, "line %" PRIu64 ": malformed "
					  "number '%.*s' in %s", m->r.lines,
					  vd_tok40(t), t, what);
	}
	p = vd_skip_space(p);
	if (!more && *p)
		return vd_ac_fail(m, "line %" PRIu64 ": unexpected '%.*s' "
				  "after the %d numbers of %s", m->r.lines,
				  vd_tok40(p), p, n, what);
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
			int f = vd_rd_fill(r);
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
	int e = vd_rd_line(r, &s, &len, 0);
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
		 vd_tok40(type), type, m->r.lines);
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
	int e = vd_mesh_add_material(m, name);
	if (e)
		return e;
	const char *q = vd_kw(vd_skip_space(p), "rgb");
	double d[3];
	if (!q || vd_numbers3(q, d) != 3)
		return vd_ac_fail(m, "line %" PRIu64 ": MATERIAL '%s' has no "
				  "'rgb r g b'", m->r.lines, name);
	for (int c = 0; c < 3; c++)
		m->mats[m->nmats - 1].rgb[c] = vd_unit_byte(d[c]);
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
	char *path = vd_mesh_path(m, NULL, name);
	if (!path || (m->ac_tex = vd_mesh_tex_slot(m, path)) < 0)
		return vd_fail(VD_ERR_NOMEM, "textures");
	return vd_mesh_tex_use(m, m->ac_tex);
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
		vd_mesh_warn(m, "line %" PRIu64 ": material %" PRIu64 " of %zu "
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
		if ((e = vd_mesh_push_vertex(m, v)))
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
	if (!(p = vd_kw(s, "SURF")))
		return vd_ac_fail(m, "line %" PRIu64 ": expected 'SURF' (the "
				  "numsurf count of object '%s' says more "
				  "surfaces follow), found '%.*s'", m->r.lines,
				  m->ac_name, vd_tok40(s), s);
	const char *t = vd_skip_space(p);
	char *end;
	errno = 0;
	unsigned long flags = strtoul(t, &end, 0);
	if (end == t || !vd_is_end(*end) || *vd_skip_space(end) ||
	    errno || *t == '-')
		return vd_ac_fail(m, "line %" PRIu64 ": malformed surface "
				  "flags '%.*s'", m->r.lines, vd_tok40(t), t);
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
		if ((p = vd_kw(s, "mat"))) {
			if (m->col_on && (e = vd_ac_mat(m, p)))
				return e;
			continue;
		}
		if ((p = vd_kw(s, "refs")))
			break;
		return vd_ac_fail(m, "line %" PRIu64 ": expected 'mat' or "
				  "'refs', found '%.*s'", m->r.lines,
				  vd_tok40(s), s);
	}
	if ((e = vd_ac_count(m, p, "refs", &refs)))
		return e;
	if (refs > MESH_MAX_CORNERS)
		return vd_fail(VD_ERR_FORMAT, "line %" PRIu64 ": surface with %"
			       PRIu64 " refs (at most %d accepted)",
			       m->r.lines, refs, MESH_MAX_CORNERS);
	if ((e = vd_mesh_grow_poly(m, (size_t)refs)))
		return e;
	if (m->col_on && (e = vd_mesh_grow_tc(m, (size_t)refs)))
		return e;
	for (uint64_t j = 0; j < refs; j++) {
		int64_t idx;
		if ((e = vd_ac_line(m, &s)) < 0)
			return -e;
		if (e == 0)
			goto cut;
		/* The UV pair after the index: only with colours. */
		if (!(p = vd_parse_int(s, &idx)) || !vd_is_end(*p))
			return vd_ac_fail(m, "line %" PRIu64 ": malformed "
					  "vertex index '%.*s'", m->r.lines,
					  vd_tok40(s), s);
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
			vd_mesh_warn(m, "the file ends after %" PRIu64 " of the %"
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
static int vd_ac_next(struct vd_mesh *m, int *got)
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
			if ((p = vd_kw(s, "OBJECT"))) {
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
					f->name, vd_tok40(s), s);
			}
			/* MATERIAL lines and their AC3Dc kin. */
			if (m->col_on && (p = vd_kw(s, "MATERIAL"))) {
				if ((e = vd_ac_material(m, p)))
					return e;
				continue;
			}
			if (vd_is_word_start(*s))
				continue;
			return vd_ac_fail(m, "line %" PRIu64 ": unexpected "
					  "'%.*s' outside any object", ln,
					  vd_tok40(s), s);
		}
		if ((p = vd_kw(s, "name"))) {
			p = vd_skip_space(p);
			size_t k = strlen(p);
			if (k >= 2 && p[0] == '"' && p[k - 1] == '"') {
				p++;
				k -= 2;
			}
			snprintf(m->ac_name, sizeof m->ac_name, "%.*s",
				 (int)(k > 47 ? 47 : k), p);
		} else if ((p = vd_kw(s, "data"))) {
			if ((e = vd_ac_count(m, p, "data", &n)) ||
			    (e = vd_ac_skip_data(m, n, ln)))
				return e;
		} else if ((p = vd_kw(s, "rot"))) {
			if ((e = vd_ac_numbers(m, p, m->ac_rot, 9, 0, "rot")))
				return e;
		} else if ((p = vd_kw(s, "loc"))) {
			if ((e = vd_ac_numbers(m, p, m->ac_loc, 3, 0, "loc")))
				return e;
		} else if ((p = vd_kw(s, "numvert"))) {
			if ((e = vd_ac_count(m, p, "numvert", &n)) ||
			    (e = vd_ac_vertices(m, n)))
				return e;
		} else if (m->col_on && (p = vd_kw(s, "texture"))) {
			if ((e = vd_ac_texture(m, p)))
				return e;
		} else if (m->col_on && (p = vd_kw(s, "texrep"))) {
			if ((e = vd_ac_numbers(m, p, m->ac_texrep, 2, 0,
					       "texrep")))
				return e;
		} else if (m->col_on && (p = vd_kw(s, "texoff"))) {
			if ((e = vd_ac_numbers(m, p, m->ac_texoff, 2, 0,
					       "texoff")))
				return e;
		} else if ((p = vd_kw(s, "numsurf"))) {
			if ((e = vd_ac_count(m, p, "numsurf", &n)))
				return e;
			m->ac_surf_left = n;
		} else if ((p = vd_kw(s, "kids"))) {
			if ((e = vd_ac_count(m, p, "kids", &n)) ||
			    (e = vd_ac_kids(m, n)))
				return e;
		} else if (vd_kw(s, "OBJECT")) {
			return vd_ac_fail(m, "line %" PRIu64 ": OBJECT before "
					  "the kids line of object '%s'", ln,
					  m->ac_name);
		} else if (vd_kw(s, "SURF") || vd_kw(s, "refs") ||
			   vd_kw(s, "mat")) {
			return vd_ac_fail(m, "line %" PRIu64 ": '%.*s' beyond "
					  "the numsurf count of object '%s'",
					  ln, vd_tok40(s), s, m->ac_name);
		} else if (!vd_is_word_start(*s)) {
			return vd_ac_fail(m, "line %" PRIu64 ": unexpected "
					  "'%.*s' in object '%s' (wrong "
					  "numvert or refs count?)", ln,
					  vd_tok40(s), s, m->ac_name);
		}
		/* Any other word: an attribute we do not need. */
	}
}

static int vd_has_ext(const char *path, const char *ext)
{
	size_t n = strlen(path), e = strlen(ext);
	return n > e && !strcasecmp(path + n - e, ext);
}

/* The detection saw "AC3D"; the rest of the first line is the version. */
static int vd_ac_open(struct vd_mesh *m, const char *path)
{
	char *s;
	size_t len;
	m->kind = MESH_AC3D;
	m->ac_torcs = vd_has_ext(path, ".acc");
	int e = vd_rd_line(&m->r, &s, &len, 0);
	if (e < 0)
		return -e;
	m->body_off = m->r.off + m->r.pos;
	m->body_lines = m->r.lines;
	return VD_OK;
}

/* ------------------------------------------------------ imported scenes
 * glTF, FBX, Collada and 3DS through the importer voxelize-assimp sets
 * (voxdag.h, "imported formats"): the importer reads the whole scene into
 * m->imp; its triangles are then handed out from memory in its order, and
 * their attributes follow the OBJ rule: the material's texture when it
 * loaded and the triangle's corners all have texture coordinates, else
 * the vertices' colours, else the material's colour, else grey. A texture
 * slot stands for one of the scene's textures under one pair of wrap
 * modes (materials may sample one image differently). */

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
static size_t vd_import_bytes(const struct vd_import_scene *s)
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
		path = vd_mesh_path(m, NULL, it->path);
		char *asked = path ? strdup(path) : NULL;
		if (path && asked)
			vd_import_fix_case(&path);
		/* the name as given was not there: if it appears, it is the
		 * texture */
		int e = asked && strcmp(asked, path) ? vd_mesh_note(m, asked)
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
	int slot = vd_mesh_tex_new(m, path);
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

static int vd_import_open(struct vd_mesh *m, const char *path)
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
	size_t bytes = vd_import_bytes(s);
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
		if ((e = vd_mesh_note_as(m, s->sources[i].path, &s->sources[i])))
			return e;
	if (!m->col_on)
		return VD_OK;
	m->col_seen = s->has_colours;
	for (size_t i = 0; i < s->nmats; i++) {
		if ((e = vd_mesh_add_material(m, "")))
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
		    (e = vd_mesh_tex_use(m, m->mats[mi].tex)))
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

static int vd_import_read(struct vd_mesh *m, struct vd_triangle *buf,
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
				e = vd_mesh_nonfinite(m, ix[j], v);
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

static int vd_stl_size_error(struct vd_mesh *m, const unsigned char *head,
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

static int vd_mesh_detect(struct vd_mesh *m, const char *path)
{
	struct vd_rd *r = &m->r;
	size_t want = m->file_bytes < 4096 ? (size_t)m->file_bytes : 4096;
	int e = vd_rd_need(r, want);
	if (e == VD_ERR_TRUNCATED)
		return vd_fail(e, "'%s' shrank while being opened", path);
	if (e)
		return e;
	const unsigned char *head = r->buf;
	size_t hn = r->len;

	if (hn >= 3 && !memcmp(head, "ply", 3) &&
	    (hn == 3 || head[3] == '\n' || head[3] == '\r'))
		return vd_ply_open(m);
	if (hn >= 4 && !memcmp(head, "AC3D", 4))
		return vd_ac_open(m, path);

	if (m->file_bytes >= 84 &&
	    84 + 50 * vd_ld(head + 80, 4, 0) == m->file_bytes) {
		m->kind = MESH_STL_BIN;
		m->stl_count = vd_ld(head + 80, 4, 0);
		m->body_off = 84;
		return vd_rd_seek(r, m->body_off, 0);
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
		return vd_rd_seek(r, 0, 0);
	}
	if (solid || vd_has_ext(path, ".stl"))
		return vd_stl_size_error(m, head, hn);
	if (vd_has_ext(path, ".obj") || vd_looks_like_obj(head, hn)) {
		m->kind = MESH_OBJ;
		return vd_rd_seek(r, 0, 0);
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
		e = vd_import_open(m, path);
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
		return vd_rd_seek(&m->r, 0, 0);
	case MESH_STL_BIN:
		return vd_rd_seek(&m->r, m->body_off, 0);
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
		vd_mesh_free_materials(m);
		return vd_rd_seek(&m->r, m->body_off, m->body_lines);
	default:
		if (m->face_elem == m->nelems) {
			m->done = 1;
			return VD_OK;
		}
		return vd_rd_seek(&m->r, m->body_off, m->body_lines);
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
	return vd_spill_triangle(m->spill, c, m->poly_face, m->poly_line,
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
			if ((e = vd_mesh_spill_open(m)) ||
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
			if (m->done)
				break;
			int got = 0;
			m->poly_n = m->poly_next = 0;
			m->poly_mat = -1;
			m->poly_has_tc = 0;
			if ((e = vd_mesh_next(m, &got)))
				return e;
			if (!got) {
				m->done = 1;
				break;
			}
			if ((e = vd_mesh_poly_done(m)))
				return e;
		}
		if (m->kind == MESH_OBJ)
			m->stats.vertices = m->nverts;
		if ((e = vd_spill_finish(m->spill)))
			return e;
		m->spill_ready = 1;
	}
	size_t ab = vd_mesh_spill_attr_bytes(m);
	while (*n < cap) {
		const uint8_t *rec[VD_SPILL_MAX_TABLES][3], *extra;
		uint32_t v[VD_SPILL_MAX_TABLES][3];
		uint64_t face, line;
		int got;
		if ((e = vd_spill_next(m->spill, rec, v, &face, &line, &extra,
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
				return vd_mesh_nonfinite(m,
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
	case MESH_OBJ: return vd_obj_next(m, got);
	case MESH_STL_ASCII: return vd_stl_ascii_next(m, got);
	case MESH_AC3D: return vd_ac_next(m, got);
	default: return vd_ply_next(m, got);
	}
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
		e = vd_stl_bin_read(m, buf, cap, &k);
		for (size_t i = 0; attr && i < k; i++) {
			memset(&attr[i], 0, sizeof attr[i]);
			memset(attr[i].rgb, VD_GREY, sizeof attr[i].rgb);
			attr[i].texture = -1;
		}
	} else if (m->kind == MESH_IMPORT) {
		e = vd_import_read(m, buf, attr, cap, &k);
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
			if (m->done)
				break;
			int got = 0;
			m->poly_n = m->poly_next = 0;
			m->poly_mat = -1;
			m->poly_has_tc = 0;
			if ((e = vd_mesh_next(m, &got)))
				break;
			if (!got) {
				m->done = 1;
				break;
			}
			if ((e = vd_mesh_poly_done(m)))
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

int vd_mesh_rewind(struct vd_mesh *m)
{
	if (!m)
		return vd_fail(VD_ERR_ARG, "vd_mesh_rewind: NULL mesh");
	m->err = 0;
	m->stats.triangles_read = 0;
	if (m->spill_ready) {
		/* the join is the whole mesh: no file to read again */
		m->spill_skip = 0;
		return vd_spill_rewind(m->spill);
	}
	return vd_mesh_restart(m);
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
		   vd_spill_memory_bytes(m->spill) + vd_import_bytes(&m->imp);
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
	vd_mesh_free_materials(m);
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
	vd_spill_close(m->spill);
	free(m->spill_dir);
	for (size_t i = 0; i < m->nelems; i++)
		free(m->elems[i].props);
	free(m->elems);
	vd_import_scene_release(&m->imp);
	free(m);
}
