/* report.c - out/<name>/report.md, .json and .csv: the paper-style tables
 * that encode computed, and the run's own figures per stage (seconds, peak
 * memory against the budget), gathered from every job's statistics file so
 * a resumed run reports the same work as an uninterrupted one. */
#include "pipeline.h"

#include <jansson.h>
#include <stdlib.h>
#include <string.h>

/* Reads a whole small text file (NULL if absent). */
static char *slurp(const char *path)
{
	FILE *f = fopen(path, "rb");
	if (!f)
		return NULL;
	fseek(f, 0, SEEK_END);
	long n = ftell(f);
	fseek(f, 0, SEEK_SET);
	char *s = malloc((size_t)n + 1);
	if (s && fread(s, 1, (size_t)n, f) != (size_t)n) {
		free(s);
		s = NULL;
	}
	if (s)
		s[n] = 0;
	fclose(f);
	return s;
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
	json_t *obj = within ? json_object_get(root, within) : root;
	json_t *v = json_is_object(obj) ? json_object_get(obj, key) : NULL;
	double d = json_is_number(v) ? json_number_value(v) : 0;
	json_decref(root);
	return d;
}

/* The same in an object already parsed (NULL: 0). */
static double json_get(const json_t *root, const char *within, const char *key)
{
	const json_t *obj = within && root ? json_object_get(root, within) : root;
	json_t *v = json_is_object(obj) ? json_object_get(obj, key) : NULL;
	return json_is_number(v) ? json_number_value(v) : 0;
}

/* The statistics file a job's stage wrote beside its output. */
static void stats_path(const struct plan *p, const struct job *j, char *buf,
		       size_t cap)
{
	const struct job_decl *d = &p->cfg->jobs_decl[j->decl];
	if (d->stage->type == STAGE_VOXELIZE)
		snprintf(buf, cap, "%s/voxelize.stats.json", j->output);
	else if (d->stage->type == STAGE_RENDER)
		snprintf(buf, cap, "%s.none", j->output); /* render has no stats */
	else if (d->stage->type == STAGE_ENCODE)
		snprintf(buf, cap, "%s/%s.encode.stats.json", j->output,
			 p->cfg->name);
	else
		snprintf(buf, cap, "%s.stats.json", j->output);
}

struct stage_row {
	int jobs;
	double seconds;        /* sum of the stages' own seconds */
	double wall_this_run;  /* sum of the jobs run this time */
	uint64_t peak_rss;     /* largest job */
};

