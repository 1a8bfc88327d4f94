/* voxdag - the pipeline runner: reads a YAML job graph, runs the stages in
 * parallel within a memory budget, resumes after a crash, writes the
 * report. */
#include "pipeline.h"
#include "io/publish.h"

#include <errno.h>
#include <fcntl.h>
#include <getopt.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

static const char usage[] =
	"usage: voxdag COMMAND CONFIG [options]\n"
	"\n"
	"Commands:\n"
	"  run CONFIG      run the pipeline; finished jobs are skipped, so after a\n"
	"                  crash or kill the same command carries on\n"
	"  plan CONFIG     print the expanded job graph without running anything\n"
	"  status CONFIG   what is done, pending, or started and not finished\n"
	"  report CONFIG   write the report (report.md, .json, .csv) again\n"
	"  clean CONFIG    remove the output directory (out/<name>/ unless the\n"
	"                  YAML's 'outputs' names another)\n"
	"  clean --staging CONFIG\n"
	"                  remove only what killed processes left half-written\n"
	"                  (NAME.tmp.PID of processes that are gone); every run\n"
	"                  does this when it starts and ends\n"
	"  job-exec LIST   what each Slurm bundle runs: the jobs of the file LIST\n"
	"                  in turn\n"
	"                  (written by the driver; schemas/pipeline.md)\n"
	"  view CONFIG|OUT_DIR\n"
	"                  serve the scene and the browser viewer on 127.0.0.1\n"
	"                  ('voxdag view --help' lists its options)\n"
	"\n"
	"Options:\n"
	"  -q, --quiet     no progress lines\n"
	"  --executor local|slurm\n"
	"                  where jobs run (overrides resources.executor): here,\n"
	"                  or on a Slurm cluster, in bundles of jobs sent as job\n"
	"                  arrays (slurm.bundle_seconds, slurm.max_queued)\n"
	"  -h, --help      this text\n"
	"\n"
	"The YAML format is described in schemas/pipeline.md.\n"
	"Exit status: 0 success, 1 failure (a job failed, bad config), 2 usage.\n";

static int cmd_plan(struct plan *p)
{
	plan_expand(p);
	const struct config *c = p->cfg;
	printf("pipeline %s: input %s, grid 2^%d, chunk level %s, %d jobs at once, "
	       "%llu MiB in all, %llu MiB per job, %d threads per job\n", c->name,
	       c->mesh, c->levels, c->chunk_level < 0 ? "auto" : "fixed",
	       c->jobs, (unsigned long long)(c->mem_budget >> 20),
	       (unsigned long long)(c->job_mem_budget >> 20), c->threads);
	uint64_t total = 0;
	for (int d = 0; d < c->njobs; d++) {
		int n = 0, fresh = 0, read = 0;
		uint64_t est = 0, disk = 0;
		for (int i = 0; i < p->n; i++)
			if (p->jobs[i].decl == d) {
				n++;
				read |= p->jobs[i].nrdeps > 0;
				fresh += p->jobs[i].state == JOB_SKIPPED;
				if (p->jobs[i].mem_estimate > est)
					est = p->jobs[i].mem_estimate;
				disk += job_disk_bytes(&p->jobs[i]);
			}
		total += disk;
		printf("  %-12s %-15s %4d processes (%d done), largest estimate "
		       "%llu MiB, %.1f MiB on disk%s\n", c->jobs_decl[d].name,
		       c->jobs_decl[d].stage->name, n, fresh,
		       (unsigned long long)(est >> 20), (double)disk / (1 << 20),
		       c->keep_given && !(c->keep_mask >> d & 1) && read ? " (keep: "
		       "intermediate)" : "");
	}
	/* what the outputs hold, beside what their file system has free: a
	 * bound of what is still to come is not known before it is written
	 * (every chunk is compressed) */
	struct statvfs fs;
	printf("  disk: %.1f MiB in the outputs", (double)total / (1 << 20));
	if (statvfs(p->dir, &fs) == 0)
		printf(", %.1f GiB free there",
		       (double)fs.f_bavail * fs.f_frsize / (1 << 30));
	if (c->keep_given)
		printf("; keep: deleted %zu files so far", keep_gone_files());
	printf("\n");
	if (!p->expanded)
		printf("  (the per-cell jobs and merges are known once voxelize "
		       "has run: at most 8^L0 cells)\n");
	for (int i = 0; i < p->n; i++) {
		const struct job *j = &p->jobs[i];
		printf("%s %s:", j->state == JOB_SKIPPED ? "done" : "todo", j->id);
		for (int k = 0; j->argv[k]; k++)
			printf(" %s", j->argv[k]);
		printf("\n");
	}
	return 0;
}

