#!/usr/bin/env bash
# Install exactly the Debian 12 packages photonmarch needs to build, test and render.
# Idempotent: when everything is present it only runs dpkg-query and exits (well under a second).
set -euo pipefail

PACKAGES=(
  build-essential pkg-config   # gcc, g++ (C++ shims), make
  libflann-dev liblz4-dev      # FLANN kd-tree (C API) for photon queries
  libopenimageio-dev           # EXR/PNG in and out
  libcjson-dev                 # scene files
  libembree-dev                # ray-triangle intersection for meshes (Embree 3 C API; issue 14)
  libassimp-dev                # OBJ/PLY mesh loading (assimp's C API, cimport.h; issue 14)
  libopenvdb-dev libtbb-dev    # .vdb volumes
  libcriterion-dev             # test framework
  gnuplot-nox                  # charts in reports and benchmarks
  python3                      # tests/check_structure.py (the code's dependency rules, make test)
  chromium                     # headless check of the compare report page (make test)
  clang-14 libclang-rt-14-dev  # make fuzz: clang with libFuzzer and its ASan/UBSan runtimes
  libomp-14-dev                # OpenMP for the clang-built fuzz targets
  libopenmpi-dev openmpi-bin   # MPI: one job over several processes or nodes (renderer/dist/, mpirun; docs/cluster.md)
)

missing=()
for p in "${PACKAGES[@]}"; do
  [[ "$p" == \#* ]] && continue
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi

echo "install-deps: installing ${missing[*]}" >&2
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "install-deps: done" >&2
