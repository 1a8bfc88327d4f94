/* test_dag.c - svo-to-dag: lossless, minimal (against brute force over
 * voxel content), chunked builds merged to the root equal the monolithic
 * build, merge errors, edge cases, chunk files. */
#include "dag_test_util.h"
#include "scene.h"

/* Two files with the same bytes. */
static int files_equal(const char *a, const char *b)
{
	FILE *fa = fopen(a, "rb"), *fb = fopen(b, "rb");
	int same = fa && fb;
	while (same) {
		int ca = fgetc(fa), cb = fgetc(fb);
		same = ca == cb;
		if (ca == EOF || cb == EOF)
			break;
	}
	if (fa) fclose(fa);
	if (fb) fclose(fb);
	return same;
}

static struct vd_dag_opts opts = {1, 0, NULL};

static int counts_equal(const struct vd_dag *a, const struct vd_dag *b)
{
	if (a->levels != b->levels || a->chunk_level != b->chunk_level ||
	    a->voxels != b->voxels)
		return 0;
	for (int l = a->chunk_level; l < a->levels; l++)
		if (a->lv[l].nodes != b->lv[l].nodes ||
		    a->lv[l].refs != b->lv[l].refs)
			return 0;
	return 1;
}

/* Byte-identical: same counts, masks, references, reflections, bricks. */
static int dags_identical(const struct vd_dag *a, const struct vd_dag *b)
{
	if (!counts_equal(a, b) || a->kind != b->kind) return 0;
	for (int l = a->chunk_level; l < a->levels; l++) {
		const struct vd_dag_level *x = &a->lv[l], *y = &b->lv[l];
		if (x->nodes && memcmp(x->mask, y->mask, x->nodes)) return 0;
		if (x->refs && memcmp(x->child, y->child, x->refs * 4)) return 0;
		if (x->refs && x->refl && memcmp(x->refl, y->refl, x->refs))
			return 0;
	}
	if (a->bricks && memcmp(a->bricks, b->bricks,
				a->lv[a->levels - 2].nodes * 8))
		return 0;
	return 1;
}

/* Builds the DAG of the whole grid; checks lossless and valid. */
static int build_whole(const struct grid *g, uint32_t kind, struct vd_dag *d)
{
	struct vd_svo s;
	grid_to_svo(g, 0, 0, &s);
	int err = vd_dag_from_svo(d, &s, kind, &opts, NULL);
	svo_free(&s);
	CHECK_EQ(err, VD_OK);
	if (err) {
		fprintf(stderr, "  %s: %s\n", vd_strerror(err), vd_error_detail());
		return err;
	}
	CHECK_EQ(vd_dag_validate(d), VD_OK);
	CHECK_EQ(d->voxels, grid_count(g));
	CHECK(dag_matches_grid(d, g));
	return err;
}

static void test_lossless_monolithic(void)
{
	for (int L = 1; L <= 6; L++)
		for (int sc = 0; sc < SC_COUNT; sc++) {
			struct grid g;
			make_scene(&g, L, sc);
			struct vd_dag d;
			build_whole(&g, VD_KIND_DAG, &d);
			if (L >= 1 && grid_count(&g)) CHECK_EQ(d.lv[0].nodes, 1);
			vd_dag_release(&d);
			grid_free(&g);
		}
}

/* Minimality: per-level node counts equal the number of distinct non-empty
 * subtrees, found by comparing full voxel content. */
static void test_minimal_brute_force(void)
{
	for (int L = 1; L <= 6; L++)
		for (int sc = 0; sc < SC_COUNT; sc++) {
			struct grid g;
			make_scene(&g, L, sc);
			struct vd_dag d;
			if (!build_whole(&g, VD_KIND_DAG, &d))
				for (int l = 0; l < L; l++) {
					uint64_t bf = brute_distinct(&g, 0, 0, l, 0);
					if (d.lv[l].nodes != bf)
						fprintf(stderr, "  L=%d %s level %d\n", L,
							scene_name[sc], l);
					CHECK_EQ(d.lv[l].nodes, bf);
				}
			vd_dag_release(&d);
			grid_free(&g);
		}
}

/* Builds one DAG per non-empty cell at L0 (plus one empty cell, which a
 * merge must accept), checks each against brute force, then merges them
 * either all at once or 8 siblings at a time up to the root. */
static void chunked(const struct grid *g, int L0, uint32_t kind,
		    int tree, struct vd_dag *root)
{
	uint64_t cells = 1ULL << (3 * L0), n = 0;
	struct vd_dag *parts = calloc(cells, sizeof *parts);
	int empty_kept = 0;
	for (uint64_t c = 0; c < cells; c++) {
		struct vd_svo s;
		grid_to_svo(g, L0, c, &s);
		if (!s.count && empty_kept++) {
			svo_free(&s);
			continue;
		}
		CHECK_EQ(vd_dag_from_svo(&parts[n], &s, kind, &opts, NULL), VD_OK);
		CHECK_EQ(vd_dag_validate(&parts[n]), VD_OK);
		if (s.count)
			for (int l = L0; l < g->L; l++)
				CHECK_EQ(parts[n].lv[l].nodes,
					 brute_distinct(g, L0, c, l,
							kind == VD_KIND_SSVDAG));
		n++;
		svo_free(&s);
	}
	if (!tree) {
		const struct vd_dag **pp = malloc(n * sizeof *pp);
		for (uint64_t i = 0; i < n; i++) pp[i] = &parts[i];
		CHECK_EQ(vd_dag_merge(root, pp, n, kind, 0, &opts, NULL), VD_OK);
		free(pp);
	} else {
		/* Reduction tree: merge groups of siblings level by level. */
		for (int lev = L0; lev > 0; lev--) {
			uint64_t m = 0;
			for (uint64_t i = 0; i < n;) {
				uint64_t parent = parts[i].cell_morton >> 3, j = i;
				const struct vd_dag *pp[8];
				while (j < n && parts[j].cell_morton >> 3 == parent) {
					pp[j - i] = &parts[j];
					j++;
				}
				struct vd_dag out;
				CHECK_EQ(vd_dag_merge(&out, pp, j - i, kind, -1,
						      &opts, NULL), VD_OK);
				CHECK_EQ(out.chunk_level, lev - 1);
				CHECK_EQ(vd_dag_validate(&out), VD_OK);
				for (uint64_t k = i; k < j; k++)
					vd_dag_release(&parts[k]);
				parts[m++] = out;
				i = j;
			}
			n = m;
		}
		CHECK_EQ(n, 1);
		*root = parts[0];
		parts[0] = (struct vd_dag){0};
	}
	for (uint64_t i = 0; i < n; i++) vd_dag_release(&parts[i]);
	free(parts);
}

