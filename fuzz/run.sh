#!/usr/bin/env bash
# Runs fuzz targets one after another for SECONDS each (default 660), niced, from binaries
# already built by `cargo +nightly fuzz build -O`, and appends libFuzzer's final stats to
# logs/<target>.log. Crashes land in artifacts/<target>/.
#   fuzz/run.sh 660 csv npy tra      (TIMEOUT=60 to allow slower inputs than 10 s)
set -uo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
cd "$here"
secs="$1"; shift
bin="target/x86_64-unknown-linux-gnu/release"
mkdir -p logs
for t in "$@"; do
    mkdir -p "corpus/$t" "artifacts/$t"
    nice -n 19 "$bin/$t" "corpus/$t" "seeds/$t" \
        -max_total_time="$secs" -timeout="${TIMEOUT:-10}" -rss_limit_mb=2048 -max_len=8192 \
        -print_final_stats=1 -artifact_prefix="artifacts/$t/" \
        > "logs/$t.log" 2>&1
    echo "$t exit $?" >> logs/summary.txt
done
