#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# `make demo`: start procamd on the simulated rig, scan two hard scenes over
# ZeroMQ with plain Gray code and with `auto`, download the results (maps,
# previews, report.html) into ./out/, print them side by side, and stop the
# daemon cleanly.
set -euo pipefail
BUILD=${1:-build}
BIN=$BUILD/bin
ENDPOINT=${PROCAM_DEMO_ENDPOINT:-tcp://127.0.0.1:5560}
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
# The point of procam in one table: the same hard scenes scanned with plain
# Gray code and with `auto`, which picks codes that survive global light
# transport (inter-reflections in the V-groove, diffusion in the curtain).
SCENES=${PROCAM_DEMO_SCENES:-v-groove shower-curtain}
for scene in $SCENES; do
  for method in gray auto; do
    echo "== scanning '$scene' with structured-light/$method"
    "$BIN/procam" scan --endpoint "$ENDPOINT" --plugin structured-light --method "$method" \
      --rig-option scene="$scene" --label "demo $scene $method" --out "$OUT/$scene-$method" \
      > "$OUT/$scene-$method.txt"
  done
done
echo
/usr/bin/python3 - "$OUT" $SCENES <<'PY'
import json, os, sys
out, scenes = sys.argv[1], sys.argv[2:]
rows = []
for scene in scenes:
    for method in ("gray", "auto"):
        with open(os.path.join(out, f"{scene}-{method}", "manifest.json")) as f:
            m = json.load(f)
        e = m.get("evaluation") or {}
        pct = lambda k: f"{100 * e[k]:.1f} %" if isinstance(e.get(k), (int, float)) else "-"
        pct2 = lambda k: f"{100 * e[k]:.2f} %" if isinstance(e.get(k), (int, float)) else "-"
        t = m.get("timing_ms", {})
        rows.append((scene, method, str(m["plan"]["patterns"]), pct("within_1col_fraction"),
                     pct("decoded_fraction"), pct2("gross_error_fraction"), f"{t.get('decode', 0):.0f} ms",
                     f"{t.get('total', 0) / 1000:.1f} s"))
head = ("scene", "method", "patterns", "right (<=1 col)", "decoded", "gross errors", "decode", "scan")
w = [max(len(r[i]) for r in rows + [head]) for i in range(len(head))]
line = lambda r: "  " + "  ".join(c.ljust(w[i]) for i, c in enumerate(r))
print("== plain Gray code vs auto, against the simulated rig's ground truth")
print("   (right: % of lit pixels within one projector column; gross: % of decoded pixels off by more than one)")
print(line(head))
print(line(tuple("-" * n for n in w)))
for r in rows:
    print(line(r))
print()
for scene in scenes:
    print(f"   look: {out}/{scene}-gray/report.html  vs  {out}/{scene}-auto/report.html")
PY
echo
echo "== one scan in detail ($OUT/${SCENES%% *}-auto.txt)"
cat "$OUT/${SCENES%% *}-auto.txt"
