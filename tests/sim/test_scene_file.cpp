// Scene files: the format's rules (a set of broken files, each with one clear error naming the JSON path), the
// load -> save -> load round trip, and the built-in scenes of sim/scenes/: equal to their former in-code definitions
// (kept here, in namespace legacy, as the reference) and rendered bit-identically.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <opencv2/core.hpp>

#include "vdrig/core/image_io.hpp"
#include "vdrig/rig/kinematics.hpp"
#include "vdrig/sim/checkerboard.hpp"
#include "vdrig/sim/renderer.hpp"
#include "vdrig/sim/scene_file.hpp"
#include "vdrig/sim/sim_rig.hpp"
#include "vdrig/test/build_paths.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::sim {
namespace legacy {

// The built-in scenes as scene.cpp defined them before they became files (the reference of the bit-identity test).
double legacy_band_shininess(int k) { return 2.0 * std::pow(250.0, k / 7.0); }

// The light of the source method's test setup: a white point light at (1500, 1500, 2000) mm. Its intensity is
// chosen so the irradiance at the surface centre is 1 (d^2 = 8.5e6 mm^2, cos = 0.686).
PointLight standard_light() {
  const Vec3d pos(1500, 1500, 2000);
  const double d2 = pos.squaredNorm();
  return {pos, Vec3d::Constant(d2 / (pos.z() / std::sqrt(d2)))};
}

// Four black discs, 30 mm radius, centred 50 mm in from each corner; order (-,-), (+,-), (+,+), (-,+).
void add_corner_markers(Scene& s) {
  s.materials.push_back({"marker black", Vec3d::Constant(0.02), Vec3d::Zero(), 1.0});
  const int m = static_cast<int>(s.materials.size()) - 1;
  const double x = s.width_mm / 2 - 50, y = s.height_mm / 2 - 50;
  s.markers = {{{-x, -y}, 30.0, m}, {{x, -y}, 30.0, m}, {{x, y}, 30.0, m}, {{-x, y}, 30.0, m}};
}

// Eight bands of one colour, shininess m = 2 .. 500, over [x0, x1] x [y0, y1].
void add_bands(Scene& s, double x0, double y0, double x1, double y1) {
  const double w = (x1 - x0) / 8.0;
  for (int k = 0; k < 8; ++k) {
    char name[32];
    std::snprintf(name, sizeof name, "band m=%.0f", legacy_band_shininess(k));
    s.materials.push_back({name, {0.25, 0.30, 0.35}, {0.45, 0.45, 0.45}, legacy_band_shininess(k)});
    s.patches.push_back({x0 + k * w, y0, x0 + (k + 1) * w, y1, static_cast<int>(s.materials.size()) - 1});
  }
}

Scene patchwork() {
  Scene s;
  s.name = "patchwork";
  // Indices 0..2 are relied on by callers (the demo takes the first Lambertian patch, red cloth, as its region).
  s.materials = {
      {"paper", {0.70, 0.68, 0.62}, {0.02, 0.02, 0.02}, 4.0},
      {"red cloth", {0.60, 0.08, 0.06}, {0, 0, 0}, 1.0},
      {"glossy plastic", {0.10, 0.20, 0.45}, {0.50, 0.50, 0.50}, 60.0},
  };
  Material metal{"brushed metal", {0.04, 0.035, 0.03}, {0.75, 0.62, 0.45}, 150.0};
  metal.bump_slope = 0.08;
  metal.bump_period_mm = 6.0;
  Material print{"printed paper", {0.80, 0.78, 0.72}, {0.03, 0.03, 0.03}, 8.0};
  print.printed = true;
  print.ink_kd = {0.05, 0.05, 0.07};
  s.materials.push_back(metal);
  s.materials.push_back(print);
  // Red diffuse patch in the -x,-y quadrant; glossy patch in the +x,-y quadrant; metal and print above them; the
  // shininess band near the top; paper elsewhere (and around the corner markers).
  s.patches = {{-400, -400, -50, -50, 1}, {50, -400, 400, -50, 2}, {-400, 50, -50, 250, 3}, {50, 50, 400, 250, 4}};
  add_bands(s, -400, 290, 400, 400);
  add_corner_markers(s);
  s.lights = {standard_light()};
  return s;
}

Scene bands() {
  Scene s;
  s.name = "bands";
  s.materials = {{"paper", {0.70, 0.68, 0.62}, {0.02, 0.02, 0.02}, 4.0}};
  add_bands(s, -400, -400, 400, 400);
  add_corner_markers(s);
  s.lights = {standard_light()};
  return s;
}

Scene lights2() {
  Scene s = patchwork();
  s.name = "lights2";
  s.lights.push_back({Vec3d(-1500, 1000, 2000), s.lights[0].intensity * 0.4});
  return s;
}

Scene softbox() {
  Scene s = patchwork();
  s.name = "softbox";
  const PointLight p = standard_light();
  // A 400 x 400 mm panel at the point light's place, facing the surface centre.
  const Vec3d nrm = (-p.position_mm).normalized();
  const Vec3d u = Vec3d::UnitZ().cross(nrm).normalized() * 400.0;
  const Vec3d v = nrm.cross(u).normalized() * 400.0;  // u x v = 400^2 nrm: emits toward the surface
  s.lights.clear();
  s.area_lights = {{p.position_mm, u, v, p.intensity, 6}};
  s.ambient = Vec3d::Constant(0.05);
  return s;
}

Scene make(const std::string& name) {
  if (name == "patchwork") return patchwork();
  if (name == "bands") return bands();
  if (name == "lights2") return lights2();
  return softbox();
}

}  // namespace legacy

