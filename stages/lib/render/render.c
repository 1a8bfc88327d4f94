/* render.c - ray casting straight through the compact encodings and DAG
 * chunks (SSVDAG paper section 5), images, PNG/PFM output and the render
 * stage's run. Conventions are in vd_render.h.
 *
 * Traversal. The tracer keeps the path from the root to the current node in
 * a stack (one entry per level: where the node is stored and the reflection
 * accumulated on the way) and the current node's integer corner `lo`. In a
 * node it picks the child holding the ray at the current time t by
 * comparing t with the times of the node's three middle planes; a
 * non-empty child is pushed (or is the hit, at the last level or when the
 * LOD test says it is small enough), an empty one is skipped: t becomes the
 * child's exit time, the cell across the crossed planes gets integer
 * coordinates, and the highest bit in which they differ from the child's
 * says how many levels to pop — straight to the ancestor holding both, with
 * no push when the step leaves the node. Every decision compares times of
 * integer planes computed one way (tp() below), which is what makes the
 * result exactly reproducible by a voxel DDA (tests/unit/test_render.c).
 *
 * Fast paths. The tracer reads the packed words directly instead of going
 * through vd_enc_child() / vd_enc_brick() (which are correct but do loops
 * per call): word formats read the header and popcount to the pointer;
 * compact nodes sum pointer sizes from the 2-bit tags with two popcounts;
 * a compact brick is converted from the SymVox bit order (16x + 4y + z) to
 * our Morton order by three bit-index swaps and reflected once when the
 * traversal enters it, after which its two levels are plain masks.
 *
 * .ssvdag48. The path carries a cube transform (0..47) instead of a
 * reflection: logical slot p of a node reached with transform a is stored
 * slot a^-1(p), its child stored with t is reached with a t (the group's
 * composition), a mask is moved by a table and the brick once on entry,
 * as above. The ray itself is never transformed: the transform maps the
 * stored nodes onto the ray's own frame, so every plane time stays the one
 * formula tp() and the result stays exactly the DDA's. */
#include "voxdag.h"
#include "util_internal.h"
#include "le.h"
#include "dag/dag_internal.h" /* the cube group's tables */
#include "io/publish.h"
#include "encode/encode_internal.h" /* the compact pointers */

#include <errno.h>
#include <jansson.h>
#include <inttypes.h>
#include <math.h>
#include <png.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define NOMEM() vd_fail(VD_ERR_NOMEM, "out of memory")

/* ------------------------------------------------------------- scenes */

int vd_render_scene_from_enc(struct vd_render_scene *s, const struct vd_enc *e)
{
	memset(s, 0, sizeof *s);
	float side = e->root_side;
	if (!isfinite(side) || !(side > 0))
		return vd_fail(VD_ERR_RANGE, "root side %g is not a positive "
			       "number", (double)side);
	for (int a = 0; a < 3; a++) {
		if (!isfinite(e->bbox_min[a]) || !isfinite(e->bbox_max[a]))
			return vd_fail(VD_ERR_RANGE, "bounding box is not finite");
		/* as vd_transform_init(): the centre in float32 like SymVox */
		float c = 0.5f * e->bbox_min[a] + 0.5f * e->bbox_max[a];
		s->origin[a] = (double)c - 0.5 * (double)side;
		s->bbox_min[a] = e->bbox_min[a];
		s->bbox_max[a] = e->bbox_max[a];
	}
	if (e->format == VD_ENC_SSVDAG48) vd__g48_init();
	s->enc = e;
	s->levels = (int)e->levels;
	s->voxel_size = (double)side / (double)(1u << e->levels);
	return VD_OK;
}

int vd_render_scene_from_dag(struct vd_render_scene *s, const struct vd_dag *d,
			     const struct vd_transform *t)
{
	memset(s, 0, sizeof *s);
	if (d->chunk_level != 0)
		return vd_fail(VD_ERR_ARG, "not a root chunk (chunk level %d)",
			       d->chunk_level);
	if (!(t->voxel_size > 0) || !isfinite(t->voxel_size))
		return vd_fail(VD_ERR_RANGE, "voxel size %g is not a positive "
			       "number", t->voxel_size);
	for (int a = 0; a < 3; a++) {
		s->origin[a] = t->origin[a];
		s->bbox_min[a] = t->bbox_min[a];
		s->bbox_max[a] = t->bbox_max[a];
	}
	s->dag = d;
	s->levels = d->levels;
	s->voxel_size = t->voxel_size;
	return VD_OK;
}

/* --------------------------------------------------------- node access */

enum source { SRC_WORDS, SRC_COMPACT, SRC_DAG };

struct tracer {
	enum source src;
	int L;
	int g48;            /* .ssvdag48: pnode.refl is a cube transform */
	const uint32_t *words;
	const uint16_t *inner;
	const uint8_t *leaves;
	const uint32_t *level_offsets;
	const struct vd_dag *dag;
};

/* A node on the path: where it is stored and its accumulated reflection
 * (a cube transform when T->g48).
 * Compact formats: `at` is an index in inner[] above level L-2; on level
 * L-2 the brick itself is held by the tracer (at is unused); on level L-1
 * `at` is the logical child slot of the brick, i.e. its byte. */
struct pnode {
	uint64_t at;
	unsigned refl;
};

/* Swaps, in a 64-bit set indexed by 6-bit numbers, the two index bits
 * whose distance is `shift` (mask: the indices with the lower bit 1 and the
 * higher bit 0). */
static inline uint64_t swap_index_bits(uint64_t x, uint64_t mask, int shift)
{
	uint64_t t = ((x >> shift) ^ x) & mask;
	return x ^ t ^ (t << shift);
}

/* SymVox brick (bit x1 x0 y1 y0 z1 z0) to ours (bit x1 y1 z1 x0 y0 z0):
 * swap index bits 4/3, then 3/1, then 2/1. */
static inline uint64_t brick_from_symvox(uint64_t v)
{
	v = swap_index_bits(v, 0x0000ff000000ff00ULL, 8);
	v = swap_index_bits(v, 0x00cc00cc00cc00ccULL, 6);
	v = swap_index_bits(v, 0x0c0c0c0c0c0c0c0cULL, 2);
	return v;
}

/* Bit p set when byte p of v is not zero. */
static inline unsigned nonzero_bytes(uint64_t v)
{
	v |= v >> 4;
	v |= v >> 2;
	v |= v >> 1;
	v &= 0x0101010101010101ULL;
	return (unsigned)((v * 0x0102040810204080ULL) >> 56);
}

/* Stored child mask of a compact header: bit s when tag s is not 00. */
static inline unsigned compact_mask(unsigned h)
{
	h = (h | h >> 1) & 0x5555;
	h = (h | h >> 1) & 0x3333;
	h = (h | h >> 2) & 0x0f0f;
	h = (h | h >> 4) & 0x00ff;
	return h;
}

