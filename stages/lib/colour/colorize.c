/* The colorize stage: a voxelize output directory's colour chunks, read
 * cell by cell in cell order (each checked against its SVO chunk), into
 * packed colours files, one per method, published as one directory with a
 * manifest; statistics in the colour paper's terms (percent of raw, GMSE). */
#include "voxdag.h"
#include "util_internal.h"

#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

struct cell {
	char *name;           /* the .svo file name (no directory) */
	int level;
	uint64_t morton;
};

static int cmp_cell(const void *a, const void *b)
{
	const struct cell *x = a, *y = b;
	if (x->level != y->level)
		return x->level - y->level;
	return (x->morton > y->morton) - (x->morton < y->morton);
}

/* Prefixes the calling thread's error detail with the file it concerns
 * (copied first: the detail is the buffer vd_fail writes). */
static int about(int err, const char *path)
{
	char d[512];
	snprintf(d, sizeof d, "%s", vd_error_detail());
	return vd_fail(err, "'%s': %s", path, d);
}

static int ends_with(const char *s, const char *e)
{
	size_t n = strlen(s), m = strlen(e);
	return n > m && !strcmp(s + n - m, e);
}

static const char *const out_names[] = {NULL, "colours.vbr",
					"colours.palette", "colours.raw",
					"colours.auto"};

static int colorize_file(const char *name)
{
	for (int m = 1; m <= VD_CPACK_AUTO; m++)
		if (!strcmp(name, out_names[m]))
			return 1;
	return !strcmp(name, "colorize.stats.json");
}

/* The cells of `dir`: every *.svo chunk, sorted by cell; each must have
 * its .col beside it and every .col its .svo. */
static int list_cells(const char *dir, struct cell **out, size_t *count)
{
	*out = NULL;
	*count = 0;
	DIR *d = opendir(dir);
	if (!d)
		return vd_fail(VD_ERR_IO, "cannot open directory '%s': %s", dir,
			       strerror(errno));
	struct cell *c = NULL;
	size_t n = 0, cap = 0, cols = 0;
	int err = VD_OK;
	struct dirent *e;
	char path[4096];
	while (!err && (e = readdir(d))) {
		if (ends_with(e->d_name, ".col") && strncmp(e->d_name, "chunk-", 6) == 0) {
			cols++;
			continue;
		}
		if (!ends_with(e->d_name, ".svo") || strncmp(e->d_name, "chunk-", 6))
			continue;
		if (n == cap) {
			cap = cap ? 2 * cap : 64;
			struct cell *g = realloc(c, cap * sizeof *c);
			if (!g) {
				err = vd_fail(VD_ERR_NOMEM, "cell list");
				break;
			}
			c = g;
		}
		struct vd_chunk_header h;
		snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
		if ((err = vd_chunk_read_header(path, &h))) {
			err = about(err, path);
			break;
		}
		c[n].name = strdup(e->d_name);
		c[n].level = (int)h.chunk_level;
		c[n].morton = h.cell_morton;
		if (!c[n].name) {
			err = vd_fail(VD_ERR_NOMEM, "cell list");
			break;
		}
		n++;
	}
	closedir(d);
	if (!err && n == 0)
		err = vd_fail(VD_ERR_EMPTY, "no SVO chunks in '%s' (not a "
			      "voxelize output directory?)", dir);
	if (!err) {
		qsort(c, n, sizeof *c, cmp_cell);
		for (size_t i = 0; i < n && !err; i++) {
			snprintf(path, sizeof path, "%s/%.*s.col", dir,
				 (int)(strlen(c[i].name) - 4), c[i].name);
			FILE *f = fopen(path, "rb");
			if (!f)
				err = vd_fail(VD_ERR_MISMATCH, "cell '%s' has no "
					      "colour chunk '%s' (voxelize the "
					      "mesh with colours)", c[i].name,
					      path);
			else
				fclose(f);
		}
		if (!err && cols != n)
			err = vd_fail(VD_ERR_MISMATCH, "%zu colour chunks for %zu "
				      "SVO chunks in '%s'", cols, n, dir);
	}
	if (err) {
		for (size_t i = 0; i < n; i++)
			free(c[i].name);
		free(c);
		return err;
	}
	*out = c;
	*count = n;
	return VD_OK;
}

