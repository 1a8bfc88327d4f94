/* run.c - running the planned jobs: parallel within the job and memory
 * limits, skipping what is fresh, a log for each job that failed or said
 * something, progress, and the failure report. */
#include "pipeline.h"
#include "spawn/spawn.h"
#include "io/publish.h"

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <poll.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

/* A runner stopped by SIGTERM, SIGINT or SIGHUP says so, in runner.log
 * and on stderr, before it dies of the signal (its jobs die with it:
 * PR_SET_PDEATHSIG); otherwise an interrupted run's log just ends. Only
 * write(2) here: a handler may not use stdio. */
static int runner_log_fd = -1;

static void on_stop(int sig)
{
	int saved = errno;
	char line[160] = "voxdag: stopped by signal ";
	size_t n = strlen(line);
	char digits[12];
	int nd = 0;
	for (int v = sig; v > 0 && nd < 11; v /= 10)
		digits[nd++] = (char)('0' + v % 10);
	while (nd > 0)
		line[n++] = digits[--nd];
	const char *tail = "; finished jobs are kept, the same command "
			   "carries on\n";
	for (size_t i = 0; tail[i] && n < sizeof line - 1; i++)
		line[n++] = tail[i];
	run_log_flush_signal(); /* the lines before it first */
	if (runner_log_fd >= 0 && write(runner_log_fd, line, n) < 0) {
		/* nothing more can be done */
	}
	if (write(2, line, n) < 0) {
		/* nor here */
	}
	errno = saved;
	signal(sig, SIG_DFL);
	raise(sig);
}

static void log_path(const struct plan *p, const struct job *j, char *buf,
		     size_t cap)
{
	char id[200];
	snprintf(id, sizeof id, "%s", j->id);
	for (char *c = id; *c; c++)
		if (*c == '/')
			*c = '.';
	snprintf(buf, cap, "%s/logs/%s.log", p->dir, id);
}

/* Takes out/<name>/.lock; a second runner on the same directory refuses,
 * naming the first. A holder that exits between the two fcntl calls is
 * retried, so a run right after a killed one is never refused. */
static int take_lock(const struct plan *p)
{
	for (int tries = 0; tries < 50; tries++) {
		long holder;
		int fd = lock_take(p->dir, &holder);
		if (fd >= 0)
			return fd;
		if (fd == -2)
			return -1;
		if (holder > 0) {
			fprintf(stderr, "voxdag: another runner (pid %ld) is "
				"working on '%s'; wait for it or stop it "
				"first\n", holder, p->dir);
			return -1;
		}
		struct timespec ts = {0, 20 * 1000 * 1000};
		nanosleep(&ts, NULL);
	}
	fprintf(stderr, "voxdag: cannot take the lock on '%s'\n", p->dir);
	return -1;
}

/* The last lines of a job's log (the memory copy, which holds the same
 * as the file), for the failure report. */
static void print_tail(int fd, int lines)
{
	int dup_fd = fd >= 0 ? dup(fd) : -1;
	FILE *f = dup_fd >= 0 ? fdopen(dup_fd, "r") : NULL;
	if (!f) {
		if (dup_fd >= 0)
			close(dup_fd);
		return;
	}
	rewind(f);
	static char buf[64][512];
	int n = 0;
	while (fgets(buf[n % 64], sizeof buf[0], f))
		n++;
	fclose(f);
	int from = n > lines ? n - lines : 0;
	for (int i = from; i < n; i++)
		fprintf(stderr, "  | %s", buf[i % 64]);
}

static void print_command(FILE *f, const struct job *j)
{
	for (int i = 0; j->argv[i]; i++)
		fprintf(f, "%s%s", i ? " " : "", j->argv[i]);
	fputc('\n', f);
}

/* Makes the output's directory and drops its key: it is being replaced.
 * Consecutive jobs mostly write into the same directory (the cells): it is
 * made once, and a key known to be absent is not unlinked. */
static void prepare_output(struct job *j)
{
	static char made[1100];
	char dir[1100];
	snprintf(dir, sizeof dir, "%s", j->output);
	char *slash = strrchr(dir, '/');
	if (slash && !j->dir_output) {
		*slash = 0;
		if (strcmp(dir, made) != 0 && mkdir_p(dir) == 0)
			snprintf(made, sizeof made, "%s", dir);
	}
	job_key_drop(j);
}

/* Why start_job last failed. */
static char start_error[1500];

/* The launcher every local job is started through (voxdag-spawn --serve,
 * beside this program; pipeline/spawn/spawn.c says why): one process,
 * exec'd at the run's start, that vforks each job, so the job's peak
 * memory is its own and not the runner's, for the cost of a message
 * rather than of a process per job. launch_fd is the runner's end of
 * their socket (-1 without a launcher). Without it (not built or not
 * installed, or dead) jobs are started directly and their peaks include
 * the runner's memory, which runner.log says once. */
static char spawn_path[PATH_MAX];
static int launch_fd = -1;
static int launch_used;  /* a launcher was started (it may be gone) */
static pid_t launch_pid; /* its pid while not reaped, else 0 */

/* Jobs' ends read from the socket and not taken yet (at most one per
 * running job, so a short list). */
static struct vd_spawn_rec *spawn_recs;
static int nspawn_recs, spawn_cap;

/* The CPU of the jobs the launcher reported, to tell its own cost (its
 * total, seen when it is reaped, minus theirs) from theirs; and that cost:
 * the runner's, added to its figure in runner.log. */
static double launched_cpu, spawn_cpu;

/* Pids of the local jobs started directly while a launcher runs (a
 * request too large for it): reaped with wait4. */
static pid_t *direct_pids;
static int ndirect;

/* The runner's signal mask before it blocked SIGCHLD (to wait for it
 * with sigtimedwait): the launcher's, and children get it back before
 * they exec. */
static sigset_t child_mask;

