/* test_colour_auto.c - the auto colour method (colour/auto.c, method 4 of
 * schemas/colour-formats.md): the specification's worked example byte
 * for byte (the encoder's blocks and the whole file's sections); every
 * decoded colour within the max error (lossless: equal) against the
 * original on random arrays of several kinds and on the bundled spider,
 * by random access and by range decoding; the spider's colours looked up
 * through the DAG (voxel counts along the path) equal the colour chunk in
 * the SVO's depth-first order; the expected mode wins on hand-made
 * blocks; truncated, corrupted and inconsistent files are refused. */
#include "check.h"
#include "le.h"
#include "scene.h"
#include "colour_fixture.h"
#include "colour/colour_internal.h" /* the coded mode's symbol numbers */

#include <math.h>

static char dir[] = "/tmp/vd_cauto_XXXXXX";
static struct vd_transform tr;

/* ------------------------------------------------ the worked example */

/* The specification's array: 72 colours, blocks of 16: a constant
 * block, three colours, 16 pseudo-random colours, small noise, and a
 * tail of 8 on a line. */
static void golden_array(uint8_t *rgb)
{
	static const uint8_t three[3][3] = {
		{10, 20, 30}, {200, 100, 50}, {40, 250, 140}};
	uint32_t s = 1;
	for (int i = 0; i < 72; i++) {
		uint8_t *x = rgb + 3 * i;
		int j = i & 15;
		if (i < 16) {
			x[0] = 10, x[1] = 20, x[2] = 30;
		} else if (i < 32) {
			memcpy(x, three[(j * 7) % 3], 3);
		} else if (i < 48) {
			for (int c = 0; c < 3; c++) {
				s = s * 1103515245u + 12345u;
				x[c] = (uint8_t)(s >> 16);
			}
		} else if (i < 64) {
			x[0] = (uint8_t)(100 + j * 5 % 8);
			x[1] = (uint8_t)(50 + j * 3 % 4);
			x[2] = (uint8_t)(60 + j % 2);
		} else {
			x[0] = (uint8_t)(100 + (i - 64));
			x[1] = 50;
			x[2] = (uint8_t)(60 + 2 * (i - 64));
		}
	}
}

/* The bytes of schemas/colour-formats.md, "Worked example". */
static const uint32_t golden_dir[5] = {0x001e140a, 0x12000000, 0x4000000e,
				       0x3000003e, 0x23000050};
static const uint8_t golden_data[90] = {
	0x02, 0x0a, 0x14, 0x1e, 0xc8, 0x64, 0x32, 0x28, 0xfa, 0x8c, 0x24, 0x49,
	0x92, 0x24, 0xc6, 0x7e, 0x81, 0x6b, 0x4b, 0xfb, 0xe2, 0xfb, 0x54, 0xf6,
	0xbd, 0xdf, 0x7c, 0x1c, 0xe1, 0x87, 0x01, 0xbf, 0x31, 0xde, 0x56, 0x72,
	0x0f, 0x47, 0x67, 0x66, 0x87, 0x59, 0xaa, 0x88, 0x3c, 0x59, 0xea, 0x56,
	0x13, 0x7b, 0xd2, 0x85, 0xa1, 0xd8, 0x3c, 0x54, 0x55, 0x2f, 0x37, 0xae,
	0x65, 0x5b, 0x64, 0x32, 0x3c, 0x01, 0x23, 0x01, 0x40, 0x2f, 0xbd, 0x44,
	0x6e, 0xad, 0x40, 0x2f, 0xbd, 0x44, 0x6e, 0xad, 0x04, 0x64, 0x32, 0x3c,
	0x6b, 0x32, 0x4a, 0x88, 0xc6, 0xfa};


/* The specification's second example (format 1.2, coded segments): 1024
 * colours, blocks of 64: pairs of a slow gradient (runs of 2, small
 * deltas) around 128 colours alternating between three (hits). */
static void golden2_array(uint8_t *rgb)
{
	static const uint8_t three[3][3] = {
		{200, 30, 30}, {30, 200, 30}, {30, 30, 200}};
	for (int i = 0; i < 1024; i++) {
		int c = i / 2;
		uint8_t *x = rgb + 3 * i;
		if (i >= 384 && i < 512) {
			memcpy(x, three[(i * 5 / 7) % 3], 3);
			continue;
		}
		x[0] = (uint8_t)(60 + c * 7 % 23);
		x[1] = (uint8_t)(90 + c / 9);
		x[2] = (uint8_t)(x[1] + c % 3);
	}
}

static const uint32_t golden2_dir[16] = {
	0x500002b7, 0x500002d0, 0x500002e9, 0x50000302, 0x5000031b, 0x50000334,
	0x5000034d, 0x5000035f, 0x50000371, 0x5000038a, 0x500003a3, 0x500003bc,
	0x500003d5, 0x500003ee, 0x50000407, 0x50000420, };
