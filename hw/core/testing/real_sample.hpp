// SPDX-License-Identifier: MIT
// Where tests find the real captures (procam-calibration-sample, MIT): the
// folder shared/data beside the repository, or $PROCAM_DATA_DIR (a
// shared/data folder) for a checkout elsewhere. Tests that read it skip with
// a printed reason when it is absent (a user's clone has none).
// Needs PROCAM_SOURCE_DIR (procam_add_test defines it). Header-only.
#pragma once

#include <cstdlib>
#include <filesystem>

namespace procam::testing {

inline std::filesystem::path real_sample_dir() {
  const char* env = std::getenv("PROCAM_DATA_DIR");
  const std::filesystem::path data = env != nullptr && *env != 0
                                         ? std::filesystem::path(env)
                                         : std::filesystem::path(PROCAM_SOURCE_DIR) / ".." / "shared" / "data";
  return data / "real" / "procam-calibration-sample" / "sample_data";
}

}  // namespace procam::testing
