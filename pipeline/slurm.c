/* slurm.c - the Slurm executor: the same job graph, each job an sbatch.
 *
 * The runner stays the driver and Slurm only runs processes, so planning,
 * keys, resume and the report are the local ones. What Slurm adds:
 * - submission: `sbatch --wrap "voxdag job-exec END -- PROG ARGS..."` with
 *   the job's memory estimate, its threads, its log, and `afterok` on the
 *   dependencies still queued or running in Slurm (jobs planned later, the
 *   cells and merges, are submitted as they become known);
 * - ends: `job-exec` writes DIR/slurm/<job>.end (exit status, seconds, peak
 *   memory) atomically when the stage exits, so the driver reads an end
 *   from the shared file system, not from accounting (often disabled); a
 *   job that vanishes from squeue without an end file was cancelled, ran
 *   out of memory or time, and `scontrol show job` says which;
 * - adoption: DIR/slurm/<job>.id holds the Slurm job id and a hash of the
 *   command; a restarted driver takes over a job still queued or running,
 *   or one that ended while no driver watched, instead of submitting it
 *   again. */
#include "pipeline.h"

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <poll.h>
#include <signal.h>
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

/* ------------------------------------------------------------ commands */

/* Runs argv (searched on PATH) with no standard input, its standard output
 * into out (NUL-terminated, cut at cap) and its standard error into err.
 * Returns its exit status, 124 after timeout_s seconds (it is killed), or
 * -1 when it could not be started. */
