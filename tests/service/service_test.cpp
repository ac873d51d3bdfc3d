// SPDX-License-Identifier: MIT
// procamd as a service (issue 6), against real daemons on private ipc://
// endpoints: bounded queue and "busy", cancel, idempotent retries, ping and
// prompt status while scanning, a 50-client load test, kill -9 and restart,
// retention, CURVE allowlist, plugin-file permissions, result-path escapes,
// oversized and malformed messages.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>

#include <atomic>
#include <cstdio>
#include <fstream>
#include <map>
#include <mutex>
#include <set>

#include "service_fixture.hpp"

namespace procam::testing {
namespace {

using json = nlohmann::json;
using namespace std::chrono_literals;

// ---- Queue, cancel, retries, liveness ---------------------------------------

TEST(ServiceQueue, FullQueueSaysBusyWithCountAndCancelWorksQueuedAndRunning) {
  ConfigOptions o;
  o.tiny_rig = false;  // full-size scans (~1 s) so the queue stays occupied
  o.max_queue = 2;
  ServiceDaemon sd(o);
  ASSERT_TRUE(sd.d->wait_ready()) << sd.d->log();
  client::Client c(sd.endpoint(), 20s);
  std::vector<std::string> ids;
  auto first = c.call(tiny_scan("plane", "q0"));
  ASSERT_TRUE(first.ok()) << first.status().to_string();
  ids.push_back((*first)["scan_id"]);
  for (int i = 0; i < 500; ++i) {  // until the worker has taken it
    auto st = c.call(proto::StatusQuery{});
    if (st && (*st)["daemon"]["state"] == "scanning") break;
    std::this_thread::sleep_for(2ms);
  }
  Status busy;
  for (int i = 1; i < 5 && busy.ok(); ++i) {
    auto r = c.call(tiny_scan("plane", "q" + std::to_string(i)));
    if (r) ids.push_back((*r)["scan_id"]);
    else busy = r.status();
  }
  ASSERT_FALSE(busy.ok()) << "5 scans never filled a queue of 2";
  EXPECT_EQ(busy.code(), Code::unavailable);
  EXPECT_NE(busy.message().find("busy: 3 scans ahead of you"), std::string::npos) << busy.to_string();
  ASSERT_EQ(ids.size(), 3u);

  // Cancel the last queued one: final at once.
  auto cq = c.call(proto::Cancel{ids[2]});
  ASSERT_TRUE(cq.ok()) << cq.status().to_string();
  EXPECT_EQ((*cq)["previous_state"], "queued");
  EXPECT_EQ((*cq)["state"], "failed");
  // Cancel the running one: it stops before its next frame.
  auto cr = c.call(proto::Cancel{ids[0]});
  ASSERT_TRUE(cr.ok()) << cr.status().to_string();
  auto fin = wait_final(c, ids[0]);
  ASSERT_FALSE(fin.is_null());
  EXPECT_EQ(fin["state"], "failed");
  EXPECT_EQ(fin["error"]["code"], "cancelled");
  auto m = c.call(proto::ResultQuery{ids[2]});
  ASSERT_TRUE(m.ok());
  EXPECT_EQ((*m)["manifest"]["error"]["code"], "cancelled");
  EXPECT_NE((*m)["manifest"]["error"]["message"].get<std::string>().find("cancelled by a client"), std::string::npos);
  // The middle one still runs to the end; cancelling a finished scan is refused.
  auto mid = wait_final(c, ids[1]);
  EXPECT_EQ(mid["state"], "done") << mid.dump();
  auto again = c.call(proto::Cancel{ids[1]});
  ASSERT_FALSE(again.ok());
  EXPECT_EQ(again.status().code(), Code::failed_precondition);
  auto unknown = c.call(proto::Cancel{"no-such-scan"});
  EXPECT_EQ(unknown.status().code(), Code::not_found);
  auto st = c.call(proto::StatusQuery{});
  ASSERT_TRUE(st.ok());
  EXPECT_EQ((*st)["daemon"]["metrics"]["scans_cancelled"], 2);
  EXPECT_EQ((*st)["daemon"]["metrics"]["scans_rejected_busy"], 1);
  EXPECT_EQ(sd.d->stop(), 0) << sd.d->log();
}

TEST(ServiceQueue, RetriedScanWithSameIdRunsOnce) {
  ServiceDaemon sd;
  ASSERT_TRUE(sd.d->wait_ready()) << sd.d->log();
  client::Client a(sd.endpoint(), 20s);
  const std::string id = a.new_request_id();
  auto first = a.call_with_id(id, tiny_scan("plane", "retry"));
  ASSERT_TRUE(first.ok()) << first.status().to_string();
  EXPECT_FALSE(first->contains("duplicate"));
  // The "retry" from a new socket (as after a timeout): same id, same content.
  client::Client b(sd.endpoint(), 20s);
  auto second = b.call_with_id(id, tiny_scan("plane", "retry"));
  ASSERT_TRUE(second.ok()) << second.status().to_string();
  EXPECT_EQ((*second)["scan_id"], (*first)["scan_id"]);
  EXPECT_EQ((*second)["duplicate"], true);
  // Same id, other content: a new scan.
  auto other = b.call_with_id(id, tiny_scan("tilted-box", "retry"));
  ASSERT_TRUE(other.ok());
  EXPECT_NE((*other)["scan_id"], (*first)["scan_id"]);
  // After it finished, a retry still names it (state done), not a new scan.
  ASSERT_FALSE(wait_final(a, (*first)["scan_id"]).is_null());
  auto late = a.call_with_id(id, tiny_scan("plane", "retry"));
  ASSERT_TRUE(late.ok());
  EXPECT_EQ((*late)["scan_id"], (*first)["scan_id"]);
  EXPECT_EQ((*late)["state"], "done");
  wait_final(a, (*other)["scan_id"]);
  auto st = a.call(proto::StatusQuery{});
  EXPECT_EQ((*st)["daemon"]["scans"]["done"], 2) << st->dump();
}

TEST(ServiceQueue, PingAndStatusAnswerPromptlyWhileAScanRuns) {
  ConfigOptions o;
  o.tiny_rig = false;
  ServiceDaemon sd(o);
  ASSERT_TRUE(sd.d->wait_ready()) << sd.d->log();
  client::Client c(sd.endpoint(), 20s);
  auto r = c.call(tiny_scan("tilted-box"));
  ASSERT_TRUE(r.ok());
  const std::string id = (*r)["scan_id"];
  std::vector<double> ms;
  bool saw_running = false;
  for (int i = 0; i < 2000; ++i) {
    auto t0 = std::chrono::steady_clock::now();
    auto st = c.call(i % 2 ? proto::RequestBody{proto::Ping{}} : proto::RequestBody{proto::StatusQuery{}});
    ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    ASSERT_TRUE(st.ok()) << st.status().to_string();
    if (i % 2 == 0 && (*st)["daemon"]["state"] == "scanning") saw_running = true;
    auto s = c.call(proto::StatusQuery{id});
    ASSERT_TRUE(s.ok()) << s.status().to_string();
    const std::string state = (*s)["scan"]["state"];
    if (state != "queued") {  // where it is, from its first moment (never null once started)
      EXPECT_TRUE((*s)["scan"]["progress"].is_object()) << state << ": " << (*s)["scan"].dump();
    }
    if (state == "done" || state == "failed") break;
  }
  EXPECT_TRUE(saw_running);
  const double p50 = percentile(ms, 50), p99 = percentile(ms, 99);
  std::printf("status/ping while scanning: n=%zu p50=%.3f ms p99=%.3f ms\n", ms.size(), p50, p99);
  ::testing::Test::RecordProperty("status_p99_us", static_cast<int>(p99 * 1000));
  EXPECT_LT(p99, 250.0);  // generous: ctest runs other suites beside this one on 2 cores
  EXPECT_EQ(wait_final(c, id)["state"], "done");
}

TEST(ServiceQueue, EventsReportProgressAndFinalState) {
  ServiceDaemon sd;
  ASSERT_TRUE(sd.d->wait_ready()) << sd.d->log();
  client::Client c(sd.endpoint(), 20s);
  int progress = 0, states = 0;
  uint64_t last_seq = 0;
  bool ordered = true, first = true;
  std::string seen;  // every event, for the failure message
  auto fin = c.scan(tiny_scan(), [&](const proto::Event& e) {
    progress += e.event == "progress";
    states += e.event == "state";
    seen += std::to_string(e.seq) + ":" + e.event + (e.event == "state" ? "=" + e.body.value("state", "") : "") + " ";
    if (!first && e.seq <= last_seq) ordered = false;
    first = false;
    last_seq = e.seq;
  });
  ASSERT_TRUE(fin.ok()) << fin.status().to_string();
  EXPECT_EQ((*fin)["state"], "done");
  EXPECT_GT(progress, 5) << seen;
  EXPECT_GE(states, 3) << seen;
  EXPECT_TRUE(ordered) << seen;
}

// A client whose queue is full when its scan runs (here: stuffed with large
// fetch replies it has not read yet) still gets every state event, in order,
// once it reads: events wait in a per-client backlog instead of being dropped
// (the CI failure of 2026-11-23 lost "writing" on a loaded machine), and
// progress events coalesce there to the newest.
TEST(ServiceQueue, StateEventsWaitForASlowClientInsteadOfBeingDropped) {
  ServiceDaemon sd;
  ASSERT_TRUE(sd.d->wait_ready()) << sd.d->log();
  client::Client c(sd.endpoint(), 30s);
  auto fin = c.scan(tiny_scan(), nullptr);
  ASSERT_TRUE(fin.ok()) << fin.status().to_string();
  const std::string first_id = (*fin)["scan_id"];
  auto m = c.call(proto::ResultQuery{first_id});
  ASSERT_TRUE(m.ok());
  std::string big;
  uint64_t big_size = 0;
  for (const auto& f : (*m)["manifest"]["files"]) {
    if (f.value("size_bytes", uint64_t{0}) > big_size) {
      big_size = f["size_bytes"];
      big = f["name"];
    }
  }
  ASSERT_GE(big_size, uint64_t{16} << 10) << "need a result file of some size; largest is " << big;

  zmq::context_t ctx;
  zmq::socket_t slow(ctx, zmq::socket_type::dealer);
  slow.set(zmq::sockopt::linger, 0);
  slow.set(zmq::sockopt::rcvhwm, 1);  // its I/O thread stops reading almost at once
  slow.set(zmq::sockopt::rcvbuf, 16384);
  slow.connect(sd.endpoint());
  auto send = [&](const std::string& body) {
    slow.send(zmq::message_t(), zmq::send_flags::sndmore);
    slow.send(zmq::buffer(body), zmq::send_flags::none);
  };
  // Enough unread bytes to fill the daemon's queue and both kernel buffers.
  const int fetches = static_cast<int>(std::max<uint64_t>(40, (uint64_t{8} << 20) / big_size));
  for (int i = 0; i < fetches; ++i)
    send(json{{"procam", 1}, {"id", "f" + std::to_string(i)}, {"type", "fetch"}, {"scan_id", first_id},
              {"file", big}, {"max_bytes", big_size}}.dump());
  proto::Scan s = tiny_scan("tilted-box", "slow-events");
  s.events = true;
  send(proto::encode_request(proto::Request{"slow-scan", s}));
  // Wait (through another client) until that scan is done, not reading `slow`.
  for (int k = 0; k < 600; ++k) {
    auto st = c.call(proto::StatusQuery{});
    ASSERT_TRUE(st.ok()) << st.status().to_string();
    if ((*st)["daemon"]["scans"].value("done", 0) >= 2) break;
    std::this_thread::sleep_for(20ms);
  }
  // Now read everything the daemon sends `slow`.
  slow.set(zmq::sockopt::rcvtimeo, 1500);
  std::vector<std::string> states;
  std::string seen, scan_id;
  uint64_t last_seq = 0;
  bool ordered = true, any = false;
  int progress = 0;
  for (;;) {
    std::vector<zmq::message_t> msg;
    if (!zmq::recv_multipart(slow, std::back_inserter(msg))) break;  // quiet for 1.5 s: all read
    size_t i = 0;
    while (i < msg.size() && msg[i].size() == 0) ++i;
    ASSERT_LT(i, msg.size());
    auto in = proto::decode_incoming(std::string_view(static_cast<const char*>(msg[i].data()), msg[i].size()));
    ASSERT_TRUE(in.ok()) << in.status().to_string();
    auto* ev = std::get_if<proto::Event>(&in->message);
    if (!ev) continue;  // fetch replies (some dropped: that is the reply queue's bound) and the scan's reply
    if (!scan_id.empty()) {
      EXPECT_EQ(ev->scan_id, scan_id);
    }
    scan_id = ev->scan_id;
    if (any && ev->seq <= last_seq) ordered = false;
    any = true;
    last_seq = ev->seq;
    progress += ev->event == "progress";
    if (ev->event == "state") states.push_back(ev->body.value("state", ""));
    seen += std::to_string(ev->seq) + ":" + ev->event + " ";
  }
  EXPECT_NE(scan_id, first_id);
  EXPECT_EQ(states, (std::vector<std::string>{"capturing", "decoding", "writing", "done"})) << seen;
  EXPECT_GE(progress, 1) << seen;
  EXPECT_TRUE(ordered) << seen;
  EXPECT_TRUE(sd.d->alive());
}

// Issue 17 item 8: a client can list the daemon's scans and the rig_options
// (the sim rig's scenes) instead of guessing them.
TEST(ServiceListing, ListScansNewestFirstFilteredAndLimited) {
  ServiceDaemon sd;
  ASSERT_TRUE(sd.d->wait_ready()) << sd.d->log();
  client::Client c(sd.endpoint(), 20s);
  auto empty = c.call(proto::ListScans{});
  ASSERT_TRUE(empty.ok()) << empty.status().to_string();
  EXPECT_TRUE((*empty)["scans"].empty());
  EXPECT_EQ((*empty)["total"], 0);
  std::vector<std::string> ids;
  for (int i = 0; i < 3; ++i) {
    auto fin = c.scan(tiny_scan(i % 2 ? "plane" : "tilted-box", "list " + std::to_string(i)), nullptr);
    ASSERT_TRUE(fin.ok()) << fin.status().to_string();
    ids.push_back((*fin)["scan_id"]);
    std::this_thread::sleep_for(1100ms);  // distinct created_utc seconds
  }
  auto bad = c.call(tiny_scan("no-such-scene"));  // refused: never listed
  EXPECT_FALSE(bad.ok());
  auto all = c.call(proto::ListScans{});
  ASSERT_TRUE(all.ok()) << all.status().to_string();
  ASSERT_EQ((*all)["scans"].size(), 3u) << all->dump();
  EXPECT_EQ((*all)["total"], 3);
  EXPECT_EQ((*all)["truncated"], false);
  for (size_t k = 0; k < 3; ++k) {  // newest first
    EXPECT_EQ((*all)["scans"][k]["scan_id"], ids[2 - k]);
    EXPECT_EQ((*all)["scans"][k]["label"], "list " + std::to_string(2 - k));
  }
  proto::ListScans two;
  two.limit = 2;
  auto lim = c.call(two);
  ASSERT_TRUE(lim.ok());
  EXPECT_EQ((*lim)["scans"].size(), 2u);
  EXPECT_EQ((*lim)["total"], 3);
  EXPECT_EQ((*lim)["truncated"], true);
  proto::ListScans active;
  active.state = "active";
  auto act = c.call(active);
  ASSERT_TRUE(act.ok());
  EXPECT_TRUE((*act)["scans"].empty()) << act->dump();
  proto::ListScans done;
  done.state = "done";
  EXPECT_EQ((*c.call(done))["total"], 3);
  // Bad filters are the client's error, named.
  zmq::context_t ctx;
  zmq::socket_t s(ctx, zmq::socket_type::dealer);
  s.set(zmq::sockopt::linger, 0);
  s.set(zmq::sockopt::rcvtimeo, 5000);
  s.connect(sd.endpoint());
  const std::string b1 = raw_exchange(s, {json{{"procam", 1}, {"id", "l1"}, {"type", "list_scans"}, {"state", "sleeping"}}.dump()});
  EXPECT_NE(b1.find("invalid_argument"), std::string::npos) << b1;
  EXPECT_NE(b1.find("'state'"), std::string::npos) << b1;
  const std::string b2 = raw_exchange(s, {json{{"procam", 1}, {"id", "l2"}, {"type", "list_scans"}, {"limit", 0}}.dump()});
  EXPECT_NE(b2.find("invalid_argument"), std::string::npos) << b2;
}

TEST(ServiceListing, RigOptionsListEverySceneTheRigAccepts) {
  ServiceDaemon sd;
  ASSERT_TRUE(sd.d->wait_ready()) << sd.d->log();
  client::Client c(sd.endpoint(), 20s);
  auto r = c.call(proto::ListRigOptions{});
  ASSERT_TRUE(r.ok()) << r.status().to_string();
  EXPECT_EQ((*r)["rig"], "sim-tiny");
  const json& scene = (*r)["options"]["scene"];
  EXPECT_EQ(scene["type"], "string");
  std::set<std::string> listed;
  for (const auto& v : scene["values"]) listed.insert(v["name"].get<std::string>());
  // The truth: the scene files in the configured folder.
  std::set<std::string> files;
  for (const auto& e : fs::directory_iterator(source("configs/scenes")))
    if (e.is_regular_file() && e.path().extension() == ".json") files.insert(e.path().stem().string());
  EXPECT_EQ(listed, files);
  EXPECT_TRUE(listed.count(scene["default"].get<std::string>())) << scene.dump();
  // Every listed name is accepted by a scan request (two, to keep it short), a
  // name not listed is not.
  for (const std::string& name : {std::string("plane"), *listed.rbegin()}) {
    auto ok = c.call(tiny_scan(name));
    EXPECT_TRUE(ok.ok()) << name << ": " << ok.status().to_string();
  }
  EXPECT_FALSE(c.call(tiny_scan("not-" + *listed.begin())).ok());
}

// 50 concurrent clients x 100 requests: status (most), list_plugins, scans.
TEST(ServiceLoad, FiftyClientsHundredRequestsEachAllAnswered) {
  ConfigOptions o;
  o.max_queue = 8;
  ServiceDaemon sd(o);
  ASSERT_TRUE(sd.d->wait_ready()) << sd.d->log();
  constexpr int kClients = 50, kRequests = 100;
  std::mutex mu;
  std::vector<double> status_ms;
  std::map<std::string, int> outcomes;
  std::atomic<int> unanswered{0};
  std::set<std::string> scan_ids;
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<std::thread> threads;
  for (int t = 0; t < kClients; ++t) {
    threads.emplace_back([&, t] {
      client::Client c(sd.endpoint(), 30s);
      std::vector<double> mine;
      std::map<std::string, int> out;
      std::vector<std::string> ids;
      for (int i = 0; i < kRequests; ++i) {
        const int kind = (t * kRequests + i) % 20;  // 17 status : 2 list_plugins : 1 scan
        auto ts = std::chrono::steady_clock::now();
        Result<json> r = Error(Code::internal, "not sent");
        std::string what;
        if (kind < 17) {
          what = "status";
          r = c.call(i % 3 == 0 && !ids.empty() ? proto::StatusQuery{ids.back()} : proto::StatusQuery{});
          mine.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - ts).count());
        } else if (kind < 19) {
          what = "list_plugins";
          r = c.call(proto::ListPlugins{});
        } else {
          what = "scan";
          r = c.call(tiny_scan(i % 2 ? "plane" : "tilted-box", "load"));
          if (r) ids.push_back((*r)["scan_id"]);
        }
        if (r) {
          out[what + " ok"]++;
        } else if (r.status().code() == Code::unavailable && r.status().message().rfind("busy:", 0) == 0) {
          out[what + " busy"]++;
        } else {
          out[what + " " + std::string(code_name(r.status().code()))]++;
          if (r.status().message().find("no reply") != std::string::npos) unanswered++;
        }
      }
      std::lock_guard lock(mu);
      status_ms.insert(status_ms.end(), mine.begin(), mine.end());
      for (auto& [k, v] : out) outcomes[k] += v;
      scan_ids.insert(ids.begin(), ids.end());
    });
  }
  for (auto& th : threads) th.join();
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  int total = 0;
  for (auto& [k, v] : outcomes) {
    total += v;
    std::printf("  %-22s %d\n", k.c_str(), v);
  }
  const double p50 = percentile(status_ms, 50), p99 = percentile(status_ms, 99);
  std::printf("load: %d clients x %d requests = %d in %.2f s (%.0f req/s); status n=%zu p50=%.3f ms p99=%.3f ms\n",
              kClients, kRequests, total, secs, total / secs, status_ms.size(), p50, p99);
  ::testing::Test::RecordProperty("load_status_p99_us", static_cast<int>(p99 * 1000));
  EXPECT_EQ(total, kClients * kRequests);
  EXPECT_EQ(unanswered.load(), 0);
  for (auto& [k, v] : outcomes)
    EXPECT_TRUE(k.ends_with(" ok") || k == "scan busy") << k << ": " << v;
  EXPECT_GT(outcomes["scan ok"], 0);
  // Every accepted scan finishes; the daemon is still healthy.
  client::Client c(sd.endpoint(), 20s);
  for (const auto& id : scan_ids) EXPECT_EQ(wait_final(c, id)["state"], "done") << id;
  auto st = c.call(proto::StatusQuery{});
  ASSERT_TRUE(st.ok());
  EXPECT_EQ((*st)["daemon"]["scans"]["done"], scan_ids.size());
  EXPECT_GE((*st)["daemon"]["metrics"]["requests"].get<int>(), total);
  EXPECT_EQ(sd.d->stop(), 0) << sd.d->log();
}

