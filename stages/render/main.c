/* render - ray cast an encoding or a root DAG chunk straight to a PNG. */
#include "voxdag.h"
#include "cli.h"

#include <getopt.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define TOOL "render"

static const char usage[] =
	"usage: render SCENE -o OUT.png [options]\n"
	"       render --compare A.png B.png\n"
	"\n"
	"Casts rays straight through the compressed structure of SCENE (a\n"
	".svdag, .ussvdag, .esvdag or .ssvdag encoding, or a root DAG or SSVDAG\n"
	"chunk, told apart by its magic number) without decompressing it, and\n"
	"writes a shaded image: normals from the depth buffer, one point light,\n"
	"hard shadows. Statistics (rays, seconds, peak memory) go to\n"
	"OUT.png.stats.json.\n"
	"\n"
	"  -o, --output OUT.png    the image (8-bit RGB PNG)\n"
	"  -s, --size WxH          image size in pixels (default 1280x720)\n"
	"  -c, --camera PRESET     front, side, top or iso, framing the scene's\n"
	"                          bounding box (default front)\n"
	"  -e, --eye X,Y,Z         camera position in world units (with --target,\n"
	"                          instead of --camera)\n"
	"  -t, --target X,Y,Z      point the camera looks at\n"
	"  -F, --camera-file F     eye, target, up, fov and image size from the\n"
	"                          JSON file F (schemas/render-outputs.md), the\n"
	"                          one the browser viewer reads; --size wins\n"
	"  -f, --fov DEG           vertical field of view in degrees, in (0, 180)\n"
	"                          (default 40)\n"
	"  -l, --light X,Y,Z       point light position in world units (default\n"
	"                          above, left of and in front of the scene)\n"
	"  -S, --no-shadows        no shadow rays\n"
	"  -d, --depth FILE        also write the hit distances: FILE.pfm as\n"
	"                          float32, FILE.png as 16-bit grey (0 = miss)\n"
	"  -i, --voxel-id FILE     also write the hit cell of every pixel\n"
	"                          (schemas/render-outputs.md)\n"
	"  -j, --threads N         threads (default: all cores)\n"
	"  -L, --lod PIXELS        level of detail: stop at nodes whose projection\n"
	"                          is at most PIXELS pixels (default 0: exact)\n"
	"  -C, --colours SRC       colour the voxels from SRC: voxelize's output\n"
	"                          directory (its colour chunks) or a colorize\n"
	"                          file; it must cover exactly the scene's voxels\n"
	"  -D, --diff OTHER        also trace OTHER (an encoding or root chunk on\n"
	"                          the same grid): draw the voxels of both scenes\n"
	"                          and those set in only one of them in red, as\n"
	"                          the lossy SVDAG paper's Fig. 1 (exact only,\n"
	"                          no --lod); the camera frames SCENE\n"
	"  -q, --quiet             no summary line on stderr\n"
	"      --no-verify         read an encoding that has no manifest beside\n"
	"                          it (a file from the SymVox tools); encode's\n"
	"                          are checked against theirs by default\n"
	"      --compare A B       compare two PNG images of one size instead:\n"
	"                          prints one JSON line with mse and psnr (RGB\n"
	"                          bytes), ssim and ms_ssim (luma; MS-SSIM needs\n"
	"                          176 pixels a side, else it is null)\n"
	"  -h, --help              this text\n"
	"\n"
	"Exit status: 0 success, 1 failure (bad input, I/O), 2 usage (including\n"
	"an impossible camera or image size).\n";



static int parse_double(const char *s, double *out)
{
	char *end;
	double v = strtod(s, &end);
	if (!*s || *end || !isfinite(v)) return -1;
	*out = v;
	return 0;
}

static int parse_vec3(const char *s, double v[3])
{
	char buf[256];
	if (strlen(s) >= sizeof buf) return -1;
	strcpy(buf, s);
	char *save, *tok = strtok_r(buf, ",", &save);
	for (int a = 0; a < 3; a++) {
		if (!tok || parse_double(tok, &v[a])) return -1;
		tok = strtok_r(NULL, ",", &save);
	}
	return tok ? -1 : 0;
}

static int parse_size(const char *s, int *w, int *h)
{
	const char *x = strchr(s, 'x');
	if (!x) return -1;
	char buf[32];
	size_t n = (size_t)(x - s);
	if (n == 0 || n >= sizeof buf) return -1;
	memcpy(buf, s, n);
	buf[n] = 0;
	return vd_cli_int(buf, 1, VD_RENDER_MAX_SIDE, w) ||
	       vd_cli_int(x + 1, 1, VD_RENDER_MAX_SIDE, h) ? -1 : 0;
}

