#!/usr/bin/env bash
# The hardware-GPU measurements of BENCHMARKS.md in one run, on a machine with a GPU that need
# not have Rust: binaries built elsewhere are passed in. Needs the settled pile of the peer
# benchmark (target/peers/settled_pile_10k_300_*.json, from `cargo bench --bench peers`).
#   MOREAU=target/release/moreau PEERS=target/release/deps/peers-<hash> OUT=dir bash benches/device.sh
# BASELINE=another/moreau adds its GPU steps beside MOREAU's (a change measured side by side);
# LATTICES=0 leaves out `moreau bench`; SWEEPS=0 the sweep anatomy (`bench --scene`); PEERS_DEVICES=gpu leaves out the CPU rows of the peers;
# CROSSING=0 the piles of 400-4,000 disks on both devices (where `auto`'s GPU_MIN_BODIES should lie);
# MIXING=0 the Anderson-against-plain GPU runs; CPU_ROWS=0 the sandbox's CPU runs (a short lease).
# The pile at rest (target/peers/settled_pile_10k_3000_*.json, from MOREAU_PEERS_WARMUP=3000 cargo
# bench --bench peers, carried with the binaries) adds its GPU steps and peer table; AT_REST=0 leaves them out.
# Writes OUT/device.log (every table, with the device each one ran on) and OUT/runs.tgz (each
# run's steps.csv and summary.json, the peer table and chart).
set -u
OUT=${OUT:-target/device}
MOREAU=${MOREAU:-target/release/moreau}
PEERS=${PEERS:-}
BASELINE=${BASELINE:-}
THREADS=${THREADS:-$(nproc)}
mkdir -p "$OUT/runs" /tmp/xdg && chmod 700 /tmp/xdg
export XDG_RUNTIME_DIR=/tmp/xdg
log=$OUT/device.log
say() { echo "== $* ($(date +%T))" | tee -a "$log"; }
settled=$(ls target/peers/settled_pile_10k_300_*.json 2>/dev/null | head -1)
at_rest=$(ls target/peers/settled_pile_10k_3000_*.json 2>/dev/null | head -1)
[ "${AT_REST:-1}" != 0 ] || at_rest=""

say "machine: $(nproc) cores"
nvidia-smi --query-gpu=name,driver_version,memory.total,clocks.sm,clocks.max.sm --format=csv 2>&1 | tee -a "$log"
# wgpu finds the GPU through the Vulkan loader; some images keep the driver's manifest aside.
if ! "$MOREAU" bench --sizes 1000 --repeats 1 2>&1 | grep -q "^GPU: .*Vulkan" ; then
    icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
    [ -f $icd ] && export VK_DRIVER_FILES=$icd
fi

if [ "${LATTICES:-1}" != 0 ]; then
    say "W product, Jacobi iteration and NLGS sweep, lattices of 1k to 1M contacts"
    timeout 240 "$MOREAU" bench --sizes 1000,10000,100000,1000000 --repeats 200 2>&1 | tee -a "$log"
fi

if [ "${SWEEPS:-1}" != 0 ]; then
    # A GPU sweep alone (kernels only, and the largest colour's dispatch) beside the solve's sweep
    # with its checks, on the same step problem: where a GPU solve's time per sweep goes.
    for scene in pile_10k sandbox; do
        say "GPU sweep alone and in the solve: $scene"
        timeout 120 "$MOREAU" bench --scene scenes/$scene.toml --steps 2 --sweeps 500 --threads-list "$THREADS" 2>&1 | tee -a "$log"
    done
fi

