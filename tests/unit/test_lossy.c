/* test_lossy.c - lossy SVDAGs against independent references on real
 * scenes: effective reference counts against subtree occurrences counted in
 * the expanded SVO, similar pairs against all-pairs brute force over the
 * expanded voxels, clusters against Debian's mcl, the voxels changed
 * against a comparison of both expansions, minimality against a rebuild. */
#include "check.h"
#include "scene.h"

#include <sys/wait.h>
#include <unistd.h>

static struct vd_dag_opts opts = {1, 0, NULL};

static uint64_t fmix(uint64_t h, uint64_t v)
{
	h ^= v + 0x9e3779b97f4a7c15ULL + (h << 6) + (h >> 2);
	h ^= h >> 31;
	h *= 0xbf58476d1ce4e5b9ULL;
	h ^= h >> 29;
	return h;
}

/* A scene: the SVO of one chunk and its DAG. */
struct scene {
	struct vd_svo svo;
	struct vd_dag dag;
	int ok;
};

static void scene_load(struct scene *s, const char *mesh, int L)
{
	struct vd_transform t;
	memset(s, 0, sizeof *s);
	if (!test_voxelize_one(mesh, L, test_tmpdir("test_lossy"), &s->svo, &t))
		return;
	CHECK_EQ(vd_dag_from_svo(&s->dag, &s->svo, VD_KIND_DAG, &opts, NULL),
		 VD_OK);
	s->ok = s->dag.lv[0].nodes == 1;
	CHECK(s->ok);
}

static void scene_free(struct scene *s)
{
	vd_svo_release(&s->svo);
	vd_dag_release(&s->dag);
}

/* ---- the expanded subtree of a DAG node: (relative brick key, brick)
 * pairs in Morton order, bricks from dag->bricks (the builder's) */
struct blist {
	uint64_t *key, *brick;
	size_t n, cap;
};

static void blist_add(struct blist *b, uint64_t k, uint64_t v)
{
	if (b->n == b->cap) {
		b->cap = b->cap ? 2 * b->cap : 64;
		b->key = realloc(b->key, b->cap * 8);
		b->brick = realloc(b->brick, b->cap * 8);
	}
	b->key[b->n] = k;
	b->brick[b->n++] = v;
}

static void expand(const struct vd_dag *d, int l, uint32_t node, uint64_t rel,
		   struct blist *out)
{
	int L = d->levels;
	if (l == L - 2) {
		blist_add(out, rel, d->bricks[node]);
		return;
	}
	const struct vd_dag_level *lv = &d->lv[l];
	uint64_t j = lv->first[node];
	for (unsigned s = 0; s < 8; s++)
		if (lv->mask[node] >> s & 1)
			expand(d, l + 1, lv->child[j++], rel << 3 | s, out);
}

static uint64_t blist_hash(const struct blist *b)
{
	uint64_t h = 1;
	for (size_t i = 0; i < b->n; i++)
		h = fmix(fmix(h, b->key[i]), b->brick[i]);
	return h;
}

static int u64_cmp(const void *a, const void *b)
{
	uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
	return x < y ? -1 : x > y;
}

/* Occurrences of the subtree with fingerprint h among the level-l cells of
 * the SVO: sorted fingerprints of every non-empty cell. */
static uint64_t *svo_cell_hashes(const struct vd_svo *s, int l, size_t *n)
{
	int L = s->levels, sh = 3 * (L - 2 - l);
	uint64_t *out = malloc((s->count + 1) * 8);
	size_t k = 0;
	for (size_t i = 0; i < s->count;) {
		uint64_t cell = s->keys[i] >> sh, h = 1;
		size_t j = i;
		for (; j < s->count && s->keys[j] >> sh == cell; j++)
			h = fmix(fmix(h, s->keys[j] & ((1ull << sh) - 1)), s->masks[j]);
		out[k++] = h;
		i = j;
	}
	qsort(out, k, 8, u64_cmp);
	*n = k;
	return out;
}

static uint64_t count_in(const uint64_t *v, size_t n, uint64_t x)
{
	size_t lo = 0, hi = n;
	while (lo < hi) {
		size_t mid = lo + (hi - lo) / 2;
		if (v[mid] < x) lo = mid + 1;
		else hi = mid;
	}
	uint64_t c = 0;
	for (size_t i = lo; i < n && v[i] == x; i++) c++;
	return c;
}

static void check_effective_refs(const struct scene *s)
{
	const struct vd_dag *d = &s->dag;
	int L = d->levels;
	uint64_t *eff[VD_MAX_LEVELS];
	CHECK_EQ(vd_lossy_effective_refs(d, L - 2, eff), VD_OK);
	for (int l = 0; l <= L - 2; l++) {
		size_t n;
		uint64_t *hs = svo_cell_hashes(&s->svo, l, &n);
		uint64_t bad = 0, total = 0;
		for (uint64_t i = 0; i < d->lv[l].nodes; i++) {
			struct blist b = {0};
			expand(d, l, (uint32_t)i, 0, &b);
			uint64_t c = count_in(hs, n, blist_hash(&b));
			if (c != eff[l][i]) bad++;
			total += c;
			free(b.key);
			free(b.brick);
		}
		CHECK_EQ(bad, 0);
		CHECK_EQ(total, n); /* every cell is some node's occurrence */
		free(hs);
	}
	for (int l = 0; l < VD_MAX_LEVELS; l++) free(eff[l]);
}