static void test_chunked_equals_monolithic(void)
{
	int Ls[] = {4, 5, 6};
	for (int kind = VD_KIND_DAG; kind <= VD_KIND_SSVDAG; kind++)
		for (int li = 0; li < 3; li++)
			for (int sc = 0; sc < SC_COUNT; sc++) {
				int L = Ls[li];
				struct grid g;
				make_scene(&g, L, sc);
				struct vd_dag mono;
				build_whole(&g, (uint32_t)kind, &mono);
				for (int L0 = 1; L0 <= 3 && L0 <= L - 2; L0++)
					for (int tree = 0; tree < 2; tree++) {
						struct vd_dag root;
						chunked(&g, L0, (uint32_t)kind, tree, &root);
						CHECK_EQ(vd_dag_validate(&root), VD_OK);
						CHECK(counts_equal(&root, &mono));
						CHECK(dag_matches_grid(&root, &g));
						vd_dag_release(&root);
					}
				vd_dag_release(&mono);
				grid_free(&g);
			}
}

/* A merge to a level between the parts and the root, and mixed chunk
 * levels (a level-1 cell next to level-2 cells of another level-1 cell). */
static void test_merge_partial_and_mixed(void)
{
	struct grid g;
	make_scene(&g, 5, SC_SHELL);
	/* level-2 cells under level-1 cell 3, merged to level 1 */
	struct vd_dag parts[9];
	const struct vd_dag *pp[9];
	for (int i = 0; i < 8; i++) {
		struct vd_svo s;
		grid_to_svo(&g, 2, 3 * 8 + (uint64_t)i, &s);
		CHECK_EQ(vd_dag_from_svo(&parts[i], &s, VD_KIND_DAG, &opts, NULL), 0);
		pp[i] = &parts[i];
		svo_free(&s);
	}
	struct vd_dag mid, whole1;
	CHECK_EQ(vd_dag_merge(&mid, pp, 8, VD_KIND_DAG, 1, &opts, NULL), 0);
	struct vd_svo s1;
	grid_to_svo(&g, 1, 3, &s1);
	CHECK_EQ(vd_dag_from_svo(&whole1, &s1, VD_KIND_DAG, &opts, NULL), 0);
	CHECK(counts_equal(&mid, &whole1));
	CHECK_EQ(mid.cell_morton, 3);
	svo_free(&s1);
	/* mixed: level-1 cell 5 whole plus the 8 level-2 cells of cell 3 */
	grid_to_svo(&g, 1, 5, &s1);
	CHECK_EQ(vd_dag_from_svo(&parts[8], &s1, VD_KIND_DAG, &opts, NULL), 0);
	svo_free(&s1);
	pp[8] = &parts[8];
	struct vd_dag mixed;
	CHECK_EQ(vd_dag_merge(&mixed, pp, 9, VD_KIND_DAG, 0, &opts, NULL), 0);
	CHECK_EQ(vd_dag_validate(&mixed), VD_OK);
	struct grid h;
	grid_init(&h, 5);
	for (uint32_t x = 0; x < 32; x++)
		for (uint32_t y = 0; y < 32; y++)
			for (uint32_t z = 0; z < 32; z++) {
				uint64_t c1 = ref_morton(x >> 4, y >> 4, z >> 4, 1);
				if (c1 == 3 || c1 == 5) *gv(&h, x, y, z) = *gv(&g, x, y, z);
			}
	CHECK(dag_matches_grid(&mixed, &h));
	for (int l = 0; l < 5; l++)
		CHECK_EQ(mixed.lv[l].nodes, brute_distinct(&h, 0, 0, l, 0));
	vd_dag_release(&mixed);
	vd_dag_release(&mid);
	vd_dag_release(&whole1);
	for (int i = 0; i < 9; i++) vd_dag_release(&parts[i]);
	grid_free(&h);
	grid_free(&g);
}

/* The merge bound: a value worked out by hand from its comment in build.c,
 * and on real merges at least the parts and the output it must hold, no
 * lower from headers than from loaded parts, and subadditive (what lets
 * the planner sum shares). */
