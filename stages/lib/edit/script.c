/* script.c - the edit tool's line format (schemas/edit-script.md), the
 * script run and the interactive shell. Scripts are parsed and checked
 * against the grid before anything is edited or written. */
#include "edit_internal.h"
#include "util_internal.h"
#include "io/publish.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

enum cmd_kind { CMD_NONE, CMD_OP, CMD_UNDO, CMD_REDO, CMD_GC, CMD_STATS,
		CMD_RENDER, CMD_SAVE, CMD_QUIT };

struct cmd {
	int kind;
	int line;
	int keep_history;        /* gc all */
	struct vd_edit_op op;
	char text[256];          /* the line, for statistics */
	char path[1024];         /* render, save */
};

/* Sets the detail to "PREFIX: [REASON: ]OLD DETAIL" (the old detail is
 * copied first: vd_fail() formats into the same buffer). */
static int rewrap(int err, int reason, const char *fmt, ...)
	__attribute__((format(printf, 3, 4)));
static int rewrap(int err, int reason, const char *fmt, ...)
{
	char old[1024], pre[1200];
	snprintf(old, sizeof old, "%s", vd_error_detail());
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(pre, sizeof pre, fmt, ap);
	va_end(ap);
	return vd_fail(err, "%s: %s%s%s", pre, reason ? vd_strerror(err) : "",
		       reason && *old ? ": " : "", old);
}

struct tok {
	const char *s;
	int len, col;
};

#define MAX_TOK 16

static int tokenize(const char *line, struct tok *t, int *n, int lineno)
{
	*n = 0;
	for (const char *p = line; *p;) {
		if (*p == '#' || *p == '\n' || *p == '\r')
			break;
		if (isspace((unsigned char)*p)) {
			p++;
			continue;
		}
		if (*n == MAX_TOK)
			return vd_fail(VD_ERR_FORMAT, "line %d, column %d: too "
				       "many words", lineno,
				       (int)(p - line) + 1);
		t[*n].s = p;
		t[*n].col = (int)(p - line) + 1;
		while (*p && !isspace((unsigned char)*p) && *p != '#')
			p++;
		t[*n].len = (int)(p - t[*n].s);
		(*n)++;
	}
	return VD_OK;
}

static int is(const struct tok *t, const char *w)
{
	return (int)strlen(w) == t->len && !strncmp(t->s, w, (size_t)t->len);
}

static int bad(int lineno, const struct tok *t, const char *what)
{
	return vd_fail(VD_ERR_FORMAT, "line %d, column %d: expected %s, found "
		       "'%.*s'", lineno, t->col, what, t->len, t->s);
}

static int num(int lineno, const struct tok *t, int whole, double *v)
{
	char buf[64], *end;
	if (t->len >= (int)sizeof buf)
		return bad(lineno, t, whole ? "a whole number" : "a number");
	memcpy(buf, t->s, (size_t)t->len);
	buf[t->len] = 0;
	errno = 0;
	if (whole) {
		long long x = strtoll(buf, &end, 10);
		if (!*buf || *end || errno || x < -(1ll << 40) || x > 1ll << 40)
			return bad(lineno, t, "a whole number");
		*v = (double)x;
	} else {
		*v = strtod(buf, &end);
		if (!*buf || *end || !isfinite(*v))
			return bad(lineno, t, "a number");
	}
	return VD_OK;
}

/* One line being parsed, shared by parse_line's steps: its words, the
 * next one to read, and the numbers read so far. */
struct line_parse {
	const char *line;
	int lineno;
	const struct tok *t;
	int n;            /* words */
	int i;            /* the next word */
	int world;        /* coordinates in world units */
	double v[10];     /* the numbers: box or sphere, then copy's target */
};

/* Parses a command that is not an operation (undo, redo, stats, quit,
 * gc, render, save) into *c; sets *simple to 0 when the first word is
 * none of these. Returns VD_OK or an error naming the line. */