static const uint8_t golden2_data[1081] = {
	0xb5, 0x02, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x20, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x10, 0x02, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x10, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x30, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x30, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x20,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x30, 0x01, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x50, 0x50, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x24, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x30, 0x30, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
	0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x20, 0x00, 0x14,
	0x00, 0x3c, 0x5a, 0x5a, 0x00, 0x88, 0x00, 0x22, 0xe0, 0x45, 0x00, 0x01,
	0x41, 0x40, 0xbc, 0x80, 0x20, 0x20, 0x08, 0xc0, 0x17, 0x00, 0x05, 0x00,
	0x14, 0x00, 0x4d, 0x5d, 0x5f, 0x14, 0x80, 0x17, 0x01, 0x44, 0x00, 0x11,
	0xf0, 0x22, 0x80, 0x80, 0x20, 0x20, 0x5e, 0x40, 0x10, 0x00, 0x05, 0xe0,
	0x0b, 0x14, 0x00, 0x47, 0x61, 0x62, 0x40, 0x01, 0x50, 0x00, 0x5e, 0x04,
	0x10, 0x01, 0x44, 0xc0, 0x0b, 0x08, 0x02, 0x82, 0x80, 0x78, 0x01, 0x41,
	0x00, 0x00, 0x14, 0x00, 0x41, 0x64, 0x64, 0x00, 0xbe, 0x00, 0x28, 0x00,
	0x44, 0xc0, 0x8b, 0x00, 0x22, 0x80, 0x08, 0x78, 0x01, 0x41, 0x40, 0x10,
	0x10, 0x2f, 0x00, 0x14, 0x00, 0x52, 0x68, 0x6a, 0x14, 0x00, 0x05, 0xe0,
	0x0b, 0x80, 0x02, 0x40, 0x04, 0xbc, 0x08, 0x20, 0x02, 0x08, 0x88, 0x17,
	0x10, 0x04, 0x04, 0x01, 0x14, 0x00, 0x4c, 0x6b, 0x6c, 0xc4, 0x0b, 0x80,
	0x02, 0xa0, 0x00, 0x7c, 0x01, 0x20, 0x02, 0x88, 0x80, 0x17, 0x01, 0x44,
	0x00, 0x01, 0xf1, 0x02, 0x02, 0x0d, 0x00, 0x1e, 0xc8, 0x1e, 0x7f, 0xe3,
	0x7d, 0x5a, 0xb5, 0x6a, 0xd5, 0xaa, 0x55, 0xab, 0x56, 0xad, 0x0a, 0x0d,
	0x00, 0x1e, 0x1e, 0xc8, 0xbc, 0xf7, 0xaf, 0x55, 0xab, 0x56, 0xad, 0x5a,
	0xb5, 0x6a, 0xd5, 0xaa, 0x01, 0x14, 0x00, 0x51, 0x76, 0x77, 0x04, 0x01,
	0xf1, 0x02, 0x82, 0x00, 0x28, 0x00, 0x5f, 0x00, 0x14, 0x00, 0x05, 0xe0,
	0x45, 0x00, 0x11, 0x40, 0x04, 0x00, 0x14, 0x00, 0x4b, 0x7a, 0x7a, 0x40,
	0x10, 0x10, 0x04, 0xc4, 0x0b, 0x08, 0x02, 0xa0, 0x00, 0x7c, 0x01, 0x50,
	0x00, 0x88, 0x80, 0x17, 0x01, 0x44, 0x00, 0x14, 0x00, 0x45, 0x7d, 0x7f,
	0x88, 0x80, 0x17, 0x10, 0x04, 0x04, 0x01, 0xf1, 0x02, 0xa0, 0x00, 0x28,
	0x00, 0x5f, 0x00, 0x14, 0x00, 0x22, 0xe0, 0x05, 0x14, 0x00, 0x3f, 0x81,
	0x82, 0x80, 0x08, 0x20, 0x20, 0x5e, 0x40, 0x10, 0x10, 0x04, 0xc4, 0x0b,
	0x80, 0x02, 0xa0, 0x00, 0x7c, 0x01, 0x20, 0x02, 0x00, 0x14, 0x00, 0x50,
	0x84, 0x84, 0x04, 0xbc, 0x08, 0x20, 0x02, 0x08, 0x88, 0x17, 0x10, 0x04,
	0x04, 0x01, 0xf8, 0x02, 0xa0, 0x00, 0x28, 0x00, 0x5f, 0x00, 0x14, 0x00,
	0x4a, 0x88, 0x8a, 0x88, 0x00, 0x22, 0xe0, 0x45, 0x00, 0x01, 0x41, 0x40,
	0xbc, 0x80, 0x20, 0x20, 0x08, 0xc0, 0x17, 0x00, 0x05, 0x40, 0x01, 0x14,
	0x00, 0x44, 0x8b, 0x8c, 0xe0, 0x45, 0x00, 0x11, 0x40, 0x04, 0xbc, 0x08,
	0x20, 0x20, 0x08, 0x88, 0x17, 0x10, 0x04, 0x40, 0x01, 0xf8, 0x02, 0x00,
	0x14, 0x00, 0x3e, 0x8f, 0x8f, 0x00, 0x14, 0x80, 0x17, 0x01, 0x44, 0x00,
	0x11, 0xf0, 0x02, 0x82, 0x80, 0x20, 0x20, 0x5e, 0x40, 0x10, 0x00, 0x05,
	0x00, };

static void path_of(char *buf, size_t cap, const char *name)
{
	snprintf(buf, cap, "%s/%s", dir, name);
}

/* A packed file of `cells` cells of the arrays rgb[c] (n[c] colours). */
static int write_cells(const char *name, const struct vd_auto_params *ap,
		       int cells, uint8_t *const *rgb, const uint64_t *n)
{
	char path[256];
	path_of(path, sizeof path, name);
	struct vd_cpack_params p = {.method = VD_CPACK_AUTO, .autop = *ap,
				    .threads = 2};
	struct vd_cpack_writer *w;
	int err = vd_cpack_writer_open(&w, path, &p, 12, &tr, "test");
	for (int c = 0; c < cells && !err; c++)
		err = vd_cpack_writer_add(w, 2, (uint64_t)c * 5 + 3, rgb[c], n[c]);
	if (err) {
		vd_cpack_writer_abort(w);
		return err;
	}
	return vd_cpack_writer_commit(w, NULL);
}

/* A one-cell file of the n colours rgb written with p: its sections hold
 * exactly the specification's bytes (CPAR par; CSEG seg unless NULL; the
 * directory dir of nb blocks; the data), and the reader gives every
 * colour back. */
