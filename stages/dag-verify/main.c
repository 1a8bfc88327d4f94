/* dag-verify - checks that a DAG or SSVDAG chunk holds exactly the voxels
 * of SVO chunks: silent on success, like a quick checker should be. */
#include "voxdag.h"
#include "cli.h"

#include <getopt.h>
#include <inttypes.h>
#include <stdlib.h>
#include <string.h>

#define TOOL "dag-verify"

static const char usage[] =
	"usage: dag-verify DAG SVO... [options]\n"
	"       dag-verify --diff A.dag B.dag\n"
	"\n"
	"Expands a DAG, SSVDAG or SSVDAG48 chunk (the 48-group symmetry merge),\n"
	"applying the reflections or transforms, and compares\n"
	"its voxels with the union of the SVO chunks, which must lie inside the\n"
	"DAG's cell and not overlap (cells without a chunk are empty). DAG may\n"
	"also be an encoded scene (.svdag, .ussvdag, .esvdag, .ssvdag,\n"
	".ssvdag48), decoded\n"
	"and compared with the SVO chunks of the whole grid, after checking it\n"
	"against the manifest encode wrote beside it. Prints nothing\n"
	"when they are equal; otherwise the number of differing voxels and the\n"
	"first one in Morton order.\n"
	"\n"
	"With --diff, walks two SVDAG chunks of the same cell together and\n"
	"prints the voxels that differ on stdout: 'differing_voxels=N\n"
	"only_a=X only_b=Y' (exit 0 once counted, whether or not they differ).\n"
	"Either may also be an SSVDAG root chunk or an encoding (decoded by its\n"
	"own decoder, checked against its manifest): then both scenes are\n"
	"expanded to their 4^3 bricks and compared.\n"
	"\n"
	"  -d, --diff              count the voxels differing between two DAGs\n"
	"  -m, --mem-budget SIZE   peak memory of the process (default 2GiB)\n"
	"  -q, --quiet             no message on a difference (exit status only)\n"
	"      --no-verify         read an encoding without a manifest (a file\n"
	"                          written by the SymVox tools)\n"
	"  -h, --help              this text\n"
	"\n"
	"Exit status: 0 equal, 1 different or failure (bad input, I/O, budget),\n"
	"2 usage.\n";



/* Walks the decoded bricks of an encoding against the sorted bricks of the
 * SVO chunks, counting differing voxels. */
struct enc_cmp {
	const uint64_t *keys, *masks;
	size_t n, at;
	uint64_t diff, first;
	int first_in_enc, have_first;
	uint64_t last;   /* the last key decoded */
	int have_last;
};

static void note(struct enc_cmp *c, uint64_t key, uint64_t a, uint64_t b)
{
	uint64_t x = a ^ b;
	if (!x)
		return;
	c->diff += (uint64_t)__builtin_popcountll(x);
	if (!c->have_first) {
		int bit = __builtin_ctzll(x);
		c->first = key << 6 | (uint64_t)bit;
		c->first_in_enc = (int)(a >> bit & 1);
		c->have_first = 1;
	}
}

static int enc_brick(void *ctx, uint64_t key, uint64_t brick)
{
	struct enc_cmp *c = ctx;
	/* The merge below needs the decoder's Morton order. */
	if (c->have_last && key <= c->last)
		return vd_fail(VD_ERR_CORRUPT, "brick %" PRIu64 " decoded after "
			       "brick %" PRIu64, key, c->last);
	c->last = key;
	c->have_last = 1;
	while (c->at < c->n && c->keys[c->at] < key) {
		note(c, c->keys[c->at], 0, c->masks[c->at]);
		c->at++;
	}
	if (c->at < c->n && c->keys[c->at] == key)
		note(c, key, brick, c->masks[c->at++]);
	else
		note(c, key, brick, 0);
	return 0;
}

static int cmp_cell(const void *a, const void *b)
{
	const struct vd_svo *x = a, *y = b;
	return (x->cell_morton > y->cell_morton) - (x->cell_morton < y->cell_morton);
}