static void test_effective_refs(void)
{
	struct scene s;
	for (int L = 7; L <= 8; L++) {
		scene_load(&s, "tests/data/bunny.ply", L);
		if (s.ok) check_effective_refs(&s);
		scene_free(&s);
	}
}

/* ---- similar pairs, all-pairs brute force over the expanded voxels:
 * height 2 one voxel apart; taller levels the same non-empty 2x2x2 cells
 * (topology but the last level) and at most floor(h^2 p) voxels apart */
static int edge_cmp(const void *a, const void *b)
{
	const struct vd_lossy_edge *x = a, *y = b;
	if (x->u != y->u) return x->u < y->u ? -1 : 1;
	return x->v < y->v ? -1 : x->v > y->v;
}

static void check_pairs(const struct scene *s, uint64_t R, double p)
{
	const struct vd_dag *d = &s->dag;
	int L = d->levels;
	uint64_t *eff[VD_MAX_LEVELS];
	CHECK_EQ(vd_lossy_effective_refs(d, L - 2, eff), VD_OK);
	for (int l = L - 2; l >= 1; l--) {
		int h = L - l;
		int64_t m = h == 2 ? 1 : (int64_t)(h * h * p);
		uint32_t *cand = malloc(d->lv[l].nodes * 4);
		size_t nc = 0;
		for (uint64_t i = 0; i < d->lv[l].nodes; i++)
			if (eff[l][i] <= R) cand[nc++] = (uint32_t)i;
		struct blist *ex = calloc(nc + 1, sizeof *ex);
		for (size_t i = 0; i < nc; i++) expand(d, l, cand[i], 0, &ex[i]);
		struct vd_lossy_edge *want = NULL;
		size_t nw = 0, cw = 0;
		for (size_t a = 0; a < nc; a++)
			for (size_t b = a + 1; b < nc; b++) {
				const struct blist *x = &ex[a], *y = &ex[b];
				if (x->n != y->n) continue;
				int64_t diff = 0, same = 1;
				for (size_t i = 0; i < x->n && same; i++) {
					if (x->key[i] != y->key[i]) same = 0;
					for (int byte = 0; byte < 8 && h > 2; byte++)
						if (!(x->brick[i] >> 8 * byte & 255) !=
						    !(y->brick[i] >> 8 * byte & 255))
							same = 0;
					diff += __builtin_popcountll(x->brick[i] ^ y->brick[i]);
				}
				if (!same || diff > m) continue;
				if (nw == cw) {
					cw = cw ? 2 * cw : 64;
					want = realloc(want, cw * sizeof *want);
				}
				want[nw++] = (struct vd_lossy_edge){cand[a], cand[b],
					(uint32_t)diff, 1.0 - (double)diff / (double)(m + 1)};
			}
		if (nw) qsort(want, nw, sizeof *want, edge_cmp);
		struct vd_lossy_edge *got;
		size_t ng;
		uint64_t ncand;
		CHECK_EQ(vd_lossy_similar_pairs(d, l, eff[l], R, p, 2, &got, &ng,
						&ncand), VD_OK);
		CHECK_EQ(ncand, nc);
		CHECK_EQ(ng, nw);
		uint64_t bad = 0;
		for (size_t i = 0; i < ng && i < nw; i++)
			if (got[i].u != want[i].u || got[i].v != want[i].v ||
			    got[i].diff != want[i].diff || got[i].s != want[i].s)
				bad++;
		CHECK_EQ(bad, 0);
		if (ng != nw || bad)
			fprintf(stderr, "  level %d (h %d, R %" PRIu64 ", p %g): %zu "
				"pairs, brute force %zu\n", l, h, R, p, ng, nw);
		free(got);
		free(want);
		for (size_t i = 0; i < nc; i++) {
			free(ex[i].key);
			free(ex[i].brick);
		}
		free(ex);
		free(cand);
	}
	for (int l = 0; l < VD_MAX_LEVELS; l++) free(eff[l]);
}

static void test_similar_pairs(void)
{
	struct scene s;
	scene_load(&s, "tests/data/bunny.ply", 7);
	if (s.ok) {
		check_pairs(&s, 1, 1.0);
		check_pairs(&s, 3, 1.0);
		check_pairs(&s, 1, 0.5);
		check_pairs(&s, 2, 3.0);
	}
	scene_free(&s);
	scene_load(&s, "tests/data/bunny.ply", 8);
	if (s.ok) check_pairs(&s, 1, 1.0);
	scene_free(&s);
}

/* ---- clusters against Debian's mcl on the same graph (abc format, node
 * labels, weights s; mcl's defaults: loops at the largest edge weight,
 * -P 10000 -S 1100; the same inflation) */
