/* view.c - `voxdag view`: serves a pipeline's output directory and the
 * browser viewer (viewer/ at the top of the tree) on 127.0.0.1.
 *
 * URL space (README.md, "Looking at a scene in the browser", says the
 * same for users):
 *   /                  the page (viewer/index.html)
 *   /NAME              a static file of the page's directory (one level)
 *   /scene.json        generated: the scene's name and every file the
 *                      manifests of the output's subdirectories list
 *   /data/DIR/FILE     a file of the output directory
 *   /colours/DIR/FILE  a colour source of the output directory (colorize's
 *                      colours.raw/.vbr/.palette, or voxelize's directory
 *                      of colour chunks) decoded by the library into the
 *                      scene's colour array, 3 bytes (R, G, B) per voxel
 *                      in Morton order: the page looks colours up in it
 *                      through per-node voxel counts. Decoding here means
 *                      every method the library reads (and any it will)
 *                      reaches the page without a decoder of its own.
 * Nothing else is reachable: every path component must be a plain name
 * (no "", ".", "..", no leading '.', so no hidden files such as .lock),
 * the resolved path (symlinks followed) must stay under the served
 * directory, and only regular files are served, so there is no listing.
 * libmicrohttpd hands us the path already percent-decoded, so "%2e%2e"
 * and "%2f" arrive as ".." and "/" and meet the same checks.
 *
 * A file listed in a manifest beside it is checked against it
 * (vd_manifest_check_file: size and XXH3) before it is served; a file
 * that fails is answered 409 with the reason as text, which the page
 * shows. The check is cached per (path, size, mtime). */
#include "pipeline.h"

#include <arpa/inet.h>
#include <ctype.h>
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <getopt.h>
#include <inttypes.h>
#include <limits.h>
#include <microhttpd.h>
#include <netinet/in.h>
#include <pthread.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

static const char view_usage[] =
	"usage: voxdag view CONFIG|OUT_DIR [options]\n"
	"\n"
	"Serves the output directory of the pipeline CONFIG (or the directory\n"
	"OUT_DIR) and the browser viewer on 127.0.0.1, prints the URL and runs\n"
	"until interrupted. Only files under the output directory and the\n"
	"viewer's own files are served; no listing.\n"
	"\n"
	"  -p, --port N        TCP port (default 8642; 0: any free port)\n"
	"  -F, --camera-file F start the page at the camera of F, the JSON\n"
	"                      file render --camera-file reads\n"
	"                      (schemas/render-outputs.md): the printed URL\n"
	"                      carries it; the page's \"camera file\" button\n"
	"                      saves the current one\n"
	"      --static DIR    the viewer's files (default: viewer/ beside the\n"
	"                      directory holding bin/voxdag's out/, else\n"
	"                      ./viewer)\n"
	"  -h, --help          this text\n"
	"\n"
	"Exit status: 0 interrupted, 1 failure (no such directory, port busy),\n"
	"2 usage.\n";

struct checked {
	char path[PATH_MAX];
	off_t size;
	struct timespec mtime;
	int ok;
	char why[256];
};

struct server {
	char data_root[PATH_MAX];   /* realpath of the output directory */
	char static_root[PATH_MAX]; /* realpath of the viewer directory */
	char name[256];
	pthread_mutex_t lock;       /* guards cache */
	struct checked cache[64];
	int ncache;
};

static int is_plain_name(const char *s, size_t n)
{
	if (n == 0 || s[0] == '.')
		return 0;
	for (size_t i = 0; i < n; i++)
		if (s[i] == '\\' || (unsigned char)s[i] < 0x20)
			return 0;
	return 1;
}

/* Joins root and the URL path rel ("a/b") into out after checking every
 * component; resolves symlinks and checks the result stays under root.
 * Returns 0, or an HTTP status (403 outside, 404 missing). */
