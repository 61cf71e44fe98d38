// Issue #16: `vdrig fit --mpi` and `vdrig obsmap build --mpi` under mpirun give what the single process gives, bit
// for bit, and a job that loses a rank ends with an error (never a hang) and resumes to the identical map.
// The reference is the single-process `vdrig fit` of the same observation-map file (fitting::fit_parameter_map,
// whose in-memory/file equivalence fitting's tests check). Skipped (CTest's skip code) when vdrig was built without
// MPI or mpirun is absent. mpirun's flags come from one CMake variable, VDRIG_MPIEXEC_FLAGS (docs/scale.md).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "vdrig/core/image_io.hpp"
#include "vdrig/fitting/parameter_map.hpp"
#include "vdrig/test/build_paths.hpp"
#include "vdrig/test/process.hpp"
#include "vdrig/test/temp_dir.hpp"
#include "vdrig/test/true_calibration.hpp"

namespace vdrig {
namespace {
namespace fs = std::filesystem;

using vdrig::test::ProcessRun;  // exit_code 124: killed by the timeout (a hang)

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

class MpiFit : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!VDRIG_WITH_MPI) GTEST_SKIP() << "vdrig built without MPI (VDRIG_WITH_MPI off)";
    if (std::system("command -v " VDRIG_MPIEXEC " >/dev/null 2>&1") != 0) GTEST_SKIP() << "no mpirun";
    // A small simulated session (160 x 120 camera, latlong:4: 53 views, two exposures), captured and merged by
    // the CLI: seconds, and enough views for the shared-lights fit to find the scene's light from the lobes.
    {
      std::ofstream rig(dir_ / "rig.json");
      rig << R"({"stage": {"backend": "sim"}, "camera": {"backend": "sim"}, "light": {"backend": "sim"},
                 "sim": {"scene": "patchwork", "camera": {"width": 160, "height": 120, "fx": 200.0, "fy": 200.0}}})";
    }
    const ProcessRun captured = vdrig("capture --rig " + (dir_ / "rig.json").string() +
                                      " --scheme latlong:4 --bracket fixed:1,0.25 --out " + session());
    ASSERT_EQ(captured.exit_code, 0) << captured.out;
    // Not a calibration test: the simulator's truth as the session's calib/ (the stages never take it themselves).
    const Status calibrated = vdrig::test::write_true_calibration(fs::path(session()));
    ASSERT_TRUE(calibrated) << calibrated.describe();
    const ProcessRun merged = vdrig("hdr " + session());
    ASSERT_EQ(merged.exit_code, 0) << merged.out;
    // 40 x 40 texels in tiles of 8: 25 tiles, enough to spread over 3 ranks.
    const ProcessRun built = vdrig("obsmap build " + session() + " --res 40x40 --tile 8 --out " + obsmap());
    ASSERT_EQ(built.exit_code, 0) << built.out;
  }

  std::string session() const { return (dir_ / "session").string(); }
  std::string obsmap() const { return (dir_ / "obs.vdobs").string(); }

  /// `command` through the shell under a timeout, stdout and stderr captured together. The timeout only catches a
  /// hang: the one-rank Phong fit under ASan takes ~110 s alone and nearly twice that on a loaded machine.
  static ProcessRun shell(const std::string& command, double timeout_s = 480) {
    return vdrig::test::run_shell(command, {.timeout_s = timeout_s, .merge_stderr = true});
  }
  ProcessRun vdrig(const std::string& args) const { return shell(std::string("'") + VDRIG_CLI_PATH + "' " + args); }
  /// `mpirun -n ranks vdrig args` with the project's flags (and --allow-run-as-root as root, as in CI).
  ProcessRun mpi_vdrig(int ranks, const std::string& args, const std::string& env = "") const {
    std::string flags = VDRIG_MPIEXEC_FLAGS;
    if (::geteuid() == 0) flags += " --allow-run-as-root";
    // Under ASan, OpenMPI's allocations at init are suppressed by library (scripts/lsan.supp), which LSan can only
    // match with full stacks: its libraries have no frame pointers for the fast unwinder.
    const std::string asan = "ASAN_OPTIONS=\"${ASAN_OPTIONS:+$ASAN_OPTIONS:}fast_unwind_on_malloc=0\" ";
    return shell("env " + asan + env + " " VDRIG_MPIEXEC " -n " + std::to_string(ranks) + " " + flags + " '" +
                 VDRIG_CLI_PATH + "' " + args);
  }

  /// Every channel bit for bit, and the header attributes but the command line that made the map.
  static void expect_identical_maps(const fs::path& a_path, const fs::path& b_path) {
    auto a = read_exr(a_path), b = read_exr(b_path);
    ASSERT_TRUE(a) << a.error().describe();
    ASSERT_TRUE(b) << b.error().describe();
    ASSERT_EQ(a->width, b->width);
    ASSERT_EQ(a->height, b->height);
    ASSERT_EQ(a->channel_names.size(), b->channel_names.size());
    for (size_t c = 0; c < a->channel_names.size(); ++c) {
      const int j = b->find(a->channel_names[c]);
      ASSERT_GE(j, 0) << a->channel_names[c];
      const cv::Mat& pa = a->channels[c];
      const cv::Mat& pb = b->channels[static_cast<size_t>(j)];
      int differing = 0;
      for (int y = 0; y < pa.rows; ++y)
        differing += std::memcmp(pa.ptr<float>(y), pb.ptr<float>(y), sizeof(float) * pa.cols) != 0;
      EXPECT_EQ(differing, 0) << "channel " << a->channel_names[c] << ": rows differing";
    }
    // The fit's wall time (vdrig.fit_seconds, shown by vdrig report) is the one number that may differ.
    auto numbers = [](std::map<std::string, double> m) {
      m.erase(fitting::kFitSecondsAttribute);
      return m;
    };
    EXPECT_EQ(numbers(a->number_attributes), numbers(b->number_attributes));
    auto strings = [](std::map<std::string, std::string> m) {
      m.erase("vdrig.command");
      return m;
    };
    EXPECT_EQ(strings(a->string_attributes), strings(b->string_attributes));
  }

  /// The single-process fit, then 1, 2 and 3 ranks, each compared with it.
  void check_ranks_agree(const std::string& model_args) {
    const fs::path reference = dir_ / "reference.exr";
    const ProcessRun single = vdrig("fit " + session() + " --obsmap " + obsmap() + " " + model_args + " --out " +
                                    reference.string() + " --threads 2");
    ASSERT_EQ(single.exit_code, 0) << single.out;
    for (int ranks : {1, 2, 3}) {
      const fs::path out = dir_ / ("mpi_" + std::to_string(ranks) + ".exr");
      const ProcessRun r = mpi_vdrig(ranks, "fit " + session() + " --obsmap " + obsmap() + " " + model_args +
                                                " --out " + out.string() + " --threads 1 --mpi");
      ASSERT_EQ(r.exit_code, 0) << r.out;
      last_fit_output_ = r.out;
      std::printf("%d rank(s): %.2f s wall\n", ranks, r.wall_s);
      expect_identical_maps(reference, out);
      EXPECT_FALSE(fs::exists(out.string() + ".tiles")) << "tile records are removed once the map is written";
    }
  }

  test::TempDir dir_{"mpi_fit"};
  std::string last_fit_output_;
};

