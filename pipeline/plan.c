/* plan.c - expanding the job graph into processes, and resume keys.
 *
 * Layout of out/<name>/ (what each job writes):
 *   <voxelize job>/            chunk-L<L0>-<cell>.svo, voxelize.stats.json
 *   <dag job>/cells/           one .dag per cell (svo-to-dag per cell)
 *   <dag job>/L<a>-<cell>.dag  merges up the reduction tree
 *   <dag job>/root.dag         the whole scene
 *   (the same for symmetry-merge jobs, with .sdag; .ssvdag is the
 *   SymVox encoding that encode writes)
 *   <lossy or edit job>/root.dag   one process on the root DAG chunk
 *   <symmetry-merge job>/root.sdag  the same after lossy-cluster or edit
 *   <encode job>/              the encodings and tables
 *   logs/                      runner.log; <job>.log for a job that
 *                              failed or said something
 *   keys                       the key journal (below)
 * Every output has a key: the stage version, the arguments and the
 * checksums of the inputs, and the digest of the output. A job whose
 * output exists with the same key and digest is skipped (voxelize of a
 * mesh only when the files its mesh pulled in are unchanged too:
 * sources_fresh).
 */
#include "pipeline.h"
#include "io/publish.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#define XXH_INLINE_ALL
#include <xxhash.h>

void path_join(char *buf, size_t cap, const char *a, const char *b)
{
	if ((size_t)snprintf(buf, cap, "%s/%s", a, b) >= cap) {
		fprintf(stderr, "voxdag: path too long: %s/%s\n", a, b);
		exit(1);
	}
}

int mkdir_p(const char *path)
{
	char tmp[1100];
	if ((size_t)snprintf(tmp, sizeof tmp, "%s", path) >= sizeof tmp) {
		errno = ENAMETOOLONG; /* never a shorter directory instead */
		return -1;
	}
	for (char *p = tmp + 1; *p; p++)
		if (*p == '/') {
			*p = 0;
			if (mkdir(tmp, 0777) != 0 && errno != EEXIST)
				return -1;
			*p = '/';
		}
	return mkdir(tmp, 0777) != 0 && errno != EEXIST ? -1 : 0;
}

/* The directory holding the stage executables: the runner's own. */
static const char *bin_dir(void)
{
	static char dir[1024];
	if (!*dir) {
		ssize_t n = readlink("/proc/self/exe", dir, sizeof dir - 1);
		if (n <= 0) {
			strcpy(dir, "out/bin");
		} else {
			dir[n] = 0;
			char *slash = strrchr(dir, '/');
			if (slash)
				*slash = 0;
		}
	}
	return dir;
}

static void *xrealloc(void *q, size_t n)
{
	void *r = realloc(q, n ? n : 1);
	if (!r) {
		fprintf(stderr, "voxdag: out of memory\n");
		exit(1);
	}
	return r;
}

static char *xstrdup(const char *s)
{
	char *d = strdup(s);
	if (!d) {
		fprintf(stderr, "voxdag: out of memory\n");
		exit(1);
	}
	return d;
}

static uint32_t id_hash(const char *id)
{
	return (uint32_t)XXH3_64bits(id, strlen(id));
}

/* The slot of `id` in the index: where it is, or the empty slot where it
 * would go. */
static int *index_slot(const struct plan *p, const char *id)
{
	uint32_t mask = (uint32_t)p->index_cap - 1;
	for (uint32_t h = id_hash(id) & mask;; h = (h + 1) & mask) {
		int *slot = &p->index[h];
		if (!*slot || !strcmp(p->jobs[*slot - 1].id, id))
			return slot;
	}
}

int plan_find(const struct plan *p, const char *id)
{
	if (!p->index_cap)
		return -1;
	int v = *index_slot(p, id);
	return v - 1;
}

static void index_grow(struct plan *p)
{
	free(p->index);
	p->index_cap = p->index_cap ? 2 * p->index_cap : 256;
	p->index = calloc((size_t)p->index_cap, sizeof *p->index);
	if (!p->index) {
		fprintf(stderr, "voxdag: out of memory\n");
		exit(1);
	}
	for (int i = 0; i < p->n; i++)
		*index_slot(p, p->jobs[i].id) = i + 1;
}

enum { OUT_FILE, OUT_DIR };

/* Appends a job, or returns NULL when one with that id is planned. A file
 * output's statistics are its first side output: every stage that writes
 * a file writes OUTPUT.stats.json beside it (a directory output keeps its
 * statistics inside, under its manifest). */
static struct job *add_job(struct plan *p, int decl, const char *id,
			   const char *output, int kind)
{
	if (plan_find(p, id) >= 0)
		return NULL; /* already planned */
	if (2 * (p->n + 1) > p->index_cap)
		index_grow(p);
	if (p->n == p->cap) {
		p->cap = p->cap ? 2 * p->cap : 64;
		p->jobs = xrealloc(p->jobs, (size_t)p->cap * sizeof *p->jobs);
	}
	struct job *j = &p->jobs[p->n++];
	memset(j, 0, sizeof *j);
	j->log_fd = -1;
	j->decl = decl;
	j->id = xstrdup(id);
	j->output = xstrdup(output);
	j->dir_output = kind == OUT_DIR;
	if (kind == OUT_FILE) {
		size_t n = strlen(output) + sizeof ".stats.json";
		j->side[0] = xrealloc(NULL, n);
		snprintf(j->side[0], n, "%s.stats.json", output);
	}
	*index_slot(p, j->id) = p->n;
	p->unfinished[decl]++;
	p->planned[decl]++;
	return j;
}

static int job_finished(const struct job *j);

void job_set_state(struct plan *p, struct job *j, enum job_state s)
{
	int was_end = job_finished(j) || j->state == JOB_FAILED ||
		      j->state == JOB_BLOCKED;
	j->state = s;
	if (was_end || s == JOB_PENDING || s == JOB_RUNNING)
		return;
	p->unfinished[j->decl]--;
	if (j->cell)
		p->cells_left[j->decl]--;
	for (int k = 0; k < j->nrdeps; k++) {
		struct job *r = &p->jobs[j->rdeps[k]];
		if (job_finished(j))
			r->nwait--;
		else
			r->nbad++;
	}
}

/* argv[0] is the stage's path; any number of arguments (no silent cut). */
static void set_argv(struct job *j, const char *prog, ...)
{
	char path[1100];
	snprintf(path, sizeof path, "%s/%s", bin_dir(), prog);
	va_list ap;
	int n = 1;
	va_start(ap, prog);
	while (va_arg(ap, const char *))
		n++;
	va_end(ap);
	j->argv = xrealloc(NULL, ((size_t)n + 1) * sizeof *j->argv);
	j->argv[0] = xstrdup(path);
	va_start(ap, prog);
	for (int i = 1; i < n; i++)
		j->argv[i] = xstrdup(va_arg(ap, const char *));
	va_end(ap);
	j->argv[n] = NULL;
}

/* The same from a NULL-terminated list. */
static void set_argv_list(struct job *j, const char *prog, const char *const *args)
{
	int n = 0;
	while (args[n])
		n++;
	char path[1100];
	snprintf(path, sizeof path, "%s/%s", bin_dir(), prog);
	j->argv = xrealloc(NULL, ((size_t)n + 2) * sizeof *j->argv);
	j->argv[0] = xstrdup(path);
	for (int i = 0; i < n; i++)
		j->argv[i + 1] = xstrdup(args[i]);
	j->argv[n + 1] = NULL;
}

/* A symmetry-merge job of a `group: 48` declaration: --group 48 appended
 * (so the key, which hashes the command line, tells the groups apart). */
static void add_group_arg(const struct job_decl *dd, struct job *j)
{
	if (dd->stage->type != STAGE_SYMMETRY_MERGE || dd->group != 48)
		return;
	int n = 0;
	while (j->argv[n])
		n++;
	j->argv = xrealloc(j->argv, ((size_t)n + 3) * sizeof *j->argv);
	j->argv[n] = xstrdup("--group");
	j->argv[n + 1] = xstrdup("48");
	j->argv[n + 2] = NULL;
}

/* Adds inputs (files whose content the key covers). */
static void add_input(struct job *j, const char *path)
{
	j->inputs = xrealloc(j->inputs, (size_t)(j->ninputs + 1) * sizeof *j->inputs);
	j->inputs[j->ninputs++] = xstrdup(path);
}

/* j (the last job added) waits for `dep`. */
static void add_dep(struct plan *p, struct job *j, int dep)
{
	struct job *d = &p->jobs[dep];
	j->deps = xrealloc(j->deps, (size_t)(j->ndeps + 1) * sizeof *j->deps);
	j->deps[j->ndeps++] = dep;
	if (d->nrdeps == d->caprdeps) {
		d->caprdeps = d->caprdeps ? 2 * d->caprdeps : 4;
		d->rdeps = xrealloc(d->rdeps, (size_t)d->caprdeps * sizeof *d->rdeps);
	}
	d->rdeps[d->nrdeps++] = (int)(j - p->jobs);
	if (d->state == JOB_FAILED || d->state == JOB_BLOCKED)
		j->nbad++;
	else if (!job_finished(d))
		j->nwait++;
}

static int job_finished(const struct job *j)
{
	return j->state == JOB_DONE || j->state == JOB_SKIPPED;
}

/* ------------------------------------------------------------------ keys */

static int gone_fp(const char *path, uint64_t *fp);

/* A file's fingerprint: for chunk files the footer (size and whole-file
 * checksum, already computed by the writer), otherwise a hash of all of it;
 * for a file keep: deleted, the one recorded then. Returns 0 if the file
 * is missing (and not deleted by keep:) or cannot be read whole. */
static int fingerprint(const char *path, uint64_t *out)
{
	int fd = vd_open_read(path);
	if (fd < 0)
		return errno == ENOENT && gone_fp(path, out);
	struct stat st;
	uint8_t foot[24];
	static const uint8_t footer_magic[8] = {0x89, 'V', 'X', 'D', 'E', 'N', 'D', '\n'};
	if (fstat(fd, &st) != 0) {
		close(fd);
		return 0;
	}
	if (S_ISREG(st.st_mode) && st.st_size >= 24 &&
	    pread(fd, foot, 24, st.st_size - 24) == 24 &&
	    memcmp(foot, footer_magic, 8) == 0) {
		*out = XXH3_64bits(foot, 24);
		close(fd);
		return 1;
	}
	close(fd);
	uint64_t size;
	if (vd_file_xxh3(path, out, &size) != VD_OK) {
		vd_error_clear();
		return 0; /* a read error: no partial hash stands for the file */
	}
	return 1;
}

/* The stat signature: what the file system says about a file without
 * reading it. Any write, truncation, rename over it, `touch` (even one that
 * puts the old mtime back) or chmod changes its ctime, which no user can
 * set, so (device, inode, size, mtime, ctime, mode) to the nanosecond
 * stands for its content as long as the file was already "settled" when it
 * was hashed: its ctime at least one timestamp tick older than the moment
 * hashing began. A file changed later within the same tick would keep
 * every field (the "racy git" problem), so a younger file's signature is
 * not recorded and it is hashed again next time. The tick is taken as 2 s
 * when the ctime has no fraction of a second (file systems that keep whole
 * or 2-second stamps), else 20 ms (Linux stamps files from a clock that
 * advances every 1-10 ms). schemas/pipeline.md, "Resume", has the rule. */
