/* error.c - the library's error codes and the per-thread detail line. */
#include "voxdag.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>

static _Thread_local char detail[512];

const char *vd_strerror(int err)
{
	switch (err) {
	case VD_OK: return "success";
	case VD_ERR_IO: return "I/O error";
	case VD_ERR_NOMEM: return "out of memory";
	case VD_ERR_NOT_CHUNK: return "not a chunk file";
	case VD_ERR_NEWER_VERSION: return "chunk format version too new";
	case VD_ERR_WRONG_KIND: return "wrong chunk kind";
	case VD_ERR_TRUNCATED: return "truncated file";
	case VD_ERR_CHECKSUM: return "checksum mismatch";
	case VD_ERR_TRAILING: return "trailing bytes after end of file";
	case VD_ERR_CORRUPT: return "corrupt content";
	case VD_ERR_FORMAT: return "malformed input";
	case VD_ERR_UNSUPPORTED: return "unsupported input";
	case VD_ERR_RANGE: return "value out of range";
	case VD_ERR_BUDGET: return "memory budget too small";
	case VD_ERR_EMPTY: return "empty input";
	case VD_ERR_ARG: return "invalid argument";
	case VD_ERR_COMPRESS: return "compression failed";
	case VD_ERR_MISMATCH: return "inputs do not match";
	case VD_ERR_INTERNAL: return "internal error";
	}
	return "unknown error";
}

const char *vd_error_detail(void)
{
	return detail;
}

/* Formatted into a local buffer first: callers rewrap the current detail
 * (vd_fail(e, "cannot write '%s': %s", p, vd_error_detail())), and
 * vsnprintf into the buffer it reads from is undefined (it printed
 * "I/O error:  space left on device"). */
int vd_fail(int err, const char *fmt, ...)
{
	char line[sizeof detail];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(line, sizeof line, fmt, ap);
	va_end(ap);
	memcpy(detail, line, sizeof detail);
	return err;
}

void vd_error_clear(void)
{
	detail[0] = 0;
}
