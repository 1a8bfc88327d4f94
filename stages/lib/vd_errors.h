/* vd_errors.h - error codes and the calling thread's error detail.
 *
 * Every library function that can fail returns an `int`: VD_OK (0) or one
 * of enum vd_error. vd_strerror() names the code; vd_error_detail() gives
 * the calling thread's one-line detail of the last failure ("line 12:
 * vertex index 900 out of range"), empty when there is none.
 */
#ifndef VD_ERRORS_H
#define VD_ERRORS_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#ifdef __cplusplus
extern "C" {
#endif

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

#ifdef __cplusplus
}
#endif

#endif /* VD_ERRORS_H */
