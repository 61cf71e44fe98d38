// A stage for tests that need one without a motor or a simulator: it stands wherever it is told, at once, and reports
// that position; its spec (limits, speed profile) and backend name are the test's.
#pragma once

#include <string>
#include <utility>

#include "vdrig/rig/devices.hpp"

namespace vdrig::test {

class InstantStage final : public rig::PanTiltStage {
 public:
  InstantStage(std::string backend, rig::StageSpec spec) : backend_(std::move(backend)), spec_(spec) {}
  std::string backend() const override { return backend_; }
  rig::StageSpec spec() const override { return spec_; }
  Status home() override { return move_to({}); }
  Status move_to(const PanTilt& target) override {
    at_ = target;
    return Status::ok();
  }
  Result<PanTilt> position() override { return at_; }
  Status stop() override { return Status::ok(); }

 private:
  std::string backend_;
  rig::StageSpec spec_;
  PanTilt at_;
};

}  // namespace vdrig::test
