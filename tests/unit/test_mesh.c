/* test_mesh.c - the mesh readers on fixtures written here, byte by byte,
 * with expected triangles typed in by hand, and on the bundled bunny and
 * the shared scenes (skipped when absent). Run from the repository root. */
#include "check.h"
#include "voxdag.h"

#include <math.h>
#include <stdarg.h>
#include <sys/stat.h>


static const char *dir;

static const char *fixture_path(const char *name)
{
	static char buf[4][600];
	static int k;
	k = (k + 1) % 4;
	snprintf(buf[k], sizeof buf[k], "%s/%s", dir, name);
	return buf[k];
}

static const char *write_bytes(const char *name, const void *data, size_t n)
{
	const char *p = fixture_path(name);
	FILE *f = fopen(p, "wb");
	if (!f || fwrite(data, 1, n, f) != n || fclose(f) != 0) {
		fprintf(stderr, "cannot write %s\n", p);
		exit(2);
	}
	return p;
}

static const char *write_text(const char *name, const char *text)
{
	return write_bytes(name, text, strlen(text));
}

/* A growing byte buffer with explicit-endian writers, so fixtures do not
 * depend on the host's byte order. */
struct bytes {
	unsigned char d[1 << 16];
	size_t n;
};

static void put(struct bytes *b, uint64_t v, int size, int be)
{
	for (int i = 0; i < size; i++)
		b->d[b->n + (be ? size - 1 - i : i)] = (unsigned char)(v >> 8 * i);
	b->n += (size_t)size;
}

static void put_f32(struct bytes *b, float f, int be)
{
	uint32_t u;
	memcpy(&u, &f, 4);
	put(b, u, 4, be);
}

static void put_f64(struct bytes *b, double f, int be)
{
	uint64_t u;
	memcpy(&u, &f, 8);
	put(b, u, 8, be);
}

static void put_str(struct bytes *b, const char *s)
{
	size_t n = strlen(s);
	memcpy(b->d + b->n, s, n);
	b->n += n;
}

/* Reads the whole mesh in chunks of `chunk` triangles into *out (malloc'd,
 * caller frees). Returns the first error of open or read. */
static int read_mesh(const char *path, size_t chunk, struct vd_triangle **out,
		     size_t *count, struct vd_mesh_stats *stats)
{
	struct vd_mesh *m;
	*out = NULL;
	*count = 0;
	int e = vd_mesh_open(&m, path);
	if (e)
		return e;
	struct vd_triangle *buf = malloc(chunk * sizeof *buf);
	size_t cap = 0, n;
	while (!(e = vd_mesh_read(m, buf, chunk, &n)) && n > 0) {
		if (*count + n > cap) {
			cap = (*count + n) * 2;
			*out = realloc(*out, cap * sizeof **out);
		}
		memcpy(*out + *count, buf, n * sizeof *buf);
		*count += n;
	}
	if (stats)
		*stats = *vd_mesh_stats(m);
	free(buf);
	vd_mesh_close(m);
	return e;
}

/* The error code of reading `path` to the end (VD_OK if it reads). */
static int mesh_error(const char *path)
{
	struct vd_triangle *t;
	size_t n;
	int e = read_mesh(path, 7, &t, &n, NULL);
	free(t);
	return e;
}

static int detail_has(const char *s)
{
	if (strstr(vd_error_detail(), s))
		return 1;
	fprintf(stderr, "detail '%s' lacks '%s'\n", vd_error_detail(), s);
	return 0;
}

/* ------------------------------------------------------ the shared mesh
 * Five vertices, a quad 0 1 2 3 and a triangle 1 4 2. Fanning the quad
 * gives (0 1 2) (0 2 3). 0.1 checks that decimal text rounds like the
 * float literal. */
static const float V[5][3] = {
	{0, 0, 0}, {1.5f, 0, 0}, {1.5f, 2.25f, 0.1f}, {0, 2.25f, 0.1f},
	{-0.75f, 1, -3.125f}};
static const int TRI[3][3] = {{0, 1, 2}, {0, 2, 3}, {1, 4, 2}};

static int same_as_reference(const struct vd_triangle *t, size_t n)
{
	if (n != 3) {
		fprintf(stderr, "got %zu triangles, want 3\n", n);
		return 0;
	}
	for (int i = 0; i < 3; i++)
		for (int c = 0; c < 3; c++)
			if (memcmp(t[i].v[c], V[TRI[i][c]], 12)) {
				fprintf(stderr, "triangle %d corner %d: %g %g %g\n",
					i, c, t[i].v[c][0], t[i].v[c][1],
					t[i].v[c][2]);
				return 0;
			}
	return 1;
}

static size_t ply_le_reference(struct bytes *b)
{
	b->n = 0;
	put_str(b, "ply\nformat binary_little_endian 1.0\ncomment test\n"
		   "element vertex 5\nproperty float x\nproperty float y\n"
		   "property float z\nelement face 2\n"
		   "property list uchar int vertex_indices\nend_header\n");
	size_t header = b->n;
	for (int i = 0; i < 5; i++)
		for (int a = 0; a < 3; a++)
			put_f32(b, V[i][a], 0);
	put(b, 4, 1, 0);
	for (int i = 0; i < 4; i++)
		put(b, (uint64_t)i, 4, 0);
	put(b, 3, 1, 0);
	put(b, 1, 4, 0);
	put(b, 4, 4, 0);
	put(b, 2, 4, 0);
	return header;
}

/* Big-endian, with every kind of thing a reader must skip: a list-bearing
 * element before the vertices, extra scalar and list properties around
 * x y z, doubles, int8-style type names, CRLF header lines, extra face
 * properties, an element after the faces. */
static void ply_be_reference(struct bytes *b)
{
	b->n = 0;
	put_str(b, "ply\r\nformat binary_big_endian 1.0\r\n"
		   "obj_info made by hand\r\n"
		   "element material 2\r\nproperty list uchar float diffuse\r\n"
		   "property uchar id\r\n"
		   "element vertex 5\r\nproperty float32 nx\r\n"
		   "property double x\r\nproperty int16 confidence\r\n"
		   "property float64 y\r\nproperty list uint8 int32 texidx\r\n"
		   "property double z\r\nproperty uchar red\r\n"
		   "property uchar green\r\nproperty uchar blue\r\n"
		   "property uchar alpha\r\n"
		   "element face 2\r\nproperty uchar flags\r\n"
		   "property list uint16 uint32 vertex_index\r\n"
		   "property float quality\r\n"
		   "element edge 1\r\nproperty int vertex1\r\n"
		   "property list uchar int more\r\nend_header\r\n");
	put(b, 3, 1, 1); /* material 0: 3 floats, id */
	for (int i = 0; i < 3; i++)
		put_f32(b, 0.5f, 1);
	put(b, 7, 1, 1);
	put(b, 0, 1, 1); /* material 1: empty list */
	put(b, 8, 1, 1);
	for (int i = 0; i < 5; i++) {
		put_f32(b, 1.0f, 1);
		put_f64(b, V[i][0], 1);
		put(b, (uint64_t)-5, 2, 1);
		put_f64(b, V[i][1], 1);
		put(b, (uint64_t)i, 1, 1); /* texidx list of i items */
		for (int j = 0; j < i; j++)
			put(b, 0xdeadbeef, 4, 1);
		put_f64(b, V[i][2], 1);
		put(b, 0x11223344, 4, 1);
	}
	put(b, 9, 1, 1);
	put(b, 4, 2, 1);
	for (int i = 0; i < 4; i++)
		put(b, (uint64_t)i, 4, 1);
	put_f32(b, 0.25f, 1);
	put(b, 9, 1, 1);
	put(b, 3, 2, 1);
	put(b, 1, 4, 1);
	put(b, 4, 4, 1);
	put(b, 2, 4, 1);
	put_f32(b, 0.25f, 1);
	put(b, 1, 4, 1); /* the edge */
	put(b, 2, 1, 1);
	put(b, 0, 4, 1);
	put(b, 1, 4, 1);
}

static const char *const ply_ascii_reference =
	"ply\r\nformat ascii 1.0\r\ncomment hand written\r\n"
	"element vertex 5\r\nproperty float nx\r\nproperty float ny\r\n"
	"property float nz\r\nproperty float x\r\nproperty float y\r\n"
	"property float z\r\nproperty uchar red\r\nproperty uchar green\r\n"
	"property uchar blue\r\nproperty float confidence\r\n"
	"element face 2\r\nproperty list uchar int vertex_indices\r\n"
	"element edge 1\r\nproperty list uchar int vertex_indices\r\n"
	"end_header\r\n"
	"0 0 1 0 0 0 255 0 0 1.0\r\n"
	"0 0 1 1.5 0 0 0 255 0 1e0\r\n"
	"0 0 1 1.5 2.25 0.1 0 0 255 .5\r\n"
	"0 0 1   0\t2.25   0.1 1 2 3 -0.5\r\n"
	"\r\n"
	"0 0 1 -0.75 1.0 -3.125e0 4 5 6 0\r\n"
	"4 0 1 2 3\r\n"
	"3 1 4 2\r\n"
	"2 0 1\r\n";

static const char *const obj_reference =
	"# a comment\r\n"
	"mtllib scene.mtl\r\n"
	"o thing\r\n"
	"v 0 0 0\r\n"
	"v 1.5 0.0 0 1.0\r\n"
	"v 1.5 2.25 0.1 0.5 0.25 1\r\n"
	"v 0 \\\r\n  2.25 0.1\r\n"
	"vt 0 0\n"
	"vn 0 0 1\n"
	"\n"
	"g group\ns 1\nusemtl red\n"
	"f 1/1/1 2/1/1 3/1/1 4/1/1\n"
	"   \t\n"
	"v -0.75 1 -3.125\n"
	"l 1 2\n"
	"p 1\n"
	"f -4//1 -1//1 -3//1";

static size_t stl_bin_reference(struct bytes *b, const char *header)
{
	b->n = 0;
	memset(b->d, ' ', 80);
	memcpy(b->d, header, strlen(header));
	b->n = 80;
	put(b, 3, 4, 0);
	for (int i = 0; i < 3; i++) {
		put_f32(b, 0, 0);
		put_f32(b, 0, 0);
		put_f32(b, 1, 0);
		for (int c = 0; c < 3; c++)
			for (int a = 0; a < 3; a++)
				put_f32(b, V[TRI[i][c]][a], 0);
		put(b, 0, 2, 0);
	}
	return b->n;
}

static const char *const stl_ascii_reference =
	"solid test mesh\n"
	"  facet normal 0 0 1\n"
	"    outer loop\n"
	"      vertex 0 0 0\n"
	"      vertex 1.5 0 0\n"
	"      vertex 1.5 2.25 0.1\n"
	"    endloop\n"
	"  endfacet\r\n"
	"FACET NORMAL 0 0 1\r\n\tOUTER   LOOP\r\n"
	"\tVERTEX 0 0 0\r\n\tVertex 1.5E0 2.25 0.1\r\n\tvertex 0 2.25 0.1\r\n"
	"\tENDLOOP\r\nENDFACET\r\n"
	"facet normal 0 0 0 outer loop vertex 1.5 0 0 vertex -0.75 1 -3.125 "
	"vertex 1.5 2.25 0.1 endloop endfacet\n"
	"endsolid test mesh\n";

static void check_reference(const char *path, const char *format,
			    uint64_t split)
{
	static const size_t chunks[] = {1, 2, 3, 1000};
	for (size_t k = 0; k < sizeof chunks / sizeof *chunks; k++) {
		struct vd_triangle *t;
		struct vd_mesh_stats st;
		size_t n;
		int e = read_mesh(path, chunks[k], &t, &n, &st);
		CHECK_EQ(e, VD_OK);
		if (e)
			fprintf(stderr, "%s: %s\n", path, vd_error_detail());
		CHECK(same_as_reference(t, n));
		CHECK_EQ(st.triangles_read, 3);
		CHECK_EQ(st.polygons_split, split);
		free(t);
	}
	struct vd_mesh *m;
	if (vd_mesh_open(&m, path) == VD_OK) {
		CHECK(!strcmp(vd_mesh_format(m), format));
		vd_mesh_close(m);
	}
}

static void test_ply_binary_le(void)
{
	struct bytes b;
	ply_le_reference(&b);
	check_reference(write_bytes("le.ply", b.d, b.n), "ply-binary-le", 1);
}

static void test_ply_binary_be(void)
{
	static struct bytes b;
	ply_be_reference(&b);
	check_reference(write_bytes("be.ply", b.d, b.n), "ply-binary-be", 1);
}

