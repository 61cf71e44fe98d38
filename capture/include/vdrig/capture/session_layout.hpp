// SessionLayout: where every file of a session folder lives. This is the only place that spells a session's file
// and folder names; every stage and command asks it, so a session written by one tool is found by the next.
//
//   SESSION/manifest.json              what was planned (capture/session.hpp: Manifest). Written atomically; stages
//                                      rewrite only its `extra` section.
//   SESSION/journal.jsonl              append-only record of committed frames and events (capture/session.hpp).
//   SESSION/capture.lock               flock'ed by the process capturing into the session, holding its PID
//                                      (capture/process_lock.hpp); present once a capture ran, locked only meanwhile.
//   SESSION/frames/view_VVVV_eEE.png   frame EE of view VVVV's exposure bracket: 8- or 16-bit PNG, BGR codes as the
//                                      camera delivered them. Journal lines name them relative to SESSION.
//   SESSION/hdr/view_VVVV.exr          the view's bracket merged to relative radiance with its clip mask
//                                      (calib/hdr.hpp; `vdrig hdr SESSION`).
//   SESSION/calib/response.json        the camera's response curve (`vdrig calib response --out` it here); when
//                                      present it is used instead of the simulator's ground truth.
//   SESSION/calib/camera.yml           the camera model (OpenCV YAML) the views were posed with.
//   SESSION/calib/views.json           per-view marker poses and the rig kinematic fit (calib/extrinsics.hpp;
//                                      `vdrig calib extrinsics SESSION`).
//   SESSION/obsmap/<S>x<T>.vdobs       observation map of every view at S x T texels (docs/obsmap.md), kept for
//                                      further fits while it is newer than hdr/ and calib/.
//   SESSION/maps/<model spec>.exr      a fitted parameter map (fitting/parameter_map.hpp), named by its model spec:
//                                      maps/phong:1.exr, maps/phong:auto.exr, maps/hsh:6.exr.
//   SESSION/renders/                   renders of held-out views beside their photographs and difference images.
//   SESSION/renders/compare/           `vdrig compare`'s default output: compare.json and <map>/view_VVVV_*.png
//                                      (pipeline/compare_stage.hpp); `vdrig report` reads compare.json.
//
// VVVV and EE are zero-padded to 4 and 2 digits (wider numbers are written in full). The type only computes paths; it
// creates nothing and touches no file.
#pragma once

#include <filesystem>
#include <string>

namespace vdrig::capture {

class SessionLayout {
 public:
  explicit SessionLayout(std::filesystem::path session_dir) : dir_(std::move(session_dir)) {}

  const std::filesystem::path& dir() const { return dir_; }

  std::filesystem::path manifest_file() const;
  std::filesystem::path journal_file() const;
  /// The file whose flock says who captures into the session (process_lock.hpp).
  std::filesystem::path lock_file() const;

  std::filesystem::path frames_dir() const;
  /// "frames/view_VVVV_eEE.png": a frame file relative to the session folder, as journal lines record it.
  static std::filesystem::path frame_file_relative(int view, int bracket_index);
  std::filesystem::path frame_file(int view, int bracket_index) const;

  std::filesystem::path hdr_dir() const;
  std::filesystem::path hdr_file(int view) const;

  std::filesystem::path calib_dir() const;
  std::filesystem::path response_file() const;
  std::filesystem::path camera_file() const;
  std::filesystem::path views_file() const;

  std::filesystem::path obsmap_dir() const;
  std::filesystem::path obsmap_file(int texels_s, int texels_t) const;

  std::filesystem::path maps_dir() const;
  /// maps/<model_spec>.exr. `model_spec` is a model's name as `vdrig fit --model` takes it ("phong:1", "hsh:6"); the
  /// demo and `vdrig fit` name their maps by it. A spec that is not a plain file name ('/', "..") aborts.
  std::filesystem::path parameter_map_file(const std::string& model_spec) const;

  std::filesystem::path renders_dir() const;
  std::filesystem::path compare_dir() const;

 private:
  std::filesystem::path dir_;
};

}  // namespace vdrig::capture
