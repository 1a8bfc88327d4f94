/* log.c - the run's log, <outputs>/logs/runner.log: one line per event
 * (started, done, failed, submitted...), stamped with the local time,
 * written by the driver (run.c) and the Slurm executor (slurm.c).
 *
 * Lines wait in memory and go out in one write(2) when the driver is
 * about to wait (run_log_flush), when they fill the buffer, at the exit,
 * and before a stop signal's own line (run_log_flush_signal): a write per
 * line was a twentieth of the Slurm driver's CPU at 28,000 jobs. Only a
 * SIGKILL loses lines, those of the driver's last pass. */
#include "pipeline.h"

#include <fcntl.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

static int log_fd = -1;
static char pending[1 << 16];
static volatile sig_atomic_t npending; /* whole lines in pending */

static void write_all(const char *s, size_t n)
{
	while (n > 0) {
		ssize_t w = write(log_fd, s, n);
		if (w <= 0)
			return; /* a log that cannot be written stops nothing */
		s += w;
		n -= (size_t)w;
	}
}

void run_log_flush_signal(void)
{
	if (log_fd >= 0 && npending > 0)
		write_all(pending, (size_t)npending);
	npending = 0;
}

void run_log_flush(void)
{
	if (log_fd < 0 || npending == 0)
		return;
	/* a stop signal's handler writes what waits itself: not while
	 * it is being written here */
	sigset_t stop, old;
	sigemptyset(&stop);
	sigaddset(&stop, SIGTERM);
	sigaddset(&stop, SIGINT);
	sigaddset(&stop, SIGHUP);
	sigprocmask(SIG_BLOCK, &stop, &old);
	run_log_flush_signal();
	sigprocmask(SIG_SETMASK, &old, NULL);
}

int run_log_open(const char *path)
{
	/* the time zone once, here: localtime_r does not read it again */
	tzset();
	log_fd = open(path, O_WRONLY | O_APPEND | O_CREAT | O_CLOEXEC, 0666);
	if (log_fd >= 0)
		atexit(run_log_flush);
	return log_fd;
}

void run_log(const char *fmt, ...)
{
	if (log_fd < 0)
		return;
	/* one stamp a second: localtime() would also stat /etc/localtime on
	 * every line (localtime_r does not, once tzset ran) */
	static time_t last;
	static char ts[32];
	time_t now = time(NULL);
	if (now != last || !*ts) {
		struct tm tm;
		localtime_r(&now, &tm);
		strftime(ts, sizeof ts, "%Y-%m-%d %H:%M:%S", &tm);
		last = now;
	}
	char line[4096], *text = line;
	va_list ap;
	va_start(ap, fmt);
	int n = vsnprintf(line, sizeof line, fmt, ap);
	va_end(ap);
	if (n < 0)
		return;
	if ((size_t)n >= sizeof line) { /* a long one: whole, on the heap */
		text = malloc((size_t)n + 1);
		if (!text)
			return;
		va_start(ap, fmt);
		vsnprintf(text, (size_t)n + 1, fmt, ap);
		va_end(ap);
	}
	size_t len = strlen(ts) + 1 + (size_t)n + 1;
	if ((size_t)npending + len > sizeof pending)
		run_log_flush();
	if (len > sizeof pending) {
		write_all(ts, strlen(ts));
		write_all(" ", 1);
		write_all(text, (size_t)n);
		write_all("\n", 1);
	} else {
		/* copied first, counted after: a signal's handler writes
		 * only whole lines */
		char *at = pending + npending;
		size_t tl = strlen(ts);
		memcpy(at, ts, tl);
		at[tl] = ' ';
		memcpy(at + tl + 1, text, (size_t)n);
		at[len - 1] = '\n';
		npending += (sig_atomic_t)len;
	}
	if (text != line)
		free(text);
}
