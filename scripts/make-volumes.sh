#!/usr/bin/env bash
# Make the volume files the example scenes use (scenes/data/), through OpenVDB:
#   scenes/data/smoke.vdb       <- the noise smoke of scenes/default.json, 64 voxels across
#                                  (small: committed; remade here)
#   scenes/data/dense-512.vdb   <- scenes/noise-block.json voxelised at 512^3, every voxel
#                                  active (scenes/dense-512.json; ~0.5 GB, not committed)
#   scenes/data/plume-1024.vdb  <- a 1024^3 sparse smoke plume, about 5% of the voxels active,
#                                  by scripts/make-plume.cpp (scenes/plume-1024.json; ~0.2 GB,
#                                  not committed)
# Usage: scripts/make-volumes.sh [path/to/photonmarch] [which...]
#   which: smoke, dense-512, plume-1024 (default: all three). Each takes from seconds (smoke)
#   to a few minutes (the large two) on 2 cores.
set -euo pipefail
BIN=${1:-build/photonmarch}
shift || true
WHICH=${*:-smoke dense-512 plume-1024}
CXX=${CXX:-g++}
for w in $WHICH; do
    case $w in
    smoke) "$BIN" voxelize scenes/default.json --res 64 -o scenes/data/smoke.vdb ;;
    dense-512) "$BIN" voxelize scenes/noise-block.json --res 512 -o scenes/data/dense-512.vdb ;;
    plume-1024)
        mkdir -p build
        "$CXX" -std=c++17 -O2 -Wall -Wextra -Wno-deprecated-declarations scripts/make-plume.cpp \
            -o build/make-plume -lopenvdb -ltbb -lImath
        build/make-plume scenes/data/plume-1024.vdb 1024 1 ;;
    *) echo "make-volumes.sh: unknown volume '$w' (smoke, dense-512, plume-1024)" >&2; exit 2 ;;
    esac
done
