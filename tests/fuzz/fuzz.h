/* fuzz.h - shared helpers of the libFuzzer targets tests/fuzz/fuzz_*.c.
 *
 * Readers that take a path get the input through a temporary file, one
 * per process, rewritten for every input (the library's APIs stay as they
 * are). Built by `make fuzz-build` with clang -fsanitize=fuzzer. */
#ifndef VD_FUZZ_H
#define VD_FUZZ_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <fcntl.h>

#include "voxdag.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* Writes data to a temporary file ending in `ext` and returns its path
 * (the same path on every call of one process; removed at exit). */
static char fuzz_path_buf[512];

static inline void fuzz_cleanup(void)
{
	if (fuzz_path_buf[0])
		unlink(fuzz_path_buf);
}

static inline const char *fuzz_tmpdir(void)
{
	const char *dir = getenv("TMPDIR");
	return dir && *dir ? dir : "/tmp";
}

static inline const char *fuzz_file(const uint8_t *data, size_t size,
			     const char *ext)
{
	if (!fuzz_path_buf[0]) {
		snprintf(fuzz_path_buf, sizeof fuzz_path_buf,
			 "%s/voxdag-fuzz-%ld%s", fuzz_tmpdir(),
			 (long)getpid(), ext);
		atexit(fuzz_cleanup);
	}
	int fd = open(fuzz_path_buf, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC,
		      0600);
	if (fd < 0)
		abort();
	size_t off = 0;
	while (off < size) {
		ssize_t w = write(fd, data + off, size - off);
		if (w <= 0)
			abort();
		off += (size_t)w;
	}
	close(fd);
	return fuzz_path_buf;
}

/* Reads every triangle of the mesh in `data` (format detected from the
 * content and `ext`), twice (the second pass after a rewind), and checks
 * that both passes agree. */
static inline int fuzz_mesh(const uint8_t *data, size_t size, const char *ext)
{
	const char *path = fuzz_file(data, size, ext);
	struct vd_mesh *m;
	if (vd_mesh_open(&m, path))
		return 0;
	static struct vd_triangle buf[256];
	uint64_t count[2] = {0, 0};
	double sum[2] = {0, 0};
	int err[2] = {0, 0};
	for (int pass = 0; pass < 2; pass++) {
		if (pass && vd_mesh_rewind(m))
			break;
		for (;;) {
			size_t n;
			if ((err[pass] = vd_mesh_read(m, buf, 256, &n)) || !n)
				break;
			count[pass] += n;
			for (size_t i = 0; i < n; i++)
				for (int k = 0; k < 3; k++)
					for (int d = 0; d < 3; d++)
						sum[pass] += buf[i].v[k][d];
		}
	}
	(void)vd_mesh_format(m);
	(void)vd_mesh_memory_bytes(m);
	if (count[0] != count[1] || err[0] != err[1] ||
	    (sum[0] != sum[1] && sum[0] == sum[0]))
		abort(); /* a rewind must read the same mesh again */
	vd_mesh_close(m);

	/* Spilled from the first vertex (joined with the faces on disk, as
	 * voxelize does past its budget): the same mesh, or an error where
	 * the reader in memory has one (perhaps after other triangles: the
	 * spill reads the whole file first). A reader that cannot spill
	 * (STL keeps a facet's vertices) refuses the tiny limit: no test. */
	struct vd_mesh_open_opts so = {.max_vertex_bytes = 12,
				       .spill_dir = fuzz_tmpdir()};
	int serr = vd_mesh_open_opts(&m, path, &so);
	uint64_t scount = 0;
	double ssum = 0;
	if (!serr) {
		for (;;) {
			size_t n;
			if ((serr = vd_mesh_read(m, buf, 256, &n)) || !n)
				break;
			scount += n;
			for (size_t i = 0; i < n; i++)
				for (int k = 0; k < 3; k++)
					for (int d = 0; d < 3; d++)
						ssum += buf[i].v[k][d];
		}
		vd_mesh_close(m);
	}
	if (serr == VD_ERR_BUDGET)
		return 0;
	if (!serr != !err[0] ||
	    (!serr && (scount != count[0] || (ssum != sum[0] && sum[0] == sum[0]))))
		abort(); /* the spill must not change the mesh */

	/* The colour readers: the same triangles when they succeed, and every
	 * attribute evaluates (textures the input names are opened too). */
	struct vd_mesh_open_opts o = {.colours = 1};
	if (vd_mesh_open_opts(&m, path, &o))
		return 0;
	static struct vd_tri_attr attr[256];
	uint64_t ccount = 0;
	int cerr;
	for (;;) {
		size_t n;
		if ((cerr = vd_mesh_read_attr(m, buf, attr, 256, &n)) || !n)
			break;
		ccount += n;
		for (size_t i = 0; i < n; i++) {
			static const double b[3] = {0.25, 0.25, 0.5};
			uint8_t rgb[3];
			vd_tri_attr_colour(&attr[i],
					   vd_mesh_texture(m, attr[i].texture),
					   b, rgb);
		}
	}
	(void)vd_mesh_has_colours(m);
	(void)vd_mesh_memory_bytes(m);
	if (!cerr && !err[0] && ccount != count[0])
		abort(); /* colours never change the geometry */
	vd_mesh_close(m);
	return 0;
}

#endif