static void check_golden_file(const char *name,
			      const struct vd_auto_params *p,
			      const uint8_t *rgb, uint32_t n,
			      const uint8_t par[64], const uint8_t seg[40],
			      const uint32_t *bdir, uint32_t nb,
			      const uint8_t *data, size_t ndata)
{
	uint8_t *cells[1] = {(uint8_t *)rgb};
	uint64_t counts[1] = {n};
	CHECK_EQ(write_cells(name, p, 1, cells, counts), VD_OK);
	char path[256];
	path_of(path, sizeof path, name);
	struct vd_chunk *ch;
	CHECK_EQ(vd_chunk_open(&ch, path, VD_KIND_CPACK), VD_OK);
	if (!ch)
		return;
	void *d;
	size_t len;
	CHECK_EQ(vd_chunk_read_section(ch, VD_TAG('C', 'P', 'A', 'R'), &d, &len),
		 VD_OK);
	CHECK(len == 64 && !memcmp(d, par, 64));
	free(d);
	if (seg) {
		CHECK_EQ(vd_chunk_read_section(ch, VD_TAG('C', 'S', 'E', 'G'),
					       &d, &len), VD_OK);
		CHECK(len == 40 && !memcmp(d, seg, 40));
		free(d);
	}
	CHECK_EQ(vd_chunk_read_section(ch, VD_TAG('A', 'B', 'L', 'K'), &d, &len),
		 VD_OK);
	CHECK_EQ(len, 4 * (size_t)nb);
	for (uint32_t b = 0; b < nb && len == 4 * (size_t)nb; b++)
		CHECK_EQ(le_get32((uint8_t *)d + 4 * b), bdir[b]);
	free(d);
	CHECK_EQ(vd_chunk_read_section(ch, VD_TAG('A', 'D', 'A', 'T'), &d, &len),
		 VD_OK);
	CHECK(len == ndata && !memcmp(d, data, len));
	free(d);
	vd_chunk_free(ch);
	struct vd_cpack *c;
	CHECK_EQ(vd_cpack_open(&c, path), VD_OK);
	if (c) {
		CHECK_EQ(vd_cpack_bytes(c), 40 + 4 * nb + ndata);
		for (uint32_t i = 0; i < n; i++) {
			uint8_t o[3];
			CHECK_EQ(vd_cpack_colour(c, (uint64_t)i, o), VD_OK);
			CHECK(!memcmp(o, rgb + 3 * i, 3));
		}
		vd_cpack_free(c);
	}
}

static void test_golden(void)
{
	uint8_t rgb[216];
	golden_array(rgb);
	struct vd_auto_segment s;
	struct vd_auto_params p = {.max_error = 0, .block_log = 4};
	CHECK_EQ(vd_auto_encode(&s, rgb, 72, &p), VD_OK);
	CHECK_EQ(s.count, 5);
	for (uint32_t b = 0; b < 5 && b < s.count; b++)
		CHECK_EQ(s.dir[b], golden_dir[b]);
	CHECK_EQ(s.data_bytes, sizeof golden_data);
	CHECK(s.data_bytes == sizeof golden_data &&
	      !memcmp(s.data, golden_data, sizeof golden_data));
	CHECK_EQ(s.sse, 0);
	vd_auto_segment_release(&s);

	/* the file: its sections hold exactly the specification's bytes */
	uint8_t par[64] = {4, 0, 0, 0, 4, 0, 0, 0, 72, 0, 0, 0, 0, 0, 0, 0,
			   1, 0, 0, 0, 0, 0, 0, 0, 5, 0, 0, 0, 0, 0, 0, 0};
	uint8_t seg[40] = {0};
	seg[24] = 3, seg[32] = 2, seg[36] = 72;
	check_golden_file("golden.auto", &p, rgb, 72, par, seg, golden_dir, 5,
			  golden_data, sizeof golden_data);
}

/* check_file, below */
static void check_file(const char *name, int cells, uint8_t *const *rgb,
		       const uint64_t *n, double et);

/* The 1.2 example: the encoder's segment and the file's sections byte
 * for byte, the coded flag in CPAR, every colour back exactly. */
static void test_golden_coded(void)
{
	uint8_t rgb[3072];
	golden2_array(rgb);
	struct vd_auto_segment s;
	struct vd_auto_params p = {.max_error = 0, .block_log = 6, .coded = 1};
	CHECK_EQ(vd_auto_encode(&s, rgb, 1024, &p), VD_OK);
	CHECK_EQ(s.count, 16);
	CHECK_EQ(s.table_bytes, 693);
	CHECK_EQ(s.mode_blocks[VD_AUTO_CODED >> 4], 16);
	for (uint32_t b = 0; b < 16 && b < s.count; b++)
		CHECK_EQ(s.dir[b], golden2_dir[b]);
	CHECK_EQ(s.data_bytes, sizeof golden2_data);
	CHECK(s.data_bytes == sizeof golden2_data &&
	      !memcmp(s.data, golden2_data, sizeof golden2_data));
	for (uint32_t i = 0; i < 1024; i += 7) {
		uint8_t o[3];
		vd_auto_segment_colour(&s, 6, i, o);
		CHECK(!memcmp(o, rgb + 3 * i, 3));
	}
	vd_auto_segment_release(&s);
	/* coded is lossless only */
	struct vd_auto_params lossy = {.max_error = 0.05, .coded = 1};
	CHECK_EQ(vd_auto_encode(&s, rgb, 1024, &lossy), VD_ERR_ARG);

	uint8_t par[64] = {4, 0, 0, 0, 6, 0, 0, 0, 0, 4, 0, 0, 0, 0, 0, 0,
			   1, 0, 0, 0, 0, 0, 0, 0, 16, 0, 0, 0, 0, 0, 0, 0};
	par[48] = 1; /* coded segments */
	check_golden_file("golden2.auto", &p, rgb, 1024, par, NULL, golden2_dir,
			  16, golden2_data, sizeof golden2_data);
	uint8_t *cells[1] = {rgb};
	uint64_t n[1] = {1024};
	check_file("golden2.auto", 1, cells, n, 0);
}

