#!/usr/bin/env bash
# Regenerate docs/cli.md from the binary's own --help texts, so the reference cannot drift
# from the program. Usage: scripts/make-cli-doc.sh [path/to/photonmarch]
set -euo pipefail
BIN=${1:-build/photonmarch}
out=docs/cli.md
tmp=$(mktemp)
{
  sed -n '1,/^<!-- help -->$/p' "$out"
  for c in "" render info bake voxelize compare explain; do
    if [ -z "$c" ]; then echo '## photonmarch --help'; else echo "## photonmarch $c"; fi
    echo; echo '```'; "$BIN" $c --help; echo '```'; echo
  done
  sed -n '/^<!-- end help -->$/,$p' "$out"
} > "$tmp"
chmod 644 "$tmp"
mv "$tmp" "$out"
