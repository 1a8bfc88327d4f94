/* spawn.h - what voxdag-spawn (pipeline/spawn/spawn.c) tells the runner
 * about one job, through a pipe they share: one fixed-size record per job,
 * written with one write() (under PIPE_BUF, so never interleaved). */
#ifndef VOXDAG_SPAWN_H
#define VOXDAG_SPAWN_H

#include <stdint.h>

#define VD_SPAWN_MAGIC 0x4e575053u /* "SPWN" */

struct vd_spawn_rec {
	uint32_t magic;
	int32_t pid;       /* voxdag-spawn's own pid: what the runner reaps */
	int32_t status;    /* the job's wait status */
	int32_t pad;
	uint64_t peak_rss; /* the job's ru_maxrss, bytes */
	uint64_t utime_us; /* the job's CPU time, so the runner can tell */
	uint64_t stime_us; /* its own launch cost from the job's */
};

#endif
