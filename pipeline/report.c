/* report.c - out/<name>/report.md, .json and .csv: the paper-style tables
 * that encode computed, and the run's own figures per stage (seconds, peak
 * memory against the budget), gathered from every job's statistics file so
 * a resumed run reports the same work as an uninterrupted one. */
#include "pipeline.h"
#include "io/publish.h"

#include <errno.h>
#include <fcntl.h>
#include <jansson.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* Reads a whole small text file (NULL if absent). No stdio: a report
 * reads one statistics file per job. */
static char *slurp(const char *path)
{
	int fd = vd_open_read(path);
	struct stat st;
	if (fd < 0)
		return NULL;
	char *s = fstat(fd, &st) == 0 ? malloc((size_t)st.st_size + 1) : NULL;
	size_t n = 0;
	while (s && n < (size_t)st.st_size) {
		ssize_t r = read(fd, s + n, (size_t)st.st_size - n);
		if (r < 0 && errno == EINTR)
			continue;
		if (r <= 0) { /* shorter than it was: not whole */
			free(s);
			s = NULL;
			break;
		}
		n += (size_t)r;
	}
	if (s)
		s[n] = 0;
	close(fd);
	return s;
}

/* The number at obj.key (0 when obj is not an object or holds no number
 * there): the one lookup every reader below ends in. */
static double num_at(const json_t *obj, const char *key)
{
	json_t *v = json_is_object(obj) ? json_object_get(obj, key) : NULL;
	return json_is_number(v) ? json_number_value(v) : 0;
}

/* The number at "key" of a statistics file's JSON text, or at
 * "within"."key" when `within` is given; 0 when the text is absent, is not
 * JSON, or has no such number (a report still comes out, with zeros). */
static double json_number(const char *text, const char *within, const char *key)
{
	if (!text)
		return 0;
	json_error_t jerr;
	json_t *root = json_loads(text, 0, &jerr);
	if (!root)
		return 0;
	double d = num_at(within ? json_object_get(root, within) : root, key);
	json_decref(root);
	return d;
}

/* The number at root.array[index].key of a JSON text (0 when absent). */
static double json_row_number(const char *text, const char *array,
			      size_t index, const char *key)
{
	if (!text)
		return 0;
	json_error_t jerr;
	json_t *root = json_loads(text, 0, &jerr);
	if (!root)
		return 0;
	double d = num_at(json_array_get(json_object_get(root, array), index),
			  key);
	json_decref(root);
	return d;
}

/* The sum of root.array[*].key, and the number of rows in *rows. */
static double json_sum(const char *text, const char *array, const char *key,
		       size_t *rows)
{
	*rows = 0;
	if (!text)
		return 0;
	json_error_t jerr;
	json_t *root = json_loads(text, 0, &jerr);
	if (!root)
		return 0;
	json_t *a = json_object_get(root, array), *row;
	size_t i;
	double sum = 0;
	json_array_foreach(a, i, row) {
		json_t *v = json_object_get(row, key);
		sum += json_is_number(v) ? json_number_value(v) : 0;
		(*rows)++;
	}
	json_decref(root);
	return sum;
}

/* json_number in an object already parsed (NULL: 0): the report parses
 * each job's statistics once, as it reads one file per job. */
static double json_get(const json_t *root, const char *within, const char *key)
{
	return num_at(within && root ? json_object_get(root, within) : root,
		      key);
}

/* json_sum in an object already parsed. */
static double json_sum_in(const json_t *root, const char *array,
			  const char *key, size_t *rows)
{
	*rows = 0;
	json_t *a = json_is_object(root) ? json_object_get(root, array) : NULL,
	       *row;
	size_t i;
	double sum = 0;
	json_array_foreach(a, i, row) {
		sum += num_at(row, key);
		(*rows)++;
	}
	return sum;
}

/* The statistics file a job's stage wrote beside its output. */
static void stats_path(const struct plan *p, const struct job *j, char *buf,
		       size_t cap)
{
	const struct job_decl *d = &p->cfg->jobs_decl[j->decl];
	if (d->stage->type == STAGE_VOXELIZE)
		snprintf(buf, cap, "%s/voxelize.stats.json", j->output);
	else if (d->stage->type == STAGE_ENCODE)
		snprintf(buf, cap, "%s/%s.encode.stats.json", j->output,
			 p->cfg->name);
	else
		snprintf(buf, cap, "%s.stats.json", j->output);
}

/* The report's files are published like every output (vd_atomic_*:
 * fsync, rename, directory fsync): a full disk leaves the previous report
 * as it was (writing in place truncated it), and the cause is said. */
static FILE *open_tmp(const char *path, struct vd_atomic *a)
{
	return vd_atomic_open(a, path) == VD_OK ? a->f : NULL;
}

/* Publishes a's file (f: a->f, or NULL when open_tmp failed); on failure
 * puts the cause in why (if it holds none yet) and returns 1. */
