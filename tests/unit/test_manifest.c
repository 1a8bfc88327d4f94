/* test_manifest.c - directory manifests (stages/lib/io/manifest.c,
 * schemas/manifest.md). The reference is xxhash itself: the manifest a
 * directory gets is compared byte for byte with the text the test builds
 * from XXH3_64bits over each file's bytes (read by the test, sorted by the
 * test), and the digest vd_manifest_verify gives with XXH3 of the
 * manifest's bytes. Then every damage the spec names gets its own error
 * and detail: a file missing, short, long, changed, unlisted; the manifest
 * missing, empty, cut at every length, with a wrong first line, unsorted
 * or malformed lines; vd_manifest_check_file on one file; and a directory
 * published whole (staging, exchange, foreign files, dead runs'
 * leftovers). */
#include "check.h"
#include "voxdag.h"

#include <errno.h>
#include <limits.h>
#include <sys/stat.h>
#include <unistd.h>
#include <xxhash.h>

static const char *root;

static void write_bytes(const char *path, const void *data, size_t n)
{
	FILE *f = fopen(path, "wb");
	CHECK(f != NULL);
	if (f) {
		CHECK_EQ(fwrite(data, 1, n, f), n);
		CHECK_EQ(fclose(f), 0);
	}
}

static void write_text(const char *path, const char *text)
{
	write_bytes(path, text, strlen(text));
}

/* The whole file (malloc'd, NUL-terminated) and its size. */
/* root/name, in a buffer of its own (path_of's are reused). */
static const char *dir_of(const char *name)
{
	static char d[700];
	snprintf(d, sizeof d, "%s/%s", root, name);
	return d;
}

/* The detail of the last error is exactly `want` (printed when not). */
static int detail_is(const char *want)
{
	int same = !strcmp(vd_error_detail(), want);
	if (!same)
		fprintf(stderr, "detail: %s\n  want: %s\n", vd_error_detail(),
			want);
	vd_error_clear();
	return same;
}

/* The fixture: five files listed, their contents chosen so that sizes
 * differ (0, 1, 5 bytes, 100000 > the 64 KiB read buffer) and names
 * sort in byte order ('Z' before 'a'), plus two that are never listed. */
#define NFILES 4
static const char *names[NFILES] = {"Z", "a.col", "b.svo", "empty"};
static uint8_t big[100000];

static void fill_dir(const char *d)
{
	char cmd[800];
	snprintf(cmd, sizeof cmd, "rm -rf '%s' && mkdir -p '%s'", d, d);
	CHECK_EQ(system(cmd), 0);
	for (size_t i = 0; i < sizeof big; i++)
		big[i] = (uint8_t)(i * 2654435761u >> 13);
	write_text(test_path(d, "Z"), "z");
	write_text(test_path(d, "a.col"), "hello");
	write_bytes(test_path(d, "b.svo"), big, sizeof big);
	write_text(test_path(d, "empty"), "");
	write_text(test_path(d, ".key"), "hidden: the runner's");
	write_text(test_path(d, "x.tmp.123"), "a temporary");
}

/* The manifest of fill_dir's directory, from XXH3 over the bytes the test
 * wrote (names already in byte order). */
static void expected_manifest(char *buf, size_t cap)
{
	const void *data[NFILES] = {"z", "hello", big, ""};
	size_t size[NFILES] = {1, 5, sizeof big, 0};
	size_t at = (size_t)snprintf(buf, cap, "voxdag-manifest 1\n");
	for (int i = 0; i < NFILES; i++)
		at += (size_t)snprintf(buf + at, cap - at, "%016llx %zu %s\n",
				       (unsigned long long)XXH3_64bits(data[i],
								       size[i]),
				       size[i], names[i]);
}

