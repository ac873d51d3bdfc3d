// SPDX-License-Identifier: MIT
// GLFW projector: presenter thread, monitor selection, exact-pixel drawing, LUT, presentation stamps.
#include "procam/hw/glfw/glfw_projector.hpp"

#include <GLFW/glfw3.h>

#include <algorithm>
#include <cmath>
#include <condition_variable>
#include <cstdlib>
#include <ctime>
#include <mutex>
#include <set>
#include <thread>

#include "procam/base/clock.hpp"
#include "procam/core/image.hpp"
#include "procam/core/json_fields.hpp"
#include "procam/core/log.hpp"

namespace procam::glfw {
namespace {

std::mutex g_error_mu;
std::string g_last_error;  // last GLFW error message (GLFW reports through a callback)

void on_glfw_error(int code, const char* msg) {
  std::lock_guard lock(g_error_mu);
  g_last_error = "GLFW error " + std::to_string(code) + ": " + (msg ? msg : "");
}

std::string last_glfw_error() {
  std::lock_guard lock(g_error_mu);
  return g_last_error;
}

// GLFW keeps global state: one user at a time in this process.
std::mutex g_glfw_mu;

nlohmann::json monitors_json() {
  nlohmann::json out = nlohmann::json::array();
  int n = 0;
  GLFWmonitor** mons = glfwGetMonitors(&n);
  for (int i = 0; i < n; ++i) {
    int x = 0, y = 0;
    glfwGetMonitorPos(mons[i], &x, &y);
    const GLFWvidmode* m = glfwGetVideoMode(mons[i]);
    const char* name = glfwGetMonitorName(mons[i]);
    out.push_back({{"index", i},
                   {"name", name ? name : ""},
                   {"x", x},
                   {"y", y},
                   {"width", m ? m->width : 0},
                   {"height", m ? m->height : 0},
                   {"refresh_hz", m ? m->refreshRate : 0}});
  }
  return out;
}

std::string monitor_list_text(const nlohmann::json& mons) {
  std::string s;
  for (const auto& m : mons)
    s += (s.empty() ? "" : ", ") + std::to_string(m["index"].get<int>()) + ": '" + m["name"].get<std::string>() + "' " +
         std::to_string(m["width"].get<int>()) + "x" + std::to_string(m["height"].get<int>()) + "+" +
         std::to_string(m["x"].get<int>()) + "+" + std::to_string(m["y"].get<int>());
  return s.empty() ? "none" : s;
}

Status init_glfw() {
  glfwSetErrorCallback(&on_glfw_error);
  const char* display = std::getenv("DISPLAY");
  if (display == nullptr || *display == '\0')
    return Error(Code::unavailable, "glfw projector: no X display (DISPLAY is not set)",
                 "run on the projector's X server, or start one: scripts/xvfb.sh start (tests) / Xorg (real projector)");
  if (glfwInit() != GLFW_TRUE)
    return Error(Code::unavailable, std::string("glfw projector: glfwInit failed on DISPLAY=") + display + ": " + last_glfw_error(),
                 "check that the X server is running and reachable");
  return Status::Ok();
}

}  // namespace

Result<GlfwProjectorConfig> parse_glfw_projector_config(const nlohmann::json& j, const std::vector<std::string>& extra_keys) {
  GlfwProjectorConfig c;
  ParseErrors errors{"rig config", {}};
  FieldReader r(j, "projector", errors);
  std::vector<std::string> known = {"backend", "monitor", "name", "width", "height", "gamma", "lut", "keep_backbuffer"};
  known.insert(known.end(), extra_keys.begin(), extra_keys.end());
  r.only(known, "glfw projector keys: monitor (name or index), name, width, height, gamma | lut, keep_backbuffer");
  c.monitor = r.name_or_index("monitor", "");
  c.name = r.string("name", std::string());
  c.width = static_cast<uint32_t>(r.integer("width", 0, 0, 65536));
  c.height = static_cast<uint32_t>(r.integer("height", 0, 0, 65536));
  c.keep_backbuffer = r.boolean("keep_backbuffer", false);
  if (!errors.ok()) return errors.first;
  if (r.has("gamma") && r.has("lut"))
    return Error(Code::invalid_argument, "rig config: projector: give either gamma or lut, not both");
  if (r.has("gamma")) {
    const double g = r.number("gamma", std::nullopt);
    if (!errors.ok()) return errors.first;
    if (!(g > 0.1 && g < 10)) return Error(Code::invalid_argument, "rig config: projector.gamma: must be in (0.1, 10)");
    for (int v = 0; v < 256; ++v)
      c.lut[static_cast<size_t>(v)] = static_cast<uint8_t>(std::lround(255.0 * std::pow(v / 255.0, 1.0 / g)));
    c.has_lut = g != 1.0;
  }
  if (const nlohmann::json* l = r.get("lut")) {
    if (!l->is_array() || l->size() != 256)
      return Error(Code::invalid_argument, "rig config: projector.lut: must be an array of 256 values in [0, 255]");
    for (size_t v = 0; v < 256; ++v) {
      const auto& e = (*l)[v];
      if (!e.is_number_integer() || e.get<int64_t>() < 0 || e.get<int64_t>() > 255)
        return Error(Code::invalid_argument, "rig config: projector.lut[" + std::to_string(v) + "]: must be in [0, 255]");
      c.lut[v] = static_cast<uint8_t>(e.get<int64_t>());
    }
    c.has_lut = true;
  }
  return c;
}

Result<nlohmann::json> list_glfw_monitors() {
  std::lock_guard lock(g_glfw_mu);
  PROCAM_TRY(init_glfw());
  auto out = monitors_json();
  glfwTerminate();
  return out;
}

struct GlfwProjector::Impl {
  GlfwProjectorConfig config;
  std::thread thread;
  std::unique_lock<std::mutex> glfw_lock{g_glfw_mu, std::defer_lock};
  std::mutex mu;
  std::condition_variable cv;
  bool started = false, quit = false;
  Status start_status;
  uint32_t width = 0, height = 0;
  std::string monitor_name;
  int32_t mx = 0, my = 0;
  double refresh_hz = 60;
  // request (bottom row first, 8-bit grey after LUT)
  std::vector<uint8_t> pending;
  uint64_t pending_id = 0;
  bool has_pending = false;
  // presented
  uint64_t presented_id = 0;
  int64_t presented_ns = 0;
  std::vector<uint8_t> backbuffer;  // top row first
  std::string draw_error;