int report_write(const struct plan *p)
{
	const struct config *c = p->cfg;
	struct stage_row rows[MAX_JOBS_DECL] = {{0}};
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
		double secs = json_get(root, "seconds", "total");
		if (secs == 0) /* the DAG stages report their phases */
			secs = json_get(root, NULL, "seconds_load") +
			       json_get(root, NULL, "seconds_build") +
			       json_get(root, NULL, "seconds_save");
		if (secs == 0) /* render writes no statistics: its wall time */
			secs = j->seconds;
		r->seconds += secs;
		r->wall_this_run += j->seconds;
		uint64_t rss = (uint64_t)json_get(root, NULL, "peak_rss_bytes");
		json_decref(root);
		if (j->peak_rss > rss)
			rss = j->peak_rss;
		if (rss > r->peak_rss)
			r->peak_rss = rss;
		free(text);
	}
	char path[1200];
	/* the voxelization summary */
	const struct job *vox = NULL, *enc = NULL;
	for (int i = 0; i < p->n; i++) {
		enum stage_type t = c->jobs_decl[p->jobs[i].decl].stage->type;
		if (t == STAGE_VOXELIZE)
			vox = &p->jobs[i];
		if (t == STAGE_ENCODE)
			enc = &p->jobs[i];
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

	snprintf(path, sizeof path, "%s/report.md", p->dir);
	FILE *f = fopen(path, "w");
	if (!f) {
		fprintf(stderr, "voxdag: cannot write '%s'\n", path);
		free(vstats);
		free(tables);
		return 1;
	}
	fprintf(f, "# voxdag report: %s\n\n", c->name);
	if (*c->title)
		fprintf(f, "%s\n\n", c->title);
	fprintf(f, "Pipeline `%s`, input `%s`, grid 2^%d (%d^3), chunk level %d, "
		"%.0f triangles, %.0f voxels in %.0f chunks.\n\n", c->path,
		*c->mesh ? c->mesh : c->vdb,
		c->levels, 1 << c->levels, (int)json_number(vstats, NULL, "chunk_level"),
		json_number(vstats, NULL, "triangles_read"),
		json_number(vstats, NULL, "voxels"), json_number(vstats, NULL, "chunks"));
	for (int i = 0; i < p->n; i++) {
		const struct job *r = &p->jobs[i];
		if (c->jobs_decl[r->decl].stage->type == STAGE_RENDER)
			/* relative to the report, which sits in p->dir */
			fprintf(f, "![%s](%s)\n\n", c->jobs_decl[r->decl].name,
				r->output + strlen(p->dir) + 1);
	}
	if (tables) /* encode's own title line is ours already */
		fprintf(f, "%s\n", strncmp(tables, "# ", 2) == 0 && strchr(tables, '\n')
				       ? strchr(tables, '\n') + 1 : tables);
	else
		fprintf(f, "(no encode job in this pipeline: no size tables)\n\n");
	fprintf(f, "## The run\n\n");
	fprintf(f, "Seconds are the stages' own (sum over a stage's jobs, from "
		"their statistics files); peak memory is the largest job's, "
		"against the per-job budget of %llu MiB.\n\n",
		(unsigned long long)(c->job_mem_budget >> 20));
	fprintf(f, "| job | stage | processes | seconds | peak MiB | budget MiB |\n"
		   "|---|---|---:|---:|---:|---:|\n");
	for (int d = 0; d < c->njobs; d++)
		fprintf(f, "| %s | %s | %d | %.2f | %.0f | %llu |\n",
			c->jobs_decl[d].name, c->jobs_decl[d].stage->name,
			rows[d].jobs, rows[d].seconds,
			(double)rows[d].peak_rss / (1 << 20),
			(unsigned long long)(c->job_mem_budget >> 20));
	int err = fclose(f) != 0;

	snprintf(path, sizeof path, "%s/report.csv", p->dir);
	f = fopen(path, "w");
	if (f) {
		fprintf(f, "job,stage,processes,seconds,peak_rss_bytes,budget_bytes\n");
		for (int d = 0; d < c->njobs; d++)
			fprintf(f, "%s,%s,%d,%.3f,%llu,%llu\n", c->jobs_decl[d].name,
				c->jobs_decl[d].stage->name, rows[d].jobs,
				rows[d].seconds,
				(unsigned long long)rows[d].peak_rss,
				(unsigned long long)c->job_mem_budget);
		err |= fclose(f) != 0;
	} else {
		err = 1;
	}

	snprintf(path, sizeof path, "%s/report.json", p->dir);
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
			vd_json_u64(j, "peak_rss_bytes", rows[d].peak_rss);
			vd_json_u64(j, "budget_bytes", c->job_mem_budget);
			vd_json_end_object(j);
		}
		vd_json_end_array(j);
		if (enc) {
			snprintf(path, sizeof path, "%s/%s.tables.json", enc->output,
				 c->name);
			vd_json_str(j, "tables", path);
		}
		err |= vd_json_close(j) != VD_OK;
	} else {
		err = 1;
	}
	free(vstats);
	free(tables);
	if (err)
		fprintf(stderr, "voxdag: cannot write the report in '%s'\n", p->dir);
	return err;
}

int status_print(struct plan *p)
{
	plan_expand(p);
	int counts[JOB_BLOCKED + 1] = {0};
	char lock[1200];
	snprintf(lock, sizeof lock, "%s/.lock", p->dir);
	int in_slurm = 0;
	for (int i = 0; i < p->n; i++) {
		struct job *j = &p->jobs[i];
		char st[256];
		if (j->state == JOB_PENDING && slurm_state(p, j, st, sizeof st)) {
			j->state = JOB_RUNNING; /* submitted by a driver */
			in_slurm++;
			continue;
		}
		if (j->state == JOB_PENDING) {
			/* a log without a key: it ran and did not finish */
			char lp[1300], id[200];
			snprintf(id, sizeof id, "%s", j->id);
			for (char *q = id; *q; q++)
				if (*q == '/')
					*q = '.';
			snprintf(lp, sizeof lp, "%s/logs/%s.log", p->dir, id);
			FILE *f = fopen(lp, "r");
			if (f) {
				j->state = JOB_FAILED;
				fclose(f);
			}
		}
		counts[j->state]++;
	}
	printf("%s: %d jobs planned%s\n", p->cfg->name, p->n,
	       p->expanded ? "" : " so far (more once the cells are known)");
	printf("  done     %d\n  started  %d (running now, or interrupted or "
	       "failed: see %s/logs/)\n  pending  %d\n", counts[JOB_SKIPPED],
	       counts[JOB_FAILED], p->dir, counts[JOB_PENDING]);
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
	return 0;
}
