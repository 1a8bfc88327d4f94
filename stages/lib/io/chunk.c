/* chunk.c - reading and writing chunk files (schemas/chunk-format.md).
 *
 * Fields are encoded one by one as little-endian; no struct is ever written
 * as it lies in memory. A writer streams zstd-compressed sections into a
 * temporary file, patches sizes and counts at the end, appends the footer
 * with the whole-file checksum and only then publishes the file (fsync,
 * rename, directory fsync: io/publish.c).
 */
#include "voxdag.h"
#include "util_internal.h"
#include "le.h"
#include "io/publish.h"

#include <errno.h>
#include <fcntl.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define XXH_INLINE_ALL
#include <xxhash.h>
#include <zstd.h>

static const uint8_t chunk_magic[8] = {0x89, 'V', 'X', 'D', '\r', '\n', 0x1a, '\n'};
static const uint8_t footer_magic[8] = {0x89, 'V', 'X', 'D', 'E', 'N', 'D', '\n'};

enum {
	HEADER_FIXED = 104,   /* bytes before the per-level counts */
	SECTION_HEADER = 32,
	FOOTER = 24,
	CODEC_STORED = 0,
	CODEC_ZSTD = 1,
	CODEC_ZSTD_PLANES4 = 2, /* zstd frames of 4 byte planes */
	/* Header sizes beyond this are corrupt, not a future extension. */
	HEADER_MAX = 4096,
};

const char *vd_chunk_kind_name(uint32_t kind)
{
	static const char *const names[] = {"any", "svo", "dag", "ssvdag",
					    "encoded", "colours", "cpack",
					    "ssvdag48"};
	return kind < VD_KIND_COUNT_ ? names[kind] : "unknown";
}

static size_t header_size(uint32_t level_count)
{
	return HEADER_FIXED + 8 * (size_t)level_count + 8;
}

/* Encodes `h` with `section_count` into buf (header_size() bytes) and its
 * checksum. */
static void encode_header(uint8_t *buf, const struct vd_chunk_header *h,
			  uint32_t section_count)
{
	size_t n = header_size(h->level_count);
	memset(buf, 0, n);
	memcpy(buf, chunk_magic, 8);
	le_put16(buf + 8, VD_CHUNK_MAJOR);
	le_put16(buf + 10, VD_CHUNK_MINOR);
	le_put32(buf + 12, (uint32_t)n);
	le_put32(buf + 16, h->kind);
	le_put32(buf + 20, h->levels);
	le_put32(buf + 24, h->chunk_level);
	le_put32(buf + 28, h->level_count);
	le_put64(buf + 32, h->cell_morton);
	for (int a = 0; a < 3; a++)
		le_putf64(buf + 40 + 8 * a, h->transform.origin[a]);
	le_putf64(buf + 64, h->transform.voxel_size);
	for (int a = 0; a < 3; a++) {
		le_putf32(buf + 72 + 4 * a, h->transform.bbox_min[a]);
		le_putf32(buf + 84 + 4 * a, h->transform.bbox_max[a]);
	}
	le_putf32(buf + 96, h->transform.root_side);
	le_put32(buf + 100, section_count);
	for (uint32_t i = 0; i < h->level_count; i++)
		le_put64(buf + HEADER_FIXED + 8 * i, h->level_nodes[i]);
	le_put64(buf + n - 8, XXH3_64bits(buf, n - 8));
}

/* ---------------------------------------------------------------- writer */

struct vd_chunk_writer {
	struct vd_atomic a; /* the file, under its temporary name */
	struct vd_chunk_header h;
	uint32_t section_count;
	/* the open section */
	int in_section;
	off_t section_pos;
	uint64_t raw_size, stored_size;
	uint32_t tag, codec;
	XXH3_state_t *hash;
	ZSTD_CCtx *zc;
	uint8_t *zbuf;
	size_t zbuf_cap;
	int failed;
};

static int writer_io_error(struct vd_chunk_writer *w, const char *what)
{
	w->failed = 1;
	return vd_fail(VD_ERR_IO, "%s '%s': %s", what, w->a.tmp, strerror(errno));
}

static int write_all(struct vd_chunk_writer *w, const void *p, size_t n)
{
	if (n && fwrite(p, 1, n, w->a.f) != n)
		return writer_io_error(w, "cannot write");
	return VD_OK;
}

int vd_chunk_writer_open(struct vd_chunk_writer **out, const char *path,
			 const struct vd_chunk_header *h,
			 const char *provenance)
{
	*out = NULL;
	if (h->level_count > VD_MAX_LEVELS + 1 || h->kind == VD_KIND_ANY ||
	    h->kind >= VD_KIND_COUNT_)
		return vd_fail(VD_ERR_ARG, "bad chunk header for '%s'", path);
	struct vd_chunk_writer *w = calloc(1, sizeof *w);
	if (!w)
		return vd_fail(VD_ERR_NOMEM, "chunk writer");
	w->h = *h;
	w->hash = XXH3_createState();
	if (!w->hash) {
		vd_chunk_writer_abort(w);
		return vd_fail(VD_ERR_NOMEM, "chunk writer");
	}
	int err = vd_atomic_open(&w->a, path);
	if (err) {
		vd_chunk_writer_abort(w);
		return err;
	}
	uint8_t buf[HEADER_MAX];
	encode_header(buf, &w->h, 0);
	err = write_all(w, buf, header_size(w->h.level_count));
	if (!err && provenance) {
		err = vd_chunk_writer_begin(w, VD_TAG_PROV, -1);
		if (!err)
			err = vd_chunk_writer_write(w, provenance,
						    strlen(provenance));
		if (!err)
			err = vd_chunk_writer_end(w);
	}
	if (err) {
		vd_chunk_writer_abort(w);
		return err;
	}
	*out = w;
	return VD_OK;
}

