// Small in-test devices: a stage that moves instantly and a camera whose image is exposure * radiance, with
// injectable faults. Lets the capture tests check exposures and fault handling against exact ground truth.
#pragma once

#include <functional>
#include <memory>

#include "vdrig/core/geometry.hpp"
#include "vdrig/rig/devices.hpp"

namespace vdrig::capture::testing {

class FakeStage : public rig::PanTiltStage {
 public:
  std::string backend() const override { return "fake"; }
  rig::StageSpec spec() const override {
    rig::StageSpec s;
    s.pan = {-2 * kPi, 2 * kPi, 1.0, 2.0, false};
    s.tilt = {-0.1, 1.5, 1.0, 2.0, false};
    return s;
  }
  Status home() override {
    pos = {};
    return Status::ok();
  }
  Status move_to(const PanTilt& t) override {
    if (fail_moves > 0) {
      --fail_moves;
      return make_error(ErrorCode::kTimeout, "injected move timeout");
    }
    pos = t;
    ++moves;
    return Status::ok();
  }
  Result<PanTilt> position() override { return pos; }
  Status stop() override { return Status::ok(); }
  PanTilt pos;
  int moves = 0;
  int fail_moves = 0;
};

/// Pixel code = min(255, radiance * exposure_s) with radiance `bright` inside `hot` (a rectangle) and `dim` elsewhere.
class FakeCamera : public rig::Camera {
 public:
  std::string backend() const override { return "fake"; }
  Result<rig::CameraInfo> info() override {
    rig::CameraInfo i;
    i.model = "fake";
    i.width = 32;
    i.height = 24;
    i.auto_exposure_on = auto_exposure;
    i.min_exposure_s = 1e-6;
    i.max_exposure_s = 10;
    return i;
  }
  Status set_exposure(double e, double g) override {
    exposure_s = e;
    gain = g;
    return Status::ok();
  }
  Result<Frame> capture() override {
    ++attempts;
    if (fail_captures > 0) {
      --fail_captures;
      return make_error(ErrorCode::kDevice, "injected camera fault");
    }
    Frame f;
    f.image = cv::Mat(24, 32, CV_8UC3, cv::Scalar::all(std::min(255.0, dim * exposure_s)));
    f.image(hot).setTo(cv::Scalar::all(std::min(255.0, bright * exposure_s)));
    f.exposure_s = exposure_s;
    f.gain = gain;
    f.sequence = ++sequence;
    return f;
  }
  double exposure_s = 0.01, gain = 1;
  double dim = 100, bright = 1000;
  cv::Rect hot{0, 0, 4, 4};
  bool auto_exposure = false;
  int fail_captures = 0;
  int attempts = 0;
  uint64_t sequence = 0;
};

inline rig::Rig make_fake_rig(FakeStage** stage = nullptr, FakeCamera** camera = nullptr) {
  rig::Rig r;
  auto s = std::make_unique<FakeStage>();
  auto c = std::make_unique<FakeCamera>();
  if (stage) *stage = s.get();
  if (camera) *camera = c.get();
  r.stage = std::move(s);
  r.camera = std::move(c);
  return r;
}

}  // namespace vdrig::capture::testing