static int have_mcl(void)
{
	return system("command -v mcl >/dev/null 2>&1") == 0;
}

static void check_mcl(const struct scene *s, int l, double inflation,
		      uint64_t *compared)
{
	const struct vd_dag *d = &s->dag;
	int L = d->levels;
	uint64_t *eff[VD_MAX_LEVELS];
	CHECK_EQ(vd_lossy_effective_refs(d, l, eff), VD_OK);
	struct vd_lossy_edge *e;
	size_t ne;
	uint64_t nc;
	CHECK_EQ(vd_lossy_similar_pairs(d, l, eff[l], 1, 1.0, 1, &e, &ne, &nc),
		 VD_OK);
	for (int k = 0; k < VD_MAX_LEVELS; k++) free(eff[k]);
	if (!ne) {
		free(e);
		return;
	}
	static int run;
	const char *dir = "out/tmp/test_lossy_mcl";
	char in[800], out[800], cmd[2000];
	snprintf(in, sizeof in, "%s/graph%d.abc", dir, run);
	snprintf(out, sizeof out, "%s/clusters%d.txt", dir, run++);
	FILE *f = fopen(in, "w");
	CHECK(f != NULL);
	if (!f) return;
	for (size_t i = 0; i < ne; i++)
		fprintf(f, "%u\t%u\t%.17g\n", e[i].u, e[i].v, e[i].s);
	fclose(f);
	snprintf(cmd, sizeof cmd, "mcl '%s' --abc -I %g -o '%s' 2>/dev/null",
		 in, inflation, out);
	CHECK_EQ(system(cmd), 0);
	uint32_t n = (uint32_t)d->lv[l].nodes;
	uint32_t *cl = malloc(n * 4ull);
	CHECK_EQ(vd_lossy_mcl(n, e, ne, inflation, 2, cl), VD_OK);
	/* every mcl cluster must be exactly one of ours */
	f = fopen(out, "r");
	CHECK(f != NULL);
	uint32_t *size = calloc(n, 4), *seen = calloc(n, 4);
	for (uint32_t i = 0; i < n; i++) size[cl[i]]++;
	char line[1 << 16];
	uint64_t bad = 0, members = 0, lines = 0;
	while (f && fgets(line, sizeof line, f)) {
		char *p = line, *end;
		uint32_t first = UINT32_MAX, cnt = 0;
		for (;;) {
			unsigned long v = strtoul(p, &end, 10);
			if (end == p) break;
			p = end;
			if (first == UINT32_MAX) first = (uint32_t)v;
			if (v >= n || cl[v] != cl[first] || seen[v]++) bad++;
			cnt++;
		}
		if (first != UINT32_MAX && size[cl[first]] != cnt) bad++;
		members += cnt;
		lines++;
	}
	if (f) fclose(f);
	/* every graph node is in one mcl cluster */
	uint64_t gn = 0;
	for (uint32_t i = 0; i < n; i++) seen[i] = 0;
	for (size_t i = 0; i < ne; i++) {
		gn += !seen[e[i].u]++;
		gn += !seen[e[i].v]++;
	}
	CHECK_EQ(members, gn);
	/* height 2: every weight is 0.5, so symmetric neighbourhoods are
	 * ties that mcl breaks by its single-precision rounding (checked on a
	 * 10-node component: an exact double-precision MCL, ours, splits it
	 * one way, mcl the other): mismatching members under 10% of its clusters.
	 * Taller levels: weighted, no ties, every cluster equal. */
	if (L - l == 2)
		CHECK(bad * 10 <= lines);
	else
		CHECK_EQ(bad, 0);
	if (bad)
		fprintf(stderr, "  level %d of %d: %" PRIu64 " mismatches in %"
			PRIu64 " mcl clusters\n", l, L, bad, lines);
	*compared += lines;
	free(size);
	free(seen);
	free(cl);
	free(e);
}

static void test_mcl(void)
{
	if (!have_mcl()) {
		printf("SKIP test_mcl (no mcl; apt-get install mcl)\n");
		return;
	}
	char dragon[600];
	snprintf(dragon, sizeof dragon, "%s/stanford_dragon_res4.ply",
		 test_shared_data());
	FILE *f = fopen(dragon, "rb");
	const char *mesh[2] = {"tests/data/bunny.ply", dragon};
	uint64_t compared = 0;
	test_tmpdir("test_lossy_mcl");
	for (int m = 0; m < (f ? 2 : 1); m++) {
		struct scene s;
		scene_load(&s, mesh[m], 8);
		for (int l = 6; l >= 4 && s.ok; l--) {
			check_mcl(&s, l, 2.0, &compared);
			check_mcl(&s, l, 1.4, &compared);
		}
		scene_free(&s);
	}
	CHECK(compared > 100); /* non-trivial graphs were compared */
	if (f) fclose(f);
	else printf("SKIP test_mcl_dragon (no %s)\n", dragon);
}