static int parse_simple(const struct line_parse *lp, struct cmd *c,
			int *simple)
{
	const struct tok *t = lp->t, *w = &t[0];
	int n = lp->n, lineno = lp->lineno, want = 1;
	*simple = 1;
	if (is(w, "undo"))
		c->kind = CMD_UNDO;
	else if (is(w, "redo"))
		c->kind = CMD_REDO;
	else if (is(w, "stats"))
		c->kind = CMD_STATS;
	else if (is(w, "quit") || is(w, "exit"))
		c->kind = CMD_QUIT;
	else if (is(w, "gc")) {
		c->kind = CMD_GC;
		if (n == 2 && is(&t[1], "all"))
			c->keep_history = 1, want = 2;
		else if (n >= 2)
			return bad(lineno, &t[1], "'all' or the end of the line");
	} else if (is(w, "render") || is(w, "save")) {
		c->kind = is(w, "render") ? CMD_RENDER : CMD_SAVE;
		if (n >= 2) {
			snprintf(c->path, sizeof c->path, "%.*s", t[1].len,
				 t[1].s);
			want = 2;
		} else if (c->kind == CMD_RENDER) {
			return vd_fail(VD_ERR_FORMAT, "line %d, column %d: "
				       "render needs a FILE.png", lineno,
				       w->col + w->len);
		}
	} else {
		*simple = 0;
		return VD_OK;
	}
	if (n > want)
		return bad(lineno, &t[want], "the end of the line");
	return VD_OK;
}

/* Reads an operation's head into *op: its kind, its shape (but copy's,
 * always a box) and 'world'. Returns VD_OK or an error naming the line. */
static int parse_op_head(struct line_parse *lp, struct vd_edit_op *op)
{
	const struct tok *t = lp->t, *w = &t[0];
	int n = lp->n, lineno = lp->lineno;
	if (is(w, "fill"))
		op->kind = VD_EDIT_FILL;
	else if (is(w, "carve"))
		op->kind = VD_EDIT_CARVE;
	else if (is(w, "copy"))
		op->kind = VD_EDIT_COPY;
	else if (is(w, "paint"))
		op->kind = VD_EDIT_PAINT;
	else
		return bad(lineno, w, "an operation (fill, carve, copy, paint, "
			   "undo, redo, gc, render, save, stats)");
	lp->i = 1, lp->world = 0;
	op->shape = VD_SHAPE_BOX;
	if (op->kind != VD_EDIT_COPY) {
		if (lp->i >= n)
			return vd_fail(VD_ERR_FORMAT, "line %d, column %d: "
				       "expected box or sphere", lineno,
				       w->col + w->len);
		if (is(&t[lp->i], "sphere"))
			op->shape = VD_SHAPE_SPHERE;
		else if (!is(&t[lp->i], "box"))
			return bad(lineno, &t[lp->i], "box or sphere");
		lp->i++;
	}
	if (lp->i < n && is(&t[lp->i], "world")) {
		if (op->kind == VD_EDIT_COPY)
			return bad(lineno, &t[lp->i], "voxel coordinates (copy "
				   "takes no 'world')");
		lp->world = 1;
		lp->i++;
	}
	return VD_OK;
}

/* Reads the numbers of an operation into lp->v: the sphere's centre and
 * radius or the box's corners, then copy's 'to' and target. Returns VD_OK
 * or an error naming the line. */
static int parse_op_numbers(struct line_parse *lp, const struct vd_edit_op *op)
{
	const struct tok *t = lp->t;
	int n = lp->n, lineno = lp->lineno, err;
	const char *line = lp->line;
	double *v = lp->v;
	int nv = op->shape == VD_SHAPE_SPHERE ? 4 : 6;
	for (int k = 0; k < nv; k++, lp->i++) {
		if (lp->i >= n)
			return vd_fail(VD_ERR_FORMAT, "line %d, column %d: "
				       "expected %d numbers", lineno,
				       (int)strlen(line) + 1, nv);
		if ((err = num(lineno, &t[lp->i],
			       !lp->world && op->shape == VD_SHAPE_BOX, &v[k])))
			return err;
	}
	if (op->kind == VD_EDIT_COPY) {
		if (lp->i >= n || !is(&t[lp->i], "to"))
			return lp->i >= n ? vd_fail(VD_ERR_FORMAT, "line %d, "
						    "column %d: expected 'to'",
						    lineno,
						    (int)strlen(line) + 1)
					  : bad(lineno, &t[lp->i], "'to'");
		lp->i++;
		for (int k = 6; k < 9; k++, lp->i++) {
			if (lp->i >= n)
				return vd_fail(VD_ERR_FORMAT, "line %d, column "
					       "%d: expected 3 numbers after "
					       "'to'", lineno,
					       (int)strlen(line) + 1);
			if ((err = num(lineno, &t[lp->i], 1, &v[k])))
				return err;
		}
	}
	return VD_OK;
}