/* Loads cell i's colours and checks them against its SVO chunk (depth,
 * cell, grid, count, brick digest) and the first cell's grid. */
static int load_cell(const char *dir, const struct cell *c,
		     struct vd_colours *col, struct vd_chunk_header *first,
		     int is_first)
{
	char svo_path[4096], col_path[4096];
	snprintf(svo_path, sizeof svo_path, "%s/%s", dir, c->name);
	snprintf(col_path, sizeof col_path, "%s/%.*s.col", dir,
		 (int)(strlen(c->name) - 4), c->name);
	struct vd_svo svo;
	struct vd_chunk_header sh, ch;
	int err = vd_svo_load(&svo, &sh, svo_path);
	if (err)
		return about(err, svo_path);
	err = vd_colours_load(col, &ch, col_path);
	if (err) {
		vd_svo_release(&svo);
		return about(err, col_path);
	}
	err = vd_colours_match(&ch, col, &sh, &svo);
	vd_svo_release(&svo);
	if (err) {
		vd_colours_release(col);
		return about(err, col_path);
	}
	if (is_first)
		*first = ch;
	else if (ch.levels != first->levels ||
		 !vd_transform_equal(&ch.transform, &first->transform)) {
		vd_colours_release(col);
		return vd_fail(VD_ERR_MISMATCH, "'%s': another grid than the "
			       "first cell's", col_path);
	}
	return VD_OK;
}

struct method_run {
	int method;
	struct vd_cpack_writer *w;
	struct vd_cpack_stats st;
	double seconds, cpu_seconds;
	uint64_t file_bytes;
};

static void json_method(struct vd_json *j, const struct vd_colorize_job *job,
			const struct method_run *r, const struct vd_palette *pal,
			uint64_t voxels, double seconds_palette, double cpu_palette)
{
	uint64_t raw = 3 * voxels;
	uint64_t bytes = r->method == VD_CPACK_RAW ? r->file_bytes : r->st.bytes;
	vd_json_object(j, vd_cpack_method_name(r->method));
	vd_json_str(j, "file", out_names[r->method]);
	vd_json_u64(j, "bytes_raw", raw);
	vd_json_u64(j, "bytes", bytes);
	vd_json_u64(j, "file_bytes", r->file_bytes);
	vd_json_f64(j, "ratio", raw ? (double)bytes / raw : 0);
	vd_json_f64(j, "percent_of_raw", raw ? 100.0 * bytes / raw : 0);
	vd_json_f64(j, "gmse", voxels ? (double)r->st.sse / voxels : 0);
	/* the same mean with the distance e in percent (channels in [0,1],
	 * times 100): the unit the colour paper's GMSE figures are in
	 * (schemas/colour-formats.md) */
	vd_json_f64(j, "gmse_percent2",
		    voxels ? (double)r->st.sse / voxels * 1e4 / (255.0 * 255.0)
			   : 0);
	vd_json_f64(j, "max_error", sqrt((double)r->st.max_dist2) / 255.0);
	vd_json_u64(j, "blocks", r->st.blocks);
	vd_json_u64(j, "segments", r->st.segments);
	double sec = r->seconds + (r->method == VD_CPACK_PALETTE ? seconds_palette : 0);
	vd_json_f64(j, "seconds", sec);
	vd_json_f64(j, "voxels_per_second", sec > 0 ? voxels / sec : 0);
	double cpu = r->cpu_seconds + (r->method == VD_CPACK_PALETTE ? cpu_palette : 0);
	vd_json_f64(j, "cpu_seconds", cpu);
	vd_json_f64(j, "voxels_per_cpu_second", cpu > 0 ? voxels / cpu : 0);
	if (r->method == VD_CPACK_VBR) {
		vd_json_f64(j, "max_error_limit", job->vbr.max_error);
		vd_json_u64(j, "weight_bits", (uint64_t)job->vbr.weight_bits);
	}
	if (r->method == VD_CPACK_AUTO) {
		static const char *const mode[VD_AUTO_MODES] = {
			"constant", "palette", "endpoints", "quant", "raw",
			"coded"};
		vd_json_f64(j, "max_error_limit", job->autop.max_error);
		vd_json_u64(j, "lossless", job->autop.max_error == 0);
		vd_json_u64(j, "block_voxels", 1u << (job->autop.block_log
							? job->autop.block_log
							: 8));
		vd_json_object(j, "mode_blocks");
		for (int m = 0; m < VD_AUTO_MODES; m++)
			vd_json_u64(j, mode[m], r->st.mode_blocks[m]);
		vd_json_end_object(j);
	}
	if (r->method == VD_CPACK_PALETTE) {
		vd_json_u64(j, "palette_colours", pal->k);
		vd_json_u64(j, "palette_colours_requested", job->palette_colours);
		vd_json_u64(j, "lossless", (uint64_t)pal->lossless);
		vd_json_u64(j, "block_palettes", r->st.palettes);
		vd_json_u64(j, "palette_entries", r->st.palette_entries);
		vd_json_f64(j, "seconds_global_palette", seconds_palette);
	}
	vd_json_end_object(j);
}