static double rusage_seconds(const struct rusage *r)
{
	return (double)r->ru_utime.tv_sec + r->ru_utime.tv_usec * 1e-6 +
	       (double)r->ru_stime.tv_sec + r->ru_stime.tv_usec * 1e-6;
}

static void spawn_setup(void)
{
	int sv[2] = {-1, -1};
	ssize_t n = readlink("/proc/self/exe", spawn_path, sizeof spawn_path - 1);
	char *slash = n > 0 ? memrchr(spawn_path, '/', (size_t)n) : NULL;
	if (!slash || (size_t)(slash - spawn_path) + 14 >= sizeof spawn_path) {
		spawn_path[0] = 0;
	} else {
		strcpy(slash + 1, "voxdag-spawn");
		if (access(spawn_path, X_OK) != 0 ||
		    socketpair(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0, sv) != 0)
			spawn_path[0] = 0;
	}
	if (spawn_path[0]) {
		char fdarg[16];
		snprintf(fdarg, sizeof fdarg, "%d", sv[1]);
		char *argv[] = {spawn_path, "--serve", fdarg, NULL};
		pid_t self = getpid();
		pid_t pid = vfork();
		if (pid == 0) {
			/* it dies with the runner, and its jobs with it */
			prctl(PR_SET_PDEATHSIG, SIGKILL);
			if (getppid() != self)
				_exit(127);
			fcntl(sv[1], F_SETFD, 0);
			execv(argv[0], argv);
			_exit(127);
		}
		close(sv[1]);
		if (pid > 0) {
			launch_fd = sv[0];
			launch_pid = pid;
			launch_used = 1;
			return;
		}
		close(sv[0]);
		spawn_path[0] = 0;
	}
	run_log("no voxdag-spawn beside the runner: jobs start directly, "
		 "and their peak memory includes the runner's");
}

/* The launcher is gone (EOF on its socket, or reaped): one line, and its
 * running jobs (killed with it) are taken as failed by reap_local. */
static void launcher_lost(int status, int reaped)
{
	pid_t pid = launch_pid;
	if (!reaped)
		while (waitpid(pid, &status, 0) < 0 && errno == EINTR)
			;
	launch_pid = 0;
	close(launch_fd);
	launch_fd = -1;
	char how[64];
	if (WIFSIGNALED(status))
		snprintf(how, sizeof how, "killed by signal %d", WTERMSIG(status));
	else
		snprintf(how, sizeof how, "exit %d", WEXITSTATUS(status));
	run_log("the job launcher (pid %ld) died (%s): its running jobs "
		 "failed, later ones start directly", (long)pid, how);
	fprintf(stderr, "voxdag: the job launcher voxdag-spawn died (%s); "
		"the jobs it was running failed with it\n", how);
}

/* Takes every record waiting on the socket into spawn_recs (blocking
 * until one comes when `wait`). Returns -1 when the launcher is gone. */
static int spawn_drain(int wait)
{
	while (launch_fd >= 0) {
		struct vd_spawn_rec r;
		ssize_t n = recv(launch_fd, &r, sizeof r, wait ? 0 : MSG_DONTWAIT);
		if (n < 0 && errno == EINTR)
			continue;
		if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK))
			return 0;
		if (n <= 0) {
			launcher_lost(0, 0);
			return -1;
		}
		if (n != (ssize_t)sizeof r || r.magic != VD_SPAWN_MAGIC)
			continue; /* not ours: nothing to use */
		if (nspawn_recs == spawn_cap) {
			int cap = spawn_cap ? 2 * spawn_cap : 16;
			void *q = realloc(spawn_recs, (size_t)cap * sizeof r);
			if (!q)
				continue; /* the job is then reported without a peak */
			spawn_recs = q;
			spawn_cap = cap;
		}
		spawn_recs[nspawn_recs++] = r;
		if (wait)
			return 0;
	}
	return -1;
}

/* Asks the launcher to start argv with log fd. Returns the pid, -1 with
 * start_error set, or -2 when the request cannot go to the launcher (too
 * large, or the launcher is gone): the caller starts the job itself. */
static pid_t launch(char **argv, int fd, char *start_err, size_t cap)
{
	size_t len = 0;
	for (int i = 0; argv[i]; i++)
		len += strlen(argv[i]) + 1;
	if (len > VD_LAUNCH_MAX_REQ)
		return -2;
	char *buf = malloc(len);
	if (!buf)
		return -2;
	char *b = buf;
	for (int i = 0; argv[i]; i++) {
		size_t l = strlen(argv[i]) + 1;
		memcpy(b, argv[i], l);
		b += l;
	}
	union vd_spawn_ctl ctl;
	struct iovec iov = {buf, len};
	struct msghdr m;
	vd_spawn_msg(&m, &iov, &ctl);
	struct cmsghdr *c = CMSG_FIRSTHDR(&m);
	c->cmsg_level = SOL_SOCKET;
	c->cmsg_type = SCM_RIGHTS;
	c->cmsg_len = CMSG_LEN(sizeof(int));
	memcpy(CMSG_DATA(c), &fd, sizeof fd);
	ssize_t n;
	while ((n = sendmsg(launch_fd, &m, MSG_NOSIGNAL)) < 0 && errno == EINTR)
		;
	free(buf);
	if (n < 0) {
		if (errno == EMSGSIZE || errno == ENOBUFS)
			return -2;
		launcher_lost(0, 0);
		return -2;
	}
	/* its reply comes next, after any job ends it reported first */
	for (;;) {
		for (int i = 0; i < nspawn_recs; i++) {
			struct vd_spawn_rec r = spawn_recs[i];
			if (r.type != VD_LAUNCH_STARTED && r.type != VD_LAUNCH_FAILED)
				continue;
			spawn_recs[i] = spawn_recs[--nspawn_recs];
			if (r.type == VD_LAUNCH_STARTED)
				return (pid_t)r.pid;
			snprintf(start_err, cap, "%s", strerror(r.status));
			return -1;
		}
		if (spawn_drain(1) != 0)
			return -2; /* gone: said once; started directly */
	}
}