// ---- Persistence -------------------------------------------------------------

void kill9(Daemon& d) {
  ASSERT_GT(d.pid, 0);
  ::kill(d.pid, SIGKILL);
  int st = 0;
  waitpid(d.pid, &st, 0);
  d.pid = -1;
}

TEST(ServicePersistence, KillNineDuringAndAfterScansLosesNothingFinished) {
  TempDir results_home;
  const std::string results = (results_home.path / "results").string();
  std::map<std::string, json> finished;  // scan id -> files
  {
    ServiceDaemon sd({}, results);
    ASSERT_TRUE(sd.d->wait_ready()) << sd.d->log();
    client::Client c(sd.endpoint(), 20s);
    for (int i = 0; i < 4; ++i) {
      auto fin = c.scan(tiny_scan(i % 2 ? "plane" : "tilted-box"), nullptr);
      ASSERT_TRUE(fin.ok()) << fin.status().to_string();
      auto m = c.call(proto::ResultQuery{(*fin)["scan_id"]});
      ASSERT_TRUE(m.ok());
      finished[(*fin)["scan_id"]] = (*m)["manifest"]["files"];
    }
    kill9(*sd.d);  // right after several scans
  }
  std::string interrupted;
  {
    ConfigOptions big;
    big.tiny_rig = false;  // a scan long enough to be killed in the middle
    ServiceDaemon sd(big, results);
    ASSERT_TRUE(sd.d->wait_ready()) << sd.d->log();
    client::Client c(sd.endpoint(), 20s);
    auto r = c.call(tiny_scan("tilted-box", "to be killed"));
    ASSERT_TRUE(r.ok());
    interrupted = (*r)["scan_id"];
    for (int i = 0; i < 1000; ++i) {
      auto s = c.call(proto::StatusQuery{interrupted});
      if (s && (*s)["scan"]["progress"].is_object() && (*s)["scan"]["progress"].value("done", 0) >= 3) break;
      std::this_thread::sleep_for(5ms);
    }
    kill9(*sd.d);  // during the scan
  }
  for (int restart = 0; restart < 2; ++restart) {
    ServiceDaemon sd({}, results);
    ASSERT_TRUE(sd.d->wait_ready()) << sd.d->log();
    client::Client c(sd.endpoint(), 20s);
    for (const auto& [id, files] : finished) {
      auto m = c.call(proto::ResultQuery{id});
      ASSERT_TRUE(m.ok()) << id << ": " << m.status().to_string();
      EXPECT_EQ((*m)["state"], "done");
      EXPECT_EQ((*m)["manifest"]["files"], files);
      for (const auto& f : files) {
        const std::string dest = (results_home.path / ("dl-" + f["name"].get<std::string>())).string();
        ASSERT_TRUE(c.fetch_file(id, f["name"], dest).ok());
        EXPECT_EQ(fs::file_size(dest), f["size_bytes"].get<uintmax_t>());
      }
    }
    auto s = c.call(proto::StatusQuery{interrupted});
    ASSERT_TRUE(s.ok()) << s.status().to_string();
    EXPECT_EQ((*s)["scan"]["state"], "failed");
    EXPECT_EQ((*s)["scan"]["error"]["code"], "cancelled");
    EXPECT_NE((*s)["scan"]["error"]["message"].get<std::string>().find("interrupted"), std::string::npos);
    auto m = c.call(proto::ResultQuery{interrupted});
    ASSERT_TRUE(m.ok());
    EXPECT_EQ((*m)["manifest"]["label"], "to be killed");  // what was asked is still known
    for (const auto& f : (*m)["manifest"]["files"])  // no temporaries listed
      EXPECT_NE(f["name"].get<std::string>()[0], '.');
    EXPECT_EQ(sd.d->stop(), 0);
  }
}

