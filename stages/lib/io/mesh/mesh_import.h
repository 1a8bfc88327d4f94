/* mesh_import.h - a scene an importer read whole (voxelize-assimp's
 * glTF, FBX, Collada and 3DS), handed to the mesh reader (imported.c), which
 * then serves its triangles and colours like those of its own formats.
 *
 * Everything is plain C and malloc'd: the importer (assimp.cc) copies
 * out of its library's scene and frees that before returning, so nothing
 * of the library outlives the call and no C++ crosses into C. */
#ifndef VD_MESH_IMPORT_H
#define VD_MESH_IMPORT_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* A texture: a file (`path`, as the scene names it: relative to the
 * scene's directory unless absolute), or an image embedded in the scene
 * (`data`, `bytes`: a compressed PNG, JPEG, ... as stored). */
struct vd_import_texture {
	char *path;            /* NULL when embedded */
	uint8_t *data;
	size_t bytes;
	char *name;            /* for messages (embedded: "*0", ...) */
	int unsupported;       /* embedded raw texels: not decoded, warned */
};

struct vd_import_material {
	uint8_t rgb[3];        /* diffuse / base colour, sRGB */
	int tex;               /* index into textures, -1: none */
	uint8_t wrap[2];       /* enum vd_tex_wrap for u and v */
};

/* Vertices are in world space. uv: u v per vertex, NaN u when the
 * vertex's mesh has no texture coordinates in channel 0; rgb: R G B and
 * a byte that is 1 when the vertex has a colour (channel 0). */
struct vd_import_scene {
	uint64_t nverts, ntris;
	float *pos;            /* 3 per vertex */
	float *uv;             /* 2 per vertex */
	uint8_t *rgb;          /* 4 per vertex */
	uint32_t *idx;         /* 3 per triangle */
	int32_t *mat;          /* per triangle, -1: none */
	struct vd_import_material *mats;
	size_t nmats;
	int has_colours;       /* some material has a colour or texture,
				* or some vertex a colour */
	struct vd_import_texture *texs;
	size_t ntexs;
	uint64_t faces_dropped_short; /* points and lines */
	char format[32];              /* "gltf2", "fbx", ... */
	/* Files the importer opened besides the scene file (a .gltf's
	 * buffers, a Collada file's includes), each hashed just before it
	 * was opened, and names it looked for in vain; paths malloc'd */
	struct vd_mesh_source *sources;
	size_t nsources;
};

/* Frees the arrays and zeroes *s (defined in imported.c). */
void vd_import_scene_release(struct vd_import_scene *s);

#ifdef __cplusplus
}
#endif

#endif