static void test_ply_ascii(void)
{
	const char *p = write_text("ascii.ply", ply_ascii_reference);
	check_reference(p, "ply-ascii", 1);
	struct vd_mesh_stats st;
	struct vd_triangle *t;
	size_t n;
	CHECK_EQ(read_mesh(p, 10, &t, &n, &st), VD_OK);
	CHECK_EQ(st.vertices, 5);
	free(t);
}

static void test_obj(void)
{
	const char *p = write_text("ref.obj", obj_reference);
	check_reference(p, "obj", 1);
	/* Detected by content without the extension. */
	check_reference(write_text("ref.txt", obj_reference), "obj", 1);
}

static void test_stl_binary(void)
{
	struct bytes b;
	stl_bin_reference(&b, "binary test");
	check_reference(write_bytes("ref.stl", b.d, b.n), "stl-binary", 0);
	/* Many exporters start binary headers with "solid": the size rule
	 * must win. */
	stl_bin_reference(&b, "solid fooled you");
	check_reference(write_bytes("solid.dat", b.d, b.n), "stl-binary", 0);
}

static void test_stl_ascii(void)
{
	check_reference(write_text("ref-ascii.stl", stl_ascii_reference),
			"stl-ascii", 0);
	/* No endsolid and no final newline loses nothing. */
	char text[2048];
	snprintf(text, sizeof text, "%s", stl_ascii_reference);
	*strstr(text, "endsolid") = 0;
	text[strlen(text) - 1] = 0;
	check_reference(write_text("noend.stl", text), "stl-ascii", 0);
}

/* Integer coordinate types convert exactly. */
static void test_ply_integer_coordinates(void)
{
	struct bytes b = {.n = 0};
	put_str(&b, "ply\nformat binary_little_endian 1.0\nelement vertex 3\n"
		    "property int x\nproperty char y\nproperty ushort z\n"
		    "element face 1\nproperty list int uint vertex_indices\n"
		    "end_header\n");
	const int xs[3] = {-100000, 7, 0}, ys[3] = {-128, 127, 1},
		  zs[3] = {65535, 0, 300};
	for (int i = 0; i < 3; i++) {
		put(&b, (uint64_t)(int64_t)xs[i], 4, 0);
		put(&b, (uint64_t)(int64_t)ys[i], 1, 0);
		put(&b, (uint64_t)zs[i], 2, 0);
	}
	put(&b, 3, 4, 0);
	put(&b, 2, 4, 0);
	put(&b, 1, 4, 0);
	put(&b, 0, 4, 0);
	struct vd_triangle *t;
	size_t n;
	CHECK_EQ(read_mesh(write_bytes("int.ply", b.d, b.n), 4, &t, &n, NULL),
		 VD_OK);
	CHECK_EQ(n, 1);
	if (n == 1) {
		const float want[3][3] = {{0, 1, 300}, {7, 127, 0},
					  {-100000, -128, 65535}};
		CHECK(!memcmp(t[0].v, want, sizeof want));
	}
	free(t);
}

/* 0, 1 and 2 corners are dropped and counted; many corners fan out. */
static void test_short_and_long_faces(void)
{
	struct bytes b = {.n = 0};
	put_str(&b, "ply\nformat binary_little_endian 1.0\nelement vertex 3\n"
		    "property float x\nproperty float y\nproperty float z\n"
		    "element face 5\nproperty list ushort int vertex_indices\n"
		    "end_header\n");
	for (int i = 0; i < 9; i++)
		put_f32(&b, (float)i, 0);
	put(&b, 0, 2, 0);
	put(&b, 1, 2, 0);
	put(&b, 2, 4, 0);
	put(&b, 2, 2, 0);
	put(&b, 0, 4, 0);
	put(&b, 1, 4, 0);
	put(&b, 1000, 2, 0);
	for (int i = 0; i < 1000; i++)
		put(&b, (uint64_t)(i % 3), 4, 0);
	put(&b, 3, 2, 0);
	put(&b, 2, 4, 0);
	put(&b, 0, 4, 0);
	put(&b, 1, 4, 0);
	struct vd_triangle *t;
	struct vd_mesh_stats st;
	size_t n;
	CHECK_EQ(read_mesh(write_bytes("short.ply", b.d, b.n), 100, &t, &n,
			   &st), VD_OK);
	CHECK_EQ(n, 998 + 1);
	CHECK_EQ(st.faces_dropped_short, 3);
	CHECK_EQ(st.polygons_split, 1);
	if (n == 999) {
		/* Fan triangle k is (c0, c(k+1), c(k+2)) with c(i) = i % 3. */
		CHECK_EQ(t[0].v[0][0], 0);
		CHECK_EQ(t[0].v[1][0], 3);
		CHECK_EQ(t[0].v[2][0], 6);
		CHECK_EQ(t[997].v[1][0], 998 % 3 * 3);
		CHECK_EQ(t[997].v[2][0], 999 % 3 * 3);
		CHECK_EQ(t[998].v[0][0], 6);
	}
	free(t);
	/* The same in text, and in OBJ. */
	const char *ply = "ply\nformat ascii 1.0\nelement vertex 3\n"
		"property float x\nproperty float y\nproperty float z\n"
		"element face 4\nproperty list uchar int vertex_indices\n"
		"end_header\n0 0 0\n1 0 0\n0 1 0\n0\n1 2\n2 0 1\n3 2 1 0\n";
	CHECK_EQ(read_mesh(write_text("short-ascii.ply", ply), 10, &t, &n,
			   &st), VD_OK);
	CHECK_EQ(n, 1);
	CHECK_EQ(st.faces_dropped_short, 3);
	free(t);
	const char *obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1\nf 1 2\n"
		"f\nf 1 2 4 3\n";
	CHECK_EQ(read_mesh(write_text("short.obj", obj), 10, &t, &n, &st),
		 VD_OK);
	CHECK_EQ(n, 2);
	CHECK_EQ(st.faces_dropped_short, 3);
	CHECK_EQ(st.polygons_split, 1);
	free(t);
}

static void test_obj_forward_reference(void)
{
	/* Supported OBJ rule: a face uses vertices defined before it. A
	 * positive index to a later vertex is refused, not guessed. */
	const char *p = write_text("fwd.obj", "v 0 0 0\nv 1 0 0\nf 1 2 3\n"
				   "v 0 1 0\n");
	CHECK_EQ(mesh_error(p), VD_ERR_RANGE);
	CHECK(detail_has("line 3"));
	CHECK(detail_has("defined so far"));
}

static void test_obj_bad_indices(void)
{
	CHECK_EQ(mesh_error(write_text("zero.obj", "v 0 0 0\nv 1 0 0\n"
				       "v 0 1 0\nf 1 2 0\n")), VD_ERR_RANGE);
	CHECK(detail_has("line 4"));
	CHECK(detail_has("index 0"));
	CHECK_EQ(mesh_error(write_text("big.obj", "v 0 0 0\nv 1 0 0\n"
				       "v 0 1 0\nf 1 2 4\n")), VD_ERR_RANGE);
	CHECK(detail_has("line 4"));
	CHECK_EQ(mesh_error(write_text("neg.obj", "v 0 0 0\nv 1 0 0\n"
				       "v 0 1 0\n\nf -1 -2 -4\n")),
		 VD_ERR_RANGE);
	CHECK(detail_has("line 5"));
	CHECK(detail_has("face 1"));
	CHECK_EQ(mesh_error(write_text("huge.obj", "v 0 0 0\nv 1 0 0\n"
				       "v 0 1 0\nf 1 2 99999999999999999999\n")),
		 VD_ERR_FORMAT);
	CHECK_EQ(mesh_error(write_text("corner.obj", "v 0 0 0\nv 1 0 0\n"
				       "v 0 1 0\nf 1 2 3x\n")), VD_ERR_FORMAT);
	CHECK(detail_has("3x"));
}

static void test_malformed_numbers(void)
{
	CHECK_EQ(mesh_error(write_text("num.obj", "# c\nv 0 0 0\nv 1 0 0\n"
				       "v 0 1e 0\nf 1 2 3\n")), VD_ERR_FORMAT);
	CHECK(detail_has("line 4"));
	CHECK(detail_has("1e"));
	CHECK_EQ(mesh_error(write_text("few.obj", "v 0 0\n")), VD_ERR_FORMAT);
	CHECK(detail_has("line 1"));
	const char *head = "ply\nformat ascii 1.0\nelement vertex 3\n"
		"property float x\nproperty float y\nproperty float z\n"
		"element face 1\nproperty list uchar int vertex_indices\n"
		"end_header\n";
	char text[1024];
	snprintf(text, sizeof text, "%s0 0 0\n1 0 0\n0 1.0.0 0\n3 0 1 2\n",
		 head);
	CHECK_EQ(mesh_error(write_text("num.ply", text)), VD_ERR_FORMAT);
	CHECK(detail_has("line 12"));
	snprintf(text, sizeof text, "%s0 0 0\n1 0 0\n0 1 0\n3 0 1 2.5\n",
		 head);
	CHECK_EQ(mesh_error(write_text("idx.ply", text)), VD_ERR_FORMAT);
	CHECK(detail_has("line 13"));
	snprintf(text, sizeof text, "%s0 0 0\n1 0 0\n0 1\n3 0 1 2\n", head);
	CHECK_EQ(mesh_error(write_text("missing.ply", text)), VD_ERR_FORMAT);
	snprintf(text, sizeof text, "%s0 0 0\n1 0 0\n0 1 0 9\n3 0 1 2\n",
		 head);
	CHECK_EQ(mesh_error(write_text("extra.ply", text)), VD_ERR_FORMAT);
	snprintf(text, sizeof text, "%s0 0 0\n1 0 0\n0 1 0\n3 0 1\n", head);
	CHECK_EQ(mesh_error(write_text("shortlist.ply", text)), VD_ERR_FORMAT);
	snprintf(text, sizeof text, "%s0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", head);
	CHECK_EQ(mesh_error(write_text("range.ply", text)), VD_ERR_RANGE);
	CHECK(detail_has("line 13"));
	snprintf(text, sizeof text, "%s0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n",
		 head);
	CHECK_EQ(mesh_error(write_text("negidx.ply", text)), VD_ERR_RANGE);
	/* Fewer lines than the header says. */
	snprintf(text, sizeof text, "%s0 0 0\n1 0 0\n0 1 0\n", head);
	CHECK_EQ(mesh_error(write_text("nofaces.ply", text)),
		 VD_ERR_TRUNCATED);
	CHECK_EQ(mesh_error(write_text("stl-num.stl",
		"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n"
		"vertex 1 0 0\nvertex 0 one 0\nendloop\nendfacet\n")),
		VD_ERR_FORMAT);
	CHECK(detail_has("line 6"));
	CHECK_EQ(mesh_error(write_text("stl-kw.stl",
		"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n"
		"vertex 1 0 0\nvertex 0 1 0\nendloop\nendface\n")),
		VD_ERR_FORMAT);
	CHECK(detail_has("endfacet"));
	CHECK_EQ(mesh_error(write_text("stl-cut.stl",
		"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n"
		"vertex 1 0 0\n")), VD_ERR_TRUNCATED);
}

/* The non-finite rule: an error naming the vertex as soon as a face uses
 * it, never when nothing uses it. */
