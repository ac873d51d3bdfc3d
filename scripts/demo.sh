#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# `make demo`: start procamd on the simulated rig, scan a bundled scene over
# ZeroMQ with the Gray-code decoder, download the results into ./out/, print a
# summary, and stop the daemon cleanly.
set -euo pipefail
BUILD=${1:-build}
BIN=$BUILD/bin
ENDPOINT=${PROCAM_DEMO_ENDPOINT:-tcp://127.0.0.1:5560}
SCENE=${PROCAM_DEMO_SCENE:-tilted-box}
OUT=out
RESULTS=$BUILD/demo-results
LOG=$BUILD/procamd-demo.log

rm -rf "$OUT"
mkdir -p "$OUT"
echo "== starting procamd (simulated rig) on $ENDPOINT; log in $LOG"
"$BIN/procamd" --config configs/procamd.json --endpoint "$ENDPOINT" --results "$RESULTS" \
  --plugins "$BUILD/plugins-out" >"$LOG" 2>&1 &
PID=$!
stop_daemon() {
  if kill -0 "$PID" 2>/dev/null; then
    kill -TERM "$PID"
    if wait "$PID"; then echo "== procamd stopped cleanly (SIGTERM, exit 0)"
    else echo "== procamd exited with status $? (see $LOG)"; fi
  fi
}
trap stop_daemon EXIT

for i in $(seq 1 50); do
  if "$BIN/procam" status --endpoint "$ENDPOINT" --timeout 1 >/dev/null 2>&1; then break; fi
  if ! kill -0 "$PID" 2>/dev/null; then echo "procamd failed to start:"; cat "$LOG"; exit 1; fi
  sleep 0.2
done
"$BIN/procam" status --endpoint "$ENDPOINT"
echo
# Plugins and their methods (parameters: `procam plugins`, full list in $BUILD/demo-plugins.txt).
"$BIN/procam" plugins --endpoint "$ENDPOINT" > "$BUILD/demo-plugins.txt"
grep -v -- '--param' "$BUILD/demo-plugins.txt" | cut -c1-110
echo
echo "== scanning scene '$SCENE' with structured-light/gray"
"$BIN/procam" scan --endpoint "$ENDPOINT" --plugin structured-light --method gray \
  --rig-option scene="$SCENE" --label demo --out "$OUT"
echo
ls -l "$OUT"
