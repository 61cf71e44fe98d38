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

}  // namespace
}  // namespace vdrig::pipeline::html
