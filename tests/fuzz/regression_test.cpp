// SPDX-License-Identifier: MIT
// Replays the committed fuzz seed corpus and every kept crash input
// (tests/fuzz/regressions/) through the fuzz harnesses, built with the normal
// compiler: runs in every `make test`, with or without clang.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <sys/mman.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "../../daemon/procamd/config.hpp"
#include "worker_wire.hpp"

extern "C" int FuzzRequest(const uint8_t* data, size_t size);
extern "C" int FuzzConfig(const uint8_t* data, size_t size);
extern "C" int FuzzWorker(const uint8_t* data, size_t size);

namespace {
namespace fs = std::filesystem;

std::vector<fs::path> inputs(const std::string& kind) {
  std::vector<fs::path> out;
  for (const char* root : {"corpus", "regressions"}) {
    const fs::path dir = fs::path(PROCAM_SOURCE_DIR) / "tests/fuzz" / root / kind;
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(dir, ec))
      if (e.is_regular_file()) out.push_back(e.path());
  }
  return out;
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

TEST(FuzzRegression, RequestCorpusAndCrashInputs) {
  auto files = inputs("request");
  EXPECT_GE(files.size(), 10u);
  for (const auto& f : files) {
    const std::string s = slurp(f);
    SCOPED_TRACE(f.string());
    EXPECT_EQ(FuzzRequest(reinterpret_cast<const uint8_t*>(s.data()), s.size()), 0);
  }
}

TEST(FuzzRegression, ConfigCorpusAndCrashInputs) {
  auto files = inputs("config");
  EXPECT_GE(files.size(), 5u);
  for (const auto& f : files) {
    const std::string s = slurp(f);
    SCOPED_TRACE(f.string());
    EXPECT_EQ(FuzzConfig(reinterpret_cast<const uint8_t*>(s.data()), s.size()), 0);
  }
}

TEST(FuzzRegression, WorkerProtocolCorpusAndCrashInputs) {
  auto files = inputs("worker");
  EXPECT_GE(files.size(), 5u);
  for (const auto& f : files) {
    const std::string s = slurp(f);
    SCOPED_TRACE(f.string());
    EXPECT_EQ(FuzzWorker(reinterpret_cast<const uint8_t*>(s.data()), s.size()), 0);
  }
}

// ---- worker protocol seeds ----
// A seed is one selector byte (fuzz_worker.cpp: 0 control packet, 1 error
// reply, 2 plan blob, 3 outputs blob, 4 create blob) and that decoder's input.
// A seed the current decoders refuse only teaches the fuzzer the refusal, so
// every committed seed must decode, except those named "refused-*" (kept
// on purpose: an old protocol version, a bad magic).
namespace wire = procam::host::wire;

procam::Status decode_worker_seed(const std::string& seed) {
  if (seed.empty()) return procam::Error(procam::Code::invalid_argument, "empty seed");
  const auto* data = reinterpret_cast<const uint8_t*>(seed.data()) + 1;
  const size_t size = seed.size() - 1;
  const int which = static_cast<uint8_t>(seed[0]) % 5;
  if (which == 0) {
    wire::Message m;
    PROCAM_TRY(wire::parse_packet(reinterpret_cast<const char*>(data), size, m));
    uint8_t ahead = 0;
    if (m.type == static_cast<uint16_t>(wire::Msg::end_round)) return wire::decode_end_round(m.payload, ahead);
    return {};
  }
  if (which == 1) {
    procam::Status out;
    return wire::decode_error(std::string_view(reinterpret_cast<const char*>(data), size), out);
  }
  // Blob decoders read a mapping, as the daemon maps a received memfd.
  void* p = ::mmap(nullptr, size, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (size == 0 || p == MAP_FAILED) return procam::Error(procam::Code::invalid_argument, "empty blob");
  std::memcpy(p, data, size);
  const wire::Mapping blob(p, size);
  if (which == 2) {
    wire::AbiPlan plan;
    return wire::decode_plan(blob, plan);
  }
  if (which == 3) {
    // As fuzz_worker.cpp: references into a 64 KiB stand-in heap.
    alignas(64) static uint8_t heap[1 << 16];
    const wire::HeapResolver resolve = [](uint64_t off, uint64_t bytes, std::string& why) -> const uint8_t* {
      if (off > sizeof heap || bytes > sizeof heap - off) {
        why = "outside the heap";
        return nullptr;
      }
      return heap + off;
    };
    std::vector<procam_output> outs;
    return wire::decode_outputs(blob.data(), blob.size(), outs, resolve);
  }
  wire::CreateRequest req;
  return wire::decode_create(blob, req);
}

// Every committed seed reaches the decoder behind its selector: it decodes
// at today's protocol version, or it is named refused-* and is refused.
TEST(FuzzRegression, WorkerSeedsDecodeAtTheCurrentVersion) {
  const fs::path dir = fs::path(PROCAM_SOURCE_DIR) / "tests/fuzz/corpus/worker";
  size_t decoded = 0, refused = 0;
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    SCOPED_TRACE(name);
    const procam::Status st = decode_worker_seed(slurp(e.path()));
    if (name.rfind("refused-", 0) == 0) {
      EXPECT_FALSE(st.ok());
      ++refused;
    } else {
      EXPECT_TRUE(st.ok()) << st.message()
                           << " (regenerate the seeds: see WorkerSeedsFromTheEncoders below)";
      ++decoded;
    }
  }
  EXPECT_GE(decoded, 8u);
  EXPECT_GE(refused, 1u);
}

// The protocol version the daemon refuses is named in the refusal: an old
// worker (or a seed left from an old version) is told apart from garbage.
TEST(FuzzRegression, WorkerSeedOfAnOldVersionIsRefusedByVersion) {
  const std::string seed =
      slurp(fs::path(PROCAM_SOURCE_DIR) / "tests/fuzz/corpus/worker/refused-packet-hello-v1");
  const procam::Status st = decode_worker_seed(seed);
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.message().find("protocol version 1, expected " + std::to_string(wire::kVersion)), std::string::npos)
      << st.message();
}

