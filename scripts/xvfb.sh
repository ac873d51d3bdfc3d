#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Start / stop a virtual X server for the glfw projector and the screen camera.
#   scripts/xvfb.sh start [DISPLAY_NUMBER] [WxH]   prints "export DISPLAY=:N"
#   scripts/xvfb.sh stop  [DISPLAY_NUMBER]
# Tests start their own servers (tests/hardware/x_server.hpp); this is for demos.
set -euo pipefail
cmd=${1:-start}
n=${2:-99}
size=${3:-1280x800}
pidfile=/tmp/procam-xvfb-$n.pid
case "$cmd" in
  start)
    if [ -e "/tmp/.X11-unix/X$n" ]; then echo "display :$n is already in use" >&2; exit 1; fi
    Xvfb ":$n" -screen 0 "${size}x24" -nolisten tcp >/tmp/procam-xvfb-$n.log 2>&1 &
    echo $! > "$pidfile"
    for _ in $(seq 50); do [ -e "/tmp/.X11-unix/X$n" ] && break; sleep 0.1; done
    echo "export DISPLAY=:$n";;
  stop)
    [ -f "$pidfile" ] && kill "$(cat "$pidfile")" 2>/dev/null || true
    rm -f "$pidfile";;
  *) echo "usage: $0 start|stop [N] [WxH]" >&2; exit 2;;
esac