static void test_merge_estimate(void)
{
	/* one part, L = 4, nodes 1 2 3 4 on levels 0..3, references 2 3 4:
	 * parts 4 + 8*1*4 + (9+8) + (18+12) + (27+16) + 8*3 = 150, all held
	 * on level 2 (bricks, d 4, refs 5): table 48*4 + 2*3 + 8192 = 8390
	 * over the late arrays, maps 15, bricks and sets 36 + 18, frontier
	 * 16: 8475, below it the 5 leaves: 8630; level 1 (d 3, refs 4): held
	 * 32 + 17 above and the part's level 1, 30; output 43 + 21, maps
	 * 10 + 15, sets 3 + 4, a table of 1024 slots at least (8192),
	 * frontier 16:
	 * 8304, below it 5 + 88: 8476; level 0 (d 2, refs 3): held 32 + 17,
	 * output 30 + 15, maps 5 + 10, sets 2 + 3, table 8192, frontier 16,
	 * below 136: 8458. The peak, 8630, plus the fixed part. */
	struct vd_dag_census c = {.levels = 4, .parts = 1,
				  .nodes = {1, 2, 3, 4}, .refs = {2, 3, 4, 0},
				  .big_nodes = {1, 2, 3, 4},
				  .big_refs = {2, 3, 4, 0}};
	CHECK_EQ(vd_dag_estimate_merge(&c, VD_KIND_DAG),
		 8630 + VD_DAG_ESTIMATE_FIXED_BYTES);
	/* two parts with a big level 1 (1000 nodes, 3000 references, 600
	 * and 1800 of them in one part), 10 bricks with 40 references, 4
	 * leaves: parts 64 + 21000 + 330 + 4 = 21398, all held on level 2
	 * (d 12, refs 42): table 576 + 20 + 8192, maps 50, bricks and sets
	 * 108 + 54, frontiers 32: 9032, below it 6: 30436; level 1 (d 1002,
	 * refs 3002): held 64 above and the big part's 5400 + 7200, output
	 * 21026 and 10513, maps 5000 + 50, sets 1002 + 12, 4 slots a node
	 * (32064), frontiers 32, below 6 + 372: 82741; level 0 (d 2, refs
	 * 2): held 64, 26 + 13 + 5000 + 2 + 1002 + 8192 + 32, below 21404:
	 * 35735. The peak is level 1's. */
	struct vd_dag_census c2 = {.levels = 4, .parts = 2,
				   .nodes = {0, 1000, 10, 4},
				   .refs = {0, 3000, 40, 0},
				   .big_nodes = {0, 600, 6, 4},
				   .big_refs = {0, 1800, 24, 0}};
	CHECK_EQ(vd_dag_estimate_merge(&c2, VD_KIND_DAG),
		 82741 + VD_DAG_ESTIMATE_FIXED_BYTES);

	struct grid g;
	make_scene(&g, 6, SC_SHELL);
	struct vd_dag parts[8], out;
	const struct vd_dag *pp[8];
	struct vd_dag_census all = {0}, half[2] = {{0}}, hdr = {0};
	uint64_t held = 0;
	for (int i = 0; i < 8; i++) {
		struct vd_svo s;
		grid_to_svo(&g, 1, (uint64_t)i, &s);
		CHECK_EQ(vd_dag_from_svo(&parts[i], &s, VD_KIND_DAG, &opts, NULL), 0);
		svo_free(&s);
		pp[i] = &parts[i];
		vd_dag_census_add(&all, &parts[i]);
		vd_dag_census_add(&half[i / 4], &parts[i]);
		struct vd_chunk_header h = {0};
		vd_dag_header(&parts[i], &h);
		vd_dag_census_add_header(&hdr, &h);
		held += vd_dag_memory_bytes(&parts[i]);
	}
	struct vd_dag_stats st;
	CHECK_EQ(vd_dag_merge_consume(&out, parts, 8, VD_KIND_DAG, 0, &opts,
				      &st), 0);
	(void)pp;
	uint64_t est = vd_dag_estimate_merge(&all, VD_KIND_DAG);
	CHECK_EQ(st.memory_estimate_bytes, est);
	CHECK(est >= held + vd_dag_memory_bytes(&out) + VD_DAG_ESTIMATE_FIXED_BYTES);
	CHECK(vd_dag_estimate_merge(&hdr, VD_KIND_DAG) >= est);
	CHECK(vd_dag_estimate_merge(&all, VD_KIND_SSVDAG) >= est);
	CHECK(est <= vd_dag_estimate_merge(&half[0], VD_KIND_DAG) +
		     vd_dag_estimate_merge(&half[1], VD_KIND_DAG) -
		     VD_DAG_ESTIMATE_FIXED_BYTES);
	vd_dag_release(&out);
	for (int i = 0; i < 8; i++) vd_dag_release(&parts[i]);
	grid_free(&g);
}

static void test_merge_errors(void)
{
	struct grid g5, g6;
	make_scene(&g5, 5, SC_RANDOM);
	make_scene(&g6, 6, SC_RANDOM);
	struct vd_svo s;
	struct vd_dag a, b, c, d, out;
	grid_to_svo(&g5, 2, 9, &s);
	vd_dag_from_svo(&a, &s, VD_KIND_DAG, &opts, NULL);
	svo_free(&s);
	grid_to_svo(&g6, 2, 10, &s);
	vd_dag_from_svo(&b, &s, VD_KIND_DAG, &opts, NULL);
	svo_free(&s);
	grid_to_svo(&g5, 2, 17, &s); /* another level-1 parent than 9 */
	vd_dag_from_svo(&c, &s, VD_KIND_DAG, &opts, NULL);
	svo_free(&s);
	grid_to_svo(&g5, 2, 9, &s);
	vd_dag_from_svo(&d, &s, VD_KIND_SSVDAG, &opts, NULL);
	svo_free(&s);

	const struct vd_dag *pp[3] = {&a, &b};
	CHECK_EQ(vd_dag_merge(&out, pp, 2, VD_KIND_DAG, -1, &opts, NULL),
		 VD_ERR_MISMATCH);   /* depths 5 and 6 */
	CHECK(strstr(vd_error_detail(), "levels") != NULL);
	vd_dag_release(&out);
	pp[1] = &a;
	CHECK_EQ(vd_dag_merge(&out, pp, 2, VD_KIND_DAG, -1, &opts, NULL),
		 VD_ERR_MISMATCH);   /* the same cell twice */
	CHECK(strstr(vd_error_detail(), "overlap") != NULL);
	vd_dag_release(&out);
	pp[1] = &c;
	CHECK_EQ(vd_dag_merge(&out, pp, 2, VD_KIND_DAG, -1, &opts, NULL),
		 VD_ERR_MISMATCH);   /* not siblings */
	CHECK(strstr(vd_error_detail(), "not inside") != NULL);
	vd_dag_release(&out);
	CHECK_EQ(vd_dag_merge(&out, pp, 2, VD_KIND_DAG, 0, &opts, NULL), VD_OK);
	vd_dag_release(&out);
	pp[1] = &d;
	CHECK_EQ(vd_dag_merge(&out, pp, 1, VD_KIND_DAG, 3, &opts, NULL),
		 VD_ERR_MISMATCH);   /* target below the parts */
	vd_dag_release(&out);
	pp[0] = &d;
	CHECK_EQ(vd_dag_merge(&out, pp, 1, VD_KIND_DAG, -1, &opts, NULL),
		 VD_ERR_WRONG_KIND); /* an ssvdag into a dag */
	vd_dag_release(&out);
	CHECK_EQ(vd_dag_merge(&out, pp, 0, VD_KIND_DAG, -1, &opts, NULL),
		 VD_ERR_EMPTY);
	vd_dag_release(&out);
	/* a budget too small for the estimate */
	struct vd_dag_opts tight = {1, 1000, NULL};
	pp[0] = &a;
	CHECK_EQ(vd_dag_merge(&out, pp, 1, VD_KIND_DAG, -1, &tight, NULL),
		 VD_ERR_BUDGET);
	CHECK(strstr(vd_error_detail(), "budget") != NULL);
	vd_dag_release(&out);
	vd_dag_release(&a);
	vd_dag_release(&b);
	vd_dag_release(&c);
	vd_dag_release(&d);
	grid_free(&g5);
	grid_free(&g6);
}

