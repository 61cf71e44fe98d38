// The Blender renderer (vdrig/sim/blender.hpp) and the "blender" camera backend (docs/blender.md).
#include "blender_camera.hpp"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "vdrig/core/file_write.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/core/log.hpp"
#include "vdrig/core/settings.hpp"
#include "vdrig/sim/blender.hpp"
#include "vdrig/sim/renderer.hpp"
#include "vdrig/sim/scene_file.hpp"

extern char** environ;

namespace vdrig::sim {

using nlohmann::json;
namespace fs = std::filesystem;

Result<BlenderSettings> BlenderSettings::parse(const json& section) {
  BlenderSettings b;
  Settings s(section, "camera blender", {"backend"});
  s.reject_unknown({"executable", "samples", "seed", "threads", "timeout_s", "startup_timeout_s", "blend", "markers"});
  b.executable = s.string("executable", b.executable);
  b.samples = static_cast<int>(s.integer("samples", b.samples, 1, 4096));
  b.seed = s.unsigned_integer("seed", b.seed);
  b.threads = static_cast<int>(s.integer("threads", b.threads, 1, 256));
  b.timeout_s = s.number("timeout_s", b.timeout_s, 0.1);
  b.startup_timeout_s = s.number("startup_timeout_s", b.startup_timeout_s, 0.1);
  b.blend = s.string("blend", b.blend);
  b.markers = s.boolean("markers", b.markers);
  if (b.executable.empty()) s.fail("executable: must not be empty");
  if (!b.blend.empty() && fs::path(b.blend).extension() != ".blend") s.fail("blend: must name a .blend file");
  if (!s.is_valid(nullptr)) return s.error();
  return b;
}

json BlenderSettings::effective() const {
  return {{"backend", "blender"},
          {"executable", executable},
          {"samples", samples},
          {"seed", seed},
          {"threads", threads},
          {"timeout_s", timeout_s},
          {"startup_timeout_s", startup_timeout_s},
          {"blend", blend},
          {"markers", markers}};
}

BlenderRenderer::BlenderRenderer(BlenderSettings settings) : settings_(std::move(settings)) {}

BlenderRenderer::~BlenderRenderer() {
  stop(false);
  std::error_code ec;
  if (!dir_.empty()) fs::remove_all(dir_, ec);
}

namespace {

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

bool has_distortion(const CameraModel& c) { return c.k1 != 0 || c.k2 != 0 || c.p1 != 0 || c.p2 != 0 || c.k3 != 0; }

}  // namespace

std::string BlenderRenderer::log_tail() const {
  std::ifstream in(dir_ / "blender.log");
  std::string line;
  std::vector<std::string> lines;
  while (std::getline(in, line))
    if (!line.empty()) lines.push_back(line);
  std::string tail;
  for (size_t i = lines.size() > 6 ? lines.size() - 6 : 0; i < lines.size(); ++i) tail += "\n  " + lines[i];
  return tail.empty() ? " (its log is empty)" : "; the end of its log:" + tail;
}

void BlenderRenderer::stop(bool kill_now) {
  if (pid_ > 0) {
    if (!kill_now && socket_ >= 0) {
      const std::string quit = "{\"cmd\": \"quit\"}\n";
      (void)send(socket_, quit.data(), quit.size(), MSG_NOSIGNAL);
      for (int i = 0; i < 50; ++i) {  // up to 5 s for a clean exit
        if (waitpid(pid_, nullptr, WNOHANG) == pid_) {
          pid_ = -1;
          break;
        }
        usleep(100000);
      }
    }
    if (pid_ > 0) {
      kill(pid_, SIGKILL);
      waitpid(pid_, nullptr, 0);
    }
  }
  pid_ = -1;
  if (socket_ >= 0) close(socket_);
  socket_ = -1;
  buffer_.clear();
  configured_ = false;
}

Status BlenderRenderer::ensure_running() {
  if (pid_ > 0 && configured_) return Status::ok();
  if (!scene_) return make_error(ErrorCode::kInvalidArgument, "blender: no scene set");
  if (pid_ <= 0) {
    std::error_code ec;
    if (dir_.empty()) {
      std::string pattern = (fs::temp_directory_path(ec) / "vdrig-blender-XXXXXX").string();
      if (!mkdtemp(pattern.data()))
        return make_error(ErrorCode::kIo, std::string("blender: cannot make a work folder: ") + std::strerror(errno));
      dir_ = pattern;
    }
    const fs::path script = dir_ / "vdrig_blender.py";
    VDRIG_TRY(write_file_atomic(script, blender_driver_script()));
    int sv[2];
    if (socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, sv) != 0)
      return make_error(ErrorCode::kIo, std::string("blender: socketpair: ") + std::strerror(errno));
    const std::string log = (dir_ / "blender.log").string();
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    // Commands arrive on stdin, answers leave on fd 3 (one socket); Blender's own messages go to the log.
    posix_spawn_file_actions_adddup2(&actions, sv[1], 0);
    posix_spawn_file_actions_adddup2(&actions, sv[1], 3);
    posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&actions, 1, 2);
    const std::string script_path = script.string();
    std::vector<std::string> args = {settings_.executable, "--background", "--factory-startup", "--python",
                                     script_path,          "--",           "--reply-fd",        "3"};
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    pid_t pid = -1;
    const auto start = std::chrono::steady_clock::now();
    const int rc = posix_spawnp(&pid, settings_.executable.c_str(), &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    close(sv[1]);
    if (rc != 0) {
      close(sv[0]);
      if (rc == ENOENT || rc == EACCES)
        return make_error(ErrorCode::kNotFound, "blender: cannot run \"" + settings_.executable + "\" (" +
                                                    std::strerror(rc) +
                                                    "): install Debian's blender package (scripts/setup) or set "
                                                    "the camera's \"executable\"");
      return make_error(ErrorCode::kDevice, "blender: cannot start: " + std::string(std::strerror(rc)));
    }
    pid_ = pid;
    socket_ = sv[0];
    auto ready = request(json(), settings_.startup_timeout_s);  // the driver's first line says it is ready
    if (!ready) return ready.error();
    startup_s_ = seconds_since(start);
    log::get("sim")->info("blender: Blender {} ready in {:.1f} s (pid {})", ready->value("blender", "?"), startup_s_,
                          pid_);
  }
  return setup();
}

