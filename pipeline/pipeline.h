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
	STAGE_LOSSY,          /* root .dag -> lossy root .dag (one process) */
	STAGE_EDIT,           /* root .dag + edit script -> edited root .dag */
	STAGE_COLORIZE,       /* voxelize's colour chunks -> packed colours */
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
	/* lossy-cluster: the YAML's text of each number, checked, so the
	 * command line (and the resume key) says what the file says */
	char inflation[32], diff_factor[32], max_refs[32];
	/* edit: the script file (relative to the YAML's directory in the
	 * file, resolved here), or its lines given inline (script_text, the
	 * lines joined by newlines; the runner writes them to a file) */
	char script[1024];
	char *script_text;
	/* colorize: one method and its setting, the YAML's text (checked) */
	char method[16], max_error[32], weight_bits[8], palette_colours[16];
	int lossless;
	/* symmetry-merge: the symmetry group, 8 (the SSVDAG, default) or 48
	 * (--group 48, an ssvdag48 root that encode writes as .ssvdag48) */
	int group;
};

/* 1 for the stages whose output is one root DAG chunk (kind dag):
 * svo-to-dag's reduction tree, lossy-cluster and edit. */
int stage_makes_root_dag(enum stage_type t);

struct config {
	char path[1024];
	int version;
	char name[MAX_NAME];
	/* input */
	char mesh[1024];
	char vdb[1024], vdb_grid[MAX_NAME], vdb_mode[32];
	char vdb_colour_grid[MAX_NAME];
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
	char outputs[1024];        /* the output directory; default out/<name> */
	/* keep: given, the outputs of the jobs not in keep_mask (bit d: job
	 * decl d) are intermediates, deleted once every job reading them has
	 * finished (plan.c, "keep:"); the outputs nothing reads are always
	 * kept */
	int keep_given;
	uint32_t keep_mask;
	enum executor { EXECUTOR_LOCAL, EXECUTOR_SLURM } executor;
	struct slurm_opts {
		char partition[MAX_NAME], account[MAX_NAME];
		char time_limit[32];               /* every job's, unless... */
		char stage_time[STAGE_COUNT_][32]; /* ...its stage has one */
		int nargs;
		char args[8][256];                 /* extra sbatch arguments */
		int shared_outputs;                /* the user vouches that
						    * every node sees outputs
						    * (a one-node cluster, a
						    * site's shared /tmp) */
		int bundle_seconds;                /* a bundle's target run
						    * time (default 300) */
		int max_queued;                    /* bundles in Slurm at
						    * once; 0: half of the
						    * cluster's MaxJobCount */
	} slurm;
};

/* Reads and validates `path`. On failure prints one line
 * "voxdag: PATH:LINE:COL: problem" to stderr and returns non-zero. Checks
 * unknown keys, types, ranges, unknown stages, needs that name no job,
 * cycles, the stage graph's shape and the input's existence. */
int config_load(struct config *c, const char *path);

/* Frees what config_load allocated (inline edit scripts); config_load
 * does it itself when it fails. */
void config_release(struct config *c);

/* ------------------------------------------------------------------ jobs */

enum job_state { JOB_PENDING, JOB_RUNNING, JOB_DONE, JOB_SKIPPED, JOB_FAILED,
		 JOB_BLOCKED };

struct job {
	/* strings on the heap: a plan holds up to millions of jobs, so the
	 * struct stays small (a few hundred bytes a job) */
	char *id;                  /* "svdag/cell-L2-3f", for logs and status */
	long slurm_id;             /* with executor slurm: the Slurm job array
				    * of its bundle, or 0 */
	int bundle;                /* ...and the bundle (slurm.c), + 1 */
	int decl;                  /* the job_decl it comes from */
	char **argv;               /* NULL-terminated; argv[0] is the program */
	char *output;              /* the file (or directory) it produces */
	int dir_output;            /* output is a directory with a manifest */
	char *side[2];             /* what the job writes beside its output,
				    * or NULL: a file output's statistics
				    * (OUTPUT.stats.json), an edit job's
				    * colour directory. The key covers them
				    * as it covers the output (plan.c,
				    * job_digest): a missing, empty or
				    * changed one reruns the job */
	int ndeps;
	int *deps;                 /* indices of jobs that must finish first */
	int cell;                  /* a per-cell job of a DAG stage */
	int nwait;                 /* dependencies not finished yet */
	int nbad;                  /* dependencies failed or blocked */
	int nrdeps, caprdeps;
	int *rdeps;                /* jobs that depend on this one */
	int ninputs;
	char **inputs;             /* files whose content the key covers */
	int sources;               /* a mesh's voxelize: the files listed in
				    * output/sources must be unchanged too */
	uint64_t mem_estimate;
	enum job_state state;
	pid_t pid;
	int log_fd;                /* a running local job's log, in memory
				    * (run.c, start_job); -1 otherwise */
	off_t log_head;            /* its first line: the command */
	double start, seconds;
	uint64_t peak_rss;         /* from wait4 */
	double cpu;                /* user + system seconds, from wait4 or
				    * Slurm's end file; -1: not known */
	uint64_t voxels;           /* from the stage's stats, for throughput */
	int logged;                /* its skip is in runner.log */
	int key_absent;            /* job_is_fresh found no key */
	int fresh_checked;         /* ...and nothing can have made one since */
	int adopt_checked;         /* Slurm: looked for an earlier submission */
	int keep_done;             /* keep: deleted its output */
	int revived;               /* keep: its key dropped to write again
				    * what it wrote, which a job needs */
};

