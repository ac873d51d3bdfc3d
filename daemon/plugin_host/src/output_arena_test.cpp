// SPDX-License-Identifier: MIT
// The output arena (output_arena.hpp): outputs written into one reused
// shared-memory arena per worker and copied by the daemon before it decodes
// them, or, when the worker is frozen, read in place. A worker that
// scribbles on the arena after its reply cannot change what the daemon
// returned; the daemon refuses arenas it could lose pages
// of (not sealed against shrinking), sparse arenas, and sizes beyond them.
#include <gtest/gtest.h>
#include <fcntl.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <linux/falloc.h>
#include <sys/mman.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <csignal>
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

// The state letter of /proc/<pid>/stat ('T' stopped, 'Z' zombie), or 0 if
// the process is gone.
char proc_state(int pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const size_t paren = text.rfind(')');
  return paren == std::string::npos || paren + 2 >= text.size() ? 0 : text[paren + 2];
}

// The name of the mapping of this process that holds `p` (the last field
// of /proc/self/maps: "/memfd:procam-outputs-heap (deleted)", ...), or "".
std::string mapping_of(const void* p) {
  std::ifstream maps("/proc/self/maps");
  const auto at = reinterpret_cast<uintptr_t>(p);
  for (std::string line; std::getline(maps, line);) {
    unsigned long lo = 0, hi = 0;
    if (std::sscanf(line.c_str(), "%lx-%lx", &lo, &hi) != 2 || at < lo || at >= hi) continue;
    const size_t slash = line.find('/');
    return slash == std::string::npos ? "[anonymous]" : line.substr(slash);
  }
  return "";
}