static inline uint64_t load_brick(const struct tracer *T, uint64_t at,
				  unsigned refl)
{
	const uint8_t *b = T->leaves + at;
	uint64_t v = 0;
	for (int i = 7; i >= 0; i--) v = v << 8 | b[i];
	v = brick_from_symvox(v);
	return T->g48 ? vd_g48_brick(v, refl) : vd_brick_reflect(v, refl);
}

/* A stored child mask seen through the accumulated reflection/transform. */
static inline unsigned seen_mask(const struct tracer *T, unsigned v,
				 unsigned refl)
{
	return T->g48 ? vd__g48_masks[refl][v] : vd_mask_reflect((uint8_t)v, refl);
}

/* Logical child mask of node n on `level`. */
static inline unsigned node_mask(const struct tracer *T, int level,
				 const struct pnode *n, uint64_t brick)
{
	switch (T->src) {
	case SRC_WORDS:
		return vd_mask_reflect((uint8_t)T->words[n->at], n->refl);
	case SRC_DAG:
		return vd_mask_reflect(T->dag->lv[level].mask[n->at], n->refl);
	case SRC_COMPACT:
		if (level < T->L - 2)
			return seen_mask(T, compact_mask(T->inner[n->at]), n->refl);
		if (level == T->L - 2) return nonzero_bytes(brick);
		return (unsigned)(brick >> 8 * n->at) & 0xff;
	}
	return 0;
}

/* Child p (logical, known to exist) of node n on `level` < L-1; loads the
 * brick when the child is on the compact brick level. */
static inline void node_child(const struct tracer *T, int level,
			      const struct pnode *n, unsigned p,
			      struct pnode *c, uint64_t *brick)
{
	unsigned s = T->g48 ? vd__g48_child[vd__g48_inv[n->refl]][p]
			    : (p ^ n->refl) & 7;
	switch (T->src) {
	case SRC_WORDS: {
		uint32_t h = T->words[n->at];
		unsigned idx = (unsigned)__builtin_popcount((h & 0xff) >> s);
		unsigned m = (h >> (8 + s) & 1) << 2 | (h >> (16 + s) & 1) << 1 |
			     (h >> (24 + s) & 1);
		c->at = T->words[n->at + idx];
		c->refl = n->refl ^ m;
		return;
	}
	case SRC_DAG: {
		const struct vd_dag_level *lv = &T->dag->lv[level];
		uint64_t k = lv->first[n->at] +
			     (uint64_t)__builtin_popcount(lv->mask[n->at] &
							  ((1u << s) - 1));
		c->at = lv->child[k];
		c->refl = n->refl ^ (lv->refl ? lv->refl[k] : 0u);
		return;
	}
	case SRC_COMPACT: {
		if (level == T->L - 2) { /* inside the brick: the byte */
			c->at = p;
			c->refl = 0;
			return;
		}
		unsigned h = T->inner[n->at];
		unsigned lo = h & 0x5555, hi = h >> 1 & 0x5555;
		unsigned above = 0xffffu << (2 * s + 2) & 0xffff;
		uint64_t off = n->at + 1 +
			       (unsigned)__builtin_popcount((lo | hi) & above) +
			       (unsigned)__builtin_popcount(hi & above);
		unsigned tag = h >> 2 * s & 3;
		const uint16_t *w = T->inner + off;
		unsigned m;
		uint32_t addr;
		if (T->g48) {
			addr = vd__enc_unpack_ptr48(tag, w, &m);
			c->refl = vd__g48_comp[n->refl][m];
		} else {
			addr = vd__enc_unpack_ptr(tag, w, &m);
			c->refl = n->refl ^ m;
		}
		if (level + 1 < T->L - 2) {
			c->at = (uint64_t)T->level_offsets[level + 1] + addr;
		} else {
			c->at = (uint64_t)addr * 8;
			*brick = load_brick(T, c->at, c->refl);
		}
		return;
	}
	}
}

/* ------------------------------------------------------------ tracing */

/* The one formula for the time of integer plane k (see vd_render.h). */
static inline double tp(const double *o, const double *inv, int a, int64_t k)
{
	return ((double)k - o[a]) * inv[a];
}

/* Fills the hit for the cell [lo, lo + side) on grid level `level`. */
static void make_hit(const struct vd_ray *r, const double *o, const double *inv,
		     const int *dir, const int64_t *lo, int64_t side, int level,
		     int L, struct vd_hit *h)
{
	double tin = -INFINITY;
	int ax = -1;
	for (int a = 0; a < 3; a++) {
		if (!dir[a]) continue;
		double near = tp(o, inv, a, dir[a] > 0 ? lo[a] : lo[a] + side);
		if (near > tin) {
			tin = near;
			ax = a;
		}
	}
	if (tin < r->tmin) {
		h->t = r->tmin;
		h->axis = -1;
	} else {
		h->t = tin;
		h->axis = ax;
	}
	for (int a = 0; a < 3; a++) h->cell[a] = (uint32_t)(lo[a] >> (L - level));
	h->level = level;
}

int vd_render_trace(const struct vd_render_scene *s, const struct vd_ray *r,
		    struct vd_hit *h)
{
	struct tracer T = {0};
	T.L = s->levels;
	if (s->dag) {
		if (!s->dag->lv[0].nodes) return 0; /* empty scene */
		T.src = SRC_DAG;
		T.dag = s->dag;
	} else if (vd_enc_format_compact(s->enc->format)) {
		T.src = SRC_COMPACT;
		T.g48 = s->enc->format == VD_ENC_SSVDAG48;
		T.inner = s->enc->inner;
		T.leaves = s->enc->leaves;
		T.level_offsets = s->enc->level_offsets;
	} else {
		T.src = SRC_WORDS;
		T.words = s->enc->words;
	}
	const int L = T.L;
	const int64_t N = (int64_t)1 << L;
	double o[3], inv[3];
	int dir[3];
	int64_t fo[3] = {0, 0, 0};
	double t = r->tmin;
	int moving = 0;
	if (!isfinite(r->o[0]) || !isfinite(r->o[1]) || !isfinite(r->o[2]) ||
	    isnan(r->tmin) || isnan(r->tmax))
		return 0; /* no ray */
	for (int a = 0; a < 3; a++) {
		o[a] = r->o[a];
		/* a component whose reciprocal overflows counts as 0: plane
		 * times must be finite for the traversal to make progress */
		if (isfinite(1.0 / r->d[a])) {
			dir[a] = r->d[a] > 0 ? 1 : -1;
			inv[a] = 1.0 / r->d[a];
			moving = 1;
			double near = tp(o, inv, a, dir[a] > 0 ? 0 : N);
			if (near > t) t = near;
		} else {
			dir[a] = 0;
			inv[a] = 0;
			double f = floor(o[a]);
			if (!(f >= 0 && f < (double)N)) return 0;
			fo[a] = (int64_t)f;
		}
	}
	if (!moving) return 0;
	double tend = r->tmax;
	for (int a = 0; a < 3; a++)
		if (dir[a]) {
			double far = tp(o, inv, a, dir[a] > 0 ? N : 0);
			if (far < tend) tend = far;
		}
	if (!(t < tend)) return 0;

