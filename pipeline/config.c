/* config.c - reading and validating a pipeline YAML (schemas/pipeline.md).
 * libyaml's document API keeps every node's position, so each complaint
 * names FILE:LINE:COLUMN. Nothing runs before the whole file is accepted. */
#include "pipeline.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <yaml.h>

static const struct stage_info stages[] = {
	{"voxelize", STAGE_VOXELIZE, 0, 0},
	{"svo-to-dag", STAGE_SVO_TO_DAG, 1, 1},
	{"symmetry-merge", STAGE_SYMMETRY_MERGE, 1, 1},
	{"encode", STAGE_ENCODE, 2, 3},
	{"render", STAGE_RENDER, 1, 2},
	{"lossy-cluster", STAGE_LOSSY, 1, 1},
	{"edit", STAGE_EDIT, 1, 2},
	{"colorize", STAGE_COLORIZE, 1, 1},
};

int stage_makes_root_dag(enum stage_type t)
{
	return t == STAGE_SVO_TO_DAG || t == STAGE_LOSSY || t == STAGE_EDIT;
}

const struct stage_info *stage_lookup(const char *name)
{
	for (size_t i = 0; i < sizeof stages / sizeof *stages; i++)
		if (strcmp(stages[i].name, name) == 0)
			return &stages[i];
	return NULL;
}

/* The stages' names, ", "-separated, for the error that names them. */
static void stage_names(char *buf, size_t cap)
{
	size_t n = 0;
	for (size_t i = 0; i < sizeof stages / sizeof *stages && n < cap; i++)
		n += (size_t)snprintf(buf + n, cap - n, "%s%s", i ? ", " : "",
				      stages[i].name);
}

struct ctx {
	yaml_document_t doc;
	const char *path;
	struct config *c;
};

static int fail_at(struct ctx *x, const yaml_node_t *n, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));

static int fail_at(struct ctx *x, const yaml_node_t *n, const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	fprintf(stderr, "voxdag: %s:%lu:%lu: ", x->path,
		n ? (unsigned long)n->start_mark.line + 1 : 1ul,
		n ? (unsigned long)n->start_mark.column + 1 : 1ul);
	vfprintf(stderr, fmt, ap);
	fputc('\n', stderr);
	va_end(ap);
	return 1;
}

static const char *scalar(const yaml_node_t *n)
{
	return n && n->type == YAML_SCALAR_NODE ? (const char *)n->data.scalar.value
						: NULL;
}

static const char *type_name(const yaml_node_t *n)
{
	return n->type == YAML_MAPPING_NODE ? "a mapping"
	       : n->type == YAML_SEQUENCE_NODE ? "a list" : "a scalar";
}

static int want_string(struct ctx *x, const yaml_node_t *n, const char *key,
		       char *out, size_t cap)
{
	const char *s = scalar(n);
	if (!s)
		return fail_at(x, n, "'%s' must be a string, not %s", key,
			       type_name(n));
	if (strlen(s) >= cap)
		return fail_at(x, n, "'%s' is longer than %zu characters", key,
			       cap - 1);
	strcpy(out, s);
	return 0;
}

static int want_int(struct ctx *x, const yaml_node_t *n, const char *key,
		    long lo, long hi, int *out)
{
	const char *s = scalar(n);
	char *end;
	long v = s ? strtol(s, &end, 10) : 0;
	if (!s || !*s || *end)
		return fail_at(x, n, "'%s' must be a whole number", key);
	if (v < lo || v > hi)
		return fail_at(x, n, "'%s' is %ld, outside %ld..%ld", key, v, lo,
			       hi);
	*out = (int)v;
	return 0;
}

/* A number lo..hi (lo excluded when lo_open), kept as the YAML's text. */
static int want_number(struct ctx *x, const yaml_node_t *n, const char *key,
		       double lo, double hi, int lo_open, char *out, size_t cap)
{
	const char *s = scalar(n);
	char *end;
	double v = s ? strtod(s, &end) : 0;
	if (!s || !*s || *end || !isfinite(v))
		return fail_at(x, n, "'%s' must be a number", key);
	if (v < lo || v > hi || (lo_open && v == lo))
		return fail_at(x, n, "'%s' is %s, outside %s%g..%g", key, s,
			       lo_open ? "(" : "", lo, hi);
	if (strlen(s) >= cap)
		return fail_at(x, n, "'%s' is longer than %zu characters", key,
			       cap - 1);
	strcpy(out, s);
	return 0;
}

static int want_size(struct ctx *x, const yaml_node_t *n, const char *key,
		     uint64_t *out)
{
	const char *s = scalar(n);
	if (!s || vd_parse_size(s, out) || *out == 0)
		return fail_at(x, n, "'%s' must be a size such as 512M or 4GiB",
			       key);
	return 0;
}

static int want_mapping(struct ctx *x, const yaml_node_t *n, const char *key)
{
	if (n->type != YAML_MAPPING_NODE)
		return fail_at(x, n, "'%s' must be a mapping, not %s", key,
			       type_name(n));
	return 0;
}

