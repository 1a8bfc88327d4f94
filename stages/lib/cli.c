/* cli.c - what every tool's main() needs: usage errors, whole-number
 * options, the one-line failure message. */
#include "voxdag.h"
#include "cli.h"

#include <stdarg.h>
#include <stdlib.h>

int vd_cli_usage(const char *tool, const char *fmt, ...)
{
	va_list ap;
	va_start(ap, fmt);
	fprintf(stderr, "%s: ", tool);
	vfprintf(stderr, fmt, ap);
	fprintf(stderr, "\nTry '%s --help'.\n", tool);
	va_end(ap);
	return 2;
}

int vd_cli_int(const char *s, int lo, int hi, int *out)
{
	char *end;
	long v = strtol(s, &end, 10);
	if (!*s || *end || v < lo || v > hi)
		return -1;
	*out = (int)v;
	return 0;
}

int vd_cli_fail(const char *tool, int err, const char *what,
		const char *subject)
{
	const char *d = vd_error_detail();
	fprintf(stderr, "%s: %s '%s': %s%s%s\n", tool, what, subject,
		vd_strerror(err), *d ? ": " : "", d);
	return 1;
}