/* ---- the stage: changed voxels by comparing both expansions, minimality
 * by rebuilding from the voxels, --max-refs 0 the identity, --threads */
static void svo_diff(const struct vd_svo *a, const struct vd_svo *b,
		     uint64_t *only_a, uint64_t *only_b)
{
	size_t i = 0, j = 0;
	*only_a = *only_b = 0;
	while (i < a->count || j < b->count) {
		if (j == b->count || (i < a->count && a->keys[i] < b->keys[j])) {
			*only_a += (uint64_t)__builtin_popcountll(a->masks[i++]);
		} else if (i == a->count || b->keys[j] < a->keys[i]) {
			*only_b += (uint64_t)__builtin_popcountll(b->masks[j++]);
		} else {
			*only_a += (uint64_t)__builtin_popcountll(a->masks[i] & ~b->masks[j]);
			*only_b += (uint64_t)__builtin_popcountll(b->masks[j] & ~a->masks[i]);
			i++;
			j++;
		}
	}
}

static int dag_copy(struct vd_dag *t, const struct vd_dag *s)
{
	/* via the chunk format: save and load */
	struct vd_transform tr;
	float lo[3] = {0, 0, 0}, hi[3] = {1, 1, 1};
	if (vd_transform_init(&tr, lo, hi, s->levels)) return -1;
	char path[800];
	snprintf(path, sizeof path, "%s/copy.dag", test_tmpdir("test_lossy_copy"));
	if (vd_dag_save(s, &tr, path, "test")) return -1;
	return vd_dag_load(t, NULL, path, VD_KIND_DAG);
}

static int dags_identical(const struct vd_dag *a, const struct vd_dag *b)
{
	if (a->levels != b->levels || a->voxels != b->voxels) return 0;
	for (int l = a->chunk_level; l < a->levels; l++) {
		const struct vd_dag_level *x = &a->lv[l], *y = &b->lv[l];
		if (x->nodes != y->nodes || x->refs != y->refs) return 0;
		if (x->nodes && memcmp(x->mask, y->mask, x->nodes)) return 0;
		if (x->refs && memcmp(x->child, y->child, x->refs * 4)) return 0;
	}
	return 1;
}

static void check_stage(const struct scene *s, double p, uint64_t R)
{
	struct vd_dag d = {0}, d2 = {0};
	CHECK_EQ(dag_copy(&d, &s->dag), VD_OK);
	CHECK_EQ(dag_copy(&d2, &s->dag), VD_OK);
	struct vd_lossy_opts o = {2.0, p, R, 1, 0, 0, 0};
	struct vd_lossy_stats st, st2;
	CHECK_EQ(vd_lossy_cluster(&d, &o, &st), VD_OK);
	o.threads = 3;
	CHECK_EQ(vd_lossy_cluster(&d2, &o, &st2), VD_OK);
	CHECK(dags_identical(&d, &d2)); /* any --threads */
	CHECK_EQ(vd_dag_validate(&d), VD_OK);
	/* changed voxels: both expansions compared brick by brick */
	struct vd_svo a, b;
	CHECK_EQ(vd_dag_to_svo(&s->dag, &a), VD_OK);
	CHECK_EQ(vd_dag_to_svo(&d, &b), VD_OK);
	uint64_t oa, ob;
	svo_diff(&a, &b, &oa, &ob);
	CHECK_EQ(st.voxels_cleared, oa);
	CHECK_EQ(st.voxels_set, ob);
	uint64_t vb = 0;
	for (size_t i = 0; i < b.count; i++)
		vb += (uint64_t)__builtin_popcountll(b.masks[i]);
	CHECK_EQ(st.voxels_after, vb);
	CHECK_EQ(d.voxels, vb);
	CHECK_EQ(st.voxels_before, s->dag.voxels);
	uint64_t nodes = 0;
	for (int l = 0; l < d.levels; l++) nodes += d.lv[l].nodes;
	CHECK_EQ(st.nodes_after, nodes);
	if (R == 0) {
		CHECK(dags_identical(&d, &s->dag));
		CHECK_EQ(oa + ob, 0);
	} else {
		CHECK(st.nodes_after < st.nodes_before);
		CHECK(oa + ob > 0);
	}
	/* still minimal: the DAG of its voxels has the same node counts */
	struct vd_dag r = {0};
	CHECK_EQ(vd_dag_from_svo(&r, &b, VD_KIND_DAG, &opts, NULL), VD_OK);
	for (int l = 0; l < d.levels; l++)
		CHECK_EQ(r.lv[l].nodes, d.lv[l].nodes);
	vd_dag_release(&r);
	vd_svo_release(&a);
	vd_svo_release(&b);
	vd_dag_release(&d);
	vd_dag_release(&d2);
}