static int close_tmp(FILE *f, struct vd_atomic *a, const char *path,
		     char *why, size_t cap)
{
	int e = errno; /* open_tmp's cause when f is NULL */
	if (f) {
		if (vd_atomic_commit(a) == VD_OK)
			return 0;
		e = errno;
	}
	if (!*why)
		snprintf(why, cap, "cannot write '%s': %s", path, strerror(e));
	return 1;
}

struct stage_row {
	int jobs;
	double seconds;        /* sum of the stages' own seconds */
	double wall_this_run;  /* sum of the jobs run this time */
	double cpu;            /* the jobs' CPU seconds, user + system */
	int cpu_unknown;       /* jobs whose CPU is not known */
	uint64_t peak_rss;     /* largest job */
	uint64_t budget;       /* largest --mem-budget given; 0: none */
};

/* The --mem-budget a job was given (0 when its stage takes none). */
static uint64_t job_budget(const struct job *j)
{
	for (char **a = j->argv; a && *a && a[1]; a++)
		if (!strcmp(*a, "--mem-budget"))
			return strtoull(a[1], NULL, 10);
	return 0;
}

/* The pictures side by side (one paragraph), then what each shows. */
static void write_pictures(FILE *f, const struct plan *p)
{
	const struct config *c = p->cfg;
	int n = 0;
	for (int d = 0; d < c->njobs; d++) {
		if (c->jobs_decl[d].stage->type != STAGE_RENDER)
			continue;
		/* relative to the report, which sits in p->dir */
		char out[1100];
		snprintf(out, sizeof out, "%s.png", c->jobs_decl[d].name);
		fprintf(f, "%s![%s](%s)", n++ ? " " : "", c->jobs_decl[d].name,
			out);
	}
	if (!n)
		return;
	fprintf(f, "\n\n");
	if (n == 1)
		return;
	fprintf(f, "Left to right:");
	n = 0;
	for (int d = 0; d < c->njobs; d++) {
		const struct job_decl *r = &c->jobs_decl[d];
		if (r->stage->type != STAGE_RENDER)
			continue;
		fprintf(f, "%s `%s`, the scene of `%s`", n++ ? ";" : "", r->name,
			c->jobs_decl[r->needs[0]].name);
		if (r->nneeds > 1 &&
		    c->jobs_decl[r->needs[1]].stage->type == STAGE_COLORIZE)
			fprintf(f, ", colours of `%s`",
				c->jobs_decl[r->needs[1]].name);
		else if (r->nneeds > 1)
			fprintf(f, ", voxels set in only one of it and `%s`'s "
				"scene in red", c->jobs_decl[r->needs[1]].name);
	}
	fprintf(f, ".\n\n");
}

static double mb(double bytes);

/* The render job drawing the colours of colorize job `d` (NULL if none). */
static const struct job_decl *render_of_colours(const struct config *c, int d,
						int *encode)
{
	for (int r = 0; r < c->njobs; r++) {
		const struct job_decl *rd = &c->jobs_decl[r];
		if (rd->stage->type == STAGE_RENDER && rd->nneeds > 1 &&
		    rd->needs[1] == d) {
			*encode = rd->needs[0];
			return rd;
		}
	}
	return NULL;
}

/* The colour paper's Table 3: per colorize job, its method and setting,
 * the share of the raw colours it stores, GMSE, and, when the scene is
 * also drawn with lossless colours (a raw or lossless palette job) by a
 * render job of the same encoding, the image MSE and MS-SSIM of its
 * picture against that one. */
