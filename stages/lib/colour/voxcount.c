/* Voxel counts per DAG node and the colour index of a voxel (colour paper
 * §3). Every node's subtree holds a fixed number of voxels, equal for
 * subtrees the DAG shares (and for reflected ones: a reflection moves
 * voxels, it does not add any), so a count per stored node is enough. A
 * voxel's index in the scene's Morton-ordered colour array is the sum, along
 * its path from the root, of the counts of the siblings that precede it in
 * logical child order; in an SSVDAG node reached with reflection a, logical
 * child p is stored at slot p ^ a, so "preceding" is decided on logical
 * slots, and the counts are read at the stored ones.
 *
 * Counts of a DAG chunk are arrays parallel to its levels. An encoding's
 * nodes are addressed by position in the file, so its counts live in a hash
 * per level keyed by that position (filled by one walk over the distinct
 * nodes). Below the brick level counts are popcounts and are not stored. */
#include "voxdag.h"
#include "util_internal.h"

#include <stdlib.h>
#include <string.h>

#define NOMEM() vd_fail(VD_ERR_NOMEM, "out of memory for voxel counts")

/* Slot of `at` in level l's table (keys hold at + 1; 0 is free). */
static uint64_t *slot(const struct vd_voxcount *vc, int l, uint64_t at)
{
	uint64_t m = vc->cap[l] - 1, i = vd_mix64(at) & m;
	while (vc->key[l][i] && vc->key[l][i] != at + 1)
		i = (i + 1) & m;
	return &vc->key[l][i];
}

static int put(struct vd_voxcount *vc, int l, uint64_t at, uint64_t count)
{
	if (2 * (vc->used[l] + 1) > vc->cap[l]) {
		uint64_t old_cap = vc->cap[l], *ok = vc->key[l],
			 *oc = vc->count[l];
		uint64_t cap = old_cap ? 2 * old_cap : 64;
		vc->key[l] = calloc(cap, sizeof *ok);
		vc->count[l] = malloc(cap * sizeof *oc);
		if (!vc->key[l] || !vc->count[l]) {
			free(vc->key[l]);
			free(vc->count[l]);
			vc->key[l] = ok;
			vc->count[l] = oc;
			return NOMEM();
		}
		vc->cap[l] = cap;
		for (uint64_t i = 0; i < old_cap; i++)
			if (ok[i]) {
				uint64_t *s = slot(vc, l, ok[i] - 1);
				*s = ok[i];
				vc->count[l][s - vc->key[l]] = oc[i];
			}
		free(ok);
		free(oc);
	}
	uint64_t *s = slot(vc, l, at);
	*s = at + 1;
	vc->count[l][s - vc->key[l]] = count;
	vc->used[l]++;
	return VD_OK;
}

static int enc_count(struct vd_voxcount *vc, const struct vd_enc_node *n,
		     uint64_t *out)
{
	const struct vd_enc *e = vc->enc;
	int bl = vd_enc_brick_level(e);
	if (n->level == bl) {
		*out = (uint64_t)__builtin_popcountll(vd_enc_brick(e, n));
		return VD_OK;
	}
	if (vc->cap[n->level]) {
		uint64_t *s = slot(vc, n->level, n->at);
		if (*s) {
			*out = vc->count[n->level][s - vc->key[n->level]];
			return VD_OK;
		}
	}
	uint64_t sum = 0, c;
	struct vd_enc_node ch;
	for (unsigned p = 0; p < 8; p++) {
		if (!vd_enc_child(e, n, p, &ch))
			continue;
		int err = enc_count(vc, &ch, &c);
		if (err)
			return err;
		sum += c;
	}
	*out = sum;
	return put(vc, n->level, n->at, sum);
}

int vd_voxcount_from_enc(struct vd_voxcount *vc, const struct vd_enc *e)
{
	memset(vc, 0, sizeof *vc);
	vc->enc = e;
	vc->levels = (int)e->levels;
	if (e->node_count == 0)
		return VD_OK;
	struct vd_enc_node r;
	vd_enc_root(e, &r);
	if (e->levels == 1) {
		vc->voxels = (uint64_t)__builtin_popcount(vd_enc_node_mask(e, &r));
		return VD_OK;
	}
	int err = enc_count(vc, &r, &vc->voxels);
	if (err)
		vd_voxcount_release(vc);
	return err;
}

int vd_voxcount_from_dag(struct vd_voxcount *vc, const struct vd_dag *d)
{
	memset(vc, 0, sizeof *vc);
	vc->dag = d;
	vc->levels = d->levels;
	if (d->voxels == 0 || d->lv[d->chunk_level].nodes == 0)
		return VD_OK;
	int L = d->levels;
	for (int l = L - 1; l >= d->chunk_level; l--) {
		const struct vd_dag_level *lv = &d->lv[l];
		uint64_t *c = malloc((lv->nodes ? lv->nodes : 1) * sizeof *c);
		if (!c) {
			vd_voxcount_release(vc);
			return NOMEM();
		}
		vc->count[l] = c;
		vc->cap[l] = vc->used[l] = lv->nodes;
		for (uint64_t i = 0; i < lv->nodes; i++) {
			if (l == L - 1) {
				c[i] = (uint64_t)__builtin_popcount(lv->mask[i]);
				continue;
			}
			uint64_t sum = 0;
			for (uint64_t k = lv->first[i]; k < lv->first[i + 1]; k++)
				sum += vc->count[l + 1][lv->child[k]];
			c[i] = sum;
		}
	}
	vc->voxels = vc->count[d->chunk_level][0];
	return VD_OK;
}