static int resolve(const char *root, const char *rel, char out[PATH_MAX])
{
	const char *p = rel;
	while (*p) {
		const char *slash = strchr(p, '/');
		size_t n = slash ? (size_t)(slash - p) : strlen(p);
		if (!is_plain_name(p, n))
			return 403;
		p += n;
		if (*p == '/')
			p++;
		if (slash && !*p)
			return 403; /* trailing slash: a directory */
	}
	char joined[PATH_MAX * 2];
	if (snprintf(joined, sizeof joined, "%s/%s", root, rel) >= PATH_MAX)
		return 404;
	if (!realpath(joined, out))
		return errno == ENOENT || errno == ENOTDIR ? 404 : 403;
	size_t rn = strlen(root);
	if (strncmp(out, root, rn) != 0 || out[rn] != '/')
		return 403;
	return 0;
}

static const char *content_type(const char *path)
{
	static const struct {
		const char *ext, *type;
	} types[] = {
		{".html", "text/html; charset=utf-8"},
		{".js", "text/javascript; charset=utf-8"},
		{".mjs", "text/javascript; charset=utf-8"},
		{".css", "text/css; charset=utf-8"},
		{".json", "application/json"},
		{".png", "image/png"},
		{".md", "text/markdown; charset=utf-8"},
		{".csv", "text/csv; charset=utf-8"},
		{".svg", "image/svg+xml"},
	};
	size_t n = strlen(path);
	for (size_t i = 0; i < sizeof types / sizeof types[0]; i++) {
		size_t e = strlen(types[i].ext);
		if (n > e && !strcmp(path + n - e, types[i].ext))
			return types[i].type;
	}
	return "application/octet-stream";
}

/* Queues r (NULL: allocation failed) as the answer with its type, never
 * cached (the pipeline may rewrite any file), and releases it. */
static enum MHD_Result send_response(struct MHD_Connection *c, unsigned status,
				     struct MHD_Response *r, const char *type)
{
	if (!r)
		return MHD_NO;
	MHD_add_response_header(r, "Content-Type", type);
	MHD_add_response_header(r, "Cache-Control", "no-store");
	enum MHD_Result ret = MHD_queue_response(c, status, r);
	MHD_destroy_response(r);
	return ret;
}

static enum MHD_Result reply_text(struct MHD_Connection *c, unsigned status,
				  const char *text)
{
	return send_response(c, status, MHD_create_response_from_buffer(
		strlen(text), (void *)text, MHD_RESPMEM_MUST_COPY),
		"text/plain; charset=utf-8");
}

/* 1 when `path` (under the data root) may be served: no manifest beside
 * it, or it matches its manifest entry; else 0 with the reason in why. */
static int manifest_ok(struct server *s, const char *path, const struct stat *st,
		       char *why, size_t why_size)
{
	char dir[PATH_MAX];
	snprintf(dir, sizeof dir, "%s", path);
	char *slash = strrchr(dir, '/');
	if (!slash)
		return 1;
	snprintf(slash, sizeof dir - (size_t)(slash - dir), "/manifest");
	if (access(dir, F_OK) != 0 || !strcmp(strrchr(path, '/') + 1, "manifest"))
		return 1;
	pthread_mutex_lock(&s->lock);
	for (int i = 0; i < s->ncache; i++) {
		struct checked *k = &s->cache[i];
		if (!strcmp(k->path, path) && k->size == st->st_size &&
		    k->mtime.tv_sec == st->st_mtim.tv_sec &&
		    k->mtime.tv_nsec == st->st_mtim.tv_nsec) {
			int ok = k->ok;
			snprintf(why, why_size, "%s", k->why);
			pthread_mutex_unlock(&s->lock);
			return ok;
		}
	}
	pthread_mutex_unlock(&s->lock);
	/* vd_error_detail() is per thread: the check and its message stay
	 * on this connection's thread */
	int ok = vd_manifest_check_file(path) == VD_OK;
	snprintf(why, why_size, "%s", ok ? "" : vd_error_detail());
	pthread_mutex_lock(&s->lock);
	struct checked *k = &s->cache[s->ncache < 64 ? s->ncache++ : 0];
	snprintf(k->path, sizeof k->path, "%s", path);
	k->size = st->st_size;
	k->mtime = st->st_mtim;
	k->ok = ok;
	snprintf(k->why, sizeof k->why, "%s", why);
	pthread_mutex_unlock(&s->lock);
	return ok;
}

