#include "vdrig/calib/kinematic.hpp"

#include <Eigen/Dense>
#include <cmath>

namespace vdrig::calib {

std::vector<KinematicResidual> kinematic_residuals(const rig::RigGeometry& geometry,
                                                   std::span<const KinematicObservation> observations) {
  std::vector<KinematicResidual> out;
  for (const auto& o : observations) {
    const ViewPose model = rig::surface_pose(geometry, o.measured);
    KinematicResidual r;
    r.view = o.view;
    r.rotation_deg = rad_to_deg(Eigen::AngleAxisd(o.pose.R * model.R.transpose()).angle());
    r.translation_mm = (o.pose.t - model.t).norm();
    r.camera_centre_mm = (o.pose.camera_centre() - model.camera_centre()).norm();
    out.push_back(r);
  }
  return out;
}

Result<KinematicFit> fit_rig_geometry(std::span<const KinematicObservation> obs) {
  if (obs.size() < 2)
    return make_error(ErrorCode::kInvalidArgument,
                      "kinematic fit needs at least 2 views with extrinsics, have " + std::to_string(obs.size()));
  // Unknowns x = (offset_x, offset_y, offset_z, D); per view t = R_cw R_ws offset + D e_z.
  const Mat3d R_cw = Vec3d(1, -1, -1).asDiagonal();
  Eigen::MatrixXd A(3 * obs.size(), 4);
  Eigen::VectorXd b(3 * obs.size());
  for (size_t i = 0; i < obs.size(); ++i) {
    A.block<3, 3>(3 * i, 0) = R_cw * rig::platform_rotation(obs[i].measured);
    A.block<3, 1>(3 * i, 3) = Vec3d::UnitZ();
    b.segment<3>(3 * i) = obs[i].pose.t;
  }
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(A);
  if (qr.rank() < 4)
    return make_error(ErrorCode::kInvalidArgument,
                      "kinematic fit is rank deficient: the views need different pan/tilt positions");
  const Eigen::Vector4d x = qr.solve(b);
  KinematicFit fit;
  fit.geometry.surface_offset_mm = x.head<3>();
  fit.geometry.camera_distance_mm = x(3);
  if (!(fit.geometry.camera_distance_mm > 0))
    return make_error(ErrorCode::kInvalidArgument, "kinematic fit gave a non-positive camera distance");
  fit.residuals = kinematic_residuals(fit.geometry, obs);
  double st = 0, sr = 0;
  for (const auto& r : fit.residuals) {
    st += r.translation_mm * r.translation_mm;
    sr += r.rotation_deg * r.rotation_deg;
    fit.max_rotation_deg = std::max(fit.max_rotation_deg, r.rotation_deg);
  }
  fit.rms_translation_mm = std::sqrt(st / fit.residuals.size());
  fit.rms_rotation_deg = std::sqrt(sr / fit.residuals.size());
  return fit;
}

nlohmann::json KinematicFit::to_json() const {
  nlohmann::json j;
  j["camera_distance_mm"] = geometry.camera_distance_mm;
  const Vec3d& o = geometry.surface_offset_mm;
  j["surface_offset_mm"] = {o.x(), o.y(), o.z()};
  j["rms_translation_mm"] = rms_translation_mm;
  j["rms_rotation_deg"] = rms_rotation_deg;
  j["max_rotation_deg"] = max_rotation_deg;
  j["views"] = nlohmann::json::array();
  for (const auto& r : residuals)
    j["views"].push_back({{"index", r.view},
                          {"rotation_deg", r.rotation_deg},
                          {"translation_mm", r.translation_mm},
                          {"camera_centre_mm", r.camera_centre_mm}});
  return j;
}

Result<rig::RigGeometry> KinematicFit::geometry_from_json(const nlohmann::json& j) {
  try {
    rig::RigGeometry g;
    g.camera_distance_mm = j.at("camera_distance_mm").get<double>();
    const auto& o = j.at("surface_offset_mm");
    g.surface_offset_mm = {o.at(0).get<double>(), o.at(1).get<double>(), o.at(2).get<double>()};
    return g;
  } catch (const nlohmann::json::exception& e) {
    return make_error(ErrorCode::kCorrupt, std::string("kinematics: ") + e.what());
  }
}

}  // namespace vdrig::calib