static int write_stats(const char *path, const struct vd_colorize_job *job,
		       const struct method_run *runs, int nruns,
		       const struct vd_palette *pal, uint64_t voxels,
		       size_t cells, const struct vd_chunk_header *h,
		       double seconds_read, double seconds_palette,
		       double cpu_palette, double t0)
{
	struct vd_json *j;
	int err = vd_json_open(&j, path);
	if (err)
		return err;
	vd_json_str(j, "tool", "colorize");
	vd_json_u64(j, "levels", h->levels);
	vd_json_u64(j, "voxels", voxels);
	vd_json_u64(j, "cells", cells);
	vd_json_u64(j, "bytes_raw", 3 * voxels);
	vd_json_f64(j, "seconds_read", seconds_read);
	vd_json_f64(j, "seconds_total", vd_seconds() - t0);
	vd_json_u64(j, "peak_rss_bytes", vd_peak_rss_bytes());
	vd_json_f64(j, "process_cpu_seconds", vd_cpu_seconds());
	vd_json_u64(j, "threads", (uint64_t)(job->threads ? job->threads
							   : vd_hardware_threads()));
	vd_json_object(j, "methods");
	for (int i = 0; i < nruns; i++)
		json_method(j, job, &runs[i], pal, voxels, seconds_palette,
			    cpu_palette);
	vd_json_end_object(j);
	return vd_json_close(j);
}