static int64_t ts_ns(struct timespec t)
{
	return (int64_t)t.tv_sec * 1000000000 + t.tv_nsec;
}

static int64_t now_ns(void)
{
	struct timespec t;
	clock_gettime(CLOCK_REALTIME, &t);
	return ts_ns(t);
}

static uint64_t stat_hash(const char *name, const struct stat *st)
{
	uint64_t f[6] = {(uint64_t)st->st_dev, (uint64_t)st->st_ino,
			 (uint64_t)st->st_size, (uint64_t)ts_ns(st->st_mtim),
			 (uint64_t)ts_ns(st->st_ctim), (uint64_t)st->st_mode};
	return XXH3_64bits_withSeed(f, sizeof f, XXH3_64bits(name, strlen(name)));
}

static int settled(const struct stat *st, int64_t t0)
{
	int64_t tick = st->st_ctim.tv_nsec == 0 ? 2000000000 : 20000000;
	return ts_ns(st->st_ctim) + tick <= t0 && ts_ns(st->st_mtim) + tick <= t0;
}

/* The signature of `path` (a file, or a directory output: itself and every
 * entry in it but the runner's key, in any order). Returns 0 and sets *ok
 * to whether every part was settled at t0, *is_dir (when not NULL) to
 * whether path is a directory; non-zero if it cannot be read. */
static int stat_sig(const char *path, int64_t t0, uint64_t *sig, int *ok,
		    int *is_dir)
{
	struct stat st;
	if (stat(path, &st) != 0)
		return -1;
	*ok = settled(&st, t0);
	if (is_dir)
		*is_dir = S_ISDIR(st.st_mode);
	if (!S_ISDIR(st.st_mode)) {
		*sig = stat_hash("", &st);
		return 0;
	}
	DIR *d = opendir(path);
	if (!d)
		return -1;
	/* an order-free sum over the entries: readdir's order is not stable */
	uint64_t sum = 0, mix = 0, n = 0;
	struct dirent *e;
	while ((e = readdir(d))) {
		const char *nm = e->d_name;
		if (!strcmp(nm, ".") || !strcmp(nm, "..") || !strncmp(nm, ".key", 4))
			continue;
		struct stat es;
		if (fstatat(dirfd(d), nm, &es, AT_SYMLINK_NOFOLLOW) != 0) {
			closedir(d);
			return -1;
		}
		*ok = *ok && settled(&es, t0);
		uint64_t h = stat_hash(nm, &es);
		sum += h;
		mix ^= h * 0x9E3779B97F4A7C15ull;
		n++;
	}
	closedir(d);
	/* the directory's own times change with its .key: not part of it */
	uint64_t f[5] = {(uint64_t)st.st_dev, (uint64_t)st.st_ino, n, sum, mix};
	*sig = XXH3_64bits(f, sizeof f);
	return 0;
}

/* A file of directory output `dir` that keep: deleted. */
static int gone_in_dir(void *ctx, const char *dir, const char *name)
{
	(void)ctx;
	char path[2200];
	snprintf(path, sizeof path, "%s/%s", dir, name);
	uint64_t fp;
	return gone_fp(path, &fp);
}

/* What a finished output is, checked before it is trusted again: a
 * directory output (voxelize, encode) through its manifest (every file's
 * size and checksum, no file more), a file through the XXH3 of all its
 * bytes. Returns 0 and the digest, or non-zero with `why` filled. *sig and
 * *sig_ok: its stat signature, valid (*sig_ok) when it was settled and did
 * not change while it was read. */
static int output_digest(const char *path, uint64_t *digest, uint64_t *sig,
			 int *sig_ok, char *why, size_t cap)
{
	int err, is_dir;
	int64_t t0 = now_ns();
	uint64_t after;
	int ok_after;
	*sig_ok = 0;
	if (stat_sig(path, t0, sig, sig_ok, &is_dir) != 0) {
		snprintf(why, cap, "'%s' is missing", path);
		return 1;
	}
	if (is_dir) {
		err = vd_manifest_verify_except(path, digest, gone_in_dir, NULL);
	} else {
		uint64_t size;
		err = vd_file_xxh3(path, digest, &size);
	}
	if (err) {
		snprintf(why, cap, "%s: %s", vd_strerror(err), vd_error_detail());
		vd_error_clear();
		return 1;
	}
	if (*sig_ok && (stat_sig(path, t0, &after, &ok_after, NULL) != 0 ||
			after != *sig))
		*sig_ok = 0;
	return 0;
}

/* output_digest and stat_sig over everything a job writes: its output,
 * mixed with each side output it has (plan.c, add_job), so a lost, empty
 * or changed statistics file or colour directory reruns the job. */
static int job_digest(const struct job *j, uint64_t *digest, uint64_t *sig,
		      int *sig_ok, char *why, size_t cap)
{
	if (output_digest(j->output, digest, sig, sig_ok, why, cap))
		return 1;
	for (int k = 0; k < 2; k++) {
		if (!j->side[k])
			continue;
		uint64_t d2, s2;
		int ok2;
		if (output_digest(j->side[k], &d2, &s2, &ok2, why, cap))
			return 1;
		uint64_t f[2] = {*digest, d2}, g[2] = {*sig, s2};
		*digest = XXH3_64bits(f, sizeof f);
		*sig = XXH3_64bits(g, sizeof g);
		*sig_ok = *sig_ok && ok2;
	}
	return 0;
}

static int job_stat_sig(const struct job *j, int64_t t0, uint64_t *sig,
			int *ok)
{
	if (stat_sig(j->output, t0, sig, ok, NULL) != 0)
		return -1;
	for (int k = 0; k < 2; k++) {
		if (!j->side[k])
			continue;
		uint64_t s2;
		int ok2;
		if (stat_sig(j->side[k], t0, &s2, &ok2, NULL) != 0)
			return -1;
		uint64_t g[2] = {*sig, s2};
		*sig = XXH3_64bits(g, sizeof g);
		*ok = *ok && ok2;
	}
	return 0;
}

/* Arguments that do not change what a job writes are left out of its key,
 * so changing resources does not rerun finished work. */
static int volatile_arg(const char *a)
{
	return !strcmp(a, "--threads") || !strcmp(a, "--mem-budget") ||
	       !strcmp(a, "-q") || !strcmp(a, "--stats") ||
	       !strcmp(a, "--stats-list");
}

int job_key(const struct job *j, char key[17])
{
	XXH3_state_t *s = XXH3_createState();
	if (!s)
		return 1;
	XXH3_64bits_reset(s);
	/* 3: the digest covers side outputs (statistics) too */
	XXH3_64bits_update(s, "voxdag-key-3", 12);
	/* argv[0] is an absolute path that may move: hash its name only, and
	 * the stage's own version, so outputs of older code are rebuilt */
	const char *prog = strrchr(j->argv[0], '/');
	prog = prog ? prog + 1 : j->argv[0];
	XXH3_64bits_update(s, prog, strlen(prog) + 1);
	int32_t version = vd_stage_version(prog);
	XXH3_64bits_update(s, &version, sizeof version);
	for (int i = 1; j->argv[i]; i++) {
		if (volatile_arg(j->argv[i])) {
			if (strcmp(j->argv[i], "-q") != 0 && j->argv[i + 1])
				i++;
			continue;
		}
		XXH3_64bits_update(s, j->argv[i], strlen(j->argv[i]) + 1);
	}
	for (int i = 0; i < j->ninputs; i++) {
		uint64_t fp;
		if (!fingerprint(j->inputs[i], &fp)) {
			XXH3_freeState(s);
			return 1;
		}
		XXH3_64bits_update(s, &fp, sizeof fp);
	}
	snprintf(key, 17, "%016llx", (unsigned long long)XXH3_64bits_digest(s));
	XXH3_freeState(s);
	return 0;
}

/* ------------------------------------------------------- the key journal
 *
 * Every finished output's key lives in one file, <outputs>/keys, not in a
 * file beside each output: creating a file (an inode) per job was most of
 * the runner's own cost at 100,000 jobs. Each line is one record, appended
 * with one write():
 *   CHECK K KEY DIGEST SIG PATH   the job that wrote PATH finished: its
 *                                 key, its output's digest, and its stat
 *                                 signature ("-" when it was not settled)
 *   CHECK D PATH                  PATH is being rebuilt: no key (and
 *                                 not gone)
 *   CHECK G FP HEADER PATH        keep: deleted the file PATH once every
 *                                 job reading it had finished: its
 *                                 fingerprint and, for a chunk, the
 *                                 header the planner reads ("-" else),
 *                                 which stand in for the file
 * CHECK is the XXH3-64 of the rest of the line; PATH is relative to the
 * outputs directory; the last valid record of a PATH counts. A line that
 * a crash tore, or any damage, fails its check and is ignored (that job
 * runs again: a damaged journal costs time, never a wrong skip). A run
 * rewrites the file (to a temporary name, then renamed) when it holds
 * damage or more than twice the records it needs. */
struct key_rec {
	char *path;
	uint64_t key, digest, sig;
	char op;        /* 'K' or 'D' */
	char has_sig;
	char gone;      /* a G record: the file was deleted by keep: */
	uint64_t fp;    /* ...its fingerprint */
	char *hdr;      /* ...its chunk header as written, or NULL */
};

static struct {
	int loaded, fd;
	size_t dirlen;
	char dir[1100];
	struct key_rec *r;
	size_t n, cap;
	uint32_t *slot;  /* indices + 1, open addressing */
	size_t nslot;
} kj = {.fd = -1};

static void kj_rehash(size_t nslot)
{
	free(kj.slot);
	kj.nslot = nslot;
	kj.slot = calloc(kj.nslot, sizeof *kj.slot);
	if (!kj.slot) {
		fprintf(stderr, "voxdag: out of memory\n");
		exit(1);
	}
	for (size_t i = 0; i < kj.n; i++) {
		size_t h = XXH3_64bits(kj.r[i].path, strlen(kj.r[i].path)) &
			   (kj.nslot - 1);
		while (kj.slot[h])
			h = (h + 1) & (kj.nslot - 1);
		kj.slot[h] = (uint32_t)i + 1;
	}
}

/* The record of `path`, made (empty) with `add` when there is none. */
static struct key_rec *kj_find(const char *path, int add)
{
	if (add && 2 * (kj.n + 1) > kj.nslot)
		kj_rehash(kj.nslot ? 2 * kj.nslot : 1024);
	if (!kj.nslot)
		return NULL;
	size_t h = XXH3_64bits(path, strlen(path)) & (kj.nslot - 1);
	for (; kj.slot[h]; h = (h + 1) & (kj.nslot - 1))
		if (!strcmp(kj.r[kj.slot[h] - 1].path, path))
			return &kj.r[kj.slot[h] - 1];
	if (!add)
		return NULL;
	if (kj.n == kj.cap) {
		kj.cap = kj.cap ? 2 * kj.cap : 1024;
		kj.r = xrealloc(kj.r, kj.cap * sizeof *kj.r);
	}
	struct key_rec *r = &kj.r[kj.n];
	memset(r, 0, sizeof *r);
	r->path = xstrdup(path);
	kj.slot[h] = (uint32_t)++kj.n;
	return r;
}

/* One record's line (without CHECK) into buf; returns its length. With
 * `gone`, its G line instead. */
