#!/usr/bin/env bash
# The frictional deposit by size and friction (BENCHMARKS.md, "Where the deposit stops being
# solvable: size and friction"): the first steps of 200 to 2,000 disks deposited in the 20 cm box
# of scenes/deposit_2k.toml (388 to 4,110 contacts), with μ from 0 to 0.5, solved by NLGS and by
# the interior point (its tries, then NLGS) to 1e-8. Usage:
#   bash benches/deposit_map.sh [OUT] [MAX_ITER]   (default out/deposit_map, 200,000; about
#   15 min on 2 cores)
set -euo pipefail
out=${1:-out/deposit_map}
max_iter=${2:-200000}
moreau=(cargo run --release --quiet --)
mkdir -p "$out/problems"
for disks in 200 500 1000 2000; do
    for mu in 0 0.05 0.1 0.2 0.3 0.5; do
        "${moreau[@]}" generate deposit --n "$disks" --mu "$mu" --seed 7 \
            --out "$out/problems/$(printf 'deposit_%04d_mu%s.dat' "$disks" "$mu")" >/dev/null
    done
done
"${moreau[@]}" sweep "$out/problems" --devices cpu --solvers nlgs,interior-point \
    --tols 1e-4,1e-6,1e-8 --profile-tol 1e-6,1e-8 --max-iter "$max_iter" --out "$out/sweep"
