// SPDX-License-Identifier: MIT
// PluginHost tests against the fixture plugins in testdata/: each broken one
// is rejected for the right reason, the host keeps working, and the good
// ("null") plugin runs a whole session.
#include "procam/host/plugin_host.hpp"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "procam/core/image.hpp"

namespace procam::host {
namespace {
namespace fs = std::filesystem;
using namespace std::chrono_literals;

std::string fixture(const std::string& name) {
  return std::string(PROCAM_HOST_FIXTURE_DIR) + "/" + name + ".so";
}

bool contains(const std::string& hay, const std::string& needle) {
  return hay.find(needle) != std::string::npos;
}

// A fresh temporary directory, removed at the end of the test.
class TempDir {
public:
  TempDir() {
    std::string tmpl = (fs::temp_directory_path() / "procam-host-test-XXXXXX").string();
    if (::mkdtemp(tmpl.data()) != nullptr) path_ = tmpl;
  }
  ~TempDir() {
    std::error_code ec;
    if (!path_.empty()) fs::remove_all(path_, ec);
  }
  const std::string& path() const { return path_; }
  std::string file(const std::string& name) const { return path_ + "/" + name; }

private:
  std::string path_;
};

// True if this process has no child processes left (none leaked, no zombies).
bool no_children() {
  int st = 0;
  return ::waitpid(-1, &st, WNOHANG) == -1 && errno == ECHILD;
}

class PluginHostTest : public ::testing::Test {
protected:
  void SetUp() override {
    ASSERT_FALSE(tmp_.path().empty());
    marker_ = tmp_.file("constructor-ran");
    ::setenv("PROCAM_TEST_MARKER", marker_.c_str(), 1);
  }
  void TearDown() override { ::unsetenv("PROCAM_TEST_MARKER"); }

  // After a rejection the same host must still load and list the good plugin.
  static void expect_host_still_works(PluginHost& host) {
    const size_t before = host.rejected().size();
    Status st = host.load_file(fixture("good"));
    ASSERT_TRUE(st.ok()) << st.to_string();
    ASSERT_NE(host.find("null"), nullptr);
    EXPECT_EQ(host.rejected().size(), before);
    auto s = host.create_session("null", "null", "{}", "{}");
    EXPECT_TRUE(s.ok()) << s.status().to_string();
  }