// Issue 17 item 5: scans queued behind a running one survive kill -9. The
// next start queues them again with their ids, labels and parameters and runs
// them to the end; the one that was running is reported interrupted. With
// queued_scans.on_restart "fail" they fail instead, saying why.
namespace {
struct KilledQueue {
  std::string running;
  std::vector<std::string> queued;
};
// A full-size scan (~1 s), then `n` tiny-rig scans queued behind it; kill -9
// once the first one is capturing.
KilledQueue kill_with_queue(const std::string& results, int n) {
  KilledQueue out;
  ConfigOptions big;
  big.tiny_rig = false;
  ServiceDaemon sd(big, results);
  EXPECT_TRUE(sd.d->wait_ready()) << sd.d->log();
  client::Client c(sd.endpoint(), 20s);
  auto r = c.call(tiny_scan("tilted-box", "running at the kill"));
  EXPECT_TRUE(r.ok()) << r.status().to_string();
  if (!r) return out;
  out.running = (*r)["scan_id"];
  for (int i = 0; i < n; ++i) {
    proto::Scan s = tiny_scan(i % 2 ? "plane" : "tilted-box", "queued " + std::to_string(i));
    s.params = {{"min_bit_margin", 0.05}};
    auto q = c.call(s);
    EXPECT_TRUE(q.ok()) << q.status().to_string();
    if (q) out.queued.push_back((*q)["scan_id"]);
  }
  for (int i = 0; i < 1000; ++i) {
    auto st = c.call(proto::StatusQuery{out.running});
    if (st && (*st)["scan"]["progress"].is_object() && (*st)["scan"]["progress"].value("done", 0) >= 2) break;
    std::this_thread::sleep_for(5ms);
  }
  kill9(*sd.d);
  return out;
}
}  // namespace