/* Iterates over a mapping's pairs with the pair pointer `it`. */
#define FOR_PAIRS(x, map, k, v, it)                                          \
	for (yaml_node_pair_t *it = (map)->data.mapping.pairs.start;         \
	     it < (map)->data.mapping.pairs.top &&                           \
	     ((k) = yaml_document_get_node(&(x)->doc, it->key),              \
	      (v) = yaml_document_get_node(&(x)->doc, it->value), 1);        \
	     it++)

static int valid_name(const char *s)
{
	if (!*s)
		return 0;
	for (; *s; s++)
		if (!isalnum((unsigned char)*s) && *s != '-' && *s != '_')
			return 0;
	return 1;
}

static int parse_input(struct ctx *x, yaml_node_t *map)
{
	struct config *c = x->c;
	if (want_mapping(x, map, "input"))
		return 1;
	/* every input key is a string */
	const struct {
		const char *key;
		char *buf;
		size_t cap;
	} fields[] = {
		{"mesh", c->mesh, sizeof c->mesh},
		{"vdb", c->vdb, sizeof c->vdb},
		{"grid", c->vdb_grid, sizeof c->vdb_grid},
		{"mode", c->vdb_mode, sizeof c->vdb_mode},
		{"colour_grid", c->vdb_colour_grid, sizeof c->vdb_colour_grid},
		{"fetch", c->fetch, sizeof c->fetch},
	};
	yaml_node_t *k, *v;
	FOR_PAIRS(x, map, k, v, it) {
		const char *key = scalar(k);
		if (!key)
			return fail_at(x, k, "keys must be strings");
		size_t f = 0;
		while (f < sizeof fields / sizeof *fields && strcmp(key, fields[f].key))
			f++;
		if (f == sizeof fields / sizeof *fields)
			return fail_at(x, k, "unknown key 'input.%s' (known: mesh, "
				       "vdb, grid, mode, colour_grid, fetch)", key);
		if (want_string(x, v, key, fields[f].buf, fields[f].cap))
			return 1;
	}
	if (!*c->mesh == !*c->vdb)
		return fail_at(x, map, "'input' needs exactly one of 'mesh' or "
			       "'vdb'");
	int mode;
	if (*c->vdb_mode && vd_vdb_mode_parse(c->vdb_mode, &mode) != VD_OK)
		return fail_at(x, map, "'input.mode' is '%s' (known: active, "
			       "levelset-surface, levelset-solid, fog)",
			       c->vdb_mode);
	if ((*c->vdb_grid || *c->vdb_mode || *c->vdb_colour_grid) && !*c->vdb)
		return fail_at(x, map, "'grid', 'mode' and 'colour_grid' go with "
			       "'vdb'");
	return 0;
}

static int want_executor(struct ctx *x, const yaml_node_t *n,
			 enum executor *out)
{
	const char *s = scalar(n);
	if (s && !strcmp(s, "local"))
		*out = EXECUTOR_LOCAL;
	else if (s && !strcmp(s, "slurm"))
		*out = EXECUTOR_SLURM;
	else
		return fail_at(x, n, "'executor' is 'local' or 'slurm'");
	return 0;
}

/* A Slurm time limit as sbatch takes it: minutes, M:S, H:M:S, D-H,
 * D-H:M, D-H:M:S, or "infinite"/"unlimited". */
static int valid_time_limit(const char *s)
{
	if (!strcmp(s, "infinite") || !strcmp(s, "unlimited"))
		return 1;
	int fields = 0, digits = 0, dash = 0;
	for (; *s; s++) {
		if (*s >= '0' && *s <= '9') {
			digits++;
			continue;
		}
		if (!digits || (*s != ':' && *s != '-') || (*s == '-' && (dash || fields)))
			return 0;
		dash += *s == '-';
		fields++;
		digits = 0;
	}
	return digits > 0 && fields <= 3;
}

static int want_time_limit(struct ctx *x, const yaml_node_t *n,
			   const char *key, char *out, size_t cap)
{
	if (want_string(x, n, key, out, cap))
		return 1;
	if (!valid_time_limit(out))
		return fail_at(x, n, "'%s' is '%s', not a Slurm time limit "
			       "(minutes, H:M:S or D-H:M:S)", key, out);
	return 0;
}

/* slurm: {partition, account, time_limit, time: {stage: limit},
 * sbatch_args: [...], shared_outputs: bool, bundle_seconds: N,
 * max_queued: N}; used with
 * resources.executor: slurm. */