namespace {

void expect_equal_vec(const Vec3d& a, const Vec3d& b, const std::string& what) {
  EXPECT_EQ(a, b) << what << ": " << a.transpose() << " vs " << b.transpose();
}

// Every field, compared exactly (bit-identical renders need bit-identical numbers).
void expect_equal(const Scene& a, const Scene& b) {
  EXPECT_EQ(a.name, b.name);
  EXPECT_EQ(a.width_mm, b.width_mm);
  EXPECT_EQ(a.height_mm, b.height_mm);
  ASSERT_EQ(a.materials.size(), b.materials.size());
  for (std::size_t i = 0; i < a.materials.size(); ++i) {
    const Material &x = a.materials[i], &y = b.materials[i];
    const std::string w = "material " + x.name;
    EXPECT_EQ(x.name, y.name);
    expect_equal_vec(x.kd, y.kd, w + " kd");
    expect_equal_vec(x.ks, y.ks, w + " ks");
    EXPECT_EQ(x.shininess, y.shininess) << w;
    EXPECT_EQ(x.kind, y.kind) << w;
    EXPECT_EQ(x.roughness, y.roughness) << w;
    EXPECT_EQ(x.roughness_y, y.roughness_y) << w;
    expect_equal_vec(x.f0, y.f0, w + " f0");
    EXPECT_EQ(x.bump_slope, y.bump_slope) << w;
    EXPECT_EQ(x.bump_period_mm, y.bump_period_mm) << w;
    EXPECT_EQ(x.printed, y.printed) << w;
    expect_equal_vec(x.ink_kd, y.ink_kd, w + " ink_kd");
    EXPECT_EQ(x.print_cell_mm, y.print_cell_mm) << w;
    EXPECT_EQ(x.kd_image, y.kd_image) << w;
    EXPECT_EQ(x.kd_texture != nullptr, y.kd_texture != nullptr) << w;
  }
  ASSERT_EQ(a.patches.size(), b.patches.size());
  for (std::size_t i = 0; i < a.patches.size(); ++i) {
    EXPECT_EQ(a.patches[i].x0_mm, b.patches[i].x0_mm);
    EXPECT_EQ(a.patches[i].y0_mm, b.patches[i].y0_mm);
    EXPECT_EQ(a.patches[i].x1_mm, b.patches[i].x1_mm);
    EXPECT_EQ(a.patches[i].y1_mm, b.patches[i].y1_mm);
    EXPECT_EQ(a.patches[i].material, b.patches[i].material);
  }
  ASSERT_EQ(a.markers.size(), b.markers.size());
  for (std::size_t i = 0; i < a.markers.size(); ++i) {
    EXPECT_EQ(a.markers[i].centre_mm, b.markers[i].centre_mm);
    EXPECT_EQ(a.markers[i].radius_mm, b.markers[i].radius_mm);
    EXPECT_EQ(a.markers[i].material, b.markers[i].material);
  }
  ASSERT_EQ(a.lights.size(), b.lights.size());
  for (std::size_t i = 0; i < a.lights.size(); ++i) {
    expect_equal_vec(a.lights[i].position_mm, b.lights[i].position_mm, "light position");
    expect_equal_vec(a.lights[i].intensity, b.lights[i].intensity, "light intensity");
  }
  ASSERT_EQ(a.area_lights.size(), b.area_lights.size());
  for (std::size_t i = 0; i < a.area_lights.size(); ++i) {
    const AreaLight &x = a.area_lights[i], &y = b.area_lights[i];
    expect_equal_vec(x.centre_mm, y.centre_mm, "area light centre");
    expect_equal_vec(x.edge_u_mm, y.edge_u_mm, "area light edge u");
    expect_equal_vec(x.edge_v_mm, y.edge_v_mm, "area light edge v");
    expect_equal_vec(x.intensity, y.intensity, "area light intensity");
    EXPECT_EQ(x.samples_per_axis, y.samples_per_axis);
  }
  expect_equal_vec(a.ambient, b.ambient, "ambient");
}

bool bit_identical(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && std::equal(a.datastart, a.dataend, b.datastart, b.dataend);
}

TEST(SceneFiles, BuiltinScenesAreTheirFormerDefinitionsAndRenderBitIdentically) {
  ASSERT_EQ(scene_names(), (std::vector<std::string>{"patchwork", "bands", "lights2", "softbox", "chessboard"}));
  const CameraModel cam{160, 120, 200.0, 200.0, 80.3, 59.2, -0.08, 0.02, 0.0004, -0.0002, 0.0};
  const RayTable rays(cam, 2);
  for (const std::string name : {"patchwork", "bands", "lights2", "softbox"}) {
    SCOPED_TRACE(name);
    const auto loaded = make_scene(name);
    ASSERT_TRUE(loaded.is_ok()) << loaded.error().message;
    const Scene reference = legacy::make(name);
    expect_equal(*loaded, reference);
    for (const PanTilt pt : {PanTilt{0, 0}, PanTilt{deg_to_rad(25), deg_to_rad(35)}}) {
      const ViewPose pose = rig::surface_pose({}, pt);
      EXPECT_TRUE(bit_identical(render_radiance(*loaded, rays, pose), render_radiance(reference, rays, pose)));
    }
  }
}

TEST(SceneFiles, ChessboardIsTheCheckerboardTargetOf9x7SquaresOf160Millimetres) {
  // The intrinsics target `vdrig demo` captures: 8 x 6 inner corners, evenly lit (ambient only), as
  // checkerboard_scene makes it.
  CheckerboardSpec spec;
  spec.cols = 9;
  spec.rows = 7;
  spec.square_mm = 160.0;
  spec.margin_mm = 80.0;
  const auto loaded = make_scene("chessboard");
  ASSERT_TRUE(loaded.is_ok()) << loaded.error().message;
  Scene expected = checkerboard_scene(spec);
  expected.name = "chessboard";
  expect_equal(*loaded, expected);
  EXPECT_TRUE(loaded->lights.empty());
}

Scene ggx_scene() {
  Scene s = legacy::make("lights2");
  s.name = "ggx test";
  Material iso{"ggx iso", {0.1, 0.2, 0.3}};
  iso.kind = MaterialKind::kGgx;
  iso.roughness = 0.25;
  iso.f0 = {0.9, 0.6, 0.3};
  Material aniso = iso;
  aniso.name = "ggx aniso";
  aniso.roughness = 0.1;
  aniso.roughness_y = 0.4;
  aniso.bump_slope = 0.05;
  s.materials.push_back(iso);
  s.materials.push_back(aniso);
  s.patches.push_back({-100, -100, 0, 0, static_cast<int>(s.materials.size()) - 2});
  s.patches.push_back({0, 0, 100, 100, static_cast<int>(s.materials.size()) - 1});
  s.area_lights = legacy::make("softbox").area_lights;
  s.ambient = {0.01, 0.02, 0.03};
  return s;
}

TEST(SceneFiles, LoadSaveLoadGivesTheSameScene) {
  test::TempDir dir("scene_round_trip");
  std::vector<Scene> scenes;
  for (const std::string& name : scene_names()) scenes.push_back(make_scene(name).value());
  scenes.push_back(ggx_scene());
  for (const Scene& scene : scenes) {
    SCOPED_TRACE(scene.name);
    const std::string first = (dir.path() / "first.json").string(), second = (dir.path() / "second.json").string();
    ASSERT_TRUE(save_scene_file(scene, first).is_ok());
    const auto loaded = load_scene_file(first);
    ASSERT_TRUE(loaded.is_ok()) << loaded.error().message;
    expect_equal(*loaded, scene);
    ASSERT_TRUE(save_scene_file(*loaded, second).is_ok());
    const auto again = make_scene(second);  // a FILE.json name loads the file
    ASSERT_TRUE(again.is_ok()) << again.error().message;
    expect_equal(*again, scene);
  }
}

TEST(SceneFiles, TheDocumentedExampleLoads) {
  std::ifstream in(std::string(VDRIG_SOURCE_DIR) + "/docs/sim.md");
  const std::string doc((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::size_t start = doc.find("```json\n{\n  \"format\": \"vdrig-scene\"");
  ASSERT_NE(start, std::string::npos);
  const std::size_t end = doc.find("```", start + 7);
  const auto scene = parse_scene(nlohmann::json::parse(doc.substr(start + 7, end - start - 7)), "docs/sim.md");
  ASSERT_TRUE(scene.is_ok()) << scene.error().message;
  EXPECT_EQ(scene->name, "ggx-metal");
  EXPECT_EQ(scene->materials[2].kind, MaterialKind::kGgx);
  EXPECT_EQ(scene->materials[2].roughness_y, 0.35);
  EXPECT_EQ(scene->patches[0].material, 3);  // by name
  EXPECT_EQ(scene->marker_centres_mm().size(), 4u);
}

TEST(SceneFiles, UnknownNamesAndMissingFilesAreErrors) {
  const auto unknown = make_scene("nonsense");
  ASSERT_FALSE(unknown.is_ok());
  EXPECT_EQ(unknown.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(unknown.error().message.find("patchwork, bands, lights2, softbox"), std::string::npos);
  const auto missing = make_scene("/nonexistent/scene.json");
  ASSERT_FALSE(missing.is_ok());
  EXPECT_EQ(missing.error().code, ErrorCode::kIo);
  EXPECT_NE(missing.error().message.find("/nonexistent/scene.json"), std::string::npos);
}

// A minimal valid scene, edited by each broken case.
nlohmann::json minimal_scene() {
  return nlohmann::json::parse(R"({
    "format": "vdrig-scene", "version": 1, "name": "minimal", "width_mm": 500, "height_mm": 400,
    "materials": [{"name": "paper", "kd": [0.7, 0.7, 0.7]}, {"name": "gloss", "kd": [0.1, 0.1, 0.1],
                  "ks": [0.5, 0.5, 0.5], "shininess": 40}, {"name": "metal", "kind": "ggx", "roughness": 0.2,
                  "f0": [0.9, 0.8, 0.6]}],
    "patches": [{"x0_mm": -100, "y0_mm": -100, "x1_mm": 0, "y1_mm": 0, "material": "gloss"}],
    "markers": [{"centre_mm": [200, 150], "radius_mm": 20, "material": 0}],
    "lights": [{"position_mm": [0, 0, 1000], "intensity": [1e6, 1e6, 1e6]}],
    "area_lights": [{"centre_mm": [0, 500, 1000], "edge_u_mm": [100, 0, 0], "edge_v_mm": [0, 100, 0]}]
  })");
}

TEST(SceneFiles, BrokenFilesGetOneClearErrorNamingThePathAndTheRule) {
  ASSERT_TRUE(parse_scene(minimal_scene(), "minimal").is_ok())
      << parse_scene(minimal_scene(), "minimal").error().message;
  struct Case {
    std::string patch;     // a JSON merge patch applied to the minimal scene
    std::string expected;  // part of the message
  };
  const std::vector<Case> cases = {
      {R"({"materials": [{"kd": [1, 1, 1]}, {}, {"shininess": 0}]})", "materials[2].shininess: must be >= 1, got 0"},
      {R"({"version": 2})", "version: must be 1"},
      {R"({"version": null})", "version: is required"},
      {R"({"format": "something"})", "\"format\" = \"something\" is not one of: vdrig-scene"},
      {R"({"width_mm": -3})", "width_mm: must be > 0, got -3"},
      {R"({"height_mm": null})", "height_mm: is required"},
      {R"({"height_mm": "tall"})", "\"height_mm\" must be a number"},
      {R"({"materials": []})", "materials: needs at least one material"},
      {R"({"materials": null})", "materials: is required"},
      {R"({"materials": {"kd": 1}})", "materials: must be an array"},
      {R"({"materials": [5]})", "materials[0]: settings must be a JSON object"},
      {R"({"materials": [{"kd": [0.5, -0.1, 0.5]}]})", "materials[0].kd[1]: must be >= 0, got -0.1"},
      {R"({"materials": [{"kd": [0.5, 0.5]}]})", "materials[0]: \"kd\" must be an array of 3"},
      {R"({"materials": [{"shinyness": 3}]})", "materials[0]: unknown field \"shinyness\""},
      {R"({"materials": [{"kind": "cook-torrance"}]})", "\"kind\" = \"cook-torrance\" is not one of: phong, ggx"},
      {R"({"materials": [{"kind": "ggx", "roughness": 0}]})", "materials[0].roughness: must be > 0 and <= 1, got 0"},
      {R"({"materials": [{"kind": "ggx", "f0": [1.2, 0, 0]}]})", "materials[0].f0[0]: must be >= 0 and <= 1, got 1.2"},
      {R"({"materials": [{"kind": "ggx", "ks": [1, 1, 1]}]})", "materials[0].ks: is not used by a ggx material"},
      {R"({"materials": [{"roughness": 0.3}]})", "materials[0].roughness: is only used by a ggx material"},
      {R"({"materials": [{"bump_period_mm": 0}]})", "materials[0].bump_period_mm: must be > 0, got 0"},
      {R"({"materials": [{"printed": "yes"}]})", "materials[0]: \"printed\" must be true or false"},
      {R"({"patches": [{"x0_mm": 0, "y0_mm": 0, "x1_mm": -5, "y1_mm": 10, "material": 0}]})",
       "patches[0].x1_mm: must be > x0_mm (0), got -5"},
      {R"({"patches": [{"x0_mm": 0, "y0_mm": 0, "x1_mm": 5, "y1_mm": 10, "material": 7}]})",
       "patches[0].material: must be an index in [0, 3), got 7"},
      {R"({"patches": [{"x0_mm": 0, "y0_mm": 0, "x1_mm": 5, "y1_mm": 10, "material": "velvet"}]})",
       "patches[0].material: no material is named \"velvet\""},
      {R"({"patches": [{"x0_mm": 0, "x1_mm": 5, "y1_mm": 10, "material": 0}]})", "patches[0].y0_mm: is required"},
      {R"({"markers": [{"centre_mm": [0, 0], "radius_mm": 0, "material": 0}]})",
       "markers[0].radius_mm: must be > 0, got 0"},
      {R"({"markers": [{"radius_mm": 3}]})", "markers[0].centre_mm: is required"},
      {R"({"lights": [{"intensity": [1, 1, 1]}]})", "lights[0].position_mm: is required"},
      {R"({"lights": [{"position_mm": [0, 0, 1], "intensity": [1, -1, 1]}]})",
       "lights[0].intensity[1]: must be >= 0, got -1"},
      {R"({"area_lights": [{"centre_mm": [0, 0, 1], "edge_u_mm": [1, 0, 0], "edge_v_mm": [2, 0, 0]}]})",
       "area_lights[0].edge_v_mm: must not be parallel to edge_u_mm"},
      {R"({"area_lights": [{"centre_mm": [0, 0, 1], "edge_u_mm": [1, 0, 0], "edge_v_mm": [0, 1, 0],
                            "samples_per_axis": 2.5}]})",
       "area_lights[0].samples_per_axis: must be an integer, got 2.5"},
      {R"({"ambient": [0, 0, -1]})", "ambient[2]: must be >= 0, got -1"},
      {R"({"colour": "blue"})", "unknown field \"colour\""},
      {R"({"materials": [{"kd_image": "/nonexistent/tex.png"}]})", "materials[0].kd_image: "},
      {R"({"materials": [{"kd_image": "tex.jpg"}]})", "materials[0].kd_image: must be a .png or .exr file"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.patch);
    nlohmann::json j = minimal_scene();
    j.merge_patch(nlohmann::json::parse(c.patch));
    const auto scene = parse_scene(j, "broken.json");
    ASSERT_FALSE(scene.is_ok());
    EXPECT_EQ(scene.error().code, ErrorCode::kInvalidArgument);
    EXPECT_NE(scene.error().message.find("scene broken.json"), std::string::npos) << scene.error().message;
    EXPECT_NE(scene.error().message.find(c.expected), std::string::npos) << scene.error().message;
  }
  // Not JSON, not an object, not a file: still one error, no crash.
  test::TempDir dir("scene_broken");
  for (const std::string text : {"{\"format\": ", "[1, 2]", "", "\x01\x02"}) {
    const std::string path = (dir.path() / "broken.json").string();
    std::ofstream(path) << text;
    const auto scene = load_scene_file(path);
    ASSERT_FALSE(scene.is_ok());
    EXPECT_EQ(scene.error().code, ErrorCode::kInvalidArgument) << scene.error().message;
    EXPECT_NE(scene.error().message.find(path), std::string::npos) << scene.error().message;
  }
}

