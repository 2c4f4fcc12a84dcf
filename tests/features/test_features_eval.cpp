// The keypoint evaluation of agvnav-features on the real logs (reduced scan count) and its tools.
#include <cmath>
#include <memory>
#include <string>

#include "agv_test.hpp"
#include "eval.hpp"

namespace f = agv::features;

namespace {
const std::string kData = std::string(AGV_SHARED_DATA_DIR) + "/laser2d/";
}

TEST_CASE("features eval: intel, fr079 and mit-csail give sane repeatability and matching", "[features][realdata]") {
  f::EvalOptions o;
  o.maxScans = 150;
  const char* names[] = {"intel", "fr079", "mit-csail"};
  const char* files[] = {"intel/intel-lab.log.gz", "fr079/fr079.log.gz", "mit-csail/mit-cscail.log.gz"};
  std::vector<f::DatasetResult> all;
  for (int d = 0; d < 3; ++d) {
    INFO(names[d]);
    f::DatasetResult r;
    std::string err;
    REQUIRE(f::evaluateLog(names[d], kData + files[d], o, r, err));  // missing data fails loudly
    CHECK(r.scans == 150U);
    CHECK(r.keypointsPerScan > 1.0);
    CHECK(r.pairs > 100U);
    for (const auto& test : r.repeatability) {
      for (const auto& level : test.second) {
        CHECK(level.second >= 0.0);
        CHECK(level.second <= 1.0);
        CHECK(r.samples.at(test.first).at(level.first) > 0U);
      }
    }
    const auto& noise = r.repeatability.at("noise");
    // More range noise, fewer repeated keypoints; 1 cm noise keeps most of them.
    CHECK(noise.at("0.01") > 0.6);
    CHECK(noise.at("0.01") > noise.at("0.05"));
    CHECK(noise.at("0.05") > noise.at("0.2"));
    const auto& sampling = r.repeatability.at("sampling");
    CHECK(sampling.at("x2") > sampling.at("x1/4"));
    // Nearby viewpoints repeat corners (the scans are real, corners are there).
    CHECK(r.repeatability.at("viewpoint").at("0.5") > 0.3);
    // Descriptors: precision falls as the threshold opens; recall rises.
    REQUIRE(r.bsc.size() >= 2U);
    CHECK(r.bsc.front().precision >= r.bsc.back().precision);
    CHECK(r.bsc.front().recall <= r.bsc.back().recall);
    CHECK(r.cgh.front().recall <= r.cgh.back().recall);
    CHECK(r.bsc.back().recall > 0.5);
    all.push_back(std::move(r));
  }
  const std::string js = f::resultsToJson(all);
  CHECK(js.find("\"repeatability\": {") != std::string::npos);
  CHECK(js.find("\"keypoints_per_scan\": {\"intel\": ") != std::string::npos);
  CHECK(js.find("\"mit-csail\": {\n      \"noise\": {\"0.01\": ") != std::string::npos);
}

TEST_CASE("features eval: resampling keeps the geometry", "[features]") {
  auto in = std::make_unique<agv::LaserScan>();
  in->angleMin = -1.0F;
  in->angleIncrement = 0.01F;
  in->rangeMin = 0.1F;
  in->rangeMax = 50.0F;
  for (int i = 0; i < 101; ++i) {
    (void)in->ranges.push_back(i == 50 ? 60.0F : 2.0F + 0.001F * static_cast<float>(i));
  }
  auto out = std::make_unique<agv::LaserScan>();
  f::resampleScan(*in, -2, *out);
  CHECK(out->size() == 51U);
  CHECK(out->angleIncrement == Approx(0.02F));
  CHECK(out->ranges[3] == in->ranges[6]);
  f::resampleScan(*in, 2, *out);
  CHECK(out->size() == 201U);
  CHECK(out->angleIncrement == Approx(0.005F));
  CHECK(out->ranges[21] == Approx(0.5F * (in->ranges[10] + in->ranges[11])));
  CHECK_FALSE(out->isValid(99));  // between a valid reading and the no-return one
  auto noisy = std::make_unique<agv::LaserScan>(*in);
  f::addRangeNoise(*noisy, 0.01, 3U);
  double sq = 0.0;
  for (std::size_t i = 0; i < in->size(); ++i) {
    if (i != 50) {
      const double e = static_cast<double>(noisy->ranges[i] - in->ranges[i]);
      sq += e * e;
    }
  }
  CHECK(std::sqrt(sq / 100.0) == Approx(0.01).epsilon(0.3));
  CHECK(noisy->ranges[50] == 60.0F);  // invalid readings stay as they are
}