namespace {

/// The kd of a printed material baked over `rect` (mm) into an EXR for the driver: vdrig's glyphs are hashed cells
/// that Blender's nodes cannot compute, so the texture holds them exactly (texels aligned with the cells, up to 4 a
/// cell and 4096 a side; the driver samples the nearest). Returns the rectangle the image covers.
Result<std::array<double, 4>> bake_printed_kd(const Scene& scene, int material, std::array<double, 4> rect,
                                              const fs::path& file) {
  const double u = scene.materials[material].print_cell_mm;
  rect = {std::floor(rect[0] / u) * u, std::floor(rect[1] / u) * u, std::ceil(rect[2] / u) * u,
          std::ceil(rect[3] / u) * u};
  const double cells_x = std::round((rect[2] - rect[0]) / u), cells_y = std::round((rect[3] - rect[1]) / u);
  const int k = std::max(1, std::min(4, static_cast<int>(4096 / std::max(cells_x, cells_y))));
  const int w = static_cast<int>(cells_x) * k, h = static_cast<int>(cells_y) * k;
  cv::Mat bgr(h, w, CV_32FC3);
  const Vec3d base = scene.materials[material].kd;
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) {
      const double x = rect[0] + (c + 0.5) * u / k, y = rect[3] - (r + 0.5) * u / k;
      const SurfacePoint sp = scene.surface_at(x, y);
      const Vec3d kd = sp.material == material ? sp.kd : base;
      bgr.at<cv::Vec3f>(r, c) =
          cv::Vec3f(static_cast<float>(kd.z()), static_cast<float>(kd.y()), static_cast<float>(kd.x()));
    }
  ExrImage image;
  image.add_bgr(bgr);
  VDRIG_TRY(write_exr(file, image, ExrPixelType::kHalf));
  return rect;
}

}  // namespace