static int run_capture(char *const argv[], char *out, size_t cap, char *err,
		       size_t ecap, int timeout_s)
{
	int po[2], pe[2];
	out[0] = err[0] = 0;
	if (pipe(po) != 0)
		return -1;
	if (pipe(pe) != 0) {
		close(po[0]);
		close(po[1]);
		return -1;
	}
	pid_t pid = fork();
	if (pid < 0) {
		close(po[0]), close(po[1]), close(pe[0]), close(pe[1]);
		return -1;
	}
	if (pid == 0) {
		int null = open("/dev/null", O_RDONLY);
		if (null >= 0)
			dup2(null, 0);
		dup2(po[1], 1);
		dup2(pe[1], 2);
		close(po[0]), close(po[1]), close(pe[0]), close(pe[1]);
		execvp(argv[0], argv);
		fprintf(stderr, "%s: %s", argv[0], strerror(errno));
		_exit(127);
	}
	close(po[1]);
	close(pe[1]);
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

static void slurm_file(const struct plan *p, const struct job *j,
		       const char *ext, char *buf, size_t cap)
{
	char id[256];
	snprintf(id, sizeof id, "%s", j->id);
	for (char *c = id; *c; c++)
		if (*c == '/')
			*c = '.';
	snprintf(buf, cap, "%s/slurm/%s.%s", p->dir, id, ext);
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

/* Reads an end file; 0 when it is complete and well formed. */
static int read_end(const char *path, struct job_end *e)
{
	FILE *f = fopen(path, "r");
	if (!f)
		return -1;
	char magic[32] = "";
	unsigned long long rss = 0;
	memset(e, 0, sizeof *e);
	int ok = fgets(magic, sizeof magic, f) &&
		 !strncmp(magic, END_MAGIC "\n", sizeof END_MAGIC) &&
		 fscanf(f, "exit %d\nsignal %d\nseconds %lf\npeak_rss %llu\n",
			&e->code, &e->signal, &e->seconds, &rss) == 4;
	fclose(f);
	e->exited = e->signal == 0;
	e->peak_rss = rss;
	return ok ? 0 : -1;
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

int slurm_preflight(const struct plan *p)
{
	const struct config *c = p->cfg;
	char out[4096], err[4096];
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
	char part[MAX_NAME + 4];
	snprintf(part, sizeof part, "%s", c->slurm.partition);
	char *sinfo[] = {"sinfo", "-h", "-o", "%P", NULL, NULL, NULL};
	if (*part) {
		sinfo[4] = "-p";
		sinfo[5] = part;
	}
	rc = run_capture(sinfo, out, sizeof out, err, sizeof err,
			 QUERY_TIMEOUT);
	if (rc != 0 || !*out) {
		if (*part)
			fprintf(stderr, "voxdag: executor slurm: partition '%s' "
				"does not exist (sinfo lists the partitions)\n",
				part);
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

int slurm_submit(const struct plan *p, struct job *j)
{
	const struct config *c = p->cfg;
	char self[PATH_MAX], cwd[PATH_MAX], end[1300], idf[1300], log[1300];
	ssize_t sl = readlink("/proc/self/exe", self, sizeof self - 1);
	if (sl <= 0 || !getcwd(cwd, sizeof cwd)) {
		fprintf(stderr, "voxdag: cannot find this program's path: %s\n",
			strerror(errno));
		return -1;
	}
	self[sl] = 0;
	slurm_file(p, j, "end", end, sizeof end);
	slurm_file(p, j, "id", idf, sizeof idf);
	char id[256];
	snprintf(id, sizeof id, "%s", j->id);
	for (char *q = id; *q; q++)
		if (*q == '/')
			*q = '.';
	snprintf(log, sizeof log, "%s/logs/%s.log", p->dir, id);
	unlink(end);
	unlink(idf);

	/* the batch script: job-exec around the stage's command line */
	size_t wcap = 1 << 16, wn = 0;
	char *wrap = malloc(wcap);
	if (!wrap)
		return -1;
	wrap[0] = 0;
	int bad = shell_quote(wrap, wcap, &wn, self) ||
		  shell_quote(wrap, wcap, &wn, "job-exec") ||
		  shell_quote(wrap, wcap, &wn, end) ||
		  shell_quote(wrap, wcap, &wn, "--");
	for (int i = 0; j->argv[i] && !bad; i++)
		bad = shell_quote(wrap, wcap, &wn, j->argv[i]);
	if (bad) {
		fprintf(stderr, "voxdag: job %s: command line too long for "
			"sbatch --wrap\n", j->id);
		free(wrap);
		return -1;
	}

	char name[256], output[1400], chdir_[PATH_MAX + 16], mem[64], cpus[32],
		part[128], acct[128], tlim[64];
	snprintf(name, sizeof name, "--job-name=voxdag:%s:%s", c->name, j->id);
	snprintf(output, sizeof output, "--output=%s", log);
	snprintf(chdir_, sizeof chdir_, "--chdir=%s", cwd);
	unsigned long long mib = (j->mem_estimate + (1u << 20) - 1) >> 20;
	snprintf(mem, sizeof mem, "--mem=%lluM", mib ? mib : 1);
	snprintf(cpus, sizeof cpus, "--cpus-per-task=%d", job_threads(j));
	const char *argv[64];
	int n = 0;
	argv[n++] = "sbatch";
	argv[n++] = "--parsable";
	argv[n++] = name;
	argv[n++] = output;
	argv[n++] = chdir_;
	argv[n++] = mem;
	argv[n++] = cpus;
	if (*c->slurm.partition) {
		snprintf(part, sizeof part, "--partition=%s", c->slurm.partition);
		argv[n++] = part;
	}
	if (*c->slurm.account) {
		snprintf(acct, sizeof acct, "--account=%s", c->slurm.account);
		argv[n++] = acct;
	}
	const char *t = c->slurm.stage_time[c->jobs_decl[j->decl].stage->type];
	if (!*t)
		t = c->slurm.time_limit;
	if (*t) {
		snprintf(tlim, sizeof tlim, "--time=%s", t);
		argv[n++] = tlim;
	}
	for (int i = 0; i < c->slurm.nargs; i++)
		argv[n++] = c->slurm.args[i];
	/* afterok on the dependencies that Slurm still has */
	size_t dcap = 32 + (size_t)j->ndeps * 24, dn;
	char *dep = malloc(dcap);
	if (!dep) {
		free(wrap);
		return -1;
	}
	dn = (size_t)snprintf(dep, dcap, "--dependency=afterok");
	int ndep = 0;
	for (int k = 0; k < j->ndeps; k++) {
		const struct job *d = &p->jobs[j->deps[k]];
		if (d->state == JOB_RUNNING && d->slurm_id > 0) {
			dn += (size_t)snprintf(dep + dn, dcap - dn, ":%ld",
					       d->slurm_id);
			ndep++;
		}
	}
	if (ndep)
		argv[n++] = dep;
	argv[n++] = "--wrap";
	argv[n++] = wrap;
	argv[n] = NULL;

	char out[1024], err[1024];
	int rc = run_capture((char *const *)argv, out, sizeof out, err,
			     sizeof err, QUERY_TIMEOUT);
	free(wrap);
	free(dep);
	char *endp;
	long sid = strtol(out, &endp, 10);
	if (rc != 0 || sid <= 0 || (*endp && *endp != ';' && *endp != '\n')) {
		fprintf(stderr, "voxdag: job %s: sbatch failed: %s\n", j->id,
			rc == 124 ? "no answer in 30 s"
			: *err	  ? first_line(err)
				  : first_line(out));
		return -1;
	}
	char text[96];
	snprintf(text, sizeof text, "%ld %016llx\n", sid,
		 (unsigned long long)argv_hash(j));
	if (write_atomic(idf, text) != 0) {
		fprintf(stderr, "voxdag: cannot write '%s': %s; cancelling "
			"Slurm job %ld\n", idf, strerror(errno), sid);
		j->slurm_id = sid;
		slurm_cancel(p, j);
		return -1;
	}
	j->slurm_id = sid;
	return 0;
}

/* Slurm's state of one job ("PENDING", "RUNNING", ...), "" when squeue no
 * longer lists it, NULL when squeue does not answer. */
static const char *squeue_state(long sid, char *buf, size_t cap)
{
	char ids[32], out[256], err[512];
	snprintf(ids, sizeof ids, "%ld", sid);
	char *argv[] = {"squeue", "-h", "-o", "%T", "-j", ids, NULL};
	int rc = run_capture(argv, out, sizeof out, err, sizeof err,
			     QUERY_TIMEOUT);
	if (rc != 0 && !strstr(err, "Invalid job id"))
		return NULL;
	snprintf(buf, cap, "%s", rc == 0 ? first_line(out) : "");
	return buf;
}

int slurm_adopt(const struct plan *p, struct job *j)
{
	char idf[1300], end[1300];
	slurm_file(p, j, "id", idf, sizeof idf);
	slurm_file(p, j, "end", end, sizeof end);
	FILE *f = fopen(idf, "r");
	if (!f)
		return 0;
	long sid = 0;
	unsigned long long h = 0;
	int ok = fscanf(f, "%ld %llx", &sid, &h) == 2 && sid > 0;
	fclose(f);
	if (!ok || h != argv_hash(j)) {
		/* another command line: that submission is not this job */
		unlink(idf);
		unlink(end);
		return 0;
	}
	struct job_end e;
	char st[64];
	if (read_end(end, &e) == 0) {
		j->slurm_id = sid; /* ended while no driver watched */
		return 1;
	}
	const char *s = squeue_state(sid, st, sizeof st);
	if (s && *s) {
		j->slurm_id = sid; /* still queued or running */
		return 1;
	}
	unlink(idf);
	return 0;
}

void slurm_cancel(const struct plan *p, struct job *j)
{
	if (j->slurm_id <= 0)
		return;
	char ids[32], out[256], err[256];
	snprintf(ids, sizeof ids, "%ld", j->slurm_id);
	char *argv[] = {"scancel", ids, NULL};
	run_capture(argv, out, sizeof out, err, sizeof err, QUERY_TIMEOUT);
	slurm_forget(p, j);
	j->slurm_id = 0;
}

void slurm_forget(const struct plan *p, const struct job *j)
{
	char path[1300];
	slurm_file(p, j, "id", path, sizeof path);
	unlink(path);
	slurm_file(p, j, "end", path, sizeof path);
	unlink(path);
}

/* What Slurm says of a job that left the queue without an end file. */
static void slurm_reason(long sid, char *buf, size_t cap)
{
	char ids[32], out[8192], err[512];
	snprintf(ids, sizeof ids, "%ld", sid);
	char *argv[] = {"scontrol", "-o", "show", "job", ids, NULL};
	if (run_capture(argv, out, sizeof out, err, sizeof err,
			QUERY_TIMEOUT) != 0) {
		snprintf(buf, cap, "Slurm job %ld left the queue without an "
			 "end record (no longer known to scontrol)", sid);
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
	snprintf(buf, cap, "Slurm job %ld: state %s, reason %s, exit code %s",
		 sid, state, reason, code);
}

static int cmp_long(const void *a, const void *b)
{
	long x = *(const long *)a, y = *(const long *)b;
	return (x > y) - (x < y);
}

int slurm_reap(const struct plan *p, struct job_end *e)
{
	static double last_query;
	char end[1300];
	for (int i = 0; i < p->n; i++) {
		const struct job *j = &p->jobs[i];
		if (j->state != JOB_RUNNING || j->slurm_id <= 0)
			continue;
		slurm_file(p, j, "end", end, sizeof end);
		if (read_end(end, e) == 0)
			return i;
	}
	double now = vd_seconds();
	if (now - last_query < 3.0)
		return -1;
	last_query = now;
	/* which of ours does Slurm still have? one squeue for all of them */
	size_t cap = 16u << 20;
	char *out = malloc(cap), err[1024];
	char *all[] = {"squeue", "--me", "-h", "-o", "%i", NULL};
	if (!out)
		return -1;
	if (run_capture(all, out, cap, err, sizeof err, QUERY_TIMEOUT) != 0) {
		free(out);
		return -1; /* no answer now: ask again later */
	}
	size_t nids = 0, idcap = 1024;
	long *ids = malloc(idcap * sizeof *ids);
	for (char *l = out; ids && *l;) {
		char *next;
		long v = strtol(l, &next, 10);
		if (next == l)
			break;
		if (nids == idcap) {
			long *grown = realloc(ids, 2 * idcap * sizeof *ids);
			if (!grown)
				break;
			ids = grown;
			idcap *= 2;
		}
		ids[nids++] = v;
		l = next + strspn(next, "\n ");
	}
	free(out);
	if (!ids)
		return -1;
	qsort(ids, nids, sizeof *ids, cmp_long);
	int found = -1;
	for (int i = 0; i < p->n && found < 0; i++) {
		const struct job *j = &p->jobs[i];
		if (j->state != JOB_RUNNING || j->slurm_id <= 0 ||
		    bsearch(&j->slurm_id, ids, nids, sizeof *ids, cmp_long))
			continue;
		slurm_file(p, j, "end", end, sizeof end);
		if (read_end(end, e) != 0) { /* else it ended between looks */
			memset(e, 0, sizeof *e);
			slurm_reason(j->slurm_id, e->reason, sizeof e->reason);
		}
		found = i;
	}
	free(ids);
	return found;
}

const char *slurm_state(const struct plan *p, const struct job *j,
			char *buf, size_t cap)
{
	char idf[1300], end[1300];
	slurm_file(p, j, "id", idf, sizeof idf);
	slurm_file(p, j, "end", end, sizeof end);
	FILE *f = fopen(idf, "r");
	if (!f)
		return NULL;
	long sid = 0;
	int ok = fscanf(f, "%ld", &sid) == 1;
	fclose(f);
	if (!ok)
		return NULL;
	struct job_end e;
	if (read_end(end, &e) == 0) {
		snprintf(buf, cap, "ENDED (Slurm job %ld, exit %d)", sid,
			 e.exited ? e.code : 128 + e.signal);
		return buf;
	}
	char st[64];
	const char *s = squeue_state(sid, st, sizeof st);
	if (!s) {
		snprintf(buf, cap, "UNKNOWN (Slurm job %ld; squeue does not "
			 "answer)", sid);
		return buf;
	}
	if (!*s) {
		char why[160];
		slurm_reason(sid, why, sizeof why);
		snprintf(buf, cap, "GONE (%s)", why);
		return buf;
	}
	snprintf(buf, cap, "%s (Slurm job %ld)", s, sid);
	return buf;
}

/* ------------------------------------------------------------ job-exec */

static volatile sig_atomic_t forward_pid;

static void forward(int sig)
{
	if (forward_pid > 0)
		kill((pid_t)forward_pid, sig);
}

int slurm_job_exec(int argc, char **argv)
{
	/* voxdag job-exec END -- PROG ARGS... */
	if (argc < 5 || strcmp(argv[3], "--") != 0) {
		fprintf(stderr, "usage: voxdag job-exec END -- PROG [ARGS...]\n");
		return 2;
	}
	const char *end = argv[2];
	char **cmd = argv + 4;
	printf("$");
	for (int i = 0; cmd[i]; i++)
		printf(" %s", cmd[i]);
	printf("\n");
	fflush(stdout);
	double t0 = vd_seconds();
	pid_t pid = fork();
	if (pid < 0) {
		fprintf(stderr, "voxdag: cannot fork: %s\n", strerror(errno));
		return 1;
	}
	if (pid == 0) {
		execv(cmd[0], cmd);
		fprintf(stderr, "voxdag: cannot run '%s': %s\n", cmd[0],
			strerror(errno));
		_exit(127);
	}
	/* scancel's SIGTERM reaches the stage too; no end file is written
	 * then, so the driver asks Slurm why the job stopped */
	forward_pid = pid;
	signal(SIGTERM, forward);
	signal(SIGINT, forward);
	int status;
	struct rusage ru;
	while (wait4(pid, &status, 0, &ru) < 0)
		if (errno != EINTR)
			return 1;
	int code = WIFEXITED(status) ? WEXITSTATUS(status) : 0;
	int sig = WIFSIGNALED(status) ? WTERMSIG(status) : 0;
	if (sig == SIGTERM || sig == SIGINT)
		return 128 + sig;
	char text[256];
	snprintf(text, sizeof text, END_MAGIC "\nexit %d\nsignal %d\nseconds "
		 "%.3f\npeak_rss %llu\n", code, sig, vd_seconds() - t0,
		 (unsigned long long)ru.ru_maxrss * 1024);
	if (write_atomic(end, text) != 0) {
		fprintf(stderr, "voxdag: cannot write '%s': %s\n", end,
			strerror(errno));
		return 1;
	}
	return sig ? 128 + sig : code;
}
