// The report's number formatting (pipeline/src/html.hpp, private to the report: included by path): values to the
// precision a reader needs, with their uncertainty, and scale ends that are zero at the scale shown as 0. The report
// printed "2.2193484540451628e-05 ± 0.00051" and a colour-bar minimum of "2.201e-17".
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "../../pipeline/src/html.hpp"

namespace vdrig::pipeline::html {
namespace {

TEST(ReportNumbers, SignificantDigitsWithoutNoise) {
  EXPECT_EQ(significant(2.2193484540451628e-05, 3), "2.22e-05");
  EXPECT_EQ(significant(0.000512, 3), "0.000512");
  EXPECT_EQ(significant(12.3456, 3), "12.3");
  EXPECT_EQ(significant(0.5, 3), "0.5");
  EXPECT_EQ(significant(1500.0, 3), "1500");
  EXPECT_EQ(significant(-2.5, 2), "-2.5");
  EXPECT_EQ(significant(0.0, 3), "0");
  EXPECT_EQ(significant(3.2e7, 3), "3.2e+07");
  EXPECT_EQ(significant(std::numeric_limits<double>::quiet_NaN()), "nan");
}

TEST(ReportNumbers, ValuesToThePrecisionOfTheirUncertainty) {
  EXPECT_EQ(with_uncertainty(2.2193484540451628e-05, 0.00051), "0.00002 ± 0.00051");
  EXPECT_EQ(with_uncertainty(-2.2193484540451628e-07, 0.00051), "0.00000 ± 0.00051") << "no negative zero";
  EXPECT_EQ(with_uncertainty(12.3456, 0.21), "12.35 ± 0.21");
  EXPECT_EQ(with_uncertainty(2503.6, 12.0), "2504 ± 12");
  EXPECT_EQ(with_uncertainty(1234567.0, 250.0), "1234567 ± 250");
  EXPECT_EQ(with_uncertainty(0.5, 0.0), "0.5") << "no usable sigma: the value alone";
  EXPECT_EQ(with_uncertainty(3e-12, 1e-13), "3e-12 ± 1e-13");
}

TEST(ReportNumbers, ScaleEndsThatAreZeroAtTheScaleReadZero) {
  EXPECT_EQ(scale_label(2.201e-17, 2.201e-17, 0.04), "0");
  EXPECT_EQ(scale_label(0.04, 2.201e-17, 0.04), "0.04");
  EXPECT_EQ(scale_label(0.013, 0.013, 0.046), "0.013");
  EXPECT_EQ(scale_label(2.201e-17, 2.201e-17, 5e-17), "2.2e-17") << "a tiny range keeps its own numbers";
}

// Colour bars and axes are labelled at round values (1, 2 or 5 x 10^k) inside the range, with the decimals of the step:
// never a raw float ("0.30000000000000004", "2.2193484540451628e-05") or a tick outside the scale.
TEST(ReportNumbers, TicksAtRoundValuesWithTheDecimalsOfTheirStep) {
  Ticks t = nice_ticks(2.201e-17, 0.04, 5);
  EXPECT_DOUBLE_EQ(t.step, 0.01);
  ASSERT_EQ(t.values.size(), 5u);
  EXPECT_EQ(tick_label(t.values[0], t.step), "0");
  EXPECT_EQ(tick_label(t.values[3], t.step), "0.03") << "not 0.030000000000000002";
  t = nice_ticks(0.011, 0.088, 5);
  EXPECT_DOUBLE_EQ(t.step, 0.02);
  ASSERT_EQ(t.values.size(), 4u);
  EXPECT_EQ(tick_label(t.values.front(), t.step), "0.02");
  EXPECT_EQ(tick_label(t.values.back(), t.step), "0.08");
  t = nice_ticks(0, 0.0213, 5);  // marker reprojection errors of hundredths of a pixel
  EXPECT_DOUBLE_EQ(t.step, 0.01);
  EXPECT_EQ(t.values.size(), 3u);
  t = nice_ticks(3, 187, 8);  // view numbers
  EXPECT_DOUBLE_EQ(t.step, 50);
  EXPECT_EQ(tick_label(t.values.front(), t.step), "50");
  t = nice_ticks(0, 2.2e-05, 5);
  EXPECT_EQ(tick_label(t.values[1], t.step), "1e-05");
  EXPECT_EQ(tick_label(-1e-18, 0.05), "0") << "no -0.00";
  EXPECT_EQ(tick_label(-0.1, 0.05), "-0.10");
  t = nice_ticks(4, 4, 5);  // an empty range: one tick at its value
  ASSERT_EQ(t.values.size(), 1u);
  EXPECT_EQ(tick_label(t.values[0], t.step), "4");
}

// A colour bar labels its ends when no tick is near them: a capture order from 1 to 188 reads "1 50 100 150 188", not
// "0 50 ..."; a residual from 5.9e-05 reads 0 at its left end.
TEST(ReportNumbers, ColourBarLabelsItsEndsAwayFromTicks) {
  const auto labels = [](const std::string& svg) {
    std::vector<std::string> out;
    for (size_t at = svg.find("<text class=\"tick"); at != std::string::npos;
         at = svg.find("<text class=\"tick", at + 1)) {
      const size_t start = svg.find('>', at) + 1;
      out.push_back(svg.substr(start, svg.find("</text>", start) - start));
    }
    return out;
  };
  EXPECT_EQ(labels(colour_bar(1, 188, "capture order")), (std::vector<std::string>{"50", "100", "150", "1", "188"}));
  EXPECT_EQ(labels(colour_bar(5.94e-05, 0.122, "rms", true)), (std::vector<std::string>{"0.05", "0.10", "0"}));
  EXPECT_NE(colour_bar(5.94e-05, 0.122, "rms", true).find("&#8805; 0.122 shown as top"), std::string::npos);
}

}  // namespace
}  // namespace vdrig::pipeline::html
