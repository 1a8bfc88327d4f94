/* fuzz_config.c - libFuzzer target: the runner's pipeline YAML reader
 * (pipeline/config.c, config_load). */
#include "fuzz.h"
#include "pipeline.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	static struct config c; /* large: keep it off the stack */
	const char *path = fuzz_file(data, size, ".yaml");
	memset(&c, 0, sizeof c);
	/* config_load prints its one error line to stderr: silence it. */
	static int quiet;
	if (!quiet && !getenv("FUZZ_VERBOSE")) {
		quiet = 1;
		if (!freopen("/dev/null", "w", stderr))
			abort();
	}
	if (config_load(&c, path) == 0)
		config_release(&c);
	return 0;
}