static int parse_slurm(struct ctx *x, yaml_node_t *map)
{
	struct slurm_opts *o = &x->c->slurm;
	if (want_mapping(x, map, "slurm"))
		return 1;
	yaml_node_t *k, *v;
	FOR_PAIRS(x, map, k, v, it) {
		const char *key = scalar(k);
		int err = 0;
		if (!key)
			return fail_at(x, k, "keys must be strings");
		if (!strcmp(key, "partition"))
			err = want_string(x, v, key, o->partition,
					  sizeof o->partition);
		else if (!strcmp(key, "account"))
			err = want_string(x, v, key, o->account,
					  sizeof o->account);
		else if (!strcmp(key, "time_limit"))
			err = want_time_limit(x, v, key, o->time_limit,
					      sizeof o->time_limit);
		else if (!strcmp(key, "time")) {
			if (want_mapping(x, v, "slurm.time"))
				return 1;
			yaml_node_t *sk, *sv;
			FOR_PAIRS(x, v, sk, sv, st) {
				const char *name = scalar(sk);
				const struct stage_info *si =
					name ? stage_lookup(name) : NULL;
				if (!si)
					return fail_at(x, sk, "'slurm.time' maps "
						       "stages to time limits; "
						       "'%s' is no stage",
						       name ? name : "?");
				if (want_time_limit(x, sv, name,
						    o->stage_time[si->type],
						    sizeof o->stage_time[0]))
					return 1;
			}
		} else if (!strcmp(key, "sbatch_args")) {
			if (v->type != YAML_SEQUENCE_NODE)
				return fail_at(x, v, "'sbatch_args' must be a "
					       "list of arguments");
			for (yaml_node_item_t *ni = v->data.sequence.items.start;
			     ni < v->data.sequence.items.top; ni++) {
				yaml_node_t *e = yaml_document_get_node(&x->doc, *ni);
				if (o->nargs == 8)
					return fail_at(x, e, "more than 8 "
						       "sbatch_args");
				if (want_string(x, e, "sbatch_args",
						o->args[o->nargs],
						sizeof o->args[0]))
					return 1;
				if (o->args[o->nargs][0] != '-')
					return fail_at(x, e, "sbatch_args are "
						       "options (starting "
						       "with '-')");
				o->nargs++;
			}
		} else if (!strcmp(key, "shared_outputs")) {
			const char *b = scalar(v);
			if (!b || (strcmp(b, "true") && strcmp(b, "false")))
				return fail_at(x, v, "'shared_outputs' is true "
					       "or false");
			o->shared_outputs = !strcmp(b, "true");
		} else if (!strcmp(key, "bundle_seconds")) {
			err = want_int(x, v, key, 1, 86400, &o->bundle_seconds);
		} else if (!strcmp(key, "max_queued")) {
			err = want_int(x, v, key, 1, 10000000, &o->max_queued);
		} else {
			return fail_at(x, k, "unknown key 'slurm.%s' (known: "
				       "partition, account, time_limit, time, "
				       "sbatch_args, shared_outputs, "
				       "bundle_seconds, max_queued)", key);
		}
		if (err)
			return 1;
	}
	return 0;
}

static int parse_resources(struct ctx *x, yaml_node_t *map)
{
	struct config *c = x->c;
	if (want_mapping(x, map, "resources"))
		return 1;
	yaml_node_t *k, *v;
	FOR_PAIRS(x, map, k, v, it) {
		const char *key = scalar(k);
		if (!key)
			return fail_at(x, k, "keys must be strings");
		int err;
		if (!strcmp(key, "jobs"))
			err = want_int(x, v, key, 1, 256, &c->jobs);
		else if (!strcmp(key, "threads"))
			err = want_int(x, v, key, 1, 1024, &c->threads);
		else if (!strcmp(key, "mem_budget"))
			err = want_size(x, v, key, &c->mem_budget);
		else if (!strcmp(key, "job_mem_budget"))
			err = want_size(x, v, key, &c->job_mem_budget);
		else if (!strcmp(key, "executor"))
			err = want_executor(x, v, &c->executor);
		else
			return fail_at(x, k, "unknown key 'resources.%s' (known: "
				       "jobs, threads, mem_budget, "
				       "job_mem_budget, executor)", key);
		if (err)
			return 1;
	}
	return 0;
}

/* An edit job's `script:`: a file name (relative to the YAML's directory)
 * or a list of lines, each one edit (schemas/edit-script.md). */
static int parse_script(struct ctx *x, struct job_decl *d, yaml_node_t *v)
{
	if (v->type == YAML_SCALAR_NODE) {
		const char *s = scalar(v);
		if (!*s)
			return fail_at(x, v, "'script' is empty");
		const char *slash = strrchr(x->path, '/');
		int dirlen = s[0] == '/' || !slash ? 0 : (int)(slash - x->path) + 1;
		if ((size_t)snprintf(d->script, sizeof d->script, "%.*s%s",
				     dirlen, x->path, s) >= sizeof d->script)
			return fail_at(x, v, "'script' path is too long");
		struct stat st;
		if (stat(d->script, &st) != 0)
			return fail_at(x, v, "edit script '%s': %s", d->script,
				       strerror(errno));
		if (!S_ISREG(st.st_mode))
			return fail_at(x, v, "edit script '%s' is not a file",
				       d->script);
		return 0;
	}
	if (v->type != YAML_SEQUENCE_NODE)
		return fail_at(x, v, "'script' is a file name or a list of edit "
			       "lines");
	size_t len = 0;
	for (yaml_node_item_t *ni = v->data.sequence.items.start;
	     ni < v->data.sequence.items.top; ni++) {
		yaml_node_t *e = yaml_document_get_node(&x->doc, *ni);
		const char *s = scalar(e);
		if (!s)
			return fail_at(x, e, "'script' lines are strings (one "
				       "edit each)");
		if (strchr(s, '\n') || strchr(s, '\r'))
			return fail_at(x, e, "a 'script' line holds one edit, "
				       "without line breaks");
		char *t = realloc(d->script_text, len + strlen(s) + 2);
		if (!t)
			return fail_at(x, e, "out of memory");
		d->script_text = t;
		len += (size_t)sprintf(t + len, "%s\n", s);
	}
	if (!len)
		return fail_at(x, v, "'script' has no lines");
	return 0;
}

