// The keypoint evaluation of agvnav-features on the real logs (reduced scan count) and its tools.
#include <cmath>
#include <cstdlib>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "agv/report/json.hpp"
#include "agv_test.hpp"
#include "eval.hpp"

namespace f = agv::features;
using agv::report::Json;

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
  // The JSON document, written and parsed back: every dataset's figures under the documented keys.
  const Json js = Json::parse(agv::report::dumpJson(f::resultsToJson(all)));
  std::vector<std::string> keys;
  for (const auto& item : js.items()) {
    keys.push_back(item.key());
  }
  CHECK(keys ==
        std::vector<std::string>{"repeatability", "keypoints_per_scan", "scans", "descriptors", "falko_params"});
  for (const f::DatasetResult& r : all) {
    INFO(r.name);
    CHECK(js.at("keypoints_per_scan").at(r.name).get<double>() == r.keypointsPerScan);
    CHECK(js.at("scans").at(r.name).get<std::size_t>() == r.scans);
    for (const auto& [test, levels] : r.repeatability) {
      for (const auto& [level, value] : levels) {
        CHECK(js.at("repeatability").at(r.name).at(test).at(level).get<double>() == value);
      }
    }
    const Json& bsc = js.at("descriptors").at(r.name).at("bsc");
    REQUIRE(bsc.size() == r.bsc.size());
    CHECK(bsc.back().at("threshold").get<double>() == r.bsc.back().threshold);
    CHECK(bsc.back().at("precision").get<double>() == r.bsc.back().precision);
    CHECK(bsc.back().at("recall").get<double>() == r.bsc.back().recall);
    CHECK(js.at("descriptors").at(r.name).at("cgh").size() == r.cgh.size());
  }
  const Json& params = js.at("falko_params");
  CHECK(params.at("neigh_a").get<double>() == 0.2);  // the float parameter as typed
  CHECK(params.at("neigh_b").get<double>() == 0.07);
  CHECK(params.at("beta").get<double>() == 4.0);
  CHECK(params.at("grid_sectors").get<std::size_t>() == 16U);
  CHECK(params.at("max_score").get<double>() == 1.5);
  CHECK(params.at("nms_radius").get<double>() == 0.2);
  CHECK_FALSE(js.contains("keypoints_file"));
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

namespace {

/// Reads back one line of the scan file `export` writes (the reader another detector would have).
bool parseScanLine(const std::string& line, std::string& dataset, std::string& variant, std::size_t& index,
                   agv::LaserScan& s) {
  std::istringstream in(line);
  std::size_t n = 0;
  std::string tok[5];
  if (!(in >> dataset >> variant >> index)) {
    return false;
  }
  for (std::string& t : tok) {
    in >> t;
  }
  s.angleMin = std::strtof(tok[0].c_str(), nullptr);
  s.angleIncrement = std::strtof(tok[1].c_str(), nullptr);
  s.rangeMin = std::strtof(tok[2].c_str(), nullptr);
  s.rangeMax = std::strtof(tok[3].c_str(), nullptr);
  n = std::strtoul(tok[4].c_str(), nullptr, 10);
  s.ranges.clear();
  for (std::size_t i = 0; i < n; ++i) {
    std::string r;
    if (!(in >> r) || s.ranges.push_back(std::strtof(r.c_str(), nullptr)) != agv::Status::Ok) {
      return false;
    }
  }
  std::string extra;
  return !(in >> extra);
}

std::vector<std::string> lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);) {
    out.push_back(l);
  }
  return out;
}

}  // namespace

