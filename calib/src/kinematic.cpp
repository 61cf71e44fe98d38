#include "vdrig/calib/kinematic.hpp"

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>

#include "vdrig/core/log.hpp"
#include "vdrig/rig/geometry_config.hpp"

namespace vdrig::calib {
namespace {

namespace model = rig::model;
using model::kParamCount;

/// Residual groups (kinematic.hpp): rotation about the image axes, about the optical axis, translation across the
/// image, along the optical axis.
enum Group : int { kRotXY = 0, kRotZ, kTransXY, kTransZ, kGroupCount };
constexpr int kResidualsPerView = 6;
constexpr Group kGroupOfResidual[kResidualsPerView] = {kRotXY, kRotXY, kRotZ, kTransXY, kTransXY, kTransZ};
using GroupSigma = std::array<double, kGroupCount>;  // rad, rad, mm, mm

/// One view's 6 residuals for the 8 parameters, each divided by its group's sigma.
struct PoseResidual {
  PanTilt reading;
  Mat3d R_measured;
  Vec3d t_measured;
  GroupSigma sigma;

  template <typename T>
  bool operator()(const T* p, T* r) const {
    model::Mat3<T> R;
    model::Vec3<T> t;
    model::surface_pose(p, reading, &R, &t);
    const model::Mat3<T> E = R_measured.cast<T>() * R.transpose();  // column-major, as ceres' overload reads it
    T rvec[3];
    ceres::RotationMatrixToAngleAxis(E.data(), rvec);
    for (int k = 0; k < 3; ++k) r[k] = rvec[k] / sigma[kGroupOfResidual[k]];
    for (int k = 0; k < 3; ++k) r[3 + k] = (T(t_measured[k]) - t[k]) / sigma[kGroupOfResidual[3 + k]];
    return true;
  }
};

constexpr const char* kParamNames[kParamCount] = {"camera distance",  "surface offset x", "surface offset y",
                                                  "surface offset z", "pan zero",         "tilt zero",
                                                  "pan axis tilt x",  "pan axis tilt y"};

/// Linear least squares for (offset, D) on the translations at the ideal rotation (the fit's start).
Result<model::Params> linear_start(std::span<const KinematicObservation> obs) {
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
  if (!(x(3) > 0)) return make_error(ErrorCode::kInvalidArgument, "kinematic fit gave a non-positive camera distance");

  // Pan zero and axis tilt: every view gives K_i = Rz(pan_r)^T Rx(tilt_r)^T R_world_surface ~ Rz(-pan_zero) A
  // (ignoring the tilt zero); their chordal mean (the sum projected on SO(3)) is decomposed as Rz(a) Rx(b) Ry(c).
  Mat3d sum = Mat3d::Zero();
  for (const auto& o : obs) sum += rig::platform_rotation(o.measured).transpose() * R_cw * o.pose.R;
  const Eigen::JacobiSVD<Mat3d> svd(sum, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Mat3d K = svd.matrixU() * svd.matrixV().transpose();
  if (K.determinant() < 0) {
    Mat3d U = svd.matrixU();
    U.col(2) *= -1.0;
    K = U * svd.matrixV().transpose();
  }
  // Row 2 of Rz(a) Rx(b) Ry(c) is (-cos b sin c, sin b, cos b cos c); then Rz(a) = K Ry(c)^T Rx(b)^T.
  const double b_rad = std::asin(std::clamp(K(2, 1), -1.0, 1.0));
  const double c_rad = std::atan2(-K(2, 0), K(2, 2));
  const Mat3d Rz = K * model::rot_y(c_rad).transpose() * model::rot_x(b_rad).transpose();
  const double a_rad = std::atan2(Rz(1, 0), Rz(0, 0));

  model::Params p{};
  p[model::kDistance] = x(3);
  // The linear fit's offset is Rz(-pan_zero) o: it turned with the ideal pan.
  const Vec3d o = model::rot_z(-a_rad) * Vec3d(x.head<3>());
  p[model::kOffsetX] = o.x();
  p[model::kOffsetY] = o.y();
  p[model::kOffsetZ] = o.z();
  p[model::kPanZero] = -a_rad;
  p[model::kTiltZero] = 0.0;
  p[model::kAxisTiltX] = b_rad;
  p[model::kAxisTiltY] = c_rad;
  return p;
}

struct Problem {
  ceres::Problem problem;
  model::Params p;
  std::vector<ceres::ResidualBlockId> blocks;
};

/// A view whose weighted squared residuals sum beyond kOutlierChi2 (a chi-square of 6 degrees of freedom passes it
/// 1.4 % of the time) weighs as Huber's loss says: linearly, not quadratically. A near-grazing view whose markers
/// were found but posed 0.1 deg off (it happens at 80 deg tilt) then pulls the fit little.
constexpr double kOutlierChi2 = 16.0;

void build_problem(Problem& pr, std::span<const KinematicObservation> obs, const GroupSigma& sigma) {
  for (const auto& o : obs) {
    auto* cost = new ceres::AutoDiffCostFunction<PoseResidual, kResidualsPerView, kParamCount>(
        new PoseResidual{o.measured, o.pose.R, o.pose.t, sigma});
    pr.blocks.push_back(pr.problem.AddResidualBlock(cost, new ceres::HuberLoss(std::sqrt(kOutlierChi2)), pr.p.data()));
  }
}

/// Whether each view's weighted residuals stay within kOutlierChi2.
std::vector<bool> inlier_views(const std::vector<double>& r, const GroupSigma& sigma) {
  std::vector<bool> in(r.size() / kResidualsPerView);
  for (size_t v = 0; v < in.size(); ++v) {
    double s = 0.0;
    for (int k = 0; k < kResidualsPerView; ++k) {
      const double w = r[v * kResidualsPerView + k] / sigma[kGroupOfResidual[k]];
      s += w * w;
    }
    in[v] = s <= kOutlierChi2;
  }
  return in;
}

bool solve(Problem& pr) {
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = 200;
  so.function_tolerance = 1e-14;
  so.gradient_tolerance = 1e-16;
  so.parameter_tolerance = 1e-14;
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &pr.problem, &summary);
  return summary.IsSolutionUsable();
}

/// Unweighted residuals (rad, mm) of every observation at p, 6 a view.
std::vector<double> raw_residuals(const model::Params& p, std::span<const KinematicObservation> obs) {
  std::vector<double> out;
  const GroupSigma unit{1.0, 1.0, 1.0, 1.0};
  for (const auto& o : obs) {
    double r[kResidualsPerView];
    PoseResidual{o.measured, o.pose.R, o.pose.t, unit}(p.data(), r);
    out.insert(out.end(), r, r + kResidualsPerView);
  }
  return out;
}

/// Each group's noise sigma from the residuals of the inlier views, the parameters' degrees of freedom shared out
/// over the groups.
GroupSigma estimate_sigma(const std::vector<double>& r, const std::vector<bool>& inlier) {
  std::array<double, kGroupCount> ss{}, n{};
  size_t used = 0;
  for (size_t i = 0; i < r.size(); ++i) {
    if (!inlier[i / kResidualsPerView]) continue;
    ++used;
    const Group g = kGroupOfResidual[i % kResidualsPerView];
    ss[g] += r[i] * r[i];
    n[g] += 1.0;
  }
  const double dof_share = 1.0 - static_cast<double>(kParamCount) / static_cast<double>(std::max<size_t>(used, 1));
  // Floors keep the weights finite on noise-free data: 1e-7 deg and 1e-6 mm are far below any marker pose.
  const GroupSigma floor{deg_to_rad(1e-7), deg_to_rad(1e-7), 1e-6, 1e-6};
  GroupSigma sigma;
  for (int g = 0; g < kGroupCount; ++g)
    sigma[g] = std::max(floor[g], std::sqrt(ss[g] / (n[g] * std::max(dof_share, 1e-3))));
  return sigma;
}

/// The Jacobian of the weighted residuals at the solution, dense.
Eigen::MatrixXd jacobian(Problem& pr) {
  ceres::CRSMatrix crs;
  ceres::Problem::EvaluateOptions eo;
  pr.problem.Evaluate(eo, nullptr, nullptr, nullptr, &crs);
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(crs.num_rows, crs.num_cols);
  for (int row = 0; row < crs.num_rows; ++row)
    for (int k = crs.rows[row]; k < crs.rows[row + 1]; ++k) J(row, crs.cols[k]) = crs.values[k];
  return J;
}

/// Empty when the columns of J (scaled to unit length) are independent; else the undetermined combination.
std::string undetermined_combination(const Eigen::MatrixXd& J) {
  Eigen::MatrixXd Js = J;
  for (int c = 0; c < Js.cols(); ++c) {
    const double n = Js.col(c).norm();
    if (n > 0) Js.col(c) /= n;
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(Js, Eigen::ComputeThinV);
  const Eigen::VectorXd s = svd.singularValues();
  // Exactly undetermined combinations come out at rounding level (~1e-12); 1e-6 leaves room for rigs whose views
  // merely span little, which the sigmas then show.
  if (s(s.size() - 1) > 1e-6 * s(0)) return {};
  const Eigen::VectorXd v = svd.matrixV().col(s.size() - 1);
  std::string what;
  for (int c = 0; c < v.size(); ++c) {
    if (std::abs(v(c)) < 0.1) continue;
    const double w = what.empty() ? v(c) : std::abs(v(c));
    if (!what.empty()) what += v(c) < 0 ? " - " : " + ";
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.2f %s", w, kParamNames[c]);
    what += buf;
  }
  return what;
}

void summarise(KinematicFit& fit, std::span<const KinematicObservation> obs) {
  fit.residuals = kinematic_residuals(fit.geometry, obs);
  double st = 0, sr = 0;
  for (const auto& r : fit.residuals) {
    st += r.translation_mm * r.translation_mm;
    sr += r.rotation_deg * r.rotation_deg;
    fit.max_rotation_deg = std::max(fit.max_rotation_deg, r.rotation_deg);
  }
  fit.rms_translation_mm = std::sqrt(st / fit.residuals.size());
  fit.rms_rotation_deg = std::sqrt(sr / fit.residuals.size());
}

nlohmann::json sigma_json(const model::Params& s) {
  return {{"camera_distance_mm", s[model::kDistance]},
          {"surface_offset_mm", {s[model::kOffsetX], s[model::kOffsetY], s[model::kOffsetZ]}},
          {"pan_zero_deg", rad_to_deg(s[model::kPanZero])},
          {"tilt_zero_deg", rad_to_deg(s[model::kTiltZero])},
          {"pan_axis_tilt_x_deg", rad_to_deg(s[model::kAxisTiltX])},
          {"pan_axis_tilt_y_deg", rad_to_deg(s[model::kAxisTiltY])}};
}

}  // namespace

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
  auto start = linear_start(obs);
  if (!start) return start.error();