/* The keys of a job that are parameters of one stage only, as found
 * (NULL: absent); checked against the stage once it is known (it may
 * come after them). */
struct job_params {
	yaml_node_t *lossy, *edit, *colour, *group;
	yaml_node_t *max_error; /* its value: vbr's floor depends on method */
};

/* Starts the declaration of job `name` in c->jobs_decl[c->njobs] (not
 * counted yet): checks the name, that there is room, and that it is not
 * declared twice. Returns it, or NULL after fail_at(). */
static struct job_decl *job_begin(struct ctx *x, yaml_node_t *name)
{
	struct config *c = x->c;
	const char *n = scalar(name);
	if (!n || !valid_name(n) || strlen(n) >= MAX_NAME) {
		fail_at(x, name, "job names are letters, digits, '-' "
			"and '_' (at most %d)", MAX_NAME - 1);
		return NULL;
	}
	if (c->njobs == MAX_JOBS_DECL) {
		fail_at(x, name, "more than %d jobs", MAX_JOBS_DECL);
		return NULL;
	}
	for (int i = 0; i < c->njobs; i++)
		if (!strcmp(c->jobs_decl[i].name, n)) {
			fail_at(x, name, "job '%s' is declared twice", n);
			return NULL;
		}
	struct job_decl *d = &c->jobs_decl[c->njobs];
	memset(d, 0, sizeof *d);
	strcpy(d->name, n);
	d->line = (int)name->start_mark.line + 1;
	d->column = (int)name->start_mark.column + 1;
	return d;
}

/* Reads the list of a job's 'needs' (`v`) into d->needs_name. Returns 0,
 * or 1 after fail_at(). */
static int parse_needs(struct ctx *x, struct job_decl *d, yaml_node_t *v)
{
	if (v->type != YAML_SEQUENCE_NODE)
		return fail_at(x, v, "'needs' must be a list of "
			       "job names");
	for (yaml_node_item_t *ni = v->data.sequence.items.start;
	     ni < v->data.sequence.items.top; ni++) {
		yaml_node_t *e = yaml_document_get_node(&x->doc, *ni);
		const char *s = scalar(e);
		if (!s || strlen(s) >= MAX_NAME)
			return fail_at(x, e, "'needs' entries are "
				       "job names");
		if (d->nneeds == MAX_NEEDS)
			return fail_at(x, e, "more than %d needs",
				       MAX_NEEDS);
		strcpy(d->needs_name[d->nneeds++], s);
	}
	return 0;
}

/* Reads one key `k` and its value `v` of job d into d, noting in *pp a
 * key that belongs to one stage only. Returns 0, or 1 after fail_at(). */
static int parse_job_key(struct ctx *x, struct job_decl *d,
			 struct job_params *pp, yaml_node_t *k, yaml_node_t *v)
{
	const char *n = d->name;
	const char *key = scalar(k);
	if (!key)
		return fail_at(x, k, "keys must be strings");
	if (!strcmp(key, "stage")) {
		const char *s = scalar(v);
		if (!s || !(d->stage = stage_lookup(s))) {
			char known[256] = "";
			stage_names(known, sizeof known);
			return fail_at(x, v, "unknown stage '%s' (known: "
				       "%s)", s ? s : "?", known);
		}
	} else if (!strcmp(key, "needs")) {
		if (parse_needs(x, d, v))
			return 1;
	} else if (!strcmp(key, "inflation")) {
		/* the ranges are lossy-cluster's own */
		if (want_number(x, v, key, 1.0, 100.0, 1, d->inflation,
				sizeof d->inflation))
			return 1;
		pp->lossy = k;
	} else if (!strcmp(key, "diff_factor")) {
		if (want_number(x, v, key, 0.0, 1e6, 0, d->diff_factor,
				sizeof d->diff_factor))
			return 1;
		pp->lossy = k;
	} else if (!strcmp(key, "max_refs")) {
		int r;
		if (want_int(x, v, key, 0, 1000000, &r))
			return 1;
		snprintf(d->max_refs, sizeof d->max_refs, "%d", r);
		pp->lossy = k;
	} else if (!strcmp(key, "group")) {
		if (want_int(x, v, key, 0, 48, &d->group))
			return 1;
		if (d->group != 8 && d->group != 48)
			return fail_at(x, v, "'group' is 8 (reflections, "
				       "the SSVDAG) or 48 (the cube's "
				       "symmetries), not %d", d->group);
		pp->group = k;
	} else if (!strcmp(key, "method")) {
		const char *m = scalar(v);
		if (!m || (strcmp(m, "auto") && strcmp(m, "vbr") &&
			   strcmp(m, "palette") && strcmp(m, "raw")))
			return fail_at(x, v, "'method' is auto, vbr, palette "
				       "or raw");
		strcpy(d->method, m);
		pp->colour = k;
	} else if (!strcmp(key, "max_error")) {
		/* colorize's own range; vbr's floor is checked with the
		 * method, which may come after */
		if (want_number(x, v, key, 0, 1.8, 1, d->max_error,
				sizeof d->max_error))
			return 1;
		pp->colour = k;
		pp->max_error = v;
	} else if (!strcmp(key, "weight_bits")) {
		int w;
		if (want_int(x, v, key, 1, 8, &w))
			return 1;
		snprintf(d->weight_bits, sizeof d->weight_bits, "%d", w);
		pp->colour = k;
	} else if (!strcmp(key, "palette_colours")) {
		int w;
		if (want_int(x, v, key, 2, 16777216, &w))
			return 1;
		snprintf(d->palette_colours, sizeof d->palette_colours,
			 "%d", w);
		pp->colour = k;
	} else if (!strcmp(key, "lossless")) {
		const char *b = scalar(v);
		if (!b || (strcmp(b, "true") && strcmp(b, "false")))
			return fail_at(x, v, "'lossless' is true or false");
		d->lossless = !strcmp(b, "true");
		pp->colour = k;
	} else if (!strcmp(key, "script")) {
		if (parse_script(x, d, v))
			return 1;
		pp->edit = k;
	} else {
		return fail_at(x, k, "unknown key '%s' in job '%s' "
			       "(known: stage, needs; group for "
			       "symmetry-merge; inflation, "
			       "diff_factor, max_refs for lossy-cluster; "
			       "script for edit; method, max_error, "
			       "weight_bits, palette_colours, lossless for "
			       "colorize)", key, n);
	}
	return 0;
}