TEST_CASE("features eval: another detector's keypoints are scored exactly like its own", "[features][realdata]") {
  f::EvalOptions o;
  o.maxScans = 40;
  const std::string log = kData + "fr079/fr079.log.gz";
  f::DatasetResult own;
  std::string err;
  REQUIRE(f::evaluateLog("fr079", log, o, own, err));
  std::ostringstream kp;
  f::ExportStreams out;
  out.keypoints = &kp;
  REQUIRE(f::exportLog("fr079", log, o, out, err));
  // One line per scan and variant: clean, 6 noise levels, 3 resampling factors.
  CHECK(lines(kp.str()).size() == 40U * 10U);

  f::KeypointTable table;
  std::istringstream in(kp.str());
  REQUIRE(f::readKeypointTable(in, table, err));
  f::DatasetResult ext;
  REQUIRE(f::evaluateLog("fr079", log, o, ext, err, &table));
  CHECK(ext.repeatability == own.repeatability);
  CHECK(ext.samples == own.samples);
  CHECK(ext.keypointsPerScan == own.keypointsPerScan);
  CHECK(ext.pairs == own.pairs);
  CHECK(ext.bsc.empty());
  CHECK(ext.cgh.empty());
  // Keypoints from a file: the file's name (escaped: quotes and backslashes) replaces the parameters.
  const Json ej = Json::parse(agv::report::dumpJson(f::resultsToJson({ext}, agv::FalkoParams{}, "dir\\kp \"1\".txt")));
  CHECK(ej.at("keypoints_file") == "dir\\kp \"1\".txt");
  CHECK_FALSE(ej.contains("falko_params"));
  CHECK(ej.at("descriptors").at("fr079").at("bsc").empty());

  // The scores come from the table: the clean keypoints as the 1 cm noise ones repeat all of
  // themselves; no keypoint at all in the oversampled scans repeats none.
  const double before = own.repeatability.at("noise").at("0.01");
  REQUIRE(before < 1.0);
  table["fr079"]["noise-0.01"] = table["fr079"]["clean"];
  for (auto& scan : table["fr079"]["sampling-x2"]) {
    scan.second.clear();
  }
  REQUIRE(f::evaluateLog("fr079", log, o, ext, err, &table));
  CHECK(ext.repeatability.at("noise").at("0.01") == 1.0);
  CHECK(ext.repeatability.at("sampling").at("x2") == 0.0);
  CHECK(ext.repeatability.at("viewpoint") == own.repeatability.at("viewpoint"));
  CHECK(ext.repeatability.at("noise").at("0.03") == own.repeatability.at("noise").at("0.03"));

  // A table that does not cover the run is refused, naming what is missing.
  f::KeypointTable bad = table;
  bad["fr079"]["noise-0.3"].erase(3);
  CHECK_FALSE(f::evaluateLog("fr079", log, o, ext, err, &bad));
  CHECK(err.find("noise-0.3: no line for scan 3") != std::string::npos);
  bad = table;
  bad["fr079"].erase("sampling-x1/4");
  CHECK_FALSE(f::evaluateLog("fr079", log, o, ext, err, &bad));
  CHECK(err.find("no line for variant sampling-x1/4") != std::string::npos);
  bad = table;
  bad["fr079"]["noise-0.5"] = table["fr079"]["clean"];
  CHECK_FALSE(f::evaluateLog("fr079", log, o, ext, err, &bad));
  CHECK(err.find("unknown variant noise-0.5") != std::string::npos);
  bad = table;
  bad["fr079"]["clean"][40] = {};
  CHECK_FALSE(f::evaluateLog("fr079", log, o, ext, err, &bad));
  CHECK(err.find("scan 40 beyond the 40 scans") != std::string::npos);
  CHECK_FALSE(f::evaluateLog("intel", kData + "intel/intel-lab.log.gz", o, ext, err, &table));
  CHECK(err.find("no line for dataset intel") != std::string::npos);
}

TEST_CASE("features export: the scans written are the scans evaluated, to the bit", "[features][realdata]") {
  f::EvalOptions o;
  o.maxScans = 6;
  std::ostringstream scans;
  std::ostringstream kp;
  std::ostringstream pairs;
  f::ExportStreams out{&scans, &kp, &pairs};
  std::string err;
  REQUIRE(f::exportLog("mit-csail", kData + "mit-csail/mit-cscail.log.gz", o, out, err));
  const std::vector<std::string> scanLines = lines(scans.str());
  const std::vector<std::string> kpLines = lines(kp.str());
  REQUIRE(scanLines.size() == 6U * f::scanVariants(o).size());
  REQUIRE(kpLines.size() == scanLines.size());
  // A detector reading the scan file finds exactly the keypoints written for each scan.
  auto scan = std::make_unique<agv::LaserScan>();
  auto detector = std::make_unique<agv::FalkoDetector>();
  agv::FalkoKeypoints kps;
  std::size_t withKeypoints = 0;
  std::size_t halfBeams = 0;
  for (std::size_t l = 0; l < scanLines.size(); ++l) {
    std::string dataset;
    std::string variant;
    std::size_t index = 0;
    REQUIRE(parseScanLine(scanLines[l], dataset, variant, index, *scan));
    CHECK(dataset == "mit-csail");
    CHECK(index == l % 6U);
    (void)detector->detect(*scan, kps);
    CHECK(f::keypointLine(dataset, variant, index, {kps.begin(), kps.end()}) == kpLines[l] + "\n");
    withKeypoints += kps.empty() ? 0U : 1U;
    halfBeams += variant == "sampling-x1/2" ? scan->size() : 0U;
  }
  CHECK(withKeypoints > scanLines.size() / 2U);
  CHECK(halfBeams == 6U * 181U);  // 361 beams, every second one kept
  // Pairs: scan i < j, within 1 m, labelled with their distance bin.
  for (const std::string& p : lines(pairs.str())) {
    std::istringstream in(p);
    std::string name;
    std::size_t i = 0;
    std::size_t j = 0;
    double d = 0.0;
    double bin = 0.0;
    REQUIRE(in >> name >> i >> j >> d >> bin);
    CHECK(i < j);
    CHECK(j < 6U);
    CHECK(d <= bin);
    CHECK(d > bin - 0.25 - 1e-9);
  }
}

