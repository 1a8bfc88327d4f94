/* test_chunk.c - chunk container: golden bytes, round trips, every
 * truncation, each corruption its own error. */
#include "check.h"
#include "voxdag.h"

#include <math.h>
#include <sys/stat.h>
#include <unistd.h>
#include <xxhash.h>

static const char *dir;

static uint8_t *slurp(const char *path, size_t *n)
{
	FILE *f = fopen(path, "rb");
	*n = 0;
	if (!f)
		return calloc(1, 1);
	fseek(f, 0, SEEK_END);
	long len = ftell(f);
	fseek(f, 0, SEEK_SET);
	uint8_t *b = malloc((size_t)len + 1);
	*n = fread(b, 1, (size_t)len, f);
	fclose(f);
	return b;
}

/* Files a and b hold the same bytes. */
static void check_same_bytes(const char *a, const char *b)
{
	size_t na, nb;
	uint8_t *ba = slurp(a, &na), *bb = slurp(b, &nb);
	CHECK_EQ(na, nb);
	CHECK(na == nb && memcmp(ba, bb, na) == 0);
	free(ba);
	free(bb);
}

/* Little-endian byte builder, written apart from chunk.c on purpose. */
struct bytes {
	uint8_t b[1024];
	size_t n;
};
static void le(struct bytes *o, uint64_t v, int width)
{
	for (int i = 0; i < width; i++)
		o->b[o->n++] = (uint8_t)(v >> 8 * i);
}
static void raw(struct bytes *o, const void *p, size_t n)
{
	memcpy(o->b + o->n, p, n);
	o->n += n;
}
static void f64(struct bytes *o, double d)
{
	uint64_t v;
	memcpy(&v, &d, 8);
	le(o, v, 8);
}
static void f32(struct bytes *o, float d)
{
	uint32_t v;
	memcpy(&v, &d, 4);
	le(o, v, 4);
}

static struct vd_chunk_header tiny_header(void)
{
	struct vd_chunk_header h = {0};
	h.kind = VD_KIND_SVO;
	h.levels = 3;
	h.chunk_level = 1;
	h.cell_morton = 5;
	h.transform.origin[0] = -1.5;
	h.transform.origin[1] = 2.0;
	h.transform.origin[2] = 0.25;
	h.transform.voxel_size = 0.5;
	h.transform.bbox_min[0] = -1.5f;
	h.transform.bbox_max[0] = 2.5f;
	h.transform.root_side = 4.0f;
	h.level_count = 3;
	h.level_nodes[0] = 1;
	h.level_nodes[1] = 2;
	h.level_nodes[2] = 9;
	return h;
}

/* A chunk with two stored sections, so its bytes do not depend on the
 * zstd version; every byte is worked out here from the specification. */
