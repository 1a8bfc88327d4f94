/* fuzz_ssvdag48.c - libFuzzer target: the .ssvdag48 decoder (vd_enc_parse, which
 * vd_enc_load calls), then a full traversal of what it accepted. */
#include "fuzz.h"
#include "fuzz_enc.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	return fuzz_enc(data, size, VD_ENC_SSVDAG48);
}