static int kj_line_of(char *buf, size_t cap, const struct key_rec *r,
		      int gone)
{
	char body[2400];
	int n;
	if (gone) {
		n = snprintf(body, sizeof body, "G %016llx %s %s",
			     (unsigned long long)r->fp, r->hdr ? r->hdr : "-",
			     r->path);
	} else if (r->op == 'K') {
		char sig[17] = "-";
		if (r->has_sig)
			snprintf(sig, sizeof sig, "%016llx", (unsigned long long)r->sig);
		n = snprintf(body, sizeof body, "K %016llx %016llx %s %s",
			     (unsigned long long)r->key,
			     (unsigned long long)r->digest, sig, r->path);
	} else {
		n = snprintf(body, sizeof body, "D %s", r->path);
	}
	return snprintf(buf, cap, "%016llx %s\n",
			(unsigned long long)XXH3_64bits(body, (size_t)n), body);
}

static int kj_line(char *buf, size_t cap, const struct key_rec *r)
{
	return kj_line_of(buf, cap, r, 0);
}

/* Applies one line (without its '\n'); 0 if it is not a valid record. */
static int kj_parse(char *line, size_t len)
{
	unsigned long long check, key, digest, sig = 0;
	if (len < 19 || line[16] != ' ' ||
	    sscanf(line, "%16llx", &check) != 1 ||
	    XXH3_64bits(line + 17, len - 17) != check)
		return 0;
	char *body = line + 17;
	line[len] = 0;
	if (body[0] == 'D' && body[1] == ' ' && body[2]) {
		struct key_rec *r = kj_find(body + 2, 1);
		r->op = 'D';
		r->gone = 0;
		return 1;
	}
	if (body[0] == 'G') {
		unsigned long long fp;
		char hdr[600];
		int at = 0;
		if (sscanf(body + 1, " %16llx %599s %n", &fp, hdr, &at) != 2 ||
		    !at || !body[1 + at])
			return 0;
		struct key_rec *r = kj_find(body + 1 + at, 1);
		r->gone = 1;
		r->fp = fp;
		free(r->hdr);
		r->hdr = strcmp(hdr, "-") ? xstrdup(hdr) : NULL;
		return 1;
	}
	char sigs[17];
	int at = 0;
	if (body[0] != 'K' || sscanf(body + 1, " %16llx %16llx %16s %n", &key,
				     &digest, sigs, &at) != 3 || !at || !body[1 + at])
		return 0;
	int has_sig = strcmp(sigs, "-") != 0;
	if (has_sig && sscanf(sigs, "%16llx", &sig) != 1)
		return 0;
	struct key_rec *r = kj_find(body + 1 + at, 1);
	r->op = 'K';
	r->key = key;
	r->digest = digest;
	r->sig = sig;
	r->has_sig = (char)has_sig;
	return 1;
}

/* ------------------------------------------------------- the runner's lock
 * One runner per output directory: it guards the key journal (only the
 * lock's holder appends to it). */

/* The pid holding the lock on `fd`'s file, or 0. */
static long holder_of(int fd)
{
	struct flock l = {.l_type = F_WRLCK, .l_whence = SEEK_SET};
	if (fcntl(fd, F_GETLK, &l) != 0 || l.l_type == F_UNLCK)
		return 0;
	return (long)l.l_pid;
}

long lock_holder(const char *dir)
{
	char path[1200];
	snprintf(path, sizeof path, "%s/.lock", dir);
	int fd = open(path, O_RDONLY | O_CLOEXEC);
	if (fd < 0)
		return 0;
	long pid = holder_of(fd);
	close(fd);
	return pid;
}

int lock_take(const char *dir, long *holder)
{
	char path[1200];
	snprintf(path, sizeof path, "%s/.lock", dir);
	int fd = open(path, O_RDWR | O_CREAT | O_CLOEXEC, 0666);
	if (fd < 0) {
		fprintf(stderr, "voxdag: cannot create '%s': %s\n", path,
			strerror(errno));
		return -2;
	}
	/* a POSIX record lock: the kernel drops it when its holder exits
	 * (before it is even a zombie), children do not inherit it, and
	 * F_GETLK names the holder, so no pid file can be stale or not yet
	 * written. The runner never opens .lock twice, which would drop it. */
	struct flock l = {.l_type = F_WRLCK, .l_whence = SEEK_SET};
	if (fcntl(fd, F_SETLK, &l) == 0) {
		if (ftruncate(fd, 0) == 0) /* for people; the lock decides */
			dprintf(fd, "%ld\n", (long)getpid());
		return fd; /* held until the process exits */
	}
	int e = errno;
	*holder = e == EACCES || e == EAGAIN ? holder_of(fd) : 0;
	close(fd);
	if (e != EACCES && e != EAGAIN) {
		fprintf(stderr, "voxdag: cannot lock '%s': %s\n", path,
			strerror(e));
		return -2;
	}
	return -1;
}

/* Loads DIR/keys; with `write` (the runner, holding the lock) also opens
 * it for appending, compacting it first when needed. Returns non-zero
 * (with a message) when it cannot be written. */
int keys_open(const char *dir, int write)
{
	if (!kj.loaded) {
		kj.loaded = 1;
		snprintf(kj.dir, sizeof kj.dir, "%s", dir);
		kj.dirlen = strlen(dir);
		char path[1200];
		snprintf(path, sizeof path, "%s/keys", dir);
		FILE *f = fopen(path, "rb");
		size_t lines = 0, bad = 0;
		if (f) {
			char *line = NULL;
			size_t cap = 0;
			ssize_t len;
			while ((len = getline(&line, &cap, f)) > 0) {
				lines++;
				if (line[len - 1] != '\n' ||
				    !kj_parse(line, (size_t)len - 1))
					bad++;
			}
			free(line);
			fclose(f);
		}
		size_t live = 0;
		for (size_t i = 0; i < kj.n; i++)
			live += (kj.r[i].op == 'K') + kj.r[i].gone;
		kj.fd = -2; /* compact when opened for writing */
		if (!bad && lines <= 2 * live + 1024)
			kj.fd = -1;
	}
	if (!write || kj.fd >= 0)
		return 0;
	char path[1200];
	snprintf(path, sizeof path, "%s/keys", dir);
	if (kj.fd == -2) {
		/* durable before any key is appended to it */
		struct vd_atomic a;
		int err = vd_atomic_open(&a, path);
		for (size_t i = 0; !err && i < kj.n; i++) {
			char line[2500];
			if (kj.r[i].op == 'K') {
				kj_line(line, sizeof line, &kj.r[i]);
				fputs(line, a.f);
			}
			if (kj.r[i].gone) {
				kj_line_of(line, sizeof line, &kj.r[i], 1);
				fputs(line, a.f);
			}
		}
		if (!err)
			err = vd_atomic_commit(&a);
		if (err) {
			fprintf(stderr, "voxdag: cannot write '%s': %s\n", path,
				strerror(errno));
			return 1;
		}
	}
	kj.fd = open(path, O_WRONLY | O_APPEND | O_CREAT | O_CLOEXEC, 0666);
	if (kj.fd < 0) {
		fprintf(stderr, "voxdag: cannot write '%s': %s\n", path,
			strerror(errno));
		return 1;
	}
	return 0;
}

/* j's output as the journal names it: relative to the outputs. */
static const char *kj_rel(const char *path)
{
	if (!strncmp(path, kj.dir, kj.dirlen) && path[kj.dirlen] == '/')
		return path + kj.dirlen + 1;
	return path;
}

static const char *kj_name(const struct job *j)
{
	return kj_rel(j->output);
}

/* The G record of `path`, when keep: deleted it and nothing wrote it
 * since (a job about to write it drops the record: job_key_drop). */
static struct key_rec *gone_rec(const char *path)
{
	struct key_rec *r = kj_find(kj_rel(path), 0);
	return r && r->gone ? r : NULL;
}

static int gone_fp(const char *path, uint64_t *fp)
{
	const struct key_rec *g = gone_rec(path);
	if (g)
		*fp = g->fp;
	return g != NULL;
}

/* Keys reach the disk in groups: an fdatasync of the journal once a
 * second or once KJ_GROUP records wait, whichever comes first, and at the
 * run's end (keys_sync). Each job's files were durable before its key was
 * appended (every stage publishes through vd_atomic_*: fsync, rename,
 * directory fsync, before it exits), so a key on disk never names an
 * output that is not; a power cut loses at most the keys of the last
 * group, and those jobs run again. */
#define KJ_GROUP 256
static size_t kj_unsynced;
static double kj_synced_at;

/* The files keep: deleted, unlinked once their G records are durable:
 * a power cut may then lose a record, never leave a file gone without one
 * (gone unrecorded, its producer and readers would run again). */
static char **unlink_q;
static size_t unlink_n, unlink_cap;

void keys_sync(int force)
{
	double now = (double)now_ns() * 1e-9;
	if (kj.fd < 0 || !kj_unsynced ||
	    (!force && kj_unsynced < KJ_GROUP && now - kj_synced_at < 1.0))
		return;
	/* a failed sync (EIO) loses only keys: those jobs run again */
	int synced = vd_sync_fd(kj.fd) == VD_OK;
	kj_unsynced = 0;
	kj_synced_at = now;
	for (size_t i = 0; i < unlink_n; i++) {
		if (synced && unlink(unlink_q[i]) != 0 && errno != ENOENT)
			run_log("cannot delete '%s' (keep:): %s", unlink_q[i],
				strerror(errno));
		free(unlink_q[i]);
	}
	unlink_n = 0;
}

/* 1 after a write that may have left part of a line (a full disk): the
 * next record starts on a line of its own, so only the torn one is lost. */
static int kj_torn;

static int kj_append_of(const struct key_rec *r, int gone)
{
	char line[2500];
	line[0] = '\n';
	int n = kj_line_of(line + 1, sizeof line - 1, r, gone);
	const char *at = kj_torn ? line : line + 1;
	size_t len = (size_t)n + (kj_torn ? 1 : 0);
	if (kj.fd < 0)
		return -1;
	ssize_t w = write(kj.fd, at, len);
	if (w != (ssize_t)len) {
		if (w >= 0)
			errno = ENOSPC; /* a short write: the disk is full */
		kj_torn = w != 0 || kj_torn;
		return -1;
	}
	kj_torn = 0;
	kj_unsynced++;
	keys_sync(0);
	return 0;
}

static int kj_append(const struct key_rec *r)
{
	return kj_append_of(r, 0);
}

/* Appends a D record for r: no key, not gone. */
static void kj_drop(struct key_rec *r)
{
	if (r->op == 'K' || r->gone) {
		r->op = 'D';
		r->gone = 0;
		kj_append(r);
	}
}

void job_key_drop(const struct job *j)
{
	struct key_rec *r = kj_find(kj_name(j), 0);
	if (r)
		kj_drop(r);
	if (!j->dir_output)
		return;
	/* the files keep: deleted from the directory it replaces */
	const char *name = kj_name(j);
	size_t len = strlen(name);
	for (size_t i = 0; i < kj.n; i++)
		if (kj.r[i].gone && !strncmp(kj.r[i].path, name, len) &&
		    kj.r[i].path[len] == '/')
			kj_drop(&kj.r[i]);
}

