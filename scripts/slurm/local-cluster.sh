#!/usr/bin/env bash
# A one-node Slurm cluster on this machine, from Debian's packages (slurmctld, slurmd, slurm-client, munge), for
# trying scripts/slurm/submit.sh and for the test run. No systemd: the daemons run as root from a state folder.
#
#   scripts/slurm/local-cluster.sh up       install what is missing, write the configuration, start munged,
#                                           slurmctld and slurmd, wait until the node is idle
#   scripts/slurm/local-cluster.sh down     stop the daemons and remove the state folder
#   scripts/slurm/local-cluster.sh status   sinfo / squeue
#   scripts/slurm/local-cluster.sh env      the line to eval so sbatch, squeue, ... talk to this cluster
#
# State folder: $EGOPD_SLURM_DIR (default: $TMPDIR/egopd-slurm, else /tmp/egopd-slurm). The cluster's slurm.conf is
# in it; the Slurm commands find it through SLURM_CONF (`eval "$(scripts/slurm/local-cluster.sh env)"`), so a
# machine's own /etc/slurm is never touched. Ports: $EGOPD_SLURM_PORT (slurmctld, default 6817) and the next one
# (slurmd). Needs root (as CI runs); the node offers every CPU and 90% of the memory of this machine.
set -euo pipefail

state=${EGOPD_SLURM_DIR:-${TMPDIR:-/tmp}/egopd-slurm}
port=${EGOPD_SLURM_PORT:-6817}
conf=$state/slurm.conf

need_root() {
  [ "$(id -u)" -eq 0 ] || { echo "local-cluster.sh: must run as root (the daemons run as root)" >&2; exit 1; }
}

install_packages() {
  "$(dirname "$0")/../install-packages.sh" slurmctld slurmd slurm-client munge
}

write_config() {
  local node cpus mem
  node=$(hostname -s)
  cpus=$(nproc)
  mem=$(awk '/MemTotal/ { printf "%d", $2 / 1024 * 0.9 }' /proc/meminfo)
  mkdir -p "$state/ctld" "$state/spool" "$state/munge"
  chmod 700 "$state/munge"
  cat >"$conf" <<EOF
ClusterName=egopd-local
SlurmctldHost=$node(127.0.0.1)
SlurmctldPort=$port
SlurmdPort=$((port + 1))
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$state/munge/munge.socket
StateSaveLocation=$state/ctld
SlurmdSpoolDir=$state/spool
SlurmctldPidFile=$state/slurmctld.pid
SlurmdPidFile=$state/slurmd.pid
SlurmctldLogFile=$state/slurmctld.log
SlurmdLogFile=$state/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
MpiDefault=none
ReturnToService=2
KillWait=10
SchedulerParameters=sched_interval=1
NodeName=$node NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=local Nodes=ALL Default=YES MaxTime=INFINITE State=UP
EOF
}

start_munge() {
  # A key of this cluster's own, readable by root only.
  [ -f "$state/munge/munge.key" ] || dd if=/dev/urandom of="$state/munge/munge.key" bs=1024 count=1 status=none
  chmod 400 "$state/munge/munge.key"
  munged --force --key-file="$state/munge/munge.key" --socket="$state/munge/munge.socket" \
    --pid-file="$state/munge/munged.pid" --log-file="$state/munge/munged.log" --seed-file="$state/munge/seed"
}

wait_for() {  # wait_for SECONDS DESCRIPTION COMMAND...
  local limit=$1 what=$2
  shift 2
  for _ in $(seq 1 $((limit * 4))); do
    "$@" >/dev/null 2>&1 && return 0
    sleep 0.25
  done
  echo "local-cluster.sh: $what did not happen within $limit s; logs in $state" >&2
  tail -5 "$state"/*.log >&2 || true
  return 1
}

node_idle() { [ "$(sinfo -h -N -o '%t' 2>/dev/null | head -1)" = "idle" ]; }

up() {
  need_root
  install_packages
  if [ -f "$state/slurmctld.pid" ] && kill -0 "$(cat "$state/slurmctld.pid")" 2>/dev/null; then
    echo "local cluster already up (state in $state)"
    return 0
  fi
  write_config
  export SLURM_CONF=$conf
  start_munge
  slurmctld -c -f "$conf"  # -c: a fresh cluster, no state from an earlier run
  wait_for 30 "slurmctld start" scontrol ping
  slurmd -f "$conf"
  wait_for 60 "the node becoming idle" node_idle
  echo "local cluster up: node $(hostname -s), $(nproc) CPUs, state in $state"
  echo "use it with: eval \"\$($0 env)\""
}

down() {
  for pid_file in "$state/slurmd.pid" "$state/slurmctld.pid" "$state/munge/munged.pid"; do
    [ -f "$pid_file" ] || continue
    pid=$(cat "$pid_file")
    kill "$pid" 2>/dev/null || true
    for _ in $(seq 1 40); do kill -0 "$pid" 2>/dev/null || break; sleep 0.25; done
    kill -9 "$pid" 2>/dev/null || true
  done
  rm -rf "$state"
  echo "local cluster down"
}

case "${1:-}" in
  up) up ;;
  down) down ;;
  status) SLURM_CONF=$conf sinfo; SLURM_CONF=$conf squeue ;;
  env) echo "export SLURM_CONF=$conf" ;;
  *) echo "usage: $0 up|down|status|env" >&2; exit 2 ;;
esac
