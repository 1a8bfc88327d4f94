/* test_plan.c - the runner's planner (pipeline/plan.c), through its public
 * entry points (pipeline.h): small YAML pipelines are loaded with
 * config_load, voxelize's output is faked with chunk files whose headers
 * the test writes (the planner reads headers only), jobs are marked done
 * by hand, and plan_expand's job graph is compared with the one worked out
 * here from schemas/pipeline.md:
 *   - before voxelize has run, one job, its exact command line (auto
 *     chunk level: no --chunk-level; colours only when a job takes them).
 *     The planner does not pick the level itself: voxelize does, from its
 *     own estimate of the process's memory, and the planner takes L0 from
 *     the chunk files' headers (level 3 and level 0 below);
 *   - one per-cell job per non-empty cell (the .svo files, not the other
 *     files voxelize writes), its command, dependency and --mem-budget
 *     (the job budget, or its estimate when it cannot fit, up to the
 *     total budget); symmetry-merge's cells after svo-to-dag's;
 *   - the reduction tree (children -> parent) at the coarsest level where
 *     every group's estimate fits the job budget, for three budgets; a
 *     one-cell scene at chunk level 0 has no tree;
 *   - the job key recomputed from its documented definition (xxhash over
 *     the stage name, its version, the arguments but --threads and
 *     --mem-budget, the inputs' fingerprints): it changes when a
 *     parameter or an input's content changes and not otherwise; the key
 *     journal line, freshness and its loss, and a later plan skipping
 *     exactly the job whose key holds;
 *   - the one-line errors config_load gives for bad pipelines. */
#include "check.h"
#include "pipeline.h"

#include <errno.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <xxhash.h>

static const char *root;   /* scratch directory */
static char outs[200];     /* every pipeline's outputs (one key journal) */
static char mesh[200];     /* the input: any file (only its bytes count) */

static void write_text(const char *path, const char *text)
{
	FILE *f = fopen(path, "wb");
	CHECK(f != NULL);
	if (f) {
		fputs(text, f);
		CHECK_EQ(fclose(f), 0);
	}
}

static void sh(const char *fmt, const char *arg)
{
	char cmd[1200];
	snprintf(cmd, sizeof cmd, fmt, arg, arg);
	CHECK_EQ(system(cmd), 0);
}

/* A pipeline: the header every test shares, then `rest` (levels,
 * chunk_level, resources, jobs). Returns config_load's status; stderr's
 * text in `err` when given. */
static int load(struct config *c, const char *rest, char *err, size_t cap)
{
	char path[700], text[4096], errpath[700];
	snprintf(path, sizeof path, "%s/p.yaml", root);
	snprintf(errpath, sizeof errpath, "%s/stderr", root);
	snprintf(text, sizeof text, "version: 1\nname: t\ninput: {mesh: %s}\n"
		 "outputs: %s\n%s", mesh, outs, rest);
	write_text(path, text);
	fflush(stderr);
	int saved = dup(2);
	int fd = open(errpath, O_WRONLY | O_CREAT | O_TRUNC, 0666);
	dup2(fd, 2);
	close(fd);
	int rc = config_load(c, path);
	fflush(stderr);
	dup2(saved, 2);
	close(saved);
	char *e = test_slurp(errpath, NULL);
	if (err)
		snprintf(err, cap, "%s", e ? e : "");
	else if (e && *e)
		fprintf(stderr, "%s", e);
	free(e);
	return rc;
}

/* A chunk file with just a header (what the planner reads): counts 1 at
 * the cell's level, then `scale` times 8, 16, ... below it. */
static void write_chunk(const char *path, uint32_t kind, int levels, int L0,
			uint64_t cell, uint64_t scale)
{
	struct vd_chunk_header h;
	memset(&h, 0, sizeof h);
	h.kind = kind;
	h.levels = (uint32_t)levels;
	h.chunk_level = (uint32_t)L0;
	h.cell_morton = cell;
	h.level_count = (uint32_t)(levels - L0 + 1);
	for (uint32_t i = 0; i < h.level_count; i++)
		h.level_nodes[i] = i == 0 ? 1 : scale * 8 * i;
	h.transform.voxel_size = 1;
	h.transform.root_side = (float)(1u << levels);
	struct vd_chunk_writer *w = NULL;
	CHECK_EQ(vd_chunk_writer_open(&w, path, &h, NULL), VD_OK);
	if (w)
		CHECK_EQ(vd_chunk_writer_commit(w), VD_OK);
}

static struct vd_chunk_header header_of(const char *path)
{
	struct vd_chunk_header h;
	memset(&h, 0, sizeof h);
	CHECK_EQ(vd_chunk_read_header(path, &h), VD_OK);
	return h;
}

/* The jobs' command line without argv[0]'s directory: "voxelize a b". */
static const char *cmd_of(const struct job *j)
{
	static char buf[8192];
	const char *prog = strrchr(j->argv[0], '/');
	size_t at = (size_t)snprintf(buf, sizeof buf, "%s",
				     prog ? prog + 1 : j->argv[0]);
	for (int i = 1; j->argv[i] && at < sizeof buf; i++)
		at += (size_t)snprintf(buf + at, sizeof buf - at, " %s",
				       j->argv[i]);
	return buf;
}

static int cmd_is(const struct job *j, const char *want)
{
	int same = !strcmp(cmd_of(j), want);
	if (!same)
		fprintf(stderr, "command: %s\n   want: %s\n", cmd_of(j), want);
	return same;
}

/* The value after `opt` in j's command, or NULL. */
static const char *arg_after(const struct job *j, const char *opt)
{
	for (int i = 1; j->argv[i]; i++)
		if (!strcmp(j->argv[i], opt))
			return j->argv[i + 1];
	return NULL;
}

static uint64_t budget_of(const struct job *j)
{
	const char *b = arg_after(j, "--mem-budget");
	return b ? strtoull(b, NULL, 10) : 0;
}

static struct job *job_named(struct plan *p, const char *id)
{
	int i = plan_find(p, id);
	if (i < 0)
		fprintf(stderr, "no job '%s'\n", id);
	return i < 0 ? NULL : &p->jobs[i];
}

/* Jobs of declaration d (cells: with `cells` 1, merges with 0). */
static int count_jobs(const struct plan *p, int d, int cells)
{
	int n = 0;
	for (int i = 0; i < p->n; i++)
		n += p->jobs[i].decl == d && !!strstr(p->jobs[i].id, "/cells/") ==
						     cells;
	return n;
}

/* The documented --mem-budget of a DAG job with estimate est
 * (pipeline.md, resources.job_mem_budget): the job budget when est fits
 * it, else est, but never above the total budget. */
static uint64_t doc_budget(const struct config *c, uint64_t est)
{
	if (est <= c->job_mem_budget)
		return c->job_mem_budget;
	return est < c->mem_budget ? est : c->mem_budget;
}

/* A part's share of a merge into `kind`, as vd_dag.h tells a planner to
 * take it (the census of its header), and a merge's bound from the sum of
 * its parts' shares (each share holds the fixed part once). */
static uint64_t share_of(const char *path, uint32_t kind)
{
	struct vd_chunk_header h = header_of(path);
	struct vd_dag_census cen;
	memset(&cen, 0, sizeof cen);
	vd_dag_census_add_header(&cen, &h);
	return vd_dag_estimate_merge(&cen, kind);
}

static uint64_t merge_bound(uint64_t sum, int parts)
{
	return sum - (uint64_t)(parts - 1) * VD_DAG_ESTIMATE_FIXED_BYTES;
}

/* ------------------------------------------------------------ fixtures */

#define NCELLS 5
/* Cells at chunk level 3 (9-bit Morton codes) chosen so that they have
 * four distinct parents at level 2 (0x00: 000 and 001; 0x01: 009;
 * 0x08: 040; 0x3f: 1ff) and three at level 1 (0: 000 001 009; 1: 040;
 * 7: 1ff). */
static const uint64_t cells3[NCELLS] = {0x000, 0x001, 0x009, 0x040, 0x1ff};

static void fresh_outputs(void)
{
	sh("rm -rf '%s' && mkdir -p '%s'", outs);
}

/* Fakes what voxelize writes into outs/vox: a .svo per cell, the colour
 * chunks and the statistics beside them (not cells). */
