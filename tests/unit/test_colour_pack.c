/* test_colour_pack.c - packed colours files (schemas/colour-formats.md):
 * random access equals full decode for every method; VBR within et for
 * every voxel; palette lossless exact, K colours nearest palette members
 * (brute force); raw exact; a cell's encoding independent of its
 * neighbours (blocks never span cells); damaged and inconsistent files
 * refused with one error each. */
#include "check.h"
#include "colour_fixture.h"
#include "le.h"
#include "voxdag.h"

#include <math.h>
#include <sys/stat.h>
#include <unistd.h>

static char dir[] = "/tmp/vd_cpack_XXXXXX";
static struct vd_transform tr;

static uint64_t rng = 777;
static uint32_t next(void)
{
	return test_xorshift(&rng);
}

/* Three cells; the second larger than a segment so it splits. */
#define NCELL 3
static const uint64_t cell_n[NCELL] = {5000, VD_CPACK_SEGMENT_MAX + 4321, 777};
static uint8_t *cell_rgb[NCELL];

static void make_cells(void)
{
	for (int c = 0; c < NCELL; c++) {
		cell_rgb[c] = malloc(3 * cell_n[c]);
		double a[3] = {next() % 256, next() % 256, next() % 256};
		for (uint64_t i = 0; i < cell_n[c]; i++) {
			if (next() % 400 == 0)
				for (int k = 0; k < 3; k++)
					a[k] = next() % 256;
			for (int k = 0; k < 3; k++) {
				double v = a[k] + 20 * sin(i * 0.01 + k) +
					   (double)(next() % 5);
				cell_rgb[c][3 * i + k] =
					(uint8_t)(v < 0 ? 0 : v > 255 ? 255 : v);
			}
		}
	}
}

static void path_of(char *buf, size_t cap, const char *name)
{
	snprintf(buf, cap, "%s/%s", dir, name);
}

static int write_file(const char *name, const struct vd_cpack_params *p,
		      int first, int last, struct vd_cpack_stats *st)
{
	char path[256];
	path_of(path, sizeof path, name);
	struct vd_cpack_writer *w;
	int err = vd_cpack_writer_open(&w, path, p, 12, &tr, "test");
	if (err)
		return err;
	for (int c = first; c <= last && !err; c++)
		err = vd_cpack_writer_add(w, 2, (uint64_t)c * 3 + 1, cell_rgb[c],
					  cell_n[c]);
	if (err) {
		vd_cpack_writer_abort(w);
		return err;
	}
	return vd_cpack_writer_commit(w, st);
}

/* Full decode, random access and the original, voxel by voxel; `check`
 * judges each decoded colour against its original. Returns the SSE. */
static uint64_t compare(const char *name, int first, int last,
			void (*check)(const uint8_t *orig, const uint8_t *dec,
				      void *ctx),
			void *ctx)
{
	char path[256];
	path_of(path, sizeof path, name);
	struct vd_cpack *c;
	CHECK_EQ(vd_cpack_open(&c, path), VD_OK);
	if (!c)
		return 0;
	uint64_t total = 0;
	for (int k = first; k <= last; k++)
		total += cell_n[k];
	CHECK_EQ(vd_cpack_voxels(c), total);
	uint8_t *all = malloc(3 * total);
	CHECK_EQ(vd_cpack_decode(c, 0, total, all), VD_OK);
	uint64_t i = 0, sse = 0, ra_bad = 0;
	for (int k = first; k <= last; k++)
		for (uint64_t j = 0; j < cell_n[k]; j++, i++) {
			uint8_t one[3];
			/* random access on a sample of voxels: every 7th and
			 * every segment's edges */
			if (j % 7 == 0 || j % VD_CPACK_SEGMENT_MAX < 2 ||
			    j + 1 == cell_n[k]) {
				CHECK_EQ(vd_cpack_colour(c, i, one), VD_OK);
				ra_bad += memcmp(one, all + 3 * i, 3) != 0;
			}
			check(cell_rgb[k] + 3 * j, all + 3 * i, ctx);
			sse += vd_rgb_dist2(cell_rgb[k] + 3 * j, all + 3 * i);
		}
	CHECK_EQ(ra_bad, 0);
	/* batched lookups give the same colours, in any order */
	uint64_t seed = 99;
	CHECK_EQ(test_cpack_many_bad(c, all, total, 0, &seed), 0);
	/* a range decode from the middle agrees too */
	if (total > 1000) {
		uint8_t mid[300];
		CHECK_EQ(vd_cpack_decode(c, total / 2, 100, mid), VD_OK);
		CHECK(!memcmp(mid, all + 3 * (total / 2), 300));
	}
	uint8_t x[3];
	CHECK_EQ(vd_cpack_colour(c, total, x), VD_ERR_RANGE);
	CHECK_EQ(vd_cpack_decode(c, total - 1, 2, all), VD_ERR_RANGE);
	free(all);
	vd_cpack_free(c);
	return sse;
}