int job_key_write(const struct job *j, char *why, size_t cap)
{
	char key[17];
	uint64_t digest, sig;
	int sig_ok;
	if (job_key(j, key)) {
		snprintf(why, cap, "an input is missing or unreadable");
		return 1;
	}
	if (job_digest(j, &digest, &sig, &sig_ok, why, cap))
		return 1;
	struct key_rec *r = kj_find(kj_name(j), 1);
	r->op = 'K';
	r->key = strtoull(key, NULL, 16);
	r->digest = digest;
	r->sig = sig;
	r->has_sig = (char)sig_ok;
	if (kj_append(r) != 0) {
		snprintf(why, cap, "cannot write its key to '%s/keys': %s",
			 kj.dir, strerror(errno));
		r->op = 'D';
		return 1;
	}
	return 0;
}

static int output_is_fresh(struct job *j, char *why, size_t cap)
{
	char want[17];
	*why = 0;
	/* an output that is there but cannot be read (permissions): the
	 * user's to fix, not ours to rebuild over */
	struct stat st;
	if (stat(j->output, &st) == 0 &&
	    faccessat(AT_FDCWD, j->output, S_ISDIR(st.st_mode) ? R_OK | X_OK
			: R_OK, AT_EACCESS) != 0 && errno != ENOENT) {
		snprintf(why, cap, "cannot read '%s': %s", j->output,
			 strerror(errno));
		return -1;
	}
	struct key_rec *r = kj_find(kj_name(j), 0);
	j->key_absent = !r || r->op != 'K';
	if (j->key_absent)
		return 0; /* never finished, or being rebuilt */
	if (job_key(j, want) || strtoull(want, NULL, 16) != r->key)
		return 0; /* its inputs, arguments or stage version changed */
	if (!j->dir_output && gone_rec(j->output) &&
	    access(j->output, F_OK) != 0 && errno == ENOENT)
		return 1; /* keep: deleted it once its readers finished; its
			   * key, in the journal, stands for it */
	uint64_t digest, sig;
	int sig_ok;
	if (r->has_sig) {
		/* unchanged since it was hashed, settled: no need to read it */
		if (job_stat_sig(j, now_ns(), &sig, &sig_ok) == 0 &&
		    sig == r->sig)
			return 1;
	}
	if (job_digest(j, &digest, &sig, &sig_ok, why, cap))
		return 0;
	if (digest != r->digest) {
		snprintf(why, cap, "'%s'%s changed after it was written",
			 j->output, j->side[0] || j->side[1]
			 ? " or a file written with it" : "");
		return 0;
	}
	if (sig_ok && kj.fd >= 0) {
		/* hashed once more: remember it settled, so next time a stat
		 * suffices (best effort: without it the next run hashes) */
		r->sig = sig;
		r->has_sig = 1;
		kj_append(r);
	}
	return 1;
}

/* The files a mesh pulled in (an OBJ's MTL files and textures, a glTF's
 * buffers, ...) are found only by reading it, so the key, which the
 * runner computes without reading meshes, cannot cover them. voxelize
 * lists them instead, each with the hash of what it read, in its output's
 * `sources` (covered by the manifest, so trusted once the output is):
 * each must be unchanged, and each name it looked for in vain still
 * absent, or voxelize runs again (and what depends on what changes). */
static int sources_fresh(const struct job *j, char *why, size_t cap)
{
	char path[1200];
	path_join(path, sizeof path, j->output, VD_SOURCES_NAME);
	int err = vd_sources_check(path);
	if (!err)
		return 1;
	if (err == VD_ERR_MISMATCH)
		snprintf(why, cap, "%s", vd_error_detail());
	else
		snprintf(why, cap, "%s: %s", vd_strerror(err),
			 vd_error_detail());
	vd_error_clear();
	return 0;
}

int job_is_fresh(struct job *j, char *why, size_t cap)
{
	int fresh = output_is_fresh(j, why, cap);
	if (fresh != 1 || !j->sources)
		return fresh;
	return sources_fresh(j, why, cap);
}

/* ------------------------------------------------------------------ keep:
 *
 * With `keep: [jobs]` in the YAML, every other job's output that some job
 * reads is an intermediate: once every job that may read it is planned
 * (readers_planned: so its readers are known) and has finished, the
 * runner deletes it (a directory output's data files; its manifest,
 * statistics and sources stay), after a G record in the journal keeps
 * what the planner and the keys read from it: its fingerprint (so its
 * readers' keys still match) and its chunk header (so the cells and the
 * merge tree are planned as before). A deleted file is then as good as
 * there for resume: its job is fresh while its key matches. A job that
 * must run again and needs one (its arguments changed, its output was
 * damaged) gets it back: the job that wrote it loses its key and the run
 * starts over (keep_revive, main.c), so that job runs again first. */

/* A chunk header as a G record keeps it: the fields the planner reads. */
static void hdr_text(const struct vd_chunk_header *h, char *buf, size_t cap)
{
	int n = snprintf(buf, cap, "%x.%x.%x.%llx", (unsigned)h->kind,
			 (unsigned)h->levels, (unsigned)h->chunk_level,
			 (unsigned long long)h->cell_morton);
	for (uint32_t l = 0; l < h->level_count && l <= VD_MAX_LEVELS &&
	     n > 0 && (size_t)n < cap; l++)
		n += snprintf(buf + n, cap - (size_t)n, ".%llx",
			      (unsigned long long)h->level_nodes[l]);
}

static int hdr_parse(const char *s, struct vd_chunk_header *h)
{
	memset(h, 0, sizeof *h);
	unsigned long long v[4 + VD_MAX_LEVELS + 1];
	int n = 0;
	for (const char *at = s; n < (int)(sizeof v / sizeof *v);) {
		char *end;
		errno = 0;
		v[n++] = strtoull(at, &end, 16);
		if (end == at || errno)
			return 0;
		if (!*end)
			break;
		if (*end != '.')
			return 0;
		at = end + 1;
	}
	if (n < 4)
		return 0;
	h->kind = (uint32_t)v[0];
	h->levels = (uint32_t)v[1];
	h->chunk_level = (uint32_t)v[2];
	h->cell_morton = v[3];
	h->level_count = (uint32_t)(n - 4);
	for (int l = 4; l < n; l++)
		h->level_nodes[l - 4] = v[l];
	return 1;
}

int plan_chunk_header(const char *path, struct vd_chunk_header *h)
{
	int err = vd_chunk_read_header(path, h);
	if (err == VD_OK || access(path, F_OK) == 0 || errno != ENOENT)
		return err;
	const struct key_rec *g = gone_rec(path);
	if (!g || !g->hdr || !hdr_parse(g->hdr, h))
		return err;
	vd_error_clear();
	return VD_OK;
}

/* Records `path` as deleted (its fingerprint, its header when it is a
 * chunk) and queues it for unlinking once the record is durable. Returns
 * 1 when it did. */
static int keep_forget_file(const char *path)
{
	uint64_t fp;
	if (access(path, F_OK) != 0 || !fingerprint(path, &fp))
		return 0; /* gone already, or unreadable: left as it is */
	struct vd_chunk_header h;
	char hdr[600] = "";
	if (vd_chunk_read_header(path, &h) == VD_OK)
		hdr_text(&h, hdr, sizeof hdr);
	else
		vd_error_clear();
	struct key_rec *r = kj_find(kj_rel(path), 1);
	r->gone = 1;
	r->fp = fp;
	free(r->hdr);
	r->hdr = *hdr ? xstrdup(hdr) : NULL;
	if (kj_append_of(r, 1) != 0) {
		r->gone = 0; /* not recorded: not deleted */
		return 0;
	}
	if (unlink_n == unlink_cap) {
		unlink_cap = unlink_cap ? 2 * unlink_cap : 256;
		unlink_q = xrealloc(unlink_q, unlink_cap * sizeof *unlink_q);
	}
	unlink_q[unlink_n++] = xstrdup(path);
	return 1;
}

/* A directory output's data files: all but its manifest, sources and
 * statistics (the report reads those), and hidden names. */
static int data_file(const char *name)
{
	size_t n = strlen(name);
	return name[0] != '.' && strcmp(name, VD_MANIFEST_NAME) &&
	       strcmp(name, VD_SOURCES_NAME) &&
	       !(n > 5 && !strcmp(name + n - 5, ".json"));
}

/* 1 when every job that may read an output of declared job x is planned
 * (so is its dependency on it): the jobs of each declared job that needs
 * x, and x's own merges, which read its cells. A DAG stage plans its
 * cells at once, then the merge tree at once; every other stage, its
 * jobs at once. */
static int readers_planned(const struct plan *p, int x)
{
	const struct config *c = p->cfg;
	int dag = c->jobs_decl[x].stage->type == STAGE_SVO_TO_DAG ||
		  c->jobs_decl[x].stage->type == STAGE_SYMMETRY_MERGE;
	if (dag && !p->merges_planned[x])
		return 0;
	for (int y = 0; y < c->njobs; y++) {
		const struct job_decl *dy = &c->jobs_decl[y];
		int needs_x = 0;
		for (int k = 0; k < dy->nneeds; k++)
			needs_x |= dy->needs[k] == x;
		if (!needs_x)
			continue;
		if (dy->stage->type == STAGE_SVO_TO_DAG ||
		    dy->stage->type == STAGE_SYMMETRY_MERGE
			    ? !p->cells_planned[y] && !p->merges_planned[y]
			    : !p->planned[y])
			return 0;
	}
	return 1;
}

/* 1 when keep: makes j's output an intermediate whose readers are all
 * known. */
static int keep_intermediate(const struct plan *p, const struct job *j)
{
	const struct config *c = p->cfg;
	return c->keep_given && !(c->keep_mask >> j->decl & 1) &&
	       !j->keep_done && job_finished(j) && j->nrdeps > 0 &&
	       readers_planned(p, j->decl);
}

/* 1 when keep: makes j's output an intermediate that may go now. */
static int keep_may_delete(const struct plan *p, const struct job *j)
{
	if (!keep_intermediate(p, j))
		return 0;
	for (int k = 0; k < j->nrdeps; k++)
		if (!job_finished(&p->jobs[j->rdeps[k]]))
			return 0;
	return 1;
}

/* 1 when reader r of directory output d reads its file `path`: it names
 * the file, or the directory or its manifest (then it reads them all:
 * colorize and edit take voxelize's colour chunks through its manifest). */
static int reads_file(const struct job *r, const struct job *d,
		      const char *path)
{
	size_t len = strlen(d->output);
	for (int i = 0; i < r->ninputs; i++) {
		const char *in = r->inputs[i];
		if (!strcmp(in, path) || !strcmp(in, d->output) ||
		    (!strncmp(in, d->output, len) && in[len] == '/' &&
		     !data_file(in + len + 1)))
			return 1;
	}
	return 0;
}

/* A file of directory output d goes as soon as the jobs reading it
 * finished, before the rest of d: voxelize's chunk of a cell once the
 * cell's DAG is built (at 2^16, 244 of the 307 MB at the peak). */
static void keep_delete_file(const struct plan *p, const struct job *d,
			     const char *path)
{
	const char *name = strrchr(path, '/');
	if (!name || !data_file(name + 1))
		return;
	for (int k = 0; k < d->nrdeps; k++) {
		const struct job *r = &p->jobs[d->rdeps[k]];
		if (!job_finished(r) && reads_file(r, d, path))
			return;
	}
	if (keep_forget_file(path))
		run_log("deleted %s (keep:)", kj_rel(path));
}