/* render --compare: the figures of the colour tables for two renders. */
static int compare_images(const char *a, const char *b)
{
	uint8_t *pa = NULL, *pb = NULL;
	int wa, ha, wb, hb;
	int err = vd_png_read_rgb(a, &pa, &wa, &ha);
	if (!err)
		err = vd_png_read_rgb(b, &pb, &wb, &hb);
	if (!err && (wa != wb || ha != hb))
		err = vd_fail(VD_ERR_MISMATCH, "'%s' is %dx%d, '%s' is %dx%d",
			      a, wa, ha, b, wb, hb);
	struct vd_image_metrics m;
	if (!err) {
		int merr = vd_image_metrics(pa, pb, wa, ha, &m);
		if (merr && merr != VD_ERR_ARG)
			err = merr;
		/* else too small for (MS-)SSIM: those are NaN, printed null */
	}
	free(pa);
	free(pb);
	if (err) {
		fprintf(stderr, "render: cannot compare: %s\n", vd_error_detail());
		return 1;
	}
	char ssim[32] = "null", ms[32] = "null", psnr[32] = "null";
	if (!isnan(m.ssim))
		snprintf(ssim, sizeof ssim, "%.6f", m.ssim);
	if (!isnan(m.ms_ssim))
		snprintf(ms, sizeof ms, "%.6f", m.ms_ssim);
	if (isfinite(m.psnr))
		snprintf(psnr, sizeof psnr, "%.4f", m.psnr);
	printf("{\"mse\": %.6f, \"psnr\": %s, \"ssim\": %s, \"ms_ssim\": %s}\n",
	       m.mse, psnr, ssim, ms);
	return 0;
}