// A shared heap as the worker makes one: a sparse memfd of `size` bytes,
// sealed against resizing, and the worker's read-write mapping of it.
void make_heap(size_t size, int& fd, wire::Mapping& worker_view) {
  fd = ::memfd_create("procam-outputs-heap", MFD_CLOEXEC | MFD_ALLOW_SEALING);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(::ftruncate(fd, static_cast<off_t>(size)), 0);
  ASSERT_EQ(::fcntl(fd, F_ADD_SEALS, F_SEAL_SHRINK | F_SEAL_GROW | F_SEAL_SEAL), 0);
  void* p = ::mmap(nullptr, size, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
  ASSERT_NE(p, MAP_FAILED);
  worker_view = wire::Mapping(p, size);
}

// The worker's shared heap, daemon side: adopted only sealed against
// resizing; a reference resolves in place to the heap's own bytes only when
// every page of its range was written (a hole would make the daemon
// allocate what it reads) and it lies inside the heap; copied, it resolves
// to private memory holding the same bytes.
TEST(OutputArenaTest, SharedHeapReferencesAreCheckedAndResolved) {
  const size_t size = size_t{4} << 20;
  wire::OutputSnapshot snap;
  {
    const int loose = ::memfd_create("procam-outputs-heap", MFD_CLOEXEC | MFD_ALLOW_SEALING);
    ASSERT_GE(loose, 0);
    ASSERT_EQ(::ftruncate(loose, static_cast<off_t>(size)), 0);
    ASSERT_EQ(::fcntl(loose, F_ADD_SEALS, F_SEAL_SHRINK), 0);  // may still grow
    const Status st = snap.adopt_heap(loose);
    EXPECT_FALSE(st.ok());
    EXPECT_NE(st.message().find("sealed against resizing"), std::string::npos) << st.message();
    ::close(loose);
    EXPECT_FALSE(snap.has_heap());
  }
  int fd = -1;
  wire::Mapping worker_view;
  ASSERT_NO_FATAL_FAILURE(make_heap(size, fd, worker_view));
  // The worker writes [1 MiB, 1 MiB + 64 KiB); the rest stays sparse.
  auto* w = worker_view.mutable_data();
  for (size_t i = 0; i < 65536; ++i) w[(1 << 20) + i] = static_cast<uint8_t>(i * 7);
  ASSERT_TRUE(snap.adopt_heap(fd).ok());
  ::close(fd);  // the snapshot keeps its own descriptor
  ASSERT_TRUE(snap.has_heap());
  std::string why;
  auto in_place = snap.heap_in_place();
  const uint8_t* r = in_place(1 << 20, 65536, why);
  ASSERT_NE(r, nullptr) << why;
  EXPECT_EQ(r[65535], static_cast<uint8_t>(65535 * 7));
  EXPECT_EQ(mapping_of(r).find("procam-outputs-heap") != std::string::npos, true) << mapping_of(r);
  // One page past the written range: a hole.
  why.clear();
  EXPECT_EQ(in_place(1 << 20, 65536 + 4096, why), nullptr);
  EXPECT_NE(why.find("unwritten"), std::string::npos) << why;
  why.clear();
  EXPECT_EQ(in_place(0, 4096, why), nullptr);
  EXPECT_NE(why.find("unwritten"), std::string::npos) << why;
  why.clear();
  EXPECT_EQ(in_place(size - 64, 128, why), nullptr);
  EXPECT_NE(why.find("byte shared heap"), std::string::npos) << why;
  why.clear();
  EXPECT_EQ(in_place(~uint64_t{0} - 10, 64, why), nullptr);  // no wrap-around
  auto copied = snap.heap_copied();
  const uint8_t* c = copied(1 << 20, 65536, why);
  ASSERT_NE(c, nullptr) << why;
  EXPECT_NE(c, r);
  EXPECT_EQ(std::memcmp(c, r, 65536), 0);
  // The worker writing afterwards changes the heap, not the copy.
  w[(1 << 20) + 5] ^= 0xff;
  EXPECT_NE(c[5], r[5]);
}

// A worker whose sandbox denies removing pages (hello's kSandboxPagesStay,
// set_pages_stay) gets each heap page checked once: a range checked before
// resolves without a check, a range with a page never checked is checked
// as before. The test plays the forbidden part: it punches a hole into
// checked pages, which only a worker without that rule could do. Without
// pages_stay the same hole is found.
TEST(OutputArenaTest, HeapPagesCheckedOnceWhereTheWorkerCannotRemoveThem) {
  const size_t size = size_t{1} << 20;
  for (const bool stay : {false, true}) {
    SCOPED_TRACE(stay ? "pages stay" : "pages may be removed");
    wire::OutputSnapshot snap;
    snap.set_pages_stay(stay);
    int fd = -1;
    wire::Mapping worker_view;
    ASSERT_NO_FATAL_FAILURE(make_heap(size, fd, worker_view));
    std::memset(worker_view.mutable_data(), 9, 65536);  // pages 0..15 written
    ASSERT_TRUE(snap.adopt_heap(fd).ok());
    auto in_place = snap.heap_in_place();
    std::string why;
    ASSERT_NE(in_place(0, 32768, why), nullptr) << why;  // pages 0..7 checked
    ASSERT_EQ(::fallocate(fd, FALLOC_FL_PUNCH_HOLE | FALLOC_FL_KEEP_SIZE, 4096, 4096), 0);  // page 1
    why.clear();
    const uint8_t* again = in_place(0, 32768, why);
    if (stay) {
      EXPECT_NE(again, nullptr) << why;  // not checked again
    } else {
      EXPECT_EQ(again, nullptr);
      EXPECT_NE(why.find("unwritten"), std::string::npos) << why;
    }
    // Pages 0..15, half of them never checked: checked now, and the hole found.
    why.clear();
    EXPECT_EQ(in_place(0, 65536, why), nullptr);
    EXPECT_NE(why.find("unwritten"), std::string::npos) << why;
    ::close(fd);
  }
}

// The scribbler's marker in any worker scratch folder under `scratch`, or "".
fs::path find_marker(const fs::path& scratch) {
  std::error_code ec;
  for (const auto& d : fs::directory_iterator(scratch, ec))
    for (const char* name : {"scribbled", "no-arena"})
      if (fs::exists(d.path() / name, ec)) return d.path() / name;
  return {};
}

fs::path wait_for_marker(const fs::path& scratch) {
  fs::path marker;
  for (int i = 0; i < 500 && marker.empty(); ++i) {
    marker = find_marker(scratch);
    if (marker.empty()) std::this_thread::sleep_for(10ms);
  }
  return marker;
}

enum class Arena { frozen, copied, none };

// An empty scratch parent for one test (name + pid), and the faults fixture
// loaded into `host` with `iso` pointed at that scratch parent.
fs::path fresh_scratch(const std::string& name) {
  const fs::path scratch = fs::temp_directory_path() / (name + std::to_string(::getpid()));
  fs::remove_all(scratch);
  fs::create_directories(scratch);
  return scratch;
}
void load_faults(PluginHost& host, IsolationOptions& iso, const fs::path& scratch) {
  ASSERT_TRUE(host.load_file(std::string(PROCAM_FAULTS_FIXTURE_DIR) + "/faults.so").ok());
  iso.scratch_parent = scratch.string();
}

// A plugin thread overwrites the worker's output arena, starting 100 ms
// after get_outputs, for about a second (it marks every pass in its scratch
// folder): the outputs the daemon returned are the plugin's reply (the
// fixture's closed-form values), before and after.
//  - frozen (reuse on, the default): the daemon stops the worker after the
//    reply and hands out views into the arena; the scribbler cannot run while
//    the session lives (no mark for 400 ms, the worker's state is 'T'), and
//    runs once the session is gone: the client's own copy of the outputs,
//    made while it held them, still shows the reply.
//  - copied (reuse on, freeze_outputs off): the worker keeps running and
//    scribbles while the client holds the outputs; the daemon's copy
//    protects them.
//  - none (reuse off): the outputs travel in a sealed blob and no writable
//    outputs mapping is left in the worker at all.
void scribble_scan(Arena mode) {
  const fs::path scratch = fresh_scratch("procam-arena-test-");
  PluginHost host;
  IsolationOptions iso;
  ASSERT_NO_FATAL_FAILURE(load_faults(host, iso, scratch));
  iso.max_idle_workers = mode == Arena::none ? 0 : 1;
  iso.freeze_outputs = mode == Arena::frozen;
  host.set_isolation(iso);
  std::vector<float> client_copy;  // what a client saved (a result file) while it held the outputs
  std::vector<float> big_copy;
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
      ASSERT_EQ(outs->size(), 5u) << when;
      const Output& big = (*outs)[4];
      EXPECT_EQ(big.name, "heap_image") << when;
      ASSERT_EQ(big.image.width, 512u);
      ASSERT_EQ(big.image.height, 512u);
      const auto* bp = static_cast<const float*>(big.image.data);
      size_t wrong = 0;
      for (size_t i = 0; i < 512 * 512; ++i) wrong += bp[i] != static_cast<float>(i % 251);
      EXPECT_EQ(wrong, 0u) << when << ": heap_image pixels changed";
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
    // Where the big map is read from: frozen, the worker's shared heap
    // itself (no copy anywhere); copied, the daemon's private copy; without
    // reuse, the sealed blob.
    const std::string where = mapping_of((*outs)[4].image.data);
#if !defined(__SANITIZE_ADDRESS__)  // an ASan worker has no shared heap
    if (mode == Arena::frozen) {
      EXPECT_NE(where.find("procam-outputs-heap"), std::string::npos) << where;
    }
#endif
    if (mode == Arena::copied) {
      EXPECT_EQ(where.find("procam-outputs"), std::string::npos) << where;
    }
    if (mode == Arena::none) {
      EXPECT_NE(where.find("procam-outputs-blob"), std::string::npos) << where;
    }
    if (mode == Arena::frozen) {
      // Stopped, and the scribbler (due 100 ms after the reply) cannot run.
      EXPECT_EQ(proc_state(s->worker_pid()), 'T') << "the worker is not stopped while its outputs are held";
      std::this_thread::sleep_for(400ms);
      EXPECT_TRUE(find_marker(scratch).empty()) << "the plugin ran while the client held its outputs";
      EXPECT_EQ(proc_state(s->worker_pid()), 'T');
      check("400 ms later");
    } else {
      // Wait until the plugin has overwritten the arena at least once (it
      // says so in its scratch folder), so this test cannot pass vacuously.
      const fs::path marker = wait_for_marker(scratch);
      ASSERT_FALSE(marker.empty()) << "the plugin's scribbler did not run within 5 s";
      EXPECT_EQ(marker.filename().string(), mode == Arena::copied ? "scribbled" : "no-arena");
      std::this_thread::sleep_for(100ms);  // and it keeps scribbling meanwhile
      check("after the plugin overwrote its arena");
    }
    // A second outputs() call returns the same views, not a new read.
    auto again = s->outputs();
    ASSERT_TRUE(again.ok());
    EXPECT_EQ((*again)[1].image.data, (*outs)[1].image.data);
    check("after a second outputs() call");
    // stop() after the outputs needs nothing from a frozen worker.
    EXPECT_TRUE(s->stop().ok());
    const auto* px = static_cast<const float*>((*outs)[1].image.data);
    client_copy.assign(px, px + 4);
    client_copy.insert(client_copy.end(), (*outs)[2].points, (*outs)[2].points + 8);
    const auto* bp = static_cast<const float*>((*outs)[4].image.data);
    big_copy.assign(bp, bp + 512 * 512);
  }
  if (mode == Arena::frozen) {
    // The session is gone: the worker was resumed (and kept for reuse), and
    // now the plugin does scribble over its arena -- after the fact.
    const fs::path marker = wait_for_marker(scratch);
    ASSERT_FALSE(marker.empty()) << "the plugin's scribbler did not run after the session ended";
    EXPECT_EQ(marker.filename().string(), "scribbled");
  }
  ASSERT_EQ(client_copy.size(), 12u);
  EXPECT_EQ(client_copy[0], 1.0f);
  EXPECT_EQ(client_copy[1], 2.0f);
  EXPECT_EQ(client_copy[2], 3.0f);
  EXPECT_TRUE(std::isnan(client_copy[3]));
  for (size_t i = 0; i < 8; ++i) EXPECT_EQ(client_copy[4 + i], static_cast<float>(i));
  ASSERT_EQ(big_copy.size(), 512u * 512u);
  size_t wrong = 0;
  for (size_t i = 0; i < big_copy.size(); ++i) wrong += big_copy[i] != static_cast<float>(i % 251);
  EXPECT_EQ(wrong, 0u);
  fs::remove_all(scratch);
}

