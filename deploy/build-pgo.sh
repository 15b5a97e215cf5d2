#!/usr/bin/env bash
# Builds strider-coordinator and strider-worker with profile-guided optimisation (PGO):
# an instrumented build runs the built-in quick experiment once, and its profile steers
# the optimised build's inlining and code layout. The binaries simulate bit for bit as
# `cargo build --release`'s do (the compiler changes no arithmetic for a profile; the
# script checks the reference trial's digest against the instrumented build's), 5 to
# 11 % faster in interleaved runs (BENCHMARKS.md, "Profile-guided optimisation"). About
# three times as long to build as `cargo build --release`; the binaries land in
# target/pgo/bin.
#
# Needs rustup's llvm-tools component (`rustup component add llvm-tools`) for the
# `llvm-profdata` that matches the compiler: a distribution's LLVM of another version
# cannot read rustc's profiles.
set -euo pipefail
cd "$(dirname "$0")/.."

host=$(rustc -vV | sed -n 's/^host: //p')
profdata="$(rustc --print sysroot)/lib/rustlib/$host/bin/llvm-profdata"
if [ ! -x "$profdata" ]; then
    echo "build-pgo.sh: no $profdata; install it with: rustup component add llvm-tools" >&2
    exit 1
fi

work="$PWD/target/pgo"
rm -rf "${work:?}/profiles" "${work:?}/train" "${work:?}/bin"
mkdir -p "$work/profiles" "$work/train" "$work/bin"
packages=(-p strider-coordinator -p strider-worker)

# `--target` keeps RUSTFLAGS off build scripts and proc macros (they run at build time,
# not in the trial).
echo "build-pgo.sh: instrumented build" >&2
RUSTFLAGS="-Cprofile-generate=$work/profiles" \
    cargo build --release --target "$host" --target-dir "$work/instrumented" "${packages[@]}"

echo "build-pgo.sh: training on the quick experiment (a few minutes)" >&2
"$work/instrumented/$host/release/strider-coordinator" run experiments/quick.toml \
    --db "$work/train/quick.db" --progress-every 60 >&2
"$profdata" merge -o "$work/strider.profdata" "$work/profiles"

echo "build-pgo.sh: optimised build" >&2
RUSTFLAGS="-Cprofile-use=$work/strider.profdata" \
    cargo build --release --target "$host" --target-dir "$work/optimised" "${packages[@]}"
# The profile must change no arithmetic: the optimised worker's reference trial (MAX,
# one second) has the instrumented one's digest, or the script refuses its binaries.
plain=$("$work/instrumented/$host/release/strider-worker" reference-trial | cut -d' ' -f1)
fast=$("$work/optimised/$host/release/strider-worker" reference-trial | cut -d' ' -f1)
if [ "$plain" != "$fast" ]; then
    echo "build-pgo.sh: the optimised build's reference trial is $fast, not $plain: not installed" >&2
    exit 1
fi
for bin in strider-coordinator strider-worker; do
    cp "$work/optimised/$host/release/$bin" "$work/bin/"
done
echo "build-pgo.sh: done (reference trial $fast, as the instrumented build's): $work/bin/strider-coordinator, $work/bin/strider-worker" >&2
