/* fuzz_vdb.c: libFuzzer entry point for the OpenVDB (.vdb) loader (harness.h; `make fuzz`). */
#include "harness.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) { return fz_vdb(data, size); }