static void test_non_finite(void)
{
	const char *head = "ply\nformat ascii 1.0\nelement vertex 4\n"
		"property float x\nproperty float y\nproperty float z\n"
		"element face 1\nproperty list uchar int vertex_indices\n"
		"end_header\n";
	char text[1024];
	snprintf(text, sizeof text, "%s0 0 0\n1 0 0\n0 1 0\nnan 0 0\n"
		 "3 0 1 2\n", head);
	CHECK_EQ(mesh_error(write_text("unused-nan.ply", text)), VD_OK);
	snprintf(text, sizeof text, "%s0 0 0\n1 0 0\n0 1 0\nnan 0 0\n"
		 "3 0 3 2\n", head);
	CHECK_EQ(mesh_error(write_text("nan.ply", text)), VD_ERR_RANGE);
	CHECK(detail_has("vertex 3"));
	CHECK(detail_has("line 14"));

	struct bytes b = {.n = 0};
	put_str(&b, "ply\nformat binary_big_endian 1.0\nelement vertex 3\n"
		    "property double x\nproperty double y\nproperty double z\n"
		    "element face 1\nproperty list uchar int vertex_indices\n"
		    "end_header\n");
	for (int i = 0; i < 9; i++)
		put_f64(&b, i == 5 ? 1e300 : 0.0, 1); /* beyond float range */
	put(&b, 3, 1, 1);
	put(&b, 0, 4, 1);
	put(&b, 1, 4, 1);
	put(&b, 2, 4, 1);
	CHECK_EQ(mesh_error(write_bytes("inf.ply", b.d, b.n)), VD_ERR_RANGE);
	CHECK(detail_has("vertex 1"));

	CHECK_EQ(mesh_error(write_text("nan.obj", "v 0 0 0\nv inf 0 0\n"
				       "v 0 1 0\nf 1 2 3\n")), VD_ERR_RANGE);
	CHECK(detail_has("vertex 2"));
	CHECK_EQ(mesh_error(write_text("nan-unused.obj", "v 0 0 0\n"
				       "v inf 0 0\nv 0 1 0\nv 1 1 1\n"
				       "f 1 4 3\n")), VD_OK);
	CHECK_EQ(mesh_error(write_text("nan.stl",
		"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n"
		"vertex 1 NaN 0\nvertex 0 1 0\nendloop\nendfacet\n")),
		VD_ERR_RANGE);

	/* A quiet NaN as the y of triangle 2's first corner. */
	stl_bin_reference(&b, "binary");
	for (int i = 0; i < 4; i++)
		b.d[84 + 50 + 12 + 4 + i] = (unsigned char)(0x7fc00000u >> 8 * i);
	CHECK_EQ(mesh_error(write_bytes("nan-bin.stl", b.d, b.n)),
		 VD_ERR_RANGE);
	CHECK(detail_has("triangle 2"));
}

static void test_ply_header_errors(void)
{
	/* Ends inside the header. */
	CHECK_EQ(mesh_error(write_text("cut-header.ply", "ply\nformat ascii "
				       "1.0\nelement vertex 3\n")),
		 VD_ERR_TRUNCATED);
	CHECK(detail_has("end_header"));
	CHECK_EQ(mesh_error(write_text("just-ply.ply", "ply")),
		 VD_ERR_TRUNCATED);
	/* No end_header before binary bytes. */
	struct bytes b = {.n = 0};
	put_str(&b, "ply\nformat binary_little_endian 1.0\nelement vertex 1\n"
		    "property float x\nproperty float y\nproperty float z\n");
	put_f32(&b, 1.0f, 0);
	put_f32(&b, 2.0f, 0);
	put_f32(&b, 3.0f, 0);
	CHECK_EQ(mesh_error(write_bytes("no-end.ply", b.d, b.n)),
		 VD_ERR_FORMAT);
	CHECK(detail_has("line 7"));
	const char *cases[][2] = {
		{"ply\nformat binary_middle_endian 1.0\nend_header\n", "u"},
		{"ply\nformat ascii 2.0\nend_header\n", "u"},
		{"ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x"
		 "\nend_header\n", "f"},
		{"ply\nformat ascii 1.0\nelement vertex 1\nproperty list float "
		 "int x\nend_header\n", "f"},
		{"ply\nformat ascii 1.0\nelement vertex 1\nproperty float\n"
		 "end_header\n", "f"},
		{"ply\nformat ascii 1.0\nelement vertex many\nend_header\n", "f"},
		{"ply\nformat ascii 1.0\nelement vertex -1\nend_header\n", "f"},
		{"ply\nformat ascii 1.0\nproperty float x\nend_header\n", "f"},
		{"ply\nformat ascii 1.0\nvertex 3\nend_header\n", "f"},
		{"ply\nelement vertex 0\nend_header\n", "f"},
		{"ply\nformat binary_little_endian 1.0\nelement nothing "
		 "9000000000000000000\nend_header\n", "f"},
		{"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
		 "property float y\nelement face 0\nproperty list uchar int "
		 "vertex_indices\nend_header\n0 0\n", "f"},
		{"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
		 "property float y\nproperty float z\nelement face 0\n"
		 "property list uchar float vertex_indices\nend_header\n"
		 "0 0 0\n", "f"},
		{"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
		 "property float y\nproperty float z\nelement face 0\n"
		 "property int vertex_indices\nend_header\n0 0 0\n", "f"},
		{"ply\nformat ascii 1.0\nelement face 1\nproperty list uchar "
		 "int vertex_indices\nend_header\n3 0 1 2\n", "f"},
		{"ply\nformat ascii 1.0\nelement face 1\nproperty list uchar "
		 "int vertex_indices\nelement vertex 3\nproperty float x\n"
		 "property float y\nproperty float z\nend_header\n3 0 1 2\n"
		 "0 0 0\n0 0 0\n0 0 0\n", "u"},
		/* Counts the rest of the file cannot hold: refused before
		 * any allocation. */
		{"ply\nformat binary_little_endian 1.0\nelement vertex "
		 "4000000000\nproperty float x\nproperty float y\n"
		 "property float z\nend_header\n0123456789ab", "t"},
		{"ply\nformat binary_little_endian 1.0\nelement vertex "
		 "99999999999999\nproperty float x\nproperty float y\n"
		 "property float z\nend_header\n0123456789ab", "r"},
		{"ply\nformat ascii 1.0\nelement vertex 1000000\n"
		 "property float x\nproperty float y\nproperty float z\n"
		 "end_header\n0 0 0\n", "t"},
		{"ply\nformat binary_little_endian 1.0\nelement vertex 0\n"
		 "property float x\nproperty float y\nproperty float z\n"
		 "element face 3000000000\nproperty list uchar int "
		 "vertex_indices\nend_header\n", "t"},
	};
	for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
		int want = cases[i][1][0] == 'u' ? VD_ERR_UNSUPPORTED
			: cases[i][1][0] == 't' ? VD_ERR_TRUNCATED
			: cases[i][1][0] == 'r' ? VD_ERR_RANGE : VD_ERR_FORMAT;
		int got = mesh_error(write_text("hdr.ply", cases[i][0]));
		if (got != want)
			fprintf(stderr, "header case %zu: %s\n", i,
				vd_error_detail());
		CHECK_EQ(got, want);
		CHECK(vd_error_detail()[0] != 0);
	}
}

static void test_list_counts(void)
{
	const char *head = "ply\nformat ascii 1.0\nelement vertex 3\n"
		"property float x\nproperty float y\nproperty float z\n"
		"element face 1\nproperty list int int vertex_indices\n"
		"end_header\n0 0 0\n1 0 0\n0 1 0\n";
	char text[1024];
	snprintf(text, sizeof text, "%s70000 0 1 2\n", head);
	CHECK_EQ(mesh_error(write_text("many.ply", text)), VD_ERR_FORMAT);
	CHECK(detail_has("70000"));
	snprintf(text, sizeof text, "%s-3 0 1 2\n", head);
	CHECK_EQ(mesh_error(write_text("negcount.ply", text)), VD_ERR_FORMAT);
	struct bytes b = {.n = 0};
	put_str(&b, "ply\nformat binary_little_endian 1.0\nelement vertex 3\n"
		    "property float x\nproperty float y\nproperty float z\n"
		    "element face 1\nproperty list uint int vertex_indices\n"
		    "end_header\n");
	for (int i = 0; i < 9; i++)
		put_f32(&b, 0, 0);
	put(&b, 4000000000u, 4, 0);
	for (int i = 0; i < 3; i++)
		put(&b, 0, 4, 0);
	CHECK_EQ(mesh_error(write_bytes("many.ply", b.d, b.n)), VD_ERR_FORMAT);
	CHECK(detail_has("face 1"));
	/* Binary index out of range names the face. */
	b.n -= 16;
	put(&b, 3, 4, 0);
	put(&b, 0, 4, 0);
	put(&b, 3, 4, 0);
	put(&b, 1, 4, 0);
	CHECK_EQ(mesh_error(write_bytes("range.ply", b.d, b.n)), VD_ERR_RANGE);
	CHECK(detail_has("face 1"));
	CHECK(detail_has("index 3"));
}

/* ------------------------------------------------------------------ AC3D */

/* The reference mesh as one AC3D object inside the world object. */
static const char *const ac_reference =
	"AC3Db\n"
	"MATERIAL \"ac3dmat1\" rgb 1 1 1  amb 0.2 0.2 0.2  emis 0 0 0  "
	"spec 0.5 0.5 0.5  shi 10  trans 0\n"
	"OBJECT world\n"
	"kids 1\n"
	"OBJECT poly\n"
	"name \"reference\"\n"
	"numvert 5\n"
	"0 0 0\n1.5 0 0\n1.5 2.25 0.1\n0 2.25 0.1\n-0.75 1 -3.125\n"
	"numsurf 2\n"
	"SURF 0x10\nmat 0\nrefs 4\n0 0 0\n1 1 0\n2 1 1\n3 0 1\n"
	"SURF 0x20\nmat 0\nrefs 3\n1 0 0\n4 0 0\n2 0 0\n"
	"kids 0\n";

/* Nested objects with rot and loc, a quad, a line, a triangle strip, a
 * data block whose bytes look like keywords, attribute lines to skip and
 * vertex lines with normals after the position.
 *
 * World transforms, worked out by hand (rot rows r0 r1 r2 / r3 r4 r5 /
 * r6 r7 r8 applied to column vectors, then loc, then the parent's):
 *   "quad" (kid of world):     p + (10 0 0)
 *   "turned" (kid of quad):    R p + (0 5 0) + (10 0 0), R (x y z) = (-y x z)
 *   "tri" (kid of turned):     R (p + (1 0 0)) + (10 5 0)
 *                              = (-y + 10, x + 6, z)
 *   "strip" (kid of world):    p + (0 0 -2)
 * so the quad's corners are (10 0 0) (11 0 0) (11 1 0) (10 1 0), the
 * triangle's (0 0 0) (2 0 0) (0 3 0) become (10 6 0) (10 8 0) (7 6 0), and
 * the strip 0 1 2 3 gives (0 1 2) and, flipped, (2 1 3). */
static const char *const ac_nested =
	"AC3Db\n"
	"MATERIAL \"white\" rgb 1 1 1  amb 0.2 0.2 0.2  emis 0 0 0  "
	"spec 0.5 0.5 0.5  shi 10  trans 0\n"
	"OBJECT world\n"
	"name \"root\"\n"
	"kids 2\n"
	"OBJECT poly\n"
	"name \"quad with a line\"\n"
	"data 11\n"
	"kids 9\nSURF\n"
	"texture \"skin.png\"\n"
	"texrep 1 1\n"
	"texoff 0 0\n"
	"loc 10 0 0\n"
	"crease 30.000000\n"
	"url http://example.org/quad\n"
	"numvert 4\n"
	"0 0 0\n1 0 0\n1 1 0\n0 1 0\n"
	"numsurf 2\n"
	"SURF 0x10\nmat 0\nrefs 4\n0 0 0\n1 1 0\n2 1 1\n3 0 1\n"
	"SURF 0x2\nmat 0\nrefs 2\n0 0 0\n2 1 1\n"
	"kids 1\n"
	"OBJECT group\n"
	"name \"turned\"\n"
	"rot 0 -1 0  1 0 0  0 0 1\n"
	"loc 0 5 0\n"
	"kids 1\n"
	"OBJECT poly\n"
	"name \"tri\"\n"
	"loc 1 0 0\n"
	"numvert 3\n"
	"0 0 0 0 0 1\n2 0 0 0 0 1\n0 3 0 0 0 1\n"
	"numsurf 1\n"
	"SURF 0x30\nmat 0\nrefs 3\n0 0 0\n1 1 0\n2 0 1\n"
	"kids 0\n"
	"OBJECT poly\n"
	"name \"strip\"\n"
	"loc 0 0 -2\n"
	"numvert 4\n"
	"0 0 0\n1 0 0\n0 1 0\n1 1 0\n"
	"numsurf 1\n"
	"SURF 0x14\nmat 0\nrefs 4\n0 0 0\n1 0 0\n2 0 0\n3 0 0\n"
	"kids 0\n";

static const float AC_NESTED[5][3][3] = {
	{{10, 0, 0}, {11, 0, 0}, {11, 1, 0}},
	{{10, 0, 0}, {11, 1, 0}, {10, 1, 0}},
	{{10, 6, 0}, {10, 8, 0}, {7, 6, 0}},
	{{0, 0, -2}, {1, 0, -2}, {0, 1, -2}},
	{{0, 1, -2}, {1, 0, -2}, {1, 1, -2}}};

