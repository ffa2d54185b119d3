#!/usr/bin/env bash
# Regenerate docs/cli.md from the binary's own --help texts, so the reference cannot drift
# from the program, then check that every option renderer/cli/ parses is named in the page
# (its --help sections or the hand-written "Option values" table); exit 1 if one is not.
# Usage: scripts/make-cli-doc.sh [path/to/photonmarch]
set -euo pipefail
cd "$(dirname "$0")/.."
BIN=${1:-build/photonmarch}
out=docs/cli.md
tmp=$(mktemp)
{
  sed -n '1,/^<!-- help -->$/p' "$out"
  for c in "" render info bake voxelize compare explain; do
    if [ -z "$c" ]; then echo '## photonmarch --help'; else echo "## photonmarch $c"; fi
    # shellcheck disable=SC2086  # "" must vanish: `photonmarch --help` has no command
    echo; echo '```'; "$BIN" $c --help; echo '```'; echo
  done
  sed -n '/^<!-- end help -->$/,$p' "$out"
} > "$tmp"
chmod 644 "$tmp"
mv "$tmp" "$out"
echo "make-cli-doc: wrote $out from $BIN --help" >&2

# Every option literal of renderer/cli/*.c ("--name" as a C string) must appear in the page.
missing=0
for opt in $(grep -oh '"--[a-z][a-z-]*"' renderer/cli/*.c | tr -d '"' | sort -u); do
    if ! grep -q -- "$opt" "$out"; then
        echo "make-cli-doc: $opt is parsed in renderer/cli/ but not named in $out" >&2
        missing=1
    fi
done
[ $missing = 0 ] && echo "make-cli-doc: every option of renderer/cli/ is in $out" >&2
exit $missing