/* Checks job d (mapping `map`) once all its keys are read: it has a
 * stage, each stage parameter in `pp` belongs to that stage, an edit job
 * has a script; and fills the defaults. Returns 0, or 1 after
 * fail_at(). */
static int job_finish(struct ctx *x, struct job_decl *d,
		      const struct job_params *pp, yaml_node_t *map)
{
	const char *n = d->name;
	if (!d->stage)
		return fail_at(x, map, "job '%s' has no 'stage'", n);
	if (pp->group && d->stage->type != STAGE_SYMMETRY_MERGE)
		return fail_at(x, pp->group, "'group' is a parameter of "
			       "symmetry-merge jobs, not of '%s' (stage %s)", n,
			       d->stage->name);
	if (!d->group)
		d->group = 8;
	if (pp->lossy && d->stage->type != STAGE_LOSSY)
		return fail_at(x, pp->lossy, "'%s' is a parameter of "
			       "lossy-cluster jobs, not of '%s' (stage %s)",
			       scalar(pp->lossy), n, d->stage->name);
	if (pp->colour && d->stage->type != STAGE_COLORIZE)
		return fail_at(x, pp->colour, "'%s' is a parameter of colorize "
			       "jobs, not of '%s' (stage %s)",
			       scalar(pp->colour), n, d->stage->name);
	/* auto: the random-access blocks of issue 37, smaller and faster
	 * than vbr (Algorithm 1, kept as the paper's reference) */
	if (d->stage->type == STAGE_COLORIZE && !*d->method)
		strcpy(d->method, "auto");
	/* below 0.0236 a single colour may not fit vbr's RGB565 endpoints */
	if (pp->max_error && !strcmp(d->method, "vbr") &&
	    strtod(d->max_error, NULL) < 0.0236)
		return fail_at(x, pp->max_error, "'max_error' %s is below "
			       "0.0236, the least method vbr always meets "
			       "(RGB565 endpoints); method auto takes any "
			       "above 0", d->max_error);
	if (pp->edit && d->stage->type != STAGE_EDIT)
		return fail_at(x, pp->edit, "'script' is a parameter of edit "
			       "jobs, not of '%s' (stage %s)", n, d->stage->name);
	if (d->stage->type == STAGE_EDIT && !pp->edit)
		return fail_at(x, map, "edit job '%s' has no 'script' (a file "
			       "or a list of edit lines)", n);
	/* lossy-cluster's defaults (van der Laan et al. 2020) */
	if (!*d->inflation)
		strcpy(d->inflation, "2.0");
	if (!*d->diff_factor)
		strcpy(d->diff_factor, "1.0");
	if (!*d->max_refs)
		strcpy(d->max_refs, "1");
	return 0;
}

/* Reads job `name` with its mapping `map` into the next c->jobs_decl:
 * job_begin, each key (parse_job_key), job_finish. Returns 0, or 1 after
 * fail_at(). */
static int parse_job(struct ctx *x, yaml_node_t *name, yaml_node_t *map)
{
	struct config *c = x->c;
	struct job_decl *d = job_begin(x, name);
	if (!d)
		return 1;
	if (want_mapping(x, map, d->name))
		return 1;
	struct job_params pp = {0};
	yaml_node_t *k, *v;
	FOR_PAIRS(x, map, k, v, it) {
		if (parse_job_key(x, d, &pp, k, v))
			return 1;
	}
	if (job_finish(x, d, &pp, map))
		return 1;
	c->njobs++;
	return 0;
}