struct plan {
	const struct config *cfg;
	char dir[1100];            /* out/<name> */
	int n, cap;
	struct job *jobs;
	int expanded;              /* all cells known (voxelize done) */
	/* jobs by id: open addressing, indices + 1 (0 empty) */
	int *index, index_cap;
	int unfinished[MAX_JOBS_DECL]; /* per declared job: planned, not
					* done or skipped */
	int cells_planned[MAX_JOBS_DECL], merges_planned[MAX_JOBS_DECL];
	int planned[MAX_JOBS_DECL];     /* per declared job: jobs planned */
	int cells_left[MAX_JOBS_DECL];  /* cell jobs not ended */
};

/* Sets j's state, keeping the dependency counters of the jobs that wait
 * for it (nwait, nbad) and the per-declaration counts right. Every change
 * to DONE, SKIPPED, FAILED or BLOCKED goes through here. */
void job_set_state(struct plan *p, struct job *j, enum job_state s);

/* Expands the graph as far as it is known: voxelize jobs always; per-cell
 * jobs and merges once the voxelize output exists (after it finished).
 * Call again when every planned job of a declared job has finished (the
 * only moment something new becomes known): each stage's cells and merges
 * are planned once, so the runner's cost stays linear in the jobs. */
int plan_expand(struct plan *p);
/* The index of the job named id, or -1. */
int plan_find(const struct plan *p, const char *id);
void plan_free(struct plan *p);

/* The hex key of job j: stage version, arguments and the checksums of its
 * inputs. Returns 0 and fills key[17], or non-zero if an input is missing. */
int job_key(const struct job *j, char key[17]);

/* Writes j's key file once it finished: its key, then the digest of its
 * output (a file's XXH3, a directory's manifest's), so that a deleted,
 * truncated or corrupted output is noticed on the next run, then the
 * output's stat signature when it may stand for the digest (plan.c,
 * stat_sig). Returns non-zero, with why in `why`, when the output is not
 * whole or the key cannot be written. */
int job_key_write(const struct job *j, char *why, size_t cap);

/* Forgets j's key (it is about to be rebuilt). */
void job_key_drop(const struct job *j);

/* Loads the key journal DIR/keys (plan.c); with `write`, which only the
 * runner holding DIR/.lock may ask, also opens it for appending. Returns
 * non-zero with a message when it cannot be written. */
int keys_open(const char *dir, int write);

/* Takes DIR/.lock, the runner's: returns its descriptor (the lock is held
 * until the process exits), -1 when another process holds it (*holder:
 * its pid, or 0 when it let go meanwhile) or -2 after saying why it could
 * not be tried (run.c). */
int lock_take(const char *dir, long *holder);
/* The pid of the runner holding DIR/.lock, or 0 (a look, not a take). */
long lock_holder(const char *dir);

/* Makes the keys appended so far durable when a group is due (once a
 * second or every 256 keys), or now with `force` (plan.c says the bound
 * on what a power cut can lose). */
void keys_sync(int force);

/* 1 if j's output exists with a matching key and is still what j wrote
 * (resume). When 0 and the output was there but is damaged, `why` says
 * what is wrong with it ("" otherwise). -1, with `why` set, when the
 * output is there but cannot be read (permissions): rebuilding over it
 * would hide the cause. Sets j->key_absent when j has no key at all
 * (never finished). */
int job_is_fresh(struct job *j, char *why, size_t cap);

/* keep: (plan.c). vd_chunk_read_header, or for a chunk keep: deleted
 * the header its G record kept. */
int plan_chunk_header(const char *path, struct vd_chunk_header *h);

/* With keep:, deletes the intermediates whose readers are all planned
 * and finished: those job `finished` read (-1: all, after the plan grew). */
void keep_sweep(struct plan *p, int finished);

/* 1 when job j needs a file keep: deleted: the job that wrote it loses
 * its key (it runs again when the run starts over), and `why` says so. */
int keep_revive(struct plan *p, struct job *j, char *why, size_t cap);

/* What j's outputs take on disk now (allocated bytes), and how many files
 * keep: has deleted in the outputs: for `voxdag plan`. */
uint64_t job_disk_bytes(const struct job *j);
size_t keep_gone_files(void);

/* ------------------------------------------------------------- running */

struct run_opts {
	int quiet;
	int dry;   /* plan only */
};

