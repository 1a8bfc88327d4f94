// parallel.cc - the library's only use of TBB, behind a C interface.
// Exceptions never cross into C: everything TBB may throw is caught here.
#include "voxdag.h"
#include "util_internal.h"

#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <exception>
#include <thread>

extern "C" int vd_hardware_threads(void)
{
	unsigned n = std::thread::hardware_concurrency();
	return n ? (int)n : 1;
}

extern "C" int vd_parallel_for(size_t n, int threads,
			       void (*fn)(void *ctx, size_t i, int worker),
			       void *ctx)
{
	// more threads than cores gain nothing, and TBB warns on stderr
	// that it ignores the extra workers
	if (threads <= 0 || threads > vd_hardware_threads())
		threads = vd_hardware_threads();
	try {
		if (threads == 1) {
			for (size_t i = 0; i < n; i++)
				fn(ctx, i, 0);
			return VD_OK;
		}
		tbb::task_arena arena(threads);
		arena.execute([&] {
			// grain 1: items (cells, levels) are few and uneven
			tbb::parallel_for(
				tbb::blocked_range<size_t>(0, n, 1),
				[&](const tbb::blocked_range<size_t> &r) {
					int w = tbb::this_task_arena::
						current_thread_index();
					for (size_t i = r.begin(); i != r.end();
					     i++)
						fn(ctx, i, w);
				},
				tbb::simple_partitioner());
		});
	} catch (const std::exception &e) {
		return vd_fail(VD_ERR_INTERNAL, "parallel_for: %s", e.what());
	} catch (...) {
		return vd_fail(VD_ERR_INTERNAL, "parallel_for: unknown exception");
	}
	return VD_OK;
}
