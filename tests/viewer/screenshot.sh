#!/usr/bin/env bash
# Headless-Chromium test of the HTML viewer (`cordis render`): builds pages for a small
# spring scene and for a cloth compared against a softer one, screenshots them, and checks
# that the pictures are not blank and that the page's script raised no error.
#
#   tests/viewer/screenshot.sh [OUTDIR]      (default: a temporary directory)
#
# Skipped (exit 0) when `chromium` is not on PATH, except in CI (CI=true), where it fails. Builds and uses target/release/cordis.
# Needs python3 (standard library only). Takes about half a minute.
set -euo pipefail

root=$(cd "$(dirname "$0")/../.." && pwd)
here="$root/tests/viewer"
if ! command -v chromium >/dev/null 2>&1; then
    # In CI the browser is installable (scripts/test.sh installs it): a skip would hide a failure.
    if [ "${CI:-}" = "true" ]; then
        echo "FAIL: chromium is not on PATH in CI (scripts/test.sh installs Debian's package)"
        exit 1
    fi
    echo "skipped: chromium is not on PATH"
    exit 0
fi
out=${1:-$(mktemp -d)}
mkdir -p "$out"
out=$(cd "$out" && pwd)

cordis="$root/target/release/cordis"
# Always: the viewer's script is compiled into the binary, a stale one would test old code.
(cd "$root" && cargo build --release -q -p cordis-cli)

python3 "$here/scenes.py" "$out"
"$cordis" simulate "$out/spring.json" --frames 400 --out "$out/spring.csv" -q >/dev/null
"$cordis" simulate "$out/cloth.json" --frames 300 --out "$out/cloth.npy" -q >/dev/null
"$cordis" simulate "$out/cloth_b.json" --frames 300 --out "$out/cloth_b.npy" -q >/dev/null
"$cordis" simulate "$out/fluid.json" --frames 300 --out "$out/fluid.tra" -q >/dev/null
"$cordis" render "$out/spring.json" --trajectory "$out/spring.csv" --html "$out/spring.html"
"$cordis" render "$out/fluid.json" --trajectory "$out/fluid.tra" --html "$out/fluid.html"
"$cordis" render "$out/cloth.json" --trajectory "$out/cloth.npy" --compare "$out/cloth_b.npy" \
    --html "$out/cloth.html" --title "cloth: original vs softer model"

# A page that does not fit its scene is refused with one line naming the file.
if "$cordis" render "$out/spring.json" --trajectory "$out/cloth.npy" --html "$out/bad.html" \
    2>"$out/bad.err"; then
    echo "FAIL: a cloth motion was accepted for the spring scene"; exit 1
fi
grep -q "cloth.npy: has 400 particles, the scene has 9" "$out/bad.err" \
    || { echo "FAIL: unexpected message: $(cat "$out/bad.err")"; exit 1; }

shoot() { # page.html#fragment shot.png
    local log="${2%.png}.log"
    # --enable-logging=stderr reports console errors ("Uncaught …") on stderr.
    chromium --headless --disable-gpu --no-sandbox --hide-scrollbars --enable-logging=stderr \
        --window-size=1000,700 --virtual-time-budget=1000 --screenshot="$2" \
        "file://$1" >"$log" 2>&1 || { cat "$log"; echo "FAIL: chromium failed on $1"; exit 1; }
    if grep -E "Uncaught|SyntaxError|TypeError|ReferenceError" "$log"; then
        echo "FAIL: the page's script failed: $1"; exit 1
    fi
    python3 "$here/png_check.py" "$2"
}

shoot "$out/spring.html#frame=120" "$out/spring.png"
shoot "$out/cloth.html#frame=150" "$out/cloth.png"
shoot "$out/cloth.html#frame=150&mode=side" "$out/cloth-side.png"
shoot "$out/fluid.html#frame=200" "$out/fluid.png"
# Ground contact: the bouncing ball over its `plane`, at frame 455, in its first contact
# (the surface patch and the tick of the penetration are drawn).
"$cordis" example bouncing-ball --out "$out/ball.json" >/dev/null
"$cordis" simulate "$out/ball.json" --frames 2000 --out "$out/ball.npy" -q >/dev/null
"$cordis" render "$out/ball.json" --trajectory "$out/ball.npy" --html "$out/ball.html"
grep -q '"plane":{' "$out/ball.html" || { echo "FAIL: ball.html has no plane"; exit 1; }
shoot "$out/ball.html#frame=455" "$out/ball.png"
# The controls: a copy of the cloth page with tests/viewer/interact.js injected after the
# viewer's script drives them with synthetic events and reports in <body data-test>.
python3 - "$out/cloth.html" "$here/interact.js" "$out/interact.html" <<'PY'
import sys
page, script, out = sys.argv[1:]
text = open(page, encoding="utf-8").read()
extra = "<script>\n" + open(script, encoding="utf-8").read() + "</script>\n</body>"
open(out, "w", encoding="utf-8").write(text.replace("</body>", extra, 1))
PY
chromium --headless --disable-gpu --no-sandbox --window-size=1000,700 --virtual-time-budget=5000 \
    --dump-dom "file://$out/interact.html" 2>/dev/null >"$out/interact.dom"