/* Compares an encoded scene with the SVO chunks (all of one chunk level). */
static int verify_encoding(const char *path, int format, struct vd_svo *svos,
			   size_t n, int quiet, int check_manifest)
{
	struct vd_enc e;
	memset(&e, 0, sizeof e);
	int err = check_manifest ? vd_manifest_check_file(path) : VD_OK;
	if (!err)
		err = vd_enc_load(&e, path, format);
	if (err)
		return vd_cli_fail(TOOL, err, "cannot read", path);
	qsort(svos, n, sizeof *svos, cmp_cell);
	size_t total = 0;
	for (size_t i = 0; i < n; i++)
		total += svos[i].count;
	uint64_t *keys = malloc((total ? total : 1) * 8),
		 *masks = malloc((total ? total : 1) * 8);
	if (!keys || !masks) {
		free(keys);
		free(masks);
		vd_enc_release(&e);
		fprintf(stderr, "dag-verify: out of memory\n");
		return 1;
	}
	size_t k = 0;
	for (size_t i = 0; i < n; i++) {
		memcpy(keys + k, svos[i].keys, 8 * svos[i].count);
		memcpy(masks + k, svos[i].masks, 8 * svos[i].count);
		k += svos[i].count;
	}
	struct enc_cmp c = {.keys = keys, .masks = masks, .n = total};
	err = vd_enc_expand(&e, enc_brick, &c);
	if (err) {
		free(keys);
		free(masks);
		vd_enc_release(&e);
		return vd_cli_fail(TOOL, err, "cannot decode", path);
	}
	while (c.at < c.n) {
		note(&c, keys[c.at], 0, masks[c.at]);
		c.at++;
	}
	free(keys);
	free(masks);
	vd_enc_release(&e);
	if (!c.diff)
		return 0;
	/* brick key << 6 | bit: the voxel is brick*4 + local coordinates */
	uint32_t bx, by, bz, lx, ly, lz;
	vd_morton3_decode(c.first >> 6, &bx, &by, &bz);
	vd_morton3_decode(c.first & 63, &lx, &ly, &lz);
	if (!quiet)
		fprintf(stderr, "dag-verify: '%s' differs from the SVO chunks in "
			"%" PRIu64 " voxels; first at voxel (%u, %u, %u), set in "
			"the encoding only: %s\n", path, c.diff, 4 * bx + lx,
			4 * by + ly, 4 * bz + lz, c.first_in_enc ? "yes" : "no");
	return 1;
}

/* A scene's bricks in Morton order (from vd_dag_expand/vd_enc_expand). */
struct bricks {
	uint64_t *keys, *masks;
	size_t n, cap;
	uint64_t bytes, budget; /* held so far, --mem-budget */
};

static int add_brick(void *ctx, uint64_t key, uint64_t brick)
{
	struct bricks *b = ctx;
	if (b->n == b->cap) {
		size_t cap = b->cap ? 2 * b->cap : 4096;
		if (b->bytes + 16 * (cap - b->cap) > b->budget)
			return vd_fail(VD_ERR_BUDGET, "the expanded bricks need "
				       "more than --mem-budget %" PRIu64 " MiB",
				       b->budget >> 20);
		uint64_t *k = realloc(b->keys, cap * 8);
		if (k) b->keys = k;
		uint64_t *m = k ? realloc(b->masks, cap * 8) : NULL;
		if (m) b->masks = m;
		if (!k || !m)
			return vd_fail(VD_ERR_NOMEM, "out of memory");
		b->bytes += 16 * (cap - b->cap);
		b->cap = cap;
	}
	b->keys[b->n] = key;
	b->masks[b->n++] = brick;
	return 0;
}

/* Expands `path`, a DAG/SSVDAG root chunk or an encoding, into *b and its
 * depth into *levels. Prints one line and returns 1 on failure. */
static int load_bricks(const char *path, struct bricks *b, int *levels,
		       int check_manifest)
{
	struct vd_chunk_header h;
	int err = vd_chunk_read_header(path, &h);
	if (err == VD_ERR_NOT_CHUNK && vd_enc_format_from_path(path) >= 0) {
		struct vd_enc e;
		memset(&e, 0, sizeof e);
		err = check_manifest ? vd_manifest_check_file(path) : VD_OK;
		if (!err)
			err = vd_enc_load(&e, path, -1);
		if (err) {
			vd_enc_release(&e);
			return vd_cli_fail(TOOL, err, "cannot read", path);
		}
		*levels = (int)e.levels;
		err = vd_enc_expand(&e, add_brick, b);
		vd_enc_release(&e);
		return err ? vd_cli_fail(TOOL, err, "cannot decode", path) : 0;
	}
	if (err)
		return vd_cli_fail(TOOL, err, "cannot read", path);
	struct vd_dag d;
	memset(&d, 0, sizeof d);
	if ((err = vd_dag_load(&d, NULL, path, VD_KIND_ANY_DAG)))
		return vd_cli_fail(TOOL, err, "cannot read", path);
	b->bytes += vd_dag_memory_bytes(&d);
	*levels = d.levels;
	err = d.chunk_level != 0
		      ? vd_fail(VD_ERR_ARG, "not a root chunk (chunk level %d)",
				d.chunk_level)
	      : b->bytes > b->budget
		      ? vd_fail(VD_ERR_BUDGET, "needs more than --mem-budget "
				"%" PRIu64 " MiB", b->budget >> 20)
		      : vd_dag_expand(&d, add_brick, b);
	b->bytes -= vd_dag_memory_bytes(&d);
	vd_dag_release(&d);
	return err ? vd_cli_fail(TOOL, err, "cannot expand", path) : 0;
}