static void test_file_xxh3(void)
{
	const char *d = dir_of("xxh3");
	fill_dir(d);
	uint64_t h = 0, n = 0;
	CHECK_EQ(vd_file_xxh3(test_path(d, "b.svo"), &h, &n), VD_OK);
	CHECK(h == XXH3_64bits(big, sizeof big));
	CHECK_EQ(n, sizeof big);
	CHECK_EQ(vd_file_xxh3(test_path(d, "empty"), &h, &n), VD_OK);
	CHECK(h == XXH3_64bits("", 0));
	CHECK_EQ(n, 0);
	char want[900];
	snprintf(want, sizeof want, "cannot open '%s': %s",
		 test_path(d, "absent"), strerror(ENOENT));
	CHECK_EQ(vd_file_xxh3(test_path(d, "absent"), &h, &n), VD_ERR_IO);
	CHECK(detail_is(want));
}

static void test_write(void)
{
	const char *d = dir_of("write");
	fill_dir(d);
	CHECK_EQ(vd_manifest_write(d), VD_OK);
	char want[2048];
	expected_manifest(want, sizeof want);
	size_t len = 0;
	char *got = test_slurp(test_path(d, VD_MANIFEST_NAME), &len);
	CHECK(got && !strcmp(got, want));
	if (got && strcmp(got, want))
		fprintf(stderr, "got:\n%s\nwant:\n%s", got, want);
	/* no temporary left beside it */
	char tmp[800];
	snprintf(tmp, sizeof tmp, "%s.tmp.%ld", test_path(d, VD_MANIFEST_NAME),
		 (long)getpid());
	CHECK(access(tmp, F_OK) != 0);
	/* the digest stands for the manifest's bytes */
	uint64_t digest = 0;
	CHECK_EQ(vd_manifest_verify(d, &digest), VD_OK);
	CHECK(got && digest == XXH3_64bits(got, len));
	CHECK_EQ(vd_manifest_verify(d, NULL), VD_OK);
	/* written again over an unchanged directory: the same bytes (the
	 * old manifest is not listed in the new one) */
	CHECK_EQ(vd_manifest_write(d), VD_OK);
	char *again = test_slurp(test_path(d, VD_MANIFEST_NAME), NULL);
	CHECK(got && again && !strcmp(got, again));
	/* one changed byte changes the digest */
	write_text(test_path(d, "a.col"), "hellO");
	CHECK_EQ(vd_manifest_write(d), VD_OK);
	uint64_t d2 = digest;
	CHECK_EQ(vd_manifest_verify(d, &d2), VD_OK);
	CHECK(d2 != digest);
	free(got);
	free(again);
}

/* What the manifest cannot list: no manifest written, no temporary. */
static void test_write_refuses(void)
{
	const char *d = dir_of("refuse");
	fill_dir(d);
	CHECK_EQ(mkdir(test_path(d, "sub"), 0777), 0);
	char want[900];
	snprintf(want, sizeof want, "'%s' is not a regular file",
		 test_path(d, "sub"));
	CHECK_EQ(vd_manifest_write(d), VD_ERR_UNSUPPORTED);
	CHECK(detail_is(want));
	CHECK(access(test_path(d, VD_MANIFEST_NAME), F_OK) != 0);
	CHECK_EQ(rmdir(test_path(d, "sub")), 0);
	CHECK_EQ(symlink("Z", test_path(d, "link")), 0);
	snprintf(want, sizeof want, "'%s' is not a regular file",
		 test_path(d, "link"));
	CHECK_EQ(vd_manifest_write(d), VD_ERR_UNSUPPORTED);
	CHECK(detail_is(want));
	CHECK(access(test_path(d, VD_MANIFEST_NAME), F_OK) != 0);
	const char *gone = test_path(root, "no-such-dir");
	snprintf(want, sizeof want, "cannot open '%s': %s", gone,
		 strerror(ENOENT));
	CHECK_EQ(vd_manifest_write(gone), VD_ERR_IO);
	CHECK(detail_is(want));
}

