#!/usr/bin/env bash
# How a pixel's estimate treats its brightest ray, measured: for each scene
# (the room, lit by a lamp and the sun; the arcade and the blind room, lit
# mostly indirectly), two fills of 1M rays for its view (seeds 1 and 2), each
# drawn by the quadtree with every candidate and no denoiser, against a
# 2048-spp reference of two halves (`holodeck compare --second`). Prints the
# mean of the two fills of every measure per scene and candidate: FLIP,
# clamped relative RMSE, SSIM and the light kept per region.
# Usage: scripts/estimator-candidates.sh [DIR]   (HOLODECK=path, default target/release/holodeck)
set -euo pipefail
dir=${1:-target/estimator-candidates}
holodeck=${HOLODECK:-target/release/holodeck}
mkdir -p "$dir"
declare -A views=(
    [room]="-vtv -vp 0.7 2 1.5 -vd 1 0 -0.1 -vu 0 0 1 -vh 75 -vv 56"
    [blind]="-vtv -vp 0.8 0.9 1.5 -vd 1 0.45 -0.3 -vu 0 0 1 -vh 75 -vv 56"
    [arcade]="-vtv -vp 16.6 2.2 1.6 -vd -0.25 1 -0.05 -vu 0 0 1 -vh 75 -vv 56"
)
candidates=(
    "--firefly-ratio 0|as they are (plain mean)"
    "--firefly-ratio 10 --firefly-spread 0|cut at 10x, dropped (the old default)"
    "--firefly-ratio 10 --firefly-spread 3|cut at 10x, spread 3 px"
    "--firefly-ratio 4 --firefly-spread 3|cut at 4x, spread 3 px (default)"
    "--firefly-ratio 2 --firefly-spread 3|cut at 2x, spread 3 px"
    "--firefly-ratio 4 --firefly-spread 6|cut at 4x, spread 6 px"
)
echo "| scene | candidate | FLIP | clamped rel. RMSE | SSIM | frame | dark | middle | bright | band |"
echo "|---|---|---|---|---|---|---|---|---|---|"
for scene in room blind arcade; do
    view=${views[$scene]}
    echo "$view" > "$dir/$scene.vf"
    for seed in 1 2; do
        [ -f "$dir/$scene-$seed.hdk" ] || "$holodeck" fill "builtin:$scene" "$dir/$scene-$seed.hdk" --rays 1M \
            --views "$dir/$scene.vf" --seed "$seed" -q >/dev/null
    done
    for half in 1 2; do
        [ -f "$dir/$scene-ref$half.hdr" ] || "$holodeck" render "builtin:$scene" --view "$view" -x 160 -y 120 \
            --spp 1024 --seed "$((10 + half))" -o "$dir/$scene-ref$half.hdr" >/dev/null
    done
    for c in "${candidates[@]}"; do
        opts=${c%%|*}
        name=${c#*|}
        for seed in 1 2; do
            # shellcheck disable=SC2086
            "$holodeck" pict "$dir/$scene-$seed.hdk" --view "$view" -x 160 -y 120 --denoise off $opts \
                -o "$dir/pict.hdr" >/dev/null
            "$holodeck" compare "$dir/pict.hdr" "$dir/$scene-ref1.hdr" --second "$dir/$scene-ref2.hdr" \
                --scene "builtin:$scene" --view "$view" --json > "$dir/$scene-$seed.json"
        done
        python3 - "$scene" "$name" "$dir/$scene-1.json" "$dir/$scene-2.json" <<'PY'
import json, sys
scene, name, files = sys.argv[1], sys.argv[2], sys.argv[3:]
ms = [json.load(open(f))["metrics"] for f in files]
mean = lambda f: sum(f(m) for m in ms) / len(ms)
cells = [mean(lambda m: m["flip"]), mean(lambda m: m["clamped_relative_rmse"]), mean(lambda m: m["ssim"])]
light = [mean(lambda m, k=k: m["light"][k]) for k in ("frame", "dark", "middle", "bright", "band")]
print(f"| {scene} | {name} | {cells[0]:.4f} | {cells[1]:.4f} | {cells[2]:.3f} | " + " | ".join(f"{x:.3f}" for x in light) + " |")
PY
    done
done
