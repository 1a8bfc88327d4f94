/* test_ssvdag.c - symmetry-merge: the leaf class table and the reflection
 * primitives against coordinate arithmetic, SSVDAG minimality against brute
 * force over all 8 reflections of every subtree's voxels, lossless
 * expansion, and the DAG -> SSVDAG path equal to the direct one. */
#include "dag_test_util.h"
#include "dag/dag_internal.h"

static struct vd_dag_opts opts = {1, 0, NULL};

/* Mask reflected by m through coordinates: voxel (x, y, z) -> mirrored. */
static unsigned coord_reflect8(unsigned v, unsigned m)
{
	unsigned out = 0;
	for (unsigned x = 0; x < 2; x++)
		for (unsigned y = 0; y < 2; y++)
			for (unsigned z = 0; z < 2; z++)
				if (v >> (4 * x + 2 * y + z) & 1) {
					unsigned X = m & 4 ? 1 - x : x,
						 Y = m & 2 ? 1 - y : y,
						 Z = m & 1 ? 1 - z : z;
					out |= 1u << (4 * X + 2 * Y + Z);
				}
	return out;
}

/* vd__node_canon against its definition: every reflection x of the node
 * keyed (mask reflected by x, then per slot the child's reference with its
 * reflection r ^ x normalized), the largest key kept, the smallest x
 * giving it, and the invariance set the x giving the same key, relative
 * to it. Children share ids and invariance sets often, so ties occur. */
static void test_node_canon_definition(void)
{
	vd__sym_init();
	for (int it = 0; it < 200000; it++) {
		unsigned mask = (unsigned)(rnd() % 255) + 1;
		uint32_t id[8];
		uint8_t r[8], g[8];
		for (int p = 0; p < 8; p++) {
			id[p] = (uint32_t)(rnd() % 3);
			r[p] = (uint8_t)(rnd() % 8);
			/* an invariance set: a subgroup of the 8 (closed) */
			static const uint8_t sub[] = {0x01, 0x03, 0x05, 0x11,
						      0x09, 0x0f, 0x33, 0x55,
						      0xff, 0x41, 0x21, 0x81};
			g[p] = sub[rnd() % sizeof sub];
		}
		uint64_t best[9] = {0}, key[9];
		unsigned bm = 0, same = 0;
		int k = 0;
		for (unsigned x = 0; x < 8; x++) {
			uint64_t c[9];
			unsigned mx = vd_mask_reflect((uint8_t)mask, x);
			int j = 0;
			c[0] = mx;
			for (unsigned q = 0; q < 8; q++)
				if (mx >> q & 1) {
					unsigned p = q ^ x;
					c[++j] = VD_REF(id[p], vd__refl_norm[g[p]][r[p] ^ x]);
				}
			k = j;
			int cmp = x == 0 ? 1 : 0;
			for (int i = 0; i <= j && !cmp; i++)
				if (c[i] != best[i]) cmp = c[i] > best[i] ? 1 : -1;
			if (cmp > 0) {
				memcpy(best, c, sizeof c);
				bm = x;
				same = 1u << x;
			} else if (cmp == 0) {
				same |= 1u << x;
			}
		}
		unsigned gi = 0;
		for (unsigned x = 0; x < 8; x++)
			if (same >> x & 1) gi |= 1u << (x ^ bm);
		uint8_t m = 99, inv = 0;
		int n = vd__node_canon(1, 0, mask, id, r, g, key, &m, &inv);
		CHECK_EQ(n, k);
		CHECK(!memcmp(key, best, sizeof(uint64_t) * (size_t)(k + 1)));
		CHECK_EQ(m, bm);
		CHECK_EQ(inv, gi);
		if (check_failed_) break;
	}
}

static void test_leaf_table(void)
{
	const struct vd_leaf_class *t = vd_leaf_classes();
	int classes = 0;
	for (unsigned v = 0; v < 256; v++) {
		unsigned best = 0, bm = 0, inv = 0;
		for (unsigned m = 0; m < 8; m++) {
			unsigned r = coord_reflect8(v, m);
			CHECK_EQ(vd_mask_reflect((uint8_t)v, m), r);
			if (r > best) best = r;
			if (r == v) inv |= 1u << m;
		}
		/* smallest m reaching the maximum */
		for (unsigned m = 0; m < 8; m++)
			if (coord_reflect8(v, m) == best) {
				bm = m;
				break;
			}
		CHECK_EQ(t[v].canon, best);
		CHECK_EQ(t[v].refl, bm);
		CHECK_EQ(t[v].inv, inv);
		CHECK_EQ(coord_reflect8(t[v].canon, t[v].refl), v);
		classes += best == v;
	}
	/* The paper's 46 classes, the empty mask included; Burnside's lemma:
	 * (256 + 7 * 16) / 8, each non-identity reflection fixing 2^4 masks. */
	CHECK_EQ(classes, 46);
}