/* Parses a single "bytes=A-B", "bytes=A-" or "bytes=-N" against size.
 * Returns 0 and the inclusive range, 1 for an unsatisfiable or
 * unsupported one (answered 416). */
static int parse_range(const char *h, uint64_t size, uint64_t *lo, uint64_t *hi)
{
	if (strncmp(h, "bytes=", 6) != 0 || strchr(h, ','))
		return 1;
	h += 6;
	char *end;
	if (*h == '-') {
		errno = 0;
		unsigned long long n = strtoull(h + 1, &end, 10);
		if (errno || *end || end == h + 1 || n == 0 || size == 0)
			return 1;
		*lo = n >= size ? 0 : size - n;
		*hi = size - 1;
		return 0;
	}
	if (*h < '0' || *h > '9')
		return 1;
	errno = 0;
	unsigned long long a = strtoull(h, &end, 10);
	if (errno || *end != '-')
		return 1;
	const char *b = end + 1;
	unsigned long long z = size ? size - 1 : 0;
	if (*b) {
		if (*b < '0' || *b > '9')
			return 1;
		z = strtoull(b, &end, 10);
		if (errno || *end)
			return 1;
		if (z >= size)
			z = size - 1;
	}
	if (a >= size || z < a)
		return 1;
	*lo = a;
	*hi = z;
	return 0;
}

static enum MHD_Result serve_file(struct server *s, struct MHD_Connection *c,
				  const char *path, int check)
{
	int fd = open(path, O_RDONLY | O_CLOEXEC);
	if (fd < 0)
		return reply_text(c, MHD_HTTP_NOT_FOUND, "not found\n");
	struct stat st;
	if (fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
		close(fd);
		return reply_text(c, MHD_HTTP_NOT_FOUND, "not found\n");
	}
	char why[256];
	if (check && !manifest_ok(s, path, &st, why, sizeof why)) {
		close(fd);
		char msg[400];
		snprintf(msg, sizeof msg, "%s\n", why);
		return reply_text(c, MHD_HTTP_CONFLICT, msg);
	}
	uint64_t size = (uint64_t)st.st_size, lo = 0, hi = size ? size - 1 : 0;
	unsigned status = MHD_HTTP_OK;
	const char *range = MHD_lookup_connection_value(c, MHD_HEADER_KIND,
							MHD_HTTP_HEADER_RANGE);
	if (range) {
		if (parse_range(range, size, &lo, &hi)) {
			close(fd);
			char cr[64];
			snprintf(cr, sizeof cr, "bytes */%" PRIu64, size);
			struct MHD_Response *r = MHD_create_response_from_buffer(
				0, NULL, MHD_RESPMEM_PERSISTENT);
			if (r)
				MHD_add_response_header(r, "Content-Range", cr);
			return send_response(c, MHD_HTTP_RANGE_NOT_SATISFIABLE,
					     r, "text/plain; charset=utf-8");
		}
		status = MHD_HTTP_PARTIAL_CONTENT;
	}
	uint64_t len = size ? hi - lo + 1 : 0;
	struct MHD_Response *r = MHD_create_response_from_fd_at_offset64(
		len, fd, lo);
	if (!r) {
		close(fd);
		return MHD_NO;
	}
	MHD_add_response_header(r, "Accept-Ranges", "bytes");
	if (status == MHD_HTTP_PARTIAL_CONTENT) {
		char cr[96];
		snprintf(cr, sizeof cr, "bytes %" PRIu64 "-%" PRIu64 "/%" PRIu64,
			 lo, hi, size);
		MHD_add_response_header(r, "Content-Range", cr);
	}
	return send_response(c, status, r, content_type(path));
}

