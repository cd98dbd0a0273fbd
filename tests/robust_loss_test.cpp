#include "fitting/robust_loss.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>

namespace s2m {
namespace {

TEST(ParseRobustLoss, ReadsEverySpellingAndItsScale) {
  EXPECT_EQ(ParseRobustLoss("none").kind, LossKind::kNone);
  EXPECT_EQ(ParseRobustLoss("huber").kind, LossKind::kHuber);
  EXPECT_EQ(ParseRobustLoss("cauchy").kind, LossKind::kCauchy);
  EXPECT_EQ(ParseRobustLoss("tukey").kind, LossKind::kTukey);
  EXPECT_EQ(ParseRobustLoss("tukey").scale, 0.0);  // from the data
  EXPECT_TRUE(ParseRobustLoss("cauchy").scale_from_data());
  const RobustLoss huber = ParseRobustLoss("huber:0.25");
  EXPECT_EQ(huber.kind, LossKind::kHuber);
  EXPECT_EQ(huber.scale, 0.25);
  EXPECT_FALSE(huber.scale_from_data());
  EXPECT_EQ(ParseRobustLoss("cauchy:1e-3").scale, 1e-3);
  EXPECT_EQ(ParseRobustLoss("tukey:2").scale, 2.0);
}

TEST(ParseRobustLoss, ToStringReadsBack) {
  for (const char* text : {"none", "huber", "cauchy", "tukey", "huber:0.5", "cauchy:0.001", "tukey:3"}) {
    const RobustLoss loss = ParseRobustLoss(text);
    const RobustLoss again = ParseRobustLoss(ToString(loss));
    EXPECT_EQ(again.kind, loss.kind) << text;
    EXPECT_EQ(again.scale, loss.scale) << text;
  }
}

TEST(ParseRobustLoss, RejectsUnknownNamesAndBadScalesNamingTheSpellings) {
  for (const char* text : {"", "l1", "Huber", "tukey:", "tukey:0", "tukey:-1", "cauchy:abc", "huber:1x",
                           "none:1", "tukey:inf", "tukey:nan"}) {
    try {
      ParseRobustLoss(text);
      ADD_FAILURE() << "accepted '" << text << "'";
    } catch (const std::invalid_argument& e) {
      const std::string message = e.what();
      EXPECT_NE(message.find("huber[:scale]"), std::string::npos) << message;
      EXPECT_NE(message.find("tukey[:scale]"), std::string::npos) << message;
    }
  }
}

// rho' and rho'' against central differences of rho (and of rho'), inside and outside the scale, for every
// loss.
TEST(EvaluateLoss, DerivativesMatchCentralDifferences) {
  const double c = 0.7;
  for (LossKind kind : {LossKind::kNone, LossKind::kHuber, LossKind::kCauchy, LossKind::kTukey}) {
    for (double s : {1e-3, 0.05, 0.2, 0.45, 0.6, 1.3, 4.0, 25.0}) {
      if (std::abs(s - c * c) < 1e-3) continue;  // Huber's and Tukey's kink at s = c^2
      const double h = 1e-6 * std::max(1.0, s);
      const LossValue v = EvaluateLoss(kind, c, s);
      const LossValue plus = EvaluateLoss(kind, c, s + h);
      const LossValue minus = EvaluateLoss(kind, c, s - h);
      const double first = (plus.rho - minus.rho) / (2 * h);
      const double second = (plus.first - minus.first) / (2 * h);
      EXPECT_NEAR(v.first, first, 1e-7 * std::max(1.0, std::abs(first))) << ToString(kind) << " s=" << s;
      EXPECT_NEAR(v.second, second, 1e-6 * std::max(1.0, std::abs(second))) << ToString(kind) << " s=" << s;
    }
  }
}

TEST(EvaluateLoss, AgreesWithLeastSquaresForSmallResidualsAndBoundsTheLargeOnes) {
  const double c = 2.0;
  for (LossKind kind : {LossKind::kHuber, LossKind::kCauchy, LossKind::kTukey}) {
    const LossValue small = EvaluateLoss(kind, c, 1e-8);
    EXPECT_NEAR(small.rho, 1e-8, 1e-14) << ToString(kind);
    EXPECT_NEAR(small.first, 1.0, 1e-8) << ToString(kind);
    EXPECT_LT(EvaluateLoss(kind, c, 100.0).first, 0.5) << ToString(kind);  // a far point is down-weighted
  }
  EXPECT_EQ(EvaluateLoss(LossKind::kTukey, c, 4.0 + 1e-9).first, 0.0);  // rejected beyond c
  EXPECT_NEAR(EvaluateLoss(LossKind::kTukey, c, 1e6).rho, c * c / 3.0, 1e-12);
}

}  // namespace
}  // namespace s2m
