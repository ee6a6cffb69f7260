#!/usr/bin/env bash
# Sharded dataset generation on a real Slurm cluster, end to end: starts a one-node cluster from
# Debian's packages (munge, slurmctld, slurmd) on this machine, submits docs/slurm/dataset.sbatch
# (the recipe docs/clusters.md gives users) as an array job, requeues one task while it is
# making frames, merges the shards and checks the result is byte-identical to a one-machine run.
#
#   bash tools/slurm/test.sh [GLASSBAKE_BINARY]    # default: target/debug/glassbake
#
# Needs root (it starts the daemons and, where missing, installs the packages with apt-get) on
# a machine or container you can throw away: it writes /etc/munge/munge.key when none exists.
# Everything else lives in a temp folder; the daemons are stopped at the end.
set -euo pipefail
cd "$(dirname "$0")/../.."
repo="$(pwd)"
glassbake="$(cd "$(dirname "${1:-target/debug/glassbake}")" && pwd)/$(basename "${1:-target/debug/glassbake}")"
[ -x "$glassbake" ] || { echo "no glassbake binary at $glassbake (build it first)" >&2; exit 1; }
[ "$(id -u)" -eq 0 ] || { echo "tools/slurm/test.sh starts Slurm's daemons: run it as root" >&2; exit 1; }

packages=(munge slurmctld slurmd slurm-client)
missing=()
for p in "${packages[@]}"; do dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p"); done
if [ "${#missing[@]}" -gt 0 ]; then
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

work="$(mktemp -d "${TMPDIR:-/tmp}/glassbake-slurm.XXXXXX")"
chmod 0755 "$work"  # munged runs as the munge user and must reach its folder
node="$(hostname -s)"
export SLURM_CONF="$work/slurm.conf"
stop() { # the daemons down; the folder removed after a pass, kept (and named) after a failure
  local status=$?
  for pid_file in "$work/slurmd.pid" "$work/slurmctld.pid" "$work/munged.pid"; do
    [ -f "$pid_file" ] && kill "$(cat "$pid_file")" 2>/dev/null
  done
  sleep 1
  if [ "$status" -eq 0 ]; then rm -rf "$work"; else echo "tools/slurm/test.sh failed; logs in $work" >&2; fi
}
trap stop EXIT

# Munge authenticates the daemons to each other; a key of its own where the machine has none.
mkdir -p /etc/munge "$work/munge"
if [ ! -f /etc/munge/munge.key ]; then
  dd if=/dev/urandom of=/etc/munge/munge.key bs=1024 count=1 2>/dev/null
fi
chown munge:munge /etc/munge /etc/munge/munge.key "$work/munge"
chmod 400 /etc/munge/munge.key
socket="$work/munge/munge.socket"
su -s /bin/sh munge -c "munged --socket=$socket --pid-file=$work/munge/munged.pid --log-file=$work/munge/munged.log --seed-file=$work/munge/seed"
cp "$work/munge/munged.pid" "$work/munged.pid"

# One node, every core; no cgroups (containers often have none to give).
cat > "$SLURM_CONF" <<CONF
ClusterName=glassbake-test
SlurmctldHost=$node(127.0.0.1)
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$socket
StateSaveLocation=$work/state
SlurmdSpoolDir=$work/spool
SlurmctldPidFile=$work/slurmctld.pid
SlurmdPidFile=$work/slurmd.pid
SlurmctldLogFile=$work/slurmctld.log
SlurmdLogFile=$work/slurmd.log
SlurmctldPort=16817
SlurmdPort=16818
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
MpiDefault=none
NodeName=$node NodeAddr=127.0.0.1 CPUs=$(nproc) State=UNKNOWN
PartitionName=test Nodes=$node Default=YES MaxTime=INFINITE State=UP
CONF
mkdir -p "$work/state" "$work/spool"
slurmctld -f "$SLURM_CONF"
slurmd -f "$SLURM_CONF"
for _ in $(seq 60); do sinfo -h -o %t 2>/dev/null | grep -q idle && break; sleep 1; done
sinfo -h -o %t | grep -q idle || { echo "the Slurm node did not come up:" >&2; tail -n 20 "$work"/slurm*.log >&2; exit 1; }
echo "slurm ($SECONDS s): one node ($node, $(nproc) CPUs) up"

# The recipe, as a user submits it, sized down: 4 shards, one CPU each.
args=(--train 24 --val 4 --test 4 --res 24 --spp 96 --test-spp 96 --seed 3 --threads 1)
cd "$work"
job=$(PATH="$(dirname "$glassbake"):$PATH" sbatch --parsable --array=0-3 --cpus-per-task=1 \
  "$repo/docs/slurm/dataset.sbatch" cornell-glass "$work/shards" "${args[@]}")
echo "slurm ($SECONDS s): array job $job submitted"

# Requeue task 1 once it has made some, but not all, of its 8 frames.
frames() {
  if [ -d "$work/shards/1/gt" ]; then find "$work/shards/1/gt" -name '*.exr' | wc -l; else echo 0; fi
}
for _ in $(seq 2400); do
  n=$(frames)
  [ "$n" -ge 2 ] && break
  sleep 0.05
done
n=$(frames)
[ "$n" -ge 2 ] && [ "$n" -lt 8 ] || { echo "task 1 had $n of 8 frames when it was to be requeued (want 2 to 7)" >&2; exit 1; }
scontrol requeue "${job}_1"
echo "slurm ($SECONDS s): task ${job}_1 requeued with $n of 8 frames made"
# Slurm holds a requeued job back for a while (its begin time moves on); let it go at once.
for _ in $(seq 120); do
  if [ "$(squeue -h -j "${job}_1" -o %T 2>/dev/null)" = PENDING ]; then
    scontrol update JobId="${job}_1" StartTime=now
    break
  fi
  sleep 0.5
done

# Every task finishes (the requeued one after its restart).
for _ in $(seq 600); do
  [ -z "$(squeue -h -j "$job" 2>/dev/null)" ] && break
  sleep 1
done
[ -z "$(squeue -h -j "$job")" ] || { echo "the array job did not finish:" >&2; squeue -j "$job" >&2; exit 1; }
log="$work/glassbake-dataset-${job}_1.log"
grep -q "already complete" "$log" || { echo "the requeued task did not resume its shard:" >&2; cat "$log" >&2; exit 1; }
echo "slurm ($SECONDS s): the requeued task resumed: $(grep 'already complete' "$log" | tail -1)"

"$glassbake" dataset merge --out "$work/merged" "$work"/shards/*
"$glassbake" dataset cornell-glass --out "$work/single" "${args[@]}" >/dev/null
diff -r "$work/merged" "$work/single"
echo "slurm ($SECONDS s): the merged dataset is byte-identical to a one-machine run ($(find "$work/single" -type f | wc -l) files)"