static void fake_voxelize(int levels, int L0, const uint64_t *cells, int n,
			  uint64_t scale)
{
	char dir[700], path[800], name[64];
	snprintf(dir, sizeof dir, "%s/vox", outs);
	sh("mkdir -p '%s'", dir);
	for (int i = 0; i < n; i++) {
		vd_chunk_file_name(name, sizeof name, L0, cells[i], "svo");
		snprintf(path, sizeof path, "%s/%s", dir, name);
		write_chunk(path, VD_KIND_SVO, levels, L0, cells[i], scale);
		vd_chunk_file_name(name, sizeof name, L0, cells[i], "col");
		snprintf(path, sizeof path, "%s/%s", dir, name);
		write_chunk(path, VD_KIND_COLOURS, levels, L0, cells[i], scale);
	}
	snprintf(path, sizeof path, "%s/voxelize.stats.json", dir);
	write_text(path, "{}\n");
	snprintf(path, sizeof path, "%s/chunk-notes.txt", dir);
	write_text(path, "not a cell");
}

/* Marks every pending job of declaration d done, first writing the DAG
 * chunk each cell job would have written (kind `kind`). */
static void finish_cells(struct plan *p, int d, uint32_t kind, int levels)
{
	for (int i = 0; i < p->n; i++) {
		struct job *j = &p->jobs[i];
		if (j->decl != d || j->state != JOB_PENDING)
			continue;
		struct vd_chunk_header h = header_of(j->inputs[0]);
		write_chunk(j->output, kind, levels, (int)h.chunk_level,
			    h.cell_morton, 1);
		job_set_state(p, j, JOB_DONE);
	}
}

static void finish(struct plan *p, const char *id)
{
	struct job *j = job_named(p, id);
	if (j)
		job_set_state(p, j, JOB_DONE);
}

/* ---------------------------------------------------------------- tests */

static const char graph[] =
	"jobs:\n"
	"  vox: {stage: voxelize}\n"
	"  svdag: {stage: svo-to-dag, needs: [vox]}\n"
	"  ssvdag: {stage: symmetry-merge, needs: [svdag]}\n"
	"  enc: {stage: encode, needs: [svdag, ssvdag]}\n";

/* Defaults (pipeline.md's table) and sizes in powers of 1024. */
static void test_config(void)
{
	struct config c;
	char text[1024];
	snprintf(text, sizeof text, "levels: 9\n%s", graph);
	CHECK_EQ(load(&c, text, NULL, 0), 0);
	CHECK_EQ(c.chunk_level, -1);
	CHECK_EQ(c.jobs, 2);
	CHECK(c.mem_budget == 4ull << 30);
	CHECK(c.job_mem_budget == 2ull << 30);
	/* the 4 deepest levels */
	CHECK_EQ(c.nres, 4);
	for (int i = 0; i < c.nres && i < 4; i++)
		CHECK_EQ(c.resolutions[i], 9 - i);
	int t = vd_hardware_threads() / 2;
	CHECK_EQ(c.threads, t > 0 ? t : 1);
	CHECK_EQ(c.njobs, 4);
	CHECK(!strcmp(c.outputs, outs));
	config_release(&c);
	snprintf(text, sizeof text, "levels: 9\nresources: {jobs: 3, "
		 "mem_budget: 1.5G, job_mem_budget: 512M, threads: 5}\n%s",
		 graph);
	CHECK_EQ(load(&c, text, NULL, 0), 0);
	CHECK(c.mem_budget == 3ull << 29);
	CHECK(c.job_mem_budget == 512ull << 20);
	CHECK_EQ(c.threads, 5);
	CHECK_EQ(c.jobs, 3);
	config_release(&c);
}

/* Before voxelize has run only voxelize is known; its command line. */
static void test_voxelize_job(void)
{
	fresh_outputs();
	struct config c;
	char text[1024], want[4096];
	snprintf(text, sizeof text, "levels: 9\nresources: {jobs: 2, "
		 "mem_budget: 1G, job_mem_budget: 256M, threads: 3}\n%s", graph);
	CHECK_EQ(load(&c, text, NULL, 0), 0);
	struct plan p = {.cfg = &c};
	CHECK_EQ(plan_expand(&p), 0);
	CHECK_EQ(p.n, 1);
	CHECK_EQ(p.expanded, 0);
	struct job *v = job_named(&p, "vox");
	if (v) {
		/* auto chunk level: no --chunk-level (voxelize picks it);
		 * threads: every job's (3 x 2), as nothing runs beside it;
		 * no job takes colours: --no-colours */
		snprintf(want, sizeof want, "voxelize %s -o %s/vox --levels 9 "
			 "--mem-budget 268435456 --threads 6 --no-colours",
			 mesh, outs);
		CHECK(cmd_is(v, want));
		CHECK_EQ(v->ninputs, 1);
		CHECK(v->ninputs == 1 && !strcmp(v->inputs[0], mesh));
		CHECK_EQ(v->ndeps, 0);
		CHECK(v->mem_estimate == 256ull << 20);
		CHECK_EQ(v->sources, 1); /* a mesh: its pulled-in files */
		CHECK_EQ(v->state, JOB_PENDING);
	}
	plan_free(&p);
	config_release(&c);
	/* a fixed chunk level is passed on; a colorize job wants colours */
	snprintf(text, sizeof text, "levels: 9\nchunk_level: 4\nresources: "
		 "{jobs: 1, mem_budget: 1G, job_mem_budget: 256M, threads: 2}\n"
		 "%s  col: {stage: colorize, needs: [vox]}\n", graph);
	CHECK_EQ(load(&c, text, NULL, 0), 0);
	struct plan q = {.cfg = &c};
	CHECK_EQ(plan_expand(&q), 0);
	v = job_named(&q, "vox");
	if (v) {
		snprintf(want, sizeof want, "voxelize %s -o %s/vox --levels 9 "
			 "--mem-budget 268435456 --threads 2 --chunk-level 4",
			 mesh, outs);
		CHECK(cmd_is(v, want));
	}
	/* colorize's input is known (the voxelize job), so it is planned */
	CHECK_EQ(q.n, 2);
	plan_free(&q);
	config_release(&c);
}

/* One cell job per .svo file voxelize wrote; symmetry-merge's cells once
 * svo-to-dag's are built, each after its own. */
