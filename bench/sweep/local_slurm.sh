#!/usr/bin/env bash
# A real single-node Slurm on 127.0.0.1 for the sweep benchmarks, started the
# way tests/sweep/slurm_cluster.hpp starts one for the tests: munged with a
# generated key and its own socket, slurmctld and slurmd with a generated
# slurm.conf (free ports, state and spool in DIR, proctrack/pgid, task/none,
# no accounting), as root, without systemd or cgroups.
#
#   bench/sweep/local_slurm.sh start DIR   # prints the SLURM_CONF to export
#   bench/sweep/local_slurm.sh stop DIR    # cancels its jobs, stops each daemon by its PID
#
# DIR must be new or a folder this script made (and stopped); its parents must be
# traversable by everyone (munged checks its socket's folders).
set -euo pipefail

cmd=${1:-}; dir=${2:-}
[[ ($cmd == start || $cmd == stop) && -n $dir ]] || { echo "usage: $0 start|stop DIR" >&2; exit 2; }
dir=$(realpath -m "$dir")
conf=$dir/slurm.conf

# Stops the process in PIDFILE: SIGTERM, SIGKILL after 10 s; waits until it is gone.
stop_pid() {
  local file=$1 pid
  [[ -s $file ]] || return 0
  pid=$(<"$file")
  [[ $pid =~ ^[0-9]+$ && $pid -gt 1 ]] || return 0
  kill -TERM "$pid" 2>/dev/null || return 0
  for i in $(seq 1 200); do
    kill -0 "$pid" 2>/dev/null || return 0
    [[ $i == 100 ]] && kill -KILL "$pid" 2>/dev/null
    sleep 0.1
  done
  echo "$0: process $pid ($file) did not stop" >&2
}

if [[ $cmd == stop ]]; then
  if [[ -f $conf ]]; then
    SLURM_CONF=$conf scancel --full --quiet --user="$(id -un)" 2>/dev/null || true
    for i in $(seq 1 100); do
      [[ -z $(SLURM_CONF=$conf squeue -h 2>/dev/null) ]] && break
      sleep 0.2
    done
  fi
  stop_pid "$dir/slurmd.pid"
  stop_pid "$dir/slurmctld.pid"
  stop_pid "$dir/munge/munged.pid"
  echo "stopped the Slurm of $dir"
  exit 0
fi

[[ $(id -u) == 0 ]] || { echo "$0: runs as root (SlurmUser=root, like the tests)" >&2; exit 2; }
for p in mungekey munged slurmctld slurmd sbatch; do
  command -v "$p" >/dev/null || { echo "$0: $p not found (deploy/install-deps.sh installs slurm-wlm and munge)" >&2; exit 2; }
done
if [[ -e $conf ]]; then
  # A Slurm of this script, stopped: start afresh. Running: refuse.
  for f in "$dir/slurmd.pid" "$dir/slurmctld.pid" "$dir/munge/munged.pid"; do
    if [[ -s $f ]] && kill -0 "$(<"$f")" 2>/dev/null; then
      echo "$0: $dir holds a running Slurm ($f); stop it first" >&2; exit 2
    fi
  done
  rm -rf "${dir:?}"/{munge,sock,state,spool,log} "$conf" "$dir"/*.pid
fi
trap 'echo "$0: start failed; stopping what started" >&2; "$0" stop "$dir" >&2' ERR
mkdir -p "$dir"/{munge,sock,state,spool,log}
chmod 755 "$dir" "$dir/sock"
chmod 700 "$dir/munge"
socket=$dir/sock/munge.sock
mungekey -c -k "$dir/munge/munge.key"
munged --socket="$socket" --key-file="$dir/munge/munge.key" --pid-file="$dir/munge/munged.pid" \
  --log-file="$dir/log/munged.log" --seed-file="$dir/munge/munged.seed"

# Two free TCP ports on 127.0.0.1.
read -r ctld_port d_port < <(python3 -c '
import socket
s = [socket.socket() for _ in range(2)]
for x in s: x.bind(("127.0.0.1", 0))
print(*[x.getsockname()[1] for x in s])')
host=$(hostname)
mem_mb=$(awk '/MemTotal/ { m = int($2 / 1024) - 1024; print (m < 512 ? 512 : m) }' /proc/meminfo)
cpus=${LOCAL_SLURM_CPUS:-$(nproc)}
cat >"$conf" <<CONF
ClusterName=locaidbench
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$d_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$socket
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
ProctrackType=proctrack/pgid
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MpiDefault=none
SwitchType=switch/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
KillWait=5
NodeName=$host NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$mem_mb State=UNKNOWN
PartitionName=debug Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF=$conf
slurmctld -c -f "$conf"
slurmd -f "$conf"
for i in $(seq 1 150); do
  if sinfo -h -o %T 2>/dev/null | grep -q idle; then
    echo "Slurm up (node $host, $cpus CPUs); use it with:"
    echo "export SLURM_CONF=$conf"
    exit 0
  fi
  sleep 0.2
done
echo "$0: the node never became idle:" >&2
sinfo >&2 || true
tail -5 "$dir/log/slurmd.log" >&2 || true
"$0" stop "$dir" >&2
exit 1
