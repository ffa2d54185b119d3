#!/usr/bin/env bash
# Regenerate the small volume files the example scenes use, from procedural media:
#   scenes/data/smoke.vdb  <- the noise smoke of scenes/default.json, 64 voxels across
# Usage: scripts/make-volumes.sh [path/to/photonmarch]
set -euo pipefail
BIN=${1:-build/photonmarch}
"$BIN" voxelize scenes/default.json --res 64 -o scenes/data/smoke.vdb