static void keep_delete(struct job *j)
{
	j->keep_done = 1;
	if (!j->dir_output) {
		if (keep_forget_file(j->output))
			run_log("deleted %s (keep:)", kj_name(j));
		return;
	}
	DIR *d = opendir(j->output);
	if (!d)
		return;
	struct dirent *e;
	int n = 0;
	while ((e = readdir(d)))
		if (data_file(e->d_name) && e->d_type != DT_DIR) {
			char path[2200];
			snprintf(path, sizeof path, "%s/%s", j->output, e->d_name);
			n += keep_forget_file(path);
		}
	closedir(d);
	if (n)
		run_log("deleted %d files of %s (keep:)", n, kj_name(j));
}

void keep_sweep(struct plan *p, int finished)
{
	if (!p->cfg->keep_given)
		return;
	if (finished < 0) {
		for (int i = 0; i < p->n; i++)
			if (keep_may_delete(p, &p->jobs[i]))
				keep_delete(&p->jobs[i]);
	} else {
		const struct job *f = &p->jobs[finished];
		for (int k = 0; k < f->ndeps; k++) {
			struct job *d = &p->jobs[f->deps[k]];
			if (keep_may_delete(p, d)) {
				keep_delete(d);
				continue;
			}
			if (!d->dir_output || !keep_intermediate(p, d))
				continue;
			size_t len = strlen(d->output);
			for (int i = 0; i < f->ninputs; i++)
				if (!strncmp(f->inputs[i], d->output, len) &&
				    f->inputs[i][len] == '/')
					keep_delete_file(p, d, f->inputs[i]);
		}
	}
	/* now, not with the next group of keys: one sync for all a job's
	 * end let go (at 2^18, a few hundred merges end after the graph is
	 * whole) */
	if (unlink_n)
		keys_sync(1);
}

/* The job among j's dependencies that writes `in` (its output, or a file
 * of its directory output), or -1. */
static int producer_of(const struct plan *p, const struct job *j,
		       const char *in)
{
	for (int k = 0; k < j->ndeps; k++) {
		const struct job *d = &p->jobs[j->deps[k]];
		size_t len = strlen(d->output);
		if (!strcmp(in, d->output) ||
		    (d->dir_output && !strncmp(in, d->output, len) &&
		     in[len] == '/'))
			return j->deps[k];
	}
	return -1;
}

/* j runs again: each input of it that keep: deleted must be written again
 * first, so the job that wrote it loses its key, and so on up the graph
 * (that job runs again too, and needs its own inputs). Returns how many
 * inputs of j are gone; `why` names the first. */
static int revive_inputs(struct plan *p, struct job *j, char *why,
			 size_t cap)
{
	int gone = 0;
	for (int i = 0; i < j->ninputs; i++) {
		const char *in = j->inputs[i];
		if (access(in, F_OK) == 0 || errno != ENOENT || !gone_rec(in))
			continue;
		int k = producer_of(p, j, in);
		if (k < 0) {
			/* no job of the plan writes it: forgotten, the job
			 * fails on it as it would without keep: */
			kj_drop(gone_rec(in));
			continue;
		}
		struct job *d = &p->jobs[k];
		if (!gone++)
			snprintf(why, cap, "needs '%s', which keep: deleted; %s "
				 "runs again first", in, d->id);
		if (d->revived)
			continue;
		d->revived = 1;
		job_key_drop(d);
		char up[600];
		revive_inputs(p, d, up, sizeof up);
	}
	return gone;
}

int keep_revive(struct plan *p, struct job *j, char *why, size_t cap)
{
	return revive_inputs(p, j, why, cap) > 0;
}

/* Bytes of a file, or of the regular files of a directory, on disk. */
static uint64_t disk_bytes(const char *path)
{
	struct stat st;
	if (stat(path, &st) != 0)
		return 0;
	if (!S_ISDIR(st.st_mode))
		return (uint64_t)st.st_blocks * 512;
	uint64_t sum = 0;
	DIR *d = opendir(path);
	struct dirent *e;
	while (d && (e = readdir(d))) {
		struct stat es;
		if (fstatat(dirfd(d), e->d_name, &es, AT_SYMLINK_NOFOLLOW) == 0 &&
		    S_ISREG(es.st_mode))
			sum += (uint64_t)es.st_blocks * 512;
	}
	if (d)
		closedir(d);
	return sum;
}

uint64_t job_disk_bytes(const struct job *j)
{
	uint64_t sum = disk_bytes(j->output);
	for (int k = 0; k < 2; k++)
		if (j->side[k])
			sum += disk_bytes(j->side[k]);
	return sum;
}

size_t keep_gone_files(void)
{
	size_t n = 0;
	for (size_t i = 0; i < kj.n; i++)
		n += kj.r[i].gone;
	return n;
}

/* -------------------------------------------------------------- expansion */

static const struct job_decl *decl_of(const struct plan *p, int d)
{
	return &p->cfg->jobs_decl[d];
}

/* 1 when a job of the graph takes voxelize's colour chunks (colorize, or
 * edit, which carries them through): the colour of every voxel costs
 * voxelize as much as its geometry, so it is computed only then. */
static int colours_wanted(const struct config *c)
{
	for (int d = 0; d < c->njobs; d++)
		if (c->jobs_decl[d].stage->type == STAGE_COLORIZE ||
		    c->jobs_decl[d].stage->type == STAGE_EDIT)
			return 1;
	return 0;
}

/* The --mem-budget argument of a job, `bytes` in decimal into `buf` (cap
 * bytes, 32 hold any): the one place every stage's command line takes it
 * from. Only the value is made here; which budget a job gets is its
 * planner's (c->job_mem_budget, or dag_job_budget for a DAG job). The
 * argument is left out of the job's key (volatile_arg). */
static void budget_arg(char *buf, size_t cap, uint64_t bytes)
{
	snprintf(buf, cap, "%llu", (unsigned long long)bytes);
}

/* The voxelize job: one process over the whole mesh. */
static void plan_voxelize(struct plan *p, int d)
{
	const struct config *c = p->cfg;
	char out[1100], lv[16], cl[16], budget[32], threads[16];
	path_join(out, sizeof out, p->dir, decl_of(p, d)->name);
	struct job *j = add_job(p, d, decl_of(p, d)->name, out, OUT_DIR);
	if (!j)
		return;
	snprintf(lv, sizeof lv, "%d", c->levels);
	snprintf(cl, sizeof cl, "%d", c->chunk_level);
	budget_arg(budget, sizeof budget, c->job_mem_budget);
	/* everything else waits for it: it gets every job's threads; its
	 * progress lines go to its log, which the runner's status shows */
	snprintf(threads, sizeof threads, "%d", c->threads * c->jobs);
	const char *in = *c->mesh ? c->mesh : c->vdb;
	const char *args[24];
	int na = 0;
	args[na++] = in;
	const char *fixed[] = {"-o", out, "--levels", lv, "--mem-budget", budget,
			       "--threads", threads};
	for (size_t i = 0; i < sizeof fixed / sizeof *fixed; i++)
		args[na++] = fixed[i];
	if (c->chunk_level >= 0)
		args[na++] = "--chunk-level", args[na++] = cl;
	if (*c->vdb_grid)
		args[na++] = "--grid", args[na++] = c->vdb_grid;
	if (*c->vdb_mode)
		args[na++] = "--vdb-mode", args[na++] = c->vdb_mode;
	if (*c->vdb_colour_grid)
		args[na++] = "--colour-grid", args[na++] = c->vdb_colour_grid;
	else if (!colours_wanted(c))
		args[na++] = "--no-colours";
	args[na] = NULL;
	set_argv_list(j, "voxelize", args);
	add_input(j, in);
	j->sources = *c->mesh != 0; /* a .vdb file pulls nothing in */
	j->mem_estimate = c->job_mem_budget;
}

static int cmp_str(const void *a, const void *b)
{
	return strcmp(*(char *const *)a, *(char *const *)b);
}

/* Sorted file names in `dir` ending in `ext`. */
static int list_files(const char *dir, const char *ext, char ***out)
{
	DIR *d = opendir(dir);
	if (!d)
		return -1;
	int n = 0, cap = 0;
	char **names = NULL;
	struct dirent *e;
	size_t el = strlen(ext);
	while ((e = readdir(d))) {
		size_t len = strlen(e->d_name);
		if (len <= el || strcmp(e->d_name + len - el, ext) ||
		    strncmp(e->d_name, "chunk-", 6))
			continue;
		if (n == cap) {
			cap = cap ? 2 * cap : 64;
			names = xrealloc(names, (size_t)cap * sizeof *names);
		}
		names[n++] = xstrdup(e->d_name);
	}
	closedir(d);
	/* ...and those keep: deleted, which the planner still needs */
	const char *rel = kj_rel(dir);
	size_t rl = strlen(rel);
	for (size_t i = 0; i < kj.n; i++) {
		const char *g = kj.r[i].path, *nm = g + rl + 1;
		size_t len = strlen(nm);
		char path[2200];
		if (!kj.r[i].gone || strncmp(g, rel, rl) || g[rl] != '/' ||
		    strchr(nm, '/') || len <= el || strcmp(nm + len - el, ext) ||
		    strncmp(nm, "chunk-", 6))
			continue;
		snprintf(path, sizeof path, "%s/%s", dir, nm);
		if (access(path, F_OK) == 0)
			continue; /* listed above */
		if (n == cap) {
			cap = cap ? 2 * cap : 64;
			names = xrealloc(names, (size_t)cap * sizeof *names);
		}
		names[n++] = xstrdup(nm);
	}
	qsort(names, (size_t)n, sizeof *names, cmp_str);
	*out = names;
	return n;
}

/* Memory estimates are the stages' own bounds (vd_dag_estimate_header),
 * so the runner never plans a job its stage would refuse. */

/* A part's share of a merge that builds `kind` from it: the bound from
 * the per-level counts of its header. The counts of the input chunk bound
 * those of its DAG (merging only removes nodes); the bound is subadditive,
 * so shares may be summed. */
static uint64_t merge_share(const struct vd_chunk_header *h, uint32_t kind)
{
	struct vd_dag_census cen = {0};
	vd_dag_census_add_header(&cen, h);
	return vd_dag_estimate_merge(&cen, kind);
}

/* The --mem-budget of a DAG job (a cell or a merge) with estimate `est`:
 * the job budget, unless the job cannot fit it (a cell of a dense scene, or
 * a merge whose parts cannot be grouped smaller: the root above all); then
 * its estimate, up to the whole budget. The scheduler runs a job estimated
 * above what is free alone, so giving it more than the job budget never
 * oversubscribes memory; without this the stage would refuse the job that
 * the whole budget could hold. */
static uint64_t dag_job_budget(const struct config *c, uint64_t est)
{
	if (est <= c->job_mem_budget)
		return c->job_mem_budget;
	return est < c->mem_budget ? est : c->mem_budget;
}

/* A merge of parts whose shares sum to `sum`: each share holds the fixed
 * part once. */
static uint64_t merge_estimate(uint64_t sum, int nparts)
{
	return sum - (uint64_t)(nparts - 1) * VD_DAG_ESTIMATE_FIXED_BYTES;
}

