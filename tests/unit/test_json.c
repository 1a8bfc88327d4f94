/* test_json.c - the statistics writer (stages/lib/io/json.c), judged by a
 * second reader: what vd_json_* writes is parsed back with libjansson (the
 * reader report.c uses) and every value, type and member count compared
 * with what was written; one small file is also compared byte for byte
 * with text written out by hand, so the layout (and the escaping of
 * characters a parser would accept either way) is pinned. Also: the file
 * appears only at close (nothing under the final name before, the old
 * file intact until then, no temporary after), and each failure (a
 * missing directory, a directory in the way) is one error with its exact
 * detail and leaves nothing behind. */
#include "check.h"
#include "voxdag.h"

#include <errno.h>
#include <jansson.h>
#include <math.h>
#include <sys/stat.h>
#include <unistd.h>

static const char *dir;

/* The whole file as a string (malloc'd), NULL when it cannot be read. */
static json_t *load(const char *path)
{
	json_error_t e;
	json_t *root = json_load_file(path, JSON_REJECT_DUPLICATES, &e);
	if (!root)
		fprintf(stderr, "%s:%d:%d: %s\n", path, e.line, e.column, e.text);
	return root;
}

/* Integers beyond 2^53 catch a writer that goes through a double; jansson
 * holds integers in a long long, so 2^63 - 1 is the largest it reads. */
#define BIG_ODD ((1ull << 53) + 1)

static const double f64s[] = {0.5, -2.5, 1e-7, 1234567.0, 3.0};

/* Every kind of value, nested, parsed back and compared. */
static void test_roundtrip(void)
{
	const char *p = test_path(dir, "all.json");
	struct vd_json *j = NULL;
	CHECK_EQ(vd_json_open(&j, p), VD_OK);
	if (!j)
		return;
	vd_json_u64(j, "zero", 0);
	vd_json_u64(j, "big_odd", BIG_ODD);
	vd_json_u64(j, "max_jansson", INT64_MAX);
	vd_json_array(j, "reals");
	for (size_t i = 0; i < sizeof f64s / sizeof *f64s; i++)
		vd_json_f64(j, NULL, f64s[i]);
	vd_json_end_array(j);
	vd_json_f64(j, "nan", NAN);
	vd_json_f64(j, "inf", -INFINITY);
	vd_json_str(j, "text", "say \"hi\"\\ to\ttab\nline\x01 caf\xc3\xa9");
	vd_json_str(j, "empty", "");
	vd_json_object(j, "nested");
	vd_json_u64(j, "a", 7);
	vd_json_object(j, "deeper");
	vd_json_str(j, "b", "x");
	vd_json_end_object(j);
	vd_json_u64(j, "after", 8);
	vd_json_end_object(j);
	vd_json_array(j, "objects");
	for (uint64_t i = 0; i < 3; i++) {
		vd_json_object(j, NULL);
		vd_json_u64(j, "i", i);
		vd_json_end_object(j);
	}
	vd_json_end_array(j);
	const uint64_t counts[] = {1, 8, 64, BIG_ODD};
	vd_json_u64_array(j, "counts", counts, 4);
	vd_json_u64_array(j, "none", counts, 0);
	vd_json_array(j, "empty_array");
	vd_json_end_array(j);
	vd_json_object(j, "empty_object");
	vd_json_end_object(j);
	vd_json_u64(j, "last", 42);
	CHECK_EQ(vd_json_close(j), VD_OK);

	json_t *r = load(p);
	CHECK(json_is_object(r));
	if (!json_is_object(r))
		return;
	/* 15 members written at the top level, no more, no fewer */
	CHECK_EQ(json_object_size(r), 15);
	json_t *v = json_object_get(r, "zero");
	CHECK(json_is_integer(v) && json_integer_value(v) == 0);
	v = json_object_get(r, "big_odd");
	CHECK(json_is_integer(v) && (uint64_t)json_integer_value(v) == BIG_ODD);
	v = json_object_get(r, "max_jansson");
	CHECK(json_is_integer(v) && json_integer_value(v) == INT64_MAX);
	v = json_object_get(r, "reals");
	CHECK(json_is_array(v) && json_array_size(v) == 5);
	for (size_t i = 0; json_is_array(v) && i < json_array_size(v) && i < 5;
	     i++) {
		json_t *x = json_array_get(v, i);
		/* json.c writes 6 significant digits ("%.6g"): each value
		 * within half a unit of the 6th; those with fewer digits
		 * exactly. 3.0 is written "3", an integer token, which is why
		 * readers must take either (report.c: json_number_value). */
		CHECK(json_is_number(x));
		double got = json_number_value(x), want = f64s[i];
		CHECK(fabs(got - want) <= 5e-6 * fabs(want));
		if (i != 3)
			CHECK(got == want);
	}
	CHECK(json_number_value(json_array_get(v, 3)) == 1234570.0);
	CHECK(json_is_integer(json_array_get(v, 4)));
	CHECK(json_is_null(json_object_get(r, "nan")));
	CHECK(json_is_null(json_object_get(r, "inf")));
	v = json_object_get(r, "text");
	CHECK(json_is_string(v) &&
	      !strcmp(json_string_value(v),
		      "say \"hi\"\\ to\ttab\nline\x01 caf\xc3\xa9"));
	v = json_object_get(r, "empty");
	CHECK(json_is_string(v) && !strcmp(json_string_value(v), ""));
	json_t *n = json_object_get(r, "nested");
	CHECK(json_is_object(n) && json_object_size(n) == 3);
	CHECK_EQ(json_integer_value(json_object_get(n, "a")), 7);
	CHECK_EQ(json_integer_value(json_object_get(n, "after")), 8);
	json_t *dd = json_object_get(n, "deeper");
	CHECK(json_is_object(dd) && json_object_size(dd) == 1);
	CHECK(json_is_string(json_object_get(dd, "b")) &&
	      !strcmp(json_string_value(json_object_get(dd, "b")), "x"));
	v = json_object_get(r, "objects");
	CHECK(json_is_array(v) && json_array_size(v) == 3);
	for (size_t i = 0; json_is_array(v) && i < json_array_size(v); i++) {
		json_t *o = json_array_get(v, i);
		CHECK(json_is_object(o) && json_object_size(o) == 1);
		CHECK_EQ(json_integer_value(json_object_get(o, "i")), i);
	}
	v = json_object_get(r, "counts");
	CHECK(json_is_array(v) && json_array_size(v) == 4);
	for (size_t i = 0; json_is_array(v) && i < 4; i++)
		CHECK((uint64_t)json_integer_value(json_array_get(v, i)) ==
		      counts[i]);
	v = json_object_get(r, "none");
	CHECK(json_is_array(v) && json_array_size(v) == 0);
	v = json_object_get(r, "empty_array");
	CHECK(json_is_array(v) && json_array_size(v) == 0);
	v = json_object_get(r, "empty_object");
	CHECK(json_is_object(v) && json_object_size(v) == 0);
	CHECK_EQ(json_integer_value(json_object_get(r, "last")), 42);
	json_decref(r);
}

