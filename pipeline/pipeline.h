/* pipeline.h - the runner's internal interfaces (pipeline/ is one program,
 * `voxdag`; nothing here is part of libvoxdag).
 *
 * A pipeline is a YAML file (schemas/pipeline.md, pipeline.schema.json):
 * an input, a grid depth, resources and a graph of named jobs, each running
 * one stage. The runner expands the graph into processes (one per cell for
 * per-cell stages, a reduction tree of merges up to the root, one for
 * global stages), runs them within the job and memory limits, skips what a
 * previous run finished (each output carries a key of its inputs), and
 * writes the report.
 */
#ifndef VOXDAG_PIPELINE_H
#define VOXDAG_PIPELINE_H

#include "voxdag.h"

#include <stdint.h>
#include <sys/types.h>

#define PIPELINE_VERSION 1
#define MAX_NAME 64
#define MAX_JOBS_DECL 32
#define MAX_NEEDS 8
#define MAX_RES 24

/* What a stage needs and produces, as the runner knows it. */
enum stage_type {
	STAGE_VOXELIZE,       /* mesh or vdb -> SVO chunks (one process) */
	STAGE_SVO_TO_DAG,     /* per cell + merge tree -> root .dag */
	STAGE_SYMMETRY_MERGE, /* per cell + merge tree -> root .ssvdag */
	STAGE_ENCODE,         /* roots -> encodings and tables */
	STAGE_RENDER,         /* an encoding -> a picture for the report */
	STAGE_COUNT_
};

struct stage_info {
	const char *name;      /* as in the YAML and out/bin/ */
	enum stage_type type;
	int min_needs, max_needs;
};

const struct stage_info *stage_lookup(const char *name);

struct job_decl {
	char name[MAX_NAME];
	const struct stage_info *stage;
	int nneeds;
	int needs[MAX_NEEDS];            /* indices into config.jobs */
	char needs_name[MAX_NEEDS][MAX_NAME];
	int line, column;                /* where declared, for errors */
};

struct config {
	char path[1024];
	int version;
	char name[MAX_NAME];
	/* input */
	char mesh[1024];
	char vdb[1024], vdb_grid[MAX_NAME], vdb_mode[32];
	char fetch[1024];          /* command that fetches a missing input */
	int levels;
	int chunk_level;           /* -1: auto */
	int nres;
	int resolutions[MAX_RES];  /* report rows */
	/* resources */
	int jobs;                  /* processes at once */
	uint64_t mem_budget;       /* sum of running estimates */
	uint64_t job_mem_budget;   /* each process's --mem-budget */
	int threads;               /* each process's --threads */
	int njobs;
	struct job_decl jobs_decl[MAX_JOBS_DECL];
	char title[256];
};

/* Reads and validates `path`. On failure prints one line
 * "voxdag: PATH:LINE:COL: problem" to stderr and returns non-zero. Checks
 * unknown keys, types, ranges, unknown stages, needs that name no job,
 * cycles, the stage graph's shape and the input's existence. */
int config_load(struct config *c, const char *path);

/* ------------------------------------------------------------------ jobs */

enum job_state { JOB_PENDING, JOB_RUNNING, JOB_DONE, JOB_SKIPPED, JOB_FAILED,
		 JOB_BLOCKED };

struct job {
	char id[160];              /* "svdag/cell-L2-3f", for logs and status */
	int decl;                  /* the job_decl it comes from */
	char **argv;               /* NULL-terminated; argv[0] is the program */
	char output[1024];         /* the file (or directory) it produces */
	char key_path[1100];       /* output + ".key" */
	int ndeps;
	int *deps;                 /* indices of jobs that must finish first */
	int ninputs;
	char **inputs;             /* files whose content the key covers */
	uint64_t mem_estimate;
	enum job_state state;
	pid_t pid;
	double start, seconds;
	uint64_t peak_rss;         /* from wait4 */
	uint64_t voxels;           /* from the stage's stats, for throughput */
	int logged;                /* its skip is in runner.log */
};

struct plan {
	const struct config *cfg;
	char dir[1100];            /* out/<name> */
	int n, cap;
	struct job *jobs;
	int expanded;              /* all cells known (voxelize done) */
};

/* Expands the graph as far as it is known: voxelize jobs always; per-cell
 * jobs and merges once the voxelize output exists (after it finished).
 * Call again after jobs finish to add what became known. */
int plan_expand(struct plan *p);
void plan_free(struct plan *p);

/* The hex key of job j: stage version, arguments and the checksums of its
 * inputs. Returns 0 and fills key[17], or non-zero if an input is missing. */
int job_key(const struct job *j, char key[17]);

/* 1 if the output of j exists with a matching key (resume). */
int job_is_fresh(const struct job *j);

/* ------------------------------------------------------------- running */

struct run_opts {
	int quiet;
	int dry;   /* plan only */
};

int run_pipeline(struct plan *p, const struct run_opts *o);
int report_write(const struct plan *p);
int status_print(struct plan *p);

/* Paths */
void path_join(char *buf, size_t cap, const char *a, const char *b);
int mkdir_p(const char *path);

#endif