/* ------------------------------------------- colours within the error */

static uint64_t rng = 4242;
static uint32_t next(void)
{
	return test_xorshift(&rng);
}

static uint8_t clamp8(double v)
{
	return (uint8_t)(v < 0 ? 0 : v > 255 ? 255 : v);
}

/* Arrays of kind 0 noise, 1 runs of few colours, 2 smooth gradients with
 * jumps, 3 small noise around drifting colours. */
static void make_array(uint8_t *rgb, uint64_t n, int kind)
{
	double a[3] = {128, 128, 128};
	uint8_t few[6][3];
	for (int q = 0; q < 6; q++)
		for (int c = 0; c < 3; c++)
			few[q][c] = (uint8_t)next();
	for (uint64_t i = 0; i < n; i++) {
		uint8_t *x = rgb + 3 * i;
		if (next() % 300 == 0)
			for (int c = 0; c < 3; c++)
				a[c] = next() % 256;
		for (int c = 0; c < 3; c++) {
			switch (kind) {
			case 0: x[c] = (uint8_t)next(); break;
			case 1: x[c] = few[(i / 37 + (next() % 4 == 0)) % 6][c]; break;
			case 2: x[c] = clamp8(a[c] + 60 * sin(i * 0.003 + 2 * c)); break;
			default: x[c] = clamp8(a[c] + (double)(next() % 9) - 4);
			}
		}
	}
}

/* Opens `name`, decodes everything and a sample at random, and checks
 * every colour against the originals: within `et` (0: equal). */
static int many_big; /* check_file: a batch over 2^20 lookups too */
static void check_file(const char *name, int cells, uint8_t *const *rgb,
		       const uint64_t *n, double et)
{
	char path[256];
	path_of(path, sizeof path, name);
	struct vd_cpack *c;
	CHECK_EQ(vd_cpack_open(&c, path), VD_OK);
	if (!c)
		return;
	uint64_t total = 0;
	for (int k = 0; k < cells; k++)
		total += n[k];
	CHECK_EQ(vd_cpack_voxels(c), total);
	CHECK_EQ(vd_cpack_method(c), VD_CPACK_AUTO);
	uint8_t *all = malloc(3 * total);
	CHECK_EQ(vd_cpack_decode(c, 0, total, all), VD_OK);
	uint64_t bad = 0, ra_bad = 0, i = 0;
	for (int k = 0; k < cells; k++)
		for (uint64_t j = 0; j < n[k]; j++, i++) {
			const uint8_t *o = rgb[k] + 3 * j, *d = all + 3 * i;
			if (et == 0)
				bad += memcmp(o, d, 3) != 0;
			else
				bad += sqrt((double)vd_rgb_dist2(o, d)) / 255 >
				       et + 1e-12;
			if (j % 5 == 0 || j + 1 == n[k]) {
				uint8_t one[3];
				CHECK_EQ(vd_cpack_colour(c, i, one), VD_OK);
				ra_bad += memcmp(one, d, 3) != 0;
			}
		}
	CHECK_EQ(bad, 0);
	CHECK_EQ(ra_bad, 0);
	/* batched: the same colours as the full decode, in any order */
	CHECK_EQ(test_cpack_many_bad(c, all, total, many_big, &rng), 0);
	/* ranges that start and end inside blocks (a coded block is decoded
	 * whole for them) */
	for (uint64_t f = total / 7, k = 0; k < 3 && f < total; k++, f += total / 5 + 13) {
		uint64_t m = total - f < 777 ? total - f : 777;
		uint8_t *part = malloc(3 * m);
		CHECK_EQ(vd_cpack_decode(c, f, m, part), VD_OK);
		CHECK(!memcmp(part, all + 3 * f, 3 * m));
		free(part);
	}
	uint8_t x[3];
	CHECK_EQ(vd_cpack_colour(c, total, x), VD_ERR_RANGE);
	free(all);
	vd_cpack_free(c);
}

static const double ets[] = {0, 0.025, 0.038, 0.05, 0.1, 0.5};

static void test_random_arrays(void)
{
	/* three cells, the second over a segment, lengths not multiples of
	 * any block */
	uint64_t n[3] = {3001, VD_CPACK_SEGMENT_MAX + 777, 95};
	uint8_t *rgb[3];
	for (int kind = 0; kind < 4; kind++) {
		for (int c = 0; c < 3; c++) {
			rgb[c] = malloc(3 * n[c]);
			make_array(rgb[c], n[c], kind);
		}
		for (size_t e = 0; e < sizeof ets / sizeof *ets; e++)
			for (int bl = 4; bl <= 12; bl += 4) {
				struct vd_auto_params p = {.max_error = ets[e],
							   .block_log = bl};
				CHECK_EQ(write_cells("r.auto", &p, 3, rgb, n), VD_OK);
				check_file("r.auto", 3, rgb, n, ets[e]);
			}
		/* lossless with coded segments (1.2): equal, every kind */
		for (int bl = 4; bl <= 12; bl += 2) {
			struct vd_auto_params p = {.block_log = bl, .coded = 1};
			CHECK_EQ(write_cells("r.auto", &p, 3, rgb, n), VD_OK);
			check_file("r.auto", 3, rgb, n, 0);
		}
		for (int c = 0; c < 3; c++)
			free(rgb[c]);
	}
}

/* The lossy modes must be used and must keep their promise on data made
 * for them: every decoded colour of gradients with noise at each
 * error, block by block through vd_auto_segment_colour. */
