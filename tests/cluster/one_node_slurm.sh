#!/bin/bash
# The cluster test of issue 33 (docs/cluster.md): a one-node Slurm cluster started here (munged, slurmctld, slurmd
# in a scratch folder under /tmp, their own MUNGE key and random ports, no systemd, no cgroups), a 4-task array of
# trial shards and its merge through sbatch --wait, and 3 shards submitted by magvine itself (--submit), and a design
# sweep's starts as a 2-task array; the merged batches compared with the one-machine batch and design; the daemons stopped by their pids (also those a killed earlier run
# left, recorded in WORK).
# Usage: one_node_slurm.sh MAGVINE SCENE WORK DESIGN (a design file with several starts, also sharded). Exit 77 (skipped) when not root, and where Slurm or MUNGE is not
# installed, unless MAGVINE_REQUIRE_SLURM is set (CI: tools/install-deps.sh installs them), where that is a failure.
set -euo pipefail
MAGVINE=$1
SCENE=$2
WORK=$3
DESIGN=$4

skip() {
  echo "SKIP: $1"
  if [ -n "${MAGVINE_REQUIRE_SLURM:-}" ]; then exit 1; fi
  exit 77
}
for tool in munged slurmctld slurmd sbatch sinfo squeue scontrol scancel runuser; do
  command -v "$tool" > /dev/null || skip "$tool is not installed (tools/install-deps.sh installs slurm-wlm and munge)"
done
if [ "$(id -u)" != 0 ]; then  # slurmd runs as root: a machine where tests do not is skipped, even in CI
  echo "SKIP: slurmd must run as root"
  exit 77
fi
id munge > /dev/null 2>&1 && id slurm > /dev/null 2>&1 || skip "the munge and slurm users are missing"

# Daemons a killed earlier run left (ctest's time-out kills without a trap): stop them first.
mkdir -p "$WORK"
PIDS=$WORK/daemons.pids
if [ -f "$PIDS" ]; then
  while read -r pid; do kill "$pid" 2> /dev/null || true; done < "$PIDS"
  sleep 1
fi
: > "$PIDS"

# The cluster's files in a folder of their own under /tmp, which the munge and slurm users can reach whatever the
# checkout's folder is (munged refuses a key or socket below a folder others may write).
CLUSTER=$(mktemp -d /tmp/magvine-slurm.XXXXXX)
chmod 755 "$CLUSTER"
echo "$CLUSTER" > "$WORK/cluster.path"
mkdir -p "$CLUSTER"/{munge,state,spool,log,run}
chown munge: "$CLUSTER/munge"
chmod 711 "$CLUSTER/munge"  # others may reach the socket, not list the folder
chown slurm: "$CLUSTER/state" "$CLUSTER/log"
KEY=$CLUSTER/munge/munge.key
dd if=/dev/urandom of="$KEY" bs=1024 count=1 status=none  # a key of our own: the cluster lives and dies here
chown munge: "$KEY"
chmod 400 "$KEY"
SOCKET=$CLUSTER/munge/munge.socket
PORT=$((17000 + RANDOM % 2000))
JOBS=()