static void write_colours(FILE *f, const struct plan *p)
{
	const struct config *c = p->cfg;
	int any = 0;
	for (int d = 0; d < c->njobs; d++)
		any |= c->jobs_decl[d].stage->type == STAGE_COLORIZE;
	if (!any)
		return;
	/* the reference picture: lossless colours */
	const struct job_decl *ref = NULL;
	int ref_enc = -1;
	for (int d = 0; d < c->njobs && !ref; d++) {
		const struct job_decl *cd = &c->jobs_decl[d];
		if (cd->stage->type == STAGE_COLORIZE &&
		    (!strcmp(cd->method, "raw") ||
		     (strcmp(cd->method, "vbr") && cd->lossless)))
			ref = render_of_colours(c, d, &ref_enc);
	}
	fprintf(f, "# Colours (Dolonius et al. 2017, Table 3)\n\n");
	fprintf(f, "| job | method | setting | %% of raw | MB | GMSE | GMSE (%%²) "
		"| max error | blocks | seconds | Mvoxels/s | image MSE | MS-SSIM |\n");
	fprintf(f, "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
	double voxels = 0, raw = 0;
	for (int d = 0; d < c->njobs; d++) {
		const struct job_decl *cd = &c->jobs_decl[d];
		if (cd->stage->type != STAGE_COLORIZE)
			continue;
		char path[1300];
		snprintf(path, sizeof path, "%s/%s/colorize.stats.json", p->dir,
			 cd->name);
		char *st = slurp(path);
		if (!st) {
			fprintf(f, "| `%s` | %s | | (not built) | | | | | | | | | |\n",
				cd->name, cd->method);
			continue;
		}
		voxels = json_number(st, NULL, "voxels");
		raw = json_number(st, NULL, "bytes_raw");
		json_error_t jerr;
		json_t *root = json_loads(st, 0, &jerr);
		json_t *m = json_object_get(json_object_get(root, "methods"),
					    cd->method);
#define NUM(k) num_at(m, k)
		char setting[64];
		if (!strcmp(cd->method, "vbr"))
			snprintf(setting, sizeof setting, "et %g, %g-bit weights",
				 NUM("max_error_limit"), NUM("weight_bits"));
		else if (!strcmp(cd->method, "palette"))
			snprintf(setting, sizeof setting, cd->lossless ?
				 "lossless (%.0f colours)" : "%.0f colours",
				 NUM("palette_colours"));
		else if (!strcmp(cd->method, "auto") && cd->lossless)
			snprintf(setting, sizeof setting, "lossless, %.0f-voxel "
				 "blocks", NUM("block_voxels"));
		else if (!strcmp(cd->method, "auto"))
			snprintf(setting, sizeof setting, "max error %g, %.0f-voxel "
				 "blocks", NUM("max_error_limit"),
				 NUM("block_voxels"));
		else
			snprintf(setting, sizeof setting, "zstd");
		char img[64] = "| |";
		int enc;
		const struct job_decl *r = render_of_colours(c, d, &enc);
		if (ref && r && enc == ref_enc) {
			char pa[1300], pb[1300];
			snprintf(pa, sizeof pa, "%s/%s.png", p->dir, ref->name);
			snprintf(pb, sizeof pb, "%s/%s.png", p->dir, r->name);
			uint8_t *a = NULL, *b = NULL;
			int wa, ha, wb, hb;
			struct vd_image_metrics im;
			if (vd_png_read_rgb(pa, &a, &wa, &ha) == VD_OK &&
			    vd_png_read_rgb(pb, &b, &wb, &hb) == VD_OK &&
			    wa == wb && ha == hb &&
			    vd_image_metrics(a, b, wa, ha, &im) == VD_OK)
				snprintf(img, sizeof img, "| %.3f | %.5f |",
					 im.mse, im.ms_ssim);
			vd_error_clear();
			free(a);
			free(b);
		}
		fprintf(f, "| `%s` | %s | %s | %.2f | %.3f | %.3f | %.3f | %.4f | "
			"%.0f | %.2f | %.2f %s\n", cd->name, cd->method, setting,
			NUM("percent_of_raw"), mb(NUM("bytes")), NUM("gmse"),
			NUM("gmse_percent2"), NUM("max_error"), NUM("blocks"), NUM("seconds"),
			NUM("voxels_per_second") / 1e6, img);
#undef NUM
		json_decref(root);
		free(st);
	}
	fprintf(f, "\n%.0f voxels, %.3f MB of raw RGB8 colours. %% of raw is "
		"the compressed structure's bytes against 3 bytes a voxel; GMSE "
		"(in 8-bit units, and in percent squared: the unit of the "
		"paper's figures) and max error as colorize reports them "
		"(schemas/colour-formats.md); image MSE and MS-SSIM compare the "
		"picture with that of lossless colours (`%s`)%s.\n\n", voxels,
		mb(raw), ref ? ref->name : "none",
		ref ? "" : ": add a raw or lossless palette colorize job and a "
		"render of it to get them");
}

/* The job of declared job d when it is an encode job, or NULL. */
static const struct job *encode_job(const struct plan *p, int d)
{
	if (p->cfg->jobs_decl[d].stage->type != STAGE_ENCODE)
		return NULL;
	for (int i = 0; i < p->n; i++)
		if (p->jobs[i].decl == d)
			return &p->jobs[i];
	return NULL;
}

/* The encode job whose DAG input is declared job `dag`, or NULL. */
static const struct job *encode_of(const struct plan *p, int dag)
{
	const struct config *c = p->cfg;
	for (int i = 0; i < p->n; i++) {
		const struct job_decl *d = &c->jobs_decl[p->jobs[i].decl];
		if (d->stage->type == STAGE_ENCODE &&
		    (d->needs[0] == dag || d->needs[1] == dag))
			return &p->jobs[i];
	}
	return NULL;
}

static double mb(double bytes)
{
	return bytes / 1048576.0;
}

/* The lossy paper's Tables 1 and 2 (van der Laan et al. 2020) for
 * lossy-cluster job d: the graph and times from its statistics, nodes and
 * sizes from the tables of the encode jobs of its input and its output.
 * `svdag_seconds` is the run's sum for the input's job, used when the
 * lossless encode has no Table 1 seconds. */
static void write_lossy(FILE *f, const struct plan *p, int d,
			double svdag_seconds)
{
	const struct config *c = p->cfg;
	const struct job_decl *ld = &c->jobs_decl[d];
	char path[1200], id[200];
	snprintf(id, sizeof id, "%s/root", ld->name);
	const struct job *lj = NULL;
	for (int i = 0; i < p->n && !lj; i++)
		if (!strcmp(p->jobs[i].id, id))
			lj = &p->jobs[i];
	fprintf(f, "# Lossy compression: job `%s`\n\n", ld->name);
	snprintf(path, sizeof path, "%s.stats.json", lj ? lj->output : "");
	char *st = lj ? slurp(path) : NULL;
	if (!st) {
		fprintf(f, "(not built)\n\n");
		return;
	}
	const struct job *e0 = encode_of(p, ld->needs[0]), *e1 = encode_of(p, d);
	char *t0 = NULL, *t1 = NULL;
	if (e0) {
		snprintf(path, sizeof path, "%s/%s.tables.json", e0->output, c->name);
		t0 = slurp(path);
	}
	if (e1) {
		snprintf(path, sizeof path, "%s/%s.tables.json", e1->output, c->name);
		t1 = slurp(path);
	}
	size_t nlev;
	json_sum(st, "per_level", "edges", &nlev);
	double vbefore = json_number(st, NULL, "voxels_before");
	double svdag_s = t0 ? json_row_number(t0, "table1", 0,
					      "seconds_svo_to_dag") : 0;
	if (svdag_s == 0)
		svdag_s = svdag_seconds;
	fprintf(f, "Lossy SVDAG (van der Laan, Scandolo and Eisemann 2020) of "
		"`%s`: inflation %s, diff_factor %s, max_refs %s. Resolution "
		"%d^3 (Table 2 and the pictures: the lossy DAG that the stages "
		"after it take).\n\n",
		c->jobs_decl[ld->needs[0]].name, ld->inflation, ld->diff_factor,
		ld->max_refs, 1 << c->levels);
	fprintf(f, "## Table 1: similarity graph and times (minutes)\n\n"
		"| scene | resolution | MVoxels | graph MNodes | graph MEdges | "
		"SVDAG constr. | sim. graph constr. | clustering |\n"
		"|---|---:|---:|---:|---:|---:|---:|---:|\n");
	/* a row per resolution: the full one, then each lower one of the
	 * report's, clustered by its own job (job id <name>/r<depth>) */
	const char *scene = c->mesh[0] ? c->mesh : c->vdb[0] ? c->vdb : c->name;
	const char *base = strrchr(scene, '/');
	base = base ? base + 1 : scene;
	for (int i = -1; i < c->nres; i++) {
		int r = i < 0 ? c->levels : c->resolutions[i];
		if (i >= 0 && r >= c->levels)
			continue;
		char *rs = st;
		if (i >= 0) {
			snprintf(id, sizeof id, "%s/r%d", ld->name, r);
			const struct job *rj = NULL;
			for (int k = 0; k < p->n && !rj; k++)
				if (!strcmp(p->jobs[k].id, id))
					rj = &p->jobs[k];
			snprintf(path, sizeof path, "%s.stats.json",
				 rj ? rj->output : "");
			rs = rj ? slurp(path) : NULL;
			if (!rs) {
				fprintf(f, "| %s | %d^3 | (not built) | | | | | |\n",
					base, 1 << r);
				continue;
			}
		}
		size_t nl;
		/* SVDAG construction: svo-to-dag at the full resolution; a
		 * lower one is the full DAG cut at its depth */
		double cons = i < 0 ? svdag_s : json_number(rs, NULL, "seconds_cut");
		fprintf(f, "| %s | %d^3 | %.6f | %.6f | %.6f | %.4f | %.4f | "
			"%.4f |\n", base, 1 << r,
			json_number(rs, NULL, "voxels_before") / 1e6,
			json_sum(rs, "per_level", "graph_nodes", &nl) / 1e6,
			json_sum(rs, "per_level", "edges", &nl) / 1e6, cons / 60,
			json_number(rs, NULL, "seconds_graph") / 60,
			json_number(rs, NULL, "seconds_clustering") / 60);
		if (rs != st)
			free(rs);
	}
	fprintf(f, "\nSVDAG construction: `svo-to-dag` over all its processes "
		"at the full resolution, the cut of its DAG at a lower one; "
		"graph and clustering summed over the levels clustered (%zu at "
		"the full resolution: effective reference counts %.3f s, "
		"lossless reduction %.3f s).\n\n",
		nlev, json_number(st, NULL, "seconds_effective_refs"),
		json_number(st, NULL, "seconds_reduction"));
	fprintf(f, "## Table 2: nodes and memory (MB = 2^20 bytes)\n\n");
	if (!t0 || !t1) {
		fprintf(f, "(needs an encode job of `%s` and one of `%s`)\n\n",
			c->jobs_decl[ld->needs[0]].name, ld->name);
	} else {
		/* name, tables text, node key, bytes key (format name) */
		static const struct {
			const char *name;
			int lossy;
			const char *nodes, *fmt;
		} rows[] = {
			{"SVO", 0, "nodes_svo", "svo"},
			{"SVDAG", 0, "nodes_svdag", "svdag"},
			{"LSVDAG", 1, "nodes_svdag", "svdag"},
			{"ESVDAG", 0, "nodes_svdag", "esvdag"},
			{"LESVDAG", 1, "nodes_svdag", "esvdag"},
			{"SSVDAG", 0, "nodes_ssvdag", "ssvdag"},
			{"LSSVDAG", 1, "nodes_ssvdag", "ssvdag"},
		};
		fprintf(f, "| method | nodes | MNodes | MB | bits/voxel | vs "
			"lossless |\n|---|---:|---:|---:|---:|---:|\n");
		for (size_t k = 0; k < sizeof rows / sizeof *rows; k++) {
			const char *t = rows[k].lossy ? t1 : t0;
			char bk[64], vk[64];
			snprintf(bk, sizeof bk, "bytes_%s", rows[k].fmt);
			snprintf(vk, sizeof vk, "bits_per_voxel_%s", rows[k].fmt);
			double nodes = json_row_number(t, "table2", 0, rows[k].nodes);
			double bytes = json_row_number(t, "table2", 0, bk);
			fprintf(f, "| %s | %.0f | %.6f | %.6f | %g |", rows[k].name,
				nodes, nodes / 1e6, mb(bytes),
				json_row_number(t, "table2", 0, vk));
			if (rows[k].lossy) {
				double b0 = json_row_number(t0, "table2", 0, bk);
				fprintf(f, " %+.1f%% MB |\n", b0 > 0 ?
					100.0 * (bytes - b0) / b0 : 0);
			} else {
				fprintf(f, " |\n");
			}
		}
		fprintf(f, "\n");
	}
	fprintf(f, "Error rate %g (%.0f voxels changed of %.0f: %.0f set, %.0f "
		"cleared; %.0f voxels after).\n\n",
		json_number(st, NULL, "error_rate"),
		json_number(st, NULL, "voxels_changed"), vbefore,
		json_number(st, NULL, "voxels_set"),
		json_number(st, NULL, "voxels_cleared"),
		json_number(st, NULL, "voxels_after"));
	free(st);
	free(t0);
	free(t1);
}

/* What edit job d did, from its statistics. */
static void write_edit(FILE *f, const struct plan *p, int d)
{
	const struct config *c = p->cfg;
	char path[1200];
	snprintf(path, sizeof path, "%s/%s/root.dag.stats.json", p->dir,
		 c->jobs_decl[d].name);
	char *st = slurp(path);
	size_t nops;
	double changed = json_sum(st, "operations", "voxels_changed", &nops);
	fprintf(f, "# Edits: job `%s`\n\n", c->jobs_decl[d].name);
	if (!st)
		fprintf(f, "(not built)\n\n");
	else
		fprintf(f, "%zu operations on `%s`'s scene (script `%s`), %.0f "
			"voxel changes in all; %.0f voxels after.\n\n", nops,
			c->jobs_decl[c->jobs_decl[d].needs[0]].name,
			c->jobs_decl[d].script_text ? "inline" :
			c->jobs_decl[d].script, changed,
			json_number(st, NULL, "voxels"));
	free(st);
}

/* Fills rows[d] for each declared job d from the statistics file of each
 * of its jobs (read once): processes, seconds (the stage's own, its
 * phases, else the job's), the largest budget and peak memory. */
static void read_rows(const struct plan *p, struct stage_row *rows)
{
	const struct config *c = p->cfg;
	for (int i = 0; i < p->n; i++) {
		const struct job *j = &p->jobs[i];
		char sp[1300];
		stats_path(p, j, sp, sizeof sp);
		char *text = slurp(sp);
		/* parsed once: a report reads one file per job */
		json_error_t jerr;
		json_t *root = text ? json_loads(text, 0, &jerr) : NULL;
		struct stage_row *r = &rows[j->decl];
		r->jobs++;
		if (job_budget(j) > r->budget)
			r->budget = job_budget(j);
		double secs = json_get(root, "seconds", "total");
		if (secs == 0) /* encode and colorize: a flat total */
			secs = json_get(root, NULL, "seconds_total");
		enum stage_type t = c->jobs_decl[j->decl].stage->type;
		size_t nops;
		if (t == STAGE_LOSSY) /* its phases, the check of its count too */
			secs = json_get(root, NULL, "seconds_load") +
			       json_get(root, NULL, "seconds_lossy") +
			       json_get(root, NULL, "seconds_diff") +
			       json_get(root, NULL, "seconds_save");
		else if (t == STAGE_EDIT) /* load, every operation, save */
			secs = json_get(root, NULL, "seconds_load") +
			       json_sum_in(root, "operations", "seconds", &nops) +
			       json_get(root, NULL, "seconds_save");
		if (secs == 0) /* the DAG stages report their phases */
			secs = json_get(root, NULL, "seconds_load") +
			       json_get(root, NULL, "seconds_build") +
			       json_get(root, NULL, "seconds_save");
		if (secs == 0) /* (statistics without a time: the job's) */
			secs = j->seconds;
		r->seconds += secs;
		r->wall_this_run += j->seconds;
		/* the stage's own count, which outlives the run that made it;
		 * else what the runner measured of a job it ran this time */
		json_t *cpu = json_is_object(root) ?
			json_object_get(root, "process_cpu_seconds") : NULL;
		if (json_is_number(cpu))
			r->cpu += json_number_value(cpu);
		else if (j->state == JOB_DONE && j->cpu >= 0 && j->seconds > 0)
			r->cpu += j->cpu;
		else
			r->cpu_unknown++;
		uint64_t rss = (uint64_t)json_get(root, NULL, "peak_rss_bytes");
		json_decref(root);
		if (j->peak_rss > rss)
			rss = j->peak_rss;
		if (rss > r->peak_rss)
			r->peak_rss = rss;
		free(text);
	}
}

/* Writes the body of report.md to f: the summary line (from the
 * voxelization statistics `vstats`, may be NULL), the pictures, the size
 * tables of the first encode job `enc` (`tables`, may be NULL; `nenc`
 * encode jobs in all) and of the others, the lossy and edit sections, the
 * colours and the table of the run. */
static void write_report_md(FILE *f, const struct plan *p,
			    const struct stage_row *rows, const char *vstats,
			    const char *tables, const struct job *enc, int nenc)
{
	const struct config *c = p->cfg;
	fprintf(f, "# voxdag report: %s\n\n", c->name);
	if (*c->title)
		fprintf(f, "%s\n\n", c->title);
	fprintf(f, "Pipeline `%s`, input `%s`, grid 2^%d (%d^3), chunk level %d, "
		"%.0f triangles, %.0f voxels in %.0f chunks.\n\n", c->path,
		*c->mesh ? c->mesh : c->vdb,
		c->levels, 1 << c->levels, (int)json_number(vstats, NULL, "chunk_level"),
		json_number(vstats, NULL, "triangles_read"),
		json_number(vstats, NULL, "voxels"), json_number(vstats, NULL, "chunks"));
	write_pictures(f, p);
	if (tables)
		fprintf(f, "To fly through the scene in a browser: `voxdag view "
			"%s` (serves this directory and the viewer on 127.0.0.1 "
			"and prints the URL to open).\n\n", c->path);
	if (tables && nenc > 1)
		fprintf(f, "# Scene of job `%s`\n\n",
			c->jobs_decl[enc->decl].name);
	if (tables) /* encode's own title line is ours already */
		fprintf(f, "%s\n", strncmp(tables, "# ", 2) == 0 && strchr(tables, '\n')
				       ? strchr(tables, '\n') + 1 : tables);
	else
		fprintf(f, "(no encode job in this pipeline: no size tables)\n\n");
	/* the other encode jobs' tables (a lossy or edited scene) */
	for (int d = 0; d < c->njobs; d++) {
		const struct job *e = encode_job(p, d);
		if (!e || e == enc)
			continue;
		/* not report_write's `path`: the report's until it is renamed */
		char other[1200];
		snprintf(other, sizeof other, "%s/%s.tables.md", e->output, c->name);
		char *t = slurp(other);
		fprintf(f, "# Scene of job `%s`\n\n%s\n", c->jobs_decl[e->decl].name,
			!t ? "(not built)\n" : strncmp(t, "# ", 2) == 0 &&
			strchr(t, '\n') ? strchr(t, '\n') + 1 : t);
		free(t);
	}
	for (int d = 0; d < c->njobs; d++) {
		if (c->jobs_decl[d].stage->type == STAGE_LOSSY)
			write_lossy(f, p, d, rows[c->jobs_decl[d].needs[0]].seconds);
		if (c->jobs_decl[d].stage->type == STAGE_EDIT)
			write_edit(f, p, d);
	}
	write_colours(f, p);
	fprintf(f, "## The run\n\n");
	fprintf(f, "Seconds are the stages' own (sum over a stage's jobs, from "
		"their statistics files); CPU seconds are the jobs' processes' "
		"user and system time, all threads (from the same files, else "
		"as the runner measured it; `-`: not known for some job); "
		"peak memory is the largest job's, "
		"against the largest `--mem-budget` given to the stage's jobs: "
		"the per-job budget of %llu MiB, or more for a job that could "
		"not fit it (started when the whole budget had room for it).\n\n",
		(unsigned long long)(c->job_mem_budget >> 20));
	fprintf(f, "| job | stage | processes | seconds | CPU seconds | peak MiB "
		   "| budget MiB |\n|---|---|---:|---:|---:|---:|---:|\n");
	for (int d = 0; d < c->njobs; d++) {
		char b[32] = "-", cpu[32] = "-";
		if (rows[d].budget)
			snprintf(b, sizeof b, "%llu",
				 (unsigned long long)(rows[d].budget >> 20));
		if (!rows[d].cpu_unknown)
			snprintf(cpu, sizeof cpu, "%.2f", rows[d].cpu);
		fprintf(f, "| %s | %s | %d | %.2f | %s | %.0f | %s |\n",
			c->jobs_decl[d].name, c->jobs_decl[d].stage->name,
			rows[d].jobs, rows[d].seconds, cpu,
			(double)rows[d].peak_rss / (1 << 20), b);
	}
}

/* Writes the rows of report.csv to f, after its header line. */
static void write_report_csv(FILE *f, const struct plan *p,
			     const struct stage_row *rows)
{
	const struct config *c = p->cfg;
	fprintf(f, "job,stage,processes,seconds,cpu_seconds,peak_rss_bytes,"
		"budget_bytes\n");
	for (int d = 0; d < c->njobs; d++) {
		/* empty: the stage takes no budget; its CPU is not known */
		char b[32] = "", cpu[32] = "";
		if (rows[d].budget)
			snprintf(b, sizeof b, "%llu",
				 (unsigned long long)rows[d].budget);
		if (!rows[d].cpu_unknown)
			snprintf(cpu, sizeof cpu, "%.3f", rows[d].cpu);
		fprintf(f, "%s,%s,%d,%.3f,%s,%llu,%s\n", c->jobs_decl[d].name,
			c->jobs_decl[d].stage->name, rows[d].jobs,
			rows[d].seconds, cpu,
			(unsigned long long)rows[d].peak_rss, b);
	}
}

/* Writes report.json at `path` (a buffer of `cap` bytes, reused for the
 * paths it names): the pipeline, the stages' rows, where the size tables
 * of `enc` (may be NULL) and the lossy tables' numbers come from. Returns
 * 0, or 1 with the cause in `why` (`why_cap` bytes). */
static int write_report_json(const struct plan *p,
			     const struct stage_row *rows, const char *vstats,
			     const struct job *enc, char *path, size_t cap,
			     char *why, size_t why_cap)
{
	const struct config *c = p->cfg;
	int err = 0;
	struct vd_json *j;
	if (vd_json_open(&j, path) == VD_OK) {
		vd_json_str(j, "pipeline", c->path);
		vd_json_str(j, "name", c->name);
		vd_json_str(j, "input", *c->mesh ? c->mesh : c->vdb);
		vd_json_u64(j, "levels", (uint64_t)c->levels);
		vd_json_u64(j, "chunk_level", (uint64_t)json_number(vstats, NULL, "chunk_level"));
		vd_json_u64(j, "voxels", (uint64_t)json_number(vstats, NULL, "voxels"));
		vd_json_array(j, "stages");
		for (int d = 0; d < c->njobs; d++) {
			vd_json_object(j, NULL);
			vd_json_str(j, "job", c->jobs_decl[d].name);
			vd_json_str(j, "stage", c->jobs_decl[d].stage->name);
			vd_json_u64(j, "processes", (uint64_t)rows[d].jobs);
			vd_json_f64(j, "seconds", rows[d].seconds);
			if (!rows[d].cpu_unknown) /* absent: not known */
				vd_json_f64(j, "cpu_seconds", rows[d].cpu);
			vd_json_u64(j, "peak_rss_bytes", rows[d].peak_rss);
			if (rows[d].budget) /* absent: the stage takes none */
				vd_json_u64(j, "budget_bytes", rows[d].budget);
			vd_json_end_object(j);
		}
		vd_json_end_array(j);
		if (enc) {
			snprintf(path, cap, "%s/%s.tables.json", enc->output,
				 c->name);
			vd_json_str(j, "tables", path);
		}
		/* where the lossy tables' numbers come from */
		vd_json_array(j, "lossy");
		for (int d = 0; d < c->njobs; d++) {
			const struct job_decl *ld = &c->jobs_decl[d];
			if (ld->stage->type != STAGE_LOSSY)
				continue;
			vd_json_object(j, NULL);
			vd_json_str(j, "job", ld->name);
			snprintf(path, cap, "%s/%s/root.dag.stats.json",
				 p->dir, ld->name);
			vd_json_str(j, "stats", path);
			const struct job *e0 = encode_of(p, ld->needs[0]),
					 *e1 = encode_of(p, d);
			if (e0) {
				snprintf(path, cap, "%s/%s.tables.json",
					 e0->output, c->name);
				vd_json_str(j, "tables_lossless", path);
			}
			if (e1) {
				snprintf(path, cap, "%s/%s.tables.json",
					 e1->output, c->name);
				vd_json_str(j, "tables_lossy", path);
			}
			vd_json_end_object(j);
		}
		vd_json_end_array(j);
		if (vd_json_close(j) != VD_OK) {
			err = 1;
			snprintf(why, why_cap, "%s", vd_error_detail());
		}
	} else {
		err = 1;
		snprintf(why, why_cap, "%s", vd_error_detail());
	}
	return err;
}

int report_write(const struct plan *p)
{
	const struct config *c = p->cfg;
	struct stage_row rows[MAX_JOBS_DECL] = {{0}};
	read_rows(p, rows);
	char path[1200];
	/* the voxelization summary */
	const struct job *vox = NULL, *enc = NULL;
	int nenc = 0;
	for (int i = 0; i < p->n; i++) {
		enum stage_type t = c->jobs_decl[p->jobs[i].decl].stage->type;
		if (t == STAGE_VOXELIZE)
			vox = &p->jobs[i];
		if (t != STAGE_ENCODE)
			continue;
		/* the first encode job declared comes first */
		if (!enc || p->jobs[i].decl < enc->decl)
			enc = &p->jobs[i];
		nenc++;
	}
	char *vstats = NULL;
	if (vox) {
		snprintf(path, sizeof path, "%s/voxelize.stats.json", vox->output);
		vstats = slurp(path);
	}
	char *tables = NULL;
	if (enc) {
		snprintf(path, sizeof path, "%s/%s.tables.md", enc->output, c->name);
		tables = slurp(path);
	}

	struct vd_atomic tmp;
	char why[1600] = "";
	snprintf(path, sizeof path, "%s/report.md", p->dir);
	FILE *f = open_tmp(path, &tmp);
	if (!f) {
		close_tmp(f, &tmp, path, why, sizeof why);
		fprintf(stderr, "voxdag: %s\n", why);
		free(vstats);
		free(tables);
		return 1;
	}
	write_report_md(f, p, rows, vstats, tables, enc, nenc);
	int err = close_tmp(f, &tmp, path, why, sizeof why);

	snprintf(path, sizeof path, "%s/report.csv", p->dir);
	f = err ? NULL : open_tmp(path, &tmp);
	if (f)
		write_report_csv(f, p, rows);
	if (!err)
		err = close_tmp(f, &tmp, path, why, sizeof why);

	snprintf(path, sizeof path, "%s/report.json", p->dir);
	if (!err) /* else said already */
		err = write_report_json(p, rows, vstats, enc, path, sizeof path,
					why, sizeof why);
	free(vstats);
	free(tables);
	if (err)
		fprintf(stderr, "voxdag: cannot write the report: %s\n", why);
	return err;
}

/* Sets started[i] for the jobs whose last word in runner.log is
 * "started" or "failed": running now, or interrupted or failed. Jobs keep their logs
 * only when they fail or say something (run.c), so the runner's log is
 * where a start is written down. */
static void mark_started(const struct plan *p, char *started)
{
	char path[1300], line[1600], id[1024];
	snprintf(path, sizeof path, "%s/logs/runner.log", p->dir);
	FILE *f = fopen(path, "r");
	if (!f)
		return;
	while (fgets(line, sizeof line, f)) {
		char what[16];
		/* "DATE TIME started ID (...)", "DATE TIME done ID in ..." */
		if (sscanf(line, "%*s %*s %15s %1023s", what, id) != 2)
			continue;
		if (strcmp(what, "started") && strcmp(what, "done") &&
		    strcmp(what, "failed"))
			continue;
		int i = plan_find(p, id);
		if (i >= 0)
			started[i] = strcmp(what, "done") != 0;
	}
	fclose(f);
}

int status_print(struct plan *p)
{
	plan_expand(p);
	int counts[JOB_BLOCKED + 1] = {0};
	int in_slurm = 0;
	char *started = calloc((size_t)p->n + 1, 1);
	if (!started) {
		fprintf(stderr, "voxdag: out of memory\n");
		return 1;
	}
	mark_started(p, started);
	for (int i = 0; i < p->n; i++) {
		struct job *j = &p->jobs[i];
		char st[256];
		if (j->state == JOB_PENDING && slurm_state(p, j, st, sizeof st)) {
			j->state = JOB_RUNNING; /* submitted by a driver */
			in_slurm++;
			continue;
		}
		if (j->state == JOB_PENDING && started[i])
			j->state = JOB_FAILED; /* started (runner.log), no key */
		counts[j->state]++;
	}
	printf("%s: %d jobs planned%s\n", p->cfg->name, p->n,
	       p->expanded ? "" : " so far (more once the cells are known)");
	printf("  done     %d\n  started  %d (running now, or interrupted or "
	       "failed: see %s/logs/runner.log)\n  pending  %d\n", counts[JOB_SKIPPED],
	       counts[JOB_FAILED], p->dir, counts[JOB_PENDING]);
	long holder = lock_holder(p->dir);
	if (holder > 0)
		printf("  a runner (pid %ld) is working on it now\n", holder);
	if (in_slurm)
		printf("  in Slurm %d (submitted by a driver):\n", in_slurm);
	for (int i = 0; i < p->n && in_slurm; i++) {
		char st[256];
		if (p->jobs[i].state == JOB_RUNNING &&
		    slurm_state(p, &p->jobs[i], st, sizeof st))
			printf("    %s: %s\n", p->jobs[i].id, st);
	}
	for (int i = 0; i < p->n; i++)
		if (p->jobs[i].state == JOB_FAILED)
			printf("  started, not finished: %s\n", p->jobs[i].id);
	free(started);
	return 0;
}