static int same_as_nested(const struct vd_triangle *t, size_t n)
{
	if (n != 5) {
		fprintf(stderr, "got %zu triangles, want 5\n", n);
		return 0;
	}
	for (int i = 0; i < 5; i++)
		for (int c = 0; c < 3; c++)
			if (memcmp(t[i].v[c], AC_NESTED[i][c], 12)) {
				fprintf(stderr, "triangle %d corner %d: %g %g "
					"%g\n", i, c, t[i].v[c][0],
					t[i].v[c][1], t[i].v[c][2]);
				return 0;
			}
	return 1;
}

/* The text with every "\n" made "\r\n"; the caller frees. */
static char *crlf(const char *s)
{
	char *o = malloc(2 * strlen(s) + 1), *p = o;
	for (; *s; s++) {
		if (*s == '\n')
			*p++ = '\r';
		*p++ = *s;
	}
	*p = 0;
	return o;
}

static void test_ac3d(void)
{
	check_reference(write_text("ref.ac", ac_reference), "ac3d", 1);
	const char *p = write_text("nested.ac", ac_nested);
	static const size_t chunks[] = {1, 2, 3, 1000};
	for (size_t k = 0; k < sizeof chunks / sizeof *chunks; k++) {
		struct vd_triangle *t;
		struct vd_mesh_stats st;
		size_t n;
		CHECK_EQ(read_mesh(p, chunks[k], &t, &n, &st), VD_OK);
		CHECK(same_as_nested(t, n));
		CHECK_EQ(st.triangles_read, 5);
		CHECK_EQ(st.faces_dropped_short, 1); /* the line */
		CHECK_EQ(st.polygons_split, 2);      /* the quad, the strip */
		CHECK_EQ(st.vertices, 11);
		free(t);
	}
	/* The same file with CRLF line ends: the data block grows a byte. */
	char *w = crlf(ac_nested), *d = strstr(w, "data 11");
	d[6] = '2';
	struct vd_triangle *t;
	size_t n;
	CHECK_EQ(read_mesh(write_text("nested-crlf.ac", w), 2, &t, &n, NULL),
		 VD_OK);
	CHECK(same_as_nested(t, n));
	free(t);
	free(w);
	/* Rewind, also from the middle of a strip and of a nested object. */
	struct vd_mesh *m;
	CHECK_EQ(vd_mesh_open(&m, p), VD_OK);
	if (!m)
		return;
	CHECK(!strcmp(vd_mesh_format(m), "ac3d"));
	struct vd_triangle buf[8];
	for (size_t stop = 1; stop <= 6; stop++) {
		size_t got = 0, k;
		int e = VD_OK;
		while (got < stop && !(e = vd_mesh_read(m, buf + got, 1, &k)) &&
		       k)
			got += k;
		CHECK_EQ(e, VD_OK);
		CHECK_EQ(got, stop < 5 ? stop : 5);
		CHECK_EQ(vd_mesh_rewind(m), VD_OK);
	}
	CHECK_EQ(vd_mesh_read(m, buf, 8, &n), VD_OK);
	CHECK(same_as_nested(buf, n));
	CHECK_EQ(vd_mesh_stats(m)->vertices, 11);
	CHECK_EQ(vd_mesh_read(m, buf, 8, &n), VD_OK);
	CHECK_EQ(n, 0);
	CHECK(vd_mesh_memory_bytes(m) > 0);
	vd_mesh_close(m);
}

/* A one-object AC3D file around `body` (its numvert, numsurf and kids). */
static int ac_error(const char *name, const char *body)
{
	char text[2048];
	snprintf(text, sizeof text, "AC3Db\nOBJECT world\nkids 1\n"
		 "OBJECT poly\nname \"o\"\n%s", body);
	return mesh_error(write_text(name, text));
}

/* Lines 1-5 are the header, the world and "OBJECT poly", "name"; so
 * "numvert" is line 6, the vertices 7-9, "numsurf" 10, "SURF" 11, "mat"
 * 12, "refs" 13, the refs 14-16. */
#define AC_VERTS "numvert 3\n0 0 0\n1 0 0\n0 1 0\n"

static void test_ac3d_errors(void)
{
	/* Refs beyond the object's vertices. */
	CHECK_EQ(ac_error("range.ac", AC_VERTS "numsurf 1\nSURF 0x10\nmat 0\n"
			  "refs 3\n0 0 0\n1 0 0\n3 0 0\nkids 0\n"),
		 VD_ERR_RANGE);
	CHECK(detail_has("line 16"));
	CHECK(detail_has("index 3"));
	CHECK(detail_has("'o' has 3 vertices"));
	CHECK_EQ(ac_error("negative.ac", AC_VERTS "numsurf 1\nSURF 0x10\n"
			  "refs 3\n0 0 0\n-1 0 0\n2 0 0\nkids 0\n"),
		 VD_ERR_RANGE);
	/* An index valid only in the previous object. */
	CHECK_EQ(mesh_error(write_text("other.ac", "AC3Db\nOBJECT world\n"
		"kids 2\nOBJECT poly\nnumvert 4\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n"
		"kids 0\nOBJECT poly\n" AC_VERTS "numsurf 1\nSURF 0\nrefs 3\n"
		"1 0 0\n2 0 0\n3 0 0\nkids 0\n")), VD_ERR_RANGE);
	CHECK(detail_has("line 21"));
	/* Bad numbers. */
	CHECK_EQ(ac_error("vertex.ac", "numvert 3\n0 0 0\n1 x 0\n0 1 0\n"
			  "kids 0\n"), VD_ERR_FORMAT);
	CHECK(detail_has("line 8"));
	CHECK(detail_has("'x'"));
	CHECK_EQ(ac_error("short-vertex.ac", "numvert 3\n0 0 0\n1 0\n0 1 0\n"
			  "kids 0\n"), VD_ERR_FORMAT);
	CHECK(detail_has("line 8"));
	CHECK_EQ(ac_error("numvert.ac", "numvert -3\nkids 0\n"), VD_ERR_FORMAT);
	CHECK(detail_has("line 6"));
	CHECK_EQ(ac_error("numvert2.ac", "numvert 2.5\nkids 0\n"),
		 VD_ERR_FORMAT);
	CHECK_EQ(ac_error("numsurf.ac", AC_VERTS "numsurf many\nkids 0\n"),
		 VD_ERR_FORMAT);
	CHECK(detail_has("line 10"));
	CHECK_EQ(ac_error("refs.ac", AC_VERTS "numsurf 1\nSURF 0x10\nmat 0\n"
			  "refs two\n0 0 0\nkids 0\n"), VD_ERR_FORMAT);
	CHECK(detail_has("line 13"));
	CHECK_EQ(ac_error("refidx.ac", AC_VERTS "numsurf 1\nSURF 0x10\n"
			  "refs 3\n0 0 0\n1.5 0 0\n2 0 0\nkids 0\n"),
		 VD_ERR_FORMAT);
	CHECK(detail_has("line 14"));
	CHECK_EQ(ac_error("flags.ac", AC_VERTS "numsurf 1\nSURF 0xZZ\n"
			  "refs 3\n0 0 0\n1 0 0\n2 0 0\nkids 0\n"),
		 VD_ERR_FORMAT);
	CHECK(detail_has("line 11"));
	CHECK_EQ(ac_error("type.ac", AC_VERTS "numsurf 1\nSURF 0x13\n"
			  "refs 3\n0 0 0\n1 0 0\n2 0 0\nkids 0\n"),
		 VD_ERR_FORMAT);
	CHECK(detail_has("surface type 3"));
	CHECK_EQ(ac_error("rot.ac", "rot 1 0 0 0 1 0 0 0\nkids 0\n"),
		 VD_ERR_FORMAT);
	CHECK(detail_has("line 6"));
	CHECK_EQ(ac_error("loc.ac", "loc 1 2 3 4\nkids 0\n"), VD_ERR_FORMAT);
	CHECK_EQ(ac_error("loc2.ac", "loc 1 2 three\nkids 0\n"),
		 VD_ERR_FORMAT);
	CHECK_EQ(ac_error("kids.ac", "kids x\n"), VD_ERR_FORMAT);
	CHECK_EQ(ac_error("data.ac", "data -1\nkids 0\n"), VD_ERR_FORMAT);
	/* Counts that disagree with the lines that follow. */
	CHECK_EQ(ac_error("fewverts.ac", "numvert 4\n0 0 0\n1 0 0\n0 1 0\n"
			  "numsurf 0\nkids 0\n"), VD_ERR_FORMAT);
	CHECK(detail_has("line 10"));
	CHECK_EQ(ac_error("moreverts.ac", "numvert 2\n0 0 0\n1 0 0\n0 1 0\n"
			  "kids 0\n"), VD_ERR_FORMAT);
	CHECK(detail_has("line 9"));
	CHECK_EQ(ac_error("fewrefs.ac", AC_VERTS "numsurf 1\nSURF 0\nrefs 4\n"
			  "0 0 0\n1 0 0\n2 0 0\nkids 0\n"), VD_ERR_FORMAT);
	CHECK_EQ(ac_error("moresurf.ac", AC_VERTS "numsurf 1\nSURF 0\nrefs 3\n"
			  "0 0 0\n1 0 0\n2 0 0\nSURF 0\nrefs 3\n0 0 0\n1 0 0\n"
			  "2 0 0\nkids 0\n"), VD_ERR_FORMAT);
	CHECK(detail_has("numsurf"));
	CHECK_EQ(ac_error("nokids.ac", AC_VERTS "OBJECT poly\nkids 0\n"),
		 VD_ERR_FORMAT);
	CHECK(detail_has("line 10"));
	CHECK_EQ(ac_error("notobject.ac", "kids 1\nnumvert 0\nkids 0\n"),
		 VD_ERR_FORMAT);
	CHECK(detail_has("expected OBJECT"));
	CHECK_EQ(mesh_error(write_text("nul.ac", "AC3Db\nOBJECT world\n"
				       "kids 0\nname \"a\0b\"\n")), VD_OK);
	CHECK_EQ(mesh_error(write_bytes("nul2.ac", "AC3Db\nOBJECT wo\0ld\n"
					"kids 0\n", 27)), VD_ERR_FORMAT);
	CHECK(detail_has("NUL"));
	/* A vertex that is not finite, once a surface uses it. */
	CHECK_EQ(ac_error("inf.ac", "numvert 3\n0 0 0\n1e999 0 0\n0 1 0\n"
			  "kids 0\n"), VD_OK);
	CHECK_EQ(ac_error("inf2.ac", "numvert 3\n0 0 0\n1e999 0 0\n0 1 0\n"
			  "numsurf 1\nSURF 0\nrefs 3\n0 0 0\n1 0 0\n2 0 0\n"
			  "kids 0\n"), VD_ERR_RANGE);
	CHECK(detail_has("line 11"));
	/* Truncation: kids missing, a data block cut, no object at all. */
	CHECK_EQ(mesh_error(write_text("halfkids.ac", "AC3Db\nOBJECT world\n"
				       "kids 2\nOBJECT poly\nkids 0\n")),
		 VD_ERR_TRUNCATED);
	CHECK(detail_has("1 of the 2 kids"));
	CHECK_EQ(ac_error("cutdata.ac", "data 100\nshort\n"),
		 VD_ERR_TRUNCATED);
	CHECK_EQ(mesh_error(write_text("header.ac", "AC3Db\n")),
		 VD_ERR_TRUNCATED);
	CHECK_EQ(mesh_error(write_text("material.ac", "AC3Db\nMATERIAL \"m\" "
				       "rgb 1 1 1\n")), VD_ERR_TRUNCATED);
	/* Empty objects are not the reader's error. */
	CHECK_EQ(mesh_error(write_text("world.ac", "AC3Db\nOBJECT world\n"
				       "kids 0")), VD_OK);
}

/* Every cut of the nested file is truncation: the structure (kids counts,
 * surface counts) always says more is due, and a cut last line that does
 * not parse is blamed on the cut. */
static void test_ac3d_every_truncation(void)
{
	size_t n = strlen(ac_nested);
	CHECK_EQ(mesh_error(write_bytes("cut.ac", ac_nested, 0)),
		 VD_ERR_EMPTY);
	for (size_t len = 1; len < 4; len++)
		CHECK_EQ(mesh_error(write_bytes("cut.ac", ac_nested, len)),
			 VD_ERR_UNSUPPORTED);
	for (size_t len = 4; len < n - 1; len++) {
		int e = mesh_error(write_bytes("cut.ac", ac_nested, len));
		if (e != VD_ERR_TRUNCATED)
			fprintf(stderr, "cut at %zu: %s\n", len,
				vd_error_detail());
		CHECK_EQ(e, VD_ERR_TRUNCATED);
	}
	/* Only the last newline may go. */
	struct vd_triangle *t;
	size_t k;
	CHECK_EQ(read_mesh(write_bytes("cut.ac", ac_nested, n - 1), 3, &t, &k,
			   NULL), VD_OK);
	CHECK(same_as_nested(t, k));
	free(t);
}