// Writes the worker seeds with today's encoders into
// <build>/tests/fuzz/worker-seeds/ and checks that each decodes; when the
// protocol changes, copy them over tests/fuzz/corpus/worker/ (the refused-*
// seeds there are kept by hand).
TEST(FuzzRegression, WorkerSeedsFromTheEncoders) {
  const fs::path out = fs::path(PROCAM_BINARY_DIR) / "tests/fuzz/worker-seeds";
  fs::create_directories(out);
  std::vector<std::pair<std::string, std::string>> seeds;
  auto add = [&](const std::string& name, uint8_t selector, const std::string& bytes) {
    seeds.emplace_back(name, std::string(1, static_cast<char>(selector)) + bytes);
  };
  auto packet = [](wire::Msg type, uint32_t seq, const std::string& payload) {
    wire::Writer w;
    w.u32(wire::kMagic);
    w.raw(&wire::kVersion, 2);
    const auto t = static_cast<uint16_t>(type);
    w.raw(&t, 2);
    w.u32(seq);
    w.u32(static_cast<uint32_t>(payload.size()));
    w.raw(payload.data(), payload.size());
    return w.bytes();
  };
  {
    wire::Writer p;
    p.u32(0xff);  // every sandbox rule
    p.str("/tmp/procam-scratch/procam-worker-1234");
    p.str("");
    add("packet-hello", 0, packet(wire::Msg::hello, 0, p.bytes()));
  }
  {
    wire::Writer p;
    p.i32(PROCAM_LOG_INFO);
    p.str("hello");
    add("packet-log", 0, packet(wire::Msg::log, 3, p.bytes()));
  }
  {
    wire::Writer p;
    p.f64(0.5);
    p.str("decoding");
    add("packet-progress", 0, packet(wire::Msg::progress, 4, p.bytes()));
  }
  {
    wire::Writer p;
    for (uint32_t v : {7u, 1u, 1920u, 1200u, 1u, uint32_t{PROCAM_PIXEL_U8}, 8u}) p.u32(v);
    add("packet-add-frame", 0, packet(wire::Msg::add_frame, 9, p.bytes()));
  }
  {
    wire::Writer p;
    p.u8(1);
    p.u64(32u << 20);
    add("packet-outputs-reply", 0, packet(wire::Msg::ok, 12, p.bytes()));
  }
  add("packet-end-round-ahead", 0, packet(wire::Msg::end_round, 10, wire::encode_end_round(3)));
  add("error-reply", 1,
      wire::encode_error(procam::Error(procam::Code::plugin_error,
                                       "plugin 'x' end_round failed (PROCAM_ERR_INTERNAL): boom", "a hint")));
  // Images: a 4x3 u8 pattern and a 2x2 u16 one; a 2x1 f32 map.
  const std::vector<uint8_t> px8{0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11};
  const std::vector<uint16_t> px16{0, 1023, 512, 7};
  const std::vector<float> pxf{1.f, 2.f, 3.f, -1.f, 0.5f, 4.f};
  auto image = [](const void* data, uint32_t w, uint32_t h, uint32_t type, uint32_t depth, size_t sample) {
    procam_image v{};
    v.width = w;
    v.height = h;
    v.channels = 1;
    v.pixel_type = type;
    v.bit_depth = depth;
    v.stride_bytes = w * sample;
    v.data = data;
    return v;
  };
  {
    procam::host::Plan plan;
    plan.note = "why";
    for (const char* label : {"col bit 0", "col bit 0 inverse"}) {
      procam::host::PlannedFrame f;
      f.label = label;
      f.pattern = image(px8.data(), 4, 3, PROCAM_PIXEL_U8, 8, 1);
      f.settings.struct_size = sizeof(procam_frame_settings);
      f.settings.camera_index = -1;
      f.settings.exposure_us = std::nan("");
      f.settings.light_index = 1;
      plan.frames.push_back(f);
    }
    add("plan-two-frames", 2, wire::encode_plan(plan));
    plan.frames.resize(1);
    plan.note.clear();
    plan.frames[0].label = "f";
    plan.frames[0].pattern = image(px16.data(), 2, 2, PROCAM_PIXEL_U16, 10, 2);
    add("plan-u16", 2, wire::encode_plan(plan));
  }
  {
    std::vector<procam::host::Output> outs(4);
    outs[0].name = "depth_mm";
    outs[0].kind = PROCAM_OUTPUT_IMAGE;
    outs[0].unit = "mm";
    outs[0].description = "depth";
    outs[0].image = image(pxf.data(), 3, 2, PROCAM_PIXEL_F32, 32, 4);
    outs[1].name = "decode_ms";
    outs[1].kind = PROCAM_OUTPUT_SCALAR;
    outs[1].unit = "ms";
    outs[1].scalar = 3.5;
    outs[2].name = "cloud";
    outs[2].kind = PROCAM_OUTPUT_POINTS;
    outs[2].unit = "mm";
    outs[2].points = pxf.data();
    outs[2].point_count = 2;
    outs[2].point_stride = 3;
    outs[2].point_fields = "x,y,z";
    outs[3].name = "report";
    outs[3].kind = PROCAM_OUTPUT_JSON;
    outs[3].json = R"({"a": 1})";
    add("outputs-every-kind", 3, wire::encode_outputs(outs));
    // The same with the image and the points named in a shared heap
    // (protocol v5, get_outputs 2), at offsets inside the stand-in heap.
    alignas(64) static float heap[1024];
    std::copy(pxf.begin(), pxf.end(), heap);
    std::copy(pxf.begin(), pxf.end(), heap + 64);
    outs[0].image.data = heap;
    outs[2].points = heap + 64;
    const wire::HeapSpan span{reinterpret_cast<const uint8_t*>(heap), sizeof heap};
    wire::Writer refs;
    wire::write_outputs(refs, outs, &span);
    add("outputs-heap-refs", 3, refs.bytes());
  }
  {
    wire::CreateRequest req;
    req.plugin_file = "/usr/lib/procam/plugins/x.so";
    req.plugin_name = "x";
    req.method = "gray";
    req.params = R"({"bits": 10})";
    req.rig = R"({"projector":{"height":3,"width":4}})";
    procam::host::InputImage in;
    in.name = "depth_mm";
    in.unit = "mm";
    in.description = "scan 1";
    in.image = image(pxf.data(), 2, 3, PROCAM_PIXEL_F32, 32, 4);
    req.inputs.push_back(in);
    add("create-with-input", 4, wire::encode_create(req));
  }
  for (const auto& [name, bytes] : seeds) {
    SCOPED_TRACE(name);
    const procam::Status st = decode_worker_seed(bytes);
    EXPECT_TRUE(st.ok()) << st.message();
    std::ofstream(out / name, std::ios::binary) << bytes;
  }
}