/* The layout, written out by hand: two spaces per depth, ", " between
 * u64_array items, a string's quote, backslash and control characters
 * escaped (\u00XX for the latter) and nothing else (a space stays a
 * space, a byte >= 0x80 stays itself). */
static void test_exact_bytes(void)
{
	const char *p = test_path(dir, "exact.json");
	struct vd_json *j = NULL;
	CHECK_EQ(vd_json_open(&j, p), VD_OK);
	if (!j)
		return;
	vd_json_str(j, "s", "a \"b\"\\\n\x1f\xc3\xa9");
	vd_json_object(j, "o");
	vd_json_f64(j, "x", 0.25);
	vd_json_end_object(j);
	const uint64_t v[] = {3, 2};
	vd_json_u64_array(j, "v", v, 2);
	CHECK_EQ(vd_json_close(j), VD_OK);
	char *text = test_slurp(p, NULL);
	const char *want =
		"{\n"
		"  \"s\": \"a \\\"b\\\"\\\\\\u000a\\u001f\xc3\xa9\",\n"
		"  \"o\": {\n"
		"    \"x\": 0.25\n"
		"  },\n"
		"  \"v\": [3, 2]\n"
		"}\n";
	CHECK(text && !strcmp(text, want));
	if (text && strcmp(text, want))
		fprintf(stderr, "got:\n%s\nwant:\n%s\n", text, want);
	free(text);
	/* an object closed at once is "{\n}\n" and parses as {} */
	p = test_path(dir, "bare.json");
	CHECK_EQ(vd_json_open(&j, p), VD_OK);
	CHECK_EQ(vd_json_close(j), VD_OK);
	text = test_slurp(p, NULL);
	CHECK(text && !strcmp(text, "{\n}\n"));
	free(text);
	json_t *r = load(p);
	CHECK(json_is_object(r) && json_object_size(r) == 0);
	json_decref(r);
}

/* Nothing under the final name until close; an old file stays whole until
 * then and is replaced by the new one; no temporary is left. */