TEST_CASE("features eval: keypoint file numbers are decimal (leading zeros are not octal)", "[features]") {
  std::istringstream in("fr079 clean 010 2 01.5 -2e0 +.5 3.\n");
  f::KeypointTable t;
  std::string err;
  REQUIRE(f::readKeypointTable(in, t, err));
  const auto& kps = t.at("fr079").at("clean").at(10);
  REQUIRE(kps.size() == 2U);
  CHECK(kps[0].x == 1.5F);
  CHECK(kps[0].y == -2.0F);
  CHECK(kps[1].x == 0.5F);
  CHECK(kps[1].y == 3.0F);
}

TEST_CASE("features eval: a malformed keypoint file is refused with its line number", "[features]") {
  const struct {
    const char* text;
    const char* message;
  } cases[] = {
      {"fr079 clean 0 1 1.0\n", "line 1: 1 keypoints need 2 coordinates, found 1"},
      {"fr079 clean 0 1 1.0 2.0 3.0\n", "line 1: 1 keypoints need 2 coordinates, found 3"},
      {"# header\n\nfr079 clean 0 1 1.0 nan\n", "line 3: keypoint 1 is not a pair of finite numbers"},
      {"fr079 clean 0 1 1e400 0\n", "line 1: keypoint 1 is not a pair of finite numbers"},
      {"fr079 clean 0 1 1.0 2.0x\n", "line 1: keypoint 1 is not a pair of finite numbers"},
      {"fr079 clean 0 1 0x1 2.0\n", "line 1: keypoint 1 is not a pair of finite numbers"},
      {"fr079 clean 0 1 1,5 2.0\n", "line 1: keypoint 1 is not a pair of finite numbers"},
      {"fr079 clean 0x1 0\n", "line 1: expected <dataset> <variant> <scan> <count>"},
      {"fr079 clean 0 1.0\n", "line 1: expected <dataset> <variant> <scan> <count>"},
      {"fr079 clean 0 -1\n", "line 1: negative scan index or count"},
      {"fr079 clean x 0\n", "line 1: expected <dataset> <variant> <scan> <count>"},
      {"fr079 clean 0\n", "line 1: expected"},
      {"fr079 clean 0 0\nfr079 clean 1 0\nfr079 clean 0 0\n", "line 3: fr079 clean scan 0 is listed twice"},
  };
  for (const auto& c : cases) {
    INFO(c.text);
    std::istringstream in(c.text);
    f::KeypointTable t;
    std::string err;
    CHECK_FALSE(f::readKeypointTable(in, t, err));
    CHECK(err.find(c.message) != std::string::npos);
  }
  std::istringstream good("# comment\n\nfr079 clean 0 2 1 2 -3.5 4e-1\nfr079 clean 1 0\n");
  f::KeypointTable t;
  std::string err;
  REQUIRE(f::readKeypointTable(good, t, err));
  const auto& scans = t.at("fr079").at("clean");
  REQUIRE(scans.size() == 2U);
  REQUIRE(scans.at(0).size() == 2U);
  CHECK(scans.at(0)[1].x == -3.5F);
  CHECK(scans.at(0)[1].y == 0.4F);
  CHECK(scans.at(1).empty());
}