TEST(OutputArenaTest, ScribblingOnTheArenaAfterTheReplyChangesNothingReturned) { scribble_scan(Arena::frozen); }

TEST(OutputArenaTest, ScribblingWhileTheDaemonCopiesChangesNothingReturned) { scribble_scan(Arena::copied); }

TEST(OutputArenaTest, WithoutReuseNoWritableOutputsMappingIsLeftInTheWorker) { scribble_scan(Arena::none); }

// A frozen worker belongs to its session: another session of the same
// plugin gets another worker while the first holds its outputs; the frozen
// one is resumed and reused afterwards.
TEST(OutputArenaTest, AFrozenWorkerIsNotHandedAnotherScan) {
  const fs::path scratch = fresh_scratch("procam-arena-test2-");
  PluginHost host;
  IsolationOptions iso;
  ASSERT_NO_FATAL_FAILURE(load_faults(host, iso, scratch));
  iso.max_idle_workers = 2;
  host.set_isolation(iso);
  Image frame(4, 3, PixelType::u8);
  for (size_t i = 0; i < 12; ++i) frame.ptr<uint8_t>()[i] = 7;
  auto scan = [&](Session& s) {
    auto plan = s.next_plan();
    ASSERT_TRUE(plan.ok() && plan->has_value());
    for (uint32_t i = 0; i < 3; ++i) ASSERT_TRUE(s.add_frame(i, frame.view()).ok());
    ASSERT_TRUE(s.end_round().ok());
    auto done = s.next_plan();
    ASSERT_TRUE(done.ok() && !done->has_value());
    auto outs = s.outputs();
    ASSERT_TRUE(outs.ok()) << outs.status().to_string();
    EXPECT_DOUBLE_EQ((*outs)[0].scalar, 3 * 12 * 7.0);
  };
  int first_pid = -1;
  {
    auto a = host.create_session("faults", "ok", "{}", "{}");
    ASSERT_TRUE(a.ok());
    scan(*a);
    first_pid = a->worker_pid();
    ASSERT_EQ(proc_state(first_pid), 'T');
    auto b = host.create_session("faults", "ok", "{}", "{}");
    ASSERT_TRUE(b.ok());
    EXPECT_NE(b->worker_pid(), first_pid);
    scan(*b);
    EXPECT_EQ(proc_state(first_pid), 'T');  // still frozen: a's outputs are still held
  }
  // Both were resumed and went idle (b first, then a): the next session
  // takes the most recently used, a's, which serves it after its freeze.
  EXPECT_NE(proc_state(first_pid), 'T');
  auto c = host.create_session("faults", "ok", "{}", "{}");
  ASSERT_TRUE(c.ok());
  EXPECT_EQ(c->worker_pid(), first_pid);
  scan(*c);
  EXPECT_EQ(proc_state(first_pid), 'T');
  fs::remove_all(scratch);
}