static void test_cells(void)
{
	fresh_outputs();
	struct config c;
	char text[1024], want[4096], in[800], out[800];
	snprintf(text, sizeof text, "levels: 7\nchunk_level: 3\nresources: "
		 "{jobs: 2, mem_budget: 1G, job_mem_budget: 512M, threads: 3}\n"
		 "%s", graph);
	CHECK_EQ(load(&c, text, NULL, 0), 0);
	struct plan p = {.cfg = &c};
	CHECK_EQ(plan_expand(&p), 0);
	fake_voxelize(7, 3, cells3, NCELLS, 1);
	/* the output exists, but voxelize has not finished: nothing new */
	CHECK_EQ(plan_expand(&p), 0);
	CHECK_EQ(p.n, 1);
	finish(&p, "vox");
	CHECK_EQ(plan_expand(&p), 0);
	const int svdag = 1, ssvdag = 2;
	CHECK_EQ(count_jobs(&p, svdag, 1), NCELLS);
	CHECK_EQ(count_jobs(&p, svdag, 0), 0); /* merges wait for the cells */
	CHECK_EQ(count_jobs(&p, ssvdag, 1), 0);
	CHECK_EQ(p.n, 1 + NCELLS);
	int vox = plan_find(&p, "vox");
	for (int i = 0; i < NCELLS; i++) {
		char name[64], id[200];
		/* 3 digits at level 3: (3 * 3 + 3) / 4 */
		snprintf(name, sizeof name, "chunk-L3-%03llx",
			 (unsigned long long)cells3[i]);
		snprintf(id, sizeof id, "svdag/cells/%s", name);
		struct job *j = job_named(&p, id);
		if (!j)
			continue;
		snprintf(in, sizeof in, "%s/vox/%s.svo", outs, name);
		snprintf(out, sizeof out, "%s/svdag/cells/%s.dag", outs, name);
		/* the estimate fits the job budget: it gets the job budget */
		struct vd_chunk_header h = header_of(in);
		CHECK(vd_dag_estimate_header(&h) <= c.job_mem_budget);
		snprintf(want, sizeof want, "svo-to-dag %s -o %s --mem-budget "
			 "536870912 --threads 3 -q", in, out);
		CHECK(cmd_is(j, want));
		CHECK(!strcmp(j->output, out));
		CHECK(j->ndeps == 1 && j->deps[0] == vox);
		CHECK(j->ninputs == 1 && !strcmp(j->inputs[0], in));
		CHECK_EQ(j->cell, 1);
		CHECK(j->mem_estimate == vd_dag_estimate_header(&h));
		/* voxels: the header's last count (scale 1: 8 * 4) */
		CHECK_EQ(j->voxels, 32);
	}
	/* planning again adds nothing */
	CHECK_EQ(plan_expand(&p), 0);
	CHECK_EQ(p.n, 1 + NCELLS);
	finish_cells(&p, svdag, VD_KIND_DAG, 7);
	CHECK_EQ(plan_expand(&p), 0);
	CHECK_EQ(count_jobs(&p, ssvdag, 1), NCELLS);
	for (int i = 0; i < NCELLS; i++) {
		char name[64], id[200];
		snprintf(name, sizeof name, "chunk-L3-%03llx",
			 (unsigned long long)cells3[i]);
		snprintf(id, sizeof id, "ssvdag/cells/%s", name);
		struct job *j = job_named(&p, id);
		snprintf(id, sizeof id, "svdag/cells/%s", name);
		int src = plan_find(&p, id);
		if (!j || src < 0)
			continue;
		snprintf(in, sizeof in, "%s/svdag/cells/%s.dag", outs, name);
		snprintf(out, sizeof out, "%s/ssvdag/cells/%s.sdag", outs, name);
		snprintf(want, sizeof want, "symmetry-merge %s -o %s --mem-budget "
			 "536870912 --threads 3 -q", in, out);
		CHECK(cmd_is(j, want));
		CHECK(j->ndeps == 1 && j->deps[0] == src);
		/* a DAG cell's estimate is its share of a symmetry merge */
		CHECK(j->mem_estimate == share_of(in, VD_KIND_SSVDAG));
	}
	/* encode waits for both roots */
	CHECK_EQ(plan_find(&p, "enc"), -1);
	CHECK_EQ(p.expanded, 0);
	plan_free(&p);
	config_release(&c);
}

/* The merge jobs of declaration d: for each, its level (--to-level) and
 * parts (the paths after --merge); the tree as "id<-part,part;" lines in
 * plan order. */
static const char *tree_of(const struct plan *p, int d)
{
	static char buf[8192];
	size_t at = 0;
	buf[0] = 0;
	for (int i = 0; i < p->n; i++) {
		const struct job *j = &p->jobs[i];
		if (j->decl != d || strstr(j->id, "/cells/"))
			continue;
		at += (size_t)snprintf(buf + at, sizeof buf - at, "%s@%s<-",
				       j->id, arg_after(j, "--to-level"));
		int k = 1;
		while (j->argv[k] && strcmp(j->argv[k], "--merge"))
			k++;
		for (k++; j->argv[k] && strcmp(j->argv[k], "-o"); k++) {
			const char *base = strrchr(j->argv[k], '/') + 1;
			at += (size_t)snprintf(buf + at, sizeof buf - at, "%s%s",
					       base, j->argv[k + 1] &&
					       strcmp(j->argv[k + 1], "-o")
						       ? "," : "");
		}
		at += (size_t)snprintf(buf + at, sizeof buf - at, ";");
	}
	return buf;
}

/* The plan for the five cells with job budget `jb` up to svo-to-dag's
 * merges (cells built). */
static void plan_to_merges(struct config *c, struct plan *p, const char *jb)
{
	fresh_outputs();
	char text[1024];
	snprintf(text, sizeof text, "levels: 7\nchunk_level: 3\nresources: "
		 "{jobs: 2, mem_budget: 4G, job_mem_budget: %s, threads: 1}\n"
		 "%s", jb, graph);
	CHECK_EQ(load(c, text, NULL, 0), 0);
	memset(p, 0, sizeof *p);
	p->cfg = c;
	CHECK_EQ(plan_expand(p), 0);
	fake_voxelize(7, 3, cells3, NCELLS, 1);
	finish(p, "vox");
	CHECK_EQ(plan_expand(p), 0);
	finish_cells(p, 1, VD_KIND_DAG, 7);
	CHECK_EQ(plan_expand(p), 0);
}

static const char *cell_dag(const char *name)
{
	static char path[800];
	snprintf(path, sizeof path, "%s/svdag/cells/%s.dag", outs, name);
	return path;
}

/* A budget every group fits: the root merges all cells at once. */
static void test_tree_one_merge(void)
{
	struct config c;
	struct plan p;
	plan_to_merges(&c, &p, "2G");
	CHECK(!strcmp(tree_of(&p, 1),
		      "svdag/root@0<-chunk-L3-000.dag,chunk-L3-001.dag,"
		      "chunk-L3-009.dag,chunk-L3-040.dag,chunk-L3-1ff.dag;"));
	struct job *r = job_named(&p, "svdag/root");
	if (r) {
		char out[800];
		snprintf(out, sizeof out, "%s/svdag/root.dag", outs);
		CHECK(!strcmp(r->output, out));
		CHECK_EQ(r->ndeps, NCELLS);
		CHECK_EQ(r->ninputs, NCELLS);
		uint64_t sum = 0;
		for (int i = 0; i < NCELLS; i++) {
			char name[64];
			snprintf(name, sizeof name, "chunk-L3-%03llx",
				 (unsigned long long)cells3[i]);
			sum += share_of(cell_dag(name), VD_KIND_DAG);
			/* each dependency is the cell job of its part */
			char id[200];
			snprintf(id, sizeof id, "svdag/cells/%s", name);
			CHECK(r->ndeps == NCELLS &&
			      r->deps[i] == plan_find(&p, id));
			CHECK(r->ninputs == NCELLS &&
			      !strcmp(r->inputs[i], cell_dag(name)));
		}
		CHECK(r->mem_estimate == merge_bound(sum, NCELLS));
		CHECK(budget_of(r) == 2ull << 30);
	}
	/* the symmetry-merge cells come with the root of svo-to-dag */
	CHECK_EQ(count_jobs(&p, 2, 1), NCELLS);
	plan_free(&p);
	config_release(&c);
}

/* A job budget no merge fits (1 MiB, below the fixed 16 MiB): a tree of
 * 8s, one level at a time - level 2 parents, level 1, the root - each
 * merge given its own estimate as its budget. Job ids name the parent
 * cell in plain hex ("L2-3f"), their files at fixed width
 * ("chunk-L2-3f.dag", "chunk-L2-08.dag"). */
static void test_tree_of_eights(void)
{
	struct config c;
	struct plan p;
	plan_to_merges(&c, &p, "1M");
	const char *want =
		"svdag/L2-0@2<-chunk-L3-000.dag,chunk-L3-001.dag;"
		"svdag/L2-1@2<-chunk-L3-009.dag;"
		"svdag/L2-8@2<-chunk-L3-040.dag;"
		"svdag/L2-3f@2<-chunk-L3-1ff.dag;"
		"svdag/L1-0@1<-chunk-L2-00.dag,chunk-L2-01.dag;"
		"svdag/L1-1@1<-chunk-L2-08.dag;"
		"svdag/L1-7@1<-chunk-L2-3f.dag;"
		"svdag/root@0<-chunk-L1-0.dag,chunk-L1-1.dag,chunk-L1-7.dag;";
	CHECK(!strcmp(tree_of(&p, 1), want));
	if (strcmp(tree_of(&p, 1), want))
		fprintf(stderr, "tree: %s\n", tree_of(&p, 1));
	/* children -> parent: each merge depends on the jobs of its parts */
	struct job *r = job_named(&p, "svdag/root");
	if (r && r->ndeps == 3) {
		CHECK(r->deps[0] == plan_find(&p, "svdag/L1-0"));
		CHECK(r->deps[1] == plan_find(&p, "svdag/L1-1"));
		CHECK(r->deps[2] == plan_find(&p, "svdag/L1-7"));
	}
	CHECK(r && r->ndeps == 3);
	struct job *m = job_named(&p, "svdag/L2-0");
	if (m && m->ndeps == 2) {
		CHECK(m->deps[0] == plan_find(&p, "svdag/cells/chunk-L3-000"));
		CHECK(m->deps[1] == plan_find(&p, "svdag/cells/chunk-L3-001"));
	}
	/* the estimate of L2-00 from its two parts, and the root's from
	 * every cell (a merged part's share is its merge's estimate) */
	uint64_t s[NCELLS], all = 0;
	for (int i = 0; i < NCELLS; i++) {
		char name[64];
		snprintf(name, sizeof name, "chunk-L3-%03llx",
			 (unsigned long long)cells3[i]);
		s[i] = share_of(cell_dag(name), VD_KIND_DAG);
		all += s[i];
	}
	if (m) {
		CHECK(m->mem_estimate == merge_bound(s[0] + s[1], 2));
		/* above the 1 MiB job budget: its estimate */
		CHECK(budget_of(m) == doc_budget(&c, m->mem_estimate));
		CHECK(budget_of(m) == m->mem_estimate);
	}
	if (r) {
		CHECK(r->mem_estimate == merge_bound(all, NCELLS));
		CHECK(budget_of(r) == r->mem_estimate);
	}
	/* cells cannot fit 1 MiB either: each gets its estimate */
	struct job *cj = job_named(&p, "svdag/cells/chunk-L3-1ff");
	if (cj)
		CHECK(budget_of(cj) == cj->mem_estimate &&
		      cj->mem_estimate > c.job_mem_budget);
	plan_free(&p);
	config_release(&c);
}