/* The level of a section given level 0 (schemas/chunk-format.md, measured
 * by tests/bench/zstd_levels.c): SVO bricks are written once by voxelize
 * and read once by svo-to-dag, where level 1 compresses 1.3-2x and
 * decompresses 1.1-1.4x faster than 3 for 5-8% more bytes; the DAG
 * sections are kept, and read again, as the pipeline's results. */
static int default_level(uint32_t tag)
{
	return tag == VD_TAG_BRKS || tag == VD_TAG_DAGM || tag == VD_TAG_DAGC ||
	       tag == VD_TAG_DAGR ? 1 : 3;
}

/* zstd_level < 0 stores the section uncompressed (used for short text). */
int vd_chunk_writer_begin(struct vd_chunk_writer *w, uint32_t tag,
			  int zstd_level)
{
	if (w->failed || w->in_section)
		return vd_fail(VD_ERR_ARG, "section already open in '%s'", w->a.tmp);
	w->section_pos = ftello(w->a.f);
	uint8_t hdr[SECTION_HEADER] = {0};
	int err = write_all(w, hdr, sizeof hdr); /* patched in _end */
	if (err)
		return err;
	w->tag = tag;
	w->codec = zstd_level < 0 ? CODEC_STORED : CODEC_ZSTD;
	w->raw_size = w->stored_size = 0;
	XXH3_64bits_reset(w->hash);
	if (w->codec == CODEC_ZSTD) {
		if (!w->zc) {
			w->zc = ZSTD_createCCtx();
			w->zbuf_cap = ZSTD_CStreamOutSize();
			w->zbuf = malloc(w->zbuf_cap);
			if (!w->zc || !w->zbuf)
				return vd_fail(VD_ERR_NOMEM, "zstd context");
		}
		ZSTD_CCtx_reset(w->zc, ZSTD_reset_session_and_parameters);
		ZSTD_CCtx_setParameter(w->zc, ZSTD_c_compressionLevel,
				       zstd_level ? zstd_level : default_level(tag));
		ZSTD_CCtx_setParameter(w->zc, ZSTD_c_checksumFlag, 0);
	}
	w->in_section = 1;
	return VD_OK;
}

static int emit_stored(struct vd_chunk_writer *w, const void *p, size_t n)
{
	XXH3_64bits_update(w->hash, p, n);
	w->stored_size += n;
	return write_all(w, p, n);
}

static int zstd_pump(struct vd_chunk_writer *w, ZSTD_inBuffer *in,
		     ZSTD_EndDirective mode)
{
	for (;;) {
		ZSTD_outBuffer out = {w->zbuf, w->zbuf_cap, 0};
		size_t left = ZSTD_compressStream2(w->zc, &out, in, mode);
		if (ZSTD_isError(left)) {
			w->failed = 1;
			return vd_fail(VD_ERR_COMPRESS, "zstd: %s",
				       ZSTD_getErrorName(left));
		}
		int err = emit_stored(w, w->zbuf, out.pos);
		if (err)
			return err;
		if (mode == ZSTD_e_end ? left == 0 : in->pos == in->size)
			return VD_OK;
	}
}

int vd_chunk_writer_write(struct vd_chunk_writer *w, const void *data,
			  size_t n)
{
	if (w->failed || !w->in_section)
		return vd_fail(VD_ERR_ARG, "no open section in '%s'", w->a.tmp);
	w->raw_size += n;
	if (w->codec == CODEC_STORED)
		return emit_stored(w, data, n);
	ZSTD_inBuffer in = {data, n, 0};
	return zstd_pump(w, &in, ZSTD_e_continue);
}

int vd_chunk_writer_end(struct vd_chunk_writer *w)
{
	if (w->failed || !w->in_section)
		return vd_fail(VD_ERR_ARG, "no open section in '%s'", w->a.tmp);
	if (w->codec == CODEC_ZSTD) {
		ZSTD_inBuffer in = {NULL, 0, 0};
		int err = zstd_pump(w, &in, ZSTD_e_end);
		if (err)
			return err;
	}
	uint8_t hdr[SECTION_HEADER];
	le_put32(hdr, w->tag);
	le_put32(hdr + 4, w->codec);
	le_put64(hdr + 8, w->raw_size);
	le_put64(hdr + 16, w->stored_size);
	le_put64(hdr + 24, XXH3_64bits_digest(w->hash));
	off_t end = ftello(w->a.f);
	if (fseeko(w->a.f, w->section_pos, SEEK_SET) != 0 ||
	    fwrite(hdr, 1, sizeof hdr, w->a.f) != sizeof hdr ||
	    fseeko(w->a.f, end, SEEK_SET) != 0)
		return writer_io_error(w, "cannot write");
	w->in_section = 0;
	w->section_count++;
	return VD_OK;
}

int vd_chunk_writer_section(struct vd_chunk_writer *w, uint32_t tag,
			    const void *data, size_t n)
{
	int err = vd_chunk_writer_begin(w, tag, 0);
	if (!err)
		err = vd_chunk_writer_write(w, data, n);
	if (!err)
		err = vd_chunk_writer_end(w);
	return err;
}