static void test_stage(void)
{
	struct scene s;
	scene_load(&s, "tests/data/bunny.ply", 8);
	if (s.ok) {
		check_stage(&s, 1.0, 1);
		check_stage(&s, 2.0, 3);
		check_stage(&s, 1.0, 0);
	}
	scene_free(&s);
	char dragon[600];
	snprintf(dragon, sizeof dragon, "%s/stanford_dragon_res4.ply",
		 test_shared_data());
	FILE *f = fopen(dragon, "rb");
	if (!f) {
		printf("SKIP test_stage_dragon (no %s)\n", dragon);
		return;
	}
	fclose(f);
	scene_load(&s, dragon, 9);
	if (s.ok) check_stage(&s, 1.0, 1);
	scene_free(&s);
}

static void test_bad_input(void)
{
	struct scene s;
	scene_load(&s, "tests/data/bunny.ply", 6);
	if (!s.ok) {
		scene_free(&s);
		return;
	}
	struct vd_lossy_opts o = {2.0, 1.0, 1, 1, 0, 0, 0};
	struct vd_lossy_stats st;
	o.inflation = 1.0;
	CHECK_EQ(vd_lossy_cluster(&s.dag, &o, &st), VD_ERR_ARG);
	o.inflation = 2.0;
	o.diff_factor = -1;
	CHECK_EQ(vd_lossy_cluster(&s.dag, &o, &st), VD_ERR_ARG);
	o.diff_factor = 1.0;
	struct vd_dag sym = {0};
	CHECK_EQ(vd_dag_from_svo(&sym, &s.svo, VD_KIND_SSVDAG, &opts, NULL), VD_OK);
	CHECK_EQ(vd_lossy_cluster(&sym, &o, &st), VD_ERR_WRONG_KIND);
	vd_dag_release(&sym);
	scene_free(&s);
}

/* One connected component of more than one block of matrix columns (4096):
 * a 90x90 grid with weights from a fixed generator, no ties. Its blocks
 * are expanded in parallel: the clusters equal mcl's, and the same for 1
 * and 2 threads. */
static void test_mcl_big(void)
{
	if (!have_mcl()) {
		printf("SKIP test_mcl_big (no mcl)\n");
		return;
	}
	enum { W = 90, N = W * W };
	struct vd_lossy_edge *e = malloc(2 * N * sizeof *e);
	size_t ne = 0;
	uint64_t x = 88172645463325252ull;
	for (uint32_t i = 0; i < N; i++)
		for (int k = 0; k < 2; k++) {
			uint32_t j = k ? i + W : i + 1;
			if ((k && j >= N) || (!k && (i + 1) % W == 0)) continue;
			x ^= x << 13;
			x ^= x >> 7;
			x ^= x << 17;
			double w = 0.5 + (double)(x >> 11) / 9007199254740992.0 / 2;
			e[ne++] = (struct vd_lossy_edge){i, j, 1, w};
		}
	/* sorted by (u, v) as the stage gives them */
	qsort(e, ne, sizeof *e, edge_cmp);
	const char *dir = test_tmpdir("test_lossy_mcl_big");
	char in[800], out[800], cmd[2000];
	snprintf(in, sizeof in, "%s/grid.abc", dir);
	snprintf(out, sizeof out, "%s/clusters.txt", dir);
	FILE *f = fopen(in, "w");
	CHECK(f != NULL);
	if (!f) {
		free(e);
		return;
	}
	for (size_t i = 0; i < ne; i++)
		fprintf(f, "%u\t%u\t%.17g\n", e[i].u, e[i].v, e[i].s);
	fclose(f);
	snprintf(cmd, sizeof cmd, "mcl '%s' --abc -I 2 -o '%s' 2>/dev/null", in, out);
	CHECK_EQ(system(cmd), 0);
	uint32_t *c1 = malloc(N * 4), *c2 = malloc(N * 4), *seen = calloc(N, 4);
	CHECK_EQ(vd_lossy_mcl(N, e, ne, 2.0, 1, c1), VD_OK);
	CHECK_EQ(vd_lossy_mcl(N, e, ne, 2.0, 2, c2), VD_OK);
	CHECK(!memcmp(c1, c2, N * 4));
	/* every mcl line is exactly one of our clusters, each node once */
	uint32_t *size = calloc(N, 4);
	for (uint32_t i = 0; i < N; i++) size[c1[i]]++;
	f = fopen(out, "r");
	CHECK(f != NULL);
	uint64_t bad = 0, members = 0, lines = 0;
	char line[1 << 16];
	while (f && fgets(line, sizeof line, f)) {
		char *p = line, *end;
		uint32_t first = UINT32_MAX, cnt = 0;
		for (;;) {
			unsigned long v = strtoul(p, &end, 10);
			if (end == p) break;
			p = end;
			if (first == UINT32_MAX) first = (uint32_t)v;
			if (v >= N || c1[v] != c1[first] || seen[v]++) bad++;
			cnt++;
		}
		if (first != UINT32_MAX && size[c1[first]] != cnt) bad++;
		members += cnt;
		lines++;
	}
	if (f) fclose(f);
	CHECK_EQ(members, N);
	CHECK_EQ(bad, 0);
	CHECK(lines > 100); /* clusters, not one blob */
	if (bad)
		fprintf(stderr, "  grid: %" PRIu64 " mismatches in %" PRIu64
			" mcl clusters\n", bad, lines);
	free(size);
	free(seen);
	free(c1);
	free(c2);
	free(e);
}