Status BlenderRenderer::setup() {
  // Printed materials: their kd baked per patch (and for the background, over the whole surface).
  json baked = json::object();
  if (settings_.blend.empty()) {
    const Scene& sc = *scene_;
    const auto bake = [&](int key, int material, std::array<double, 4> rect) -> Status {
      if (!sc.materials[material].printed) return Status::ok();
      const fs::path file = dir_ / ("kd_" + std::to_string(key + 1) + ".exr");
      auto covered = bake_printed_kd(sc, material, rect, file);
      if (!covered) return covered.error();
      baked[std::to_string(key)] = {{"file", file.string()}, {"rect_mm", covered.value()}};
      return Status::ok();
    };
    VDRIG_TRY(bake(-1, 0, {-sc.width_mm / 2, -sc.height_mm / 2, sc.width_mm / 2, sc.height_mm / 2}));
    for (size_t i = 0; i < sc.patches.size(); ++i) {
      const Patch& p = sc.patches[i];
      VDRIG_TRY(bake(static_cast<int>(i), p.material, {p.x0_mm, p.y0_mm, p.x1_mm, p.y1_mm}));
    }
  }
  json camera = {{"width", pinhole_.width}, {"height", pinhole_.height}, {"fx", pinhole_.fx},
                 {"fy", pinhole_.fy},       {"cx", pinhole_.cx},         {"cy", pinhole_.cy}};
  json command = {{"cmd", "setup"},
                  {"scene", scene_to_json(*scene_)},
                  {"blend", settings_.blend.empty() ? std::string() : fs::absolute(settings_.blend).string()},
                  {"markers", settings_.markers},
                  {"baked_kd", baked},
                  {"camera", camera},
                  {"samples", settings_.samples},
                  {"seed", settings_.seed},
                  {"threads", settings_.threads}};
  auto answer = request(command, settings_.startup_timeout_s);
  if (!answer) return answer.error();
  if (!answer->value("ok", false))
    return make_error(ErrorCode::kInvalidArgument,
                      "blender: the scene was refused: " + answer->value("error", std::string("no reason given")));
  configured_ = true;
  return Status::ok();
}

Result<json> BlenderRenderer::request(const json& command, double timeout_s) {
  if (socket_ < 0) return make_error(ErrorCode::kDisconnected, "blender: not running");
  if (!command.is_null()) {
    const std::string line = command.dump() + "\n";
    size_t sent = 0;
    while (sent < line.size()) {
      const ssize_t n = send(socket_, line.data() + sent, line.size() - sent, MSG_NOSIGNAL);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) break;
      sent += static_cast<size_t>(n);
    }
    if (sent < line.size()) {
      const std::string tail = log_tail();
      stop(true);
      return make_error(ErrorCode::kDevice, "blender: the process went away (cannot send it a command)" + tail);
    }
  }
  const auto start = std::chrono::steady_clock::now();
  for (;;) {
    if (const size_t eol = buffer_.find('\n'); eol != std::string::npos) {
      const std::string line = buffer_.substr(0, eol);
      buffer_.erase(0, eol + 1);
      json answer = json::parse(line, nullptr, false);
      if (answer.is_discarded() || !answer.is_object())
        return make_error(ErrorCode::kDevice, "blender: unreadable answer: " + line.substr(0, 200));
      return answer;
    }
    const double left_s = timeout_s - seconds_since(start);
    if (left_s <= 0) {
      stop(true);
      return make_error(ErrorCode::kTimeout, "blender: no answer in " + std::to_string(timeout_s) +
                                                 " s (killed; the next capture starts a new Blender)");
    }
    pollfd p{socket_, POLLIN, 0};
    const int ready = poll(&p, 1, static_cast<int>(std::ceil(std::min(left_s, 1.0) * 1000)));
    if (ready < 0 && errno == EINTR) continue;
    if (ready <= 0) continue;
    char chunk[4096];
    const ssize_t n = recv(socket_, chunk, sizeof chunk, 0);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      int status = 0;
      std::string how = "closed its end";
      if (waitpid(pid_, &status, 0) == pid_) {
        how = WIFSIGNALED(status) ? "was killed by signal " + std::to_string(WTERMSIG(status))
                                  : "exited with status " + std::to_string(WEXITSTATUS(status));
        pid_ = -1;
      }
      const std::string tail = log_tail();
      stop(true);
      return make_error(ErrorCode::kDevice, "blender: the process " + how + tail);
    }
    buffer_.append(chunk, static_cast<size_t>(n));
  }
}