/* A budget of exactly the largest level-1 group's estimate: the root does
 * not fit it, the level-1 groups do, so the cells merge straight into
 * level 1 (not level 2, which would fit too: the coarsest level wins),
 * then the root, which gets its estimate (up to the total budget). */
static void test_tree_coarsest_fit(void)
{
	/* the shares first, from cells built by a throwaway plan */
	struct config c;
	struct plan p;
	plan_to_merges(&c, &p, "2G");
	uint64_t s[NCELLS];
	for (int i = 0; i < NCELLS; i++) {
		char name[64];
		snprintf(name, sizeof name, "chunk-L3-%03llx",
			 (unsigned long long)cells3[i]);
		s[i] = share_of(cell_dag(name), VD_KIND_DAG);
	}
	plan_free(&p);
	config_release(&c);
	uint64_t g0 = merge_bound(s[0] + s[1] + s[2], 3);
	uint64_t g1 = s[3], g7 = s[4];
	uint64_t root_est = merge_bound(s[0] + s[1] + s[2] + s[3] + s[4], 5);
	uint64_t b = g0 > g1 ? g0 : g1;
	b = b > g7 ? b : g7;
	CHECK(root_est > b);
	char jb[32];
	snprintf(jb, sizeof jb, "%llu", (unsigned long long)b);
	plan_to_merges(&c, &p, jb);
	const char *want =
		"svdag/L1-0@1<-chunk-L3-000.dag,chunk-L3-001.dag,chunk-L3-009.dag;"
		"svdag/L1-1@1<-chunk-L3-040.dag;"
		"svdag/L1-7@1<-chunk-L3-1ff.dag;"
		"svdag/root@0<-chunk-L1-0.dag,chunk-L1-1.dag,chunk-L1-7.dag;";
	CHECK(!strcmp(tree_of(&p, 1), want));
	if (strcmp(tree_of(&p, 1), want))
		fprintf(stderr, "tree: %s\n", tree_of(&p, 1));
	struct job *m = job_named(&p, "svdag/L1-0");
	if (m) {
		CHECK(m->mem_estimate == g0);
		CHECK(budget_of(m) == b); /* fits: the job budget */
	}
	struct job *r = job_named(&p, "svdag/root");
	if (r) {
		CHECK(r->mem_estimate == root_est);
		CHECK(budget_of(r) == doc_budget(&c, root_est));
		CHECK(budget_of(r) == root_est);
	}
	plan_free(&p);
	config_release(&c);
}

/* A cell whose estimate is above the whole budget gets the whole budget
 * (it runs alone), never more. */
static void test_budget_capped(void)
{
	fresh_outputs();
	struct config c;
	char text[1024];
	snprintf(text, sizeof text, "levels: 7\nchunk_level: 3\nresources: "
		 "{jobs: 2, mem_budget: 64M, job_mem_budget: 32M, threads: 1}\n"
		 "%s", graph);
	CHECK_EQ(load(&c, text, NULL, 0), 0);
	struct plan p = {.cfg = &c};
	CHECK_EQ(plan_expand(&p), 0);
	/* cell 000 dense (a million nodes a level), the others tiny */
	fake_voxelize(7, 3, cells3, NCELLS, 1);
	char path[800];
	snprintf(path, sizeof path, "%s/vox/chunk-L3-000.svo", outs);
	write_chunk(path, VD_KIND_SVO, 7, 3, 0, 1000000);
	finish(&p, "vox");
	CHECK_EQ(plan_expand(&p), 0);
	struct job *big = job_named(&p, "svdag/cells/chunk-L3-000");
	struct job *small = job_named(&p, "svdag/cells/chunk-L3-001");
	if (big) {
		struct vd_chunk_header h = header_of(path);
		CHECK(vd_dag_estimate_header(&h) > c.mem_budget);
		CHECK(big->mem_estimate == vd_dag_estimate_header(&h));
		CHECK(budget_of(big) == 64ull << 20);
	}
	if (small) {
		CHECK(small->mem_estimate <= c.job_mem_budget);
		CHECK(budget_of(small) == 32ull << 20);
	}
	plan_free(&p);
	config_release(&c);
}

/* One cell at chunk level 0 is the whole scene: svo-to-dag writes the
 * root from it (no cell job, no merge), symmetry-merge runs once on that
 * root, and encode takes both roots - all known as soon as voxelize has
 * run (they wait for each other by dependencies), so the graph is whole. */
static void test_single_cell(void)
{
	fresh_outputs();
	struct config c;
	char text[1024], want[4096];
	snprintf(text, sizeof text, "levels: 5\nchunk_level: 0\nresources: "
		 "{jobs: 1, mem_budget: 1G, job_mem_budget: 1G, threads: 2}\n"
		 "resolutions: [5, 3]\n%s", graph);
	CHECK_EQ(load(&c, text, NULL, 0), 0);
	struct plan p = {.cfg = &c};
	CHECK_EQ(plan_expand(&p), 0);
	const uint64_t one = 0;
	fake_voxelize(5, 0, &one, 1, 1);
	CHECK_EQ(p.expanded, 0);
	finish(&p, "vox");
	CHECK_EQ(plan_expand(&p), 0);
	CHECK_EQ(p.n, 4);
	CHECK_EQ(count_jobs(&p, 1, 1), 0);
	CHECK_EQ(p.expanded, 1);
	struct job *r = job_named(&p, "svdag/root");
	if (r) {
		snprintf(want, sizeof want, "svo-to-dag %s/vox/chunk-L0-0.svo -o "
			 "%s/svdag/root.dag --mem-budget 1073741824 --threads 2 -q",
			 outs, outs);
		CHECK(cmd_is(r, want));
		CHECK_EQ(r->cell, 0);
		CHECK(r->ndeps == 1 && r->deps[0] == plan_find(&p, "vox"));
	}
	struct job *s = job_named(&p, "ssvdag/root");
	if (s) {
		snprintf(want, sizeof want, "symmetry-merge %s/svdag/root.dag -o "
			 "%s/ssvdag/root.sdag --mem-budget 1073741824 --threads 2 "
			 "-q", outs, outs);
		CHECK(cmd_is(s, want));
		CHECK(s->ndeps == 1 && s->deps[0] == plan_find(&p, "svdag/root"));
	}
	struct job *e = job_named(&p, "enc");
	if (e) {
		/* --min-level: the shallowest resolution */
		snprintf(want, sizeof want, "encode %s/svdag/root.dag "
			 "%s/ssvdag/root.sdag -o %s/enc --name t --min-level 3 "
			 "--mem-budget 1073741824 --threads 2 -q --stats-list "
			 "%s/enc.stats-list", outs, outs, outs, outs);
		CHECK(cmd_is(e, want));
		CHECK(e->ndeps == 2 && e->deps[0] == plan_find(&p, "svdag/root") &&
		      e->deps[1] == plan_find(&p, "ssvdag/root"));
		/* Table 1's seconds: the statistics of both DAG jobs */
		char list[800];
		snprintf(list, sizeof list, "%s/enc.stats-list", outs);
		char *text2 = test_slurp(list, NULL);
		snprintf(want, sizeof want, "%s/svdag/root.dag.stats.json\n"
			 "%s/ssvdag/root.sdag.stats.json\n", outs, outs);
		CHECK(text2 && !strcmp(text2, want));
		free(text2);
	}
	/* nothing more to plan */
	CHECK_EQ(plan_expand(&p), 0);
	CHECK_EQ(p.n, 4);
	plan_free(&p);
	config_release(&c);
}

