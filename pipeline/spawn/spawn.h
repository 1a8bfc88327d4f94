/* spawn.h - how the runner and its job launcher (voxdag-spawn --serve,
 * pipeline/spawn/spawn.c) talk, over a SOCK_SEQPACKET socketpair (each
 * message whole, never interleaved):
 *
 *   runner -> launcher: a start request, the job's argv as NUL-ended
 *     strings one after another (at most VD_LAUNCH_MAX_REQ bytes), with
 *     the job's log, already opened and begun, passed as SCM_RIGHTS;
 *   launcher -> runner: one reply per request (STARTED with the pid, or
 *     FAILED with the errno of vfork), then ENDED for each job when it
 *     ends (its wait status, peak RSS and CPU).
 */
#ifndef VOXDAG_SPAWN_H
#define VOXDAG_SPAWN_H

#include <stdint.h>
#include <string.h>
#include <sys/socket.h>

#define VD_SPAWN_MAGIC 0x4e575053u /* "SPWN" */

/* a request larger than this is refused by the runner before sending (it
 * starts that job itself): the launcher's buffer, and under the socket's
 * usual send buffer */
#define VD_LAUNCH_MAX_REQ (160u << 10)

enum { VD_LAUNCH_STARTED = 1, VD_LAUNCH_FAILED = 2, VD_LAUNCH_ENDED = 3 };

struct vd_spawn_rec {
	uint32_t magic;
	int32_t pid;       /* the job's pid */
	int32_t status;    /* ENDED: the wait status; FAILED: the errno */
	int32_t type;      /* VD_LAUNCH_* */
	uint64_t peak_rss; /* the job's ru_maxrss, bytes */
	uint64_t utime_us; /* the job's CPU time, so the runner can tell */
	uint64_t stime_us; /* its own launch cost from the job's */
};

/* A message of one buffer with room for one descriptor (SCM_RIGHTS), as
 * both ends build it: the runner to send a request, the launcher to
 * receive one. */
union vd_spawn_ctl {
	struct cmsghdr h;
	char space[CMSG_SPACE(sizeof(int))];
};

static inline void vd_spawn_msg(struct msghdr *m, struct iovec *iov,
				union vd_spawn_ctl *ctl)
{
	memset(m, 0, sizeof *m);
	memset(ctl, 0, sizeof *ctl);
	m->msg_iov = iov;
	m->msg_iovlen = 1;
	m->msg_control = ctl->space;
	m->msg_controllen = sizeof ctl->space;
}

#endif
