#!/usr/bin/env bash
# The frictional deposit as a family (BENCHMARKS.md, "The frictional deposit as a family"): the
# first steps of deposits of 100 to 450 disks in the same 20 cm box (6 to 25 grains deep), six
# seeds each, swept by the solvers that reach tight tolerances. Usage:
#   bash benches/deposits.sh [OUT] [MU]   (default out/deposits, μ 0.3; about 2 min on 2 cores)
set -euo pipefail
out=${1:-out/deposits}
mu=${2:-0.3}
moreau=(cargo run --release --quiet --)
mkdir -p "$out/problems"
for disks in 100 150 200 250 300 350 400 450; do
    for seed in 7 8 9 10 11 12; do
        "${moreau[@]}" generate deposit --n "$disks" --mu "$mu" --seed "$seed" \
            --out "$out/problems/$(printf 'deposit_%03d_s%02d.dat' "$disks" "$seed")" >/dev/null
    done
done
"${moreau[@]}" sweep "$out/problems" --devices cpu --solvers nlgs,pcpg,nlgs-newton,interior-point \
    --tols 1e-4,1e-6,1e-8 --profile-tol 1e-6,1e-8 --max-iter 20000 --out "$out/sweep"