/* A similarity graph over its budget fails the run with one line that
 * counts its edges all the same (against the pair search run alone),
 * leaving the DAG as it was; a --mem-budget too small for the first
 * level's arrays fails before its graph; a large budget changes
 * nothing. */
static void test_graph_budget(void)
{
	struct scene s;
	scene_load(&s, "tests/data/bunny.ply", 8);
	if (!s.ok) {
		scene_free(&s);
		return;
	}
	int L = s.dag.levels;
	uint64_t *eff[VD_MAX_LEVELS];
	CHECK_EQ(vd_lossy_effective_refs(&s.dag, L - 2, eff), VD_OK);
	struct vd_lossy_edge *e;
	size_t ne;
	uint64_t nc;
	CHECK_EQ(vd_lossy_similar_pairs(&s.dag, L - 2, eff[L - 2], 1, 1.0, 1,
					&e, &ne, &nc), VD_OK);
	for (int l = 0; l < VD_MAX_LEVELS; l++) free(eff[l]);
	free(e);
	CHECK(ne > 1024); /* more than one slice's first array */
	struct vd_dag d = {0}, d2 = {0}, d3 = {0};
	CHECK_EQ(dag_copy(&d, &s.dag), VD_OK);
	CHECK_EQ(dag_copy(&d2, &s.dag), VD_OK);
	CHECK_EQ(dag_copy(&d3, &s.dag), VD_OK);
	/* a graph budget of 1 byte */
	struct vd_lossy_opts o = {2.0, 1.0, 1, 2, 0, 1, 0};
	struct vd_lossy_stats st;
	CHECK_EQ(vd_lossy_cluster(&d, &o, &st), VD_ERR_BUDGET);
	char want[200];
	snprintf(want, sizeof want, "the similarity graph of level %d (%" PRIu64
		 " candidates, %zu edges) needs about", L - 2, nc, ne);
	CHECK(strstr(vd_error_detail(), want) != NULL);
	if (!strstr(vd_error_detail(), want))
		fprintf(stderr, "  wanted '%s' in '%s'\n", want, vd_error_detail());
	CHECK(dags_identical(&d, &s.dag));
	o.graph_budget = 0;
	o.mem_budget = 1;
	CHECK_EQ(vd_lossy_cluster(&d, &o, &st), VD_ERR_BUDGET);
	snprintf(want, sizeof want, "the arrays of level %d (%" PRIu64 " nodes) "
		 "need about", L - 2, s.dag.lv[L - 2].nodes);
	CHECK(strstr(vd_error_detail(), want) != NULL);
	CHECK(dags_identical(&d, &s.dag));
	o.mem_budget = 1ull << 40;
	CHECK_EQ(vd_lossy_cluster(&d2, &o, &st), VD_OK);
	o.mem_budget = 0;
	CHECK_EQ(vd_lossy_cluster(&d3, &o, &st), VD_OK);
	CHECK(dags_identical(&d2, &d3));
	vd_dag_release(&d);
	vd_dag_release(&d2);
	vd_dag_release(&d3);
	scene_free(&s);
}

/* The bytes of a DAG saved as a chunk (the same transform and provenance
 * for all), in a new buffer. */
static unsigned char *dag_bytes(const struct vd_dag *d, const char *path,
				long *len)
{
	struct vd_transform tr;
	float lo[3] = {0, 0, 0}, hi[3] = {1, 1, 1};
	*len = 0;
	if (vd_transform_init(&tr, lo, hi, d->levels)) return NULL;
	if (vd_dag_save(d, &tr, path, "test")) return NULL;
	FILE *f = fopen(path, "rb");
	if (!f) return NULL;
	fseek(f, 0, SEEK_END);
	*len = ftell(f);
	rewind(f);
	unsigned char *b = malloc((size_t)*len + 1);
	if (b && fread(b, 1, (size_t)*len, f) != (size_t)*len) {
		free(b);
		b = NULL;
	}
	fclose(f);
	return b;
}

/* A similarity graph over its budget is spilled to $TMPDIR and clustered
 * a few components at a time: the chunk is byte for byte the one of the
 * unlimited run, for 1 and 2 threads, and no file is left. The graph's
 * budget is fixed (graph_budget; --mem-budget leaves it what the RSS
 * leaves, which varies) and steps up to the largest graph: each run
 * either fits its components into groups (and must then match) or names
 * the component that does not; some must have spilled into several
 * groups, and the smallest budget cannot hold any component. */
