/* mesh_spill.h - private to io/mesh/: the external join that resolves an
 * indexed mesh's faces against tables of records that do not fit in
 * memory (its vertices; an OBJ's texture coordinates too).
 *
 * The reader hands over each table's records, in index order, as opaque
 * records of a fixed size per table (table 0 the vertices: 12 bytes of
 * position, 16 with a packed colour; table 1 an OBJ's vt: two floats;
 * whatever a reader keeps per record rides along unseen), then every
 * triangle as, per table, three indices (VD_SPILL_NONE: this corner has
 * no record in that table) with a fixed-size record of its own (the
 * reader's per-triangle data: material, texture, inline uv).
 * vd__spill_finish() sorts the corners' indices by (table, index) in
 * bounded runs on disk, merge-joins them with each table's records, sorts
 * the joined corners back by triangle (one sort per table), and
 * vd__spill_next() then yields the triangles in the order they were given,
 * each with its corners' records. Memory stays within the `mem_bytes`
 * given at open; disk use is 16 + 12 + record bytes per corner and table
 * it has an index in, plus 16 + triangle record bytes per triangle, plus
 * the tables, in unlinked temporary files of `dir` (gone when closed or
 * when the process dies). */
#ifndef VD_MESH_SPILL_H
#define VD_MESH_SPILL_H

#include <stddef.h>
#include <stdint.h>

/* Tables a spill may have (vertices and texture coordinates). */
#define VD_SPILL_MAX_TABLES 2
/* A corner without a record in a table; never a valid index. */
#define VD_SPILL_NONE UINT32_MAX

struct vd_spill;

/* Starts a spill with files in `dir`, `ntables` (1..VD_SPILL_MAX_TABLES)
 * tables whose records are rec_bytes[t] bytes, triangle records of
 * `tri_bytes` (may be 0), within `mem_bytes` of memory (at least 1 MiB
 * is used). VD_ERR_IO when dir cannot hold a temporary file,
 * VD_ERR_NOMEM, VD_ERR_ARG for a table count out of range. */
int vd__spill_open(struct vd_spill **out, const char *dir, size_t ntables,
		  const size_t rec_bytes[], size_t tri_bytes,
		  uint64_t mem_bytes);
/* Appends the next record of table t (index = the table's records
 * appended before it; at most VD_SPILL_NONE of them). */
int vd__spill_record(struct vd_spill *s, size_t t, const void *rec);
/* Appends the next triangle: idx[t][k] the index of corner k's record in
 * table t (below the number of records the table has by vd__spill_finish),
 * or VD_SPILL_NONE; for messages the face it comes from and its line in
 * a text file; and its record (tri_bytes bytes). */
int vd__spill_triangle(struct vd_spill *s,
		      const uint32_t idx[VD_SPILL_MAX_TABLES][3],
		      uint64_t face, uint64_t line, const void *tri_rec);
/* Ends the input and does the sorting and the join. */
int vd__spill_finish(struct vd_spill *s);
/* The next triangle after vd__spill_finish(): *got = 0 at the end, else
 * rec[t][k] points at corner k's record of table t (NULL for
 * VD_SPILL_NONE; valid until the next call), idx[t][k] its index as
 * given, face and line as given, and *tri_rec the triangle's record
 * (valid until the next call). */
int vd__spill_next(struct vd_spill *s,
		  const uint8_t *rec[VD_SPILL_MAX_TABLES][3],
		  uint32_t idx[VD_SPILL_MAX_TABLES][3], uint64_t *face,
		  uint64_t *line, const uint8_t **tri_rec, int *got);
/* Back to the first triangle (after vd__spill_finish()). */
int vd__spill_rewind(struct vd_spill *s);
/* Bytes of memory held now. */
size_t vd__spill_memory_bytes(const struct vd_spill *s);
void vd__spill_close(struct vd_spill *s);

#endif