record() {  # the pid in file $1 (waiting for the daemon to write it) into $PIDS
  for _ in $(seq 40); do
    if [ -s "$1" ]; then
      cat "$1" >> "$PIDS"
      return 0
    fi
    sleep 0.25
  done
  echo "no pid file $1"
  return 1
}
stop() {  # the jobs (while slurmctld answers), then the daemons; once
  if [ ${#JOBS[@]} -gt 0 ]; then timeout 5 scancel "${JOBS[@]}" 2> /dev/null || true; fi
  JOBS=()
  while read -r pid; do kill "$pid" 2> /dev/null || true; done < "$PIDS"
  for _ in $(seq 20); do
    alive=0
    while read -r pid; do kill -0 "$pid" 2> /dev/null && alive=1; done < "$PIDS"
    [ $alive = 0 ] && break
    sleep 0.25
  done
  : > "$PIDS"
}
failed() {
  echo "FAILED at line $1; the daemons' logs:"
  tail -n 20 "$CLUSTER"/munge/munged.log "$CLUSTER"/log/*.log 2> /dev/null || true
}
trap 'failed $LINENO' ERR
trap stop EXIT

runuser -u munge -- munged --socket="$SOCKET" --key-file="$KEY" --pid-file="$CLUSTER/munge/munged.pid" \
  --log-file="$CLUSTER/munge/munged.log" --seed-file="$CLUSTER/munge/seed"
record "$CLUSTER/munge/munged.pid"
cat > "$CLUSTER/slurm.conf" << CONF
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
DependencyParameters=kill_invalid_depend
StateSaveLocation=$CLUSTER/state
SlurmdSpoolDir=$CLUSTER/spool
SlurmctldPidFile=$CLUSTER/run/slurmctld.pid
SlurmdPidFile=$CLUSTER/run/slurmd.pid
SlurmctldLogFile=$CLUSTER/log/slurmctld.log
SlurmdLogFile=$CLUSTER/log/slurmd.log
NodeName=localhost CPUs=$(nproc) State=UNKNOWN
PartitionName=test Nodes=localhost Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF=$CLUSTER/slurm.conf
slurmctld -f "$SLURM_CONF"
record "$CLUSTER/run/slurmctld.pid"
slurmd -f "$SLURM_CONF" -N localhost # whatever the machine is called
record "$CLUSTER/run/slurmd.pid"
idle=0
for _ in $(seq 60); do
  if sinfo -h -o %t 2> /dev/null | grep -q idle; then
    idle=1
    break
  fi
  sleep 0.5
done
[ $idle = 1 ] || { echo "the node did not come up idle in 30 s"; sinfo || true; false; }

# The batch on one machine, then as 4 shards on the cluster, submitted by hand.
"$MAGVINE" trials "$SCENE" --repeats 8 --jobs 2 --out "$CLUSTER/one" > /dev/null
"$MAGVINE" trials "$SCENE" --repeats 8 --jobs 1 --shards 4 --slurm "$CLUSTER/job.sh" --out "$CLUSTER/cluster" > /dev/null
jid=$(sbatch --parsable "$CLUSTER/job.sh")
JOBS+=("$jid")
timeout 90 sbatch --wait --dependency=afterok:"$jid" "$CLUSTER/job.merge.sh"
# Every value but the runtimes (column 14 of trials.csv): the same batch.
cut -d, -f1-13,15- "$CLUSTER/one/trials.csv" > "$CLUSTER/one.csv"
cut -d, -f1-13,15- "$CLUSTER/cluster/trials.csv" > "$CLUSTER/cluster.csv"
diff "$CLUSTER/one.csv" "$CLUSTER/cluster.csv"
diff "$CLUSTER/one/summary.csv" "$CLUSTER/cluster/summary.csv"
diff "$CLUSTER/one/summary.md" "$CLUSTER/cluster/summary.md"
test "$(ls -d "$CLUSTER"/cluster/shard-* | wc -l)" = 4

# --submit: magvine submits both itself (the merge afterok on the array) and prints their ids; wait for the merge.
read -r array merge < <("$MAGVINE" trials "$SCENE" --repeats 8 --jobs 1 --shards 3 --slurm "$CLUSTER/again.sh" \
  --submit --out "$CLUSTER/submitted")
JOBS+=("$array" "$merge")
state=
for _ in $(seq 180); do
  state=$(scontrol show job -o "$merge" 2> /dev/null | sed -n 's/.*JobState=\([A-Z_]*\).*/\1/p')
  case "$state" in
    COMPLETED | FAILED | CANCELLED | TIMEOUT | NODE_FAIL | OUT_OF_MEMORY) break ;;
  esac
  sleep 0.5
done
[ "$state" = COMPLETED ] || { echo "the submitted merge job ended $state"; false; }
cut -d, -f1-13,15- "$CLUSTER/submitted/trials.csv" > "$CLUSTER/submitted.csv"
diff "$CLUSTER/one.csv" "$CLUSTER/submitted.csv"
diff "$CLUSTER/one/summary.md" "$CLUSTER/submitted/summary.md"

# A design sweep: its starts as a 2-task array and the merge; the design one machine finds, to the last digit.
"$MAGVINE" design "$DESIGN" --out "$CLUSTER/design-one" > /dev/null 2>&1
"$MAGVINE" design "$DESIGN" --shards 2 --slurm "$CLUSTER/design.sh" --out "$CLUSTER/design" > /dev/null 2>&1
jid=$(sbatch --parsable "$CLUSTER/design.sh")
JOBS+=("$jid")
timeout 90 sbatch --wait --dependency=afterok:"$jid" "$CLUSTER/design.merge.sh"
grep -v '"runtime_s"\|"time_s"' "$CLUSTER/design-one/design.json" > "$CLUSTER/design-one.json"
grep -v '"runtime_s"\|"time_s"' "$CLUSTER/design/design.json" > "$CLUSTER/design-cluster.json"
diff "$CLUSTER/design-one.json" "$CLUSTER/design-cluster.json"
for f in shape.csv target.csv scene.yaml; do cmp "$CLUSTER/design-one/$f" "$CLUSTER/design/$f"; done
echo "the cluster's merged batches of $(($(wc -l < "$CLUSTER/one.csv") - 1)) trials (4 shards by hand, 3 by --submit)" \
  "equal the one-machine batch; the design sweep's 2 shards, the one-machine design"
stop
rm -rf "$CLUSTER"
