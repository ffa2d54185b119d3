/* fuzz_guide.c: libFuzzer entry point for the .guide guide grid loader (harness.h; `make fuzz`). */
#include "harness.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) { return fz_guide(data, size); }
