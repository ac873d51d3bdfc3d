// SPDX-License-Identifier: MIT
// The output arena (output_arena.hpp): outputs written into one reused
// shared-memory arena per worker and copied by the daemon before it decodes
// them. A worker that scribbles on the arena after its reply cannot change
// what the daemon returned; the daemon refuses arenas it could lose pages
// of (not sealed against shrinking), sparse arenas, and sizes beyond them.
#include <gtest/gtest.h>
#include <fcntl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include "output_arena.hpp"
#include "procam/core/image.hpp"
#include "procam/host/plugin_host.hpp"
#include "worker_wire.hpp"

namespace procam::host {
namespace {
namespace fs = std::filesystem;
using namespace std::chrono_literals;

// Encodes `n` JSON outputs named o0.. with `payload` each.
std::function<void(wire::Writer&)> json_outputs(size_t n, const std::string& payload) {
  return [n, payload](wire::Writer& w) {
    std::vector<Output> outs(n);
    for (size_t i = 0; i < n; ++i) {
      outs[i].name = "o" + std::to_string(i);
      outs[i].kind = PROCAM_OUTPUT_JSON;
      outs[i].json = payload;
    }
    wire::write_outputs(w, outs);
  };
}

TEST(OutputArenaTest, ReusedUntilOutgrownAndTheSnapshotIsACopy) {
  wire::OutputArena arena;
  wire::OutputSnapshot snap;
  auto a = arena.write(json_outputs(2, "\"small\""));
  ASSERT_TRUE(a.ok()) << a.status().to_string();
  ASSERT_GE(a->new_fd, 0);  // the first write makes the arena
  ASSERT_TRUE(snap.adopt(a->new_fd).ok());
  ASSERT_TRUE(snap.take(a->used).ok());
  std::vector<procam_output> abi;
  ASSERT_TRUE(wire::decode_outputs(snap.data(), snap.size(), abi).ok());
  ASSERT_EQ(abi.size(), 2u);
  EXPECT_STREQ(abi[1].json, "\"small\"");
  const uint64_t cap = arena.capacity();

  // Fits: the same arena, no descriptor to send.
  auto b = arena.write(json_outputs(3, "\"again\""));
  ASSERT_TRUE(b.ok());
  EXPECT_EQ(b->new_fd, -1);
  EXPECT_EQ(arena.capacity(), cap);
  // The views of the first take are the daemon's copy: the worker's new
  // bytes are not in them until the next take.
  EXPECT_STREQ(abi[1].json, "\"small\"");
  ASSERT_TRUE(snap.take(b->used).ok());
  ASSERT_TRUE(wire::decode_outputs(snap.data(), snap.size(), abi).ok());
  ASSERT_EQ(abi.size(), 3u);
  EXPECT_STREQ(abi[2].json, "\"again\"");

  // Outgrown: a new arena (and descriptor), at least 5/4 of the need.
  const std::string big(cap, 'x');
  auto c = arena.write(json_outputs(1, "\"" + big + "\""));
  ASSERT_TRUE(c.ok());
  ASSERT_GE(c->new_fd, 0);
  EXPECT_GE(arena.capacity(), c->used + c->used / 4);
  EXPECT_FALSE(snap.take(c->used).ok());  // beyond the adopted arena: refused
  ASSERT_TRUE(snap.adopt(c->new_fd).ok());
  ASSERT_TRUE(snap.take(c->used).ok());
  ASSERT_TRUE(wire::decode_outputs(snap.data(), snap.size(), abi).ok());
  ASSERT_EQ(abi.size(), 1u);
  EXPECT_EQ(std::string(abi[0].json).size(), cap + 2);
}

TEST(OutputArenaTest, RefusesWhatItCouldLosePagesOfOrIsSparse) {
  wire::OutputSnapshot snap;
  EXPECT_FALSE(snap.take(16).ok());  // no arena yet
  // Not sealed against shrinking: the sender could truncate it under us (SIGBUS).
  wire::UniqueFd plain(::memfd_create("t", MFD_CLOEXEC | MFD_ALLOW_SEALING));
  ASSERT_EQ(::ftruncate(plain.get(), 4096), 0);
  ASSERT_EQ(::write(plain.get(), std::string(4096, 'a').data(), 4096), 4096);
  Status st = snap.adopt(plain.get());
  EXPECT_EQ(st.code(), Code::corrupt_data);
  EXPECT_NE(st.message().find("shrinking"), std::string::npos) << st.message();
  // Sealed but sparse (1 GiB of holes): this process would allocate what it reads.
  wire::UniqueFd sparse(::memfd_create("t", MFD_CLOEXEC | MFD_ALLOW_SEALING));
  ASSERT_EQ(::ftruncate(sparse.get(), off_t{1} << 30), 0);
  ASSERT_EQ(::fcntl(sparse.get(), F_ADD_SEALS, F_SEAL_SHRINK), 0);
  st = snap.adopt(sparse.get());
  EXPECT_EQ(st.code(), Code::corrupt_data);
  EXPECT_NE(st.message().find("sparse"), std::string::npos) << st.message();
  EXPECT_FALSE(snap.has_arena());
  // A good one, then a size beyond it and a size of 0.
  ASSERT_EQ(::fcntl(plain.get(), F_ADD_SEALS, F_SEAL_SHRINK), 0);
  ASSERT_TRUE(snap.adopt(plain.get()).ok());
  EXPECT_TRUE(snap.take(4096).ok());
  EXPECT_FALSE(snap.take(4097).ok());
  EXPECT_FALSE(snap.take(0).ok());
}

// A plugin thread overwrites the worker's output arena, starting 100 ms
// after get_outputs, for about a second: the outputs the daemon returned are
// the plugin's reply (the fixture's closed-form values), before and after.
// With reuse on the worker keeps a writable arena (the daemon's copy
// protects the client); with reuse off the outputs travel in a sealed blob
// and no writable outputs mapping is left in the worker at all.
void scribble_scan(uint32_t max_idle_workers) {
  const fs::path scratch = fs::temp_directory_path() / ("procam-arena-test-" + std::to_string(::getpid()));
  fs::remove_all(scratch);
  fs::create_directories(scratch);
  PluginHost host;
  ASSERT_TRUE(host.load_file(std::string(PROCAM_FAULTS_FIXTURE_DIR) + "/faults.so").ok());
  IsolationOptions iso;
  iso.scratch_parent = scratch.string();
  iso.max_idle_workers = max_idle_workers;
  host.set_isolation(iso);
  {
    auto s = host.create_session("faults", "scribble", "{}", "{}");
    ASSERT_TRUE(s.ok()) << s.status().to_string();
    ASSERT_TRUE(s->isolated());
    Image frame(4, 3, PixelType::u8);
    for (size_t i = 0; i < 12; ++i) frame.ptr<uint8_t>()[i] = 7;
    auto plan = s->next_plan();
    ASSERT_TRUE(plan.ok() && plan->has_value());
    for (uint32_t i = 0; i < 3; ++i) ASSERT_TRUE(s->add_frame(i, frame.view()).ok());
    ASSERT_TRUE(s->end_round().ok());
    auto done = s->next_plan();
    ASSERT_TRUE(done.ok() && !done->has_value());
    auto outs = s->outputs();
    ASSERT_TRUE(outs.ok()) << outs.status().to_string();
    // What the returned views show, checked against the fixture's values.
    auto check = [&](const char* when) {
      ASSERT_EQ(outs->size(), 4u) << when;
      const Output& sum = (*outs)[0];
      EXPECT_EQ(sum.name, "frame_sum") << when;
      EXPECT_DOUBLE_EQ(sum.scalar, 3 * 12 * 7.0) << when;
      const Output& img = (*outs)[1];
      ASSERT_EQ(img.image.width, 2u);
      const auto* px = static_cast<const float*>(img.image.data);
      EXPECT_EQ(px[0], 1.0f) << when;
      EXPECT_EQ(px[1], 2.0f) << when;
      EXPECT_EQ(px[2], 3.0f) << when;
      EXPECT_TRUE(std::isnan(px[3])) << when;
      const Output& pts = (*outs)[2];
      ASSERT_EQ(pts.point_count, 2u);
      for (int i = 0; i < 8; ++i) EXPECT_EQ(pts.points[i], static_cast<float>(i)) << when << " point float " << i;
      EXPECT_EQ(std::string((*outs)[3].json), "{\"frames\": 3}") << when;
    };
    check("at once");
    // Wait until the plugin has overwritten the arena at least once (it
    // says so in its scratch folder), so this test cannot pass vacuously.
    fs::path marker;
    const char* expect = max_idle_workers > 0 ? "scribbled" : "no-arena";
    for (int i = 0; i < 500 && marker.empty(); ++i) {
      for (const auto& d : fs::directory_iterator(scratch))
        for (const char* name : {"scribbled", "no-arena"})
          if (fs::exists(d.path() / name)) marker = d.path() / name;
      if (marker.empty()) std::this_thread::sleep_for(10ms);
    }
    ASSERT_FALSE(marker.empty()) << "the plugin's scribbler did not run within 5 s";
    EXPECT_EQ(marker.filename().string(), expect);
    std::this_thread::sleep_for(100ms);  // and it keeps scribbling meanwhile
    check("after the plugin overwrote its arena");
    // A second outputs() call returns the same copy, not a new read.
    auto again = s->outputs();
    ASSERT_TRUE(again.ok());
    EXPECT_EQ((*again)[1].image.data, (*outs)[1].image.data);
    check("after a second outputs() call");
  }
  fs::remove_all(scratch);
}

TEST(OutputArenaTest, ScribblingOnTheArenaAfterTheReplyChangesNothingReturned) { scribble_scan(1); }

TEST(OutputArenaTest, WithoutReuseNoWritableOutputsMappingIsLeftInTheWorker) { scribble_scan(0); }

}  // namespace
}  // namespace procam::host
