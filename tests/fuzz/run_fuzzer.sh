#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Runs one libFuzzer harness for a bounded time from the committed seed corpus.
# usage: run_fuzzer.sh FUZZER SEED_DIR REGRESSION_DIR WORK_DIR SECONDS
# Fails (exit != 0) on a crash, leak, timeout or sanitizer report; the input
# is left in WORK_DIR/artifacts/: copy it into REGRESSION_DIR and fix the bug.
set -euo pipefail
fuzzer=$1 seeds=$2 regressions=$3 work=$4 seconds=$5
rm -rf "$work"
mkdir -p "$work/corpus" "$work/artifacts"
# Known crash inputs first: each must pass (libFuzzer runs given files once).
if compgen -G "$regressions/*" > /dev/null; then
  "$fuzzer" -runs=0 "$regressions"/* 2>&1 | tail -3
fi
"$fuzzer" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -max_len=65536 \
  -print_final_stats=1 -artifact_prefix="$work/artifacts/" "$work/corpus" "$seeds" 2>&1 | \
  grep -E "stat::|ERROR|SUMMARY|crash|Done|INFO: seed corpus" || true
# libFuzzer exits non-zero on a finding; with the pipe above, check artifacts.
if compgen -G "$work/artifacts/*" > /dev/null; then
  echo "fuzzer found a problem: $(ls "$work/artifacts")" >&2
  exit 1
fi
