// SPDX-License-Identifier: MIT
// Shared by the isolation benchmarks: one PluginHost per (plugin file,
// isolation mode), loaded once and kept for the whole run (never destroyed:
// sessions may still hold it at exit). Aborts if the file does not load, so
// a benchmark never times a broken setup.
#pragma once

#include <cstdlib>
#include <map>
#include <string>
#include <tuple>
#include <utility>

#include "procam/host/plugin_host.hpp"

namespace procam::host::bench {

// `max_idle_workers` > 0: isolated sessions reuse warm workers
// (IsolationOptions::max_idle_workers; README.md "Worker reuse");
// `freeze_outputs` false: the daemon copies their outputs out of the arena
// instead of freezing the worker (IsolationOptions::freeze_outputs).
inline PluginHost& host_with(const std::string& plugin_file, Isolation mode, uint32_t max_idle_workers = 0,
                             bool freeze_outputs = true) {
  static auto* hosts = new std::map<std::tuple<std::string, Isolation, uint32_t, bool>, PluginHost*>();
  PluginHost*& h = (*hosts)[{plugin_file, mode, max_idle_workers, freeze_outputs}];
  if (h == nullptr) {
    h = new PluginHost();
    if (!h->load_file(plugin_file).ok()) std::abort();
    IsolationOptions iso;
    iso.mode = mode;
    iso.max_idle_workers = max_idle_workers;
    iso.freeze_outputs = freeze_outputs;
    h->set_isolation(iso);
  }
  return *h;
}

}  // namespace procam::host::bench