int vd_chunk_writer_set_counts(struct vd_chunk_writer *w,
			       const uint64_t *level_nodes,
			       uint32_t level_count)
{
	if (level_count != w->h.level_count)
		return vd_fail(VD_ERR_ARG, "level count %u, header has %u",
			       level_count, w->h.level_count);
	memcpy(w->h.level_nodes, level_nodes, 8 * (size_t)level_count);
	return VD_OK;
}

/* Codec 2: the n bytes (4-byte elements) of a frame as 4 planes, byte p
 * of element i at p * n/4 + i, and back. */
static void planes4(uint8_t *dst, const uint8_t *src, size_t n)
{
	size_t k = n / 4;
	for (size_t i = 0; i < k; i++) {
		dst[i] = src[4 * i];
		dst[k + i] = src[4 * i + 1];
		dst[2 * k + i] = src[4 * i + 2];
		dst[3 * k + i] = src[4 * i + 3];
	}
}

static void unplanes4(uint8_t *dst, const uint8_t *src, size_t n)
{
	size_t k = n / 4;
	for (size_t i = 0; i < k; i++) {
		dst[4 * i] = src[i];
		dst[4 * i + 1] = src[k + i];
		dst[4 * i + 2] = src[2 * k + i];
		dst[4 * i + 3] = src[3 * k + i];
	}
}

/* A framed section: frames of VD_CHUNK_FRAME_BYTES raw bytes (the last one
 * shorter), each its own zstd frame with its content size, so readers can
 * decompress them in parallel. The frame size is fixed, not derived from
 * the thread count: the bytes are the same with any number of threads. */
struct frame_job {
	void (*fill)(void *ctx, uint64_t offset, uint8_t *buf, size_t n);
	void *ctx;
	uint64_t raw_size, first; /* frame index of out[0] */
	int level;
	int planes;               /* codec 2: 4 byte planes a frame */
	uint8_t **raw;            /* per worker, VD_CHUNK_FRAME_BYTES (twice
				     with planes: raw, then its planes) */
	ZSTD_CCtx **zc;           /* per worker */
	uint8_t **out;            /* per frame of the batch */
	size_t *out_size, out_cap;
	int *errs;
	int nworkers;
};

static void frame_worker(void *ctx, size_t i, int worker)
{
	struct frame_job *fj = ctx;
	if (worker < 0 || worker >= fj->nworkers) {
		fj->errs[i] = VD_ERR_INTERNAL;
		return;
	}
	uint64_t off = (fj->first + i) * (uint64_t)VD_CHUNK_FRAME_BYTES;
	size_t n = fj->raw_size - off < VD_CHUNK_FRAME_BYTES ?
		   (size_t)(fj->raw_size - off) : VD_CHUNK_FRAME_BYTES;
	if (!fj->raw[worker])
		fj->raw[worker] = malloc((fj->planes ? 2 : 1) *
					 (size_t)VD_CHUNK_FRAME_BYTES);
	if (!fj->zc[worker])
		fj->zc[worker] = ZSTD_createCCtx();
	if (!fj->raw[worker] || !fj->zc[worker]) {
		fj->errs[i] = VD_ERR_NOMEM;
		return;
	}
	uint8_t *in = fj->raw[worker];
	fj->fill(fj->ctx, off, in, n);
	if (fj->planes) {
		planes4(in + VD_CHUNK_FRAME_BYTES, in, n);
		in += VD_CHUNK_FRAME_BYTES;
	}
	size_t r = ZSTD_compressCCtx(fj->zc[worker], fj->out[i], fj->out_cap,
				     in, n, fj->level);
	if (ZSTD_isError(r)) {
		fj->errs[i] = VD_ERR_COMPRESS;
		return;
	}
	fj->out_size[i] = r;
}

