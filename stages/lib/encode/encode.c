/* encode.c - the SVDAG, USSVDAG, ESVDAG and SSVDAG files of the SSVDAG
 * paper (section 4.3) from root DAG chunks, their readers and decoders, and
 * the paper's statistics tables. The byte layout is schemas/encodings.md.
 *
 * Encoding is a pass per level over the in-memory root DAG. The word
 * formats keep the DAG's node order (any order is valid: pointers are
 * absolute word indices). The compact formats are built bottom-up, as
 * pointers into a level need that level's final order: level L-2 becomes
 * bricks, then each level above is sorted by decreasing number of
 * references from its parent level (ties: the DAG's order, so the output
 * is deterministic) and encoded with 16-bit pointers to addresses below
 * 2^13 and 32-bit ones above.
 */
#include "voxdag.h"
#include "util_internal.h"
#include "le.h"
#include "encode/encode_internal.h"
#include "dag/dag_internal.h" /* the cube group's tables (.ssvdag48) */

#include <errno.h>
#include <inttypes.h>
#include <jansson.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define NOMEM() vd_fail(VD_ERR_NOMEM, "out of memory in %s", __func__)

uint64_t vd__enc_max_address = 1ull << 30;
uint64_t vd__enc_max_bricks = (1ull << 29) - 1;
uint64_t vd__enc_max_words = 0xffffffffull;

static const char *const format_names[VD_ENC_ALL_] = {
	"svdag", "ussvdag", "esvdag", "ssvdag", "ssvdag48"};

const char *vd_enc_format_name(int format)
{
	return format >= 0 && format < VD_ENC_ALL_ ? format_names[format]
						      : "unknown";
}

int vd_enc_format_from_path(const char *path)
{
	const char *dot = strrchr(path, '.');
	if (!dot || strchr(dot, '/')) return -1;
	for (int f = 0; f < VD_ENC_ALL_; f++)
		if (!strcmp(dot + 1, format_names[f])) return f;
	return -1;
}

/* ------------------------------------------------------- brick layouts */

/* SymVox bit of the voxel with local Morton code b: 16x + 4y + z. */
static inline unsigned symvox_bit(unsigned b)
{
	unsigned x = (b >> 4 & 2) | (b >> 2 & 1);
	unsigned y = (b >> 3 & 2) | (b >> 1 & 1);
	unsigned z = (b >> 2 & 2) | (b & 1);
	return 16 * x + 4 * y + z;
}

/* to_symvox[k][m]: the SymVox bits of byte k of a Morton brick being m;
 * a brick is 8 lookups (a loop over its set bits was 4% of encode). */
static uint64_t to_symvox[8][256];
static pthread_once_t to_symvox_once = PTHREAD_ONCE_INIT;

static void to_symvox_init(void)
{
	for (unsigned k = 0; k < 8; k++)
		for (unsigned m = 0; m < 256; m++) {
			uint64_t out = 0;
			for (unsigned b = 0; b < 8; b++)
				if (m >> b & 1) out |= 1ull << symvox_bit(8 * k + b);
			to_symvox[k][m] = out;
		}
}

uint64_t vd__enc_brick_to_symvox(uint64_t v)
{
	pthread_once(&to_symvox_once, to_symvox_init);
	uint64_t out = 0;
	for (unsigned k = 0; k < 8; k++)
		out |= to_symvox[k][v >> 8 * k & 0xff];
	return out;
}

uint64_t vd__enc_brick_from_symvox(uint64_t v)
{
	uint64_t out = 0;
	while (v) {
		unsigned i = (unsigned)__builtin_ctzll(v);
		v &= v - 1;
		unsigned x = i >> 4, y = i >> 2 & 3, z = i & 3;
		out |= 1ull << vd_morton3(x, y, z);
	}
	return out;
}

/* ------------------------------------------------------------- building */

void vd_enc_release(struct vd_enc *e)
{
	if (!e) return;
	free(e->words);
	free(e->inner);
	free(e->leaves);
	free(e->level_offsets);
	memset(e, 0, sizeof *e);
}

/* Bits set in a child mask; the builtin is a libgcc call without
 * -mpopcnt (it showed in encode's profile). */
static inline unsigned pop8(unsigned m)
{
	m -= m >> 1 & 0x55;
	m = (m & 0x33) + (m >> 2 & 0x33);
	return (m + (m >> 4)) & 0x0f;
}

static uint64_t dag_total_nodes(const struct vd_dag *d)
{
	uint64_t n = 0;
	for (int l = d->chunk_level; l < d->levels; l++) n += d->lv[l].nodes;
	return n;
}

/* `count_only`: word_count and the other counts, no words (the size of a
 * words format depends on the DAG's counts alone). */
static int build_words(struct vd_enc *e, const struct vd_dag *d,
		       int count_only)
{
	int L = d->levels, sym = e->format == VD_ENC_USSVDAG;
	if (!d->lv[0].nodes) {
		/* empty scene: one empty root word, no nodes counted */
		e->word_count = 1;
		e->first_leaf_word = L == 1 ? 0 : 1;
		if (count_only) return VD_OK;
		e->words = calloc(1, 4);
		if (!e->words) return NOMEM();
		return VD_OK;
	}
	uint64_t w = 0, first_leaf = 0;
	for (int l = 0; l < L; l++) {
		if (l == L - 1) first_leaf = w;
		w += d->lv[l].nodes + (l < L - 1 ? d->lv[l].refs : 0);
	}
	if (w > vd__enc_max_words)
		return vd_fail(VD_ERR_RANGE, "the %s needs %" PRIu64 " 32-bit "
			       "words; its word indices address %" PRIu64,
			       vd_enc_format_name(e->format), w,
			       vd__enc_max_words);
	if (count_only) {
		e->word_count = (uint32_t)w;
		e->first_leaf_word = (uint32_t)first_leaf;
		e->node_count = (uint32_t)dag_total_nodes(d);
		return VD_OK;
	}
	e->words = malloc(w * 4);
	uint64_t *pos = malloc(((size_t)d->lv[0].nodes + 1) * 8);
	if (!e->words || !pos) {
		free(pos);
		return NOMEM();
	}
	/* pos[]: word index of each node of the level below */
	uint64_t start = 0;
	for (int l = 0; l < L; l++) {
		const struct vd_dag_level *lv = &d->lv[l];
		uint64_t next = start;
		for (uint64_t i = 0; i < lv->nodes; i++)
			next += 1 + (l < L - 1 ? (uint64_t)pop8(lv->mask[i]) : 0);
		uint64_t *npos = NULL;
		if (l < L - 1) {
			const struct vd_dag_level *below = &d->lv[l + 1];
			npos = malloc(((size_t)below->nodes + 1) * 8);
			if (!npos) {
				free(pos);
				return NOMEM();
			}
			uint64_t p = next;
			for (uint64_t i = 0; i < below->nodes; i++) {
				npos[i] = p;
				p += 1 + (l + 1 < L - 1 ? (uint64_t)pop8(below->mask[i]) : 0);
			}
		}
		uint64_t at = start;
		for (uint64_t i = 0; i < lv->nodes; i++) {
			uint32_t head = lv->mask[i];
			uint32_t *hp = &e->words[at++];
			if (l < L - 1) {
				uint64_t j = lv->first[i + 1];
				for (int s = 7; s >= 0; s--) {
					if (!(lv->mask[i] >> s & 1)) continue;
					j--;
					e->words[at++] = (uint32_t)npos[lv->child[j]];
					unsigned m = lv->refl ? lv->refl[j] : 0;
					if (sym && (m & 4)) head |= 1u << (8 + s);
					if (sym && (m & 2)) head |= 1u << (16 + s);
					if (sym && (m & 1)) head |= 1u << (24 + s);
				}
			}
			*hp = head;
		}
		free(pos);
		pos = npos;
		start = next;
	}
	free(pos);
	e->word_count = (uint32_t)w;
	e->first_leaf_word = (uint32_t)first_leaf;
	e->node_count = (uint32_t)dag_total_nodes(d);
	return VD_OK;
}

/* The nodes of level l in output order: decreasing number of references
 * from level l-1, ties in increasing index (a stable counting sort). */
static int sort_by_refs(const struct vd_dag *d, int l, uint32_t **out)
{
	uint64_t n = d->lv[l].nodes;
	uint32_t *order = malloc(n ? n * 4 : 4);
	uint32_t *cnt = calloc(n ? n : 1, 4);
	if (!order || !cnt) {
		free(order);
		free(cnt);
		return NOMEM();
	}
	uint32_t maxc = 0;
	if (l > 0) {
		const struct vd_dag_level *up = &d->lv[l - 1];
		for (uint64_t j = 0; j < up->refs; j++) cnt[up->child[j]]++;
		for (uint64_t i = 0; i < n; i++)
			if (cnt[i] > maxc) maxc = cnt[i];
	}
	uint64_t *hist = calloc((size_t)maxc + 2, 8);
	if (!hist) {
		free(order);
		free(cnt);
		return NOMEM();
	}
	/* bucket b = maxc - count: the most referenced first */
	for (uint64_t i = 0; i < n; i++) hist[maxc - cnt[i] + 1]++;
	for (uint32_t b = 1; b <= maxc + 1; b++) hist[b] += hist[b - 1];
	for (uint64_t i = 0; i < n; i++) order[hist[maxc - cnt[i]]++] = (uint32_t)i;
	free(hist);
	free(cnt);
	*out = order;
	return VD_OK;
}

/* The compact formats differ only in their pointers: .ssvdag48 gives 6
 * bits to a transform where the others give 3 to a reflection. */
static uint64_t max_address(int format)
{
	return format == VD_ENC_SSVDAG48 && vd__enc_max_address > VD__ENC48_MAX_ADDRESS
	       ? VD__ENC48_MAX_ADDRESS : vd__enc_max_address;
}

static unsigned pack_ptr(int format, uint32_t addr, unsigned m, uint16_t w[2])
{
	return format == VD_ENC_SSVDAG48 ? vd__enc_pack_ptr48(addr, m, w)
					 : vd__enc_pack_ptr(addr, m, w);
}

