/* colour_internal.h - what colour/'s files share and users of the library
 * do not need. Not installed. */
#ifndef VD_COLOUR_INTERNAL_H
#define VD_COLOUR_INTERNAL_H

#include "vd_colour.h"

/* One segment in the palette format before its block palettes are shared:
 * block b covers start[b].., its palette is the sorted global indices
 * pal[pal_first[b] .. pal_first[b+1]) (pal_first has count+1 entries), each
 * voxel an offset into it (offsets[i] for voxel i, unpacked here). */
struct vd_palette_segment {
	uint32_t n, count;
	uint32_t *start;
	uint32_t *pal_first;
	uint32_t *pal;
	uint32_t *offsets;
	uint64_t sse;
	unsigned max_dist2;
};
int vd_palette_encode(struct vd_palette_segment *s, const uint8_t *rgb,
		      uint32_t n, const struct vd_palette *p);
void vd_palette_segment_release(struct vd_palette_segment *s);

#endif /* VD_COLOUR_INTERNAL_H */