int vd_chunk_writer_frames(struct vd_chunk_writer *w, uint32_t tag,
			   uint64_t raw_size,
			   void (*fill)(void *ctx, uint64_t offset,
					uint8_t *buf, size_t n),
			   void *ctx, int threads, int planes)
{
	if (w->failed || w->in_section)
		return vd_fail(VD_ERR_ARG, "section already open in '%s'", w->a.tmp);
	if (planes && raw_size % 4)
		return vd_fail(VD_ERR_ARG, "section '%.4s' of %llu bytes is not "
			       "4-byte elements", (const char *)&tag,
			       (unsigned long long)raw_size);
	if (threads < 1)
		threads = vd_hardware_threads();
	/* frames in flight: a few per thread keeps the threads busy to the
	 * end of a batch while bounding the memory */
	size_t batch = 2 * (size_t)threads;
	uint64_t nframes = (raw_size + VD_CHUNK_FRAME_BYTES - 1) /
			   VD_CHUNK_FRAME_BYTES;
	int nw = threads + 1; /* TBB's worker index: 0..threads-1 */
	struct frame_job fj = {fill, ctx, raw_size, 0, default_level(tag),
			       planes, calloc((size_t)nw, sizeof(uint8_t *)),
			       calloc((size_t)nw, sizeof(ZSTD_CCtx *)),
			       calloc(batch, sizeof(uint8_t *)),
			       calloc(batch, sizeof(size_t)),
			       ZSTD_compressBound(VD_CHUNK_FRAME_BYTES),
			       calloc(batch, sizeof(int)), nw};
	int err = !fj.raw || !fj.zc || !fj.out || !fj.out_size || !fj.errs ?
		  vd_fail(VD_ERR_NOMEM, "section '%.4s'", (const char *)&tag) : VD_OK;
	for (size_t i = 0; i < batch && !err; i++)
		if (!(fj.out[i] = malloc(fj.out_cap)))
			err = vd_fail(VD_ERR_NOMEM, "section '%.4s'",
				      (const char *)&tag);
	/* the header first, patched with the sizes and checksum at the end */
	off_t pos = err ? 0 : ftello(w->a.f);
	uint8_t hdr[SECTION_HEADER] = {0};
	if (!err)
		err = write_all(w, hdr, sizeof hdr);
	uint64_t stored = 0;
	XXH3_64bits_reset(w->hash);
	for (uint64_t f = 0; f < nframes && !err; f += batch) {
		size_t nb = nframes - f < batch ? (size_t)(nframes - f) : batch;
		fj.first = f;
		memset(fj.errs, 0, batch * sizeof *fj.errs);
		err = vd_parallel_for(nb, threads, frame_worker, &fj);
		for (size_t i = 0; i < nb && !err; i++)
			if (fj.errs[i])
				err = vd_fail(fj.errs[i], "cannot compress "
					      "section '%.4s'", (const char *)&tag);
		for (size_t i = 0; i < nb && !err; i++) {
			XXH3_64bits_update(w->hash, fj.out[i], fj.out_size[i]);
			stored += fj.out_size[i];
			err = write_all(w, fj.out[i], fj.out_size[i]);
		}
	}
	if (!err) {
		le_put32(hdr, tag);
		le_put32(hdr + 4, planes ? CODEC_ZSTD_PLANES4 : CODEC_ZSTD);
		le_put64(hdr + 8, raw_size);
		le_put64(hdr + 16, stored);
		le_put64(hdr + 24, XXH3_64bits_digest(w->hash));
		off_t end = ftello(w->a.f);
		if (fseeko(w->a.f, pos, SEEK_SET) != 0 ||
		    fwrite(hdr, 1, sizeof hdr, w->a.f) != sizeof hdr ||
		    fseeko(w->a.f, end, SEEK_SET) != 0)
			err = writer_io_error(w, "cannot write");
		else
			w->section_count++;
	}
	if (err)
		w->failed = 1;
	for (int i = 0; i < nw && fj.raw; i++)
		free(fj.raw[i]);
	for (int i = 0; i < nw && fj.zc; i++)
		ZSTD_freeCCtx(fj.zc[i]);
	for (size_t i = 0; i < batch && fj.out; i++)
		free(fj.out[i]);
	free(fj.raw);
	free(fj.zc);
	free(fj.out);
	free(fj.out_size);
	free(fj.errs);
	return err;
}

int vd_chunk_writer_commit(struct vd_chunk_writer *w)
{
	int err = VD_OK;
	if (w->failed || w->in_section)
		err = vd_fail(VD_ERR_ARG, "cannot commit '%s': %s", w->a.path,
			      w->in_section ? "a section is open"
					    : "an earlier write failed");
	uint8_t buf[HEADER_MAX];
	if (!err) {
		encode_header(buf, &w->h, w->section_count);
		if (fseeko(w->a.f, 0, SEEK_SET) != 0 ||
		    fwrite(buf, 1, header_size(w->h.level_count), w->a.f) !=
			    header_size(w->h.level_count) ||
		    fflush(w->a.f) != 0)
			err = writer_io_error(w, "cannot write");
	}
	/* The whole-file checksum is taken from the bytes as they are on disk
	 * (after patching), read back through the page cache. */
	uint64_t size = 0;
	if (!err) {
		XXH3_64bits_reset(w->hash);
		if (fseeko(w->a.f, 0, SEEK_SET) != 0)
			err = writer_io_error(w, "cannot seek");
		size_t n;
		while (!err && (n = fread(buf, 1, sizeof buf, w->a.f)) > 0) {
			XXH3_64bits_update(w->hash, buf, n);
			size += n;
		}
		if (!err && ferror(w->a.f))
			err = writer_io_error(w, "cannot read back");
	}
	if (!err) {
		uint8_t foot[FOOTER];
		memcpy(foot, footer_magic, 8);
		le_put64(foot + 8, size + FOOTER);
		XXH3_64bits_update(w->hash, foot, 16);
		le_put64(foot + 16, XXH3_64bits_digest(w->hash));
		if (fseeko(w->a.f, 0, SEEK_END) != 0 ||
		    fwrite(foot, 1, FOOTER, w->a.f) != FOOTER ||
		    fflush(w->a.f) != 0)
			err = writer_io_error(w, "cannot write");
	}
	/* fsync, rename, fsync of the directory; the struct is then empty,
	 * so abort below only frees the writer */
	if (!err)
		err = vd_atomic_commit(&w->a);
	vd_chunk_writer_abort(w);
	return err;
}

void vd_chunk_writer_abort(struct vd_chunk_writer *w)
{
	if (!w)
		return;
	vd_atomic_abort(&w->a);
	XXH3_freeState(w->hash);
	ZSTD_freeCCtx(w->zc);
	free(w->zbuf);
	free(w);
}

/* ---------------------------------------------------------------- reader */

struct section {
	uint32_t tag, codec;
	uint64_t raw_size, stored_size;
	size_t offset; /* of the stored bytes in the image */
};

