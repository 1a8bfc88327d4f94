/* fs_shutdown.c - cuts the power of the file system that holds PATH, for
 * the power-cut test (tests/cli/powercut.sh):
 *
 *   fs_shutdown PATH
 *
 * ext4's shutdown ioctl (XFS's "going down", the same number) with
 * NOLOGFLUSH: the file system stops at once without writing its journal,
 * every later I/O on it fails with EIO, and after a remount only what had
 * reached the device survives, which is what a power cut leaves. Needs
 * CAP_SYS_ADMIN. Exit status: 0 done, 1 failure (one line on stderr). */
#include <errno.h>
#include <fcntl.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <sys/ioctl.h>
#include <unistd.h>

/* fs/ext4/ext4.h; not in the uapi headers of every kernel */
#ifndef EXT4_IOC_SHUTDOWN
#define EXT4_IOC_SHUTDOWN _IOR('X', 125, uint32_t)
#endif
#define EXT4_GOING_FLAGS_NOLOGFLUSH 0x2

int main(int argc, char **argv)
{
	if (argc != 2) {
		fprintf(stderr, "usage: fs_shutdown PATH\n");
		return 2;
	}
	int fd = open(argv[1], O_RDONLY | O_CLOEXEC);
	if (fd < 0) {
		fprintf(stderr, "fs_shutdown: cannot open '%s': %s\n", argv[1],
			strerror(errno));
		return 1;
	}
	uint32_t how = EXT4_GOING_FLAGS_NOLOGFLUSH;
	if (ioctl(fd, EXT4_IOC_SHUTDOWN, &how) != 0) {
		fprintf(stderr, "fs_shutdown: cannot shut down '%s': %s\n",
			argv[1], strerror(errno));
		close(fd);
		return 1;
	}
	close(fd);
	return 0;
}
