#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Installs the Debian 12 packages procam needs to build, test and run.
# Idempotent: installs only what is missing; does nothing (and needs no
# network) when everything is present. Run as root (or with sudo available).
set -euo pipefail

PACKAGES=(
  # toolchain
  build-essential cmake pkg-config git
  # libraries (see README "Dependencies")
  libopenimageio-dev openimageio-tools   # result files: EXR, PNG, TIFF
  libopencv-dev                          # required by OpenImageIO's CMake package
  nlohmann-json3-dev                     # JSON (config, protocol, plugin ABI data)
  libzmq3-dev cppzmq-dev                 # ZeroMQ transport
  # tests and benchmarks
  libgtest-dev libgmock-dev libbenchmark-dev
  python3 python3-zmq python3-jsonschema # spec-only Python client; schema checks of PROTOCOL.md examples
)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  if command -v sudo >/dev/null; then SUDO="sudo"; else
    echo "install-deps: missing packages (${missing[*]}) and not root; run as root or install them" >&2
    exit 1
  fi
fi
echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