/* Resolves needs, checks the graph has no cycle and each stage gets the
 * inputs it takes. */
static int check_graph(struct ctx *x, yaml_node_t *jobs_node)
{
	struct config *c = x->c;
	for (int i = 0; i < c->njobs; i++) {
		struct job_decl *d = &c->jobs_decl[i];
		for (int k = 0; k < d->nneeds; k++) {
			int found = -1;
			for (int j = 0; j < c->njobs; j++)
				if (!strcmp(c->jobs_decl[j].name, d->needs_name[k]))
					found = j;
			if (found < 0) {
				fprintf(stderr, "voxdag: %s:%d:%d: job '%s' needs "
					"'%s', which is not a job\n", x->path,
					d->line, d->column, d->name,
					d->needs_name[k]);
				return 1;
			}
			d->needs[k] = found;
		}
	}
	/* cycles: repeatedly take jobs whose needs are all taken */
	int taken[MAX_JOBS_DECL] = {0}, ntaken = 0, progress = 1;
	while (progress) {
		progress = 0;
		for (int i = 0; i < c->njobs; i++) {
			if (taken[i])
				continue;
			int ok = 1;
			for (int k = 0; k < c->jobs_decl[i].nneeds; k++)
				ok &= taken[c->jobs_decl[i].needs[k]];
			if (ok)
				taken[i] = 1, ntaken++, progress = 1;
		}
	}
	if (ntaken < c->njobs) {
		for (int i = 0; i < c->njobs; i++)
			if (!taken[i]) {
				fprintf(stderr, "voxdag: %s:%d:%d: job '%s' is "
					"part of a cycle of needs\n", x->path,
					c->jobs_decl[i].line,
					c->jobs_decl[i].column,
					c->jobs_decl[i].name);
				return 1;
			}
	}
	/* what each stage takes: a job producing one root DAG chunk is
	 * svo-to-dag's tree, lossy-cluster or edit; symmetry-merge runs per
	 * cell after svo-to-dag, as one process on the root after the others */
	for (int i = 0; i < c->njobs; i++) {
		struct job_decl *d = &c->jobs_decl[i];
		const struct stage_info *s = d->stage;
		int bad = d->nneeds < s->min_needs || d->nneeds > s->max_needs;
		enum stage_type t[MAX_NEEDS];
		for (int k = 0; k < d->nneeds; k++)
			t[k] = c->jobs_decl[d->needs[k]].stage->type;
		for (int k = 0; k < d->nneeds && !bad; k++) {
			switch (s->type) {
			case STAGE_SVO_TO_DAG:
				bad = t[k] != STAGE_VOXELIZE;
				break;
			case STAGE_SYMMETRY_MERGE:
			case STAGE_LOSSY:
				bad = !stage_makes_root_dag(t[k]);
				break;
			case STAGE_EDIT:
				/* a second need: the voxelize job, whose
				 * colours are those of svo-to-dag's scene
				 * (not of a lossy or edited one) */
				bad = k == 0 ? !stage_makes_root_dag(t[k])
					     : t[k] != STAGE_VOXELIZE ||
					       t[0] != STAGE_SVO_TO_DAG;
				break;
			case STAGE_ENCODE:
				bad = !stage_makes_root_dag(t[k]) &&
				      t[k] != STAGE_SYMMETRY_MERGE;
				break;
			case STAGE_RENDER:
				/* a second need: an encode job to show the
				 * differences from, or the colours */
				bad = k == 0 ? t[k] != STAGE_ENCODE
					     : t[k] != STAGE_ENCODE &&
					       t[k] != STAGE_COLORIZE;
				break;
			case STAGE_COLORIZE:
				/* or an edit job that carries the colours */
				bad = t[k] != STAGE_VOXELIZE &&
				      !(t[k] == STAGE_EDIT &&
					c->jobs_decl[d->needs[k]].nneeds == 2);
				break;
			default:
				bad = 1;
			}
		}
		if (s->type == STAGE_ENCODE && !bad) {
			/* one DAG job and the symmetry-merge jobs built from
			 * it (one, or one of each group): else the encodings
			 * are of two scenes */
			int dk = -1, groups = 0;
			for (int k = 0; k < d->nneeds; k++)
				if (stage_makes_root_dag(t[k]))
					bad |= dk >= 0, dk = k;
			for (int k = 0; k < d->nneeds && !bad && dk >= 0; k++) {
				if (k == dk)
					continue;
				const struct job_decl *sm = &c->jobs_decl[d->needs[k]];
				int g = sm->group == 48 ? 2 : 1;
				bad = t[k] != STAGE_SYMMETRY_MERGE ||
				      sm->needs[0] != d->needs[dk] || (groups & g);
				groups |= g;
			}
			bad |= dk < 0;
		}
		if (bad) {
			static const char *const shape[STAGE_COUNT_] = {
				[STAGE_VOXELIZE] = "no needs",
				[STAGE_SVO_TO_DAG] = "needs: [a voxelize job]",
				[STAGE_SYMMETRY_MERGE] = "needs: [an svo-to-dag, "
					"lossy-cluster or edit job]",
				[STAGE_ENCODE] = "needs: [a DAG job (svo-to-dag, "
					"lossy-cluster or edit), the symmetry-merge "
					"job that needs it (and a second one of the "
					"other group)]",
				[STAGE_RENDER] = "needs: [an encode job] or [an "
					"encode job, an encode job to show the "
					"differences from, or a colorize job for "
					"the colours]",
				[STAGE_COLORIZE] = "needs: [a voxelize job] or "
					"[an edit job with colours]",
				[STAGE_LOSSY] = "needs: [an svo-to-dag, "
					"lossy-cluster or edit job]",
				[STAGE_EDIT] = "needs: [an svo-to-dag, "
					"lossy-cluster or edit job] or, with "
					"colours, [an svo-to-dag job, the "
					"voxelize job]",
			};
			fprintf(stderr, "voxdag: %s:%d:%d: job '%s' (stage %s) "
				"takes %s\n", x->path, d->line, d->column,
				d->name, s->name, shape[s->type]);
			return 1;
		}
	}
	int vox = 0;
	for (int i = 0; i < c->njobs; i++)
		vox += c->jobs_decl[i].stage->type == STAGE_VOXELIZE;
	if (vox != 1)
		return fail_at(x, jobs_node, "a pipeline has exactly one voxelize "
			       "job (found %d)", vox);
	return 0;
}

