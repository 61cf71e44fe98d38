// gphoto2's setting labels without a camera or libgphoto2 (rig/src/gphoto2_labels.hpp, built whatever the
// gphoto2 backend's option): the shutter/ISO/aperture labels of every vendor's spelling, the nearest stop, and
// which config names each vendor's driver uses (camlibs/ptp2/config.c of libgphoto2), on configs modelled on those.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "gphoto2_labels.hpp"
#include "still_camera.hpp"

namespace vdrig::rig {
namespace {

// ---- labels ----

TEST(Gphoto2Labels, ShutterSpeedsInEveryVendorsSpelling) {
  const std::vector<std::pair<const char*, double>> good = {
      {"1/250", 1.0 / 250}, {"1/3", 1.0 / 3},     {"2", 2.0},         {"0.5", 0.5},
      {"1\"3", 1.3},        {"30\"", 30.0},       {"0.0080s", 0.008}, {"1/4000", 0.00025},
      {"10/1250", 0.008},   {" 1/60 ", 1.0 / 60}, {"2.5", 2.5},       {"0\"5", 0.5}};
  for (const auto& [label, seconds] : good) {
    const auto v = parse_shutter_label(label);
    ASSERT_TRUE(v) << label;
    EXPECT_NEAR(*v, seconds, 1e-12) << label;
  }
  for (const char* label : {"bulb", "Bulb", "BULB", "Time", "x 200", "Auto", "", "1/0", "-1", "1/", "/250", "0",
                            "1.5\"3", "1e-3", "1/250x"})
    EXPECT_FALSE(parse_shutter_label(label)) << "\"" << label << "\" read as " << *parse_shutter_label(label);
}

TEST(Gphoto2Labels, IsoAndAperture) {
  EXPECT_EQ(parse_iso_label("100"), 100.0);
  EXPECT_EQ(parse_iso_label("ISO 200"), 200.0);
  EXPECT_EQ(parse_iso_label("25600"), 25600.0);
  for (const char* label : {"Auto", "Auto ISO", "auto", "Hi 1", "Lo 1", "", "0"})
    EXPECT_FALSE(parse_iso_label(label)) << label;
  EXPECT_EQ(parse_aperture_label("f/5.6"), 5.6);
  EXPECT_EQ(parse_aperture_label("5.6"), 5.6);
  EXPECT_EQ(parse_aperture_label("F8"), 8.0);
  EXPECT_EQ(parse_aperture_label("f/22"), 22.0);
  for (const char* label : {"implicit auto", "f/", "", "f/-2"}) EXPECT_FALSE(parse_aperture_label(label)) << label;
}

// Canon EOS's shutter choices as libgphoto2 lists them (bulb first).
const std::vector<std::string> kCanonShutter = {
    "bulb",  "30",    "25",     "20",     "15",     "13",     "10",     "8",      "6",     "5",     "4",
    "3.2",   "2.5",   "2",      "1.6",    "1.3",    "1",      "0.8",    "0.6",    "0.5",   "0.4",   "0.3",
    "1/4",   "1/5",   "1/6",    "1/8",    "1/10",   "1/13",   "1/15",   "1/20",   "1/25",  "1/30",  "1/40",
    "1/50",  "1/60",  "1/80",   "1/100",  "1/125",  "1/160",  "1/200",  "1/250",  "1/320", "1/400", "1/500",
    "1/640", "1/800", "1/1000", "1/1250", "1/1600", "1/2000", "1/2500", "1/3200", "1/4000"};

TEST(Gphoto2Labels, NearestStopAndTheExposureReallySet) {
  // 7.5 ms: 1/125 is 0.093 stops off, 1/160 is 0.263 (log2(7.5/6.25)).
  auto c = choose_stop(kCanonShutter, 0.0075, parse_shutter_label);
  ASSERT_TRUE(c);
  EXPECT_EQ(c->label, "1/125");
  EXPECT_DOUBLE_EQ(c->value, 0.008);
  EXPECT_EQ(kCanonShutter[c->index], "1/125");
  // Longer than anything: the longest timed exposure, never bulb; shorter than anything: the shortest.
  EXPECT_EQ(choose_stop(kCanonShutter, 1e6, parse_shutter_label)->label, "30");
  EXPECT_EQ(choose_stop(kCanonShutter, 1e-9, parse_shutter_label)->label, "1/4000");
  // Nearest in stops, not in seconds: 0.55 s is 0.30 s from 1/4 and 0.45 s from 1, but 1.14 vs 0.86 stops.
  EXPECT_EQ(choose_stop({"1/4", "1"}, 0.55, parse_shutter_label)->label, "1");
  const std::vector<std::string> iso = {"Auto", "100", "200", "400", "800", "1600", "3200", "6400"};
  EXPECT_EQ(choose_stop(iso, 300, parse_iso_label)->label, "400");  // 0.415 stops; 200 is 0.585
  EXPECT_EQ(choose_stop(iso, 10, parse_iso_label)->label, "100");
  EXPECT_FALSE(choose_stop({"Auto", "bulb"}, 100, parse_iso_label));
  EXPECT_FALSE(choose_stop(iso, -1, parse_iso_label));
  const auto range = stop_range(kCanonShutter, parse_shutter_label);
  ASSERT_TRUE(range);
  EXPECT_DOUBLE_EQ(range->first, 1.0 / 4000);
  EXPECT_DOUBLE_EQ(range->second, 30.0);
}

TEST(StillCameraStops, NearestStopSkipsWhatIsNoExposure) {
  EXPECT_EQ(nearest_stop({0.0, -1.0, NAN, 0.01, INFINITY}, 1.0), 3u);
  EXPECT_EQ(nearest_stop({0.5, 2.0}, 1.0), 0u);  // a tie: the first listed
  EXPECT_FALSE(nearest_stop({0.0, NAN}, 1.0));
  EXPECT_FALSE(nearest_stop({1.0}, 0.0));
  EXPECT_TRUE(is_decodable_image_name("IMG_0001.JPG"));
  EXPECT_TRUE(is_decodable_image_name("a.tiff"));
  EXPECT_FALSE(is_decodable_image_name("IMG_0001.CR2"));
  EXPECT_FALSE(is_decodable_image_name("DSC_0001.NEF"));
  EXPECT_FALSE(is_decodable_image_name("jpg"));
}

// ---- config names across vendors ----

ConfigEntry entry(std::string name, std::vector<std::string> choices, std::string value, bool readonly = false) {
  ConfigEntry e;
  e.name = std::move(name);
  e.choices = std::move(choices);
  e.value = std::move(value);
  e.readonly = readonly;
  return e;
}

TEST(Gphoto2Config, SettingNamesOfCanonNikonAndSony) {
  // Canon EOS: shutterspeed / iso / aperture, capturetarget "Internal RAM" / "Memory card".
  const std::vector<ConfigEntry> canon = {entry("capturetarget", {"Internal RAM", "Memory card"}, "Memory card"),
                                          entry("shutterspeed", kCanonShutter, "1/60"),
                                          entry("iso", {"Auto", "100", "200", "400"}, "Auto"),
                                          entry("aperture", {"4", "5.6", "8", "11"}, "5.6")};
  EXPECT_EQ(find_setting(canon, StillSetting::kShutter, parse_shutter_label)->name, "shutterspeed");
  EXPECT_EQ(find_setting(canon, StillSetting::kIso, parse_iso_label)->name, "iso");
  EXPECT_EQ(find_setting(canon, StillSetting::kAperture, parse_aperture_label)->name, "aperture");
  EXPECT_EQ(choose_capture_target(find_setting(canon, StillSetting::kCaptureTarget)->choices, true), "Internal RAM");
  EXPECT_EQ(choose_capture_target(find_setting(canon, StillSetting::kCaptureTarget)->choices, false), "Memory card");

  // Nikon: the generic ExposureTime ("shutterspeed", in "0.0080s" form) read-only outside M, the vendor's
  // "shutterspeed2" writable; "f-number"; SDRAM / Card targets.
  const std::vector<ConfigEntry> nikon = {
      entry("shutterspeed", {"0.0010s", "0.0080s", "1.0000s"}, "0.0080s", /*readonly=*/true),
      entry("shutterspeed2", {"1/1000", "1/125", "1", "30", "Bulb", "x 200"}, "1/125"),
      entry("f-number", {"f/3.5", "f/5.6", "f/8"}, "f/5.6"), entry("iso", {"100", "200", "400"}, "200"),
      entry("capturetarget", {"SDRAM", "Card"}, "Card")};
  EXPECT_EQ(find_setting(nikon, StillSetting::kShutter, parse_shutter_label)->name, "shutterspeed2");
  EXPECT_EQ(find_setting(nikon, StillSetting::kAperture, parse_aperture_label)->name, "f-number");
  EXPECT_EQ(choose_capture_target(nikon.back().choices, true), "SDRAM");
  EXPECT_EQ(choose_capture_target(nikon.back().choices, false), "Card");
  EXPECT_EQ(choose_stop(nikon[1].choices, 20.0, parse_shutter_label)->label, "30");  // never "Bulb" or "x 200"

  // Sony: shutterspeed with seconds marks, iso with "Auto ISO", f-number.
  const std::vector<ConfigEntry> sony = {entry("shutterspeed", {"30\"", "1\"3", "1/250", "Bulb"}, "1/250"),
                                         entry("iso", {"Auto ISO", "100", "800"}, "Auto ISO"),
                                         entry("f-number", {"f/2.8", "f/4"}, "f/4")};
  EXPECT_EQ(
      choose_stop(find_setting(sony, StillSetting::kShutter, parse_shutter_label)->choices, 1.0, parse_shutter_label)
          ->label,
      "1\"3");
  EXPECT_EQ(find_setting(sony, StillSetting::kAperture, parse_aperture_label)->name, "f-number");

  // A camera in an automatic mode (everything read-only) or one whose ISO is Auto only: nothing to set.
  const std::vector<ConfigEntry> automatic = {entry("shutterspeed", kCanonShutter, "1/60", true),
                                              entry("iso", {"Auto"}, "Auto")};
  EXPECT_EQ(find_setting(automatic, StillSetting::kShutter, parse_shutter_label), nullptr);
  EXPECT_EQ(find_setting(automatic, StillSetting::kIso, parse_iso_label), nullptr);
  EXPECT_EQ(find_setting({}, StillSetting::kCaptureTarget), nullptr);
  EXPECT_FALSE(choose_capture_target({"Memory card"}, true));
}

}  // namespace
}  // namespace vdrig::rig