static void test_golden_bytes(void)
{
	char path[600];
	snprintf(path, sizeof path, "%s/golden.chk", dir);
	struct vd_chunk_header h = tiny_header();
	struct vd_chunk_writer *w;
	CHECK_EQ(vd_chunk_writer_open(&w, path, &h, "tool=t"), VD_OK);
	CHECK_EQ(vd_chunk_writer_begin(w, VD_TAG('T', 'E', 'S', 'T'), -1), VD_OK);
	CHECK_EQ(vd_chunk_writer_write(w, "abc", 3), VD_OK);
	CHECK_EQ(vd_chunk_writer_end(w), VD_OK);
	CHECK_EQ(vd_chunk_writer_commit(w), VD_OK);

	struct bytes e = {.n = 0};
	static const uint8_t magic[8] = {0x89, 'V', 'X', 'D', 13, 10, 26, 10};
	raw(&e, magic, 8);
	le(&e, 1, 2);            /* major */
	le(&e, 0, 2);            /* minor */
	le(&e, 104 + 24 + 8, 4); /* header size: fixed + 3 counts + checksum */
	le(&e, 1, 4);            /* kind svo */
	le(&e, 3, 4);            /* levels */
	le(&e, 1, 4);            /* chunk level */
	le(&e, 3, 4);            /* level count */
	le(&e, 5, 8);            /* cell */
	f64(&e, -1.5), f64(&e, 2.0), f64(&e, 0.25), f64(&e, 0.5);
	f32(&e, -1.5f), f32(&e, 0), f32(&e, 0);
	f32(&e, 2.5f), f32(&e, 0), f32(&e, 0);
	f32(&e, 4.0f);
	le(&e, 2, 4);            /* sections */
	le(&e, 1, 8), le(&e, 2, 8), le(&e, 9, 8);
	le(&e, XXH3_64bits(e.b, e.n), 8);
	raw(&e, "PROV", 4), le(&e, 0, 4), le(&e, 6, 8), le(&e, 6, 8);
	le(&e, XXH3_64bits("tool=t", 6), 8);
	raw(&e, "tool=t", 6);
	raw(&e, "TEST", 4), le(&e, 0, 4), le(&e, 3, 8), le(&e, 3, 8);
	le(&e, XXH3_64bits("abc", 3), 8);
	raw(&e, "abc", 3);
	static const uint8_t end[8] = {0x89, 'V', 'X', 'D', 'E', 'N', 'D', 10};
	raw(&e, end, 8);
	le(&e, e.n + 16, 8);
	le(&e, XXH3_64bits(e.b, e.n), 8);

	size_t n;
	uint8_t *got = slurp(path, &n);
	CHECK(got != NULL);
	CHECK_EQ(n, e.n);
	CHECK(got && n == e.n && memcmp(got, e.b, n) == 0);

	struct vd_chunk *c;
	CHECK_EQ(vd_chunk_open(&c, path, VD_KIND_SVO), VD_OK);
	if (c) {
		const struct vd_chunk_header *r = vd_chunk_header(c);
		CHECK_EQ(r->levels, 3);
		CHECK_EQ(r->cell_morton, 5);
		CHECK(r->transform.origin[2] == 0.25);
		CHECK(r->transform.root_side == 4.0f);
		CHECK_EQ(r->level_nodes[2], 9);
		CHECK(strcmp(vd_chunk_provenance(c), "tool=t") == 0);
		void *d;
		size_t dn;
		CHECK_EQ(vd_chunk_read_section(c, VD_TAG('T', 'E', 'S', 'T'), &d,
					       &dn), VD_OK);
		CHECK(dn == 3 && memcmp(d, "abc", 3) == 0);
		free(d);
		CHECK_EQ(vd_chunk_read_section(c, VD_TAG('N', 'O', 'P', 'E'), &d,
					       &dn), VD_ERR_CORRUPT);
		vd_chunk_free(c);
	}
	free(got);
}

/* A realistic chunk: an SVO with zstd sections. */
static void write_sample_svo(const char *path)
{
	struct vd_svo s = {.levels = 6, .chunk_level = 1, .cell_morton = 3};
	s.count = 300;
	s.keys = malloc(8 * s.count);
	s.masks = malloc(8 * s.count);
	for (size_t i = 0; i < s.count; i++) {
		s.keys[i] = (3ull << 9) | (i * 7 % 512 / 1); /* filled below */
		s.masks[i] = 0x8001ull * (i + 1);
	}
	/* strictly increasing keys inside cell 3 at level 1 (9 bits below) */
	for (size_t i = 0; i < s.count; i++)
		s.keys[i] = (3ull << 9) | (i + i / 3);
	struct vd_transform t = {.voxel_size = 1, .root_side = 64};
	CHECK_EQ(vd_svo_save(&s, &t, path, "tool=test"), VD_OK);
	vd_svo_release(&s);
}

static void test_svo_round_trip(void)
{
	char path[600];
	snprintf(path, sizeof path, "%s/svo.chk", dir);
	write_sample_svo(path);
	struct vd_svo s;
	struct vd_chunk_header h;
	CHECK_EQ(vd_svo_load(&s, &h, path), VD_OK);
	CHECK_EQ(s.count, 300);
	uint64_t voxels = 0;
	for (size_t i = 0; i < s.count; i++) {
		CHECK_EQ(s.keys[i], (3ull << 9) | (i + i / 3));
		CHECK_EQ(s.masks[i], 0x8001ull * (i + 1));
		voxels += (uint64_t)__builtin_popcountll(s.masks[i]);
	}
	CHECK_EQ(h.level_count, 6);
	CHECK_EQ(h.level_nodes[5], voxels);      /* level 6: voxels */
	CHECK_EQ(h.level_nodes[3], 300);         /* level 4: bricks */
	CHECK_EQ(h.level_nodes[0], 1);           /* level 1: the cell */
	vd_svo_release(&s);
	/* no temporary file left behind */
	char tmp[700];
	snprintf(tmp, sizeof tmp, "%s/svo.chk.tmp.%ld", dir, (long)getpid());
	CHECK(access(tmp, F_OK) != 0);
}

