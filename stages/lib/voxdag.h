/* voxdag.h - the public interface of libvoxdag, the library every voxdag
 * stage links: the umbrella of the per-concern headers below, one for
 * each layer of stages/lib/ (README.md, "The library").
 *
 * Conventions that hold everywhere below:
 * - Functions that can fail return an `int` error code: VD_OK (0) or one of
 *   enum vd_error. vd_strerror() names it; vd_error_detail() gives the
 *   calling thread's one-line detail of the last failure ("line 12: vertex
 *   index 900 out of range"), empty when there is none.
 * - `_open`/`_close` acquire and release a handle; `_free` releases memory
 *   the library allocated and accepts NULL.
 * - Grid conventions: a grid of `levels` L has 2^L voxels per side. Node
 *   levels run from 0 (the root) to L-1 (2x2x2 masks); level L is the voxels.
 *   Child index c = 4*x + 2*y + z (bit 2 = +X, bit 1 = +Y, bit 0 = +Z).
 *   A Morton code is the sequence of child indices from the root, most
 *   significant first, so sorting by Morton code is depth-first order.
 * - Bricks: a brick is the 4x4x4 block of voxels below one level-(L-2) node,
 *   stored as a uint64_t whose bit b is the voxel with local Morton code b
 *   (b = morton3(x&3, y&3, z&3)). Byte c of a brick is therefore the 2x2x2
 *   mask of the brick's child c, whose bit c' is that child's voxel c'.
 *   A brick key is the Morton code of the brick's coordinates (voxel >> 2)
 *   in the whole grid. Grids with L < 2 have one brick, key 0, partly used.
 */
#ifndef VOXDAG_H
#define VOXDAG_H

#include "vd_errors.h"
#include "vd_common.h"
#include "vd_chunk.h"
#include "vd_mesh.h"
#include "vd_voxel.h"
#include "vd_vdb.h"
#include "vd_dag.h"
#include "vd_enc.h"
#include "vd_colour.h"
#include "vd_render.h"
#include "vd_edit.h"

#endif /* VOXDAG_H */
