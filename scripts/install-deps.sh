#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Installs the Debian 12 packages procam needs to build, test and run.
# Idempotent: installs only what is missing; does nothing (and needs no
# network) when everything is present. Run as root (or with sudo available).
set -euo pipefail

PACKAGES=(
  # toolchain
  build-essential cmake pkg-config git
  ccache                                 # the sim-only build test reuses the main build's objects (Makefile)
  # libraries (see README "Dependencies")
  libopenimageio-dev openimageio-tools   # result files: EXR, PNG, TIFF
  libopencv-dev                          # required by OpenImageIO's CMake package
  libopencv-contrib-dev                  # GrayCodePattern: speed/identity baseline in procam_sl_ensemble_bench (issue 4)
  nlohmann-json3-dev                     # JSON (config, protocol, plugin ABI data)
  libzmq3-dev cppzmq-dev                 # ZeroMQ transport
  # tests and benchmarks
  libgtest-dev libgmock-dev libbenchmark-dev
  python3 python3-zmq python3-jsonschema # spec-only Python client; schema checks of PROTOCOL.md examples
  clang libclang-rt-14-dev               # libFuzzer harnesses over the protocol decoder and config parser (issue 6)
  # real hardware path (issue 5): GenICam cameras, libcamera, GLFW projector, X servers for tests
  libaravis-dev aravis-tools aravis-tools-cli libusb-1.0-0-dev   # Aravis 0.8 (+ arv-fake-gv-camera-0.8)
  libcamera-dev                                                  # libcamera cameras
  libglfw3-dev libgl-dev libgl1-mesa-dri libglx-mesa0 libx11-dev # GLFW projector, X11 screen camera
  xvfb xserver-xorg-core xserver-xorg-video-dummy x11-xserver-utils # Xvfb / two-monitor Xorg dummy + xrandr
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
$SUDO apt-get install -y -qq "${missing[@]}"
