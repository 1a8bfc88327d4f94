/* enc_test_util.h - helpers of the encoding tests (test_encode.c,
 * test_encode48.c): an expansion sink compared with an SVO, whole-file
 * reads, node and wide-pointer counts. Include after check.h. */
#ifndef VD_ENC_TEST_UTIL_H
#define VD_ENC_TEST_UTIL_H

#include "voxdag.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Collects an expansion (keys and bricks) for comparison. */
struct sink {
	size_t n, cap;
	uint64_t *keys, *masks;
};

static int sink_add(void *ctx, uint64_t key, uint64_t brick)
{
	struct sink *s = ctx;
	if (s->n == s->cap) {
		s->cap = s->cap ? 2 * s->cap : 1024;
		s->keys = realloc(s->keys, s->cap * 8);
		s->masks = realloc(s->masks, s->cap * 8);
	}
	s->keys[s->n] = key;
	s->masks[s->n++] = brick;
	return 0;
}

static void sink_free(struct sink *s)
{
	free(s->keys);
	free(s->masks);
	memset(s, 0, sizeof *s);
}

/* 1 when the expansion of e equals the bricks of svo exactly. */
static int enc_equals_svo(const struct vd_enc *e, const struct vd_svo *svo)
{
	struct sink s = {0};
	int ok = vd_enc_expand(e, sink_add, &s) == 0 && s.n == svo->count;
	for (size_t i = 0; ok && i < s.n; i++)
		ok = s.keys[i] == svo->keys[i] && s.masks[i] == svo->masks[i];
	if (!ok)
		fprintf(stderr, "  %s: %zu bricks decoded, %zu expected\n",
			vd_enc_format_name(e->format), s.n, svo->count);
	sink_free(&s);
	return ok;
}

static uint8_t *read_all(const char *path, size_t *n)
{
	FILE *f = fopen(path, "rb");
	if (!f) return NULL;
	fseek(f, 0, SEEK_END);
	long sz = ftell(f);
	fseek(f, 0, SEEK_SET);
	uint8_t *b = malloc(sz > 0 ? (size_t)sz : 1);
	*n = fread(b, 1, (size_t)sz, f);
	fclose(f);
	return b;
}

/* 32-bit pointers in a compact file (nodes lie back to back). */
static uint64_t count_wide(const struct vd_enc *e)
{
	uint64_t at = 0, n = 0;
	while (at < e->inner_count) {
		unsigned h = e->inner[at++];
		for (int s = 7; s >= 0; s--) {
			unsigned tag = h >> 2 * s & 3;
			at += tag == 0 ? 0 : tag == 1 ? 1 : 2;
			n += tag >= 2;
		}
	}
	return n;
}

static uint64_t total_nodes(const struct vd_dag *d)
{
	uint64_t n = 0;
	for (int l = 0; l < d->levels; l++) n += d->lv[l].nodes;
	return n;
}

#endif