/* A fresh directory with its manifest, for one damage each. */
static const char *fresh(const char *name)
{
	const char *d = dir_of(name);
	fill_dir(d);
	CHECK_EQ(vd_manifest_write(d), VD_OK);
	return d;
}

/* Damage to the files the manifest lists, or a file it does not. */
static void test_verify_files(void)
{
	char want[900];
	const char *d = fresh("files");
	char b[800];
	snprintf(b, sizeof b, "%s", test_path(d, "b.svo"));
	/* missing */
	CHECK_EQ(unlink(b), 0);
	snprintf(want, sizeof want, "'%s', listed in the manifest, is missing", b);
	CHECK_EQ(vd_manifest_verify(d, NULL), VD_ERR_TRUNCATED);
	CHECK(detail_is(want));
	/* one byte short */
	write_bytes(b, big, sizeof big - 1);
	snprintf(want, sizeof want, "'%s' has 99999 bytes, the manifest says "
		 "100000", b);
	CHECK_EQ(vd_manifest_verify(d, NULL), VD_ERR_TRUNCATED);
	CHECK(detail_is(want));
	/* one byte long */
	FILE *f = fopen(b, "ab");
	CHECK(f != NULL);
	if (f) {
		fputc(big[sizeof big - 1], f);
		fputc(0, f);
		fclose(f);
	}
	snprintf(want, sizeof want, "'%s' has 100001 bytes, the manifest says "
		 "100000", b);
	CHECK_EQ(vd_manifest_verify(d, NULL), VD_ERR_TRAILING);
	CHECK(detail_is(want));
	/* the right size, the last byte changed (past the first 64 KiB
	 * read, so the whole file must be hashed) */
	big[sizeof big - 1] ^= 1;
	write_bytes(b, big, sizeof big);
	big[sizeof big - 1] ^= 1;
	snprintf(want, sizeof want, "'%s' does not match its checksum in the "
		 "manifest", b);
	CHECK_EQ(vd_manifest_verify(d, NULL), VD_ERR_CHECKSUM);
	CHECK(detail_is(want));
	write_bytes(b, big, sizeof big);
	CHECK_EQ(vd_manifest_verify(d, NULL), VD_OK);
	/* a file the manifest does not list, sorted first, between, last */
	const char *extra[] = {"0first", "aa", "zz"};
	for (int i = 0; i < 3; i++) {
		write_text(test_path(d, extra[i]), "x");
		snprintf(want, sizeof want, "'%s/%s' is not in the manifest", d,
			 extra[i]);
		CHECK_EQ(vd_manifest_verify(d, NULL), VD_ERR_CORRUPT);
		CHECK(detail_is(want));
		CHECK_EQ(unlink(test_path(d, extra[i])), 0);
	}
	/* hidden files and temporaries are not part of the output */
	write_text(test_path(d, ".other"), "x");
	write_text(test_path(d, "b.svo.tmp.77"), "x");
	CHECK_EQ(vd_manifest_verify(d, NULL), VD_OK);
	/* a directory where a listed file was */
	CHECK_EQ(unlink(test_path(d, "Z")), 0);
	CHECK_EQ(mkdir(test_path(d, "Z"), 0777), 0);
	snprintf(want, sizeof want, "'%s' is not a regular file", test_path(d, "Z"));
	CHECK_EQ(vd_manifest_verify(d, NULL), VD_ERR_UNSUPPORTED);
	CHECK(detail_is(want));
}

/* Replaces the manifest of d with `text`. */
static void set_manifest(const char *d, const char *text, size_t n)
{
	write_bytes(test_path(d, VD_MANIFEST_NAME), text, n);
}

/* The manifest cut at every length fails, each cut with its error: no
 * bytes is "empty"; inside a line, that line is cut; at a line end, the
 * files of the lines lost are not in the manifest. */