static int bad_count;
static double check_et;

static void within_et(const uint8_t *o, const uint8_t *d, void *ctx)
{
	double e = sqrt((double)vd_rgb_dist2(o, d)) / 255;
	bad_count += e > check_et + 1e-12;
}

static void exact(const uint8_t *o, const uint8_t *d, void *ctx)
{
	bad_count += memcmp(o, d, 3) != 0;
}

/* decoded must be a palette colour at the smallest distance any palette
 * colour has (brute force over the palette) */
static uint64_t nearest_calls;

static void nearest(const uint8_t *o, const uint8_t *d, void *ctx)
{
	const struct vd_palette *p = ctx;
	if (nearest_calls++ % 5) /* every fifth voxel: K * N is large */
		return;
	unsigned best = UINT32_MAX;
	int member = 0;
	for (uint32_t k = 0; k < p->k; k++) {
		unsigned e = vd_rgb_dist2(o, p->rgb + 3 * k);
		if (e < best)
			best = e;
		member |= !memcmp(d, p->rgb + 3 * k, 3);
	}
	bad_count += !member || vd_rgb_dist2(o, d) != best;
}

static void test_vbr_file(void)
{
	static const double ets[] = {0.025, 0.1};
	for (int e = 0; e < 2; e++) {
		struct vd_cpack_params p = {.method = VD_CPACK_VBR,
					    .vbr = {.max_error = ets[e],
						    .weight_bits = 3},
					    .threads = 2};
		struct vd_cpack_stats st;
		CHECK_EQ(write_file("a.vbr", &p, 0, NCELL - 1, &st), VD_OK);
		CHECK_EQ(st.segments, 4); /* 1 + 2 + 1 */
		bad_count = 0;
		check_et = ets[e];
		uint64_t sse = compare("a.vbr", 0, NCELL - 1, within_et, NULL);
		CHECK_EQ(bad_count, 0);
		CHECK_EQ(sse, st.sse);
		/* the structure's size from its parts: 40 per segment, 8 per
		 * block, the weights byte-aligned per segment */
		uint64_t wbytes = 0;
		for (int c = 0; c < NCELL; c++)
			for (uint64_t f = 0; f < cell_n[c]; f += VD_CPACK_SEGMENT_MAX) {
				uint64_t n = cell_n[c] - f < VD_CPACK_SEGMENT_MAX
						     ? cell_n[c] - f
						     : VD_CPACK_SEGMENT_MAX;
				wbytes += (3 * n + 7) / 8;
			}
		CHECK_EQ(st.bytes, 40 * 4 + 8 * st.blocks + wbytes);
		char path[256];
		path_of(path, sizeof path, "a.vbr");
		struct vd_cpack *c;
		CHECK_EQ(vd_cpack_open(&c, path), VD_OK);
		CHECK_EQ(vd_cpack_bytes(c), st.bytes);
		CHECK_EQ(vd_cpack_blocks(c), st.blocks);
		CHECK_EQ(vd_cpack_method(c), VD_CPACK_VBR);
		vd_cpack_free(c);
	}
}

/* Blocks never span a cell: each cell written alone decodes to the same
 * colours as inside the whole file, and the blocks add up. */