static void test_graph_spill(void)
{
	struct scene s;
	scene_load(&s, "tests/data/bunny.ply", 8);
	if (!s.ok) {
		scene_free(&s);
		return;
	}
	char tmp[600], path[800];
	snprintf(tmp, sizeof tmp, "%s", test_tmpdir("test_lossy_spill"));
	const char *old = getenv("TMPDIR");
	char *saved = old ? strdup(old) : NULL;
	setenv("TMPDIR", tmp, 1);
	struct vd_dag ref = {0};
	CHECK_EQ(dag_copy(&ref, &s.dag), VD_OK);
	struct vd_lossy_opts o = {2.0, 1.0, 1, 1, 0, 0, 0};
	struct vd_lossy_stats st;
	CHECK_EQ(vd_lossy_cluster(&ref, &o, &st), VD_OK);
	uint64_t most = 0;
	for (int i = 0; i < st.n_levels; i++) {
		CHECK_EQ(st.level[i].graph_spilled, 0);
		if (st.level[i].edges > most) most = st.level[i].edges;
	}
	CHECK(most > 1000);
	snprintf(path, sizeof path, "%s/../test_lossy_spill_ref.dag", tmp);
	long rlen, len;
	unsigned char *rb = dag_bytes(&ref, path, &rlen);
	CHECK(rb != NULL && rlen > 0);
	int spilled[3] = {0, 0, 0}, ok[3] = {0, 0, 0};
	for (int threads = 1; threads <= 2; threads++) {
		for (int k = 0; k <= 16; k++) {
			struct vd_dag d = {0};
			CHECK_EQ(dag_copy(&d, &s.dag), VD_OK);
			o.threads = threads;
			o.graph_budget = k ? (uint64_t)k * most * 240 / 16 : 1;
			int err = vd_lossy_cluster(&d, &o, &st);
			CHECK(err == VD_OK || err == VD_ERR_BUDGET);
			if (k == 0) CHECK_EQ(err, VD_ERR_BUDGET);
			/* a component's graph, or its Markov clustering
			 * beside it, over what is left */
			if (err == VD_ERR_BUDGET) {
				int named = strstr(vd_error_detail(), "largest component") ||
					    strstr(vd_error_detail(), "Markov clustering");
				CHECK(named);
				if (!named) fprintf(stderr, "  %s\n", vd_error_detail());
			}
			if (err == VD_OK) {
				ok[threads]++;
				int sp = 0;
				for (int i = 0; i < st.n_levels; i++)
					if (st.level[i].graph_spilled &&
					    st.level[i].spill_buckets > 1)
						sp = 1;
				spilled[threads] += sp;
				unsigned char *b = dag_bytes(&d, path, &len);
				CHECK(b && rb && len == rlen && !memcmp(b, rb, (size_t)len));
				if (!(b && rb && len == rlen && !memcmp(b, rb, (size_t)len)))
					fprintf(stderr, "  threads %d budget %" PRIu64
						": chunk differs\n", threads, o.graph_budget);
				free(b);
			}
			vd_dag_release(&d);
		}
	}
	printf("  spill: %d/%d runs split the graph (1 thread), %d/%d (2)\n",
	       spilled[1], ok[1], spilled[2], ok[2]);
	CHECK(spilled[1] > 0);
	CHECK(spilled[2] > 0);
	/* nothing left in $TMPDIR */
	char cmd[900];
	snprintf(cmd, sizeof cmd, "test -z \"$(ls -A '%s')\"", tmp);
	CHECK_EQ(system(cmd), 0);
	if (saved) setenv("TMPDIR", saved, 1);
	else unsetenv("TMPDIR");
	free(saved);
	free(rb);
	vd_dag_release(&ref);
	scene_free(&s);
}

/* The representatives against their rule worked out here by brute force,
 * on the height-2 level: with --diff-factor 0 it is the only lossy one
 * (taller subtrees would have to be equal, and a reduced DAG has no two
 * equal). mcl's clusters (vd_lossy_mcl, itself checked against Debian's
 * mcl above) taken in the order of their components' smallest graph
 * node, then their own; the representative: the largest sum of
 * similarities within the cluster, then the least change of the
 * cluster's voxel count (occurrences times voxels), then the run's net
 * change closest to zero, then the smallest node. The stage's net change
 * and voxels changed (from its walk of both DAGs) must equal the sums
 * over the members here. */