static void test_manifest_cut(void)
{
	const char *d = fresh("cut");
	char full[2048], want[900];
	expected_manifest(full, sizeof full);
	size_t len = strlen(full);
	const char *mpath = test_path(d, VD_MANIFEST_NAME);
	char mp[800];
	snprintf(mp, sizeof mp, "%s", mpath);
	int bad = 0;
	/* cuts inside line 1 (the magic): test_first_line_number */
	size_t magic = strlen("voxdag-manifest 1\n");
	for (size_t cut = 0; cut < len; cut++) {
		if (cut > 0 && cut < magic)
			continue;
		set_manifest(d, full, cut);
		int err = vd_manifest_verify(d, NULL);
		size_t lines = 0; /* whole lines kept */
		for (size_t i = 0; i < cut; i++)
			lines += full[i] == '\n';
		int ok;
		if (cut == 0) {
			snprintf(want, sizeof want, "'%s' is empty", mp);
			ok = err == VD_ERR_TRUNCATED && detail_is(want);
		} else if (full[cut - 1] != '\n') {
			snprintf(want, sizeof want, "'%s': line %zu is cut or "
				 "too long", mp, lines + 1);
			ok = err == VD_ERR_CORRUPT && detail_is(want);
		} else {
			/* line 1 is the magic: files[lines - 1] is the first
			 * one lost */
			snprintf(want, sizeof want, "'%s/%s' is not in the "
				 "manifest", d, names[lines - 1]);
			ok = err == VD_ERR_CORRUPT && detail_is(want);
		}
		if (!ok && bad++ < 3)
			fprintf(stderr, "cut at %zu: error %d\n", cut, err);
		vd_error_clear();
	}
	CHECK_EQ(bad, 0);
	set_manifest(d, full, len);
	CHECK_EQ(vd_manifest_verify(d, NULL), VD_OK);
	/* no manifest at all */
	CHECK_EQ(unlink(mp), 0);
	snprintf(want, sizeof want, "'%s' has no manifest (its writer did not "
		 "finish)", d);
	CHECK_EQ(vd_manifest_verify(d, NULL), VD_ERR_TRUNCATED);
	CHECK(detail_is(want));
}

/* A manifest cut inside its first line (the magic) names line 1 (it was
 * reported as line 2: the count was right for entry lines only). */
static void test_first_line_number(void)
{
	const char *d = fresh("firstline");
	char want[900], mp[800];
	snprintf(mp, sizeof mp, "%s", test_path(d, VD_MANIFEST_NAME));
	set_manifest(d, "voxdag-manif", 12);
	snprintf(want, sizeof want, "'%s': line 1 is cut or too long", mp);
	CHECK_EQ(vd_manifest_verify(d, NULL), VD_ERR_CORRUPT);
	CHECK(detail_is(want));
}