static void test_edge_cases(void)
{
	/* empty SVO: an empty DAG, which expands to nothing */
	struct vd_svo s = {.levels = 4};
	struct vd_dag d;
	CHECK_EQ(vd_dag_from_svo(&d, &s, VD_KIND_DAG, &opts, NULL), VD_OK);
	CHECK_EQ(d.lv[0].nodes, 0);
	CHECK_EQ(d.voxels, 0);
	CHECK_EQ(vd_dag_validate(&d), VD_OK);
	struct vd_svo e;
	CHECK_EQ(vd_dag_to_svo(&d, &e), VD_OK);
	CHECK_EQ(e.count, 0);
	svo_free(&e);
	vd_dag_release(&d);
	/* L = 1: a single 2x2x2 mask, every value */
	for (unsigned v = 1; v < 256; v++) {
		uint64_t key = 0, mask = v;
		struct vd_svo t = {1, 0, 0, 1, &key, &mask};
		for (int kind = VD_KIND_DAG; kind <= VD_KIND_SSVDAG; kind++) {
			CHECK_EQ(vd_dag_from_svo(&d, &t, (uint32_t)kind, &opts, NULL), 0);
			CHECK_EQ(d.lv[0].nodes, 1);
			CHECK_EQ(d.lv[0].mask[0], v); /* the root is never reflected */
			CHECK_EQ(d.voxels, (uint64_t)__builtin_popcount(v));
			CHECK_EQ(vd_dag_to_svo(&d, &e), 0);
			CHECK(e.count == 1 && e.keys[0] == 0 && e.masks[0] == v);
			svo_free(&e);
			vd_dag_release(&d);
		}
	}
	/* L = 1 voxel outside the 2^1 grid; unsorted and empty bricks */
	uint64_t k2[2] = {0, 0}, m2[2] = {0x100, 1};
	struct vd_svo t = {1, 0, 0, 1, k2, m2};
	CHECK_EQ(vd_dag_from_svo(&d, &t, VD_KIND_DAG, &opts, NULL), VD_ERR_CORRUPT);
	vd_dag_release(&d);
	t = (struct vd_svo){3, 0, 0, 2, k2, m2};
	CHECK_EQ(vd_dag_from_svo(&d, &t, VD_KIND_DAG, &opts, NULL), VD_ERR_CORRUPT);
	vd_dag_release(&d);
	k2[1] = 1;
	m2[1] = 0;
	CHECK_EQ(vd_dag_from_svo(&d, &t, VD_KIND_DAG, &opts, NULL), VD_ERR_CORRUPT);
	vd_dag_release(&d);
	/* a brick outside its cell */
	k2[0] = 9;
	m2[1] = 1;
	k2[1] = 17;
	t = (struct vd_svo){4, 1, 1, 2, k2, m2};
	CHECK_EQ(vd_dag_from_svo(&d, &t, VD_KIND_DAG, &opts, NULL), VD_ERR_CORRUPT);
	CHECK(strstr(vd_error_detail(), "outside") != NULL);
	vd_dag_release(&d);
	/* the deepest grid: bricks at both far corners, whole and as two
	 * cells at level L-2 merged to the root (64-bit Morton ranges) */
	{
		uint64_t kmax = (1ULL << 57) - 1, keys[2] = {0, kmax},
			 masks[2] = {1, 1ULL << 63};
		struct vd_svo big = {21, 0, 0, 2, keys, masks}, c0, c1;
		CHECK_EQ(vd_dag_from_svo(&d, &big, VD_KIND_SSVDAG, &opts, NULL), 0);
		CHECK_EQ(vd_dag_validate(&d), VD_OK);
		CHECK_EQ(d.voxels, 2);
		CHECK_EQ(vd_dag_to_svo(&d, &e), 0);
		CHECK(e.count == 2 && e.keys[1] == kmax && e.masks[1] == 1ULL << 63);
		svo_free(&e);
		c0 = (struct vd_svo){21, 19, 0, 1, keys, masks};
		c1 = (struct vd_svo){21, 19, kmax, 1, keys + 1, masks + 1};
		struct vd_dag p0, p1, m;
		CHECK_EQ(vd_dag_from_svo(&p0, &c0, VD_KIND_SSVDAG, &opts, NULL), 0);
		CHECK_EQ(vd_dag_from_svo(&p1, &c1, VD_KIND_SSVDAG, &opts, NULL), 0);
		const struct vd_dag *pq[2] = {&p1, &p0};
		CHECK_EQ(vd_dag_merge(&m, pq, 2, VD_KIND_SSVDAG, 0, &opts, NULL), 0);
		CHECK(counts_equal(&m, &d));
		/* one corner voxel is the other reflected by X+Y+Z: one class
		 * per level below the root */
		for (int l = 1; l < 21; l++) CHECK_EQ(m.lv[l].nodes, 1);
		const struct vd_svo *sv[2] = {&c1, &c0};
		struct vd_dag_diff diff;
		CHECK_EQ(vd_dag_compare_svo(&m, sv, 2, &diff), 0);
		CHECK_EQ(diff.differing_voxels, 0);
		CHECK_EQ(vd_dag_compare_svo(&m, sv, 1, &diff), 0);
		CHECK_EQ(diff.differing_voxels, 1);
		CHECK_EQ(diff.first_voxel_morton, 0);
		CHECK_EQ(diff.first_in_dag, 1);
		vd_dag_release(&p0);
		vd_dag_release(&p1);
		vd_dag_release(&m);
		vd_dag_release(&d);
	}
	/* full cube: one node per level */
	struct grid g;
	make_scene(&g, 6, SC_FULL);
	CHECK_EQ(build_whole(&g, VD_KIND_SSVDAG, &d), 0);
	for (int l = 0; l < 6; l++) CHECK_EQ(d.lv[l].nodes, 1);
	CHECK_EQ(d.voxels, 1ULL << 18);
	vd_dag_release(&d);
	grid_free(&g);
	/* single voxel at L = 7: one node per level */
	make_scene(&g, 7, SC_ONE);
	CHECK_EQ(build_whole(&g, VD_KIND_DAG, &d), 0);
	for (int l = 0; l < 7; l++) CHECK_EQ(d.lv[l].nodes, 1);
	CHECK_EQ(d.voxels, 1);
	vd_dag_release(&d);
	grid_free(&g);
	/* L = 2, chunk level 0 and merged from 1... (L0 <= L-2 in svo files,
	 * but the library accepts a 2x2x2 cell too) */
	make_scene(&g, 2, SC_RANDOM);
	struct vd_dag mono, parts[8];
	const struct vd_dag *pp[8];
	build_whole(&g, VD_KIND_DAG, &mono);
	size_t n = 0;
	for (uint64_t c = 0; c < 8; c++) {
		struct vd_svo u;
		grid_to_svo(&g, 1, c, &u);
		CHECK_EQ(vd_dag_from_svo(&parts[n], &u, VD_KIND_DAG, &opts, NULL), 0);
		pp[n] = &parts[n];
		n++;
		svo_free(&u);
	}
	CHECK_EQ(vd_dag_merge(&d, pp, n, VD_KIND_DAG, -1, &opts, NULL), 0);
	CHECK(counts_equal(&d, &mono));
	CHECK(dag_matches_grid(&d, &g));
	vd_dag_release(&d);
	vd_dag_release(&mono);
	for (size_t i = 0; i < n; i++) vd_dag_release(&parts[i]);
	grid_free(&g);
}

