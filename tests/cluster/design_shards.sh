#!/bin/bash
# Design sweeps in shards (issue 33, docs/cluster.md): the four starts of a follow-the-leader design split in 2 and in
# 3 shards, merged, give the design one machine finds, in every file and every value but the runtimes; a missing
# shard, a shard given twice, a trials shard and shards of a scene edited since are refused with one line and exit 2,
# writing nothing; the Bayesian baseline (one run, no starts) refuses --shard.
# Usage: design_shards.sh MAGVINE DESIGN_SCENE WORK (a design file with 4 starts)
set -euo pipefail
MAGVINE=$1
SCENE=$2
WORK=$3
rm -rf "$WORK"
mkdir -p "$WORK"
cd "$WORK"

same() {  # the design in $1 equals the design in $2 (design.json less its times, every other file byte for byte)
  grep -v '"runtime_s"\|"time_s"' "$1/design.json" > a.json
  grep -v '"runtime_s"\|"time_s"' "$2/design.json" > b.json
  diff a.json b.json
  for f in shape.csv target.csv insertion.csv scene.yaml; do cmp "$1/$f" "$2/$f"; done
  test "$(ls "$1")" = "$(ls "$2")"
}

refused() {  # `magvine $1` with the other arguments exits 2 with one line naming $2 and writes nothing
  local verb=$1 expect=$2
  shift 2
  set +e
  # shellcheck disable=SC2086
  "$MAGVINE" $verb "$@" --out refused > out.txt 2> err.txt
  local rc=$?
  set -e
  test "$rc" = 2 || { echo "exit $rc, not 2: $verb $*"; cat err.txt; exit 1; }
  test "$(wc -l < err.txt)" = 1 || { echo "not one line:"; cat err.txt; exit 1; }
  grep -q "$expect" err.txt || { echo "does not say '$expect':"; cat err.txt; exit 1; }
  test ! -e refused || { echo "refused $verb wrote refused/"; exit 1; }
}

# The design file by a relative path, as a user gives it (scene.yaml's header quotes it).
cp "$SCENE" ins.yaml
"$MAGVINE" design ins.yaml --out one > /dev/null 2>&1
grep -q '"message": ".*(the best of 4 starts)"' one/design.json
for i in 0 1; do "$MAGVINE" design ins.yaml --shard $i/2 --out a$i > /dev/null 2>&1; done
"$MAGVINE" design merge a1 a0 --out merged2 > /dev/null 2>&1  # in any order
same one merged2
for i in 0 1 2; do "$MAGVINE" design ins.yaml --shard $i/3 --out b$i > /dev/null 2>&1; done
(cd / && "$MAGVINE" design merge "$WORK/b0" "$WORK/b1" "$WORK/b2" --out "$WORK/merged3" > /dev/null 2>&1)  # elsewhere
same one merged3
# Shards copied away from their design file: --scene names it, checked against the shards' hash.
cp ins.yaml moved.yaml
"$MAGVINE" design merge a0 a1 --scene moved.yaml --out merged_moved > /dev/null 2>&1
same one merged_moved

refused "design merge" "shard 2/3 is missing" b0 b1
refused "design merge" "given twice" b0 b1 b1 b2
refused "design merge" "shard count" b0 b1 a0
mkdir -p trials_shard
printf '{"magvine_trials_shard": 1, "shard": 0, "shards": 1, "trials": []}\n' > trials_shard/shard.json
refused "design merge" "not a shard of magvine design" trials_shard
echo "# another file" > other.yaml
refused "design merge" "has changed since the shards ran" a0 a1 --scene other.yaml
refused design "would leave tasks idle" ins.yaml --shards 5 --slurm idle.sh
# A scene edited after its shards ran: the merge would write another scene's design.
cp "$SCENE" edited.yaml
for i in 0 1; do "$MAGVINE" design edited.yaml --shard $i/2 --out e$i > /dev/null 2>&1; done
echo "# edited" >> edited.yaml
refused "design merge" "has changed since the shards ran" e0 e1
sed 's/^design:$/design:\n  method: bayesian/' "$SCENE" > bayesian.yaml
refused design "no starts to shard" bayesian.yaml --shard 0/2
echo "design shards: 4 starts in 2 and in 3 shards merged equal the one-machine design; missing, twice, foreign," \
     "edited-scene shards and a sharded Bayesian run refused"
