#!/usr/bin/env bash
# Display-only replay, as on a low-end machine with no GPU: a walk of views
# drawn from a filled room file by each CPU driver on one core and on all
# cores, a fresh driver for each view and then the same walk in one driver
# (as the window replays it). Writes its tables to standard output;
# docs/RESULTS.md quotes them as published by `holodeck bench publish`:
#   docs/results/replay.sh | holodeck bench publish replay \
#       --command docs/results/replay.sh --markdown docs/results
# Usage: docs/results/replay.sh [HOLODECK] [WORK DIR]
set -euo pipefail
H=${1:-target/release/holodeck}
W=${2:-target/replay}
mkdir -p "$W"
F="$W/room.hdk"
VIEW="-vtv -vp 0.7 2 1.5 -vd 1 0 -0.1 -vu 0 0 1 -vh 75 -vv 56"
# The file is filled once for the walk's first view and kept.
if [ ! -f "$F" ]; then
  echo "$VIEW" > "$W/view.vf"
  "$H" fill builtin:room "$F" --rays 8M --views "$W/view.vf" -q >&2
fi
echo "A walk of 10 views from \`$VIEW\`, 5 cm and 2 degrees a step, at 1280 x 720, from a file of the room filled with 8M rays for the first view (\`holodeck bench replay\`):"
echo
"$H" bench replay "$F" --views 10 --view "$VIEW"