static int file_copy_prefix(const char *src, const char *dst, long n)
{
	FILE *a = fopen(src, "rb"), *b = fopen(dst, "wb");
	if (!a || !b) return -1;
	for (long i = 0; i < n; i++) {
		int c = fgetc(a);
		if (c == EOF) break;
		fputc(c, b);
	}
	fclose(a);
	return fclose(b);
}

/* Sections larger than a frame (2 MiB raw) are written as several frames:
 * the same bytes with 1 and 3 threads, and read back, by the one-stream
 * decoder (1 thread) and by the frame-parallel one, as the same arrays. */
static void test_framed_sections(void)
{
	const char *dir = test_tmpdir("test_dag_frames");
	char p1[600], p3[600];
	struct vd_transform t;
	float lo[3] = {0, 0, 0}, hi[3] = {1, 1, 1};
	struct grid g;
	make_scene(&g, 8, SC_RANDOM);
	CHECK_EQ(vd_transform_init(&t, lo, hi, 8), VD_OK);
	struct vd_svo s;
	grid_to_svo(&g, 0, 0, &s);
	for (int kind = VD_KIND_DAG; kind <= VD_KIND_SSVDAG; kind++) {
		struct vd_dag d;
		CHECK_EQ(vd_dag_from_svo(&d, &s, (uint32_t)kind, &opts, NULL), 0);
		uint64_t refs = 0;
		for (int l = 0; l < d.levels - 1; l++)
			refs += d.lv[l].refs;
		CHECK(refs * 4 > 2 * VD_CHUNK_FRAME_BYTES); /* DAGC: 3+ frames */
		snprintf(p1, sizeof p1, "%s/k%d.1.dag", dir, kind);
		snprintf(p3, sizeof p3, "%s/k%d.3.dag", dir, kind);
		CHECK_EQ(vd_dag_save_mt(&d, &t, p1, "tool=test", 1), VD_OK);
		CHECK_EQ(vd_dag_save_mt(&d, &t, p3, "tool=test", 3), VD_OK);
		CHECK(files_equal(p1, p3));
		for (int threads = 1; threads <= 2; threads++) {
			struct vd_chunk *ch;
			struct vd_dag e;
			CHECK_EQ(vd_chunk_open(&ch, p3, VD_KIND_ANY), VD_OK);
			CHECK_EQ(vd_dag_from_chunk_mt(&e, ch, VD_KIND_ANY, threads), VD_OK);
			CHECK(counts_equal(&d, &e));
			for (int l = 0; l < d.levels; l++) {
				CHECK(!memcmp(d.lv[l].mask, e.lv[l].mask, d.lv[l].nodes));
				if (l == d.levels - 1)
					continue;
				CHECK(!memcmp(d.lv[l].child, e.lv[l].child, d.lv[l].refs * 4));
				if (kind == VD_KIND_SSVDAG)
					CHECK(!memcmp(d.lv[l].refl, e.lv[l].refl, d.lv[l].refs));
			}
			vd_dag_release(&e);
			vd_chunk_free(ch);
		}
		vd_dag_release(&d);
	}
	svo_free(&s);
	grid_free(&g);
}

/* Save and load give back the same DAG; wrong kinds, truncation and a
 * corrupted reference are each refused. */
/* A whole small file as a NUL-terminated string, or NULL. */
static char *read_text(const char *path)
{
	FILE *f = fopen(path, "rb");
	if (!f) return NULL;
	char *t = calloc(1, 1 << 16);
	size_t n = t ? fread(t, 1, (1 << 16) - 1, f) : 0;
	(void)n;
	fclose(f);
	return t;
}

