/* subdivide.c - makes a large binary PLY for the memory benchmarks: every
 * triangle of a binary little-endian PLY (vertex x y z float, then any
 * uchar properties; face: uchar count, int indices, triangles only) is
 * split into 16 (a 4x4 grid on each triangle). Edge points are shared
 * between neighbours, so the mesh stays indexed like a real one.
 * usage: subdivide IN.ply OUT.ply */
#include "bench_ply.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

struct edge { uint32_t lo, hi; uint64_t base; };

static uint64_t *slots; /* edge index + 1 */
static size_t nslots;
static struct edge *edges;
static size_t nedges;

static uint64_t hash(uint32_t a, uint32_t b)
{
	uint64_t k = (uint64_t)a << 32 | b;
	k ^= k >> 33;
	k *= 0xff51afd7ed558ccdULL;
	return k ^ k >> 33;
}

/* Index of the first of the 3 points of edge (a, b), ordered lo..hi. */
static uint64_t edge_base(uint32_t a, uint32_t b, uint64_t *next)
{
	uint32_t lo = a < b ? a : b, hi = a < b ? b : a;
	size_t j = hash(lo, hi) & (nslots - 1);
	while (slots[j]) {
		struct edge *e = &edges[slots[j] - 1];
		if (e->lo == lo && e->hi == hi)
			return e->base;
		j = (j + 1) & (nslots - 1);
	}
	edges[nedges] = (struct edge){lo, hi, *next};
	slots[j] = ++nedges;
	*next += 3;
	return edges[nedges - 1].base;
}

/* Point t/4 along a -> b of edge (a, b). */
static uint32_t edge_pt(uint32_t a, uint32_t b, int t, uint64_t *next)
{
	uint64_t base = edge_base(a, b, next);
	return (uint32_t)(base + (a < b ? t - 1 : 3 - t));
}

int main(int argc, char **argv)
{
	if (argc != 3) {
		fprintf(stderr, "usage: subdivide IN.ply OUT.ply\n");
		return 2;
	}
	float *v;
	uint32_t *f;
	uint64_t nv, nf;
	if (bench_ply_read(argv[1], &v, &nv, &f, &nf))
		return 1;
	for (nslots = 1; nslots < 4 * nf; nslots *= 2)
		;
	slots = calloc(nslots, sizeof *slots);
	edges = malloc(3 * nf * sizeof *edges);
	uint64_t next = nv;
	for (uint64_t i = 0; i < nf; i++)
		for (int k = 0; k < 3; k++)
			edge_base(f[3 * i + k], f[3 * i + (k + 1) % 3], &next);
	uint64_t total_v = next + 3 * nf, total_f = 16 * nf;
	FILE *out = fopen(argv[2], "wb");
	if (!out) {
		perror(argv[2]);
		return 1;
	}
	fprintf(out, "ply\nformat binary_little_endian 1.0\ncomment 4x4 "
		"subdivision of %s\nelement vertex %lu\nproperty float x\n"
		"property float y\nproperty float z\nelement face %lu\n"
		"property list uchar int vertex_indices\nend_header\n",
		argv[1], total_v, total_f);
	fwrite(v, 12, nv, out);
	for (size_t e = 0; e < nedges; e++)
		for (int t = 1; t <= 3; t++) {
			float p[3];
			for (int a = 0; a < 3; a++)
				p[a] = v[3 * edges[e].lo + a] +
				       (v[3 * edges[e].hi + a] - v[3 * edges[e].lo + a]) * (float)t / 4;
			fwrite(p, 4, 3, out);
		}
	for (uint64_t i = 0; i < nf; i++) {
		const float *A = v + 3 * f[3 * i], *B = v + 3 * f[3 * i + 1],
			    *C = v + 3 * f[3 * i + 2];
		static const int ij[3][2] = {{1, 1}, {2, 1}, {1, 2}};
		for (int q = 0; q < 3; q++) {
			float p[3];
			for (int a = 0; a < 3; a++)
				p[a] = A[a] + (B[a] - A[a]) * (float)ij[q][0] / 4 +
				       (C[a] - A[a]) * (float)ij[q][1] / 4;
			fwrite(p, 4, 3, out);
		}
	}
	for (uint64_t i = 0; i < nf; i++) {
		uint32_t a = f[3 * i], b = f[3 * i + 1], c = f[3 * i + 2];
		uint32_t g[5][5];
		g[0][0] = a, g[4][0] = b, g[0][4] = c;
		for (int t = 1; t <= 3; t++) {
			g[t][0] = edge_pt(a, b, t, &next);
			g[0][t] = edge_pt(a, c, t, &next);
			g[4 - t][t] = edge_pt(b, c, t, &next);
		}
		uint32_t in0 = (uint32_t)(next + 3 * i);
		g[1][1] = in0, g[2][1] = in0 + 1, g[1][2] = in0 + 2;
		for (int x = 0; x < 4; x++)
			for (int y = 0; x + y < 4; y++) {
				unsigned char n = 3;
				uint32_t t1[3] = {g[x][y], g[x + 1][y], g[x][y + 1]};
				fwrite(&n, 1, 1, out);
				fwrite(t1, 4, 3, out);
				if (x + y < 3) {
					uint32_t t2[3] = {g[x + 1][y], g[x + 1][y + 1], g[x][y + 1]};
					fwrite(&n, 1, 1, out);
					fwrite(t2, 4, 3, out);
				}
			}
	}
	if (fclose(out) != 0) {
		perror(argv[2]);
		return 1;
	}
	fprintf(stderr, "subdivide: %lu vertices, %lu triangles\n", total_v,
		total_f);
	return 0;
}