	struct pnode stack[VD_MAX_LEVELS + 1];
	uint64_t brick = 0;
	int level = 0;
	int64_t lo[3] = {0, 0, 0};
	stack[0].at = 0;
	stack[0].refl = 0;
	const double lod = r->lod > 0 ? r->lod : 0;
	for (;;) {
		const int64_t half = (int64_t)1 << (L - level - 1);
		unsigned p = 0;
		int64_t clo[3];
		for (int a = 0; a < 3; a++) {
			int64_t mid = lo[a] + half;
			int up = dir[a] > 0 ? tp(o, inv, a, mid) <= t :
				 dir[a] < 0 ? tp(o, inv, a, mid) > t :
					      fo[a] >= mid;
			p |= (unsigned)up << (2 - a);
			clo[a] = up ? mid : lo[a];
		}
		unsigned mask = node_mask(&T, level, &stack[level], brick);
		if (mask >> p & 1) {
			if (level + 1 == L || (lod > 0 && (double)half <= lod * t)) {
				make_hit(r, o, inv, dir, clo, half, level + 1, L, h);
				return 1;
			}
			node_child(&T, level, &stack[level], p, &stack[level + 1],
				   &brick);
			level++;
			lo[0] = clo[0];
			lo[1] = clo[1];
			lo[2] = clo[2];
			continue;
		}
		/* skip the empty child: leave it through its nearest far plane */
		double far[3], tx = INFINITY;
		for (int a = 0; a < 3; a++) {
			far[a] = INFINITY;
			if (dir[a])
				far[a] = tp(o, inv, a, dir[a] > 0 ? clo[a] + half : clo[a]);
			if (far[a] < tx) tx = far[a];
		}
		if (!(tx < r->tmax)) return 0;
		uint64_t diff = 0;
		int64_t nc[3];
		for (int a = 0; a < 3; a++) {
			nc[a] = clo[a];
			if (far[a] == tx) {
				nc[a] = dir[a] > 0 ? clo[a] + half : clo[a] - 1;
				if (nc[a] < 0 || nc[a] >= N) return 0;
				diff |= (uint64_t)(nc[a] ^ clo[a]);
			}
		}
		/* the deepest level whose cell holds both: bits >= L - l agree */
		int hb = 63 - __builtin_clzll(diff);
		int nl = L - hb - 1;
		if (nl < level) level = nl;
		int64_t cmask = ~(((int64_t)1 << (L - level)) - 1);
		for (int a = 0; a < 3; a++) lo[a] = nc[a] & cmask;
		t = tx;
	}
}

/* ------------------------------------------------------------- cameras */