struct vd_chunk {
	struct vd_chunk_header h;
	uint8_t *image;
	size_t size;
	uint32_t section_count;
	struct section *sections;
	char *provenance;
};

/* Walks the sections after the header. Returns the footer position, or an
 * error: TRUNCATED if the structure runs past `len`. */
static int walk_sections(struct vd_chunk *c, size_t hsize, uint32_t count,
			 size_t len, size_t *footer_pos)
{
	size_t p = hsize;
	for (uint32_t i = 0; i < count; i++) {
		if (len - p < SECTION_HEADER)
			return vd_fail(VD_ERR_TRUNCATED, "file ends in the header "
				       "of section %u of %u", i + 1, count);
		const uint8_t *s = c->image + p;
		struct section *sec = &c->sections[i];
		sec->tag = le_get32(s);
		sec->codec = le_get32(s + 4);
		sec->raw_size = le_get64(s + 8);
		sec->stored_size = le_get64(s + 16);
		sec->offset = p + SECTION_HEADER;
		if (sec->stored_size > len - sec->offset)
			return vd_fail(VD_ERR_TRUNCATED, "file ends inside section "
				       "%u of %u (%llu bytes missing)", i + 1,
				       count,
				       (unsigned long long)(sec->stored_size -
							    (len - sec->offset)));
		p = sec->offset + sec->stored_size;
	}
	*footer_pos = p;
	return VD_OK;
}

static int has_footer_at(const struct vd_chunk *c, size_t p)
{
	return c->size - p >= FOOTER &&
	       memcmp(c->image + p, footer_magic, 8) == 0 &&
	       le_get64(c->image + p + 8) == p + FOOTER;
}

/* Checks and decodes the header in the first `len` bytes of `b`. */
static int parse_header(const uint8_t *b, size_t len,
			struct vd_chunk_header *h, uint32_t *hsize_out,
			uint32_t want_kind)
{
	if (len < 8) {
		if (len > 0 && memcmp(b, chunk_magic, len) == 0)
			return vd_fail(VD_ERR_TRUNCATED, "only %zu bytes", len);
		return vd_fail(VD_ERR_NOT_CHUNK, "no chunk magic number");
	}
	if (memcmp(b, chunk_magic, 8) != 0)
		return vd_fail(VD_ERR_NOT_CHUNK, "no chunk magic number");
	if (len < 12)
		return vd_fail(VD_ERR_TRUNCATED, "file ends in the header");
	uint16_t major = le_get16(b + 8), minor = le_get16(b + 10);
	if (major > VD_CHUNK_MAJOR)
		return vd_fail(VD_ERR_NEWER_VERSION, "format %u.%u, this voxdag "
			       "reads up to %u.x; upgrade voxdag", major, minor,
			       VD_CHUNK_MAJOR);
	if (major == 0)
		return vd_fail(VD_ERR_CORRUPT, "format major version 0");
	if (len < HEADER_FIXED + 8)
		return vd_fail(VD_ERR_TRUNCATED, "file ends in the header");
	uint32_t hsize = le_get32(b + 12), level_count = le_get32(b + 28);
	if (hsize > HEADER_MAX || level_count > VD_MAX_LEVELS + 1 ||
	    hsize < header_size(level_count)) {
		/* These fields are under the header checksum: a mismatch says
		 * corruption better than a size complaint would. */
		if (hsize <= len && hsize >= 16 &&
		    XXH3_64bits(b, hsize - 8) != le_get64(b + hsize - 8))
			return vd_fail(VD_ERR_CHECKSUM, "header checksum");
		return vd_fail(VD_ERR_CORRUPT, "header size %u for %u levels",
			       hsize, level_count);
	}
	if (len < hsize)
		return vd_fail(VD_ERR_TRUNCATED, "file ends in the header");
	if (XXH3_64bits(b, hsize - 8) != le_get64(b + hsize - 8))
		return vd_fail(VD_ERR_CHECKSUM, "header checksum");

	h->major = major;
	h->minor = minor;
	h->kind = le_get32(b + 16);
	h->levels = le_get32(b + 20);
	h->chunk_level = le_get32(b + 24);
	h->level_count = level_count;
	h->cell_morton = le_get64(b + 32);
	for (int a = 0; a < 3; a++) {
		h->transform.origin[a] = le_getf64(b + 40 + 8 * a);
		h->transform.bbox_min[a] = le_getf32(b + 72 + 4 * a);
		h->transform.bbox_max[a] = le_getf32(b + 84 + 4 * a);
	}
	h->transform.voxel_size = le_getf64(b + 64);
	h->transform.root_side = le_getf32(b + 96);
	for (uint32_t i = 0; i < level_count; i++)
		h->level_nodes[i] = le_get64(b + HEADER_FIXED + 8 * i);
	if (want_kind != VD_KIND_ANY && h->kind != want_kind)
		return vd_fail(VD_ERR_WRONG_KIND, "a %s chunk, expected %s",
			       vd_chunk_kind_name(h->kind),
			       vd_chunk_kind_name(want_kind));
	if (h->levels < 1 || h->levels > VD_MAX_LEVELS ||
	    h->chunk_level > h->levels)
		return vd_fail(VD_ERR_CORRUPT, "levels %u, chunk level %u",
			       h->levels, h->chunk_level);
	*hsize_out = hsize;
	return VD_OK;
}

