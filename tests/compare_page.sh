#!/usr/bin/env bash
# The compare report page in headless Chromium (issue 11). Usage: tests/compare_page.sh DIR [SHOT.png]
# Loads DIR/index.html#selftest from disk (file://, no server): the page's self-check, run on the
# window's load event (every image has then loaded or failed), checks that every image has a
# natural width > 0 and that a click on the viewer switches its image (it waits for the new
# image's load event), and writes "SELFTEST PASS" or "SELFTEST FAIL" into #selftest.
# --dump-dom prints the DOM once the page is idle (--virtual-time-budget: Chromium's virtual
# clock, advanced as soon as nothing is pending; no wall-clock sleep). The console (every
# message the page or Chromium logs for it: script errors, images that fail to load) goes to
# stderr with --enable-logging=stderr; any console line fails the check, since the page logs
# nothing of its own. Then --screenshot writes SHOT.png (default DIR/screenshot.png).
# Exit 0 when everything passed; 1 with the reason otherwise.
set -uo pipefail
dir=$(cd "$1" && pwd) || { echo "compare_page: no folder $1"; exit 1; }
shot=${2:-$dir/screenshot.png}
browser=$(command -v chromium || command -v chromium-browser) || { echo "compare_page: chromium not installed (scripts/install-deps.sh)"; exit 1; }
profile=$(mktemp -d)
trap 'rm -rf "$profile"' EXIT
flags=(--headless --no-sandbox --disable-gpu --no-first-run --user-data-dir="$profile"
       --allow-file-access-from-files --virtual-time-budget=20000)
url="file://$dir/index.html"

"$browser" "${flags[@]}" --enable-logging=stderr --v=0 --dump-dom "$url#selftest" \
    >"$profile/dom.html" 2>"$profile/log.txt"
status=$?
[ $status -eq 0 ] || { echo "compare_page: chromium exited $status"; tail -5 "$profile/log.txt"; exit 1; }
result=$(sed -n '/<pre id="selftest"/,/<\/pre>/p' "$profile/dom.html")
echo "$result" | sed 's/<[^>]*>//g'
echo "$result" | grep -q 'SELFTEST PASS' || { echo "compare_page: the page's self-check did not pass"; exit 1; }
if grep -q 'CONSOLE' "$profile/log.txt"; then
    echo "compare_page: console messages:"; grep 'CONSOLE' "$profile/log.txt"; exit 1
fi
"$browser" "${flags[@]}" --window-size=1280,1500 --hide-scrollbars --screenshot="$shot" "$url" \
    >/dev/null 2>"$profile/shot.txt"
[ -s "$shot" ] || { echo "compare_page: no screenshot at $shot"; tail -5 "$profile/shot.txt"; exit 1; }
echo "compare_page: ok; screenshot $shot"