Status BlenderRenderer::set_scene(const Scene& scene, const CameraModel& camera) {
  std::string why;
  if (!camera.is_valid(&why)) return make_error(ErrorCode::kInvalidArgument, "blender: " + why);
  if (std::abs(camera.fx - camera.fy) > 1e-9 * camera.fx)
    return make_error(ErrorCode::kInvalidArgument, "blender: the camera needs square pixels (fx = fy)");
  scene_ = std::make_unique<Scene>(scene);
  camera_ = camera;
  pinhole_ = camera;
  pinhole_.k1 = pinhole_.k2 = pinhole_.p1 = pinhole_.p2 = pinhole_.k3 = 0;
  map_x_.release();
  map_y_.release();
  if (has_distortion(camera)) {
    // Blender's camera is an ideal pinhole: render a larger one and resample it where each distorted pixel's ray
    // lands (the ray table's undistortion, the one the simulator renders with).
    const RayTable rays(camera, 1);
    map_x_.create(camera.height, camera.width, CV_32F);
    map_y_.create(camera.height, camera.width, CV_32F);
    double margin = 0;
    for (int y = 0; y < camera.height; ++y)
      for (int x = 0; x < camera.width; ++x) {
        const cv::Vec3f r = rays.rays(x, y)[0];
        const double u = camera.fx * r[0] / r[2] + camera.cx, v = camera.fy * r[1] / r[2] + camera.cy;
        map_x_.at<float>(y, x) = static_cast<float>(u);
        map_y_.at<float>(y, x) = static_cast<float>(v);
        margin = std::max({margin, -u, -v, u - (camera.width - 1), v - (camera.height - 1)});
      }
    const int m = static_cast<int>(std::ceil(margin)) + 2;
    pinhole_.width += 2 * m;
    pinhole_.height += 2 * m;
    pinhole_.cx += m;
    pinhole_.cy += m;
    map_x_ += m;
    map_y_ += m;
  }
  if (pid_ > 0) return setup();
  configured_ = false;
  return Status::ok();
}

Result<cv::Mat> BlenderRenderer::render(const ViewPose& pose, bool lights) {
  VDRIG_TRY(ensure_running());
  // Camera to surface frame: the camera centre -R^T t (mm -> m) and its axes, the columns of R^T (OpenCV's).
  const Mat3d rt = pose.R.transpose();
  const Vec3d centre_m = -rt * pose.t / 1000.0;
  json m = json::array();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) m.push_back(rt(r, c));
    m.push_back(centre_m[r]);
  }
  for (double v : {0.0, 0.0, 0.0, 1.0}) m.push_back(v);
  const fs::path out = dir_ / ("view_" + std::to_string(renders_++) + ".exr");
  const auto start = std::chrono::steady_clock::now();
  auto answer = request({{"cmd", "render"}, {"camera_to_world", m}, {"lights", lights}, {"out", out.string()}},
                        settings_.timeout_s);
  if (!answer) return answer.error();
  if (!answer->value("ok", false))
    return make_error(ErrorCode::kDevice, "blender: render failed: " + answer->value("error", std::string("?")));
  last_render_s_ = seconds_since(start);
  auto exr = read_exr(out);
  std::error_code ec;
  fs::remove(out, ec);
  if (!exr) return exr.error();
  const int r = exr->find("R"), g = exr->find("G"), b = exr->find("B");
  if (r < 0 || g < 0 || b < 0 || exr->width != pinhole_.width || exr->height != pinhole_.height)
    return make_error(ErrorCode::kDevice, "blender: the render is not a " + std::to_string(pinhole_.width) + "x" +
                                              std::to_string(pinhole_.height) + " RGB image");
  cv::Mat bgr;
  cv::merge(std::vector<cv::Mat>{exr->channels[b], exr->channels[g], exr->channels[r]}, bgr);
  if (map_x_.empty()) return bgr;
  cv::Mat distorted;
  cv::remap(bgr, distorted, map_x_, map_y_, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar::all(0));
  return distorted;
}

