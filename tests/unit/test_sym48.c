/* test_sym48.c - symmetry-merge --group 48: the subgroup and leaf tables,
 * brick canonical forms, and minimality of the ssvdag48 against brute
 * force (every subtree of every level expanded to its voxels, moved by all
 * 48 transforms through coordinate arithmetic written here from the
 * header's definition, classes counted) on synthetic scenes with every
 * kind of symmetry and on a real mesh; lossless expansion, merges of
 * mixed parts, the chunk file round trip. */
#include "dag_test_util.h"
#include "scene.h"
#include "dag/dag_internal.h"

#include <unistd.h>

static struct vd_dag_opts opts = {1, 0, NULL};

/* Point p of an n-cube moved by t, from the header's definition: output
 * axis i takes input axis names[k][i], then axis i is mirrored if bit
 * 2 - i of m is set (t = 8k + m). */
static const char *names[6] = {"XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"};
static void coord(unsigned t, uint32_t n, const uint32_t p[3], uint32_t q[3])
{
	for (unsigned i = 0; i < 3; i++) {
		q[i] = p[names[t / 8][i] - 'X'];
		if (t >> (2 - i) & 1) q[i] = n - 1 - q[i];
	}
}

static uint8_t coord_mask(uint8_t v, unsigned t)
{
	uint8_t out = 0;
	for (unsigned c = 0; c < 8; c++)
		if (v >> c & 1) {
			uint32_t p[3] = {c >> 2 & 1, c >> 1 & 1, c & 1}, q[3];
			coord(t, 2, p, q);
			out |= (uint8_t)(1u << (q[0] << 2 | q[1] << 1 | q[2]));
		}
	return out;
}

static void test_subgroups(void)
{
	/* The octahedral group O_h has 98 subgroups. */
	CHECK_EQ(vd_g48_subgroup_count(), 98);
	vd__g48_init();
	for (unsigned i = 0; i < VD_G48_SUBGROUPS; i++) {
		uint64_t s = vd__g48_sub[i];
		CHECK(s & 1);
		if (i) CHECK(s > vd__g48_sub[i - 1]);
		unsigned order = 0;
		for (unsigned a = 0; a < VD_G48; a++) {
			if (!(s >> a & 1)) continue;
			order++;
			for (unsigned b = 0; b < VD_G48; b++)
				if (s >> b & 1)
					CHECK(s >> vd_g48_compose(a, b) & 1);
		}
		CHECK_EQ(48 % order, 0); /* Lagrange */
		CHECK_EQ(vd__g48_subgroup(s), i);
		/* norm is the smallest of the coset t s */
		for (unsigned t = 0; t < VD_G48; t++) {
			unsigned best = 99;
			for (unsigned g = 0; g < VD_G48; g++)
				if ((s >> g & 1) && vd_g48_compose(t, g) < best)
					best = vd_g48_compose(t, g);
			CHECK_EQ(vd__g48_norm[i][t], best);
		}
	}
}

static void test_leaf_table48(void)
{
	const struct vd_leaf_class *lt = vd_leaf_classes48();
	int classes = 0;
	for (unsigned v = 0; v < 256; v++) {
		uint8_t best = 0;
		for (unsigned t = 0; t < VD_G48; t++)
			if (coord_mask((uint8_t)v, t) > best)
				best = coord_mask((uint8_t)v, t);
		CHECK_EQ(lt[v].canon, best);
		CHECK(lt[v].refl < VD_G48);
		CHECK_EQ(coord_mask(lt[v].canon, lt[v].refl), v);
		uint64_t stab = 0;
		for (unsigned t = 0; t < VD_G48; t++)
			if (coord_mask(best, t) == best) stab |= 1ull << t;
		CHECK(lt[v].inv < VD_G48_SUBGROUPS);
		CHECK(vd__g48_sub[lt[v].inv] == stab);
		classes += best == v;
	}
	/* 2-colourings of the cube's 8 vertices under O_h, empty and full
	 * included (Burnside). */
	CHECK_EQ(classes, 22);
}

static void test_brick_canon48(void)
{
	vd__g48_init();
	for (int round = 0; round < 3000; round++) {
		uint64_t v = rnd();
		if (round % 3 == 1) v &= rnd() & rnd();
		if (round % 3 == 2) { /* symmetric: the union of an orbit part */
			uint64_t w = rnd() & rnd() & rnd();
			unsigned a = (unsigned)(rnd() % 48);
			v = w | vd_g48_brick(w, a) | vd_g48_brick(w, vd_g48_compose(a, a));
		}
		if (round < 64) v = 1ull << round;
		if (round == 64) v = ~0ull;
		uint64_t c, best = 0, stab = 0;
		uint8_t t, inv;
		vd__brick_canon48(v, &c, &t, &inv);
		for (unsigned u = 0; u < VD_G48; u++)
			if (vd_g48_brick(v, u) > best) best = vd_g48_brick(v, u);
		for (unsigned u = 0; u < VD_G48; u++)
			if (vd_g48_brick(best, u) == best) stab |= 1ull << u;
		CHECK(c == best);
		CHECK(vd_g48_brick(c, t) == v);
		CHECK(vd__g48_sub[inv] == stab);
	}
}