static void test_chunk_files(void)
{
	const char *dir = test_tmpdir("test_dag");
	char path[600], cut[600];
	struct vd_transform t;
	float lo[3] = {0, 0, 0}, hi[3] = {1, 2, 3};
	for (int kind = VD_KIND_DAG; kind <= VD_KIND_SSVDAG; kind++)
		for (int L = 1; L <= 5; L++) {
			struct grid g;
			make_scene(&g, L, SC_TILES);
			CHECK_EQ(vd_transform_init(&t, lo, hi, L), VD_OK);
			struct vd_svo s;
			int L0 = L >= 3 ? 1 : 0;
			grid_to_svo(&g, L0, 1 % (1u << (3 * L0)), &s);
			struct vd_dag d, e;
			CHECK_EQ(vd_dag_from_svo(&d, &s, (uint32_t)kind, &opts, NULL), 0);
			snprintf(path, sizeof path, "%s/k%d-L%d.dag", dir, kind, L);
			CHECK_EQ(vd_dag_save(&d, &t, path, "tool=test"), VD_OK);
			/* sections compressed side by side: the same bytes,
			 * and read back side by side the same DAG below */
			char path2[700];
			snprintf(path2, sizeof path2, "%s.mt", path);
			CHECK_EQ(vd_dag_save_mt(&d, &t, path2, "tool=test", 3), VD_OK);
			CHECK(files_equal(path, path2));
			struct vd_chunk_header h;
			struct vd_chunk *ch;
			CHECK_EQ(vd_chunk_open(&ch, path2, VD_KIND_ANY), VD_OK);
			CHECK_EQ(vd_dag_from_chunk_mt(&e, ch, VD_KIND_ANY, 2), VD_OK);
			CHECK(counts_equal(&d, &e));
			vd_dag_release(&e);
			vd_chunk_free(ch);
			CHECK_EQ(vd_dag_load(&e, &h, path, VD_KIND_ANY), VD_OK);
			CHECK_EQ(h.kind, kind);
			CHECK_EQ(h.level_count, L - L0 + 1);
			CHECK_EQ(h.level_nodes[L - L0], d.voxels);
			CHECK(counts_equal(&d, &e));
			CHECK_EQ(e.kind, kind);
			CHECK_EQ(e.cell_morton, d.cell_morton);
			for (int l = L0; l < L && d.lv[L0].nodes; l++) {
				CHECK(!memcmp(d.lv[l].mask, e.lv[l].mask, d.lv[l].nodes));
				if (l < L - 1)
					CHECK(!memcmp(d.lv[l].child, e.lv[l].child,
						      d.lv[l].refs * 4));
				if (l < L - 1 && kind == VD_KIND_SSVDAG)
					CHECK(!memcmp(d.lv[l].refl, e.lv[l].refl,
						      d.lv[l].refs));
			}
			struct vd_svo a, b;
			CHECK_EQ(vd_dag_to_svo(&d, &a), 0);
			CHECK_EQ(vd_dag_to_svo(&e, &b), 0);
			CHECK(a.count == s.count && b.count == s.count);
			CHECK(!memcmp(b.keys, s.keys, s.count * 8));
			CHECK(!memcmp(b.masks, s.masks, s.count * 8));
			svo_free(&a);
			svo_free(&b);
			vd_dag_release(&e);
			/* the other DAG kind, and an SVO file, are refused */
			CHECK_EQ(vd_dag_load(&e, NULL, path, kind == VD_KIND_DAG ?
					     VD_KIND_SSVDAG : VD_KIND_DAG),
				 VD_ERR_WRONG_KIND);
			vd_dag_release(&e);
			snprintf(cut, sizeof cut, "%s/k%d-L%d.svo", dir, kind, L);
			CHECK_EQ(vd_svo_save(&s, &t, cut, NULL), VD_OK);
			CHECK_EQ(vd_dag_load(&e, NULL, cut, VD_KIND_ANY),
				 VD_ERR_WRONG_KIND);
			CHECK(strstr(vd_error_detail(), "svo") != NULL);
			vd_dag_release(&e);
			/* the stage run takes the voxel, leaf and parent
			 * counts from the SVO file's header (L >= 3 here)
			 * instead of counting them: the same DAG and input
			 * statistics as vd_dag_from_svo */
			if (kind == VD_KIND_DAG) {
				char out[700], stats[800], *text;
				snprintf(out, sizeof out, "%s.run.dag", cut);
				const char *in[1] = {cut};
				struct vd_dag_job job = {.tool = "svo-to-dag",
					.kind = VD_KIND_DAG, .to_level = -1,
					.inputs = in, .n_inputs = 1,
					.output = out, .opts = opts, .quiet = 1};
				CHECK_EQ(vd_dag_run(&job), VD_OK);
				CHECK_EQ(vd_dag_load(&e, NULL, out, VD_KIND_DAG), VD_OK);
				CHECK(counts_equal(&d, &e));
				CHECK_EQ(e.voxels, d.voxels);
				for (int l = L0; l < L - 1 && d.lv[L0].nodes; l++)
					CHECK(!memcmp(d.lv[l].child, e.lv[l].child,
						      d.lv[l].refs * 4));
				vd_dag_release(&e);
				struct vd_dag_stats ds;
				struct vd_dag f;
				CHECK_EQ(vd_dag_from_svo(&f, &s, VD_KIND_DAG, &opts, &ds), VD_OK);
				vd_dag_release(&f);
				snprintf(stats, sizeof stats, "%s.stats.json", out);
				text = read_text(stats);
				char want[120];
				snprintf(want, sizeof want, "\"input_voxels\": %" PRIu64
					 ",", ds.input_voxels);
				CHECK(text && strstr(text, want) != NULL);
				snprintf(want, sizeof want, "\"memory_estimate_bytes\": %"
					 PRIu64 ",", ds.memory_estimate_bytes);
				CHECK(text && strstr(text, want) != NULL);
				free(text);
			}
			/* every cut of the file is an error, never a DAG */
			FILE *f = fopen(path, "rb");
			fseek(f, 0, SEEK_END);
			long size = ftell(f);
			fclose(f);
			snprintf(cut, sizeof cut, "%s/cut.dag", dir);
			for (long n = 0; n < size; n += (n < 200 ? 1 : 7)) {
				file_copy_prefix(path, cut, n);
				int err = vd_dag_load(&e, NULL, cut, VD_KIND_ANY);
				CHECK(err != VD_OK);
				vd_dag_release(&e);
			}
			svo_free(&s);
			vd_dag_release(&d);
			grid_free(&g);
		}
	/* content that passes the checksums but not validation */
	struct grid g;
	make_scene(&g, 4, SC_RANDOM);
	struct vd_svo s;
	grid_to_svo(&g, 0, 0, &s);
	struct vd_dag d, e;
	vd_dag_from_svo(&d, &s, VD_KIND_DAG, &opts, NULL);
	d.lv[0].child[0] = 999;
	CHECK_EQ(vd_dag_validate(&d), VD_ERR_CORRUPT);
	CHECK_EQ(vd_dag_save(&d, &t, path, NULL), VD_ERR_CORRUPT);
	d.lv[0].child[0] = 0;
	/* a brick that is not what its leaf masks say, first or last */
	CHECK_EQ(vd_dag_validate(&d), VD_OK);
	uint64_t nb = d.lv[d.levels - 2].nodes;
	for (uint64_t at = 0; at < nb; at += nb - 1 ? nb - 1 : 1) {
		d.bricks[at] ^= 1ull << 63;
		CHECK_EQ(vd_dag_validate(&d), VD_ERR_CORRUPT);
		CHECK(strstr(vd_error_detail(), "disagrees with its masks") != NULL);
		d.bricks[at] ^= 1ull << 63;
	}
	CHECK_EQ(vd_dag_validate(&d), VD_OK);
	d.voxels++;
	snprintf(path, sizeof path, "%s/badcount.dag", dir);
	CHECK_EQ(vd_dag_save(&d, &t, path, NULL), VD_OK);
	CHECK_EQ(vd_dag_load(&e, NULL, path, VD_KIND_DAG), VD_ERR_CORRUPT);
	CHECK(strstr(vd_error_detail(), "voxels") != NULL);
	vd_dag_release(&e);
	vd_dag_release(&d);
	svo_free(&s);
	grid_free(&g);
}

/* Real meshes: voxelize monolithically and with L0 = 1, 2, 3; build DAG
 * and SSVDAG chunks, merge them to the root (all at once and 8 siblings at
 * a time), and check: the voxels equal the SVO chunks', and the per-level
 * counts equal the monolithic build's. */