/* The streaming SVO writer gives vd_svo_save's bytes (keys and masks in
 * uneven batches) and the bricks' digest; keys out of order, too few or
 * too many bricks and an empty mask are refused and leave no file. */
static void test_svo_writer_stream(void)
{
	char a[600], b[600];
	snprintf(a, sizeof a, "%s/svo.chk", dir);
	snprintf(b, sizeof b, "%s/svo-stream.chk", dir);
	write_sample_svo(a);
	struct vd_svo s;
	CHECK_EQ(vd_svo_load(&s, NULL, a), VD_OK);
	struct vd_transform t = {.voxel_size = 1, .root_side = 64};
	struct vd_svo_writer *w;
	CHECK_EQ(vd_svo_writer_open(&w, b, 6, 1, 3, &t, "tool=test", s.count),
		 VD_OK);
	for (size_t i = 0; i < s.count; i += 7)
		CHECK_EQ(vd_svo_writer_keys(w, s.keys + i,
					    s.count - i < 7 ? s.count - i : 7),
			 VD_OK);
	for (size_t i = 0; i < s.count; i += 100)
		CHECK_EQ(vd_svo_writer_masks(w, s.keys + i, s.masks + i,
					     s.count - i < 100 ? s.count - i : 100),
			 VD_OK);
	uint64_t dig = 0;
	CHECK_EQ(vd_svo_writer_commit(w, &dig), VD_OK);
	CHECK_EQ(dig, vd_svo_digest(s.keys, s.masks, s.count));
	size_t na, nb;
	char *x = test_slurp(a, &na), *y = test_slurp(b, &nb);
	CHECK(x && y && na == nb && !memcmp(x, y, na));
	free(x);
	free(y);
	/* refusals */
	unlink(b);
	CHECK_EQ(vd_svo_writer_open(&w, b, 6, 1, 3, &t, NULL, 2), VD_OK);
	uint64_t k2[2] = {s.keys[1], s.keys[0]};
	CHECK_EQ(vd_svo_writer_keys(w, k2, 2), VD_ERR_ARG);
	vd_svo_writer_abort(w);
	CHECK_EQ(vd_svo_writer_open(&w, b, 6, 1, 3, &t, NULL, 2), VD_OK);
	CHECK_EQ(vd_svo_writer_keys(w, s.keys, 3), VD_ERR_ARG); /* extra */
	CHECK_EQ(vd_svo_writer_keys(w, s.keys, 1), VD_OK);
	CHECK_EQ(vd_svo_writer_masks(w, s.keys, s.masks, 1), VD_ERR_ARG);
	vd_svo_writer_abort(w);
	CHECK_EQ(vd_svo_writer_open(&w, b, 6, 1, 3, &t, NULL, 2), VD_OK);
	uint64_t zero[2] = {0, 0};
	CHECK_EQ(vd_svo_writer_keys(w, s.keys, 2), VD_OK);
	CHECK_EQ(vd_svo_writer_masks(w, s.keys, zero, 2), VD_ERR_ARG);
	vd_svo_writer_abort(w);
	CHECK_EQ(vd_svo_writer_open(&w, b, 6, 1, 3, &t, NULL, 2), VD_OK);
	CHECK_EQ(vd_svo_writer_keys(w, s.keys, 2), VD_OK);
	CHECK_EQ(vd_svo_writer_masks(w, s.keys, s.masks, 1), VD_OK);
	CHECK_EQ(vd_svo_writer_commit(w, NULL), VD_ERR_ARG); /* one missing */
	CHECK(access(b, F_OK) != 0);
	char cmd[700];
	snprintf(cmd, sizeof cmd, "ls '%s' | grep -q 'svo-stream.*tmp'", dir);
	CHECK(system(cmd) != 0);
	vd_svo_release(&s);
}