/* Ends the launcher at the end of the run (it exits when its socket
 * closes) and counts its own CPU. */
static void launcher_stop(void)
{
	if (launch_fd < 0)
		return;
	close(launch_fd);
	launch_fd = -1;
	int status;
	struct rusage ru;
	while (wait4(launch_pid, &status, 0, &ru) < 0 && errno == EINTR)
		;
	launch_pid = 0;
	double own = rusage_seconds(&ru) - launched_cpu;
	spawn_cpu += own > 0 ? own : 0;
}

static pid_t start_job(const struct plan *p, struct job *j)
{
	(void)p;
	prepare_output(j);
	/* the log's first line, made here: the child may only make system
	 * calls (vfork: it shares our memory until it execs, which spares
	 * copying the runner's page tables for every one of 100,000 jobs) */
	size_t len = 2;
	for (int i = 0; j->argv[i]; i++)
		len += strlen(j->argv[i]) + 1;
	char **argv = j->argv;
	char *head = malloc(len + 1), failed[PATH_MAX + 64];
	if (!head)
		return -1;
	int nfailed = snprintf(failed, sizeof failed, "voxdag: cannot run "
			       "'%s'\n", argv[0]);
	char *h = head;
	*h++ = '$';
	for (int i = 0; j->argv[i]; i++)
		h += sprintf(h, " %s", j->argv[i]);
	*h++ = '\n';
	/* The job writes into memory; its log file is made when it ends,
	 * and only when it failed or said something (save_log): creating a
	 * file per job was most of the runner's own cost on 100,000-cell
	 * plans. Nothing is lost: the runner holds the memory file until
	 * the end is recorded, and a killed runner takes its jobs along. */
	int fd = memfd_create("voxdag-job-log", MFD_CLOEXEC);
	size_t hlen = (size_t)(h - head);
	ssize_t wrote = fd >= 0 ? write(fd, head, hlen) : -1;
	free(head);
	if (wrote != (ssize_t)hlen) {
		int e = wrote < 0 ? errno : ENOSPC;
		snprintf(start_error, sizeof start_error, "cannot make its log "
			 "in memory: %s", strerror(e));
		if (fd >= 0)
			close(fd);
		return -1;
	}
	j->log_fd = fd;
	j->log_head = (off_t)hlen;
	if (launch_fd >= 0) {
		pid_t pid = launch(argv, fd, start_error, sizeof start_error);
		if (pid != -2)
			return pid;
	}
	pid_t pid = vfork();
	if (pid == 0) {
		/* die with the runner: a killed runner leaves no orphans */
		prctl(PR_SET_PDEATHSIG, SIGKILL);
		sigprocmask(SIG_SETMASK, &child_mask, NULL);
		dup2(fd, 1); /* the copies lose O_CLOEXEC; fd closes at exec */
		dup2(fd, 2);
		int null = open("/dev/null", O_RDONLY);
		if (null >= 0)
			dup2(null, 0);
		execv(argv[0], argv);
		if (write(2, failed, (size_t)nfailed) < 0) {
			/* nothing more to say */
		}
		_exit(127);
	}
	int saved = errno;
	if (pid < 0)
		snprintf(start_error, sizeof start_error, "%s", strerror(saved));
	else if (launch_used)
		direct_pids[ndirect++] = pid; /* beside the launcher's jobs */
	return pid;
}

/* Ends j's in-memory log: written to logs/<job>.log when the job failed
 * or said more than its command line, else any older log of the job is
 * removed (it told of an earlier run). Returns 0, or -1 with why in err
 * when the log could not be written (the memory copy stays open for the
 * caller to show; log_close ends it). */