/* ------------------------------------------------------------------ keys */

/* The key as pipeline.md defines it, computed here from the job's argv
 * and the files: XXH3-64 over "voxdag-key-3", the program's name and NUL,
 * its stage version (int32), each argument and NUL but --threads N,
 * --mem-budget N, -q, --stats F, --stats-list F, then each input's
 * fingerprint: a chunk file's 24-byte footer hashed (the writer's own
 * whole-file checksum), any other file's XXH3 over all its bytes. */
static int ref_key(const struct job *j, char key[17])
{
	XXH3_state_t *s = XXH3_createState();
	XXH3_64bits_reset(s);
	XXH3_64bits_update(s, "voxdag-key-3", 12);
	const char *prog = strrchr(j->argv[0], '/') + 1;
	XXH3_64bits_update(s, prog, strlen(prog) + 1);
	int32_t v = vd_stage_version(prog);
	XXH3_64bits_update(s, &v, sizeof v);
	for (int i = 1; j->argv[i]; i++) {
		const char *a = j->argv[i];
		if (!strcmp(a, "-q"))
			continue;
		if (!strcmp(a, "--threads") || !strcmp(a, "--mem-budget") ||
		    !strcmp(a, "--stats") || !strcmp(a, "--stats-list")) {
			i++;
			continue;
		}
		XXH3_64bits_update(s, a, strlen(a) + 1);
	}
	int ok = 1;
	for (int i = 0; i < j->ninputs; i++) {
		FILE *f = fopen(j->inputs[i], "rb");
		if (!f) {
			ok = 0;
			break;
		}
		static uint8_t buf[1 << 20];
		size_t n = fread(buf, 1, sizeof buf, f);
		fclose(f);
		static const uint8_t magic[8] = {0x89, 'V', 'X', 'D', 'E', 'N',
						 'D', '\n'};
		uint64_t fp = n >= 24 && !memcmp(buf + n - 24, magic, 8)
				      ? XXH3_64bits(buf + n - 24, 24)
				      : XXH3_64bits(buf, n);
		XXH3_64bits_update(s, &fp, sizeof fp);
	}
	snprintf(key, 17, "%016llx", (unsigned long long)XXH3_64bits_digest(s));
	XXH3_freeState(s);
	return ok ? 0 : 1;
}

/* The keys of vox and of cell 009's svdag job for resources `res` and
 * grid depth `levels` (cells faked already), each checked against
 * ref_key. */
static void keys_for(const char *res, const char *levels, char vkey[17],
		     char ckey[17])
{
	struct config c;
	char text[1024];
	snprintf(text, sizeof text, "levels: %s\nchunk_level: 3\n%s\n%s",
		 levels, res, graph);
	CHECK_EQ(load(&c, text, NULL, 0), 0);
	struct plan p = {.cfg = &c};
	CHECK_EQ(plan_expand(&p), 0);
	finish(&p, "vox");
	CHECK_EQ(plan_expand(&p), 0);
	strcpy(vkey, "?");
	strcpy(ckey, "?");
	struct job *v = job_named(&p, "vox");
	struct job *cj = job_named(&p, "svdag/cells/chunk-L3-009");
	char want[17];
	if (v) {
		CHECK_EQ(job_key(v, vkey), 0);
		CHECK(ref_key(v, want) == 0 && !strcmp(vkey, want));
	}
	if (cj) {
		CHECK_EQ(job_key(cj, ckey), 0);
		CHECK(ref_key(cj, want) == 0 && !strcmp(ckey, want));
	}
	plan_free(&p);
	config_release(&c);
}

static void test_keys(void)
{
	fresh_outputs();
	write_text(mesh, "ply v1\n");
	fake_voxelize(7, 3, cells3, NCELLS, 1);
	const char *res1 = "resources: {jobs: 2, mem_budget: 1G, "
			   "job_mem_budget: 512M, threads: 3}";
	const char *res2 = "resources: {jobs: 4, mem_budget: 2G, "
			   "job_mem_budget: 256M, threads: 1}";
	char v1[17], c1[17], v2[17], c2[17];
	keys_for(res1, "7", v1, c1);
	/* again: the same */
	keys_for(res1, "7", v2, c2);
	CHECK(!strcmp(v1, v2) && !strcmp(c1, c2));
	/* other threads and budgets: the same (they change no output) */
	keys_for(res2, "7", v2, c2);
	CHECK(!strcmp(v1, v2) && !strcmp(c1, c2));
	/* another depth: voxelize's key changes (an argument) */
	keys_for(res1, "8", v2, c2);
	CHECK(strcmp(v1, v2) != 0);
	/* the mesh touched, bytes the same: the same key */
	struct timespec ts[2] = {{.tv_sec = 1000000000}, {.tv_sec = 1000000000}};
	CHECK_EQ(utimensat(AT_FDCWD, mesh, ts, 0), 0);
	keys_for(res1, "7", v2, c2);
	CHECK(!strcmp(v1, v2) && !strcmp(c1, c2));
	/* the mesh's content changed: voxelize's key changes, the cell's
	 * (its input is the .svo, unchanged) does not */
	write_text(mesh, "ply v2\n");
	keys_for(res1, "7", v2, c2);
	CHECK(strcmp(v1, v2) != 0);
	CHECK(!strcmp(c1, c2));
	/* the cell's .svo rewritten with the same header and bytes: the
	 * same; with other counts: the cell's key changes */
	char path[800];
	snprintf(path, sizeof path, "%s/vox/chunk-L3-009.svo", outs);
	write_chunk(path, VD_KIND_SVO, 7, 3, 9, 1);
	keys_for(res1, "7", v2, c2);
	CHECK(!strcmp(c1, c2));
	write_chunk(path, VD_KIND_SVO, 7, 3, 9, 2);
	keys_for(res1, "7", v2, c2);
	CHECK(strcmp(c1, c2) != 0);
	write_text(mesh, "ply v1\n");
	/* a missing input: no key */
	struct config c;
	char text[1024];
	snprintf(text, sizeof text, "levels: 7\n%s\n%s", res1, graph);
	CHECK_EQ(load(&c, text, NULL, 0), 0);
	struct plan p = {.cfg = &c};
	CHECK_EQ(plan_expand(&p), 0);
	CHECK_EQ(unlink(mesh), 0);
	char k[17];
	struct job *v = job_named(&p, "vox");
	CHECK(v && job_key(v, k) != 0);
	write_text(mesh, "ply v1\n");
	plan_free(&p);
	config_release(&c);
}

/* The stages on a root (pipeline.md's table): lossy-cluster (and a job
 * per lower resolution of the report), symmetry-merge of its root, an
 * edit with inline lines and the colours, colorize of the edited colours,
 * encode of the lossy scene and a render with the colours. */
static const char global_graph[] =
	"jobs:\n"
	"  vox: {stage: voxelize}\n"
	"  svdag: {stage: svo-to-dag, needs: [vox]}\n"
	"  lossy: {stage: lossy-cluster, needs: [svdag], inflation: %s, "
	"diff_factor: 1.0, max_refs: 2}\n"
	"  lssv: {stage: symmetry-merge, needs: [lossy]}\n"
	"  ed: {stage: edit, needs: [svdag, vox], script: [\"%s\", "
	"\"carve box 0 0 0 1 1 1\"]}\n"
	"  col: {stage: colorize, needs: [ed], method: vbr}\n"
	"  enc: {stage: encode, needs: [lossy, lssv]}\n"
	"  pic: {stage: render, needs: [enc, col]}\n";

