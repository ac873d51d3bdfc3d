// SPDX-License-Identifier: MIT
// CLI commands for running procamd as a service: keygen (CURVE key pairs for
// remote access), cancel (a queued or running scan), ping (liveness).
#include <sys/stat.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>

#include "cli.hpp"

namespace procam::cli {

namespace {
// Writes `text` to `path` with `mode`, refusing to overwrite an existing file.
Status write_new_file(const std::string& path, const std::string& text, mode_t mode) {
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0)
    return Error(Code::failed_precondition, "'" + path + "' already exists; not overwriting a key",
                 "choose another --out name or remove the old file first");
  const mode_t old = ::umask(0077);
  std::ofstream out(path, std::ios::trunc);
  ::umask(old);
  out << text;
  out.close();
  if (!out) return Error(Code::io_error, "cannot write '" + path + "'");
  ::chmod(path.c_str(), mode);
  return Status::Ok();
}
}  // namespace

int cmd_keygen(const Args& a) {
  if (!a.has("out")) return usage_error("keygen needs --out NAME (writes NAME.pub and NAME.secret)");
  auto kp = client::generate_keypair();
  if (!kp) return report(kp.status());
  const std::string base = a.get("out");
  const std::string note = "# procam CURVE key (Z85), made by `procam keygen`\n";
  if (auto s = write_new_file(base + ".secret", note + "# SECRET: keep it private (mode 600)\n" + kp->second + "\n", 0600);
      !s)
    return report(s);
  if (auto s = write_new_file(base + ".pub", note + kp->first + "\n", 0644); !s) return report(s);
  if (a.json) {
    std::cout << nlohmann::json{{"public", kp->first}, {"public_file", base + ".pub"}, {"secret_file", base + ".secret"}}
                     .dump(2)
              << "\n";
    return 0;
  }
  std::printf("public key  %s\n  written to %s.pub\nsecret key written to %s.secret (mode 600)\n", kp->first.c_str(),
              base.c_str(), base.c_str());
  std::printf("daemon: point curve.secret_key_file at the .secret file; clients: add the .pub line to\n"
              "the daemon's authorized_keys file. See README \"Remote access with CURVE keys\".\n");
  return 0;
}

int cmd_cancel(const Args& a) {
  if (!a.has("scan")) return usage_error("cancel needs --scan ID");
  client::Client c = a.connect();
  auto r = c.call(proto::Cancel{a.get("scan")});
  if (!r) return report(r.status());
  if (a.json) {
    std::cout << r->dump(2) << "\n";
    return 0;
  }
  std::printf("scan %s: was %s, now %s\n", r->value("scan_id", "").c_str(), r->value("previous_state", "").c_str(),
              r->value("state", "").c_str());
  return 0;
}

int cmd_ping(const Args& a) {
  client::Client c = a.connect();
  const auto t0 = std::chrono::steady_clock::now();
  auto r = c.call(proto::Ping{});
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  if (!r) return report(r.status());
  if (a.json) {
    (*r)["round_trip_ms"] = ms;
    std::cout << r->dump(2) << "\n";
    return 0;
  }
  std::printf("procamd at %s alive: up %.0f s, round trip %.2f ms\n", c.endpoint().c_str(), r->value("uptime_s", 0.0),
              ms);
  return 0;
}

}  // namespace procam::cli
