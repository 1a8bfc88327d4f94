/* voxdag-spawn - the runner's job launcher:
 *
 *   voxdag-spawn --serve FD
 *
 * is started once per run and starts every local job the runner asks for
 * on the socket FD (spawn.h says what they say), waits for them and tells
 * the runner how each ended.
 *
 * Why it exists: a process's peak RSS (wait4's ru_maxrss) starts at that of
 * the memory it had before its exec, and a job the runner starts with
 * vfork or fork had the runner's (the kernel keeps the old memory's
 * high-water mark at exec). On a 100,000-cell plan every job then "peaked"
 * at the runner's 119 MiB, and the report's per-stage peaks were the
 * runner's. This program is exec'd first (so it is small), and the job is
 * forked from it, so the job's peak is its own plus this program's few
 * hundred KiB. It is linked statically and uses libc only. One launcher
 * per run rather than a trampoline per job: an exec per job cost ~1.7 ms,
 * over 10% of a cell's CPU on large plans.
 *
 * The launcher dies with the runner (PR_SET_PDEATHSIG, set before its exec
 * and kept across it), and its jobs die with it, so a killed runner still
 * leaves no orphans. If it dies, its socket closes: the runner says so and
 * takes the jobs it ran as failed. */
#include "spawn.h"

#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdlib.h>
#include <poll.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

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

static void on_child(int sig)
{
	(void)sig; /* only wakes ppoll */
}

static void reply(int sock, int type, pid_t pid, int status,
		  const struct rusage *ru)
{
	struct vd_spawn_rec r;
	memset(&r, 0, sizeof r);
	r.magic = VD_SPAWN_MAGIC;
	r.type = type;
	r.pid = (int32_t)pid;
	r.status = status;
	if (ru) {
		r.peak_rss = (uint64_t)ru->ru_maxrss * 1024;
		r.utime_us = usec(ru->ru_utime);
		r.stime_us = usec(ru->ru_stime);
	}
	/* blocking: at most one record per running job is ever waiting, far
	 * under the socket's buffer; a runner gone ends the loop (EOF) */
	while (send(sock, &r, sizeof r, MSG_NOSIGNAL) < 0 && errno == EINTR)
		;
}

/* Starts one job: argv in buf (n bytes of NUL-ended strings), its log fd. */
static void start(int sock, char *buf, size_t n, char **argv, int log,
		  const sigset_t *job_mask, pid_t self)
{
	int argc = 0;
	for (size_t i = 0; i < n; i += strlen(buf + i) + 1)
		argv[argc++] = buf + i;
	argv[argc] = NULL;
	if (argc == 0 || log < 0) {
		reply(sock, VD_LAUNCH_FAILED, 0, EINVAL, NULL);
		if (log >= 0)
			close(log);
		return;
	}
	/* the child's error line, made before vfork: the child may make
	 * system calls only */
	char failed[4200];
	size_t nf = 0;
	const char *parts[3] = {"voxdag: cannot run '", argv[0], "'\n"};
	for (int i = 0; i < 3; i++)
		for (const char *q = parts[i]; *q && nf < sizeof failed - 2; q++)
			failed[nf++] = *q;
	pid_t pid = vfork();
	if (pid == 0) {
		/* die with this launcher, which dies with the runner */
		prctl(PR_SET_PDEATHSIG, SIGKILL);
		if (getppid() != self)
			_exit(127);
		/* what the launcher ignores, the job does not (an ignored
		 * disposition would survive exec); its mask is the runner's */
		signal(SIGINT, SIG_DFL);
		signal(SIGQUIT, SIG_DFL);
		signal(SIGHUP, SIG_DFL);
		signal(SIGPIPE, SIG_DFL);
		sigprocmask(SIG_SETMASK, job_mask, NULL);
		dup2(log, 1); /* the copies lose O_CLOEXEC; log closes at exec */
		dup2(log, 2);
		int null = open("/dev/null", O_RDONLY);
		if (null >= 0)
			dup2(null, 0);
		execv(argv[0], argv);
		if (write(2, failed, nf) < 0) {
			/* nothing more to say */
		}
		_exit(127);
	}
	int e = errno;
	close(log);
	if (pid < 0)
		reply(sock, VD_LAUNCH_FAILED, 0, e, NULL);
	else
		reply(sock, VD_LAUNCH_STARTED, pid, 0, NULL);
}