/* --diff where one side is not an SVDAG chunk: both expanded to bricks
 * and merged in Morton order. */
static int diff_bricks(const char *pa, const char *pb, uint64_t budget,
		       int quiet, int check_manifest)
{
	struct bricks a = {.budget = budget}, b = {.budget = budget};
	int la = 0, lb = 0, rc = load_bricks(pa, &a, &la, check_manifest);
	b.bytes = a.bytes;
	if (!rc)
		rc = load_bricks(pb, &b, &lb, check_manifest);
	if (!rc && la != lb) {
		fprintf(stderr, "dag-verify: cannot compare '%s' (2^%d) and '%s' "
			"(2^%d): not the same grid\n", pa, la, pb, lb);
		rc = 1;
	}
	uint64_t oa = 0, ob = 0;
	for (size_t i = 0, k = 0; !rc && (i < a.n || k < b.n);) {
		if (k == b.n || (i < a.n && a.keys[i] < b.keys[k])) {
			oa += (uint64_t)__builtin_popcountll(a.masks[i++]);
		} else if (i == a.n || b.keys[k] < a.keys[i]) {
			ob += (uint64_t)__builtin_popcountll(b.masks[k++]);
		} else {
			oa += (uint64_t)__builtin_popcountll(a.masks[i] & ~b.masks[k]);
			ob += (uint64_t)__builtin_popcountll(b.masks[k] & ~a.masks[i]);
			i++, k++;
		}
	}
	free(a.keys);
	free(a.masks);
	free(b.keys);
	free(b.masks);
	if (!rc && !quiet)
		printf("differing_voxels=%" PRIu64 " only_a=%" PRIu64 " only_b=%"
		       PRIu64 "\n", oa + ob, oa, ob);
	return rc;
}

static int symmetric(uint32_t kind)
{
	return kind == VD_KIND_SSVDAG || kind == VD_KIND_SSVDAG48;
}

/* --diff: the voxels differing between two SVDAG chunks. */
static int diff_dags(const char *pa, const char *pb, uint64_t budget,
		     int quiet, int check_manifest)
{
	struct vd_dag a, b;
	struct vd_chunk_header ha, hb;
	memset(&a, 0, sizeof a);
	memset(&b, 0, sizeof b);
	int err = vd_chunk_read_header(pa, &ha);
	int errb = vd_chunk_read_header(pb, &hb);
	/* an encoding or an SSVDAG (8 or 48) on either side: through the
	 * bricks */
	if ((err == VD_ERR_NOT_CHUNK && vd_enc_format_from_path(pa) >= 0) ||
	    (errb == VD_ERR_NOT_CHUNK && vd_enc_format_from_path(pb) >= 0) ||
	    (!err && !errb && (symmetric(ha.kind) || symmetric(hb.kind))))
		return diff_bricks(pa, pb, budget, quiet, check_manifest);
	if (err) return vd_cli_fail(TOOL, err, "cannot read", pa);
	if ((err = errb))
		return vd_cli_fail(TOOL, err, "cannot read", pb);
	/* both loaded plus the pair memo: about 3x their bounds */
	uint64_t need = 3 * (vd_dag_estimate_header(&ha) +
			     vd_dag_estimate_header(&hb));
	if (need > budget) {
		fprintf(stderr, "dag-verify: cannot compare '%s' and '%s': memory "
			"budget too small: about %" PRIu64 " MiB needed, budget "
			"--mem-budget %" PRIu64 " MiB\n", pa, pb, need >> 20,
			budget >> 20);
		return 1;
	}
	if ((err = vd_dag_load(&a, NULL, pa, VD_KIND_DAG)))
		return vd_cli_fail(TOOL, err, "cannot read", pa);
	if ((err = vd_dag_load(&b, NULL, pb, VD_KIND_DAG))) {
		vd_dag_release(&a);
		return vd_cli_fail(TOOL, err, "cannot read", pb);
	}
	uint64_t oa, ob, vb;
	err = vd_dag_diff(&a, &b, &oa, &ob, &vb);
	vd_dag_release(&a);
	vd_dag_release(&b);
	if (err) return vd_cli_fail(TOOL, err, "cannot compare", pa);
	if (!quiet)
		printf("differing_voxels=%" PRIu64 " only_a=%" PRIu64 " only_b=%"
		       PRIu64 "\n", oa + ob, oa, ob);
	return 0;
}