static void test_segment_bounds(void)
{
	uint32_t n = 50000;
	uint8_t *rgb = malloc(3 * (size_t)n);
	make_array(rgb, n, 3);
	uint64_t used[5] = {0};
	for (size_t e = 1; e < sizeof ets / sizeof *ets; e++) {
		struct vd_auto_segment s;
		struct vd_auto_params p = {.max_error = ets[e]};
		CHECK_EQ(vd_auto_encode(&s, rgb, n, &p), VD_OK);
		unsigned limit = vd_colour_error_limit(ets[e]), worst = 0;
		uint64_t sse = 0;
		for (uint32_t i = 0; i < n; i++) {
			uint8_t o[3];
			vd_auto_segment_colour(&s, 0, i, o);
			unsigned d = vd_rgb_dist2(o, rgb + 3 * i);
			worst = d > worst ? d : worst;
			sse += d;
		}
		CHECK(worst <= limit);
		CHECK_EQ(worst, s.max_dist2);
		CHECK_EQ(sse, s.sse);
		for (int m = 0; m < 5; m++)
			used[m] += s.mode_blocks[m];
		vd_auto_segment_release(&s);
	}
	/* small noise: quantised blocks at small errors, endpoints or
	 * constant at large ones */
	CHECK(used[VD_AUTO_QUANT >> 4] > 0);
	CHECK(used[VD_AUTO_ENDPOINTS >> 4] + used[VD_AUTO_CONST >> 4] > 0);
	free(rgb);
}

/* ---------------------------------------------------- the expected mode */

static unsigned mode_of(const uint8_t *rgb, uint32_t n, double et)
{
	struct vd_auto_segment s;
	struct vd_auto_params p = {.max_error = et};
	CHECK_EQ(vd_auto_encode(&s, rgb, n, &p), VD_OK);
	unsigned m = s.count == 1 ? s.dir[0] >> 24 & 0xf0 : 0xff;
	vd_auto_segment_release(&s);
	return m;
}

static void test_mode_choice(void)
{
	uint8_t b[256 * 3];
	/* constant */
	for (int i = 0; i < 256; i++)
		b[3 * i] = 7, b[3 * i + 1] = 99, b[3 * i + 2] = 201;
	CHECK_EQ(mode_of(b, 256, 0), VD_AUTO_CONST);
	CHECK_EQ(mode_of(b, 256, 0.05), VD_AUTO_CONST);
	/* nearly constant (within 0.05): constant when lossy */
	for (int i = 0; i < 256; i++)
		b[3 * i] = (uint8_t)(7 + i % 3);
	CHECK_EQ(mode_of(b, 256, 0.05), VD_AUTO_CONST);
	/* two colours, scattered: a palette of two */
	for (int i = 0; i < 256; i++) {
		int k = (i * 37 + i / 5) % 3 == 0;
		b[3 * i] = k ? 13 : 250, b[3 * i + 1] = k ? 77 : 3,
		b[3 * i + 2] = k ? 190 : 31;
	}
	CHECK_EQ(mode_of(b, 256, 0), VD_AUTO_PALETTE);
	/* lossy, RGB565 endpoints hold both within 0.025 in 2 bytes less */
	CHECK_EQ(mode_of(b, 256, 0.025), VD_AUTO_ENDPOINTS);
	/* three colours off any line: a palette, lossless or not */
	for (int i = 0; i < 256; i += 3)
		b[3 * i] = 120, b[3 * i + 1] = 240, b[3 * i + 2] = 5;
	CHECK_EQ(mode_of(b, 256, 0), VD_AUTO_PALETTE);
	CHECK_EQ(mode_of(b, 256, 0.025), VD_AUTO_PALETTE);
	/* a gradient: endpoints */
	for (int i = 0; i < 256; i++)
		b[3 * i] = (uint8_t)i, b[3 * i + 1] = (uint8_t)(255 - i),
		b[3 * i + 2] = (uint8_t)(40 + i / 2);
	CHECK_EQ(mode_of(b, 256, 0.025), VD_AUTO_ENDPOINTS);
	/* full-range noise, lossless: raw */
	for (int i = 0; i < 768; i++)
		b[i] = (uint8_t)next();
	CHECK_EQ(mode_of(b, 256, 0), VD_AUTO_RAW);
	/* small noise around a colour, lossless: quantised offsets */
	for (int i = 0; i < 256; i++)
		for (int c = 0; c < 3; c++)
			b[3 * i + c] = (uint8_t)(100 + 40 * c + next() % 8);
	CHECK_EQ(mode_of(b, 256, 0), VD_AUTO_QUANT);
}

/* --------------------------------------------- a real scene, via the DAG */

