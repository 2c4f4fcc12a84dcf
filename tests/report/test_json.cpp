// The JSON helpers: key order kept, strings escaped by the library, invalid UTF-8 replaced,
// files written with an error that names the file.
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

#include "agv/report/json.hpp"
#include "agv_test.hpp"

using agv::report::Json;

TEST_CASE("dumpJson: insertion order, escaping, parses back", "[report]") {
  Json doc;
  doc["zeta"] = 1;
  doc["alpha"] = "quote \" backslash \\ newline \n tab \t bell \x07";
  doc["path"] = "W\xE4nde.txt";  // Latin-1 file name: not valid UTF-8
  doc["nested"]["b"] = true;
  doc["nested"]["a"] = 0.25;
  const std::string text = agv::report::dumpJson(doc);
  CHECK(text.back() == '\n');
  CHECK(text.find("\"zeta\"") < text.find("\"alpha\""));
  const Json back = Json::parse(text);
  CHECK(back.at("zeta") == 1);
  CHECK(back.at("alpha") == "quote \" backslash \\ newline \n tab \t bell \x07");
  CHECK(back.at("path") == "W\xEF\xBF\xBDnde.txt");
  CHECK(back.at("nested").at("a") == 0.25);
  CHECK(back.at("nested").at("b") == true);
}

TEST_CASE("shortestDouble: floats as typed", "[report]") {
  CHECK(agv::report::shortestDouble(0.2F) == 0.2);
  CHECK(agv::report::shortestDouble(0.07F) == 0.07);
  CHECK(agv::report::shortestDouble(16.0F) == 16.0);
  CHECK(Json(agv::report::shortestDouble(0.2F)).dump() == "0.2");
}

TEST_CASE("writeJsonFile: writes the document or says why not", "[report]") {
  const std::string path = "test_report_json_out.json";
  Json doc = {{"a", 1}};
  std::string error;
  REQUIRE(agv::report::writeJsonFile(path, doc, error));
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  CHECK(Json::parse(s.str()) == doc);
  std::remove(path.c_str());
  CHECK_FALSE(agv::report::writeJsonFile("/nonexistent-dir/x.json", doc, error));
  CHECK(error.find("cannot write /nonexistent-dir/x.json: ") == 0);
}