TEST(ServicePersistence, QueuedScansSurviveKillNineAndRunAfterTheRestart) {
  TempDir home;
  const std::string results = (home.path / "results").string();
  const KilledQueue k = kill_with_queue(results, 3);
  ASSERT_EQ(k.queued.size(), 3u);
  ServiceDaemon sd({}, results);
  ASSERT_TRUE(sd.d->wait_ready()) << sd.d->log();
  client::Client c(sd.endpoint(), 20s);
  auto run = c.call(proto::StatusQuery{k.running});
  ASSERT_TRUE(run.ok()) << run.status().to_string();
  EXPECT_EQ((*run)["scan"]["state"], "failed");
  EXPECT_NE((*run)["scan"]["error"]["message"].get<std::string>().find("interrupted"), std::string::npos);
  std::vector<std::string> finished;
  for (size_t i = 0; i < k.queued.size(); ++i) {
    const json fin = wait_final(c, k.queued[i]);
    ASSERT_FALSE(fin.is_null()) << k.queued[i] << " never finished; log:\n" << sd.d->log();
    EXPECT_EQ(fin["state"], "done") << fin.dump();
    EXPECT_EQ(fin["label"], "queued " + std::to_string(i));
    finished.push_back(fin["finished_utc"]);
    auto m = c.call(proto::ResultQuery{k.queued[i]});
    ASSERT_TRUE(m.ok());
    EXPECT_EQ((*m)["manifest"]["params"].value("min_bit_margin", -1.0), 0.05) << "the parameters were kept";
    for (const auto& f : (*m)["manifest"]["files"]) EXPECT_NE(f["name"], "request.json");
  }
  EXPECT_TRUE(std::is_sorted(finished.begin(), finished.end())) << "they ran in their old order";
  // The three were accepted within about a second, and created_utc has whole
  // seconds: their acceptance order survives the restart through
  // accepted_unix_ns (before it, ties fell back to the random part of the
  // ids). list_scans gives them newest first, so in reverse submission order.
  {
    auto listed = c.call(proto::ListScans{});
    ASSERT_TRUE(listed.ok()) << listed.status().to_string();
    std::vector<std::string> order;
    for (const auto& sc : (*listed)["scans"])
      if (std::find(k.queued.begin(), k.queued.end(), sc["scan_id"].get<std::string>()) != k.queued.end())
        order.push_back(sc["scan_id"]);
    EXPECT_EQ(order, std::vector<std::string>(k.queued.rbegin(), k.queued.rend()));
    uint64_t prev = 0;
    for (const auto& id : k.queued) {
      auto m = c.call(proto::ResultQuery{id});
      ASSERT_TRUE(m.ok());
      const uint64_t ns = (*m)["manifest"].value("accepted_unix_ns", uint64_t{0});
      EXPECT_GT(ns, prev) << id << ": accepted_unix_ns increases in submission order";
      prev = ns;
    }
  }
  EXPECT_NE(sd.d->log().find("3 queued again, 0 failed"), std::string::npos) << sd.d->log();
  EXPECT_EQ(sd.d->stop(), 0);
  // A second restart finds them finished: nothing runs twice.
  ServiceDaemon again({}, results);
  ASSERT_TRUE(again.d->wait_ready()) << again.d->log();
  EXPECT_EQ(again.d->log().find("queued again"), std::string::npos) << again.d->log();
}