/* TORCS's .acc files declare more kids than they hold (22 of its 25 tracks
 * end that way): an .acc file that ends between two objects is read as
 * complete, with one warning however often it is read; the same bytes
 * named .ac are truncated, and a cut inside an object is truncation in
 * both. */
static int acc_warnings;
static char acc_warning[600];

static void count_warning(void *ctx, const char *line)
{
	(void)ctx;
	acc_warnings++;
	snprintf(acc_warning, sizeof acc_warning, "%s", line);
}

static void test_acc_short_kids(void)
{
	/* the world declares 5 kids; the file holds 2 */
	char *w = strdup(ac_nested), *k = strstr(w, "kids 2\n");
	k[5] = '5';
	CHECK_EQ(mesh_error(write_text("short.ac", w)), VD_ERR_TRUNCATED);
	CHECK(detail_has("2 of the 5 kids"));
	const char *acc = write_text("short.acc", w);
	struct vd_mesh_open_opts o = {.warn = count_warning};
	struct vd_mesh *m;
	acc_warnings = 0;
	CHECK_EQ(vd_mesh_open_opts(&m, acc, &o), VD_OK);
	if (!m) {
		free(w);
		return;
	}
	for (int pass = 0; pass < 2; pass++) {
		struct vd_triangle buf[8];
		size_t got = 0, n;
		int e;
		while (!(e = vd_mesh_read(m, buf + got, 1, &n)) && n)
			got += n;
		CHECK_EQ(e, VD_OK);
		CHECK(same_as_nested(buf, got));
		CHECK_EQ(vd_mesh_rewind(m), VD_OK);
	}
	vd_mesh_close(m);
	CHECK_EQ(acc_warnings, 1);
	CHECK(strstr(acc_warning, "2 of the 5 kids of object 'root'") != NULL);
	/* every cut: truncated, unless it falls right after a kids line
	 * (between two objects, the line's newline kept or not), where TORCS
	 * would stop too; "kids 9" inside the data block is no kids line */
	size_t len = strlen(w);
	for (size_t cut = 4; cut < len - 1; cut++) {
		int e = mesh_error(write_bytes("cut.acc", w, cut));
		const char *line = w + cut - 1;
		while (line > w && line[-1] != '\n')
			line--;
		int boundary = (w[cut - 1] == '\n' || w[cut] == '\n') &&
			       !strncmp(line, "kids ", 5) &&
			       strncmp(line, "kids 9\nSURF", 11);
		if (e != (boundary ? VD_OK : VD_ERR_TRUNCATED))
			fprintf(stderr, "cut at %zu (%d, boundary %d): %s\n",
				cut, e, boundary, vd_error_detail());
		CHECK_EQ(e, (boundary ? VD_OK : VD_ERR_TRUNCATED));
	}
	free(w);
}

/* A line longer than the read buffer is an error naming its line in every
 * text format; the error used to come back as "a line" of garbage. */
static void test_long_lines(void)
{
	static const char *const heads[] = {"v 0 0 0\n# ", "solid x\n",
					    "ply\ncomment ",
					    "AC3Db\nMATERIAL "};
	static const char *const names[] = {"long.obj", "long.stl", "long.ply",
					    "long.ac"};
	size_t n = (1u << 20) + 100;
	char *s = malloc(n + 64);
	for (int i = 0; i < 4; i++) {
		size_t h = strlen(heads[i]);
		memcpy(s, heads[i], h);
		memset(s + h, 'x', n);
		s[h + n] = '\n';
		int e = mesh_error(write_bytes(names[i], s, h + n + 1));
		CHECK_EQ(e, VD_ERR_FORMAT);
		CHECK(detail_has("line 2: longer than"));
	}
	free(s);
}

static void test_not_meshes(void)
{
	CHECK_EQ(mesh_error(fixture_path("does-not-exist.ply")), VD_ERR_IO);
	CHECK(detail_has("No such file"));
	char sub[600];
	snprintf(sub, sizeof sub, "%s/adir.ply", dir);
	mkdir(sub, 0755);
	CHECK_EQ(mesh_error(sub), VD_ERR_IO);
	CHECK(detail_has("directory"));
	CHECK_EQ(mesh_error(write_text("empty.ply", "")), VD_ERR_EMPTY);
	CHECK_EQ(mesh_error(write_text("empty.obj", "")), VD_ERR_EMPTY);
	static unsigned char zeros[1000];
	CHECK_EQ(mesh_error(write_bytes("zeros.bin", zeros, sizeof zeros)),
		 VD_ERR_UNSUPPORTED);
	CHECK(detail_has("not a PLY, OBJ, STL or AC3D file"));
	CHECK(detail_has("00 00"));
	CHECK_EQ(mesh_error(write_text("hello.txt", "hello world\n")),
		 VD_ERR_UNSUPPORTED);
	CHECK(detail_has("hello"));
	/* Binary bytes in a file named .obj. */
	CHECK_EQ(mesh_error(write_bytes("zeros.obj", zeros, sizeof zeros)),
		 VD_ERR_FORMAT);
	CHECK_EQ(mesh_error(write_text("junk.obj", "v 0 0 0\n$$$\n")),
		 VD_ERR_FORMAT);
	CHECK(detail_has("line 2"));
	/* A binary STL whose size disagrees with its count. */
	struct bytes b;
	stl_bin_reference(&b, "binary");
	b.d[b.n++] = 0;
	CHECK_EQ(mesh_error(write_bytes("long.stl", b.d, b.n)),
		 VD_ERR_TRAILING);
	/* Empty meshes are not the reader's error. */
	CHECK_EQ(mesh_error(write_text("none.obj", "# nothing\n")), VD_OK);
	CHECK_EQ(mesh_error(write_text("points.ply", "ply\nformat ascii 1.0\n"
				       "element vertex 1\nproperty float x\n"
				       "property float y\nproperty float z\n"
				       "end_header\n1 2 3\n")), VD_OK);
	stl_bin_reference(&b, "binary");
	b.n = 80;
	put(&b, 0, 4, 0);
	CHECK_EQ(mesh_error(write_bytes("none.stl", b.d, b.n)), VD_OK);
	CHECK_EQ(mesh_error(write_text("none-ascii.stl", "solid empty\n"
				       "endsolid empty\n")), VD_OK);
	/* Arguments. */
	struct vd_mesh *m;
	CHECK_EQ(vd_mesh_open(&m, NULL), VD_ERR_ARG);
}

/* Every cut of a binary body is an error, never a crash or a short read
 * passed off as the whole mesh. */
static void test_every_truncation(void)
{
	struct bytes b;
	size_t header = ply_le_reference(&b);
	for (size_t len = 0; len < b.n; len++) {
		int e = mesh_error(write_bytes("cut.ply", b.d, len));
		CHECK(e != VD_OK);
		if (len >= header)
			CHECK_EQ(e, VD_ERR_TRUNCATED);
		else if (len > 3)
			CHECK(e == VD_ERR_TRUNCATED);
		else if (len > 0) /* "p", "pl": not recognisable */
			CHECK(e == VD_ERR_UNSUPPORTED ||
			      e == VD_ERR_TRUNCATED);
	}
	static struct bytes be;
	ply_be_reference(&be);
	for (size_t len = 1; len < be.n; len++)
		CHECK(mesh_error(write_bytes("cut-be.ply", be.d, len)) != VD_OK);
	size_t full = stl_bin_reference(&b, "binary");
	CHECK_EQ(mesh_error(write_bytes("cut.stl", b.d, 0)), VD_ERR_EMPTY);
	for (size_t len = 1; len < full; len++)
		CHECK_EQ(mesh_error(write_bytes("cut.stl", b.d, len)),
			 VD_ERR_TRUNCATED);
	stl_bin_reference(&b, "solid but binary");
	for (size_t len = 84; len < full; len++)
		CHECK_EQ(mesh_error(write_bytes("cut-solid.bin", b.d, len)),
			 VD_ERR_TRUNCATED);
}

/* Every byte of every fixture replaced by a few telling values: any
 * outcome but a crash, a hang or an error without a detail. Run under ASan
 * this is a small deterministic fuzzer. */
static void corrupt_each_byte(const char *name, const unsigned char *d,
			      size_t n)
{
	static const unsigned char vals[] = {0x00, 0xff, '\n', '9', ' ', '-'};
	unsigned char *c = malloc(n);
	for (size_t i = 0; i < n; i++)
		for (size_t v = 0; v < sizeof vals; v++) {
			memcpy(c, d, n);
			c[i] = vals[v];
			int e = mesh_error(write_bytes(name, c, n));
			CHECK(e >= VD_OK && e < VD_ERR_COUNT_);
			if (e != VD_OK && vd_error_detail()[0] == 0) {
				fprintf(stderr, "%s: byte %zu = %02x: no "
					"detail\n", name, i, vals[v]);
				CHECK(0);
			}
		}
	free(c);
}

static void test_corrupt_bytes(void)
{
	static struct bytes b;
	ply_le_reference(&b);
	corrupt_each_byte("fz-le.ply", b.d, b.n);
	ply_be_reference(&b);
	corrupt_each_byte("fz-be.ply", b.d, b.n);
	stl_bin_reference(&b, "solid binary");
	corrupt_each_byte("fz.stl", b.d, b.n);
	corrupt_each_byte("fz-ascii.ply",
			  (const unsigned char *)ply_ascii_reference,
			  strlen(ply_ascii_reference));
	corrupt_each_byte("fz.obj", (const unsigned char *)obj_reference,
			  strlen(obj_reference));
	corrupt_each_byte("fz-ascii.stl",
			  (const unsigned char *)stl_ascii_reference,
			  strlen(stl_ascii_reference));
	corrupt_each_byte("fz.ac", (const unsigned char *)ac_nested,
			  strlen(ac_nested));
}

/* All seven encodings of the reference mesh give one triangle list, and a
 * rewind gives it again. */
static void test_formats_agree_and_rewind(void)
{
	static struct bytes b;
	const char *paths[7];
	ply_le_reference(&b);
	paths[0] = write_bytes("agree-le.ply", b.d, b.n);
	ply_be_reference(&b);
	paths[1] = write_bytes("agree-be.ply", b.d, b.n);
	paths[2] = write_text("agree-ascii.ply", ply_ascii_reference);
	paths[3] = write_text("agree.obj", obj_reference);
	stl_bin_reference(&b, "x");
	paths[4] = write_bytes("agree.stl", b.d, b.n);
	paths[5] = write_text("agree-ascii.stl", stl_ascii_reference);
	paths[6] = write_text("agree.ac", ac_reference);
	struct vd_triangle first[3];
	for (int i = 0; i < 7; i++) {
		struct vd_mesh *m;
		int e = vd_mesh_open(&m, paths[i]);
		CHECK_EQ(e, VD_OK);
		if (e)
			continue;
		struct vd_triangle t[8];
		for (int pass = 0; pass < 3; pass++) {
			size_t n = 0, k;
			/* Stop early in pass 1: rewind mid-stream too. */
			size_t stop = pass == 1 ? 2 : 8;
			while (n < stop && !(e = vd_mesh_read(m, t + n, 1, &k)) &&
			       k)
				n += k;
			CHECK_EQ(e, VD_OK);
			if (pass != 1) {
				CHECK(same_as_reference(t, n));
				CHECK_EQ(vd_mesh_stats(m)->triangles_read, 3);
			}
			if (i == 0 && pass == 0)
				memcpy(first, t, sizeof first);
			else if (pass != 1)
				CHECK(!memcmp(first, t, sizeof first));
			CHECK_EQ(vd_mesh_rewind(m), VD_OK);
			CHECK_EQ(vd_mesh_stats(m)->triangles_read, 0);
		}
		CHECK(vd_mesh_memory_bytes(m) > 0);
		vd_mesh_close(m);
	}
}