/* `keep: [job, ...]`: the jobs whose outputs stay; each must be a job. */
static int parse_keep(struct ctx *x, yaml_node_t *v)
{
	struct config *c = x->c;
	c->keep_given = 1;
	for (yaml_node_item_t *ni = v->data.sequence.items.start;
	     ni < v->data.sequence.items.top; ni++) {
		yaml_node_t *e = yaml_document_get_node(&x->doc, *ni);
		const char *s = scalar(e);
		int d = 0;
		while (s && d < c->njobs && strcmp(c->jobs_decl[d].name, s))
			d++;
		if (!s || d == c->njobs)
			return fail_at(x, e, "'keep' names '%s', which is not a "
				       "job", s ? s : "?");
		c->keep_mask |= 1u << d;
	}
	return 0;
}

static int parse_root(struct ctx *x, yaml_node_t *root)
{
	struct config *c = x->c;
	if (!root || root->type != YAML_MAPPING_NODE)
		return fail_at(x, root, "a pipeline is a mapping of version, "
			       "name, input, levels, resources, jobs");
	yaml_node_t *k, *v, *jobs_node = NULL, *input = NULL, *levels = NULL,
			      *res_node = NULL, *keep = NULL;
	int have_version = 0;
	FOR_PAIRS(x, root, k, v, it) {
		const char *key = scalar(k);
		int err = 0;
		if (!key)
			return fail_at(x, k, "keys must be strings");
		if (!strcmp(key, "version")) {
			err = want_int(x, v, key, 1, 1000, &c->version);
			if (!err && c->version > PIPELINE_VERSION)
				return fail_at(x, v, "pipeline version %d is newer "
					       "than this runner's %d; upgrade "
					       "voxdag", c->version,
					       PIPELINE_VERSION);
			have_version = 1;
		} else if (!strcmp(key, "name")) {
			err = want_string(x, v, key, c->name, sizeof c->name);
			if (!err && !valid_name(c->name))
				return fail_at(x, v, "'name' is letters, digits, "
					       "'-' and '_' (it names out/<name>/)");
		} else if (!strcmp(key, "input")) {
			input = v;
			err = parse_input(x, v);
		} else if (!strcmp(key, "levels")) {
			levels = v;
			err = want_int(x, v, key, 1, VD_MAX_LEVELS, &c->levels);
		} else if (!strcmp(key, "chunk_level")) {
			const char *s = scalar(v);
			if (s && !strcmp(s, "auto"))
				c->chunk_level = -1;
			else
				err = want_int(x, v, key, 0, 7, &c->chunk_level);
		} else if (!strcmp(key, "resolutions")) {
			res_node = v;
			if (v->type != YAML_SEQUENCE_NODE)
				return fail_at(x, v, "'resolutions' must be a list "
					       "of grid depths");
			for (yaml_node_item_t *ni = v->data.sequence.items.start;
			     ni < v->data.sequence.items.top && !err; ni++) {
				if (c->nres == MAX_RES)
					return fail_at(x, v, "too many resolutions");
				err = want_int(x, yaml_document_get_node(&x->doc, *ni),
					       "resolutions", 1, VD_MAX_LEVELS,
					       &c->resolutions[c->nres++]);
			}
		} else if (!strcmp(key, "resources")) {
			err = parse_resources(x, v);
		} else if (!strcmp(key, "slurm")) {
			err = parse_slurm(x, v);
		} else if (!strcmp(key, "outputs")) {
			err = want_string(x, v, key, c->outputs,
					  sizeof c->outputs - 64);
			if (!err && !*c->outputs)
				return fail_at(x, v, "'outputs' is empty");
		} else if (!strcmp(key, "keep")) {
			keep = v; /* names jobs: read once they are known */
			if (v->type != YAML_SEQUENCE_NODE)
				return fail_at(x, v, "'keep' must be a list of "
					       "job names");
		} else if (!strcmp(key, "jobs")) {
			jobs_node = v;
			if (want_mapping(x, v, "jobs"))
				return 1;
			yaml_node_t *jk, *jv;
			FOR_PAIRS(x, v, jk, jv, jt) {
				if (parse_job(x, jk, jv))
					return 1;
			}
		} else if (!strcmp(key, "report")) {
			if (want_mapping(x, v, "report"))
				return 1;
			yaml_node_t *rk, *rv;
			FOR_PAIRS(x, v, rk, rv, rt) {
				const char *r = scalar(rk);
				if (r && !strcmp(r, "title")) {
					if (want_string(x, rv, "title", c->title,
							sizeof c->title))
						return 1;
				} else {
					return fail_at(x, rk, "unknown key "
						       "'report.%s' (known: "
						       "title)", r ? r : "?");
				}
			}
		} else {
			return fail_at(x, k, "unknown key '%s' (known: version, "
				       "name, input, levels, chunk_level, "
				       "resolutions, resources, slurm, outputs, "
				       "keep, jobs, report)", key);
		}
		if (err)
			return 1;
	}
	if (!have_version)
		return fail_at(x, root, "missing 'version' (this runner reads "
			       "version %d)", PIPELINE_VERSION);
	if (!*c->name)
		return fail_at(x, root, "missing 'name'");
	if (!input)
		return fail_at(x, root, "missing 'input'");
	if (!levels)
		return fail_at(x, root, "missing 'levels'");
	if (!jobs_node || c->njobs == 0)
		return fail_at(x, root, "missing 'jobs'");
	for (int i = 0; i < c->nres; i++)
		if (c->resolutions[i] > c->levels)
			return fail_at(x, res_node, "resolution %d is deeper "
				       "than 'levels' %d", c->resolutions[i],
				       c->levels);
	if (c->chunk_level > 0 && c->chunk_level > c->levels - 2)
		return fail_at(x, root, "'chunk_level' %d is deeper than "
			       "levels - 2", c->chunk_level);
	if (c->job_mem_budget > c->mem_budget)
		return fail_at(x, root, "'job_mem_budget' is larger than "
			       "'mem_budget'");
	if (check_graph(x, jobs_node))
		return 1;
	if (keep && parse_keep(x, keep))
		return 1;
	struct stat st;
	const char *in = *c->mesh ? c->mesh : c->vdb;
	if (stat(in, &st) != 0) {
		if (*c->fetch)
			return fail_at(x, input, "input '%s' is missing; fetch "
				       "it with: %s", in, c->fetch);
		return fail_at(x, input, "input '%s': %s", in, strerror(errno));
	}
	return 0;
}