static double dot3(const double *a, const double *b)
{
	return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static void cross3(const double *a, const double *b, double *c)
{
	c[0] = a[1] * b[2] - a[2] * b[1];
	c[1] = a[2] * b[0] - a[0] * b[2];
	c[2] = a[0] * b[1] - a[1] * b[0];
}

static double norm3(double *v)
{
	double n = sqrt(dot3(v, v));
	if (n > 0)
		for (int a = 0; a < 3; a++) v[a] /= n;
	return n;
}

int vd_camera_check(const struct vd_camera *c)
{
	for (int a = 0; a < 3; a++)
		if (!isfinite(c->eye[a]) || !isfinite(c->target[a]) ||
		    !isfinite(c->up[a]))
			return vd_fail(VD_ERR_ARG, "camera position, target or up "
				       "is not finite");
	if (!(c->fov_deg > 0 && c->fov_deg < 180))
		return vd_fail(VD_ERR_ARG, "field of view %g is not in (0, 180) "
			       "degrees", c->fov_deg);
	double f[3], u[3], x[3];
	for (int a = 0; a < 3; a++) {
		f[a] = c->target[a] - c->eye[a];
		u[a] = c->up[a];
	}
	if (!(norm3(f) > 0))
		return vd_fail(VD_ERR_ARG, "eye and target are the same point");
	if (!(norm3(u) > 0))
		return vd_fail(VD_ERR_ARG, "up vector is zero");
	cross3(f, u, x);
	if (!(sqrt(dot3(x, x)) > 1e-9))
		return vd_fail(VD_ERR_ARG, "up vector is parallel to the viewing "
			       "direction");
	return VD_OK;
}

int vd_camera_preset(struct vd_camera *c, const struct vd_render_scene *s,
		     const char *name, double fov_deg, int width, int height)
{
	static const struct {
		const char *name;
		double dir[3], up[3];
	} presets[] = {
		{"front", {0, 0, 1}, {0, 1, 0}},
		{"side", {1, 0, 0}, {0, 1, 0}},
		{"top", {0, 1, 0}, {0, 0, -1}},
		{"iso", {0.57735026918962573, 0.57735026918962573,
			 0.57735026918962573}, {0, 1, 0}},
	};
	int k = -1;
	for (int i = 0; i < 4; i++)
		if (!strcmp(name, presets[i].name)) k = i;
	if (k < 0)
		return vd_fail(VD_ERR_ARG, "unknown camera preset '%s' (front, "
			       "side, top, iso)", name);
	if (!(fov_deg > 0 && fov_deg < 180))
		return vd_fail(VD_ERR_ARG, "field of view %g is not in (0, 180) "
			       "degrees", fov_deg);
	/* the nearest distance at which all 8 corners of the bounding box
	 * project inside the frame, plus a margin */
	double centre[3], fwd[3], right[3], up[3];
	for (int a = 0; a < 3; a++) {
		centre[a] = 0.5 * ((double)s->bbox_min[a] + (double)s->bbox_max[a]);
		fwd[a] = -presets[k].dir[a];
	}
	cross3(fwd, presets[k].up, right);
	norm3(right);
	cross3(right, fwd, up);
	double tan_v = tan(fov_deg * M_PI / 360.0);
	double tan_h = tan_v * (double)width / (double)height;
	double dist = 0;
	for (int corner = 0; corner < 8; corner++) {
		double v[3];
		for (int a = 0; a < 3; a++)
			v[a] = (corner >> a & 1 ? (double)s->bbox_max[a] :
				(double)s->bbox_min[a]) - centre[a];
		double x = fabs(dot3(v, right)), y = fabs(dot3(v, up));
		double z = dot3(v, presets[k].dir);
		double need = z + (x / tan_h > y / tan_v ? x / tan_h : y / tan_v);
		if (need > dist) dist = need;
	}
	dist *= 1.08;
	if (!(dist > 0)) dist = s->voxel_size * (double)(1u << s->levels);
	for (int a = 0; a < 3; a++) {
		c->target[a] = centre[a];
		c->eye[a] = centre[a] + dist * presets[k].dir[a];
		c->up[a] = presets[k].up[a];
	}
	c->fov_deg = fov_deg;
	return VD_OK;
}

static int json_vec3(json_t *root, const char *key, double v[3], int need)
{
	json_t *a = json_object_get(root, key);
	if (!a) return need ? vd_fail(VD_ERR_ARG, "no \"%s\"", key) : VD_OK;
	if (!json_is_array(a) || json_array_size(a) != 3)
		return vd_fail(VD_ERR_ARG, "\"%s\" is not [x, y, z]", key);
	for (int i = 0; i < 3; i++) {
		json_t *x = json_array_get(a, (size_t)i);
		if (!json_is_number(x))
			return vd_fail(VD_ERR_ARG, "\"%s\" is not [x, y, z]", key);
		v[i] = json_number_value(x);
	}
	return VD_OK;
}

static int json_side(json_t *root, const char *key, int *out)
{
	json_t *x = json_object_get(root, key);
	if (!x) return VD_OK;
	if (!json_is_integer(x) || json_integer_value(x) < 1 ||
	    json_integer_value(x) > VD_RENDER_MAX_SIDE)
		return vd_fail(VD_ERR_ARG, "\"%s\" is not a number of pixels "
			       "in 1..%d", key, VD_RENDER_MAX_SIDE);
	*out = (int)json_integer_value(x);
	return VD_OK;
}

int vd_camera_read(const char *path, struct vd_camera *c, int *width,
		   int *height)
{
	json_error_t jerr;
	json_t *root = json_load_file(path, JSON_REJECT_DUPLICATES, &jerr);
	if (!root) {
		struct stat st;
		if (access(path, R_OK) != 0)
			return vd_fail(VD_ERR_IO, "%s", strerror(errno));
		if (stat(path, &st) == 0 && S_ISDIR(st.st_mode))
			return vd_fail(VD_ERR_IO, "%s", strerror(EISDIR));
		return vd_fail(VD_ERR_ARG, "line %d: %s", jerr.line, jerr.text);
	}
	struct vd_camera k = {.up = {0, 1, 0}, .fov_deg = 40};
	int w = *width, h = *height;
	int err = json_is_object(root) ? VD_OK :
		  vd_fail(VD_ERR_ARG, "not a JSON object");
	if (!err) err = json_vec3(root, "eye", k.eye, 1);
	if (!err) err = json_vec3(root, "target", k.target, 1);
	if (!err) err = json_vec3(root, "up", k.up, 0);
	json_t *fov = err ? NULL : json_object_get(root, "fov");
	if (fov && !json_is_number(fov))
		err = vd_fail(VD_ERR_ARG, "\"fov\" is not a number");
	if (fov && !err) k.fov_deg = json_number_value(fov);
	if (!err) err = json_side(root, "width", &w);
	if (!err) err = json_side(root, "height", &h);
	if (!err) err = vd_camera_check(&k);
	json_decref(root);
	if (err) return err;
	*c = k;
	*width = w;
	*height = h;
	return VD_OK;
}

/* The orthonormal frame of a checked camera and the tangent of half the
 * vertical field of view. */
struct frame {
	double eye[3], fwd[3], right[3], up[3];
	double tan_half, aspect;
	int width, height;
};

static void camera_frame(const struct vd_camera *c, int width, int height,
			 struct frame *f)
{
	for (int a = 0; a < 3; a++) {
		f->eye[a] = c->eye[a];
		f->fwd[a] = c->target[a] - c->eye[a];
	}
	norm3(f->fwd);
	cross3(f->fwd, c->up, f->right);
	norm3(f->right);
	cross3(f->right, f->fwd, f->up);
	f->tan_half = tan(c->fov_deg * M_PI / 360.0);
	f->aspect = (double)width / (double)height;
	f->width = width;
	f->height = height;
}

/* Unit world direction through the centre of pixel (x, y). */
static void pixel_dir(const struct frame *f, int x, int y, double *d)
{
	double u = (2.0 * (x + 0.5) / f->width - 1.0) * f->tan_half * f->aspect;
	double v = (1.0 - 2.0 * (y + 0.5) / f->height) * f->tan_half;
	for (int a = 0; a < 3; a++)
		d[a] = f->fwd[a] + u * f->right[a] + v * f->up[a];
	norm3(d);
}

/* ------------------------------------------------------------- images */

struct render_ctx {
	const struct vd_render_scene *s;
	const struct vd_render_opts *o;
	struct frame f;
	struct vd_image *img;
	double lod_k;          /* vd_ray.lod for primary and shadow rays */
	uint64_t *shadow_rays; /* per row */
	const struct vd_voxcount *counts; /* with o->colours: voxel indices */
	float srgb_to_linear[256];
};

static void primary_row(void *ctx, size_t row, int worker)
{
	(void)worker;
	struct render_ctx *c = ctx;
	const struct vd_render_scene *s = c->s;
	struct vd_image *img = c->img;
	int y = (int)row;
	double inv_vs = 1.0 / s->voxel_size;
	for (int x = 0; x < img->width; x++) {
		size_t i = (size_t)y * img->width + x;
		double d[3];
		pixel_dir(&c->f, x, y, d);
		struct vd_ray r;
		for (int a = 0; a < 3; a++) {
			r.o[a] = (c->f.eye[a] - s->origin[a]) * inv_vs;
			r.d[a] = d[a] * inv_vs;
		}
		r.tmin = 0;
		r.tmax = INFINITY;
		r.lod = c->lod_k;
		struct vd_hit *h = &img->hits[i];
		int hit = vd_render_trace(s, &r, h);
		if (c->o->diff) {
			/* the first voxel of the union is the nearer of the two
			 * first hits; the voxels along a ray come in one order
			 * whatever the scene, so when the two hits are not one
			 * voxel, the nearer is not set in the other scene (it
			 * would have been hit there first) */
			struct vd_hit h2;
			int hit2 = vd_render_trace(c->o->diff, &r, &h2);
			int same = hit && hit2 && h->level == h2.level &&
				   !memcmp(h->cell, h2.cell, sizeof h->cell);
			if (hit2 && (!hit || (!same && h2.t < h->t)))
				*h = h2;
			img->differs[i] = (hit || hit2) && !same;
			hit |= hit2;
		}
		if (hit) {
			img->depth[i] = (float)h->t;
		} else {
			memset(h, 0, sizeof *h);
			h->level = -1;
			img->depth[i] = INFINITY;
		}
	}
}

/* World position of the hit in pixel i (direction d). */
static void hit_point(const struct render_ctx *c, size_t i, const double *d,
		      double *p)
{
	double t = c->img->hits[i].t;
	for (int a = 0; a < 3; a++) p[a] = c->f.eye[a] + t * d[a];
}

/* Normal from the depth buffer: the hit points of the horizontal and the
 * vertical neighbour on the same surface (the one nearer in depth, when
 * within a few cells of it), crossed. Returns 0 when a side has none. */
static int depth_normal(const struct render_ctx *c, int x, int y,
			const double *p, double *n)
{
	const struct vd_image *img = c->img;
	size_t i = (size_t)y * img->width + x;
	const struct vd_hit *h = &img->hits[i];
	double cell = c->s->voxel_size *
		      (double)(1u << (c->s->levels - h->level));
	double pix = h->t * 2.0 * c->f.tan_half / c->f.height;
	double limit = 4.0 * (cell > pix ? cell : pix);
	double dv[2][3];
	for (int k = 0; k < 2; k++) {
		int best = 0;
		double bestdiff = INFINITY, q[3];
		for (int sgn = -1; sgn <= 1; sgn += 2) {
			int nx = x + (k == 0 ? sgn : 0), ny = y + (k == 1 ? sgn : 0);
			if (nx < 0 || ny < 0 || nx >= img->width || ny >= img->height)
				continue;
			size_t j = (size_t)ny * img->width + nx;
			if (img->hits[j].level < 0) continue;
			double diff = fabs(img->hits[j].t - h->t);
			if (diff < bestdiff) {
				bestdiff = diff;
				best = sgn;
			}
		}
		if (!best || bestdiff > limit) return 0;
		int nx = x + (k == 0 ? best : 0), ny = y + (k == 1 ? best : 0);
		double d[3];
		pixel_dir(&c->f, nx, ny, d);
		hit_point(c, (size_t)ny * img->width + nx, d, q);
		for (int a = 0; a < 3; a++) dv[k][a] = best * (q[a] - p[a]);
	}
	cross3(dv[0], dv[1], n);
	return norm3(n) > 0;
}

static uint8_t to_srgb8(double v)
{
	if (!(v > 0)) v = 0;
	if (v > 1) v = 1;
	return (uint8_t)lrint(255.0 * pow(v, 1.0 / 2.2));
}

static void shade_row(void *ctx, size_t row, int worker)
{
	(void)worker;
	struct render_ctx *c = ctx;
	const struct vd_render_scene *s = c->s;
	struct vd_image *img = c->img;
	int y = (int)row;
	double inv_vs = 1.0 / s->voxel_size;
	uint64_t shadow_rays = 0;
	/* the row's voxel colours first, looked up all at once (a packed
	 * file's lookups then overlap their cache misses): at[x] the
	 * pixel's place in index[] and rgb[], -1 for none (or, when the
	 * scratch cannot be had, looked up one by one below) */
	int32_t *at = NULL;
	uint64_t *index = NULL;
	uint8_t *rgb_row = NULL;
	if (c->counts) {
		at = malloc((size_t)img->width * sizeof *at);
		index = malloc((size_t)img->width * sizeof *index);
		rgb_row = malloc(3 * (size_t)img->width);
		if (!at || !index || !rgb_row) {
			free(at);
			free(index);
			free(rgb_row);
			at = NULL;
			index = NULL;
			rgb_row = NULL;
		}
	}
	if (at) {
		size_t m = 0;
		for (int x = 0; x < img->width; x++) {
			size_t i = (size_t)y * img->width + x;
			const struct vd_hit *h = &img->hits[i];
			at[x] = -1;
			if (h->level >= 0 && !(img->differs && img->differs[i]) &&
			    vd_voxcount_index(c->counts, h->level, h->cell[0],
					      h->cell[1], h->cell[2], &index[m]))
				at[x] = (int32_t)m++;
		}
		vd_colour_source_get_many(c->o->colours, index, m, rgb_row);
	}
	for (int x = 0; x < img->width; x++) {
		size_t i = (size_t)y * img->width + x;
		uint8_t *px = img->rgb + 3 * i;
		const struct vd_hit *h = &img->hits[i];
		if (h->level < 0) { /* sky: a soft vertical gradient */
			double v = (double)y / (img->height > 1 ? img->height - 1 : 1);
			px[0] = (uint8_t)lrint(160 + 70 * v);
			px[1] = (uint8_t)lrint(178 + 57 * v);
			px[2] = (uint8_t)lrint(204 + 38 * v);
			continue;
		}
		double d[3], p[3], n[3], face[3] = {0, 0, 0};
		pixel_dir(&c->f, x, y, d);
		hit_point(c, i, d, p);
		if (h->axis >= 0) face[h->axis] = d[h->axis] > 0 ? -1 : 1;
		else for (int a = 0; a < 3; a++) face[a] = -d[a];
		if (!depth_normal(c, x, y, p, n))
			memcpy(n, face, sizeof n);
		if (dot3(n, d) > 0)
			for (int a = 0; a < 3; a++) n[a] = -n[a];
		double l[3];
		for (int a = 0; a < 3; a++) l[a] = c->o->light[a] - p[a];
		double ldist = norm3(l);
		double lambert = dot3(n, l);
		/* the hit face's own orientation is not asked: under a smooth
		 * normal it is a random step of the voxel staircase (speckles);
		 * the lifted shadow ray decides */
		double vis = lambert > 0 && h->axis >= 0;
		if (vis > 0 && c->o->shadows) {
			/* from just before the hit along the view ray (a point in
			 * the empty cell the ray came from), lifted off the surface
			 * along the smooth normal by two cells or pixels: the
			 * voxel staircase under a smooth normal would otherwise
			 * shadow itself in speckles */
			double t0 = h->t - 1e-3 * s->voxel_size;
			double cell = s->voxel_size * (double)(1u << (s->levels - h->level));
			double pix = h->t * 2.0 * c->f.tan_half / c->f.height;
			double lift = 2.0 * (cell > pix ? cell : pix);
			struct vd_ray r;
			for (int a = 0; a < 3; a++) {
				r.o[a] = (c->f.eye[a] + t0 * d[a] + lift * n[a] -
					  s->origin[a]) * inv_vs;
				r.d[a] = l[a] * inv_vs;
			}
			r.tmin = 0;
			r.tmax = ldist;
			r.lod = c->lod_k;
			struct vd_hit sh;
			shadow_rays++;
			if (vd_render_trace(s, &r, &sh) ||
			    (c->o->diff && vd_render_trace(c->o->diff, &r, &sh)))
				vis = 0;
		}
		double sky = 0.5 + 0.5 * n[1];
		double light = 0.10 + 0.12 * sky + 0.80 * (lambert > 0 ? lambert : 0) * vis;
		static const double grey[3] = {0.82, 0.76, 0.66},
				    red[3] = {0.90, 0.05, 0.04};
		double albedo[3] = {grey[0], grey[1], grey[2]};
		uint64_t one;
		if (img->differs && img->differs[i]) {
			memcpy(albedo, red, sizeof albedo);
		} else if (at ? at[x] >= 0
			      : c->counts &&
				vd_voxcount_index(c->counts, h->level, h->cell[0],
						  h->cell[1], h->cell[2], &one)) {
			/* a voxel's own colour; an LOD cell's first voxel's */
			uint8_t rgb[3];
			if (at)
				memcpy(rgb, rgb_row + 3 * (size_t)at[x], 3);
			else
				c->o->colours->get(c->o->colours, one, rgb);
			for (int k = 0; k < 3; k++)
				albedo[k] = c->srgb_to_linear[rgb[k]];
		}
		for (int k = 0; k < 3; k++) px[k] = to_srgb8(albedo[k] * light);
	}
	c->shadow_rays[row] = shadow_rays;
	free(at);
	free(index);
	free(rgb_row);
}

void vd_image_release(struct vd_image *img)
{
	free(img->rgb);
	free(img->depth);
	free(img->hits);
	free(img->differs);
	memset(img, 0, sizeof *img);
}

static int check_size(int width, int height)
{
	if (width < 1 || height < 1 || width > VD_RENDER_MAX_SIDE ||
	    height > VD_RENDER_MAX_SIDE ||
	    (uint64_t)width * (uint64_t)height > VD_RENDER_MAX_PIXELS)
		return vd_fail(VD_ERR_ARG, "image size %dx%d outside 1x1 .. "
			       "%dx%d (at most %llu pixels)", width, height,
			       VD_RENDER_MAX_SIDE, VD_RENDER_MAX_SIDE,
			       (unsigned long long)VD_RENDER_MAX_PIXELS);
	return VD_OK;
}

int vd_render_image(const struct vd_render_scene *s,
		    const struct vd_render_opts *o, struct vd_image *img)
{
	memset(img, 0, sizeof *img);
	int err = check_size(o->width, o->height);
	if (!err) err = vd_camera_check(&o->cam);
	if (err) return err;
	for (int a = 0; a < 3; a++)
		if (!isfinite(o->light[a]))
			return vd_fail(VD_ERR_ARG, "light position is not finite");
	if (!(o->lod_pixels >= 0) || !isfinite(o->lod_pixels))
		return vd_fail(VD_ERR_ARG, "LOD %g pixels is not a number >= 0",
			       o->lod_pixels);
	if (o->diff && o->lod_pixels > 0)
		return vd_fail(VD_ERR_ARG, "the differences of two scenes are "
			       "drawn exactly only (no LOD)");
	if (o->diff && (o->diff->levels != s->levels ||
			o->diff->voxel_size != s->voxel_size ||
			memcmp(o->diff->origin, s->origin, sizeof s->origin)))
		return vd_fail(VD_ERR_MISMATCH, "the two scenes are not on one "
			       "grid (2^%d and 2^%d, or another origin or voxel "
			       "size)", s->levels, o->diff->levels);
	size_t n = (size_t)o->width * (size_t)o->height;
	img->width = o->width;
	img->height = o->height;
	img->rgb = malloc(3 * n);
	img->depth = malloc(n * sizeof *img->depth);
	img->hits = malloc(n * sizeof *img->hits);
	uint64_t *rows = calloc((size_t)o->height, sizeof *rows);
	if (o->diff)
		img->differs = calloc(n, 1);
	if (!img->rgb || !img->depth || !img->hits || !rows ||
	    (o->diff && !img->differs)) {
		free(rows);
		return NOMEM();
	}
	struct render_ctx c = {.s = s, .o = o, .img = img, .shadow_rays = rows};
	struct vd_voxcount counts = {0};
	if (o->colours) {
		err = s->dag ? vd_voxcount_from_dag(&counts, s->dag)
			     : vd_voxcount_from_enc(&counts, s->enc);
		if (!err && counts.voxels != o->colours->voxels)
			err = vd_fail(VD_ERR_MISMATCH, "%llu colours for a scene "
				      "of %llu voxels",
				      (unsigned long long)o->colours->voxels,
				      (unsigned long long)counts.voxels);
		if (err) {
			vd_voxcount_release(&counts);
			free(rows);
			return err;
		}
		c.counts = &counts;
		/* the inverse of to_srgb8()'s curve */
		for (int v = 0; v < 256; v++)
			c.srgb_to_linear[v] = (float)pow(v / 255.0, 2.2);
	}
	camera_frame(&o->cam, o->width, o->height, &c.f);
	/* a node of side S voxels at distance t spans S * voxel_size /
	 * (t * pixel angle) pixels */
	c.lod_k = o->lod_pixels * 2.0 * c.f.tan_half / o->height / s->voxel_size;
	double t0 = vd_seconds();
	err = vd_parallel_for((size_t)o->height, o->threads, primary_row, &c);
	double t1 = vd_seconds();
	if (!err) err = vd_parallel_for((size_t)o->height, o->threads, shade_row, &c);
	double t2 = vd_seconds();
	img->primary_rays = n;
	for (int y = 0; y < o->height; y++) img->shadow_rays += rows[y];
	for (size_t i = 0; img->differs && i < n; i++)
		img->differing_pixels += img->differs[i];
	img->seconds_primary = t1 - t0;
	img->seconds_shade = t2 - t1;
	free(rows);
	vd_voxcount_release(&counts);
	return err;
}

/* -------------------------------------------------------------- output */

/* Writes `path` through write(FILE *, ctx) and publishes it
 * (vd_atomic_*: fsync, rename, directory fsync) when complete. */
static int write_atomic(const char *path, int (*write)(FILE *f, void *ctx),
			void *ctx)
{
	struct vd_atomic a;
	int err = vd_atomic_open(&a, path);
	if (err)
		return err;
	vd_error_clear();
	if (write(a.f, ctx) != 0) {
		int e1 = errno;
		err = vd_fail(VD_ERR_IO, "cannot write '%s': %s", a.tmp,
			      *vd_error_detail() ? vd_error_detail() :
			      strerror(e1));
		vd_atomic_abort(&a);
		return err;
	}
	return vd_atomic_commit(&a);
}

struct png_job {
	int width, height, depth16;
	const uint8_t *rows; /* width * (depth16 ? 2 : 3) bytes per row */
};

static void png_error_fn(png_structp p, png_const_charp msg)
{
	vd_fail(VD_ERR_IO, "libpng: %s", msg);
	png_longjmp(p, 1);
}

static void png_warning_fn(png_structp p, png_const_charp msg)
{
	(void)p;
	(void)msg;
}

/* libpng's own writer ignores why fwrite failed ("Write Error"); this one
 * names the cause, e.g. a full disk. */
static void png_write_fn(png_structp p, png_bytep data, size_t n)
{
	FILE *f = png_get_io_ptr(p);
	if (fwrite(data, 1, n, f) != n)
		png_error(p, strerror(errno));
}

static void png_flush_fn(png_structp p)
{
	FILE *f = png_get_io_ptr(p);
	if (fflush(f) != 0)
		png_error(p, strerror(errno));
}

static int write_png(FILE *f, void *ctx)
{
	struct png_job *j = ctx;
	png_structp p = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL,
						png_error_fn, png_warning_fn);
	if (!p) return vd_fail(VD_ERR_NOMEM, "libpng: out of memory");
	png_infop info = png_create_info_struct(p);
	if (!info) {
		png_destroy_write_struct(&p, NULL);
		return vd_fail(VD_ERR_NOMEM, "libpng: out of memory");
	}
	if (setjmp(png_jmpbuf(p))) {
		png_destroy_write_struct(&p, &info);
		return VD_ERR_IO;
	}
	png_set_write_fn(p, f, png_write_fn, png_flush_fn);
	png_set_IHDR(p, info, (png_uint_32)j->width, (png_uint_32)j->height,
		     j->depth16 ? 16 : 8,
		     j->depth16 ? PNG_COLOR_TYPE_GRAY : PNG_COLOR_TYPE_RGB,
		     PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
		     PNG_FILTER_TYPE_DEFAULT);
	png_write_info(p, info);
	size_t stride = (size_t)j->width * (j->depth16 ? 2 : 3);
	for (int y = 0; y < j->height; y++)
		png_write_row(p, (png_const_bytep)(j->rows + (size_t)y * stride));
	png_write_end(p, info);
	png_destroy_write_struct(&p, &info);
	return 0;
}

