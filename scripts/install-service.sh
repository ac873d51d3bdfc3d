#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Installs procamd as a systemd service (README "Running under systemd").
# usage (as root): scripts/install-service.sh [BUILD_DIR] [PREFIX]
#   BUILD_DIR  a configured and built tree (default: build)
#   PREFIX     install prefix (default: /usr/local)
# Layout:
#   PREFIX/bin/procamd, PREFIX/bin/procam      daemon and CLI
#   PREFIX/lib/procam/plugins/*.so             decoder plugins (root-owned, not world-writable)
#   PREFIX/lib/libprocam-client.so*, PREFIX/include/procam/, PREFIX/lib/cmake/procam/   C++ client
#   /etc/procam/procamd.json                   config (from configs/procamd-system.json; kept if present)
#   /etc/procam/rigs/, /etc/procam/scenes/     rig and scene configs
#   /etc/procam/keys/                          CURVE keys (0750 root:procam)
#   /var/lib/procam/results/                   scans (owned by the procam user)
#   /etc/systemd/system/procamd.service        the unit
# Idempotent: re-running upgrades binaries and keeps config, keys and results.
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
prefix=${2:-/usr/local}
[ "$(id -u)" -eq 0 ] || { echo "install-service: run as root" >&2; exit 1; }
[ -x "$build/bin/procamd" ] || { echo "install-service: build first (make build)" >&2; exit 1; }

cmake --install "$build" --prefix "$prefix"
id procam >/dev/null 2>&1 || useradd --system --home-dir /var/lib/procam --shell /usr/sbin/nologin procam
install -d -m 0755 /etc/procam /etc/procam/rigs /etc/procam/scenes
install -d -m 0750 -g procam /etc/procam/keys
install -d -m 0750 -o procam -g procam /var/lib/procam /var/lib/procam/results
cp -n configs/rigs/*.json /etc/procam/rigs/
cp -n configs/scenes/*.json /etc/procam/scenes/
if [ ! -e /etc/procam/procamd.json ]; then
  sed "s#/usr/local/lib/procam/plugins#$prefix/lib/procam/plugins#" configs/procamd-system.json > /etc/procam/procamd.json
fi
chmod -R go-w "$prefix/lib/procam/plugins"
sed "s#/usr/local/bin/procamd#$prefix/bin/procamd#" scripts/systemd/procamd.service \
  > /etc/systemd/system/procamd.service
if command -v systemctl >/dev/null && [ -d /run/systemd/system ]; then
  systemctl daemon-reload
  systemctl enable --now procamd
  systemctl --no-pager status procamd || true
else
  echo "install-service: systemd not running here; start with: systemctl enable --now procamd"
fi
