/* bench_ply.h - the one PLY reader of the benchmark mesh makers (stack.c,
 * subdivide.c): a binary little-endian PLY as ../shared/data has them
 * (vertex x y z float, then any uchar properties; face: uchar count, int
 * indices, triangles only). Not the project's reader: these tools write
 * test inputs, and must not depend on the code they feed. */
#ifndef BENCH_PLY_H
#define BENCH_PLY_H

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Reads PATH into *v (3 floats a vertex) and *f (3 indices a triangle).
 * 0 on success; otherwise says why on stderr and returns 1. */
static int bench_ply_read(const char *path, float **v, uint64_t *nv,
			  uint32_t **f, uint64_t *nf)
{
	FILE *in = fopen(path, "rb");
	if (!in) {
		perror(path);
		return 1;
	}
	char line[256];
	int extra = 0, in_vertex = 0;
	*nv = *nf = 0;
	while (fgets(line, sizeof line, in) && strcmp(line, "end_header\n")) {
		if (sscanf(line, "element vertex %lu", nv) == 1)
			in_vertex = 1;
		else if (sscanf(line, "element face %lu", nf) == 1)
			in_vertex = 0;
		else if (in_vertex && !strncmp(line, "property uchar", 14))
			extra++;
	}
	*v = malloc(*nv * 12 + 1);
	*f = malloc(*nf * 12 + 1);
	const char *why = !*v || !*f ? "out of memory" : extra > 16 ?
			  "too many vertex properties" : NULL;
	for (uint64_t i = 0; !why && i < *nv; i++) {
		unsigned char rec[12 + 16];
		if (fread(rec, 12 + (size_t)extra, 1, in) != 1)
			why = "truncated";
		else
			memcpy(*v + 3 * i, rec, 12);
	}
	for (uint64_t i = 0; !why && i < *nf; i++) {
		unsigned char n;
		if (fread(&n, 1, 1, in) != 1 || n != 3 ||
		    fread(*f + 3 * i, 4, 3, in) != 3)
			why = "not a triangle mesh";
	}
	fclose(in);
	if (why) {
		fprintf(stderr, "%s: %s\n", path, why);
		return 1;
	}
	return 0;
}

#endif