/* Appends s to the growing buffer as a JSON string. */
static int json_str(char **buf, size_t *len, size_t *cap, const char *s)
{
	size_t need = *len + 2 * strlen(s) * 6 + 8;
	if (need > *cap) {
		size_t ncap = need * 2;
		char *nb = realloc(*buf, ncap);
		if (!nb)
			return -1;
		*buf = nb;
		*cap = ncap;
	}
	char *o = *buf + *len;
	*o++ = '"';
	for (; *s; s++) {
		unsigned char ch = (unsigned char)*s;
		if (ch == '"' || ch == '\\') {
			*o++ = '\\';
			*o++ = (char)ch;
		} else if (ch < 0x20) {
			o += sprintf(o, "\\u%04x", ch);
		} else {
			*o++ = (char)ch;
		}
	}
	*o++ = '"';
	*len = (size_t)(o - *buf);
	return 0;
}

static int json_raw(char **buf, size_t *len, size_t *cap, const char *s)
{
	size_t n = strlen(s);
	if (*len + n + 1 > *cap) {
		size_t ncap = (*len + n + 1) * 2;
		char *nb = realloc(*buf, ncap);
		if (!nb)
			return -1;
		*buf = nb;
		*cap = ncap;
	}
	memcpy(*buf + *len, s, n + 1);
	*len += n;
	return 0;
}

static int by_name(const void *a, const void *b)
{
	return strcmp(*(char *const *)a, *(char *const *)b);
}

/* scene.json: {"name": N, "files": [{"path": "DIR/FILE", "size": S}, ...]}
 * for every file the manifests of the output's immediate subdirectories
 * list (what the page may load), directories in name order. */
static enum MHD_Result serve_scene(struct server *s, struct MHD_Connection *c)
{
	char *buf = NULL;
	size_t len = 0, cap = 0;
	int err = json_raw(&buf, &len, &cap, "{\"name\": ") ||
		  json_str(&buf, &len, &cap, s->name) ||
		  json_raw(&buf, &len, &cap, ", \"files\": [");
	char cmd_dirs[PATH_MAX + 8];
	snprintf(cmd_dirs, sizeof cmd_dirs, "%s", s->data_root);
	DIR *d = opendir(cmd_dirs);
	char *names[512];
	int nn = 0;
	if (d) {
		struct dirent *e;
		while ((e = readdir(d)) && nn < 512)
			if (e->d_name[0] != '.')
				names[nn++] = strdup(e->d_name);
		closedir(d);
	}
	qsort(names, (size_t)nn, sizeof names[0], by_name);
	int first = 1;
	for (int i = 0; i < nn; i++) {
		char mpath[PATH_MAX * 2];
		snprintf(mpath, sizeof mpath, "%s/%s/manifest", s->data_root,
			 names[i] ? names[i] : "");
		FILE *f = names[i] ? fopen(mpath, "r") : NULL;
		if (f) {
			char line[1200];
			int lineno = 0;
			while (fgets(line, sizeof line, f)) {
				if (lineno++ == 0)
					continue;
				char sum[32], fname[1024];
				unsigned long long size;
				if (sscanf(line, "%31s %llu %1023[^\n]", sum, &size,
					   fname) != 3)
					continue;
				char path[1300], num[32];
				snprintf(path, sizeof path, "%s/%s", names[i], fname);
				snprintf(num, sizeof num, "%llu", size);
				err = err || json_raw(&buf, &len, &cap,
						      first ? "{\"path\": " : ", {\"path\": ") ||
				      json_str(&buf, &len, &cap, path) ||
				      json_raw(&buf, &len, &cap, ", \"size\": ") ||
				      json_raw(&buf, &len, &cap, num) ||
				      json_raw(&buf, &len, &cap, "}");
				first = 0;
			}
			fclose(f);
		}
		free(names[i]);
	}
	err = err || json_raw(&buf, &len, &cap, "]}\n");
	if (err) {
		free(buf);
		return reply_text(c, MHD_HTTP_INTERNAL_SERVER_ERROR,
				  "out of memory\n");
	}
	struct MHD_Response *r = MHD_create_response_from_buffer(
		len, buf, MHD_RESPMEM_MUST_FREE);
	if (!r)
		free(buf);
	return send_response(c, MHD_HTTP_OK, r, "application/json");
}