static int open_bytes(const uint8_t *b, size_t n, uint32_t kind)
{
	struct vd_chunk *c;
	int err = vd_chunk_open_mem(&c, b, n, kind);
	vd_chunk_free(c);
	return err;
}

static void test_every_truncation(void)
{
	char path[600];
	snprintf(path, sizeof path, "%s/svo.chk", dir);
	write_sample_svo(path);
	size_t n;
	uint8_t *b = slurp(path, &n);
	CHECK_EQ(open_bytes(b, n, VD_KIND_SVO), VD_OK);
	int bad = 0;
	for (size_t len = 0; len < n; len++) {
		int err = open_bytes(b, len, VD_KIND_SVO);
		int want = len == 0 ? VD_ERR_NOT_CHUNK : VD_ERR_TRUNCATED;
		if (err != want) {
			if (!bad++)
				fprintf(stderr, "length %zu of %zu: %s (%s)\n", len,
					n, vd_strerror(err), vd_error_detail());
		}
	}
	CHECK_EQ(bad, 0);
	free(b);
}

static void test_each_corruption(void)
{
	char path[600];
	snprintf(path, sizeof path, "%s/svo.chk", dir);
	write_sample_svo(path);
	size_t n;
	uint8_t *b = slurp(path, &n);
	uint8_t *x = malloc(n + 24);

	memcpy(x, b, n);
	x[1] = 'W';
	CHECK_EQ(open_bytes(x, n, VD_KIND_SVO), VD_ERR_NOT_CHUNK);
	CHECK_EQ(open_bytes((const uint8_t *)"ply\nformat", 10, VD_KIND_SVO),
		 VD_ERR_NOT_CHUNK);

	memcpy(x, b, n);
	x[8] = 2; /* major 2 */
	CHECK_EQ(open_bytes(x, n, VD_KIND_SVO), VD_ERR_NEWER_VERSION);

	memcpy(x, b, n);
	x[10] = 7; /* a newer minor version is read (header checksum fails
		    * here only because we edited the bytes) */
	CHECK_EQ(open_bytes(x, n, VD_KIND_SVO), VD_ERR_CHECKSUM);

	CHECK_EQ(open_bytes(b, n, VD_KIND_DAG), VD_ERR_WRONG_KIND);
	CHECK_EQ(open_bytes(b, n, VD_KIND_ANY), VD_OK);

	/* a flipped bit anywhere after the header: checksum */
	int bad = 0;
	for (size_t i = 0; i < n; i++) {
		memcpy(x, b, n);
		x[i] ^= 0x10;
		int err = open_bytes(x, n, VD_KIND_SVO);
		/* the magic and version bytes have their own verdicts */
		if (i < 12)
			continue;
		if (err != VD_ERR_CHECKSUM && err != VD_ERR_CORRUPT) {
			if (!bad++)
				fprintf(stderr, "flip at %zu: %s (%s)\n", i,
					vd_strerror(err), vd_error_detail());
		}
	}
	CHECK_EQ(bad, 0);

	memcpy(x, b, n);
	memcpy(x + n, "garbage!", 8);
	CHECK_EQ(open_bytes(x, n + 8, VD_KIND_SVO), VD_ERR_TRAILING);
	memcpy(x + n, b + n - 24, 24); /* a second copy of the footer */
	CHECK_EQ(open_bytes(x, n + 24, VD_KIND_SVO), VD_ERR_TRAILING);
	free(x);
	free(b);
}

static void test_abort_leaves_nothing(void)
{
	char path[600];
	snprintf(path, sizeof path, "%s/aborted.chk", dir);
	struct vd_chunk_header h = tiny_header();
	struct vd_chunk_writer *w;
	CHECK_EQ(vd_chunk_writer_open(&w, path, &h, NULL), VD_OK);
	CHECK_EQ(vd_chunk_writer_section(w, VD_TAG_BRKS, "x", 1), VD_OK);
	vd_chunk_writer_abort(w);
	CHECK(access(path, F_OK) != 0);
	char cmd[700];
	snprintf(cmd, sizeof cmd, "ls '%s' | grep -q aborted", dir);
	CHECK(system(cmd) != 0);
	/* an unwritable directory is an I/O error, not a crash */
	snprintf(path, sizeof path, "%s/no/such/dir/x.chk", dir);
	CHECK_EQ(vd_chunk_writer_open(&w, path, &h, NULL), VD_ERR_IO);
	struct vd_chunk *c;
	CHECK_EQ(vd_chunk_open(&c, path, VD_KIND_ANY), VD_ERR_IO);
	CHECK_EQ(vd_chunk_open(&c, dir, VD_KIND_ANY), VD_ERR_IO);
}

