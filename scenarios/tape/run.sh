#!/bin/bash
# The runs behind scenarios/tape/README.md: each case in fixed-point arithmetic without and
# with the information tape ([reversal] tape = true), and the verdicts, tape sizes and bits
# destroyed, one line each, into OUT/summary.txt.
#   scenarios/tape/run.sh OUT [CASE ...]   (from the project root; every case: about an hour
#                                          on one core; CASE: the names below, to run those)
set -u
OUT=${1:?usage: scenarios/tape/run.sh OUT [CASE ...]}
shift
ONLY=" $* "
REVDEM=${REVDEM:-.venv/bin/revdem}
PYTHON=${PYTHON:-.venv/bin/python}
mkdir -p "$OUT"
FCC=(--set contact.tangential=linear --set contact.ks=1e11 --set contact.friction=0.25
     --set stages.1.steps=100000)
case_() {  # which name config [--set ...]: which = both (without the tape, then with it) or taped
  which=$1; name=$2; config=$3; shift 3
  [ "$ONLY" != "  " ] && [[ "$ONLY" != *" $name "* ]] && return
  for tape in false true; do
    [ "$which" = taped ] && [ "$tape" = false ] && continue
    folder=$OUT/$name.tape_$tape
    figures='[]'
    [ "$tape" = true ] && figures='["information"]'
    start=$(date +%s.%N)
    "$REVDEM" run "$config" --out "$folder" --force --set integrator.arithmetic=fixed \
      --set reversal.tape=$tape --set "output.figures=$figures" "$@" > "$folder.log" 2>&1
    status=$?
    seconds=$(echo "$(date +%s.%N) - $start" | bc)
    "$PYTHON" - "$name" "$tape" "$status" "$seconds" "$folder" >> "$OUT/summary.txt" <<'PY'
import glob, json, sys
name, tape, status, seconds, folder = sys.argv[1:]
line = {"case": name, "tape": tape == "true", "exit": int(status), "seconds": float(seconds)}
for path in glob.glob(f"{folder}/*.compare.json"):
    verdict = json.load(open(path))
    line |= {key: verdict[key] for key in ("bitwise_identical", "first_divergence_step")}
    line["information_tape"] = verdict.get("information_tape")
print(json.dumps(line))
PY
  done
}
case_ both collision_shear_inf configs/collision_shear.toml
case_ both collision_shear_0.3 configs/collision_shear.toml --set contact.friction=0.3
case_ both rolling_resistance configs/rolling_resistance.toml
case_ both oedometer_pour configs/tape/oedometer_pour.toml
case_ taped oedometer_all_stages configs/smoke/oedometer.toml --set reversal.all_stages=true
case_ both fcc_mu0.25 configs/fcc_triaxial.toml "${FCC[@]}"
case_ both fcc_mu0.25_proportional configs/fcc_triaxial.toml "${FCC[@]}" --set cell.servo=proportional
case_ both drop_A configs/drop_A.toml
case_ both drop_B configs/drop_B.toml
case_ both drop_C configs/drop_C.toml
