/* mesh_spill.h - private to io/: the external join that resolves an
 * indexed mesh's faces against vertices that do not fit in memory.
 *
 * The reader hands over every vertex, in index order, as an opaque record
 * of a fixed size (12 bytes of position, 16 with a packed colour:
 * whatever a reader keeps per vertex rides along unseen), then every
 * triangle as three vertex indices with a fixed-size record of its own
 * (the reader's per-triangle data: texture coordinates, material). vd_spill_finish() sorts the corners by vertex index in
 * bounded runs on disk, merge-joins them with the vertex stream, sorts the
 * joined corners back by triangle, and vd_spill_next() then yields the
 * triangles in the order they were given, each with its three vertex
 * records. Memory stays within the `mem_bytes` given at open; disk use is
 * about (3 x (16 + 12 + record) + 16 + triangle record) bytes per
 * triangle plus the
 * vertices, in unlinked temporary files of `dir` (gone when closed or
 * when the process dies). */
#ifndef VD_MESH_SPILL_H
#define VD_MESH_SPILL_H

#include <stddef.h>
#include <stdint.h>

struct vd_spill;

/* Starts a spill with files in `dir`, vertex records of `rec_bytes`,
 * triangle records of `tri_bytes` (may be 0), within `mem_bytes` of
 * memory (at least 1 MiB is used). VD_ERR_IO when dir cannot hold a
 * temporary file, VD_ERR_NOMEM. */
int vd_spill_open(struct vd_spill **out, const char *dir, size_t rec_bytes,
		  size_t tri_bytes, uint64_t mem_bytes);
/* Appends the next vertex (index = vertices appended before it). */
int vd_spill_vertex(struct vd_spill *s, const void *rec);
/* Appends the next triangle: vertex indices (each below the number of
 * vertices appended by vd_spill_finish), for messages the face it comes
 * from and its line in a text file, and its record (tri_bytes bytes). */
int vd_spill_triangle(struct vd_spill *s, const uint32_t v[3], uint64_t face,
		      uint64_t line, const void *tri_rec);
/* Ends the input and does the sorting and the join. */
int vd_spill_finish(struct vd_spill *s);
/* The next triangle after vd_spill_finish(): *got = 0 at the end, else
 * rec[k] points at corner k's vertex record (valid until the next call),
 * v[k] its index, face and line as given, and *tri_rec the triangle's
 * record (valid until the next call). */
int vd_spill_next(struct vd_spill *s, const uint8_t *rec[3], uint32_t v[3],
		  uint64_t *face, uint64_t *line, const uint8_t **tri_rec,
		  int *got);
/* Back to the first triangle (after vd_spill_finish()). */
int vd_spill_rewind(struct vd_spill *s);
/* Bytes of memory held now. */
size_t vd_spill_memory_bytes(const struct vd_spill *s);
void vd_spill_close(struct vd_spill *s);

#endif