/* The launcher: one process per run, exec'd while nothing of the runner's
 * memory is its own, so the jobs it vforks start with a peak near zero.
 * It dies with the runner (PR_SET_PDEATHSIG, set before its exec) and its
 * jobs with it; it ends when the runner closes its socket. */
static int serve(int sock)
{
	pid_t self = getpid();
	/* inherited without close-on-exec; the jobs must not hold it, or a
	 * dead launcher's socket would stay open while an orphan lives */
	fcntl(sock, F_SETFD, FD_CLOEXEC);
	sigset_t job_mask, blocked, waiting;
	sigprocmask(SIG_SETMASK, NULL, &job_mask);
	/* Ctrl-C and a hang-up reach the jobs and the runner themselves (one
	 * process group); the launcher stays to report the jobs' ends */
	signal(SIGINT, SIG_IGN);
	signal(SIGQUIT, SIG_IGN);
	signal(SIGHUP, SIG_IGN);
	signal(SIGPIPE, SIG_IGN);
	struct sigaction sa;
	memset(&sa, 0, sizeof sa);
	sa.sa_handler = on_child;
	sigemptyset(&sa.sa_mask);
	sigaction(SIGCHLD, &sa, NULL);
	/* SIGCHLD only interrupts the wait in ppoll: no end is missed
	 * between a look with wait4 and the wait */
	sigemptyset(&blocked);
	sigaddset(&blocked, SIGCHLD);
	sigprocmask(SIG_BLOCK, &blocked, &waiting);
	sigdelset(&waiting, SIGCHLD);
	char *buf = malloc(VD_LAUNCH_MAX_REQ + 1);
	char **argv = malloc((VD_LAUNCH_MAX_REQ / 2 + 2) * sizeof *argv);
	if (!buf || !argv) {
		say("the job launcher is out of memory", NULL, NULL);
		return 1;
	}
	for (;;) {
		int status;
		struct rusage ru;
		pid_t pid;
		while ((pid = wait4(-1, &status, WNOHANG, &ru)) > 0)
			reply(sock, VD_LAUNCH_ENDED, pid, status, &ru);
		struct pollfd pfd = {sock, POLLIN, 0};
		if (ppoll(&pfd, 1, NULL, &waiting) < 0) {
			if (errno == EINTR)
				continue;
			return 1;
		}
		union vd_spawn_ctl ctl;
		struct iovec iov = {buf, VD_LAUNCH_MAX_REQ};
		struct msghdr m;
		vd_spawn_msg(&m, &iov, &ctl);
		ssize_t n = recvmsg(sock, &m, MSG_CMSG_CLOEXEC);
		if (n < 0 && (errno == EINTR || errno == EAGAIN))
			continue;
		if (n <= 0)
			return 0; /* the runner is done (or gone) */
		int log = -1;
		struct cmsghdr *c = CMSG_FIRSTHDR(&m);
		if (c && c->cmsg_level == SOL_SOCKET && c->cmsg_type == SCM_RIGHTS)
			memcpy(&log, CMSG_DATA(c), sizeof log);
		if (m.msg_flags & (MSG_TRUNC | MSG_CTRUNC) || buf[n - 1] != 0) {
			if (log >= 0)
				close(log);
			log = -1; /* refused below */
		}
		start(sock, buf, (size_t)n, argv, log, &job_mask, self);
	}
}

int main(int argc, char **argv)
{
	char *end = NULL;
	long fd = argc == 3 && strcmp(argv[1], "--serve") == 0 ?
		strtol(argv[2], &end, 10) : -1;
	if (end && !*end && fd >= 3)
		return serve((int)fd);
	say("usage: voxdag-spawn --serve FD (run by voxdag)", NULL, NULL);
	return 2;
}