static void load_global(struct config *c, const char *inflation,
			const char *edit, int threads)
{
	char jobs[2048], text[4096];
	snprintf(jobs, sizeof jobs, global_graph, inflation, edit);
	snprintf(text, sizeof text, "levels: 5\nchunk_level: 0\nresolutions: "
		 "[5, 4, 3]\nresources: {jobs: 2, mem_budget: 1G, "
		 "job_mem_budget: 128M, threads: %d}\n%s", threads, jobs);
	CHECK_EQ(load(c, text, NULL, 0), 0);
}

/* Plans the global graph up to its end: a one-cell scene, so every job
 * is known once voxelize has run. */
static void plan_global(struct plan *p, const struct config *c)
{
	memset(p, 0, sizeof *p);
	p->cfg = c;
	CHECK_EQ(plan_expand(p), 0);
	finish(p, "vox");
	CHECK_EQ(plan_expand(p), 0);
}

static void test_global_jobs(void)
{
	fresh_outputs();
	const uint64_t one = 0;
	fake_voxelize(5, 0, &one, 1, 1);
	struct config c;
	load_global(&c, "2.5", "fill box 0 0 0 3 3 3", 3);
	struct plan p;
	plan_global(&p, &c);
	/* vox, svdag/root, lossy/root + r4 + r3 (not r5: the full depth is
	 * the root), lssv/root, ed/root, col, enc, pic */
	CHECK_EQ(p.n, 10);
	CHECK_EQ(p.expanded, 1);
	char want[4096];
	const char *B = "134217728", *o = outs;
	struct job *j = job_named(&p, "vox");
	if (j) { /* a job takes the colours: no --no-colours */
		snprintf(want, sizeof want, "voxelize %s -o %s/vox --levels 5 "
			 "--mem-budget %s --threads 6 --chunk-level 0", mesh, o, B);
		CHECK(cmd_is(j, want));
	}
	j = job_named(&p, "lossy/root");
	if (j) {
		snprintf(want, sizeof want, "lossy-cluster %s/svdag/root.dag -o "
			 "%s/lossy/root.dag --inflation 2.5 --diff-factor 1.0 "
			 "--max-refs 2 --mem-budget %s --threads 3 -q", o, o, B);
		CHECK(cmd_is(j, want));
		CHECK(j->ndeps == 1 && j->deps[0] == plan_find(&p, "svdag/root"));
	}
	for (int r = 3; r <= 4; r++) {
		char id[64];
		snprintf(id, sizeof id, "lossy/r%d", r);
		j = job_named(&p, id);
		if (!j)
			continue;
		snprintf(want, sizeof want, "lossy-cluster %s/svdag/root.dag -o "
			 "%s/lossy/r%d.dag --levels %d --inflation 2.5 "
			 "--diff-factor 1.0 --max-refs 2 --mem-budget %s "
			 "--threads 3 -q", o, o, r, r, B);
		CHECK(cmd_is(j, want));
	}
	CHECK_EQ(plan_find(&p, "lossy/r5"), -1);
	j = job_named(&p, "lssv/root");
	if (j) {
		snprintf(want, sizeof want, "symmetry-merge %s/lossy/root.dag -o "
			 "%s/lssv/root.sdag --mem-budget %s --threads 3 -q", o, o,
			 B);
		CHECK(cmd_is(j, want));
		CHECK(j->ndeps == 1 && j->deps[0] == plan_find(&p, "lossy/root"));
	}
	j = job_named(&p, "ed/root");
	if (j) {
		snprintf(want, sizeof want, "edit %s/svdag/root.dag -o "
			 "%s/ed/root.dag --script %s/ed/script.txt --colours "
			 "%s/vox --colours-out %s/ed/colours --mem-budget %s "
			 "--threads 3 -q", o, o, o, o, o, B);
		CHECK(cmd_is(j, want));
		/* what the key covers beside the output: its statistics and
		 * the edited colours */
		snprintf(want, sizeof want, "%s/ed/root.dag.stats.json", o);
		CHECK(j->side[0] && !strcmp(j->side[0], want));
		snprintf(want, sizeof want, "%s/ed/colours", o);
		CHECK(j->side[1] && !strcmp(j->side[1], want));
		/* the inline lines, a line each, in the file the key covers */
		snprintf(want, sizeof want, "%s/ed/script.txt", o);
		char *script = test_slurp(want, NULL);
		CHECK(script && !strcmp(script, "fill box 0 0 0 3 3 3\n"
					       "carve box 0 0 0 1 1 1\n"));
		free(script);
		CHECK_EQ(j->ninputs, 3);
		if (j->ninputs == 3) {
			char m[800];
			snprintf(m, sizeof m, "%s/vox/manifest", o);
			CHECK(!strcmp(j->inputs[0], m));
			CHECK(!strcmp(j->inputs[2], want));
		}
	}
	j = job_named(&p, "col");
	if (j) {
		snprintf(want, sizeof want, "colorize %s/ed/colours -o %s/col "
			 "--method vbr --threads 3 -q", o, o);
		CHECK(cmd_is(j, want));
		CHECK(j->ndeps == 1 && j->deps[0] == plan_find(&p, "ed/root"));
	}
	j = job_named(&p, "enc");
	if (j) {
		snprintf(want, sizeof want, "encode %s/lossy/root.dag "
			 "%s/lssv/root.sdag -o %s/enc --name t --min-level 3 "
			 "--mem-budget %s --threads 3 -q --stats-list "
			 "%s/enc.stats-list", o, o, o, B, o);
		CHECK(cmd_is(j, want));
	}
	j = job_named(&p, "pic");
	if (j) {
		snprintf(want, sizeof want, "render %s/enc/t.ssvdag -o %s/pic.png "
			 "--size 960x720 --camera iso --colours %s/col/colours.vbr "
			 "--threads 6 -q", o, o, o);
		CHECK(cmd_is(j, want));
		CHECK(j->ndeps == 2 && j->deps[0] == plan_find(&p, "col") &&
		      j->deps[1] == plan_find(&p, "enc"));
	}
	plan_free(&p);
	config_release(&c);
}

/* The key of job `id` in the global graph with these settings (its
 * inputs made to exist first), checked against ref_key. */
static void global_key(const char *inflation, const char *edit, int threads,
		       const char *id, char key[17])
{
	struct config c;
	load_global(&c, inflation, edit, threads);
	struct plan p;
	plan_global(&p, &c);
	strcpy(key, "?");
	struct job *j = job_named(&p, id);
	if (j) {
		for (int i = 0; i < j->ninputs; i++)
			if (access(j->inputs[i], F_OK) != 0)
				write_chunk(j->inputs[i], VD_KIND_DAG, 5, 0, 0, 1);
		char want[17];
		CHECK_EQ(job_key(j, key), 0);
		CHECK(ref_key(j, want) == 0 && !strcmp(key, want));
	}
	plan_free(&p);
	config_release(&c);
}

/* A parameter of a stage is in its key; an edit's script content too. */
static void test_keys_global(void)
{
	fresh_outputs();
	const uint64_t one = 0;
	fake_voxelize(5, 0, &one, 1, 1);
	char vox[700];
	snprintf(vox, sizeof vox, "%s/vox", outs);
	CHECK_EQ(vd_manifest_write(vox), VD_OK);
	sh("mkdir -p '%s/svdag' '%s/svdag'", outs);
	char a[17], b[17];
	global_key("2.5", "fill box 0 0 0 3 3 3", 3, "lossy/root", a);
	global_key("2.5", "fill box 0 0 0 3 3 3", 1, "lossy/root", b);
	CHECK(!strcmp(a, b));
	global_key("3.0", "fill box 0 0 0 3 3 3", 3, "lossy/root", b);
	CHECK(strcmp(a, b) != 0);
	/* the lower-resolution jobs differ from the root's (--levels) */
	global_key("2.5", "fill box 0 0 0 3 3 3", 3, "lossy/r4", b);
	CHECK(strcmp(a, b) != 0);
	/* an edit line changed: the same command line, another script */
	global_key("2.5", "fill box 0 0 0 3 3 3", 3, "ed/root", a);
	global_key("2.5", "fill box 0 0 0 3 3 3", 1, "ed/root", b);
	CHECK(!strcmp(a, b));
	global_key("2.5", "fill box 0 0 0 3 3 4", 3, "ed/root", b);
	CHECK(strcmp(a, b) != 0);
	/* the colour chunks (through voxelize's manifest) are its input */
	global_key("2.5", "fill box 0 0 0 3 3 3", 3, "ed/root", a);
	char path[800];
	snprintf(path, sizeof path, "%s/chunk-L0-0.col", vox);
	write_chunk(path, VD_KIND_COLOURS, 5, 0, 0, 2);
	CHECK_EQ(vd_manifest_write(vox), VD_OK);
	global_key("2.5", "fill box 0 0 0 3 3 3", 3, "ed/root", b);
	CHECK(strcmp(a, b) != 0);
}