static void real_mesh(const char *mesh, int L)
{
	/* Voxelized once, at L0 = 3; the SVO chunks of coarser cells are the
	 * concatenations of their subcells' bricks (Morton order), so every
	 * L0 is tested on the voxelizer's own output without re-running it
	 * (which under ASan dominated the test's time). */
	const char *dir = test_tmpdir("test_dag_mesh");
	struct vd_voxelize_result res;
	int err = test_voxelize(mesh, L, 3, dir, &res);
	CHECK_EQ(err, VD_OK);
	if (err)
		return;
	struct vd_svo *fine = calloc(512, sizeof *fine);
	uint64_t nfine = 0;
	for (uint64_t c = 0; c < 512; c++) {
		char name[64], path[800];
		vd_chunk_file_name(name, sizeof name, 3, c, "svo");
		snprintf(path, sizeof path, "%s/%s", dir, name);
		FILE *f = fopen(path, "rb");
		if (!f) continue;
		fclose(f);
		CHECK_EQ(vd_svo_load(&fine[nfine++], NULL, path), VD_OK);
	}
	CHECK_EQ(nfine, res.chunks);
	struct vd_dag mono[2];
	memset(mono, 0, sizeof mono);
	for (int L0 = 0; L0 <= 3; L0++) {
		uint64_t cells = 1ULL << (3 * L0), n = 0;
		struct vd_svo *svo = calloc(cells, sizeof *svo);
		const struct vd_svo **sp = calloc(cells, sizeof *sp);
		struct vd_dag *parts[2];
		parts[0] = calloc(cells, sizeof(struct vd_dag));
		parts[1] = calloc(cells, sizeof(struct vd_dag));
		for (uint64_t i = 0; i < nfine;) {
			uint64_t cell = fine[i].cell_morton >> 3 * (3 - L0), j = i;
			size_t bricks = 0;
			for (; j < nfine && fine[j].cell_morton >> 3 * (3 - L0) == cell; j++)
				bricks += fine[j].count;
			struct vd_svo *v = &svo[n];
			*v = (struct vd_svo){L, L0, cell, 0, malloc(bricks * 8),
					     malloc(bricks * 8)};
			for (; i < j; i++) {
				memcpy(v->keys + v->count, fine[i].keys, fine[i].count * 8);
				memcpy(v->masks + v->count, fine[i].masks, fine[i].count * 8);
				v->count += fine[i].count;
			}
			sp[n] = v;
			for (int k = 0; k < 2; k++)
				CHECK_EQ(vd_dag_from_svo(&parts[k][n], v,
							 k ? VD_KIND_SSVDAG : VD_KIND_DAG,
							 &opts, NULL), VD_OK);
			n++;
		}
		for (int k = 0; k < 2; k++) {
			struct vd_dag root;
			if (L0 == 0) {
				root = parts[k][0];
				parts[k][0] = (struct vd_dag){0};
			} else {
				const struct vd_dag **pp = malloc(n * sizeof *pp);
				for (uint64_t i = 0; i < n; i++) pp[i] = &parts[k][i];
				CHECK_EQ(vd_dag_merge(&root, pp, n, k ? VD_KIND_SSVDAG :
						      VD_KIND_DAG, 0, &opts, NULL), 0);
				free(pp);
			}
			CHECK_EQ(vd_dag_validate(&root), VD_OK);
			CHECK_EQ(root.voxels, res.voxels);
			/* the parallel passes number nodes as the serial ones */
			if (L0 == 0 || L0 == 2) {
				struct vd_dag par;
				struct vd_dag_opts po = {3, 0, NULL};
				if (L0 == 0)
					CHECK_EQ(vd_dag_from_svo(&par, &svo[0], root.kind,
								 &po, NULL), 0);
				else {
					const struct vd_dag **pp = malloc(n * sizeof *pp);
					for (uint64_t i = 0; i < n; i++) pp[i] = &parts[k][i];
					CHECK_EQ(vd_dag_merge(&par, pp, n, root.kind, 0,
							      &po, NULL), 0);
					free(pp);
				}
				CHECK(dags_identical(&par, &root));
				vd_dag_release(&par);
			}
			/* the merge that frees its parts as it reads them makes
			 * the same bytes, serial and parallel, and releases them */
			for (int t = 0; t < 2 && L0 > 0; t++) {
				struct vd_dag own, *cp = calloc(n, sizeof *cp);
				struct vd_dag_opts po = {3, 0, NULL};
				for (uint64_t i = 0; i < n; i++)
					CHECK_EQ(vd_dag_from_svo(&cp[i], &svo[i],
								 k ? VD_KIND_SSVDAG : VD_KIND_DAG,
								 &opts, NULL), VD_OK);
				CHECK_EQ(vd_dag_merge_consume(&own, cp, n, root.kind, 0,
							      t ? &po : &opts, NULL), 0);
				CHECK(dags_identical(&own, &root));
				for (uint64_t i = 0; i < n; i++)
					CHECK(!cp[i].levels && !cp[i].lv[L - 1].mask);
				vd_dag_release(&own);
				free(cp);
			}
			struct vd_dag_diff diff;
			CHECK_EQ(vd_dag_compare_svo(&root, sp, n, &diff), VD_OK);
			CHECK_EQ(diff.differing_voxels, 0);
			if (L0 == 0)
				mono[k] = root;
			else {
				CHECK(counts_equal(&root, &mono[k]));
				vd_dag_release(&root);
			}
		}
		for (uint64_t i = 0; i < n; i++) {
			vd_svo_release(&svo[i]);
			vd_dag_release(&parts[0][i]);
			vd_dag_release(&parts[1][i]);
		}
		free(svo);
		free(sp);
		free(parts[0]);
		free(parts[1]);
	}
	for (uint64_t i = 0; i < nfine; i++) vd_svo_release(&fine[i]);
	free(fine);
	for (int l = 0; l < L; l++) CHECK(mono[1].lv[l].nodes <= mono[0].lv[l].nodes);
	vd_dag_release(&mono[0]);
	vd_dag_release(&mono[1]);
}

static void test_real_meshes(void)
{
	char dragon[600];
	snprintf(dragon, sizeof dragon, "%s/stanford_dragon_res2.ply",
		 test_shared_data());
	FILE *f = fopen(dragon, "rb");
	for (int L = 8; L <= 10; L += 2) {
		real_mesh("tests/data/bunny.ply", L);
		if (f) real_mesh(dragon, L);
	}
	if (f)
		fclose(f);
	else
		printf("SKIP test_real_meshes_dragon (no %s)\n", dragon);
}

