/* vdb_walk.c - the structure walk of an OpenVDB file, before OpenVDB reads
 * it (C, no OpenVDB: fuzzed on its own by tests/fuzz/fuzz_vdb.c).
 *
 * OpenVDB trusts the lengths it reads (a cut file can make it wait on a
 * huge read or report zero grids), so a cut is found here, by the first
 * length that points past the end of the file. Layout (little-endian):
 * int64 magic, uint32 file version, uint32 library major and minor, uint8
 * "has grid offsets", 36-byte UUID, file metadata (int32 count, then name,
 * type and value, each as uint32 length + bytes), int32 grid count, then
 * per grid a descriptor (name, type and parent name strings, int64 grid,
 * block and end offsets) followed by the grid up to its end offset. */
#include <errno.h>
#include <stdio.h>
#include <string.h>

#include "voxdag.h"

struct walk {
	FILE *f;
	uint64_t pos, size;
};

static int need(const struct walk *w, uint64_t n, const char *what)
{
	if (n > w->size || w->pos + n > w->size)
		return vd_fail(VD_ERR_TRUNCATED, "the file (%llu bytes) ends "
			       "inside %s", (unsigned long long)w->size, what);
	return VD_OK;
}

static int rd(struct walk *w, int n, const char *what, uint64_t *v)
{
	unsigned char b[8];
	int err = need(w, (uint64_t)n, what);
	if (err)
		return err;
	if (fseeko(w->f, (off_t)w->pos, SEEK_SET) != 0 ||
	    fread(b, 1, (size_t)n, w->f) != (size_t)n)
		return vd_fail(VD_ERR_IO, "cannot read at byte %llu",
			       (unsigned long long)w->pos);
	w->pos += (uint64_t)n;
	*v = 0;
	for (int i = n - 1; i >= 0; i--)
		*v = *v << 8 | b[i];
	return VD_OK;
}

static int skip_string(struct walk *w, const char *what)
{
	uint64_t len;
	int err = rd(w, 4, what, &len);
	if (!err && !(err = need(w, len, what)))
		w->pos += len;
	return err;
}

int vd_vdb_walk(FILE *f, uint64_t *grids)
{
	/* OpenVDB files open with the int64 0x56444220 (" BDV") */
	static const unsigned char want[8] = {0x20, 0x42, 0x44, 0x56, 0, 0, 0, 0};
	unsigned char head[8];
	*grids = 0;
	if (fseeko(f, 0, SEEK_SET) != 0)
		return vd_fail(VD_ERR_IO, "cannot seek: %s", strerror(errno));
	size_t got = fread(head, 1, sizeof head, f);
	if (ferror(f))
		return vd_fail(VD_ERR_IO, "%s", strerror(errno));
	if (got == 0)
		return vd_fail(VD_ERR_EMPTY, "the file is empty");
	if (got < 8 && memcmp(head, want, got) == 0)
		return vd_fail(VD_ERR_TRUNCATED, "the file ends inside the "
			       "OpenVDB magic number");
	if (got < 8 || memcmp(head, want, 8) != 0)
		return vd_fail(VD_ERR_FORMAT, "not an OpenVDB file (no VDB "
			       "magic number)");
	struct walk w = {f, 0, 0};
	off_t end;
	if (fseeko(f, 0, SEEK_END) != 0 || (end = ftello(f)) < 0)
		return vd_fail(VD_ERR_IO, "cannot seek: %s", strerror(errno));
	w.size = (uint64_t)end;
	uint64_t version, v, offsets, count;
	int err;
	if ((err = rd(&w, 8, "the magic number", &v)) ||
	    (err = rd(&w, 4, "the header", &version)) ||
	    (err = rd(&w, 8, "the header", &v)) ||
	    (err = rd(&w, 1, "the header", &offsets)) ||
	    (err = need(&w, 36, "the header")))
		return err;
	w.pos += 36; /* UUID */
	if ((err = rd(&w, 4, "the file metadata", &count)))
		return err;
	for (uint64_t i = 0; i < count; i++)
		if ((err = skip_string(&w, "the file metadata")) ||
		    (err = skip_string(&w, "the file metadata")) ||
		    (err = skip_string(&w, "the file metadata")))
			return err;
	if ((err = rd(&w, 4, "the grid count", grids)))
		return err;
	if (!offsets)
		return VD_OK; /* old files without offsets: OpenVDB checks alone */
	for (uint64_t i = 0; i < *grids; i++) {
		uint64_t gpos, bpos, epos;
		if ((err = skip_string(&w, "a grid descriptor")) ||
		    (err = skip_string(&w, "a grid descriptor")) ||
		    (err = skip_string(&w, "a grid descriptor")) ||
		    (err = rd(&w, 8, "a grid descriptor", &gpos)) ||
		    (err = rd(&w, 8, "a grid descriptor", &bpos)) ||
		    (err = rd(&w, 8, "a grid descriptor", &epos)))
			return err;
		if (gpos != w.pos || bpos < gpos || epos < bpos)
			return vd_fail(VD_ERR_CORRUPT, "grid %llu has offsets "
				       "%llu, %llu, %llu at byte %llu",
				       (unsigned long long)i,
				       (unsigned long long)gpos,
				       (unsigned long long)bpos,
				       (unsigned long long)epos,
				       (unsigned long long)w.pos);
		if ((err = need(&w, epos - w.pos, "grid data")))
			return err;
		w.pos = epos;
	}
	(void)version;
	return VD_OK;
}
