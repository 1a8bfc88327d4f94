/* vd_colour.h - voxel colours (colour/): the compressed colour
 * arrays (VBR blocks, palettes), colorize, and the per-node voxel counts
 * through which a voxel finds its colour.
 */
#ifndef VD_COLOUR_H
#define VD_COLOUR_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include "vd_voxel.h"

#ifdef __cplusplus
extern "C" {
#endif

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
 * - auto: fixed-size blocks (2^block_log voxels), each stored in the
 *   cheapest of five modes (constant, local palette, two endpoints with
 *   per-voxel weights, per-channel quantised offsets from the block's
 *   minimum, raw) that keeps every colour within max_error (0: lossless).
 *   A voxel's colour is one directory entry plus a few bytes of one block.
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
	VD_CPACK_AUTO = 4,
};

/* "vbr", "palette", "raw", "auto"; NULL if unknown. */
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

/* The auto method's blocks (schemas/colour-formats.md, method 4). */
struct vd_auto_params {
	double max_error;   /* sRGB distance, channels in [0,1]; 0: lossless */
	int block_log;      /* blocks of 2^block_log voxels, 4..12 (0: 8) */
	int coded;          /* 1 (lossless only): each segment may carry a
			     * code table and blocks in the coded mode
			     * (format 1.2); 0: the 1.1 layout */
};

/* Block modes: the top byte of a block's directory entry. */
enum vd_auto_mode {
	VD_AUTO_CONST = 0x00,    /* colour in the entry's low 24 bits */
	VD_AUTO_PALETTE = 0x10,  /* | index bits 1..8 */
	VD_AUTO_ENDPOINTS = 0x20,/* | weight bits 1..8 */
	VD_AUTO_QUANT = 0x30,
	VD_AUTO_RAW = 0x40,
	VD_AUTO_CODED = 0x50,    /* lossless, needs its segment's code table */
};
#define VD_AUTO_MODES 6

/* One segment encoded: dir[b] the directory entry of block b (mode << 24
 * | byte offset in `data`, or | colour for a constant block), `data` the
 * blocks' bytes in block order. */
struct vd_auto_segment {
	uint32_t n, count;
	uint32_t *dir;
	uint8_t *data;
	size_t data_bytes;
	uint64_t sse;
	unsigned max_dist2;
	uint64_t mode_blocks[VD_AUTO_MODES]; /* blocks per mode (by mode >> 4) */
	uint32_t table_bytes;     /* coded: bytes of the segment's code table
				   * (0: none), after the u16 at data[0] */
};

/* Encodes rgb[0..n) (n <= VD_CPACK_SEGMENT_MAX) into blocks of
 * 2^p->block_log voxels, each in the mode of fewest bytes whose every
 * colour decodes within p->max_error (vd_colour_error_limit; 0: exactly).
 * Errors: VD_ERR_ARG, VD_ERR_NOMEM. Release with
 * vd_auto_segment_release(). */
int vd_auto_encode(struct vd_auto_segment *s, const uint8_t *rgb, uint32_t n,
		   const struct vd_auto_params *p);
/* Colour j (< n) of an encoded segment (the reader's decode). */
void vd_auto_segment_colour(const struct vd_auto_segment *s, int block_log,
			    uint32_t j, uint8_t rgb[3]);
/* Readable bytes the decoder needs past a segment's last block (it reads
 * bit fields 4 bytes at a time); vd_auto_encode leaves them zero. */
#define VD_AUTO_PAD 8
/* The n colours of one block into rgb (3n bytes): `entry` its directory
 * entry (dir[b]), `data` the bytes of its segment (its blocks from offset
 * 0, with VD_AUTO_PAD readable bytes after the last), n its length (the
 * block length, or what is left of the segment for its last block).
 * Blocks decode alone: an editor decodes the blocks it changes. */
void vd_auto_block_decode(uint32_t entry, const uint8_t *data, uint32_t n,
			  uint8_t *rgb);
void vd_auto_segment_release(struct vd_auto_segment *s);

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

/* Writing a packed colours file (kind VD_KIND_CPACK). Open, feed the cells
 * in increasing cell order (each split into segments and encoded on up to
 * `threads` threads), commit. The file appears under `path` only on
 * commit; the big arrays are streamed (one spooled beside the file), so
 * memory holds a few segments, not the array. */
struct vd_cpack_params {
	int method;                 /* enum vd_cpack_method */
	struct vd_vbr_params vbr;
	struct vd_auto_params autop;/* VD_CPACK_AUTO */
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
	uint64_t mode_blocks[VD_AUTO_MODES]; /* auto: blocks per mode (enum vd_auto_mode >> 4) */
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
/* Colours of voxels idx[0 .. n) into rgb (3n bytes, rgb + 3q for
 * idx[q]): the same colours as vd_cpack_colour, in any order, duplicates
 * allowed. For the auto method many lookups are in flight at once (their
 * cache misses overlap), and a coded file's lookups are sorted so that
 * each block touched is decoded once: batches of a few hundred or more
 * pay, and the nearer the voxels (a frame's hits), the more. Every index
 * is checked first: VD_ERR_RANGE, with rgb untouched, when one is >=
 * voxels; VD_ERR_NOMEM (coded files allocate 16 bytes a lookup, at most
 * 2^20 at once). Thread-safe on one reader. */
int vd_cpack_colour_many(const struct vd_cpack *c, const uint64_t *idx,
			 size_t n, uint8_t *rgb);
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
	struct vd_auto_params autop; /* auto: max_error (0 lossless), block */
	uint32_t palette_colours; /* K */
	int lossless;
	int threads, quiet;
	const char *provenance;
};
int vd_colorize_run(const struct vd_colorize_job *job);

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
	/* optional: the colours of index[0 .. n) into rgb (3n bytes), as
	 * get() gives them one by one, but faster for many (a packed file's
	 * lookups overlap, vd_cpack_colour_many); NULL: get() is used.
	 * Called through vd_colour_source_get_many. */
	void (*get_many)(const struct vd_colour_source *s,
			 const uint64_t *index, size_t n, uint8_t *rgb);
};

/* The colours of index[0 .. n) (each < voxels) into rgb (3n bytes):
 * s->get_many, or s->get for each. Thread-safe like get(). */
void vd_colour_source_get_many(const struct vd_colour_source *s,
			       const uint64_t *index, size_t n, uint8_t *rgb);

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

#ifdef __cplusplus
}
#endif

#endif /* VD_COLOUR_H */
