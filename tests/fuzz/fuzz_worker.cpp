// SPDX-License-Identifier: MIT
// libFuzzer harness over the plugin worker protocol decoders
// (daemon/plugin_host/src/worker_wire.*, WORKER_PROTOCOL.md): what the
// daemon reads from a worker it cannot trust. The first byte picks the
// decoder (control packet, error reply, plan blob, outputs blob, create
// blob); the rest is its input. Each must accept or refuse with a Status,
// never throw, crash or read outside the input: every byte a decoded view
// claims is read here, so ASan catches a bound that was not checked.
// Outputs may refer into a shared heap (a 64 KiB stand-in here).
#include <sys/mman.h>

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "worker_wire.hpp"

#ifndef PROCAM_FUZZ_ENTRY
#define PROCAM_FUZZ_ENTRY LLVMFuzzerTestOneInput
#endif

namespace {
using namespace procam::host;

// An exact-size private mapping of the input, as map_sealed_blob would give
// (page-aligned start; reads past the end fault or trip ASan).
wire::Mapping map_copy(const uint8_t* data, size_t size) {
  if (size == 0) return wire::Mapping();
  void* p = ::mmap(nullptr, size, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (p == MAP_FAILED) return wire::Mapping();
  std::memcpy(p, data, size);
  return wire::Mapping(p, size);
}

volatile uint64_t g_sink;

// The daemon's view of a worker's shared heap (protocol v5 references):
// 64 KiB, every reference bounds-checked as OutputSnapshot does.
alignas(64) uint8_t g_heap[1 << 16];
const uint8_t* resolve_heap(uint64_t off, uint64_t bytes, std::string& why) {
  if (off > sizeof g_heap || bytes > sizeof g_heap - off) {
    why = "outside the heap";
    return nullptr;
  }
  return g_heap + off;
}

void touch_image(const procam_image& v) {
  const size_t row = wire::packed_row_bytes(v);
  if (v.data == nullptr) return;
  const auto* b = static_cast<const uint8_t*>(v.data);
  uint64_t s = 0;
  for (uint32_t y = 0; y < v.height; ++y) s += b[y * v.stride_bytes] + b[y * v.stride_bytes + row - 1];
  g_sink = s;
}

}  // namespace

extern "C" int PROCAM_FUZZ_ENTRY(const uint8_t* data, size_t size);
extern "C" int PROCAM_FUZZ_ENTRY(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const int which = data[0] % 5;
  ++data;
  --size;
  switch (which) {
    case 0: {
      wire::Message m;
      if (!wire::parse_packet(reinterpret_cast<const char*>(data), size, m).ok()) break;
      // A request's payload the worker decodes itself (version 6).
      uint8_t ahead = 0;
      if (m.type == static_cast<uint16_t>(wire::Msg::end_round) && wire::decode_end_round(m.payload, ahead).ok())
        g_sink = ahead;
      break;
    }
    case 1: {
      procam::Status out;
      (void)wire::decode_error(std::string_view(reinterpret_cast<const char*>(data), size), out);
      break;
    }
    case 2: {
      wire::Mapping m = map_copy(data, size);
      wire::AbiPlan plan;
      if (!wire::decode_plan(m, plan).ok()) break;
      g_sink = std::strlen(plan.plan.note);
      for (const procam_pattern_frame& f : plan.frames) {
        g_sink = std::strlen(f.label);
        touch_image(f.pattern);
      }
      break;
    }
    case 3: {
      wire::Mapping m = map_copy(data, size);
      std::vector<procam_output> outs;
      if (!wire::decode_outputs(m.data(), m.size(), outs, resolve_heap).ok()) break;
      for (const procam_output& o : outs) {
        g_sink = std::strlen(o.name) + std::strlen(o.unit) + std::strlen(o.description);
        if (o.kind == PROCAM_OUTPUT_IMAGE) touch_image(o.image);
        if (o.kind == PROCAM_OUTPUT_JSON) g_sink = std::strlen(o.json);
        if (o.kind == PROCAM_OUTPUT_POINTS && o.point_count > 0 && o.point_stride > 0) {
          uint32_t bits;  // the last float's bytes (any bit pattern: no float conversion)
          std::memcpy(&bits, o.points + (o.point_count * o.point_stride - 1), sizeof bits);
          g_sink = bits;
        }
      }
      break;
    }
    default: {
      wire::Mapping m = map_copy(data, size);
      wire::CreateRequest req;
      if (!wire::decode_create(m, req).ok()) break;
      for (const InputImage& in : req.inputs) touch_image(in.image);
      break;
    }
  }
  return 0;
}
