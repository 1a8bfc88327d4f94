/* vd_render.h - ray tracing the compressed DAG (render/) and image metrics.
 */
#ifndef VD_RENDER_H
#define VD_RENDER_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include "vd_chunk.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- render (render.c) */
/* Ray casting straight through the compressed structures (SSVDAG paper
 * section 5): an octree DDA with a stack of the nodes on the current path,
 * carrying the accumulated 3-bit reflection (child-index bits, as in the
 * DAG block) and applying it to child slots and to the voxels of 4x4x4
 * bricks and 2x2x2 masks; when a step leaves the current node the traversal
 * pops straight to the ancestor holding the next cell (no push); optional
 * level of detail stops at nodes smaller than a given projected size.
 *
 * Ray conventions (the contract the brute-force test checks exactly):
 * - Rays live in grid coordinates: voxel (i, j, k) of the 2^L grid is the
 *   cube [i, i+1) x [j, j+1) x [k, k+1); the point at parameter t is o + t d.
 *   The world maps to the grid by g = (w - origin) / voxel_size.
 * - The time of integer plane k on axis a is the double
 *   tp(a, k) = ((double)k - o[a]) * (1.0 / d[a]), computed exactly so (no
 *   other rounding), and every decision is a comparison of such times: the
 *   voxel coordinate along a at time t is the largest k with tp(a, k) <= t
 *   when d[a] > 0, and the smallest k with tp(a, k) <= t, minus one, when
 *   d[a] < 0; when d[a] == 0 it is floor(o[a]) (as for a
 *   subnormal d[a] whose reciprocal overflows). So a boundary belongs to
 *   the voxel the ray enters (cells are half-open in the ray's direction),
 *   a ray crossing an edge or corner at one time steps diagonally without
 *   visiting the voxels beside it, and a ray lying in a grid plane
 *   perpendicular to a (d[a] == 0, o[a] an integer) sees the voxels on the
 *   + side of it.
 * - The ray is [tmin, tmax). The hit is the first voxel, in time order, that
 *   is set and is occupied by the ray at some time in [tmin, tmax). Its time
 *   is its entry time max_a tp(a, near plane) or tmin if larger; a ray
 *   starting inside a set voxel hits it at tmin with axis -1.
 * - The hit axis is the lowest axis whose near-plane time equals the entry
 *   time (the face crossed); the face normal is -sign(d[axis]) along it.
 */

/* A scene rays can be traced through: one encoding or one root DAG chunk,
 * and where its grid sits in the world. Holds pointers only: the encoding
 * or DAG must outlive it. */
struct vd_render_scene {
	const struct vd_enc *enc;   /* one of enc, dag is set */
	const struct vd_dag *dag;
	int levels;                 /* L: 2^L voxels per side */
	double origin[3];           /* world position of the grid corner */
	double voxel_size;          /* world units per voxel */
	float bbox_min[3], bbox_max[3]; /* tight bounding box, world units */
};

/* Scene over a validated encoding: the grid cube is centred on the bounding
 * box centre with the file's root side. VD_ERR_RANGE for a non-finite box
 * or side. */
int vd_render_scene_from_enc(struct vd_render_scene *s, const struct vd_enc *e);

/* Scene over a validated root DAG or SSVDAG chunk (chunk_level 0, else
 * VD_ERR_ARG) placed by `t`. */
int vd_render_scene_from_dag(struct vd_render_scene *s, const struct vd_dag *d,
			     const struct vd_transform *t);

/* One ray, in grid coordinates (see the conventions above). */
struct vd_ray {
	double o[3];      /* origin (anywhere, inside the grid or not) */
	double d[3];      /* direction, not all zero; need not be unit */
	double tmin, tmax; /* the ray is [tmin, tmax); tmax may be INFINITY */
	double lod;       /* 0: exact. Else a non-empty node of side s voxels
			     met at time t >= 0 with s <= lod * t counts as a
			     solid cell (level of detail) */
};

