/* fuzz_image.c: libFuzzer entry point for the image reader (harness.h; `make fuzz`). */
#include "harness.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) { return fz_image(data, size); }
