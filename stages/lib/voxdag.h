/* voxdag.h - the one public header of libvoxdag, the library every voxdag
 * stage links.
 *
 * Conventions that hold everywhere below:
 * - Functions that can fail return an `int` error code: VD_OK (0) or one of
 *   enum vd_error. vd_strerror() names it; vd_error_detail() gives the
 *   calling thread's one-line detail of the last failure ("line 12: vertex
 *   index 900 out of range"), empty when there is none.
 * - `_open`/`_close` acquire and release a handle; `_free` releases memory
 *   the library allocated and accepts NULL.
 * - Grid conventions: a grid of `levels` L has 2^L voxels per side. Node
 *   levels run from 0 (the root) to L-1 (2x2x2 masks); level L is the voxels.
 *   Child index c = 4*x + 2*y + z (bit 2 = +X, bit 1 = +Y, bit 0 = +Z).
 *   A Morton code is the sequence of child indices from the root, most
 *   significant first, so sorting by Morton code is depth-first order.
 * - Bricks: a brick is the 4x4x4 block of voxels below one level-(L-2) node,
 *   stored as a uint64_t whose bit b is the voxel with local Morton code b
 *   (b = morton3(x&3, y&3, z&3)). Byte c of a brick is therefore the 2x2x2
 *   mask of the brick's child c, whose bit c' is that child's voxel c'.
 *   A brick key is the Morton code of the brick's coordinates (voxel >> 2)
 *   in the whole grid. Grids with L < 2 have one brick, key 0, partly used.
 */
