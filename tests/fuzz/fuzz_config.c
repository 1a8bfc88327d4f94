/* fuzz_config.c - libFuzzer target: the runner's pipeline YAML reader
 * (pipeline/config.c, config_load). */
#include "fuzz.h"
#include "pipeline.h"

#include <fcntl.h>
#include <unistd.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	static struct config c; /* large: keep it off the stack */
	const char *path = fuzz_file(data, size, ".yaml");
	memset(&c, 0, sizeof c);
	/* config_load prints its one error line to stderr: silence it for
	 * the call only. Closing stderr for good (freopen) also hid
	 * libFuzzer's own statistics and crash reports. */
	static int devnull = -1, saved = -1;
	int quiet = !getenv("FUZZ_VERBOSE");
	if (quiet && devnull < 0) {
		devnull = open("/dev/null", O_WRONLY);
		saved = dup(2);
		if (devnull < 0 || saved < 0)
			abort();
	}
	if (quiet) {
		fflush(stderr);
		dup2(devnull, 2);
	}
	if (config_load(&c, path) == 0)
		config_release(&c);
	if (quiet) {
		fflush(stderr);
		dup2(saved, 2);
	}
	return 0;
}