static void test_svo_content_checks(void)
{
	/* A well-formed container whose bricks leave their cell. */
	char path[600];
	snprintf(path, sizeof path, "%s/outside.chk", dir);
	struct vd_svo s = {.levels = 6, .chunk_level = 1, .cell_morton = 3};
	uint64_t key = 2ull << 9, mask = 1;
	s.count = 1;
	s.keys = &key;
	s.masks = &mask;
	struct vd_transform t = {.voxel_size = 1, .root_side = 64};
	CHECK_EQ(vd_svo_save(&s, &t, path, NULL), VD_OK);
	struct vd_svo r;
	CHECK_EQ(vd_svo_load(&r, NULL, path), VD_ERR_CORRUPT);
	CHECK(strstr(vd_error_detail(), "outside") != NULL);
}

/* vd_transform_equal against pairs the three old comparisons (now dag/stage.c:
 * box, side, origin, voxel size by ==; encode.c: box and side; vdb_export.c:
 * origin and voxel size) judged wrongly. */
static void test_transform_equal(void)
{
	const float lo[3] = {-1, 0, 2}, hi[3] = {3, 1, 4};
	struct vd_transform t, u;
	CHECK_EQ(vd_transform_init(&t, lo, hi, 8), VD_OK);
	u = t;
	CHECK(vd_transform_equal(&t, &u));
	/* Another depth: same box, side and origin; encode.c said equal. */
	CHECK_EQ(vd_transform_init(&u, lo, hi, 9), VD_OK);
	CHECK(t.root_side == u.root_side && t.origin[0] == u.origin[0]);
	CHECK(!vd_transform_equal(&t, &u));
	/* Another origin, same box: encode.c said equal. */
	u = t;
	u.origin[1] += t.voxel_size;
	CHECK(!vd_transform_equal(&t, &u));
	/* Another stored box (the encodings' header), same placement:
	 * vdb_export.c said equal. */
	u = t;
	u.bbox_min[2] = 2.5f;
	CHECK(!vd_transform_equal(&t, &u));
	/* -0 and +0: different header bytes; == said equal everywhere. */
	const float lo0[3] = {0.0f, 0, 0}, lon[3] = {-0.0f, 0, 0};
	const float hi1[3] = {1, 1, 1};
	CHECK_EQ(vd_transform_init(&t, lo0, hi1, 4), VD_OK);
	CHECK_EQ(vd_transform_init(&u, lon, hi1, 4), VD_OK);
	CHECK(t.bbox_min[0] == u.bbox_min[0]);
	CHECK(!vd_transform_equal(&t, &u));
	/* A NaN field equals itself (== said never). */
	u = t;
	u.voxel_size = NAN;
	struct vd_transform w = u;
	CHECK(vd_transform_equal(&u, &w));
	/* Padding bytes do not matter. */
	memset(&u, 0xa5, sizeof u);
	memset(&w, 0x5a, sizeof w);
	u.root_side = w.root_side = 1;
	for (int i = 0; i < 3; i++) {
		u.bbox_min[i] = w.bbox_min[i] = 0;
		u.bbox_max[i] = w.bbox_max[i] = 1;
		u.origin[i] = w.origin[i] = 0;
	}
	u.voxel_size = w.voxel_size = 0.5;
	CHECK(vd_transform_equal(&u, &w));
}

/* Raw bytes for the framed sections: a function of the offset alone, half
 * runs (so zstd has work) and half noise. */
static uint8_t framed_byte(uint64_t i)
{
	uint64_t x = (i / 64) * 0x9E3779B97F4A7C15ull;
	return (i / 4096) % 2 ? (uint8_t)(i / 512) : (uint8_t)(x >> 56 ^ i);
}

static void framed_fill(void *ctx, uint64_t off, uint8_t *buf, size_t n)
{
	(void)ctx;
	CHECK_EQ(off % VD_CHUNK_FRAME_BYTES, 0);
	for (size_t i = 0; i < n; i++)
		buf[i] = framed_byte(off + i);
}

