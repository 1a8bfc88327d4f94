/* util_internal.h - what every part of the library uses and its users do
 * not need: the thread pool (parallel.cc), process memory, array growth,
 * the hash (util.c). Not installed. */
#ifndef VD_UTIL_INTERNAL_H
#define VD_UTIL_INTERNAL_H

#include "vd_common.h"

#ifdef __cplusplus
extern "C" {
#endif

/* A small C interface to TBB. Runs fn(ctx, i, worker) for i in [0, n) on up
 * to `threads` threads (0: all cores); `worker` is in [0, threads) and
 * unique among concurrently running calls. Returns VD_OK, or VD_ERR_INTERNAL
 * if TBB threw (the exception never crosses into C). */
int vd_parallel_for(size_t n, int threads,
		    void (*fn)(void *ctx, size_t i, int worker), void *ctx);

/* Peak resident set size of this process so far, in bytes. */
uint64_t vd_peak_rss_bytes(void);
/* CPU seconds of this process so far, user and system, all threads:
 * work per CPU second is the per-core rate whatever the machine's load. */
double vd_cpu_seconds(void);
/* Resident set size of this process now, in bytes (the peak if
 * /proc/self/statm cannot be read). */
uint64_t vd_current_rss_bytes(void);

/* Room for element n of a doubling array of `elem`-byte elements with
 * capacity *cap (`first` when empty): returns the array, moved if it grew,
 * with *cap > n; NULL when out of memory, the old array untouched. */
void *vd_grow(void *a, size_t n, size_t *cap, size_t elem, size_t first);

/* MurmurHash3's 64-bit finalizer: every bit of x moves every bit of the
 * result. The mixing of the library's in-memory hash tables (DAG nodes,
 * voxel counts) from keys that are already well spread. */
static inline uint64_t vd_mix64(uint64_t x)
{
	x ^= x >> 33;
	x *= 0xff51afd7ed558ccdULL;
	x ^= x >> 33;
	x *= 0xc4ceb9fe1a85ec53ULL;
	x ^= x >> 33;
	return x;
}

/* Widens the box lo..hi to hold n points of 3 floats, `stride` floats
 * apart. Six scalars, not arrays indexed by axis: gcc kept those in
 * memory, 120 instructions a triangle (voxelize's bounds pass). */
static inline void vd_bounds_widen(const float *v, size_t n, size_t stride,
				   float lo[3], float hi[3])
{
	float lx = lo[0], hx = hi[0], ly = lo[1], hy = hi[1], lz = lo[2],
	      hz = hi[2];
	for (size_t i = 0; i < n; i++, v += stride) {
		lx = v[0] < lx ? v[0] : lx;
		hx = v[0] > hx ? v[0] : hx;
		ly = v[1] < ly ? v[1] : ly;
		hy = v[1] > hy ? v[1] : hy;
		lz = v[2] < lz ? v[2] : lz;
		hz = v[2] > hz ? v[2] : hz;
	}
	lo[0] = lx, lo[1] = ly, lo[2] = lz;
	hi[0] = hx, hi[1] = hy, hi[2] = hz;
}

/* XXH3 64-bit hash (the library's one hash). */
uint64_t vd_hash64(const void *data, size_t n, uint64_t seed);

#ifdef __cplusplus
}
#endif

#endif /* VD_UTIL_INTERNAL_H */