// A frozen worker still ends: killed when its session cannot be reused (its
// PluginHost is gone), and killed by its parent-death signal when the daemon
// dies without cleaning up (a stopped process reads no EOF).
TEST(OutputArenaTest, AFrozenWorkerEndsWhenKilledAndWhenTheDaemonDies) {
  // The death test's child re-runs this test in a new process: it takes the
  // parent's folder from the environment.
  const char* inherited = std::getenv("PROCAM_TEST_ARENA_DIR");
  const fs::path scratch = inherited != nullptr ? fs::path(inherited)
                                                : fs::temp_directory_path() /
                                                      ("procam-arena-test3-" + std::to_string(::getpid()));
  ::setenv("PROCAM_TEST_ARENA_DIR", scratch.c_str(), 1);
  const fs::path pid_file = scratch / "worker.pid";
  auto frozen_session = [&](PluginHost& host) -> Result<Session> {
    IsolationOptions iso;
    iso.scratch_parent = scratch.string();
    iso.max_idle_workers = 1;
    host.set_isolation(iso);
    auto s = host.create_session("faults", "ok", "{}", "{}");
    if (!s) return s.status();
    Image frame(4, 3, PixelType::u8);
    if (!s->next_plan().ok()) return Error(Code::internal, "next_plan");
    for (uint32_t i = 0; i < 3; ++i)
      if (!s->add_frame(i, frame.view()).ok()) return Error(Code::internal, "add_frame");
    if (!s->end_round().ok() || !s->next_plan().ok() || !s->outputs().ok()) return Error(Code::internal, "scan");
    return std::move(*s);
  };
  fs::remove_all(scratch);
  fs::create_directories(scratch);
  {
    auto host = std::make_unique<PluginHost>();
    ASSERT_TRUE(host->load_file(std::string(PROCAM_FAULTS_FIXTURE_DIR) + "/faults.so").ok());
    int pid = -1;
    {
      auto s = frozen_session(*host);
      ASSERT_TRUE(s.ok()) << s.status().to_string();
      pid = s->worker_pid();
      ASSERT_EQ(proc_state(pid), 'T');
      host.reset();  // the session outlives its host: its worker is killed, not kept
    }
    EXPECT_EQ(proc_state(pid), 0) << "a frozen worker survived the end of its session";
  }
  // The daemon dies (SIGKILL) while its worker is frozen: a child process
  // (a fresh re-run of this test binary, gtest's threadsafe death test)
  // plays the daemon and writes its worker's pid first. This process is
  // made a subreaper, so the orphaned worker becomes its child: a parent in
  // the same session, as under a container's init, so the kernel's
  // orphaned-process-group SIGHUP + SIGCONT does not come (it would end the
  // worker under systemd or a shell that exits); only the worker's
  // parent-death signal ends it. And this process can reap it and see how.
  const std::string old_style = GTEST_FLAG_GET(death_test_style);
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  ASSERT_EQ(::prctl(PR_SET_CHILD_SUBREAPER, 1), 0);
  EXPECT_EXIT(
      {
        PluginHost host;
        if (!host.load_file(std::string(PROCAM_FAULTS_FIXTURE_DIR) + "/faults.so").ok()) std::_Exit(3);
        auto s = frozen_session(host);
        if (!s.ok() || proc_state(s->worker_pid()) != 'T') std::_Exit(4);
        std::ofstream(pid_file) << s->worker_pid() << "\n";
        ::raise(SIGKILL);
      },
      ::testing::KilledBySignal(SIGKILL), "");
  int pid = 0;
  std::ifstream(pid_file) >> pid;
  EXPECT_GT(pid, 0);
  int st = 0;
  pid_t reaped = 0;
  for (int i = 0; pid > 0 && i < 500 && reaped == 0; ++i) {
    reaped = ::waitpid(pid, &st, WNOHANG);
    if (reaped == 0) std::this_thread::sleep_for(10ms);
  }
  ::prctl(PR_SET_CHILD_SUBREAPER, 0);
  GTEST_FLAG_SET(death_test_style, old_style);
  EXPECT_EQ(reaped, pid) << "the frozen worker of a dead daemon is still there (state " << proc_state(pid) << ")";
  if (reaped == pid) {
    EXPECT_TRUE(WIFSIGNALED(st) && WTERMSIG(st) == SIGKILL) << "status " << st;
  }
  if (pid > 0 && reaped == 0) {
    ::kill(pid, SIGKILL);
    ::waitpid(pid, &st, 0);
  }
  ::unsetenv("PROCAM_TEST_ARENA_DIR");
  fs::remove_all(scratch);
}

}  // namespace
}  // namespace procam::host