Status BlenderRenderer::inject(const std::string& what) {
  if (socket_ < 0) return make_error(ErrorCode::kDisconnected, "blender: not running");
  const std::string line = json{{"cmd", what}}.dump() + "\n";
  if (send(socket_, line.data(), line.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(line.size()))
    return make_error(ErrorCode::kIo, "blender: cannot send");
  return Status::ok();
}

namespace {

/// The Blender camera: the simulated rig's world (stage pose, exposure, sensor) with Cycles rendering the radiance.
class BlenderCamera final : public rig::Camera {
 public:
  BlenderCamera(std::shared_ptr<SimWorld> world, const BlenderSettings& settings, rig::PanTiltStage* follow)
      : world_(std::move(world)), renderer_(settings), follow_(follow) {}
  std::string backend() const override { return "blender"; }

  Result<rig::CameraInfo> info() override {
    const auto& c = world_->config;
    return rig::CameraInfo{
        "Blender Cycles (vdrig)", c.camera.width, c.camera.height, c.sensor.response.bits(), 1e-6, 60.0, false};
  }

  Status set_exposure(double exposure_s, double gain) override {
    if (!(exposure_s > 0) || !(gain > 0))
      return make_error(ErrorCode::kInvalidArgument, "blender camera: exposure and gain must be positive");
    std::lock_guard lock(world_->mutex);
    world_->exposure_s = exposure_s;
    world_->gain = gain;
    return Status::ok();
  }

  Result<Frame> capture() override {
    if (follow_) {
      auto at = follow_->position();
      if (!at) return at.error();
      std::lock_guard lock(world_->mutex);
      world_->position = at.value();
    }
    Frame frame;
    ViewPose pose;
    bool light_on = true;
    uint64_t noise_key = 0;
    {
      std::lock_guard lock(world_->mutex);
      pose = world_->pose();
      frame.exposure_s = world_->exposure_s;
      frame.gain = world_->gain;
      frame.measured = frame.commanded = world_->position;
      frame.sequence = world_->frame_sequence++;
      noise_key = world_->noise_key(frame.sequence);
      light_on = world_->light_on;
    }
    const auto& c = world_->config;
    if (!scene_set_) {
      VDRIG_TRY(renderer_.set_scene(world_->scene, c.camera));
      scene_set_ = true;
    }
    frame.timestamp_ns =
        std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
            .count();
    frame.bits = c.sensor.response.bits();
    // A bracket photographs one pose several times: Cycles renders it once.
    if (cached_.empty() || cached_position_.pan_rad != frame.measured.pan_rad ||
        cached_position_.tilt_rad != frame.measured.tilt_rad || cached_light_on_ != light_on) {
      auto radiance = renderer_.render(pose, light_on);
      if (!radiance) {
        cached_.release();
        return radiance.error();
      }
      cached_ = radiance.value();
      cached_position_ = frame.measured;
      cached_light_on_ = light_on;
    }
    frame.image = expose(cached_, frame.exposure_s, frame.gain, c.sensor, noise_key);
    return frame;
  }

 private:
  std::shared_ptr<SimWorld> world_;
  BlenderRenderer renderer_;
  rig::PanTiltStage* follow_ = nullptr;
  bool scene_set_ = false;
  cv::Mat cached_;
  PanTilt cached_position_;
  bool cached_light_on_ = true;
};

}  // namespace

void register_blender_camera(rig::BackendRegistry& registry, WorldOf world_of) {
  registry.add_camera(
      "blender",
      [world_of](const json& section, rig::RigContext& ctx) -> Result<std::unique_ptr<rig::Camera>> {
        auto settings = BlenderSettings::parse(section);
        if (!settings) return settings.error();
        auto world = world_of(ctx);
        if (!world) return world.error();
        rig::PanTiltStage* follow = nullptr;  // paired with another backend's stage, render where it says it is
        if (auto it = ctx.shared.find("rig.stage"); it != ctx.shared.end()) {
          auto* stage = static_cast<rig::PanTiltStage*>(it->second.get());
          if (stage && stage->backend() != "sim") follow = stage;
        }
        return std::unique_ptr<rig::Camera>(std::make_unique<BlenderCamera>(world.value(), settings.value(), follow));
      },
      {.sections = {"sim"}, .check = rig::settings_check(BlenderSettings::parse)});
}

}  // namespace vdrig::sim