/* Where a ray stopped. */
struct vd_hit {
	double t;          /* hit time (entry time, or tmin when inside) */
	uint32_t cell[3];  /* the hit cell's coordinates on the 2^level grid */
	int level;         /* L for a voxel; smaller for an LOD cell */
	int axis;          /* 0..2 the face entered, -1 started inside */
};

/* Traces `r` through `s`. Returns 1 and fills *h on a hit, 0 on a miss
 * (then *h is untouched); a ray with a non-finite origin, a NaN bound or
 * a zero direction misses. Thread-safe; no allocation. */
int vd_render_trace(const struct vd_render_scene *s, const struct vd_ray *r,
		    struct vd_hit *h);

/* A pinhole camera in world units. `up` need not be orthogonal to the
 * viewing direction, only not parallel to it. */
struct vd_camera {
	double eye[3], target[3], up[3];
	double fov_deg;    /* vertical field of view, in (0, 180) */
};

/* Checks a camera: VD_ERR_ARG (detail says why) when eye == target, a
 * value is not finite, fov_deg is outside (0, 180) or up is parallel to
 * the viewing direction. */
int vd_camera_check(const struct vd_camera *c);

/* Fills `c` with the preset `name` ("front": looking along -Z, "side":
 * along -X, "top": down along -Y, "iso": from +X+Y+Z) at the nearest
 * distance (plus 8%) where the 8 corners of the scene's bounding box fit a
 * width x height image with vertical field of view fov_deg.
 * VD_ERR_ARG for an unknown name. */
int vd_camera_preset(struct vd_camera *c, const struct vd_render_scene *s,
		     const char *name, double fov_deg, int width, int height);

/* Reads a camera file (schemas/render-outputs.md, "Camera file"), the
 * JSON object {"eye": [x,y,z], "target": [x,y,z], "up": [x,y,z], "fov":
 * deg, "width": w, "height": h} that render --camera-file and the browser
 * viewer both read; "up" (default [0,1,0]), "fov" (default 40), "width"
 * and "height" may be left out (*width and *height are then untouched).
 * The camera is checked (vd_camera_check). VD_ERR_IO when unreadable,
 * VD_ERR_ARG (detail names the field) when malformed. */
int vd_camera_read(const char *path, struct vd_camera *c, int *width,
		   int *height);

/* What to render. */
struct vd_colour_source;

struct vd_render_opts {
	int width, height;        /* pixels, 1..VD_RENDER_MAX_SIDE each */
	struct vd_camera cam;
	double light[3];          /* point light, world units */
	int shadows;              /* 1: cast a shadow ray per lit pixel */
	double lod_pixels;        /* 0: exact; else stop at nodes whose
				     projection is at most this many pixels */
	int threads;              /* 0: all cores */
	/* Voxel colours (NULL: one grey). A hit voxel takes its colour, an
	 * LOD cell its first voxel's; the source must cover exactly the
	 * scene's voxels (VD_ERR_MISMATCH). */
	const struct vd_colour_source *colours;
	const struct vd_render_scene *diff; /* NULL, or a second scene on the
				     same grid (levels, origin, voxel size):
				     the picture is then of both scenes'
				     voxels, and those set in only one of
				     them are red (lossy paper, Fig. 1);
				     exact rendering only (lod_pixels 0) */
};

#define VD_RENDER_MAX_SIDE 16384
#define VD_RENDER_MAX_PIXELS (1ull << 26)

/* A rendered image and its buffers, row-major from the top-left pixel. */
struct vd_image {
	int width, height;
	uint8_t *rgb;             /* 3 bytes per pixel, sRGB */
	float *depth;             /* hit distance in world units along the
				     unit view ray; INFINITY on a miss */
	struct vd_hit *hits;      /* level -1 on a miss */
	uint8_t *differs;         /* with opts.diff: 1 where the hit voxel is
				     set in one scene only; else NULL */
	uint64_t differing_pixels;
	uint64_t primary_rays, shadow_rays;
	double seconds_primary, seconds_shade;
};