/* Reads the rest of an operation: fill's and paint's 'colour R G B',
 * then the end of the line; paint on a coloured scene needs a colour.
 * Returns VD_OK or an error naming the line. */
static int parse_op_tail(struct line_parse *lp, const struct vd_hashdag *h,
			 struct vd_edit_op *op)
{
	const struct tok *t = lp->t;
	int n = lp->n, lineno = lp->lineno, err;
	if (lp->i < n &&
	    (op->kind == VD_EDIT_FILL || op->kind == VD_EDIT_PAINT) &&
	    (is(&t[lp->i], "colour") || is(&t[lp->i], "color"))) {
		int at = t[lp->i].col + t[lp->i].len;
		lp->i++;
		for (int k = 0; k < 3; k++, lp->i++) {
			if (lp->i >= n)
				return vd_fail(VD_ERR_FORMAT, "line %d, column "
					       "%d: expected 3 numbers 0..255 "
					       "after 'colour'", lineno, at);
			double x;
			if ((err = num(lineno, &t[lp->i], 1, &x)))
				return err;
			if (x < 0 || x > 255)
				return bad(lineno, &t[lp->i], "a number 0..255");
			op->rgb[k] = (uint8_t)x;
		}
		op->has_rgb = 1;
	}
	if (lp->i < n)
		return bad(lineno, &t[lp->i], op->kind == VD_EDIT_FILL ||
						      op->kind == VD_EDIT_PAINT
					      ? "'colour R G B' or the end of "
						"the line"
					      : "the end of the line");
	if (op->kind == VD_EDIT_PAINT && !op->has_rgb && h->col)
		return vd_fail(VD_ERR_FORMAT, "line %d, column %d: paint needs "
			       "'colour R G B'", lineno,
			       (int)strlen(lp->line) + 1);
	return VD_OK;
}

/* Sets op's sphere or box (and copy's target) in voxels from the numbers
 * read, converting world units with the grid's transform. */
static void op_to_voxels(const struct line_parse *lp,
			 const struct vd_hashdag *h, struct vd_edit_op *op)
{
	const double *v = lp->v;
	int world = lp->world;
	const struct vd_transform *tr = &h->t;
	if (op->shape == VD_SHAPE_SPHERE) {
		for (int a = 0; a < 3; a++)
			op->c[a] = world ? (v[a] - tr->origin[a]) / tr->voxel_size
					 : v[a];
		op->r = world ? v[3] / tr->voxel_size : v[3];
	} else {
		for (int a = 0; a < 3; a++) {
			if (world) {
				double lo = fmin(v[a], v[a + 3]),
				       hi = fmax(v[a], v[a + 3]);
				/* voxels whose centre lies in [lo, hi] */
				op->lo[a] = (int64_t)ceil((lo - tr->origin[a]) /
							  tr->voxel_size - 0.5);
				op->hi[a] = (int64_t)floor((hi - tr->origin[a]) /
							   tr->voxel_size - 0.5);
			} else {
				op->lo[a] = (int64_t)v[a];
				op->hi[a] = (int64_t)v[a + 3];
			}
			if (op->kind == VD_EDIT_COPY)
				op->dst[a] = (int64_t)v[6 + a];
		}
	}
}

/* Parses `line` (number `lineno`) into *c, checking it against the grid of
 * `h`: parse_simple, else an operation (parse_op_head, parse_op_numbers,
 * parse_op_tail, op_to_voxels, vd_edit_op_check). Errors name the line
 * and the column. */
