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
	VD_KIND_COLOURS = 5, /* voxel colours (colorize stage) */
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
 * the default level 3; negative stores the bytes uncompressed). Only one
 * section is open at a time. */
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

/* The same on an in-memory image of `size` bytes (copied). */
int vd_chunk_open_mem(struct vd_chunk **out, const void *data, size_t size,
		      uint32_t kind);

const struct vd_chunk_header *vd_chunk_header(const struct vd_chunk *c);

/* Decompresses section `tag` into a new buffer (*data, free with free();
 * *data is non-NULL even for an empty section) of *size bytes. Returns
 * VD_ERR_CORRUPT if the section is missing (detail names it). */
int vd_chunk_read_section(const struct vd_chunk *c, uint32_t tag,
			  void **data, size_t *size);

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
 * OBJ and STL (binary and ASCII). Indexed formats keep their vertex
 * positions in memory (12 bytes per vertex); triangles are streamed. */

struct vd_triangle {
	float v[3][3]; /* three vertices, x y z each, world units */
};

/* What the reader saw. A face with fewer than 3 corners is dropped and
 * counted; a face with more is fan-triangulated. A vertex with a NaN or
 * infinite coordinate is an error (VD_ERR_RANGE) as soon as a face uses it;
 * unused vertices are never checked. */
struct vd_mesh_stats {
	uint64_t triangles_read;     /* triangles handed to the caller */
	uint64_t faces_dropped_short;/* faces with fewer than 3 corners */
	uint64_t polygons_split;     /* faces with more than 3 corners */
	uint64_t vertices;           /* vertices declared (indexed formats) */
};

struct vd_mesh;

/* Opens `path`, detecting the format from its first bytes (PLY magic, STL
 * binary size rule / "solid", OBJ otherwise if the extension is .obj or the
 * first statement is an OBJ one). Parses the header (PLY: also loads the
 * vertices); the body is read by vd_mesh_read(). Errors: VD_ERR_IO (also a
 * directory), VD_ERR_EMPTY (0-byte file), VD_ERR_UNSUPPORTED (unknown
 * format), VD_ERR_FORMAT (bad header), VD_ERR_TRUNCATED (also counts the
 * file cannot hold), VD_ERR_TRAILING (binary STL longer than its count). */
int vd_mesh_open(struct vd_mesh **out, const char *path);

/* Reads up to `cap` triangles into `buf` and sets *n; *n == 0 means the
 * end of the mesh. Errors: VD_ERR_FORMAT (syntax, with the line or byte
 * offset in the detail), VD_ERR_RANGE (index out of range, non-finite
 * coordinate), VD_ERR_TRUNCATED (file ends inside the body). An OBJ face
 * may only use vertices defined before it (VD_ERR_RANGE otherwise). After
 * an error every read repeats it until vd_mesh_rewind(). */
int vd_mesh_read(struct vd_mesh *m, struct vd_triangle *buf, size_t cap,
		 size_t *n);

/* Restarts reading at the first triangle (for a second pass); counts
 * restart too. */
int vd_mesh_rewind(struct vd_mesh *m);

/* "ply-binary-le", "ply-ascii", "obj", "stl-binary", "stl-ascii", ... */
const char *vd_mesh_format(const struct vd_mesh *m);
/* Bytes of memory the reader holds (vertex arrays, read buffer), for
 * budgets. OBJ vertices are collected while reading, so for OBJ this is
 * final only after a whole pass. */
size_t vd_mesh_memory_bytes(const struct vd_mesh *m);
const struct vd_mesh_stats *vd_mesh_stats(const struct vd_mesh *m);
void vd_mesh_close(struct vd_mesh *m);

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

/* Monotonic seconds. */
double vd_seconds(void);

/* Builds the provenance text stored in chunk files:
 * "tool=NAME version=X args='a' 'b' ...". Returns a malloc'd string (free
 * with free()), NULL when out of memory. */
char *vd_provenance_new(const char *tool, int argc, char **argv);

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

/* ---- OpenVDB (vdb.cc)
 * OpenVDB grids in and out. vdb.cc is the only file that includes OpenVDB;
 * every exception is caught there and returned as an error code with a
 * detail line. The import driver (vdb_import.c) and the chunk export
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
};

/* opts->levels: 0 to fit (see above), or the depth to resample to. */
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
};

/* Voxelizes the mesh at `mesh_path` into SVO chunk files
 * OUTDIR/chunk-L<L0>-<morton>.svo, one per non-empty cell. Existing chunk
 * files of an earlier run in `outdir` are removed first. */
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

/* ------------------------------------------------- DAG and SSVDAG (dag.c) */

/* ------------------------------------------------------ end of DAG block */

#ifdef __cplusplus
}
#endif

#endif /* VOXDAG_H */