/* symmetry-merge with `group: 48` beside the group-8 one: its jobs carry
 * --group 48 (so their keys differ from the group 8 ones on the same
 * input), encode takes the third root after the second, and Table 1's
 * seconds leave the 48-group's merge out. */
static void test_group48(void)
{
	fresh_outputs();
	struct config c;
	char text[2048], want[4096];
	snprintf(text, sizeof text, "levels: 5\nchunk_level: 0\nresolutions: "
		 "[5]\nresources: {jobs: 1, mem_budget: 1G, job_mem_budget: 1G, "
		 "threads: 1}\njobs:\n"
		 "  vox: {stage: voxelize}\n"
		 "  svdag: {stage: svo-to-dag, needs: [vox]}\n"
		 "  s8: {stage: symmetry-merge, needs: [svdag]}\n"
		 "  s48: {stage: symmetry-merge, needs: [svdag], group: 48}\n"
		 "  enc: {stage: encode, needs: [svdag, s48, s8]}\n");
	CHECK_EQ(load(&c, text, NULL, 0), 0);
	const uint64_t one = 0;
	fake_voxelize(5, 0, &one, 1, 1);
	struct plan p = {.cfg = &c};
	CHECK_EQ(plan_expand(&p), 0);
	finish(&p, "vox");
	CHECK_EQ(plan_expand(&p), 0);
	CHECK_EQ(p.n, 5);
	CHECK_EQ(p.expanded, 1);
	const char *o = outs;
	struct job *s8 = job_named(&p, "s8/root"), *s48 = job_named(&p, "s48/root");
	if (s8) {
		snprintf(want, sizeof want, "symmetry-merge %s/svdag/root.dag -o "
			 "%s/s8/root.sdag --mem-budget 1073741824 --threads 1 -q",
			 o, o);
		CHECK(cmd_is(s8, want));
	}
	if (s48) {
		snprintf(want, sizeof want, "symmetry-merge %s/svdag/root.dag -o "
			 "%s/s48/root.sdag --mem-budget 1073741824 --threads 1 -q "
			 "--group 48", o, o);
		CHECK(cmd_is(s48, want));
	}
	struct job *e = job_named(&p, "enc");
	if (e) {
		/* the group-8 root second, whatever the order of needs */
		snprintf(want, sizeof want, "encode %s/svdag/root.dag "
			 "%s/s8/root.sdag %s/s48/root.sdag -o %s/enc --name t "
			 "--min-level 5 --mem-budget 1073741824 --threads 1 -q "
			 "--stats-list %s/enc.stats-list", o, o, o, o, o);
		CHECK(cmd_is(e, want));
		CHECK_EQ(e->ndeps, 3);
		char list[800];
		snprintf(list, sizeof list, "%s/enc.stats-list", o);
		char *got = test_slurp(list, NULL);
		snprintf(want, sizeof want, "%s/svdag/root.dag.stats.json\n"
			 "%s/s8/root.sdag.stats.json\n", o, o);
		CHECK(got && !strcmp(got, want));
		free(got);
	}
	/* the same input, the same output name but for the directory: the
	 * keys differ by the group (and the -o path) */
	if (s8 && s48) {
		sh("mkdir -p '%s/svdag' '%s/svdag'", o);
		write_chunk(s8->inputs[0], VD_KIND_DAG, 5, 0, 0, 1);
		char k8[17], k48[17], r48[17];
		CHECK_EQ(job_key(s8, k8), 0);
		CHECK_EQ(job_key(s48, k48), 0);
		CHECK(strcmp(k8, k48) != 0);
		CHECK(ref_key(s48, r48) == 0 && !strcmp(k48, r48));
	}
	plan_free(&p);
	config_release(&c);
}

/* A finished job's journal line, freshness, and what makes it stale. */
static void test_journal(void)
{
	fresh_outputs();
	struct config c;
	char text[1024], why[600];
	snprintf(text, sizeof text, "levels: 7\nchunk_level: 3\nresources: "
		 "{jobs: 2, mem_budget: 1G, job_mem_budget: 512M, threads: 3}\n"
		 "%s", graph);
	CHECK_EQ(load(&c, text, NULL, 0), 0);
	struct plan p = {.cfg = &c};
	CHECK_EQ(plan_expand(&p), 0); /* loads outs/keys, read only */
	CHECK_EQ(keys_open(outs, 1), 0);
	fake_voxelize(7, 3, cells3, NCELLS, 1);
	finish(&p, "vox");
	CHECK_EQ(plan_expand(&p), 0);
	struct job *j = job_named(&p, "svdag/cells/chunk-L3-040");
	if (!j) {
		plan_free(&p);
		config_release(&c);
		return;
	}
	/* never finished: not fresh, no key */
	CHECK_EQ(job_is_fresh(j, why, sizeof why), 0);
	CHECK_EQ(j->key_absent, 1);
	write_chunk(j->output, VD_KIND_DAG, 7, 3, 0x40, 1);
	/* a file output's statistics are part of what it wrote: without
	 * them the job did not finish */
	char stats[800];
	snprintf(stats, sizeof stats, "%s.stats.json", j->output);
	CHECK(j->side[0] && !strcmp(j->side[0], stats));
	CHECK(job_key_write(j, why, sizeof why) != 0);
	write_text(stats, "{\"voxels\": 1}\n");
	CHECK_EQ(job_key_write(j, why, sizeof why), 0);
	/* the journal's one line: CHECK K KEY DIGEST SIG PATH, the path
	 * relative to the outputs, the output just written so not settled
	 * ("-"), CHECK the XXH3 of the rest; DIGEST the XXH3 of the two
	 * files' XXH3s, the output's first */
	char kpath[800], key[17], body[600], line[700];
	snprintf(kpath, sizeof kpath, "%s/keys", outs);
	char *journal = test_slurp(kpath, NULL);
	CHECK(ref_key(j, key) == 0);
	uint64_t digests[2] = {0, 0}, size;
	CHECK_EQ(vd_file_xxh3(j->output, &digests[0], &size), VD_OK);
	CHECK_EQ(vd_file_xxh3(stats, &digests[1], &size), VD_OK);
	uint64_t digest = XXH3_64bits(digests, sizeof digests);
	int n = snprintf(body, sizeof body, "K %s %016llx - "
			 "svdag/cells/chunk-L3-040.dag", key,
			 (unsigned long long)digest);
	snprintf(line, sizeof line, "%016llx %s\n",
		 (unsigned long long)XXH3_64bits(body, (size_t)n), body);
	CHECK(journal && !strcmp(journal, line));
	if (journal && strcmp(journal, line))
		fprintf(stderr, "journal: %s   want: %s", journal, line);
	free(journal);
	CHECK_EQ(job_is_fresh(j, why, sizeof why), 1);
	CHECK_EQ(j->key_absent, 0);
	/* the output changed after it was written */
	write_chunk(j->output, VD_KIND_DAG, 7, 3, 0x40, 2);
	char want[900];
	snprintf(want, sizeof want, "'%s' or a file written with it changed "
		 "after it was written", j->output);
	CHECK_EQ(job_is_fresh(j, why, sizeof why), 0);
	CHECK(!strcmp(why, want));
	write_chunk(j->output, VD_KIND_DAG, 7, 3, 0x40, 1);
	CHECK_EQ(job_is_fresh(j, why, sizeof why), 1);
	/* its statistics emptied (what a power cut did before they were
	 * fsynced), changed, deleted: it runs again */
	write_text(stats, "");
	CHECK_EQ(job_is_fresh(j, why, sizeof why), 0);
	CHECK(!strcmp(why, want));
	write_text(stats, "{\"voxels\": 2}\n");
	CHECK_EQ(job_is_fresh(j, why, sizeof why), 0);
	CHECK_EQ(unlink(stats), 0);
	snprintf(want, sizeof want, "'%s' is missing", stats);
	CHECK_EQ(job_is_fresh(j, why, sizeof why), 0);
	CHECK(!strcmp(why, want));
	write_text(stats, "{\"voxels\": 1}\n");
	CHECK_EQ(job_is_fresh(j, why, sizeof why), 1);
	/* the output deleted */
	CHECK_EQ(unlink(j->output), 0);
	snprintf(want, sizeof want, "'%s' is missing", j->output);
	CHECK_EQ(job_is_fresh(j, why, sizeof why), 0);
	CHECK(!strcmp(why, want));
	write_chunk(j->output, VD_KIND_DAG, 7, 3, 0x40, 1);
	/* its input changed: another key, stale ("" : nothing wrong with
	 * the output itself) */
	char in[800];
	snprintf(in, sizeof in, "%s", j->inputs[0]);
	write_chunk(in, VD_KIND_SVO, 7, 3, 0x40, 3);
	CHECK_EQ(job_is_fresh(j, why, sizeof why), 0);
	CHECK(!strcmp(why, ""));
	write_chunk(in, VD_KIND_SVO, 7, 3, 0x40, 1);
	CHECK_EQ(job_is_fresh(j, why, sizeof why), 1);
	/* a later run's plan counts it finished (skipped) as soon as it is
	 * planned; the other cells, never finished, are pending */
	struct plan q = {.cfg = &c};
	CHECK_EQ(plan_expand(&q), 0);
	finish(&q, "vox");
	CHECK_EQ(plan_expand(&q), 0);
	CHECK_EQ(count_jobs(&q, 1, 1), NCELLS);
	for (int i = 0; i < q.n; i++)
		if (q.jobs[i].decl == 1)
			CHECK_EQ(q.jobs[i].state,
				 strstr(q.jobs[i].id, "chunk-L3-040") ? JOB_SKIPPED
								      : JOB_PENDING);
	plan_free(&q);
	/* dropped (about to be rebuilt): no key, and a D line appended */
	job_key_drop(j);
	CHECK_EQ(job_is_fresh(j, why, sizeof why), 0);
	CHECK_EQ(j->key_absent, 1);
	journal = test_slurp(kpath, NULL);
	n = snprintf(body, sizeof body, "D svdag/cells/chunk-L3-040.dag");
	snprintf(want, sizeof want, "%016llx %s\n",
		 (unsigned long long)XXH3_64bits(body, (size_t)n), body);
	CHECK(journal && strlen(journal) >= strlen(want) &&
	      !strcmp(journal + strlen(journal) - strlen(want), want));
	free(journal);
	/* and a later plan runs it again */
	memset(&q, 0, sizeof q);
	q.cfg = &c;
	CHECK_EQ(plan_expand(&q), 0);
	finish(&q, "vox");
	CHECK_EQ(plan_expand(&q), 0);
	struct job *again = job_named(&q, "svdag/cells/chunk-L3-040");
	CHECK(again && again->state == JOB_PENDING);
	plan_free(&q);
	plan_free(&p);
	config_release(&c);
}