static int parse_line(const struct vd_hashdag *h, const char *line,
		      int lineno, struct cmd *c)
{
	struct tok t[MAX_TOK];
	int n, err;
	memset(c, 0, sizeof *c);
	c->line = lineno;
	snprintf(c->text, sizeof c->text, "%s", line);
	c->text[strcspn(c->text, "\r\n")] = 0;
	if ((err = tokenize(line, t, &n, lineno)))
		return err;
	if (!n)
		return VD_OK;
	struct line_parse lp = {line, lineno, t, n, 0, 0, {0}};
	int simple;
	if ((err = parse_simple(&lp, c, &simple)) || simple)
		return err;
	struct vd_edit_op *op = &c->op;
	c->kind = CMD_OP;
	if ((err = parse_op_head(&lp, op)))
		return err;
	int first = lp.i;
	if ((err = parse_op_numbers(&lp, op)) ||
	    (err = parse_op_tail(&lp, h, op)))
		return err;
	op_to_voxels(&lp, h, op);
	if ((err = vd_edit_op_check(h, op)))
		return rewrap(err, 0, "line %d, column %d", lineno,
			      t[first].col);
	return VD_OK;
}

/* ---------------------------------------------------------- statistics */

static void json_op(struct vd_json *j, const struct vd_hashdag *h,
		    const struct cmd *c, const struct vd_edit_stats *st)
{
	vd_json_object(j, NULL);
	vd_json_u64(j, "line", (uint64_t)c->line);
	vd_json_str(j, "op", c->kind == CMD_GC ? "gc" : c->kind == CMD_UNDO
			     ? "undo" : c->kind == CMD_REDO ? "redo"
			     : c->op.kind == VD_EDIT_FILL ? "fill"
			     : c->op.kind == VD_EDIT_CARVE ? "carve"
			     : c->op.kind == VD_EDIT_PAINT ? "paint" : "copy");
	vd_json_u64(j, "voxels_changed", st->voxels_changed);
	vd_json_u64_array(j, c->kind == CMD_GC ? "nodes_kept" : "nodes_added",
			  st->nodes_added, (size_t)h->levels - 1);
	vd_json_f64(j, "seconds", st->seconds);
	vd_json_f64(j, "cpu_seconds", st->cpu_seconds);
	if (h->col && c->kind == CMD_OP)
		vd_json_u64(j, "colour_cells_rebuilt",
			    st->colour_cells_rebuilt);
	vd_json_u64(j, "hash_bytes", st->hash_bytes);
	vd_json_u64(j, "peak_rss_bytes", vd_peak_rss_bytes());
	vd_json_end_object(j);
}

static void print_stats(FILE *f, const struct vd_hashdag *h)
{
	uint64_t stored[VD_MAX_LEVELS], reach[VD_MAX_LEVELS];
	vd_hashdag_counts(h, stored, reach);
	fprintf(f, "history %zu/%zu, hash bytes %llu, peak RSS %llu\n",
		h->cur + 1, h->nroots,
		(unsigned long long)vd_hashdag_memory_bytes(h),
		(unsigned long long)vd_peak_rss_bytes());
	for (int l = 0; l <= h->levels - 2; l++)
		fprintf(f, "level %2d: %llu stored, %llu reachable, fullest "
			"bucket %u/%u words\n", l,
			(unsigned long long)stored[l],
			(unsigned long long)reach[l],
			vd_hashdag_max_bucket(h, l), 1u << h->lv[l].m);
}

static void mem_get(const struct vd_colour_source *s, uint64_t i,
		    uint8_t rgb[3])
{
	memcpy(rgb, (const uint8_t *)s->impl + 3 * i, 3);
}

static int render_to(const struct vd_edit_job *job, struct vd_hashdag *h,
		     const char *png)
{
	/* with colours, the picture takes the scene's colour array as it is
	 * in memory (a source of its own, nothing written) */
	struct vd_colour_source cs = {.levels = h->levels, .cell_level = -1,
				      .get = mem_get};
	uint8_t *rgb = NULL;
	if (h->col) {
		int err = vd_hashdag_colour_array(h, &rgb, &cs.voxels);
		if (err)
			return rewrap(err, 1, "cannot render '%s'", png);
		cs.impl = rgb;
	}
	char tmp[1100];
	snprintf(tmp, sizeof tmp, "%s.edit-%d.dag", png, (int)getpid());
	int err = vd_hashdag_save(h, tmp, NULL);
	if (err) {
		free(rgb);
		return rewrap(err, 1, "cannot render '%s'", png);
	}
	struct vd_render_job r = {.tool = job->tool, .input = tmp,
				  .output = png, .preset = "iso", .quiet = 1};
	r.opts.width = 640;
	r.opts.height = 480;
	r.opts.cam.fov_deg = 40;
	r.opts.threads = job->opts.threads;
	r.opts.colours = h->col ? &cs : NULL;
	err = vd_render_run(&r);
	unlink(tmp);
	free(rgb);
	return err;
}