static uint32_t unpack_ptr(int format, unsigned tag, const uint16_t *w,
			   unsigned *m)
{
	return format == VD_ENC_SSVDAG48 ? vd__enc_unpack_ptr48(tag, w, m)
					 : vd__enc_unpack_ptr(tag, w, m);
}

/* `count_only`: the addresses and sizes only (inner_count, leaf_bytes,
 * level_offsets), no inner words and no leaves, for the tables' rows,
 * which need vd_enc_size_bytes() and nothing else. The same checks. */
static int build_compact(struct vd_enc *e, const struct vd_dag *d,
			 int count_only)
{
	const uint64_t max_addr = max_address(e->format);
	int L = d->levels, err = VD_OK;
	e->level_count = (uint32_t)(L - 2);
	e->level_offsets = calloc((size_t)L - 2, 4);
	if (!e->level_offsets) return NOMEM();
	if (!d->lv[0].nodes) {
		/* empty scene: one empty root header, no bricks */
		e->inner_count = 1;
		for (int l = 1; l < L - 2; l++) e->level_offsets[l] = 1;
		if (count_only) return VD_OK;
		e->inner = calloc(1, 2);
		e->leaves = malloc(1);
		if (!e->inner || !e->leaves) return NOMEM();
		return VD_OK;
	}
	uint16_t *buf[VD_MAX_LEVELS] = {0};
	uint64_t len[VD_MAX_LEVELS] = {0}, cap[VD_MAX_LEVELS] = {0};
	uint32_t *addr_below = NULL, *order = NULL, *addr = NULL;
	for (int l = L - 2; l >= 0; l--) {
		const struct vd_dag_level *lv = &d->lv[l];
		uint64_t n = lv->nodes;
		if ((err = sort_by_refs(d, l, &order))) goto out;
		addr = malloc(n * 4);
		if (!addr) {
			err = NOMEM();
			goto out;
		}
		if (l == L - 2) {
			if (n > vd__enc_max_bricks || (l > 0 && n > max_addr)) {
				err = vd_fail(VD_ERR_RANGE, "level %d has %" PRIu64
					      " bricks; the %s addresses at most "
					      "%" PRIu64, l, n,
					      vd_enc_format_name(e->format),
					      vd__enc_max_bricks < max_addr ?
					      vd__enc_max_bricks : max_addr);
				goto out;
			}
			e->leaf_bytes = (uint32_t)(n * 8);
			if (count_only) {
				for (uint64_t k = 0; k < n; k++)
					addr[order[k]] = (uint32_t)k;
				goto next;
			}
			e->leaves = malloc(n * 8);
			if (!e->leaves) {
				err = NOMEM();
				goto out;
			}
			for (uint64_t k = 0; k < n; k++) {
				uint32_t i = order[k];
				addr[i] = (uint32_t)k;
				uint64_t v = vd__enc_brick_to_symvox(d->bricks[i]);
				for (int b = 0; b < 8; b++)
					e->leaves[8 * k + b] = (uint8_t)(v >> 8 * b);
			}
		} else {
			/* at most 17 uint16 per node; counted, a scratch
			 * node (the words are not kept) */
			uint16_t scratch[17];
			cap[l] = count_only ? 0 : n * 17 + 1;
			buf[l] = count_only ? NULL : malloc(cap[l] * 2);
			if (!count_only && !buf[l]) {
				err = NOMEM();
				goto out;
			}
			uint16_t *b = count_only ? scratch : buf[l];
			uint64_t base = 0; /* at of b[0] */
			uint64_t at = 0;
			for (uint64_t k = 0; k < n; k++) {
				uint32_t i = order[k];
				if (l > 0 && at >= max_addr) {
					err = vd_fail(VD_ERR_RANGE, "level %d needs "
						      "addresses up to %" PRIu64
						      " (uint16 units); the %s "
						      "addresses below %" PRIu64,
						      l, at, vd_enc_format_name(e->format),
						      max_addr);
					goto out;
				}
				addr[i] = (uint32_t)at;
				if (count_only) base = at;
				uint64_t h = at++;
				unsigned head = 0;
				uint64_t j = lv->first[i + 1];
				for (int s = 7; s >= 0; s--) {
					if (!(lv->mask[i] >> s & 1)) continue;
					j--;
					uint16_t w[2];
					unsigned m = lv->refl ? lv->refl[j] : 0;
					unsigned tag = pack_ptr(e->format,
								addr_below[lv->child[j]], m, w);
					head |= tag << 2 * s;
					b[at++ - base] = w[0];
					if (tag > 1) b[at++ - base] = w[1];
				}
				b[h - base] = (uint16_t)head;
			}
			len[l] = at;
		}
	next:
		free(order);
		order = NULL;
		free(addr_below);
		addr_below = addr;
		addr = NULL;
	}
	uint64_t total = 0;
	for (int l = 0; l < L - 2; l++) {
		if (total > 0xffffffffull) break;
		e->level_offsets[l] = (uint32_t)total;
		total += len[l];
	}
	if (total > 0xffffffffull) {
		err = vd_fail(VD_ERR_RANGE, "the inner levels need %" PRIu64
			      " uint16 words; the %s counts them in 32 bits",
			      total, vd_enc_format_name(e->format));
		goto out;
	}
	e->inner_count = (uint32_t)total;
	if (count_only) goto done;
	e->inner = malloc(total * 2);
	if (!e->inner) {
		err = NOMEM();
		goto out;
	}
	for (int l = 0; l < L - 2; l++)
		memcpy(e->inner + e->level_offsets[l], buf[l], len[l] * 2);
done:
	e->node_count = (uint32_t)dag_total_nodes(d);
out:
	for (int l = 0; l < L; l++) free(buf[l]);
	free(addr_below);
	free(addr);
	free(order);
	return err;
}

/* vd_enc_build, or with `count_only` its vd_enc_size_bytes() and counts
 * without the encoding itself (no words, inner words or leaves). */
static int enc_build(struct vd_enc *e, int format, const struct vd_dag *dag,
		     const struct vd_transform *t, int count_only)
{
	memset(e, 0, sizeof *e);
	if (format < 0 || format >= VD_ENC_ALL_)
		return vd_fail(VD_ERR_ARG, "unknown encoding %d", format);
	uint32_t want = vd_enc_format_kind(format);
	if (format == VD_ENC_SSVDAG48) vd__g48_init();
	if (dag->kind != want)
		return vd_fail(VD_ERR_WRONG_KIND, "the %s encoding needs a %s "
			       "chunk, got %s", format_names[format],
			       vd_chunk_kind_name(want),
			       vd_chunk_kind_name(dag->kind));
	if (dag->chunk_level != 0)
		return vd_fail(VD_ERR_ARG, "chunk level %d is not a root chunk "
			       "(chunk level 0): merge the chunks up to the root "
			       "first", dag->chunk_level);
	int L = dag->levels;
	if (L < 1 || L > VD_MAX_LEVELS)
		return vd_fail(VD_ERR_RANGE, "levels %d out of 1..%d", L,
			       VD_MAX_LEVELS);
	if (vd_enc_format_compact(format) && L < 3)
		return vd_fail(VD_ERR_UNSUPPORTED, "the %s encoding needs at "
			       "least 3 levels (an inner level above the 4^3 "
			       "bricks), the grid has %d", format_names[format], L);
	uint64_t nodes = dag_total_nodes(dag);
	if (nodes > 0xffffffffull)
		return vd_fail(VD_ERR_RANGE, "%" PRIu64 " nodes do not fit the "
			       "32-bit node count", nodes);
	e->format = format;
	e->levels = (uint32_t)L;
	if (t) {
		memcpy(e->bbox_min, t->bbox_min, sizeof e->bbox_min);
		memcpy(e->bbox_max, t->bbox_max, sizeof e->bbox_max);
		e->root_side = t->root_side;
	}
	int err = vd_enc_format_compact(format)
		  ? build_compact(e, dag, count_only)
		  : build_words(e, dag, count_only);
	return err;
}

int vd_enc_build(struct vd_enc *e, int format, const struct vd_dag *dag,
		 const struct vd_transform *t)
{
	return enc_build(e, format, dag, t, 0);
}

uint64_t vd_enc_size_bytes(const struct vd_enc *e)
{
	if (vd_enc_format_compact(e->format))
		return 2ull * e->inner_count + e->leaf_bytes + 4ull * e->level_count;
	return 4ull * e->word_count;
}

/* ---------------------------------------------------------------- files */

static uint64_t file_bytes(const struct vd_enc *e)
{
	return vd_enc_size_bytes(e) + (vd_enc_format_compact(e->format) ?
				       VD_ENC_HEADER_BYTES_COMPACT :
				       VD_ENC_HEADER_BYTES_WORDS);
}

/* The file is written through a buffer of this many bytes, not built
 * whole in memory first (that copy was as large as the file, per file
 * written at once). */
#define SAVE_BUF (1u << 18)

struct sink {
	FILE *f;
	uint8_t *b;
	size_t n;
	uint64_t total;
	int bad;
};

static void sink_flush(struct sink *k)
{
	if (k->n && !k->bad && fwrite(k->b, 1, k->n, k->f) != k->n) k->bad = 1;
	k->total += k->n;
	k->n = 0;
}

/* Room for `need` (at most SAVE_BUF) more bytes at k->b + k->n. */
static uint8_t *sink_room(struct sink *k, size_t need)
{
	if (k->n + need > SAVE_BUF) sink_flush(k);
	return k->b + k->n;
}

/* n little-endian words through the buffer: a16's 16-bit ones, or else
 * a32's 32-bit ones. */
static void sink_words(struct sink *k, const uint16_t *a16,
		       const uint32_t *a32, uint32_t n)
{
	size_t width = a16 ? 2 : 4, per = SAVE_BUF / 2 / width;
	for (uint32_t i = 0; i < n;) {
		uint8_t *p = sink_room(k, SAVE_BUF / 2);
		uint32_t m = n - i < per ? n - i : (uint32_t)per;
		for (uint32_t q = 0; q < m; q++, p += width)
			if (a16)
				le_put16(p, a16[i + q]);
			else
				le_put32(p, a32[i + q]);
		k->n += width * m;
		i += m;
	}
}

