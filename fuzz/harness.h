/* harness.h: one function per file loader that takes an input as bytes, the way a fuzzer gives
 * it, writes it to a temporary file (the loaders read paths), loads it, exercises the result a
 * little and frees everything. Used by the libFuzzer targets (fuzz/fuzz_*.c, `make fuzz`) and by
 * the regression replay in tests/test_fuzz.c (tests/data/fuzz/<target>/). Each returns 0; a bug
 * shows as a crash or a sanitizer report, never as a return value. Files are written only under
 * $TMPDIR (default /tmp) and removed before returning. */
#ifndef PHOTONMARCH_FUZZ_HARNESS_H
#define PHOTONMARCH_FUZZ_HARNESS_H

#include <stddef.h>
#include <stdint.h>

/* A scene file through rd_scene_load, with --set overrides: the input is split at NUL bytes;
 * the first part is the scene JSON, each further part (at most 8) one KEY=VALUE override. */
int fz_scene(const uint8_t *data, size_t n);
/* A .pmap through pm_map_load; its last 8 bytes are replaced by the FNV-1a 64 checksum of the
 * bytes before them, so mutations reach the parser past the checksum. */
int fz_pmap(const uint8_t *data, size_t n);
/* A .guide through sh_guide_load, checksum fixed up as for fz_pmap. */
int fz_guide(const uint8_t *data, size_t n);
/* A raw float32 grid through rd_raw_load: the first 3 bytes give the dims (1 + byte % 16 each),
 * the rest is the file. */
int fz_raw(const uint8_t *data, size_t n);
/* A .vdb through the OpenVDB shim rd_vdb_load (grid "density"). */
int fz_vdb(const uint8_t *data, size_t n);
/* An image through rd_image_read (OpenImageIO; what `compare --reference` and `--add` read):
 * the first byte picks the file's extension (even: .exr, odd: .png), the rest is the file. */
int fz_image(const uint8_t *data, size_t n);

#endif