/* The colour array of the source at `path` (checked by
 * vd_colour_source_open against its manifest or SVO chunks), or 409 with
 * the reason. */
static enum MHD_Result serve_colours(struct MHD_Connection *c, const char *path)
{
	struct vd_colour_source src = {0};
	if (vd_colour_source_open(&src, path)) {
		char msg[600];
		snprintf(msg, sizeof msg, "cannot read colours: %s\n",
			 vd_error_detail());
		vd_colour_source_release(&src);
		return reply_text(c, MHD_HTTP_CONFLICT, msg);
	}
	if (src.voxels > ((uint64_t)1 << 31) / 3) {
		vd_colour_source_release(&src);
		return reply_text(c, MHD_HTTP_CONFLICT,
				  "cannot read colours: more than 2^31 bytes\n");
	}
	size_t n = (size_t)src.voxels;
	uint8_t *rgb = malloc(3 * n + 1);
	if (!rgb) {
		vd_colour_source_release(&src);
		return reply_text(c, MHD_HTTP_INTERNAL_SERVER_ERROR,
				  "out of memory\n");
	}
	for (size_t i = 0; i < n; i++)
		src.get(&src, i, rgb + 3 * i);
	char levels[16];
	snprintf(levels, sizeof levels, "%d", src.levels);
	vd_colour_source_release(&src);
	struct MHD_Response *r = MHD_create_response_from_buffer(
		3 * n, rgb, MHD_RESPMEM_MUST_FREE);
	if (!r)
		free(rgb);
	else
		MHD_add_response_header(r, "X-Voxdag-Levels", levels);
	return send_response(c, MHD_HTTP_OK, r, "application/octet-stream");
}

static enum MHD_Result handle(void *cls, struct MHD_Connection *c,
			      const char *url, const char *method,
			      const char *version, const char *upload_data,
			      size_t *upload_data_size, void **req_cls)
{
	(void)version;
	(void)upload_data;
	struct server *s = cls;
	if (strcmp(method, "GET") && strcmp(method, "HEAD"))
		return reply_text(c, MHD_HTTP_METHOD_NOT_ALLOWED,
				  "only GET and HEAD\n");
	if (*upload_data_size)
		return reply_text(c, MHD_HTTP_BAD_REQUEST, "no body expected\n");
	(void)req_cls;
	if (url[0] != '/')
		return reply_text(c, MHD_HTTP_BAD_REQUEST, "bad path\n");
	/* a NUL decoded from %00 would hide the rest of the path */
	if (strlen(url) != strcspn(url, "\r\n"))
		return reply_text(c, MHD_HTTP_BAD_REQUEST, "bad path\n");
	const char *rel = url + 1;
	const char *root = s->static_root;
	int check = 0, colours = 0;
	if (!*rel)
		rel = "index.html";
	else if (!strcmp(rel, "scene.json"))
		return serve_scene(s, c);
	else if (!strncmp(rel, "data/", 5)) {
		rel += 5;
		root = s->data_root;
		check = 1;
	} else if (!strncmp(rel, "colours/", 8)) {
		rel += 8;
		root = s->data_root;
		colours = 1;
	} else if (strchr(rel, '/')) {
		return reply_text(c, MHD_HTTP_NOT_FOUND, "not found\n");
	}
	char path[PATH_MAX];
	int status = resolve(root, rel, path);
	if (status == 403)
		return reply_text(c, MHD_HTTP_FORBIDDEN, "forbidden\n");
	if (status)
		return reply_text(c, MHD_HTTP_NOT_FOUND, "not found\n");
	if (colours)
		return serve_colours(c, path);
	return serve_file(s, c, path, check);
}