/* The index walk on a DAG chunk (its root is the cell at chunk_level; the
 * coordinates are the cell-relative Morton code `m` at depth `level`). */
static int dag_index(const struct vd_voxcount *vc, int level, uint64_t m,
		     uint64_t *index)
{
	const struct vd_dag *d = vc->dag;
	uint64_t i = 0, sum = 0;
	unsigned a = 0;
	for (int l = d->chunk_level; l < level; l++) {
		const struct vd_dag_level *lv = &d->lv[l];
		unsigned p = (unsigned)(m >> 3 * (level - 1 - l)) & 7;
		unsigned mask = lv->mask[i];
		if (!(mask >> (p ^ a) & 1))
			return 0;
		if (l == d->levels - 1) { /* voxels of a 2x2x2 mask */
			for (unsigned q = 0; q < p; q++)
				sum += mask >> (q ^ a) & 1;
			break;
		}
		uint64_t k = 0;
		for (unsigned q = 0; q < p; q++) {
			unsigned s = q ^ a;
			if (!(mask >> s & 1))
				continue;
			k = lv->first[i] + (uint64_t)__builtin_popcount(mask & ((1u << s) - 1));
			sum += vc->count[l + 1][lv->child[k]];
		}
		unsigned s = p ^ a;
		k = lv->first[i] + (uint64_t)__builtin_popcount(mask & ((1u << s) - 1));
		i = lv->child[k];
		a ^= lv->refl ? lv->refl[k] : 0u;
	}
	*index = sum;
	return 1;
}

static int enc_index(const struct vd_voxcount *vc, int level, uint64_t m,
		     uint64_t *index)
{
	const struct vd_enc *e = vc->enc;
	int L = vc->levels, bl = vd_enc_brick_level(e);
	struct vd_enc_node n, ch;
	vd_enc_root(e, &n);
	uint64_t sum = 0;
	if (L == 1) { /* the root is a 2x2x2 mask */
		unsigned mask = vd_enc_node_mask(e, &n), p = (unsigned)m & 7;
		if (level == 0) {
			*index = 0;
			return mask != 0;
		}
		*index = (uint64_t)__builtin_popcount(mask & ((1u << p) - 1));
		return mask >> p & 1;
	}
	for (int l = 0; l < level; l++) {
		if (l == bl) { /* the rest of the path is inside the brick */
			uint64_t b = vd_enc_brick(e, &n);
			int below = level - bl;  /* 1 or 2 levels */
			unsigned k = (unsigned)m & ((1u << 3 * below) - 1);
			unsigned bit = below == 2 ? k : 8 * k;
			uint64_t cell = below == 2 ? 1 : 0xff;
			if (!(b >> bit & cell))
				return 0;
			sum += (uint64_t)__builtin_popcountll(b & ((1ull << bit) - 1));
			break;
		}
		unsigned p = (unsigned)(m >> 3 * (level - 1 - l)) & 7;
		unsigned mask = vd_enc_node_mask(e, &n);
		if (!(mask >> p & 1))
			return 0;
		for (unsigned q = 0; q < p; q++) {
			if (!(mask >> q & 1) || !vd_enc_child(e, &n, q, &ch))
				continue;
			if (ch.level == bl)
				sum += (uint64_t)__builtin_popcountll(vd_enc_brick(e, &ch));
			else
				sum += vc->count[ch.level][slot(vc, ch.level, ch.at) -
							   vc->key[ch.level]];
		}
		struct vd_enc_node next;
		vd_enc_child(e, &n, p, &next);
		n = next;
	}
	*index = sum;
	return 1;
}

int vd_voxcount_index(const struct vd_voxcount *vc, int level, uint32_t x,
		      uint32_t y, uint32_t z, uint64_t *index)
{
	if (vc->voxels == 0 || level < 0 || level > vc->levels)
		return 0;
	uint64_t side = 1ull << level;
	if (x >= side || y >= side || z >= side)
		return 0;
	uint64_t m = vd_morton3(x, y, z);
	if (vc->dag) {
		const struct vd_dag *d = vc->dag;
		int cl = d->chunk_level;
		if (level < cl) { /* a cell above this chunk's root */
			if (m != d->cell_morton >> 3 * (cl - level))
				return 0;
			*index = 0;
			return 1;
		}
		if (m >> 3 * (level - cl) != d->cell_morton)
			return 0;
		return dag_index(vc, level, m, index);
	}
	return enc_index(vc, level, m, index);
}

uint64_t vd_voxcount_stored_bytes(const struct vd_voxcount *vc)
{
	/* Counts above the brick level, each level at the smallest width of
	 * 1, 2, 4 or 8 bytes that holds its largest count: what a renderer
	 * that keeps them beside the nodes needs. */
	int top = vc->dag ? vc->dag->chunk_level : 0;
	int bl = vc->levels - 2;
	uint64_t bytes = 0;
	for (int l = top; l < bl; l++) {
		uint64_t max = 0, n = 0;
		for (uint64_t i = 0; i < vc->cap[l]; i++) {
			if (vc->key[l] && !vc->key[l][i])
				continue;
			n++;
			if (vc->count[l][i] > max)
				max = vc->count[l][i];
		}
		unsigned w = max < 1ull << 8 ? 1 : max < 1ull << 16 ? 2 :
			     max < 1ull << 32 ? 4 : 8;
		bytes += n * w;
	}
	return bytes;
}

void vd_voxcount_release(struct vd_voxcount *vc)
{
	for (int l = 0; l < VD_MAX_LEVELS; l++) {
		free(vc->count[l]);
		free(vc->key[l]);
	}
	memset(vc, 0, sizeof *vc);
}
