#!/usr/bin/env bash
# Screenshot of Rerun's web viewer on the built-in scene's recording: docs/images/rerun_viewer.png
# (issue 47). Not run by CI: it needs a browser and takes a few minutes on a CPU.
#
#   docs/images/screenshot_viewer.sh [OUT.png]          # from the repository root
#
# Needs: the venv with the viz extra (.venv/bin/pip install -e ".[viz]"), Debian's chromium
# (apt-get install chromium) and a Python with the playwright package (PW_PYTHON, default python3;
# e.g. python3 -m venv /tmp/pw && /tmp/pw/bin/pip install playwright && PW_PYTHON=/tmp/pw/bin/python).
# Playwright drives the system's chromium: no browser of its own is downloaded.
#
# Steps: record 300 steps of the built-in scene (`compare --rerun`), serve the file with Rerun's own
# web viewer (`rerun --serve-web`), with a blueprint that is the recording's own layout (RerunLog's)
# plus a camera near the pile and the side panels collapsed; open it in headless chromium (WebGL
# through SwiftShader, a CPU rasteriser) and screenshot it once two shots 10 s apart are the same.
# The viewer follows the data to the last step, 299.
set -euo pipefail
OUT=${1:-docs/images/rerun_viewer.png}
PW_PYTHON=${PW_PYTHON:-python3}
CHROMIUM=${CHROMIUM:-/usr/bin/chromium}
WEB_PORT=${WEB_PORT:-19090}
GRPC_PORT=${GRPC_PORT:-19877}
export RERUN_ANALYTICS=0
TMP=$(mktemp -d)
SERVER=""
cleanup() { if [ -n "$SERVER" ]; then kill -- "-$SERVER" 2>/dev/null || true; fi; rm -rf "$TMP"; }
trap cleanup EXIT

.venv/bin/python -m collide compare --steps 300 --rerun "$TMP/scene.rrd" > "$TMP/compare.txt"
.venv/bin/python - "$TMP/view.rbl" <<'EOF'
import sys
import rerun.blueprint as rrb

# RerunLog's layout (collide/rerun_log.py), with the eye on the pile rather than the whole floor.
eye = rrb.EyeControls3D(position=[1.2, -1.5, 1.1], look_target=[-0.15, 0.1, 0.15])
rrb.Blueprint(
    rrb.Horizontal(
        rrb.Spatial3DView(origin="/world", name="scene", eye_controls=eye),
        rrb.Vertical(
            rrb.TimeSeriesView(origin="/stats/pairs", name="geom pairs per step"),
            rrb.TimeSeriesView(origin="/stats/contacts", name="contact points per step"),
            rrb.TimeSeriesView(origin="/stats/time_us", name="time per step (us)"),
        ),
        column_shares=[3, 2],
    ),
    rrb.BlueprintPanel(state="collapsed"), rrb.SelectionPanel(state="collapsed"),
    rrb.TimePanel(state="collapsed", timeline="step"),
).save("collide", sys.argv[1])
EOF

# setsid: the server in a process group of its own (the venv's `rerun` starts the binary as a child).
setsid .venv/bin/rerun --serve-web --web-viewer-port "$WEB_PORT" --port "$GRPC_PORT" \
    "$TMP/scene.rrd" "$TMP/view.rbl" > "$TMP/rerun.log" 2>&1 &
SERVER=$!
sleep 5

"$PW_PYTHON" - "http://127.0.0.1:$WEB_PORT/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A$GRPC_PORT%2Fproxy&renderer=webgl" \
    "$OUT" "$CHROMIUM" <<'EOF'
import sys
import time
from playwright.sync_api import sync_playwright

url, out, chromium = sys.argv[1:4]
args = ["--no-sandbox", "--no-first-run", "--disable-quic", "--disable-background-networking",
        "--disable-component-update", "--disable-sync",
        "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist"]
with sync_playwright() as p:
    browser = p.chromium.launch(executable_path=chromium, headless=True, args=args)
    page = browser.new_page(viewport={"width": 1600, "height": 1000})
    page.goto(url)
    last, t0 = b"", time.monotonic()
    while True:  # WASM start, the data streamed in, then software-rendered frames: wait until still
        time.sleep(10)
        shot = page.screenshot(timeout=150_000)
        if shot == last or time.monotonic() - t0 > 300:
            break
        last = shot
    with open(out, "wb") as f:
        f.write(shot)
    print(f"wrote {out} after {time.monotonic() - t0:.0f} s ({'still' if shot == last else 'NOT still'})")
    browser.close()
EOF