int vd_image_write_png(const struct vd_image *img, const char *path)
{
	struct png_job j = {img->width, img->height, 0, img->rgb};
	return write_atomic(path, write_png, &j);
}

struct bytes_job {
	const uint8_t *b;
	size_t n;
};

static int write_bytes(FILE *f, void *ctx)
{
	struct bytes_job *j = ctx;
	return fwrite(j->b, 1, j->n, f) == j->n ? 0 : -1;
}

static int has_suffix(const char *s, const char *suffix)
{
	size_t a = strlen(s), b = strlen(suffix);
	return a >= b && !strcmp(s + a - b, suffix);
}

int vd_image_write_depth(const struct vd_image *img, const char *path)
{
	size_t n = (size_t)img->width * img->height;
	if (has_suffix(path, ".png")) {
		double lo = INFINITY, hi = -INFINITY;
		for (size_t i = 0; i < n; i++)
			if (img->hits[i].level >= 0) {
				if (img->depth[i] < lo) lo = img->depth[i];
				if (img->depth[i] > hi) hi = img->depth[i];
			}
		uint8_t *rows = malloc(2 * n);
		if (!rows) return NOMEM();
		for (size_t i = 0; i < n; i++) {
			unsigned v = 0;
			if (img->hits[i].level >= 0)
				v = hi > lo ? 1 + (unsigned)lrint((img->depth[i] - lo) /
								  (hi - lo) * 65534.0) : 1;
			rows[2 * i] = (uint8_t)(v >> 8); /* PNG is big-endian */
			rows[2 * i + 1] = (uint8_t)v;
		}
		struct png_job j = {img->width, img->height, 1, rows};
		int err = write_atomic(path, write_png, &j);
		free(rows);
		return err;
	}
	if (!has_suffix(path, ".pfm"))
		return vd_fail(VD_ERR_ARG, "depth output '%s' needs the extension "
			       ".pfm (float) or .png (16-bit)", path);
	char head[64];
	int hl = snprintf(head, sizeof head, "Pf\n%d %d\n-1.0\n", img->width,
			  img->height);
	uint8_t *b = malloc((size_t)hl + 4 * n);
	if (!b) return NOMEM();
	memcpy(b, head, (size_t)hl);
	uint8_t *q = b + hl;
	for (int y = img->height - 1; y >= 0; y--) /* PFM: bottom row first */
		for (int x = 0; x < img->width; x++) {
			uint32_t u;
			memcpy(&u, &img->depth[(size_t)y * img->width + x], 4);
			le_put32(q, u);
			q += 4;
		}
	struct bytes_job j = {b, (size_t)hl + 4 * n};
	int err = write_atomic(path, write_bytes, &j);
	free(b);
	return err;
}

