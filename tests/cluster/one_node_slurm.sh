#!/bin/bash
# The cluster test of issue 33 (docs/cluster.md): a one-node Slurm cluster started here (munged, slurmctld, slurmd
# in a scratch folder, their own ports, no systemd, no cgroups), a 4-task array of trial shards and its merge
# through sbatch --wait, and 3 shards submitted by magvine itself (--submit), the merged batches compared with the
# one-machine batch, the daemons stopped by their pids.
# Usage: one_node_slurm.sh MAGVINE SCENE WORK. Exit 77 (skipped) where Slurm or munge is not installed or not root.
set -euo pipefail
MAGVINE=$1
SCENE=$2
WORK=$3
for tool in munged slurmctld slurmd sbatch sinfo; do
  if ! command -v "$tool" > /dev/null; then
    echo "SKIP: $tool is not installed (tools/install-deps.sh installs slurm-wlm and munge)"
    exit 77
  fi
done
if [ "$(id -u)" != 0 ]; then
  echo "SKIP: slurmd must run as root"
  exit 77
fi
rm -rf "$WORK"
mkdir -p "$WORK"/{munge,state,spool,log,run}
chown munge: "$WORK/munge"
chmod 711 "$WORK/munge"  # others may reach the socket, not list the folder
chown slurm: "$WORK/state" "$WORK/log"
KEY=$WORK/munge/munge.key
# A key of our own: the cluster lives and dies with this test.
dd if=/dev/urandom of="$KEY" bs=1024 count=1 status=none
chown munge: "$KEY"
chmod 400 "$KEY"
SOCKET=$WORK/munge/munge.socket
PORT=$((17000 + RANDOM % 2000))

stop() {
  for pid in "$WORK"/run/slurmd.pid "$WORK"/run/slurmctld.pid "$WORK"/munge/munged.pid; do
    if [ -f "$pid" ]; then kill "$(cat "$pid")" 2> /dev/null || true; fi
  done
}
trap stop EXIT

runuser -u munge -- munged --socket="$SOCKET" --key-file="$KEY" --pid-file="$WORK/munge/munged.pid" \
  --log-file="$WORK/munge/munged.log" --seed-file="$WORK/munge/seed"
cat > "$WORK/slurm.conf" << CONF
ClusterName=magvine-test
SlurmctldHost=localhost
SlurmctldPort=$PORT
SlurmdPort=$((PORT + 1))
SlurmUser=slurm
AuthType=auth/munge
AuthInfo=socket=$SOCKET
CredType=cred/munge
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
MpiDefault=none
ReturnToService=2
StateSaveLocation=$WORK/state
SlurmdSpoolDir=$WORK/spool
SlurmctldPidFile=$WORK/run/slurmctld.pid
SlurmdPidFile=$WORK/run/slurmd.pid
SlurmctldLogFile=$WORK/log/slurmctld.log
SlurmdLogFile=$WORK/log/slurmd.log
NodeName=localhost CPUs=$(nproc) State=UNKNOWN
PartitionName=test Nodes=localhost Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF=$WORK/slurm.conf
slurmctld -f "$SLURM_CONF"
slurmd -f "$SLURM_CONF" -N localhost  # whatever the machine is called
for _ in $(seq 60); do
  if sinfo -h -o %t 2> /dev/null | grep -q idle; then break; fi
  sleep 0.5
done
sinfo

# The batch on one machine, then as 4 shards on the cluster.
"$MAGVINE" trials "$SCENE" --repeats 8 --jobs 2 --out "$WORK/one" > /dev/null
"$MAGVINE" trials "$SCENE" --repeats 8 --jobs 1 --shards 4 --slurm "$WORK/job.sh" --out "$WORK/cluster" > /dev/null
jid=$(sbatch --parsable "$WORK/job.sh")
sbatch --wait --dependency=afterok:"$jid" "$WORK/job.merge.sh"
# Every value but the runtimes (column 14 of trials.csv): the same batch.
cut -d, -f1-13,15- "$WORK/one/trials.csv" > "$WORK/one.csv"
cut -d, -f1-13,15- "$WORK/cluster/trials.csv" > "$WORK/cluster.csv"
diff "$WORK/one.csv" "$WORK/cluster.csv"
diff "$WORK/one/summary.csv" "$WORK/cluster/summary.csv"
diff "$WORK/one/summary.md" "$WORK/cluster/summary.md"
test "$(ls -d "$WORK"/cluster/shard-* | wc -l)" = 4

# --submit: magvine submits both itself (the merge afterok on the array) and prints their ids; wait for the merge.
read -r array merge < <("$MAGVINE" trials "$SCENE" --repeats 8 --jobs 1 --shards 3 --slurm "$WORK/again.sh" \
  --submit --out "$WORK/submitted" 2> /dev/null)
for _ in $(seq 240); do
  if [ -z "$(squeue -h -j "$array,$merge" 2> /dev/null)" ]; then break; fi
  sleep 0.5
done
cut -d, -f1-13,15- "$WORK/submitted/trials.csv" > "$WORK/submitted.csv"
diff "$WORK/one.csv" "$WORK/submitted.csv"
diff "$WORK/one/summary.md" "$WORK/submitted/summary.md"
echo "the cluster's merged batches of $(($(wc -l < "$WORK/one.csv") - 1)) trials (4 shards by hand, 3 by --submit)" \
  "equal the one-machine batch"
