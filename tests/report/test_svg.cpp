// The SVG writer: every text and attribute value escaped, elements nested and closed.
#include <string>

#include "agv/report/svg.hpp"
#include "agv_test.hpp"

using agv::report::SvgDocument;
using agv::report::svgNumber;
using agv::report::SvgPoints;
using agv::report::xmlEscape;

TEST_CASE("xmlEscape: markup characters become entities, forbidden controls U+FFFD", "[report]") {
  CHECK(xmlEscape("plain text 1.5") == "plain text 1.5");
  CHECK(xmlEscape("a<b & c>d") == "a&lt;b &amp; c&gt;d");
  CHECK(xmlEscape("say \"hi\" 'x'") == "say &quot;hi&quot; &apos;x&apos;");
  CHECK(xmlEscape("&amp;") == "&amp;amp;");  // no double-unescaping
  CHECK(xmlEscape(std::string("a\x01"
                              "b\tc\n",
                              6)) ==
        "a\xEF\xBF\xBD"
        "b\tc\n");
  CHECK(xmlEscape("W\xC3\xA4nde") == "W\xC3\xA4nde");  // UTF-8 passes unchanged
}

TEST_CASE("svgNumber: two decimals, locale-free, no negative zero", "[report]") {
  CHECK(svgNumber(1.0) == "1.00");
  CHECK(svgNumber(-12.345) == "-12.35");
  CHECK(svgNumber(-0.001) == "0.00");
  CHECK(svgNumber(1e6) == "1000000.00");
}

TEST_CASE("SvgDocument: attributes and text escaped, nesting closed", "[report]") {
  SvgDocument doc(100.0, 50.0, {{"font-family", "sans-serif"}});
  doc.add("line", {{"x1", 0.0}, {"y1", 1.5}, {"stroke", "#444"}});
  doc.addText("text", {{"x", 10.0}, {"data-path", "P1\" onload=\"alert(1)"}}, "<P1> & 'P2'");
  doc.open("text", {{"x", 1}});
  doc.addText("tspan", {{"fill", "#000"}}, "a<b");
  doc.text(" & ");
  doc.open("tspan", {});
  doc.text("unclosed");
  SvgPoints pts;
  CHECK(pts.empty());
  pts.add(1.0, 2.0);
  pts.add(3.004, -4.0);
  CHECK(pts.str() == "1.00,2.00 3.00,-4.00");
  const std::string s = doc.str();
  CHECK(s.rfind(
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"100.00\" height=\"50.00\" font-family=\"sans-serif\">\n"
            "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n",
            0) == 0);
  CHECK(s.find("<line x1=\"0.00\" y1=\"1.50\" stroke=\"#444\"/>\n") != std::string::npos);
  CHECK(
      s.find(
          "<text x=\"10.00\" data-path=\"P1&quot; onload=&quot;alert(1)\">&lt;P1&gt; &amp; &apos;P2&apos;</text>\n") !=
      std::string::npos);
  CHECK(s.find("<text x=\"1\"><tspan fill=\"#000\">a&lt;b</tspan> &amp; <tspan>unclosed</tspan></text>\n</svg>\n") !=
        std::string::npos);
  // Every '<' outside the markup was escaped: tags balance.
  std::size_t opens = 0;
  std::size_t closes = 0;
  for (std::size_t i = 0; i + 1 < s.size(); ++i) {
    opens += s[i] == '<' && s[i + 1] != '/' ? 1U : 0U;
    closes += (s[i] == '<' && s[i + 1] == '/') || (s[i] == '/' && s[i + 1] == '>') ? 1U : 0U;
  }
  CHECK(opens == closes);
  doc.close();
  doc.close();
  doc.close();  // nothing left open: no effect
  CHECK(doc.str() == s);
}