int vd_chunk_read_header(const char *path, struct vd_chunk_header *h)
{
	/* no stdio: the runner reads the header of every cell it plans */
	uint8_t buf[HEADER_MAX];
	int fd = vd_open_read(path);
	if (fd < 0)
		return vd_fail(VD_ERR_IO, "%s", strerror(errno));
	size_t n = 0;
	while (n < sizeof buf) {
		ssize_t r = read(fd, buf + n, sizeof buf - n);
		if (r < 0 && errno == EINTR)
			continue;
		if (r <= 0)
			break; /* an error reads as a short header */
		n += (size_t)r;
	}
	close(fd);
	uint32_t hsize;
	return parse_header(buf, n, h, &hsize, VD_KIND_ANY);
}

static int parse(struct vd_chunk *c, uint32_t want_kind)
{
	const uint8_t *b = c->image;
	size_t len = c->size;
	uint32_t hsize;
	int herr = parse_header(b, len, &c->h, &hsize, want_kind);
	if (herr)
		return herr;

	uint32_t count = le_get32(b + 100);
	/* The count is under the header checksum, so more sections than the
	 * rest of the file can hold means bytes are missing. */
	if (count > (len - hsize) / SECTION_HEADER)
		return vd_fail(VD_ERR_TRUNCATED, "%u sections cannot fit in "
			       "the %zu bytes after the header", count,
			       len - hsize);
	c->sections = calloc(count ? count : 1, sizeof *c->sections);
	if (!c->sections)
		return vd_fail(VD_ERR_NOMEM, "%u sections", count);
	c->section_count = count;

	/* A complete file ends with a footer that states its size; then the
	 * whole-file checksum decides. Otherwise the structure tells whether
	 * bytes are missing or extra. */
	size_t fpos;
	if (len >= hsize + FOOTER && has_footer_at(c, len - FOOTER)) {
		uint64_t sum = XXH3_64bits(b, len - 8);
		if (sum != le_get64(b + len - 8))
			return vd_fail(VD_ERR_CHECKSUM, "whole-file checksum");
		int err = walk_sections(c, hsize, count, len - FOOTER, &fpos);
		if (err || fpos != len - FOOTER)
			return vd_fail(VD_ERR_CORRUPT, "sections do not fill "
				       "the file");
	} else {
		int err = walk_sections(c, hsize, count, len, &fpos);
		if (err)
			return err;
		if (len - fpos < FOOTER)
			return vd_fail(VD_ERR_TRUNCATED, "file ends before "
				       "its footer");
		if (has_footer_at(c, fpos))
			return vd_fail(VD_ERR_TRAILING, "%zu bytes after the "
				       "footer", len - fpos - FOOTER);
		return vd_fail(VD_ERR_CORRUPT, "no footer where the sections "
			       "end");
	}
	for (uint32_t i = 0; i < count; i++) {
		const struct section *s = &c->sections[i];
		uint64_t want = le_get64(b + s->offset - 8);
		if (XXH3_64bits(b + s->offset, s->stored_size) != want)
			return vd_fail(VD_ERR_CHECKSUM, "section %u", i + 1);
		if (s->codec > CODEC_ZSTD_PLANES4)
			return vd_fail(VD_ERR_UNSUPPORTED, "section %u has "
				       "codec %u", i + 1, s->codec);
		if (s->codec == CODEC_ZSTD_PLANES4 && s->raw_size % 4)
			return vd_fail(VD_ERR_CORRUPT, "section %u: codec 2 "
				       "of %llu bytes", i + 1,
				       (unsigned long long)s->raw_size);
		if (s->codec == CODEC_STORED && s->raw_size != s->stored_size)
			return vd_fail(VD_ERR_CORRUPT, "section %u sizes", i + 1);
	}
	if (vd_chunk_has_section(c, VD_TAG_PROV)) {
		void *text;
		size_t n;
		int err = vd_chunk_read_section(c, VD_TAG_PROV, &text, &n);
		if (err)
			return err;
		c->provenance = realloc(text, n + 1);
		if (!c->provenance) {
			free(text);
			return vd_fail(VD_ERR_NOMEM, "provenance");
		}
		c->provenance[n] = 0;
	}
	return VD_OK;
}

int vd_chunk_open_mem(struct vd_chunk **out, const void *data, size_t size,
		      uint32_t kind)
{
	*out = NULL;
	struct vd_chunk *c = calloc(1, sizeof *c);
	if (!c || !(c->image = malloc(size ? size : 1))) {
		free(c);
		return vd_fail(VD_ERR_NOMEM, "%zu bytes", size);
	}
	memcpy(c->image, data, size);
	c->size = size;
	int err = parse(c, kind);
	if (err) {
		vd_chunk_free(c);
		return err;
	}
	*out = c;
	return VD_OK;
}