/* Runs the plan; returns the exit code (0, 1), or RUN_AGAIN when keep:
 * deleted a file a job needs: the run starts over (main.c), and the job
 * that wrote it, its key dropped, runs again first. */
#define RUN_AGAIN 3
int run_pipeline(struct plan *p, const struct run_opts *o);

/* How a job ended, from wait4 (local) or its status file (Slurm). */
struct job_end {
	int exited, code, signal;  /* exited: code valid; else signal (or 0) */
	double seconds;
	uint64_t peak_rss;         /* bytes */
	double cpu;                /* user + system seconds; -1: not known */
	char reason[160];          /* Slurm's state and reason when it failed */
};

/* ---------------------------------------------------- the Slurm executor
 * (slurm.c). The runner stays the driver: it packs the jobs that are ready
 * (their dependencies done, or themselves in Slurm) into bundles, each
 * bundle a task of a Slurm job array that runs its jobs in sequence
 * (`voxdag job-exec LIST`), polls Slurm once per poll for the
 * bundles that left the queue, and on a restart adopts the jobs of bundles
 * still queued or running. Each job still writes DIR/slurm/<job>.end and
 * DIR/logs/<job>.log. */

/* Checks, before anything is submitted: sbatch on PATH, the controller
 * answers, the partition exists, the output directory is not node-local;
 * reads the cluster's limits and what an earlier driver submitted. Prints
 * one line and returns non-zero on a problem. */
int slurm_preflight(const struct plan *p);

/* Marks j, ready, for the next slurm_flush (its state stays pending). */
void slurm_want(const struct plan *p, struct job *j);

/* Submits the jobs slurm_want marked since the last call, as bundles
 * within the queue's cap: those submitted become JOB_RUNNING (their count
 * is returned), those sbatch refused JOB_FAILED (counted in *failed, each
 * array said on stderr), the rest stay pending for a later call. */
int slurm_flush(struct plan *p, int *failed);

/* If a previous driver submitted j with the same command and Slurm still
 * has its bundle, or the bundle wrote j's end while no driver watched:
 * sets j->slurm_id and j->bundle and returns 1 (the caller then treats j
 * as running). */
int slurm_adopt(const struct plan *p, struct job *j);

/* Looks for a running job that ended. Returns its index and fills *end,
 * or -1 when none has (yet). Reads the end files of a bundle once it left
 * its .done (job-exec went through its list) or left the queue (squeue,
 * every few seconds, one call for all); a job without one (cancelled, out
 * of memory, time limit, node failure) gets Slurm's reason for its
 * bundle. */
int slurm_reap(const struct plan *p, struct job_end *end);

/* 1 while ends read by the last poll are not all taken by slurm_reap. */
int slurm_ends_waiting(void);

/* j is no longer waited for in its bundle (blocked by a failed
 * dependency: job-exec skips it); a bundle left with nothing to wait for
 * is cancelled in Slurm. */
void slurm_cancel(const struct plan *p, struct job *j);

/* j's end is recorded: the same bookkeeping as slurm_cancel. */
void slurm_forget(const struct plan *p, struct job *j);

/* "123_4", the Slurm task of j's bundle, or "". */
const char *slurm_bundle_name(const struct job *j);

/* The CPU seconds of the stages whose ends the driver read. */
double slurm_stages_cpu(void);

/* At the end of a run (nothing of ours in Slurm): removes the bundles'
 * lists and records. */
void slurm_done(const struct plan *p);

/* `voxdag job-exec LIST`, what each bundle runs: each job of the
 * list in turn, skipping one whose dependency's end does not say success,
 * its output appended to its log, then its end file (exit status,
 * seconds, peak memory) written atomically. */
int slurm_job_exec(int argc, char **argv);

/* The run's log, <outputs>/logs/runner.log (log.c, below the driver and
 * the executors that write to it): run_log_open appends to `path` and
 * returns its descriptor (for a signal handler's write(2)), -1 when it
 * cannot be opened (then run_log writes nothing). run_log: one line,
 * stamped with the local time, kept in memory until run_log_flush (before
 * the driver waits; at the exit too) or run_log_flush_signal (the same,
 * from a signal's handler). */
int run_log_open(const char *path);
void run_log(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
void run_log_flush(void);
void run_log_flush_signal(void);

/* `voxdag view` (view.c): argv[0] is "view"; serves an output directory
 * and the browser viewer on 127.0.0.1 until interrupted. Returns the exit
 * status. */
int view_main(int argc, char **argv);

/* For `voxdag status`: the Slurm state of j ("PENDING", "RUNNING", ...)
 * when a driver submitted it, else NULL. */
const char *slurm_state(const struct plan *p, const struct job *j,
			char *buf, size_t cap);
int report_write(const struct plan *p);
int status_print(struct plan *p);

/* Paths */
void path_join(char *buf, size_t cap, const char *a, const char *b);
int mkdir_p(const char *path);

#endif
