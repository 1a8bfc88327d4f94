/* cli.h - command-line helpers for the voxdag tools' main()s (cli.c). Not
 * part of the installed library's interface.
 */
#ifndef VD_CLI_H
#define VD_CLI_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include "vd_errors.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Command-line helpers for the tools' main()s (cli.c). vd_cli_usage prints
 * "TOOL: message" and "Try 'TOOL --help'." to stderr and returns 2, the
 * usage exit status. vd_cli_int parses a whole number in [lo, hi] (0, or
 * -1 if it is not one). vd_cli_fail prints the one-line failure
 * "TOOL: WHAT 'SUBJECT': <vd_strerror(err)>: <detail>" and returns 1. */
int vd_cli_usage(const char *tool, const char *fmt, ...)
	__attribute__((format(printf, 2, 3)));
int vd_cli_int(const char *s, int lo, int hi, int *out);
int vd_cli_fail(const char *tool, int err, const char *what,
		const char *subject);

#ifdef __cplusplus
}
#endif

#endif /* VD_CLI_H */