TEST_F(MpiFit, PhongAutoWithSharedLightsIsBitIdenticalOnOneTwoThreeRanks) {
  check_ranks_agree("--model phong:auto --shared-lights");
  // The gather/broadcast step ran with lights to share (the map says which it found, and uses them somewhere).
  auto map = read_exr(dir_ / "mpi_3.exr");
  ASSERT_TRUE(map);
  EXPECT_FALSE(map->string_attributes["vdrig.shared_lights"].empty()) << last_fit_output_;
  const int c = map->find("shared_lights");
  ASSERT_GE(c, 0);
  EXPECT_GT(cv::countNonZero(map->channels[static_cast<size_t>(c)]), 0);
}

TEST_F(MpiFit, HshIsBitIdenticalOnOneTwoThreeRanks) { check_ranks_agree("--model hsh:2 --holdout 1"); }

TEST_F(MpiFit, GgxIsBitIdenticalOnOneTwoThreeRanks) {
  // A BRDF fit depends on each texel's place under the light: every tile's texels are fitted where they lie.
  check_ranks_agree("--model ggx:iso --light 0.1,-0.2,1.5 --holdout 1");
  auto map = read_exr(dir_ / "mpi_3.exr");
  ASSERT_TRUE(map);
  EXPECT_EQ(map->string_attributes["vdrig.session_light"].rfind("point 0.1 -0.2 1.5", 0), 0u) << last_fit_output_;
}