int vd_image_write_ids(const struct vd_image *img, const char *path)
{
	size_t n = (size_t)img->width * img->height;
	uint8_t *b = malloc(16 + 16 * n);
	if (!b) return NOMEM();
	static const uint8_t magic[4] = {0x89, 'V', 'I', 'D'};
	memcpy(b, magic, 4);
	le_put32(b + 4, 1);
	le_put32(b + 8, (uint32_t)img->width);
	le_put32(b + 12, (uint32_t)img->height);
	for (size_t i = 0; i < n; i++) {
		const struct vd_hit *h = &img->hits[i];
		uint8_t *q = b + 16 + 16 * i;
		int miss = h->level < 0;
		for (int a = 0; a < 3; a++)
			le_put32(q + 4 * a, miss ? 0xffffffffu : h->cell[a]);
		le_put32(q + 12, miss ? 0xffffffffu : (uint32_t)h->level);
	}
	struct bytes_job j = {b, 16 + 16 * n};
	int err = write_atomic(path, write_bytes, &j);
	free(b);
	return err;
}

/* ---------------------------------------------------------- the stage */

static int reword(int err, const char *what, const char *subject)
{
	char d[512];
	snprintf(d, sizeof d, "%s", vd_error_detail());
	return vd_fail(err, "%s '%s': %s%s%s", what, subject, vd_strerror(err),
		       *d ? ": " : "", d);
}