static void test_spider(void)
{
	struct vd_voxelize_opts vo = {.levels = 8, .chunk_level = 0,
				      .mem_budget_bytes = 1ull << 30,
				      .threads = 2, .quiet = 1, .tool = "test",
				      .colours = 1};
	struct vd_voxelize_result r;
	CHECK_EQ(vd_voxelize_mesh("tests/data/spider/spider.obj", dir, &vo, &r),
		 VD_OK);
	struct vd_svo svo;
	struct vd_chunk_header sh;
	char name[64], path[800];
	vd_chunk_file_name(name, sizeof name, 0, 0, "svo");
	snprintf(path, sizeof path, "%s/%s", dir, name);
	if (vd_svo_load(&svo, &sh, path) != VD_OK) {
		CHECK(0);
		return;
	}
	vd_chunk_file_name(name, sizeof name, 0, 0, "col");
	snprintf(path, sizeof path, "%s/%s", dir, name);
	struct vd_colours col;
	struct vd_chunk_header h;
	CHECK_EQ(vd_colours_load(&col, &h, path), VD_OK);
	uint8_t *cells[1] = {col.rgb};
	uint64_t n[1] = {col.voxels};
	for (size_t e = 0; e < sizeof ets / sizeof *ets; e++) {
		struct vd_auto_params p = {.max_error = ets[e]};
		CHECK_EQ(write_cells("spider.auto", &p, 1, cells, n), VD_OK);
		check_file("spider.auto", 1, cells, n, ets[e]);
	}
	struct vd_auto_params pc = {.max_error = 0, .coded = 1};
	CHECK_EQ(write_cells("spider.auto", &pc, 1, cells, n), VD_OK);
	many_big = 1;
	check_file("spider.auto", 1, cells, n, 0);
	many_big = 0;
	/* through the DAG: voxel i of the SVO's depth-first (Morton) order
	 * has colour i of the chunk; its index comes from the path (the
	 * coded file, the slower lookup) */
	struct vd_auto_params p = {.max_error = 0, .coded = 1};
	CHECK_EQ(write_cells("spider.auto", &p, 1, cells, n), VD_OK);
	path_of(path, sizeof path, "spider.auto");
	struct vd_cpack *c;
	CHECK_EQ(vd_cpack_open(&c, path), VD_OK);
	struct vd_dag_opts o = {.threads = 2};
	struct vd_dag d;
	CHECK_EQ(vd_dag_from_svo(&d, &svo, VD_KIND_SSVDAG, &o, NULL), VD_OK);
	struct vd_voxcount vc;
	CHECK_EQ(vd_voxcount_from_dag(&vc, &d), VD_OK);
	uint64_t i = 0, bad = 0;
	for (size_t k = 0; k < svo.count && c; k++)
		for (int b = 0; b < 64; b++) {
			if (!(svo.masks[k] >> b & 1))
				continue;
			uint32_t x, y, z;
			vd_morton3_decode(svo.keys[k] << 6 | (uint64_t)b, &x, &y, &z);
			uint64_t idx = ~0ull;
			uint8_t rgb[3] = {0, 0, 0};
			if (vd_voxcount_index(&vc, 8, x, y, z, &idx) != 1 ||
			    vd_cpack_colour(c, idx, rgb) != VD_OK ||
			    memcmp(rgb, col.rgb + 3 * i, 3))
				bad++;
			i++;
		}
	CHECK_EQ(i, col.voxels);
	CHECK_EQ(bad, 0);
	vd_voxcount_release(&vc);
	vd_dag_release(&d);
	vd_cpack_free(c);
	vd_colours_release(&col);
	vd_svo_release(&svo);
}

/* --------------------------------------------------------- bad input */

/* Every truncation and a flipped byte every few are refused. */
static void test_damaged(void)
{
	uint8_t rgb[216];
	golden_array(rgb);
	uint8_t *cells[1] = {rgb};
	uint64_t n[1] = {72};
	struct vd_auto_params p = {.max_error = 0, .block_log = 4};
	CHECK_EQ(write_cells("d.auto", &p, 1, cells, n), VD_OK);
	size_t len = 0;
	char path[256];
	path_of(path, sizeof path, "d.auto");
	uint8_t *b = (uint8_t *)test_slurp(path, &len);
	CHECK(b != NULL);
	if (!b)
		return;
	struct vd_cpack *c;
	CHECK_EQ(vd_cpack_open_mem(&c, b, len), VD_OK);
	vd_cpack_free(c);
	int accepted = test_cpack_damage_accepted(b, len, 2, 0x10);
	CHECK_EQ(accepted, 0);
	free(b);
	/* the same for the coded example (1.2) */
	uint8_t rgb2[3072];
	golden2_array(rgb2);
	uint8_t *cells2[1] = {rgb2};
	uint64_t n2[1] = {1024};
	struct vd_auto_params p2 = {.block_log = 6, .coded = 1};
	CHECK_EQ(write_cells("d2.auto", &p2, 1, cells2, n2), VD_OK);
	path_of(path, sizeof path, "d2.auto");
	b = (uint8_t *)test_slurp(path, &len);
	CHECK(b != NULL);
	if (!b)
		return;
	CHECK_EQ(vd_cpack_open_mem(&c, b, len), VD_OK);
	vd_cpack_free(c);
	CHECK_EQ(test_cpack_damage_accepted(b, len, 7, 0x10), 0);
	free(b);
}

/* A file with good checksums but the given sections, written directly:
 * the structural checks must refuse what the checksums cannot. */
static int open_crafted_x(uint32_t block_log, uint64_t voxels,
			  const uint32_t *dirs, uint32_t nb, const uint8_t *data,
			  size_t nd, uint32_t flags, double et)
{
	char path[256];
	path_of(path, sizeof path, "c.auto");
	uint8_t par[64] = {0}, seg[40] = {0}, blk[64];
	le_put32(par, VD_CPACK_AUTO);
	le_put32(par + 4, block_log);
	le_put64(par + 8, voxels);
	le_put64(par + 16, 1);
	le_put64(par + 24, nb);
	uint64_t etb;
	memcpy(&etb, &et, 8);
	le_put64(par + 32, etb);
	le_put32(par + 48, flags);
	le_put32(seg + 36, (uint32_t)voxels);
	for (uint32_t k = 0; k < nb; k++)
		le_put32(blk + 4 * k, dirs[k]);
	const uint32_t tags[4] = {VD_TAG('C', 'P', 'A', 'R'), VD_TAG('C', 'S', 'E', 'G'),
				  VD_TAG('A', 'B', 'L', 'K'), VD_TAG('A', 'D', 'A', 'T')};
	const void *const d[4] = {par, seg, blk, data};
	const size_t len[4] = {64, 40, 4 * (size_t)nb, nd};
	return test_cpack_crafted(path, &tr, voxels, 4, tags, d, len);
}