TEST(SceneFiles, TheSimulatedRigTakesASceneFile) {
  test::TempDir dir("scene_rig");
  const std::string good = (dir.path() / "good.json").string(), bad = (dir.path() / "bad.json").string();
  ASSERT_TRUE(save_scene_file(ggx_scene(), good).is_ok());
  nlohmann::json broken = minimal_scene();
  broken["materials"][1]["shininess"] = 0;
  std::ofstream(bad) << broken.dump();
  rig::BackendRegistry registry;
  register_backends(registry);
  const nlohmann::json camera = {{"width", 32}, {"height", 24}, {"fx", 20.0}, {"fy", 20.0}};
  auto rig = registry.make_rig(sim_rig_config({{"scene", good}, {"camera", camera}}));
  EXPECT_TRUE(rig.is_ok()) << rig.error().describe();
  auto refused = registry.make_rig(sim_rig_config({{"scene", bad}, {"camera", camera}}));
  ASSERT_FALSE(refused.is_ok());
  EXPECT_NE(refused.error().message.find("materials[1].shininess: must be >= 1, got 0"), std::string::npos)
      << refused.error().message;
}

TEST(SceneFiles, KdFromAnImageStretchedOverItsPatch) {
  test::TempDir dir("scene_kd_image");
  // 2 x 2 pixels, BGR as OpenCV stores them: row 0 = (255, 128, 0) RGB, (0, 0, 255); row 1 = grey 64, white.
  cv::Mat png(2, 2, CV_8UC3);
  png.at<cv::Vec3b>(0, 0) = {0, 128, 255};
  png.at<cv::Vec3b>(0, 1) = {255, 0, 0};
  png.at<cv::Vec3b>(1, 0) = {64, 64, 64};
  png.at<cv::Vec3b>(1, 1) = {255, 255, 255};
  ASSERT_TRUE(write_png(dir.path() / "tex.png", png).is_ok());
  ExrImage exr;  // linear, one pixel
  exr.add("R", cv::Mat(1, 1, CV_32F, cv::Scalar(0.25)));
  exr.add("G", cv::Mat(1, 1, CV_32F, cv::Scalar(0.5)));
  exr.add("B", cv::Mat(1, 1, CV_32F, cv::Scalar(2.0)));
  ASSERT_TRUE(write_exr(dir.path() / "tex.exr", exr).is_ok());
  nlohmann::json j = minimal_scene();
  j["materials"][1]["kd_image"] = "tex.png";  // "gloss": the patch [-100, 0] x [-100, 0]
  j["materials"][0]["kd_image"] = "tex.exr";  // the background: the whole surface
  const std::string file = (dir.path() / "textured.json").string();
  std::ofstream(file) << j.dump();
  const auto scene = load_scene_file(file);
  ASSERT_TRUE(scene.is_ok()) << scene.error().message;
  auto srgb = [](double c) { return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4); };
  auto expect_kd = [&](double x, double y, const Vec3d& kd) {
    const Vec3d got = scene->surface_at(x, y).kd;
    EXPECT_LT((got - kd).norm(), 1e-6) << x << ", " << y << ": " << got.transpose() << " vs " << kd.transpose();
  };
  // Pixel centres: row 0 at the patch's smallest y.
  expect_kd(-75, -75, Vec3d(1.0, srgb(128 / 255.0), 0.0));
  expect_kd(-25, -75, Vec3d(0.0, 0.0, 1.0));
  expect_kd(-75, -25, Vec3d::Constant(srgb(64 / 255.0)));
  expect_kd(-25, -25, Vec3d::Ones());
  expect_kd(-50, -75, Vec3d(0.5, 0.5 * srgb(128 / 255.0), 0.5));  // bilinear between the two top pixels
  expect_kd(150, 100, Vec3d(0.25, 0.5, 2.0));                     // background: the EXR over the whole surface
  // The radiance follows the local kd (a Lambertian background under the point light straight above it).
  EXPECT_GT(scene->radiance(Vec3d(-25, -75, 0), Vec3d::UnitZ())[2],
            scene->radiance(Vec3d(-75, -75, 0), Vec3d::UnitZ())[2]);

  // Saved with the image's absolute path: the copy loads from anywhere.
  const std::string copy = (dir.path() / "copy.json").string();
  ASSERT_TRUE(save_scene_file(*scene, copy).is_ok());
  const auto again = load_scene_file(copy);
  ASSERT_TRUE(again.is_ok()) << again.error().message;
  expect_equal(*again, *scene);
  EXPECT_EQ(again->surface_at(-50, -75).kd, scene->surface_at(-50, -75).kd);
  EXPECT_EQ(again->materials[1].kd_image, (dir.path() / "tex.png").lexically_normal().string());
}

}  // namespace
}  // namespace vdrig::sim
