/* fuzz_raw.c: libFuzzer entry point for the raw float32 grid loader (harness.h; `make fuzz`). */
#include "harness.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) { return fz_raw(data, size); }