result=$(grep -o 'data-test="[^"]*"' "$out/interact.dom" || true)
echo "controls: $result"
if [ -z "$result" ] || echo "$result" | grep -q FAIL; then
    echo "FAIL: the controls do not respond as expected"; exit 1
fi
# The frame the PNG button exported decodes and drew something.
grep -o 'data-png="data:image/png;base64,[^"]*"' "$out/interact.dom" \
    | sed 's/^data-png="data:image\/png;base64,//; s/"$//' | base64 -d >"$out/exported.png"
python3 "$here/png_check.py" "$out/exported.png" 800 any

# A large scene: the page stays small, and building a frame's drawing is fast: `#bench=10`
# makes the page draw ten times and record the mean time in <body data-draw-ms> (the time of
# the script: projection and paths; the browser rasterizes afterwards, on the GPU if any).
"$cordis" simulate "$out/big.json" --frames 200 --out "$out/big.npy" -q >/dev/null
"$cordis" render "$out/big.json" --trajectory "$out/big.npy" --compare "$out/big.npy" \
    --html "$out/big.html"
size=$(stat -c %s "$out/big.html")
[ "$size" -lt 20000000 ] || { echo "FAIL: big.html is $size bytes"; exit 1; }
chromium --headless --disable-gpu --no-sandbox --window-size=1000,700 --virtual-time-budget=5000 \
    --dump-dom "file://$out/big.html#frame=199&bench=10" 2>/dev/null >"$out/big.dom"
ms=$(grep -o 'data-draw-ms="[0-9.]*"' "$out/big.dom" | grep -o '[0-9.]\+' || true)
[ -n "$ms" ] || { echo "FAIL: big.html drew nothing"; exit 1; }
echo "big.html: $size bytes; a frame (A and B overlaid, 2 x 14,898 links) built in $ms ms"
python3 -c "import sys; sys.exit(0 if float('$ms') < 100 else 1)" \
    || { echo "FAIL: drawing a frame took $ms ms"; exit 1; }
# The identification report (`cordis report`): a fit of the rigid example by output-error
# (with intervals) to a noisy motion, screenshotted in both themes. No fetch is allowed: the
# page's Content-Security-Policy blocks any, and Chromium's console reports each blocked one
# ("… violates the following Content Security Policy directive"), which fails the test.
"$cordis" example rigid --out "$out/rigid.json" -q
"$cordis" example rigid --unknowns --out "$out/rigid-u.json" -q
"$cordis" simulate "$out/rigid.json" --frames 100 --out "$out/rigid.npy" -q >/dev/null
"$cordis" identify "$out/rigid-u.json" -t "$out/rigid.npy" --strategy output-error --noise 0.001 \
    --log "$out/rigid-log.csv" --out "$out/rigid-fit.json" --json -q >"$out/rigid-summary.json"
"$cordis" report "$out/rigid-fit.json" -t "$out/rigid.npy" --log "$out/rigid-log.csv" \
    --summary "$out/rigid-summary.json" --html "$out/report.html"
if grep -Eq '(src|href|action)="[a-z]+:|url\((https?:)?//' "$out/report.html"; then
    echo "FAIL: report.html refers to an outside resource"; exit 1
fi
for theme in light dark; do
    log="$out/report-$theme.log"
    chromium --headless --disable-gpu --no-sandbox --hide-scrollbars --enable-logging=stderr \
        --v=0 --log-level=0 --window-size=1100,2400 --virtual-time-budget=2000 \
        --screenshot="$out/report-$theme.png" "file://$out/report.html#theme=$theme" >"$log" 2>&1 \
        || { cat "$log"; echo "FAIL: chromium failed on report.html"; exit 1; }
    if grep -E "Uncaught|SyntaxError|TypeError|ReferenceError|Content Security Policy" "$log"; then
        echo "FAIL: report.html ($theme) raised an error or tried a fetch"; exit 1
    fi
    (cd "$here" && python3 report_check.py "$out/report-$theme.png" "$theme")
done
echo "ok: screenshots in $out"
