/* test_sources.c - the files a mesh pulls in (stages/lib/io/sources.c and
 * the reader's list, vd_mesh_sources): an OBJ's list worked out by hand
 * (MTL files, the textures of the materials faces use and not the others,
 * a missing texture, a mtllib name with spaces looked for whole), each
 * hash that of vd_file_xxh3; geometry only lists nothing; the sources file
 * written and checked back (a changed, deleted or appearing file is
 * VD_ERR_MISMATCH naming it; odd names survive), and damaged files are
 * VD_ERR_FORMAT. */
#include "check.h"
#include "voxdag.h"

#include <sys/stat.h>
#include <unistd.h>

static const char *dir;

static void write_text(const char *name, const char *text)
{
	FILE *f = fopen(test_path(dir, name), "wb");
	CHECK(f != NULL);
	if (f) {
		fputs(text, f);
		CHECK_EQ(fclose(f), 0);
	}
}

/* No texture need decode: an undecodable one is still a file read (a
 * warning), and the list is about files. */
static const char obj[] =
	"mtllib a.mtl b c.mtl\n"
	"v 0 0 0\nv 1 0 0\nv 0 1 0\n"
	"vt 0 0\nvt 1 0\nvt 0 1\n"
	"usemtl red\nf 1/1 2/2 3/3\n"
	"usemtl tex\nf 1/1 2/2 3/3\n"
	"usemtl lost\nf 1/1 2/2 3/3\n"
	"usemtl tex\nf 1/1 2/2 3/3\n"
	"usemtl zero\nf 1/1 2/2 3/3\n";

static int warnings;
static void on_warn(void *ctx, const char *line)
{
	(void)ctx;
	(void)line;
	warnings++;
}

static struct vd_mesh *read_all(const char *path, int colours)
{
	struct vd_mesh_open_opts o = {.colours = colours, .warn = on_warn};
	struct vd_mesh *m = NULL;
	CHECK_EQ(vd_mesh_open_opts(&m, path, &o), VD_OK);
	if (!m)
		return NULL;
	struct vd_triangle t[8];
	struct vd_tri_attr a[8];
	size_t n = 0;
	CHECK_EQ(colours ? vd_mesh_read_attr(m, t, a, 8, &n)
			 : vd_mesh_read(m, t, 8, &n), VD_OK);
	CHECK_EQ(n, 5);
	return m;
}

static void check_entry(const struct vd_mesh_source *s, const char *name,
			int found)
{
	CHECK(!strcmp(s->path, test_path(dir, name)));
	CHECK_EQ(s->found, found);
	uint64_t h = 0, size = 0;
	if (found) {
		CHECK_EQ(vd_file_xxh3(s->path, &h, &size), VD_OK);
	} else {
		CHECK(vd_file_xxh3(s->path, &h, &size) != VD_OK);
		vd_error_clear();
		h = size = 0;
	}
	CHECK(s->xxh3 == h);
	CHECK(s->size == size);
}

/* "mtllib a.mtl b c.mtl": no file is named all of that, so the whole name
 * is looked for in vain, then a.mtl, b (missing) and c.mtl are read.
 * Faces use red (no texture), tex (tex.png, twice), lost (gone.png,
 * missing) and zero (/dev/zero); unused (unused.png) is never read. */
static void test_obj_list(void)
{
	write_text("s.obj", obj);
	write_text("a.mtl", "newmtl red\nKd 1 0 0\nnewmtl tex\nmap_Kd tex.png\n");
	write_text("c.mtl", "newmtl lost\nmap_Kd gone.png\n"
			    "newmtl unused\nmap_Kd unused.png\n"
			    "newmtl zero\nmap_Kd /dev/zero\n");
	write_text("tex.png", "not a png");
	write_text("unused.png", "never read");
	warnings = 0;
	struct vd_mesh *m = read_all(test_path(dir, "s.obj"), 1);
	size_t n = 0;
	const struct vd_mesh_source *s = vd_mesh_sources(m, &n);
	CHECK_EQ(n, 7);
	if (n == 7) {
		check_entry(&s[0], "a.mtl b c.mtl", 0);
		check_entry(&s[1], "a.mtl", 1);
		check_entry(&s[2], "b", 0);
		check_entry(&s[3], "c.mtl", 1);
		check_entry(&s[4], "tex.png", 1);
		check_entry(&s[5], "gone.png", 0);
		/* not a regular file: never read (it has no end) */
		CHECK(!strcmp(s[6].path, "/dev/zero") && !s[6].found);
	}
	CHECK_EQ(warnings, 4); /* b, tex.png undecodable, gone.png, zero */
	vd_mesh_close(m);
	/* without colours no MTL is read */
	m = read_all(test_path(dir, "s.obj"), 0);
	CHECK(m && (vd_mesh_sources(m, &n), n == 0));
	vd_mesh_close(m);
}