/* Writes a DAG chunk by hand: sections as given (NULL: omitted). */
static int write_raw(const char *path, uint32_t kind, int L, int L0,
		     const uint64_t *counts, const void *m, size_t mn,
		     const void *c, size_t cn, const void *r, size_t rn)
{
	struct vd_chunk_header h = {0};
	h.kind = kind;
	h.levels = (uint32_t)L;
	h.chunk_level = (uint32_t)L0;
	h.level_count = (uint32_t)(L - L0 + 1);
	float lo[3] = {0, 0, 0}, hi[3] = {1, 1, 1};
	vd_transform_init(&h.transform, lo, hi, L);
	memcpy(h.level_nodes, counts, h.level_count * 8);
	struct vd_chunk_writer *w;
	int err = vd_chunk_writer_open(&w, path, &h, NULL);
	if (err) return err;
	if (m) vd_chunk_writer_section(w, VD_TAG_DAGM, m, mn);
	if (c) vd_chunk_writer_section(w, VD_TAG_DAGC, c, cn);
	if (r) vd_chunk_writer_section(w, VD_TAG_DAGR, r, rn);
	return vd_chunk_writer_commit(w);
}

/* Files whose checksums are right but whose content is not: each is
 * refused as corrupt, with a detail naming what is wrong. The good file
 * is L = 3: a root with children 0 and 7, both brick node 0, whose child 0
 * is leaf 0 (mask 0x81) and child 3 leaf 1 (mask 0x01): 6 voxels. */
static void test_crafted_files(void)
{
	const char *dir = test_tmpdir("test_dag_crafted");
	char path[600];
	snprintf(path, sizeof path, "%s/x.dag", dir);
	struct vd_dag d;
	struct {
		const char *name, *detail;
		uint32_t kind;
		uint64_t counts[4];
		uint8_t masks[4];
		uint32_t child[4];
		uint8_t refl[4];
		size_t msize, nref;
	} cases[] = {
		{"good", NULL, VD_KIND_DAG, {1, 1, 2, 6}, {0x81, 0x09, 0x81, 0x01},
		 {0, 0, 0, 1}, {0}, 4, 4},
		{"good ssvdag", NULL, VD_KIND_SSVDAG, {1, 1, 2, 6},
		 {0x81, 0x09, 0x81, 0x01}, {0, 0, 0, 1}, {0, 0, 0, 0}, 4, 4},
		{"zero mask", "empty mask", VD_KIND_DAG, {1, 1, 2, 6},
		 {0x81, 0x09, 0x00, 0x01}, {0, 0, 0, 1}, {0}, 4, 4},
		{"index out of range", "child 5", VD_KIND_DAG, {1, 1, 2, 6},
		 {0x81, 0x09, 0x81, 0x01}, {0, 5, 0, 1}, {0}, 4, 4},
		{"unreferenced leaf", "never referenced", VD_KIND_DAG, {1, 1, 2, 6},
		 {0x81, 0x09, 0x81, 0x01}, {0, 0, 0, 0}, {0}, 4, 4},
		{"reflection 9", "reflection 9", VD_KIND_SSVDAG, {1, 1, 2, 6},
		 {0x81, 0x09, 0x81, 0x01}, {0, 0, 0, 1}, {0, 9, 0, 0}, 4, 4},
		{"mask section size", "mask section", VD_KIND_DAG, {1, 1, 2, 6},
		 {0x81, 0x09, 0x81, 0x01}, {0, 0, 0, 1}, {0}, 3, 4},
		{"reference section size", "reference sections", VD_KIND_DAG,
		 {1, 1, 2, 6}, {0x81, 0x09, 0x81, 0x01}, {0, 0, 0, 1}, {0}, 4, 3},
		{"two roots", "2 roots", VD_KIND_DAG, {2, 1, 1, 6},
		 {0x01, 0x01, 0x01, 0x01}, {0, 0, 0, 0}, {0}, 4, 3},
		{"voxel count", "voxels", VD_KIND_DAG, {1, 1, 2, 7},
		 {0x81, 0x09, 0x81, 0x01}, {0, 0, 0, 1}, {0}, 4, 4},
	};
	for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
		uint8_t cbytes[16];
		for (int k = 0; k < 4; k++)
			for (int b = 0; b < 4; b++)
				cbytes[4 * k + b] = (uint8_t)(cases[i].child[k] >> 8 * b);
		int sym = cases[i].kind == VD_KIND_SSVDAG;
		CHECK_EQ(write_raw(path, cases[i].kind, 3, 0, cases[i].counts,
				   cases[i].masks, cases[i].msize, cbytes,
				   4 * cases[i].nref, sym ? cases[i].refl : NULL,
				   cases[i].nref), VD_OK);
		int err = vd_dag_load(&d, NULL, path, VD_KIND_ANY);
		if (!cases[i].detail) {
			CHECK_EQ(err, VD_OK);
			if (!err) {
				CHECK_EQ(d.voxels, 6);
				CHECK(d.bricks[0] == (0x81ULL | 0x01ULL << 24));
			}
		} else {
			CHECK_EQ(err, VD_ERR_CORRUPT);
			if (!strstr(vd_error_detail(), cases[i].detail))
				fprintf(stderr, "  %s: detail '%s'\n", cases[i].name,
					vd_error_detail());
			CHECK(strstr(vd_error_detail(), cases[i].detail) != NULL);
		}
		vd_dag_release(&d);
	}
	/* an SSVDAG without its reflections */
	CHECK_EQ(write_raw(path, VD_KIND_SSVDAG, 3, 0, cases[0].counts,
			   cases[0].masks, 4, (uint8_t[16]){0, [12] = 1}, 16,
			   NULL, 0), VD_OK);
	CHECK_EQ(vd_dag_load(&d, NULL, path, VD_KIND_ANY), VD_ERR_CORRUPT);
	CHECK(strstr(vd_error_detail(), "DAGR") != NULL ||
	      strstr(vd_error_detail(), "missing") != NULL);
	vd_dag_release(&d);
}

int main(void)
{
	RUN(test_lossless_monolithic);
	RUN(test_minimal_brute_force);
	RUN(test_chunked_equals_monolithic);
	RUN(test_merge_partial_and_mixed);
	RUN(test_merge_estimate);
	RUN(test_merge_errors);
	RUN(test_edge_cases);
	RUN(test_chunk_files);
	RUN(test_framed_sections);
	RUN(test_crafted_files);
	RUN(test_real_meshes);
	return CHECK_DONE();
}
