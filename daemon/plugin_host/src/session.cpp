// SPDX-License-Identifier: MIT
// Session: one scan on a plugin method; validates everything the plugin returns.
#include <cmath>
#include <cstring>
#include <set>
#include <utility>

#include "host_services.hpp"
#include "plugin_loader.hpp"
#include "procam/core/image.hpp"
#include "procam/host/plugin_host.hpp"
#include "session_checks.hpp"
#include "worker_proxy.hpp"

namespace procam::host {

Session::Session(std::shared_ptr<const detail::LoadedPlugin> plugin, procam_session* session,
                 std::string method, std::unique_ptr<detail::HostBridge> bridge)
    : plugin_(std::move(plugin)),
      session_(session),
      method_(std::move(method)),
      bridge_(std::move(bridge)) {}

Session::Session(std::shared_ptr<const detail::LoadedPlugin> plugin, std::unique_ptr<detail::WorkerProxy> proxy,
                 std::string method, std::unique_ptr<detail::HostBridge> bridge)
    : plugin_(std::move(plugin)),
      method_(std::move(method)),
      bridge_(std::move(bridge)),
      proxy_(std::move(proxy)) {
  proxy_->set_bridge(bridge_.get());
}

int Session::worker_pid() const { return proxy_ ? proxy_->pid() : -1; }

Session::Session(Session&& o) noexcept
    : plugin_(std::move(o.plugin_)),
      session_(std::exchange(o.session_, nullptr)),
      method_(std::move(o.method_)),
      in_round_(o.in_round_),
      finished_(o.finished_),
      plan_promised_(o.plan_promised_),
      rounds_(o.rounds_),
      added_(std::move(o.added_)),
      bridge_(std::move(o.bridge_)),
      proxy_(std::move(o.proxy_)),
      idle_(std::move(o.idle_)) {}

Session& Session::operator=(Session&& o) noexcept {
  if (this != &o) {
    end_worker();  // the old worker ends or goes idle, judged by the old session's state
    if (session_ != nullptr) plugin_->vtable->session_destroy(session_);
    plugin_ = std::move(o.plugin_);
    session_ = std::exchange(o.session_, nullptr);
    method_ = std::move(o.method_);
    in_round_ = o.in_round_;
    finished_ = o.finished_;
    plan_promised_ = o.plan_promised_;
    rounds_ = o.rounds_;
    added_ = std::move(o.added_);
    proxy_ = std::move(o.proxy_);
    idle_ = std::move(o.idle_);
    bridge_ = std::move(o.bridge_);  // after session_destroy of the old session
  }
  return *this;
}

Session::~Session() {
  if (session_ != nullptr) plugin_->vtable->session_destroy(session_);
  end_worker();  // the worker ends or goes idle (before the bridge it reports to)
  // plugin_ (and with it possibly the library) and bridge_ are released after the session.
}

void Session::end_worker() {
  if (!proxy_) return;
  // Clean: the scan ran to its end (or stop()) with no round open; the
  // proxy itself knows whether any call faulted or was refused.
  const bool clean = finished_ && !in_round_;
  if (auto pool = idle_.lock()) pool->give(std::move(proxy_), clean);
  proxy_.reset();
}

void Session::set_log_handler(LogHandler handler) {
  if (bridge_) bridge_->set_log_handler(std::move(handler));
}

void Session::set_progress_handler(ProgressHandler handler) {
  if (bridge_) bridge_->set_progress_handler(std::move(handler));
}

const std::string& Session::plugin_name() const {
  static const std::string none;
  return plugin_ ? plugin_->name : none;
}

Status Session::plugin_failure(const char* call, int rc, const procam_error& err) const {
  if (rc < 0)
    return Error(detail::code_for_rc(rc), "plugin '" + plugin_->name + "' " + call + " failed (" +
                                         detail::rc_name(rc) + "): " + detail::error_message(err));
  return Error(Code::plugin_error, "plugin '" + plugin_->name + "' " + call + " returned " +
                                       detail::rc_name(rc) +
                                       ", which the plugin ABI does not allow");
}

Result<std::optional<Plan>> Session::next_plan() {
  if (moved_from()) return Error(Code::failed_precondition, "session was moved from");
  if (in_round_)
    return Error(Code::failed_precondition,
                 "next_plan called before end_round of the current round");
  if (finished_) return std::optional<Plan>{};
  plan_promised_ = false;
  const std::string who = "plugin '" + plugin_->name + "'";
  if (rounds_ >= kMaxRounds)
    return Error(Code::plugin_error, who + " asked for more than " + std::to_string(kMaxRounds) +
                                         " rounds; the scan was stopped");
  if (proxy_) {
    auto r = proxy_->next_plan(rounds_ + 1);
    if (!r) return r.status();
    if (!r->has_value()) {
      finished_ = true;
    } else {
      ++rounds_;
      in_round_ = true;
      added_.assign((*r)->frames.size(), false);
    }
    return r;
  }
  try {
    const procam_plan* plan = nullptr;
    procam_error err{};
    int rc = 0;
    {
      detail::HostBridge::CallScope scope(bridge_.get());  // host services allowed
      rc = plugin_->vtable->next_plan(session_, &plan, &err);
    }
    if (rc == 0) {
      finished_ = true;
      return std::optional<Plan>{};
    }
    if (rc != 1) return plugin_failure("next_plan", rc, err);

    auto checked = detail::plan_from_abi(plan, who, rounds_ + 1, plugin_->abi);
    if (!checked) return checked.status();
    Plan out = std::move(*checked);
    ++rounds_;
    in_round_ = true;
    added_.assign(out.frames.size(), false);
    return std::optional<Plan>(std::move(out));
  } catch (const std::exception& e) {
    return Error(Code::internal, who + " next_plan: " + e.what());
  }
}

Status Session::add_frame(uint32_t index, const procam_image& frame) {
  if (moved_from()) return Error(Code::failed_precondition, "session was moved from");
  if (!in_round_)
    return Error(Code::failed_precondition,
                 "add_frame called outside a round (call next_plan first)");
  if (index >= added_.size())
    return Error(Code::invalid_argument, "frame index " + std::to_string(index) +
                                             " is out of range: the plan has " +
                                             std::to_string(added_.size()) + " frames");
  if (added_[index])
    return Error(Code::failed_precondition,
                 "frame " + std::to_string(index) + " was already added");
  if (const char* p = validate_view(frame))
    return Error(Code::invalid_argument, "frame " + std::to_string(index) + ": " + p);
  if (proxy_) {
    PROCAM_TRY(proxy_->add_frame(index, frame));
    added_[index] = true;
    return {};
  }
  procam_error err{};
  int rc = 0;
  {
    detail::HostBridge::CallScope scope(bridge_.get());  // host services allowed
    rc = plugin_->vtable->add_frame(session_, index, &frame, &err);
  }
  if (rc != PROCAM_OK) return plugin_failure("add_frame", rc, err);
  added_[index] = true;
  return {};
}

Status Session::end_round(AfterRound after) {
  if (moved_from()) return Error(Code::failed_precondition, "session was moved from");
  if (!in_round_)
    return Error(Code::failed_precondition,
                 "end_round called outside a round (call next_plan first)");
  try {
    std::string missing;
    size_t n_missing = 0;
    for (size_t i = 0; i < added_.size(); ++i) {
      if (added_[i]) continue;
      if (++n_missing <= 10) missing += (missing.empty() ? "" : ", ") + std::to_string(i);
    }
    if (n_missing > 0)
      return Error(Code::failed_precondition,
                   std::to_string(n_missing) + " of " + std::to_string(added_.size()) +
                       " frames were not added (" + missing + (n_missing > 10 ? ", ..." : "") +
                       "): add every frame of the plan before end_round");
  } catch (const std::exception& e) {
    return Error(Code::internal, std::string("end_round: ") + e.what());
  }
  if (proxy_) {
    in_round_ = false;
    const bool ahead = after == AfterRound::next_plan;
    PROCAM_TRY(proxy_->end_round(added_.size(), ahead));
    plan_promised_ = ahead;
    return {};
  }
  procam_error err{};
  int rc = 0;
  {
    detail::HostBridge::CallScope scope(bridge_.get());  // host services allowed
    rc = plugin_->vtable->end_round(session_, &err);
  }
  in_round_ = false;  // after a failed decode the session should be discarded
  if (rc != PROCAM_OK) return plugin_failure("end_round", rc, err);
  plan_promised_ = after == AfterRound::next_plan;  // checked the same way in-process
  return {};
}

Status Session::stop() {
  if (moved_from()) return Error(Code::failed_precondition, "session was moved from");
  if (in_round_) return Error(Code::failed_precondition, "stop called during a round: call end_round first");
  if (rounds_ == 0) return Error(Code::failed_precondition, "stop called before any round was decoded");
  if (plan_promised_)
    return Error(Code::failed_precondition,
                 "stop called after end_round(AfterRound::next_plan), which promised next_plan: call next_plan, "
                 "or end the round with AfterRound::next_plan_or_stop where the host may stop");
  if (proxy_)
    if (Status s = proxy_->stop(); !s) return s;
  finished_ = true;
  return {};
}

Result<std::vector<Output>> Session::outputs() {
  if (moved_from()) return Error(Code::failed_precondition, "session was moved from");
  if (!finished_)
    return Error(Code::failed_precondition,
                 "outputs requested before the scan finished (next_plan has not returned "
                 "'no more rounds')");
  const std::string who = "plugin '" + plugin_->name + "'";
  if (proxy_) return proxy_->outputs();
  try {
    const procam_output* outs = nullptr;
    uint32_t count = 0;
    procam_error err{};
    int rc = 0;
    {
      detail::HostBridge::CallScope scope(bridge_.get());  // host services allowed
      rc = plugin_->vtable->get_outputs(session_, &outs, &count, &err);
    }
    if (rc != PROCAM_OK) return plugin_failure("get_outputs", rc, err);
    return detail::outputs_from_abi(outs, count, who);
  } catch (const std::exception& e) {
    return Error(Code::internal, who + " outputs: " + e.what());
  }
}

}  // namespace procam::host