/* Malformed manifests: each is VD_ERR_CORRUPT naming the line. */
static void test_manifest_malformed(void)
{
	const char *d = fresh("malformed");
	char full[2048], text[2048], want[900], mp[800];
	expected_manifest(full, sizeof full);
	snprintf(mp, sizeof mp, "%s", test_path(d, VD_MANIFEST_NAME));
	/* the lines of `full`: [0] magic, [1..4] the files */
	char lines[5][200];
	const char *at = full;
	for (int i = 0; i < 5; i++) {
		const char *nl = strchr(at, '\n');
		snprintf(lines[i], sizeof lines[i], "%.*s", (int)(nl - at), at);
		at = nl + 1;
	}
	/* another version, or not a manifest */
	snprintf(text, sizeof text, "voxdag-manifest 2\n%s\n", lines[1]);
	set_manifest(d, text, strlen(text));
	snprintf(want, sizeof want, "'%s' is not a voxdag manifest (first line "
		 "'voxdag-manifest 2')", mp);
	CHECK_EQ(vd_manifest_verify(d, NULL), VD_ERR_CORRUPT);
	CHECK(detail_is(want));
	/* two lines swapped: not sorted at the second of them (line 3) */
	snprintf(text, sizeof text, "%s\n%s\n%s\n%s\n%s\n", lines[0], lines[2],
		 lines[1], lines[3], lines[4]);
	set_manifest(d, text, strlen(text));
	snprintf(want, sizeof want, "'%s': names not sorted at line 3", mp);
	CHECK_EQ(vd_manifest_verify(d, NULL), VD_ERR_CORRUPT);
	CHECK(detail_is(want));
	/* a line twice */
	snprintf(text, sizeof text, "%s\n%s\n%s\n%s\n%s\n%s\n", lines[0],
		 lines[1], lines[2], lines[2], lines[3], lines[4]);
	set_manifest(d, text, strlen(text));
	snprintf(want, sizeof want, "'%s': names not sorted at line 4", mp);
	CHECK_EQ(vd_manifest_verify(d, NULL), VD_ERR_CORRUPT);
	CHECK(detail_is(want));
	/* line 2 replaced by each malformed line */
	const char *badl[] = {
		"0123456789abcdef 1",            /* no name */
		"0123456789abcdef 1 ",           /* no name either */
		"xyz 1 Z",                       /* not hex */
		"0123456789abcdef Z",            /* no size */
		"0123456789abcdef 1 ../Z",       /* a path, not a name */
		"0123456789abcdef 1 manifest",   /* the manifest itself */
		"0123456789abcdef 1 .key",       /* hidden */
		"0123456789abcdef 1 Z.tmp.1",    /* a temporary */
		"",                              /* empty */
	};
	for (size_t i = 0; i < sizeof badl / sizeof *badl; i++) {
		snprintf(text, sizeof text, "%s\n%s\n%s\n", lines[0], badl[i],
			 lines[2]);
		set_manifest(d, text, strlen(text));
		snprintf(want, sizeof want, "'%s': line 2 is not 'CHECKSUM SIZE "
			 "NAME'", mp);
		int err = vd_manifest_verify(d, NULL);
		CHECK_EQ(err, VD_ERR_CORRUPT);
		if (!detail_is(want))
			fprintf(stderr, "  line: '%s'\n", badl[i]);
	}
	/* a line longer than the reader's 512 bytes: cut or too long */
	char name[600];
	memset(name, 'q', sizeof name - 1);
	name[sizeof name - 1] = 0;
	snprintf(text, sizeof text, "%s\n0123456789abcdef 1 %s\n", lines[0], name);
	set_manifest(d, text, strlen(text));
	snprintf(want, sizeof want, "'%s': line 2 is cut or too long", mp);
	CHECK_EQ(vd_manifest_verify(d, NULL), VD_ERR_CORRUPT);
	CHECK(detail_is(want));
	/* a well-formed manifest with one checksum digit changed */
	snprintf(text, sizeof text, "%s", full);
	char *b = strstr(text, " b.svo\n");
	/* b is at the ' ' before the name: "HEX 100000 b.svo" */
	char *hex = b ? b - 6 - 1 - 16 : text;
	CHECK(b && hex[16] == ' ');
	hex[0] = hex[0] == '0' ? '1' : '0';
	set_manifest(d, text, strlen(text));
	snprintf(want, sizeof want, "'%s' does not match its checksum in the "
		 "manifest", test_path(d, "b.svo"));
	CHECK_EQ(vd_manifest_verify(d, NULL), VD_ERR_CHECKSUM);
	CHECK(detail_is(want));
}

/* schemas/manifest.md: a line's checksum is 16 lower-case hex digits.
 * "%16llx %llu" alone took "1" (one digit), a "0x" prefix, a 17th digit
 * (read as the size, the size then as the name), and the reader went on
 * to blame a file ("does not match its checksum", "is missing"). Such a
 * line is malformed and refused as one. */