/* Distinct non-empty subtrees on level l of g (one cell, L0 = 0) up to the
 * first `ng` transforms (8: the reflections, 48: all), by their voxels. */
static uint64_t brute48(const struct grid *g, int l, unsigned ng)
{
	uint32_t side = g->n >> l, per = 1u << l;
	size_t bytes = ((size_t)side * side * side + 7) / 8, n = 0;
	uint8_t *all = malloc((size_t)per * per * per * bytes + 1);
	uint8_t *tmp = malloc(bytes);
	uint32_t *pts = malloc((size_t)side * side * side * 3 * 4);
	for (uint32_t cx = 0; cx < per; cx++)
		for (uint32_t cy = 0; cy < per; cy++)
			for (uint32_t cz = 0; cz < per; cz++) {
				size_t np = 0;
				for (uint32_t x = 0; x < side; x++)
					for (uint32_t y = 0; y < side; y++)
						for (uint32_t z = 0; z < side; z++)
							if (*gv((struct grid *)g, cx * side + x,
								cy * side + y, cz * side + z)) {
								pts[3 * np] = x;
								pts[3 * np + 1] = y;
								pts[3 * np++ + 2] = z;
							}
				if (!np) continue;
				uint8_t *dst = all + n++ * bytes;
				for (unsigned t = 0; t < ng; t++) {
					memset(tmp, 0, bytes);
					for (size_t i = 0; i < np; i++) {
						uint32_t q[3];
						coord(t, side, pts + 3 * i, q);
						size_t b = ((size_t)q[0] * side + q[1]) * side + q[2];
						tmp[b >> 3] |= (uint8_t)(1u << (b & 7));
					}
					if (!t || memcmp(tmp, dst, bytes) > 0)
						memcpy(dst, tmp, bytes);
				}
			}
	bf_bytes = bytes;
	qsort(all, n, bytes, bf_cmp);
	uint64_t d = 0;
	for (size_t i = 0; i < n; i++)
		if (!i || memcmp(all + i * bytes, all + (i - 1) * bytes, bytes))
			d++;
	free(all);
	free(tmp);
	free(pts);
	return d;
}

static void build(const struct grid *g, uint32_t kind, struct vd_dag *d)
{
	struct vd_svo s;
	grid_to_svo(g, 0, 0, &s);
	CHECK_EQ(vd_dag_from_svo(d, &s, kind, &opts, NULL), VD_OK);
	svo_free(&s);
	CHECK_EQ(vd_dag_validate(d), VD_OK);
}

/* Scenes beyond make_scene's: tiles of side t, each empty or one of three
 * random patterns moved by a random one of the 48 transforms; `kind`
 * shapes the patterns: 0 none, 1 invariant only under the anti-diagonal
 * mirror (x, y, z) -> (n-1-y, n-1-x, z), a permutation composed with a
 * reflection (neither alone leaves it unchanged), 2 invariant under the
 * quarter turn about Z (x, y) -> (y, n-1-x), generated by such a
 * composition, 3 invariant under the 3-cycle of the axes. */
enum { S48_PLAIN, S48_ANTIDIAG, S48_QUARTER, S48_CYCLE, S48_COUNT };

static void make_tiles48(struct grid *g, int L, int kind, uint32_t t)
{
	grid_init(g, L);
	uint32_t n = g->n;
	if (t > n) t = n;
	/* the generator of each pattern's symmetry, as a transform */
	unsigned gen = kind == S48_ANTIDIAG ? 8 * 2 + 6  /* YXZ, mirror X, Y */
		     : kind == S48_QUARTER ? 8 * 2 + 2   /* YXZ, mirror Y */
		     : kind == S48_CYCLE ? 8 * 3         /* YZX */
		     : 0;
	static uint8_t pat[3][512];
	for (int p = 0; p < 3; p++) {
		memset(pat[p], 0, sizeof pat[p]);
		for (uint32_t x = 0; x < t; x++)
			for (uint32_t y = 0; y < t; y++)
				for (uint32_t z = 0; z < t; z++) {
					if (rnd() % 5) continue;
					uint32_t a[3] = {x, y, z}, b[3];
					/* the orbit of (x, y, z) under gen */
					for (int k = 0; k < 4; k++) {
						pat[p][(a[0] * t + a[1]) * t + a[2]] = 1;
						coord(gen, t, a, b);
						memcpy(a, b, sizeof a);
					}
				}
	}
	for (uint32_t bx = 0; bx < n / t; bx++)
		for (uint32_t by = 0; by < n / t; by++)
			for (uint32_t bz = 0; bz < n / t; bz++) {
				int p = (int)(rnd() % 4);
				unsigned tr = (unsigned)(rnd() % 48);
				if (p == 3) continue;
				for (uint32_t x = 0; x < t; x++)
					for (uint32_t y = 0; y < t; y++)
						for (uint32_t z = 0; z < t; z++) {
							uint32_t a[3] = {x, y, z}, q[3];
							if (!pat[p][(x * t + y) * t + z])
								continue;
							coord(tr, t, a, q);
							*gv(g, bx * t + q[0], by * t + q[1],
							    bz * t + q[2]) = 1;
						}
			}
}

