#!/usr/bin/env bash
# Model no more than a scene needs: the server's memory against its cache
# setting and the file's size, a sampler's memory against the view's
# working set and the scene's size, and the beams a fill computes against
# those the views see. Writes its tables to standard output; docs/RESULTS.md
# quotes them as published by `holodeck bench publish`:
#   docs/results/memory.sh | holodeck bench publish model \
#       --command docs/results/memory.sh --markdown docs/results
# Usage: docs/results/memory.sh [HOLODECK] [WORK DIR]
set -euo pipefail
H=${1:-target/release/holodeck}
W=${2:-target/model-memory}
# Every run measures files made by this build.
rm -rf "$W"
mkdir -p "$W"
hwm() { awk '/VmHWM/ {print $2 / 1024 " MiB"}' "/proc/$1/status"; }

parts=${PARTS:-123}   # which of the three parts to run, e.g. PARTS=13

# A walk through the room: 70 eye positions, six directions from each.
views="$W/walk.vf"
: > "$views"
for x in 0.8 1.6 2.4 3.2 4.0 4.8 5.4; do
  for y in 0.8 1.4 2.0 2.6 3.2; do
    for z in 1.0 1.8; do
      for d in "1 0.3 -0.1" "-1 -0.3 0" "0.2 1 0" "-0.3 -1 0.2" "0 0.1 -1" "0.1 0 1"; do
        echo "-vtv -vp $x $y $z -vd $d -vu 0 0 1 -vh 90 -vv 70" >> "$views"
      done
    done
  done
done

# 1. Server: one file, three cache settings, the same headless walk.
if [[ $parts == *1* ]]; then
"$H" fill builtin:room "$W/room.hdk" --rays 30M --bounces 0 -q
echo "file: $(( $(stat -c %s "$W/room.hdk") >> 20 )) MiB, $(wc -l < "$views") views"
echo "| cache | server peak RSS | samples sent and drawn | walk time |"
echo "|---|---|---|---|"
for cache in 16M 64M 256M 1G; do
  "$H" serve "$W/room.hdk" --no-fill --cache "$cache" --listen 127.0.0.1:7417 --token t -q > /dev/null &
  pid=$!
  sleep 1
  start=$(date +%s.%N)
  drawn=$("$H" view --connect 127.0.0.1:7417 --token t --headless --read-only --views "$views" \
      --frames "$W/frames" -x 256 -y 192 --stride 2 | awk '{gsub(",", "", $2); s += $2} END {print s}')
  secs=$(echo "$(date +%s.%N) - $start" | bc)
  echo "| $cache | $(hwm $pid) | $drawn | ${secs} s |"
  kill -TERM $pid
  wait $pid || true
done
fi

# 2. Sampler: one scene file, views that need little and much of it.
if [[ $parts == *2* ]]; then
"$H" scene build builtin:landscape --triangles 10M -o "$W/land.hds" -q
echo "scene file: $(( $(stat -c %s "$W/land.hds") >> 20 )) MiB"
echo "| view | mode | peak RSS | render output |"
echo "|---|---|---|---|"
for v in "forest|-vp 8 2 4 -vd 1 0 -0.12 -vh 90 -vv 60" "above the room|-vp -20 2 40 -vd 1 0 -0.45 -vh 70 -vv 50" "horizon|-vp 0 0 120 -vd 1 0.3 -0.08 -vh 90 -vv 60"; do
  name=${v%%|*}
  view="-vtv ${v#*|} -vu 0 0 1"
  for mode in --out-of-core ""; do
    out=$( { /usr/bin/time -f "TIME %M" "$H" render "$W/land.hds" --view "$view" -x 512 -y 384 --spp 1 --bounces 1 $mode -o "$W/land.png" ; } 2>&1 )
    rss=$(echo "$out" | awk '/^TIME/ {print $2 / 1024 " MiB"}')
    echo "| $name | ${mode:-in core} | $rss | $(echo "$out" | grep -v '^TIME' | tr '\n' ' ' | cut -c1-200) |"
  done
done
fi

# 3. Beams: a fill for the walk's views against a fill of the whole volume.
if [[ $parts == *3* ]]; then
for how in "whole volume|" "the walk's views|--views $views"; do
  rm -f "$W/beams.hdk"
  echo "$(echo "$how" | cut -d'|' -f1): $("$H" fill builtin:room "$W/beams.hdk" --rays 2M --bounces 0 ${how#*|} 2>&1 | tail -1 | sed "s/.*rays\/s[^;]*; //")"
done
fi
