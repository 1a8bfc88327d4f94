/* vdb-export - SVO chunk files to an OpenVDB BoolGrid. */
#include "voxdag.h"
#include "cli.h"

#include <dirent.h>
#include <errno.h>
#include <getopt.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#define TOOL "vdb-export"

static const char usage[] =
	"usage: vdb-export -o OUT.vdb [--grid-name NAME] CHUNK_OR_DIR...\n"
	"\n"
	"Writes the voxels of SVO chunk files (the files given, and every *.svo\n"
	"file of each directory given) as one OpenVDB BoolGrid with the chunks'\n"
	"world transform: voxel size, and index (0,0,0) at the grid's corner\n"
	"voxel. Full 8^3 leaves become tiles. The chunks must belong to one grid\n"
	"(same depth and transform). Prints the active voxel count of the\n"
	"written grid on stdout.\n"
	"\n"
	"  -o, --output FILE       the .vdb file to write (replaced atomically)\n"
	"  -g, --grid-name NAME    name of the grid (default: voxels)\n"
	"  -h, --help              this text\n"
	"\n"
	"Exit status: 0 success, 1 failure (bad chunk, I/O), 2 usage.\n";


static int cmp_str(const void *a, const void *b)
{
	return strcmp(*(char *const *)a, *(char *const *)b);
}

struct list {
	char **v;
	size_t n, cap;
};

static int add(struct list *l, const char *s)
{
	if (l->n == l->cap) {
		size_t cap = l->cap ? 2 * l->cap : 64;
		char **v = realloc(l->v, cap * sizeof *v);
		if (!v)
			return -1;
		l->v = v;
		l->cap = cap;
	}
	return (l->v[l->n++] = strdup(s)) ? 0 : -1;
}

/* Adds the *.svo files of `dir` in name order (Morton order of the cells). */
static int add_dir(struct list *l, const char *dir)
{
	DIR *d = opendir(dir);
	if (!d) {
		fprintf(stderr, "vdb-export: cannot read '%s': %s\n", dir,
			strerror(errno));
		return -1;
	}
	size_t first = l->n;
	struct dirent *e;
	char path[4400];
	while ((e = readdir(d))) {
		size_t n = strlen(e->d_name);
		if (n > 4 && strcmp(e->d_name + n - 4, ".svo") == 0) {
			snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
			if (add(l, path)) {
				closedir(d);
				fprintf(stderr, "vdb-export: out of memory\n");
				return -1;
			}
		}
	}
	closedir(d);
	qsort(l->v + first, l->n - first, sizeof *l->v, cmp_str);
	return 0;
}

int main(int argc, char **argv)
{
	static const struct option longopts[] = {
		{"output", required_argument, NULL, 'o'},
		{"grid-name", required_argument, NULL, 'g'},
		{"help", no_argument, NULL, 'h'},
		{NULL, 0, NULL, 0},
	};
	const char *out = NULL, *name = "voxels";
	int c;
	while ((c = getopt_long(argc, argv, "o:g:h", longopts, NULL)) != -1) {
		switch (c) {
		case 'o':
			out = optarg;
			break;
		case 'g':
			name = optarg;
			break;
		case 'h':
			fputs(usage, stdout);
			return 0;
		default:
			fprintf(stderr, "Try 'vdb-export --help'.\n");
			return 2;
		}
	}
	if (!out)
		return vd_cli_usage(TOOL, "%s", "no output file (-o OUT.vdb) given");
	if (optind >= argc)
		return vd_cli_usage(TOOL, "%s", "no CHUNK or DIR given");
	struct list l = {0};
	int rc = 0;
	for (int i = optind; i < argc && !rc; i++) {
		struct stat st;
		if (stat(argv[i], &st) == 0 && S_ISDIR(st.st_mode))
			rc = add_dir(&l, argv[i]) ? 1 : 0;
		else if (add(&l, argv[i]))
			rc = 1;
	}
	if (!rc && l.n == 0) {
		fprintf(stderr, "vdb-export: no .svo chunk files in the "
			"directories given\n");
		rc = 1;
	}
	uint64_t voxels = 0;
	if (!rc) {
		int err = vd_vdb_export_svo(out, name, l.v, l.n, &voxels);
		if (err) {
			const char *d = vd_error_detail();
			fprintf(stderr, "vdb-export: cannot export to '%s': %s%s%s\n",
				out, vd_strerror(err), *d ? ": " : "", d);
			rc = 1;
		} else {
			printf("%llu voxels from %zu chunks written to '%s'\n",
			       (unsigned long long)voxels, l.n, out);
		}
	}
	for (size_t i = 0; i < l.n; i++)
		free(l.v[i]);
	free(l.v);
	if (fflush(stdout) != 0 && !rc)
		rc = 1;
	return rc;
}