int vd_colorize_run(const struct vd_colorize_job *job)
{
	double t0 = vd_seconds(), seconds_read = 0, seconds_palette = 0;
	double cpu_palette = 0;
	struct cell *cells = NULL;
	size_t ncells = 0;
	struct vd_palette pal = {0};
	struct vd_colour_hist hist = {0};
	struct method_run runs[4] = {{0}};
	int nruns = 0, staged = 0;
	char staging[4096];
	struct vd_chunk_header first = {0};
	uint64_t voxels = 0;
	int err = list_cells(job->indir, &cells, &ncells);
	if (err)
		goto out;
	for (int m = 1; m <= VD_CPACK_AUTO; m++)
		if (job->methods & 1 << m)
			runs[nruns++].method = m;
	if (!nruns) {
		err = vd_fail(VD_ERR_ARG, "no colour method chosen");
		goto out;
	}
	/* the palette's pass: a histogram of every colour, then the global
	 * palette (Dado et al. quantise the whole scene first) */
	if (job->methods & 1 << VD_CPACK_PALETTE) {
		double tp = vd_seconds(), cp = vd_cpu_seconds(), cpu_read = 0;
		if ((err = vd_colour_hist_init(&hist)))
			goto out;
		for (size_t i = 0; i < ncells; i++) {
			struct vd_colours col;
			double tr = vd_seconds(), cr = vd_cpu_seconds();
			if ((err = load_cell(job->indir, &cells[i], &col, &first,
					     i == 0)))
				goto out;
			seconds_read += vd_seconds() - tr;
			cpu_read += vd_cpu_seconds() - cr;
			vd_colour_hist_add(&hist, col.rgb, col.voxels);
			vd_colours_release(&col);
		}
		if ((err = vd_palette_build(&pal, &hist, job->palette_colours,
					    job->lossless, job->threads)))
			goto out;
		seconds_palette = vd_seconds() - tp - seconds_read;
		cpu_palette = vd_cpu_seconds() - cp - cpu_read;
	}
	if ((err = vd_dir_stage(job->outdir, colorize_file, staging,
				sizeof staging)))
		goto out;
	staged = 1;
	for (size_t i = 0; i < ncells; i++) {
		struct vd_colours col;
		double tr = vd_seconds();
		if ((err = load_cell(job->indir, &cells[i], &col, &first, i == 0)))
			goto out;
		seconds_read += vd_seconds() - tr;
		if (i == 0)
			for (int r = 0; r < nruns && !err; r++) {
				char path[4200];
				snprintf(path, sizeof path, "%s/%s", staging,
					 out_names[runs[r].method]);
				struct vd_cpack_params p = {
					.method = runs[r].method, .vbr = job->vbr,
					.autop = job->autop, .palette = &pal,
					.palette_colours = job->palette_colours,
					.threads = job->threads};
				err = vd_cpack_writer_open(&runs[r].w, path, &p,
							   (int)first.levels,
							   &first.transform,
							   job->provenance);
			}
		for (int r = 0; r < nruns && !err; r++) {
			double tm = vd_seconds(), cm = vd_cpu_seconds();
			err = vd_cpack_writer_add(runs[r].w, (int)cells[i].level,
						  cells[i].morton, col.rgb,
						  col.voxels);
			runs[r].seconds += vd_seconds() - tm;
			runs[r].cpu_seconds += vd_cpu_seconds() - cm;
		}
		voxels += col.voxels;
		vd_colours_release(&col);
		if (err)
			goto out;
	}
	for (int r = 0; r < nruns; r++) {
		double tm = vd_seconds(), cm = vd_cpu_seconds();
		int e = vd_cpack_writer_commit(runs[r].w, &runs[r].st);
		runs[r].w = NULL;
		runs[r].seconds += vd_seconds() - tm;
		runs[r].cpu_seconds += vd_cpu_seconds() - cm;
		if (e && !err)
			err = e;
		char path[4200];
		snprintf(path, sizeof path, "%s/%s", staging,
			 out_names[runs[r].method]);
		uint64_t hsh;
		if (!err && (err = vd_file_xxh3(path, &hsh, &runs[r].file_bytes)))
			break;
	}
	if (err)
		goto out;
	{
		char path[4200];
		snprintf(path, sizeof path, "%s/colorize.stats.json", staging);
		if ((err = write_stats(path, job, runs, nruns, &pal, voxels, ncells,
				       &first, seconds_read, seconds_palette,
				       cpu_palette, t0)))
			goto out;
	}
	if ((err = vd_dir_publish(staging, job->outdir)))
		goto out;
	staged = 0;
	if (job->stats_path &&
	    (err = write_stats(job->stats_path, job, runs, nruns, &pal, voxels,
			       ncells, &first, seconds_read, seconds_palette,
				       cpu_palette, t0)))
		goto out;
	if (!job->quiet) {
		fprintf(stderr, "colorize: %llu voxels in %zu cells:",
			(unsigned long long)voxels, ncells);
		for (int r = 0; r < nruns; r++) {
			uint64_t b = runs[r].method == VD_CPACK_RAW
					     ? runs[r].file_bytes
					     : runs[r].st.bytes;
			fprintf(stderr, " %s %.1f%% GMSE %.2f%s",
				vd_cpack_method_name(runs[r].method),
				voxels ? 100.0 * b / (3.0 * voxels) : 0,
				voxels ? (double)runs[r].st.sse / voxels : 0,
				r + 1 < nruns ? "," : "\n");
		}
	}
out:
	for (int r = 0; r < nruns; r++)
		vd_cpack_writer_abort(runs[r].w);
	if (staged)
		vd_dir_abandon(staging);
	for (size_t i = 0; i < ncells; i++)
		free(cells[i].name);
	free(cells);
	vd_palette_release(&pal);
	vd_colour_hist_release(&hist);
	return err;
}
