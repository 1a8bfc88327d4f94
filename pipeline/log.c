/* log.c - the run's log, <outputs>/logs/runner.log: one line per event
 * (started, done, failed, submitted...), stamped with the local time,
 * written by the driver (run.c) and the Slurm executor (slurm.c). */
#include "pipeline.h"

#include <stdarg.h>
#include <stdio.h>
#include <time.h>

static FILE *log_file;

int run_log_open(const char *path)
{
	/* the time zone once, here: localtime_r does not read it again */
	tzset();
	log_file = fopen(path, "a");
	return log_file ? fileno(log_file) : -1;
}

void run_log(const char *fmt, ...)
{
	if (!log_file)
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
	va_list ap;
	va_start(ap, fmt);
	fprintf(log_file, "%s ", ts);
	vfprintf(log_file, fmt, ap);
	va_end(ap);
	fputc('\n', log_file);
	fflush(log_file);
}
