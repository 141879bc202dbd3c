#!/usr/bin/env bash
# Frame rates and latencies of the walkthrough window, per driver, replaying a
# holodeck file on a virtual X screen (the GPU drivers on whatever Vulkan
# adapter wgpu picks: lavapipe where there is no GPU):
#   still:   `bench 20`, 20 frames drawn back to back;
#   motion:  the left button held for 2 s over the middle of the window
#            (frames during the motion; from the press to the first step on
#            screen: the input-to-frame latency);
#   refined: from the release to the first frame with the new view's beams.
# Usage: scripts/bench-window.sh FILE.hdk [WIDTH HEIGHT [DRIVERS...]]
# With SERVER="--connect HOST:PORT --token-file F" the window is a live
# display on that server (`holodeck view`) instead of a replay of FILE.
# Needs Xvfb, xdotool (apt-get install xvfb xdotool) and a built holodeck
# (HOLODECK=path, default target/release/holodeck). EXTRA="--denoise off"
# (say) adds flags to the window's command.
set -euo pipefail
file=${1:?usage: $0 FILE.hdk [WIDTH HEIGHT [DRIVERS...]]}
width=${2:-640}
height=${3:-480}
shift $(( $# > 3 ? 3 : $# ))
drivers=("$@")
[ ${#drivers[@]} -gt 0 ] || drivers=(quadtree splat voronoi mesh)
holodeck=${HOLODECK:-target/release/holodeck}
work=$(mktemp -d)
Xvfb -displayfd 3 -screen 0 1280x1024x24 -nolisten tcp 3>"$work/display" 2>/dev/null &
xvfb=$!
trap 'kill $xvfb 2>/dev/null; rm -rf "$work"' EXIT
for _ in $(seq 50); do [ -s "$work/display" ] && break; sleep 0.1; done
export DISPLAY=":$(cat "$work/display")"
wait_for() { # pattern file
    for _ in $(seq 600); do grep -q "$1" "$2" && return 0; sleep 0.1; done
    echo "no '$1' in $2:" >&2; cat "$2" >&2; return 1
}
for driver in "${drivers[@]}"; do
    out="$work/$driver.out"
    mkfifo "$work/$driver.in"
    if [ -n "${SERVER:-}" ]; then
        # shellcheck disable=SC2086
        set -- view $SERVER -i
    else
        set -- pict "$file" --window -i
    fi
    # shellcheck disable=SC2086
    "$holodeck" "$@" --driver "$driver" -x "$width" -y "$height" ${EXTRA:-} \
        <"$work/$driver.in" >"$out" 2>"$work/$driver.err" &
    pid=$!
    exec 4>"$work/$driver.in"
    wait_for '^ready' "$out"
    echo "bench 20" >&4
    wait_for '^frames:' "$out"
    id=$(xdotool search --sync --name '^holodeck: ' | head -1)
    xdotool mousemove --window "$id" $((width / 2)) $((height / 2))
    xdotool mousedown 1
    sleep 2
    xdotool mouseup 1
    echo sync >&4
    wait_for '^refined:' "$out"
    echo quit >&4
    exec 4>&-
    wait $pid || true
    echo "== $driver, $width x $height"
    grep -E '^(frames|moved|motion|refined):' "$out"
done