TEST_F(MpiFit, ObsmapBuildOnTwoRanksIsByteIdentical) {
  const fs::path out = dir_ / "mpi.vdobs";
  const ProcessRun r =
      mpi_vdrig(2, "obsmap build " + session() + " --res 40x40 --tile 8 --out " + out.string() + " --mpi");
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const std::string a = slurp(obsmap()), b = slurp(out);
  ASSERT_GT(a.size(), 128u);
  EXPECT_EQ(a.size(), b.size());
  EXPECT_TRUE(a == b) << "the assembled file differs from the single-process one";
  for (const auto& e : fs::directory_iterator(dir_))
    EXPECT_EQ(e.path().string().find(".part-"), std::string::npos) << "part left behind: " << e.path();
}

TEST_F(MpiFit, LostRankEndsTheJobAndTheResumedFitIsIdentical) {
  const std::string model = "--model phong:auto --shared-lights";
  const fs::path reference = dir_ / "reference.exr", out = dir_ / "resumed.exr";
  const ProcessRun single = vdrig("fit " + session() + " --obsmap " + obsmap() + " " + model + " --out " +
                                  reference.string() + " --threads 2");
  ASSERT_EQ(single.exit_code, 0) << single.out;
  const std::string args =
      "fit " + session() + " --obsmap " + obsmap() + " " + model + " --out " + out.string() + " --threads 1 --mpi";
  // TEST HOOK: rank 2 exits hard after recording 3 tiles.
  const ProcessRun killed = mpi_vdrig(3, args, "VDRIG_TEST_MPI_EXIT_RANK=2 VDRIG_TEST_MPI_EXIT_AFTER_TILES=3");
  EXPECT_NE(killed.exit_code, 0) << killed.out;
  EXPECT_NE(killed.exit_code, 124) << "the job hung after losing a rank:\n" << killed.out;
  EXPECT_FALSE(fs::exists(out));
  // Rank 0's log names which rank had which tile.
  EXPECT_NE(killed.out.find("-> rank 2"), std::string::npos) << killed.out;
  int records = 0;
  for (const auto& e : fs::recursive_directory_iterator(out.string() + ".tiles"))
    records += e.path().extension() == ".rec";
  EXPECT_GE(records, 3) << "the tiles finished before the loss are on disk";
  EXPECT_LT(records, 50) << "not every tile of both passes was recorded";

  const ProcessRun resumed = mpi_vdrig(2, args);
  ASSERT_EQ(resumed.exit_code, 0) << resumed.out;
  EXPECT_NE(resumed.out.find("already recorded"), std::string::npos) << resumed.out;
  EXPECT_EQ(resumed.out.find("pass 1/2: 0 of"), std::string::npos) << "the resumed job refitted every tile";
  expect_identical_maps(reference, out);
}

}  // namespace
}  // namespace vdrig