/* The file's bytes (schemas/encodings.md) into k. */
static void serialize(const struct vd_enc *e, struct sink *k)
{
	uint8_t *p = sink_room(k, 36);
	for (int i = 0; i < 3; i++) le_putf32(p + 4 * i, e->bbox_min[i]);
	for (int i = 0; i < 3; i++) le_putf32(p + 12 + 4 * i, e->bbox_max[i]);
	le_putf32(p + 24, e->root_side);
	le_put32(p + 28, e->levels);
	le_put32(p + 32, e->node_count);
	k->n += 36;
	if (vd_enc_format_compact(e->format)) {
		le_put32(sink_room(k, 4), e->inner_count);
		k->n += 4;
		sink_words(k, e->inner, NULL, e->inner_count);
		le_put32(sink_room(k, 4), e->leaf_bytes);
		k->n += 4;
		sink_flush(k);
		if (e->leaf_bytes && !k->bad &&
		    fwrite(e->leaves, 1, e->leaf_bytes, k->f) != e->leaf_bytes)
			k->bad = 1;
		k->total += e->leaf_bytes;
		le_put32(sink_room(k, 4), e->level_count);
		k->n += 4;
		for (uint32_t i = 0; i < e->level_count; i++) {
			le_put32(sink_room(k, 4), e->level_offsets[i]);
			k->n += 4;
		}
	} else {
		p = sink_room(k, 8);
		le_put32(p, e->first_leaf_word);
		le_put32(p + 4, e->word_count);
		k->n += 8;
		sink_words(k, NULL, e->words, e->word_count);
	}
	sink_flush(k);
}

int vd_enc_save(const struct vd_enc *e, const char *path)
{
	uint8_t *buf = malloc(SAVE_BUF);
	if (!buf)
		return NOMEM();
	struct vd_atomic a;
	int err = vd_atomic_open(&a, path);
	if (!err) {
		struct sink k = {a.f, buf, 0, 0, 0};
		serialize(e, &k);
		if (k.bad)
			err = vd_fail(VD_ERR_IO, "cannot write '%s': %s", a.tmp,
				      strerror(errno));
		else if (k.total != file_bytes(e))
			err = vd_fail(VD_ERR_INTERNAL, "encode.c: wrote %" PRIu64
				      " of %" PRIu64 " bytes", k.total,
				      file_bytes(e));
		if (err)
			vd_atomic_abort(&a);
		else
			err = vd_atomic_commit(&a);
	}
	free(buf);
	return err;
}

/* ------------------------------------------------------------- reading */

struct cursor {
	const uint8_t *p;
	size_t left;
	const char *what;
};

static int take(struct cursor *c, size_t n, const uint8_t **out,
		const char *field)
{
	if (c->left < n)
		return vd_fail(VD_ERR_TRUNCATED, "the file ends inside %s "
			       "(%zu bytes left, %zu needed)", field, c->left, n);
	*out = c->p;
	c->p += n;
	c->left -= n;
	return VD_OK;
}

/* Validation walks every node reachable from the root once; `seen` marks
 * visited node starts (words: with their level + 1). */
struct checker {
	const struct vd_enc *e;
	uint8_t *seen;
	uint8_t *brick_seen;
};

static int check_words_node(struct checker *k, uint64_t at, int l)
{
	const struct vd_enc *e = k->e;
	int L = (int)e->levels;
	if (k->seen[at]) {
		if (k->seen[at] != l + 1)
			return vd_fail(VD_ERR_CORRUPT, "word %" PRIu64 " is "
				       "reached as a node of levels %d and %d",
				       at, k->seen[at] - 1, l);
		return VD_OK;
	}
	k->seen[at] = (uint8_t)(l + 1);
	uint32_t h = e->words[at];
	unsigned mask = h & 0xff;
	if (!mask && !(at == 0 && l == 0))
		return vd_fail(VD_ERR_CORRUPT, "word %" PRIu64 ": empty node "
			       "on level %d", at, l);
	if (l == L - 1) {
		if (h >> 8)
			return vd_fail(VD_ERR_CORRUPT, "word %" PRIu64 ": leaf "
				       "0x%08x has bits above its voxel mask",
				       at, h);
		return VD_OK;
	}
	if (e->format == VD_ENC_SVDAG && h >> 8)
		return vd_fail(VD_ERR_CORRUPT, "word %" PRIu64 ": node 0x%08x "
			       "has bits above its child mask", at, h);
	for (int a = 1; a <= 3; a++)
		if ((h >> 8 * a & 0xff) & ~mask)
			return vd_fail(VD_ERR_CORRUPT, "word %" PRIu64 ": mirror "
				       "bits 0x%08x of absent children", at, h);
	unsigned np = (unsigned)pop8(mask);
	if (at + np >= e->word_count)
		return vd_fail(VD_ERR_CORRUPT, "word %" PRIu64 ": %u pointers "
			       "run past the %u words", at, np, e->word_count);
	for (unsigned i = 1; i <= np; i++) {
		uint32_t c = e->words[at + i];
		/* children follow their parents: this also rules out cycles */
		if (c <= at + np || c >= e->word_count)
			return vd_fail(VD_ERR_CORRUPT, "word %" PRIu64 ": pointer "
				       "%u to word %u outside %" PRIu64 "..%u",
				       at, i, c, at + np + 1, e->word_count - 1);
		int err = check_words_node(k, c, l + 1);
		if (err) return err;
	}
	return VD_OK;
}

static uint64_t level_end(const struct vd_enc *e, int l)
{
	return l + 1 < (int)e->level_count ? e->level_offsets[l + 1]
					   : e->inner_count;
}

static int check_compact_node(struct checker *k, uint64_t at, int l)
{
	const struct vd_enc *e = k->e;
	int L = (int)e->levels;
	if (k->seen[at]) return VD_OK;
	k->seen[at] = 1;
	uint64_t end = level_end(e, l);
	unsigned h = e->inner[at];
	if (!h && !(at == 0 && l == 0))
		return vd_fail(VD_ERR_CORRUPT, "inner word %" PRIu64 ": empty "
			       "node on level %d", at, l);
	uint64_t p = at + 1;
	for (int s = 7; s >= 0; s--) {
		unsigned tag = h >> 2 * s & 3;
		if (!tag) continue;
		unsigned nw = tag == 1 ? 1 : 2;
		if (p + nw > end)
			return vd_fail(VD_ERR_CORRUPT, "inner word %" PRIu64 ": "
				       "node of level %d runs past its level's "
				       "end %" PRIu64, at, l, end);
		unsigned m;
		uint32_t a = unpack_ptr(e->format, tag, e->inner + p, &m);
		p += nw;
		if (m >= VD_G48) /* only .ssvdag48 has room for more */
			return vd_fail(VD_ERR_CORRUPT, "inner word %" PRIu64
				       ": child %d has transform %u (not "
				       "below 48)", at, s, m);
		int err;
		if (l + 1 < L - 2) {
			uint64_t c = (uint64_t)e->level_offsets[l + 1] + a;
			if (c >= level_end(e, l + 1))
				return vd_fail(VD_ERR_CORRUPT, "inner word %" PRIu64
					       ": child %d address %u outside "
					       "level %d", at, s, a, l + 1);
			err = check_compact_node(k, c, l + 1);
		} else {
			if ((uint64_t)a * 8 + 8 > e->leaf_bytes)
				return vd_fail(VD_ERR_CORRUPT, "inner word %" PRIu64
					       ": child %d brick %u beyond the %u "
					       "bricks", at, s, a, e->leaf_bytes / 8);
			err = VD_OK;
			if (!k->brick_seen[a]) {
				k->brick_seen[a] = 1;
				uint64_t v = 0;
				for (int b = 0; b < 8; b++) v |= e->leaves[8ull * a + b];
				if (!v)
					err = vd_fail(VD_ERR_CORRUPT, "brick %u is "
						      "empty", a);
			}
		}
		if (err) return err;
	}
	return VD_OK;
}

static int validate(struct vd_enc *e)
{
	struct checker k = {e, NULL, NULL};
	int err;
	if (vd_enc_format_compact(e->format)) {
		if (e->level_count != e->levels - 2)
			return vd_fail(VD_ERR_CORRUPT, "%u level offsets for %u "
				       "levels (expected %u)", e->level_count,
				       e->levels, e->levels - 2);
		if (e->leaf_bytes % 8)
			return vd_fail(VD_ERR_CORRUPT, "%u leaf bytes are not "
				       "whole 8-byte bricks", e->leaf_bytes);
		if (e->inner_count == 0)
			return vd_fail(VD_ERR_CORRUPT, "no root node");
		for (uint32_t l = 0; l < e->level_count; l++)
			if ((l == 0 && e->level_offsets[0] != 0) ||
			    (l > 0 && e->level_offsets[l] <= e->level_offsets[l - 1] &&
			     e->inner[0] != 0) ||
			    e->level_offsets[l] > e->inner_count)
				return vd_fail(VD_ERR_CORRUPT, "level offset %u of "
					       "level %u out of order", 
					       e->level_offsets[l], l);
		k.seen = calloc(e->inner_count, 1);
		k.brick_seen = calloc(e->leaf_bytes / 8 + 1, 1);
		if (!k.seen || !k.brick_seen) {
			free(k.seen);
			free(k.brick_seen);
			return NOMEM();
		}
		err = check_compact_node(&k, 0, 0);
	} else {
		if (e->word_count == 0)
			return vd_fail(VD_ERR_CORRUPT, "no root node");
		if (e->first_leaf_word > e->word_count)
			return vd_fail(VD_ERR_CORRUPT, "first leaf word %u beyond "
				       "the %u words", e->first_leaf_word,
				       e->word_count);
		k.seen = calloc(e->word_count, 1);
		if (!k.seen) return NOMEM();
		err = check_words_node(&k, 0, 0);
	}
	free(k.seen);
	free(k.brick_seen);
	return err;
}