static void write_framed(const char *path, uint64_t raw, int threads,
			 int planes)
{
	struct vd_chunk_header h = tiny_header();
	struct vd_chunk_writer *w;
	CHECK_EQ(vd_chunk_writer_open(&w, path, &h, NULL), VD_OK);
	CHECK_EQ(vd_chunk_writer_frames(w, VD_TAG_BRKS, raw, framed_fill,
					NULL, threads, planes), VD_OK);
	CHECK_EQ(vd_chunk_writer_section(w, VD_TAG('T', 'A', 'I', 'L'), "x", 1),
		 VD_OK);
	CHECK_EQ(vd_chunk_writer_commit(w), VD_OK);
}

/* The codec field of the section tagged BRKS in file `path`. */
static uint32_t brks_codec(const char *path)
{
	FILE *f = fopen(path, "rb");
	static uint8_t b[1 << 12];
	size_t n = f ? fread(b, 1, sizeof b, f) : 0;
	if (f) fclose(f);
	for (size_t i = 0; i + 8 <= n; i++)
		if (!memcmp(b + i, "BRKS", 4))
			return (uint32_t)b[i + 4] | (uint32_t)b[i + 5] << 8 |
			       (uint32_t)b[i + 6] << 16 | (uint32_t)b[i + 7] << 24;
	return UINT32_MAX;
}

/* A section written as several zstd frames: the same file whatever the
 * thread count, read back exactly by the serial reader (concatenated
 * frames are one zstd stream to ZSTD_decompress) and the parallel one.
 * With planes (codec 2, 4-byte elements as byte planes a frame) too: the
 * bytes read back are the raw ones, on the one-frame path (a copy of the
 * whole) and the parallel one. */
static void test_framed_sections(void)
{
	uint64_t sizes[] = {0, 1, 4, VD_CHUNK_FRAME_BYTES,
			    2 * (uint64_t)VD_CHUNK_FRAME_BYTES + 8 * 12345};
	for (size_t k = 0; k < 2 * sizeof sizes / sizeof *sizes; k++) {
		uint64_t raw = sizes[k / 2];
		int planes = k % 2;
		char p1[600], p3[600];
		snprintf(p1, sizeof p1, "%s/framed1.chk", dir);
		snprintf(p3, sizeof p3, "%s/framed3.chk", dir);
		if (planes && raw % 4) {
			/* not 4-byte elements: refused, nothing written */
			struct vd_chunk_header h = tiny_header();
			struct vd_chunk_writer *w;
			CHECK_EQ(vd_chunk_writer_open(&w, p1, &h, NULL), VD_OK);
			CHECK_EQ(vd_chunk_writer_frames(w, VD_TAG_BRKS, raw,
							framed_fill, NULL, 1, 1),
				 VD_ERR_ARG);
			vd_chunk_writer_abort(w);
			continue;
		}
		write_framed(p1, raw, 1, planes);
		write_framed(p3, raw, 3, planes);
		check_same_bytes(p1, p3);
		CHECK_EQ(brks_codec(p1), planes ? 2u : 1u);
		struct vd_chunk *c;
		CHECK_EQ(vd_chunk_open(&c, p1, VD_KIND_ANY), VD_OK);
		for (int threads = 1; threads <= 4; threads += 3) {
			void *data;
			size_t size;
			CHECK_EQ(vd_chunk_read_section_mt(c, VD_TAG_BRKS, &data,
							  &size, threads), VD_OK);
			CHECK_EQ(size, raw);
			size_t bad = 0;
			for (size_t i = 0; i < size; i++)
				bad += ((uint8_t *)data)[i] != framed_byte(i);
			CHECK_EQ(bad, 0);
			free(data);
		}
		vd_chunk_free(c);
	}
}

int main(void)
{
	dir = test_tmpdir("chunk");
	RUN(test_golden_bytes);
	RUN(test_svo_round_trip);
	RUN(test_svo_writer_stream);
	RUN(test_every_truncation);
	RUN(test_each_corruption);
	RUN(test_abort_leaves_nothing);
	RUN(test_svo_content_checks);
	RUN(test_transform_equal);
	RUN(test_framed_sections);
	return CHECK_DONE();
}
