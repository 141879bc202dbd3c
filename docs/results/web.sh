#!/usr/bin/env bash
# The web display against the native display client, same run: one server
# (no fill: what is stored is all there is) of a room file, the same walk of
# views at 640 x 480 with the quadtree driver (no denoiser), drawn
# by `holodeck view --headless` and by the page in Debian's chromium
# (headless, driven by holodeck-tools/tests/web/bench.mjs: `npm ci` there
# first). Writes its tables to standard output; docs/RESULTS.md quotes them
# as published by `holodeck bench publish`:
#   docs/results/web.sh | holodeck bench publish web \
#       --command docs/results/web.sh --markdown docs/results
# Usage: docs/results/web.sh [HOLODECK] [WORK DIR]
set -euo pipefail
H=$(realpath "${1:-target/release/holodeck}")
W=${2:-target/web-bench}
NODE_DIR=$(dirname "$0")/../../holodeck-tools/tests/web
rm -rf "$W" && mkdir -p "$W"
W=$(realpath "$W")
F="$W/room.hdk"
VIEW="-vtv -vp 0.7 2 1.5 -vd 1 0 -0.1 -vu 0 0 1 -vh 75 -vv 56"
echo "$VIEW" > "$W/fill.vf"
"$H" fill builtin:room "$F" --rays 4M --views "$W/fill.vf" -q >&2
# The walk: 5 cm forward and 2 degrees left a step.
python3 - "$W/walk.vf" <<'PY'
import math, sys
with open(sys.argv[1], "w") as f:
    for i in range(8):
        a = math.radians(2 * i)
        f.write(f"-vtv -vp {0.7 + 0.05 * i:.2f} 2 1.5 -vd {math.cos(a):.6f} {math.sin(a):.6f} -0.1 -vu 0 0 1 -vh 75 -vv 56\n")
PY
"$H" serve "$F" --listen 127.0.0.1:0 --no-fill --web 127.0.0.1:0 > "$W/serve.log" 2>&1 &
SERVER=$!
trap 'kill $SERVER 2>/dev/null || true' EXIT
for _ in $(seq 100); do grep -q "web display on" "$W/serve.log" && break; sleep 0.1; done
ADDR=$(sed -n 's/^listening on //p' "$W/serve.log" | head -1)
LINK=$(sed -n 's/.*a viewer.s link: \(.*\))$/\1/p' "$W/serve.log")
"$H" view --connect "$ADDR" --token-file "$F.viewer.token" --headless --views "$W/walk.vf" \
    --frames "$W/native" -x 640 -y 480 --wait 0s --denoise off > "$W/native.log" 2>&1
FIRST=$(head -1 "$W/walk.vf" | sed 's/ /%20/g')
tail -n +2 "$W/walk.vf" | (cd "$NODE_DIR" && node bench.mjs "$LINK&view=$FIRST&width=640&height=480&max-density=1&denoise=off" 20) > "$W/page.json"
kill "$SERVER" && wait "$SERVER" || true
"$H" export web "$F" -o "$W/site" -q
python3 - "$W" <<'PY'
import gzip, json, re, sys
w = sys.argv[1]
native = []
for line in open(f"{w}/native.log"):
    m = re.search(r"([\d,]+) new samples in (\d+) ms .* drawn in ([\d.]+) ms", line)
    if m:
        native.append((int(m[1].replace(",", "")), float(m[2]), float(m[3])))
page = json.load(open(f"{w}/page.json"))
wasm = open(f"{w}/site/holodeck_web_bg.wasm", "rb").read()
def rate(samples, ms): return samples / max(ms, 1e-9) * 1e3
n0, t0, _ = native[0]
later = native[1:]
nl_s, nl_t = sum(x[0] for x in later), sum(x[1] for x in later)
p0 = page["first"]
pc = page["changes"]
pl_s, pl_t, pl_b = sum(c["samples"] for c in pc), sum(c["ms"] for c in pc), sum(c["bytes"] for c in pc)
frame_native = sum(x[2] for x in native) / len(native)
print(f"A walk of {len(native)} views at 640 x 480 from one server of the room filled with 4M rays for the first view; the quadtree driver, no denoiser; the page in Debian's chromium (headless, no GPU), the native client `holodeck view --headless`, same run:")
print()
print("| | native client | web page | page / native |")
print("|---|---|---|---|")
print(f"| first view: samples | {n0:,} | {p0['samples']:,} | |")
print(f"| first view: samples/s (request to last ray drawn in; the page from opening the link) | {rate(n0, t0):,.0f} | {rate(p0['samples'], p0['ms']):,.0f} | {rate(p0['samples'], p0['ms']) / rate(n0, t0):.2f} |")
print(f"| {len(pc)} view changes: mean ms to every stored ray | {nl_t / len(later):.0f} | {pl_t / len(pc):.0f} | {(pl_t / len(pc)) / (nl_t / len(later)):.2f} |")
print(f"| view changes: samples/s | {rate(nl_s, nl_t):,.0f} | {rate(pl_s, pl_t):,.0f} | {rate(pl_s, pl_t) / rate(nl_s, nl_t):.2f} |")
print(f"| a frame drawn afresh by the quadtree, ms | {frame_native:.1f} | {page['frame']['render_ms']:.1f} | {page['frame']['render_ms'] / frame_native:.2f} |")
print(f"| the page's whole draw of a frame (the quadtree, the tone map and the canvas), ms | | {page['frame']['draw_ms']:.1f} | |")
print()
print(f"Bytes sent to the page per view change: {pl_b / len(pc) / 1e6:.2f} MB on average ({pl_b / max(pl_s, 1):.1f} bytes per sample; the first view {p0['bytes'] / 1e6:.1f} MB). The WebAssembly is {len(wasm) / 1e3:.0f} kB ({len(gzip.compress(wasm)) / 1e3:.0f} kB gzipped).")
PY
