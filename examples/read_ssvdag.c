/* read_ssvdag.c - a first program over libvoxdag: open a scene that the
 * `encode` stage wrote, count its voxels, and look voxels up by their
 * coordinates, with their colours.
 *
 *   usage: read_ssvdag SCENE.ssvdag [COLOURS] < POINTS
 *
 * SCENE is any encoding of `encode` (.ssvdag, .esvdag, .svdag, .ussvdag,
 * .ssvdag48: the extension names the format). COLOURS, optional, is the
 * scene's colour array: a file of `colorize` (colours.vbr, colours.palette,
 * colours.raw) or voxelize's output directory (its .col chunks). POINTS
 * are lines "x y z", voxel coordinates in the 2^L grid (0 <= x < 2^L).
 * It prints
 *
 *   levels L
 *   voxels N            (counted by walking every brick of the DAG)
 *   x y z set R G B     (or "x y z set" without COLOURS)
 *   x y z empty
 *   queried Q, set S
 *
 * Build it against the installed library (make install, then):
 *   cc read_ssvdag.c $(pkg-config --cflags --libs voxdag) -o read_ssvdag
 * (examples/README.md has the static build and the rest).
 */
#include <voxdag.h>

#include <stdio.h>
#include <stdlib.h>

/* Every library function that can fail returns VD_OK (0) or an enum
 * vd_error; vd_strerror() names it and vd_error_detail() says what
 * exactly happened on this thread. */
static int fail(const char *what, const char *path, int err)
{
	fprintf(stderr, "read_ssvdag: %s '%s': %s: %s\n", what, path,
		vd_strerror(err), vd_error_detail());
	return 1;
}

/* Called by vd_enc_expand() for every non-empty 4x4x4 brick, in Morton
 * order; a brick is 64 bits, one per voxel. Returning non-zero would stop
 * the walk. */
static int count_brick(void *ctx, uint64_t key, uint64_t brick)
{
	(void)key; /* the brick's position: Morton code of (x, y, z) / 4 */
	*(uint64_t *)ctx += (uint64_t)__builtin_popcountll(brick);
	return 0;
}

int main(int argc, char **argv)
{
	if (argc < 2 || argc > 3) {
		fprintf(stderr, "usage: read_ssvdag SCENE.ssvdag [COLOURS] "
				"< POINTS\n");
		return 2;
	}
	const char *scene = argv[1], *colours_path = argc > 2 ? argv[2] : NULL;

	/* 1. The encoding, read whole into memory and validated: every
	 * pointer is checked, so the walks below cannot go astray. -1 takes
	 * the format from the file name's extension. */
	struct vd_enc enc = {0};
	int err = vd_enc_load(&enc, scene, -1);
	if (err) {
		vd_enc_release(&enc);
		return fail("cannot read", scene, err);
	}
	uint64_t voxels = 0;
	vd_enc_expand(&enc, count_brick, &voxels);
	printf("levels %u\nvoxels %llu\n", enc.levels,
	       (unsigned long long)voxels);

	/* 2. Voxel counts per DAG node. Colours never enter the DAG: they are
	 * one array of the scene's voxels in Morton order, and a voxel's
	 * index in it is the sum, along its path from the root, of the
	 * counts of the siblings before it (colour paper, section 3). The
	 * same counts answer "is this voxel set?". */
	struct vd_voxcount counts = {0};
	err = vd_voxcount_from_enc(&counts, &enc);
	if (err) {
		vd_enc_release(&enc);
		return fail("cannot count the voxels of", scene, err);
	}

	/* 3. The colours, if given: checked to belong to a scene of this
	 * depth and size (a colour array of another scene would give wrong
	 * colours, not an error, without this check). */
	struct vd_colour_source colours = {0};
	if (colours_path) {
		err = vd_colour_source_open(&colours, colours_path);
		if (!err && (colours.levels != (int)enc.levels ||
			     colours.voxels != counts.voxels))
			err = vd_fail(VD_ERR_MISMATCH, "%llu colours at depth %d "
				      "for %llu voxels at depth %u",
				      (unsigned long long)colours.voxels,
				      colours.levels,
				      (unsigned long long)counts.voxels,
				      enc.levels);
		if (err) {
			vd_colour_source_release(&colours);
			vd_voxcount_release(&counts);
			vd_enc_release(&enc);
			return fail("cannot use the colours", colours_path, err);
		}
	}

	/* 4. Look the points up. */
	const unsigned long side = 1ul << enc.levels;
	unsigned long x, y, z, queried = 0, set = 0;
	int rc = 0;
	while (scanf("%lu %lu %lu", &x, &y, &z) == 3) {
		if (x >= side || y >= side || z >= side) {
			fprintf(stderr, "read_ssvdag: point %lu %lu %lu is outside "
				"the %lu^3 grid\n", x, y, z, side);
			rc = 1;
			break;
		}
		queried++;
		uint64_t index; /* the voxel's place in the colour array */
		if (!vd_voxcount_index(&counts, (int)enc.levels, (uint32_t)x,
				       (uint32_t)y, (uint32_t)z, &index)) {
			printf("%lu %lu %lu empty\n", x, y, z);
			continue;
		}
		set++;
		if (!colours_path) {
			printf("%lu %lu %lu set\n", x, y, z);
			continue;
		}
		uint8_t rgb[3];
		colours.get(&colours, index, rgb);
		printf("%lu %lu %lu set %u %u %u\n", x, y, z, rgb[0], rgb[1],
		       rgb[2]);
	}
	if (!rc && !feof(stdin)) {
		fprintf(stderr, "read_ssvdag: expected lines \"x y z\" on "
			"standard input\n");
		rc = 1;
	}
	printf("queried %lu, set %lu\n", queried, set);

	/* Everything the library allocated is released by its owner's
	 * _release function. */
	vd_colour_source_release(&colours);
	vd_voxcount_release(&counts);
	vd_enc_release(&enc);
	return rc;
}