static void check_representatives(int L, int threads)
{
	struct scene s;
	scene_load(&s, "tests/data/bunny.ply", L);
	if (!s.ok) {
		scene_free(&s);
		return;
	}
	const struct vd_dag *d = &s.dag;
	uint64_t *eff[VD_MAX_LEVELS];
	CHECK_EQ(vd_lossy_effective_refs(d, L - 2, eff), VD_OK);
	struct vd_lossy_edge *e;
	size_t ne;
	uint64_t nc, nl = d->lv[L - 2].nodes;
	CHECK_EQ(vd_lossy_similar_pairs(d, L - 2, eff[L - 2], 1, 0.0, 1, &e, &ne,
					&nc), VD_OK);
	/* graph nodes: nodes with an edge, in order */
	uint32_t *gid = malloc(nl * 4), *node = malloc(nl * 4), gn = 0;
	for (uint64_t i = 0; i < nl; i++) gid[i] = UINT32_MAX;
	for (size_t k = 0; k < ne; k++) gid[e[k].u] = gid[e[k].v] = 0;
	for (uint64_t i = 0; i < nl; i++)
		if (gid[i] != UINT32_MAX) {
			node[gn] = (uint32_t)i;
			gid[i] = gn++;
		}
	struct vd_lossy_edge *ge = malloc((ne + 1) * sizeof *ge);
	for (size_t k = 0; k < ne; k++) {
		ge[k] = e[k];
		ge[k].u = gid[e[k].u];
		ge[k].v = gid[e[k].v];
	}
	uint32_t *cl = malloc((gn + 1) * 4), *comp = malloc((gn + 1) * 4);
	double *sim = calloc(gn + 1, 8);
	CHECK_EQ(vd_lossy_mcl(gn, ge, ne, 2.0, 1, cl), VD_OK);
	/* components by relaxation to the smallest node */
	for (uint32_t i = 0; i < gn; i++) comp[i] = i;
	for (int changed = 1; changed;) {
		changed = 0;
		for (size_t k = 0; k < ne; k++) {
			uint32_t a = comp[ge[k].u], b = comp[ge[k].v];
			if (a != b) {
				comp[ge[k].u] = comp[ge[k].v] = a < b ? a : b;
				changed = 1;
			}
		}
	}
	for (size_t k = 0; k < ne; k++)
		if (cl[ge[k].u] == cl[ge[k].v]) {
			sim[ge[k].u] += ge[k].s;
			sim[ge[k].v] += ge[k].s;
		}
	/* clusters in order: (component, smallest member) */
	uint64_t *order = malloc((gn + 1) * 8), no = 0;
	for (uint32_t i = 0; i < gn; i++)
		if (cl[i] == i) order[no++] = (uint64_t)comp[i] << 32 | i;
	qsort(order, no, 8, u64_cmp);
	int64_t net = 0;
	uint64_t changed = 0, pairs = 0;
	for (uint64_t k = 0; k < no; k++) {
		uint32_t c = (uint32_t)order[k], r = UINT32_MAX;
		double most = -1;
		for (uint32_t i = 0; i < gn; i++)
			if (cl[i] == c && sim[i] > most) most = sim[i];
		int64_t rd = 0;
		uint32_t members = 0;
		for (uint32_t i = 0; i < gn; i++) {
			if (cl[i] != c) continue;
			members++;
			if (sim[i] < most - 1e-9 * (most > 1 ? most : 1)) continue;
			int64_t dl = 0;
			for (uint32_t j = 0; j < gn; j++)
				if (cl[j] == c)
					dl += (int64_t)eff[L - 2][node[j]] *
					      ((int64_t)__builtin_popcountll(d->bricks[node[i]]) -
					       (int64_t)__builtin_popcountll(d->bricks[node[j]]));
			int64_t a = dl < 0 ? -dl : dl, b = rd < 0 ? -rd : rd;
			int64_t x = net + dl < 0 ? -(net + dl) : net + dl,
				y = net + rd < 0 ? -(net + rd) : net + rd;
			if (r == UINT32_MAX || a < b || (a == b && x < y)) {
				r = i;
				rd = dl;
			}
		}
		net += rd;
		pairs += members == 2;
		for (uint32_t j = 0; j < gn; j++)
			if (cl[j] == c)
				changed += eff[L - 2][node[j]] *
					   (uint64_t)__builtin_popcountll(d->bricks[node[r]] ^
									 d->bricks[node[j]]);
	}
	CHECK(pairs > 10); /* the third rule is used */
	struct vd_dag out = {0};
	CHECK_EQ(dag_copy(&out, d), VD_OK);
	struct vd_lossy_opts o = {2.0, 0.0, 1, threads, 0, 0, 0};
	struct vd_lossy_stats st;
	CHECK_EQ(vd_lossy_cluster(&out, &o, &st), VD_OK);
	CHECK_EQ((int64_t)(st.voxels_after - st.voxels_before), net);
	CHECK_EQ(st.voxels_set + st.voxels_cleared, changed);
	for (int i = 1; i < st.n_levels; i++) CHECK_EQ(st.level[i].merged, 0);
	printf("  L %d: net change %" PRId64 ", %" PRIu64 " voxels changed, %"
	       PRIu64 " clusters (%" PRIu64 " pairs)\n", L, net, changed, no, pairs);
	vd_dag_release(&out);
	for (int l = 0; l < VD_MAX_LEVELS; l++) free(eff[l]);
	free(e);
	free(ge);
	free(gid);
	free(node);
	free(cl);
	free(comp);
	free(sim);
	free(order);
	scene_free(&s);
}

static void test_representatives(void)
{
	check_representatives(8, 1);
	check_representatives(9, 2);
}

int main(void)
{
	RUN(test_effective_refs);
	RUN(test_similar_pairs);
	RUN(test_mcl);
	RUN(test_mcl_big);
	RUN(test_stage);
	RUN(test_bad_input);
	RUN(test_graph_budget);
	RUN(test_graph_spill);
	RUN(test_representatives);
	return CHECK_DONE();
}
