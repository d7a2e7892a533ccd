#!/usr/bin/env bash
# Times two moreau binaries on the same steps: for a change that does not give the same bits, two
# runs of a scene follow different trajectories, and the trajectory alone moves their cost by tens
# of per cent (BENCHMARKS.md, "When the work list gives way to full sweeps"). Here both binaries
# take one step from each checkpoint of one run: the same warm start, the same problem.
#
# Usage: bash benches/paired_steps.sh BINARY_A BINARY_B SCENE CHECKPOINT_DIR [THREADS] [STEPS]
#   CHECKPOINT_DIR: the checkpoints of a run of SCENE (`[output] checkpoint_every = k`).
#   STEPS (default 1): steps taken from each checkpoint. More than one lets a change's effect on
#   the following steps' starts count too (a solve that stops nearer tol leaves more to the next).
# Prints the solve seconds and sweeps' worth of each checkpoint's steps for both, then the totals.
set -euo pipefail
[ $# -ge 4 ] || { sed -n 2,11p "$0"; exit 2; }
a=$1 b=$2 scene=$3 dir=$4 threads=${5:-2} steps=${6:-1}
scratch=$(mktemp -d)
trap 'rm -rf "$scratch"' EXIT
one_step() { # binary, checkpoint -> "solve_seconds iterations converged" of the step taken
    if ! "$1" run "$scene" --restart "$2" --steps "$steps" --threads "$threads" --device cpu --quiet \
        --out "$scratch/out" >/dev/null 2>"$scratch/log"; then
        echo "$1 failed on $2:" >&2
        cat "$scratch/log" >&2
        return 1
    fi
    awk -F, 'NR == 1 { for (k = 1; k <= NF; k++) col[$k] = k; all = "true" }
             NR > 1 { s += $col["solve_seconds"]; i += $col["iterations"]; if ($col["converged"] != "true") all = "false" }
             END { print s, i, all }' "$scratch/out/steps.csv"
}
printf '%-28s %12s %8s %12s %8s\n' checkpoint "A solve s" "A its" "B solve s" "B its"
for checkpoint in "$dir"/checkpoint_*.json; do
    [ -e "$checkpoint" ] || continue
    A=$(one_step "$a" "$checkpoint") || exit 2
    B=$(one_step "$b" "$checkpoint") || exit 2
    read -r sa ia ca <<<"$A"
    read -r sb ib cb <<<"$B"
    printf '%-28s %12.4f %8d %12.4f %8d %s\n' "$(basename "$checkpoint")" "$sa" "$ia" "$sb" "$ib" \
        "$([ "$ca" = true ] && [ "$cb" = true ] || echo "(a step missed tol: A $ca, B $cb)")"
done | tee "$scratch/rows"
[ -s "$scratch/rows" ] || { echo "no checkpoint_*.json in $dir" >&2; exit 2; }
awk '{ sa += $2; ia += $3; sb += $4; ib += $5; n++; if ($4 < $2) faster++ }
     END { printf "total over %d checkpoint(s), '"$steps"' step(s) from each: A %.3f s (%d sweeps'"'"' worth), B %.3f s (%d); B faster on %d\n", n, sa, ia, sb, ib, faster }' \
    "$scratch/rows"