/* A failure repeats on the next read instead of resuming past it. */
static void test_error_is_sticky(void)
{
	const char *p = write_text("sticky.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n"
				   "f 1 2 3\nf 1 2 9\nf 1 2 3\n");
	struct vd_mesh *m;
	CHECK_EQ(vd_mesh_open(&m, p), VD_OK);
	struct vd_triangle t[4];
	size_t n;
	CHECK_EQ(vd_mesh_read(m, t, 4, &n), VD_ERR_RANGE);
	CHECK_EQ(vd_mesh_read(m, t, 4, &n), VD_ERR_RANGE);
	CHECK_EQ(n, 0);
	CHECK(detail_has("line 5"));
	CHECK_EQ(vd_mesh_rewind(m), VD_OK);
	CHECK_EQ(vd_mesh_read(m, t, 1, &n), VD_OK);
	CHECK_EQ(n, 1);
	CHECK_EQ(vd_mesh_read(m, t, 0, &n), VD_ERR_ARG);
	vd_mesh_close(m);
}

/* Counts and an order-sensitive hash of the triangles of a whole pass. */
static int pass_hash(struct vd_mesh *m, uint64_t *count, uint64_t *hash)
{
	static struct vd_triangle buf[5000];
	size_t n;
	int e;
	*count = 0;
	*hash = 1469598103934665603ULL;
	while (!(e = vd_mesh_read(m, buf, 5000, &n)) && n) {
		*count += n;
		const unsigned char *p = (const unsigned char *)buf;
		for (size_t i = 0; i < n * sizeof *buf; i++)
			*hash = (*hash ^ p[i]) * 1099511628211ULL;
	}
	return e;
}

static void check_real(const char *path, uint64_t triangles,
		       uint64_t vertices)
{
	struct vd_mesh *m;
	CHECK_EQ(vd_mesh_open(&m, path), VD_OK);
	if (!m)
		return;
	uint64_t n1, h1, n2, h2;
	CHECK_EQ(pass_hash(m, &n1, &h1), VD_OK);
	CHECK_EQ(n1, triangles);
	CHECK_EQ(vd_mesh_stats(m)->vertices, vertices);
	CHECK_EQ(vd_mesh_stats(m)->faces_dropped_short, 0);
	CHECK(vd_mesh_memory_bytes(m) >= vertices * 12);
	CHECK_EQ(vd_mesh_rewind(m), VD_OK);
	CHECK_EQ(pass_hash(m, &n2, &h2), VD_OK);
	CHECK_EQ(n2, triangles);
	CHECK(h1 == h2);
	vd_mesh_close(m);
}

static void test_bunny(void)
{
	check_real("tests/data/bunny.ply", 69451, 34834);
}

static char dragon_path[600];

static void test_shared_dragon(void)
{
	check_real(dragon_path, 11102, 5203);
}

/* FlightGear's Boeing 777-200LR, fetched by config/fetch-boeing.sh. */
static const char *const boeing_path = "out/data/boeing777/77L.ac";

static void test_boeing(void)
{
	check_real(boeing_path, 6830, 3954);
}

/* ------------------------------------------------------- vertex spill */

/* What the coloured comparison saw of the reference's attributes, so a
 * test can require that the colour paths were exercised at all. */
struct spill_seen {
	long long textured;   /* triangles with a texture */
	long long vcol;       /* corners coloured but not grey or a texture */
};

/* Reads `path` twice in lockstep, without a limit and with a vertex limit
 * of `cap` bytes spilling to `dir` (read in batches of `batch`), then
 * rewinds the spilled reader and compares a second pass: the same
 * triangles in the same order, the same statistics. With `colours` both
 * are opened with colours and read with vd_mesh_read_attr: the same
 * attributes too (every byte), and `seen` (may be NULL) counts what the
 * reference's attributes hold. Returns the number of triangles, or -1
 * after a failed CHECK. */
static long long spill_compare_opts(const char *path, uint64_t cap,
				    size_t batch, int colours,
				    struct spill_seen *seen)
{
	struct vd_mesh *a = NULL, *b = NULL;
	struct vd_mesh_open_opts oa = {.colours = colours};
	struct vd_mesh_open_opts ob = {.colours = colours,
				       .max_vertex_bytes = cap,
				       .spill_dir = dir};
	int e1 = vd_mesh_open_opts(&a, path, &oa);
	int e2 = vd_mesh_open_opts(&b, path, &ob);
	CHECK_EQ(e1, VD_OK);
	CHECK_EQ(e2, VD_OK);
	if (e1 || e2) {
		fprintf(stderr, "%s: %s\n", path, vd_error_detail());
		vd_mesh_close(a);
		vd_mesh_close(b);
		return -1;
	}
	static struct vd_triangle ta[4096], tb[4096];
	static struct vd_tri_attr aa[4096], ab[4096];
	long long total = 0, bad = 0;
	if (seen)
		memset(seen, 0, sizeof *seen);
	for (int pass = 0; pass < 2 && !bad; pass++) {
		CHECK_EQ(vd_mesh_rewind(a), VD_OK);
		if (pass)
			CHECK_EQ(vd_mesh_rewind(b), VD_OK);
		size_t na = 0, ia = 0;
		total = 0;
		for (;;) {
			/* a reads in big batches, b in `batch`es: they meet
			 * triangle by triangle */
			size_t nb = 0;
			int eb = colours ? vd_mesh_read_attr(b, tb, ab, batch, &nb)
					 : vd_mesh_read(b, tb, batch, &nb);
			CHECK_EQ(eb, VD_OK);
			if (eb) {
				fprintf(stderr, "%s: %s\n", path, vd_error_detail());
				bad = 1;
				break;
			}
			for (size_t i = 0; i < nb; i++) {
				if (ia == na) {
					ia = 0;
					CHECK_EQ(colours
						 ? vd_mesh_read_attr(a, ta, aa, 4096, &na)
						 : vd_mesh_read(a, ta, 4096, &na),
						 VD_OK);
					if (na == 0) {
						bad = 1;
						break;
					}
				}
				if (memcmp(&ta[ia], &tb[i], sizeof tb[i]) != 0)
					bad = 1;
				if (colours && memcmp(&aa[ia], &ab[i],
						      sizeof ab[i]) != 0)
					bad = 1;
				if (colours && seen && pass == 0) {
					seen->textured += aa[ia].texture >= 0;
					for (int j = 0; j < 3; j++)
						seen->vcol += aa[ia].texture < 0 &&
							(aa[ia].rgb[j][0] != VD_GREY ||
							 aa[ia].rgb[j][1] != VD_GREY ||
							 aa[ia].rgb[j][2] != VD_GREY);
				}
				ia++;
				total++;
			}
			if (nb == 0 || bad)
				break;
		}
		if (!bad && ia == na)
			CHECK_EQ(colours ? vd_mesh_read_attr(a, ta, aa, 4096, &na)
				 : vd_mesh_read(a, ta, 4096, &na), VD_OK);
		CHECK(!bad && (ia < na ? 0 : na == 0));
		if (bad)
			fprintf(stderr, "%s: spilled triangles differ near %lld "
				"(pass %d)\n", path, total, pass);
		const struct vd_mesh_stats *sa = vd_mesh_stats(a),
					   *sb = vd_mesh_stats(b);
		CHECK_EQ(sa->triangles_read, sb->triangles_read);
		CHECK_EQ(sa->vertices, sb->vertices);
		CHECK_EQ(sa->faces_dropped_short, sb->faces_dropped_short);
		CHECK_EQ(sa->polygons_split, sb->polygons_split);
		CHECK_EQ(vd_mesh_has_colours(a), vd_mesh_has_colours(b));
		CHECK_EQ(vd_mesh_textures_loaded(a), vd_mesh_textures_loaded(b));
	}
	/* the spill is bounded: at most its 1 MiB floor and the buffers,
	 * besides the decoded textures both readers hold */
	size_t texels = 0;
	for (int i = 0; i < 256; i++) {
		const struct vd_texture *t = vd_mesh_texture(b, i);
		if (t)
			texels += 3 * (size_t)t->width * t->height;
	}
	CHECK(vd_mesh_memory_bytes(b) < (cap > (1u << 20) ? cap : 1u << 20) +
	      (2u << 20) + texels);
	vd_mesh_close(a);
	vd_mesh_close(b);
	return bad ? -1 : total;
}

static long long spill_compare(const char *path, uint64_t cap, size_t batch)
{
	return spill_compare_opts(path, cap, batch, 0, NULL);
}

/* An OBJ with each triangle's vertices just before it (so a limit is
 * passed mid-file, after triangles were handed out), negative and
 * positive indices, quads, a degenerate face, a nan vertex when asked. */
static const char *write_interleaved_obj(const char *name, int n, int nan_at)
{
	const char *p = fixture_path(name);
	FILE *f = fopen(p, "w");
	CHECK(f != NULL);
	if (!f)
		return p;
	for (int i = 0; i < n; i++) {
		double x = (i * 7919 % 1000) / 10.0, y = (i * 104729 % 997) / 9.0;
		if (i == nan_at)
			fprintf(f, "v nan 0 0\n");
		else
			fprintf(f, "v %.4f %.4f %.4f\n", x, y, i * 0.01);
		fprintf(f, "v %.4f %.4f %.4f\nv %.4f %.4f %.4f\n", y, x, 1.0,
			x + 1, y - 1, -i * 0.02);
		if (i % 5 == 0)
			fprintf(f, "v 1 2 3\nf -4 -3 -2 -1\n");
		else if (i % 7 == 0)
			fprintf(f, "f %d %d\n", 3 * i + i / 5 + 1, 3 * i + i / 5 + 2);
		else if (i > 3)
			fprintf(f, "f -3 -2 -1 %d\n", (i * 31) % (3 * i) + 1);
		else
			fprintf(f, "f -3 -2 -1\n");
	}
	CHECK(fclose(f) == 0);
	return p;
}

static void test_spill_bundled(void)
{
	/* 34,834 vertices: a limit of one vertex, seven runs per sort */
	long long n = spill_compare("tests/data/bunny.ply", 12, 1000);
	CHECK_EQ(n, 69451);
	/* OBJ passing its limit after a few hundred triangles, read in
	 * batches that straddle the switch */
	const char *obj = write_interleaved_obj("spill.obj", 20000, -1);
	CHECK(spill_compare(obj, 12 * 1000, 77) > 20000);
	CHECK(spill_compare(obj, 12 * 1000, 4096) > 20000);
	/* an ASCII PLY */
	const char *ply = write_text("spill-ascii.ply",
		"ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\n"
		"property float y\nproperty float z\nelement face 3\n"
		"property list uchar int vertex_indices\nend_header\n"
		"0 0 0\n1 0 0\n1 1 0\n0 1 0\n0 0 1\n"
		"4 0 1 2 3\n3 4 3 0\n3 2 4 1\n");
	CHECK_EQ(spill_compare(ply, 12, 1), 4);
}

/* An OBJ like write_interleaved_obj's, with colours: two materials of
 * their own colour (an MTL beside it), every third vertex coloured
 * ("v x y z r g b"), corners with texture coordinates or without, faces
 * with no material before the first usemtl and after an unknown one. */
/* Writes `mtl` as NAME.mtl and opens OBJ file NAME with its mtllib line:
 * the caller writes the rest and closes it. NULL after a failed CHECK. */
static FILE *open_obj_with_mtl(const char *name, const char *mtl)
{
	char path[64];
	snprintf(path, sizeof path, "%s.mtl", name);
	FILE *f = fopen(fixture_path(path), "w");
	CHECK(f != NULL);
	if (!f)
		return NULL;
	fputs(mtl, f);
	CHECK(fclose(f) == 0);
	f = fopen(fixture_path(name), "w");
	CHECK(f != NULL);
	if (f)
		fprintf(f, "mtllib %s\n", path);
	return f;
}

static const char *write_coloured_obj(const char *name, int n)
{
	FILE *f = open_obj_with_mtl(name, "newmtl red\nKd 0.9 0.1 0.1\n"
				    "newmtl sea\nKd 0.1 0.4 0.8\n");
	const char *p = fixture_path(name);
	if (!f)
		return p;
	int vt = 0;
	for (int i = 0; i < n; i++) {
		double x = (i * 7919 % 1000) / 10.0, y = (i * 104729 % 997) / 9.0;
		if (i % 97 == 10)
			fprintf(f, "usemtl %s\n", i % 3 ? "red" : i % 2 ? "sea"
				: "none");
		fprintf(f, "v %.4f %.4f %.4f %.3f %.3f %.3f\n", x, y, i * 0.01,
			(i % 10) / 9.0, (i % 7) / 6.0, (i % 3) / 2.0);
		fprintf(f, "v %.4f %.4f %.4f\nv %.4f %.4f %.4f\n", y, x, 1.0,
			x + 1, y - 1, -i * 0.02);
		fprintf(f, "vt %.3f %.3f\nvt %.3f %.3f\n", (i % 13) / 12.0,
			(i % 11) / 10.0, (i % 5) / 4.0, 0.5);
		vt += 2;
		if (i % 5 == 0)
			fprintf(f, "v 1 2 3\nf -4/-1 -3/-2 -2/-1 -1/%d\n", vt);
		else if (i % 3 == 0)
			fprintf(f, "f -3//1 -2//1 -1//1\n");
		else if (i > 3)
			fprintf(f, "f -3/-2 -2/-1 -1/-2 %d/%d\n",
				(i * 31) % (3 * i) + 1, 1 + i % vt);
		else
			fprintf(f, "f -3 -2 -1\n");
	}
	CHECK(fclose(f) == 0);
	return p;
}

