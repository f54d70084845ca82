#!/bin/bash
# Spin-up to failure of a 1 000-sphere aggregate, from scratch (README.md in this folder):
#   examples/spin-up/run.sh [RUBBLE] [RUNS_DIR]
# RUBBLE defaults to build/release/apps/rubble, RUNS_DIR to spin-up-runs. For mu = 0.2 and 0.6:
# accretes the aggregate to rest, then for each pull-off force (0, 100, 300 N) climbs a staircase
# of spins placed by the closed-form limit omega_H of that case: omega_k = 0.7 x 1.3^k omega_H.
# Every stage branches from the previous one (--from), adds the rigid spin increment
# omega_k - omega_{k-1} about the settled aggregate's axis of largest moment of inertia, through
# its centre of mass ([[initial_conditions]]; spin_up.py axis), and relaxes for
# 1 700 s (the first stage, the largest increment) or 850 s (the next ones); spin_up.py check
# measures it. The climb stops at the first failed stage (when the first stage fails, one stage
# from the settled aggregate at 0.7 / 1.3 of its spin brackets the failure from below). Last, a
# control per mu: the settled aggregate with no spin, measured the same way.
# Each run's CPU time (user, system, wall: /usr/bin/time) is written to RUN.log.time.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
rubble=$(realpath "${1:-$here/../../build/release/apps/rubble}")
runs=${2:-spin-up-runs}
python=/usr/bin/python3
first_relax=1700 # s: one dynamical time 1/sqrt(G rho) of the grains' density, after the first increment
relax=850        # s: half of it (about the free-fall time 920 s) after each later, smaller one
# MU06_FROM=branch (default): the mu = 0.6 aggregate is the settled mu = 0.2 one with its friction
# raised to 0.6 and relaxed for 1 700 s (README.md, "Method"); MU06_FROM=accretion accretes it at
# mu = 0.6 from the cloud (accretion-mu0.6.toml), which does not come to rest within hours of CPU.
mu06_from=${MU06_FROM:-branch}
# REFINE=1 (default): one more stage per case at the geometric mean of the bracket found.
refine=${REFINE:-1}
mkdir -p "$runs"

timed() { # timed LOG COMMAND...: run with one thread, CPU times into LOG.time
  local log=$1
  shift
  OMP_NUM_THREADS=1 /usr/bin/time -f "%U %S %e" -o "$log.time" "$@" > "$log" 2>&1
}
calc() { awk "BEGIN { printf \"%.6g\", $1 }"; }

# stage_scene NAME SPIN_BEFORE SPIN FILE: the stage scene NAME.toml with the increment SPIN - SPIN_BEFORE
# about $axis, written to FILE.
stage_scene() {
  local dw
  dw=$(calc "$3 - $2")
  sed "s/^angular_velocity = \[0.0, 0.0, 1e-4\]/angular_velocity = [$(awk -v dw="$dw" -F', ' '{ printf "%.9g, %.9g, %.9g", dw * $1, dw * $2, dw * $3 }' <<< "$axis")]/" \
    "$here/$1.toml" > "$4"
  grep -q "^angular_velocity = \[0.0, 0.0, 1e-4\]" "$4" && { echo "stage_scene: no increment written into $4" >&2; exit 1; }
  return 0
}

# stage NAME FROM SPIN_BEFORE SPIN OUT RELAX: one branched stage, measured; returns the check's status.
stage() {
  local name=$1 from=$2 before=$3 spin=$4 out=$5 relax=$6 end
  if [ ! -f "$out/stage.json" ]; then
    stage_scene "$name" "$before" "$spin" "$out.toml"
    end=$(calc "$("$python" "$here/spin_up.py" end-time "$from") + $relax")
    rm -rf "$out"
    timed "$out.log" "$rubble" run "$out.toml" --from "$from" --end-time "$end" --out "$out" -q ||
      { echo "$out: rubble run failed (see $out.log)" >&2; exit 1; }
  fi
  local status=0
  "$python" "$here/spin_up.py" check "$out" "$acc" --spin "$spin" || status=$?
  [ $status -eq 0 ] || [ $status -eq 10 ] || { echo "$out: the check failed ($status)" >&2; exit 1; }
  return $status
}

for mu in 0.2 0.6; do
  acc=$runs/accretion-mu$mu
  if [ ! -f "$acc/run.h5" ] && [ "$mu" = 0.6 ] && [ "$mu06_from" = branch ]; then
    echo "aggregate mu = 0.6: the settled mu = 0.2 aggregate with its friction raised, $first_relax s"
    axis=$("$python" "$here/spin_up.py" axis "$runs/accretion-mu0.2")
    stage_scene spin-mu0.6-c0 0 1e-12 "$acc.toml"
    end=$(calc "$("$python" "$here/spin_up.py" end-time "$runs/accretion-mu0.2") + $first_relax")
    timed "$acc.log" "$rubble" run "$acc.toml" --from "$runs/accretion-mu0.2" --end-time "$end" --out "$acc" -q
  elif [ ! -f "$acc/run.h5" ]; then
    echo "accretion mu = $mu"
    timed "$acc.log" "$rubble" run "$here/accretion-mu$mu.toml" --out "$acc" -q
  fi
  axis=$("$python" "$here/spin_up.py" axis "$acc")
  for c in 0 100 300; do
    name=spin-mu$mu-c$c
    limit=$("$python" "$here/spin_up.py" predict "$acc" $mu $c)
    echo "$name: closed-form limit $limit rad/s"
    prev=$acc
    spin=0
    held=0
    failed=0
    for k in 0 1 2 3 4 5; do
      next=$(calc "0.7 * 1.3^$k * $limit")
      [ $k -eq 0 ] && wait_s=$first_relax || wait_s=$relax
      if stage $name "$prev" "$spin" "$next" "$runs/$name-$k" "$wait_s"; then
        prev=$runs/$name-$k
        spin=$next
        held=$next
      else
        spin=$next
        failed=1
        break
      fi
    done
    if [ "$prev" = "$acc" ]; then
      stage $name "$acc" 0 "$(calc "$spin / 1.3")" "$runs/$name-r" $first_relax || true
    elif [ "$refine" = 1 ] && [ $failed = 1 ]; then
      # One more stage from the last that held, at the geometric mean of the bracket: the bracket's
      # factor 1.3 becomes 1.14 (either half, whichever way this stage goes).
      stage $name "$prev" "$held" "$(calc "sqrt($held * $spin)")" "$runs/$name-f" $relax || true
    fi
  done
done
# Control: the settled aggregate branched with no spin (an increment of 1e-12 rad/s) for 1 700 s,
# measured like a stage: the creep that the failure criterion sees without any spin.
for mu in 0.6 0.2; do
  acc=$runs/accretion-mu$mu
  axis=$("$python" "$here/spin_up.py" axis "$acc")
  stage spin-mu$mu-c0 "$acc" 0 1e-12 "$runs/control-mu$mu" $first_relax || true
done
"$python" "$here/spin_up.py" analyse "$runs" --png "$runs/spin-up.png" --markdown "$runs/results.md"