/* What the input file holds. */
struct input {
	struct vd_enc enc;
	struct vd_dag dag;
	int is_dag;
	struct vd_render_scene scene;
	char what[32];      /* "ssvdag encoding", "dag chunk" */
};

static void input_release(struct input *in)
{
	vd_enc_release(&in->enc);
	vd_dag_release(&in->dag);
}

static int load_input(struct input *in, const char *path, int check_manifest)
{
	memset(in, 0, sizeof *in);
	FILE *f = fopen(path, "rb");
	if (!f)
		return vd_fail(VD_ERR_IO, "cannot open '%s': %s", path,
			       strerror(errno));
	fclose(f);
	struct vd_chunk_header h;
	int err = vd_chunk_read_header(path, &h);
	if (err == VD_ERR_NOT_CHUNK) {
		/* not a chunk file: one of the encodings, by extension */
		int format = vd_enc_format_from_path(path);
		if (format < 0)
			return vd_fail(VD_ERR_UNSUPPORTED, "cannot read '%s': "
				       "unknown format: neither a chunk file nor "
				       "an encoding (.svdag, .ussvdag, .esvdag, "
				       ".ssvdag, .ssvdag48)", path);
		/* the bytes are SymVox's: their checksum is in the manifest
		 * beside them, checked before a picture is made of them */
		err = check_manifest ? vd_manifest_check_file(path) : VD_OK;
		if (!err) err = vd_enc_load(&in->enc, path, format);
		if (!err) err = vd_render_scene_from_enc(&in->scene, &in->enc);
		if (err) return reword(err, "cannot read", path);
		snprintf(in->what, sizeof in->what, "%s encoding",
			 vd_enc_format_name(format));
		return VD_OK;
	}
	if (!err && h.kind != VD_KIND_DAG && h.kind != VD_KIND_SSVDAG)
		err = vd_fail(VD_ERR_WRONG_KIND, "a %s chunk; render reads DAG and "
			      "SSVDAG root chunks and the encodings",
			      vd_chunk_kind_name(h.kind));
	if (!err && h.chunk_level != 0)
		err = vd_fail(VD_ERR_ARG, "not a root chunk (chunk level %u): "
			      "merge the chunks up to level 0 first", h.chunk_level);
	if (!err) err = vd_dag_load(&in->dag, &h, path, VD_KIND_ANY);
	if (!err) err = vd_render_scene_from_dag(&in->scene, &in->dag,
						 &h.transform);
	if (err) return reword(err, "cannot read", path);
	in->is_dag = 1;
	snprintf(in->what, sizeof in->what, "%s chunk",
		 vd_chunk_kind_name(h.kind));
	return VD_OK;
}

