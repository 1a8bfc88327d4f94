/* slurm.c - the Slurm executor: the same job graph, its jobs packed into
 * bundles that Slurm runs as the tasks of job arrays.
 *
 * The runner stays the driver and Slurm only runs processes, so planning,
 * keys, resume and the report are the local ones. What Slurm adds:
 * - bundles: the ready jobs of one declared job are cut into bundles of
 *   about `slurm.bundle_seconds` each (from the jobs' estimates, corrected
 *   by what the stage's jobs really took so far), at least as many as the
 *   partition has CPUs for while each keeps a tenth of that target, and a
 *   bundle's one task runs its jobs in sequence (`voxdag job-exec
 *   FILE`). Every bundle submitted at once goes out in one `sbatch
 *   --array=0-N`, within MaxArraySize, with the largest memory estimate and
 *   thread count of its jobs, and `afterany` on the arrays that hold jobs
 *   it needs; the bundles in Slurm (queued or running) never exceed
 *   `slurm.max_queued`, by default half the controller's MaxJobCount.
 *   `afterany`, not `afterok`: a bundle whose job failed still ran the
 *   others, and a job whose dependency did not succeed is skipped by
 *   job-exec itself (it reads the dependency's end file), so what does not
 *   depend on a failure goes on;
 * - ends: job-exec writes DIR/slurm/<job>.end (exit status, seconds, peak
 *   memory) atomically when each stage exits, and the job's output into
 *   DIR/logs/<job>.log (appended: one "$ command" line per run). The driver
 *   asks `squeue` once per poll which of its array tasks Slurm still has,
 *   and reads the end files of a bundle only when it left the queue, so
 *   its cost is per bundle, not per job; a job of a bundle that left
 *   without its end file was cancelled, ran out of memory or time (the
 *   whole array or its task alone), and `scontrol show job` says which;
 * - adoption: each submission leaves DIR/slurm/<bundle>.<task>.list (its
 *   jobs and a hash of each command) and DIR/slurm/<bundle>.sub (the array's
 *   Slurm id, written once sbatch answered). A restarted driver takes over
 *   a job whose bundle Slurm still has, or whose end file its bundle wrote
 *   while no driver watched, instead of submitting it again. job-exec runs
 *   nothing until the .sub names its own array: a bundle whose driver died
 *   between sbatch and that write runs nothing, and its jobs are submitted
 *   again by the next driver (never twice). */
#include "pipeline.h"
#include "io/publish.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <math.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/vfs.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#include <xxhash.h>

#define END_MAGIC "voxdag-job-end 1"
#define QUERY_TIMEOUT 30 /* seconds for sbatch, squeue, scontrol */

/* The CPU seconds of the stages whose ends were read (for runner.log). */
static double stages_cpu_seen;

double slurm_stages_cpu(void)
{
	return stages_cpu_seen;
}

/* ------------------------------------------------------------ commands */

/* Runs argv (searched on PATH) with no standard input, its standard output
 * into out (NUL-terminated, cut at cap) and its standard error into err.
 * Returns its exit status, 124 after timeout_s seconds (it is killed), 127
 * (why in err) when it could not be started, or -1 without pipes. Started
 * with posix_spawn, not fork: a fork copied the driver's page tables (its
 * plan of every job), then threw them away at the exec, for each squeue:
 * a twentieth of the driver's CPU. */
