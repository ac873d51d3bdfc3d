#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Regenerates the table of docs/gray-per-scene.md: starts procamd on the
# simulated rig, scans every scene of the library with the conventional Gray
# decoder (structured-light / gray) and prints one Markdown row per scene from
# the scan manifest's "evaluation" (procamd's comparison with the sim rig's
# ground truth, daemon/engine/src/evaluate.cpp).
#   usage: hw/sim/tools/gray-per-scene.sh [BUILD_DIR]   (default: build)
set -euo pipefail
BUILD=${1:-build}
BIN=$BUILD/bin
ENDPOINT=${PROCAM_GRAY_TABLE_ENDPOINT:-tcp://127.0.0.1:5593}
WORK=$(mktemp -d)
SCENES=${PROCAM_GRAY_TABLE_SCENES:-"plane v-groove marble-slab bowl-on-marble shower-curtain metal-lamp wax-candle deep-scene tilted-box sphere"}
"$BIN/procamd" --config configs/procamd.json --endpoint "$ENDPOINT" --results "$WORK/results" \
  --plugins "$BUILD/plugins-out" >"$WORK/procamd.log" 2>&1 &
PID=$!
trap 'kill -TERM $PID 2>/dev/null; wait $PID 2>/dev/null; rm -rf "$WORK"' EXIT
for i in $(seq 1 100); do
  "$BIN/procam" status --endpoint "$ENDPOINT" --timeout 1 >/dev/null 2>&1 && break
  kill -0 "$PID" 2>/dev/null || { cat "$WORK/procamd.log"; exit 1; }
  sleep 0.2
done
echo "| scene | lit px | lit px within 1 column | decoded | gross errors (> 1 col) | column RMS (px) | depth RMS (mm) |"
echo "|---|---:|---:|---:|---:|---:|---:|"
for s in $SCENES; do
  "$BIN/procam" scan --endpoint "$ENDPOINT" --timeout 120 --plugin structured-light --method gray \
    --rig-option scene="$s" --label "gray-$s" --out "$WORK/$s" >/dev/null 2>"$WORK/$s.err" ||
    { echo "| $s | scan failed: $(tail -1 "$WORK/$s.err") |"; continue; }
  python3 - "$WORK/$s/manifest.json" "$s" <<'PY'
import json, sys
e = json.load(open(sys.argv[1]))["evaluation"]
pct = lambda x: f"{100 * x:.1f} %"
print(f"| {sys.argv[2]} | {e['lit_pixels']} | {pct(e['within_1col_fraction'])} | {pct(e['decoded_fraction'])} | "
      f"{pct(e['gross_error_fraction'])} | {e['col_rms_px']:.2f} | {e.get('depth_rms_mm', float('nan')):.2f} |")
PY
done
