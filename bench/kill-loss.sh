#!/usr/bin/env bash
# How many results a SIGKILL of the coordinator loses: the throughput benchmark's
# experiment (instant made-up results, so the writer is as far behind as it ever gets),
# once whole, then once per KILL_AFTER second with the coordinator SIGKILLed then and
# started again on its database and port; the workers reconnect by themselves. Results
# the workers had to send again = results sent in all (their closing log lines) minus
# those of the whole run. Usage: bench/kill-loss.sh [KILL_AFTER_SECONDS ...]
# (default 1 2 3 4 5). BIN=dir runs the binaries in dir instead of building;
# EXPERIMENT and WORKER_ARGS replace the experiment and the workers' options (real
# simulations: WORKER_ARGS="--threads 1").
set -euo pipefail
cd "$(dirname "$0")/.."
if [ -z "${BIN:-}" ]; then
  cargo build --release --quiet --bins
  BIN=./target/release
fi
workers=2
experiment=${EXPERIMENT:-experiments/bench-service.toml}
worker_args=${WORKER_ARGS:---threads 32 --benchmark-instant-results}

# One run: $1 = seconds before the SIGKILL ("" for none). Prints the results sent in all.
one_run() {
  local dir port coordinator
  dir=$(mktemp -d)
  head -c 24 /dev/urandom | od -An -tx1 | tr -d ' \n' > "$dir/secret"
  port=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
  serve() {
    "$BIN"/strider-coordinator serve --db "$dir/bench.db" \
      --experiment "$experiment" --listen "127.0.0.1:$port" \
      --token-file "$dir/secret" --progress-every 100 2>> "$dir/coordinator.log" &
    coordinator=$!
  }
  serve
  while ! grep -q "serving experiment" "$dir/coordinator.log" 2>/dev/null; do sleep 0.05; done
  for i in $(seq "$workers"); do
    # shellcheck disable=SC2086 # the options are words
    "$BIN"/strider-worker --connect "http://127.0.0.1:$port" --token-file "$dir/secret" \
      $worker_args 2> "$dir/worker-$i.log" &
  done
  if [ -n "$1" ]; then
    sleep "$1"
    kill -KILL "$coordinator"
    wait "$coordinator" 2>/dev/null || true
    serve
  fi
  wait
  sed -n 's/.*results_sent=\([0-9]*\).*/\1/p' "$dir"/worker-*.log | paste -sd+ | bc
  rm -rf "$dir"
}

whole=$(one_run "")
echo "whole run: $whole results sent"
[ $# -gt 0 ] || set -- 1 2 3 4 5
for after in "$@"; do
  sent=$(one_run "$after")
  echo "killed at ${after} s: $sent results sent, $((sent - whole)) sent again"
done
