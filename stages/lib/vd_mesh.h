/* vd_mesh.h - triangle meshes in (io/): the streaming readers, surface colours
 * and textures, the sources a voxelization read, imported formats.
 */
#ifndef VD_MESH_H
#define VD_MESH_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include "vd_common.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---------------------------------------------------------------- meshes
 * Streaming triangle readers for PLY (binary little/big endian and ASCII),
 * OBJ, STL (binary and ASCII) and AC3D (.ac, FlightGear's model format).
 * Indexed formats keep their vertex positions in memory (12 bytes per
 * vertex; AC3D only those of the object being read, already moved to world
 * coordinates by the object's and its ancestors' rot and loc); triangles
 * are streamed. */

struct vd_triangle {
	float v[3][3]; /* three vertices, x y z each, world units */
};

/* What the reader saw. A face with fewer than 3 corners is dropped and
 * counted, and so is an AC3D line or closed-line surface (it bounds no
 * area); a face with more is fan-triangulated (an AC3D triangle strip is
 * cut into its triangles and counted as split). A vertex with a NaN or
 * infinite coordinate is an error (VD_ERR_RANGE) as soon as a face uses it;
 * unused vertices are never checked. */
struct vd_mesh_stats {
	uint64_t triangles_read;     /* triangles handed to the caller */
	uint64_t faces_dropped_short;/* faces with fewer than 3 corners */
	uint64_t polygons_split;     /* faces with more than 3 corners */
	uint64_t vertices;           /* vertices declared (indexed formats) */
};

struct vd_mesh;

/* Opens `path`, detecting the format from its first bytes (PLY magic,
 * "AC3D" magic, STL binary size rule / "solid", OBJ otherwise if the
 * extension is .obj or the first statement is an OBJ one). Parses the
 * header (PLY: also loads the vertices); the body is read by
 * vd_mesh_read(). Errors: VD_ERR_IO (also a
 * directory), VD_ERR_EMPTY (0-byte file), VD_ERR_UNSUPPORTED (unknown
 * format), VD_ERR_FORMAT (bad header), VD_ERR_TRUNCATED (also counts the
 * file cannot hold), VD_ERR_TRAILING (binary STL longer than its count). */
int vd_mesh_open(struct vd_mesh **out, const char *path);
/* As vd_mesh_open, but the vertex array may not grow beyond
 * `max_vertex_bytes` (0: no limit; an OBJ read with colours counts its
 * texture coordinates against it too, 8 bytes each): VD_ERR_BUDGET, from
 * vd_mesh_open_limited for a PLY whose header asks for more, from
 * vd_mesh_read for other formats, before the memory is taken. */
int vd_mesh_open_limited(struct vd_mesh **out, const char *path,
			 uint64_t max_vertex_bytes);
/* As vd_mesh_open_limited, but vertices (and OBJ texture coordinates)
 * over the limit are not refused: the faces are resolved against them by
 * an external join in unlinked temporary files of `spill_dir` (which must
 * exist when the reading starts), so memory stays within
 * `max_vertex_bytes` (at least 1 MiB) whatever the mesh. AC3D spills
 * when one object's vertices pass the limit. The triangles, their order
 * and their attributes are those of the in-memory reader; a spilled mesh
 * is read whole on its first vd_mesh_read() (OBJ and AC3D: again from the
 * start when the limit is passed mid-file) and rewinds without reading
 * the file again. Errors besides vd_mesh_open_limited's: VD_ERR_IO naming
 * the spill directory (a full disk); VD_ERR_RANGE for a spilled AC3D file
 * with more than 2^32 - 1 vertices in all its objects together. */
int vd_mesh_open_spill(struct vd_mesh **out, const char *path,
		       uint64_t max_vertex_bytes, const char *spill_dir);

/* Reads up to `cap` triangles into `buf` and sets *n; *n == 0 means the
 * end of the mesh. Errors: VD_ERR_FORMAT (syntax, with the line or byte
 * offset in the detail), VD_ERR_RANGE (index out of range, non-finite
 * coordinate), VD_ERR_TRUNCATED (file ends inside the body). An OBJ face
 * may only use vertices defined before it (VD_ERR_RANGE otherwise); an
 * AC3D surface only its own object's vertices. After
 * an error every read repeats it until vd_mesh_rewind(). */
int vd_mesh_read(struct vd_mesh *m, struct vd_triangle *buf, size_t cap,
		 size_t *n);

/* Restarts reading at the first triangle (for a second pass); counts
 * restart too. */
int vd_mesh_rewind(struct vd_mesh *m);

/* "ply-binary-le", "ply-ascii", "obj", "stl-binary", "stl-ascii", "ac3d",
 * ... */
const char *vd_mesh_format(const struct vd_mesh *m);
/* Bytes of memory the reader holds (vertex arrays, read buffer), for
 * budgets. OBJ vertices are collected while reading, so for OBJ this is
 * final only after a whole pass. */
size_t vd_mesh_memory_bytes(const struct vd_mesh *m);
const struct vd_mesh_stats *vd_mesh_stats(const struct vd_mesh *m);
/* The bounds of the vertices, when the reader holds them all before any
 * face is read: a PLY's vertex element is loaded at open, and when it is
 * in memory (not spilled) and finite, sets lo[] and hi[] and returns 1;
 * else returns 0 (other formats, which meet vertices among the faces).
 * The triangles' bounds lie inside; they are equal unless a face-less
 * vertex reaches further, which the caller must check when it matters. */
int vd_mesh_vertex_bounds(const struct vd_mesh *m, float lo[3], float hi[3]);
void vd_mesh_close(struct vd_mesh *m);

/* ------------------------------------------------------- surface colours
 * Colour is read only when the caller opens the mesh with `colours` set
 * (vd_mesh_open_opts); otherwise every reader does exactly what it does
 * for geometry alone. With colours, vd_mesh_read_attr() hands out, beside
 * each triangle, a vd_tri_attr: the triangle's own colour data, whole, so
 * that it can be stored with the triangle (voxelize's bins) and evaluated
 * later at any point of the triangle without the reader.
 *
 * Sources, by format (a triangle takes the first that applies):
 * - a texture: the material's texture (OBJ map_Kd, AC3D object texture)
 *   loaded, and every corner has texture coordinates (OBJ vt, AC3D refs);
 *   the texture replaces the material colour (it is not multiplied);
 * - vertex colours: PLY red/green/blue (or diffuse_red/...; uchar as is,
 *   ushort scaled from 0..65535, float/double from 0..1, clamped; alpha
 *   ignored), OBJ `v x y z r g b` (0..1);
 * - the material colour: OBJ Kd, AC3D MATERIAL rgb;
 * - grey (VD_GREY) otherwise (STL, faces without a material).
 * Colours are sRGB, 8 bits: interpolated linearly in sRGB over the
 * triangle and rounded to nearest. Texture coordinates wrap (repeat), as
 * OBJ and AC3D renderers do; v = 0 is the image's bottom row (both formats
 * follow OpenGL). A non-finite texture coordinate is VD_ERR_RANGE. A
 * texture that is missing or cannot be decoded (PNG by libpng, JPEG by
 * libjpeg-turbo, TGA/BMP/others by stb_image) gives one warning naming it
 * and the material colour is used instead; with `strict` it is an error
 * (VD_ERR_IO / VD_ERR_FORMAT), and so is a missing MTL file. Spec:
 * schemas/colour-rule.md. */
#define VD_GREY 128

/* How a texture coordinate outside 0..1 is read: repeat (OBJ, AC3D and
 * the default), clamp to the edge texels, or mirrored repeat (glTF's and
 * Assimp's samplers may ask for either). */
enum vd_tex_wrap { VD_WRAP_REPEAT = 0, VD_WRAP_CLAMP, VD_WRAP_MIRROR };

/* A decoded texture: RGB8 texels, rows top first. */
struct vd_texture {
	uint32_t width, height;
	uint8_t *rgb;          /* 3 * width * height bytes */
	uint8_t wrap[2];       /* enum vd_tex_wrap in u and in v */
};

/* Decodes the image at `path` (format from its first bytes). Errors:
 * VD_ERR_IO (cannot open), VD_ERR_FORMAT (corrupt or undecodable, the
 * decoder's reason in the detail), VD_ERR_UNSUPPORTED (known but
 * unsupported format, e.g. a colour-mapped SGI image), VD_ERR_RANGE (wider or higher than
 * 32768 texels). Free with vd_texture_release(). */
int vd_texture_load(struct vd_texture *t, const char *path);
/* As vd_texture_load, for an image file's `bytes` bytes at `data` (an
 * image embedded in a scene); `name` stands for the path in messages. */
int vd_texture_load_mem(struct vd_texture *t, const void *data, size_t bytes,
			const char *name);
void vd_texture_release(struct vd_texture *t);

/* Bilinear sample at (u, v) (finite), wrapping in both directions as
 * t->wrap says (vd_texture_load: repeat), v = 0 the bottom row: texel (i, j) (row j from the top) has its centre at
 * u = (i + 0.5) / width, v = 1 - (j + 0.5) / height. Rounds to nearest. */
void vd_texture_sample(const struct vd_texture *t, double u, double v,
		       uint8_t rgb[3]);

/* A triangle's colour data. `texture` >= 0: texels of
 * vd_mesh_texture(mesh, texture) at the corners' `uv`; otherwise the
 * corners' `rgb`. Plain data: may be copied and stored as bytes by the
 * process that read it (texture indices belong to that mesh reader). */
struct vd_tri_attr {
	uint8_t rgb[3][3];     /* sRGB colour of each corner */
	uint8_t pad[3];        /* 0 */
	int32_t texture;       /* texture index, -1: none */
	float uv[3][2];        /* texture coordinates of each corner */
};

/* The colour at barycentric coordinates b (b0 + b1 + b2 = 1, each in
 * [0, 1]) of a triangle with attributes `a`; `tex` is the texture `a`
 * names (NULL when a->texture < 0). */
void vd_tri_attr_colour(const struct vd_tri_attr *a,
			const struct vd_texture *tex, const double b[3],
			uint8_t rgb[3]);

/* vd_tri_attr_colour in two steps, for a caller with many colours to
 * find: vd_tri_attr_texels finds the four texels the colour at b blends
 * and starts fetching them into the cache (returns 0, q untouched, when
 * `a` has no texture: then vd_tri_attr_colour), vd_texel_quad_colour
 * blends them later, once the memory latencies of several have
 * overlapped. The same colour as vd_tri_attr_colour, bit for bit. */
struct vd_texel_quad {
	const uint8_t *p[4];   /* upper row left, right; lower row */
	double ax, ay;         /* weights of the right column, lower row */
};
int vd_tri_attr_texels(const struct vd_tri_attr *a,
		       const struct vd_texture *tex, const double b[3],
		       struct vd_texel_quad *q);
void vd_texel_quad_colour(const struct vd_texel_quad *q, uint8_t rgb[3]);

struct vd_mesh_open_opts {
	uint64_t max_vertex_bytes; /* as vd_mesh_open_limited; 0: no limit */
	int colours;               /* decode colours (vd_mesh_read_attr) */
	int strict;                /* missing texture or MTL is an error */
	/* Receives each warning (one line, no newline; e.g. a texture that
	 * cannot be read); NULL: warnings are dropped. */
	void (*warn)(void *ctx, const char *line);
	void *warn_ctx;
	/* As vd_mesh_open_spill's: vertices (and OBJ texture coordinates)
	 * over max_vertex_bytes are joined with the faces on disk in this
	 * directory; NULL: refused. A spilled mesh hands out the same
	 * triangles and attributes. */
	const char *spill_dir;
};

/* vd_mesh_open_limited with options. */
int vd_mesh_open_opts(struct vd_mesh **out, const char *path,
		      const struct vd_mesh_open_opts *o);

/* As vd_mesh_read, filling attr[0..*n) too. The mesh must have been opened
 * with `colours` (else VD_ERR_ARG). */
int vd_mesh_read_attr(struct vd_mesh *m, struct vd_triangle *buf,
		      struct vd_tri_attr *attr, size_t cap, size_t *n);

/* 1 when the mesh (opened with `colours`) has a colour source: PLY vertex
 * colours, OBJ vertex colours or a material applied by usemtl, any AC3D
 * surface. Final after one whole pass (known at open for PLY). */
int vd_mesh_has_colours(const struct vd_mesh *m);

/* Texture `i` of a vd_tri_attr, NULL if there is none such. Valid until
 * vd_mesh_close(); safe to call from several threads once reading ended. */
const struct vd_texture *vd_mesh_texture(const struct vd_mesh *m, int i);

/* Textures the mesh referred to that could not be loaded, so far. */
uint64_t vd_mesh_textures_missing(const struct vd_mesh *m);
/* Textures loaded, so far. */
uint64_t vd_mesh_textures_loaded(const struct vd_mesh *m);

/* A file the reader read besides the mesh (an OBJ's MTL files and the
 * textures its faces use, an AC3D file's textures, the buffers and images
 * of an imported scene), or a name it looked for and could not read: what
 * is read from the mesh depends on each. `found` 0: not there or
 * unreadable (xxh3 and size 0). The content is hashed just before the
 * reader opens it, so a change made while or after it reads is a
 * difference, never missed. */
struct vd_mesh_source {
	char *path;            /* as the reader opened it (relative names stay
				* relative to the working directory) */
	uint64_t xxh3, size;   /* vd_file_xxh3 of the whole file */
	int found;
};
/* The sources so far, in the order first read, each path once (complete
 * after a whole pass); *n receives their count. Owned by the mesh, valid
 * until the next read or vd_mesh_close(). Without colours
 * (vd_mesh_open_opts.colours 0) an OBJ's MTL files and textures are not
 * read, so not listed; an imported scene's buffers are, colours or not. */
const struct vd_mesh_source *vd_mesh_sources(const struct vd_mesh *m,
					     size_t *n);

/* vd_file_xxh3 for a source: VD_ERR_IO unless `path` is a regular file
 * read whole (a name such as /dev/zero or a FIFO, which a mesh may give,
 * is not read: it counts as unreadable). */
int vd_source_xxh3(const char *path, uint64_t *hash, uint64_t *size);
/* Writes `path` (a "sources" file, schemas/manifest.md) listing s[0..n),
 * atomically. Returns VD_OK or VD_ERR_IO. */
int vd_sources_write(const char *path, const struct vd_mesh_source *s,
		     size_t n);
/* Checks the sources file `path` against the files it lists (relative
 * names from the working directory): each found one must still have its
 * size and XXH3, each other must still be unreadable. Returns VD_OK;
 * VD_ERR_MISMATCH when one differs (the detail names the first and how:
 * "'x.png' changed", "... is missing or unreadable", "... can be read
 * now"); VD_ERR_FORMAT for a malformed file; VD_ERR_IO when it cannot be
 * read. */
int vd_sources_check(const char *path);
/* The name of voxelize's sources file in its OUTDIR. */
#define VD_SOURCES_NAME "sources"

/* ----------------------------------------------------- imported formats
 * glTF 2.0 (.gltf, .glb), FBX (.fbx), Collada (.dae) and 3DS (.3ds) are
 * read by an importer that loads the whole scene in memory (Assimp, in
 * io/assimp.cc). Only voxelize-assimp links it and sets it with
 * vd_mesh_set_importer(), so the other programs do not carry the library
 * (voxelize execs voxelize-assimp for these names). vd_mesh_open*() then
 * hands out the scene's triangles in world space, in the importer's
 * order, with vd_tri_attr colours by the same rule as OBJ's
 * (schemas/colour-rule.md, "Imported formats"). The scene is held whole:
 * its vertices, triangles and attributes (about 40 bytes a vertex and 16 a
 * triangle) count against max_vertex_bytes (VD_ERR_BUDGET beyond it; no
 * spill). */
struct vd_import_scene; /* io/mesh/mesh_import.h */

/* Reads the scene at `path` into *out (zeroed first; the caller releases
 * it with vd_import_scene_release). Returns VD_OK or an error code with
 * a detail line. */
typedef int (*vd_mesh_importer)(const char *path, struct vd_import_scene *out);

/* Sets the importer vd_mesh_open*() uses for names vd_mesh_is_imported()
 * accepts (NULL: none, and such a name is VD_ERR_UNSUPPORTED). Call it
 * before opening meshes; it is process-wide. */
void vd_mesh_set_importer(vd_mesh_importer fn);

/* 1 when `path` ends (any case) in .gltf, .glb, .fbx, .dae or .3ds. */
int vd_mesh_is_imported(const char *path);

/* The Assimp importer (a vd_mesh_importer). Never throws: Assimp's
 * failures are VD_ERR_FORMAT with its message in the detail, VD_ERR_EMPTY
 * for a scene without triangles, VD_ERR_NOMEM, VD_ERR_RANGE for more than
 * 2^32 - 1 vertices. */
int vd_assimp_import(const char *path, struct vd_import_scene *out);

#ifdef __cplusplus
}
#endif

#endif /* VD_MESH_H */