  // Weights: a first guess of marker-pose noise, then each group's own estimate (kinematic.hpp).
  GroupSigma sigma{deg_to_rad(0.01), deg_to_rad(0.01), 0.1, 0.3};
  model::Params p = start.value();
  std::unique_ptr<Problem> pr;
  constexpr int kRounds = 4;
  for (int round = 0; round < kRounds; ++round) {
    pr = std::make_unique<Problem>();
    pr->p = p;
    build_problem(*pr, obs, sigma);
    if (!solve(*pr)) return make_error(ErrorCode::kInvalidArgument, "kinematic fit did not converge");
    p = pr->p;
    if (round == 0) {
      const std::string undetermined = undetermined_combination(jacobian(*pr));
      if (!undetermined.empty())
        return make_error(ErrorCode::kInvalidArgument,
                          "kinematic fit: the views do not determine the rig's parameters (" + undetermined +
                              " is free); take views at several pans and tilts");
    }
    // The first round's weights are a guess: every view counts toward the first estimate.
    const std::vector<double> r = raw_residuals(p, obs);
    if (round < kRounds - 1)
      sigma = estimate_sigma(r, round == 0 ? std::vector<bool>(obs.size(), true) : inlier_views(r, sigma));
  }
  if (!(p[model::kDistance] > 0))
    return make_error(ErrorCode::kInvalidArgument, "kinematic fit gave a non-positive camera distance");