static int cmd_clean(struct plan *p, int staging)
{
	struct stat st;
	long holder;
	if (stat(p->dir, &st) != 0)
		return 0; /* nothing to clean */
	if (lock_take(p->dir, &holder) == -1) {
		fprintf(stderr, "voxdag: a runner (pid %ld) is working on '%s'; "
			"not removing it\n", holder, p->dir);
		return 1;
	}
	if (staging) {
		long n = vd_staging_sweep(p->dir, 0);
		printf("removed %ld staging entr%s from '%s'\n", n,
		       n == 1 ? "y" : "ies", p->dir);
		return 0;
	}
	char cmd[1300];
	snprintf(cmd, sizeof cmd, "rm -rf -- '%s'", p->dir);
	return system(cmd) != 0;
}

/* keep: deleted a file that a job needs: the run starts over in a new
 * process (the lock, the journal and the launcher are a process's), where
 * the job that wrote the file, its key dropped, runs again first. Each
 * start over drops at least one key, so a graph needs at most its depth of
 * them; a bound catches what should never happen. Returns 1 when it
 * cannot. */
static int start_over(char **argv)
{
	const char *was = getenv("VOXDAG_STARTS");
	int n = was ? atoi(was) : 0;
	if (n >= 64) {
		fprintf(stderr, "voxdag: started over %d times to rebuild what "
			"keep: deleted; giving up\n", n);
		return 1;
	}
	char v[16];
	snprintf(v, sizeof v, "%d", n + 1);
	setenv("VOXDAG_STARTS", v, 1);
	fflush(NULL);
	execv("/proc/self/exe", argv);
	fprintf(stderr, "voxdag: cannot start over: %s\n", strerror(errno));
	return 1;
}

int main(int argc, char **argv)
{
	static const struct option longopts[] = {
		{"quiet", no_argument, NULL, 'q'},
		{"executor", required_argument, NULL, 'E'},
		{"help", no_argument, NULL, 'h'},
		{"staging", no_argument, NULL, 'S'},
		{NULL, 0, NULL, 0},
	};
	if (argc > 1 && !strcmp(argv[1], "job-exec"))
		return slurm_job_exec(argc, argv);
	if (argc > 1 && !strcmp(argv[1], "view"))
		return view_main(argc - 1, argv + 1);
	struct run_opts o = {0};
	const char *executor = NULL;
	int staging = 0;
	int c;
	while ((c = getopt_long(argc, argv, "qh", longopts, NULL)) != -1) {
		if (c == 'q') {
			o.quiet = 1;
		} else if (c == 'E') {
			if (strcmp(optarg, "local") && strcmp(optarg, "slurm")) {
				fprintf(stderr, "voxdag: --executor is 'local' or "
					"'slurm', not '%s'\nTry 'voxdag "
					"--help'.\n", optarg);
				return 2;
			}
			executor = optarg;
		} else if (c == 'S') {
			staging = 1;
		} else if (c == 'h') {
			fputs(usage, stdout);
			return 0;
		} else {
			fprintf(stderr, "Try 'voxdag --help'.\n");
			return 2;
		}
	}
	if (argc - optind != 2) {
		fprintf(stderr, "voxdag: expected a COMMAND and a CONFIG\nTry "
			"'voxdag --help'.\n");
		return 2;
	}
	const char *cmd = argv[optind], *path = argv[optind + 1];
	static const char *const cmds[] = {"run", "plan", "status", "report", "clean"};
	int which = -1;
	for (int i = 0; i < 5; i++)
		if (!strcmp(cmd, cmds[i]))
			which = i;
	if (which < 0) {
		fprintf(stderr, "voxdag: unknown command '%s' (run, plan, status, "
			"report, clean, view)\nTry 'voxdag --help'.\n", cmd);
		return 2;
	}
	if (staging && which != 4) {
		fprintf(stderr, "voxdag: --staging goes with 'clean'\nTry "
			"'voxdag --help'.\n");
		return 2;
	}
	struct config cfg;
	if (config_load(&cfg, path))
		return 1;
	if (executor)
		cfg.executor = !strcmp(executor, "slurm") ? EXECUTOR_SLURM
							  : EXECUTOR_LOCAL;
	struct plan p = {.cfg = &cfg};
	snprintf(p.dir, sizeof p.dir, "%s", cfg.outputs);
	int rc;
	switch (which) {
	case 0:
		rc = run_pipeline(&p, &o);
		if (rc == RUN_AGAIN)
			rc = start_over(argv);
		if (rc == 0 && !o.quiet)
			fprintf(stderr, "voxdag: done; the report is %s/report.md\n",
				p.dir);
		break;
	case 1:
		rc = cmd_plan(&p);
		break;
	case 2:
		rc = status_print(&p);
		break;
	case 3:
		plan_expand(&p);
		rc = report_write(&p);
		if (!rc)
			printf("%s/report.md\n", p.dir);
		break;
	default:
		rc = cmd_clean(&p, staging);
		break;
	}
	plan_free(&p);
	config_release(&cfg);
	return rc;
}