/* The statistics beside the image, as every stage leaves them beside its
 * output: the runner's report reads render's time and memory there, also
 * when it is written again after the run (voxdag report). */
static int write_stats(const char *path, const struct vd_render_opts *o,
		       const struct input *in, const struct vd_image *img,
		       int threads, double t0)
{
	struct vd_json *j;
	int err = vd_json_open(&j, path);
	if (err)
		return err;
	vd_json_str(j, "tool", "render");
	vd_json_str(j, "version", VD_VERSION_STRING);
	vd_json_str(j, "input", in->what);
	vd_json_u64(j, "levels", (uint64_t)in->scene.levels);
	vd_json_u64(j, "width", (uint64_t)o->width);
	vd_json_u64(j, "height", (uint64_t)o->height);
	vd_json_u64(j, "primary_rays", img->primary_rays);
	vd_json_u64(j, "shadow_rays", img->shadow_rays);
	vd_json_f64(j, "seconds_primary", img->seconds_primary);
	vd_json_f64(j, "seconds_shade", img->seconds_shade);
	vd_json_f64(j, "seconds_total", vd_seconds() - t0);
	vd_json_u64(j, "peak_rss_bytes", vd_peak_rss_bytes());
	vd_json_f64(j, "process_cpu_seconds", vd_cpu_seconds());
	vd_json_u64(j, "threads", (uint64_t)threads);
	return vd_json_close(j);
}

/* The image and OUT.png.stats.json, replacing the previous pair together
 * (vd_publish_pair: a full disk leaves the old pair whole). */
static int write_image(const struct vd_render_job *job,
		       const struct vd_render_opts *o, const struct input *in,
		       const struct vd_image *img, int threads, double t0)
{
	char sp[4096], staged[4096], staged_sp[4096];
	int err = snprintf(sp, sizeof sp, "%s.stats.json", job->output) <
		  (int)sizeof sp ? VD_OK :
		  vd_fail(VD_ERR_RANGE, "the name is too long");
	if (!err) err = vd_stage_name(job->output, staged, sizeof staged);
	if (!err) err = vd_stage_name(sp, staged_sp, sizeof staged_sp);
	if (!err && !(err = vd_image_write_png(img, staged))) {
		err = write_stats(staged_sp, o, in, img, threads, t0);
		if (!err)
			err = vd_publish_pair(staged, job->output, staged_sp, sp);
		if (err)
			unlink(staged);
	}
	return err ? reword(err, "cannot write", job->output) : VD_OK;
}

int vd_render_run(const struct vd_render_job *job)
{
	const double t0 = vd_seconds();
	struct vd_render_opts o = job->opts;
	int err = check_size(o.width, o.height);
	if (err) return reword(err, "cannot render", job->input);
	struct input in;
	err = load_input(&in, job->input, !job->no_verify);
	if (err) {
		input_release(&in);
		return err;
	}
	const struct vd_render_scene *s = &in.scene;
	struct input other;
	memset(&other, 0, sizeof other);
	if (job->diff_input) {
		err = load_input(&other, job->diff_input, !job->no_verify);
		if (err) {
			input_release(&other);
			input_release(&in);
			return err;
		}
		o.diff = &other.scene;
	}
	if (!job->has_eye) {
		err = vd_camera_preset(&o.cam, s, job->preset ? job->preset : "front",
				       o.cam.fov_deg, o.width, o.height);
	} else if (!(o.cam.up[0] || o.cam.up[1] || o.cam.up[2])) {
		/* +Y up, unless looking along Y */
		double f[3];
		for (int a = 0; a < 3; a++) f[a] = o.cam.target[a] - o.cam.eye[a];
		double n = sqrt(dot3(f, f));
		o.cam.up[1] = 1;
		if (n > 0 && fabs(f[1]) > 0.999 * n) {
			o.cam.up[1] = 0;
			o.cam.up[2] = -1;
		}
	}
	if (!err) err = vd_camera_check(&o.cam);
	if (err) {
		input_release(&other);
		input_release(&in);
		return reword(err, "cannot render", job->input);
	}
	if (!job->has_light) {
		/* above, left of and in front of the scene, as seen by the eye */
		struct frame f;
		camera_frame(&o.cam, o.width, o.height, &f);
		double dist = 0, dir[3];
		for (int a = 0; a < 3; a++) {
			double e = o.cam.eye[a] - o.cam.target[a];
			dist += e * e;
			dir[a] = -0.8 * f.right[a] + 1.0 * f.up[a] - 0.45 * f.fwd[a];
		}
		norm3(dir);
		for (int a = 0; a < 3; a++)
			o.light[a] = o.cam.target[a] + 2.0 * sqrt(dist) * dir[a];
	}
	struct vd_colour_source colours = {0};
	if (job->colours) {
		err = vd_colour_source_open(&colours, job->colours);
		if (!err && colours.levels != s->levels)
			err = vd_fail(VD_ERR_MISMATCH, "colours made at depth %d, "
				      "the scene has depth %d", colours.levels,
				      s->levels);
		if (err) {
			vd_colour_source_release(&colours);
			input_release(&in);
			return reword(err, "cannot read colours", job->colours);
		}
		o.colours = &colours;
	}
	struct vd_image img;
	err = vd_render_image(s, &o, &img);
	vd_colour_source_release(&colours);
	if (err) err = reword(err, "cannot render", job->input);
	const int threads = o.threads > 0 ? o.threads : vd_hardware_threads();
	if (!err) err = write_image(job, &o, &in, &img, threads, t0);
	if (!err && job->depth_path) {
		err = vd_image_write_depth(&img, job->depth_path);
		if (err) err = reword(err, "cannot write", job->depth_path);
	}
	if (!err && job->ids_path) {
		err = vd_image_write_ids(&img, job->ids_path);
		if (err) err = reword(err, "cannot write", job->ids_path);
	}
	if (!err && !job->quiet) {
		double sec = img.seconds_primary + img.seconds_shade;
		uint64_t rays = img.primary_rays + img.shadow_rays;
		fprintf(stderr, "%s: %dx%d of the %s (2^%d) in %.3f s: %" PRIu64
			" primary rays (%.3f s, %.2f Mrays/s), %" PRIu64 " shadow rays "
			"(%.3f s with shading, %.2f Mrays/s), %d threads; wrote '%s'\n",
			job->tool, o.width, o.height, in.what, s->levels, sec,
			img.primary_rays, img.seconds_primary,
			img.primary_rays / (img.seconds_primary > 0 ? img.seconds_primary : 1e-9) / 1e6,
			img.shadow_rays, img.seconds_shade,
			img.shadow_rays / (img.seconds_shade > 0 ? img.seconds_shade : 1e-9) / 1e6,
			threads, job->output);
		if (job->diff_input)
			fprintf(stderr, "%s: %" PRIu64 " pixels show voxels set in "
				"only one of '%s' and '%s' (red)\n", job->tool,
				img.differing_pixels, job->input,
				job->diff_input);
		(void)rays;
	}
	vd_image_release(&img);
	input_release(&other);
	input_release(&in);
	return err;
}