static void test_brick_reflect(void)
{
	for (int it = 0; it < 200; it++) {
		uint64_t v = rnd() & rnd();
		for (unsigned m = 0; m < 8; m++) {
			uint64_t want = 0;
			for (uint32_t b = 0; b < 64; b++) {
				if (!(v >> b & 1)) continue;
				uint32_t x, y, z;
				ref_unmorton(b, 2, &x, &y, &z);
				if (m & 4) x = 3 - x;
				if (m & 2) y = 3 - y;
				if (m & 1) z = 3 - z;
				want |= 1ULL << ref_morton(x, y, z, 2);
			}
			CHECK(vd_brick_reflect(v, m) == want);
			/* byte c of the reflection is byte c^m reflected */
			for (unsigned c = 0; c < 8; c++)
				CHECK_EQ((uint8_t)(want >> 8 * c),
					 coord_reflect8((uint8_t)(v >> 8 * (c ^ m)), m));
		}
	}
}

static void build(const struct grid *g, uint32_t kind, struct vd_dag *d)
{
	struct vd_svo s;
	grid_to_svo(g, 0, 0, &s);
	CHECK_EQ(vd_dag_from_svo(d, &s, kind, &opts, NULL), VD_OK);
	svo_free(&s);
	CHECK_EQ(vd_dag_validate(d), VD_OK);
}

static void test_lossless(void)
{
	for (int L = 1; L <= 6; L++)
		for (int sc = 0; sc < SC_COUNT; sc++) {
			struct grid g;
			make_scene(&g, L, sc);
			struct vd_dag d;
			build(&g, VD_KIND_SSVDAG, &d);
			CHECK(dag_matches_grid(&d, &g));
			CHECK_EQ(d.voxels, grid_count(&g));
			vd_dag_release(&d);
			grid_free(&g);
		}
}

/* SSVDAG per-level counts == distinct subtrees up to reflection; direct
 * build == DAG then symmetry merge; never more nodes than the DAG. */
static void test_minimal_brute_force(void)
{
	int saw_fewer = 0;
	for (int L = 1; L <= 6; L++)
		for (int sc = 0; sc < SC_COUNT; sc++) {
			struct grid g;
			make_scene(&g, L, sc);
			struct vd_dag dag, direct, merged;
			build(&g, VD_KIND_DAG, &dag);
			build(&g, VD_KIND_SSVDAG, &direct);
			const struct vd_dag *pp[1] = {&dag};
			CHECK_EQ(vd_dag_merge(&merged, pp, 1, VD_KIND_SSVDAG, 0,
					      &opts, NULL), VD_OK);
			CHECK_EQ(vd_dag_validate(&merged), VD_OK);
			CHECK(dag_matches_grid(&merged, &g));
			for (int l = 0; l < L; l++) {
				uint64_t bf = brute_distinct(&g, 0, 0, l, 1);
				if (direct.lv[l].nodes != bf)
					fprintf(stderr, "  L=%d %s level %d: %llu, "
						"brute force %llu\n", L,
						scene_name[sc], l,
						(unsigned long long)direct.lv[l].nodes,
						(unsigned long long)bf);
				CHECK_EQ(direct.lv[l].nodes, bf);
				CHECK_EQ(merged.lv[l].nodes, bf);
				CHECK(bf <= dag.lv[l].nodes);
				saw_fewer += bf < dag.lv[l].nodes;
			}
			vd_dag_release(&dag);
			vd_dag_release(&direct);
			vd_dag_release(&merged);
			grid_free(&g);
		}
	CHECK(saw_fewer > 10); /* the scenes do exercise symmetry */
}

/* A 16^3 block made of 8^3 tiles, each empty or a random reflection of
 * one of two random patterns, placed 8 times under each of the 8
 * reflections. Level 1 must hold exactly one node. With patterns invariant
 * under X and Y mirrored together (and nothing else), the block's copies
 * only merge if that combined invariance is known: three per-axis
 * invariance bits would leave several level-1 nodes. */
