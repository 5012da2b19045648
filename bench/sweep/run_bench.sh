#!/usr/bin/env bash
# The sweep benchmarks of docs/sweeps.md ("Measured"): 40 filter runs of the
# real KITTI excerpt from its VO cache (bench/sweep/excerpt-40.yaml).
#
#   bench/sweep/run_bench.sh local BIN WORK [REPS]   # --jobs 1 vs --jobs 2, and `report` alone
#   bench/sweep/run_bench.sh slurm BIN WORK [REPS]   # Slurm (--runs-per-task 1 and auto) vs local --jobs 2
#                                                    # (SWEEP_BENCH_KS="1 20 auto": other values)
#
# BIN: the folder of locaid-sweep (build/bin); WORK: a scratch folder (the
# sweep goes to WORK/sweep, the benchmark Slurm to WORK/slurm, started and
# stopped by bench/sweep/local_slurm.sh). Each timed `run` starts from the
# same state: the VO run done and its cache kept, the 40 filter results
# deleted. Prints one line per timed command (wall time; the CPU time of
# locaid-sweep and its children; the CPU time the rest of the machine used
# meanwhile, which for Slurm includes the daemons and the array tasks) and
# the medians.
set -euo pipefail

mode=${1:-}; bin=${2:-}; work=${3:-}; reps=${4:-3}
[[ ($mode == local || $mode == slurm) && -x $bin/locaid-sweep && -n $work ]] ||
  { echo "usage: $0 local|slurm BIN WORK [REPS]" >&2; exit 2; }
here=$(cd "$(dirname "$0")" && pwd)
manifest=$here/excerpt-40.yaml
work=$(realpath -m "$work")
out=$work/sweep
sweep=$bin/locaid-sweep
mkdir -p "$work"

now() { date +%s.%N; }
# Deletes the filter runs' results (and the report), keeps the VO run and its cache.
reset_filter() { find "$out/runs" -name '*.json' ! -name 'vo.*' -delete; rm -f "$out"/results.csv "$out"/summary.*; }
median() { python3 -c 'import statistics, sys; print("%.2f" % statistics.median(float(x) for x in sys.argv[1:]))' "$@"; }
# Busy CPU seconds of the whole machine so far (/proc/stat: all but idle and iowait).
busy() { awk -v hz="$(getconf CLK_TCK)" '/^cpu / { print ($2 + $3 + $4 + $7 + $8 + $9) / hz }' /proc/stat; }
# time_cmd LABEL CMD...: runs CMD (output to WORK/last.log), prints and returns (in $t) its wall seconds,
# with the CPU seconds it used and those the rest of the machine used meanwhile ("others": the idleness check).
time_cmd() {
  local label=$1; shift
  local t0 t1 b0 b1 cpu
  b0=$(busy); t0=$(now)
  python3 - "$work/last.log" "$work/last.cpu" "$@" <<'PY' || { echo "$label failed:" >&2; tail -20 "$work/last.log" >&2; exit 1; }
import resource, subprocess, sys
with open(sys.argv[1], "w") as log:
    rc = subprocess.call(sys.argv[3:], stdout=log, stderr=subprocess.STDOUT)
r = resource.getrusage(resource.RUSAGE_CHILDREN)
open(sys.argv[2], "w").write("%.2f" % (r.ru_utime + r.ru_stime))
sys.exit(rc)
PY
  t1=$(now); b1=$(busy)
  cpu=$(<"$work/last.cpu")
  t=$(python3 -c "print('%.2f' % ($t1 - $t0))")
  printf '%-36s %6s s wall  %6s s CPU  others %5s CPU-s  (load %s)\n' "$label" "$t" "$cpu" \
    "$(python3 -c "print('%.2f' % max(0, $b1 - $b0 - $cpu))")" "$(cut -d' ' -f1-3 /proc/loadavg)"
}

if ! compgen -G "$out/vo/*.cache" >/dev/null; then
  echo "# setup: plan (measures one VO and one filter run, keeps them in $out/costs.json), then the VO run"
  "$sweep" plan "$manifest" --out "$out"
  "$sweep" run "$manifest" --out "$out" --jobs 2 >/dev/null 2>&1 || true
fi
compgen -G "$out/vo/*.cache" >/dev/null || { echo "no VO cache in $out/vo" >&2; exit 1; }

if [[ $mode == local ]]; then
  declare -A runs reports
  for rep in $(seq 1 "$reps"); do
    for jobs in 1 2; do
      reset_filter
      time_cmd "run --jobs $jobs (rep $rep)" "$sweep" run "$manifest" --out "$out" --jobs "$jobs"
      runs[$jobs]+=" $t"
      time_cmd "report (rep $rep)" "$sweep" report "$out"
      reports[$jobs]+=" $t"
    done
  done
  r1=$(median ${runs[1]}); r2=$(median ${runs[2]}); rep1=$(median ${reports[1]}); rep2=$(median ${reports[2]})
  echo "median run --jobs 1: $r1 s, --jobs 2: $r2 s: speed-up $(python3 -c "print('%.2f' % ($r1 / $r2))")x"
  echo "median report alone: $rep1 s / $rep2 s; without it: $(python3 -c "print('%.2f s / %.2f s: speed-up %.2fx' % ($r1 - $rep1, $r2 - $rep2, ($r1 - $rep1) / ($r2 - $rep2)))")"
  exit 0
fi

# slurm
slurm=$work/slurm
"$here/local_slurm.sh" start "$slurm" >/dev/null
trap '"$here/local_slurm.sh" stop "$slurm" >/dev/null' EXIT
export SLURM_CONF=$slurm/slurm.conf
ks=${SWEEP_BENCH_KS:-1 auto}  # the --runs-per-task values to time
declare -A times
for rep in $(seq 1 "$reps"); do
  reset_filter
  time_cmd "local --jobs 2 (rep $rep)" "$sweep" run "$manifest" --out "$out" --jobs 2
  times[local]+=" $t"
  for k in $ks; do
    reset_filter
    time_cmd "slurm --runs-per-task $k (rep $rep)" \
      "$sweep" run "$manifest" --out "$out" --engine slurm --runs-per-task "$k" --wait --poll-s 0.5
    times[$k]+=" $t"
    grep -h "filter stage" "$work/last.log" | sed 's/^/    /'
  done
done
l=$(median ${times[local]})
echo "median local --jobs 2: $l s"
for k in $ks; do
  m=$(median ${times[$k]})
  python3 -c "print('median slurm --runs-per-task %s: %s s: added per run %.3f s' % ('$k', $m, ($m - $l) / 40))"
done