// The count fields accept JSON integers in range only. A huge float (1e52
// threads, found by fuzz_config in CI) used to reach an unsigned conversion,
// which is undefined behaviour; 2.5 was silently truncated to 2.
TEST(FuzzRegression, ConfigCountsAreIntegersInRange) {
  const auto base = nlohmann::json{{"rig", nlohmann::json{{"name", "inline"}}}};
  auto with = [&](const char* key, nlohmann::json v) {
    auto j = base;
    j[key] = std::move(v);
    return procam::daemon::parse_config(j, "/fuzz/base");
  };
  ASSERT_TRUE(procam::daemon::parse_config(base, "/fuzz/base").ok());
  for (const char* key : {"threads", "max_queue"}) {
    SCOPED_TRACE(key);
    for (const nlohmann::json& bad : {nlohmann::json(1.2e52), nlohmann::json(2.5), nlohmann::json(-1),
                                      nlohmann::json(0), nlohmann::json(1000000), nlohmann::json("4")}) {
      auto c = with(key, bad);
      ASSERT_FALSE(c.ok()) << bad.dump();
      EXPECT_NE(c.status().message().find(key), std::string::npos) << c.status().message();
      EXPECT_NE(c.status().message().find("integer"), std::string::npos) << c.status().message();
    }
  }
  auto ok = with("threads", 8);
  ASSERT_TRUE(ok.ok()) << ok.status().message();
  EXPECT_EQ(ok->threads, 8u);
  ok = with("max_queue", 100000);
  ASSERT_TRUE(ok.ok()) << ok.status().message();
  EXPECT_EQ(ok->max_queue, 100000u);
}