TEST(ServicePersistence, QueuedScansFailWithAReasonWhenConfiguredOrStale) {
  TempDir home;
  const std::string results = (home.path / "results").string();
  const KilledQueue k = kill_with_queue(results, 2);
  ASSERT_EQ(k.queued.size(), 2u);
  // Make the second one stale: accepted two hours before the restart.
  {
    const fs::path mp = fs::path(results) / k.queued[1] / "manifest.json";
    std::ifstream in(mp);
    json m = json::parse(in);
    ASSERT_EQ(m["state"], "queued");
    m["created_utc"] = "2000-01-01T00:00:00Z";
    std::ofstream(mp) << m.dump();
  }
  ConfigOptions o;
  o.queued_scans = {{"on_restart", "run"}, {"max_age_s", 3600}};
  {
    ServiceDaemon sd(o, results);
    ASSERT_TRUE(sd.d->wait_ready()) << sd.d->log();
    client::Client c(sd.endpoint(), 20s);
    EXPECT_EQ(wait_final(c, k.queued[0])["state"], "done");
    const json stale = wait_final(c, k.queued[1]);
    EXPECT_EQ(stale["state"], "failed");
    EXPECT_EQ(stale["error"]["code"], "cancelled");
    EXPECT_NE(stale["error"]["message"].get<std::string>().find("stale"), std::string::npos) << stale.dump();
    EXPECT_EQ(sd.d->stop(), 0);
  }
  // on_restart "fail": a fresh kill with one queued scan.
  TempDir home2;
  const std::string results2 = (home2.path / "results").string();
  const KilledQueue k2 = kill_with_queue(results2, 1);
  ASSERT_EQ(k2.queued.size(), 1u);
  o.queued_scans = {{"on_restart", "fail"}};
  ServiceDaemon sd(o, results2);
  ASSERT_TRUE(sd.d->wait_ready()) << sd.d->log();
  client::Client c(sd.endpoint(), 20s);
  const json f = wait_final(c, k2.queued[0]);
  EXPECT_EQ(f["state"], "failed");
  EXPECT_NE(f["error"]["message"].get<std::string>().find("restarted before this scan started"), std::string::npos)
      << f.dump();
  auto m = c.call(proto::ResultQuery{k2.queued[0]});
  ASSERT_TRUE(m.ok());
  EXPECT_EQ((*m)["manifest"]["label"], "queued 0");
}

TEST(ServicePersistence, RetentionKeepsNewestAndNeverADownloadingScan) {
  ConfigOptions o;
  o.retention = {{"max_scans", 3}};
  ServiceDaemon sd(o);
  ASSERT_TRUE(sd.d->wait_ready()) << sd.d->log();
  client::Client c(sd.endpoint(), 20s);
  std::vector<std::string> ids;
  for (int i = 0; i < 2; ++i) {
    auto fin = c.scan(tiny_scan(), nullptr);
    ASSERT_TRUE(fin.ok());
    ids.push_back((*fin)["scan_id"]);
    std::this_thread::sleep_for(1100ms);  // distinct finish seconds
  }
  // A client starts downloading the oldest scan.
  auto m0 = c.call(proto::ResultQuery{ids[0]});
  ASSERT_TRUE(m0.ok());
  const std::string f0 = (*m0)["manifest"]["files"][0]["name"];
  ASSERT_TRUE(c.call(proto::Fetch{ids[0], f0, 0, 16}).ok());
  for (int i = 0; i < 4; ++i) {
    auto fin = c.scan(tiny_scan(), nullptr);
    ASSERT_TRUE(fin.ok());
    ids.push_back((*fin)["scan_id"]);
    std::this_thread::sleep_for(1100ms);
  }
  // 6 scans, limit 3: ids[1..3] went (oldest first); ids[0] stays (downloading).
  EXPECT_TRUE(c.call(proto::StatusQuery{ids[0]}).ok()) << "a scan being downloaded was deleted";
  for (int i = 1; i <= 3; ++i) {
    auto s = c.call(proto::StatusQuery{ids[static_cast<size_t>(i)]});
    EXPECT_EQ(s.status().code(), Code::not_found) << i;
    EXPECT_FALSE(fs::exists(fs::path(sd.results) / ids[static_cast<size_t>(i)]));
  }
  for (int i = 4; i <= 5; ++i) EXPECT_TRUE(c.call(proto::StatusQuery{ids[static_cast<size_t>(i)]}).ok());
  EXPECT_NE(sd.d->log().find("retention: deleted scan"), std::string::npos);
}

// ---- Security ----------------------------------------------------------------

std::pair<std::string, std::string> keypair() {
  auto kp = client::generate_keypair();
  EXPECT_TRUE(kp.ok());
  return *kp;
}

