/* vset.h - sets of voxels (or any 64-bit keys) for tests: collect, sort,
 * compare, and name the first difference. */
#ifndef VD_TEST_VSET_H
#define VD_TEST_VSET_H

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

struct vset {
	uint64_t *v;
	size_t n, cap;
};

static inline void vset_add(struct vset *s, uint64_t key)
{
	if (s->n == s->cap) {
		s->cap = s->cap ? 2 * s->cap : 1024;
		s->v = realloc(s->v, s->cap * sizeof *s->v);
	}
	s->v[s->n++] = key;
}

static inline int vset_cmp_u64(const void *a, const void *b)
{
	uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
	return (x > y) - (x < y);
}

/* Sorts and removes duplicates. */
static inline void vset_finish(struct vset *s)
{
	if (!s->n)
		return;
	qsort(s->v, s->n, sizeof *s->v, vset_cmp_u64);
	size_t m = 0;
	for (size_t i = 0; i < s->n; i++)
		if (m == 0 || s->v[m - 1] != s->v[i])
			s->v[m++] = s->v[i];
	s->n = m;
}

/* 1 if the finished sets are equal; otherwise prints the counts and the
 * first differing key, written by `name` (e.g. as coordinates). */
static inline int vset_equal(const struct vset *a, const struct vset *b,
			     const char *what,
			     void (*name)(uint64_t key, char *buf, size_t cap))
{
	size_t i = 0, j = 0, diff = 0;
	uint64_t first = 0;
	while (i < a->n || j < b->n) {
		if (i < a->n && j < b->n && a->v[i] == b->v[j]) {
			i++, j++;
			continue;
		}
		uint64_t k = j >= b->n || (i < a->n && a->v[i] < b->v[j]) ? a->v[i++]
									  : b->v[j++];
		if (!diff++)
			first = k;
	}
	if (diff) {
		char buf[96];
		name(first, buf, sizeof buf);
		fprintf(stderr, "%s: %zu vs %zu voxels, %zu differ, first at %s\n",
			what, a->n, b->n, diff, buf);
	}
	return diff == 0;
}

#endif