  TempDir tmp_;
  std::string marker_;
};

// ---------------------------------------------------------------- good plugin

TEST_F(PluginHostTest, GoodPluginLoadsAndListsMethod) {
  PluginHost host;
  Status st = host.load_file(fixture("good"));
  ASSERT_TRUE(st.ok()) << st.to_string();
  ASSERT_EQ(host.plugins().size(), 1u);
  EXPECT_TRUE(host.rejected().empty());
  const PluginInfo& p = host.plugins()[0];
  EXPECT_EQ(p.name, "null");
  EXPECT_EQ(p.version, "0.0.1");
  EXPECT_EQ(p.file, fixture("good"));
  ASSERT_EQ(p.methods.size(), 1u);
  EXPECT_EQ(p.methods[0].name, "null");
  EXPECT_EQ(p.methods[0].description, "one black frame, trivial outputs");
  EXPECT_EQ(p.methods[0].describe.value("name", ""), "null");
  EXPECT_TRUE(p.methods[0].describe["params"].is_array());
  EXPECT_EQ(host.find("null"), &p);
  EXPECT_EQ(host.find("other"), nullptr);
  EXPECT_TRUE(no_children());
}

// Runs the null plugin's one round with a frame of constant `value`.
void run_null_scan(Session& s, uint8_t value) {
  auto plan = s.next_plan();
  ASSERT_TRUE(plan.ok()) << plan.status().to_string();
  ASSERT_TRUE(plan->has_value());
  const Plan& p = **plan;
  EXPECT_EQ(p.note, "the only round");
  ASSERT_EQ(p.frames.size(), 1u);
  const PlannedFrame& f = p.frames[0];
  EXPECT_EQ(f.label, "black");
  EXPECT_EQ(f.pattern.width, 4u);
  EXPECT_EQ(f.pattern.height, 3u);
  EXPECT_EQ(f.pattern.channels, 1u);
  EXPECT_EQ(f.pattern.pixel_type, static_cast<uint32_t>(PROCAM_PIXEL_U8));
  Image pattern = Image::copy_of(f.pattern);
  ASSERT_FALSE(pattern.empty());
  for (size_t i = 0; i < pattern.size_bytes(); ++i) EXPECT_EQ(pattern.data()[i], 0);
  EXPECT_EQ(f.settings.struct_size, sizeof(procam_frame_settings));
  EXPECT_TRUE(std::isnan(f.settings.polarizer_deg));

  Image frame(4, 3, PixelType::u8);
  std::memset(frame.data(), value, frame.size_bytes());
  Status st = s.add_frame(0, frame.view());
  ASSERT_TRUE(st.ok()) << st.to_string();
  st = s.end_round();
  ASSERT_TRUE(st.ok()) << st.to_string();
  auto done = s.next_plan();
  ASSERT_TRUE(done.ok()) << done.status().to_string();
  EXPECT_FALSE(done->has_value());
}

TEST_F(PluginHostTest, GoodPluginRunsSessionEndToEnd) {
  PluginHost host;
  ASSERT_TRUE(host.load_file(fixture("good")).ok());
  auto session = host.create_session("null", "null", R"({"x": 1})", "{}");
  ASSERT_TRUE(session.ok()) << session.status().to_string();
  Session& s = *session;
  EXPECT_EQ(s.plugin_name(), "null");
  EXPECT_EQ(s.method(), "null");
  run_null_scan(s, 10);

  auto outs = s.outputs();
  ASSERT_TRUE(outs.ok()) << outs.status().to_string();
  ASSERT_EQ(outs->size(), 2u);
  const Output& mean = (*outs)[0];
  EXPECT_EQ(mean.name, "frame_mean");
  EXPECT_EQ(mean.kind, PROCAM_OUTPUT_SCALAR);
  EXPECT_DOUBLE_EQ(mean.scalar, 10.0);
  const Output& depth = (*outs)[1];
  EXPECT_EQ(depth.name, "depth_mm");
  EXPECT_EQ(depth.unit, "mm");
  EXPECT_EQ(depth.kind, PROCAM_OUTPUT_IMAGE);
  Image d = Image::copy_of(depth.image);
  ASSERT_EQ(d.width(), 2u);
  ASSERT_EQ(d.type(), PixelType::f32);
  EXPECT_FLOAT_EQ(d.at<float>(0, 0), 1.0f);
  EXPECT_FLOAT_EQ(d.at<float>(1, 0), 2.0f);
  EXPECT_FLOAT_EQ(d.at<float>(0, 1), 3.0f);
  EXPECT_TRUE(std::isnan(d.at<float>(1, 1)));
  // After the last round next_plan keeps saying "done" without asking the plugin.
  auto again = s.next_plan();
  ASSERT_TRUE(again.ok());
  EXPECT_FALSE(again->has_value());
}

TEST_F(PluginHostTest, GoodPluginWithoutProbe) {
  PluginHost host(LoadOptions{.probe_in_child = false, .probe_timeout = 1000ms});
  ASSERT_TRUE(host.load_file(fixture("good")).ok());
  auto s = host.create_session("null", "null", "", "");
  ASSERT_TRUE(s.ok()) << s.status().to_string();
  run_null_scan(*s, 7);
}

TEST_F(PluginHostTest, SessionOutlivesHostAndMoves) {
  std::optional<Session> kept;
  {
    PluginHost host;
    ASSERT_TRUE(host.load_file(fixture("good")).ok());
    auto s = host.create_session("null", "null", "{}", "{}");
    ASSERT_TRUE(s.ok());
    kept.emplace(std::move(*s));
  }  // the host is gone; the session keeps the library loaded
  Session moved = std::move(*kept);
  auto stale = kept->next_plan();
  EXPECT_EQ(stale.status().code(), Code::failed_precondition);
  run_null_scan(moved, 3);
  auto outs = moved.outputs();
  ASSERT_TRUE(outs.ok()) << outs.status().to_string();
  EXPECT_DOUBLE_EQ((*outs)[0].scalar, 3.0);
}

TEST_F(PluginHostTest, SessionProtocolIsEnforced) {
  PluginHost host;
  ASSERT_TRUE(host.load_file(fixture("good")).ok());
  auto session = host.create_session("null", "null", "{}", "{}");
  ASSERT_TRUE(session.ok());
  Session& s = *session;
  Image frame(4, 3, PixelType::u8);

  EXPECT_EQ(s.add_frame(0, frame.view()).code(), Code::failed_precondition);
  EXPECT_EQ(s.end_round().code(), Code::failed_precondition);
  EXPECT_EQ(s.outputs().status().code(), Code::failed_precondition);

  auto plan = s.next_plan();
  ASSERT_TRUE(plan.ok() && plan->has_value());
  EXPECT_EQ(s.next_plan().status().code(), Code::failed_precondition);  // round still open
  Status st = s.add_frame(1, frame.view());
  EXPECT_EQ(st.code(), Code::invalid_argument);
  EXPECT_TRUE(contains(st.message(), "out of range")) << st.message();

  procam_image bad = frame.view();
  bad.data = nullptr;
  st = s.add_frame(0, bad);
  EXPECT_EQ(st.code(), Code::invalid_argument);
  EXPECT_TRUE(contains(st.message(), "null pixel data")) << st.message();

  // The plugin itself refuses a U16 frame: its message comes through.
  Image wrong(4, 3, PixelType::u16);
  st = s.add_frame(0, wrong.view());
  EXPECT_EQ(st.code(), Code::corrupt_data);
  EXPECT_TRUE(contains(st.message(), "PROCAM_ERR_BAD_FRAME")) << st.message();
  EXPECT_TRUE(contains(st.message(), "expected frame 0, 1-channel U8")) << st.message();

  st = s.end_round();  // frame 0 still missing
  EXPECT_EQ(st.code(), Code::failed_precondition);
  EXPECT_TRUE(contains(st.message(), "1 of 1 frames were not added")) << st.message();

  ASSERT_TRUE(s.add_frame(0, frame.view()).ok());
  EXPECT_EQ(s.add_frame(0, frame.view()).code(), Code::failed_precondition);  // twice
  ASSERT_TRUE(s.end_round().ok());
}

TEST_F(PluginHostTest, CreateSessionErrors) {
  PluginHost host;
  ASSERT_TRUE(host.load_file(fixture("good")).ok());

  auto r = host.create_session("nope", "null", "{}", "{}");
  EXPECT_EQ(r.status().code(), Code::not_found);
  EXPECT_TRUE(contains(r.status().message(), "'nope'")) << r.status().message();
  EXPECT_TRUE(contains(r.status().message(), "loaded plugins: null")) << r.status().message();

  r = host.create_session("null", "gray", "{}", "{}");
  EXPECT_EQ(r.status().code(), Code::not_found);
  EXPECT_TRUE(contains(r.status().message(), "no method 'gray'")) << r.status().message();
  EXPECT_TRUE(contains(r.status().message(), "its methods: null")) << r.status().message();

  r = host.create_session("null", "null", "[1, 2]", "{}");
  EXPECT_EQ(r.status().code(), Code::invalid_argument);
  r = host.create_session("null", "null", "{}", "{not json");
  EXPECT_EQ(r.status().code(), Code::invalid_argument);

  PluginHost empty;
  r = empty.create_session("null", "null", "{}", "{}");
  EXPECT_EQ(r.status().code(), Code::not_found);
  EXPECT_TRUE(contains(r.status().message(), "none")) << r.status().message();
}

// ------------------------------------------------------------ broken plugins

struct BadCase {
  const char* fixture;
  Code code;
  std::vector<std::string> message_parts;
};

void PrintTo(const BadCase& c, std::ostream* os) { *os << c.fixture; }

class RejectTest : public PluginHostTest, public ::testing::WithParamInterface<BadCase> {};

void check_rejected(PluginHost& host, const std::string& path, const BadCase& c) {
  Status st = host.load_file(path);
  ASSERT_FALSE(st.ok()) << path << " was accepted";
  EXPECT_EQ(st.code(), c.code) << st.to_string();
  EXPECT_TRUE(contains(st.message(), "plugin '" + path + "'")) << st.message();
  for (const auto& part : c.message_parts)
    EXPECT_TRUE(contains(st.message(), part)) << "missing \"" << part << "\" in: " << st.message();
  EXPECT_TRUE(host.plugins().empty());
  ASSERT_EQ(host.rejected().size(), 1u);
  EXPECT_EQ(host.rejected()[0].file, path);
  EXPECT_EQ(host.rejected()[0].error.code(), c.code);
}

TEST_P(RejectTest, RejectedWithReasonAndHostKeepsWorking) {
  const BadCase& c = GetParam();
  const bool hangs = std::string(c.fixture) == "hang_on_load";
  PluginHost host(LoadOptions{.probe_in_child = true, .probe_timeout = hangs ? 300ms : 5000ms});
  const auto t0 = std::chrono::steady_clock::now();
  check_rejected(host, fixture(c.fixture), c);
  if (hangs) {
    EXPECT_LT(std::chrono::steady_clock::now() - t0, 3s);
  }
  EXPECT_TRUE(no_children()) << "probe child not reaped";
  EXPECT_FALSE(fs::exists(marker_)) << "a fixture constructor ran in this process";
  expect_host_still_works(host);
}

INSTANTIATE_TEST_SUITE_P(
    Fixtures, RejectTest,
    ::testing::Values(
        BadCase{"wrong_abi",
                Code::abi_mismatch,
                {"was built for plugin ABI 999, this procamd speaks ABI 1..3",
                 "rebuild the plugin against this procamd's plugin_abi.h"}},
        BadCase{"bad_magic", Code::corrupt_data, {"magic 0xdeadbeef", "expected 0x49504350"}},
        BadCase{"missing_create", Code::corrupt_data, {"exports no 'procam_plugin_create'"}},
        BadCase{"no_info", Code::corrupt_data, {"exports no 'procam_plugin_info'"}},
        BadCase{
            "create_returns_null", Code::abi_mismatch, {"procam_plugin_create(3) returned NULL"}},
        BadCase{"null_function", Code::plugin_error, {"NULL function pointers (get_outputs)"}},
        BadCase{"crash_on_load",
                Code::plugin_error,
                {"crashed while loading (signal 11, SIGSEGV)", "in dlopen"}},
        BadCase{"crash_in_describe",
                Code::plugin_error,
                {"crashed while loading (signal 11, SIGSEGV)", "in describe()"}},
        BadCase{"hang_on_load",
                Code::timeout,
                {"did not finish loading within 300 ms", "in dlopen", "killed"}}),
    [](const ::testing::TestParamInfo<BadCase>& i) { return std::string(i.param.fixture); });

// The checks on the file happen before any plugin code runs: even with the
// probe off, these fixtures' constructors (which abort) never run.
TEST_F(PluginHostTest, FileChecksRunBeforeAnyPluginCode) {
  PluginHost host(LoadOptions{.probe_in_child = false, .probe_timeout = 1000ms});
  EXPECT_EQ(host.load_file(fixture("wrong_abi")).code(), Code::abi_mismatch);
  EXPECT_EQ(host.load_file(fixture("bad_magic")).code(), Code::corrupt_data);
  EXPECT_FALSE(fs::exists(marker_));
  EXPECT_EQ(host.rejected().size(), 2u);
  expect_host_still_works(host);
}

// In-process (probe off) checks reject the same way as the probe.
TEST_F(PluginHostTest, InProcessChecksWithoutProbe) {
  PluginHost host(LoadOptions{.probe_in_child = false, .probe_timeout = 1000ms});
  Status st = host.load_file(fixture("null_function"));
  EXPECT_EQ(st.code(), Code::plugin_error);
  EXPECT_TRUE(contains(st.message(), "get_outputs")) << st.message();
  st = host.load_file(fixture("create_returns_null"));
  EXPECT_EQ(st.code(), Code::abi_mismatch);
  EXPECT_TRUE(contains(st.message(), "returned NULL")) << st.message();
  expect_host_still_works(host);
}

TEST_F(PluginHostTest, NonElfAndTruncatedFilesRejected) {
  PluginHost host;
  const std::string corrupt = tmp_.file("corrupt.so");
  std::ofstream(corrupt) << "this is not a shared library\n";
  Status st = host.load_file(corrupt);
  EXPECT_EQ(st.code(), Code::corrupt_data);
  EXPECT_TRUE(contains(st.message(), "plugin '" + corrupt + "'")) << st.message();
  EXPECT_TRUE(contains(st.message(), "not an ELF file")) << st.message();

  const std::string truncated = tmp_.file("truncated.so");
  fs::copy_file(fixture("good"), truncated);
  fs::resize_file(truncated, fs::file_size(truncated) / 2);
  st = host.load_file(truncated);
  EXPECT_EQ(st.code(), Code::corrupt_data);
  EXPECT_TRUE(contains(st.message(), "plugin '" + truncated + "'")) << st.message();
  EXPECT_TRUE(contains(st.message(), "past the end of the file")) << st.message();

  st = host.load_file(tmp_.file("missing.so"));
  EXPECT_EQ(st.code(), Code::not_found);
  EXPECT_TRUE(contains(st.message(), "missing.so")) << st.message();

  EXPECT_EQ(host.rejected().size(), 3u);
  expect_host_still_works(host);
}

// Code that others could have replaced never runs in the daemon (issue 6).
TEST_F(PluginHostTest, WorldWritablePluginFilesAndFoldersAreRefused) {
  PluginHost host;
  const std::string copy = tmp_.file("writable.so");
  fs::copy_file(fixture("good"), copy);
  ::chmod(copy.c_str(), 0666);
  Status st = host.load_file(copy);
  EXPECT_EQ(st.code(), Code::failed_precondition);
  EXPECT_TRUE(contains(st.message(), "world-writable")) << st.message();
  EXPECT_TRUE(contains(st.hint(), "chmod o-w")) << st.hint();
  ::chmod(copy.c_str(), 0644);
  ::chmod(tmp_.path().c_str(), 0777);
  st = host.load_file(copy);
  EXPECT_EQ(st.code(), Code::failed_precondition);
  EXPECT_TRUE(contains(st.message(), "plugin folder")) << st.message();
  ::chmod(tmp_.path().c_str(), 0700);
  EXPECT_TRUE(host.load_file(copy).ok());
  EXPECT_TRUE(host.plugins().size() == 1u);
}

TEST_F(PluginHostTest, SessionCreateFailureCarriesPluginMessage) {
  PluginHost host;
  ASSERT_TRUE(host.load_file(fixture("session_fails")).ok());
  auto r = host.create_session("session_fails", "null", "{}", "{}");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Code::invalid_argument);
  const std::string m = r.status().message();
  EXPECT_TRUE(contains(m, "plugin 'session_fails' could not start method 'null'")) << m;
  EXPECT_TRUE(contains(m, "PROCAM_ERR_INVALID_ARGUMENT")) << m;
  EXPECT_TRUE(contains(m, "this fixture refuses every session")) << m;
  // The fixture fills the whole buffer without a NUL: the copy stops at 512.
  const size_t at = m.find("null plugin:");
  ASSERT_NE(at, std::string::npos);
  EXPECT_EQ(m.size() - at, sizeof(procam_error::message)) << m;
}

TEST_F(PluginHostTest, BadOutputNameIsRejected) {
  PluginHost host;
  ASSERT_TRUE(host.load_file(fixture("bad_outputs")).ok());
  auto s = host.create_session("bad_outputs", "null", "{}", "{}");
  ASSERT_TRUE(s.ok()) << s.status().to_string();
  run_null_scan(*s, 1);
  auto outs = s->outputs();
  ASSERT_FALSE(outs.ok());
  EXPECT_EQ(outs.status().code(), Code::plugin_error);
  EXPECT_TRUE(contains(outs.status().message(), "plugin 'bad_outputs'")) << outs.status().message();
  EXPECT_TRUE(contains(outs.status().message(), "\"../evil\"")) << outs.status().message();
  EXPECT_TRUE(contains(outs.status().message(), "file names")) << outs.status().message();
}

TEST_F(PluginHostTest, BadPlanLabelIsRejected) {
  PluginHost host;
  ASSERT_TRUE(host.load_file(fixture("bad_plan")).ok());
  auto s = host.create_session("bad_plan", "null", "{}", "{}");
  ASSERT_TRUE(s.ok()) << s.status().to_string();
  auto plan = s->next_plan();
  ASSERT_FALSE(plan.ok());
  EXPECT_EQ(plan.status().code(), Code::plugin_error);
  const std::string m = plan.status().message();
  EXPECT_TRUE(contains(m, "plugin 'bad_plan' returned an invalid plan (round 1)")) << m;
  EXPECT_TRUE(contains(m, "frame 0 label \"../up\" contains a path separator")) << m;
  // The round never opened.
  Image frame(4, 3, PixelType::u8);
  EXPECT_EQ(s->add_frame(0, frame.view()).code(), Code::failed_precondition);
}

// ---------------------------------------------------------------- directories

TEST_F(PluginHostTest, LoadDirectoriesSortsSkipsAndRecords) {
  // The timeout applies to every probe here, good ones too: generous enough
  // for a loaded CI machine, short enough to keep hang_on_load cheap.
  PluginHost host(LoadOptions{.probe_in_child = true, .probe_timeout = 1500ms});
  // Listed twice (second time via "/."): scanned once, no duplicate-name rejections.
  host.load_directories(
      {PROCAM_HOST_FIXTURE_DIR, tmp_.file("does-not-exist"), PROCAM_HOST_FIXTURE_DIR "/."});
  std::vector<std::string> names;
  for (const auto& p : host.plugins()) names.push_back(p.name);
  // Loaded in file-name order: bad_outputs.so, bad_plan.so, good.so,
  // host_services.so, sdk_host_services.so, session_fails.so, v1_host.so, v1_table.so,
  // v2_frames.so.
  EXPECT_EQ(names, (std::vector<std::string>{"bad_outputs", "bad_plan", "null", "host_services",
                                             "sdk_host_services", "session_fails", "v1_host",
                                             "v1_table", "v2_frames"}));
  std::vector<std::string> rejected;
  for (const auto& r : host.rejected()) rejected.push_back(fs::path(r.file).filename().string());
  EXPECT_EQ(rejected, (std::vector<std::string>{"bad_magic.so", "crash_in_describe.so",
                                                "crash_on_load.so", "create_returns_null.so",
                                                "hang_on_load.so", "missing_create.so",
                                                "no_info.so", "null_function.so", "wrong_abi.so"}));
  EXPECT_FALSE(fs::exists(marker_));
  EXPECT_TRUE(no_children());
  auto s = host.create_session("null", "null", "{}", "{}");
  ASSERT_TRUE(s.ok()) << s.status().to_string();
  run_null_scan(*s, 5);
}

TEST_F(PluginHostTest, DuplicateNamesAndNonPluginEntries) {
  fs::copy_file(fixture("good"), tmp_.file("a.so"));
  fs::copy_file(fixture("good"), tmp_.file("b.so"));
  std::ofstream(tmp_.file("notes.txt")) << "not a plugin";
  std::ofstream(tmp_.file(".so")) << "no stem";
  fs::create_directory(tmp_.file("dir.so"));
  std::ofstream(tmp_.file("dir.so/inner.so")) << "not scanned: not recursive";
  PluginHost host;
  host.load_directories({tmp_.path()});
  ASSERT_EQ(host.plugins().size(), 1u);
  EXPECT_EQ(host.plugins()[0].file, tmp_.file("a.so"));
  ASSERT_EQ(host.rejected().size(), 1u);
  const Rejected& r = host.rejected()[0];
  EXPECT_EQ(r.file, tmp_.file("b.so"));
  EXPECT_EQ(r.error.code(), Code::failed_precondition);
  EXPECT_TRUE(contains(r.error.message(), "duplicate plugin name 'null', first loaded from '" +
                                              tmp_.file("a.so") + "'"))
      << r.error.message();

  // A plugin directory that is a file is recorded, not fatal.
  PluginHost other;
  other.load_directories({tmp_.file("notes.txt")});
  ASSERT_EQ(other.rejected().size(), 1u);
  EXPECT_EQ(other.rejected()[0].error.code(), Code::io_error);
  EXPECT_TRUE(other.plugins().empty());
}

}  // namespace
}  // namespace procam::host