static int open_crafted(uint32_t block_log, uint64_t voxels,
			const uint32_t *dirs, uint32_t nb, const uint8_t *data,
			size_t nd)
{
	return open_crafted_x(block_log, voxels, dirs, nb, data, nd, 0, 0);
}

/* Coded segments (1.2): a table or a block that breaks a rule is
 * refused however good the checksums. */
/* Lookups in coded blocks start at the reader's restart point at or
 * before the voxel (VD_AUTO_RESTART, colour_pack.c): every voxel of
 * blocks where runs of one colour start before a restart point and end
 * at, just before or after later ones, and where noise and a few
 * alternating colours (the recent list's hits) cross them, looked up
 * one by one and compared with the array. */
static void test_coded_restart(void)
{
	uint64_t n[1] = {4 * 512 + 77};
	uint8_t *rgb = malloc(3 * n[0]);
	uint32_t s = 7;
	for (uint64_t i = 0; i < n[0]; i++) {
		uint32_t j = (uint32_t)(i % 512), blk = (uint32_t)(i / 512);
		uint8_t *x = rgb + 3 * i;
		/* block b: a run over [40 + 7b, 40 + 7b + 64 (b + 1) + b), so
		 * its end falls on, before and after restart points */
		uint32_t r0 = 40 + 7 * blk, r1 = r0 + 64 * (blk + 1) + blk;
		s = s * 1103515245u + 12345u;
		if (j >= r0 && j < r1) {
			x[0] = 9, x[1] = 99, x[2] = (uint8_t)blk;
		} else if (j % 128 < 30) {
			static const uint8_t few[3][3] = {
				{1, 2, 3}, {200, 10, 40}, {60, 61, 62}};
			memcpy(x, few[(s >> 20) % 3], 3);
		} else {
			x[0] = (uint8_t)(s >> 16);
			x[1] = (uint8_t)(x[0] + (s >> 28));
			x[2] = (uint8_t)(s >> 24);
		}
	}
	uint8_t *cells[1] = {rgb};
	for (int bl = 6; bl <= 9; bl++) {
		struct vd_auto_params p = {.block_log = bl, .coded = 1};
		CHECK_EQ(write_cells("restart.auto", &p, 1, cells, n), VD_OK);
		char path[256];
		path_of(path, sizeof path, "restart.auto");
		struct vd_cpack *c;
		CHECK_EQ(vd_cpack_open(&c, path), VD_OK);
		uint64_t bad = 0;
		for (uint64_t i = 0; c && i < n[0]; i++) {
			uint8_t o[3] = {0, 0, 0};
			CHECK_EQ(vd_cpack_colour(c, i, o), VD_OK);
			bad += memcmp(o, rgb + 3 * i, 3) != 0;
		}
		CHECK_EQ(bad, 0);
		/* batched, in random order: the decoder going on from the
		 * previous voxel asked of the block or from a restart point */
		if (c)
			CHECK_EQ(test_cpack_many_bad(c, rgb, n[0], 0, &rng), 0);
		vd_cpack_free(c);
	}
	free(rgb);
}

static void test_coded_inconsistent(void)
{
	enum { T = VD_AUTO_TABLE_BYTES, ND = sizeof golden2_data };
	static uint8_t d[ND + 64];
	uint32_t g[16];
	memcpy(g, golden2_dir, sizeof g);
	memcpy(d, golden2_data, ND);
	CHECK_EQ(open_crafted_x(6, 1024, g, 16, d, ND, 1, 0), VD_OK);
	/* without the flag the table is not expected; flags unknown; the
	 * flag with a lossy max error */
	CHECK_EQ(open_crafted_x(6, 1024, g, 16, d, ND, 0, 0), VD_ERR_CORRUPT);
	CHECK_EQ(open_crafted_x(6, 1024, g, 16, d, ND, 2, 0), VD_ERR_CORRUPT);
	CHECK_EQ(open_crafted_x(6, 1024, g, 16, d, ND, 1, 0.05), VD_ERR_CORRUPT);
	/* a table of another size */
	d[0] = (uint8_t)(T - 1);
	CHECK_EQ(open_crafted_x(6, 1024, g, 16, d, ND, 1, 0), VD_ERR_CORRUPT);
	memcpy(d, golden2_data, ND);
	/* a length over 11 bits; lengths over-filling the code space (every
	 * symbol of A after a run 1 bit long); the unused last nibble */
	d[2] |= 0x0c;
	CHECK_EQ(open_crafted_x(6, 1024, g, 16, d, ND, 1, 0), VD_ERR_CORRUPT);
	memcpy(d, golden2_data, ND);
	memset(d + 2, 0x11, VD_AUTO_SYM_A / 2);
	CHECK_EQ(open_crafted_x(6, 1024, g, 16, d, ND, 1, 0), VD_ERR_CORRUPT);
	memcpy(d, golden2_data, ND);
	d[2 + T - 1] |= 0x10;
	CHECK_EQ(open_crafted_x(6, 1024, g, 16, d, ND, 1, 0), VD_ERR_CORRUPT);
	memcpy(d, golden2_data, ND);
	/* a block's stream one byte longer than its bits (the next block
	 * moved up one byte, the data one byte longer) */
	uint32_t at = golden2_dir[15] & 0xffffff;
	uint8_t *b = d + at;
	unsigned S = b[0] | b[1] << 8;
	b[0] = (uint8_t)(S + 1), b[1] = (uint8_t)((S + 1) >> 8);
	CHECK_EQ(open_crafted_x(6, 1024, g, 16, d, ND + 1, 1, 0), VD_ERR_CORRUPT);
	memcpy(d, golden2_data, ND);
	/* a coded block in a segment without a table */
	uint8_t e[16];
	uint32_t k[1] = {0x50000002};
	memset(e, 0, sizeof e);
	e[2] = 1, e[4] = 3; /* S = 3, voxel 0 black */
	CHECK_EQ(open_crafted_x(4, 16, k, 1, e, 8, 1, 0), VD_ERR_CORRUPT);

	/* hand-made tables: at the start (context 2) only "run 1" (code 0)
	 * and "hit at position 5" or "run 16" (code 1), after a run only
	 * "run 1" */
	static uint8_t h[2 + T + 16];
	for (int bad = 0; bad < 3; bad++) {
		memset(h, 0, sizeof h);
		h[0] = (uint8_t)T, h[1] = (uint8_t)(T >> 8);
		unsigned s0 = 2 * VD_AUTO_SYM_A, s1 = s0 + (bad == 1 ? 15
					 : VD_AUTO_HIT0 - 1 + 5);
		h[2 + s0 / 2] |= (uint8_t)(1 << 4 * (s0 & 1));
		h[2 + s1 / 2] |= (uint8_t)(1 << 4 * (s1 & 1));
		h[2] |= 1; /* after a run (context 0): "run 1", code 0 */
		/* 16 voxels: voxel 0, then 15 steps of "run 1" (15 zero
		 * bits, two bytes); bad 0: the first step a hit at 5 of a
		 * list of 1; bad 1: a run of 16 past the block */
		uint8_t *q = h + 2 + T;
		q[0] = 2, q[2] = 9, q[3] = 8, q[4] = 7;
		if (bad < 2)
			q[5] = 1; /* the first step's code: 1 */
		k[0] = 0x50000000 | (2 + T);
		CHECK_EQ(open_crafted_x(4, 16, k, 1, h, 2 + T + 7, 1, 0),
			 (bad == 2 ? VD_OK : VD_ERR_CORRUPT));
	}
}