static void test_cells_independent(void)
{
	struct vd_cpack_params p = {.method = VD_CPACK_VBR,
				    .vbr = {.max_error = 0.05, .weight_bits = 3},
				    .threads = 1};
	struct vd_cpack_stats all, one;
	CHECK_EQ(write_file("all.vbr", &p, 0, NCELL - 1, &all), VD_OK);
	char path[256];
	path_of(path, sizeof path, "all.vbr");
	struct vd_cpack *a;
	CHECK_EQ(vd_cpack_open(&a, path), VD_OK);
	uint64_t blocks = 0, off = 0;
	for (int c = 0; c < NCELL && a; c++) {
		CHECK_EQ(write_file("one.vbr", &p, c, c, &one), VD_OK);
		blocks += one.blocks;
		path_of(path, sizeof path, "one.vbr");
		struct vd_cpack *o;
		CHECK_EQ(vd_cpack_open(&o, path), VD_OK);
		uint8_t *x = malloc(3 * cell_n[c]), *y = malloc(3 * cell_n[c]);
		CHECK_EQ(vd_cpack_decode(o, 0, cell_n[c], x), VD_OK);
		CHECK_EQ(vd_cpack_decode(a, off, cell_n[c], y), VD_OK);
		CHECK(!memcmp(x, y, 3 * cell_n[c]));
		off += cell_n[c];
		free(x);
		free(y);
		vd_cpack_free(o);
	}
	CHECK_EQ(blocks, all.blocks);
	vd_cpack_free(a);
	/* cells out of order are refused */
	path_of(path, sizeof path, "bad.vbr");
	struct vd_cpack_writer *w;
	CHECK_EQ(vd_cpack_writer_open(&w, path, &p, 12, &tr, NULL), VD_OK);
	CHECK_EQ(vd_cpack_writer_add(w, 2, 5, cell_rgb[2], 10), VD_OK);
	CHECK_EQ(vd_cpack_writer_add(w, 2, 5, cell_rgb[2], 10), VD_ERR_ARG);
	vd_cpack_writer_abort(w);
	CHECK(access(path, F_OK) != 0);
}

static void build_palette(struct vd_palette *p, uint32_t k, int lossless)
{
	struct vd_colour_hist h;
	CHECK_EQ(vd_colour_hist_init(&h), VD_OK);
	for (int c = 0; c < NCELL; c++)
		vd_colour_hist_add(&h, cell_rgb[c], cell_n[c]);
	CHECK_EQ(vd_palette_build(p, &h, k, lossless, 1), VD_OK);
	vd_colour_hist_release(&h);
}

static void test_palette_lossless(void)
{
	struct vd_palette pal;
	build_palette(&pal, 256, 1);
	CHECK(pal.lossless);
	struct vd_cpack_params p = {.method = VD_CPACK_PALETTE, .palette = &pal,
				    .palette_colours = 256};
	struct vd_cpack_stats st;
	CHECK_EQ(write_file("a.pal", &p, 0, NCELL - 1, &st), VD_OK);
	bad_count = 0;
	CHECK_EQ(compare("a.pal", 0, NCELL - 1, exact, NULL), 0);
	CHECK_EQ(bad_count, 0);
	CHECK_EQ(st.sse, 0);
	CHECK(st.palettes <= st.blocks);
	vd_palette_release(&pal);
}

static void test_palette_k(void)
{
	static const uint32_t ks[] = {256, 2048};
	for (int i = 0; i < 2; i++) {
		struct vd_palette pal;
		build_palette(&pal, ks[i], 0);
		CHECK(!pal.lossless && pal.k <= ks[i] && pal.k > ks[i] / 2);
		/* the map agrees with the brute-force nearest distance */
		struct vd_cpack_params p = {.method = VD_CPACK_PALETTE,
					    .palette = &pal,
					    .palette_colours = ks[i]};
		struct vd_cpack_stats st;
		CHECK_EQ(write_file("k.pal", &p, 0, NCELL - 1, &st), VD_OK);
		bad_count = 0;
		uint64_t sse = compare("k.pal", 0, NCELL - 1, nearest, &pal);
		CHECK_EQ(bad_count, 0);
		CHECK_EQ(sse, st.sse);
		printf("  K %u: %llu blocks, %llu block palettes, %.1f%% of raw, "
		       "GMSE %.2f\n", ks[i], (unsigned long long)st.blocks,
		       (unsigned long long)st.palettes,
		       100.0 * st.bytes / (3.0 * st.voxels),
		       (double)st.sse / st.voxels);
		vd_palette_release(&pal);
	}
}

