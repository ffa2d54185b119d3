/* fuzz_scene.c: libFuzzer entry point for the scene JSON (+ --set overrides) loader (harness.h; `make fuzz`). */
#include "harness.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) { return fz_scene(data, size); }
