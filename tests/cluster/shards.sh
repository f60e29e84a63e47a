#!/bin/bash
# Trial shards (issue 33, docs/cluster.md): shards 0/2 and 1/2 of a 4-trial batch, and 3 shards of a 16-trial batch,
# merged, equal the one-machine batch in every value but the runtimes; a missing shard, a shard given twice and a
# shard of another batch are refused with one line and exit 2, writing nothing.
# Usage: shards.sh MAGVINE SCENE WORK
set -euo pipefail
MAGVINE=$1
SCENE=$2
WORK=$3
rm -rf "$WORK"
mkdir -p "$WORK"
cd "$WORK"

same() {  # the batch in $1 equals the batch in $2 (trials.csv less its runtime_s column, the summaries)
  cut -d, -f1-13,15- "$1/trials.csv" > a.csv
  cut -d, -f1-13,15- "$2/trials.csv" > b.csv
  diff a.csv b.csv
  diff "$1/summary.csv" "$2/summary.csv"
  diff "$1/summary.md" "$2/summary.md"
}

refused() {  # `magvine trials merge` with these arguments exits 2 with one line naming $1 and writes nothing
  local expect=$1
  shift
  set +e
  "$MAGVINE" trials merge "$@" --out refused > out.txt 2> err.txt
  local rc=$?
  set -e
  test "$rc" = 2 || { echo "exit $rc, not 2: $*"; cat err.txt; exit 1; }
  test "$(wc -l < err.txt)" = 1 || { echo "not one line:"; cat err.txt; exit 1; }
  grep -q "$expect" err.txt || { echo "does not say '$expect':"; cat err.txt; exit 1; }
  test ! -e refused || { echo "refused merge wrote refused/"; exit 1; }
}

"$MAGVINE" trials "$SCENE" --repeats 4 --jobs 2 --out one4 > /dev/null 2>&1
"$MAGVINE" trials "$SCENE" --repeats 4 --jobs 1 --shard 0/2 --out a0 2> /dev/null
"$MAGVINE" trials "$SCENE" --repeats 4 --jobs 1 --shard 1/2 --out a1 2> /dev/null
"$MAGVINE" trials merge a1 a0 --out merged4 > /dev/null 2>&1  # in any order
same one4 merged4

"$MAGVINE" trials "$SCENE" --repeats 16 --jobs 2 --out one16 > /dev/null 2>&1
for i in 0 1 2; do "$MAGVINE" trials "$SCENE" --repeats 16 --jobs 2 --shard $i/3 --out b$i 2> /dev/null; done
test "$(($(wc -l < b0/trials.csv) + $(wc -l < b1/trials.csv) + $(wc -l < b2/trials.csv) - 3))" = 16
"$MAGVINE" trials merge b0 b1 b2 --out merged16 > /dev/null 2>&1
same one16 merged16

refused "shard 2/3 is missing" b0 b1
refused "given twice" b0 b1 b1 b2
refused "repeats" b0 b1 a0
refused "no shard here" b0 b1 one16
echo "shards: 2 of 4 trials and 3 of 16 merged equal the one-machine batches; missing, twice, foreign shards refused"