int vd_enc_parse(struct vd_enc *e, const void *data, size_t size, int format)
{
	memset(e, 0, sizeof *e);
	if (format < 0 || format >= VD_ENC_ALL_)
		return vd_fail(VD_ERR_ARG, "unknown encoding %d", format);
	if (format == VD_ENC_SSVDAG48) vd__g48_init();
	struct cursor c = {data, size, NULL};
	const uint8_t *p = NULL;
	int err;
	e->format = format;
	if ((err = take(&c, 36, &p, "the header"))) return err;
	for (int i = 0; i < 3; i++) e->bbox_min[i] = le_getf32(p + 4 * i);
	for (int i = 0; i < 3; i++) e->bbox_max[i] = le_getf32(p + 12 + 4 * i);
	e->root_side = le_getf32(p + 24);
	e->levels = le_get32(p + 28);
	e->node_count = le_get32(p + 32);
	if (e->levels < 1 || e->levels > VD_MAX_LEVELS)
		return vd_fail(VD_ERR_UNSUPPORTED, "levels %u out of 1..%d",
			       e->levels, VD_MAX_LEVELS);
	if (vd_enc_format_compact(format)) {
		if (e->levels < 3)
			return vd_fail(VD_ERR_UNSUPPORTED, "a %s file needs at "
				       "least 3 levels, this one has %u",
				       format_names[format], e->levels);
		if ((err = take(&c, 4, &p, "the inner node count"))) goto fail;
		e->inner_count = le_get32(p);
		if ((err = take(&c, 2ull * e->inner_count, &p, "the inner nodes")))
			goto fail;
		if (!(e->inner = malloc(2ull * e->inner_count + 2))) goto nomem;
		for (uint32_t i = 0; i < e->inner_count; i++)
			e->inner[i] = le_get16(p + 2 * i);
		if ((err = take(&c, 4, &p, "the leaf byte count"))) goto fail;
		e->leaf_bytes = le_get32(p);
		if ((err = take(&c, e->leaf_bytes, &p, "the leaves"))) goto fail;
		if (!(e->leaves = malloc((size_t)e->leaf_bytes + 1))) goto nomem;
		memcpy(e->leaves, p, e->leaf_bytes);
		if ((err = take(&c, 4, &p, "the level offset count"))) goto fail;
		e->level_count = le_get32(p);
		if (e->level_count != e->levels - 2) {
			err = vd_fail(VD_ERR_CORRUPT, "%u level offsets for %u "
				      "levels (expected %u)", e->level_count,
				      e->levels, e->levels - 2);
			goto fail;
		}
		if ((err = take(&c, 4ull * e->level_count, &p, "the level offsets")))
			goto fail;
		if (!(e->level_offsets = malloc(4ull * e->level_count + 4)))
			goto nomem;
		for (uint32_t i = 0; i < e->level_count; i++)
			e->level_offsets[i] = le_get32(p + 4 * i);
	} else {
		if ((err = take(&c, 8, &p, "the header"))) goto fail;
		e->first_leaf_word = le_get32(p);
		e->word_count = le_get32(p + 4);
		if ((err = take(&c, 4ull * e->word_count, &p, "the words")))
			goto fail;
		if (!(e->words = malloc(4ull * e->word_count + 4))) goto nomem;
		for (uint32_t i = 0; i < e->word_count; i++)
			e->words[i] = le_get32(p + 4 * i);
	}
	if (c.left) {
		err = vd_fail(VD_ERR_TRAILING, "%zu bytes after the end of the "
			      "%s structure", c.left, format_names[format]);
		goto fail;
	}
	if ((err = validate(e))) goto fail;
	return VD_OK;
nomem:
	err = NOMEM();
fail:
	vd_enc_release(e);
	return err;
}

int vd_enc_load(struct vd_enc *e, const char *path, int format)
{
	memset(e, 0, sizeof *e);
	if (format < 0) format = vd_enc_format_from_path(path);
	if (format < 0)
		return vd_fail(VD_ERR_ARG, "'%s' has none of the extensions "
			       ".svdag, .ussvdag, .esvdag, .ssvdag, .ssvdag48", path);
	FILE *f = fopen(path, "rb");
	if (!f) return vd_fail(VD_ERR_IO, "%s", strerror(errno));
	uint8_t *buf = NULL;
	size_t n = 0, cap = 0;
	int err = VD_OK;
	for (;;) {
		if (n == cap) {
			cap = cap ? cap * 2 : 1 << 16;
			uint8_t *nb = realloc(buf, cap);
			if (!nb) {
				err = NOMEM();
				break;
			}
			buf = nb;
		}
		size_t r = fread(buf + n, 1, cap - n, f);
		n += r;
		if (r == 0) {
			if (ferror(f))
				err = vd_fail(VD_ERR_IO, "%s", strerror(errno));
			break;
		}
	}
	fclose(f);
	if (!err) err = vd_enc_parse(e, buf, n, format);
	free(buf);
	return err;
}

/* ----------------------------------------------------------- traversal */

void vd_enc_root(const struct vd_enc *e, struct vd_enc_node *n)
{
	(void)e;
	n->level = 0;
	n->at = 0;
	n->refl = 0;
}

int vd_enc_brick_level(const struct vd_enc *e)
{
	return (int)e->levels - 2;
}

/* Stored child mask of an inner node (or leaf mask of a word format). */
static unsigned stored_mask(const struct vd_enc *e, const struct vd_enc_node *n)
{
	if (vd_enc_format_compact(e->format)) {
		unsigned h = e->inner[n->at], m = 0;
		for (unsigned s = 0; s < 8; s++)
			if (h >> 2 * s & 3) m |= 1u << s;
		return m;
	}
	return e->words[n->at] & 0xff;
}

unsigned vd_enc_node_mask(const struct vd_enc *e, const struct vd_enc_node *n)
{
	if (vd_enc_format_compact(e->format) && n->level == (int)e->levels - 2) {
		uint64_t b = vd_enc_brick(e, n);
		unsigned m = 0;
		for (unsigned p = 0; p < 8; p++)
			if (b >> 8 * p & 0xff) m |= 1u << p;
		return m;
	}
	if (e->format == VD_ENC_SSVDAG48)
		return vd__g48_masks[n->refl][stored_mask(e, n)];
	return vd_mask_reflect((uint8_t)stored_mask(e, n), n->refl);
}

int vd_enc_child(const struct vd_enc *e, const struct vd_enc_node *n,
		 unsigned p, struct vd_enc_node *child)
{
	int g48 = e->format == VD_ENC_SSVDAG48;
	/* the stored slot seen as logical slot p: p itself moved back */
	unsigned s = g48 ? vd__g48_child[vd__g48_inv[n->refl]][p & 7]
			 : (p ^ n->refl) & 7;
	int L = (int)e->levels;
	if (vd_enc_format_compact(e->format)) {
		unsigned h = e->inner[n->at], tag = h >> 2 * s & 3;
		if (!tag) return 0;
		uint64_t off = n->at + 1;
		for (unsigned i = 7; i > s; i--) {
			unsigned t = h >> 2 * i & 3;
			off += t == 0 ? 0 : t == 1 ? 1 : 2;
		}
		unsigned m;
		uint32_t a = unpack_ptr(e->format, tag, e->inner + off, &m);
		child->level = n->level + 1;
		child->refl = g48 ? vd__g48_comp[n->refl][m] : n->refl ^ m;
		child->at = child->level < L - 2 ?
			    (uint64_t)e->level_offsets[child->level] + a :
			    (uint64_t)a * 8;
		return 1;
	}
	uint32_t h = e->words[n->at];
	if (!(h >> s & 1)) return 0;
	unsigned idx = (unsigned)pop8((h & 0xff) >> s);
	unsigned m = (h >> (8 + s) & 1) << 2 | (h >> (16 + s) & 1) << 1 |
		     (h >> (24 + s) & 1);
	child->level = n->level + 1;
	child->refl = n->refl ^ m;
	child->at = e->words[n->at + idx];
	return 1;
}

uint64_t vd_enc_brick(const struct vd_enc *e, const struct vd_enc_node *n)
{
	if (vd_enc_format_compact(e->format)) {
		uint64_t v = 0;
		for (int b = 0; b < 8; b++)
			v |= (uint64_t)e->leaves[n->at + b] << 8 * b;
		v = vd__enc_brick_from_symvox(v);
		return e->format == VD_ENC_SSVDAG48 ? vd_g48_brick(v, n->refl)
						    : vd_brick_reflect(v, n->refl);
	}
	uint64_t v = 0;
	struct vd_enc_node c;
	for (unsigned p = 0; p < 8; p++)
		if (vd_enc_child(e, n, p, &c))
			v |= (uint64_t)vd_mask_reflect((uint8_t)(e->words[c.at] & 0xff),
						       c.refl) << 8 * p;
	return v;
}

struct expander {
	const struct vd_enc *e;
	int (*fn)(void *ctx, uint64_t key, uint64_t brick);
	void *ctx;
};

static int expand_node(const struct expander *x, const struct vd_enc_node *n,
		       uint64_t morton)
{
	const struct vd_enc *e = x->e;
	if (n->level == (int)e->levels - 2)
		return x->fn(x->ctx, morton, vd_enc_brick(e, n));
	struct vd_enc_node c;
	for (unsigned p = 0; p < 8; p++) {
		if (!vd_enc_child(e, n, p, &c)) continue;
		int err = expand_node(x, &c, morton << 3 | p);
		if (err) return err;
	}
	return 0;
}

int vd_enc_expand(const struct vd_enc *e,
		  int (*fn)(void *ctx, uint64_t key, uint64_t brick),
		  void *ctx)
{
	struct vd_enc_node r;
	vd_enc_root(e, &r);
	if (e->levels == 1) {
		unsigned m = stored_mask(e, &r);
		return m ? fn(ctx, 0, m) : 0;
	}
	uint64_t first = 0;
	if (vd_enc_format_compact(e->format)) first = e->inner[0];
	else first = e->words[0] & 0xff;
	if (!first) return 0;
	struct expander x = {e, fn, ctx};
	return expand_node(&x, &r, 0);
}

/* ---------------------------------------------------------- statistics */

/* src[] / use[] index of a format's DAG: 0 dag, 1 ssvdag, 2 ssvdag48. */
static int source_of(int format)
{
	return format == VD_ENC_SSVDAG48 ? 2 : vd_enc_format_symmetric(format);
}

