/* fuzz_enc.h - the body of the four encoding targets. */
#ifndef VD_FUZZ_ENC_H
#define VD_FUZZ_ENC_H

struct fuzz_walk {
	uint64_t bricks, last_key;
};

static inline int fuzz_brick(void *ctx, uint64_t key, uint64_t brick)
{
	struct fuzz_walk *w = ctx;
	if (w->bricks && key <= w->last_key)
		abort(); /* vd_enc_expand promises Morton order */
	if (!brick)
		abort(); /* and only non-empty bricks */
	w->last_key = key;
	/* A small file can stand for an exponential number of bricks: stop
	 * after enough to have walked every stored node many times. */
	return ++w->bricks >= 20000;
}

static inline int fuzz_enc(const uint8_t *data, size_t size, int format)
{
	struct vd_enc e;
	if (vd_enc_parse(&e, data, size, format))
		return 0;
	(void)vd_enc_size_bytes(&e);
	struct fuzz_walk w = {0, 0};
	(void)vd_enc_expand(&e, fuzz_brick, &w);
	vd_enc_release(&e);
	return 0;
}

#endif