/* Puts an edit's outputs in place together: the DAG chunk `staged`
 * (and its statistics staged_stats, or NULL) and, when cstage is not
 * NULL, the colour directory staged there for colours_out. Everything was
 * written complete before this (a full disk fails before any rename);
 * the colours go in first and are put back if the chunk's rename fails,
 * so the DAG and its colours are replaced together or not at all (the
 * pair once left a new DAG beside old colours when the colours failed).
 * On failure the staged files are removed. */
static int publish(const char *cstage, const char *colours_out,
		   const char *staged, const char *out,
		   const char *staged_stats, const char *stats)
{
	int had_old = 0, err;
	if (cstage && (err = vd_dir_swap(cstage, colours_out, &had_old))) {
		vd_dir_abandon(cstage);
		unlink(staged);
		if (staged_stats)
			unlink(staged_stats);
		return rewrap(err, 1, "cannot write '%s'", colours_out);
	}
	err = staged_stats ? vd_publish_pair(staged, out, staged_stats, stats)
			   : vd_replace_file(staged, out);
	if (err) {
		unlink(staged);
		err = rewrap(err, 1, "cannot write '%s'", out);
		/* the new colours back under the staging name, then removed
		 * (if they cannot go back, both stay: nothing is deleted) */
		if (cstage && vd_dir_unswap(cstage, colours_out, had_old) == VD_OK)
			vd_dir_abandon(cstage);
		return err;
	}
	if (cstage && had_old) { /* the old colours, now replaced */
		vd_dir_abandon(cstage);
		vd_error_clear();
	}
	return VD_OK;
}

/* Runs one command; *st is filled for edits and gc. */
static int run_cmd(const struct vd_edit_job *job, struct vd_hashdag *h,
		   const struct cmd *c, struct vd_edit_stats *st)
{
	memset(st, 0, sizeof *st);
	switch (c->kind) {
	case CMD_OP:
		return vd_hashdag_apply(h, &c->op, st);
	case CMD_UNDO:
		return vd_hashdag_undo(h);
	case CMD_REDO:
		return vd_hashdag_redo(h);
	case CMD_GC:
		return vd_hashdag_gc(h, c->keep_history, st);
	case CMD_RENDER:
		return render_to(job, h, c->path);
	case CMD_SAVE: {
		const char *p = c->path[0] ? c->path : job->output;
		if (!p)
			return vd_fail(VD_ERR_ARG, "save needs a FILE (no -o)");
		char staged[1200], cstage[4096];
		int err = vd_stage_name(p, staged, sizeof staged);
		if (!err && (err = vd_hashdag_save(h, staged, job->provenance)))
			unlink(staged);
		if (err)
			return rewrap(err, 1, "cannot write '%s'", p);
		if (job->colours_out &&
		    (err = vd_hashdag_colours_stage(h, job->colours_out,
						    job->provenance, cstage,
						    sizeof cstage))) {
			unlink(staged);
			return rewrap(err, 1, "cannot write '%s'",
				      job->colours_out);
		}
		return publish(job->colours_out ? cstage : NULL,
			       job->colours_out, staged, p, NULL, NULL);
	}
	case CMD_STATS:
		print_stats(job->out ? job->out : stdout, h);
		return VD_OK;
	default:
		return VD_OK;
	}
}

static int read_script(const char *path, char **text)
{
	FILE *f = fopen(path, "rb");
	if (!f)
		return vd_fail(VD_ERR_IO, "cannot read '%s': %s", path,
			       strerror(errno));
	size_t cap = 4096, n = 0;
	char *b = malloc(cap);
	for (size_t r; b && (r = fread(b + n, 1, cap - n - 1, f)) > 0;) {
		n += r;
		if (n + 1 == cap) {
			char *nb = realloc(b, cap *= 2);
			if (!nb)
				free(b);
			b = nb;
		}
	}
	int bad_read = ferror(f);
	fclose(f);
	if (!b)
		return vd_fail(VD_ERR_NOMEM, "script");
	if (bad_read) {
		free(b);
		return vd_fail(VD_ERR_IO, "cannot read '%s'", path);
	}
	b[n] = 0;
	if (memchr(b, 0, n)) {
		free(b);
		return vd_fail(VD_ERR_FORMAT, "cannot parse '%s': a NUL byte "
			       "in the text", path);
	}
	*text = b;
	return VD_OK;
}