# name binary: GPU steps of the sandbox, of the pile at rest and of the settled pile, one binary
# after the other.
gpu_steps() {
    say "$1: sandbox on the GPU, tol 1e-4 (the scene's NLGS)"
    timeout 90 "$2" run scenes/sandbox.toml --device gpu --steps 5 --vtk-every 0 --quiet \
        --out "$OUT/runs/$1_sandbox_gpu" 2>&1 | tee -a "$log"
    if [ -n "$at_rest" ]; then
        # The scene's setting: where the checks' cadence near tol decides the dispatches.
        say "$1: pile_10k at rest (3,000 steps) on the GPU, as the scene sets it"
        timeout 60 "$2" run scenes/pile_10k.toml --restart "$at_rest" --device gpu --steps 30 --quiet \
            --out "$OUT/runs/$1_rest_pile_gpu" 2>&1 | grep -v "^warning" | tee -a "$log"
    fi
    [ -n "$settled" ] || return
    # The scene's own settings (step-velocity, work list), and the same with block sweeps.
    for setting in "--tol 1e-2" "--tol 1e-4" "--tol 1e-4 --ordering worklist --criterion velocity --anderson 0" \
        "--max-iter 4 --tol 1e-300" "--block-sweeps 0" "--block-sweeps 4" "--block-sweeps 16"; do
        say "$1: pile_10k on the GPU from its settled state, $setting"
        timeout 60 "$2" run scenes/pile_10k.toml --restart "$settled" --device gpu --steps 30 $setting --quiet \
            --out "$OUT/runs/$1_pile_gpu_${setting//[^a-z0-9]/}" 2>&1 | grep -v "^warning" | tee -a "$log"
    done
}
[ -n "$BASELINE" ] && gpu_steps baseline "$BASELINE"
gpu_steps moreau "$MOREAU"
if [ -n "$settled" ] && [ "${MIXING:-1}" != 0 ]; then
    # Mixing against plain sweeps on the GPU, same binary: where Anderson cuts sweeps (the 400-disk
    # pile) and where its f32 mixing stalls (the settled pile run to convergence).
    for anderson in 0 5; do
        say "pile (400 disks), 100 GPU steps, anderson $anderson"
        timeout 60 "$MOREAU" run scenes/pile.toml --device gpu --steps 100 --anderson $anderson --vtk-every 0 --quiet \
            --out "$OUT/runs/pile400_a$anderson" 2>&1 | grep -v "^warning" | tee -a "$log"
        say "pile_10k settled, steps 301-302 to tol 1e-4 (cap 30000), anderson $anderson"
        timeout 60 "$MOREAU" run scenes/pile_10k.toml --restart "$settled" --device gpu --steps 2 --max-iter 30000 \
            --anderson $anderson --quiet --out "$OUT/runs/pile_to_1e4_a$anderson" 2>&1 | grep -v "^warning" | tee -a "$log"
    done
fi
if [ -z "$BASELINE" ]; then
    say "the sandbox's first step to 1e-4: 100,000 GPU sweeps; focused sweeps on $THREADS cores (20,000 sweeps' worth)"
    timeout 60 "$MOREAU" run scenes/sandbox.toml --device gpu --steps 1 --max-iter 100000 --vtk-every 0 --quiet \
        --out "$OUT/runs/sandbox_gpu_1e4" 2>&1 | tee -a "$log"
    say "the sandbox's first step to 1e-4: block sweeps, 16 a round (100,000 sweeps' worth)"
    timeout 60 "$MOREAU" run scenes/sandbox.toml --device gpu --steps 1 --block-sweeps 16 --max-iter 6250 --vtk-every 0 \
        --quiet --out "$OUT/runs/sandbox_gpu_blocks_1e4" 2>&1 | tee -a "$log"
    [ "${CPU_ROWS:-1}" != 0 ] && timeout 90 "$MOREAU" run scenes/sandbox.toml --device cpu --threads "$THREADS" --steps 1 \
        --max-iter 20000 --focus 19 --anderson 0 --vtk-every 0 --quiet --out "$OUT/runs/sandbox_cpu_focus_1e4" 2>&1 | tee -a "$log"