static void test_atomic(void)
{
	const char *p = test_path(dir, "atomic.json");
	FILE *f = fopen(p, "w");
	CHECK(f != NULL);
	if (f) {
		fputs("old", f);
		fclose(f);
	}
	struct vd_json *j = NULL;
	CHECK_EQ(vd_json_open(&j, p), VD_OK);
	if (!j)
		return;
	CHECK(test_exists(test_tmp_of(p)));
	vd_json_u64(j, "n", 1);
	char *text = test_slurp(p, NULL);
	CHECK(text && !strcmp(text, "old"));
	free(text);
	CHECK_EQ(vd_json_close(j), VD_OK);
	CHECK(!test_exists(test_tmp_of(p)));
	json_t *r = load(p);
	CHECK(json_is_object(r) &&
	      json_integer_value(json_object_get(r, "n")) == 1);
	json_decref(r);
	/* a new file: absent until close */
	p = test_path(dir, "new.json");
	CHECK_EQ(vd_json_open(&j, p), VD_OK);
	CHECK(!test_exists(p));
	CHECK_EQ(vd_json_close(j), VD_OK);
	CHECK(test_exists(p) && !test_exists(test_tmp_of(p)));
}

/* A directory that does not exist: VD_ERR_IO naming the temporary and the
 * cause; *out untouched, nothing created. */
static void test_open_missing_dir(void)
{
	const char *p = test_path(dir, "no/such/dir/s.json");
	struct vd_json *j = (struct vd_json *)&j; /* a sentinel */
	vd_error_clear();
	CHECK_EQ(vd_json_open(&j, p), VD_ERR_IO);
	CHECK(j == (struct vd_json *)&j);
	char want[800];
	snprintf(want, sizeof want, "cannot create '%s': %s", test_tmp_of(p),
		 strerror(ENOENT));
	CHECK(!strcmp(vd_error_detail(), want));
	if (strcmp(vd_error_detail(), want))
		fprintf(stderr, "detail: %s\n", vd_error_detail());
	CHECK(!test_exists(test_path(dir, "no")));
	vd_error_clear();
}

/* A directory where the file should go: close refuses to rename over it
 * (VD_ERR_IO, vd_replace_file's detail), removes its temporary, and the
 * directory is untouched. */
static void test_close_onto_directory(void)
{
	const char *p = test_path(dir, "taken.json");
	CHECK_EQ(mkdir(p, 0777), 0);
	struct vd_json *j = NULL;
	CHECK_EQ(vd_json_open(&j, p), VD_OK);
	if (!j)
		return;
	vd_json_u64(j, "n", 1);
	vd_error_clear();
	CHECK_EQ(vd_json_close(j), VD_ERR_IO);
	char want[800];
	snprintf(want, sizeof want, "'%s' exists and is not a regular file; "
		 "refusing to replace it", p);
	CHECK(!strcmp(vd_error_detail(), want));
	if (strcmp(vd_error_detail(), want))
		fprintf(stderr, "detail: %s\n", vd_error_detail());
	struct stat st;
	CHECK(stat(p, &st) == 0 && S_ISDIR(st.st_mode));
	CHECK(!test_exists(test_tmp_of(p)));
	vd_error_clear();
}

/* Objects nested `depth` levels below the top one, a member in each. */
static int nested_parses(int depth)
{
	const char *p = test_path(dir, "deep.json");
	struct vd_json *j = NULL;
	if (vd_json_open(&j, p) != VD_OK)
		return 0;
	for (int i = 0; i < depth; i++) {
		vd_json_u64(j, "n", (uint64_t)i);
		vd_json_object(j, "o");
	}
	vd_json_u64(j, "n", (uint64_t)depth);
	for (int i = 0; i < depth; i++)
		vd_json_end_object(j);
	if (vd_json_close(j) != VD_OK)
		return 0;
	json_t *r = load(p), *o = r;
	int ok = r != NULL;
	for (int i = 0; ok && i <= depth; i++) {
		ok = json_is_object(o) && json_object_size(o) ==
			(i < depth ? 2u : 1u) &&
		     json_integer_value(json_object_get(o, "n")) == i;
		o = json_object_get(o, "o");
	}
	json_decref(r);
	return ok;
}

/* json.c keeps a member count per depth for 32 depths (count[32]); 31
 * levels below the top object are within it. */
static void test_nesting_31(void)
{
	CHECK(nested_parses(31));
}

/* One level more: json.c once stopped counting depth at 31 while
 * vd_json_end_object still stepped back, so the output was not JSON
 * ("{,\n" inside the 32nd object) and the depth went below 0. */
static void test_nesting_32(void)
{
	CHECK(nested_parses(32));
}

int main(void)
{
	dir = test_tmpdir("test_json");
	RUN(test_roundtrip);
	RUN(test_exact_bytes);
	RUN(test_atomic);
	RUN(test_open_missing_dir);
	RUN(test_close_onto_directory);
	RUN(test_nesting_31);
	RUN(test_nesting_32);
	return CHECK_DONE();
}
