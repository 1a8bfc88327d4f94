/* voxdag-spawn - the runner's trampoline for one local job:
 *
 *   voxdag-spawn FD PROG [ARGS...]
 *
 * forks PROG, waits for it and writes one struct vd_spawn_rec (its wait
 * status, peak RSS and CPU times) to the pipe FD, then exits as PROG did.
 *
 * Why it exists: a process's peak RSS (wait4's ru_maxrss) starts at that of
 * the memory it had before its exec, and a job the runner starts with
 * vfork or fork had the runner's (the kernel keeps the old memory's
 * high-water mark at exec). On a 100,000-cell plan every job then "peaked"
 * at the runner's 119 MiB, and the report's per-stage peaks were the
 * runner's. This program is exec'd first (so it is small), and the job is
 * forked from it, so the job's peak is its own plus this program's few
 * hundred KiB. It is linked statically and uses libc only: it runs once
 * per job, so its exec must cost little.
 *
 * It dies with the runner (PR_SET_PDEATHSIG, set before its exec and kept
 * across it), and the job dies with it, so a killed runner still leaves no
 * orphans. If it dies before writing its record the runner sees its own
 * exit and takes the job as failed with that cause (no peak). */
#include "spawn.h"

#include <errno.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

static volatile sig_atomic_t job_pid;

/* A signal meant for the job (Ctrl-C reaches the whole group; a kill
 * aimed at this process) is passed on, so the job can stop cleanly as it
 * did when it was the runner's child. */
static void forward(int sig)
{
	if (job_pid > 0)
		kill((pid_t)job_pid, sig);
}

/* Says "voxdag: A'B'C\n" on stderr with write() alone: no stdio, which
 * would double this program's size and its start-up cost, and the child
 * of vfork may make system calls only. */
static void say(const char *a, const char *b, const char *c)
{
	char buf[4200];
	size_t n = 0;
	const char *parts[4] = {"voxdag: ", a, b, c};
	for (int i = 0; i < 4; i++)
		for (const char *q = parts[i]; q && *q && n < sizeof buf - 1; q++)
			buf[n++] = *q;
	buf[n++] = '\n';
	if (write(2, buf, n) < 0) {
		/* nothing more to say */
	}
}

static uint64_t usec(struct timeval t)
{
	return (uint64_t)t.tv_sec * 1000000u + (uint64_t)t.tv_usec;
}

int main(int argc, char **argv)
{
	char *end;
	long fd = argc >= 3 ? strtol(argv[1], &end, 10) : -1;
	if (argc < 3 || *end || fd < 3) {
		say("usage: voxdag-spawn FD PROG [ARGS...] (run by voxdag, one "
		    "per job)", NULL, NULL);
		return 2;
	}
	pid_t self = getpid();
	/* vfork: this process is small, so the job's peak starts near zero
	 * either way, and no page tables are copied */
	pid_t pid = vfork();
	if (pid < 0) {
		say("cannot fork '", argv[2], "'");
		return 127;
	}
	if (pid == 0) {
		prctl(PR_SET_PDEATHSIG, SIGKILL);
		if (getppid() != self) /* it died between vfork and prctl */
			_exit(127);
		close((int)fd);
		execv(argv[2], argv + 2);
		say("cannot run '", argv[2], "'");
		_exit(127);
	}
	job_pid = pid;
	struct sigaction sa;
	memset(&sa, 0, sizeof sa);
	sa.sa_handler = forward;
	sigemptyset(&sa.sa_mask);
	sigaction(SIGTERM, &sa, NULL);
	sigaction(SIGINT, &sa, NULL);
	sigaction(SIGHUP, &sa, NULL);
	sigaction(SIGQUIT, &sa, NULL);
	signal(SIGPIPE, SIG_IGN); /* a runner gone: write fails, no signal */
	int status;
	struct rusage ru;
	while (wait4(pid, &status, 0, &ru) < 0)
		if (errno != EINTR)
			return 127;
	struct vd_spawn_rec r;
	memset(&r, 0, sizeof r);
	r.magic = VD_SPAWN_MAGIC;
	r.pid = (int32_t)self;
	r.status = status;
	r.peak_rss = (uint64_t)ru.ru_maxrss * 1024;
	r.utime_us = usec(ru.ru_utime);
	r.stime_us = usec(ru.ru_stime);
	/* one write under PIPE_BUF: records from many jobs never interleave */
	int told = write((int)fd, &r, sizeof r) == (ssize_t)sizeof r;
	if (WIFEXITED(status))
		return WEXITSTATUS(status);
	int sig = WIFSIGNALED(status) ? WTERMSIG(status) : 0;
	if (!told && sig) {
		/* the runner learns how the job ended from this exit only:
		 * end the same way (without a second core dump) */
		struct rlimit none = {0, 0};
		setrlimit(RLIMIT_CORE, &none);
		signal(sig, SIG_DFL);
		sigset_t all;
		sigfillset(&all);
		sigprocmask(SIG_UNBLOCK, &all, NULL);
		raise(sig);
	}
	return 128 + sig;
}