static void test_loose_checksum_field(void)
{
	const char *d = fresh("loose");
	char full[2048], text[2048], want[900], mp[800];
	expected_manifest(full, sizeof full);
	snprintf(mp, sizeof mp, "%s", test_path(d, VD_MANIFEST_NAME));
	/* line 2 is Z's: "HEX 1 Z"; the rest of the manifest after it */
	const char *rest = strchr(strchr(full, '\n') + 1, '\n') + 1;
	char hex[17];
	memcpy(hex, strchr(full, '\n') + 1, 16);
	hex[16] = 0;
	char lines[3][64];
	snprintf(lines[0], sizeof lines[0], "1 1 Z");
	snprintf(lines[1], sizeof lines[1], "0x%.14s 1 Z", hex + 2);
	snprintf(lines[2], sizeof lines[2], "%s0 1 Z", hex);
	snprintf(want, sizeof want, "'%s': line 2 is not 'CHECKSUM SIZE NAME'",
		 mp);
	for (int i = 0; i < 3; i++) {
		snprintf(text, sizeof text, "voxdag-manifest 1\n%s\n%s",
			 lines[i], rest);
		set_manifest(d, text, strlen(text));
		int err = vd_manifest_verify(d, NULL);
		CHECK_EQ(err, VD_ERR_CORRUPT);
		if (!detail_is(want))
			fprintf(stderr, "  line: '%s'\n", lines[i]);
	}
}

/* One file against the manifest beside it (encode's encodings). */
static void test_check_file(void)
{
	char want[900];
	const char *d = fresh("check");
	CHECK_EQ(vd_manifest_check_file(test_path(d, "b.svo")), VD_OK);
	CHECK_EQ(vd_manifest_check_file(test_path(d, "empty")), VD_OK);
	/* damage to another file is not this one's */
	write_text(test_path(d, "Z"), "y");
	CHECK_EQ(vd_manifest_check_file(test_path(d, "a.col")), VD_OK);
	snprintf(want, sizeof want, "'%s' does not match its checksum in the "
		 "manifest", test_path(d, "Z"));
	CHECK_EQ(vd_manifest_check_file(test_path(d, "Z")), VD_ERR_CHECKSUM);
	CHECK(detail_is(want));
	write_text(test_path(d, "new"), "x");
	snprintf(want, sizeof want, "'%s' is not in the manifest beside it",
		 test_path(d, "new"));
	CHECK_EQ(vd_manifest_check_file(test_path(d, "new")), VD_ERR_CORRUPT);
	CHECK(detail_is(want));
	/* no manifest: the way out is named */
	CHECK_EQ(unlink(test_path(d, VD_MANIFEST_NAME)), 0);
	snprintf(want, sizeof want, "no manifest beside '%s' to check it "
		 "against (encode writes one; for a file from elsewhere, use "
		 "--no-verify)", test_path(d, "a.col"));
	CHECK_EQ(vd_manifest_check_file(test_path(d, "a.col")), VD_ERR_UNSUPPORTED);
	CHECK(detail_is(want));
	/* an empty one is damage, not absence */
	set_manifest(d, "", 0);
	snprintf(want, sizeof want, "'%s' is empty", test_path(d, VD_MANIFEST_NAME));
	CHECK_EQ(vd_manifest_check_file(test_path(d, "a.col")), VD_ERR_TRUNCATED);
	CHECK(detail_is(want));
}

static int count_entries(const char *d)
{
	char cmd[800];
	snprintf(cmd, sizeof cmd, "ls -A '%s' | wc -l", d);
	FILE *p = popen(cmd, "r");
	int n = -1;
	if (p) {
		if (fscanf(p, "%d", &n) != 1)
			n = -1;
		pclose(p);
	}
	return n;
}

/* A directory output published whole: staged beside the final name,
 * exchanged in one step, the old one gone; leftovers of dead runs
 * removed, a live run's kept; a directory holding a file no manifest
 * lists is never replaced. */