int config_load(struct config *c, const char *path)
{
	memset(c, 0, sizeof *c);
	snprintf(c->path, sizeof c->path, "%s", path);
	c->chunk_level = -1;
	c->jobs = 2;
	c->mem_budget = 4ull << 30;
	c->job_mem_budget = 2ull << 30;
	c->slurm.bundle_seconds = 300;
	FILE *f = fopen(path, "rb");
	if (!f) {
		fprintf(stderr, "voxdag: cannot read '%s': %s\n", path,
			strerror(errno));
		return 1;
	}
	struct ctx x = {.path = path, .c = c};
	yaml_parser_t parser;
	yaml_parser_initialize(&parser);
	yaml_parser_set_input_file(&parser, f);
	int ok = yaml_parser_load(&parser, &x.doc);
	fclose(f);
	if (!ok) {
		fprintf(stderr, "voxdag: %s:%lu:%lu: %s%s%s\n", path,
			(unsigned long)parser.problem_mark.line + 1,
			(unsigned long)parser.problem_mark.column + 1,
			parser.problem ? parser.problem : "YAML syntax error",
			parser.context ? " " : "",
			parser.context ? parser.context : "");
		yaml_parser_delete(&parser);
		return 1;
	}
	yaml_parser_delete(&parser);
	int err = parse_root(&x, yaml_document_get_root_node(&x.doc));
	yaml_document_delete(&x.doc);
	if (!err && c->threads == 0) {
		int t = vd_hardware_threads() / c->jobs;
		c->threads = t > 0 ? t : 1;
	}
	if (!err && !*c->outputs)
		snprintf(c->outputs, sizeof c->outputs, "out/%s", c->name);
	if (!err && c->nres == 0)
		for (int l = c->levels; l >= 1 && l > c->levels - 4; l--)
			c->resolutions[c->nres++] = l;
	if (err)
		config_release(c);
	return err;
}

void config_release(struct config *c)
{
	/* a job that failed to parse is not counted in njobs */
	for (int i = 0; i < MAX_JOBS_DECL; i++) {
		free(c->jobs_decl[i].script_text);
		c->jobs_decl[i].script_text = NULL;
	}
}
