#!/usr/bin/env bash
# How many results per second one coordinator accepts over loopback with durable commits
# (WAL, full sync, group commits), fed by workers that answer instantly with made-up
# results. Usage: bench/service-throughput.sh [WORKERS] [THREADS_PER_WORKER]
# Prints results/s computed from the database (results stored / wall time of the run) and
# the coordinator's peak memory. BIN=dir runs the binaries in dir instead of building
# (to compare two builds on the same machine).
set -euo pipefail
cd "$(dirname "$0")/.."
workers=${1:-4}
threads=${2:-4}
if [ -z "${BIN:-}" ]; then
  cargo build --release --quiet --bins
  BIN=./target/release
fi
dir=$(mktemp -d)
trap 'kill $(jobs -p) 2>/dev/null || true; [ -n "${KEEP:-}" ] && cp "$dir/coordinator.log" "$dir/bench.db" /tmp/; rm -rf "$dir"' EXIT
head -c 24 /dev/urandom | od -An -tx1 | tr -d ' \n' > "$dir/secret"
/usr/bin/time -f 'coordinator peak memory: %M KB' -o "$dir/time" \
  "$BIN"/strider-coordinator serve --db "$dir/bench.db" \
  --experiment experiments/bench-service.toml --listen 127.0.0.1:0 \
  --token-file "$dir/secret" --address-file "$dir/address" --progress-every 2 \
  2> "$dir/coordinator.log" &
coordinator=$!
while [ ! -s "$dir/address" ]; do sleep 0.05; done
url=$(head -1 "$dir/address")
start=$(date +%s.%N)
for i in $(seq "$workers"); do
  "$BIN"/strider-worker --connect "$url" --token-file "$dir/secret" \
    --threads "$threads" --benchmark-instant-results 2> "$dir/worker-$i.log" &
done
wait "$coordinator"
end=$(date +%s.%N)
results=$(sqlite3 "$dir/bench.db" "SELECT SUM(results) FROM workers")
candidates=$(sqlite3 "$dir/bench.db" "SELECT COUNT(*) FROM candidates")
echo "workers=$workers threads=$threads results=$results candidates=$candidates seconds=$(echo "$end - $start" | bc)"
echo "results/s: $(echo "$results / ($end - $start)" | bc)"
grep "results/s" "$dir/coordinator.log" | tail -3
cat "$dir/time"