fi
if [ "${CROSSING:-1}" != 0 ]; then
    # scenes/pile.toml with more disks in a box grown with them: the first 100 steps on each device.
    mkdir -p "$OUT/scenes"
    for n in 400 1000 2000 4000; do
        s=$(awk "BEGIN { print sqrt($n / 400) }")
        awk -v n=$n -v s=$s '/^count =/ { $0 = "count = " n }
            /max = \[0.12, 0.3\]/ { sub(/\[0.12, 0.3\]/, "[" 0.12 * s ", " 0.3 * s "]") } { print }' \
            scenes/pile.toml > "$OUT/scenes/pile_$n.toml"
        for device in gpu cpu; do
            say "pile of $n disks, first 100 steps, $device"
            timeout 60 "$MOREAU" run "$OUT/scenes/pile_$n.toml" --steps 100 --device $device --threads "$THREADS" \
                --vtk-every 0 --quiet --out "$OUT/runs/crossing_${n}_$device" 2>&1 | grep -v "^warning" | tee -a "$log"
        done
    done
fi
say "sandbox on the GPU, PCPG tol 1e-4"
timeout 60 "$MOREAU" run scenes/sandbox.toml --device gpu --solver pcpg --steps 5 --vtk-every 0 --quiet \
    --out "$OUT/runs/sandbox_gpu_pcpg" 2>&1 | tee -a "$log"
if [ -z "$BASELINE" ] && [ "${CPU_ROWS:-1}" != 0 ]; then
    say "sandbox on the CPU, $THREADS threads, tol 1e-4"
    timeout 60 "$MOREAU" run scenes/sandbox.toml --device cpu --threads "$THREADS" --steps 2 --vtk-every 0 --quiet \
        --out "$OUT/runs/sandbox_cpu" 2>&1 | tee -a "$log"
fi

# peer_table WARMUP STATE NAME: the peer benchmark from a settled state (its settling steps, its
# file), its table into the log and its CSV and chart into runs/ as NAME.csv and NAME.png.
peer_table() {
    say "the peer pile after $1 steps: rapier2d, Box2D, moreau on ${PEERS_DEVICES:-gpu,cpu} ($THREADS threads)"
    cp -n "$2" "target/peers/settled_pile_10k_$1_$THREADS.json" 2>/dev/null
    MOREAU_PEERS_WARMUP=$1 MOREAU_PEERS_LEAD=${LEAD:-20} MOREAU_PEERS_STEPS=${STEPS:-10} \
        MOREAU_PEERS_THREADS=$THREADS MOREAU_PEERS_DEVICES=${PEERS_DEVICES:-gpu,cpu} timeout 200 "$PEERS" 2>&1 | tee -a "$log"
    cp target/peers/peers.csv "$OUT/runs/$3.csv" 2>/dev/null
    cp target/peers/peers.png "$OUT/runs/$3.png" 2>/dev/null
}
[ -n "$PEERS" ] && [ -n "$settled" ] && peer_table 300 "$settled" peers
if [ -n "$at_rest" ]; then
    # The piles of BENCHMARKS "The piles at rest beside rapier2d", on the GPU: the scene's
    # setting (step-velocity 1e-2, work list) and the two readings of tol 1e-4, with colour and
    # block sweeps.
    for setting in "" "--block-sweeps 4" "--block-sweeps 16" "--criterion velocity --tol 1e-4" \
        "--criterion velocity --tol 1e-4 --block-sweeps 16" "--criterion natural --tol 1e-4 --ordering forward"; do
        say "pile_10k at rest (3,000 steps) on the GPU, ${setting:-as the scene sets it}"
        timeout 60 "$MOREAU" run scenes/pile_10k.toml --restart "$at_rest" --device gpu --steps 30 $setting --quiet \
            --out "$OUT/runs/rest_pile_gpu_${setting//[^a-z0-9]/}" 2>&1 | grep -v "^warning" | tee -a "$log"
    done
    [ -n "$PEERS" ] && peer_table 3000 "$at_rest" peers_at_rest
fi
find "$OUT/runs" -name '*.vt?' -delete
tar czf "$OUT/runs.tgz" -C "$OUT" runs && rm -rf "$OUT/runs"
say done
