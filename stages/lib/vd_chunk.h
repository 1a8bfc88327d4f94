/* vd_chunk.h - the files every stage reads and writes (io/): chunk files,
 * durable publishing of files and directories, directory manifests, spill
 * files and the statistics JSON.
 */
#ifndef VD_CHUNK_H
#define VD_CHUNK_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include "vd_common.h"

#ifdef __cplusplus
extern "C" {
#endif

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

/* Writes the footer and publishes the file (vd_atomic_commit: fsync,
 * rename to the final name, fsync of its directory). Frees `w` whatever
 * the outcome; on failure the temporary file is
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

/* ------------------------------------------------ publishing (io/publish.c)
 * Every file voxdag writes reaches its final name one way: written under
 * "<path>.tmp.<pid>" (a name manifests, the runner and vd_dir_stage take
 * for a temporary), then flushed, fsynced, closed, renamed onto `path`,
 * and the directory holding `path` fsynced, in that order. Until the
 * rename `path` is untouched (the old file, or none); once
 * vd_atomic_commit() returns VD_OK the new file survives a power cut.
 * Wherever these headers say a file is written "atomically" or "(atomic)",
 * it is written this way.
 *
 *     struct vd_atomic a;
 *     if ((err = vd_atomic_open(&a, path))) return err;
 *     fprintf(a.f, ...);
 *     return vd_atomic_commit(&a);   (or vd_atomic_abort(&a) to give up)
 */
struct vd_atomic {
	FILE *f;    /* the caller writes here (opened "w+b": it may read back) */
	char *path; /* the final name; owned by the struct */
	char *tmp;  /* "<path>.tmp.<pid>"; owned by the struct */
};

/* Creates a->tmp and opens a->f on it. VD_ERR_IO ("cannot create '<tmp>':
 * cause", errno kept) or VD_ERR_NOMEM; the struct is then empty and needs
 * no abort. On VD_OK the caller must end with exactly one of commit or
 * abort. A caller may write through fileno(a->f) instead of a->f, as long
 * as it does not mix the two. */
int vd_atomic_open(struct vd_atomic *a, const char *path);

/* Publishes the file: fflush, fsync, fclose, rename onto a->path,
 * fsync of a->path's directory. Refuses to rename over anything but a
 * regular file (run as root, a rename over /dev/null would replace the
 * device). On failure the temporary is removed, the old file stays (but
 * for a failed directory fsync: the new file is then in place, not known
 * durable), and VD_ERR_IO says why in one line ("cannot write '<tmp>': cause", "'<path>'
 * exists and is not a regular file; refusing to replace it", "cannot
 * rename ...", "cannot sync directory '<dir>': cause"); errno is the
 * cause (EISDIR or EEXIST for a refusal), for callers that word their own
 * message. A write error the caller met earlier (ferror) fails the commit
 * too. The struct is empty afterwards, whatever the result. */
int vd_atomic_commit(struct vd_atomic *a);

/* Closes and removes the temporary; the old file at a->path stays. Safe on
 * an empty struct (after open failed, or commit); keeps errno and the
 * error detail. */
void vd_atomic_abort(struct vd_atomic *a);

/* fsyncs directory `dir` (vd_fsync_parent: the directory holding `path`,
 * "." for a bare name, a trailing '/' ignored), so that names created,
 * renamed or removed in it survive a power cut; every rename of a file or
 * directory into its final place is followed by one (vd_atomic_commit,
 * vd_dir_swap). VD_ERR_IO "cannot sync directory '<dir>': cause"; a
 * directory the process may not open for reading (EACCES) or a file
 * system that cannot sync directories (EINVAL) is not an error, as in
 * PostgreSQL's fsync_fname. */
int vd_fsync_dir(const char *dir);
int vd_fsync_parent(const char *path);

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

/* The same, except that a listed file which is absent passes when
 * gone(ctx, dir, name) returns non-zero (the runner's `keep:` deletes
 * intermediates a job wrote once every job that reads them finished, and
 * remembers each one; the rest of the directory is still checked whole). */
int vd_manifest_verify_except(const char *dir, uint64_t *digest,
			      int (*gone)(void *ctx, const char *dir,
					  const char *name),
			      void *ctx);

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
 * in one step (renameat2 RENAME_EXCHANGE), fsyncs final's directory, then
 * removes the old output. */
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
 * they failed (the new directory is then under the staging name). Both
 * fsync final's directory after the rename (vd_fsync_parent); when that
 * fails, vd_dir_swap undoes the rename, so a failed swap changed nothing. */
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

/* ------------------------------------------------------- JSON statistics
 * A minimal writer for the statistics files beside every output. The file
 * appears under its name, durably, only when vd_json_close() succeeds. Keys are
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
/* Closes the top-level object and publishes the file (vd_atomic_commit:
 * fsync, rename, directory fsync); frees j. VD_ERR_INTERNAL, and no file,
 * when the objects and arrays were not closed in order (a writer's bug). */
int vd_json_close(struct vd_json *j);
/* Drops the statistics of a run that failed: removes the temporary file,
 * frees j (NULL is fine) and leaves the error detail as it was. */
void vd_json_abort(struct vd_json *j);

#ifdef __cplusplus
}
#endif

#endif /* VD_CHUNK_H */