int main(int argc, char **argv)
{
	static const struct option longopts[] = {
		{"diff", no_argument, NULL, 'd'},
		{"mem-budget", required_argument, NULL, 'm'},
		{"quiet", no_argument, NULL, 'q'},
		{"no-verify", no_argument, NULL, 'V'},
		{"help", no_argument, NULL, 'h'},
		{NULL, 0, NULL, 0},
	};
	uint64_t budget = 2ull << 30;
	int c, quiet = 0, check_manifest = 1, diff_mode = 0;
	while ((c = getopt_long(argc, argv, "dm:qh", longopts, NULL)) != -1) {
		switch (c) {
		case 'd':
			diff_mode = 1;
			break;
		case 'm':
			if (vd_parse_size(optarg, &budget) || budget == 0)
				return vd_cli_usage(TOOL, "--mem-budget '%s' is not a "
						   "size (e.g. 512M, 2GiB)", optarg);
			break;
		case 'q':
			quiet = 1;
			break;
		case 'V':
			check_manifest = 0;
			break;
		case 'h':
			fputs(usage, stdout);
			return 0;
		default:
			fprintf(stderr, "Try 'dag-verify --help'.\n");
			return 2;
		}
	}
	if (diff_mode) {
		if (argc - optind != 2)
			return vd_cli_usage(TOOL, "%s", "--diff needs exactly two "
					   "DAG chunks or encodings");
		return diff_dags(argv[optind], argv[optind + 1], budget, quiet,
				 check_manifest);
	}
	if (argc - optind < 2)
		return vd_cli_usage(TOOL, "%s", "needs a DAG chunk and at least one "
				   "SVO chunk");
	const char *dag_path = argv[optind];
	size_t n = (size_t)(argc - optind - 1);
	/* a chunk file is known by its magic, whatever its name; only other
	 * files are taken as encodings by their extension */
	struct vd_chunk_header ch_head;
	int format = vd_chunk_read_header(dag_path, &ch_head) == VD_ERR_NOT_CHUNK
			     ? vd_enc_format_from_path(dag_path) : -1;
	struct vd_dag dag;
	memset(&dag, 0, sizeof dag);
	int err = format >= 0 ? VD_OK
			      : vd_dag_load(&dag, NULL, dag_path, VD_KIND_ANY_DAG);
	if (err) return vd_cli_fail(TOOL, err, "cannot read", dag_path);
	uint64_t used = format >= 0 ? 0 : vd_dag_memory_bytes(&dag);
	struct vd_svo *svos = calloc(n, sizeof *svos);
	const struct vd_svo **sp = calloc(n, sizeof *sp);
	int rc = 0;
	if (!svos || !sp) {
		fprintf(stderr, "dag-verify: out of memory\n");
		rc = 1;
	}
	for (size_t i = 0; i < n && !rc; i++) {
		const char *path = argv[optind + 1 + i];
		struct vd_chunk *ch;
		if ((err = vd_chunk_open(&ch, path, VD_KIND_SVO))) {
			rc = vd_cli_fail(TOOL, err, "cannot read", path);
			break;
		}
		const struct vd_chunk_header *h = vd_chunk_header(ch);
		uint64_t bricks = h->level_count >= 3 ?
			h->level_nodes[h->level_count - 3] : 1;
		used += 16 * bricks;
		if (used > budget) {
			vd_chunk_free(ch);
			fprintf(stderr, "dag-verify: cannot load '%s': memory budget"
				" too small: the chunks need about %" PRIu64 " MiB, "
				"budget --mem-budget %" PRIu64 " MiB\n", path,
				used >> 20, budget >> 20);
			rc = 1;
			break;
		}
		err = vd_svo_from_chunk(&svos[i], ch);
		vd_chunk_free(ch);
		if (err) {
			rc = vd_cli_fail(TOOL, err, "cannot read", path);
			break;
		}
		sp[i] = &svos[i];
	}
	if (!rc && format >= 0) {
		rc = verify_encoding(dag_path, format, svos, n, quiet,
				     check_manifest);
	} else if (!rc) {
		struct vd_dag_diff diff;
		err = vd_dag_compare_svo(&dag, sp, n, &diff);
		if (err) {
			rc = vd_cli_fail(TOOL, err, "cannot compare", dag_path);
		} else if (diff.differing_voxels) {
			uint32_t x, y, z;
			vd_morton3_decode(diff.first_voxel_morton, &x, &y, &z);
			if (!quiet)
				fprintf(stderr, "dag-verify: '%s' differs from the "
					"SVO chunks in %" PRIu64 " voxels; first at "
					"voxel (%u, %u, %u), set in the %s only\n",
					dag_path, diff.differing_voxels, x, y, z,
					diff.first_in_dag ? "DAG" : "SVO chunks");
			rc = 1;
		}
	}
	for (size_t i = 0; i < n; i++) vd_svo_release(&svos[i]);
	free(svos);
	free(sp);
	vd_dag_release(&dag);
	return rc;
}