#ifndef VOXDAG_H
#define VOXDAG_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#ifdef __cplusplus
extern "C" {
#endif

#define VD_VERSION_STRING "0.1.0"

/* Every stage's own version. It is part of every resume key the runner
 * computes and of the provenance each file records, so outputs written by
 * older code are rebuilt, never reused. RULE: bump a stage's number in the
 * same commit that changes the bytes or the format of what it writes, and
 * say why beside it. */
#define VD_STAGE_VERSIONS(X)                                                 \
	X("voxelize", 6)       /* 6: sources; 5: .vdb colours (see below); \
				  4: SGI textures; 3: .col; 2: manifest */  \
	/* A .vdb input runs as `voxelize` (which execs voxelize-vdb), so the  \
	 * runner's keys and the chunks' provenance carry voxelize's number:  \
	 * bump both. */                                                      \
	X("voxelize-vdb", 3)   /* 3: .col from a Vec3 grid; 2: manifest */   \
	X("svo-to-dag", 2)     /* 2: stage_version in provenance */          \
	X("symmetry-merge", 2) /* 2: the same */                             \
	X("encode", 3)         /* 3: ssvdag48 columns; 2: manifest */        \
	X("render", 1)                                                      \
	X("lossy-cluster", 3)  /* 3: balanced representatives; seconds_cut */\
	X("edit", 2)           /* 2: paint, colours, cpu_seconds per op */ \
	X("colorize", 2)       /* 2: exact single-colour VBR blocks */

/* The version of the stage named `tool` (as in out/bin/), 0 if unknown. */
int vd_stage_version(const char *tool);

/* Largest grid depth: voxel Morton codes need 3*L bits of a uint64_t. */
#define VD_MAX_LEVELS 21

/* ------------------------------------------------------------------ errors */

enum vd_error {
	VD_OK = 0,
	VD_ERR_IO,             /* a system call failed; the detail has strerror */
	VD_ERR_NOMEM,          /* allocation failed */
	VD_ERR_NOT_CHUNK,      /* file does not start with the chunk magic */
	VD_ERR_NEWER_VERSION,  /* chunk format major version newer than ours */
	VD_ERR_WRONG_KIND,     /* chunk of another kind than the caller expects */
	VD_ERR_TRUNCATED,      /* file ends before its structure does */
	VD_ERR_CHECKSUM,       /* a stored checksum does not match the bytes */
	VD_ERR_TRAILING,       /* bytes after the end of the structure */
	VD_ERR_CORRUPT,        /* checksums match but the content is inconsistent */
	VD_ERR_FORMAT,         /* malformed input file (mesh syntax, bad header) */
	VD_ERR_UNSUPPORTED,    /* valid but unsupported input (format, feature) */
	VD_ERR_RANGE,          /* a value out of its allowed range */
	VD_ERR_BUDGET,         /* the work cannot fit the memory budget */
	VD_ERR_EMPTY,          /* nothing to work on (no triangles, no voxels) */
	VD_ERR_ARG,            /* invalid argument from the caller */
	VD_ERR_COMPRESS,       /* zstd failed */
	VD_ERR_MISMATCH,       /* inputs that must agree do not (depth, cells) */
	VD_ERR_INTERNAL,       /* a bug; the detail says where */
	VD_ERR_COUNT_
};

/* Returns a static, one-phrase description of `err` ("truncated file"). */
const char *vd_strerror(int err);

/* Returns the calling thread's detail for the last error set by the library
 * (never NULL; "" when none). Valid until the next library call on this
 * thread. */
const char *vd_error_detail(void);

/* Sets the calling thread's detail (printf format) and returns `err`, so
 * callers can write `return vd_fail(VD_ERR_RANGE, "index %u", i);`. */
int vd_fail(int err, const char *fmt, ...)
	__attribute__((format(printf, 2, 3)));

/* Clears the calling thread's detail. */
void vd_error_clear(void);

/* ------------------------------------------------------------ Morton maths */

/* Spreads the low 21 bits of v so that bit i lands at bit 3i. */
static inline uint64_t vd_morton_spread(uint64_t v)
{
	v &= 0x1fffff;
	v = (v | v << 32) & 0x1f00000000ffffULL;
	v = (v | v << 16) & 0x1f0000ff0000ffULL;
	v = (v | v << 8) & 0x100f00f00f00f00fULL;
	v = (v | v << 4) & 0x10c30c30c30c30c3ULL;
	v = (v | v << 2) & 0x1249249249249249ULL;
	return v;
}

/* Inverse of vd_morton_spread: gathers bits 3i into bit i. */
static inline uint64_t vd_morton_compact(uint64_t v)
{
	v &= 0x1249249249249249ULL;
	v = (v ^ (v >> 2)) & 0x10c30c30c30c30c3ULL;
	v = (v ^ (v >> 4)) & 0x100f00f00f00f00fULL;
	v = (v ^ (v >> 8)) & 0x1f0000ff0000ffULL;
	v = (v ^ (v >> 16)) & 0x1f00000000ffffULL;
	v = (v ^ (v >> 32)) & 0x1fffff;
	return v;
}

/* Morton code of (x, y, z), each < 2^21; x is the most significant. */
static inline uint64_t vd_morton3(uint32_t x, uint32_t y, uint32_t z)
{
	return vd_morton_spread(x) << 2 | vd_morton_spread(y) << 1 |
	       vd_morton_spread(z);
}

static inline void vd_morton3_decode(uint64_t m, uint32_t *x, uint32_t *y,
				     uint32_t *z)
{
	*x = (uint32_t)vd_morton_compact(m >> 2);
	*y = (uint32_t)vd_morton_compact(m >> 1);
	*z = (uint32_t)vd_morton_compact(m);
}

/* --------------------------------------------------------- world transform */

/* Where the grid sits in the world. The cube's side is the largest extent
 * of the input's tight bounding box, centred on the box centre (the SymVox
 * convention, see schemas/chunk-format.md); bbox and side are kept as float32
 * because the SymVox encodings store them so. */
struct vd_transform {
	float bbox_min[3];   /* tight bounding box of the input, world units */
	float bbox_max[3];
	float root_side;     /* side of the cube, world units */
	double origin[3];    /* world position of the grid's (0,0,0) corner */
	double voxel_size;   /* world units per voxel at the grid's depth */
};

/* Fills `t` for the given tight bounding box and grid depth. Returns
 * VD_ERR_EMPTY if the box has zero extent on every axis, VD_ERR_RANGE if it
 * is not finite. */
int vd_transform_init(struct vd_transform *t, const float bbox_min[3],
		      const float bbox_max[3], int levels);

/* 1 when `a` and `b` place a grid identically: every field (bounding box,
 * root side, origin, voxel size) has the same bits, so -0 and +0 differ (the
 * encodings store the box's bits) and a NaN equals itself. The one
 * comparison used wherever chunks of one grid are combined. */
int vd_transform_equal(const struct vd_transform *a,
		       const struct vd_transform *b);

/* -------------------------------------------------------------- chunk files
 * The binary format every stage reads and writes; specified in
 * schemas/chunk-format.md. A writer streams sections to a temporary file and
 * renames it to the final name only in vd_chunk_writer_commit(), so a killed
 * writer never leaves a file that looks complete. A reader verifies every
 * checksum before handing out any content. */

#define VD_CHUNK_MAJOR 1
#define VD_CHUNK_MINOR 0

enum vd_chunk_kind {
	VD_KIND_ANY = 0,     /* for readers: accept every kind */
	VD_KIND_SVO = 1,     /* sparse voxel octree bricks of one L0 cell */
	VD_KIND_DAG = 2,     /* SVDAG: identical subtrees merged */
	VD_KIND_SSVDAG = 3,  /* SSVDAG: subtrees equal up to reflection merged */
	VD_KIND_ENCODED = 4, /* compact encodings (encode stage) */
	VD_KIND_COLOURS = 5, /* voxel colours of one cell (voxelize) */
	VD_KIND_CPACK = 6,   /* a scene's colours compressed (colorize) */
	VD_KIND_SSVDAG48 = 7, /* subtrees equal under the 48 cube symmetries
				 merged (symmetry-merge --group 48) */
	VD_KIND_COUNT_
};

/* Returns "svo", "dag", ... or "unknown". */
const char *vd_chunk_kind_name(uint32_t kind);

/* Section tags are four ASCII bytes read as a little-endian uint32. */
#define VD_TAG(a, b, c, d)                                                   \
	((uint32_t)(a) | (uint32_t)(b) << 8 | (uint32_t)(c) << 16 |          \
	 (uint32_t)(d) << 24)
#define VD_TAG_PROV VD_TAG('P', 'R', 'O', 'V') /* provenance text */
#define VD_TAG_BRKS VD_TAG('B', 'R', 'K', 'S') /* SVO bricks, see the spec */

/* The fixed part of a chunk header. */
struct vd_chunk_header {
	uint16_t major, minor;  /* format version of the file (filled by writer) */
	uint32_t kind;          /* enum vd_chunk_kind */
	uint32_t levels;        /* grid depth L */
	uint32_t chunk_level;   /* level of the cell this chunk covers (L0) */
	uint64_t cell_morton;   /* Morton code of the cell at chunk_level */
	struct vd_transform transform;
	/* Non-empty node counts inside the cell for levels chunk_level..levels
	 * (level `levels` is the voxel count): level_count == levels -
	 * chunk_level + 1 entries, at most VD_MAX_LEVELS + 1. */
	uint32_t level_count;
	uint64_t level_nodes[VD_MAX_LEVELS + 1];
};

struct vd_chunk_writer;

/* Creates `path`.tmp.<pid> and writes a provisional header. `h->major` and
 * `h->minor` are ignored (the writer's version is written). `provenance` is
 * a text such as "tool=voxelize version=0.1.0 args=..." stored in a PROV
 * section; NULL for none. On success *out must later go to exactly one of
 * vd_chunk_writer_commit() or vd_chunk_writer_abort(). */
int vd_chunk_writer_open(struct vd_chunk_writer **out, const char *path,
			 const struct vd_chunk_header *h,
			 const char *provenance);

/* Starts a section; data is streamed through zstd at `zstd_level` (0 means
 * the section's default: level 1 for BRKS, 3 for the rest, as measured in
 * schemas/chunk-format.md; negative stores the bytes uncompressed). Only
 * one section is open at a time. */
int vd_chunk_writer_begin(struct vd_chunk_writer *w, uint32_t tag,
			  int zstd_level);
/* Appends `n` bytes to the open section. */
int vd_chunk_writer_write(struct vd_chunk_writer *w, const void *data,
			  size_t n);
/* Closes the open section. */
int vd_chunk_writer_end(struct vd_chunk_writer *w);
/* begin + write + end in one call. */
int vd_chunk_writer_section(struct vd_chunk_writer *w, uint32_t tag,
			    const void *data, size_t n);

/* Writes section `tag` of `raw_size` raw bytes at its default level as
 * zstd frames of VD_CHUNK_FRAME_BYTES raw bytes each (the last shorter),
 * each declaring its content size, compressed on up to `threads` threads;
 * fill(ctx, offset, buf, n) writes the raw bytes [offset, offset + n) into
 * buf, from any thread (offset is a multiple of VD_CHUNK_FRAME_BYTES). The
 * frame size is fixed, so the file does not depend on `threads`; readers
 * decompress the frames in parallel (vd_chunk_read_section_mt). Memory:
 * about 3 * threads frames. No section may be open.
 *
 * With `planes`, the raw bytes are an array of 4-byte little-endian
 * elements (`raw_size` a multiple of 4, else VD_ERR_ARG), stored with
 * codec 2: each frame's elements split into 4 byte planes (all first
 * bytes, then all second bytes, ...) before zstd. Slowly varying indices
 * then leave the high planes nearly constant: on DAG child indices zstd
 * level 1 runs 2-3x faster and stores 20% fewer bytes. Readers undo it
 * (vd_chunk_read_section gives the raw bytes); readers before codec 2
 * refuse the file ("codec 2"). */
#define VD_CHUNK_FRAME_BYTES (2u << 20)
int vd_chunk_writer_frames(struct vd_chunk_writer *w, uint32_t tag,
			   uint64_t raw_size,
			   void (*fill)(void *ctx, uint64_t offset,
					uint8_t *buf, size_t n),
			   void *ctx, int threads, int planes);

/* Replaces the per-level counts of the header (they are often known only
 * after the sections are written). `level_count` must equal the one given
 * at open. */
int vd_chunk_writer_set_counts(struct vd_chunk_writer *w,
			       const uint64_t *level_nodes,
			       uint32_t level_count);

/* Writes the footer, flushes, fsyncs and renames the file to its final
 * name. Frees `w` whatever the outcome; on failure the temporary file is
 * removed and nothing is left at the final path by this writer. */
int vd_chunk_writer_commit(struct vd_chunk_writer *w);

/* Removes the temporary file and frees `w`. Accepts NULL. */
void vd_chunk_writer_abort(struct vd_chunk_writer *w);

struct vd_chunk;

/* Reads and verifies the whole file `path`: magic, version, header checksum,
 * kind (unless `kind` is VD_KIND_ANY), structure, whole-file and section
 * checksums. Distinct errors for: not a chunk file, newer major version,
 * wrong kind, truncated, checksum mismatch, trailing bytes. The detail names
 * what was found. On success the caller frees *out with vd_chunk_free(). */
int vd_chunk_open(struct vd_chunk **out, const char *path, uint32_t kind);

/* Reads only the header of `path` (for planning: sizes and counts without
 * reading the whole file), checking magic, version and header checksum.
 * The rest of the file is not verified. */
int vd_chunk_read_header(const char *path, struct vd_chunk_header *h);

/* The same on an in-memory image of `size` bytes (copied). */
int vd_chunk_open_mem(struct vd_chunk **out, const void *data, size_t size,
		      uint32_t kind);

const struct vd_chunk_header *vd_chunk_header(const struct vd_chunk *c);

/* Decompresses section `tag` into a new buffer (*data, free with free();
 * *data is non-NULL even for an empty section) of *size bytes. Returns
 * VD_ERR_CORRUPT if the section is missing (detail names it). */
int vd_chunk_read_section(const struct vd_chunk *c, uint32_t tag,
			  void **data, size_t *size);

/* The same, a section of several zstd frames decompressed on up to
 * `threads` threads (one frame, or threads 1: as above). */
int vd_chunk_read_section_mt(const struct vd_chunk *c, uint32_t tag,
			     void **data, size_t *size, int threads);

/* Returns 1 if section `tag` is present. */
int vd_chunk_has_section(const struct vd_chunk *c, uint32_t tag);

/* The provenance text ("" if none); owned by `c`. */
const char *vd_chunk_provenance(const struct vd_chunk *c);

/* Number of sections and the tag of section i, for listing. */
uint32_t vd_chunk_section_count(const struct vd_chunk *c);
uint32_t vd_chunk_section_tag(const struct vd_chunk *c, uint32_t i);

void vd_chunk_free(struct vd_chunk *c);

/* ------------------------------------------------------------------- SVO
 * The content of an SVO chunk: the non-empty bricks of one cell in Morton
 * order. This is also the in-memory form stages pass around. */
struct vd_svo {
	int levels;            /* grid depth L */
	int chunk_level;       /* L0 of the cell */
	uint64_t cell_morton;  /* cell Morton code at chunk_level */
	size_t count;          /* number of non-empty bricks */
	uint64_t *keys;        /* brick keys, strictly increasing */
	uint64_t *masks;       /* brick masks, never 0 */
};

/* Reads an SVO chunk file and verifies that its bricks are strictly
 * increasing, non-empty, inside the cell and the grid, and agree with the
 * header's counts. Free with vd_svo_release(). */
int vd_svo_load(struct vd_svo *svo, struct vd_chunk_header *h,
		const char *path);

/* Same, from an already opened chunk of kind SVO. */
int vd_svo_from_chunk(struct vd_svo *svo, const struct vd_chunk *c);
/* The same, the bricks' zstd frames decompressed on up to `threads`. */
int vd_svo_from_chunk_mt(struct vd_svo *svo, const struct vd_chunk *c,
			 int threads);

/* Computes the per-level non-empty node counts of the bricks in `svo` for
 * levels chunk_level..levels into counts[0..levels-chunk_level]. */
void vd_svo_count_levels(const struct vd_svo *svo, uint64_t *counts);

/* Writes `svo` as an SVO chunk file at `path` (atomic). `t` is the world
 * transform, `provenance` as for vd_chunk_writer_open(). */
int vd_svo_save(const struct vd_svo *svo, const struct vd_transform *t,
		const char *path, const char *provenance);

void vd_svo_release(struct vd_svo *svo);

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
struct vd_import_scene; /* io/mesh_import.h */

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

/* ---------------------------------------------------- triangle/box overlap
 * Voxelization decides overlap exactly on snapped coordinates: a vertex is
 * placed on a lattice of 2^-VD_SNAP_ROOT_BITS of the cube's side
 * (vd_snap_triangle), and then every test is integer arithmetic without
 * rounding, so touching counts as overlap with no epsilon and results never
 * depend on evaluation order. The lattice is the same at every grid depth,
 * so a coarse voxel is set exactly when one of its children is; 2^-24 of
 * the side is about what float32 coordinates resolve, and a voxel at depth
 * L is 2^(24-L) lattice steps (8 at the deepest, L = 21). */
#define VD_SNAP_ROOT_BITS 24

/* Lattice steps per voxel at grid depth `levels`. */
static inline int64_t vd_snap_voxel(int levels)
{
	return (int64_t)1 << (VD_SNAP_ROOT_BITS - levels);
}

/* Snapped coordinates of a triangle, in lattice steps from the grid's
 * (0,0,0) corner. */
struct vd_snapped_tri {
	int64_t v[3][3];
};

/* Snaps `t` onto the lattice of `tr`. Returns VD_ERR_RANGE if a coordinate
 * is not finite. */
int vd_snap_triangle(struct vd_snapped_tri *out, const struct vd_triangle *t,
		     const struct vd_transform *tr);

/* Returns 1 if the closed triangle and the closed axis-aligned cube
 * [lo, lo + size] (in voxels of a grid of depth `levels`, per axis)
 * overlap, else 0. Degenerate triangles are treated as the segment or point
 * they are. */
int vd_tri_box_overlap(const struct vd_snapped_tri *t, int levels,
		       const int64_t lo[3], int64_t size);

/* -------------------------------------------------------------- parallel
 * A small C interface to TBB. Runs fn(ctx, i, worker) for i in [0, n) on up
 * to `threads` threads (0: all cores); `worker` is in [0, threads) and
 * unique among concurrently running calls. Returns VD_OK, or VD_ERR_INTERNAL
 * if TBB threw (the exception never crosses into C). */
int vd_parallel_for(size_t n, int threads,
		    void (*fn)(void *ctx, size_t i, int worker), void *ctx);

/* Number of hardware threads. */
int vd_hardware_threads(void);

/* ------------------------------------------------------------- utilities */

/* Parses "1024", "512K", "2M", "2GiB", "1.5G" (powers of 1024) into bytes.
 * Returns VD_ERR_ARG on anything else. */
int vd_parse_size(const char *s, uint64_t *bytes);

/* Peak resident set size of this process so far, in bytes. */
uint64_t vd_peak_rss_bytes(void);
/* Resident set size of this process now, in bytes (the peak if
 * /proc/self/statm cannot be read). */
uint64_t vd_current_rss_bytes(void);

/* Monotonic seconds. */
double vd_seconds(void);

/* Room for element n of a doubling array of `elem`-byte elements with
 * capacity *cap (`first` when empty): returns the array, moved if it grew,
 * with *cap > n; NULL when out of memory, the old array untouched. */
void *vd_grow(void *a, size_t n, size_t *cap, size_t elem, size_t first);

/* Builds the provenance text stored in chunk files:
 * "tool=NAME version=X args='a' 'b' ...", without --threads (-j) and its
 * value, which change no output byte. Returns a malloc'd string (free
 * with free()), NULL when out of memory. */
char *vd_provenance_new(const char *tool, int argc, char **argv);

/* Renames the finished temporary file `tmp` to `path`, the last step of
 * every atomic write. Refuses (VD_ERR_IO, the detail says why) when `path`
 * exists and is not a regular file: run as root, a rename over an output
 * path such as /dev/null would replace the device. */
int vd_replace_file(const char *tmp, const char *path);

/* A file output and the statistics beside it are published as a pair:
 * both are written complete under staging names (vd_stage_name: "<final>
 * .tmp.<pid>.new", so it is taken for a temporary everywhere), then
 * vd_publish_pair renames them into place. Renames need no space, so a
 * full disk fails before either is replaced and the previous pair stays
 * whole (writing the output and then its statistics left a new output
 * beside old statistics, or none). vd_stage_name returns VD_ERR_RANGE when
 * `cap` is too small. vd_publish_pair removes the staged files it did not
 * rename when a rename fails (VD_ERR_IO). */
int vd_stage_name(const char *final, char *buf, size_t cap);
int vd_publish_pair(const char *staged_out, const char *out,
		    const char *staged_stats, const char *stats);

/* ------------------------------------------------- manifests (io/manifest.c)
 * A directory output (voxelize's chunks, encode's encodings and tables)
 * carries `manifest`: one line per file with its XXH3-64 checksum, size and
 * name (schemas/manifest.md). It is written last, inside a staging
 * directory that replaces the old output in one rename, so an output
 * directory is always a whole run's. */
#define VD_MANIFEST_NAME "manifest"

/* XXH3-64 of a whole file and its size. VD_ERR_IO when it cannot be read. */
int vd_file_xxh3(const char *path, uint64_t *hash, uint64_t *size);

/* Writes dir/manifest for the regular files in dir (hidden names, the
 * manifest and temporaries excepted), atomically. */
int vd_manifest_write(const char *dir);

/* Checks every file dir/manifest lists (size, then checksum over all its
 * bytes) and that dir holds no other file. On success sets *digest (may be
 * NULL) to the XXH3-64 of the manifest's bytes, which stands for the whole
 * directory. Errors: VD_ERR_TRUNCATED (no manifest, a file missing or
 * short), VD_ERR_TRAILING (a file longer), VD_ERR_CHECKSUM, VD_ERR_CORRUPT
 * (a malformed manifest, a file not listed); the detail names the file. */
int vd_manifest_verify(const char *dir, uint64_t *digest);

/* Checks one file against the manifest of its directory (the encodings:
 * SymVox reads them by offsets, so their checksum lives beside them).
 * Errors as vd_manifest_verify(); a missing manifest's detail names the
 * way out (--no-verify) for files written elsewhere. */
int vd_manifest_check_file(const char *path);

/* Starts a directory output: checks that `final` is absent, empty, a
 * voxdag output (has a manifest) or holds only files `ours` (may be NULL)
 * accepts, creates final's missing parent directories, removes staging
 * directories of dead runs (exactly "<final>.tmp.<digits>" whose process
 * no longer exists: kill(pid, 0) fails with ESRCH), and creates the
 * staging directory "<final>.tmp.<pid>" into `staging` (cap bytes); a
 * trailing '/' of `final` is ignored. The
 * caller writes its files there, then calls vd_dir_publish(), or
 * vd_dir_abandon() on failure. */
int vd_dir_stage(const char *final, int (*ours)(const char *name),
		 char *staging, size_t cap);

/* Writes the staging directory's manifest and puts it in place of `final`
 * in one step (renameat2 RENAME_EXCHANGE), then removes the old output. */
int vd_dir_publish(const char *staging, const char *final);

/* Removes a staging directory after a failure; keeps the error detail. */
void vd_dir_abandon(const char *staging);

/* vd_dir_publish's rename alone, for a directory published together with
 * other outputs (edit's DAG and colours): the caller has written the
 * staging directory's manifest (vd_manifest_write). vd_dir_swap puts the
 * staging directory in place of `final` in one step; the old output, if
 * there was one (*had_old), is then under the staging name, for the
 * caller to remove with vd_dir_abandon() once the other outputs are in
 * place, or to put back with vd_dir_unswap(staging, final, had_old) if
 * they failed (the new directory is then under the staging name). */
int vd_dir_swap(const char *staging, const char *final, int *had_old);
int vd_dir_unswap(const char *staging, const char *final, int had_old);

/* Spill files (tmpfile.c). vd_tmpfile opens an anonymous file in `dir`
 * (O_TMPFILE; where the file system lacks it, "<dir>/<stem>.tmp.XXXXXX"
 * unlinked at once), so nothing is left behind on any exit: the fd, or -1
 * with errno. vd_pwrite_full / vd_pread_full move all n bytes at `off`
 * (retrying short transfers and EINTR): 0, or -1 with errno (ENOSPC for a
 * write that makes no progress, EIO for a read past the end). Callers say
 * what failed, in their own words. */
int vd_tmpfile(const char *dir, const char *stem);
int vd_pwrite_full(int fd, const void *p, size_t n, uint64_t off);
int vd_pread_full(int fd, void *p, size_t n, uint64_t off);

/* Command-line helpers for the tools' main()s (cli.c). vd_cli_usage prints
 * "TOOL: message" and "Try 'TOOL --help'." to stderr and returns 2, the
 * usage exit status. vd_cli_int parses a whole number in [lo, hi] (0, or
 * -1 if it is not one). vd_cli_fail prints the one-line failure
 * "TOOL: WHAT 'SUBJECT': <vd_strerror(err)>: <detail>" and returns 1. */
int vd_cli_usage(const char *tool, const char *fmt, ...)
	__attribute__((format(printf, 2, 3)));
int vd_cli_int(const char *s, int lo, int hi, int *out);
int vd_cli_fail(const char *tool, int err, const char *what,
		const char *subject);

/* XXH3 64-bit hash (the library's one hash). */
uint64_t vd_hash64(const void *data, size_t n, uint64_t seed);

/* ------------------------------------------------------- JSON statistics
 * A minimal writer for the statistics files beside every output. The file
 * appears under its name only when vd_json_close() succeeds. Keys are
 * written as given (no escaping): use plain identifiers. Inside arrays pass
 * key NULL. */
struct vd_json;
int vd_json_open(struct vd_json **j, const char *path);
void vd_json_object(struct vd_json *j, const char *key);
void vd_json_end_object(struct vd_json *j);
void vd_json_array(struct vd_json *j, const char *key);
void vd_json_end_array(struct vd_json *j);
void vd_json_u64(struct vd_json *j, const char *key, uint64_t v);
void vd_json_f64(struct vd_json *j, const char *key, double v);
void vd_json_str(struct vd_json *j, const char *key, const char *s);
void vd_json_u64_array(struct vd_json *j, const char *key, const uint64_t *v,
		       size_t n);
/* Closes the top-level object, flushes and renames; frees j. */
int vd_json_close(struct vd_json *j);

/* ---- OpenVDB (io/vdb.cc reads, io/vdb_write.cc writes)
 * OpenVDB grids in and out. Those two are the only files that include
 * OpenVDB; every exception is caught there and returned as an error code
 * with a detail line. The import driver (vdb_import.c) and the chunk export
 * (vdb_export.c) are C on top of these calls.
 *
 * Index space: an OpenVDB voxel (i, j, k) is centred at index (i, j, k), so
 * it covers [i - 1/2, i + 1/2) in index units; our voxel v covers
 * [origin + v*voxel_size, origin + (v+1)*voxel_size) in world units. */

struct vd_voxelize_opts;

/* What counts as a set voxel when importing. */
enum vd_vdb_mode {
	VD_VDB_ACTIVE = 0,       /* active voxels and active tiles (any type) */
	/* The zero crossing of a level set, one voxel thick: every voxel with
	 * value <= 0 that has a face neighbour (of the 6) with value > 0,
	 * active or not (inactive values are the +-background). This is the
	 * inner shell of levelset-solid: the solid less its 6-erosion. */
	VD_VDB_LEVELSET_SURFACE,
	/* The inside of a level set: every voxel with value <= 0, active or
	 * not, inside tiles included. A background <= 0 (an inside without
	 * end) is refused. */
	VD_VDB_LEVELSET_SOLID,
	/* Active voxels and active tiles whose value is above the threshold
	 * (inactive values, the background, never count). */
	VD_VDB_FOG,
	VD_VDB_MODE_COUNT_
};

/* "active", "levelset-surface", "levelset-solid", "fog"; NULL if unknown. */
const char *vd_vdb_mode_name(int mode);
/* Parses one of those names into *mode. Returns VD_ERR_ARG otherwise. */
int vd_vdb_mode_parse(const char *name, int *mode);

/* Which grid of a file and which of its voxels. */
struct vd_vdb_select {
	const char *grid_name;   /* NULL: the first grid in the file */
	int mode;                /* enum vd_vdb_mode */
	double fog_threshold;    /* VD_VDB_FOG: set when value > this */
	/* The colour grid (vd_vdb_colour_open; used by vd_vdb_import when
	 * opts->colours): NULL picks one by name, or none. */
	const char *colour_grid;
};

/* What vd_vdb_open() found. Index boxes are inclusive, in OpenVDB index
 * coordinates. */
struct vd_vdb_info {
	char grid_name[128];
	char value_type[32];      /* "float", "double", "bool", "mask", ... */
	char grid_class[32];      /* "level set", "fog volume", "unknown", ... */
	double voxel_size;        /* world units per index unit */
	double translation[3];    /* world position of index (0,0,0) */
	uint64_t active_voxels;   /* OpenVDB's activeVoxelCount() */
	uint64_t leaves;          /* leaf nodes in the tree */
	int has_active;           /* 0: no active value at all */
	int32_t active_min[3], active_max[3]; /* evalActiveVoxelBoundingBox */
};

struct vd_vdb;

/* Walks the structure of the OpenVDB file `f` (vdb_walk.c, no OpenVDB):
 * magic number, header, file metadata, grid descriptors and their end
 * offsets, and checks each length against the file's size before OpenVDB
 * trusts it. Sets *grids to the grid count. Errors: VD_ERR_EMPTY,
 * VD_ERR_FORMAT (no magic), VD_ERR_TRUNCATED, VD_ERR_CORRUPT, VD_ERR_IO. */
int vd_vdb_walk(FILE *f, uint64_t *grids);

/* Reads grid `sel->grid_name` (the first grid when NULL) of the OpenVDB
 * file `path` into memory (OpenVDB holds the tree; nothing is copied
 * densely) and checks it can be read in mode `sel->mode`. Errors:
 * VD_ERR_IO (cannot open), VD_ERR_FORMAT (not an OpenVDB file),
 * VD_ERR_TRUNCATED (the file ends early or its data is damaged: OpenVDB
 * cannot tell the two apart), VD_ERR_EMPTY (no grid in the file),
 * VD_ERR_ARG (no grid of that name; the detail lists the names),
 * VD_ERR_UNSUPPORTED (a value type the mode cannot read, a rotated,
 * non-uniform or non-linear transform: voxdag grids are axis-aligned cubes,
 * so such a grid must first be resampled, e.g. with OpenVDB's
 * tools::resampleToMatch; or a level set whose background is <= 0).
 * Fills `info` when not NULL. Close with vd_vdb_close(). */
int vd_vdb_open(struct vd_vdb **out, const char *path,
		const struct vd_vdb_select *sel, struct vd_vdb_info *info);
void vd_vdb_close(struct vd_vdb *v);

/* A node of the tree that holds selected voxels. A leaf (is_leaf) covers
 * the 8^3 voxels from `origin`; voxel (x, y, z) of it (0..7 each) is set
 * when bit 8*y + z of mask[x] is. A tile covers dim^3 voxels from `origin`,
 * all set; mask is unused. */
struct vd_vdb_node {
	int32_t origin[3];
	uint32_t dim;
	int is_leaf;
	uint64_t mask[8];
};

/* Calls fn for every leaf with at least one selected voxel and every tile
 * (at any level) whose voxels are all selected, in the tree's order; stops
 * at the first non-zero return of fn and returns it. Tiles are reported
 * whole: their voxels are never visited. */
int vd_vdb_scan(struct vd_vdb *v,
		int (*fn)(void *ctx, const struct vd_vdb_node *n), void *ctx);

/* The selected voxels of the leaf at `origin` (as vd_vdb_node.mask; all 0
 * when there is no leaf there). Safe to call from several threads. */
int vd_vdb_leaf_mask(struct vd_vdb *v, const int32_t origin[3],
		     uint64_t mask[8]);

/* Colour from a Vec3 grid beside the density grid; the rule, value ranges
 * and sampling are in schemas/colour-rule.md ("OpenVDB colour grids"). */
struct vd_vdb_colour;

struct vd_vdb_colour_info {
	char grid_name[128];
	char value_type[32];   /* "vec3s", "vec3d" or "vec3i" */
	/* 1: the colour grid's transform is the density grid's, so a voxel's
	 * colour is read at its own index; 0: read at the colour grid's voxel
	 * nearest to the voxel centre's world position */
	int same_transform;
};

/* Reads the colour grid of the OpenVDB file `path` beside the density grid
 * `density` (open): the grid named `name`, or when `name` is NULL a grid
 * named Cd, color, colour or rgb whose values are Vec3
 * (vec3s, vec3d or vec3i), names tried in that order (OpenVDB lists a
 * file's grids by name, so a file order is not to be had); with no such
 * grid *out is NULL and VD_OK is
 * returned (no colours). Errors: those of vd_vdb_open(), VD_ERR_ARG (no
 * grid `name`; the detail lists the names), VD_ERR_UNSUPPORTED (grid `name`
 * is not a Vec3 grid, or has a non-linear transform). Fills `info` when
 * there is a grid and `info` is not NULL. Close with
 * vd_vdb_colour_close(). */
int vd_vdb_colour_open(struct vd_vdb_colour **out, const char *path,
		       const char *name, const struct vd_vdb *density,
		       struct vd_vdb_colour_info *info);
void vd_vdb_colour_close(struct vd_vdb_colour *c);

/* The sRGB colours (R, G, B bytes, rgb[0..3V) for V the voxels of the
 * bricks) of the voxels of n bricks of an import, bricks in the order
 * given, within a brick in mask bit order: brick i's key is
 * keys[i * stride], its mask masks[i * stride]. Our voxel v is the
 * OpenVDB voxels off + v 2^shift .. off + (v + 1) 2^shift - 1 of the density
 * grid (vd_vdb_import_result.index_offset, resample_shift); its colour is
 * read at its centre. Safe to call from several threads. */
int vd_vdb_colour_bricks(const struct vd_vdb_colour *c, const int32_t off[3],
			 int shift, const uint64_t *keys,
			 const uint64_t *masks, size_t stride, size_t n,
			 uint8_t *rgb);

/* Import: the selected voxels of a grid into SVO chunk files, one per
 * non-empty L0 cell, named and laid out as vd_voxelize_mesh() does.
 *
 * Placement: the grid covers the bounding box of the selected voxels.
 * With opts->levels == 0 one OpenVDB voxel is one voxel, and L is the
 * smallest depth whose 2^L voxels cover the box from its minimum rounded
 * down to a multiple of 8 (so OpenVDB leaves fall on our 4^3 bricks and
 * never straddle a cell). With opts->levels == L the same holds if the box
 * fits; otherwise the grid is resampled by the smallest power of two 2^k
 * that makes it fit: one of our voxels is 2^k OpenVDB voxels per side and
 * is set when any of them is (no new voxel appears, thin features stay),
 * the box's minimum rounded down to a multiple of 8*2^k. A larger L than
 * needed only pads. Returns what vd_vdb_open() returns, VD_ERR_EMPTY when
 * no voxel is selected, VD_ERR_RANGE when the grid needs more than 2^21
 * voxels per side (pass opts->levels to resample), VD_ERR_BUDGET. */
struct vd_vdb_import_result {
	int levels, chunk_level;
	struct vd_transform transform;
	struct vd_vdb_info info;
	int mode;
	double fog_threshold;
	int resample_shift;          /* k above; 0: no resampling */
	int32_t index_offset[3];     /* OpenVDB index of our voxel (0,0,0) */
	uint64_t leaves_selected;    /* leaves with a selected voxel */
	uint64_t tiles_selected;     /* tiles wholly selected */
	uint64_t voxels, chunks, bricks;
	uint64_t level_nodes[VD_MAX_LEVELS + 1]; /* whole grid, levels 0..L */
	double seconds_read, seconds_scan, seconds_voxelize, seconds_total;
	uint64_t peak_rss_bytes, mem_budget_bytes;
	int threads;
	int colours;                 /* colour chunks were written */
	struct vd_vdb_colour_info colour; /* their grid, when colours */
};

/* opts->levels: 0 to fit (see above), or the depth to resample to. With
 * opts->colours and a colour grid (vd_vdb_colour_open with
 * sel->colour_grid), each cell also gets its colour chunk, as
 * vd_voxelize_mesh() writes them. */
int vd_vdb_import(const char *vdb_path, const char *outdir,
		  const struct vd_vdb_select *sel,
		  const struct vd_voxelize_opts *opts,
		  struct vd_vdb_import_result *res);

/* Writes `res` as JSON to `path` (atomic), with the fields of
 * vd_voxelize_write_stats() that apply plus the grid and the mode. */
int vd_vdb_import_write_stats(const struct vd_vdb_import_result *res,
			      const char *path);

/* Export. Bricks arrive through `next`: each call sets *keys, *masks to
 * *n bricks (any order, keys as in the grid conventions of a grid of
 * depth `levels`) and returns VD_OK; *n == 0 ends; a non-zero return
 * aborts the export and is returned. The voxels are written to `path`
 * (replaced atomically) as one BoolGrid named `grid_name`, active and
 * true, with the transform of `t`: our voxel v is OpenVDB index v, voxel
 * size t->voxel_size, index (0,0,0) centred at t->origin + voxel_size/2.
 * Full 8^3 leaves are pruned into tiles. *voxels (if not NULL) gets the
 * active voxel count of the written grid, as OpenVDB counts it. */
int vd_vdb_export(const char *path, const char *grid_name, int levels,
		  const struct vd_transform *t,
		  int (*next)(void *ctx, const uint64_t **keys,
			      const uint64_t **masks, size_t *n),
		  void *ctx, uint64_t *voxels);

/* Exports the SVO chunk files paths[0..n) (cells of one grid: same depth
 * and transform, else VD_ERR_MISMATCH) with vd_vdb_export(), one chunk in
 * memory at a time. */
int vd_vdb_export_svo(const char *path, const char *grid_name,
		      char *const *paths, size_t n, uint64_t *voxels);

/* Test support (used by the tests and vdb-make-test-grids, not by the
 * pipeline): builds grids through the OpenVDB API and writes them. Each
 * vd_vdb_test_add_* appends one grid to `f`; vd_vdb_test_write() writes
 * them all to `path`. */
struct vd_vdb_test_file;
int vd_vdb_test_new(struct vd_vdb_test_file **f);
/* Level set sphere (tools::createLevelSetSphere): radius and centre in
 * world units, `half_width` voxels of narrow band each side. */
int vd_vdb_test_add_sphere(struct vd_vdb_test_file *f, const char *name,
			   double radius, const double centre[3],
			   double voxel_size, double half_width);
/* Fog volume: float grid, background 0, the inclusive index box lo..hi
 * filled active with `value` (tree.fill: whole tiles where the box
 * covers them), then the inclusive box inner_lo..inner_hi set to
 * `inner_value` unless inner_lo[0] > inner_hi[0]. */
int vd_vdb_test_add_fog_box(struct vd_vdb_test_file *f, const char *name,
			    const int32_t lo[3], const int32_t hi[3],
			    float value, const int32_t inner_lo[3],
			    const int32_t inner_hi[3], float inner_value);
/* Level set of a mesh file (read with vd_mesh_*) by
 * tools::meshToLevelSet, `resolution` voxels across the mesh's largest
 * extent. */
int vd_vdb_test_add_mesh(struct vd_vdb_test_file *f, const char *name,
			 const char *mesh_path, int resolution,
			 double half_width);
/* A float grid with no active value (background 0). */
int vd_vdb_test_add_empty(struct vd_vdb_test_file *f, const char *name);
/* A float fog box (value 1) of side `n` at the origin whose transform is
 * rotated about Z by `rotate_deg` and scaled by (sx, sy, sz). */
int vd_vdb_test_add_transformed(struct vd_vdb_test_file *f,
				const char *name, int n, double rotate_deg,
				double sx, double sy, double sz);
/* The test colour of OpenVDB index (x, y, z), sRGB 0..255: a fixed
 * function of the coordinate that vd_vdb_test_add_colour() stores. */
void vd_vdb_test_colour_of(int64_t x, int64_t y, int64_t z, uint8_t rgb[3]);
/* A colour grid of `type` ("vec3s", "vec3d": vd_vdb_test_colour_of / 255;
 * "vec3i": as it is) with voxel size `voxel_size` and index (0,0,0) at world
 * `translation`: every index of the inclusive box lo..hi active with its
 * test colour, then those of off_lo..off_hi made inactive (their values
 * kept) unless off_lo[0] > off_hi[0]; the background is `bg` in the same
 * encoding. Voxel by voxel: small boxes only. */
int vd_vdb_test_add_colour(struct vd_vdb_test_file *f, const char *name,
			   const char *type, double voxel_size,
			   const double translation[3], const int32_t lo[3],
			   const int32_t hi[3], const int32_t off_lo[3],
			   const int32_t off_hi[3], const uint8_t bg[3]);
/* A colour grid of `type` (as above; background 0) whose index (i, 0, 0)
 * holds values[3i .. 3i+2] (converted to the type), active, i < n. */
int vd_vdb_test_add_colour_values(struct vd_vdb_test_file *f,
				  const char *name, const char *type, int n,
				  const double *values);
int vd_vdb_test_write(struct vd_vdb_test_file *f, const char *path);
void vd_vdb_test_free(struct vd_vdb_test_file *f);

/* Brute force reference for tests: evaluates the mode's definition at
 * every voxel of the grid's active bounding box grown by `margin` voxels
 * (with an accessor, no node iteration) and calls fn for each selected
 * one; *count gets their number. Slow: small grids only. */
int vd_vdb_test_reference(const char *path, const struct vd_vdb_select *sel,
			  int margin,
			  void (*fn)(void *ctx, int32_t x, int32_t y,
				     int32_t z),
			  void *ctx, uint64_t *count);

/* ---- end of OpenVDB block */

/* ------------------------------------------------------------ voxelizer */

struct vd_voxelize_opts {
	int levels;               /* L, 1..VD_MAX_LEVELS */
	int chunk_level;          /* L0, or -1 to choose from the budget */
	uint64_t mem_budget_bytes;/* per-process budget */
	int threads;              /* 0: all cores */
	int quiet;                /* no progress on stderr */
	const char *provenance;   /* stored in every chunk */
	const char *tool;         /* prefix for progress lines */
	/* Write each non-empty cell's colour chunk ("col", vd_colours_save)
	 * when the mesh has colours (vd_mesh_has_colours) or the OpenVDB file
	 * a colour grid (vd_vdb_colour_open); rules in
	 * schemas/colour-rule.md. The SVO chunks' voxels are the same either
	 * way. */
	int colours;
	int strict;               /* a missing texture or MTL is an error */
};

struct vd_voxelize_result {
	int levels, chunk_level;
	struct vd_transform transform;
	struct vd_mesh_stats mesh;
	uint64_t triangles_binned;   /* triangle-cell pairs written to bins */
	uint64_t voxels;
	uint64_t chunks;
	uint64_t bricks;
	uint64_t level_nodes[VD_MAX_LEVELS + 1]; /* whole grid, levels 0..L */
	double seconds_bounds, seconds_bin, seconds_voxelize, seconds_total;
	uint64_t peak_rss_bytes;
	uint64_t mem_budget_bytes;
	int threads;                 /* workers used for the cells */
	char format[32];             /* input format, vd_mesh_format() */
	int colours;                 /* colour chunks were written */
	uint64_t textures_loaded, textures_missing;
	double seconds_colour;       /* summed over workers */
};

/* Voxelizes the mesh at `mesh_path` into SVO chunk files
 * OUTDIR/chunk-L<L0>-<morton>.svo, one per non-empty cell, and with
 * opts->colours, when the mesh has colours, a colour chunk
 * chunk-L<L0>-<morton>.col beside each. Existing chunk files of an
 * earlier run in `outdir` are removed first. */
int vd_voxelize_mesh(const char *mesh_path, const char *outdir,
		     const struct vd_voxelize_opts *opts,
		     struct vd_voxelize_result *res);

/* Writes `res` as JSON to `path` (atomic). */
int vd_voxelize_write_stats(const struct vd_voxelize_result *res,
			    const char *path);

/* Name of a cell's chunk file inside a directory: "chunk-L3-000123.svo".
 * Writes at most `cap` bytes into `buf`. */
void vd_chunk_file_name(char *buf, size_t cap, int chunk_level,
			uint64_t cell_morton, const char *ext);

/* --------------------------------------------------------- colour chunks
 * A colour chunk (kind VD_KIND_COLOURS, file vd_chunk_file_name(.., "col")
 * beside the cell's "svo" chunk) holds the sRGB colours (R, G, B bytes) of
 * one cell's voxels in the cell's depth-first Morton order: bricks in key
 * order, within a brick voxels in mask bit order. That is the order of a
 * depth-first walk of the cell's octree visiting children 0..7, so the
 * cells' arrays in cell order are the scene's colour array. The header is
 * the SVO chunk's (depth, cell, transform, counts) with the kind changed,
 * and a BDIG section holds vd_svo_digest() of the bricks the colours were
 * written for. Spec: schemas/chunk-format.md, "Colour chunks". */
#define VD_TAG_COLS VD_TAG('C', 'O', 'L', 'S') /* RGB8 per voxel */
#define VD_TAG_BDIG VD_TAG('B', 'D', 'I', 'G') /* digest of the bricks */

struct vd_colours {
	uint64_t voxels;      /* number of colours = voxels of the cell */
	uint8_t *rgb;         /* 3 * voxels bytes */
	uint64_t svo_digest;  /* vd_svo_digest() of the cell's bricks */
};

/* XXH3-64 over the little-endian (key, mask) u64 pairs of n bricks. */
uint64_t vd_svo_digest(const uint64_t *keys, const uint64_t *masks,
		       size_t n);
/* The same with key i at keys[i * stride], mask i at masks[i * stride]. */
uint64_t vd_svo_digest_stride(const uint64_t *keys, const uint64_t *masks,
			      size_t stride, size_t n);

/* Writes the colours `rgb` (3 * voxels bytes) of the cell whose SVO chunk
 * header is `svo_h` (its voxel count must equal `voxels`: VD_ERR_MISMATCH)
 * and whose bricks have digest `svo_digest`, atomically at `path`. */
int vd_colours_save(const char *path, const struct vd_chunk_header *svo_h,
		    uint64_t svo_digest, const uint8_t *rgb, uint64_t voxels,
		    const char *provenance);

/* The same, the colours streamed: each call of `next` sets *rgb to the next
 * *n colours (3 * *n bytes, valid until the next call) and returns VD_OK;
 * *n == 0 ends, a non-zero return aborts the write and is returned. More
 * or fewer than `voxels` colours in all: VD_ERR_MISMATCH, nothing
 * written. */
int vd_colours_write(const char *path, const struct vd_chunk_header *svo_h,
		     uint64_t svo_digest, uint64_t voxels,
		     int (*next)(void *ctx, const uint8_t **rgb, size_t *n),
		     void *ctx, const char *provenance);

/* Reads and verifies a colour chunk. Free with vd_colours_release(). */
int vd_colours_load(struct vd_colours *c, struct vd_chunk_header *h,
		    const char *path);
int vd_colours_from_chunk(struct vd_colours *c, const struct vd_chunk *ch);

/* VD_OK when colour chunk (`col_h`, `c`) belongs to the SVO chunk
 * (`svo_h`, `svo`): same depth, cell, grid, voxel count, and (when `svo` is
 * not NULL) brick digest; VD_ERR_MISMATCH with a detail otherwise. */
int vd_colours_match(const struct vd_chunk_header *col_h,
		     const struct vd_colours *c,
		     const struct vd_chunk_header *svo_h,
		     const struct vd_svo *svo);

void vd_colours_release(struct vd_colours *c);

/* ---------------------------------------------------- colour compression
 * The scene's colour array (the cells' colour chunks in cell order) stored
 * three ways, each a "packed colours" chunk file (kind VD_KIND_CPACK,
 * schemas/colour-formats.md):
 * - VBR, variable-bitrate blocks (Dolonius et al. 2017, section 4.2): blocks
 *   of any length, each the index of its first voxel and two RGB565
 *   endpoints; every voxel a fixed-width weight between them. Built by the
 *   paper's Algorithm 1; every decoded colour is within max_error of its
 *   original (sRGB distance, channels in [0,1]).
 * - palette, the baseline of Dado et al. 2016: a global palette of K colours
 *   (or every distinct colour: lossless), block palettes (lists of global
 *   indices, shared by every block with the same set), per-voxel offsets of
 *   the smallest width into the block palette.
 * - raw: the RGB8 array, zstd-compressed, for reference.
 * The array is cut into segments: a cell's voxels, split every
 * VD_CPACK_SEGMENT_MAX voxels. Blocks never span a segment, so a segment is
 * built from its cell alone (out of core, in parallel) and an edit rebuilds
 * only the segments of the cells it touches. */

/* Largest segment, in voxels: bounds the builder's memory per thread and
 * lets a block store its start as a u32 relative to its segment; the
 * table costs 40 bytes per 2^18 voxels, 0.005% of the raw colours. */
#define VD_CPACK_SEGMENT_MAX (1u << 18)

enum vd_cpack_method {
	VD_CPACK_VBR = 1,
	VD_CPACK_PALETTE = 2,
	VD_CPACK_RAW = 3,
};

/* "vbr", "palette", "raw"; NULL if unknown. */
const char *vd_cpack_method_name(int method);

/* RGB565: r5 << 11 | g6 << 5 | b5; decoded to 8 bits by bit replication
 * (r8 = r5 << 3 | r5 >> 2, g8 = g6 << 2 | g6 >> 4), as BC1 decoders do. */
static inline void vd_rgb565_decode(uint16_t c, uint8_t rgb[3])
{
	unsigned r = c >> 11, g = c >> 5 & 63, b = c & 31;
	rgb[0] = (uint8_t)(r << 3 | r >> 2);
	rgb[1] = (uint8_t)(g << 2 | g >> 4);
	rgb[2] = (uint8_t)(b << 3 | b >> 2);
}

/* The VBR decode rule, per channel, exactly (integers, M = 2^bits - 1):
 * (c0 * (M - w) + c1 * w + M / 2) / M with c0, c1 the decoded endpoints. */
static inline void vd_vbr_interp(uint16_t c0, uint16_t c1, unsigned w,
				 int weight_bits, uint8_t rgb[3])
{
	uint8_t a[3], b[3];
	unsigned m = (1u << weight_bits) - 1;
	vd_rgb565_decode(c0, a);
	vd_rgb565_decode(c1, b);
	for (int k = 0; k < 3; k++)
		rgb[k] = (uint8_t)((a[k] * (m - w) + b[k] * w + m / 2) / m);
}

/* Squared sRGB distance of two RGB8 colours, in 8-bit units. The error of
 * the paper is sqrt of this / 255; GMSE is its mean over all voxels. */
static inline unsigned vd_rgb_dist2(const uint8_t *a, const uint8_t *b)
{
	int d0 = a[0] - b[0], d1 = a[1] - b[1], d2 = a[2] - b[2];
	return (unsigned)(d0 * d0 + d1 * d1 + d2 * d2);
}

/* Largest squared 8-bit distance within `max_error` (channels in [0,1]):
 * a colour is within the threshold iff vd_rgb_dist2 <= this. */
unsigned vd_colour_error_limit(double max_error);

struct vd_vbr_params {
	double max_error;   /* et: sRGB distance, channels in [0,1] */
	int weight_bits;    /* W, 1..8 (paper: 3) */
	int no_single_sweep;/* 1: skip the first sweep for single-colour runs */
};

/* The one fit rule of a block (the greedy and the tests' brute force use it
 * alike): a block of one colour gets the endpoints and weight that decode
 * nearest it (exact whenever RGB565 endpoints and W-bit weights can
 * represent it); others least-squares endpoints along the colours'
 * principal axis, rounded to RGB565, each voxel's weight the one that
 * decodes nearest; failing that the axis' extreme points, then the first
 * colour's nearest RGB565 as one colour (the first sweep's rule, so its
 * runs always fit).
 * Returns 1 when every colour of rgb[0..n) decodes within `limit`
 * (vd_colour_error_limit), 0 otherwise (stopping at the first colour
 * outside). On 1 sets *c0, *c1, *sse (sum of squared 8-bit distances) and,
 * when `w` is not NULL, w[0..n). */
int vd_vbr_fit(const uint8_t *rgb, uint32_t n, unsigned limit,
	       int weight_bits, uint16_t *c0, uint16_t *c1, uint8_t *w,
	       uint64_t *sse);

/* One segment encoded: `count` blocks, block b covering voxels
 * start[b] .. start[b+1]-1 (the last to n-1; start[0] == 0), weights
 * packed LSB first, voxel i's at bit i * weight_bits of `weights`. */
struct vd_vbr_segment {
	uint32_t n, count;
	int weight_bits;
	uint32_t *start;
	uint16_t *c0, *c1;
	uint8_t *weights;     /* (n * weight_bits + 7) / 8 bytes */
	uint64_t sse;         /* sum of squared 8-bit errors */
	unsigned max_dist2;   /* largest squared 8-bit error */
	uint64_t passes;      /* merge passes Algorithm 1 ran */
};

/* Encodes rgb[0..n) (n <= VD_CPACK_SEGMENT_MAX) with Algorithm 1. Errors:
 * VD_ERR_ARG (bad parameters), VD_ERR_RANGE (max_error so small that a
 * single colour cannot be stored within it from RGB565 endpoints; any
 * max_error >= 0.0236 always works), VD_ERR_NOMEM. Release with
 * vd_vbr_segment_release(). */
int vd_vbr_encode(struct vd_vbr_segment *s, const uint8_t *rgb, uint32_t n,
		  const struct vd_vbr_params *p);
/* Colour i of an encoded segment (binary search over block starts). */
void vd_vbr_segment_colour(const struct vd_vbr_segment *s, uint32_t i,
			   uint8_t rgb[3]);
void vd_vbr_segment_release(struct vd_vbr_segment *s);
/* 1 (default): vd_vbr_encode uses AVX2 lanes where the CPU has them, with
 * the scalar loops' bits; 0: the scalar loops only (for the tests that
 * compare the two). */
extern int vd_vbr_lanes;

/* Palette baseline. A histogram of 24-bit colours (2^24 u32 counts,
 * saturating), filled cell by cell, then the global palette. */
struct vd_colour_hist {
	uint32_t *count;      /* 2^24 entries, index r << 16 | g << 8 | b */
	uint64_t voxels, distinct;
};
int vd_colour_hist_init(struct vd_colour_hist *h);
void vd_colour_hist_add(struct vd_colour_hist *h, const uint8_t *rgb,
			uint64_t n);
void vd_colour_hist_release(struct vd_colour_hist *h);

/* A global palette and the map of every colour of the histogram to its
 * palette index. */
struct vd_palette {
	uint32_t k;           /* colours in the palette */
	uint8_t *rgb;         /* 3k bytes */
	int lossless;         /* 1: the palette is every distinct colour */
	uint32_t *index;      /* 2^24 entries: palette index of each colour
			       * the histogram saw (others undefined) */
};

/* Builds a palette of at most `k` colours (2..2^24) from `h`: median cut
 * (Heckbert 1982: split the box of largest squared error at the weighted
 * median of its widest axis) then Lloyd iterations, deterministic; exact
 * (every distinct colour, sorted) when `lossless` or when the histogram has
 * at most k colours. Takes over h->count as p->index (h is released). */
int vd_palette_build(struct vd_palette *p, struct vd_colour_hist *h,
		     uint32_t k, int lossless, int threads);
/* Nearest palette colour of any RGB8 colour (exact search; ties to the
 * lower index). For tests and colours the histogram did not see. */
uint32_t vd_palette_nearest(const struct vd_palette *p, const uint8_t rgb[3]);
void vd_palette_release(struct vd_palette *p);

/* One segment in the palette format before its block palettes are shared:
 * block b covers start[b].., its palette is the sorted global indices
 * pal[pal_first[b] .. pal_first[b+1]) (pal_first has count+1 entries), each
 * voxel an offset into it (offsets[i] for voxel i, unpacked here). */
struct vd_palette_segment {
	uint32_t n, count;
	uint32_t *start;
	uint32_t *pal_first;
	uint32_t *pal;
	uint32_t *offsets;
	uint64_t sse;
	unsigned max_dist2;
};
int vd_palette_encode(struct vd_palette_segment *s, const uint8_t *rgb,
		      uint32_t n, const struct vd_palette *p);
void vd_palette_segment_release(struct vd_palette_segment *s);

/* Writing a packed colours file (kind VD_KIND_CPACK). Open, feed the cells
 * in increasing cell order (each split into segments and encoded on up to
 * `threads` threads), commit. The file appears under `path` only on
 * commit; the big arrays are streamed (one spooled beside the file), so
 * memory holds a few segments, not the array. */
struct vd_cpack_params {
	int method;                 /* enum vd_cpack_method */
	struct vd_vbr_params vbr;
	const struct vd_palette *palette; /* VD_CPACK_PALETTE: built first */
	uint32_t palette_colours;   /* the K asked for (recorded) */
	int zstd_level;             /* VD_CPACK_RAW (0: 9) */
	int threads;                /* 0: all cores */
};

/* What a writer produced. */
struct vd_cpack_stats {
	uint64_t voxels, segments, blocks, palettes, palette_entries;
	uint64_t bytes;        /* the compressed structure: content sections */
	uint64_t file_bytes;   /* the whole file */
	uint64_t sse;          /* sum of squared 8-bit errors */
	unsigned max_dist2;
	double seconds;
};

struct vd_cpack_writer;
int vd_cpack_writer_open(struct vd_cpack_writer **w, const char *path,
			 const struct vd_cpack_params *p, int levels,
			 const struct vd_transform *t,
			 const char *provenance);
/* Appends cell (`chunk_level`, `cell_morton`)'s `n` colours. Cells must
 * come in strictly increasing order (VD_ERR_ARG). */
int vd_cpack_writer_add(struct vd_cpack_writer *w, int chunk_level,
			uint64_t cell_morton, const uint8_t *rgb, uint64_t n);
/* Finishes the file; fills `st` (may be NULL). Frees w either way. */
int vd_cpack_writer_commit(struct vd_cpack_writer *w,
			   struct vd_cpack_stats *st);
void vd_cpack_writer_abort(struct vd_cpack_writer *w);

/* Reading. vd_cpack_open() verifies the container, then every structural
 * rule of schemas/colour-formats.md (segments tile the array, block starts
 * increase inside each segment, offsets inside their palettes, ...), so
 * the lookups below never read outside the file's arrays. */
struct vd_cpack;
int vd_cpack_open(struct vd_cpack **out, const char *path);
int vd_cpack_open_mem(struct vd_cpack **out, const void *data, size_t size);
int vd_cpack_method(const struct vd_cpack *c);
uint64_t vd_cpack_voxels(const struct vd_cpack *c);
/* Colour of voxel `i` (binary search over segments, then block headers).
 * VD_ERR_RANGE when i >= voxels. */
int vd_cpack_colour(const struct vd_cpack *c, uint64_t i, uint8_t rgb[3]);
/* Colours of voxels first .. first+n-1 into rgb (3n bytes). */
int vd_cpack_decode(const struct vd_cpack *c, uint64_t first, uint64_t n,
		    uint8_t *rgb);
/* Bytes of the compressed structure (as vd_cpack_stats.bytes). */
uint64_t vd_cpack_bytes(const struct vd_cpack *c);
uint64_t vd_cpack_blocks(const struct vd_cpack *c);
/* Chunk level of the cells its segments were cut at (-1: no segment). */
int vd_cpack_cell_level(const struct vd_cpack *c);
void vd_cpack_free(struct vd_cpack *c);

/* The colorize stage: the colour chunks of a voxelize output directory to
 * OUTDIR/colours.{vbr,palette,raw} (staged, published whole with a
 * manifest) and statistics. */
struct vd_colorize_job {
	const char *indir, *outdir, *stats_path;
	int methods;              /* bit (1 << method) per method */
	struct vd_vbr_params vbr;
	uint32_t palette_colours; /* K */
	int lossless;
	int threads, quiet;
	const char *provenance;
};
int vd_colorize_run(const struct vd_colorize_job *job);

/* ------------------------------------------------- DAG and SSVDAG (dag.c) */
/* A DAG chunk in memory: the minimal SVDAG (VD_KIND_DAG) or SSVDAG
 * (VD_KIND_SSVDAG) of one cell at `chunk_level`, or its 48-group version
 * (VD_KIND_SSVDAG48: `refl` holds cube transforms 0..47, see "Cube group"
 * below, and minimality is under all 48). Specified on disk in
 * schemas/chunk-format.md, "DAG and SSVDAG chunks" and "48-group SSVDAG
 * chunks".
 *
 * Levels are indexed by their absolute level l in the grid and run from
 * chunk_level (the cell's root, one node; none when the cell is empty) to
 * levels-1. A node on level l < levels-1 has an 8-bit child mask (bit c set
 * when child c = 4x+2y+z is non-empty) and one reference per set bit, in
 * increasing slot order: node i's references are first[i] .. first[i+1]-1.
 * A reference is the index of a node on level l+1, and in an SSVDAG also a
 * 3-bit reflection. Level levels-1 holds 2x2x2 voxel masks (bit c = voxel c)
 * and no references. Level levels-2 (when levels >= 2) is additionally
 * available as 4x4x4 bricks in `bricks`, in the header's brick layout.
 *
 * Reflections: a 3-bit value m uses child-index bits, bit 2 (4) = mirror
 * along X, bit 1 (2) = along Y, bit 0 (1) = along Z, so reflecting a node by
 * m moves child slot p to slot p ^ m and reflects that child by m too.
 * (The SymVox files put X, Y, Z in pointer bits 13, 14, 15 / 29, 30, 31: the
 * encoder maps bit 2 -> X, 1 -> Y, 0 -> Z.) A reference (i, m) means "node i
 * reflected by m". Reflections compose by XOR down a path: in a node reached
 * with accumulated reflection a, logical child slot p is stored slot p ^ a,
 * and the child is reached with a ^ m. A 2x2x2 mask reflected by m moves bit
 * c to bit c ^ m; a brick reflected by m moves byte c to byte c ^ m and
 * reflects each byte by m (vd_brick_reflect()).
 *
 * Minimality: no two nodes on a level represent the same subtree (DAG), or
 * subtrees equal up to any of the 8 reflections (SSVDAG). Every node is
 * reachable from the root. SSVDAG nodes below the root are the canonical
 * representatives of their class; the root is stored as the cell really is
 * (unreflected), so a chunk never needs a reflection on its root. An SSVDAG
 * reference's reflection is normalized (the smallest of m ^ g over the
 * reflections g its child is invariant under), so equal subtrees are
 * referenced by equal bytes. Nodes on a level are in the order they were
 * first met: deterministic, independent of --threads, meaningless.
 */
struct vd_dag_level {
	uint64_t nodes;   /* nodes on this level */
	uint64_t refs;    /* references held by this level's nodes (0 on L-1) */
	uint8_t *mask;    /* nodes child masks; on level L-1 the voxel masks */
	uint64_t *first;  /* nodes+1 offsets into child/refl; NULL on L-1 */
	uint32_t *child;  /* refs indices into level l+1; NULL on L-1 */
	uint8_t *refl;    /* refs reflections (SSVDAG), transforms 0..47
			     (SSVDAG48); NULL in a DAG */
};

struct vd_dag {
	uint32_t kind;         /* VD_KIND_DAG, VD_KIND_SSVDAG or _SSVDAG48 */
	int levels;            /* grid depth L */
	int chunk_level;       /* level of the cell (its root) */
	uint64_t cell_morton;  /* Morton code of the cell at chunk_level */
	uint64_t voxels;       /* voxels in the cell */
	struct vd_dag_level lv[VD_MAX_LEVELS]; /* [chunk_level, levels-1] used */
	uint64_t *bricks;      /* lv[L-2].nodes bricks of level L-2 (the stored,
				  unreflected nodes); NULL when L < 2, when
				  the root is below level L-2, or the cell is
				  empty */
};

/* Options of the DAG builders. */
struct vd_dag_opts {
	int threads;               /* 0: all cores */
	uint64_t mem_budget_bytes; /* 0: no limit */
	const char *const *part_names; /* merge: names of the parts for error
					  details (file names), or NULL */
};

/* What a build or merge measured. */
struct vd_dag_stats {
	uint64_t input_voxels;
	uint64_t input_nodes;                 /* bricks or part nodes read */
	double seconds_level[VD_MAX_LEVELS];  /* reduction time per level */
	double seconds_build;                 /* whole build */
	uint64_t memory_estimate_bytes;       /* what the budget check used */
};

/* Section tags of DAG chunks. */
#define VD_TAG_DAGM VD_TAG('D', 'A', 'G', 'M') /* node masks, all levels */
#define VD_TAG_DAGC VD_TAG('D', 'A', 'G', 'C') /* child indices, uint32 */
#define VD_TAG_DAGR VD_TAG('D', 'A', 'G', 'R') /* child reflections, uint8 */

/* Reflects a 2x2x2 mask by m (bit c -> bit c ^ m). */
static inline uint8_t vd_mask_reflect(uint8_t v, unsigned m)
{
	if (m & 1) v = (uint8_t)((v & 0x55) << 1 | (v >> 1 & 0x55));
	if (m & 2) v = (uint8_t)((v & 0x33) << 2 | (v >> 2 & 0x33));
	if (m & 4) v = (uint8_t)(v << 4 | v >> 4);
	return v;
}

/* Reflects a brick by m: local Morton bit b -> b ^ (m << 3 | m). */
static inline uint64_t vd_brick_reflect(uint64_t v, unsigned m)
{
	const uint64_t k1 = 0x5555555555555555ULL, k2 = 0x3333333333333333ULL,
		       k4 = 0x0f0f0f0f0f0f0f0fULL, k8 = 0x00ff00ff00ff00ffULL,
		       k16 = 0x0000ffff0000ffffULL;
	if (m & 1) {
		v = (v & k1) << 1 | (v >> 1 & k1);
		v = (v & k8) << 8 | (v >> 8 & k8);
	}
	if (m & 2) {
		v = (v & k2) << 2 | (v >> 2 & k2);
		v = (v & k16) << 16 | (v >> 16 & k16);
	}
	if (m & 4) {
		v = (v & k4) << 4 | (v >> 4 & k4);
		v = v << 32 | v >> 32;
	}
	return v;
}

/* The symmetry class of a 2x2x2 mask: `canon` is the largest value among
 * its 8 reflections, `refl` the smallest m with vd_mask_reflect(mask, m) ==
 * canon (so mask == vd_mask_reflect(canon, refl)), and `inv` the set of
 * reflections leaving the mask unchanged (bit m set for each such m; bit 0
 * always). 46 classes, the empty mask included (Burnside: (256 + 7*16)/8). */
struct vd_leaf_class {
	uint8_t canon, refl, inv;
};

/* The 256-entry leaf table, indexed by mask. */
const struct vd_leaf_class *vd_leaf_classes(void);

/* Builds the minimal DAG of `svo` into *dag: kind VD_KIND_DAG (SVDAG),
 * VD_KIND_SSVDAG or VD_KIND_SSVDAG48 (symmetry-merged directly). `svo` must hold strictly
 * increasing, non-zero bricks inside its cell (VD_ERR_CORRUPT otherwise); an
 * empty SVO gives an empty DAG. VD_ERR_BUDGET if opts->mem_budget_bytes is
 * too small for the estimate. `stats` may be NULL. Release *dag with
 * vd_dag_release() (also after a failure). */
int vd_dag_from_svo(struct vd_dag *dag, const struct vd_svo *svo,
		    uint32_t kind, const struct vd_dag_opts *opts,
		    struct vd_dag_stats *stats);

/* Merge mode: builds the chunk of the cell at `chunk_level` that contains
 * the `n` chunks parts[0..n-1] (any order), reducing again from the leaf
 * level so that subtrees shared across parts become one; cells absent from
 * `parts` are empty. `kind` VD_KIND_DAG needs DAG parts; VD_KIND_SSVDAG
 * accepts DAG and SSVDAG parts (so one DAG part at its own chunk level is
 * the symmetry merge). chunk_level -1 means one level above the shallowest
 * part. VD_KIND_SSVDAG48 accepts parts of all three kinds;
 * VD_KIND_SSVDAG refuses ssvdag48 parts. Errors: VD_ERR_EMPTY (n == 0), VD_ERR_MISMATCH (different depths,
 * overlapping cells, cells not inside one cell at chunk_level),
 * VD_ERR_WRONG_KIND, VD_ERR_BUDGET. Release *out with vd_dag_release(). */
int vd_dag_merge(struct vd_dag *out, const struct vd_dag *const *parts,
		 size_t n, uint32_t kind, int chunk_level,
		 const struct vd_dag_opts *opts, struct vd_dag_stats *stats);

/* vd_dag_merge on parts[0..n-1] it takes over: it frees each part's levels
 * as soon as it has read them (so the merge's lower levels are never held
 * twice, as parts and as output) and releases every part before it
 * returns, whatever the outcome. Its peak is the one
 * vd_dag_estimate_merge() bounds; vd_dag_merge, which only reads its
 * parts, holds them whole to the end and is checked against a larger
 * bound. */
int vd_dag_merge_consume(struct vd_dag *out, struct vd_dag *parts, size_t n,
			 uint32_t kind, int chunk_level,
			 const struct vd_dag_opts *opts,
			 struct vd_dag_stats *stats);

/* Calls fn(ctx, key, brick) for every non-empty brick of `dag` in Morton
 * order, applying reflections (key and brick as in struct vd_svo; for
 * L < 2 one brick, key 0). Stops at and returns the first non-zero return
 * of fn. */
int vd_dag_expand(const struct vd_dag *dag,
		  int (*fn)(void *ctx, uint64_t key, uint64_t brick),
		  void *ctx);

/* The outcome of vd_dag_compare_svo(). */
struct vd_dag_diff {
	uint64_t differing_voxels;   /* 0: equal */
	uint64_t first_voxel_morton; /* the first difference in Morton order,
					a voxel Morton code (3*L bits) */
	int first_in_dag;            /* 1: that voxel is set in the DAG only,
					0: in the SVO chunks only */
};

/* Compares the voxels of `dag` with the union of the SVO chunks
 * svos[0..n-1] (any order), streaming the DAG's expansion. The SVO cells
 * must lie inside the DAG's cell, have its depth and not overlap
 * (VD_ERR_MISMATCH otherwise); voxels of the DAG outside every SVO cell
 * count as differences. Fills *diff and returns VD_OK whether or not they
 * differ. */
int vd_dag_compare_svo(const struct vd_dag *dag,
		       const struct vd_svo *const *svos, size_t n,
		       struct vd_dag_diff *diff);

/* Expands `dag` into a new SVO (release with vd_svo_release()). */
int vd_dag_to_svo(const struct vd_dag *dag, struct vd_svo *svo);

/* Checks the structure: counts, masks, indices and reflections in range,
 * every node referenced, root count. VD_ERR_CORRUPT with the detail naming
 * the first problem. */
int vd_dag_validate(const struct vd_dag *dag);

/* Fills h->kind, levels, chunk_level, cell_morton and level counts from
 * `dag` (the transform is left alone). */
void vd_dag_header(const struct vd_dag *dag, struct vd_chunk_header *h);

/* Writes `dag` as a chunk file at `path` (atomic). */
int vd_dag_save(const struct vd_dag *dag, const struct vd_transform *t,
		const char *path, const char *provenance);
/* The same, with the DAG's check and its reflections section (DAGR)
 * compressed beside the child section on up to `threads` threads (0: all
 * cores); the file is byte for byte vd_dag_save's. Memory: DAGR
 * compressed, held until DAGC is written (at most a byte a reference). */
int vd_dag_save_mt(const struct vd_dag *dag, const struct vd_transform *t,
		   const char *path, const char *provenance, int threads);

/* Reads a DAG chunk file: `kind` VD_KIND_DAG, VD_KIND_SSVDAG,
 * VD_KIND_SSVDAG48, VD_KIND_ANY (dag or ssvdag: what the stages after the
 * symmetry merge read) or VD_KIND_ANY_DAG (any of the three);
 * VD_ERR_WRONG_KIND for other kinds.
 * Validates as vd_dag_validate() and checks the voxel count. `h` may be
 * NULL. Release with vd_dag_release(). */
#define VD_KIND_ANY_DAG 0x100u
int vd_dag_load(struct vd_dag *dag, struct vd_chunk_header *h,
		const char *path, uint32_t kind);

/* The same from an opened chunk. */
int vd_dag_from_chunk(struct vd_dag *dag, const struct vd_chunk *c,
		      uint32_t kind);
/* The same, its sections decompressed on up to `threads` threads. */
int vd_dag_from_chunk_mt(struct vd_dag *dag, const struct vd_chunk *c,
			 uint32_t kind, int threads);

/* Bytes held by `dag`. */
uint64_t vd_dag_memory_bytes(const struct vd_dag *dag);

/* Upper bound of the peak bytes of vd_dag_from_svo() on an SVO with
 * `bricks` bricks, `leaves` non-empty level L-1 nodes and `parents`
 * non-empty level L-3 nodes (the SVO header's per-level counts); input
 * included. A bound, not a guess: it assumes no two nodes are equal, so a
 * real scan needs about half. The stage compares it with --mem-budget
 * before loading anything. */
uint64_t vd_dag_estimate_from_svo(uint64_t bricks, uint64_t leaves,
				  uint64_t parents);

/* The per-level totals of a merge's parts, all that its memory bound
 * needs. Zero it, then add each part (loaded, or by its header). */
struct vd_dag_census {
	int levels;                    /* grid depth L (the first part's) */
	uint64_t parts;                /* parts added */
	uint64_t nodes[VD_MAX_LEVELS]; /* nodes on level l, over the parts */
	uint64_t refs[VD_MAX_LEVELS];  /* references held on level l */
	uint64_t largest;              /* the largest part's section bytes */
	uint64_t big_nodes[VD_MAX_LEVELS]; /* most nodes of one part on l */
	uint64_t big_refs[VD_MAX_LEVELS];  /* most references of one part */
};

/* Adds a loaded part (exact counts). */
void vd_dag_census_add(struct vd_dag_census *c, const struct vd_dag *d);

/* Adds a part by its chunk header: an SVO header's counts bound those of
 * its DAG (references on level l: the SVO's nodes on level l+1); a DAG
 * header's node counts are exact and its references bounded by 8 per node,
 * as headers do not count them. */
void vd_dag_census_add_header(struct vd_dag_census *c,
			      const struct vd_chunk_header *h);

/* Upper bound of the peak bytes of vd_dag_merge_consume() into `kind` on
 * parts with census `c`, loading the parts (vd_dag_run) included. Assumes no
 * two nodes are equal, so a merge that shares much needs less. It is
 * subadditive: the bound of parts A and B together is at most the sum of
 * theirs less VD_DAG_ESTIMATE_FIXED_BYTES, so a planner may sum shares. */
uint64_t vd_dag_estimate_merge(const struct vd_dag_census *c, uint32_t kind);

/* The bound from a chunk header alone, as the stages check it before
 * loading (and as a planner should): for an SVO header, what svo-to-dag
 * needs; for a DAG or SSVDAG header, that input's share of a merge or
 * symmetry merge into its own kind (vd_dag_estimate_merge() of its census
 * for another). Sum the shares of a merge's inputs; each share includes
 * the fixed 16 MiB, so subtract VD_DAG_ESTIMATE_FIXED_BYTES per input
 * beyond the first. */
#define VD_DAG_ESTIMATE_FIXED_BYTES (16ull << 20)
uint64_t vd_dag_estimate_header(const struct vd_chunk_header *h);

/* Writes the statistics of a build (`tool` names the stage; `seconds_load`
 * and `seconds_save` are the caller's phases) as JSON to `path` (atomic):
 * per-level node and reference counts, seconds per phase, peak RSS. */
int vd_dag_write_stats(const struct vd_dag *dag,
		       const struct vd_dag_stats *st, const char *tool,
		       double seconds_load, double seconds_save,
		       const char *path);

/* One run of the svo-to-dag or symmetry-merge stage, as its main() sets
 * it up from the command line. */
struct vd_dag_job {
	const char *tool;          /* "svo-to-dag": messages and statistics */
	uint32_t kind;             /* output: VD_KIND_DAG, VD_KIND_SSVDAG or
				      VD_KIND_SSVDAG48 (--group 48) */
	int merge;                 /* inputs are DAG chunks to merge */
	int to_level;              /* merge: output chunk level, -1 default */
	const char *const *inputs; /* input chunk files */
	size_t n_inputs;
	const char *output;        /* output chunk file; statistics go to
				      output + ".stats.json" */
	const char *provenance;    /* stored in the output, or NULL */
	struct vd_dag_opts opts;
	int quiet;                 /* no summary line on stderr */
};

/* Loads the inputs (an SVO chunk for VD_KIND_DAG, a DAG chunk for
 * VD_KIND_SSVDAG; with `merge`, DAG chunks, and for VD_KIND_SSVDAG also
 * SSVDAG chunks), checks the memory budget before each load, builds,
 * saves the output atomically and writes the statistics. On failure the
 * detail is the whole message after the tool name ("cannot read 'x.svo':
 * truncated file: ...") and nothing is left at the output path. */
int vd_dag_run(const struct vd_dag_job *job);

/* Frees everything `dag` holds and zeroes it. Accepts a zeroed struct. */
void vd_dag_release(struct vd_dag *dag);

/* The whole command line of svo-to-dag and symmetry-merge (dag_main.c):
 * they share their options and differ in `kind`; `usage` is the tool's
 * --help text. Returns the exit status. */
int vd_dag_stage_main(int argc, char **argv, const char *tool, uint32_t kind,
		      const char *usage);

/* ------------------------------------------------------ end of DAG block */

/* ---- encodings (encode.c) */
/* The compact encodings of the SSVDAG paper (section 4.3), byte-compatible
 * with the files of the SymVox reference code; the byte layout is specified
 * in schemas/encodings.md. Four formats:
 *   .svdag    plain DAG in 32-bit words (from a VD_KIND_DAG root)
 *   .ussvdag  the same layout over the SSVDAG, with mirror bytes
 *   .esvdag   4^3 leaf bricks, 16-bit headers with 2-bit child tags, 16/32-bit
 *             tagged pointers, levels sorted by reference count (DAG root)
 *   .ssvdag   the same over the SSVDAG, with mirror bits in the pointers
 * A `struct vd_enc` is a file in memory: built from a root DAG by
 * vd_enc_build(), or read and validated by vd_enc_load(). Every reading
 * function below may assume a validated struct (built or loaded) and never
 * reads out of its arrays. */

enum vd_enc_format {
	VD_ENC_SVDAG = 0,
	VD_ENC_USSVDAG = 1,
	VD_ENC_ESVDAG = 2,
	VD_ENC_SSVDAG = 3,
	VD_ENC_COUNT_,  /* the four SymVox formats: 0 .. VD_ENC_COUNT_-1 */
	/* voxdag's own: the .ssvdag layout over an ssvdag48 chunk, with a
	 * 6-bit cube transform per pointer (schemas/encodings.md). Outside
	 * VD_ENC_COUNT_ so loops over the paper's four stay as they are. */
	VD_ENC_SSVDAG48 = VD_ENC_COUNT_,
	VD_ENC_ALL_
};

/* Bytes of a file that its counted size leaves out: the fixed fields before
 * and between the arrays (bounding box, side, levels, counts). A file's size
 * is vd_enc_size_bytes() plus this. */
#define VD_ENC_HEADER_BYTES_WORDS 44   /* .svdag, .ussvdag */
#define VD_ENC_HEADER_BYTES_COMPACT 48 /* .esvdag, .ssvdag */

/* "svdag", "ussvdag", "esvdag", "ssvdag", "ssvdag48" (also the file
 * extensions), or "unknown". */
const char *vd_enc_format_name(int format);

/* The format named by the extension of `path`, or -1. */
int vd_enc_format_from_path(const char *path);

/* 1 for the formats that need a symmetric DAG (USSVDAG, SSVDAG). */
static inline int vd_enc_format_symmetric(int format)
{
	return format == VD_ENC_USSVDAG || format == VD_ENC_SSVDAG;
}

/* 1 for the compact formats (ESVDAG, SSVDAG, SSVDAG48). */
static inline int vd_enc_format_compact(int format)
{
	return format == VD_ENC_ESVDAG || format == VD_ENC_SSVDAG ||
	       format == VD_ENC_SSVDAG48;
}

/* The chunk kind a format is built from: VD_KIND_DAG, VD_KIND_SSVDAG or
 * VD_KIND_SSVDAG48. */
static inline uint32_t vd_enc_format_kind(int format)
{
	return format == VD_ENC_SSVDAG48 ? VD_KIND_SSVDAG48
	       : vd_enc_format_symmetric(format) ? VD_KIND_SSVDAG : VD_KIND_DAG;
}

/* One file. Unused arrays are NULL and their counts 0. */
struct vd_enc {
	int format;               /* enum vd_enc_format */
	float bbox_min[3], bbox_max[3]; /* tight bounding box, world units */
	float root_side;          /* side of the cube, world units */
	uint32_t levels;          /* L: 2^L voxels per side */
	uint32_t node_count;      /* distinct DAG nodes on levels 0..L-1 */
	/* .svdag, .ussvdag: nodes level by level from the root */
	uint32_t first_leaf_word; /* word index of the first level L-1 node */
	uint32_t word_count;
	uint32_t *words;
	/* .esvdag, .ssvdag */
	uint32_t inner_count;     /* uint16 units of inner[] (levels 0..L-3) */
	uint16_t *inner;
	uint32_t leaf_bytes;      /* 8 per brick (level L-2 nodes) */
	uint8_t *leaves;
	uint32_t level_count;     /* L-2 */
	uint32_t *level_offsets;  /* start of inner level l in inner[] */
};

/* Encodes the root chunk `dag` (chunk_level 0) into `e` in `format`, with
 * the bounding box and side of `t`. The symmetric formats need a
 * VD_KIND_SSVDAG `dag`, the others a VD_KIND_DAG one (VD_ERR_WRONG_KIND).
 * The compact formats need L >= 3, one inner level above the bricks
 * (VD_ERR_UNSUPPORTED). VD_ERR_RANGE when a level holds more than the
 * format can address (compact: addresses from 2^30 on, more than 2^29 - 1
 * bricks; words: 2^32 words or more). An empty `dag` gives the empty scene
 * of schemas/encodings.md. Release `e` with vd_enc_release(), also after a
 * failure. */
int vd_enc_build(struct vd_enc *e, int format, const struct vd_dag *dag,
		 const struct vd_transform *t);

/* The counted size in bytes (schemas/encodings.md): 4*word_count, or
 * 2*inner_count + leaf_bytes + 4*level_count. */
uint64_t vd_enc_size_bytes(const struct vd_enc *e);

/* Writes `e` to `path` atomically (temporary name, fsync, rename). */
int vd_enc_save(const struct vd_enc *e, const char *path);

/* Reads and validates the file `path`; `format` -1 takes it from the
 * extension. Errors: VD_ERR_IO, VD_ERR_ARG (unknown extension),
 * VD_ERR_TRUNCATED, VD_ERR_TRAILING, VD_ERR_CORRUPT (a pointer out of its
 * level, a node overlapping the next level, an empty brick, ...),
 * VD_ERR_UNSUPPORTED (levels out of 1..21, compact with L < 3). */
int vd_enc_load(struct vd_enc *e, const char *path, int format);

/* The same on `size` bytes in memory (copied). */
int vd_enc_parse(struct vd_enc *e, const void *data, size_t size,
		 int format);

/* Frees the arrays of `e` and zeroes it; accepts a zeroed struct. */
void vd_enc_release(struct vd_enc *e);

/* A node reached from the root, for traversal (render): its level, where
 * it is stored and the reflection accumulated on the way (child-index bits,
 * as in the DAG block). The view below applies the reflection, so callers
 * work with logical child slots and voxels only. */
struct vd_enc_node {
	int level;      /* 0 (root) .. L-1 */
	uint64_t at;    /* words: index of the node's first word; compact:
			   index in inner[] (levels < L-2) or byte offset in
			   leaves[] (level L-2) */
	unsigned refl;  /* accumulated reflection, 0..7; for .ssvdag48 the
			   accumulated cube transform, 0..47 ("Cube group") */
};

/* The root (level 0, unreflected). */
void vd_enc_root(const struct vd_enc *e, struct vd_enc_node *n);

/* The level whose nodes are bricks: L-2 for the compact formats; for the
 * word formats L-2 too (a brick is assembled from the 8 masks below), or
 * -1 when L == 1 (the root is a 2x2x2 mask). */
int vd_enc_brick_level(const struct vd_enc *e);

/* The logical child mask of `n` (bit p set when child p = 4x+2y+z is not
 * empty); for a level L-1 node of a word format, its voxel mask. */
unsigned vd_enc_node_mask(const struct vd_enc *e, const struct vd_enc_node *n);

/* Fills *child with logical child p (0..7) of `n`, a node above the brick
 * level. Returns 1, or 0 when that child is empty. */
int vd_enc_child(const struct vd_enc *e, const struct vd_enc_node *n,
		 unsigned p, struct vd_enc_node *child);

/* The 4x4x4 voxels of `n`, a node on the brick level, in the header's
 * brick layout (Morton bits) and logical orientation. */
uint64_t vd_enc_brick(const struct vd_enc *e, const struct vd_enc_node *n);

/* Calls fn(ctx, key, brick) for every non-empty brick in Morton order, as
 * vd_dag_expand() does (for L < 2 one brick, key 0). Stops at and returns
 * the first non-zero return of fn. */
int vd_enc_expand(const struct vd_enc *e,
		  int (*fn)(void *ctx, uint64_t key, uint64_t brick),
		  void *ctx);

/* The DAG of `dag` (a root chunk, DAG or SSVDAG) cut at depth `levels`
 * (1 <= levels <= dag->levels): a voxel of the 2^levels grid is set iff a
 * voxel below it is set. Reduced again, so it equals the minimal DAG (or
 * SSVDAG) built directly at that depth. Release *out with
 * vd_dag_release(). */
int vd_enc_cut(const struct vd_dag *dag, int levels, struct vd_dag *out);

/* Per-level node counts of the (pointerless) SVO a root DAG stands for:
 * svo_nodes[l] for l = 0..L, the last being the voxel count. */
int vd_enc_svo_counts(const struct vd_dag *dag,
		      uint64_t svo_nodes[VD_MAX_LEVELS + 1]);

/* One row of the SSVDAG paper's Table 2 (and the voxels of Table 1). Node
 * counts as schemas/encodings.md says: distinct nodes over levels
 * 0..levels-1. */
struct vd_enc_row {
	int levels;                     /* resolution 2^levels */
	uint64_t voxels;
	uint64_t svo_nodes;             /* SVO nodes, levels 0..levels-1 */
	uint64_t dag_nodes;             /* SVDAG = ESVDAG */
	uint64_t ssvdag_nodes;          /* SSVDAG = USSVDAG (0 without one) */
	uint64_t ssvdag48_nodes;        /* SSVDAG48 (0 without one) */
	int has_ssvdag, has_ssvdag48;   /* which symmetric DAGs were given */
	uint64_t svo_bytes;             /* one byte per SVO node */
	uint64_t bytes[VD_ENC_ALL_];    /* vd_enc_size_bytes() per format */
	int has[VD_ENC_ALL_];           /* 0: not encodable (compact, L < 3)
					   or its DAG not given */
};

/* Computes the row of resolution 2^levels from the root DAG and the
 * SSVDAG and/or 48-group SSVDAG of one scene (same depth and voxels, else
 * VD_ERR_MISMATCH; `ssvdag` or `ssvdag48` may be NULL, not both), cutting
 * each at `levels` and encoding the cuts in memory. */
int vd_enc_table_row(const struct vd_dag *dag, const struct vd_dag *ssvdag,
		     const struct vd_dag *ssvdag48, int levels,
		     struct vd_enc_row *row);

/* Build times for Table 1, summed over the statistics files of the DAG
 * stages (load + build + save of each); negative when not given. */
struct vd_enc_timing {
	double seconds_svo_to_dag;
	double seconds_symmetry_merge;
};

/* Adds the seconds of one statistics file written by svo-to-dag or
 * symmetry-merge (by its "tool" field) to `t`. VD_ERR_FORMAT when the file
 * is not such a statistics file. */
int vd_enc_timing_add(struct vd_enc_timing *t, const char *stats_path);

/* Writes the tables as DIR/NAME.tables.json, DIR/NAME.table1.csv,
 * DIR/NAME.table2.csv and DIR/NAME.tables.md (each atomically). rows[0] is
 * the highest resolution. */
int vd_enc_write_tables(const char *dir, const char *name,
			const struct vd_enc_row *rows, size_t n,
			const struct vd_enc_timing *t, double seconds_encode);

/* One run of the encode stage, as its main() sets it up. */
struct vd_enc_job {
	const char *tool;          /* "encode", for messages */
	const char *dag_path;      /* root DAG chunk */
	const char *ssvdag_path;   /* root SSVDAG chunk, or NULL */
	const char *ssvdag48_path; /* root ssvdag48 chunk, or NULL (not both) */
	const char *outdir;        /* created if missing */
	const char *name;          /* output base name ("scene") */
	const char *const *stats_paths; /* DAG stage statistics, or NULL */
	size_t n_stats;
	int min_level;             /* lowest resolution row, 2^min_level */
	uint64_t mem_budget_bytes; /* 0: no limit */
	int threads;               /* rows computed in parallel; 0: all */
	int quiet;                 /* no summary on stderr */
};

/* Loads the root chunks, writes DIR/NAME.{svdag,esvdag}, with an SSVDAG
 * DIR/NAME.{ussvdag,ssvdag}, with an ssvdag48 DIR/NAME.ssvdag48,
 * the tables and DIR/NAME.encode.stats.json. On failure the detail is the
 * whole message after the tool name ("cannot read 'x.dag': truncated file:
 * ..."). */
int vd_enc_run(const struct vd_enc_job *job);

/* ---- end of encodings block */

/* ---- render (render.c) */
/* Ray casting straight through the compressed structures (SSVDAG paper
 * section 5): an octree DDA with a stack of the nodes on the current path,
 * carrying the accumulated 3-bit reflection (child-index bits, as in the
 * DAG block) and applying it to child slots and to the voxels of 4x4x4
 * bricks and 2x2x2 masks; when a step leaves the current node the traversal
 * pops straight to the ancestor holding the next cell (no push); optional
 * level of detail stops at nodes smaller than a given projected size.
 *
 * Ray conventions (the contract the brute-force test checks exactly):
 * - Rays live in grid coordinates: voxel (i, j, k) of the 2^L grid is the
 *   cube [i, i+1) x [j, j+1) x [k, k+1); the point at parameter t is o + t d.
 *   The world maps to the grid by g = (w - origin) / voxel_size.
 * - The time of integer plane k on axis a is the double
 *   tp(a, k) = ((double)k - o[a]) * (1.0 / d[a]), computed exactly so (no
 *   other rounding), and every decision is a comparison of such times: the
 *   voxel coordinate along a at time t is the largest k with tp(a, k) <= t
 *   when d[a] > 0, and the smallest k with tp(a, k) <= t, minus one, when
 *   d[a] < 0; when d[a] == 0 it is floor(o[a]) (as for a
 *   subnormal d[a] whose reciprocal overflows). So a boundary belongs to
 *   the voxel the ray enters (cells are half-open in the ray's direction),
 *   a ray crossing an edge or corner at one time steps diagonally without
 *   visiting the voxels beside it, and a ray lying in a grid plane
 *   perpendicular to a (d[a] == 0, o[a] an integer) sees the voxels on the
 *   + side of it.
 * - The ray is [tmin, tmax). The hit is the first voxel, in time order, that
 *   is set and is occupied by the ray at some time in [tmin, tmax). Its time
 *   is its entry time max_a tp(a, near plane) or tmin if larger; a ray
 *   starting inside a set voxel hits it at tmin with axis -1.
 * - The hit axis is the lowest axis whose near-plane time equals the entry
 *   time (the face crossed); the face normal is -sign(d[axis]) along it.
 */

/* A scene rays can be traced through: one encoding or one root DAG chunk,
 * and where its grid sits in the world. Holds pointers only: the encoding
 * or DAG must outlive it. */
struct vd_render_scene {
	const struct vd_enc *enc;   /* one of enc, dag is set */
	const struct vd_dag *dag;
	int levels;                 /* L: 2^L voxels per side */
	double origin[3];           /* world position of the grid corner */
	double voxel_size;          /* world units per voxel */
	float bbox_min[3], bbox_max[3]; /* tight bounding box, world units */
};

/* Scene over a validated encoding: the grid cube is centred on the bounding
 * box centre with the file's root side. VD_ERR_RANGE for a non-finite box
 * or side. */
int vd_render_scene_from_enc(struct vd_render_scene *s, const struct vd_enc *e);

/* Scene over a validated root DAG or SSVDAG chunk (chunk_level 0, else
 * VD_ERR_ARG) placed by `t`. */
int vd_render_scene_from_dag(struct vd_render_scene *s, const struct vd_dag *d,
			     const struct vd_transform *t);

/* One ray, in grid coordinates (see the conventions above). */
struct vd_ray {
	double o[3];      /* origin (anywhere, inside the grid or not) */
	double d[3];      /* direction, not all zero; need not be unit */
	double tmin, tmax; /* the ray is [tmin, tmax); tmax may be INFINITY */
	double lod;       /* 0: exact. Else a non-empty node of side s voxels
			     met at time t >= 0 with s <= lod * t counts as a
			     solid cell (level of detail) */
};

/* Where a ray stopped. */
struct vd_hit {
	double t;          /* hit time (entry time, or tmin when inside) */
	uint32_t cell[3];  /* the hit cell's coordinates on the 2^level grid */
	int level;         /* L for a voxel; smaller for an LOD cell */
	int axis;          /* 0..2 the face entered, -1 started inside */
};

/* Traces `r` through `s`. Returns 1 and fills *h on a hit, 0 on a miss
 * (then *h is untouched); a ray with a non-finite origin, a NaN bound or
 * a zero direction misses. Thread-safe; no allocation. */
int vd_render_trace(const struct vd_render_scene *s, const struct vd_ray *r,
		    struct vd_hit *h);

/* A pinhole camera in world units. `up` need not be orthogonal to the
 * viewing direction, only not parallel to it. */
struct vd_camera {
	double eye[3], target[3], up[3];
	double fov_deg;    /* vertical field of view, in (0, 180) */
};

/* Checks a camera: VD_ERR_ARG (detail says why) when eye == target, a
 * value is not finite, fov_deg is outside (0, 180) or up is parallel to
 * the viewing direction. */
int vd_camera_check(const struct vd_camera *c);

/* Fills `c` with the preset `name` ("front": looking along -Z, "side":
 * along -X, "top": down along -Y, "iso": from +X+Y+Z) at the nearest
 * distance (plus 8%) where the 8 corners of the scene's bounding box fit a
 * width x height image with vertical field of view fov_deg.
 * VD_ERR_ARG for an unknown name. */
int vd_camera_preset(struct vd_camera *c, const struct vd_render_scene *s,
		     const char *name, double fov_deg, int width, int height);

/* What to render. */
struct vd_colour_source;

struct vd_render_opts {
	int width, height;        /* pixels, 1..VD_RENDER_MAX_SIDE each */
	struct vd_camera cam;
	double light[3];          /* point light, world units */
	int shadows;              /* 1: cast a shadow ray per lit pixel */
	double lod_pixels;        /* 0: exact; else stop at nodes whose
				     projection is at most this many pixels */
	int threads;              /* 0: all cores */
	/* Voxel colours (NULL: one grey). A hit voxel takes its colour, an
	 * LOD cell its first voxel's; the source must cover exactly the
	 * scene's voxels (VD_ERR_MISMATCH). */
	const struct vd_colour_source *colours;
	const struct vd_render_scene *diff; /* NULL, or a second scene on the
				     same grid (levels, origin, voxel size):
				     the picture is then of both scenes'
				     voxels, and those set in only one of
				     them are red (lossy paper, Fig. 1);
				     exact rendering only (lod_pixels 0) */
};

#define VD_RENDER_MAX_SIDE 16384
#define VD_RENDER_MAX_PIXELS (1ull << 26)

/* A rendered image and its buffers, row-major from the top-left pixel. */
struct vd_image {
	int width, height;
	uint8_t *rgb;             /* 3 bytes per pixel, sRGB */
	float *depth;             /* hit distance in world units along the
				     unit view ray; INFINITY on a miss */
	struct vd_hit *hits;      /* level -1 on a miss */
	uint8_t *differs;         /* with opts.diff: 1 where the hit voxel is
				     set in one scene only; else NULL */
	uint64_t differing_pixels;
	uint64_t primary_rays, shadow_rays;
	double seconds_primary, seconds_shade;
};

/* Renders `s` as `o` says into *img (release with vd_image_release(), also
 * after a failure): primary rays, normals from the depth buffer (the hit
 * face where neighbours are missing), Lambert shading, hard shadows. The
 * pixels depend only on the hits, so equal scenes give equal images
 * whatever the encoding. VD_ERR_ARG for a bad size or camera. */
int vd_render_image(const struct vd_render_scene *s,
		    const struct vd_render_opts *o, struct vd_image *img);

void vd_image_release(struct vd_image *img);

/* Writes img->rgb as an 8-bit RGB PNG at `path` (atomic). */
int vd_image_write_png(const struct vd_image *img, const char *path);

/* Writes the depth buffer: ".pfm" as a float32 greyscale PFM (bottom row
 * first, as the format says; misses +INFINITY), ".png" as a 16-bit
 * greyscale PNG (0 a miss, 1..65535 nearest to farthest hit, linear).
 * VD_ERR_ARG for another extension. Atomic. */
int vd_image_write_depth(const struct vd_image *img, const char *path);

/* Writes the hit cells (schemas/render-outputs.md): a 16-byte header
 * (bytes 0x89 'V' 'I' 'D', u32 version 1, u32 width, u32 height) then per
 * pixel u32 x, y, z, level, little-endian; all four 0xffffffff on a miss.
 * Atomic. */
int vd_image_write_ids(const struct vd_image *img, const char *path);

/* Image comparison (render/metrics.c; conventions there): MSE over the RGB
 * bytes, PSNR in dB, single-scale SSIM and 5-scale MS-SSIM on luma. */
struct vd_image_metrics {
	double mse, psnr, ssim, ms_ssim;
};

/* Compares two w x h RGB images. mse and psnr are always set; SSIM needs
 * 11 pixels and MS-SSIM 176 on each side: what cannot be computed is NaN
 * and the return VD_ERR_ARG. */
int vd_image_metrics(const uint8_t *a, const uint8_t *b, int w, int h,
		     struct vd_image_metrics *m);

/* SSIM and mean contrast-structure of two w x h greyscale images (values
 * in 0..255) at one scale. */
int vd_ssim_scale(const double *a, const double *b, int w, int h,
		  double *ssim, double *cs);

/* Reads a PNG of any colour type as 8-bit RGB (*rgb: free with free()). */
int vd_png_read_rgb(const char *path, uint8_t **rgb, int *width,
		    int *height);

/* One run of the render stage, as its main() sets it up. */
struct vd_render_job {
	const char *tool;          /* "render", for messages */
	const char *input;         /* an encoding or a root DAG/SSVDAG chunk */
	const char *output;        /* PNG */
	const char *depth_path;    /* or NULL */
	const char *ids_path;      /* or NULL */
	const char *diff_input;    /* or NULL: a second scene (opts.diff) */
	const char *preset;        /* camera preset, used when !has_eye */
	int has_eye;               /* opts.cam.eye/target given */
	int has_light;             /* opts.light given (else above the eye) */
	struct vd_render_opts opts;
	int quiet;                 /* no summary on stderr */
	int no_verify;             /* read an encoding without its manifest */
	const char *colours;       /* vd_colour_source_open() path, or NULL */
};

/* Loads the input (a chunk file by its magic, else an encoding by its
 * extension, checked against the manifest beside it unless no_verify:
 * vd_manifest_check_file()), sets up the camera and light, renders and writes the
 * outputs. On failure the detail is the whole message after the tool name
 * ("cannot read 'x.ssvdag': truncated file: ..."). With diff_input,
 * that scene is loaded the same way and must lie on the same grid
 * (VD_ERR_MISMATCH); the camera frames the input. */
int vd_render_run(const struct vd_render_job *job);

/* ---- end of render block */

/* ---- voxel counts and colour indices (colour/voxcount.c)
 * The colour paper's §3: each DAG node's voxel count, from which a voxel's
 * index in the scene's colour array (Morton order of the set voxels, the
 * order of the colour chunks) is a sum along its path. Works on a DAG or
 * SSVDAG chunk (reflections: logical child order, counts at the stored
 * slots) and on every encoding (through the logical view of vd_enc_*). */
struct vd_voxcount {
	const struct vd_dag *dag;   /* one of dag, enc */
	const struct vd_enc *enc;
	int levels;
	uint64_t voxels;            /* voxels below the root */
	/* DAG: count[l][i] for node i of level l (cap = used = nodes).
	 * Encoding: a hash per level above the brick level, key[l][j] = node
	 * position + 1 (0 = free slot), count[l][j] its count. */
	uint64_t *count[VD_MAX_LEVELS];
	uint64_t *key[VD_MAX_LEVELS];
	uint64_t cap[VD_MAX_LEVELS], used[VD_MAX_LEVELS];
};

/* Counts of every node of `d` (any chunk level) or of the encoding `e`,
 * which must outlive *vc. Release with vd_voxcount_release(). */
int vd_voxcount_from_dag(struct vd_voxcount *vc, const struct vd_dag *d);
int vd_voxcount_from_enc(struct vd_voxcount *vc, const struct vd_enc *e);

/* For the cell (x, y, z) of the 2^level grid (level L: a voxel; smaller: a
 * cell, as a level-of-detail hit): returns 1 and sets *index to the colour
 * index of the cell's first voxel in Morton order, or 0 when the cell is
 * empty. For a chunk that is not the root, indices count from the chunk's
 * first voxel. */
int vd_voxcount_index(const struct vd_voxcount *vc, int level, uint32_t x,
		      uint32_t y, uint32_t z, uint64_t *index);

/* Bytes of the counts a renderer would store beside the nodes: levels
 * above the brick level, each at the smallest of 1/2/4/8 bytes per count
 * holding its largest one (brick and mask counts are popcounts). */
uint64_t vd_voxcount_stored_bytes(const struct vd_voxcount *vc);

void vd_voxcount_release(struct vd_voxcount *vc);

/* Colour sources: the colour of voxel i of the scene's colour array, from
 * the colour chunks voxelize writes (a directory) or a compressed file of
 * colorize. get() is thread-safe and takes index < voxels. */
struct vd_colour_source {
	uint64_t voxels;            /* length of the colour array */
	int levels;                 /* grid depth the colours were made at */
	int cell_level;             /* chunk level of its cells (-1 unknown) */
	void (*get)(const struct vd_colour_source *s, uint64_t index,
		    uint8_t rgb[3]);
	void *impl;
	void (*release)(struct vd_colour_source *s);
};

/* Opens `path`: a directory of colour chunks (each checked against the SVO
 * chunk beside it, concatenated in cell order), or a packed colours file of
 * colorize (colours.vbr, .palette, .raw; checked against the manifest
 * beside it, decoded voxel by voxel on demand). */
int vd_colour_source_open(struct vd_colour_source *s, const char *path);
void vd_colour_source_release(struct vd_colour_source *s);

/* The whole colour array of the colour chunks in `dir`, in cell order
 * (3 bytes per voxel, free with free()), each chunk verified against the
 * SVO chunk beside it. *first gets the first chunk's header (or NULL). */
int vd_colour_chunks_load(const char *dir, uint8_t **rgb, uint64_t *voxels,
			  struct vd_chunk_header *first);

/* ---- end of voxel counts block */

/* ---- Cube group (symmetry-merge --group 48)
 *
 * The 48 symmetries of the cube, numbered t = 8 * k + m: k (0..5) an axis
 * permutation, m (0..7) a reflection in the bits of the 8-reflection group
 * (bit 2 = X, bit 1 = Y, bit 0 = Z). Transform t maps a point p of an
 * n-cube to q with q[i] = p[perm[k][i]] (axis 0 = X, 1 = Y, 2 = Z), then
 * q[i] = n - 1 - q[i] for each axis i reflected by m: permute first, then
 * reflect. t = 0 is the identity; t < 8 are the SSVDAG's reflections with
 * the same numbering. Permutations k: 0 XYZ, 1 XZY, 2 YXZ, 3 YZX, 4 ZXY,
 * 5 ZYX (output axis i takes input axis perm[k][i]). A transformed subtree
 * holds voxel T(p) for each voxel p of the original. */
#define VD_G48 48
/* The cube group has 98 subgroups (its invariance sets). */
#define VD_G48_SUBGROUPS 98

/* perm[k] of transform t: output axis i takes input axis vd_g48_perm(t)[i]. */
const uint8_t *vd_g48_perm(unsigned t);
/* Child index c (bit 2 = x, 1 = y, 0 = z) moved by t. */
unsigned vd_g48_child(unsigned t, unsigned c);
/* The transform p -> a(b(p)). */
unsigned vd_g48_compose(unsigned a, unsigned b);
/* The transform u with vd_g48_compose(t, u) == 0. */
unsigned vd_g48_inverse(unsigned t);
/* A 2x2x2 mask transformed by t: bit c -> bit vd_g48_child(t, c). */
uint8_t vd_g48_mask(uint8_t v, unsigned t);
/* A brick (byte c = child c's mask) transformed by t: local Morton bit
 * c << 3 | c' -> child(t, c) << 3 | child(t, c'). */
uint64_t vd_g48_brick(uint64_t v, unsigned t);

/* The number of subgroups found (VD_G48_SUBGROUPS; a test checks it). */
unsigned vd_g48_subgroup_count(void);

/* The 256-entry leaf table under the 48: `canon` the largest of the 48
 * transforms of the mask, `refl` the transform t with vd_g48_mask(canon, t)
 * == mask, `inv` the index of its invariance subgroup (not a set). */
const struct vd_leaf_class *vd_leaf_classes48(void);

/* ---- end of cube group block */

/* ------------------------------------------------------- edit (lib/edit/)
 * The HashDAG of Careil, Billeter and Eisemann (2020) on the CPU: a root
 * DAG chunk loaded into per-level hashed tables so that edits (fill, carve,
 * copy) descend only where they change something, find or append the new
 * nodes by hashing and yield a new root while the old roots stay valid
 * (undo / redo). Per level, 2^P buckets of 2^M 32-bit words are reserved
 * as virtual memory (mmap MAP_NORESERVE) and committed only when touched;
 * a node's pointer is bucket << M | offset. Inner nodes are hashed with
 * XXH3, the 4x4x4 leaf bricks with a 64-bit bit mixer. A full bucket fails
 * the edit with VD_ERR_BUDGET (the scene is left as it was): run gc, or
 * reserve more (larger buckets_log2 / bucket_words_log2). Saving writes the
 * minimal DAG svo-to-dag would build for the same voxels, byte for byte.
 * The line format of edit scripts and the shell: schemas/edit-script.md. */
struct vd_hashdag;

struct vd_hashdag_opts {
	int buckets_log2;      /* P: level l gets 2^min(P, 3 l + 4) buckets;
				  0: automatic, from the level's size at
				  load (buckets at most half full, at least
				  2^min(3 l + 4, 10)) */
	int bucket_words_log2; /* M (0: 10); P + M <= 30 */
	int threads;           /* 0: all cores */
	int split_level;       /* edits run one job per node of this level
				  (0: 3, clamped to L-2) */
	uint64_t mem_budget_bytes; /* 0: none. Else the bucket tables, the
				  committed pages of every level (counted
				  per 4 KiB page a bucket touches, so an
				  over-estimate when buckets are smaller than
				  a page) and the colour arrays stay under it:
				  loading or an edit that would pass it fails
				  with VD_ERR_BUDGET naming what it needs */
	int colour_segment_log2; /* with colours: each cell's colour array is
				  kept in segments, the subtrees of side
				  2^this, so an edit rebuilds the segments
				  it meets only (0: 6; clamped to the cell
				  and brick sides) */
};

enum vd_edit_kind { VD_EDIT_FILL, VD_EDIT_CARVE, VD_EDIT_COPY,
		    VD_EDIT_PAINT };
enum vd_edit_shape { VD_SHAPE_BOX, VD_SHAPE_SPHERE };

/* One edit in voxel coordinates. Box: voxels lo..hi inclusive, inside the
 * grid. Sphere: voxels whose centre (x + 0.5, y + 0.5, z + 0.5) is at
 * distance <= r of c. Copy: the box lo..hi of the scene before the edit is
 * written (set and cleared voxels) at dst..dst + hi - lo. */
struct vd_edit_op {
	int kind;              /* enum vd_edit_kind */
	int shape;             /* enum vd_edit_shape (copy: box) */
	int64_t lo[3], hi[3];  /* box */
	double c[3], r;        /* sphere */
	int64_t dst[3];        /* copy destination corner */
	int has_rgb;           /* fill, paint: rgb given (paint needs it) */
	uint8_t rgb[3];        /* sRGB colour */
};

/* What one edit (or gc) did. */
struct vd_edit_stats {
	uint64_t voxels_changed;
	uint64_t nodes_added[VD_MAX_LEVELS];  /* per level 0..L-2 */
	double seconds;
	uint64_t hash_bytes;                  /* committed bytes afterwards */
	double cpu_seconds;                   /* CPU time of the process
						 (all threads): the machine
						 may be shared */
	uint64_t colour_cells_rebuilt;        /* with colours: cells whose
						 colour array was rebuilt */
};

/* Loads a root DAG chunk (kind dag, chunk_level 0, L >= 3). `o` may be
 * NULL. Free with vd_hashdag_free(). */
int vd_hashdag_load(struct vd_hashdag **out, const char *path,
		    const struct vd_hashdag_opts *o);
/* The same from a DAG in memory placed by `t`. */
int vd_hashdag_from_dag(struct vd_hashdag **out, const struct vd_dag *dag,
			const struct vd_transform *t,
			const struct vd_hashdag_opts *o);
void vd_hashdag_free(struct vd_hashdag *h);

int vd_hashdag_levels(const struct vd_hashdag *h);
const struct vd_transform *vd_hashdag_transform(const struct vd_hashdag *h);

/* Checks `op` against the grid (VD_ERR_RANGE, detail says what). */
int vd_edit_op_check(const struct vd_hashdag *h, const struct vd_edit_op *op);

/* Applies `op` to the current scene and makes the result current (the redo
 * part of the history is dropped). VD_ERR_UNSUPPORTED for paint or a
 * colour without colours (vd_hashdag_colours_open), VD_ERR_BUDGET for a
 * full bucket or the memory budget (nothing changes). `st` may be NULL.
 * With colours, the scene's colour array follows the edit (colour rules
 * in schemas/edit-script.md): filled voxels take op->rgb, or the default
 * colour when the op has none; carved voxels drop theirs; copied voxels
 * take their source's; paint sets op->rgb on the set voxels of the region
 * (for paint, voxels_changed counts the voxels whose colour changed). Only
 * the colours of the segments (opts.colour_segment_log2) the region meets
 * are rebuilt; the others are shared with the previous root of the
 * history, so an edit costs what its region holds, not what its cells
 * hold. */
int vd_hashdag_apply(struct vd_hashdag *h, const struct vd_edit_op *op,
		     struct vd_edit_stats *st);

/* Steps through the history: VD_ERR_RANGE when there is nothing to undo or
 * redo. */
int vd_hashdag_undo(struct vd_hashdag *h);
int vd_hashdag_redo(struct vd_hashdag *h);

/* Garbage collection: keeps the current root (keep_history 0; the history
 * becomes that one root) or every root of the history, drops every other
 * node and compacts each level bottom-up into fresh tables. Afterwards the
 * tables hold exactly the nodes reachable from the kept roots. */
int vd_hashdag_gc(struct vd_hashdag *h, int keep_history,
		  struct vd_edit_stats *st);

/* Per level 0..L-2: nodes stored, and nodes reachable from the current
 * root (either may be NULL). */
void vd_hashdag_counts(const struct vd_hashdag *h, uint64_t *stored,
		       uint64_t *reachable);
/* Bytes of the committed pages of the tables plus their bookkeeping. */
uint64_t vd_hashdag_memory_bytes(const struct vd_hashdag *h);
/* Fullest bucket of level l, in words used. */
uint32_t vd_hashdag_max_bucket(const struct vd_hashdag *h, int l);

/* The current scene as SVO bricks (Morton order), as the minimal DAG that
 * svo-to-dag builds from those bricks, or saved as a root DAG chunk. */
int vd_hashdag_to_svo(const struct vd_hashdag *h, struct vd_svo *svo);
int vd_hashdag_to_dag(const struct vd_hashdag *h, struct vd_dag *dag);
int vd_hashdag_save(const struct vd_hashdag *h, const char *path,
		    const char *provenance);

/* Colours (stages/lib/edit/colours.c). The scene's colour array (the
 * colour paper's depth-first order) kept per cell of the source's chunk
 * level (a packed file's cells; min(3, L-2) when unknown) in segments,
 * each cell's table of segments and each segment shared between the roots
 * of the history that did not change it,
 * so undo, redo and gc carry colours along. `src` is what
 * vd_colour_source_open() takes (a voxelize directory of .col chunks or a
 * colorize packed file); it must hold exactly the current scene's voxels
 * at the same depth (VD_ERR_MISMATCH). `fill_rgb` is the colour of voxels
 * a fill without a colour adds (NULL: VD_EDIT_DEFAULT_RGB). */
#define VD_EDIT_DEFAULT_RGB {128, 128, 128}
int vd_hashdag_colours_open(struct vd_hashdag *h, const char *src,
			    const uint8_t *fill_rgb);
/* 1 when the scene has colours. */
int vd_hashdag_has_colours(const struct vd_hashdag *h);
/* The current scene's colour array, 3 bytes per voxel in depth-first
 * order (*rgb: free with free()); VD_ERR_UNSUPPORTED without colours. */
int vd_hashdag_colour_array(const struct vd_hashdag *h, uint8_t **rgb,
			    uint64_t *voxels);
/* Writes the current scene as a voxelize-style directory `dir`: per
 * non-empty cell its SVO chunk and colour chunk (chunk-L<C>-<cell>.svo,
 * .col) and a manifest, staged and published whole (vd_dir_stage). Cells
 * whose colours and voxels are those loaded from a source directory are
 * hard links to the source's files (copies when links fail); the others
 * are written. So render --colours DIR and colorize DIR take it. */
int vd_hashdag_colours_save(const struct vd_hashdag *h, const char *dir,
			    const char *provenance);

/* The first half of vd_hashdag_colours_save, for publishing the colours
 * together with the DAG: writes the directory complete (cells and
 * manifest) under the staging name it puts in `staging` (cap bytes), for
 * the caller to publish with vd_dir_swap() or drop with vd_dir_abandon().
 * On failure nothing is left behind. */
int vd_hashdag_colours_stage(const struct vd_hashdag *h, const char *dir,
			     const char *provenance, char *staging,
			     size_t cap);

/* One run of the edit tool (script.c). */
struct vd_edit_job {
	const char *tool;         /* "edit" */
	const char *input;        /* root DAG chunk */
	const char *output;       /* edited chunk; statistics beside it with
				     ".stats.json" (script mode) */
	const char *script;       /* script file, or NULL for the shell */
	FILE *in, *out;           /* shell streams */
	const char *provenance;
	struct vd_hashdag_opts opts;
	int quiet;
	const char *colours;      /* colour source, or NULL */
	const char *colours_out;  /* colour directory written beside output */
	int has_fill_rgb;
	uint8_t fill_rgb[3];      /* default fill colour (has_fill_rgb) */
};

/* Script mode: parses and checks the whole script first (errors name line
 * and column), loads, applies, saves and writes the statistics. Shell mode
 * (script NULL): reads lines from job->in and answers on job->out. On
 * failure the detail is the whole message after the tool name. */
int vd_edit_run(const struct vd_edit_job *job);

/* ----------------------------------------------------- end of edit block */


/* ------------------------------------------------ lossy SVDAGs (lossy.c)
 * van der Laan, Scandolo and Eisemann 2020: on each level from height 2
 * (level L-2) up to the root, nodes whose effective reference count (how
 * often their subtree occurs in the scene) is at most max_refs and whose
 * voxels differ by at most m = h^2 * diff_factor (m = 1 at height 2) from
 * another such node are joined in a similarity graph, clustered by Markov
 * clustering per connected component, and every cluster replaced by its
 * member with the largest sum of similarities; the levels above are then
 * reduced losslessly again. The result is an ordinary minimal SVDAG. */
struct vd_lossy_opts {
	double inflation;          /* MCL inflation, > 1 (default 2.0) */
	double diff_factor;        /* p of m = h^2 * p (default 1.0) */
	uint64_t max_refs;         /* R: candidates have <= R effective refs */
	int threads;               /* 0: all cores */
	uint64_t mem_budget;       /* bytes, 0: none. Every phase stays
				    * under it: a level's arrays that do not
				    * fit fail the run (VD_ERR_BUDGET); a
				    * similarity graph that would pass it is
				    * spilled to a file in $TMPDIR (or /tmp)
				    * and clustered a few components at a
				    * time, the Markov clustering's matrices
				    * counted as they grow, with the same
				    * result; a single component over what is
				    * left fails the run (VD_ERR_BUDGET); the
				    * final difference remembers pairs of
				    * subtrees only within what is left,
				    * walking the others again */
	uint64_t graph_budget;     /* bytes for a level's similarity graph in
				    * memory, 0: what is left of mem_budget
				    * beside the process's RSS when the
				    * search starts (a fixed figure for
				    * tests: the RSS varies, under ASan much) */
	int levels;                /* vd_lossy_run: cut the input at this
				    * depth first (vd_enc_cut), a 2^levels
				    * grid; 0: the input's own */
};

struct vd_lossy_level_stats {
	int level, height;
	uint64_t candidates, graph_nodes, edges, clusters, merged;
	uint64_t level_nodes_before, level_nodes_after; /* on this level */
	uint64_t nodes_before, nodes_after;             /* all levels */
	int graph_spilled;       /* the graph went to disk (--mem-budget) */
	uint64_t spill_buckets;  /* then: the groups of components loaded */
};

struct vd_lossy_stats {
	struct vd_lossy_level_stats level[VD_MAX_LEVELS]; /* bottom-up */
	int n_levels;
	uint64_t nodes_before, nodes_after;
	uint64_t voxels_before, voxels_after, voxels_set, voxels_cleared;
	double seconds_eff, seconds_graph, seconds_cluster, seconds_reduce,
	       seconds_diff;
	/* CPU seconds of the process (all threads) over the four phases
	 * above: on a shared machine wall time is not the work done */
	double cpu_seconds_lossy;
	/* vd_lossy_run with levels: seconds of cutting the input */
	double seconds_cut;
};

/* An edge of a similarity graph: u < v, `diff` voxels apart, similarity
 * s = 1 - diff / (m + 1). */
struct vd_lossy_edge {
	uint32_t u, v, diff;
	double s;
};

/* Clusters the SVDAG `dag` in place (VD_ERR_WRONG_KIND for an SSVDAG,
 * VD_ERR_ARG for parameters out of range). The voxel statistics come from
 * vd_dag_diff() of the input and the result. */
int vd_lossy_cluster(struct vd_dag *dag, const struct vd_lossy_opts *o,
		     struct vd_lossy_stats *st);

/* Effective reference counts of the nodes of levels chunk_level..to_level
 * into new arrays eff[l] (free each; the others are set to NULL): the root
 * counts 1, a node the sum of its parents' counts per reference. */
int vd_lossy_effective_refs(const struct vd_dag *dag, int to_level,
			    uint64_t **eff);

/* The similar pairs among the candidates of level l (eff[i] <= max_refs),
 * edges as node indices of level l sorted by (u, v), in a new array
 * (free()); *candidates gets their number. The same for any `threads`. */
int vd_lossy_similar_pairs(const struct vd_dag *dag, int l,
			   const uint64_t *eff, uint64_t max_refs,
			   double diff_factor, int threads,
			   struct vd_lossy_edge **edges,
			   size_t *n_edges, uint64_t *candidates);

/* Markov clustering of the graph of n nodes and edges e[0..ne-1] (u < v,
 * weights s), per connected component, with mcl's defaults (a loop on every
 * node weighing its largest edge weight, pruning below 1/10000, at most
 * 1100 entries per column). cluster[i] = the smallest node of i's cluster.
 * The same clusters for any `threads`. */
int vd_lossy_mcl(uint32_t n, const struct vd_lossy_edge *e, size_t ne,
		 double inflation, int threads, uint32_t *cluster);

/* Voxels set in a but not in b (*only_a) and in b but not in a (*only_b),
 * walking both SVDAGs of the same cell together (pairs of nodes counted
 * once); *voxels_b gets b's voxel count. */
int vd_dag_diff(const struct vd_dag *a, const struct vd_dag *b,
		uint64_t *only_a, uint64_t *only_b, uint64_t *voxels_b);

/* Writes the statistics of a lossy clustering as JSON to `path` (atomic). */
int vd_lossy_write_stats(const struct vd_dag *dag,
			 const struct vd_lossy_opts *o,
			 const struct vd_lossy_stats *st, double seconds_load,
			 double seconds_save, const char *path);

/* The lossy-cluster stage: reads the DAG chunk `in` (kind dag), clusters
 * it, writes `out` and `out`.stats.json (atomic; neither is left on a
 * failure). mem_budget 0: no limit. */
int vd_lossy_run(const char *in, const char *out,
		 const struct vd_lossy_opts *o, uint64_t mem_budget,
		 const char *provenance, int quiet);

#ifdef __cplusplus
}
#endif

#endif /* VOXDAG_H */