struct part {
	const char *path;  /* its job's output (heap, stable) */
	int job;           /* producing job */
	int level;         /* chunk level of the part */
	uint64_t cell;
	uint64_t share;    /* its share of a merge's memory, an upper bound */
};

/* Plans the merges of `parts` (all finished or planned) up to the root,
 * grouping by the coarsest ancestor level at which every group fits the
 * job budget. Returns the root's job index. */
static int plan_merges(struct plan *p, int d, struct part *parts, int n,
		       const char *ext)
{
	const struct config *c = p->cfg;
	const char *prog = decl_of(p, d)->stage->type == STAGE_SVO_TO_DAG
				   ? "svo-to-dag" : "symmetry-merge";
	char dir[1100];
	path_join(dir, sizeof dir, p->dir, decl_of(p, d)->name);
	for (;;) {
		int L0 = parts[0].level;
		/* target level: the coarsest a whose groups all fit, and at most
		 * four levels up, so a merge takes at most 8^4 parts (its
		 * command line stays far below the kernel's limit) */
		int a = L0 > 4 ? L0 - 4 : 0;
		for (; a < L0; a++) {
			int fits = 1;
			for (int i = 0; i < n && fits;) {
				uint64_t anc = parts[i].cell >> 3 * (L0 - a), sum = 0;
				int k = i;
				while (k < n && parts[k].cell >> 3 * (L0 - a) == anc)
					sum += parts[k++].share;
				fits = merge_estimate(sum, k - i) <= c->job_mem_budget;
				i = k;
			}
			if (fits)
				break;
		}
		if (a == L0)
			a = L0 - 1; /* at least one level up: a tree of 8s */
		if (a < 0)
			a = 0;
		int m = 0;
		for (int i = 0; i < n;) {
			uint64_t anc = L0 > a ? parts[i].cell >> 3 * (L0 - a) : parts[i].cell;
			int k = i;
			uint64_t sum = 0;
			while (k < n && (L0 > a ? parts[k].cell >> 3 * (L0 - a) : parts[k].cell) == anc)
				sum += parts[k++].share;
			char out[1200], id[200], to[16], budget[32],
				threads[16], name[64];
			if (a == 0) {
				snprintf(out, sizeof out, "%s/root.%s", dir, ext);
				snprintf(id, sizeof id, "%s/root", decl_of(p, d)->name);
			} else {
				vd_chunk_file_name(name, sizeof name, a, anc, ext);
				snprintf(out, sizeof out, "%s/%s", dir, name);
				snprintf(id, sizeof id, "%s/L%d-%llx", decl_of(p, d)->name,
					 a, (unsigned long long)anc);
			}
			snprintf(to, sizeof to, "%d", a);
			budget_arg(budget, sizeof budget,
				   dag_job_budget(c, merge_estimate(sum, k - i)));
			snprintf(threads, sizeof threads, "%d", c->threads);
			int idx = plan_find(p, id);
			struct job *j = idx < 0 ? add_job(p, d, id, out, OUT_FILE) : NULL;
			if (j) {
				char path[1100];
				snprintf(path, sizeof path, "%s/%s", bin_dir(), prog);
				const char *tail[] = {"-o", out, "--to-level", to,
						      "--mem-budget", budget,
						      "--threads", threads, "-q"};
				size_t nt = sizeof tail / sizeof *tail;
				j->argv = xrealloc(NULL, ((size_t)(k - i) + nt + 3) *
							     sizeof *j->argv);
				int z = 0;
				j->argv[z++] = xstrdup(path);
				j->argv[z++] = xstrdup("--merge");
				for (int q = i; q < k; q++)
					j->argv[z++] = xstrdup(parts[q].path);
				for (size_t q = 0; q < nt; q++)
					j->argv[z++] = xstrdup(tail[q]);
				j->argv[z] = NULL;
				add_group_arg(decl_of(p, d), j);
				for (int q = i; q < k; q++) {
					add_input(j, parts[q].path);
					if (parts[q].job >= 0)
						add_dep(p, j, parts[q].job);
				}
				j->mem_estimate = merge_estimate(sum, k - i);
				idx = p->n - 1;
			}
			/* the merged chunk is no larger than its parts */
			struct part np = {.job = idx, .level = a, .cell = anc,
					  .share = merge_estimate(sum, k - i),
					  .path = p->jobs[idx].output};
			parts[m++] = np;
			i = k;
		}
		n = m;
		if (a == 0)
			break;
	}
	return parts[0].job;
}

/* The per-cell jobs of a DAG stage and its reduction tree, once the cells
 * of its input are known. */
static void plan_dag_merges(struct plan *p, int d, const char *ext,
			    uint32_t kind);

static int stage_root_job(const struct plan *p, int d);

/* A global stage on the root DAG chunk of job decl `src` (lossy-cluster,
 * edit, or symmetry-merge after one of them): one process whose job id is
 * "<name>/root" and whose output is <name>/root.<ext>, like the root of a
 * reduction tree, so the stages after it find it the same way. Returns
 * the job (NULL when the input is not planned yet or it is planned). */
static struct job *add_root_job(struct plan *p, int d, int src,
				const char *ext, int *in_job)
{
	*in_job = stage_root_job(p, src);
	if (*in_job < 0)
		return NULL;
	char out[1200], id[200];
	snprintf(out, sizeof out, "%s/%s/root.%s", p->dir, decl_of(p, d)->name,
		 ext);
	snprintf(id, sizeof id, "%s/root", decl_of(p, d)->name);
	struct job *j = add_job(p, d, id, out, OUT_FILE);
	if (j)
		/* its input is a whole scene: the stage's bound from its
		 * header is not known before it exists; the budget is the
		 * limit the stage itself holds to */
		j->mem_estimate = p->cfg->job_mem_budget;
	return j;
}

/* symmetry-merge of a single root DAG chunk (after lossy-cluster or edit):
 * no cells, no tree. */
static void plan_root_ssvdag(struct plan *p, int d)
{
	const struct config *c = p->cfg;
	int in;
	struct job *j = add_root_job(p, d, decl_of(p, d)->needs[0], "sdag", &in);
	if (!j)
		return;
	char budget[32], threads[16];
	budget_arg(budget, sizeof budget, c->job_mem_budget);
	snprintf(threads, sizeof threads, "%d", c->threads);
	const char *src = p->jobs[in].output;
	set_argv(j, "symmetry-merge", src, "-o", j->output, "--mem-budget",
		 budget, "--threads", threads, "-q", NULL);
	add_group_arg(decl_of(p, d), j);
	add_input(j, src);
	add_dep(p, j, in);
	p->merges_planned[d] = 1;
}

/* lossy-cluster on the root DAG chunk: the lossy root (LSVDAG). */
static void plan_lossy(struct plan *p, int d)
{
	const struct config *c = p->cfg;
	const struct job_decl *dd = decl_of(p, d);
	int in;
	struct job *j = add_root_job(p, d, dd->needs[0], "dag", &in);
	if (!j)
		return;
	char budget[32], threads[16];
	budget_arg(budget, sizeof budget, c->job_mem_budget);
	snprintf(threads, sizeof threads, "%d", c->threads);
	const char *src = p->jobs[in].output;
	set_argv(j, "lossy-cluster", src, "-o", j->output, "--inflation",
		 dd->inflation, "--diff-factor", dd->diff_factor, "--max-refs",
		 dd->max_refs, "--mem-budget", budget, "--threads", threads, "-q",
		 NULL);
	add_input(j, src);
	add_dep(p, j, in);
	/* the report's Table 1 has a row per resolution, as the paper's:
	 * the scene at each lower resolution of the report (the root DAG
	 * cut at that depth) clustered too, for its statistics; nothing
	 * else takes these DAGs */
	for (int i = 0; i < c->nres; i++) {
		int r = c->resolutions[i];
		if (r >= c->levels)
			continue;
		char out[1200], id[200], lv[16];
		snprintf(out, sizeof out, "%s/%s/r%d.dag", p->dir, dd->name, r);
		snprintf(id, sizeof id, "%s/r%d", dd->name, r);
		snprintf(lv, sizeof lv, "%d", r);
		struct job *rj = add_job(p, d, id, out, OUT_FILE);
		if (!rj)
			continue;
		rj->mem_estimate = c->job_mem_budget;
		set_argv(rj, "lossy-cluster", src, "-o", rj->output, "--levels",
			 lv, "--inflation", dd->inflation, "--diff-factor",
			 dd->diff_factor, "--max-refs", dd->max_refs,
			 "--mem-budget", budget, "--threads", threads, "-q", NULL);
		add_input(rj, src);
		add_dep(p, rj, in);
	}
}

/* Writes `text` to `path` unless it holds exactly that already (atomic). */
static int write_if_changed(const char *path, const char *text)
{
	size_t n = strlen(text);
	FILE *f = fopen(path, "rb");
	if (f) {
		char *have = malloc(n + 1);
		size_t got = have ? fread(have, 1, n + 1, f) : 0;
		int same = have && got == n && memcmp(have, text, n) == 0;
		free(have);
		fclose(f);
		if (same)
			return 0;
	}
	struct vd_atomic a;
	if (vd_atomic_open(&a, path) != VD_OK)
		return -1;
	if (fwrite(text, 1, n, a.f) != n) {
		vd_atomic_abort(&a);
		return -1;
	}
	return vd_atomic_commit(&a) == VD_OK ? 0 : -1;
}

/* edit on the root DAG chunk with the job's script; the script's content
 * is an input, so a changed script reruns the edit and what follows. With
 * the voxelize job as a second need the edit takes its colour chunks and
 * writes the edited colours to <job>/colours (a second output, replaced
 * together with the DAG), which a colorize job needing the edit packs. */
static void plan_edit(struct plan *p, int d)
{
	const struct config *c = p->cfg;
	const struct job_decl *dd = decl_of(p, d);
	int in, vox = -1;
	if (dd->nneeds > 1 &&
	    (vox = plan_find(p, decl_of(p, dd->needs[1])->name)) < 0)
		return;
	struct job *j = add_root_job(p, d, dd->needs[0], "dag", &in);
	if (!j)
		return;
	char budget[32], threads[16], script[1200], dir[1100];
	budget_arg(budget, sizeof budget, c->job_mem_budget);
	snprintf(threads, sizeof threads, "%d", c->threads);
	path_join(dir, sizeof dir, p->dir, dd->name);
	if (dd->script_text) {
		/* inline lines: written beside the output, where the edit
		 * tool and its key read them */
		snprintf(script, sizeof script, "%s/script.txt", dir);
		if (mkdir_p(dir) != 0 ||
		    write_if_changed(script, dd->script_text) != 0) {
			fprintf(stderr, "voxdag: cannot write '%s': %s\n", script,
				strerror(errno));
			exit(1);
		}
	} else {
		snprintf(script, sizeof script, "%s", dd->script);
	}
	const char *src = p->jobs[in].output;
	if (vox >= 0) {
		char colours[1200], manifest[1200];
		path_join(colours, sizeof colours, dir, "colours");
		j->side[1] = xstrdup(colours);
		set_argv(j, "edit", src, "-o", j->output, "--script", script,
			 "--colours", p->jobs[vox].output, "--colours-out",
			 colours, "--mem-budget", budget, "--threads", threads,
			 "-q", NULL);
		/* the colour chunks through the voxelize manifest */
		path_join(manifest, sizeof manifest, p->jobs[vox].output,
			  "manifest");
		add_input(j, manifest);
		add_dep(p, j, vox);
	} else {
		set_argv(j, "edit", src, "-o", j->output, "--script", script,
			 "--mem-budget", budget, "--threads", threads, "-q",
			 NULL);
	}
	add_input(j, src);
	add_input(j, script);
	add_dep(p, j, in);
}

