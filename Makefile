# SPDX-License-Identifier: MIT
# Two commands do everything on a fresh Debian 12 machine:
#   make demo   install packages, build, scan a simulated scene through procamd, print a summary
#   make test   install packages, build, run every test through ctest
BUILD ?= build
JOBS ?= $(shell nproc)
BUILD_TYPE ?= RelWithDebInfo
# ccache (installed by scripts/install-deps.sh) is used when present: the
# sim-only build test (tests/build/sim_only_build.cmake) configures a second
# build tree and then reuses this tree's objects instead of compiling them
# again, and rebuilds after `git pull` are faster. Paths are hashed relative
# to the checkout so both trees share entries.
export CCACHE_BASEDIR ?= $(CURDIR)
export CCACHE_NOHASHDIR ?= 1

.PHONY: all deps configure build test demo bench clean

all: build

deps:
	@scripts/install-deps.sh

configure: deps
	@launcher=""; if command -v ccache >/dev/null 2>&1; then \
	  launcher="-DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache"; fi; \
	cmake -S . -B $(BUILD) -DCMAKE_BUILD_TYPE=$(BUILD_TYPE) $$launcher > $(BUILD).configure.log 2>&1 || \
	  { cat $(BUILD).configure.log; exit 1; }

build: configure
	cmake --build $(BUILD) -j$(JOBS)

test: build
	ctest --test-dir $(BUILD) --output-on-failure -j$(JOBS) --timeout 600

demo: build
	@scripts/demo.sh $(BUILD)

clean:
	rm -rf $(BUILD) $(BUILD).configure.log out