/* The global palette's map against the brute-force nearest colour
 * (vd_palette_nearest: least squared distance, ties to the lower index),
 * index for index, over every colour the histogram saw: clustered and
 * spread colours, palettes from sparse (256) to dense (16K), where the
 * search visits few or many cells. */
static void test_palette_map_exact(void)
{
	static const uint32_t ks[] = {256, 2048, 16384};
	uint64_t r = 99;
	uint32_t n = 60000;
	uint8_t *rgb = malloc(3 * (size_t)n);
	CHECK(rgb != NULL);
	for (uint32_t i = 0; i < n; i++) {
		r ^= r << 13, r ^= r >> 7, r ^= r << 17;
		/* half in a few tight clusters (ties and near ties), half
		 * anywhere in the cube */
		int spread = i % 2 ? 256 : 12;
		for (int k = 0; k < 3; k++) {
			unsigned base = i % 2 ? 0 : (unsigned)(i / 2 % 7) * 36;
			rgb[3 * i + k] = (uint8_t)(base + (r >> (8 * k + 5)) % spread);
		}
	}
	for (int t = 0; t < 3; t++) {
		struct vd_colour_hist h;
		CHECK_EQ(vd_colour_hist_init(&h), VD_OK);
		vd_colour_hist_add(&h, rgb, n);
		struct vd_palette pal;
		CHECK_EQ(vd_palette_build(&pal, &h, ks[t], 0, 1), VD_OK);
		CHECK(!pal.lossless);
		uint32_t bad = 0;
		for (uint32_t i = 0; i < n; i++) {
			const uint8_t *x = rgb + 3 * i;
			uint32_t c = (uint32_t)x[0] << 16 | (uint32_t)x[1] << 8 | x[2];
			bad += pal.index[c] != vd_palette_nearest(&pal, x);
		}
		CHECK_EQ(bad, 0);
		vd_palette_release(&pal);
		vd_colour_hist_release(&h);
	}
	free(rgb);
}

static void test_raw(void)
{
	struct vd_cpack_params p = {.method = VD_CPACK_RAW, .zstd_level = 3};
	struct vd_cpack_stats st;
	CHECK_EQ(write_file("a.raw", &p, 0, NCELL - 1, &st), VD_OK);
	bad_count = 0;
	CHECK_EQ(compare("a.raw", 0, NCELL - 1, exact, NULL), 0);
	CHECK_EQ(bad_count, 0);
}

static uint8_t *slurp(const char *name, size_t *n)
{
	char path[256];
	path_of(path, sizeof path, name);
	return (uint8_t *)test_slurp(path, n); /* NULL: the caller's CHECK */
}

/* Damage: every truncation and a flipped byte every few bytes are
 * refused (never a crash, never accepted); a colour chunk is the wrong
 * kind. */
static void test_damaged(void)
{
	struct vd_cpack_params p = {.method = VD_CPACK_VBR,
				    .vbr = {.max_error = 0.1, .weight_bits = 3}};
	CHECK_EQ(write_file("s.vbr", &p, 2, 2, NULL), VD_OK);
	struct vd_palette pal;
	build_palette(&pal, 64, 0);
	struct vd_cpack_params q = {.method = VD_CPACK_PALETTE, .palette = &pal};
	CHECK_EQ(write_file("s.pal", &q, 2, 2, NULL), VD_OK);
	vd_palette_release(&pal);
	static const char *const names[] = {"s.vbr", "s.pal"};
	for (int f = 0; f < 2; f++) {
		size_t n = 0;
		uint8_t *b = slurp(names[f], &n);
		CHECK(b != NULL);
		struct vd_cpack *c;
		CHECK_EQ(vd_cpack_open_mem(&c, b, n), VD_OK);
		vd_cpack_free(c);
		int accepted = test_cpack_damage_accepted(b, n, 3, 0x20);
		CHECK_EQ(accepted, 0);
		free(b);
	}
	char path[256];
	path_of(path, sizeof path, "x.col");
	struct vd_chunk_header h = {.kind = VD_KIND_SVO, .levels = 4,
				    .chunk_level = 1, .level_count = 4,
				    .transform = tr};
	h.level_nodes[3] = 2;
	uint8_t rgb[6] = {1, 2, 3, 4, 5, 6};
	CHECK_EQ(vd_colours_save(path, &h, 1, rgb, 2, NULL), VD_OK);
	struct vd_cpack *c;
	CHECK_EQ(vd_cpack_open(&c, path), VD_ERR_WRONG_KIND);
}