/* 1 when declared job d has cell jobs. */
static int has_cells(const struct plan *p, int d)
{
	for (int i = 0; i < p->n; i++)
		if (p->jobs[i].decl == d && p->jobs[i].cell)
			return 1;
	return 0;
}

/* svo-to-dag of a scene whose one cell is the whole grid (chunk level 0):
 * that cell's DAG is the root, so one job builds root.dag from it, with no
 * one-part merge after it (which would only load, re-reduce and save the
 * same DAG). Returns 0, planning nothing, when the cell is not level 0. */
static int plan_single_root(struct plan *p, int d, const char *src_dir,
			    const char *name, int src_job)
{
	const struct config *c = p->cfg;
	char in[1400], out[1200], id[200], budget[32], threads[16];
	snprintf(in, sizeof in, "%s/%s", src_dir, name);
	struct vd_chunk_header h;
	if (plan_chunk_header(in, &h) != VD_OK || h.chunk_level != 0)
		return 0;
	snprintf(out, sizeof out, "%s/%s/root.dag", p->dir, decl_of(p, d)->name);
	snprintf(id, sizeof id, "%s/root", decl_of(p, d)->name);
	uint64_t est = vd_dag_estimate_header(&h);
	budget_arg(budget, sizeof budget, dag_job_budget(c, est));
	snprintf(threads, sizeof threads, "%d", c->threads);
	struct job *j = add_job(p, d, id, out, OUT_FILE);
	if (j) {
		set_argv(j, "svo-to-dag", in, "-o", out, "--mem-budget", budget,
			 "--threads", threads, "-q", NULL);
		add_group_arg(decl_of(p, d), j);
		add_input(j, in);
		add_dep(p, j, src_job);
		j->mem_estimate = est;
		if (h.level_count > 0)
			j->voxels = h.level_nodes[h.level_count - 1];
	}
	p->cells_planned[d] = 1;
	p->merges_planned[d] = 1;
	return 1;
}

static void plan_dag_stage(struct plan *p, int d)
{
	const struct config *c = p->cfg;
	const struct job_decl *dd = decl_of(p, d);
	int src = dd->needs[0];
	const char *src_name = decl_of(p, src)->name;
	int is_dag = dd->stage->type == STAGE_SVO_TO_DAG;
	/* .sdag, not .ssvdag: that is the SymVox encoding's extension */
	const char *ext = is_dag ? "dag" : "sdag";
	const char *src_ext = is_dag ? ".svo" : ".dag";
	uint32_t kind = is_dag ? VD_KIND_DAG : dd->group == 48 ? VD_KIND_SSVDAG48
							    : VD_KIND_SSVDAG;
	if (p->merges_planned[d])
		return; /* planned whole: nothing more becomes known */
	if (!is_dag && decl_of(p, src)->stage->type != STAGE_SVO_TO_DAG) {
		plan_root_ssvdag(p, d);
		return;
	}
	/* the cells are planned once; the merges once they are all built */
	if (p->cells_planned[d]) {
		if (p->unfinished[d] == 0)
			plan_dag_merges(p, d, ext, kind);
		return;
	}
	char src_dir[1100], cells_dir[1200], dir[1100];
	path_join(dir, sizeof dir, p->dir, dd->name);
	snprintf(src_dir, sizeof src_dir, "%s/%s%s", p->dir, src_name,
		 is_dag ? "" : "/cells");
	/* the source's cells are known when voxelize finished, or all the
	 * source stage's cell jobs did (they are planned together) */
	int src_job = -1;
	if (is_dag) {
		src_job = plan_find(p, src_name);
		if (src_job < 0 || !job_finished(&p->jobs[src_job]))
			return;
	} else if (!p->cells_planned[src] || p->cells_left[src] > 0) {
		return;
	} else if (p->merges_planned[src] && stage_root_job(p, src) >= 0 &&
		   !has_cells(p, src)) {
		plan_root_ssvdag(p, d); /* the source is one root, no cells */
		return;
	}
	/* voxelize replaces its directory, so its listing is exact; a DAG
	 * stage's cells are the jobs planned for it (a listing could hold
	 * cells of an earlier configuration) */
	char **names = NULL;
	int n = 0;
	if (is_dag) {
		n = list_files(src_dir, src_ext, &names);
		if (n < 0)
			return;
		if (n == 1 && plan_single_root(p, d, src_dir, names[0], src_job)) {
			free(names[0]);
			free(names);
			return;
		}
	} else {
		names = xrealloc(NULL, ((size_t)p->n + 1) * sizeof *names);
		for (int i = 0; i < p->n; i++) {
			const char *id = p->jobs[i].id, *slash = strrchr(id, '/');
			if (p->jobs[i].decl == src && strstr(id, "/cells/")) {
				char nm[256];
				snprintf(nm, sizeof nm, "%s%s", slash + 1, src_ext);
				names[n++] = xstrdup(nm);
			}
		}
	}
	path_join(cells_dir, sizeof cells_dir, dir, "cells");
	if (n > 0 && mkdir_p(cells_dir) != 0) {
		fprintf(stderr, "voxdag: cannot create '%s': %s\n", cells_dir,
			strerror(errno));
		exit(1);
	}
	for (int i = 0; i < n; i++) {
		char in[1400], out[1400], id[300], budget[32], threads[16];
		snprintf(in, sizeof in, "%s/%s", src_dir, names[i]);
		snprintf(out, sizeof out, "%s/%.*s.%s", cells_dir,
			 (int)(strlen(names[i]) - strlen(src_ext)), names[i], ext);
		snprintf(id, sizeof id, "%s/cells/%.*s", dd->name,
			 (int)(strlen(names[i]) - strlen(src_ext)), names[i]);
		snprintf(threads, sizeof threads, "%d", c->threads);
		struct vd_chunk_header h;
		int ok = plan_chunk_header(in, &h) == VD_OK;
		/* the stage's own bound for this input */
		uint64_t est = !ok ? c->job_mem_budget : is_dag ?
			vd_dag_estimate_header(&h) : merge_share(&h, kind);
		budget_arg(budget, sizeof budget, dag_job_budget(c, est));
		struct job *j = add_job(p, d, id, out, OUT_FILE);
		if (j) {
			j->cell = 1;
			p->cells_left[d]++;
			set_argv(j, is_dag ? "svo-to-dag" : "symmetry-merge", in, "-o",
				 out, "--mem-budget", budget, "--threads", threads,
				 "-q", NULL);
			add_group_arg(dd, j);
			add_input(j, in);
			if (is_dag) {
				add_dep(p, j, src_job);
			} else {
				char sid[400];
				snprintf(sid, sizeof sid, "%s/cells/%.*s", decl_of(p, src)->name,
					 (int)(strlen(names[i]) - strlen(src_ext)), names[i]);
				int si = plan_find(p, sid);
				if (si >= 0)
					add_dep(p, j, si);
			}
			j->mem_estimate = est;
			/* voxels it handles, for the progress line (read
			 * here once, not again when it ends) */
			if (ok && h.level_count > 0)
				j->voxels = h.level_nodes[h.level_count - 1];
		}
		free(names[i]);
	}
	free(names);
	p->cells_planned[d] = 1;
	if (p->unfinished[d] == 0)
		plan_dag_merges(p, d, ext, kind); /* all fresh */
}

/* The reduction tree of DAG stage d, once its cells are built. */
static void plan_dag_merges(struct plan *p, int d, const char *ext,
			    uint32_t kind)
{
	int n = 0;
	for (int i = 0; i < p->n; i++)
		n += p->jobs[i].decl == d && p->jobs[i].cell;
	struct part *parts = xrealloc(NULL, (size_t)(n ? n : 1) * sizeof *parts);
	memset(parts, 0, (size_t)(n ? n : 1) * sizeof *parts);
	n = 0;
	for (int i = 0; i < p->n; i++)
		if (p->jobs[i].decl == d && p->jobs[i].cell) {
			parts[n].job = i;
			parts[n].path = p->jobs[i].output;
			n++;
		}
	/* The reduction tree is planned once the cells are built, from their
	 * real headers: an estimate from the inputs would be far too high
	 * (a DAG is much smaller than its SVO) and group the merges badly. */
	int all_built = n > 0;
	for (int i = 0; i < n && all_built; i++) {
		struct vd_chunk_header h;
		all_built = parts[i].job >= 0 && job_finished(&p->jobs[parts[i].job]) &&
			    plan_chunk_header(parts[i].path, &h) == VD_OK;
		if (all_built) {
			parts[i].level = (int)h.chunk_level;
			parts[i].cell = h.cell_morton;
			parts[i].share = merge_share(&h, kind);
		}
	}
	/* (a single cell at level 0 has no cell job: plan_single_root) */
	if (all_built) {
		plan_merges(p, d, parts, n, ext);
		p->merges_planned[d] = 1;
	}
	free(parts);
}

static int stage_root_job(const struct plan *p, int d)
{
	char id[200];
	snprintf(id, sizeof id, "%s/root", decl_of(p, d)->name);
	return plan_find(p, id);
}

/* 1 when declared job `a` is `d` or one it needs, directly or not. */
static int decl_needs(const struct config *c, int d, int a)
{
	if (d == a)
		return 1;
	for (int k = 0; k < c->jobs_decl[d].nneeds; k++)
		if (decl_needs(c, c->jobs_decl[d].needs[k], a))
			return 1;
	return 0;
}

/* 1 when the file at path holds exactly the n bytes of text. */
static int same_content(const char *path, const char *text, size_t n)
{
	FILE *f = fopen(path, "rb");
	if (!f)
		return 0;
	char buf[1 << 14];
	size_t off = 0, got;
	int same = 1;
	while (same && (got = fread(buf, 1, sizeof buf, f)) > 0) {
		same = off + got <= n && memcmp(buf, text + off, got) == 0;
		off += got;
	}
	same = same && !ferror(f) && off == n;
	fclose(f);
	return same;
}