/* vd_enc_table_row; `sizes`, when not NULL, are vd_enc_size_bytes() of the
 * encodings of the uncut DAGs (VD_ENC_ALL_ entries, 0 for one not built),
 * taken for the full-resolution row instead of encoding everything again:
 * the encode stage has just built them for its files. `counts`, when not
 * NULL, holds vd_dag_svo_counts() of the dag, the ssvdag and the ssvdag48
 * (rows of 3 x (VD_MAX_LEVELS + 1), a row for each source given): a pass
 * over the whole DAG each, otherwise made again for every row and cut.
 * `only` is the source whose nodes and bytes are computed (0 dag, 1
 * ssvdag, 2 ssvdag48; the others' stay 0): a row is three tasks, joined
 * by row_join. */
static int table_row(const struct vd_dag *dag, const struct vd_dag *ssvdag,
		     const struct vd_dag *ssvdag48, int levels,
		     struct vd_enc_row *row, const uint64_t *sizes,
		     const uint64_t (*counts)[VD_MAX_LEVELS + 1], int only)
{
	memset(row, 0, sizeof *row);
	row->levels = levels;
	const struct vd_dag *src[3] = {dag, ssvdag, ssvdag48}, *use[3] = {0};
	static const uint32_t kinds[3] = {VD_KIND_DAG, VD_KIND_SSVDAG,
					  VD_KIND_SSVDAG48};
	if (!ssvdag && !ssvdag48)
		return vd_fail(VD_ERR_ARG, "tables need an ssvdag or an "
			       "ssvdag48 beside the dag");
	for (int k = 0; k < 3; k++) {
		if (!src[k]) continue;
		if (src[k]->kind != kinds[k])
			return vd_fail(VD_ERR_WRONG_KIND, "tables need a %s chunk "
				       "there, got %s", vd_chunk_kind_name(kinds[k]),
				       vd_chunk_kind_name(src[k]->kind));
		if (src[k]->levels != dag->levels || src[k]->voxels != dag->voxels)
			return vd_fail(VD_ERR_MISMATCH, "the dag (%d levels, %"
				       PRIu64 " voxels) and the %s (%d levels, %"
				       PRIu64 " voxels) are not of one scene",
				       dag->levels, dag->voxels,
				       vd_chunk_kind_name(kinds[k]),
				       src[k]->levels, src[k]->voxels);
	}
	row->has_ssvdag = ssvdag != NULL;
	row->has_ssvdag48 = ssvdag48 != NULL;
	uint64_t own[VD_MAX_LEVELS + 1];
	const uint64_t *dc = counts ? counts[0] : own;
	int err = counts ? VD_OK : vd_dag_svo_counts(dag, own);
	if (err) return err;
	row->voxels = dc[levels];
	for (int l = 0; l < levels; l++) row->svo_nodes += dc[l];
	row->svo_bytes = row->svo_nodes;
	struct vd_dag cuts[3];
	memset(cuts, 0, sizeof cuts);
	for (int k = 0; k < 3 && !err; k++) {
		if (!src[k] || k != only) continue;
		if (levels == dag->levels) {
			use[k] = src[k];
		} else {
			err = vd_dag_cut(src[k], levels, counts ? counts[k] : NULL,
				  &cuts[k]);
			use[k] = &cuts[k];
		}
	}
	if (!err) {
		row->dag_nodes = use[0] ? dag_total_nodes(use[0]) : 0;
		row->ssvdag_nodes = use[1] ? dag_total_nodes(use[1]) : 0;
		row->ssvdag48_nodes = use[2] ? dag_total_nodes(use[2]) : 0;
	}
	for (int f = 0; f < VD_ENC_ALL_ && !err; f++) {
		if (vd_enc_format_compact(f) && levels < 3) continue;
		if (!use[source_of(f)]) continue;
		if (sizes && levels == dag->levels) {
			row->bytes[f] = sizes[f];
			row->has[f] = 1;
			continue;
		}
		struct vd_enc e;
		err = enc_build(&e, f, use[source_of(f)], NULL, 1);
		if (!err) {
			row->bytes[f] = vd_enc_size_bytes(&e);
			row->has[f] = 1;
		}
		vd_enc_release(&e);
	}
	for (int k = 0; k < 3; k++) vd_dag_release(&cuts[k]);
	return err;
}

/* A row from its three sources' parts (table_row with `only` 0, 1, 2). */
static void row_join(struct vd_enc_row *out, const struct vd_enc_row p[3])
{
	struct vd_enc_row row = p[0];
	row.ssvdag_nodes = p[1].ssvdag_nodes;
	row.ssvdag48_nodes = p[2].ssvdag48_nodes;
	for (int f = 0; f < VD_ENC_ALL_; f++) {
		int k = source_of(f);
		row.bytes[f] = p[k].bytes[f];
		row.has[f] = p[k].has[f];
	}
	*out = row;
}

/* As the encode stage computes it, one source at a time, so the tests of
 * this function check the stage's rows too. */
int vd_enc_table_row(const struct vd_dag *dag, const struct vd_dag *ssvdag,
		     const struct vd_dag *ssvdag48, int levels,
		     struct vd_enc_row *row)
{
	const struct vd_dag *src[3] = {dag, ssvdag, ssvdag48};
	struct vd_enc_row p[3];
	memset(p, 0, sizeof p);
	memset(row, 0, sizeof *row);
	for (int k = 0; k < 3; k++) {
		if (k > 0 && !src[k]) continue;
		int err = table_row(dag, ssvdag, ssvdag48, levels, &p[k], NULL,
				    NULL, k);
		if (err) return err;
	}
	row_join(row, p);
	return VD_OK;
}

/* ------------------------------------------------------------- timings */

/* The statistics files are read with a JSON parser, not by searching the
 * text: a key's name inside a string value, reordered or nested keys and
 * malformed files must not be taken for numbers. */
int vd_enc_timing_add(struct vd_enc_timing *t, const char *path)
{
	json_error_t jerr;
	json_t *root = json_load_file(path, JSON_REJECT_DUPLICATES, &jerr);
	if (!root) {
		/* jansson reports an unopenable file as a parse error with
		 * errno still set; tell the two apart */
		FILE *f = fopen(path, "rb");
		if (!f) return vd_fail(VD_ERR_IO, "%s", strerror(errno));
		fclose(f);
		return vd_fail(VD_ERR_FORMAT, "not a statistics file (invalid JSON "
			       "at line %d, column %d: %s)", jerr.line, jerr.column, jerr.text);
	}
	int err = VD_OK;
	double *dst = NULL, s = 0;
	const char *tool = json_string_value(json_object_get(root, "tool"));
	if (!json_is_object(root))
		err = vd_fail(VD_ERR_FORMAT, "not a statistics file (not a "
			      "JSON object)");
	else if (tool && !strcmp(tool, "svo-to-dag"))
		dst = &t->seconds_svo_to_dag;
	else if (tool && !strcmp(tool, "symmetry-merge"))
		dst = &t->seconds_symmetry_merge;
	else
		err = vd_fail(VD_ERR_FORMAT, "not a statistics file of "
			      "svo-to-dag or symmetry-merge (\"tool\" is %s%s%s)",
			      tool ? "\"" : "", tool ? tool : "missing",
			      tool ? "\"" : "");
	static const char *const keys[] = {"seconds_load", "seconds_build",
					   "seconds_save"};
	for (int i = 0; i < 3 && !err; i++) {
		json_t *v = json_object_get(root, keys[i]);
		double d = json_is_number(v) ? json_number_value(v) : -1;
		if (!(d >= 0))
			err = vd_fail(VD_ERR_FORMAT, "no \"%s\" number of "
				      "seconds", keys[i]);
		s += d;
	}
	json_decref(root);
	if (err) return err;
	*dst = (*dst < 0 ? 0 : *dst) + s;
	return VD_OK;
}

/* --------------------------------------------------------------- tables */

#define MB(b) ((double)(b) / 1048576.0)

/* Writes `text` to dir/name.suffix durably (vd_atomic_*). */
static int write_text(const char *dir, const char *name, const char *suffix,
		      const char *text, size_t n)
{
	char path[4096];
	snprintf(path, sizeof path, "%s/%s.%s", dir, name, suffix);
	struct vd_atomic a;
	int err = vd_atomic_open(&a, path);
	if (err)
		return err;
	if (fwrite(text, 1, n, a.f) != n) {
		err = vd_fail(VD_ERR_IO, "cannot write '%s': %s", path,
			      strerror(errno));
		vd_atomic_abort(&a);
		return err;
	}
	return vd_atomic_commit(&a);
}

/* A growing text buffer for the CSV and Markdown files. */
struct text {
	char *s;
	size_t n, cap;
	int nomem;
};

__attribute__((format(printf, 2, 3)))
static void tprintf(struct text *t, const char *fmt, ...)
{
	va_list ap;
	for (;;) {
		size_t room = t->cap - t->n;
		va_start(ap, fmt);
		int k = t->cap ? vsnprintf(t->s + t->n, room, fmt, ap) : -2;
		va_end(ap);
		if (k >= 0 && (size_t)k < room) {
			t->n += (size_t)k;
			return;
		}
		size_t nc = t->cap ? t->cap * 2 : 4096;
		char *ns = realloc(t->s, nc);
		if (!ns) {
			t->nomem = 1;
			return;
		}
		t->s = ns;
		t->cap = nc;
	}
}

static double bpv(uint64_t bytes, uint64_t voxels)
{
	return voxels ? 8.0 * (double)bytes / (double)voxels : 0;
}

/* The order of the paper's columns; the 48-group's own, when given, goes
 * first in JSON and Markdown and after the paper's columns in the CSV (so
 * readers of the old columns keep their positions). */
static const int table_order[VD_ENC_ALL_] = {VD_ENC_SSVDAG48, VD_ENC_SSVDAG,
					     VD_ENC_USSVDAG, VD_ENC_ESVDAG,
					     VD_ENC_SVDAG};

/* The JSON tables: Table 1 (scene, build times) and Table 2 (nodes,
 * bytes, bits per voxel) per row, the paper's columns in table_order. */