int vd_chunk_open(struct vd_chunk **out, const char *path, uint32_t kind)
{
	*out = NULL;
	int fd = open(path, O_RDONLY);
	if (fd < 0)
		return vd_fail(VD_ERR_IO, "%s", strerror(errno));
	struct stat st;
	if (fstat(fd, &st) != 0) {
		int e = errno;
		close(fd);
		return vd_fail(VD_ERR_IO, "cannot stat: %s", strerror(e));
	}
	if (!S_ISREG(st.st_mode)) {
		close(fd);
		return vd_fail(VD_ERR_IO, "%s", S_ISDIR(st.st_mode) ?
			       "is a directory" : "not a regular file");
	}
	struct vd_chunk *c = calloc(1, sizeof *c);
	size_t size = (size_t)st.st_size;
	if (!c || !(c->image = malloc(size ? size : 1))) {
		free(c);
		close(fd);
		return vd_fail(VD_ERR_NOMEM, "%zu bytes", size);
	}
	size_t got = 0;
	while (got < size) {
		ssize_t r = read(fd, c->image + got, size - got);
		if (r < 0 && errno == EINTR)
			continue;
		if (r <= 0) {
			int e = errno;
			close(fd);
			vd_chunk_free(c);
			return vd_fail(VD_ERR_IO, "%s", r ? strerror(e) :
				       "file shrank while reading");
		}
		got += (size_t)r;
	}
	close(fd);
	c->size = size;
	int err = parse(c, kind);
	if (err) {
		vd_chunk_free(c);
		return err;
	}
	*out = c;
	return VD_OK;
}

const struct vd_chunk_header *vd_chunk_header(const struct vd_chunk *c)
{
	return &c->h;
}

static const struct section *find_section(const struct vd_chunk *c,
					  uint32_t tag)
{
	for (uint32_t i = 0; i < c->section_count; i++)
		if (c->sections[i].tag == tag)
			return &c->sections[i];
	return NULL;
}

int vd_chunk_has_section(const struct vd_chunk *c, uint32_t tag)
{
	return find_section(c, tag) != NULL;
}

/* The frames of a zstd section when it has several, each declaring its
 * content size (as vd_chunk_writer_frames writes them) and together
 * exactly raw_size: then they decompress in parallel. Returns the count, 0
 * for "decompress it whole" (one frame, or sizes not declared: the serial
 * path then checks everything). */
struct dframe {
	size_t src, src_size, dst, dst_size;
};

static size_t list_frames(const uint8_t *p, size_t n, uint64_t raw_size,
			  struct dframe **out)
{
	*out = NULL;
	size_t cap = 0, count = 0, src = 0;
	uint64_t dst = 0;
	while (src < n) {
		size_t fs = ZSTD_findFrameCompressedSize(p + src, n - src);
		if (ZSTD_isError(fs))
			break;
		unsigned long long cs = ZSTD_getFrameContentSize(p + src, fs);
		if (cs == ZSTD_CONTENTSIZE_ERROR ||
		    cs == ZSTD_CONTENTSIZE_UNKNOWN || cs > raw_size - dst)
			break;
		if (count == cap) {
			cap = cap ? 2 * cap : 16;
			struct dframe *q = realloc(*out, cap * sizeof *q);
			if (!q)
				break;
			*out = q;
		}
		(*out)[count++] = (struct dframe){src, fs, (size_t)dst, (size_t)cs};
		src += fs;
		dst += cs;
	}
	if (src != n || dst != raw_size || count < 2) {
		free(*out);
		*out = NULL;
		return 0;
	}
	return count;
}

struct dframe_job {
	const uint8_t *src;
	uint8_t *dst;
	const struct dframe *f;
	int *bad;
};

static void dframe_worker(void *ctx, size_t i, int worker)
{
	(void)worker;
	struct dframe_job *j = ctx;
	const struct dframe *f = &j->f[i];
	size_t r = ZSTD_decompress(j->dst + f->dst, f->dst_size,
				   j->src + f->src, f->src_size);
	j->bad[i] = ZSTD_isError(r) || r != f->dst_size;
}

/* Codec 2 frames, each decompressed into its worker's scratch frame and
 * put back from its planes into place. */
struct pframe_job {
	const uint8_t *src;
	uint8_t *dst;
	const struct dframe *f;
	int *bad;
	uint8_t **scratch; /* per worker */
	int nworkers;
};

static void pframe_worker(void *ctx, size_t i, int worker)
{
	struct pframe_job *j = ctx;
	const struct dframe *f = &j->f[i];
	j->bad[i] = 1;
	if (worker < 0 || worker >= j->nworkers)
		return;
	if (!j->scratch[worker] &&
	    !(j->scratch[worker] = malloc(VD_CHUNK_FRAME_BYTES)))
		return;
	size_t r = ZSTD_decompress(j->scratch[worker], f->dst_size,
				   j->src + f->src, f->src_size);
	if (ZSTD_isError(r) || r != f->dst_size)
		return;
	unplanes4(j->dst + f->dst, j->scratch[worker], f->dst_size);
	j->bad[i] = 0;
}

/* Section s of codec 2 into buf (raw_size bytes). The frames written by
 * vd_chunk_writer_frames with planes are each one plane group: decompressed in
 * parallel through a frame of scratch each. Any other framing (one frame,
 * for a section of one group) goes through a copy of the whole. */