static int run_script(const struct vd_edit_job *job, struct vd_hashdag *h,
		      double seconds_load, double cpu_seconds_load)
{
	char *text = NULL;
	int err = read_script(job->script, &text);
	if (err)
		return err;
	struct cmd *cmds = NULL;
	size_t nc = 0, cap = 0;
	int lineno = 0;
	for (char *p = text; *p && !err; lineno++) {
		char *e = strchr(p, '\n');
		if (e)
			*e = 0;
		if (nc == cap) {
			struct cmd *v = realloc(cmds, (cap = cap ? 2 * cap : 64) *
						sizeof *v);
			if (!v) {
				err = vd_fail(VD_ERR_NOMEM, "script");
				break;
			}
			cmds = v;
		}
		if ((err = parse_line(h, p, lineno + 1, &cmds[nc])))
			err = rewrap(err, 0, "cannot parse '%s'", job->script);
		if (!err && cmds[nc].kind != CMD_NONE)
			nc++;
		p = e ? e + 1 : p + strlen(p);
	}
	free(text);
	/* the chunk, its statistics and the colour directory are written
	 * under staging names and replace the previous outputs together
	 * (publish), so a failure (a full disk) leaves them as they were */
	char stats[1100], staged[1200], staged_stats[1200];
	snprintf(stats, sizeof stats, "%s.stats.json", job->output);
	if (!err)
		err = vd_stage_name(job->output, staged, sizeof staged);
	if (!err)
		err = vd_stage_name(stats, staged_stats, sizeof staged_stats);
	struct vd_json *j = NULL;
	if (!err && (err = vd_json_open(&j, staged_stats)))
		err = rewrap(err, 1, "cannot write '%s'", stats);
	if (!err) {
		vd_json_str(j, "tool", job->tool);
		vd_json_str(j, "version", VD_VERSION_STRING);
		vd_json_u64(j, "levels", (uint64_t)h->levels);
		vd_json_f64(j, "seconds_load", seconds_load);
		vd_json_f64(j, "cpu_seconds_load", cpu_seconds_load);
		uint64_t st0[VD_MAX_LEVELS];
		vd_hashdag_counts(h, st0, NULL);
		vd_json_u64_array(j, "input_nodes", st0, (size_t)h->levels - 1);
		vd_json_array(j, "operations");
	}
	for (size_t i = 0; i < nc && !err; i++) {
		struct vd_edit_stats st;
		if ((err = run_cmd(job, h, &cmds[i], &st))) {
			err = rewrap(err, 0, "cannot apply line %d of '%s'",
				     cmds[i].line, job->script);
			break;
		}
		if (cmds[i].kind == CMD_OP || cmds[i].kind == CMD_GC ||
		    cmds[i].kind == CMD_UNDO || cmds[i].kind == CMD_REDO)
			json_op(j, h, &cmds[i], &st);
	}
	free(cmds);
	if (err) {
		vd_json_abort(j); /* no statistics of a failed run */
		return err;
	}
	vd_json_end_array(j);
	double t0 = vd_seconds(), c0 = vd_cpu_seconds();
	struct vd_dag dag;
	if ((err = vd_hashdag_to_dag(h, &dag)) ||
	    (err = vd_dag_save(&dag, &h->t, staged, job->provenance)))
		err = rewrap(err, 1, "cannot write '%s'", job->output);
	if (!err) {
		uint64_t st1[VD_MAX_LEVELS], reach[VD_MAX_LEVELS];
		vd_hashdag_counts(h, st1, reach);
		vd_json_u64_array(j, "stored_nodes", st1, (size_t)h->levels - 1);
		vd_json_u64_array(j, "reachable_nodes", reach,
				  (size_t)h->levels - 1);
		vd_json_u64(j, "voxels", dag.voxels);
		vd_json_u64(j, "hash_bytes", vd_hashdag_memory_bytes(h));
		vd_json_u64(j, "dag_bytes", vd_dag_memory_bytes(&dag));
		vd_json_f64(j, "seconds_save", vd_seconds() - t0);
		vd_json_f64(j, "cpu_seconds_save", vd_cpu_seconds() - c0);
		vd_json_u64(j, "peak_rss_bytes", vd_peak_rss_bytes());
		if (!job->quiet)
			fprintf(stderr, "%s: %zu lines applied, %llu voxels, "
				"hash %.1f MiB, %.2f s to save\n", job->tool,
				nc, (unsigned long long)dag.voxels,
				(double)vd_hashdag_memory_bytes(h) / 1048576.0,
				vd_seconds() - t0);
	}
	vd_dag_release(&dag);
	/* the colours are staged too before anything is replaced */
	char cstage[4096];
	t0 = vd_seconds();
	c0 = vd_cpu_seconds();
	if (!err && job->colours_out &&
	    (err = vd_hashdag_colours_stage(h, job->colours_out,
					    job->provenance, cstage,
					    sizeof cstage)))
		err = rewrap(err, 1, "cannot write '%s'", job->colours_out);
	if (!err && job->colours_out) {
		vd_json_f64(j, "seconds_save_colours", vd_seconds() - t0);
		vd_json_f64(j, "cpu_seconds_save_colours", vd_cpu_seconds() - c0);
		vd_json_u64(j, "peak_rss_bytes_colours", vd_peak_rss_bytes());
	}
	if (!err)
		vd_json_f64(j, "process_cpu_seconds", vd_cpu_seconds());
	if (!err && (err = vd_json_close(j))) {
		err = rewrap(err, 1, "cannot write '%s'", stats);
		if (job->colours_out)
			vd_dir_abandon(cstage);
	} else if (err) {
		vd_json_abort(j);
	}
	if (err) {
		unlink(staged_stats);
		unlink(staged);
		return err;
	}
	return publish(job->colours_out ? cstage : NULL, job->colours_out,
		       staged, job->output, staged_stats, stats);
}

