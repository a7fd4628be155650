#!/usr/bin/env bash
# Screenshots a report the way a reader sees it: headless Chromium renders each figure of
# REPORT.html (every inline <svg> inside a <figure>) on its own, at its own size, into
# OUTDIR/fig_NN.png, and the page itself (its first 1280×TOP pixels) into OUTDIR/page.png.
# Look at the PNGs with any image viewer.
#
#   scripts/screenshot.sh out/report/report.html out/shots [TOP]
#
# Needs chromium (Debian: apt-get install chromium) and python3; no network.
set -euo pipefail
if [ $# -lt 2 ]; then
    echo "usage: $0 REPORT.html OUTDIR [TOP]" >&2
    exit 2
fi
report=$1
outdir=$2
top=${3:-2400}
browser=$(command -v chromium || command -v chromium-browser || command -v google-chrome || true)
if [ -z "$browser" ]; then
    echo "$0: no chromium found (apt-get install chromium)" >&2
    exit 2
fi
mkdir -p "$outdir"
python3 - "$report" "$outdir" <<'PY'
import re, sys, pathlib
html = pathlib.Path(sys.argv[1]).read_text(encoding="utf-8")
out = pathlib.Path(sys.argv[2])
figs = re.findall(r"<figure>\s*(<svg.*?</svg>)", html, flags=re.S)
with open(out / "sizes.txt", "w") as sizes:
    for i, svg in enumerate(figs, 1):
        if "xmlns=" not in svg[:200]:
            svg = svg.replace("<svg", '<svg xmlns="http://www.w3.org/2000/svg"', 1)
        m = re.search(r'width="([\d.]+)" height="([\d.]+)"', svg)
        w, h = (int(float(m.group(1))) + 1, int(float(m.group(2))) + 1) if m else (800, 600)
        (out / f"fig_{i:02}.svg").write_text(svg, encoding="utf-8")
        sizes.write(f"fig_{i:02} {w} {h}\n")
print(f"{len(figs)} figures")
PY
shoot() { # file.svg|html out.png width height
    "$browser" --headless --no-sandbox --disable-gpu --hide-scrollbars \
        --window-size="$3,$4" --screenshot="$2" "file://$(realpath "$1")" >/dev/null 2>&1
}
while read -r name w h; do
    shoot "$outdir/$name.svg" "$outdir/$name.png" "$w" "$h"
done < "$outdir/sizes.txt"
shoot "$report" "$outdir/page.png" 1280 "$top"
ls "$outdir"/*.png