  void run();
};

void GlfwProjector::Impl::run() {
  auto fail = [&](Status s) {
    std::lock_guard lock(mu);
    start_status = std::move(s);
    started = true;
    cv.notify_all();
  };
  Status s = init_glfw();
  if (!s) return fail(s);
  int n = 0;
  GLFWmonitor** mons = glfwGetMonitors(&n);
  const auto list = monitors_json();
  GLFWmonitor* mon = nullptr;
  if (config.monitor.empty()) {
    mon = glfwGetPrimaryMonitor();
  } else {
    for (int i = 0; i < n && !mon; ++i) {
      const char* name = glfwGetMonitorName(mons[i]);
      if ((name && config.monitor == name) || config.monitor == std::to_string(i)) mon = mons[i];
    }
  }
  if (!mon) {
    glfwTerminate();
    return fail(Error(Code::not_found,
                      "glfw projector: no monitor '" + (config.monitor.empty() ? std::string("<primary>") : config.monitor) + "'",
                      "monitors on DISPLAY=" + std::string(std::getenv("DISPLAY") ? std::getenv("DISPLAY") : "") + ": " +
                          monitor_list_text(list)));
  }
  const GLFWvidmode* mode = glfwGetVideoMode(mon);
  glfwGetMonitorPos(mon, &mx, &my);
  monitor_name = glfwGetMonitorName(mon) ? glfwGetMonitorName(mon) : "";
  if (!mode) {
    glfwTerminate();
    return fail(Error(Code::unavailable, "glfw projector: monitor '" + monitor_name + "' has no video mode"));
  }
  if ((config.width && static_cast<uint32_t>(mode->width) != config.width) ||
      (config.height && static_cast<uint32_t>(mode->height) != config.height)) {
    glfwTerminate();
    return fail(Error(Code::invalid_argument,
                      "glfw projector: monitor '" + monitor_name + "' runs " + std::to_string(mode->width) + "x" +
                          std::to_string(mode->height) + " but the rig config says " + std::to_string(config.width) +
                          "x" + std::to_string(config.height),
                      "set the projector's native mode on the X server (xrandr) or fix the config"));
  }
  width = static_cast<uint32_t>(mode->width);
  height = static_cast<uint32_t>(mode->height);
  refresh_hz = mode->refreshRate > 0 ? mode->refreshRate : 60;
  glfwWindowHint(GLFW_DECORATED, GLFW_FALSE);
  glfwWindowHint(GLFW_AUTO_ICONIFY, GLFW_FALSE);
  glfwWindowHint(GLFW_FLOATING, GLFW_TRUE);
  glfwWindowHint(GLFW_RED_BITS, mode->redBits);
  glfwWindowHint(GLFW_GREEN_BITS, mode->greenBits);
  glfwWindowHint(GLFW_BLUE_BITS, mode->blueBits);
  glfwWindowHint(GLFW_REFRESH_RATE, mode->refreshRate);
  glfwWindowHint(GLFW_SRGB_CAPABLE, GLFW_FALSE);
  GLFWwindow* win = glfwCreateWindow(mode->width, mode->height, "procam projector", mon, nullptr);
  if (!win) {
    glfwTerminate();
    return fail(Error(Code::unavailable, "glfw projector: cannot open a fullscreen window on '" + monitor_name + "': " + last_glfw_error()));
  }
  glfwMakeContextCurrent(win);
  glfwSwapInterval(1);
  int fw = 0, fh = 0;
  glfwGetFramebufferSize(win, &fw, &fh);
  if (static_cast<uint32_t>(fw) != width || static_cast<uint32_t>(fh) != height) {
    glfwDestroyWindow(win);
    glfwTerminate();
    return fail(Error(Code::unavailable, "glfw projector: framebuffer is " + std::to_string(fw) + "x" + std::to_string(fh) +
                                             ", monitor mode " + std::to_string(width) + "x" + std::to_string(height),
                      "the window manager resized the window; run without one or make the window fullscreen-exempt"));
  }
  // Exact pixel path: no blending, dithering, filtering; 1-byte rows.
  glDisable(GL_DITHER);
  glDisable(GL_BLEND);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glViewport(0, 0, fw, fh);
  glMatrixMode(GL_PROJECTION);
  glLoadIdentity();
  glOrtho(0, fw, 0, fh, -1, 1);
  glMatrixMode(GL_MODELVIEW);
  glLoadIdentity();
  glPixelZoom(1.0f, 1.0f);
  glClearColor(0, 0, 0, 1);
  glClear(GL_COLOR_BUFFER_BIT);
  glfwSwapBuffers(win);
  {
    std::lock_guard lock(mu);
    started = true;
    cv.notify_all();
  }
  PROCAM_LOG(hw, info) << "glfw projector: fullscreen " << width << "x" << height << " on '" << monitor_name << "' at +" << mx
                       << "+" << my;
  std::vector<uint8_t> frame, readback;
  for (;;) {
    uint64_t id = 0;
    {
      std::unique_lock lock(mu);
      cv.wait_for(lock, std::chrono::milliseconds(20), [&] { return quit || has_pending; });
      if (quit) break;
      if (!has_pending) {
        lock.unlock();
        glfwPollEvents();
        continue;
      }
      frame.swap(pending);
      id = pending_id;
      has_pending = false;
    }
    glRasterPos2i(0, 0);
    glDrawPixels(static_cast<GLsizei>(width), static_cast<GLsizei>(height), GL_LUMINANCE, GL_UNSIGNED_BYTE, frame.data());
    if (config.keep_backbuffer) {
      readback.resize(size_t{width} * height);
      glReadBuffer(GL_BACK);
      glReadPixels(0, 0, static_cast<GLsizei>(width), static_cast<GLsizei>(height), GL_RED, GL_UNSIGNED_BYTE, readback.data());
    }
    glfwSwapBuffers(win);
    glFinish();
    const int64_t t = mono_ns();
    const GLenum err = glGetError();
    glfwPollEvents();
    std::lock_guard lock(mu);
    if (err != GL_NO_ERROR) draw_error = "OpenGL error " + std::to_string(err) + " while drawing pattern " + std::to_string(id);
    if (config.keep_backbuffer) {
      backbuffer.resize(readback.size());
      for (uint32_t y = 0; y < height; ++y)  // GL rows are bottom first
        std::copy_n(readback.data() + size_t{height - 1 - y} * width, width, backbuffer.data() + size_t{y} * width);
    }
    presented_id = id;
    presented_ns = t;
    cv.notify_all();
  }
  glfwDestroyWindow(win);
  glfwTerminate();
}

Result<std::unique_ptr<GlfwProjector>> GlfwProjector::open(const GlfwProjectorConfig& config) {
  std::unique_ptr<GlfwProjector> p(new GlfwProjector());
  p->impl_ = std::make_unique<Impl>();
  Impl& d = *p->impl_;
  d.config = config;
  if (!d.glfw_lock.try_lock())
    return Error(Code::unavailable, "glfw projector: another GLFW projector is open in this process",
                 "one glfw projector per process");
  d.thread = std::thread([&d] { d.run(); });
  {
    std::unique_lock lock(d.mu);
    d.cv.wait(lock, [&] { return d.started; });
  }
  if (!d.start_status.ok()) {
    d.thread.join();
    return d.start_status;
  }
  p->info_.backend = "glfw";
  p->info_.name = config.name.empty() ? d.monitor_name : config.name;
  p->info_.width = d.width;
  p->info_.height = d.height;
  p->info_.refresh_hz = d.refresh_hz;
  const char* disp = std::getenv("DISPLAY");
  p->info_.display = disp ? disp : "";
  p->info_.screen_x = d.mx;
  p->info_.screen_y = d.my;
  return p;
}

GlfwProjector::~GlfwProjector() {
  if (!impl_) return;
  {
    std::lock_guard lock(impl_->mu);
    impl_->quit = true;
    impl_->cv.notify_all();
  }
  if (impl_->thread.joinable()) impl_->thread.join();
}

Status GlfwProjector::show(const procam_image& pattern, uint64_t pattern_id) {
  if (const char* why = validate_view(pattern)) return Error(Code::invalid_argument, std::string("glfw projector: bad pattern: ") + why);
  if (pattern.width != info_.width || pattern.height != info_.height || pattern.channels != 1)
    return Error(Code::invalid_argument, "glfw projector: pattern is " + std::to_string(pattern.width) + "x" +
                                             std::to_string(pattern.height) + "x" + std::to_string(pattern.channels) +
                                             ", projector is " + std::to_string(info_.width) + "x" + std::to_string(info_.height) + "x1");
  Impl& d = *impl_;
  std::vector<uint8_t> buf(size_t{info_.width} * info_.height);
  const auto* base = static_cast<const uint8_t*>(pattern.data);
  for (uint32_t y = 0; y < info_.height; ++y) {
    const uint8_t* row = base + size_t{y} * pattern.stride_bytes;
    uint8_t* out = buf.data() + size_t{info_.height - 1 - y} * info_.width;  // GL rows bottom first
    for (uint32_t x = 0; x < info_.width; ++x) {
      uint8_t v = 0;
      if (pattern.pixel_type == PROCAM_PIXEL_U8) {
        v = row[x];
      } else if (pattern.pixel_type == PROCAM_PIXEL_U16) {
        const uint16_t w = reinterpret_cast<const uint16_t*>(row)[x];
        const uint32_t bits = pattern.bit_depth ? pattern.bit_depth : 16;
        const double maxv = static_cast<double>((1u << bits) - 1);
        v = static_cast<uint8_t>(std::lround(std::min(1.0, w / maxv) * 255.0));
      } else {
        const float f = reinterpret_cast<const float*>(row)[x];
        v = static_cast<uint8_t>(std::lround(std::clamp(static_cast<double>(f), 0.0, 1.0) * 255.0));
      }
      out[x] = d.config.has_lut ? d.config.lut[v] : v;
    }
  }
  std::lock_guard lock(d.mu);
  if (!d.draw_error.empty()) return Error(Code::io_error, "glfw projector: " + d.draw_error);
  d.pending.swap(buf);
  d.pending_id = pattern_id;
  d.has_pending = true;
  d.cv.notify_all();
  return Status::Ok();
}

Result<hw::Presentation> GlfwProjector::wait_presented(uint64_t pattern_id, std::chrono::milliseconds timeout) {
  Impl& d = *impl_;
  std::unique_lock lock(d.mu);
  if (!d.cv.wait_for(lock, timeout, [&] { return d.presented_id == pattern_id && !d.has_pending; }))
    return Error(Code::timeout, "glfw projector: pattern " + std::to_string(pattern_id) + " not presented within " +
                                    std::to_string(timeout.count()) + " ms");
  return hw::Presentation{pattern_id, d.presented_ns};
}

Status GlfwProjector::set_focus_mm(double focus_mm) {
  if (std::isnan(focus_mm) || focus_mm <= 0) return Status::Ok();
  return Error(Code::failed_precondition, "glfw projector: fixed focus (a display cannot refocus)",
               "remove projector_focus_mm from the plan");
}

Status GlfwProjector::set_polarizer_deg(double deg) {
  if (std::isnan(deg)) return Status::Ok();
  return Error(Code::failed_precondition,
               "glfw projector: no motorised polariser (the plan asks for projector_polarizer_deg " +
                   std::to_string(deg) + ")",
               "remove projector_polarizer_deg from the plan or use a rig with a motorised polariser");
}

std::vector<uint8_t> GlfwProjector::last_backbuffer() const {
  std::lock_guard lock(impl_->mu);
  return impl_->backbuffer;
}

}  // namespace procam::glfw