static int run_shell(const struct vd_edit_job *job, struct vd_hashdag *h)
{
	FILE *in = job->in ? job->in : stdin, *out = job->out ? job->out : stdout;
	char line[4096];
	int lineno = 0, failed = 0;
	while (fgets(line, sizeof line, in)) {
		struct cmd c;
		struct vd_edit_stats st;
		lineno++;
		int err = parse_line(h, line, lineno, &c);
		if (!err && c.kind == CMD_QUIT)
			break;
		if (!err)
			err = run_cmd(job, h, &c, &st);
		if (err) {
			fprintf(stderr, "%s: %s: %s\n", job->tool,
				vd_strerror(err), vd_error_detail());
			failed = 1;
			continue;
		}
		if (c.kind == CMD_OP)
			fprintf(out, "ok: %llu voxels changed, %.3f s\n",
				(unsigned long long)st.voxels_changed,
				st.seconds);
		else if (c.kind == CMD_GC)
			fprintf(out, "ok: gc in %.3f s, hash %llu bytes\n",
				st.seconds, (unsigned long long)st.hash_bytes);
		else if (c.kind != CMD_NONE && c.kind != CMD_STATS)
			fprintf(out, "ok\n");
		fflush(out);
	}
	/* A shell that met errors says so in its exit status; each was
	 * reported on its line, so the detail stays empty. */
	vd_error_clear();
	return failed ? VD_ERR_FORMAT : VD_OK;
}

int vd_edit_run(const struct vd_edit_job *job)
{
	double t0 = vd_seconds(), c0 = vd_cpu_seconds();
	struct vd_hashdag *h;
	int err = vd_hashdag_load(&h, job->input, &job->opts);
	if (err)
		return rewrap(err, 1, "cannot read '%s'", job->input);
	if (job->colours &&
	    (err = vd_hashdag_colours_open(h, job->colours,
					   job->has_fill_rgb ? job->fill_rgb
							     : NULL))) {
		vd_hashdag_free(h);
		return rewrap(err, 1, "cannot read colours '%s'", job->colours);
	}
	err = job->script ? run_script(job, h, vd_seconds() - t0,
				       vd_cpu_seconds() - c0)
			  : run_shell(job, h);
	vd_hashdag_free(h);
	return err;
}
