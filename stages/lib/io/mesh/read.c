/* read.c - the buffered reader every mesh format reads its file through,
 * and the token and number parsing the text formats share (the
 * character tests are inline in mesh_internal.h). */
#include "io/mesh/mesh_internal.h"

#include <errno.h>
#include <inttypes.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <unistd.h>

/* Returns 1 if bytes were added, 0 at end of file or when the buffer is full
 * of unread bytes, -1 after a failed read (detail set). */
int vd__rd_fill(struct vd_rd *r)
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
int vd__rd_need(struct vd_rd *r, size_t n)
{
	while (r->len - r->pos < n) {
		int f = vd__rd_fill(r);
		if (f < 0)
			return VD_ERR_IO;
		if (f == 0)
			return VD_ERR_TRUNCATED;
	}
	return VD_OK;
}

/* Skips n bytes, which may be more than the buffer holds. Same returns as
 * vd__rd_need. */
int vd__rd_skip(struct vd_rd *r, uint64_t n)
{
	while (n > 0) {
		if (r->pos == r->len) {
			int f = vd__rd_fill(r);
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

int vd__rd_seek(struct vd_rd *r, uint64_t off, uint64_t lines)
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
int vd__rd_line(struct vd_rd *r, char **s, size_t *len, int join)
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
		int f = vd__rd_fill(r);
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

/* Parses one number token at p (no leading space). Returns the character
 * after it, or NULL if the token is not a number. */
const char *vd__parse_double(const char *p, double *out)
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
const char *vd__parse_int(const char *p, int64_t *out)
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

/* Length of the token at t, at most 40, for messages. */
int vd__tok40(const char *t)
{
	ptrdiff_t n = vd_token_end(t) - t;
	return n > 40 ? 40 : (int)n;
}

/* Returns the text after keyword kw if line p starts with it, else NULL. */
const char *vd__kw(const char *p, const char *kw)
{
	size_t n = strlen(kw);
	return !strncmp(p, kw, n) && vd_is_end(p[n]) ? p + n : NULL;
}

int vd__has_ext(const char *path, const char *ext)
{
	size_t n = strlen(path), e = strlen(ext);
	return n > e && !strcasecmp(path + n - e, ext);
}