TEST(ServiceSecurity, CurveAllowlistLetsInOnlyKnownClients) {
  if (!zmq_has("curve")) GTEST_SKIP() << "libzmq without CURVE";
  TempDir keys;
  auto [server_pub, server_sec] = keypair();
  auto [good_pub, good_sec] = keypair();
  auto [bad_pub, bad_sec] = keypair();
  auto [other_pub, other_sec] = keypair();
  std::ofstream(keys.path / "server.secret") << "# test key\n" << server_sec << "\n";
  ::chmod((keys.path / "server.secret").c_str(), 0600);
  std::ofstream(keys.path / "authorized_keys") << "# allowed clients\n" << good_pub << "  \n\n";
  ConfigOptions o;
  o.curve = {{"secret_key_file", (keys.path / "server.secret").string()},
             {"authorized_keys", (keys.path / "authorized_keys").string()}};
  ServiceDaemon sd(o);
  const client::CurveKeys good{server_pub, good_pub, good_sec};
  // wait_ready() uses a plain client, which must get nothing: wait with ours.
  bool up = false;
  for (int i = 0; i < 60 && !up; ++i) {
    client::Client c(sd.endpoint(), 500ms, good);
    up = c.call(proto::Ping{}).ok();
  }
  ASSERT_TRUE(up) << sd.d->log();
  {
    client::Client c(sd.endpoint(), 5s, good);
    auto st = c.call(proto::StatusQuery{});
    ASSERT_TRUE(st.ok()) << st.status().to_string();
    EXPECT_EQ((*st)["daemon"]["metrics"]["curve"], true);
    auto fin = c.scan(tiny_scan(), nullptr);
    ASSERT_TRUE(fin.ok()) << fin.status().to_string();
    EXPECT_EQ((*fin)["state"], "done");
  }
  auto gets_nothing = [&](const client::CurveKeys& k, const char* who) {
    client::Client c(sd.endpoint(), 1500ms, k);
    auto r = c.call(proto::StatusQuery{});
    EXPECT_FALSE(r.ok()) << who << " got a reply";
    if (!r.ok()) {
      EXPECT_EQ(r.status().code(), Code::unavailable) << who << ": " << r.status().to_string();
    }
  };
  gets_nothing({server_pub, bad_pub, bad_sec}, "unknown key");
  gets_nothing({}, "no key");
  gets_nothing({other_pub, good_pub, good_sec}, "wrong server key");
  // Raw pyzmq-style plain socket too.
  {
    zmq::context_t ctx;
    zmq::socket_t s(ctx, zmq::socket_type::dealer);
    s.set(zmq::sockopt::linger, 0);
    s.set(zmq::sockopt::rcvtimeo, 1000);
    s.connect(sd.endpoint());
    EXPECT_EQ(raw_exchange(s, {R"({"procam":1,"id":"x","type":"ping"})"}), "");
  }
  EXPECT_NE(sd.d->log().find("refused CURVE client"), std::string::npos) << sd.d->log();
  // The allowlist is re-read when it changes: add the unknown key.
  std::this_thread::sleep_for(20ms);
  std::ofstream(keys.path / "authorized_keys", std::ios::app) << bad_pub << "\n";
  {
    client::Client c(sd.endpoint(), 5s, {server_pub, bad_pub, bad_sec});
    EXPECT_TRUE(c.call(proto::Ping{}).ok()) << sd.d->log();
  }
  // Still serving the good client after all that.
  client::Client c(sd.endpoint(), 5s, good);
  EXPECT_TRUE(c.call(proto::Ping{}).ok());
  // The CLI takes its keys from the environment (a key file and a key).
  std::ofstream(keys.path / "me.secret") << "# SECRET\n" << good_sec << "\n";
  ::setenv("PROCAM_SERVER_KEY", server_pub.c_str(), 1);
  ::setenv("PROCAM_CLIENT_KEY", (keys.path / "me.secret").c_str(), 1);
  std::string out;
  const int rc = run_command({bin("procam"), "ping", "--endpoint", sd.endpoint(), "--timeout", "5"}, &out);
  const auto stranger = keypair();
  ::setenv("PROCAM_CLIENT_KEY", stranger.second.c_str(), 1);
  std::string out_bad;
  const int rc_bad = run_command({bin("procam"), "ping", "--endpoint", sd.endpoint(), "--timeout", "1"}, &out_bad);
  ::unsetenv("PROCAM_SERVER_KEY");
  ::unsetenv("PROCAM_CLIENT_KEY");
  EXPECT_EQ(rc, 0) << out;
  EXPECT_NE(out.find("alive"), std::string::npos) << out;
  EXPECT_NE(rc_bad, 0) << out_bad;
}

TEST(ServiceSecurity, BadCurveConfigIsRefusedAtStart) {
  TempDir keys;
  std::ofstream(keys.path / "server.secret") << "not a key\n";
  std::ofstream(keys.path / "authorized_keys") << "";
  ConfigOptions o;
  o.curve = {{"secret_key_file", (keys.path / "server.secret").string()},
             {"authorized_keys", (keys.path / "authorized_keys").string()}};
  ServiceDaemon sd(o);
  for (int i = 0; i < 200 && sd.d->alive(); ++i) std::this_thread::sleep_for(50ms);
  EXPECT_FALSE(sd.d->alive());
  EXPECT_NE(sd.d->log().find("server.secret"), std::string::npos) << sd.d->log();
}

TEST(ServiceSecurity, WorldWritablePluginFilesAndFoldersAreRefused) {
  TempDir plugins;
  const fs::path wdir = plugins.path / "writable-dir";
  const fs::path wfile = plugins.path / "writable-file";
  fs::create_directories(wdir);
  fs::create_directories(wfile);
  fs::path so;
  for (const auto& e : fs::directory_iterator(PROCAM_PLUGIN_DIR))
    if (e.path().filename().string().find("structured-light") != std::string::npos) so = e.path();
  ASSERT_FALSE(so.empty());
  fs::copy_file(so, wdir / "procam-copy-a.so");
  fs::copy_file(so, wfile / "procam-copy-b.so");
  ::chmod(wdir.c_str(), 0777);
  ::chmod((wfile / "procam-copy-b.so").c_str(), 0666);
  ConfigOptions o;
  o.plugin_paths = {wdir.string(), wfile.string()};
  ServiceDaemon sd(o);
  ASSERT_TRUE(sd.d->wait_ready()) << sd.d->log();
  client::Client c(sd.endpoint(), 10s);
  auto p = c.call(proto::ListPlugins{});
  ASSERT_TRUE(p.ok());
  int refused = 0;
  for (const auto& r : (*p)["rejected"])
    if (r["error"]["message"].get<std::string>().find("world-writable") != std::string::npos) ++refused;
  EXPECT_EQ(refused, 2) << p->dump(2);
  // Only the good ones from the build folder are loaded: none of the copies.
  size_t built = 0;
  for (const auto& e : fs::directory_iterator(PROCAM_PLUGIN_DIR))
    if (e.path().extension() == ".so") ++built;
  EXPECT_EQ((*p)["plugins"].size(), built) << p->dump(2);
  for (const auto& pl : (*p)["plugins"]) {
    const std::string file = pl["file"].get<std::string>();
    EXPECT_EQ(file.find("procam-copy"), std::string::npos) << file;
    EXPECT_EQ(file.find('/'), std::string::npos) << file;  // a bare file name (PROTOCOL.md)
  }
}