/* Its length is the option switch, a case per option of --help. */
int main(int argc, char **argv)
{
	static const struct option longopts[] = {
		{"output", required_argument, NULL, 'o'},
		{"size", required_argument, NULL, 's'},
		{"camera", required_argument, NULL, 'c'},
		{"eye", required_argument, NULL, 'e'},
		{"target", required_argument, NULL, 't'},
		{"fov", required_argument, NULL, 'f'},
		{"camera-file", required_argument, NULL, 'F'},
		{"light", required_argument, NULL, 'l'},
		{"no-shadows", no_argument, NULL, 'S'},
		{"depth", required_argument, NULL, 'd'},
		{"voxel-id", required_argument, NULL, 'i'},
		{"threads", required_argument, NULL, 'j'},
		{"lod", required_argument, NULL, 'L'},
		{"diff", required_argument, NULL, 'D'},
		{"quiet", no_argument, NULL, 'q'},
		{"colours", required_argument, NULL, 'C'},
		{"compare", no_argument, NULL, 'K'},
		{"no-verify", no_argument, NULL, 'V'},
		{"help", no_argument, NULL, 'h'},
		{NULL, 0, NULL, 0},
	};
	struct vd_render_job job = {.tool = "render"};
	job.opts.width = 1280;
	job.opts.height = 720;
	job.opts.cam.fov_deg = 40;
	job.opts.shadows = 1;
	int has_target = 0, compare = 0, has_size = 0;
	const char *camera_file = NULL;
	int c;
	while ((c = getopt_long(argc, argv, "o:s:c:e:t:f:F:l:Sd:i:j:L:D:qC:h", longopts,
				NULL)) != -1) {
		switch (c) {
		case 'o':
			job.output = optarg;
			break;
		case 's':
			if (parse_size(optarg, &job.opts.width, &job.opts.height) ||
			    (uint64_t)job.opts.width * (uint64_t)job.opts.height >
				    VD_RENDER_MAX_PIXELS)
				return vd_cli_usage(TOOL, "--size '%s' is not WxH with each "
						   "side in 1..16384 and at most "
						   "2^26 pixels", optarg);
			has_size = 1;
			break;
		case 'F':
			camera_file = optarg;
			break;
		case 'c':
			if (strcmp(optarg, "front") && strcmp(optarg, "side") &&
			    strcmp(optarg, "top") && strcmp(optarg, "iso"))
				return vd_cli_usage(TOOL, "--camera '%s' is not front, side, "
						   "top or iso", optarg);
			job.preset = optarg;
			break;
		case 'e':
			if (parse_vec3(optarg, job.opts.cam.eye))
				return vd_cli_usage(TOOL, "--eye '%s' is not X,Y,Z", optarg);
			job.has_eye = 1;
			break;
		case 't':
			if (parse_vec3(optarg, job.opts.cam.target))
				return vd_cli_usage(TOOL, "--target '%s' is not X,Y,Z", optarg);
			has_target = 1;
			break;
		case 'f':
			if (parse_double(optarg, &job.opts.cam.fov_deg) ||
			    !(job.opts.cam.fov_deg > 0 && job.opts.cam.fov_deg < 180))
				return vd_cli_usage(TOOL, "--fov '%s' is not an angle in (0, "
						   "180) degrees", optarg);
			break;
		case 'l':
			if (parse_vec3(optarg, job.opts.light))
				return vd_cli_usage(TOOL, "--light '%s' is not X,Y,Z", optarg);
			job.has_light = 1;
			break;
		case 'S':
			job.opts.shadows = 0;
			break;
		case 'd':
			job.depth_path = optarg;
			break;
		case 'i':
			job.ids_path = optarg;
			break;
		case 'j':
			if (vd_cli_int(optarg, 1, 1024, &job.opts.threads))
				return vd_cli_usage(TOOL, "--threads '%s' is not a number "
						   "from 1 to 1024", optarg);
			break;
		case 'L':
			if (parse_double(optarg, &job.opts.lod_pixels) ||
			    job.opts.lod_pixels < 0)
				return vd_cli_usage(TOOL, "--lod '%s' is not a number of "
						   "pixels >= 0", optarg);
			break;
		case 'D':
			job.diff_input = optarg;
			break;
		case 'q':
			job.quiet = 1;
			break;
		case 'V':
			job.no_verify = 1;
			break;
		case 'C':
			job.colours = optarg;
			break;
		case 'K':
			compare = 1;
			break;
		case 'h':
			fputs(usage, stdout);
			return 0;
		default:
			fprintf(stderr, "Try 'render --help'.\n");
			return 2;
		}
	}
	if (compare)
		return argc - optind != 2 ?
		       vd_cli_usage(TOOL, "%s", "--compare needs two images") :
		       compare_images(argv[optind], argv[optind + 1]);
	if (argc - optind != 1)
		return vd_cli_usage(TOOL, "%s", argc - optind < 1 ?
				   "needs one input: SCENE" :
				   "more than one input");
	if (!job.output)
		return vd_cli_usage(TOOL, "%s", "no output image (-o OUT.png) given");
	if (job.has_eye != has_target)
		return vd_cli_usage(TOOL, "%s", "--eye and --target go together");
	if (job.has_eye && job.preset)
		return vd_cli_usage(TOOL, "%s", "--camera and --eye/--target exclude "
				   "each other");
	if (camera_file && (job.has_eye || job.preset))
		return vd_cli_usage(TOOL, "%s", "--camera-file excludes --camera "
				   "and --eye/--target");
	if (camera_file) {
		int w = job.opts.width, h = job.opts.height;
		if (vd_camera_read(camera_file, &job.opts.cam, &w, &h)) {
			fprintf(stderr, "render: cannot read camera file '%s': %s\n",
				camera_file, vd_error_detail());
			return 1;
		}
		if (!has_size) {
			job.opts.width = w;
			job.opts.height = h;
		}
		if ((uint64_t)job.opts.width * (uint64_t)job.opts.height >
		    VD_RENDER_MAX_PIXELS)
			return vd_cli_usage(TOOL, "%s", "the camera file's image is "
					   "more than 2^26 pixels");
		job.has_eye = 1;
	} else if (job.has_eye) {
		/* up is left zero: the library picks +Y, or -Z looking along Y */
		double d = 0;
		for (int a = 0; a < 3; a++)
			d += fabs(job.opts.cam.eye[a] - job.opts.cam.target[a]);
		if (d == 0)
			return vd_cli_usage(TOOL, "%s", "--eye and --target are the same "
					   "point");
	}
	if (job.diff_input && job.opts.lod_pixels > 0)
		return vd_cli_usage(TOOL, "%s", "--diff draws voxels exactly: no "
				   "--lod with it");
	if (job.depth_path) {
		size_t n = strlen(job.depth_path);
		if (!(n > 4 && (!strcmp(job.depth_path + n - 4, ".pfm") ||
				!strcmp(job.depth_path + n - 4, ".png"))))
			return vd_cli_usage(TOOL, "--depth '%s' needs the extension .pfm "
					   "or .png", job.depth_path);
	}
	job.input = argv[optind];
	if (vd_render_run(&job)) {
		fprintf(stderr, "render: %s\n", vd_error_detail());
		return 1;
	}
	return 0;
}