static void plan_encode(struct plan *p, int d)
{
	const struct config *c = p->cfg;
	const struct job_decl *dd = decl_of(p, d);
	int dag = -1, ssv = -1, s48 = -1, want48 = 0;
	for (int k = 0; k < dd->nneeds; k++) {
		int n = dd->needs[k];
		if (stage_makes_root_dag(decl_of(p, n)->stage->type))
			dag = stage_root_job(p, n);
		else if (decl_of(p, n)->group == 48)
			want48 = 1, s48 = stage_root_job(p, n);
		else
			ssv = stage_root_job(p, n);
	}
	/* the first symmetric input is either; encode tells them by kind */
	if (ssv < 0) {
		ssv = s48;
		s48 = -1;
		want48 = 0;
	}
	if (dag < 0 || ssv < 0 || (want48 && s48 < 0))
		return;
	char out[1100], budget[32], minl[16], threads[16];
	path_join(out, sizeof out, p->dir, dd->name);
	struct job *j = add_job(p, d, dd->name, out, OUT_DIR);
	if (!j)
		return;
	int min = c->levels;
	for (int i = 0; i < c->nres; i++)
		min = c->resolutions[i] < min ? c->resolutions[i] : min;
	snprintf(minl, sizeof minl, "%d", min);
	budget_arg(budget, sizeof budget, c->job_mem_budget);
	snprintf(threads, sizeof threads, "%d", c->threads);
	const struct job *jd = &p->jobs[dag], *js = &p->jobs[ssv];
	const char *head[] = {jd->output, js->output, "-o", out, "--name",
			      c->name, "--min-level", minl, "--mem-budget",
			      budget, "--threads", threads, "-q"};
	size_t nh = sizeof head / sizeof *head;
	/* Table 1's seconds: the statistics of every DAG job (not part of
	 * the key: timings are not content), one path a line in a file, so
	 * the command line does not grow with the cells (the kernel's limit
	 * is near 25,000 arguments of this length) */
	char list[1200];
	snprintf(list, sizeof list, "%s/%s.stats-list", p->dir, dd->name);
	char *text = NULL;
	size_t len = 0;
	FILE *m = open_memstream(&text, &len);
	if (!m) {
		fprintf(stderr, "voxdag: out of memory\n");
		exit(1);
	}
	for (int i = 0; i < p->n; i++) {
		enum stage_type t = decl_of(p, p->jobs[i].decl)->stage->type;
		/* only this scene's: a lossy or edited scene's own
		 * symmetry-merge is not the lossless one's work */
		/* beside the SSVDAG, the 48-group's merge is not Table 1's
		 * symmetry-merge time */
		if (s48 >= 0 && t == STAGE_SYMMETRY_MERGE &&
		    decl_of(p, p->jobs[i].decl)->group == 48)
			continue;
		if ((t == STAGE_SVO_TO_DAG || t == STAGE_SYMMETRY_MERGE) &&
		    decl_needs(p->cfg, d, p->jobs[i].decl))
			fprintf(m, "%s.stats.json\n", p->jobs[i].output);
	}
	if (fclose(m) != 0) {
		fprintf(stderr, "voxdag: out of memory\n");
		exit(1);
	}
	/* written only when it changes: a rerun on a full disk that has
	 * nothing left to build must not fail here */
	if (!same_content(list, text, len)) {
		struct vd_atomic a;
		int bad = mkdir_p(p->dir) != 0 ||
			  vd_atomic_open(&a, list) != VD_OK;
		if (!bad && fwrite(text, 1, len, a.f) != len) {
			vd_atomic_abort(&a);
			bad = 1;
		} else if (!bad) {
			bad = vd_atomic_commit(&a) != VD_OK;
		}
		if (bad) {
			fprintf(stderr, "voxdag: cannot write '%s': %s\n", list,
				strerror(errno));
			exit(1);
		}
	}
	free(text);
	char path[1100];
	snprintf(path, sizeof path, "%s/encode", bin_dir());
	j->argv = xrealloc(NULL, (nh + 5) * sizeof *j->argv);
	int z = 0;
	j->argv[z++] = xstrdup(path);
	for (size_t q = 0; q < nh; q++) {
		j->argv[z++] = xstrdup(head[q]);
		if (q == 1 && s48 >= 0) /* the third input */
			j->argv[z++] = xstrdup(p->jobs[s48].output);
	}
	j->argv[z++] = xstrdup("--stats-list");
	j->argv[z++] = xstrdup(list);
	j->argv[z] = NULL;
	add_input(j, jd->output);
	add_input(j, js->output);
	add_dep(p, j, dag);
	add_dep(p, j, ssv);
	if (s48 >= 0) {
		add_input(j, p->jobs[s48].output);
		add_dep(p, j, s48);
	}
	j->mem_estimate = c->job_mem_budget;
}

/* colorize: the voxelize output's colour chunks into one packed colours
 * file of the job's method (a directory with its manifest). */
static void plan_colorize(struct plan *p, int d)
{
	const struct config *c = p->cfg;
	const struct job_decl *dd = decl_of(p, d);
	/* the voxelize job's colour chunks, or an edit job's edited ones */
	int edit = decl_of(p, dd->needs[0])->stage->type == STAGE_EDIT;
	int vox = edit ? stage_root_job(p, dd->needs[0])
		       : plan_find(p, decl_of(p, dd->needs[0])->name);
	if (vox < 0)
		return;
	const char *src = edit ? p->jobs[vox].side[1] : p->jobs[vox].output;
	char out[1100], threads[16];
	path_join(out, sizeof out, p->dir, dd->name);
	struct job *j = add_job(p, d, dd->name, out, OUT_DIR);
	if (!j)
		return;
	snprintf(threads, sizeof threads, "%d", c->threads);
	const char *args[24];
	int na = 0;
	const char *head[] = {src, "-o", out, "--method",
			      dd->method, "--threads", threads, "-q"};
	for (size_t i = 0; i < sizeof head / sizeof *head; i++)
		args[na++] = head[i];
	if (*dd->max_error)
		args[na++] = "--max-error", args[na++] = dd->max_error;
	if (*dd->weight_bits)
		args[na++] = "--weight-bits", args[na++] = dd->weight_bits;
	if (*dd->palette_colours)
		args[na++] = "--palette-colours", args[na++] = dd->palette_colours;
	if (dd->lossless)
		args[na++] = "--lossless";
	args[na] = NULL;
	set_argv_list(j, "colorize", args);
	/* a directory is fingerprinted through its manifest: every file's
	 * checksum, the colour chunks' too */
	char manifest[1200];
	path_join(manifest, sizeof manifest, src, "manifest");
	add_input(j, manifest);
	add_dep(p, j, vox);
	j->mem_estimate = c->job_mem_budget;
}

/* The symmetric encoding render reads from an encode declaration's
 * output: "ssvdag" when it has a group 8 symmetry-merge need, else
 * "ssvdag48". */
static const char *enc_sym_ext(const struct plan *p, int enc_decl)
{
	const struct job_decl *e = decl_of(p, enc_decl);
	for (int k = 0; k < e->nneeds; k++) {
		const struct job_decl *n = decl_of(p, e->needs[k]);
		if (n->stage->type == STAGE_SYMMETRY_MERGE && n->group != 48)
			return "ssvdag";
	}
	return "ssvdag48";
}

/* A picture of the scene for the report, traced through the SSVDAG
 * encoding that encode wrote (.ssvdag48 for the 48-group's). */
static void plan_render(struct plan *p, int d)
{
	const struct config *c = p->cfg;
	const struct job_decl *dd = decl_of(p, d);
	int enc = plan_find(p, decl_of(p, dd->needs[0])->name);
	/* with a second encode job: its scene's differing voxels in red */
	int other = dd->nneeds > 1 ? plan_find(p, decl_of(p, dd->needs[1])->name)
				   : -1;
	int colours = other >= 0 &&
		      decl_of(p, dd->needs[1])->stage->type == STAGE_COLORIZE;
	if (enc < 0 || (dd->nneeds > 1 && other < 0))
		return;
	char out[1100], in[1300], threads[16];
	snprintf(out, sizeof out, "%s/%s.png", p->dir, dd->name);
	struct job *j = add_job(p, d, dd->name, out, OUT_FILE);
	if (!j)
		return;
	snprintf(in, sizeof in, "%s/%s.%s", p->jobs[enc].output, c->name,
		 enc_sym_ext(p, dd->needs[0]));
	snprintf(threads, sizeof threads, "%d", c->threads * c->jobs);
	if (colours) {
		char in2[1300];
		snprintf(in2, sizeof in2, "%s/colours.%s", p->jobs[other].output,
			 decl_of(p, dd->needs[1])->method);
		set_argv(j, "render", in, "-o", out, "--size", "960x720",
			 "--camera", "iso", "--colours", in2, "--threads", threads,
			 "-q", NULL);
		add_input(j, in2);
		add_dep(p, j, other);
	} else if (other >= 0) {
		char in2[1300];
		snprintf(in2, sizeof in2, "%s/%s.%s", p->jobs[other].output,
			 c->name, enc_sym_ext(p, dd->needs[1]));
		set_argv(j, "render", in, "-o", out, "--size", "960x720",
			 "--camera", "iso", "--diff", in2, "--threads", threads,
			 "-q", NULL);
		add_input(j, in2);
		add_dep(p, j, other);
	} else {
		set_argv(j, "render", in, "-o", out, "--size", "960x720",
			 "--camera", "iso", "--threads", threads, "-q", NULL);
	}
	add_input(j, in);
	add_dep(p, j, enc);
	j->mem_estimate = c->job_mem_budget;
}

int plan_expand(struct plan *p)
{
	const struct config *c = p->cfg;
	snprintf(p->dir, sizeof p->dir, "%s", c->outputs);
	keys_open(p->dir, 0); /* read only, unless the runner opened it */
	int before;
	do {
		before = p->n;
		for (int d = 0; d < c->njobs; d++) {
			switch (c->jobs_decl[d].stage->type) {
			case STAGE_VOXELIZE:
				plan_voxelize(p, d);
				break;
			case STAGE_SVO_TO_DAG:
			case STAGE_SYMMETRY_MERGE:
				plan_dag_stage(p, d);
				break;
			case STAGE_ENCODE:
				plan_encode(p, d);
				break;
			case STAGE_RENDER:
				plan_render(p, d);
				break;
			case STAGE_LOSSY:
				plan_lossy(p, d);
				break;
			case STAGE_EDIT:
				plan_edit(p, d);
				break;
			case STAGE_COLORIZE:
				plan_colorize(p, d);
				break;
			default:
				break;
			}
		}
		/* newly planned jobs that a previous run finished count as
		 * finished now, which may reveal further jobs; only once
		 * their own inputs are final (dependencies come first) */
		for (int i = before; i < p->n; i++) {
			struct job *j = &p->jobs[i];
			int ready = j->state == JOB_PENDING && j->nwait == 0 &&
				    j->nbad == 0;
			char why[600]; /* the runner says it when it reruns j */
			if (ready && job_is_fresh(j, why, sizeof why) == 1)
				job_set_state(p, j, JOB_SKIPPED);
			else if (ready && j->key_absent)
				j->fresh_checked = 1; /* no need to look again */
		}
	} while (p->n != before);
	/* the graph is whole when every declared job has its final job */
	p->expanded = 1;
	for (int d = 0; d < c->njobs; d++) {
		char id[200];
		snprintf(id, sizeof id, "%s%s", c->jobs_decl[d].name,
			 stage_makes_root_dag(c->jobs_decl[d].stage->type) ||
			 c->jobs_decl[d].stage->type == STAGE_SYMMETRY_MERGE
				 ? "/root" : "");
		if (plan_find(p, id) < 0)
			p->expanded = 0;
	}
	return 0;
}

void plan_free(struct plan *p)
{
	for (int i = 0; i < p->n; i++) {
		struct job *j = &p->jobs[i];
		for (int k = 0; j->argv && j->argv[k]; k++)
			free(j->argv[k]);
		free(j->argv);
		for (int k = 0; k < j->ninputs; k++)
			free(j->inputs[k]);
		free(j->inputs);
		free(j->deps);
		free(j->rdeps);
		free(j->id);
		free(j->output);
		free(j->side[0]);
		free(j->side[1]);
	}
	free(p->jobs);
	free(p->index);
	memset(p, 0, sizeof *p);
}