/* Colours through the spill: vertex colours (PLY at open, OBJ switching
 * mid-file), materials, per-corner texture coordinates and textures give
 * the same vd_tri_attr, byte for byte, as the in-memory reader. */
static void test_spill_colours(void)
{
	struct spill_seen seen;
	/* PLY vertex colours: a limit of one 16-byte record */
	CHECK_EQ(spill_compare_opts("tests/data/textured/vcol.ply", 16, 1, 1,
				    &seen), 4);
	CHECK(seen.vcol == 12);
	/* OBJ with vt, MTL and textures (five JPEGs), switching to the
	 * spill after about 100 of its 762 vertices */
	long long n = spill_compare_opts("tests/data/spider/spider.obj",
					 16 * 100, 100, 1, &seen);
	CHECK(n > 1000);
	CHECK(seen.textured == n);
	/* the small textured scene: spilled from its first vertex */
	CHECK(spill_compare_opts("tests/data/textured/scene.obj", 16, 3, 1,
				 &seen) > 0);
	CHECK(seen.textured > 0);
	/* coloured vertices and materials, switching mid-file in batches
	 * that straddle the switch */
	const char *obj = write_coloured_obj("spill-col.obj", 6000);
	CHECK(spill_compare_opts(obj, 16 * 1000, 77, 1, &seen) > 6000);
	CHECK(seen.vcol > 1000);
	CHECK(spill_compare_opts(obj, 16 * 1000, 4096, 1, &seen) > 6000);
	/* and the bunny, opened with colours but having none */
	CHECK_EQ(spill_compare_opts("tests/data/bunny.ply", 12, 1000, 1,
				    &seen), 69451);
	CHECK(seen.vcol == 0 && seen.textured == 0);
}

/* A non-finite vertex: the same error from the join as from memory. */
/* STL is not indexed, so it never spills: an ASCII STL over a tiny limit
 * is refused as before, not handed out as its first triangle over and
 * over (the spill's fuzz check found that); under a real limit it reads
 * as in memory. */
static void test_spill_stl_refused(void)
{
	const char *p = write_text("spill.stl",
		"solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n"
		"vertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n"
		"facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n"
		"vertex 0 0 1\nendloop\nendfacet\nendsolid t\n");
	struct vd_mesh_open_opts o = {.max_vertex_bytes = 12,
				      .spill_dir = dir};
	struct vd_mesh *m = NULL;
	int e = vd_mesh_open_opts(&m, p, &o);
	struct vd_triangle t[4];
	size_t n = 0;
	if (!e) {
		e = vd_mesh_read(m, t, 4, &n);
		vd_mesh_close(m);
	}
	CHECK_EQ(e, VD_ERR_BUDGET);
	CHECK_EQ(spill_compare(p, 1 << 20, 1), 2);
}

static void test_spill_nonfinite(void)
{
	const char *obj = write_interleaved_obj("spill-nan.obj", 3000, 2500);
	char want[512] = "", got[512] = "";
	for (int k = 0; k < 2; k++) {
		struct vd_mesh *m;
		CHECK_EQ(k ? vd_mesh_open_spill(&m, obj, 1200, dir)
			   : vd_mesh_open(&m, obj), VD_OK);
		struct vd_triangle t[256];
		size_t n;
		int e;
		while ((e = vd_mesh_read(m, t, 256, &n)) == VD_OK && n)
			;
		CHECK_EQ(e, VD_ERR_RANGE);
		snprintf(k ? got : want, 512, "%s", vd_error_detail());
		vd_mesh_close(m);
	}
	CHECK(strstr(want, "whose position is not finite") != NULL);
	if (strcmp(want, got))
		fprintf(stderr, "memory: %s\nspill:  %s\n", want, got);
	CHECK(strcmp(want, got) == 0);
}

/* The shared scenes, when present, spilled with a limit of 64 KiB. */
static void test_spill_shared(void)
{
	static const char *const names[] = {"stanford_bunny.ply",
					    "cgal_fandisk.ply",
					    "oa_am_underworks2.ply",
					    "stanford_dragon_res2.ply"};
	int found = 0;
	for (size_t i = 0; i < sizeof names / sizeof *names; i++) {
		char path[1024];
		snprintf(path, sizeof path, "%s/%s", test_shared_data(), names[i]);
		struct stat st;
		if (stat(path, &st) != 0)
			continue;
		found++;
		CHECK(spill_compare(path, 64 << 10, 4096) > 0);
	}
	if (!found)
		printf("SKIP test_spill_shared: no meshes in %s\n",
		       test_shared_data());
}

/* --------------------------------------------- spilled vt and AC3D */

/* The bundled checker texture, as an absolute path (fixtures are written
 * elsewhere). */
static const char *checker_png(void)
{
	static char path[4096];
	if (!path[0] && !realpath("tests/data/textured/checker.png", path))
		snprintf(path, sizeof path, "checker.png");
	return path;
}

/* An OBJ with three vt per vertex (so vt pass a vertex limit before the
 * vertices do), a textured and a plain material, and faces with relative
 * and absolute vt indices, some reaching far back, corners without vt,
 * v//vn and v/vt/vn corners and quads. n vertices, 3n vt. */
static const char *write_vt_obj(const char *name, int n)
{
	char text[600];
	snprintf(text, sizeof text, "newmtl tex\nKd 1 1 1\nmap_Kd %s\n"
		 "newmtl plain\nKd 0.2 0.5 0.9\n", checker_png());
	FILE *f = open_obj_with_mtl(name, text);
	const char *p = fixture_path(name);
	if (!f)
		return p;
	for (int i = 0; i < n; i++) {
		if (i % 50 == 0)
			fprintf(f, "usemtl %s\n", i / 50 % 3 == 2 ? "plain" : "tex");
		fprintf(f, "v %.4f %.4f %.4f\n", (i * 7919 % 1000) / 10.0,
			(i * 104729LL % 997) / 9.0, (i % 89) * 0.5);
		for (int k = 0; k < 3; k++)
			fprintf(f, "vt %.4f %.4f\n", (i * 31 + k * 17) % 1000 / 250.0,
				(i * 13 + k * 7) % 997 / 997.0);
		if (i < 3)
			continue;
		int vt = 3 * (i + 1);
		switch (i % 6) {
		case 0:
			fprintf(f, "f -3/-1 -2/-4 -1/-2\n");
			break;
		case 1:
			fprintf(f, "f %d/%d -2/-3 -1/%d\n", i / 2 + 1,
				(i * 37) % vt + 1, vt - 1);
			break;
		case 2:
			fprintf(f, "f -4/-1 -3/-2 -2/-3 -1/-6\n");
			break;
		case 3:
			fprintf(f, "f -3/-1 -2 -1/-2\n");
			break;
		case 4:
			fprintf(f, "f -3//1 -2//1 -1//1\n");
			break;
		default:
			fprintf(f, "f -3/-1/1 -2/%d/1 -1/-3/1\n", 1 + i % 5);
		}
	}
	CHECK(fclose(f) == 0);
	return p;
}

/* What reading `path` to the end gives, as one line: the number of
 * triangles and a hash of their bytes (with colours: of their attributes
 * too), then the error code and detail. A spill of `cap` bytes when cap
 * is not 0. */
static void read_outcome(const char *path, uint64_t cap, int colours,
			 char *out, size_t outsize)
{
	struct vd_mesh *m;
	struct vd_mesh_open_opts o = {.colours = colours,
				      .max_vertex_bytes = cap,
				      .spill_dir = cap ? dir : NULL};
	int e = vd_mesh_open_opts(&m, path, &o);
	uint64_t h = 1469598103934665603ull, n = 0;
	if (!e) {
		static struct vd_triangle t[64];
		static struct vd_tri_attr a[64];
		size_t k;
		while (!(e = colours ? vd_mesh_read_attr(m, t, a, 64, &k)
				     : vd_mesh_read(m, t, 64, &k)) && k) {
			const unsigned char *b[2] = {(const void *)t,
						     (const void *)a};
			size_t len[2] = {k * sizeof *t,
					 colours ? k * sizeof *a : 0};
			for (int j = 0; j < 2; j++)
				for (size_t i = 0; i < len[j]; i++)
					h = (h ^ b[j][i]) * 1099511628211ull;
			n += k;
		}
		vd_mesh_close(m);
	}
	snprintf(out, outsize, "%" PRIu64 " triangles %016" PRIx64 "; %d %s",
		 n, h, e, e ? vd_error_detail() : "");
}

/* Reading `path` spilled (a limit of `cap` bytes) ends as in memory: the
 * same error, with the same detail. The triangles before it are not
 * compared: the spill reads the whole file before it hands any out. */
static int same_error_spilled(const char *path, uint64_t cap, int colours)
{
	char want[700], got[700];
	read_outcome(path, 0, colours, want, sizeof want);
	read_outcome(path, cap, colours, got, sizeof got);
	const char *w = strchr(want, ';'), *g = strchr(got, ';');
	if (!strcmp(w, g))
		return 1;
	fprintf(stderr, "%s\nmemory:%s\nspill: %s\n", path, w + 1, g + 1);
	return 0;
}

/* OBJ texture coordinates share the vertices' limit and, over it, are
 * joined with the corners on disk: the same triangles and attributes
 * (every uv byte) as in memory, within the limit. */
static void test_spill_vt(void)
{
	struct spill_seen seen;
	/* 60,000 vertices of 16 bytes (0.92 MiB) fit a limit of 1.25 MiB,
	 * but their 180,000 vt (1.37 MiB) do not */
	const char *obj = write_vt_obj("spill-vt.obj", 60000);
	uint64_t cap = 5 << 18;
	struct vd_mesh *m;
	struct vd_mesh_open_opts o = {.colours = 1, .max_vertex_bytes = cap};
	CHECK_EQ(vd_mesh_open_opts(&m, obj, &o), VD_OK);
	struct vd_triangle t[256];
	struct vd_tri_attr a[256];
	size_t n;
	int e;
	while ((e = vd_mesh_read_attr(m, t, a, 256, &n)) == VD_OK && n)
		;
	CHECK_EQ(e, VD_ERR_BUDGET);
	CHECK(detail_has("texture coordinates need more than 1280 KiB"));
	vd_mesh_close(m);
	/* spilled by the vt, read in batches that straddle the switch */
	long long tris = spill_compare_opts(obj, cap, 77, 1, &seen);
	CHECK(tris > 60000);
	CHECK(seen.textured > tris / 3 && seen.textured < tris);
	CHECK(spill_compare_opts(obj, cap, 4096, 1, &seen) == tris);
	/* spilled from the first vertex, and switching early */
	CHECK(spill_compare_opts(obj, 16, 4096, 1, &seen) == tris);
	CHECK(spill_compare_opts(obj, 16 * 1000, 1000, 1, &seen) == tris);
	/* without colours vt are not read: the vertices fit */
	o.colours = 0;
	CHECK_EQ(vd_mesh_open_opts(&m, obj, &o), VD_OK);
	while ((e = vd_mesh_read(m, t, 256, &n)) == VD_OK && n)
		;
	CHECK_EQ(e, VD_OK);
	vd_mesh_close(m);
	CHECK(spill_compare(obj, cap, 4096) == tris);
}

/* A vt error while spilled: the in-memory message, face and line, from
 * the first vertex on and after a switch mid-file; a file cut anywhere
 * reads as in memory. */
/* Every cut of buf (len bytes) written to `name` reads the same in
 * memory as spilled at `cap` bytes: triangles, attributes and error.
 * Returns the number of cuts that differ (at most 3 are looked for). */