TEST(ServiceSecurity, ResultFilesCannotEscapeTheResultsFolder) {
  TempDir home;
  const std::string results = (home.path / "results").string();
  std::string id;
  {
    ServiceDaemon sd({}, results);
    ASSERT_TRUE(sd.d->wait_ready()) << sd.d->log();
    client::Client c(sd.endpoint(), 20s);
    auto fin = c.scan(tiny_scan(), nullptr);
    ASSERT_TRUE(fin.ok());
    id = (*fin)["scan_id"];
    EXPECT_EQ(sd.d->stop(), 0);
  }
  // Someone edits the manifest on disk: a symlink out and a path with "..".
  const fs::path dir = fs::path(results) / id;
  std::ofstream(home.path / "secret.txt") << "secret";
  fs::create_symlink(home.path / "secret.txt", dir / "link.txt");
  json m = json::parse(std::ifstream(dir / "manifest.json"));
  m["files"].push_back({{"name", "link.txt"}, {"size_bytes", 6}});
  m["files"].push_back({{"name", "../secret.txt"}, {"size_bytes", 6}});
  std::ofstream(dir / "manifest.json") << m.dump();
  ServiceDaemon sd({}, results);
  ASSERT_TRUE(sd.d->wait_ready()) << sd.d->log();
  client::Client c(sd.endpoint(), 20s);
  auto r = c.call(proto::Fetch{id, "link.txt", 0, 100});
  EXPECT_EQ(r.status().code(), Code::not_found) << r.status().to_string();
  zmq::context_t ctx;
  zmq::socket_t s(ctx, zmq::socket_type::dealer);
  s.set(zmq::sockopt::linger, 0);
  s.set(zmq::sockopt::rcvtimeo, 5000);
  s.connect(sd.endpoint());
  const std::string body = raw_exchange(
      s, {json{{"procam", 1}, {"id", "e"}, {"type", "fetch"}, {"scan_id", id}, {"file", "../secret.txt"}}.dump()});
  EXPECT_NE(body.find("invalid_argument"), std::string::npos) << body;
  const std::string body2 = raw_exchange(
      s, {json{{"procam", 1}, {"id", "e2"}, {"type", "fetch"}, {"scan_id", "../" + id}, {"file", "depth_mm.exr"}}.dump()});
  EXPECT_NE(body2.find("\"ok\":false"), std::string::npos) << body2;
  EXPECT_EQ(body2.find("secret"), std::string::npos);
  // A scan id that cannot exist is an unknown scan (not_found, naming the id),
  // not a complaint about the (valid) file name.
  auto bad = c.call(proto::Fetch{"../" + id, "valid.png", 0, 100});
  EXPECT_EQ(bad.status().code(), Code::not_found) << bad.status().to_string();
  EXPECT_NE(bad.status().message().find("no scan with id"), std::string::npos) << bad.status().to_string();
  EXPECT_EQ(bad.status().message().find("plain file name"), std::string::npos) << bad.status().to_string();
}

long rss_kib(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("VmRSS:", 0) == 0) return std::stol(line.substr(6));
  return -1;
}

// A client that asks for many large fetches and never reads them must not grow
// the daemon without bound (issue 17: 200 unread 8 MiB fetches grew it by
// ~0.9 GB). The daemon keeps at most kReplyQueueMessages (16) replies per
// client, drops the rest with a log line and a metric, and serves everyone else.
TEST(ServiceRobustness, SlowReadersCannotGrowTheDaemon) {
  ConfigOptions o;
  o.tiny_rig = false;  // full-size outputs: points.ply is several MiB
  ServiceDaemon sd(o);
  ASSERT_TRUE(sd.d->wait_ready()) << sd.d->log();
  client::Client c(sd.endpoint(), 60s);
  auto fin = c.scan(tiny_scan(), nullptr);
  ASSERT_TRUE(fin.ok()) << fin.status().to_string();
  const std::string id = (*fin)["scan_id"];
  auto m = c.call(proto::ResultQuery{id});
  ASSERT_TRUE(m.ok());
  std::string big;
  uint64_t big_size = 0;
  for (const auto& f : (*m)["manifest"]["files"])
    if (f.value("size_bytes", uint64_t{0}) > big_size) {
      big_size = f["size_bytes"];
      big = f["name"];
    }
  ASSERT_GE(big_size, uint64_t{4} << 20) << "need a large result file; largest is " << big;
  const uint64_t reply_bytes = std::min<uint64_t>(big_size, proto::kMaxFetchBytes);

  const long before = rss_kib(sd.d->pid);
  ASSERT_GT(before, 0);
  zmq::context_t ctx;
  zmq::socket_t slow(ctx, zmq::socket_type::dealer);
  slow.set(zmq::sockopt::linger, 0);
  slow.set(zmq::sockopt::rcvhwm, 1);       // its I/O thread stops reading almost at once
  slow.set(zmq::sockopt::rcvbuf, 65536);
  slow.connect(sd.endpoint());
  const int kFetches = 120;
  for (int i = 0; i < kFetches; ++i) {
    const std::string body = json{{"procam", 1}, {"id", "f" + std::to_string(i)}, {"type", "fetch"},
                                  {"scan_id", id}, {"file", big}, {"max_bytes", reply_bytes}}.dump();
    slow.send(zmq::message_t(), zmq::send_flags::sndmore);
    slow.send(zmq::buffer(body), zmq::send_flags::none);
  }
  // Let the daemon answer them all (a fresh client's status call is queued behind).
  client::Client other(sd.endpoint(), 30s);
  json st;
  for (int k = 0; k < 300; ++k) {
    auto r = other.call(proto::StatusQuery{});
    ASSERT_TRUE(r.ok()) << r.status().to_string();
    st = *r;
    if (st["daemon"]["metrics"]["requests"].get<uint64_t>() >= static_cast<uint64_t>(kFetches)) break;
    std::this_thread::sleep_for(20ms);
  }
  const long after = rss_kib(sd.d->pid);
  const double grown_mib = static_cast<double>(after - before) / 1024.0;
  // Unbounded, 120 replies would hold ~120 x reply_bytes; bounded, at most 16
  // queued plus what the kernel socket buffers hold.
  const double unbounded_mib = kFetches * static_cast<double>(reply_bytes) / (1 << 20);
  std::printf("slow reader: %d fetches of %.1f MiB; daemon RSS grew %.1f MiB (unbounded would be ~%.0f MiB)\n",
              kFetches, static_cast<double>(reply_bytes) / (1 << 20), grown_mib, unbounded_mib);
  EXPECT_LT(grown_mib, 20.0 * static_cast<double>(reply_bytes) / (1 << 20) + 64.0);
  EXPECT_GT(st["daemon"]["metrics"]["replies_dropped"].get<uint64_t>(), 0u) << st.dump();
  EXPECT_NE(sd.d->log().find("is not reading its replies"), std::string::npos);
  // Everyone else is still served, fetches included.
  auto f = other.call(proto::Fetch{id, "valid.png", 0, 1000});
  EXPECT_TRUE(f.ok()) << f.status().to_string();
  EXPECT_TRUE(sd.d->alive());
}