// plugins.freeze_outputs reaches IsolationOptions::freeze_outputs; absent it
// stays on (the default every rig ran with), and a non-boolean is refused
// naming the key.
TEST(ProcamdConfig, PluginsFreezeOutputs) {
  auto parse = [](nlohmann::json plugins) {
    nlohmann::json j{{"rig", nlohmann::json{{"name", "inline"}}}};
    if (!plugins.is_null()) j["plugins"] = std::move(plugins);
    return procam::daemon::parse_config(j, "/fuzz/base");
  };
  auto dflt = parse(nullptr);
  ASSERT_TRUE(dflt.ok()) << dflt.status().message();
  EXPECT_TRUE(dflt->plugins.freeze_outputs);
  auto off = parse({{"freeze_outputs", false}, {"max_idle_workers", 1u}});
  ASSERT_TRUE(off.ok()) << off.status().message();
  EXPECT_FALSE(off->plugins.freeze_outputs);
  EXPECT_TRUE(off->plugins.sandbox);  // the shared boolean branch sets only its own key
  EXPECT_TRUE(off->plugins.prestart);
  auto on = parse({{"freeze_outputs", true}});
  ASSERT_TRUE(on.ok()) << on.status().message();
  EXPECT_TRUE(on->plugins.freeze_outputs);
  for (const nlohmann::json& bad : {nlohmann::json("false"), nlohmann::json(0), nlohmann::json(nullptr)}) {
    auto c = parse({{"freeze_outputs", bad}});
    ASSERT_FALSE(c.ok()) << bad.dump();
    EXPECT_NE(c.status().message().find("plugins.freeze_outputs"), std::string::npos) << c.status().message();
    EXPECT_NE(c.status().message().find("true or false"), std::string::npos) << c.status().message();
  }
}

}  // namespace
