// SPDX-License-Identifier: MIT
// Scratch folders left behind by a daemon killed with SIGKILL (README.md
// "Least privilege"): a new daemon removes, when it sets up isolation, the
// procam-worker-<pid>-* folders whose daemon pid no longer exists, and
// leaves those of live daemons and anything else alone.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "procam/host/plugin_host.hpp"
#include "worker_proxy.hpp"

namespace procam::host {
namespace {
namespace fs = std::filesystem;

// A pid that existed and is gone now (a reaped child).
pid_t dead_pid() {
  const pid_t pid = ::fork();
  if (pid == 0) ::_exit(0);
  int st = 0;
  ::waitpid(pid, &st, 0);
  return pid;
}

fs::path make_folder(const fs::path& parent, const std::string& name) {
  const fs::path p = parent / name;
  fs::create_directories(p / "sub");
  std::ofstream(p / "sub" / "left-by-plugin") << "x";
  return p;
}

TEST(ScratchSweepTest, RemovesTheFoldersOfDeadDaemonsOnly) {
  std::string tmpl = (fs::temp_directory_path() / "procam-sweep-test-XXXXXX").string();
  ASSERT_NE(::mkdtemp(tmpl.data()), nullptr);
  const fs::path parent = tmpl;
  const pid_t gone = dead_pid();
  ASSERT_EQ(::kill(gone, 0), -1);  // really gone
  const fs::path stale1 = make_folder(parent, "procam-worker-" + std::to_string(gone) + "-abc123");
  const fs::path stale2 = make_folder(parent, "procam-worker-" + std::to_string(gone) + "-def456");
  const fs::path live = make_folder(parent, "procam-worker-" + std::to_string(::getpid()) + "-ghi789");
  const fs::path old_style = make_folder(parent, "procam-worker-Xy12Zq");  // no pid: not judged
  const fs::path other = make_folder(parent, "someone-else-" + std::to_string(gone));
  // A symlink named like a stale folder is not followed or removed.
  fs::create_directory_symlink(other, parent / ("procam-worker-" + std::to_string(gone) + "-link"));

  EXPECT_EQ(detail::sweep_stale_scratch(parent.string()), 2u);
  EXPECT_FALSE(fs::exists(stale1));
  EXPECT_FALSE(fs::exists(stale2));
  EXPECT_TRUE(fs::exists(live / "sub" / "left-by-plugin"));
  EXPECT_TRUE(fs::exists(old_style));
  EXPECT_TRUE(fs::exists(other / "sub" / "left-by-plugin"));
  EXPECT_TRUE(fs::is_symlink(parent / ("procam-worker-" + std::to_string(gone) + "-link")));

  // Through the daemon's start-up path: set_isolation sweeps its scratch parent.
  const fs::path stale3 = make_folder(parent, "procam-worker-" + std::to_string(gone) + "-jkl012");
  {
    PluginHost host;
    IsolationOptions iso;
    iso.scratch_parent = parent.string();
    iso.prestart = false;
    host.set_isolation(iso);
  }
  EXPECT_FALSE(fs::exists(stale3));
  EXPECT_TRUE(fs::exists(live));
  fs::remove_all(parent);
}

// A worker's own scratch folder carries its daemon's pid, so the sweep can judge it.
TEST(ScratchSweepTest, WorkerScratchFoldersNameTheirDaemon) {
  std::string tmpl = (fs::temp_directory_path() / "procam-sweep-test-XXXXXX").string();
  ASSERT_NE(::mkdtemp(tmpl.data()), nullptr);
  PluginHost host;
  ASSERT_TRUE(host.load_file(std::string(PROCAM_FAULTS_FIXTURE_DIR) + "/faults.so").ok());
  IsolationOptions iso;
  iso.scratch_parent = tmpl;
  host.set_isolation(iso);
  {
    auto s = host.create_session("faults", "ok", "{}", "{}");
    ASSERT_TRUE(s.ok()) << s.status().to_string();
    size_t n = 0;
    for (const auto& d : fs::directory_iterator(tmpl)) {
      ++n;
      EXPECT_EQ(d.path().filename().string().rfind("procam-worker-" + std::to_string(::getpid()) + "-", 0), 0u)
          << d.path();
    }
    EXPECT_EQ(n, 1u);
    // A live daemon's folder survives a sweep.
    EXPECT_EQ(detail::sweep_stale_scratch(tmpl), 0u);
  }
  fs::remove_all(tmpl);
}

}  // namespace
}  // namespace procam::host