/* Checks the ssvdag48 of g: lossless, valid, per-level counts equal the
 * brute force, never more than the ssvdag; the ssvdag's counts equal the
 * 8-transform brute force. Returns how many levels the 48 beat the 8 on. */
static int check_scene(const struct grid *g, const char *what)
{
	struct vd_dag d8, d48, dag, merged;
	build(g, VD_KIND_SSVDAG, &d8);
	build(g, VD_KIND_SSVDAG48, &d48);
	build(g, VD_KIND_DAG, &dag);
	const struct vd_dag *pp[1] = {&dag};
	CHECK_EQ(vd_dag_merge(&merged, pp, 1, VD_KIND_SSVDAG48, 0, &opts, NULL),
		 VD_OK);
	CHECK(dag_matches_grid(&d48, g));
	CHECK(dag_matches_grid(&merged, g));
	CHECK_EQ(d48.voxels, grid_count(g));
	int fewer = 0;
	for (int l = 0; l < g->L; l++) {
		uint64_t b48 = brute48(g, l, 48), b8 = brute48(g, l, 8);
		/* the 8-transform count agrees with the SSVDAG tests' own
		 * brute force (reflections written separately) */
		CHECK_EQ(b8, brute_distinct(g, 0, 0, l, 1));
		if (d48.lv[l].nodes != b48 || d8.lv[l].nodes != b8)
			fprintf(stderr, "  %s L=%d level %d: 48: %llu, brute force "
				"%llu; 8: %llu, brute force %llu\n", what, g->L, l,
				(unsigned long long)d48.lv[l].nodes,
				(unsigned long long)b48,
				(unsigned long long)d8.lv[l].nodes,
				(unsigned long long)b8);
		CHECK_EQ(d48.lv[l].nodes, b48);
		CHECK_EQ(merged.lv[l].nodes, b48);
		CHECK_EQ(d8.lv[l].nodes, b8);
		fewer += b48 < b8;
	}
	vd_dag_release(&d8);
	vd_dag_release(&d48);
	vd_dag_release(&dag);
	vd_dag_release(&merged);
	return fewer;
}

static void test_minimal_synthetic(void)
{
	int fewer = 0;
	for (int L = 1; L <= 6; L++)
		for (int sc = 0; sc < SC_COUNT; sc++) {
			struct grid g;
			make_scene(&g, L, sc);
			fewer += check_scene(&g, scene_name[sc]);
			grid_free(&g);
		}
	static const char *const s48[S48_COUNT] = {
		"tiles48", "antidiagonal", "quarter-turn", "axis-cycle"};
	for (int L = 3; L <= 6; L++)
		for (int k = 0; k < S48_COUNT; k++)
			for (uint32_t t = 4; t <= 8; t *= 2) {
				struct grid g;
				make_tiles48(&g, L, k, t);
				fewer += check_scene(&g, s48[k]);
				grid_free(&g);
			}
	CHECK(fewer > 20); /* the scenes do exercise the permutations */
}

/* A 16^3 block of 8^3 tiles of one pattern invariant only under the
 * anti-diagonal mirror, placed in the 8 octants of a 32^3 grid each moved
 * by a different transform: level 1 must hold one node, which needs the
 * composed invariance (without it the octants reached through
 * transforms differing by the mirror would not merge). */
static void test_composed_invariance_one_class(void)
{
	struct grid blk, g;
	make_tiles48(&blk, 4, S48_ANTIDIAG, 8);
	grid_init(&g, 5);
	for (unsigned c = 0; c < 8; c++) {
		unsigned tr = c == 0 ? 0 : c == 1 ? 8 * 2 + 6 : (unsigned)(rnd() % 48);
		for (uint32_t x = 0; x < 16; x++)
			for (uint32_t y = 0; y < 16; y++)
				for (uint32_t z = 0; z < 16; z++) {
					uint32_t a[3] = {x, y, z}, q[3];
					if (!*gv(&blk, x, y, z)) continue;
					coord(tr, 16, a, q);
					*gv(&g, (c >> 2) * 16 + q[0], (c >> 1 & 1) * 16 + q[1],
					    (c & 1) * 16 + q[2]) = 1;
				}
	}
	struct vd_dag d;
	build(&g, VD_KIND_SSVDAG48, &d);
	CHECK_EQ(d.lv[1].nodes, 1);
	CHECK(dag_matches_grid(&d, &g));
	check_scene(&g, "octants");
	vd_dag_release(&d);
	grid_free(&g);
	grid_free(&blk);
}

