/* fuzz_pmap.c: libFuzzer entry point for the .pmap photon map loader (harness.h; `make fuzz`). */
#include "harness.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) { return fz_pmap(data, size); }
