/* stack.c - makes a mesh of many cells for the runner's benchmark: K copies
 * of a binary little-endian PLY (vertex x y z float, then any uchar
 * properties; face: uchar count, int indices), the i-th raised by i/K of the
 * mesh's larger horizontal extent, so that K layers of a terrain fill the
 * grid's cube and a height field of ~4^L0 cells becomes ~K 4^L0 of them.
 * usage: stack K IN.ply OUT.ply */
#include "bench_ply.h"

#include <float.h>
#include <stdint.h>
#include <stdio.h>

int main(int argc, char **argv)
{
	int k = argc == 4 ? atoi(argv[1]) : 0;
	if (k < 1) {
		fprintf(stderr, "usage: stack K IN.ply OUT.ply\n");
		return 2;
	}
	float *v;
	uint32_t *f;
	uint64_t nv, nf;
	if (bench_ply_read(argv[2], &v, &nv, &f, &nf))
		return 1;
	float lo[3] = {FLT_MAX, FLT_MAX, FLT_MAX}, hi[3] = {-FLT_MAX, -FLT_MAX, -FLT_MAX};
	for (uint64_t i = 0; i < nv; i++)
		for (int a = 0; a < 3; a++) {
			lo[a] = v[3 * i + a] < lo[a] ? v[3 * i + a] : lo[a];
			hi[a] = v[3 * i + a] > hi[a] ? v[3 * i + a] : hi[a];
		}
	/* the up axis: the one of least extent */
	int up = 0;
	for (int a = 1; a < 3; a++)
		if (hi[a] - lo[a] < hi[up] - lo[up])
			up = a;
	float side = 0;
	for (int a = 0; a < 3; a++)
		if (a != up && hi[a] - lo[a] > side)
			side = hi[a] - lo[a];
	float step = (side - (hi[up] - lo[up])) / (float)k;
	if (step < 0)
		step = 0;
	FILE *out = fopen(argv[3], "wb");
	if (!out) {
		perror(argv[3]);
		return 1;
	}
	fprintf(out, "ply\nformat binary_little_endian 1.0\ncomment %d layers "
		"of %s\nelement vertex %lu\nproperty float x\nproperty float y\n"
		"property float z\nelement face %lu\nproperty list uchar int "
		"vertex_indices\nend_header\n", k, argv[2], nv * k, nf * k);
	for (int c = 0; c < k; c++)
		for (uint64_t i = 0; i < nv; i++) {
			float p[3] = {v[3 * i], v[3 * i + 1], v[3 * i + 2]};
			p[up] += step * (float)c;
			fwrite(p, 4, 3, out);
		}
	for (int c = 0; c < k; c++)
		for (uint64_t i = 0; i < nf; i++) {
			unsigned char n = 3;
			uint32_t t[3];
			for (int q = 0; q < 3; q++)
				t[q] = f[3 * i + q] + (uint32_t)(nv * (uint64_t)c);
			fwrite(&n, 1, 1, out);
			fwrite(t, 4, 3, out);
		}
	if (fclose(out) != 0) {
		perror(argv[3]);
		return 1;
	}
	fprintf(stderr, "stack: %d layers, %lu vertices, %lu triangles\n", k,
		nv * k, nf * k);
	return 0;
}