TEST(ServiceRobustness, OversizedAndMalformedMessagesNeverStopTheDaemon) {
  ServiceDaemon sd;
  ASSERT_TRUE(sd.d->wait_ready()) << sd.d->log();
  zmq::context_t ctx;
  auto sock = [&] {
    zmq::socket_t s(ctx, zmq::socket_type::dealer);
    s.set(zmq::sockopt::linger, 0);
    s.set(zmq::sockopt::rcvtimeo, 3000);
    s.connect(sd.endpoint());
    return s;
  };
  auto s = sock();
  struct Case { std::string body; std::string code; };
  std::string deep(40, '[');
  const std::vector<Case> cases = {
      {R"({"procam":1,"id":"t","type":"sta)", "bad_message"},                     // truncated
      {std::string(2u << 20, ' ') + "{}", "too_large"},                           // over 1 MiB
      {R"({"procam":1,"id":"w","type":"scan","plugin":7,"method":"gray"})", "bad_message"},  // wrong type
      {R"({"procam":1,"id":"u","type":"ping","extra":1})", "bad_message"},        // unknown field
      {std::string("\x00\xff\xfe\x80garbage\x01", 12), "bad_message"},            // binary
      {R"({"procam":1,"id":"c","type":"cancel"})", "bad_message"},                // missing field
      {R"({"procam":1,"id":")" + std::string(200, 'x') + R"(","type":"ping"})", "too_large"},
      {R"({"procam":1,"id":"l","type":"scan","plugin":"structured-light","method":"gray","label":")" +
           std::string(300, 'l') + "\"}", "too_large"},
      {deep, "too_large"},
  };
  for (const auto& k : cases) {
    const std::string body = raw_exchange(s, {k.body});
    ASSERT_FALSE(body.empty()) << "no reply to " << k.body.substr(0, 60);
    auto j = json::parse(body);
    EXPECT_EQ(j["error"]["code"], k.code) << body;
    EXPECT_FALSE(j["error"]["message"].get<std::string>().empty());
  }
  // Two body frames: bad_message.
  const std::string two = raw_exchange(s, {"{}", "{}"});
  EXPECT_NE(two.find("bad_message"), std::string::npos) << two;
  // Over the 1 MiB request limit but under the 64 MiB hard cap (issue 17
  // item 6): read and answered too_large with its id, and the same
  // connection is served next.
  {
    std::string body = R"({"procam":1,"id":"nine-mib","type":"ping","pad":")";
    body += std::string(9u << 20, 'p') + "\"}";
    const std::string r = raw_exchange(s, {body});
    ASSERT_FALSE(r.empty()) << "no reply to a 9 MiB request";
    const json j = json::parse(r);
    EXPECT_EQ(j["id"], "nine-mib") << r;
    EXPECT_EQ(j["error"]["code"], "too_large") << r;
    EXPECT_NE(j["error"]["message"].get<std::string>().find(std::to_string(body.size()) + " bytes"), std::string::npos)
        << r;
    const std::string next = raw_exchange(s, {R"({"procam":1,"id":"after","type":"ping"})"});
    ASSERT_FALSE(next.empty());
    EXPECT_EQ(json::parse(next)["id"], "after") << next;
  }
  // Over the 64 MiB hard cap: ZeroMQ drops it before buffering it and closes
  // that connection (no reply is possible); the daemon's socket monitor
  // counts and logs it. Both sockets stay open meanwhile, so the one
  // connection that ends is the dropped one.
  const auto closed = [&] {
    const std::string r = raw_exchange(s, {R"({"procam":1,"id":"m","type":"status"})"});
    return r.empty() ? -1 : json::parse(r)["daemon"]["metrics"]["connections_closed"].get<int>();
  };
  const int closed_before = closed();
  ASSERT_GE(closed_before, 0);
  {
    auto big = sock();
    big.send(zmq::message_t(), zmq::send_flags::sndmore);
    big.send(zmq::buffer(std::string((64u << 20) + 1, 'x')), zmq::send_flags::none);
    zmq::message_t m;
    EXPECT_FALSE(big.recv(m).has_value());
    int now = closed();
    for (int i = 0; i < 100 && now == closed_before; ++i) {
      std::this_thread::sleep_for(20ms);
      now = closed();
    }
    EXPECT_EQ(now, closed_before + 1);
    EXPECT_NE(sd.d->log().find("dropped it for a message over the 64 MiB hard limit"), std::string::npos)
        << sd.d->log();
  }
  // The daemon still serves everyone.
  client::Client c(sd.endpoint(), 5s);
  auto st = c.call(proto::StatusQuery{});
  ASSERT_TRUE(st.ok()) << sd.d->log();
  EXPECT_GE((*st)["daemon"]["metrics"]["bad_requests"].get<int>(), 10);
  EXPECT_TRUE(sd.d->alive());
}

}  // namespace

// Issue 15 acceptance: a sim scene with a Legendre medium (drifting fog that
// evolves frame by frame during the scan, docs/legendre.md) runs through
// procamd. A plain Gray scan of legendre-fog on the tiny rig finishes with
// depth, and its columns are right (>= 90 % of lit pixels within one column
// of the sim's truth, procamd's own evaluation: the fog is optically thin).
// polarized-striping/striping scans of legendre-fog and of its 2x denser,
// 4x faster variant finish with depth, and the fog shows in them: the
// denser fog leaves a lower contrast quality S / (S + B) (Eq. 5.8, the
// plugin's report) than the thinner one.
TEST(ServiceMedia, LegendreFogScansRunThroughProcamd) {
  ServiceDaemon sd;
  ASSERT_TRUE(sd.d->wait_ready()) << sd.d->log();
  client::Client c(sd.endpoint(), 20s);
  auto scan = [&](const proto::Scan& s) -> json {
    auto r = c.call(s);
    EXPECT_TRUE(r.ok()) << s.method << ": " << r.status().to_string();
    if (!r) return json();
    const json fin = wait_final(c, (*r)["scan_id"], 300s);
    EXPECT_FALSE(fin.is_null()) << s.method << " never finished; log:\n" << sd.d->log();
    if (fin.is_null()) return json();
    EXPECT_EQ(fin["state"], "done") << fin.dump();
    auto m = c.call(proto::ResultQuery{(*r)["scan_id"]});
    EXPECT_TRUE(m.ok()) << m.status().to_string();
    if (!m) return json();
    const json man = (*m)["manifest"];
    bool depth = false;
    for (const auto& o : man["outputs"]) depth = depth || o.value("name", "") == "depth_mm";
    EXPECT_TRUE(depth) << s.label << ": no depth_mm in " << man["outputs"].dump();
    return man;
  };
  const json gray = scan(tiny_scan("legendre-fog", "gray through fog"));
  ASSERT_TRUE(gray.contains("evaluation")) << gray.dump();
  std::printf("legendre-fog through procamd, gray: %s\n", gray["evaluation"].dump().c_str());
  EXPECT_GE(gray["evaluation"].value("within_1col_fraction", 0.0), 0.9) << gray["evaluation"].dump();
  double cqm[2] = {0, 0};
  const char* scenes[2] = {"legendre-fog", "legendre-variants/legendre-fog-dense"};
  for (int k = 0; k < 2; ++k) {
    proto::Scan s = tiny_scan(scenes[k], std::string("striping through ") + scenes[k]);
    s.plugin = "polarized-striping";
    s.method = "striping";
    const json man = scan(s);
    for (const auto& o : man.value("outputs", json::array()))
      if (o.value("name", "") == "report") cqm[k] = o["value"]["quality"].value("cqm_mean", 0.0);
  }
  std::printf("striping contrast quality: legendre-fog %.4f, dense fog %.4f\n", cqm[0], cqm[1]);
  EXPECT_GT(cqm[0], 0.0);
  EXPECT_LT(cqm[1], cqm[0]) << "the denser fog should veil the stripes more";
}

}  // namespace procam::testing