static int tables_json(const char *dir, const char *name,
		       const struct vd_enc_row *rows, size_t n,
		       const struct vd_enc_timing *t, double seconds_encode)
{
	char path[4096];
	int err;
	snprintf(path, sizeof path, "%s/%s.tables.json", dir, name);
	struct vd_json *j;
	if ((err = vd_json_open(&j, path))) return err;
	vd_json_str(j, "scene", name);
	vd_json_u64(j, "levels", n ? (uint64_t)rows[0].levels : 0);
	vd_json_str(j, "node_count", "distinct nodes over levels 0..L-1; "
		    "svo: SVO nodes over the same levels, one byte each");
	vd_json_str(j, "bytes", "counted size: file size minus header "
		    "(schemas/encodings.md); MB = 2^20 bytes");
	vd_json_f64(j, "seconds_encode", seconds_encode);
	vd_json_array(j, "table1");
	for (size_t i = 0; i < n; i++) {
		vd_json_object(j, NULL);
		vd_json_u64(j, "levels", (uint64_t)rows[i].levels);
		vd_json_u64(j, "resolution", 1ull << rows[i].levels);
		vd_json_u64(j, "voxels", rows[i].voxels);
		vd_json_f64(j, "mvoxels", (double)rows[i].voxels / 1e6);
		if (i == 0 && t && t->seconds_svo_to_dag >= 0)
			vd_json_f64(j, "seconds_svo_to_dag", t->seconds_svo_to_dag);
		if (i == 0 && t && t->seconds_symmetry_merge >= 0)
			vd_json_f64(j, "seconds_symmetry_merge",
				    t->seconds_symmetry_merge);
		vd_json_end_object(j);
	}
	vd_json_end_array(j);
	vd_json_array(j, "table2");
	for (size_t i = 0; i < n; i++) {
		const struct vd_enc_row *r = &rows[i];
		vd_json_object(j, NULL);
		vd_json_u64(j, "levels", (uint64_t)r->levels);
		vd_json_u64(j, "resolution", 1ull << r->levels);
		vd_json_u64(j, "voxels", r->voxels);
		vd_json_u64(j, "nodes_svo", r->svo_nodes);
		vd_json_u64(j, "nodes_svdag", r->dag_nodes);
		if (r->has_ssvdag) vd_json_u64(j, "nodes_ssvdag", r->ssvdag_nodes);
		if (r->has_ssvdag48)
			vd_json_u64(j, "nodes_ssvdag48", r->ssvdag48_nodes);
		vd_json_u64(j, "bytes_svo", r->svo_bytes);
		vd_json_f64(j, "bits_per_voxel_svo", bpv(r->svo_bytes, r->voxels));
		for (int k = 0; k < VD_ENC_ALL_; k++) {
			int f = table_order[k];
			if (!r->has[f]) continue;
			char key[64];
			snprintf(key, sizeof key, "bytes_%s", format_names[f]);
			vd_json_u64(j, key, r->bytes[f]);
			snprintf(key, sizeof key, "bits_per_voxel_%s", format_names[f]);
			vd_json_f64(j, key, bpv(r->bytes[f], r->voxels));
		}
		vd_json_end_object(j);
	}
	vd_json_end_array(j);
	return vd_json_close(j);
}

/* Writes c's text as <dir>/<name>.<suffix> and empties c for the next
 * file; on an error (c out of memory, the write) frees c's buffer. */
static int text_publish(struct text *c, const char *dir, const char *name,
			const char *suffix)
{
	if (c->nomem) {
		free(c->s);
		c->s = NULL;
		return NOMEM();
	}
	int err = write_text(dir, name, suffix, c->s, c->n);
	c->n = 0;
	if (err) {
		free(c->s);
		c->s = NULL;
	}
	return err;
}

/* table1.csv: resolution, MVoxels and the build times (full resolution
 * only; the lower rows are cuts of the same DAG). */
static void table1_csv(struct text *c, const struct vd_enc_row *rows,
		       size_t n, const struct vd_enc_timing *t)
{
	tprintf(c, "levels,resolution,mvoxels,seconds_svo_to_dag,"
		"seconds_symmetry_merge\n");
	for (size_t i = 0; i < n; i++) {
		tprintf(c, "%d,%llu,%.6f,", rows[i].levels,
			1ull << rows[i].levels, (double)rows[i].voxels / 1e6);
		if (i == 0 && t && t->seconds_svo_to_dag >= 0)
			tprintf(c, "%.3f", t->seconds_svo_to_dag);
		tprintf(c, ",");
		if (i == 0 && t && t->seconds_symmetry_merge >= 0)
			tprintf(c, "%.3f", t->seconds_symmetry_merge);
		tprintf(c, "\n");
	}
}

/* table2.csv: nodes, bytes and bits per voxel, the paper's columns first
 * and the 48-group's after them when the first row has it. */
static void table2_csv(struct text *c, const struct vd_enc_row *rows,
		       size_t n)
{
	int g48 = n && rows[0].has_ssvdag48;
	tprintf(c, "levels,resolution,voxels,nodes_ssvdag,nodes_svdag,"
		"nodes_svo,bytes_ssvdag,bytes_ussvdag,bytes_esvdag,bytes_svdag,"
		"bytes_svo,bpv_ssvdag,bpv_ussvdag,bpv_esvdag,bpv_svdag,bpv_svo%s\n",
		g48 ? ",nodes_ssvdag48,bytes_ssvdag48,bpv_ssvdag48" : "");
	for (size_t i = 0; i < n; i++) {
		const struct vd_enc_row *r = &rows[i];
		tprintf(c, "%d,%llu,%llu,", r->levels, 1ull << r->levels,
			(unsigned long long)r->voxels);
		if (r->has_ssvdag)
			tprintf(c, "%llu", (unsigned long long)r->ssvdag_nodes);
		tprintf(c, ",%llu,%llu", (unsigned long long)r->dag_nodes,
			(unsigned long long)r->svo_nodes);
		/* k from 1: the paper's four */
		for (int k = 1; k < VD_ENC_ALL_; k++) {
			int f = table_order[k];
			if (r->has[f]) tprintf(c, ",%llu", (unsigned long long)r->bytes[f]);
			else tprintf(c, ",");
		}
		tprintf(c, ",%llu", (unsigned long long)r->svo_bytes);
		for (int k = 1; k < VD_ENC_ALL_; k++) {
			int f = table_order[k];
			if (r->has[f]) tprintf(c, ",%.4f", bpv(r->bytes[f], r->voxels));
			else tprintf(c, ",");
		}
		tprintf(c, ",%.4f", bpv(r->svo_bytes, r->voxels));
		if (g48) {
			tprintf(c, ",%llu,", (unsigned long long)r->ssvdag48_nodes);
			if (r->has[VD_ENC_SSVDAG48])
				tprintf(c, "%llu,%.4f", (unsigned long long)
					r->bytes[VD_ENC_SSVDAG48],
					bpv(r->bytes[VD_ENC_SSVDAG48], r->voxels));
			else
				tprintf(c, ",");
		}
		tprintf(c, "\n");
	}
}

/* tables.md's heading and Table 1, laid out like the paper's. */
static void table1_md(struct text *c, const char *name,
		      const struct vd_enc_row *rows, size_t n,
		      const struct vd_enc_timing *t, double seconds_encode)
{
	tprintf(c, "# %s\n\n## Table 1: scene and build times\n\n", name);
	tprintf(c, "| resolution | MVoxels | svo-to-dag (s) | symmetry-merge (s) |\n"
		"|---:|---:|---:|---:|\n");
	for (size_t i = 0; i < n; i++) {
		tprintf(c, "| %llu^3 | %.3f | ", 1ull << rows[i].levels,
			(double)rows[i].voxels / 1e6);
		if (i == 0 && t && t->seconds_svo_to_dag >= 0)
			tprintf(c, "%.2f", t->seconds_svo_to_dag);
		else tprintf(c, "-");
		tprintf(c, " | ");
		if (i == 0 && t && t->seconds_symmetry_merge >= 0)
			tprintf(c, "%.2f", t->seconds_symmetry_merge);
		else tprintf(c, "-");
		tprintf(c, " |\n");
	}
	tprintf(c, "\nBuild times are for the full resolution (the lower "
		"resolutions are cuts of the same DAG); encode took %.2f s.\n",
		seconds_encode);
}

/* tables.md's Table 2, laid out like the paper's; the 48-group's columns
 * first when g48. */
static void table2_md(struct text *c, const struct vd_enc_row *rows,
		      size_t n, int g48)
{
	tprintf(c, "\n## Table 2: nodes (millions) and memory (MB = 2^20 bytes)\n\n"
		"| resolution |%s nodes SSVDAG | nodes SVDAG | nodes SVO |%s "
		"MB SSVDAG | MB USSVDAG | MB ESVDAG | MB SVDAG | MB SVO |\n"
		"|---:|---:|---:|---:|---:|---:|---:|---:|---:|%s\n",
		g48 ? " nodes SSVDAG48 |" : "", g48 ? " MB SSVDAG48 |" : "",
		g48 ? "---:|---:|" : "");
	for (size_t i = 0; i < n; i++) {
		const struct vd_enc_row *r = &rows[i];
		tprintf(c, "| %llu^3", 1ull << r->levels);
		if (g48) tprintf(c, " | %.3f", (double)r->ssvdag48_nodes / 1e6);
		if (r->has_ssvdag)
			tprintf(c, " | %.3f", (double)r->ssvdag_nodes / 1e6);
		else
			tprintf(c, " | -");
		tprintf(c, " | %.3f | %.3f", (double)r->dag_nodes / 1e6,
			(double)r->svo_nodes / 1e6);
		for (int k = g48 ? 0 : 1; k < VD_ENC_ALL_; k++) {
			int f = table_order[k];
			if (r->has[f]) tprintf(c, " | %.3f", MB(r->bytes[f]));
			else tprintf(c, " | -");
		}
		tprintf(c, " | %.3f |\n", MB(r->svo_bytes));
	}
}

/* tables.md's closing lines: bits per voxel of the full-resolution row and
 * the compact encodings' sizes relative to the SVDAG. */
