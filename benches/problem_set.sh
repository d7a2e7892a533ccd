#!/usr/bin/env bash
# The problem set of the README's performance profile: the Siconos fc2d files in
# ../shared/data/siconos-fc2d (when present) and problems dumped from shipped scenes, swept by every
# CPU solver. Usage: bash benches/problem_set.sh [OUT]   (default out/problem_set; about 3 min)
set -euo pipefail
out=${1:-out/problem_set}
moreau=(cargo run --release --quiet --)
mkdir -p "$out/problems"
# --anderson 0: the plain-NLGS trajectory, so the problem set stays the one first measured.
dump() { # scene, steps to dump..., from a run of the last one
    local scene=$1; shift
    local last=${*: -1} args=()
    for s in "$@"; do args+=(--dump-problem "$s"); done
    local name
    name=$(basename "$scene" .toml)
    "${moreau[@]}" run "$scene" --device cpu --anderson 0 --steps "$last" --quiet --vtk-every 0 --out "$out/runs/$name" "${args[@]}" >/dev/null
    for s in "$@"; do
        cp "$out/runs/$name/$(printf 'problem_%06d.dat' "$s")" "$out/problems/${name}_$(printf '%04d' "$s").dat"
    done
}
dump scenes/pile.toml 40 80 150 300
dump scenes/polygon_pile.toml 100 200
dump scenes/box_pyramid.toml 1 50
dump scenes/rotating_drum.toml 100 200
dump scenes/hopper.toml 100
shared=../shared/data/siconos-fc2d
if [ -d "$shared" ]; then cp "$shared"/*.dat "$out/problems/"; fi
# newton (the Alart–Curnier prototype) is left out: an iteration is a Newton step of up to 120
# products, so the shared iteration cap would let it run for many minutes on the frictional files.
"${moreau[@]}" sweep "$out/problems" --devices cpu --solvers nlgs,pcpg,cpg,jacobi,apgd,latin,nlgs-newton,interior-point \
    --tols 1e-2,1e-4,1e-6,1e-8 --profile-tol 1e-6,1e-4,1e-8 --max-iter 20000 --out "$out/sweep"