struct crafted {
	uint32_t voxels, seg_n, seg_first, blocks, b1_start, wbytes;
	uint64_t header_voxels;
	uint32_t method, wbits;
};

static int open_crafted(const struct crafted *k)
{
	char path[256];
	path_of(path, sizeof path, "c.vbr");
	uint8_t par[64] = {0}, seg[40] = {0}, blk[16] = {0}, wgt[64] = {0};
	le_put32(par, k->method);
	le_put32(par + 4, k->wbits);
	le_put64(par + 8, k->voxels);
	le_put64(par + 16, 1);
	le_put64(par + 24, k->blocks);
	le_put64(seg, k->seg_first);
	le_put32(seg + 36, k->seg_n);
	le_put32(blk + 8, k->b1_start);
	const uint32_t tags[4] = {VD_TAG('C', 'P', 'A', 'R'), VD_TAG('C', 'S', 'E', 'G'),
				  VD_TAG('V', 'B', 'L', 'K'), VD_TAG('V', 'W', 'G', 'T')};
	const void *const d[4] = {par, seg, blk, wgt};
	const size_t len[4] = {64, 40, 8 * (size_t)k->blocks, k->wbytes};
	return test_cpack_crafted(path, &tr, k->header_voxels, 4, tags, d, len);
}

static void test_inconsistent(void)
{
	/* a good one first: 10 voxels, one segment, two blocks, 30 bits */
	struct crafted good = {.voxels = 10, .seg_n = 10, .blocks = 2,
			       .b1_start = 4, .wbytes = 4, .header_voxels = 10,
			       .method = 1, .wbits = 3};
	CHECK_EQ(open_crafted(&good), VD_OK);
	struct crafted k = good;
	k.header_voxels = 11;
	CHECK_EQ(open_crafted(&k), VD_ERR_CORRUPT);
	k = good, k.seg_n = 9;
	CHECK_EQ(open_crafted(&k), VD_ERR_CORRUPT);
	k = good, k.seg_first = 1;
	CHECK_EQ(open_crafted(&k), VD_ERR_CORRUPT);
	k = good, k.b1_start = 0; /* blocks not increasing */
	CHECK_EQ(open_crafted(&k), VD_ERR_CORRUPT);
	k = good, k.b1_start = 10; /* a block past its segment */
	CHECK_EQ(open_crafted(&k), VD_ERR_CORRUPT);
	k = good, k.wbytes = 3;
	CHECK_EQ(open_crafted(&k), VD_ERR_CORRUPT);
	k = good, k.wbytes = 5;
	CHECK_EQ(open_crafted(&k), VD_ERR_CORRUPT);
	k = good, k.wbits = 9;
	CHECK_EQ(open_crafted(&k), VD_ERR_CORRUPT);
	k = good, k.method = 7;
	CHECK_EQ(open_crafted(&k), VD_ERR_UNSUPPORTED);
}

int main(void)
{
	if (!mkdtemp(dir))
		return 1;
	float lo[3] = {0, 0, 0}, hi[3] = {1, 1, 1};
	vd_transform_init(&tr, lo, hi, 12);
	make_cells();
	RUN(test_vbr_file);
	RUN(test_cells_independent);
	RUN(test_palette_lossless);
	RUN(test_palette_k);
	RUN(test_palette_map_exact);
	RUN(test_raw);
	RUN(test_damaged);
	RUN(test_inconsistent);
	for (int c = 0; c < NCELL; c++)
		free(cell_rgb[c]);
	char cmd[300];
	snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
	if (system(cmd)) {
	}
	return CHECK_DONE();
}