static int save_log(const struct plan *p, struct job *j, int failed,
		    char *err, size_t cap)
{
	char lp[1300];
	log_path(p, j, lp, sizeof lp);
	off_t size = j->log_fd >= 0 ? lseek(j->log_fd, 0, SEEK_END) : 0;
	if (!failed && size <= j->log_head) {
		unlink(lp);
		return 0;
	}
	int out = open(lp, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
	off_t at = 0;
	int e = out < 0 ? errno : 0;
	while (!e && at < size) {
		char buf[65536];
		ssize_t n = pread(j->log_fd, buf, sizeof buf, at);
		if (n <= 0) {
			e = n < 0 ? errno : EIO;
			break;
		}
		if (vd_pwrite_full(out, buf, (size_t)n, (uint64_t)at) != 0)
			e = errno ? errno : ENOSPC;
		at += n;
	}
	if (out >= 0 && close(out) != 0 && !e)
		e = errno;
	if (!e)
		return 0;
	snprintf(err, cap, "cannot %s its log '%s': %s", out < 0 ? "create" :
		 "write", lp, strerror(e));
	return -1;
}

static void log_close(struct job *j)
{
	if (j->log_fd >= 0)
		close(j->log_fd);
	j->log_fd = -1;
}

/* 0 ready, 1 waiting, 2 blocked, 3 waiting only for jobs Slurm has (so
 * it can be submitted with afterok on them). */
static int deps_state(const struct plan *p, const struct job *j)
{
	if (j->nbad)
		return 2;
	if (p->cfg->executor != EXECUTOR_SLURM)
		return j->nwait ? 1 : 0; /* counted as dependencies end */
	int waiting = 0, in_slurm = 0;
	for (int k = 0; k < j->ndeps; k++) {
		const struct job *d = &p->jobs[j->deps[k]];
		if (d->state == JOB_FAILED || d->state == JOB_BLOCKED)
			return 2;
		if (d->state == JOB_RUNNING && d->slurm_id > 0)
			in_slurm = 1;
		else if (d->state != JOB_DONE && d->state != JOB_SKIPPED)
			waiting = 1;
	}
	return waiting ? 1 : in_slurm ? 3 : 0;
}

/* The one job that can start while nothing runs, or -1. Such a job runs
 * alone to its end: no other job's dependencies can finish meanwhile, and
 * the plan grows only while nothing runs. Scans from `from` and stops at a
 * second candidate, so the runner's cost stays near-linear in jobs. */
static int lone_ready(const struct plan *p, int from)
{
	int found = -1;
	for (int i = from; i < p->n; i++) {
		const struct job *j = &p->jobs[i];
		if (j->state != JOB_PENDING || deps_state(p, j) != 0)
			continue;
		if (found >= 0)
			return -1;
		found = i;
	}
	return found;
}

/* A job that runs alone gets the threads of every job slot, as voxelize
 * always does: the stages write the same bytes for any --threads (which is
 * why it is not part of a job's key), and the chain of root jobs after
 * voxelize (svo-to-dag, symmetry-merge, encode on a one-cell scene or the
 * root merges) would otherwise leave the other cores idle. Returns 0, or
 * -1 when out of memory (the job keeps its threads). */
static int widen_threads(const struct config *c, struct job *j)
{
	int all = c->threads * c->jobs;
	for (int i = 1; j->argv[i] && j->argv[i + 1]; i++) {
		if (strcmp(j->argv[i], "--threads") != 0)
			continue;
		if (atoi(j->argv[i + 1]) >= all)
			return 0;
		char *v = malloc(16);
		if (!v)
			return -1;
		snprintf(v, 16, "%d", all);
		free(j->argv[i + 1]);
		j->argv[i + 1] = v;
		return 0;
	}
	return 0;
}

static void fmt_time(char *buf, size_t cap, double s)
{
	if (s < 0 || s > 1e7)
		snprintf(buf, cap, "?");
	else
		snprintf(buf, cap, "%d:%02d:%02d", (int)s / 3600, (int)s / 60 % 60,
			 (int)s % 60);
}

static uint64_t job_voxels(const struct job *j)
{
	/* voxels handled: the level-L count of the first chunk input */
	for (int i = 0; i < j->ninputs; i++) {
		struct vd_chunk_header h;
		if (plan_chunk_header(j->inputs[i], &h) == VD_OK &&
		    h.level_count > 0)
			return h.level_nodes[h.level_count - 1];
	}
	return 0;
}

/* The last line of a running job's log (what a long job last said),
 * trimmed; nothing while the log holds only its command line. */
static void last_run_log(const struct job *j, char *buf, size_t cap)
{
	buf[0] = 0;
	off_t n = j->log_fd >= 0 ? lseek(j->log_fd, 0, SEEK_END) : -1;
	if (n <= j->log_head)
		return;
	char tail[512];
	off_t from = n - (off_t)sizeof tail + 1;
	if (from < j->log_head)
		from = j->log_head;
	ssize_t got = pread(j->log_fd, tail, (size_t)(n - from), from);
	if (got <= 0)
		return;
	tail[got] = 0;
	while (got > 0 && (tail[got - 1] == '\n' || tail[got - 1] == '\r'))
		tail[--got] = 0;
	char *line = strrchr(tail, '\n');
	line = line ? line + 1 : tail;
	/* "voxelize: [  12.0s] voxelizing cells 3/8, ..." -> after "] " */
	char *msg = strstr(line, "] ");
	snprintf(buf, cap, "%s", msg ? msg + 2 : line);
}

static void progress(const struct plan *p, double t0, int tty, int final)
{
	int done = 0, running = 0, failed = 0;
	uint64_t vox = 0;
	for (int i = 0; i < p->n; i++) {
		const struct job *j = &p->jobs[i];
		done += j->state == JOB_DONE || j->state == JOB_SKIPPED;
		running += j->state == JOB_RUNNING;
		failed += j->state == JOB_FAILED || j->state == JOB_BLOCKED;
		if (j->state == JOB_DONE)
			vox += j->voxels;
	}
	double el = vd_seconds() - t0;
	char e[32], eta[32], fails[48] = "";
	fmt_time(e, sizeof e, el);
	int left = p->n - done - failed;
	fmt_time(eta, sizeof eta, done && p->expanded ? el / done * left : -1);
	if (failed)
		snprintf(fails, sizeof fails, ", %d failed or blocked", failed);
	/* with one job running long, what it says is the news */
	char said[200] = "";
	if (running == 1 && !final)
		for (int i = 0; i < p->n; i++)
			if (p->jobs[i].state == JOB_RUNNING) {
				char line[160];
				last_run_log(&p->jobs[i], line, sizeof line);
				if (*line)
					snprintf(said, sizeof said, " [%s: %s]",
						 p->jobs[i].id, line);
			}
	fprintf(stderr, "%svoxdag: %d/%d jobs done, %d running%s, %.1f Mvoxels/s, "
		"elapsed %s, ETA %s%s%s", tty ? "\r\033[K" : "", done, p->n,
		running, fails, el > 0 ? (double)vox / el / 1e6 : 0.0, e, eta,
		said, tty && !final ? "" : "\n");
}

/* The local jobs running now (indices), so a reaped pid is found without
 * a walk over every job. */
static int *running_local, nrunning_local;

/* Takes running job r (an index in running_local) off the list, filling
 * in *e what is known of every end. */
static int take_running(const struct plan *p, int r, struct job_end *e)
{
	int i = running_local[r];
	running_local[r] = running_local[--nrunning_local];
	memset(e, 0, sizeof *e);
	e->seconds = vd_seconds() - p->jobs[i].start;
	e->cpu = -1;
	return i;
}

static void set_status(struct job_end *e, int status)
{
	e->exited = WIFEXITED(status);
	e->code = e->exited ? WEXITSTATUS(status) : 0;
	e->signal = WIFSIGNALED(status) ? WTERMSIG(status) : 0;
}

static int is_direct(pid_t pid, int drop)
{
	for (int k = 0; k < ndirect; k++)
		if (direct_pids[k] == pid) {
			if (drop)
				direct_pids[k] = direct_pids[--ndirect];
			return 1;
		}
	return 0;
}

/* An end the launcher reported, or a launched job failed with a dead
 * launcher: its index (filling *e), else -1. */
static int reap_launched(const struct plan *p, struct job_end *e)
{
	if (launch_fd >= 0)
		spawn_drain(0);
	while (nspawn_recs > 0) {
		struct vd_spawn_rec sr = spawn_recs[--nspawn_recs];
		if (sr.type != VD_LAUNCH_ENDED)
			continue; /* a reply to no request: nothing to use */
		launched_cpu += (double)(sr.utime_us + sr.stime_us) / 1e6;
		for (int r = 0; r < nrunning_local; r++) {
			const struct job *j = &p->jobs[running_local[r]];
			if (j->state != JOB_RUNNING || j->pid != sr.pid)
				continue;
			int i = take_running(p, r, e);
			e->peak_rss = sr.peak_rss;
			e->cpu = (double)(sr.utime_us + sr.stime_us) / 1e6;
			set_status(e, sr.status);
			return i;
		}
	}
	if (launch_fd >= 0)
		return -1;
	/* the launcher is gone, and its jobs with it (PR_SET_PDEATHSIG) */
	for (int r = 0; r < nrunning_local; r++) {
		const struct job *j = &p->jobs[running_local[r]];
		if (j->state != JOB_RUNNING || is_direct(j->pid, 0))
			continue;
		int i = take_running(p, r, e);
		snprintf(e->reason, sizeof e->reason, "the job launcher "
			 "(voxdag-spawn) died while it ran");
		return i;
	}
	return -1;
}

/* The index of a local job that ended (filling *e), -1 when none has yet,
 * -2 when there is no child left to wait for. */
static int reap_local(const struct plan *p, struct job_end *e)
{
	if (launch_used) {
		int i = reap_launched(p, e);
		if (i >= 0 || ndirect == 0)
			return i;
	}
	int status;
	struct rusage ru;
	pid_t pid = wait4(-1, &status, WNOHANG, &ru);
	if (pid == 0 || (pid < 0 && errno == EINTR))
		return -1;
	if (pid < 0)
		return launch_fd >= 0 ? -1 : -2;
	if (launch_pid > 0 && pid == launch_pid) {
		if (launch_fd >= 0)
			launcher_lost(status, 1);
		launch_pid = 0;
		return -1;
	}
	if (launch_used)
		is_direct(pid, 1);
	for (int r = 0; r < nrunning_local; r++) {
		const struct job *j = &p->jobs[running_local[r]];
		if (j->state != JOB_RUNNING || j->pid != pid)
			continue;
		int i = take_running(p, r, e);
		/* started directly: its peak includes the runner's memory */
		e->peak_rss = (uint64_t)ru.ru_maxrss * 1024;
		e->cpu = rusage_seconds(&ru);
		set_status(e, status);
		return i;
	}
	return -1; /* not one of ours */
}

/* Records how j ended: its key when it succeeded, else the failure report
 * (job, command line, Slurm's reason, the end of its log; one line only
 * when it is not the run's first failure). Returns 0 when it succeeded. */
static int end_job(struct plan *p, struct job *j, const struct job_end *e,
		   int tty, int first_failure)
{
	j->seconds = e->seconds;
	j->peak_rss = e->peak_rss;
	j->cpu = e->cpu;
	int ok = e->exited && e->code == 0 && !*e->reason;
	char key_error[1500] = "";
	/* a local job's log first: a job whose warnings cannot be kept is
	 * not trusted either (the rerun says them again) */
	int log_saved = j->log_fd < 0 ||
		save_log(p, j, !ok, key_error, sizeof key_error) == 0;
	if (!log_saved && !ok)
		key_error[0] = 0; /* the job's own cause is the news */
	if (!log_saved)
		ok = 0;
	if (ok && job_key_write(j, key_error, sizeof key_error) != 0)
		ok = 0;
	if (ok) {
		job_set_state(p, j, JOB_DONE);
		if (!j->cell) /* a cell's count was read when it was planned */
			j->voxels = job_voxels(j);
		char cpu[32] = "";
		if (j->cpu >= 0)
			snprintf(cpu, sizeof cpu, " (cpu %.2fs)", j->cpu);
		run_log("done %s in %.2fs%s, peak %llu MiB (estimate %llu MiB)",
			 j->id, j->seconds, cpu,
			 (unsigned long long)(j->peak_rss >> 20),
			 (unsigned long long)(j->mem_estimate >> 20));
		if (j->slurm_id > 0)
			slurm_forget(p, j);
		/* something new is known only when the last planned job of a
		 * declared job ends (its cells, its merges, its output) */
		if (p->unfinished[j->decl] == 0)
			plan_expand(p);
		return 0;
	}
	job_set_state(p, j, JOB_FAILED);
	char lp[1300];
	log_path(p, j, lp, sizeof lp);
	run_log("failed %s%s%s%s%s", j->id, *e->reason ? ": " : "", e->reason,
		 *key_error ? ": " : "", key_error);
	if (tty)
		fputs("\r\033[K", stderr);
	if (!first_failure) {
		/* jobs that were running beside the first failure: one line
		 * each, so the first cause is not lost in their repetitions */
		char how[64];
		if (!e->exited)
			snprintf(how, sizeof how, "killed by signal %d", e->signal);
		else
			snprintf(how, sizeof how, "exit %d", e->code);
		fprintf(stderr, "voxdag: job %s failed too (%s), log: %s\n",
			j->id, *e->reason ? e->reason : *key_error ?
			"its key or log could not be written" : how,
			log_saved ? lp : "not saved");
		if (j->slurm_id > 0)
			slurm_forget(p, j);
		return -1;
	}
	if (*key_error) {
		/* the stage succeeded; its output stays but is not trusted
		 * without its key: the rerun makes it again */
		fprintf(stderr, "voxdag: job %s finished but %s\n", j->id,
			key_error);
		if (j->slurm_id > 0)
			slurm_forget(p, j);
		return -1;
	}
	if (*e->reason)
		fprintf(stderr, "voxdag: job %s did not finish: %s\n", j->id,
			e->reason);
	else if (!e->exited)
		fprintf(stderr, "voxdag: job %s killed by signal %d\n", j->id,
			e->signal);
	else
		fprintf(stderr, "voxdag: job %s failed (exit %d)\n", j->id,
			e->code);
	fprintf(stderr, "  command: ");
	print_command(stderr, j);
	if (log_saved)
		fprintf(stderr, "  log: %s\n", lp);
	else
		fprintf(stderr, "  log: not saved; it ended with:\n");
	if (j->log_fd >= 0) {
		print_tail(j->log_fd, 8);
	} else { /* Slurm wrote it */
		int fd = open(lp, O_RDONLY | O_CLOEXEC);
		print_tail(fd, 8);
		if (fd >= 0)
			close(fd);
	}
	if (j->slurm_id > 0)
		slurm_forget(p, j);
	return -1;
}

/* Records how j ended (end_job) and lets its in-memory log go. */
static int finish_job(struct plan *p, struct job *j, const struct job_end *e,
		      int tty, int first_failure)
{
	ptrdiff_t i = j - p->jobs; /* end_job may plan more: jobs move */
	int r = end_job(p, j, e, tty, first_failure);
	log_close(&p->jobs[i]);
	return r;
}

/* With Slurm, jobs already submitted with afterok on a failed job would
 * wait forever: cancel them and mark them blocked. */
static void cancel_dependents(struct plan *p, int *running)
{
	int changed = 1;
	while (changed) {
		changed = 0;
		for (int i = 0; i < p->n; i++) {
			struct job *j = &p->jobs[i];
			if (j->state != JOB_RUNNING || j->slurm_id <= 0 ||
			    deps_state(p, j) != 2)
				continue;
			slurm_cancel(p, j);
			job_set_state(p, j, JOB_BLOCKED);
			run_log("blocked %s (cancelled in Slurm)", j->id);
			(*running)--;
			changed = 1;
		}
	}
}

/* The state of one run shared by its steps below: what run_pipeline's
 * locals were before it was split. */
struct run_state {
	struct plan *p;
	const struct run_opts *o;
	const struct config *c;
	int slurm;
	int tty;
	double t0, last;
	/* how often progress is shown (quiet: how long a wait may last) */
	double every;
	uint64_t mem_used;
	int running, failures;
	/* jobs before `scan_from` have all left JOB_PENDING (states only move
	 * forward), so each pass starts there; locally a pass stops once
	 * every slot is taken: the runner's cost stays near-linear in jobs */
	int scan_from;
	/* SIGCHLD, blocked while the runner runs locally */
	sigset_t chld;
	/* Slurm: a job ended or was submitted since the last pass */
	int dirty;
	/* keep: jobs planned at the last sweep over every job (the plan grew
	 * since: more readers known); a job needs what keep: deleted: no new
	 * job, then start over */
	int keep_swept, restart;
};

/* Removes the staging entries of dead processes under the outputs (every
 * one with `all`: no job of ours runs anywhere) and says so in
 * runner.log. */
static void sweep_staging(const struct plan *p, int all)
{
	long n = vd_staging_sweep(p->dir, all);
	if (n)
		run_log("removed %ld staging entr%s of killed processes", n,
			 n == 1 ? "y" : "ies");
}

/* Step 1 of a run: creates the logs directory, takes the lock and the
 * keys, checks Slurm, opens runner.log, catches the stop signals, starts
 * the launcher (locally) and expands the plan. Returns 0, or 1 after
 * saying why on stderr. */
static int run_open(struct plan *p)
{
	const struct config *c = p->cfg;
	char logs[1200];
	snprintf(logs, sizeof logs, "%s/logs", p->dir);
	if (mkdir_p(logs) != 0) {
		fprintf(stderr, "voxdag: cannot create '%s': %s\n", logs,
			strerror(errno));
		return 1;
	}
	if (take_lock(p) < 0 || keys_open(p->dir, 1) != 0)
		return 1;
	int slurm = c->executor == EXECUTOR_SLURM;
	char rl[1300];
	snprintf(rl, sizeof rl, "%s/runner.log", logs);
	runner_log_fd = run_log_open(rl);
	signal(SIGTERM, on_stop);
	signal(SIGINT, on_stop);
	signal(SIGHUP, on_stop);
	run_log("run %s (pid %ld)", c->path, (long)getpid());
	if (slurm && slurm_preflight(p) != 0)
		return 1;
	/* what killed runs left half-written (locally: with Slurm, jobs of a
	 * killed driver may still run elsewhere, under pids not ours) */
	if (!slurm)
		sweep_staging(p, 0);
	if (!slurm)
		spawn_setup();
	plan_expand(p);
	return 0;
}

/* Submits job i to Slurm, or starts it locally when a slot and the memory
 * budget allow (with every thread when it runs alone: i == lone). Returns
 * 1 when it now runs, 0 when it waits or failed (counted in s). */
static int launch_ready(struct run_state *s, int i, int lone)
{
	struct plan *p = s->p;
	const struct config *c = s->c;
	struct job *j = &p->jobs[i];
	if (s->slurm) {
		/* bundled and submitted at the end of the pass (slurm_flush):
		 * its key is gone from now on, so it is not looked for again */
		prepare_output(j);
		j->fresh_checked = 1;
		slurm_want(p, j);
		return 0;
	} else {
		if (s->running >= c->jobs ||
		    (s->running > 0 &&
		     s->mem_used + j->mem_estimate > c->mem_budget))
			return 0;
		if (i == lone && s->running == 0)
			widen_threads(c, j);
		j->pid = start_job(p, j);
		if (j->pid < 0) {
			log_close(j);
			fprintf(stderr, "%svoxdag: cannot start "
				"job %s: %s\n", s->tty ? "\r\033[K" : "",
				j->id, start_error);
			job_set_state(p, j, JOB_FAILED);
			s->failures++;
			return 0;
		}
		running_local[nrunning_local++] = i;
		s->mem_used += j->mem_estimate;
		run_log("started %s (estimate %llu MiB)", j->id,
			 (unsigned long long)(j->mem_estimate >> 20));
	}
	return 1;
}

/* Looks at job i in a pass over the plan: logs a skip found when
 * planning, blocks it behind a failed dependency, adopts a live Slurm
 * submission, skips it when its output is fresh, else launches it
 * (launch_ready) once its dependencies are done, and marks it running. */
static void consider_job(struct run_state *s, int i, int lone)
{
	struct plan *p = s->p;
	struct job *j = &p->jobs[i];
	if (j->state == JOB_SKIPPED && !j->logged) {
		/* found fresh when planned */
		run_log("skipped %s (output is fresh)", j->id);
		j->logged = 1;
	}
	if (j->state != JOB_PENDING)
		return;
	int ds = deps_state(p, j);
	if (ds == 2) {
		job_set_state(p, j, JOB_BLOCKED);
		run_log("blocked %s", j->id);
		return;
	}
	if (s->slurm && !j->adopt_checked) {
		/* a previous driver's submission, still alive */
		j->adopt_checked = 1;
		if (slurm_adopt(p, j)) {
			j->state = JOB_RUNNING;
			j->start = vd_seconds();
			s->running++;
			run_log("adopted %s (Slurm job %s)", j->id,
				 slurm_bundle_name(j));
			return;
		}
	}
	if (ds == 1 || (ds == 3 && !s->slurm))
		return;
	char why[600] = "";
	/* a key found absent when planned is absent still: only
	 * the runner writes keys, and only of jobs it ran */
	int fresh = ds == 0 && !j->fresh_checked ?
		    job_is_fresh(j, why, sizeof why) : 0;
	if (fresh == 1) {
		job_set_state(p, j, JOB_SKIPPED);
		j->logged = 1;
		run_log("skipped %s (output is fresh)", j->id);
		keep_sweep(p, i);
		return;
	}
	if (fresh < 0) {
		run_log("failed %s: %s", j->id, why);
		fprintf(stderr, "%svoxdag: cannot check job %s: %s\n",
			s->tty ? "\r\033[K" : "", j->id, why);
		job_set_state(p, j, JOB_FAILED);
		s->failures++;
		return;
	}
	if (*why) {
		run_log("rebuilding %s: %s", j->id, why);
		if (!s->o->quiet)
			fprintf(stderr, "%svoxdag: rebuilding %s: %s\n",
				s->tty ? "\r\033[K" : "", j->id, why);
	}
	/* once the run is to start over, the pass only looks for more jobs
	 * that need what keep: deleted, so that one start over serves them */
	if (keep_revive(p, j, why, sizeof why)) {
		run_log("%s %s; the run starts over", j->id, why);
		if (!s->o->quiet)
			fprintf(stderr, "%svoxdag: %s %s\n",
				s->tty ? "\r\033[K" : "", j->id, why);
		s->restart = 1;
	}
	if (s->restart || !launch_ready(s, i, lone))
		return;
	j->state = JOB_RUNNING;
	j->start = vd_seconds();
	s->running++;
}

/* One pass over the plan from s->scan_from: starts what is ready
 * (consider_job), until every local slot is taken or, locally, once a
 * job has failed. */
static void start_ready(struct run_state *s)
{
	struct plan *p = s->p;
	int all_left = 1;
	int lone = !s->slurm && s->running == 0 && s->c->jobs > 1 ?
		   lone_ready(p, s->scan_from) : -1;
	if (s->keep_swept != p->n) {
		keep_sweep(p, -1);
		s->keep_swept = p->n;
	}
	for (int i = s->scan_from; i < p->n; i++) {
		struct job *j = &p->jobs[i];
		if (all_left && j->state != JOB_PENDING &&
		    (j->state != JOB_SKIPPED || j->logged))
			s->scan_from = i + 1;
		else
			all_left = 0;
		if (!s->slurm && s->running >= s->c->jobs)
			break;
		/* after a failure, no new local job: the cause (a full
		 * disk, a budget) would fail them too, and the rerun
		 * keeps every finished one */
		if (!s->slurm && s->failures)
			break;
		consider_job(s, i, lone);
	}
	if (s->slurm) {
		int failed;
		s->running += slurm_flush(p, &failed);
		if (failed) {
			s->failures += failed;
			cancel_dependents(p, &s->running);
		}
	}
}

/* With nothing running: expands the plan, and when that added no job,
 * blocks every job still pending. Returns 1 when the run is over, 0 when
 * new jobs came to start. */
static int run_idle(struct run_state *s)
{
	struct plan *p = s->p;
	int before = p->n;
	plan_expand(p);
	if (p->n != before)
		return 0;
	int pending = 0;
	for (int i = 0; i < p->n; i++)
		pending += p->jobs[i].state == JOB_PENDING;
	if (!pending)
		return 1;
	/* pending jobs whose dependencies can never finish */
	for (int i = 0; i < p->n; i++)
		if (p->jobs[i].state == JOB_PENDING)
			job_set_state(p, &p->jobs[i], JOB_BLOCKED);
	return 1;
}

/* No job has ended: sleeps until one may have (a launcher message,
 * SIGCHLD, 200 ms with Slurm) or progress is due, and shows progress
 * when it is. */
static void run_wait(struct run_state *s)
{
	run_log_flush();
	if (s->slurm) {
		struct timespec ts = {0, 200 * 1000 * 1000};
		nanosleep(&ts, NULL);
	} else {
		double left = s->last + s->every - vd_seconds();
		if (left < 0.01)
			left = 0.01;
		struct timespec ts = {(time_t)left,
				      (long)((left - (time_t)left) * 1e9)};
		if (launch_fd >= 0) {
			/* ends come from the launcher; a job
			 * started directly beside it is
			 * looked for every 20 ms */
			if (ndirect && left > 0.02)
				ts = (struct timespec){0, 20000000};
			struct pollfd pfd = {launch_fd, POLLIN, 0};
			ppoll(&pfd, 1, &ts, NULL);
		} else {
			sigtimedwait(&s->chld, NULL, &ts);
		}
	}
	keys_sync(0);
	/* quiet, the clock still moves on: else every
	 * wait after the first 5 s would end at once */
	double now = vd_seconds();
	if (now - s->last >= s->every) {
		if (!s->o->quiet)
			progress(s->p, s->t0, s->tty, 0);
		s->last = now;
	}
}

/* Job `done` ended as `end` says: gives its slot and memory back and
 * records it (finish_job); a failure is counted and, with Slurm, its
 * submitted dependents are cancelled. */
static void run_reaped(struct run_state *s, int done,
		       const struct job_end *end)
{
	struct plan *p = s->p;
	struct job *j = &p->jobs[done];
	s->running--;
	if (!s->slurm)
		s->mem_used -= j->mem_estimate;
	if (finish_job(p, j, end, s->tty, s->failures == 0) != 0) {
		s->failures++;
		if (s->slurm)
			cancel_dependents(p, &s->running);
	} else {
		keep_sweep(p, done);
	}
}

/* The last step of a run: final progress, the launcher stopped, the
 * summary line in runner.log, and the failure message or the report.
 * Returns the run's exit code (0 or 1). */
static int run_close(struct run_state *s)
{
	struct plan *p = s->p;
	const struct config *c = s->c;
	if (!s->o->quiet)
		progress(p, s->t0, s->tty, 1);
	int blocked = 0;
	for (int i = 0; i < p->n; i++)
		blocked += p->jobs[i].state == JOB_BLOCKED;
	launcher_stop();
	keys_sync(1);
	sweep_staging(p, s->slurm); /* nothing of ours runs now */
	if (s->slurm)
		slurm_done(p);
	if (s->restart && !s->failures) {
		run_log("starting over (keep:)");
		run_log_flush();
		return RUN_AGAIN;
	}
	/* the runner's own cost against the stages' (children reaped) */
	struct rusage self, kids;
	getrusage(RUSAGE_SELF, &self);
	getrusage(RUSAGE_CHILDREN, &kids);
	/* starting jobs is the runner's work, though the launcher did it as
	 * its child */
	if (s->slurm) /* the children are sbatch, squeue, scontrol, scancel:
		       * the driver's cost; the stages' is in their ends */
		run_log("finished: %d failed, %d blocked, %.1fs, %d jobs, "
			 "runner cpu %.3fs (%.3fs of it in Slurm's commands), "
			 "stages cpu %.3fs, runner peak %ld MiB", s->failures,
			 blocked, vd_seconds() - s->t0, p->n,
			 rusage_seconds(&self) + rusage_seconds(&kids),
			 rusage_seconds(&kids), slurm_stages_cpu(),
			 self.ru_maxrss / 1024);
	else
		run_log("finished: %d failed, %d blocked, %.1fs, %d jobs, "
			 "runner cpu %.3fs (%.3fs of it starting jobs), stages "
			 "cpu %.3fs, runner peak %ld MiB", s->failures, blocked,
			 vd_seconds() - s->t0, p->n, rusage_seconds(&self) +
			 spawn_cpu, spawn_cpu, rusage_seconds(&kids) - spawn_cpu,
			 self.ru_maxrss / 1024);
	if (s->failures || blocked) {
		fprintf(stderr, "voxdag: %d job%s failed, %d not run because of "
			"them; rerun 'voxdag run %s' after fixing the cause "
			"(finished jobs are kept)\n", s->failures,
			s->failures == 1 ? "" : "s", blocked, c->path);
		return 1;
	}
	if (report_write(p) != 0)
		return 1;
	return 0;
}

int run_pipeline(struct plan *p, const struct run_opts *o)
{
	const struct config *c = p->cfg;
	if (run_open(p) != 0)
		return 1;
	struct run_state s = {0};
	s.p = p;
	s.o = o;
	s.c = c;
	s.slurm = c->executor == EXECUTOR_SLURM;
	s.tty = isatty(2) && !o->quiet;
	s.t0 = vd_seconds();
	s.last = 0;
	s.every = o->quiet ? 5.0 : s.tty ? 0.5 : 10.0;
	s.dirty = 1;
	running_local = calloc((size_t)c->jobs + 1, sizeof *running_local);
	direct_pids = calloc((size_t)c->jobs + 1, sizeof *direct_pids);
	if (!running_local || !direct_pids) {
		fprintf(stderr, "voxdag: out of memory\n");
		return 1;
	}
	/* locally the runner sleeps until a job ends (SIGCHLD, blocked so it
	 * stays pending between a look with wait4 and the wait) or progress
	 * is due, never polling */
	sigemptyset(&s.chld);
	sigaddset(&s.chld, SIGCHLD);
	sigprocmask(SIG_BLOCK, s.slurm ? NULL : &s.chld, &child_mask);
	for (;;) {
		/* with Slurm, a pass only when something can have changed
		 * (an end, a submission), and after the ends a poll brought
		 * are all recorded: the bundles are cut from every ready job */
		if (!s.slurm || (s.dirty && !slurm_ends_waiting())) {
			int before = s.running;
			start_ready(&s);
			s.dirty = s.running != before;
		}
		if (s.running == 0) {
			s.dirty = 1;
			if (s.restart || run_idle(&s))
				break;
			continue;
		}
		/* wait for a job, showing progress meanwhile */
		struct job_end end;
		int done = s.slurm ? slurm_reap(p, &end) : reap_local(p, &end);
		if (done == -2)
			break;
		if (done < 0) {
			run_wait(&s);
			continue;
		}
		run_reaped(&s, done, &end);
		s.dirty = 1;
	}
	return run_close(&s);
}