static int run_capture(char *const argv[], char *out, size_t cap, char *err,
		       size_t ecap, int timeout_s)
{
	int po[2], pe[2];
	out[0] = err[0] = 0;
	if (pipe2(po, O_CLOEXEC) != 0)
		return -1;
	if (pipe2(pe, O_CLOEXEC) != 0) {
		close(po[0]);
		close(po[1]);
		return -1;
	}
	posix_spawn_file_actions_t fa;
	pid_t pid;
	int rc = posix_spawn_file_actions_init(&fa);
	if (rc == 0) {
		/* dup2 clears close-on-exec on the copies */
		posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
		posix_spawn_file_actions_adddup2(&fa, po[1], 1);
		posix_spawn_file_actions_adddup2(&fa, pe[1], 2);
		rc = posix_spawnp(&pid, argv[0], &fa, NULL, argv, environ);
		posix_spawn_file_actions_destroy(&fa);
	}
	close(po[1]);
	close(pe[1]);
	if (rc != 0) { /* as a child that could not exec said it */
		close(po[0]);
		close(pe[0]);
		snprintf(err, ecap, "%s: %s", argv[0], strerror(rc));
		return 127;
	}
	struct pollfd fds[2] = {{po[0], POLLIN, 0}, {pe[0], POLLIN, 0}};
	size_t n[2] = {0, 0}, caps[2] = {cap, ecap};
	char *bufs[2] = {out, err};
	int open_fds = 2, timed_out = 0;
	double deadline = vd_seconds() + timeout_s;
	while (open_fds > 0) {
		int left = (int)((deadline - vd_seconds()) * 1000);
		if (left <= 0) {
			timed_out = 1;
			break;
		}
		if (poll(fds, 2, left) < 0 && errno != EINTR)
			break;
		for (int i = 0; i < 2; i++) {
			if (fds[i].fd < 0 || !(fds[i].revents & (POLLIN | POLLHUP)))
				continue;
			char tmp[4096];
			ssize_t got = read(fds[i].fd, tmp, sizeof tmp);
			if (got <= 0) {
				close(fds[i].fd);
				fds[i].fd = -1;
				open_fds--;
				continue;
			}
			size_t room = caps[i] - 1 - n[i];
			size_t take = (size_t)got < room ? (size_t)got : room;
			memcpy(bufs[i] + n[i], tmp, take);
			n[i] += take;
			bufs[i][n[i]] = 0;
		}
	}
	for (int i = 0; i < 2; i++)
		if (fds[i].fd >= 0)
			close(fds[i].fd);
	if (timed_out)
		kill(pid, SIGKILL);
	int status;
	while (waitpid(pid, &status, 0) < 0 && errno == EINTR)
		;
	if (timed_out)
		return 124;
	return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

/* `sinfo -h -o FMT`, of the pipeline's partition when it names one:
 * run_capture's status. */
static int sinfo(const struct config *c, const char *fmt, char *out,
		 size_t cap, char *err, size_t ecap)
{
	char part[MAX_NAME + 4], f[16];
	snprintf(part, sizeof part, "%s", c->slurm.partition);
	snprintf(f, sizeof f, "%s", fmt);
	char *argv[] = {"sinfo", "-h", "-o", f, NULL, NULL, NULL};
	if (*part) {
		argv[4] = "-p";
		argv[5] = part;
	}
	return run_capture(argv, out, cap, err, ecap, QUERY_TIMEOUT);
}

/* The first line of s, for one-line messages. */
static const char *first_line(char *s)
{
	s[strcspn(s, "\n")] = 0;
	return s;
}

static int on_path(const char *prog)
{
	const char *path = getenv("PATH");
	if (!path)
		return 0;
	char dir[PATH_MAX + 64];
	while (*path) {
		size_t len = strcspn(path, ":");
		snprintf(dir, sizeof dir, "%.*s/%s", (int)len, path, prog);
		if (len && access(dir, X_OK) == 0)
			return 1;
		path += len + (path[len] == ':');
	}
	return 0;
}

/* --------------------------------------------------------------- files */

static void job_file(const struct plan *p, const struct job *j,
		     const char *sub, const char *ext, char *buf, size_t cap)
{
	char id[256];
	snprintf(id, sizeof id, "%s", j->id);
	for (char *c = id; *c; c++)
		if (*c == '/')
			*c = '.';
	snprintf(buf, cap, "%s/%s/%s.%s", p->dir, sub, id, ext);
}

static uint64_t argv_hash(const struct job *j)
{
	XXH3_state_t *s = XXH3_createState();
	if (!s)
		return 0;
	XXH3_64bits_reset(s);
	for (int i = 0; j->argv[i]; i++)
		XXH3_64bits_update(s, j->argv[i], strlen(j->argv[i]) + 1);
	uint64_t h = XXH3_64bits_digest(s);
	XXH3_freeState(s);
	return h;
}

/* Writes text to path durably (vd_atomic_*); -1 with errno on failure. */
static int write_atomic(const char *path, const char *text)
{
	struct vd_atomic a;
	if (vd_atomic_open(&a, path) != VD_OK)
		return -1;
	if (fputs(text, a.f) < 0) {
		vd_atomic_abort(&a);
		return -1;
	}
	return vd_atomic_commit(&a) == VD_OK ? 0 : -1;
}

/* Writes text to path whole or not at all (a temporary, then rename),
 * without fsync: an end file is a message to the driver, not a record
 * that must outlive a power cut (one lost with the cluster's power makes
 * its job run again; its output was published durably by the stage). Two
 * fsyncs per job were most of a bundle's own cost. -1 with errno. */
static int write_whole(const char *path, const char *text)
{
	char tmp[1400];
	snprintf(tmp, sizeof tmp, "%s.tmp.%ld", path, (long)getpid());
	FILE *f = fopen(tmp, "w");
	if (!f)
		return -1;
	int bad = fputs(text, f) < 0;
	if ((fclose(f) != 0) | bad || rename(tmp, path) != 0) {
		int e = errno;
		unlink(tmp);
		errno = e;
		return -1;
	}
	return 0;
}

/* Reads an end file; 0 when it is complete and well formed. One read,
 * no stdio: the driver reads one per job. */
static int read_end(const char *path, struct job_end *e)
{
	memset(e, 0, sizeof *e);
	int fd = vd_open_read(path);
	if (fd < 0)
		return -1;
	char text[512];
	ssize_t n = read(fd, text, sizeof text - 1);
	close(fd);
	if (n <= 0)
		return -1;
	text[n] = 0;
	unsigned long long rss = 0;
	int at = 0;
	int ok = !strncmp(text, END_MAGIC "\n", sizeof END_MAGIC) &&
		 sscanf(text + sizeof END_MAGIC, "exit %d\nsignal %d\nseconds "
			"%lf\npeak_rss %llu\n%n", &e->code, &e->signal,
			&e->seconds, &rss, &at) == 4 && at > 0;
	double cpu = -1;
	if (ok && sscanf(text + sizeof END_MAGIC + at, "cpu %lf", &cpu) == 1)
		stages_cpu_seen += cpu; /* since bundles */
	e->cpu = cpu;
	e->exited = e->signal == 0;
	e->peak_rss = rss;
	return ok ? 0 : -1;
}

/* ------------------------------------------------------- driver state */

/* One array task: the jobs it runs in sequence. */
struct bundle {
	char sid[48];     /* Slurm's id of the task, "123_4" */
	long array_id;    /* 123 */
	char name[48];    /* b<start>-<pid>-<n>: its files' names */
	int task;
	int *jobs, njobs; /* indices into the plan (jobs of an earlier
			   * driver: -1 until adopted) */
	char **ids;       /* an earlier driver's bundle: its jobs' ids */
	uint64_t *hashes; /* ...and their commands' hashes */
	int left;         /* its jobs the driver still waits for */
	int ended;        /* its ends were read (its .done, or gone) */
	int gone;         /* Slurm no longer lists it */
	int reason_asked;
	char state[24];   /* an earlier driver's: squeue's state at load */
	char reason[160];
};

static struct bundle *bundles;
static int nbundles, capbundles;
static int live_tasks;          /* bundles Slurm still lists */
static int starved;             /* ready jobs wait for room in the queue */
static struct slurm_site {
	long max_job_count, max_array_size, min_job_age;
	int cpus;                     /* the partition's, all nodes */
	int max_queued;
} site;
static long sub_start;          /* names of this driver's submissions */
static int sub_count;
static int previous_loaded;

/* The end files DIR/slurm held when the driver started (names, sorted):
 * the only ones besides an earlier driver's jobs' that can be stale when
 * a job is submitted, so the others are not unlinked one by one. */
static char **old_ends;
static int nold_ends;

/* Ready jobs waiting for slurm_flush. */
static int *wanted, nwanted, capwanted;

/* Ends read, not taken by slurm_reap yet (in bundle order, so a failed
 * dependency is recorded before the jobs that were skipped for it). */
static struct end_rec {
	int job;
	struct job_end e;
} *ends;
static int nends, headends, capends;
static double next_poll, next_squeue, last_squeue;

/* Per declared job, then for cell jobs and for the others of every
 * declared job: the jobs' seconds against their priors, to correct the
 * estimates of the next bundles. */
static double seen_seconds[MAX_JOBS_DECL + 2], seen_prior[MAX_JOBS_DECL + 2];

static void *grow(void *q, int *cap, int need, size_t size)
{
	if (need <= *cap)
		return q;
	int c = *cap ? *cap : 16;
	while (c < need)
		c *= 2;
	void *r = realloc(q, (size_t)c * size);
	if (!r) {
		fprintf(stderr, "voxdag: out of memory\n");
		exit(1);
	}
	*cap = c;
	return r;
}

static struct bundle *bundle_add(void)
{
	bundles = grow(bundles, &capbundles, nbundles + 1, sizeof *bundles);
	struct bundle *b = &bundles[nbundles++];
	memset(b, 0, sizeof *b);
	return b;
}

static void push_end(int job, const struct job_end *e)
{
	if (headends == nends)
		headends = nends = 0;
	ends = grow(ends, &capends, nends + 1, sizeof *ends);
	ends[nends].job = job;
	ends[nends].e = *e;
	nends++;
}

int slurm_ends_waiting(void)
{
	return headends < nends;
}

/* The live array tasks of this user: one squeue, sorted ids ("123_4", or
 * "123" for a job that is no array), each followed by its state; NULL
 * when squeue does not answer. *n: how many. */
struct live {
	char id[48];
	char state[24];
};

static int cmp_live(const void *a, const void *b)
{
	return strcmp(((const struct live *)a)->id, ((const struct live *)b)->id);
}

static struct live *squeue_live(int *n)
{
	size_t cap = 16u << 20;
	char *out = malloc(cap), err[1024];
	char *argv[] = {"squeue", "--me", "-h", "-r", "-o", "%i %T", NULL};
	*n = 0;
	if (!out)
		return NULL;
	if (run_capture(argv, out, cap, err, sizeof err, QUERY_TIMEOUT) != 0) {
		free(out);
		return NULL;
	}
	int capl = 0;
	struct live *l = NULL;
	for (char *line = out; *line;) {
		char *nl = strchr(line, '\n');
		if (nl)
			*nl = 0;
		struct live x = {"", ""};
		if (sscanf(line, "%47s %23s", x.id, x.state) >= 1) {
			l = grow(l, &capl, *n + 1, sizeof *l);
			l[(*n)++] = x;
		}
		if (!nl)
			break;
		line = nl + 1;
	}
	free(out);
	if (!l)
		l = calloc(1, sizeof *l);
	if (l)
		qsort(l, (size_t)*n, sizeof *l, cmp_live);
	return l;
}

static const struct live *live_find(const struct live *l, int n,
				    const char *sid)
{
	struct live key;
	snprintf(key.id, sizeof key.id, "%s", sid);
	return bsearch(&key, l, (size_t)n, sizeof *l, cmp_live);
}

/* What Slurm says of a task that left the queue before its jobs ended;
 * `log`: the task's own log, which Slurm creates when the task starts. */
static void slurm_reason(const char *sid, const char *log, char *buf,
			 size_t cap)
{
	char out[8192], err[512], id[48];
	snprintf(id, sizeof id, "%s", sid);
	char *argv[] = {"scontrol", "-o", "show", "job", id, NULL};
	if (run_capture(argv, out, sizeof out, err, sizeof err,
			QUERY_TIMEOUT) != 0) {
		/* a pending array task cancelled alone leaves no record */
		if (access(log, F_OK) != 0)
			snprintf(buf, cap, "Slurm job %s left the queue before "
				 "it started (cancelled while pending; scontrol "
				 "no longer knows it)", sid);
		else
			snprintf(buf, cap, "Slurm job %s left the queue without "
				 "an end record (no longer known to scontrol)",
				 sid);
		return;
	}
	char state[64] = "?", reason[96] = "?", code[32] = "?";
	const char *s;
	if ((s = strstr(out, "JobState=")))
		sscanf(s, "JobState=%63s", state);
	if ((s = strstr(out, " Reason=")))
		sscanf(s, " Reason=%95s", reason);
	if ((s = strstr(out, " ExitCode=")))
		sscanf(s, " ExitCode=%31s", code);
	snprintf(buf, cap, "Slurm job %s: state %s, reason %s, exit code %s",
		 sid, state, reason, code);
}

/* ------------------------------------------------------------- lists
 * A bundle's list, DIR/slurm/<bundle>.<task>.list, one field a line:
 *   voxdag-job-list 1
 *   sub PATH            the submission's record (job-exec waits for it)
 *   job ID HASH         then, for that job:
 *   end PATH              its end file
 *   log PATH              its log (appended)
 *   after PATH            an end file that must say exit 0 (0 or more)
 *   arg TEXT              its command line, one argument a line
 *   run                   the end of the job
 * Arguments with a newline cannot be written; the driver refuses them. */
#define LIST_MAGIC "voxdag-job-list 1"

static int list_write(const struct plan *p, const struct bundle *b,
		      const char *sub, char *why, size_t cap)
{
	char path[1300], end[1300], log[1300];
	snprintf(path, sizeof path, "%s/slurm/%s.%d.list", p->dir, b->name,
		 b->task);
	FILE *f = fopen(path, "w");
	if (!f) {
		snprintf(why, cap, "cannot create '%s': %s", path, strerror(errno));
		return -1;
	}
	fprintf(f, LIST_MAGIC "\nsub %s\n", sub);
	for (int k = 0; k < b->njobs; k++) {
		const struct job *j = &p->jobs[b->jobs[k]];
		job_file(p, j, "slurm", "end", end, sizeof end);
		job_file(p, j, "logs", "log", log, sizeof log);
		fprintf(f, "job %s %016llx\nend %s\nlog %s\n", j->id,
			(unsigned long long)argv_hash(j), end, log);
		for (int d = 0; d < j->ndeps; d++) {
			const struct job *dj = &p->jobs[j->deps[d]];
			if (dj->state == JOB_RUNNING && dj->slurm_id > 0) {
				job_file(p, dj, "slurm", "end", end, sizeof end);
				fprintf(f, "after %s\n", end);
			}
		}
		for (int i = 0; j->argv[i]; i++) {
			if (strchr(j->argv[i], '\n')) {
				fclose(f);
				unlink(path);
				snprintf(why, cap, "job %s: an argument holds a "
					 "newline", j->id);
				return -1;
			}
			fprintf(f, "arg %s\n", j->argv[i]);
		}
		fputs("run\n", f);
	}
	if (ferror(f) | (fclose(f) != 0)) {
		snprintf(why, cap, "cannot write '%s': %s", path, strerror(errno));
		unlink(path);
		return -1;
	}
	return 0;
}

/* One job of a list as job-exec and the adoption read it. */
struct list_job {
	char *id, *end, *log;
	uint64_t hash;
	char **afters;
	int nafters;
	char **argv;
	int argc;
};

static void list_free(struct list_job *l, int n)
{
	for (int k = 0; k < n; k++) {
		free(l[k].id), free(l[k].end), free(l[k].log);
		for (int i = 0; i < l[k].nafters; i++)
			free(l[k].afters[i]);
		for (int i = 0; i < l[k].argc; i++)
			free(l[k].argv[i]);
		free(l[k].afters), free(l[k].argv);
	}
	free(l);
}

static char *dup_or_die(const char *s)
{
	char *d = strdup(s);
	if (!d) {
		fprintf(stderr, "voxdag: out of memory\n");
		exit(1);
	}
	return d;
}

/* Reads a list: its jobs into *out (n of them), the submission record's
 * path into sub. Returns the count, or -1 when the file is not a whole
 * list (line: the bad line's number, 0 when it cannot be opened). */
static int list_read(const char *path, char *sub, size_t subcap,
		     struct list_job **out, int *line)
{
	FILE *f = fopen(path, "r");
	*out = NULL;
	*line = 0;
	if (!f)
		return -1;
	struct list_job *l = NULL;
	int n = 0, cap = 0, ok = 1, in_job = 0, done = 0;
	int acap = 0, vcap = 0;
	char *buf = NULL;
	size_t bcap = 0;
	ssize_t len;
	while (ok && (len = getline(&buf, &bcap, f)) > 0) {
		(*line)++;
		if (buf[len - 1] != '\n') {
			ok = 0;
			break;
		}
		buf[--len] = 0;
		char *v = strchr(buf, ' ');
		if (v)
			*v++ = 0;
		struct list_job *j = in_job ? &l[n - 1] : NULL;
		if (*line == 1) {
			ok = v && !strcmp(buf, "voxdag-job-list") && !strcmp(v, "1");
		} else if (!strcmp(buf, "sub") && v && !in_job) {
			snprintf(sub, subcap, "%s", v);
		} else if (!strcmp(buf, "job") && v && !in_job) {
			char *h = strrchr(v, ' ');
			ok = h != NULL;
			if (ok) {
				*h++ = 0;
				l = grow(l, &cap, n + 1, sizeof *l);
				memset(&l[n], 0, sizeof *l);
				l[n].id = dup_or_die(v);
				l[n].hash = strtoull(h, NULL, 16);
				n++;
				in_job = 1;
				acap = vcap = 0;
			}
		} else if (j && !strcmp(buf, "end") && v) {
			free(j->end);
			j->end = dup_or_die(v);
		} else if (j && !strcmp(buf, "log") && v) {
			free(j->log);
			j->log = dup_or_die(v);
		} else if (j && !strcmp(buf, "after") && v) {
			j->afters = grow(j->afters, &acap, j->nafters + 1,
					 sizeof *j->afters);
			j->afters[j->nafters++] = dup_or_die(v);
		} else if (j && !strcmp(buf, "arg") && v) {
			j->argv = grow(j->argv, &vcap, j->argc + 2, sizeof *j->argv);
			j->argv[j->argc++] = dup_or_die(v);
			j->argv[j->argc] = NULL;
		} else if (j && !strcmp(buf, "run") && !v) {
			ok = j->end && j->log && j->argc > 0;
			in_job = 0;
			done = 1;
		} else {
			ok = 0;
		}
	}
	free(buf);
	fclose(f);
	if (!ok || in_job || !done) {
		list_free(l, n);
		if (!*line)
			*line = 1;
		return -1;
	}
	*out = l;
	return n;
}

/* ------------------------------------------------ an earlier driver's */

static int cmp_str(const void *a, const void *b)
{
	return strcmp(*(char *const *)a, *(char *const *)b);
}

static void prev_index_build(void);

/* Loads the submissions an earlier driver left (DIR/slurm/<bundle>.sub and their
 * lists) as bundles whose jobs are known by id, with Slurm's word on each
 * task: one squeue in all. Returns 0, or -1 after saying why (squeue does
 * not answer: adopting nothing could run a job twice). */
static int load_previous(const struct plan *p)
{
	if (previous_loaded)
		return 0;
	char dir[1200];
	snprintf(dir, sizeof dir, "%s/slurm", p->dir);
	DIR *d = opendir(dir);
	if (!d) {
		previous_loaded = 1;
		return 0;
	}
	struct dirent *e;
	int nlive = 0, asked = 0;
	int capold = 0;
	struct live *live = NULL;
	while ((e = readdir(d))) {
		size_t len = strlen(e->d_name);
		if (len > 4 && !strcmp(e->d_name + len - 4, ".end")) {
			old_ends = grow(old_ends, &capold, nold_ends + 1,
					sizeof *old_ends);
			old_ends[nold_ends++] = dup_or_die(e->d_name);
			continue;
		}
		if (len < 6 || strcmp(e->d_name + len - 5, ".list") != 0)
			continue;
		char path[1500], sub[1300] = "", name[48];
		snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
		int task = -1;
		char *dot = memchr(e->d_name, '.', len);
		if (!dot || (size_t)(dot - e->d_name) >= sizeof name)
			continue;
		snprintf(name, sizeof name, "%.*s", (int)(dot - e->d_name), e->d_name);
		task = atoi(dot + 1);
		struct list_job *l;
		int line, n = list_read(path, sub, sizeof sub, &l, &line);
		FILE *sf = n > 0 ? fopen(sub, "r") : NULL;
		long aid = 0;
		int ok = sf && fscanf(sf, "%ld", &aid) == 1 && aid > 0;
		if (sf)
			fclose(sf);
		if (!ok) { /* never submitted, or not whole: nothing runs it */
			list_free(l, n > 0 ? n : 0);
			continue;
		}
		if (!asked) {
			asked = 1;
			live = squeue_live(&nlive);
			if (!live) {
				fprintf(stderr, "voxdag: executor slurm: squeue "
					"does not answer, so the jobs an earlier "
					"driver submitted cannot be adopted; try "
					"again when it does\n");
				list_free(l, n);
				closedir(d);
				return -1;
			}
		}
		struct bundle *b = bundle_add();
		snprintf(b->name, sizeof b->name, "%s", name);
		b->task = task;
		b->array_id = aid;
		snprintf(b->sid, sizeof b->sid, "%ld_%d", aid, task);
		const struct live *lv = live_find(live, nlive, b->sid);
		char done[1500];
		snprintf(done, sizeof done, "%s/%s.%d.done", dir, name, task);
		b->gone = !lv;
		b->ended = b->gone || access(done, F_OK) == 0;
		snprintf(b->state, sizeof b->state, "%s", lv ? lv->state : "");
		live_tasks += !b->gone;
		b->njobs = n;
		b->jobs = malloc((size_t)n * sizeof *b->jobs);
		b->ids = malloc((size_t)n * sizeof *b->ids);
		b->hashes = malloc((size_t)n * sizeof *b->hashes);
		if (!b->jobs || !b->ids || !b->hashes) {
			fprintf(stderr, "voxdag: out of memory\n");
			exit(1);
		}
		for (int k = 0; k < n; k++) {
			b->jobs[k] = -1;
			b->ids[k] = l[k].id;
			l[k].id = NULL;
			b->hashes[k] = l[k].hash;
		}
		list_free(l, n);
	}
	closedir(d);
	free(live);
	if (nold_ends)
		qsort(old_ends, (size_t)nold_ends, sizeof *old_ends, cmp_str);
	prev_index_build();
	previous_loaded = 1;
	return 0;
}

/* The earlier driver's jobs by id: open addressing over (bundle, slot)
 * pairs, built once after load_previous. */
static struct prev_slot {
	int b, k; /* b + 1; 0 empty */
} *prev_index;
static size_t prev_cap;

static void prev_index_build(void)
{
	size_t n = 0;
	for (int b = 0; b < nbundles; b++)
		n += bundles[b].ids ? (size_t)bundles[b].njobs : 0;
	if (!n)
		return;
	prev_cap = 16;
	while (prev_cap < 2 * n)
		prev_cap *= 2;
	prev_index = calloc(prev_cap, sizeof *prev_index);
	if (!prev_index) {
		fprintf(stderr, "voxdag: out of memory\n");
		exit(1);
	}
	for (int b = 0; b < nbundles; b++)
		for (int k = 0; bundles[b].ids && k < bundles[b].njobs; k++) {
			const char *id = bundles[b].ids[k];
			size_t h = XXH3_64bits(id, strlen(id)) & (prev_cap - 1);
			while (prev_index[h].b)
				h = (h + 1) & (prev_cap - 1);
			prev_index[h] = (struct prev_slot){b + 1, k};
		}
}

/* The earlier driver's bundle of job j and its slot there, or NULL (the
 * last submission of the job counts: a later bundle wins). */
static struct bundle *previous_of(const struct job *j, int *slot)
{
	if (!prev_index)
		return NULL;
	struct bundle *found = NULL;
	size_t h = XXH3_64bits(j->id, strlen(j->id)) & (prev_cap - 1);
	for (; prev_index[h].b; h = (h + 1) & (prev_cap - 1)) {
		struct bundle *b = &bundles[prev_index[h].b - 1];
		int k = prev_index[h].k;
		if (strcmp(b->ids[k], j->id) != 0)
			continue;
		if (!found || b->array_id > found->array_id) {
			found = b;
			*slot = k;
		}
	}
	return found;
}
/* The controller's limits and the partition's CPUs, for the bundles' sizes
 * and the cap on them in the queue. Returns 0, or 1 after saying why. */
static int site_limits(const struct plan *p)
{
	const struct config *c = p->cfg;
	size_t cap = 1 << 18;
	char *out = malloc(cap), err[1024];
	if (!out)
		return 1;
	char *conf[] = {"scontrol", "show", "config", NULL};
	site.max_job_count = 10000; /* Slurm's defaults */
	site.max_array_size = 1001;
	site.min_job_age = 300;
	if (run_capture(conf, out, cap, err, sizeof err, QUERY_TIMEOUT) == 0) {
		for (char *l = out; l && *l;) {
			char key[64];
			long v;
			if (sscanf(l, "%63s = %ld", key, &v) == 2) {
				if (!strcmp(key, "MaxJobCount"))
					site.max_job_count = v;
				else if (!strcmp(key, "MaxArraySize"))
					site.max_array_size = v;
				else if (!strcmp(key, "MinJobAge"))
					site.min_job_age = v;
			}
			l = strchr(l, '\n');
			l = l ? l + 1 : NULL;
		}
	}
	site.cpus = 0;
	if (sinfo(c, "%C", out, cap, err, sizeof err) == 0)
		for (char *l = out; l && *l;) {
			long a, i, o, t;
			if (sscanf(l, "%ld/%ld/%ld/%ld", &a, &i, &o, &t) == 4)
				site.cpus += (int)t;
			l = strchr(l, '\n');
			l = l ? l + 1 : NULL;
		}
	free(out);
	if (site.cpus < 1)
		site.cpus = 1;
	/* half of MaxJobCount: the others' jobs, and ours that ended but
	 * stay in the controller's memory for MinJobAge, count too */
	site.max_queued = c->slurm.max_queued > 0 ? c->slurm.max_queued
		: site.max_job_count / 2 > 0 ? (int)(site.max_job_count / 2) : 1;
	if (site.max_array_size < 1)
		site.max_array_size = 1;
	return 0;
}

/* ----------------------------------------------------------- preflight */

/* Output directories that one node's jobs see and another's do not. */
static const char *node_local(const char *dir)
{
	struct statfs fs;
	if (statfs(dir, &fs) == 0 &&
	    (fs.f_type == 0x01021994 /* tmpfs */ ||
	     fs.f_type == 0x858458f6 /* ramfs */))
		return "a tmpfs, local to this node";
	char real[PATH_MAX];
	if (!realpath(dir, real))
		return NULL;
	static const char *const local[] = {"/tmp", "/var/tmp", "/dev/shm",
					    "/run"};
	for (size_t i = 0; i < sizeof local / sizeof *local; i++) {
		size_t n = strlen(local[i]);
		if (!strncmp(real, local[i], n) && (real[n] == '/' || !real[n]))
			return "under a node-local directory";
	}
	return NULL;
}

/* This program's path, read once (slurm_preflight, before any job): read
 * again after `make` relinked it, /proc/self/exe names the unlinked file
 * ("... (deleted)"), and every bundle submitted then would fail to start.
 * NULL when it cannot be read (errno says why). */
static const char *self_exe(void)
{
	static char self[PATH_MAX];
	static int err;
	if (!*self && !err) {
		ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
		if (n <= 0) {
			err = n < 0 ? errno : ENAMETOOLONG;
			self[0] = 0;
		} else {
			self[n] = 0;
		}
	}
	errno = err;
	return *self ? self : NULL;
}

int slurm_preflight(const struct plan *p)
{
	const struct config *c = p->cfg;
	char out[4096], err[4096];
	(void)self_exe(); /* now, while it is the file that runs */
	if (!on_path("sbatch")) {
		fprintf(stderr, "voxdag: executor slurm: no 'sbatch' on PATH "
			"(install Slurm's client commands, or use executor: "
			"local)\n");
		return 1;
	}
	char *ping[] = {"scontrol", "ping", NULL};
	int rc = run_capture(ping, out, sizeof out, err, sizeof err,
			     QUERY_TIMEOUT);
	if (rc != 0 || !strstr(out, "is UP")) {
		fprintf(stderr, "voxdag: executor slurm: the Slurm controller "
			"does not answer ('scontrol ping': %s)\n",
			rc == 124 ? "no answer in 30 s"
			: *out	  ? first_line(out)
			: *err	  ? first_line(err)
				  : "failed");
		return 1;
	}
	rc = sinfo(c, "%P", out, sizeof out, err, sizeof err);
	if (rc != 0 || !*out) {
		if (*c->slurm.partition)
			fprintf(stderr, "voxdag: executor slurm: partition '%s' "
				"does not exist (sinfo lists the partitions)\n",
				c->slurm.partition);
		else
			fprintf(stderr, "voxdag: executor slurm: the cluster "
				"has no partition ('sinfo': %s)\n",
				*err ? first_line(err) : "nothing listed");
		return 1;
	}
	if (mkdir_p(p->dir) != 0) {
		fprintf(stderr, "voxdag: cannot create '%s': %s\n", p->dir,
			strerror(errno));
		return 1;
	}
	const char *why = c->slurm.shared_outputs ? NULL : node_local(p->dir);
	if (why) {
		fprintf(stderr, "voxdag: executor slurm: the output directory "
			"'%s' is %s, so jobs on other nodes cannot see it; set "
			"'outputs:' to a directory every node shares (or "
			"'slurm: {shared_outputs: true}' on one node)\n",
			p->dir, why);
		return 1;
	}
	char dir[1200];
	snprintf(dir, sizeof dir, "%s/slurm", p->dir);
	if (mkdir_p(dir) != 0) {
		fprintf(stderr, "voxdag: cannot create '%s': %s\n", dir,
			strerror(errno));
		return 1;
	}
	if (site_limits(p) != 0 || load_previous(p) != 0)
		return 1;
	run_log("Slurm: at most %d bundles in the queue (MaxJobCount %ld), "
		"MaxArraySize %ld, %d CPUs in the partition, bundles of about "
		"%d s", site.max_queued, site.max_job_count, site.max_array_size,
		site.cpus, c->slurm.bundle_seconds);
	return 0;
}

/* ---------------------------------------------------------- submitting */

/* Appends s to the shell command buf in single quotes. */
static int shell_quote(char *buf, size_t cap, size_t *n, const char *s)
{
	if (*n + 3 >= cap)
		return -1;
	buf[(*n)++] = ' ';
	buf[(*n)++] = '\'';
	for (; *s; s++) {
		const char *piece = *s == '\'' ? "'\\''" : NULL;
		size_t len = piece ? 4 : 1;
		if (*n + len + 2 >= cap)
			return -1;
		if (piece)
			memcpy(buf + *n, piece, 4);
		else
			buf[*n] = *s;
		*n += len;
	}
	buf[(*n)++] = '\'';
	buf[*n] = 0;
	return 0;
}

static int job_threads(const struct job *j)
{
	for (int i = 0; j->argv[i] && j->argv[i + 1]; i++)
		if (!strcmp(j->argv[i], "--threads"))
			return atoi(j->argv[i + 1]) > 0 ? atoi(j->argv[i + 1]) : 1;
	return 1;
}

/* A job's seconds before any of its stage ran: a start-up cost and one
 * second per GiB of its memory estimate (the stages' time grows with the
 * data they hold, which the estimate bounds); corrected below by what
 * the declared job's ended jobs really took against theirs. */
static double prior_seconds(const struct job *j)
{
	return 0.05 + (double)j->mem_estimate / (1u << 30);
}

static double est_seconds(const struct job *j)
{
	double s = seen_seconds[j->decl], q = seen_prior[j->decl];
	if (q <= 0) { /* none of its own yet: every declared job's cells
		       * (or non-cells: one voxelize says little of a cell) */
		s = seen_seconds[MAX_JOBS_DECL + !j->cell];
		q = seen_prior[MAX_JOBS_DECL + !j->cell];
	}
	double f = q > 0 ? s / q : 1;
	if (f < 0.01)
		f = 0.01; /* a few very quick jobs say little of the rest */
	return prior_seconds(j) * f;
}

void slurm_want(const struct plan *p, struct job *j)
{
	(void)p;
	wanted = grow(wanted, &capwanted, nwanted + 1, sizeof *wanted);
	wanted[nwanted++] = (int)(j - p->jobs);
}

/* Submits one array whose task t runs the jobs g[start[t]..start[t+1]).
 * Returns 0, 1 when Slurm refused it for a dependency that just left the
 * queue (try again after the next poll), or -1 after saying why. */
static int submit_array(struct plan *p, const int *g, const int *start,
			int ntasks, char *why, size_t whycap)
{
	const struct config *c = p->cfg;
	char cwd[PATH_MAX];
	const char *self = self_exe();
	if (!self || !getcwd(cwd, sizeof cwd)) {
		snprintf(why, whycap, "cannot find this program's path: %s",
			 strerror(errno));
		return -1;
	}
	if (!sub_start)
		sub_start = (long)time(NULL);
	char name[48], sub[1300];
	/* unique across drivers: time and pid (a restarted driver may
	 * start within the second its predecessor did) */
	snprintf(name, sizeof name, "b%ld-%ld-%d", sub_start, (long)getpid(),
		 sub_count++);
	snprintf(sub, sizeof sub, "%s/slurm/%s.sub", p->dir, name);
	int first = nbundles;
	uint64_t mem = 0;
	int cpus = 1;
	long *deps = NULL;
	int ndeps = 0, capdeps = 0;
	for (int t = 0; t < ntasks; t++) {
		struct bundle *b = bundle_add();
		snprintf(b->name, sizeof b->name, "%s", name);
		b->task = t;
		b->njobs = start[t + 1] - start[t];
		b->jobs = malloc((size_t)b->njobs * sizeof *b->jobs);
		if (!b->jobs) {
			fprintf(stderr, "voxdag: out of memory\n");
			exit(1);
		}
		for (int k = 0; k < b->njobs; k++) {
			const struct job *j = &p->jobs[g[start[t] + k]];
			b->jobs[k] = g[start[t] + k];
			if (j->mem_estimate > mem)
				mem = j->mem_estimate;
			if (job_threads(j) > cpus)
				cpus = job_threads(j);
			for (int d = 0; d < j->ndeps; d++) {
				const struct job *dj = &p->jobs[j->deps[d]];
				if (dj->state != JOB_RUNNING || dj->slurm_id <= 0)
					continue;
				int seen = 0;
				for (int q = 0; q < ndeps && !seen; q++)
					seen = deps[q] == dj->slurm_id;
				if (!seen) {
					deps = grow(deps, &capdeps, ndeps + 1,
						    sizeof *deps);
					deps[ndeps++] = dj->slurm_id;
				}
			}
		}
		if (list_write(p, b, sub, why, whycap) != 0) {
			nbundles = first; /* (their lists are removed below) */
			goto fail;
		}
	}

	/* the batch script: job-exec on the task's list */
	size_t wcap = 8192, wn = 0;
	char wrap[8192], listp[1300];
	wrap[0] = 0;
	snprintf(listp, sizeof listp, "%s/slurm/%s.", p->dir, name);
	int bad = shell_quote(wrap, wcap, &wn, self) ||
		  shell_quote(wrap, wcap, &wn, "job-exec") ||
		  shell_quote(wrap, wcap, &wn, listp);
	const char *tail = "\"$SLURM_ARRAY_TASK_ID\"'.list'";
	if (bad || wn + strlen(tail) + 1 >= wcap) {
		snprintf(why, whycap, "the output directory's path is too long "
			 "for sbatch --wrap");
		goto fail;
	}
	strcpy(wrap + wn, tail);

	char jname[256], output[1400], chdir_[PATH_MAX + 16], memo[64],
		cpuo[32], part[128], acct[128], tlim[64], array[64];
	const struct job *j0 = &p->jobs[g[0]];
	snprintf(jname, sizeof jname, "--job-name=voxdag:%s:%s", c->name,
		 c->jobs_decl[j0->decl].name);
	snprintf(output, sizeof output, "--output=%s/logs/%s.%%a.log", p->dir,
		 name);
	snprintf(chdir_, sizeof chdir_, "--chdir=%s", cwd);
	unsigned long long mib = (mem + (1u << 20) - 1) >> 20;
	snprintf(memo, sizeof memo, "--mem=%lluM", mib ? mib : 1);
	snprintf(cpuo, sizeof cpuo, "--cpus-per-task=%d", cpus);
	snprintf(array, sizeof array, "--array=0-%d", ntasks - 1);
	const char *argv[64];
	int n = 0;
	argv[n++] = "sbatch";
	argv[n++] = "--parsable";
	argv[n++] = jname;
	argv[n++] = output;
	argv[n++] = chdir_;
	argv[n++] = memo;
	argv[n++] = cpuo;
	argv[n++] = array;
	if (*c->slurm.partition) {
		snprintf(part, sizeof part, "--partition=%s", c->slurm.partition);
		argv[n++] = part;
	}
	if (*c->slurm.account) {
		snprintf(acct, sizeof acct, "--account=%s", c->slurm.account);
		argv[n++] = acct;
	}
	const char *t = c->slurm.stage_time[c->jobs_decl[j0->decl].stage->type];
	if (!*t)
		t = c->slurm.time_limit;
	if (*t) {
		snprintf(tlim, sizeof tlim, "--time=%s", t);
		argv[n++] = tlim;
	}
	for (int i = 0; i < c->slurm.nargs; i++)
		argv[n++] = c->slurm.args[i];
	size_t dcap = 32 + (size_t)ndeps * 24, dn;
	char *dep = malloc(dcap);
	if (!dep) {
		fprintf(stderr, "voxdag: out of memory\n");
		exit(1);
	}
	dn = (size_t)snprintf(dep, dcap, "--dependency=afterany");
	for (int q = 0; q < ndeps; q++)
		dn += (size_t)snprintf(dep + dn, dcap - dn, ":%ld", deps[q]);
	if (ndeps)
		argv[n++] = dep;
	argv[n++] = "--wrap";
	argv[n++] = wrap;
	argv[n] = NULL;

	char out[1024], err[1024];
	int rc = run_capture((char *const *)argv, out, sizeof out, err,
			     sizeof err, QUERY_TIMEOUT);
	free(dep);
	char *endp;
	long aid = strtol(out, &endp, 10);
	if (rc != 0 || aid <= 0 || (*endp && *endp != ';' && *endp != '\n')) {
		if (rc != 124 && ndeps && strstr(err, "ependency")) {
			nbundles = first;
			free(deps);
			return 1;
		}
		snprintf(why, whycap, "sbatch failed: %s", rc == 124 ?
			 "no answer in 30 s" : *err ? first_line(err) :
			 first_line(out));
		goto fail;
	}
	char text[64];
	snprintf(text, sizeof text, "%ld\n", aid);
	if (write_atomic(sub, text) != 0) {
		/* its tasks wait for this record, then run nothing */
		snprintf(why, whycap, "cannot write '%s': %s; Slurm job %ld "
			 "will run nothing", sub, strerror(errno), aid);
		char ids[32];
		snprintf(ids, sizeof ids, "%ld", aid);
		char *cancel[] = {"scancel", ids, NULL};
		run_capture(cancel, out, sizeof out, err, sizeof err,
			    QUERY_TIMEOUT);
		goto fail;
	}
	for (int q = first; q < nbundles; q++) {
		struct bundle *b = &bundles[q];
		b->array_id = aid;
		snprintf(b->sid, sizeof b->sid, "%ld_%d", aid, b->task);
		b->left = b->njobs;
		live_tasks++;
		for (int k = 0; k < b->njobs; k++) {
			struct job *j = &p->jobs[b->jobs[k]];
			j->slurm_id = aid;
			j->bundle = q + 1;
		}
	}
	free(deps);
	return 0;
fail:
	for (int q = first; q < first + ntasks; q++) {
		char path[1300];
		snprintf(path, sizeof path, "%s/slurm/%s.%d.list", p->dir, name,
			 q - first);
		unlink(path);
	}
	nbundles = first;
	free(deps);
	return -1;
}

/* Removes j's end file when an earlier run may have left one: it was
 * there when the driver started, or an earlier driver's bundle (maybe
 * still running) holds j. */
static void drop_stale_end(const struct plan *p, const struct job *j)
{
	char end[1300];
	int k;
	job_file(p, j, "slurm", "end", end, sizeof end);
	const char *name = strrchr(end, '/') + 1;
	if (previous_of(j, &k) ||
	    (nold_ends && bsearch(&name, old_ends, (size_t)nold_ends,
				  sizeof *old_ends, cmp_str)))
		unlink(end);
}

int slurm_flush(struct plan *p, int *failed)
{
	const struct config *c = p->cfg;
	int submitted = 0;
	*failed = 0;
	starved = 0;
	int *g = malloc(((size_t)nwanted + 1) * sizeof *g);
	int *start = malloc(((size_t)nwanted + 2) * sizeof *start);
	if (!g || !start) {
		fprintf(stderr, "voxdag: out of memory\n");
		exit(1);
	}
	/* the wanted jobs of one declared job at a time, in plan order */
	for (int from = 0; from < nwanted;) {
		int d = p->jobs[wanted[from]].decl, ng = 0, to = from;
		for (int i = from; i < nwanted; i++)
			if (p->jobs[wanted[i]].decl == d &&
			    p->jobs[wanted[i]].state == JOB_PENDING)
				g[ng++] = wanted[i];
		for (int i = from; i < nwanted; i++)
			if (p->jobs[wanted[i]].decl != d)
				wanted[to++] = wanted[i];
		nwanted = to;
		int free_tasks = site.max_queued - live_tasks;
		if (ng == 0)
			continue;
		if (free_tasks <= 0) {
			starved = 1;
			continue;
		}
		double total = 0;
		for (int i = 0; i < ng; i++)
			total += est_seconds(&p->jobs[g[i]]);
		/* as many bundles as the target duration asks, and at
		 * least as many as the partition has CPUs for while each
		 * bundle keeps a tenth of the target */
		double target = c->slurm.bundle_seconds;
		int width = site.cpus / job_threads(&p->jobs[g[0]]);
		long by_time = (long)ceil(total / target);
		long by_width = (long)ceil(total / (target / 10));
		if (by_width > width)
			by_width = width;
		long nb = by_time > by_width ? by_time : by_width;
		if (nb > ng)
			nb = ng;
		if (nb < 1)
			nb = 1;
		double per = total / (double)nb;
		/* cut in plan order (neighbouring cells together) */
		int nt = 0;
		double acc = 0;
		start[0] = 0;
		for (int i = 0; i < ng; i++) {
			acc += est_seconds(&p->jobs[g[i]]);
			if (acc >= per * (nt + 1) - 1e-9 && nt + 1 < nb)
				start[++nt] = i + 1;
		}
		if (start[nt] < ng)
			start[++nt] = ng;
		/* within the queue's cap, MaxArraySize per array */
		while (nt > 0 && free_tasks > 0) {
			int take = nt < free_tasks ? nt : free_tasks;
			if (take > site.max_array_size)
				take = (int)site.max_array_size;
			int *tstart = malloc(((size_t)take + 1) * sizeof *tstart);
			if (!tstart) {
				fprintf(stderr, "voxdag: out of memory\n");
				exit(1);
			}
			for (int t = 0; t <= take; t++)
				tstart[t] = start[t] - start[0];
			char why[1600] = "";
			int *gg = g + start[0];
			int njobs = start[take] - start[0];
			/* stale ends of earlier runs must not be read as
			 * this submission's */
			for (int k = 0; k < njobs; k++)
				drop_stale_end(p, &p->jobs[gg[k]]);
			int rc = submit_array(p, gg, tstart, take, why, sizeof why);
			free(tstart);
			if (rc == 1) {
				/* see what ended, then again */
				next_poll = next_squeue = 0;
				break;
			}
			for (int k = 0; k < njobs; k++) {
				struct job *j = &p->jobs[gg[k]];
				if (rc == 0) {
					j->state = JOB_RUNNING;
					j->start = vd_seconds();
					const struct bundle *b = &bundles[j->bundle - 1];
					run_log("submitted %s (Slurm job %s, %llu "
						"MiB)", j->id, b->sid,
						(unsigned long long)(j->mem_estimate >> 20));
					submitted++;
				} else {
					job_set_state(p, j, JOB_FAILED);
					(*failed)++;
				}
			}
			if (rc != 0) {
				fprintf(stderr, "voxdag: %d job%s of %s not "
					"submitted: %s\n", njobs, njobs == 1 ?
					"" : "s", c->jobs_decl[d].name, why);
				run_log("failed to submit %d jobs of %s: %s", njobs,
					c->jobs_decl[d].name, why);
				break;
			}
			run_log("sbatch: Slurm job %ld, %d bundle%s of %d %s "
				"jobs (about %.1f s each)",
				bundles[nbundles - 1].array_id, take, take == 1 ?
				"" : "s", njobs, c->jobs_decl[d].name, per);
			free_tasks -= take;
			memmove(start, start + take, (size_t)(nt - take + 1) *
				sizeof *start);
			nt -= take;
		}
		if (nt > 0)
			starved = 1;
	}
	nwanted = 0;
	free(g);
	free(start);
	return submitted;
}

int slurm_adopt(const struct plan *p, struct job *j)
{
	if (load_previous(p) != 0)
		exit(1);
	int k;
	struct bundle *b = previous_of(j, &k);
	if (!b || b->jobs[k] >= 0)
		return 0;
	if (b->hashes[k] != argv_hash(j))
		return 0; /* another command line: not this job */
	char end[1300];
	job_file(p, j, "slurm", "end", end, sizeof end);
	struct job_end e;
	int has_end = read_end(end, &e) == 0;
	if (b->ended && !has_end)
		return 0; /* it never ran, or was stopped: submit again */
	b->jobs[k] = (int)(j - p->jobs);
	b->left++;
	j->slurm_id = b->array_id;
	j->bundle = (int)(b - bundles) + 1;
	if (b->ended) /* ended while no driver watched */
		push_end(b->jobs[k], &e);
	return 1;
}

const char *slurm_bundle_name(const struct job *j)
{
	return j->bundle > 0 ? bundles[j->bundle - 1].sid : "";
}

/* A job of bundle b is no longer waited for. The bundle's Slurm task is
 * cancelled once it runs nothing the driver waits for. */
static void bundle_drop(struct bundle *b, struct job *j)
{
	j->bundle = 0;
	j->slurm_id = 0;
	if (--b->left > 0 || b->ended)
		return;
	char out[256], err[256], id[48];
	snprintf(id, sizeof id, "%s", b->sid);
	char *argv[] = {"scancel", id, NULL};
	run_capture(argv, out, sizeof out, err, sizeof err, QUERY_TIMEOUT);
}

void slurm_cancel(const struct plan *p, struct job *j)
{
	(void)p;
	if (j->bundle > 0)
		bundle_drop(&bundles[j->bundle - 1], j);
}

void slurm_forget(const struct plan *p, struct job *j)
{
	(void)p;
	if (j->bundle > 0)
		bundle_drop(&bundles[j->bundle - 1], j);
}

/* Bundle bi went through its list (by_done: its .done is there) or left
 * the queue without: queues its jobs' ends, in bundle order, so a failed
 * dependency is recorded before the jobs skipped for it. */
static void bundle_ended(const struct plan *p, int bi, int by_done)
{
	struct bundle *b = &bundles[bi];
	b->ended = 1;
	for (int k = 0; k < b->njobs; k++) {
		int ji = b->jobs[k];
		if (ji < 0 || p->jobs[ji].state != JOB_RUNNING ||
		    p->jobs[ji].bundle != bi + 1)
			continue;
		char end[1300];
		struct job_end e;
		job_file(p, &p->jobs[ji], "slurm", "end", end, sizeof end);
		if (read_end(end, &e) != 0) {
			memset(&e, 0, sizeof e);
			e.cpu = -1;
			if (by_done) {
				snprintf(e.reason, sizeof e.reason, "not run in "
					 "Slurm job %s: a job it needs did not "
					 "succeed", b->sid);
			} else {
				if (!b->reason_asked) {
					char log[1300];
					b->reason_asked = 1;
					snprintf(log, sizeof log, "%s/logs/%s.%d.log",
						 p->dir, b->name, b->task);
					slurm_reason(b->sid, log, b->reason,
						     sizeof b->reason);
				}
				snprintf(e.reason, sizeof e.reason, "%s", b->reason);
			}
		}
		push_end(ji, &e);
	}
}

/* Looks for bundles that ended: their .done files (a stat each, cheap),
 * and with ask_slurm one squeue for those that left the queue without
 * one (cancelled, killed, out of memory or time). Returns -1 when squeue
 * does not answer. */
static int poll_bundles(const struct plan *p, int ask_slurm)
{
	for (int bi = 0; bi < nbundles; bi++) {
		struct bundle *b = &bundles[bi];
		if (b->ended || !b->sid[0])
			continue;
		char done[1300];
		snprintf(done, sizeof done, "%s/slurm/%s.%d.done", p->dir,
			 b->name, b->task);
		if (access(done, F_OK) == 0)
			bundle_ended(p, bi, 1);
	}
	if (!ask_slurm)
		return 0;
	int nlive;
	struct live *live = squeue_live(&nlive);
	if (!live)
		return -1; /* no answer now: ask again later */
	for (int bi = 0; bi < nbundles; bi++) {
		struct bundle *b = &bundles[bi];
		if (b->gone || live_find(live, nlive, b->sid))
			continue;
		b->gone = 1;
		live_tasks--;
		if (!b->ended)
			bundle_ended(p, bi, 0);
	}
	free(live);
	return 0;
}

int slurm_reap(const struct plan *p, struct job_end *e)
{
	while (headends < nends) {
		struct end_rec *r = &ends[headends++];
		const struct job *j = &p->jobs[r->job];
		if (j->state != JOB_RUNNING)
			continue; /* blocked meanwhile: skipped in its bundle */
		*e = r->e;
		if (!*e->reason && e->exited) {
			int d = j->decl;
			seen_seconds[d] += e->seconds;
			seen_prior[d] += prior_seconds(j);
			seen_seconds[MAX_JOBS_DECL + !j->cell] += e->seconds;
			seen_prior[MAX_JOBS_DECL + !j->cell] += prior_seconds(j);
		}
		return r->job;
	}
	double now = vd_seconds();
	if (now < next_poll)
		return -1;
	/* the .done files twice a second (slower with thousands of
	 * bundles in flight); squeue every 5 s for bundles that died,
	 * or every 2 s while ready jobs wait for room in the queue and
	 * bundles that finished may not have left it yet */
	next_poll = now + 0.5 + live_tasks * 0.0005;
	int waiting_room = 0;
	for (int bi = 0; bi < nbundles && starved && !waiting_room; bi++)
		waiting_room = bundles[bi].ended && !bundles[bi].gone;
	int ask = now >= next_squeue ||
		  (waiting_room && now >= last_squeue + 2.0);
	if (ask) {
		last_squeue = now;
		next_squeue = now + 5.0;
	}
	if (poll_bundles(p, ask) == 0 && headends < nends)
		return slurm_reap(p, e);
	return -1;
}

void slurm_done(const struct plan *p)
{
	/* nothing of ours runs now: the bundles' records go */
	char dir[1200];
	snprintf(dir, sizeof dir, "%s/slurm", p->dir);
	DIR *d = opendir(dir);
	if (!d)
		return;
	struct dirent *e;
	while ((e = readdir(d))) {
		size_t len = strlen(e->d_name);
		if (e->d_name[0] == 'b' &&
		    ((len > 5 && !strcmp(e->d_name + len - 5, ".list")) ||
		     (len > 5 && !strcmp(e->d_name + len - 5, ".done")) ||
		     (len > 4 && !strcmp(e->d_name + len - 4, ".sub")))) {
			char path[1500];
			snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
			unlink(path);
		}
	}
	closedir(d);
	/* the bundles' own logs that say nothing (job-exec speaks only when
	 * it skipped a job or could not write an end) */
	for (int bi = 0; bi < nbundles; bi++) {
		char path[1300];
		struct stat st;
		snprintf(path, sizeof path, "%s/logs/%s.%d.log", p->dir,
			 bundles[bi].name, bundles[bi].task);
		if (stat(path, &st) == 0 && st.st_size == 0)
			unlink(path);
	}
}

const char *slurm_state(const struct plan *p, const struct job *j,
			char *buf, size_t cap)
{
	if (load_previous(p) != 0)
		return NULL;
	int k;
	const struct bundle *b = previous_of(j, &k);
	if (!b)
		return NULL;
	char end[1300];
	struct job_end e;
	job_file(p, j, "slurm", "end", end, sizeof end);
	if (read_end(end, &e) == 0) {
		snprintf(buf, cap, "ENDED (Slurm job %s, exit %d)", b->sid,
			 e.exited ? e.code : 128 + e.signal);
		return buf;
	}
	if (b->gone) {
		char why[160], log[1300];
		snprintf(log, sizeof log, "%s/logs/%s.%d.log", p->dir, b->name,
			 b->task);
		slurm_reason(b->sid, log, why, sizeof why);
		snprintf(buf, cap, "GONE (%s)", why);
		return buf;
	}
	snprintf(buf, cap, "%s (Slurm job %s)", b->state, b->sid);
	return buf;
}

/* ------------------------------------------------------------ job-exec */

static volatile sig_atomic_t forward_pid, stopping;

static void forward(int sig)
{
	stopping = sig;
	if (forward_pid > 0)
		kill((pid_t)forward_pid, sig);
}

/* 1 when the end file at path says the job succeeded. */
static int end_ok(const char *path)
{
	struct job_end e;
	return read_end(path, &e) == 0 && e.exited && e.code == 0;
}

/* Runs one job of a list: its log appended, its end written. Returns 0,
 * or 1 when its end could not be written (said on stderr). */
static int exec_one(const struct list_job *lj)
{
	int log = open(lj->log, O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0666);
	if (log < 0) {
		fprintf(stderr, "voxdag: job %s: cannot open its log '%s': %s\n",
			lj->id, lj->log, strerror(errno));
		return 1;
	}
	FILE *lf = fdopen(dup(log), "a");
	if (lf) {
		fputc('$', lf);
		for (int i = 0; i < lj->argc; i++)
			fprintf(lf, " %s", lj->argv[i]);
		fputc('\n', lf);
		fclose(lf);
	}
	double t0 = vd_seconds();
	pid_t pid = fork();
	if (pid < 0) {
		fprintf(stderr, "voxdag: cannot fork: %s\n", strerror(errno));
		close(log);
		return 1;
	}
	if (pid == 0) {
		int null = open("/dev/null", O_RDONLY);
		if (null >= 0)
			dup2(null, 0);
		dup2(log, 1);
		dup2(log, 2);
		execv(lj->argv[0], lj->argv);
		fprintf(stderr, "voxdag: cannot run '%s': %s\n", lj->argv[0],
			strerror(errno));
		_exit(127);
	}
	close(log);
	forward_pid = pid;
	int status;
	struct rusage ru;
	while (wait4(pid, &status, 0, &ru) < 0)
		if (errno != EINTR)
			return 1;
	forward_pid = 0;
	int code = WIFEXITED(status) ? WEXITSTATUS(status) : 0;
	int sig = WIFSIGNALED(status) ? WTERMSIG(status) : 0;
	/* scancel's SIGTERM reached the stage too; no end file is written
	 * then, so the driver asks Slurm why the job stopped */
	if (stopping || sig == SIGTERM || sig == SIGINT)
		return 0;
	char text[256];
	snprintf(text, sizeof text, END_MAGIC "\nexit %d\nsignal %d\nseconds "
		 "%.3f\npeak_rss %llu\ncpu %.3f\n", code, sig,
		 vd_seconds() - t0, (unsigned long long)ru.ru_maxrss * 1024,
		 (double)ru.ru_utime.tv_sec + ru.ru_utime.tv_usec * 1e-6 +
		 (double)ru.ru_stime.tv_sec + ru.ru_stime.tv_usec * 1e-6);
	if (write_whole(lj->end, text) != 0) {
		fprintf(stderr, "voxdag: cannot write '%s': %s\n", lj->end,
			strerror(errno));
		return 1;
	}
	return 0;
}

int slurm_job_exec(int argc, char **argv)
{
	/* voxdag job-exec LIST */
	if (argc != 3 || argv[2][0] == '-') {
		fprintf(stderr, "usage: voxdag job-exec LIST\n");
		return 2;
	}
	char sub[1300] = "";
	struct list_job *l;
	int line, n = list_read(argv[2], sub, sizeof sub, &l, &line);
	if (n < 0) {
		if (!line)
			fprintf(stderr, "voxdag: job-exec: cannot open '%s': %s\n",
				argv[2], strerror(errno));
		else
			fprintf(stderr, "voxdag: job-exec: '%s' is not a job "
				"list (line %d)\n", argv[2], line);
		return 1;
	}
	/* run nothing unless the driver recorded this very array: one whose
	 * driver died before recording it is submitted again by the next */
	const char *mine = getenv("SLURM_ARRAY_JOB_ID");
	if (!mine)
		mine = getenv("SLURM_JOB_ID");
	if (mine && *sub) {
		long rec = 0;
		for (int tries = 0; tries < 600 && rec <= 0; tries++) {
			FILE *f = fopen(sub, "r");
			if (f) {
				if (fscanf(f, "%ld", &rec) != 1)
					rec = 0;
				fclose(f);
			}
			if (rec <= 0) {
				struct timespec ts = {0, 100 * 1000 * 1000};
				nanosleep(&ts, NULL);
			}
		}
		if (rec != atol(mine)) {
			fprintf(stderr, "voxdag: job-exec: '%s' does not name "
				"Slurm job %s (its driver stopped before "
				"recording it): running nothing\n", sub, mine);
			list_free(l, n);
			return 0;
		}
	}
	signal(SIGTERM, forward);
	signal(SIGINT, forward);
	int rc = 0;
	for (int k = 0; k < n && !stopping; k++) {
		int deps_ok = 1;
		for (int a = 0; a < l[k].nafters && deps_ok; a++)
			if (!end_ok(l[k].afters[a])) {
				deps_ok = 0;
				fprintf(stderr, "voxdag: job %s not run: the job "
					"that wrote '%s' did not succeed\n",
					l[k].id, l[k].afters[a]);
			}
		if (deps_ok && exec_one(&l[k]) != 0)
			rc = 1;
	}
	list_free(l, n);
	if (stopping)
		return 128 + stopping;
	/* through the list: the driver sees this before squeue does */
	size_t len = strlen(argv[2]);
	if (len > 5 && !strcmp(argv[2] + len - 5, ".list")) {
		char done[1300];
		snprintf(done, sizeof done, "%.*s.done", (int)(len - 5), argv[2]);
		if (write_whole(done, "done\n") != 0) {
			fprintf(stderr, "voxdag: cannot write '%s': %s\n", done,
				strerror(errno));
			rc = 1;
		}
	}
	return rc;
}
