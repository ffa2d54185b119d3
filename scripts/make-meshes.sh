#!/usr/bin/env bash
# Make the triangle meshes of the surface scenes (issue 14) in scenes/data/, by
# tools/make-meshes.c (built by `make tools`). Small enough to commit; remade here:
#   scenes/data/icosphere-3.obj   unit icosphere, level 3 (1280 triangles)
#   scenes/data/blob-4.obj        displaced icosphere, level 4 (5120 triangles)
#   scenes/data/knot.obj          (2,3) torus knot tube, 192 rings of 12 (4608 triangles)
#   scenes/data/box.obj           the cube [-1,1]^3, flat (12 triangles): floors
#   scenes/data/window-wall.obj   the slab [-1,1]^3 with a hole [-0.25,0.25] x [-0.16,0.24]
#                                 through z, flat (32 triangles): a wall with a window
# Usage: scripts/make-meshes.sh [BUILD]   (BUILD: the build folder, default build)
set -euo pipefail
BUILD=${1:-build}
make -s BUILD="$BUILD" "$BUILD/tools/make-meshes"
T="$BUILD/tools/make-meshes"
mkdir -p scenes/data
"$T" icosphere 3 scenes/data/icosphere-3.obj
"$T" displaced 4 scenes/data/blob-4.obj
"$T" knot 192 12 scenes/data/knot.obj
"$T" box scenes/data/box.obj
"$T" wall -0.25 0.25 -0.16 0.24 scenes/data/window-wall.obj
ls -l scenes/data/icosphere-3.obj scenes/data/blob-4.obj scenes/data/knot.obj scenes/data/box.obj scenes/data/window-wall.obj