/* The viewer's directory: --static, else the first of DIR/viewer and
 * DIR/share/voxdag/viewer (`make install`) holding index.html, for DIR
 * each directory above the executable's (out/bin/voxdag -> the source
 * tree's viewer/), else ./viewer. */
static int find_static(const char *given, char out[PATH_MAX])
{
	if (given)
		return realpath(given, out) ? 0 : -1;
	char exe[PATH_MAX];
	ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 32);
	static const char *const under[] = {"viewer", "share/voxdag/viewer"};
	if (n > 0) {
		exe[n] = 0;
		for (int up = 0; up < 3; up++) {
			char *slash = strrchr(exe, '/');
			if (!slash)
				break;
			*slash = 0;
			for (int i = 0; i < 2; i++) {
				char cand[PATH_MAX + 40];
				snprintf(cand, sizeof cand, "%s/%s/index.html", exe,
					 under[i]);
				if (access(cand, R_OK) == 0) {
					snprintf(cand, sizeof cand, "%s/%s", exe,
						 under[i]);
					return realpath(cand, out) ? 0 : -1;
				}
			}
		}
	}
	return realpath("viewer", out) ? 0 : -1;
}

static volatile sig_atomic_t stop;

static void on_signal(int sig)
{
	(void)sig;
	stop = 1;
}

/* "?camera=..." for the camera file `path`: read and checked as render
 * reads it, written back as JSON (17 significant digits, so the page
 * gets render's doubles) and percent-encoded. */
static int camera_query(const char *path, char *out, size_t cap)
{
	struct vd_camera cam;
	int w = 0, h = 0;
	if (vd_camera_read(path, &cam, &w, &h)) {
		fprintf(stderr, "voxdag: camera file '%s': %s\n", path,
			vd_error_detail());
		return -1;
	}
	char json[512];
	int n = snprintf(json, sizeof json,
			 "{\"eye\":[%.17g,%.17g,%.17g],\"target\":[%.17g,%.17g,"
			 "%.17g],\"up\":[%.17g,%.17g,%.17g],\"fov\":%.17g",
			 cam.eye[0], cam.eye[1], cam.eye[2], cam.target[0],
			 cam.target[1], cam.target[2], cam.up[0], cam.up[1],
			 cam.up[2], cam.fov_deg);
	if (w > 0 && h > 0)
		n += snprintf(json + n, sizeof json - (size_t)n,
			      ",\"width\":%d,\"height\":%d", w, h);
	snprintf(json + n, sizeof json - (size_t)n, "}");
	size_t k = (size_t)snprintf(out, cap, "?camera=");
	for (const char *p = json; *p && k + 4 < cap; p++) {
		unsigned char ch = (unsigned char)*p;
		if (isalnum(ch) || strchr("-._~", ch))
			out[k++] = (char)ch;
		else
			k += (size_t)snprintf(out + k, cap - k, "%%%02X", ch);
	}
	out[k] = '\0';
	return 0;
}