static void bits_md(struct text *c, const struct vd_enc_row *rows, size_t n)
{
	if (n) {
		const struct vd_enc_row *r = &rows[0];
		tprintf(c, "\nBits per voxel at %llu^3 (%llu voxels):",
			1ull << r->levels, (unsigned long long)r->voxels);
		for (int k = 0; k < VD_ENC_ALL_; k++) {
			int f = table_order[k];
			if (r->has[f])
				tprintf(c, " %s %.3f,", format_names[f],
					bpv(r->bytes[f], r->voxels));
		}
		tprintf(c, " svo %.3f.\n", bpv(r->svo_bytes, r->voxels));
		if (r->has[VD_ENC_SSVDAG] && r->bytes[VD_ENC_SVDAG])
			tprintf(c, "SSVDAG/SVDAG = %.1f%%, ESVDAG/SVDAG = %.1f%%.\n",
				100.0 * (double)r->bytes[VD_ENC_SSVDAG] / (double)r->bytes[VD_ENC_SVDAG],
				100.0 * (double)r->bytes[VD_ENC_ESVDAG] / (double)r->bytes[VD_ENC_SVDAG]);
		if (r->has[VD_ENC_SSVDAG48] && r->bytes[VD_ENC_SVDAG])
			tprintf(c, "SSVDAG48/SVDAG = %.1f%%.\n",
				100.0 * (double)r->bytes[VD_ENC_SSVDAG48] /
				(double)r->bytes[VD_ENC_SVDAG]);
	}
}

int vd_enc_write_tables(const char *dir, const char *name,
			const struct vd_enc_row *rows, size_t n,
			const struct vd_enc_timing *t, double seconds_encode)
{
	int err;
	if ((err = tables_json(dir, name, rows, n, t, seconds_encode)))
		return err;
	/* one text buffer, emptied between the files */
	struct text c = {0};
	table1_csv(&c, rows, n, t);
	if ((err = text_publish(&c, dir, name, "table1.csv")))
		return err;
	int g48 = n && rows[0].has_ssvdag48;
	table2_csv(&c, rows, n);
	if ((err = text_publish(&c, dir, name, "table2.csv")))
		return err;
	table1_md(&c, name, rows, n, t, seconds_encode);
	table2_md(&c, rows, n, g48);
	bits_md(&c, rows, n);
	err = text_publish(&c, dir, name, "tables.md");
	free(c.s);
	return err;
}

/* ---------------------------------------------------------- stage run */

/* Rewrites the current error as "<what> '<subject>': <cause>: <detail>". */
static int reword(int err, const char *what, const char *subject)
{
	char d[512];
	snprintf(d, sizeof d, "%s", vd_error_detail());
	return vd_fail(err, "%s '%s': %s%s%s", what, subject, vd_strerror(err),
		       *d ? ": " : "", d);
}

/* Opens a root chunk of `kind` and checks the budget against its header;
 * decode_roots loads it. */
static int open_root(struct vd_chunk **out, const char *path, uint32_t kind,
		     uint64_t *budget_used, uint64_t budget)
{
	struct vd_chunk *c;
	*out = NULL;
	int err = vd_chunk_open(&c, path, kind);
	if (err) return reword(err, "cannot read", path);
	const struct vd_chunk_header *h = vd_chunk_header(c);
	if (h->chunk_level != 0) {
		uint32_t level = h->chunk_level;
		uint64_t cell = h->cell_morton;
		vd_chunk_free(c);
		return vd_fail(VD_ERR_ARG, "cannot encode '%s': not a root chunk "
			       "(chunk level %u, cell %" PRIu64 "): merge the "
			       "chunks up to level 0 first (svo-to-dag --merge, "
			       "symmetry-merge --merge)", path, level, cell);
	}
	uint64_t nodes = 0;
	for (uint32_t i = 0; i + 1 < h->level_count; i++) nodes += h->level_nodes[i];
	/* the chunk in memory (masks, offsets, 8 references at most) */
	*budget_used += nodes * 61;
	if (budget && *budget_used > budget) {
		vd_chunk_free(c);
		return vd_fail(VD_ERR_BUDGET, "cannot load '%s': needs about "
			       "%" PRIu64 " MiB, budget --mem-budget %" PRIu64
			       " MiB", path, *budget_used >> 20, budget >> 20);
	}
	*out = c;
	return VD_OK;
}

/* The opened roots decoded side by side (the SVDAG and the SSVDAG are
 * about the same size: one each on two threads); errors reported in
 * input order. */
struct roots_job {
	struct vd_chunk *c[3];
	struct vd_dag *d[3];
	const char *path[3];
	uint32_t kind[3];
	int errs[3];
	char details[3][512];
};

static void root_worker(void *ctx, size_t i, int worker)
{
	(void)worker;
	struct roots_job *rj = ctx;
	if (!rj->c[i]) return;
	int err = vd_dag_from_chunk(rj->d[i], rj->c[i], rj->kind[i]);
	if (err) {
		vd_dag_release(rj->d[i]);
		err = reword(err, "cannot read", rj->path[i]);
		snprintf(rj->details[i], sizeof rj->details[i], "%s",
			 vd_error_detail());
	}
	rj->errs[i] = err;
}

static int decode_roots(struct roots_job *rj, int threads)
{
	int err = vd_parallel_for(3, threads, root_worker, rj);
	for (int i = 0; i < 3 && !err; i++)
		if (rj->errs[i]) err = vd_fail(rj->errs[i], "%s", rj->details[i]);
	return err;
}

struct row_job {
	const struct vd_dag *dag, *ssvdag, *ssvdag48;
	const uint64_t *sizes; /* of the files just written */
	const uint64_t (*counts)[VD_MAX_LEVELS + 1]; /* per source */
	struct vd_enc_row *rows;
	int *errs;
	char (*details)[512];
};

/* Task t is row t / 3 of source t % 3: the full-resolution cut of the
 * dag is most of the tables' work, so a task a row would leave a thread
 * idle while one works through it. */
static void row_worker(void *ctx, size_t t, int worker)
{
	(void)worker;
	struct row_job *r = ctx;
	const struct vd_dag *src[3] = {r->dag, r->ssvdag, r->ssvdag48};
	size_t i = t / 3;
	int k = (int)(t % 3);
	if (!src[k]) return;
	int err = table_row(r->dag, r->ssvdag, r->ssvdag48,
			    r->dag->levels - (int)i, &r->rows[t], r->sizes,
			    r->counts, k);
	r->errs[t] = err;
	if (err) snprintf(r->details[t], sizeof r->details[t], "%s",
			  vd_error_detail());
}



/* The encodings' files, one per format, built and written in parallel
 * when the job has threads (independent of one another; at most `threads`
 * of them in memory at once). An error's detail is the worker's, kept for
 * the caller to report the first in format order. */
struct file_job {
	const struct vd_dag *const *src;
	const struct vd_transform *t;
	const char *dir, *name;
	uint64_t *bytes;
	int *written;
	int errs[VD_ENC_ALL_];
	char details[VD_ENC_ALL_][1024];
};

static void file_worker(void *ctx, size_t i, int worker)
{
	(void)worker;
	struct file_job *fj = ctx;
	int f = (int)i;
	const struct vd_dag *d = fj->src[source_of(f)];
	if (!d || (vd_enc_format_compact(f) && d->levels < 3))
		return;
	char path[4096 + 512];
	snprintf(path, sizeof path, "%s/%s.%s", fj->dir, fj->name,
		 format_names[f]);
	struct vd_enc e;
	int err = vd_enc_build(&e, f, d, fj->t);
	if (err) err = reword(err, "cannot encode", path);
	else if ((err = vd_enc_save(&e, path)))
		err = reword(err, "cannot write", path);
	fj->bytes[f] = vd_enc_size_bytes(&e);
	fj->written[f] = !err;
	vd_enc_release(&e);
	fj->errs[f] = err;
	if (err)
		snprintf(fj->details[f], sizeof fj->details[f], "%s",
			 vd_error_detail());
}

/* Files an output directory from before manifests may hold (so it can be
 * replaced); anything else there is the user's. */
static int encode_file(const char *name)
{
	static const char *const ends[] = {".svdag", ".ussvdag", ".esvdag",
					   ".ssvdag", ".ssvdag48", ".tables.json",
					   ".table1.csv", ".table2.csv",
					   ".tables.md", ".encode.stats.json"};
	size_t n = strlen(name);
	for (size_t i = 0; i < sizeof ends / sizeof *ends; i++) {
		size_t e = strlen(ends[i]);
		if (n > e && !strcmp(name + n - e, ends[i]))
			return 1;
	}
	return 0;
}

/* One encode run's state, shared by its steps (vd_enc_run releases it). */
struct enc_run {
	const struct vd_enc_job *job;
	const char *name;
	struct vd_dag dag, ss, s48;
	struct vd_transform t1;
	const struct vd_dag *src[3]; /* dag, ssvdag, ssvdag48 or NULL */
	struct vd_enc_timing tm;
	char dir[4096]; /* the staging directory */
	uint64_t bytes[VD_ENC_ALL_];
	int written[VD_ENC_ALL_];
	struct vd_enc_row *rows;
	int *errs;
	char (*details)[512];
	double t0, t_load, t_enc, t_tab;
};

/* Reads the DAG and the symmetric DAGs given (their chunks' roots, within
 * the memory budget) and refuses them unless they are one scene with
 * voxels; sets r->src. */