/* Parts of every kind merged into an ssvdag48 equal the direct build; an
 * ssvdag merge refuses an ssvdag48 part; the chunk file round-trips and
 * readers of dag-or-ssvdag refuse it. */
static void test_merge_and_file(void)
{
	struct grid g;
	make_tiles48(&g, 6, S48_QUARTER, 8);
	struct vd_dag parts[8], root, mono, bad, back;
	const struct vd_dag *pp[8];
	static const uint32_t kinds[3] = {VD_KIND_DAG, VD_KIND_SSVDAG,
					  VD_KIND_SSVDAG48};
	for (uint64_t c = 0; c < 8; c++) {
		struct vd_svo s;
		grid_to_svo(&g, 1, c, &s);
		CHECK_EQ(vd_dag_from_svo(&parts[c], &s, kinds[c % 3], &opts, NULL),
			 VD_OK);
		pp[c] = &parts[c];
		svo_free(&s);
	}
	CHECK_EQ(vd_dag_merge(&root, pp, 8, VD_KIND_SSVDAG48, -1, &opts, NULL),
		 VD_OK);
	build(&g, VD_KIND_SSVDAG48, &mono);
	for (int l = 0; l < 6; l++) CHECK_EQ(root.lv[l].nodes, mono.lv[l].nodes);
	CHECK(dag_matches_grid(&root, &g));
	CHECK_EQ(vd_dag_merge(&bad, pp, 8, VD_KIND_SSVDAG, -1, &opts, NULL),
		 VD_ERR_WRONG_KIND);
	vd_dag_release(&bad);

	char path[64];
	snprintf(path, sizeof path, "/tmp/test_sym48.%d.s48", (int)getpid());
	struct vd_transform tr = {0};
	CHECK_EQ(vd_dag_save(&root, &tr, path, "test"), VD_OK);
	CHECK_EQ(vd_dag_load(&back, NULL, path, VD_KIND_ANY), VD_ERR_WRONG_KIND);
	vd_dag_release(&back);
	CHECK_EQ(vd_dag_load(&back, NULL, path, VD_KIND_SSVDAG), VD_ERR_WRONG_KIND);
	vd_dag_release(&back);
	CHECK_EQ(vd_dag_load(&back, NULL, path, VD_KIND_ANY_DAG), VD_OK);
	CHECK_EQ(back.kind, VD_KIND_SSVDAG48);
	CHECK(dag_matches_grid(&back, &g));
	for (int l = 0; l < 6; l++) {
		CHECK_EQ(back.lv[l].nodes, root.lv[l].nodes);
		if (l < 5)
			CHECK(!memcmp(back.lv[l].refl, root.lv[l].refl,
				      (size_t)root.lv[l].refs));
	}
	vd_dag_release(&back);
	/* a transform of 48 or more is corrupt */
	int l = 2;
	uint8_t keep = root.lv[l].refl[0];
	root.lv[l].refl[0] = 48;
	CHECK_EQ(vd_dag_validate(&root), VD_ERR_CORRUPT);
	root.lv[l].refl[0] = keep;
	unlink(path);
	vd_dag_release(&root);
	vd_dag_release(&mono);
	for (int c = 0; c < 8; c++) vd_dag_release(&parts[c]);
	grid_free(&g);
}

/* The bundled bunny at 2^7: counts equal the brute force, lossless. */
static void test_real_scene(void)
{
	char dir[64];
	snprintf(dir, sizeof dir, "/tmp/test_sym48.%d", (int)getpid());
	struct vd_svo svo;
	struct vd_transform tr;
	if (!test_voxelize_one("tests/data/bunny.ply", 7, dir, &svo, &tr)) return;
	struct grid g;
	grid_init(&g, 7);
	CHECK_EQ(svo_to_grid(&svo, &g), 0);
	vd_svo_release(&svo);
	CHECK(check_scene(&g, "bunny") >= 3);
	grid_free(&g);
	char cmd[128];
	snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
	CHECK_EQ(system(cmd), 0);
}

int main(void)
{
	RUN(test_subgroups);
	RUN(test_leaf_table48);
	RUN(test_brick_canon48);
	RUN(test_minimal_synthetic);
	RUN(test_composed_invariance_one_class);
	RUN(test_merge_and_file);
	RUN(test_real_scene);
	return CHECK_DONE();
}
