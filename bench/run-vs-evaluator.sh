#!/usr/bin/env bash
# `run` against the batch evaluator alone, on the same cores and the same trials:
# runs experiments/bench-local.toml with `strider-coordinator run`, then evaluates every
# candidate that run simulated again with the batch evaluator alone (no coordinator, no
# gRPC, no database), PAIRS times in turn, and prints wall, CPU and the ratio of trials/s.
# Usage: bench/run-vs-evaluator.sh [PAIRS] [THREADS]. Run it on a quiet machine.
set -euo pipefail
cd "$(dirname "$0")/.."
pairs=${1:-3}
threads=${2:-2}
cargo build --release --quiet --bins --example evaluator_alone
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
timed() { # prints "wall cpu" of a command
  /usr/bin/time -f "%e %U %S" -o "$dir/time" "$@" > "$dir/out" 2> "$dir/err"
  awk '{printf "%.1f %.1f\n", $1, $2 + $3}' "$dir/time"
}
for p in $(seq "$pairs"); do
  rm -f "$dir"/b.db*
  read -r run_wall run_cpu < <(timed ./target/release/strider-coordinator run \
    experiments/bench-local.toml --db "$dir/b.db" --workers "$threads" --progress-every 1000)
  read -r alone_wall alone_cpu < <(timed ./target/release/examples/evaluator_alone \
    "$dir/b.db" "$threads")
  trials=$(awk '{print $1}' "$dir/out")
  echo "pair $p: $trials trials; run ${run_wall} s wall ${run_cpu} s CPU;" \
    "alone ${alone_wall} s wall ${alone_cpu} s CPU;" \
    "ratio $(echo "scale=1; 100 * $alone_wall / $run_wall" | bc) %"
done