/* Written, then checked against the files as they change. */
static void test_write_check(void)
{
	write_text("one", "1");
	write_text("odd\\name\nx", "2");
	struct vd_mesh_source s[3] = {
		{.path = (char *)test_path(dir, "one")},
		{.path = (char *)test_path(dir, "odd\\name\nx")},
		{.path = (char *)test_path(dir, "absent")},
	};
	char keep[3][600];
	for (int i = 0; i < 3; i++) {
		snprintf(keep[i], sizeof keep[i], "%s", s[i].path);
		s[i].path = keep[i];
		s[i].found = i < 2;
		if (s[i].found)
			CHECK_EQ(vd_file_xxh3(s[i].path, &s[i].xxh3, &s[i].size),
				 VD_OK);
	}
	char list[600];
	snprintf(list, sizeof list, "%s", test_path(dir, "sources"));
	CHECK_EQ(vd_sources_write(list, s, 3), VD_OK);
	CHECK_EQ(vd_sources_check(list), VD_OK);
	/* the same size, other bytes */
	write_text("odd\\name\nx", "3");
	CHECK_EQ(vd_sources_check(list), VD_ERR_MISMATCH);
	CHECK(strstr(vd_error_detail(), "changed") &&
	      strstr(vd_error_detail(), "odd\\name\nx"));
	vd_error_clear();
	write_text("odd\\name\nx", "2");
	CHECK_EQ(vd_sources_check(list), VD_OK);
	unlink(keep[0]);
	CHECK_EQ(vd_sources_check(list), VD_ERR_MISMATCH);
	CHECK(strstr(vd_error_detail(), "missing"));
	vd_error_clear();
	/* a FIFO in its place: unreadable, and not waited on */
	CHECK_EQ(mkfifo(keep[0], 0600), 0);
	CHECK_EQ(vd_sources_check(list), VD_ERR_MISMATCH);
	vd_error_clear();
	unlink(keep[0]);
	write_text("one", "1");
	write_text("absent", "");
	CHECK_EQ(vd_sources_check(list), VD_ERR_MISMATCH);
	CHECK(strstr(vd_error_detail(), "can be read now"));
	vd_error_clear();
	unlink(keep[2]);
	CHECK_EQ(vd_sources_check(list), VD_OK);
	/* an empty list */
	CHECK_EQ(vd_sources_write(list, NULL, 0), VD_OK);
	CHECK_EQ(vd_sources_check(list), VD_OK);
	CHECK_EQ(vd_sources_check(test_path(dir, "no such list")), VD_ERR_IO);
	vd_error_clear();
}

/* Damaged lists are VD_ERR_FORMAT, never taken for a match. */
static void test_damaged(void)
{
	write_text("one", "1");
	static const char *const bad[] = {
		"",
		"voxdag-sources 2\n",
		"voxdag-sources 1",
		"voxdag-sources 1\n- - one",
		"voxdag-sources 1\n- - \n",
		"voxdag-sources 1\nzz 1 one\n",
		"voxdag-sources 1\n0123456789ABCDEF 1 one\n",
		"voxdag-sources 1\n0123456789abcdef one\n",
		"voxdag-sources 1\n0123456789abcdef 1one\n",
		"voxdag-sources 1\n- - bad\\escape\n",
	};
	for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
		write_text("damaged", bad[i]);
		int e = vd_sources_check(test_path(dir, "damaged"));
		if (e != VD_ERR_FORMAT)
			fprintf(stderr, "case %zu: %d\n", i, e);
		CHECK_EQ(e, VD_ERR_FORMAT);
		vd_error_clear();
	}
}

int main(void)
{
	dir = test_tmpdir("sources");
	RUN(test_obj_list);
	RUN(test_write_check);
	RUN(test_damaged);
	return CHECK_DONE();
}
