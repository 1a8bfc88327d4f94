/* publish.h - the library's own publishing helpers (io/publish.c), beside
 * the public vd_atomic_* and vd_fsync_* of vd_chunk.h. Not installed. */
#ifndef VD_PUBLISH_H
#define VD_PUBLISH_H

#include "voxdag.h"

/* open(path, O_RDONLY | O_CLOEXEC) that leaves the file's access time
 * alone (O_NOATIME) where the process may, i.e. owns the file or is root;
 * a plain open elsewhere. The runner reads every output once right after
 * its job wrote it, and on a relatime mount that first read wrote the
 * inode back for its atime: a twentieth of the Slurm driver's CPU. */
int vd_open_read(const char *path);

/* fsync(fd): the one place voxdag syncs, so that `make config=nofsync`
 * can price durability for make bench (it skips them all). */
int vd_sync_fd(int fd);

/* Renames the finished temporary file `tmp` (written and fsynced by the
 * caller) onto `path`, then fsyncs path's directory: the last steps of
 * vd_atomic_commit(), for outputs written under a staging name first.
 * Refuses (VD_ERR_IO, errno EISDIR or EEXIST) when `path` exists and is
 * not a regular file: run as root, a rename over an output path such as
 * /dev/null would replace the device. `tmp` stays when the rename fails
 * (the caller removes it). */
int vd_replace_file(const char *tmp, const char *path);

/* A file output and the statistics beside it are published as a pair:
 * both are written complete under staging names (vd_stage_name: "<final>
 * .tmp.<pid>.new", so it is taken for a temporary everywhere; each written
 * through vd_atomic_*, so durable under that name), then vd_publish_pair
 * renames them into place and fsyncs their directories once. Renames need
 * no space, so a full disk fails before either is replaced and the
 * previous pair stays whole (writing the output and then its statistics
 * left a new output beside old statistics, or none). vd_stage_name
 * returns VD_ERR_RANGE when `cap` is too small. vd_publish_pair removes
 * the staged files it did not rename when a rename fails (VD_ERR_IO). */
int vd_stage_name(const char *final, char *buf, size_t cap);
int vd_publish_pair(const char *staged_out, const char *out,
		    const char *staged_stats, const char *stats);

/* Staging entries (the temporaries and staging names above) of processes
 * that died before publishing: a kill -9, a power cut. vd_staging_pid is
 * the pid a name "<x>.tmp.<pid>" or "<x>.tmp.<pid>.new" carries, else 0.
 * vd_pid_alive: 1 for a live process or one we may not signal (another
 * user's); 0 for none and for a zombie (it has exited and writes nothing
 * more). vd_staging_sweep removes every staging entry under `dir`
 * (recursively; a staging directory whole) whose process is dead, or
 * every one with `all` (the caller knows no writer runs), and returns how
 * many it removed. A pid reused by an unrelated live process keeps its
 * entry until that process ends: a leftover, never a live write lost.
 * vd_remove_tree removes a directory and what it holds. */
long vd_staging_pid(const char *name);
int vd_pid_alive(long pid);
long vd_staging_sweep(const char *dir, int all);
int vd_remove_tree(const char *dir);

#endif /* VD_PUBLISH_H */