static void test_inconsistent(void)
{
	uint32_t g[5];
	memcpy(g, golden_dir, sizeof g);
	uint8_t d[96];
	memcpy(d, golden_data, 90);
	/* the example itself is accepted */
	CHECK_EQ(open_crafted(4, 72, g, 5, d, 90), VD_OK);
	/* block size out of range; another block size than the data */
	CHECK_EQ(open_crafted(13, 72, g, 5, d, 90), VD_ERR_CORRUPT);
	CHECK_EQ(open_crafted(5, 72, g, 5, d, 90), VD_ERR_CORRUPT);
	/* one block too few or too many */
	CHECK_EQ(open_crafted(4, 72, g, 4, d, 90), VD_ERR_CORRUPT);
	CHECK_EQ(open_crafted(4, 88, g, 5, d, 90), VD_ERR_CORRUPT);
	/* data too short or too long */
	CHECK_EQ(open_crafted(4, 72, g, 5, d, 89), VD_ERR_CORRUPT);
	CHECK_EQ(open_crafted(4, 72, g, 5, d, 91), VD_ERR_CORRUPT);
	/* an unknown mode; index bits 0 and 9 */
	uint32_t k[5];
	memcpy(k, g, sizeof k);
	k[2] = 0x5000000e;
	CHECK_EQ(open_crafted(4, 72, k, 5, d, 90), VD_ERR_CORRUPT);
	memcpy(k, g, sizeof k);
	k[1] = 0x10000000;
	CHECK_EQ(open_crafted(4, 72, k, 5, d, 90), VD_ERR_CORRUPT);
	k[1] = 0x19000000;
	CHECK_EQ(open_crafted(4, 72, k, 5, d, 90), VD_ERR_CORRUPT);
	/* a block not where the earlier ones end */
	memcpy(k, g, sizeof k);
	k[3] = 0x3000003f;
	CHECK_EQ(open_crafted(4, 72, k, 5, d, 90), VD_ERR_CORRUPT);
	/* a palette index past the palette's three colours (index 3 of 2
	 * bits), then a palette size the index width does not fit */
	uint8_t e[96];
	memcpy(e, d, 90);
	e[10] |= 0x03;
	CHECK_EQ(open_crafted(4, 72, g, 5, e, 90), VD_ERR_CORRUPT);
	memcpy(e, d, 90);
	e[0] = 4; /* five colours in 2 bits */
	CHECK_EQ(open_crafted(4, 72, g, 5, e, 90), VD_ERR_CORRUPT);
	/* quantised widths over 8 bits, a step of 0 */
	memcpy(e, d, 90);
	e[62 + 4] = 0x29;
	CHECK_EQ(open_crafted(4, 72, g, 5, e, 90), VD_ERR_CORRUPT);
	memcpy(e, d, 90);
	e[62 + 3] = 0;
	CHECK_EQ(open_crafted(4, 72, g, 5, e, 90), VD_ERR_CORRUPT);
	/* endpoints parts longer than a block */
	memcpy(e, d, 90);
	e[80] = 5;
	CHECK_EQ(open_crafted(4, 72, g, 5, e, 90), VD_ERR_CORRUPT);
	/* a constant block's entry is its colour: any value is valid */
	memcpy(k, g, sizeof k);
	k[0] = 0x00ffffff;
	CHECK_EQ(open_crafted(4, 72, k, 5, d, 90), VD_OK);
}

int main(void)
{
	if (!mkdtemp(dir))
		return 1;
	float lo[3] = {0, 0, 0}, hi[3] = {1, 1, 1};
	vd_transform_init(&tr, lo, hi, 12);
	RUN(test_golden);
	RUN(test_mode_choice);
	RUN(test_segment_bounds);
	RUN(test_random_arrays);
	RUN(test_spider);
	RUN(test_damaged);
	RUN(test_inconsistent);
	RUN(test_golden_coded);
	RUN(test_coded_inconsistent);
	RUN(test_coded_restart);
	char cmd[300];
	snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
	if (system(cmd)) {
	}
	return CHECK_DONE();
}