/* -------------------------------------------------------- bad pipelines */

struct bad {
	const char *rest;  /* after version, name, input, outputs */
	const char *error; /* after "voxdag: PATH:" */
};

static const struct bad bads[] = {
	{"levels: 9\njobs:\n  vox: {stage: voxelise}\n",
	 "7:16: unknown stage 'voxelise' (known: voxelize, svo-to-dag, "
	 "symmetry-merge, encode, render, lossy-cluster, edit, colorize)"},
	{"levels: 9\njobs:\n  vox: {stage: voxelize}\n"
	 "  d: {stage: svo-to-dag, needs: [vx]}\n",
	 "8:3: job 'd' needs 'vx', which is not a job"},
	{"levels: 9\njobs:\n  vox: {stage: voxelize}\n"
	 "  d: {stage: svo-to-dag, needs: [vox]}\n"
	 "  s: {stage: symmetry-merge, needs: [vox]}\n",
	 "9:3: job 's' (stage symmetry-merge) takes needs: [an svo-to-dag, "
	 "lossy-cluster or edit job]"},
	{"levels: 9\njobs:\n  a: {stage: voxelize}\n  b: {stage: voxelize}\n",
	 "7:3: a pipeline has exactly one voxelize job (found 2)"},
	{"levels: 22\njobs:\n  vox: {stage: voxelize}\n",
	 "5:9: 'levels' is 22, outside 1..21"},
	{"levels: 9\nchunk_level: 8\njobs:\n  vox: {stage: voxelize}\n",
	 "6:14: 'chunk_level' is 8, outside 0..7"},
	{"levels: 6\nchunk_level: 5\njobs:\n  vox: {stage: voxelize}\n",
	 "1:1: 'chunk_level' 5 is deeper than levels - 2"},
	{"levels: 9\nresources: {mem_budget: 1G, job_mem_budget: 2G}\n"
	 "jobs:\n  vox: {stage: voxelize}\n",
	 "1:1: 'job_mem_budget' is larger than 'mem_budget'"},
	{"levels: 9\nresources: {mem_budget: lots}\njobs:\n"
	 "  vox: {stage: voxelize}\n",
	 "6:25: 'mem_budget' must be a size such as 512M or 4GiB"},
	{"levels: 9\nresolutions: [9, 10]\njobs:\n  vox: {stage: voxelize}\n",
	 "6:14: resolution 10 is deeper than 'levels' 9"},
	{"levels: nine\njobs:\n  vox: {stage: voxelize}\n",
	 "5:9: 'levels' must be a whole number"},
	{"jobs:\n  vox: {stage: voxelize}\n", "1:1: missing 'levels'"},
};

static void test_bad_configs(void)
{
	char path[700], err[2048], want[4096];
	snprintf(path, sizeof path, "%s/p.yaml", root);
	for (size_t i = 0; i < sizeof bads / sizeof *bads; i++) {
		struct config c;
		CHECK_EQ(load(&c, bads[i].rest, err, sizeof err), 1);
		snprintf(want, sizeof want, "voxdag: %s:%s\n", path,
			 bads[i].error);
		CHECK(!strcmp(err, want));
		if (strcmp(err, want))
			fprintf(stderr, "  got: %s want: %s", err, want);
	}
	/* a missing input names it and the cause */
	struct config c;
	char keep[200];
	snprintf(keep, sizeof keep, "%s", mesh);
	snprintf(mesh, sizeof mesh, "%s/absent.ply", root);
	CHECK_EQ(load(&c, "levels: 9\njobs:\n  vox: {stage: voxelize}\n", err,
		      sizeof err), 1);
	snprintf(want, sizeof want, "voxdag: %s:3:8: input '%s': %s\n", path,
		 mesh, strerror(ENOENT));
	CHECK(!strcmp(err, want));
	if (strcmp(err, want))
		fprintf(stderr, "  got: %s want: %s", err, want);
	snprintf(mesh, sizeof mesh, "%s", keep);
}

/* The error for an unknown stage names every stage the runner accepts
 * (it once listed them by hand, without colorize, so a user who
 * misspelt "colorize" was not told the right name). */
static void test_unknown_stage_lists_all(void)
{
	struct config c;
	char err[2048];
	CHECK_EQ(load(&c, "levels: 9\njobs:\n  vox: {stage: voxelize}\n"
		      "  col: {stage: colourize, needs: [vox]}\n", err,
		      sizeof err), 1);
	CHECK(stage_lookup("colorize") != NULL);
	CHECK(strstr(err, "colorize") != NULL);
}

int main(void)
{
	root = test_tmpdir("test_plan");
	snprintf(outs, sizeof outs, "%s/out", root);
	snprintf(mesh, sizeof mesh, "%s/in.ply", root);
	write_text(mesh, "ply v1\n");
	RUN(test_config);
	RUN(test_voxelize_job);
	RUN(test_cells);
	RUN(test_tree_one_merge);
	RUN(test_tree_of_eights);
	RUN(test_tree_coarsest_fit);
	RUN(test_budget_capped);
	RUN(test_single_cell);
	RUN(test_keys);
	RUN(test_global_jobs);
	RUN(test_keys_global);
	RUN(test_group48);
	RUN(test_bad_configs);
	RUN(test_unknown_stage_lists_all);
	RUN(test_journal); /* last: it writes the one key journal */
	return CHECK_DONE();
}