/* Renders `s` as `o` says into *img (release with vd_image_release(), also
 * after a failure): primary rays, normals from the depth buffer (the hit
 * face where neighbours are missing), Lambert shading, hard shadows. The
 * pixels depend only on the hits, so equal scenes give equal images
 * whatever the encoding. VD_ERR_ARG for a bad size or camera. */
int vd_render_image(const struct vd_render_scene *s,
		    const struct vd_render_opts *o, struct vd_image *img);

void vd_image_release(struct vd_image *img);

/* Writes img->rgb as an 8-bit RGB PNG at `path` (atomic). */
int vd_image_write_png(const struct vd_image *img, const char *path);

/* Writes the depth buffer: ".pfm" as a float32 greyscale PFM (bottom row
 * first, as the format says; misses +INFINITY), ".png" as a 16-bit
 * greyscale PNG (0 a miss, 1..65535 nearest to farthest hit, linear).
 * VD_ERR_ARG for another extension. Atomic. */
int vd_image_write_depth(const struct vd_image *img, const char *path);

/* Writes the hit cells (schemas/render-outputs.md): a 16-byte header
 * (bytes 0x89 'V' 'I' 'D', u32 version 1, u32 width, u32 height) then per
 * pixel u32 x, y, z, level, little-endian; all four 0xffffffff on a miss.
 * Atomic. */
int vd_image_write_ids(const struct vd_image *img, const char *path);

/* Image comparison (render/metrics.c; conventions there): MSE over the RGB
 * bytes, PSNR in dB, single-scale SSIM and 5-scale MS-SSIM on luma. */
struct vd_image_metrics {
	double mse, psnr, ssim, ms_ssim;
};

/* Compares two w x h RGB images. mse and psnr are always set; SSIM needs
 * 11 pixels and MS-SSIM 176 on each side: what cannot be computed is NaN
 * and the return VD_ERR_ARG. */
int vd_image_metrics(const uint8_t *a, const uint8_t *b, int w, int h,
		     struct vd_image_metrics *m);

/* SSIM and mean contrast-structure of two w x h greyscale images (values
 * in 0..255) at one scale. */
int vd_ssim_scale(const double *a, const double *b, int w, int h,
		  double *ssim, double *cs);

/* Reads a PNG of any colour type as 8-bit RGB (*rgb: free with free()). */
int vd_png_read_rgb(const char *path, uint8_t **rgb, int *width,
		    int *height);

/* One run of the render stage, as its main() sets it up. */
struct vd_render_job {
	const char *tool;          /* "render", for messages */
	const char *input;         /* an encoding or a root DAG/SSVDAG chunk */
	const char *output;        /* PNG */
	const char *depth_path;    /* or NULL */
	const char *ids_path;      /* or NULL */
	const char *diff_input;    /* or NULL: a second scene (opts.diff) */
	const char *preset;        /* camera preset, used when !has_eye */
	int has_eye;               /* opts.cam.eye/target given */
	int has_light;             /* opts.light given (else above the eye) */
	struct vd_render_opts opts;
	int quiet;                 /* no summary on stderr */
	int no_verify;             /* read an encoding without its manifest */
	const char *colours;       /* vd_colour_source_open() path, or NULL */
};

/* Loads the input (a chunk file by its magic, else an encoding by its
 * extension, checked against the manifest beside it unless no_verify:
 * vd_manifest_check_file()), sets up the camera and light, renders and writes the
 * outputs. On failure the detail is the whole message after the tool name
 * ("cannot read 'x.ssvdag': truncated file: ..."). With diff_input,
 * that scene is loaded the same way and must lie on the same grid
 * (VD_ERR_MISMATCH); the camera frames the input. */
int vd_render_run(const struct vd_render_job *job);

#ifdef __cplusplus
}
#endif

#endif /* VD_RENDER_H */