int view_main(int argc, char **argv)
{
	static const struct option longopts[] = {
		{"port", required_argument, NULL, 'p'},
		{"static", required_argument, NULL, 'S'},
		{"camera-file", required_argument, NULL, 'F'},
		{"help", no_argument, NULL, 'h'},
		{NULL, 0, NULL, 0},
	};
	int port = 8642;
	const char *static_dir = NULL, *camera_file = NULL;
	int c;
	optind = 1;
	while ((c = getopt_long(argc, argv, "p:F:h", longopts, NULL)) != -1) {
		if (c == 'p') {
			char *end;
			errno = 0;
			long v = strtol(optarg, &end, 10);
			if (errno || *end || !*optarg || v < 0 || v > 65535) {
				fprintf(stderr, "voxdag: --port '%s' is not a port "
					"number 0..65535\nTry 'voxdag view "
					"--help'.\n", optarg);
				return 2;
			}
			port = (int)v;
		} else if (c == 'S') {
			static_dir = optarg;
		} else if (c == 'F') {
			camera_file = optarg;
		} else if (c == 'h') {
			fputs(view_usage, stdout);
			return 0;
		} else {
			fprintf(stderr, "Try 'voxdag view --help'.\n");
			return 2;
		}
	}
	if (argc - optind != 1) {
		fprintf(stderr, "voxdag: view needs one CONFIG or OUT_DIR\nTry "
			"'voxdag view --help'.\n");
		return 2;
	}
	const char *arg = argv[optind];
	char query[2048] = "";
	if (camera_file && camera_query(camera_file, query, sizeof query))
		return 1;
	static struct server s;
	pthread_mutex_init(&s.lock, NULL);
	struct stat st;
	char dir[1024];
	if (stat(arg, &st) != 0) {
		fprintf(stderr, "voxdag: cannot serve '%s': %s\n", arg,
			strerror(errno));
		return 1;
	}
	if (S_ISDIR(st.st_mode)) {
		snprintf(dir, sizeof dir, "%s", arg);
		const char *b = strrchr(arg, '/');
		snprintf(s.name, sizeof s.name, "%s", b && b[1] ? b + 1 : arg);
	} else {
		struct config cfg;
		if (config_load(&cfg, arg))
			return 1;
		snprintf(dir, sizeof dir, "%s", cfg.outputs);
		snprintf(s.name, sizeof s.name, "%s", cfg.name);
		config_release(&cfg);
	}
	if (!realpath(dir, s.data_root) ||
	    stat(s.data_root, &st) != 0 || !S_ISDIR(st.st_mode)) {
		fprintf(stderr, "voxdag: cannot serve '%s': %s (run the "
			"pipeline first)\n", dir,
			errno ? strerror(errno) : "not a directory");
		return 1;
	}
	if (find_static(static_dir, s.static_root) ||
	    access(s.static_root, R_OK) != 0) {
		fprintf(stderr, "voxdag: cannot find the viewer's files '%s': %s "
			"(give --static DIR)\n",
			static_dir ? static_dir : "viewer", strerror(errno));
		return 1;
	}
	/* our own socket, so a busy port is one clear line with its cause */
	int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
	if (fd < 0) {
		fprintf(stderr, "voxdag: cannot open a socket: %s\n",
			strerror(errno));
		return 1;
	}
	int one = 1;
	setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
	struct sockaddr_in sa = {.sin_family = AF_INET,
				 .sin_port = htons((uint16_t)port)};
	sa.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
	socklen_t sl = sizeof sa;
	if (bind(fd, (struct sockaddr *)&sa, sizeof sa) != 0 ||
	    listen(fd, 64) != 0 ||
	    getsockname(fd, (struct sockaddr *)&sa, &sl) != 0) {
		fprintf(stderr, "voxdag: cannot listen on 127.0.0.1:%d: %s\n",
			port, strerror(errno));
		close(fd);
		return 1;
	}
	struct MHD_Daemon *d = MHD_start_daemon(
		MHD_USE_INTERNAL_POLLING_THREAD | MHD_USE_THREAD_PER_CONNECTION,
		0, NULL, NULL, handle, &s, MHD_OPTION_LISTEN_SOCKET, fd,
		MHD_OPTION_CONNECTION_TIMEOUT, (unsigned)60, MHD_OPTION_END);
	if (!d) {
		fprintf(stderr, "voxdag: cannot start the HTTP server on "
			"127.0.0.1:%d\n", ntohs(sa.sin_port));
		close(fd);
		return 1;
	}
	signal(SIGINT, on_signal);
	signal(SIGTERM, on_signal);
	printf("http://127.0.0.1:%d/%s\n", ntohs(sa.sin_port), query);
	fflush(stdout);
	fprintf(stderr, "voxdag: serving '%s' and the viewer '%s'; Ctrl-C "
		"stops\n", s.data_root, s.static_root);
	while (!stop)
		pause();
	MHD_stop_daemon(d);
	close(fd);
	return 0;
}