  KinematicFit fit;
  fit.geometry = model::from_params(p);
  fit.noise_rotation_xy_deg = rad_to_deg(sigma[kRotXY]);
  fit.noise_rotation_z_deg = rad_to_deg(sigma[kRotZ]);
  fit.noise_translation_xy_mm = sigma[kTransXY];
  fit.noise_translation_z_mm = sigma[kTransZ];

  const std::vector<double> r = raw_residuals(p, obs);
  const std::vector<bool> inlier = inlier_views(r, sigma);
  double ss = 0.0;
  size_t n_res = 0;
  for (size_t i = 0; i < r.size(); ++i) {
    if (!inlier[i / kResidualsPerView]) continue;
    const double w = r[i] / sigma[kGroupOfResidual[i % kResidualsPerView]];
    ss += w * w;
    ++n_res;
  }
  for (size_t v = 0; v < obs.size(); ++v)
    if (!inlier[v]) fit.downweighted_views.push_back(obs[v].view);

  // Covariance of the weighted fit (Ceres applies the loss of the down-weighted views), scaled by the inliers'
  // reduced chi-square (~1 after the reweighting). A failure leaves the fit without sigmas; it does not fail the fit.
  const double chi2 = n_res > kParamCount ? ss / static_cast<double>(n_res - kParamCount) : 1.0;
  ceres::Covariance::Options co;
  co.algorithm_type = ceres::DENSE_SVD;
  ceres::Covariance covariance(co);
  const std::vector<std::pair<const double*, const double*>> blocks{{pr->p.data(), pr->p.data()}};
  std::array<double, kParamCount * kParamCount> cov{};
  if (covariance.Compute(blocks, &pr->problem) &&
      covariance.GetCovarianceBlock(pr->p.data(), pr->p.data(), cov.data())) {
    model::Params s;
    for (int i = 0; i < kParamCount; ++i) s[i] = std::sqrt(std::max(0.0, cov[i * kParamCount + i] * chi2));
    fit.sigma = s;
  } else {
    log::get("calib")->warn("kinematic fit: the covariance could not be computed; no standard deviations");
  }
  summarise(fit, obs);
  return fit;
}

nlohmann::json KinematicFit::geometry_to_json(const rig::RigGeometry& g) { return rig::kinematics_to_json(g); }

nlohmann::json KinematicFit::to_json() const {
  nlohmann::json j = geometry_to_json(geometry);
  j["sigma"] = sigma ? sigma_json(*sigma) : nlohmann::json();
  j["noise"] = {{"rotation_xy_deg", noise_rotation_xy_deg},
                {"rotation_z_deg", noise_rotation_z_deg},
                {"translation_xy_mm", noise_translation_xy_mm},
                {"translation_z_mm", noise_translation_z_mm}};
  j["downweighted_views"] = downweighted_views;
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
  return rig::kinematics_from_json(j);
}

}  // namespace vdrig::calib