static int run_load(struct enc_run *r)
{
	const struct vd_enc_job *job = r->job;
	struct vd_transform t2, t3;
	int err;
	uint64_t used = 0;
	/* the symmetric DAGs given: [0] the ssvdag, [1] the ssvdag48 */
	struct vd_dag *sym[2] = {&r->ss, &r->s48};
	struct vd_transform *st[2] = {&t2, &t3};
	const char *sp[2] = {job->ssvdag_path, job->ssvdag48_path};
	static const uint32_t sk[2] = {VD_KIND_SSVDAG, VD_KIND_SSVDAG48};
	struct roots_job roots = {{NULL}, {&r->dag, &r->ss, &r->s48},
			       {job->dag_path, sp[0], sp[1]},
			       {VD_KIND_DAG, sk[0], sk[1]}, {0}, {{0}}};
	err = VD_OK;
	for (int k = 0; k < 3 && !err; k++)
		if (roots.path[k])
			err = open_root(&roots.c[k], roots.path[k], roots.kind[k], &used,
					job->mem_budget_bytes);
	if (!err) {
		r->t1 = vd_chunk_header(roots.c[0])->transform;
		for (int k = 0; k < 2; k++)
			if (roots.c[k + 1]) *st[k] = vd_chunk_header(roots.c[k + 1])->transform;
		err = decode_roots(&roots, job->threads);
	}
	for (int k = 0; k < 3; k++) vd_chunk_free(roots.c[k]);
	if (err) return err;
	for (int k = 0; k < 2; k++) {
		if (!sp[k]) continue;
		if (r->dag.levels != sym[k]->levels || r->dag.voxels != sym[k]->voxels ||
		    !vd_transform_equal(&r->t1, st[k])) {
			err = vd_fail(VD_ERR_MISMATCH, "cannot encode '%s' with "
				      "'%s': not the same scene (%d and %d levels, %"
				      PRIu64 " and %" PRIu64 " voxels, or another "
				      "bounding box)", job->dag_path, sp[k],
				      r->dag.levels, sym[k]->levels, r->dag.voxels,
				      sym[k]->voxels);
			return err;
		}
	}
	r->src[0] = &r->dag;
	r->src[1] = job->ssvdag_path ? &r->ss : NULL;
	r->src[2] = job->ssvdag48_path ? &r->s48 : NULL;
	if (r->dag.voxels == 0) {
		err = vd_fail(VD_ERR_EMPTY, "cannot encode '%s': the scene has "
			      "no voxels", job->dag_path);
		return err;
	}
	return VD_OK;
}

/* Builds and writes every encoding into the staging directory, in
 * parallel; the first error in format order is the one reported. */
static int run_files(struct enc_run *r)
{
	int err;
	struct file_job fj = {r->src, &r->t1, r->dir, r->name, r->bytes,
			      r->written, {0}, {{0}}};
	if ((err = vd_parallel_for(VD_ENC_ALL_, r->job->threads, file_worker, &fj)))
		return err;
	for (int f = 0; f < VD_ENC_ALL_ && !err; f++)
		if (fj.errs[f])
			err = vd_fail(fj.errs[f], "%s", fj.details[f]);
	return err;
}

/* Computes the tables' rows (one per resolution from job->min_level up,
 * each joined from its three sources' rows, in parallel) and writes the
 * tables into the staging directory. */
static int run_tables(struct enc_run *r)
{
	const struct vd_enc_job *job = r->job;
	int err = VD_OK;
	int lo = job->min_level < 1 ? 1 : job->min_level;
	size_t nrows = r->dag.levels >= lo ? (size_t)(r->dag.levels - lo + 1) : 1;
	r->rows = calloc(3 * nrows, sizeof *r->rows);
	r->errs = calloc(3 * nrows, sizeof *r->errs);
	r->details = calloc(3 * nrows, sizeof *r->details);
	if (!r->rows || !r->errs || !r->details)
		return NOMEM();
	uint64_t counts[3][VD_MAX_LEVELS + 1];
	for (int k = 0; k < 3 && !err; k++)
		if (r->src[k]) err = vd_dag_svo_counts(r->src[k], counts[k]);
	if (err) return err;
	struct row_job rj = {&r->dag, r->src[1], r->src[2], r->bytes, counts,
			     r->rows, r->errs, r->details};
	if ((err = vd_parallel_for(3 * nrows, job->threads, row_worker, &rj)))
		return err;
	for (size_t t = 0; t < 3 * nrows; t++)
		if (r->errs[t]) {
			err = vd_fail(r->errs[t], "cannot compute the %llu^3 row: "
				      "%s: %s", 1ull << r->rows[t].levels,
				      vd_strerror(r->errs[t]), r->details[t]);
			return err;
		}
	for (size_t i = 0; i < nrows; i++) row_join(&r->rows[i], &r->rows[3 * i]);
	if ((err = vd_enc_write_tables(r->dir, r->name, r->rows, nrows, &r->tm,
				       r->t_enc))) {
		err = reword(err, "cannot write the tables in", job->outdir);
		return err;
	}
	return VD_OK;
}

/* Writes <name>.encode.stats.json into the staging directory: the scene,
 * each encoding's bytes (or why it was skipped) and the timings. */
static int run_stats(struct enc_run *r)
{
	const struct vd_enc_job *job = r->job;
	int err;
	char path[4096 + 512];
	snprintf(path, sizeof path, "%s/%s.encode.stats.json", r->dir, r->name);
	struct vd_json *j;
	if ((err = vd_json_open(&j, path))) {
		err = reword(err, "cannot write", path);
		return err;
	}
	vd_json_str(j, "tool", job->tool ? job->tool : "encode");
	vd_json_str(j, "version", VD_VERSION_STRING);
	vd_json_u64(j, "levels", (uint64_t)r->dag.levels);
	vd_json_u64(j, "voxels", r->dag.voxels);
	vd_json_u64(j, "nodes_svdag", dag_total_nodes(&r->dag));
	if (r->src[1]) vd_json_u64(j, "nodes_ssvdag", dag_total_nodes(&r->ss));
	if (r->src[2]) vd_json_u64(j, "nodes_ssvdag48", dag_total_nodes(&r->s48));
	for (int f = 0; f < VD_ENC_ALL_; f++) {
		char key[64];
		if (!r->written[f]) {
			snprintf(key, sizeof key, "skipped_%s", format_names[f]);
			vd_json_str(j, key, !r->src[source_of(f)] ?
				    (f == VD_ENC_SSVDAG48 ? "no ssvdag48 input"
							  : "no ssvdag input")
				    : "fewer than 3 levels");
			continue;
		}
		snprintf(key, sizeof key, "bytes_%s", format_names[f]);
		vd_json_u64(j, key, r->bytes[f]);
		snprintf(key, sizeof key, "file_bytes_%s", format_names[f]);
		vd_json_u64(j, key, r->bytes[f] + (vd_enc_format_compact(f) ?
			    VD_ENC_HEADER_BYTES_COMPACT : VD_ENC_HEADER_BYTES_WORDS));
	}
	vd_json_f64(j, "seconds_load", r->t_load);
	vd_json_f64(j, "seconds_encode", r->t_enc);
	vd_json_f64(j, "seconds_tables", r->t_tab);
	vd_json_f64(j, "seconds_total", vd_seconds() - r->t0);
	vd_json_u64(j, "peak_rss_bytes", vd_peak_rss_bytes());
	vd_json_f64(j, "process_cpu_seconds", vd_cpu_seconds());
	if ((err = vd_json_close(j))) {
		err = reword(err, "cannot write", path);
		return err;
	}
	return VD_OK;
}

/* The one progress line on stderr: each encoding's bytes, the compact
 * ones relative to the SVDAG, and the times. */
static void run_summary(const struct enc_run *r)
{
	const struct vd_enc_job *job = r->job;
	const uint64_t *bytes = r->bytes;
	const int *written = r->written;
	fprintf(stderr, "%s: %llu^3, %" PRIu64 " voxels: svdag %" PRIu64
		" B", job->tool ? job->tool : "encode",
		1ull << r->dag.levels, r->dag.voxels, bytes[VD_ENC_SVDAG]);
	if (written[VD_ENC_USSVDAG])
		fprintf(stderr, ", ussvdag %" PRIu64 " B",
			bytes[VD_ENC_USSVDAG]);
	if (r->dag.levels < 3)
		fprintf(stderr, ", no compact encodings (fewer than 3 "
			"levels)");
	if (written[VD_ENC_ESVDAG])
		fprintf(stderr, ", esvdag %" PRIu64 " B",
			bytes[VD_ENC_ESVDAG]);
	for (int f = VD_ENC_SSVDAG; f <= VD_ENC_SSVDAG48; f++)
		if (written[f])
			fprintf(stderr, ", %s %" PRIu64 " B (%.1f%% of "
				"svdag)", format_names[f], bytes[f],
				100.0 * (double)bytes[f] /
				(double)bytes[VD_ENC_SVDAG]);
	fprintf(stderr, "; encode %.3f s, tables %.3f s, in '%s'\n",
		r->t_enc, r->t_tab, job->outdir);
}

int vd_enc_run(const struct vd_enc_job *job)
{
	struct enc_run r = {0};
	int err, staged = 0;
	r.job = job;
	r.t0 = vd_seconds();
	r.name = job->name ? job->name : "scene";
	if (!job->dag_path || (!job->ssvdag_path && !job->ssvdag48_path) ||
	    !job->outdir)
		return vd_fail(VD_ERR_ARG, "the dag chunk, an ssvdag or ssvdag48 "
			       "chunk and the output directory are needed");
	if ((err = run_load(&r)))
		goto out;
	r.tm = (struct vd_enc_timing){-1, -1};
	for (size_t i = 0; i < job->n_stats; i++)
		if ((err = vd_enc_timing_add(&r.tm, job->stats_paths[i]))) {
			err = reword(err, "cannot read", job->stats_paths[i]);
			goto out;
		}
	/* every encoding and table or none: written into a staging directory
	 * that replaces job->outdir whole (with its manifest, the encodings'
	 * checksums) only once all are there */
	if ((err = vd_dir_stage(job->outdir, encode_file, r.dir, sizeof r.dir)))
		goto out;
	staged = 1;
	r.t_load = vd_seconds() - r.t0;
	double t_enc0 = vd_seconds();
	if ((err = run_files(&r)))
		goto out;
	r.t_enc = vd_seconds() - t_enc0;
	double t_tab0 = vd_seconds();
	if ((err = run_tables(&r)))
		goto out;
	r.t_tab = vd_seconds() - t_tab0;
	if ((err = run_stats(&r)))
		goto out;
	if (!job->quiet)
		run_summary(&r);
	if (!err && (err = vd_dir_publish(r.dir, job->outdir)))
		err = reword(err, "cannot finish", job->outdir);
out:
	if (err && staged)
		vd_dir_abandon(r.dir);
	free(r.rows);
	free(r.errs);
	free(r.details);
	vd_dag_release(&r.dag);
	vd_dag_release(&r.ss);
	vd_dag_release(&r.s48);
	return err;
}