static void test_all_reflections_one_class(void)
{
	for (int symxy = 0; symxy < 2; symxy++) {
		struct grid g;
		grid_init(&g, 5);
		uint8_t pat[2][512], blk[4096];
		for (int p = 0; p < 2; p++)
			for (uint32_t x = 0; x < 8; x++)
				for (uint32_t y = 0; y < 8; y++)
					for (uint32_t z = 0; z < 8; z++) {
						uint8_t v = rnd() % 3 == 0;
						if (!symxy) {
							pat[p][(x * 8 + y) * 8 + z] = v;
						} else if (x < 4) {
							pat[p][(x * 8 + y) * 8 + z] = v;
							pat[p][((7 - x) * 8 + 7 - y) * 8 + z] = v;
						}
					}
		memset(blk, 0, sizeof blk);
		for (unsigned t = 0; t < 8; t++) {
			unsigned p = (unsigned)(rnd() % 3), m = (unsigned)(rnd() % 8);
			if (t == 0) p = 0, m = 0;
			if (t == 1) p = 0, m = 5;
			if (p == 2) continue;
			for (uint32_t x = 0; x < 8; x++)
				for (uint32_t y = 0; y < 8; y++)
					for (uint32_t z = 0; z < 8; z++) {
						uint32_t sx = m & 4 ? 7 - x : x,
							 sy = m & 2 ? 7 - y : y,
							 sz = m & 1 ? 7 - z : z;
						blk[(((t >> 2) * 8 + x) * 16 + (t >> 1 & 1) * 8 + y) * 16 +
						    (t & 1) * 8 + z] = pat[p][(sx * 8 + sy) * 8 + sz];
					}
		}
		for (unsigned c = 0; c < 8; c++)
			for (uint32_t x = 0; x < 16; x++)
				for (uint32_t y = 0; y < 16; y++)
					for (uint32_t z = 0; z < 16; z++) {
						uint32_t sx = c & 4 ? 15 - x : x,
							 sy = c & 2 ? 15 - y : y,
							 sz = c & 1 ? 15 - z : z;
						*gv(&g, (c >> 2) * 16 + x, (c >> 1 & 1) * 16 + y,
						    (c & 1) * 16 + z) = blk[(sx * 16 + sy) * 16 + sz];
					}
		struct vd_dag d;
		build(&g, VD_KIND_SSVDAG, &d);
		CHECK_EQ(d.lv[1].nodes, 1);
		CHECK(dag_matches_grid(&d, &g));
		for (int l = 0; l < 5; l++)
			CHECK_EQ(d.lv[l].nodes, brute_distinct(&g, 0, 0, l, 1));
		vd_dag_release(&d);
		grid_free(&g);
	}
}

/* Every reflected variant of a random DAG expands to the reflected grid. */
static void test_merge_of_reflected_parts(void)
{
	struct grid g;
	make_scene(&g, 5, SC_TILES);
	struct vd_dag parts[8], root, mono;
	const struct vd_dag *pp[8];
	for (uint64_t c = 0; c < 8; c++) {
		struct vd_svo s;
		grid_to_svo(&g, 1, c, &s);
		/* alternate kinds: an ssvdag merge accepts both */
		CHECK_EQ(vd_dag_from_svo(&parts[c], &s, c & 1 ? VD_KIND_SSVDAG :
					 VD_KIND_DAG, &opts, NULL), VD_OK);
		pp[c] = &parts[c];
		svo_free(&s);
	}
	CHECK_EQ(vd_dag_merge(&root, pp, 8, VD_KIND_SSVDAG, -1, &opts, NULL),
		 VD_OK);
	build(&g, VD_KIND_SSVDAG, &mono);
	for (int l = 0; l < 5; l++) CHECK_EQ(root.lv[l].nodes, mono.lv[l].nodes);
	CHECK(dag_matches_grid(&root, &g));
	vd_dag_release(&root);
	vd_dag_release(&mono);
	for (int c = 0; c < 8; c++) vd_dag_release(&parts[c]);
	grid_free(&g);
}

int main(void)
{
	RUN(test_node_canon_definition);
	RUN(test_leaf_table);
	RUN(test_brick_reflect);
	RUN(test_lossless);
	RUN(test_minimal_brute_force);
	RUN(test_all_reflections_one_class);
	RUN(test_merge_of_reflected_parts);
	return CHECK_DONE();
}