static int cuts_disagree(const char *name, const char *buf, size_t len,
			 uint64_t cap)
{
	int bad = 0;
	for (size_t k = 1; k <= len && bad < 3; k++) {
		char w[700], g[700];
		const char *p = write_bytes(name, buf, k);
		read_outcome(p, 0, 1, w, sizeof w);
		read_outcome(p, cap, 1, g, sizeof g);
		if (strcmp(w, g)) {
			fprintf(stderr, "cut at %zu:\nmemory: %s\nspill:  %s\n",
				k, w, g);
			bad++;
		}
	}
	return bad;
}

static void test_spill_vt_errors(void)
{
	static const char *const faces[] = {
		"f 1/1 2/2 3/4\n",       /* past the end */
		"f 1/1 2/-4 3/3\n",      /* relative, before the first */
		"f 1/1 2/0 3/3\n",       /* 0 */
		"f 1/1 2/2 3/x\n",       /* malformed */
	};
	static const char *const want[] = {
		"line 10: face 2: texture coordinate index 4 out of range "
		"(3 defined so far)",
		"line 10: face 2: texture coordinate index -4 out of range "
		"(3 defined so far)",
		"line 10: face 2: texture coordinate index 0 out of range "
		"(3 defined so far)",
		"line 10: malformed face corner '3/x'"};
	char text[512], name[32];
	for (size_t i = 0; i < sizeof faces / sizeof *faces; i++) {
		snprintf(text, sizeof text, "mtllib spill-vt.obj.mtl\n"
			 "usemtl tex\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
			 "vt 0 0\nf 1/1 2/-1 3/1\nvt 1 0\nvt 0 1\n%s"
			 "f 1/1 2/2 3/3\n", faces[i]);
		snprintf(name, sizeof name, "spill-vt-bad%zu.obj", i);
		const char *p = write_text(name, text);
		CHECK(same_error_spilled(p, 16, 1));
		char got[700];
		read_outcome(p, 16, 1, got, sizeof got);
		if (!strstr(got, want[i]))
			fprintf(stderr, "%s lacks '%s'\n", got, want[i]);
		CHECK(strstr(got, want[i]) != NULL);
	}
	/* after the switch: the bad face at the end of a file that passes
	 * the limit near its start */
	const char *obj = write_vt_obj("spill-vt-late.obj", 3000);
	FILE *f = fopen(obj, "a");
	CHECK(f != NULL);
	if (f) {
		fprintf(f, "f 1/1 2/2 3/9001\n");
		CHECK(fclose(f) == 0);
	}
	CHECK(same_error_spilled(obj, 16 * 200, 1));
	char got[700];
	read_outcome(obj, 16 * 200, 1, got, sizeof got);
	CHECK(strstr(got, "texture coordinate index 9001 out of range "
		      "(9000 defined so far)") != NULL);
	/* cut at every length: the same triangles, attributes and error */
	const char *whole = write_vt_obj("spill-vt-cut.obj", 16);
	FILE *in = fopen(whole, "rb");
	static char buf[8192];
	size_t len = in ? fread(buf, 1, sizeof buf, in) : 0;
	if (in)
		fclose(in);
	CHECK(len > 600 && len < sizeof buf);
	CHECK_EQ(cuts_disagree("spill-vt-cut.obj", buf, len, 16), 0);
}

/* An AC3D file of small objects around one of `n` x `n` vertices
 * (textured, with quads, strips, a line, under a rotated and moved
 * parent): the small ones fit a limit the big one passes. */
static const char *write_big_ac(const char *name, int n)
{
	const char *p = fixture_path(name);
	FILE *f = fopen(p, "w");
	CHECK(f != NULL);
	if (!f)
		return p;
	fprintf(f, "AC3Db\nMATERIAL \"red\" rgb 0.9 0.1 0.1  amb 0.2 0.2 0.2"
		"  emis 0 0 0  spec 0 0 0  shi 10  trans 0\n"
		"MATERIAL \"sea\" rgb 0.1 0.4 0.8  amb 0.2 0.2 0.2  emis 0 0 0"
		"  spec 0 0 0  shi 10  trans 0\nOBJECT world\nkids 3\n");
	fprintf(f, "OBJECT poly\nname \"small\"\nloc 1 2 3\nnumvert 4\n"
		"0 0 0\n10 0 0\n10 10 0\n0 10 5\nnumsurf 1\nSURF 0x10\nmat 1\n"
		"refs 4\n0 0 0\n1 1 0\n2 1 1\n3 0 1\nkids 0\n");
	fprintf(f, "OBJECT group\nname \"parent\"\nrot 0 1 0 -1 0 0 0 0 1\n"
		"loc 5 -3 1\nkids 2\n");
	fprintf(f, "OBJECT poly\nname \"big\"\ntexture \"%s\"\ntexrep 2 3\n"
		"texoff 0.5 0\nloc 0 0 2\nnumvert %d\n", checker_png(), n * n);
	for (int j = 0; j < n; j++)
		for (int i = 0; i < n; i++)
			fprintf(f, "%d %d %.3f\n", i, j,
				20 * sin(i / 37.0) * cos(j / 23.0));
	int s = 3, c = (n - 1) / s;
	fprintf(f, "numsurf %d\n", c * c + 1);
	for (int j = 0; j < c; j++)
		for (int i = 0; i < c; i++) {
			int a = s * (j * n + i), b = a + s, d = a + s * n,
			    e = d + s;
			if (i % 5 == 3)
				fprintf(f, "SURF 0x14\nmat %d\nrefs 4\n%d 0 0\n"
					"%d 1 0\n%d 0 1\n%d 1 1\n", (i + j) % 2,
					a, b, d, e);
			else if (i % 7 == 2)
				fprintf(f, "SURF 0x10\nmat 0\nrefs 3\n%d\n%d\n"
					"%d\n", a, b, e);
			else
				fprintf(f, "SURF 0x10\nmat %d\nrefs 4\n%d 0 0\n"
					"%d 0.%d 0\n%d 1 1\n%d 0 1\n",
					(i + j) % 2, a, b, i % 10, e, d);
		}
	fprintf(f, "SURF 0x12\nmat 0\nrefs 2\n0 0 0\n1 1 1\nkids 0\n");
	fprintf(f, "OBJECT poly\nname \"after\"\nnumvert 3\n0 0 0\n1 0 0\n"
		"0 1 0\nnumsurf 1\nSURF 0x10\nmat 0\nrefs 3\n0\n1\n2\nkids 0\n");
	fprintf(f, "OBJECT poly\nname \"last\"\nnumvert 4\n0 0 0\n1 0 0\n"
		"0 1 0\n1 1 1\nnumsurf 1\nSURF 0x10\nmat 1\nrefs 3\n3\n1\n2\n"
		"kids 0\n");
	CHECK(fclose(f) == 0);
	return p;
}

/* A TORCS .acc file with short kids counts (test_acc_short_kids) reads
 * the same spilled as in memory. */
static void test_spill_acc_short_kids(void)
{
	char *w = strdup(ac_nested), *k = strstr(w, "kids 2\n");
	k[5] = '5';
	const char *acc = write_text("spill-short.acc", w);
	for (int col = 0; col < 2; col++)
		CHECK_EQ(spill_compare_opts(acc, 12, 1, col, NULL), 5);
	free(w);
}

/* AC3D objects over the limit are joined with their surfaces on disk
 * (once over, the whole file is): the same triangles and attributes as
 * in memory, within the limit; errors as in memory. */
static void test_spill_ac3d(void)
{
	struct spill_seen seen;
	const char *nested = write_text("spill-nested.ac", ac_nested);
	for (int col = 0; col < 2; col++) {
		CHECK_EQ(spill_compare_opts(nested, 12, 1, col, NULL), 5);
		CHECK_EQ(spill_compare_opts(nested, 12 * 4, 2, col, NULL), 5);
	}
	CHECK_EQ(spill_compare_opts("tests/data/textured/scene.ac", 12, 1, 1,
				    &seen), 3);
	CHECK_EQ(seen.textured, 2);
	/* 90,000 vertices (1.03 MiB) over a limit of 1 MiB, after an object
	 * that fits; read in batches that straddle the switch */
	const char *big = write_big_ac("spill-big.ac", 300);
	struct vd_mesh *m;
	CHECK_EQ(vd_mesh_open_limited(&m, big, 1 << 20), VD_OK);
	struct vd_triangle t[256];
	size_t n;
	int e;
	while ((e = vd_mesh_read(m, t, 256, &n)) == VD_OK && n)
		;
	CHECK_EQ(e, VD_ERR_BUDGET);
	vd_mesh_close(m);
	long long tris = spill_compare_opts(big, 1 << 20, 1, 1, &seen);
	CHECK(tris > 10000);
	CHECK(seen.textured > tris / 2 && seen.textured < tris);
	CHECK(spill_compare_opts(big, 1 << 20, 4096, 1, &seen) == tris);
	CHECK(spill_compare_opts(big, 1 << 20, 77, 0, NULL) == tris);
	CHECK(spill_compare_opts(big, 12, 4096, 1, &seen) == tris);
	/* errors in the second object, after the switch: a ref past its
	 * vertices (valid in the first), a non-finite vertex (its index is
	 * the object's own), a cut file */
	static const char *const second[] = {
		"numvert 3\n0 0 0\n1 0 0\n0 1 0\nnumsurf 1\nSURF 0\nrefs 3\n"
		"0\n1\n3\nkids 0\n",
		"numvert 3\n0 0 0\n1 nan 0\n0 1 0\nnumsurf 1\nSURF 0\nrefs 3\n"
		"0\n2\n1\nkids 0\n"};
	static const char *const want[] = {
		"line 30: surface 2: vertex index 3 out of range (object "
		"'second' has 3 vertices)",
		"line 26: face 2 uses vertex 1 whose position is not finite"};
	for (int i = 0; i < 2; i++) {
		char text[1024], got[700];
		snprintf(text, sizeof text, "AC3Db\nOBJECT world\nkids 2\n"
			 "OBJECT poly\nname \"first\"\nnumvert 4\n0 0 0\n"
			 "1 0 0\n0 1 0\n1 1 1\nnumsurf 1\nSURF 0\nrefs 4\n0\n"
			 "1\n2\n3\nkids 0\nOBJECT poly\nname \"second\"\n%s",
			 second[i]);
		const char *p = write_text("spill-bad.ac", text);
		CHECK(same_error_spilled(p, 12 * 4, 0));
		CHECK(same_error_spilled(p, 12, 1));
		read_outcome(p, 12 * 4, 0, got, sizeof got);
		if (!strstr(got, want[i]))
			fprintf(stderr, "%s lacks '%s'\n", got, want[i]);
		CHECK(strstr(got, want[i]) != NULL);
	}
	CHECK_EQ(cuts_disagree("spill-cut.ac", ac_nested, strlen(ac_nested),
			       12), 0);
}

int main(void)
{
	dir = test_tmpdir("mesh");
	RUN(test_ply_binary_le);
	RUN(test_spill_bundled);
	RUN(test_spill_nonfinite);
	RUN(test_spill_stl_refused);
	RUN(test_spill_colours);
	RUN(test_spill_shared);
	RUN(test_spill_vt);
	RUN(test_spill_vt_errors);
	RUN(test_spill_ac3d);
	RUN(test_spill_acc_short_kids);
	RUN(test_ply_binary_be);
	RUN(test_ply_ascii);
	RUN(test_obj);
	RUN(test_stl_binary);
	RUN(test_stl_ascii);
	RUN(test_ply_integer_coordinates);
	RUN(test_short_and_long_faces);
	RUN(test_obj_forward_reference);
	RUN(test_obj_bad_indices);
	RUN(test_malformed_numbers);
	RUN(test_non_finite);
	RUN(test_ply_header_errors);
	RUN(test_list_counts);
	RUN(test_ac3d);
	RUN(test_ac3d_errors);
	RUN(test_ac3d_every_truncation);
	RUN(test_acc_short_kids);
	RUN(test_long_lines);
	RUN(test_not_meshes);
	RUN(test_every_truncation);
	RUN(test_corrupt_bytes);
	RUN(test_formats_agree_and_rewind);
	RUN(test_error_is_sticky);
	RUN(test_bunny);
	snprintf(dragon_path, sizeof dragon_path, "%s/stanford_dragon_res4.ply",
		 test_shared_data());
	struct stat st;
	if (stat(dragon_path, &st) == 0)
		RUN(test_shared_dragon);
	else
		printf("SKIP test_shared_dragon (%s absent)\n", dragon_path);
	if (stat(boeing_path, &st) == 0)
		RUN(test_boeing);
	else
		printf("SKIP test_boeing (%s absent; config/fetch-boeing.sh "
		       "fetches it)\n", boeing_path);
	return CHECK_DONE();
}