static int read_planes(const struct vd_chunk *c, const struct section *s,
		       uint8_t *buf, int threads)
{
	const uint8_t *src = c->image + s->offset;
	uint64_t raw = s->raw_size;
	struct dframe *fr = NULL;
	size_t nf = list_frames(src, s->stored_size, raw, &fr);
	for (size_t i = 0; i < nf; i++) {
		uint64_t at = (uint64_t)i * VD_CHUNK_FRAME_BYTES;
		if (fr[i].dst != at || fr[i].dst_size != (raw - at <
		    VD_CHUNK_FRAME_BYTES ? raw - at : VD_CHUNK_FRAME_BYTES)) {
			nf = 0;
			break;
		}
	}
	int err = VD_OK;
	if (nf) {
		int nw = threads + 1; /* TBB's worker index: 0..threads-1 */
		int *bad = calloc(nf, sizeof *bad);
		uint8_t **scratch = calloc((size_t)nw, sizeof *scratch);
		if (!bad || !scratch) {
			err = vd_fail(VD_ERR_NOMEM, "section '%.4s'",
				      (const char *)&s->tag);
		} else {
			struct pframe_job j = {src, buf, fr, bad, scratch, nw};
			err = vd_parallel_for(nf, threads, pframe_worker, &j);
			for (size_t i = 0; i < nf && !err; i++)
				if (bad[i])
					err = vd_fail(VD_ERR_CORRUPT, "section "
						      "'%.4s' frame %zu does "
						      "not decompress to its "
						      "size", (const char *)&s->tag,
						      i + 1);
		}
		for (int i = 0; scratch && i < nw; i++)
			free(scratch[i]);
		free(scratch);
		free(bad);
		free(fr);
		return err;
	}
	free(fr);
	uint8_t *tmp = malloc(raw ? (size_t)raw : 1);
	if (!tmp)
		return vd_fail(VD_ERR_NOMEM, "section '%.4s' of %llu bytes",
			       (const char *)&s->tag, (unsigned long long)raw);
	size_t n = ZSTD_decompress(tmp, (size_t)raw, src, s->stored_size);
	if (ZSTD_isError(n) || n != raw) {
		err = vd_fail(VD_ERR_CORRUPT, "section '%.4s' does not "
			      "decompress to its size: %s", (const char *)&s->tag,
			      ZSTD_isError(n) ? ZSTD_getErrorName(n)
					      : "size differs");
	} else {
		for (uint64_t at = 0; at < raw; at += VD_CHUNK_FRAME_BYTES)
			unplanes4(buf + at, tmp + at, raw - at < VD_CHUNK_FRAME_BYTES
				  ? (size_t)(raw - at) : VD_CHUNK_FRAME_BYTES);
	}
	free(tmp);
	return err;
}

int vd_chunk_read_section(const struct vd_chunk *c, uint32_t tag,
			  void **data, size_t *size)
{
	return vd_chunk_read_section_mt(c, tag, data, size, 1);
}

int vd_chunk_read_section_mt(const struct vd_chunk *c, uint32_t tag,
			     void **data, size_t *size, int threads)
{
	*data = NULL;
	*size = 0;
	const struct section *s = find_section(c, tag);
	if (!s)
		return vd_fail(VD_ERR_CORRUPT, "no '%.4s' section",
			       (const char *)&tag);
	if (s->raw_size > SIZE_MAX - 1)
		return vd_fail(VD_ERR_CORRUPT, "section size");
	uint8_t *buf = malloc(s->raw_size ? s->raw_size : 1);
	if (!buf)
		return vd_fail(VD_ERR_NOMEM, "section '%.4s' of %llu bytes",
			       (const char *)&tag,
			       (unsigned long long)s->raw_size);
	if (threads < 1)
		threads = vd_hardware_threads();
	if (s->codec == CODEC_STORED) {
		memcpy(buf, c->image + s->offset, s->raw_size);
	} else if (s->codec == CODEC_ZSTD_PLANES4) {
		int err = read_planes(c, s, buf, threads);
		if (err) {
			free(buf);
			return err;
		}
	} else {
		struct dframe *fr = NULL;
		size_t nf = threads > 1 ? list_frames(c->image + s->offset,
						      s->stored_size,
						      s->raw_size, &fr) : 0;
		int *bad = nf ? calloc(nf, sizeof *bad) : NULL;
		if (nf && bad) {
			struct dframe_job j = {c->image + s->offset, buf, fr, bad};
			int err = vd_parallel_for(nf, threads, dframe_worker, &j);
			for (size_t i = 0; i < nf && !err; i++)
				if (bad[i])
					err = vd_fail(VD_ERR_CORRUPT, "section "
						      "'%.4s' frame %zu does "
						      "not decompress to its "
						      "size", (const char *)&tag,
						      i + 1);
			free(fr);
			free(bad);
			if (err) {
				free(buf);
				return err;
			}
			*data = buf;
			*size = s->raw_size;
			return VD_OK;
		}
		free(fr);
		free(bad);
		size_t n = ZSTD_decompress(buf, s->raw_size, c->image + s->offset,
					   s->stored_size);
		if (ZSTD_isError(n) || n != s->raw_size) {
			free(buf);
			return vd_fail(VD_ERR_CORRUPT, "section '%.4s' does not "
				       "decompress to its size: %s",
				       (const char *)&tag,
				       ZSTD_isError(n) ? ZSTD_getErrorName(n)
						       : "size differs");
		}
	}
	*data = buf;
	*size = s->raw_size;
	return VD_OK;
}

const char *vd_chunk_provenance(const struct vd_chunk *c)
{
	return c->provenance ? c->provenance : "";
}

uint32_t vd_chunk_section_count(const struct vd_chunk *c)
{
	return c->section_count;
}

uint32_t vd_chunk_section_tag(const struct vd_chunk *c, uint32_t i)
{
	return i < c->section_count ? c->sections[i].tag : 0;
}

void vd_chunk_free(struct vd_chunk *c)
{
	if (!c)
		return;
	free(c->image);
	free(c->sections);
	free(c->provenance);
	free(c);
}
