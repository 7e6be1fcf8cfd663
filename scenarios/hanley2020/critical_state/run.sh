#!/usr/bin/env bash
# The critical-state runs of Hanley 2020 §6 (README.md in this folder): the dense and the
# loose sample of configs/critical_state/, each sheared four ways, with the wall time of each
# run appended to OUT/wall_times.txt. Then: python figures.py OUT.
#
#   scenarios/hanley2020/critical_state/run.sh [OUT] [SAMPLES]   (from the repository root)
#
# friction    mu = 0.5, no damping (the configs as written)
# elastic     mu = 0, no damping: energy-conserving; reversed, compare.json beside it
# viscous     mu = 0, viscous normal damping 0.3 of critical: dissipation, no shear force
# tangential  mu = 0, viscous tangential damping 0.3 of critical: shear forces, no friction
# seed23      mu = 0.5 as friction, from another random packing (packings.0.seed = 23)
# long        mu = 0.5 as friction, to 40 % axial strain at 0.1 1/s (I <= 1e-3 still)
# tape        mu = 0.5 as friction, with an information tape, reversed (0.8 GB a tape)
set -euo pipefail
out=${1:-out/critical_state}
samples=${2:-dense loose}
export NUMBA_NUM_THREADS=${NUMBA_NUM_THREADS:-1}
revdem=${REVDEM:-.venv/bin/revdem}
mkdir -p "$out"
for sample in $samples; do
    run() {
        local case=$1
        shift
        local start
        start=$(date +%s)
        "$revdem" run "configs/critical_state/$sample.toml" --out "$out/$case" --force -q "$@"
        echo "$case $sample $(($(date +%s) - start)) s" >>"$out/wall_times.txt"
    }
    run friction --no-reverse
    run elastic --set stages.2.contact.friction=0
    run viscous --no-reverse --set stages.2.contact.friction=0 \
        --set stages.2.contact.normal_damping=0.3
    run tangential --no-reverse --set stages.2.contact.friction=0 \
        --set stages.2.contact.tangential_damping=0.3
    run seed23 --no-reverse --set packings.0.seed=23
    run long --no-reverse --set stages.2.steps=200000 --set stages.2.cell.z.strain_rate=-0.1
    run tape --set reversal.tape=true
done