static void test_publish(void)
{
	char final[700], staging[800], want[1200], parent[600];
	snprintf(parent, sizeof parent, "%s/pub/deeper", root);
	snprintf(final, sizeof final, "%s/out", parent);
	/* a dead run's leftover (no process has that pid: above pid_max)
	 * and a live run's (our parent's), beside it */
	char dead[800], live[800];
	snprintf(dead, sizeof dead, "%s.tmp.99999999", final);
	snprintf(live, sizeof live, "%s.tmp.%ld", final, (long)getppid());
	CHECK_EQ(vd_dir_stage(final, NULL, staging, sizeof staging), VD_OK);
	char expect[800];
	snprintf(expect, sizeof expect, "%s.tmp.%ld", final, (long)getpid());
	CHECK(!strcmp(staging, expect));
	write_text(test_path(staging, "one"), "1");
	write_text(test_path(staging, "two"), "2");
	CHECK_EQ(vd_dir_publish(staging, final), VD_OK);
	CHECK(access(staging, F_OK) != 0);
	CHECK_EQ(vd_manifest_verify(final, NULL), VD_OK);
	CHECK_EQ(count_entries(final), 3); /* one, two, manifest */
	/* again, over it, with a trailing '/' and leftovers beside it */
	CHECK_EQ(mkdir(dead, 0777), 0);
	write_text(test_path(dead, "junk"), "j");
	CHECK_EQ(mkdir(live, 0777), 0);
	char given[800];
	snprintf(given, sizeof given, "%s/", final);
	CHECK_EQ(vd_dir_stage(given, NULL, staging, sizeof staging), VD_OK);
	CHECK(!strcmp(staging, expect));
	CHECK(access(dead, F_OK) != 0);
	CHECK(access(live, F_OK) == 0);
	write_text(test_path(staging, "three"), "3");
	CHECK_EQ(vd_dir_publish(staging, final), VD_OK);
	CHECK_EQ(vd_manifest_verify(final, NULL), VD_OK);
	CHECK_EQ(count_entries(final), 2); /* three, manifest: the old gone */
	CHECK(access(test_path(final, "one"), F_OK) != 0);
	CHECK(access(staging, F_OK) != 0);
	rmdir(live);
	/* a file the manifest does not list: the user's */
	write_text(test_path(final, "mine.txt"), "keep");
	snprintf(want, sizeof want, "'%s' holds 'mine.txt', which this tool "
		 "did not write; give a new or empty output directory", final);
	CHECK_EQ(vd_dir_stage(final, NULL, staging, sizeof staging), VD_ERR_IO);
	CHECK(detail_is(want));
	char *keep = test_slurp(test_path(final, "mine.txt"), NULL);
	CHECK(keep && !strcmp(keep, "keep"));
	free(keep);
	/* a file where the directory should be */
	snprintf(want, sizeof want, "'%s' exists and is not a directory",
		 test_path(final, "mine.txt"));
	CHECK_EQ(vd_dir_stage(test_path(final, "mine.txt"), NULL, staging,
			      sizeof staging), VD_ERR_IO);
	CHECK(detail_is(want));
	/* abandoning a staging directory removes it and keeps the detail */
	CHECK_EQ(unlink(test_path(final, "mine.txt")), 0);
	CHECK_EQ(vd_dir_stage(final, NULL, staging, sizeof staging), VD_OK);
	write_text(test_path(staging, "half"), "h");
	vd_fail(VD_ERR_IO, "the caller's reason");
	vd_dir_abandon(staging);
	CHECK(access(staging, F_OK) != 0);
	CHECK(detail_is("the caller's reason"));
	CHECK_EQ(vd_manifest_verify(final, NULL), VD_OK);
}

int main(void)
{
	root = test_tmpdir("test_manifest");
	RUN(test_file_xxh3);
	RUN(test_write);
	RUN(test_write_refuses);
	RUN(test_verify_files);
	RUN(test_manifest_cut);
	RUN(test_first_line_number);
	RUN(test_manifest_malformed);
	RUN(test_loose_checksum_field);
	RUN(test_check_file);
	RUN(test_publish);
	return CHECK_DONE();
}
